//! The one hierarchy builder, shared by the scene (over objects) and by meshes (over
//! triangles): parallel binned-SAH build of 4-wide SoA nodes ([`Quad`]) over f32 item boxes,
//! for ordered closest-hit traversal (four child boxes per SSE slab test) and for nearest-point
//! queries. Items are referred to by their position in leaf order.
//!
//! Layout. A quad's slot `s` is a leaf when `count[s] > 0` (items `child[s]..child[s] +
//! count[s]` of the leaf order) and otherwise refers to the quad `child[s]`; quads are laid out
//! depth first from the root `quads[0]`, and the root's box is kept apart ([`Node`]).
//!
//! Build. Item boxes and centroids in f32; each split bins centroids into 32 bins per axis (8
//! for nodes of at most 64 items)
//! (binning itself in parallel for large nodes), sweeps the SAH (traversal step cost 1; leaves
//! cost what the caller's [`Leaves`] say: one per item, or one price for a whole leaf whose
//! items are tested together, a split's sides priced as that many full leaves), and partitions
//! in place; the children's boxes are the unions of their bins' boxes and their centre boxes
//! are gathered while partitioning, so a node costs two passes over its items. A node becomes a leaf when SAH prefers it and it holds at most [`Leaves::max`]
//! items; below depth [`MEDIAN_DEPTH`] (or when all centroids coincide) it is split
//! at the median instead, which bounds the depth to `MEDIAN_DEPTH + 32` and the traversal stack.
//! The quads are written as the splits are decided, with no binary tree in between: a quad's
//! children are its node's two sides, the inner one of largest surface area replaced by its own
//! two sides while there are fewer than four (the binary SAH tree collapsed two levels at a
//! time). Subtrees of more than [`PARALLEL_MIN`] items are built with rayon, each into a range
//! of the node array as long as its bound (`items − 1` nodes), the rest of which stays unused
//! and costs no memory ([`QuadArray`]); smaller subtrees are packed depth first. So the build
//! holds the items and the nodes, nothing else (a million scene objects: 28 + 56 MB).
//!
//! Traversal. Slab tests in f32 against the mesh's own f32 ray (the one the triangle test uses),
//! with exits enlarged by `1 + 2γ₃` as in Woop, Benthin and Wald (2013), so that the box test
//! never rejects a ray the watertight triangle test would hit. The nearer child is visited
//! first; the farther one is pushed with its entry distance and skipped when popped if the
//! closest hit found meanwhile is nearer. A mesh's single rays walk its quads collapsed into
//! 8-wide nodes ([`super::oct`], [`SlabRay::entry8`]); packets walk the quads.

use super::oct::Oct;
use super::quad_array::QuadArray;
use super::{max_f32, min_f32, NodeTest, Quad, SlabsFrom};
use crate::traits::Wanted;
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
/// The largest [`Leaves::max`] a caller may ask for: a quad stores leaf sizes in 16 bits, and a
/// leaf holds at most that many items (or one, below the median-split depth).
pub(crate) const MAX_LEAF_ITEMS: usize = u16::MAX as usize;
/// From this depth on, nodes are split at the median.
const MEDIAN_DEPTH: usize = 64;

/// How a hierarchy's leaves are made: at most [`Leaves::max`] items each, and what testing one
/// costs in the SAH (in units of one item test; a traversal step costs 1).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Leaves {
    /// The most items a leaf holds.
    pub max: usize,
    /// The SAH cost of a whole leaf, whatever its size (items tested together, one SIMD pass
    /// for up to eight triangles), or `None`: one per item (items tested one by one).
    whole: Option<f32>,
}

impl Leaves {
    /// Leaves of at most `max` items tested one by one.
    pub(crate) const fn per_item(max: usize) -> Self {
        Self { max, whole: None }
    }

    /// Leaves of at most `max` items tested together at the price `cost`.
    pub(crate) const fn tested_together(max: usize, cost: f32) -> Self {
        Self { max, whole: Some(cost) }
    }

    /// The SAH cost of testing `n` items: `n` tests where items are tested one by one, else as
    /// if in full leaves (`⌈n / max⌉` of them: one leaf's price for a leaf of `n ≤ max`, a
    /// split's side priced as that many leaves).
    fn cost(self, n: u32) -> f32 {
        match self.whole {
            Some(cost) => cost * n.div_ceil(self.max as u32) as f32,
            None => n as f32,
        }
    }
}

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

    /// Its seven 4-byte words (box and id), for moving it word by word.
    #[inline(always)]
    fn words_mut(&mut self) -> &mut [u32; 7] {
        const _: () = assert!(
            std::mem::size_of::<BuildItem>() == 28 && std::mem::align_of::<BuildItem>() == 4,
            "seven 4-byte words, no padding"
        );
        // SAFETY: `repr(C)` of seven f32 and u32 fields, no padding, aligned as a u32 (checked
        // above); every bit pattern is a valid u32 and a valid f32
        unsafe { &mut *(self as *mut Self).cast::<[u32; 7]>() }
    }

    /// Component `axis` of [`BuildItem::centroid`] (the same f32 operations).
    #[inline]
    fn centroid_on(&self, axis: usize) -> f32 {
        0.5 * self.lo[axis] + 0.5 * self.hi[axis]
    }
}

/// A node whose split is decided: a leaf of `count` items from `start` (`split` is `None`), or
/// an inner node whose items are already partitioned into its two sides.
struct Decided {
    bounds: Bb,
    start: u32,
    count: u32,
    depth: usize,
    split: Option<Children>,
}

impl Decided {
    /// Its items, as positions inside the items of an ancestor starting at `ancestor_start`.
    fn range(&self, ancestor_start: u32) -> std::ops::Range<usize> {
        let first = (self.start - ancestor_start) as usize;
        first..first + self.count as usize
    }
}

/// The hierarchy; triangles are referred to by their position in leaf order. Closest-hit
/// traversal and nearest-point queries both walk the 4-wide `quads`; `root` is the box of
/// everything. Subtrees built in parallel leave unused, zero nodes after their own (see
/// [`QuadArray`]); no slot refers to those.
#[derive(Clone, Debug, Default)]
pub(crate) struct QuadBvh {
    pub root: Node,
    quads: QuadArray,
    /// The nodes in use (the others are the parallel subtrees' unused room).
    used: usize,
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

    /// Adds `tris` to the bins of their centres (`lo` and `scale` as in [`bin_of`]). Many
    /// items are added alternately to these bins and to a second set, merged at the end (the
    /// same bins: unions and sums in any order): neighbouring items (a mesh's triangles come
    /// in surface order) fall in the same bins, and each update of a bin waited for the
    /// previous one to be written. The level-8 bench mesh's load and build: 0.288 → 0.281 s
    /// (medians of 9 alternating runs).
    fn add(&mut self, tris: &[BuildItem], lo: Vec3A, scale: Vec3A) {
        if tris.len() < 4 * N {
            self.add_each(tris, lo, scale);
            return;
        }
        let mut other = Self::empty();
        let mut pairs = tris.chunks_exact(2);
        for pair in &mut pairs {
            self.add_one(&pair[0], lo, scale);
            other.add_one(&pair[1], lo, scale);
        }
        self.add_each(pairs.remainder(), lo, scale);
        *self = self.merge(other);
    }

    /// Adds `tris` one after another.
    #[inline(always)]
    fn add_each(&mut self, tris: &[BuildItem], lo: Vec3A, scale: Vec3A) {
        for t in tris {
            self.add_one(t, lo, scale);
        }
    }

    /// Adds `t` to the bins of its centre.
    #[inline(always)]
    fn add_one(&mut self, t: &BuildItem, lo: Vec3A, scale: Vec3A) {
        let b = bin_of::<N>(t.centroid(), lo, scale);
        let bounds = t.bounds();
        for (axis, &i) in b[..3].iter().enumerate() {
            let i = i as usize;
            self.counts[axis][i] += 1;
            self.bounds[axis][i] = self.bounds[axis][i].union(bounds);
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

/// The bin of centre `c` on each axis (the fourth lane is filler): `⌊(c − lo)·scale⌋`, at most
/// `N − 1`. A NaN (from boxes beyond the f32 range, where `c − lo` overflows) lands in the last
/// bin. Binning and partitioning both call it, so an item is always moved to the side its bin is
/// on (the sides' boxes are their bins' boxes).
#[inline(always)]
fn bin_of<const N: usize>(c: Vec3A, lo: Vec3A, scale: Vec3A) -> [u32; 4] {
    let x = (c - lo) * scale;
    let last = (N - 1) as u32;
    #[cfg(target_arch = "x86_64")]
    {
        // four truncations in one instruction; NaN and values past i32 give 0x8000_0000, which
        // the clamp below sends to the last bin (`x` is never negative: `lo` is the smallest
        // centre, computed by the same f32 operations)
        // SAFETY: SSE2 is part of every x86-64 CPU; an `__m128i` is 16 bytes of plain data,
        // as is `[u32; 4]`
        let lanes: [u32; 4] = unsafe { std::mem::transmute(std::arch::x86_64::_mm_cvttps_epi32(x.into())) };
        lanes.map(|i| i.min(last))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x.extend(0.0).to_array().map(|v| {
            if v.is_nan() || v >= 2_147_483_648.0 {
                last
            } else {
                (v as u32).min(last)
            }
        })
    }
}

impl QuadBvh {
    /// Builds over `tris` (reordered in place into leaf order), with leaves as `leaves` says.
    /// `tris` must not be empty.
    pub fn build(tris: &mut [BuildItem], leaves: Leaves) -> Self {
        assert!(leaves.max <= MAX_LEAF_ITEMS, "leaves of at most {MAX_LEAF_ITEMS} items");
        let (bounds, centroids) = if tris.len() > PARALLEL_BINNING_MIN {
            tris.par_chunks(16384)
                .map(boxes_of)
                .reduce(|| (Bb::EMPTY, Bb::EMPTY), |a, b| (a.0.union(b.0), a.1.union(b.1)))
        } else {
            boxes_of(tris)
        };
        let root = decide(tris, 0, bounds, centroids, 0, leaves);
        let node = |first, count| Node {
            lo: bounds.lo.to_array(),
            first,
            hi: bounds.hi.to_array(),
            count,
        };
        if root.split.is_none() {
            // a leaf root: one node whose only child is the leaf
            let mut quads = QuadArray::zeroed(1);
            quads[0].len = 1;
            set_slot(&mut quads[0], 0, &root);
            return Self {
                root: node(root.start, root.count),
                quads,
                used: 1,
            };
        }
        let mut quads = QuadArray::zeroed(node_bound(root.count));
        let (span, used) = build_quad(tris, &root, &mut quads, 0, leaves);
        quads.truncate(span as usize);
        Self {
            root: node(0, 0),
            quads,
            used: used as usize,
        }
    }

    /// [`QuadBvh::build`] taking the items and giving their ids in leaf order (the items are
    /// dropped before returning).
    pub fn build_ids(mut tris: Vec<BuildItem>, leaves: Leaves) -> (Self, Vec<u32>) {
        let bvh = Self::build(&mut tris, leaves);
        let ids = tris.iter().map(|t| t.id).collect();
        (bvh, ids)
    }

    /// Every leaf reached from the root, as `(first, count)` (items `first..first + count` of
    /// the leaf order), in leaf order: they partition the items.
    pub fn leaves(&self) -> Vec<(usize, usize)> {
        let mut leaves = Vec::new();
        self.walk_slots(|_, quad, s, _| match quad.count[s] {
            0 => true,
            count => {
                leaves.push((quad.child[s] as usize, usize::from(count)));
                false
            }
        });
        leaves.sort_unstable();
        leaves
    }

    /// The boxes of the slots `levels` levels below the root (the root's own slots are level 1),
    /// and of the leaves met above that level, `(lo, hi)` per axis: they hold every item.
    pub fn boxes_below(&self, levels: u32) -> Vec<([f32; 3], [f32; 3])> {
        let mut boxes = Vec::new();
        self.walk_slots(|_, quad, s, level| {
            let descend = quad.count[s] == 0 && level < levels;
            if !descend {
                boxes.push(quad.slot_bounds(s));
            }
            descend
        });
        boxes
    }

    /// The numbers `4·q + s` of the slots holding leaves (slot `s` of node `q`), each once: the
    /// first levels' slots in order, each inner one replaced by the numbers of its subtree, the
    /// subtrees walked in parallel (depth first). Only the nodes reached are read: the room
    /// reserved between the parallel subtrees is never touched.
    pub(crate) fn leaf_slot_numbers(&self) -> Vec<u32> {
        self.leaf_slot_numbers_kept(|_, _| Wanted::Everything)
    }

    /// [`QuadBvh::leaf_slot_numbers`], in the same order, asking `wanted(node, slot)` about
    /// each inner slot reached: below one answered [`Wanted::Nothing`] nothing is read or
    /// returned, below one answered [`Wanted::Everything`] every leaf is returned without
    /// asking further. Leaf slots are not asked about. Pruning a depth-first walk keeps the
    /// order of what it still visits.
    pub(crate) fn leaf_slot_numbers_kept(&self, wanted: impl Fn(&Quad, usize) -> Wanted + Sync) -> Vec<u32> {
        /// Slots to split the walk into before handing out the subtrees.
        const SUBTREES: usize = 64;
        if self.quads.is_empty() {
            return Vec::new();
        }
        // `(node, slot)` pairs of the first levels, inner slots split into their children's
        // in place until there are enough (or only leaves)
        let slots_of = |q: usize| (0..self.quads[q].len as usize).map(move |s| (q, s));
        let mut top: Vec<(usize, usize)> = slots_of(0).collect();
        let inner = |&(q, s): &(usize, usize)| self.quads[q].count[s] == 0;
        while top.len() < SUBTREES && top.iter().any(inner) {
            let mut split = Vec::with_capacity(4 * top.len());
            for (q, s) in top {
                let quad = &self.quads[q];
                if quad.count[s] == 0 {
                    split.extend(slots_of(quad.child[s] as usize));
                } else {
                    split.push((q, s));
                }
            }
            top = split;
        }
        let parts: Vec<Vec<u32>> = top
            .par_iter()
            .map(|&(q, s)| {
                let quad = &self.quads[q];
                if quad.count[s] != 0 {
                    return vec![(4 * q + s) as u32];
                }
                let asking = match wanted(quad, s) {
                    Wanted::Nothing => return Vec::new(),
                    Wanted::Everything => false,
                    Wanted::Partly => true,
                };
                let mut numbers = Vec::new();
                // each node with whether its inner slots are asked about
                self.walk_slots_with(quad.child[s] as usize, asking, |q, quad, s, asking| {
                    if quad.count[s] != 0 {
                        numbers.push((4 * q + s) as u32);
                        return None;
                    }
                    match asking.then(|| wanted(quad, s)) {
                        Some(Wanted::Nothing) => None,
                        Some(Wanted::Partly) => Some(true),
                        Some(Wanted::Everything) | None => Some(false),
                    }
                });
                numbers
            })
            .collect();
        parts.concat()
    }

    /// Visits the slots reached from the root, each with its node's index and level (the root's
    /// slots are level 1); `visit(q, quad, slot, level)` says whether to descend into an inner
    /// slot's node.
    fn walk_slots(&self, visit: impl FnMut(usize, &Quad, usize, u32) -> bool) {
        if !self.quads.is_empty() {
            self.walk_slots_from(0, visit);
        }
    }

    /// [`QuadBvh::walk_slots`] below node `root` (its slots being level 1).
    fn walk_slots_from(&self, root: usize, mut visit: impl FnMut(usize, &Quad, usize, u32) -> bool) {
        self.walk_slots_with(root, 1, |q, quad, s, level| {
            visit(q, quad, s, level).then_some(level + 1)
        });
    }

    /// The slots reached from node `root`, depth first, each visited with its node's index and
    /// the state its node was entered with (`state` for `root`'s): `visit(q, quad, slot, state)`
    /// returns the state to enter an inner slot's node with, or `None` not to enter it.
    fn walk_slots_with<T: Copy>(
        &self,
        root: usize,
        state: T,
        mut visit: impl FnMut(usize, &Quad, usize, T) -> Option<T>,
    ) {
        let mut pending = vec![(root, state)];
        while let Some((q, state)) = pending.pop() {
            let quad = &self.quads[q];
            for s in 0..quad.len as usize {
                if let Some(below) = visit(q, quad, s, state) {
                    if quad.count[s] == 0 {
                        pending.push((quad.child[s] as usize, below));
                    }
                }
            }
        }
    }

    /// The 4-wide nodes, root first.
    pub fn quads(&self) -> &[Quad] {
        &self.quads
    }

    /// Number of 4-wide nodes in use.
    pub fn quad_count(&self) -> usize {
        self.used
    }

    /// Bytes held by the nodes in use (the parallel subtrees' unused room is address space
    /// only, see [`QuadArray`]).
    pub fn memory_bytes(&self) -> usize {
        self.used * std::mem::size_of::<Quad>() + std::mem::size_of::<Node>()
    }

    /// Depth-first visit for nearest-point queries: `lower_bound(node)` gives a lower bound
    /// of the distance to anything in `node`'s box (or `None` to prune it), `leaf(first,
    /// count)` visits a leaf's items. The root's box is asked first; a quad's children are
    /// visited nearer bound first, and each is asked again when popped (the bound may have
    /// tightened meanwhile).
    pub fn nearest(&self, mut lower_bound: impl FnMut(&Node) -> Option<f64>, mut leaf: impl FnMut(u32, u32)) {
        if lower_bound(&self.root).is_none() {
            return;
        }
        if self.root.count > 0 {
            leaf(self.root.first, self.root.count);
            return;
        }
        let slot = |quad: &Quad, s: usize| {
            let (lo, hi) = quad.slot_bounds(s);
            Node {
                lo,
                first: quad.child[s],
                hi,
                count: u32::from(quad.count[s]),
            }
        };
        let mut stack: Vec<(Node, f64)> = Vec::with_capacity(64);
        let mut quad = &self.quads[0];
        loop {
            let mut children = [(Node::default(), 0.0); 4];
            let mut len = 0;
            for s in 0..quad.len as usize {
                let node = slot(quad, s);
                if let Some(d) = lower_bound(&node) {
                    children[len] = (node, d);
                    len += 1;
                }
            }
            // farthest pushed first, so the nearest is popped next (a stable sort: equal bounds
            // keep slot order)
            children[..len].sort_by(|a, b| b.1.total_cmp(&a.1));
            stack.extend_from_slice(&children[..len]);
            let next = loop {
                let Some((node, _)) = stack.pop() else { return };
                if lower_bound(&node).is_none() {
                    continue;
                }
                if node.count > 0 {
                    leaf(node.first, node.count);
                    continue;
                }
                break node.first;
            };
            quad = &self.quads[next as usize];
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

    /// Whether the ray enters the box `lo..hi` within `[t0, t1]`: the arithmetic of
    /// [`SlabRay::entry8`] for one box. Rounding is monotonic, so a ray that does not enter a
    /// box by this test enters none of the boxes inside it by `entry4` or `entry8` (each
    /// slab's entry can only be later and its exit earlier).
    #[inline(always)]
    pub(crate) fn enters(&self, lo: [f32; 3], hi: [f32; 3], t0: f32, t1: f32) -> bool {
        let (mut n, mut f) = (t0, f32::INFINITY);
        for axis in 0..3 {
            let a = (lo[axis] - self.origin[axis]) * self.inv[axis];
            let b = (hi[axis] - self.origin[axis]) * self.inv[axis];
            n = max_f32(n, min_f32(a, b));
            f = min_f32(f, max_f32(a, b));
        }
        n <= min_f32(f * EXIT_PAD, t1)
    }

    /// [`SlabRay::entry4`] for the eight boxes of `oct` (the same operations on each box), one
    /// loop over the slots that the compiler turns into 8-wide AVX in the AVX2 copy.
    #[inline(always)]
    pub(crate) fn entry8(&self, oct: &Oct, t0: f32, t1: f32) -> (u32, [f32; 8]) {
        let mut near = [t0; 8];
        let mut inside = [0i32; 8];
        for s in 0..8 {
            let mut n = t0;
            let mut f = f32::INFINITY;
            for axis in 0..3 {
                let a = (oct.lo[axis][s] - self.origin[axis]) * self.inv[axis];
                let b = (oct.hi[axis][s] - self.origin[axis]) * self.inv[axis];
                n = max_f32(n, min_f32(a, b));
                f = min_f32(f, max_f32(a, b));
            }
            let f = min_f32(f * EXIT_PAD, t1);
            near[s] = n;
            inside[s] = -i32::from(n <= f);
        }
        (super::lane_mask(&inside), near)
    }
}

impl NodeTest for SlabsFrom<'_, SlabRay> {
    #[inline(always)]
    fn entry4(&self, quad: &Quad, t_max: f32) -> (u32, [f32; 4]) {
        self.ray.entry4(quad, self.t_min, t_max)
    }
}

/// The most 4-wide nodes a subtree over `count ≥ 2` items can need: every node has at least two
/// children and every leaf at least one item, so a tree of `L ≤ count` leaves has at most
/// `L − 1` nodes.
fn node_bound(count: u32) -> usize {
    count.saturating_sub(1).max(1) as usize
}

/// The box of `tris`' boxes and the box of their centres.
fn boxes_of(tris: &[BuildItem]) -> (Bb, Bb) {
    tris.iter().fold((Bb::EMPTY, Bb::EMPTY), |(b, c), t| {
        (b.union(t.bounds()), c.include(t.centroid()))
    })
}

/// Decides how the node over `tris` (items `start..` of the leaf order), whose boxes span
/// `bounds` and whose centres span `centroids`, is split, and partitions its items
/// accordingly: SAH over binned centres, a leaf where SAH prefers one of at most
/// [`Leaves::max`] items, the median along the widest centre axis from depth [`MEDIAN_DEPTH`] on or where
/// every centre coincides. The sides' boxes come from the bins and their centre boxes from the
/// partition pass, so a node costs two passes over its items.
fn decide(tris: &mut [BuildItem], start: u32, bounds: Bb, centroids: Bb, depth: usize, leaves: Leaves) -> Decided {
    let n = tris.len();
    let decided = |split| Decided {
        bounds,
        start,
        count: n as u32,
        depth,
        split,
    };
    if n == 1 {
        return decided(None);
    }
    let extent = centroids.hi - centroids.lo;
    let split = if depth >= MEDIAN_DEPTH || extent.max_element() <= 0.0 {
        None
    } else {
        sah_split(tris, bounds, centroids, leaves)
    };
    match split {
        Some(Split::Leaf) => decided(None),
        Some(Split::At(children)) => decided(Some(children)),
        None => {
            // median along the widest centroid axis (any order when all centroids coincide)
            let axis = extent.max_position();
            let mid = n / 2;
            tris.select_nth_unstable_by(mid, |a, b| a.centroid_on(axis).total_cmp(&b.centroid_on(axis)));
            let (left, right) = tris.split_at(mid);
            let ((lb, lc), (rb, rc)) = (boxes_of(left), boxes_of(right));
            decided(Some(Children {
                mid,
                bounds: [lb, rb],
                centroids: [lc, rc],
            }))
        }
    }
}

/// The two children of the inner node `node`, whose items are `tris`, decided (in parallel
/// for a node of more than [`PARALLEL_MIN`] items).
fn children_of(tris: &mut [BuildItem], node: &Decided, leaves: Leaves) -> [Decided; 2] {
    let Children {
        mid,
        bounds: [lb, rb],
        centroids: [lc, rc],
    } = *node.split.as_ref().expect("an inner node");
    let (left, right) = tris.split_at_mut(mid);
    let (start, rstart, depth) = (node.start, node.start + mid as u32, node.depth + 1);
    if node.count as usize > PARALLEL_MIN {
        let (l, r) = rayon::join(
            || decide(left, start, lb, lc, depth, leaves),
            || decide(right, rstart, rb, rc, depth, leaves),
        );
        [l, r]
    } else {
        [
            decide(left, start, lb, lc, depth, leaves),
            decide(right, rstart, rb, rc, depth, leaves),
        ]
    }
}

/// Writes `node`'s box into `quad`'s slot `slot`, and for a leaf its items (an inner node's
/// child index is written once its subtree has a place).
fn set_slot(quad: &mut Quad, slot: usize, node: &Decided) {
    for axis in 0..3 {
        quad.lo[axis][slot] = node.bounds.lo[axis];
        quad.hi[axis][slot] = node.bounds.hi[axis];
    }
    if node.split.is_none() {
        quad.child[slot] = node.start;
        quad.count[slot] =
            u16::try_from(node.count).expect("leaves hold at most u16::MAX items (checked by the build)");
    }
}

/// Builds the 4-wide subtree of the inner node `node` (items `tris`) into `slots` (at least
/// [`node_bound`] of its count), its own node into `slots[0]`, whose index is `index`.
///
/// The node's children are its two sides, the inner one of largest surface area replaced by
/// its own two sides while fewer than four (the binary SAH tree collapsed two levels at a
/// time). The children's subtrees follow depth first in slot order: packed one after the other
/// for a node of at most [`PARALLEL_MIN`] items, otherwise built in parallel, each in a range
/// of its bound, leaving the unused rest of each range zero. Returns the slots spanned and the
/// nodes written.
fn build_quad(tris: &mut [BuildItem], node: &Decided, slots: &mut [Quad], index: u32, leaves: Leaves) -> (u32, u32) {
    let [first, second] = children_of(tris, node, leaves);
    let mut members = [Some(first), Some(second), None, None];
    let mut len = 2;
    while len < 4 {
        // the widest inner member (the last of equal areas)
        let mut widest: Option<(usize, f32)> = None;
        for (i, member) in members[..len].iter().enumerate() {
            let member = member.as_ref().expect("the first `len` members are set");
            if member.split.is_some() {
                let area = member.bounds.half_area();
                if widest.is_none_or(|(_, w)| area.total_cmp(&w).is_ge()) {
                    widest = Some((i, area));
                }
            }
        }
        let Some((i, _)) = widest else { break };
        let opened = members[i].take().expect("set");
        let [a, b] = children_of(&mut tris[opened.range(node.start)], &opened, leaves);
        members[i] = Some(a);
        members[len] = Some(b);
        len += 1;
    }
    // the first `len` are set
    let members = &members[..len];
    let member = |slot: usize| members[slot].as_ref().expect("the first `len` members are set");
    let mut quad = Quad {
        len: len as u32,
        ..Quad::default()
    };
    for (slot, member) in members.iter().flatten().enumerate() {
        set_slot(&mut quad, slot, member);
    }
    let (head, rest) = slots.split_first_mut().expect("a slot for every 4-wide node");
    let (mut span, mut used) = (1u32, 1u32);
    if node.count as usize <= PARALLEL_MIN {
        // packed: each subtree right after the previous one
        let mut rest = rest;
        for (slot, member) in members.iter().flatten().enumerate() {
            if member.split.is_none() {
                continue;
            }
            quad.child[slot] = index + span;
            let (s, u) = build_quad(&mut tris[member.range(node.start)], member, rest, index + span, leaves);
            rest = &mut std::mem::take(&mut rest)[s as usize..];
            span += s;
            used += u;
        }
    } else {
        // each subtree in a range of its bound, its items and slots split off as disjoint slices
        let mut by_position: Vec<usize> = (0..len).collect();
        by_position.sort_by_key(|&slot| member(slot).start);
        let mut items: [Option<&mut [BuildItem]>; 4] = [None, None, None, None];
        let mut remaining = tris;
        for &slot in &by_position {
            let (mine, after) = std::mem::take(&mut remaining).split_at_mut(member(slot).count as usize);
            items[slot] = Some(mine);
            remaining = after;
        }
        let mut work = Vec::with_capacity(4);
        let mut rest = rest;
        for (slot, (member, items)) in members.iter().flatten().zip(items).enumerate() {
            if member.split.is_none() {
                continue;
            }
            let bound = node_bound(member.count);
            let (own, after) = std::mem::take(&mut rest).split_at_mut(bound);
            rest = after;
            quad.child[slot] = index + span;
            work.push((items.expect("every member's items"), member, own, index + span));
            span += bound as u32;
        }
        used += work
            .into_par_iter()
            .map(|(items, member, own, at)| build_quad(items, member, own, at, leaves).1)
            .sum::<u32>();
    }
    *head = quad;
    (span, used)
}

enum Split {
    Leaf,
    At(Children),
}

/// Where a node's items were split and the two sides' boxes and centre boxes.
#[derive(Clone, Copy)]
struct Children {
    mid: usize,
    bounds: [Bb; 2],
    centroids: [Bb; 2],
}

fn sah_split(tris: &mut [BuildItem], bounds: Bb, centroids: Bb, leaves: Leaves) -> Option<Split> {
    if tris.len() <= FEW_ITEMS {
        sah_split_binned::<FEW_BINS>(tris, bounds, centroids, leaves)
    } else {
        sah_split_binned::<BINS>(tris, bounds, centroids, leaves)
    }
}

/// The SAH split over `N` centroid bins per axis (see the module docs).
fn sah_split_binned<const N: usize>(
    tris: &mut [BuildItem],
    bounds: Bb,
    centroids: Bb,
    leaves: Leaves,
) -> Option<Split> {
    let n = tris.len();
    let extent = centroids.hi - centroids.lo;
    // axes with zero extent get scale 0: everything in bin 0, never a valid split there
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(N as f32 * (1.0 - 1e-6)) / extent,
        Vec3A::ZERO,
    );
    // filled in place (the bins of 32 are 3.5 kB: moving them cost more than binning a
    // small node)
    let mut bins = Bins::<N>::empty();
    if n > PARALLEL_BINNING_MIN {
        bins = tris
            .par_chunks(16384)
            .map(|c| {
                let mut b = Bins::<N>::empty();
                b.add(c, centroids.lo, scale);
                b
            })
            .reduce(Bins::<N>::empty, Bins::merge);
    } else {
        bins.add(tris, centroids.lo, scale);
    }
    let parent = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if scale[axis] == 0.0 {
            continue;
        }
        // an empty bin changes neither side's box nor count, so the areas and costs at its
        // edges repeat their neighbours' and are not computed again (small nodes leave most
        // bins empty)
        let mut right_area = [0f32; N];
        let mut right_count = [0u32; N];
        let (mut acc, mut count, mut area) = (Bb::EMPTY, 0, 0.0);
        for i in (1..N).rev() {
            if bins.counts[axis][i] > 0 {
                acc = acc.union(bins.bounds[axis][i]);
                count += bins.counts[axis][i];
                area = acc.half_area();
            }
            right_area[i] = area;
            right_count[i] = count;
        }
        let (mut acc, mut count) = (Bb::EMPTY, 0);
        for split in 1..N {
            if bins.counts[axis][split - 1] == 0 {
                // the same sides, hence the same cost, as the split before (never strictly better)
                continue;
            }
            acc = acc.union(bins.bounds[axis][split - 1]);
            count += bins.counts[axis][split - 1];
            if right_count[split] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.half_area() * leaves.cost(count) + right_area[split] * leaves.cost(right_count[split])) / parent;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    if n <= leaves.max && cost >= leaves.cost(n as u32) {
        return Some(Split::Leaf);
    }
    // the sides' boxes are the unions of their bins' boxes (each bin's box is the union of its
    // items' boxes); their centre boxes are gathered while partitioning
    let side = |range: std::ops::Range<usize>| bins.bounds[axis][range].iter().fold(Bb::EMPTY, |b, x| b.union(*x));
    let (mut lc, mut rc) = (Bb::EMPTY, Bb::EMPTY);
    let mut mid = 0;
    for i in 0..n {
        let c = tris[i].centroid();
        // the item goes to the side its bin is on
        if (bin_of::<N>(c, centroids.lo, scale)[axis] as usize) < split {
            lc = lc.include(c);
            if i != mid {
                // word by word: `swap` went through a stack copy written in two overlapping
                // 16-byte pieces and read back across them, a store-forwarding stall on every
                // move (the level-8 bench mesh's load and build: 0.291 → 0.274 s, medians of
                // 9 alternating runs)
                let (left, right) = tris.split_at_mut(i);
                let [mid_item, i_item] = [&mut left[mid], &mut right[0]];
                for (x, y) in mid_item.words_mut().iter_mut().zip(i_item.words_mut().iter_mut()) {
                    std::mem::swap(x, y);
                }
            }
            mid += 1;
        } else {
            rc = rc.include(c);
        }
    }
    (mid > 0 && mid < n).then(|| {
        Split::At(Children {
            mid,
            bounds: [side(0..split), side(split..N)],
            centroids: [lc, rc],
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Items in surface order (neighbours fall in the same bins), one in 97 at the far end of
    /// the f32 range.
    fn binned_items(n: usize) -> Vec<BuildItem> {
        (0..n)
            .map(|i| {
                let x = i as f32 * 0.01;
                let lo = if i % 97 == 5 {
                    Vec3A::new(-f32::MAX, 1.0, 2.0)
                } else {
                    Vec3A::new(x, (x * 3.0).sin(), 0.5 * x)
                };
                BuildItem::new(
                    Bb {
                        lo,
                        hi: lo + Vec3A::new(0.02, 0.03, 0.01),
                    },
                    i as u32,
                )
            })
            .collect()
    }

    /// The two sets of bins of a large node's binning, merged, are the bins of one set: the same
    /// counts, the same boxes, bit for bit.
    #[test]
    fn paired_bins_equal_one_set() {
        for n in [3, 127, 128, 129, 1000, 4097] {
            let items = binned_items(n);
            let (_, centroids) = boxes_of(&items);
            let extent = centroids.hi - centroids.lo;
            let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), Vec3A::splat(31.9) / extent, Vec3A::ZERO);
            let mut paired = Bins::<BINS>::empty();
            paired.add(&items, centroids.lo, scale);
            let mut single = Bins::<BINS>::empty();
            single.add_each(&items, centroids.lo, scale);
            assert_eq!(paired.counts, single.counts, "{n} items");
            let bits = |b: &Bins<BINS>| {
                b.bounds
                    .iter()
                    .flatten()
                    .flat_map(|bb| [bb.lo.to_array(), bb.hi.to_array()])
                    .flatten()
                    .map(f32::to_bits)
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&paired), bits(&single), "{n} items");
        }
    }

    /// The SAH split moves its items word by word: afterwards the same items, each whole, those
    /// whose bin is left of the split first, in the order in which they came.
    #[test]
    fn split_partitions_whole_items_stably_on_the_left() {
        let items = binned_items(3000);
        let mut split = items.clone();
        let (bounds, centroids) = boxes_of(&split);
        let Some(Split::At(children)) =
            sah_split_binned::<BINS>(&mut split, bounds, centroids, Leaves::tested_together(8, 3.0))
        else {
            panic!("3000 spread items are split");
        };
        let key = |t: &BuildItem| (t.id, t.lo.map(f32::to_bits), t.hi.map(f32::to_bits));
        let mut before: Vec<_> = items.iter().map(key).collect();
        let mut after: Vec<_> = split.iter().map(key).collect();
        // the left side keeps the items' order (each is swapped to the end of the left side)
        let left: Vec<u32> = split[..children.mid].iter().map(|t| t.id).collect();
        assert!(left.windows(2).all(|w| w[0] < w[1]), "left side in input order");
        let in_left = |t: &BuildItem| left.binary_search(&t.id).is_ok();
        let lc = split[..children.mid]
            .iter()
            .fold(Bb::EMPTY, |b, t| b.include(t.centroid()));
        assert_eq!(lc.lo.to_array(), children.centroids[0].lo.to_array());
        assert!(split[children.mid..].iter().all(|t| !in_left(t)));
        before.sort_unstable();
        after.sort_unstable();
        assert_eq!(before, after, "the same items, each whole");
    }

    #[test]
    fn build_items_are_small_and_keep_box_and_centre() {
        assert_eq!(std::mem::size_of::<BuildItem>(), 28);
        assert_eq!(std::mem::size_of::<Quad>(), 128);
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

    /// Every node in use is reached exactly once from the root, children after their parent;
    /// the parallel subtrees' unused room is zero nodes that no slot refers to; every item lies
    /// in exactly one leaf, inside its box. For leaf roots and trees of every shape, small ones
    /// packed and large ones built in parallel (more than `PARALLEL_MIN` items).
    #[test]
    fn node_arrays_hold_the_whole_tree() {
        let mut state = 12345u64;
        let mut random = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        // random boxes, then (from 10⁴ items on) boxes whose centres all coincide, which are split
        // at the median all the way down
        let sizes = [1, 2, 3, 7, 64, 65, 1000, 5000, 70_000, 10_000, 20_000];
        for (round, n) in sizes.into_iter().enumerate() {
            let coincide = round >= 9;
            let mut items: Vec<BuildItem> = (0..n)
                .map(|id| {
                    let lo = Vec3A::new(random(), random(), random()) * 100.0;
                    let size = Vec3A::new(random(), random(), random());
                    let bounds = if coincide {
                        Bb {
                            lo: Vec3A::splat(-1.0) - size,
                            hi: Vec3A::splat(1.0) + size,
                        }
                    } else {
                        Bb { lo, hi: lo + size }
                    };
                    BuildItem::new(bounds, id)
                })
                .collect();
            for leaves in [
                Leaves::per_item(2),
                Leaves::per_item(6),
                Leaves::tested_together(8, 3.0),
            ] {
                let bvh = QuadBvh::build(&mut items, leaves);
                assert!(!bvh.quads.is_empty());
                assert!(bvh.quads.len() <= node_bound(n));
                // every quad reached once, children after their parent (depth first), and
                // every item in exactly one leaf inside its leaf's box
                let mut reached = vec![0; bvh.quads.len()];
                let mut covered = vec![0; n as usize];
                reached[0] = 1;
                for (index, quad) in bvh.quads.iter().enumerate() {
                    for s in 0..quad.len as usize {
                        let (first, count) = (quad.child[s] as usize, usize::from(quad.count[s]));
                        if count == 0 {
                            assert!(first > index, "{n} items: quad {index} slot {s}");
                            reached[first] += 1;
                            continue;
                        }
                        for item in &items[first..first + count] {
                            covered[item.id as usize] += 1;
                            for axis in 0..3 {
                                assert!(quad.lo[axis][s] <= item.lo[axis] && item.hi[axis] <= quad.hi[axis][s]);
                            }
                        }
                    }
                }
                assert_eq!(reached.iter().filter(|&&r| r == 1).count(), bvh.quad_count());
                for (quad, &r) in bvh.quads.iter().zip(&reached) {
                    assert!(r <= 1, "{n} items, {leaves:?}");
                    if r == 0 {
                        assert!(quad.len == 0 && quad.child == [0; 4] && quad.count == [0; 4]);
                    }
                }
                if n <= PARALLEL_MIN as u32 {
                    assert_eq!(bvh.quads.len(), bvh.quad_count(), "packed: {n} items");
                }
                assert!(covered.iter().all(|&c| c == 1), "{n} items, {leaves:?}");
            }
        }
    }
}
