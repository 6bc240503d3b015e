//! Interleaved walks: the rays of a batch that enter a large mesh walk its 8-wide nodes
//! [`IN_FLIGHT`] at a time, one step each in turn.
//!
//! Why. On a mesh many times the cache a single ray's walk waits on memory at almost every step:
//! the children of a node are requested as soon as they are entered (`prefetch_children`), but
//! the walk visits the nearest one right after and waits for it. Random rays entering the level-8
//! bench mesh (1.3 million triangles) spent most of their time in those waits. Here each
//! ray in flight takes one step in turn (a node opened or a leaf tested) and then requests what
//! its next step reads (that node's four cache lines or that leaf's rows), which arrives while
//! the other rays take theirs: the misses of several rays overlap instead of following one
//! another. Only the next step's item is requested (pushed children when they come up: most are
//! culled first, and requests for all would fill the core's miss buffers with lines never
//! read). A hit's first read when finished (its file index) is requested when the candidate is
//! found, and the hit is finished a round after the ray's last step.
//!
//! The gain is large on the level-8 mesh and small on level 6, whose nodes and rows fit in the
//! L3 cache (see docs/performance.md).
//!
//! Same answers. Each ray walks exactly as the single-ray walk does ([`super::oct::Octs::traverse`]:
//! the same node tests, the same order of visits, the same culling at
//! [`crate::bvh::cull_bound`], the same leaf test [`Mesh::leaf_closest`] and
//! [`Mesh::finish`]); only the steps of different rays are interleaved. The closest hit is the
//! smallest `(t, leaf position)` whatever the order of visits anyway.
//!
//! Where. Only where the nodes outgrow a core's L2 cache ([`worth_prefetching`]): in a mesh that
//! fits there, a ray's walk does not wait on memory, and keeping its state in memory between
//! steps (rather than in registers) only costs (slower on the level-4 mesh, see docs/performance.md).
//! There each ray walks alone ([`single_ray`], less the ball test already made).
//!
//! The ball first. Either way, a batch is judged [`BLOCK`] rays at a time by the ball test
//! ([`Mesh::misses_ball`]) before any walk is set up, four rays at once
//! ([`Mesh::misses_ball4`]: the one-ray test for each of four rays, which the AVX2 copy runs
//! four wide); only the rays it keeps ([`Passing`]) are walked, the others are misses. Most
//! of a random batch ends there (see docs/performance.md).

use super::query::{Candidate, MeshQuery};
use super::storage::Mesh;
use super::walk::single_ray_in_ball;
use crate::bvh::oct::{push_entered_unbranched, Oct, OCT_STACK};
use crate::bvh::prefetching::{prefetch, prefetch_node, worth_prefetching};
use crate::bvh::walk::{cull_bound, next_within, Pending};
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use std::mem::MaybeUninit;

/// Rays walked at once: enough that the other rays' steps cover one ray's miss to memory (fewer
/// were slower on the level-8 bench mesh, more no faster; see docs/performance.md).
const IN_FLIGHT: usize = 8;

/// Rays of a batch judged together by [`Mesh::passing`] (at most).
const BLOCK: usize = 256;

/// Which rays of a block (at most [`BLOCK`]) may meet the mesh, a bit each: those that do not
/// surely pass it by ([`Mesh::misses_ball`]). Most rays of a random batch surely do, and are
/// answered without a walk being set up.
struct Passing {
    bits: [u64; BLOCK / 64],
}

impl Passing {
    /// The lowest ray left, taken.
    #[inline(always)]
    fn take_next(&mut self) -> Option<usize> {
        for (w, word) in self.bits.iter_mut().enumerate() {
            if *word != 0 {
                let bit = word.trailing_zeros() as usize;
                *word &= *word - 1;
                return Some(64 * w + bit);
            }
        }
        None
    }
}

impl Mesh {
    /// The rays of `rays` (at most [`BLOCK`]) that may meet the mesh: [`Mesh::misses_ball`]
    /// four rays at a time ([`Mesh::misses_ball4`], the same answers), the rest one by one.
    #[inline(always)]
    fn passing(&self, rays: &[Ray], ranges: &[Interval]) -> Passing {
        assert!(
            rays.len() <= BLOCK && ranges.len() == rays.len(),
            "a block of rays and their ranges"
        );
        let mut bits = [0u64; BLOCK / 64];
        let whole = rays.len() / 4 * 4;
        for (g, (four, four_ranges)) in rays[..whole]
            .chunks_exact(4)
            .zip(ranges[..whole].chunks_exact(4))
            .enumerate()
        {
            let miss = self.misses_ball4(four, four_ranges);
            let nibble = (0..4).fold(0u64, |m, l| m | u64::from(!miss[l]) << l);
            bits[g / 16] |= nibble << (4 * (g % 16));
        }
        for i in whole..rays.len() {
            if !self.misses_ball(&rays[i], ranges[i]) {
                bits[i / 64] |= 1 << (i % 64);
            }
        }
        Passing { bits }
    }
}

/// A ray's walk in progress, between two of its steps.
struct Flight<'a> {
    mesh: &'a Mesh,
    octs: &'a [Oct],
    ray: &'a Ray,
    range: Interval,
    /// The ray's place in the batch.
    index: usize,
    query: MeshQuery,
    /// The closest candidate so far and its `t` (the query's `t_max` before one is found).
    best: Option<Candidate>,
    t_max: f32,
    /// What the next step visits: an inner node or a leaf, requested from memory already.
    next: Pending,
    /// Entries in use on the ray's stack.
    top: usize,
    /// Whether the walk is over (the hit is finished at the ray's next turn).
    landed: bool,
}

impl Flight<'_> {
    /// Opens node `o`, whose entered slots are `hits` (entries `near`): all but the nearest pushed,
    /// then the next item to visit taken ([`Flight::advance`]). `false` once the walk is over.
    #[inline(always)]
    fn open(&mut self, o: &Oct, hits: u32, near: &[f32; 8], stack: &mut [MaybeUninit<Pending>]) -> bool {
        let next = push_entered_unbranched(o, hits, near, stack, &mut self.top);
        self.advance(next, stack)
    }

    /// Takes `next`, else the top of the stack, skipping entries farther than
    /// [`cull_bound`]`(t_max)` ([`next_within`], as the single walk), as the item of the ray's
    /// next step, and asks memory for it. `false` once the stack is empty.
    #[inline(always)]
    fn advance(&mut self, next: Option<Pending>, stack: &[MaybeUninit<Pending>]) -> bool {
        let Some(item) = next_within(stack, &mut self.top, next, self.t_max) else {
            return false;
        };
        self.next = item;
        self.request(item);
        true
    }

    /// Asks memory for what visiting `item` reads: the node's four cache lines, or the leaf's
    /// rows. Only the item of the next step is requested, a round of the other rays' steps
    /// ahead; children pushed are requested when they come up (most are culled before: a
    /// request for each would fill the core's miss buffers with lines never read).
    #[inline(always)]
    fn request(&self, (child, count, _): Pending) {
        if count == 0 {
            prefetch_node(self.octs, child as usize);
        } else {
            self.mesh.prefetch_leaf(child, count);
        }
    }

    /// One step: the node or leaf `next` visited. `false` once the walk is over.
    #[inline(always)]
    fn step(&mut self, stack: &mut [MaybeUninit<Pending>]) -> bool {
        let (child, count, _) = self.next;
        if count == 0 {
            let o = &self.octs[child as usize];
            let (entered, near) = self.query.ray.slab.entry8(o, self.query.t_min, cull_bound(self.t_max));
            return self.open(o, entered & o.occupied(), &near, stack);
        }
        let axes = self.query.ray.k;
        let found = self.mesh.leaf_closest(
            self.ray,
            self.range,
            &self.query,
            axes,
            child,
            count,
            self.t_max,
            &mut self.best,
        );
        if let Some(t) = found {
            self.t_max = t;
            // what finishing the hit reads first, requested now (it is read after a round)
            if let Some(best) = &self.best {
                prefetch(self.mesh.leaf_to_file.as_ptr().wrapping_add(best.k()));
            }
        }
        self.advance(None, stack)
    }
}

impl Mesh {
    /// The next ray of `passing` that enters the root's children, its walk started (the root
    /// opened); the rays of `passing` taken before it miss the mesh (their hits are `None`
    /// already). `None` once `passing` is used up.
    #[inline(always)]
    fn take_off<'a>(
        &'a self,
        rays: &'a [Ray],
        ranges: &[Interval],
        passing: &mut Passing,
        stack: &mut [MaybeUninit<Pending>],
    ) -> Option<Flight<'a>> {
        while let Some(index) = passing.take_next() {
            let (ray, range) = (&rays[index], ranges[index]);
            let Some((entry, (entered, near))) = self.walk_start_in_ball(ray, range) else {
                continue;
            };
            let query = entry.query();
            let octs = self.octs().nodes();
            let mut flight = Flight {
                mesh: self,
                octs,
                ray,
                range,
                index,
                t_max: query.t_max,
                query,
                best: None,
                next: (0, 0, 0.0),
                top: 0,
                landed: false,
            };
            if flight.open(&octs[0], entered, &near, stack) {
                return Some(flight);
            }
        }
        None
    }

    /// The closest hit of each ray of `rays` over its range in `ranges`, into `hits`: the same
    /// answers as [`single_ray`] ray by ray, the walks of [`IN_FLIGHT`] rays interleaved (see the
    /// module docs) where the nodes outgrow the L2 cache.
    #[inline(always)]
    pub(super) fn intersect_stream(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>]) {
        let octs = self.octs().nodes();
        if !worth_prefetching(octs) {
            for ((rays, ranges), hits) in rays.chunks(BLOCK).zip(ranges.chunks(BLOCK)).zip(hits.chunks_mut(BLOCK)) {
                let mut passing = self.passing(rays, ranges);
                hits.fill(None);
                while let Some(i) = passing.take_next() {
                    hits[i] = single_ray_in_ball(self, &rays[i], ranges[i]);
                }
            }
            return;
        }
        self.interleaved(rays, ranges, hits);
    }

    /// The interleaved walks of [`Mesh::intersect_stream`], whatever the size of the nodes, a
    /// block of [`BLOCK`] rays at a time.
    #[inline(always)]
    pub(super) fn interleaved(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>]) {
        // uninitialised: only entries below a flight's `top`, written before, are ever read
        let mut stacks = [const { [const { MaybeUninit::<Pending>::uninit() }; OCT_STACK] }; IN_FLIGHT];
        for ((rays, ranges), hits) in rays.chunks(BLOCK).zip(ranges.chunks(BLOCK)).zip(hits.chunks_mut(BLOCK)) {
            let mut passing = self.passing(rays, ranges);
            hits.fill(None);
            self.interleaved_block(rays, ranges, hits, &mut passing, &mut stacks);
        }
    }

    /// [`Mesh::interleaved`] on one block, whose rays that may meet the mesh are `passing` (the
    /// others' `hits` are `None` already).
    #[inline(always)]
    fn interleaved_block(
        &self,
        rays: &[Ray],
        ranges: &[Interval],
        hits: &mut [Option<RawHit>],
        passing: &mut Passing,
        stacks: &mut [[MaybeUninit<Pending>; OCT_STACK]; IN_FLIGHT],
    ) {
        let mut flights: [Option<Flight<'_>>; IN_FLIGHT] = std::array::from_fn(|_| None);
        let mut flying = 0;
        for (flight, stack) in flights.iter_mut().zip(stacks.iter_mut()) {
            *flight = self.take_off(rays, ranges, passing, stack);
            flying += usize::from(flight.is_some());
        }
        while flying > 0 {
            for (slot, stack) in flights.iter_mut().zip(stacks.iter_mut()) {
                let Some(flight) = slot else { continue };
                if !flight.landed {
                    flight.landed = !flight.step(stack);
                    continue;
                }
                // finished a round after its last step, when its first read has arrived
                hits[flight.index] = self.finish(flight.ray, flight.range, &flight.query, flight.best);
                *slot = self.take_off(rays, ranges, passing, stack);
                flying -= usize::from(slot.is_none());
            }
        }
    }
}
