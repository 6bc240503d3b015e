//! The ordered closest-hit walk of one ray over 4-wide nodes ([`traverse_quads`]), and the pieces
//! the other walks share with it: the node and leaf tests a walk is given ([`NodeTest`],
//! [`LeafTest`]), the choice of the next node ([`next_inner_node`], [`next_within`]), the culling
//! bound ([`cull_bound`]) and the prefetch of entered children ([`prefetch_children`]).
//!
//! Order: the nearest entered child is visited next, the others pushed farthest first (a fixed
//! sorting network, [`farthest_first`]); a pushed child whose entry is beyond the closest hit
//! found meanwhile (by more than [`cull_bound`]'s margin) is skipped when popped. Which hit wins
//! never depends on the order: the leaf tests keep the smallest `(t, leaf position)`.

use super::prefetching::{prefetch_node, worth_prefetching};
use super::quad::Quad;
use glam::{BVec4A, Vec4, Vec4Swizzles};
use std::mem::MaybeUninit;

/// Traversal stack capacity: at most 3 entries left per level over at most 128 levels (both
/// hierarchies split at the median below a fixed depth, which bounds theirs under 128), plus 4.
pub(crate) const QUAD_STACK: usize = 3 * 128 + 4;

/// Ordered closest-hit walk over 4-wide nodes, starting at `quads[0]`: `entry4(quad, t_max)`
/// gives a bit per child slot the ray enters before `t_max` and the entry distances. The nearest
/// entered child is visited next and the others pushed farthest first (among equal entries the
/// later slot is visited first); one popped after the closest hit moved nearer than its entry
/// (by more than [`cull_bound`]'s margin) is skipped. `leaf(first, count, t_max)` tests a leaf
/// and returns the new, smaller `t_max` if it found a hit.
#[inline(always)]
pub(crate) fn traverse_quads(quads: &[Quad], t_max: f32, nodes: impl NodeTest, leaf: impl LeafTest) {
    traverse_quads_from(quads, 0, t_max, nodes, leaf);
}

/// The distance past which the walks skip a node when the closest hit so far is at `t_max`:
/// `t_max` enlarged by `2⁻¹⁰` of itself (infinities and NaN unchanged). A triangle's f32 `t` can
/// come out a few ulps below the computed entry into its own box, so culling at `t_max` itself
/// could drop a leaf holding a triangle hit at the same `t` as the best so far, and which of the
/// two wins (the one earlier in leaf order) would then depend on the order of visits: a single
/// ray and a packet could disagree. The margin keeps the leaf in; it costs next to nothing.
#[inline(always)]
pub(crate) fn cull_bound(t_max: f32) -> f32 {
    const MARGIN: f32 = 1.0 / 1024.0;
    t_max * if t_max >= 0.0 { 1.0 + MARGIN } else { 1.0 - MARGIN }
}

/// What [`traverse_quads`] does at a node: `entry4(quad, t_max)` gives a bit per child slot the
/// ray enters before `t_max` and the entry distances. A type with an `#[inline(always)]` method
/// (not a closure), so that the test is inlined into the walk for certain.
pub(crate) trait NodeTest {
    fn entry4(&self, quad: &Quad, t_max: f32) -> (u32, [f32; 4]);
}

/// A ray's slab tests (`S`: the scene's conservative `scene::SlabRay` or a mesh's f32
/// [`SlabRay`](super::slab::SlabRay)) over its range from `t_min`: a [`NodeTest`].
pub(crate) struct SlabsFrom<'a, S> {
    pub ray: &'a S,
    pub t_min: f32,
}

/// What [`traverse_quads`] does at a leaf: `test(first, count, t_max)` tests the leaf's items
/// and returns the new, smaller `t_max` if it found a hit. Closures are leaf tests; a type of
/// its own with an `#[inline(always)]` method is inlined into the walk for certain (a closure
/// called from the walk's loop may be left out of line, its ray data spilled around each call).
pub(crate) trait LeafTest {
    fn test(&mut self, first: u32, count: u32, t_max: f32) -> Option<f32>;

    /// Asks memory for what testing the leaf of `count` items from `first` will read (called
    /// by walks that prefetch, see [`worth_prefetching`], as soon as the leaf is entered).
    #[inline(always)]
    fn prefetch(&self, _first: u32, _count: u32) {}
}

impl<F: FnMut(u32, u32, f32) -> Option<f32>> LeafTest for F {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, t_max: f32) -> Option<f32> {
        self(first, count, t_max)
    }
}

/// [`traverse_quads`] of the subtree under `quads[root]`.
#[inline(always)]
pub(crate) fn traverse_quads_from(
    quads: &[Quad],
    root: usize,
    mut t_max: f32,
    nodes: impl NodeTest,
    mut leaf: impl LeafTest,
) {
    if quads.is_empty() {
        return;
    }
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<Pending>::uninit() }; QUAD_STACK];
    let mut top = 0usize;
    let mut quad = root;
    let prefetch = worth_prefetching(quads);
    loop {
        let q = &quads[quad];
        let (hits, near) = nodes.entry4(q, cull_bound(t_max));
        let hits = hits & q.occupied();
        if prefetch {
            prefetch_children(quads, &q.child, &q.count, hits, &leaf);
        }
        let mut next = None;
        if hits != 0 {
            if hits & (hits - 1) == 0 {
                let slot = hits.trailing_zeros() as usize;
                next = Some((q.child[slot], u32::from(q.count[slot]), near[slot]));
            } else {
                let first = hits.trailing_zeros() as usize;
                let rest = hits & (hits - 1);
                let (slot, pushed) = if rest & (rest - 1) == 0 {
                    // two: the farther pushed, the nearer next
                    nearer_of_two(first, rest.trailing_zeros() as usize, &near)
                } else {
                    // three or four, sorted farthest first ([`farthest_first`], no branch on the
                    // entries); the two farthest written whatever their number, the top raised past
                    // those pushed
                    let order = farthest_first(hits, near);
                    let entered = 3 + usize::from(hits == 0b1111);
                    for (k, &slot) in order[..2].iter().enumerate() {
                        stack[top + k].write((q.child[slot], u32::from(q.count[slot]), near[slot]));
                    }
                    top += entered - 2;
                    (order[entered - 1], order[entered - 2])
                };
                stack[top].write((q.child[pushed], u32::from(q.count[pushed]), near[pushed]));
                top += 1;
                next = Some((q.child[slot], u32::from(q.count[slot]), near[slot]));
            }
        }
        match next_inner_node(&stack, &mut top, next, &mut t_max, &mut leaf) {
            Some(inner) => quad = inner,
            None => return,
        }
    }
}

/// A child waiting on a single-ray walk's stack: `(child, count, entry)`, an inner node
/// (`count = 0`, `child` its index) or a leaf of `count` items from `child`, and the ray's entry
/// distance into its box.
pub(crate) type Pending = (u32, u32, f32);

/// The end of one step of the ordered single-ray walks ([`traverse_quads_from`],
/// [`oct::Octs::traverse`]): visits `next`, else pops `stack[..top]`, until an inner node to open,
/// whose index it returns (`None` once the stack is empty). An entry farther than
/// [`cull_bound`]`(t_max)` is skipped ([`next_within`]); a leaf is tested (`leaf`), lowering
/// `t_max` if it hits.
#[inline(always)]
pub(crate) fn next_inner_node(
    stack: &[MaybeUninit<Pending>],
    top: &mut usize,
    mut next: Option<Pending>,
    t_max: &mut f32,
    leaf: &mut impl LeafTest,
) -> Option<usize> {
    loop {
        let (child, count, _) = next_within(stack, top, next.take(), *t_max)?;
        if count == 0 {
            return Some(child as usize);
        }
        if let Some(t) = leaf.test(child, count, *t_max) {
            *t_max = t;
        }
    }
}

/// `next`, else the top of `stack[..top]` (popped), skipping entries farther than
/// [`cull_bound`]`(t_max)`: the item a walk visits next (`None` once the stack is empty).
#[inline(always)]
pub(crate) fn next_within(
    stack: &[MaybeUninit<Pending>],
    top: &mut usize,
    mut next: Option<Pending>,
    t_max: f32,
) -> Option<Pending> {
    loop {
        let item = match next.take() {
            Some(item) => item,
            None => {
                *top = top.checked_sub(1)?;
                // SAFETY: `stack[*top]` was written by the push that raised `top` above it
                unsafe { stack[*top].assume_init() }
            }
        };
        if item.2 > cull_bound(t_max) {
            continue;
        }
        return Some(item);
    }
}

/// The two entered slots `first` and `second` (`first < second`) as `(nearer, farther)` by their
/// entries `near[slot]`; among equal entries the later slot is the nearer, so it is visited first.
#[inline(always)]
pub(crate) fn nearer_of_two(first: usize, second: usize, near: &[f32]) -> (usize, usize) {
    if near[second] <= near[first] {
        (second, first)
    } else {
        (first, second)
    }
}

/// Asks the cache for the nodes (`N`: [`Quad`] or [`oct::Oct`], every cache line of each) of
/// the entered inner children (bits of `entered`) of a node whose slots refer to `child` and
/// `count`, as soon as they are known: the walk visits one next and pushes the others, and in a
/// hierarchy larger than the cache each visit would otherwise wait on memory in turn. A leaf slot
/// asks for `nodes[0]` (no branch on the slot's kind), and for what `leaf` will read
/// ([`LeafTest::prefetch`]; nothing, and no branch, for a leaf test without a prefetch).
#[inline(always)]
pub(crate) fn prefetch_children<N>(nodes: &[N], child: &[u32], count: &[u16], entered: u32, leaf: &impl LeafTest) {
    let mut slots = entered;
    while slots != 0 {
        let slot = slots.trailing_zeros() as usize;
        slots &= slots - 1;
        prefetch_node(nodes, if count[slot] == 0 { child[slot] as usize } else { 0 });
        if count[slot] != 0 {
            leaf.prefetch(child[slot], u32::from(count[slot]));
        }
    }
}

/// The slots of a node, the entered ones (bits of `entered`) first, sorted farthest first by
/// their entry `near[slot]` (entries within 3 ulps count as equal; among equal entries the later
/// slot last, so that it is visited first); the slots not entered follow in no particular order.
/// The order only steers the walk: which hit wins never depends on it. A fixed sorting network of five
/// min/max exchanges on keys that carry the slot in their two low bits, so no branch depends on
/// the entries.
#[inline(always)]
pub(super) fn farthest_first(entered: u32, near: [f32; 4]) -> [usize; 4] {
    let mut keys = [0f32; 4];
    for slot in 0..4 {
        // finite keys (no NaN from the slot bits), the slot's bits below the entry's: `3 − slot`
        // raises a positive key more for an earlier slot, `slot` lowers a negative one more for a
        // later slot
        let bits = near[slot].clamp(-f32::MAX, f32::MAX).to_bits();
        let tie = if bits >> 31 == 0 { 3 - slot as u32 } else { slot as u32 };
        let key = f32::from_bits((bits & !3) | tie);
        keys[slot] = if entered & (1 << slot) != 0 {
            key
        } else {
            f32::NEG_INFINITY
        };
    }
    let keys = Vec4::from_array(keys);
    // exchanges (0,1) and (2,3), then (0,2) and (1,3), then (1,2): larger key to the lower index
    let exchange = |v: Vec4, partner: Vec4, upper: BVec4A| Vec4::select(upper, v.max(partner), v.min(partner));
    let keys = exchange(keys, keys.yxwz(), BVec4A::new(true, false, true, false));
    let keys = exchange(keys, keys.zwxy(), BVec4A::new(true, true, false, false));
    let keys = exchange(keys, keys.xzyw(), BVec4A::new(true, true, false, false));
    keys.to_array().map(|key| {
        let bits = key.to_bits();
        (if bits >> 31 == 0 { 3 - (bits & 3) } else { bits & 3 }) as usize
    })
}
