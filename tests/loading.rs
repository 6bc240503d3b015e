//! Loading large scenes: the `objects` list parsed in parallel gives exactly the descriptions of
//! the one-piece parse, a streamed load builds exactly the objects of a load in one piece (and
//! reports the same errors), and an error keeps its line and column.

use std::sync::Arc;
use zeroset::scene::registry::BuildContext;
use zeroset::scene::{parse_scene_desc, ron_options, Scene, SceneDesc};

/// A scene of `n` objects of several kinds, with names, materials, comments and strings holding
/// brackets and commas.
fn many_objects(n: usize) -> String {
    let mut text = String::from("// generated\nScene(camera: (eye: (0, 0, -50), look_at: (0, 0, 0)), objects: [\n");
    for i in 0..n {
        let x = (i % 100) as f64 * 0.5;
        let line = match i % 5 {
            0 => format!("    (name: \"ball [{i}], (x)\", shape: Sphere(center: ({x}, 1, 2), radius: 0.2), material: (color: (0.1, 0.2, 0.3))),\n"),
            1 => format!("    (shape: Box(min: ({x}, 0, 0), max: ({}, 1, 1))), // a box, ]\n", x + 0.3),
            2 => format!("    /* a [nested /* ] */ comment */ (shape: Difference(children: [Sphere(center: ({x}, 0, 0)), Sphere(center: ({x}, 0, 0.5), radius: 0.5)])),\n"),
            3 => format!("    (name: r#\"raw \"]\" name\"#, shape: Cylinder(base: ({x}, 0, 0), radius: 0.1, height: 2), transform: (rotate: (axis: (1, 0, 0), degrees: 30))),\n"),
            _ => format!("    (shape: Ellipsoid(center: ({x}, 2, 0), radii: (0.1, 0.2, 0.3)))\n    ,\n"),
        };
        text.push_str(&line);
    }
    text.push_str("], lights: [Directional(direction: (0, -1, 0))], ambient: (0.2, 0.2, 0.2))\n");
    text
}

fn sequential(text: &str) -> Result<SceneDesc, ron::error::SpannedError> {
    ron_options().from_str(text)
}

#[test]
fn parallel_parse_gives_the_same_descriptions() {
    let text = many_objects(30_000);
    let parallel = parse_scene_desc(&text).unwrap();
    let one_piece = sequential(&text).unwrap();
    assert_eq!(parallel.objects.len(), 30_000);
    assert_eq!(format!("{parallel:?}"), format!("{one_piece:?}"));
}

#[test]
fn an_error_in_a_large_list_keeps_its_position() {
    let text = many_objects(30_000).replacen("radius: 0.2), material", "radius: 0.2, oops: 1), material", 4_000);
    let parallel = parse_scene_desc(&text).unwrap_err();
    let one_piece = sequential(&text).unwrap_err();
    assert_eq!(parallel.to_string(), one_piece.to_string());
    assert!(parallel.to_string().contains("oops"), "{parallel}");
}

/// `text` with the `n`th occurrence (from 1) of `from` replaced by `to`.
fn replace_nth(text: &str, from: &str, to: &str, n: usize) -> String {
    let (at, _) = text.match_indices(from).nth(n - 1).expect("n occurrences");
    format!("{}{to}{}", &text[..at], &text[at + from.len()..])
}

/// The scene built in one piece from the whole text's descriptions, as before streaming.
fn built_in_one_piece(text: &str) -> Result<Scene, (String, String)> {
    Scene::from_desc(sequential(text).expect("parses"), &BuildContext::default())
}

/// What a loaded scene is made of, for comparison: every object (primitive, motion, material,
/// name) and the warnings.
fn contents(scene: &Scene) -> String {
    format!("{:?}\n{:?}\n{:?}", scene.objects, scene.warnings, scene.lights)
}

#[test]
fn a_streamed_load_builds_the_objects_of_a_load_in_one_piece() {
    // 30,000 objects, about 3.5 MB: read in 1 MB blocks whose ends fall inside strings, raw
    // strings and comments; every fifth a degenerate triangle (warned) in place of the ellipsoid
    let text = many_objects(30_000)
        .replace("Ellipsoid(center: (", "Triangle(b: (0, 0, 0), c: (0, 0, 0), a: (")
        .replace(", radii: (0.1, 0.2, 0.3))", ")");
    assert_eq!(text.matches("Triangle").count(), 6_000);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.ron");
    std::fs::write(&path, &text).unwrap();
    let streamed = Scene::load(&path).unwrap();
    let in_memory = Scene::from_ron(&text, "many.ron").unwrap();
    let one_piece = built_in_one_piece(&text).unwrap();
    assert_eq!(streamed.objects.len(), 30_000);
    assert!(!one_piece.warnings.is_empty());
    assert_eq!(contents(&streamed), contents(&one_piece));
    assert_eq!(contents(&in_memory), contents(&one_piece));
    // equal materials share one allocation, across the streamed batches too
    let first = &streamed.objects[0].material;
    let same = streamed
        .objects
        .iter()
        .filter(|o| Arc::ptr_eq(&o.material, first))
        .count();
    let equal = streamed.objects.iter().filter(|o| o.material == *first).count();
    assert_eq!((same, equal), (6_000, 6_000));
}

#[test]
fn a_streamed_load_reports_errors_as_a_load_in_one_piece() {
    let dir = tempfile::tempdir().unwrap();
    // an object that does not build, past the first batches
    let bad_radius = replace_nth(&many_objects(30_000), "radius: 0.2)", "radius: -0.2)", 5_000);
    let one_piece = built_in_one_piece(&bad_radius).unwrap_err();
    assert!(one_piece.0.starts_with("objects[24995]"), "{one_piece:?}");
    let path = dir.path().join("bad_radius.ron");
    std::fs::write(&path, &bad_radius).unwrap();
    let message = Scene::load(&path).unwrap_err().to_string();
    assert_eq!(message, format!("{}: {}: {}", path.display(), one_piece.0, one_piece.1));
    // a syntax error keeps its line and column; so does one after the list
    for (name, text) in [
        (
            "bad_field.ron",
            replace_nth(
                &many_objects(30_000),
                "radius: 0.1, height",
                "radius: 0.1, heigth",
                4_000,
            ),
        ),
        (
            "bad_light.ron",
            many_objects(30_000).replace("(direction: (0, -1, 0))", "(direction: (0, -1, 0), x: 1)"),
        ),
    ] {
        let expected = sequential(&text).unwrap_err();
        let path = dir.path().join(name);
        std::fs::write(&path, &text).unwrap();
        let message = Scene::load(&path).unwrap_err().to_string();
        assert_eq!(
            message,
            format!(
                "{}:{}:{}: {}",
                path.display(),
                expected.span.start.line,
                expected.span.start.col,
                expected.code
            )
        );
        assert!(expected.span.start.line > 3_000, "{expected}");
    }
}

/// A scene of `n` plain spheres, as `scenes/bench/make_spheres.py` writes them (every tenth
/// named and coloured): the streamed load reads these without serde.
fn plain_spheres(n: usize) -> String {
    let mut text = String::from("Scene(\n    camera: (eye: (0, 40, -260), look_at: (0, 0, 0)),\n    objects: [\n");
    for i in 0..n {
        let (x, y, r) = (
            i as f64 * 0.013 - 97.5,
            -(i as f64).sqrt() / 7.0,
            0.05 + (i % 11) as f64 * 0.025,
        );
        if i % 10 == 0 {
            text.push_str(&format!(
                "        (name: \"ball {i}\", shape: Sphere(center: ({x:?}, {y:e}, 3), radius: {r:?}), material: (color: (0.{}, 0.5, 1))),\n",
                i % 1000
            ));
        } else {
            text.push_str(&format!(
                "        (shape: Sphere(center: ({x:?}, {y:e}, 3), radius: {r:?})),\n"
            ));
        }
    }
    text.push_str("    ],\n)\n");
    text
}

#[test]
fn plain_spheres_stream_to_the_objects_and_errors_of_a_load_in_one_piece() {
    let dir = tempfile::tempdir().unwrap();
    let text = plain_spheres(30_000);
    let path = dir.path().join("spheres.ron");
    std::fs::write(&path, &text).unwrap();
    let streamed = Scene::load(&path).unwrap();
    assert_eq!(streamed.objects.len(), 30_000);
    assert_eq!(contents(&streamed), contents(&built_in_one_piece(&text).unwrap()));
    // an object that does not build
    let bad_radius = replace_nth(&text, "radius: 0.05)", "radius: -0.05)", 2_000);
    let one_piece = built_in_one_piece(&bad_radius).unwrap_err();
    let path = dir.path().join("bad_radius.ron");
    std::fs::write(&path, &bad_radius).unwrap();
    let message = Scene::load(&path).unwrap_err().to_string();
    assert_eq!(message, format!("{}: {}: {}", path.display(), one_piece.0, one_piece.1));
    // syntax errors in plain spheres: RON's message, line and column
    for (name, bad) in [
        (
            "bad_number.ron",
            replace_nth(&text, "radius: 0.05)", "radius: 0.05e)", 2_000),
        ),
        (
            "bad_field.ron",
            replace_nth(&text, "radius: 0.05)", "radius: 0.05, colour: 1)", 2_000),
        ),
        ("two_commas.ron", replace_nth(&text, ")),\n", ")),,\n", 20_000)),
        ("missing_comma.ron", replace_nth(&text, ")),\n", "))\n", 20_000)),
        (
            "two_radii.ron",
            replace_nth(&text, "radius: 0.05)", "radius: 0.05, radius: 1)", 2_000),
        ),
    ] {
        let expected = sequential(&bad).unwrap_err();
        let path = dir.path().join(name);
        std::fs::write(&path, &bad).unwrap();
        let message = Scene::load(&path).unwrap_err().to_string();
        assert_eq!(
            message,
            format!(
                "{}:{}:{}: {}",
                path.display(),
                expected.span.start.line,
                expected.span.start.col,
                expected.code
            ),
            "{name}"
        );
        assert!(expected.span.start.line > 1_000, "{name}: {expected}");
    }
}
