//! Ellipsoid with arbitrary orientation.
//!
//! | field         | meaning                                          | constraint                   |
//! |---------------|--------------------------------------------------|------------------------------|
//! | `center`      | centre `c`                                       | finite                       |
//! | `radii`       | semi-axes `r = (r_x, r_y, r_z)` in the local frame | finite, each `> 0`         |
//! | `orientation` | rotation `R` taking local axes to world axes     | finite, `‖R‖ = 1 ± 10⁻⁶` (renormalised) |
//!
//! With `q = R⁻¹(p − c)` the local point and `s = q ⊘ r` its image in unit-sphere space:
//!
//! - **Φ(p) = (|s| − 1)·min(r)**: negative exactly inside (`|s| < 1`). Lipschitz bound 1:
//!   `p ↦ s` is a rotation followed by a division of each component by at least `min(r)`, so it
//!   shrinks distances by at least `1/min(r)`, and `|·|` is 1-Lipschitz. Φ is not a distance (it
//!   underestimates it by up to the ratio `max(r)/min(r)` away from the short axis).
//! - **∇Φ = min(r)·R(s ⊘ r)/|s|** (analytic; zero at the centre); the normal is its direction.
//! - **Parametric form**: the unit sphere's ([`Sphere`]: `u, v ∈ [0, 1]`, poles on the local ±Y
//!   axis, seam at `u = 0` on the local +X side) mapped by `c + R(r ⊙ ·)`; `∂p/∂u × ∂p/∂v`
//!   stays outward because the map is linear with positive determinant.
//! - **Intersection**: the ray is mapped to unit-sphere space, `o′ = R⁻¹(o − c) ⊘ r`,
//!   `d′ = R⁻¹d ⊘ r`, **without renormalising `d′`**, so `t` is unchanged; the unit sphere's
//!   cancellation-free quadratic ([`Sphere::roots`]: discriminant `|d′|² − |o′ × d′|²`, roots
//!   `q/a`, `c₀/q`) then gives the hits. The normal at a hit is computed from the unit-space
//!   point `o′ + t·d′` directly, `R(s ⊘ r)`, normalised.
//! - **Closest point** (`nearest_in_octant`), after D. Eberly, "Distance from a Point to an
//!   Ellipse, an Ellipsoid, or a Hyperellipsoid" (2013): by symmetry in each local axis the
//!   problem is solved for `y = |q|` (the first octant) with the semi-axes sorted,
//!   `e₀ ≥ e₁ ≥ e₂`, and the answer permuted back and given `q`'s signs. A nearest point `x` is
//!   a stationary point of `|x − y|²` on `Σ xᵢ²/eᵢ² = 1`: `xᵢ = eᵢ²yᵢ/(t + eᵢ²)` for a Lagrange
//!   parameter `t`. Where every `yᵢ > 0`, the nearest one has `t > −e₂²` (each `xᵢ` of `yᵢ`'s
//!   sign), the unique root of `F(t) = Σ (eᵢyᵢ/(t + eᵢ²))² − 1`, which decreases strictly from
//!   `+∞` to `−1` there. With `σ = (t + e₂²)/e₂² > 0`, `zᵢ = yᵢ/eᵢ`, `ρᵢ = eᵢ²/e₂² ≥ 1` and
//!   `δᵢ = ρᵢ − 1 = (eᵢ − e₂)(eᵢ + e₂)/e₂² ≥ 0`, it is the root of
//!   `G(σ) = Σ (ρᵢzᵢ/(σ + δᵢ))² − 1` in `[z₂, |ρ ⊙ z|]` (`G ≥ 0` at the left end, from its last
//!   term alone; `G ≤ 0` at the right end since `σ + δᵢ ≥ |ρ ⊙ z|`), or in `[z₂, 1]` from inside
//!   (`G(1) = |z|² − 1 < 0`), found by bisection to the last bit (until the midpoint rounds to
//!   an end), and `xᵢ = ρᵢyᵢ/(σ + δᵢ)`. Eberly's `s = σ − 1` would lose `σ`'s relative precision
//!   near the medial surface (`σ ≈ z₂` tiny, where `x₂ = y₂/σ` is a ratio of two small
//!   numbers): `σ` itself keeps it. The degenerate cases, where the root is not inside that
//!   bracket:
//!   - `y₂ > 0` with some other `yᵢ = 0` (a point in a coordinate plane through the smallest
//!     axis, or on that axis): `xᵢ = 0` (`t = −eᵢ² ≤ −e₂²` would flip `x₂`'s sign), and the
//!     remaining axes, the smallest among them, are solved as above (on the smallest axis alone,
//!     `x₂ = e₂`);
//!   - `y₂ = 0` (the plane of the two larger axes, which holds the medial surface): if
//!     `t = −e₂²` is feasible, that is `xᵢ/eᵢ = eᵢyᵢ/(eᵢ² − e₂²) < 1` for each `yᵢ > 0` (`i < 2`,
//!     which needs `eᵢ > e₂`) with `Σ (xᵢ/eᵢ)² < 1`, the nearest points leave the plane:
//!     `x₂ = e₂·√(1 − Σ (xᵢ/eᵢ)²)` (the two mirror images are equally near, the `+` one is
//!     returned); otherwise `x₂ = 0` and the ellipse of the two larger axes is solved the same
//!     way (down to one axis, `x₀ = e₀`).
//!
//!   At the centre, on an axis or on the medial surface the nearest point is not unique and one
//!   of them is returned; the distance is exact to rounding in every case. Computed in f64 in
//!   the local frame, then mapped back: `c + R·x`.

use crate::bounds::Aabb;
use crate::error::{
    require_coordinates_within, require_finite, require_length_in_range, require_positive, PrimitiveError,
    MAX_MAGNITUDE,
};
use crate::hit::RawHit;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::sphere::Sphere;
use crate::traits::{Implicit, Intersect, Parametric};
use glam::{DMat3, DQuat, DVec2, DVec3};

/// An ellipsoid with semi-axes `radii` along the rotated local axes, centred at `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    center: DVec3,
    radii: DVec3,
    orientation: DQuat,
    /// `R` as a matrix (columns: the local axes in world space) and its inverse `Rᵀ`.
    world_from_local: DMat3,
    local_from_world: DMat3,
    /// The unit sphere at the origin, whose quadratic and parametric form are reused.
    unit: Sphere,
}

impl Ellipsoid {
    /// An ellipsoid; errors on a non-finite centre, a radius that is not finite and positive, or
    /// an orientation that is not a finite unit quaternion (to within `10⁻⁶`; it is then
    /// renormalised exactly).
    pub fn new(center: DVec3, radii: DVec3, orientation: DQuat) -> Result<Self, PrimitiveError> {
        let center = require_finite("Ellipsoid", "center", center)?;
        let radii = DVec3::new(
            require_positive("Ellipsoid", "radii.x", radii.x)?,
            require_positive("Ellipsoid", "radii.y", radii.y)?,
            require_positive("Ellipsoid", "radii.z", radii.z)?,
        );
        require_coordinates_within("Ellipsoid", "center", center, MAX_MAGNITUDE)?;
        for (field, r) in [("radii.x", radii.x), ("radii.y", radii.y), ("radii.z", radii.z)] {
            require_length_in_range("Ellipsoid", field, r)?;
        }
        let norm = orientation.length();
        if !(orientation.is_finite() && (norm - 1.0).abs() <= 1e-6) {
            return Err(PrimitiveError::new(
                "Ellipsoid",
                "orientation",
                format!("must be a unit quaternion, got {orientation} (norm {norm})"),
            ));
        }
        let orientation = orientation / norm;
        let world_from_local = DMat3::from_quat(orientation);
        Ok(Self {
            center,
            radii,
            orientation,
            world_from_local,
            local_from_world: world_from_local.transpose(),
            unit: Sphere::new(DVec3::ZERO, 1.0)?,
        })
    }

    /// Centre.
    #[must_use]
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// Semi-axes along the local axes.
    #[must_use]
    pub fn radii(&self) -> DVec3 {
        self.radii
    }

    /// Rotation from the local frame to the world (unit quaternion).
    #[must_use]
    pub fn orientation(&self) -> DQuat {
        self.orientation
    }

    /// `p` in unit-sphere space: `R⁻¹(p − c) ⊘ r`.
    fn unit_space(&self, p: DVec3) -> DVec3 {
        self.local_from_world * (p - self.center) / self.radii
    }

    /// The world-space gradient direction (unnormalised) at unit-space point `s`: `R(s ⊘ r)`.
    fn normal_direction(&self, s: DVec3) -> DVec3 {
        self.world_from_local * (s / self.radii)
    }
}

impl Implicit for Ellipsoid {
    fn phi(&self, p: DVec3) -> f64 {
        (self.unit_space(p).length() - 1.0) * self.radii.min_element()
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let s = self.unit_space(p);
        let len = s.length();
        if len > 0.0 {
            self.normal_direction(s) * (self.radii.min_element() / len)
        } else {
            DVec3::ZERO
        }
    }

    fn bounds(&self) -> Aabb {
        // world component i of R(r ⊙ s) over |s| = 1 reaches |(R_i0 r_x, R_i1 r_y, R_i2 r_z)|
        let m = self.world_from_local;
        let square = |v: DVec3| v * v;
        let reach = square(m.x_axis * self.radii.x) + square(m.y_axis * self.radii.y) + square(m.z_axis * self.radii.z);
        let reach = DVec3::new(reach.x.sqrt(), reach.y.sqrt(), reach.z.sqrt());
        Aabb::new(self.center - reach, self.center + reach)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    /// The nearest point by the Lagrange root in the first octant (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let q = self.local_from_world * (p - self.center);
        // axes by decreasing semi-axis (stable: equal semi-axes keep their order)
        let mut order = [0usize, 1, 2];
        order.sort_by(|&i, &j| self.radii[j].total_cmp(&self.radii[i]));
        let e = order.map(|i| self.radii[i]);
        let y = order.map(|i| q[i].abs());
        let mut x = [0.0; 3];
        nearest_in_octant(&e, &y, &mut x);
        let mut local = DVec3::ZERO;
        for (k, &i) in order.iter().enumerate() {
            local[i] = x[k].copysign(q[i]);
        }
        Some(Closest::exact(p, self.center + self.world_from_local * local, 0))
    }
}

/// The nearest point `x` (written to `x`) of the ellipsoid (ellipse, or pair of points, by the
/// length of the slices) with semi-axes `e`, sorted decreasing, to `y ≥ 0` componentwise, in
/// the first octant: the case analysis of the module docs.
fn nearest_in_octant(e: &[f64], y: &[f64], x: &mut [f64]) {
    let last = e.len() - 1;
    if last == 0 {
        x[0] = e[0];
        return;
    }
    if y[last] > 0.0 {
        // the axes with yᵢ = 0 have xᵢ = 0; the others (the smallest axis among them) by the root
        let mut es = [0.0; 3];
        let mut ys = [0.0; 3];
        let mut at = [0usize; 3];
        let mut n = 0;
        for i in 0..=last {
            x[i] = 0.0;
            if y[i] > 0.0 {
                (es[n], ys[n], at[n]) = (e[i], y[i], i);
                n += 1;
            }
        }
        let mut xs = [0.0; 3];
        lagrange_root_point(&es[..n], &ys[..n], &mut xs[..n]);
        for k in 0..n {
            x[at[k]] = xs[k];
        }
        return;
    }
    // y on the plane of the larger axes: off it where t = −e_last² is feasible
    let e_last = e[last];
    let mut sum = 0.0;
    let mut feasible = true;
    for i in 0..last {
        x[i] = 0.0;
        if y[i] > 0.0 {
            let (numer, denom) = (e[i] * y[i], (e[i] - e_last) * (e[i] + e_last));
            if !(numer < denom) {
                feasible = false;
                break;
            }
            let ratio = numer / denom;
            x[i] = e[i] * ratio;
            sum += ratio * ratio;
        }
    }
    if feasible && sum < 1.0 {
        x[last] = e_last * (1.0 - sum).sqrt();
        return;
    }
    x[last] = 0.0;
    nearest_in_octant(&e[..last], &y[..last], &mut x[..last]);
}

/// `xᵢ = ρᵢyᵢ/(σ + δᵢ)` at the root `σ` of `G(σ) = Σ (ρᵢzᵢ/(σ + δᵢ))² − 1` (module docs), for
/// semi-axes `e` sorted decreasing and every `yᵢ > 0`; bisection on the bracket until the
/// midpoint rounds to one of its ends.
fn lagrange_root_point(e: &[f64], y: &[f64], x: &mut [f64]) {
    let n = e.len();
    let e_min = e[n - 1];
    if n == 1 {
        x[0] = e[0];
        return;
    }
    let (mut z, mut ratio, mut delta, mut rz) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
    for i in 0..n {
        z[i] = y[i] / e[i];
        let r = e[i] / e_min;
        ratio[i] = r * r;
        delta[i] = (e[i] - e_min) / e_min * ((e[i] + e_min) / e_min);
        rz[i] = ratio[i] * z[i];
    }
    let length = |v: &[f64]| {
        let big = v.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        if big == 0.0 || !big.is_finite() {
            return big;
        }
        v.iter().map(|a| (a / big) * (a / big)).sum::<f64>().sqrt() * big
    };
    let g = |sigma: f64| (0..n).map(|i| (rz[i] / (sigma + delta[i])).powi(2)).sum::<f64>() - 1.0;
    let mut lo = z[n - 1];
    let mut hi = if length(&z[..n]) < 1.0 { 1.0 } else { length(&rz[..n]) };
    let mut sigma = lo;
    // at most ~2100 halvings reach adjacent doubles from any finite bracket
    for _ in 0..2200 {
        sigma = 0.5 * (lo + hi);
        if sigma == lo || sigma == hi {
            break;
        }
        let value = g(sigma);
        if value > 0.0 {
            lo = sigma;
        } else if value < 0.0 {
            hi = sigma;
        } else {
            break;
        }
    }
    for i in 0..n {
        x[i] = ratio[i] * y[i] / (sigma + delta[i]);
    }
}

impl Intersect for Ellipsoid {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Ellipsoid, ray: &Ray, range: Interval) -> Option<RawHit> {
            let local = Ray::new(
                this.unit_space(ray.origin),
                this.local_from_world * ray.dir / this.radii,
            );
            this.unit.intersect(&local, range)
        }
        crate::with_fma!(test(this: &Ellipsoid = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        let s = self.unit_space(ray.origin) + raw.t * (self.local_from_world * ray.dir / self.radii);
        self.normal_direction(s).normalize_or_zero()
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(self.uv(ray.at(raw.t)))
    }
}

impl Parametric for Ellipsoid {
    fn point(&self, uv: DVec2) -> DVec3 {
        self.center + self.world_from_local * (self.radii * self.unit.point(uv))
    }

    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let (du, dv) = self.unit.partials(uv);
        (
            self.world_from_local * (self.radii * du),
            self.world_from_local * (self.radii * dv),
        )
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        self.unit.uv(self.unit_space(p).normalize_or_zero())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(e: &Ellipsoid, ray: Ray) -> Option<(f64, DVec3)> {
        e.intersect(&ray, Interval::POSITIVE)
            .map(|h| (h.t, e.normal_at(&ray, &h)))
    }

    #[test]
    fn rejects_bad_parameters() {
        let make = |r: DVec3, q: DQuat| Ellipsoid::new(DVec3::ZERO, r, q);
        assert!(make(DVec3::ONE, DQuat::IDENTITY).is_ok());
        assert!(make(DVec3::new(1.0, 0.0, 1.0), DQuat::IDENTITY).is_err());
        assert!(make(DVec3::new(1.0, 1.0, -1.0), DQuat::IDENTITY).is_err());
        assert!(make(DVec3::new(f64::NAN, 1.0, 1.0), DQuat::IDENTITY).is_err());
        assert!(
            make(DVec3::ONE, DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0)).is_err(),
            "not unit"
        );
        assert!(make(DVec3::ONE, DQuat::from_xyzw(0.0, 0.0, f64::NAN, 1.0)).is_err());
        assert!(
            make(DVec3::ONE, DQuat::from_xyzw(0.0, 0.0, 0.0, 1.0 + 1e-9)).is_ok(),
            "rounding is tolerated"
        );
        assert!(Ellipsoid::new(DVec3::INFINITY, DVec3::ONE, DQuat::IDENTITY).is_err());
    }

    #[test]
    fn axis_hits_are_exact() {
        let e = Ellipsoid::new(DVec3::new(1.0, 0.0, 0.0), DVec3::new(3.0, 2.0, 1.0), DQuat::IDENTITY).unwrap();
        assert_eq!(
            hit(&e, Ray::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::X)),
            Some((3.0, -DVec3::X))
        );
        assert_eq!(
            hit(&e, Ray::new(DVec3::new(1.0, 0.0, 5.0), -DVec3::Z)),
            Some((4.0, DVec3::Z))
        );
        assert_eq!(
            hit(&e, Ray::new(DVec3::new(1.0, 0.0, 0.0), DVec3::Y)),
            Some((2.0, DVec3::Y))
        );
        assert_eq!(e.phi(DVec3::new(7.0, 0.0, 0.0)), 1.0, "(|s| − 1)·min r = (2 − 1)·1");
        // rotated a quarter turn about Z: the long local X axis lies along world Y
        let q = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
        let e = Ellipsoid::new(DVec3::ZERO, DVec3::new(3.0, 1.0, 1.0), q).unwrap();
        let (t, n) = hit(&e, Ray::new(DVec3::new(0.0, -10.0, 0.0), DVec3::Y)).unwrap();
        // (the quarter-turn quaternion is itself rounded, so allow a few ulp)
        assert!((t - 7.0).abs() < 1e-14 && (n + DVec3::Y).length() < 1e-14, "{t} {n}");
    }

    #[test]
    fn radii_ratio_1e4_keeps_precision() {
        let e = Ellipsoid::new(DVec3::ZERO, DVec3::new(1e4, 1.0, 1.0), DQuat::IDENTITY).unwrap();
        // along the long axis from far away: t = 10⁶ − 10⁴ exactly
        let (t, n) = hit(&e, Ray::new(DVec3::new(-1e6, 0.0, 0.0), DVec3::X)).unwrap();
        assert_eq!((t, n), (990_000.0, -DVec3::X));
        // across the thin axis at x = 5000: y = −√(1 − 1/4), t = 10⁵ − √0.75
        let (t, n) = hit(&e, Ray::new(DVec3::new(5e3, -1e5, 0.0), DVec3::Y)).unwrap();
        let expect = 1e5 - 0.75f64.sqrt();
        assert!((t - expect).abs() <= 2e-11, "t − expected = {:e}", t - expect);
        // the normal ∝ (x/a², y/b², z/c²) = (5·10⁻⁵, −√0.75, 0)
        let exact = DVec3::new(5e3 / 1e8, -(0.75f64.sqrt()), 0.0).normalize();
        assert!((n - exact).length() < 1e-15, "{n}");
    }

    #[test]
    fn rotated_thin_ellipsoid_hits_constructed_surface_points() {
        // radii ratio 10⁴, arbitrary orientation. Independent reference: points built on the
        // surface as c + R(r ⊙ s) with |s| = 1, and rays aimed at them from 7 units away along
        // an inward direction, so the exact first hit is t = 7 (up to the rounding of the
        // construction) and the normal is R(s ⊘ r) normalised.
        let q = DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 0.7);
        let (c, r) = (DVec3::new(2.0, -1.0, 3.0), DVec3::new(1e-2, 1e2, 1.0));
        let e = Ellipsoid::new(c, r, q).unwrap();
        let rot = DMat3::from_quat(q);
        let (mut worst_t, mut worst_n) = (0.0f64, 0.0f64);
        for i in 0..40 {
            let (theta, phi) = (0.1 + 0.075 * f64::from(i), 0.9 * f64::from(i));
            let s = DVec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            let p = c + rot * (r * s);
            let n = (rot * (s / r)).normalize();
            let dir = (0.5 * n.any_orthonormal_vector() - n).normalize();
            let (t, normal) = hit(&e, Ray::new(p - 7.0 * dir, dir)).unwrap();
            worst_t = worst_t.max((t - 7.0).abs());
            worst_n = worst_n.max((normal - n).length());
        }
        eprintln!("thin ellipsoid: largest |t − 7| {worst_t:e}, largest normal error {worst_n:e}");
        assert!(worst_t < 1e-13, "largest t error {worst_t:e}");
        assert!(worst_n < 1e-12, "largest normal error {worst_n:e}");
    }

    #[test]
    fn thin_ellipsoid_agrees_with_the_textbook_world_space_quadric() {
        // the same ellipsoid against (p − c)ᵀ M (p − c) = 1 solved by the textbook formula on
        // well-conditioned rays; M's entries span r⁻² = 10⁻⁴ … 10⁴, which costs the reference
        // itself up to ~3·10⁻¹³ relative (a 50-digit evaluation put the closed form at ≤ 2·10⁻¹⁵)
        let q = DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 0.7);
        let (c, r) = (DVec3::new(2.0, -1.0, 3.0), DVec3::new(1e-2, 1e2, 1.0));
        let e = Ellipsoid::new(c, r, q).unwrap();
        let rot = DMat3::from_quat(q);
        let m = rot * DMat3::from_diagonal(DVec3::ONE / (r * r)) * rot.transpose();
        for (i, offset) in [-0.5, -0.2, 0.0, 0.3, 0.6].into_iter().enumerate() {
            let target = c + rot * DVec3::new(0.0, 40.0 * offset, 0.2 * offset);
            let dir = DVec3::new(0.3, 1.0 + 0.1 * i as f64, -0.4).normalize();
            let origin = target - 7.0 * dir;
            let f = origin - c;
            let (a, b, cc) = (dir.dot(m * dir), dir.dot(m * f), f.dot(m * f) - 1.0);
            let reference = (-b - (b * b - a * cc).sqrt()) / a;
            let (t, _) = hit(&e, Ray::new(origin, dir)).unwrap();
            assert!((t - reference).abs() < 1e-12 * reference, "t {t} reference {reference}");
        }
    }

    #[test]
    fn bounds_are_tight() {
        let q = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_4);
        let e = Ellipsoid::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 0.5), q).unwrap();
        let b = e.bounds();
        // x reach of the rotated ellipse: √((2·cos45°)² + (1·sin45°)²) = √2.5
        assert!(
            (b.max - DVec3::new(2.5f64.sqrt(), 2.5f64.sqrt(), 0.5)).length() < 1e-15,
            "{b:?}"
        );
        let p = e.point(DVec2::new(0.125, 0.5));
        assert!(e.phi(p).abs() < 1e-15 && b.contains(p));
    }
}
