//! Every crossing along a ray ([`Scene::all_hits`]): wall thickness, multi-return LiDAR, X-ray
//! style paths.
//!
//! Each object whose box the ray passes through gives its own crossing stream
//! ([`zeroset_primitives::Intersect::crossings`]: closed forms, meshes and CSG walk their
//! surfaces once per ray); the streams are merged by `t` (ties by object index). Within one
//! object, crossings closer than a relative `2⁻⁴⁰` in `t` are one crossing
//! ([`zeroset_primitives::crossings::step_past`]), so a ray through an edge or vertex shared by
//! triangles is reported once, and tangential contacts (`dir · n = 0`) are not crossings. Each
//! crossing says whether the ray enters the object's solid there (`dir · ∇Φ < 0`).

use crate::scene::Scene;
use zeroset_primitives::{HitRequest, Interval, Ray, SurfaceHit};

/// One crossing of a surface along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCrossing {
    /// The object crossed.
    pub object: u32,
    /// The completed hit: `t`, point, outward normal, uv where the primitive has them, and the
    /// primitive's part (`feature`: a mesh's triangle, a box's face).
    pub hit: SurfaceHit,
    /// Whether the ray enters the object's solid here (`dir · n < 0`, from `Φ > 0` to `Φ < 0`).
    pub entering: bool,
}

/// What [`Scene::all_hits`] completes for each crossing: normal and uv.
const CROSSING_ANSWER: HitRequest = HitRequest {
    normal: true,
    uv: true,
    error: false,
};

impl Scene {
    /// Every crossing of every object's surface with `t` in `range`, in increasing `t` (see the
    /// module docs), appended to `out` (cleared first).
    pub fn all_hits(&self, ray: &Ray, range: Interval, out: &mut Vec<RayCrossing>) {
        out.clear();
        self.each_crossed_object(ray, range, |id| {
            let primitive = &*self.objects[id as usize].primitive;
            for crossing in primitive.crossings(ray, range) {
                if !range.contains(crossing.hit.t) {
                    continue;
                }
                out.push(RayCrossing {
                    object: id,
                    hit: SurfaceHit::complete(primitive, ray, &crossing.hit, CROSSING_ANSWER),
                    entering: crossing.inside_after,
                });
            }
        });
        if out
            .windows(2)
            .any(|w| w[1].hit.t < w[0].hit.t || (w[1].hit.t == w[0].hit.t && w[1].object < w[0].object))
        {
            out.sort_by(|a, b| a.hit.t.total_cmp(&b.hit.t).then(a.object.cmp(&b.object)));
        }
    }

    /// The number of crossings [`Scene::all_hits`] reports, without completing them.
    #[must_use]
    pub fn count_crossings(&self, ray: &Ray, range: Interval) -> usize {
        let mut count = 0;
        self.each_crossed_object(ray, range, |id| {
            count += self.objects[id as usize]
                .primitive
                .crossings(ray, range)
                .filter(|c| range.contains(c.hit.t))
                .count();
        });
        count
    }

    /// Calls `visit` with each object the ray may cross within `range`, each once: those tested
    /// by every ray, and those whose box in the hierarchy it enters.
    fn each_crossed_object(&self, ray: &Ray, range: Interval, mut visit: impl FnMut(u32)) {
        if self.hierarchy.bvh.is_empty() {
            self.hierarchy.unbounded.iter().for_each(|&id| visit(id));
            return;
        }
        let mut candidates = self.hierarchy.unbounded.clone();
        // a closest-hit walk that never finds a hit visits every box the ray enters
        self.hierarchy.bvh.closest(ray, range, |id, _| {
            candidates.push(id);
            None
        });
        candidates.sort_unstable();
        candidates.dedup();
        candidates.into_iter().for_each(visit);
    }
}

/// The columns of `zeroset query --all-hits`: one row per crossing.
pub const ALL_HITS_COLUMNS: [&str; 13] = [
    "ray",
    "t",
    "px",
    "py",
    "pz",
    "nx",
    "ny",
    "nz",
    "id",
    "primitive",
    "u",
    "v",
    "entering",
];

/// Every crossing along every ray of `source`, written to `sink` as rows of
/// [`ALL_HITS_COLUMNS`] (rays in input order, each chunk traced in parallel); returns the number
/// of rays and of crossings.
///
/// # Errors
/// Malformed input or a write error.
pub fn run_all_hits<W: std::io::Write>(
    scene: &Scene,
    source: &mut dyn super::RaySource,
    sink: &mut super::point_table::TableSink<W>,
) -> anyhow::Result<(u64, u64)> {
    use rayon::prelude::*;
    let mut rays = Vec::new();
    let (mut ray_count, mut crossing_count) = (0u64, 0u64);
    loop {
        let more = source.read_chunk(super::CHUNK_RAYS, &mut rays)?;
        let first = ray_count;
        let rows: Vec<f64> = rays
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map_init(Vec::new, |found, (i, q)| {
                scene.all_hits(&q.ray, q.range, found);
                let mut rows = Vec::with_capacity(found.len() * ALL_HITS_COLUMNS.len());
                for c in found.iter() {
                    let n = c.hit.normal.map_or([f64::NAN; 3], |n| n.to_array());
                    let uv = c.hit.uv.map_or([f64::NAN; 2], |uv| uv.to_array());
                    rows.extend_from_slice(&[
                        (first + i as u64) as f64,
                        c.hit.t,
                        c.hit.point.x,
                        c.hit.point.y,
                        c.hit.point.z,
                        n[0],
                        n[1],
                        n[2],
                        f64::from(c.object),
                        f64::from(c.hit.feature),
                        uv[0],
                        uv[1],
                        f64::from(u8::from(c.entering)),
                    ]);
                }
                rows
            })
            .flatten_iter()
            .collect();
        crossing_count += (rows.len() / ALL_HITS_COLUMNS.len()) as u64;
        ray_count += rays.len() as u64;
        sink.write(&rows)?;
        if !more {
            return Ok((ray_count, crossing_count));
        }
    }
}
