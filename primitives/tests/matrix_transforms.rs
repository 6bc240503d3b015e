//! General affine transforms (`matrix:` in RON: any invertible linear part, mirrors and shears
//! included) give the hits the same primitive's closed form in **world space** gives.
//!
//! - Boxes under the 48 signed axis permutations (with dyadic translations): `t` **bit for bit**
//!   equal to the world-space axis-aligned box.
//! - A mirrored + sheared + rotated box against its 12 world-space triangles (the watertight
//!   triangle test on the transformed corners): same hit/miss, `t` to `10⁻¹²` relative, normals
//!   pointing out of the world box.
//! - A mirrored + sheared cylinder against the world-space quadric `(p−T)ᵀQ(p−T) = r²`,
//!   `Q = Aᵀ·diag(1, 0, 1)·A`, `A = W⁻¹` (lateral) and the cap planes: `t` to `10⁻⁹`, normals
//!   parallel to the world gradient `2Q(p−T)` and pointing out.
//! - A mirrored mesh against world-space triangles of its transformed vertices.

use glam::{DAffine3, DMat3, DQuat, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use zeroset_primitives::testing::random_unit;
use zeroset_primitives::*;

fn transformed<P>(p: P, m: DAffine3) -> Transformed<P> {
    Transformed::new(p, m).unwrap()
}

/// Every 3×3 signed permutation matrix (48, half of them mirrors).
fn signed_permutations() -> Vec<DMat3> {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut out = Vec::new();
    for p in perms {
        for signs in 0..8 {
            let mut cols = [DVec3::ZERO; 3];
            for (i, &j) in p.iter().enumerate() {
                let s = if signs & (1 << i) != 0 { -1.0 } else { 1.0 };
                cols[i][j] = s;
            }
            out.push(DMat3::from_cols(cols[0], cols[1], cols[2]));
        }
    }
    out
}

fn f32_exact(v: DVec3) -> DVec3 {
    DVec3::new(f64::from(v.x as f32), f64::from(v.y as f32), f64::from(v.z as f32))
}

#[test]
fn boxes_under_axis_permutations_are_bit_exact() {
    let (lo, hi) = (DVec3::new(-1.0, -0.5, 0.25), DVec3::new(0.75, 1.5, 2.0));
    let local = Cuboid::new(lo, hi).unwrap();
    let translation = DVec3::new(0.5, -1.25, 3.0);
    let mut rng = StdRng::seed_from_u64(21);
    let (mut rays, mut hits, mut normals_ok) = (0, 0, 0);
    for m in signed_permutations() {
        let w = DAffine3::from_mat3_translation(m, translation);
        let a = m * lo + translation;
        let b = m * hi + translation;
        let world = Cuboid::new(a.min(b), a.max(b)).unwrap();
        let placed = transformed(local, w);
        for _ in 0..2000 {
            let target =
                world.bounds().center() + f32_exact(DVec3::new(rng.random(), rng.random(), rng.random()) * 3.0 - 1.5);
            let origin = f32_exact(target + random_unit(&mut rng) * 6.0);
            let ray = Ray::new(origin, f32_exact(target - origin));
            rays += 1;
            let got = placed.intersect(&ray, Interval::POSITIVE);
            let expected = world.intersect(&ray, Interval::POSITIVE);
            assert_eq!(got.map(|h| h.t), expected.map(|h| h.t), "matrix {m} ray {ray:?}");
            if let (Some(g), Some(e)) = (got, expected) {
                hits += 1;
                let (ng, ne) = (placed.normal_at(&ray, &g), world.normal_at(&ray, &e));
                assert_eq!(ng, ne, "normal under {m}");
                normals_ok += 1;
            }
        }
    }
    println!("[matrix] boxes under 48 signed permutations: {rays} rays, {hits} hits, t and normals bit-identical ({normals_ok})");
    assert!(hits > 30_000);
}

/// A mirror composed with a shear and a rotation (determinant < 0).
fn mirrored_shear() -> DAffine3 {
    let shear = DMat3::from_cols(
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.7, 1.0, 0.0),
        DVec3::new(-0.3, 0.4, 1.2),
    );
    let mirror = DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0));
    let rotation = DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(0.2, 1.0, -0.5).normalize(), 0.9));
    DAffine3::from_mat3_translation(rotation * mirror * shear, DVec3::new(3.0, -1.0, 2.0))
}

#[test]
fn mirrored_sheared_box_matches_its_world_triangles() {
    let (lo, hi) = (DVec3::new(-1.0, -0.5, 0.25), DVec3::new(0.75, 1.5, 2.0));
    let w = mirrored_shear();
    assert!(w.matrix3.determinant() < 0.0);
    let placed = transformed(Cuboid::new(lo, hi).unwrap(), w);
    let corner = |i: usize| {
        w.transform_point3(DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        ))
    };
    let quads = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    let triangles: Vec<Triangle> = quads
        .iter()
        .flat_map(|q| {
            [
                Triangle::new(corner(q[0]), corner(q[1]), corner(q[2])).unwrap(),
                Triangle::new(corner(q[0]), corner(q[2]), corner(q[3])).unwrap(),
            ]
        })
        .collect();
    let centre = w.transform_point3(0.5 * (lo + hi));
    let mut rng = StdRng::seed_from_u64(22);
    let (mut hits, mut worst) = (0, 0.0f64);
    for _ in 0..50_000 {
        let target = centre + random_unit(&mut rng) * rng.random_range(0.0..2.5);
        let origin = target + random_unit(&mut rng) * 8.0;
        let ray = Ray::new(origin, (target - origin).normalize());
        let reference = triangles
            .iter()
            .filter_map(|t| t.intersect(&ray, Interval::POSITIVE).map(|h| (h.t, t.normal())))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let got = placed.intersect(&ray, Interval::POSITIVE);
        match (got, reference) {
            (Some(g), Some((t, face))) => {
                hits += 1;
                worst = worst.max((g.t - t).abs() / t);
                let n = placed.normal_at(&ray, &g);
                let p = ray.at(g.t);
                assert!((n.dot(face).abs() - 1.0).abs() < 1e-9, "normal {n} vs face {face}");
                assert!(n.dot(p - centre) > 0.0, "normal points out of the world box");
            }
            (None, None) => {}
            // a ray through an edge within rounding may be decided differently
            (g, r) => {
                let t = g.map(|h| h.t).or(r.map(|r| r.0)).unwrap();
                let p = ray.at(t);
                let near_edge = triangles.iter().any(|tri| {
                    let l = tri.barycentric(p);
                    l.min_element().abs() < 1e-9
                });
                assert!(
                    near_edge,
                    "hit/miss disagreement away from edges: {g:?} vs {r:?} ray {ray:?}"
                );
            }
        }
    }
    println!("[matrix] mirrored sheared box vs world triangles: {hits} hits, max rel |Δt| {worst:e}");
    assert!(hits > 20_000 && worst < 1e-12, "{hits} {worst:e}");
}

/// World-space closed form of a cylinder (base 0, axis y, radius r, height H, capped) under `w`.
fn world_cylinder(w: &DAffine3, r: f64, height: f64, ray: &Ray) -> Option<(f64, DVec3)> {
    let a = w.matrix3.inverse();
    let q = a.transpose() * DMat3::from_diagonal(DVec3::new(1.0, 0.0, 1.0)) * a;
    let rel = ray.origin - w.translation;
    let (qa, qb, qc) = (
        ray.dir.dot(q * ray.dir),
        2.0 * ray.dir.dot(q * rel),
        rel.dot(q * rel) - r * r,
    );
    let axial = |p: DVec3| (a * (p - w.translation)).y;
    let mut candidates = Vec::new();
    let disc = qb * qb - 4.0 * qa * qc;
    if disc >= 0.0 && qa != 0.0 {
        let s = disc.sqrt();
        let q1 = -0.5 * (qb + s.copysign(qb));
        for t in [q1 / qa, qc / q1] {
            let p = ray.at(t);
            if t >= 0.0 && (0.0..=height).contains(&axial(p)) {
                candidates.push((t, (q * (p - w.translation)).normalize()));
            }
        }
    }
    // caps: the axial coordinate (row 1 of A) equal to 0 or H
    let row = a.row(1);
    for (level, sign) in [(0.0, -1.0), (height, 1.0)] {
        let denom = row.dot(ray.dir);
        if denom != 0.0 {
            let t = (level - row.dot(rel)) / denom;
            let p = ray.at(t);
            let l = a * (p - w.translation);
            if t >= 0.0 && l.x * l.x + l.z * l.z <= r * r {
                candidates.push((t, (sign * row).normalize()));
            }
        }
    }
    candidates.into_iter().min_by(|x, y| x.0.total_cmp(&y.0))
}

#[test]
fn mirrored_sheared_cylinder_matches_the_world_quadric() {
    let (r, height) = (0.8, 2.0);
    let w = mirrored_shear();
    let placed = transformed(Cylinder::new(DVec3::ZERO, DVec3::Y, r, height, true).unwrap(), w);
    let centre = w.transform_point3(DVec3::new(0.0, 1.0, 0.0));
    let mut rng = StdRng::seed_from_u64(23);
    let (mut hits, mut worst_t, mut worst_n, mut rim) = (0, 0.0f64, 0.0f64, 0);
    for _ in 0..50_000 {
        let target = centre + random_unit(&mut rng) * rng.random_range(0.0..2.5);
        let origin = target + random_unit(&mut rng) * 8.0;
        let ray = Ray::new(origin, (target - origin).normalize());
        let got = placed.intersect(&ray, Interval::POSITIVE);
        let reference = world_cylinder(&w, r, height, &ray);
        match (got, reference) {
            (Some(g), Some((t, n))) => {
                let p = ray.at(g.t);
                let l = placed.local_point(p);
                // the rim (side meets cap) is an edge: either face's normal is right there
                let at_rim = (l.x.hypot(l.z) - r).abs() < 1e-7 && (l.y.abs() < 1e-7 || (l.y - height).abs() < 1e-7);
                hits += 1;
                worst_t = worst_t.max((g.t - t).abs() / t);
                let ng = placed.normal_at(&ray, &g);
                if at_rim {
                    rim += 1;
                } else {
                    // outward on both sides of the mirror: the world gradient of the quadric
                    // (positive outside) and the outward cap normals
                    worst_n = worst_n.max(1.0 - ng.dot(n));
                    assert!(ng.dot(n) > 1.0 - 1e-9, "normal {ng} vs outward world normal {n}");
                }
            }
            (None, None) => {}
            (g, rf) => {
                // only grazing contacts may differ: the quadric's double root within rounding
                let t = g.map(|h| h.t).or(rf.map(|x| x.0)).unwrap();
                let l = placed.local_point(ray.at(t));
                let on_rim_or_tangent = (l.x.hypot(l.z) - r).abs() < 1e-6;
                assert!(on_rim_or_tangent, "disagreement: {g:?} vs {rf:?} for {ray:?}");
            }
        }
    }
    println!("[matrix] mirrored sheared cylinder vs world quadric: {hits} hits ({rim} on the rim), max rel |Δt| {worst_t:e}, max normal difference {worst_n:e}");
    assert!(hits > 20_000 && worst_t < 1e-9, "{hits} {worst_t:e}");
}

#[test]
fn mirrored_rotated_mesh_matches_world_triangles() {
    let vertices: Vec<[f32; 3]> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.1],
        [1.0, 1.0, 0.3],
        [0.0, 1.0, -0.2],
        [0.5, 0.5, 0.9],
    ];
    let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]];
    let mesh = Mesh::new(vertices.clone(), faces.clone(), None).unwrap();
    let w = mirrored_shear();
    let placed = transformed(mesh, w);
    let world = |i: u32| {
        let v = vertices[i as usize];
        w.transform_point3(DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
    };
    let triangles: Vec<Triangle> = faces
        .iter()
        .map(|f| Triangle::new(world(f[0]), world(f[1]), world(f[2])).unwrap())
        .collect();
    let mut rng = StdRng::seed_from_u64(24);
    let mut hits = 0;
    let mut worst = 0.0f64;
    for _ in 0..20_000 {
        // aim at a point well inside a random face, so that no edge decision is involved
        let tri = &triangles[rng.random_range(0..triangles.len())];
        let (mut u, mut v): (f64, f64) = (rng.random_range(0.05..0.9), rng.random_range(0.05..0.9));
        if u + v > 0.95 {
            (u, v) = (0.95 - u, 0.95 - v);
            (u, v) = (u.max(0.05), v.max(0.05));
        }
        let [a, b, c] = tri.vertices();
        let target = a + u * (b - a) + v * (c - a);
        let origin = target + random_unit(&mut rng) * 5.0;
        let ray = Ray::new(origin, (target - origin).normalize());
        let reference = triangles
            .iter()
            .filter_map(|t| t.intersect(&ray, Interval::POSITIVE).map(|h| (h.t, t)))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        let got = placed.intersect(&ray, Interval::POSITIVE);
        let ((t, face), g) = (reference.expect("aimed inside a face"), got.expect("mesh hit"));
        hits += 1;
        worst = worst.max((g.t - t).abs() / t);
        let n = placed.normal_at(&ray, &g);
        // away from edges (a nearer face may be hit anywhere), the normals are the same plane's
        if face.barycentric(ray.at(t)).min_element() > 1e-6 {
            assert!(
                n.dot(face.normal()).abs() > 1.0 - 1e-9,
                "normal {n} vs {}",
                face.normal()
            );
        }
    }
    println!("[matrix] mirrored sheared mesh vs world triangles: {hits} hits, max rel |Δt| {worst:e}");
    assert!(worst < 1e-9, "{worst:e}");
}
