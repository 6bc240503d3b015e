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

use crate::bounds::Aabb;
use crate::cone::Cone;
use crate::error::{require_direction, require_finite, require_positive, PrimitiveError};
use crate::hit::RawHit;
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
    pub fn new(
        base: DVec3,
        axis: DVec3,
        radius: f64,
        height: f64,
        capped: bool,
    ) -> Result<Self, PrimitiveError> {
        let base = require_finite("Cylinder", "base", base)?;
        let axis = require_direction("Cylinder", "axis", axis)?;
        let radius = require_positive("Cylinder", "radius", radius)?;
        let height = require_positive("Cylinder", "height", height)?;
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
