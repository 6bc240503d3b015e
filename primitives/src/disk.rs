//! Disk (flat, one-sided in Φ, hit from both sides).
//!
//! | field    | meaning                          | constraint        |
//! |----------|----------------------------------|-------------------|
//! | `center` | centre `c`                       | finite            |
//! | `normal` | normal `n` (normalised on input) | finite, non-zero  |
//! | `radius` | radius `r`                       | finite, `> 0`     |
//!
//! - **Φ(p) = ⟨p − c, n⟩**, the signed distance to the supporting plane (positive on the side `n`
//!   points to; Lipschitz bound 1); **∇Φ = n**. [`Implicit::within_boundary`] keeps the points
//!   whose distance from `c` measured in the plane is `≤ r` (rim included).
//! - **Parametric form**: plane coordinates `p(u, v) = c + u·e₁ + v·e₂` with `(e₁, e₂, n)` the
//!   right-handed basis of [`orthonormal_basis`] (`e₁ × e₂ = n`); domain `u, v ∈ [−r, r]`, whose
//!   corners (`u² + v² > r²`) lie outside the disk.
//! - **Intersection**: the plane hit `t = ⟨c − o, n⟩ / ⟨dir, n⟩`, then the radius test on the
//!   hit's plane coordinates, which are kept in [`RawHit::local`]. A ray parallel to the plane
//!   (`⟨dir, n⟩ = 0`), including one lying in it, misses.
//! - **Closest point**: with `h = Φ(p)` and `w = (p − c) − h·n` the in-plane offset of `p` from
//!   the centre (`ρ = |w|`), the projection `q = c + w` where `ρ ≤ r` (distance `|h|`), else
//!   the rim point `q = c + r·w/ρ` (distance `√(h² + (ρ − r)²)`): the disk is convex, so the
//!   nearest point of the disk to `p` is the nearest one to `p`'s projection on its plane. Exact
//!   to rounding; from a point on the axis (`ρ = 0`) the centre is the nearest point.

use crate::bounds::Aabb;
use crate::error::{
    require_coordinates_within, require_direction, require_finite, require_length_in_range, require_positive,
    PrimitiveError, MAX_MAGNITUDE,
};
use crate::hit::RawHit;
use crate::math::dot_minus;
use crate::math::orthonormal_basis;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};

/// A disk of radius `radius` around `center`, facing `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disk {
    center: DVec3,
    normal: DVec3,
    radius: f64,
    e1: DVec3,
    e2: DVec3,
}

impl Disk {
    /// A disk; errors on a non-finite centre, a zero or non-finite normal, or a radius that is
    /// not finite and positive.
    pub fn new(center: DVec3, normal: DVec3, radius: f64) -> Result<Self, PrimitiveError> {
        let center = require_finite("Disk", "center", center)?;
        let normal = require_direction("Disk", "normal", normal)?;
        let radius = require_positive("Disk", "radius", radius)?;
        require_coordinates_within("Disk", "center", center, MAX_MAGNITUDE)?;
        require_length_in_range("Disk", "radius", radius)?;
        let (e1, e2) = orthonormal_basis(normal);
        Ok(Self {
            center,
            normal,
            radius,
            e1,
            e2,
        })
    }

    /// Centre.
    #[must_use]
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// Unit normal.
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Radius.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Plane coordinates `(⟨p − c, e₁⟩, ⟨p − c, e₂⟩)` of `p` (of its projection on the plane).
    #[inline]
    fn plane_coordinates(&self, p: DVec3) -> DVec2 {
        let q = p - self.center;
        DVec2::new(q.dot(self.e1), q.dot(self.e2))
    }
}

impl Implicit for Disk {
    fn phi(&self, p: DVec3) -> f64 {
        (p - self.center).dot(self.normal)
    }

    fn gradient(&self, _p: DVec3) -> DVec3 {
        self.normal
    }

    /// The exact box of the rim: half-extent `r·√(1 − nᵢ²)` on axis `i`.
    fn bounds(&self) -> Aabb {
        let n = self.normal;
        let half = self.radius
            * DVec3::new(
                (n.y * n.y + n.z * n.z).sqrt(),
                (n.z * n.z + n.x * n.x).sqrt(),
                (n.x * n.x + n.y * n.y).sqrt(),
            );
        Aabb::new(self.center - half, self.center + half)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    fn within_boundary(&self, p: DVec3) -> bool {
        self.plane_coordinates(p).length_squared() <= self.radius * self.radius
    }

    /// The projection on the plane, moved onto the rim where it falls outside (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let uv = self.plane_coordinates(p);
        let rho = uv.length();
        let uv = if rho > self.radius {
            uv * (self.radius / rho)
        } else {
            uv
        };
        Some(Closest::exact(p, self.point(uv), 0))
    }
}

impl Intersect for Disk {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Disk, ray: &Ray, range: Interval) -> Option<RawHit> {
            let denom = dot_minus(ray.dir, this.normal, 0.0);
            if denom == 0.0 {
                return None;
            }
            let t = -dot_minus(ray.origin, this.normal, this.center.dot(this.normal)) / denom;
            if !range.contains(t) {
                return None;
            }
            let uv = this.plane_coordinates(ray.at(t));
            (uv.length_squared() <= this.radius * this.radius).then_some(RawHit {
                t,
                feature: 0,
                local: uv,
            })
        }
        crate::with_fma!(test(this: &Disk = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    fn normal_at(&self, _ray: &Ray, _raw: &RawHit) -> DVec3 {
        self.normal
    }

    fn uv_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(raw.local)
    }
}

impl Parametric for Disk {
    fn domain(&self) -> UvDomain {
        UvDomain {
            u: (-self.radius, self.radius),
            v: (-self.radius, self.radius),
        }
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        self.center + uv.x * self.e1 + uv.y * self.e2
    }

    fn partials(&self, _uv: DVec2) -> (DVec3, DVec3) {
        (self.e1, self.e2)
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        self.plane_coordinates(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_parameters() {
        assert!(Disk::new(DVec3::ZERO, DVec3::Z, 0.0).is_err());
        assert!(Disk::new(DVec3::ZERO, DVec3::Z, -1.0).is_err());
        assert!(Disk::new(DVec3::ZERO, DVec3::Z, f64::NAN).is_err());
        assert!(Disk::new(DVec3::ZERO, DVec3::ZERO, 1.0).is_err());
        assert!(Disk::new(DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 1.0), 1.0).is_err());
        assert!(Disk::new(DVec3::new(0.0, f64::INFINITY, 0.0), DVec3::Z, 1.0).is_err());
        let e = Disk::new(DVec3::ZERO, DVec3::Z, 0.0).unwrap_err();
        assert_eq!((e.primitive, e.field.as_str()), ("Disk", "radius"));
    }

    #[test]
    fn known_hits_rim_and_misses() {
        // disk of radius 2 at (1, 1, 3) facing +z (normal given unnormalised)
        let disk = Disk::new(DVec3::new(1.0, 1.0, 3.0), DVec3::new(0.0, 0.0, 5.0), 2.0).unwrap();
        assert_eq!(disk.normal(), DVec3::Z);
        let down = |x: f64, y: f64| Ray::new(DVec3::new(x, y, 10.0), DVec3::new(0.0, 0.0, -2.0));
        let hit = disk.intersect(&down(2.0, 1.5), Interval::POSITIVE).unwrap();
        assert_eq!(hit.t, 3.5); // 7 units of distance at |dir| = 2
        assert!((hit.local.length() - 1.25f64.sqrt()).abs() < 1e-15);
        assert!((disk.point(hit.local) - DVec3::new(2.0, 1.5, 3.0)).length() < 1e-15);
        assert!(
            disk.intersect(&down(3.0, 1.0), Interval::POSITIVE).is_some(),
            "rim point counts"
        );
        assert!(
            disk.intersect(&down(3.0 + 1e-12, 1.0), Interval::POSITIVE).is_none(),
            "just outside the rim"
        );
        assert!(
            disk.intersect(&down(2.5, 2.5), Interval::POSITIVE).is_none(),
            "corner of the uv domain"
        );
        // from below: hit, same normal; parallel and in-plane rays miss
        let up = Ray::new(DVec3::new(1.0, 0.0, 0.0), DVec3::Z);
        let hit = disk.intersect(&up, Interval::POSITIVE).unwrap();
        assert_eq!((hit.t, disk.normal_at(&up, &hit)), (3.0, DVec3::Z));
        assert!(disk
            .intersect(&Ray::new(DVec3::new(1.0, 1.0, 3.0), DVec3::X), Interval::POSITIVE)
            .is_none());
        assert_eq!(disk.phi(DVec3::new(-7.0, 4.0, 1.0)), -2.0);
    }

    #[test]
    fn tilted_disk_bounds_are_tight() {
        let n = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let disk = Disk::new(DVec3::new(0.5, -1.0, 2.0), n, 3.0).unwrap();
        let b = disk.bounds();
        // extreme rim point along x: c + r·(x̂ − n_x n)/|x̂ − n_x n|
        let mut max_x = f64::NEG_INFINITY;
        for i in 0..100_000 {
            let a = i as f64 * std::f64::consts::TAU / 100_000.0;
            let p = disk.point(3.0 * DVec2::from_angle(a));
            assert!(b.expanded(1e-12).contains(p), "{p} outside {b:?}");
            max_x = max_x.max(p.x);
        }
        let expected = 0.5 + 3.0 * (1.0 - n.x * n.x).sqrt();
        assert!(
            (b.max.x - expected).abs() < 1e-14 && (max_x - expected).abs() < 1e-8,
            "{} {max_x} {expected}",
            b.max.x
        );
    }
}
