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
//! [`crate::stream`]: bands of rows handed in order to the output files as they finish); every
//! pixel is computed independently from the scene and its own samples (a hash of
//! seed, pixel and sample index), so the image is bit-identical whatever the thread count. With
//! one sample per pixel, the pixel centres of 4 × 2 blocks are traced together
//! ([`Scene::intersect_packet`]: the scene's hierarchy and each mesh's walked once per packet, the
//! rays in SIMD lanes), each ray getting exactly the hit it gets alone. The loop knows nothing
//! about any particular primitive: it calls [`Scene::intersect_packet`], [`Scene::intersect`] (or
//! [`Scene::intersect_at`]) and [`SurfaceHit::complete`].

use crate::aov::Aov;
use crate::camera::footprint::Coverage;
use crate::camera::{Camera, NoRay, PixelRays};
use crate::piece_bins::{BandBins, PieceBins, RowBins};
use crate::sampling::{pixel_samples, PixelSample};
use crate::scene::{Light, Scene};
use crate::tracing::scalar;
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};
use zeroset_primitives::root::thread_uncertain_events;
use zeroset_primitives::{facing, HitRequest, Interval, RawHit, Ray, SurfaceHit};

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
/// [`crate::stream`] hands them to the output files band by band instead.
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

/// One render in progress: what its rows share, the progress bar and the counts of samples
/// without a ray. Rows may be traced in any order and on any thread; each is computed from the
/// scene and its own pixels only, so the samples do not depend on the order.
pub(crate) struct Tracer<'a> {
    scene: &'a Scene,
    context: RowContext<'a>,
    sampled: bool,
    /// First column of the window.
    x0: u32,
    /// Samples per row of the window.
    row_len: usize,
    progress: bool,
    bar: ProgressBar,
    bar_shown: AtomicBool,
    start: Instant,
}

impl<'a> Tracer<'a> {
    /// Starts the clock of a render of `layout` through `camera`.
    pub(crate) fn new(scene: &'a Scene, camera: &'a Camera, options: &RenderOptions, layout: &'a FrameLayout) -> Self {
        // what is worked out for the view before the first ray (pixel bins, coverage) counts
        let start = Instant::now();
        let aovs = &layout.aovs;
        let sampled = scene.sampling.spp > 1 || scene.has_motion();
        let uncertain_offset = channel_offset_in(aovs, Aov::Uncertain);
        // the paths that trace pixel by pixel (samples, the Uncertain flag) keep their own
        let bins = if sampled || uncertain_offset.is_some() {
            None
        } else {
            PieceBins::new(scene, camera, &layout.window)
        };
        let seen = if sampled || bins.is_some() {
            None
        } else {
            scene.coverage(camera)
        };
        let request = HitRequest {
            normal: aovs
                .iter()
                .any(|a| matches!(a, Aov::Beauty | Aov::Normal | Aov::CameraNormal | Aov::ShadingNormal)),
            uv: aovs.contains(&Aov::Uv),
            // shadow rays start from beauty's hits; the headlight of a scene without lights
            // casts none
            error: aovs.contains(&Aov::Beauty) && !scene.lights.is_empty(),
        };
        let bar = ProgressBar::with_draw_target(Some(u64::from(layout.window.height())), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {elapsed} elapsed, ~{eta} left")
                .expect("valid template"),
        );
        let mut context = RowContext {
            aovs,
            request,
            shading: aovs.contains(&Aov::ShadingNormal),
            beauty: aovs.contains(&Aov::Beauty),
            channels: layout.channel_count(),
            world_to_camera: camera.world_to_camera(),
            depth_miss: options.depth_miss,
            camera,
            no_ray: NoRayCounts::default(),
            uncertain_offset,
            seen,
            bins,
            miss_colour: if options.background {
                scene.background
            } else {
                DVec3::ZERO
            },
            miss_pixel: Vec::new(),
            record_free: RecordFree::of(aovs, scene),
            value_offsets: ValueOffsets::of(aovs),
        };
        context.miss_pixel = miss_pixel(scene, &context);
        Self {
            scene,
            context,
            sampled,
            x0: layout.window.x0,
            row_len: layout.row_len(),
            progress: options.progress,
            bar,
            bar_shown: AtomicBool::new(false),
            start,
        }
    }

    /// Traces the rows from `y0` on (full-image row numbers) into `out`: whole rows of the
    /// window, interleaved samples.
    pub(crate) fn rows(&self, y0: u32, out: &mut [f32]) {
        let mut rows = 0;
        if self.sampled {
            for (k, row) in out.chunks_exact_mut(self.row_len.max(1)).enumerate() {
                render_row_sampled(self.scene, &self.context, self.x0, y0 + k as u32, row);
                rows += 1;
            }
        } else if let Some(bins) = &self.context.bins {
            render_rows_binned(self.scene, &self.context, bins, self.x0, y0, self.row_len, out);
            rows = (out.len() / self.row_len.max(1)) as u64;
        } else {
            // pairs of rows, traced in packets of 4 × 2 pixels
            let pixel_rays = self
                .context
                .camera
                .pixel_rays(self.x0, self.row_len / self.context.channels.max(1));
            for (k, pair) in out.chunks_mut(2 * self.row_len.max(1)).enumerate() {
                render_rows(
                    self.scene,
                    &self.context,
                    &pixel_rays,
                    y0 + 2 * k as u32,
                    self.row_len,
                    pair,
                );
                rows += (pair.len() / self.row_len.max(1)) as u64;
            }
        }
        if self.progress {
            self.bar.inc(rows);
            if !self.bar_shown.load(Ordering::Relaxed)
                && self.start.elapsed() > Duration::from_secs(1)
                && !self.bar_shown.swap(true, Ordering::Relaxed)
            {
                self.bar.set_draw_target(ProgressDrawTarget::stderr());
            }
        }
    }

    /// Time since the trace started.
    pub(crate) fn elapsed(&self) -> Duration {
        self.start.elapsed()
    }

    /// Ends the trace (clearing the progress bar) with its facts, `elapsed` being its wall time.
    pub(crate) fn finish(self, elapsed: Duration) -> TraceStats {
        self.bar.finish_and_clear();
        TraceStats {
            elapsed,
            spp: self.scene.sampling.spp.max(1),
            outside_field: self.context.no_ray.outside_field.into_inner(),
            not_converged: self.context.no_ray.not_converged.into_inner(),
        }
    }
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

/// Renders the one or two rows in `out` (interleaved AOV samples, whole rows of `row_len`
/// samples) from row `y` and column `x0` on, one ray per pixel centre. Neighbouring pixels are traced
/// together in packets ([`Scene::intersect_packet`], the same hits as one by one) of 4 × 2
/// pixels (8 × 1 for a single row), except when the `Uncertain` AOV needs each pixel's
/// root-finder events on their own.
#[inline(never)]
fn render_rows(scene: &Scene, context: &RowContext, pixel_rays: &PixelRays, y: u32, row_len: usize, out: &mut [f32]) {
    let x0 = pixel_rays.x0();
    const N: usize = zeroset_primitives::PACKET;
    let channels = context.channels;
    let height = out.len() / row_len.max(1);
    let width = row_len / channels;
    if context.uncertain_offset.is_some() {
        for (k, row) in out.chunks_exact_mut(row_len.max(1)).enumerate() {
            for (column, pixel) in row.chunks_exact_mut(channels).enumerate() {
                render_pixel(scene, context, x0 + column as u32, y + k as u32, pixel);
            }
        }
        return;
    }
    let camera = context.camera;
    let group = N / height;
    let row_rays = [pixel_rays.row(y), pixel_rays.row(y + 1)];
    for first in (0..width).step_by(group) {
        let columns = group.min(width - first);
        // the pixels with a ray, packed; `lane[row][column]` is where each pixel's ray is
        let mut rays = [Ray::new(camera.eye, camera.forward); N];
        let mut lane = [[usize::MAX; N]; 2];
        let mut n = 0;
        for (row, lanes) in lane.iter_mut().enumerate().take(height) {
            for (column, slot) in lanes.iter_mut().enumerate().take(columns) {
                let (i, j) = (x0 + (first + column) as u32, y + row as u32);
                // a pixel whose ray provably misses every object gets the miss values untraced
                if context.seen.as_ref().is_some_and(|seen| !seen.holds_pixel(i, j)) {
                    continue;
                }
                match row_rays[row].ray_into(first + column, &mut rays[n]) {
                    Ok(()) => {
                        *slot = n;
                        n += 1;
                    }
                    Err(reason) => context.no_ray.add(reason),
                }
            }
        }
        let mut hits = [None; N];
        if n > 0 {
            scene.intersect_packet(&rays[..n], &[Interval::POSITIVE; N][..n], &mut hits[..n]);
        }
        for (row, lanes) in lane.iter().enumerate().take(height) {
            for (column, &lane) in lanes.iter().enumerate().take(columns) {
                let at = row * row_len + (first + column) * channels;
                let pixel = &mut out[at..at + channels];
                if lane == usize::MAX {
                    write_miss(pixel, context);
                } else {
                    write_pixel(pixel, scene, context, &rays[lane], hits[lane]);
                }
            }
        }
    }
}

/// Renders the rows in `out` (whole rows of `row_len` samples) from row `y` and column `x0` on,
/// each pixel's ray tested against the pieces it can see ([`PieceBins`]): the same values as
/// [`render_rows`]. Out of line, as are [`render_rows`] and [`render_row_sampled`]: inlined,
/// the three paths made [`Tracer::rows`] one function of 36 KB, whose hot loop the compiler laid
/// out anew at any change elsewhere in the crate (±3 % from one build to the next).
#[inline(never)]
fn render_rows_binned(
    scene: &Scene,
    context: &RowContext,
    bins: &PieceBins,
    x0: u32,
    y: u32,
    row_len: usize,
    out: &mut [f32],
) {
    let channels = context.channels;
    let width = row_len / channels;
    let rows = out.len() / row_len.max(1);
    let camera = context.camera;
    let (mut band, mut row_bins) = (BandBins::default(), RowBins::default());
    bins.band(y, rows, x0, width, &mut band);
    let every_pixel = bins.tests_every_pixel();
    // a lone object's pieces, where the pixels write the normal: asked for it with the hit
    let normal_with_hit = bins.lone().filter(|_| context.record_free.writes_normal());
    let pixel_rays = camera.pixel_rays(x0, width);
    let mut ray = Ray::new(DVec3::ZERO, DVec3::ZERO);
    let mut directions = Vec::new();
    for (k, row) in out.chunks_exact_mut(row_len.max(1)).enumerate() {
        let listed = band.row(k, width, &mut row_bins);
        // the directions of the pixels that may be traced, worked out together
        let traced = if every_pixel { 0..width } else { listed };
        let row_rays = pixel_rays.row_with(y + k as u32, traced, &mut directions);
        for (column, pixel) in row.chunks_exact_mut(channels).enumerate() {
            let candidates = row_bins.get(column);
            // a pixel that can see no piece gets the miss values untraced
            if candidates.is_empty() && !every_pixel {
                write_miss(pixel, context);
                continue;
            }
            match row_rays.ray_into(column, &mut ray) {
                Ok(()) => {
                    // the normal with the hit where the pixel writes one and a lone object's
                    // pieces find it (bins of several objects keep one call of their test)
                    let (hit, normal) = match normal_with_hit {
                        Some((object, pieces)) => split_normal(scene.intersect_lone_pieces::<true>(
                            object,
                            pieces,
                            &ray,
                            Interval::POSITIVE,
                            candidates,
                        )),
                        None => (bins.intersect(scene, &ray, Interval::POSITIVE, candidates), None),
                    };
                    write_pixel_knowing(pixel, scene, context, &ray, hit, normal);
                }
                Err(reason) => {
                    context.no_ray.add(reason);
                    write_miss(pixel, context);
                }
            }
        }
    }
}

/// Traces and writes one pixel (the one-ray-at-a-time path of [`render_rows`]).
fn render_pixel(scene: &Scene, context: &RowContext, x: u32, y: u32, pixel: &mut [f32]) {
    let exhausted_before = thread_uncertain_events();
    match context.camera.pixel_ray(x, y) {
        Ok(ray) => {
            let hit = scene.intersect(&ray, Interval::POSITIVE);
            write_pixel(pixel, scene, context, &ray, hit);
        }
        Err(reason) => {
            context.no_ray.add(reason);
            write_miss(pixel, context);
        }
    }
    flag_uncertain(pixel, context, exhausted_before);
}

/// The hit of [`Scene::intersect_lone_pieces`] and the normal it may come with.
#[inline(always)]
fn split_normal(found: Option<(u32, RawHit, Option<Vec3>)>) -> (Option<(u32, RawHit)>, Option<Vec3>) {
    match found {
        Some((object, raw, normal)) => (Some((object, raw)), normal),
        None => (None, None),
    }
}

/// Completes the closest hit (if any) of a pixel's `ray` and writes every AOV of `context`.
#[inline(always)]
fn write_pixel(pixel: &mut [f32], scene: &Scene, context: &RowContext, ray: &Ray, hit: Option<(u32, RawHit)>) {
    write_pixel_knowing(pixel, scene, context, ray, hit, None);
}

/// [`write_pixel`], given the hit's `normal_at_f32` where the trace found it (`known_normal`:
/// the record-free path takes it instead of asking the primitive again).
#[inline(always)]
fn write_pixel_knowing(
    pixel: &mut [f32],
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    hit: Option<(u32, RawHit)>,
    known_normal: Option<Vec3>,
) {
    // (no closure for these three: left to the compiler, one was not inlined)
    match context.record_free {
        RecordFree::Scalars => return write_without_record::<false, false>(pixel, scene, context, ray, hit, None),
        RecordFree::WithNormal => {
            return write_without_record::<true, false>(pixel, scene, context, ray, hit, known_normal)
        }
        RecordFree::WithHeadlight => {
            return write_without_record::<true, true>(pixel, scene, context, ray, hit, known_normal)
        }
        RecordFree::No => {}
    }
    #[allow(clippy::manual_map, reason = "no closure: see `completed`")]
    let hit = match hit {
        Some((object, raw)) => Some(completed(scene, context, ray, object, &raw)),
        None => None,
    };
    let mut rest = &mut pixel[..];
    for aov in context.aovs {
        let n = write_aov(rest, scene, *aov, ray, hit.as_ref(), context);
        rest = &mut rest[n..];
    }
}

/// [`write_pixel`] where every AOV is one that [`RecordFree`] allows: the values
/// [`write_aov`] writes (the depth from the point `ray.at(t)` and the normal `normal_at`, as
/// [`SurfaceHit::complete`] makes them; the headlight's colour as [`shade`] makes it), without
/// building the hit record. `NORMAL`: the AOVs include the normal or the beauty (`normal_at` is
/// asked); `HEADLIGHT`: the beauty.
#[inline(always)]
fn write_without_record<const NORMAL: bool, const HEADLIGHT: bool>(
    pixel: &mut [f32],
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    hit: Option<(u32, RawHit)>,
    known_normal: Option<Vec3>,
) {
    let Some((object, raw)) = hit else {
        write_miss(pixel, context);
        return;
    };
    // the f32 normal the AOV stores (`normal_at` rounded: the same values as the record's),
    // unless the trace found it already
    let normal = if NORMAL {
        known_normal.unwrap_or_else(|| scene.objects[object as usize].primitive.normal_at_f32(ray, &raw))
    } else {
        Vec3::ZERO
    };
    let at = &context.value_offsets;
    if let Some(k) = at.depth {
        pixel[k] = context.camera.depth(ray.at(raw.t), raw.t) as f32;
    }
    if let Some(k) = at.distance {
        pixel[k] = raw.t as f32;
    }
    if let Some(k) = at.alpha {
        pixel[k] = 1.0;
    }
    if let Some(k) = at.id {
        pixel[k] = object as f32;
    }
    if let (true, Some(k)) = (NORMAL, at.normal) {
        pixel[k..k + 3].copy_from_slice(&normal.to_array());
    }
    if let (true, Some(k)) = (HEADLIGHT, at.beauty) {
        let colour = scene.objects[object as usize].material.color;
        pixel[k..k + 3].copy_from_slice(&headlight(colour, scene.ambient, normal, ray.dir).to_array());
    }
}

/// The hit record of `object`'s `raw` hit along a pixel's `ray`, completed as `context` asks,
/// and its shading normal where the beauty is shaded. Always inlined, never a closure: left to
/// the compiler, the record came back through memory (a copy of it for every pixel hit).
#[inline(always)]
fn completed(
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    object: u32,
    raw: &RawHit,
) -> (u32, SurfaceHit, Option<DVec3>) {
    let primitive = &*scene.objects[object as usize].primitive;
    let hit = SurfaceHit::complete(primitive, ray, raw, context.request);
    let shading_normal = if context.shading {
        primitive.shading_normal_at(ray, raw).or(hit.normal)
    } else {
        None
    };
    (object, hit, shading_normal)
}

/// Writes the miss values of every AOV of `context` into `pixel`.
#[inline(always)]
fn write_miss(pixel: &mut [f32], context: &RowContext) {
    pixel.copy_from_slice(&context.miss_pixel);
}

/// The values every AOV of `context` takes where nothing is hit (the same for every pixel).
fn miss_pixel(scene: &Scene, context: &RowContext) -> Vec<f32> {
    let camera = context.camera;
    let mut pixel = vec![0.0; context.channels];
    let mut rest = &mut pixel[..];
    for aov in context.aovs {
        let n = write_aov(rest, scene, *aov, &Ray::new(camera.eye, camera.forward), None, context);
        rest = &mut rest[n..];
    }
    pixel
}

/// Whether a render's pixels are written without a hit record ([`write_without_record`]), and
/// which of its values they need: only where every AOV is a value of the hit's `t` and object
/// (Depth, Distance, Alpha, PrimitiveId), its normal (Normal) or the headlight's colour (the
/// beauty of a scene without lights). The record, its copies and the match over its AOVs were
/// about 45 instructions of a hit pixel's 555 in the quadrics scene's Depth render
/// (cachegrind). Medians of 11–15 alternating runs: Depth renders quadrics 0.0144 → 0.0120 s,
/// spheres1k 0.0186 → 0.0165 s; AOV renders (Depth, Normal, Alpha) quadrics 0.0219 → 0.0195 s,
/// spheres1k 0.0302 → 0.0281 s, mesh4 0.0319 → 0.0306 s, mesh6 0.0336 → 0.0329 s; default
/// renders quadrics 0.0265 → 0.0249 s, mesh4 and mesh6 unchanged. (One writer for Position
/// too, with the point made up front, was 3–8 % slower everywhere, Depth renders included.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RecordFree {
    /// Some AOV needs the record: [`write_pixel`]'s general path.
    No,
    /// Depth, Distance, Alpha, PrimitiveId.
    Scalars,
    /// Those and Normal.
    WithNormal,
    /// Those, Normal and the headlight's beauty.
    WithHeadlight,
}

impl RecordFree {
    /// Whether the record-free pixel writes the hit's normal (or shades with it).
    #[inline(always)]
    fn writes_normal(self) -> bool {
        matches!(self, RecordFree::WithNormal | RecordFree::WithHeadlight)
    }

    /// The path of a render of `aovs` in `scene`.
    fn of(aovs: &[Aov], scene: &Scene) -> Self {
        let scalar = |a: &Aov| matches!(a, Aov::Depth | Aov::Distance | Aov::Alpha | Aov::PrimitiveId);
        if aovs.iter().all(scalar) {
            Self::Scalars
        } else if aovs.iter().all(|a| scalar(a) || *a == Aov::Normal) {
            Self::WithNormal
        } else if scene.lights.is_empty() && aovs.iter().all(|a| scalar(a) || matches!(a, Aov::Normal | Aov::Beauty)) {
            Self::WithHeadlight
        } else {
            Self::No
        }
    }
}

/// Where each value a record-free pixel writes ([`write_without_record`]) sits in the pixel:
/// the offset of its first channel, for the AOVs rendered. Worked out once per render, so that a
/// pixel stores each value at its place instead of walking the AOV list (the walk's match and
/// slicing were a third of the row loop's own time in the level-4 mesh's default render).
#[derive(Clone, Copy, Debug)]
struct ValueOffsets {
    depth: Option<usize>,
    distance: Option<usize>,
    alpha: Option<usize>,
    id: Option<usize>,
    normal: Option<usize>,
    beauty: Option<usize>,
}

impl ValueOffsets {
    /// The offsets of `aovs` (in channel order, without repeats).
    fn of(aovs: &[Aov]) -> Self {
        let at = |aov| channel_offset_in(aovs, aov);
        Self {
            depth: at(Aov::Depth),
            distance: at(Aov::Distance),
            alpha: at(Aov::Alpha),
            id: at(Aov::PrimitiveId),
            normal: at(Aov::Normal),
            beauty: at(Aov::Beauty),
        }
    }
}

/// What every row of one render shares.
struct RowContext<'a> {
    aovs: &'a [Aov],
    request: HitRequest,
    shading: bool,
    beauty: bool,
    channels: usize,
    world_to_camera: glam::DMat4,
    depth_miss: f32,
    camera: &'a Camera,
    no_ray: NoRayCounts,
    /// Beauty of the uncovered part of a pixel: the background, or black (premultiplied).
    miss_colour: DVec3,
    /// Every AOV's values where nothing is hit ([`miss_pixel`]).
    miss_pixel: Vec<f32>,
    /// Which AOVs' pixels are written without a hit record ([`write_without_record`]).
    record_free: RecordFree,
    /// Where those pixels' values go.
    value_offsets: ValueOffsets,
    /// Where the `Uncertain` channel is in a pixel, if it was asked for.
    uncertain_offset: Option<usize>,
    /// The pixel centres whose rays can meet an object ([`Scene::coverage`]), if the camera
    /// can say; the others see nothing and are not traced.
    seen: Option<Coverage>,
    /// The pieces each pixel can see ([`PieceBins`]: a lone mesh's leaves, or the objects of a
    /// scene of several), where a pinhole sees the scene: its pixels are traced against those
    /// alone, instead of in packets.
    bins: Option<PieceBins<'a>>,
}

/// Sets the pixel's `Uncertain` channel (if rendered) to 1 if this thread's root finder ran out of
/// budget since `exhausted_before` — that is, while this pixel's rays were traced — else 0.
#[inline(always)]
fn flag_uncertain(pixel: &mut [f32], context: &RowContext, exhausted_before: u64) {
    if let Some(at) = context.uncertain_offset {
        pixel[at] = if thread_uncertain_events() == exhausted_before {
            0.0
        } else {
            1.0
        };
    }
}

/// One sample's hit: the object, its record, shading normal, planar depth and ray.
struct SampleHit {
    object: u32,
    hit: SurfaceHit,
    shading_normal: Option<DVec3>,
    depth: f64,
    ray: Ray,
}

/// Renders row `y` from column `x0` with the scene's samples per pixel, resolving each pixel's
/// samples per AOV as the module table says.
#[inline(never)]
fn render_row_sampled(scene: &Scene, context: &RowContext, x0: u32, y: u32, out: &mut [f32]) {
    let camera = context.camera;
    let filter = scene.sampling.filter;
    let mut points: Vec<PixelSample> = Vec::new();
    let mut scratch = Vec::new();
    let mut hits: Vec<SampleHit> = Vec::new();
    // (object, samples that hit it, its nearest depth)
    let mut counts: Vec<(u32, u32, f64)> = Vec::new();
    for (column, pixel) in out.chunks_exact_mut(context.channels).enumerate() {
        let x = x0 + column as u32;
        let exhausted_before = thread_uncertain_events();
        pixel_samples(&scene.sampling, camera.shutter, x, y, &mut points, &mut scratch);
        let (cx, cy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        let (mut weights, mut covered, mut colour) = (0.0, 0.0, DVec3::ZERO);
        hits.clear();
        for sample in &points {
            let w = filter.weight(sample.x - cx, sample.y - cy);
            weights += w;
            // a sample with no ray (outside the field) sees nothing, like a miss
            let ray = match camera.lens_ray(sample.x, sample.y, sample.lens) {
                Ok(ray) => ray,
                Err(reason) => {
                    context.no_ray.add(reason);
                    if context.beauty {
                        colour += w * context.miss_colour;
                    }
                    continue;
                }
            };
            let Some((object, raw)) = scene.intersect_at(&ray, Interval::POSITIVE, sample.time) else {
                if context.beauty {
                    colour += w * context.miss_colour;
                }
                continue;
            };
            let (hit, shading_normal) = scene.with_primitive_at(object, sample.time, |primitive| {
                let hit = SurfaceHit::complete(primitive, &ray, &raw, context.request);
                let shading_normal = if context.shading {
                    primitive.shading_normal_at(&ray, &raw).or(hit.normal)
                } else {
                    None
                };
                (hit, shading_normal)
            });
            if context.beauty {
                colour += w * shade_at(scene, object, &ray, &hit, sample.time);
            }
            covered += w;
            hits.push(SampleHit {
                object,
                hit,
                shading_normal,
                depth: camera.depth(hit.point, hit.t),
                ray,
            });
        }
        let mut rest = &mut pixel[..];
        // the nearest hit sample (the first of equals), for depth, distance and position
        let Some(nearest) = hits.iter().min_by(|a, b| a.depth.total_cmp(&b.depth)) else {
            write_miss(rest, context);
            flag_uncertain(pixel, context, exhausted_before);
            continue;
        };
        // the object most samples hit (ties: the nearest), for id, normals and uv
        counts.clear();
        for h in &hits {
            match counts.iter_mut().find(|c| c.0 == h.object) {
                Some(c) => {
                    c.1 += 1;
                    c.2 = c.2.min(h.depth);
                }
                None => counts.push((h.object, 1, h.depth)),
            }
        }
        let chosen = counts
            .iter()
            .copied()
            .reduce(|a, b| if b.1 > a.1 || (b.1 == a.1 && b.2 < a.2) { b } else { a })
            .map_or(nearest.object, |c| c.0);
        let (mut normal, mut shading_normal, mut uv, mut uv_count) = (DVec3::ZERO, DVec3::ZERO, glam::DVec2::ZERO, 0.0);
        for h in hits.iter().filter(|h| h.object == chosen) {
            normal += h.hit.normal.unwrap_or(DVec3::ZERO);
            shading_normal += h.shading_normal.unwrap_or(DVec3::ZERO);
            if let Some(v) = h.hit.uv {
                uv += v;
                uv_count += 1.0;
            }
        }
        let merged = SurfaceHit {
            normal: context.request.normal.then(|| normal.normalize_or_zero()),
            uv: (uv_count > 0.0).then(|| uv / uv_count),
            ..nearest.hit
        };
        let merged = (
            chosen,
            merged,
            context.shading.then(|| shading_normal.normalize_or_zero()),
        );
        for aov in context.aovs {
            let n = match aov {
                Aov::Beauty => {
                    let c = colour / weights;
                    rest[0] = c.x as f32;
                    rest[1] = c.y as f32;
                    rest[2] = c.z as f32;
                    3
                }
                Aov::Alpha => {
                    rest[0] = (covered / weights) as f32;
                    1
                }
                _ => write_aov(rest, scene, *aov, &nearest.ray, Some(&merged), context),
            };
            rest = &mut rest[n..];
        }
        flag_uncertain(pixel, context, exhausted_before);
    }
}

/// Writes one AOV's channels for one pixel at the start of `out`; returns how many it wrote.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn write_aov(
    out: &mut [f32],
    scene: &Scene,
    aov: Aov,
    ray: &Ray,
    hit: Option<&(u32, SurfaceHit, Option<DVec3>)>,
    context: &RowContext,
) -> usize {
    let (world_to_camera, depth_miss, miss_colour) =
        (&context.world_to_camera, context.depth_miss, context.miss_colour);
    let mut put3 = |v: DVec3| {
        out[0] = v.x as f32;
        out[1] = v.y as f32;
        out[2] = v.z as f32;
        3
    };
    let Some((object, hit, shading_normal)) = hit else {
        return match aov {
            Aov::Beauty => put3(miss_colour),
            Aov::Normal | Aov::Position | Aov::CameraNormal | Aov::ShadingNormal => put3(DVec3::ZERO),
            Aov::Depth | Aov::Distance => {
                out[0] = depth_miss;
                1
            }
            Aov::PrimitiveId => {
                out[0] = -1.0;
                1
            }
            Aov::Alpha | Aov::Uncertain => {
                out[0] = 0.0;
                1
            }
            Aov::Uv => {
                out[..2].fill(0.0);
                2
            }
        };
    };
    let normal = hit.normal.unwrap_or(DVec3::ZERO);
    let scalar = match aov {
        Aov::Beauty => return put3(shade(scene, *object, ray, hit)),
        Aov::Normal => return put3(normal),
        Aov::Position => return put3(hit.point),
        Aov::CameraNormal => return put3(world_to_camera.transform_vector3(normal)),
        Aov::ShadingNormal => return put3(shading_normal.unwrap_or(normal)),
        Aov::Uv => {
            let uv = hit.uv.unwrap_or_default();
            out[0] = uv.x as f32;
            out[1] = uv.y as f32;
            return 2;
        }
        Aov::Alpha => 1.0,
        Aov::Depth => context.camera.depth(hit.point, hit.t) as f32,
        Aov::Distance => hit.t as f32,
        Aov::PrimitiveId => *object as f32,
        // set once the whole pixel is traced (`flag_uncertain`)
        Aov::Uncertain => 0.0,
    };
    out[0] = scalar;
    1
}

/// Where a secondary (shadow) ray starts: the hit point moved along the facing normal by the
/// kernel's bound on its rounding error, `SurfaceHit::error` (primitive- and transform-aware, see
/// `zeroset_primitives::offset`), and rounded one ulp further away.
#[must_use]
pub fn secondary_offset(hit: &SurfaceHit, dir: DVec3) -> DVec3 {
    hit.secondary_origin(dir)
}

/// Local shading: ambient + Lambert (+ Blinn-Phong) per light, hard shadows by shadow rays. With
/// no lights, a headlight at the eye (no shadows).
#[must_use]
pub fn shade(scene: &Scene, object: u32, ray: &Ray, hit: &SurfaceHit) -> DVec3 {
    shade_with(scene, object, ray, hit, |r, range| scene.occluded(r, range))
}

/// [`shade`] at frame time `time`: shadow rays see moving objects where they are at that time.
#[must_use]
pub fn shade_at(scene: &Scene, object: u32, ray: &Ray, hit: &SurfaceHit, time: f64) -> DVec3 {
    shade_with(scene, object, ray, hit, |r, range| scene.occluded_at(r, range, time))
}

/// The colour of a surface of colour `colour` lit by the headlight of a scene without lights:
/// `colour·(ambient + max(n·v, 0))`, `n` the normal facing the viewer (zero for none) and
/// `v = −dir/‖dir‖` the direction back along the ray, worked out in f32 for the f32 beauty from
/// the normal rounded to f32, whichever way it faces, as `|n·d| / ‖d‖`, or `|n·d|` where `d`
/// is a unit vector within f32 rounding (every camera model's rays); a zero normal gives the
/// ambient term alone. Every path of the render shades with it, with or without a hit record:
/// the same bits. Against the f64 formula of before, at most 9 ulps (1.8·10⁻⁷) on the shipped
/// scenes' beauty.
#[inline(always)]
fn headlight(colour: DVec3, ambient: DVec3, normal: Vec3, dir: DVec3) -> Vec3 {
    let dir = dir.as_vec3();
    let length_squared = dir.length_squared();
    // a unit direction (every camera model's) within 2⁻²¹ spares the square root and division:
    // `|n·d|` is then within 2⁻²² of the cosine; `max` turns a NaN (a direction rounded to
    // zero or to infinity) into 0
    let dot = normal.dot(dir).abs();
    let cosine = if (length_squared - 1.0).abs() <= 1.0 / (1 << 21) as f32 {
        dot
    } else {
        (dot / length_squared.sqrt()).max(0.0)
    };
    colour.as_vec3() * (ambient.as_vec3() + Vec3::splat(cosine))
}

#[inline(always)]
fn shade_with(
    scene: &Scene,
    object: u32,
    ray: &Ray,
    hit: &SurfaceHit,
    occluded: impl Fn(&Ray, Interval) -> bool,
) -> DVec3 {
    let material = &scene.objects[object as usize].material;
    // the direction and the normal read a component at a time: the hit record was just written
    // field by field, and a 16-byte load straddling two of those writes waits for both to reach
    // the cache (a store-forwarding stall on every pixel, 6 % of the quadrics' default render)
    let by_component = |v: &DVec3| DVec3::new(scalar(&v.x), scalar(&v.y), scalar(&v.z));
    let dir = by_component(&ray.dir);
    let n = hit
        .normal
        .as_ref()
        .map_or(DVec3::ZERO, |n| facing(by_component(n), dir));
    if scene.lights.is_empty() {
        return headlight(material.color, scene.ambient, n.as_vec3(), dir).as_dvec3();
    }
    let view = -dir.normalize();
    let origin = secondary_offset(hit, ray.dir);
    let mut colour = material.color * scene.ambient;
    for light in &scene.lights {
        let (to_light, distance, intensity) = match *light {
            Light::Point { position, intensity } => {
                let d = position - origin;
                let len = d.length();
                (d / len, len, intensity / (len * len))
            }
            Light::Directional { direction, intensity } => (-direction.normalize(), f64::INFINITY, intensity),
        };
        let cos = n.dot(to_light);
        if cos <= 0.0 || occluded(&Ray::new(origin, to_light), Interval::new(0.0, distance)) {
            continue;
        }
        colour += material.color * intensity * cos;
        if material.specular > 0.0 {
            let half = (to_light + view).normalize();
            colour += material.specular * intensity * n.dot(half).max(0.0).powf(material.shininess);
        }
    }
    colour
}
