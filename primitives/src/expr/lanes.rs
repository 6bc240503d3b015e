//! Several points at once: [`Lanes`] holds [`WIDTH`] `f64` values and applies every operation
//! lane by lane with exactly `f64`'s own arithmetic (the same bits as one point at a time), so a
//! tape evaluated in it ([`crate::expr::tape::Tape::eval_points`]) runs its instruction loop once
//! for many points: independent lanes fill the pipeline where one point would wait on each
//! instruction's latency.

use super::scalar::Scalar;
use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Points evaluated together.
pub const WIDTH: usize = 8;

/// [`WIDTH`] values, one per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lanes(pub [f64; WIDTH]);

impl Lanes {
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut out = [0.0; WIDTH];
        for (out, a) in out.iter_mut().zip(self.0) {
            *out = f(a);
        }
        Self(out)
    }

    #[inline(always)]
    fn zip(self, y: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut out = [0.0; WIDTH];
        for ((out, a), b) in out.iter_mut().zip(self.0).zip(y.0) {
            *out = f(a, b);
        }
        Self(out)
    }
}

macro_rules! lane_wise_operator {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Self;
            #[inline(always)]
            fn $method(self, y: Self) -> Self {
                self.zip(y, |a, b| a $op b)
            }
        }
    };
}

lane_wise_operator!(Add, add, +);
lane_wise_operator!(Sub, sub, -);
lane_wise_operator!(Mul, mul, *);
lane_wise_operator!(Div, div, /);

impl Neg for Lanes {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

macro_rules! lane_wise_functions {
    ($($name:ident),*) => {
        $(
            #[inline(always)]
            fn $name(self) -> Self {
                self.map(<f64 as Scalar>::$name)
            }
        )*
    };
}

impl Scalar for Lanes {
    #[inline(always)]
    fn constant(c: f64) -> Self {
        Self([c; WIDTH])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }
    lane_wise_functions!(exp, ln, sin, cos, tan, atan, tanh, asin, acos, sinh, cosh, log10, log2, cbrt, abs, sign);
    #[inline(always)]
    fn powi(self, n: i32) -> Self {
        // the small powers as `f64::powi` of the `Scalar` trait computes them, for all lanes
        match n {
            1 => self,
            2 => self * self,
            3 => self * self * self,
            _ => self.map(|a| <f64 as Scalar>::powi(a, n)),
        }
    }
    #[inline(always)]
    fn pow(self, y: Self) -> Self {
        self.zip(y, <f64 as Scalar>::pow)
    }
    #[inline(always)]
    fn min(self, y: Self) -> Self {
        self.zip(y, <f64 as Scalar>::min)
    }
    #[inline(always)]
    fn max(self, y: Self) -> Self {
        self.zip(y, <f64 as Scalar>::max)
    }
    /// Lanes are separate points: no order holds for all of them.
    fn certain_order(self, _: Self) -> Option<Ordering> {
        None
    }
    fn either(self, _: Self) -> Self {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;

    /// A tape evaluated in lanes gives each lane the bits of its own f64 evaluation.
    #[test]
    fn lanes_are_bit_for_bit_single_points() {
        let texts = [
            "sqrt(x^2 + y^2 + z^2) - 1",
            "max(abs(sqrt(x^2 + y^2 + z^2) - 0.9) - 0.02, 0.35 - abs(sin(6*x)*cos(6*y) + sin(6*y)*cos(6*z)))",
            "asin(0.5*x) + acos(0.3*y) + sinh(z) * cosh(x) + log10(2 + y) + log2(3 + x) + cbrt(x*z - 2) + x^7 + y^-3",
            "min(exp(-x*x) - tanh(y), atan(z) / tan(x + 0.1)) + pow(1.5 + y, x) + sq(x - y) + ln(4 + z) + log(2 + x)",
        ];
        for text in texts {
            let tape = Expr::parse(text).unwrap().compile();
            let points: Vec<[f64; 3]> = (0..3 * WIDTH)
                .map(|i| {
                    let s = i as f64;
                    [(0.37 * s).sin() * 1.3, (0.91 * s).cos() - 0.2, 0.05 * s - 0.6]
                })
                .collect();
            let mut values = vec![0.0; points.len()];
            tape.eval_points(&points, &mut values, &mut Vec::new());
            for (p, v) in points.iter().zip(&values) {
                let single = tape.eval_f64(*p, &mut Vec::new());
                assert_eq!(v.to_bits(), single.to_bits(), "{text} at {p:?}: {v} vs {single}");
            }
        }
    }
}
