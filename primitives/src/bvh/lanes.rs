//! Lane helpers shared by the SIMD walks and tests: `min`/`max` in the forms that compile to one
//! `minps`/`maxps` (NaN handling of the instruction: the second operand wins), a lane mask from
//! per-lane flags (`-1` or `0`, one bit per lane, lane `l` in bit `l`) and the iteration over a
//! mask's set lanes, lowest first.

use crate::PACKET;

/// `max` that compiles to one `maxps`.
#[inline(always)]
pub(crate) fn max_f32(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `min` that compiles to one `minps`.
#[inline(always)]
pub(crate) fn min_f32(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Bit `l` set where `flags[l]` is `-1` (all ones) rather than `0`: two `movmskps` on x86-64
/// (a bit loop otherwise, which the compiler turns into a chain of shuffles).
#[inline(always)]
pub(crate) fn lane_mask(flags: &[i32; PACKET]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128i, _mm_castsi128_ps, _mm_loadu_si128, _mm_movemask_ps};
        const _: () = assert!(PACKET == 8);
        let halves = flags.as_ptr().cast::<__m128i>();
        // SAFETY: SSE2 is in every x86-64 CPU; the two 16-byte loads stay inside `flags`
        // (32 bytes: `PACKET` is 8, checked above)
        unsafe {
            let lo = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves)));
            let hi = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves.add(1))));
            (lo | (hi << 4)) as u32
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut mask = 0;
        for (l, &f) in flags.iter().enumerate() {
            mask |= u32::from(f != 0) << l;
        }
        mask
    }
}

/// Bits of `lanes`, lowest first.
#[inline(always)]
pub(crate) fn lanes_of(lanes: u32) -> impl Iterator<Item = usize> {
    let mut rest = lanes;
    std::iter::from_fn(move || {
        (rest != 0).then(|| {
            let l = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            l
        })
    })
}
