//! The one hierarchy builder, shared by the scene (over objects) and by meshes (over
//! triangles): parallel binned-SAH build of a binary tree over f32 item boxes, collapsed into
//! 4-wide SoA nodes ([`Quad`]) for ordered closest-hit traversal, four child boxes per SSE slab
//! test; meshes also keep the binary tree as 32-byte f32 nodes in sibling pairs (for
//! nearest-point queries). Items are referred to by their position in leaf order.
//!
//! Layout. Every interior node refers to a [`Pair`] holding its two children; a node is
//! `lo[3], first, hi[3], count` (32 bytes): a leaf has `count > 0` triangles starting at `first`
//! in the leaf-ordered triangle array, an interior node has `count = 0` and its children in
//! `pairs[first]`. The root is kept apart. Pairs are laid out depth-first, so a pair's first
//! child's subtree follows it.
//!
//! Build. Item boxes and centroids in f32; each split bins centroids into 32 bins per axis (8
//! for nodes of at most 64 items)
//! (binning itself in parallel for large nodes), sweeps the SAH (traversal step cost 1, triangle
//! cost 1), and partitions in place. Subtrees of more than [`PARALLEL_MIN`] triangles are built with
//! `rayon::join`. A node becomes a leaf when SAH prefers it and it holds at most the caller's `max_leaf`
//! items; below depth [`MEDIAN_DEPTH`] (or when all centroids coincide) it is split at the
//! median instead, which bounds the depth to `MEDIAN_DEPTH + 32` and the traversal stack.
//!
//! Traversal. Slab tests in f32 against the mesh's own f32 ray (the one the triangle test uses),
//! with exits enlarged by `1 + 2γ₃` as in Woop, Benthin and Wald (2013), so that the box test
//! never rejects a ray the watertight triangle test would hit. The nearer child is visited
//! first; the farther one is pushed with its entry distance and skipped when popped if the
//! closest hit found meanwhile is nearer.

use super::{traverse_quads, Quad};
use glam::{Vec3A, Vec4};
use rayon::prelude::*;

/// SAH cost of a traversal step (testing a pair of child boxes) relative to one triangle test.
const TRAVERSAL_COST: f32 = 1.0;
/// Centroid bins per axis for large nodes.
const BINS: usize = 32;
/// Centroid bins per axis for nodes of at most [`FEW_ITEMS`] items (fewer bins to clear and
/// sweep where there are few centroids to tell apart).
const FEW_BINS: usize = 8;
/// Nodes up to this many items bin into [`FEW_BINS`].
const FEW_ITEMS: usize = 64;
/// Subtrees with more triangles than this are built in parallel.
pub(crate) const PARALLEL_MIN: usize = 4096;
/// Nodes with more triangles than this bin in parallel.
const PARALLEL_BINNING_MIN: usize = 65536;
/// From this depth on, nodes are split at the median.
const MEDIAN_DEPTH: usize = 64;

/// `1 + 2γ₃` in f32 (γₙ = nε/(1 − nε), ε = 2⁻²⁴).
pub(crate) const EXIT_PAD: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// A node (see the module docs).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(crate) struct Node {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

/// The two children of an interior node, in one cache line.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Pair(pub [Node; 2]);

/// An f32 box.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bb {
    pub lo: Vec3A,
    pub hi: Vec3A,
}

impl Bb {
    pub const EMPTY: Self = Self {
        lo: Vec3A::splat(f32::INFINITY),
        hi: Vec3A::splat(f32::NEG_INFINITY),
    };

    #[inline]
    fn union(self, o: Self) -> Self {
        Self {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    #[inline]
    fn include(self, p: Vec3A) -> Self {
        Self {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    /// Half the surface area (enough for SAH ratios); 0 for an empty box.
    #[inline]
    fn half_area(self) -> f32 {
        let e = (self.hi - self.lo).max(Vec3A::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// One item (triangle or object) during the build: its f32 box and its id, in 28 bytes (the
/// build permutes them in place, so a million scene objects cost 28 MB here). The box's centre,
/// which the build bins, is computed where it is needed ([`BuildItem::centroid`]).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(crate) struct BuildItem {
    lo: [f32; 3],
    /// The caller's id (a triangle's or object's index).
    pub id: u32,
    hi: [f32; 3],
}

impl BuildItem {
    /// The item `id` with box `bounds`.
    #[inline]
    pub fn new(bounds: Bb, id: u32) -> Self {
        Self {
            lo: bounds.lo.to_array(),
            id,
            hi: bounds.hi.to_array(),
        }
    }

    /// Its box.
    #[inline]
    pub fn bounds(&self) -> Bb {
        Bb {
            lo: Vec3A::from_array(self.lo),
            hi: Vec3A::from_array(self.hi),
        }
    }

    /// Its box's centre, `lo/2 + hi/2` (finite for any finite box, where `(lo + hi)/2` may
    /// overflow).
    #[inline]
    pub fn centroid(&self) -> Vec3A {
        0.5 * Vec3A::from_array(self.lo) + 0.5 * Vec3A::from_array(self.hi)
    }

    /// Component `axis` of [`BuildItem::centroid`] (the same f32 operations).
    #[inline]
    fn centroid_on(&self, axis: usize) -> f32 {
        0.5 * self.lo[axis] + 0.5 * self.hi[axis]
    }
}

/// A node of the binary tree during the build: 40 bytes, its box as f32 arrays (not the 16-byte
/// aligned [`Bb`]), so that an inner node's pair of children is an 80-byte allocation (a million
/// scene objects: about a million of them).
enum BuildNode {
    Leaf {
        bounds: NodeBox,
        start: u32,
        count: u32,
    },
    Inner {
        bounds: NodeBox,
        children: Box<[BuildNode; 2]>,
    },
}

/// A box stored in a [`BuildNode`].
#[derive(Clone, Copy, Debug)]
struct NodeBox {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl From<Bb> for NodeBox {
    fn from(b: Bb) -> Self {
        Self {
            lo: b.lo.to_array(),
            hi: b.hi.to_array(),
        }
    }
}

impl NodeBox {
    fn node(self, first: u32, count: u32) -> Node {
        Node {
            lo: self.lo,
            first,
            hi: self.hi,
            count,
        }
    }

    fn half_area(self) -> f32 {
        Bb {
            lo: Vec3A::from_array(self.lo),
            hi: Vec3A::from_array(self.hi),
        }
        .half_area()
    }
}

/// The hierarchy; triangles are referred to by their position in leaf order. Closest-hit
/// traversal uses the 4-wide `quads` (collapsed from the binary tree); nearest-point queries
/// use the binary `pairs`.
#[derive(Clone, Debug, Default)]
pub(crate) struct QuadBvh {
    pub root: Node,
    pub pairs: Vec<Pair>,
    quads: Vec<Quad>,
}

#[derive(Clone, Copy)]
struct Bins<const N: usize> {
    bounds: [[Bb; N]; 3],
    counts: [[u32; N]; 3],
}

impl<const N: usize> Bins<N> {
    fn empty() -> Self {
        Self {
            bounds: [[Bb::EMPTY; N]; 3],
            counts: [[0; N]; 3],
        }
    }

    fn add(&mut self, tris: &[BuildItem], lo: Vec3A, scale: Vec3A) {
        for t in tris {
            let b = ((t.centroid() - lo) * scale).min(Vec3A::splat((N - 1) as f32));
            let bounds = t.bounds();
            for axis in 0..3 {
                let i = b[axis] as usize;
                self.counts[axis][i] += 1;
                self.bounds[axis][i] = self.bounds[axis][i].union(bounds);
            }
        }
    }

    fn merge(mut self, o: Self) -> Self {
        for axis in 0..3 {
            for i in 0..N {
                self.counts[axis][i] += o.counts[axis][i];
                self.bounds[axis][i] = self.bounds[axis][i].union(o.bounds[axis][i]);
            }
        }
        self
    }
}

impl QuadBvh {
    /// Builds over `tris` (reordered in place into leaf order), with leaves of at most
    /// `max_leaf` items; with `pairs`, also keeps the binary tree for nearest-point queries.
    /// `tris` must not be empty.
    pub fn build(tris: &mut [BuildItem], max_leaf: usize, pairs: bool) -> Self {
        let tree = build_tree(tris, max_leaf);
        Self::flatten_tree(&tree, pairs)
    }

    /// [`QuadBvh::build`] without `pairs`, taking the items and giving their ids in leaf order:
    /// the items are dropped as soon as the binary tree is built, before the 4-wide nodes are
    /// written (a million scene objects: 28 MB less at the peak).
    pub fn build_ids(mut tris: Vec<BuildItem>, max_leaf: usize) -> (Self, Vec<u32>) {
        let tree = build_tree(&mut tris, max_leaf);
        let ids = tris.iter().map(|t| t.id).collect();
        drop(tris);
        (Self::flatten_tree(&tree, false), ids)
    }

    /// The nodes of `tree`, with `pairs` also the binary ones.
    fn flatten_tree(tree: &BuildNode, pairs: bool) -> Self {
        // exact capacities: a node array is never grown or shrunk, which would copy it (their
        // 64-byte alignment rules out an in-place `realloc`): 120 MB at the peak for 10⁶ objects
        let (top, len) = collapse(tree);
        let mut bvh = Self {
            root: Node::default(),
            pairs: Vec::with_capacity(if pairs { inner_count(tree) } else { 0 }),
            quads: Vec::with_capacity(quad_count(&top[..len])),
        };
        bvh.flatten_quad(&top[..len]);
        bvh.root = match tree {
            BuildNode::Leaf { bounds, start, count } => bounds.node(*start, *count),
            BuildNode::Inner { bounds, children } if pairs => {
                let first = bvh.flatten(children);
                bounds.node(first, 0)
            }
            BuildNode::Inner { bounds, .. } => bounds.node(0, 0),
        };
        debug_assert_eq!(bvh.quads.len(), bvh.quads.capacity());
        debug_assert_eq!(bvh.pairs.len(), bvh.pairs.capacity());
        bvh
    }

    fn flatten_quad(&mut self, children: &[&BuildNode]) -> u32 {
        let index = self.quads.len();
        self.quads.push(Quad::default());
        let mut quad = Quad {
            len: children.len() as u32,
            ..Quad::default()
        };
        for (slot, child) in children.iter().enumerate() {
            let (bounds, first, count) = match child {
                BuildNode::Leaf { bounds, start, count } => (bounds, *start, *count),
                BuildNode::Inner { bounds, .. } => {
                    let (nodes, len) = collapse(child);
                    (bounds, self.flatten_quad(&nodes[..len]), 0)
                }
            };
            for axis in 0..3 {
                quad.lo[axis][slot] = bounds.lo[axis];
                quad.hi[axis][slot] = bounds.hi[axis];
            }
            quad.child[slot] = first;
            quad.count[slot] = count;
        }
        self.quads[index] = quad;
        index as u32
    }

    fn flatten(&mut self, children: &[BuildNode; 2]) -> u32 {
        let index = self.pairs.len();
        self.pairs.push(Pair::default());
        for (slot, child) in children.iter().enumerate() {
            let node = match child {
                BuildNode::Leaf { bounds, start, count } => bounds.node(*start, *count),
                BuildNode::Inner { bounds, children } => {
                    let first = self.flatten(children);
                    bounds.node(first, 0)
                }
            };
            self.pairs[index].0[slot] = node;
        }
        index as u32
    }

    /// The 4-wide nodes, root first.
    pub fn quads(&self) -> &[Quad] {
        &self.quads
    }

    /// Number of 4-wide nodes.
    pub fn quad_count(&self) -> usize {
        self.quads.len()
    }

    /// Bytes held by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.pairs.capacity() * std::mem::size_of::<Pair>()
            + self.quads.capacity() * std::mem::size_of::<Quad>()
            + std::mem::size_of::<Node>()
    }

    /// Closest-hit traversal over the 4-wide nodes: `leaf(first, count, t_max)` tests a leaf's
    /// triangles and returns the new, smaller `t_max` if it found a hit. `t_min`/`t_max` bound
    /// the search. The children a node's ray enters are pushed farthest first, so the nearest is
    /// visited next; an entry popped after the closest hit moved nearer than it is skipped.
    #[inline]
    pub fn traverse(&self, ray: &SlabRay, t_min: f32, t_max: f32, leaf: impl FnMut(u32, u32, f32) -> Option<f32>) {
        traverse_quads(&self.quads, t_max, |q, t1| ray.entry4(q, t_min, t1), leaf);
    }

    /// Depth-first visit for nearest-point queries: `visit_box(node) -> lower bound` (or `None` to
    /// prune), `leaf(first, count)`. Children are visited nearer bound first.
    pub fn nearest(&self, mut lower_bound: impl FnMut(&Node) -> Option<f64>, mut leaf: impl FnMut(u32, u32)) {
        if lower_bound(&self.root).is_none() {
            return;
        }
        let mut stack: Vec<(&Node, f64)> = vec![(&self.root, 0.0)];
        while let Some((node, _)) = stack.pop() {
            if lower_bound(node).is_none() {
                continue;
            }
            if node.count > 0 {
                leaf(node.first, node.count);
                continue;
            }
            let pair = &self.pairs[node.first as usize].0;
            let a = lower_bound(&pair[0]).map(|d| (&pair[0], d));
            let b = lower_bound(&pair[1]).map(|d| (&pair[1], d));
            match (a, b) {
                (Some(a), Some(b)) => {
                    if a.1 <= b.1 {
                        stack.push(b);
                        stack.push(a);
                    } else {
                        stack.push(a);
                        stack.push(b);
                    }
                }
                (Some(x), None) | (None, Some(x)) => stack.push(x),
                (None, None) => {}
            }
        }
    }
}

/// Per-ray data for the slab tests: the f32 origin and clamped reciprocal direction.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    pub origin: Vec3A,
    pub inv: Vec3A,
}

impl SlabRay {
    /// From the f32 ray. Reciprocals are clamped to ±`f32::MAX`, so a zero direction component
    /// gives `0·MAX = 0` rather than `0·∞ = NaN` on a slab plane through the origin.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        let inv = Vec3A::ONE / dir;
        Self {
            origin,
            inv: inv.clamp(Vec3A::splat(-f32::MAX), Vec3A::splat(f32::MAX)),
        }
    }

    /// Entry distances into the four boxes of `quad` within `[t0, t1]` (per axis `(lo − o)·inv` and
    /// `(hi − o)·inv`, nearest exit enlarged by `1 + 2γ₃`; four boxes per SSE operation).
    #[inline(always)]
    pub(crate) fn entry4(&self, quad: &Quad, t0: f32, t1: f32) -> (u32, [f32; 4]) {
        let mut near = Vec4::splat(t0);
        let mut far = Vec4::splat(f32::INFINITY);
        for axis in 0..3 {
            let o = Vec4::splat(self.origin[axis]);
            let inv = Vec4::splat(self.inv[axis]);
            let a = (Vec4::from_array(quad.lo[axis]) - o) * inv;
            let b = (Vec4::from_array(quad.hi[axis]) - o) * inv;
            near = near.max(a.min(b));
            far = far.min(a.max(b));
        }
        let far = (far * EXIT_PAD).min(Vec4::splat(t1));
        (near.cmple(far).bitmask(), near.to_array())
    }
}

/// Up to four nodes standing for `node` in a 4-wide tree: its children, with the inner one of
/// largest surface area replaced by its own two children while fewer than four (a leaf root is
/// its own single child).
/// The number of quads [`QuadBvh::flatten_quad`] writes for a quad of `children`.
fn quad_count(children: &[&BuildNode]) -> usize {
    1 + children
        .iter()
        .filter(|child| matches!(child, BuildNode::Inner { .. }))
        .map(|child| {
            let (nodes, len) = collapse(child);
            quad_count(&nodes[..len])
        })
        .sum::<usize>()
}

/// The number of inner nodes in the tree under `node`, `node` included: the pairs
/// [`QuadBvh::flatten`] writes for it (one per inner node).
fn inner_count(node: &BuildNode) -> usize {
    match node {
        BuildNode::Leaf { .. } => 0,
        BuildNode::Inner { children, .. } => 1 + inner_count(&children[0]) + inner_count(&children[1]),
    }
}

fn collapse(node: &BuildNode) -> ([&BuildNode; 4], usize) {
    let BuildNode::Inner { children, .. } = node else {
        return ([node; 4], 1);
    };
    // `out[..len]` are the nodes; the rest is filler
    let mut out = [&children[0], &children[1], node, node];
    let mut len = 2;
    while len < 4 {
        let widest = out[..len]
            .iter()
            .enumerate()
            .filter_map(|(i, n)| match n {
                BuildNode::Inner { bounds, .. } => Some((i, bounds.half_area())),
                BuildNode::Leaf { .. } => None,
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = widest else { break };
        let BuildNode::Inner { children, .. } = out[i] else {
            unreachable!("chosen among inner nodes")
        };
        out[i] = &children[0];
        out[len] = &children[1];
        len += 1;
    }
    (out, len)
}

/// The binary tree over `tris` (reordered in place into leaf order); `tris` must not be empty.
fn build_tree(tris: &mut [BuildItem], max_leaf: usize) -> BuildNode {
    let bounds = tris.par_iter().map(BuildItem::bounds).reduce(|| Bb::EMPTY, Bb::union);
    build_node(tris, 0, bounds, 0, max_leaf)
}

fn build_node(tris: &mut [BuildItem], start: u32, bounds: Bb, depth: usize, max_leaf: usize) -> BuildNode {
    let n = tris.len();
    if n == 1 {
        return BuildNode::Leaf {
            bounds: bounds.into(),
            start,
            count: 1,
        };
    }
    let centroids = if n > PARALLEL_BINNING_MIN {
        tris.par_chunks(16384)
            .map(|c| c.iter().fold(Bb::EMPTY, |b, t| b.include(t.centroid())))
            .reduce(|| Bb::EMPTY, Bb::union)
    } else {
        tris.iter().fold(Bb::EMPTY, |b, t| b.include(t.centroid()))
    };
    let extent = centroids.hi - centroids.lo;
    let split = if depth >= MEDIAN_DEPTH || extent.max_element() <= 0.0 {
        None
    } else {
        sah_split(tris, bounds, centroids, max_leaf)
    };
    let mid = match split {
        Some(Split::Leaf) => {
            return BuildNode::Leaf {
                bounds: bounds.into(),
                start,
                count: n as u32,
            }
        }
        Some(Split::At(mid)) => mid,
        None => {
            // median along the widest centroid axis (any order when all centroids coincide)
            let axis = extent.max_position();
            let mid = n / 2;
            tris.select_nth_unstable_by(mid, |a, b| a.centroid_on(axis).total_cmp(&b.centroid_on(axis)));
            mid
        }
    };
    let (left, right) = tris.split_at_mut(mid);
    let lb = left.iter().fold(Bb::EMPTY, |b, t| b.union(t.bounds()));
    let rb = right.iter().fold(Bb::EMPTY, |b, t| b.union(t.bounds()));
    let rstart = start + mid as u32;
    let (l, r) = if n > PARALLEL_MIN {
        rayon::join(
            || build_node(left, start, lb, depth + 1, max_leaf),
            || build_node(right, rstart, rb, depth + 1, max_leaf),
        )
    } else {
        (
            build_node(left, start, lb, depth + 1, max_leaf),
            build_node(right, rstart, rb, depth + 1, max_leaf),
        )
    };
    BuildNode::Inner {
        bounds: bounds.into(),
        children: Box::new([l, r]),
    }
}

enum Split {
    Leaf,
    At(usize),
}

fn sah_split(tris: &mut [BuildItem], bounds: Bb, centroids: Bb, max_leaf: usize) -> Option<Split> {
    if tris.len() <= FEW_ITEMS {
        sah_split_binned::<FEW_BINS>(tris, bounds, centroids, max_leaf)
    } else {
        sah_split_binned::<BINS>(tris, bounds, centroids, max_leaf)
    }
}

/// The SAH split over `N` centroid bins per axis (see the module docs).
fn sah_split_binned<const N: usize>(
    tris: &mut [BuildItem],
    bounds: Bb,
    centroids: Bb,
    max_leaf: usize,
) -> Option<Split> {
    let n = tris.len();
    let extent = centroids.hi - centroids.lo;
    // axes with zero extent get scale 0: everything in bin 0, never a valid split there
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(N as f32 * (1.0 - 1e-6)) / extent,
        Vec3A::ZERO,
    );
    let bins = if n > PARALLEL_BINNING_MIN {
        tris.par_chunks(16384)
            .map(|c| {
                let mut b = Bins::<N>::empty();
                b.add(c, centroids.lo, scale);
                b
            })
            .reduce(Bins::<N>::empty, Bins::merge)
    } else {
        let mut b = Bins::<N>::empty();
        b.add(tris, centroids.lo, scale);
        b
    };
    let parent = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if scale[axis] == 0.0 {
            continue;
        }
        let mut right_area = [0f32; N];
        let mut right_count = [0u32; N];
        let (mut acc, mut count) = (Bb::EMPTY, 0);
        for i in (1..N).rev() {
            acc = acc.union(bins.bounds[axis][i]);
            count += bins.counts[axis][i];
            right_area[i] = acc.half_area();
            right_count[i] = count;
        }
        let (mut acc, mut count) = (Bb::EMPTY, 0);
        for split in 1..N {
            acc = acc.union(bins.bounds[axis][split - 1]);
            count += bins.counts[axis][split - 1];
            if count == 0 || right_count[split] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.half_area() * count as f32 + right_area[split] * right_count[split] as f32) / parent;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    if n <= max_leaf && cost >= n as f32 {
        return Some(Split::Leaf);
    }
    let (lo, s) = (centroids.lo[axis], scale[axis]);
    let bin_of = |t: &BuildItem| (((t.centroid_on(axis) - lo) * s) as usize).min(N - 1);
    let mut mid = 0;
    for i in 0..n {
        if bin_of(&tris[i]) < split {
            tris.swap(i, mid);
            mid += 1;
        }
    }
    (mid > 0 && mid < n).then_some(Split::At(mid))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn build_items_are_small_and_keep_box_and_centre() {
        assert_eq!(std::mem::size_of::<BuildItem>(), 28);
        assert_eq!(std::mem::size_of::<BuildNode>(), 40);
        let bounds = Bb {
            lo: Vec3A::new(-f32::MAX, 1.0, -3.5),
            hi: Vec3A::new(f32::MAX, f32::MAX, 0.25),
        };
        let item = BuildItem::new(bounds, 7);
        assert_eq!(item.id, 7);
        assert_eq!((item.bounds().lo, item.bounds().hi), (bounds.lo, bounds.hi));
        // lo/2 + hi/2 in f64 (exact here), where (lo + hi)/2 would overflow to infinity
        let expected = [0.0, 0.5 + f64::from(f32::MAX) / 2.0, -1.625];
        for (axis, expected) in expected.into_iter().enumerate() {
            assert_eq!(f64::from(item.centroid()[axis]), expected as f32 as f64, "axis {axis}");
            assert_eq!(item.centroid_on(axis).to_bits(), item.centroid()[axis].to_bits());
        }
    }

    /// The node arrays are allocated at their exact final size (never grown or shrunk, which
    /// copies them), for leaf roots and trees of every shape.
    #[test]
    fn node_arrays_are_allocated_exactly() {
        let mut state = 12345u64;
        let mut random = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for n in [1, 2, 3, 7, 64, 65, 1000, 5000, 70_000] {
            let mut items: Vec<BuildItem> = (0..n)
                .map(|id| {
                    let lo = Vec3A::new(random(), random(), random()) * 100.0;
                    let size = Vec3A::new(random(), random(), random());
                    BuildItem::new(Bb { lo, hi: lo + size }, id)
                })
                .collect();
            for (max_leaf, pairs) in [(2, false), (6, true)] {
                let bvh = QuadBvh::build(&mut items, max_leaf, pairs);
                assert_eq!(bvh.quads.len(), bvh.quads.capacity(), "{n} items");
                assert_eq!(bvh.pairs.len(), bvh.pairs.capacity(), "{n} items");
                assert!(!bvh.quads.is_empty());
                assert_eq!(bvh.pairs.is_empty(), !pairs || bvh.root.count > 0, "{n} items");
            }
        }
    }
}
