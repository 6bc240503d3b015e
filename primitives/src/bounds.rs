//! Axis-aligned bounding boxes.

use crate::ray::{Interval, Ray};
use glam::{DAffine3, DVec3};

/// An axis-aligned box `min ≤ p ≤ max` (component-wise). Infinite extents are allowed (a plane's
/// bounds); [`Aabb::EMPTY`] has `min = +∞`, `max = −∞` and contains nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb {
    /// The box containing nothing; the identity of [`Aabb::union`].
    pub const EMPTY: Self = Self {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };
    /// The whole space.
    pub const EVERYTHING: Self = Self {
        min: DVec3::NEG_INFINITY,
        max: DVec3::INFINITY,
    };

    /// The box with the given corners (no reordering).
    #[must_use]
    pub const fn new(min: DVec3, max: DVec3) -> Self {
        Self { min, max }
    }

    /// The smallest box containing all `points`.
    #[must_use]
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.including(p))
    }

    /// The smallest box containing `self` and `p`.
    #[must_use]
    pub fn including(self, p: DVec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box containing both.
    #[must_use]
    pub fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The box grown by `margin` on every side.
    #[must_use]
    pub fn expanded(self, margin: f64) -> Self {
        Self {
            min: self.min - DVec3::splat(margin),
            max: self.max + DVec3::splat(margin),
        }
    }

    /// Whether the box contains nothing.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Whether every bound is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// Centre point (meaningful for finite boxes).
    #[must_use]
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// `max − min`.
    #[must_use]
    pub fn extent(&self) -> DVec3 {
        self.max - self.min
    }

    /// Length of the diagonal: the natural length scale of what the box bounds.
    #[must_use]
    pub fn diagonal_length(&self) -> f64 {
        self.extent().length()
    }

    /// Surface area (used by the SAH); 0 for an empty box.
    #[must_use]
    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Whether `p` lies in the closed box.
    #[must_use]
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The box bounding the image of `self` under `m` (transforms the eight corners).
    #[must_use]
    pub fn transformed(&self, m: &DAffine3) -> Self {
        if !self.is_finite() {
            return if self.is_empty() { Self::EMPTY } else { Self::EVERYTHING };
        }
        let mut out = Self::EMPTY;
        for i in 0..8 {
            out = out.including(m.transform_point3(self.corner(i)));
        }
        out
    }

    /// Corner `i` of the box (`0..8`): bit 0 of `i` picks `max.x` over `min.x`, bit 1 `max.y`,
    /// bit 2 `max.z`.
    #[must_use]
    pub fn corner(&self, i: usize) -> DVec3 {
        DVec3::new(
            if i & 1 == 0 { self.min.x } else { self.max.x },
            if i & 2 == 0 { self.min.y } else { self.max.y },
            if i & 4 == 0 { self.min.z } else { self.max.z },
        )
    }

    /// The part of `range` where the ray is inside the box (robust slab test), or `None`.
    ///
    /// Direction components of ±0 give ±∞ reciprocals; an origin exactly on a slab plane then
    /// gives `0·∞ = NaN`, which the `min`/`max` ordering below discards, so a ray lying in a face
    /// plane counts as inside that slab. The exit distance is enlarged by `1 + 2γ₃` (pbrt-v4) so
    /// rounding never culls a true hit.
    #[must_use]
    pub fn clip(&self, ray: &Ray, range: Interval) -> Option<Interval> {
        let inv = ray.dir.recip();
        let mut t0 = range.min;
        let mut t1 = range.max;
        for axis in 0..3 {
            let o = ray.origin[axis];
            let (lo, hi) = (self.min[axis], self.max[axis]);
            if inv[axis].is_infinite() && lo <= o && o <= hi {
                continue;
            }
            let mut near = (lo - o) * inv[axis];
            let mut far = (hi - o) * inv[axis];
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            far *= 1.0 + 2.0 * crate::math::gamma(3);
            // `f64::max`/`min` ignore a NaN operand, keeping the current bound.
            t0 = t0.max(near);
            t1 = t1.min(far);
            if t0 > t1 {
                return None;
            }
        }
        Some(Interval::new(t0, t1))
    }
}
