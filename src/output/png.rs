//! PNG previews (8-bit sRGB), made and encoded in parallel with the fast deflate setting and
//! written atomically: beauty (over the scene background, clamped to [0, 1]), depth (log depth normalised between the
//! nearest hit and the 98th percentile, coloured from yellow (near) to dark violet (far), misses
//! in a flat dark grey), normals (`(n + 1)/2`, misses black).

use crate::aov::Aov;
use crate::render::Frame;
use crate::output::atomic::write_atomically;
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
    let c: Vec<u8> = (0..3)
        .map(|k| unit_to_byte(STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f))
        .collect();
    Rgb([c[0], c[1], c[2]])
}

const MISS_GREY: Rgb<u8> = Rgb([40, 40, 40]);

/// Encodes an 8-bit RGB image of the frame's window, made row by row in parallel, as PNG with
/// the fast deflate setting, written atomically.
fn save(frame: &Frame, path: &Path, pixel: impl Fn(usize) -> Rgb<u8> + Sync) -> anyhow::Result<()> {
    let (w, h) = (frame.window.width(), frame.window.height());
    let mut bytes = vec![0u8; w as usize * h as usize * 3];
    bytes
        .par_chunks_mut(w as usize * 3)
        .enumerate()
        .for_each(|(row, out)| {
            for (column, rgb) in out.chunks_exact_mut(3).enumerate() {
                rgb.copy_from_slice(&pixel(row * w as usize + column).0);
            }
        });
    write_atomically(path, |file| {
        PngEncoder::new_with_quality(file, CompressionType::Fast, FilterType::Adaptive)
            .write_image(&bytes, w, h, ExtendedColorType::Rgb8)
            .with_context(|| format!("encoding {}", path.display()))
    })
}

/// Writes `<stem>.beauty.png`, `<stem>.depth.png` and `<stem>.normal.png` for the AOVs the frame
/// has, in parallel; returns the paths written. The beauty preview shows the premultiplied
/// colour over `background` (`RGB + (1 − A)·background`; black without an `Alpha` AOV).
///
/// # Errors
/// Encoding or writing a file fails (files already written stay).
pub fn write_previews(frame: &Frame, dir: &Path, stem: &str, background: [f32; 3]) -> anyhow::Result<Vec<PathBuf>> {
    let jobs: Vec<(Aov, PathBuf)> = [(Aov::Beauty, "beauty"), (Aov::Depth, "depth"), (Aov::Normal, "normal")]
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
    match aov {
        Aov::Beauty => save(frame, path, |i| {
            let s = &frame.samples[i * stride + o..];
            let uncovered = alpha.map_or(0.0, |a| 1.0 - frame.samples[i * stride + a]);
            let c = |k: usize| srgb_encode(s[k] + uncovered * background[k]);
            Rgb([c(0), c(1), c(2)])
        }),
        Aov::Depth => {
            let mut depths: Vec<f32> = frame
                .samples
                .par_iter()
                .skip(o)
                .step_by(stride)
                .copied()
                .filter(|z| z.is_finite() && *z > 0.0)
                .collect();
            depths.par_sort_unstable_by(f32::total_cmp);
            // log depth between the nearest hit and the 98th percentile, so a far horizon does
            // not flatten the foreground
            let lo = depths.first().copied().unwrap_or(1.0).ln();
            let hi = depths.get(depths.len() * 98 / 100).copied().unwrap_or(1.0).ln();
            let range = (hi - lo).max(f32::MIN_POSITIVE);
            save(frame, path, |i| {
                let hit = alpha.is_none_or(|a| frame.samples[i * stride + a] > 0.0);
                let z = frame.samples[i * stride + o];
                if hit && z.is_finite() && z > 0.0 {
                    depth_ramp((z.ln() - lo) / range)
                } else {
                    MISS_GREY
                }
            })
        }
        _ => save(frame, path, |i| {
            let n = &frame.samples[i * stride + o..];
            if n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0 {
                Rgb([0, 0, 0])
            } else {
                Rgb([
                    unit_to_byte((n[0] + 1.0) * 0.5),
                    unit_to_byte((n[1] + 1.0) * 0.5),
                    unit_to_byte((n[2] + 1.0) * 0.5),
                ])
            }
        }),
    }
}
