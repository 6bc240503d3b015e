//! Double-double arithmetic (≈ 106-bit significand) for the reference answers.
//!
//! A value is `hi + lo` with `|lo| ≤ ulp(hi)/2`, built from error-free transformations (Knuth's
//! two-sum, two-product by fused multiply-add). On inputs that are f64 values its relative error
//! is about 10⁻³², negligible next to any f64 or f32 error measured here.

use glam::DVec3;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// `hi + lo`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dd {
    pub hi: f64,
    pub lo: f64,
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let v = s - a;
    (s, (a - (s - v)) + (b - v))
}

#[inline]
fn fast_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

impl Dd {
    pub const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };

    #[inline]
    pub fn new(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }

    #[inline]
    pub fn f64(self) -> f64 {
        self.hi + self.lo
    }

    #[inline]
    pub fn is_negative(self) -> bool {
        self.hi < 0.0 || (self.hi == 0.0 && self.lo < 0.0)
    }

    pub fn sqrt(self) -> Dd {
        if self.hi <= 0.0 {
            return Dd::ZERO;
        }
        // one Newton step from the f64 square root doubles its precision
        let s = self.hi.sqrt();
        let p = s * s;
        let e = s.mul_add(s, -p);
        let r = ((self.hi - p) - e + self.lo) / (2.0 * s);
        let (hi, lo) = fast_two_sum(s, r);
        Dd { hi, lo }
    }

    pub fn abs(self) -> Dd {
        if self.is_negative() {
            -self
        } else {
            self
        }
    }
}

impl Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Add for Dd {
    type Output = Dd;
    fn add(self, y: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, y.hi);
        let (t, f) = two_sum(self.lo, y.lo);
        let (s, e) = fast_two_sum(s, e + t);
        let (hi, lo) = fast_two_sum(s, e + f);
        Dd { hi, lo }
    }
}

impl Sub for Dd {
    type Output = Dd;
    fn sub(self, y: Dd) -> Dd {
        self + (-y)
    }
}

impl Mul for Dd {
    type Output = Dd;
    fn mul(self, y: Dd) -> Dd {
        let p = self.hi * y.hi;
        let e = self.hi.mul_add(y.hi, -p);
        let (hi, lo) = fast_two_sum(p, e + (self.hi * y.lo + self.lo * y.hi));
        Dd { hi, lo }
    }
}

impl Div for Dd {
    type Output = Dd;
    fn div(self, y: Dd) -> Dd {
        // long division, three quotient digits
        let q1 = self.hi / y.hi;
        let r = self - y * Dd::new(q1);
        let q2 = r.hi / y.hi;
        let r = r - y * Dd::new(q2);
        let q3 = r.hi / y.hi;
        let (a, b) = fast_two_sum(q1, q2);
        Dd { hi: a, lo: b } + Dd::new(q3)
    }
}

impl From<f64> for Dd {
    fn from(x: f64) -> Dd {
        Dd::new(x)
    }
}

/// A 3-vector of double-doubles.
#[derive(Clone, Copy, Debug)]
pub struct V3(pub Dd, pub Dd, pub Dd);

impl V3 {
    pub fn new(v: DVec3) -> V3 {
        V3(Dd::new(v.x), Dd::new(v.y), Dd::new(v.z))
    }
    pub fn dot(self, o: V3) -> Dd {
        self.0 * o.0 + self.1 * o.1 + self.2 * o.2
    }
    pub fn cross(self, o: V3) -> V3 {
        V3(
            self.1 * o.2 - self.2 * o.1,
            self.2 * o.0 - self.0 * o.2,
            self.0 * o.1 - self.1 * o.0,
        )
    }
    pub fn sub(self, o: V3) -> V3 {
        V3(self.0 - o.0, self.1 - o.1, self.2 - o.2)
    }
    pub fn add(self, o: V3) -> V3 {
        V3(self.0 + o.0, self.1 + o.1, self.2 + o.2)
    }
    pub fn scale(self, s: Dd) -> V3 {
        V3(self.0 * s, self.1 * s, self.2 * s)
    }
    pub fn f64(self) -> DVec3 {
        DVec3::new(self.0.f64(), self.1.f64(), self.2.f64())
    }
}

/// The ray point `o + t·d` in double-double.
pub fn at(o: DVec3, d: DVec3, t: Dd) -> V3 {
    V3::new(o).add(V3::new(d).scale(t))
}

/// Real roots of `A t² + 2B t + C = 0`, ascending, and the relative discriminant
/// `(B² − AC)/(B² + |AC|)` (0 at tangency, the ray's distance from a hit/miss decision).
pub fn quadratic(a: Dd, b: Dd, c: Dd) -> (Option<(Dd, Dd)>, f64) {
    let disc = b * b - a * c;
    let scale = (b * b).abs() + (a * c).abs();
    let rel = if scale.hi > 0.0 {
        (disc.hi / scale.hi).abs()
    } else {
        0.0
    };
    if disc.is_negative() {
        return (None, rel);
    }
    if a.hi == 0.0 {
        if b.hi == 0.0 {
            return (None, rel);
        }
        let t = -c / (b + b);
        return (Some((t, t)), rel);
    }
    let s = disc.sqrt();
    let (t0, t1) = ((-b - s) / a, (-b + s) / a);
    if t0.f64() <= t1.f64() {
        (Some((t0, t1)), rel)
    } else {
        (Some((t1, t0)), rel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqrt_and_division_reach_double_double_precision() {
        let two = Dd::new(2.0);
        let s = two.sqrt();
        let back = s * s - two;
        assert!(back.f64().abs() < 1e-30, "{back:?}");
        let third = Dd::new(1.0) / Dd::new(3.0);
        let err = third * Dd::new(3.0) - Dd::new(1.0);
        assert!(err.f64().abs() < 1e-31, "{err:?}");
    }
}
