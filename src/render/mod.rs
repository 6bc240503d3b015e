//! The render loop: rays through each pixel, first hit wins, and only the requested AOVs
//! computed for it.
//!
//! With one sample per pixel and no moving object, one ray goes through each pixel centre (the
//! camera model's ray; for a thin lens, through the lens centre) and the AOVs are that ray's.
//! Otherwise each pixel traces the samples of [`crate::sampling`] (position, lens point, time)
//! and resolves them per AOV:
//!
//! | AOV | rule over the pixel's samples |
//! |---|---|
//! | `Beauty` | filter-weighted mean of the samples' colours, misses black (premultiplied by `A`; the background only with [`RenderOptions::background`]) |
//! | `Alpha` | filter-weighted fraction of samples that hit (with `Box`: hits / spp) |
//! | `Depth`, `Distance`, `Position` | of the **nearest** hit sample (smallest `Z`), never averaged |
//! | `PrimitiveId` | the object hit by the most samples (ties: the one with the nearest sample) |
//! | `Normal`, `CameraNormal`, `ShadingNormal` | mean over the samples that hit that object, renormalised |
//! | `Uv` | mean over the same samples as the normal |
//!
//! and a pixel no sample hits gets the miss values. A pixel (or sample) where the camera model
//! has no ray (outside a fisheye's image circle, or where the OpenCV undistortion does not
//! converge) sees nothing, like a miss, and is counted in [`Frame`]. [`render`] traces the
//! scene's camera, [`render_view`] any other (such as one of the scene's `views`).
//!
//! Rows are traced on rayon's threads ([`render_view`]: one task per 16 rows, into a [`Frame`];
//! [`crate::render::stream`]: bands of rows handed in order to the output files as they finish); every
//! pixel is computed independently from the scene and its own samples (a hash of
//! seed, pixel and sample index), so the image is bit-identical whatever the thread count. With
//! one sample per pixel, the pixel centres of 4 × 2 blocks are traced together
//! ([`Scene::intersect_packet`]: the scene's hierarchy and each mesh's walked once per packet, the
//! rays in SIMD lanes), each ray getting exactly the hit it gets alone. The loop knows nothing
//! about any particular primitive: it calls [`Scene::intersect_packet`], [`Scene::intersect`] (or
//! [`Scene::intersect_at`]) and [`zeroset_primitives::SurfaceHit::complete`].

pub mod cull;
mod pixel;
mod sampled;
mod shade;
mod tracer;

pub use shade::{secondary_offset, shade, shade_at};
pub(crate) use tracer::Tracer;
pub mod stream;
pub mod views;

use crate::aov::Aov;
use crate::camera::{Camera, NoRay};
use crate::scene::Scene;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// A pixel rectangle `[x0, x1) × [y0, y1)` of the full image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Window {
    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// The window itself if it is a non-empty part of a `width × height` image.
    ///
    /// # Errors
    /// An empty window or one reaching outside the image: what is needed, in words.
    pub fn within(self, width: u32, height: u32) -> Result<Self, String> {
        if self.x0 >= self.x1 || self.y0 >= self.y1 || self.x1 > width || self.y1 > height {
            return Err(format!("need x0 < x1 ≤ {width} and y0 < y1 ≤ {height}"));
        }
        Ok(self)
    }
}

/// How to render.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// AOVs to compute (duplicates ignored; order kept).
    pub aovs: Vec<Aov>,
    /// Part of the image to render; `None` for all of it.
    pub crop: Option<Window>,
    /// Value written to `Z` and `distance` where nothing was hit (default `+∞`).
    pub depth_miss: f32,
    /// Show a progress bar on stderr once the render has taken a second.
    pub progress: bool,
    /// Fill the uncovered part of each pixel's `Beauty` with the scene background. Off by
    /// default: `R, G, B` are premultiplied by coverage `A` (EXR's convention), so a miss is
    /// black and compositing `over` another image gives the right colour.
    pub background: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            aovs: Aov::DEFAULT.to_vec(),
            crop: None,
            depth_miss: f32::INFINITY,
            progress: false,
            background: false,
        }
    }
}

/// A rendered frame: interleaved `f32` samples of the requested AOVs' channels over `window`.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Full image width (the display window).
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// The rendered part (the data window).
    pub window: Window,
    /// The AOVs, in channel order.
    pub aovs: Vec<Aov>,
    /// `window.width() × window.height() × channel_count()` samples, row-major, channels
    /// interleaved per pixel.
    pub samples: Vec<f32>,
    /// Wall time of the trace.
    pub elapsed: Duration,
    /// Primary rays per pixel (samples per pixel).
    pub spp: u32,
    /// Pixel samples with no ray because they lie outside the camera's field (a fisheye's
    /// image circle); such pixels get the miss values.
    pub outside_field: u64,
    /// Pixel samples with no ray because the OpenCV undistortion did not converge there
    /// ([`crate::camera::opencv`]); such pixels get the miss values.
    pub not_converged: u64,
}

impl Frame {
    /// Channels per pixel.
    #[must_use]
    pub fn channel_count(&self) -> usize {
        self.aovs.iter().map(|a| a.channels().len()).sum()
    }

    /// Offset of `aov`'s first channel within a pixel, if it was rendered.
    #[must_use]
    pub fn channel_offset(&self, aov: Aov) -> Option<usize> {
        channel_offset_in(&self.aovs, aov)
    }

    /// The frame's layout (size, window, AOVs), without the samples.
    #[must_use]
    pub fn layout(&self) -> FrameLayout {
        FrameLayout {
            width: self.width,
            height: self.height,
            window: self.window,
            aovs: self.aovs.clone(),
        }
    }

    /// The values of `aov` at pixel `(x, y)` of the full image (must lie in the window).
    #[must_use]
    pub fn pixel(&self, aov: Aov, x: u32, y: u32) -> Option<&[f32]> {
        let offset = self.channel_offset(aov)?;
        if x < self.window.x0 || x >= self.window.x1 || y < self.window.y0 || y >= self.window.y1 {
            return None;
        }
        let index = ((y - self.window.y0) as usize * self.window.width() as usize + (x - self.window.x0) as usize)
            * self.channel_count();
        Some(&self.samples[index + offset..index + offset + aov.channels().len()])
    }

    /// One channel (by EXR name) as a planar row-major vector over the window.
    #[must_use]
    pub fn planar_channel(&self, aov: Aov, component: usize) -> Vec<f32> {
        let stride = self.channel_count();
        let offset = self.channel_offset(aov).expect("AOV was rendered") + component;
        self.samples.iter().skip(offset).step_by(stride).copied().collect()
    }

    /// Primary rays per second (millions), all samples counted.
    #[must_use]
    pub fn mrays_per_second(&self) -> f64 {
        f64::from(self.window.width()) * f64::from(self.window.height()) * f64::from(self.spp)
            / self.elapsed.as_secs_f64().max(1e-12)
            / 1e6
    }
}

/// Renders `scene` through its camera as `options` ask (on the current rayon pool).
#[must_use]
pub fn render(scene: &Scene, options: &RenderOptions) -> Frame {
    render_view(scene, &scene.camera, options)
}

/// Counts of samples without a ray, by reason.
#[derive(Default)]
struct NoRayCounts {
    outside_field: AtomicU64,
    not_converged: AtomicU64,
}

impl NoRayCounts {
    fn add(&self, reason: NoRay) {
        match reason {
            NoRay::OutsideField => &self.outside_field,
            NoRay::NotConverged => &self.not_converged,
        }
        .fetch_add(1, Ordering::Relaxed);
    }
}

/// What a render of one camera produces, known before any ray is traced: the image size, the
/// data window and the AOVs in channel order (duplicates dropped). [`Frame`] holds the samples;
/// [`crate::render::stream`] hands them to the output files band by band instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameLayout {
    /// Full image width (the display window).
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// The rendered part (the data window).
    pub window: Window,
    /// The AOVs, in channel order.
    pub aovs: Vec<Aov>,
}

impl FrameLayout {
    /// The layout of rendering `camera` as `options` ask: the crop (or the whole image) and the
    /// requested AOVs without repeats, in the order asked.
    #[must_use]
    pub fn new(camera: &Camera, options: &RenderOptions) -> Self {
        let window = options.crop.unwrap_or(Window {
            x0: 0,
            y0: 0,
            x1: camera.width,
            y1: camera.height,
        });
        let mut aovs = Vec::new();
        for a in &options.aovs {
            if !aovs.contains(a) {
                aovs.push(*a);
            }
        }
        Self {
            width: camera.width,
            height: camera.height,
            window,
            aovs,
        }
    }

    /// Channels per pixel.
    #[must_use]
    pub fn channel_count(&self) -> usize {
        self.aovs.iter().map(|a| a.channels().len()).sum()
    }

    /// Samples per row of the window (`width × channels`).
    #[must_use]
    pub fn row_len(&self) -> usize {
        self.window.width() as usize * self.channel_count()
    }

    /// Offset of `aov`'s first channel within a pixel, if it is rendered.
    #[must_use]
    pub fn channel_offset(&self, aov: Aov) -> Option<usize> {
        channel_offset_in(&self.aovs, aov)
    }
}

/// Offset of `aov`'s first channel within a pixel of interleaved `aovs`.
fn channel_offset_in(aovs: &[Aov], aov: Aov) -> Option<usize> {
    let mut offset = 0;
    for a in aovs {
        if *a == aov {
            return Some(offset);
        }
        offset += a.channels().len();
    }
    None
}

/// Facts about a finished trace besides its samples.
#[derive(Clone, Copy, Debug)]
pub struct TraceStats {
    /// Wall time of the trace.
    pub elapsed: Duration,
    /// Primary rays per pixel.
    pub spp: u32,
    /// Pixel samples outside the camera's field (see [`Frame::outside_field`]).
    pub outside_field: u64,
    /// Pixel samples where the undistortion did not converge (see [`Frame::not_converged`]).
    pub not_converged: u64,
}

/// Whether a render of `scene` through `camera` (whole frame, one sample per pixel, no
/// `Uncertain` AOV) tests each pixel's ray against the pieces it can see (`piece_bins`) rather
/// than tracing packets: for tests.
#[doc(hidden)]
#[must_use]
pub fn uses_piece_bins(scene: &Scene, camera: &Camera) -> bool {
    let options = RenderOptions::default();
    let layout = FrameLayout::new(camera, &options);
    Tracer::new(scene, camera, &options, &layout).context.bins.is_some()
}

/// Renders `scene` through `camera` (one of its views, or any other camera) as `options` ask.
#[must_use]
pub fn render_view(scene: &Scene, camera: &Camera, options: &RenderOptions) -> Frame {
    let layout = FrameLayout::new(camera, options);
    let mut samples = vec![0.0f32; layout.row_len() * layout.window.height() as usize];
    let stats = render_view_into(scene, camera, options, &mut samples);
    Frame {
        width: layout.width,
        height: layout.height,
        window: layout.window,
        aovs: layout.aovs,
        samples,
        elapsed: stats.elapsed,
        spp: stats.spp,
        outside_field: stats.outside_field,
        not_converged: stats.not_converged,
    }
}

/// [`render_view`]'s samples written into `samples` (of [`FrameLayout::row_len`] times the
/// window's height, interleaved as [`Frame::samples`]), which may hold anything: every sample is
/// written. A caller rendering band after band reuses one buffer.
///
/// # Panics
/// If `samples` is not the window's size.
pub fn render_view_into(scene: &Scene, camera: &Camera, options: &RenderOptions, samples: &mut [f32]) -> TraceStats {
    let layout = FrameLayout::new(camera, options);
    let row_len = layout.row_len();
    assert_eq!(
        samples.len(),
        row_len * layout.window.height() as usize,
        "one frame of samples"
    );
    let tracer = Tracer::new(scene, camera, options, &layout);
    // sixteen rows a task: the bucket of pixel bins, eight packets' pairs of rows
    const ROWS_PER_TASK: usize = 16;
    samples
        .par_chunks_mut(ROWS_PER_TASK * row_len.max(1))
        .enumerate()
        .for_each(|(task, out)| {
            tracer.rows(layout.window.y0 + (ROWS_PER_TASK * task) as u32, out);
        });
    let elapsed = tracer.elapsed();
    tracer.finish(elapsed)
}
