//! Query rays from a camera: `zeroset query SCENE --pixels PIXELS.csv [--camera CAMERA_SCENE]`.
//!
//! Input: one pixel per line, `x,y` or `x,y,view`: an image position in zeroset's pixel
//! convention (pixel `(i, j)` of the EXR has its centre at `(i + ½, j + ½)`, so `10.5,20.5` is
//! the exact ray of EXR pixel `(10, 20)`; fractional positions are allowed) and, for a scene
//! with `views`, the view index (default 0). Blank lines and `#` comments are skipped, and so is
//! a non-numeric first line (a header). The camera is that of `--camera` (a scene file whose
//! camera and views are used) or else the queried scene's. Each pixel becomes the camera's unit
//! ray with `t ∈ (0, ∞)`, the same ray a render traces there, so `t` is the `distance` AOV.
//! A position with no ray (outside a fisheye's image circle, or where the lens undistortion does
//! not converge) is an error naming the line.

use crate::camera::Camera;
use crate::query::QueryRay;
use crate::scene::Scene;
use std::path::Path;
use zeroset_primitives::Interval;

/// A malformed or ray-less line of the pixel file.
#[derive(Debug, thiserror::Error)]
#[error("{path}:{line}: {message}")]
pub struct PixelsError {
    /// The pixel file.
    pub path: String,
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// The cameras pixel files may refer to: the scene's views, or its camera when it has none.
#[must_use]
pub fn scene_cameras(scene: &Scene) -> Vec<&Camera> {
    if scene.views.is_empty() {
        vec![&scene.camera]
    } else {
        scene.views.iter().collect()
    }
}

/// Parses the pixel list (module docs) into query rays through `cameras`.
pub fn pixel_rays(text: &str, path: &str, cameras: &[&Camera]) -> Result<Vec<QueryRay>, PixelsError> {
    let mut rays = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let err = |message: String| PixelsError {
            path: path.to_string(),
            line: index + 1,
            message,
        };
        let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
        let Ok(numbers) = fields.iter().map(|f| f.parse::<f64>()).collect::<Result<Vec<_>, _>>() else {
            if index == 0 {
                continue; // header
            }
            return Err(err(format!("expected numbers `x,y[,view]`, got `{trimmed}`")));
        };
        if numbers.len() != 2 && numbers.len() != 3 {
            return Err(err(format!(
                "expected 2 or 3 fields `x,y[,view]`, got {}",
                numbers.len()
            )));
        }
        let (x, y) = (numbers[0], numbers[1]);
        if !(x.is_finite() && y.is_finite()) {
            return Err(err("the image position must be finite".into()));
        }
        let view = match numbers.get(2) {
            None => 0,
            Some(&v) if v >= 0.0 && v.fract() == 0.0 && (v as usize) < cameras.len() => v as usize,
            Some(&v) => {
                return Err(err(format!(
                    "view {v} does not exist (the camera has views 0 to {})",
                    cameras.len() - 1
                )))
            }
        };
        let ray = cameras[view]
            .ray_through(x, y)
            .map_err(|reason| err(format!("image position ({x}, {y}) of view {view} has no ray: {reason}")))?;
        rays.push(QueryRay {
            ray,
            range: Interval::POSITIVE,
        });
    }
    Ok(rays)
}

/// Reads the pixel file `pixels` and makes rays through the camera of scene file `camera`
/// (loaded here), or through `scene`'s own camera when `camera` is `None`.
pub fn pixel_rays_from_files(scene: &Scene, camera: Option<&Path>, pixels: &Path) -> anyhow::Result<Vec<QueryRay>> {
    use anyhow::Context;
    let text = crate::resources::read_input_to_string(pixels, "pixel file")
        .with_context(|| format!("reading {}", pixels.display()))?;
    let path = pixels.display().to_string();
    Ok(match camera {
        None => pixel_rays(&text, &path, &scene_cameras(scene))?,
        Some(file) => {
            let other = Scene::load(file)?;
            pixel_rays(&text, &path, &scene_cameras(&other))?
        }
    })
}
