//! An octree of a box that knows, cell by cell, whether Φ may vanish there, and with which
//! pruned tape: made as rays first reach its cells, shared by every ray (and point query) that
//! crosses the box.
//!
//! **Built** by interval evaluation (`Tape::eval_choices`) over each cell grown by a margin
//! `m` on every side: a cell whose enclosure of Φ excludes 0 (and is defined) holds no point of
//! the zero set and is marked **empty** (Φ > 0 all over it, or Φ < 0 all over it); otherwise it
//! is split in eight, each child evaluated with the tape pruned over its parent (Keeter 2020,
//! "Massively parallel rendering of complex closed-form implicit surfaces"; libfive), down to
//! [`MIN_LEAF_DEPTH`] levels (or [`MAX_DEPTH`] where the cell's gradients point in too wide a
//! cone), where a **leaf** keeps the tape pruned over itself and enclosures of
//! the partial derivatives of Φ over its grown cell ([`Leaf::gradient`]: a ray whose
//! slope `∇Φ·d` they prove non-zero is monotone across the whole leaf). A pruned tape gives
//! the full tape's values bit for bit inside its grown cell ([`crate::expr::tape`]).
//!
//! **Made on demand**: only the root is classified when the tree is made; any other cell is
//! classified when a walk first enters it (the first walk does the work, others entering it
//! meanwhile wait), so cells no ray enters (behind the first surface, outside the view, the
//! siblings a ray passes by) cost nothing. The cells made are cells an eager build would make,
//! with the same tapes and enclosures.
//!
//! **Walked** front to back along a ray ([`CellTree::walk`]): the ray's parameter range is cut
//! at the cells' mid-planes, and every `t` of the range is handed to exactly one leaf or empty
//! cell (the cuts are computed values, so the pieces cover the range with no gap whatever the
//! rounding). A point `o + t·d` handed to a cell lies in it up to the rounding of the cuts,
//! which the margin covers whenever [`CellTree::margin_covers`] says so; a caller that cannot
//! rely on it (an origin far beyond the box's scale) evaluates the full tape instead. A packet of
//! coherent rays walks it together ([`CellTree::walk_packet`]), each ray handed exactly the
//! leaves and pieces of its own walk.

use super::hessian::{enclose_hessian, Hessian, SecondOrder};
use super::tape::{Choice, Pruning, Tape};
use super::Jet;
use crate::math::enclosure::Enclosure;
use glam::DVec3;
use std::sync::{Arc, OnceLock};

/// Levels of the octree below its root (a leaf is `1/2^MAX_DEPTH` of the box on each axis).
pub const MAX_DEPTH: u32 = 8;

/// Levels below which a cell is always split: from here on a cell whose gradients lie in a
/// narrow cone is a leaf already (rays crossing it are monotone there, except
/// for nearly tangent ones).
pub const MIN_LEAF_DEPTH: u32 = 6;

/// Margin added on every side of a cell before its interval evaluation, relative to the box's
/// diagonal.
const MARGIN: f64 = 1e-6;

/// A cell of the tree.
#[derive(Debug)]
enum Cell {
    /// Φ cannot vanish in the (grown) cell.
    Empty,
    /// An inner cell, its children made on first use.
    Inner(Node),
    /// A leaf.
    Leaf(Box<Leaf>),
}

/// An inner cell: the tape pruned over it, its depth, and its eight children (bit 0: upper x
/// half, 1: y, 2: z), each classified by the first walk that enters it.
#[derive(Debug)]
struct Node {
    tape: Arc<Tape>,
    depth: u32,
    children: Box<[OnceLock<Cell>; 8]>,
}

/// The octree (see the module docs).
#[derive(Debug)]
pub struct CellTree {
    lo: DVec3,
    hi: DVec3,
    margin: f64,
    root: Cell,
}

/// A cell and its box, as a search over the tree sees it ([`CellTree::root`]).
#[derive(Clone, Copy)]
pub(crate) struct CellView<'a> {
    cell: &'a Cell,
    /// The cell's box (not grown).
    pub(crate) lo: DVec3,
    /// The cell's box (not grown).
    pub(crate) hi: DVec3,
}

/// What a cell holds, once opened ([`CellView::open`]).
#[allow(
    clippy::large_enum_variant,
    reason = "returned and matched at once, never stored: boxing the children would only add an allocation"
)]
pub(crate) enum Opened<'a> {
    /// Φ cannot vanish in it.
    Empty,
    /// A leaf: its pruned tape and grown box.
    Leaf(&'a Leaf),
    /// Its children (made now if no walk made them yet).
    Children([CellView<'a>; 8]),
}

impl<'a> CellView<'a> {
    /// What the cell holds; an inner cell's children are classified by the first caller, as
    /// for a ray's walk.
    pub(crate) fn open(&self, tree: &CellTree) -> Opened<'a> {
        match self.cell {
            Cell::Empty => Opened::Empty,
            Cell::Leaf(leaf) => Opened::Leaf(leaf),
            Cell::Inner(node) => {
                let children: [CellView<'a>; 8] = std::array::from_fn(|bits| {
                    let (lo, hi) = child_box(self.lo, self.hi, bits);
                    CellView {
                        cell: node.child(bits, lo, hi, tree.margin),
                        lo,
                        hi,
                    }
                });
                if children.iter().all(|c| matches!(c.cell, Cell::Empty)) {
                    Opened::Empty
                } else {
                    Opened::Children(children)
                }
            }
        }
    }
}

/// A leaf: its cell grown by the margin, the tape pruned over it, and enclosures of the partial
/// derivatives `∂Φ/∂x, ∂Φ/∂y, ∂Φ/∂z` over the grown cell.
#[derive(Debug)]
pub struct Leaf {
    lo: DVec3,
    hi: DVec3,
    tape: Arc<Tape>,
    gradient: [Enclosure; 3],
    /// Its Hessian over the grown cell, enclosed when first asked for ([`Leaf::hessian`]).
    hessian: OnceLock<Option<Box<Hessian>>>,
}

impl Leaf {
    /// The tape pruned over the leaf: the full tape's values bit for bit inside its grown cell.
    #[must_use]
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// The leaf's cell grown by the margin, `(lo, hi)`.
    #[must_use]
    pub fn grown(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Enclosures of `∂Φ/∂x, ∂Φ/∂y, ∂Φ/∂z` over the grown cell (from the pruned tape).
    #[must_use]
    pub fn gradient(&self) -> &[Enclosure; 3] {
        &self.gradient
    }

    /// Enclosures of Φ's second derivatives over the grown cell (from the pruned tape; `None`
    /// where [`enclose_hessian`] gives none), enclosed by the first caller.
    pub fn hessian(&self, slots: &mut Vec<SecondOrder>) -> Option<&Hessian> {
        let made = self
            .hessian
            .get_or_init(|| enclose_hessian(&self.tape, self.lo, self.hi, slots).map(Box::new));
        made.as_deref()
    }
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
    pruning: Pruning,
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
    tape.eval(Jet::axes(vars), slots).slope
}

thread_local! {
    static BUILD_SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// The cell `[lo, hi]` at `depth`, classified with `tape` (pruned over its parent) by interval
/// evaluation over the cell grown by `margin`: empty, a leaf, or an inner cell whose children
/// are left for later.
fn classify(tape: &Arc<Tape>, lo: DVec3, hi: DVec3, margin: f64, depth: u32, scratch: &mut Scratch) -> Cell {
    let vars = [
        Enclosure::new(lo.x - margin, hi.x + margin),
        Enclosure::new(lo.y - margin, hi.y + margin),
        Enclosure::new(lo.z - margin, hi.z + margin),
    ];
    let value = tape.eval_choices(vars, &mut scratch.slots, &mut scratch.choices);
    if !value.undefined() && !value.contains_zero() {
        return Cell::Empty;
    }
    let pruned = match tape.pruned(&scratch.choices, &mut scratch.pruning) {
        Some(shorter) => Arc::new(shorter),
        None => Arc::clone(tape),
    };
    if depth >= MIN_LEAF_DEPTH {
        let gradient = enclose_gradient(&pruned, vars, &mut scratch.jets);
        if depth == MAX_DEPTH || narrow_cone(&gradient) {
            let m = DVec3::splat(margin);
            return Cell::Leaf(Box::new(Leaf {
                lo: lo - m,
                hi: hi + m,
                tape: pruned,
                gradient,
                hessian: OnceLock::new(),
            }));
        }
    }
    Cell::Inner(Node {
        tape: pruned,
        depth,
        children: Box::new(std::array::from_fn(|_| OnceLock::new())),
    })
}

impl Node {
    /// Child `bits` of this node, whose box is `[lo, hi]`, classified by the first caller
    /// (other callers meanwhile wait; the work calls no thread pool).
    #[inline]
    fn child(&self, bits: usize, lo: DVec3, hi: DVec3, margin: f64) -> &Cell {
        match self.children[bits].get() {
            Some(made) => made,
            None => self.make_child(bits, lo, hi, margin),
        }
    }

    #[cold]
    #[inline(never)]
    fn make_child(&self, bits: usize, lo: DVec3, hi: DVec3, margin: f64) -> &Cell {
        self.children[bits].get_or_init(|| {
            let make = |scratch: &mut Scratch| classify(&self.tape, lo, hi, margin, self.depth + 1, scratch);
            BUILD_SCRATCH.with(|cell| match cell.try_borrow_mut() {
                Ok(mut scratch) => make(&mut scratch),
                Err(_) => make(&mut Scratch::default()),
            })
        })
    }
}

impl CellTree {
    /// The tree of `tape` over the box `[lo, hi]` (finite, non-empty): its root classified now,
    /// every other cell by the first walk that reaches it (cells no ray reaches cost nothing).
    #[must_use]
    pub fn new(tape: &Tape, lo: DVec3, hi: DVec3) -> Self {
        let margin = MARGIN * (hi - lo).length();
        let root = BUILD_SCRATCH.with(|cell| {
            let tape = Arc::new(tape.clone());
            match cell.try_borrow_mut() {
                Ok(mut scratch) => classify(&tape, lo, hi, margin, 0, &mut scratch),
                Err(_) => classify(&tape, lo, hi, margin, 0, &mut Scratch::default()),
            }
        });
        Self { lo, hi, margin, root }
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

    /// The tape that gives Φ at `p`: the pruned tape of a leaf made so far whose grown cell
    /// holds `p`, else `None` (the full tape is then the one to use).
    #[must_use]
    pub fn tape_at(&self, p: DVec3) -> Option<&Tape> {
        let (mut lo, mut hi, mut cell) = (self.lo, self.hi, &self.root);
        loop {
            match cell {
                Cell::Empty => return None,
                Cell::Leaf(leaf) => {
                    return (p.cmpge(leaf.lo) & p.cmple(leaf.hi)).all().then(|| leaf.tape());
                }
                Cell::Inner(node) => {
                    let mid = 0.5 * (lo + hi);
                    let upper = p.cmpge(mid);
                    let bits = usize::from(upper.x) | usize::from(upper.y) << 1 | usize::from(upper.z) << 2;
                    (lo, hi) = child_box_at(lo, mid, hi, bits);
                    cell = node.children[bits].get()?;
                }
            }
        }
    }

    /// The root cell, for searches that walk the tree in their own order
    /// ([`CellView::open`]).
    #[must_use]
    pub(crate) fn root(&self) -> CellView<'_> {
        CellView {
            cell: &self.root,
            lo: self.lo,
            hi: self.hi,
        }
    }

    /// Number of distinct tapes and of inner cells made so far (for reports and tests).
    #[must_use]
    pub fn sizes(&self) -> (usize, usize) {
        let mut tapes = std::collections::HashSet::new();
        let mut inner = 0;
        let mut stack = vec![&self.root];
        while let Some(cell) = stack.pop() {
            match cell {
                Cell::Empty => {}
                Cell::Leaf(leaf) => {
                    tapes.insert(Arc::as_ptr(&leaf.tape));
                }
                Cell::Inner(node) => {
                    inner += 1;
                    stack.extend(node.children.iter().filter_map(OnceLock::get));
                }
            }
        }
        (tapes.len(), inner)
    }

    /// Hands each leaf the ray `origin + t·dir` passes through, front to back, for `t` in
    /// `[t0, t1]` (already clipped to the box): `visit(leaf, ta, tb)` with the leaf (its tape,
    /// its cell grown by the margin, its gradient) and the pieces `[ta, tb]` covering `[t0, t1]`
    /// less the pieces in empty cells, making the cells it reaches that were not made yet.
    /// Stops when `visit` returns `true`, and then returns `true`.
    pub fn walk(
        &self,
        origin: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
        visit: &mut impl FnMut(&Leaf, f64, f64) -> bool,
    ) -> bool {
        let inv = dir.recip();
        self.walk_cell(&self.root, self.lo, self.hi, origin, dir, inv, t0, t1, visit)
    }

    #[allow(clippy::too_many_arguments)]
    fn walk_cell(
        &self,
        cell: &Cell,
        lo: DVec3,
        hi: DVec3,
        origin: DVec3,
        dir: DVec3,
        inv: DVec3,
        t0: f64,
        t1: f64,
        visit: &mut impl FnMut(&Leaf, f64, f64) -> bool,
    ) -> bool {
        match cell {
            Cell::Empty => false,
            Cell::Leaf(leaf) => visit(leaf, t0, t1),
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
                let mut t = t0;
                loop {
                    let mut next = t1;
                    for &c in &cut {
                        if c > t && c < next {
                            next = c;
                        }
                    }
                    let (l, h) = child_box_at(lo, mid, hi, bits);
                    let child = node.child(bits, l, h, self.margin);
                    if !matches!(child, Cell::Empty) && self.walk_cell(child, l, h, origin, dir, inv, t, next, visit) {
                        return true;
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

/// Rays of one packet walked together ([`CellTree::walk_packet`]), one array per axis, and a
/// beam around them: a central ray `c + t·e` (one of the lanes) and radii `r0 + r1·|t|` (per
/// axis, grown by the tree's margin) such that every lane's point `o_i + t·d_i` lies within
/// them of the central ray's point at the same `t`.
struct Beam {
    origin: [[f64; LANES]; 3],
    dir: [[f64; LANES]; 3],
    inv: [[f64; LANES]; 3],
    center: DVec3,
    center_dir: DVec3,
    center_inv: DVec3,
    r0: DVec3,
    r1: DVec3,
}

impl Beam {
    /// For each axis and half (0: lower, 1: upper) of the cell `[lo, hi]` cut at `mid`, the
    /// range of `t` where the central ray is within the radii (at `range`'s largest `|t|`) of
    /// that half's slab: a lane crossing a child does so at some `t` of the intersection of its
    /// three halves' ranges and `range` (an empty one: no lane crosses it).
    #[inline]
    fn halves(&self, lo: DVec3, mid: DVec3, hi: DVec3, (ta, tb): (f64, f64)) -> [[(f64, f64); 2]; 3] {
        let radius = self.r0 + self.r1 * ta.abs().max(tb.abs());
        std::array::from_fn(|axis| {
            let (c, e) = (self.center[axis], self.center_dir[axis]);
            let r = radius[axis];
            let bounds = [(lo[axis] - r, mid[axis] + r), (mid[axis] - r, hi[axis] + r)];
            bounds.map(|(l, h)| {
                if e == 0.0 {
                    if c < l || c > h {
                        (f64::INFINITY, f64::NEG_INFINITY)
                    } else {
                        (f64::NEG_INFINITY, f64::INFINITY)
                    }
                } else {
                    let inv = self.center_inv[axis];
                    let (x, y) = ((l - c) * inv, (h - c) * inv);
                    if e > 0.0 {
                        (x, y)
                    } else {
                        (y, x)
                    }
                }
            })
        })
    }
}

/// The most rays [`CellTree::walk_packet`] walks together.
pub const LANES: usize = crate::PACKET;

/// What [`CellTree::walk_packet`] hands each leaf to: the leaf, its lanes and their pieces;
/// returns the lanes whose walk ends there.
pub trait LaneVisitor: FnMut(&Leaf, u32, &[f64; LANES], &[f64; LANES]) -> u32 {}
impl<F: FnMut(&Leaf, u32, &[f64; LANES], &[f64; LANES]) -> u32> LaneVisitor for F {}

/// A cell's faces that are mid-planes of an ancestor (bit `a`: the lower face on axis `a`, bit
/// `3 + a`: the upper one); the others lie on the root's box, where no walk cuts.
type InnerFaces = u8;

/// The faces of child `bits` of a cell with inner faces `faces`.
#[inline]
fn child_faces(faces: InnerFaces, bits: usize) -> InnerFaces {
    let mut faces = faces;
    for axis in 0..3 {
        faces |= if bits >> axis & 1 != 0 { 1 << axis } else { 8 << axis };
    }
    faces
}

impl CellTree {
    /// [`CellTree::walk`] for up to [`LANES`] rays at once: lane `i` (ray `origin[i] + t·dir[i]`,
    /// `t` in `[t0[i], t1[i]]`) is handed exactly the leaves and pieces its own walk would be, in
    /// the same order. `visit(leaf, lanes, ta, tb)` gets a leaf with the set of lanes that cross
    /// it (bit `i` for lane `i`) and their pieces `[ta[i], tb[i]]`, and returns the lanes whose
    /// walk ends there.
    ///
    /// Rays whose directions agree in sign on every axis (zero agrees with both) share the
    /// descent: it follows a beam around them (a central ray and radii, [`Beam`]) into the
    /// children it may cross, taken in the order the common direction signs give (each lane's
    /// front-to-back order). At a leaf, a lane's piece is `[max(t0, entry cuts), min(t1, exit
    /// cuts)]` with the cuts of the leaf's faces that are mid-planes of its ancestors: the same
    /// numbers as its own walk, whose cuts at the ancestors' other mid-planes lie beyond them
    /// (the rounded cut `(m − o)·(1/d)` is monotone in `m`). Lanes too far apart for a narrow
    /// beam, and any other lane (a direction of other signs, an empty range), are walked alone.
    pub fn walk_packet(&self, origin: &[DVec3], dir: &[DVec3], t0: &[f64], t1: &[f64], visit: &mut impl LaneVisitor) {
        let n = origin.len();
        assert!(n <= LANES && dir.len() == n && t0.len() == n && t1.len() == n);
        let mut beam = Beam {
            origin: [[0.0; LANES]; 3],
            dir: [[0.0; LANES]; 3],
            inv: [[1.0; LANES]; 3],
            center: DVec3::ZERO,
            center_dir: DVec3::ZERO,
            center_inv: DVec3::ZERO,
            r0: DVec3::ZERO,
            r1: DVec3::ZERO,
        };
        let (mut lo, mut hi) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
        let (mut negative, mut positive) = ([false; 3], [false; 3]);
        let mut together = 0u32;
        let alone = |lane: usize, visit: &mut dyn LaneVisitor| {
            self.walk(origin[lane], dir[lane], t0[lane], t1[lane], &mut |leaf, ta, tb| {
                let (mut a, mut b) = ([0.0; LANES], [0.0; LANES]);
                (a[lane], b[lane]) = (ta, tb);
                visit(leaf, 1 << lane, &a, &b) != 0
            })
        };
        let mut range = (f64::INFINITY, f64::NEG_INFINITY);
        for lane in 0..n {
            let d = dir[lane];
            let disagrees = |a: usize| (d[a] < 0.0 && positive[a]) || (d[a] > 0.0 && negative[a]);
            let joins = t0[lane] < t1[lane] && !(0..3).any(disagrees);
            if !joins {
                alone(lane, visit);
                continue;
            }
            if together == 0 {
                (beam.center, beam.center_dir, beam.center_inv) = (origin[lane], d, d.recip());
            }
            for a in 0..3 {
                negative[a] |= d[a] < 0.0;
                positive[a] |= d[a] > 0.0;
                beam.origin[a][lane] = origin[lane][a];
                beam.dir[a][lane] = d[a];
                beam.inv[a][lane] = d[a].recip();
            }
            beam.r0 = beam.r0.max((origin[lane] - beam.center).abs());
            beam.r1 = beam.r1.max((d - beam.center_dir).abs());
            (lo[lane], hi[lane]) = (t0[lane], t1[lane]);
            range = (range.0.min(t0[lane]), range.1.max(t1[lane]));
            together |= 1 << lane;
        }
        if together == 0 {
            return;
        }
        // the margin covers the rounding of the lanes' points and of the beam's own cuts
        beam.r0 += DVec3::splat(2.0 * self.margin);
        let spread = beam.r0 + beam.r1 * range.0.abs().max(range.1.abs());
        if (spread.cmpgt((self.hi - self.lo) / 16.0)).any() {
            for lane in (0..n).filter(|&lane| together & 1 << lane != 0) {
                alone(lane, visit);
            }
            return;
        }
        let flip = usize::from(negative[0]) | usize::from(negative[1]) << 1 | usize::from(negative[2]) << 2;
        self.walk_cell_packet(
            &self.root, self.lo, self.hi, 0, &beam, flip, range, &lo, &hi, together, visit,
        );
    }

    /// One cell of [`CellTree::walk_packet`] for the lanes in `active`, the beam within `range`
    /// there; returns the lanes whose walk ended here. `t0`, `t1`: the lanes' whole ranges.
    #[allow(clippy::too_many_arguments)]
    fn walk_cell_packet(
        &self,
        cell: &Cell,
        lo: DVec3,
        hi: DVec3,
        faces: InnerFaces,
        beam: &Beam,
        flip: usize,
        range: (f64, f64),
        t0: &[f64; LANES],
        t1: &[f64; LANES],
        active: u32,
        visit: &mut impl LaneVisitor,
    ) -> u32 {
        match cell {
            Cell::Empty => 0,
            Cell::Leaf(leaf) => {
                let (ta, tb, lanes) = lane_pieces(lo, hi, faces, beam, t0, t1);
                let lanes = lanes & active;
                if lanes == 0 {
                    return 0;
                }
                visit(leaf, lanes, &ta, &tb) & lanes
            }
            Cell::Inner(node) => {
                let mid = 0.5 * (lo + hi);
                let halves = beam.halves(lo, mid, hi, range);
                let mut active = active;
                let mut ended = 0;
                for order in 0..8 {
                    let bits = order ^ flip;
                    let (mut a, mut b) = range;
                    for (axis, halves) in halves.iter().enumerate() {
                        let (near, far) = halves[bits >> axis & 1];
                        a = a.max(near);
                        b = b.min(far);
                    }
                    if a > b {
                        continue;
                    }
                    let within = (a, b);
                    let (l, h) = child_box_at(lo, mid, hi, bits);
                    let child = node.child(bits, l, h, self.margin);
                    if matches!(child, Cell::Empty) {
                        continue;
                    }
                    let faces = child_faces(faces, bits);
                    let done = self.walk_cell_packet(child, l, h, faces, beam, flip, within, t0, t1, active, visit);
                    ended |= done;
                    active &= !done;
                    if active == 0 {
                        break;
                    }
                }
                ended
            }
        }
    }
}

/// Each lane's piece `[ta, tb]` of the leaf `[lo, hi]` and the set of lanes with `ta < tb`:
/// `[t0, t1]` cut where the lane crosses the leaf's inner faces (a lane that does not move on an
/// axis is in the leaf there when its origin is on the leaf's side of each inner face: at or
/// above a lower one, below an upper one, as the walk decides at each mid-plane).
#[inline]
fn lane_pieces(
    lo: DVec3,
    hi: DVec3,
    faces: InnerFaces,
    beam: &Beam,
    t0: &[f64; LANES],
    t1: &[f64; LANES],
) -> ([f64; LANES], [f64; LANES], u32) {
    let (mut ta, mut tb) = (*t0, *t1);
    for axis in 0..3 {
        let lower = faces & 1 << axis != 0;
        let upper = faces & 8 << axis != 0;
        for lane in 0..LANES {
            let (o, d, inv) = (beam.origin[axis][lane], beam.dir[axis][lane], beam.inv[axis][lane]);
            let (a, b) = (&mut ta[lane], &mut tb[lane]);
            if d > 0.0 {
                if lower {
                    *a = a.max((lo[axis] - o) * inv);
                }
                if upper {
                    *b = b.min((hi[axis] - o) * inv);
                }
            } else if d < 0.0 {
                if upper {
                    *a = a.max((hi[axis] - o) * inv);
                }
                if lower {
                    *b = b.min((lo[axis] - o) * inv);
                }
            } else if (lower && o < lo[axis]) || (upper && o >= hi[axis]) {
                *a = f64::INFINITY;
            }
        }
    }
    let mut lanes = 0u32;
    for lane in 0..LANES {
        lanes |= u32::from(ta[lane] < tb[lane]) << lane;
    }
    (ta, tb, lanes)
}

#[cfg(test)]
mod tests;
