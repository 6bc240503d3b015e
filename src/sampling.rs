//! Samples per pixel: where in the pixel, where on the lens and when in the shutter each
//! primary ray goes, and the reconstruction filter that weights them.
//!
//! With `spp = 1` the single sample is the pixel centre, the lens centre and the middle of the
//! shutter (the image of one ray per pixel). With `spp > 1` the pixel is cut into an `n × m`
//! grid of strata (`n·m = spp`, as square as possible, `n ≥ m` columns by rows) and sample `k`
//! is jittered inside stratum `(k mod n, k div n)`. The lens and time dimensions are stratified
//! too, each through its own per-pixel random permutation of the strata (so position, lens and
//! time are not correlated): lens on the same `n × m` grid mapped by the concentric disk map,
//! time in `spp` equal slices of the shutter.
//!
//! Every random number is a counter-based hash of `(seed, pixel x, pixel y, sample index,
//! dimension)` (SplitMix64 finalisers), so a pixel's samples depend on nothing else: the image is
//! bit-identical whatever the thread count or the order pixels are rendered in.
//!
//! **Filter.** Each pixel reconstructs from its own samples only (no splatting into neighbours):
//! `Box` weights them equally; `Gaussian { sigma }` weights a sample at offset `d` (pixels) from
//! the pixel centre by `exp(−|d|²/(2σ²))`, a Gaussian truncated to the pixel.

use serde::Deserialize;

/// Reconstruction filter for the beauty (and the coverage `A`), over a pixel's own samples.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Filter {
    /// Equal weights.
    Box,
    /// `exp(−|d|²/(2σ²))`, `d` the offset from the pixel centre in pixels, truncated to the pixel.
    Gaussian {
        /// Standard deviation in pixels (> 0); 0.5 is a gentle smoothing.
        sigma: f64,
    },
}

impl Filter {
    /// The weight of a sample at offset `(dx, dy)` pixels from the pixel centre.
    #[inline]
    #[must_use]
    pub fn weight(&self, dx: f64, dy: f64) -> f64 {
        match *self {
            Filter::Box => 1.0,
            Filter::Gaussian { sigma } => (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp(),
        }
    }
}

fn default_spp() -> u32 {
    1
}
fn default_filter() -> Filter {
    Filter::Box
}

/// `sampling: (spp: 16, filter: Box | Gaussian(sigma: 0.5), seed: 0)`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sampling {
    /// Samples per pixel (≥ 1); default 1.
    #[serde(default = "default_spp")]
    pub spp: u32,
    /// Reconstruction filter for the beauty and `A`; default `Box`.
    #[serde(default = "default_filter")]
    pub filter: Filter,
    /// Seed of the sample positions; default 0.
    #[serde(default)]
    pub seed: u64,
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            spp: 1,
            filter: Filter::Box,
            seed: 0,
        }
    }
}

impl Sampling {
    /// Checks the values; the error names the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.spp == 0 {
            return Err("field `spp`: must be at least 1".into());
        }
        if let Filter::Gaussian { sigma } = self.filter {
            if !(sigma.is_finite() && sigma > 0.0) {
                return Err(format!("field `filter.sigma`: must be finite and > 0, got {sigma}"));
            }
        }
        Ok(())
    }
}

/// The stratification grid `(columns, rows)` for `spp` samples: `columns · rows = spp`, rows the
/// largest divisor of `spp` not above `√spp`.
#[must_use]
pub fn grid(spp: u32) -> (u32, u32) {
    let mut rows = (f64::from(spp).sqrt() as u32).max(1);
    while spp % rows != 0 {
        rows -= 1;
    }
    (spp / rows, rows)
}

/// One primary-ray sample of a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelSample {
    /// Position in the image, in continuous pixel coordinates (`(i + ½, j + ½)` is the centre).
    pub x: f64,
    /// See `x`.
    pub y: f64,
    /// Lens sample in `[0, 1)²` (`(½, ½)` is the lens centre).
    pub lens: (f64, f64),
    /// Frame time within the shutter.
    pub time: f64,
}

/// SplitMix64's finaliser: a bijective mix of 64 bits.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A 64-bit hash of `(seed, x, y, index, dimension)`.
#[inline]
#[must_use]
pub fn hash(seed: u64, x: u32, y: u32, index: u32, dimension: u32) -> u64 {
    let h = mix(seed ^ mix((u64::from(x) << 32) | u64::from(y)));
    mix(h ^ mix((u64::from(index) << 32) | u64::from(dimension)))
}

/// A uniform number in `[0, 1)` from the hash (53 random bits).
#[inline]
fn uniform(seed: u64, x: u32, y: u32, index: u32, dimension: u32) -> f64 {
    (hash(seed, x, y, index, dimension) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

// the hash dimensions
const JITTER_X: u32 = 0;
const JITTER_Y: u32 = 1;
const LENS_X: u32 = 2;
const LENS_Y: u32 = 3;
const TIME: u32 = 4;
const PERMUTE_LENS: u32 = 5;
const PERMUTE_TIME: u32 = 6;

/// A per-pixel random permutation of `0..n` (Fisher–Yates driven by the hash).
fn permutation(out: &mut [u32], seed: u64, x: u32, y: u32, dimension: u32) {
    for (i, v) in out.iter_mut().enumerate() {
        *v = i as u32;
    }
    for i in (1..out.len()).rev() {
        let j = (hash(seed, x, y, i as u32, dimension) % (i as u64 + 1)) as usize;
        out.swap(i, j);
    }
}

/// The samples of pixel `(px, py)` under `sampling` for a shutter open over `[open, close]`,
/// written to `out` (cleared first). `scratch` is reused between calls to avoid allocating.
pub fn pixel_samples(
    sampling: &Sampling,
    shutter: (f64, f64),
    px: u32,
    py: u32,
    out: &mut Vec<PixelSample>,
    scratch: &mut Vec<u32>,
) {
    out.clear();
    let (open, close) = shutter;
    if sampling.spp <= 1 {
        out.push(PixelSample {
            x: f64::from(px) + 0.5,
            y: f64::from(py) + 0.5,
            lens: (0.5, 0.5),
            time: 0.5 * (open + close),
        });
        return;
    }
    let spp = sampling.spp;
    let seed = sampling.seed;
    let (n, m) = grid(spp);
    scratch.resize(2 * spp as usize, 0);
    let (lens_strata, time_strata) = scratch.split_at_mut(spp as usize);
    permutation(lens_strata, seed, px, py, PERMUTE_LENS);
    permutation(time_strata, seed, px, py, PERMUTE_TIME);
    for k in 0..spp {
        let u = uniform(seed, px, py, k, JITTER_X);
        let v = uniform(seed, px, py, k, JITTER_Y);
        let lens_stratum = lens_strata[k as usize];
        let lu = (f64::from(lens_stratum % n) + uniform(seed, px, py, k, LENS_X)) / f64::from(n);
        let lv = (f64::from(lens_stratum / n) + uniform(seed, px, py, k, LENS_Y)) / f64::from(m);
        let slice = (f64::from(time_strata[k as usize]) + uniform(seed, px, py, k, TIME)) / f64::from(spp);
        out.push(PixelSample {
            x: f64::from(px) + (f64::from(k % n) + u) / f64::from(n),
            y: f64::from(py) + (f64::from(k / n) + v) / f64::from(m),
            lens: (lu, lv),
            time: open + (close - open) * slice,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_are_as_square_as_possible() {
        assert_eq!(grid(1), (1, 1));
        assert_eq!(grid(16), (4, 4));
        assert_eq!(grid(8), (4, 2));
        assert_eq!(grid(12), (4, 3));
        assert_eq!(grid(7), (7, 1));
    }

    #[test]
    fn samples_are_stratified_and_depend_only_on_the_pixel() {
        let s = Sampling {
            spp: 16,
            filter: Filter::Box,
            seed: 3,
        };
        let (mut a, mut b, mut scratch) = (Vec::new(), Vec::new(), Vec::new());
        pixel_samples(&s, (0.0, 2.0), 5, 9, &mut a, &mut scratch);
        pixel_samples(&s, (0.0, 1.0), 6, 9, &mut b, &mut scratch);
        pixel_samples(&s, (0.0, 2.0), 5, 9, &mut b, &mut scratch);
        assert_eq!(a, b);
        let mut cells = [false; 16];
        let mut slices = [false; 16];
        for p in &a {
            assert!((5.0..6.0).contains(&p.x) && (9.0..10.0).contains(&p.y));
            cells[((p.y - 9.0) * 4.0) as usize * 4 + ((p.x - 5.0) * 4.0) as usize] = true;
            slices[(p.time / 2.0 * 16.0) as usize] = true;
        }
        assert!(cells.iter().all(|&c| c) && slices.iter().all(|&c| c));
        let one = Sampling::default();
        pixel_samples(&one, (0.0, 1.0), 2, 3, &mut a, &mut scratch);
        assert_eq!(
            a,
            [PixelSample {
                x: 2.5,
                y: 3.5,
                lens: (0.5, 0.5),
                time: 0.5
            }]
        );
    }
}
