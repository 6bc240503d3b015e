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

/// A box with `holes` spherical holes along its front face, as a flat `Difference` and as the
/// left-deep chain `Difference(Difference(…(box − h₁)…) − hₙ)` a generated file would write.
fn holed_box(holes: usize) -> (Arc<dyn Primitive>, Vec<Arc<dyn Primitive>>) {
    let block: Arc<dyn Primitive> =
        Arc::new(Cuboid::new(DVec3::new(-2.0, -1.0, -0.5), DVec3::new(2.0, 1.0, 0.5)).unwrap());
    let side = (holes as f64).sqrt().ceil() as usize;
    let holes = (0..holes)
        .map(|i| {
            let (col, row) = ((i % side) as f64, (i / side) as f64);
            let c = DVec3::new(
                -1.6 + 3.2 * (col + 0.5) / side as f64,
                -0.8 + 1.6 * (row + 0.5) / side as f64,
                -0.5,
            );
            Arc::new(Sphere::new(c, 0.8 / side as f64).unwrap()) as Arc<dyn Primitive>
        })
        .collect();
    (block, holes)
}

fn flat_difference(block: &Arc<dyn Primitive>, holes: &[Arc<dyn Primitive>]) -> Csg {
    let children = std::iter::once(block.clone()).chain(holes.iter().cloned()).collect();
    Csg::new(CsgOp::Difference, children).unwrap()
}

fn chained_difference(block: &Arc<dyn Primitive>, holes: &[Arc<dyn Primitive>]) -> Arc<dyn Primitive> {
    holes.iter().fold(block.clone(), |acc, hole| {
        Arc::new(Csg::new(CsgOp::Difference, vec![acc, hole.clone()]).unwrap())
    })
}

/// Rays from in front of the box, aimed at random points of its front half.
fn rays_at_the_box(rng: &mut StdRng, count: usize) -> Vec<Ray> {
    (0..count)
        .map(|_| {
            let origin = DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), -4.0);
            let target = DVec3::new(
                rng.random_range(-2.2..2.2),
                rng.random_range(-1.2..1.2),
                rng.random_range(-0.6..0.6),
            );
            Ray::new(origin, (target - origin).normalize())
        })
        .collect()
}

/// Both forms give the same `t` bit for bit, the same normal and the same hit error.
fn assert_same_hits(a: &dyn Primitive, b: &dyn Primitive, rays: &[Ray]) -> usize {
    let mut hits = 0;
    for ray in rays {
        let (ha, hb) = (
            a.intersect(ray, Interval::POSITIVE),
            b.intersect(ray, Interval::POSITIVE),
        );
        assert_eq!(ha.map(|h| h.t), hb.map(|h| h.t), "ray {ray:?}");
        if let (Some(ha), Some(hb)) = (ha, hb) {
            hits += 1;
            assert_eq!(a.normal_at(ray, &ha), b.normal_at(ray, &hb), "ray {ray:?}");
            assert_eq!(a.hit_error(ray, &ha), b.hit_error(ray, &hb), "ray {ray:?}");
        }
    }
    hits
}

#[test]
fn deep_difference_chain_equals_the_flat_difference() {
    let (block, holes) = holed_box(300);
    let flat = flat_difference(&block, &holes);
    let chain = chained_difference(&block, &holes);
    let mut rng = StdRng::seed_from_u64(14);
    let rays = rays_at_the_box(&mut rng, 400);
    let hits = assert_same_hits(&flat, &*chain, &rays);
    assert!(hits > 200, "only {hits} of 400 rays hit");
    // some rays must go through a hole and hit its far wall (a subtracted child's negated normal)
    let through_holes = rays
        .iter()
        .filter_map(|r| Some((r, flat.intersect(r, Interval::POSITIVE)?)))
        .filter(|(_, h)| h.feature > 0)
        .count();
    assert!(through_holes > 10, "{through_holes} rays end on a hole's wall");
}

#[test]
fn nested_single_child_unions_are_the_child() {
    let ball: Arc<dyn Primitive> = Arc::new(Sphere::new(DVec3::new(0.1, -0.2, 0.3), 0.9).unwrap());
    let nested = (0..300).fold(ball.clone(), |acc, _| {
        Arc::new(Csg::new(CsgOp::Union, vec![acc]).unwrap()) as Arc<dyn Primitive>
    });
    let mut rng = StdRng::seed_from_u64(15);
    let rays: Vec<Ray> = (0..300)
        .map(|_| {
            let origin = 3.0 * random_point(&mut rng, 1.0).normalize();
            Ray::new(origin, (random_point(&mut rng, 0.8) - origin).normalize())
        })
        .collect();
    let hits = assert_same_hits(&*ball, &*nested, &rays);
    assert!(hits > 150, "only {hits} of 300 rays hit");
}

/// Counts `intersect` calls on the wrapped primitive.
#[derive(Debug)]
struct Counted {
    inner: Arc<dyn Primitive>,
    calls: Arc<std::sync::atomic::AtomicUsize>,
}

impl Implicit for Counted {
    fn phi(&self, p: DVec3) -> f64 {
        self.inner.phi(p)
    }
    fn bounds(&self) -> Aabb {
        self.inner.bounds()
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        self.inner.gradient(p)
    }
}

impl Intersect for Counted {
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        self.calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.inner.intersect(ray, range)
    }
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        self.inner.normal_at(ray, raw)
    }
}

/// The regression of the exponential re-evaluation: a 16-deep chain asked its leaves ~2¹⁶ times
/// per ray. Each leaf is now asked about as often as in the flat form.
#[test]
fn nested_chain_queries_each_leaf_as_often_as_the_flat_form() {
    let calls = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let (block, holes) = holed_box(16);
    let count = |p: Arc<dyn Primitive>| -> Arc<dyn Primitive> {
        Arc::new(Counted {
            inner: p,
            calls: calls.clone(),
        })
    };
    let block = count(block);
    let holes: Vec<_> = holes.into_iter().map(count).collect();
    let flat = flat_difference(&block, &holes);
    let chain = chained_difference(&block, &holes);
    let mut rng = StdRng::seed_from_u64(16);
    for ray in rays_at_the_box(&mut rng, 500) {
        calls.store(0, std::sync::atomic::Ordering::Relaxed);
        let a = flat.intersect(&ray, Interval::POSITIVE);
        let flat_calls = calls.swap(0, std::sync::atomic::Ordering::Relaxed);
        let b = chain.intersect(&ray, Interval::POSITIVE);
        let chain_calls = calls.load(std::sync::atomic::Ordering::Relaxed);
        assert_eq!(a.map(|h| h.t), b.map(|h| h.t));
        assert!(
            chain_calls <= 2 * flat_calls + 2,
            "chain {chain_calls} leaf queries against flat {flat_calls} for {ray:?}"
        );
    }
}

/// A random Boolean tree over random closed children, with its own membership predicate.
enum Tree {
    Leaf(Arc<dyn Primitive>),
    Node(CsgOp, Vec<Tree>),
}

impl Tree {
    fn random(rng: &mut StdRng, depth: usize) -> Self {
        if depth == 0 || rng.random_range(0..4) == 0 {
            return Tree::Leaf(random_child(rng));
        }
        let op = OPS[rng.random_range(0..3)];
        Tree::Node(
            op,
            (0..rng.random_range(1..4))
                .map(|_| Tree::random(rng, depth - 1))
                .collect(),
        )
    }

    fn build(&self) -> Arc<dyn Primitive> {
        match self {
            Tree::Leaf(p) => p.clone(),
            Tree::Node(op, children) => Arc::new(Csg::new(*op, children.iter().map(Tree::build).collect()).unwrap()),
        }
    }

    fn member(&self, p: DVec3) -> bool {
        match self {
            Tree::Leaf(c) => c.phi(p) < 0.0,
            Tree::Node(CsgOp::Union, c) => c.iter().any(|t| t.member(p)),
            Tree::Node(CsgOp::Intersection, c) => c.iter().all(|t| t.member(p)),
            Tree::Node(CsgOp::Difference, c) => c[0].member(p) && !c[1..].iter().any(|t| t.member(p)),
        }
    }
}

#[test]
fn nested_trees_hit_the_first_membership_change() {
    let mut rng = StdRng::seed_from_u64(17);
    let (mut rays, mut hits, mut grazing) = (0, 0, 0);
    for _ in 0..150 {
        let tree = Tree::random(&mut rng, 5);
        let csg = tree.build();
        for _ in 0..20 {
            let origin = 4.0 * random_point(&mut rng, 1.0).normalize();
            let ray = Ray::new(origin, (random_point(&mut rng, 1.0) - origin).normalize());
            let start = tree.member(ray.origin);
            // the reference: march membership in steps of 1e-3, bisect the first change
            let mut reference = None;
            let mut t = 0.0;
            while t < 8.0 {
                let next = t + 1e-3;
                if tree.member(ray.at(next)) != start {
                    let (mut a, mut b) = (t, next);
                    while b - a > 1e-12 {
                        let m = 0.5 * (a + b);
                        if tree.member(ray.at(m)) != start {
                            b = m;
                        } else {
                            a = m;
                        }
                    }
                    reference = Some(0.5 * (a + b));
                    break;
                }
                t = next;
            }
            rays += 1;
            match (csg.intersect(&ray, Interval::new(0.0, 8.0)), reference) {
                (Some(hit), Some(r)) => {
                    hits += 1;
                    assert!((hit.t - r).abs() < 1e-9, "t {} vs reference {r}", hit.t);
                    let n = csg.normal_at(&ray, &hit);
                    assert!((n.length() - 1.0).abs() < 1e-9);
                    assert_eq!(n.dot(ray.dir) < 0.0, !start, "normal {n} faces the wrong way");
                }
                (None, None) => {}
                _ => grazing += 1,
            }
        }
    }
    assert!(hits > rays / 5, "only {hits} of {rays} rays hit");
    assert!(grazing * 300 <= rays, "{grazing} of {rays} rays disagree");
}
