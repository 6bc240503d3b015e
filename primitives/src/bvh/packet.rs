//! The ordered walk of a packet of up to [`PACKET`] rays over 4-wide nodes ([`walk_packet`]):
//! a child is visited by the lanes that enter it, nearest first by its nearest lane's entry; a
//! lane whose closest hit moved nearer than its entry drops out when the child is popped; a node
//! entered by few lanes is handed to each lane's single-ray walk ([`PacketVisitor::alone`]).
//! The hierarchy's user supplies the slab and leaf tests ([`PacketVisitor`]).

use super::lanes::{lane_mask, min_f32};
use super::quad::Quad;
use super::walk::{cull_bound, QUAD_STACK};
use crate::PACKET;
use std::mem::MaybeUninit;

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
