//! `g(t) = Φ(o + t·d)` along one ray inside one leaf of the octree ([`LeafAlong`]): what the
//! interval isolation ([`crate::isolation`]) asks of a compiled expression there.

use super::{defined_or_outside, Scratch};
use crate::bounds::Aabb;
use crate::expr::cells::Leaf;
use crate::expr::hessian::curvature_sign;
use crate::expr::tape::Tape;
use crate::expr::{coordinates_along, jets_along, Jet};
use crate::isolation::{AlongRay, Shape};
use crate::math::enclosure::Enclosure;
use crate::ray::{Interval, Ray};
use glam::DVec3;

/// `g(t)` on the pieces of a ray inside one leaf of the octree: the leaf's pruned tape where
/// the points lie in its grown cell (the full tape's values there), the full tape elsewhere.
pub(super) struct LeafAlong<'a> {
    pub(super) ray: &'a Ray,
    pub(super) leaf: &'a Leaf,
    pub(super) full: &'a Tape,
    pub(super) cell_lo: DVec3,
    pub(super) cell_hi: DVec3,
    pub(super) bounds: &'a Aabb,
    pub(super) scratch: &'a mut Scratch,
    /// The last point value `(t, g(t))` along the ray, kept across leaves (a leaf's exit is the
    /// next one's entry; every tape gives the same value there).
    pub(super) last: &'a mut (f64, f64),
}

impl<'a> LeafAlong<'a> {
    /// The leaf's tape where the point `p` lies in its grown cell, the full tape elsewhere.
    fn tape_at(&self, p: DVec3) -> &'a Tape {
        if (p.cmpge(self.cell_lo) & p.cmple(self.cell_hi)).all() {
            self.leaf.tape()
        } else {
            self.full
        }
    }

    fn tape_for(&self, c: &[Enclosure; 3]) -> &'a Tape {
        let inside = (0..3).all(|a| c[a].lo >= self.cell_lo[a] && c[a].hi <= self.cell_hi[a]);
        if inside {
            self.leaf.tape()
        } else {
            self.full
        }
    }
}

impl LeafAlong<'_> {
    /// `g` as a jet of jets over the coordinates `c` of a piece: value, `g′` twice and `g″`.
    fn second_order(&mut self, tape: &Tape, c: [Enclosure; 3]) -> Jet<Jet<Enclosure>, Jet<Enclosure>> {
        let d = self.ray.dir;
        let seed = |a: usize| {
            let slope = Enclosure::point(d[a]);
            Jet::new(Jet::new(c[a], slope), Jet::new(slope, Enclosure::point(0.0)))
        };
        tape.eval([seed(0), seed(1), seed(2)], &mut self.scratch.curvatures)
    }
}

/// Whether two slope enclosures prove one function strictly increasing and the other strictly
/// decreasing.
fn opposite(u: Enclosure, v: Enclosure) -> bool {
    matches!((u.strict_sign(), v.strict_sign()), (Some(a), Some(b)) if a != b)
}

impl AlongRay for LeafAlong<'_> {
    fn value(&mut self, piece: Interval) -> Enclosure {
        match coordinates_along(self.ray, piece, self.bounds.min, self.bounds.max) {
            Some(c) => {
                let tape = self.tape_for(&c);
                tape.eval(c, &mut self.scratch.enclosures)
            }
            None => Enclosure::point(f64::INFINITY),
        }
    }

    fn point(&mut self, t: f64) -> f64 {
        if t == self.last.0 {
            return self.last.1;
        }
        let p = self.ray.at(t);
        let g = defined_or_outside(self.tape_at(p).eval_f64(p.to_array(), &mut self.scratch.points));
        *self.last = (t, g);
        g
    }

    fn within_boundary(&mut self, _t: f64) -> bool {
        true
    }

    /// Where the piece lies in the leaf's grown cell, its tape has no `min`, `max` or `abs`,
    /// and the leaf's Hessian proves `dᵀ·H·d` of one strict sign for the ray's direction.
    fn known_convex(&mut self, piece: Interval) -> Option<Shape> {
        // a leaf tape with kinks has no Hessian, and the full tape then has them too
        if self.leaf.tape().has_branches() {
            return None;
        }
        let c = coordinates_along(self.ray, piece, self.bounds.min, self.bounds.max)?;
        if !std::ptr::eq(self.tape_for(&c), self.leaf.tape()) {
            return None;
        }
        let d = self.ray.dir;
        let hessian = self.leaf.hessian(&mut self.scratch.hessians)?;
        curvature_sign(hessian, d).map(Shape::Convex)
    }

    /// On tapes without `min`, `max` or `abs`: the sign of `g″` from second-order jets (`g`,
    /// `g′`, `g′`, `g″` as a jet of jets) over the piece: one evaluation, whose first-order part
    /// is computed by the same operations as a jet's. On other tapes `g″` is not enclosed
    /// (their kinks put into `g″` what no jet sees): the jet, and where the result is a `max`
    /// or `min` of two slots whose slopes (read from the same evaluation) have strict opposite
    /// signs, [`Shape::Unimodal`].
    fn jet_and_curvature(&mut self, piece: Interval) -> (Jet<Enclosure>, Option<Shape>) {
        let Some(c) = coordinates_along(self.ray, piece, self.bounds.min, self.bounds.max) else {
            return (Jet::new(Enclosure::point(f64::INFINITY), Enclosure::ENTIRE), None);
        };
        let tape = self.tape_for(&c);
        if tape.has_branches() {
            let jet = tape.eval(jets_along(c, self.ray.dir), &mut self.scratch.jets);
            let shape = tape.result_extremum().and_then(|(max, a, b)| {
                let slots = &self.scratch.jets;
                opposite(slots[a].slope, slots[b].slope).then_some(Shape::Unimodal(if max { 1.0 } else { -1.0 }))
            });
            return (jet, shape);
        }
        let second = self.second_order(tape, c);
        (second.value, second.slope.slope.strict_sign().map(Shape::Convex))
    }

    fn point_slope(&mut self, t: f64) -> (f64, f64) {
        let p = self.ray.at(t);
        let d = self.ray.dir;
        let seed = |a: usize| Jet::new(p[a], d[a]);
        let jet = self
            .tape_at(p)
            .eval([seed(0), seed(1), seed(2)], &mut self.scratch.slopes);
        let g = defined_or_outside(jet.value);
        *self.last = (t, g);
        (g, jet.slope)
    }
}
