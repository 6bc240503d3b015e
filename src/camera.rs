//! The pinhole camera of classic ray casting.
//!
//! Basis (right-handed, as in the benchmark harnesses): forward `f = normalize(look_at − eye)`,
//! right `r = normalize(f × up)`, true up `u = r × f` (so `up` need only not be parallel to `f`).
//! Pixel `(i, j)`, row 0 at the top, is sampled through its centre: the ray from `eye` along
//! `f + x·r + y·u` with
//! `x = ((i + ½)/W·2 − 1)·tan(θv/2)·W/H` and `y = (1 − (j + ½)/H·2)·tan(θv/2)`,
//! normalised, so the ray parameter `t` is metric distance. Pixels are square:
//! `tan(θv/2)/tan(θh/2) = H/W`.
//!
//! **Thin lens.** With `aperture > 0` a sample also picks a point on the lens disk of that radius
//! (centred on the eye, spanned by `right` and `up`); the primary ray starts there and passes
//! through the point where the pinhole ray meets the focus plane (the plane perpendicular to
//! `forward` at `focus_distance` from the eye), so everything on the focus plane stays sharp.
//! With `aperture = 0` [`Camera::lens_ray`] returns the pinhole ray itself, bit for bit.
//!
//! **Shutter.** The shutter is open over the frame times `[open, close]` (default `[0, 1]`);
//! moving objects are keyed at frame times 0 and 1 (see `scene.rs`).
//!
//! Camera space (for the EXR `worldToCamera` attribute and camera-space normals): origin at the
//! eye, `+x` right, `+y` up, the camera looking along `−z` (the OpenGL/Nuke convention).

use glam::{DMat4, DVec3, DVec4};
use zeroset_primitives::Ray;

/// A validated pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (world space).
    pub eye: DVec3,
    /// Unit view direction.
    pub forward: DVec3,
    /// Unit right vector.
    pub right: DVec3,
    /// Unit true-up vector.
    pub up: DVec3,
    /// `tan(θv/2)`.
    pub tan_half_vfov: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Lens radius (world units); 0 is the pinhole.
    pub aperture: f64,
    /// Distance from the eye to the plane in focus, along `forward`.
    pub focus_distance: f64,
    /// Frame times `(open, close)` during which the shutter is open.
    pub shutter: (f64, f64),
}

/// Why a camera description is impossible, naming the field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("camera: field `{field}`: {problem}")]
pub struct CameraError {
    /// Offending field.
    pub field: &'static str,
    /// What is wrong.
    pub problem: String,
}

fn err(field: &'static str, problem: impl Into<String>) -> CameraError {
    CameraError {
        field,
        problem: problem.into(),
    }
}

impl Camera {
    /// A camera at `eye` looking along `direction` (any length > 0), with `up` orthonormalised
    /// against it, vertical field of view `vfov_deg` ∈ (0°, 180°) and `width × height` pixels.
    pub fn new(
        eye: DVec3,
        direction: DVec3,
        up: DVec3,
        vfov_deg: f64,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if !eye.is_finite() {
            return Err(err("eye", format!("must be finite, got {eye}")));
        }
        if !direction.is_finite() || direction.length() == 0.0 {
            return Err(err(
                "look_at",
                "the view direction must be finite and non-zero (look_at equals eye?)",
            ));
        }
        if !up.is_finite() || up.length() == 0.0 {
            return Err(err("up", format!("must be finite and non-zero, got {up}")));
        }
        if !(vfov_deg > 0.0 && vfov_deg < 180.0) {
            return Err(err("vfov_deg", format!("must lie in (0, 180) degrees, got {vfov_deg}")));
        }
        if width == 0 || height == 0 {
            return Err(err(
                if width == 0 { "width" } else { "height" },
                "must be at least 1 pixel",
            ));
        }
        let forward = direction.normalize();
        let side = forward.cross(up.normalize());
        if side.length() < 1e-9 {
            return Err(err("up", "is parallel to the view direction"));
        }
        let right = side.normalize();
        let true_up = right.cross(forward);
        Ok(Self {
            eye,
            forward,
            right,
            up: true_up,
            tan_half_vfov: (vfov_deg.to_radians() * 0.5).tan(),
            width,
            height,
            aperture: 0.0,
            focus_distance: direction.length(),
            shutter: (0.0, 1.0),
        })
    }

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
        Ok(self)
    }

    /// The same camera with the shutter open over frame times `[open, close]`.
    pub fn with_shutter(mut self, open: f64, close: f64) -> Result<Self, CameraError> {
        if !(open.is_finite() && close.is_finite() && open <= close) {
            return Err(err(
                "shutter",
                format!("needs finite open ≤ close, got ({open}, {close})"),
            ));
        }
        self.shutter = (open, close);
        Ok(self)
    }

    /// The same camera at another resolution, keeping the vertical field of view.
    pub fn with_resolution(&self, width: u32, height: u32) -> Result<Self, CameraError> {
        let mut camera = Self::new(
            self.eye,
            self.forward,
            self.up,
            2.0 * self.tan_half_vfov.atan().to_degrees(),
            width,
            height,
        )?;
        camera.aperture = self.aperture;
        camera.focus_distance = self.focus_distance;
        camera.shutter = self.shutter;
        Ok(camera)
    }

    /// The vertical field of view (degrees) giving horizontal field `hfov_deg` at this aspect.
    #[must_use]
    pub fn vfov_from_hfov(hfov_deg: f64, width: u32, height: u32) -> f64 {
        2.0 * ((hfov_deg.to_radians() * 0.5).tan() * f64::from(height) / f64::from(width))
            .atan()
            .to_degrees()
    }

    /// `tan(θh/2) = tan(θv/2)·W/H`.
    #[must_use]
    pub fn tan_half_hfov(&self) -> f64 {
        self.tan_half_vfov * f64::from(self.width) / f64::from(self.height)
    }

    /// The unit-direction ray through image position `(x, y)` in pixels (`(i + ½, j + ½)` is the
    /// centre of pixel `(i, j)`).
    #[inline]
    #[must_use]
    pub fn ray_through(&self, x: f64, y: f64) -> Ray {
        let sx = (x / f64::from(self.width) * 2.0 - 1.0) * self.tan_half_hfov();
        let sy = (1.0 - y / f64::from(self.height) * 2.0) * self.tan_half_vfov;
        Ray::new(self.eye, (self.forward + sx * self.right + sy * self.up).normalize())
    }

    /// The primary ray through image position `(x, y)` for the lens sample `lens ∈ [0, 1)²`
    /// (mapped to the lens disk by [`concentric_disk`]). With `aperture = 0` this is exactly
    /// [`Camera::ray_through`] (the same bits); otherwise the ray starts at the lens point and
    /// passes through the pinhole ray's point on the focus plane, and is unit length.
    #[inline]
    #[must_use]
    pub fn lens_ray(&self, x: f64, y: f64, lens: (f64, f64)) -> Ray {
        let pinhole = self.ray_through(x, y);
        if self.aperture == 0.0 {
            return pinhole;
        }
        // where the pinhole ray crosses the focus plane ⟨p − eye, forward⟩ = focus_distance
        let focus = self.eye + pinhole.dir * (self.focus_distance / pinhole.dir.dot(self.forward));
        let (dx, dy) = concentric_disk(lens.0, lens.1);
        let origin = self.eye + self.aperture * (dx * self.right + dy * self.up);
        Ray::new(origin, (focus - origin).normalize())
    }

    /// The ray through the centre of pixel `(i, j)`.
    #[inline]
    #[must_use]
    pub fn pixel_ray(&self, i: u32, j: u32) -> Ray {
        self.ray_through(f64::from(i) + 0.5, f64::from(j) + 0.5)
    }

    /// Planar depth of a world point: its distance along the view axis, `⟨p − eye, forward⟩`.
    #[inline]
    #[must_use]
    pub fn planar_depth(&self, p: DVec3) -> f64 {
        (p - self.eye).dot(self.forward)
    }

    /// World → camera space (module docs: `+x` right, `+y` up, looking along `−z`).
    #[must_use]
    pub fn world_to_camera(&self) -> DMat4 {
        let camera_to_world = DMat4::from_cols(
            self.right.extend(0.0),
            self.up.extend(0.0),
            (-self.forward).extend(0.0),
            self.eye.extend(1.0),
        );
        camera_to_world.inverse()
    }

    /// World → normalised device coordinates: `x, y ∈ [−1, 1]` across the image (left → right,
    /// bottom → top), `z ∈ [−1, 1]` between near plane `near` and far plane `far`, after the
    /// perspective divide (OpenGL convention).
    #[must_use]
    pub fn world_to_ndc(&self, near: f64, far: f64) -> DMat4 {
        let sx = 1.0 / self.tan_half_hfov();
        let sy = 1.0 / self.tan_half_vfov;
        let projection = DMat4::from_cols(
            DVec4::new(sx, 0.0, 0.0, 0.0),
            DVec4::new(0.0, sy, 0.0, 0.0),
            DVec4::new(0.0, 0.0, -(far + near) / (far - near), -1.0),
            DVec4::new(0.0, 0.0, -2.0 * far * near / (far - near), 0.0),
        );
        projection * self.world_to_camera()
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

    fn camera() -> Camera {
        Camera::new(
            DVec3::new(0.0, 3.0, -9.0),
            DVec3::new(0.0, -2.2, 9.0),
            DVec3::Y,
            40.0,
            1280,
            720,
        )
        .unwrap()
    }

    #[test]
    fn centre_ray_is_forward_and_corners_match_fov() {
        let c = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 90.0, 2, 2).unwrap();
        // pixel (0,0) of a 2×2 image: x = −½·tan45·1, y = +½
        let r = c.pixel_ray(0, 0);
        let expected = (DVec3::Z + 0.5 * DVec3::X + 0.5 * DVec3::Y).normalize(); // right = Z × Y = −X
        assert!((r.dir - expected).length() < 1e-15, "{r:?}");
        let even = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 60.0, 3, 3).unwrap();
        assert!((even.pixel_ray(1, 1).dir - DVec3::Z).length() < 1e-15);
    }

    #[test]
    fn zero_aperture_lens_rays_are_the_pinhole_rays_bit_for_bit() {
        let c = camera().with_lens(0.0, 3.0).unwrap();
        for k in 0..200u32 {
            let x = f64::from(k * 37 % 1280) + f64::from(k) / 200.0;
            let y = f64::from(k * 11 % 720) + 0.25;
            let lens = (f64::from(k) / 200.0, f64::from((k * 7) % 200) / 200.0);
            let a = c.lens_ray(x, y, lens);
            let b = c.ray_through(x, y);
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
        let centre = c.ray_through(300.5, 200.5);
        let focus = centre.at(7.0 / centre.dir.dot(c.forward));
        for (u, v) in [(0.1, 0.9), (0.5, 0.5), (0.99, 0.01), (0.3, 0.6)] {
            let r = c.lens_ray(300.5, 200.5, (u, v));
            assert!(((r.origin - c.eye).length()) <= 0.2 + 1e-12);
            let t = (focus - r.origin).length();
            assert!((r.at(t) - focus).length() < 1e-9, "{u} {v}");
        }
        let (x, y) = concentric_disk(1.0, 0.5);
        assert!((x - 1.0).abs() < 1e-15 && y.abs() < 1e-15);
    }

    #[test]
    fn hfov_conversion_keeps_square_pixels() {
        let v = Camera::vfov_from_hfov(90.0, 1920, 1080);
        let c = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, v, 1920, 1080).unwrap();
        assert!((c.tan_half_hfov() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn impossible_cameras_are_errors() {
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Y, DVec3::Y, 40.0, 10, 10)
                .unwrap_err()
                .field,
            "up"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 180.0, 10, 10)
                .unwrap_err()
                .field,
            "vfov_deg"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 0.0, 10, 10)
                .unwrap_err()
                .field,
            "vfov_deg"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 0, 10)
                .unwrap_err()
                .field,
            "width"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::ZERO, DVec3::Y, 40.0, 1, 1)
                .unwrap_err()
                .field,
            "look_at"
        );
        assert_eq!(
            Camera::new(DVec3::NAN, DVec3::Z, DVec3::Y, 40.0, 1, 1)
                .unwrap_err()
                .field,
            "eye"
        );
    }

    #[test]
    fn camera_space_looks_down_negative_z() {
        let c = camera();
        let m = c.world_to_camera();
        let ahead = m.transform_point3(c.eye + 5.0 * c.forward);
        assert!((ahead - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-12);
        let ndc = c
            .world_to_ndc(0.1, 100.0)
            .project_point3(c.eye + 5.0 * c.forward + 1.0 * c.right);
        assert!(ndc.x > 0.0 && ndc.y.abs() < 1e-12);
    }
}
