//! Where a secondary ray (shadow, reflection) starts: an error-bound offset, not a magic epsilon.
//!
//! A hit point `p = o + t·d` is computed in f64 and differs from the exact surface point by
//! rounding: of the primitive's own arithmetic (which works with numbers as large as its
//! coordinates), of the sum `o + t·d`, and, under a [`crate::Transformed`], of the maps into and
//! out of local space. [`crate::Intersect::hit_error`] returns a bound `δ` on that distance for a
//! hit, built from
//!
//! - [`point_error_bound`]: `γ₃₂·(‖o‖∞ + ‖t·d‖∞ + m)`, `m` the largest coordinate magnitude the
//!   primitive works with (its bounds' [`magnitude`]); `γₙ = nε/(1 − nε)` with `ε = 2⁻⁵³`. The
//!   closed forms need about `γ₈`; the factor 4 is margin (a shadow ray loses nothing visible
//!   by starting `10⁻¹⁴` relative further out).
//! - under a transform, the local bound times `‖world_from_local‖_F` plus the rounding of the
//!   transform itself, `γ₃₂·κ_F·(‖p‖∞ + ‖o‖∞ + ‖translation‖∞)` with `κ_F = ‖W‖_F·‖W⁻¹‖_F`.
//!
//! [`offset_origin`] then moves `p` by `δ` along the unit normal **on the side the arriving ray
//! came from** (the viewer-facing normal) and rounds each component one ulp further away. The
//! new origin lies strictly on that side, beyond the rounding of the re-intersection, so
//!
//! - a ray leaving the surface towards that side never re-hits it at `t ≈ 0` (no self-hit), and
//! - a ray crossing the surface (going to the other side) meets it at `t ≈ δ / |cos θ|`: it is
//!   not lost (shadow rays towards a light behind the surface are blocked by it).
//!
//! Measured over ≥ 100k rays per primitive type in `primitives/tests/hard_cases.rs`
//! (`recast_*` tests), including transforms with translation `10⁵` and scales `10⁻³…10³`; see
//! `docs/numerics.md`.

use crate::bounds::Aabb;
use crate::math::gamma;
use crate::ray::Ray;
use glam::DVec3;

/// How many rounded operations' worth of relative error the offset covers (`γ₃₂ ≈ 3.6·10⁻¹⁵`).
pub const OFFSET_GAMMA: u32 = 32;

/// The largest coordinate magnitude in `bounds`, or 0 for unbounded (infinite) bounds, whose
/// closed forms (planes) only work with numbers no larger than the hit point's.
#[must_use]
pub fn magnitude(bounds: &Aabb) -> f64 {
    if bounds.is_finite() {
        bounds.min.abs().max(bounds.max.abs()).max_element()
    } else {
        0.0
    }
}

/// `γ₃₂·(‖o‖∞ + ‖t·d‖∞ + magnitude)`: a bound on the distance of `ray.at(t)` from the surface a
/// closed form computing with numbers up to `magnitude` found at `t`.
#[must_use]
pub fn point_error_bound(ray: &Ray, t: f64, magnitude: f64) -> f64 {
    gamma(OFFSET_GAMMA) * (ray.origin.abs().max_element() + (t * ray.dir).abs().max_element() + magnitude)
}

/// The next representable value after `x` away from zero direction `towards` (by sign).
fn step_towards(x: f64, towards: f64) -> f64 {
    if towards == 0.0 || !x.is_finite() {
        return x;
    }
    if x == 0.0 {
        return f64::from_bits(1).copysign(towards);
    }
    let bits = x.to_bits();
    // moving away from zero increments the magnitude bits; towards zero decrements them
    if (x > 0.0) == (towards > 0.0) {
        f64::from_bits(bits + 1)
    } else {
        f64::from_bits(bits - 1)
    }
}

/// `point` moved by `error_bound` along the unit `normal`, each component then rounded one ulp
/// further in the normal's direction, so the result lies at least `error_bound` from the exact
/// surface point on the `normal` side. Pass the normal facing the side the new ray should start
/// on (for shadow rays the viewer-facing normal, [`crate::SurfaceHit::facing_normal`]).
#[must_use]
pub fn offset_origin(point: DVec3, normal: DVec3, error_bound: f64) -> DVec3 {
    let p = point + error_bound * normal;
    DVec3::new(
        step_towards(p.x, normal.x),
        step_towards(p.y, normal.y),
        step_towards(p.z, normal.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_away_moves_one_ulp_in_the_normal_direction() {
        assert_eq!(step_towards(1.0, 1.0), 1.0 + f64::EPSILON);
        assert_eq!(step_towards(1.0, -1.0), 1.0 - f64::EPSILON / 2.0);
        assert_eq!(step_towards(-1.0, -1.0), -1.0 - f64::EPSILON);
        assert_eq!(step_towards(0.0, -1.0), -f64::from_bits(1));
        assert_eq!(step_towards(3.0, 0.0), 3.0);
        let p = offset_origin(DVec3::new(1e5, 0.0, -2.0), DVec3::X, 1e-10);
        assert!(p.x > 1e5 + 1e-10 * 0.99 && p.y == 0.0 && p.z == -2.0, "{p}");
    }

    #[test]
    fn bound_scales_with_the_numbers_involved() {
        let ray = Ray::new(DVec3::new(0.0, 0.0, -1e4), DVec3::Z);
        let near = point_error_bound(&ray, 1e4, 1e-3);
        assert!(near > 1e4 * f64::EPSILON && near < 1e4 * 1e-13, "{near:e}");
        assert_eq!(magnitude(&Aabb::EVERYTHING), 0.0);
    }
}
