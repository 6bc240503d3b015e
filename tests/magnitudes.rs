//! Magnitudes whose squares overflow, through whole scenes: a sphere of radius 10¹⁵⁵ is hit
//! where the closed form says, query directions of length 10⁻³⁰…10³⁰⁰ give `t` in units of their
//! length, and out-of-range sizes are refused at load naming the object and field.

use glam::DVec3;
use zeroset::scene::Scene;

mod support;
use support::scene_from_ron;
use zeroset_primitives::{HitRequest, Interval, Ray, SurfaceHit};

fn scene(objects: &str) -> Scene {
    scene_from_ron(
        &format!("Scene(camera: (eye: (0, 0, -10), look_at: (0, 0, 0)), objects: [{objects}])"),
        "magnitudes.ron",
    )
}

#[test]
fn sphere_of_radius_1e155_is_hit_at_its_closed_form() {
    for radius in [1e155, 1e200, 1e300] {
        let s = scene(&format!(
            "(shape: Sphere(center: (0, 0, 0), radius: {radius:e})), (shape: Sphere(center: (0, 0, {:e}), radius: 1))",
            4.0 * radius
        ));
        // from 2R in front, straight on: t = R, normal −z
        let ray = Ray::new(DVec3::new(0.0, 0.0, -2.0 * radius), DVec3::Z);
        let (object, raw) = s.intersect(&ray, Interval::POSITIVE).expect("hit");
        assert_eq!(object, 0);
        assert!(
            (raw.t - radius).abs() <= 1e-15 * radius,
            "R = {radius:e}: t = {:e}",
            raw.t
        );
        let n = s.objects[0].primitive.normal_at(&ray, &raw);
        assert!((n + DVec3::Z).length() < 1e-15, "{n}");
        // the small sphere behind it, seen from inside the big one along +z
        let inside = Ray::new(DVec3::new(0.0, 0.0, 3.0 * radius), DVec3::Z);
        let (object, raw) = s.intersect(&inside, Interval::POSITIVE).unwrap();
        assert_eq!(object, 1);
        assert!((raw.t - (radius - 1.0)).abs() <= 1e-15 * radius);
    }
}

#[test]
fn query_directions_of_any_length_give_t_in_their_units() {
    let s = scene(
        "(shape: Sphere(center: (0, 0, 5), radius: 1)), (shape: Box(min: (2, -1, 4), max: (4, 1, 6))),
         (shape: Cylinder(base: (-3, -1, 5), axis: (0, 1, 0), radius: 1, height: 2)),
         (shape: Triangle(a: (-1, 3, 4), b: (1, 3, 4), c: (0, 5, 4))),
         (shape: Ellipsoid(center: (0, -3, 5), radii: (1, 0.5, 0.7)))",
    );
    let targets = [
        DVec3::new(0.1, 0.2, 5.0),
        DVec3::new(3.0, 0.3, 5.0),
        DVec3::new(-3.0, 0.0, 5.0),
        DVec3::new(0.0, 3.5, 4.0),
        DVec3::new(0.2, -3.0, 5.0),
    ];
    for target in targets {
        let unit = Ray::new_normalized(DVec3::ZERO, target);
        let (object, hit) = s.intersect(&unit, Interval::POSITIVE).expect("unit ray hits");
        for length in [1e-30, 1e-100, 1e-300, 1e30, 1e155, 1e300] {
            let ray = Ray::new(DVec3::ZERO, unit.dir * length);
            let (o, h) = s
                .intersect(&ray, Interval::POSITIVE)
                .unwrap_or_else(|| panic!("|d| = {length:e} towards {target} misses"));
            assert_eq!(o, object);
            let t = hit.t / length;
            assert!(
                (h.t - t).abs() <= 1e-12 * t,
                "|d| = {length:e}: t = {:e}, expected {t:e}",
                h.t
            );
            // the full record as `query` writes it: the same point and normal as the unit ray's
            let primitive = &*s.objects[o as usize].primitive;
            let full = SurfaceHit::complete(primitive, &ray, &h, HitRequest::ALL);
            let reference = SurfaceHit::complete(primitive, &unit, &hit, HitRequest::ALL);
            assert!((full.point - reference.point).length() <= 1e-12 * reference.point.length());
            assert!(
                (full.normal.unwrap() - reference.normal.unwrap()).length() < 1e-9,
                "|d| = {length:e}"
            );
        }
    }
}

#[test]
fn out_of_range_sizes_are_refused_naming_the_field() {
    for (object, field) in [
        ("Cylinder(radius: 1e160, height: 1)", "radius"),
        ("Cone(base_radius: 1, top_radius: 0, height: 1e-170)", "height"),
        ("Ellipsoid(radii: (1, 1e151, 1))", "radii.y"),
        ("Disk(center: (2e150, 0, 0), radius: 1)", "center"),
    ] {
        let err = Scene::from_ron(
            &format!("Scene(camera: (), objects: [(name: \"big\", shape: {object})])"),
            "limits.ron",
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("objects[0] \"big\"") && err.contains(&format!("field `{field}`")),
            "{err}"
        );
    }
}
