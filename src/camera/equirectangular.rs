//! `Equirectangular(azimuth_deg: (a0, a1), elevation_deg: (e0, e1))`: a panoramic range image,
//! 360° × 180° by default, or a limited band for spinning range sensors.
//!
//! Azimuth `φ` is measured from `forward` towards `right`, elevation `θ` from the horizontal
//! plane (spanned by `forward` and `right`) towards `up`. Columns are linear in azimuth and rows
//! in elevation, top row highest:
//!
//! `φ = a0 + x/W·(a1 − a0)`,  `θ = e1 − y/H·(e1 − e0)`,
//!
//! and the ray leaves the eye along `cos θ sin φ·right + sin θ·up + cos θ cos φ·forward`. The
//! projection inverts it with `θ = atan2(b, √(a² + c²))`, `φ = atan2(a, c)` (taken within ±180° of
//! the range's centre). There is no view axis: depth `Z` is the ray distance, as `distance` is.

use super::Camera;
use glam::{DVec2, DVec3};
use std::f64::consts::{PI, TAU};
use zeroset_primitives::Ray;

/// Angular ranges in radians (the RON gives degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equirectangular {
    /// `(a0, a1)`, `a0 < a1`, `a1 − a0 ≤ 2π`.
    pub azimuth: (f64, f64),
    /// `(e0, e1)`, `−π/2 ≤ e0 < e1 ≤ π/2`.
    pub elevation: (f64, f64),
}

impl Default for Equirectangular {
    fn default() -> Self {
        Self {
            azimuth: (-PI, PI),
            elevation: (-0.5 * PI, 0.5 * PI),
        }
    }
}

impl Equirectangular {
    /// Checks the ranges (given in degrees in messages).
    pub fn validate(&self) -> Result<(), String> {
        let (a0, a1) = self.azimuth;
        let (e0, e1) = self.elevation;
        if !(a0.is_finite() && a1.is_finite() && a0 < a1 && a1 - a0 <= TAU * (1.0 + 1e-12)) {
            return Err(format!(
                "azimuth_deg needs a0 < a1 with a1 − a0 ≤ 360, got ({}, {})",
                a0.to_degrees(),
                a1.to_degrees()
            ));
        }
        let limit = 0.5 * PI * (1.0 + 1e-12);
        if !(e0.is_finite() && e1.is_finite() && e0 < e1 && e0 >= -limit && e1 <= limit) {
            return Err(format!(
                "elevation_deg needs −90 ≤ e0 < e1 ≤ 90, got ({}, {})",
                e0.to_degrees(),
                e1.to_degrees()
            ));
        }
        Ok(())
    }

    /// The ray through image position `(x, y)`.
    #[inline]
    #[must_use]
    pub fn ray(&self, camera: &Camera, x: f64, y: f64) -> Ray {
        let phi = self.azimuth.0 + x / f64::from(camera.width) * (self.azimuth.1 - self.azimuth.0);
        let theta = self.elevation.1 - y / f64::from(camera.height) * (self.elevation.1 - self.elevation.0);
        let (sin_phi, cos_phi) = phi.sin_cos();
        let (sin_theta, cos_theta) = theta.sin_cos();
        let local = DVec3::new(cos_theta * sin_phi, sin_theta, cos_theta * cos_phi);
        Ray::new(camera.eye, camera.local_to_world(local).normalize())
    }

    /// Image position of camera-local point `local` (`None` at the eye itself).
    #[must_use]
    pub fn project(&self, camera: &Camera, local: DVec3) -> Option<DVec2> {
        if local == DVec3::ZERO {
            return None;
        }
        let theta = local.y.atan2(local.x.hypot(local.z));
        let centre = 0.5 * (self.azimuth.0 + self.azimuth.1);
        // φ − centre wrapped into (−π, π]
        let mut offset = local.x.atan2(local.z) - centre;
        offset -= TAU * ((offset + PI) / TAU).floor();
        let phi = centre + offset;
        Some(DVec2::new(
            (phi - self.azimuth.0) / (self.azimuth.1 - self.azimuth.0) * f64::from(camera.width),
            (self.elevation.1 - theta) / (self.elevation.1 - self.elevation.0) * f64::from(camera.height),
        ))
    }
}
