//! End-to-end tests of issue 13 through the `zeroset` binary: the query range open at 0, spawned
//! origins from normal columns, `Function` expressions (syntax and domain errors, guaranteed
//! roots on a thin shell), degenerate triangles (warned, rendered), `matrix:` transforms.

mod support;

use std::process::Output;
use support::{assert_fails, assert_ok, p, run, stderr, stdout, write_file};

/// Parsed output rows: `(hit, t)`.
fn query(scene: &str, rays: &str, extra: &[&str]) -> (Output, Vec<Option<f64>>) {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("s.ron");
    let rays_path = dir.path().join("r.csv");
    std::fs::write(&scene_path, scene).unwrap();
    std::fs::write(&rays_path, rays).unwrap();
    let mut args = vec!["query", p(&scene_path), "--rays", p(&rays_path)];
    args.extend_from_slice(extra);
    let out = run(&args);
    let rows = stdout(&out)
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0] == "1").then(|| f[1].parse::<f64>().unwrap())
        })
        .collect();
    (out, rows)
}

const FACES: &str = r#"Scene(
    camera: (eye: (0, 0, -5), look_at: (0, 0, 0)),
    objects: [
        (name: "box", shape: Box(min: (-1, -1, -1), max: (1, 1, 1))),
        (name: "can", shape: Cylinder(base: (5, 0, 0), axis: (0, 1, 0), radius: 1, height: 2)),
        (name: "floor", shape: Plane(normal: (0, 1, 0), offset: -3)),
    ],
)
"#;

#[test]
fn query_range_is_open_at_zero_unless_closed_is_asked() {
    // origins exactly on a box face, a cylinder cap and the plane, rays into and out of them
    let rays = "0.25,-0.5,-1,0,0,1\n\
                0.25,-0.5,-1,0,0,-1\n\
                5.5,2,0.25,0,-1,0\n\
                4,-3,0,0.1,1,0\n\
                4,-3,0,0,-1,0.1\n";
    let (out, open) = query(FACES, rays, &[]);
    assert_ok(&out, "open range");
    // into the box: its far face at t = 2; out of it: nothing at t = 0 (a miss ahead)
    assert_eq!(open[0], Some(2.0));
    assert_eq!(open[1], None);
    // down through the cap: the bottom cap at t = 2
    assert_eq!(open[2], Some(2.0));
    // from the floor upwards: nothing at t = 0; downwards: nothing
    assert!(open[3].is_none_or(|t| t > 0.0));
    assert_eq!(open[4], None);
    let (out, closed) = query(FACES, rays, &["--closed-range"]);
    assert_ok(&out, "closed range");
    assert_eq!(closed[0], Some(0.0));
    assert_eq!(closed[1], Some(0.0));
    assert_eq!(closed[2], Some(0.0));
    assert_eq!(closed[4], Some(0.0));
}

#[test]
fn query_spawns_from_f32_points_with_normals() {
    let scene = r#"Scene(
    camera: (eye: (0, 0, -5), look_at: (0, 0, 0)),
    objects: [(name: "ball", shape: Sphere(center: (0.1, 0.2, 0.3), radius: 1.7))],
)
"#;
    // points on the sphere rounded to f32, leaving rays at 80° from the normal; without spawning
    // a share of them re-hit the sphere at t ≈ 1e-7, with spawning none does
    let centre = [0.1f64, 0.2, 0.3];
    let mut plain = String::new();
    let mut spawned = String::new();
    for k in 0..400 {
        let a = f64::from(k) * 0.0157;
        let b = f64::from(k) * 0.731;
        let n = [a.sin() * b.cos(), a.sin() * b.sin(), a.cos()];
        let point: Vec<f32> = (0..3).map(|i| (centre[i] + 1.7 * n[i]) as f32).collect();
        let t = [n[1], -n[0], 0.0];
        let tl = (t[0] * t[0] + t[1] * t[1]).sqrt().max(1e-9);
        let d: Vec<f64> = (0..3).map(|i| 0.17 * n[i] + 0.98 * t[i] / tl).collect();
        let line = format!("{},{},{},{},{},{}", point[0], point[1], point[2], d[0], d[1], d[2]);
        plain.push_str(&line);
        plain.push('\n');
        let n32: Vec<f32> = n.iter().map(|&x| x as f32).collect();
        spawned.push_str(&format!("{line},{},{},{}\n", n32[0], n32[1], n32[2]));
    }
    let (out, hits) = query(scene, &plain, &[]);
    assert_ok(&out, "plain");
    let self_hits = hits.iter().flatten().filter(|&&t| t < 1e-3).count();
    let (out, hits) = query(scene, &spawned, &["--origin-precision", "f32"]);
    assert_ok(&out, "spawned");
    let after = hits.iter().flatten().count();
    println!("[cli] f32 points on a sphere: {self_hits} self-hits without spawning, {after} with");
    assert!(self_hits > 20, "{self_hits}");
    assert_eq!(after, 0);
    // an absolute bound works too, and missing normals are an error naming the line
    let (out, hits) = query(scene, &spawned, &["--origin-precision", "1e-5"]);
    assert_ok(&out, "absolute");
    assert_eq!(hits.iter().flatten().count(), 0);
    let (out, _) = query(scene, &plain, &["--origin-precision", "f32"]);
    assert_fails(&out, &["r.csv:1", "nx,ny,nz"], "no normals");
    let (out, _) = query(scene, &plain, &["--origin-precision", "fast"]);
    assert_fails(&out, &["f32", "f64"], "bad precision");
}

fn scene_with(shape: &str) -> String {
    format!(
        "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 24, height: 16), objects: [(name: \"it\", shape: {shape})])"
    )
}

fn scene_with_transform(shape: &str, transform: &str) -> String {
    format!(
        "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 24, height: 16), \
         objects: [(name: \"it\", shape: {shape}, transform: ({transform}))])"
    )
}

fn render(scene: &str) -> Output {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(dir.path(), "s.ron", scene);
    let out_dir = dir.path().join("out");
    run(&["render", p(&path), "-o", p(&out_dir), "--no-previews"])
}

#[test]
fn function_expressions_errors_and_guaranteed_roots() {
    let bad = render(&scene_with(
        r#"Function(phi: "x^2 + * y", min: (-1, -1, -1), max: (1, 1, 1))"#,
    ));
    assert_fails(&bad, &["phi", "column 7", "expected a number"], "syntax error");
    assert!(!stderr(&bad).contains("Token"), "no internal dumps: {}", stderr(&bad));
    let domain = render(&scene_with(
        r#"Function(phi: "sqrt(x) - 0.5", min: (-1, -1, -1), max: (1, 1, 1))"#,
    ));
    assert_fails(
        &domain,
        &["phi", "sqrt of a negative number", "column 1"],
        "domain error",
    );
    let budget = render(&scene_with(
        r#"Function(phi: "x^2 + y^2 + z^2 - 1", min: (-1, -1, -1), max: (1, 1, 1), budget: 1)"#,
    ));
    assert_fails(&budget, &["budget", "at least 2"], "budget");
    let old = render(&scene_with(
        r#"Function(phi: "x^2 + y^2 + z^2 - 1", min: (-1, -1, -1), max: (1, 1, 1), lipschitz: 2)"#,
    ));
    assert_ok(&old, "lipschitz still accepted");
    let negative = render(&scene_with(
        r#"Function(phi: "x^2 + y^2 + z^2 - 1", min: (-1, -1, -1), max: (1, 1, 1), lipschitz: -2)"#,
    ));
    assert_fails(&negative, &["lipschitz"], "negative lipschitz");

    // a shell 1e-4 thick, queried on a grid of rays: every ray through it hits at the outer sphere
    let shell = scene_with(
        r#"Function(phi: "abs(sqrt(x^2 + y^2 + z^2) - 1) - 5e-5", min: (-1.1, -1.1, -1.1), max: (1.1, 1.1, 1.1), tolerance: 1e-9, budget: 50000)"#,
    );
    let mut rays = String::new();
    let mut expected = Vec::new();
    for i in 0..40 {
        for j in 0..40 {
            let (x, y) = (-1.2 + 0.06 * f64::from(i), -1.2 + 0.06 * f64::from(j));
            rays.push_str(&format!("{x},{y},-5,0,0,1\n"));
            let r2 = x * x + y * y;
            let outer = 1.0 + 5e-5;
            expected.push((r2 < outer * outer).then(|| 5.0 - (outer * outer - r2).sqrt()));
        }
    }
    let (out, hits) = query(&shell, &rays, &[]);
    assert_ok(&out, "shell query");
    let mut worst = 0.0f64;
    for (i, (h, e)) in hits.iter().zip(&expected).enumerate() {
        match (h, e) {
            (Some(h), Some(e)) => worst = worst.max((h - e).abs()),
            (None, None) => {}
            _ => panic!("ray {i}: got {h:?}, expected {e:?}"),
        }
    }
    println!("[cli] thin shell 1e-4: {} rays, worst |Δt| {worst:e}", hits.len());
    assert!(worst < 1e-7, "{worst:e}");
    assert!(!stderr(&out).contains("not decided exactly"), "{}", stderr(&out));

    // undecided rays are counted and reported, never dropped silently: a double root everywhere
    // (touches, reported as hits) and a budget too small to isolate anything (misses)
    let touch = scene_with(r#"Function(phi: "(x^2 + y^2 + z^2 - 1)^2", min: (-2, -2, -2), max: (2, 2, 2))"#);
    // (rays whose touch point is not where Φ evaluates to exactly 0: a root found at an exact
    // zero, such as z = −1 on the axis, is a proven root and is not flagged)
    let (out, hits) = query(&touch, "0.3,0.2,-5,0,0,1\n0.5,0,-5,0,0,1\n", &[]);
    assert_ok(&out, "double root");
    assert!(hits.iter().all(Option::is_some), "{hits:?}");
    assert!(stderr(&out).contains("2 rays touch"), "{}", stderr(&out));
    // the two rays point alike, so they go as a packet (and are traced again, one by one, to
    // tell which is uncertain): each is counted once, in either order
    let (out, _) = query(&touch, "0.3,0.2,-5,0,0,1\n0.5,0,-5,0,0,1\n", &["--ray-order", "sorted"]);
    assert!(stderr(&out).contains("2 rays touch"), "{}", stderr(&out));
    let starved = scene_with(
        r#"Function(phi: "abs(sqrt(x^2 + y^2 + z^2) - 1) - 1e-4", min: (-2, -2, -2), max: (2, 2, 2), budget: 2)"#,
    );
    let (out, _) = query(&starved, "0,0,-5,0,0,1\n", &[]);
    assert_ok(&out, "starved");
    assert!(
        stderr(&out).contains("1 rays ran out of their budget"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn degenerate_triangles_warn_and_render() {
    let out = render(&scene_with("Triangle(a: (0, 0, 0), b: (1, 1, 1), c: (2, 2, 2))"));
    assert_ok(&out, "degenerate triangle");
    assert!(
        stderr(&out).contains("warning") && stderr(&out).contains("degenerate"),
        "{}",
        stderr(&out)
    );
    // a mesh with two degenerate faces of five
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 5\nf 2 3 5\nf 3 3 3\n",
    )
    .unwrap();
    let scene = write_file(dir.path(), "s.ron", scene_with(r#"Mesh(path: "m.obj")"#));
    let out = run(&["render", p(&scene), "-o", p(&dir.path().join("out")), "--no-previews"]);
    assert_ok(&out, "mesh with degenerate triangles");
    assert!(
        stderr(&out).contains("2 of 5 triangles are degenerate"),
        "{}",
        stderr(&out)
    );
    // a mesh all of whose faces are degenerate has no surface: loaded with a warning, never hit,
    // even by rays aimed at its vertices and along its collapsed edges
    let flat = dir.path().join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 4\nf 4 4 4\n").unwrap();
    let rays = "0,0,-6,0,0,1\n1,0,-6,0,0,1\n0.5,0,-6,0,0,1\n0,0.5,-6,0,0,1\n0,1,-6,0,0,1\n-1,0,0,1,0,0\n";
    let (out, hits) = query(&scene_with(&format!("Mesh(path: {:?})", p(&flat))), rays, &[]);
    assert_ok(&out, "mesh without a surface");
    assert!(
        stderr(&out).contains("all 3 triangles are degenerate (zero area): the mesh has no surface"),
        "{}",
        stderr(&out)
    );
    assert_eq!(hits, vec![None; 6]);
}

#[test]
fn matrix_transforms_validate_and_equal_their_decomposed_form() {
    let rays: String = (0..200)
        .map(|k| {
            let a = f64::from(k) * 0.37;
            format!(
                "{},{},-6,{},{},1\n",
                a.sin(),
                a.cos() * 0.8,
                0.05 * a.cos(),
                -0.03 * a.sin()
            )
        })
        .collect();
    // rotation 90° about z then translation: as a matrix and as translate/rotate
    let slab = "Box(min: (-1, -0.5, -0.25), max: (1, 0.5, 0.25))";
    let decomposed = scene_with_transform(slab, "translate: (0.5, 0, 0), rotate: (axis: (0, 0, 1), degrees: 90)");
    let matrix = scene_with_transform(
        slab,
        "matrix: [[0, -1, 0, 0.5], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
    );
    let (o1, a) = query(&decomposed, &rays, &[]);
    let (o2, b) = query(&matrix, &rays, &[]);
    assert_ok(&o1, "decomposed");
    assert_ok(&o2, "matrix");
    assert!(a.iter().flatten().count() > 50);
    for (x, y) in a.iter().zip(&b) {
        match (x, y) {
            (Some(x), Some(y)) => assert!((x - y).abs() < 1e-12, "{x} vs {y}"),
            (None, None) => {}
            _ => panic!("{x:?} vs {y:?}"),
        }
    }
    let bad = |m: &str, needles: &[&str]| {
        let out = render(&scene_with_transform("Sphere(radius: 1)", &format!("matrix: {m}")));
        assert_fails(&out, needles, m);
    };
    bad(
        "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]]",
        &["transform.matrix", "singular"],
    );
    bad(
        "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]",
        &["transform.matrix", "last row"],
    );
    bad("[[1, 0, 0, 0], [0, 1, 0, 0]]", &["transform.matrix", "3 or 4 rows"]);
    bad(
        "[[1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]",
        &["transform.matrix", "row 0"],
    );
    let both = scene_with_transform(
        "Sphere(radius: 1)",
        "matrix: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], translate: (1, 0, 0)",
    );
    assert_fails(&render(&both), &["cannot be combined"], "matrix and translate");
    // a mirror renders
    let mirror = scene_with_transform(
        "Cylinder(radius: 0.5, height: 1)",
        "matrix: [[-1, 0, 0, 0], [0, 1, 0.3, 0], [0, 0, 1, 0]]",
    );
    assert_ok(&render(&mirror), "mirror");
}
