//! Enclosures of the second derivatives of Φ over a box, and what they say about the sign of
//! `g″(t) = dᵀ·H(o + t·d)·d` along a ray of direction `d` crossing it: a leaf of the octree
//! whose Hessian proves `g″` of one strict sign lets interval isolation take its convex (or
//! concave) step without enclosing `g″` piece by piece ([`crate::isolation`]).

use super::tape::Tape;
use super::Jet;
use crate::math::enclosure::Enclosure;
use glam::DVec3;

/// Enclosures of `∂²Φ/∂x², ∂²Φ/∂y², ∂²Φ/∂z², ∂²Φ/∂x∂y, ∂²Φ/∂x∂z, ∂²Φ/∂y∂z` over a box.
pub type Hessian = [Enclosure; 6];

/// A number with its gradient, and the gradient's own derivatives: forward mode of second
/// order over the three axes.
pub type SecondOrder = Jet<Jet<Enclosure, [Enclosure; 3]>, [Jet<Enclosure, [Enclosure; 3]>; 3]>;

/// The Hessian of `tape` over the box `[lo, hi]`, from one evaluation in second-order jets;
/// `None` where the tape has a `min`, `max` or `abs` (its kinks put into the second
/// derivatives what no jet sees) or an entry is undefined or unbounded.
pub fn enclose_hessian(tape: &Tape, lo: DVec3, hi: DVec3, slots: &mut Vec<SecondOrder>) -> Option<Hessian> {
    if tape.has_branches() {
        return None;
    }
    let vars = std::array::from_fn(|a| Enclosure::new(lo[a], hi[a]));
    let second = tape.eval(Jet::axes(Jet::axes(vars)), slots);
    let h = |i: usize, j: usize| second.slope[i].slope[j];
    let hessian = [h(0, 0), h(1, 1), h(2, 2), h(0, 1), h(0, 2), h(1, 2)];
    hessian
        .iter()
        .all(|e| !e.undefined() && e.lo.is_finite() && e.hi.is_finite())
        .then_some(hessian)
}

/// `Some(±1.0)` where `dᵀ·H·d` has one strict sign for every Hessian `H` the enclosures
/// hold, else `None`. The sum is taken in `f64`: a slack of `16·ε` times the sum of the
/// terms' magnitudes covers the rounding of the weights, the products and the sum.
#[must_use]
pub fn curvature_sign(hessian: &Hessian, d: DVec3) -> Option<f64> {
    let weights = [
        d.x * d.x,
        d.y * d.y,
        d.z * d.z,
        2.0 * d.x * d.y,
        2.0 * d.x * d.z,
        2.0 * d.y * d.z,
    ];
    Enclosure::weighted_sum_sign(hessian.iter().copied().zip(weights), 16.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;

    fn tape(text: &str) -> Tape {
        Tape::compile(&Expr::parse(text).expect("parses").root)
    }

    /// Every second derivative of a cubic in closed form, at points of the box and over it.
    #[test]
    fn the_hessian_of_a_cubic_holds_its_closed_form() {
        let t = tape("x^3 + 2*x*y*z - y^2*z + 3*z^2");
        let (lo, hi) = (DVec3::new(-0.5, 0.25, 1.0), DVec3::new(0.75, 1.5, 2.0));
        let h = enclose_hessian(&t, lo, hi, &mut Vec::new()).expect("no branches");
        let exact = |p: DVec3| [6.0 * p.x, -2.0 * p.z, 6.0, 2.0 * p.z, 2.0 * p.y, 2.0 * p.x - 2.0 * p.y];
        for i in 0..=4 {
            for j in 0..=4 {
                for k in 0..=4 {
                    let f = DVec3::new(i as f64, j as f64, k as f64) / 4.0;
                    let p = lo + (hi - lo) * f;
                    for (e, v) in h.iter().zip(exact(p)) {
                        assert!(e.lo <= v && v <= e.hi, "{v} outside [{}, {}]", e.lo, e.hi);
                    }
                }
            }
        }
        // the constant entry is a point
        assert_eq!((h[2].lo, h[2].hi), (6.0, 6.0));
    }

    #[test]
    fn curvature_signs_follow_the_quadratic_form() {
        // Φ = x² − y²: g″ = 2dx² − 2dy²
        let t = tape("x^2 - y^2");
        let h = enclose_hessian(&t, DVec3::splat(-1.0), DVec3::splat(1.0), &mut Vec::new()).expect("no branches");
        assert_eq!(curvature_sign(&h, DVec3::X), Some(1.0));
        assert_eq!(curvature_sign(&h, DVec3::Y), Some(-1.0));
        assert_eq!(curvature_sign(&h, DVec3::new(1.0, 1.0, 0.0).normalize()), None);
        assert_eq!(curvature_sign(&h, DVec3::Z), None);
        assert_eq!(curvature_sign(&h, DVec3::new(1.0, 0.5, 0.3).normalize()), Some(1.0));
    }

    #[test]
    fn tapes_with_kinks_or_undefined_entries_give_none() {
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
        assert!(enclose_hessian(&tape("abs(x) + y"), lo, hi, &mut Vec::new()).is_none());
        assert!(enclose_hessian(&tape("min(x, y)"), lo, hi, &mut Vec::new()).is_none());
        // √ at 0: its second derivative is unbounded
        assert!(enclose_hessian(&tape("sqrt(x^2 + y^2)"), lo, hi, &mut Vec::new()).is_none());
    }
}
