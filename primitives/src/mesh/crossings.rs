//! Every crossing of a ray with the mesh in one walk ([`Mesh::crossings`]'s stream): the
//! 8-wide nodes are walked once, every leaf the ray enters within its range is tested (no
//! closest-hit culling), each hit lane is taken as the single-ray test takes it (the f64 test for
//! lanes with a zero edge function, the band rule near `t_min`, `t` recomputed in f64 on the
//! triangle's plane), and the hits are sorted by `(t, leaf position)`.
//!
//! Hits closer than [`step_past`] in `t` are one place on the surface (a ray through an edge or
//! vertex shared by triangles hits each of them): where their facings (signs of `dir · n`) add up
//! to zero the ray only touches the surface there (a silhouette edge) and nothing is reported;
//! otherwise one crossing, the first triangle's, with the facing of the sum. Hits whose plane
//! contains the ray (`dir · n = 0`) are not crossings.

use super::query::{Candidate, MeshQuery};
use super::storage::Mesh;
use super::watertight::watertight_lanes;
use crate::bvh::lanes::lanes_of;
use crate::bvh::walk::LeafTest;
use crate::crossings::{step_past, Crossing};
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};

/// The leaf test that keeps every hit.
struct AllLeaves<'a, const KX: usize, const KY: usize, const KZ: usize> {
    mesh: &'a Mesh,
    ray: &'a Ray,
    range: Interval,
    query: &'a MeshQuery,
    found: Vec<Candidate>,
}

impl<const KX: usize, const KY: usize, const KZ: usize> LeafTest for &mut AllLeaves<'_, KX, KY, KZ> {
    /// Keeps the leaf's hits; returns nothing, so no leaf is culled.
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, _t_far: f32) -> Option<f32> {
        let leaf = self.mesh.leaf(first, count);
        let mesh_ray = &self.query.ray;
        let origin = mesh_ray.origin_k;
        let k = [KX, KY, KZ];
        let (t_min, t_max) = (self.query.t_min, self.query.t_max);
        let lanes = watertight_lanes(&leaf.all_corner_rows(k), &origin, &mesh_ray.shear, t_min, t_max);
        for i in lanes_of((lanes.pass | lanes.zero) & ((1 << count) - 1)) {
            let hit = if lanes.zero & (1 << i) != 0 {
                let [a, b, c] = leaf.permuted_corners(i, k);
                match mesh_ray.permuted_triangle(a, b, c, origin, t_min, t_max) {
                    Some(hit) => hit,
                    None => continue,
                }
            } else {
                lanes.hit(i)
            };
            if self
                .mesh
                .counts(self.ray, self.range, self.query, first as usize + i, hit.0)
            {
                self.found.push(Candidate::new(hit, first, count, i));
            }
        }
        None
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.mesh.prefetch_leaf(first, count);
    }
}

impl Mesh {
    /// The walk of [`all_crossings`] for a ray whose axes are `[KX, KY, KZ]`.
    #[inline(always)]
    fn all_hits_walk<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        root: (u32, [f32; 8]),
        found: Vec<Candidate>,
    ) -> Vec<Candidate> {
        let mut leaves = AllLeaves::<KX, KY, KZ> {
            mesh: self,
            ray,
            range,
            query,
            found,
        };
        self.octs()
            .traverse(&query.ray.slab, query.t_min, query.t_max, root, &mut leaves);
        leaves.found
    }
}

/// The crossings of `ray` with `mesh` within `range`, in increasing `t` (see the module docs).
#[inline(always)]
pub(super) fn all_crossings(mesh: &Mesh, ray: &Ray, range: Interval) -> Vec<Crossing> {
    let Some((entry, root)) = mesh.walk_start(ray, range) else {
        return Vec::new();
    };
    let query = entry.query();
    SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
        Ok(mut scratch) => crossings_of(mesh, ray, range, &query, root, &mut scratch),
        Err(_) => crossings_of(mesh, ray, range, &query, root, &mut Scratch::default()),
    })
}

/// Room reused from ray to ray by [`all_crossings`]: the candidates of the walk and the hits
/// made of them.
#[derive(Default)]
struct Scratch {
    candidates: Vec<Candidate>,
    hits: Vec<(RawHit, f64, usize)>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// [`all_crossings`] once the ray enters the mesh's root, with `scratch` as room.
#[inline(always)]
fn crossings_of(
    mesh: &Mesh,
    ray: &Ray,
    range: Interval,
    query: &MeshQuery,
    root: (u32, [f32; 8]),
    scratch: &mut Scratch,
) -> Vec<Crossing> {
    let mut candidates = std::mem::take(&mut scratch.candidates);
    candidates.clear();
    let candidates = by_axes!(query.ray.k, mesh.all_hits_walk(ray, range, query, root, candidates));
    let hits = &mut scratch.hits;
    hits.clear();
    hits.extend(candidates.iter().filter_map(|c| {
        let (hit, n) = mesh.finish_on_plane(ray, range, query, *c)?;
        let facing = ray.dir.dot(n);
        Some((hit, facing.signum() * f64::from(u8::from(facing != 0.0)), c.k()))
    }));
    scratch.candidates = candidates;
    hits.sort_unstable_by(|a, b| a.0.t.total_cmp(&b.0.t).then(a.2.cmp(&b.2)));
    let mut out = Vec::with_capacity(hits.len());
    let mut i = 0;
    while i < hits.len() {
        let (first, _, _) = hits[i];
        let end = step_past(first.t);
        let mut net = 0.0;
        let mut j = i;
        while j < hits.len() && hits[j].0.t < end {
            net += hits[j].1;
            j += 1;
        }
        if net != 0.0 {
            out.push(Crossing {
                hit: first,
                inside_after: net < 0.0,
            });
        }
        i = j;
    }
    out
}
