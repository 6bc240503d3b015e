//! The built 4-wide hierarchy ([`QuadBvh`], made by `build.rs`) and what it answers without a
//! ray: its leaves, the boxes some levels down, the leaf slots (all, or pruned by a predicate,
//! walked in parallel), and the depth-first nearest-point walk ([`QuadBvh::nearest`]).
//!
//! Layout. A quad's slot `s` is a leaf when `count[s] > 0` (items `child[s]..child[s] +
//! count[s]` of the leaf order) and otherwise refers to the quad `child[s]`; quads are laid out
//! depth first from the root `quads[0]`, and the root's box is kept apart ([`Node`]). Items are
//! referred to by their position in leaf order.

use super::quad::Quad;
use super::quad_array::QuadArray;
use crate::traits::Wanted;
use rayon::prelude::*;

/// A node (see the module docs).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(crate) struct Node {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

/// The hierarchy; triangles are referred to by their position in leaf order. Closest-hit
/// traversal and nearest-point queries both walk the 4-wide `quads`; `root` is the box of
/// everything. Subtrees built in parallel leave unused, zero nodes after their own (see
/// [`QuadArray`]); no slot refers to those.
#[derive(Clone, Debug, Default)]
pub(crate) struct QuadBvh {
    pub root: Node,
    pub(super) quads: QuadArray,
    /// The nodes in use (the others are the parallel subtrees' unused room).
    pub(super) used: usize,
}

impl QuadBvh {
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
