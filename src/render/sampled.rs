//! Pixels of several samples (spp > 1, or moving objects): each sample traced and the
//! samples resolved per AOV as the table of [`crate::render`] says.

use super::pixel::{flag_uncertain, write_aov, write_miss, RowContext};
use super::shade::shade_at;
use crate::aov::Aov;
use crate::sampling::{pixel_samples, PixelSample};
use crate::scene::Scene;
use glam::DVec3;
use zeroset_primitives::root::thread_uncertain_events;
use zeroset_primitives::{Interval, Ray, SurfaceHit};

/// One sample's hit: the object, its record, shading normal, planar depth and ray.
pub(super) struct SampleHit {
    pub(super) object: u32,
    pub(super) hit: SurfaceHit,
    pub(super) shading_normal: Option<DVec3>,
    pub(super) depth: f64,
    pub(super) ray: Ray,
}

/// Renders row `y` from column `x0` with the scene's samples per pixel, resolving each pixel's
/// samples per AOV as the module table says.
#[inline(never)]
pub(super) fn render_row_sampled(scene: &Scene, context: &RowContext, x0: u32, y: u32, out: &mut [f32]) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::size_of;

    #[test]
    fn a_sample_fits_the_memory_estimate() {
        // what a thread holds per sample of a pixel: its position, its stratification scratch
        // (two u32), its hit and, at worst, a count entry of its own, all but the scratch in
        // vectors grown by doubling (up to twice their length)
        let bytes = 2 * (size_of::<PixelSample>() + size_of::<SampleHit>() + size_of::<(u32, u32, f64)>())
            + 2 * size_of::<u32>();
        assert!(
            bytes as u64 <= crate::resources::BYTES_PER_SAMPLE,
            "{bytes} bytes a sample"
        );
    }
}
