//! Real roots of a monic quartic by Ferrari's method.

/// Real roots of `t⁴ + a t³ + b t² + c t + d = 0` (unordered; a double root may appear twice).
///
/// The quartic is depressed by `t = y − a/4` to `y⁴ + p y² + q y + r`; for `q ≈ 0` it is a
/// quadratic in `y²`, otherwise a positive root `m` of the resolvent cubic
/// `8m³ + 8p m² + (2p² − 8r) m − q² = 0` splits it into two quadratics
/// `y² ± √(2m)·y + (p/2 + m ∓ q/(2√(2m))) = 0`. The caller should polish roots it relies on
/// (e.g. by a Newton step on the original polynomial).
#[must_use]
pub fn solve_quartic(a: f64, b: f64, c: f64, d: f64) -> Vec<f64> {
    let a2 = a * a;
    let p = b - 3.0 * a2 / 8.0;
    let q = c - a * b / 2.0 + a2 * a / 8.0;
    let r = d - a * c / 4.0 + a2 * b / 16.0 - 3.0 * a2 * a2 / 256.0;
    let shift = -a / 4.0;
    let mut roots = Vec::with_capacity(4);
    let scale = 1.0 + p.abs() + r.abs().sqrt();
    if q.abs() <= 1e-14 * scale * scale.sqrt() {
        // biquadratic
        for z in quadratic_roots(1.0, p, r) {
            if z >= 0.0 {
                let y = z.sqrt();
                roots.push(y + shift);
                roots.push(-y + shift);
            }
        }
        return roots;
    }
    let m = largest_cubic_root(p, p * p / 4.0 - r, -q * q / 8.0);
    if !(m > 0.0) {
        return roots;
    }
    let s = (2.0 * m).sqrt();
    for (sign, offset) in [(1.0, -q / (2.0 * s)), (-1.0, q / (2.0 * s))] {
        for y in quadratic_roots(1.0, sign * s, p / 2.0 + m + offset) {
            roots.push(y + shift);
        }
    }
    roots
}

/// Real roots of `α x² + β x + γ` (cancellation-free pair).
fn quadratic_roots(alpha: f64, beta: f64, gamma: f64) -> Vec<f64> {
    let disc = beta * beta - 4.0 * alpha * gamma;
    if !(disc >= 0.0) {
        return Vec::new();
    }
    let q = -0.5 * (beta + disc.sqrt().copysign(beta));
    if q == 0.0 {
        return vec![0.0, 0.0];
    }
    vec![q / alpha, gamma / q]
}

/// The largest real root of `m³ + e m² + f m + g = 0`, polished by Newton's method.
fn largest_cubic_root(e: f64, f: f64, g: f64) -> f64 {
    let p = f - e * e / 3.0;
    let q = 2.0 * e * e * e / 27.0 - e * f / 3.0 + g;
    let shift = -e / 3.0;
    let disc = q * q / 4.0 + p * p * p / 27.0;
    let mut m = if disc > 0.0 {
        let s = disc.sqrt();
        (-q / 2.0 + s).cbrt() + (-q / 2.0 - s).cbrt() + shift
    } else {
        // three real roots: trigonometric form, the largest is k = 0
        let rad = (-p / 3.0).max(0.0).sqrt();
        let angle = if rad > 0.0 {
            (3.0 * q / (2.0 * p * rad)).clamp(-1.0, 1.0).acos() / 3.0
        } else {
            0.0
        };
        2.0 * rad * angle.cos() + shift
    };
    for _ in 0..4 {
        let value = ((m + e) * m + f) * m + g;
        let slope = (3.0 * m + 2.0 * e) * m + f;
        if slope == 0.0 {
            break;
        }
        let next = m - value / slope;
        if !next.is_finite() {
            break;
        }
        m = next;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_known_roots_are_found() {
        // (t − 1)(t + 2)(t − 3)(t − 0.5) = t⁴ − 2.5t³ − 4t² + 8.5t − 3
        let mut roots = solve_quartic(-2.5, -4.0, 8.5, -3.0);
        roots.sort_by(f64::total_cmp);
        for (got, want) in roots.iter().zip([-2.0, 0.5, 1.0, 3.0]) {
            assert!((got - want).abs() < 1e-9, "{roots:?}");
        }
        assert_eq!(roots.len(), 4);
    }

    #[test]
    fn no_real_roots() {
        // (t² + 1)(t² + 4)
        assert!(solve_quartic(0.0, 5.0, 0.0, 4.0).is_empty());
    }
}
