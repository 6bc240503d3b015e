//! Inside / outside of a closed mesh by grid cell ([`Regions`]): what makes occupancy and the
//! sign of signed distance cost a lookup for most points.
//!
//! **Why it is exact.** The generalized winding number `w(p)` of a *closed* mesh (every edge
//! shared by exactly two triangles, in opposite directions, once welded by position) is an
//! integer constant on each connected part of space that the surface does not cut. The mesh's
//! box is divided into a grid; every cell that a triangle's box (grown by a relative `10⁻⁹`)
//! touches is *marked*. The unmarked cells, joined across shared faces, form regions that no
//! triangle meets, so `w` is one integer on each: it is found once per region, at the centre of
//! one of its cells, by the fast winding number rounded (a region whose value is not within
//! `0.1` of an integer stays undecided). Cells of regions reaching the grid's border, and all
//! space outside the box, have `w = 0`.
//!
//! A point in an unmarked, decided cell gets that integer; every other point (a marked cell: the
//! surface is near) is answered by the chosen method as without the grid. The answers are the
//! same as the methods' own: `|w| ≥ 1` for the winding numbers, `w` odd for parity (the two
//! differ only where the mesh overlaps itself). A mesh that is not closed has no grid.

use super::storage::{v64, Mesh};
use crate::bounds::Aabb;
use glam::DVec3;

/// The state of a cell: a surface may pass through it, or the winding number of its region.
const MARKED: i8 = i8::MIN;
/// A region whose winding number could not be decided.
const UNDECIDED: i8 = i8::MIN + 1;

/// The grid of a closed mesh (see the module docs).
#[derive(Clone, Debug)]
pub(super) struct Regions {
    lo: DVec3,
    inverse_size: DVec3,
    dims: [usize; 3],
    /// Per cell: [`MARKED`], [`UNDECIDED`] or the winding number of its region.
    cells: Vec<i8>,
}

impl Regions {
    /// Bytes held.
    pub(super) fn memory_bytes(&self) -> usize {
        self.cells.capacity()
    }

    /// The winding number of the region holding `p`, where the grid decides it.
    #[inline]
    pub(super) fn winding(&self, p: DVec3) -> Option<i8> {
        let f = (p - self.lo) * self.inverse_size;
        if !(f.min_element() >= 0.0) {
            return if f.is_nan() { None } else { Some(0) };
        }
        let (i, j, k) = (f.x as usize, f.y as usize, f.z as usize);
        if i >= self.dims[0] || j >= self.dims[1] || k >= self.dims[2] {
            return Some(0);
        }
        match self.cells[(k * self.dims[1] + j) * self.dims[0] + i] {
            MARKED | UNDECIDED => None,
            w => Some(w),
        }
    }
}

/// Each vertex's first vertex at the same position (`−0` as `+0`): the vertices welded by
/// position, so that triangles saved as loose corners share their edges.
pub(super) fn welded(vertices: &[[f32; 3]]) -> Vec<u32> {
    let key = |i: u32| vertices[i as usize].map(|x| (x + 0.0).to_bits());
    let mut order: Vec<u32> = (0..vertices.len() as u32).collect();
    order.sort_unstable_by_key(|&i| (key(i), i));
    let mut canon = vec![0u32; vertices.len()];
    let mut start = 0;
    for (j, &i) in order.iter().enumerate() {
        if key(i) != key(order[start]) {
            start = j;
        }
        canon[i as usize] = order[start];
    }
    canon
}

/// Whether the triangles `tris` (of `vertices`) form a closed surface: welded by position, each
/// undirected edge is used exactly twice, once in each direction.
fn is_closed(vertices: &[[f32; 3]], tris: &[[u32; 3]]) -> bool {
    if tris.is_empty() {
        return false;
    }
    let canon = welded(vertices);
    // (smaller end, larger end, direction)
    let mut edges: Vec<(u32, u32, bool)> = Vec::with_capacity(3 * tris.len());
    for t in tris {
        for e in 0..3 {
            let (a, b) = (canon[t[e] as usize], canon[t[(e + 1) % 3] as usize]);
            if a == b {
                return false;
            }
            edges.push((a.min(b), a.max(b), a < b));
        }
    }
    edges.sort_unstable();
    edges
        .chunk_by(|x, y| x.0 == y.0 && x.1 == y.1)
        .all(|run| run.len() == 2 && run[0].2 != run[1].2)
}

impl Mesh {
    /// The grid of a closed mesh, made the first time it is asked for; `None` for a mesh that is
    /// not closed.
    pub(super) fn regions(&self) -> Option<&Regions> {
        self.regions.get_or_init(|| self.make_regions()).as_ref()
    }

    fn make_regions(&self) -> Option<Regions> {
        let tris = &self.tris[..self.in_bvh];
        if !is_closed(&self.vertices, tris) {
            return None;
        }
        let bounds: Aabb = self.bounds;
        let extent = bounds.max - bounds.min;
        // about 64 cells along the longest side (128 past 10⁵ triangles), at least 1 each way:
        // finer grids decide more points but take longer to flood than they save in one batch
        let along = if tris.len() > 100_000 { 128.0 } else { 64.0 };
        let size = extent.max_element() / along;
        if !(size > 0.0) || !size.is_finite() {
            return None;
        }
        let dims = [0, 1, 2].map(|a| ((extent[a] / size).ceil() as usize).clamp(1, 256));
        let lo = bounds.min;
        let inverse_size = DVec3::new(
            dims[0] as f64 / extent.x.max(f64::MIN_POSITIVE),
            dims[1] as f64 / extent.y.max(f64::MIN_POSITIVE),
            dims[2] as f64 / extent.z.max(f64::MIN_POSITIVE),
        );
        let mut cells = vec![0i8; dims[0] * dims[1] * dims[2]];
        let index = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
        let cell_of = |x: f64, axis: usize| -> usize {
            let f = ((x - lo[axis]) * inverse_size[axis]).floor();
            if f <= 0.0 {
                0
            } else {
                (f as usize).min(dims[axis] - 1)
            }
        };
        let grow = 1e-9 * (extent.length() + lo.abs().max(bounds.max.abs()).max_element());
        for t in tris {
            let [a, b, c] = t.map(|i| v64(self.vertices[i as usize]));
            let (tlo, thi) = (
                a.min(b).min(c) - DVec3::splat(grow),
                a.max(b).max(c) + DVec3::splat(grow),
            );
            for k in cell_of(tlo.z, 2)..=cell_of(thi.z, 2) {
                for j in cell_of(tlo.y, 1)..=cell_of(thi.y, 1) {
                    for i in cell_of(tlo.x, 0)..=cell_of(thi.x, 0) {
                        cells[index(i, j, k)] = MARKED;
                    }
                }
            }
        }
        // regions of unmarked cells, flooded across faces; `0` marks "not reached yet" and is
        // replaced by each region's value (a region reaching the border is the outside: 0)
        let mut seen = vec![false; cells.len()];
        let mut queue = Vec::new();
        let mut members = Vec::new();
        for start in 0..cells.len() {
            if seen[start] || cells[start] == MARKED {
                continue;
            }
            seen[start] = true;
            queue.push(start);
            members.clear();
            let mut border = false;
            while let Some(c) = queue.pop() {
                members.push(c);
                let (i, j, k) = (c % dims[0], (c / dims[0]) % dims[1], c / (dims[0] * dims[1]));
                border |= i == 0 || j == 0 || k == 0 || i + 1 == dims[0] || j + 1 == dims[1] || k + 1 == dims[2];
                let mut visit = |n: usize| {
                    if !seen[n] && cells[n] != MARKED {
                        seen[n] = true;
                        queue.push(n);
                    }
                };
                if i > 0 {
                    visit(c - 1);
                }
                if i + 1 < dims[0] {
                    visit(c + 1);
                }
                if j > 0 {
                    visit(c - dims[0]);
                }
                if j + 1 < dims[1] {
                    visit(c + dims[0]);
                }
                if k > 0 {
                    visit(c - dims[0] * dims[1]);
                }
                if k + 1 < dims[2] {
                    visit(c + dims[0] * dims[1]);
                }
            }
            let value = if border {
                0
            } else {
                let c = members[0];
                let (i, j, k) = (c % dims[0], (c / dims[0]) % dims[1], c / (dims[0] * dims[1]));
                let centre = lo + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) / inverse_size;
                let w = self.fast_winding_number(centre);
                let rounded = w.round();
                if (w - rounded).abs() <= 0.1 && rounded.abs() < 100.0 {
                    rounded as i8
                } else {
                    UNDECIDED
                }
            };
            for &c in &members {
                cells[c] = value;
            }
        }
        Some(Regions {
            lo,
            inverse_size,
            dims,
            cells,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cube's 12 triangles, outward.
    fn cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let v: Vec<[f32; 3]> = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (v, f)
    }

    #[test]
    fn closedness_is_decided_by_welded_edges() {
        let (v, f) = cube();
        assert!(is_closed(&v, &f));
        // one face missing: open
        assert!(!is_closed(&v, &f[1..]));
        // one face flipped: an edge used twice in one direction
        let mut flipped = f.clone();
        flipped[0] = [0, 1, 2];
        assert!(!is_closed(&v, &flipped));
        // the same cube with every triangle's corners duplicated (a triangle soup) welds closed
        let soup_v: Vec<[f32; 3]> = f.iter().flat_map(|t| t.map(|i| v[i as usize])).collect();
        let soup_f: Vec<[u32; 3]> = (0..f.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        assert!(is_closed(&soup_v, &soup_f));
        // a duplicated face in the opposite direction: an edge used four times
        let mut doubled = f.clone();
        doubled.push([0, 1, 2]);
        doubled.push([0, 2, 1]);
        assert!(!is_closed(&v, &doubled));
    }

    #[test]
    fn a_cube_s_cells_agree_with_its_box() {
        let (v, f) = cube();
        let mesh = Mesh::new(v, f, None).unwrap();
        let regions = mesh.regions().expect("a cube is closed");
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 1.6 - 0.3
        };
        let mut decided = 0;
        for _ in 0..20_000 {
            let p = DVec3::new(next(), next(), next());
            if let Some(w) = regions.winding(p) {
                decided += 1;
                let inside = p.min_element() > 0.0 && p.max_element() < 1.0;
                assert_eq!(w != 0, inside, "{p}: winding {w}");
            }
        }
        assert!(decided > 15_000, "most points are decided by their cell ({decided})");
    }
}
