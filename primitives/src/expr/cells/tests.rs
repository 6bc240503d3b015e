//! The octree's walks against a brute-force scan of Φ along the rays.

use super::*;
use crate::expr::Expr;

/// Every `t` of a ray's range lands in exactly one cell, in order, and the cells handed out
/// contain the points (up to the margin); empty cells hold no sign change of Φ.
#[test]
fn walks_cover_the_range_and_skip_only_empty_cells() {
    let e = Expr::parse("min(sqrt(x^2 + y^2 + z^2) - 0.5, sqrt((x - 0.8)^2 + y^2 + z^2) - 0.2)").unwrap();
    let tape = e.compile();
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let tree = CellTree::new(&tape, lo, hi);
    assert_eq!(tree.sizes(), (0, 1), "only the root is made before a walk");
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
        tree.walk(o, d, range.min, range.max, &mut |leaf, ta, tb| {
            assert!(ta <= tb);
            let (l, h) = leaf.grown();
            for t in [ta, 0.5 * (ta + tb), tb] {
                let p = ray.at(t);
                assert!((p.cmpge(l) & p.cmple(h)).all(), "{p} outside {l} {h}");
                // the leaf's tape, and the tape found for the point, have the full tape's
                // value here
                // (the ends lie on cell faces, where the point may be found in a neighbour)
                let mut s = Vec::new();
                let found = tree.tape_at(p);
                if t > ta && t < tb && tb - ta > 1e-9 {
                    assert!(found.is_some(), "no leaf found for {p} inside a piece");
                }
                for tape in std::iter::once(leaf.tape()).chain(found) {
                    assert_eq!(tape.eval_f64(p.to_array(), &mut s).to_bits(), e.eval(p).to_bits());
                }
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
    let (tapes, nodes) = tree.sizes();
    assert!(tapes > 2 && nodes > 8, "{tapes} {nodes}");
}
