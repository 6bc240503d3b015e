//! The default pinhole stays bit-identical to the renderer before camera models existed:
//! (1) every pixel ray equals, bit for bit, the pre-models formula written out here again, and
//! (2) full renders of shipped scenes hash to checksums recorded with the code before the change
//! (commit 6a35775, `cargo test --test cameras_pinhole`).

use glam::DVec3;
use zeroset::aov::Aov;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

/// FNV-1a over the bits of every sample.
fn fnv1a(samples: &[f32]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for s in samples {
        for b in s.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

fn render_checksum(file: &str, width: u32, height: u32) -> u64 {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let mut scene = Scene::load(&path).unwrap();
    scene.camera = scene.camera.with_resolution(width, height).unwrap();
    let frame = render(
        &scene,
        &RenderOptions {
            aovs: vec![
                Aov::Beauty,
                Aov::Alpha,
                Aov::Depth,
                Aov::Distance,
                Aov::Normal,
                Aov::Position,
                Aov::CameraNormal,
                Aov::PrimitiveId,
            ],
            // the checksums predate premultiplied beauty: misses then held the background
            background: true,
            ..RenderOptions::default()
        },
    );
    fnv1a(&frame.samples)
}

#[test]
fn pinhole_renders_hash_to_the_checksums_recorded_before_camera_models() {
    for (file, w, h, expected) in [
        ("scenes/default.ron", 96, 54, 0xb061_90e1_5642_a9cfu64),
        ("scenes/sphere.ron", 64, 48, 0xad4e_f3f5_6feb_a0f0),
        ("scenes/dof.ron", 48, 36, 0xd7f0_3e42_e420_b68c),
    ] {
        let got = render_checksum(file, w, h);
        println!("{file}: {got:#018x}");
        assert_eq!(got, expected, "{file} {w}x{h}: {got:#018x}");
    }
}

/// The pre-models pixel ray, written out from the old `Camera::ray_through`.
fn old_formula(camera: &zeroset::camera::Camera, i: u32, j: u32) -> (DVec3, DVec3) {
    let (x, y) = (f64::from(i) + 0.5, f64::from(j) + 0.5);
    let tan_half_hfov = camera.tan_half_vfov * f64::from(camera.width) / f64::from(camera.height);
    let sx = (x / f64::from(camera.width) * 2.0 - 1.0) * tan_half_hfov;
    let sy = (1.0 - y / f64::from(camera.height) * 2.0) * camera.tan_half_vfov;
    (
        camera.eye,
        (camera.forward + sx * camera.right + sy * camera.up).normalize(),
    )
}

#[test]
fn default_pinhole_rays_equal_the_old_formula_bit_for_bit() {
    let scene = Scene::from_ron(
        "Scene(camera: (eye: (0.3, 2.5, -7.1), look_at: (0.1, 0.8, 0.2), up: (0.05, 1, 0), vfov_deg: 37.5, \
         width: 123, height: 77))",
        "inline.ron",
    )
    .unwrap();
    for camera in [
        scene.camera.clone(),
        scene.camera.with_resolution(64, 100).unwrap(),
        Scene::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/default.ron"))
            .unwrap()
            .camera,
    ] {
        for j in 0..camera.height {
            for i in 0..camera.width {
                let ray = camera.pixel_ray(i, j).unwrap();
                let (origin, dir) = old_formula(&camera, i, j);
                assert_eq!(
                    ray.origin.to_array().map(f64::to_bits),
                    origin.to_array().map(f64::to_bits)
                );
                assert_eq!(
                    ray.dir.to_array().map(f64::to_bits),
                    dir.to_array().map(f64::to_bits),
                    "({i}, {j})"
                );
            }
        }
    }
}
