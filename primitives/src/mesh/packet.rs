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
//! Traversal: a node's four children are tested for all lanes at once; a child is visited by
//! the lanes that enter it (its lane mask), nearest child first by its smallest entry over
//! those lanes; the stack keeps each child's per-lane entries, so a lane whose closest hit moved
//! nearer than its entry drops out when the child is popped. The watertight test permutes axes by
//! the direction's largest component; a packet whose lanes disagree on it (rays on both sides of
//! a diagonal) is traced lane by lane instead.

#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several per-lane arrays by the lane; the form the compiler vectorises"
)]

use super::{Candidate, Mesh, MeshQuery};
use crate::bvh::build::EXIT_PAD;
use crate::bvh::{traverse_quads_from, Quad, QUAD_STACK};
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::Intersect;
use crate::PACKET;
use std::mem::MaybeUninit;

/// One f32 per lane.
type Lanes = [f32; PACKET];

/// `max` that compiles to one `maxps` (no NaN reaches it: see the slab tests' module docs).
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `min` that compiles to one `minps`.
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

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
    /// Each lane's closest hit so far (`−∞` for a lane that takes no part).
    t_max: Lanes,
}

/// A child waiting on the stack: node or leaf (`count > 0`), the lanes entering it and their
/// entry distances.
#[derive(Clone, Copy)]
struct Pending {
    child: u32,
    count: u32,
    lanes: u32,
    entry: Lanes,
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
    // a loop rather than `array::from_fn`, whose closure would not be inlined into the AVX2 copy
    let mut queries: [Option<MeshQuery>; PACKET] = [const { None }; PACKET];
    for l in 0..n {
        queries[l] = mesh.query(&rays[l], ranges[l]);
    }
    let Some(first) = queries.iter().flatten().next() else {
        return;
    };
    let k = first.ray.k;
    if queries.iter().flatten().any(|q| q.ray.k != k) {
        for l in 0..n {
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
        t_max: [f32::NEG_INFINITY; PACKET],
    };
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
            packet.t_max[l] = q.t_max;
            active |= 1 << l;
        }
    }
    let mut best: [Option<Candidate>; PACKET] = [None; PACKET];
    let lanes = PacketQuery {
        mesh,
        queries: &queries,
        rays,
        ranges,
    };
    lanes.walk(&mut packet, &mut best, active);
    for l in 0..n {
        if let Some(q) = &queries[l] {
            if let Some(hit) = mesh.finish(&rays[l], ranges[l], q, best[l]) {
                ranges[l].max = hit.t;
                hits[l] = Some(hit);
            }
        }
    }
}

/// Entry distances of every lane into child `slot` of `quad`, and the lanes that enter it before
/// their `t1`: the single-ray slab test (`SlabRay::entry4`), lane by lane.
#[inline(always)]
fn entry(packet: &Packet, quad: &Quad, slot: usize, t1: &Lanes) -> (u32, Lanes) {
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
            n = max(n, min(a, b));
            f = min(f, max(a, b));
        }
        let f = min(f * EXIT_PAD, t1[l]);
        near[l] = n;
        inside[l] = flag(n <= f);
    }
    (bitmask(&inside), near)
}

/// A lane's flag as a full-width mask: all ones for `true`, zero for `false`.
#[inline(always)]
fn flag(b: bool) -> i32 {
    -i32::from(b)
}

/// Bit `l` set where `flags[l]` (a [`flag`]) is set: two `movmskps` on x86-64 (a bit loop
/// otherwise, which the compiler turns into a chain of shuffles).
#[inline(always)]
fn bitmask(flags: &[i32; PACKET]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_castsi128_ps, _mm_loadu_si128, _mm_movemask_ps};
        let halves = flags.as_ptr().cast::<std::arch::x86_64::__m128i>();
        // SAFETY: SSE2 is in every x86-64 CPU; the two 16-byte loads stay inside `flags`
        // (32 bytes; `PACKET` is 8, checked below)
        const _: () = assert!(PACKET == 8);
        unsafe {
            let lo = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves)));
            let hi = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(halves.add(1))));
            (lo | (hi << 4)) as u32
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut mask = 0;
        for (l, &f) in flags.iter().enumerate() {
            mask |= u32::from(f != 0) << l;
        }
        mask
    }
}

/// Below this many lanes, a leaf's triangles are tested lane by lane (the SIMD test costs the
/// same for one lane as for eight).
const FEW_LANES: u32 = 2;

/// A node entered by at most this many lanes is walked by each of them alone.
const ALONE_LANES: u32 = 2;

/// What the walk reads about each lane: its ray and range as given and its set-up.
struct PacketQuery<'a> {
    mesh: &'a Mesh,
    queries: &'a [Option<MeshQuery>; PACKET],
    rays: &'a [Ray],
    ranges: &'a [Interval],
}

impl PacketQuery<'_> {
    /// Walks the hierarchy for the lanes of `active`, testing each leaf that some lanes enter
    /// before their closest hit so far. A node entered by at most [`ALONE_LANES`] lanes is walked by
    /// each alone, as a single ray would.
    #[inline(always)]
    fn walk(&self, packet: &mut Packet, best: &mut [Option<Candidate>; PACKET], active: u32) {
        let quads = self.mesh.bvh.quads();
        if quads.is_empty() || active == 0 {
            return;
        }
        // uninitialised: only entries below `top`, written before, are ever read
        let mut stack = [const { MaybeUninit::<Pending>::uninit() }; QUAD_STACK];
        stack[0].write(Pending {
            child: 0,
            count: 0,
            lanes: active,
            entry: packet.t_min,
        });
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            // SAFETY: `stack[top]` was written by the push that raised `top` above it
            let pending = unsafe { stack[top].assume_init() };
            let mut still = [0i32; PACKET];
            for l in 0..PACKET {
                still[l] = flag(pending.entry[l] <= packet.t_max[l]);
            }
            let lanes = pending.lanes & bitmask(&still);
            if lanes == 0 {
                continue;
            }
            if pending.count > 0 {
                self.leaf(packet, best, pending.child, pending.count, lanes);
                continue;
            }
            if lanes.count_ones() <= ALONE_LANES {
                let mut rest = lanes;
                while rest != 0 {
                    let l = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    self.walk_lane(packet, best, l, pending.child as usize);
                }
                continue;
            }
            let quad = &quads[pending.child as usize];
            let mut t1 = [f32::NEG_INFINITY; PACKET];
            for (l, t) in t1.iter_mut().enumerate() {
                if lanes & (1 << l) != 0 {
                    *t = packet.t_max[l];
                }
            }
            // the entered children, sorted farthest first by their nearest lane's entry
            let mut order: [(f32, Pending); 4] = [(0.0, pending); 4];
            let mut entered = 0;
            for slot in 0..quad.len as usize {
                let (inside, near) = entry(packet, quad, slot, &t1);
                if inside == 0 {
                    continue;
                }
                let mut nearest = f32::INFINITY;
                for (l, &t) in near.iter().enumerate() {
                    if inside & (1 << l) != 0 {
                        nearest = min(nearest, t);
                    }
                }
                let child = Pending {
                    child: quad.child[slot],
                    count: quad.count[slot],
                    lanes: inside,
                    entry: near,
                };
                let mut k = entered;
                while k > 0 && order[k - 1].0 < nearest {
                    order[k] = order[k - 1];
                    k -= 1;
                }
                order[k] = (nearest, child);
                entered += 1;
            }
            for (_, child) in &order[..entered] {
                stack[top].write(*child);
                top += 1;
            }
        }
    }

    /// Lane `l` alone through the subtree under `quads[root]`: the single-ray walk.
    #[inline(always)]
    fn walk_lane(&self, packet: &mut Packet, best: &mut [Option<Candidate>; PACKET], l: usize, root: usize) {
        let Some(q) = &self.queries[l] else { return };
        let mut t_max = packet.t_max[l];
        traverse_quads_from(
            self.mesh.bvh.quads(),
            root,
            t_max,
            |quad, t1| q.ray.slab.entry4(quad, q.t_min, t1),
            |first, count, t_far| {
                let t = self.leaf_lane(&mut best[l], l, first, count, t_far);
                (t < t_far).then(|| {
                    t_max = t;
                    t
                })
            },
        );
        // a hit at exactly `t_far` (an earlier triangle at the same `t`) leaves it unchanged
        packet.t_max[l] = t_max;
    }

    /// The leaf's triangles for lane `l` alone, its closest hit so far at `t_far`: the single-ray
    /// leaf test. Returns the new `t_far`.
    #[inline(always)]
    fn leaf_lane(&self, best: &mut Option<Candidate>, l: usize, first: u32, count: u32, mut t_far: f32) -> f32 {
        let Some(q) = &self.queries[l] else { return t_far };
        let mesh = self.mesh;
        for k in first as usize..(first + count) as usize {
            let [a, b, c] = mesh.tris[k].map(|i| mesh.vertices[i as usize]);
            if let Some((t, u, v)) = q.ray.triangle(a, b, c, q.t_min, t_far) {
                if !Mesh::beats(best.as_ref(), k, t, t_far) || !mesh.counts(&self.rays[l], self.ranges[l], q, k, t) {
                    continue;
                }
                t_far = t;
                *best = Some((k, t, u, v));
            }
        }
        t_far
    }

    /// Tests the leaf's triangles `first..first + count` for the lanes of `lanes`, updating each
    /// lane's closest candidate and `t_max`.
    #[inline(always)]
    fn leaf(&self, packet: &mut Packet, best: &mut [Option<Candidate>; PACKET], first: u32, count: u32, lanes: u32) {
        if lanes.count_ones() <= FEW_LANES {
            let mut rest = lanes;
            while rest != 0 {
                let l = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                packet.t_max[l] = self.leaf_lane(&mut best[l], l, first, count, packet.t_max[l]);
            }
            return;
        }
        let mesh = self.mesh;
        let [kx, ky, kz] = packet.k;
        for k in first as usize..(first + count) as usize {
            let [a, b, c] = mesh.tris[k].map(|i| mesh.vertices[i as usize]);
            let mut t = [0.0f32; PACKET];
            let mut e = [[0.0f32; PACKET]; 2];
            let mut det = [0.0f32; PACKET];
            let mut zero = [0i32; PACKET];
            let mut pass = [0i32; PACKET];
            for l in 0..PACKET {
                let [ox, oy, oz] = [packet.origin[kx][l], packet.origin[ky][l], packet.origin[kz][l]];
                let [sx, sy, sz] = [packet.shear[0][l], packet.shear[1][l], packet.shear[2][l]];
                let (az, bz, cz) = (a[kz] - oz, b[kz] - oz, c[kz] - oz);
                let ax = (a[kx] - ox) - sx * az;
                let ay = (a[ky] - oy) - sy * az;
                let bx = (b[kx] - ox) - sx * bz;
                let by = (b[ky] - oy) - sy * bz;
                let cx = (c[kx] - ox) - sx * cz;
                let cy = (c[ky] - oy) - sy * cz;
                let e0 = cx * by - cy * bx;
                let e1 = ax * cy - ay * cx;
                let e2 = bx * ay - by * ax;
                zero[l] = flag(e0 == 0.0 || e1 == 0.0 || e2 == 0.0);
                let d = e0 + e1 + e2;
                let tl = (e0 * (sz * az) + e1 * (sz * bz) + e2 * (sz * cz)) / d;
                let mixed = (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0);
                pass[l] = flag(!mixed && d != 0.0 && tl >= packet.t_min[l] && tl <= packet.t_max[l]);
                t[l] = tl;
                e[0][l] = e1;
                e[1][l] = e2;
                det[l] = d;
            }
            let zero = bitmask(&zero) & lanes;
            let mut found = bitmask(&pass) & lanes & !zero;
            // lanes with an edge function of exactly zero: the single-ray test, f64
            // recomputation included
            let mut exact = [(0.0f32, 0.0f32, 0.0f32); PACKET];
            let mut rest = zero;
            while rest != 0 {
                let l = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                if let Some(q) = &self.queries[l] {
                    if let Some(hit) = q.ray.triangle(a, b, c, q.t_min, packet.t_max[l]) {
                        exact[l] = hit;
                        found |= 1 << l;
                    }
                }
            }
            while found != 0 {
                let l = found.trailing_zeros() as usize;
                found &= found - 1;
                let Some(q) = &self.queries[l] else { continue };
                let hit = if zero & (1 << l) != 0 {
                    exact[l]
                } else {
                    (t[l], e[0][l] / det[l], e[1][l] / det[l])
                };
                if !Mesh::beats(best[l].as_ref(), k, hit.0, packet.t_max[l])
                    || !mesh.counts(&self.rays[l], self.ranges[l], q, k, hit.0)
                {
                    continue;
                }
                packet.t_max[l] = hit.0;
                best[l] = Some((k, hit.0, hit.1, hit.2));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
