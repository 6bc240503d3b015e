//! Triangle meshes: a shared f32 vertex buffer, 32-bit index triples, optional per-vertex
//! normals, a per-mesh BVH and a watertight ray/triangle test.
//!
//! # Conventions
//! - **Orientation.** A triangle `(a, b, c)` faces the side from which it is seen
//!   counter-clockwise; its geometric normal is `(b − a) × (c − a)` normalised. A closed mesh
//!   wound consistently counter-clockwise seen from outside has outward normals.
//! - **Hits.** [`RawHit::feature`] is the triangle's index in the order given to [`Mesh::new`]
//!   (the file's face order), [`RawHit::local`] its barycentrics `(u, v)`: the hit point is
//!   `(1 − u − v)·a + u·b + v·c`. [`Intersect::uv_at`] returns the same `(u, v)`.
//! - **Normals.** [`Intersect::normal_at`] is the hit triangle's geometric normal (never
//!   interpolated); [`Mesh::shading_normal`] / [`Intersect::shading_normal_at`] interpolate the
//!   per-vertex normals with the barycentrics, where the mesh has them.
//! - **Φ.** The exact unsigned distance to the nearest triangle, signed by that triangle's face
//!   normal: `Φ(p) = ±|p − q|` with `q` the nearest surface point, `+` on the side the normal points
//!   to. Where several triangles are (nearly) equally near (`q` on an edge or vertex), the one
//!   whose plane is most nearly perpendicular to `p − q` decides, which gives the right sign for a
//!   closed, consistently oriented mesh. Near the surface this is the signed distance; far from a
//!   mesh that is not closed the sign is only "which side of the nearest face". Φ costs a BVH
//!   nearest-point query (it is not on the hot path: intersection never evaluates it).
//! - **Precision.** Storage is f32. Each query converts the f64 ray once to an f32 ray (its
//!   direction scaled by a power of two, exactly, so that its largest component lies in `[1, 2)`)
//!   and precomputes the data of the watertight test of Woop, Benthin and Wald (2013,
//!   "Watertight Ray/Triangle Intersection", JCGT 2(1)): the axis `k_z` of the largest direction
//!   component, the permuted axes and the shear constants. Edge functions that evaluate to exactly
//!   zero are recomputed in f64, and a ray through a shared edge or vertex hits at least one of
//!   the triangles sharing it: closed meshes do not leak. The reported `t` is recomputed in f64
//!   from the hit triangle's plane (exact f32 vertices, f64 ray), so depth is accurate to f64
//!   rounding rather than f32; hits within `10⁻⁵` of the scene scale of `t_min` are re-decided
//!   with that f64 `t` so that rays leaving the surface do not re-hit it.
//! - **Degenerate triangles** (zero area, exactly) are **skipped**: they keep their index (so
//!   `feature` still matches the file) but are left out of the BVH, so they are never hit and do
//!   not take part in Φ. [`Mesh::skipped_triangles`] counts them.
//!
//! # Storage
//! Vertices `12 B` each (plus `12 B` with normals), triangles `12 B` (index triple, kept in BVH
//! leaf order) plus `8 B` (leaf ↔ file order maps), their corners again in the leaves' rows
//! (`36 B`, see [`leaf_rows`]: a leaf test reads its triangles' coordinates eight at a time,
//! without going through the indices), each triangle's unit normal rounded to f32 (`12 B`, for
//! [`Intersect::normal_at_f32`]; meshes of up to 2¹⁸ triangles), 4-wide BVH nodes `128 B` each, about
//! `0.07 N` of them for `N` triangles on the benchmark meshes, which packets walk, and the same
//! hierarchy collapsed into 8-wide nodes of `256 B`, about half as many, which single rays walk,
//! made when the first single ray needs them (see [`Mesh::memory_bytes`]). The BVH is described
//! in `bvh/build.rs`, the 8-wide nodes in `bvh/oct.rs`.
//!
//! One mesh can be placed many times without copying: wrap an `Arc<Mesh>` in
//! [`crate::Transformed`] per instance; the scene BVH holds the instances, each instance's mesh
//! its own BVH (two levels).

use crate::bounds::Aabb;
use crate::bvh::build::{Bb, BuildItem, Leaves, Node, QuadBvh, SlabRay};
use crate::bvh::oct::Octs;
use crate::bvh::{lane_mask, lanes_of, prefetch, round_down, round_up, LeafTest};
use crate::error::PrimitiveError;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect};
use crate::PACKET;
/// A mesh's leaves: up to eight triangles, all tested in one 8-lane pass ([`watertight_lanes`]),
/// priced in the SAH as three single triangle tests (a split's sides as that many full leaves).
/// Measured against leaves of at most six triangles priced one test each, on random rays
/// entering the bench meshes' boxes: 13 %, 16 % and 20 % faster on levels 4, 6 and 8, with a
/// quarter of the nodes (0.07 N quads for N triangles, against 0.28 N).
const LEAVES: Leaves = Leaves::tested_together(8, 3.0);
const _: () = assert!(LEAVES.max <= PACKET, "a leaf's triangles fit in the lanes of one test");

/// How many levels below the root [`Implicit::bounds_parts`] takes the boxes from.
const PART_LEVELS: u32 = 4;
use glam::{DVec2, DVec3, Vec3A};
use rayon::prelude::*;
use std::fmt;

/// `$mesh.$method::<KX, KY, KZ>(args…)` for the watertight test's axes `$k` (`[KX, KY, KZ]`,
/// one of the six orders): each order has its own copy of the method, its permutations resolved
/// at compile time.
macro_rules! by_axes {
    ($k:expr, $mesh:ident.$method:ident($($arg:expr),* $(,)?)) => {
        match $k {
            [1, 2, 0] => $mesh.$method::<1, 2, 0>($($arg),*),
            [2, 1, 0] => $mesh.$method::<2, 1, 0>($($arg),*),
            [2, 0, 1] => $mesh.$method::<2, 0, 1>($($arg),*),
            [0, 2, 1] => $mesh.$method::<0, 2, 1>($($arg),*),
            [0, 1, 2] => $mesh.$method::<0, 1, 2>($($arg),*),
            _ => $mesh.$method::<1, 0, 2>($($arg),*),
        }
    };
}

mod packet;
mod pieces;
mod stream;

/// A triangle mesh (see the module docs for its conventions).
#[derive(Clone)]
pub struct Mesh {
    vertices: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    /// Index triples in BVH leaf order; the skipped (degenerate) ones after the first `in_bvh`.
    tris: Vec<[u32; 3]>,
    leaf_to_file: Vec<u32>,
    file_to_leaf: Vec<u32>,
    in_bvh: usize,
    /// The 4-wide hierarchy: packets of rays and nearest-point queries walk it.
    bvh: QuadBvh,
    /// The corners of the triangles in the hierarchy, leaf by leaf in rows (see [`leaf_rows`]):
    /// what the leaf tests read, up to eight triangles' values of one coordinate at a time.
    leaf_corners: Vec<f32>,
    /// Each triangle's [`Intersect::normal_at`] rounded to f32, in the file's order (indexed by
    /// [`RawHit::feature`]; zero for a skipped one): [`Intersect::normal_at_f32`] reads it, one
    /// load where the f64 normal takes a square root and a division on every hit. Empty for a
    /// mesh of more than [`NORMALS_TABLE_MAX`] triangles.
    unit_normals: Vec<[f32; 3]>,
    /// For each leaf position, where its triangle sits in its leaf (see [`leaf_places`]): with
    /// it, a hit's leaf position alone finds the triangle's rows.
    leaf_places: Vec<u8>,
    /// The same hierarchy collapsed into 8-wide nodes: single rays walk it (fewer levels to wait
    /// on memory for, see `bvh/oct.rs`). Made when a single ray first needs it ([`Mesh::octs`]):
    /// a render whose camera rays all travel in packets never pays for it.
    octs: std::sync::OnceLock<Octs>,
    bounds: Aabb,
    center: DVec3,
    radius: f64,
    /// The largest distance from `center` to a vertex (f64, rounded up): every triangle lies in
    /// this ball, tighter than the box's (`radius`) for a rounded shape. [`Mesh::misses_ball`].
    ball_radius: f64,
}

impl fmt::Debug for Mesh {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Mesh")
            .field("triangles", &self.tris.len())
            .field("vertices", &self.vertices.len())
            .field("normals", &self.normals.is_some())
            .field("skipped", &self.skipped_triangles())
            .field("bounds", &self.bounds)
            .finish()
    }
}

/// Triangles per task of the normals' table ([`unit_normals_into`]).
const NORMALS_RUN: usize = 4096;

/// The most triangles a mesh keeps the f32 normals' table for ([`Intersect::normal_at_f32`]).
/// The table spares a hit the square root and division of its normal, which a small mesh waits
/// on: the default render of the level-4 and level-6 bench meshes (5,120 and 81,920 triangles)
/// 13 % faster. On a mesh past the caches a hit's normal waits on memory instead, whether read
/// from the table or worked out from the leaf's rows: the level-8 mesh (1,310,720 triangles)
/// rendered no faster with the table (0.0537 against 0.0539 s), which took 13 ms more to load
/// (page faults on 15 MB of fresh memory) and 12 bytes a triangle.
const NORMALS_TABLE_MAX: usize = 1 << 18;

/// Into `out[i]`, the unit normal of triangle `run[i]` as [`Intersect::normal_at`] makes it
/// ([`Mesh::plane`]'s `(b − a) × (c − a)` in f64, then glam's `normalize_or_zero`: the same
/// operations in the same order, so the same f64 values), rounded to f32. Four triangles at a
/// time, each step over the four lanes (packed square roots and divisions where one at a time
/// waited on each).
#[inline(always)]
fn unit_normals_into(run: &[[u32; 3]], vertices: &[[f32; 3]], out: &mut [[f32; 3]]) {
    let mut groups = run.chunks_exact(4);
    let mut outs = out.chunks_exact_mut(4);
    for (group, out) in (&mut groups).zip(&mut outs) {
        // lane `l` is triangle `group[l]`: its corners `a`, and the edges `b − a`, `c − a`
        let (mut a, mut e1, mut e2) = ([[0.0f64; 4]; 3], [[0.0f64; 4]; 3], [[0.0f64; 4]; 3]);
        for (l, t) in group.iter().enumerate() {
            let [p, q, r] = t.map(|i| vertices[i as usize]);
            for k in 0..3 {
                a[k][l] = f64::from(p[k]);
                e1[k][l] = f64::from(q[k]) - a[k][l];
                e2[k][l] = f64::from(r[k]) - a[k][l];
            }
        }
        // glam's `cross`: x = s.y·r.z − r.y·s.z, y = s.z·r.x − r.z·s.x, z = s.x·r.y − r.x·s.y;
        // then `normalize_or_zero`: `1 / √(n·n)`, the dot summed left to right
        let (mut n, mut rcp) = ([[0.0f64; 4]; 3], [0.0f64; 4]);
        for l in 0..4 {
            n[0][l] = e1[1][l] * e2[2][l] - e2[1][l] * e1[2][l];
            n[1][l] = e1[2][l] * e2[0][l] - e2[2][l] * e1[0][l];
            n[2][l] = e1[0][l] * e2[1][l] - e2[0][l] * e1[1][l];
        }
        for l in 0..4 {
            rcp[l] = 1.0 / ((n[0][l] * n[0][l] + n[1][l] * n[1][l]) + n[2][l] * n[2][l]).sqrt();
        }
        // `rcp.is_finite() && rcp > 0` (false for NaN), as a select the lanes share
        let mut unit = [[0.0f32; 4]; 3];
        for k in 0..3 {
            for l in 0..4 {
                let r = rcp[l];
                unit[k][l] = if r > 0.0 && r < f64::INFINITY {
                    (n[k][l] * r) as f32
                } else {
                    0.0
                };
            }
        }
        for (l, out) in out.iter_mut().enumerate() {
            *out = [unit[0][l], unit[1][l], unit[2][l]];
        }
    }
    for (t, unit) in groups.remainder().iter().zip(outs.into_remainder()) {
        let [a, b, c] = t.map(|i| v64(vertices[i as usize]));
        *unit = (b - a).cross(c - a).normalize_or_zero().as_vec3().to_array();
    }
}

fn v64(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// Whether the triangle `a, b, c` has zero area, exactly: `(b−a)×(c−a) = 0` computed in f64 from
/// the f32 vertices (the differences are exact and so are their products, so the test is exact).
/// Such triangles (collinear or repeated vertices) are left out of a [`Mesh`] and never hit.
#[must_use]
pub fn is_degenerate_triangle(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> bool {
    (v64(b) - v64(a)).cross(v64(c) - v64(a)) == DVec3::ZERO
}

/// Floats after the last leaf's rows, so that eight floats read from the start of any row stay
/// inside the buffer.
const ROW_PAD: usize = 8;

/// The corners of the triangles of every leaf of `bvh` ([`QuadBvh::leaves`]), whose leaf
/// positions index `tris`, laid out leaf by leaf in rows: the leaf of `count` triangles from
/// leaf position `first` owns the floats `9·first .. 9·(first + count)`, row `r = 3·corner + axis`
/// (corners `a, b, c`, axes `x, y, z`) starting at `9·first + r·count`, one float per triangle
/// in leaf order; [`ROW_PAD`] zeros follow. A leaf's rows are one contiguous block (at most
/// `9·8·4 = 288` bytes), and any row loads as one 8-lane vector whose lanes from `count` on
/// hold the next row's values (ignored).
fn leaf_rows(bvh: &QuadBvh, tris: &[[u32; 3]], vertices: &[[f32; 3]]) -> Vec<f32> {
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
fn leaf_places(bvh: &QuadBvh, len: usize) -> Vec<u8> {
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
struct LeafRows<'a> {
    /// The leaf's block and the floats after it (at least [`ROW_PAD`] more).
    block: &'a [f32],
    count: usize,
}

impl LeafRows<'_> {
    /// Row `r` (`3·corner + axis`) as eight lanes, lane `i < count` the leaf's `i`-th triangle.
    #[inline(always)]
    fn row(&self, r: usize) -> Lanes {
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
    fn all_corner_rows(&self, k: [usize; 3]) -> [[Lanes; 3]; 3] {
        [self.corner_rows(0, k), self.corner_rows(1, k), self.corner_rows(2, k)]
    }

    /// [`Mesh::plane`] of the leaf's `i`-th triangle, from its rows: the same f32 corners, the
    /// same arithmetic, so the same values.
    #[inline(always)]
    fn plane(&self, i: usize) -> (DVec3, DVec3) {
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
    fn permuted_corners(&self, i: usize, k: [usize; 3]) -> [[f32; 3]; 3] {
        let mut corners = [[0.0; 3]; 3];
        for (corner, permuted) in corners.iter_mut().enumerate() {
            for (component, &axis) in permuted.iter_mut().zip(&k) {
                *component = self.block[(3 * corner + axis) * self.count + i];
            }
        }
        corners
    }
}

/// `t` of `ray` on the plane through `a` with normal `n` (any length), if finite (f64).
#[inline(always)]
fn plane_t(n: DVec3, a: DVec3, ray: &Ray) -> Option<f64> {
    let t = n.dot(a - ray.origin) / n.dot(ray.dir);
    t.is_finite().then_some(t)
}

/// One f32 per SIMD lane.
type Lanes = [f32; PACKET];

/// An operand of the lane kernels ([`watertight_lanes`]): a value per lane ([`Lanes`]) or one
/// value shared by every lane (`f32`), which the compiler broadcasts once rather than reading
/// eight equal lanes from memory.
trait PerLane: Copy {
    /// The value in lane `l`.
    fn lane(&self, l: usize) -> f32;
}

impl PerLane for Lanes {
    #[inline(always)]
    fn lane(&self, l: usize) -> f32 {
        self[l]
    }
}

impl PerLane for f32 {
    #[inline(always)]
    fn lane(&self, _: usize) -> f32 {
        *self
    }
}

/// Eight watertight tests at once ([`watertight_lanes`]), lane by lane.
struct WatertightLanes {
    /// `t` along the (scaled) ray.
    t: Lanes,
    /// The second and third scaled barycentrics and their sum with the first.
    e1: Lanes,
    e2: Lanes,
    det: Lanes,
    /// Lanes with an edge function of exactly zero: their answer is the single test's
    /// ([`MeshRay::permuted_triangle`], which recomputes those in f64), not the lane's.
    zero: u32,
    /// Lanes whose triangle is hit at a `t` in their range (meaningless where `zero`).
    pass: u32,
}

impl WatertightLanes {
    /// Lane `l`'s hit `(t, u, v)`, as the single test gives it (for a lane in `pass`, not in
    /// `zero`).
    #[inline(always)]
    fn hit(&self, l: usize) -> (f32, f32, f32) {
        (self.t[l], self.e1[l] / self.det[l], self.e2[l] / self.det[l])
    }
}

/// The watertight test of [`MeshRay::permuted_triangle`], eight lanes at once, in exactly its
/// f32 arithmetic but without the f64 recomputation (lanes that need it are marked `zero`):
/// lane `l` tests the triangle of corners `a, b, c` (`[axis][lane]`, components in the ray's
/// order `(k_x, k_y, k_z)`) against the ray of origin `origin` (same order) and shear constants
/// `shear`, over `[t_min, t_max]`. One ray against eight triangles (the corners per lane, the
/// ray's values shared) or eight rays against one triangle (the other way round): a value shared
/// by all lanes is given as one `f32` ([`PerLane`]), the same in every lane, so both forms give
/// the lanes bit for bit the same answers.
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays by the lane; the form the compiler vectorises"
)]
fn watertight_lanes<C: PerLane, R: PerLane>(
    [a, b, c]: &[[C; 3]; 3],
    origin: &[R; 3],
    shear: &[R; 3],
    t_min: R,
    t_max: R,
) -> WatertightLanes {
    let mut out = WatertightLanes {
        t: [0.0; PACKET],
        e1: [0.0; PACKET],
        e2: [0.0; PACKET],
        det: [0.0; PACKET],
        zero: 0,
        pass: 0,
    };
    let mut zero = [0i32; PACKET];
    let mut pass = [0i32; PACKET];
    for l in 0..PACKET {
        let [ox, oy, oz] = [origin[0].lane(l), origin[1].lane(l), origin[2].lane(l)];
        let [sx, sy, sz] = [shear[0].lane(l), shear[1].lane(l), shear[2].lane(l)];
        let (az, bz, cz) = (a[2].lane(l) - oz, b[2].lane(l) - oz, c[2].lane(l) - oz);
        let ax = (a[0].lane(l) - ox) - sx * az;
        let ay = (a[1].lane(l) - oy) - sy * az;
        let bx = (b[0].lane(l) - ox) - sx * bz;
        let by = (b[1].lane(l) - oy) - sy * bz;
        let cx = (c[0].lane(l) - ox) - sx * cz;
        let cy = (c[1].lane(l) - oy) - sy * cz;
        let e0 = cx * by - cy * bx;
        let e1 = ax * cy - ay * cx;
        let e2 = bx * ay - by * ax;
        zero[l] = -i32::from((e0 == 0.0) | (e1 == 0.0) | (e2 == 0.0));
        let det = e0 + e1 + e2;
        let t = (e0 * (sz * az) + e1 * (sz * bz) + e2 * (sz * cz)) / det;
        let mixed = ((e0 < 0.0) | (e1 < 0.0) | (e2 < 0.0)) & ((e0 > 0.0) | (e1 > 0.0) | (e2 > 0.0));
        pass[l] = -i32::from(!mixed & (det != 0.0) & (t >= t_min.lane(l)) & (t <= t_max.lane(l)));
        out.t[l] = t;
        out.e1[l] = e1;
        out.e2[l] = e2;
        out.det[l] = det;
    }
    out.zero = lane_mask(&zero);
    out.pass = lane_mask(&pass);
    out
}

/// Per-query f32 ray data (see the module docs).
struct MeshRay {
    slab: SlabRay,
    origin: [f32; 3],
    k: [usize; 3],
    /// `origin` in the order `k` ([`permuted`]), made once for the ray by selects: the leaf
    /// tests of the interleaved walks (whose axes are not constants) took `permuted`'s branch
    /// on the order, mispredicted about 1.7 times a ray (cachegrind, 30,000 random rays
    /// entering the level-6 mesh's ball: 1.64 → 1.59 million mispredictions, the same
    /// instructions).
    origin_k: [f32; 3],
    shear: [f32; 3],
}

impl MeshRay {
    /// The ray of `origin` and `dir` (`dir` finite, its largest component of magnitude in
    /// `[2⁻⁵³, 8)`, see [`direction_scale`]) whose slab test `slab` is already made (the root is
    /// tested before the rest is set up, see [`Mesh::entry`]).
    ///
    /// Written without branches on the direction (selects and array reads rather than
    /// `Vec3A::max_position` and indexing, which branch): random rays would mispredict them.
    #[inline(always)]
    fn with_slab(slab: SlabRay, origin: Vec3A, dir: Vec3A) -> Self {
        let d = dir.to_array();
        let a = dir.abs().to_array();
        // the axis of the largest |component|, the first among equals
        let first_two = if a[1] > a[0] { 1 } else { 0 };
        let kz = if a[2] > a[first_two] { 2 } else { first_two };
        let (next, after) = ([1, 2, 0][kz], [2, 0, 1][kz]);
        // a negative `d_kz` swaps the other two, keeping the winding of the test
        let negative = d[kz] < 0.0;
        let kx = if negative { after } else { next };
        let ky = if negative { next } else { after };
        let o = origin.to_array();
        // selects, not `permuted`'s branch on the order
        let component = |axis: usize| {
            if axis == 0 {
                o[0]
            } else if axis == 1 {
                o[1]
            } else {
                o[2]
            }
        };
        Self {
            slab,
            origin: o,
            k: [kx, ky, kz],
            origin_k: [component(kx), component(ky), component(kz)],
            shear: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        }
    }

    /// The watertight test against `(a, b, c)`: `(t, u, v)` with `t` in `[t_min, t_max]`.
    #[inline(always)]
    fn triangle(&self, a: [f32; 3], b: [f32; 3], c: [f32; 3], t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let p = |v| permuted(v, self.k);
        self.permuted_triangle(p(a), p(b), p(c), self.origin_k, t_min, t_max)
    }

    /// The watertight test on corners and origin whose components are in the order `k`.
    #[inline(always)]
    fn permuted_triangle(
        &self,
        a: [f32; 3],
        b: [f32; 3],
        c: [f32; 3],
        o: [f32; 3],
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, f32, f32)> {
        let [sx, sy, sz] = self.shear;
        // vertices relative to the origin, then sheared so the ray is the +z axis
        let (az, bz, cz) = (a[2] - o[2], b[2] - o[2], c[2] - o[2]);
        let ax = (a[0] - o[0]) - sx * az;
        let ay = (a[1] - o[1]) - sy * az;
        let bx = (b[0] - o[0]) - sx * bz;
        let by = (b[1] - o[1]) - sy * bz;
        let cx = (c[0] - o[0]) - sx * cz;
        let cy = (c[1] - o[1]) - sy * cz;
        // scaled barycentrics (edge functions)
        let mut e0 = cx * by - cy * bx;
        let mut e1 = ax * cy - ay * cx;
        let mut e2 = bx * ay - by * ax;
        // `|` and `&` rather than `||` and `&&`: one branch per test, not one per comparison
        if (e0 == 0.0) | (e1 == 0.0) | (e2 == 0.0) {
            let f = f64::from;
            e0 = (f(cx) * f(by) - f(cy) * f(bx)) as f32;
            e1 = (f(ax) * f(cy) - f(ay) * f(cx)) as f32;
            e2 = (f(bx) * f(ay) - f(by) * f(ax)) as f32;
        }
        if ((e0 < 0.0) | (e1 < 0.0) | (e2 < 0.0)) & ((e0 > 0.0) | (e1 > 0.0) | (e2 > 0.0)) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        let t = (e0 * (sz * az) + e1 * (sz * bz) + e2 * (sz * cz)) / det;
        if !(t >= t_min && t <= t_max) {
            return None;
        }
        Some((t, e1 / det, e2 / det))
    }
}

/// `[v[kx], v[ky], v[kz]]` for the axes `k` of a [`MeshRay`], with constant indices in each arm
/// (a run-time index would send `v` through memory).
#[inline(always)]
fn permuted(v: [f32; 3], k: [usize; 3]) -> [f32; 3] {
    match k {
        [1, 2, 0] => [v[1], v[2], v[0]],
        [2, 1, 0] => [v[2], v[1], v[0]],
        [2, 0, 1] => [v[2], v[0], v[1]],
        [0, 2, 1] => [v[0], v[2], v[1]],
        [0, 1, 2] => [v[0], v[1], v[2]],
        _ => [v[1], v[0], v[2]],
    }
}

/// The point of triangle `(a, b, c)` nearest to `p` (Ericson, "Real-Time Collision Detection",
/// §5.1.5, by Voronoi regions).
fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

impl Mesh {
    /// A mesh of `indices` (counter-clockwise triples into `vertices`) with optional per-vertex
    /// `normals` (one per vertex, any non-zero length). Builds the BVH (in parallel on the
    /// current rayon pool).
    ///
    /// # Errors
    /// No triangles; a non-finite vertex or normal (`vertices[i]`, `normals[i]`); an index out of
    /// range (`indices[t]`); a normal count different from the vertex count; 2³² − 1 triangles
    /// or more. Degenerate triangles are not an error (they are skipped, see the module docs).
    pub fn new(
        vertices: Vec<[f32; 3]>,
        indices: Vec<[u32; 3]>,
        normals: Option<Vec<[f32; 3]>>,
    ) -> Result<Self, PrimitiveError> {
        if indices.is_empty() {
            return Err(PrimitiveError::new("Mesh", "indices", "the mesh has no triangles"));
        }
        // triangles are numbered in u32, and u32::MAX marks a degenerate one during the build
        if indices.len() >= u32::MAX as usize {
            return Err(PrimitiveError::new(
                "Mesh",
                "indices",
                format!("{} triangles (at most {} in one mesh)", indices.len(), u32::MAX - 1),
            ));
        }
        if let Some(i) = vertices.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
            return Err(PrimitiveError::new(
                "Mesh",
                format!("vertices[{i}]"),
                format!("must be finite, got {:?}", vertices[i]),
            ));
        }
        let nv = vertices.len();
        if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| i as usize >= nv)) {
            return Err(PrimitiveError::new(
                "Mesh",
                format!("indices[{t}]"),
                format!("{:?} refers past the last vertex ({nv} vertices)", indices[t]),
            ));
        }
        if let Some(n) = &normals {
            if n.len() != nv {
                return Err(PrimitiveError::new(
                    "Mesh",
                    "normals",
                    format!("{} normals for {nv} vertices", n.len()),
                ));
            }
            if let Some(i) = n.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
                return Err(PrimitiveError::new(
                    "Mesh",
                    format!("normals[{i}]"),
                    format!("must be finite, got {:?}", n[i]),
                ));
            }
        }
        // triangle boxes, written in place in parallel (an indexed collect: a filtered one
        // gathers pieces and copies them); degenerate triangles are marked, then left out
        const DEGENERATE: u32 = u32::MAX;
        let mut build: Vec<BuildItem> = Vec::new();
        build.par_extend(indices.par_iter().enumerate().map(|(id, t)| {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            let (a, b, c, id) = if is_degenerate_triangle(a, b, c) {
                (a, a, a, DEGENERATE)
            } else {
                (a, b, c, id as u32)
            };
            let (a, b, c) = (Vec3A::from_array(a), Vec3A::from_array(b), Vec3A::from_array(c));
            let bounds = Bb {
                lo: a.min(b).min(c),
                hi: a.max(b).max(c),
            };
            BuildItem::new(bounds, id)
        }));
        build.retain(|item| item.id != DEGENERATE);
        if build.is_empty() {
            return Err(PrimitiveError::new(
                "Mesh",
                "indices",
                "every triangle is degenerate (zero area)",
            ));
        }
        let bvh = QuadBvh::build(&mut build, LEAVES);
        let in_bvh = build.len();
        let mut leaf_to_file: Vec<u32> = build.par_iter().map(|b| b.id).collect();
        drop(build);
        let mut file_to_leaf = vec![u32::MAX; indices.len()];
        for (leaf, &file) in leaf_to_file.iter().enumerate() {
            file_to_leaf[file as usize] = leaf as u32;
        }
        for (file, slot) in file_to_leaf.iter_mut().enumerate() {
            if *slot == u32::MAX {
                *slot = leaf_to_file.len() as u32;
                leaf_to_file.push(file as u32);
            }
        }
        let tris: Vec<[u32; 3]> = leaf_to_file.par_iter().map(|&f| indices[f as usize]).collect();
        // a triangle left out of the hierarchy (a zero cross product) gets a zero normal, as
        // `normal_at` answers
        let mut unit_normals = Vec::new();
        if indices.len() <= NORMALS_TABLE_MAX {
            unit_normals = vec![[0.0; 3]; indices.len()];
            unit_normals
                .par_chunks_mut(NORMALS_RUN)
                .zip(indices.par_chunks(NORMALS_RUN))
                .for_each(|(out, run)| {
                    crate::with_fma!(unit_normals_into(
                        run: &[[u32; 3]] = run,
                        vertices: &[[f32; 3]] = &vertices,
                        out: &mut [[f32; 3]] = out,
                    ) -> ())
                });
        }
        drop(indices);
        let leaf_corners = leaf_rows(&bvh, &tris[..in_bvh], &vertices);
        let leaf_places = leaf_places(&bvh, in_bvh);
        let bounds = Aabb::new(v64(bvh.root.lo), v64(bvh.root.hi));
        let center = bounds.center();
        let ball_radius = vertices
            .par_iter()
            .map(|&v| (v64(v) - center).length())
            .reduce(|| 0.0, f64::max)
            .next_up();
        Ok(Self {
            ball_radius,
            center,
            radius: 0.5 * bounds.diagonal_length(),
            vertices,
            normals,
            tris,
            leaf_to_file,
            file_to_leaf,
            in_bvh,
            leaf_corners,
            leaf_places,
            unit_normals,
            octs: std::sync::OnceLock::new(),
            bvh,
            bounds,
        })
    }

    /// Number of triangles (including skipped degenerate ones).
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Number of vertices.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Degenerate (zero-area) triangles left out of the BVH.
    #[must_use]
    pub fn skipped_triangles(&self) -> usize {
        self.tris.len() - self.in_bvh
    }

    /// Whether per-vertex normals were given.
    #[must_use]
    pub fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    /// The vertex buffer.
    #[must_use]
    pub fn vertices(&self) -> &[[f32; 3]] {
        &self.vertices
    }

    /// Vertex indices of triangle `i` (in the order given to [`Mesh::new`]).
    ///
    /// # Panics
    /// If `i` is not below [`Mesh::triangle_count`].
    #[must_use]
    pub fn triangle_indices(&self, i: usize) -> [u32; 3] {
        self.tris[self.file_to_leaf[i] as usize]
    }

    /// Corners of triangle `i`, in f64.
    ///
    /// # Panics
    /// If `i` is not below [`Mesh::triangle_count`].
    #[must_use]
    pub fn triangle(&self, i: usize) -> [DVec3; 3] {
        self.triangle_indices(i).map(|v| v64(self.vertices[v as usize]))
    }

    /// Bytes of heap memory held (vertices, normals, triangles, order maps, BVH nodes; the
    /// 8-wide nodes once a single ray has made them, about 40 bytes a triangle more).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.vertices.capacity() * 12
            + self.normals.as_ref().map_or(0, |n| n.capacity() * 12)
            + self.tris.capacity() * 12
            + self.leaf_corners.capacity() * 4
            + self.leaf_places.capacity()
            + self.unit_normals.capacity() * 12
            + (self.leaf_to_file.capacity() + self.file_to_leaf.capacity()) * 4
            + self.bvh.memory_bytes()
            + self.octs.get().map_or(0, Octs::memory_bytes)
    }

    /// Number of 4-wide BVH nodes.
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.bvh.quad_count()
    }

    /// The interpolated, normalised per-vertex normal at a hit of this mesh (`raw.feature` the
    /// triangle, `raw.local` the barycentrics); `None` without per-vertex normals, or where the
    /// interpolation vanishes.
    #[must_use]
    pub fn shading_normal(&self, raw: &RawHit) -> Option<DVec3> {
        let normals = self.normals.as_ref()?;
        let [a, b, c] = self.tris.get(*self.file_to_leaf.get(raw.feature as usize)? as usize)?;
        let (u, v) = (raw.local.x, raw.local.y);
        let n =
            (1.0 - u - v) * v64(normals[*a as usize]) + u * v64(normals[*b as usize]) + v * v64(normals[*c as usize]);
        let n = n.normalize_or_zero();
        (n != DVec3::ZERO).then_some(n)
    }

    /// The leaf of the triangle at leaf position `k`: `(first, count, i)`, the triangle being
    /// the `i`-th of the `count` from leaf position `first`; `None` beyond the hierarchy's
    /// triangles.
    #[inline(always)]
    fn leaf_place(&self, k: usize) -> Option<(usize, usize, usize)> {
        let place = usize::from(*self.leaf_places.get(k)?);
        let i = place & 7;
        Some((k - i, place >> 3, i))
    }

    /// [`Mesh::plane`] of the triangle of a hit (`raw.feature`), read from its leaf's rows
    /// rather than through its index triple: the rows were read by the test that found the hit
    /// (still in cache), the vertices maybe never (a miss each on a large mesh). `None` if
    /// `raw.feature` is no triangle of the hierarchy.
    #[inline(always)]
    fn hit_plane(&self, raw: &RawHit) -> Option<(DVec3, DVec3)> {
        let k = *self.file_to_leaf.get(raw.feature as usize)? as usize;
        let (first, count, i) = self.leaf_place(k)?;
        if i >= count {
            return None;
        }
        Some(self.leaf(first as u32, count as u32).plane(i))
    }

    /// The f32 corners of the triangle at leaf position `k`.
    #[inline(always)]
    fn corners(&self, k: usize) -> [[f32; 3]; 3] {
        let [a, b, c] = self.tris[k];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Unnormalised geometric normal of the triangle at leaf position `k`, and its first corner.
    /// Inlined: returned through memory, its six f64s were read back in 16-byte pieces straddling
    /// the writes that made them (a store-forwarding stall on every hit).
    #[inline(always)]
    fn plane(&self, k: usize) -> (DVec3, DVec3) {
        let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
        ((b - a).cross(c - a), a)
    }

    /// `t` of `ray` on the plane of the triangle at leaf position `k` (f64).
    fn plane_t(&self, ray: &Ray, k: usize) -> Option<f64> {
        let (n, a) = self.plane(k);
        plane_t(n, a, ray)
    }

    /// The closest hit found by running the watertight test on every triangle, without the BVH
    /// (a reference for tests): `(file index, f32 t along the unit direction)`. The same f32 ray
    /// and the same rule as [`Mesh::intersect`]: the smallest `(t, leaf position)` wins.
    #[doc(hidden)]
    #[must_use]
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<(u32, f32)> {
        let query = self.query(ray, Interval::new(0.0, f64::INFINITY))?;
        let mut best: Option<(u32, f32)> = None;
        for k in 0..self.in_bvh {
            let [a, b, c] = self.corners(k);
            if let Some((t, _, _)) = query.ray.triangle(a, b, c, 0.0, f32::INFINITY) {
                if best.is_none_or(|(_, t_best)| t < t_best) {
                    best = Some((self.leaf_to_file[k], t));
                }
            }
        }
        let unit = query.scale * ray.dir.length();
        best.map(|(file, t)| (file, (f64::from(t) * unit) as f32))
    }

    /// Nearest surface point to `p`: `(q, leaf position of its triangle)`.
    fn nearest(&self, p: DVec3) -> (DVec3, usize) {
        let best_d2 = std::cell::Cell::new(f64::INFINITY);
        let mut best = (p, 0usize, -1.0f64); // (q, k, |cos| tie-break key)
        let tol = 1e-10;
        self.bvh.nearest(
            |node: &Node| {
                let d = (v64(node.lo) - p).max(p - v64(node.hi)).max(DVec3::ZERO);
                let d2 = d.length_squared();
                (d2 <= best_d2.get() * (1.0 + tol)).then_some(d2)
            },
            |first, count| {
                for k in first as usize..(first + count) as usize {
                    let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
                    let q = closest_on_triangle(p, a, b, c);
                    let d2 = (p - q).length_squared();
                    if d2 > best_d2.get() * (1.0 + tol) {
                        continue;
                    }
                    let n = (b - a).cross(c - a).normalize_or_zero();
                    let len = d2.sqrt();
                    let key = if len > 0.0 { (n.dot(p - q) / len).abs() } else { 1.0 };
                    if d2 < best_d2.get() * (1.0 - tol) || key > best.2 {
                        best = (q, k, key);
                    }
                    best_d2.set(best_d2.get().min(d2));
                }
            },
        );
        (best.0, best.1)
    }
}

impl Implicit for Mesh {
    /// Distance to the nearest triangle, signed by its face normal (see the module docs).
    fn phi(&self, p: DVec3) -> f64 {
        let (q, k) = self.nearest(p);
        let d = (p - q).length();
        let (n, _) = self.plane(k);
        if n.dot(p - q) < 0.0 {
            -d
        } else {
            d
        }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The boxes [`PART_LEVELS`] levels below the hierarchy's root (at most `4^PART_LEVELS`; a
    /// leaf met on the way gives its own box): together they hold every triangle.
    fn bounds_parts(&self, parts: &mut Vec<Aabb>) {
        if self.bvh.quads().is_empty() {
            parts.push(self.bounds);
            return;
        }
        let boxes = self.bvh.boxes_below(PART_LEVELS);
        parts.extend(boxes.into_iter().map(|(lo, hi)| Aabb::new(v64(lo), v64(hi))));
    }

    /// `±(p − q)/|p − q|` towards `Φ > 0`, or the nearest triangle's normal on the surface.
    fn gradient(&self, p: DVec3) -> DVec3 {
        let (q, k) = self.nearest(p);
        let n = self.plane(k).0.normalize_or_zero();
        let d = p - q;
        let len = d.length();
        if len <= 1e-12 * self.radius.max(f64::MIN_POSITIVE) {
            n
        } else if n.dot(d) < 0.0 {
            -d / len
        } else {
            d / len
        }
    }
}

/// One ray's set-up for the mesh tests: the f32 ray (its direction scaled by a power of two, see
/// [`direction_scale`]), its range in that ray's `t`, and the band near `t_min` where hits are
/// re-decided in f64 (see the module docs), worked out at the first candidate hit (most rays have
/// none).
struct MeshQuery {
    ray: MeshRay,
    /// The power of two `s` the f64 direction was multiplied by: `t` along the f32 ray is the
    /// ray's `t` divided by `s`.
    scale: f64,
    t_min: f32,
    t_max: f32,
    /// `t_min + 10⁻⁵·(radius + |origin − centre|) / |s·dir|`, once asked for ([`Mesh::counts`]).
    band: std::cell::OnceCell<f32>,
}

/// The part of a [`MeshQuery`] made before the root test ([`Mesh::entry`]): the f32 ray (origin
/// and scaled direction), its slab test, the scale and the range in the f32 ray's `t`.
struct MeshEntry {
    slab: SlabRay,
    origin: Vec3A,
    dir: Vec3A,
    scale: f64,
    t_min: f32,
    t_max: f32,
}

impl MeshEntry {
    /// The whole set-up: the watertight test's axes and shear added.
    #[inline(always)]
    fn query(self) -> MeshQuery {
        MeshQuery {
            ray: MeshRay::with_slab(self.slab, self.origin, self.dir),
            scale: self.scale,
            t_min: self.t_min,
            t_max: self.t_max,
            band: std::cell::OnceCell::new(),
        }
    }
}

/// The closest candidate so far.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    /// `t` along the f32 ray's scaled direction.
    t: f32,
    /// Barycentrics of the hit.
    u: f32,
    v: f32,
    /// The leaf holding the triangle, its first leaf position and its number of triangles
    /// (whose rows, [`Mesh::leaf`], just read by the test, give the triangle's plane without the
    /// index and vertex loads of [`Mesh::plane`]: two cache misses in a row on a large mesh),
    /// and the triangle's place in it. 20 bytes in all, as small as the tuple it replaced.
    first: u32,
    count: u16,
    i: u16,
}

impl Candidate {
    /// The hit `(t, u, v)` on the `i`-th triangle of the leaf of `count` from `first`.
    #[inline(always)]
    fn new((t, u, v): (f32, f32, f32), first: u32, count: u32, i: usize) -> Self {
        Self {
            t,
            u,
            v,
            first,
            count: count as u16,
            i: i as u16,
        }
    }

    /// The triangle's leaf position.
    #[inline(always)]
    fn k(&self) -> usize {
        self.first as usize + usize::from(self.i)
    }
}

/// For a direction whose largest component magnitude is `m` (finite, > 0): the power of two `s`
/// that brings `s·m` into `[1, 2)` (into `[2⁻⁵³, 8)` at the ends of the f64 range, where `s`
/// is clamped to `[2⁻¹⁰²¹, 2¹⁰²¹]`), and `1/s`. Scaling by `s` is exact, so it costs no accuracy
/// and, unlike normalising, no square root or division.
#[inline(always)]
fn direction_scale(m: f64) -> (f64, f64) {
    let exponent = (((m.to_bits() >> 52) & 0x7ff) as i64 - 1023).clamp(-1021, 1021);
    let power_of_two = |e: i64| f64::from_bits(((1023 + e) as u64) << 52);
    (power_of_two(-exponent), power_of_two(exponent))
}

/// `range.min · unscale` rounded down to f32 and clamped to `[0, f32::MAX]`: the f32 ray's
/// `t_min`. A subnormal `min` (a range opened at 0 starts at `0.next_up()`) times an `unscale`
/// below `2⁸⁷³` is below `2⁻¹⁵⁰`, so 0, answered without the multiplication: on x86 a subnormal
/// operand takes a microcode assist of some hundred cycles, which was half the cost of a ray
/// passing the mesh by.
#[inline(always)]
fn scaled_t_min(min: f64, unscale: f64) -> f32 {
    if min > 0.0 && min < f64::MIN_POSITIVE && unscale < f64::from_bits((1023 + 873) << 52) {
        return 0.0;
    }
    round_down(min * unscale).clamp(0.0, f32::MAX)
}

impl Mesh {
    /// The set-up of `ray` over `range`, or `None` where nothing can be hit (a zero, infinite or
    /// NaN direction, a non-finite origin, an empty range).
    #[inline(always)]
    fn query(&self, ray: &Ray, range: Interval) -> Option<MeshQuery> {
        Some(self.entry(ray, range)?.query())
    }

    /// The first half of [`Mesh::query`]: the f32 ray and its slab test, all that the root test
    /// needs, so that a ray passing the mesh by (most of a random batch) costs this, the test of
    /// the root ([`Mesh::enters_root`]) and nothing more.
    #[inline(always)]
    fn entry(&self, ray: &Ray, range: Interval) -> Option<MeshEntry> {
        let largest = ray.dir.abs().max_element();
        if !(largest > 0.0 && largest.is_finite() && ray.origin.is_finite()) || range.is_empty() {
            return None;
        }
        let (scale, unscale) = direction_scale(largest);
        let (origin, dir) = (ray.origin.as_vec3a(), (ray.dir * scale).as_vec3a());
        Some(MeshEntry {
            slab: SlabRay::new(origin, dir),
            origin,
            dir,
            scale,
            t_min: scaled_t_min(range.min, unscale),
            t_max: round_up(range.max * unscale),
        })
    }

    /// Whether `ray` surely passes the mesh by, decided in f64 without a division: its line
    /// stays farther than `R` from the ball's centre `c` (`|(o − c) × d|² > R²·|d|²`), or, for a
    /// range starting at `t ≥ 0`, it starts outside that distance and moves away
    /// (`(o − c)·d ≥ 0`). `R` is the ball's radius enlarged by `10⁻⁶·(radius + |o|∞ + |o − c|₁)`,
    /// far more than the f32 ray the test traces is off the f64 one (`2⁻²⁴` of those sizes), and
    /// the products' rounding (`< 10⁻¹⁴·|o − c|²·|d|²`) is allowed for. So `true` never hides
    /// a hit, and most of a random batch (which misses the mesh by far) is answered here, in a
    /// few multiplications, rather than by the f32 set-up and the root's slab test (a third of
    /// the time of a random batch on a small mesh). Any NaN or overflow answers `false`.
    #[inline(always)]
    fn misses_ball(&self, ray: &Ray, range: Interval) -> bool {
        let oc = ray.origin - self.center;
        let d = ray.dir;
        let (oc2, d2) = (oc.length_squared(), d.length_squared());
        let reach =
            self.ball_radius + 1e-6 * (self.ball_radius + ray.origin.abs().max_element() + oc.abs().element_sum());
        let reach2 = reach * reach;
        let beside = oc.cross(d).length_squared() > reach2 * d2 + 1e-14 * oc2 * d2;
        // no short cuts: without branches, four rays' tests run four wide ([`Mesh::misses_ball4`])
        let leaving = (range.min >= 0.0) & (oc2 > reach2) & (oc.dot(d) >= 0.0);
        beside | leaving
    }

    /// [`Mesh::misses_ball`] of four rays (`rays` and `ranges` hold four each): the same test
    /// ray by ray, which the AVX2 copy of a batch's test ([`Intersect::intersect_each`])
    /// computes four wide; one ray at a time, the test took as long as building the ray (most
    /// of a random batch ends there).
    #[inline(always)]
    fn misses_ball4(&self, rays: &[Ray], ranges: &[Interval]) -> [bool; 4] {
        let mut miss = [false; 4];
        for l in 0..4 {
            miss[l] = self.misses_ball(&rays[l], ranges[l]);
        }
        miss
    }

    /// The 8-wide nodes, collapsed from the quads the first time a single ray asks (about 68 ms
    /// for 1.3 million triangles; concurrent first callers wait for the one that makes them).
    #[inline(always)]
    fn octs(&self) -> &Octs {
        self.octs
            .get_or_init(|| Octs::collapse(self.bvh.quads(), self.bvh.quad_count()))
    }

    /// The slab test of the ray of `entry` against the root's children (the 8-wide walk's first
    /// step, see [`Octs::root_entry`]), or `None` if it enters none: made before the rest of the
    /// set-up and the choice of walk, which a ray passing the mesh by never needs.
    #[inline(always)]
    fn enters_root(&self, entry: &MeshEntry) -> Option<(u32, [f32; 8])> {
        let root = self.octs().root_entry(&entry.slab, entry.t_min, entry.t_max)?;
        (root.0 != 0).then_some(root)
    }

    /// What every walk starts from: the ray's set-up ([`Mesh::entry`]) and the root's children it
    /// enters ([`Mesh::enters_root`]), or `None` where it cannot hit the mesh (it passes the
    /// bounding ball by, [`Mesh::misses_ball`], or enters none of those children).
    #[inline(always)]
    fn walk_start(&self, ray: &Ray, range: Interval) -> Option<(MeshEntry, (u32, [f32; 8]))> {
        if self.misses_ball(ray, range) {
            return None;
        }
        self.walk_start_in_ball(ray, range)
    }

    /// [`Mesh::walk_start`] of a ray that the ball test kept already (a batch's rays are judged
    /// by it four at a time first, `mesh/stream.rs`): the set-up and the root's test.
    #[inline(always)]
    fn walk_start_in_ball(&self, ray: &Ray, range: Interval) -> Option<(MeshEntry, (u32, [f32; 8]))> {
        let entry = self.entry(ray, range)?;
        let root = self.enters_root(&entry)?;
        Some((entry, root))
    }

    /// Whether a hit at f32 `t` on the triangle at leaf position `k` counts: outside the band
    /// near `t_min` always, inside it only if the f64 `t` on the triangle's plane is in `range`.
    #[inline(always)]
    fn counts(&self, ray: &Ray, range: Interval, query: &MeshQuery, k: usize, t: f32) -> bool {
        self.surely_beyond_band(ray, query, t)
            || t > self.band(ray, query)
            || self.plane_t(ray, k).is_some_and(|t| range.contains(t))
    }

    /// The f32 end of the band near `t_min` where hits are re-decided in f64:
    /// `t_min + 10⁻⁵·(radius + |o − c|)/|s·d|`, worked out once per ray.
    #[inline(always)]
    fn band(&self, ray: &Ray, query: &MeshQuery) -> f32 {
        *query.band.get_or_init(|| {
            let band = 1e-5 * (self.radius + (ray.origin - self.center).length());
            query.t_min + (band / (ray.dir * query.scale).length()) as f32
        })
    }

    /// A bound that decides most candidates (those far beyond the band) without the band's
    /// square roots and division: `true` only where `t > ` [`Mesh::band`]. With
    /// `B = 10⁻⁵·(radius + |o − c|)`, `|o − c| ≤ |o − c|₁` and `|s·d| ≥ m = max |s·dᵢ|`, the band's
    /// f32 end is at most `(t_min + 10⁻⁵·(radius + |o − c|₁)/m)·(1 + 2⁻²³)` (two f32 roundings
    /// up, `t_min ≥ 0`), so a `t` beyond `1 + 10⁻⁶` times that, compared multiplied through by
    /// `m`, is beyond the band.
    #[inline(always)]
    fn surely_beyond_band(&self, ray: &Ray, query: &MeshQuery, t: f32) -> bool {
        let m = (ray.dir * query.scale).abs().max_element();
        let bound = f64::from(query.t_min) * m + 1e-5 * (self.radius + (ray.origin - self.center).abs().element_sum());
        f64::from(t) * m > bound * (1.0 + 1e-6)
    }

    /// Whether a candidate at `(k, t)` replaces `best`, whose `t` is `t_far`: a nearer `t`, or the
    /// same `t` on a triangle earlier in leaf order. The closest hit is thus the smallest
    /// `(t, k)`, whatever order the leaves are visited in (single rays and packets agree).
    #[inline(always)]
    fn beats(best: Option<&Candidate>, k: usize, t: f32, t_far: f32) -> bool {
        t < t_far || best.is_none_or(|b| k < b.k())
    }

    /// The raw hit of the closest candidate: `t` recomputed in f64 on the triangle's plane.
    #[inline(always)]
    fn finish(&self, ray: &Ray, range: Interval, query: &MeshQuery, best: Option<Candidate>) -> Option<RawHit> {
        let best = best?;
        let (hit, _) = self.finish_on_plane(ray, range, query, best)?;
        // what finishing the hit reads next ([`Mesh::hit_plane`]): asked for now, it arrives
        // while other rays are traced (on a large mesh, a cache miss each)
        prefetch(self.file_to_leaf.as_ptr().wrapping_add(hit.feature as usize));
        prefetch(self.leaf_places.as_ptr().wrapping_add(best.k()));
        Some(hit)
    }

    /// [`Mesh::finish`] and the hit's normal as [`Intersect::normal_at_f32`] gives it: from the
    /// normals' table where the mesh keeps one, else normalised from the plane `t` was found on
    /// (the triangle's rows, read for it, still in cache), as `normal_at` does, without its two
    /// lookups of the triangle's place (a cache miss each on a large mesh).
    #[inline(always)]
    fn finish_with_normal(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        best: Option<Candidate>,
    ) -> Option<(RawHit, glam::Vec3)> {
        let (hit, n) = self.finish_on_plane(ray, range, query, best?)?;
        Some((hit, self.unit_normal_f32(hit.feature, || Some(n))))
    }

    /// The f32 unit normal of triangle `feature` (file order), [`Intersect::normal_at_f32`]'s
    /// answer: the table's entry where the mesh keeps one, else `plane()` (the triangle's
    /// unnormalised normal, `None` for no triangle) normalised as `normal_at` does and rounded;
    /// zero for no triangle.
    #[inline(always)]
    fn unit_normal_f32(&self, feature: u32, plane: impl FnOnce() -> Option<DVec3>) -> glam::Vec3 {
        if self.unit_normals.is_empty() {
            return plane().map_or(glam::Vec3::ZERO, |n| n.normalize_or_zero().as_vec3());
        }
        self.unit_normals
            .get(feature as usize)
            .map_or(glam::Vec3::ZERO, |&n| glam::Vec3::from_array(n))
    }

    /// The raw hit of the candidate `best` (`t` recomputed in f64 on the triangle's plane) and
    /// that plane's unnormalised normal; `None` where `t` lies beyond the range.
    #[inline(always)]
    fn finish_on_plane(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        best: Candidate,
    ) -> Option<(RawHit, DVec3)> {
        let (n, a) = self.leaf(best.first, u32::from(best.count)).plane(usize::from(best.i));
        let t = plane_t(n, a, ray)
            .unwrap_or(f64::from(best.t) * query.scale)
            .max(range.min);
        if t > range.max {
            return None;
        }
        let hit = RawHit {
            t,
            feature: self.leaf_to_file[best.k()],
            local: DVec2::new(f64::from(best.u), f64::from(best.v)),
        };
        Some((hit, n))
    }
}

impl Mesh {
    /// The single-ray walk of `query` (whose axes are `[KX, KY, KZ]`), the root's slab test
    /// `root` made ([`Mesh::enters_root`]): the closest candidate.
    #[inline(always)]
    fn closest_candidate<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        root: (u32, [f32; 8]),
    ) -> Option<Candidate> {
        let mut leaves = SingleRayLeaves::<KX, KY, KZ> {
            mesh: self,
            ray,
            range,
            query,
            best: None,
        };
        self.octs()
            .traverse(&query.ray.slab, query.t_min, query.t_max, root, &mut leaves);
        leaves.best
    }
}

/// The single-ray leaf test for a ray whose axes are `[KX, KY, KZ]`: each triangle of the leaf
/// in turn, keeping the closest candidate.
struct SingleRayLeaves<'a, const KX: usize, const KY: usize, const KZ: usize> {
    mesh: &'a Mesh,
    ray: &'a Ray,
    range: Interval,
    query: &'a MeshQuery,
    best: Option<Candidate>,
}

impl<const KX: usize, const KY: usize, const KZ: usize> LeafTest for &mut SingleRayLeaves<'_, KX, KY, KZ> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, t_far: f32) -> Option<f32> {
        self.mesh.leaf_closest(
            self.ray,
            self.range,
            self.query,
            [KX, KY, KZ],
            first,
            count,
            t_far,
            &mut self.best,
        )
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.mesh.prefetch_leaf(first, count);
    }
}

impl Mesh {
    /// The rows of the leaf of `count` triangles from leaf position `first` (see [`leaf_rows`]).
    #[inline(always)]
    fn leaf(&self, first: u32, count: u32) -> LeafRows<'_> {
        let count = count as usize;
        let start = 9 * first as usize;
        LeafRows {
            block: &self.leaf_corners[start..start + 9 * count + ROW_PAD],
            count,
        }
    }

    /// Asks memory for the rows of the leaf of `count` triangles from `first` (its `36·count`
    /// bytes, at most five cache lines).
    #[inline(always)]
    fn prefetch_leaf(&self, first: u32, count: u32) {
        let start = self.leaf_corners.as_ptr().wrapping_add(9 * first as usize).cast::<u8>();
        let end = start.wrapping_add(36 * count as usize - 1);
        let mut line = start.wrapping_sub(start as usize & 63);
        while line <= end {
            prefetch(line);
            line = line.wrapping_add(64);
        }
    }

    /// The leaf test of one ray (`query`, whose axes are `k`: a constant where the caller knows
    /// them) against the leaf of `count` triangles from `first`, its closest candidate so far
    /// `best` at `t_far`: all the leaf's triangles in one 8-lane test ([`watertight_lanes`]),
    /// then the lanes hit, in leaf order, each as the single test would take it (the f64 test
    /// for lanes with a zero edge function, the current `t_far`, [`Mesh::beats`],
    /// [`Mesh::counts`]). Returns the new `t_far` if a candidate was kept.
    #[allow(clippy::too_many_arguments, reason = "one ray's walk state, all of it read")]
    #[inline(always)]
    fn leaf_closest(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        k: [usize; 3],
        first: u32,
        count: u32,
        mut t_far: f32,
        best: &mut Option<Candidate>,
    ) -> Option<f32> {
        let leaf = self.leaf(first, count);
        let mesh_ray = &query.ray;
        let origin = mesh_ray.origin_k;
        let lanes = watertight_lanes(&leaf.all_corner_rows(k), &origin, &mesh_ray.shear, query.t_min, t_far);
        let mut found = None;
        for i in lanes_of((lanes.pass | lanes.zero) & ((1 << count) - 1)) {
            let hit = if lanes.zero & (1 << i) != 0 {
                let [a, b, c] = leaf.permuted_corners(i, k);
                match mesh_ray.permuted_triangle(a, b, c, origin, query.t_min, t_far) {
                    Some(hit) => hit,
                    None => continue,
                }
            } else if lanes.t[i] <= t_far {
                lanes.hit(i)
            } else {
                continue;
            };
            let k = first as usize + i;
            if !Mesh::beats(best.as_ref(), k, hit.0, t_far) || !self.counts(ray, range, query, k, hit.0) {
                continue;
            }
            t_far = hit.0;
            found = Some(t_far);
            *best = Some(Candidate::new(hit, first, count, i));
        }
        found
    }
}

/// The single-ray walk of a ray whose set-up `entry` is made and which enters the root's children
/// `root` ([`Mesh::enters_root`]): the axes' copy of the walk chosen, the closest candidate
/// finished.
#[inline(always)]
fn walk(mesh: &Mesh, ray: &Ray, range: Interval, entry: MeshEntry, root: (u32, [f32; 8])) -> Option<RawHit> {
    let query = entry.query();
    let best = by_axes!(query.ray.k, mesh.closest_candidate(ray, range, &query, root));
    mesh.finish(ray, range, &query, best)
}

/// [`walk`] in its own function (its AVX2+FMA copy where the CPU has them), whichever copy calls
/// it: inlined, the walk's stack and register saves would be paid by every ray, also by those
/// passing the mesh by (most of a random batch).
#[inline(never)]
fn walk_either(mesh: &Mesh, ray: &Ray, range: Interval, entry: MeshEntry, root: (u32, [f32; 8])) -> Option<RawHit> {
    crate::with_fma!(walk(
        mesh: &Mesh = mesh,
        ray: &Ray = ray,
        range: Interval = range,
        entry: MeshEntry = entry,
        root: (u32, [f32; 8]) = root,
    ) -> Option<RawHit>)
}

/// A single ray's test: the start every walk shares ([`Mesh::walk_start`]: the ball around the
/// mesh, the set-up and the root's test), then, for a ray entering one of the root's children,
/// the walk ([`walk_either`]).
#[inline(always)]
fn single_ray(mesh: &Mesh, ray: &Ray, range: Interval) -> Option<RawHit> {
    let (entry, root) = mesh.walk_start(ray, range)?;
    walk_either(mesh, ray, range, entry, root)
}

/// [`single_ray`] of a ray that the ball test kept already ([`Mesh::walk_start_in_ball`]).
#[inline(always)]
fn single_ray_in_ball(mesh: &Mesh, ray: &Ray, range: Interval) -> Option<RawHit> {
    let (entry, root) = mesh.walk_start_in_ball(ray, range)?;
    walk_either(mesh, ray, range, entry, root)
}

impl Intersect for Mesh {
    /// [`single_ray`] in its AVX2+FMA copy where the CPU has them.
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        crate::with_fma!(single_ray(mesh: &Mesh = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    /// The rays inside one AVX2+FMA copy (the CPU's features checked once for the batch), their
    /// walks interleaved on a mesh larger than the L2 cache (`mesh/stream.rs`): the same answers
    /// as [`Mesh::intersect`] ray by ray. A mesh has no root finder, so no answer is uncertain.
    fn intersect_each(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>], uncertain: &mut [bool]) {
        uncertain.fill(false);
        #[inline(always)]
        fn each(mesh: &Mesh, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>]) {
            mesh.intersect_stream(rays, ranges, hits);
        }
        crate::with_fma!(each(mesh: &Mesh = self, rays: &[Ray] = rays, ranges: &[Interval] = ranges, hits: &mut [Option<RawHit>] = hits) -> ())
    }

    /// Walks the hierarchy once for the whole packet (see `mesh/packet.rs`); the same answers
    /// as [`Mesh::intersect`] lane by lane.
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        for ((rays, ranges), hits) in rays
            .chunks(crate::PACKET)
            .zip(ranges.chunks_mut(crate::PACKET))
            .zip(hits.chunks_mut(crate::PACKET))
        {
            packet::intersect(self, rays, ranges, hits);
        }
    }

    /// The hit triangle's geometric normal, `(b − a) × (c − a)` normalised.
    fn normal_at(&self, _ray: &Ray, raw: &RawHit) -> DVec3 {
        self.hit_plane(raw).map_or(DVec3::ZERO, |(n, _)| n.normalize_or_zero())
    }

    /// The hit triangle's normal from the f32 table made with the mesh (the same rounded
    /// values as `normal_at(…).as_vec3()`); without one (a large mesh), `normal_at` rounded.
    fn normal_at_f32(&self, _ray: &Ray, raw: &RawHit) -> glam::Vec3 {
        self.unit_normal_f32(raw.feature, || self.hit_plane(raw).map(|(n, _)| n))
    }

    /// The barycentrics `(u, v)` of the hit (see the module docs).
    fn uv_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(raw.local)
    }

    fn shading_normal_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec3> {
        self.shading_normal(raw)
    }

    /// The hierarchy's leaves (see `mesh/pieces.rs`).
    fn pieces(&self) -> Option<&dyn crate::Pieces> {
        Some(self)
    }

    /// The f32 copy of the origin is off by up to `2⁻²⁴` of each component's size: at most
    /// `√3·2⁻²⁴·max |oᵢ| < 2⁻²³·max |oᵢ|` in all.
    fn origin_rounding(&self, origin: DVec3) -> f64 {
        f64::from(f32::EPSILON) * origin.abs().max_element()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The short cut of `scaled_t_min` for a subnormal `t_min` gives what the multiplication
    /// gives, for every power-of-two `unscale` a direction can have (`2⁻¹⁰²¹ … 2¹⁰²¹`), around
    /// the cut's limit `2⁸⁷³` too.
    #[test]
    fn scaled_t_min_equals_the_product_rounded_down() {
        let mins = [
            0.0,
            -0.0,
            0.0f64.next_up(),
            2.0 * 0.0f64.next_up(),
            1e-310,
            f64::MIN_POSITIVE.next_down(),
            f64::MIN_POSITIVE,
            1e-200,
            0.5,
            -1.0,
            f64::NEG_INFINITY,
        ];
        for exponent in -1021i32..=1021 {
            let unscale = 2f64.powi(exponent);
            for min in mins {
                let reference = round_down(min * unscale).clamp(0.0, f32::MAX);
                let got = scaled_t_min(min, unscale);
                assert_eq!(got.to_bits(), reference.to_bits(), "min {min:e}, unscale 2^{exponent}");
            }
        }
    }

    /// A ray's origin in its axis order, made once by selects, is `permuted`'s, for directions
    /// along every axis, either way, with equal and zero components.
    #[test]
    fn origin_in_axis_order_is_permuted_origin() {
        let origin = Vec3A::new(1.5, -2.25, 3.125);
        let values = [-2.0f32, -1.0, -0.0, 0.0, 1.0, 2.0];
        let mut orders = std::collections::HashSet::new();
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let dir = Vec3A::new(x, y, z);
                    if dir.abs().max_element() == 0.0 {
                        continue;
                    }
                    let ray = MeshRay::with_slab(SlabRay::new(origin, dir), origin, dir);
                    assert_eq!(ray.origin_k, permuted(origin.to_array(), ray.k), "direction {dir}");
                    orders.insert(ray.k);
                }
            }
        }
        assert_eq!(orders.len(), 6, "every axis order met");
    }

    /// The height field of `n × n` vertices `(i, height(i, j), j)` on the unit grid, two
    /// triangles a cell.
    fn height_field(n: usize, height: impl Fn(usize, usize) -> f32) -> Mesh {
        let vertices: Vec<[f32; 3]> = (0..n * n)
            .map(|k| [(k % n) as f32, height(k % n, k / n), (k / n) as f32])
            .collect();
        let mut indices = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let k = (j * n + i) as u32;
                indices.push([k, k + n as u32, k + 1]);
                indices.push([k + 1, k + n as u32, k + n as u32 + 1]);
            }
        }
        Mesh::new(vertices, indices, None).unwrap()
    }

    /// The ball test never turns a hit away: rays aimed at the corners of the mesh (the
    /// vertices farthest out) from near and very far, at grazing angles along the ball's edge,
    /// with ranges starting before and after 0, all give the brute-force answer; and it turns
    /// away the rays that pass well outside the ball, or start outside it moving away.
    #[test]
    fn the_ball_test_keeps_every_hit_and_turns_away_rays_passing_by() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = height_field(12, |i, j| ((i * 5 + j * 3) % 4) as f32 * 0.25);
        let mut rng = StdRng::seed_from_u64(77);
        let corners: Vec<DVec3> = m.vertices.iter().map(|&v| v64(v)).collect();
        let (mut kept, mut turned) = (0, 0);
        for trial in 0..6000 {
            let target = corners[rng.random_range(0..corners.len())];
            let distance = 10f64.powf(rng.random_range(-1.0..7.0));
            let away = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let origin = target + away * distance;
            // aimed at the vertex, a hair beside it, or well beside the ball
            let beside = match trial % 3 {
                0 => DVec3::ZERO,
                1 => DVec3::splat(1e-9 * distance),
                _ => away.any_orthonormal_vector() * 3.0 * m.ball_radius,
            };
            let dir = (target + beside - origin) * rng.random_range(0.001..1000.0);
            let ray = Ray::new(origin, dir);
            let range = if trial % 4 == 0 {
                Interval::new(-1e9, f64::INFINITY)
            } else {
                Interval::POSITIVE
            };
            let brute = m.intersect_brute_force(&ray);
            if m.misses_ball(&ray, range) {
                turned += 1;
                assert!(brute.is_none() || range.min < 0.0, "trial {trial}: a hit turned away");
                if range.min >= 0.0 {
                    assert_eq!(m.intersect(&ray, range), None);
                }
            } else {
                kept += 1;
            }
            if range.min >= 0.0 {
                assert_eq!(
                    m.intersect(&ray, range).map(|h| h.feature),
                    brute.map(|b| b.0),
                    "trial {trial}"
                );
            }
            // pointing away from the mesh, from outside its ball: turned away
            let back = Ray::new(origin, -dir);
            if (origin - m.center).length() > 2.0 * m.ball_radius && (origin - m.center).dot(-dir) > 0.0 {
                assert!(
                    m.misses_ball(&back, Interval::POSITIVE),
                    "trial {trial}: leaving ray kept"
                );
            }
        }
        assert!(kept > 2000 && turned > 1000, "{kept} kept, {turned} turned away");
    }

    /// The four-lane ball test answers each lane as the one-ray test does for that lane's ray and
    /// range (each lane drawn on its own, so a lane handed another's ray or range fails): rays
    /// near the ball's edge, far off, from inside, leaving, with ranges starting before and
    /// after 0, and with zero, infinite and NaN components.
    #[test]
    fn four_lane_ball_test_equals_the_single_one() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = height_field(9, |i, j| ((i * 7 + j * 5) % 3) as f32 * 0.4);
        let mut rng = StdRng::seed_from_u64(4);
        let specials = [0.0, -0.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 1e300, 1e-300];
        let (mut missed, mut kept) = (0, 0);
        for trial in 0..20_000 {
            let rays: [(Ray, Interval); 4] = std::array::from_fn(|_| {
                let away = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize_or(DVec3::X);
                let origin = m.center + away * m.ball_radius * 10f64.powf(rng.random_range(-2.0..4.0));
                // aimed at a point just inside or just outside the ball's edge, or well beside it
                let beside = if trial % 2 == 0 {
                    rng.random_range(-1e-6..1e-6)
                } else {
                    rng.random_range(0.0..2.0)
                };
                let edge = m.center + away.any_orthonormal_vector() * m.ball_radius * (1.0 + beside);
                let mut c = [
                    origin.x,
                    origin.y,
                    origin.z,
                    edge.x - origin.x,
                    edge.y - origin.y,
                    edge.z - origin.z,
                ];
                if trial % 7 == 0 {
                    c[rng.random_range(0..6)] = specials[rng.random_range(0..specials.len())];
                }
                if trial % 5 == 0 {
                    for v in &mut c[3..] {
                        *v = -*v;
                    }
                }
                // drawn per lane, so that a lane given another's range fails
                let range = if rng.random_bool(1.0 / 3.0) {
                    Interval::new(-1.0, f64::INFINITY)
                } else {
                    Interval::POSITIVE
                };
                (
                    Ray::new(DVec3::new(c[0], c[1], c[2]), DVec3::new(c[3], c[4], c[5])),
                    range,
                )
            });
            let (four, ranges): (Vec<Ray>, Vec<Interval>) = rays.iter().copied().unzip();
            let lanes = m.misses_ball4(&four, &ranges);
            for l in 0..4 {
                assert_eq!(lanes[l], m.misses_ball(&four[l], ranges[l]), "trial {trial}, lane {l}");
                if lanes[l] {
                    missed += 1;
                } else {
                    kept += 1;
                }
            }
        }
        assert!(missed > 20_000 && kept > 20_000, "{missed} missed, {kept} kept");
    }

    /// The interleaved walks (`stream.rs`) give every ray exactly the single walk's answer, and
    /// the brute-force triangle where the range starts at 0: on a bumpy height field (with exact
    /// ties, rays through shared vertices and edges), for batches of 1 to 300 rays mixing rays
    /// that miss, rays entering from above at every slope, short ranges ending before the
    /// surface, and ranges starting beyond it; whatever the batch size, flights take off,
    /// land and refill in every order.
    #[test]
    fn interleaved_walks_equal_single_rays() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = height_field(48, |i, j| ((i * 7 + j * 3) % 5) as f32 * 0.5);
        let mut rng = StdRng::seed_from_u64(2027);
        let (mut hits, mut total) = (0, 0);
        for batch in [1, 2, 7, 8, 9, 31, 300] {
            for _ in 0..6 {
                let mut rays = Vec::new();
                let mut ranges = Vec::new();
                for r in 0..batch {
                    let origin = DVec3::new(
                        rng.random_range(-5.0..52.0),
                        rng.random_range(-3.0..8.0),
                        rng.random_range(-5.0..52.0),
                    );
                    let target = if r % 5 == 0 {
                        // a vertex: the hit is shared by up to six triangles
                        v64(m.vertices[rng.random_range(0..m.vertices.len())])
                    } else {
                        DVec3::new(
                            rng.random_range(-2.0..50.0),
                            rng.random_range(-1.0..3.0),
                            rng.random_range(-2.0..50.0),
                        )
                    };
                    rays.push(Ray::new(origin, (target - origin) * rng.random_range(0.01..100.0)));
                    ranges.push(match r % 7 {
                        0 => Interval::new(0.0, rng.random_range(0.0..1.2)),
                        1 => Interval::new(rng.random_range(0.0..2.0), f64::INFINITY),
                        _ => Interval::POSITIVE,
                    });
                }
                // stale answers of an earlier batch: every one must be overwritten
                let mut streamed = vec![Some(RawHit::at(-1.0)); batch];
                m.interleaved(&rays, &ranges, &mut streamed);
                for (i, (ray, range)) in rays.iter().zip(&ranges).enumerate() {
                    let single = single_ray(&m, ray, *range);
                    assert_eq!(streamed[i], single, "batch {batch}, ray {i}");
                    if *range == Interval::POSITIVE {
                        assert_eq!(
                            single.map(|h| h.feature),
                            m.intersect_brute_force(ray).map(|b| b.0),
                            "ray {i}"
                        );
                    }
                    hits += usize::from(single.is_some());
                    total += 1;
                }
            }
        }
        assert!(hits > total / 4 && hits < total * 3 / 4, "{hits} hits of {total}");
    }

    /// Every triangle lies inside one of the mesh's bounds parts, which number at most
    /// `4^PART_LEVELS`, lie inside its bounds, and are fewer and smaller than the whole box
    /// where the mesh is large (a tetrahedron: its own few leaves).
    #[test]
    fn bounds_parts_hold_every_triangle() {
        for mesh in [tetra(), height_field(60, |i, j| ((i * 7 + j * 3) % 11) as f32 * 0.3)] {
            let mut parts = Vec::new();
            mesh.bounds_parts(&mut parts);
            assert!(!parts.is_empty() && parts.len() <= 4usize.pow(PART_LEVELS));
            let bounds = mesh.bounds();
            for part in &parts {
                assert!(
                    bounds.contains(part.min) && bounds.contains(part.max),
                    "{part:?} in {bounds:?}"
                );
            }
            for tri in &mesh.tris[..mesh.in_bvh] {
                let corners = tri.map(|i| v64(mesh.vertices[i as usize]));
                assert!(
                    parts.iter().any(|p| corners.iter().all(|&c| p.contains(c))),
                    "triangle {corners:?} in no part"
                );
            }
            if mesh.in_bvh > 1000 {
                assert!(parts.len() >= 16, "{} parts", parts.len());
                let volume = |b: &Aabb| b.extent().x * b.extent().y * b.extent().z;
                assert!(parts.iter().map(volume).sum::<f64>() < volume(&bounds));
            }
        }
    }

    fn tetra() -> Mesh {
        let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        // counter-clockwise seen from outside
        let i = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        Mesh::new(v, i, None).unwrap()
    }

    /// |Φ| is the distance to the nearest triangle: the 4-wide hierarchy's nearest-point walk
    /// against a brute-force minimum over every triangle, on a bumpy height field of 2 × 24²
    /// triangles (many leaves and levels) and points around, above and below it.
    #[test]
    fn phi_is_the_distance_to_the_nearest_triangle() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = height_field(25, |i, j| ((i * 7 + j * 13) % 11) as f32 * 0.05);
        assert!(m.node_count() > 20);
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..2000 {
            let p = DVec3::new(
                rng.random_range(-3.0..27.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..27.0),
            );
            let brute = (0..m.triangle_count())
                .map(|k| {
                    let [a, b, c] = m.triangle(k);
                    (p - closest_on_triangle(p, a, b, c)).length()
                })
                .fold(f64::INFINITY, f64::min);
            let phi = m.phi(p).abs();
            assert!(
                (phi - brute).abs() <= 1e-9 * brute.max(1e-300),
                "{p}: |Φ| {phi}, nearest {brute}"
            );
        }
    }

    /// The batch entry point gives each ray exactly its single-ray answer, writing every entry
    /// (callers reuse their buffers uncleared): rays entering the height field, passing it by,
    /// and without a direction, over blocks of 256 and a last one whose length is no multiple of
    /// four (the ball test's one-ray tail).
    #[test]
    fn intersect_each_equals_intersect() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = height_field(30, |i, j| ((i * 5 + j * 11) % 7) as f32 * 0.1);
        let mut rng = StdRng::seed_from_u64(21);
        let rays: Vec<Ray> = (0..2003)
            .map(|i| {
                let o = DVec3::new(
                    rng.random_range(-5.0..35.0),
                    rng.random_range(-2.0..3.0),
                    rng.random_range(-5.0..35.0),
                );
                let d = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                Ray::new(o, if i % 101 == 0 { DVec3::ZERO } else { d })
            })
            .collect();
        let ranges: Vec<Interval> = (0..rays.len())
            .map(|i| {
                if i % 3 == 0 {
                    Interval::new(0.5, 20.0)
                } else {
                    Interval::POSITIVE
                }
            })
            .collect();
        // stale answers of an earlier batch: every one must be overwritten
        let (mut hits, mut uncertain) = (vec![Some(RawHit::at(-1.0)); rays.len()], vec![true; rays.len()]);
        m.intersect_each(&rays, &ranges, &mut hits, &mut uncertain);
        assert!(uncertain.iter().all(|u| !u));
        let single: Vec<Option<RawHit>> = rays.iter().zip(&ranges).map(|(r, g)| m.intersect(r, *g)).collect();
        assert_eq!(hits, single);
        // a hit's normal, read from its leaf's rows, is the one its index triple gives
        for (ray, hit) in rays.iter().zip(&single) {
            let Some(hit) = hit else { continue };
            let [a, b, c] = m.triangle(hit.feature as usize);
            assert_eq!(m.normal_at(ray, hit), (b - a).cross(c - a).normalize());
        }
        let found = single.iter().flatten().count();
        assert!(found > 200 && found < 1800, "{found} hits");
    }

    /// Every leaf's rows hold its triangles' corners (as the index triples give them) and give
    /// their planes, each row readable as eight lanes, and the leaves' blocks tile the buffer in
    /// leaf order.
    #[test]
    fn leaf_rows_hold_each_leaf_s_corners() {
        let m = height_field(40, |i, j| (((j * 40 + i) * 7919) % 13) as f32 * 0.1);
        assert_eq!(m.leaf_corners.len(), 9 * m.in_bvh + ROW_PAD);
        let (mut covered, mut sizes) = (vec![0u32; m.in_bvh], [0usize; 9]);
        for (first, count) in m.bvh.leaves() {
            sizes[count] += 1;
            let leaf = m.leaf(first as u32, count as u32);
            for i in 0..count {
                let k = first + i;
                covered[k] += 1;
                let corners = m.corners(k);
                assert_eq!(leaf.permuted_corners(i, [0, 1, 2]), corners, "leaf triangle {k}");
                assert_eq!(
                    leaf.permuted_corners(i, [2, 0, 1])[1],
                    [corners[1][2], corners[1][0], corners[1][1]]
                );
                for r in 0..9 {
                    assert_eq!(leaf.row(r)[i], corners[r / 3][r % 3], "triangle {k}, row {r}");
                }
                // the plane from the rows is the plane from the index triple, bit for bit
                let [a, b, c] = corners.map(v64);
                assert_eq!(leaf.plane(i), ((b - a).cross(c - a), a), "triangle {k}");
                // and the triangle's leaf is found again from its position
                assert_eq!(m.leaf_place(k), Some((first, count, i)));
            }
        }
        assert!(covered.iter().all(|&c| c == 1), "every triangle in exactly one leaf");
        // SAH, pricing a whole leaf as three tests, fills leaves well beyond one triangle
        let leaves: usize = sizes.iter().sum();
        assert!(sizes[1..4].iter().sum::<usize>() * 2 < leaves, "leaf sizes {sizes:?}");
    }

    #[allow(
        clippy::needless_range_loop,
        reason = "the lane indexes the test's arrays and the corners alike"
    )]
    /// The 8-lane watertight test gives, lane by lane, exactly the single test's `(t, u, v)` (or
    /// its miss) wherever no edge function is exactly zero, and marks the lanes where one is:
    /// random triangles, and triangles with a corner or an edge on the ray.
    #[test]
    fn eight_lane_test_equals_the_single_test() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let mut rng = StdRng::seed_from_u64(88);
        let m = tetra();
        let (mut zero_lanes, mut hits) = (0, 0);
        for _ in 0..3000 {
            let origin = DVec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            );
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let ray = Ray::new(origin, dir);
            let Some(q) = m.query(&ray, Interval::POSITIVE) else {
                continue;
            };
            let k = q.ray.k;
            let d32 = (dir * q.scale).as_vec3a().to_array();
            let mut corners = [[[0f32; 3]; 3]; PACKET];
            for (l, tri) in corners.iter_mut().enumerate() {
                for v in tri.iter_mut() {
                    *v = std::array::from_fn(|_| rng.random_range(-1.5f32..1.5));
                }
                // lanes 1 and 2: a corner on the ray (an origin corner: every edge through it is zero)
                if l == 1 {
                    tri[0] = q.ray.origin;
                }
                if l == 2 {
                    tri[2] = q.ray.origin;
                    tri[1] = std::array::from_fn(|a| q.ray.origin[a] + 0.5 * d32[a]);
                }
            }
            let permuted_corners = corners.map(|tri| tri.map(|v| permuted(v, k)));
            let rows: [[Lanes; 3]; 3] =
                std::array::from_fn(|c| std::array::from_fn(|a| std::array::from_fn(|l| permuted_corners[l][c][a])));
            let origin = permuted(q.ray.origin, k);
            let t_max = rng.random_range(0.5f32..4.0);
            let lanes = watertight_lanes(&rows, &origin, &q.ray.shear, q.t_min, t_max);
            for l in 0..PACKET {
                let [a, b, c] = permuted_corners[l];
                let single = q.ray.permuted_triangle(a, b, c, origin, q.t_min, t_max);
                if lanes.zero & (1 << l) != 0 {
                    zero_lanes += 1;
                    continue;
                }
                let lane = (lanes.pass & (1 << l) != 0)
                    .then(|| (lanes.t[l], lanes.e1[l] / lanes.det[l], lanes.e2[l] / lanes.det[l]));
                hits += usize::from(single.is_some());
                assert_eq!(
                    lane.map(|(t, u, v)| [t.to_bits(), u.to_bits(), v.to_bits()]),
                    single.map(|(t, u, v)| [t.to_bits(), u.to_bits(), v.to_bits()]),
                    "lane {l}: {corners:?}, ray {ray:?}"
                );
            }
        }
        assert!(zero_lanes >= 6000 && hits > 200, "{zero_lanes} zero lanes, {hits} hits");
    }

    #[test]
    fn tetrahedron_hit_normal_and_phi() {
        let m = tetra();
        let ray = Ray::new(DVec3::new(0.2, 0.2, -1.0), DVec3::Z);
        let hit = m.intersect(&ray, Interval::POSITIVE).unwrap();
        assert!((hit.t - 1.0).abs() < 1e-12);
        assert_eq!(hit.feature, 0);
        assert!((m.normal_at(&ray, &hit) - DVec3::NEG_Z).length() < 1e-12);
        let p = ray.at(hit.t);
        let [a, b, c] = m.triangle(0);
        let q = (1.0 - hit.local.x - hit.local.y) * a + hit.local.x * b + hit.local.y * c;
        assert!((p - q).length() < 1e-6);
        assert!((m.phi(DVec3::new(0.2, 0.2, -0.5)) - 0.5).abs() < 1e-12);
        assert!(m.phi(DVec3::splat(0.1)) < 0.0);
        // an outside point nearest to an edge and to a vertex
        assert!(m.phi(DVec3::new(0.5, -0.3, -0.3)) > 0.0);
        assert!(m.phi(DVec3::new(-0.2, -0.2, -0.2)) > 0.0);
        // the far side of the range
        assert!(m.intersect(&ray, Interval::new(0.0, 0.999)).is_none());
        assert_eq!(
            m.intersect(&ray, Interval::new(1.001, 10.0)).map(|h| h.feature),
            Some(3)
        );
    }

    /// The band's cheap bound never claims a `t` that is not beyond the band, over directions
    /// from 10⁻³⁰⁰ to 10³⁰⁰ long, origins near and far and `t` on either side of the band's end;
    /// and it does decide ordinary hits (a `t` of twice the band).
    #[test]
    fn band_bound_is_conservative() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let m = tetra();
        let mut rng = StdRng::seed_from_u64(11);
        let (mut decided, mut total) = (0, 0);
        for _ in 0..20_000 {
            let far = 10f64.powi(rng.random_range(-3..6));
            let origin = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * far;
            let length = 10f64.powi(rng.random_range(-300..300));
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * length;
            let t_min = if rng.random_bool(0.5) {
                0.0
            } else {
                rng.random_range(0.0..2.0) / length
            };
            let ray = Ray::new(origin, dir);
            let Some(query) = m.query(&ray, Interval::new(t_min, f64::INFINITY)) else {
                continue;
            };
            let band = m.band(&ray, &query);
            let mut probes = vec![
                band,
                band.next_up(),
                band.next_down(),
                2.0 * band + f32::MIN_POSITIVE,
                f32::MAX,
            ];
            probes.extend((0..8).map(|_| band * rng.random_range(0.5f32..4.0)));
            for t in probes {
                total += 1;
                if m.surely_beyond_band(&ray, &query, t) {
                    assert!(
                        t > band,
                        "ray {ray:?}, t_min {t_min}: bound claims {t} beyond the band's end {band}"
                    );
                    decided += 1;
                }
            }
            let twice = 2.0 * band + f32::MIN_POSITIVE;
            if band > 0.0 && band.is_finite() && twice.is_finite() && query.t_min == 0.0 {
                assert!(m.surely_beyond_band(&ray, &query, 4.0 * twice), "{ray:?}: band {band}");
            }
        }
        assert!(decided > total / 4, "{decided} of {total} decided");
    }

    #[test]
    fn constructor_errors() {
        let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let e = Mesh::new(v.clone(), vec![[0, 1, 3]], None).unwrap_err();
        assert_eq!(e.field, "indices[0]");
        let e = Mesh::new(
            vec![[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
            None,
        )
        .unwrap_err();
        assert_eq!(e.field, "vertices[0]");
        assert!(Mesh::new(v.clone(), vec![], None).is_err());
        let e = Mesh::new(v.clone(), vec![[0, 1, 2]], Some(vec![[0.0, 0.0, 1.0]])).unwrap_err();
        assert_eq!(e.field, "normals");
        // a degenerate triangle is skipped, not an error
        let m = Mesh::new(v, vec![[0, 1, 2], [0, 0, 1]], None).unwrap();
        assert_eq!(m.skipped_triangles(), 1);
        assert_eq!(m.triangle_indices(1), [0, 0, 1]);
    }
}
