//! Shared numerics: floating-point error bounds, orthonormal bases, 2-D polygon predicates, a
//! cancellation-free quadratic solver.

pub mod basis;
pub mod polygon2d;
pub mod quadratic;

pub use basis::orthonormal_basis;
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
