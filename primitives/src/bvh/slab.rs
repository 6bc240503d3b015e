//! A mesh's f32 slab tests: the ray of the watertight triangle test (f32 origin, reciprocal
//! direction clamped to ±`f32::MAX`, so that a zero component gives `0·MAX = 0` rather than
//! `0·∞ = NaN` on a slab plane through the origin) against one box, four boxes of a [`Quad`]
//! (SSE) or, in `oct.rs`, the eight of an `Oct`.
//!
//! Per axis the slab is `[(lo − o)·inv, (hi − o)·inv]`; the entry is the largest slab start (and
//! `t0`), the exit the smallest slab end enlarged by `1 + 2γ₃` ([`EXIT_PAD`]) as in Woop, Benthin
//! and Wald (2013), so that the box test never rejects a ray the watertight triangle test would
//! hit.

use super::lanes::{max_f32, min_f32};
use super::quad::Quad;
use super::walk::{NodeTest, SlabsFrom};
use glam::{Vec3A, Vec4};

/// `1 + 2γ₃` in f32 (γₙ = nε/(1 − nε), ε = 2⁻²⁴).
pub(crate) const EXIT_PAD: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Per-ray data for the slab tests: the f32 origin and clamped reciprocal direction.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    pub origin: Vec3A,
    pub inv: Vec3A,
}

impl SlabRay {
    /// From the f32 ray. Reciprocals are clamped to ±`f32::MAX`, so a zero direction component
    /// gives `0·MAX = 0` rather than `0·∞ = NaN` on a slab plane through the origin.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        let inv = Vec3A::ONE / dir;
        Self {
            origin,
            inv: inv.clamp(Vec3A::splat(-f32::MAX), Vec3A::splat(f32::MAX)),
        }
    }

    /// Entry distances into the four boxes of `quad` within `[t0, t1]` (per axis `(lo − o)·inv` and
    /// `(hi − o)·inv`, nearest exit enlarged by `1 + 2γ₃`; four boxes per SSE operation).
    #[inline(always)]
    pub(crate) fn entry4(&self, quad: &Quad, t0: f32, t1: f32) -> (u32, [f32; 4]) {
        let mut near = Vec4::splat(t0);
        let mut far = Vec4::splat(f32::INFINITY);
        for axis in 0..3 {
            let o = Vec4::splat(self.origin[axis]);
            let inv = Vec4::splat(self.inv[axis]);
            let a = (Vec4::from_array(quad.lo[axis]) - o) * inv;
            let b = (Vec4::from_array(quad.hi[axis]) - o) * inv;
            near = near.max(a.min(b));
            far = far.min(a.max(b));
        }
        let far = (far * EXIT_PAD).min(Vec4::splat(t1));
        (near.cmple(far).bitmask(), near.to_array())
    }

    /// Whether the ray enters the box `lo..hi` within `[t0, t1]`: the arithmetic of
    /// [`SlabRay::entry8`] for one box. Rounding is monotonic, so a ray that does not enter a
    /// box by this test enters none of the boxes inside it by `entry4` or `entry8` (each
    /// slab's entry can only be later and its exit earlier).
    #[inline(always)]
    pub(crate) fn enters(&self, lo: [f32; 3], hi: [f32; 3], t0: f32, t1: f32) -> bool {
        let (mut n, mut f) = (t0, f32::INFINITY);
        for axis in 0..3 {
            let a = (lo[axis] - self.origin[axis]) * self.inv[axis];
            let b = (hi[axis] - self.origin[axis]) * self.inv[axis];
            n = max_f32(n, min_f32(a, b));
            f = min_f32(f, max_f32(a, b));
        }
        n <= min_f32(f * EXIT_PAD, t1)
    }
}

impl NodeTest for SlabsFrom<'_, SlabRay> {
    #[inline(always)]
    fn entry4(&self, quad: &Quad, t_max: f32) -> (u32, [f32; 4]) {
        self.ray.entry4(quad, self.t_min, t_max)
    }
}
