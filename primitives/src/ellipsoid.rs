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

use crate::bounds::Aabb;
use crate::error::{require_finite, require_positive, PrimitiveError};
use crate::hit::RawHit;
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
    fn to_unit(&self, p: DVec3) -> DVec3 {
        self.local_from_world * (p - self.center) / self.radii
    }

    /// The world-space gradient direction (unnormalised) at unit-space point `s`: `R(s ⊘ r)`.
    fn normal_direction(&self, s: DVec3) -> DVec3 {
        self.world_from_local * (s / self.radii)
    }
}

impl Implicit for Ellipsoid {
    fn phi(&self, p: DVec3) -> f64 {
        (self.to_unit(p).length() - 1.0) * self.radii.min_element()
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let s = self.to_unit(p);
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
        let reach = square(m.x_axis * self.radii.x)
            + square(m.y_axis * self.radii.y)
            + square(m.z_axis * self.radii.z);
        let reach = DVec3::new(reach.x.sqrt(), reach.y.sqrt(), reach.z.sqrt());
        Aabb::new(self.center - reach, self.center + reach)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }
}

impl Intersect for Ellipsoid {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        let local = Ray::new(
            self.to_unit(ray.origin),
            self.local_from_world * ray.dir / self.radii,
        );
        self.unit.intersect(&local, range)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        let s = self.to_unit(ray.origin) + raw.t * (self.local_from_world * ray.dir / self.radii);
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
        self.unit.uv(self.to_unit(p).normalize_or_zero())
    }
}
