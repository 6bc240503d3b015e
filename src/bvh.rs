//! A bounding volume hierarchy over the scene's bounded objects: binned SAH build, flattened
//! depth-first nodes, ordered closest-hit traversal.
//!
//! Build: each split evaluates 16 bins of centroids per axis with the surface-area heuristic
//! (traversal cost 1, intersection cost 1 per item) and makes a leaf when no split is cheaper
//! or at most 2 items remain. Nodes are stored depth-first: an interior node's first child follows
//! it, the second is at `second_child`.
//!
//! Traversal: a slab test per child with precomputed reciprocal directions, the nearer child
//! first, farther ones skipped once the closest hit so far is nearer than their entry. Exit
//! distances are enlarged by `1 + 2γ₃` (pbrt-v4) so rounding never culls a true hit.

use zeroset_primitives::math::gamma;
use zeroset_primitives::{Aabb, Interval, Ray};

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `items`; interior: index of the second child.
    offset: u32,
    /// Items in a leaf; 0 for an interior node.
    count: u32,
}

/// A BVH over items identified by `u32` indices.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    items: Vec<u32>,
}

const BINS: usize = 16;
const MAX_LEAF: usize = 2;

struct BuildItem {
    bounds: Aabb,
    centroid: glam::DVec3,
    index: u32,
}

impl Bvh {
    /// Builds over `bounds[i]` for each item `i` (all must be finite).
    #[must_use]
    pub fn build(bounds: &[Aabb]) -> Self {
        let mut work: Vec<BuildItem> = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| BuildItem {
                bounds: *b,
                centroid: b.center(),
                index: i as u32,
            })
            .collect();
        let mut bvh = Self {
            nodes: Vec::with_capacity(2 * bounds.len()),
            items: Vec::with_capacity(bounds.len()),
        };
        if !work.is_empty() {
            bvh.build_node(&mut work);
        }
        bvh
    }

    /// Number of nodes (0 for an empty hierarchy).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    fn build_node(&mut self, work: &mut [BuildItem]) -> usize {
        let bounds = work.iter().fold(Aabb::EMPTY, |b, w| b.union(w.bounds));
        let node_index = self.nodes.len();
        self.nodes.push(Node {
            bounds,
            offset: 0,
            count: 0,
        });
        let split = if work.len() > MAX_LEAF {
            best_split(work, &bounds)
        } else {
            None
        };
        match split {
            None => {
                self.nodes[node_index].offset = self.items.len() as u32;
                self.nodes[node_index].count = work.len() as u32;
                self.items.extend(work.iter().map(|w| w.index));
            }
            Some(mid) => {
                let (left, right) = work.split_at_mut(mid);
                self.build_node(left);
                let second = self.build_node(right);
                self.nodes[node_index].offset = second as u32;
            }
        }
        node_index
    }

    /// Closest-hit traversal: calls `test(item, range)` for items whose node the ray enters
    /// within `range`; `test` returns the hit parameter if it found one inside the range, which
    /// then becomes the new `range.max`. Returns the final range's `max`-setting item, if any.
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        mut range: Interval,
        mut test: impl FnMut(u32, Interval) -> Option<f64>,
    ) -> Option<u32> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = ray.dir.recip();
        let mut best = None;
        let mut stack = [0u32; 64];
        let mut top = 0usize;
        let mut current = 0usize;
        if slab_entry(&self.nodes[0].bounds, ray, inv, range).is_none() {
            return None;
        }
        loop {
            let node = &self.nodes[current];
            if node.count > 0 {
                let start = node.offset as usize;
                for &item in &self.items[start..start + node.count as usize] {
                    if let Some(t) = test(item, range) {
                        range.max = t;
                        best = Some(item);
                    }
                }
            } else {
                let (a, b) = (current + 1, node.offset as usize);
                let ta = slab_entry(&self.nodes[a].bounds, ray, inv, range);
                let tb = slab_entry(&self.nodes[b].bounds, ray, inv, range);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        stack[top] = far as u32;
                        top += 1;
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // pop the next node that the ray still enters before the closest hit
            loop {
                if top == 0 {
                    return best;
                }
                top -= 1;
                let candidate = stack[top] as usize;
                if slab_entry(&self.nodes[candidate].bounds, ray, inv, range).is_some() {
                    current = candidate;
                    break;
                }
            }
        }
    }
}

/// Entry parameter of the ray into `b` within `range`, or `None`.
#[inline(always)]
fn slab_entry(b: &Aabb, ray: &Ray, inv: glam::DVec3, range: Interval) -> Option<f64> {
    let t_lo = (b.min - ray.origin) * inv;
    let t_hi = (b.max - ray.origin) * inv;
    let near = t_lo.min(t_hi);
    let far = t_lo.max(t_hi) * (1.0 + 2.0 * gamma(3));
    // f64::max/min drop a NaN (origin on a slab plane of a zero direction component)
    let t0 = range.min.max(near.x).max(near.y).max(near.z);
    let t1 = range.max.min(far.x).min(far.y).min(far.z);
    (t0 <= t1).then_some(t0)
}

/// Index at which to split `work` (sorted in place), or `None` for a leaf.
fn best_split(work: &mut [BuildItem], bounds: &Aabb) -> Option<usize> {
    let centroid_bounds = work.iter().fold(Aabb::EMPTY, |b, w| b.including(w.centroid));
    let extent = centroid_bounds.extent();
    let leaf_cost = work.len() as f64;
    let parent_area = bounds.surface_area().max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins left of split)
    for axis in 0..3 {
        if !(extent[axis] > 0.0) {
            continue;
        }
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        let scale = BINS as f64 / extent[axis];
        let bin_of = |c: f64| (((c - centroid_bounds.min[axis]) * scale) as usize).min(BINS - 1);
        for w in work.iter() {
            let bin = bin_of(w.centroid[axis]);
            bin_counts[bin] += 1;
            bin_bounds[bin] = bin_bounds[bin].union(w.bounds);
        }
        // sweep from the right, then from the left
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(bin_bounds[i]);
            count += bin_counts[i];
            right_area[i] = acc.surface_area();
            right_count[i] = count;
        }
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for split in 1..BINS {
            acc = acc.union(bin_bounds[split - 1]);
            count += bin_counts[split - 1];
            if count == 0 || right_count[split] == 0 {
                continue;
            }
            let cost =
                1.0 + (acc.surface_area() * count as f64 + right_area[split] * right_count[split] as f64) / parent_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    if cost >= leaf_cost && work.len() <= 8 {
        return None;
    }
    let scale = BINS as f64 / extent[axis];
    let lo = centroid_bounds.min[axis];
    let mut mid = 0;
    for i in 0..work.len() {
        if ((((work[i].centroid[axis] - lo) * scale) as usize).min(BINS - 1)) < split {
            work.swap(i, mid);
            mid += 1;
        }
    }
    (mid > 0 && mid < work.len()).then_some(mid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// The BVH finds the same closest box as testing every box, on random boxes and rays.
    #[test]
    fn closest_hit_equals_brute_force() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let boxes: Vec<Aabb> = (0..500)
            .map(|_| {
                let c = DVec3::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                );
                let h = DVec3::new(
                    rng.random_range(0.01..1.0),
                    rng.random_range(0.01..1.0),
                    rng.random_range(0.01..1.0),
                );
                Aabb::new(c - h, c + h)
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        let entry = |b: &Aabb, ray: &Ray, range: Interval| b.clip(ray, range).map(|r| r.min);
        for _ in 0..5000 {
            let o = DVec3::new(rng.random_range(-15.0..15.0), rng.random_range(-15.0..15.0), -20.0);
            let d = DVec3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), 1.0).normalize();
            let ray = Ray::new(o, d);
            let brute = boxes
                .iter()
                .enumerate()
                .filter_map(|(i, b)| entry(b, &ray, Interval::POSITIVE).map(|t| (t, i as u32)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let found = bvh.closest(&ray, Interval::POSITIVE, |i, r| entry(&boxes[i as usize], &ray, r));
            assert_eq!(
                found.map(|i| entry(&boxes[i as usize], &ray, Interval::POSITIVE).unwrap()),
                brute.map(|b| b.0)
            );
        }
    }
}
