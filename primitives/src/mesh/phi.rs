//! The nearest-point query: the point of the mesh nearest to `p`, its triangle and its
//! barycentrics ([`Mesh::nearest_feature`]), what Φ, ∇Φ, `closest` and the pseudo-normal sign
//! all use.
//!
//! **Walk.** Depth first over the 4-wide hierarchy, nearer box first, a box skipped once a lower
//! bound of its squared distance from `p` (four boxes in f32 lanes, lowered by the rounding
//! bound below) exceeds the best squared distance so far (no allocation: the pending nodes wait
//! in a fixed array).
//!
//! **Leaves in two stages.** A leaf's triangles (its f32 rows, up to eight) get the distance from
//! `p` in f32 lanes at once (projection onto the plane where it falls inside all three edges,
//! else the nearest of the three edges' nearest points), lowered by a bound on the f32 rounding
//! (`2⁻¹⁷ ×` the magnitudes involved, generous against the few dozen operations): a lower bound of
//! the exact distance (a sliver, whose f32 normal is unreliable, gets the bound 0). Only triangles whose bound does not exceed the best so far are tested
//! again exactly in f64 ([`closest_barycentrics`]), so the answer is the f64 one while most
//! triangles cost one lane of a vector pass.
//!
//! **A start.** Each thread remembers the triangle its last query on the mesh found; the next
//! query measures that triangle first, so that its walk prunes from the start (neighbouring
//! points, which batches take in Morton order, mostly share their nearest triangle: 11 % on the
//! benchmark meshes). It only sets the first bound: the answer is the walk's either way.
//!
//! **Ties.** Φ (see the module docs of [`crate::mesh`]) is `±|p − q|` signed by the nearest
//! triangle's face normal. Where several triangles are within a relative `10⁻¹⁰` of the same
//! squared distance (`q` on a shared edge or vertex), the one whose plane is most nearly
//! perpendicular to `p − q` (largest `|n̂·(p − q)| / |p − q|`) is kept, which gives the right sign
//! for a closed, consistently oriented mesh; then the smaller leaf position.

use super::rows::LeafRows;
use super::storage::Mesh;
use crate::bvh::quad::Quad;
use crate::bvh::walk::QUAD_STACK;
pub(super) use crate::triangle::closest_barycentrics;
use crate::triangle::closest_on_collapsed;
use crate::PACKET;
use glam::DVec3;
use std::mem::MaybeUninit;

/// The relative width within which squared distances tie.
const TIE: f64 = 1e-10;

/// The nearest point found by [`Mesh::nearest_feature`].
#[derive(Clone, Copy, Debug)]
pub(super) struct NearestPoint {
    /// The point.
    pub(super) point: DVec3,
    /// Leaf position of its triangle.
    pub(super) k: usize,
    /// Its barycentrics in that triangle (`a`, `b`, `c`).
    pub(super) barycentrics: [f64; 3],
}

/// The best answer so far: the point, its squared distance and the tie-break key.
struct Best {
    found: NearestPoint,
    d2: f64,
    key: f64,
}

#[inline(always)]
fn sub(u: [f32; 3], v: [f32; 3]) -> [f32; 3] {
    [u[0] - v[0], u[1] - v[1], u[2] - v[2]]
}

#[inline(always)]
fn dot(u: [f32; 3], v: [f32; 3]) -> f32 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

#[inline(always)]
fn cross(u: [f32; 3], v: [f32; 3]) -> [f32; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// Squared distance from the origin of `from` (`p − u`) to the segment `u + s·e`, `s ∈ [0, 1]`.
#[inline(always)]
fn segment_d2(e: [f32; 3], from: [f32; 3]) -> f32 {
    let ee = dot(e, e);
    let t = if ee > 0.0 {
        (dot(from, e) / ee).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [from[0] - t * e[0], from[1] - t * e[1], from[2] - t * e[2]];
    dot(d, d)
}

/// Lower bounds of the squared distances from `p` to a leaf's triangles, lane `i < count` the
/// leaf's `i`-th (f32 arithmetic lowered by its rounding bound; see the module docs). No
/// closures: they would not be compiled into the AVX2 copy.
#[inline(always)]
fn leaf_lower_bounds(rows: &LeafRows<'_>, p: [f32; 3], margin: f32) -> [f32; PACKET] {
    let (ax, ay, az) = (rows.row(0), rows.row(1), rows.row(2));
    let (bx, by, bz) = (rows.row(3), rows.row(4), rows.row(5));
    let (cx, cy, cz) = (rows.row(6), rows.row(7), rows.row(8));
    let mut out = [0.0f32; PACKET];
    for l in 0..PACKET {
        let a = [ax[l], ay[l], az[l]];
        let b = [bx[l], by[l], bz[l]];
        let c = [cx[l], cy[l], cz[l]];
        let (e0, e1, e2) = (sub(b, a), sub(c, b), sub(a, c));
        let (pa, pb, pc) = (sub(p, a), sub(p, b), sub(p, c));
        let n = cross(e0, sub(c, a));
        let nn = dot(n, n);
        // inside all three edges (seen along n): the plane's distance
        let inside = dot(cross(e0, pa), n) >= 0.0 && dot(cross(e1, pb), n) >= 0.0 && dot(cross(e2, pc), n) >= 0.0;
        let h = dot(n, pa);
        let plane = if nn > 0.0 { h * h / nn } else { f32::INFINITY };
        let edges = segment_d2(e0, pa).min(segment_d2(e1, pb)).min(segment_d2(e2, pc));
        // a sliver's f32 normal may point anywhere: no bound (the exact test decides)
        let sliver = nn <= 1e-4 * dot(e0, e0) * dot(e2, e2);
        let d2 = if inside && plane.is_finite() { plane } else { edges };
        let d = d2.sqrt() - margin;
        out[l] = if d > 0.0 && !sliver { d * d } else { 0.0 };
    }
    out
}

/// Lower bounds of the squared distances from `p` to the four boxes of `quad`, in f32 lanes
/// lowered by `margin` (the rounding of `p` and of the arithmetic, as for the triangles).
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays by the lane; the form the compiler vectorises"
)]
fn box_lower_bounds(quad: &Quad, p: [f32; 3], margin: f32) -> [f32; 4] {
    let mut d2 = [0.0f32; 4];
    for axis in 0..3 {
        for s in 0..4 {
            let d = (quad.lo[axis][s] - p[axis]).max(p[axis] - quad.hi[axis][s]).max(0.0);
            d2[s] += d * d;
        }
    }
    let mut out = [0.0f32; 4];
    for s in 0..4 {
        let d = d2[s].sqrt() - margin;
        out[s] = if d > 0.0 { d * d } else { 0.0 };
    }
    out
}

/// The leaf of `count` triangles from leaf position `first`: f32 bounds for all, the exact test
/// for those that may be nearer than `best`.
#[inline(always)]
fn visit_leaf(mesh: &Mesh, first: u32, count: u32, p: DVec3, p32: [f32; 3], margin: f32, best: &mut Best) {
    let rows = mesh.leaf(first, count);
    let bounds = leaf_lower_bounds(&rows, p32, margin);
    for (i, &bound) in bounds.iter().enumerate().take(count as usize) {
        if f64::from(bound) <= best.d2 * (1.0 + TIE) {
            test_exactly(&rows, first as usize, i, p, best);
        }
    }
}

/// The exact f64 test of triangle `i` of the leaf from leaf position `first` (its corners from
/// the rows), kept in `best` if nearer, or as near and better placed for the sign.
#[inline(always)]
fn test_exactly(rows: &LeafRows<'_>, first: usize, i: usize, p: DVec3, best: &mut Best) {
    let at = |r: usize| f64::from(rows.block[r * rows.count + i]);
    let a = DVec3::new(at(0), at(1), at(2));
    let b = DVec3::new(at(3), at(4), at(5));
    let c = DVec3::new(at(6), at(7), at(8));
    let w = closest_barycentrics(p, a, b, c);
    let q = w[0] * a + w[1] * b + w[2] * c;
    let d2 = (p - q).length_squared();
    if d2 > best.d2 * (1.0 + TIE) {
        return;
    }
    let n = (b - a).cross(c - a).normalize_or_zero();
    let len = d2.sqrt();
    let key = if len > 0.0 { (n.dot(p - q) / len).abs() } else { 1.0 };
    let k = first + i;
    if d2 < best.d2 * (1.0 - TIE) || key > best.key || (key == best.key && k < best.found.k) {
        best.found = NearestPoint {
            point: q,
            k,
            barycentrics: w,
        };
        best.key = key;
    }
    best.d2 = best.d2.min(d2);
}

/// [`Mesh::nearest_feature`]'s walk (compiled once more with AVX2 and FMA, see
/// [`crate::with_fma`]).
#[inline(always)]
fn nearest_walk(mesh: &Mesh, p: DVec3) -> NearestPoint {
    let quads = mesh.bvh.quads();
    let mut best = Best {
        found: NearestPoint {
            point: p,
            k: 0,
            barycentrics: [1.0, 0.0, 0.0],
        },
        d2: f64::INFINITY,
        key: -1.0,
    };
    // the previous query's triangle on this thread, a bound to start from (see the module docs)
    let hint = LAST_NEAREST.with(|last| {
        let (mesh_id, k) = last.get();
        (mesh_id == std::ptr::from_ref(mesh) as usize && k < mesh.in_bvh).then_some(k)
    });
    if let Some(k) = hint {
        if let Some((first, count, i)) = mesh.leaf_place(k) {
            let rows = mesh.leaf(first as u32, count as u32);
            test_exactly(&rows, first, i, p, &mut best);
        }
    }
    let p32 = p.as_vec3().to_array();
    // the f32 rounding of `p` itself, then of the lane arithmetic over the mesh's extent
    let extent = p.abs().max_element() + mesh.bounds.min.abs().max(mesh.bounds.max.abs()).max_element();
    let margin = (extent * (1.0 / 131_072.0)) as f32;
    let root = &mesh.bvh.root;
    if root.count > 0 {
        visit_leaf(mesh, root.first, root.count, p, p32, margin, &mut best);
        return best.found;
    }
    // pending children `(node or first leaf position, triangle count, squared box distance)`;
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<(u32, u32, f64)>::uninit() }; QUAD_STACK];
    let mut top = 0usize;
    let mut q = 0usize;
    loop {
        let quad = &quads[q];
        let bounds = box_lower_bounds(quad, p32, margin);
        let mut near = [(0u32, 0u32, 0.0f64); 4];
        let mut len = 0;
        for (s, &d2) in bounds.iter().enumerate().take(quad.len as usize) {
            let d2 = f64::from(d2);
            if d2 <= best.d2 * (1.0 + TIE) {
                near[len] = (quad.child[s], u32::from(quad.count[s]), d2);
                len += 1;
            }
        }
        // farthest pushed first, so the nearest is popped next
        for i in 1..len {
            let mut j = i;
            while j > 0 && near[j - 1].2 < near[j].2 {
                near.swap(j - 1, j);
                j -= 1;
            }
        }
        for &item in &near[..len] {
            stack[top].write(item);
            top += 1;
        }
        let next = loop {
            if top == 0 {
                return best.found;
            }
            top -= 1;
            // SAFETY: `stack[top]` was written by the push that raised `top` above it
            let (child, count, d2) = unsafe { stack[top].assume_init() };
            if d2 > best.d2 * (1.0 + TIE) {
                continue;
            }
            if count == 0 {
                break child as usize;
            }
            visit_leaf(mesh, child, count, p, p32, margin, &mut best);
        };
        q = next;
    }
}

thread_local! {
    /// `(mesh address, leaf position)` of the last nearest triangle found on this thread.
    static LAST_NEAREST: std::cell::Cell<(usize, usize)> = const { std::cell::Cell::new((0, 0)) };
}

impl Mesh {
    /// The surface point nearest to `p`, its triangle and barycentrics (see the module docs).
    /// On a mesh without a surface, the nearest point of the collapsed triangles, each tried.
    pub(super) fn nearest_feature(&self, p: DVec3) -> NearestPoint {
        if !self.surface {
            return self.nearest_collapsed(p);
        }
        let found = crate::with_fma!(nearest_walk(mesh: &Mesh = self, p: DVec3 = p) -> NearestPoint);
        LAST_NEAREST.with(|last| last.set((std::ptr::from_ref(self) as usize, found.k)));
        found
    }

    /// [`Mesh::nearest_feature`] on a mesh whose triangles all have zero area: the nearest
    /// point of the segments (or points) they collapse to, by trying each (the first of equal
    /// distances).
    fn nearest_collapsed(&self, p: DVec3) -> NearestPoint {
        let mut best = (
            f64::INFINITY,
            NearestPoint {
                point: p,
                k: 0,
                barycentrics: [1.0, 0.0, 0.0],
            },
        );
        for k in 0..self.tris.len() {
            let [a, b, c] = self.corners(k).map(super::storage::v64);
            let (point, barycentrics) = closest_on_collapsed(p, a, b, c);
            let d2 = (p - point).length_squared();
            if d2 < best.0 {
                best = (d2, NearestPoint { point, k, barycentrics });
            }
        }
        best.1
    }

    /// Nearest surface point to `p`: `(q, leaf position of its triangle)`.
    pub(super) fn nearest(&self, p: DVec3) -> (DVec3, usize) {
        let found = self.nearest_feature(p);
        (found.point, found.k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f32 lower bounds never exceed the exact f64 distances, on random triangles of one
    /// leaf-sized block around and far from the points.
    #[test]
    fn leaf_bounds_are_below_the_exact_distances() {
        let mut state = 99u64;
        let mut next = |scale: f64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * scale
        };
        for trial in 0..2000 {
            let scale = [1e-3, 1.0, 1e4][trial % 3];
            let count = 1 + trial % PACKET;
            let corners: Vec<[[f32; 3]; 3]> = (0..count)
                .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| next(scale) as f32)))
                .collect();
            let mut block = vec![0.0f32; 9 * count + PACKET];
            for (i, t) in corners.iter().enumerate() {
                for (corner, v) in t.iter().enumerate() {
                    for axis in 0..3 {
                        block[(3 * corner + axis) * count + i] = v[axis];
                    }
                }
            }
            let rows = LeafRows { block: &block, count };
            let p = DVec3::new(next(3.0 * scale), next(3.0 * scale), next(3.0 * scale));
            let extent = p.abs().max_element() + scale;
            let bounds = leaf_lower_bounds(&rows, p.as_vec3().to_array(), (extent / 131_072.0) as f32);
            for (i, t) in corners.iter().enumerate() {
                let [a, b, c] = t.map(|v| DVec3::from_array(v.map(f64::from)));
                let w = closest_barycentrics(p, a, b, c);
                let exact = (p - (w[0] * a + w[1] * b + w[2] * c)).length_squared();
                assert!(
                    f64::from(bounds[i]) <= exact,
                    "triangle {t:?}, point {p}: bound {} above {exact}",
                    bounds[i]
                );
            }
        }
    }
}
