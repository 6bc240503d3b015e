//! Properties of `Mesh`: watertightness on a closed mesh, agreement with the same triangles as
//! separate primitives and with an independent f64 ray/triangle test, Φ's sign near the surface,
//! shading normals, instancing under transforms. Run with `--nocapture` for the measured figures.

use glam::{DAffine3, DQuat, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Arc;
use zeroset_primitives::testing::random_unit;
use zeroset_primitives::*;

/// A closed icosphere, subdivided `level` times, radially displaced (so neighbouring faces are not
/// coplanar), counter-clockwise seen from outside: `20·4^level` triangles.
fn icosphere(level: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (v, f) = zeroset_primitives::testing::icosphere(level);
    let verts = v
        .iter()
        .map(|&p| {
            let p = DVec3::from_array(p.map(f64::from));
            let r = 1.0 + 0.08 * (9.0 * p.x).sin() * (9.0 * p.y).sin() * (9.0 * p.z).sin();
            (p * r).as_vec3().to_array()
        })
        .collect();
    (verts, f)
}

/// ≥ 1M rays aimed exactly at vertices and at points of shared edges of a closed mesh must all hit:
/// zero leaks. Origins inside the mesh (every ray from inside must leave through the surface), and
/// outside, where the ray crosses the surface transversally at the target (every triangle sharing
/// the edge or vertex faces the ray, `n̂·d̂ < −0.02`; a ray grazing a silhouette edge may rightly
/// miss once rounded to f32, so those are not counted).
#[test]
fn watertight_rays_at_edges_and_vertices_never_leak() {
    let (v, f) = icosphere(4);
    let mesh = Mesh::new(v.clone(), f.clone(), None).unwrap();
    let p = |i: u32| glam::Vec3::from_array(v[i as usize]).as_dvec3();
    let normals: Vec<DVec3> = f
        .iter()
        .map(|t| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).normalize())
        .collect();
    let mut around: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, t) in f.iter().enumerate() {
        for k in 0..3 {
            around.entry((t[k], t[k])).or_default().push(i);
            let (a, b) = (t[k], t[(k + 1) % 3]);
            around.entry((a.min(b), a.max(b))).or_default().push(i);
        }
    }
    let batches = 64u64;
    let per_batch = 24_000usize;
    let results: Vec<(usize, usize)> = (0..batches)
        .into_par_iter()
        .map(|batch| {
            let mut rng = StdRng::seed_from_u64(0x5eed_0000 + batch);
            let (mut rays, mut leaks) = (0, 0);
            for _ in 0..per_batch {
                let tri = f[rng.random_range(0..f.len())];
                let k = rng.random_range(0..3);
                let (key, target) = if rng.random_bool(0.3) {
                    ((tri[k], tri[k]), p(tri[k]))
                } else {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    ((a.min(b), a.max(b)), p(a).lerp(p(b), rng.random::<f64>()))
                };
                let inside = rng.random_bool(0.5);
                let origin = if inside {
                    random_unit(&mut rng) * rng.random_range(0.0..0.5)
                } else {
                    random_unit(&mut rng) * rng.random_range(1.5..20.0)
                };
                // f32-representable origins as well as arbitrary f64 ones
                let origin = if rng.random_bool(0.5) {
                    origin.as_vec3().as_dvec3()
                } else {
                    origin
                };
                let dir = (target - origin).normalize();
                if !inside && around[&key].iter().any(|&i| normals[i].dot(dir) > -0.02) {
                    continue;
                }
                let ray = Ray::new(origin, target - origin);
                rays += 1;
                if mesh.intersect(&ray, Interval::POSITIVE).is_none() {
                    if leaks < 3 {
                        eprintln!("leak {ray:?} brute force {:?}", mesh.intersect_brute_force(&ray));
                    }
                    leaks += 1;
                }
            }
            (rays, leaks)
        })
        .collect();
    let rays: usize = results.iter().map(|r| r.0).sum();
    let leaks: usize = results.iter().map(|r| r.1).sum();
    eprintln!(
        "watertight: {rays} rays at edges/vertices of {} triangles, {leaks} leaks",
        f.len()
    );
    assert!(rays >= 1_000_000);
    assert_eq!(leaks, 0);
}

/// Möller–Trumbore in f64, as an independent reference.
fn reference(ray: &Ray, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let s = ray.origin - a;
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = ray.dir.dot(q) / det;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) / det;
    (t >= 0.0).then_some(t)
}

/// Distance from the barycentrics `(u, v)` to the triangle's boundary (0 on an edge).
fn edge_distance(u: f64, v: f64) -> f64 {
    u.min(v).min(1.0 - u - v)
}

/// Hits on the mesh equal hits on the same triangles as separate primitives (one-triangle meshes,
/// closest found by testing each) and the f64 reference: `t` within 1e-5 relative, the same
/// triangle except where the hit lies within 1e-4 (barycentric) of an edge.
#[test]
fn mesh_hits_equal_separate_triangles() {
    let (v, f) = icosphere(3);
    let mesh = Mesh::new(v.clone(), f.clone(), None).unwrap();
    let separate: Vec<Mesh> = f
        .iter()
        .map(|t| Mesh::new(t.iter().map(|&i| v[i as usize]).collect(), vec![[0, 1, 2]], None).unwrap())
        .collect();
    // and as the kernel's own `Triangle` primitives (f64, watertight), one per face
    let triangles: Vec<Triangle> = (0..f.len())
        .map(|i| {
            let [a, b, c] = mesh.triangle(i);
            Triangle::new(a, b, c).unwrap()
        })
        .collect();
    let mut max_rel_triangle = 0f64;
    let corners = |i: usize| mesh.triangle(i);
    let mut rng = StdRng::seed_from_u64(11);
    let (mut hits, mut misses, mut other_triangle) = (0, 0, 0);
    let (mut max_rel, mut max_rel_ref) = (0f64, 0f64);
    for _ in 0..20_000 {
        let origin = random_unit(&mut rng) * rng.random_range(1.3..6.0);
        let aim = random_unit(&mut rng) * rng.random_range(0.0..1.2);
        let ray = Ray::new(origin, (aim - origin).normalize());
        let m = mesh.intersect(&ray, Interval::POSITIVE);
        let s = separate
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.intersect(&ray, Interval::POSITIVE).map(|h| (i, h)))
            .min_by(|a, b| a.1.t.total_cmp(&b.1.t));
        let r = (0..f.len())
            .filter_map(|i| {
                let [a, b, c] = corners(i);
                reference(&ray, a, b, c).map(|t| (i, t))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let tri = triangles
            .iter()
            .filter_map(|p| p.intersect(&ray, Interval::POSITIVE))
            .min_by(|a, b| a.t.total_cmp(&b.t));
        assert_eq!(
            m.is_some(),
            tri.is_some(),
            "mesh and Triangle primitives disagree on {ray:?}"
        );
        if let (Some(m), Some(tri)) = (m, tri) {
            max_rel_triangle = max_rel_triangle.max((m.t - tri.t).abs() / tri.t);
        }
        match (m, s, r) {
            (None, None, None) => misses += 1,
            (Some(m), Some((si, sh)), Some((_, rt))) => {
                hits += 1;
                max_rel = max_rel.max((m.t - sh.t).abs() / sh.t);
                max_rel_ref = max_rel_ref.max((m.t - rt).abs() / rt);
                if m.feature as usize != si {
                    other_triangle += 1;
                    assert!(
                        edge_distance(m.local.x, m.local.y) < 1e-4,
                        "different triangle away from an edge: mesh {} {:?}, separate {si}",
                        m.feature,
                        m.local
                    );
                }
            }
            other => panic!("hit/miss disagreement on {ray:?}: {other:?}"),
        }
    }
    eprintln!(
        "mesh vs separate: {hits} hits, {misses} misses, {other_triangle} on a different triangle at an edge, \
         max rel t error vs separate {max_rel:.2e}, vs f64 reference {max_rel_ref:.2e}"
    );
    assert!(hits > 5_000 && misses > 1_000);
    assert!(max_rel < 1e-5 && max_rel_ref < 1e-5);
    eprintln!("mesh vs Triangle primitives: max relative t difference {max_rel_triangle:e}");
    assert!(max_rel_triangle < 1e-12, "{max_rel_triangle:e}");
}

/// Φ is ≈ 0 at hits, and negative just inside / positive just outside along the normal.
#[test]
fn phi_sign_near_the_surface() {
    let (v, f) = icosphere(3);
    let mesh = Mesh::new(v, f, None).unwrap();
    let mut rng = StdRng::seed_from_u64(5);
    let (mut checked, mut max_phi) = (0, 0f64);
    for _ in 0..3000 {
        let origin = random_unit(&mut rng) * 4.0;
        let ray = Ray::new(origin, (random_unit(&mut rng) * 0.5 - origin).normalize());
        let Some(hit) = mesh.intersect(&ray, Interval::POSITIVE) else {
            continue;
        };
        let p = ray.at(hit.t);
        let n = mesh.normal_at(&ray, &hit);
        max_phi = max_phi.max(mesh.phi(p).abs());
        for eps in [1e-4, 1e-3] {
            assert!(mesh.phi(p + eps * n) > 0.0, "outside at {p} + {eps}·{n}");
            assert!(mesh.phi(p - eps * n) < 0.0, "inside at {p} − {eps}·{n}");
        }
        checked += 1;
    }
    eprintln!("phi: {checked} hits, max |Φ(hit)| {max_phi:.2e}");
    assert!(checked > 1000 && max_phi < 1e-6);
    assert!(mesh.phi(DVec3::ZERO) < -0.5 && mesh.phi(DVec3::splat(3.0)) > 3.0);
}

/// Shading normals interpolate the vertex normals; at a vertex they equal that vertex's normal.
#[test]
fn shading_normal_interpolates_vertex_normals() {
    let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let n = vec![[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 1.0, -1.0]];
    let mesh = Mesh::new(v.clone(), vec![[0, 1, 2]], Some(n)).unwrap();
    let ray = Ray::new(DVec3::new(0.25, 0.25, -1.0), DVec3::Z);
    let hit = mesh.intersect(&ray, Interval::POSITIVE).unwrap();
    assert!((mesh.normal_at(&ray, &hit) - DVec3::Z).length() < 1e-12);
    let s = mesh.shading_normal_at(&ray, &hit).unwrap();
    let expect = DVec3::new(0.25, 0.25, -1.0).normalize();
    assert!((s - expect).length() < 1e-6, "{s} vs {expect}");
    let bare = Mesh::new(v, vec![[0, 1, 2]], None).unwrap();
    assert!(bare
        .shading_normal_at(&ray, &bare.intersect(&ray, Interval::POSITIVE).unwrap())
        .is_none());
    // through a transform the shading normal maps like the geometric one
    let m = DAffine3::from_scale_rotation_translation(DVec3::new(2.0, 1.0, 1.0), DQuat::from_rotation_y(0.3), DVec3::X);
    let placed = Transformed::new(Arc::new(mesh), m).unwrap();
    let world = Ray::new(m.transform_point3(ray.origin), m.transform_vector3(ray.dir));
    let hit = placed.intersect(&world, Interval::POSITIVE).unwrap();
    let s = placed.shading_normal_at(&world, &hit).unwrap();
    let expect = (m.matrix3.inverse().transpose() * expect).normalize();
    assert!((s - expect).length() < 1e-6);
}

/// One `Arc<Mesh>` under several transforms equals meshes built from transformed vertices.
#[test]
fn instances_share_one_mesh_and_match_transformed_copies() {
    let (v, f) = icosphere(2);
    let shared = Arc::new(Mesh::new(v.clone(), f.clone(), None).unwrap());
    let mut rng = StdRng::seed_from_u64(3);
    let mut max_rel = 0f64;
    for i in 0..4 {
        let m = DAffine3::from_scale_rotation_translation(
            DVec3::splat(0.5 + i as f64 * 0.3),
            DQuat::from_axis_angle(random_unit(&mut rng), rng.random_range(0.0..6.0)),
            random_unit(&mut rng) * 2.0,
        );
        let instance = Transformed::new(Arc::clone(&shared), m).unwrap();
        let copy = Mesh::new(
            v.iter()
                .map(|p| {
                    m.transform_point3(glam::Vec3::from_array(*p).as_dvec3())
                        .as_vec3()
                        .to_array()
                })
                .collect(),
            f.clone(),
            None,
        )
        .unwrap();
        for _ in 0..2000 {
            let origin = m.translation + random_unit(&mut rng) * 5.0;
            let ray = Ray::new(
                origin,
                (m.translation + random_unit(&mut rng) * 0.5 - origin).normalize(),
            );
            match (
                instance.intersect(&ray, Interval::POSITIVE),
                copy.intersect(&ray, Interval::POSITIVE),
            ) {
                (Some(a), Some(b)) => max_rel = max_rel.max((a.t - b.t).abs() / b.t),
                (None, None) => {}
                (a, b) => {
                    // only grazing rays near the silhouette may differ (f32 rounding of the copy)
                    let t = a.or(b).unwrap().t;
                    let n = match (a, b) {
                        (Some(hit), _) => instance.normal_at(&ray, &hit),
                        (None, Some(hit)) => copy.normal_at(&ray, &hit),
                        (None, None) => unreachable!("one of the two hit"),
                    };
                    assert!(n.dot(ray.dir).abs() < 0.05, "non-grazing disagreement at t = {t}");
                }
            }
        }
    }
    assert_eq!(Arc::strong_count(&shared), 1);
    eprintln!("instances vs copies: max rel t difference {max_rel:.2e}");
    assert!(max_rel < 1e-5);
}

/// `normal_at_f32` (the mesh's f32 table) is `normal_at` rounded to f32, bit for bit, on every
/// triangle of meshes with every group/remainder split of the table's four-lane runs: random
/// triangles spanning many magnitudes (from `10⁻⁶` to `10⁶`), slivers, exactly degenerate ones
/// (zero normal, left out of the hierarchy) and repeated vertices; the last mesh is past the
/// size up to which the table is kept (its f32 normals are `normal_at`'s, rounded on the way).
/// The f64 normal itself is checked against the normalised cross product worked out here.
#[test]
fn f32_normals_are_the_exact_normals_rounded() {
    let mut rng = StdRng::seed_from_u64(0x6e6f726d);
    for count in [1usize, 3, 4, 5, 7, 8, 9, 4099, 10_001, (1 << 18) + 1] {
        let mut vertices: Vec<[f32; 3]> = Vec::new();
        let mut tris = Vec::new();
        for i in 0..count {
            let scale = 10f32.powi(rng.random_range(-6..=6));
            let corner = |rng: &mut StdRng| {
                [
                    rng.random_range(-1.0f32..1.0) * scale,
                    rng.random_range(-1.0f32..1.0) * scale,
                    rng.random_range(-1.0f32..1.0) * scale,
                ]
            };
            let a = corner(&mut rng);
            let b = corner(&mut rng);
            let c = match i % 5 {
                // exactly degenerate: on the line through a and b
                0 if i > 0 => b,
                // a sliver: c a hair off a
                1 => [a[0] * (1.0 + f32::EPSILON), a[1], a[2]],
                _ => corner(&mut rng),
            };
            let n = vertices.len() as u32;
            vertices.extend([a, b, c]);
            tris.push([n, n + 1, n + 2]);
        }
        let mesh = Mesh::new(vertices.clone(), tris.clone(), None).unwrap();
        let ray = Ray::new(DVec3::ZERO, DVec3::Z);
        for (i, t) in tris.iter().enumerate() {
            let raw = RawHit::on_feature(1.0, i as u32);
            let exact = mesh.normal_at(&ray, &raw);
            let [a, b, c] = t.map(|k| DVec3::from_array(vertices[k as usize].map(f64::from)));
            let cross = (b - a).cross(c - a);
            let length = cross.length();
            if length > 0.0 && length.is_finite() {
                assert!(
                    (exact - cross / length).length() < 1e-15,
                    "triangle {i}: {exact} against {}",
                    cross / length
                );
            } else {
                assert_eq!(exact, DVec3::ZERO, "triangle {i}");
            }
            let rounded = mesh.normal_at_f32(&ray, &raw);
            assert_eq!(
                rounded.to_array().map(f32::to_bits),
                exact.as_vec3().to_array().map(f32::to_bits),
                "triangle {i} of {count}: {rounded} against {exact}"
            );
        }
        // a feature past the last triangle: zero, as `normal_at` answers
        let past = RawHit::on_feature(1.0, count as u32);
        assert_eq!(mesh.normal_at_f32(&ray, &past), glam::Vec3::ZERO);
        assert_eq!(mesh.normal_at(&ray, &past), DVec3::ZERO);
    }
}

/// The normal the pieces find with the hit (`intersect_pieces_nearest_first_with_normal`, which
/// the renderer's pixel bins use) is `normal_at_f32`'s for that hit, bit for bit, and the hit is
/// `intersect`'s: on a height field small enough to keep the normals' table and on one past the
/// size up to which the table is kept (there the normal is normalised from the plane the hit's
/// `t` was found on). Rays from above, toward random points of the field and past its edges.
#[test]
fn normals_found_with_the_hit_are_normal_at_f32() {
    let mut rng = StdRng::seed_from_u64(0x6869_746e);
    // 2·39² = 3,042 triangles, and 2·363² = 263,538 > 2¹⁸
    for side in [40usize, 364] {
        let at = |i: usize| -1.0 + 2.0 * i as f32 / (side - 1) as f32;
        let mut vertices = Vec::with_capacity(side * side);
        for j in 0..side {
            for i in 0..side {
                let (x, y) = (at(i), at(j));
                let z = 0.05 * (3.0 * x).sin() * (2.0 * y).cos() + 0.002 * rng.random_range(-1.0f32..1.0);
                vertices.push([x, y, z]);
            }
        }
        let index = |i: usize, j: usize| (j * side + i) as u32;
        let mut tris = Vec::with_capacity(2 * (side - 1) * (side - 1));
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                tris.push([index(i, j), index(i + 1, j), index(i + 1, j + 1)]);
                tris.push([index(i, j), index(i + 1, j + 1), index(i, j + 1)]);
            }
        }
        let mesh = Mesh::new(vertices, tris, None).unwrap();
        let pieces = mesh.pieces().unwrap();
        // every piece, each with distance 0 (a lower bound on any distance): all are tested
        let listed: Vec<(u32, f32)> = pieces.piece_numbers().into_iter().map(|n| (n, 0.0)).collect();
        let mut hits = 0;
        for trial in 0..200 {
            let origin = DVec3::new(rng.random_range(-1.2..1.2), rng.random_range(-1.2..1.2), 2.0);
            let target = DVec3::new(rng.random_range(-1.1..1.1), rng.random_range(-1.1..1.1), 0.0);
            let ray = Ray::new(origin, target - origin);
            let range = Interval::POSITIVE;
            let walk = mesh.intersect(&ray, range);
            let found = pieces.intersect_pieces_nearest_first_with_normal(&ray, range, &listed);
            assert_eq!(found.map(|(hit, _)| hit), walk, "side {side}, trial {trial}");
            if let Some((hit, normal)) = found {
                hits += 1;
                let normal = normal.expect("a mesh finds the normal with the hit");
                assert_eq!(
                    normal.to_array().map(f32::to_bits),
                    mesh.normal_at_f32(&ray, &hit).to_array().map(f32::to_bits),
                    "side {side}, trial {trial}"
                );
                assert!(
                    (normal.length() - 1.0).abs() < 1e-6,
                    "side {side}, trial {trial}: {normal}"
                );
            }
        }
        assert!(hits > 150, "side {side}: {hits} hits");
    }
}
