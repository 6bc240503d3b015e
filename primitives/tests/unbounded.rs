//! The generic root finder on surfaces whose bounds are infinite (a plane under `Offset` or
//! `SmoothUnion`): rays whose range runs to `+∞` find the first root, rays that leave the
//! surface are misses, and rays that cannot be decided are counted as uncertain, never a
//! silent miss.

use glam::DVec3;
use std::sync::Arc;
use zeroset_primitives::root::uncertain_while;
use zeroset_primitives::{
    first_root, Aabb, Implicit, Intersect, Interval, Offset, Plane, Primitive, Ray, RootOptions, SmoothUnion, Sphere,
};

fn ground() -> Arc<dyn Primitive> {
    Arc::new(Plane::new(DVec3::Z, 0.0).unwrap())
}

/// `t` where the ray reaches height `z`, worked out directly.
fn t_at_height(ray: &Ray, z: f64) -> f64 {
    (z - ray.origin.z) / ray.dir.z
}

#[test]
fn offset_plane_is_hit_along_an_infinite_range() {
    let offset = Offset::new(ground(), 0.5).unwrap();
    let mut checked = 0;
    for (i, dir) in [
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::new(0.1, 0.2, -1.0),
        DVec3::new(3.0, -2.0, -1.0),
        DVec3::new(-40.0, 7.0, -1.0),
    ]
    .into_iter()
    .enumerate()
    {
        let ray = Ray::new_normalized(DVec3::new(0.3, -0.2, 5.0 + i as f64), dir);
        let (hit, uncertain) = uncertain_while(|| offset.intersect(&ray, Interval::POSITIVE));
        let t = hit.expect("the offset plane z = 0.5 is hit").t;
        let expected = t_at_height(&ray, 0.5);
        assert!(
            (t - expected).abs() <= 1e-6 * expected,
            "{dir}: t = {t}, expected {expected}"
        );
        assert!(!uncertain);
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn smooth_union_with_a_plane_is_hit_along_an_infinite_range() {
    let ball: Arc<dyn Primitive> = Arc::new(Sphere::new(DVec3::new(0.0, 0.0, 3.0), 1.0).unwrap());
    let blend = SmoothUnion::new(ground(), ball, 0.5).unwrap();
    // far from the ball the blend is the plane itself: t = 5 exactly (within the tolerance)
    let ray = Ray::new(DVec3::new(100.0, 0.0, 5.0), DVec3::new(0.0, 0.0, -1.0));
    let (hit, uncertain) = uncertain_while(|| blend.intersect(&ray, Interval::POSITIVE));
    assert!((hit.expect("plane hit").t - 5.0).abs() < 1e-6 && !uncertain);
    // straight down onto the ball: its top at z = 4 (the blend only lowers Φ, so not later)
    let ray = Ray::new(DVec3::new(0.0, 0.0, 10.0), DVec3::new(0.0, 0.0, -1.0));
    let t = blend.intersect(&ray, Interval::POSITIVE).expect("ball hit").t;
    assert!((t - 6.0).abs() < 1e-6, "t = {t}");
}

#[test]
fn rays_leaving_the_plane_are_certain_misses() {
    let offset = Offset::new(ground(), 0.5).unwrap();
    for dir in [DVec3::Z, DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 0.2)] {
        let ray = Ray::new_normalized(DVec3::new(0.0, 0.0, 2.0), dir);
        let report = first_root(&offset, &ray, Interval::POSITIVE, &RootOptions::default());
        assert_eq!(report.hit, None, "{dir}");
        assert!(!report.uncertain, "{dir}: {} evaluations", report.evaluations);
    }
}

#[test]
fn a_ray_parallel_to_the_plane_is_uncertain_not_a_silent_miss() {
    let offset = Offset::new(ground(), 0.5).unwrap();
    let ray = Ray::new(DVec3::new(0.0, 0.0, 2.0), DVec3::X);
    let (report, uncertain) =
        uncertain_while(|| first_root(&offset, &ray, Interval::POSITIVE, &RootOptions::default()));
    assert_eq!(report.hit, None);
    assert!(report.uncertain && uncertain);
    assert!(report.evaluations >= RootOptions::default().max_evaluations);
    // a range starting at −∞ has no first point: uncertain too
    let ray = Ray::new(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z);
    let report = first_root(
        &offset,
        &ray,
        Interval::new(f64::NEG_INFINITY, f64::INFINITY),
        &RootOptions::default(),
    );
    assert!(report.hit.is_none() && report.uncertain);
}

/// An unbounded type without a Lipschitz bound: the plane z = 100000, sampled over segments
/// doubling in length from the origin's scale (1), found in the 17th.
struct FarPlane;

impl Implicit for FarPlane {
    fn phi(&self, p: DVec3) -> f64 {
        p.z - 1e5
    }
    fn bounds(&self) -> Aabb {
        Aabb::EVERYTHING
    }
}

#[test]
fn unbounded_without_a_lipschitz_bound_is_sampled_in_growing_segments() {
    let ray = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.8));
    let report = first_root(&FarPlane, &ray, Interval::POSITIVE, &RootOptions::default());
    let t = report.hit.expect("found").t;
    assert!((t - 1e5 / 0.8).abs() < 1e-6, "t = {t}");
    assert!(!report.uncertain);
    // facing away: not decidable without a bound, so the budget runs out and it is counted
    let away = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.6, -0.8));
    let report = first_root(&FarPlane, &away, Interval::POSITIVE, &RootOptions::default());
    assert!(report.hit.is_none() && report.uncertain);
}
