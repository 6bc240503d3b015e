//! Camera poses for many views per run: the scene's `views: [...]` list.
//!
//! Each entry is one of
//!
//! - `LookAt(eye: (x, y, z), look_at: (x, y, z), up: (0, 1, 0))` (`up` optional, default `+Y`);
//! - `CameraToWorld(matrix: [[…4], […4], […4], [0, 0, 0, 1]], axes: OpenGl)`: a 4×4
//!   camera-to-world matrix written row by row, whose rotation columns are the camera axes in
//!   world space and whose last column is the eye. With `axes: OpenGl` (the default; NeRF's and
//!   the EXR `worldToCamera` convention) the columns are right, up, backward (the camera looks
//!   along `−z`); with `axes: OpenCv` they are right, down, forward. The rotation must be
//!   orthonormal and right-handed within 1e-6, the last row `(0, 0, 0, 1)`;
//! - `File("poses.txt")`: a text file (relative to the scene file) with one view per line:
//!   9 numbers `eye look_at up`, or 16 numbers, a row-major OpenGL camera-to-world matrix;
//!   separated by spaces or commas; blank lines and `#` comments are skipped.
//!
//! Every view shares the scene camera's model, resolution, lens and shutter; only the pose
//! changes (the `camera`'s own pose is not rendered when `views` is given).

use super::Camera;
use crate::resources::{ensure_memory, read_input_to_string, NotEnoughMemory};
use glam::{DMat3, DVec3};
use serde::Deserialize;
use std::path::Path;

fn default_up() -> DVec3 {
    DVec3::Y
}

/// Which camera axes a camera-to-world matrix's columns are.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum Axes {
    /// Right, up, backward (looking along `−z`).
    #[default]
    OpenGl,
    /// Right, down, forward.
    OpenCv,
}

/// One entry of `views` (module docs).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum ViewDesc {
    /// Eye, target and up.
    LookAt {
        /// Eye position.
        eye: DVec3,
        /// Point looked at.
        look_at: DVec3,
        /// Up vector; default `+Y`.
        #[serde(default = "default_up")]
        up: DVec3,
    },
    /// A 4×4 camera-to-world matrix, row by row.
    CameraToWorld {
        /// The rows.
        matrix: Vec<Vec<f64>>,
        /// The axes convention of its columns; default `OpenGl`.
        #[serde(default)]
        axes: Axes,
    },
    /// A pose file.
    File(String),
}

/// `(eye, direction, up)` of a camera-to-world matrix given as rows, checked.
pub fn pose_from_matrix(rows: &[Vec<f64>], axes: Axes) -> Result<(DVec3, DVec3, DVec3), String> {
    if rows.len() != 4 || rows.iter().any(|r| r.len() != 4) {
        return Err("the matrix must have 4 rows of 4 numbers".into());
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err("the matrix must be finite".into());
    }
    if (rows[3][0].abs() + rows[3][1].abs() + rows[3][2].abs() + (rows[3][3] - 1.0).abs()) > 1e-9 {
        return Err(format!("the last row must be (0, 0, 0, 1), got {:?}", rows[3]));
    }
    let column = |k: usize| DVec3::new(rows[0][k], rows[1][k], rows[2][k]);
    let rotation = DMat3::from_cols(column(0), column(1), column(2));
    let gram = rotation.transpose() * rotation;
    let off = (gram - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if off > 1e-6 || rotation.determinant() <= 0.0 {
        return Err(format!(
            "the rotation part must be orthonormal and right-handed (|RᵀR − I| = {off:.2e}, det = {:.6})",
            rotation.determinant()
        ));
    }
    let (direction, up) = match axes {
        Axes::OpenGl => (-column(2), column(1)),
        Axes::OpenCv => (column(2), -column(1)),
    };
    Ok((column(3), direction, up))
}

/// Parses a pose file (module docs) into `(eye, direction, up)` triples; errors name
/// `path:line`.
pub fn parse_pose_file(text: &str, path: &str) -> Result<Vec<(DVec3, DVec3, DVec3)>, String> {
    let mut poses = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = |m: String| format!("{path}:{}: {m}", index + 1);
        let numbers: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .map(|f| f.parse::<f64>().map_err(|_| at(format!("`{f}` is not a number"))))
            .collect::<Result<_, _>>()?;
        let v = |k: usize| DVec3::new(numbers[k], numbers[k + 1], numbers[k + 2]);
        match numbers.len() {
            9 => poses.push((v(0), v(3) - v(0), v(6))),
            16 => {
                let rows: Vec<Vec<f64>> = numbers.chunks(4).map(<[f64]>::to_vec).collect();
                poses.push(pose_from_matrix(&rows, Axes::OpenGl).map_err(at)?);
            }
            n => {
                return Err(at(format!(
                    "expected 9 numbers (eye look_at up) or 16 (a 4×4 matrix), got {n}"
                )))
            }
        }
    }
    if poses.is_empty() {
        return Err(format!("{path}: no views in the file"));
    }
    Ok(poses)
}

/// The cameras of `views`: `base` (model, resolution, lens, shutter) at each pose, with files
/// resolved against `scene_dir`. Errors are `(location, message)` as scene validation reports.
pub fn build_views(views: &[ViewDesc], base: &Camera, scene_dir: &Path) -> Result<Vec<Camera>, (String, String)> {
    let mut cameras = Vec::new();
    for (index, view) in views.iter().enumerate() {
        let location = format!("views[{index}]");
        let place = |eye: DVec3, direction: DVec3, up: DVec3| {
            base.with_pose(eye, direction, up)
                .map_err(|e| (location.clone(), format!("field `{}`: {}", e.field, e.problem)))
        };
        match view {
            ViewDesc::LookAt { eye, look_at, up } => {
                if !look_at.is_finite() {
                    return Err((location, format!("field `look_at`: must be finite, got {look_at}")));
                }
                cameras.push(place(*eye, *look_at - *eye, *up)?);
            }
            ViewDesc::CameraToWorld { matrix, axes } => {
                let (eye, direction, up) =
                    pose_from_matrix(matrix, *axes).map_err(|m| (location.clone(), format!("field `matrix`: {m}")))?;
                cameras.push(place(eye, direction, up)?);
            }
            ViewDesc::File(file) => {
                let path = scene_dir.join(file);
                let shown = path.display().to_string();
                let text = read_input_to_string(&path, "pose file")
                    .map_err(|e| (location.clone(), format!("{shown}: {e}")))?;
                // at most a pose a line, parsed and then a camera each: guarded before either
                let lines = text.lines().count();
                let per_pose = std::mem::size_of::<(DVec3, DVec3, DVec3)>() + std::mem::size_of::<Camera>();
                ensure_memory(
                    &format!("{shown}: {lines} lines of poses"),
                    (lines as u64).saturating_mul(per_pose as u64),
                )
                .and_then(|()| {
                    cameras.try_reserve(lines).map_err(|_| NotEnoughMemory {
                        what: format!("{shown}: {lines} lines of poses"),
                        needed: (lines as u64).saturating_mul(per_pose as u64),
                        room: None,
                    })
                })
                .map_err(|e| (location.clone(), e.to_string()))?;
                for (eye, direction, up) in parse_pose_file(&text, &shown).map_err(|m| (location.clone(), m))? {
                    cameras.push(
                        base.with_pose(eye, direction, up)
                            .map_err(|e| (location.clone(), format!("{shown}: field `{}`: {}", e.field, e.problem)))?,
                    );
                }
            }
        }
    }
    Ok(cameras)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrix_poses_in_both_conventions_give_the_same_camera() {
        // looking along +x from (1, 2, 3), up +y: right = f × up = +z
        let gl = vec![
            vec![0.0, 0.0, -1.0, 1.0],
            vec![0.0, 1.0, 0.0, 2.0],
            vec![1.0, 0.0, 0.0, 3.0],
            vec![0.0, 0.0, 0.0, 1.0],
        ];
        let cv = vec![
            vec![0.0, 0.0, 1.0, 1.0],
            vec![0.0, -1.0, 0.0, 2.0],
            vec![1.0, 0.0, 0.0, 3.0],
            vec![0.0, 0.0, 0.0, 1.0],
        ];
        let a = pose_from_matrix(&gl, Axes::OpenGl).unwrap();
        let b = pose_from_matrix(&cv, Axes::OpenCv).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.1, DVec3::X);
        let camera = Camera::new(a.0, a.1, a.2, 40.0, 8, 8).unwrap();
        assert!((camera.right - DVec3::Z).length() < 1e-15);
        // and the camera's own camera-to-world matrix is the one given
        let m = camera.camera_to_world();
        for (r, row) in gl.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                assert!((m.col(c)[r] - v).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn bad_matrices_and_pose_lines_are_errors() {
        let scaled = vec![
            vec![2.0, 0.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0, 0.0],
            vec![0.0, 0.0, 1.0, 0.0],
            vec![0.0, 0.0, 0.0, 1.0],
        ];
        assert!(pose_from_matrix(&scaled, Axes::OpenGl)
            .unwrap_err()
            .contains("orthonormal"));
        assert!(pose_from_matrix(&scaled[..3], Axes::OpenGl)
            .unwrap_err()
            .contains("4 rows"));
        let e = parse_pose_file("# orbit\n0 0 -5 0 0 0 0 1 0\n1 2 3\n", "p.txt").unwrap_err();
        assert!(e.starts_with("p.txt:3:"), "{e}");
        let e = parse_pose_file("0 0 -5 0 0 x 0 1 0\n", "p.txt").unwrap_err();
        assert!(e.contains("p.txt:1:") && e.contains("`x`"), "{e}");
        assert_eq!(
            parse_pose_file("0,0,-5, 0,0,0, 0,1,0 # a comment\n", "p")
                .unwrap()
                .len(),
            1
        );
    }
}
