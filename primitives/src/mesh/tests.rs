//! Tests of the mesh across its files (set-up, ball test, walks, rows, lanes, Φ).

use super::impls::PART_LEVELS;
use super::query::scaled_t_min;
use super::rows::ROW_PAD;
use super::storage::{v64, Mesh};
use super::walk::single_ray;
use super::watertight::{permuted, watertight_lanes, Lanes, MeshRay};
use crate::bounds::Aabb;
use crate::bvh::rounding::round_down;
use crate::bvh::slab::SlabRay;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect};
use crate::triangle::closest_on_triangle;
use crate::PACKET;
use glam::{DVec3, Vec3A};

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
    assert!(m.has_surface());
}

/// A mesh whose triangles all have zero area is accepted and has no surface: every ray path
/// (single, batch, packet, crossings) misses, no point is inside by any sign method, winding
/// numbers are 0, and Φ, ∇Φ and `closest` are the nearest collapsed triangle's, against the
/// least of the degenerate [`crate::Triangle`]s' own answers over all of them.
#[test]
fn a_mesh_of_degenerate_triangles_has_no_surface() {
    use crate::proximity::SignMethod;
    use crate::Triangle;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};
    let mut rng = StdRng::seed_from_u64(44);
    let mut range = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let mut vertices: Vec<[f32; 3]> = Vec::new();
    let mut indices = Vec::new();
    for i in 0..60u32 {
        let a = [
            range(-1.0, 1.0) as f32,
            range(-1.0, 1.0) as f32,
            range(-1.0, 1.0) as f32,
        ];
        let step = [
            range(-0.5, 0.5) as f32,
            range(-0.5, 0.5) as f32,
            range(-0.5, 0.5) as f32,
        ];
        // zero area exactly: the third corner repeats one of the first two, or all coincide
        let b = [a[0] + step[0], a[1] + step[1], a[2] + step[2]];
        let base = vertices.len() as u32;
        vertices.extend([a, b]);
        indices.push(match i % 3 {
            0 => [base, base + 1, base],
            1 => [base + 1, base, base + 1],
            _ => [base, base, base],
        });
    }
    let mesh = Mesh::new(vertices.clone(), indices.clone(), None).unwrap();
    assert!(!mesh.has_surface());
    assert_eq!(mesh.skipped_triangles(), indices.len());
    assert_eq!(mesh.triangle_count(), indices.len());
    assert!(mesh.pieces().is_none());
    let bounds = mesh.bounds();
    for v in indices.iter().flatten().map(|&i| vertices[i as usize]) {
        assert!(bounds.contains(v64(v)), "{v:?} outside {bounds:?}");
    }
    let collapsed: Vec<Triangle> = indices
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| v64(vertices[i as usize]));
            Triangle::new(a, b, c).unwrap()
        })
        .collect();
    assert!(collapsed.iter().all(Triangle::is_degenerate));
    for _ in 0..300 {
        let p = DVec3::new(range(-2.0, 2.0), range(-2.0, 2.0), range(-2.0, 2.0));
        let reference = collapsed.iter().map(|t| t.phi(p)).fold(f64::INFINITY, f64::min);
        assert_eq!(mesh.phi(p), reference, "Φ at {p:?}");
        let closest = mesh.closest(p).unwrap();
        let q = closest.point.unwrap();
        assert_eq!((q - p).length(), reference);
        assert_eq!((closest.lower, closest.upper), (reference, reference));
        let feature = closest.feature as usize;
        assert_eq!(
            collapsed[feature].phi(p),
            reference,
            "the feature is a nearest triangle"
        );
        let g = mesh.gradient(p);
        assert!((g - (p - q) / reference).length() < 1e-12, "∇Φ at {p:?}: {g:?}");
        for method in SignMethod::ALL {
            assert!(!mesh.contains(p, method), "{p:?} inside by {method:?}");
        }
        assert_eq!(mesh.winding_number(p), 0.0);
        assert_eq!(mesh.fast_winding_number(p), 0.0);
    }
    // rays aimed at the collapsed triangles' corners and midpoints, and random ones
    let mut rays = Vec::new();
    for (i, v) in vertices.iter().enumerate() {
        let origin = DVec3::new(range(-3.0, 3.0), range(-3.0, 3.0), 3.0);
        let target = if i % 2 == 0 {
            v64(*v)
        } else {
            0.5 * (v64(*v) + v64(vertices[i - 1]))
        };
        rays.push(Ray::new(origin, target - origin));
        let d = DVec3::new(range(-1.0, 1.0), range(-1.0, 1.0), range(-1.0, 1.0));
        rays.push(Ray::new(DVec3::ZERO, d));
    }
    let everything = Interval::new(0.0, f64::INFINITY);
    for ray in &rays {
        assert!(mesh.intersect(ray, everything).is_none());
        assert!(mesh.intersect_brute_force(ray).is_none());
        let mut crossings = mesh.crossings(ray, everything);
        assert!(!crossings.starts_inside());
        assert_eq!(crossings.count(), 0);
    }
    let ranges = vec![everything; rays.len()];
    let mut hits = vec![
        Some(RawHit {
            t: 1.0,
            feature: 0,
            local: glam::DVec2::ZERO
        });
        rays.len()
    ];
    let mut uncertain = vec![true; rays.len()];
    mesh.intersect_each(&rays, &ranges, &mut hits, &mut uncertain);
    assert!(hits.iter().all(Option::is_none) && uncertain.iter().all(|u| !u));
    let mut ranges = ranges;
    hits.fill(Some(RawHit {
        t: 1.0,
        feature: 0,
        local: glam::DVec2::ZERO,
    }));
    mesh.intersect_packet(&rays, &mut ranges, &mut hits);
    assert!(hits.iter().all(Option::is_none));
}
