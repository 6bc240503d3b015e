//! The single-ray walk: a ray that enters the root's children walks the 8-wide nodes
//! ([`Octs::traverse`](crate::bvh::oct::Octs::traverse)), nearest child first, testing each
//! leaf's triangles in one 8-lane watertight test ([`Mesh::leaf_closest`]) and keeping the
//! closest candidate; the candidate is then finished in f64 ([`Mesh::finish`]).
//!
//! The watertight test's axis order `[KX, KY, KZ]` is a const generic: the walk is compiled once
//! per order (`by_axes!`), its permutations resolved at compile time. The walk is kept out of
//! line ([`walk_either`]) so that rays passing the mesh by do not pay for its stack. Also here:
//! the brute-force reference ([`Mesh::intersect_brute_force`]) the tests compare against.

use super::query::{Candidate, MeshEntry, MeshQuery};
use super::storage::Mesh;
use super::watertight::watertight_lanes;
use crate::bvh::lanes::lanes_of;
use crate::bvh::walk::LeafTest;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};

impl Mesh {
    /// The single-ray walk of `query` (whose axes are `[KX, KY, KZ]`), the root's slab test
    /// `root` made ([`Mesh::enters_root`]): the closest candidate.
    #[inline(always)]
    fn closest_candidate<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        root: (u32, [f32; 8]),
    ) -> Option<Candidate> {
        let mut leaves = SingleRayLeaves::<KX, KY, KZ> {
            mesh: self,
            ray,
            range,
            query,
            best: None,
        };
        self.octs()
            .traverse(&query.ray.slab, query.t_min, query.t_max, root, &mut leaves);
        leaves.best
    }

    /// The leaf test of one ray (`query`, whose axes are `k`: a constant where the caller knows
    /// them) against the leaf of `count` triangles from `first`, its closest candidate so far
    /// `best` at `t_far`: all the leaf's triangles in one 8-lane test ([`watertight_lanes`]),
    /// then the lanes hit, in leaf order, each as the single test would take it (the f64 test
    /// for lanes with a zero edge function, the current `t_far`, [`Mesh::beats`],
    /// [`Mesh::counts`]). Returns the new `t_far` if a candidate was kept.
    #[allow(clippy::too_many_arguments, reason = "one ray's walk state, all of it read")]
    #[inline(always)]
    pub(super) fn leaf_closest(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        k: [usize; 3],
        first: u32,
        count: u32,
        mut t_far: f32,
        best: &mut Option<Candidate>,
    ) -> Option<f32> {
        let leaf = self.leaf(first, count);
        let mesh_ray = &query.ray;
        let origin = mesh_ray.origin_k;
        let lanes = watertight_lanes(&leaf.all_corner_rows(k), &origin, &mesh_ray.shear, query.t_min, t_far);
        let mut found = None;
        for i in lanes_of((lanes.pass | lanes.zero) & ((1 << count) - 1)) {
            let hit = if lanes.zero & (1 << i) != 0 {
                let [a, b, c] = leaf.permuted_corners(i, k);
                match mesh_ray.permuted_triangle(a, b, c, origin, query.t_min, t_far) {
                    Some(hit) => hit,
                    None => continue,
                }
            } else if lanes.t[i] <= t_far {
                lanes.hit(i)
            } else {
                continue;
            };
            let k = first as usize + i;
            if !Mesh::beats(best.as_ref(), k, hit.0, t_far) || !self.counts(ray, range, query, k, hit.0) {
                continue;
            }
            t_far = hit.0;
            found = Some(t_far);
            *best = Some(Candidate::new(hit, first, count, i));
        }
        found
    }

    /// The closest hit found by running the watertight test on every triangle, without the BVH
    /// (a reference for tests): `(file index, f32 t along the unit direction)`. The same f32 ray
    /// and the same rule as [`Mesh::intersect`]: the smallest `(t, leaf position)` wins.
    #[doc(hidden)]
    #[must_use]
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<(u32, f32)> {
        if !self.surface {
            return None;
        }
        let query = self.query(ray, Interval::new(0.0, f64::INFINITY))?;
        let mut best: Option<(u32, f32)> = None;
        for k in 0..self.in_bvh {
            let [a, b, c] = self.corners(k);
            if let Some((t, _, _)) = query.ray.triangle(a, b, c, 0.0, f32::INFINITY) {
                if best.is_none_or(|(_, t_best)| t < t_best) {
                    best = Some((self.leaf_to_file[k], t));
                }
            }
        }
        let unit = query.scale * ray.dir.length();
        best.map(|(file, t)| (file, (f64::from(t) * unit) as f32))
    }
}

/// The single-ray leaf test for a ray whose axes are `[KX, KY, KZ]`: each triangle of the leaf
/// in turn, keeping the closest candidate.
struct SingleRayLeaves<'a, const KX: usize, const KY: usize, const KZ: usize> {
    mesh: &'a Mesh,
    ray: &'a Ray,
    range: Interval,
    query: &'a MeshQuery,
    best: Option<Candidate>,
}

impl<const KX: usize, const KY: usize, const KZ: usize> LeafTest for &mut SingleRayLeaves<'_, KX, KY, KZ> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, t_far: f32) -> Option<f32> {
        self.mesh.leaf_closest(
            self.ray,
            self.range,
            self.query,
            [KX, KY, KZ],
            first,
            count,
            t_far,
            &mut self.best,
        )
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.mesh.prefetch_leaf(first, count);
    }
}

/// The single-ray walk of a ray whose set-up `entry` is made and which enters the root's children
/// `root` ([`Mesh::enters_root`]): the axes' copy of the walk chosen, the closest candidate
/// finished.
#[inline(always)]
pub(super) fn walk(mesh: &Mesh, ray: &Ray, range: Interval, entry: MeshEntry, root: (u32, [f32; 8])) -> Option<RawHit> {
    let query = entry.query();
    let best = by_axes!(query.ray.k, mesh.closest_candidate(ray, range, &query, root));
    mesh.finish(ray, range, &query, best)
}

/// [`walk`] in its own function (its AVX2+FMA copy where the CPU has them), whichever copy calls
/// it: inlined, the walk's stack and register saves would be paid by every ray, also by those
/// passing the mesh by (most of a random batch).
#[inline(never)]
fn walk_either(mesh: &Mesh, ray: &Ray, range: Interval, entry: MeshEntry, root: (u32, [f32; 8])) -> Option<RawHit> {
    crate::with_fma!(walk(
        mesh: &Mesh = mesh,
        ray: &Ray = ray,
        range: Interval = range,
        entry: MeshEntry = entry,
        root: (u32, [f32; 8]) = root,
    ) -> Option<RawHit>)
}

/// A single ray's test: the start every walk shares ([`Mesh::walk_start`]: the ball around the
/// mesh, the set-up and the root's test), then, for a ray entering one of the root's children,
/// the walk ([`walk_either`]).
#[inline(always)]
pub(super) fn single_ray(mesh: &Mesh, ray: &Ray, range: Interval) -> Option<RawHit> {
    let (entry, root) = mesh.walk_start(ray, range)?;
    walk_either(mesh, ray, range, entry, root)
}

/// [`single_ray`] of a ray that the ball test kept already ([`Mesh::walk_start_in_ball`]).
#[inline(always)]
pub(super) fn single_ray_in_ball(mesh: &Mesh, ray: &Ray, range: Interval) -> Option<RawHit> {
    let (entry, root) = mesh.walk_start_in_ball(ray, range)?;
    walk_either(mesh, ray, range, entry, root)
}
