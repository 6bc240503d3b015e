//! The number types an expression is evaluated in: `f64` (a point), [`Enclosure`] (an interval)
//! and [`Jet`] (a value with its derivative along one direction, forward-mode differentiation),
//! all behind one [`Scalar`] trait so that one tree walk serves every evaluation.

use crate::math::enclosure::Enclosure;
use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// What an expression needs from a number type.
pub trait Scalar:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// Whether the arithmetic rounds outward (intervals and jets of them), its quotients and
    /// square roots by the exact residual of a fused multiply-add: tapes evaluate such types in
    /// a copy compiled for the CPU's FMA instruction.
    const DIRECTED: bool = false;
    /// The number `c`.
    fn constant(c: f64) -> Self;
    /// `√x`.
    fn sqrt(self) -> Self;
    /// `eˣ`.
    fn exp(self) -> Self;
    /// `ln x`.
    fn ln(self) -> Self;
    /// `sin x`.
    fn sin(self) -> Self;
    /// `cos x`.
    fn cos(self) -> Self;
    /// `tan x`.
    fn tan(self) -> Self;
    /// `atan x`.
    fn atan(self) -> Self;
    /// `tanh x`.
    fn tanh(self) -> Self;
    /// `asin x`.
    fn asin(self) -> Self;
    /// `acos x`.
    fn acos(self) -> Self;
    /// `sinh x`.
    fn sinh(self) -> Self;
    /// `cosh x`.
    fn cosh(self) -> Self;
    /// `log₁₀ x`.
    fn log10(self) -> Self;
    /// `log₂ x`.
    fn log2(self) -> Self;
    /// `∛x`.
    fn cbrt(self) -> Self;
    /// `|x|`.
    fn abs(self) -> Self;
    /// The derivative of `|x|`: `sign(x)` (an enclosure of it across 0).
    fn sign(self) -> Self;
    /// `xⁿ`.
    fn powi(self, n: i32) -> Self;
    /// `xʸ` (positive base).
    fn pow(self, y: Self) -> Self;
    /// `min(x, y)`.
    fn min(self, y: Self) -> Self;
    /// `max(x, y)`.
    fn max(self, y: Self) -> Self;
    /// The certain order of two values, if there is one (`None` for overlapping enclosures).
    fn certain_order(self, y: Self) -> Option<Ordering>;
    /// A value covering both (for a branch that cannot be decided); a point type returns `self`.
    fn either(self, y: Self) -> Self;
}

impl Scalar for f64 {
    #[inline]
    fn constant(c: f64) -> Self {
        c
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn tan(self) -> Self {
        f64::tan(self)
    }
    #[inline]
    fn atan(self) -> Self {
        f64::atan(self)
    }
    #[inline]
    fn tanh(self) -> Self {
        f64::tanh(self)
    }
    #[inline]
    fn asin(self) -> Self {
        f64::asin(self)
    }
    #[inline]
    fn acos(self) -> Self {
        f64::acos(self)
    }
    #[inline]
    fn sinh(self) -> Self {
        f64::sinh(self)
    }
    #[inline]
    fn cosh(self) -> Self {
        f64::cosh(self)
    }
    #[inline]
    fn log10(self) -> Self {
        f64::log10(self)
    }
    #[inline]
    fn log2(self) -> Self {
        f64::log2(self)
    }
    #[inline]
    fn cbrt(self) -> Self {
        f64::cbrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn sign(self) -> Self {
        if self > 0.0 {
            1.0
        } else if self < 0.0 {
            -1.0
        } else {
            0.0
        }
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        // small powers inline (a runtime exponent would otherwise be a library call)
        match n {
            1 => self,
            2 => self * self,
            3 => self * self * self,
            n if n > 0 => crate::math::enclosure::power(self, n),
            _ => f64::powi(self, n),
        }
    }
    #[inline]
    fn pow(self, y: Self) -> Self {
        if self > 0.0 {
            f64::powf(self, y)
        } else {
            f64::NAN
        }
    }
    #[inline]
    fn min(self, y: Self) -> Self {
        f64::min(self, y)
    }
    #[inline]
    fn max(self, y: Self) -> Self {
        f64::max(self, y)
    }
    #[inline]
    fn certain_order(self, y: Self) -> Option<Ordering> {
        self.partial_cmp(&y)
    }
    #[inline]
    fn either(self, _: Self) -> Self {
        self
    }
}

impl Scalar for Enclosure {
    const DIRECTED: bool = true;
    #[inline]
    fn constant(c: f64) -> Self {
        Enclosure::point(c)
    }
    #[inline]
    fn sqrt(self) -> Self {
        Enclosure::sqrt(self)
    }
    #[inline]
    fn exp(self) -> Self {
        Enclosure::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        Enclosure::ln(self)
    }
    #[inline]
    fn sin(self) -> Self {
        Enclosure::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        Enclosure::cos(self)
    }
    #[inline]
    fn tan(self) -> Self {
        Enclosure::tan(self)
    }
    #[inline]
    fn atan(self) -> Self {
        Enclosure::atan(self)
    }
    #[inline]
    fn tanh(self) -> Self {
        Enclosure::tanh(self)
    }
    #[inline]
    fn asin(self) -> Self {
        Enclosure::asin(self)
    }
    #[inline]
    fn acos(self) -> Self {
        Enclosure::acos(self)
    }
    #[inline]
    fn sinh(self) -> Self {
        Enclosure::sinh(self)
    }
    #[inline]
    fn cosh(self) -> Self {
        Enclosure::cosh(self)
    }
    #[inline]
    fn log10(self) -> Self {
        Enclosure::log10(self)
    }
    #[inline]
    fn log2(self) -> Self {
        Enclosure::log2(self)
    }
    #[inline]
    fn cbrt(self) -> Self {
        Enclosure::cbrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        Enclosure::abs(self)
    }
    #[inline]
    fn sign(self) -> Self {
        Enclosure::sign(self)
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        Enclosure::powi(self, n)
    }
    #[inline]
    fn pow(self, y: Self) -> Self {
        Enclosure::pow(self, y)
    }
    #[inline]
    fn min(self, y: Self) -> Self {
        Enclosure::min(self, y)
    }
    #[inline]
    fn max(self, y: Self) -> Self {
        Enclosure::max(self, y)
    }
    #[inline]
    fn certain_order(self, y: Self) -> Option<Ordering> {
        if self.hi < y.lo {
            Some(Ordering::Less)
        } else if self.lo > y.hi {
            Some(Ordering::Greater)
        } else {
            None
        }
    }
    #[inline]
    fn either(self, y: Self) -> Self {
        self.hull(y)
    }
}

/// What the slope of a [`Jet`] can be: a derivative along one direction (`T` itself), or the
/// partial derivatives along the three axes at once (`[T; 3]`: a gradient in one pass, each
/// component computed by the same operations as the one-direction jet along that axis).
pub trait Tangent<T>: Copy {
    /// The zero slope (of a constant).
    fn zero() -> Self;
    /// `self + o`.
    fn plus(self, o: Self) -> Self;
    /// `self − o`.
    fn minus(self, o: Self) -> Self;
    /// `−self`.
    fn negated(self) -> Self;
    /// `k · self` (the chain rule's factor on the left, as in one-direction jets).
    fn scaled(self, k: T) -> Self;
    /// `self / k`.
    fn divided(self, k: T) -> Self;
    /// A slope covering both (see [`Scalar::either`]).
    fn covering(self, o: Self) -> Self;
}

impl<T: Scalar> Tangent<T> for T {
    #[inline(always)]
    fn zero() -> Self {
        T::constant(0.0)
    }
    #[inline(always)]
    fn plus(self, o: Self) -> Self {
        self + o
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        self - o
    }
    #[inline(always)]
    fn negated(self) -> Self {
        -self
    }
    #[inline(always)]
    fn scaled(self, k: T) -> Self {
        k * self
    }
    #[inline(always)]
    fn divided(self, k: T) -> Self {
        self / k
    }
    #[inline(always)]
    fn covering(self, o: Self) -> Self {
        self.either(o)
    }
}

impl<T: Scalar> Tangent<T> for [T; 3] {
    #[inline(always)]
    fn zero() -> Self {
        [T::constant(0.0); 3]
    }
    #[inline(always)]
    fn plus(self, o: Self) -> Self {
        [self[0] + o[0], self[1] + o[1], self[2] + o[2]]
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        [self[0] - o[0], self[1] - o[1], self[2] - o[2]]
    }
    #[inline(always)]
    fn negated(self) -> Self {
        [-self[0], -self[1], -self[2]]
    }
    #[inline(always)]
    fn scaled(self, k: T) -> Self {
        [k * self[0], k * self[1], k * self[2]]
    }
    #[inline(always)]
    fn divided(self, k: T) -> Self {
        [self[0] / k, self[1] / k, self[2] / k]
    }
    #[inline(always)]
    fn covering(self, o: Self) -> Self {
        [self[0].either(o[0]), self[1].either(o[1]), self[2].either(o[2])]
    }
}

/// `value + slope·h`: a number with its derivative along one direction (forward mode), or with
/// its gradient (`S = [T; 3]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<T, S = T> {
    /// The value.
    pub value: T,
    /// Its derivative.
    pub slope: S,
}

impl<T: Scalar, S: Tangent<T>> Jet<T, S> {
    /// A variable with value `value` whose derivative along the direction is `slope`.
    #[inline]
    pub fn new(value: T, slope: S) -> Self {
        Self { value, slope }
    }

    #[inline]
    fn chain(self, value: T, derivative: T) -> Self {
        Self {
            value,
            slope: self.slope.scaled(derivative),
        }
    }
}

impl<T: Scalar> Jet<T, [T; 3]> {
    /// The coordinates `p` as variables whose slopes are the unit axes: evaluated through Φ,
    /// they give Φ and its gradient in one pass.
    #[inline]
    pub fn axes(p: [T; 3]) -> [Self; 3] {
        let (zero, one) = (T::constant(0.0), T::constant(1.0));
        std::array::from_fn(|axis| Self::new(p[axis], std::array::from_fn(|a| if a == axis { one } else { zero })))
    }
}

impl<T: Scalar, S: Tangent<T>> Add for Jet<T, S> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.value + o.value, self.slope.plus(o.slope))
    }
}

impl<T: Scalar, S: Tangent<T>> Sub for Jet<T, S> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.value - o.value, self.slope.minus(o.slope))
    }
}

impl<T: Scalar, S: Tangent<T>> Mul for Jet<T, S> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.value * o.value,
            self.slope.scaled(o.value).plus(o.slope.scaled(self.value)),
        )
    }
}

impl<T: Scalar, S: Tangent<T>> Div for Jet<T, S> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let q = self.value / o.value;
        Self::new(q, self.slope.minus(o.slope.scaled(q)).divided(o.value))
    }
}

impl<T: Scalar, S: Tangent<T>> Neg for Jet<T, S> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.value, self.slope.negated())
    }
}

impl<T: Scalar, S: Tangent<T>> Scalar for Jet<T, S> {
    const DIRECTED: bool = T::DIRECTED;
    #[inline]
    fn constant(c: f64) -> Self {
        Self::new(T::constant(c), S::zero())
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.value.sqrt();
        self.chain(s, T::constant(0.5) / s)
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.value.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain(self.value.ln(), T::constant(1.0) / self.value)
    }
    #[inline]
    fn sin(self) -> Self {
        self.chain(self.value.sin(), self.value.cos())
    }
    #[inline]
    fn cos(self) -> Self {
        self.chain(self.value.cos(), -self.value.sin())
    }
    #[inline]
    fn tan(self) -> Self {
        let t = self.value.tan();
        self.chain(t, T::constant(1.0) + t.powi(2))
    }
    #[inline]
    fn atan(self) -> Self {
        self.chain(
            self.value.atan(),
            T::constant(1.0) / (T::constant(1.0) + self.value.powi(2)),
        )
    }
    #[inline]
    fn tanh(self) -> Self {
        let t = self.value.tanh();
        self.chain(t, T::constant(1.0) - t.powi(2))
    }
    #[inline]
    fn asin(self) -> Self {
        let one = T::constant(1.0);
        self.chain(self.value.asin(), one / (one - self.value.powi(2)).sqrt())
    }
    #[inline]
    fn acos(self) -> Self {
        let one = T::constant(1.0);
        self.chain(self.value.acos(), -(one / (one - self.value.powi(2)).sqrt()))
    }
    #[inline]
    fn sinh(self) -> Self {
        self.chain(self.value.sinh(), self.value.cosh())
    }
    #[inline]
    fn cosh(self) -> Self {
        self.chain(self.value.cosh(), self.value.sinh())
    }
    #[inline]
    fn log10(self) -> Self {
        self.chain(self.value.log10(), T::constant(std::f64::consts::LOG10_E) / self.value)
    }
    #[inline]
    fn log2(self) -> Self {
        self.chain(self.value.log2(), T::constant(std::f64::consts::LOG2_E) / self.value)
    }
    #[inline]
    fn cbrt(self) -> Self {
        let c = self.value.cbrt();
        self.chain(c, T::constant(1.0) / (T::constant(3.0) * c.powi(2)))
    }
    #[inline]
    fn abs(self) -> Self {
        self.chain(self.value.abs(), self.value.sign())
    }
    #[inline]
    fn sign(self) -> Self {
        Self::new(self.value.sign(), S::zero())
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        let derivative = match n {
            1 => T::constant(1.0),
            2 => T::constant(2.0) * self.value,
            _ => T::constant(f64::from(n)) * self.value.powi(n - 1),
        };
        self.chain(self.value.powi(n), derivative)
    }
    #[inline]
    fn pow(self, y: Self) -> Self {
        let r = self.value.pow(y.value);
        let slope = y
            .slope
            .scaled(self.value.ln())
            .plus(self.slope.scaled(y.value).divided(self.value));
        Self::new(r, slope.scaled(r))
    }
    #[inline]
    fn min(self, y: Self) -> Self {
        let value = self.value.min(y.value);
        let slope = match self.value.certain_order(y.value) {
            Some(Ordering::Less) => self.slope,
            Some(Ordering::Greater) => y.slope,
            // equal points take the first; overlapping enclosures cover both branches
            _ => self.slope.covering(y.slope),
        };
        Self::new(value, slope)
    }
    #[inline]
    fn max(self, y: Self) -> Self {
        let value = self.value.max(y.value);
        let slope = match self.value.certain_order(y.value) {
            Some(Ordering::Greater) => self.slope,
            Some(Ordering::Less) => y.slope,
            _ => self.slope.covering(y.slope),
        };
        Self::new(value, slope)
    }
    #[inline]
    fn certain_order(self, y: Self) -> Option<Ordering> {
        self.value.certain_order(y.value)
    }
    #[inline]
    fn either(self, y: Self) -> Self {
        Self::new(self.value.either(y.value), self.slope.covering(y.slope))
    }
}
