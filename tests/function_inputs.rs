//! Extreme inputs around `Function` shapes and the query options: integer powers above 64, a
//! syntax error in a huge expression, a huge balanced expression, a search box of zero
//! thickness, a negative `--origin-precision`.

mod support;

use std::time::Instant;
use support::{bin, stderr, stdout, write_file};
use zeroset::scene::Scene;

/// A scene with one `Function` of `phi` in the box `min`..`max`.
fn function_scene(phi: &str, min: &str, max: &str) -> String {
    format!(
        "Scene(
    camera: (eye: (0, 0, -4), look_at: (0, 0, 0), vfov_deg: 40, width: 32, height: 24),
    objects: [
        (shape: Sphere(center: (3, 0, 0), radius: 0.5)),
        (shape: Function(phi: \"{phi}\", min: {min}, max: {max})),
    ],
)"
    )
}

fn load_error(text: &str) -> String {
    Scene::from_ron(text, "f.ron").unwrap_err().to_string()
}

#[test]
fn integer_powers_above_64_load_and_hit() {
    let dir = tempfile::tempdir().unwrap();
    // z⁶⁵ = −1 − x⁶⁶ − y⁶⁶: an integer power of a negative base, so the surface is at z ≈ −1
    let text = function_scene("x^66 + y^66 + pow(z, 65) + 1", "(-2, -2, -2)", "(2, 2, 2)");
    let scene = write_file(dir.path(), "powers.ron", text);
    let rays = write_file(dir.path(), "rays.csv", "0.5,0.5,-4,0,0,1\n");
    let o = bin()
        .args(["query", scene.to_str().unwrap(), "--rays", rays.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let row: Vec<&str> = out.lines().nth(1).expect("a result row").split(',').collect();
    assert_eq!(row[0], "1", "{out}");
    let t: f64 = row[1].parse().unwrap();
    assert!((t - 3.0).abs() < 1e-6, "t = {t}");
}

#[test]
fn a_syntax_error_in_a_huge_expression_is_quoted_around_its_column() {
    // a 260 KB expression with a stray `*` in the middle
    let half = vec!["x"; 32_500].join(" + ");
    let phi = format!("{half} + * {half}");
    let message = load_error(&function_scene(&phi, "(-1, -1, -1)", "(1, 1, 1)"));
    assert!(message.len() < 600, "{} bytes: {}", message.len(), &message[..600]);
    assert!(
        message.contains("syntax error in `…") && message.contains("…` at column 130001"),
        "{message}"
    );
    assert!(message.contains("x + * x"), "{message}");
    assert!(message.contains("objects[1] (Function): field `phi`"), "{message}");
}

#[test]
fn a_huge_balanced_expression_is_refused_quickly() {
    let mut terms: Vec<String> = (0..131_072).map(|i| format!("x*{i}")).collect();
    while terms.len() > 1 {
        terms = terms.chunks(2).map(|p| format!("({}+{})", p[0], p[1])).collect();
    }
    assert!(terms[0].len() > 1_000_000);
    let started = Instant::now();
    let message = load_error(&function_scene(&terms[0], "(-1, -1, -1)", "(1, 1, 1)"));
    assert!(started.elapsed().as_secs_f64() < 5.0, "{:?}", started.elapsed());
    assert!(
        message.contains("operations, more than 20000"),
        "{}",
        &message[..message.len().min(600)]
    );
    assert!(message.len() < 1000, "{} bytes", message.len());
}

#[test]
fn a_search_box_of_zero_thickness_is_refused() {
    let sphere = "x^2 + y^2 + z^2 - 1";
    for (min, max, what) in [
        ("(-2, -2, 0)", "(2, 2, 0)", "zero thickness along z"),
        ("(-2, 1, -2)", "(2, 1, 2)", "zero thickness along y"),
        ("(2, -2, -2)", "(-2, 2, 2)", "inverted along x"),
    ] {
        let message = load_error(&function_scene(sphere, min, max));
        assert!(
            message.contains("objects[1] (Function)") && message.contains("`min`/`max`") && message.contains(what),
            "{min} {max}: {message}"
        );
    }
    // a thin but real box is accepted
    Scene::from_ron(&function_scene(sphere, "(-2, -2, -1e-9)", "(2, 2, 1e-9)"), "f.ron").unwrap();
}

#[test]
fn a_negative_origin_precision_names_the_option_and_its_range() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "s.ron", function_scene("x", "(-1, -1, -1)", "(1, 1, 1)"));
    let rays = write_file(dir.path(), "rays.csv", "0,0,-4,0,0,1,0,0,-1\n");
    for value in ["-1", "-1e-3", "-inf"] {
        let o = bin()
            .args(["query", scene.to_str().unwrap(), "--rays", rays.to_str().unwrap()])
            .args(["--origin-precision", value])
            .output()
            .unwrap();
        assert!(!o.status.success());
        let err = stderr(&o);
        assert!(
            err.contains("--origin-precision") && err.contains("≥ 0") && err.contains(&format!("`{value}`")),
            "{value}: {err}"
        );
        assert!(!err.contains("unexpected argument"), "{err}");
    }
    // valid values still parse, including a bound in exponent notation
    let o = bin()
        .args(["query", scene.to_str().unwrap(), "--rays", rays.to_str().unwrap()])
        .args(["--origin-precision", "1e-6"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A `Function` whose box is smaller than its surface is reported at load: the object and the
/// faces it cuts, each with a point where Φ < 0; a box that encloses the surface (even touching
/// it) is not.
#[test]
fn a_search_box_that_cuts_the_surface_is_reported_with_its_faces() {
    let warnings = |min: &str, max: &str| {
        Scene::from_ron(&function_scene("x^2 + y^2 + z^2 - 1", min, max), "f.ron")
            .unwrap()
            .warnings
    };
    assert!(warnings("(-1.2, -1.2, -1.2)", "(1.2, 1.2, 1.2)").is_empty());
    assert!(warnings("(-1, -1, -1)", "(1, 1, 1)").is_empty());
    // the unit sphere in x ≤ 0.5: only the +X face (x = 0.5) cuts it
    let cut = warnings("(-1.2, -1.2, -1.2)", "(0.5, 1.2, 1.2)");
    assert_eq!(cut.len(), 1, "{cut:?}");
    let w = &cut[0];
    assert!(
        w.starts_with("objects[1] (Function): the search box cuts the surface"),
        "{w}"
    );
    assert!(w.contains("face +X (x = 0.5; Φ < 0 at (0.5, "), "{w}");
    for other in ["−X", "−Y", "+Y", "−Z", "+Z"] {
        assert!(!w.contains(other), "{other} is not cut: {w}");
    }
    // on the command line, the warning is printed before the render
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(
        dir.path(),
        "cut.ron",
        function_scene("x^2 + y^2 + z^2 - 1", "(-0.8, -0.8, -0.8)", "(0.8, 0.8, 0.8)"),
    );
    let out = bin()
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            dir.path().join("o").to_str().unwrap(),
            "--no-previews",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains(
            "warning: objects[1] (Function): the search box cuts the surface: Φ < 0 (inside) on its faces −X (x = -0.8"
        ),
        "{err}"
    );
}
