//! Circular cylinder about an arbitrary axis, capped (a solid) or open (a tube).
//!
//! | field    | meaning                                  | constraint        |
//! |----------|------------------------------------------|-------------------|
//! | `base`   | centre `b` of the bottom disk            | finite            |
//! | `axis`   | axis direction `a` (normalised on input) | finite, non-zero  |
//! | `radius` | radius `r`                               | finite, `> 0`     |
//! | `height` | axial length `H` (top disk at `b + H·a`) | finite, `> 0`     |
//! | `capped` | closed solid (`true`) or open tube       | —                 |
//!
//! A cylinder is the frustum with equal radii, and every formula of [`Cone`] reduces exactly to
//! the cylinder's when `r₀ = r₁ = r` (the slope `k = 0` makes `s(h) = r`, `s′ = 0` and the slant
//! `S = H`, with no rounding), so this type validates the cylinder's parameters and delegates to
//! a [`Cone`]. In the local frame `(x, y, h)` of the cone module (`ρ = |(x, y)|`):
//!
//! - **Φ, capped**: the exact signed distance of the solid, the 2-D distance to the rectangle
//!   `[0, r] × [0, H]` in the `(ρ, h)` half-plane; `∇Φ` is `ρ̂`, `−a` or `+a` where the nearest
//!   point is inside the side or a cap, and the direction from the nearest rim point otherwise.
//! - **Φ, open**: `Φ = ρ − r` (the infinite tube, Lipschitz 1), `∇Φ = ρ̂`;
//!   [`Implicit::within_boundary`] keeps `0 ≤ h ≤ H`. Both Φ are Lipschitz 1.
//! - **Parametric form**: `u ∈ [0, 1]` is the angle `2πu` from `e₁` towards `e₂` (seam at `u = 0`,
//!   the `e₁` side); side `v ∈ [0, 1]` with `h = v·H`. Capped, `v ∈ [−1, 2]`: `v ∈ [−1, 0)` is the
//!   bottom disk at `ρ = (1 + v)·r`, `v ∈ (1, 2]` the top disk at `ρ = (2 − v)·r`, continuous
//!   through both rims; `∂p/∂u × ∂p/∂v` points outward everywhere.
//! - **Intersection**: the side quadratic is formed from the components of `o − b` and `d`
//!   perpendicular to the axis, `A = |d⊥|²`, `B = o⊥·d⊥`, `C = |o⊥|² − r²`, with the
//!   discriminant `A r² − (o⊥ × d⊥)²` (Lagrange's identity, no cancellation of `B²` against `AC`)
//!   and the roots `q/A`, `C/q`. A ray parallel to the axis has `A = 0` and `B = 0`: the solver
//!   reports no side root and only the caps can be hit. A side root counts if `0 ≤ h ≤ H`; the caps
//!   (capped only) are the planes `h = 0`, `h = H` with `ρ ≤ r`, the rim included. Features: `0`
//!   side, `1` bottom cap, `2` top cap ([`crate::cone::SIDE`], [`crate::cone::BOTTOM`],
//!   [`crate::cone::TOP`]).
//! - **Closest point**: the cone's with `r₀ = r₁` (exact to rounding): in `p`'s meridian
//!   half-plane, the nearest point of the side segment `ρ′ = r, 0 ≤ h′ ≤ H` (`(r, clamp(h, 0,
//!   H))`) and, capped, of the cap segments `0 ≤ ρ′ ≤ r` at `h′ = 0` and `h′ = H`
//!   (`(min(ρ, r), 0)`, `(min(ρ, r), H)`), the nearest of them, mapped back as `b + ρ′·ρ̂ + h′·a`.

use crate::bounds::Aabb;
use crate::cone::Cone;
use crate::error::{
    require_coordinates_within, require_direction, require_finite, require_length_in_range, require_positive,
    PrimitiveError, MAX_MAGNITUDE,
};
use crate::hit::RawHit;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};

/// A circular cylinder (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    cone: Cone,
}

impl Cylinder {
    /// A cylinder; errors on a non-finite base, a zero axis, or a radius or height that is not
    /// finite and positive.
    pub fn new(base: DVec3, axis: DVec3, radius: f64, height: f64, capped: bool) -> Result<Self, PrimitiveError> {
        let base = require_finite("Cylinder", "base", base)?;
        let axis = require_direction("Cylinder", "axis", axis)?;
        let radius = require_positive("Cylinder", "radius", radius)?;
        let height = require_positive("Cylinder", "height", height)?;
        require_coordinates_within("Cylinder", "base", base, MAX_MAGNITUDE)?;
        require_length_in_range("Cylinder", "radius", radius)?;
        require_length_in_range("Cylinder", "height", height)?;
        Ok(Self {
            cone: Cone::from_valid(base, axis, radius, radius, height, capped),
        })
    }

    /// Centre of the bottom disk.
    #[must_use]
    pub fn base(&self) -> DVec3 {
        self.cone.base()
    }

    /// Unit axis, from the bottom towards the top.
    #[must_use]
    pub fn axis(&self) -> DVec3 {
        self.cone.axis()
    }

    /// Radius.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.cone.radii().0
    }

    /// Axial length.
    #[must_use]
    pub fn height(&self) -> f64 {
        self.cone.height()
    }

    /// Whether the cylinder is a closed solid.
    #[must_use]
    pub fn capped(&self) -> bool {
        self.cone.capped()
    }
}

impl Implicit for Cylinder {
    fn phi(&self, p: DVec3) -> f64 {
        self.cone.phi(p)
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.cone.gradient(p)
    }

    fn bounds(&self) -> Aabb {
        self.cone.bounds()
    }

    fn lipschitz(&self) -> Option<f64> {
        self.cone.lipschitz()
    }

    fn within_boundary(&self, p: DVec3) -> bool {
        self.cone.within_boundary(p)
    }

    /// The cone's nearest point (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        self.cone.closest(p)
    }
}

impl Intersect for Cylinder {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        self.cone.intersect(ray, range)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        self.cone.normal_at(ray, raw)
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        self.cone.uv_at(ray, raw)
    }
}

impl Parametric for Cylinder {
    fn domain(&self) -> UvDomain {
        self.cone.domain()
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        self.cone.point(uv)
    }

    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        self.cone.partials(uv)
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        self.cone.uv(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cone::{BOTTOM, SIDE, TOP};
    use crate::math::orthonormal_basis;

    /// Radius 1, from z = 0 to z = 2 on the Z axis.
    fn cylinder(capped: bool) -> Cylinder {
        Cylinder::new(DVec3::ZERO, DVec3::Z, 1.0, 2.0, capped).unwrap()
    }

    fn hit(c: &Cylinder, ray: Ray) -> Option<(f64, u32, DVec3)> {
        c.intersect(&ray, Interval::POSITIVE)
            .map(|h| (h.t, h.feature, c.normal_at(&ray, &h)))
    }

    #[test]
    fn rejects_bad_parameters() {
        let make = |r, h| Cylinder::new(DVec3::ZERO, DVec3::Z, r, h, true);
        assert!(make(1.0, 1.0).is_ok());
        assert!(make(0.0, 1.0).is_err() && make(-1.0, 1.0).is_err() && make(f64::NAN, 1.0).is_err());
        assert!(make(1.0, 0.0).is_err() && make(1.0, -2.0).is_err() && make(1.0, f64::INFINITY).is_err());
        assert!(Cylinder::new(DVec3::ZERO, DVec3::ZERO, 1.0, 1.0, true).is_err());
        assert!(Cylinder::new(DVec3::new(0.0, f64::NAN, 0.0), DVec3::Z, 1.0, 1.0, true).is_err());
    }

    #[test]
    fn side_and_cap_hits_are_exact() {
        for capped in [true, false] {
            let c = cylinder(capped);
            let ray = Ray::new(DVec3::new(-3.0, 0.0, 1.0), DVec3::X);
            assert_eq!(hit(&c, ray), Some((2.0, SIDE, -DVec3::X)));
            // from inside: the far wall, normal still outward
            assert_eq!(
                hit(&c, Ray::new(DVec3::new(0.0, 0.0, 1.0), DVec3::X)),
                Some((1.0, SIDE, DVec3::X))
            );
        }
        let c = cylinder(true);
        assert_eq!(
            hit(&c, Ray::new(DVec3::new(0.5, 0.0, 5.0), -DVec3::Z)),
            Some((3.0, TOP, DVec3::Z))
        );
        // a ray lying in the top plane meets the side at the rim
        assert_eq!(
            hit(&c, Ray::new(DVec3::new(-3.0, 0.0, 2.0), DVec3::X)),
            Some((2.0, SIDE, -DVec3::X))
        );
    }

    #[test]
    fn tilted_side_hit_matches_geometry() {
        let axis = DVec3::new(1.0, 2.0, 3.0).normalize();
        let (e1, e2) = orthonormal_basis(axis);
        let base = DVec3::new(0.3, -1.7, 2.9);
        let out = (0.6 * e1 + 0.8 * e2).normalize();
        let c = Cylinder::new(base, axis, 1.25, 3.0, true).unwrap();
        let ray = Ray::new(base + 1.5 * axis + 6.0 * out, -out);
        let (t, feature, n) = hit(&c, ray).unwrap();
        assert!((t - 4.75).abs() < 1e-14, "t = {t}");
        assert_eq!(feature, SIDE);
        assert!((n - out).length() < 1e-14, "{n}");
    }

    #[test]
    fn rays_along_the_axis() {
        // Z axis: the local perpendicular direction is exactly zero, A = B = 0
        for capped in [true, false] {
            let c = cylinder(capped);
            let inside = hit(&c, Ray::new(DVec3::new(0.5, 0.0, -5.0), DVec3::Z));
            assert_eq!(inside, capped.then_some((5.0, BOTTOM, -DVec3::Z)));
            assert_eq!(hit(&c, Ray::new(DVec3::new(1.5, 0.0, -5.0), DVec3::Z)), None);
            let from_within = hit(&c, Ray::new(DVec3::new(0.5, 0.0, 1.0), -DVec3::Z));
            assert_eq!(from_within, capped.then_some((1.0, BOTTOM, -DVec3::Z)));
        }
        // a tilted axis: rounding leaves a tiny perpendicular part, the side roots are huge
        let axis = DVec3::new(1.0, 2.0, 3.0).normalize();
        let (e1, _) = orthonormal_basis(axis);
        let c = Cylinder::new(DVec3::ZERO, axis, 1.0, 2.0, true).unwrap();
        let (t, feature, n) = hit(&c, Ray::new(0.5 * e1 - 5.0 * axis, axis)).unwrap();
        assert!(
            (t - 5.0).abs() < 1e-14 && feature == BOTTOM && n == -axis,
            "{t} {feature} {n}"
        );
        let open = Cylinder::new(DVec3::ZERO, axis, 1.0, 2.0, false).unwrap();
        assert!(open
            .intersect(&Ray::new(0.5 * e1 - 5.0 * axis, axis), Interval::POSITIVE)
            .is_none());
    }

    #[test]
    fn ray_through_the_cap_rim() {
        // aimed at the rim point (1, 0, 2) from (−2, 0, 3): side and top cap both at t = 1
        let c = cylinder(true);
        let ray = Ray::new(DVec3::new(-2.0, 0.0, 3.0), DVec3::new(3.0, 0.0, -1.0));
        let (t, feature, n) = hit(&c, ray).unwrap();
        assert_eq!(t, 1.0);
        assert_eq!((feature, n), (TOP, DVec3::Z), "the cap keeps the tie");
        // the open tube has no cap: the side, at the same point
        assert_eq!(hit(&cylinder(false), ray), Some((1.0, SIDE, DVec3::X)));
    }

    #[test]
    fn phi_values() {
        let (solid, tube) = (cylinder(true), cylinder(false));
        assert_eq!(solid.phi(DVec3::new(0.0, 0.0, 1.0)), -1.0);
        assert_eq!(solid.phi(DVec3::new(0.0, 0.5, 1.75)), -0.25);
        assert_eq!(solid.gradient(DVec3::new(0.0, 0.5, 1.75)), DVec3::Z);
        assert_eq!(solid.phi(DVec3::new(0.0, 0.0, 2.5)), 0.5);
        assert_eq!(solid.phi(DVec3::new(2.0, 0.0, 3.0)), 2f64.sqrt());
        assert!((solid.gradient(DVec3::new(2.0, 0.0, 3.0)) - DVec3::new(1.0, 0.0, 1.0) / 2f64.sqrt()).length() < 1e-15);
        assert_eq!(tube.phi(DVec3::new(0.0, 0.0, 5.0)), -1.0);
        assert_eq!(tube.phi(DVec3::new(3.0, 0.0, 1.0)), 2.0);
        assert!(!tube.within_boundary(DVec3::new(1.0, 0.0, 2.5)) && tube.within_boundary(DVec3::new(1.0, 0.0, 2.0)));
    }

    #[test]
    fn uv_covers_the_caps_continuously() {
        let c = cylinder(true);
        assert_eq!(c.domain().v, (-1.0, 2.0));
        assert_eq!(cylinder(false).domain().v, (0.0, 1.0));
        // bottom cap at radius 0.5, a quarter turn from e₁ = X towards e₂ = Y
        let p = c.point(DVec2::new(0.25, -0.5));
        assert!((p - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-15, "{p}");
        assert!((c.uv(p) - DVec2::new(0.25, -0.5)).length() < 1e-15);
        let top = c.point(DVec2::new(0.5, 1.5));
        assert!((top - DVec3::new(-0.5, 0.0, 2.0)).length() < 1e-15, "{top}");
        let (du, dv) = c.partials(DVec2::new(0.5, 1.5));
        assert!((du.cross(dv).normalize() - DVec3::Z).length() < 1e-15);
    }
}
