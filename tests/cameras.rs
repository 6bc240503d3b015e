//! Camera models: for every model, every hit point `P` of every pixel projects back through the
//! model's forward projection to that pixel's centre within 1e-6 px; the rendered `Z`,
//! `distance` and `P` AOVs carry the stated depth semantics; closed-form rays of each model
//! (computed here from the documented formulas) match; bad model descriptions are errors naming
//! the field.

use glam::{DVec2, DVec3};
use zeroset::aov::Aov;
use zeroset::camera::Model;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

mod support;
use support::scene_from_ron;
use zeroset_primitives::Interval;

/// Objects all around the eye (a closed room sphere of radius 30 centred near it, so every ray of
/// a panoramic camera hits) and in front of it.
const OBJECTS: &str = "objects: [
        (name: \"room\", shape: Sphere(center: (0.7, -0.4, 1.1), radius: 30)),
        (shape: Sphere(center: (-1.2, 1.0, 0.0), radius: 1.0)),
        (shape: Sphere(radius: 1.0), transform: (translate: (1.4, 0.6, 0.5), scale: (0.8, 0.6, 0.8))),
        (shape: Box(min: (-0.5, -0.4, -0.6), max: (0.5, 0.4, 0.6)), transform: (translate: (0.2, -0.6, -1.5), rotate: (axis: (1, 1, 0), degrees: 30))),
        (shape: Plane(normal: (0, 1, 0), offset: -1.2)),
    ]";

fn scene(camera: &str) -> Scene {
    let text = format!(
        "Scene(camera: (eye: (0.3, 1.1, -6.5), look_at: (0.1, 0.5, 0.4), up: (0.08, 1, 0), {camera}), {OBJECTS})"
    );
    scene_from_ron(&text, "inline.ron")
}

/// Projects the hit point of every pixel's ray back through the camera; returns the number of
/// hit pixels and the worst distance (px) from the pixel centre. Also checks the rendered AOVs
/// against the f64 hit: `distance` = t, `P` = the hit point, `Z` = the model's depth.
fn round_trip(scene: &Scene) -> (usize, f64) {
    let camera = &scene.camera;
    let frame = render(
        scene,
        &RenderOptions {
            aovs: vec![Aov::Depth, Aov::Distance, Aov::Position],
            ..RenderOptions::default()
        },
    );
    let (mut hits, mut worst) = (0, 0.0f64);
    for j in 0..camera.height {
        for i in 0..camera.width {
            let centre = DVec2::new(f64::from(i) + 0.5, f64::from(j) + 0.5);
            let Ok(ray) = camera.pixel_ray(i, j) else {
                assert_eq!(frame.pixel(Aov::Distance, i, j).unwrap()[0], f32::INFINITY);
                continue;
            };
            let Some((_, raw)) = scene.intersect(&ray, Interval::POSITIVE) else {
                continue;
            };
            hits += 1;
            let p = ray.at(raw.t);
            let back = camera
                .project(p)
                .unwrap_or_else(|| panic!("pixel ({i}, {j}): {p} does not project"));
            worst = worst.max((back - centre).length());
            // the AOVs of the render are this hit, rounded to f32
            let depth = if camera.model.planar_depth() {
                (p - camera.eye).dot(camera.forward)
            } else {
                (p - ray.origin).length()
            };
            let z = f64::from(frame.pixel(Aov::Depth, i, j).unwrap()[0]);
            let d = f64::from(frame.pixel(Aov::Distance, i, j).unwrap()[0]);
            assert!(
                (z - depth).abs() <= 1e-6 * depth.abs().max(1.0),
                "Z at ({i}, {j}): {z} vs {depth}"
            );
            assert!(
                (d - raw.t).abs() <= 1e-6 * raw.t.max(1.0),
                "distance at ({i}, {j}): {d} vs {}",
                raw.t
            );
            let stored = frame.pixel(Aov::Position, i, j).unwrap();
            let stored = DVec3::new(f64::from(stored[0]), f64::from(stored[1]), f64::from(stored[2]));
            assert!((stored - p).length() <= 1e-6 * p.length().max(1.0), "P at ({i}, {j})");
        }
    }
    (hits, worst)
}

fn check_model(camera: &str, min_hits: usize) {
    let scene = scene(camera);
    let (hits, worst) = round_trip(&scene);
    println!("{camera}: {hits} hit pixels, worst reprojection {worst:.3e} px");
    assert!(hits >= min_hits, "{camera}: only {hits} hit pixels");
    assert!(worst <= 1e-6, "{camera}: reprojection error {worst:e} px");
}

#[test]
fn perspective_with_principal_offset_reprojects_every_hit_within_1e_6_px() {
    check_model(
        "vfov_deg: 50, width: 160, height: 100, model: Perspective(principal_offset: (37.5, -21.25))",
        160 * 100,
    );
}

#[test]
fn orthographic_reprojects_every_hit_within_1e_6_px() {
    check_model("width: 120, height: 90, model: Orthographic(width: 7.5)", 120 * 90);
}

#[test]
fn equirectangular_full_and_limited_reproject_every_hit_within_1e_6_px() {
    check_model("width: 128, height: 64, model: Equirectangular()", 128 * 64);
    check_model(
        "width: 96, height: 40, model: Equirectangular(azimuth_deg: (-60, 120), elevation_deg: (-15, 30))",
        96 * 40,
    );
    // a range across the ±180° seam
    check_model(
        "width: 90, height: 30, model: Equirectangular(azimuth_deg: (100, 300), elevation_deg: (-90, 10))",
        90 * 30,
    );
}

#[test]
fn fisheye_up_to_360_degrees_reprojects_every_hit_within_1e_6_px() {
    // inside the image circle every ray hits the room sphere
    let circle = |w: u32, h: u32| {
        let r = f64::from(w.min(h)) / 2.0;
        (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .filter(|&(i, j)| {
                (f64::from(i) + 0.5 - f64::from(w) / 2.0).hypot(f64::from(j) + 0.5 - f64::from(h) / 2.0) <= r
            })
            .count()
    };
    check_model("width: 96, height: 96, model: Fisheye(fov_deg: 360)", circle(96, 96));
    check_model("width: 120, height: 80, model: Fisheye(fov_deg: 190)", circle(120, 80));
    check_model("width: 64, height: 64, model: Fisheye(fov_deg: 90)", circle(64, 64));
}

#[test]
fn opencv_with_distortion_reprojects_every_hit_within_1e_6_px() {
    check_model(
        "width: 160, height: 120, model: OpenCv(fx: 150, fy: 146, cx: 81.3, cy: 57.9, \
         distortion: [-0.21, 0.05, 0.0011, -0.0008, -0.006])",
        160 * 120,
    );
}

#[test]
fn perspective_rays_follow_the_documented_formula_with_offset() {
    let scene = scene("vfov_deg: 50, width: 160, height: 100, model: Perspective(principal_offset: (37.5, -21.25))");
    let c = &scene.camera;
    let tan_v = (25.0f64).to_radians().tan();
    let tan_h = tan_v * 160.0 / 100.0;
    // the principal point itself looks straight ahead
    let axis = c.ray_through(80.0 + 37.5, 50.0 - 21.25).unwrap();
    assert!((axis.dir - c.forward).length() < 1e-15);
    // the left image edge at the principal row is tan_h·(1 + 2·37.5/160) to the left
    let edge = c.ray_through(0.0, 50.0 - 21.25).unwrap();
    let expected = (c.forward - tan_h * (1.0 + 2.0 * 37.5 / 160.0) * c.right).normalize();
    assert!((edge.dir - expected).length() < 1e-15);
    // K (OpenCV convention) reproduces the projection
    let k = c.intrinsics().unwrap();
    let p = c.eye + 3.0 * c.forward + 0.4 * c.right - 0.7 * c.up;
    let (r, t) = c.opencv_extrinsics();
    let q = r * p + t;
    let uv = DVec2::new(k.x_axis.x * q.x / q.z + k.z_axis.x, k.y_axis.y * q.y / q.z + k.z_axis.y);
    assert!((uv + DVec2::splat(0.5) - c.project(p).unwrap()).length() < 1e-12);
}

#[test]
fn orthographic_rays_are_parallel_and_evenly_spaced() {
    let scene = scene("width: 120, height: 90, model: Orthographic(width: 7.5)");
    let c = &scene.camera;
    let a = c.pixel_ray(10, 20).unwrap();
    let b = c.pixel_ray(11, 20).unwrap();
    let d = c.pixel_ray(10, 21).unwrap();
    assert_eq!(a.dir, c.forward);
    assert!(((b.origin - a.origin) - 7.5 / 120.0 * c.right).length() < 1e-14);
    assert!(((d.origin - a.origin) + 7.5 / 120.0 * c.up).length() < 1e-14);
    // the frame's top-left corner
    let corner = c.ray_through(0.0, 0.0).unwrap().origin;
    let expected = c.eye - 3.75 * c.right + 3.75 * 90.0 / 120.0 * c.up;
    assert!((corner - expected).length() < 1e-14);
}

#[test]
fn equirectangular_rays_point_along_their_azimuth_and_elevation() {
    let scene = scene("width: 360, height: 180, model: Equirectangular()");
    let c = &scene.camera;
    let dir = |x: f64, y: f64| c.ray_through(x, y).unwrap().dir;
    assert!((dir(180.0, 90.0) - c.forward).length() < 1e-15);
    assert!((dir(270.0, 90.0) - c.right).length() < 1e-15);
    assert!((dir(90.0, 90.0) + c.right).length() < 1e-15);
    assert!((dir(0.0, 90.0) + c.forward).length() < 1e-15);
    assert!((dir(123.0, 0.0) - c.up).length() < 1e-15);
    // 30° up, 45° right
    let d = dir(225.0, 60.0);
    let expected = 30f64.to_radians().cos()
        * (45f64.to_radians().sin() * c.right + 45f64.to_radians().cos() * c.forward)
        + 30f64.to_radians().sin() * c.up;
    assert!((d - expected).length() < 1e-15);
}

#[test]
fn fisheye_angle_from_the_axis_is_proportional_to_the_image_radius() {
    let scene = scene("width: 200, height: 100, model: Fisheye(fov_deg: 240)");
    let c = &scene.camera;
    // R = 50 px ↔ 120°; 25 px up from the centre ↔ 60° towards up
    let d = c.ray_through(100.0, 25.0).unwrap().dir;
    let expected = 60f64.to_radians().sin() * c.up + 60f64.to_radians().cos() * c.forward;
    assert!((d - expected).length() < 1e-15);
    let rim = c.ray_through(150.0, 50.0).unwrap().dir;
    assert!((rim.dot(c.forward) - 120f64.to_radians().cos()).abs() < 1e-15);
    assert!(rim.dot(c.right) > 0.0);
    assert_eq!(
        c.ray_through(151.0, 50.0).unwrap_err(),
        zeroset::camera::NoRay::OutsideField
    );
    // outside the circle the render writes misses and counts them
    let frame = render(
        &scene,
        &RenderOptions {
            aovs: vec![Aov::Alpha],
            ..RenderOptions::default()
        },
    );
    let inside = (0..100u32)
        .flat_map(|j| (0..200u32).map(move |i| (i, j)))
        .filter(|&(i, j)| (f64::from(i) + 0.5 - 100.0).hypot(f64::from(j) + 0.5 - 50.0) <= 50.0)
        .count() as u64;
    assert_eq!(frame.outside_field, 200 * 100 - inside);
    assert_eq!(frame.not_converged, 0);
}

#[test]
fn opencv_without_distortion_is_the_perspective_with_the_same_k() {
    // vfov 50° at 160×100: fy = 50/tan25°, fx = fy, principal point at the centre
    let fy = 50.0 / 25f64.to_radians().tan();
    let a = scene("vfov_deg: 50, width: 160, height: 100");
    let b = scene(&format!(
        "width: 160, height: 100, model: OpenCv(fx: {fy:?}, fy: {fy:?}, cx: 79.5, cy: 49.5)"
    ));
    let ka = a.camera.intrinsics().unwrap();
    let kb = b.camera.intrinsics().unwrap();
    assert!(
        (ka - kb).abs().to_cols_array().iter().all(|v| *v < 1e-12),
        "{ka} vs {kb}"
    );
    for (i, j) in [(0, 0), (159, 99), (37, 81), (80, 50)] {
        let ra = a.camera.pixel_ray(i, j).unwrap();
        let rb = b.camera.pixel_ray(i, j).unwrap();
        assert!((ra.dir - rb.dir).length() < 1e-15, "({i}, {j})");
    }
    // and so is its worldToNDC matrix (the pinhole with the same K)
    let (na, nb) = (
        a.camera.world_to_ndc(0.1, 10.0).unwrap(),
        b.camera.world_to_ndc(0.1, 10.0).unwrap(),
    );
    assert!(
        (na - nb).abs().to_cols_array().iter().all(|v| *v < 1e-12),
        "{na} vs {nb}"
    );
}

#[test]
fn strong_distortion_beyond_its_fold_counts_non_converging_pixels() {
    // ρ = 1 − 0.6 r²: r·ρ peaks at r* = 1/√1.8 with value ⅔·r* ≈ 0.497, so the image corners
    // (distorted radius up to 0.83) have no preimage; Newton from inside converges monotonically
    // (r·ρ is concave), slowly only within a hair of the fold
    let scene =
        scene("width: 80, height: 60, model: OpenCv(fx: 60, fy: 60, cx: 39.5, cy: 29.5, distortion: [-0.6, 0, 0, 0])");
    let frame = render(
        &scene,
        &RenderOptions {
            aovs: vec![Aov::Alpha, Aov::Distance],
            ..RenderOptions::default()
        },
    );
    let fold = 2.0 / 3.0 / 1.8f64.sqrt();
    let beyond = |limit: f64| {
        (0..60u32)
            .flat_map(|j| (0..80u32).map(move |i| (i, j)))
            .filter(|&(i, j)| (f64::from(i) - 39.5).hypot(f64::from(j) - 29.5) / 60.0 > limit)
            .count() as u64
    };
    let (surely, at_most) = (beyond(fold), beyond(fold * (1.0 - 1e-3)));
    assert!(surely > 100, "{surely}");
    assert!(
        (surely..=at_most).contains(&frame.not_converged),
        "{} not in {surely}..={at_most}",
        frame.not_converged
    );
    assert_eq!(frame.pixel(Aov::Distance, 0, 0).unwrap()[0], f32::INFINITY);
}

#[test]
fn bad_models_are_errors_naming_the_field() {
    for (camera, needle) in [
        ("model: Fisheye(fov_deg: 400)", "fov_deg"),
        ("model: Fisheye(), vfov_deg: 40", "vfov_deg"),
        ("model: Orthographic(width: -1)", "Orthographic width"),
        ("model: Equirectangular(azimuth_deg: (10, -10))", "azimuth_deg"),
        ("model: Equirectangular(elevation_deg: (-95, 10))", "elevation_deg"),
        ("model: OpenCv(fx: 0, fy: 1, cx: 0, cy: 0)", "fx and fy"),
        (
            "model: OpenCv(fx: 1, fy: 1, cx: 0, cy: 0, distortion: [1, 2, 3])",
            "4 or 5",
        ),
        ("model: Orthographic(width: 1), aperture: 0.1", "aperture"),
        ("model: Fisheye(fov: 90)", "fov"),
    ] {
        let text = format!("Scene(camera: ({camera}))");
        let e = Scene::from_ron(&text, "bad.ron").unwrap_err().to_string();
        assert!(e.contains("bad.ron") && e.contains(needle), "{camera}: {e}");
    }
}

#[test]
fn resolution_changes_keep_each_models_field() {
    let s = scene("width: 160, height: 120, model: OpenCv(fx: 150, fy: 146, cx: 81.3, cy: 57.9)");
    let half = s.camera.with_resolution(80, 60).unwrap();
    let Model::OpenCv(c) = half.model else { panic!() };
    assert!((c.fx - 75.0).abs() < 1e-12 && (c.cx - 40.4).abs() < 1e-12 && (c.cy - 28.7).abs() < 1e-12);
    // the same world point lands at half the image position
    let p = s.camera.eye + 4.0 * s.camera.forward + 0.3 * s.camera.right;
    let full = s.camera.project(p).unwrap();
    assert!((half.project(p).unwrap() - full * 0.5).length() < 1e-12);
}

#[test]
fn world_to_ndc_agrees_with_the_projection_for_the_linear_models() {
    for camera in [
        "vfov_deg: 50, width: 160, height: 100, model: Perspective(principal_offset: (37.5, -21.25))",
        "width: 120, height: 90, model: Orthographic(width: 7.5)",
        "width: 160, height: 120, model: OpenCv(fx: 150, fy: 146, cx: 81.3, cy: 57.9)",
    ] {
        let scene = scene(camera);
        let c = &scene.camera;
        let ndc = c.world_to_ndc(0.1, 100.0).unwrap();
        for (a, b, d) in [(0.3, -0.2, 4.0), (-1.1, 0.7, 9.0), (0.0, 0.0, 2.5)] {
            let p = c.eye + d * c.forward + a * c.right + b * c.up;
            let image = c.project(p).unwrap();
            let n = ndc.project_point3(p);
            let expected = DVec2::new(
                2.0 * image.x / f64::from(c.width) - 1.0,
                1.0 - 2.0 * image.y / f64::from(c.height),
            );
            assert!(
                (n.truncate() - expected).length() < 1e-12,
                "{camera}: {n} vs {expected}"
            );
        }
    }
    assert!(scene("width: 64, height: 32, model: Equirectangular()")
        .camera
        .world_to_ndc(0.1, 100.0)
        .is_none());
}
