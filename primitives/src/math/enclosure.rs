//! Interval arithmetic: an [`Enclosure`] `[lo, hi]` is a set of reals guaranteed to contain the
//! exact value of an expression whose arguments lie in the argument enclosures.
//!
//! **Rounding.** Rust has no directed rounding, so `+ − × ÷ √` are rounded to nearest and then
//! corrected with their exact rounding error (two-sum for sums, a fused multiply-add for the
//! residual of products, quotients and square roots): a bound moves one ulp outward only when
//! the rounded value lies on the wrong side of the exact one, so these are exactly the directed
//! roundings (an exact result, such as `−1 + 1 = 0`, stays exact). The elementary functions
//! (`exp ln sin cos …`, faithful to 1–2 ulp in every mainstream libm) are widened by
//! [`LIBM_ULPS`] ulps. Hence `lo ≤ exact ≤ hi` for every exact argument in the argument
//! enclosures.
//!
//! **Domain.** Where an operation is undefined for part of its argument (`√` of a negative, `ln`
//! of a non-positive, `÷` by an enclosure containing 0, `tan` across a pole) the result is
//! computed for the defined part (or is the whole line) and [`Enclosure::undefined`] is set. It
//! propagates through every later operation, so the final enclosure says whether the expression
//! might be undefined somewhere in the argument box.

use super::ulps::{down, up};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Extra ulps of widening for the libm elementary functions (they are faithful to 1–2 ulp).
pub const LIBM_ULPS: u32 = 4;

/// A closed set `[lo, hi]` of reals (bounds may be infinite) containing an exact value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Enclosure {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
    /// 1 where some operation was (possibly) evaluated outside its domain, else 0
    /// ([`Enclosure::undefined`]); a full word, so that copies of an enclosure are whole-word
    /// moves (a byte flag made them partial and stalled the store forwarding of every copy).
    flag: u64,
}

/// `a + b` rounded towards −∞ (`DOWN`) or +∞, from the exact error of the nearest sum.
#[inline(always)]
fn add_directed<const DOWN: bool>(a: f64, b: f64) -> f64 {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    directed::<DOWN>(s, e)
}

/// The exact error `a·b − p` of the nearest product `p = a·b` by Dekker's two-product (Veltkamp's
/// split: inline wherever an enclosure is computed, where a fused multiply-add would be a call
/// into the C library outside the tape evaluators' FMA copy), or `None` outside the range where
/// the split cannot overflow and the error is representable.
#[inline(always)]
fn product_error(a: f64, b: f64, p: f64) -> Option<f64> {
    const SPLITTER: f64 = 134_217_729.0; // 2^27 + 1
    const BIG: f64 = f64::from_bits((1023 + 996) << 52); // 2^996
    const SMALL: f64 = f64::from_bits((1023 - 969) << 52); // 2^-969
    if !(a.abs() < BIG && b.abs() < BIG && p.abs() < BIG && p.abs() > SMALL) {
        return None;
    }
    let split = |x: f64| {
        let c = SPLITTER * x;
        let hi = c - (c - x);
        (hi, x - hi)
    };
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    Some(((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

/// `a · b` rounded towards −∞ (`DOWN`) or +∞: the nearest product, moved one ulp to the
/// requested side where its exact error says it lies on the other (exact products stay exact),
/// or one ulp outward where the error cannot be computed; `0 · ∞ = 0` (the exact product of a
/// finite zero factor with an unbounded one).
#[inline(always)]
fn mul_directed<const DOWN: bool>(a: f64, b: f64) -> f64 {
    if a == 0.0 || b == 0.0 {
        return 0.0;
    }
    let p = a * b;
    match product_error(a, b, p) {
        Some(e) => directed::<DOWN>(p, e),
        None if p == 0.0 => {
            // an underflow: the exact product is a tiny number of the factors' sign
            let positive = (a > 0.0) == (b > 0.0);
            match (DOWN, positive) {
                (true, true) | (false, false) => 0.0,
                (true, false) => -f64::from_bits(1),
                (false, true) => f64::from_bits(1),
            }
        }
        None if DOWN => p.next_down(),
        None => p.next_up(),
    }
}

/// `a / b` rounded towards −∞ and towards +∞: the residual `a − q·b` (exact by FMA) has the
/// sign of `(a/b − q)·b`.
#[inline(always)]
fn div_both(a: f64, b: f64) -> (f64, f64) {
    let q = a / b;
    let r = (-q).mul_add(b, a);
    let e = if b > 0.0 { r } else { -r };
    (directed::<true>(q, e), directed::<false>(q, e))
}

/// `√x` rounded towards −∞ (`DOWN`) or +∞: the residual `x − s²` has the sign of `√x − s`.
#[inline(always)]
fn sqrt_directed<const DOWN: bool>(x: f64) -> f64 {
    let s = x.sqrt();
    directed::<DOWN>(s, (-s).mul_add(s, x))
}

/// The rounded value `v` of an exact value `v + e`, moved one ulp to the requested side where it
/// lies on the other; non-finite values or errors fall back to one ulp outward.
#[inline(always)]
fn directed<const DOWN: bool>(v: f64, e: f64) -> f64 {
    if !v.is_finite() || !e.is_finite() {
        // an overflow to ±∞ or a NaN error: the plain outward step is still sound
        return if DOWN { v.next_down() } else { v.next_up() };
    }
    if DOWN && e < 0.0 {
        v.next_down()
    } else if !DOWN && e > 0.0 {
        v.next_up()
    } else {
        v
    }
}

impl Enclosure {
    /// Every real number.
    pub const ENTIRE: Self = Self {
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
        flag: 0,
    };

    /// `[lo, hi]` as given (the caller guarantees `lo ≤ hi`).
    #[must_use]
    #[inline]
    pub const fn new(lo: f64, hi: f64) -> Self {
        Self { lo, hi, flag: 0 }
    }

    /// The exact number `x` (a point enclosure).
    #[must_use]
    #[inline]
    pub const fn point(x: f64) -> Self {
        Self::new(x, x)
    }

    /// Whether some operation was (possibly) evaluated outside its domain.
    #[inline]
    #[must_use]
    pub const fn undefined(&self) -> bool {
        self.flag != 0
    }

    /// `[lo, hi]` widened outward by `ulps`, NaN bounds replaced by infinities, the flag kept.
    #[inline(always)]
    fn widened(lo: f64, hi: f64, ulps: u32, undefined: bool) -> Self {
        let lo = if lo.is_nan() { f64::NEG_INFINITY } else { down(lo, ulps) };
        let hi = if hi.is_nan() { f64::INFINITY } else { up(hi, ulps) };
        Self {
            lo,
            hi,
            flag: u64::from(undefined),
        }
    }

    /// `[lo, hi]` with NaN bounds (`∞ − ∞`, `∞ / ∞`) replaced by infinities.
    #[inline(always)]
    fn checked(lo: f64, hi: f64, undefined: bool) -> Self {
        Self {
            lo: if lo.is_nan() { f64::NEG_INFINITY } else { lo },
            hi: if hi.is_nan() { f64::INFINITY } else { hi },
            flag: u64::from(undefined),
        }
    }

    /// Whether `0 ∈ [lo, hi]`.
    #[must_use]
    #[inline]
    pub fn contains_zero(&self) -> bool {
        self.lo <= 0.0 && 0.0 <= self.hi
    }

    /// `Some(1.0)` where every value enclosed is positive, `Some(-1.0)` where every one is
    /// negative, else `None` (an undefined enclosure included).
    #[must_use]
    #[inline]
    pub fn strict_sign(&self) -> Option<f64> {
        if self.undefined() {
            None
        } else if self.lo > 0.0 {
            Some(1.0)
        } else if self.hi < 0.0 {
            Some(-1.0)
        } else {
            None
        }
    }

    /// `Some(±1.0)` where `Σ eᵢ·wᵢ` has one strict sign for every `eᵢ` in the enclosures
    /// `terms` (weights `wᵢ` exact), else `None` (an undefined or unbounded term included). The
    /// sum is taken in `f64`: `slack` times `ε` times the sum of the terms' magnitudes must
    /// cover the rounding of the products and the sum (and of the weights, where they were
    /// computed).
    #[must_use]
    #[inline]
    pub fn weighted_sum_sign(terms: impl IntoIterator<Item = (Enclosure, f64)>, slack: f64) -> Option<f64> {
        let (mut lo, mut hi, mut size) = (0.0f64, 0.0f64, 0.0f64);
        for (e, w) in terms {
            if e.undefined() {
                return None;
            }
            let (a, b) = if w >= 0.0 {
                (e.lo * w, e.hi * w)
            } else {
                (e.hi * w, e.lo * w)
            };
            lo += a;
            hi += b;
            size += a.abs().max(b.abs());
        }
        let slack = slack * f64::EPSILON * size;
        if !size.is_finite() {
            None
        } else if lo > slack {
            Some(1.0)
        } else if hi < -slack {
            Some(-1.0)
        } else {
            None
        }
    }

    /// Whether `x ∈ [lo, hi]`.
    #[must_use]
    #[inline]
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// `hi − lo`.
    #[must_use]
    #[inline]
    pub fn width(&self) -> f64 {
        self.hi - self.lo
    }

    /// The smallest enclosure containing both.
    #[must_use]
    #[inline]
    pub fn hull(self, other: Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            flag: self.flag | other.flag,
        }
    }

    #[inline(always)]
    fn either_undefined(self, other: Self) -> bool {
        self.undefined() || other.undefined()
    }

    /// `√x` over the non-negative part; flagged where `lo < 0`.
    #[must_use]
    #[inline]
    pub fn sqrt(self) -> Self {
        if self.hi < 0.0 {
            return Self {
                lo: 0.0,
                hi: 0.0,
                flag: 1,
            };
        }
        Self {
            lo: sqrt_directed::<true>(self.lo.max(0.0)).max(0.0),
            hi: sqrt_directed::<false>(self.hi),
            flag: u64::from(self.undefined() || self.lo < 0.0),
        }
    }

    #[inline]
    fn clamp_lo(mut self, lo: f64) -> Self {
        self.lo = self.lo.max(lo);
        self
    }

    #[inline]
    fn clamp(mut self, lo: f64, hi: f64) -> Self {
        self.lo = self.lo.clamp(lo, hi);
        self.hi = self.hi.clamp(lo, hi);
        self
    }

    /// `eˣ` (monotone).
    #[must_use]
    #[inline]
    pub fn exp(self) -> Self {
        Self::widened(self.lo.exp(), self.hi.exp(), LIBM_ULPS, self.undefined()).clamp_lo(0.0)
    }

    /// `ln x` over the positive part; flagged where `lo ≤ 0`.
    #[must_use]
    #[inline]
    pub fn ln(self) -> Self {
        if self.hi <= 0.0 {
            return Self {
                lo: f64::NEG_INFINITY,
                hi: f64::NEG_INFINITY,
                flag: 1,
            };
        }
        let lo = if self.lo <= 0.0 {
            f64::NEG_INFINITY
        } else {
            self.lo.ln()
        };
        Self::widened(lo, self.hi.ln(), LIBM_ULPS, self.undefined() || self.lo <= 0.0)
    }

    /// `|x|`.
    #[must_use]
    #[inline]
    pub fn abs(self) -> Self {
        if self.lo >= 0.0 {
            self
        } else if self.hi <= 0.0 {
            -self
        } else {
            Self {
                lo: 0.0,
                hi: (-self.lo).max(self.hi),
                flag: self.flag,
            }
        }
    }

    /// `min(a, b)` (exact: no rounding).
    #[must_use]
    #[inline]
    pub fn min(self, other: Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.min(other.hi),
            flag: self.flag | other.flag,
        }
    }

    /// `max(a, b)` (exact: no rounding).
    #[must_use]
    #[inline]
    pub fn max(self, other: Self) -> Self {
        Self {
            lo: self.lo.max(other.lo),
            hi: self.hi.max(other.hi),
            flag: self.flag | other.flag,
        }
    }

    /// `xⁿ` for an integer `n`: the tight range (even powers are non-negative and smallest at the
    /// point of the argument nearest 0); negative `n` is `1 / x⁻ⁿ`.
    #[must_use]
    #[inline(always)]
    pub fn powi(self, n: i32) -> Self {
        if n == 0 {
            return Self {
                flag: self.flag,
                ..Self::point(1.0)
            };
        }
        if n < 0 {
            return Self::point(1.0) / self.powi(-n);
        }
        if n == 1 {
            return self;
        }
        if n == 2 {
            // the square, with directed products: exact where the square is representable
            let (down, up) = (mul_directed::<true>, mul_directed::<false>);
            let (l, h) = (self.lo, self.hi);
            let (lo, hi) = if l >= 0.0 {
                (down(l, l), up(h, h))
            } else if h <= 0.0 {
                (down(h, h), up(l, l))
            } else {
                (0.0, up(l, l).max(up(h, h)))
            };
            return Self::checked(lo, hi, self.undefined());
        }

        // each powi rounds at most ~n times; widen by n ulps (relative error ≤ γₙ)
        let ulps = n.unsigned_abs() + 1;
        let a = power(self.lo, n);
        let b = if self.hi == self.lo { a } else { power(self.hi, n) };
        if n % 2 == 1 {
            Self::widened(a, b, ulps, self.undefined())
        } else if self.lo >= 0.0 {
            Self::widened(a, b, ulps, self.undefined()).clamp_lo(0.0)
        } else if self.hi <= 0.0 {
            Self::widened(b, a, ulps, self.undefined()).clamp_lo(0.0)
        } else {
            Self::widened(0.0, a.max(b), ulps, self.undefined()).clamp_lo(0.0)
        }
    }

    /// `xʸ = e^{y·ln x}` for a positive base; flagged where the base may be ≤ 0.
    #[must_use]
    #[inline]
    pub fn pow(self, exponent: Self) -> Self {
        (exponent * self.ln()).exp()
    }

    /// `sin x`: the end values, widened to ±1 where the enclosure contains a peak `π/2 + kπ`.
    #[must_use]
    #[inline]
    pub fn sin(self) -> Self {
        self.periodic(f64::sin, FRAC_PI_2)
    }

    /// `cos x` (`sin` shifted by `π/2`, with the peak test done on the unshifted argument).
    #[must_use]
    #[inline]
    pub fn cos(self) -> Self {
        self.periodic(f64::cos, 0.0)
    }

    /// Shared `sin`/`cos`: `f` has its maxima at `peak + 2kπ` and minima at `peak + π + 2kπ`.
    #[inline]
    fn periodic(self, f: fn(f64) -> f64, peak: f64) -> Self {
        if !(self.width() < TAU) || !self.lo.is_finite() || !self.hi.is_finite() {
            return Self {
                lo: -1.0,
                hi: 1.0,
                flag: self.flag,
            };
        }
        // a point (a coordinate a ray does not move along) needs one call of `f`
        let a = f(self.lo);
        let b = if self.hi == self.lo { a } else { f(self.hi) };
        let mut lo = a.min(b);
        let mut hi = a.max(b);
        // the first maximum at or after lo (and minimum): conservative in the presence of rounding
        // of the reduction, by testing a slightly widened argument range
        let slack = 4.0 * f64::EPSILON * self.lo.abs().max(self.hi.abs()).max(1.0);
        let contains_point = |p0: f64| {
            let k = ((self.lo - slack - p0) / TAU).ceil();
            let p = p0 + k * TAU;
            p <= self.hi + slack
        };
        if contains_point(peak) {
            hi = 1.0;
        }
        if contains_point(peak + PI) {
            lo = -1.0;
        }
        Self::widened(lo, hi, LIBM_ULPS, self.undefined()).clamp(-1.0, 1.0)
    }

    /// `tan x`: monotone between poles; the whole line (flagged) across a pole `π/2 + kπ`.
    #[must_use]
    #[inline]
    pub fn tan(self) -> Self {
        let slack = 4.0 * f64::EPSILON * self.lo.abs().max(self.hi.abs()).max(1.0);
        let k = ((self.lo - slack - FRAC_PI_2) / PI).ceil();
        let pole = FRAC_PI_2 + k * PI;
        if !(self.width() < PI) || pole <= self.hi + slack {
            return Self {
                flag: 1,
                ..Self::ENTIRE
            };
        }
        Self::widened(self.lo.tan(), self.hi.tan(), LIBM_ULPS, self.undefined())
    }

    /// `atan x` (monotone).
    #[must_use]
    #[inline]
    pub fn atan(self) -> Self {
        Self::widened(self.lo.atan(), self.hi.atan(), LIBM_ULPS, self.undefined()).clamp(-FRAC_PI_2, FRAC_PI_2)
    }

    /// `tanh x` (monotone).
    #[must_use]
    #[inline]
    pub fn tanh(self) -> Self {
        Self::widened(self.lo.tanh(), self.hi.tanh(), LIBM_ULPS, self.undefined()).clamp(-1.0, 1.0)
    }

    /// `asin x` over `[−1, 1]` (monotone); flagged where the argument leaves `[−1, 1]`.
    #[must_use]
    #[inline]
    pub fn asin(self) -> Self {
        self.unit_domain(f64::asin, true)
    }

    /// `acos x` over `[−1, 1]` (decreasing); flagged where the argument leaves `[−1, 1]`.
    #[must_use]
    #[inline]
    pub fn acos(self) -> Self {
        self.unit_domain(f64::acos, false)
    }

    #[inline]
    fn unit_domain(self, f: fn(f64) -> f64, increasing: bool) -> Self {
        let undefined = self.undefined() || self.lo < -1.0 || self.hi > 1.0;
        if self.hi < -1.0 || self.lo > 1.0 {
            return Self {
                flag: 1,
                ..Self::ENTIRE
            };
        }
        let (a, b) = (f(self.lo.max(-1.0)), f(self.hi.min(1.0)));
        let (lo, hi) = if increasing { (a, b) } else { (b, a) };
        Self::widened(lo, hi, LIBM_ULPS, undefined)
    }

    /// `sinh x` (monotone).
    #[must_use]
    #[inline]
    pub fn sinh(self) -> Self {
        Self::widened(self.lo.sinh(), self.hi.sinh(), LIBM_ULPS, self.undefined())
    }

    /// `cosh x` (even, smallest at the point nearest 0).
    #[must_use]
    #[inline]
    pub fn cosh(self) -> Self {
        let (a, b) = (self.lo.cosh(), self.hi.cosh());
        let lo = if self.contains_zero() { 1.0 } else { a.min(b) };
        Self::widened(lo, a.max(b), LIBM_ULPS, self.undefined()).clamp_lo(1.0)
    }

    /// `log₁₀ x` over the positive part; flagged where `lo ≤ 0`.
    #[must_use]
    #[inline]
    pub fn log10(self) -> Self {
        self.positive_log(f64::log10)
    }

    /// `log₂ x` over the positive part; flagged where `lo ≤ 0`.
    #[must_use]
    #[inline]
    pub fn log2(self) -> Self {
        self.positive_log(f64::log2)
    }

    #[inline]
    fn positive_log(self, f: fn(f64) -> f64) -> Self {
        if self.hi <= 0.0 {
            return Self {
                lo: f64::NEG_INFINITY,
                hi: f64::NEG_INFINITY,
                flag: 1,
            };
        }
        let lo = if self.lo <= 0.0 { f64::NEG_INFINITY } else { f(self.lo) };
        Self::widened(lo, f(self.hi), LIBM_ULPS, self.undefined() || self.lo <= 0.0)
    }

    /// `∛x` (monotone, defined everywhere).
    #[must_use]
    #[inline]
    pub fn cbrt(self) -> Self {
        Self::widened(self.lo.cbrt(), self.hi.cbrt(), LIBM_ULPS, self.undefined())
    }

    /// `sign(x)` as an enclosure of the derivative of `|x|`: `[−1, 1]` across 0.
    #[must_use]
    #[inline]
    pub fn sign(self) -> Self {
        let s = |x: f64| {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            }
        };
        let lo = if self.lo < 0.0 { -1.0 } else { s(self.lo) };
        let hi = if self.hi > 0.0 { 1.0 } else { s(self.hi) };
        Self {
            lo,
            hi,
            flag: self.flag,
        }
    }
}

impl Neg for Enclosure {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            lo: -self.hi,
            hi: -self.lo,
            flag: self.flag,
        }
    }
}

impl Add for Enclosure {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::checked(
            add_directed::<true>(self.lo, o.lo),
            add_directed::<false>(self.hi, o.hi),
            self.either_undefined(o),
        )
    }
}

impl Sub for Enclosure {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::checked(
            add_directed::<true>(self.lo, -o.hi),
            add_directed::<false>(self.hi, -o.lo),
            self.either_undefined(o),
        )
    }
}

/// `xⁿ` for `n ≥ 1` by repeated squaring, inline (the same products, in the same order, as the
/// runtime's `powi`).
#[inline(always)]
pub(crate) fn power(x: f64, n: i32) -> f64 {
    let mut base = x;
    let mut n = n.unsigned_abs();
    let mut result = 1.0;
    loop {
        if n & 1 == 1 {
            result *= base;
        }
        n >>= 1;
        if n == 0 {
            return result;
        }
        base *= base;
    }
}

/// The smallest lower and largest upper bound of four directed results.
#[inline(always)]
fn hull_of(bounds: [(f64, f64); 4]) -> (f64, f64) {
    let lo = bounds[0].0.min(bounds[1].0).min(bounds[2].0.min(bounds[3].0));
    let hi = bounds[0].1.max(bounds[1].1).max(bounds[2].1.max(bounds[3].1));
    (lo, hi)
}

impl Mul for Enclosure {
    type Output = Self;
    /// The product by the signs of the factors' bounds (two directed products in the eight
    /// cases where the signs decide which corners bound it, four where both straddle 0).
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let (al, ah, bl, bh) = (self.lo, self.hi, o.lo, o.hi);
        let down = mul_directed::<true>;
        let up = mul_directed::<false>;
        let (lo, hi) = if al >= 0.0 {
            if bl >= 0.0 {
                (down(al, bl), up(ah, bh))
            } else if bh <= 0.0 {
                (down(ah, bl), up(al, bh))
            } else {
                (down(ah, bl), up(ah, bh))
            }
        } else if ah <= 0.0 {
            if bl >= 0.0 {
                (down(al, bh), up(ah, bl))
            } else if bh <= 0.0 {
                (down(ah, bh), up(al, bl))
            } else {
                (down(al, bh), up(al, bl))
            }
        } else if bl >= 0.0 {
            (down(al, bh), up(ah, bh))
        } else if bh <= 0.0 {
            (down(ah, bl), up(al, bl))
        } else {
            (down(al, bh).min(down(ah, bl)), up(al, bl).max(up(ah, bh)))
        };
        Self::checked(lo, hi, self.either_undefined(o))
    }
}

impl Div for Enclosure {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        if o.contains_zero() {
            return Self {
                flag: 1,
                ..Self::ENTIRE
            };
        }
        let (lo, hi) = hull_of([
            div_both(self.lo, o.lo),
            div_both(self.lo, o.hi),
            div_both(self.hi, o.lo),
            div_both(self.hi, o.hi),
        ]);
        Self::checked(lo, hi, self.either_undefined(o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every enclosure must contain the f64 value at sample arguments (a necessary property;
    /// the f64 value is within an ulp of the exact one, inside the widening).
    #[test]
    fn enclosures_contain_sampled_values() {
        let args = [
            (-3.0, -0.5),
            (-1.0, 2.0),
            (0.25, 7.5),
            (1.0, 1.0),
            (-20.0, -13.0),
            (100.0, 104.0),
        ];
        type Pair = (fn(Enclosure) -> Enclosure, fn(f64) -> f64);
        let functions: [Pair; 12] = [
            (Enclosure::sinh, f64::sinh),
            (Enclosure::cosh, f64::cosh),
            (Enclosure::cbrt, f64::cbrt),
            (|e| (e * Enclosure::point(0.05)).asin(), |x| (x * 0.05).asin()),
            (Enclosure::sin, f64::sin),
            (Enclosure::cos, f64::cos),
            (Enclosure::exp, f64::exp),
            (Enclosure::atan, f64::atan),
            (Enclosure::tanh, f64::tanh),
            (Enclosure::abs, f64::abs),
            (|e| e.powi(2), |x| x * x),
            (|e| e.powi(3), |x| x * x * x),
        ];
        for &(lo, hi) in &args {
            let e = Enclosure::new(lo, hi);
            for (fi, f) in &functions {
                let r = fi(e);
                for k in 0..=200 {
                    let x = lo + (hi - lo) * f64::from(k) / 200.0;
                    if f(x).is_nan() {
                        assert!(r.undefined(), "[{lo}, {hi}] at {x}: undefined but not flagged");
                    } else {
                        assert!(r.contains(f(x)), "[{lo}, {hi}] at {x}: {} ∉ {r:?}", f(x));
                    }
                }
            }
        }
    }

    #[test]
    fn peaks_widen_and_domains_flag() {
        let s = Enclosure::new(1.0, 2.0).sin();
        assert_eq!(s.hi, 1.0);
        assert!(s.lo < 1.0_f64.sin() && s.lo > 0.84);
        let c = Enclosure::new(3.0, 3.5).cos();
        assert_eq!(c.lo, -1.0);
        assert!(Enclosure::new(-1.0, -0.5).sqrt().undefined());
        assert!(!Enclosure::new(0.0, 4.0).sqrt().undefined());
        assert!(Enclosure::new(-1.0, 1.0).ln().undefined());
        assert!((Enclosure::point(1.0) / Enclosure::new(-1.0, 1.0)).undefined());
        assert!(Enclosure::new(1.0, 2.0).tan().undefined());
        let sq = Enclosure::new(-2.0, 1.0).powi(2);
        assert!(sq.lo == 0.0 && sq.hi >= 4.0 && sq.hi < 4.0 + 1e-14);
        let m = Enclosure::new(-2.0, 3.0) * Enclosure::new(-1.0, 0.5);
        assert_eq!((m.lo, m.hi), (-3.0, 2.0), "exact products stay exact");
        let z = Enclosure::new(-1.0, 1.0) + Enclosure::point(1.0);
        assert_eq!(z.lo, 0.0, "an exact sum is not widened");
        assert!(!z.sqrt().undefined());
        // inexact results: directed, and tight
        let third = Enclosure::point(1.0) / Enclosure::point(3.0);
        assert!(third.lo < third.hi && third.hi == third.lo.next_up());
        assert!(third.lo <= 1.0 / 3.0 && 1.0 / 3.0 <= third.hi);
        let tenth = Enclosure::point(0.1) + Enclosure::point(0.2);
        assert!(tenth.contains(0.1 + 0.2) && tenth.hi == tenth.lo.next_up());
        let root = Enclosure::point(2.0).sqrt();
        assert!(root.hi == root.lo.next_up() && root.lo * root.lo < 2.0 && root.hi * root.hi > 2.0);
    }
}
