//! The render loop: one ray per pixel through the pixel centre, first hit wins, and only the
//! requested AOVs computed for it.
//!
//! Rows are distributed over rayon's threads in bands; every pixel is computed independently
//! from the scene alone, so the image is bit-identical whatever the thread count. The loop knows
//! nothing about any particular primitive: it calls [`Scene::intersect`] and
//! [`SurfaceHit::complete`].

use crate::aov::Aov;
use crate::scene::{Light, Scene};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use zeroset_primitives::{HitRequest, Interval, Ray, SurfaceHit};

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
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            aovs: Aov::DEFAULT.to_vec(),
            crop: None,
            depth_miss: f32::INFINITY,
            progress: false,
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
        let mut offset = 0;
        for a in &self.aovs {
            if *a == aov {
                return Some(offset);
            }
            offset += a.channels().len();
        }
        None
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

    /// Primary rays per second (millions).
    #[must_use]
    pub fn mrays_per_second(&self) -> f64 {
        f64::from(self.window.width()) * f64::from(self.window.height()) / self.elapsed.as_secs_f64().max(1e-12) / 1e6
    }
}

/// Renders `scene` as `options` ask (on the current rayon pool).
#[must_use]
pub fn render(scene: &Scene, options: &RenderOptions) -> Frame {
    let camera = &scene.camera;
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
    let request = HitRequest {
        normal: aovs
            .iter()
            .any(|a| matches!(a, Aov::Beauty | Aov::Normal | Aov::CameraNormal | Aov::ShadingNormal)),
        uv: aovs.contains(&Aov::Uv),
    };
    let shading = aovs.contains(&Aov::ShadingNormal);
    let channels: usize = aovs.iter().map(|a| a.channels().len()).sum();
    let row_len = window.width() as usize * channels;
    let mut samples = vec![0.0f32; row_len * window.height() as usize];
    let world_to_camera = camera.world_to_camera();

    let start = Instant::now();
    let bar = ProgressBar::with_draw_target(Some(u64::from(window.height())), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {elapsed} elapsed, ~{eta} left")
            .expect("valid template"),
    );
    let bar_shown = AtomicBool::new(false);

    samples.par_chunks_mut(row_len).enumerate().for_each(|(row, out)| {
        let y = window.y0 + row as u32;
        for (column, pixel) in out.chunks_exact_mut(channels).enumerate() {
            let x = window.x0 + column as u32;
            let ray = camera.pixel_ray(x, y);
            let hit = scene.intersect(&ray, Interval::POSITIVE).map(|(object, raw)| {
                let primitive = &*scene.objects[object as usize].primitive;
                let hit = SurfaceHit::complete(primitive, &ray, &raw, request);
                let shading_normal = if shading {
                    primitive.shading_normal_at(&ray, &raw).or(hit.normal)
                } else {
                    None
                };
                (object, hit, shading_normal)
            });
            let mut rest = &mut pixel[..];
            for aov in &aovs {
                let n = write_aov(
                    rest,
                    scene,
                    *aov,
                    &ray,
                    hit.as_ref(),
                    &world_to_camera,
                    options.depth_miss,
                );
                rest = &mut rest[n..];
            }
        }
        if options.progress {
            bar.inc(1);
            if !bar_shown.load(Ordering::Relaxed)
                && start.elapsed() > Duration::from_secs(1)
                && !bar_shown.swap(true, Ordering::Relaxed)
            {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
        }
    });
    bar.finish_and_clear();
    Frame {
        width: camera.width,
        height: camera.height,
        window,
        aovs,
        samples,
        elapsed: start.elapsed(),
    }
}

/// Writes one AOV's channels for one pixel at the start of `out`; returns how many it wrote.
#[inline(always)]
fn write_aov(
    out: &mut [f32],
    scene: &Scene,
    aov: Aov,
    ray: &Ray,
    hit: Option<&(u32, SurfaceHit, Option<DVec3>)>,
    world_to_camera: &glam::DMat4,
    depth_miss: f32,
) -> usize {
    let mut put3 = |v: DVec3| {
        out[0] = v.x as f32;
        out[1] = v.y as f32;
        out[2] = v.z as f32;
        3
    };
    let Some((object, hit, shading_normal)) = hit else {
        return match aov {
            Aov::Beauty => put3(scene.background),
            Aov::Normal | Aov::Position | Aov::CameraNormal | Aov::ShadingNormal => put3(DVec3::ZERO),
            Aov::Depth | Aov::Distance => {
                out[0] = depth_miss;
                1
            }
            Aov::PrimitiveId => {
                out[0] = -1.0;
                1
            }
            Aov::Alpha => {
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
        Aov::Depth => scene.camera.planar_depth(hit.point) as f32,
        Aov::Distance => hit.t as f32,
        Aov::PrimitiveId => *object as f32,
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
    let material = &scene.objects[object as usize].material;
    let n = hit.facing_normal(ray.dir).unwrap_or(DVec3::ZERO);
    let view = -ray.dir.normalize();
    if scene.lights.is_empty() {
        return material.color * (scene.ambient + DVec3::splat(n.dot(view).max(0.0)));
    }
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
        if cos <= 0.0 || scene.occluded(&Ray::new(origin, to_light), Interval::new(0.0, distance)) {
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
