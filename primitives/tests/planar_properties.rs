//! The generic property checks (`zeroset_primitives::testing`) on the planar primitives:
//! triangles, disks and polygons (star-shaped concave, with and without a hole).

use glam::{DVec2, DVec3};
use rand::rngs::StdRng;
use rand::Rng;
use std::f64::consts::TAU;
use zeroset_primitives::math::orthonormal_basis;
use zeroset_primitives::testing::{check_primitive, CheckReport, Expectations};
use zeroset_primitives::*;

fn random_point(rng: &mut StdRng, half: f64) -> DVec3 {
    DVec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

fn random_direction(rng: &mut StdRng) -> DVec3 {
    loop {
        let v = random_point(rng, 1.0);
        if v.length_squared() > 1e-2 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

fn assert_report(name: &str, report: &CheckReport) {
    println!("{name}: {report:?}");
    assert!(report.rays >= 24 * 2 * 400, "{name}: {report:?}");
    assert!(report.max_t_error < 1e-9, "{name}: {report:?}");
}

#[test]
fn triangle_properties() {
    let report = check_primitive(
        "Triangle",
        |rng| loop {
            let (a, b, c) = (random_point(rng, 5.0), random_point(rng, 5.0), random_point(rng, 5.0));
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            // keep triangles whose area is not tiny against their longest edge
            if (b - a).cross(c - a).length() > 0.2 * longest * longest {
                break Triangle::new(a, b, c).unwrap();
            }
        },
        Expectations::default(),
    );
    assert_report("Triangle", &report);
}

#[test]
fn disk_properties() {
    let report = check_primitive(
        "Disk",
        |rng| {
            Disk::new(
                random_point(rng, 5.0),
                random_direction(rng),
                rng.random_range(0.1..4.0),
            )
            .unwrap()
        },
        Expectations::default(),
    );
    assert_report("Disk", &report);
}

/// A star-shaped polygon around a random centre in a random plane: 5–12 vertices at sorted
/// random angles (gaps under 2π/3) and radii in `[0.4, 1]·R`, so the ring is simple and the
/// centre sees every edge at a distance of at least `0.4·R·cos(π/3) = 0.2·R`. With `hole`, a
/// triangle or square of circumradius `0.15·R` around the centre, in a random orientation.
fn random_star(rng: &mut StdRng, hole: bool) -> Polygon {
    let n = rng.random_range(5..13);
    let radius = rng.random_range(0.5..4.0);
    let angles: Vec<f64> = loop {
        let mut a: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..TAU)).collect();
        a.sort_by(f64::total_cmp);
        let widest = (0..n)
            .map(|i| {
                if i + 1 < n {
                    a[i + 1] - a[i]
                } else {
                    a[0] + TAU - a[n - 1]
                }
            })
            .fold(0.0, f64::max);
        if widest < TAU / 3.0 {
            break a;
        }
    };
    let center = random_point(rng, 5.0);
    let (e1, e2) = orthonormal_basis(random_direction(rng));
    let lift = |q: DVec2| center + q.x * e1 + q.y * e2;
    let outer = angles
        .iter()
        .map(|&a| lift(radius * rng.random_range(0.4..1.0) * DVec2::from_angle(a)))
        .collect();
    let holes = if hole {
        let k = rng.random_range(3..5);
        let turn = rng.random_range(0.0..TAU);
        let mut ring: Vec<DVec3> = (0..k)
            .map(|i| lift(0.15 * radius * DVec2::from_angle(turn + i as f64 * TAU / k as f64)))
            .collect();
        if rng.random() {
            ring.reverse();
        }
        vec![ring]
    } else {
        vec![]
    };
    Polygon::new(outer, holes).unwrap()
}

#[test]
fn star_polygon_properties() {
    let report = check_primitive("Polygon", |rng| random_star(rng, false), Expectations::default());
    assert_report("Polygon", &report);
}

#[test]
fn star_polygon_with_hole_properties() {
    let report = check_primitive(
        "Polygon with hole",
        |rng| random_star(rng, true),
        Expectations::default(),
    );
    assert_report("Polygon with hole", &report);
}

#[test]
fn convex_polygon_properties() {
    // regular-ish convex polygons exercise the same-sign intersection path
    let report = check_primitive(
        "Convex polygon",
        |rng| {
            let n = rng.random_range(3..10);
            let (e1, e2) = orthonormal_basis(random_direction(rng));
            let (center, radius) = (random_point(rng, 5.0), rng.random_range(0.5..4.0));
            let points = (0..n).map(|i| {
                center + radius * (e1 * (i as f64 * TAU / n as f64).cos() + e2 * (i as f64 * TAU / n as f64).sin())
            });
            let poly = Polygon::new(points.collect(), vec![]).unwrap();
            assert!(poly.is_convex());
            poly
        },
        Expectations::default(),
    );
    assert_report("Convex polygon", &report);
}

#[test]
fn aimed_rays_return_the_aimed_uv() {
    // property (e) of STYLE.md item 8 for the uv each planar primitive caches in RawHit::local
    let mut rng = <StdRng as rand::SeedableRng>::seed_from_u64(99);
    let tri = Triangle::new(
        DVec3::new(0.3, -1.0, 2.0),
        DVec3::new(2.0, 0.5, 1.0),
        DVec3::new(-1.0, 1.5, 0.0),
    )
    .unwrap();
    let disk = Disk::new(DVec3::new(1.0, 2.0, 3.0), DVec3::new(-1.0, 0.5, 0.25), 1.5).unwrap();
    let star = random_star(&mut rng, true);
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        let prims: [(&dyn Primitive, &dyn Parametric); 3] = [(&tri, &tri), (&disk, &disk), (&star, &star)];
        for (prim, param) in prims {
            let d = param.domain();
            let uv = DVec2::new(rng.random_range(d.u.0..=d.u.1), rng.random_range(d.v.0..=d.v.1));
            let target = param.point(uv);
            if !prim.within_boundary(target) {
                continue;
            }
            // not grazing, so that t is well conditioned
            let w = loop {
                let w = random_direction(&mut rng);
                if w.dot(prim.gradient(target)).abs() > 0.2 {
                    break w;
                }
            };
            let origin = target + 3.0 * w;
            let ray = Ray::new(origin, target - origin);
            let hit = prim
                .intersect(&ray, Interval::POSITIVE)
                .expect("a ray aimed at an interior point hits");
            assert!((hit.t - 1.0).abs() < 1e-12, "t = {}", hit.t);
            let got = prim.uv_at(&ray, &hit).unwrap();
            worst = worst.max((got - uv).length());
            checked += 1;
        }
    }
    assert!(checked > 3000, "{checked}");
    assert!(worst < 1e-12, "largest uv error {worst:e}");
}
