//! The generic property checks (`zeroset_primitives::testing`) on every built-in primitive.

use glam::DVec3;
use rand::rngs::StdRng;
use rand::Rng;
use zeroset_primitives::testing::{check_primitive, Expectations};
use zeroset_primitives::*;

fn random_point(rng: &mut StdRng, half: f64) -> DVec3 {
    DVec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

#[test]
fn sphere_properties() {
    let report = check_primitive(
        "Sphere",
        |rng| Sphere::new(random_point(rng, 5.0), rng.random_range(0.1..4.0)).unwrap(),
        Expectations::default(),
    );
    assert!(report.max_t_error < 1e-9, "{report:?}");
}

#[test]
fn plane_properties() {
    check_primitive(
        "Plane",
        |rng| Plane::new(random_point(rng, 1.0), rng.random_range(-3.0..3.0)).unwrap(),
        Expectations::default(),
    );
}
