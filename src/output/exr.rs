//! EXR output: one single-part scanline file, `FLOAT` channels, ZIP compression (16 scanlines
//! per block), channel names as in [`crate::aov`].
//!
//! The display window is the full image; the data window is the rendered part (the crop, or the
//! whole image). Header attributes: `worldToCamera` and `worldToNDC` (the OpenEXR standard
//! attributes, Imath row-vector convention, camera looking along −z; NDC near/far 0.01/1000),
//! `zeroset/scene` (the scene file), `zeroset/depth` (the depth convention in words) and
//! `zeroset/depthMiss` (the value written where nothing was hit), and the camera's intrinsics
//! from [`crate::output::cameras_json::exr_camera_attributes`] (`zeroset/camera/…`).

use crate::render::Frame;
use exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use exr::prelude::*;
use glam::DMat4;
use std::path::Path;

/// Scene facts recorded in the header.
#[derive(Clone, Debug)]
pub struct ExrHeader {
    /// World → camera matrix.
    pub world_to_camera: DMat4,
    /// World → NDC matrix (`None` for cameras without a linear projection: no attribute).
    pub world_to_ndc: Option<DMat4>,
    /// The scene file.
    pub scene_file: String,
    /// Value written to depth channels on a miss.
    pub depth_miss: f32,
    /// Further header attributes (the camera's intrinsics), by name.
    pub camera_attributes: Vec<(String, AttributeValue)>,
}

/// The Imath (row-vector, row-major) layout of a column-vector matrix: the transpose, which is
/// `m`'s column-major array.
fn imath_matrix(m: &DMat4) -> [f32; 16] {
    m.to_cols_array().map(|x| x as f32)
}

/// Writes `frame` to `path`.
pub fn write_exr(frame: &Frame, path: &Path, header: &ExrHeader) -> std::result::Result<(), exr::error::Error> {
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for aov in &frame.aovs {
        for (component, name) in aov.channels().iter().enumerate() {
            list.push(AnyChannel::new(
                *name,
                FlatSamples::F32(frame.planar_channel(*aov, component)),
            ));
        }
    }
    let window = frame.window;
    let attributes = LayerAttributes {
        layer_position: Vec2(window.x0 as i32, window.y0 as i32),
        world_to_camera: Some(imath_matrix(&header.world_to_camera)),
        world_to_normalized_device: header.world_to_ndc.as_ref().map(imath_matrix),
        ..LayerAttributes::default()
    };
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        Vec2(window.width() as usize, window.height() as usize),
        attributes,
        encoding,
        AnyChannels::sort(list),
    );
    let mut image_attributes = ImageAttributes::new(IntegerBounds::new(
        Vec2(0, 0),
        Vec2(frame.width as usize, frame.height as usize),
    ));
    let other = &mut image_attributes.other;
    other.insert(
        Text::from("zeroset/scene"),
        AttributeValue::Text(Text::from(header.scene_file.as_str())),
    );
    other.insert(
        Text::from("zeroset/depth"),
        AttributeValue::Text(Text::from(
            "Z: camera-space planar depth along the view axis (Perspective, OpenCv, Orthographic cameras; ray distance for Equirectangular, Fisheye: see zeroset/camera/depth); distance: ray distance from the eye (unit-length rays)",
        )),
    );
    other.insert(Text::from("zeroset/depthMiss"), AttributeValue::F32(header.depth_miss));
    for (name, value) in &header.camera_attributes {
        other.insert(Text::from(name.as_str()), value.clone());
    }
    Image::new(image_attributes, layer).write().to_file(path)
}
