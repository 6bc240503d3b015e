//! Rendering a lone mesh by per-pixel candidate pieces (the leaves whose footprints hold the
//! pixel, `piece_bins`) gives every pixel what its ray alone gets: `Scene::intersect` of the
//! pixel's ray, completed independently here (depth, distance, geometric normal, object, alpha, the
//! headlight's beauty),
//! bit for bit, over random pinhole cameras near and far, principal offsets and crops included.

use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use zeroset::aov::Aov;
use zeroset::camera::{Camera, Model, Perspective};
use zeroset::render::{render_view, shade, uses_piece_bins, RenderOptions, Window};
use zeroset::scene::Scene;
use zeroset_primitives::{HitRequest, Interval, SurfaceHit};

/// A closed, bumpy sphere of `4·n²` triangles (radius about 1, centre `c`) as OBJ text.
fn bumpy_sphere_obj(n: usize, c: DVec3) -> String {
    let (rows, columns) = (n, 2 * n);
    let mut text = String::new();
    for i in 0..=rows {
        for j in 0..columns {
            let theta = std::f64::consts::PI * i as f64 / rows as f64;
            let phi = std::f64::consts::TAU * j as f64 / columns as f64;
            let r = 1.0 + 0.15 * (5.0 * phi).sin() * (3.0 * theta).sin();
            let p = c + r * DVec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            text += &format!("v {} {} {}\n", p.x as f32, p.y as f32, p.z as f32);
        }
    }
    for i in 0..rows {
        for j in 0..columns {
            let at = |i: usize, j: usize| i * columns + j % columns + 1;
            text += &format!("f {} {} {}\n", at(i, j), at(i + 1, j), at(i + 1, j + 1));
            text += &format!("f {} {} {}\n", at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    text
}

/// Renders `camera`'s view (cropped to `crop`) and checks every pixel against its own ray;
/// returns the number of hits.
fn assert_pixels_equal_rays(scene: &Scene, camera: &Camera, crop: Option<Window>, what: &str) -> usize {
    let aovs = vec![Aov::Depth, Aov::Distance, Aov::Normal, Aov::Alpha, Aov::PrimitiveId];
    let options = RenderOptions {
        aovs: aovs.clone(),
        crop,
        ..RenderOptions::default()
    };
    let frame = render_view(scene, camera, &options);
    // without the normal every AOV is a value of the hit's `t` and object, which the renderer
    // writes without a hit record: the same values are expected
    let scalars = render_view(
        scene,
        camera,
        &RenderOptions {
            aovs: vec![Aov::PrimitiveId, Aov::Alpha, Aov::Distance, Aov::Depth],
            crop,
            ..RenderOptions::default()
        },
    );
    // the headlight's beauty beside the normal, written without a hit record too
    let lit = render_view(
        scene,
        camera,
        &RenderOptions {
            aovs: vec![Aov::Beauty, Aov::Normal],
            crop,
            ..RenderOptions::default()
        },
    );
    let window = frame.window;
    let mut hits = 0;
    for y in window.y0..window.y1 {
        for x in window.x0..window.x1 {
            let ray = camera.pixel_ray(x, y).unwrap();
            let hit = scene.intersect(&ray, Interval::POSITIVE);
            let beauty = match hit {
                Some((object, raw)) => {
                    let record =
                        SurfaceHit::complete(&*scene.objects[object as usize].primitive, &ray, &raw, HitRequest::ALL);
                    let c = shade(scene, object, &ray, &record);
                    [c.x as f32, c.y as f32, c.z as f32]
                }
                None => [0.0; 3],
            };
            let (depth, distance, normal, alpha, id) = match hit {
                Some((object, raw)) => {
                    hits += 1;
                    let point = ray.at(raw.t);
                    let n = scene.objects[object as usize].primitive.normal_at(&ray, &raw);
                    (
                        camera.depth(point, raw.t) as f32,
                        raw.t as f32,
                        [n.x as f32, n.y as f32, n.z as f32],
                        1.0,
                        object as f32,
                    )
                }
                None => (f32::INFINITY, f32::INFINITY, [0.0; 3], 0.0, -1.0),
            };
            let at = |aov| frame.pixel(aov, x, y).unwrap().to_vec();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&at(Aov::Depth)), bits(&[depth]), "{what}: depth at ({x}, {y})");
            assert_eq!(
                bits(&at(Aov::Distance)),
                bits(&[distance]),
                "{what}: distance at ({x}, {y})"
            );
            assert_eq!(bits(&at(Aov::Normal)), bits(&normal), "{what}: normal at ({x}, {y})");
            assert_eq!(at(Aov::Alpha), vec![alpha], "{what}: alpha at ({x}, {y})");
            assert_eq!(at(Aov::PrimitiveId), vec![id], "{what}: object at ({x}, {y})");
            let lit_at = |aov| lit.pixel(aov, x, y).unwrap().to_vec();
            assert_eq!(
                bits(&lit_at(Aov::Beauty)),
                bits(&beauty),
                "{what}: beauty at ({x}, {y})"
            );
            assert_eq!(
                bits(&lit_at(Aov::Normal)),
                bits(&normal),
                "{what}: normal beside the beauty at ({x}, {y})"
            );
            let scalar = |aov| scalars.pixel(aov, x, y).unwrap().to_vec();
            assert_eq!(
                bits(&[depth, distance, alpha, id]),
                bits(&[
                    scalar(Aov::Depth)[0],
                    scalar(Aov::Distance)[0],
                    scalar(Aov::Alpha)[0],
                    scalar(Aov::PrimitiveId)[0]
                ]),
                "{what}: scalar AOVs alone at ({x}, {y})"
            );
        }
    }
    hits
}

/// [`assert_pixels_equal_rays`] on the whole view, on the crop `[w/l, h/t, w − r, h − h/b]`
/// of `[l, t, r, b]`, on its top left ninth and on a strip three pixels wide down its middle (a
/// crop's bins leave out the pieces under the hierarchy's nodes it cannot see); returns the
/// whole view's hits.
fn assert_view_and_crop_equal_rays(scene: &Scene, camera: &Camera, [l, t, r, b]: [u32; 4], what: &str) -> usize {
    let hits = assert_pixels_equal_rays(scene, camera, None, what);
    let (width, height) = (camera.width, camera.height);
    let crops = [
        Window {
            x0: width / l,
            y0: height / t,
            x1: width - r,
            y1: height - height / b,
        },
        Window {
            x0: 0,
            y0: 0,
            x1: width / 3,
            y1: height / 3,
        },
        Window {
            x0: width / 2,
            y0: 0,
            x1: width / 2 + 3,
            y1: height,
        },
    ];
    for (k, crop) in crops.into_iter().enumerate() {
        assert_pixels_equal_rays(scene, camera, Some(crop), &format!("{what} crop {k}"));
    }
    hits
}

/// Random cameras around a lone mesh (the shipped icosphere, a generated bumpy sphere of
/// 12,800 triangles off the origin, and one of 3,200 at 22,000 from it): the rendered values are those of the pixels' own rays
/// wherever the render takes the piece path, and the path is taken from outside the mesh's box
/// and not from inside it (pieces behind the eye).
#[test]
fn binned_pixels_equal_their_rays() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = dir.path().join("bumpy.obj");
    std::fs::write(&sphere, bumpy_sphere_obj(40, DVec3::new(3.0, -2.0, 5.0))).unwrap();
    // far from the origin: the f32 copies of the eye are off by ~10⁻³, which the footprints allow
    let far = dir.path().join("far.obj");
    let far_centre = DVec3::new(2.0e4, -1.0e4, 0.5);
    std::fs::write(&far, bumpy_sphere_obj(20, far_centre)).unwrap();
    let icosphere = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/icosphere2.ply");
    let scenes = [
        (icosphere.clone(), DVec3::ZERO, 1.0),
        (sphere, DVec3::new(3.0, -2.0, 5.0), 1.15),
        (far, far_centre, 1.15),
    ];
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let (mut binned, mut hits, mut inside) = (0, 0, 0);
    for (mesh, centre, radius) in scenes {
        let text = format!(
            "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0)), objects: [(shape: Mesh(path: {:?}))])",
            mesh.display().to_string()
        );
        let scene = Scene::from_ron(&text, "bins.ron").unwrap();
        for trial in 0..14 {
            // from outside the box (2 to 8 radii away), or from inside it (every third camera)
            let distance = if trial % 3 == 2 {
                rng.random_range(0.1..0.5) * radius
            } else {
                rng.random_range(2.0..8.0) * radius
            };
            let towards = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let eye = centre + distance * towards.normalize();
            let target =
                centre + 0.4 * radius * DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.0);
            let (width, height) = (rng.random_range(40..90), rng.random_range(30..70));
            let mut camera =
                Camera::new(eye, target - eye, DVec3::Y, rng.random_range(15.0..70.0), width, height).unwrap();
            camera.model = Model::Perspective(Perspective {
                principal_offset: DVec2::new(rng.random_range(-6.0..6.0), rng.random_range(-6.0..6.0)),
            });
            let what = format!("{} trial {trial}", mesh.display());
            if uses_piece_bins(&scene, &camera) {
                binned += 1;
            } else if trial % 3 == 2 {
                inside += 1;
            }
            hits += assert_view_and_crop_equal_rays(&scene, &camera, [5, 3, 3, 5], &what);
        }
    }
    assert!(binned >= 24, "{binned} cameras took the piece path");
    assert!(inside >= 9, "{inside} cameras inside the box did not");
    assert!(hits > 20_000, "{hits} hits");
}

/// A random scene of `n` simple objects (spheres, boxes, capped cylinders, cones, ellipsoids,
/// triangles, a few of them touching or overlapping, two of them the same sphere so that ties
/// occur) around the origin, with, for even `n`, a translated mesh and a rotated box, a large
/// ground polygon (its box reaches behind most eyes) and, if `plane`, an unbounded plane
/// behind everything.
fn simple_objects_scene(rng: &mut rand::rngs::StdRng, n: usize, plane: bool) -> Scene {
    let mut shapes = Vec::new();
    let mut r = |a: f64, b: f64| rng.random_range(a..b);
    for k in 0..n {
        let (x, y, z) = (r(-3.0, 3.0), r(0.0, 2.0), r(-3.0, 3.0));
        let s = r(0.2, 0.8);
        shapes.push(match k % 6 {
            0 => format!("Sphere(center: ({x}, {y}, {z}), radius: {s})"),
            1 => format!(
                "Box(min: ({x}, {y}, {z}), max: ({}, {}, {}))",
                x + s,
                y + 0.7 * s,
                z + 1.3 * s
            ),
            2 => format!(
                "Cylinder(base: ({x}, {y}, {z}), axis: ({}, 1, {}), radius: {}, height: {s}, capped: true)",
                r(-0.5, 0.5),
                r(-0.5, 0.5),
                0.5 * s
            ),
            3 => format!("Cone(base: ({x}, {y}, {z}), base_radius: {}, height: {s})", 0.6 * s),
            4 => format!(
                "Ellipsoid(center: ({x}, {y}, {z}), radii: ({s}, {}, {}))",
                0.5 * s,
                0.8 * s
            ),
            _ => format!(
                "Triangle(a: ({x}, {y}, {z}), b: ({}, {y}, {z}), c: ({x}, {}, {}))",
                x + s,
                y + s,
                z + 0.3
            ),
        });
    }
    shapes.push("Sphere(center: (0.5, 1, 0.5), radius: 0.5)".into());
    shapes.push("Sphere(center: (0.5, 1, 0.5), radius: 0.5)".into());
    if n % 2 == 0 {
        // a mesh (the shipped icosphere, traced ray by ray) and a rotated box among them
        let icosphere = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/icosphere2.ply");
        shapes.push(format!(
            "Mesh(path: {:?}), transform: (translate: (-1.5, 1, 1))",
            icosphere.display().to_string()
        ));
        shapes.push(
            "Box(min: (1, 0, -2), max: (2, 0.8, -1.2)), transform: (rotate: (axis: (0, 1, 0), degrees: 30))".into(),
        );
    }
    shapes.push("Polygon(points: [(-40, 0, 40), (40, 0, 40), (40, 0, -40), (-40, 0, -40)])".into());
    if plane {
        shapes.push("Plane(normal: (0, 0, -1), point: (0, 0, 30))".into());
    }
    let objects: Vec<String> = shapes.iter().map(|s| format!("(shape: {s})")).collect();
    let text = format!(
        "Scene(camera: (eye: (0, 3, -9), look_at: (0, 0, 0)), objects: [{}])",
        objects.join(", ")
    );
    Scene::from_ron(&text, "objects.ron").unwrap()
}

/// Scenes of several objects take the same path with the objects as pieces: every
/// pixel's values are those of its own ray (closest object, ties between the two equal spheres
/// to the smaller index), from cameras outside and among the objects, with and without an
/// unbounded plane, crops included.
#[test]
fn binned_objects_equal_their_rays() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(29);
    let (mut binned, mut hits) = (0, 0);
    for trial in 0..16 {
        let scene = simple_objects_scene(&mut rng, 6 + 5 * trial, trial % 2 == 0);
        let eye = if trial % 4 == 3 {
            // among the objects
            DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(0.3..1.5),
                rng.random_range(-1.0..1.0),
            )
        } else {
            DVec3::new(
                rng.random_range(-8.0..8.0),
                rng.random_range(0.5..6.0),
                rng.random_range(-12.0..-5.0),
            )
        };
        let target = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(0.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let (width, height) = (rng.random_range(50..100), rng.random_range(30..70));
        let mut camera = Camera::new(eye, target - eye, DVec3::Y, rng.random_range(25.0..80.0), width, height).unwrap();
        camera.model = Model::Perspective(Perspective {
            principal_offset: DVec2::new(rng.random_range(-6.0..6.0), rng.random_range(-6.0..6.0)),
        });
        if uses_piece_bins(&scene, &camera) {
            binned += 1;
        }
        let what = format!("objects trial {trial}");
        hits += assert_view_and_crop_equal_rays(&scene, &camera, [4, 5, 2, 3], &what);
    }
    assert_eq!(binned, 16, "every camera took the piece path");
    assert!(hits > 40_000, "{hits} hits");
}
