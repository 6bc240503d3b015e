//! The leaves' corner rows: each leaf's triangles' corners, stored again next to each other in
//! structure-of-arrays rows so that a leaf test reads one coordinate of up to eight triangles as
//! one 8-lane vector, without going through the index triples ([`leaf_rows`], [`LeafRows`]).
//!
//! Layout: the leaf of `count` triangles from leaf position `first` owns the floats
//! `9·first .. 9·(first + count)`; row `r = 3·corner + axis` (corners `a, b, c`, axes `x, y, z`)
//! starts at `9·first + r·count`, one float per triangle in leaf order. [`ROW_PAD`] zeros end the
//! buffer so that eight floats read from the start of any row stay inside it.

use super::watertight::Lanes;
use crate::bvh::quad_bvh::QuadBvh;
use crate::PACKET;
use glam::DVec3;
use rayon::prelude::*;

/// Floats after the last leaf's rows, so that eight floats read from the start of any row stay
/// inside the buffer.
pub(super) const ROW_PAD: usize = 8;

/// The corners of the triangles of every leaf of `bvh` ([`QuadBvh::leaves`]), whose leaf
/// positions index `tris`, laid out leaf by leaf in rows: the leaf of `count` triangles from
/// leaf position `first` owns the floats `9·first .. 9·(first + count)`, row `r = 3·corner + axis`
/// (corners `a, b, c`, axes `x, y, z`) starting at `9·first + r·count`, one float per triangle
/// in leaf order; [`ROW_PAD`] zeros follow. A leaf's rows are one contiguous block (at most
/// `9·8·4 = 288` bytes), and any row loads as one 8-lane vector whose lanes from `count` on
/// hold the next row's values (ignored).
pub(super) fn leaf_rows(bvh: &QuadBvh, tris: &[[u32; 3]], vertices: &[[f32; 3]]) -> Vec<f32> {
    let leaves = bvh.leaves();
    let mut rows = vec![0.0f32; 9 * tris.len() + ROW_PAD];
    // each leaf's block, in leaf order (the leaves partition the leaf positions)
    let mut blocks = Vec::with_capacity(leaves.len());
    let mut rest = &mut rows[..9 * tris.len()];
    for &(first, count) in &leaves {
        let (block, after) = rest.split_at_mut(9 * count);
        blocks.push((first, count, block));
        rest = after;
    }
    debug_assert!(rest.is_empty() && leaves.iter().map(|l| l.1).sum::<usize>() == tris.len());
    blocks.into_par_iter().for_each(|(first, count, block)| {
        for (i, tri) in tris[first..first + count].iter().enumerate() {
            for (corner, &v) in tri.iter().enumerate() {
                for (axis, &x) in vertices[v as usize].iter().enumerate() {
                    block[(3 * corner + axis) * count + i] = x;
                }
            }
        }
    });
    rows
}

/// For each of the `len` leaf positions of `bvh`'s leaves: `i | count << 3`, the triangle being
/// the leaf's `i`-th of `count` (`count ≤ 8`), so that its leaf starts at position `k − i`.
pub(super) fn leaf_places(bvh: &QuadBvh, len: usize) -> Vec<u8> {
    let mut places = vec![0u8; len];
    for (first, count) in bvh.leaves() {
        for (i, place) in places[first..first + count].iter_mut().enumerate() {
            *place = (i | count << 3) as u8;
        }
    }
    places
}

/// One leaf's rows (see [`leaf_rows`]).
#[derive(Clone, Copy)]
pub(super) struct LeafRows<'a> {
    /// The leaf's block and the floats after it (at least [`ROW_PAD`] more).
    pub(super) block: &'a [f32],
    pub(super) count: usize,
}

impl LeafRows<'_> {
    /// Row `r` (`3·corner + axis`) as eight lanes, lane `i < count` the leaf's `i`-th triangle.
    #[inline(always)]
    pub(super) fn row(&self, r: usize) -> Lanes {
        let start = r * self.count;
        let mut lanes = [0.0; PACKET];
        lanes.copy_from_slice(&self.block[start..start + PACKET]);
        lanes
    }

    /// The three rows of `corner`'s components in the order `k`.
    #[inline(always)]
    fn corner_rows(&self, corner: usize, k: [usize; 3]) -> [Lanes; 3] {
        // no `map` with a closure: closures are not inlined into the AVX2 copies
        [
            self.row(3 * corner + k[0]),
            self.row(3 * corner + k[1]),
            self.row(3 * corner + k[2]),
        ]
    }

    /// The three corners' rows, components in the order `k`.
    #[inline(always)]
    pub(super) fn all_corner_rows(&self, k: [usize; 3]) -> [[Lanes; 3]; 3] {
        [self.corner_rows(0, k), self.corner_rows(1, k), self.corner_rows(2, k)]
    }

    /// [`Mesh::plane`] of the leaf's `i`-th triangle, from its rows: the same f32 corners, the
    /// same arithmetic, so the same values.
    #[inline(always)]
    pub(super) fn plane(&self, i: usize) -> (DVec3, DVec3) {
        let corner = |c: usize| {
            DVec3::new(
                f64::from(self.block[3 * c * self.count + i]),
                f64::from(self.block[(3 * c + 1) * self.count + i]),
                f64::from(self.block[(3 * c + 2) * self.count + i]),
            )
        };
        let (a, b, c) = (corner(0), corner(1), corner(2));
        ((b - a).cross(c - a), a)
    }

    /// The corners of the leaf's `i`-th triangle, components in the order `k`.
    #[inline(always)]
    pub(super) fn permuted_corners(&self, i: usize, k: [usize; 3]) -> [[f32; 3]; 3] {
        let mut corners = [[0.0; 3]; 3];
        for (corner, permuted) in corners.iter_mut().enumerate() {
            for (component, &axis) in permuted.iter_mut().zip(&k) {
                *component = self.block[(3 * corner + axis) * self.count + i];
            }
        }
        corners
    }
}
