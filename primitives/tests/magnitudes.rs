//! Huge and tiny magnitudes: every built-in closed-form primitive scaled by a power of two `2ᵏ`
//! (all its lengths), seen by rays scaled the same way, gives the same hits with `t` scaled by
//! `2ᵏ` and the same normals (scaling by a power of two is exact, so the reference is the
//! primitive at scale 1). A direction scaled by `2ʲ` gives `t` scaled by `2⁻ʲ`.
//!
//! Where a primitive cannot compute at a scale, its constructor must refuse the value with the
//! field named instead of building something that misses every ray.

use glam::{DQuat, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use zeroset_primitives::*;

/// A built-in by name, or the constructor's refusal.
type Built = (&'static str, Result<Box<dyn Primitive>, PrimitiveError>);

/// The built-ins at scale `s` (every length multiplied by `s`).
fn primitives_at(s: f64) -> Vec<Built> {
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * s;
    fn boxed<P: Primitive + 'static>(r: Result<P, PrimitiveError>) -> Result<Box<dyn Primitive>, PrimitiveError> {
        r.map(|p| Box::new(p) as Box<dyn Primitive>)
    }
    vec![
        ("Sphere", boxed(Sphere::new(v(0.1, 0.2, 0.3), 0.9 * s))),
        ("Box", boxed(Cuboid::new(v(-0.7, -0.5, -0.6), v(0.8, 0.6, 0.5)))),
        (
            "Cylinder",
            boxed(Cylinder::new(
                v(0.1, -0.6, 0.0),
                DVec3::new(0.2, 1.0, 0.1),
                0.6 * s,
                1.2 * s,
                true,
            )),
        ),
        (
            "Cone",
            boxed(Cone::new(
                v(0.0, -0.6, 0.1),
                DVec3::new(0.1, 1.0, -0.2),
                0.7 * s,
                0.2 * s,
                1.1 * s,
                true,
            )),
        ),
        (
            "Ellipsoid",
            boxed(Ellipsoid::new(
                v(0.1, 0.0, -0.1),
                v(0.9, 0.5, 0.7),
                DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.6),
            )),
        ),
        (
            "Disk",
            boxed(Disk::new(v(0.0, 0.1, 0.0), DVec3::new(0.2, 0.3, -1.0), 0.8 * s)),
        ),
        ("Plane", boxed(Plane::new(DVec3::new(0.1, 1.0, 0.2), 0.3 * s))),
        (
            "Polygon",
            boxed(Polygon::new(
                vec![
                    v(-0.8, -0.7, 0.1),
                    v(0.9, -0.6, 0.1),
                    v(0.7, 0.8, 0.1),
                    v(-0.6, 0.7, 0.1),
                ],
                vec![],
            )),
        ),
    ]
}

/// Rays from about 3 units away aimed at points within 1 unit of the origin (scale 1).
fn rays(rng: &mut StdRng, count: usize) -> Vec<Ray> {
    let mut point = |r: f64| {
        DVec3::new(
            rng.random_range(-r..r),
            rng.random_range(-r..r),
            rng.random_range(-r..r),
        )
    };
    (0..count)
        .map(|_| {
            let origin = 3.0 * point(1.0).normalize();
            Ray::new(origin, (point(1.0) - origin).normalize())
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// Hits at scale 1 against hits at `2ᵏ` with rays scaled by `2ᵏ` and directions by `2ʲ`.
fn check_scale(k: i32, j: i32) -> Vec<String> {
    let (s, dir_scale) = (2f64.powi(k), 2f64.powi(j));
    let mut failures = Vec::new();
    let mut rng = StdRng::seed_from_u64(21);
    let rays = rays(&mut rng, 300);
    for ((name, unit), (_, scaled)) in primitives_at(1.0).into_iter().zip(primitives_at(s)) {
        let unit = unit.unwrap();
        let scaled = match scaled {
            Ok(p) => p,
            Err(e) => {
                // refused: the message must name the primitive and a field
                assert!(!e.field.is_empty(), "{name} at 2^{k}: refused without a field: {e}");
                continue;
            }
        };
        let mut hits = 0;
        for ray in &rays {
            let big = Ray::new(ray.origin * s, ray.dir * dir_scale);
            let (a, b) = (
                unit.intersect(ray, Interval::POSITIVE),
                scaled.intersect(&big, Interval::POSITIVE),
            );
            let ok = match (a, b) {
                (None, None) => true,
                (Some(a), Some(b)) => {
                    hits += 1;
                    let t = a.t * s / dir_scale;
                    let (na, nb) = (unit.normal_at(ray, &a), scaled.normal_at(&big, &b));
                    close(b.t, t) && (na - nb).length() < 1e-9
                }
                _ => false,
            };
            if !ok {
                failures.push(format!("{name} at 2^{k}, direction 2^{j}: {a:?} vs {b:?} on {ray:?}"));
                break;
            }
        }
        if name != "Plane" && hits == 0 {
            failures.push(format!("{name}: no ray hits at scale 1"));
        }
    }
    failures
}

#[test]
fn huge_and_tiny_primitives_hit_where_the_unit_ones_do_or_are_refused() {
    let mut failures = Vec::new();
    // 2^520 ≈ 3.4e156 (a sphere of radius ≥ 1e155 used to miss every ray), 2^-520 ≈ 3e-157;
    // 2^498 ≈ 8e149, 2^-490 ≈ 3e-148 and 2^249 ≈ 9e74 lie just inside the quadrics' and the polygon's limits
    for k in [-1000, -800, -520, -490, -300, 249, 300, 498, 520, 800, 1000] {
        failures.extend(check_scale(k, 0));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Which primitives refuse a scale: only beyond their documented limits, never the sphere, the
/// box or the plane.
#[test]
fn refusals_are_the_documented_limits() {
    for k in [-490, 249, 498] {
        for (name, p) in primitives_at(2f64.powi(k)) {
            let accepted = p.is_ok();
            let expected = !(name == "Polygon" && k.abs() > 249);
            assert_eq!(accepted, expected, "{name} at 2^{k}: {:?}", p.err());
        }
    }
    for k in [-520, 520, 1000] {
        for (name, p) in primitives_at(2f64.powi(k)) {
            let refused = p.as_ref().err().map(|e| e.to_string());
            match name {
                "Sphere" | "Box" | "Plane" => assert!(refused.is_none(), "{name} at 2^{k}: {refused:?}"),
                _ => {
                    let message = refused.unwrap_or_else(|| panic!("{name} at 2^{k} accepted"));
                    assert!(message.contains("field `"), "{message}");
                }
            }
        }
    }
}

#[test]
fn tiny_and_huge_directions_scale_t() {
    let mut failures = Vec::new();
    // |d| = 2^-100 ≈ 7.9e-31 and 2^520 ≈ 3.4e156 used to miss every ray
    for j in [-1000, -520, -100, 100, 520, 1000] {
        failures.extend(check_scale(0, j));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Closed forms: a sphere of radius `R` centred at the origin, seen from `(0, 0, −2R)` along +z,
/// is hit at `t = R` with normal −z; from `(0, R/2, −2R)` at `t = 2R − (√3/2)·R`.
#[test]
fn huge_spheres_have_their_closed_form_hits() {
    for radius in [1e155, 1e200, 1e300, 1e-160, 1e-300] {
        let sphere = Sphere::new(DVec3::ZERO, radius).unwrap();
        let ray = Ray::new(DVec3::new(0.0, 0.0, -2.0 * radius), DVec3::Z);
        let hit = sphere.intersect(&ray, Interval::POSITIVE).expect("head-on ray hits");
        assert!(close(hit.t, radius), "R = {radius:e}: t = {:e}", hit.t);
        assert!((sphere.normal_at(&ray, &hit) + DVec3::Z).length() < 1e-15);
        assert!(sphere.phi(ray.at(hit.t)).abs() <= 1e-15 * radius);
        assert!((sphere.gradient(ray.at(hit.t)) + DVec3::Z).length() < 1e-15);
        let off_axis = Ray::new(DVec3::new(0.0, 0.5 * radius, -2.0 * radius), DVec3::Z);
        let t = sphere.intersect(&off_axis, Interval::POSITIVE).unwrap().t;
        let expected = (2.0 - 0.75f64.sqrt()) * radius;
        assert!(
            (t - expected).abs() <= 1e-14 * expected,
            "R = {radius:e}: {t:e} vs {expected:e}"
        );
    }
}
