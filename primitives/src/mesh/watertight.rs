//! The watertight ray/triangle test of Woop, Benthin and Wald (2013, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1)), in f32: the ray's set-up ([`MeshRay`]: the axis `k_z`
//! of the largest direction component, the other two ordered to keep the winding, the shear
//! constants `(d_kx/d_kz, d_ky/d_kz, 1/d_kz)`), the single test ([`MeshRay::permuted_triangle`],
//! which recomputes edge functions that come out exactly zero in f64, so that a ray through a
//! shared edge or vertex hits at least one of the triangles sharing it) and the same test eight
//! lanes at once ([`watertight_lanes`]: one ray against a leaf's triangles, or a packet's rays
//! against one triangle), bit for bit the single test's f32 arithmetic.
//!
//! The edge functions `e0, e1, e2` are the scaled barycentrics; a hit has them all of one sign
//! and a non-zero sum `det`, then `t = (e0·z_a + e1·z_b + e2·z_c)·s_z / det` and
//! `(u, v) = (e1, e2) / det`.

use crate::bvh::lanes::lane_mask;
use crate::bvh::slab::SlabRay;
use crate::PACKET;
use glam::Vec3A;

/// One f32 per SIMD lane.
pub(super) type Lanes = [f32; PACKET];

/// An operand of the lane kernels ([`watertight_lanes`]): a value per lane ([`Lanes`]) or one
/// value shared by every lane (`f32`), which the compiler broadcasts once rather than reading
/// eight equal lanes from memory.
pub(super) trait PerLane: Copy {
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
pub(super) struct WatertightLanes {
    /// `t` along the (scaled) ray.
    pub(super) t: Lanes,
    /// The second and third scaled barycentrics and their sum with the first.
    pub(super) e1: Lanes,
    pub(super) e2: Lanes,
    pub(super) det: Lanes,
    /// Lanes with an edge function of exactly zero: their answer is the single test's
    /// ([`MeshRay::permuted_triangle`], which recomputes those in f64), not the lane's.
    pub(super) zero: u32,
    /// Lanes whose triangle is hit at a `t` in their range (meaningless where `zero`).
    pub(super) pass: u32,
}

impl WatertightLanes {
    /// Lane `l`'s hit `(t, u, v)`, as the single test gives it (for a lane in `pass`, not in
    /// `zero`).
    #[inline(always)]
    pub(super) fn hit(&self, l: usize) -> (f32, f32, f32) {
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
pub(super) fn watertight_lanes<C: PerLane, R: PerLane>(
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
pub(super) struct MeshRay {
    pub(super) slab: SlabRay,
    pub(super) origin: [f32; 3],
    pub(super) k: [usize; 3],
    /// `origin` in the order `k` ([`permuted`]), made once for the ray by selects: the leaf
    /// tests of the interleaved walks (whose axes are not constants) took `permuted`'s branch
    /// on the order, mispredicted about 1.7 times a ray.
    pub(super) origin_k: [f32; 3],
    pub(super) shear: [f32; 3],
}

impl MeshRay {
    /// The ray of `origin` and `dir` (`dir` finite, its largest component of magnitude in
    /// `[2⁻⁵³, 8)`, see [`direction_scale`]) whose slab test `slab` is already made (the root is
    /// tested before the rest is set up, see [`Mesh::entry`]).
    ///
    /// Written without branches on the direction (selects and array reads rather than
    /// `Vec3A::max_position` and indexing, which branch): random rays would mispredict them.
    #[inline(always)]
    pub(super) fn with_slab(slab: SlabRay, origin: Vec3A, dir: Vec3A) -> Self {
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
    pub(super) fn triangle(
        &self,
        a: [f32; 3],
        b: [f32; 3],
        c: [f32; 3],
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, f32, f32)> {
        let p = |v| permuted(v, self.k);
        self.permuted_triangle(p(a), p(b), p(c), self.origin_k, t_min, t_max)
    }

    /// The watertight test on corners and origin whose components are in the order `k`.
    #[inline(always)]
    pub(super) fn permuted_triangle(
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
pub(super) fn permuted(v: [f32; 3], k: [usize; 3]) -> [f32; 3] {
    match k {
        [1, 2, 0] => [v[1], v[2], v[0]],
        [2, 1, 0] => [v[2], v[1], v[0]],
        [2, 0, 1] => [v[2], v[0], v[1]],
        [0, 2, 1] => [v[0], v[2], v[1]],
        [0, 1, 2] => [v[0], v[1], v[2]],
        _ => [v[1], v[0], v[2]],
    }
}
