//! The mesh's storage and public API: [`Mesh`] (vertices, index triples in BVH leaf order, the
//! leaf ↔ file order maps, the 4-wide hierarchy, the leaves' corner rows, the f32 normals'
//! table), its constructor and accessors, and the per-triangle geometry every query reads.
//!
//! A triangle is addressed two ways: its **file index** (the order given to [`Mesh::new`],
//! [`RawHit::feature`]) and its **leaf position** `k` (its place in the hierarchy's leaf order,
//! which indexes `tris`, the corner rows and `leaf_places`). `file_to_leaf` and `leaf_to_file`
//! map between them. A triangle's plane is `n = (b − a) × (c − a)` (unnormalised, f64 from the
//! f32 corners, exact differences) through `a`; its `t` along an f64 ray is `n·(a − o) / n·d`
//! ([`plane_t`]).

use super::inside::PseudoNormals;
use super::rows::{leaf_places, leaf_rows, LeafRows, ROW_PAD};
use super::winding::WindingNodes;
use crate::bounds::Aabb;
use crate::bvh::build::{Bb, BuildItem, Leaves};
use crate::bvh::oct::Octs;
use crate::bvh::prefetching::prefetch;
use crate::bvh::quad_bvh::QuadBvh;
use crate::error::PrimitiveError;
use crate::hit::RawHit;
use crate::ray::Ray;
use crate::PACKET;
use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use std::fmt;

/// A mesh's leaves: up to eight triangles, all tested in one 8-lane pass
/// ([`super::watertight::watertight_lanes`]), priced in the SAH as three single triangle tests
/// (a split's sides as that many full leaves): fewer, fuller leaves than leaves priced one test
/// a triangle, and faster on the bench meshes (see docs/performance.md).
const LEAVES: Leaves = Leaves::tested_together(8, 3.0);
const _: () = assert!(LEAVES.max <= PACKET, "a leaf's triangles fit in the lanes of one test");

/// A triangle mesh (see the module docs for its conventions).
#[derive(Clone)]
pub struct Mesh {
    pub(super) vertices: Vec<[f32; 3]>,
    pub(super) normals: Option<Vec<[f32; 3]>>,
    /// Index triples in BVH leaf order; the skipped (degenerate) ones after the first `in_bvh`.
    pub(super) tris: Vec<[u32; 3]>,
    pub(super) leaf_to_file: Vec<u32>,
    pub(super) file_to_leaf: Vec<u32>,
    pub(super) in_bvh: usize,
    /// Whether any triangle has an area: when none has, the hierarchy holds all of them (so
    /// that its boxes and Φ's nearest points are the collapsed triangles'), and no ray or
    /// inside test walks it (see [`Mesh::has_surface`]).
    pub(super) surface: bool,
    /// The 4-wide hierarchy: packets of rays and nearest-point queries walk it.
    pub(super) bvh: QuadBvh,
    /// The corners of the triangles in the hierarchy, leaf by leaf in rows (see [`leaf_rows`]):
    /// what the leaf tests read, up to eight triangles' values of one coordinate at a time.
    pub(super) leaf_corners: Vec<f32>,
    /// Each triangle's [`Intersect::normal_at`] rounded to f32, in the file's order (indexed by
    /// [`RawHit::feature`]; zero for a skipped one): [`Intersect::normal_at_f32`] reads it, one
    /// load where the f64 normal takes a square root and a division on every hit. Empty for a
    /// mesh of more than [`NORMALS_TABLE_MAX`] triangles.
    unit_normals: Vec<[f32; 3]>,
    /// For each leaf position, where its triangle sits in its leaf (see [`leaf_places`]): with
    /// it, a hit's leaf position alone finds the triangle's rows.
    pub(super) leaf_places: Vec<u8>,
    /// The same hierarchy collapsed into 8-wide nodes: single rays walk it (fewer levels to wait
    /// on memory for, see `bvh/oct.rs`). Made when a single ray first needs it ([`Mesh::octs`]):
    /// a render whose camera rays all travel in packets never pays for it.
    pub(super) octs: std::sync::OnceLock<Octs>,
    /// The fast winding number's per-node moments ([`Mesh::fast_winding_number`], `winding.rs`),
    /// made when first asked for.
    pub(super) winding_nodes: std::sync::OnceLock<WindingNodes>,
    /// The angle-weighted pseudo-normals of vertices and edges (`inside.rs`), made when
    /// [`SignMethod::PseudoNormal`](crate::SignMethod::PseudoNormal) first needs them.
    pub(super) pseudo_normals: std::sync::OnceLock<PseudoNormals>,
    /// The inside / outside grid of a closed mesh (`regions.rs`; `None` inside for a mesh that
    /// is not closed), made when a sign is first asked for.
    pub(super) regions: std::sync::OnceLock<Option<super::regions::Regions>>,
    pub(super) bounds: Aabb,
    pub(super) center: DVec3,
    pub(super) radius: f64,
    /// The largest distance from `center` to a vertex (f64, rounded up): every triangle lies in
    /// this ball, tighter than the box's (`radius`) for a rounded shape. [`Mesh::misses_ball`].
    pub(super) ball_radius: f64,
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
/// on; on a mesh past the caches a hit's normal waits on memory instead, whether read from the
/// table or worked out from the leaf's rows, and the table only costs load time and 12 bytes a
/// triangle (see docs/performance.md).
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

#[inline]
pub(super) fn v64(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// Whether the triangle `a, b, c` has zero area, exactly: `(b−a)×(c−a) = 0` computed in f64 from
/// the f32 vertices (the differences are exact and so are their products, so the test is exact).
/// Such triangles (collinear or repeated vertices) are left out of a [`Mesh`] and never hit.
#[must_use]
pub fn is_degenerate_triangle(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> bool {
    (v64(b) - v64(a)).cross(v64(c) - v64(a)) == DVec3::ZERO
}

/// `t` of `ray` on the plane through `a` with normal `n` (any length), if finite (f64).
#[inline(always)]
pub(super) fn plane_t(n: DVec3, a: DVec3, ray: &Ray) -> Option<f64> {
    let t = n.dot(a - ray.origin) / n.dot(ray.dir);
    t.is_finite().then_some(t)
}

impl Mesh {
    /// A mesh of `indices` (counter-clockwise triples into `vertices`) with optional per-vertex
    /// `normals` (one per vertex, any non-zero length). Builds the BVH (in parallel on the
    /// current rayon pool).
    ///
    /// # Errors
    /// No triangles; a non-finite vertex or normal (`vertices[i]`, `normals[i]`); an index out of
    /// range (`indices[t]`); a normal count different from the vertex count; 2³² − 1 triangles
    /// or more. Degenerate triangles are not an error (they are skipped, see the module docs),
    /// not even when all of them are (a mesh without a surface, [`Mesh::has_surface`]).
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
        // gathers pieces and copies them); degenerate triangles are marked, then left out —
        // unless all of them are: then the hierarchy holds them all, and no query walks it
        // (a mesh without a surface, see [`Mesh::has_surface`])
        const DEGENERATE: u32 = u32::MAX;
        let boxes = |skip_degenerate: bool| {
            let mut build: Vec<BuildItem> = Vec::new();
            build.par_extend(indices.par_iter().enumerate().map(|(id, t)| {
                let [a, b, c] = t.map(|i| Vec3A::from_array(vertices[i as usize]));
                let degenerate = skip_degenerate && {
                    let [a, b, c] = t.map(|i| vertices[i as usize]);
                    is_degenerate_triangle(a, b, c)
                };
                let bounds = Bb {
                    lo: a.min(b).min(c),
                    hi: a.max(b).max(c),
                };
                BuildItem::new(bounds, if degenerate { DEGENERATE } else { id as u32 })
            }));
            build
        };
        let mut build = boxes(true);
        build.retain(|item| item.id != DEGENERATE);
        let surface = !build.is_empty();
        if !surface {
            build = boxes(false);
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
            surface,
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
            winding_nodes: std::sync::OnceLock::new(),
            pseudo_normals: std::sync::OnceLock::new(),
            regions: std::sync::OnceLock::new(),
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

    /// Degenerate (zero-area) triangles, which are never hit: all of them in a mesh without
    /// a surface, else those left out of the BVH.
    #[must_use]
    pub fn skipped_triangles(&self) -> usize {
        if self.surface {
            self.tris.len() - self.in_bvh
        } else {
            self.tris.len()
        }
    }

    /// Whether any triangle has an area. A mesh whose triangles all have zero area has no
    /// surface: no ray hits it or crosses it, no point is inside it, its winding numbers are
    /// `0`, and its Φ, gradient and closest points are those of the collapsed triangles (each
    /// the segment or point a degenerate [`crate::Triangle`] collapses to, the nearest of them
    /// found by trying each), unsigned.
    #[must_use]
    pub fn has_surface(&self) -> bool {
        self.surface
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
    /// 8-wide nodes once a single ray has made them, about 40 bytes a triangle more; the winding
    /// numbers' and pseudo-normals' data once made).
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
            + self.winding_nodes.get().map_or(0, WindingNodes::memory_bytes)
            + self.pseudo_normals.get().map_or(0, PseudoNormals::memory_bytes)
            + self
                .regions
                .get()
                .and_then(Option::as_ref)
                .map_or(0, super::regions::Regions::memory_bytes)
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
    pub(super) fn leaf_place(&self, k: usize) -> Option<(usize, usize, usize)> {
        let place = usize::from(*self.leaf_places.get(k)?);
        let i = place & 7;
        Some((k - i, place >> 3, i))
    }

    /// [`Mesh::plane`] of the triangle of a hit (`raw.feature`), read from its leaf's rows
    /// rather than through its index triple: the rows were read by the test that found the hit
    /// (still in cache), the vertices maybe never (a miss each on a large mesh). `None` if
    /// `raw.feature` is no triangle of the hierarchy.
    #[inline(always)]
    pub(super) fn hit_plane(&self, raw: &RawHit) -> Option<(DVec3, DVec3)> {
        let k = *self.file_to_leaf.get(raw.feature as usize)? as usize;
        let (first, count, i) = self.leaf_place(k)?;
        if i >= count {
            return None;
        }
        Some(self.leaf(first as u32, count as u32).plane(i))
    }

    /// The f32 corners of the triangle at leaf position `k`.
    #[inline(always)]
    pub(super) fn corners(&self, k: usize) -> [[f32; 3]; 3] {
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
    pub(super) fn plane(&self, k: usize) -> (DVec3, DVec3) {
        let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
        ((b - a).cross(c - a), a)
    }

    /// `t` of `ray` on the plane of the triangle at leaf position `k` (f64).
    #[inline]
    pub(super) fn plane_t(&self, ray: &Ray, k: usize) -> Option<f64> {
        let (n, a) = self.plane(k);
        plane_t(n, a, ray)
    }

    /// The 8-wide nodes, collapsed from the quads the first time a single ray asks (a one-off cost
    /// linear in the nodes, see docs/performance.md; concurrent first callers wait for the one
    /// that makes them).
    #[inline(always)]
    pub(super) fn octs(&self) -> &Octs {
        self.octs
            .get_or_init(|| Octs::collapse(self.bvh.quads(), self.bvh.quad_count()))
    }

    /// The f32 unit normal of triangle `feature` (file order), [`Intersect::normal_at_f32`]'s
    /// answer: the table's entry where the mesh keeps one, else `plane()` (the triangle's
    /// unnormalised normal, `None` for no triangle) normalised as `normal_at` does and rounded;
    /// zero for no triangle.
    #[inline(always)]
    pub(super) fn unit_normal_f32(&self, feature: u32, plane: impl FnOnce() -> Option<DVec3>) -> glam::Vec3 {
        if self.unit_normals.is_empty() {
            return plane().map_or(glam::Vec3::ZERO, |n| n.normalize_or_zero().as_vec3());
        }
        self.unit_normals
            .get(feature as usize)
            .map_or(glam::Vec3::ZERO, |&n| glam::Vec3::from_array(n))
    }

    /// The rows of the leaf of `count` triangles from leaf position `first` (see [`leaf_rows`]).
    #[inline(always)]
    pub(super) fn leaf(&self, first: u32, count: u32) -> LeafRows<'_> {
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
    pub(super) fn prefetch_leaf(&self, first: u32, count: u32) {
        let start = self.leaf_corners.as_ptr().wrapping_add(9 * first as usize).cast::<u8>();
        let end = start.wrapping_add(36 * count as usize - 1);
        let mut line = start.wrapping_sub(start as usize & 63);
        while line <= end {
            prefetch(line);
            line = line.wrapping_add(64);
        }
    }
}
