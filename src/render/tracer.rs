//! The tracer: one render in progress, row by row, on the path chosen once per render
//! (pixel bins, packets of pixel centres, samples per pixel).

use super::pixel::{
    flag_uncertain, miss_pixel, write_miss, write_pixel, write_pixel_knowing, RecordFree, RowContext, ValueOffsets,
};
use super::sampled::render_row_sampled;
use super::{channel_offset_in, FrameLayout, NoRayCounts, RenderOptions, TraceStats};
use crate::aov::Aov;
use crate::camera::{Camera, PixelRays};
use crate::render::cull::piece_bins::{BandBins, PieceBins, RowBins};
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use zeroset_primitives::root::thread_uncertain_events;
use zeroset_primitives::{HitRequest, Interval, RawHit, Ray};

/// One render in progress: what its rows share, the progress bar and the counts of samples
/// without a ray. Rows may be traced in any order and on any thread; each is computed from the
/// scene and its own pixels only, so the samples do not depend on the order.
pub(crate) struct Tracer<'a> {
    pub(super) scene: &'a Scene,
    pub(super) context: RowContext<'a>,
    pub(super) sampled: bool,
    /// First column of the window.
    pub(super) x0: u32,
    /// Samples per row of the window.
    pub(super) row_len: usize,
    pub(super) progress: bool,
    pub(super) bar: ProgressBar,
    pub(super) bar_shown: AtomicBool,
    pub(super) start: Instant,
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

/// Renders the one or two rows in `out` (interleaved AOV samples, whole rows of `row_len`
/// samples) from row `y` and column `x0` on, one ray per pixel centre. Neighbouring pixels are traced
/// together in packets ([`Scene::intersect_packet`], the same hits as one by one) of 4 × 2
/// pixels (8 × 1 for a single row), except when the `Uncertain` AOV needs each pixel's
/// root-finder events on their own.
#[inline(never)]
pub(super) fn render_rows(
    scene: &Scene,
    context: &RowContext,
    pixel_rays: &PixelRays,
    y: u32,
    row_len: usize,
    out: &mut [f32],
) {
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
pub(super) fn render_rows_binned(
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
pub(super) fn render_pixel(scene: &Scene, context: &RowContext, x: u32, y: u32, pixel: &mut [f32]) {
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
pub(super) fn split_normal(found: Option<(u32, RawHit, Option<Vec3>)>) -> (Option<(u32, RawHit)>, Option<Vec3>) {
    match found {
        Some((object, raw, normal)) => (Some((object, raw)), normal),
        None => (None, None),
    }
}
