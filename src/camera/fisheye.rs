//! `Fisheye(fov_deg: 180)`: the equidistant fisheye, `r = f·θ`, field of view up to 360°.
//!
//! The image circle is the largest circle centred in the image, radius `R = min(W, H)/2` pixels,
//! and its rim is at angle `θmax = fov/2` from `forward`, so `f = R/θmax` pixels per radian. At
//! image position `(x, y)`, with `dx = x − W/2`, `dy = y − H/2`, `r = √(dx² + dy²)`:
//! `θ = r/f`, and the ray leaves the eye along
//! `sin θ·(dx/r·right − dy/r·up) + cos θ·forward`. Positions with `θ > θmax` (outside the image
//! circle) have no ray: the renderer writes the miss values there. Projection inverts it with
//! `θ = atan2(√(a² + b²), c)`. There is no single view axis for wide fields: depth `Z` is the ray
//! distance, as `distance` is.
//!
//! In OpenCV terms this is `cv2.fisheye` with `K = [[f, 0, W/2 − ½], [0, f, H/2 − ½], [0, 0, 1]]`
//! and zero distortion (`θd = θ`), valid there for `θ < 90°`.

use super::perspective::intrinsic_matrix;
use super::Camera;
use glam::{DMat3, DVec2, DVec3};
use zeroset_primitives::Ray;

/// The equidistant fisheye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fisheye {
    /// Half the field of view, radians: `θmax ∈ (0, π]`.
    pub half_fov: f64,
}

impl Fisheye {
    /// Focal length `f = R/θmax` in pixels per radian.
    #[must_use]
    pub fn focal(&self, camera: &Camera) -> f64 {
        0.5 * f64::from(camera.width.min(camera.height)) / self.half_fov
    }

    /// The ray through image position `(x, y)`, `None` outside the image circle.
    #[inline]
    #[must_use]
    pub fn ray(&self, camera: &Camera, x: f64, y: f64) -> Option<Ray> {
        let dx = x - 0.5 * f64::from(camera.width);
        let dy = y - 0.5 * f64::from(camera.height);
        let r = dx.hypot(dy);
        let theta = r / self.focal(camera);
        if theta > self.half_fov {
            return None;
        }
        if r == 0.0 {
            return Some(Ray::new(camera.eye, camera.forward));
        }
        let (sin_theta, cos_theta) = theta.sin_cos();
        let local = DVec3::new(sin_theta * dx / r, -sin_theta * dy / r, cos_theta);
        Some(Ray::new(camera.eye, camera.local_to_world(local).normalize()))
    }

    /// Image position of camera-local point `local` (`None` at the eye itself).
    #[must_use]
    pub fn project(&self, camera: &Camera, local: DVec3) -> Option<DVec2> {
        if local == DVec3::ZERO {
            return None;
        }
        let centre = 0.5 * DVec2::new(f64::from(camera.width), f64::from(camera.height));
        let rho = local.x.hypot(local.y);
        if rho == 0.0 {
            // on the axis: the centre in front, the whole rim behind (only seen with fov 360°)
            return (local.z > 0.0).then_some(centre);
        }
        let r = rho.atan2(local.z) * self.focal(camera);
        Some(centre + DVec2::new(r * local.x / rho, -r * local.y / rho))
    }

    /// `K` of the equivalent `cv2.fisheye` camera (module docs).
    #[must_use]
    pub fn intrinsics(&self, camera: &Camera) -> DMat3 {
        let f = self.focal(camera);
        intrinsic_matrix(
            f,
            f,
            0.5 * f64::from(camera.width) - 0.5,
            0.5 * f64::from(camera.height) - 0.5,
        )
    }
}
