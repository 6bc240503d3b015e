//! Scaling by powers of two so that squares neither overflow nor underflow: the "scale first"
//! of huge and tiny magnitudes (a sphere of radius 10¹⁵⁵, a direction of length 10⁻³⁰).

/// The power of two `2ᵉ` nearest below `|x|` for a finite non-zero `x` (exponent clamped to the
/// normal range), and `1` otherwise: a scale that divides exactly.
#[inline]
#[must_use]
pub fn power_of_two_scale(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return 1.0;
    }
    match (x.to_bits() >> 52) & 0x7ff {
        0 => f64::MIN_POSITIVE, // subnormal: 2⁻¹⁰²² (dividing by it is exact)
        exponent => f64::from_bits(exponent << 52),
    }
}

/// Whether `x` lies where squares and products of a few such terms neither overflow nor
/// underflow: `2⁻²⁴⁰ ≤ |x| ≤ 2²⁴⁰` (a product of four stays within `2^±960`).
#[inline]
#[must_use]
pub fn is_square_safe(x: f64) -> bool {
    const LIMIT: f64 = 1.766_847_064_778_384e72; // 2²⁴⁰
    let a = x.abs();
    (1.0 / LIMIT..=LIMIT).contains(&a)
}

/// `|v|` without overflow or underflow of the squares: `v` is divided by a power of two near its
/// largest component first (exact) when that component is not [`is_square_safe`].
#[inline]
#[must_use]
pub fn length_scaled(v: glam::DVec3) -> f64 {
    let m = v.abs().max_element();
    if is_square_safe(m) || m == 0.0 || !m.is_finite() {
        return v.length();
    }
    let s = power_of_two_scale(m);
    (v / s).length() * s
}

/// `v/|v|` computed as [`length_scaled`] does, so that huge and tiny vectors keep their
/// direction; zero for a zero or non-finite `v`.
#[inline]
#[must_use]
pub fn normalize_scaled(v: glam::DVec3) -> glam::DVec3 {
    let m = v.abs().max_element();
    if is_square_safe(m) || m == 0.0 || !m.is_finite() {
        return v.normalize_or_zero();
    }
    (v / power_of_two_scale(m)).normalize_or_zero()
}
