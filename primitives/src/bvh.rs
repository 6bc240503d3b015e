//! The scene's bounding volume hierarchy over its bounded objects, and what every hierarchy
//! shares: the 4-wide node ([`Quad`]) and its ordered closest-hit walk ([`traverse_quads`]).
//! One builder (`build`: parallel binned SAH, written straight into 4-wide nodes) makes both the
//! scene's hierarchy (leaves of at most two objects) and each mesh's (leaves of at most six
//! triangles); a mesh's quads are also collapsed into 8-wide nodes for its single rays ([`oct`]).
//!
//! Traversal of the scene's hierarchy: quads hold their children's f32 bounds (rounded outward
//! from the objects' f64 bounds) in SoA layout, tested four at a time with SSE, conservative
//! against the f64 ray (see `SlabRay`); the nearest entered child is visited next, the others
//! pushed farthest first and skipped when popped if the closest hit is already nearer.
//! Primitives are then tested in f64, so the f32 traversal never changes a hit.

pub(crate) mod build;
pub(crate) mod oct;
mod quad_array;

use crate::PACKET;
use crate::{Aabb, Interval, Ray};
use build::{Bb, BuildItem, Leaves, QuadBvh};
use glam::{BVec4A, Vec3A, Vec4, Vec4Swizzles};
use std::mem::MaybeUninit;

/// Rounds an f64 to the nearest f32 not above it (boxes and ray ranges rounded outward).
///
/// A subnormal `x` (a range opened at 0 starts at `0.next_up()`) is answered without converting
/// it: on x86 an arithmetic operation or conversion on a subnormal operand takes a microcode
/// assist of some hundred cycles, more than the rest of a ray's set-up.
#[inline]
pub(crate) fn round_down(x: f64) -> f32 {
    if x != 0.0 && x.abs() < f64::MIN_POSITIVE {
        // below f32's smallest subnormal: 0 from above, −2⁻¹⁴⁹ from below
        return if x > 0.0 { 0.0 } else { -f32::from_bits(1) };
    }
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

/// Rounds an f64 to the nearest f32 not below it.
#[inline]
pub(crate) fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        y.next_up()
    } else {
        y
    }
}

/// A BVH over items identified by `u32` ids.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The 4-wide nodes; leaves index `items`.
    tree: QuadBvh,
    /// Item ids in leaf order.
    items: Vec<u32>,
}

/// A 4-wide node, shared by the scene's and the meshes' hierarchies: up to four children's f32
/// boxes in SoA layout, tested in one SSE pass per axis. `count[i] = 0` marks an inner child
/// (its quad is `child[i]`), `count[i] > 0` a leaf of that many items (or triangles) from
/// `child[i]`; slots beyond `len` are empty. 128 bytes: two cache lines (leaves hold at most
/// `u16::MAX` items, which the builder checks).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Quad {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub child: [u32; 4],
    pub count: [u16; 4],
    pub len: u32,
}

impl Quad {
    /// Slot `s`'s box, `(lo, hi)` per axis.
    #[inline(always)]
    pub(crate) fn slot_bounds(&self, s: usize) -> ([f32; 3], [f32; 3]) {
        (
            [self.lo[0][s], self.lo[1][s], self.lo[2][s]],
            [self.hi[0][s], self.hi[1][s], self.hi[2][s]],
        )
    }

    /// The box around its slots' boxes, `(lo, hi)` per axis: it holds every box below this
    /// node, so a ray that [`build::SlabRay::enters`] none of it enters none of theirs.
    #[inline(always)]
    pub(crate) fn box_of_slots(&self) -> ([f32; 3], [f32; 3]) {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for slot in 0..(self.len as usize).min(4) {
            for axis in 0..3 {
                lo[axis] = min_f32(lo[axis], self.lo[axis][slot]);
                hi[axis] = max_f32(hi[axis], self.hi[axis][slot]);
            }
        }
        (lo, hi)
    }

    /// A bit for each slot in use (`0..len`).
    #[inline(always)]
    pub(crate) fn occupied(&self) -> u32 {
        (1u32 << self.len) - 1
    }
}

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

/// A ray's slab tests (`S`: the scene's conservative [`SlabRay`] or a mesh's f32
/// `build::SlabRay`) over its range from `t_min`: a [`NodeTest`].
pub(crate) struct SlabsFrom<'a, S> {
    pub ray: &'a S,
    pub t_min: f32,
}

impl NodeTest for SlabsFrom<'_, SlabRay> {
    #[inline(always)]
    fn entry4(&self, quad: &Quad, t_max: f32) -> (u32, [f32; 4]) {
        self.ray.entry4(quad, self.t_min, t_max)
    }
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

/// Node bytes from which the walks prefetch ([`worth_prefetching`]): 512 KiB, the L2 cache of a
/// Zen 2/3 core (1 MiB on Zen 4 and recent Intel cores).
const PREFETCH_MIN_BYTES: usize = 512 << 10;

/// Whether a walk over `nodes` should prefetch the entered children ([`prefetch_children`]):
/// only where the nodes outgrow a core's L2 cache. In a smaller hierarchy they are in cache
/// already, and the prefetch loop's data-dependent trip count only costs mispredicted branches
/// (mesh4's octs: 1505 -> 1386 instructions and 18.4 -> 14.7 mispredictions a ray entering the
/// box, cachegrind).
#[inline(always)]
pub(crate) fn worth_prefetching<N>(nodes: &[N]) -> bool {
    std::mem::size_of_val(nodes) >= PREFETCH_MIN_BYTES
}

/// Asks memory for the cache line holding `*p` (a hint: it never faults, whatever the address;
/// nothing on other architectures than x86-64).
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch never faults, whatever the address
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Asks memory for every cache line of `nodes[index]` (a hint: any index will do).
#[inline(always)]
pub(crate) fn prefetch_node<N>(nodes: &[N], index: usize) {
    let bytes = nodes.as_ptr().wrapping_add(index).cast::<u8>();
    for line in 0..std::mem::size_of::<N>().div_ceil(64) {
        prefetch(bytes.wrapping_add(64 * line));
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
fn farthest_first(entered: u32, near: [f32; 4]) -> [usize; 4] {
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

/// Largest leaf of the scene's hierarchy.
const MAX_LEAF: usize = 2;

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
    fn entry(&self, bounds: &[[f32; 3]; 2], t0: f32, t1: f32) -> Option<f32> {
        let lo = (Vec3A::from_array(bounds[0]) - self.origin) * self.inv;
        let hi = (Vec3A::from_array(bounds[1]) - self.origin) * self.inv;
        let near = lo.min(hi) - self.pad;
        let far = lo.max(hi) * EXIT_PAD + self.pad;
        let near = near.max_element().max(t0);
        let far = far.min_element().min(t1);
        (near <= far).then_some(near)
    }
}

impl Bvh {
    /// Whether the hierarchy holds no items (then every walk finds nothing).
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Builds over items `(bounds, id)` (all bounds finite), in parallel; traversal reports
    /// the ids. The tree does not depend on the thread count.
    #[must_use]
    pub fn build(items: &[(Aabb, u32)]) -> Self {
        Self::build_from(items.iter().copied())
    }

    /// [`Bvh::build`] over boxes given one at a time, so that the caller need not hold a list of
    /// them (48 B each) during the build.
    #[must_use]
    pub fn build_from(items: impl IntoIterator<Item = (Aabb, u32)>) -> Self {
        let work: Vec<BuildItem> = items
            .into_iter()
            .map(|(b, id)| {
                let bounds = Bb {
                    lo: Vec3A::new(round_down(b.min.x), round_down(b.min.y), round_down(b.min.z)),
                    hi: Vec3A::new(round_up(b.max.x), round_up(b.max.y), round_up(b.max.z)),
                };
                BuildItem::new(bounds, id)
            })
            .collect();
        if work.is_empty() {
            return Self::default();
        }
        let (tree, items) = QuadBvh::build_ids(work, Leaves::per_item(MAX_LEAF));
        Self { tree, items }
    }

    /// Number of 4-wide nodes.
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.tree.quad_count()
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
        // an empty hierarchy (a scene whose one bounded object is tested directly) costs nothing,
        // not even the slab set-up's divisions
        if self.items.is_empty() {
            return None;
        }
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
            self.tree.quads(),
            round_up(range.max),
            SlabsFrom { ray: &slab, t_min: t0 },
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

/// A packet's rays for the scene hierarchy's slab tests, in SoA layout (see [`SlabRay`]).
struct SlabPacket {
    origin: [[f32; PACKET]; 3],
    inv: [[f32; PACKET]; 3],
    pad: [[f32; PACKET]; 3],
    t_min: [f32; PACKET],
}

impl SlabPacket {
    /// Entry distances of every lane into child `slot` of `quad` and the lanes entering it
    /// before their `t1`: [`SlabRay::entry4`]'s arithmetic, lane by lane.
    #[inline(always)]
    fn entry(&self, quad: &Quad, slot: usize, t1: &[f32; PACKET]) -> (u32, [f32; PACKET]) {
        let mut near = [0.0; PACKET];
        let mut inside = [0i32; PACKET];
        for l in 0..PACKET {
            let mut n = self.t_min[l];
            let mut f = t1[l];
            for axis in 0..3 {
                let o = self.origin[axis][l];
                let inv = self.inv[axis][l];
                let pad = self.pad[axis][l];
                let a = (quad.lo[axis][slot] - o) * inv;
                let b = (quad.hi[axis][slot] - o) * inv;
                n = max_f32(n, min_f32(a, b) - pad);
                f = min_f32(f, max_f32(a, b) * EXIT_PAD + pad);
            }
            near[l] = n;
            inside[l] = -i32::from(n <= f);
        }
        (lane_mask(&inside), near)
    }
}

/// `max` that compiles to one `maxps`.
#[inline(always)]
pub(crate) fn max_f32(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `min` that compiles to one `minps`.
#[inline(always)]
pub(crate) fn min_f32(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Bit `l` set where `flags[l]` is `-1` (all ones) rather than `0`: two `movmskps` on x86-64
/// (a bit loop otherwise, which the compiler turns into a chain of shuffles).
#[inline(always)]
pub(crate) fn lane_mask(flags: &[i32; PACKET]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128i, _mm_castsi128_ps, _mm_loadu_si128, _mm_movemask_ps};
        const _: () = assert!(PACKET == 8);
        let halves = flags.as_ptr().cast::<__m128i>();
        // SAFETY: SSE2 is in every x86-64 CPU; the two 16-byte loads stay inside `flags`
        // (32 bytes: `PACKET` is 8, checked above)
        unsafe {
            let lo = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves)));
            let hi = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves.add(1))));
            (lo | (hi << 4)) as u32
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut mask = 0;
        for (l, &f) in flags.iter().enumerate() {
            mask |= u32::from(f != 0) << l;
        }
        mask
    }
}

/// A child waiting on a packet walk's stack: node or leaf (`count > 0`), the lanes entering it
/// and their entry distances.
#[derive(Clone, Copy)]
pub(crate) struct PendingChild {
    pub child: u32,
    pub count: u32,
    pub lanes: u32,
    pub entry: [f32; PACKET],
}

/// What a packet walk ([`walk_packet`]) asks of the hierarchy's user.
pub(crate) trait PacketVisitor {
    /// The lanes entering child `slot` of `quad` before their `t1`, and their entry distances.
    fn entry(&self, quad: &Quad, slot: usize, t1: &[f32; PACKET]) -> (u32, [f32; PACKET]);
    /// Tests the leaf `first..first + count` for `lanes`, lowering their `t_max`.
    fn leaf(&mut self, first: u32, count: u32, lanes: u32, t_max: &mut [f32; PACKET]);
    /// Walks the subtree under `quads[root]` for each of `lanes` alone, lowering their `t_max`.
    fn alone(&mut self, root: usize, lanes: u32, t_max: &mut [f32; PACKET]);
}

/// Ordered walk of a packet over 4-wide nodes from `quads[0]` for the lanes of `active` (see
/// [`PacketVisitor`]): children are visited by the lanes entering them, nearest first by their
/// nearest lane's entry; a lane whose `t_max` fell below its entry drops out when the child is
/// popped; a node entered by at most `alone_lanes` lanes is handed to [`PacketVisitor::alone`].
#[inline(always)]
pub(crate) fn walk_packet(
    quads: &[Quad],
    active: u32,
    t_min: [f32; PACKET],
    t_max: &mut [f32; PACKET],
    alone_lanes: u32,
    visitor: &mut impl PacketVisitor,
) {
    if quads.is_empty() || active == 0 {
        return;
    }
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<PendingChild>::uninit() }; QUAD_STACK];
    stack[0].write(PendingChild {
        child: 0,
        count: 0,
        lanes: active,
        entry: t_min,
    });
    let mut top = 1usize;
    while top > 0 {
        top -= 1;
        // SAFETY: `stack[top]` was written by the push that raised `top` above it
        let pending = unsafe { stack[top].assume_init() };
        let mut still = [0i32; PACKET];
        for l in 0..PACKET {
            still[l] = -i32::from(pending.entry[l] <= cull_bound(t_max[l]));
        }
        let lanes = pending.lanes & lane_mask(&still);
        if lanes == 0 {
            continue;
        }
        if pending.count > 0 {
            visitor.leaf(pending.child, pending.count, lanes, t_max);
            continue;
        }
        if lanes.count_ones() <= alone_lanes {
            visitor.alone(pending.child as usize, lanes, t_max);
            continue;
        }
        let quad = &quads[pending.child as usize];
        let mut t1 = [f32::NEG_INFINITY; PACKET];
        for l in 0..PACKET {
            if (lanes >> l) & 1 != 0 {
                t1[l] = cull_bound(t_max[l]);
            }
        }
        // the entered children, sorted farthest first by their nearest lane's entry
        let mut order: [(f32, PendingChild); 4] = [(0.0, pending); 4];
        let mut entered = 0;
        for slot in 0..quad.len as usize {
            let (inside, near) = visitor.entry(quad, slot, &t1);
            if inside == 0 {
                continue;
            }
            let mut nearest = f32::INFINITY;
            for (l, &t) in near.iter().enumerate() {
                if (inside >> l) & 1 != 0 {
                    nearest = min_f32(nearest, t);
                }
            }
            let child = PendingChild {
                child: quad.child[slot],
                count: u32::from(quad.count[slot]),
                lanes: inside,
                entry: near,
            };
            let mut k = entered;
            while k > 0 && order[k - 1].0 < nearest {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = (nearest, child);
            entered += 1;
        }
        for (_, child) in &order[..entered] {
            stack[top].write(*child);
            top += 1;
        }
    }
}

/// Bits of `lanes`, lowest first.
#[inline(always)]
pub(crate) fn lanes_of(lanes: u32) -> impl Iterator<Item = usize> {
    let mut rest = lanes;
    std::iter::from_fn(move || {
        (rest != 0).then(|| {
            let l = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            l
        })
    })
}

/// A node of the scene's hierarchy entered by at most this many lanes is walked by each alone.
const SCENE_ALONE_LANES: u32 = 1;

/// The scene hierarchy's packet walk: lanes' slab rays, ranges and closest ids so far.
struct ScenePacket<'a, T> {
    bvh: &'a Bvh,
    slabs: &'a [Option<SlabRay>; PACKET],
    packet: SlabPacket,
    ranges: [Interval; PACKET],
    best: [Option<u32>; PACKET],
    test: T,
}

impl<T: FnMut(usize, u32, Interval) -> Option<f64>> ScenePacket<'_, T> {
    /// Lane `l`'s items `first..first + count`: [`Bvh::closest`]'s leaf test. Returns the new
    /// `t_max` if one was hit.
    #[inline(always)]
    fn leaf_lane(&mut self, l: usize, first: u32, count: u32) -> Option<f32> {
        let mut found = None;
        for &id in &self.bvh.items[first as usize..(first + count) as usize] {
            if let Some(t) = (self.test)(l, id, self.ranges[l]) {
                self.ranges[l].max = t;
                self.best[l] = Some(id);
                found = Some(round_up(t));
            }
        }
        found
    }
}

impl<T: FnMut(usize, u32, Interval) -> Option<f64>> PacketVisitor for ScenePacket<'_, T> {
    #[inline(always)]
    fn entry(&self, quad: &Quad, slot: usize, t1: &[f32; PACKET]) -> (u32, [f32; PACKET]) {
        self.packet.entry(quad, slot, t1)
    }

    #[inline(always)]
    fn leaf(&mut self, first: u32, count: u32, lanes: u32, t_max: &mut [f32; PACKET]) {
        for l in lanes_of(lanes) {
            if let Some(t) = self.leaf_lane(l, first, count) {
                t_max[l] = t;
            }
        }
    }

    #[inline(always)]
    fn alone(&mut self, root: usize, lanes: u32, t_max: &mut [f32; PACKET]) {
        for l in lanes_of(lanes) {
            let Some(slab) = &self.slabs[l] else { continue };
            let t0 = self.packet.t_min[l];
            let mut lane_max = t_max[l];
            let quads = self.bvh.tree.quads();
            traverse_quads_from(
                quads,
                root,
                lane_max,
                SlabsFrom { ray: slab, t_min: t0 },
                |first, count, _| {
                    let t = self.leaf_lane(l, first, count)?;
                    lane_max = t;
                    Some(t)
                },
            );
            t_max[l] = lane_max;
        }
    }
}

impl Bvh {
    /// [`Bvh::closest`] for a packet of at most [`PACKET`] rays at once: `test(lane, id, range)`
    /// as there, per lane; returns each lane's id that set its final `range.max`. The rays walk
    /// the 4-wide nodes together (see [`walk_packet`]). Where `test` settles exact ties of `t`
    /// by id (rejects a hit at exactly `range.max` from an id above the one holding it), every
    /// lane gets [`Bvh::closest`]'s answer whatever order the leaves are visited in.
    pub fn closest_packet(
        &self,
        rays: &[Ray],
        ranges: &[Interval],
        mut test: impl FnMut(usize, u32, Interval) -> Option<f64>,
    ) -> [Option<u32>; PACKET] {
        let n = rays.len().min(PACKET);
        if n == 0 {
            return [None; PACKET];
        }
        let slabs: [Option<SlabRay>; PACKET] = std::array::from_fn(|l| (l < n).then(|| SlabRay::new(&rays[l])));
        if slabs[..n].iter().flatten().any(|s| !s.is_representable()) || self.tree.quads().is_empty() {
            let mut best = [None; PACKET];
            for l in 0..n {
                best[l] = self.closest(&rays[l], ranges[l], |id, r| test(l, id, r));
            }
            return best;
        }
        let mut packet = SlabPacket {
            origin: [[0.0; PACKET]; 3],
            inv: [[0.0; PACKET]; 3],
            pad: [[0.0; PACKET]; 3],
            t_min: [0.0; PACKET],
        };
        let mut t_max = [f32::NEG_INFINITY; PACKET];
        let mut lane_ranges = [Interval::POSITIVE; PACKET];
        let mut active = 0;
        for l in 0..PACKET {
            // a lane without a ray repeats the first with an empty range
            let (slab, range) = match &slabs[l] {
                Some(slab) => (slab, ranges[l]),
                None => (
                    slabs[0].as_ref().expect("a packet has a first ray"),
                    Interval::new(1.0, 0.0),
                ),
            };
            for axis in 0..3 {
                packet.origin[axis][l] = slab.origin[axis];
                packet.inv[axis][l] = slab.inv[axis];
                packet.pad[axis][l] = slab.pad[axis];
            }
            packet.t_min[l] = round_down(range.min);
            lane_ranges[l] = range;
            if l < n && !range.is_empty() {
                t_max[l] = round_up(range.max);
                active |= 1 << l;
            }
        }
        // the walk runs in the AVX2 copy where the CPU has it (eight lanes per slab operation);
        // `test` is called through a pointer, as a type without a name cannot cross into it
        #[inline(always)]
        fn walk(
            bvh: &Bvh,
            slabs: &[Option<SlabRay>; PACKET],
            packet: SlabPacket,
            ranges: [Interval; PACKET],
            active: u32,
            t_max: &mut [f32; PACKET],
            test: &mut dyn FnMut(usize, u32, Interval) -> Option<f64>,
        ) -> [Option<u32>; PACKET] {
            let t_min = packet.t_min;
            let mut visitor = ScenePacket {
                bvh,
                slabs,
                packet,
                ranges,
                best: [None; PACKET],
                test,
            };
            walk_packet(bvh.tree.quads(), active, t_min, t_max, SCENE_ALONE_LANES, &mut visitor);
            visitor.best
        }
        crate::with_fma!(walk(
            bvh: &Bvh = self,
            slabs: &[Option<SlabRay>; PACKET] = &slabs,
            packet: SlabPacket = packet,
            ranges: [Interval; PACKET] = lane_ranges,
            active: u32 = active,
            t_max: &mut [f32; PACKET] = &mut t_max,
            test: &mut dyn FnMut(usize, u32, Interval) -> Option<f64> = &mut test,
        ) -> [Option<u32>; PACKET])
    }
}

/// Splits `work` at its median centroid along the centroids' longest axis.
#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// `round_down(x)` is the largest f32 not above `x` and `round_up(x)` the smallest not below,
    /// checked by their definition in f64 (exact for every f32) on zeros of both signs, subnormal
    /// f64s (a range opened at 0 starts at `0.next_up()`), f32 subnormals, normal values and the
    /// ends of the ranges.
    #[test]
    fn rounding_brackets_every_value() {
        let values = [
            0.0,
            -0.0,
            0.0f64.next_up(),
            -(0.0f64.next_up()),
            f64::MIN_POSITIVE.next_down(),
            -f64::MIN_POSITIVE.next_down(),
            f64::MIN_POSITIVE,
            1e-310,
            -1e-310,
            1e-45,
            7e-46,
            -7e-46,
            1.5e-39,
            0.1,
            -0.1,
            1.0,
            3.4e38,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for x in values {
            let down = round_down(x);
            let exact = |r: f32| f64::from(r) == x;
            assert!(
                f64::from(down) <= x && (exact(down) || f64::from(down.next_up()) > x),
                "round_down({x:e}) = {down:e}"
            );
            let up = round_up(x);
            assert!(
                f64::from(up) >= x && (exact(up) || f64::from(up.next_down()) < x),
                "round_up({x:e}) = {up:e}"
            );
        }
    }

    /// The sorting network puts the entered slots first, farthest entry first (entries within 3
    /// ulps, which share a key, in slot order), and among equal entries the earlier slot first,
    /// for every set of entered slots (entries drawn from a few values, so that ties, near-ties,
    /// zeros of both signs, negatives and infinities all occur).
    #[test]
    fn farthest_first_sorts_the_entered_slots() {
        let values = [
            -2.5f32,
            -0.0,
            0.0,
            1e-30,
            1.0,
            1.0 + f32::EPSILON,
            1.5,
            3.0,
            f32::INFINITY,
        ];
        let close = |a: f32, b: f32| a == b || (a.signum() == b.signum() && a.to_bits().abs_diff(b.to_bits()) <= 3);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for _ in 0..2000 {
            let near: [f32; 4] = std::array::from_fn(|_| values[rng.random_range(0..values.len())]);
            for entered in 1u32..16 {
                let got = farthest_first(entered, near);
                let n = entered.count_ones() as usize;
                let mut slots = got[..n].to_vec();
                slots.sort_unstable();
                let want: Vec<usize> = (0..4).filter(|&s| entered & (1 << s) != 0).collect();
                assert_eq!(slots, want, "the entered slots first: {near:?} {entered:04b}");
                for pair in got[..n].windows(2) {
                    let (a, b) = (near[pair[0]], near[pair[1]]);
                    assert!(a > b || close(a, b), "farthest first: {near:?} {entered:04b} {got:?}");
                    if a.to_bits() == b.to_bits() {
                        assert!(pair[0] < pair[1], "ties in slot order: {near:?} {entered:04b} {got:?}");
                    }
                }
            }
        }
    }

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
                let (lo, hi) = (c - h, c + h);
                let node = [
                    [round_down(lo.x), round_down(lo.y), round_down(lo.z)],
                    [round_up(hi.x), round_up(hi.y), round_up(hi.z)],
                ];
                for (axis, (lo, hi)) in node[0].iter().zip(&node[1]).enumerate() {
                    quad.lo[axis][slot] = *lo;
                    quad.hi[axis][slot] = *hi;
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

    /// Above `build::PARALLEL_MIN` items the subtrees are built in parallel; origins beyond
    /// f32 range take the linear scan.
    #[test]
    fn parallel_build_and_far_origins_equal_brute_force() {
        closest_hit_equals_brute_force_with(5 * build::PARALLEL_MIN, 8, -20.0);
        closest_hit_equals_brute_force_with(600, 9, -1e39);
    }

    /// Packets of rays (coherent, scattered, partial, with limited ranges) get exactly the
    /// single-ray walk's answers, exact ties of `t` settled by id in both (boxes sharing faces).
    #[test]
    fn packets_equal_single_rays() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        // a grid of unit boxes (shared faces give exact ties) plus random ones
        let mut boxes: Vec<Aabb> = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                let c = DVec3::new(f64::from(i) - 3.0, f64::from(j) - 3.0, 0.0);
                boxes.push(Aabb::new(c, c + DVec3::ONE));
            }
        }
        for _ in 0..3000 {
            let c = DVec3::new(
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
            );
            let h = DVec3::new(
                rng.random_range(0.01..0.5),
                rng.random_range(0.01..0.5),
                rng.random_range(0.01..0.5),
            );
            boxes.push(Aabb::new(c - h, c + h));
        }
        let items: Vec<(Aabb, u32)> = boxes.iter().enumerate().map(|(i, b)| (*b, i as u32)).collect();
        let bvh = Bvh::build(&items);
        let entry = |b: &Aabb, ray: &Ray, range: Interval| b.clip(ray, range).map(|r| r.min);
        // the closest box, exact ties going to the smaller id
        let settle = |best: Option<u32>, id: u32, t: f64, range: Interval| t < range.max || best.is_none_or(|b| id < b);
        for round in 0..3000 {
            let n = if round % 5 == 0 {
                rng.random_range(1..=PACKET)
            } else {
                PACKET
            };
            let eye = DVec3::new(rng.random_range(-12.0..12.0), rng.random_range(-12.0..12.0), -15.0);
            let spread = if round % 2 == 0 { 0.01 } else { 1.0 };
            let rays: Vec<Ray> = (0..n)
                .map(|_| {
                    let d = DVec3::new(
                        rng.random_range(-spread..spread),
                        rng.random_range(-spread..spread),
                        1.0,
                    );
                    Ray::new(eye, d)
                })
                .collect();
            let ranges: Vec<Interval> = (0..n)
                .map(|_| {
                    if rng.random_bool(0.2) {
                        Interval::new(10.0, 16.0)
                    } else {
                        Interval::POSITIVE
                    }
                })
                .collect();
            let single: Vec<Option<u32>> = (0..n)
                .map(|l| {
                    let mut best = None;
                    bvh.closest(&rays[l], ranges[l], |id, r| {
                        let t = entry(&boxes[id as usize], &rays[l], r)?;
                        settle(best, id, t, r).then(|| {
                            best = Some(id);
                            t
                        })
                    })
                })
                .collect();
            let mut best = [None; PACKET];
            let packet = bvh.closest_packet(&rays, &ranges, |l, id, r| {
                let t = entry(&boxes[id as usize], &rays[l], r)?;
                settle(best[l], id, t, r).then(|| {
                    best[l] = Some(id);
                    t
                })
            });
            assert_eq!(&packet[..n], &single[..], "rays {rays:?}");
            assert!(packet[n..].iter().all(Option::is_none));
        }
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
