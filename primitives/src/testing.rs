//! Generic property checks that every primitive must pass (feature `testing`).
//!
//! [`check_primitive`] draws seeded random instances of a primitive, plus the same instances under
//! random affine transforms, and checks, each against a value computed independently of the
//! primitive's closed-form intersector:
//!
//! 1. `Φ(point(u, v)) ≈ 0` on the parametric domain;
//! 2. `∇Φ` is parallel to `∂p/∂u × ∂p/∂v`, same direction, and matches central differences of Φ;
//! 3. nudging: `Φ(p − εn) < 0 < Φ(p + εn)` at surface points;
//! 4. `point(uv(p)) ≈ p`;
//! 5. a ray aimed at `point(u, v)` from the outside (Φ > 0) side hits there, with the surface's
//!    normal; for convex primitives it is always the first hit;
//! 6. a ray leaving the bounds misses;
//! 7. a hit is not returned when the query interval ends just before it, nor when it starts just
//!    after it;
//! 8. the closed-form intersector agrees with the generic root finder
//!    ([`crate::root::first_root`]) on random rays through the bounds: same hit/miss and the same
//!    `t` within the root finder's tolerance, except for a small stated fraction of grazing rays.
//!
//! Users can run it on their own primitive types with `features = ["testing"]`.

use crate::bounds::Aabb;
use crate::ray::{Interval, Ray};
use crate::root::{first_root, RootOptions};
use crate::traits::{Parametric, Primitive};
use crate::transformed::Transformed;
use glam::{DAffine3, DQuat, DVec2, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// What to expect of a primitive in [`check_primitive`].
#[derive(Clone, Copy, Debug)]
pub struct Expectations {
    /// Instances to draw (each is also checked under a random transform).
    pub instances: usize,
    /// Random rays per instance for the root-finder comparison (check 8).
    pub rays_per_instance: usize,
    /// Whether the surface is convex (then a ray aimed at a surface point from its outward side
    /// always hits that point first).
    pub convex: bool,
    /// Relative tolerance, as a fraction of the bounds' diagonal, on positions and on `t`.
    pub tolerance: f64,
    /// Largest fraction of rays on which the closed form and the root finder may disagree
    /// (grazing rays, crossings shorter than the root finder's resolution).
    pub max_disagreement: f64,
    /// Largest angle, in degrees, between the normal at a hit and the gradient direction.
    pub max_normal_error_deg: f64,
}

impl Default for Expectations {
    fn default() -> Self {
        Self {
            instances: 24,
            rays_per_instance: 400,
            convex: true,
            tolerance: 1e-9,
            max_disagreement: 0.002,
            max_normal_error_deg: 1e-5,
        }
    }
}

/// Measured figures from [`check_primitive`], for reports.
#[derive(Clone, Copy, Debug, Default)]
pub struct CheckReport {
    /// Rays compared against the root finder.
    pub rays: usize,
    /// Rays where closed form and root finder disagreed (hit vs miss, or a different root).
    pub disagreements: usize,
    /// Largest `|t_closed − t_root| / diagonal` over rays where both agreed.
    pub max_t_error: f64,
    /// Largest normal angle error (degrees) of aimed rays.
    pub max_normal_error_deg: f64,
}

fn sample_domain(rng: &mut StdRng, (lo, hi): (f64, f64), window: f64) -> f64 {
    let (lo, hi) = (lo.max(-window), hi.min(window));
    lo + (hi - lo) * rng.random::<f64>()
}

/// A uniformly distributed random unit vector (rejection sampling in the unit ball).
pub fn random_unit(rng: &mut StdRng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 1e-3 && l <= 1.0 {
            return v / l;
        }
    }
}

/// A random affine map: rotation, anisotropic scale in `[0.3, 3]` and a translation of up to 10.
pub fn random_transform(rng: &mut StdRng) -> DAffine3 {
    let axis = random_unit(rng);
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    let scale = DVec3::new(
        rng.random_range(0.3..3.0),
        rng.random_range(0.3..3.0),
        rng.random_range(0.3..3.0),
    );
    let translation = 10.0 * random_unit(rng) * rng.random::<f64>();
    DAffine3::from_scale_rotation_translation(scale, DQuat::from_axis_angle(axis, angle), translation)
}

fn angle_deg(a: DVec3, b: DVec3) -> f64 {
    a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Bounds used to place rays: the primitive's bounds, or a box of half-size 10 around the origin
/// for unbounded primitives.
fn finite_bounds(b: Aabb) -> Aabb {
    if b.is_finite() {
        b
    } else {
        Aabb::new(b.min.max(DVec3::splat(-10.0)), b.max.min(DVec3::splat(10.0)))
    }
}

/// Runs checks 1–8 (module docs) on `instances` values of `make` and on each under a random
/// transform. Panics with a message naming the check, instance and values on the first failure.
pub fn check_primitive<P, F>(name: &str, make: F, expect: Expectations) -> CheckReport
where
    P: Primitive + Parametric + Clone,
    F: Fn(&mut StdRng) -> P,
{
    let mut rng = StdRng::seed_from_u64(0x5eed_2e20_5e70);
    let mut report = CheckReport::default();
    for instance in 0..expect.instances {
        let prim = make(&mut rng);
        check_instance(&format!("{name} #{instance}"), &prim, &expect, &mut rng, &mut report);
        let moved = Transformed::new(prim, random_transform(&mut rng)).expect("random transforms are invertible");
        check_instance(
            &format!("{name} #{instance} transformed"),
            &moved,
            &expect,
            &mut rng,
            &mut report,
        );
    }
    let fraction = report.disagreements as f64 / report.rays.max(1) as f64;
    assert!(
        fraction <= expect.max_disagreement,
        "{name}: closed form and root finder disagree on {} of {} rays ({fraction:.4} > {})",
        report.disagreements,
        report.rays,
        expect.max_disagreement
    );
    report
}

fn check_instance<P: Primitive + Parametric>(
    label: &str,
    prim: &P,
    expect: &Expectations,
    rng: &mut StdRng,
    report: &mut CheckReport,
) {
    let bounds = finite_bounds(prim.bounds());
    let scale = bounds.diagonal_length();
    let tol = expect.tolerance * scale;
    let domain = prim.domain();
    let window = 10.0;

    let mut surface_points = 0;
    for _ in 0..200 {
        let uv = DVec2::new(
            sample_domain(rng, domain.u, window),
            sample_domain(rng, domain.v, window),
        );
        let p = prim.point(uv);
        if !prim.within_boundary(p) {
            continue;
        }
        surface_points += 1;
        // 1. on the zero set
        let phi = prim.phi(p);
        assert!(phi.abs() <= tol, "{label}: Φ(point({uv})) = {phi:e}, tolerance {tol:e}");
        // 2. gradient ∥ ∂u × ∂v, and analytic gradient = central differences
        let g = prim.gradient(p);
        let (du, dv) = prim.partials(uv);
        let cross = du.cross(dv);
        if cross.length() > 1e-6 * du.length() * dv.length() && g.length() > 0.0 {
            let a = angle_deg(g, cross);
            assert!(a < 1e-3, "{label}: ∇Φ and ∂u×∂v differ by {a}° at uv {uv}");
        }
        let h = 1e-6 * scale;
        let numeric = crate::math::central_difference(|q| prim.phi(q), p, h);
        // central differences are a reference only where Φ is smooth on the scale of the step;
        // within a step of a conical point (a cone's apex) halving the step changes the estimate
        let halved = crate::math::central_difference(|q| prim.phi(q), p, 0.5 * h);
        if numeric.length() > 1e-3 * g.length() && angle_deg(numeric, halved) < 1e-3 {
            let a = angle_deg(g, numeric);
            assert!(
                a < 1e-2,
                "{label}: analytic ∇Φ differs from central differences by {a}° at {p}"
            );
        }
        // 3. nudge in and out
        let n = g.normalize();
        let eps = 1e-6 * scale;
        assert!(
            prim.phi(p - eps * n) < 0.0 && prim.phi(p + eps * n) > 0.0,
            "{label}: Φ does not change sign across {p}"
        );
        // 4. uv round trip
        let back = prim.point(prim.uv(p));
        assert!(
            (back - p).length() <= 1e-8 * scale,
            "{label}: point(uv(p)) = {back}, p = {p}"
        );
        // 5. aimed ray from the outward side
        let w = loop {
            let w = random_unit(rng);
            if w.dot(n) > 0.3 {
                break w;
            }
        };
        let distance = 2.0 * scale;
        let ray = Ray::new(p + distance * w, -w);
        match prim.intersect(&ray, Interval::POSITIVE) {
            Some(hit) => {
                let at_target = (hit.t - distance).abs() <= 1e-7 * scale;
                if at_target {
                    let normal = prim.normal_at(&ray, &hit);
                    let a = angle_deg(normal, n);
                    report.max_normal_error_deg = report.max_normal_error_deg.max(a);
                    assert!(a <= expect.max_normal_error_deg, "{label}: normal off by {a}° at {p}");
                    assert!((normal.length() - 1.0).abs() < 1e-12, "{label}: normal not unit at {p}");
                } else {
                    assert!(
                        !expect.convex,
                        "{label}: aimed ray hit at t = {} instead of {distance}",
                        hit.t
                    );
                    assert!(hit.t < distance, "{label}: aimed ray passed through its target {p}");
                }
            }
            None => panic!("{label}: ray aimed at surface point {p} missed"),
        }
        // 7. interval ends just before / starts just after the hit
        if let Some(hit) = prim.intersect(&ray, Interval::POSITIVE) {
            let before = Interval::new(0.0, hit.t - 1e-6 * scale);
            assert!(
                prim.intersect(&ray, before).is_none(),
                "{label}: hit at {} returned for t_max {}",
                hit.t,
                before.max
            );
            if let Some(later) = prim.intersect(&ray, Interval::new(hit.t + 1e-6 * scale, f64::INFINITY)) {
                assert!(later.t > hit.t, "{label}: t_min not respected");
            }
        }
    }
    assert!(
        surface_points >= 20,
        "{label}: only {surface_points} of 200 parameter samples lie on the surface"
    );

    // 6. rays leaving the bounds miss
    let centre = bounds.center();
    for _ in 0..50 {
        let w = random_unit(rng);
        let ray = Ray::new(centre + 1.01 * scale * w, w);
        assert!(
            prim.intersect(&ray, Interval::POSITIVE).is_none() || !prim.bounds().is_finite(),
            "{label}: ray leaving the bounds hit"
        );
    }

    // 8. closed form against the generic root finder
    let options = RootOptions {
        tolerance: 1e-10 * scale,
        samples: 4096,
        max_evaluations: 1_000_000,
    };
    for _ in 0..expect.rays_per_instance {
        let origin = centre + 1.5 * scale * random_unit(rng);
        let target = bounds.min + bounds.extent() * DVec3::new(rng.random(), rng.random(), rng.random());
        let ray = Ray::new(origin, (target - origin).normalize());
        let range = Interval::new(0.0, 4.0 * scale);
        let closed = prim.intersect(&ray, range).map(|h| h.t);
        let generic = first_root(prim, &ray, range, &options).hit.map(|h| h.t);
        report.rays += 1;
        match (closed, generic) {
            (Some(a), Some(b)) if (a - b).abs() <= 1e-7 * scale => {
                report.max_t_error = report.max_t_error.max((a - b).abs() / scale);
            }
            (None, None) => {}
            _ => report.disagreements += 1,
        }
    }
}

/// A unit icosphere (vertices on the unit sphere), subdivided `level` times, counter-clockwise
/// seen from outside: `20·4^level` triangles, edges about `1.1 / 2^level` long. Closed and
/// convex (it is the hull of its vertices), so answers about it are easy to work out.
#[must_use]
pub fn icosphere(level: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    v.push(((v[i as usize] + v[j as usize]) * 0.5).normalize());
                    (v.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v.iter().map(|p| p.as_vec3().to_array()).collect(), f)
}
