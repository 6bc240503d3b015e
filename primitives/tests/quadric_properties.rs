//! The generic property checks (`zeroset_primitives::testing`) on the quadric primitives: box,
//! cylinder and cone (capped and open), ellipsoid.

use glam::{DQuat, DVec3};
use rand::rngs::StdRng;
use rand::Rng;
use zeroset_primitives::testing::{check_primitive, CheckReport, Expectations};
use zeroset_primitives::*;

fn random_point(rng: &mut StdRng, half: f64) -> DVec3 {
    DVec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

fn random_axis(rng: &mut StdRng) -> DVec3 {
    loop {
        let v = random_point(rng, 1.0);
        if v.length() > 0.1 {
            return v;
        }
    }
}

fn random_rotation(rng: &mut StdRng) -> DQuat {
    DQuat::from_axis_angle(
        random_axis(rng).normalize(),
        rng.random_range(0.0..std::f64::consts::TAU),
    )
}

/// Closed-form `t` must agree with the root finder far inside the harness's own 1e-7 acceptance.
fn assert_accurate(name: &str, report: CheckReport) {
    eprintln!("{name}: {report:?}");
    assert!(report.max_t_error < 1e-9, "{name}: {report:?}");
    assert!(
        report.rays > 0 && report.disagreements * 500 <= report.rays,
        "{name}: {report:?}"
    );
}

fn open(expect: Expectations) -> Expectations {
    Expectations {
        convex: false,
        ..expect
    }
}

#[test]
fn cuboid_properties() {
    let report = check_primitive(
        "Cuboid",
        |rng| {
            let min = random_point(rng, 5.0);
            let extent = DVec3::new(
                rng.random_range(0.1..4.0),
                rng.random_range(0.1..4.0),
                rng.random_range(0.1..4.0),
            );
            Cuboid::new(min, min + extent).unwrap()
        },
        Expectations::default(),
    );
    assert_accurate("Cuboid", report);
}

fn random_cylinder(rng: &mut StdRng, capped: bool) -> Cylinder {
    let base = random_point(rng, 5.0);
    let axis = random_axis(rng);
    Cylinder::new(
        base,
        axis,
        rng.random_range(0.1..3.0),
        rng.random_range(0.1..5.0),
        capped,
    )
    .unwrap()
}

#[test]
fn capped_cylinder_properties() {
    let report = check_primitive(
        "Cylinder capped",
        |rng| random_cylinder(rng, true),
        Expectations::default(),
    );
    assert_accurate("Cylinder capped", report);
}

#[test]
fn open_cylinder_properties() {
    let report = check_primitive(
        "Cylinder open",
        |rng| random_cylinder(rng, false),
        open(Expectations::default()),
    );
    assert_accurate("Cylinder open", report);
}

/// A pointed cone (`top_radius = 0`) or a frustum whose top radius is smaller or larger than the
/// base radius.
fn random_cone(rng: &mut StdRng, pointed: bool, capped: bool) -> Cone {
    let base = random_point(rng, 5.0);
    let axis = random_axis(rng);
    let r0 = rng.random_range(0.1..3.0);
    let r1 = if pointed { 0.0 } else { rng.random_range(0.05..3.0) };
    Cone::new(base, axis, r0, r1, rng.random_range(0.1..5.0), capped).unwrap()
}

#[test]
fn capped_pointed_cone_properties() {
    let report = check_primitive(
        "Cone pointed capped",
        |rng| random_cone(rng, true, true),
        Expectations::default(),
    );
    assert_accurate("Cone pointed capped", report);
}

#[test]
fn open_pointed_cone_properties() {
    let report = check_primitive(
        "Cone pointed open",
        |rng| random_cone(rng, true, false),
        open(Expectations::default()),
    );
    assert_accurate("Cone pointed open", report);
}

#[test]
fn capped_frustum_properties() {
    let report = check_primitive(
        "Frustum capped",
        |rng| random_cone(rng, false, true),
        Expectations::default(),
    );
    assert_accurate("Frustum capped", report);
}

#[test]
fn open_frustum_properties() {
    let report = check_primitive(
        "Frustum open",
        |rng| random_cone(rng, false, false),
        open(Expectations::default()),
    );
    assert_accurate("Frustum open", report);
}

#[test]
fn ellipsoid_properties() {
    let report = check_primitive(
        "Ellipsoid",
        |rng| {
            // radii in [0.2, 4]: ratios up to 20
            let radii = DVec3::new(
                rng.random_range(0.2..4.0),
                rng.random_range(0.2..4.0),
                rng.random_range(0.2..4.0),
            );
            Ellipsoid::new(random_point(rng, 5.0), radii, random_rotation(rng)).unwrap()
        },
        Expectations::default(),
    );
    assert_accurate("Ellipsoid", report);
}
