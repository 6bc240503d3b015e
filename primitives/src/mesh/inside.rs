//! Inside / outside of a mesh ([`Implicit::contains`](crate::Implicit::contains) by a
//! [`SignMethod`]): the winding numbers of `winding.rs`, the angle-weighted pseudo-normal of
//! the nearest feature, and ray parity.
//!
//! # Pseudo-normal
//! Bærentzen and Aanæs (2005): with `q` the surface point nearest to `p` and `n` the
//! angle-weighted pseudo-normal of the feature `q` lies on, `p` is inside when `(p − q)·n < 0`.
//! The feature is read from `q`'s barycentrics in its triangle ([`Feature::of`]): all three
//! above a tolerance, the face (its normal); one at zero, the edge opposite that corner (the
//! sum of the unit normals of the faces sharing it); two at zero, the corner (the sum over the
//! faces around it of the unit normal times the face's angle there). Faces share an edge or a
//! corner when their corners are at the same position (not only the same index), so meshes
//! saved as separate triangles work as welded ones. The pseudo-normals are made once per mesh
//! ([`PseudoNormals`]). Right for closed, consistently oriented, manifold meshes; a wholly
//! flipped mesh is answered the other way round, and open meshes and duplicated faces mislead
//! it.
//!
//! The nearest point is found by a depth-first walk of the 4-wide hierarchy nearer box first,
//! pruned by the squared distance to each box, with no allocation (a stack on the call's frame).
//!
//! # Parity
//! A ray from `p` in the fixed direction [`DIRECTIONS`]`[0]` walks the 8-wide nodes once,
//! visiting every leaf it enters (no closest-hit culling) and counting the triangles the
//! watertight test hits at `t ≥ 0`: odd is inside. The test is watertight (a ray through a shared
//! edge or vertex hits at least one of the triangles there, and the f32 edge functions of a
//! shared edge are exact negatives of each other), and a hit that could still be counted twice
//! or not at all is avoided by re-casting: a hit whose barycentrics are within [`BARY_TOL`] of an
//! edge, an edge function of exactly zero, or a ray within [`GRAZING`] of a hit face's plane
//! abandons the ray, and the next direction is tried (the walk stops at once). After
//! [`DIRECTIONS`]`.len()` abandoned rays (a point on an edge of the surface) the fast winding
//! number decides. A point outside the mesh's box is outside. Points within the f32 rounding of
//! the surface (the ray starts from `p` rounded to f32) may go either way.

use super::query::MeshQuery;
use super::rows::LeafRows;
use super::storage::{v64, Mesh};
use super::watertight::watertight_lanes;
use crate::bvh::lanes::lanes_of;
use crate::bvh::walk::{LeafTest, QUAD_STACK};
use crate::proximity::SignMethod;
use crate::ray::{Interval, Ray};
use glam::DVec3;
use std::mem::MaybeUninit;

/// The directions parity rays are cast in, in turn (normalised when used): fixed, with no
/// component zero or a simple ratio of another, so that a ray rarely runs along a mesh's edges
/// or planes (axis-aligned and diagonal ones in particular).
pub(super) const DIRECTIONS: [[f64; 3]; 6] = [
    [0.5377, 0.8147, -0.2154],
    [-0.6917, 0.3187, 0.6311],
    [0.2913, -0.5436, 0.7874],
    [-0.4462, -0.6983, -0.5594],
    [0.8611, -0.1779, 0.4766],
    [-0.1234, 0.9312, 0.3429],
];

/// A parity ray whose hit has a barycentric below this (in f32) is abandoned.
pub(super) const BARY_TOL: f32 = 1e-5;

/// A parity ray is abandoned where `|n̂·d̂|` of a hit face is below this.
pub(super) const GRAZING: f64 = 1e-5;

/// Barycentrics below this (relative) put the nearest point on an edge or corner.
const FEATURE_TOL: f64 = 1e-12;

/// The part of a triangle a point lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Feature {
    /// The interior.
    Face,
    /// Edge `e` of the triangle `(a, b, c)`: `0` is `a b`, `1` is `b c`, `2` is `c a`.
    Edge(usize),
    /// Corner `0`, `1` or `2` (`a`, `b`, `c`).
    Vertex(usize),
}

impl Feature {
    /// The feature of the point of barycentrics `w` (`wₐ + w_b + w_c = 1`, each `≥ 0`): a
    /// barycentric below [`FEATURE_TOL`] is zero.
    pub(super) fn of(w: [f64; 3]) -> Self {
        let zero = w.map(|x| x <= FEATURE_TOL);
        match zero {
            [false, false, false] => Self::Face,
            [true, false, false] => Self::Edge(1),
            [false, true, false] => Self::Edge(2),
            [false, false, true] => Self::Edge(0),
            [false, true, true] => Self::Vertex(0),
            [true, false, true] => Self::Vertex(1),
            [true, true, false] => Self::Vertex(2),
            // not a triangle's barycentrics; the largest corner
            [true, true, true] => Self::Vertex(if w[0] >= w[1] && w[0] >= w[2] {
                0
            } else if w[1] >= w[2] {
                1
            } else {
                2
            }),
        }
    }
}

/// The barycentrics `[wₐ, w_b, w_c]` of the point of triangle `(a, b, c)` nearest to `p`:
/// `p` is projected into the Voronoi region of a corner, an edge or the face, tested in that
/// order with the dot products of `p − corner` and the two edges from `a`. A corner's region
/// gives exactly `1` there, an edge's exactly `0` at the corner opposite.
pub(super) fn nearest_barycentrics(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let (e, f) = (b - a, c - a);
    let from_a = p - a;
    let (ea, fa) = (e.dot(from_a), f.dot(from_a));
    if ea <= 0.0 && fa <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let from_b = p - b;
    let (eb, fb) = (e.dot(from_b), f.dot(from_b));
    if eb >= 0.0 && fb <= eb {
        return [0.0, 1.0, 0.0];
    }
    // the area coordinate of `c` (times the squared area): ≤ 0 beyond edge `a b`
    let wc = ea * fb - eb * fa;
    if wc <= 0.0 && ea >= 0.0 && eb <= 0.0 {
        let t = ea / (ea - eb);
        return [1.0 - t, t, 0.0];
    }
    let from_c = p - c;
    let (ec, fc) = (e.dot(from_c), f.dot(from_c));
    if fc >= 0.0 && ec <= fc {
        return [0.0, 0.0, 1.0];
    }
    let wb = ec * fa - ea * fc;
    if wb <= 0.0 && fa >= 0.0 && fc <= 0.0 {
        let t = fa / (fa - fc);
        return [1.0 - t, 0.0, t];
    }
    let wa = eb * fc - ec * fb;
    if wa <= 0.0 && (fb - eb) >= 0.0 && (ec - fc) >= 0.0 {
        let t = (fb - eb) / ((fb - eb) + (ec - fc));
        return [0.0, 1.0 - t, t];
    }
    let sum = wa + wb + wc;
    let (v, w) = (wb / sum, wc / sum);
    [1.0 - v - w, v, w]
}

/// The pseudo-normals, made once per mesh ([`Mesh::pseudo_normals`]): for each vertex the
/// angle-weighted sum of the unit normals of the faces around its position, for each triangle
/// (leaf position) and edge (`a b`, `b c`, `c a`) the sum of the unit normals of the faces
/// sharing it, in f32 (their direction is all that is read).
#[derive(Clone, Debug)]
pub(crate) struct PseudoNormals {
    vertex: Vec<[f32; 3]>,
    edge: Vec<[[f32; 3]; 3]>,
}

impl PseudoNormals {
    /// Bytes held.
    pub(super) fn memory_bytes(&self) -> usize {
        self.vertex.capacity() * 12 + self.edge.capacity() * 36
    }
}

/// The corners of the `i`-th triangle of a leaf, from its rows, in f64.
#[inline(always)]
fn leaf_corners(rows: &LeafRows<'_>, count: usize, i: usize) -> [DVec3; 3] {
    let at = |r: usize| f64::from(rows.block[r * count + i]);
    [
        DVec3::new(at(0), at(1), at(2)),
        DVec3::new(at(3), at(4), at(5)),
        DVec3::new(at(6), at(7), at(8)),
    ]
}

/// A pending child of the nearest-point walk: `(child, count, squared distance to its box)`.
type Near = (u32, u32, f64);

impl Mesh {
    /// Whether `p` is inside by `method` (see [`SignMethod`] and the module docs).
    pub(super) fn contains_by(&self, p: DVec3, method: SignMethod) -> bool {
        match method {
            SignMethod::Winding => self.winding_number(p).abs() > 0.5,
            SignMethod::FastWinding => self.fast_winding_number(p).abs() > 0.5,
            SignMethod::PseudoNormal => self.pseudo_normal_inside(p),
            SignMethod::Parity => self.parity_inside(p),
        }
    }

    /// The pseudo-normals, made the first time they are asked for.
    pub(super) fn pseudo_normals(&self) -> &PseudoNormals {
        self.pseudo_normals.get_or_init(|| self.make_pseudo_normals())
    }

    fn make_pseudo_normals(&self) -> PseudoNormals {
        let nv = self.vertices.len();
        // each vertex's first vertex at the same position (−0 as +0)
        let key = |i: u32| self.vertices[i as usize].map(|x| (x + 0.0).to_bits());
        let mut order: Vec<u32> = (0..nv as u32).collect();
        order.sort_unstable_by_key(|&i| (key(i), i));
        let mut canon = vec![0u32; nv];
        let mut start = 0;
        for (j, &i) in order.iter().enumerate() {
            if key(i) != key(order[start]) {
                start = j;
            }
            canon[i as usize] = order[start];
        }
        drop(order);
        let tris = &self.tris[..self.in_bvh];
        let unit = |k: usize| {
            let (n, _) = self.plane(k);
            n.normalize_or_zero()
        };
        let mut at_vertex = vec![DVec3::ZERO; nv];
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * tris.len());
        for (k, t) in tris.iter().enumerate() {
            let n = unit(k);
            let corners = t.map(|i| v64(self.vertices[i as usize]));
            for j in 0..3 {
                let (u, w) = (corners[(j + 1) % 3] - corners[j], corners[(j + 2) % 3] - corners[j]);
                at_vertex[canon[t[j] as usize] as usize] += u.angle_between(w) * n;
                let (x, y) = (canon[t[j] as usize], canon[t[(j + 1) % 3] as usize]);
                let key = (u64::from(x.min(y)) << 32) | u64::from(x.max(y));
                edges.push((key, (3 * k + j) as u32));
            }
        }
        edges.sort_unstable();
        let mut edge = vec![[[0.0f32; 3]; 3]; tris.len()];
        for run in edges.chunk_by(|a, b| a.0 == b.0) {
            let sum: DVec3 = run.iter().map(|&(_, e)| unit(e as usize / 3)).sum();
            for &(_, e) in run {
                edge[e as usize / 3][e as usize % 3] = sum.as_vec3().to_array();
            }
        }
        let vertex = (0..nv)
            .map(|i| at_vertex[canon[i] as usize].as_vec3().to_array())
            .collect();
        PseudoNormals { vertex, edge }
    }

    /// The surface point nearest to `p`: `(q, leaf position of its triangle, q's barycentrics
    /// there)`, by a depth-first walk of the 4-wide hierarchy (see the module docs). Of
    /// triangles equally near, the first met.
    pub(super) fn nearest_feature(&self, p: DVec3) -> (DVec3, usize, [f64; 3]) {
        let quads = self.bvh.quads();
        let mut best_d2 = f64::INFINITY;
        let mut best = (p, 0usize, [1.0, 0.0, 0.0]);
        // uninitialised: only entries below `top`, written before, are ever read
        let mut stack = [const { MaybeUninit::<Near>::uninit() }; QUAD_STACK];
        let mut top = 0usize;
        let mut q = 0usize;
        loop {
            let quad = &quads[q];
            let mut near = [(0u32, 0u32, f64::INFINITY); 4];
            let mut len = 0;
            for s in 0..quad.len as usize {
                let (lo, hi) = quad.slot_bounds(s);
                let d = (v64(lo) - p).max(p - v64(hi)).max(DVec3::ZERO);
                let d2 = d.length_squared();
                if d2 <= best_d2 {
                    near[len] = (quad.child[s], u32::from(quad.count[s]), d2);
                    len += 1;
                }
            }
            // farthest pushed first, so the nearest is popped next
            near[..len].sort_unstable_by(|a, b| b.2.total_cmp(&a.2));
            for &item in &near[..len] {
                stack[top].write(item);
                top += 1;
            }
            let next = loop {
                if top == 0 {
                    return best;
                }
                top -= 1;
                // SAFETY: `stack[top]` was written by the push that raised `top` above it
                let (child, count, d2) = unsafe { stack[top].assume_init() };
                if d2 > best_d2 {
                    continue;
                }
                if count == 0 {
                    break child as usize;
                }
                let rows = self.leaf(child, count);
                for i in 0..count as usize {
                    let [a, b, c] = leaf_corners(&rows, count as usize, i);
                    let w = nearest_barycentrics(p, a, b, c);
                    let x = w[0] * a + w[1] * b + w[2] * c;
                    let d2 = (p - x).length_squared();
                    if d2 < best_d2 {
                        best_d2 = d2;
                        best = (x, child as usize + i, w);
                    }
                }
            };
            q = next;
        }
    }

    /// Inside by the angle-weighted pseudo-normal of the nearest feature (see the module docs).
    fn pseudo_normal_inside(&self, p: DVec3) -> bool {
        let normals = self.pseudo_normals();
        let (q, k, w) = self.nearest_feature(p);
        let n = match Feature::of(w) {
            Feature::Face => self.plane(k).0,
            Feature::Edge(e) => v64(normals.edge[k][e]),
            Feature::Vertex(v) => v64(normals.vertex[self.tris[k][v] as usize]),
        };
        (p - q).dot(n) < 0.0
    }

    /// Inside by ray parity (see the module docs).
    fn parity_inside(&self, p: DVec3) -> bool {
        if !self.bounds.contains(p) {
            return false;
        }
        for dir in DIRECTIONS {
            let ray = Ray::new(p, DVec3::from_array(dir).normalize());
            let count = crate::with_fma!(count_crossings(mesh: &Mesh = self, ray: &Ray = &ray) -> Option<u32>);
            if let Some(count) = count {
                return count % 2 == 1;
            }
        }
        self.fast_winding_number(p).abs() > 0.5
    }

    /// The walk of [`count_crossings`] for a ray whose axes are `[KX, KY, KZ]`.
    #[inline(always)]
    fn crossings_walk<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ray: &Ray,
        query: &MeshQuery,
        root: (u32, [f32; 8]),
    ) -> Option<u32> {
        let mut leaves = CountLeaves::<KX, KY, KZ> {
            mesh: self,
            query,
            dir: ray.dir,
            count: 0,
            abandoned: false,
        };
        self.octs()
            .traverse(&query.ray.slab, query.t_min, query.t_max, root, &mut leaves);
        (!leaves.abandoned).then_some(leaves.count)
    }
}

/// The triangles `ray` (unit direction) hits at `t ≥ 0`, or `None` where a hit was too near an
/// edge or the ray too near a hit face's plane (see the module docs).
#[inline(always)]
fn count_crossings(mesh: &Mesh, ray: &Ray) -> Option<u32> {
    let range = Interval::new(0.0, f64::INFINITY);
    let Some((entry, root)) = mesh.walk_start(ray, range) else {
        return Some(0);
    };
    let query = entry.query();
    by_axes!(query.ray.k, mesh.crossings_walk(ray, &query, root))
}

/// The parity walk's leaf test: every triangle the ray hits counted, none culled.
struct CountLeaves<'a, const KX: usize, const KY: usize, const KZ: usize> {
    mesh: &'a Mesh,
    query: &'a MeshQuery,
    dir: DVec3,
    count: u32,
    abandoned: bool,
}

impl<const KX: usize, const KY: usize, const KZ: usize> LeafTest for &mut CountLeaves<'_, KX, KY, KZ> {
    /// Counts the leaf's hits; returns `−∞` as the new `t_max` to end the walk at once where the
    /// ray is abandoned, and otherwise nothing (so no leaf is culled).
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, _t_max: f32) -> Option<f32> {
        let leaf = self.mesh.leaf(first, count);
        let ray = &self.query.ray;
        let lanes = watertight_lanes(
            &leaf.all_corner_rows([KX, KY, KZ]),
            &ray.origin_k,
            &ray.shear,
            self.query.t_min,
            self.query.t_max,
        );
        let mask = (1u32 << count) - 1;
        if lanes.zero & mask != 0 {
            self.abandoned = true;
            return Some(f32::NEG_INFINITY);
        }
        for i in lanes_of(lanes.pass & mask) {
            let det = lanes.det[i];
            let (e1, e2) = (lanes.e1[i], lanes.e2[i]);
            let e0 = det - e1 - e2;
            let tol = BARY_TOL * det.abs();
            let (n, _) = leaf.plane(i);
            let grazing = n.dot(self.dir).abs() < GRAZING * n.length();
            if e0.abs().min(e1.abs()).min(e2.abs()) < tol || grazing {
                self.abandoned = true;
                return Some(f32::NEG_INFINITY);
            }
            self.count += 1;
        }
        None
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.mesh.prefetch_leaf(first, count);
    }
}
