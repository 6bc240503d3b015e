//! The PNG previews of a render made while it is traced ([`crate::stream`]): the same pixels as
//! [`crate::output::png::write_previews`] makes from a whole frame.
//!
//! The beauty and normal previews are streamed: each band's 8-bit rows are made by the thread
//! that traced it ([`BandSink::prepare`]) and fed in order to the `png` crate's `StreamWriter`
//! (fast deflate, `Sub` filter), which writes the file as it goes. The depth preview's colours
//! depend on the nearest depth and the 98th percentile of the whole frame, so it keeps one `f32`
//! per pixel while the frame is traced and is made and encoded by [`PreviewStream::finish`].
//! Every file is written under a temporary name and renamed into place when complete
//! ([`crate::output::atomic`]).

use crate::aov::Aov;
use crate::output::atomic::AtomicFile;
use crate::output::png::{beauty_pixel, depth_pixel, depth_scale, normal_pixel, save, SrgbTable};
use crate::render::FrameLayout;
use crate::stream::BandSink;
use anyhow::{Context, Result};
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

/// Bytes the PNG stream gathers before writing an `IDAT` chunk.
const CHUNK_BYTES: usize = 1 << 20;

/// One preview being made band by band; see the module docs.
pub struct PreviewStream {
    path: PathBuf,
    aov: Aov,
    /// Offset of the AOV's first channel, and of `Alpha` if rendered, in an interleaved pixel.
    offset: usize,
    alpha: Option<usize>,
    stride: usize,
    width: u32,
    height: u32,
    background: [f32; 3],
    table: SrgbTable,
    state: Mutex<Progress>,
}

/// What the preview has so far.
enum Progress {
    /// Beauty and normal: the file, written row by row.
    Streaming {
        file: AtomicFile,
        png: png::StreamWriter<'static, File>,
    },
    /// Depth: the depths seen (see [`PreviewStream::prepare`]), one per pixel so far.
    Depths(Vec<f32>),
}

impl PreviewStream {
    /// Starts the preview of `aov` (`Beauty`, `Depth` or `Normal`, which `layout` must have) at
    /// `path`; `background` is what the beauty preview shows through uncovered pixels.
    ///
    /// # Errors
    /// The file cannot be created or its header written.
    pub fn create(path: &Path, aov: Aov, layout: &FrameLayout, background: [f32; 3]) -> Result<Self> {
        let (width, height) = (layout.window.width(), layout.window.height());
        let state = if aov == Aov::Depth {
            Progress::Depths(Vec::with_capacity(width as usize * height as usize))
        } else {
            let mut file = AtomicFile::create(path)?;
            let handle = file
                .file()
                .try_clone()
                .with_context(|| format!("opening {}", path.display()))?;
            let mut encoder = png::Encoder::new(handle, width, height);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_compression(png::Compression::Fast);
            encoder.set_filter(png::Filter::Sub);
            let png = encoder
                .write_header()
                .and_then(|w| w.into_stream_writer_with_size(CHUNK_BYTES))
                .with_context(|| format!("writing {}", path.display()))?;
            Progress::Streaming { file, png }
        };
        Ok(Self {
            path: path.to_path_buf(),
            aov,
            offset: layout
                .channel_offset(aov)
                .context("a preview of an AOV that is not rendered")?,
            alpha: layout.channel_offset(Aov::Alpha),
            stride: layout.channel_count(),
            width,
            height,
            background,
            table: SrgbTable::new(),
            state: Mutex::new(state),
        })
    }

    /// The file this preview is written to.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Completes the file (for depth: scales, colours and encodes it) and renames it into place.
    ///
    /// # Errors
    /// Encoding or a file operation fails (the destination is then untouched).
    pub fn finish(self) -> Result<()> {
        match self.state.into_inner().unwrap_or_else(PoisonError::into_inner) {
            Progress::Streaming { file, png } => {
                png.finish()
                    .with_context(|| format!("writing {}", self.path.display()))?;
                file.commit()
            }
            Progress::Depths(depths) => {
                // a depth counts for the scale when finite and positive, a hit or not (as in
                // `write_previews`); it is stored negated when it is not a hit, NaN when neither
                let mut counted: Vec<f32> = depths.iter().filter(|v| v.is_finite()).map(|v| v.abs()).collect();
                let scale = depth_scale(&mut counted);
                drop(counted);
                save(self.width, self.height, &self.path, |i| {
                    let v = depths[i];
                    depth_pixel(v, v > 0.0, scale)
                })
            }
        }
    }
}

impl BandSink for PreviewStream {
    /// The band's 8-bit RGB rows (nothing for depth).
    fn prepare(&self, _first_row: u32, rows: &[f32]) -> Result<Vec<u8>> {
        let (o, stride) = (self.offset, self.stride);
        let pixels = rows.chunks_exact(stride);
        Ok(match self.aov {
            Aov::Depth => Vec::new(),
            Aov::Beauty => pixels
                .flat_map(|p| {
                    let uncovered = self.alpha.map_or(0.0, |a| 1.0 - p[a]);
                    beauty_pixel(&self.table, &p[o..], uncovered, self.background)
                })
                .collect(),
            _ => pixels.flat_map(|p| normal_pixel(&p[o..])).collect(),
        })
    }

    fn write(&self, _first_row: u32, rows: &[f32], prepared: Vec<u8>) -> Result<()> {
        match &mut *self.state.lock().unwrap_or_else(PoisonError::into_inner) {
            Progress::Streaming { png, .. } => png
                .write_all(&prepared)
                .with_context(|| format!("writing {}", self.path.display())),
            Progress::Depths(depths) => {
                depths.extend(rows.chunks_exact(self.stride).map(|p| {
                    let z = p[self.offset];
                    let hit = self.alpha.is_none_or(|a| p[a] > 0.0);
                    match (z.is_finite() && z > 0.0, hit) {
                        (true, true) => z,
                        (true, false) => -z,
                        (false, _) => f32::NAN,
                    }
                }));
                Ok(())
            }
        }
    }
}
