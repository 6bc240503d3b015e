//! End-to-end tests of the `zeroset` binary: render, query, primitives, and bad input (each bad
//! input must fail with a non-zero exit status and a message that locates the problem, never a
//! panic).

use exr::meta::MetaData;
use exr::prelude::*;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use zeroset::aov::Aov;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_zeroset"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("the binary runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn assert_ok(o: &Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        stdout(o),
        stderr(o)
    );
}

/// The command failed cleanly: non-zero status that is not a panic's (101), no panic message,
/// and stderr mentions every one of `needles`. Returns stderr.
fn assert_fails(o: &Output, needles: &[&str], what: &str) -> String {
    let err = stderr(o);
    assert!(!o.status.success(), "{what}: should fail, but exited 0\nstderr:\n{err}");
    assert_ne!(o.status.code(), Some(101), "{what}: exit code 101 is a panic\n{err}");
    assert!(o.status.code().is_some(), "{what}: killed by a signal\n{err}");
    assert!(!err.contains("panicked"), "{what}: panicked\n{err}");
    for n in needles {
        assert!(err.contains(n), "{what}: stderr should mention {n:?}:\n{err}");
    }
    err
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn file_names(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

fn channel_names(path: &Path) -> BTreeSet<String> {
    let meta = MetaData::read_from_file(path, true).expect("valid EXR");
    meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

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

/// Reads every channel of a single-layer EXR: `(name, samples)`.
fn read_channels(path: &Path) -> Vec<(String, Vec<f32>)> {
    let image = read_all_flat_layers_from_file(path).expect("readable EXR");
    image.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|ch| {
            let FlatSamples::F32(v) = &ch.sample_data else {
                panic!("{} is not FLOAT", ch.name)
            };
            (ch.name.to_string(), v.clone())
        })
        .collect()
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
/// Fails at the time of writing: `#[arg(long, value_delimiter = ',', num_args = 4)]` (src/cli.rs)
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
    let scene = dir.path().join("q.ron");
    std::fs::write(&scene, QUERY_SCENE).unwrap();
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
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
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
    let scene = dir.path().join("q.ron");
    std::fs::write(&scene, QUERY_SCENE).unwrap();
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
        let rays = dir.path().join(format!("{name}.csv"));
        std::fs::write(&rays, text).unwrap();
        let o = run(&["query", p(&scene), "--rays", p(&rays)]);
        assert_fails(&o, &[&format!("{}:{line}:", p(&rays))], &format!("query {name}"));
        assert!(stdout(&o).is_empty(), "query {name}: no partial output");
    }
    let o = run(&["query", p(&scene), "--rays", p(&dir.path().join("none.csv"))]);
    assert_fails(&o, &["none.csv"], "missing rays file");
}
