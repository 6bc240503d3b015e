//! The 4-wide node shared by every hierarchy (the scene's over objects, each mesh's over
//! triangles): four child boxes in f32, structure of arrays, so that one SSE operation per axis
//! and per bound tests a ray against all four.

use super::lanes::{max_f32, min_f32};

/// A 4-wide node, shared by the scene's and the meshes' hierarchies: up to four children's f32
/// boxes in SoA layout, tested in one SSE pass per axis. `count[i] = 0` marks an inner child
/// (its quad is `child[i]`), `count[i] > 0` a leaf of that many items (or triangles) from
/// `child[i]`; slots beyond `len` are empty. 128 bytes: two cache lines (leaves hold at most
/// `u16::MAX` items, which the builder checks).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Quad {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub child: [u32; 4],
    pub count: [u16; 4],
    pub len: u32,
}

impl Quad {
    /// Slot `s`'s box, `(lo, hi)` per axis.
    #[inline(always)]
    pub(crate) fn slot_bounds(&self, s: usize) -> ([f32; 3], [f32; 3]) {
        (
            [self.lo[0][s], self.lo[1][s], self.lo[2][s]],
            [self.hi[0][s], self.hi[1][s], self.hi[2][s]],
        )
    }

    /// The box around its slots' boxes, `(lo, hi)` per axis: it holds every box below this
    /// node, so a ray that [`SlabRay::enters`](super::slab::SlabRay::enters) none of it enters none of theirs.
    #[inline(always)]
    pub(crate) fn box_of_slots(&self) -> ([f32; 3], [f32; 3]) {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for slot in 0..(self.len as usize).min(4) {
            for axis in 0..3 {
                lo[axis] = min_f32(lo[axis], self.lo[axis][slot]);
                hi[axis] = max_f32(hi[axis], self.hi[axis][slot]);
            }
        }
        (lo, hi)
    }

    /// A bit for each slot in use (`0..len`).
    #[inline(always)]
    pub(crate) fn occupied(&self) -> u32 {
        (1u32 << self.len) - 1
    }
}
