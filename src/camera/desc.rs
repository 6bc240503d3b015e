//! The RON description of a camera model, `camera: (…, model: …)`, and its validation into a
//! [`Model`].

use super::{CameraError, Equirectangular, Fisheye, Model, OpenCv, Orthographic, Perspective};
use glam::DVec2;
use serde::Deserialize;

fn default_azimuth() -> (f64, f64) {
    (-180.0, 180.0)
}
fn default_elevation() -> (f64, f64) {
    (-90.0, 90.0)
}
fn default_fisheye_fov() -> f64 {
    180.0
}

/// `model: …` of the camera: the projection (see `src/camera/` for each model's maths).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum ModelDesc {
    /// `Perspective(principal_offset: (ox, oy))`: the pinhole, field of view from `vfov_deg` /
    /// `hfov_deg`; principal point minus image centre in pixels (`+y` down), default `(0, 0)`.
    Perspective {
        /// Principal-point offset, pixels.
        #[serde(default)]
        principal_offset: DVec2,
    },
    /// `Orthographic(width: w)`: parallel rays, a frame `w` world units wide.
    Orthographic {
        /// Frame width in world units.
        width: f64,
    },
    /// `Equirectangular(azimuth_deg: (−180, 180), elevation_deg: (−90, 90))`.
    Equirectangular {
        /// Azimuth range, degrees, from `forward` towards `right`.
        #[serde(default = "default_azimuth")]
        azimuth_deg: (f64, f64),
        /// Elevation range, degrees, towards `up`.
        #[serde(default = "default_elevation")]
        elevation_deg: (f64, f64),
    },
    /// `Fisheye(fov_deg: 180)`: equidistant, field of view up to 360°.
    Fisheye {
        /// Full field of view across the image circle, degrees; default 180.
        #[serde(default = "default_fisheye_fov")]
        fov_deg: f64,
    },
    /// `OpenCv(fx: …, fy: …, cx: …, cy: …, distortion: [k1, k2, p1, p2, k3])`: OpenCV's pixel
    /// convention (pixel centres at integers); `distortion` takes 4 or 5 numbers (k3 = 0), default
    /// none.
    OpenCv {
        /// Focal length along x, pixels.
        fx: f64,
        /// Focal length along y, pixels.
        fy: f64,
        /// Principal point x.
        cx: f64,
        /// Principal point y.
        cy: f64,
        /// `[k1, k2, p1, p2(, k3)]`.
        #[serde(default)]
        distortion: Vec<f64>,
    },
}

impl ModelDesc {
    /// The model, or the problem with it.
    pub fn build(&self) -> Result<Model, CameraError> {
        Ok(match self {
            ModelDesc::Perspective { principal_offset } => Model::Perspective(Perspective {
                principal_offset: *principal_offset,
            }),
            ModelDesc::Orthographic { width } => Model::Orthographic(Orthographic { width: *width }),
            ModelDesc::Equirectangular {
                azimuth_deg,
                elevation_deg,
            } => Model::Equirectangular(Equirectangular {
                azimuth: (azimuth_deg.0.to_radians(), azimuth_deg.1.to_radians()),
                elevation: (elevation_deg.0.to_radians(), elevation_deg.1.to_radians()),
            }),
            ModelDesc::Fisheye { fov_deg } => Model::Fisheye(Fisheye {
                half_fov: 0.5 * fov_deg.to_radians(),
            }),
            ModelDesc::OpenCv {
                fx,
                fy,
                cx,
                cy,
                distortion,
            } => {
                let mut k = [0.0; 5];
                match distortion.len() {
                    0 | 4 | 5 => k[..distortion.len()].copy_from_slice(distortion),
                    n => {
                        return Err(CameraError {
                            field: "model",
                            problem: format!("OpenCv distortion takes 4 or 5 numbers [k1, k2, p1, p2, k3], got {n}"),
                        })
                    }
                }
                Model::OpenCv(OpenCv {
                    fx: *fx,
                    fy: *fy,
                    cx: *cx,
                    cy: *cy,
                    distortion: k,
                })
            }
        })
    }
}
