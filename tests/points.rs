//! Point queries and every crossing along rays, on scenes: the scene's nearest point against a
//! brute force over every triangle, crossings against clipping by the faces' planes, the CLI's
//! `points` and `query --all-hits` files.

#[path = "support/mesh_writers.rs"]
mod mesh_writers;
mod support;

use glam::DVec3;
use rand::{Rng, SeedableRng};
use std::path::Path;
use support::{assert_ok, run, stderr, stdout};
use zeroset::scene::Scene;
use zeroset_primitives::{Interval, Ray};

/// A scene of the icosphere written to `dir` and placed at each of `centres` (as translations).
fn mesh_scene(dir: &Path, levels: u32, centres: &[DVec3]) -> (Scene, Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (vertices, triangles) = zeroset_primitives::testing::icosphere(levels);
    mesh_writers::write(&dir.join("ico.off"), &mesh_writers::off(&vertices, &triangles));
    let objects: Vec<String> = centres
        .iter()
        .map(|c| {
            format!(
                "(shape: Mesh(path: \"ico.off\"), transform: (translate: ({}, {}, {})))",
                c.x, c.y, c.z
            )
        })
        .collect();
    let text = format!(
        "Scene(camera: (eye: (0, 0, -6), look_at: (0, 0, 0)), objects: [{}])",
        objects.join(", ")
    );
    let path = dir.join("scene.ron");
    std::fs::write(&path, text).unwrap();
    (Scene::load(&path).unwrap(), vertices, triangles)
}

/// Distance from `p` to triangle `abc`, computed without Voronoi regions: the projection onto
/// the plane if it falls inside (by the signs of three cross products), else the nearest of the
/// three edges' nearest points.
fn triangle_distance(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
    let n = (b - a).cross(c - a);
    let q = p - n * ((p - a).dot(n) / n.length_squared());
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| (v - u).cross(q - u).dot(n) >= 0.0);
    if inside {
        return (p - q).length();
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| {
            let s = ((p - u).dot(v - u) / (v - u).length_squared()).clamp(0.0, 1.0);
            (p - (u + (v - u) * s)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

fn corners(vertices: &[[f32; 3]], t: [u32; 3], offset: DVec3) -> [DVec3; 3] {
    t.map(|i| DVec3::from_array(vertices[i as usize].map(f64::from)) + offset)
}

#[test]
fn the_scene_s_nearest_point_is_the_brute_force_nearest_over_every_triangle() {
    let dir = tempfile::tempdir().unwrap();
    let centres = [DVec3::new(-1.25, 0.0, 0.0), DVec3::new(1.25, 0.5, 0.0)];
    let (scene, vertices, triangles) = mesh_scene(dir.path(), 2, &centres);
    let mut rng = rand::rngs::StdRng::seed_from_u64(43);
    let mut worst = 0.0f64;
    for k in 0..2000 {
        // mostly around the meshes, some on their vertices and far away
        let p = match k % 10 {
            0 => corners(&vertices, triangles[k % triangles.len()], centres[k % 2])[k % 3],
            1 => DVec3::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0), 30.0),
            _ => DVec3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ),
        };
        let (reference, object) = centres
            .iter()
            .enumerate()
            .flat_map(|(o, &c)| triangles.iter().map(move |&t| (t, o, c)))
            .map(|(t, o, c)| (triangle_distance(p, corners(&vertices, t, c)), o))
            .fold((f64::INFINITY, 0), |best, d| if d.0 < best.0 { d } else { best });
        let found = scene.closest_point(p).unwrap();
        assert!(found.closest.is_exact(), "{p}: a mesh's answer is exact");
        let error = (found.closest.upper - reference).abs();
        assert!(
            error <= 1e-12 * reference.max(1.0),
            "{p}: distance {} against {reference}",
            found.closest.upper
        );
        if reference > 1e-9 {
            assert_eq!(found.object as usize, object, "{p}: the nearer mesh");
        }
        let q = found.closest.point.unwrap();
        assert!(((q - p).length() - found.closest.upper).abs() <= 1e-12 * reference.max(1.0));
        worst = worst.max(error / reference.max(1e-300));
    }
    assert!(worst <= 1e-12, "largest relative error {worst:e}");
}

/// Entry and exit of the ray into the convex solid bounded by the triangles' planes
/// (Cyrus–Beck clipping, in f64).
fn clip(ray: &Ray, planes: &[(DVec3, f64)]) -> Option<(f64, f64)> {
    let (mut enter, mut exit) = (f64::NEG_INFINITY, f64::INFINITY);
    for &(n, d) in planes {
        let denom = n.dot(ray.dir);
        let dist = n.dot(ray.origin) - d;
        if denom == 0.0 {
            if dist > 0.0 {
                return None;
            }
            continue;
        }
        let t = -dist / denom;
        if denom < 0.0 {
            enter = enter.max(t);
        } else {
            exit = exit.min(t);
        }
    }
    (enter <= exit).then_some((enter, exit))
}

#[test]
fn a_ray_through_a_vertex_or_an_edge_of_a_convex_mesh_crosses_it_exactly_twice() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, vertices, triangles) = mesh_scene(dir.path(), 2, &[DVec3::ZERO]);
    let planes: Vec<(DVec3, f64)> = triangles
        .iter()
        .map(|&t| {
            let [a, b, c] = corners(&vertices, t, DVec3::ZERO);
            let n = (b - a).cross(c - a).normalize();
            (n, n.dot(a))
        })
        .collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let mut targets: Vec<DVec3> = vertices.iter().map(|v| DVec3::from_array(v.map(f64::from))).collect();
    for &[a, b, _] in &triangles {
        let [a, b] = [a, b].map(|i| DVec3::from_array(vertices[i as usize].map(f64::from)));
        targets.push((a + b) / 2.0);
    }
    let mut found = Vec::new();
    for target in targets {
        // from outside, on the target's side, aimed through it into the solid
        let jitter = DVec3::new(
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
        );
        let origin = target * 4.0 + jitter;
        let ray = Ray::new(origin, target - origin);
        let range = Interval::new(0.0, f64::INFINITY);
        scene.all_hits(&ray, range, &mut found);
        let (enter, exit) = clip(&ray, &planes).expect("the ray passes through the solid");
        assert_eq!(found.len(), 2, "through {target}: {found:?}");
        assert_eq!(scene.count_crossings(&ray, range), 2);
        assert!(found[0].entering && !found[1].entering);
        for (hit, reference) in found.iter().zip([enter, exit]) {
            assert!(
                (hit.hit.t - reference).abs() <= 1e-6 * reference,
                "through {target}: t {} against {reference}",
                hit.hit.t
            );
        }
    }
}

#[test]
fn crossings_from_outside_a_closed_mesh_are_even_alternate_and_counted_alike() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, _, _) = mesh_scene(dir.path(), 3, &[DVec3::ZERO, DVec3::new(0.7, 0.2, 0.1)]);
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut found = Vec::new();
    let mut total = 0;
    for _ in 0..3000 {
        let origin = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
            * 4.0;
        let aim = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let ray = Ray::new(origin, aim - origin);
        let range = Interval::new(0.0, f64::INFINITY);
        scene.all_hits(&ray, range, &mut found);
        assert_eq!(found.len(), scene.count_crossings(&ray, range));
        total += found.len();
        for object in 0..2u32 {
            let own: Vec<_> = found.iter().filter(|c| c.object == object).collect();
            assert_eq!(own.len() % 2, 0, "{ray:?}: object {object} {own:?}");
            for (k, c) in own.iter().enumerate() {
                assert_eq!(c.entering, k % 2 == 0, "{ray:?}: object {object} alternates");
            }
        }
        assert!(found.windows(2).all(|w| w[0].hit.t <= w[1].hit.t));
    }
    assert!(total > 3000, "most rays cross something ({total} crossings)");
}

#[test]
fn the_points_command_writes_one_row_per_point_in_csv_and_npy() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("spheres.ron");
    std::fs::write(
        &scene,
        "Scene(camera: (eye: (0, 0, -6), look_at: (0, 0, 0)), objects: [
            (shape: Box(min: (-1, -1, -1), max: (1, 1, 1)), transform: (translate: (3, 0, 0))),
            (shape: Box(min: (-1, -1, -1), max: (1, 1, 1)))])",
    )
    .unwrap();
    let points = dir.path().join("p.csv");
    std::fs::write(&points, "x,y,z\n# a comment\n0,0,0\n\n5,0,0\n1.5,0,0\n0,3,0\n").unwrap();
    let scene_arg = scene.to_str().unwrap();
    let o = run(&[
        "points",
        scene_arg,
        "--points",
        points.to_str().unwrap(),
        "--query",
        "signed",
    ]);
    assert_ok(&o, "points --query signed");
    let text = stdout(&o);
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(text.lines().next(), Some("signed_distance,lower,upper"));
    // inside the first box by 1, outside the second by 1, between them 0.5, above by 2
    let expected = [-1.0, 1.0, 0.5, 2.0];
    assert_eq!(rows.len(), expected.len());
    for (row, e) in rows.iter().zip(expected) {
        assert_eq!(row[0], e, "{row:?}");
    }
    let out = dir.path().join("occupancy.npy");
    let o = run(&[
        "points",
        scene_arg,
        "--points",
        points.to_str().unwrap(),
        "--query",
        "occupancy",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_ok(&o, "points --query occupancy");
    let bytes = std::fs::read(&out).unwrap();
    assert!(String::from_utf8_lossy(&bytes[..128]).contains("'shape': (4, 1)"));
    let values: Vec<f64> = bytes[128..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(values, [1.0, 0.0, 0.0, 0.0]);

    std::fs::write(&points, "0,0,0\n1,2\n").unwrap();
    let o = run(&[
        "points",
        scene_arg,
        "--points",
        points.to_str().unwrap(),
        "--query",
        "distance",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("p.csv:2: expected 3"), "{}", stderr(&o));
    std::fs::write(&points, "0,0,nan\n").unwrap();
    let o = run(&[
        "points",
        scene_arg,
        "--points",
        points.to_str().unwrap(),
        "--query",
        "distance",
    ]);
    assert!(
        stderr(&o).contains("p.csv:1: `nan`: coordinates must be finite"),
        "{}",
        stderr(&o)
    );
    let o = run(&[
        "points",
        scene_arg,
        "--points",
        points.to_str().unwrap(),
        "--query",
        "distance",
        "--sign",
        "vote",
    ]);
    assert!(stderr(&o).contains("unknown sign method `vote`"), "{}", stderr(&o));
}

#[test]
fn query_all_hits_lists_every_crossing_of_each_ray_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.ron");
    std::fs::write(
        &scene,
        "Scene(camera: (eye: (0, 0, -6), look_at: (0, 0, 0)), objects: [
            (shape: Sphere(center: (0, 0, 0), radius: 1)),
            (shape: Sphere(center: (0, 0, 4), radius: 2))])",
    )
    .unwrap();
    let rays = dir.path().join("r.csv");
    std::fs::write(&rays, "0,0,-5,0,0,1\n0,5,0,1,0,0\n0,0.5,-5,0,0,1\n").unwrap();
    let o = run(&[
        "query",
        scene.to_str().unwrap(),
        "--rays",
        rays.to_str().unwrap(),
        "--all-hits",
    ]);
    assert_ok(&o, "query --all-hits");
    let rows: Vec<Vec<f64>> = stdout(&o)
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect())
        .collect();
    // ray 0 crosses the unit sphere at t = 4, 6 and the big one at t = 7, 11; ray 1 nothing;
    // ray 2 at ±√0.75 around t = 5, and the big sphere at 4 ± √3.75 + 5
    let c = 0.75f64.sqrt();
    let b = 3.75f64.sqrt();
    let expected = [
        (0.0, 4.0, 0.0, 1.0),
        (0.0, 6.0, 0.0, 0.0),
        (0.0, 7.0, 1.0, 1.0),
        (0.0, 11.0, 1.0, 0.0),
        (2.0, 5.0 - c, 0.0, 1.0),
        (2.0, 5.0 + c, 0.0, 0.0),
        (2.0, 9.0 - b, 1.0, 1.0),
        (2.0, 9.0 + b, 1.0, 0.0),
    ];
    assert_eq!(rows.len(), expected.len(), "{}", stdout(&o));
    for (row, (ray, t, id, entering)) in rows.iter().zip(expected) {
        assert_eq!(row[0], ray);
        assert!((row[1] - t).abs() <= 1e-12 * t, "{row:?} against t = {t}");
        assert_eq!(row[8], id);
        assert_eq!(row[12], entering);
    }
}
