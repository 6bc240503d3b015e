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
    /// The chain with every level wrapped in an identity `Transformed`, which stops flattening:
    /// the renderer walks the nested tree itself.
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

/// Alpha and depth are equal bit for bit; normals (and beauty, if `shading`) agree to `1e-6` (an
/// identity `Transformed` renormalises the normal, which may move it by an ulp).
///
/// Beauty is left out for hundreds of nested `Transformed`s: each multiplies the hit-error bound
/// that offsets shadow-ray origins by its map's Frobenius norm (√3 for the identity), so at 300
/// levels the bound is meaningless and shadows differ. That is `Transformed`'s bound, not CSG.
fn assert_same_hits(a: &Frame, b: &Frame, shading: bool) {
    for (aov, channels) in [(Aov::Alpha, 1), (Aov::Depth, 1)] {
        assert!(bits(a, aov, channels) == bits(b, aov, channels), "{aov:?} differs");
    }
    let compared: &[(Aov, usize)] = if shading {
        &[(Aov::Beauty, 3), (Aov::Normal, 3)]
    } else {
        &[(Aov::Normal, 3)]
    };
    for &(aov, channels) in compared {
        for c in 0..channels {
            let (x, y) = (a.planar_channel(aov, c), b.planar_channel(aov, c));
            let worst = x.iter().zip(&y).map(|(p, q)| (p - q).abs()).fold(0.0f32, f32::max);
            assert!(worst <= 1e-6, "{aov:?}[{c}] differs by {worst}");
        }
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
    assert_same_hits(&flat, &render_at(&holes_scene(16, Form::WrappedChain), 160, 120), true);
}

#[test]
fn three_hundred_level_chains_load_and_render_as_the_flat_difference() {
    let flat = render_at(&holes_scene(300, Form::Flat), 40, 30);
    assert_identical(&flat, &render_at(&holes_scene(300, Form::Chain), 40, 30));
    assert_same_hits(&flat, &render_at(&holes_scene(300, Form::WrappedChain), 40, 30), false);
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
