//! `Perspective`: the pinhole of classic ray casting (the default model), with an optional
//! principal-point offset.
//!
//! With camera-local coordinates `(a, b, c)` of a point (along `right`, `up`, `forward`) and
//! `sx = a/c`, `sy = b/c`, the point is seen at image position
//!
//! `x = (sx / tan(θh/2) + 1)·W/2 + ox`,  `y = (1 − sy / tan(θv/2))·H/2 + oy`,
//!
//! where `(ox, oy)` is the principal-point offset in pixels (`+x` right, `+y` down, from the image
//! centre; default `(0, 0)`). The ray through `(x, y)` inverts this: it leaves the eye along
//! `forward + sx·right + sy·up`, normalised. With a zero offset the arithmetic is exactly the
//! pre-models formula, so default renders are bit-identical to older versions.
//!
//! In OpenCV terms (pixel centres at integers): `fx = W / (2 tan(θh/2))`, `fy = H / (2 tan(θv/2))`,
//! `cx = W/2 + ox − ½`, `cy = H/2 + oy − ½`, no distortion. Depth `Z` is planar.

use super::Camera;
use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};
use zeroset_primitives::Ray;

/// The pinhole's only parameter beyond the field of view (kept on [`Camera`] as
/// `tan_half_vfov`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Perspective {
    /// Principal point minus image centre, in pixels (`+x` right, `+y` down).
    pub principal_offset: DVec2,
}

impl Perspective {
    /// The ray through image position `(x, y)`.
    #[inline]
    #[must_use]
    pub fn ray(&self, camera: &Camera, x: f64, y: f64) -> Ray {
        Self::ray_at(camera, self.screen_x(camera, x), self.screen_y(camera, y))
    }

    /// `sx`, the image plane's coordinate at distance 1 along `right`, of image position `x`:
    /// what a ray depends on of its column.
    #[inline]
    #[must_use]
    pub fn screen_x(&self, camera: &Camera, x: f64) -> f64 {
        ((x - self.principal_offset.x) / f64::from(camera.width) * 2.0 - 1.0) * camera.tan_half_hfov()
    }

    /// `sy`, the image plane's coordinate at distance 1 along `up`, of image position `y`.
    #[inline]
    #[must_use]
    pub fn screen_y(&self, camera: &Camera, y: f64) -> f64 {
        (1.0 - (y - self.principal_offset.y) / f64::from(camera.height) * 2.0) * camera.tan_half_vfov
    }

    /// The ray through the image plane's point `(sx, sy)` ([`Perspective::screen_x`],
    /// [`Perspective::screen_y`]): `forward + sx·right + sy·up`, normalised.
    #[inline]
    #[must_use]
    pub fn ray_at(camera: &Camera, sx: f64, sy: f64) -> Ray {
        Ray::new(
            camera.eye,
            (camera.forward + sx * camera.right + sy * camera.up).normalize(),
        )
    }

    /// Image position of camera-local point `local` (`None` on or behind the eye plane).
    #[must_use]
    pub fn project(&self, camera: &Camera, local: DVec3) -> Option<DVec2> {
        if local.z <= 0.0 {
            return None;
        }
        let (sx, sy) = (local.x / local.z, local.y / local.z);
        Some(DVec2::new(
            (sx / camera.tan_half_hfov() + 1.0) * 0.5 * f64::from(camera.width) + self.principal_offset.x,
            (1.0 - sy / camera.tan_half_vfov) * 0.5 * f64::from(camera.height) + self.principal_offset.y,
        ))
    }

    /// OpenCV intrinsics `K` (pixel centres at integer coordinates).
    #[must_use]
    pub fn intrinsics(&self, camera: &Camera) -> DMat3 {
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        intrinsic_matrix(
            w / (2.0 * camera.tan_half_hfov()),
            h / (2.0 * camera.tan_half_vfov),
            w * 0.5 + self.principal_offset.x - 0.5,
            h * 0.5 + self.principal_offset.y - 0.5,
        )
    }

    /// The OpenGL projection (camera space → clip space) with near/far planes, the principal
    /// offset shifting the frustum.
    #[must_use]
    pub fn projection(&self, camera: &Camera, near: f64, far: f64) -> DMat4 {
        let sx = 1.0 / camera.tan_half_hfov();
        let sy = 1.0 / camera.tan_half_vfov;
        let ox = -2.0 * self.principal_offset.x / f64::from(camera.width);
        let oy = 2.0 * self.principal_offset.y / f64::from(camera.height);
        DMat4::from_cols(
            DVec4::new(sx, 0.0, 0.0, 0.0),
            DVec4::new(0.0, sy, 0.0, 0.0),
            DVec4::new(ox, oy, -(far + near) / (far - near), -1.0),
            DVec4::new(0.0, 0.0, -2.0 * far * near / (far - near), 0.0),
        )
    }

    /// The same model for an image scaled by `(sx, sy)`.
    #[must_use]
    pub fn rescaled(&self, sx: f64, sy: f64) -> Self {
        Self {
            principal_offset: self.principal_offset * DVec2::new(sx, sy),
        }
    }
}

/// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` as a column-major matrix.
#[must_use]
pub fn intrinsic_matrix(fx: f64, fy: f64, cx: f64, cy: f64) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(fx, 0.0, 0.0),
        DVec3::new(0.0, fy, 0.0),
        DVec3::new(cx, cy, 1.0),
    )
}
