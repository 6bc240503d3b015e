//! The thin lens of the `Perspective` model: depth of field.
//!
//! With `aperture > 0` a sample also picks a point on the lens disk of that radius (centred on
//! the eye, spanned by `right` and `up`, by [`concentric_disk`]); the primary ray starts there and
//! passes through the point where the pinhole ray meets the focus plane (the plane perpendicular
//! to `forward` at `focus_distance` from the eye), so everything on the focus plane stays sharp.
//! With `aperture = 0` [`Camera::lens_ray`] returns the pinhole ray itself, bit for bit.

use super::{err, Camera, CameraError, NoRay};
use zeroset_primitives::Ray;

impl Camera {
    /// The same camera with a thin lens of radius `aperture` (0: pinhole) focused at
    /// `focus_distance` along the view axis; errors on a negative or non-finite aperture or a
    /// non-positive focus distance.
    pub fn with_lens(mut self, aperture: f64, focus_distance: f64) -> Result<Self, CameraError> {
        if !(aperture.is_finite() && aperture >= 0.0) {
            return Err(err("aperture", format!("must be finite and ≥ 0, got {aperture}")));
        }
        if !(focus_distance.is_finite() && focus_distance > 0.0) {
            return Err(err(
                "focus_distance",
                format!("must be finite and > 0, got {focus_distance}"),
            ));
        }
        self.aperture = aperture;
        self.focus_distance = focus_distance;
        self.check_lens_model()?;
        Ok(self)
    }

    /// The primary ray through image position `(x, y)` for the lens sample `lens ∈ [0, 1)²`
    /// (mapped to the lens disk by [`concentric_disk`]). With `aperture = 0` this is exactly
    /// [`Camera::ray_through`] (the same bits); otherwise the ray starts at the lens point and
    /// passes through the pinhole ray's point on the focus plane, and is unit length.
    #[inline]
    pub fn lens_ray(&self, x: f64, y: f64, lens: (f64, f64)) -> Result<Ray, NoRay> {
        let pinhole = self.ray_through(x, y)?;
        if self.aperture == 0.0 {
            return Ok(pinhole);
        }
        // where the pinhole ray crosses the focus plane ⟨p − eye, forward⟩ = focus_distance
        let focus = self.eye + pinhole.dir * (self.focus_distance / pinhole.dir.dot(self.forward));
        let (dx, dy) = concentric_disk(lens.0, lens.1);
        let origin = self.eye + self.aperture * (dx * self.right + dy * self.up);
        Ok(Ray::new(origin, (focus - origin).normalize()))
    }
}

/// Shirley and Chiu's concentric map of the unit square `[0, 1)²` onto the unit disk: area
/// preserving (uniform samples stay uniform, strata stay compact), `(½, ½)` ↦ the centre.
#[must_use]
pub fn concentric_disk(u: f64, v: f64) -> (f64, f64) {
    let a = 2.0 * u - 1.0;
    let b = 2.0 * v - 1.0;
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, theta) = if a.abs() > b.abs() {
        (a, std::f64::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (a / b))
    };
    (r * theta.cos(), r * theta.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::tests::camera;

    #[test]
    fn zero_aperture_lens_rays_are_the_pinhole_rays_bit_for_bit() {
        let c = camera().with_lens(0.0, 3.0).unwrap();
        for k in 0..200u32 {
            let x = f64::from(k * 37 % 1280) + f64::from(k) / 200.0;
            let y = f64::from(k * 11 % 720) + 0.25;
            let lens = (f64::from(k) / 200.0, f64::from((k * 7) % 200) / 200.0);
            let a = c.lens_ray(x, y, lens).unwrap();
            let b = c.ray_through(x, y).unwrap();
            assert_eq!(
                a.origin.to_array().map(f64::to_bits),
                b.origin.to_array().map(f64::to_bits)
            );
            assert_eq!(a.dir.to_array().map(f64::to_bits), b.dir.to_array().map(f64::to_bits));
        }
    }

    #[test]
    fn lens_rays_meet_on_the_focus_plane() {
        let c = camera().with_lens(0.2, 7.0).unwrap();
        let centre = c.ray_through(300.5, 200.5).unwrap();
        let focus = centre.at(7.0 / centre.dir.dot(c.forward));
        for (u, v) in [(0.1, 0.9), (0.5, 0.5), (0.99, 0.01), (0.3, 0.6)] {
            let r = c.lens_ray(300.5, 200.5, (u, v)).unwrap();
            assert!(((r.origin - c.eye).length()) <= 0.2 + 1e-12);
            let t = (focus - r.origin).length();
            assert!((r.at(t) - focus).length() < 1e-9, "{u} {v}");
        }
        let (x, y) = concentric_disk(1.0, 0.5);
        assert!((x - 1.0).abs() < 1e-15 && y.abs() < 1e-15);
    }
}
