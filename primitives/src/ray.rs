//! Rays and parameter intervals.
//!
//! A [`Ray`] is the half-line `p(t) = origin + t·dir`. The direction need **not** be unit length:
//! `t` is always measured in units of `dir`, so `t` equals metric distance exactly when
//! `|dir| = 1` (which is what [`Ray::new_normalized`] and every camera ray in zeroset use, making
//! the depth AOV a true distance).
//!
//! A query asks for hits with `t` in a closed [`Interval`] `t_min ≤ t ≤ t_max`; a hit outside it does
//! not count.

use glam::DVec3;

/// A ray `p(t) = origin + t·dir` in the space of whatever it is tested against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts (`t = 0`).
    pub origin: DVec3,
    /// Direction; not necessarily unit length (see the module docs for what `t` means).
    pub dir: DVec3,
}

impl Ray {
    /// A ray with the direction as given (`t` in units of `dir`).
    #[must_use]
    pub const fn new(origin: DVec3, dir: DVec3) -> Self {
        Self { origin, dir }
    }

    /// A ray whose direction is normalised, so that `t` is metric distance from `origin`.
    #[must_use]
    pub fn new_normalized(origin: DVec3, dir: DVec3) -> Self {
        Self {
            origin,
            dir: dir.normalize(),
        }
    }

    /// The point at parameter `t`: `origin + t·dir`.
    #[inline]
    #[must_use]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.dir
    }

    /// Whether origin and direction are finite and the direction is non-zero.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite() && self.dir.is_finite() && self.dir != DVec3::ZERO
    }
}

/// A closed parameter range `min ≤ t ≤ max` (`max` may be `+∞`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Smallest accepted `t`.
    pub min: f64,
    /// Largest accepted `t`.
    pub max: f64,
}

impl Interval {
    /// `[0, +∞]`.
    pub const POSITIVE: Self = Self {
        min: 0.0,
        max: f64::INFINITY,
    };

    /// `[min, max]`.
    #[must_use]
    pub const fn new(min: f64, max: f64) -> Self {
        Self { min, max }
    }

    /// Whether `t` lies in the closed range and is finite: NaN and `±∞` are never contained
    /// (a hit at infinity, from a direction component that underflows a division, is no hit,
    /// also for the range `[−∞, ∞]`).
    #[inline]
    #[must_use]
    pub fn contains(&self, t: f64) -> bool {
        self.min <= t && t <= self.max && t.is_finite()
    }

    /// Whether the range holds no value (`min > max`, or a NaN bound).
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        !(self.min <= self.max)
    }

    /// The same range with `max` lowered to `t` (used to shrink the search after a hit).
    #[inline]
    #[must_use]
    pub fn with_max(self, t: f64) -> Self {
        Self { min: self.min, max: t }
    }
}
