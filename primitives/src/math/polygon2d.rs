//! 2-D point-in-polygon predicates, named after their preconditions.
//!
//! | function                   | precondition                                         | rule          |
//! |----------------------------|------------------------------------------------------|---------------|
//! | [`point_in_convex_polygon`] | one convex ring, counter-clockwise                   | same sign     |
//! | [`point_in_polygon`]        | any rings (outer ring and holes, either orientation) | even-odd      |
//! | [`ConvexRing::contains`]    | as [`point_in_convex_polygon`], prepared once        | same sign     |
//!
//! # Exactness
//! Every side test is the sign of the orientation determinant [`orient2d`], computed **exactly**
//! by Shewchuk's adaptive predicates (crate `robust`). No x-intercept is ever computed, so the
//! answers are exact for any finite `f64` input.
//!
//! # Boundary points: one symbolic rule for both functions
//! A query point `p` is classified as if it were moved to `p + (ε, ε²)` for an infinitesimal
//! `ε > 0` (simulation of simplicity). That point never lies on an edge, so every point of the
//! plane gets a definite answer, and:
//! - of a counter-clockwise polygon, points on the **left and bottom** edges are inside and
//!   points on the **right and top** edges are outside; a vertex is inside exactly when the
//!   region just up and to its right is inside;
//! - two polygons that share an edge (in either direction) and do not overlap claim each point of
//!   it **exactly once**; around a shared vertex exactly one polygon of a fan claims the vertex;
//! - [`point_in_convex_polygon`] and [`point_in_polygon`] give the **same** answer for every
//!   point whenever the former's precondition holds.
//!
//! In the crossing test this is the half-open rule: an edge counts when exactly one endpoint is
//! strictly above `p.y` (an upward edge includes its start and excludes its end), and it counts as
//! a crossing to the right of `p` when `p` is strictly left of the edge directed upward.

use glam::DVec2;
use robust::Coord;

/// Twice the signed area of the triangle `(a, b, c)` with **exact sign**: positive when `c` is
/// left of the directed line `a → b` (counter-clockwise), negative when right, zero when collinear.
/// The magnitude is approximate; only the sign is guaranteed.
#[inline(always)]
#[must_use]
pub fn orient2d(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    robust::orient2d(
        Coord { x: a.x, y: a.y },
        Coord { x: b.x, y: b.y },
        Coord { x: c.x, y: c.y },
    )
}

/// Whether `p` is inside the convex polygon `ccw` by the same-sign test (strictly left of every
/// edge), with boundary points decided by the module's `p + (ε, ε²)` rule.
///
/// **Precondition**: `ccw` is a convex polygon in counter-clockwise order (collinear and repeated
/// vertices are allowed). For other input the answer is meaningless; use [`point_in_polygon`].
/// Fewer than three vertices contain nothing.
#[must_use]
pub fn point_in_convex_polygon(p: DVec2, ccw: &[DVec2]) -> bool {
    if ccw.len() < 3 {
        return false;
    }
    let mut prev = ccw[ccw.len() - 1];
    for &cur in ccw {
        let side = orient2d(prev, cur, p);
        if side < 0.0 {
            return false;
        }
        if side == 0.0 {
            // p on the edge's line: the sign of orient(prev, cur, p + (ε, ε²)) is that of
            // d.x·ε² − d.y·ε; a zero-length edge constrains nothing
            let d = cur - prev;
            let perturbed = if d.y != 0.0 { -d.y } else { d.x };
            if perturbed < 0.0 {
                return false;
            }
        }
        prev = cur;
    }
    true
}

/// A convex counter-clockwise ring prepared for [`point_in_convex_polygon`]'s test: the same
/// answer for every point, with the edges parallel to an axis (a rectangle's every edge, a
/// ground's) reduced to four comparisons.
///
/// For an edge `a → b` with `b.y = a.y` the orientation determinant is exactly
/// `(b.x − a.x)·(p.y − a.y)`: its sign is `sign(b.x − a.x)` times the comparison of `p.y` with
/// `a.y`, and where `p.y = a.y` the perturbation rule keeps `p` when `b.x > a.x`. So a rightward
/// horizontal edge keeps `p.y ≥ a.y` and a leftward one `p.y < a.y`; likewise an upward
/// vertical edge keeps `p.x < a.x` and a downward one `p.x ≥ a.x`. Edges on parallel lines
/// combine into one bound each way (the largest lower bound, the smallest upper one). Other
/// edges keep the exact determinant; zero-length edges constrain nothing and are dropped.
///
/// The determinant is exact as long as nothing overflows or underflows, so the prepared test
/// is made only for rings whose coordinates are within [`ConvexRing::LIMIT`] in magnitude and
/// asked only of points within it ([`ConvexRing::contains`] answers `None` for others, NaN
/// included, which then take [`point_in_convex_polygon`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ConvexRing {
    /// Kept: `p.x ≥ x_at_least`, `p.x < x_below`, `p.y ≥ y_at_least`, `p.y < y_below` (±∞ where
    /// no edge bounds that side); no bound holds at all for a ring of fewer than three vertices.
    x_at_least: f64,
    x_below: f64,
    y_at_least: f64,
    y_below: f64,
    /// The other edges, `(prev, cur)`.
    general: Vec<(DVec2, DVec2)>,
}

impl ConvexRing {
    /// The largest coordinate magnitude of the prepared test: differences stay below `2·10¹⁰⁰` and
    /// products below `4·10²⁰⁰`, far from overflow.
    pub const LIMIT: f64 = 1e100;

    /// The edge tests of `ccw` (the precondition of [`point_in_convex_polygon`]); `None` where a
    /// coordinate exceeds [`ConvexRing::LIMIT`] in magnitude (or is not finite).
    #[must_use]
    pub fn new(ccw: &[DVec2]) -> Option<Self> {
        if !ccw
            .iter()
            .all(|v| v.is_finite() && v.abs().max_element() <= Self::LIMIT)
        {
            return None;
        }
        let mut ring = Self {
            x_at_least: f64::NEG_INFINITY,
            x_below: f64::INFINITY,
            y_at_least: f64::NEG_INFINITY,
            y_below: f64::INFINITY,
            general: Vec::new(),
        };
        if ccw.len() < 3 {
            // contains nothing: an empty range
            ring.x_below = f64::NEG_INFINITY;
            return Some(ring);
        }
        for (i, &cur) in ccw.iter().enumerate() {
            let prev = ccw[(i + ccw.len() - 1) % ccw.len()];
            let d = cur - prev;
            if d == DVec2::ZERO {
                continue;
            } else if d.y == 0.0 {
                if d.x > 0.0 {
                    ring.y_at_least = ring.y_at_least.max(prev.y);
                } else {
                    ring.y_below = ring.y_below.min(prev.y);
                }
            } else if d.x == 0.0 {
                if d.y > 0.0 {
                    ring.x_below = ring.x_below.min(prev.x);
                } else {
                    ring.x_at_least = ring.x_at_least.max(prev.x);
                }
            } else {
                ring.general.push((prev, cur));
            }
        }
        Some(ring)
    }

    /// [`point_in_convex_polygon`]`(p, ring)`, or `None` where `p` lies beyond
    /// [`ConvexRing::LIMIT`] (or is NaN). Inlined into the polygon's test, which calls it for
    /// every pixel that meets a ground polygon's plane.
    #[inline(always)]
    #[must_use]
    pub fn contains(&self, p: DVec2) -> Option<bool> {
        // false for NaN
        if !(p.x.abs() <= Self::LIMIT && p.y.abs() <= Self::LIMIT) {
            return None;
        }
        let bounded = (p.x >= self.x_at_least) & (p.x < self.x_below) & (p.y >= self.y_at_least) & (p.y < self.y_below);
        // the edges along neither axis, tested out of line (an axis-aligned rectangle, the usual
        // ground, has none)
        #[inline(never)]
        fn inside_general(general: &[(DVec2, DVec2)], p: DVec2) -> bool {
            general.iter().all(|&(prev, cur)| {
                let side = orient2d(prev, cur, p);
                // on the line (`side` = 0): `d.y ≠ 0` here, so the rule drops `p` when `d.y > 0`
                !(side < 0.0 || (side == 0.0 && cur.y > prev.y))
            })
        }
        Some(bounded && (self.general.is_empty() || inside_general(&self.general, p)))
    }
}

/// Whether `p` is inside the region bounded by `rings` by the even-odd crossing rule, with
/// boundary points decided by the module's `p + (ε, ε²)` rule.
///
/// `rings` holds the outer ring and any number of holes, each a closed ring given without
/// repeating its first vertex. Because the rule is even-odd, the rings' orientations do not
/// matter (holes may be given either way) and a hole may touch the outer ring; where rings
/// overlap, a point is inside when it lies inside an odd number of them. Rings with fewer than
/// three vertices add nothing.
#[must_use]
pub fn point_in_polygon<R: AsRef<[DVec2]>>(p: DVec2, rings: &[R]) -> bool {
    let mut inside = false;
    for ring in rings {
        let ring = ring.as_ref();
        if ring.len() < 3 {
            continue;
        }
        let mut prev = ring[ring.len() - 1];
        for &cur in ring {
            let (prev_above, cur_above) = (prev.y > p.y, cur.y > p.y);
            if prev_above != cur_above {
                // direct the edge upward; the crossing is right of p iff p is strictly left of it
                let (low, high) = if cur_above { (prev, cur) } else { (cur, prev) };
                if orient2d(low, high, p) > 0.0 {
                    inside = !inside;
                }
            }
            prev = cur;
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn ring(points: &[(i64, i64)]) -> Vec<DVec2> {
        points.iter().map(|&(x, y)| DVec2::new(x as f64, y as f64)).collect()
    }

    /// Reference: parity of the winding number of `p + (ε, ε²)` in exact i128 arithmetic.
    ///
    /// Coordinates are integers in `[-R, R]`; everything is scaled by `K` and the point is moved
    /// by `(k, 1)` with `R ≪ k ≪ K`, which realises the symbolic perturbation with integers: the
    /// moved point is at no vertex's height, on no edge's line, and on the same side of every
    /// edge as `p + (ε, ε²)`. The winding number then follows from signed upward/downward
    /// crossings without any tie rule.
    fn reference_inside(p: (i64, i64), rings: &[Vec<(i64, i64)>]) -> bool {
        const K: i128 = 1 << 24;
        const SHIFT: i128 = 1 << 10;
        let (px, py) = (K * p.0 as i128 + SHIFT, K * p.1 as i128 + 1);
        let mut winding = 0i64;
        for ring in rings {
            for i in 0..ring.len() {
                let (ax, ay) = (K * ring[i].0 as i128, K * ring[i].1 as i128);
                let j = (i + 1) % ring.len();
                let (bx, by) = (K * ring[j].0 as i128, K * ring[j].1 as i128);
                if (ax, ay) == (bx, by) {
                    continue; // a repeated vertex: no edge
                }
                let cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
                assert_ne!(cross, 0, "perturbed point lies on an edge line");
                if ay < py && by > py && cross > 0 {
                    winding += 1;
                } else if ay > py && by < py && cross < 0 {
                    winding -= 1;
                }
            }
        }
        winding % 2 != 0
    }

    fn to_f64(rings: &[Vec<(i64, i64)>]) -> Vec<Vec<DVec2>> {
        rings.iter().map(|r| ring(r)).collect()
    }

    /// Compares [`point_in_polygon`] with the reference on `samples` seeded points (a third on
    /// vertices, a third on integer points of edges, a third on a grid); returns how many were
    /// inside.
    fn check_against_reference(name: &str, rings: &[Vec<(i64, i64)>], seed: u64, samples: usize) -> usize {
        let float = to_f64(rings);
        let mut rng = StdRng::seed_from_u64(seed);
        let all: Vec<(i64, i64)> = rings.iter().flatten().copied().collect();
        let (lo, hi) = (-12, 12);
        let mut inside = 0;
        for k in 0..samples {
            // a third each: vertices, points on edges, grid points
            let q = match k % 3 {
                0 => all[rng.random_range(0..all.len())],
                1 => {
                    let ring = &rings[rng.random_range(0..rings.len())];
                    let i = rng.random_range(0..ring.len());
                    let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                    // an integer point of the segment, if it has one besides the ends
                    let g = gcd((b.0 - a.0).abs(), (b.1 - a.1).abs()).max(1);
                    let s = rng.random_range(0..=g);
                    (a.0 + (b.0 - a.0) / g * s, a.1 + (b.1 - a.1) / g * s)
                }
                _ => (rng.random_range(lo..=hi), rng.random_range(lo..=hi)),
            };
            let expected = reference_inside(q, rings);
            let got = point_in_polygon(DVec2::new(q.0 as f64, q.1 as f64), &float);
            assert_eq!(got, expected, "{name}: point {q:?}");
            inside += usize::from(got);
        }
        inside
    }

    fn assert_mixed(name: &str, inside: usize, samples: usize) {
        assert!(
            inside > samples / 20 && inside < samples - samples / 20,
            "{name}: degenerate sample ({inside} inside)"
        );
    }

    fn gcd(a: i64, b: i64) -> i64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }

    #[test]
    fn unit_square_boundary_rule() {
        let sq = ring(&[(0, 0), (2, 0), (2, 2), (0, 2)]);
        let rings = [sq.clone()];
        let cases = [
            ((1.0, 1.0), true),
            ((0.0, 1.0), true),  // left edge
            ((2.0, 1.0), false), // right edge
            ((1.0, 0.0), true),  // bottom edge
            ((1.0, 2.0), false), // top edge
            ((0.0, 0.0), true),  // bottom-left vertex
            ((2.0, 0.0), false),
            ((2.0, 2.0), false),
            ((0.0, 2.0), false),
            ((3.0, 1.0), false),
        ];
        for ((x, y), want) in cases {
            let p = DVec2::new(x, y);
            assert_eq!(point_in_polygon(p, &rings), want, "crossing test at {p}");
            assert_eq!(point_in_convex_polygon(p, &sq), want, "convex test at {p}");
        }
    }

    #[test]
    fn point_on_shared_edge_claimed_once() {
        // two triangles sharing an oblique edge with non-representable coordinates; the edge is
        // traversed in opposite directions, as in a mesh
        let (a, b) = (DVec2::new(0.1, 0.3), DVec2::new(0.7, 2.1));
        let left = [a, b, DVec2::new(-1.3, 1.9)];
        let right = [b, a, DVec2::new(1.7, 0.2)];
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..20_000 {
            // on the edge up to rounding, and the edge's endpoints themselves
            let s: f64 = rng.random_range(0.0..=1.0);
            let p = if rng.random_range(0..10) == 0 {
                [a, b][rng.random_range(0..2)]
            } else {
                a + s * (b - a)
            };
            let in_left = point_in_polygon(p, &[left]);
            let in_right = point_in_polygon(p, &[right]);
            // at the endpoints the pair covers the point only if the union does
            let union = point_in_polygon(p, &[[a, DVec2::new(1.7, 0.2), b, DVec2::new(-1.3, 1.9)]]);
            assert_eq!(u8::from(in_left) + u8::from(in_right), u8::from(union), "point {p:?}");
            assert_eq!(point_in_convex_polygon(p, &left), in_left);
            assert_eq!(point_in_convex_polygon(p, &right), in_right);
        }
    }

    #[test]
    fn shared_vertex_of_a_fan_claimed_once() {
        // eight triangles around an interior vertex with awkward coordinates
        let c = DVec2::new(0.3, -0.7);
        let spokes: Vec<DVec2> = (0..8)
            .map(|i| c + DVec2::from_angle(0.4 + i as f64 * std::f64::consts::TAU / 8.0) * 1.1)
            .collect();
        let claims = (0..8)
            .filter(|&i| {
                let tri = [c, spokes[i], spokes[(i + 1) % 8]];
                let a = point_in_polygon(c, &[tri]);
                assert_eq!(a, point_in_convex_polygon(c, &tri));
                a
            })
            .count();
        assert_eq!(claims, 1);
    }

    #[test]
    fn horizontal_line_through_vertices() {
        // a zig-zag whose vertices lie on the query's horizontal line y = 2
        let rings = vec![vec![
            (0, 0),
            (6, 0),
            (6, 4),
            (5, 2),
            (4, 4),
            (3, 2),
            (2, 4),
            (1, 2),
            (0, 4),
        ]];
        let f = to_f64(&rings);
        let expected = [false, true, true, true, true, true, true, false, false];
        for (x, want) in (-1..=7).zip(expected) {
            let p = DVec2::new(x as f64, 2.0);
            assert_eq!(point_in_polygon(p, &f), want, "at {p}");
            assert_eq!(reference_inside((x, 2), &rings), want, "reference at {p}");
        }
        // inside the teeth just below the tips' line, outside between tips above it
        assert!(point_in_polygon(DVec2::new(2.5, 2.0), &f));
        assert!(!point_in_polygon(DVec2::new(1.0, 3.0), &f));
        assert!(point_in_polygon(DVec2::new(2.0, 3.0), &f));
    }

    #[test]
    fn concave_polygons_against_exact_winding() {
        let comb = vec![vec![
            (-8, -8),
            (8, -8),
            (8, 8),
            (4, 8),
            (4, -2),
            (0, -2),
            (0, 8),
            (-4, 8),
            (-4, 0),
            (-8, 0),
        ]];
        assert_mixed("comb", check_against_reference("comb", &comb, 1, 6000), 6000);
        // a spiral-ish concave ring with collinear vertices on several edges
        let spiral = vec![vec![
            (-10, -10),
            (0, -10),
            (10, -10),
            (10, 10),
            (-6, 10),
            (-6, -4),
            (4, -4),
            (4, 4),
            (0, 4),
            (0, 0),
            (-2, 0),
            (-2, 6),
            (6, 6),
            (6, -6),
            (-8, -6),
            (-8, 10),
            (-10, 10),
            (-10, 0),
        ]];
        assert_mixed("spiral", check_against_reference("spiral", &spiral, 2, 6000), 6000);
    }

    #[test]
    fn holes_in_either_orientation_and_touching_the_outer_ring() {
        let outer = vec![(-10, -10), (10, -10), (10, 10), (-10, 10)];
        let ccw_hole = vec![(-5, -5), (0, -5), (0, 0), (-5, 0)];
        let cw_hole = vec![(2, 2), (2, 7), (7, 7), (7, 2)];
        // touches the outer ring along part of its right edge and at a vertex
        let touching = vec![(10, -8), (10, -2), (5, -5)];
        let corner = vec![(-10, 10), (-7, 6), (-4, 10)];
        let rings = vec![outer, ccw_hole, cw_hole, touching, corner];
        assert_mixed("holes", check_against_reference("holes", &rings, 3, 9000), 9000);
        let f = to_f64(&rings);
        assert!(!point_in_polygon(DVec2::new(-2.5, -2.5), &f));
        assert!(!point_in_polygon(DVec2::new(4.5, 4.5), &f));
        assert!(!point_in_polygon(DVec2::new(9.0, -5.0), &f));
        assert!(point_in_polygon(DVec2::new(1.0, 1.0), &f));
    }

    #[test]
    fn random_star_polygons_against_exact_winding() {
        let mut rng = StdRng::seed_from_u64(11);
        let mut total = 0;
        for case in 0..40 {
            let n = rng.random_range(3..14);
            let mut angles: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect();
            angles.sort_by(f64::total_cmp);
            let mut outer: Vec<(i64, i64)> = angles
                .iter()
                .map(|a| {
                    let r = rng.random_range(2.0..10.0);
                    ((r * a.cos()).round() as i64, (r * a.sin()).round() as i64)
                })
                .collect();
            outer.dedup();
            if case % 2 == 1 {
                outer.reverse();
            }
            total += check_against_reference(&format!("star {case}"), &[outer], 100 + case, 1500);
        }
        assert_mixed("stars", total, 40 * 1500);
    }

    #[test]
    fn convex_and_crossing_tests_agree_on_convex_polygons() {
        let mut rng = StdRng::seed_from_u64(5);
        let polys = [
            vec![(-6, -6), (0, -9), (6, -6), (9, 0), (6, 6), (0, 9), (-6, 6), (-9, 0)],
            vec![(-4, -4), (0, -4), (4, -4), (4, 0), (4, 4), (-4, 4)], // collinear vertices
            vec![(-7, -3), (5, -8), (2, 9)],
        ];
        let mut checked = 0;
        for poly in &polys {
            let f = ring(poly);
            for _ in 0..5000 {
                let p = DVec2::new(rng.random_range(-10..=10) as f64, rng.random_range(-10..=10) as f64) * 0.5;
                let a = point_in_convex_polygon(p, &f);
                assert_eq!(a, point_in_polygon(p, &[&f]), "{poly:?} at {p}");
                checked += 1;
            }
            for v in &f {
                assert_eq!(point_in_convex_polygon(*v, &f), point_in_polygon(*v, &[&f]));
            }
        }
        assert_eq!(checked, 15_000);
    }

    /// The prepared ring answers as [`point_in_convex_polygon`] everywhere: rectangles and
    /// other polygons with axis-parallel edges (either orientation of each), with collinear and
    /// repeated vertices, general convex ones; points on vertices, on edges, on the edges' lines
    /// beyond them and on a grid, and points off by one ulp of a vertex coordinate.
    #[test]
    fn prepared_convex_ring_equals_the_direct_test() {
        let mut rng = StdRng::seed_from_u64(77);
        let polys = [
            vec![(-4, -3), (5, -3), (5, 2), (-4, 2)],                  // rectangle
            vec![(-4, -3), (0, -3), (5, -3), (5, 2), (5, 2), (-4, 2)], // collinear, repeated
            vec![(-6, -2), (6, -2), (3, 5), (-3, 5)],                  // trapezoid
            vec![(0, -6), (6, 0), (0, 6), (-6, 0)],                    // diamond: no axis edge
            vec![(-5, -5), (5, -5), (5, 5)],                           // right triangle
            vec![(-6, -6), (0, -9), (6, -6), (9, 0), (6, 6), (0, 9), (-6, 6), (-9, 0)],
        ];
        let mut inside = 0;
        let mut checked = 0;
        for (n, poly) in polys.iter().enumerate() {
            let mut f = ring(poly);
            // the same polygon scaled by a non-integer, so the coordinates are not small integers
            if n % 2 == 1 {
                f.iter_mut().for_each(|v| *v *= 0.37);
            }
            let prepared = ConvexRing::new(&f).expect("small coordinates");
            let mut points: Vec<DVec2> = f.clone();
            for i in 0..f.len() {
                let (a, b) = (f[i], f[(i + 1) % f.len()]);
                for s in [-0.5, 0.0, 0.25, 0.5, 1.0, 1.5] {
                    points.push(a + (b - a) * s);
                }
                for v in [a.x, a.y] {
                    let (up, down) = (v.next_up(), v.next_down());
                    points.extend([
                        DVec2::new(up, a.y),
                        DVec2::new(down, a.y),
                        DVec2::new(a.x, up),
                        DVec2::new(a.x, down),
                    ]);
                }
            }
            for _ in 0..3000 {
                points.push(DVec2::new(rng.random_range(-20..=20) as f64, rng.random_range(-20..=20) as f64) * 0.5);
            }
            for p in points {
                let expected = point_in_convex_polygon(p, &f);
                assert_eq!(prepared.contains(p), Some(expected), "{poly:?} at {p:?}");
                inside += usize::from(expected);
                checked += 1;
            }
        }
        assert!(
            inside > checked / 20 && inside < checked - checked / 20,
            "{inside} of {checked}"
        );
        let line = [DVec2::ZERO, DVec2::ONE];
        assert_eq!(
            ConvexRing::new(&line).and_then(|r| r.contains(DVec2::ZERO)),
            Some(false)
        );
        let square = ring(&[(0, 0), (1, 0), (1, 1), (0, 1)]);
        let prepared = ConvexRing::new(&square).expect("small coordinates");
        for far in [
            DVec2::new(f64::NAN, 0.5),
            DVec2::new(0.5, f64::INFINITY),
            DVec2::new(2e100, 0.5),
        ] {
            assert_eq!(prepared.contains(far), None, "{far:?}");
        }
        assert_eq!(ConvexRing::new(&[DVec2::ZERO, DVec2::X * 1e101, DVec2::ONE]), None);
    }

    #[test]
    fn degenerate_input_contains_nothing() {
        let line = [DVec2::ZERO, DVec2::ONE];
        assert!(!point_in_convex_polygon(DVec2::ZERO, &line));
        assert!(!point_in_polygon(DVec2::ZERO, &[line]));
    }
}
