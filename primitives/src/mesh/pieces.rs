//! A mesh as [`Pieces`]: its hierarchy's leaves (up to eight triangles each), the piece
//! numbered `4·q + s` being the leaf in slot `s` of 4-wide node `q`, its box that slot's box,
//! the one the walks test before the leaf. Numbers of other slots (inner nodes, empty slots)
//! name no piece.
//!
//! [`Pieces::intersect_pieces`] runs, for each candidate leaf in the order given, the walk's own
//! steps: the slab test of the leaf's box against the f32 ray up to [`cull_bound`] of the closest
//! hit so far (the test by which the walk skips a subtree), then the leaf's 8-lane watertight
//! test keeping the smallest `(t, leaf position)`, and at the end the same f64 `t`. A leaf
//! holding the closest hit is entered by that test (its box holds the triangle, the slab test is
//! conservative), so any set of candidates holding it gives the walk's answer, in any order.
//! A triangle the watertight test accepts lies within a few f32 ulps of the f32 ray, which is
//! within f32 rounding of the f64 ray (`2⁻²⁴` of the distance, and the origin's own rounding,
//! [`crate::Intersect::origin_rounding`]): the f64 ray passes its box closer than the margin
//! the trait asks candidates to be chosen with.

use super::query::{Candidate, MeshQuery};
use super::storage::{v64, Mesh};
use crate::bounds::Aabb;
use crate::bvh::quad::Quad;
use crate::bvh::walk::cull_bound;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::{Pieces, Wanted};
use glam::Vec3;

impl Mesh {
    /// The node and slot of the leaf numbered `number`, if one is.
    #[inline(always)]
    fn leaf_slot(&self, number: u32) -> Option<(&Quad, usize)> {
        let quad = self.bvh.quads().get((number >> 2) as usize)?;
        let slot = (number & 3) as usize;
        (slot < quad.len as usize && quad.count[slot] > 0).then_some((quad, slot))
    }

    /// The closest candidate among the leaves `candidates` for a ray whose axes are
    /// `[KX, KY, KZ]` (module docs); with `near` (the candidates' distances, see
    /// [`Pieces::intersect_pieces_nearest_first`]), the list ends at the first candidate whose
    /// `near` lies beyond the closest hit so far.
    #[inline(always)]
    fn closest_among<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        candidates: impl Iterator<Item = (u32, Option<f32>)>,
    ) -> Option<Candidate> {
        let mut best = None;
        let mut t_far = query.t_max;
        // `near²` beyond which a candidate cannot be entered by the slab test below: the
        // distance along the ray of `cull_bound(t_far)` (f32 `t` along the scaled direction, `t`
        // along the ray's times `scale`), enlarged by `10⁻⁶` for the rounding of the slab test
        // and of this bound (`near` already lies below the box by the trait's margin, far more
        // than the f32 origin's rounding)
        let mut reach_squared = f64::INFINITY;
        for (number, near) in candidates {
            if let Some(near) = near {
                let near = f64::from(near);
                if near * near > reach_squared {
                    break;
                }
            }
            let Some((quad, slot)) = self.leaf_slot(number) else {
                continue;
            };
            let (lo, hi) = quad.slot_bounds(slot);
            if !query.ray.slab.enters(lo, hi, query.t_min, cull_bound(t_far)) {
                continue;
            }
            let (first, count) = (quad.child[slot], u32::from(quad.count[slot]));
            if let Some(t) = self.leaf_closest(ray, range, query, [KX, KY, KZ], first, count, t_far, &mut best) {
                t_far = t;
                let reach = f64::from(cull_bound(t_far)) * query.scale;
                reach_squared = reach * reach * ray.dir.length_squared() * (1.0 + 1e-6);
            }
        }
        best
    }
}

/// The candidates `listed()` of `mesh` (`(number, near)`, see [`Mesh::closest_among`]; `empty`
/// where there are none): the ray's set-up, the copy for its axes, the f64 `t`, and where
/// `NORMAL` asks for it the hit's f32 normal ([`Mesh::finish_with_normal`]). (No closure to
/// finish with: left to the compiler, one was not inlined.)
#[inline(always)]
fn among_listed<const NORMAL: bool, I: Iterator<Item = (u32, Option<f32>)>>(
    mesh: &Mesh,
    ray: &Ray,
    range: Interval,
    empty: bool,
    listed: impl Fn() -> I,
) -> Option<(RawHit, Option<Vec3>)> {
    if empty {
        return None;
    }
    let query = mesh.entry(ray, range)?.query();
    let best = by_axes!(query.ray.k, mesh.closest_among(ray, range, &query, listed()));
    if NORMAL {
        let (hit, normal) = mesh.finish_with_normal(ray, range, &query, best)?;
        Some((hit, Some(normal)))
    } else {
        Some((mesh.finish(ray, range, &query, best)?, None))
    }
}

/// [`Pieces::intersect_pieces`] of `mesh` ([`among_listed`], every candidate tested).
#[inline(always)]
fn among(mesh: &Mesh, ray: &Ray, range: Interval, candidates: &[u32]) -> Option<RawHit> {
    let found = among_listed::<false, _>(mesh, ray, range, candidates.is_empty(), || {
        candidates.iter().map(|&number| (number, None))
    });
    Some(found?.0)
}

/// [`Pieces::intersect_pieces_nearest_first`] of `mesh` ([`among_listed`], the list ending where
/// the candidates lie beyond the closest hit so far), with the hit's normal where `NORMAL`
/// asks for it.
#[inline(always)]
fn among_nearest_first<const NORMAL: bool>(
    mesh: &Mesh,
    ray: &Ray,
    range: Interval,
    candidates: &[(u32, f32)],
) -> Option<(RawHit, Option<Vec3>)> {
    among_listed::<NORMAL, _>(mesh, ray, range, candidates.is_empty(), || {
        candidates.iter().map(|&(number, near)| (number, Some(near)))
    })
}

/// [`among_nearest_first`], the raw hit alone.
#[inline(always)]
fn nearest_first(mesh: &Mesh, ray: &Ray, range: Interval, candidates: &[(u32, f32)]) -> Option<RawHit> {
    Some(among_nearest_first::<false>(mesh, ray, range, candidates)?.0)
}

/// [`among_nearest_first`] with the hit's f32 normal.
#[inline(always)]
fn nearest_first_with_normal(
    mesh: &Mesh,
    ray: &Ray,
    range: Interval,
    candidates: &[(u32, f32)],
) -> Option<(RawHit, Option<Vec3>)> {
    among_nearest_first::<true>(mesh, ray, range, candidates)
}

impl Pieces for Mesh {
    fn piece_numbers(&self) -> Vec<u32> {
        self.bvh.leaf_slot_numbers()
    }

    /// The walk of [`Pieces::piece_numbers`] over the hierarchy, asking about each inner node's
    /// box (its slot's box in its parent): not entering a node wanted for [`Wanted::Nothing`],
    /// taking every leaf below one wanted for [`Wanted::Everything`] without asking further.
    /// Leaves themselves are not asked about (their boxes are the pieces').
    fn piece_numbers_kept(&self, wanted: &(dyn Fn(&Aabb) -> Wanted + Sync)) -> Vec<u32> {
        self.bvh.leaf_slot_numbers_kept(|quad, slot| {
            let (lo, hi) = quad.slot_bounds(slot);
            wanted(&Aabb::new(v64(lo), v64(hi)))
        })
    }

    fn piece_box(&self, number: u32) -> Option<Aabb> {
        let (quad, slot) = self.leaf_slot(number)?;
        let (lo, hi) = quad.slot_bounds(slot);
        Some(Aabb::new(v64(lo), v64(hi)))
    }

    /// [`among`] in its AVX2+FMA copy where the CPU has them.
    fn intersect_pieces(&self, ray: &Ray, range: Interval, candidates: &[u32]) -> Option<RawHit> {
        crate::with_fma!(among(
            mesh: &Mesh = self,
            ray: &Ray = ray,
            range: Interval = range,
            candidates: &[u32] = candidates,
        ) -> Option<RawHit>)
    }

    /// [`nearest_first_with_normal`] in its AVX2+FMA copy where the CPU has them.
    fn intersect_pieces_nearest_first_with_normal(
        &self,
        ray: &Ray,
        range: Interval,
        candidates: &[(u32, f32)],
    ) -> Option<(RawHit, Option<Vec3>)> {
        crate::with_fma!(nearest_first_with_normal(
            mesh: &Mesh = self,
            ray: &Ray = ray,
            range: Interval = range,
            candidates: &[(u32, f32)] = candidates,
        ) -> Option<(RawHit, Option<Vec3>)>)
    }

    /// [`nearest_first`] in its AVX2+FMA copy where the CPU has them.
    fn intersect_pieces_nearest_first(&self, ray: &Ray, range: Interval, candidates: &[(u32, f32)]) -> Option<RawHit> {
        crate::with_fma!(nearest_first(
            mesh: &Mesh = self,
            ray: &Ray = ray,
            range: Interval = range,
            candidates: &[(u32, f32)] = candidates,
        ) -> Option<RawHit>)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traits::Intersect;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// A closed, bumpy sphere of `4·n²` triangles around the origin (radius about 1).
    fn bumpy_sphere(n: usize) -> Mesh {
        let mut vertices = Vec::new();
        let mut tris = Vec::new();
        let (rows, columns) = (n, 2 * n);
        for i in 0..=rows {
            for j in 0..columns {
                let theta = std::f64::consts::PI * i as f64 / rows as f64;
                let phi = std::f64::consts::TAU * j as f64 / columns as f64;
                let r = 1.0 + 0.1 * (5.0 * phi).sin() * (3.0 * theta).sin();
                vertices.push([
                    (r * theta.sin() * phi.cos()) as f32,
                    (r * theta.cos()) as f32,
                    (r * theta.sin() * phi.sin()) as f32,
                ]);
            }
        }
        for i in 0..rows {
            for j in 0..columns {
                let at = |i: usize, j: usize| (i * columns + j % columns) as u32;
                tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        Mesh::new(vertices, tris, None).unwrap()
    }

    /// Whether the f64 ray passes within `margin` of `bounds` inside `range` (the exact slab
    /// test on the box grown by `margin`).
    fn passes_near(bounds: &Aabb, margin: f64, ray: &Ray, range: Interval) -> bool {
        bounds.expanded(margin).clip(ray, range).is_some()
    }

    /// Every piece of `mesh` with its box.
    fn piece_boxes(mesh: &Mesh) -> Vec<(u32, Aabb)> {
        mesh.piece_numbers()
            .into_iter()
            .map(|n| (n, mesh.piece_box(n).unwrap()))
            .collect()
    }

    /// The margin the trait asks candidates to be chosen with, for `bounds` seen from `origin`.
    fn trait_margin(mesh: &Mesh, bounds: &Aabb, origin: DVec3) -> f64 {
        1e-6 * (bounds.diagonal_length() + (bounds.center() - origin).length()) + 4.0 * mesh.origin_rounding(origin)
    }

    /// A random ray through the bumpy sphere's box (direction `target − origin`): from inside it
    /// one trial in `inside_every`, else from in front of it.
    fn random_ray(rng: &mut impl Rng, trial: usize, inside_every: usize) -> (DVec3, DVec3) {
        let origin = if trial % inside_every == 0 {
            DVec3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            )
        } else {
            DVec3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), -4.0)
        };
        let target = DVec3::new(
            rng.random_range(-1.3..1.3),
            rng.random_range(-1.3..1.3),
            rng.random_range(-1.0..1.0),
        );
        (origin, target - origin)
    }

    /// With the candidates chosen as the trait asks (every piece whose box the ray passes within
    /// the margin), shuffled or not, the answer is `intersect`'s, bit for bit, over random rays
    /// from outside and inside, hitting and missing; the candidates are a small share of the
    /// pieces, and dropping the piece that holds the hit loses it.
    #[test]
    fn candidate_pieces_give_the_walk_s_answer() {
        let mesh = bumpy_sphere(40);
        let boxes = piece_boxes(&mesh);
        assert!(boxes.len() > 100, "{} pieces", boxes.len());
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (mut hits, mut candidates_seen, mut lost) = (0, 0usize, 0);
        for trial in 0..3000 {
            let (origin, dir) = random_ray(&mut rng, trial, 4);
            let ray = Ray::new(origin, dir);
            let range = Interval::POSITIVE;
            let mut candidates: Vec<u32> = boxes
                .iter()
                .filter(|(_, b)| passes_near(b, trait_margin(&mesh, b, origin), &ray, range))
                .map(|&(n, _)| n)
                .collect();
            candidates_seen += candidates.len();
            let walk = mesh.intersect(&ray, range);
            assert_eq!(mesh.intersect_pieces(&ray, range, &candidates), walk, "trial {trial}");
            // farthest first, with repeats and numbers of no piece
            candidates.reverse();
            let repeated: Vec<u32> = candidates
                .iter()
                .chain(&candidates)
                .chain(&[0, 1, u32::MAX])
                .copied()
                .collect();
            assert_eq!(
                mesh.intersect_pieces(&ray, range, &repeated),
                walk,
                "trial {trial} reversed"
            );
            if let Some(hit) = walk {
                hits += 1;
                let k = mesh.file_to_leaf[hit.feature as usize];
                let holder = boxes
                    .iter()
                    .map(|&(n, _)| n)
                    .find(|&n| {
                        let (quad, slot) = mesh.leaf_slot(n).unwrap();
                        (quad.child[slot]..quad.child[slot] + u32::from(quad.count[slot])).contains(&k)
                    })
                    .unwrap();
                candidates.retain(|&c| c != holder);
                if mesh.intersect_pieces(&ray, range, &candidates) != walk {
                    lost += 1;
                }
            }
        }
        assert!(hits > 1500, "{hits} hits");
        assert_eq!(lost, hits, "the hit's own piece is needed");
        assert!(
            candidates_seen < 3000 * boxes.len() / 10,
            "{candidates_seen} candidates over 3000 rays of {} pieces",
            boxes.len()
        );
        assert_eq!(
            mesh.intersect_pieces(&Ray::new(DVec3::ZERO, DVec3::X), Interval::POSITIVE, &[]),
            None
        );
    }

    /// Listed nearest first with their distances (as the trait allows them: the distance from
    /// the origin to the box less the trait's margin, rounded down), the candidates give the
    /// walk's answer, bit for bit, for directions of any length; and the candidates whose
    /// distance lies beyond the hit, which the list's early end leaves untested, are never
    /// needed: without them the answer is the same.
    #[test]
    fn candidates_listed_nearest_first_give_the_walk_s_answer() {
        let mesh = bumpy_sphere(40);
        let boxes = piece_boxes(&mesh);
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let mut hits = 0;
        for trial in 0..3000 {
            let (origin, dir) = random_ray(&mut rng, trial, 5);
            // directions of any length: the distances are compared along the ray itself
            let ray = Ray::new(origin, dir * rng.random_range(0.01..100.0));
            let range = Interval::POSITIVE;
            let mut listed: Vec<(u32, f32)> = boxes
                .iter()
                .filter_map(|(n, b)| {
                    let margin = trait_margin(&mesh, b, origin);
                    if !passes_near(b, margin, &ray, range) {
                        return None;
                    }
                    let distance = (origin.clamp(b.min, b.max) - origin).length();
                    Some((*n, crate::bvh::rounding::round_down((distance - margin).max(0.0))))
                })
                .collect();
            listed.sort_by(|a, b| a.1.total_cmp(&b.1));
            let walk = mesh.intersect(&ray, range);
            assert_eq!(
                mesh.intersect_pieces_nearest_first(&ray, range, &listed),
                walk,
                "trial {trial}"
            );
            if let Some(hit) = walk {
                hits += 1;
                // the pieces whose `near` lies beyond the hit, by more than rounding: never needed
                let reach = hit.t * ray.dir.length() * (1.0 + 1e-6);
                let kept: Vec<(u32, f32)> = listed.iter().copied().filter(|c| f64::from(c.1) <= reach).collect();
                assert_eq!(
                    mesh.intersect_pieces_nearest_first(&ray, range, &kept),
                    walk,
                    "trial {trial} kept"
                );
            }
        }
        assert!(hits > 1500, "{hits} hits");
    }

    /// Pieces kept by the boxes they lie in: asked about nothing (every box wanted
    /// [`Wanted::Everything`]) the walk returns `piece_numbers` as it is; asked about a region,
    /// it returns a subsequence of it (the same order) holding every piece whose box meets the
    /// region, and fewer pieces in all; a region outside the mesh keeps at most the few leaves
    /// of the first levels, which are never asked about.
    #[test]
    fn kept_pieces_are_those_of_the_boxes_wanted() {
        let mesh = bumpy_sphere(48);
        let all = mesh.piece_numbers();
        assert_eq!(mesh.piece_numbers_kept(&|_| Wanted::Everything), all);
        let meets = |b: &Aabb, lo: DVec3, hi: DVec3| b.min.cmple(hi).all() && b.max.cmpge(lo).all();
        let within = |b: &Aabb, lo: DVec3, hi: DVec3| b.min.cmpge(lo).all() && b.max.cmple(hi).all();
        let regions = [
            (DVec3::new(-0.2, -0.3, -2.0), DVec3::new(0.4, 0.1, 2.0)),
            (DVec3::new(0.5, 0.5, 0.5), DVec3::new(2.0, 2.0, 2.0)),
            (DVec3::new(-2.0, -2.0, -2.0), DVec3::new(2.0, 0.0, 2.0)),
        ];
        for (lo, hi) in regions {
            let asked = std::sync::atomic::AtomicUsize::new(0);
            let kept = mesh.piece_numbers_kept(&|b| {
                asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if !meets(b, lo, hi) {
                    Wanted::Nothing
                } else if within(b, lo, hi) {
                    Wanted::Everything
                } else {
                    Wanted::Partly
                }
            });
            let mut rest = all.iter();
            assert!(kept.iter().all(|k| rest.any(|a| a == k)), "not in piece_numbers' order");
            for &n in &all {
                if meets(&mesh.piece_box(n).unwrap(), lo, hi) {
                    assert!(kept.contains(&n), "piece {n} meets the region but was left out");
                }
            }
            assert!(kept.len() < all.len(), "{} of {} pieces kept", kept.len(), all.len());
            assert!(asked.into_inner() > 0);
        }
        let far = mesh.piece_numbers_kept(&|b| {
            if meets(b, DVec3::splat(5.0), DVec3::splat(6.0)) {
                Wanted::Partly
            } else {
                Wanted::Nothing
            }
        });
        assert!(far.len() <= 4, "{} pieces kept far from the mesh", far.len());
    }

    /// The pieces' boxes hold their triangles, and the pieces partition the triangles; the
    /// numbers of the other slots name no piece.
    #[test]
    fn pieces_hold_their_triangles() {
        let mesh = bumpy_sphere(24);
        let numbers = mesh.piece_numbers();
        let mut seen = vec![0u32; mesh.in_bvh];
        for &number in &numbers {
            let bounds = mesh.piece_box(number).unwrap();
            let (quad, slot) = mesh.leaf_slot(number).unwrap();
            for k in quad.child[slot]..quad.child[slot] + u32::from(quad.count[slot]) {
                seen[k as usize] += 1;
                for v in mesh.corners(k as usize) {
                    assert!(bounds.contains(v64(v)), "leaf triangle {k}");
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1));
        let others = (0..4 * mesh.node_count() as u32).filter(|n| !numbers.contains(n));
        assert!(others.clone().count() > 0);
        assert!(others.clone().all(|n| mesh.piece_box(n).is_none()));
        // in bulk: the same boxes, the numbers of no piece empty
        let asked: Vec<u32> = numbers.iter().copied().chain(others).chain([u32::MAX]).collect();
        let mut boxes = vec![Aabb::new(glam::DVec3::ZERO, glam::DVec3::ONE); asked.len()];
        mesh.piece_boxes(&asked, &mut boxes);
        for (&number, bounds) in asked.iter().zip(&boxes) {
            assert_eq!(*bounds, mesh.piece_box(number).unwrap_or(Aabb::EMPTY), "piece {number}");
        }
        assert!(boxes[numbers.len()..].iter().all(Aabb::is_empty));
    }
}
