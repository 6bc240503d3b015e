//! Hit records: the cheap one an intersector returns, and the full one built once for the closest.
//!
//! Intersection runs in two stages ("cheap first, full once"):
//!
//! 1. [`crate::Intersect::intersect`] finds the smallest `t` in the query
//!    interval and returns a [`RawHit`]: `t` plus whatever the primitive needs to finish later (a
//!    face index, barycentric coordinates).
//! 2. For the closest hit only, [`SurfaceHit::complete`] computes the point and, if asked for in a
//!    [`HitRequest`], the normal and the surface parameters.
//!
//! # Conventions
//! - `t` is in units of the ray direction (metric distance for a unit direction).
//! - The normal is `∇Φ/|∇Φ|`: unit length, pointing to the `Φ > 0` side (outward for closed
//!   surfaces). It is **never** flipped toward the viewer; [`SurfaceHit::facing_normal`] gives the
//!   viewer-facing one.
//! - `entered_from_outside` is `dir · n < 0`: the ray crossed from the `Φ > 0` side.

use glam::{DVec2, DVec3};

/// What an intersector returns: the ray parameter and primitive-private data for finishing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawHit {
    /// Ray parameter of the hit (in units of the ray direction).
    pub t: f64,
    /// Primitive-defined part index (a box face, a cylinder cap, a mesh triangle); 0 if unused.
    pub feature: u32,
    /// Primitive-defined cached coordinates (triangle barycentrics); zero if unused.
    pub local: DVec2,
}

impl RawHit {
    /// A hit at `t` with no cached data.
    #[inline]
    #[must_use]
    pub const fn at(t: f64) -> Self {
        Self {
            t,
            feature: 0,
            local: DVec2::ZERO,
        }
    }

    /// A hit at `t` on part `feature`.
    #[inline]
    #[must_use]
    pub const fn on_feature(t: f64, feature: u32) -> Self {
        Self {
            t,
            feature,
            local: DVec2::ZERO,
        }
    }
}

/// Which parts of a [`SurfaceHit`] to compute. Asking for less costs less.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HitRequest {
    /// Compute the unit normal (`∇Φ` direction).
    pub normal: bool,
    /// Compute surface parameters `(u, v)` where the primitive has them.
    pub uv: bool,
    /// Compute the bound on the hit point's error ([`SurfaceHit::error`]), which starting a
    /// secondary ray needs.
    pub error: bool,
}

impl HitRequest {
    /// Everything.
    pub const ALL: Self = Self {
        normal: true,
        uv: true,
        error: true,
    };
    /// Only `t` and the point.
    pub const NONE: Self = Self {
        normal: false,
        uv: false,
        error: false,
    };
}

/// The full record of a hit, built once for the closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Ray parameter (metric distance for a unit-length direction).
    pub t: f64,
    /// `ray.origin + t·ray.dir`.
    pub point: DVec3,
    /// Unit `∇Φ` direction at the hit, towards `Φ > 0`; `None` if not requested.
    pub normal: Option<DVec3>,
    /// Surface parameters where the primitive defines them and they were requested.
    pub uv: Option<DVec2>,
    /// Primitive-defined part index (see [`RawHit::feature`]).
    pub feature: u32,
    /// Bound on the distance between `point` and the exact surface
    /// ([`crate::Intersect::hit_error`]); pass it to [`crate::offset::offset_origin`] to start
    /// secondary rays. `+∞` (a valid but useless bound) where the request did not ask for it
    /// ([`HitRequest::error`]): no secondary ray may start from such a record.
    pub error: f64,
}

impl SurfaceHit {
    /// Whether the ray arrived from the `Φ > 0` side (`dir · n < 0`); `None` without a normal.
    #[must_use]
    pub fn entered_from_outside(&self, dir: DVec3) -> Option<bool> {
        self.normal.map(|n| dir.dot(n) < 0.0)
    }

    /// Origin for a secondary ray from this hit, on the side the arriving ray (direction `dir`)
    /// came from: [`crate::offset::spawn_origin`] with the absolute bound `SurfaceHit::error / 2`
    /// (so the point moves by `error + γ₃₂·‖p‖∞` along the facing normal, rounded away; `error`
    /// already covers the re-intersection's rounding). Without a normal, the point itself.
    #[must_use]
    pub fn secondary_origin(&self, dir: DVec3) -> DVec3 {
        match self.facing_normal(dir) {
            Some(n) => crate::offset::spawn_origin(
                self.point,
                n,
                n,
                crate::offset::PointPrecision::Absolute(0.5 * self.error),
                0.0,
            ),
            None => self.point,
        }
    }

    /// The normal flipped, if needed, to face against `dir` (towards the viewer).
    #[must_use]
    pub fn facing_normal(&self, dir: DVec3) -> Option<DVec3> {
        self.normal.map(|n| facing(n, dir))
    }
}

/// `n`, flipped if needed to face against `dir`: `−n` where `dir · n > 0`.
#[inline]
#[must_use]
pub fn facing(n: DVec3, dir: DVec3) -> DVec3 {
    if dir.dot(n) > 0.0 {
        -n
    } else {
        n
    }
}
