//! Many views per run and the camera files, end to end through the `zeroset` binary:
//! `NAME.IIII.exr` per view equal to single renders of that pose; `--view I`; `cameras.json`
//! re-projecting every hit with an OpenCV projection written here from its documented formula;
//! `transforms.json` read by a tiny reference reader written from the NeRF convention giving the
//! same rays; the EXR header's intrinsics; `query --pixels` giving the rays a render traces; bad
//! views and pixels are errors naming file and line.

mod support;

use exr::prelude::Text;

use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};
use serde_json::Value;
use std::path::Path;
use support::{assert_fails, assert_ok, p, read_channel, run, write_file};
use zeroset::aov::Aov;
use zeroset::render::{render_view, RenderOptions};
use zeroset::scene::Scene;
use zeroset_primitives::Interval;

fn load(file: &str, width: u32, height: u32) -> Scene {
    let mut scene = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(file)).unwrap();
    scene.camera = scene.camera.with_resolution(width, height).unwrap();
    for view in &mut scene.views {
        *view = view.with_resolution(width, height).unwrap();
    }
    scene
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn mat3(v: &Value) -> DMat3 {
    let r = |i: usize, j: usize| v[i][j].as_f64().unwrap();
    DMat3::from_cols(
        DVec3::new(r(0, 0), r(1, 0), r(2, 0)),
        DVec3::new(r(0, 1), r(1, 1), r(2, 1)),
        DVec3::new(r(0, 2), r(1, 2), r(2, 2)),
    )
}

fn vec3(v: &Value) -> DVec3 {
    DVec3::new(v[0].as_f64().unwrap(), v[1].as_f64().unwrap(), v[2].as_f64().unwrap())
}

#[test]
fn every_view_is_rendered_once_to_its_own_file_equal_to_a_single_render_of_that_pose() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/cameras/views.ron",
        "-o",
        p(dir.path()),
        "--width",
        "40",
        "--height",
        "30",
    ]);
    assert_ok(&o, "views");
    let scene = load("scenes/cameras/views.ron", 40, 30);
    assert_eq!(scene.views.len(), 12, "2 LookAt + 2 matrices + 8 from the pose file");
    // the two matrix views are the same pose in the two conventions
    assert!((scene.views[2].forward - scene.views[3].forward).length() < 1e-15);
    assert!((scene.views[2].up - scene.views[3].up).length() < 1e-15);
    let cameras = json(&dir.path().join("views.cameras.json"));
    let entries = cameras["views"].as_array().unwrap();
    assert_eq!(entries.len(), 12);
    for (k, view) in scene.views.iter().enumerate() {
        let file = dir.path().join(format!("views.{k:04}.exr"));
        assert_eq!(entries[k]["exr"], format!("views.{k:04}.exr"));
        let frame = render_view(
            &scene,
            view,
            &RenderOptions {
                aovs: vec![Aov::Depth],
                ..RenderOptions::default()
            },
        );
        let z = read_channel(&file, "Z");
        assert_eq!(z.len(), 40 * 30);
        assert!(
            z.iter().zip(&frame.samples).all(|(a, b)| a.to_bits() == b.to_bits()),
            "view {k} differs from a single render of its pose"
        );
    }
    // the first view is the pose written in the scene
    let first = &scene.views[0];
    assert_eq!(first.eye, DVec3::new(0.0, 1.5, -6.0));
    assert!((first.forward - (DVec3::new(0.0, 0.5, 0.0) - first.eye).normalize()).length() < 1e-15);

    // --view 3 renders that view only
    let one = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/cameras/views.ron",
        "-o",
        p(one.path()),
        "--width",
        "40",
        "--height",
        "30",
        "--view",
        "3",
        "--no-previews",
    ]);
    assert_ok(&o, "--view 3");
    let mut names: Vec<String> = std::fs::read_dir(one.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["views.0003.exr", "views.cameras.json"]);
    assert_eq!(
        read_channel(&one.path().join("views.0003.exr"), "Z"),
        read_channel(&dir.path().join("views.0003.exr"), "Z")
    );
    assert_fails(
        &run(&[
            "render",
            "scenes/cameras/views.ron",
            "-o",
            p(one.path()),
            "--view",
            "12",
        ]),
        &["--view 12", "0 to 11"],
        "view out of range",
    );
    assert_fails(
        &run(&["render", "scenes/sphere.ron", "-o", p(one.path()), "--view", "0"]),
        &["--view", "no `views`"],
        "view without views",
    );
}

/// OpenCV's projection written from its documentation: `x_cam = R·X + t`, `x' = x/z`, radial and
/// tangential distortion, `u = fx·x'' + cx`.
fn opencv_project(entry: &Value, point: DVec3) -> DVec2 {
    let k = mat3(&entry["K"]);
    let q = mat3(&entry["R"]) * point + vec3(&entry["t"]);
    let d: Vec<f64> = entry["distortion"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let (x, y) = (q.x / q.z, q.y / q.z);
    let r2 = x * x + y * y;
    let radial = 1.0 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
    let xd = x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
    let yd = y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
    DVec2::new(k.col(0).x * xd + k.col(2).x, k.col(1).y * yd + k.col(2).y)
}

#[test]
fn cameras_json_reprojects_every_hit_of_a_distorted_render_to_its_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "render",
        "scenes/cameras/opencv.ron",
        "-o",
        p(dir.path()),
        "--width",
        "160",
        "--height",
        "120",
        "--no-previews",
    ]);
    assert_ok(&o, "opencv render");
    let scene = load("scenes/cameras/opencv.ron", 160, 120);
    let cameras = json(&dir.path().join("opencv.cameras.json"));
    let entry = &cameras["views"][0];
    assert_eq!(entry["model"], "OpenCv");
    assert_eq!(entry["width"], 160);
    assert_eq!(entry["exr"], "opencv.exr");
    let camera = &scene.camera;
    let (mut hits, mut worst) = (0, 0.0f64);
    for j in 0..120 {
        for i in 0..160 {
            let ray = camera.pixel_ray(i, j).unwrap();
            let Some((_, raw)) = scene.intersect(&ray, Interval::POSITIVE) else {
                continue;
            };
            hits += 1;
            let uv = opencv_project(entry, ray.at(raw.t));
            worst = worst.max((uv - DVec2::new(f64::from(i), f64::from(j))).length());
        }
    }
    println!("{hits} hits, worst {worst:e} px");
    assert!(hits > 160 * 60);
    assert!(worst < 1e-6, "{worst}");
    // the planar views' R is a rotation and t puts the eye at the origin
    let r = mat3(&entry["R"]);
    assert!(((r * r.transpose()) - DMat3::IDENTITY)
        .abs()
        .to_cols_array()
        .iter()
        .all(|v| *v < 1e-15));
    assert!((r * camera.eye + vec3(&entry["t"])).length() < 1e-14);
    // the EXR header carries the same intrinsics
    let meta = exr::meta::MetaData::read_from_file(dir.path().join("opencv.exr"), false).unwrap();
    let other = &meta.headers[0].own_attributes.other;
    let f64_attribute = |name: &str| match other.get(&Text::from(name)) {
        Some(exr::meta::attribute::AttributeValue::F64(v)) => *v,
        v => panic!("{name}: {v:?}"),
    };
    assert_eq!(f64_attribute("zeroset/camera/fx"), 520.0 * 160.0 / 640.0);
    assert_eq!(f64_attribute("zeroset/camera/cy"), (242.1 + 0.5) * 120.0 / 480.0 - 0.5);
    match other.get(&Text::from("zeroset/camera/model")) {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => assert_eq!(t.to_string(), "OpenCv"),
        v => panic!("model: {v:?}"),
    }
}

/// A tiny `transforms.json` reader written from the NeRF / instant-ngp convention: camera
/// direction `((i + ½ − cx)/fl_x, −(j + ½ − cy)/fl_y, −1)` rotated by the frame's
/// `transform_matrix` (camera-to-world, OpenGL axes), origin its translation.
fn nerf_ray(transforms: &Value, frame: usize, i: u32, j: u32) -> (DVec3, DVec3) {
    let f = |k: &str| transforms[k].as_f64().unwrap();
    let w = f("w");
    // fl_x from camera_angle_x, as NeRF's loaders do
    let fl_x = 0.5 * w / (0.5 * f("camera_angle_x")).tan();
    assert!((fl_x - f("fl_x")).abs() < 1e-9 * fl_x);
    let m = &transforms["frames"][frame]["transform_matrix"];
    let e = |r: usize, c: usize| m[r][c].as_f64().unwrap();
    let c2w = DMat4::from_cols(
        DVec4::new(e(0, 0), e(1, 0), e(2, 0), e(3, 0)),
        DVec4::new(e(0, 1), e(1, 1), e(2, 1), e(3, 1)),
        DVec4::new(e(0, 2), e(1, 2), e(2, 2), e(3, 2)),
        DVec4::new(e(0, 3), e(1, 3), e(2, 3), e(3, 3)),
    );
    let d = DVec3::new(
        (f64::from(i) + 0.5 - f("cx")) / fl_x,
        -(f64::from(j) + 0.5 - f("cy")) / f("fl_y"),
        -1.0,
    );
    (c2w.w_axis.truncate(), c2w.transform_vector3(d).normalize())
}

#[test]
fn transforms_json_read_the_nerf_way_gives_the_same_rays() {
    for scene_file in ["scenes/cameras/views.ron", "scenes/cameras/perspective_offset.ron"] {
        let dir = tempfile::tempdir().unwrap();
        let o = run(&[
            "render",
            scene_file,
            "-o",
            p(dir.path()),
            "--width",
            "48",
            "--height",
            "36",
            "--no-previews",
            "--transforms",
        ]);
        assert_ok(&o, scene_file);
        let transforms = json(&dir.path().join("transforms.json"));
        let scene = load(scene_file, 48, 36);
        let cameras: Vec<_> = if scene.views.is_empty() {
            vec![&scene.camera]
        } else {
            scene.views.iter().collect()
        };
        assert_eq!(transforms["frames"].as_array().unwrap().len(), cameras.len());
        let mut worst = 0.0f64;
        for (k, camera) in cameras.iter().enumerate() {
            let file = transforms["frames"][k]["file_path"].as_str().unwrap();
            assert!(dir.path().join(file).exists(), "{file}");
            for j in 0..36 {
                for i in 0..48 {
                    let (origin, dir) = nerf_ray(&transforms, k, i, j);
                    let ray = camera.pixel_ray(i, j).unwrap();
                    assert!((origin - ray.origin).length() < 1e-12);
                    worst = worst.max((dir - ray.dir).length());
                }
            }
        }
        println!("{scene_file}: worst direction error {worst:e}");
        assert!(worst < 1e-6, "{scene_file}: {worst}");
    }
    // models NeRF cannot describe are refused, not written wrongly
    let dir = tempfile::tempdir().unwrap();
    assert_fails(
        &run(&[
            "render",
            "scenes/cameras/fisheye.ron",
            "-o",
            p(dir.path()),
            "--width",
            "16",
            "--height",
            "16",
            "--transforms",
        ]),
        &["--transforms", "Fisheye"],
        "fisheye transforms",
    );
}

#[test]
fn query_pixels_traces_the_rays_of_the_render() {
    let dir = tempfile::tempdir().unwrap();
    let pixels = write_file(
        dir.path(),
        "pixels.csv",
        "x,y,view\n10.5,20.5\n100.5,60.5,0\n33.25,71.75\n",
    );
    let out = dir.path().join("hits.csv");
    let o = run(&[
        "query",
        "scenes/cameras/opencv.ron",
        "--pixels",
        p(&pixels),
        "-o",
        p(&out),
    ]);
    assert_ok(&o, "query --pixels");
    let scene = load("scenes/cameras/opencv.ron", 640, 480);
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), 3);
    for (row, (x, y)) in rows.iter().zip([(10.5, 20.5), (100.5, 60.5), (33.25, 71.75)]) {
        let ray = scene.camera.ray_through(x, y).unwrap();
        let expected = scene.intersect(&ray, Interval::POSITIVE).map(|(_, raw)| raw.t);
        let fields: Vec<&str> = row.split(',').collect();
        match expected {
            Some(t) => assert_eq!(fields[1].parse::<f64>().unwrap(), t, "({x}, {y})"),
            None => assert_eq!(fields[0], "0"),
        }
    }
    // --camera takes the rays from another scene's views
    std::fs::write(&pixels, "160.5,120.5,11\n").unwrap();
    let o = run(&[
        "query",
        "scenes/cameras/opencv.ron",
        "--camera",
        "scenes/cameras/views.ron",
        "--pixels",
        p(&pixels),
        "-o",
        p(&out),
    ]);
    assert_ok(&o, "query --camera");
    let views = load("scenes/cameras/views.ron", 320, 240);
    let ray = views.views[11].ray_through(160.5, 120.5).unwrap();
    let t = scene.intersect(&ray, Interval::POSITIVE).map(|(_, raw)| raw.t).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        text.lines()
            .nth(1)
            .unwrap()
            .split(',')
            .nth(1)
            .unwrap()
            .parse::<f64>()
            .unwrap(),
        t
    );
    // positions without a ray and malformed lines name the line
    std::fs::write(&pixels, "1,1\n0.5,0.5\n").unwrap();
    assert_fails(
        &run(&["query", "scenes/cameras/fisheye.ron", "--pixels", p(&pixels)]),
        &["pixels.csv:1", "no ray", "outside"],
        "fisheye corner",
    );
    std::fs::write(&pixels, "1,1\n2,2,5\n").unwrap();
    assert_fails(
        &run(&["query", "scenes/cameras/opencv.ron", "--pixels", p(&pixels)]),
        &["pixels.csv:2", "view 5"],
        "missing view",
    );
    assert_fails(
        &run(&[
            "query",
            "scenes/cameras/opencv.ron",
            "--rays",
            p(&pixels),
            "--pixels",
            p(&pixels),
        ]),
        &["--pixels"],
        "both",
    );
}

#[test]
fn bad_views_are_errors_naming_file_and_entry() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.ron");
    for (views, needles) in [
        ("[LookAt(eye: (0, 0, -5), look_at: (0, 0, -5))]", vec!["views[0]", "look_at"]),
        (
            "[LookAt(eye: (0, 0, -5), look_at: (0, 0, 0)), CameraToWorld(matrix: [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])]",
            vec!["views[1]", "orthonormal"],
        ),
        ("[File(\"missing.poses\")]", vec!["views[0]", "missing.poses"]),
        ("[File(\"bad.poses\")]", vec!["bad.poses:2", "9 numbers"]),
        ("[Orbit(radius: 3)]", vec!["s.ron:1", "Orbit"]),
    ] {
        std::fs::write(dir.path().join("bad.poses"), "0 0 -5 0 0 0 0 1 0\n1 2 3 4\n").unwrap();
        std::fs::write(&scene, format!("Scene(camera: (), views: {views}, objects: [(shape: Sphere())])")).unwrap();
        let o = run(&["render", p(&scene), "-o", p(dir.path())]);
        assert_fails(&o, &needles, views);
    }
}

#[test]
fn non_converging_pixels_are_reported_by_render_and_refused_by_query() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("strong.ron");
    std::fs::write(
        &scene,
        "Scene(camera: (width: 80, height: 60, model: OpenCv(fx: 60, fy: 60, cx: 39.5, cy: 29.5, \
         distortion: [-0.6, 0, 0, 0])), objects: [(shape: Plane(normal: (0, 0, -1), offset: -3))])",
    )
    .unwrap();
    let o = run(&["render", p(&scene), "-o", p(dir.path()), "--no-previews"]);
    assert_ok(&o, "strong distortion");
    let err = String::from_utf8_lossy(&o.stderr);
    let line = err
        .lines()
        .find(|l| l.contains("did not converge"))
        .unwrap_or_else(|| panic!("{err}"));
    let count: u64 = line
        .split_whitespace()
        .find_map(|w| w.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(count > 100, "{line}");
    // those pixels hold the miss values; the centre does not
    let z = read_channel(&dir.path().join("strong.exr"), "Z");
    assert_eq!(z[0], f32::INFINITY);
    assert!((z[30 * 80 + 40] - 8.0).abs() < 1e-5, "{}", z[30 * 80 + 40]);
    assert_eq!(z.iter().filter(|v| v.is_infinite()).count() as u64, count);
    let pixels = write_file(dir.path(), "corner.csv", "40.5,30.5\n0.5,0.5\n");
    assert_fails(
        &run(&["query", p(&scene), "--pixels", p(&pixels)]),
        &["corner.csv:2", "does not converge"],
        "query at a non-converging pixel",
    );
}
