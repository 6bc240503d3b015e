//! Whether a search box cuts its surface: where Φ < 0 (inside) reaches a face of the box
//! `[lo, hi]`, the surface, searched only inside the box, is cut open there (or missing).
//!
//! Each face is a rectangle with one coordinate fixed. It is covered by interval evaluation
//! ([`Expr::enclose`] over the rectangle as a flat box): a piece whose enclosure is `> 0`
//! everywhere is clear; one whose enclosure is `< 0` everywhere proves the cut; any other
//! (including pieces where Φ may be undefined) is split in four, down to
//! [`FACE_DEPTH`] levels, and at that depth Φ is evaluated at the piece's centre, a cut where it is
//! `< 0`. A face where Φ only touches 0 (a sphere inscribed in its box) is not a cut. Each face
//! is given at most [`FACE_BUDGET`] enclosures; a face not decided within them is not reported
//! (only sure cuts are).

use crate::expr::Expr;
use glam::DVec3;

/// Levels of four-way splitting of a face before its pieces are judged by their centre.
pub const FACE_DEPTH: u32 = 8;

/// Most enclosures spent on one face.
pub const FACE_BUDGET: u32 = 20_000;

/// The names of the faces of a box, in the order of [`negative_faces`]'s indices: `2·axis` the
/// lower face of `axis`, `2·axis + 1` the upper one.
pub const FACE_NAMES: [&str; 6] = ["−X", "+X", "−Y", "+Y", "−Z", "+Z"];

/// A face of the box on which Φ < 0 somewhere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceCut {
    /// The face: `2·axis` lower, `2·axis + 1` upper ([`FACE_NAMES`]).
    pub face: usize,
    /// A point of the face where Φ < 0 (the centre of a piece proved negative).
    pub witness: DVec3,
}

/// The faces of the box `[lo, hi]` on which `phi` is surely negative somewhere, each with a point
/// where it is (see the module docs), in face order.
#[must_use]
pub fn negative_faces(phi: &Expr, lo: DVec3, hi: DVec3) -> Vec<FaceCut> {
    (0..6)
        .filter_map(|face| {
            let axis = face / 2;
            let at = if face % 2 == 0 { lo[axis] } else { hi[axis] };
            let (mut flo, mut fhi) = (lo, hi);
            flo[axis] = at;
            fhi[axis] = at;
            let mut budget = FACE_BUDGET;
            negative_point(phi, flo, fhi, axis, 0, &mut budget).map(|witness| FaceCut { face, witness })
        })
        .collect()
}

/// A point of the flat box `[lo, hi]` (flat along `axis`) where `phi < 0`, if one is found.
fn negative_point(phi: &Expr, lo: DVec3, hi: DVec3, axis: usize, depth: u32, budget: &mut u32) -> Option<DVec3> {
    let centre = 0.5 * (lo + hi);
    if depth >= FACE_DEPTH {
        return (phi.eval(centre) < 0.0).then_some(centre);
    }
    if *budget == 0 {
        return None;
    }
    *budget -= 1;
    let e = phi.enclose(lo, hi);
    if !e.undefined() && e.lo > 0.0 {
        return None;
    }
    if !e.undefined() && e.hi < 0.0 {
        return Some(centre);
    }
    // the two axes of the face, each halved
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    for (su, sv) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (mut piece_lo, mut piece_hi) = (lo, hi);
        for (a, s) in [(u, su), (v, sv)] {
            if s == 0 {
                piece_hi[a] = centre[a];
            } else {
                piece_lo[a] = centre[a];
            }
        }
        if let Some(p) = negative_point(phi, piece_lo, piece_hi, axis, depth + 1, budget) {
            return Some(p);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn faces(text: &str, lo: f64, hi: f64) -> Vec<usize> {
        let e = Expr::parse(text).unwrap();
        negative_faces(&e, DVec3::splat(lo), DVec3::splat(hi))
            .iter()
            .map(|c| {
                // the witness is on the face and Φ is negative there
                let axis = c.face / 2;
                let at = if c.face % 2 == 0 { lo } else { hi };
                assert_eq!(c.witness[axis], at);
                assert!(e.eval(c.witness) < 0.0, "{text}: {:?}", c);
                c.face
            })
            .collect()
    }

    #[test]
    fn a_box_that_encloses_the_surface_cuts_nothing() {
        // a unit sphere in boxes of half-width 1.5 and exactly 1 (touching the faces at 6 points)
        assert_eq!(faces("x^2 + y^2 + z^2 - 1", -1.5, 1.5), Vec::<usize>::new());
        assert_eq!(faces("x^2 + y^2 + z^2 - 1", -1.0, 1.0), Vec::<usize>::new());
    }

    #[test]
    fn a_box_smaller_than_the_surface_is_cut_on_every_face_it_crosses() {
        // the unit sphere in a box of half-width 0.9: every face crosses it
        assert_eq!(faces("x^2 + y^2 + z^2 - 1", -0.9, 0.9), vec![0, 1, 2, 3, 4, 5]);
        // a sphere of radius 1 centred at (0.5, 0, 0) in [-1, 1]³: only the +X face (x = 1 is
        // 0.5 from the centre) is cut; x = −1 is 1.5 away, and the ±Y, ±Z faces only touch it
        assert_eq!(faces("(x - 0.5)^2 + y^2 + z^2 - 1", -1.0, 1.0), vec![1]);
        // a slab |z| < 2 in [-1, 1]³: the four side faces are inside it, the ±Z faces too
        assert_eq!(faces("abs(z) - 2", -1.0, 1.0), vec![0, 1, 2, 3, 4, 5]);
        // a thin cylinder along x of radius 0.2: cut by the ±X faces only
        assert_eq!(faces("y^2 + z^2 - 0.04", -1.0, 1.0), vec![0, 1]);
    }
}
