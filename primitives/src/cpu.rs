//! Run-time CPU dispatch: one build runs on every x86-64 CPU, and the hot code takes the widest
//! instructions the CPU has.
//!
//! The crate is compiled for the architecture's baseline (SSE2 on x86-64). [`with_fma!`] runs a
//! function inlined into a copy compiled with AVX2 and FMA when the CPU has both (checked once, then
//! cached by `std`), so that the closure, inlined there, uses them: `f64::mul_add` (the
//! error-free products of [`crate::math`]) becomes one `vfmadd` instead of a call to the
//! software fused multiply-add, and vector code gets 256-bit registers. Results are bit-identical
//! either way: `mul_add` is correctly rounded in both, and Rust never contracts `a·b + c` into a
//! fused operation on its own.

/// Whether the CPU running this has AVX2 and FMA (x86-64 only; always `false` elsewhere).
#[inline]
#[must_use]
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Calls the `#[inline(always)]` function `$f` with the given arguments, through a copy
/// compiled with AVX2 and FMA where the CPU has them (see the module docs): the argument list
/// names each parameter with its type and value, `with_fma!(test(x: f64 = 1.0) -> f64)`. Expands
/// to an expression; `$f` is inlined into both copies, so the fast one really is compiled for
/// the wider target (a closure shared by both would be compiled once, for the baseline). Both
/// copies are out of line, so the expression itself is a test of the CPU's features and a call:
/// inlined, the baseline copy made every call save registers and set up a frame for code it
/// never runs on a CPU with AVX2 (a primitive's `intersect` saved six registers and reserved
/// 424 bytes of stack around the call of its fast copy).
#[macro_export]
macro_rules! with_fma {
    ($f:ident($($arg:ident: $ty:ty = $val:expr),* $(,)?) -> $ret:ty) => {{
        #[cfg(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma"))))]
        #[target_feature(enable = "avx2,fma")]
        fn fast($($arg: $ty),*) -> $ret {
            $f($($arg),*)
        }
        #[cfg(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma"))))]
        #[inline(never)]
        fn baseline($($arg: $ty),*) -> $ret {
            $f($($arg),*)
        }
        #[cfg(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma"))))]
        let fast_path = $crate::cpu::has_avx2_fma();
        #[cfg(not(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma")))))]
        let fast_path = false;
        if fast_path {
            #[cfg(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma"))))]
            let result = {
                let arguments = ($($val,)*);
                let ($($arg,)*) = arguments;
                // SAFETY: the CPU has AVX2 and FMA, checked just above
                unsafe { fast($($arg),*) }
            };
            #[cfg(not(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma")))))]
            let result = $f($($val),*);
            result
        } else {
            #[cfg(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma"))))]
            let result = baseline($($val),*);
            #[cfg(not(all(target_arch = "x86_64", not(all(target_feature = "avx2", target_feature = "fma")))))]
            let result = $f($($val),*);
            result
        }
    }};
}

#[cfg(test)]
mod tests {
    /// The fast copy and the baseline give the same bits for fused multiply-adds with an
    /// inexact product (where a separate multiply and add would differ).
    #[test]
    fn fused_results_agree() {
        let (a, b, c) = (1.0 + f64::EPSILON, 1.0 - f64::EPSILON, -1.0);
        #[inline(always)]
        fn fused_op(a: f64, b: f64, c: f64) -> f64 {
            a.mul_add(b, c)
        }
        let fused = crate::with_fma!(fused_op(a: f64 = a, b: f64 = b, c: f64 = c) -> f64);
        assert_eq!(fused, -f64::EPSILON * f64::EPSILON);
        assert_eq!(fused.to_bits(), a.mul_add(b, c).to_bits());
        assert_ne!(fused, a * b + c);
    }
}
