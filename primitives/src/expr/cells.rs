//! An octree of a box that knows, cell by cell, whether Φ may vanish there, and with which
//! pruned tape: built once, shared by every ray (and point query) that crosses the box.
//!
//! **Built** by interval evaluation (`Tape::eval_choices`) over each cell grown by a margin
//! `m` on every side: a cell whose enclosure of Φ excludes 0 (and is defined) holds no point of
//! the zero set and is marked **empty** (Φ > 0 all over it, or Φ < 0 all over it); otherwise it
//! is split in eight, each child evaluated with the tape pruned over its parent (Keeter 2020,
//! "Massively parallel rendering of complex closed-form implicit surfaces"; libfive), down to
//! [`MIN_LEAF_DEPTH`] levels (or [`MAX_DEPTH`] where the cell's gradients point in too wide a
//! cone), where a **leaf** keeps the tape pruned over itself and enclosures of
//! the partial derivatives of Φ over its grown cell ([`CellTree::leaf_gradient`]: a ray whose
//! slope `∇Φ·d` they prove non-zero is monotone across the whole leaf). A pruned tape gives
//! the full tape's values bit for bit inside its grown cell ([`crate::expr::tape`]).
//!
//! **Walked** front to back along a ray ([`CellTree::walk`]): the ray's parameter range is cut
//! at the cells' mid-planes, and every `t` of the range is handed to exactly one leaf or empty
//! cell (the cuts are computed values, so the pieces cover the range with no gap whatever the
//! rounding). A point `o + t·d` handed to a cell lies in it up to the rounding of the cuts,
//! which the margin covers whenever [`CellTree::margin_covers`] says so; a caller that cannot
//! rely on it (an origin far beyond the box's scale) evaluates the full tape instead.

use super::tape::{Choice, Tape};
use super::Jet;
use crate::math::enclosure::Enclosure;
use glam::DVec3;
use std::sync::Arc;

/// Levels of the octree below its root (a leaf is `1/2^MAX_DEPTH` of the box on each axis).
pub const MAX_DEPTH: u32 = 7;

/// Levels below which a cell is always split: from here on a cell whose gradients lie in a
/// narrow cone is a leaf already (rays crossing it are monotone there, except
/// for nearly tangent ones).
pub const MIN_LEAF_DEPTH: u32 = 6;

/// Margin added on every side of a cell before its interval evaluation, relative to the box's
/// diagonal.
const MARGIN: f64 = 1e-6;

/// A cell of the tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cell {
    /// Φ cannot vanish in the (grown) cell.
    Empty,
    /// Eight children, at this index of the node table (bit 0: upper x half, 1: y, 2: z).
    Inner(u32),
    /// A leaf with this index into the leaf table.
    Leaf(u32),
}

/// The octree (see the module docs).
#[derive(Debug)]
pub struct CellTree {
    lo: DVec3,
    hi: DVec3,
    margin: f64,
    root: Cell,
    nodes: Vec<[Cell; 8]>,
    tapes: Vec<Arc<Tape>>,
    leaves: Vec<Leaf>,
}

/// A leaf: its cell grown by the margin, its tape's index, and enclosures of the partial
/// derivatives `∂Φ/∂x, ∂Φ/∂y, ∂Φ/∂z` over the grown cell.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    lo: DVec3,
    hi: DVec3,
    tape: u32,
    gradient: [Enclosure; 3],
}

/// A cell as built, before the tables are laid out.
enum Built {
    Empty,
    Leaf(Arc<Tape>, DVec3, DVec3, [Enclosure; 3]),
    Inner(Box<[Built; 8]>),
}

fn child_box(lo: DVec3, hi: DVec3, bits: usize) -> (DVec3, DVec3) {
    child_box_at(lo, 0.5 * (lo + hi), hi, bits)
}

/// The child `bits` of the cell `[lo, hi]` whose mid-point is `mid`.
#[inline]
fn child_box_at(lo: DVec3, mid: DVec3, hi: DVec3, bits: usize) -> (DVec3, DVec3) {
    let upper = glam::BVec3::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
    (DVec3::select(upper, mid, lo), DVec3::select(upper, hi, mid))
}

/// Scratch space of a build (one per thread of it).
#[derive(Default)]
struct Scratch {
    slots: Vec<Enclosure>,
    choices: Vec<Choice>,
    jets: Vec<Jet<Enclosure, [Enclosure; 3]>>,
}

/// Whether the gradients enclosed by `gradient` lie in a cone of half-angle below 30° around
/// the enclosures' midpoint (the radius vector shorter than half the midpoint vector): then
/// `∇Φ·d` has one strict sign for every direction `d` more than 60° from the surface's tangent
/// plane, and subdividing the cell would help only nearly tangent rays.
fn narrow_cone(gradient: &[Enclosure; 3]) -> bool {
    if gradient
        .iter()
        .any(|g| g.undefined() || !g.lo.is_finite() || !g.hi.is_finite())
    {
        return false;
    }
    let mid = DVec3::from_array(std::array::from_fn(|a| 0.5 * (gradient[a].lo + gradient[a].hi)));
    let radius = DVec3::from_array(std::array::from_fn(|a| 0.5 * (gradient[a].hi - gradient[a].lo)));
    radius.length() < 0.5 * mid.length()
}

/// Enclosures of `∂Φ/∂x, ∂Φ/∂y, ∂Φ/∂z` over the box `vars` (forward mode, the three axes in
/// one pass).
fn enclose_gradient(
    tape: &Tape,
    vars: [Enclosure; 3],
    slots: &mut Vec<Jet<Enclosure, [Enclosure; 3]>>,
) -> [Enclosure; 3] {
    let unit = |axis: usize| std::array::from_fn(|a| Enclosure::point(if a == axis { 1.0 } else { 0.0 }));
    tape.eval([0, 1, 2].map(|axis| Jet::new(vars[axis], unit(axis))), slots)
        .slope
}

fn build(
    tape: &Arc<Tape>,
    lo: DVec3,
    hi: DVec3,
    margin: f64,
    depth: u32,
    parallel: bool,
    scratch: &mut Scratch,
) -> Built {
    let vars = [
        Enclosure::new(lo.x - margin, hi.x + margin),
        Enclosure::new(lo.y - margin, hi.y + margin),
        Enclosure::new(lo.z - margin, hi.z + margin),
    ];
    let value = tape.eval_choices(vars, &mut scratch.slots, &mut scratch.choices);
    if !value.undefined() && !value.contains_zero() {
        return Built::Empty;
    }
    let pruned = match tape.pruned(&scratch.choices) {
        Some(shorter) => Arc::new(shorter),
        None => Arc::clone(tape),
    };
    if depth >= MIN_LEAF_DEPTH {
        let gradient = enclose_gradient(&pruned, vars, &mut scratch.jets);
        if depth == MAX_DEPTH || narrow_cone(&gradient) {
            return Built::Leaf(pruned, lo, hi, gradient);
        }
    }
    let child = |bits: usize, scratch: &mut Scratch| {
        let (l, h) = child_box(lo, hi, bits);
        build(&pruned, l, h, margin, depth + 1, parallel, scratch)
    };
    let built: Box<[Built; 8]> = if parallel && depth == 0 {
        Box::new(build_children_on_threads(&|bits, scratch| child(bits, scratch)))
    } else {
        Box::new(std::array::from_fn(|bits| child(bits, scratch)))
    };
    if built.iter().all(|c| matches!(c, Built::Empty)) {
        return Built::Empty;
    }
    Built::Inner(built)
}

/// The eight children of the root, built on as many threads of their own as the current rayon
/// pool has (plain threads that wait for nothing but their work: a pool's threads, while they
/// wait for stolen work, may run other jobs that need this very tree), each taking the next
/// child not yet taken; on the calling thread alone where no thread can be started.
fn build_children_on_threads(child: &(dyn Fn(usize, &mut Scratch) -> Built + Sync)) -> [Built; 8] {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;
    let workers = rayon::current_num_threads().clamp(1, 8);
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(usize, Built)>> = Mutex::new(Vec::with_capacity(8));
    let work = || {
        let mut scratch = Scratch::default();
        loop {
            let bits = next.fetch_add(1, Ordering::Relaxed);
            if bits >= 8 {
                break;
            }
            let built = child(bits, &mut scratch);
            done.lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push((bits, built));
        }
    };
    std::thread::scope(|scope| {
        for _ in 1..workers {
            // a thread that cannot be started leaves its share to the others
            let _ = std::thread::Builder::new().spawn_scoped(scope, work);
        }
        work();
    });
    let mut slots: [Option<Built>; 8] = Default::default();
    for (bits, built) in done.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner) {
        slots[bits] = Some(built);
    }
    slots.map(|slot| slot.unwrap_or(Built::Empty))
}

impl CellTree {
    /// The tree of `tape` over the box `[lo, hi]` (finite, non-empty), its upper levels built
    /// on threads of its own if `parallel` (the root's eight children shared among as many
    /// threads as the current rayon pool has).
    #[must_use]
    pub fn new(tape: &Tape, lo: DVec3, hi: DVec3, parallel: bool) -> Self {
        let margin = MARGIN * (hi - lo).length();
        let built = build(
            &Arc::new(tape.clone()),
            lo,
            hi,
            margin,
            0,
            parallel,
            &mut Scratch::default(),
        );
        let mut tree = Self {
            lo,
            hi,
            margin,
            root: Cell::Empty,
            nodes: Vec::new(),
            tapes: Vec::new(),
            leaves: Vec::new(),
        };
        let mut seen = std::collections::HashMap::new();
        tree.root = tree.lay_out(built, &mut seen);
        tree
    }

    fn lay_out(&mut self, built: Built, seen: &mut std::collections::HashMap<*const Tape, u32>) -> Cell {
        match built {
            Built::Empty => Cell::Empty,
            Built::Leaf(tape, lo, hi, gradient) => {
                let key = Arc::as_ptr(&tape);
                let index = *seen.entry(key).or_insert_with(|| {
                    self.tapes.push(Arc::clone(&tape));
                    (self.tapes.len() - 1) as u32
                });
                let m = DVec3::splat(self.margin);
                self.leaves.push(Leaf {
                    lo: lo - m,
                    hi: hi + m,
                    tape: index,
                    gradient,
                });
                Cell::Leaf((self.leaves.len() - 1) as u32)
            }
            Built::Inner(children) => {
                let index = self.nodes.len();
                self.nodes.push([Cell::Empty; 8]);
                for (bits, child) in children.into_iter().enumerate() {
                    let cell = self.lay_out(child, seen);
                    self.nodes[index][bits] = cell;
                }
                Cell::Inner(index as u32)
            }
        }
    }

    /// The margin each cell was grown by (absolute).
    #[must_use]
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// Whether the margin covers the rounding of points `o + t·d` handed to cells by
    /// [`CellTree::walk`] for `t` up to `t_max` in magnitude: a few ulps of `|o| + |t|·|d|` (the
    /// cuts' and the point's rounding), with a factor of 64 to spare.
    #[must_use]
    pub fn margin_covers(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        let scale = origin.abs().max_element() + t_max.abs() * dir.abs().max_element() + self.hi.abs().max_element();
        64.0 * f64::EPSILON * scale < self.margin
    }

    /// The tape that gives Φ at `p`, knowing `p` was found in leaf `leaf` (a number handed
    /// to [`CellTree::walk`]'s visitor): that leaf's pruned tape if `p` lies in its grown cell,
    /// else `None` (the full tape is then the one to use).
    #[must_use]
    pub fn tape_at(&self, leaf: u32, p: DVec3) -> Option<&Tape> {
        let leaf = self.leaves.get(leaf as usize)?;
        (p.cmpge(leaf.lo) & p.cmple(leaf.hi))
            .all()
            .then(|| &*self.tapes[leaf.tape as usize])
    }

    /// Enclosures of `∂Φ/∂x, ∂Φ/∂y, ∂Φ/∂z` over the grown cell of leaf `leaf` (a number handed
    /// to [`CellTree::walk`]'s visitor), from its pruned tape; `None` for no such leaf.
    #[must_use]
    pub fn leaf_gradient(&self, leaf: u32) -> Option<&[Enclosure; 3]> {
        self.leaves.get(leaf as usize).map(|l| &l.gradient)
    }

    /// Number of leaves' distinct tapes and of inner nodes (for reports and tests).
    #[must_use]
    pub fn sizes(&self) -> (usize, usize) {
        (self.tapes.len(), self.nodes.len())
    }

    /// Hands each leaf the ray `origin + t·dir` passes through, front to back, for `t` in
    /// `[t0, t1]` (already clipped to the box): `visit(leaf, tape, grown_lo, grown_hi, ta, tb)`
    /// with the leaf's number, its tape and its cell grown by the margin, the pieces `[ta, tb]`
    /// covering `[t0, t1]` less the pieces in empty cells. Stops when `visit` returns `true`,
    /// and then returns `true`.
    pub fn walk(
        &self,
        origin: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
        visit: &mut impl FnMut(u32, &Tape, DVec3, DVec3, f64, f64) -> bool,
    ) -> bool {
        let inv = dir.recip();
        self.walk_cell(self.root, self.lo, self.hi, origin, dir, inv, t0, t1, visit)
    }

    #[allow(clippy::too_many_arguments)]
    fn walk_cell(
        &self,
        cell: Cell,
        lo: DVec3,
        hi: DVec3,
        origin: DVec3,
        dir: DVec3,
        inv: DVec3,
        t0: f64,
        t1: f64,
        visit: &mut impl FnMut(u32, &Tape, DVec3, DVec3, f64, f64) -> bool,
    ) -> bool {
        match cell {
            Cell::Empty => false,
            Cell::Leaf(index) => {
                let leaf = &self.leaves[index as usize];
                visit(index, &self.tapes[leaf.tape as usize], leaf.lo, leaf.hi, t0, t1)
            }
            Cell::Inner(node) => {
                let mid = 0.5 * (lo + hi);
                // where the ray crosses each mid-plane (never, along an axis it does not move on)
                let mut cut = [f64::INFINITY; 3];
                let mut bits = 0usize;
                for axis in 0..3 {
                    let d = dir[axis];
                    let upper = if d > 0.0 {
                        cut[axis] = (mid[axis] - origin[axis]) * inv[axis];
                        cut[axis] <= t0
                    } else if d < 0.0 {
                        cut[axis] = (mid[axis] - origin[axis]) * inv[axis];
                        cut[axis] > t0
                    } else {
                        origin[axis] >= mid[axis]
                    };
                    if upper {
                        bits |= 1 << axis;
                    }
                }
                let children = &self.nodes[node as usize];
                let mut t = t0;
                loop {
                    let mut next = t1;
                    for &c in &cut {
                        if c > t && c < next {
                            next = c;
                        }
                    }
                    let child = children[bits];
                    if child != Cell::Empty {
                        let (l, h) = child_box_at(lo, mid, hi, bits);
                        if self.walk_cell(child, l, h, origin, dir, inv, t, next, visit) {
                            return true;
                        }
                    }
                    if next >= t1 {
                        return false;
                    }
                    for (axis, &c) in cut.iter().enumerate() {
                        if c == next {
                            bits ^= 1 << axis;
                        }
                    }
                    t = next;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;

    /// Every `t` of a ray's range lands in exactly one cell, in order, and the cells handed out
    /// contain the points (up to the margin); empty cells hold no sign change of Φ.
    #[test]
    fn walks_cover_the_range_and_skip_only_empty_cells() {
        let e = Expr::parse("min(sqrt(x^2 + y^2 + z^2) - 0.5, sqrt((x - 0.8)^2 + y^2 + z^2) - 0.2)").unwrap();
        let tape = e.compile();
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
        let tree = CellTree::new(&tape, lo, hi, true);
        let (tapes, nodes) = tree.sizes();
        assert!(tapes > 2 && nodes > 8, "{tapes} {nodes}");
        let mut rng = 0x1234_5678_u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..300 {
            let o = DVec3::new(next() * 6.0 - 3.0, next() * 6.0 - 3.0, 3.0);
            let target = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
            let d = target - o;
            let ray = crate::Ray::new(o, d);
            let Some(range) = crate::Aabb::new(lo, hi).clip(&ray, crate::Interval::POSITIVE) else {
                continue;
            };
            let mut pieces: Vec<(f64, f64)> = Vec::new();
            tree.walk(o, d, range.min, range.max, &mut |number, leaf, l, h, ta, tb| {
                assert!(ta <= tb);
                for t in [ta, 0.5 * (ta + tb), tb] {
                    let p = ray.at(t);
                    assert!((p.cmpge(l) & p.cmple(h)).all(), "{p} outside {l} {h}");
                    assert!(std::ptr::eq(tree.tape_at(number, p).unwrap(), leaf));
                    // the leaf's tape has the full tape's value here
                    let mut s = Vec::new();
                    assert_eq!(leaf.eval_f64(p.to_array(), &mut s).to_bits(), e.eval(p).to_bits());
                }
                pieces.push((ta, tb));
                false
            });
            // ordered, disjoint
            for w in pieces.windows(2) {
                assert!(w[0].1 <= w[1].0);
            }
            // a sign change of Φ along the range lies in a piece handed out
            let n = 2000;
            let mut prev = e.eval(ray.at(range.min));
            for k in 1..=n {
                let t = range.min + (range.max - range.min) * f64::from(k) / f64::from(n);
                let v = e.eval(ray.at(t));
                if (v < 0.0) != (prev < 0.0) {
                    let tp = range.min + (range.max - range.min) * f64::from(k - 1) / f64::from(n);
                    assert!(
                        pieces.iter().any(|&(a, b)| a <= t && tp <= b),
                        "sign change in [{tp}, {t}] not in {pieces:?}"
                    );
                }
                prev = v;
            }
        }
    }
}
