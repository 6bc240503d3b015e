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
use super::storage::{v64, Mesh};
use super::watertight::watertight_lanes;
use crate::bvh::lanes::lanes_of;
use crate::bvh::walk::LeafTest;
use crate::proximity::SignMethod;
use crate::ray::{Interval, Ray};
use glam::DVec3;

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

impl Mesh {
    /// Whether `p` is inside by `method` (see [`SignMethod`] and the module docs).
    pub(super) fn contains_by(&self, p: DVec3, method: SignMethod) -> bool {
        if !self.surface {
            return false;
        }
        // a closed mesh's grid decides most points by their cell (`regions.rs`)
        if method != SignMethod::PseudoNormal {
            if let Some(w) = self.regions().and_then(|r| r.winding(p)) {
                return if method == SignMethod::Parity {
                    w % 2 != 0
                } else {
                    w != 0
                };
            }
        }
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
        let canon = super::regions::welded(&self.vertices);
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

    /// Inside by the angle-weighted pseudo-normal of the nearest feature (see the module docs).
    fn pseudo_normal_inside(&self, p: DVec3) -> bool {
        let normals = self.pseudo_normals();
        let found = self.nearest_feature(p);
        let (q, k, w) = (found.point, found.k, found.barycentrics);
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
