//! PNG previews (8-bit sRGB), made and encoded in parallel with the fast deflate setting and
//! the `Sub` row filter (about 10 % less CPU than adaptive filtering for 20 % larger files), and
//! written atomically: beauty (over the scene background, clamped to [0, 1]), depth (log depth
//! normalised between the
//! nearest hit and the 98th percentile, coloured from yellow (near) to dark violet (far), misses
//! in a flat dark grey), normals (`(n + 1)/2`, misses black).

use crate::aov::Aov;
use crate::output::atomic::write_atomically;
use crate::render::Frame;
use anyhow::Context;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, Rgb};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

fn srgb_encode(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// `srgb_encode` by table: `thresholds[b − 1]` is the smallest linear value that encodes to at
/// least byte `b`, found by bisection on the f32 bit patterns of [0, 1] (which are ordered like
/// the values), so the lookup equals `srgb_encode` exactly. A value in `(0, 1)` is looked up in
/// two steps: `buckets[bits >> 16]` is the byte of the smallest value of its bucket (the values
/// sharing the top 16 bits), and one comparison with the next byte's threshold settles the rest,
/// for no bucket holds two byte boundaries (the encoding rises by at most 0.45 of a byte across
/// one: a bucket spans 2⁻⁷ of its octave, and the slope times the octave is largest at 1). One
/// load and one comparison, where a bisection of the 255 thresholds took eight comparisons, each
/// a coin toss for the branch predictor.
pub(crate) struct SrgbTable {
    thresholds: [f32; 255],
    buckets: Vec<u8>,
}

/// The buckets of [`SrgbTable`]: those of the f32 bit patterns of `(0, 1)`.
const SRGB_BUCKETS: usize = (0x3F80_0000 >> 16) as usize;

impl SrgbTable {
    /// The table, made once per process, when first asked for (about a millisecond's work, which
    /// every preview used to repeat, the depth and normal previews without using it).
    pub(crate) fn shared() -> &'static Self {
        static TABLE: std::sync::OnceLock<SrgbTable> = std::sync::OnceLock::new();
        TABLE.get_or_init(Self::new)
    }

    pub(crate) fn new() -> Self {
        let mut thresholds = [0.0; 255];
        for (k, t) in thresholds.iter_mut().enumerate() {
            let byte = k as u8 + 1;
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits()); // encode(lo) < byte ≤ encode(hi)
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if srgb_encode(f32::from_bits(mid)) >= byte {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            *t = f32::from_bits(hi);
        }
        let buckets = (0..SRGB_BUCKETS as u32)
            .map(|j| Self::bisected(&thresholds, f32::from_bits(j << 16)))
            .collect();
        Self { thresholds, buckets }
    }

    /// The byte of `linear` (not NaN) by bisection of `thresholds`.
    fn bisected(thresholds: &[f32; 255], linear: f32) -> u8 {
        thresholds.partition_point(|t| *t <= linear) as u8
    }

    #[inline]
    pub(crate) fn encode(&self, linear: f32) -> u8 {
        if !(linear > 0.0 && linear < 1.0) {
            return if linear >= 1.0 { 255 } else { srgb_encode(linear) };
        }
        let byte = self.buckets[(linear.to_bits() >> 16) as usize];
        match self.thresholds.get(usize::from(byte)) {
            Some(&next) => byte + u8::from(next <= linear),
            None => byte,
        }
    }
}

fn unit_to_byte(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Colour ramp for depth: near = yellow, far = dark blue (piecewise linear through five stops).
fn depth_ramp(s: f32) -> Rgb<u8> {
    const STOPS: [[f32; 3]; 5] = [
        [0.99, 0.91, 0.15],
        [0.55, 0.82, 0.25],
        [0.13, 0.57, 0.55],
        [0.23, 0.32, 0.55],
        [0.27, 0.0, 0.33],
    ];
    let x = s.clamp(0.0, 1.0) * 4.0;
    let i = (x as usize).min(3);
    let f = x - i as f32;
    Rgb(std::array::from_fn(|k| {
        unit_to_byte(STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f)
    }))
}

const MISS_GREY: Rgb<u8> = Rgb([40, 40, 40]);

/// The beauty preview's pixel: the premultiplied colour `rgb` over `background`
/// (`RGB + (1 − A)·background`), sRGB-encoded.
pub(crate) fn beauty_pixel(table: &SrgbTable, rgb: &[f32], uncovered: f32, background: [f32; 3]) -> [u8; 3] {
    std::array::from_fn(|k| table.encode(rgb[k] + uncovered * background[k]))
}

/// The normal preview's pixel: `(n + 1)/2`, black where `n` is zero (a miss).
pub(crate) fn normal_pixel(n: &[f32]) -> [u8; 3] {
    if n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0 {
        [0, 0, 0]
    } else {
        [
            unit_to_byte((n[0] + 1.0) * 0.5),
            unit_to_byte((n[1] + 1.0) * 0.5),
            unit_to_byte((n[2] + 1.0) * 0.5),
        ]
    }
}

/// The depth preview's scale from the depths that count (finite and positive, hits or not):
/// `(ln nearest, ln 98th percentile − ln nearest)`, so a far horizon does not flatten the
/// foreground (a selection, not a sort: linear time). Reorders `depths`.
pub(crate) fn depth_scale(depths: &mut [f32]) -> (f32, f32) {
    let nearest = depths.par_iter().copied().reduce(|| f32::INFINITY, f32::min);
    let rank = depths.len() * 98 / 100;
    let percentile = (!depths.is_empty()).then(|| *depths.select_nth_unstable_by(rank, f32::total_cmp).1);
    depth_scale_of(nearest, percentile)
}

/// [`depth_scale`] from the nearest counted depth (`+∞` if none) and the 98th percentile (the
/// element of rank `⌊0.98 n⌋` of the `n` counted depths, `None` if none).
pub(crate) fn depth_scale_of(nearest: f32, percentile: Option<f32>) -> (f32, f32) {
    let lo = if nearest.is_finite() { nearest.ln() } else { 0.0 };
    let hi = percentile.map_or(0.0, f32::ln);
    (lo, (hi - lo).max(f32::MIN_POSITIVE))
}

/// The depth preview's pixel for depth `z` with scale `(lo, range)` ([`depth_scale`]): the
/// ramp for a hit at a finite positive depth, a flat grey otherwise.
pub(crate) fn depth_pixel(z: f32, hit: bool, scale: (f32, f32)) -> [u8; 3] {
    depth_pixel_of_log(
        if hit && z.is_finite() && z > 0.0 {
            z.ln()
        } else {
            f32::NAN
        },
        scale,
    )
}

/// [`depth_pixel`] from `ln z`, NaN where the pixel is drawn as a miss.
pub(crate) fn depth_pixel_of_log(log_z: f32, (lo, range): (f32, f32)) -> [u8; 3] {
    if log_z.is_nan() {
        MISS_GREY.0
    } else {
        depth_ramp((log_z - lo) / range).0
    }
}

/// The encoder settings of every preview: 8-bit RGB, the fast deflate setting, the `Sub` filter.
pub(crate) fn encoder<W: std::io::Write>(out: W) -> PngEncoder<W> {
    PngEncoder::new_with_quality(out, CompressionType::Fast, FilterType::Sub)
}

/// Encodes a `w × h` 8-bit RGB image, made row by row in parallel, as PNG (see [`encoder`]),
/// written atomically.
pub(crate) fn save(w: u32, h: u32, path: &Path, pixel: impl Fn(usize) -> [u8; 3] + Sync) -> anyhow::Result<()> {
    let mut bytes = vec![0u8; w as usize * h as usize * 3];
    bytes.par_chunks_mut(w as usize * 3).enumerate().for_each(|(row, out)| {
        for (column, rgb) in out.chunks_exact_mut(3).enumerate() {
            rgb.copy_from_slice(&pixel(row * w as usize + column));
        }
    });
    write_atomically(path, |file| {
        encoder(file)
            .write_image(&bytes, w, h, ExtendedColorType::Rgb8)
            .with_context(|| format!("encoding {}", path.display()))
    })
}

/// The previews made for a frame's AOVs: `(AOV, file name suffix)`.
pub const PREVIEWS: [(Aov, &str); 3] = [(Aov::Beauty, "beauty"), (Aov::Depth, "depth"), (Aov::Normal, "normal")];

/// Writes `<stem>.beauty.png`, `<stem>.depth.png` and `<stem>.normal.png` for the AOVs the frame
/// has, in parallel; returns the paths written. The beauty preview shows the premultiplied
/// colour over `background` (`RGB + (1 − A)·background`; black without an `Alpha` AOV).
///
/// # Errors
/// Encoding or writing a file fails (files already written stay).
pub fn write_previews(frame: &Frame, dir: &Path, stem: &str, background: [f32; 3]) -> anyhow::Result<Vec<PathBuf>> {
    let jobs: Vec<(Aov, PathBuf)> = PREVIEWS
        .into_iter()
        .filter(|(aov, _)| frame.channel_offset(*aov).is_some())
        .map(|(aov, name)| (aov, dir.join(format!("{stem}.{name}.png"))))
        .collect();
    jobs.par_iter()
        .map(|(aov, path)| write_preview(frame, *aov, path, background).map(|()| path.clone()))
        .collect()
}

/// Writes the preview of one AOV (beauty, depth or normal).
fn write_preview(frame: &Frame, aov: Aov, path: &Path, background: [f32; 3]) -> anyhow::Result<()> {
    let stride = frame.channel_count();
    let alpha = frame.channel_offset(Aov::Alpha);
    let o = frame.channel_offset(aov).expect("only rendered AOVs are previewed");
    let (w, h) = (frame.window.width(), frame.window.height());
    match aov {
        Aov::Beauty => {
            let table = SrgbTable::shared();
            save(w, h, path, |i| {
                let uncovered = alpha.map_or(0.0, |a| 1.0 - frame.samples[i * stride + a]);
                beauty_pixel(table, &frame.samples[i * stride + o..], uncovered, background)
            })
        }
        Aov::Depth => {
            let mut depths: Vec<f32> = frame
                .samples
                .par_iter()
                .skip(o)
                .step_by(stride)
                .copied()
                .filter(|z| z.is_finite() && *z > 0.0)
                .collect();
            let scale = depth_scale(&mut depths);
            save(w, h, path, |i| {
                let hit = alpha.is_none_or(|a| frame.samples[i * stride + a] > 0.0);
                depth_pixel(frame.samples[i * stride + o], hit, scale)
            })
        }
        _ => save(w, h, path, |i| normal_pixel(&frame.samples[i * stride + o..])),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_table_equals_the_formula() {
        let table = SrgbTable::new();
        let mut x = -0.5f32;
        while x < 1.5 {
            assert_eq!(table.encode(x), srgb_encode(x), "{x}");
            x += 1.0 / 65536.0;
        }
        for t in table.thresholds {
            assert_eq!(table.encode(t), srgb_encode(t));
            let below = f32::from_bits(t.to_bits() - 1);
            assert_eq!(table.encode(below), srgb_encode(below));
        }
        assert_eq!(table.encode(f32::INFINITY), 255);
        assert_eq!(table.encode(f32::NAN), srgb_encode(f32::NAN));
        assert_eq!(table.encode(-0.0), 0);
        // no bucket holds two byte boundaries: its last value's byte is at most one above its
        // first's (what the two-step lookup rests on), and both equal the formula
        for j in 0..SRGB_BUCKETS as u32 {
            let (first, last) = (f32::from_bits(j << 16), f32::from_bits(j << 16 | 0xFFFF));
            let (a, b) = (srgb_encode(first), srgb_encode(last));
            assert!(b - a <= 1, "bucket {j}: {a}..{b}");
            assert_eq!((table.encode(first), table.encode(last)), (a, b), "bucket {j}");
        }
        // and a spread of bit patterns over all of [0, 1]
        for bits in (0..=1.0f32.to_bits()).step_by(9973) {
            let x = f32::from_bits(bits);
            assert_eq!(table.encode(x), srgb_encode(x), "{x}");
        }
    }
}
