//! The implicit combinators agree with the set operations they stand for: on random points
//! (sign of Φ = Boolean of the children's signs) and on random rays (the CSG hit is the first
//! parameter where membership of the combined set changes, found independently by marching the
//! membership predicate and bisecting it).

use glam::DVec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use zeroset_primitives::*;

fn random_point(rng: &mut StdRng, half: f64) -> DVec3 {
    DVec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

/// Random closed children: spheres, boxes, capped cylinders and ellipsoids near the origin.
fn random_child(rng: &mut StdRng) -> Arc<dyn Primitive> {
    let c = random_point(rng, 1.0);
    match rng.random_range(0..4) {
        0 => Arc::new(Sphere::new(c, rng.random_range(0.3..1.2)).unwrap()),
        1 => {
            let h = DVec3::new(
                rng.random_range(0.2..1.0),
                rng.random_range(0.2..1.0),
                rng.random_range(0.2..1.0),
            );
            Arc::new(Cuboid::new(c - h, c + h).unwrap())
        }
        2 => Arc::new(
            Cylinder::new(
                c,
                random_point(rng, 1.0),
                rng.random_range(0.2..0.8),
                rng.random_range(0.5..2.0),
                true,
            )
            .unwrap(),
        ),
        _ => Arc::new(
            Ellipsoid::new(
                c,
                DVec3::new(
                    rng.random_range(0.3..1.0),
                    rng.random_range(0.3..1.0),
                    rng.random_range(0.3..1.0),
                ),
                glam::DQuat::IDENTITY,
            )
            .unwrap(),
        ),
    }
}

fn member(op: CsgOp, children: &[Arc<dyn Primitive>], p: DVec3) -> bool {
    let inside = |c: &Arc<dyn Primitive>| c.phi(p) < 0.0;
    match op {
        CsgOp::Union => children.iter().any(inside),
        CsgOp::Intersection => children.iter().all(inside),
        CsgOp::Difference => inside(&children[0]) && !children[1..].iter().any(inside),
    }
}

const OPS: [CsgOp; 3] = [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference];

#[test]
fn phi_sign_is_the_set_operation_on_random_points() {
    let mut rng = StdRng::seed_from_u64(11);
    for _ in 0..200 {
        let children: Vec<_> = (0..rng.random_range(2..4)).map(|_| random_child(&mut rng)).collect();
        for op in OPS {
            let csg = Csg::new(op, children.clone()).unwrap();
            for _ in 0..200 {
                let p = random_point(&mut rng, 2.5);
                let phi = csg.phi(p);
                if phi.abs() > 1e-12 {
                    assert_eq!(phi < 0.0, member(op, &children, p), "{op:?} at {p}");
                }
            }
        }
    }
}

/// First parameter in `[0, t_max]` where membership changes, by marching in steps of `h` and
/// bisecting the first change to 1e-12.
fn first_change(op: CsgOp, children: &[Arc<dyn Primitive>], ray: &Ray, t_max: f64, h: f64) -> Option<f64> {
    let start = member(op, children, ray.origin);
    let mut t = 0.0;
    while t < t_max {
        let next = (t + h).min(t_max);
        if member(op, children, ray.at(next)) != start {
            let (mut a, mut b) = (t, next);
            while b - a > 1e-12 {
                let m = 0.5 * (a + b);
                if member(op, children, ray.at(m)) != start {
                    b = m;
                } else {
                    a = m;
                }
            }
            return Some(0.5 * (a + b));
        }
        t = next;
    }
    None
}

#[test]
fn first_hit_is_the_first_membership_change_on_random_rays() {
    let mut rng = StdRng::seed_from_u64(12);
    let (mut rays, mut hits, mut grazing) = (0, 0, 0);
    for _ in 0..60 {
        let children: Vec<_> = (0..rng.random_range(2..4)).map(|_| random_child(&mut rng)).collect();
        for op in OPS {
            let csg = Csg::new(op, children.clone()).unwrap();
            for _ in 0..40 {
                let origin = 4.0 * random_point(&mut rng, 1.0).normalize();
                let ray = Ray::new(origin, (random_point(&mut rng, 1.0) - origin).normalize());
                let t_max = 8.0;
                let raw = csg.intersect(&ray, Interval::new(0.0, t_max));
                let closed = raw.map(|h| h.t);
                let reference = first_change(op, &children, &ray, t_max, 1e-3);
                rays += 1;
                match (closed, reference) {
                    (Some(a), Some(b)) => {
                        hits += 1;
                        assert!((a - b).abs() < 1e-9, "{op:?}: t {a} vs reference {b}");
                        // the normal is unit and points out of the set: against the ray where it
                        // enters the set, along it where it leaves
                        let n = csg.normal_at(&ray, &raw.unwrap());
                        assert!((n.length() - 1.0).abs() < 1e-9);
                        let entering = !member(op, &children, ray.origin);
                        assert!(
                            (n.dot(ray.dir) < 0.0) == entering,
                            "{op:?}: normal {n} faces the wrong way"
                        );
                    }
                    (None, None) => {}
                    // a crossing shorter than the reference's 1e-3 step is invisible to it
                    _ => grazing += 1,
                }
            }
        }
    }
    assert!(hits > rays / 4, "only {hits} of {rays} rays hit");
    assert!(grazing * 500 <= rays, "{grazing} of {rays} rays disagree");
}

#[test]
fn smooth_union_and_offset_follow_their_definitions() {
    let a: Arc<dyn Primitive> = Arc::new(Sphere::new(DVec3::new(-0.5, 0.0, 0.0), 0.6).unwrap());
    let b: Arc<dyn Primitive> = Arc::new(Sphere::new(DVec3::new(0.5, 0.0, 0.0), 0.6).unwrap());
    let k = 0.3;
    let blend = SmoothUnion::new(a.clone(), b.clone(), k).unwrap();
    let grown = Offset::new(a.clone(), 0.25).unwrap();
    let mut rng = StdRng::seed_from_u64(13);
    for _ in 0..10_000 {
        let p = random_point(&mut rng, 1.5);
        let (pa, pb) = (a.phi(p), b.phi(p));
        // the blend is below the union by at most k/4, and equal where the children differ by ≥ k
        let s = blend.phi(p);
        assert!(s <= pa.min(pb) + 1e-15 && s >= pa.min(pb) - k / 4.0 - 1e-15);
        if (pa - pb).abs() >= k {
            assert_eq!(s, pa.min(pb));
        }
        assert!((grown.phi(p) - (pa - 0.25)).abs() < 1e-15);
    }
    // rays along x through the blend's neck hit where Φ = 0, found by the root finder
    let ray = Ray::new(DVec3::new(0.0, 3.0, 0.0), -DVec3::Y);
    let hit = blend.intersect(&ray, Interval::POSITIVE).unwrap();
    assert!(blend.phi(ray.at(hit.t)).abs() < 1e-6);
    // at x = 0 both spheres are at distance √(0.25 + y²) − 0.6, equal, so Φ = d − k/4
    let expected_y = ((0.6 + k / 4.0).powi(2) - 0.25).sqrt();
    assert!(
        (ray.at(hit.t).y - expected_y).abs() < 1e-6,
        "{} vs {expected_y}",
        ray.at(hit.t).y
    );
    // the offset sphere is a sphere of radius 0.85
    let hit = grown
        .intersect(&Ray::new(DVec3::new(-0.5, 3.0, 0.0), -DVec3::Y), Interval::POSITIVE)
        .unwrap();
    assert!((hit.t - (3.0 - 0.85)).abs() < 1e-6, "{}", hit.t);
}
