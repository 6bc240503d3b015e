//! Infinite plane.
//!
//! | field    | meaning                          | constraint          |
//! |----------|----------------------------------|---------------------|
//! | `normal` | normal `n` (normalised on input) | finite, non-zero    |
//! | `offset` | `d` in `⟨p, n⟩ = d`              | finite              |
//!
//! - **Φ(p) = ⟨p, n⟩ − d** (signed distance; positive on the side `n` points to); **∇Φ = n**.
//!   A non-unit `n` given on input is normalised together with `d`, leaving the plane unchanged.
//! - **Parametric form**: plane coordinates `p(u, v) = d·n + u·e₁ + v·e₂` with `(e₁, e₂, n)` the
//!   right-handed basis of [`orthonormal_basis`]; `u, v ∈ (−∞, ∞)`; `e₁ × e₂ = n`.
//! - **Intersection**: `t = (d − ⟨o, n⟩) / ⟨dir, n⟩` with the normal and offset as given
//!   (not normalised) and both sums of products compensated ([`crate::math::sum_of_products`]). A ray parallel to the plane
//!   (`⟨dir, n⟩ = 0`), including one lying in it, misses.
//! - **Closest point**: the orthogonal projection `q = p − Φ(p)·n`, at distance `|Φ(p)|`, exact
//!   to rounding.

use crate::bounds::Aabb;
use crate::error::{require_direction, PrimitiveError};
use crate::hit::RawHit;
use crate::math::dot_minus;
use crate::math::orthonormal_basis;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};

/// The plane `⟨p, n⟩ = d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    normal: DVec3,
    offset: f64,
    e1: DVec3,
    e2: DVec3,
    /// The normal and offset as given (unnormalised): `t` is computed from them, so that the
    /// rounding of the normalisation does not limit nearly parallel rays.
    input: (DVec3, f64),
}

impl Plane {
    /// The plane `⟨p, normal⟩ = offset`; errors on a zero or non-finite normal or offset.
    pub fn new(normal: DVec3, offset: f64) -> Result<Self, PrimitiveError> {
        if !offset.is_finite() {
            return Err(PrimitiveError::new(
                "Plane",
                "offset",
                format!("must be finite, got {offset}"),
            ));
        }
        let length = normal.length();
        let n = require_direction("Plane", "normal", normal)?;
        let (e1, e2) = orthonormal_basis(n);
        Ok(Self {
            normal: n,
            offset: offset / length,
            e1,
            e2,
            input: (normal, offset),
        })
    }

    /// The plane through `point` with normal `normal`.
    pub fn through(point: DVec3, normal: DVec3) -> Result<Self, PrimitiveError> {
        let n = require_direction("Plane", "normal", normal)?;
        Self::new(n, point.dot(n))
    }

    /// Unit normal.
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Offset `d` (signed distance of the plane from the origin along the normal).
    #[must_use]
    pub fn offset(&self) -> f64 {
        self.offset
    }
}

impl Implicit for Plane {
    fn phi(&self, p: DVec3) -> f64 {
        p.dot(self.normal) - self.offset
    }

    fn gradient(&self, _p: DVec3) -> DVec3 {
        self.normal
    }

    fn bounds(&self) -> Aabb {
        Aabb::EVERYTHING
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    /// The orthogonal projection `p − Φ(p)·n` (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        Some(Closest::exact(p, p - self.phi(p) * self.normal, 0))
    }
}

impl Intersect for Plane {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Plane, ray: &Ray, range: Interval) -> Option<RawHit> {
            // both with the input normal and compensated sums: ⟨d, n⟩ keeps its relative precision
            // for a nearly parallel ray, ⟨o, n⟩ − d for an origin close to the plane
            let (n, offset) = this.input;
            let denom = dot_minus(ray.dir, n, 0.0);
            if denom == 0.0 {
                return None;
            }
            let t = -dot_minus(ray.origin, n, offset) / denom;
            range.contains(t).then(|| RawHit::at(t))
        }
        crate::with_fma!(test(this: &Plane = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    fn normal_at(&self, _ray: &Ray, _raw: &RawHit) -> DVec3 {
        self.normal
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(self.uv(ray.at(raw.t)))
    }
}

impl Parametric for Plane {
    fn domain(&self) -> UvDomain {
        UvDomain {
            u: (f64::NEG_INFINITY, f64::INFINITY),
            v: (f64::NEG_INFINITY, f64::INFINITY),
        }
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        self.offset * self.normal + uv.x * self.e1 + uv.y * self.e2
    }

    fn partials(&self, _uv: DVec2) -> (DVec3, DVec3) {
        (self.e1, self.e2)
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        let q = p - self.offset * self.normal;
        DVec2::new(q.dot(self.e1), q.dot(self.e2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_ray_misses_and_non_unit_normal_is_normalised() {
        let p = Plane::new(DVec3::new(0.0, 2.0, 0.0), 2.0).unwrap();
        assert_eq!(p.offset(), 1.0);
        assert!(p
            .intersect(&Ray::new(DVec3::new(0.0, 1.0, 0.0), DVec3::X), Interval::POSITIVE)
            .is_none());
        let hit = p
            .intersect(&Ray::new(DVec3::new(0.0, 3.0, 0.0), -DVec3::Y), Interval::POSITIVE)
            .unwrap();
        assert_eq!(hit.t, 2.0);
        assert!(Plane::new(DVec3::ZERO, 1.0).is_err());
    }
}
