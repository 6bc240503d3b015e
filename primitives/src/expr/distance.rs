//! Guaranteed bounds on the distance from a point to the zero set of an expression inside a box
//! ([`distance_bounds`]): what [`crate::Function::closest`] answers.
//!
//! **Branch and bound, nearest box first.** Boxes (the search box, then octants) wait in a heap
//! ordered by a lower bound on the distance from `p` to any zero of Φ in them. A popped box whose
//! interval enclosure of Φ excludes 0 holds no surface and is dropped. Otherwise its bound is
//! tightened by the **slab test**: by the mean value theorem every zero `x` of the box satisfies
//! `0 ∈ Φ(c) + G·(x − c)` for its centre `c` and an enclosure `G` of ∇Φ over the box; with `g`
//! the midpoint of `G` and `r = Σ rad(Gᵢ)·hᵢ + rad(Φ(c))` (`h` the half-widths) the zeros lie in
//! the slab `|Φ(c) + g·(x − c)| ≤ r`, whose distance from `p` is
//! `(|Φ(c) + g·(p − c)| − r)/|g|`. The box's bound is the larger of that and the distance to the
//! box. Near a smooth surface `r` shrinks with the square of the box size, so few boxes per level
//! remain near the nearest point and the interval closes quickly.
//!
//! **The octree.** A `Function` starts the search from the octree its rays walk
//! ([`distance_bounds`], [`crate::expr::cells`]): cells proved empty are dropped without an
//! evaluation, and the boxes inside a leaf are evaluated with the leaf's pruned tape.
//!
//! **Witnesses.** The upper bound is the distance to a certified surface point: two points whose
//! interval values of Φ have strictly opposite signs (taken across the slab, along `g`, through
//! the point of the slab nearest to `p`) bracket a zero on the segment between them, which is
//! narrowed by bisection with certified signs; the farther end's distance from `p` bounds the
//! distance above, and the nearer end is reported as the point.
//!
//! The search stops when the smallest bound still waiting is within `tolerance` of the upper
//! bound, or after `budget` boxes; the bounds returned are valid either way (only wider). Where
//! Φ may be undefined (a domain error) a box is kept, never dropped, and no witness is taken
//! from undefined values.

use super::cells::{CellTree, CellView, Opened};
use super::scalar::Jet;
use super::tape::Tape;
use crate::math::enclosure::Enclosure;
use crate::proximity::Closest;
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A box waiting in the heap with its lower bound: a cell of the octree not opened yet, or a box
/// inside a leaf with the leaf's pruned tape.
struct Waiting<'a> {
    bound: f64,
    lo: DVec3,
    hi: DVec3,
    what: Part<'a>,
}

/// What a waiting box is.
enum Part<'a> {
    Cell(CellView<'a>),
    Piece(&'a Tape),
}

impl PartialEq for Waiting<'_> {
    fn eq(&self, other: &Self) -> bool {
        self.bound == other.bound
    }
}
impl Eq for Waiting<'_> {}
impl PartialOrd for Waiting<'_> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Waiting<'_> {
    /// Smallest bound first (the heap is a max-heap).
    fn cmp(&self, other: &Self) -> Ordering {
        other.bound.total_cmp(&self.bound)
    }
}

/// Scratch of the evaluations.
#[derive(Default)]
struct Slots {
    values: Vec<Enclosure>,
    jets: Vec<Jet<Enclosure, [Enclosure; 3]>>,
}

fn enclosures(lo: DVec3, hi: DVec3) -> [Enclosure; 3] {
    [
        Enclosure::new(lo.x, hi.x),
        Enclosure::new(lo.y, hi.y),
        Enclosure::new(lo.z, hi.z),
    ]
}

/// Φ enclosed at the point `x` (exact inputs; the rounding of the evaluation included).
fn at_point(tape: &Tape, x: DVec3, slots: &mut Slots) -> Enclosure {
    tape.eval(x.to_array().map(Enclosure::point), &mut slots.values)
}

/// The sign Φ certainly has at `x`: `Some(±1)`, or `None` where the enclosure holds 0 or Φ may be
/// undefined.
fn certain_sign(tape: &Tape, x: DVec3, slots: &mut Slots) -> Option<f64> {
    let v = at_point(tape, x, slots);
    if v.undefined() {
        None
    } else if v.lo > 0.0 {
        Some(1.0)
    } else if v.hi < 0.0 {
        Some(-1.0)
    } else {
        None
    }
}

fn box_distance(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    (lo - p).max(p - hi).max(DVec3::ZERO).length()
}

/// Guaranteed bounds on the distance from `p` to the zero set of Φ inside the box of the
/// octree `tree` (see the module docs). `point` is a certified surface point's bracket end
/// nearer `p`, at distance at most `upper` (the bracket is narrowed until its width is
/// negligible against `tolerance`); with no zero found, `point` is `None` and `upper` is `+∞`.
/// The search starts from the tree's cells (the ones the rays walk, made by whichever query
/// reaches them first): empty cells are dropped without an evaluation, and the boxes inside a
/// leaf are evaluated with the leaf's pruned tape (shorter than the full one).
pub(crate) fn distance_bounds(tree: &CellTree, p: DVec3, tolerance: f64, budget: usize) -> Closest {
    let root = tree.root();
    let start = Waiting {
        bound: box_distance(p, root.lo, root.hi),
        lo: root.lo,
        hi: root.hi,
        what: Part::Cell(root),
    };
    search(Some(tree), start, p, tolerance, budget)
}

/// The search of the module docs from `start`.
fn search<'a>(tree: Option<&'a CellTree>, start: Waiting<'a>, p: DVec3, tolerance: f64, budget: usize) -> Closest {
    let mut slots = Slots::default();
    let mut heap = BinaryHeap::new();
    heap.push(start);
    let mut upper = f64::INFINITY;
    let mut witness: Option<DVec3> = None;
    // the smallest bound of the boxes too small to split (their zeros are not excluded)
    let mut unsplit = f64::INFINITY;
    // the smallest bound of the boxes left unexamined because they could not improve `upper` by
    // more than the tolerance
    let mut dropped = f64::INFINITY;
    let smallest = tolerance * 0.25;
    let mut visited = 0usize;
    let lower = loop {
        let Some(item) = heap.pop() else {
            break unsplit.min(dropped).min(upper);
        };
        if item.bound >= upper - tolerance || visited >= budget {
            break item.bound.min(unsplit).min(dropped);
        }
        visited += 1;
        let tape = match item.what {
            Part::Piece(tape) => tape,
            Part::Cell(view) => {
                match view.open(tree.expect("cells come from a tree")) {
                    Opened::Empty => {}
                    Opened::Leaf(leaf) => {
                        let (lo, hi) = leaf.grown();
                        heap.push(Waiting {
                            bound: item.bound.max(box_distance(p, lo, hi)),
                            lo,
                            hi,
                            what: Part::Piece(leaf.tape()),
                        });
                    }
                    Opened::Children(children) => {
                        for child in children {
                            heap.push(Waiting {
                                bound: item.bound.max(box_distance(p, child.lo, child.hi)),
                                lo: child.lo,
                                hi: child.hi,
                                what: Part::Cell(child),
                            });
                        }
                    }
                }
                continue;
            }
        };
        let vars = enclosures(item.lo, item.hi);
        let value = tape.eval(vars, &mut slots.values);
        if !value.undefined() && !value.contains_zero() {
            continue;
        }
        let mut bound = item.bound;
        let centre = (item.lo + item.hi) * 0.5;
        let half = (item.hi - item.lo) * 0.5;
        if !value.undefined() {
            let gradient = tape.eval(Jet::axes(vars), &mut slots.jets).slope;
            let at_centre = at_point(tape, centre, &mut slots);
            if let Some((foot, normal, width)) = slab(p, centre, half, gradient, at_centre) {
                match slab_box_distance(p, item.lo, item.hi, normal, normal.dot(foot), width) {
                    // the slab misses the box: no zero in it
                    None => continue,
                    Some(d) => bound = bound.max(d),
                }
                if let Some((near, far)) = bracket(tape, foot, normal, width, item.lo, item.hi, &mut slots, smallest) {
                    let reach = (far - p).length().max((near - p).length());
                    if reach < upper {
                        upper = reach;
                        witness = Some(near);
                    }
                }
            }
        }
        if bound >= upper - tolerance {
            // dropped for the tolerance alone: its zeros may still be nearer than `upper`
            if bound < upper {
                dropped = dropped.min(bound);
            }
            continue;
        }
        if half.max_element() * 2.0 <= smallest || half.max_element() <= centre.abs().max_element() * 4.0 * f64::EPSILON
        {
            unsplit = unsplit.min(bound);
            continue;
        }
        for octant in 0..8 {
            let pick = |axis: usize, a: f64, m: f64, b: f64| if octant >> axis & 1 == 0 { (a, m) } else { (m, b) };
            let (x0, x1) = pick(0, item.lo.x, centre.x, item.hi.x);
            let (y0, y1) = pick(1, item.lo.y, centre.y, item.hi.y);
            let (z0, z1) = pick(2, item.lo.z, centre.z, item.hi.z);
            let (clo, chi) = (DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z1));
            heap.push(Waiting {
                bound: bound.max(box_distance(p, clo, chi)),
                lo: clo,
                hi: chi,
                what: Part::Piece(tape),
            });
        }
    };
    Closest {
        point: witness,
        feature: 0,
        lower: lower.min(upper).max(0.0),
        upper,
    }
}

/// The slab holding a box's zeros (see the module docs): `(the point of its middle plane
/// nearest p, the unit normal g/|g|, the slab's half-width)`, the slab being
/// `|normal·x − normal·foot| ≤ half-width`; `None` where the gradient's midpoint vanishes or
/// anything is not finite.
fn slab(
    p: DVec3,
    centre: DVec3,
    half: DVec3,
    gradient: [Enclosure; 3],
    at_centre: Enclosure,
) -> Option<(DVec3, DVec3, f64)> {
    let g = DVec3::from_array(gradient.map(|e| 0.5 * e.lo + 0.5 * e.hi));
    let spread = DVec3::from_array(gradient.map(|e| (e.hi - e.lo) * 0.5));
    let phi_c = 0.5 * at_centre.lo + 0.5 * at_centre.hi;
    let mut r = spread.dot(half) + (at_centre.hi - at_centre.lo) * 0.5;
    let offset = phi_c + g.dot(p - centre);
    // the rounding of the sums above and of the plane's form below, generously
    r += 16.0 * f64::EPSILON * (phi_c.abs() + g.abs().dot((p - centre).abs()) + g.abs().dot(half + centre.abs()) + r);
    let length = g.length();
    if !(length > 0.0) || !r.is_finite() || !offset.is_finite() {
        return None;
    }
    let normal = g / length;
    let foot = p - normal * (offset / length);
    Some((foot, normal, r / length))
}

/// A lower bound on the distance from `p` to the part of the box `[lo, hi]` inside the slab
/// `|n·x − m| ≤ w` (`n` unit), or `None` where the slab misses the box. The nearest point of a
/// box and a half-space is `clamp(p − λn)` for the `λ` where it meets the slab's face, and its
/// distance grows with `|λ|`: `λ` is bracketed by bisection and the distance taken at the
/// bracket's end nearer 0 (never beyond the exact one), less 4 ulps.
fn slab_box_distance(p: DVec3, lo: DVec3, hi: DVec3, n: DVec3, m: f64, w: f64) -> Option<f64> {
    let at = |lambda: f64| (p - n * lambda).clamp(lo, hi);
    let level = |lambda: f64| n.dot(at(lambda)) - m;
    let start = level(0.0);
    if start.abs() <= w {
        return Some((at(0.0) - p).length());
    }
    // move along −n·sign(start) until the level reaches the slab's near face
    let direction = start.signum();
    let face = direction * w;
    let span = (hi - lo).length() + (p - lo.clamp(p, hi)).length() + (p - hi.clamp(p, lo)).length();
    let far = direction * (span + start.abs());
    if (level(far) - face) * direction > 0.0 {
        return None;
    }
    let (mut near, mut beyond) = (0.0f64, far);
    for _ in 0..80 {
        let mid = 0.5 * (near + beyond);
        if mid == near || mid == beyond {
            break;
        }
        if (level(mid) - face) * direction > 0.0 {
            near = mid;
        } else {
            beyond = mid;
        }
    }
    Some((at(near) - p).length() * (1.0 - 4.0 * f64::EPSILON))
}

/// Two points of the box with certified opposite signs of Φ, across the slab through `foot`
/// (clamped into the box) along `normal`, narrowed by bisection to at most `width_goal` apart:
/// `(end nearer the middle, other end)`. `None` where no such pair is found.
#[allow(clippy::too_many_arguments)]
fn bracket(
    tape: &Tape,
    foot: DVec3,
    normal: DVec3,
    half_width: f64,
    lo: DVec3,
    hi: DVec3,
    slots: &mut Slots,
    width_goal: f64,
) -> Option<(DVec3, DVec3)> {
    let foot = foot.clamp(lo, hi);
    let reach = (half_width * 2.0).max((hi - lo).max_element() * 1e-3);
    let mut a = (foot - normal * reach).clamp(lo, hi);
    let mut b = (foot + normal * reach).clamp(lo, hi);
    let sa = certain_sign(tape, a, slots)?;
    let sb = certain_sign(tape, b, slots)?;
    if sa == sb {
        return None;
    }
    for _ in 0..200 {
        if (b - a).length() <= width_goal {
            break;
        }
        let m = (a + b) * 0.5;
        if m == a || m == b {
            break;
        }
        match certain_sign(tape, m, slots) {
            Some(s) if s == sa => a = m,
            Some(_) => b = m,
            None => break,
        }
    }
    Some((a, b))
}

#[cfg(test)]
mod tests {
    use crate::expr::cells::CellTree;
    use crate::expr::Expr;
    use glam::DVec3;

    /// Bounds around the distance to a sphere and a torus (closed forms) from points inside,
    /// outside and near the surface: they contain it and close to the tolerance.
    #[test]
    fn bounds_contain_the_closed_form_distance_and_close_to_the_tolerance() {
        let (lo, hi) = (DVec3::splat(-1.5), DVec3::splat(1.5));
        let tree = |text: &str| CellTree::new(&Expr::parse(text).unwrap().compile(), lo, hi);
        let sphere = tree("sqrt(x^2 + y^2 + z^2) - 1");
        let torus = tree("sqrt((sqrt(x^2 + y^2) - 1)^2 + z^2) - 0.25");
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.5
        };
        let tolerance = 1e-9;
        for k in 0..200 {
            let p = DVec3::new(next(), next(), next()) * if k % 4 == 0 { 3.0 } else { 1.0 };
            let sphere_distance = (p.length() - 1.0).abs();
            let rho = (p.x * p.x + p.y * p.y).sqrt();
            let torus_distance = (((rho - 1.0).powi(2) + p.z * p.z).sqrt() - 0.25).abs();
            for (tree, reference) in [(&sphere, sphere_distance), (&torus, torus_distance)] {
                let c = super::distance_bounds(tree, p, tolerance, 100_000);
                let slack = 1e-12 * (1.0 + p.length());
                assert!(
                    c.lower <= reference + slack && reference <= c.upper + slack,
                    "{p}: [{}, {}] misses {reference}",
                    c.lower,
                    c.upper
                );
                assert!(
                    c.upper - c.lower <= 2.0 * tolerance,
                    "{p}: [{}, {}] too wide",
                    c.lower,
                    c.upper
                );
                let q = c.point.expect("a surface point");
                assert!((q - p).length() <= c.upper);
            }
        }
    }
}
