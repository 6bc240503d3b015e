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
        })
    }

    /// The same camera at another resolution, keeping the vertical field of view.
    pub fn with_resolution(&self, width: u32, height: u32) -> Result<Self, CameraError> {
        Self::new(
            self.eye,
            self.forward,
            self.up,
            2.0 * self.tan_half_vfov.atan().to_degrees(),
            width,
            height,
        )
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
