//! `zeroset merge CROP.exr… -o FULL.exr`: crops of one frame (renders with `--crop`, each an EXR
//! whose data window is the crop inside the full display window) assembled into the full frame.
//!
//! The merge is a copy, not a composite: every channel (`Z = +∞` misses, ids, normals, alpha 0
//! included) keeps its exact bits. The crops must
//! - be single-part flat scanline or tiled images with the same display window,
//! - have the same channels (names and sample types) and the same header attributes apart from
//!   the data window (so they come from one camera and scene, and were rendered with the same
//!   samples per pixel: [`SPP_ATTRIBUTE`]),
//! - tile the display window: lie inside it, cover every pixel, and overlap nowhere.
//!
//! The output has the display window as its data window, the first crop's compression and all of
//! its header attributes, and is written atomically with sorted attributes
//! ([`crate::output::exr`]).

use crate::output::exr::{write_image_atomically, FlatImage};

/// The header attribute holding the samples per pixel a render used (`i32`).
pub const SPP_ATTRIBUTE: &str = "zeroset/spp";

/// A crop's samples per pixel, as its header says (read back, a single part's attributes are
/// the image's or the layer's).
fn spp_of(image: &ImageAttributes, layer: &LayerAttributes) -> String {
    let name = Text::from(SPP_ATTRIBUTE);
    match image.other.get(&name).or_else(|| layer.other.get(&name)) {
        Some(AttributeValue::I32(spp)) => format!("{spp} spp"),
        Some(other) => format!("{other:?} spp"),
        None => "an unrecorded spp".to_string(),
    }
}
use anyhow::{bail, Context, Result};
use exr::meta::attribute::IntegerBounds;
use exr::prelude::*;
use std::path::{Path, PathBuf};

/// One crop as read: its file, data window and channels.
struct Crop {
    path: PathBuf,
    bounds: IntegerBounds,
    layer: Layer<AnyChannels<FlatSamples>>,
}

/// Reads one crop and checks it has exactly one layer.
fn read_crop(path: &Path) -> Result<(ImageAttributes, Crop)> {
    let image = read_all_flat_layers_from_file(path).with_context(|| format!("reading {}", path.display()))?;
    if image.layer_data.len() != 1 {
        bail!(
            "{}: has {} layers; merge takes single-layer images",
            path.display(),
            image.layer_data.len()
        );
    }
    let layer = image.layer_data.into_iter().next().expect("one layer");
    let bounds = IntegerBounds::new(layer.attributes.layer_position, layer.size);
    Ok((
        image.attributes,
        Crop {
            path: path.to_path_buf(),
            bounds,
            layer,
        },
    ))
}

/// `(name, sample type)` of each channel, in file order.
fn channel_signature(layer: &Layer<AnyChannels<FlatSamples>>) -> Vec<(String, &'static str)> {
    // sub-sampled channels (chroma) would need their own windows: zeroset never writes them
    layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            let kind = match c.sample_data {
                FlatSamples::F16(_) => "half",
                FlatSamples::F32(_) => "float",
                FlatSamples::U32(_) => "uint",
            };
            let kind = if c.sampling == Vec2(1, 1) { kind } else { "sub-sampled" };
            (c.name.to_string(), kind)
        })
        .collect()
}

fn intersects(a: &IntegerBounds, b: &IntegerBounds) -> bool {
    let (a_end, b_end) = (a.end(), b.end());
    a.position.x() < b_end.x() && b.position.x() < a_end.x() && a.position.y() < b_end.y() && b.position.y() < a_end.y()
}

fn contains(outer: &IntegerBounds, inner: &IntegerBounds) -> bool {
    let (o_end, i_end) = (outer.end(), inner.end());
    inner.position.x() >= outer.position.x()
        && inner.position.y() >= outer.position.y()
        && i_end.x() <= o_end.x()
        && i_end.y() <= o_end.y()
}

fn describe(b: &IntegerBounds) -> String {
    let end = b.end();
    format!("[{}, {}) × [{}, {})", b.position.x(), end.x(), b.position.y(), end.y())
}

/// Copies the rows of `source` (over `from`) into `target` (over `to`, which contains `from`).
fn copy_window<T: Copy>(source: &[T], from: &IntegerBounds, target: &mut [T], to: &IntegerBounds) {
    let width = from.size.x();
    let target_width = to.size.x();
    let dx = usize::try_from(from.position.x() - to.position.x()).expect("inside");
    let dy = usize::try_from(from.position.y() - to.position.y()).expect("inside");
    for (row, values) in source.chunks_exact(width).enumerate() {
        let start = (dy + row) * target_width + dx;
        target[start..start + width].copy_from_slice(values);
    }
}

/// Merges `crops` into the full frame and writes it to `output`.
///
/// # Errors
/// A crop cannot be read, the crops disagree (display window, channels, attributes), or they do
/// not tile the display window; or writing fails (`output` is then untouched).
pub fn merge_crops(crops: &[PathBuf], output: &Path) -> Result<()> {
    let Some((first_path, rest)) = crops.split_first() else {
        bail!("merge needs at least one crop");
    };
    let (image_attributes, first) = read_crop(first_path)?;
    let display = image_attributes.display_window;
    let signature = channel_signature(&first.layer);
    if let Some((name, _)) = signature.iter().find(|(_, kind)| *kind == "sub-sampled") {
        bail!(
            "{}: channel {name} is sub-sampled; merge takes full-resolution channels",
            first_path.display()
        );
    }
    let mut all = vec![first];
    for path in rest {
        let (attributes, crop) = read_crop(path)?;
        if attributes.display_window != display {
            bail!(
                "{}: display window {} differs from {}'s {}",
                path.display(),
                describe(&attributes.display_window),
                first_path.display(),
                describe(&display)
            );
        }
        if channel_signature(&crop.layer) != signature {
            bail!(
                "{}: channels {:?} differ from {}'s {:?}",
                path.display(),
                channel_signature(&crop.layer),
                first_path.display(),
                signature
            );
        }
        let spp = spp_of(&attributes, &crop.layer.attributes);
        let first_spp = spp_of(&image_attributes, &all[0].layer.attributes);
        if spp != first_spp {
            bail!(
                "{}: rendered at {spp}, {} at {first_spp}: crops of one frame must be rendered with the \
                 same --spp",
                path.display(),
                first_path.display()
            );
        }
        let mut same_position = crop.layer.attributes.clone();
        same_position.layer_position = all[0].layer.attributes.layer_position;
        if same_position != all[0].layer.attributes || attributes != image_attributes {
            bail!(
                "{}: header attributes differ from {}'s (crops of different frames?)",
                path.display(),
                first_path.display()
            );
        }
        all.push(crop);
    }

    // tiling: inside the display window, pairwise disjoint, areas summing to the display's
    let mut covered = 0usize;
    for (i, crop) in all.iter().enumerate() {
        if !contains(&display, &crop.bounds) {
            bail!(
                "{}: data window {} is not inside the display window {}",
                crop.path.display(),
                describe(&crop.bounds),
                describe(&display)
            );
        }
        if let Some(other) = all[..i].iter().find(|o| intersects(&o.bounds, &crop.bounds)) {
            bail!(
                "{} and {} overlap: data windows {} and {}",
                other.path.display(),
                crop.path.display(),
                describe(&other.bounds),
                describe(&crop.bounds)
            );
        }
        covered += crop.bounds.size.area();
    }
    if covered != display.size.area() {
        bail!(
            "the crops cover {covered} of the display window's {} pixels {}: some pixels are missing",
            display.size.area(),
            describe(&display)
        );
    }

    let area = display.size.area();
    let first = &all[0];
    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (k, channel) in first.layer.channel_data.list.iter().enumerate() {
        let mut data = match channel.sample_data {
            FlatSamples::F16(_) => FlatSamples::F16(vec![f16::ZERO; area]),
            FlatSamples::F32(_) => FlatSamples::F32(vec![0.0; area]),
            FlatSamples::U32(_) => FlatSamples::U32(vec![0; area]),
        };
        for crop in &all {
            let source = &crop.layer.channel_data.list[k].sample_data;
            match (source, &mut data) {
                (FlatSamples::F16(s), FlatSamples::F16(t)) => copy_window(s, &crop.bounds, t, &display),
                (FlatSamples::F32(s), FlatSamples::F32(t)) => copy_window(s, &crop.bounds, t, &display),
                (FlatSamples::U32(s), FlatSamples::U32(t)) => copy_window(s, &crop.bounds, t, &display),
                _ => unreachable!("channel types were checked equal"),
            }
        }
        channels.push(AnyChannel {
            name: channel.name.clone(),
            sample_data: data,
            quantize_linearly: channel.quantize_linearly,
            sampling: channel.sampling,
        });
    }
    let mut attributes = first.layer.attributes.clone();
    attributes.layer_position = display.position;
    let layer = Layer::new(
        display.size,
        attributes,
        Encoding {
            compression: first.layer.encoding.compression,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(channels),
    );
    let image: FlatImage = Image::new(image_attributes, layer);
    write_image_atomically(&image, output)
}
