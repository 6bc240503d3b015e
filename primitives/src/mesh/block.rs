//! Triangle blocks: up to [`LANES`] consecutive triangles of a BVH leaf with their vertices
//! gathered (through the index triples, on the stack: no memory is added per triangle) into
//! structure-of-arrays form, so that the watertight test runs on all of them in one SIMD pass
//! instead of one triangle at a time.
//!
//! The lanes compute exactly the operations of the scalar test ([`super::MeshRay::triangle`]),
//! in the same order and in the same f32 arithmetic (SSE has no fused operations unless asked),
//! so every lane's `(t, u, v)` is bit-identical to the scalar answer; a lane whose edge function
//! is exactly zero takes the scalar path, which re-decides it in f64.

use glam::Vec4;

/// Triangles per block (one SSE register of f32).
pub(crate) const LANES: usize = 4;

/// A leaf's triangles: `vertex[corner][axis][lane]`, corners `a, b, c`, and the leaf-order index
/// of lane 0 (lane `i` is triangle `first + i`); lanes at or past `count` repeat lane 0 and are
/// masked out.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TriBlock {
    pub vertex: [[[f32; LANES]; 3]; 3],
    pub first: u32,
    pub count: u32,
}

impl TriBlock {
    /// The block of `corners` (each triangle's `a, b, c`), `first` the leaf-order index of the
    /// first; at most [`LANES`] triangles, at least one.
    #[cfg(test)]
    pub fn new(first: u32, corners: &[[[f32; 3]; 3]]) -> Self {
        debug_assert!((1..=LANES).contains(&corners.len()));
        let mut vertex = [[[0f32; LANES]; 3]; 3];
        for (corner, axes) in vertex.iter_mut().enumerate() {
            for (axis, lanes) in axes.iter_mut().enumerate() {
                for (lane, value) in lanes.iter_mut().enumerate() {
                    *value = corners.get(lane).unwrap_or(&corners[0])[corner][axis];
                }
            }
        }
        Self {
            vertex,
            first,
            count: corners.len() as u32,
        }
    }

    /// The block of triangles `tris` (index triples into `vertices`), `first` the leaf-order
    /// index of the first; at most [`LANES`] triangles, at least one.
    #[inline(always)]
    pub fn gather(first: u32, tris: &[[u32; 3]], vertices: &[[f32; 3]]) -> Self {
        debug_assert!((1..=LANES).contains(&tris.len()));
        let mut vertex = [[[0f32; LANES]; 3]; 3];
        for (lane, tri) in (0..LANES).map(|lane| tris.get(lane).unwrap_or(&tris[0])).enumerate() {
            for (corner, &index) in tri.iter().enumerate() {
                let v = vertices[index as usize];
                vertex[corner][0][lane] = v[0];
                vertex[corner][1][lane] = v[1];
                vertex[corner][2][lane] = v[2];
            }
        }
        Self {
            vertex,
            first,
            count: tris.len() as u32,
        }
    }

    /// Corner `corner` of lane `lane`.
    pub fn corner(&self, corner: usize, lane: usize) -> [f32; 3] {
        [0, 1, 2].map(|axis| self.vertex[corner][axis][lane])
    }
}

/// Per-lane results of a block test: `t`, barycentrics `u`, `v`, a bit per lane that hit within
/// the range, and a bit per lane that must be re-decided by the scalar test.
pub(crate) struct BlockHits {
    pub t: [f32; LANES],
    pub u: [f32; LANES],
    pub v: [f32; LANES],
    pub hit: u32,
    pub rescan: u32,
}

/// The watertight test of a sheared ray (`origin`, permuted axes `k`, shear constants `shear`,
/// as in [`super::MeshRay`]) against all lanes of `block`, with `t` in `[t_min, t_max]`.
#[inline(always)]
pub(crate) fn test_block(
    origin: [f32; 3],
    k: [usize; 3],
    shear: [f32; 3],
    block: &TriBlock,
    t_min: f32,
    t_max: f32,
) -> BlockHits {
    let [kx, ky, kz] = k;
    let load = |corner: usize, axis: usize| Vec4::from_array(block.vertex[corner][axis]);
    let (ox, oy, oz) = (
        Vec4::splat(origin[kx]),
        Vec4::splat(origin[ky]),
        Vec4::splat(origin[kz]),
    );
    let (sx, sy, sz) = (Vec4::splat(shear[0]), Vec4::splat(shear[1]), Vec4::splat(shear[2]));
    let (az, bz, cz) = (load(0, kz) - oz, load(1, kz) - oz, load(2, kz) - oz);
    let ax = (load(0, kx) - ox) - sx * az;
    let ay = (load(0, ky) - oy) - sy * az;
    let bx = (load(1, kx) - ox) - sx * bz;
    let by = (load(1, ky) - oy) - sy * bz;
    let cx = (load(2, kx) - ox) - sx * cz;
    let cy = (load(2, ky) - oy) - sy * cz;
    let e0 = cx * by - cy * bx;
    let e1 = ax * cy - ay * cx;
    let e2 = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let lanes = (1u32 << block.count) - 1;
    let rescan = (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).bitmask() & lanes;
    let negative = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
    let positive = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
    let det = e0 + e1 + e2;
    let t = (e0 * (sz * az) + e1 * (sz * bz) + e2 * (sz * cz)) / det;
    let inside = !(negative & positive).bitmask();
    let in_range = (det.cmpne(zero) & t.cmpge(Vec4::splat(t_min)) & t.cmple(Vec4::splat(t_max))).bitmask();
    BlockHits {
        t: t.to_array(),
        u: (e1 / det).to_array(),
        v: (e2 / det).to_array(),
        hit: inside & in_range & lanes & !rescan,
        rescan,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshRay;
    use glam::Vec3A;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Every lane of the block test gives bit for bit the scalar test's answer, on random
    /// triangles (some sharing edges with the ray's axis-aligned planes, some with exact zeros)
    /// and random rays, with partly filled blocks.
    #[test]
    fn lanes_equal_the_scalar_test() {
        let mut rng = StdRng::seed_from_u64(11);
        let point = |rng: &mut StdRng| -> [f32; 3] {
            // coarse grid values make exactly-zero edge functions common
            std::array::from_fn(|_| (rng.random_range(-8i32..=8) as f32) * 0.25)
        };
        let (mut hits, mut rescans) = (0, 0);
        for _ in 0..20_000 {
            let count = rng.random_range(1..=LANES);
            let corners: Vec<[[f32; 3]; 3]> = (0..count)
                .map(|_| [point(&mut rng), point(&mut rng), point(&mut rng)])
                .collect();
            let block = TriBlock::new(0, &corners);
            let origin = Vec3A::from_array(point(&mut rng)) * 3.0;
            // aimed near one of the triangles' centroids, so that many rays hit
            let aim = corners[rng.random_range(0..count)]
                .iter()
                .fold(Vec3A::ZERO, |s, v| s + Vec3A::from_array(*v) / 3.0);
            let jitter = Vec3A::from_array(point(&mut rng)) * 0.5;
            let dir = (aim + jitter - origin).normalize_or_zero();
            if dir == Vec3A::ZERO {
                continue;
            }
            let ray = MeshRay::new(origin, dir);
            let (t_min, t_max) = (0.0, rng.random_range(0.5f32..40.0));
            let lanes = test_block(ray.origin, ray.k, ray.shear, &block, t_min, t_max);
            for (lane, c) in corners.iter().enumerate() {
                let scalar = ray.triangle(c[0], c[1], c[2], t_min, t_max);
                let bit = 1 << lane;
                if lanes.rescan & bit != 0 {
                    rescans += 1;
                    continue;
                }
                let simd = (lanes.hit & bit != 0).then(|| (lanes.t[lane], lanes.u[lane], lanes.v[lane]));
                let bits = |h: Option<(f32, f32, f32)>| h.map(|(t, u, v)| [t, u, v].map(f32::to_bits));
                assert_eq!(
                    bits(simd),
                    bits(scalar),
                    "lane {lane} of {corners:?}, ray {origin} {dir}"
                );
                hits += usize::from(simd.is_some());
            }
            assert_eq!(lanes.hit >> count, 0, "lanes past the count never hit");
        }
        assert!(hits > 1000 && rescans > 20, "{hits} hits, {rescans} rescans");
    }
}
