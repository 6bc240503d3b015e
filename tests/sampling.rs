//! Beyond one centre ray: samples per pixel, the thin lens and motion blur.
//!
//! - the defaults (spp 1, aperture 0, no motion) and their explicit equivalents render
//!   bit-identically, and a static scene ignores the shutter;
//! - at a silhouette the depth AOV is the nearest sample's depth, computed here independently,
//!   never a blend;
//! - an edge on the focus plane stays sharp and one off it blurs by the circle of confusion;
//! - a moving sphere's blur matches its velocity × shutter;
//! - images are bit-identical on 1, 2 and 3 threads.
//!
//! Measured values are printed with `--nocapture`.

use glam::DVec3;
use zeroset::aov::Aov;
use zeroset::render::{render, Frame, RenderOptions};
use zeroset::sampling::pixel_samples;
use zeroset::scene::Scene;

mod support;
use support::{aovs_except, frame_bits, scene_from_ron};

/// The scene of RON `text`.
fn scene(text: &str) -> Scene {
    scene_from_ron(text, "test.ron")
}

fn render_all(scene: &Scene) -> Frame {
    render(
        scene,
        &RenderOptions {
            aovs: aovs_except(&[Aov::Uncertain]),
            ..RenderOptions::default()
        },
    )
}

/// A small scene with shadows, a transformed box and a sphere; `camera_extra`, `sphere_extra`
/// and `top_extra` are spliced into the camera, the sphere object and the scene.
fn base_scene(camera_extra: &str, sphere_extra: &str, top_extra: &str) -> String {
    format!(
        "Scene(camera: (eye: (0.4, 1.5, -6), look_at: (-0.2, 0.3, 0.5), vfov_deg: 38, width: 48, height: 32 \
         {camera_extra}), \
         objects: [ \
           (shape: Sphere(radius: 0.8), transform: (translate: (0.3, 0.5, 0.2)) {sphere_extra}), \
           (shape: Box(min: (-0.5, -0.5, -0.5), max: (0.5, 0.5, 0.5)), \
            transform: (translate: (-1.2, 0.2, 0.8), rotate: (axis: (0, 1, 0), degrees: 30))), \
           (shape: Plane(normal: (0, 1, 0), offset: -0.4)), \
         ], \
         lights: [Point(position: (2, 4, -3), intensity: (20, 20, 20))] {top_extra})"
    )
}

#[test]
fn pinhole_equivalence_at_aperture_zero_zero_motion_and_spp_one() {
    let reference = frame_bits(&render_all(&scene(&base_scene("", "", ""))));
    let explicit = scene(&base_scene(
        ", aperture: 0, focus_distance: 3, shutter: (open: 0.2, close: 0.9)",
        ", transform_close: (translate: (0.3, 0.5, 0.2))",
        ", sampling: (spp: 1, filter: Gaussian(sigma: 0.5), seed: 9)",
    ));
    assert!(!explicit.has_motion(), "a motion to the same placement is static");
    assert_eq!(frame_bits(&render_all(&explicit)), reference);

    // at spp 16 a static scene ignores the shutter and a zero motion, bit for bit
    let sampled = frame_bits(&render_all(&scene(&base_scene(
        "",
        "",
        ", sampling: (spp: 16, seed: 4)",
    ))));
    let shuttered = frame_bits(&render_all(&scene(&base_scene(
        ", shutter: (open: 0.3, close: 0.35)",
        ", transform_close: (translate: (0.3, 0.5, 0.2))",
        ", sampling: (spp: 16, seed: 4)",
    ))));
    assert_eq!(sampled, shuttered);
    assert_ne!(sampled, reference, "16 samples differ from one");
}

/// The documented camera ray through continuous image position `(x, y)`, computed here.
fn camera_ray(eye: DVec3, look_at: DVec3, vfov_deg: f64, w: u32, h: u32, x: f64, y: f64) -> (DVec3, DVec3, DVec3) {
    let f = (look_at - eye).normalize();
    let r = f.cross(DVec3::Y).normalize();
    let u = r.cross(f);
    let tan = (vfov_deg.to_radians() / 2.0).tan();
    let (w, h) = (f64::from(w), f64::from(h));
    let sx = (x / w * 2.0 - 1.0) * tan * w / h;
    let sy = (1.0 - y / h * 2.0) * tan;
    (eye, (f + sx * r + sy * u).normalize(), f)
}

#[test]
fn silhouette_depth_is_the_nearest_sample_never_a_blend() {
    // a sphere in front of a backdrop (the plane z = 2, only where x ≥ 0.2): silhouettes of
    // sphere/backdrop, sphere/background and backdrop/background
    let (w, h) = (48u32, 32u32);
    let eye = DVec3::new(0.0, 0.0, -6.0);
    let text = format!(
        "Scene(camera: (eye: (0, 0, -6), look_at: (0, 0, 0), vfov_deg: 30, width: {w}, height: {h}), \
         objects: [(shape: Sphere(radius: 1)), \
                   (shape: Polygon(points: [(0.2, -5, 2), (0.2, 5, 2), (9, 5, 2), (9, -5, 2)]))], \
         sampling: (spp: 16, seed: 1))"
    );
    let s = scene(&text);
    let frame = render_all(&s);
    let (mut points, mut scratch) = (Vec::new(), Vec::new());
    let (mut partial, mut mixed) = (0, 0);
    for j in 0..h {
        for i in 0..w {
            let a = frame.pixel(Aov::Alpha, i, j).unwrap()[0];
            pixel_samples(&s.sampling, s.camera.shutter, i, j, &mut points, &mut scratch);
            // each sample's (object, planar depth), independently: ray/sphere and ray/plane
            let mut depths: Vec<(u32, f64)> = Vec::new();
            for p in &points {
                let (o, d, f) = camera_ray(eye, DVec3::ZERO, 30.0, w, h, p.x, p.y);
                let b = o.dot(d);
                let disc = b * b - (o.dot(o) - 1.0);
                let sphere = (disc >= 0.0).then(|| -b - disc.sqrt());
                let t_plane = (2.0 - o.z) / d.z;
                let q = o + t_plane * d;
                let plane = (q.x >= 0.2 && q.x <= 9.0 && q.y.abs() <= 5.0).then_some(t_plane);
                match (sphere, plane) {
                    (Some(t), _) => depths.push((0, t * d.dot(f))),
                    (None, Some(t)) => depths.push((1, t * d.dot(f))),
                    (None, None) => {}
                }
            }
            let hit_fraction = depths.len() as f32 / points.len() as f32;
            let objects_hit =
                usize::from(depths.iter().any(|d| d.0 == 0)) + usize::from(depths.iter().any(|d| d.0 == 1));
            // pixels whose samples straddle a silhouette (samples right at an edge may disagree
            // with the renderer; skip pixels where the count differs)
            if (a - hit_fraction).abs() > 1e-6 {
                continue;
            }
            let silhouette = (a > 0.0 && a < 1.0) || objects_hit == 2;
            if !silhouette {
                continue;
            }
            partial += usize::from(a > 0.0 && a < 1.0);
            mixed += usize::from(objects_hit == 2);
            let z = f64::from(frame.pixel(Aov::Depth, i, j).unwrap()[0]);
            let nearest = depths.iter().map(|d| d.1).fold(f64::INFINITY, f64::min);
            assert!(
                (z - nearest).abs() <= 1e-6 * nearest,
                "pixel ({i}, {j}): Z = {z}, nearest sample depth {nearest}, samples {depths:?}"
            );
            assert!(depths.iter().any(|d| (z - d.1).abs() <= 1e-6 * d.1));
            // id: the object most samples hit; normal: unit length
            let id = frame.pixel(Aov::PrimitiveId, i, j).unwrap()[0];
            let sphere_count = depths.iter().filter(|d| d.0 == 0).count();
            let plane_count = depths.len() - sphere_count;
            let expected = if sphere_count >= plane_count { 0.0 } else { 1.0 };
            assert_eq!(id, expected, "pixel ({i}, {j})");
            let n = frame.pixel(Aov::Normal, i, j).unwrap();
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-5, "|N| = {len}");
        }
    }
    println!("silhouette pixels checked: {partial} with 0 < A < 1, {mixed} with both surfaces");
    assert!(partial >= 30 && mixed >= 5, "{partial} {mixed}");
}

/// Where a monotone profile (sampled at pixel centres `i + ½`) first crosses `level`.
fn crossing(profile: &[f64], level: f64) -> f64 {
    let falling = profile[0] > profile[profile.len() - 1];
    for i in 0..profile.len() - 1 {
        let (a, b) = (profile[i], profile[i + 1]);
        let crossed = if falling {
            a >= level && b < level
        } else {
            a <= level && b > level
        };
        if crossed {
            return i as f64 + 0.5 + (level - a) / (b - a);
        }
    }
    panic!("no crossing of {level} in {profile:?}");
}

/// 10–90 % width of a step profile, in pixels.
fn edge_width(profile: &[f64]) -> f64 {
    (crossing(profile, 0.9) - crossing(profile, 0.1)).abs()
}

/// The mean alpha of each column.
fn column_profile(frame: &Frame) -> Vec<f64> {
    (0..frame.width)
        .map(|i| {
            (0..frame.height)
                .map(|j| f64::from(frame.pixel(Aov::Alpha, i, j).unwrap()[0]))
                .sum::<f64>()
                / f64::from(frame.height)
        })
        .collect()
}

/// The step response of a uniform disk of radius `r` (fraction of the disk left of `x`).
fn disk_step(x: f64, r: f64) -> f64 {
    let u = (x / r).clamp(-1.0, 1.0);
    0.5 + (u * (1.0 - u * u).sqrt() + u.asin()) / std::f64::consts::PI
}

#[test]
fn depth_of_field_keeps_the_focus_plane_sharp_and_blurs_by_the_circle_of_confusion() {
    // a half-plane x ≥ 0.013 at z = 0 seen from 5 units away
    let (w, h, vfov, d, aperture) = (96u32, 12u32, 20.0f64, 5.0f64, 0.6f64);
    let render_edge = |focus: f64| {
        let text = format!(
            "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), vfov_deg: {vfov}, width: {w}, height: {h}, \
             aperture: {aperture}, focus_distance: {focus}), \
             objects: [(shape: Polygon(points: [(0.013, -20, 0), (0.013, 20, 0), (20, 20, 0), (20, -20, 0)]))], \
             sampling: (spp: 256, seed: 2))"
        );
        column_profile(&render(
            &scene(&text),
            &RenderOptions {
                aovs: vec![Aov::Alpha],
                ..RenderOptions::default()
            },
        ))
    };
    let sharp = edge_width(&render_edge(d));
    println!("edge 10–90 % width in focus: {sharp:.3} px");
    assert!(sharp <= 1.0, "in-focus edge width {sharp}");
    let tan = (vfov.to_radians() / 2.0).tan();
    let edge_x = f64::from(w) / 2.0 - 0.013 / (d * tan * f64::from(w) / f64::from(h)) * f64::from(w) / 2.0;
    for focus in [2.5, 3.5, 8.0] {
        let blurred = edge_width(&render_edge(focus));
        // circle of confusion: diameter aperture·2·|d − f|/f on the plane at distance d (rays from
        // the lens disk converge at f and spread again), in pixels of size 2·d·tan(θv/2)/H there
        let coc_px = 2.0 * aperture * (d - focus).abs() / focus / (2.0 * d * tan / f64::from(h));
        // expected profile: the disk's step response box-filtered over each pixel, measured alike
        let expected_profile: Vec<f64> = (0..w)
            .map(|i| {
                (0..100)
                    .map(|k| disk_step(edge_x - (f64::from(i) + (f64::from(k) + 0.5) / 100.0), coc_px / 2.0))
                    .sum::<f64>()
                    / 100.0
            })
            .collect();
        let expected = edge_width(&expected_profile);
        println!(
            "edge 10–90 % width focused at {focus}: {blurred:.3} px, predicted {expected:.3} px \
             (circle of confusion {coc_px:.3} px; 0.687·CoC = {:.3} px)",
            0.687 * coc_px
        );
        assert!(
            (blurred - expected).abs() <= 0.35,
            "focus {focus}: {blurred} vs {expected}"
        );
    }
}

#[test]
fn a_moving_sphere_blurs_by_velocity_times_shutter() {
    // radius 0.5 moving along x from −1.2 (time 0) to +1.2 (time 1): v = 2.4; shutter [0.25, 0.75]
    let (w, h, vfov, eye_z, r) = (160u32, 45u32, 10.0f64, -20.0f64, 0.5f64);
    let (x0, x1, open, close) = (-1.2f64, 1.2f64, 0.25f64, 0.75f64);
    let v = (x1 - x0) / 1.0;
    let text = format!(
        "Scene(camera: (eye: (0, 0, {eye_z}), look_at: (0, 0, 0), vfov_deg: {vfov}, width: {w}, height: {h}, \
         shutter: (open: {open}, close: {close})), \
         objects: [(shape: Sphere(radius: {r}), transform: (translate: ({x0}, 0, 0)), \
                    transform_close: (translate: ({x1}, 0, 0)))], \
         sampling: (spp: 256, seed: 5))"
    );
    let frame = render(
        &scene(&text),
        &RenderOptions {
            aovs: vec![Aov::Alpha],
            ..RenderOptions::default()
        },
    );
    let row = h / 2; // through y = 0
    let alpha: Vec<f64> = (0..w)
        .map(|i| f64::from(frame.pixel(Aov::Alpha, i, row).unwrap()[0]))
        .collect();
    let tan_h = (vfov.to_radians() / 2.0).tan() * f64::from(w) / f64::from(h);
    let to_px = |tangent: f64| tangent / tan_h * f64::from(w) / 2.0;
    // exact perspective extent: from the left tangent at the shutter-open centre to the right
    // tangent at the shutter-close centre
    let (c_open, c_close) = (x0 + v * open, x0 + v * close);
    let tangent = |c: f64, side: f64| {
        let distance = (c * c + eye_z * eye_z).sqrt();
        ((c / -eye_z).atan() + side * (r / distance).asin()).tan()
    };
    let predicted = to_px(tangent(c_close, 1.0)) - to_px(tangent(c_open, -1.0));
    let pixel_at_plane = 2.0 * -eye_z * tan_h / f64::from(w);
    let naive = (2.0 * r + v * (close - open)) / pixel_at_plane;
    let covered: Vec<usize> = (0..w as usize).filter(|&i| alpha[i] > 0.0).collect();
    let support = (covered[covered.len() - 1] - covered[0] + 1) as f64;
    // the profile is a trapezoid whose half-maximum width is the centre's travel v·Δt
    let peak = alpha.iter().copied().fold(0.0, f64::max);
    let half: Vec<f64> = alpha.iter().map(|a| a / peak).collect();
    let rise = crossing(&half, 0.5);
    let fall = {
        let reversed: Vec<f64> = half.iter().rev().copied().collect();
        w as f64 - crossing(&reversed, 0.5)
    };
    let travel_px = fall - rise;
    let travel_predicted = to_px(c_close / -eye_z) - to_px(c_open / -eye_z);
    println!(
        "motion blur: covered extent {support} px (2r + v·Δt: exact perspective {predicted:.2} px, \
         orthographic {naive:.2} px); half-maximum width {travel_px:.2} px vs travel v·Δt {travel_predicted:.2} px; \
         plateau {peak:.3} (2r/(v·Δt) = {:.3})",
        2.0 * r / (v * (close - open))
    );
    assert!((support - predicted).abs() <= 2.0, "{support} vs {predicted}");
    assert!(
        (travel_px - travel_predicted).abs() <= 1.0,
        "{travel_px} vs {travel_predicted}"
    );
}

#[test]
fn sampled_images_are_bit_identical_on_any_thread_count() {
    let text = base_scene(
        ", aperture: 0.15, shutter: (open: 0, close: 1)",
        ", transform_close: (translate: (0.9, 0.7, 0.0), rotate: (axis: (0, 0, 1), degrees: 40))",
        ", sampling: (spp: 12, filter: Gaussian(sigma: 0.4), seed: 77)",
    );
    let s = scene(&text);
    assert!(s.has_motion());
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| frame_bits(&render_all(&s)))
    };
    let one = on(1);
    assert_eq!(one, on(2));
    assert_eq!(one, on(3));
    let other_seed = scene(&text.replace("seed: 77", "seed: 78"));
    assert_ne!(one, frame_bits(&render_all(&other_seed)));
}
