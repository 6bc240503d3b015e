//! Distance answers that combine others: transforms (exact under similarities, guaranteed bounds
//! under other affine maps) and CSG (exact where a child's nearest point survives, guaranteed
//! bounds otherwise), against closed forms computed here.

use glam::{DAffine3, DMat3, DQuat, DVec3};
use std::sync::Arc;
use zeroset_primitives::{Closest, Csg, CsgOp, Cuboid, Ellipsoid, Implicit, Primitive, Sphere, Transformed};

/// A small deterministic generator of points in `[-r, r]³`.
struct Points(u64);

impl Points {
    fn next(&mut self, r: f64) -> DVec3 {
        let mut coordinate = || {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * r
        };
        DVec3::new(coordinate(), coordinate(), coordinate())
    }
}

/// Asserts that `c`'s distance bounds hold `reference` (the distance from `p` computed here), up
/// to `1e-12·(1 + reference)`; returns that slack.
fn assert_bounds_hold(p: DVec3, c: &Closest, reference: f64) -> f64 {
    let slack = 1e-12 * (1.0 + reference);
    assert!(
        c.lower <= reference + slack && reference <= c.upper + slack,
        "{p}: [{}, {}] misses {reference}",
        c.lower,
        c.upper
    );
    slack
}

#[test]
fn a_sphere_under_a_similarity_answers_exactly() {
    let rotation = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let scale = 2.5;
    let map = DAffine3::from_scale_rotation_translation(DVec3::splat(scale), rotation, DVec3::new(10.0, -3.0, 4.0));
    let sphere = Sphere::new(DVec3::new(0.5, 0.0, -0.25), 1.0).unwrap();
    let placed = Transformed::new(sphere, map).unwrap();
    let centre = map.transform_point3(DVec3::new(0.5, 0.0, -0.25));
    let mut points = Points(3);
    for _ in 0..2000 {
        let p = centre + points.next(8.0);
        let reference = ((p - centre).length() - scale).abs();
        let c = placed.closest(p).unwrap();
        assert!(c.is_exact(), "{p}: a similarity keeps distances exact");
        assert!(
            (c.upper - reference).abs() <= 1e-13 * (1.0 + reference),
            "{p}: {} against {reference}",
            c.upper
        );
        let q = c.point.unwrap();
        assert!(((q - centre).length() - scale).abs() <= 1e-13 * scale);
    }
}

#[test]
fn a_sphere_stretched_into_an_ellipsoid_bounds_the_ellipsoid_s_distance() {
    // the unit sphere under diag(3, 1, 0.5) then a rotation is this ellipsoid
    let rotation = DQuat::from_axis_angle(DVec3::new(0.0, 1.0, 1.0).normalize(), 0.4);
    let radii = DVec3::new(3.0, 1.0, 0.5);
    let linear = DMat3::from_quat(rotation) * DMat3::from_diagonal(radii);
    let placed = Transformed::new(
        Sphere::new(DVec3::ZERO, 1.0).unwrap(),
        DAffine3::from_mat3_translation(linear, DVec3::new(1.0, 2.0, 3.0)),
    )
    .unwrap();
    let ellipsoid = Ellipsoid::new(DVec3::new(1.0, 2.0, 3.0), radii, rotation).unwrap();
    let mut points = Points(9);
    let mut widest = 0.0f64;
    for _ in 0..2000 {
        let p = DVec3::new(1.0, 2.0, 3.0) + points.next(5.0);
        let reference = ellipsoid.closest(p).unwrap().upper;
        let c = placed.closest(p).unwrap();
        let slack = assert_bounds_hold(p, &c, reference);
        let q = c.point.unwrap();
        assert!(ellipsoid.phi(q).abs() <= 1e-12, "{p}: the witness lies on the surface");
        assert!(((q - p).length() - c.upper).abs() <= slack);
        widest = widest.max(c.upper - c.lower);
    }
    assert!(widest > 0.0, "a non-uniform stretch cannot claim exactness");
}

/// Distance from `p` to the circle of radius `r` about `centre` in the plane normal to `axis`.
fn circle_distance(p: DVec3, centre: DVec3, axis: DVec3, r: f64) -> f64 {
    let d = p - centre;
    let along = d.dot(axis);
    let radial = (d - axis * along).length();
    ((radial - r).powi(2) + along * along).sqrt()
}

#[test]
fn csg_distances_are_exact_where_a_child_s_nearest_point_survives_and_bounded_otherwise() {
    // a union of two unit spheres whose centres are 1.2 apart, and a unit sphere with its cap
    // above z = 0.5 cut away by a box
    let a = Sphere::new(DVec3::new(-0.6, 0.0, 0.0), 1.0).unwrap();
    let b = Sphere::new(DVec3::new(0.6, 0.0, 0.0), 1.0).unwrap();
    let union = Csg::new(CsgOp::Union, vec![Arc::new(a) as Arc<dyn Primitive>, Arc::new(b)]).unwrap();
    let cut = Csg::new(
        CsgOp::Difference,
        vec![
            Arc::new(Sphere::new(DVec3::ZERO, 1.0).unwrap()) as Arc<dyn Primitive>,
            Arc::new(Cuboid::new(DVec3::new(-2.0, -2.0, 0.5), DVec3::splat(2.0)).unwrap()),
        ],
    )
    .unwrap();
    let rim = 0.75f64.sqrt();
    let mut points = Points(21);
    let (mut exact, mut bounded) = (0, 0);
    for _ in 0..4000 {
        let p = points.next(2.5);
        // the union: each sphere's nearest point where it is outside the other, and the circle
        // where they meet (x = 0, radius 0.8)
        let mut candidates = vec![circle_distance(p, DVec3::ZERO, DVec3::X, 0.8)];
        for (c, other) in [(-0.6, 0.6), (0.6, -0.6)] {
            let centre = DVec3::new(c, 0.0, 0.0);
            let q = centre + (p - centre).normalize() * 1.0;
            if (q - DVec3::new(other, 0.0, 0.0)).length() >= 1.0 {
                candidates.push(((p - centre).length() - 1.0).abs());
            }
        }
        let union_reference = candidates.into_iter().fold(f64::INFINITY, f64::min);
        // the cut sphere: the sphere below z = 0.5, its rim, and the disk of radius √0.75
        let q = p.normalize();
        let mut candidates = vec![circle_distance(p, DVec3::new(0.0, 0.0, 0.5), DVec3::Z, rim)];
        if q.z <= 0.5 {
            candidates.push((p.length() - 1.0).abs());
        }
        let radial = (p.x * p.x + p.y * p.y).sqrt();
        if radial <= rim {
            candidates.push((p.z - 0.5).abs());
        }
        let cut_reference = candidates.into_iter().fold(f64::INFINITY, f64::min);
        for (shape, reference) in [(&union, union_reference), (&cut, cut_reference)] {
            let c = shape.closest(p).unwrap();
            let slack = assert_bounds_hold(p, &c, reference);
            if c.is_exact() {
                exact += 1;
                assert!(
                    (c.upper - reference).abs() <= slack,
                    "{p}: exact {} against {reference}",
                    c.upper
                );
            } else {
                bounded += 1;
            }
            let w = c.point.expect("a witness on the surface");
            assert!(shape.phi(w).abs() <= 1e-12, "{p}: witness {w} off the surface");
        }
    }
    assert!(exact > 5000 && bounded > 0, "{exact} exact, {bounded} bounded");
}
