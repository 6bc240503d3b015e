//! Hard cases for the closed-form intersectors, with numeric pass criteria.
//!
//! Every case draws its parameters and rays as **f32 values** (widened to f64 for zeroset's API)
//! and compares against a double-double reference on the same inputs (`support`). Each asserts:
//! the largest relative `t` error, the largest normal angle error (radians), zero hit/miss
//! disagreements outside a stated band around silhouettes (rays whose reference margin, a
//! relative distance from tangency, an edge or a rim, is below the band may go either way;
//! they are counted as "banded"), no NaN/∞ in `t`, point, normal, uv or error bound, and `t`
//! inside the query interval. `cargo test --test hard_cases -- --nocapture` prints one `[hard]`
//! line per case with the measured maxima and medians (quoted in `docs/numerics.md`).

mod support;

use glam::{DAffine3, DQuat, DVec2, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use support::{Reference, Stats};
use zeroset_primitives::testing::random_unit;
use zeroset_primitives::*;

/// One f32 ulp at 1, relative: 2⁻²³. The aim is "a few f32 ulp" (4 ulp ≈ 4.8e-7 at
/// worst, 2.4e-7 typical); the closed forms do far better and the bounds below say by how much.
const F32_ULP: f64 = 1.1920929e-7;

fn f(x: f64) -> f64 {
    f64::from(x as f32)
}

fn v32(v: DVec3) -> DVec3 {
    DVec3::new(f(v.x), f(v.y), f(v.z))
}

fn log_uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

/// Runs one ray through `prim` and books it against `reference`.
fn book(stats: &mut Stats, prim: &dyn Primitive, ray: Ray, range: Interval, reference: Reference, band: f64) {
    stats.rays += 1;
    let hit = prim.intersect(&ray, range);
    if let Some(raw) = hit {
        stats.hits += 1;
        let full = SurfaceHit::complete(prim, &ray, &raw, HitRequest::ALL);
        let n = full.normal.unwrap_or(DVec3::NAN);
        let finite = raw.t.is_finite()
            && full.point.is_finite()
            && n.is_finite()
            && (n.length() - 1.0).abs() < 1e-9
            && full.uv.is_none_or(|uv| uv.is_finite())
            && full.error.is_finite();
        if !finite {
            stats.non_finite += 1;
            if stats.non_finite < 4 {
                eprintln!("{}: non-finite {full:?} for {ray:?}", stats.name);
            }
        }
        if !range.contains(raw.t) {
            stats.out_of_range += 1;
        }
    }
    if reference.margin < band {
        stats.banded += 1;
        return;
    }
    match (hit, reference.t) {
        (Some(raw), Some(t_ref)) => {
            let t_ref64 = t_ref.to_f64();
            let err = ((support::Dd::new(raw.t) - t_ref).to_f64() / t_ref64.abs().max(1e-300)).abs();
            stats.t_errors.push(err);
            let n = prim.normal_at(&ray, &raw);
            stats.normal_errors.push(support::angle(n, reference.normal));
        }
        (None, None) => {}
        _ => {
            stats.disagreements += 1;
            if stats.disagreements < 4 {
                eprintln!("{}: zeroset {hit:?} reference {reference:?} ray {ray:?}", stats.name);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sphere

#[test]
fn sphere_small_and_far() {
    // r = 10⁻³ at distance 10⁴…10⁵; rays from near the origin aimed within 1.2 r of the centre
    let mut rng = StdRng::seed_from_u64(1);
    let mut stats = Stats::new("sphere r=1e-3 at 1e4..1e5");
    for _ in 0..100_000 {
        let c = v32(random_unit(&mut rng) * log_uniform(&mut rng, 1e4, 1e5));
        let r = f(1e-3);
        let o = v32(DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ));
        let target = c + random_unit(&mut rng) * r * 1.2 * rng.random::<f64>().sqrt();
        let d = v32((target - o).normalize());
        let s = Sphere::new(c, r).unwrap();
        let reference = support::sphere(o, d, c, r, 0.0);
        book(&mut stats, &s, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    assert!(stats.hits > 50_000);
    // the normal is limited by t's own rounding (ε·10⁴ along the ray, over r = 10⁻³)
    stats.check(1e-15, 3e-8);
}

#[test]
fn sphere_huge_seen_from_close() {
    // r = 10⁴…10⁶ with the origin 10⁻³…1 above the surface: the near root c₀/q must keep its
    // precision (plain |f|² − r² loses r/(2h) ulp)
    let mut rng = StdRng::seed_from_u64(2);
    let mut stats = Stats::new("sphere r=1e4..1e6 from 1e-3..1 away");
    for _ in 0..100_000 {
        let r = f(log_uniform(&mut rng, 1e4, 1e6));
        let c = v32(DVec3::new(0.0, -r, 0.0));
        let h = log_uniform(&mut rng, 1e-3, 1.0);
        let o = v32(DVec3::new(rng.random_range(-1.0..1.0), h, rng.random_range(-1.0..1.0)));
        // downward-ish directions, including shallow ones
        let mut d = random_unit(&mut rng);
        d.y = -d.y.abs().max(1e-4);
        let d = v32(d);
        let s = Sphere::new(c, r).unwrap();
        let reference = support::sphere(o, d, c, r, 0.0);
        book(&mut stats, &s, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    // median ~1e-16; the maximum is set by the shallowest rays, whose near root is
    // ill-conditioned in the discriminant (an f64-rounded |f × d|² of size a·r² ≈ 10¹²)
    stats.check(1e-8, 1e-12);
}

#[test]
fn sphere_grazing_within_1e_6_of_tangency() {
    // impact parameter r·(1 ± δ), δ log-uniform in [10⁻¹⁴, 10⁻⁶]
    let mut rng = StdRng::seed_from_u64(3);
    let mut stats = Stats::new("sphere grazing |δ| ≤ 1e-6");
    for _ in 0..100_000 {
        let c = v32(random_unit(&mut rng) * rng.random_range(0.0..10.0));
        let r = f(log_uniform(&mut rng, 0.1, 10.0));
        let d = v32(random_unit(&mut rng));
        let side = d.any_orthonormal_vector();
        let delta = log_uniform(&mut rng, 1e-14, 1e-6) * if rng.random::<bool>() { 1.0 } else { -1.0 };
        let o = v32(c + side * r * (1.0 + delta) - d * rng.random_range(2.0..20.0) * r);
        let s = Sphere::new(c, r).unwrap();
        let reference = support::sphere(o, d, c, r, 0.0);
        book(&mut stats, &s, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    stats.check(1e-9, 1e-6);
}

#[test]
fn sphere_origin_inside() {
    let mut rng = StdRng::seed_from_u64(4);
    let mut stats = Stats::new("sphere origin inside");
    for _ in 0..50_000 {
        let c = v32(random_unit(&mut rng) * rng.random_range(0.0..100.0));
        let r = f(log_uniform(&mut rng, 1e-3, 1e3));
        let o = v32(c + random_unit(&mut rng) * r * rng.random::<f64>() * 0.999);
        let d = v32(random_unit(&mut rng));
        let s = Sphere::new(c, r).unwrap();
        let reference = support::sphere(o, d, c, r, 0.0);
        assert!(reference.t.is_some());
        book(&mut stats, &s, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    assert_eq!(
        stats.hits, stats.rays,
        "every ray from inside leaves through the sphere"
    );
    stats.check(1e-13, 1e-10);
}

// ---------------------------------------------------------------------------------------------
// Ellipsoid and transforms

#[test]
fn ellipsoid_radii_ratio_1e4() {
    let mut rng = StdRng::seed_from_u64(5);
    let mut stats = Stats::new("ellipsoid ratio 1e4");
    for i in 0..60_000 {
        let mut radii = DVec3::new(
            f(1e4 * rng.random_range(0.5..1.0)),
            f(rng.random_range(0.5..1.0)),
            f(rng.random_range(0.5..1.0)),
        );
        radii = match i % 3 {
            0 => radii,
            1 => DVec3::new(radii.y, radii.z, radii.x),
            _ => DVec3::new(radii.z, radii.x, radii.y),
        };
        let c = v32(random_unit(&mut rng) * 100.0);
        let e = Ellipsoid::new(c, radii, DQuat::IDENTITY).unwrap();
        // aim at points of (or near) the surface from up to 3·10⁴ away
        let s = random_unit(&mut rng) * rng.random_range(0.9..1.05);
        let target = c + radii * s;
        let o = v32(target + random_unit(&mut rng) * log_uniform(&mut rng, 1.0, 3e4));
        let d = v32((target - o).normalize());
        let reference = support::ellipsoid(o, d, c, radii, 0.0);
        book(&mut stats, &e, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    stats.check(1e-12, 1e-9);
}

#[test]
fn transformed_sphere_and_box_at_1e5_with_scales_1e_3_to_1e3() {
    let mut rng = StdRng::seed_from_u64(6);
    let mut sphere_stats = Stats::new("transformed sphere T=1e5 s=1e-3..1e3");
    let mut box_stats = Stats::new("transformed box T=1e5 s=1e-3..1e3");
    let unit_sphere = Sphere::new(DVec3::ZERO, 1.0).unwrap();
    let unit_box = Cuboid::new(DVec3::splat(-1.0), DVec3::new(1.0, 2.0, 0.5)).unwrap();
    for _ in 0..60_000 {
        let s = f(log_uniform(&mut rng, 1e-3, 1e3));
        let translation = v32(random_unit(&mut rng) * 1e5);
        let m = DAffine3::from_scale_rotation_translation(DVec3::splat(s), DQuat::IDENTITY, translation);
        let ts = Transformed::new(unit_sphere, m).unwrap();
        let tb = Transformed::new(unit_box, m).unwrap();
        let target = translation + random_unit(&mut rng) * s * rng.random_range(0.0..1.2);
        let o = v32(target + random_unit(&mut rng) * s * log_uniform(&mut rng, 2.0, 1e3));
        let d = v32((target - o).normalize());
        let ray = Ray::new(o, d);
        let reference = support::sphere(o, d, translation, s, 0.0);
        book(&mut sphere_stats, &ts, ray, Interval::POSITIVE, reference, 1e-9);
        let lo = (support::V::from(translation)).add(support::V::from(DVec3::splat(-1.0)).scale(support::Dd::new(s)));
        let hi =
            (support::V::from(translation)).add(support::V::from(DVec3::new(1.0, 2.0, 0.5)).scale(support::Dd::new(s)));
        let reference = support::cuboid(o, d, lo.to_f64(), hi.to_f64(), 0.0);
        book(&mut box_stats, &tb, ray, Interval::POSITIVE, reference, 1e-9);
    }
    // the world coordinates are 1e5 while the object is down to 1e-3: the transform's own
    // rounding (ε·1e5 ≈ 2e-11 absolute) dominates; t error relative to t ≥ 2e-3
    sphere_stats.check(1e-9, 1e-7);
    box_stats.check(1e-9, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Planar primitives

#[test]
fn plane_parallel_nearly_parallel_and_in_plane() {
    let mut rng = StdRng::seed_from_u64(7);
    let mut stats = Stats::new("plane nearly parallel 1e-12..1");
    let mut parallel_hits = 0;
    for _ in 0..60_000 {
        let n = v32(random_unit(&mut rng));
        let offset = f(rng.random_range(-100.0..100.0));
        let p = Plane::new(n, offset).unwrap();
        let o = v32(random_unit(&mut rng) * rng.random_range(0.0..1000.0));
        // a direction with ⟨d, n⟩ of relative size 1e-12…1
        let tangent = n.any_orthonormal_vector();
        let cos = log_uniform(&mut rng, 1e-12, 1.0) * if rng.random::<bool>() { 1.0 } else { -1.0 };
        let d = v32(tangent + cos * n);
        let reference = support::plane(o, d, n, offset, 0.0);
        book(&mut stats, &p, Ray::new(o, d), Interval::POSITIVE, reference, 1e-15);
        // exactly parallel: an axis-aligned plane and a direction with a zero component
        let axis_plane = Plane::new(DVec3::Y, offset).unwrap();
        let flat = DVec3::new(d.x, 0.0, d.z);
        if flat != DVec3::ZERO {
            let hit = axis_plane.intersect(&Ray::new(o, flat), Interval::POSITIVE);
            parallel_hits += usize::from(hit.is_some());
            // lying in the plane
            let in_plane = DVec3::new(o.x, offset, o.z);
            parallel_hits += usize::from(
                axis_plane
                    .intersect(&Ray::new(in_plane, flat), Interval::POSITIVE)
                    .is_some(),
            );
        }
    }
    assert_eq!(parallel_hits, 0, "parallel and in-plane rays miss (no NaN t)");
    stats.check(1e-13, 1e-15);
}

#[test]
fn disk_and_polygon_nearly_parallel() {
    let mut rng = StdRng::seed_from_u64(8);
    let mut disk_stats = Stats::new("disk nearly parallel");
    let mut poly_stats = Stats::new("polygon nearly parallel");
    let disk = Disk::new(DVec3::new(0.0, 1.0, 0.0), DVec3::Y, 1e3).unwrap();
    let square = Polygon::new(
        vec![
            DVec3::new(-1e3, 1.0, 1e3),
            DVec3::new(1e3, 1.0, 1e3),
            DVec3::new(1e3, 1.0, -1e3),
            DVec3::new(-1e3, 1.0, -1e3),
        ],
        vec![],
    )
    .unwrap();
    for _ in 0..60_000 {
        let o = v32(DVec3::new(
            rng.random_range(-10.0..10.0),
            rng.random_range(0.0..2.0),
            rng.random_range(-10.0..10.0),
        ));
        let tangent = DVec3::new(rng.random_range(-1.0..1.0), 0.0, rng.random_range(-1.0..1.0));
        let cos = log_uniform(&mut rng, 1e-6, 1.0) * (1.0 - o.y).signum();
        let d = v32(tangent + DVec3::new(0.0, cos, 0.0));
        let reference = support::plane(o, d, DVec3::Y, 1.0, 0.0);
        // inside the disk / square unless the hit is out past ~1e3
        let inside = |r: &Reference| {
            r.t.is_some_and(|t| {
                let p = o + t.to_f64() * d;
                p.x.hypot(p.z) < 0.999e3
            })
        };
        let on_rim = |r: &Reference| {
            r.t.is_some_and(|t| {
                let p = o + t.to_f64() * d;
                (p.x.hypot(p.z) - 1e3).abs() < 1.0 || (p.x.abs().max(p.z.abs()) - 1e3).abs() < 1.0
            })
        };
        let mut dr = reference;
        if !inside(&dr) {
            dr.t = None;
        }
        if on_rim(&reference) {
            dr.margin = 0.0;
        }
        book(&mut disk_stats, &disk, Ray::new(o, d), Interval::POSITIVE, dr, 1e-15);
        let mut pr = reference;
        let in_square = reference.t.is_some_and(|t| {
            let p = o + t.to_f64() * d;
            p.x.abs().max(p.z.abs()) < 1e3
        });
        if !in_square {
            pr.t = None;
        }
        if on_rim(&reference) {
            pr.margin = 0.0;
        }
        pr.normal = square.normal();
        book(&mut poly_stats, &square, Ray::new(o, d), Interval::POSITIVE, pr, 1e-15);
    }
    disk_stats.check(1e-13, 0.0);
    poly_stats.check(1e-13, 1e-15);
}

/// A closed, star-shaped mesh: an icosahedron subdivided once, vertices pushed to radius
/// 1 ± 0.1 at awkward coordinates, every other triangle's vertex list rotated.
fn closed_mesh(rng: &mut StdRng) -> (Vec<Triangle>, Vec<DVec3>, Vec<(DVec3, DVec3)>) {
    let (unit, fine) = zeroset_primitives::testing::icosphere(1);
    let center = DVec3::new(0.3, -0.2, 0.1);
    let verts: Vec<DVec3> = unit
        .iter()
        .map(|&v| v32(center + DVec3::from(v.map(f64::from)) * rng.random_range(0.9..1.1) * 1.37))
        .collect();
    let mut edges = Vec::new();
    let tris = fine
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let [a, b, c] = t.map(|i| i as usize);
            edges.extend([(verts[a], verts[b]), (verts[b], verts[c]), (verts[c], verts[a])]);
            let (a, b, c) = match k % 3 {
                0 => (a, b, c),
                1 => (b, c, a),
                _ => (c, a, b),
            };
            Triangle::new(verts[a], verts[b], verts[c]).unwrap()
        })
        .collect();
    (tris, verts, edges)
}

#[test]
fn triangle_mesh_is_watertight_at_shared_edges_and_vertices() {
    // 1M rays from inside the (star-shaped) mesh's kernel through shared edges and vertices:
    // each must cross the mesh exactly once (zero leaks, zero crossings at two distinct t)
    let mut rng = StdRng::seed_from_u64(9);
    let (mesh, verts, edges) = closed_mesh(&mut rng);
    let center = DVec3::new(0.3, -0.2, 0.1);
    let (mut leaks, mut doubles, mut rays) = (0usize, 0usize, 0usize);
    let bounds = Aabb::from_points(verts.iter().copied());
    let total = 1_000_000;
    for k in 0..total {
        let target = if k % 4 == 0 {
            verts[rng.random_range(0..verts.len())]
        } else {
            let (a, b) = edges[rng.random_range(0..edges.len())];
            // a point of the edge, rounded: on it up to rounding (the hard case)
            a + rng.random::<f64>() * (b - a)
        };
        let o = v32(center + random_unit(&mut rng) * rng.random_range(0.0..0.05));
        let ray = Ray::new(o, target - o);
        rays += 1;
        let mut ts: Vec<f64> = Vec::new();
        if bounds.clip(&ray, Interval::POSITIVE).is_some() {
            for tri in &mesh {
                if let Some(h) = tri.intersect(&ray, Interval::POSITIVE) {
                    ts.push(h.t);
                }
            }
        }
        if ts.is_empty() {
            leaks += 1;
            continue;
        }
        let (lo, hi) = ts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
        if hi - lo > 1e-9 * hi {
            doubles += 1;
        }
    }
    println!("[hard] triangle mesh watertight: {rays} rays at shared edges/vertices, leaks {leaks}, double crossings {doubles}");
    assert_eq!((leaks, doubles), (0, 0));
}

#[test]
fn sliver_and_degenerate_triangles() {
    // degenerate: valid but never hit (see triangle.rs); sliver (aspect 1e7): hits agree with the
    // plane reference
    assert!(Triangle::new(DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0))
        .unwrap()
        .is_degenerate());
    assert!(Triangle::new(DVec3::ZERO, DVec3::ZERO, DVec3::Y)
        .unwrap()
        .is_degenerate());
    assert!(Triangle::new(DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)).is_err());
    let mut rng = StdRng::seed_from_u64(10);
    let mut stats = Stats::new("sliver triangle aspect 1e5..1e7");
    for _ in 0..50_000 {
        let len = f(log_uniform(&mut rng, 1.0, 1e3));
        let width = f(len * log_uniform(&mut rng, 1e-7, 1e-5));
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 2.0),
            DVec3::new(len, 0.0, 2.0),
            DVec3::new(0.5 * len, width, 2.0),
        );
        let tri = Triangle::new(a, b, c).unwrap();
        // aim at interior points (barycentrics ≥ 0.05) from above/below, oblique
        let (u, v) = (rng.random_range(0.05..0.9), rng.random_range(0.05..0.9));
        let (u, v) = if u + v > 0.95 { (0.95 - v, 0.95 - u) } else { (u, v) };
        let target = a + u * (b - a) + v * (c - a);
        let o = v32(target
            + DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(0.2..3.0) * if rng.random::<bool>() { 1.0 } else { -1.0 },
            ));
        let d = target - o;
        let mut reference = support::plane(o, d, DVec3::Z, 2.0, 0.0);
        reference.margin = 1.0;
        book(&mut stats, &tri, Ray::new(o, d), Interval::POSITIVE, reference, 0.0);
    }
    stats.check(1e-15, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Box

#[test]
fn box_face_planes_edges_corners_and_signed_zeros() {
    let mut rng = StdRng::seed_from_u64(11);
    let mut stats = Stats::new("box face planes/edges/corners/±0");
    let mut exact_edges = 0;
    for i in 0..100_000 {
        let lo = v32(random_unit(&mut rng) * 10.0);
        let hi = lo
            + v32(DVec3::new(
                rng.random_range(0.01..5.0),
                rng.random_range(0.01..5.0),
                rng.random_range(0.01..5.0),
            ));
        let hi = v32(hi);
        let b = Cuboid::new(lo, hi).unwrap();
        let pick = |rng: &mut StdRng, axis: usize| match rng.random_range(0..4) {
            0 => lo[axis],
            1 => hi[axis],
            _ => f(rng.random_range(lo[axis]..hi[axis])),
        };
        // a target on an edge or corner (or a face)
        let target = DVec3::new(pick(&mut rng, 0), pick(&mut rng, 1), pick(&mut rng, 2));
        let mut o = v32(target + random_unit(&mut rng) * rng.random_range(0.5..20.0));
        let mut d = v32(target - o);
        match i % 4 {
            // a zero (±0) component: the origin shares that coordinate with the target, which may
            // be a face plane
            0 => {
                let axis = rng.random_range(0..3);
                o[axis] = target[axis];
                d[axis] = if rng.random::<bool>() { 0.0 } else { -0.0 };
            }
            // a tiny component: 1e-11 (POV-Ray treats it as parallel and misses)
            1 => {
                let axis = rng.random_range(0..3);
                d[axis] = 1e-11 * d[axis].signum();
            }
            _ => {}
        }
        if d == DVec3::ZERO {
            continue;
        }
        let reference = support::cuboid(o, d, lo, hi, 0.0);
        exact_edges += usize::from(reference.margin == 0.0);
        book(&mut stats, &b, Ray::new(o, d), Interval::POSITIVE, reference, 1e-15);
    }
    println!("[hard] box: {exact_edges} rays exactly grazing an edge/corner/face (banded)");
    stats.check(2.0 * f64::EPSILON, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Cylinder and cone (axis Z, so the reference's frame is exact)

fn cone_case(
    name: &str,
    seed: u64,
    r0: f64,
    r1: f64,
    capped: bool,
    rays: impl Fn(&mut StdRng, f64, f64, f64) -> (DVec3, DVec3),
) -> Stats {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut stats = Stats::new(name);
    for _ in 0..40_000 {
        let scale = f(log_uniform(&mut rng, 1e-2, 1e2));
        let base = v32(random_unit(&mut rng) * 10.0);
        let (r0, r1, h) = (f(r0 * scale), f(r1 * scale), f(scale * 2.0));
        let prim: Box<dyn Primitive> = if r0 == r1 {
            Box::new(Cylinder::new(base, DVec3::Z, r0, h, capped).unwrap())
        } else {
            Box::new(Cone::new(base, DVec3::Z, r0, r1, h, capped).unwrap())
        };
        let (o, d) = rays(&mut rng, r0.max(r1), h, scale);
        let (o, d) = (v32(base + o), v32(d));
        if d == DVec3::ZERO {
            continue;
        }
        let reference = support::cone_z(o, d, base, r0, r1, h, capped, 0.0);
        book(&mut stats, &*prim, Ray::new(o, d), Interval::POSITIVE, reference, 1e-12);
    }
    stats
}

#[test]
fn cylinder_rays_along_the_axis() {
    let axis_rays = |rng: &mut StdRng, r: f64, h: f64, _s: f64| {
        // parallel to the axis, radial offset within 1e-8 relative of the rim on either side
        let rho = r * (1.0 + log_uniform(rng, 1e-15, 1e-8) * if rng.random::<bool>() { 1.0 } else { -1.0 });
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let up = rng.random::<bool>();
        let z = if up { -h } else { 2.0 * h };
        (
            DVec3::new(rho * a.cos(), rho * a.sin(), z),
            if up { DVec3::Z } else { -DVec3::Z },
        )
    };
    for capped in [true, false] {
        let stats = cone_case(
            if capped {
                "cylinder axis-parallel at rim ±1e-8"
            } else {
                "tube axis-parallel at rim ±1e-8"
            },
            12,
            1.0,
            1.0,
            capped,
            axis_rays,
        );
        stats.check(2.0 * f64::EPSILON, 0.0);
        if capped {
            assert!(stats.hits > 10_000, "axis-parallel rays inside the rim hit the cap");
        }
    }
}

#[test]
fn cylinder_and_cone_through_the_cap_rim() {
    let rim_rays = |rng: &mut StdRng, r: f64, h: f64, s: f64| {
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let z = if rng.random::<bool>() { 0.0 } else { h };
        let target = DVec3::new(r * a.cos(), r * a.sin(), z) * (1.0 + rng.random_range(-1e-3..1e-3));
        let o = target + random_unit(rng) * s * rng.random_range(1.0..10.0);
        (o, target - o)
    };
    for (name, r0, r1) in [("cylinder through rim", 1.0, 1.0), ("frustum through rim", 1.0, 0.5)] {
        let stats = cone_case(name, 13, r0, r1, true, rim_rays);
        stats.check(1e-9, 1e-7);
    }
}

#[test]
fn cone_through_the_apex_and_parallel_to_the_side() {
    // apex at (0, 0, h): rays aimed exactly at it from above, inside the cone's solid angle
    let mut rng = StdRng::seed_from_u64(14);
    let mut apex_stats = Stats::new("cone through apex");
    for _ in 0..20_000 {
        let (r, h) = (f(log_uniform(&mut rng, 0.1, 10.0)), f(log_uniform(&mut rng, 0.1, 10.0)));
        let cone = Cone::new(DVec3::ZERO, DVec3::Z, r, 0.0, h, rng.random::<bool>()).unwrap();
        let apex = DVec3::new(0.0, 0.0, h);
        // from above, within the half-angle of the upward nappe's mirror: the ray enters the cone
        let half = (r / h).atan() * 0.9;
        let (th, ph) = (
            rng.random_range(0.0..half),
            rng.random_range(0.0..std::f64::consts::TAU),
        );
        let w = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
        let o = v32(apex + w * rng.random_range(0.1..10.0));
        let d = apex - o;
        let ray = Ray::new(o, d);
        let hit = cone.intersect(&ray, Interval::POSITIVE);
        let reference = Reference {
            t: Some(support::Dd::new(1.0)),
            normal: DVec3::Z,
            margin: 1.0,
        };
        book(&mut apex_stats, &cone, ray, Interval::POSITIVE, reference, 0.0);
        assert!(hit.is_some());
    }
    // the apex normal is +axis by definition (the limit of the side normal is undefined there)
    apex_stats.check(2.0 * f64::EPSILON, 0.0);

    let side_rays = |rng: &mut StdRng, r: f64, h: f64, _s: f64| {
        // parallel to a generator: direction (−r·cos a, −r·sin a, h), origin anywhere near
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let d = DVec3::new(-r * a.cos(), -r * a.sin(), h);
        let shift = DVec3::new(a.cos(), a.sin(), 0.0) * r * rng.random_range(-0.8..0.8) + random_unit(rng) * 0.05 * r;
        (DVec3::new(r * a.cos(), r * a.sin(), 0.0) + shift - d, d)
    };
    for capped in [true, false] {
        let stats = cone_case(
            if capped {
                "cone parallel to a side line"
            } else {
                "open cone parallel to a side line"
            },
            15,
            1.0,
            0.0,
            capped,
            side_rays,
        );
        stats.check(1e-12, 1e-9);
    }
}

// ---------------------------------------------------------------------------------------------
// Polygons: exact point-in-polygon at vertices, on edges, collinear vertices, touching holes

#[test]
fn polygons_sharing_edges_claim_each_point_once() {
    // a 6×6 square split along a zig-zag with collinear vertices into two polygons; the second
    // has a hole touching its outer boundary at a vertex and along an edge. Every grid point
    // (vertices, edge points, hole corners) at spacing 1/4 is claimed by exactly one of the
    // pieces or lies in the hole, and the hole's points by none.
    let z = 0.5;
    let p = |x: f64, y: f64| DVec3::new(x, y, z);
    let zig = [
        p(3.0, 0.0),
        p(3.0, 1.0),
        p(2.0, 2.0),
        p(3.0, 3.0),
        p(3.0, 4.0),
        p(3.0, 5.0),
        p(3.0, 6.0),
    ];
    let mut left = vec![p(0.0, 0.0)];
    left.extend(zig.iter().copied());
    left.push(p(0.0, 6.0));
    // right ring: (3,0) → (6,0) → (6,6) → the zig-zag back down; counter-clockwise
    let mut right = vec![p(3.0, 0.0), p(6.0, 0.0), p(6.0, 6.0)];
    right.extend(zig.iter().rev().take(zig.len() - 1).copied());
    let hole = vec![p(4.0, 2.0), p(6.0, 2.0), p(6.0, 3.0), p(4.0, 3.0)];
    let left = Polygon::new(left, vec![]).unwrap();
    let right = Polygon::new(right, vec![hole]).unwrap();
    let (mut claimed_twice, mut unclaimed, mut points) = (0, 0, 0);
    for i in 1..24 {
        for j in 1..24 {
            let (x, y) = (f64::from(i) * 0.25, f64::from(j) * 0.25);
            let ray = Ray::new(DVec3::new(x, y, 2.0), -DVec3::Z);
            let n = usize::from(left.intersect(&ray, Interval::POSITIVE).is_some())
                + usize::from(right.intersect(&ray, Interval::POSITIVE).is_some());
            // in the hole by the same ε-perturbation rule: x + ε, y + ε²
            let in_hole = (4.0..6.0).contains(&x) && (2.0..3.0).contains(&y);
            points += 1;
            match (n, in_hole) {
                (0, false) => unclaimed += 1,
                (2, _) => claimed_twice += 1,
                (1, true) => claimed_twice += 1,
                _ => {}
            }
        }
    }
    println!("[hard] polygons sharing a zig-zag edge with a touching hole: {points} grid points, unclaimed {unclaimed}, claimed twice {claimed_twice}");
    assert_eq!((unclaimed, claimed_twice), (0, 0));
}

// ---------------------------------------------------------------------------------------------
// Generic root finder

#[derive(Debug)]
struct Slab {
    half: f64,
    declared: f64,
}

impl Implicit for Slab {
    fn phi(&self, p: DVec3) -> f64 {
        p.z.abs() - self.half
    }
    fn bounds(&self) -> Aabb {
        Aabb::new(DVec3::new(-10.0, -10.0, -self.half), DVec3::new(10.0, 10.0, self.half))
    }
    fn lipschitz(&self) -> Option<f64> {
        Some(self.declared)
    }
}

impl Intersect for Slab {}

#[derive(Debug)]
struct Steep {
    sphere: Sphere,
    gain: f64,
    declared: f64,
}

impl Implicit for Steep {
    fn phi(&self, p: DVec3) -> f64 {
        self.gain * self.sphere.phi(p)
    }
    fn bounds(&self) -> Aabb {
        self.sphere.bounds()
    }
    fn lipschitz(&self) -> Option<f64> {
        Some(self.declared)
    }
}

impl Intersect for Steep {}

#[test]
fn root_finder_thin_slab_and_tangential_hits() {
    let mut rng = StdRng::seed_from_u64(16);
    // a slab 1e-6 thick (10 × the default tolerance), oblique rays: every one must be found
    let slab = Slab {
        half: 5e-7,
        declared: 1.0,
    };
    let mut lost = 0;
    let mut worst = 0.0f64;
    for _ in 0..2_000 {
        let o = DVec3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(0.5..5.0),
        );
        let target = DVec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), 0.0);
        let d = (target - o).normalize();
        match slab.intersect(&Ray::new(o, d), Interval::POSITIVE) {
            Some(h) => worst = worst.max(((o.z - 5e-7) / -d.z - h.t).abs()),
            None => lost += 1,
        }
    }
    println!("[hard] root finder thin slab 1e-6: lost {lost}/2000, max |t − t_exact| {worst:.2e}");
    assert_eq!(lost, 0);
    assert!(worst <= 1e-7);
    // tangential: a sphere through the generic finder on rays with impact parameter r(1 − δ);
    // crossings longer than the tolerance are found
    let sphere = Steep {
        sphere: Sphere::new(DVec3::ZERO, 1.0).unwrap(),
        gain: 1.0,
        declared: 1.0,
    };
    let (mut found, mut expected) = (0, 0);
    for k in 0..2_000 {
        let delta = 10f64.powf(-2.0 - 10.0 * f64::from(k) / 2000.0);
        let o = DVec3::new(1.0 - delta, 0.0, -3.0);
        let chord = 2.0 * (1.0 - (1.0 - delta) * (1.0 - delta)).sqrt();
        let ray = Ray::new(o, DVec3::Z);
        let hit = sphere.intersect(&ray, Interval::POSITIVE);
        if chord > 2e-7 {
            expected += 1;
            found += usize::from(hit.is_some());
        }
        if let Some(h) = hit {
            assert!(
                h.t.is_finite() && (h.t - (3.0 - chord / 2.0)).abs() < 1e-6,
                "δ {delta:e}: {h:?}"
            );
        }
    }
    println!("[hard] root finder tangential: found {found}/{expected} chords longer than 2e-7");
    assert_eq!(found, expected);
}

#[test]
fn root_finder_reports_a_too_small_lipschitz_bound() {
    // Φ = 10·(|p| − 1) declared 1-Lipschitz (true bound 10): compare with the true bound
    let mut rng = StdRng::seed_from_u64(17);
    let wrong = Steep {
        sphere: Sphere::new(DVec3::ZERO, 1.0).unwrap(),
        gain: 10.0,
        declared: 1.0,
    };
    let right = Steep {
        sphere: Sphere::new(DVec3::ZERO, 1.0).unwrap(),
        gain: 10.0,
        declared: 10.0,
    };
    let before = root::lipschitz_violations();
    let (mut true_hits, mut lost, mut lost_silently, mut flagged) = (0, 0, 0, 0);
    for _ in 0..5_000 {
        let o = random_unit(&mut rng) * rng.random_range(1.5..6.0);
        let d = (random_unit(&mut rng) * rng.random_range(0.0..1.3) - o).normalize();
        let ray = Ray::new(o, d);
        let truth = first_root(&right, &ray, Interval::POSITIVE, &RootOptions::default());
        let report = first_root(&wrong, &ray, Interval::POSITIVE, &RootOptions::default());
        flagged += usize::from(report.lipschitz_violated);
        if truth.hit.is_some() {
            true_hits += 1;
            if report.hit.is_none() {
                lost += 1;
                lost_silently += usize::from(!report.lipschitz_violated);
            }
        }
    }
    let counted = root::lipschitz_violations() - before;
    println!("[hard] root finder wrong Lipschitz (declared 1, true 10): {true_hits} true hits, lost {lost} (silently {lost_silently}), flagged {flagged} rays, counter +{counted}");
    assert_eq!(lost_silently, 0, "a lost surface is always reported");
    assert!(flagged > 0 && counted >= flagged as u64);
}

// ---------------------------------------------------------------------------------------------
// Invalid input

#[test]
fn non_finite_parameters_are_rejected_at_construction() {
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    assert!(Sphere::new(DVec3::new(nan, 0.0, 0.0), 1.0).is_err());
    assert!(Sphere::new(DVec3::ZERO, inf).is_err());
    assert!(Plane::new(DVec3::new(0.0, inf, 0.0), 1.0).is_err());
    assert!(Plane::new(DVec3::Y, nan).is_err());
    assert!(Disk::new(DVec3::ZERO, DVec3::Y, nan).is_err());
    assert!(Cuboid::new(DVec3::ZERO, DVec3::splat(inf)).is_err());
    assert!(Cylinder::new(DVec3::ZERO, DVec3::Z, 1.0, nan, true).is_err());
    assert!(Cone::new(DVec3::ZERO, DVec3::new(nan, 0.0, 1.0), 1.0, 0.0, 1.0, true).is_err());
    assert!(Ellipsoid::new(DVec3::ZERO, DVec3::new(1.0, inf, 1.0), DQuat::IDENTITY).is_err());
    assert!(Polygon::new(vec![DVec3::ZERO, DVec3::X, DVec3::new(0.0, nan, 0.0)], vec![]).is_err());
    let s = Sphere::new(DVec3::ZERO, 1.0).unwrap();
    assert!(Transformed::new(s, DAffine3::from_translation(DVec3::new(inf, 0.0, 0.0))).is_err());
    assert!(Transformed::new(s, DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0))).is_err());
    let _ = (Arc::new(s), DVec2::ZERO, F32_ULP);
}

// ---------------------------------------------------------------------------------------------
// Re-casting from hit points (the offset policy of `zeroset_primitives::offset`)

/// Whether Φ confirms that the ray from `origin` along `dir` really reaches the side opposite
/// to `arrival` (the sign of Φ on the side the secondary ray starts on) somewhere on
/// `origin + s·dir`, `s ∈ {hi, hi·(1 + 2⁻ᵏ), …}` for a re-hit (`after = true`: just beyond
/// `hi`) or `s ∈ {hi·2⁻ᵏ}` (`after = false`: before `hi`), at a point that belongs to the
/// surface's region ([`Implicit::within_boundary`]; planar shapes restrict their plane there).
/// Φ is the implicit definition of the surface, independent of the intersector; a point counts
/// only where Φ is strictly of the other sign.
fn crosses(prim: &dyn Primitive, origin: DVec3, dir: DVec3, arrival: f64, hi: f64, after: bool) -> bool {
    (0..=40).any(|k| {
        let step = 0.5f64.powi(k);
        let s = if after { hi * (1.0 + step) } else { hi * step };
        let q = origin + s * dir;
        prim.phi(q) * arrival < 0.0 && prim.within_boundary(q)
    })
}

/// Per-shape counts of [`recast`].
#[derive(Default, Debug)]
struct Recast {
    /// Outward (leaving) rays re-cast.
    out: usize,
    /// Leaving rays that hit the surface again where Φ shows no crossing: the self-hits.
    self_hits: usize,
    /// Leaving rays that hit the surface again at a crossing Φ confirms (a chord through a
    /// concave side, another part of a non-convex shape).
    genuine: usize,
    /// Secondary origins not strictly on the arrival side by Φ.
    wrong_side: usize,
    /// Entering rays re-cast.
    inward: usize,
    /// Entering rays that missed (or hit beyond `4δ/|cos|`) although Φ confirms they cross.
    missed: usize,
    /// Entering rays that do not cross within `4δ/|cos|` by Φ: they pass over an edge or rim
    /// (the edge band), so a miss is right.
    edge_band: usize,
}

/// Fires primary rays at `prim` (aimed at `targets` from `eye`s), then from each hit's
/// `secondary_origin` re-casts one ray leaving towards the arrival side (any direction with
/// `cos ≥ 1e-6` to the facing normal, tangent ones included) and, every fifth hit, one crossing
/// the surface (`cos ≤ −band`).
///
/// A re-hit of a leaving ray is a **self-hit** unless Φ confirms a real crossing just beyond it
/// ([`crosses`]); rays from inside a closed shape legitimately meet its far side, at a chord
/// `2R·cos` that can be shorter than any fixed distance threshold. An entering ray must hit
/// within `4δ/|cos|`; if it does not, it counts as **missed** only where Φ confirms that it
/// crosses the surface within that distance (otherwise it passes over an edge or rim).
fn recast(prim: &dyn Primitive, rng: &mut StdRng, rays: usize, aim: &dyn Fn(&mut StdRng) -> Ray) -> Recast {
    let debug = std::env::var_os("ZS_DEBUG").is_some();
    let mut r = Recast::default();
    let mut attempts = 0;
    while r.out < rays && attempts < 20 * rays {
        attempts += 1;
        let ray = aim(rng);
        let Some(raw) = prim.intersect(&ray, Interval::POSITIVE) else {
            continue;
        };
        let hit = SurfaceHit::complete(prim, &ray, &raw, HitRequest::ALL);
        let n = hit.facing_normal(ray.dir).unwrap();
        // the sign of Φ on the side the secondary rays start on
        let arrival = if n.dot(hit.normal.unwrap()) > 0.0 { 1.0 } else { -1.0 };
        let origin = hit.secondary_origin(ray.dir);
        let side = prim.phi(origin) * arrival;
        if side <= 0.0 || side.is_nan() {
            r.wrong_side += 1;
        }
        // leaving: cos log-uniform in [1e-6, 1]
        let cos = log_uniform(rng, 1e-6, 1.0);
        let tangent = (random_unit(rng) - n * n.dot(random_unit(rng)))
            .cross(n)
            .normalize_or_zero();
        let tangent = if tangent == DVec3::ZERO {
            n.any_orthonormal_vector()
        } else {
            tangent
        };
        let dir = (n * cos + tangent * (1.0 - cos * cos).sqrt()).normalize();
        r.out += 1;
        if let Some(h) = prim.intersect(&Ray::new(origin, dir), Interval::POSITIVE) {
            if crosses(prim, origin, dir, arrival, h.t, true) {
                r.genuine += 1;
            } else {
                r.self_hits += 1;
                if debug {
                    eprintln!(
                        "SELF {prim:?}\n  ray {ray:?} raw {raw:?}\n  point {:?} n {n:?} err {:e}\n  origin {origin:?} dir {dir:?} cos {cos:e} h {h:?}\n  phi(point) {:e} phi(origin) {:e}",
                        hit.point, hit.error, prim.phi(hit.point), prim.phi(origin)
                    );
                }
            }
        }
        if r.out % 5 == 0 {
            // a ray entering a curved surface from height δ can miss it below sin α = √(2δ/R):
            // the band is 10·√(δ/size) (and at least 1e-3)
            let size = prim.bounds().diagonal_length();
            let band = if size.is_finite() {
                (10.0 * (hit.error / size).sqrt()).max(1e-3)
            } else {
                1e-3
            };
            let cos = -log_uniform(rng, band.min(0.5), 1.0);
            let dir = (n * cos + tangent * (1.0 - cos * cos).sqrt()).normalize();
            r.inward += 1;
            let limit = 4.0 * hit.error / cos.abs() + 1e-300;
            match prim.intersect(&Ray::new(origin, dir), Interval::POSITIVE) {
                Some(h) if h.t <= limit => {}
                _ if !crosses(prim, origin, dir, arrival, limit, false) => r.edge_band += 1,
                other => {
                    r.missed += 1;
                    if debug {
                        eprintln!(
                            "MISS {prim:?}\n  ray {ray:?} raw {raw:?}\n  point {:?} n {n:?} err {:e}\n  origin {origin:?} dir {dir:?} cos {cos:e} got {other:?} limit {limit:e}\n  phi(point) {:e} phi(origin) {:e}",
                            hit.point, hit.error, prim.phi(hit.point), prim.phi(origin)
                        );
                    }
                }
            }
        }
    }
    r
}

#[test]
fn recast_from_hit_points_never_self_hits_and_never_misses_entering() {
    let mut rng = StdRng::seed_from_u64(18);
    let aim_at = |bounds: Aabb, shrink: f64| {
        move |rng: &mut StdRng| {
            let c = bounds.center();
            let e = bounds.extent() * 0.5 * shrink;
            let target = c + e * DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let o = target + random_unit(rng) * bounds.diagonal_length().max(1e-300) * rng.random_range(0.6..3.0);
            Ray::new(o, (target - o).normalize())
        }
    };
    let quat = DQuat::from_axis_angle(DVec3::new(0.3, -1.0, 0.5).normalize(), 0.7);
    let mut shapes = support::one_of_each_builtin();
    shapes.insert(
        1,
        (
            "Sphere r=1e-3 at 1e4",
            Arc::new(Sphere::new(DVec3::new(1e4, 0.0, 0.0), 1e-3).unwrap()),
            0.9,
        ),
    );
    let mut all = shapes.clone();
    for (name, prim, shrink) in &shapes {
        for s in [1e-3, 1.0, 1e3] {
            let m = DAffine3::from_scale_rotation_translation(
                DVec3::new(s, s * 1.3, s * 0.8),
                quat,
                DVec3::new(1e5, -3e4, 7e4),
            );
            let t: Arc<dyn Primitive> = Arc::new(Transformed::new(prim.clone(), m).unwrap());
            all.push((
                Box::leak(format!("T(1e5, s={s:e}) {name}").into_boxed_str()),
                t,
                *shrink,
            ));
        }
    }
    let csg: Arc<dyn Primitive> = Arc::new(
        Csg::new(
            CsgOp::Union,
            vec![
                shapes[0].1.clone(),
                Arc::new(Sphere::new(DVec3::new(2.0, 2.0, 3.0), 1.2).unwrap()),
            ],
        )
        .unwrap(),
    );
    all.push(("Csg union", csg, 0.9));
    let mut total = (0, 0, 0, 0, 0);
    for (name, prim, shrink) in &all {
        let bounds = prim.bounds();
        let bounds = if bounds.is_finite() {
            bounds
        } else {
            Aabb::new(DVec3::splat(-2.0), DVec3::splat(2.0))
        };
        let aim = aim_at(bounds, *shrink);
        let rays = if name.starts_with("T(") { 34_000 } else { 100_000 };
        let r = recast(&**prim, &mut rng, rays, &aim);
        println!(
            "[hard] recast {name:<34} outward {:>7} self-hits {} (genuine re-hits {}) wrong-side {} | entering {:>6} missed {} (edge band {})",
            r.out, r.self_hits, r.genuine, r.wrong_side, r.inward, r.missed, r.edge_band
        );
        assert!(r.out >= rays, "{name}: too few primary hits");
        total.0 += r.out;
        total.1 += r.self_hits;
        total.2 += r.wrong_side;
        total.3 += r.inward;
        total.4 += r.missed;
    }
    println!(
        "[hard] recast total outward {} self-hits {} wrong-side {} | entering {} missed {}",
        total.0, total.1, total.2, total.3, total.4
    );
    assert_eq!(
        (total.1, total.2, total.4),
        (0, 0, 0),
        "self-hits, wrong-side origins, missed entries"
    );
}
