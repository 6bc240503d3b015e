//! PNG previews (8-bit sRGB): beauty (clamped to [0, 1]), depth (log depth normalised between the
//! nearest hit and the 98th percentile, coloured from yellow (near) to dark violet (far), misses
//! in a flat dark grey), normals (`(n + 1)/2`, misses black).

use crate::aov::Aov;
use crate::render::Frame;
use image::{Rgb, RgbImage};
use std::path::Path;

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

fn save(frame: &Frame, path: &Path, pixel: impl Fn(usize) -> Rgb<u8>) -> image::ImageResult<()> {
    let (w, h) = (frame.window.width(), frame.window.height());
    let mut img = RgbImage::new(w, h);
    for (i, p) in img.pixels_mut().enumerate() {
        *p = pixel(i);
    }
    img.save(path)
}

/// Writes `<stem>.beauty.png`, `<stem>.depth.png` and `<stem>.normal.png` for the AOVs the frame
/// has; returns the paths written.
pub fn write_previews(frame: &Frame, dir: &Path, stem: &str) -> image::ImageResult<Vec<std::path::PathBuf>> {
    let mut written = Vec::new();
    let stride = frame.channel_count();
    let alpha = frame.channel_offset(Aov::Alpha);
    if let Some(o) = frame.channel_offset(Aov::Beauty) {
        let path = dir.join(format!("{stem}.beauty.png"));
        save(frame, &path, |i| {
            let s = &frame.samples[i * stride + o..];
            Rgb([srgb_encode(s[0]), srgb_encode(s[1]), srgb_encode(s[2])])
        })?;
        written.push(path);
    }
    if let Some(o) = frame.channel_offset(Aov::Depth) {
        let mut depths: Vec<f32> = frame
            .samples
            .iter()
            .skip(o)
            .step_by(stride)
            .copied()
            .filter(|z| z.is_finite() && *z > 0.0)
            .collect();
        depths.sort_unstable_by(f32::total_cmp);
        // log depth between the nearest hit and the 98th percentile, so a far horizon does not
        // flatten the foreground
        let lo = depths.first().copied().unwrap_or(1.0).ln();
        let hi = depths.get(depths.len() * 98 / 100).copied().unwrap_or(1.0).ln();
        let range = (hi - lo).max(f32::MIN_POSITIVE);
        let path = dir.join(format!("{stem}.depth.png"));
        save(frame, &path, |i| {
            let hit = alpha.is_none_or(|a| frame.samples[i * stride + a] > 0.0);
            let z = frame.samples[i * stride + o];
            if hit && z.is_finite() && z > 0.0 {
                depth_ramp((z.ln() - lo) / range)
            } else {
                MISS_GREY
            }
        })?;
        written.push(path);
    }
    if let Some(o) = frame.channel_offset(Aov::Normal) {
        let path = dir.join(format!("{stem}.normal.png"));
        save(frame, &path, |i| {
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
        })?;
        written.push(path);
    }
    Ok(written)
}
