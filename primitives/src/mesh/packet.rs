//! Packet tracing of a mesh: up to [`PACKET`] rays (neighbouring pixels, say) walk the 4-wide
//! hierarchy together, one ray per SIMD lane.
//!
//! Each lane runs exactly the arithmetic of the single-ray test ([`Mesh::intersect`]): the same
//! f32 ray set-up (`MeshQuery`), the same slab tests (conservative, the exit enlarged by
//! `1 + 2γ₃`), the same watertight triangle test with its f64 recomputation of edge functions that
//! come out zero, the same band re-check near `t_min` and the same f64 `t` at the end. Only the
//! loops run across lanes, so the compiler keeps eight lanes in one 256-bit register where the
//! CPU has AVX2 (through [`crate::with_fma!`]) and two 128-bit ones otherwise, with identical
//! results. The closest hit is the smallest `(t, leaf position)` in both paths, so the order in
//! which a packet visits the leaves does not change any lane's answer.
//!
//! Traversal is the shared packet walk (`bvh::walk_packet`): a child is visited by the lanes that
//! enter it, nearest first; a node entered by at most [`ALONE_LANES`] lanes is walked by each
//! alone (the single-ray walk), and a leaf entered by at most [`FEW_LANES`] lanes is tested lane
//! by lane. The watertight test permutes axes by the direction's largest component; a packet
//! whose lanes disagree on it (rays on both sides of a diagonal) is traced lane by lane instead.

#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several per-lane arrays by the lane; the form the compiler vectorises"
)]

use super::query::{Candidate, MeshQuery};
use super::storage::Mesh;
use super::watertight::{permuted, watertight_lanes, Lanes};
use crate::bvh::lanes::{lane_mask, lanes_of, max_f32, min_f32};
use crate::bvh::packet::{walk_packet, PacketVisitor};
use crate::bvh::quad::Quad;
use crate::bvh::slab::EXIT_PAD;
use crate::bvh::walk::{cull_bound, traverse_quads_from, SlabsFrom};
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::Intersect;
use crate::PACKET;

/// Below this many lanes, a leaf's triangles are tested lane by lane (the SIMD test costs the
/// same for one lane as for eight).
const FEW_LANES: u32 = 2;

/// A node entered by at most this many lanes is walked by each of them alone.
const ALONE_LANES: u32 = 2;

/// The lanes' rays in SoA layout for the slab and triangle tests.
struct Packet {
    /// Origins, per axis.
    origin: [Lanes; 3],
    /// Clamped reciprocal directions, per axis.
    inv: [Lanes; 3],
    /// The watertight test's shear constants `(d_kx/d_kz, d_ky/d_kz, 1/d_kz)`.
    shear: [Lanes; 3],
    /// The axis permutation `(kx, ky, kz)` every lane shares.
    k: [usize; 3],
    t_min: Lanes,
}

/// Traces `rays` (at most [`PACKET`]) as [`Intersect::intersect_packet`] says.
pub(super) fn intersect(mesh: &Mesh, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
    #[inline(always)]
    fn run(mesh: &Mesh, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        trace(mesh, rays, ranges, hits);
    }
    crate::with_fma!(run(mesh: &Mesh = mesh, rays: &[Ray] = rays, ranges: &mut [Interval] = ranges, hits: &mut [Option<RawHit>] = hits) -> ())
}

#[inline(always)]
fn trace(mesh: &Mesh, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
    let n = rays.len().min(PACKET);
    let Some(root) = mesh.bvh.quads().first() else {
        return;
    };
    // only the lanes entering the box around the root's children are set up: the others would
    // enter none of the children (`SlabRay::enters`), and a packet beside the mesh (half a
    // camera's packets on the bench meshes) costs the f32 rays and one box test
    let (lo, hi) = root.box_of_slots();
    // loops rather than `array::from_fn`, whose closure would not be inlined into the AVX2 copy
    let mut queries: [Option<MeshQuery>; PACKET] = [const { None }; PACKET];
    for l in 0..n {
        if let Some(entry) = mesh.entry(&rays[l], ranges[l]) {
            if entry.slab.enters(lo, hi, entry.t_min, cull_bound(entry.t_max)) {
                queries[l] = Some(entry.query());
            }
        }
    }
    let Some(first) = queries.iter().flatten().next() else {
        return;
    };
    let k = first.ray.k;
    if queries.iter().flatten().any(|q| q.ray.k != k) {
        for l in 0..n {
            if queries[l].is_none() {
                continue;
            }
            if let Some(hit) = mesh.intersect(&rays[l], ranges[l]) {
                ranges[l].max = hit.t;
                hits[l] = Some(hit);
            }
        }
        return;
    }
    let mut packet = Packet {
        origin: [[0.0; PACKET]; 3],
        inv: [[0.0; PACKET]; 3],
        shear: [[0.0; PACKET]; 3],
        k,
        t_min: [0.0; PACKET],
    };
    let mut t_max = [f32::NEG_INFINITY; PACKET];
    let mut active = 0u32;
    for l in 0..PACKET {
        // a lane without a ray repeats the first lane's ray with an empty range
        let (q, on) = match &queries[l] {
            Some(q) => (q, true),
            None => (first, false),
        };
        for axis in 0..3 {
            packet.origin[axis][l] = q.ray.origin[axis];
            packet.inv[axis][l] = q.ray.slab.inv[axis];
            packet.shear[axis][l] = q.ray.shear[axis];
        }
        packet.t_min[l] = q.t_min;
        if on {
            t_max[l] = q.t_max;
            active |= 1 << l;
        }
    }
    let t_min = packet.t_min;
    let mut walk = PacketQuery {
        mesh,
        queries: &queries,
        rays,
        ranges,
        packet: &packet,
        best: [None; PACKET],
    };
    walk_packet(mesh.bvh.quads(), active, t_min, &mut t_max, ALONE_LANES, &mut walk);
    let best = walk.best;
    for l in 0..n {
        if let Some(q) = &queries[l] {
            if let Some(hit) = mesh.finish(&rays[l], ranges[l], q, best[l]) {
                ranges[l].max = hit.t;
                hits[l] = Some(hit);
            }
        }
    }
}

/// The packet walk over a mesh: each lane's ray and range as given, its set-up, the SoA
/// packet and the closest candidates so far.
struct PacketQuery<'a> {
    mesh: &'a Mesh,
    queries: &'a [Option<MeshQuery>; PACKET],
    rays: &'a [Ray],
    ranges: &'a [Interval],
    packet: &'a Packet,
    best: [Option<Candidate>; PACKET],
}

impl PacketVisitor for PacketQuery<'_> {
    /// The single-ray slab test (`SlabRay::entry4`), lane by lane.
    #[inline(always)]
    fn entry(&self, quad: &Quad, slot: usize, t1: &Lanes) -> (u32, Lanes) {
        let packet = self.packet;
        let mut near = [0.0; PACKET];
        let mut inside = [0i32; PACKET];
        for l in 0..PACKET {
            let mut n = packet.t_min[l];
            let mut f = f32::INFINITY;
            for axis in 0..3 {
                let o = packet.origin[axis][l];
                let inv = packet.inv[axis][l];
                let a = (quad.lo[axis][slot] - o) * inv;
                let b = (quad.hi[axis][slot] - o) * inv;
                n = max_f32(n, min_f32(a, b));
                f = min_f32(f, max_f32(a, b));
            }
            let f = min_f32(f * EXIT_PAD, t1[l]);
            near[l] = n;
            inside[l] = -i32::from(n <= f);
        }
        (lane_mask(&inside), near)
    }

    #[inline(always)]
    fn leaf(&mut self, first: u32, count: u32, lanes: u32, t_max: &mut Lanes) {
        if lanes.count_ones() <= FEW_LANES {
            for l in lanes_of(lanes) {
                t_max[l] = self.leaf_lane(l, first, count, t_max[l]);
            }
        } else {
            self.leaf_packet(first, count, lanes, t_max);
        }
    }

    /// The single-ray walk of each lane through the subtree under `quads[root]`.
    #[inline(always)]
    fn alone(&mut self, root: usize, lanes: u32, t_max: &mut Lanes) {
        for l in lanes_of(lanes) {
            let Some(q) = &self.queries[l] else { continue };
            let mut lane_max = t_max[l];
            traverse_quads_from(
                self.mesh.bvh.quads(),
                root,
                lane_max,
                SlabsFrom {
                    ray: &q.ray.slab,
                    t_min: q.t_min,
                },
                |first, count, t_far| {
                    let t = self.leaf_lane(l, first, count, t_far);
                    // a hit at exactly `t_far` (an earlier triangle at the same `t`) keeps it
                    (t < t_far).then(|| {
                        lane_max = t;
                        t
                    })
                },
            );
            t_max[l] = lane_max;
        }
    }
}

impl PacketQuery<'_> {
    /// The leaf's triangles for lane `l` alone, its closest hit so far at `t_far`: the single-ray
    /// leaf test. Returns the new `t_far`.
    #[inline(always)]
    fn leaf_lane(&mut self, l: usize, first: u32, count: u32, t_far: f32) -> f32 {
        let Some(q) = &self.queries[l] else { return t_far };
        self.mesh
            .leaf_closest(
                &self.rays[l],
                self.ranges[l],
                q,
                q.ray.k,
                first,
                count,
                t_far,
                &mut self.best[l],
            )
            .unwrap_or(t_far)
    }

    /// The leaf's triangles for the lanes of `lanes`, eight lanes per SIMD operation.
    #[inline(always)]
    fn leaf_packet(&mut self, first: u32, count: u32, lanes: u32, t_max: &mut Lanes) {
        let mesh = self.mesh;
        let packet = self.packet;
        let axes = packet.k;
        let leaf = mesh.leaf(first, count);
        let origin = [packet.origin[axes[0]], packet.origin[axes[1]], packet.origin[axes[2]]];
        for i in 0..count as usize {
            // the corners' components in the order (kx, ky, kz), the same in every lane
            let corners = leaf.permuted_corners(i, axes);
            let test = watertight_lanes(&corners, &origin, &packet.shear, packet.t_min, *t_max);
            let zero = test.zero & lanes;
            let found = test.pass & lanes & !zero;
            // lanes with an edge function of exactly zero: the single-ray test, f64
            // recomputation included
            for l in lanes_of(zero | found) {
                let Some(q) = &self.queries[l] else { continue };
                let hit = if zero & (1 << l) != 0 {
                    let [a, b, c] = corners;
                    match q
                        .ray
                        .permuted_triangle(a, b, c, permuted(q.ray.origin, axes), q.t_min, t_max[l])
                    {
                        Some(hit) => hit,
                        None => continue,
                    }
                } else {
                    test.hit(l)
                };
                let k = first as usize + i;
                if !Mesh::beats(self.best[l].as_ref(), k, hit.0, t_max[l])
                    || !mesh.counts(&self.rays[l], self.ranges[l], q, k, hit.0)
                {
                    continue;
                }
                t_max[l] = hit.0;
                self.best[l] = Some(Candidate::new(hit, first, count, i));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::slab::SlabRay;
    use crate::mesh::Mesh;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// A closed, bumpy sphere of `2·n·(n − 1)` triangles: a latitude–longitude grid whose radius
    /// varies with the angles, so that rays meet many triangles at many depths.
    fn bumpy_sphere(n: usize) -> Mesh {
        let mut vertices = vec![[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
        for i in 1..n {
            let theta = std::f64::consts::PI * i as f64 / n as f64;
            for j in 0..2 * n {
                let phi = std::f64::consts::PI * j as f64 / n as f64;
                let r = 1.0 + 0.15 * (3.0 * theta).sin() * (5.0 * phi).cos();
                let p = r * DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                vertices.push(p.as_vec3().to_array());
            }
        }
        let ring = |i: usize, j: usize| (2 + (i - 1) * 2 * n + j % (2 * n)) as u32;
        let mut tris = Vec::new();
        for j in 0..2 * n {
            tris.push([0, ring(1, j), ring(1, j + 1)]);
            tris.push([1, ring(n - 1, j + 1), ring(n - 1, j)]);
            for i in 1..n - 1 {
                tris.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                tris.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
        }
        Mesh::new(vertices, tris, None).unwrap()
    }

    /// Compares the packet with lane-by-lane single rays, hit for hit, bit for bit, starting
    /// from the given ranges and earlier hits.
    fn assert_packet_equals_single(mesh: &Mesh, rays: &[Ray], ranges: &[Interval]) {
        let mut single_ranges = ranges.to_vec();
        let mut single = vec![None; rays.len()];
        for l in 0..rays.len() {
            if let Some(hit) = mesh.intersect(&rays[l], ranges[l]) {
                single_ranges[l].max = hit.t;
                single[l] = Some(hit);
            }
        }
        let mut packet_ranges = ranges.to_vec();
        let mut packet = vec![None; rays.len()];
        mesh.intersect_packet(rays, &mut packet_ranges, &mut packet);
        assert_eq!(packet, single, "rays {rays:?}");
        assert_eq!(packet_ranges, single_ranges);
    }

    /// Coherent packets (a camera's neighbouring pixels, grazing the silhouette included),
    /// scattered packets, partial packets and lanes with limited ranges all give exactly the
    /// single-ray answers.
    #[test]
    fn packets_equal_single_rays() {
        let mesh = bumpy_sphere(24);
        let mut rng = rand::rngs::StdRng::seed_from_u64(31);
        let mut hits = 0;
        for round in 0..3000 {
            let eye = DVec3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), -3.0);
            let centre = DVec3::new(rng.random_range(-1.3..1.3), rng.random_range(-1.3..1.3), 0.0);
            let spread = if round % 3 == 0 { 0.5 } else { 0.002 };
            let n = if round % 7 == 0 {
                rng.random_range(1..=PACKET)
            } else {
                PACKET
            };
            let rays: Vec<Ray> = (0..n)
                .map(|l| {
                    let target =
                        centre + spread * DVec3::new((l % 4) as f64, (l / 4) as f64, rng.random_range(-1.0..1.0));
                    Ray::new(eye, target - eye)
                })
                .collect();
            let ranges: Vec<Interval> = (0..n)
                .map(|_| match rng.random_range(0..4) {
                    0 => Interval::new(rng.random_range(0.5..0.9), rng.random_range(0.9..1.1)),
                    _ => Interval::POSITIVE,
                })
                .collect();
            hits += rays
                .iter()
                .filter(|r| mesh.intersect(r, Interval::POSITIVE).is_some())
                .count();
            assert_packet_equals_single(&mesh, &rays, &ranges);
        }
        assert!(hits > 5000, "{hits}");
    }

    /// The single-ray walk, compiled once per axis permutation of the watertight test, finds the
    /// triangle that testing every triangle finds, at the same `t`, for rays of all six
    /// permutations (dominant axis either way, and both orders of the other two).
    #[test]
    fn single_rays_of_every_axis_permutation_equal_brute_force() {
        let mesh = bumpy_sphere(16);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let mut seen = std::collections::BTreeMap::new();
        for _ in 0..6000 {
            let axis = rng.random_range(0..3);
            let mut d = [
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
            ];
            d[axis] = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let dir = DVec3::from_array(d);
            let aim = DVec3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
            );
            let ray = Ray::new(aim - 3.0 * dir, dir);
            let unit = (ray.dir / ray.dir.length()).as_vec3a();
            let (origin, unit) = (ray.origin.as_vec3a(), unit);
            let k = crate::mesh::watertight::MeshRay::with_slab(SlabRay::new(origin, unit), origin, unit).k;
            let single = mesh.intersect(&ray, Interval::POSITIVE);
            let brute = mesh.intersect_brute_force(&ray);
            assert_eq!(single.map(|h| h.feature), brute.map(|b| b.0), "{ray:?}");
            if let (Some(h), Some((_, t32))) = (single, brute) {
                let t = h.t * ray.dir.length();
                assert!((t - f64::from(t32)).abs() <= 1e-5 * t, "{ray:?}: {t} against {t32}");
            }
            *seen.entry(k).or_insert(0) += usize::from(single.is_some());
        }
        assert_eq!(seen.len(), 6, "{seen:?}");
        assert!(seen.values().all(|&hits| hits > 300), "{seen:?}");
    }

    /// Rays from inside the mesh, lanes whose axis permutations differ (traced lane by lane) and
    /// invalid lanes (zero direction, NaN origin) next to good ones.
    #[test]
    fn inside_mixed_and_invalid_lanes() {
        let mesh = bumpy_sphere(12);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..2000 {
            let o = DVec3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            );
            let mut rays: Vec<Ray> = (0..PACKET)
                .map(|_| {
                    let d = DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    );
                    Ray::new(o, d)
                })
                .collect();
            if rng.random_bool(0.3) {
                rays[3].dir = DVec3::ZERO;
                rays[5].origin.x = f64::NAN;
            }
            assert_packet_equals_single(&mesh, &rays, &[Interval::POSITIVE; PACKET]);
        }
    }

    /// Rays through the mesh's vertices, where edge functions come out exactly zero and the f64
    /// recomputation decides: packets agree with single rays there too.
    #[test]
    fn rays_through_vertices() {
        let mesh = bumpy_sphere(8);
        let eye = DVec3::new(0.0, 0.0, -4.0);
        let vertices: Vec<DVec3> = mesh
            .vertices()
            .iter()
            .map(|v| DVec3::new(v[0].into(), v[1].into(), v[2].into()))
            .collect();
        for chunk in vertices.chunks(PACKET) {
            let rays: Vec<Ray> = chunk.iter().map(|v| Ray::new(eye, *v - eye)).collect();
            assert_packet_equals_single(&mesh, &rays, &vec![Interval::POSITIVE; rays.len()]);
        }
        // axis-aligned rays through vertices: the f32 shear is exact, edge functions are zero
        let rays: Vec<Ray> = vertices[..PACKET]
            .iter()
            .map(|v| Ray::new(DVec3::new(v.x, v.y, -4.0), DVec3::Z))
            .collect();
        assert_packet_equals_single(&mesh, &rays, &[Interval::POSITIVE; PACKET]);
    }
}
