//! The one hierarchy builder, shared by the scene (over objects) and by meshes (over
//! triangles): parallel binned-SAH build of 4-wide SoA nodes ([`Quad`]) over f32 item boxes,
//! written straight into a [`QuadBvh`] (its layout and queries are in `quad_bvh.rs`). Items are
//! referred to by their position in leaf order, which the build makes by permuting them in place.
//!
//! Build. Item boxes and centroids in f32; each split bins centroids into 32 bins per axis (8
//! for nodes of at most 64 items; binning itself in parallel for large nodes), sweeps the SAH
//! (traversal step cost 1; leaves cost what the caller's [`Leaves`] say: one per item, or one
//! price for a whole leaf whose items are tested together, a split's sides priced as that many
//! full leaves), and partitions in place; the children's boxes are the unions of their bins'
//! boxes and their centre boxes are gathered while partitioning, so a node costs two passes over
//! its items. A node becomes a leaf when SAH prefers it and it holds at most [`Leaves::max`]
//! items; below depth [`MEDIAN_DEPTH`] (or when all centroids coincide) it is split at the median
//! instead, which bounds the depth to `MEDIAN_DEPTH + 32` and the traversal stack.
//!
//! The quads are written as the splits are decided, with no binary tree in between: a quad's
//! children are its node's two sides, the inner one of largest surface area replaced by its own
//! two sides while there are fewer than four (the binary SAH tree collapsed two levels at a
//! time). Subtrees of more than [`PARALLEL_MIN`] items are built with rayon, each into a range
//! of the node array as long as its bound (`items − 1` nodes), the rest of which stays unused
//! and costs no memory ([`QuadArray`]); smaller subtrees are packed depth first. So the build
//! holds the items and the nodes, nothing else (a million scene objects: 28 + 56 MB).

use super::quad::Quad;
use super::quad_array::QuadArray;
use super::quad_bvh::{Node, QuadBvh};
use glam::Vec3A;
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
    /// previous one to be written (see docs/performance.md).
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
mod tests;
