//! Boolean combinators from scene files: generated deep chains load (beyond RON's default
//! nesting limit), are flattened, and render exactly as the flat form.

use zeroset::aov::Aov;
use zeroset::render::{render, Frame, RenderOptions};
use zeroset::scene::Scene;

/// How the holes are subtracted from the box.
#[derive(Clone, Copy, Debug)]
enum Form {
    /// `Difference(children: [box, h₁, …, hₙ])`.
    Flat,
    /// `Difference(children: [Difference(children: [… box, h₁ …]), hₙ])`, left-deep.
    Chain,
    /// The chain with every level wrapped in an identity `Transformed`, which flattening looks
    /// through: it loads as the flat form too.
    WrappedChain,
}

/// The RON scene of a box with `holes` cylindrical holes through it (a square grid), in `form`.
fn holes_scene(holes: usize, form: Form) -> String {
    let side = (holes as f64).sqrt().ceil() as usize;
    let hole = |i: usize| {
        let (col, row) = ((i % side) as f64, (i / side) as f64);
        let x = -1.6 + 3.2 * (col + 0.5) / side as f64;
        let y = -1.6 + 3.2 * (row + 0.5) / side as f64;
        format!(
            "Cylinder(base: ({x}, {y}, -1), axis: (0, 0, 1), radius: {}, height: 2, capped: true)",
            1.2 / side as f64
        )
    };
    let block = "Box(min: (-2, -2, -0.5), max: (2, 2, 0.5))".to_string();
    let shape = match form {
        Form::Flat => {
            let mut children = vec![block];
            children.extend((0..holes).map(hole));
            format!("Difference(children: [{}])", children.join(", "))
        }
        Form::Chain | Form::WrappedChain => (0..holes).fold(block, |acc, i| {
            let level = format!("Difference(children: [{acc}, {}])", hole(i));
            match form {
                Form::WrappedChain => format!("Transformed(shape: {level}, transform: ())"),
                _ => level,
            }
        }),
    };
    format!(
        "Scene(camera: (eye: (1.5, 2, -6), look_at: (0, 0, 0), width: 160, height: 120),
  objects: [(name: \"holed box\", shape: {shape}), (shape: Plane(normal: (0, 1, 0), offset: -2.5))],
  lights: [Directional(direction: (-1, -2, 1.5))])"
    )
}

fn render_at(text: &str, width: u32, height: u32) -> Frame {
    let mut scene = Scene::from_ron(text, "holes.ron").unwrap_or_else(|e| panic!("{e}"));
    scene.camera = scene.camera.with_resolution(width, height).unwrap();
    render(
        &scene,
        &RenderOptions {
            aovs: vec![Aov::Beauty, Aov::Alpha, Aov::Depth, Aov::Normal],
            ..RenderOptions::default()
        },
    )
}

fn bits(frame: &Frame, aov: Aov, channels: usize) -> Vec<u32> {
    (0..channels)
        .flat_map(|c| {
            frame
                .planar_channel(aov, c)
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Every channel of the two frames is equal bit for bit, and the object covers many pixels.
fn assert_identical(a: &Frame, b: &Frame) {
    for (aov, channels) in [(Aov::Beauty, 3), (Aov::Alpha, 1), (Aov::Depth, 1), (Aov::Normal, 3)] {
        assert!(bits(a, aov, channels) == bits(b, aov, channels), "{aov:?} differs");
    }
    assert_covered(a);
}

fn assert_covered(a: &Frame) {
    let hits = a.planar_channel(Aov::Alpha, 0).iter().filter(|&&v| v == 1.0).count();
    assert!(
        hits > a.planar_channel(Aov::Alpha, 0).len() / 4,
        "only {hits} pixels hit"
    );
}

#[test]
fn sixteen_hole_chain_renders_as_the_flat_difference() {
    let flat = render_at(&holes_scene(16, Form::Flat), 160, 120);
    assert_identical(&flat, &render_at(&holes_scene(16, Form::Chain), 160, 120));
    // the identity transforms are folded at load: the same tree, so the same bits
    assert_identical(&flat, &render_at(&holes_scene(16, Form::WrappedChain), 160, 120));
}

#[test]
fn three_hundred_level_chains_load_and_render_as_the_flat_difference() {
    let flat = render_at(&holes_scene(300, Form::Flat), 40, 30);
    assert_identical(&flat, &render_at(&holes_scene(300, Form::Chain), 40, 30));
    assert_identical(&flat, &render_at(&holes_scene(300, Form::WrappedChain), 40, 30));
}

/// The wrapped chain loads as one flat `Difference` of the box and its 16 holes, no
/// `Transformed` left; a non-identity transform is kept (and nested ones composed into one).
#[test]
fn identity_transforms_are_folded_and_nested_ones_composed() {
    let scene = Scene::from_ron(&holes_scene(16, Form::WrappedChain), "w.ron").unwrap();
    let tree = format!("{:?}", scene.objects[0].primitive);
    assert!(!tree.contains("Transformed"), "{tree}");
    assert_eq!(tree.matches("Cylinder").count(), 16, "{tree}");
    assert_eq!(tree.matches("Csg").count(), 1, "one flat Difference: {tree}");
    // a unit sphere moved by (1, 0, 0), then scaled by 2: centre (2, 0, 0), radius 2; a ray
    // from (2, 0, −10) along +z meets it at t = 8, and (3, 0, −10) at t = 10 − √3
    let nested = "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0)), objects: [(shape: \
                  Transformed(shape: Transformed(shape: Sphere(radius: 1), transform: (translate: (1, 0, 0))), \
                  transform: (scale: (2, 2, 2))))])";
    let scene = Scene::from_ron(nested, "n.ron").unwrap();
    let tree = format!("{:?}", scene.objects[0].primitive);
    assert_eq!(tree.matches("Transformed").count(), 1, "composed into one: {tree}");
    for (x, expected) in [(2.0, 8.0), (3.0, 10.0 - 3f64.sqrt())] {
        let ray = zeroset_primitives::Ray::new(glam::DVec3::new(x, 0.0, -10.0), glam::DVec3::Z);
        let (_, hit) = scene.intersect(&ray, zeroset_primitives::Interval::POSITIVE).unwrap();
        assert!((hit.t - expected).abs() < 1e-12, "x = {x}: t = {}", hit.t);
    }
    // an error inside a folded identity transform names the path through it
    let text = holes_scene(3, Form::WrappedChain).replacen("radius: 0.6", "radius: -0.6", 1);
    let message = Scene::from_ron(&text, "bad.ron").unwrap_err().to_string();
    assert!(
        message.contains("children[0] (Transformed).shape (Difference).children[0] (Transformed)"),
        "{message}"
    );
}

#[test]
fn nesting_beyond_the_limit_is_refused_with_a_message() {
    // 2,000 levels: beyond `RON_NESTING_LIMIT`, refused with its position and no stack overflow
    let err = Scene::from_ron(&holes_scene(2_000, Form::Chain), "deep.ron").unwrap_err();
    let message = err.to_string();
    assert!(message.starts_with("deep.ron:2:"), "{message}");
    assert!(
        message.contains(&format!("more than {} levels", zeroset::scene::RON_NESTING_LIMIT)),
        "{message}"
    );
    assert!(!message.contains("serde_stacker"), "{message}");
}

/// A hole of negative radius deep in a chain is named by its path through the flattened levels.
#[test]
fn errors_inside_a_flattened_chain_name_the_path() {
    let text = holes_scene(3, Form::Chain).replacen("radius: 0.6", "radius: -0.6", 1);
    let message = Scene::from_ron(&text, "bad.ron").unwrap_err().to_string();
    assert!(
        message.contains("children[0] (Difference).children[0] (Difference).children[1] (Cylinder).radius"),
        "{message}"
    );
}
