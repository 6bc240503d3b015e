//! End-to-end tests of the `zeroset` binary: render, query, primitives, and bad input (each bad
//! input must fail with a non-zero exit status and a message that locates the problem, never a
//! panic).

mod support;

use exr::meta::MetaData;
use exr::prelude::*;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use support::{
    assert_fails, assert_ok, bin, channel_names, file_names, p, read_channels, run, stderr, stdout, write_file,
};
use zeroset::aov::Aov;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

fn set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|s| s.to_string()).collect()
}

#[test]
fn render_default_scene() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&["render", "scenes/default.ron", "-o", p(dir.path())]);
    assert_ok(&o, "render default");
    assert_eq!(
        file_names(dir.path()),
        set(&[
            "default.exr",
            "default.cameras.json",
            "default.beauty.png",
            "default.depth.png",
            "default.normal.png"
        ])
    );
    let out = stdout(&o);
    let last = out.lines().last().expect("some output");
    assert!(last.contains("Mrays/s"), "last line: {last:?}");
    assert!(last.contains("960x540"), "last line: {last:?}");
    let exr = dir.path().join("default.exr");
    assert_eq!(
        channel_names(&exr),
        set(&["R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z"])
    );
    let meta = MetaData::read_from_file(&exr, true).unwrap();
    assert_eq!(meta.headers[0].layer_size, Vec2(960, 540));
    for png in ["default.beauty.png", "default.depth.png", "default.normal.png"] {
        assert_eq!(
            image::image_dimensions(dir.path().join(png)).unwrap(),
            (960, 540),
            "{png}"
        );
    }
}

#[test]
fn render_resized_matches_library_render() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "64",
        "--height",
        "36",
        "--threads",
        "2",
    ]);
    assert_ok(&o, "render --width 64 --height 36");
    let exr = dir.path().join("default.exr");
    let meta = MetaData::read_from_file(&exr, true).unwrap();
    assert_eq!(meta.headers[0].layer_size, Vec2(64, 36));
    assert_eq!(meta.headers[0].shared_attributes.display_window.size, Vec2(64, 36));
    for png in ["default.beauty.png", "default.depth.png", "default.normal.png"] {
        assert_eq!(
            image::image_dimensions(dir.path().join(png)).unwrap(),
            (64, 36),
            "{png}"
        );
    }

    // the file holds what the library renders for the same scene at 64×36 (vfov kept)
    let mut scene = Scene::load(Path::new("scenes/default.ron")).unwrap();
    let vfov = scene.camera.tan_half_vfov;
    scene.camera = scene.camera.with_resolution(64, 36).unwrap();
    assert!((scene.camera.tan_half_vfov - vfov).abs() < 1e-12);
    let frame = render(&scene, &RenderOptions::default());
    let mut inf = 0;
    let channels = read_channels(&exr);
    assert_eq!(channels.len(), 8);
    for (name, v) in channels {
        let (aov, k) = Aov::DEFAULT
            .iter()
            .find_map(|a| a.channels().iter().position(|c| *c == name).map(|k| (*a, k)))
            .unwrap_or_else(|| panic!("unexpected channel {name}"));
        let expected = frame.planar_channel(aov, k);
        assert!(
            v.iter().map(|x| x.to_bits()).eq(expected.iter().map(|x| x.to_bits())),
            "{name} differs from the library render"
        );
        if name == "Z" {
            inf = v.iter().filter(|z| z.is_infinite()).count();
        }
    }
    assert!(inf > 0, "the sky misses: +inf depth by default");
}

/// `--aov Depth,Normal`: the AOV names as documented (and as written in scene files).
///
/// Fails at the time of writing: clap's `ValueEnum` derive on `Aov` (src/aov.rs) only accepts the
/// kebab-case names `depth`, `camera-normal`, … and rejects `Depth`.
#[test]
fn render_aov_flag_selects_channels() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "64",
        "--height",
        "36",
        "--aov",
        "Depth,Normal",
    ]);
    assert_ok(&o, "render --aov Depth,Normal");
    let exr = dir.path().join("default.exr");
    assert_eq!(
        channel_names(&exr),
        set(&["Z", "N.X", "N.Y", "N.Z"]),
        "only those channels"
    );
    let meta = MetaData::read_from_file(&exr, true).unwrap();
    assert_eq!(meta.headers[0].layer_size, Vec2(64, 36));
    let names = file_names(dir.path());
    assert!(
        !names.contains("default.beauty.png"),
        "no beauty preview without Beauty: {names:?}"
    );
}

/// `--crop x0,y0,x1,y1` as documented in `zeroset render --help`.
///
/// Fails at the time of writing: `#[arg(long, value_delimiter = ',', num_args = 4)]` (src/cli/mod.rs)
/// makes clap demand four separate arguments (`--crop 10 3 50 30`) and reject `--crop 10,3,50,30`.
#[test]
fn render_crop_flag_sets_data_window() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "64",
        "--height",
        "36",
        "--crop",
        "10,3,50,30",
        "--no-previews",
    ]);
    assert_ok(&o, "render --crop 10,3,50,30");
    let last = stdout(&o).lines().last().unwrap_or_default().to_string();
    assert!(last.contains("40x27") && last.contains("Mrays/s"), "{last}");
    let exr = dir.path().join("default.exr");
    let meta = MetaData::read_from_file(&exr, true).unwrap();
    let h = &meta.headers[0];
    assert_eq!(h.shared_attributes.display_window.size, Vec2(64, 36));
    assert_eq!(h.shared_attributes.display_window.position, Vec2(0, 0));
    assert_eq!(h.data_window().position, Vec2(10, 3));
    assert_eq!(h.data_window().size, Vec2(40, 27));
}

#[test]
fn render_to_exr_path_with_depth_miss() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sub").join("shot.exr");
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(&out),
        "--width",
        "64",
        "--height",
        "36",
        "--depth-miss",
        "0",
        "--no-previews",
    ]);
    assert_ok(&o, "render -o shot.exr --depth-miss 0");
    assert_eq!(
        file_names(&dir.path().join("sub")),
        set(&["shot.exr", "shot.cameras.json"]),
        "no previews"
    );
    let channels = read_channels(&out);
    let get = |n: &str| channels.iter().find(|(name, _)| name == n).unwrap().1.clone();
    let (z, a) = (get("Z"), get("A"));
    let misses = a.iter().filter(|x| **x == 0.0).count();
    assert!(misses > 0, "the image includes sky");
    for (z, a) in z.iter().zip(&a) {
        if *a == 0.0 {
            assert_eq!(*z, 0.0, "--depth-miss 0");
        } else {
            assert!(z.is_finite() && *z > 0.0);
        }
    }
}

const QUERY_SCENE: &str = r#"Scene(
    camera: (eye: (0, 0, -5), look_at: (0, 0, 0)),
    objects: [
        (name: "ball", shape: Sphere(center: (0, 0, 0), radius: 1)),
        (name: "floor", shape: Plane(normal: (0, 1, 0), offset: -2)),
    ],
)
"#;

#[test]
fn query_hits_and_misses() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "q.ron", QUERY_SCENE);
    let rays = dir.path().join("rays.csv");
    // (ray line, expected: None for a miss or Some((t, normal, id, name)))
    type Expect = Option<(f64, [f64; 3], u32, &'static str)>;
    let r = (1.0f64 - 0.34).sqrt(); // sqrt(1 − 0.5² − 0.3²)
    let cases: Vec<(&str, Expect)> = vec![
        ("0,0,-5,0,0,1", Some((4.0, [0.0, 0.0, -1.0], 0, "ball"))),
        ("0.5,0.3,-5,0,0,1", Some((5.0 - r, [0.5, 0.3, -r], 0, "ball"))),
        // t is in units of |d|
        ("0,0,-5,0,0,2", Some((2.0, [0.0, 0.0, -1.0], 0, "ball"))),
        ("0,5,0,0,1,0", None),
        // tmax before the sphere
        ("0,0,-5,0,0,1,0,3", None),
        // tmin past the front: the back of the sphere, outward normal not flipped
        ("0,0,-5,0,0,1,4.5,100", Some((6.0, [0.0, 0.0, 1.0], 0, "ball"))),
        // unnormalised direction down to the floor y = −2: t = 2
        ("3,0,-5,0,-1,0.5", Some((2.0, [0.0, 1.0, 0.0], 1, "floor"))),
        // from inside the sphere
        ("0,0,0,1,0,0", Some((1.0, [1.0, 0.0, 0.0], 0, "ball"))),
        // with spaces, 8 fields, range excluding everything
        (" 0, 0, -5, 0, 0, 1, 6.5, 7 ", None),
    ];
    let mut text = String::from("ox,oy,oz,dx,dy,dz,tmin,tmax\n");
    for (i, (line, _)) in cases.iter().enumerate() {
        text.push_str(line);
        text.push('\n');
        if i == 3 {
            text.push_str("# a comment\n\n");
        }
    }
    std::fs::write(&rays, &text).unwrap();
    let out = dir.path().join("hits.csv");
    let o = run(&["query", p(&scene), "--rays", p(&rays), "-o", p(&out)]);
    assert_ok(&o, "query");
    let csv = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "hit,t,px,py,pz,nx,ny,nz,id,name,u,v");
    assert_eq!(lines.len(), cases.len() + 1, "{csv}");
    for ((ray, expected), line) in cases.iter().zip(&lines[1..]) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 12, "{line}");
        match expected {
            None => assert_eq!(*line, "0,,,,,,,,,,,", "ray {ray:?}"),
            Some((t, n, id, name)) => {
                assert_eq!(f[0], "1", "ray {ray:?}: {line}");
                let t_got: f64 = f[1].parse().unwrap();
                assert!((t_got - t).abs() <= 1e-9 * t.max(1.0), "ray {ray:?}: t {t_got} vs {t}");
                let v: Vec<f64> = ray.split(',').map(|s| s.trim().parse().unwrap()).collect();
                for k in 0..3 {
                    let pk: f64 = f[2 + k].parse().unwrap();
                    let want = v[k] + t * v[3 + k];
                    assert!((pk - want).abs() <= 1e-9, "ray {ray:?}: p[{k}] {pk} vs {want}");
                    let nk: f64 = f[5 + k].parse().unwrap();
                    assert!((nk - n[k]).abs() <= 1e-9, "ray {ray:?}: n[{k}] {nk} vs {}", n[k]);
                }
                assert_eq!(f[8], id.to_string(), "ray {ray:?}");
                assert_eq!(f[9], *name, "ray {ray:?}");
            }
        }
    }
    // stdout output
    let o = run(&["query", p(&scene), "--rays", p(&rays)]);
    assert_ok(&o, "query to stdout");
    assert_eq!(stdout(&o), csv);
}

#[test]
fn primitives_lists_builtins() {
    let o = run(&["primitives"]);
    assert_ok(&o, "primitives");
    let names: BTreeSet<String> = stdout(&o).lines().map(|l| l.trim().to_string()).collect();
    for n in ["Sphere", "Plane", "Box", "Cylinder", "Cone", "Ellipsoid"] {
        assert!(names.contains(n), "{n} missing from {names:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Bad input

const CAMERA: &str = "camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 32, height: 18)";

/// Writes `text` to `dir/name` and renders it; the command must fail.
fn render_bad(dir: &Path, name: &str, text: &str) -> (PathBuf, Output) {
    let path = write_file(dir, name, text);
    let out = dir.join("out");
    let o = run(&["render", p(&path), "-o", p(&out), "--no-previews"]);
    (path, o)
}

/// `path:line:column:` with the given line and some column.
fn assert_position(err: &str, path: &Path, line: usize) {
    let prefix = format!("{}:{line}:", p(path));
    let at = err
        .find(&prefix)
        .unwrap_or_else(|| panic!("stderr should contain {prefix:?}COLUMN:\n{err}"));
    let rest = &err[at + prefix.len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    assert!(
        !digits.is_empty() && rest[digits.len()..].starts_with(':'),
        "a column number after {prefix:?}:\n{err}"
    );
}

fn scene_with_object(object: &str) -> String {
    format!("Scene(\n    {CAMERA},\n    objects: [\n        {object},\n    ],\n)\n")
}

#[test]
fn bad_ron_syntax() {
    let dir = tempfile::tempdir().unwrap();
    // line 4: missing comma between the two objects
    let text = format!(
        "Scene(\n    {CAMERA},\n    objects: [\n        (shape: Sphere(radius: 1)) (shape: Sphere(radius: 2)),\n    ],\n)\n"
    );
    let (path, o) = render_bad(dir.path(), "syntax.ron", &text);
    let err = assert_fails(&o, &[], "RON syntax error");
    assert_position(&err, &path, 4);
    // unbalanced parenthesis at the end of the file
    let (path, o) = render_bad(
        dir.path(),
        "unbalanced.ron",
        &format!("Scene(\n    {CAMERA},\n    objects: [\n"),
    );
    let err = assert_fails(&o, &[], "unbalanced");
    assert!(err.contains(&format!("{}:", p(&path))), "{err}");
}

#[test]
fn bad_unknown_field() {
    let dir = tempfile::tempdir().unwrap();
    let (path, o) = render_bad(
        dir.path(),
        "radus.ron",
        &scene_with_object("(shape: Sphere(radus: 1.0))"),
    );
    let err = assert_fails(&o, &["radus"], "unknown field");
    assert_position(&err, &path, 4);
    // unknown camera field
    let (path, o) = render_bad(
        dir.path(),
        "fov.ron",
        "Scene(\n  camera: (eye: (0, 0, -5), fov: 40),\n)\n",
    );
    let err = assert_fails(&o, &["fov"], "unknown camera field");
    assert_position(&err, &path, 2);
}

#[test]
fn bad_unknown_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let (path, o) = render_bad(
        dir.path(),
        "torus.ron",
        &scene_with_object("(shape: Torus(major: 1, minor: 0.2))"),
    );
    let err = assert_fails(
        &o,
        &["Torus", "Sphere", "Plane", "Box", "Cylinder", "Cone", "Ellipsoid"],
        "unknown primitive",
    );
    assert_position(&err, &path, 4);
}

#[test]
fn bad_radius_values() {
    let dir = tempfile::tempdir().unwrap();
    for (name, radius) in [("zero", "0"), ("negative", "-1.5"), ("nan", "NaN"), ("inf", "inf")] {
        let object = format!(
            "(name: \"first\", shape: Sphere(radius: 1)),\n        (name: \"ball\", shape: Sphere(radius: {radius}))"
        );
        let (path, o) = render_bad(dir.path(), &format!("{name}.ron"), &scene_with_object(&object));
        assert_fails(
            &o,
            &[p(&path), "objects[1]", "ball", "radius"],
            &format!("{name} radius"),
        );
    }
    // other primitives' radii
    for (name, object) in [
        ("cylinder", "(shape: Cylinder(radius: 0))"),
        ("cone", "(shape: Cone(base_radius: -1))"),
        ("ellipsoid", "(shape: Ellipsoid(radii: (1, 0, 1)))"),
    ] {
        let (path, o) = render_bad(dir.path(), &format!("{name}.ron"), &scene_with_object(object));
        assert_fails(&o, &[p(&path), "objects[0]"], name);
    }
}

fn camera_scene(camera: &str) -> String {
    format!("Scene(\n    camera: ({camera}),\n    objects: [(shape: Sphere(radius: 1))],\n)\n")
}

#[test]
fn bad_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "up_parallel",
            "eye: (0, 0, -5), look_at: (0, 0, 0), up: (0, 0, 1)",
            "up",
        ),
        (
            "up_antiparallel",
            "eye: (0, 3, 0), look_at: (0, 0, 0), up: (0, 1, 0)",
            "up",
        ),
        ("vfov0", "eye: (0, 0, -5), vfov_deg: 0", "vfov_deg"),
        ("vfov180", "eye: (0, 0, -5), vfov_deg: 180", "vfov_deg"),
        ("vfov_nan", "eye: (0, 0, -5), vfov_deg: NaN", "vfov_deg"),
        ("hfov180", "eye: (0, 0, -5), hfov_deg: 180", "hfov_deg"),
        ("width0", "eye: (0, 0, -5), width: 0", "width"),
        ("height0", "eye: (0, 0, -5), height: 0", "height"),
        (
            "inconsistent_fov",
            "eye: (0, 0, -5), vfov_deg: 40, hfov_deg: 40, width: 64, height: 36",
            "hfov_deg",
        ),
        ("look_at_eye", "eye: (1, 2, 3), look_at: (1, 2, 3)", "look_at"),
        ("eye_inf", "eye: (0, 0, inf)", "eye"),
        ("zero_up", "eye: (0, 0, -5), up: (0, 0, 0)", "up"),
        (
            "both_targets",
            "eye: (0, 0, -5), look_at: (0, 0, 0), direction: (0, 0, 1)",
            "direction",
        ),
    ];
    for (name, camera, field) in cases {
        let (path, o) = render_bad(dir.path(), &format!("{name}.ron"), &camera_scene(camera));
        assert_fails(&o, &[p(&path), "camera", field], name);
    }
}

#[test]
fn consistent_vfov_and_hfov_are_accepted() {
    // the inverse of `inconsistent_fov`: matching values load (tan(hfov/2) = tan(vfov/2)·W/H)
    let vfov = 40.0f64;
    let hfov = 2.0 * ((vfov.to_radians() / 2.0).tan() * 64.0 / 36.0).atan().to_degrees();
    let text = camera_scene(&format!(
        "eye: (0, 0, -5), vfov_deg: {vfov:?}, hfov_deg: {hfov:?}, width: 64, height: 36"
    ));
    let scene = Scene::from_ron(&text, "fov.ron").expect("consistent fields load");
    assert!((scene.camera.tan_half_vfov - (vfov.to_radians() / 2.0).tan()).abs() < 1e-12);
}

#[test]
fn bad_boxes_and_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "box_flat",
            "(name: \"slab\", shape: Box(min: (0, 0, 0), max: (1, 0, 1)))",
            &["slab", "max"][..],
        ),
        (
            "box_inverted",
            "(name: \"slab\", shape: Box(min: (0, 0, 0), max: (1, -1, 1)))",
            &["slab", "max"][..],
        ),
        (
            "box_nan",
            "(name: \"slab\", shape: Box(min: (0, NaN, 0), max: (1, 1, 1)))",
            &["slab", "min"][..],
        ),
        (
            "translate_inf",
            "(name: \"t\", shape: Sphere(radius: 1), transform: (translate: (inf, 0, 0)))",
            &["\"t\"", "transform.translate"][..],
        ),
        (
            "scale_zero",
            "(name: \"t\", shape: Sphere(radius: 1), transform: (scale: (1, 0, 1)))",
            &["\"t\"", "transform.scale"][..],
        ),
        (
            "scale_nan",
            "(name: \"t\", shape: Sphere(radius: 1), transform: (scale: (1, NaN, 1)))",
            &["\"t\"", "transform.scale"][..],
        ),
        (
            "rotate_zero_axis",
            "(name: \"t\", shape: Sphere(radius: 1), transform: (rotate: (axis: (0, 0, 0), degrees: 30)))",
            &["\"t\"", "transform.rotate"][..],
        ),
        (
            "rotate_nan_angle",
            "(name: \"t\", shape: Sphere(radius: 1), transform: (rotate: (axis: (0, 1, 0), degrees: NaN)))",
            &["\"t\"", "transform.rotate"][..],
        ),
        (
            "plane_zero_normal",
            "(shape: Plane(normal: (0, 0, 0)))",
            &["objects[0]", "normal"][..],
        ),
        (
            "plane_both",
            "(shape: Plane(normal: (0, 1, 0), offset: 1, point: (0, 1, 0)))",
            &["objects[0]", "point"][..],
        ),
    ];
    for (name, object, needles) in cases {
        let (path, o) = render_bad(dir.path(), &format!("{name}.ron"), &scene_with_object(object));
        let mut all = vec![p(&path), "objects[0]"];
        all.extend_from_slice(needles);
        assert_fails(&o, &all, name);
    }
}

#[test]
fn bad_materials_and_lights() {
    let dir = tempfile::tempdir().unwrap();
    let (path, o) = render_bad(
        dir.path(),
        "material.ron",
        &scene_with_object("(shape: Sphere(radius: 1), material: (shininess: 0))"),
    );
    assert_fails(&o, &[p(&path), "objects[0]", "material"], "shininess 0");
    let text = format!("Scene({CAMERA}, lights: [Directional(direction: (0, 0, 0))])");
    let (path, o) = render_bad(dir.path(), "light.ron", &text);
    assert_fails(&o, &[p(&path), "lights[0]", "direction"], "zero light direction");
    let text = format!("Scene({CAMERA}, outputs: (aovs: []))");
    let (path, o) = render_bad(dir.path(), "no_aovs.ron", &text);
    assert_fails(&o, &[p(&path), "aovs"], "empty aovs");
}

#[test]
fn bad_missing_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("does_not_exist.ron");
    let o = run(&["render", p(&missing), "-o", p(&dir.path().join("out"))]);
    assert_fails(&o, &[p(&missing)], "missing scene");
    assert!(!dir.path().join("out").exists(), "nothing written");
    let o = run(&["query", p(&missing), "--rays", p(&missing)]);
    assert_fails(&o, &[p(&missing)], "query: missing scene");
}

#[test]
fn bad_command_line_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let base = [
        "render",
        "scenes/default.ron",
        "-o",
        p(&out),
        "--width",
        "64",
        "--height",
        "36",
    ];
    let cases: [(&[&str], &[&str]); 9] = [
        (&["--crop", "10,5,5,30"], &["--crop"]),
        (&["--crop", "0,0,65,36"], &["--crop"]),
        (&["--crop", "0,36,64,36"], &["--crop"]),
        (&["--crop", "1,2,3"], &["crop"]),
        (&["--crop", "a,b,c,d"], &["crop"]),
        (&["--threads", "0"], &["--threads"]),
        (&["--aov", "Bogus"], &["Bogus"]),
        (&["--width", "0"], &["width"]),
        (&["--depth-miss", "NaN"], &["--depth-miss"]),
    ];
    // (while `--crop a,b,c,d` is rejected by clap itself — see `render_crop_flag_sets_data_window`
    // — the first three crop cases fail for that reason rather than for their values)
    for (extra, needles) in cases {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let o = run(&args);
        assert_fails(&o, needles, &format!("{extra:?}"));
    }
    assert!(
        !out.join("default.exr").exists(),
        "no output written for rejected command lines"
    );
}

#[test]
fn bad_query_csv() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "q.ron", QUERY_SCENE);
    let cases = [
        ("words", "ox,oy,oz,dx,dy,dz\n0,0,-5,0,0,1\n0,0,-5,zero,0,1\n", 3),
        ("count", "0,0,-5,0,0,1\n0,0,-5,0,0\n", 2),
        ("seven", "0,0,-5,0,0,1\n\n0,0,-5,0,0,1,0\n", 3),
        ("zero_dir", "0,0,-5,0,0,1\n0,0,-5,0,0,0\n", 2),
        ("nan", "0,0,NaN,0,0,1\n", 1),
        ("inf_dir", "# c\n0,0,0,inf,0,1\n", 2),
        ("range", "0,0,-5,0,0,1,5,1\n", 1),
        ("range_nan", "0,0,-5,0,0,1,NaN,1\n", 1),
        ("second_header", "ox,oy,oz,dx,dy,dz\nox,oy,oz,dx,dy,dz\n", 2),
    ];
    for (name, text, line) in cases {
        let rays = write_file(dir.path(), format!("{name}.csv"), text);
        let o = run(&["query", p(&scene), "--rays", p(&rays)]);
        assert_fails(&o, &[&format!("{}:{line}:", p(&rays))], &format!("query {name}"));
        assert!(stdout(&o).is_empty(), "query {name}: no partial output");
    }
    let o = run(&["query", p(&scene), "--rays", p(&dir.path().join("none.csv"))]);
    assert_fails(&o, &["none.csv"], "missing rays file");
}

// ---------------------------------------------------------------------------------------------
// Output conventions and resources (issue 12)

#[test]
fn output_path_with_another_extension_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("img.png");
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(&png),
        "--width",
        "32",
        "--height",
        "18",
    ]);
    let err = assert_fails(&o, &["img.png", ".exr"], "-o img.png");
    assert!(!png.exists(), "no directory named img.png created\n{err}");
    // an existing directory with a dot in its name is still a directory
    let dotted = dir.path().join("renders.v2");
    std::fs::create_dir(&dotted).unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(&dotted),
        "--width",
        "32",
        "--height",
        "18",
    ]);
    assert_ok(&o, "existing dotted directory");
    assert!(dotted.join("default.exr").exists());
}

#[test]
fn huge_renders_are_refused_up_front_with_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (extra, needle) in [
        (&["--width", "100000", "--height", "100000"][..], "100000x100000"),
        (&["--spp", "4294967295"][..], "4294967295 spp"),
    ] {
        let mut args = vec!["render", "scenes/default.ron", "-o", p(&out)];
        args.extend_from_slice(extra);
        let start = std::time::Instant::now();
        let o = run(&args);
        let seconds = start.elapsed().as_secs_f64();
        let err = assert_fails(&o, &[needle, "of memory", "available"], &format!("{extra:?}"));
        assert_eq!(o.status.code(), Some(1), "{err}");
        // the estimate is in the message, in bytes with a unit
        assert!(err.contains(" TB ") || err.contains(" GB "), "{err}");
        assert!(seconds < 5.0, "{extra:?}: refused after {seconds} s");
        assert!(!out.join("default.exr").exists());
    }
}

#[test]
fn threads_are_capped_with_a_warning_and_t_is_an_alias() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "32",
        "--height",
        "18",
        "-t",
        "100000",
    ]);
    assert_ok(&o, "-t 100000");
    let err = stderr(&o);
    assert!(err.contains("warning: --threads 100000 capped at"), "{err}");
    let cores = std::thread::available_parallelism().unwrap().get();
    assert!(
        stdout(&o).contains(&format!("on {} threads", 4 * cores)),
        "{}",
        stdout(&o)
    );
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "32",
        "--height",
        "18",
        "-t",
        "1",
    ]);
    assert_ok(&o, "-t 1");
    assert!(stdout(&o).contains("on 1 threads"), "{}", stdout(&o));
}

#[test]
fn aov_all_writes_every_channel() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "32",
        "--height",
        "18",
        "--aov",
        "all",
        "--no-previews",
    ]);
    assert_ok(&o, "--aov all");
    let expected: BTreeSet<String> = Aov::ALL
        .iter()
        .flat_map(|a| a.channels().iter().map(|c| c.to_string()))
        .collect();
    assert_eq!(expected.len(), 22);
    assert_eq!(channel_names(&dir.path().join("default.exr")), expected);
}

#[test]
fn os_errors_are_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.ron");
    let o = run(&["render", p(&missing)]);
    let err = assert_fails(&o, &["missing.ron", "os error 2"], "missing scene");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
    // an output directory that cannot be created (a file is in the way) is found before tracing
    let blocker = write_file(dir.path(), "file", "x");
    let target = blocker.join("sub");
    let o = run(&["render", "scenes/default.ron", "-o", p(&target)]);
    let err = assert_fails(&o, &["output directory", "file/sub"], "unwritable output");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
    assert!(!stdout(&o).contains("rendered"), "refused before rendering");
}

#[test]
fn summary_reports_trace_and_wall_time_and_a_writing_status() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/default.ron",
        "-o",
        p(dir.path()),
        "--width",
        "64",
        "--height",
        "36",
    ]);
    assert_ok(&o, "render");
    let out = stdout(&o);
    let last = out.lines().last().unwrap();
    let number_after = |key: &str| -> f64 {
        let rest = &last[last.find(key).unwrap_or_else(|| panic!("{key} in {last}")) + key.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    let (trace, wall, write) = (number_after("trace "), number_after("wall "), number_after("write "));
    assert!(trace > 0.0 && write > 0.0 && wall >= trace + write - 2e-3, "{last}");
    assert!(stderr(&o).contains("writing "), "{}", stderr(&o));
}

#[test]
fn render_compression_flag_sets_the_codec() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, codec) in [
        ("none", Compression::Uncompressed),
        ("rle", Compression::RLE),
        ("zips", Compression::ZIP1),
        ("zip", Compression::ZIP16),
        ("piz", Compression::PIZ),
    ] {
        let path = dir.path().join(format!("{flag}.exr"));
        let o = run(&[
            "render",
            "scenes/default.ron",
            "-o",
            p(&path),
            "--width",
            "32",
            "--height",
            "18",
            "--compression",
            flag,
        ]);
        assert_ok(&o, flag);
        let meta = MetaData::read_from_file(&path, true).unwrap();
        assert_eq!(meta.headers[0].compression, codec, "{flag}");
    }
    let o = run(&["render", "scenes/default.ron", "--compression", "pxr24"]);
    assert_fails(&o, &["pxr24"], "lossy codec");
}

#[test]
fn merge_command_assembles_crops_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let size = ["--width", "48", "--height", "30"];
    let render_to = |name: &str, crop: Option<&str>| {
        let path = dir.path().join(name);
        let mut args = vec![
            "render",
            "scenes/default.ron",
            "-o",
            p(&path),
            "--aov",
            "all",
            "--no-previews",
        ];
        args.extend_from_slice(&size);
        if let Some(c) = crop {
            args.extend_from_slice(&["--crop", c]);
        }
        assert_ok(&run(&args), name);
        path
    };
    let full = render_to("full.exr", None);
    let left = render_to("left.exr", Some("0,0,17,30"));
    let right = render_to("right.exr", Some("17,0,48,30"));
    let merged = dir.path().join("merged.exr");
    let o = run(&["merge", p(&left), p(&right), "-o", p(&merged)]);
    assert_ok(&o, "merge");
    let (a, b) = (read_channels(&merged), read_channels(&full));
    assert_eq!(a.len(), 22);
    for ((na, va), (nb, vb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(
            va.iter().map(|x| x.to_bits()).eq(vb.iter().map(|x| x.to_bits())),
            "channel {na}"
        );
    }
    assert_eq!(std::fs::read(&merged).unwrap(), std::fs::read(&full).unwrap());
    let o = run(&["merge", p(&left), "-o", p(&dir.path().join("half.exr"))]);
    assert_fails(&o, &["missing"], "merge of one crop");
    assert!(!dir.path().join("half.exr").exists());
}

/// A NumPy 1.0 `.npy` file of `<f8` values, shape `(rows, columns)`, written here independently of
/// zeroset's writer.
fn npy_bytes(values: &[f64], columns: usize) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {columns}), }}",
        values.len() / columns
    );
    let mut header = dict.into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(&header);
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

/// `(shape, values)` of a `<f8` C-order `.npy` file.
fn read_npy(bytes: &[u8]) -> ((usize, usize), Vec<f64>) {
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(
        header.contains("'descr': '<f8'") && header.contains("'fortran_order': False"),
        "{header}"
    );
    let shape = header.split("'shape': (").nth(1).unwrap().split(')').next().unwrap();
    let dims: Vec<usize> = shape
        .split(',')
        .map(|s| s.trim())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    let values: Vec<f64> = bytes[10 + len..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(values.len(), dims[0] * dims[1]);
    ((dims[0], dims[1]), values)
}

/// Rows a query returns, or the line and text of its error.
type Expected = std::result::Result<usize, (usize, &'static str)>;

#[test]
fn query_never_drops_the_first_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "q.ron", QUERY_SCENE);
    let ray = "0,0,-5,0,0,1";
    // (first line, rows expected, or the error's line and text)
    let cases: [(&str, Expected); 7] = [
        ("\u{feff}0,0,-5,0,0,1", Ok(3)),
        ("\u{feff}ox,oy,oz,dx,dy,dz", Ok(2)),
        ("  0 , 0 , -5 , 0 , 0 , 1  ", Ok(3)),
        ("ox, oy, oz, dx, dy, dz, tmin, tmax", Ok(2)),
        ("0;0;-5;0;0;1", Err((1, "separated by commas"))),
        ("0,0,-5,0,0,1,", Err((1, "trailing comma"))),
        ("0 0 -5 0 0 1", Err((1, "not a number"))),
    ];
    for (first, expected) in cases {
        let rays = write_file(dir.path(), "rays.csv", format!("{first}\n{ray}\n{ray}\n"));
        let out = dir.path().join("hits.csv");
        let _ = std::fs::remove_file(&out);
        let o = run(&["query", p(&scene), "--rays", p(&rays), "-o", p(&out)]);
        match expected {
            Ok(rows) => {
                assert_ok(&o, first);
                let csv = std::fs::read_to_string(&out).unwrap();
                assert_eq!(csv.lines().count(), rows + 1, "{first:?}: {csv}");
                assert!(csv.lines().skip(1).all(|l| l.starts_with("1,4e0,")), "{first:?}: {csv}");
                assert!(
                    stderr(&o).contains(&format!("{rows} rays, {rows} hits")),
                    "{}",
                    stderr(&o)
                );
            }
            Err((line, text)) => {
                assert_fails(&o, &[&format!("{}:{line}:", p(&rays)), text], first);
                assert!(!out.exists(), "{first:?}: no output file");
            }
        }
    }
}

#[test]
fn query_npy_in_and_out_match_csv() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "q.ron", QUERY_SCENE);
    // hits on the ball, the floor, misses, a t range; 8 columns
    let mut values = Vec::new();
    let mut csv = String::new();
    for i in 0..300 {
        let x = f64::from(i % 17) * 0.1 - 0.8;
        let ray = [
            x,
            0.2,
            -5.0,
            0.0,
            -0.3 * f64::from(i % 3),
            1.0,
            0.0,
            if i % 5 == 0 { 3.0 } else { 1e9 },
        ];
        values.extend_from_slice(&ray);
        let text: Vec<String> = ray.iter().map(|v| format!("{v:e}")).collect();
        csv.push_str(&text.join(","));
        csv.push('\n');
    }
    let (rays_npy, rays_csv) = (dir.path().join("rays.npy"), dir.path().join("rays.csv"));
    std::fs::write(&rays_npy, npy_bytes(&values, 8)).unwrap();
    std::fs::write(&rays_csv, &csv).unwrap();
    let hits_csv = dir.path().join("hits.csv");
    assert_ok(
        &run(&["query", p(&scene), "--rays", p(&rays_csv), "-o", p(&hits_csv)]),
        "csv",
    );
    let expected: Vec<Vec<f64>> = std::fs::read_to_string(&hits_csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            // drop the name column (9); empty fields are NaN in .npy
            f.iter()
                .enumerate()
                .filter(|(k, _)| *k != 9)
                .map(|(_, s)| if s.is_empty() { f64::NAN } else { s.parse().unwrap() })
                .collect()
        })
        .collect();
    assert_eq!(expected.len(), 300);
    assert!(expected.iter().any(|r| r[0] == 0.0) && expected.iter().any(|r| r[0] == 1.0));
    for (input, output) in [(&rays_npy, "a.npy"), (&rays_csv, "b.npy")] {
        let out = dir.path().join(output);
        assert_ok(&run(&["query", p(&scene), "--rays", p(input), "-o", p(&out)]), output);
        let (shape, got) = read_npy(&std::fs::read(&out).unwrap());
        assert_eq!(shape, (300, 11), "{output}");
        for (row, want) in got.chunks(11).zip(&expected) {
            for (g, w) in row.iter().zip(want) {
                assert!(
                    g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                    "{output}: {row:?} vs {want:?}"
                );
            }
        }
    }
    // .npy to stdout needs a known row count: from .npy input it streams, from CSV it is refused
    let o = run(&["query", p(&scene), "--rays", p(&rays_npy), "--format", "npy"]);
    assert_ok(&o, "npy to stdout");
    assert_eq!(o.stdout, std::fs::read(dir.path().join("a.npy")).unwrap());
    let o = run(&["query", p(&scene), "--rays", p(&rays_csv), "--format", "npy"]);
    assert_fails(&o, &["stdout"], "csv → npy on stdout");
    // CSV from stdin
    let mut child = bin()
        .args(["query", p(&scene), "--rays", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write as _;
    child.stdin.take().unwrap().write_all(csv.as_bytes()).unwrap();
    let o = child.wait_with_output().unwrap();
    assert_ok(&o, "stdin");
    assert_eq!(stdout(&o), std::fs::read_to_string(&hits_csv).unwrap());
    // malformed .npy input: located errors
    let mut bad = values.clone();
    bad[8 * 7 + 4] = f64::NAN; // row 7's dy
    std::fs::write(&rays_npy, npy_bytes(&bad, 8)).unwrap();
    let o = run(&["query", p(&scene), "--rays", p(&rays_npy)]);
    assert_fails(&o, &[&format!("{}:row 7:", p(&rays_npy)), "finite"], "nan in npy");
    std::fs::write(&rays_npy, npy_bytes(&values[..7 * 50], 7)).unwrap();
    let o = run(&["query", p(&scene), "--rays", p(&rays_npy)]);
    assert_fails(&o, &["header", "(N, 6) or (N, 8)"], "7 columns");
    let mut truncated = npy_bytes(&values, 8);
    truncated.truncate(truncated.len() - 8);
    std::fs::write(&rays_npy, truncated).unwrap();
    let o = run(&["query", p(&scene), "--rays", p(&rays_npy)]);
    assert_fails(&o, &["row 0", "shorter"], "truncated npy");
}

/// The README's oiiotool recipe: `--add` of data-windowed crops equals the full frame bit for
/// bit; `--over` does not (it turns the misses' `Z = inf` into 0). Runs where `oiiotool`
/// (OpenImageIO) is installed, and says so on stderr where it is not.
#[test]
fn oiiotool_add_of_crops_is_exact_and_over_is_not() {
    if Command::new("oiiotool").arg("--help").output().is_err() {
        eprintln!("oiiotool not installed: the recipe is not checked here");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let render_to = |name: &str, crop: Option<&str>| {
        let path = dir.path().join(name);
        let mut args = vec![
            "render",
            "scenes/default.ron",
            "-o",
            p(&path),
            "--aov",
            "all",
            "--no-previews",
        ];
        args.extend_from_slice(&["--width", "96", "--height", "54"]);
        if let Some(c) = crop {
            args.extend_from_slice(&["--crop", c]);
        }
        assert_ok(&run(&args), name);
        path
    };
    let full = render_to("full.exr", None);
    let a = render_to("a.exr", Some("0,0,40,54"));
    let b = render_to("b.exr", Some("40,0,96,54"));
    let (add, over) = (dir.path().join("add.exr"), dir.path().join("over.exr"));
    for (op, out) in [("--add", &add), ("--over", &over)] {
        let o = Command::new("oiiotool")
            .args([p(&a), p(&b), op, "-o", p(out)])
            .output()
            .unwrap();
        assert_ok(&o, op);
    }
    let by_name = |path: &Path| -> std::collections::BTreeMap<String, Vec<u32>> {
        read_channels(path)
            .into_iter()
            .map(|(n, v)| (n, v.iter().map(|x| x.to_bits()).collect()))
            .collect()
    };
    let (expected, added, composited) = (by_name(&full), by_name(&add), by_name(&over));
    assert_eq!(expected.len(), 22);
    assert_eq!(
        added, expected,
        "oiiotool --add of the crops is the full frame, bit for bit"
    );
    let z_inf = expected["Z"].iter().filter(|z| **z == f32::INFINITY.to_bits()).count();
    let z_inf_over = composited["Z"]
        .iter()
        .filter(|z| **z == f32::INFINITY.to_bits())
        .count();
    assert!(z_inf > 100, "the frame has misses: {z_inf}");
    assert!(
        z_inf_over < z_inf,
        "--over keeps every miss's Z = inf: the README's warning is wrong"
    );
}

/// A unit spherical shell 2·10⁻⁴ thick as a `Function` with the smallest budget, 2 evaluations
/// per ray: a ray through the shell needs more to separate its two walls and runs out (reported
/// as a miss, counted, flagged); a ray through the box far from the shell crosses only cells its
/// octree proved empty; a ray missing the box evaluates nothing.
const LOOSE_SCENE: &str = "Scene(camera: (eye: (0, 0, -6), look_at: (0, 0, 0), vfov_deg: 30, width: 12, height: 4), \
    objects: [(name: \"loose\", shape: Function(phi: \"abs(sqrt(x^2 + y^2 + z^2) - 1) - 1e-4\", min: (-2, -2, -2), max: (2, 2, 2), budget: 2))])";

#[test]
fn exhausted_budgets_are_counted_and_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "loose.ron", LOOSE_SCENE);
    // through the sphere, through the box beside it, and two missing the box
    let rays = write_file(
        dir.path(),
        "rays.csv",
        "0,0,-6,0,0,1\n1.5,1.5,-6,0,0,1\n0,5,-6,0,0,1\n5,0,0,0,1,0\n",
    );
    let o = run(&["query", p(&scene), "--rays", p(&rays), "--uncertain"]);
    assert_ok(&o, "query --uncertain");
    assert!(stderr(&o).contains("warning: 1 rays may be wrong"), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "hit,t,px,py,pz,nx,ny,nz,id,name,u,v,uncertain");
    let flags: Vec<&str> = lines[1..].iter().map(|l| l.rsplit(',').next().unwrap()).collect();
    assert_eq!(flags, ["1", "0", "0", "0"], "{out}");
    // the flagged ray is the one the budget lost: reported as a miss
    assert!(lines[1].starts_with("0,") && lines[2].starts_with("0,"), "{out}");
    // without the flag: the same rows without the column, and the same warning
    let o = run(&["query", p(&scene), "--rays", p(&rays)]);
    assert!(stdout(&o).lines().all(|l| l.split(',').count() == 12));
    assert!(stderr(&o).contains("warning: 1 rays"), "{}", stderr(&o));

    // a render: the pixels whose rays cross the shell are flagged, the others not
    let exr = dir.path().join("loose.exr");
    let o = run(&[
        "render",
        p(&scene),
        "-o",
        p(&exr),
        "--aov",
        "Alpha,Uncertain",
        "--no-previews",
    ]);
    assert_ok(&o, "render");
    let channels = read_channels(&exr);
    let flags = &channels.iter().find(|(n, _)| n == "uncertain").unwrap().1;
    let flagged = flags.iter().filter(|f| **f == 1.0).count();
    assert!(flags.iter().all(|f| *f == 0.0 || *f == 1.0));
    assert!(flagged > 0 && flagged < flags.len(), "{flags:?}");
    assert!(
        stderr(&o).contains(&format!("warning: {flagged} rays (primary or shadow) may be wrong")),
        "{}",
        stderr(&o)
    );
}

/// Crops rendered with different `--spp` are refused by `merge` (the header records the spp),
/// naming both files and both counts; nothing is written.
#[test]
fn merge_refuses_crops_of_different_spp() {
    let dir = tempfile::tempdir().unwrap();
    let render_to = |name: &str, crop: &str, spp: &str| {
        let path = dir.path().join(name);
        let args = [
            "render",
            "scenes/default.ron",
            "-o",
            p(&path),
            "--no-previews",
            "--width",
            "24",
            "--height",
            "16",
            "--crop",
            crop,
            "--spp",
            spp,
        ];
        assert_ok(&run(&args), name);
        path
    };
    let left = render_to("left.exr", "0,0,10,16", "4");
    let right = render_to("right.exr", "10,0,24,16", "16");
    let merged = dir.path().join("merged.exr");
    let o = run(&["merge", p(&left), p(&right), "-o", p(&merged)]);
    assert_fails(
        &o,
        &[p(&right), "rendered at 16 spp", p(&left), "at 4 spp", "same --spp"],
        "crops of different spp",
    );
    assert!(!merged.exists());
    // the same spp merges
    let right4 = render_to("right4.exr", "10,0,24,16", "4");
    assert_ok(&run(&["merge", p(&left), p(&right4), "-o", p(&merged)]), "same spp");
}

/// `-o DIR.exr` where DIR.exr is a directory, and `-o link.exr` where the link points to
/// `/dev/null`, are refused before anything is written (no cameras.json) or traced.
#[cfg(unix)]
#[test]
fn output_paths_that_are_not_files_are_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let taken = dir.path().join("taken.exr");
    std::fs::create_dir(&taken).unwrap();
    let o = run(&["render", "scenes/sphere.ron", "-o", p(&taken), "--no-previews"]);
    assert_fails(&o, &[p(&taken), "is a directory, not a regular file"], "a directory");
    assert!(!dir.path().join("taken.cameras.json").exists());
    let link = dir.path().join("link.exr");
    std::os::unix::fs::symlink("/dev/null", &link).unwrap();
    let o = run(&["render", "scenes/sphere.ron", "-o", p(&link), "--no-previews"]);
    let err = assert_fails(
        &o,
        &[
            p(&link),
            "a link to /dev/null",
            "a character device, not a regular file",
        ],
        "a link to /dev/null",
    );
    assert!(!err.contains("writing"), "refused before the render: {err}");
    assert!(!dir.path().join("link.cameras.json").exists());
    // a preview that would replace a directory is refused too
    std::fs::create_dir(dir.path().join("p.depth.png")).unwrap();
    let o = run(&["render", "scenes/sphere.ron", "-o", p(&dir.path().join("p.exr"))]);
    assert_fails(&o, &["p.depth.png", "is a directory"], "a preview path");
    assert!(!dir.path().join("p.exr").exists() && !dir.path().join("p.cameras.json").exists());
}
