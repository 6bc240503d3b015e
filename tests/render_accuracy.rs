//! Render accuracy: every pixel of small renders is checked against an independent f64
//! computation of the documented camera ray (module docs of `src/camera.rs`) and the closed-form
//! first hit (ray/sphere quadratic, ray/plane, slab test under an affine transform).
//!
//! Tolerances: the AOVs are `f32`, so the bound used is a relative error of 1e-6 (about 8–16 f32
//! ulp); for the normal and position the error is taken relative to the vector's norm (a
//! component near zero has no meaningful relative error).
//!
//! Measured maxima (run with `--nocapture` to print them per scene): see `MAX_REL` below.

use glam::DVec3;
use zeroset::aov::Aov;
use zeroset::render::{render, Frame, RenderOptions, Window};
use zeroset::scene::Scene;

mod support;
use support::{aovs_except, frame_bits, scene_from_ron};

/// Relative error allowed between an f32 AOV sample and the exact f64 value.
///
/// Measured maxima over all checked pixels of all scenes in this file (every pixel of eleven
/// 64×36 renders; at most a handful skipped as ambiguous): depth `Z` 5.85e-8, distance 5.91e-8,
/// normal 4.49e-8 and camera-space normal 4.51e-8 (relative to |N| = 1), position 5.74e-8
/// (relative to |P|) — all at or below the f32 rounding of the exact value (≤ 2⁻²⁴ ≈ 5.96e-8), i.e. the f64
/// pipeline is exact to f32 precision.
const MAX_REL: f64 = 1e-6;

const W: u32 = 64;
const H: u32 = 36;

/// The camera shared by the scenes: eye off-axis, slightly tilted `up`, a non-square image.
struct Cam {
    eye: DVec3,
    look_at: DVec3,
    up: DVec3,
    vfov_deg: f64,
}

const CAM: Cam = Cam {
    eye: DVec3::new(0.4, 1.5, -6.0),
    look_at: DVec3::new(-0.2, 0.3, 0.5),
    up: DVec3::new(0.1, 1.0, 0.0),
    vfov_deg: 38.0,
};

fn camera_ron(c: &Cam) -> String {
    format!(
        "camera: (eye: ({:?}, {:?}, {:?}), look_at: ({:?}, {:?}, {:?}), up: ({:?}, {:?}, {:?}), vfov_deg: {:?}, \
         width: {W}, height: {H})",
        c.eye.x, c.eye.y, c.eye.z, c.look_at.x, c.look_at.y, c.look_at.z, c.up.x, c.up.y, c.up.z, c.vfov_deg
    )
}

impl Cam {
    fn forward(&self) -> DVec3 {
        (self.look_at - self.eye).normalize()
    }

    /// The documented pixel-centre ray, computed here independently: `(origin, unit direction)`.
    fn ray(&self, i: u32, j: u32) -> (DVec3, DVec3) {
        let f = self.forward();
        let r = f.cross(self.up).normalize();
        let u = r.cross(f);
        let tan = (self.vfov_deg.to_radians() / 2.0).tan();
        let (w, h) = (f64::from(W), f64::from(H));
        let x = ((f64::from(i) + 0.5) / w * 2.0 - 1.0) * tan * w / h;
        let y = (1.0 - (f64::from(j) + 0.5) / h * 2.0) * tan;
        (self.eye, (f + x * r + y * u).normalize())
    }
}

/// The closed-form answer for one object and one ray.
#[derive(Clone, Copy, Debug)]
enum Analytic {
    /// A hit at `t` with the outward unit normal `n`.
    Hit { t: f64, n: DVec3 },
    /// No hit.
    Miss,
    /// Too close to a silhouette or an edge to say which (the pixel is skipped).
    Ambiguous,
}

type Shape = Box<dyn Fn(DVec3, DVec3) -> Analytic>;

fn sphere(center: DVec3, radius: f64) -> Shape {
    Box::new(move |o, d| {
        // |o + t d − c|² = r², |d| = 1: t² + 2bt + c = 0
        let oc = o - center;
        let b = oc.dot(d);
        let c = oc.dot(oc) - radius * radius;
        let disc = b * b - c;
        if disc.abs() < 1e-9 * radius * radius {
            return Analytic::Ambiguous;
        }
        if disc < 0.0 {
            return Analytic::Miss;
        }
        let s = disc.sqrt();
        let t = if -b - s > 0.0 { -b - s } else { -b + s };
        if t <= 0.0 {
            return Analytic::Miss;
        }
        Analytic::Hit {
            t,
            n: (o + t * d - center) / radius,
        }
    })
}

/// The plane `⟨p, n⟩ = offset` (n need not be unit); the normal is `n/|n|` on both sides.
fn plane(normal: DVec3, offset: f64) -> Shape {
    let len = normal.length();
    let n = normal / len;
    let offset = offset / len;
    Box::new(move |o, d| {
        let dn = d.dot(n);
        if dn.abs() < 1e-9 {
            return Analytic::Ambiguous;
        }
        let t = (offset - o.dot(n)) / dn;
        if t > 0.0 {
            Analytic::Hit { t, n }
        } else {
            Analytic::Miss
        }
    })
}

/// Rotation matrix (columns) about unit `axis` by `degrees`, right-handed (Rodrigues).
fn rotation(axis: DVec3, degrees: f64) -> [DVec3; 3] {
    let k = axis.normalize();
    let (s, c) = degrees.to_radians().sin_cos();
    let rot = |v: DVec3| v * c + k.cross(v) * s + k * k.dot(v) * (1.0 - c);
    [rot(DVec3::X), rot(DVec3::Y), rot(DVec3::Z)]
}

fn mat_mul(m: &[DVec3; 3], v: DVec3) -> DVec3 {
    m[0] * v.x + m[1] * v.y + m[2] * v.z
}

fn mat_t_mul(m: &[DVec3; 3], v: DVec3) -> DVec3 {
    DVec3::new(m[0].dot(v), m[1].dot(v), m[2].dot(v))
}

/// The box `[min, max]` placed by `T·R·S` (scale, then rotate, then translate).
fn placed_box(min: DVec3, max: DVec3, scale: DVec3, axis: DVec3, degrees: f64, translate: DVec3) -> Shape {
    let r = rotation(axis, degrees);
    Box::new(move |o, d| {
        // local = S⁻¹ Rᵀ (world − T); the direction is not renormalised, so t is shared.
        let ol = mat_t_mul(&r, o - translate) / scale;
        let dl = mat_t_mul(&r, d) / scale;
        let mut t_near = f64::NEG_INFINITY;
        let mut t_far = f64::INFINITY;
        let mut near_axis = 0;
        let mut far_axis = 0;
        let mut entries = [f64::NEG_INFINITY; 3];
        let mut exits = [f64::INFINITY; 3];
        for a in 0..3 {
            if dl[a] == 0.0 {
                if ol[a] < min[a] || ol[a] > max[a] {
                    return Analytic::Miss;
                }
                continue;
            }
            let t1 = (min[a] - ol[a]) / dl[a];
            let t2 = (max[a] - ol[a]) / dl[a];
            entries[a] = t1.min(t2);
            exits[a] = t1.max(t2);
            if entries[a] > t_near {
                t_near = entries[a];
                near_axis = a;
            }
            if exits[a] < t_far {
                t_far = exits[a];
                far_axis = a;
            }
        }
        let scale_t = t_near.abs().max(t_far.abs()).max(1.0);
        if (t_near - t_far).abs() < 1e-9 * scale_t {
            return Analytic::Ambiguous;
        }
        if t_near > t_far || t_far <= 0.0 {
            return Analytic::Miss;
        }
        let (t, a, sign) = if t_near > 0.0 {
            // entering face: normal opposes the local direction
            (t_near, near_axis, -dl[near_axis].signum())
        } else {
            (t_far, far_axis, dl[far_axis].signum())
        };
        // an edge or corner: two slabs give (almost) the same t
        let ties = if t_near > 0.0 { &entries } else { &exits };
        for (b, tie) in ties.iter().enumerate() {
            if b != a && tie.is_finite() && (tie - t).abs() < 1e-9 * scale_t {
                return Analytic::Ambiguous;
            }
        }
        let mut nl = DVec3::ZERO;
        nl[a] = sign;
        // normals map by the inverse transpose of R·S, i.e. R·S⁻¹
        let n = mat_mul(&r, nl / scale).normalize();
        Analytic::Hit { t, n }
    })
}

fn scene(objects: &str) -> Scene {
    let text = format!("Scene({}, objects: [{objects}])", camera_ron(&CAM));
    scene_from_ron(&text, "test.ron")
}

fn options(aovs: &[Aov]) -> RenderOptions {
    RenderOptions {
        aovs: aovs.to_vec(),
        ..RenderOptions::default()
    }
}

fn get(frame: &Frame, aov: Aov, i: u32, j: u32) -> Vec<f32> {
    frame
        .pixel(aov, i, j)
        .unwrap_or_else(|| panic!("{aov:?} missing at ({i}, {j})"))
        .to_vec()
}

fn rel(actual: f64, expected: f64) -> f64 {
    (actual - expected).abs() / expected.abs()
}

fn vec_rel(actual: &[f32], expected: DVec3) -> f64 {
    let a = DVec3::new(f64::from(actual[0]), f64::from(actual[1]), f64::from(actual[2]));
    (a - expected).length() / expected.length().max(1e-300)
}

#[derive(Debug, Default)]
struct Stats {
    hits: usize,
    misses: usize,
    skipped: usize,
    max_depth: f64,
    max_distance: f64,
    max_normal: f64,
    max_position: f64,
    max_camera_normal: f64,
}

/// Checks every pixel of a full render of `objects` against the closed forms `shapes`
/// (`shapes[k]` is `objects[k]`): hit/miss, Z, distance, N, P, Nc, A and id.
fn check_scene(objects: &str, shapes: &[Shape]) -> Stats {
    let scene = scene(objects);
    assert_eq!(scene.objects.len(), shapes.len());
    let frame = render(&scene, &options(&aovs_except(&[Aov::ShadingNormal, Aov::Uncertain])));
    assert_eq!((frame.width, frame.height), (W, H));
    let f = CAM.forward();
    let mut s = Stats::default();
    for j in 0..H {
        for i in 0..W {
            let (o, d) = CAM.ray(i, j);
            // closest hit over all objects; ambiguous if any object is, or two hits nearly tie
            let mut best: Option<(usize, f64, DVec3)> = None;
            let mut ambiguous = false;
            let mut ts = Vec::new();
            for (k, shape) in shapes.iter().enumerate() {
                match shape(o, d) {
                    Analytic::Hit { t, n } => {
                        ts.push(t);
                        if best.is_none_or(|(_, bt, _)| t < bt) {
                            best = Some((k, t, n));
                        }
                    }
                    Analytic::Miss => {}
                    Analytic::Ambiguous => ambiguous = true,
                }
            }
            ts.sort_by(f64::total_cmp);
            if ts.len() >= 2 && (ts[1] - ts[0]) < 1e-9 * ts[1] {
                ambiguous = true;
            }
            if ambiguous {
                s.skipped += 1;
                continue;
            }
            let at = format!("pixel ({i}, {j})");
            let z = f64::from(get(&frame, Aov::Depth, i, j)[0]);
            let dist = f64::from(get(&frame, Aov::Distance, i, j)[0]);
            let normal = get(&frame, Aov::Normal, i, j);
            let position = get(&frame, Aov::Position, i, j);
            let cam_normal = get(&frame, Aov::CameraNormal, i, j);
            let alpha = get(&frame, Aov::Alpha, i, j)[0];
            let id = get(&frame, Aov::PrimitiveId, i, j)[0];
            match best {
                None => {
                    s.misses += 1;
                    assert_eq!(z, f64::INFINITY, "{at}: Z on a miss");
                    assert_eq!(dist, f64::INFINITY, "{at}: distance on a miss");
                    assert_eq!(normal, [0.0; 3], "{at}: N on a miss");
                    assert_eq!(position, [0.0; 3], "{at}: P on a miss");
                    assert_eq!(cam_normal, [0.0; 3], "{at}: Nc on a miss");
                    assert_eq!(alpha, 0.0, "{at}: A on a miss");
                    assert_eq!(id, -1.0, "{at}: id on a miss");
                    assert_eq!(get(&frame, Aov::Uv, i, j), [0.0; 2], "{at}: uv on a miss");
                    assert_eq!(
                        get(&frame, Aov::Beauty, i, j),
                        [0.0; 3],
                        "{at}: default background is black"
                    );
                }
                Some((k, t, n)) => {
                    s.hits += 1;
                    let p = o + t * d;
                    let depth = (p - CAM.eye).dot(f);
                    assert_eq!(alpha, 1.0, "{at}: A on a hit");
                    assert_eq!(id, k as f32, "{at}: id is the object index");
                    let e = rel(z, depth);
                    assert!(e <= MAX_REL, "{at}: Z = {z}, expected {depth} (rel. error {e:e})");
                    s.max_depth = s.max_depth.max(e);
                    let e = rel(dist, t);
                    assert!(e <= MAX_REL, "{at}: distance = {dist}, expected {t} (rel. error {e:e})");
                    s.max_distance = s.max_distance.max(e);
                    let e = vec_rel(&normal, n);
                    assert!(e <= MAX_REL, "{at}: N = {normal:?}, expected {n} (error {e:e})");
                    s.max_normal = s.max_normal.max(e);
                    let e = vec_rel(&position, p);
                    assert!(e <= MAX_REL, "{at}: P = {position:?}, expected {p} (rel. error {e:e})");
                    s.max_position = s.max_position.max(e);
                    // camera space: +x right, +y up, looking along −z
                    let r = f.cross(CAM.up).normalize();
                    let u = r.cross(f);
                    let nc = DVec3::new(n.dot(r), n.dot(u), -n.dot(f));
                    let e = vec_rel(&cam_normal, nc);
                    assert!(e <= MAX_REL, "{at}: Nc = {cam_normal:?}, expected {nc} (error {e:e})");
                    s.max_camera_normal = s.max_camera_normal.max(e);
                }
            }
        }
    }
    eprintln!("{objects}\n  {s:?}");
    let total = (W * H) as usize;
    assert!(s.skipped * 100 <= total, "too many ambiguous pixels: {s:?}");
    s
}

#[test]
fn sphere_every_pixel_matches_closed_form() {
    let s = check_scene(
        "(shape: Sphere(center: (0.2, 0.5, 0.5), radius: 1.3))",
        &[sphere(DVec3::new(0.2, 0.5, 0.5), 1.3)],
    );
    assert!(
        s.hits > 300 && s.misses > 300,
        "the sphere should cover part of the image: {s:?}"
    );
}

#[test]
fn tilted_plane_every_pixel_matches_closed_form() {
    // tilted so the horizon crosses the image: hits below, misses above
    let s = check_scene(
        "(shape: Plane(normal: (0.2, 1.0, 0.15), offset: -0.4))",
        &[plane(DVec3::new(0.2, 1.0, 0.15), -0.4)],
    );
    assert!(
        s.hits > 300 && s.misses > 100,
        "the horizon should cross the image: {s:?}"
    );
}

#[test]
fn plane_seen_from_behind_keeps_its_normal() {
    // the camera is on the back side (normal points away from the eye): N is not flipped
    let s = check_scene(
        "(shape: Plane(normal: (0.1, -1.0, 0.2), point: (0.0, -0.5, 0.0)))",
        &[plane(
            DVec3::new(0.1, -1.0, 0.2),
            DVec3::new(0.1, -1.0, 0.2).dot(DVec3::new(0.0, -0.5, 0.0)),
        )],
    );
    assert!(s.hits > 300, "{s:?}");
}

#[test]
fn axis_aligned_box_every_pixel_matches_slab_test() {
    let s = check_scene(
        "(shape: Box(min: (-1.1, -0.4, -0.7), max: (0.9, 1.2, 0.8)))",
        &[placed_box(
            DVec3::new(-1.1, -0.4, -0.7),
            DVec3::new(0.9, 1.2, 0.8),
            DVec3::ONE,
            DVec3::Y,
            0.0,
            DVec3::ZERO,
        )],
    );
    assert!(s.hits > 300 && s.misses > 300, "{s:?}");
}

#[test]
fn rotated_scaled_box_every_pixel_matches_slab_test() {
    // T·R·S with a non-uniform scale: exercises t preservation and the inverse-transpose normal
    let s = check_scene(
        "(shape: Box(min: (-0.7, -0.5, -0.6), max: (0.8, 0.6, 0.9)), \
          transform: (translate: (0.2, 0.3, 0.4), rotate: (axis: (1, 1, 0), degrees: 35), scale: (1.3, 0.8, 1.1)))",
        &[placed_box(
            DVec3::new(-0.7, -0.5, -0.6),
            DVec3::new(0.8, 0.6, 0.9),
            DVec3::new(1.3, 0.8, 1.1),
            DVec3::new(1.0, 1.0, 0.0),
            35.0,
            DVec3::new(0.2, 0.3, 0.4),
        )],
    );
    assert!(s.hits > 100 && s.misses > 300, "{s:?}");
}

#[test]
fn several_objects_closest_hit_and_primitive_ids() {
    // a floor (unbounded) plus bounded objects that occlude each other and the floor
    let s = check_scene(
        "(name: \"floor\", shape: Plane(normal: (0, 1, 0), offset: -0.5)), \
         (name: \"ball\", shape: Sphere(center: (-0.9, 0.3, 0.2), radius: 0.8)), \
         (shape: Box(min: (0.2, -0.5, -0.3), max: (1.4, 0.9, 0.6)), \
          transform: (rotate: (axis: (0, 1, 0), degrees: -25))), \
         (name: \"far ball\", shape: Sphere(center: (0.0, 1.0, 4.0), radius: 1.5))",
        &[
            plane(DVec3::Y, -0.5),
            sphere(DVec3::new(-0.9, 0.3, 0.2), 0.8),
            placed_box(
                DVec3::new(0.2, -0.5, -0.3),
                DVec3::new(1.4, 0.9, 0.6),
                DVec3::ONE,
                DVec3::Y,
                -25.0,
                DVec3::ZERO,
            ),
            sphere(DVec3::new(0.0, 1.0, 4.0), 1.5),
        ],
    );
    assert!(s.hits > 1000 && s.misses > 50, "{s:?}");
}

/// Many overlapping spheres (bounded objects, so the BVH is exercised) over a floor: the closest
/// hit and its id must equal a brute-force search over the closed forms.
#[test]
fn many_spheres_closest_hit_matches_brute_force() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut ron = String::from("(shape: Plane(normal: (0, 1, 0), offset: -1.2))");
    let mut shapes = vec![plane(DVec3::Y, -1.2)];
    for _ in 0..80 {
        let c = DVec3::new(next() * 6.0 - 3.0, next() * 3.0 - 1.0, next() * 8.0 - 2.0);
        let r = 0.1 + next() * 0.4;
        ron.push_str(&format!(
            ", (shape: Sphere(center: ({:?}, {:?}, {:?}), radius: {r:?}))",
            c.x, c.y, c.z
        ));
        shapes.push(sphere(c, r));
    }
    let s = check_scene(&ron, &shapes);
    assert!(s.hits > 1500, "{s:?}");
}

/// Explicitly chosen pixels, including off-centre ones, with the expected numbers spelled out
/// as a sanity check of the harness itself (the camera looks straight down +z here, so the
/// closed forms reduce to a few lines).
#[test]
fn chosen_pixels_of_a_sphere_straight_ahead() {
    let text = "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), up: (0, 1, 0), vfov_deg: 40, width: 64, \
                height: 36), objects: [(shape: Sphere(radius: 1.5))])";
    let scene = Scene::from_ron(text, "chosen.ron").unwrap();
    let frame = render(&scene, &options(&[Aov::Depth, Aov::Distance, Aov::Normal, Aov::Alpha]));
    let tan = 20f64.to_radians().tan();
    for (i, j) in [
        (31, 17),
        (32, 18),
        (0, 0),
        (20, 10),
        (40, 25),
        (26, 5),
        (45, 17),
        (63, 35),
    ] {
        // right = forward × up = (0,0,1)×(0,1,0) = (−1,0,0); true up = +y
        let x = ((f64::from(i) + 0.5) / 64.0 * 2.0 - 1.0) * tan * 64.0 / 36.0;
        let y = (1.0 - (f64::from(j) + 0.5) / 36.0 * 2.0) * tan;
        let d = DVec3::new(-x, y, 1.0).normalize();
        let o = DVec3::new(0.0, 0.0, -5.0);
        let b = o.dot(d);
        let disc = b * b - (o.dot(o) - 2.25);
        let z = f64::from(frame.pixel(Aov::Depth, i, j).unwrap()[0]);
        if disc < 0.0 {
            assert_eq!(z, f64::INFINITY, "({i}, {j}) misses");
            continue;
        }
        let t = -b - disc.sqrt();
        let p = o + t * d;
        assert!(rel(z, p.z + 5.0) <= MAX_REL, "({i}, {j}): Z {z} vs {}", p.z + 5.0);
        let dist = f64::from(frame.pixel(Aov::Distance, i, j).unwrap()[0]);
        assert!(rel(dist, t) <= MAX_REL, "({i}, {j}): distance {dist} vs {t}");
        let n = frame.pixel(Aov::Normal, i, j).unwrap();
        assert!(vec_rel(n, p / 1.5) <= MAX_REL, "({i}, {j}): N {n:?} vs {}", p / 1.5);
        assert_eq!(frame.pixel(Aov::Alpha, i, j).unwrap()[0], 1.0);
    }
    // the centre pixels straddle the axis: their depth is almost exactly 5 − 1.5
    let centre = f64::from(frame.pixel(Aov::Depth, 32, 18).unwrap()[0]);
    assert!((centre - 3.5).abs() < 1e-3, "{centre}");
    // the corners miss
    assert_eq!(frame.pixel(Aov::Depth, 0, 0).unwrap()[0], f32::INFINITY);
}

#[test]
fn depth_miss_option_is_honoured() {
    let scene = scene("(shape: Sphere(center: (0.2, 0.5, 0.5), radius: 1.3))");
    let aovs = [Aov::Depth, Aov::Distance, Aov::Alpha, Aov::Normal];
    let default = render(&scene, &options(&aovs));
    for miss in [0.0f32, -1.0, 1e4, f32::NEG_INFINITY] {
        let frame = render(
            &scene,
            &RenderOptions {
                depth_miss: miss,
                ..options(&aovs)
            },
        );
        let (mut hits, mut misses) = (0, 0);
        for j in 0..H {
            for i in 0..W {
                let hit = default.pixel(Aov::Alpha, i, j).unwrap()[0] == 1.0;
                for aov in [Aov::Depth, Aov::Distance] {
                    let v = frame.pixel(aov, i, j).unwrap()[0];
                    let d = default.pixel(aov, i, j).unwrap()[0];
                    if hit {
                        assert_eq!(
                            v.to_bits(),
                            d.to_bits(),
                            "{aov:?} at ({i}, {j}) must not change on a hit"
                        );
                    } else {
                        assert_eq!(d, f32::INFINITY);
                        assert_eq!(
                            v.to_bits(),
                            miss.to_bits(),
                            "{aov:?} at ({i}, {j}) with depth_miss {miss}"
                        );
                    }
                }
                // only Z and distance depend on the option
                assert_eq!(frame.pixel(Aov::Normal, i, j), default.pixel(Aov::Normal, i, j));
                if hit {
                    hits += 1;
                } else {
                    misses += 1;
                }
            }
        }
        assert!(hits > 300 && misses > 300);
    }
}

#[test]
fn deterministic_across_thread_counts() {
    // lights and shadows so Beauty exercises secondary rays too
    let text = format!(
        "Scene({}, objects: [\
           (shape: Plane(normal: (0, 1, 0), offset: -0.5)), \
           (shape: Sphere(center: (-0.9, 0.3, 0.2), radius: 0.8), material: (specular: 0.5)), \
           (shape: Box(min: (0.2, -0.5, -0.3), max: (1.4, 0.9, 0.6)), \
            transform: (rotate: (axis: (0, 1, 0), degrees: -25), scale: (1, 1.2, 0.9))), \
           (shape: Ellipsoid(center: (0, 1.2, 1.5), radii: (1.0, 0.5, 0.7), rotate: (axis: (0, 0, 1), degrees: 20))), \
           (shape: Cylinder(base: (-2, -0.5, 1), radius: 0.4, height: 1.5)), \
           (shape: Cone(base: (2, -0.5, 1.5), base_radius: 0.6, height: 1.2))], \
         lights: [Directional(direction: (-0.4, -1.0, 0.6)), Point(position: (-3, 4, -4), intensity: (6, 6, 6))])",
        camera_ron(&CAM)
    );
    let scene = Scene::from_ron(&text, "determinism.ron").unwrap();
    let opts = options(&aovs_except(&[Aov::ShadingNormal, Aov::Uncertain]));
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    let one = pool(1).install(|| render(&scene, &opts));
    let two = pool(2).install(|| render(&scene, &opts));
    let two_again = pool(2).install(|| render(&scene, &opts));
    assert_eq!(one.samples.len(), (W * H) as usize * 18);
    assert!(frame_bits(&one) == frame_bits(&two), "1 and 2 threads differ");
    assert!(
        frame_bits(&two) == frame_bits(&two_again),
        "two renders on 2 threads differ"
    );
    // not a trivially constant image
    let ids: std::collections::BTreeSet<u32> = one
        .planar_channel(Aov::PrimitiveId, 0)
        .iter()
        .map(|x| x.to_bits())
        .collect();
    assert!(ids.len() >= 5, "expected most objects to be visible: {ids:?}");
}

#[test]
fn crop_pixels_equal_full_frame_pixels() {
    let scene = scene(
        "(shape: Plane(normal: (0, 1, 0), offset: -0.5)), (shape: Sphere(center: (-0.9, 0.3, 0.2), radius: 0.8))",
    );
    let full = render(&scene, &options(&aovs_except(&[Aov::ShadingNormal, Aov::Uncertain])));
    let crop = Window {
        x0: 5,
        y0: 7,
        x1: 41,
        y1: 30,
    };
    let part = render(
        &scene,
        &RenderOptions {
            crop: Some(crop),
            ..options(&aovs_except(&[Aov::ShadingNormal, Aov::Uncertain]))
        },
    );
    assert_eq!((part.width, part.height), (W, H), "the full image size is kept");
    assert_eq!(part.window, crop);
    assert_eq!(part.samples.len(), 36 * 23 * part.channel_count());
    for j in 0..H {
        for i in 0..W {
            let inside = (5..41).contains(&i) && (7..30).contains(&j);
            for aov in aovs_except(&[Aov::ShadingNormal, Aov::Uncertain]) {
                match part.pixel(aov, i, j) {
                    Some(v) => {
                        assert!(inside, "({i}, {j}) is outside the crop");
                        let f = full.pixel(aov, i, j).unwrap();
                        assert_eq!(
                            v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                            f.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                            "{aov:?} at ({i}, {j})"
                        );
                    }
                    None => assert!(!inside, "({i}, {j}) is inside the crop"),
                }
            }
        }
    }
}

/// Möller–Trumbore for the triangle `a, b, c`, normal `normalize((b − a) × (c − a))`.
fn triangle(a: DVec3, b: DVec3, c: DVec3) -> Shape {
    let n = (b - a).cross(c - a).normalize();
    Box::new(move |o, d| {
        let (e1, e2) = (b - a, c - a);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-12 {
            return Analytic::Ambiguous;
        }
        let tv = o - a;
        let u = tv.dot(pv) / det;
        let qv = tv.cross(e1);
        let v = d.dot(qv) / det;
        let margin = u.min(v).min(1.0 - u - v);
        if margin.abs() < 1e-9 {
            return Analytic::Ambiguous;
        }
        let t = e2.dot(qv) / det;
        if margin < 0.0 || t <= 0.0 {
            Analytic::Miss
        } else {
            Analytic::Hit { t, n }
        }
    })
}

fn triangle_ron(a: DVec3, b: DVec3, c: DVec3) -> String {
    format!(
        "(shape: Triangle(a: ({:?}, {:?}, {:?}), b: ({:?}, {:?}, {:?}), c: ({:?}, {:?}, {:?})))",
        a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z
    )
}

/// A tilted triangle, `Triangle(a:, b:, c:)`: the normal is `normalize((b − a) × (c − a))` (the
/// front side, documented in `src/scene/shapes.rs`), not flipped when seen from behind. Both vertex
/// orders are rendered, so the camera sees the front of one and the back of the other.
#[test]
fn tilted_triangle_every_pixel_matches_closed_form() {
    let (a, b, c) = (
        DVec3::new(-1.5, -0.6, 0.3),
        DVec3::new(1.4, -0.2, 1.2),
        DVec3::new(0.1, 1.6, -0.4),
    );
    // (b − a) × (c − a) points away from the eye: the back side is seen
    assert!((b - a).cross(c - a).dot(CAM.forward()) > 0.0);
    let s = check_scene(&triangle_ron(a, b, c), &[triangle(a, b, c)]);
    assert!(s.hits > 100 && s.misses > 300, "{s:?}");
    let s = check_scene(&triangle_ron(a, c, b), &[triangle(a, c, b)]);
    assert!(s.hits > 100 && s.misses > 300, "{s:?}");
}

/// A triangle placed by a `transform` (scale, rotation, translation).
#[test]
fn transformed_triangle_matches_closed_form() {
    // local triangle, then T·R·S applied to its vertices (an affine map of a triangle is the
    // triangle of the mapped vertices)
    let (a, b, c) = (
        DVec3::new(-1.0, -1.0, 0.0),
        DVec3::new(1.0, -1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    );
    let r = rotation(DVec3::new(1.0, 0.0, 0.0), -30.0);
    let scale = DVec3::new(1.5, 0.7, 1.0);
    let translate = DVec3::new(0.3, 0.6, 0.2);
    let place = |p: DVec3| mat_mul(&r, p * scale) + translate;
    let s = check_scene(
        "(shape: Triangle(a: (-1, -1, 0), b: (1, -1, 0), c: (0, 1, 0)), \
          transform: (translate: (0.3, 0.6, 0.2), rotate: (axis: (1, 0, 0), degrees: -30), scale: (1.5, 0.7, 1)))",
        &[triangle(place(a), place(b), place(c))],
    );
    assert!(s.hits > 100 && s.misses > 300, "{s:?}");
}

#[test]
fn builtin_primitives_are_registered() {
    let names = zeroset::scene::registry::registered_names();
    for builtin in ["Box", "Cone", "Cylinder", "Ellipsoid", "Plane", "Sphere", "Triangle"] {
        assert!(names.iter().any(|n| n == builtin), "{builtin} missing from {names:?}");
    }
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted, "registered_names() is documented as sorted");
}
