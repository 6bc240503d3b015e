//! `OpenCv(fx, fy, cx, cy, distortion: [k1, k2, p1, p2, k3])`: the calibrated pinhole with
//! Brown–Conrady lens distortion, exactly as OpenCV's `projectPoints` models it.
//!
//! **Coordinates.** `fx, fy, cx, cy` are in OpenCV's pixel convention, where pixel `(i, j)` has
//! its centre at `(i, j)`; zeroset's image positions put it at `(i + ½, j + ½)`, so image position
//! `(x, y)` is OpenCV's `(u, v) = (x − ½, y − ½)`. The OpenCV camera frame is `X` along `right`,
//! `Y` along `−up` (down), `Z` along `forward`.
//!
//! **Forward model.** `x' = X/Z`, `y' = Y/Z`, `r² = x'² + y'²`,
//! `ρ = 1 + k1 r² + k2 r⁴ + k3 r⁶`,
//! `x'' = x'ρ + 2 p1 x'y' + p2 (r² + 2x'²)`, `y'' = y'ρ + p1 (r² + 2y'²) + 2 p2 x'y'`,
//! `u = fx x'' + cx`, `v = fy y'' + cy`.
//!
//! **Rays.** The ray through `(u, v)` needs the undistorted `(x', y')` whose distortion is
//! `d = ((u − cx)/fx, (v − cy)/fy)`. It is found by Newton's method on `D(x', y') − d = 0` with the
//! analytic Jacobian, started at `d`, and accepted once the residual is at most `1e-12` px in
//! both coordinates (`|fx·Δx''|`, `|fy·Δy''|`) and the root lies in the lens's invertible region:
//! the Jacobian determinant there is positive, and the radial map `r ↦ r·ρ(r²)` is still
//! increasing all the way out to the root's radius, i.e. `g(s) = d(rρ)/dr = 1 + 3k1 s + 5k2 s² +
//! 7k3 s³ > 0` for every `s = r²` up to the root's (checked exactly: at the ends and at the
//! roots of `g'` in between). This rejects the spurious roots a strongly distorting model has
//! beyond its fold (with `k1 < 0`, far-out points wrap around to the opposite side of the
//! image). A pixel that fails within 50 iterations has no ray: it is counted, reported and
//! written as a miss. With all coefficients zero the ray is the plain
//! pinhole ray. The residual is evaluated in f64, whose rounding is about `3·10⁻¹⁶·fx` px, so
//! the 1e-12 px tolerance holds comfortably up to focal lengths of a few thousand pixels.
//!
//! Depth `Z` is planar, along the optical axis (`forward`).

use super::perspective::intrinsic_matrix;
use super::{Camera, Perspective};
use glam::{DMat3, DMat4, DVec2, DVec3};
use zeroset_primitives::Ray;

/// Largest accepted undistortion residual, pixels.
pub const UNDISTORT_TOLERANCE_PX: f64 = 1e-12;
/// Newton iterations before a pixel is declared non-converging.
pub const UNDISTORT_MAX_ITERATIONS: usize = 50;

/// The calibrated pinhole (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenCv {
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point `u` (OpenCV pixel convention).
    pub cx: f64,
    /// Principal point `v`.
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]`.
    pub distortion: [f64; 5],
}

impl OpenCv {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.fx.is_finite() && self.fx > 0.0 && self.fy.is_finite() && self.fy > 0.0) {
            return Err(format!(
                "fx and fy must be finite and > 0, got {} and {}",
                self.fx, self.fy
            ));
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return Err(format!("cx and cy must be finite, got {} and {}", self.cx, self.cy));
        }
        if !self.distortion.iter().all(|k| k.is_finite()) {
            return Err(format!("distortion must be finite, got {:?}", self.distortion));
        }
        Ok(())
    }

    /// `(x'', y'')` and the Jacobian `[[∂x''/∂x', ∂x''/∂y'], [∂y''/∂x', ∂y''/∂y']]` at `(x, y)`.
    #[must_use]
    pub fn distort(&self, x: f64, y: f64) -> (DVec2, [[f64; 2]; 2]) {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // dρ/d(r²)
        let radial_slope = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let cross = 2.0 * x * y * radial_slope;
        let jacobian = [
            [
                radial + 2.0 * x * x * radial_slope + 2.0 * p1 * y + 6.0 * p2 * x,
                cross + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                cross + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * radial_slope + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ];
        (DVec2::new(xd, yd), jacobian)
    }

    /// Whether `g(s) = 1 + 3k1 s + 5k2 s² + 7k3 s³`, the radial map's slope, is positive on
    /// `[0, s_max]` (module docs): checked at `s_max` and at the stationary points of `g` inside.
    #[must_use]
    pub fn radially_increasing_up_to(&self, s_max: f64) -> bool {
        let [k1, k2, _, _, k3] = self.distortion;
        let g = |s: f64| 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3));
        if g(s_max) <= 0.0 {
            return false;
        }
        // g'(s) = 3k1 + 10k2 s + 21k3 s²
        let (a, b, c) = (21.0 * k3, 10.0 * k2, 3.0 * k1);
        let mut stationary = Vec::with_capacity(2);
        if a == 0.0 {
            if b != 0.0 {
                stationary.push(-c / b);
            }
        } else {
            let disc = b * b - 4.0 * a * c;
            if disc >= 0.0 {
                let root = disc.sqrt();
                stationary.push((-b - root) / (2.0 * a));
                stationary.push((-b + root) / (2.0 * a));
            }
        }
        stationary
            .into_iter()
            .filter(|s| *s > 0.0 && *s < s_max)
            .all(|s| g(s) > 0.0)
    }

    /// The undistorted normalised coordinates `(x', y')` seen at distorted `target`, or `None`
    /// where Newton's method does not meet the module's acceptance test.
    #[must_use]
    pub fn undistort(&self, target: DVec2) -> Option<DVec2> {
        if self.distortion == [0.0; 5] {
            return Some(target);
        }
        let mut p = target;
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let (d, j) = self.distort(p.x, p.y);
            let e = d - target;
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if (e.x * self.fx).abs() <= UNDISTORT_TOLERANCE_PX && (e.y * self.fy).abs() <= UNDISTORT_TOLERANCE_PX {
                return (det > 0.0 && self.radially_increasing_up_to(p.length_squared())).then_some(p);
            }
            if !(det.is_finite() && det != 0.0) {
                return None;
            }
            p -= DVec2::new(
                (j[1][1] * e.x - j[0][1] * e.y) / det,
                (j[0][0] * e.y - j[1][0] * e.x) / det,
            );
            if !p.is_finite() {
                return None;
            }
        }
        None
    }

    /// The ray through image position `(x, y)`, `None` where undistortion fails.
    #[inline]
    #[must_use]
    pub fn ray(&self, camera: &Camera, x: f64, y: f64) -> Option<Ray> {
        let target = DVec2::new((x - 0.5 - self.cx) / self.fx, (y - 0.5 - self.cy) / self.fy);
        let p = self.undistort(target)?;
        // OpenCV (x', y', 1) → (right, up, forward) = (x', −y', 1)
        let local = DVec3::new(p.x, -p.y, 1.0);
        Some(Ray::new(camera.eye, camera.local_to_world(local).normalize()))
    }

    /// Image position of camera-local point `local` (`None` on or behind the eye plane).
    #[must_use]
    pub fn project(&self, local: DVec3) -> Option<DVec2> {
        if local.z <= 0.0 {
            return None;
        }
        let (d, _) = self.distort(local.x / local.z, -local.y / local.z);
        Some(DVec2::new(self.fx * d.x + self.cx + 0.5, self.fy * d.y + self.cy + 0.5))
    }

    /// `K`.
    #[must_use]
    pub fn intrinsics(&self) -> DMat3 {
        intrinsic_matrix(self.fx, self.fy, self.cx, self.cy)
    }

    /// The OpenGL projection (camera space → clip space) of the undistorted pinhole with this
    /// `K`: the perspective's with `tan(θv/2) = (H/2)/fy`, `x` scaled by `2fx/W` and the principal
    /// offset `(cx + ½ − W/2, cy + ½ − H/2)`.
    #[must_use]
    pub fn projection(&self, camera: &Camera, near: f64, far: f64) -> DMat4 {
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        let pinhole = Camera {
            tan_half_vfov: 0.5 * h / self.fy,
            ..camera.clone()
        };
        let offset = DVec2::new(self.cx + 0.5 - 0.5 * w, self.cy + 0.5 - 0.5 * h);
        let mut projection = Perspective {
            principal_offset: offset,
        }
        .projection(&pinhole, near, far);
        projection.x_axis.x = 2.0 * self.fx / w;
        projection
    }

    /// The same camera for an image scaled by `(sx, sy)` (pixel edges scale, so centres move by
    /// `(c + ½)·s − ½`).
    #[must_use]
    pub fn rescaled(&self, sx: f64, sy: f64) -> Self {
        Self {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            distortion: self.distortion,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> OpenCv {
        OpenCv {
            fx: 420.0,
            fy: 415.0,
            cx: 159.3,
            cy: 121.7,
            distortion: [-0.28, 0.09, 0.0012, -0.0007, -0.012],
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let c = lens();
        for (x, y) in [(0.1, -0.2), (-0.35, 0.27), (0.0, 0.0), (0.4, 0.05)] {
            let (_, j) = c.distort(x, y);
            let h = 1e-6;
            let dx = (c.distort(x + h, y).0 - c.distort(x - h, y).0) / (2.0 * h);
            let dy = (c.distort(x, y + h).0 - c.distort(x, y - h).0) / (2.0 * h);
            for (a, b) in [(j[0][0], dx.x), (j[1][0], dx.y), (j[0][1], dy.x), (j[1][1], dy.y)] {
                assert!((a - b).abs() < 1e-8, "{a} vs {b} at ({x}, {y})");
            }
        }
    }

    #[test]
    fn undistortion_inverts_distortion_to_the_tolerance() {
        let c = lens();
        for i in 0..=20 {
            for j in 0..=20 {
                let target = DVec2::new(-0.4 + 0.04 * f64::from(i), -0.3 + 0.03 * f64::from(j));
                let p = c.undistort(target).expect("converges in the calibrated field");
                let (d, _) = c.distort(p.x, p.y);
                assert!(((d - target) * DVec2::new(c.fx, c.fy)).abs().max_element() <= UNDISTORT_TOLERANCE_PX);
            }
        }
    }

    #[test]
    fn beyond_the_fold_of_strong_barrel_distortion_there_is_no_ray() {
        // ρ = 1 − 0.5 r²: r·ρ peaks at r = √(2/3) where it is 0.544; larger distorted radii have
        // no preimage at all
        let c = OpenCv {
            distortion: [-0.5, 0.0, 0.0, 0.0, 0.0],
            ..lens()
        };
        assert!(c.undistort(DVec2::new(0.6, 0.0)).is_none());
        assert!(c.undistort(DVec2::new(0.3, 0.0)).is_some());
    }
}
