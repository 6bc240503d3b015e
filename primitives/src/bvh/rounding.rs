//! f64 → f32 rounding toward −∞ and +∞: how the hierarchies' f32 boxes and ray ranges are made
//! conservative (a box rounded outward holds its f64 box; a range rounded outward holds the f64
//! range), so that the f32 traversal never drops a hit the f64 tests would find.

/// Rounds an f64 to the nearest f32 not above it (boxes and ray ranges rounded outward).
///
/// A subnormal `x` (a range opened at 0 starts at `0.next_up()`) is answered without converting
/// it: on x86 an arithmetic operation or conversion on a subnormal operand takes a microcode
/// assist of some hundred cycles, more than the rest of a ray's set-up.
#[inline]
pub(crate) fn round_down(x: f64) -> f32 {
    if x != 0.0 && x.abs() < f64::MIN_POSITIVE {
        // below f32's smallest subnormal: 0 from above, −2⁻¹⁴⁹ from below
        return if x > 0.0 { 0.0 } else { -f32::from_bits(1) };
    }
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

/// Rounds an f64 to the nearest f32 not below it.
#[inline]
pub(crate) fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        y.next_up()
    } else {
        y
    }
}
