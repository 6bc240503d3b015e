//! `Orthographic(width: w)`: parallel rays along the view axis, for height maps and
//! measurement views.
//!
//! The frame is `w` world units wide and `w·H/W` high (square pixels), centred on the eye in the
//! plane through the eye perpendicular to `forward`. Image position `(x, y)` is the ray from
//! `eye + a·right + b·up` along `forward`, with
//!
//! `a = (x/W·2 − 1)·w/2`,  `b = (1 − y/H·2)·h/2`,
//!
//! so rays start on the eye plane and only what lies in front of it is seen. Depth `Z` is planar
//! (distance from the eye plane, which equals the ray distance `t`). In OpenCV terms the camera
//! is affine: `u = fx·X + cx`, `v = fy·Y + cy` (no division by `Z`) with
//! `fx = fy = W/w` pixels per world unit, `cx = W/2 − ½`, `cy = H/2 − ½`.

use super::perspective::intrinsic_matrix;
use super::Camera;
use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};
use zeroset_primitives::Ray;

/// A parallel projection `width` world units wide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orthographic {
    /// Frame width in world units.
    pub width: f64,
}

impl Orthographic {
    /// Half the frame's width and height in world units.
    fn half_extent(&self, camera: &Camera) -> DVec2 {
        let half_width = 0.5 * self.width;
        DVec2::new(
            half_width,
            half_width * f64::from(camera.height) / f64::from(camera.width),
        )
    }

    /// The ray through image position `(x, y)`.
    #[inline]
    #[must_use]
    pub fn ray(&self, camera: &Camera, x: f64, y: f64) -> Ray {
        let half = self.half_extent(camera);
        let a = (x / f64::from(camera.width) * 2.0 - 1.0) * half.x;
        let b = (1.0 - y / f64::from(camera.height) * 2.0) * half.y;
        Ray::new(camera.eye + a * camera.right + b * camera.up, camera.forward)
    }

    /// Image position of camera-local point `local` (any depth).
    #[must_use]
    pub fn project(&self, camera: &Camera, local: DVec3) -> DVec2 {
        let half = self.half_extent(camera);
        DVec2::new(
            (local.x / half.x + 1.0) * 0.5 * f64::from(camera.width),
            (1.0 - local.y / half.y) * 0.5 * f64::from(camera.height),
        )
    }

    /// The affine intrinsics (module docs): `u = fx·X + cx`, `v = fy·Y + cy`.
    #[must_use]
    pub fn intrinsics(&self, camera: &Camera) -> DMat3 {
        let f = f64::from(camera.width) / self.width;
        intrinsic_matrix(
            f,
            f,
            0.5 * f64::from(camera.width) - 0.5,
            0.5 * f64::from(camera.height) - 0.5,
        )
    }

    /// The OpenGL orthographic projection (camera space → clip space) between `near` and `far`.
    #[must_use]
    pub fn projection(&self, camera: &Camera, near: f64, far: f64) -> DMat4 {
        let half = self.half_extent(camera);
        DMat4::from_cols(
            DVec4::new(1.0 / half.x, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 1.0 / half.y, 0.0, 0.0),
            DVec4::new(0.0, 0.0, -2.0 / (far - near), 0.0),
            DVec4::new(0.0, 0.0, -(far + near) / (far - near), 1.0),
        )
    }
}
