//! Generalized winding numbers of a mesh: the exact sum ([`Mesh::winding_number`]) and the
//! hierarchical approximation ([`Mesh::fast_winding_number`]) over the mesh's own 4-wide
//! hierarchy.
//!
//! # The exact sum
//! The generalized winding number (Jacobson, Kavan and Sorkine-Hornung 2013) of a point `p` is
//! `w(p) = Σ Ωᵢ(p) / 4π`, `Ωᵢ` the signed solid angle of triangle `i` seen from `p`. With
//! `a, b, c` the corners minus `p` (Van Oosterom and Strackee 1983):
//!
//! `tan(Ω/2) = a·(b × c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|)`,
//!
//! `Ω/2 = atan2(det, den)` in `(−π, π)`, positive when `p` lies behind the triangle (on the side
//! its normal `(b − a) × (c − a)` points away from), so `w = 1` inside a closed mesh wound
//! counter-clockwise seen from outside, `0` outside, `−1` inside a wholly flipped one.
//!
//! The sum of the half angles is not taken with an `atan2` per triangle: each triangle's
//! `(den, det)`, normalised, is a unit complex number `e^{iΩ/2}`, and the sum of their
//! arguments is the argument of their product plus `2π` times the turns the product made
//! around the origin ([`Turns`]: a turn is counted each time the running product crosses the
//! negative real axis, its direction read from the product's own cross product with the step,
//! so the count agrees with the computed values). One `atan2` per query, square roots and a
//! division per triangle computed eight lanes at once: about five times faster than an `atan2`
//! each, to the same f64 accuracy (the product's rounding adds `~ n·2⁻⁵³` radians for `n`
//! triangles). A point on a triangle (`Ω = ±2π`, a half turn) has no defined winding number.
//!
//! # The fast approximation
//! Barill, Dickson, Schmidt, Levin and Jacobson (2018): a cluster of triangles far from `p`
//! contributes about the Taylor expansion of its integral `Ω = ∫ n·(x − p)/|x − p|³ dA` about
//! its area-weighted centroid `c = Σ Aᵢcᵢ / Σ Aᵢ`: the dipole term `N·(c − p)/|c − p|³`
//! (`N = Σ Aᵢnᵢ`, half the cross products summed) and the first- and second-order terms, which
//! read the cluster's first and second moments of `n` about `c` ([`expansion`]; the first-order
//! expansion alone was off by up to `5·10⁻²` at `β = 2` on a sphere, its large clusters being
//! curved). For every slot of every node of the hierarchy (its whole subtree's triangles)
//! [`WindingNodes`] keeps `c`, `N`, the moments and `(β·r)²`, `r` the radius of a ball about `c`
//! holding the subtree (`β = 2`). The walk from the root takes a slot's expansion when
//! `|c − p| > β·r`, and otherwise descends (an inner slot) or sums the leaf's triangles exactly.
//! The four slots of a node are expanded at once in f32; the exact leaves in f64 as above.
//!
//! Error against the exact sum (measured, `tests/mesh_signs.rs`, random points in and around
//! the box of icospheres of 5,120 and 81,920 triangles and of a sphere with a cap cut away, half
//! of them within 5% of the radius of the surface): at most `2.6·10⁻³`, mean `5`–`8·10⁻⁴`. So
//! a point is misjudged only where `|w − ½| < 3·10⁻³`, for a closed mesh within a small fraction
//! of a triangle of the surface.

use super::rows::LeafRows;
use super::storage::{v64, Mesh};
use crate::bvh::rounding::round_up;
use crate::bvh::walk::QUAD_STACK;
use glam::DVec3;
use std::f64::consts::{PI, TAU};
use std::mem::MaybeUninit;

/// The ratio `β` of a cluster's distance to its radius beyond which its expansion stands for
/// it ([`Mesh::fast_winding_number`]).
pub(super) const BETA: f64 = 2.0;

/// A sum of angles in `(−π, π)` each, kept as the product of the unit complex numbers
/// `e^{iθ}` and the number of times the running product crossed the negative real axis (see
/// the module docs).
#[derive(Clone, Copy, Debug)]
pub(super) struct Turns {
    x: f64,
    y: f64,
    turns: f64,
}

impl Turns {
    /// The empty sum.
    pub(super) const ZERO: Self = Self {
        x: 1.0,
        y: 0.0,
        turns: 0.0,
    };

    /// Adds the angle of the unit complex number `(c, s)` (`θ = atan2(s, c)`, `|θ| < π`).
    ///
    /// The product's argument is taken in `(−π, π]` (`y ≥ 0` is the upper half, `−0` included,
    /// as [`Turns::angle`] reads it). A step that takes the product from the upper half to the
    /// lower turning counter-clockwise (`x·y′ − x′·y > 0`) crossed the negative real axis (one
    /// turn more); from the lower to the upper turning clockwise, one turn less; any other sign
    /// change crossed the positive axis. Where the product lies near the negative axis both
    /// `x` are negative and the cross product has no cancellation, so its sign is exact.
    #[inline(always)]
    pub(super) fn add(&mut self, c: f64, s: f64) {
        let x = self.x * c - self.y * s;
        let y = self.x * s + self.y * c;
        let cross = self.x * y - x * self.y;
        let (was_upper, upper) = (self.y >= 0.0, y >= 0.0);
        let up = was_upper & !upper & (cross > 0.0);
        let down = !was_upper & upper & (cross < 0.0);
        self.turns += f64::from(u8::from(up)) - f64::from(u8::from(down));
        self.x = x;
        self.y = y;
    }

    /// The sum of the angles added.
    #[inline(always)]
    pub(super) fn angle(&self) -> f64 {
        // `+ 0.0` turns `−0` into `+0`: the upper half, as `add` counts it
        (self.y + 0.0).atan2(self.x) + TAU * self.turns
    }
}

/// Adds to `sum` the half solid angles `Ωᵢ/2` of the first `count` triangles of a leaf (its
/// rows `rows`) seen from `p` (see the module docs): the factors `e^{iΩᵢ/2}` eight lanes at
/// once, then multiplied in one after another.
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays by the lane; the form the compiler vectorises"
)]
pub(super) fn add_half_angles(rows: &LeafRows<'_>, count: usize, p: DVec3, sum: &mut Turns) {
    // no `map` with a closure: closures are not inlined into the AVX2 copies
    let r = [
        rows.row(0),
        rows.row(1),
        rows.row(2),
        rows.row(3),
        rows.row(4),
        rows.row(5),
        rows.row(6),
        rows.row(7),
        rows.row(8),
    ];
    let (mut cs, mut sn) = ([0.0f64; 8], [0.0f64; 8]);
    for l in 0..8 {
        let ax = f64::from(r[0][l]) - p.x;
        let ay = f64::from(r[1][l]) - p.y;
        let az = f64::from(r[2][l]) - p.z;
        let bx = f64::from(r[3][l]) - p.x;
        let by = f64::from(r[4][l]) - p.y;
        let bz = f64::from(r[5][l]) - p.z;
        let cx = f64::from(r[6][l]) - p.x;
        let cy = f64::from(r[7][l]) - p.y;
        let cz = f64::from(r[8][l]) - p.z;
        let la = (ax * ax + ay * ay + az * az).sqrt();
        let lb = (bx * bx + by * by + bz * bz).sqrt();
        let lc = (cx * cx + cy * cy + cz * cz).sqrt();
        let det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
        let den = la * lb * lc
            + (ax * bx + ay * by + az * bz) * lc
            + (bx * cx + by * cy + bz * cz) * la
            + (cx * ax + cy * ay + cz * az) * lb;
        let h = (den * den + det * det).sqrt();
        let inv = 1.0 / h;
        // a zero factor (`p` at a corner) adds nothing
        let some = h > 0.0 && inv < f64::INFINITY;
        cs[l] = if some { den * inv } else { 1.0 };
        sn[l] = if some { det * inv } else { 0.0 };
    }
    for l in 0..count.min(8) {
        sum.add(cs[l], sn[l]);
    }
}

/// What the fast winding number keeps for the four slots of one node of the hierarchy, lane
/// `s` for slot `s` (see the module docs): the centroid `c` (rows 0–2), the area-weighted
/// normal sum `N` (rows 3–5), `(β·r)²` (row 6) and the expansion's coefficients about `c`
/// (rows 7–22, [`Moments::coefficients`]), in f32. `r` allows for the rounding of `c`
/// to f32 and `(β·r)²` is rounded up, so `|c − p| > β·r` in f32 still means `p` is farther
/// than `β` radii from the centroid kept.
type WindingQuad = [[f32; 4]; 23];

/// The fast winding number's data, made once per mesh ([`Mesh::winding_nodes`]).
#[derive(Clone, Debug)]
pub(crate) struct WindingNodes {
    /// Indexed like the hierarchy's quads (the unused room between parallel subtrees stays
    /// zero and is never read; zero pages the allocator hands out are not touched).
    quads: Vec<WindingQuad>,
    /// The whole mesh's centroid, normal sum, `(β·r)²` and first moment's symmetric part, in
    /// f64: a point beyond is answered by one expansion ([`expansion`]).
    root: (DVec3, DVec3, f64, [f64; 16]),
}

impl WindingNodes {
    /// Bytes held.
    pub(super) fn memory_bytes(&self) -> usize {
        self.quads.capacity() * std::mem::size_of::<WindingQuad>()
    }
}

/// A cluster's moments while the nodes are made: area `Σ Aᵢ`, normal sum `N = Σ Aᵢnᵢ`,
/// `Σ Aᵢcᵢ`, and once its centroid `c` is known, about `c`: the first moment
/// `M[k][j] = ∫ nₖ δⱼ dA` and the second `T[k][j][l] = ∫ nₖ δⱼ δₗ dA` (`δ = x − c`; exact for
/// triangles: `∫ δ dA = A·(centroid − c)` and `∫ δ δᵀ dA = A/12·(Σ δᵢδᵢᵀ + s sᵀ)`, `δᵢ` the
/// corners' and `s` their sum), and the radius of a ball about `c` holding the cluster.
#[derive(Clone, Copy, Default)]
struct Moments {
    area: f64,
    normal: DVec3,
    first: DVec3,
    centroid: DVec3,
    moment: [DVec3; 3],
    second: [[DVec3; 3]; 3],
    radius: f64,
}

impl Moments {
    /// `M` and `T` about `point` rather than the centroid: with `e = c − point`,
    /// `M′[k][j] = M[k][j] + Nₖeⱼ`, `T′[k][j][l] = T[k][j][l] + M[k][j]eₗ + M[k][l]eⱼ + Nₖeⱼeₗ`.
    fn about(&self, point: DVec3) -> ([DVec3; 3], [[DVec3; 3]; 3]) {
        let e = self.centroid - point;
        let (mut m, mut t) = (self.moment, self.second);
        for k in 0..3 {
            m[k] += self.normal[k] * e;
            for j in 0..3 {
                t[k][j] += self.moment[k][j] * e + e[j] * self.moment[k] + self.normal[k] * e[j] * e;
            }
        }
        (m, t)
    }

    /// The expansion's coefficients about `point` ([`expansion`]): the symmetric part of `M`
    /// (`xx, yy, zz, xy, xz, yz`) and the fully symmetric part of `T` (`xxx, yyy, zzz, xxy, xxz,
    /// xyy, yyz, xzz, yzz, xyz`).
    fn coefficients(&self, point: DVec3) -> [f64; 16] {
        let (m, t) = self.about(point);
        // the mean of `T` over the permutations of its indices
        let sym3 = |i: usize, j: usize, k: usize| {
            (t[i][j][k] + t[i][k][j] + t[j][i][k] + t[j][k][i] + t[k][i][j] + t[k][j][i]) / 6.0
        };
        [
            m[0].x,
            m[1].y,
            m[2].z,
            0.5 * (m[0].y + m[1].x),
            0.5 * (m[0].z + m[2].x),
            0.5 * (m[1].z + m[2].y),
            sym3(0, 0, 0),
            sym3(1, 1, 1),
            sym3(2, 2, 2),
            sym3(0, 0, 1),
            sym3(0, 0, 2),
            sym3(0, 1, 1),
            sym3(1, 1, 2),
            sym3(0, 2, 2),
            sym3(1, 2, 2),
            sym3(0, 1, 2),
        ]
    }
}

impl Mesh {
    /// The fast winding number's node data, made the first time it is asked for (linear in the
    /// triangles; concurrent first callers wait for the one that makes it).
    pub(super) fn winding_nodes(&self) -> &WindingNodes {
        self.winding_nodes.get_or_init(|| self.make_winding_nodes())
    }

    fn make_winding_nodes(&self) -> WindingNodes {
        let quads = self.bvh.quads();
        let mut data: Vec<WindingQuad> = vec![[[0.0; 4]; 23]; quads.len()];
        let root = if quads.is_empty() {
            self.leaf_moments(self.bvh.root.first as usize, self.bvh.root.count as usize)
        } else {
            self.quad_moments(0, &mut data)
        };
        WindingNodes {
            quads: data,
            root: (
                root.centroid,
                root.normal,
                (BETA * root.radius).powi(2) * (1.0 + 1e-12),
                root.coefficients(root.centroid),
            ),
        }
    }

    /// The moments of the `count` triangles from leaf position `first`, radius included (the
    /// farthest corner from the centroid).
    fn leaf_moments(&self, first: usize, count: usize) -> Moments {
        let mut m = Moments::default();
        for k in first..first + count {
            let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
            let n = 0.5 * (b - a).cross(c - a);
            let area = n.length();
            m.area += area;
            m.normal += n;
            m.first += area * (a + b + c) / 3.0;
        }
        m.centroid = m.first / m.area;
        for k in first..first + count {
            let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
            let n = 0.5 * (b - a).cross(c - a);
            let d = [a - m.centroid, b - m.centroid, c - m.centroid];
            let sum = d[0] + d[1] + d[2];
            for j in 0..3 {
                let q = (d[0][j] * d[0] + d[1][j] * d[1] + d[2][j] * d[2] + sum[j] * sum) / 12.0;
                for k in 0..3 {
                    m.moment[k][j] += n[k] * sum[j] / 3.0;
                    m.second[k][j] += n[k] * q;
                }
            }
            for x in d {
                m.radius = m.radius.max(x.length());
            }
        }
        m
    }

    /// The moments of node `q`'s slots, written into `data[q]` (and its subtree's), and of the
    /// whole node returned. An inner slot's radius is the smaller of two bounds: its children's
    /// balls about its centroid, and the farthest corner of its box.
    fn quad_moments(&self, q: usize, data: &mut [WindingQuad]) -> Moments {
        let quad = self.bvh.quads()[q];
        let mut slots = [Moments::default(); 4];
        for (s, slot) in slots.iter_mut().enumerate().take(quad.len as usize) {
            *slot = if quad.count[s] > 0 {
                self.leaf_moments(quad.child[s] as usize, usize::from(quad.count[s]))
            } else {
                self.quad_moments(quad.child[s] as usize, data)
            };
            let (lo, hi) = quad.slot_bounds(s);
            let far = (slot.centroid - v64(lo)).abs().max((v64(hi) - slot.centroid).abs());
            slot.radius = slot.radius.min(far.length());
            let c = slot.centroid.as_vec3();
            let radius = slot.radius + (c.as_dvec3() - slot.centroid).length();
            // the moments about the centroid kept (rounded to f32)
            let coefficients = slot.coefficients(c.as_dvec3());
            for axis in 0..3 {
                data[q][axis][s] = c[axis];
                data[q][3 + axis][s] = slot.normal[axis] as f32;
            }
            data[q][6][s] = round_up((BETA * radius).powi(2) * (1.0 + 1e-6));
            for (row, x) in coefficients.into_iter().enumerate() {
                data[q][7 + row][s] = x as f32;
            }
        }
        let mut all = Moments::default();
        for slot in &slots[..quad.len as usize] {
            all.area += slot.area;
            all.normal += slot.normal;
            all.first += slot.first;
        }
        all.centroid = all.first / all.area;
        for slot in &slots[..quad.len as usize] {
            let (m, t) = slot.about(all.centroid);
            for ((moment, second), (m, t)) in all.moment.iter_mut().zip(&mut all.second).zip(m.iter().zip(&t)) {
                *moment += *m;
                for (row, t) in second.iter_mut().zip(t) {
                    *row += *t;
                }
            }
            all.radius = all.radius.max((slot.centroid - all.centroid).length() + slot.radius);
        }
        let (lo, hi) = quad.box_of_slots();
        let far = (all.centroid - v64(lo)).abs().max((v64(hi) - all.centroid).abs());
        all.radius = all.radius.min(far.length());
        all
    }

    /// The generalized winding number of `p`, exactly (to f64 rounding): the sum of the signed
    /// solid angles of the triangles seen from `p` over 4π (see `mesh/winding.rs`). `1` inside a
    /// closed mesh wound counter-clockwise seen from outside, `0` outside, `−1` inside a wholly
    /// flipped one; a fraction near holes and for open meshes. Costs every triangle (about
    /// 10 ns each); [`Mesh::fast_winding_number`] is the hierarchical approximation.
    #[must_use]
    pub fn winding_number(&self, p: DVec3) -> f64 {
        if !self.surface {
            return 0.0;
        }
        crate::with_fma!(exact_winding(mesh: &Mesh = self, p: DVec3 = p) -> f64)
    }

    /// The generalized winding number of `p` by the hierarchy's multipole expansion (Barill et al.
    /// 2018, `β = 2`, to second order, exact sums for the leaves near `p`; see `mesh/winding.rs`).
    /// Measured against [`Mesh::winding_number`] at random points in and around the mesh's box
    /// (icospheres of 5k and 80k triangles, an open one): an error of at most `2.6·10⁻³`, mean
    /// `5`–`8·10⁻⁴`. [`SignMethod::FastWinding`](crate::SignMethod::FastWinding) calls a point inside
    /// where `|w| > ½`.
    #[must_use]
    pub fn fast_winding_number(&self, p: DVec3) -> f64 {
        if !self.surface {
            return 0.0;
        }
        let nodes = self.winding_nodes();
        crate::with_fma!(fast_winding(mesh: &Mesh = self, nodes: &WindingNodes = nodes, p: DVec3 = p) -> f64)
    }
}

/// A cluster's solid angle seen from `p` to second order about its centroid `c` (`d = c − p`,
/// normal sum `n`, coefficients `k` as [`Moments::coefficients`] gives them): with
/// `K(y) = y/|y|³ = −∇(1/|y|)` expanded about `d`,
/// `Ω ≈ n·K(d) + J(d) : M + ½ H(d) ⋮ T`, `J = I/r³ − 3 d dᵀ/r⁵`,
/// `Hₖⱼₗ = 15 dₖdⱼdₗ/r⁷ − 3(δₖⱼdₗ + δₖₗdⱼ + δⱼₗdₖ)/r⁵` (`r = |d|`), so
/// `Ω ≈ (n·d + tr S)/r³ − 3 dᵀS d/r⁵ + 15 C(d)/(2r⁷) − 9 t·d/(2r⁵)`, `S` the symmetric part of
/// `M`, `C(d) = Σ T̃ₖⱼₗ dₖdⱼdₗ` and `tₗ = Σₖ T̃ₖₖₗ` of `T`'s fully symmetric part `T̃`.
#[inline(always)]
fn expansion(d: DVec3, n: DVec3, k: [f64; 16]) -> f64 {
    let (x, y, z) = (d.x, d.y, d.z);
    let r2 = d.length_squared();
    let inv3 = 1.0 / (r2 * r2.sqrt());
    let inv5 = inv3 / r2;
    let quadratic = x * x * k[0] + y * y * k[1] + z * z * k[2] + 2.0 * (x * y * k[3] + x * z * k[4] + y * z * k[5]);
    let cubic = x * x * x * k[6]
        + y * y * y * k[7]
        + z * z * z * k[8]
        + 3.0
            * (x * x * y * k[9]
                + x * x * z * k[10]
                + x * y * y * k[11]
                + y * y * z * k[12]
                + x * z * z * k[13]
                + y * z * z * k[14])
        + 6.0 * x * y * z * k[15];
    let t = x * (k[6] + k[11] + k[13]) + y * (k[9] + k[7] + k[14]) + z * (k[10] + k[12] + k[8]);
    (n.dot(d) + k[0] + k[1] + k[2]) * inv3 - 3.0 * quadratic * inv5 + (7.5 * cubic / r2 - 4.5 * t) * inv5
}

/// [`Mesh::winding_number`]: every leaf of the hierarchy, in leaf order.
#[inline(always)]
fn exact_winding(mesh: &Mesh, p: DVec3) -> f64 {
    let mut sum = Turns::ZERO;
    let mut k = 0;
    while k < mesh.in_bvh {
        let count = usize::from(mesh.leaf_places[k] >> 3);
        add_half_angles(&mesh.leaf(k as u32, count as u32), count, p, &mut sum);
        k += count.max(1);
    }
    sum.angle() / TAU
}

/// [`Mesh::fast_winding_number`] (see the module docs).
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays by the lane; the form the compiler vectorises"
)]
fn fast_winding(mesh: &Mesh, nodes: &WindingNodes, p: DVec3) -> f64 {
    let (c, n, far2, sym) = nodes.root;
    let d = c - p;
    if d.length_squared() > far2 {
        return expansion(d, n, sym) / (4.0 * PI);
    }
    let quads = mesh.bvh.quads();
    let mut exact = Turns::ZERO;
    if quads.is_empty() {
        let root = &mesh.bvh.root;
        add_half_angles(&mesh.leaf(root.first, root.count), root.count as usize, p, &mut exact);
        return exact.angle() / TAU;
    }
    let pf = p.as_vec3().to_array();
    let mut far_sum = 0.0f64;
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<u32>::uninit() }; QUAD_STACK];
    let mut top = 0usize;
    let mut q = 0usize;
    loop {
        let quad = &quads[q];
        let data = &nodes.quads[q];
        let mut terms = [0.0f32; 4];
        let mut far = [false; 4];
        for s in 0..4 {
            let dx = data[0][s] - pf[0];
            let dy = data[1][s] - pf[1];
            let dz = data[2][s] - pf[2];
            let d2 = dx * dx + dy * dy + dz * dz;
            far[s] = d2 > data[6][s];
            let dot = dx * data[3][s] + dy * data[4][s] + dz * data[5][s];
            let k = |i: usize| data[7 + i][s];
            let inv3 = 1.0 / (d2 * d2.sqrt());
            let inv5 = inv3 / d2;
            let quadratic = dx * dx * k(0)
                + dy * dy * k(1)
                + dz * dz * k(2)
                + 2.0 * (dx * dy * k(3) + dx * dz * k(4) + dy * dz * k(5));
            let cubic = dx * dx * dx * k(6)
                + dy * dy * dy * k(7)
                + dz * dz * dz * k(8)
                + 3.0
                    * (dx * dx * dy * k(9)
                        + dx * dx * dz * k(10)
                        + dx * dy * dy * k(11)
                        + dy * dy * dz * k(12)
                        + dx * dz * dz * k(13)
                        + dy * dz * dz * k(14))
                + 6.0 * dx * dy * dz * k(15);
            let t = dx * (k(6) + k(11) + k(13)) + dy * (k(9) + k(7) + k(14)) + dz * (k(10) + k(12) + k(8));
            let term = (dot + k(0) + k(1) + k(2)) * inv3 - 3.0 * quadratic * inv5 + (7.5 * cubic / d2 - 4.5 * t) * inv5;
            terms[s] = if far[s] { term } else { 0.0 };
        }
        far_sum += f64::from((terms[0] + terms[1]) + (terms[2] + terms[3]));
        for s in 0..quad.len as usize {
            if far[s] {
                continue;
            }
            let count = u32::from(quad.count[s]);
            if count > 0 {
                add_half_angles(&mesh.leaf(quad.child[s], count), count as usize, p, &mut exact);
            } else {
                stack[top].write(quad.child[s]);
                top += 1;
            }
        }
        if top == 0 {
            break;
        }
        top -= 1;
        // SAFETY: `stack[top]` was written by the push that raised `top` above it
        q = unsafe { stack[top].assume_init() } as usize;
    }
    far_sum / (4.0 * PI) + exact.angle() / TAU
}
