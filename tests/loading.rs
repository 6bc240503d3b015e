//! Loading large scenes: the `objects` list parsed in parallel gives exactly the descriptions of
//! the one-piece parse, and an error keeps its line and column.

use zeroset::scene::{parse_scene_desc, ron_options, SceneDesc};

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
