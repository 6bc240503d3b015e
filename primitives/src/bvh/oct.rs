//! 8-wide nodes for the single-ray walk over a mesh: the 4-wide hierarchy ([`Quad`]s, from the
//! one builder) collapsed so that each node holds up to eight child boxes.
//!
//! Why. A ray walking a mesh's quads waits at every node for the next one: on a cache-resident
//! mesh for the slab test and the choice of child, on a mesh many times the cache for memory too
//! (see docs/performance.md). Eight children a node take fewer levels, so fewer waits. The eight
//! slab tests are one loop that the AVX2 copy of the walk ([`crate::with_fma!`]) computes 8 wide,
//! so an oct costs about what a quad did there (two explicit SSE halves did not).
//!
//! Same hits. The boxes are the quads' own child boxes moved up a level and the leaves are the
//! quads' leaves (the same items, the same leaf order), so the walk meets the same candidates and
//! keeps the same closest hit, the smallest `(t, leaf position)`, whatever the order of visits
//! (see [`super::walk::cull_bound`]).
//!
//! Collapse. Each oct starts from a quad's slots; while there is room, the inner slot of largest
//! surface area whose quad's slots fit in the room left is replaced by those slots (the greedy rule
//! that made the quads from the binary SAH splits). Octs are laid out depth first from the root
//! `octs[0]`.
//!
//! Traversal ([`Octs::traverse`]): as [`super::walk::traverse_quads`]; the entered children are ordered
//! farthest first by insertion (one or two entered children, the common case, take no loop), and
//! the entered inner children's nodes are requested from memory as soon as they are known.

use super::lanes::{lane_mask, max_f32, min_f32};
use super::prefetching::worth_prefetching;
use super::quad::Quad;
use super::slab::{SlabRay, EXIT_PAD};
use super::walk::{cull_bound, nearer_of_two, next_inner_node, prefetch_children, LeafTest, Pending, QUAD_STACK};
use std::mem::MaybeUninit;

/// An 8-wide node: up to eight children's f32 boxes in SoA layout (`SlabRay::entry8` tests all
/// eight in one pass). `count[i] = 0` marks an inner child (its oct is `child[i]`), `count[i] > 0` a leaf of
/// that many items from `child[i]`; slots beyond `len` are empty. 256 bytes: four cache lines.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Oct {
    pub lo: [[f32; 8]; 3],
    pub hi: [[f32; 8]; 3],
    pub child: [u32; 8],
    pub count: [u16; 8],
    pub len: u32,
}

impl Oct {
    /// Slot `s` as a stack entry, with its entry distance `near[s]`.
    #[inline(always)]
    fn pending(&self, s: usize, near: &[f32; 8]) -> Pending {
        (self.child[s], u32::from(self.count[s]), near[s])
    }

    /// A bit for each slot in use (`0..len`).
    #[inline(always)]
    pub(crate) fn occupied(&self) -> u32 {
        (1u32 << self.len) - 1
    }
}

/// Traversal stack capacity: at most 7 entries left per level over at most as many levels as the
/// quads have (each oct level spans at least one quad level), plus 8.
pub(crate) const OCT_STACK: usize = 7 * (QUAD_STACK / 3) + 8;

/// The octs of one hierarchy, root first (empty for an empty hierarchy).
#[derive(Clone, Debug, Default)]
pub(crate) struct Octs {
    nodes: Vec<Oct>,
}

/// One child slot while a node is gathered: its box, and `(child, count)` as in a node.
#[derive(Clone, Copy)]
struct Slot {
    lo: [f32; 3],
    hi: [f32; 3],
    child: u32,
    count: u16,
}

impl Slot {
    /// Slot `s` of `quad`.
    fn of(quad: &Quad, s: usize) -> Self {
        let (lo, hi) = quad.slot_bounds(s);
        Self {
            lo,
            hi,
            child: quad.child[s],
            count: quad.count[s],
        }
    }

    /// Half the surface area of its box (in f64: the comparison only steers the collapse).
    fn half_area(&self) -> f64 {
        let d: [f64; 3] = std::array::from_fn(|a| f64::from(self.hi[a]) - f64::from(self.lo[a]));
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

impl Octs {
    /// The octs of the 4-wide hierarchy `quads` (root `quads[0]`, `used` of them in use; see the
    /// module docs). Room for `used` octs is reserved up front (there are never more octs than
    /// quads), so the nodes are written once, never moved; the part of that room left unused is
    /// address space the process never touches, not memory ([`Octs::memory_bytes`] counts the
    /// octs written).
    pub(crate) fn collapse(quads: &[Quad], used: usize) -> Self {
        let mut nodes = Vec::with_capacity(used.max(1));
        if !quads.is_empty() {
            emit(quads, 0, &mut nodes);
        }
        Self { nodes }
    }

    /// The nodes, root first.
    #[inline(always)]
    pub(crate) fn nodes(&self) -> &[Oct] {
        &self.nodes
    }

    /// Bytes of the octs written (the reserved room beyond them is never touched, see
    /// [`Octs::collapse`]).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Oct>()
    }

    /// The root's slab test (`None` for an empty hierarchy): the entered slots and their entry
    /// distances, as the walk's first step makes it (culling at [`cull_bound`]`(t_max)`), so a
    /// caller can test the root first and hand the result to [`Octs::traverse`].
    #[inline(always)]
    pub(crate) fn root_entry(&self, ray: &SlabRay, t_min: f32, t_max: f32) -> Option<(u32, [f32; 8])> {
        let root = self.nodes.first()?;
        let (entered, near) = ray.entry8(root, t_min, cull_bound(t_max));
        Some((entered & root.occupied(), near))
    }

    /// Ordered closest-hit walk from the root, whose slab test `root` ([`Octs::root_entry`] of
    /// the same ray and range) is already made: the nearest entered child is visited next and
    /// the others pushed farthest first; one popped after the closest hit moved nearer than its
    /// entry (by more than [`cull_bound`]'s margin) is skipped. `leaf(first, count, t_max)` tests
    /// a leaf and returns the new, smaller `t_max` if it found a hit.
    #[inline(always)]
    pub(crate) fn traverse(
        &self,
        ray: &SlabRay,
        t_min: f32,
        mut t_max: f32,
        root: (u32, [f32; 8]),
        mut leaf: impl LeafTest,
    ) {
        let octs = self.nodes();
        let prefetch = worth_prefetching(octs);
        // uninitialised: only entries below `top`, written before, are ever read
        let mut stack = [const { MaybeUninit::<Pending>::uninit() }; OCT_STACK];
        let mut top = 0usize;
        let mut node = 0usize;
        let mut tested = Some(root);
        loop {
            let o = &octs[node];
            let (hits, near) = match tested.take() {
                Some(root) => root,
                None => {
                    let (entered, near) = ray.entry8(o, t_min, cull_bound(t_max));
                    (entered & o.occupied(), near)
                }
            };
            if prefetch {
                prefetch_children(octs, &o.child, &o.count, hits, &leaf);
            }
            let next = push_entered(o, hits, &near, &mut stack, &mut top);
            match next_inner_node(&stack, &mut top, next, &mut t_max, &mut leaf) {
                Some(inner) => node = inner,
                None => return,
            }
        }
    }
}

/// The step of the ordered walks at an opened node `o` whose entered slots are `hits` (entries
/// `near`): the nearest entered child is returned (`None` if none), to be visited next, and the
/// others pushed onto `stack[..top]` farthest first, so that they pop nearest first. One or two
/// entered children, the common case, take no loop; three to eight are sorted by insertion (among
/// equal entries the later slot after the earlier, so visited first).
#[inline(always)]
pub(crate) fn push_entered(
    o: &Oct,
    hits: u32,
    near: &[f32; 8],
    stack: &mut [MaybeUninit<Pending>],
    top: &mut usize,
) -> Option<Pending> {
    let slot = |s: usize| o.pending(s, near);
    if hits == 0 {
        return None;
    }
    let first = hits.trailing_zeros() as usize;
    let rest = hits & (hits - 1);
    if rest == 0 {
        return Some(slot(first));
    }
    if rest & (rest - 1) == 0 {
        // two: the farther pushed, the nearer next
        let (nearer, farther) = nearer_of_two(first, rest.trailing_zeros() as usize, near);
        stack[*top].write(slot(farther));
        *top += 1;
        return Some(slot(nearer));
    }
    push_sorted(o, hits, near, stack, top)
}

/// [`push_entered`] without a branch on whether none, one or two children are entered (the
/// cases of five nodes in six): the farther of two is written in any case and kept by raising
/// `top` only where there are two (with one, it is that one, written and dropped; with none,
/// slot 0, read and dropped; the entry written beyond the stack's top is within the room that
/// [`OCT_STACK`] keeps beyond the deepest walk). The same pushes and the same answer.
///
/// For the interleaved walks (`mesh/stream.rs`), whose random rays mispredicted those branches
/// about twice a ray. The single walk keeps the branches: there the extra instructions cost what
/// the mispredictions did (see docs/performance.md).
#[inline(always)]
pub(crate) fn push_entered_unbranched(
    o: &Oct,
    hits: u32,
    near: &[f32; 8],
    stack: &mut [MaybeUninit<Pending>],
    top: &mut usize,
) -> Option<Pending> {
    let count = hits.count_ones();
    if count > 2 {
        return push_sorted(o, hits, near, stack, top);
    }
    let slot = |s: usize| o.pending(s, near);
    // `& 7`: slot 0 where there is none (32 trailing zeros)
    let first = hits.trailing_zeros() as usize & 7;
    let rest = hits & hits.wrapping_sub(1);
    let second = if rest == 0 {
        first
    } else {
        rest.trailing_zeros() as usize & 7
    };
    let (nearer, farther) = nearer_of_two(first, second, near);
    stack[*top].write(slot(farther));
    *top += usize::from(count == 2);
    (count != 0).then(|| slot(nearer))
}

/// [`push_entered`] of three or more entered children (`hits`): sorted by insertion, the
/// nearest returned, the others pushed farthest first.
#[inline(always)]
fn push_sorted(
    o: &Oct,
    hits: u32,
    near: &[f32; 8],
    stack: &mut [MaybeUninit<Pending>],
    top: &mut usize,
) -> Option<Pending> {
    let slot = |s: usize| o.pending(s, near);
    let mut order = [0usize; 8];
    let mut entered = 0;
    let mut slots = hits;
    while slots != 0 {
        let s = slots.trailing_zeros() as usize;
        slots &= slots - 1;
        let mut i = entered;
        while i > 0 && near[order[i - 1]] < near[s] {
            order[i] = order[i - 1];
            i -= 1;
        }
        order[i] = s;
        entered += 1;
    }
    for &s in &order[..entered - 1] {
        stack[*top].write(slot(s));
        *top += 1;
    }
    Some(slot(order[entered - 1]))
}

/// Writes the oct for `quads[q]` and, depth first after it, those of its inner children; returns
/// its index.
fn emit(quads: &[Quad], q: usize, nodes: &mut Vec<Oct>) -> u32 {
    let quad = &quads[q];
    let mut slots = [Slot::of(quad, 0); 8];
    let mut len = quad.len as usize;
    for (s, slot) in slots.iter_mut().enumerate().take(len).skip(1) {
        *slot = Slot::of(quad, s);
    }
    // open the largest inner slot whose quad fits in the room left, while any does
    loop {
        let open = (0..len)
            .filter(|&s| slots[s].count == 0 && len - 1 + quads[slots[s].child as usize].len as usize <= 8)
            .max_by(|&a, &b| slots[a].half_area().total_cmp(&slots[b].half_area()));
        let Some(s) = open else { break };
        let inner = &quads[slots[s].child as usize];
        slots[s] = Slot::of(inner, 0);
        for k in 1..inner.len as usize {
            slots[len] = Slot::of(inner, k);
            len += 1;
        }
    }
    let index = nodes.len();
    nodes.push(Oct::default());
    let mut oct = Oct {
        len: len as u32,
        ..Oct::default()
    };
    for (i, slot) in slots[..len].iter().enumerate() {
        for axis in 0..3 {
            oct.lo[axis][i] = slot.lo[axis];
            oct.hi[axis][i] = slot.hi[axis];
        }
        oct.count[i] = slot.count;
        oct.child[i] = if slot.count == 0 {
            emit(quads, slot.child as usize, nodes)
        } else {
            slot.child
        };
    }
    nodes[index] = oct;
    index as u32
}

impl SlabRay {
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
        (lane_mask(&inside), near)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{Bb, BuildItem, Leaves};
    use crate::bvh::quad_bvh::QuadBvh;
    use glam::Vec3A;
    use rand::{Rng, SeedableRng};

    /// `push_entered_unbranched` makes the same pushes and gives the same next item as
    /// `push_entered` for every set of entered slots, entries with ties among them.
    #[test]
    fn unbranched_push_equals_push_entered() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut oct = Oct {
            len: 8,
            ..Oct::default()
        };
        for s in 0..8 {
            oct.child[s] = 100 + s as u32;
            oct.count[s] = (s % 3) as u16;
        }
        let bits = |p: &Pending| (p.0, p.1, p.2.to_bits());
        for round in 0..4000 {
            let hits = (round % 256) as u32;
            // few distinct values: equal entries are common
            let near: [f32; 8] = std::array::from_fn(|_| f32::from(rng.random_range(0u8..4)) * 0.5);
            let start = rng.random_range(0..5);
            type Push = fn(&Oct, u32, &[f32; 8], &mut [MaybeUninit<Pending>], &mut usize) -> Option<Pending>;
            let run = |push: Push| {
                let mut stack = [MaybeUninit::new((7u32, 7u32, -1.0f32)); 16];
                let mut top = start;
                let next = push(&oct, hits, &near, &mut stack, &mut top);
                // SAFETY: every entry was initialised above
                let pushed: Vec<_> = stack[..top].iter().map(|e| bits(&unsafe { e.assume_init() })).collect();
                (next.as_ref().map(bits), pushed)
            };
            assert_eq!(
                run(push_entered),
                run(push_entered_unbranched),
                "hits {hits:08b}, near {near:?}"
            );
        }
    }

    /// The quads over `count` random boxes (leaves of at most 6 items).
    fn quads(count: usize, seed: u64) -> QuadBvh {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut items: Vec<BuildItem> = (0..count as u32)
            .map(|id| {
                let c = Vec3A::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-1.0..1.0),
                );
                let h = Vec3A::new(
                    rng.random_range(0.0..0.5),
                    rng.random_range(0.0..0.5),
                    rng.random_range(0.0..0.5),
                );
                BuildItem::new(Bb { lo: c - h, hi: c + h }, id)
            })
            .collect();
        QuadBvh::build(&mut items, Leaves::per_item(6))
    }

    /// A leaf as a node holds it: `(first, count, lo, hi)`.
    type Leaf = (u32, u16, [f32; 3], [f32; 3]);

    /// The leaves reachable from the root of a hierarchy whose node `i` has `len(i)` slots, slot
    /// `s` reading as `slot(i, s) = (child, count, lo, hi)`; and the number of nodes reached.
    fn leaves(len: impl Fn(usize) -> usize, slot: impl Fn(usize, usize) -> Leaf) -> (Vec<Leaf>, usize) {
        let (mut found, mut nodes, mut pending) = (Vec::new(), 0, vec![0usize]);
        while let Some(i) = pending.pop() {
            nodes += 1;
            for s in 0..len(i) {
                let leaf = slot(i, s);
                if leaf.1 == 0 {
                    pending.push(leaf.0 as usize);
                } else {
                    found.push(leaf);
                }
            }
        }
        found.sort_by_key(|l| l.0);
        (found, nodes)
    }

    /// The octs hold exactly the quads' leaves, each with its own box, in nodes of 1 to 8 slots,
    /// every oct reached from the root once, and fewer of them than there are quads.
    #[test]
    fn collapse_keeps_every_leaf_with_its_box() {
        for (count, seed) in [(1, 1), (2, 2), (7, 3), (100, 4), (5000, 5)] {
            let bvh = quads(count, seed);
            let octs = Octs::collapse(bvh.quads(), bvh.quad_count());
            let (q, o) = (bvh.quads(), octs.nodes());
            let (quad_leaves, quads_reached) = leaves(
                |i| q[i].len as usize,
                |i, s| {
                    let n = &q[i];
                    let lo = [n.lo[0][s], n.lo[1][s], n.lo[2][s]];
                    (n.child[s], n.count[s], lo, [n.hi[0][s], n.hi[1][s], n.hi[2][s]])
                },
            );
            let (oct_leaves, octs_reached) = leaves(
                |i| o[i].len as usize,
                |i, s| {
                    let n = &o[i];
                    let lo = [n.lo[0][s], n.lo[1][s], n.lo[2][s]];
                    (n.child[s], n.count[s], lo, [n.hi[0][s], n.hi[1][s], n.hi[2][s]])
                },
            );
            assert_eq!(oct_leaves, quad_leaves, "{count} items");
            assert_eq!(quad_leaves.iter().map(|l| u32::from(l.1)).sum::<u32>(), count as u32);
            assert_eq!(octs_reached, o.len(), "every oct is reached once");
            assert!(o.iter().all(|n| (1..=8).contains(&n.len)));
            assert!(
                count < 100 || o.len() * 3 < quads_reached * 2,
                "{} octs for {quads_reached} quads",
                o.len()
            );
        }
    }

    /// The 8-wide slab test gives, bit for bit, what the 4-wide one gives for the same boxes.
    #[test]
    fn eight_wide_entry_equals_four_wide() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let bvh = quads(3000, 9);
        let octs = Octs::collapse(bvh.quads(), bvh.quad_count());
        for _ in 0..20_000 {
            let origin = Vec3A::new(
                rng.random_range(-12.0..12.0),
                rng.random_range(-12.0..12.0),
                rng.random_range(-3.0..3.0),
            );
            let mut dir = Vec3A::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if rng.random_bool(0.2) {
                dir.z = 0.0;
            }
            let oct = &octs.nodes()[rng.random_range(0..octs.nodes().len())];
            if rng.random_bool(0.4) {
                // through a corner of one of the boxes: entry and exit meet there, and only the
                // exit's enlargement decides whether the box is entered
                let s = rng.random_range(0..oct.len as usize);
                let mut pick = |axis: usize| {
                    if rng.random_bool(0.5) {
                        oct.lo[axis][s]
                    } else {
                        oct.hi[axis][s]
                    }
                };
                dir = Vec3A::new(pick(0), pick(1), pick(2)) - origin;
            }
            let ray = SlabRay::new(origin, dir);
            let (t0, t1) = (rng.random_range(0.0..0.5), rng.random_range(1.0..40.0));
            let (hits, near) = ray.entry8(oct, t0, t1);
            for half in 0..2 {
                let mut quad = Quad {
                    len: 4,
                    ..Quad::default()
                };
                for s in 0..4 {
                    for axis in 0..3 {
                        quad.lo[axis][s] = oct.lo[axis][4 * half + s];
                        quad.hi[axis][s] = oct.hi[axis][4 * half + s];
                    }
                }
                let (four_hits, four_near) = ray.entry4(&quad, t0, t1);
                assert_eq!((hits >> (4 * half)) & 0b1111, four_hits);
                for s in 0..4 {
                    assert_eq!(near[4 * half + s].to_bits(), four_near[s].to_bits());
                }
            }
        }
    }
}
