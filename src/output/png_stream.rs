//! The PNG previews of a render made while it is traced ([`crate::render::stream`]): the same pixels as
//! [`crate::output::png::write_previews`] makes from a whole frame.
//!
//! The beauty and normal previews are streamed: each band's 8-bit rows are made by the thread
//! that traced it ([`BandSink::prepare`]) and fed in order to the `png` crate's `StreamWriter`
//! (fast deflate, `Sub` filter), which writes the file as it goes. The depth preview's colours
//! depend on the nearest depth and the 98th percentile of the whole frame, so it keeps two `f32`
//! per pixel (the depth and its logarithm) and a histogram while the frame is traced, and is
//! coloured and encoded by [`PreviewStream::finish`].
//! Every file is written under a temporary name and renamed into place when complete
//! ([`crate::output::atomic`]).

use crate::aov::Aov;
use crate::output::atomic::AtomicFile;
use crate::output::png::{beauty_pixel, depth_pixel_of_log, depth_scale_of, normal_pixel, save, SrgbTable};
use crate::render::stream::BandSink;
use crate::render::FrameLayout;
use anyhow::{Context, Result};
use rayon::prelude::*;
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
    table: &'static SrgbTable,
    state: Mutex<Progress>,
}

/// What the preview has so far.
enum Progress {
    /// Beauty and normal: the file, written row by row.
    Streaming {
        file: AtomicFile,
        png: Box<png::StreamWriter<'static, File>>,
    },
    /// Depth: what the scale and the colours need, gathered band by band.
    Depths(DepthPlane),
}

/// The depth preview's data so far. A depth counts for the scale when it is finite and positive,
/// a hit or not (as in `write_previews`); a pixel is coloured when it is a hit at a counted
/// depth. The 98th percentile is found exactly without a selection over the whole frame: a
/// histogram of the counted depths by the top 16 bits of their `f32` pattern (ordered like the
/// values for positive numbers) gives the bin holding the wanted rank, and only that bin's
/// depths are selected from.
struct DepthPlane {
    /// Per pixel: the depth `z` if coloured, `−z` if counted but not coloured (a counted depth is
    /// positive), NaN if not counted. The logarithms of the coloured ones are taken when the
    /// preview is coloured ([`DepthPlane::log`]), in parallel, not pixel by pixel as the bands
    /// are written in order.
    depths: Vec<f32>,
    /// Counted depths per bin of `bits >> 16`.
    histogram: Vec<u64>,
    /// The nearest counted depth (`+∞` before any).
    nearest: f32,
}

impl DepthPlane {
    fn with_capacity(pixels: usize) -> Self {
        Self {
            depths: Vec::with_capacity(pixels),
            histogram: vec![0; 1 << 16],
            nearest: f32::INFINITY,
        }
    }

    fn push(&mut self, z: f32, hit: bool) {
        let counts = z.is_finite() && z > 0.0;
        if counts {
            self.histogram[(z.to_bits() >> 16) as usize] += 1;
            self.nearest = self.nearest.min(z);
        }
        self.depths.push(match (counts, hit) {
            (true, true) => z,
            (true, false) => -z,
            (false, _) => f32::NAN,
        });
    }

    /// `ln z` of pixel `i` if coloured, else NaN.
    fn log(&self, i: usize) -> f32 {
        let z = self.depths[i];
        if z > 0.0 {
            z.ln()
        } else {
            f32::NAN
        }
    }

    /// `(ln nearest, ln percentile − ln nearest)`, as `depth_scale` computes it over all depths.
    fn scale(&self) -> (f32, f32) {
        let total: u64 = self.histogram.iter().sum();
        let rank = (total as usize) * 98 / 100;
        let percentile = (total > 0).then(|| {
            let (mut below, mut bin) = (0, 0);
            while below + self.histogram[bin] as usize <= rank {
                below += self.histogram[bin] as usize;
                bin += 1;
            }
            let mut members: Vec<f32> = self
                .depths
                .par_iter()
                .map(|z| z.abs())
                .filter(|z| !z.is_nan() && (z.to_bits() >> 16) as usize == bin)
                .collect();
            *members.select_nth_unstable_by(rank - below, f32::total_cmp).1
        });
        depth_scale_of(self.nearest, percentile)
    }
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
            Progress::Depths(DepthPlane::with_capacity(width as usize * height as usize))
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
            Progress::Streaming {
                file,
                png: Box::new(png),
            }
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
            table: SrgbTable::shared(),
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
            Progress::Depths(plane) => {
                let scale = plane.scale();
                save(self.width, self.height, &self.path, |i| {
                    depth_pixel_of_log(plane.log(i), scale)
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
        if self.aov == Aov::Depth {
            return Ok(Vec::new());
        }
        // every byte written below (a flattened collect grew its vector byte by byte)
        let mut bytes = vec![0u8; 3 * pixels.len()];
        let out = bytes.chunks_exact_mut(3);
        if self.aov == Aov::Beauty {
            // a pixel nothing covers (`A = 0`, no colour) shows the background: the same bytes
            // for every such pixel, those `beauty_pixel` gives it (`±0 + 1·background`)
            let uncovered_bytes = beauty_pixel(self.table, &[0.0; 3], 1.0, self.background);
            for (rgb, p) in out.zip(pixels) {
                let uncovered = self.alpha.map_or(0.0, |a| 1.0 - p[a]);
                rgb.copy_from_slice(&if uncovered == 1.0 && p[o..o + 3] == [0.0; 3] {
                    uncovered_bytes
                } else {
                    beauty_pixel(self.table, &p[o..], uncovered, self.background)
                });
            }
        } else {
            for (rgb, p) in out.zip(pixels) {
                rgb.copy_from_slice(&normal_pixel(&p[o..]));
            }
        }
        Ok(bytes)
    }

    fn write(&self, _first_row: u32, rows: &[f32], prepared: Vec<u8>) -> Result<()> {
        match &mut *self.state.lock().unwrap_or_else(PoisonError::into_inner) {
            Progress::Streaming { png, .. } => png
                .write_all(&prepared)
                .with_context(|| format!("writing {}", self.path.display())),
            Progress::Depths(plane) => {
                for p in rows.chunks_exact(self.stride) {
                    plane.push(p[self.offset], self.alpha.is_none_or(|a| p[a] > 0.0));
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::png::depth_scale;

    /// Depths with repeats, misses, zeros, infinities and a wide spread of magnitudes.
    fn depth(i: usize) -> (f32, bool) {
        let z = match i % 11 {
            0 => f32::INFINITY,
            1 => 0.0,
            2 => f32::NAN,
            3 => 7.25, // repeated exactly
            _ => 1e-3 * (1.0 + ((i * 7919) % 100_003) as f32).powf(1.7),
        };
        (z, i % 5 != 0)
    }

    #[test]
    fn histogram_scale_equals_the_selection_over_all_depths() {
        for n in [0, 1, 2, 3, 50, 1000, 100_003] {
            let mut plane = DepthPlane::with_capacity(n);
            let mut counted = Vec::new();
            for i in 0..n {
                let (z, hit) = depth(i);
                plane.push(z, hit);
                if z.is_finite() && z > 0.0 {
                    counted.push(z);
                }
                // a coloured pixel holds ln z, the others NaN
                let log = plane.log(i);
                assert_eq!(log.is_nan(), !(hit && z.is_finite() && z > 0.0), "{i}");
                // a counted pixel holds ±z, the others NaN
                let stored = plane.depths[i].abs();
                assert_eq!(stored.is_nan(), !(z.is_finite() && z > 0.0), "{i}");
                if !log.is_nan() {
                    assert_eq!(log.to_bits(), z.ln().to_bits(), "{i}");
                }
                if !stored.is_nan() {
                    assert_eq!(stored.to_bits(), z.to_bits(), "{i}");
                }
            }
            let (a, b) = (plane.scale(), depth_scale(&mut counted));
            assert_eq!(
                (a.0.to_bits(), a.1.to_bits()),
                (b.0.to_bits(), b.1.to_bits()),
                "{n} depths"
            );
        }
    }
}
