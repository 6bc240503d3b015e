//! Sphere.
//!
//! | field    | meaning            | constraint        |
//! |----------|--------------------|-------------------|
//! | `center` | centre `c`         | finite            |
//! | `radius` | radius `r`         | finite, `> 0`     |
//!
//! - **Φ(p) = |p − c| − r**, the signed distance (Lipschitz bound 1); **∇Φ = (p − c)/|p − c|**.
//! - **Parametric form** (`u, v ∈ [0, 1]`, poles on the ±Y axis, seam at `u = 0` on the +X side):
//!   `φ = 2πu`, `θ = πv`, `p(u, v) = c + r·(sin θ cos φ, cos θ, sin θ sin φ)`; `v = 0` is the north
//!   pole (+Y). `∂p/∂u × ∂p/∂v` points outward.
//! - **Intersection**: the quadratic `a t² + 2b t + c₀ = 0` with `f = o − c`, `a = d·d`, `b = f·d`,
//!   `c₀ = f·f − r²`, solved as in Haines et al., "Precision Improvements for Ray/Sphere
//!   Intersection" (Ray Tracing Gems, 2019): the discriminant is `a·r² − |f × d|²` (no cancellation
//!   of two large terms for a small, distant sphere), the root away from `−b` is
//!   `q = −(b + sign(b)·√disc)`, and the roots are `q/a` and `c₀/q` (no cancellation for the near
//!   root of a huge sphere seen from close). All in f64, with compensated sums of products
//!   (`b`, `c₀ = |f|² − r²` and the discriminant, [`crate::math::sum_of_products`]) and an
//!   accurate cross product, so neither a far tiny sphere, nor an origin close to a huge one, nor
//!   a grazing ray loses more than a few f64 ulp (measured in `tests/hard_cases.rs`).
//! - **Closest point**: the radial projection `q = c + r·(p − c)/|p − c|`, at distance
//!   `| |p − c| − r |`, exact to rounding. At the centre every surface point is nearest (at
//!   distance `r`); the north pole `c + r·ŷ` is returned.

use crate::bounds::Aabb;
use crate::error::{require_finite, require_positive, PrimitiveError};
use crate::hit::RawHit;
use crate::math::{
    cross_accurate, is_square_safe, length_scaled, normalize_scaled, power_of_two_scale, sum_of_products, two_sum,
};
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric};
use glam::{DVec2, DVec3};
use std::f64::consts::{PI, TAU};

/// Relative distance from zero (64ε) beyond which the fast path of [`Sphere::roots`] trusts the
/// sign of its discriminant.
const SIGN_MARGIN: f64 = 64.0 * f64::EPSILON;

/// Fraction (2⁻⁸) of its operands that `c₀ = |f|² − r²` must keep for the fast path.
const C0_MARGIN: f64 = 1.0 / 256.0;

/// `ε / 2⁻⁴⁰`: the fast path needs `ε·scale / (√disc·|q|) < 2⁻⁴⁰`.
const Q_ERROR_MARGIN: f64 = f64::EPSILON * 1_099_511_627_776.0;

/// Squared distance, in squared radii, beyond which [`Sphere::roots`] always takes the
/// compensated path (1024 radii).
const FAR_RADII: f64 = 1024.0 * 1024.0;

/// A sphere of radius `radius` around `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    center: DVec3,
    radius: f64,
}

impl Sphere {
    /// A sphere; errors on a non-finite centre or a radius that is not finite and positive.
    pub fn new(center: DVec3, radius: f64) -> Result<Self, PrimitiveError> {
        Ok(Self {
            center: require_finite("Sphere", "center", center)?,
            radius: require_positive("Sphere", "radius", radius)?,
        })
    }

    /// Centre.
    #[must_use]
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// Radius.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Both roots of the ray's quadratic in increasing order, or `None` if the ray misses.
    ///
    /// Magnitudes whose squares or products would overflow or underflow (a radius or distance
    /// beyond `2^±240` ≈ `10^±72`, a direction length likewise) are scaled first: `o`, `c` and `r`
    /// by a power of two `s` near `max(|o − c|, r)`, the direction by one `k` near `|d|`, all
    /// exact, and the roots `t'` of the scaled ray mapped back by `t = t'·s/k`.
    #[inline(always)]
    #[must_use]
    pub fn roots(&self, ray: &Ray) -> Option<(f64, f64)> {
        let size = (ray.origin - self.center).abs().max_element().max(self.radius);
        let dir_size = ray.dir.abs().max_element();
        if is_square_safe(size) && is_square_safe(dir_size) {
            return self.roots_in_range(ray);
        }
        // o − c may itself overflow: then the operands' own size
        let size = if size.is_finite() {
            size
        } else {
            ray.origin.abs().max_element().max(self.center.abs().max_element())
        };
        let (s, k) = (power_of_two_scale(size), power_of_two_scale(dir_size));
        let scaled = Self {
            center: self.center / s,
            radius: self.radius / s,
        };
        let (t0, t1) = scaled.roots_in_range(&Ray::new(ray.origin / s, ray.dir / k))?;
        let back = |t: f64| if s >= k { t * (s / k) } else { t / (k / s) };
        Some((back(t0), back(t1)))
    }

    /// [`Sphere::roots`] for magnitudes whose squares are safe.
    #[inline(always)]
    fn roots_in_range(&self, ray: &Ray) -> Option<(f64, f64)> {
        // Fast path in plain f64 (with an FMA cross product), taken where its rounding provably
        // cannot matter, else the compensated path below. With the cross product rounded once per
        // component, `disc = a·r² − |f × d|²` is within ~4ε·(a·r² + |f × d|²) of exact, so its
        // sign is certain beyond 64ε of that scale; `q = −(b + sign(b)·√disc)` adds two terms of
        // one sign, and its relative error, about ε·scale / (2√disc·|q|), is kept below 2⁻⁴⁰;
        // `c₀ = |f|² − r²` must keep 2⁻⁸ of its operands (the origin is not near the surface), and
        // the origin must lie within 1024 radii (beyond, the rounding of t along the ray,
        // amplified by |f|/r, would dominate the normal).
        let f = ray.origin - self.center;
        let d = ray.dir;
        let r2 = self.radius * self.radius;
        let a = d.length_squared();
        if !(a > 0.0 && a.is_finite()) {
            return self.roots_compensated(ray);
        }
        let ar2 = a * r2;
        let ww = cross_accurate(f, d).length_squared();
        let disc = ar2 - ww;
        let scale = ar2 + ww;
        if disc < -SIGN_MARGIN * scale {
            return None; // certainly no real root
        }
        let ff = f.length_squared();
        let c0 = ff - r2;
        if disc > SIGN_MARGIN * scale && c0.abs() > (ff + r2) * C0_MARGIN && ff < r2 * FAR_RADII {
            let b = f.dot(d);
            let root = disc.sqrt();
            let q = -(b + root.copysign(b));
            if scale * Q_ERROR_MARGIN < root * q.abs() {
                let (t0, t1) = (c0 / q, q / a);
                return Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) });
            }
        }
        self.roots_compensated(ray)
    }

    /// [`Sphere::roots`] with compensated arithmetic throughout.
    fn roots_compensated(&self, ray: &Ray) -> Option<(f64, f64)> {
        // f = o − c split exactly into f + f_lo (two-sum): an origin close to a huge sphere keeps
        // its height above the surface even where o − c rounds
        let (fx, lx) = two_sum(ray.origin.x, -self.center.x);
        let (fy, ly) = two_sum(ray.origin.y, -self.center.y);
        let (fz, lz) = two_sum(ray.origin.z, -self.center.z);
        let (f, lo) = (DVec3::new(fx, fy, fz), DVec3::new(lx, ly, lz));
        let d = ray.dir;
        let r = self.radius;
        let a = d.length_squared();
        if !(a > 0.0) {
            // a zero direction, or one whose square underflows (|d| < 1.5e-162): no usable ray
            return None;
        }
        let b = sum_of_products([(f.x, d.x), (f.y, d.y), (f.z, d.z), (lo.dot(d), 1.0)]);
        // |f|² − r² compensated: the near root c₀/q of a huge sphere seen from close keeps full
        // precision (plain f64 loses r/(2h) ulps for an origin at height h)
        let c0 = sum_of_products([
            (f.x, f.x),
            (f.y, f.y),
            (f.z, f.z),
            (r, -r),
            (2.0 * f.x, lo.x),
            (2.0 * f.y, lo.y),
            (2.0 * f.z, lo.z),
        ]);
        // a·r² − |f × d|² with an accurate cross product (a tiny distant sphere's f × d nearly
        // cancels component by component) and a compensated difference near tangency
        let w = cross_accurate(f, d) + lo.cross(d);
        let dr = d * r;
        let disc = sum_of_products([
            (dr.x, dr.x),
            (dr.y, dr.y),
            (dr.z, dr.z),
            (w.x, -w.x),
            (w.y, -w.y),
            (w.z, -w.z),
        ]);
        if !(disc >= 0.0) {
            return None;
        }
        let q = -(b + disc.sqrt().copysign(b));
        if q == 0.0 {
            // b = 0 and disc = 0: the ray grazes with the tangent point at its origin
            return Some((0.0, 0.0));
        }
        let (t0, t1) = (c0 / q, q / a);
        Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) })
    }
}

impl Implicit for Sphere {
    fn phi(&self, p: DVec3) -> f64 {
        length_scaled(p - self.center) - self.radius
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        normalize_scaled(p - self.center)
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(
            self.center - DVec3::splat(self.radius),
            self.center + DVec3::splat(self.radius),
        )
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    /// The radial projection of `p` (module docs); the north pole from the centre.
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let v = p - self.center;
        let len = length_scaled(v);
        let q = if len > 0.0 {
            self.center + v * (self.radius / len)
        } else {
            self.center + DVec3::new(0.0, self.radius, 0.0)
        };
        Some(Closest::exact(p, q, 0))
    }
}

impl Intersect for Sphere {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Sphere, ray: &Ray, range: Interval) -> Option<RawHit> {
            let (t0, t1) = this.roots(ray)?;
            if range.contains(t0) {
                Some(RawHit::at(t0))
            } else if range.contains(t1) {
                Some(RawHit::at(t1))
            } else {
                None
            }
        }
        crate::with_fma!(test(this: &Sphere = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    /// From `(o − c) + t·d` with one rounding per component (exact two-sum of `o − c`, fused
    /// multiply-add), not from the rounded hit point: a tiny sphere far from the origin keeps its
    /// normal to ~10⁻⁹ rad instead of `ε·|p|/r`.
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        let local = |o: f64, c: f64, d: f64| {
            let (f, lo) = two_sum(o, -c);
            raw.t.mul_add(d, f) + lo
        };
        let o = ray.origin;
        normalize_scaled(DVec3::new(
            local(o.x, self.center.x, ray.dir.x),
            local(o.y, self.center.y, ray.dir.y),
            local(o.z, self.center.z, ray.dir.z),
        ))
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(self.uv(ray.at(raw.t)))
    }

    /// The sphere itself.
    fn bounding_ball(&self) -> Option<(DVec3, f64)> {
        Some((self.center, self.radius))
    }
}

impl Parametric for Sphere {
    fn point(&self, uv: DVec2) -> DVec3 {
        let (sin_phi, cos_phi) = (TAU * uv.x).sin_cos();
        let (sin_theta, cos_theta) = (PI * uv.y).sin_cos();
        self.center + self.radius * DVec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
    }

    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let (sin_phi, cos_phi) = (TAU * uv.x).sin_cos();
        let (sin_theta, cos_theta) = (PI * uv.y).sin_cos();
        let r = self.radius;
        (
            TAU * r * sin_theta * DVec3::new(-sin_phi, 0.0, cos_phi),
            PI * r * DVec3::new(cos_theta * cos_phi, -sin_theta, cos_theta * sin_phi),
        )
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        let q = (p - self.center) / self.radius;
        let mut u = q.z.atan2(q.x) / TAU;
        if u < 0.0 {
            u += 1.0;
        }
        DVec2::new(u, q.y.clamp(-1.0, 1.0).acos() / PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_radius() {
        assert!(Sphere::new(DVec3::ZERO, 0.0).is_err());
        assert!(Sphere::new(DVec3::ZERO, -1.0).is_err());
        assert!(Sphere::new(DVec3::ZERO, f64::NAN).is_err());
        assert!(Sphere::new(DVec3::new(f64::INFINITY, 0.0, 0.0), 1.0).is_err());
    }

    #[test]
    fn head_on_hit_is_exact() {
        let s = Sphere::new(DVec3::new(0.0, 0.0, 10.0), 2.0).unwrap();
        let ray = Ray::new(DVec3::ZERO, DVec3::Z);
        let hit = s.intersect(&ray, Interval::POSITIVE).unwrap();
        assert_eq!(hit.t, 8.0);
        assert_eq!(s.normal_at(&ray, &hit), -DVec3::Z);
        // from inside, the far wall
        let inside = Ray::new(DVec3::new(0.0, 0.0, 10.0), DVec3::Z);
        assert_eq!(s.intersect(&inside, Interval::POSITIVE).unwrap().t, 2.0);
    }

    #[test]
    fn tiny_far_sphere_keeps_precision() {
        // r = 1e-3 at distance 1e4: t = 1e4 − 1e-3 exactly representable to ~1e-12
        let s = Sphere::new(DVec3::new(0.0, 0.0, 1e4), 1e-3).unwrap();
        let t = s
            .intersect(&Ray::new(DVec3::ZERO, DVec3::Z), Interval::POSITIVE)
            .unwrap()
            .t;
        assert!((t - (1e4 - 1e-3)).abs() < 1e-11, "t = {t}");
    }
}
