//! The scene's bounding volume hierarchy over its bounded objects: binned-SAH build of a binary
//! tree, collapsed into 4-wide nodes for ordered closest-hit traversal. (Meshes have their own,
//! `crate::mesh`.)
//!
//! Build: each split evaluates 16 bins of centroids per axis with the surface-area heuristic
//! (traversal cost 1, intersection cost 1 per item) and makes a leaf when no split is cheaper
//! or at most 2 items remain; below depth 28 it splits at the median. Binary nodes are stored
//! depth-first (an interior node's first child follows it, the second is at `offset`), then each
//! interior node is collapsed with its widest descendants into a 4-wide node (`Quad`).
//!
//! Traversal: quads hold their children's f32 bounds (rounded outward) in SoA layout, tested
//! four at a time with SSE, conservative against the f64 ray (see `SlabRay`); entered children
//! are pushed farthest first and skipped when popped if the closest hit is already nearer.
//! Primitives are then tested in f64, so the f32 traversal never changes a hit.

use crate::{Aabb, Interval, Ray};
use glam::{Vec3, Vec3A, Vec4};
use std::mem::MaybeUninit;

/// A node: bounds in f32, rounded outward from the f64 bounds so they still contain them.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    /// `[min, max]`.
    bounds: [[f32; 3]; 2],
    /// Leaf: first index into `items`; interior: index of the second child.
    offset: u32,
    /// Items in a leaf; 0 for an interior node.
    count: u32,
}

fn round_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        y.next_up()
    } else {
        y
    }
}

impl Node {
    #[cfg(test)]
    fn new(b: &Aabb) -> Self {
        Self {
            bounds: [
                [round_down(b.min.x), round_down(b.min.y), round_down(b.min.z)],
                [round_up(b.max.x), round_up(b.max.y), round_up(b.max.z)],
            ],
            offset: 0,
            count: 0,
        }
    }
}

/// A BVH over items identified by `u32` ids.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The binary tree during the build; emptied (and its memory freed) once collapsed.
    nodes: Vec<Node>,
    node_count: usize,
    items: Vec<u32>,
    /// The binary tree collapsed into 4-wide nodes, which the traversal walks.
    quads: Vec<Quad>,
}

/// A 4-wide node, shared by the scene's and the meshes' hierarchies: up to four children's f32
/// boxes in SoA layout, tested in one SSE pass per axis. `count[i] = 0` marks an inner child
/// (its quad is `child[i]`), `count[i] > 0` a leaf of that many items (or triangles) from
/// `child[i]`; slots beyond `len` are empty.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Quad {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub child: [u32; 4],
    pub count: [u32; 4],
    pub len: u32,
}

/// Traversal stack capacity: at most 3 entries left per level over at most 128 levels (both
/// hierarchies split at the median below a fixed depth, which bounds theirs under 128), plus 4.
const QUAD_STACK: usize = 3 * 128 + 4;

/// Ordered closest-hit walk over 4-wide nodes, starting at `quads[0]`: `entry4(quad, t_max)`
/// gives a bit per child slot the ray enters before `t_max` and the entry distances. The nearest
/// entered child is visited next and the others pushed farthest first (among equal entries the
/// later slot is visited first); one popped after the closest hit moved nearer than its entry
/// is skipped. `leaf(first, count, t_max)` tests a leaf and returns the new, smaller `t_max` if
/// it found a hit.
#[inline(always)]
pub(crate) fn traverse_quads(
    quads: &[Quad],
    mut t_max: f32,
    entry4: impl Fn(&Quad, f32) -> (u32, [f32; 4]),
    mut leaf: impl FnMut(u32, u32, f32) -> Option<f32>,
) {
    if quads.is_empty() {
        return;
    }
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<(u32, u32, f32)>::uninit() }; QUAD_STACK];
    let mut top = 0usize;
    let mut quad = 0usize;
    'nodes: loop {
        let q = &quads[quad];
        let (hits, near) = entry4(q, t_max);
        let mut hits = hits & ((1u32 << q.len) - 1);
        let mut next = None;
        if hits != 0 {
            if hits & (hits - 1) == 0 {
                let slot = hits.trailing_zeros() as usize;
                next = Some((q.child[slot], q.count[slot], near[slot]));
            } else {
                // the entered children sorted farthest first (insertion into at most four)
                let mut order = [(0f32, 0usize); 4];
                let mut n = 0;
                while hits != 0 {
                    let slot = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    let t = near[slot];
                    let mut k = n;
                    while k > 0 && order[k - 1].0 < t {
                        order[k] = order[k - 1];
                        k -= 1;
                    }
                    order[k] = (t, slot);
                    n += 1;
                }
                for &(t, slot) in &order[..n - 1] {
                    stack[top].write((q.child[slot], q.count[slot], t));
                    top += 1;
                }
                let (t, slot) = order[n - 1];
                next = Some((q.child[slot], q.count[slot], t));
            }
        }
        // visit `next`, else pop, until an inner node to open
        loop {
            let (child, count, entry) = match next.take() {
                Some(entry) => entry,
                None => {
                    if top == 0 {
                        return;
                    }
                    top -= 1;
                    // SAFETY: `stack[top]` was written by the push that raised `top` above it
                    unsafe { stack[top].assume_init() }
                }
            };
            if entry > t_max {
                continue;
            }
            if count == 0 {
                quad = child as usize;
                continue 'nodes;
            }
            if let Some(t) = leaf(child, count, t_max) {
                t_max = t;
            }
        }
    }
}

/// Subtrees with at least this many items are built in parallel.
pub const PARALLEL_ITEMS: usize = 4096;

/// A binary subtree in depth-first order, its indices (second children, first items) relative
/// to its own lists.
struct Subtree {
    nodes: Vec<Node>,
    items: Vec<u32>,
}

impl Subtree {
    fn build(work: &mut [BuildItem], depth: usize) -> Self {
        let mut tree = Self {
            nodes: Vec::with_capacity(work.len()),
            items: Vec::with_capacity(work.len()),
        };
        tree.build_node(work, depth);
        tree
    }

    /// Appends the node for `work` and its descendants; returns its index.
    fn build_node(&mut self, work: &mut [BuildItem], depth: usize) -> usize {
        let bounds = work.iter().fold(Box32::EMPTY, |b, w| b.union(w.bounds));
        let node_index = self.nodes.len();
        self.nodes.push(Node {
            bounds: [bounds.lo.to_array(), bounds.hi.to_array()],
            offset: 0,
            count: 0,
        });
        let split = if work.len() <= MAX_LEAF {
            None
        } else if depth >= MEDIAN_DEPTH {
            Some(median_split(work))
        } else {
            best_split(work, &bounds)
        };
        match split {
            None => {
                self.nodes[node_index].offset = self.items.len() as u32;
                self.nodes[node_index].count = work.len() as u32;
                self.items.extend(work.iter().map(|w| w.id));
            }
            Some(mid) if work.len() >= PARALLEL_ITEMS => {
                let (left, right) = work.split_at_mut(mid);
                let (left, right) = rayon::join(|| Self::build(left, depth + 1), || Self::build(right, depth + 1));
                self.append(left);
                let second = self.nodes.len();
                self.append(right);
                self.nodes[node_index].offset = second as u32;
            }
            Some(mid) => {
                let (left, right) = work.split_at_mut(mid);
                self.build_node(left, depth + 1);
                let second = self.build_node(right, depth + 1);
                self.nodes[node_index].offset = second as u32;
            }
        }
        node_index
    }

    /// Appends `other` after the current nodes and items, rebasing its indices.
    fn append(&mut self, other: Self) {
        let (node_base, item_base) = (self.nodes.len() as u32, self.items.len() as u32);
        self.nodes.extend(other.nodes.into_iter().map(|mut n| {
            n.offset += if n.count > 0 { item_base } else { node_base };
            n
        }));
        self.items.extend(other.items);
    }
}

const BINS: usize = 16;
const MAX_LEAF: usize = 2;
/// Below this depth nodes split at the median, so the tree is at most `MEDIAN_DEPTH + log₂ n`
/// deep (under the 128 levels `QUAD_STACK` is sized for) for any `n < 2³²`.
const MEDIAN_DEPTH: usize = 28;

struct BuildItem {
    /// The item's bounds rounded outward to f32 (as its leaf's node will store them).
    bounds: Box32,
    centroid: Vec3,
    id: u32,
}

/// An f32 box, for the build: half the memory traffic of [`Aabb`], and unions of outward-rounded
/// boxes are exactly the outward rounding of the f64 unions (rounding is monotone).
#[derive(Clone, Copy, Debug)]
struct Box32 {
    lo: Vec3,
    hi: Vec3,
}

impl Box32 {
    const EMPTY: Self = Self {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    fn outward(b: &Aabb) -> Self {
        Self {
            lo: Vec3::new(round_down(b.min.x), round_down(b.min.y), round_down(b.min.z)),
            hi: Vec3::new(round_up(b.max.x), round_up(b.max.y), round_up(b.max.z)),
        }
    }

    #[inline]
    fn union(self, other: Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    #[inline]
    fn including(self, p: Vec3) -> Self {
        Self {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    /// Half the surface area (in f64: an extent of 10³⁸ squared stays finite).
    fn half_area(&self) -> f64 {
        let e = (self.hi - self.lo).as_dvec3().max(glam::DVec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// Per-ray data for the f32 slab tests, conservative with respect to the f64 ray.
///
/// The origin is rounded to f32 with error `δ ≤ ½ ulp` per component, which is the same as
/// testing the f64 ray against the box grown by `δ`: each axis's interval is widened by
/// `|δ|·|1/d|`. Rounding of the subtraction, the reciprocal, the direction and the product is
/// covered by enlarging exits by `1 + 2γ₅` (f32). A zero direction component gets a reciprocal
/// of ±10³⁰ instead of ±∞, so an origin on a slab plane gives 0 rather than `0·∞ = NaN` and the
/// axis constrains nothing unless the origin lies outside the slab.
struct SlabRay {
    origin: Vec3A,
    inv: Vec3A,
    pad: Vec3A,
}

const EXIT_PAD: f32 = 1.0 + 2.0 * (5.0 * f32::EPSILON * 0.5) / (1.0 - 5.0 * f32::EPSILON * 0.5);

impl SlabRay {
    #[inline]
    fn new(ray: &Ray) -> Self {
        let origin = ray.origin.as_vec3a();
        let error = (ray.origin - origin.as_dvec3()).abs().as_vec3a();
        let inv = Vec3A::from_array(ray.dir.to_array().map(|d| {
            if d == 0.0 {
                1e30f32.copysign(d as f32)
            } else {
                (1.0 / d) as f32
            }
        }));
        // one more f32 ulp of the origin keeps the pad itself conservative
        let pad = (error + origin.abs() * f32::EPSILON) * inv.abs();
        Self { origin, inv, pad }
    }

    /// Whether the f32 slab arithmetic is meaningful for this ray: origin, reciprocals and pads
    /// finite, and the origin well inside f32 range (so that `box − origin` cannot overflow).
    #[inline]
    fn is_representable(&self) -> bool {
        self.origin.abs().max_element() <= 1e37 && self.inv.is_finite() && self.pad.is_finite()
    }

    /// Entry distances into the four boxes of `quad` within `[t0, t1]`: [`SlabRay::entry`]'s
    /// arithmetic, four boxes per SSE operation.
    #[inline(always)]
    fn entry4(&self, quad: &Quad, t0: f32, t1: f32) -> (u32, [f32; 4]) {
        let mut near = Vec4::splat(t0);
        let mut far = Vec4::splat(t1);
        for axis in 0..3 {
            let o = Vec4::splat(self.origin[axis]);
            let inv = Vec4::splat(self.inv[axis]);
            let pad = Vec4::splat(self.pad[axis]);
            let a = (Vec4::from_array(quad.lo[axis]) - o) * inv;
            let b = (Vec4::from_array(quad.hi[axis]) - o) * inv;
            near = near.max(a.min(b) - pad);
            far = far.min(a.max(b) * EXIT_PAD + pad);
        }
        (near.cmple(far).bitmask(), near.to_array())
    }

    /// Entry distance into the node within `[t0, t1]`, or `None`.
    #[inline(always)]
    #[cfg(test)]
    fn entry(&self, node: &Node, t0: f32, t1: f32) -> Option<f32> {
        let lo = (Vec3A::from_array(node.bounds[0]) - self.origin) * self.inv;
        let hi = (Vec3A::from_array(node.bounds[1]) - self.origin) * self.inv;
        let near = lo.min(hi) - self.pad;
        let far = lo.max(hi) * EXIT_PAD + self.pad;
        let near = near.max_element().max(t0);
        let far = far.min_element().min(t1);
        (near <= far).then_some(near)
    }
}

impl Bvh {
    /// Builds over items `(bounds, id)` (all bounds finite); traversal reports the ids.
    ///
    /// Subtrees of at least [`PARALLEL_ITEMS`] items are built in parallel (rayon), each into
    /// its own node and item lists, which are then appended with their indices rebased: the
    /// tree is the one the sequential build makes, bit for bit.
    #[must_use]
    pub fn build(items: &[(Aabb, u32)]) -> Self {
        let mut work: Vec<BuildItem> = items
            .iter()
            .map(|(b, id)| {
                let bounds = Box32::outward(b);
                BuildItem {
                    bounds,
                    centroid: 0.5 * bounds.lo + 0.5 * bounds.hi,
                    id: *id,
                }
            })
            .collect();
        let mut bvh = Self::default();
        if !work.is_empty() {
            let tree = Subtree::build(&mut work, 0);
            drop(work);
            bvh.nodes = tree.nodes;
            bvh.items = tree.items;
            bvh.node_count = bvh.nodes.len();
            bvh.quads.reserve(items.len() / 2 + 1);
            let children = bvh.collapse(0);
            bvh.flatten_quad(&children);
            bvh.quads.shrink_to_fit();
            bvh.nodes = Vec::new();
        }
        bvh
    }

    fn half_area(&self, node: usize) -> f32 {
        let [lo, hi] = self.nodes[node].bounds;
        let e = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    /// Up to four nodes standing for `node` in the 4-wide tree: its children, with the inner
    /// one of largest surface area replaced by its own two children while fewer than four (a
    /// leaf stands for itself).
    fn collapse(&self, node: usize) -> Vec<usize> {
        if self.nodes[node].count > 0 {
            return vec![node];
        }
        let mut out = vec![node + 1, self.nodes[node].offset as usize];
        while out.len() < 4 {
            let widest = out
                .iter()
                .enumerate()
                .filter(|(_, &n)| self.nodes[n].count == 0)
                .max_by(|a, b| self.half_area(*a.1).total_cmp(&self.half_area(*b.1)));
            let Some((i, &n)) = widest else { break };
            out[i] = n + 1;
            out.push(self.nodes[n].offset as usize);
        }
        out
    }

    fn flatten_quad(&mut self, children: &[usize]) -> u32 {
        let index = self.quads.len();
        self.quads.push(Quad::default());
        let mut quad = Quad {
            len: children.len() as u32,
            ..Quad::default()
        };
        for (slot, &child) in children.iter().enumerate() {
            let node = self.nodes[child];
            for axis in 0..3 {
                quad.lo[axis][slot] = node.bounds[0][axis];
                quad.hi[axis][slot] = node.bounds[1][axis];
            }
            if node.count > 0 {
                quad.child[slot] = node.offset;
                quad.count[slot] = node.count;
            } else {
                let grandchildren = self.collapse(child);
                quad.child[slot] = self.flatten_quad(&grandchildren);
            }
        }
        self.quads[index] = quad;
        index as u32
    }

    /// Number of nodes of the binary tree it was built as (0 for an empty hierarchy).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.node_count
    }

    /// Closest-hit traversal: calls `test(id, range)` for items whose node the ray enters
    /// within `range`; `test` returns the hit parameter if it found one inside the range, which
    /// then becomes the new `range.max`. Returns the id of the item that set the final
    /// `range.max`. Walks the 4-wide nodes, entered children pushed farthest first.
    ///
    /// The f32 slab tests need the origin within f32 range and finite reciprocals of the
    /// direction; a ray beyond that (an origin past `10³⁷`, a direction component below
    /// `10⁻³⁸` but not zero) tests every item instead (slow, exact). Boxes beyond f32 range are
    /// stored as infinite and need nothing special.
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        mut range: Interval,
        mut test: impl FnMut(u32, Interval) -> Option<f64>,
    ) -> Option<u32> {
        let slab = SlabRay::new(ray);
        let mut best = None;
        if !slab.is_representable() {
            for &id in &self.items {
                if let Some(t) = test(id, range) {
                    range.max = t;
                    best = Some(id);
                }
            }
            return best;
        }
        let t0 = round_down(range.min);
        traverse_quads(
            &self.quads,
            round_up(range.max),
            |q, t1| slab.entry4(q, t0, t1),
            |first, count, _| {
                let mut found = None;
                for &id in &self.items[first as usize..(first + count) as usize] {
                    if let Some(t) = test(id, range) {
                        range.max = t;
                        best = Some(id);
                        found = Some(round_up(t));
                    }
                }
                found
            },
        );
        best
    }
}

/// Splits `work` at its median centroid along the centroids' longest axis.
fn median_split(work: &mut [BuildItem]) -> usize {
    let centroids = work.iter().fold(Box32::EMPTY, |b, w| b.including(w.centroid));
    let extent = centroids.hi - centroids.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = work.len() / 2;
    work.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    mid
}

/// Index at which to split `work` (sorted in place), or `None` for a leaf.
///
/// One pass over the items bins them on all three axes at once (each item's bounds and
/// centroid read once per level), then each axis's 15 split planes are swept.
fn best_split(work: &mut [BuildItem], bounds: &Box32) -> Option<usize> {
    let centroid_bounds = work.iter().fold(Box32::EMPTY, |b, w| b.including(w.centroid));
    let extent = centroid_bounds.hi - centroid_bounds.lo;
    let leaf_cost = work.len() as f64;
    let parent_area = bounds.half_area().max(f64::MIN_POSITIVE);
    let scale: [f32; 3] = std::array::from_fn(|axis| {
        if extent[axis] > 0.0 {
            BINS as f32 / extent[axis]
        } else {
            0.0
        }
    });
    let lo = centroid_bounds.lo;
    let bin_of = |axis: usize, c: f32| (((c - lo[axis]) * scale[axis]) as usize).min(BINS - 1);
    let mut bin_bounds = [[Box32::EMPTY; BINS]; 3];
    let mut bin_counts = [[0usize; BINS]; 3];
    for w in work.iter() {
        for axis in 0..3 {
            let bin = bin_of(axis, w.centroid[axis]);
            bin_counts[axis][bin] += 1;
            bin_bounds[axis][bin] = bin_bounds[axis][bin].union(w.bounds);
        }
    }
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins left of split)
    for axis in 0..3 {
        if !(extent[axis] > 0.0) {
            continue;
        }
        let (bin_bounds, bin_counts) = (&bin_bounds[axis], &bin_counts[axis]);
        // sweep from the right, then from the left
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut count) = (Box32::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(bin_bounds[i]);
            count += bin_counts[i];
            right_area[i] = acc.half_area();
            right_count[i] = count;
        }
        let (mut acc, mut count) = (Box32::EMPTY, 0);
        for split in 1..BINS {
            acc = acc.union(bin_bounds[split - 1]);
            count += bin_counts[split - 1];
            if count == 0 || right_count[split] == 0 {
                continue;
            }
            let cost =
                1.0 + (acc.half_area() * count as f64 + right_area[split] * right_count[split] as f64) / parent_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    if cost >= leaf_cost && work.len() <= 8 {
        return None;
    }
    let mut mid = 0;
    for i in 0..work.len() {
        if bin_of(axis, work[i].centroid[axis]) < split {
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

    /// The 4-wide slab test gives exactly the single-box test's answer for each of its boxes.
    #[test]
    fn four_wide_entry_equals_single_entries() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for _ in 0..20_000 {
            let mut quad = Quad {
                len: 4,
                ..Quad::default()
            };
            let mut nodes = Vec::new();
            for slot in 0..4 {
                let c = DVec3::new(
                    rng.random_range(-9.0..9.0),
                    rng.random_range(-9.0..9.0),
                    rng.random_range(-9.0..9.0),
                );
                let h = DVec3::new(
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                );
                let node = Node::new(&Aabb::new(c - h, c + h));
                for axis in 0..3 {
                    quad.lo[axis][slot] = node.bounds[0][axis];
                    quad.hi[axis][slot] = node.bounds[1][axis];
                }
                nodes.push(node);
            }
            let mut d = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if rng.random_bool(0.2) {
                d.y = 0.0;
            }
            let o = DVec3::new(
                rng.random_range(-1e3..1e3),
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
            );
            let slab = SlabRay::new(&Ray::new(o, d));
            let (t0, t1) = (rng.random_range(0.0..1.0), rng.random_range(1.0..2e3));
            let single: Vec<_> = nodes.iter().map(|n| slab.entry(n, t0, t1)).collect();
            let (hits, near) = slab.entry4(&quad, t0, t1);
            let four: Vec<_> = (0..4).map(|i| (hits & (1 << i) != 0).then_some(near[i])).collect();
            assert_eq!(four, single);
        }
    }

    /// The BVH finds the same closest box as testing every box, on random boxes and rays.
    #[test]
    fn closest_hit_equals_brute_force() {
        closest_hit_equals_brute_force_with(500, 7, -20.0);
    }

    /// Above `PARALLEL_ITEMS` the subtrees are built in parallel and appended; origins beyond
    /// f32 range take the linear scan.
    #[test]
    fn parallel_build_and_far_origins_equal_brute_force() {
        closest_hit_equals_brute_force_with(5 * PARALLEL_ITEMS, 8, -20.0);
        closest_hit_equals_brute_force_with(600, 9, -1e39);
    }

    fn closest_hit_equals_brute_force_with(count: usize, seed: u64, origin_z: f64) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let boxes: Vec<Aabb> = (0..count)
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
        let items: Vec<(Aabb, u32)> = boxes.iter().enumerate().map(|(i, b)| (*b, i as u32)).collect();
        let bvh = Bvh::build(&items);
        let entry = |b: &Aabb, ray: &Ray, range: Interval| b.clip(ray, range).map(|r| r.min);
        for _ in 0..5000 {
            let o = DVec3::new(rng.random_range(-15.0..15.0), rng.random_range(-15.0..15.0), origin_z);
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
