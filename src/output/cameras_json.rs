//! Camera files beside the EXRs, so other tools read the cameras without parsing scene files.
//!
//! **`NAME.cameras.json`** (always written): `{"convention": …, "views": [ … ]}` with, per view,
//!
//! | key | value |
//! |---|---|
//! | `view`, `exr` | the view's index and the EXR file it belongs to |
//! | `model` | `Perspective`, `Orthographic`, `Equirectangular`, `Fisheye` or `OpenCv` |
//! | `width`, `height` | pixels |
//! | `K` | 3×3 intrinsics, row-major, OpenCV pixel convention (pixel `(i, j)`'s centre at `(i, j)`); for `Orthographic` affine (`u = fx·X + cx`, no division by `Z`), for `Fisheye` that of `cv2.fisheye`; `null` for `Equirectangular` |
//! | `distortion` | `[k1, k2, p1, p2, k3]` for `OpenCv` (zeros for `Perspective`), `[k1, k2, k3, k4] = 0` for `Fisheye` (`cv2.fisheye`), `[]` otherwise |
//! | `R`, `t` | world → camera, `x_cam = R·x_world + t`, OpenCV axes (`+x` right, `+y` down, `+z` forward) |
//! | `parameters` | the model's own parameters (fields of view, angular ranges, frame width) |
//! | `depth` | what the `Z` channel holds for this model |
//!
//! The file lists every view of the scene whether or not this run rendered it (`--view I`), so
//! it is the same for every run of a scene and resolution.
//!
//! **`transforms.json`** (with `--transforms`, pinhole models only): the NeRF / instant-ngp
//! convention. `camera_angle_x` (horizontal field of view, radians), `camera_angle_y`, `fl_x`,
//! `fl_y`, `cx`, `cy` (instant-ngp's: the ray through pixel `(i, j)` has camera direction
//! `((i + ½ − cx)/fl_x, −(j + ½ − cy)/fl_y, −1)`), `w`, `h`, `k1`, `k2`, `p1`, `p2`, and per frame
//! `file_path` and `transform_matrix`, the camera-to-world matrix (rows) with OpenGL axes (`+x`
//! right, `+y` up, looking along `−z`).

use crate::camera::{Camera, Model};
use exr::meta::attribute::{AttributeValue, Text};
use glam::{DMat3, DMat4};
use serde_json::{json, Value};

/// Rows of a 3×3 matrix.
fn rows3(m: &DMat3) -> Value {
    json!((0..3)
        .map(|r| (0..3).map(|c| m.col(c)[r]).collect::<Vec<_>>())
        .collect::<Vec<_>>())
}

/// Rows of a 4×4 matrix.
fn rows4(m: &DMat4) -> Value {
    json!((0..4)
        .map(|r| (0..4).map(|c| m.col(c)[r]).collect::<Vec<_>>())
        .collect::<Vec<_>>())
}

/// What `Z` holds for `camera`'s model, in words.
#[must_use]
pub fn depth_meaning(camera: &Camera) -> &'static str {
    if camera.model.planar_depth() {
        "planar: distance along the view axis (forward) from the eye plane"
    } else {
        "ray distance from the eye"
    }
}

/// The model's own parameters.
fn parameters(camera: &Camera) -> Value {
    match &camera.model {
        Model::Perspective(p) => json!({
            "vfov_deg": 2.0 * camera.tan_half_vfov.atan().to_degrees(),
            "hfov_deg": 2.0 * camera.tan_half_hfov().atan().to_degrees(),
            "principal_offset": [p.principal_offset.x, p.principal_offset.y],
        }),
        Model::Orthographic(o) => json!({
            "frame_width": o.width,
            "frame_height": o.width * f64::from(camera.height) / f64::from(camera.width),
        }),
        Model::Equirectangular(e) => json!({
            "azimuth_deg": [e.azimuth.0.to_degrees(), e.azimuth.1.to_degrees()],
            "elevation_deg": [e.elevation.0.to_degrees(), e.elevation.1.to_degrees()],
        }),
        Model::Fisheye(f) => json!({ "fov_deg": 2.0 * f.half_fov.to_degrees(), "projection": "equidistant" }),
        Model::OpenCv(_) => json!({}),
    }
}

/// The distortion coefficients as camera files write them (table above).
fn distortion(camera: &Camera) -> Vec<f64> {
    match &camera.model {
        Model::OpenCv(c) => c.distortion.to_vec(),
        Model::Perspective(_) => vec![0.0; 5],
        Model::Fisheye(_) => vec![0.0; 4],
        Model::Orthographic(_) | Model::Equirectangular(_) => Vec::new(),
    }
}

/// One view's entry of `cameras.json`.
#[must_use]
pub fn camera_entry(camera: &Camera, view: usize, exr: &str) -> Value {
    let (rotation, translation) = camera.opencv_extrinsics();
    json!({
        "view": view,
        "exr": exr,
        "model": camera.model.name(),
        "width": camera.width,
        "height": camera.height,
        "K": camera.intrinsics().map(|k| rows3(&k)),
        "distortion": distortion(camera),
        "R": rows3(&rotation),
        "t": [translation.x, translation.y, translation.z],
        "parameters": parameters(camera),
        "depth": depth_meaning(camera),
    })
}

/// `cameras.json` for `views` (camera and EXR file name each).
#[must_use]
pub fn cameras_json(views: &[(&Camera, String)]) -> String {
    let entries: Vec<Value> = views
        .iter()
        .enumerate()
        .map(|(index, (camera, exr))| camera_entry(camera, index, exr))
        .collect();
    let document = json!({
        "convention": "OpenCV: x_cam = R·x_world + t, +x right, +y down, +z forward; K in pixels with pixel (i, j) centred at (i, j)",
        "views": entries,
    });
    serde_json::to_string_pretty(&document).expect("JSON values serialise") + "\n"
}

/// `transforms.json` (NeRF / instant-ngp) for `views`, which share one pinhole camera model;
/// errors for other models.
pub fn transforms_json(views: &[(&Camera, String)]) -> Result<String, String> {
    let Some((first, _)) = views.first() else {
        return Err("no views".into());
    };
    let (fx, fy, cx, cy, k) = match &first.model {
        Model::Perspective(_) | Model::OpenCv(_) => {
            let k = first.intrinsics().expect("pinhole models have K");
            let d = distortion(first);
            (k.x_axis.x, k.y_axis.y, k.z_axis.x + 0.5, k.z_axis.y + 0.5, d)
        }
        other => {
            return Err(format!(
                "transforms.json (NeRF) describes pinhole cameras only, not {}",
                other.name()
            ))
        }
    };
    let (w, h) = (f64::from(first.width), f64::from(first.height));
    let frames: Vec<Value> = views
        .iter()
        .map(|(camera, file)| json!({ "file_path": file, "transform_matrix": rows4(&camera.camera_to_world()) }))
        .collect();
    let document = json!({
        "camera_angle_x": 2.0 * (0.5 * w / fx).atan(),
        "camera_angle_y": 2.0 * (0.5 * h / fy).atan(),
        "fl_x": fx,
        "fl_y": fy,
        "cx": cx,
        "cy": cy,
        "w": first.width,
        "h": first.height,
        "k1": k[0],
        "k2": k[1],
        "p1": k[2],
        "p2": k[3],
        "k3": k[4],
        "frames": frames,
    });
    Ok(serde_json::to_string_pretty(&document).expect("JSON values serialise") + "\n")
}

/// EXR header attributes with the camera's intrinsics: `zeroset/camera/model` (text),
/// `zeroset/camera/K` (3×3, row-major, f32), `zeroset/camera/fx`, `…/fy`, `…/cx`, `…/cy` (f64,
/// OpenCV pixel convention), `zeroset/camera/distortion` (text, the coefficients), and
/// `zeroset/camera/json` (this view's `cameras.json` entry, full precision, without the file
/// name: crops of one frame, and a file renamed later, carry the same header, so
/// `zeroset merge` can check that crops belong together).
#[must_use]
pub fn exr_camera_attributes(camera: &Camera, view: usize) -> Vec<(String, AttributeValue)> {
    let mut entry = camera_entry(camera, view, "");
    if let Some(fields) = entry.as_object_mut() {
        fields.remove("exr");
    }
    let mut attributes = vec![
        (
            "zeroset/camera/model".to_string(),
            AttributeValue::Text(Text::from(camera.model.name())),
        ),
        (
            "zeroset/camera/depth".to_string(),
            AttributeValue::Text(Text::from(depth_meaning(camera))),
        ),
        (
            "zeroset/camera/json".to_string(),
            AttributeValue::Text(Text::from(entry.to_string().as_str())),
        ),
    ];
    if let Some(k) = camera.intrinsics() {
        let rows = k.transpose().to_cols_array().map(|v| v as f32);
        attributes.push(("zeroset/camera/K".to_string(), AttributeValue::Matrix3x3(rows)));
        for (name, value) in [
            ("fx", k.x_axis.x),
            ("fy", k.y_axis.y),
            ("cx", k.z_axis.x),
            ("cy", k.z_axis.y),
        ] {
            attributes.push((format!("zeroset/camera/{name}"), AttributeValue::F64(value)));
        }
    }
    let d = distortion(camera);
    if !d.is_empty() {
        attributes.push((
            "zeroset/camera/distortion".to_string(),
            AttributeValue::Text(Text::from(format!("{d:?}").as_str())),
        ));
    }
    attributes
}
