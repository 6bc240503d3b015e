//! EXR output: one single-part scanline file, `FLOAT` channels, channel names as in
//! [`crate::aov`], compression chosen by [`ExrCompression`]. The default is no compression: with
//! the `exr` crate's encoders, RLE takes 2–3.3× its CPU time for 55–70 % of the size and deflate
//! (ZIPS/ZIP) 7–22× for 13–40 % (the README's codec table), and only uncompressed output keeps a
//! 4K render's write within half its trace time.
//!
//! The display window is the full image; the data window is the rendered part (the crop, or the
//! whole image). Header attributes: `worldToCamera` and `worldToNDC` (the OpenEXR standard
//! attributes, Imath row-vector convention, camera looking along −z; NDC near/far 0.01/1000),
//! `zeroset/scene` (the scene file), `zeroset/depth` (the depth convention in words) and
//! `zeroset/depthMiss` (the value written where nothing was hit), and the camera's intrinsics
//! from [`crate::output::cameras_json::exr_camera_attributes`] (`zeroset/camera/…`).
//!
//! **Deterministic bytes**: the `exr` crate keeps custom attributes in a hash map, so their order
//! would change from run to run; after writing, the header's attributes are sorted by name (the
//! order the OpenEXR reference library writes). Reordering does not change the header's length,
//! so the offset table stays valid. Identical frames give identical files.
//!
//! **Atomic**: the file is written next to its destination under a temporary name and renamed
//! into place ([`crate::output::atomic`]).
//!
//! `zeroset render` writes the same file band by band while the frame is traced
//! ([`crate::output::exr_stream`]); this module writes it from a whole [`Frame`] (views, merge,
//! Python).

use crate::aov::Aov;
use crate::output::atomic::AtomicFile;
use crate::render::{Frame, FrameLayout};
use anyhow::{bail, Context, Result};
use exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use exr::prelude::*;
use glam::DMat4;
use rayon::prelude::*;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

/// A single-layer image of flat `f32` channels, as zeroset writes and `zeroset merge` reads.
pub type FlatImage = Image<Layer<AnyChannels<FlatSamples>>>;

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

/// The lossless EXR codecs the `exr` crate writes (PXR24 and B44 are lossy for `f32`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ExrCompression {
    /// No compression: the fastest to write, the largest files (the default).
    #[default]
    None,
    /// Run-length encoding.
    Rle,
    /// Deflate per scanline (`ZIPS_COMPRESSION`).
    Zips,
    /// Deflate per block of 16 scanlines (`ZIP_COMPRESSION`).
    Zip,
    /// Wavelet + Huffman (`PIZ_COMPRESSION`).
    Piz,
}

impl ExrCompression {
    /// All codecs, in the order above.
    pub const ALL: [ExrCompression; 5] = [Self::None, Self::Rle, Self::Zips, Self::Zip, Self::Piz];

    /// The `exr` crate's value.
    #[must_use]
    pub fn codec(self) -> Compression {
        match self {
            Self::None => Compression::Uncompressed,
            Self::Rle => Compression::RLE,
            Self::Zips => Compression::ZIP1,
            Self::Zip => Compression::ZIP16,
            Self::Piz => Compression::PIZ,
        }
    }
}

/// The Imath (row-vector, row-major) layout of a column-vector matrix: the transpose, which is
/// `m`'s column-major array.
fn imath_matrix(m: &DMat4) -> [f32; 16] {
    m.to_cols_array().map(|x| x as f32)
}

/// Upper bound of the file size of an uncompressed EXR with `channels` float channels over
/// `pixels` pixels (samples, plus the offset table and headers): what the free-space check uses.
#[must_use]
pub fn size_estimate(pixels: u64, channels: u64, rows: u64) -> u64 {
    pixels * channels * 4 + rows * 16 + 64 * 1024
}

/// Writes `frame` to `path` (atomically) with the default compression.
///
/// # Errors
/// Encoding or any file operation fails; `path` is then untouched.
pub fn write_exr(frame: &Frame, path: &Path, header: &ExrHeader) -> Result<()> {
    write_exr_with(frame, path, header, ExrCompression::default())
}

/// Writes `frame` to `path` (atomically) with `compression`.
///
/// # Errors
/// Encoding or any file operation fails; `path` is then untouched.
pub fn write_exr_with(frame: &Frame, path: &Path, header: &ExrHeader, compression: ExrCompression) -> Result<()> {
    // the interleaved frame split into planar channels, one channel per task
    let layout = frame.layout();
    let planes: Vec<Vec<f32>> = frame_channels(&layout)
        .par_iter()
        .map(|(aov, component, _, _)| frame.planar_channel(*aov, *component))
        .collect();
    write_image_atomically(&flat_image(&layout, planes, header, compression), path)
}

/// Every channel of a frame of `layout`, in the frame's order: its AOV, its component within the
/// AOV, its EXR name and its offset within an interleaved pixel.
pub(crate) fn frame_channels(layout: &FrameLayout) -> Vec<(Aov, usize, &'static str, usize)> {
    let mut offset = 0;
    let mut channels = Vec::new();
    for aov in &layout.aovs {
        for (component, name) in aov.channels().iter().enumerate() {
            channels.push((*aov, component, *name, offset));
            offset += 1;
        }
    }
    channels
}

/// The EXR image of a frame of `layout`: `planes` are the channels in the order of
/// [`frame_channels`] (empty vectors describe the file without its pixels, as the streaming
/// writer needs), `header` its attributes.
pub(crate) fn flat_image(
    layout: &FrameLayout,
    planes: Vec<Vec<f32>>,
    header: &ExrHeader,
    compression: ExrCompression,
) -> FlatImage {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = frame_channels(layout)
        .iter()
        .zip(planes)
        .map(|((_, _, name, _), plane)| AnyChannel::new(*name, FlatSamples::F32(plane)))
        .collect();
    let window = layout.window;
    let attributes = LayerAttributes {
        layer_position: Vec2(window.x0 as i32, window.y0 as i32),
        world_to_camera: Some(imath_matrix(&header.world_to_camera)),
        world_to_normalized_device: header.world_to_ndc.as_ref().map(imath_matrix),
        ..LayerAttributes::default()
    };
    let encoding = Encoding {
        compression: compression.codec(),
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
        Vec2(layout.width as usize, layout.height as usize),
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
    Image::new(image_attributes, layer)
}

/// Writes any single-part flat image atomically, with its header attributes sorted by name.
///
/// # Errors
/// Encoding or any file operation fails; `path` is then untouched.
pub fn write_image_atomically(image: &FlatImage, path: &Path) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    {
        let mut writer = BufWriter::with_capacity(1 << 20, file.file());
        image
            .write()
            .to_buffered(&mut writer)
            .with_context(|| format!("encoding {}", path.display()))?;
        writer.flush().with_context(|| format!("writing {}", path.display()))?;
    }
    sort_header_attributes(file.file()).with_context(|| format!("writing the header of {}", path.display()))?;
    file.commit()
}

/// Sorts the attributes of a single-part EXR header by name, in place (see the module docs).
pub(crate) fn sort_header_attributes(file: &mut std::fs::File) -> Result<()> {
    const HEADER_START: u64 = 8; // magic number and version field
    let mut magic_and_version = [0u8; 8];
    file.seek(SeekFrom::Start(0))?;
    file.read_exact(&mut magic_and_version)?;
    if magic_and_version[..4] != [0x76, 0x2f, 0x31, 0x01] || magic_and_version[5] & 0x10 != 0 {
        bail!("not a single-part EXR file");
    }
    // headers are small (here about a kilobyte); a megabyte is plenty
    let mut head = Vec::new();
    Read::by_ref(file).take(1 << 20).read_to_end(&mut head)?;
    let (mut attributes, end) = split_attributes(&head)?;
    attributes.sort_by(|a, b| a.0.cmp(b.0));
    let sorted: Vec<u8> = attributes.iter().flat_map(|a| a.1.iter().copied()).collect();
    debug_assert_eq!(sorted.len(), end);
    file.seek(SeekFrom::Start(HEADER_START))?;
    file.write_all(&sorted)?;
    Ok(())
}

/// An attribute's name and its whole encoding (name, type, size, value).
type RawAttribute<'a> = (&'a [u8], &'a [u8]);

/// `(name, whole attribute bytes)` for each attribute of the header at the start of `bytes`, and
/// the header's length without its terminating zero byte.
fn split_attributes(bytes: &[u8]) -> Result<(Vec<RawAttribute<'_>>, usize)> {
    let mut attributes = Vec::new();
    let mut at = 0;
    let zero_after = |from: usize| -> Result<usize> {
        bytes[from..]
            .iter()
            .position(|b| *b == 0)
            .map(|p| from + p)
            .context("truncated EXR header")
    };
    loop {
        let name_end = zero_after(at)?;
        if name_end == at {
            return Ok((attributes, at));
        }
        let type_end = zero_after(name_end + 1)?;
        let size_at = type_end + 1;
        let size_bytes: [u8; 4] = bytes
            .get(size_at..size_at + 4)
            .context("truncated EXR header")?
            .try_into()?;
        let size = usize::try_from(i32::from_le_bytes(size_bytes)).context("negative attribute size")?;
        let end = size_at + 4 + size;
        if end > bytes.len() {
            bail!("truncated EXR header");
        }
        attributes.push((&bytes[at..name_end], &bytes[at..end]));
        at = end;
    }
}
