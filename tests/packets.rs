//! Packet tracing gives every ray exactly the answer it gets alone: `Scene::intersect_packet`
//! against `Scene::intersect` ray by ray, hit for hit and bit for bit, on every shipped scene
//! (meshes, the scene hierarchy of the bench scenes, transforms, combinators, user functions),
//! for coherent packets (4 × 2 pixels of the scene's camera), scattered ones (pixels far apart,
//! random rays) and partial ones.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use zeroset::camera::Camera;
use zeroset::scene::Scene;
use zeroset_primitives::{Interval, Ray, PACKET};

/// Every scene that loads: `scenes/`, `scenes/hard/`, and the bench scenes whose meshes have
/// been generated (`scenes/bench/make_meshes.sh`).
fn scenes() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files = Vec::new();
    for dir in [root.clone(), root.join("hard"), root.join("bench")] {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "ron") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// Compares the packet with single rays; returns the number of hits.
fn assert_packet_equals_single(scene: &Scene, rays: &[Ray], range: Interval, what: &str) -> usize {
    let single: Vec<_> = rays.iter().map(|r| scene.intersect(r, range)).collect();
    let mut packet = vec![None; rays.len()];
    scene.intersect_packet(rays, &vec![range; rays.len()], &mut packet);
    assert_eq!(packet, single, "{what}: rays {rays:?}");
    single.iter().flatten().count()
}

#[test]
fn packets_equal_single_rays_on_every_scene() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(2026);
    let mut tested = 0;
    let mut total_hits = 0;
    for path in scenes() {
        let Ok(scene) = Scene::load(&path) else {
            // a bench scene whose mesh was not generated
            assert!(
                path.to_string_lossy().contains("bench"),
                "{} does not load",
                path.display()
            );
            continue;
        };
        let name = path.display().to_string();
        let camera = scene.camera.with_resolution(128, 72).unwrap();
        let mut hits = 0;
        // coherent 4 × 2 packets over the whole frame
        for y in (0..72).step_by(2) {
            for x in (0..128).step_by(4) {
                let rays: Vec<Ray> = (0..PACKET as u32)
                    .filter_map(|l| camera.pixel_ray(x + l % 4, y + l / 4).ok())
                    .collect();
                hits += assert_packet_equals_single(&scene, &rays, Interval::POSITIVE, &name);
            }
        }
        // scattered and partial packets, limited ranges
        for _ in 0..300 {
            let n = rng.random_range(1..=PACKET);
            let rays: Vec<Ray> = (0..n)
                .filter_map(|_| camera.pixel_ray(rng.random_range(0..128), rng.random_range(0..72)).ok())
                .collect();
            let range = Interval::new(rng.random_range(0.0..2.0), rng.random_range(2.0..40.0));
            hits += assert_packet_equals_single(&scene, &rays, range, &name);
        }
        // random rays from around the scene, any direction
        let bounds = 20.0;
        for _ in 0..300 {
            let rays: Vec<Ray> = (0..PACKET)
                .map(|_| {
                    let o = DVec3::new(
                        rng.random_range(-bounds..bounds),
                        rng.random_range(-bounds..bounds),
                        rng.random_range(-bounds..bounds),
                    );
                    let d = DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    );
                    Ray::new(o, d)
                })
                .collect();
            hits += assert_packet_equals_single(&scene, &rays, Interval::POSITIVE, &name);
        }
        assert!(hits > 0, "{name}: no ray hit anything");
        total_hits += hits;
        tested += 1;
    }
    assert!(tested >= 20, "only {tested} scenes loaded");
    assert!(total_hits > 10_000, "{total_hits}");
}

/// The pixels of `camera` outside its coverage of `scene` (`Scene::coverage`: the footprints of
/// `Scene::bounds_parts`, what a render skips), if it has one: every such pixel inside the
/// footprint of the scene's whole box or within three pixels of it, and every 7th one beyond,
/// sees nothing (`Scene::intersect` of its ray). Returns the number of pixels checked, or `None`
/// where the camera gives no footprint.
fn assert_outside_sees_nothing(scene: &Scene, camera: &Camera, what: &str) -> Option<usize> {
    // what the renderer skips: the coverage of the scene's parts (a mesh's upper boxes)
    let rect = camera.footprint(&scene.bounds())?;
    let seen = scene.coverage(camera)?;
    let mut checked = 0;
    for j in 0..camera.height {
        for i in 0..camera.width {
            let (x, y) = (f64::from(i) + 0.5, f64::from(j) + 0.5);
            if seen.holds_pixel(i, j) {
                continue;
            }
            let near = x > rect.x0 - 3.0 && x < rect.x1 + 3.0 && y > rect.y0 - 3.0 && y < rect.y1 + 3.0;
            if !near && (i + j * camera.width) % 7 != 0 {
                continue;
            }
            let ray = camera.pixel_ray(i, j).unwrap();
            assert_eq!(
                scene.intersect(&ray, Interval::POSITIVE),
                None,
                "{what}: pixel ({i}, {j}) outside {rect:?}"
            );
            checked += 1;
        }
    }
    Some(checked)
}

/// A render leaves out the pixels outside the camera's footprint of the scene's bounds: on every
/// shipped scene, through its own camera at its own resolution where that camera gives a
/// footprint, and through a pinhole placed outside the scene's box (twice its diagonal from its
/// centre, looking at it, so every bounded scene has a footprint there), those pixels see
/// nothing, and they are a real part of the frames.
#[test]
fn pixels_outside_the_footprint_see_nothing_on_every_scene() {
    let (mut footprints, mut checked) = (0, 0);
    for path in scenes() {
        let Ok(scene) = Scene::load(&path) else {
            continue;
        };
        let name = path.display().to_string();
        if let Some(n) = assert_outside_sees_nothing(&scene, &scene.camera, &name) {
            footprints += 1;
            checked += n;
        }
        let bounds = scene.bounds();
        if !bounds.is_finite() {
            continue;
        }
        let centre = bounds.center();
        let eye = centre + 2.0 * bounds.diagonal_length().max(1e-3) * DVec3::new(0.3, 0.5, -1.0).normalize();
        let outside = Camera::new(eye, centre - eye, DVec3::Y, 40.0, 160, 90).unwrap();
        let n = assert_outside_sees_nothing(&scene, &outside, &format!("{name} (outside view)"))
            .unwrap_or_else(|| panic!("{name}: no footprint from outside its box"));
        footprints += 1;
        checked += n;
    }
    // without the generated bench meshes: 7 footprints, 15,071 pixels
    assert!(footprints >= 6, "{footprints} footprints");
    assert!(checked > 10_000, "{checked} pixels checked");
}
