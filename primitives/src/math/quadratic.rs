//! Real roots of `a t² + 2b t + c = 0` without catastrophic cancellation.

/// The finite real roots of `a t² + 2b t + c = 0` in increasing order, given the reduced
/// discriminant `disc = b² − a c`, which the caller computes in a cancellation-free form of its
/// own (for a sphere `a r² − |f × d|²`).
///
/// The root away from `−b` is `q = −(b + sign(b)·√disc)`; the roots are `q/a` and `c/q`, neither
/// of which subtracts nearly equal numbers (Press et al., *Numerical Recipes* §5.6).
///
/// - `disc < 0` or NaN: `None` (NaN is rejected explicitly, not by comparison fall-through).
/// - `a = 0` (the equation is linear): `q = −2b`, so `q/a` is infinite and dropped and `c/q` is
///   the single root `−c/(2b)`, returned twice.
/// - `b = disc = 0`: `q = 0`, `q/a = 0` is the double root.
/// - `a = b = 0`: no isolated root, `None`.
///
/// A non-finite candidate is never returned.
#[inline(always)]
#[must_use]
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "`!(disc >= 0)` rejects NaN as well")]
pub fn solve_quadratic(a: f64, b: f64, c: f64, disc: f64) -> Option<(f64, f64)> {
    if !(disc >= 0.0) {
        return None;
    }
    let q = -(b + disc.sqrt().copysign(b));
    let (t0, t1) = (q / a, c / q);
    match (t0.is_finite(), t1.is_finite()) {
        (true, true) => Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) }),
        (true, false) => Some((t0, t0)),
        (false, true) => Some((t1, t1)),
        (false, false) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solve(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
        solve_quadratic(a, b, c, b * b - a * c)
    }

    #[test]
    fn ordered_roots_of_a_plain_quadratic() {
        // (t − 1)(t − 3) = t² − 4t + 3: a = 1, 2b = −4, c = 3
        assert_eq!(solve(1.0, -2.0, 3.0), Some((1.0, 3.0)));
        // −(t + 2)(t − 5) = −t² + 3t + 10
        assert_eq!(solve(-1.0, 1.5, 10.0), Some((-2.0, 5.0)));
    }

    #[test]
    fn small_root_keeps_full_precision() {
        // t² − 2·10⁸ t + 1 = 0: roots 10⁸ ± √(10¹⁶ − 1); small root ≈ 5·10⁻⁹ (1 + 2.5·10⁻¹⁷).
        // The textbook formula (−b − √disc)/a loses every digit here.
        let (t0, t1) = solve(1.0, -1e8, 1.0).unwrap();
        assert!((t0 - 5e-9).abs() <= 1e-24, "t0 = {t0:e}");
        assert!((t1 - 2e8).abs() <= 1e-7, "t1 = {t1:e}");
        let textbook = 1e8 - (1e16_f64 - 1.0).sqrt();
        assert!(
            (textbook - 5e-9).abs() > 1e-10,
            "the comparison would not show anything"
        );
    }

    #[test]
    fn degenerate_cases_give_no_nan() {
        // linear: 2·2 t − 8 = 0
        assert_eq!(solve(0.0, 2.0, -8.0), Some((2.0, 2.0)));
        assert_eq!(solve(-0.0, -2.0, -8.0), Some((-2.0, -2.0)));
        // a = b = 0: no isolated root
        assert_eq!(solve(0.0, 0.0, 1.0), None);
        assert_eq!(solve(0.0, 0.0, 0.0), None);
        // double root at 0
        assert_eq!(solve(2.0, 0.0, 0.0), Some((0.0, 0.0)));
        // no real root, NaN discriminant
        assert_eq!(solve(1.0, 0.0, 1.0), None);
        assert_eq!(solve_quadratic(1.0, 0.0, 1.0, f64::NAN), None);
    }
}
