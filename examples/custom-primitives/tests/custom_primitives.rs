//! The worked examples of primitives defined outside zeroset: they load from RON through the
//! registry, render with depth and normal AOVs, and the Φ-only torus (generic root finder) agrees
//! with the closed-form quartic torus.

use std::path::Path;
use zeroset::aov::Aov;
use zeroset::output::exr::{write_exr, ExrHeader};
use zeroset::render::{render, Frame, RenderOptions};
use zeroset::scene::{Scene, SceneError};

fn scene_path(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)
}

fn load(name: &str) -> Scene {
    zeroset_custom_primitives::register_all();
    Scene::load(&scene_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn render_small(scene: &mut Scene, aovs: &[Aov]) -> Frame {
    scene.camera = scene.camera.with_resolution(160, 120).unwrap();
    render(
        scene,
        &RenderOptions {
            aovs: aovs.to_vec(),
            ..RenderOptions::default()
        },
    )
}

/// Every example scene renders and writes an EXR with depth and normals that reads back.
#[test]
fn every_example_scene_renders_to_exr() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["torus.ron", "quartic_torus.ron", "superellipsoid.ron", "gyroid.ron"] {
        let mut scene = load(name);
        let frame = render_small(&mut scene, &[Aov::Beauty, Aov::Alpha, Aov::Depth, Aov::Normal]);
        let hits = (0..120)
            .flat_map(|y| (0..160).map(move |x| (x, y)))
            .filter(|&(x, y)| frame.pixel(Aov::Alpha, x, y).unwrap()[0] == 1.0)
            .count();
        assert!(hits > 500, "{name}: only {hits} pixels hit");
        for y in 0..120 {
            for x in 0..160 {
                if frame.pixel(Aov::Alpha, x, y).unwrap()[0] == 1.0 {
                    let n = frame.pixel(Aov::Normal, x, y).unwrap();
                    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                    assert!((len - 1.0).abs() < 1e-5, "{name}: normal {n:?} at ({x}, {y})");
                    assert!(frame.pixel(Aov::Depth, x, y).unwrap()[0].is_finite());
                }
            }
        }
        let path = dir.path().join(name.replace(".ron", ".exr"));
        let header = ExrHeader {
            world_to_camera: scene.camera.world_to_camera(),
            world_to_ndc: scene.camera.world_to_ndc(0.01, 1000.0),
            scene_file: name.into(),
            depth_miss: f32::INFINITY,
            camera_attributes: Vec::new(),
        };
        write_exr(&frame, &path, &header).unwrap();
        let image = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
        let names: Vec<String> = image.layer_data[0]
            .channel_data
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        for channel in ["Z", "N.X", "N.Y", "N.Z", "A", "R", "G", "B"] {
            assert!(
                names.iter().any(|n| n == channel),
                "{name}: channel {channel} missing from {names:?}"
            );
        }
    }
}

/// The Φ-only torus (generic root finder, tolerance 1e-7) and the closed-form quartic torus give
/// the same depth on every pixel both hit, and the same hit mask except at a few silhouette
/// pixels.
#[test]
fn phi_only_torus_matches_quartic_torus() {
    let mut generic = load("torus.ron");
    let mut quartic = load("quartic_torus.ron");
    let aovs = [Aov::Alpha, Aov::Distance, Aov::Normal];
    let a = render_small(&mut generic, &aovs);
    let b = render_small(&mut quartic, &aovs);
    let (mut both, mut disagree, mut max_rel, mut max_normal_deg) = (0, 0, 0.0f64, 0.0f64);
    for y in 0..120 {
        for x in 0..160 {
            let ha = a.pixel(Aov::Alpha, x, y).unwrap()[0] == 1.0;
            let hb = b.pixel(Aov::Alpha, x, y).unwrap()[0] == 1.0;
            if ha != hb {
                disagree += 1;
                continue;
            }
            if ha {
                both += 1;
                let ta = f64::from(a.pixel(Aov::Distance, x, y).unwrap()[0]);
                let tb = f64::from(b.pixel(Aov::Distance, x, y).unwrap()[0]);
                max_rel = max_rel.max((ta - tb).abs() / tb);
                let na = a.pixel(Aov::Normal, x, y).unwrap();
                let nb = b.pixel(Aov::Normal, x, y).unwrap();
                let chord: f64 = na
                    .iter()
                    .zip(nb)
                    .map(|(p, q)| f64::from(p - q).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let angle = (2.0 * (0.5 * chord).asin()).to_degrees();
                max_normal_deg = max_normal_deg.max(angle);
            }
        }
    }
    assert!(both > 2000, "only {both} pixels hit");
    eprintln!("both hit {both}, disagree {disagree}, max rel depth {max_rel:e}, max normal {max_normal_deg:e}°");
    assert!(disagree <= 4, "{disagree} pixels disagree on hit/miss");
    assert!(max_rel < 1e-6, "max relative depth difference {max_rel:e}");
    assert!(max_normal_deg < 1e-3, "max normal difference {max_normal_deg}°");
}

/// The closed-form torus hits lie on the torus: |Φ| at the hit is at rounding level.
#[test]
fn quartic_torus_hits_lie_on_the_surface() {
    use rand::{Rng, SeedableRng};
    use zeroset_custom_primitives::QuarticTorus;
    use zeroset_primitives::{glam::DVec3, Implicit, Intersect, Interval, Ray};
    let torus = QuarticTorus {
        major: 1.0,
        minor: 0.35,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let mut hits = 0;
    for _ in 0..20_000 {
        let origin = DVec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        );
        let target = DVec3::new(
            rng.random_range(-1.3..1.3),
            rng.random_range(-0.4..0.4),
            rng.random_range(-1.3..1.3),
        );
        let ray = Ray::new(origin, (target - origin).normalize());
        if let Some(hit) = torus.intersect(&ray, Interval::POSITIVE) {
            hits += 1;
            let phi = torus.phi(ray.at(hit.t));
            assert!(phi.abs() < 1e-12, "Φ = {phi:e} at a hit of {ray:?}");
            // nothing nearer: Φ keeps the origin's sign along the ray before the hit
            let inside = torus.phi(origin) < 0.0;
            for k in 0..200 {
                let phi = torus.phi(ray.at(hit.t * f64::from(k) / 200.0));
                assert!(
                    (phi < 0.0) == inside || phi.abs() < 1e-9,
                    "crossing before t = {} on {ray:?}",
                    hit.t
                );
            }
        }
    }
    assert!(hits > 5000, "{hits}");
}

/// A registered type with a misspelt or missing field is a `file:line:column` error.
#[test]
fn wrong_or_missing_field_of_a_registered_type_is_located() {
    zeroset_custom_primitives::register_all();
    let text =
        "Scene(\n  camera: (eye: (0, 0, -5)),\n  objects: [\n    (shape: Torus(major: 1.0, minr: 0.3)),\n  ],\n)\n";
    match Scene::from_ron(text, "bad.ron") {
        Err(e @ SceneError::Parse { line: 4, .. }) => {
            let message = e.to_string();
            assert!(
                message.starts_with("bad.ron:4:") && message.contains("minr"),
                "{message}"
            );
        }
        other => panic!("expected a parse error on line 4, got {other:?}"),
    }
    let missing = "Scene(camera: (eye: (0, 0, -5)), objects: [(shape: Torus(major: 1.0))])";
    let message = Scene::from_ron(missing, "missing.ron").unwrap_err().to_string();
    assert!(
        message.starts_with("missing.ron:1:") && message.contains("minor"),
        "{message}"
    );
    let invalid = "Scene(camera: (eye: (0, 0, -5)), objects: [(name: \"ring\", shape: Torus(major: 0.2, minor: 0.3))])";
    let message = Scene::from_ron(invalid, "invalid.ron").unwrap_err().to_string();
    assert!(
        message.contains("objects[0] \"ring\" (Torus)") && message.contains("major"),
        "{message}"
    );
}

/// The user's binary renders a scene of external primitives end to end.
#[test]
fn custom_binary_renders_external_scene() {
    let dir = tempfile::tempdir().unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_zeroset-custom"))
        .args(["render", scene_path("gyroid.ron").to_str().unwrap(), "-o"])
        .arg(dir.path())
        .args(["--width", "64", "--height", "48", "--no-previews"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(dir.path().join("gyroid.exr").exists());
    let listing = std::process::Command::new(env!("CARGO_BIN_EXE_zeroset-custom"))
        .arg("primitives")
        .output()
        .unwrap();
    let names = String::from_utf8_lossy(&listing.stdout);
    for name in ["Torus", "QuarticTorus", "Superellipsoid", "Gyroid", "Sphere"] {
        assert!(names.lines().any(|l| l == name), "{name} not listed: {names}");
    }
}

/// The generically written torus (Φ once, `ScalarField`): a tube 10⁻⁵ thick is found by every
/// ray aimed through it (guaranteed isolation, no sampling step to fall between), at the exact
/// first crossing, with normals equal to the analytic gradient's direction to 10⁻¹².
#[test]
fn generic_torus_has_no_holes_and_exact_normals() {
    use zeroset_custom_primitives::Torus;
    use zeroset_primitives::{glam::DVec3, FieldSurface, Intersect, Interval, Ray};
    let (major, minor) = (1.0, 1e-5);
    let torus = FieldSurface::new(Torus { major, minor });
    let mut holes = 0;
    for k in 0..2000 {
        let a = f64::from(k) * std::f64::consts::TAU / 2000.0;
        // from outside, at an angle, through the tube's centre circle (offset well inside r)
        let target = DVec3::new(major * a.cos(), 0.3 * minor * (7.0 * a).sin(), major * a.sin());
        let origin = DVec3::new(2.5 * (a + 0.4).cos(), 1.7, 2.5 * (a + 0.4).sin());
        let ray = Ray::new(origin, (target - origin).normalize());
        let Some(hit) = torus.intersect(&ray, Interval::POSITIVE) else {
            holes += 1;
            continue;
        };
        let p = ray.at(hit.t);
        let centre = DVec3::new(p.x, 0.0, p.z).normalize() * major;
        // ∇Φ by the chain rule: ring = ρ − R, ρ = √(x² + z²); ∇Φ = (ring·x/ρ, y, ring·z/ρ) / √(ring² + y²)
        let rho = (p.x * p.x + p.z * p.z).sqrt();
        let ring = rho - major;
        let analytic = DVec3::new(ring * p.x / rho, p.y, ring * p.z / rho).normalize();
        let normal = torus.normal_at(&ray, &hit);
        assert!((normal - analytic).length() <= 1e-12, "{normal} vs {analytic} at {p}");
        // on the tube: the distance to the centre circle is r, to the tolerance of t
        assert!(((p - centre).length() - minor).abs() <= 2e-7, "{p}");
    }
    assert_eq!(holes, 0, "{holes} of 2000 rays through the thin tube missed it");
}

/// Shadow rays from the gyroid example's hits, started where `SurfaceHit::secondary_origin`
/// puts them and aimed at the scene's two lights where they face them, never re-hit their own
/// surface at the start (a re-hit within ten tolerances of the origin is shadow acne: the
/// offset did not cover the root finder's tolerance).
#[test]
fn gyroid_shadow_rays_do_not_hit_their_own_surface() {
    use rand::{Rng, SeedableRng};
    use zeroset_custom_primitives::Gyroid;
    use zeroset_primitives::{FieldSurface, HitRequest, Intersect, Interval, Ray, SurfaceHit};
    let surface = FieldSurface::new(Gyroid {
        frequency: 6.0,
        thickness: 0.4,
        half_size: 1.0,
    });
    let tolerance = surface.root_options().tolerance;
    let lights = [glam::DVec3::new(1.0, 2.0, -1.0), glam::DVec3::new(-1.0, -0.5, -1.0)].map(|d| d.normalize());
    let eye = glam::DVec3::new(2.2, 2.0, -3.2);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let (mut shadow_rays, mut self_hits) = (0, 0);
    for _ in 0..3000 {
        let target = glam::DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let ray = Ray::new(eye, target - eye);
        let Some(raw) = surface.intersect(&ray, Interval::POSITIVE) else {
            continue;
        };
        let hit = SurfaceHit::complete(&surface, &ray, &raw, HitRequest::ALL);
        let n = hit.facing_normal(ray.dir).expect("a normal at every hit");
        for light in lights {
            if n.dot(light) <= 0.0 {
                continue;
            }
            shadow_rays += 1;
            let shadow = Ray::new(hit.secondary_origin(ray.dir), light);
            if surface
                .intersect(&shadow, Interval::POSITIVE)
                .is_some_and(|h| h.t < 10.0 * tolerance)
            {
                self_hits += 1;
            }
        }
    }
    assert!(shadow_rays > 1000, "{shadow_rays}");
    assert_eq!(
        self_hits, 0,
        "{self_hits} of {shadow_rays} shadow rays hit their own surface"
    );
}
