//! Shared numerics: floating-point error bounds, error-free transformations and compensated
//! sums of products, orthonormal bases, 2-D polygon predicates, a cancellation-free quadratic
//! solver.

pub mod basis;
pub mod enclosure;
pub mod magnitude;
pub mod polygon2d;
pub mod quadratic;
pub(crate) mod ulps;

pub use basis::orthonormal_basis;
pub use magnitude::{is_square_safe, length_scaled, normalize_scaled, power_of_two_scale};
pub use quadratic::solve_quadratic;

/// `γₙ = n·ε / (1 − n·ε)` with ε the f64 unit roundoff (2⁻⁵³): the relative error bound of `n`
/// successive rounded operations (Higham; pbrt-v4 §6.8).
#[inline]
#[must_use]
pub const fn gamma(n: u32) -> f64 {
    let e = f64::EPSILON * 0.5;
    (n as f64 * e) / (1.0 - n as f64 * e)
}

/// Central-difference gradient of `f` at `p` with step `h` (error O(h²)).
#[must_use]
pub fn central_difference(f: impl Fn(glam::DVec3) -> f64, p: glam::DVec3, h: f64) -> glam::DVec3 {
    use glam::DVec3;
    let dx = DVec3::new(h, 0.0, 0.0);
    let dy = DVec3::new(0.0, h, 0.0);
    let dz = DVec3::new(0.0, 0.0, h);
    DVec3::new(f(p + dx) - f(p - dx), f(p + dy) - f(p - dy), f(p + dz) - f(p - dz)) / (2.0 * h)
}

/// `(p, e)` with `p = fl(a·b)` and `a·b = p + e` exactly (fused multiply-add).
#[inline(always)]
#[must_use]
pub fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// `(s, e)` with `s = fl(a + b)` and `a + b = s + e` exactly (Knuth's two-sum).
#[inline(always)]
#[must_use]
pub fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `Σ aᵢ·bᵢ` as if computed in twice the working precision, then rounded (algorithm Dot2 of
/// Ogita, Rump and Oishi, "Accurate sum and dot product", SIAM J. Sci. Comput. 2005): the error
/// is at most `ε·|Σ| + γₙ²·Σ|aᵢbᵢ|`, so cancellation between the terms costs nothing until it
/// reaches about 10⁻¹⁶ of their size.
#[inline(always)]
#[must_use]
pub fn sum_of_products<const N: usize>(terms: [(f64, f64); N]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (a, b) in terms {
        let (p, e) = two_prod(a, b);
        let (t, f) = two_sum(s, p);
        s = t;
        c += e + f;
    }
    s + c
}

/// `a·b − c·d` within 1.5 ulp (Kahan's algorithm with a fused multiply-add), also when the two
/// products nearly cancel.
#[inline(always)]
#[must_use]
pub fn difference_of_products(a: f64, b: f64, c: f64, d: f64) -> f64 {
    let cd = c * d;
    let error = c.mul_add(-d, cd);
    a.mul_add(b, -cd) + error
}

/// `a × b` with each component within 1.5 ulp ([`difference_of_products`]), also for nearly
/// parallel vectors.
#[inline(always)]
#[must_use]
pub fn cross_accurate(a: glam::DVec3, b: glam::DVec3) -> glam::DVec3 {
    glam::DVec3::new(
        difference_of_products(a.y, b.z, a.z, b.y),
        difference_of_products(a.z, b.x, a.x, b.z),
        difference_of_products(a.x, b.y, a.y, b.x),
    )
}

/// `⟨a, b⟩ − c` by [`sum_of_products`].
#[inline(always)]
#[must_use]
pub fn dot_minus(a: glam::DVec3, b: glam::DVec3, c: f64) -> f64 {
    sum_of_products([(a.x, b.x), (a.y, b.y), (a.z, b.z), (c, -1.0)])
}

#[cfg(test)]
mod compensated_tests {
    use super::*;

    #[test]
    fn compensated_forms_survive_cancellation() {
        // (1e8 + 1)² − 1e16 = 2e8 + 1, lost by plain f64 (1e16 + 2e8 + 1 rounds)
        let x = 1e8 + 1.0;
        assert_eq!(sum_of_products([(x, x), (-1e8, 1e8)]), 2e8 + 1.0);
        let (a, b) = (1.0 + f64::EPSILON, 1.0 - f64::EPSILON);
        // a·b − 1 = −ε²
        assert_eq!(difference_of_products(a, b, 1.0, 1.0), -f64::EPSILON * f64::EPSILON);
        let c = cross_accurate(glam::DVec3::new(1e4, 1.0, 0.0), glam::DVec3::new(1e4 + 1e-8, 1.0, 0.0));
        // exact: 1e4·1 − 1·fl(1e4 + 1e-8) = 1e4 − fl(1e4 + 1e-8), itself exact (Sterbenz)
        assert_eq!(c.z, 1e4 - (1e4 + 1e-8), "{c}");
    }
}
