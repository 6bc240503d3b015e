use super::*;
use crate::camera::{Orthographic, Perspective};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use std::ops::Range;
use zeroset_primitives::{Interval, Ray};

/// A random box: its centre's coordinates drawn from `centre`, its half-extents from `half`.
fn random_box(rng: &mut impl Rng, centre: [Range<f64>; 3], half: Range<f64>) -> Aabb {
    let [x, y, z] = centre;
    let c = DVec3::new(rng.random_range(x), rng.random_range(y), rng.random_range(z));
    let h = DVec3::new(
        rng.random_range(half.clone()),
        rng.random_range(half.clone()),
        rng.random_range(half),
    );
    Aabb::new(c - h, c + h)
}

/// A `width × height` camera at `z = −10` (eye `x` and `y` within ±5) looking along `+z`
/// tilted by up to `tilt` on each axis, its vertical field of view drawn from `fov` (degrees).
fn random_camera(rng: &mut impl Rng, width: u32, height: u32, tilt: f64, fov: Range<f64>) -> Camera {
    let eye = DVec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), -10.0);
    let direction = DVec3::new(rng.random_range(-tilt..tilt), rng.random_range(-tilt..tilt), 1.0);
    Camera::new(eye, direction, DVec3::Y, rng.random_range(fov), width, height).unwrap()
}

/// A pinhole whose principal point is offset by up to `offset` pixels on each axis.
fn random_pinhole(rng: &mut impl Rng, offset: f64) -> Model {
    Model::Perspective(Perspective {
        principal_offset: DVec2::new(rng.random_range(-offset..offset), rng.random_range(-offset..offset)),
    })
}

/// Checks that every pixel of `camera` whose centre lies outside `rect` has a ray missing
/// `bounds` grown by half the footprint's margin (the f64 slab test of `Aabb::clip`);
/// returns how many pixels inside `rect` meet it and how many are left out.
fn check_pixels_outside(camera: &Camera, bounds: &Aabb, rect: &ImageRect, trial: usize) -> (usize, usize) {
    let grown = bounds.expanded(0.5 * enlargement(bounds, camera.eye, 0.0));
    count_pixels(camera, rect, trial, |ray| grown.clip(ray, Interval::POSITIVE).is_some())
}

/// Checks that no pixel of `camera` whose centre lies outside `rect` has a ray that
/// `meets` the shape; returns how many pixels inside `rect` meet it and how many are left
/// out.
fn count_pixels(camera: &Camera, rect: &ImageRect, trial: usize, meets: impl Fn(&Ray) -> bool) -> (usize, usize) {
    let (mut meeting, mut left_out) = (0, 0);
    for j in 0..camera.height {
        for i in 0..camera.width {
            let meets = meets(&camera.pixel_ray(i, j).unwrap());
            if rect.holds_pixel(i, j) {
                meeting += usize::from(meets);
            } else {
                left_out += 1;
                assert!(
                    !meets,
                    "trial {trial}: pixel ({i}, {j}) outside {rect:?} meets the shape"
                );
            }
        }
    }
    (meeting, left_out)
}

/// Over random pinhole (principal offsets included) and orthographic cameras and random
/// boxes, near and far, in view and beside it: every pixel whose centre is outside the
/// footprint has a ray that misses the box grown by half the margin (the f64 slab test of
/// `Aabb::clip`), and the footprint leaves pixels out in most trials.
#[test]
fn pixels_outside_the_footprint_miss_the_box() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(71);
    let (width, height) = (48u32, 32u32);
    let (mut culled, mut rects, mut hits) = (0usize, 0usize, 0usize);
    for trial in 0..400 {
        let mut camera = random_camera(&mut rng, width, height, 0.3, 10.0..90.0);
        camera.model = if trial % 3 == 0 {
            Model::Orthographic(Orthographic {
                width: rng.random_range(2.0..30.0),
            })
        } else {
            random_pinhole(&mut rng, 8.0)
        };
        let bounds = random_box(&mut rng, [-8.0..8.0, -8.0..8.0, -12.0..20.0], 0.01..3.0);
        let Some(rect) = camera.footprint(&bounds) else {
            continue;
        };
        rects += 1;
        let (meeting, left_out) = check_pixels_outside(&camera, &bounds, &rect, trial);
        hits += meeting;
        culled += left_out;
    }
    assert!(rects > 200, "{rects} footprints");
    assert!(culled > 100 * rects, "{culled} pixels left out over {rects} footprints");
    assert!(hits > 20 * rects, "{hits} pixels meeting their boxes");
}

/// Four boxes at a time give each box's own footprint (to within rounding, `10⁻⁹` pixels)
/// and its distance less the enlargement, `None` exactly where the single-box footprint has
/// none (boxes beside, behind and around the eye, a pinhole with principal offsets and
/// with a mesh's origin rounding), and `None` for every box through an orthographic camera.
#[test]
fn four_boxes_at_a_time_give_each_box_s_footprint() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(72);
    let (mut compared, mut without) = (0, 0);
    for trial in 0..500 {
        let mut camera = random_camera(&mut rng, 640, 480, 0.5, 10.0..90.0);
        camera.model = random_pinhole(&mut rng, 30.0);
        let eye = camera.eye;
        let projector = camera.box_projector(if trial % 2 == 0 { 0.0 } else { 1e-6 });
        let boxes: [Aabb; 4] =
            std::array::from_fn(|_| random_box(&mut rng, [-8.0..8.0, -8.0..8.0, -14.0..20.0], 0.001..2.0));
        let four = projector.pinhole_footprints(&boxes, TIGHT_WIDENING);
        for (bounds, found) in boxes.iter().zip(four) {
            match (projector.footprint(bounds, TIGHT_WIDENING), found) {
                (Some(one), Some((rect, near))) => {
                    compared += 1;
                    let scale = 1e-9 * (1.0 + one.x0.abs().max(one.x1.abs()).max(one.y0.abs()).max(one.y1.abs()));
                    for (a, b) in [
                        (one.x0, rect.x0),
                        (one.x1, rect.x1),
                        (one.y0, rect.y0),
                        (one.y1, rect.y1),
                    ] {
                        assert!((a - b).abs() <= scale, "trial {trial}: {one:?} against {rect:?}");
                    }
                    let distance = (eye.clamp(bounds.min, bounds.max) - eye).length();
                    let expected = distance - projector.enlargement(bounds);
                    assert!(
                        (near - expected).abs() <= 1e-12 * (1.0 + distance),
                        "trial {trial}: {near} against {expected}"
                    );
                }
                (None, None) => without += 1,
                (one, four) => panic!("trial {trial}: {one:?} against {four:?} for {bounds:?}"),
            }
        }
    }
    assert!(
        compared > 1000 && without > 100,
        "{compared} compared, {without} without a footprint"
    );
    let mut orthographic = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
    orthographic.model = Model::Orthographic(Orthographic { width: 10.0 });
    let bounds = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 5.0));
    assert!(orthographic
        .box_projector(0.0)
        .footprint(&bounds, TIGHT_WIDENING)
        .is_some());
    assert_eq!(
        orthographic
            .box_projector(0.0)
            .pinhole_footprints(&[bounds; 4], TIGHT_WIDENING),
        [None; 4]
    );
}

/// A ball's footprint: every pixel whose centre it leaves out has a ray that misses the ball
/// grown by half the enlargement (the distance from the centre to the ray, in f64), the
/// rectangle lies within the footprint of the ball's box and is smaller than it, and `near`
/// is the distance to the ball less the enlargement; `None` for a ball reaching behind the
/// eye plane and for an orthographic camera.
#[test]
fn pixels_outside_a_ball_s_footprint_miss_the_ball() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(73);
    let (width, height) = (64u32, 48u32);
    let (mut rects, mut culled, mut meeting, mut smaller) = (0usize, 0usize, 0usize, 0usize);
    for trial in 0..300 {
        let mut camera = random_camera(&mut rng, width, height, 0.3, 20.0..90.0);
        camera.model = random_pinhole(&mut rng, 6.0);
        let eye = camera.eye;
        let centre = DVec3::new(
            rng.random_range(-8.0..8.0),
            rng.random_range(-8.0..8.0),
            rng.random_range(-12.0..20.0),
        );
        let radius = rng.random_range(0.05..3.0);
        let bounds = Aabb::new(centre - DVec3::splat(radius), centre + DVec3::splat(radius));
        let projector = camera.box_projector(0.0);
        let Some((rect, near)) = projector.ball_footprint(centre, radius, &bounds, TIGHT_WIDENING) else {
            let local = camera.world_to_local(centre);
            assert!(
                local.z - radius <= 2.0 * projector.enlargement(&bounds) + 1e-9,
                "trial {trial}: in front, no footprint"
            );
            continue;
        };
        rects += 1;
        let delta = projector.enlargement(&bounds);
        let distance = (centre - eye).length() - radius - delta;
        assert!(
            (near - distance).abs() <= 1e-12 * (1.0 + distance.abs()),
            "trial {trial}"
        );
        let grown = radius + 0.5 * delta;
        // whether a ray comes within `grown` of the centre (its closest approach, t ≥ 0)
        let meets = |ray: &Ray| {
            let t = (centre - ray.origin).dot(ray.dir).max(0.0) / ray.dir.length_squared();
            (ray.at(t) - centre).length() <= grown
        };
        // just outside each side of the rectangle (a millionth of a pixel), along it
        for k in 0..=64 {
            let (u, v) = (f64::from(k) / 64.0, 1e-6);
            let (x, y) = (rect.x0 + u * (rect.x1 - rect.x0), rect.y0 + u * (rect.y1 - rect.y0));
            for (px, py) in [(rect.x0 - v, y), (rect.x1 + v, y), (x, rect.y0 - v), (x, rect.y1 + v)] {
                let ray = camera.ray_through(px, py).unwrap();
                assert!(
                    !meets(&ray),
                    "trial {trial}: ({px}, {py}) just outside {rect:?} meets the ball"
                );
            }
        }
        let (inside, outside) = count_pixels(&camera, &rect, trial, meets);
        meeting += inside;
        culled += outside;
        if let Some(boxed) = projector.footprint(&bounds, TIGHT_WIDENING) {
            let within = rect.x0 >= boxed.x0 - 1e-6
                && rect.x1 <= boxed.x1 + 1e-6
                && rect.y0 >= boxed.y0 - 1e-6
                && rect.y1 <= boxed.y1 + 1e-6;
            assert!(within, "trial {trial}: {rect:?} outside the box's {boxed:?}");
            let area = |r: &ImageRect| (r.x1 - r.x0) * (r.y1 - r.y0);
            smaller += usize::from(area(&rect) < 0.95 * area(&boxed));
        }
    }
    assert!(
        rects > 100 && culled > 50 * rects && meeting > 5 * rects,
        "{rects} rects, {culled} culled, {meeting} meeting"
    );
    assert!(smaller > rects / 2, "{smaller} of {rects} smaller than the box's");
    let mut orthographic = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
    orthographic.model = Model::Orthographic(Orthographic { width: 10.0 });
    let bounds = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 6.0));
    assert_eq!(
        orthographic
            .box_projector(0.0)
            .ball_footprint(DVec3::new(0.0, 0.0, 5.0), 1.0, &bounds, TIGHT_WIDENING),
        None
    );
}

/// The cut footprint of boxes reaching behind a pinhole's eye plane (long slabs under and
/// beside the eye, boxes around it or behind it): every pixel whose centre it leaves out has
/// a ray that misses the box grown by half the margin, the pixels meeting the box are held,
/// and most footprints leave pixels out (the ground's sky). Boxes wholly in front get the
/// plain footprint.
#[test]
fn pixels_outside_the_cut_footprint_miss_the_box() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(73);
    let (width, height) = (48u32, 32u32);
    let (mut cut, mut culled, mut hits, mut none) = (0usize, 0usize, 0usize, 0usize);
    for trial in 0..400 {
        let eye = DVec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(0.2..5.0),
            rng.random_range(-3.0..3.0),
        );
        let direction = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.8..0.3),
            rng.random_range(-1.0..1.0),
        );
        let Ok(mut camera) = Camera::new(eye, direction, DVec3::Y, rng.random_range(10.0..120.0), width, height) else {
            continue;
        };
        camera.model = random_pinhole(&mut rng, 8.0);
        let bounds = if trial % 2 == 0 {
            // a thick ground slab under the eye, reaching far behind it
            let half = rng.random_range(5.0..200.0);
            let top = rng.random_range(-0.5..0.1);
            Aabb::new(
                DVec3::new(-half, top - rng.random_range(0.0..0.5), -half),
                DVec3::new(half, top, half),
            )
        } else {
            random_box(&mut rng, [-6.0..6.0, -6.0..6.0, -6.0..6.0], 0.01..6.0)
        };
        let projector = camera.box_projector(0.0);
        let Some(rect) = projector.footprint_clipped(&bounds, 1.0) else {
            none += 1;
            continue;
        };
        if projector.footprint(&bounds, 1.0) == Some(rect) {
            continue;
        }
        cut += 1;
        let (meeting, left_out) = check_pixels_outside(&camera, &bounds, &rect, trial);
        hits += meeting;
        culled += usize::from(left_out > 0);
    }
    assert!(cut > 150, "{cut} cut footprints ({none} without one)");
    assert!(culled > cut / 3, "{culled} of {cut} cut footprints leave pixels out");
    assert!(hits > 100 * cut, "{hits} pixels meeting their boxes");
}

/// Over random cameras and random sets of up to 40 boxes: every pixel the coverage leaves
/// out has a ray that misses every box grown by half its margin, every pixel some box's
/// footprint holds is held, and the coverage leaves out pixels the single box around them all
/// would hold.
#[test]
fn pixels_outside_the_coverage_miss_every_box() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(72);
    let (width, height) = (48u32, 32u32);
    let (mut covered, mut finer) = (0usize, 0usize);
    for trial in 0..200 {
        let eye = DVec3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), -12.0);
        let mut camera = Camera::new(eye, DVec3::Z, DVec3::Y, rng.random_range(20.0..70.0), width, height).unwrap();
        if trial % 4 == 0 {
            camera.model = Model::Orthographic(Orthographic {
                width: rng.random_range(5.0..30.0),
            });
        }
        let boxes: Vec<Aabb> = (0..rng.random_range(1..=40))
            .map(|_| random_box(&mut rng, [-6.0..6.0, -4.0..4.0, -2.0..8.0], 0.01..1.0))
            .collect();
        let Some(coverage) = camera.coverage(&boxes, 0.0) else {
            continue;
        };
        covered += 1;
        let all = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
        let whole = camera.footprint(&all).unwrap();
        let rects: Vec<ImageRect> = boxes.iter().map(|b| camera.footprint(b).unwrap()).collect();
        for j in 0..height {
            for i in 0..width {
                let held = coverage.holds_pixel(i, j);
                assert_eq!(
                    held,
                    rects.iter().any(|r| r.holds_pixel(i, j)),
                    "trial {trial}, pixel ({i}, {j})"
                );
                if held {
                    continue;
                }
                finer += usize::from(whole.holds_pixel(i, j));
                let ray = camera.pixel_ray(i, j).unwrap();
                for b in &boxes {
                    let delta = enlargement(b, camera.eye, 0.0);
                    assert!(
                        b.expanded(0.5 * delta).clip(&ray, Interval::POSITIVE).is_none(),
                        "trial {trial}: pixel ({i}, {j}) meets {b:?}"
                    );
                }
            }
        }
    }
    assert!(covered > 150, "{covered} coverages");
    assert!(finer > 1000, "{finer} pixels left out inside the whole box's footprint");
}

/// No footprint where the camera cannot give one: a box reaching behind the pinhole's eye
/// plane, an unbounded or empty box, a panorama.
#[test]
fn no_footprint_where_rays_are_not_confined() {
    let camera = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
    let in_front = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 6.0));
    let rect = camera.footprint(&in_front).expect("a box in front has a footprint");
    assert!(rect.holds_pixel(32, 24) && !rect.holds_pixel(0, 0));
    let behind = Aabb::new(DVec3::new(-1.0, -1.0, -1.0), DVec3::new(1.0, 1.0, 6.0));
    assert_eq!(camera.footprint(&behind), None);
    assert_eq!(camera.footprint(&Aabb::EVERYTHING), None);
    assert_eq!(camera.footprint(&Aabb::EMPTY), None);
    let mut panorama = camera.clone();
    panorama.model = Model::Equirectangular(crate::camera::Equirectangular {
        azimuth: (-3.0, 3.0),
        elevation: (-1.5, 1.5),
    });
    assert_eq!(panorama.footprint(&in_front), None);
}
