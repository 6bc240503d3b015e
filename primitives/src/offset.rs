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
//!
//! # Spawning from a point known only approximately
//! [`spawn_origin`] generalises this to a point the caller got from elsewhere (a float32 EXR, a
//! CSV written as float32, another program) with its [`PointPrecision`]: `f32`, `f64` or an
//! explicit absolute error bound `E`. With `δₚ` the point's error bound
//! ([`PointPrecision::error_bound`]) and `δᵣ = γ₃₂·(‖p‖∞ + m)` the rounding of re-intersecting a
//! surface whose closed form computes with numbers up to `m` from an origin of magnitude `‖p‖∞`
//! (as in [`point_error_bound`] at `t = 0`), the origin is `p` moved by `D = 2δₚ + δᵣ` along the
//! unit normal on the side the new ray leaves to, each component rounded one ulp further.
//!
//! **Claim.** If the exact surface point `s` has `|p − s| ≤ δₚ` and the surface is its tangent
//! plane within `D` of `s` (curvature radius ≫ `D`), then (1) the origin `o` is at a distance
//! `≥ D − δₚ ≥ δₚ + δᵣ > δᵣ` from the surface on the leaving side, and every point `o + t·d`,
//! `t > 0`, of a ray leaving to that side (`d·n > 0`) is farther still, so no rounding of size
//! `δᵣ` can produce a hit on that surface near `t = 0` (**no self-hit**); (2) `|o − p| ≤ D + 3`
//! ulps, so any other surface farther than [`spawn_distance`] from `p` along the ray is still hit
//! (**no lost hit beyond the bound**). Shown on every built-in primitive from f32-rounded points at
//! scales `10⁻³…10⁵` and grazing angles in `primitives/tests/spawn.rs`.

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

/// [`point_error_bound`] plus `tolerance·|d|`: a bound for a point found by a root finder that
/// stops within `tolerance` (in `t`) of the root (a `Function`, a `FieldSurface`).
#[must_use]
pub fn root_error_bound(ray: &Ray, t: f64, magnitude: f64, tolerance: f64) -> f64 {
    // |d| without overflow for huge components
    let largest = ray.dir.abs().max_element();
    let length = if largest > 0.0 {
        largest * (ray.dir / largest).length()
    } else {
        0.0
    };
    point_error_bound(ray, t, magnitude) + tolerance * length
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

/// How precisely a point is known: the bound `δₚ` on its distance from the exact surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointPrecision {
    /// The exact point rounded to f64 after a computation of magnitude `‖p‖∞` (zeroset's own
    /// hit points, or CSV output printed in full): `δₚ = √3·γ₃₂·‖p‖∞`.
    F64,
    /// The exact point rounded to f32 (an EXR `P` channel, float32 output):
    /// `δₚ = √3·(2⁻²⁴ + γ₃₂)·‖p‖∞ + √3·2⁻¹⁴⁹` (half an f32 ulp per coordinate, relative, plus the
    /// f64 error the value had before rounding, plus the f32 subnormal spacing).
    F32,
    /// An absolute bound `E ≥ 0` supplied by the caller (for points of other or unknown origin).
    Absolute(f64),
}

impl PointPrecision {
    /// `δₚ` for the point `p` (see the variants).
    #[must_use]
    pub fn error_bound(&self, p: DVec3) -> f64 {
        let m = p.abs().max_element();
        let sqrt3 = 3f64.sqrt();
        match *self {
            PointPrecision::F64 => sqrt3 * gamma(OFFSET_GAMMA) * m,
            PointPrecision::F32 => sqrt3 * ((2f64.powi(-24) + gamma(OFFSET_GAMMA)) * m + 2f64.powi(-149)),
            PointPrecision::Absolute(e) => e,
        }
    }
}

impl std::str::FromStr for PointPrecision {
    type Err = String;

    /// `f32`, `f64`, or a finite number `E ≥ 0` (an absolute bound).
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "f32" => Ok(Self::F32),
            "f64" => Ok(Self::F64),
            other => match other.parse::<f64>() {
                Ok(e) if e.is_finite() && e >= 0.0 => Ok(Self::Absolute(e)),
                _ => Err(format!(
                    "expected `f32`, `f64` or an absolute error bound ≥ 0, got `{other}`"
                )),
            },
        }
    }
}

/// The offset `D = 2δₚ + γ₃₂·(‖p‖∞ + magnitude)` [`spawn_origin`] moves a point by (before the
/// final one-ulp rounding of each component). `magnitude` is the largest coordinate magnitude the
/// surfaces' closed forms compute with ([`magnitude`] of their bounds; 0 for planes).
#[must_use]
pub fn spawn_distance(point: DVec3, precision: PointPrecision, magnitude: f64) -> f64 {
    2.0 * precision.error_bound(point) + gamma(OFFSET_GAMMA) * (point.abs().max_element() + magnitude)
}

/// A ray origin for a ray leaving the surface through `point` in direction `dir`, where `point`
/// is known to `precision` and `normal` is the surface normal there (either orientation; unit or
/// not, non-zero): `point` moved by [`spawn_distance`] along the normal on the side `dir` points
/// to, rounded away (see the module docs for what is guaranteed). A `dir` tangent to the surface
/// leaves on the side `normal` points to. Returns `point` unchanged for a zero or non-finite
/// normal.
#[must_use]
pub fn spawn_origin(point: DVec3, normal: DVec3, dir: DVec3, precision: PointPrecision, magnitude: f64) -> DVec3 {
    let n = normal.normalize_or_zero();
    if n == DVec3::ZERO {
        return point;
    }
    let n = if dir.dot(n) < 0.0 { -n } else { n };
    offset_origin(point, n, spawn_distance(point, precision, magnitude))
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
    fn spawn_moves_to_the_leaving_side_by_the_stated_distance() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        let n = DVec3::new(0.0, 0.0, 2.0);
        let up = spawn_origin(p, n, DVec3::new(1.0, 0.0, 0.1), PointPrecision::F32, 0.0);
        let down = spawn_origin(p, n, DVec3::new(1.0, 0.0, -0.1), PointPrecision::F32, 0.0);
        let d = spawn_distance(p, PointPrecision::F32, 0.0);
        // half an f32 ulp of 3 is 2⁻²³·… : δₚ ≈ √3·2⁻²⁴·3
        assert!((d - 2.0 * 3f64.sqrt() * 3.0 * 2f64.powi(-24)).abs() < 1e-12, "{d:e}");
        assert!(up.z - 3.0 >= d && up.z - 3.0 < d * 1.000_001, "{up}");
        assert!(3.0 - down.z >= d && 3.0 - down.z < d * 1.000_001, "{down}");
        assert_eq!((up.x, up.y), (1.0, 2.0));
        assert_eq!(spawn_origin(p, DVec3::ZERO, DVec3::X, PointPrecision::F64, 0.0), p);
        assert_eq!("f32".parse::<PointPrecision>(), Ok(PointPrecision::F32));
        assert_eq!("1e-6".parse::<PointPrecision>(), Ok(PointPrecision::Absolute(1e-6)));
        assert!("-1".parse::<PointPrecision>().is_err() && "nan".parse::<PointPrecision>().is_err());
    }

    #[test]
    fn bound_scales_with_the_numbers_involved() {
        let ray = Ray::new(DVec3::new(0.0, 0.0, -1e4), DVec3::Z);
        let near = point_error_bound(&ray, 1e4, 1e-3);
        assert!(near > 1e4 * f64::EPSILON && near < 1e4 * 1e-13, "{near:e}");
        assert_eq!(magnitude(&Aabb::EVERYTHING), 0.0);
    }
}
