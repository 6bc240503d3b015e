//! Deterministic property fuzzing of every primitive type with random and adversarial rays.
//!
//! Subjects: Sphere, Plane, Triangle, Disk, Polygon, Cuboid, Cylinder (capped/open), Cone
//! (pointed/frustum, capped/open), Ellipsoid, each also under a random affine map
//! ([`Transformed`]: non-uniform scales 10⁻³…10³, any rotation, translation up to 10⁵), and the
//! `Function` expressions (interval isolation), combinators [`Csg`] (union, intersection,
//! difference), [`SmoothUnion`] and [`Offset`] over
//! them.
//!
//! Rays: origins at random near the subject, **exactly on the surface** (`Parametric::point`),
//! far away (up to 10¹⁵⁰) or tiny (down to 10⁻³⁰⁰); directions random, **tangent** to the surface
//! at the origin, along an axis, with components `±0`, denormal (`5e-324`, `1e-310`), tiny
//! (`1e-200`) or huge (`1e150`), or the zero vector; query intervals `[0, ∞]`, `[t, t]`,
//! empty (`min > max`), `[−∞, ∞]` and random.
//!
//! Asserted for every ray: no panic; a hit's `t` is finite and inside the query interval;
//! `normal_at` is finite and of unit length, except exactly zero for the implicit-only
//! combinators ([`SmoothUnion`], [`Offset`]), whose normal is the central-difference ∇Φ
//! normalised and vanishes where that difference does (on a medial ridge, e.g. the inner
//! offset of a box along its centre plane); `uv_at` finite; every [`SurfaceHit::complete`]
//! field and the secondary origin finite.
//!
//! Deterministic (fixed seed, no persistence). `cargo test --test fuzz` runs `FUZZ_CASES` cases
//! of 12 rays each per property; `ZS_FUZZ_CASES=N` overrides the count.

use glam::{DAffine3, DQuat, DVec2, DVec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::sync::Arc;
use zeroset_primitives::*;

/// Cases per property in the test profile.
const FUZZ_CASES: u32 = 10_000;

/// A subject: the primitive, a surface point for a unit square parameter, whether its normal may
/// be exactly zero (implicit-only types), and a name.
#[derive(Clone)]
struct Subject {
    prim: Arc<dyn Primitive>,
    surface: Arc<dyn Fn(DVec2) -> DVec3 + Send + Sync>,
    implicit_only: bool,
    name: String,
}

impl std::fmt::Debug for Subject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {:?}", self.name, self.prim)
    }
}

fn from_domain(d: UvDomain, s: DVec2) -> DVec2 {
    let clamp = |(lo, hi): (f64, f64)| (lo.max(-10.0), hi.min(10.0));
    let (u, v) = (clamp(d.u), clamp(d.v));
    DVec2::new(u.0 + s.x * (u.1 - u.0), v.0 + s.y * (v.1 - v.0))
}

fn parametric<P: Parametric + Primitive + 'static>(name: &str, p: P) -> Subject {
    let p = Arc::new(p);
    let q = p.clone();
    Subject {
        prim: p,
        surface: Arc::new(move |s| q.point(from_domain(q.domain(), s))),
        implicit_only: false,
        name: name.to_string(),
    }
}

fn transformed<P: Parametric + Primitive + Clone + 'static>(name: &str, p: P, m: Option<DAffine3>) -> Option<Subject> {
    Some(match m {
        None => parametric(name, p),
        Some(m) => parametric(&format!("T({name})"), Transformed::new(p, m).ok()?),
    })
}

/// A base primitive from kind `kind` and twelve parameters in `[-1, 1]`, optionally transformed.
fn base(kind: u8, a: [f64; 12], m: Option<DAffine3>) -> Option<Subject> {
    let v = |i: usize| DVec3::new(a[i], a[i + 1], a[i + 2]);
    let pos = |x: f64| 0.05 + 2.0 * x.abs();
    match kind {
        0 => transformed("Sphere", Sphere::new(v(0), pos(a[3])).ok()?, m),
        1 => transformed("Plane", Plane::new(v(0), 3.0 * a[3]).ok()?, m),
        2 => transformed("Triangle", Triangle::new(v(0), v(3), v(6)).ok()?, m),
        3 => transformed("Disk", Disk::new(v(0), v(3), pos(a[6])).ok()?, m),
        4 => {
            let (c, e1, e2) = (v(0), v(3), v(6));
            let pts = (0..5)
                .map(|k| {
                    let ang = f64::from(k) * std::f64::consts::TAU / 5.0;
                    let r = pos(a[9 + (k as usize % 3)]);
                    c + r * (ang.cos() * e1 + ang.sin() * e2)
                })
                .collect();
            transformed("Polygon", Polygon::new(pts, vec![]).ok()?, m)
        }
        5 => {
            let lo = v(0);
            transformed(
                "Cuboid",
                Cuboid::new(lo, lo + DVec3::new(pos(a[3]), pos(a[4]), pos(a[5]))).ok()?,
                m,
            )
        }
        6 | 7 => transformed(
            "Cylinder",
            Cylinder::new(v(0), v(3), pos(a[6]), pos(a[7]), kind == 6).ok()?,
            m,
        ),
        8..=11 => {
            let top = if kind < 10 { 0.0 } else { pos(a[7]) };
            transformed(
                "Cone",
                Cone::new(v(0), v(3), pos(a[6]), top, pos(a[8]), kind % 2 == 0).ok()?,
                m,
            )
        }
        _ => {
            let q = DQuat::from_axis_angle(v(3).try_normalize()?, 3.0 * a[6]);
            // radii ratios up to 10⁴
            let r = DVec3::new(10f64.powf(2.0 * a[7]), 10f64.powf(2.0 * a[8]), 10f64.powf(2.0 * a[9]));
            transformed("Ellipsoid", Ellipsoid::new(v(0), r, q).ok()?, m)
        }
    }
}

const BASE_KINDS: u8 = 13;

fn closed_kind(kind: u8) -> u8 {
    // kinds whose solids are closed (for CSG): sphere, box, capped cylinder/cones, ellipsoid
    [0, 5, 6, 8, 10, 12][usize::from(kind) % 6]
}

/// Per-axis log10 scales / 3, rotation axis, angle, translation.
type AffineSpec = ([f64; 3], [f64; 3], f64, [f64; 3]);

fn affine(t: AffineSpec) -> DAffine3 {
    let (scale, axis, angle, translation) = t;
    let s = DVec3::new(
        10f64.powf(3.0 * scale[0]),
        10f64.powf(3.0 * scale[1]),
        10f64.powf(3.0 * scale[2]),
    );
    let axis = DVec3::from(axis).try_normalize().unwrap_or(DVec3::Y);
    DAffine3::from_scale_rotation_translation(s, DQuat::from_axis_angle(axis, angle), DVec3::from(translation))
}

/// What the subject is made of.
#[derive(Clone, Debug)]
struct Recipe {
    /// 0: base; 1–3: union/intersection/difference; 4: smooth union; 5: offset; 6: a `Function`
    /// expression (a wavy spherical shell, interval isolation), transformed like the bases.
    combinator: u8,
    kinds: (u8, u8),
    params: ([f64; 12], [f64; 12]),
    transform: Option<AffineSpec>,
    amount: f64,
}

impl Recipe {
    fn build(&self) -> Option<Subject> {
        let m = self.transform.map(affine);
        if self.combinator == 0 {
            return base(self.kinds.0 % BASE_KINDS, self.params.0, m);
        }
        let a = base(closed_kind(self.kinds.0), self.params.0, m)?;
        if self.combinator == 6 {
            let p = self.params.1;
            let (c, r) = (DVec3::new(p[0], p[1], p[2]), 0.05 + 2.0 * p[3].abs());
            let w = r * 10f64.powf(-1.0 - 3.0 * p[4].abs());
            let text = format!(
                "abs(sqrt((x - {})^2 + (y - {})^2 + (z - {})^2) - {r}) - {w} + {} * sin({} * x) * cos({} * y)",
                c.x,
                c.y,
                c.z,
                0.1 * w * p[5],
                3.0 / r,
                2.0 / r
            );
            let bounds = Aabb::new(c - DVec3::splat(1.2 * r + w), c + DVec3::splat(1.2 * r + w));
            let f = Function::from_expr(Expr::parse(&text).expect("valid"), bounds, RootOptions::default()).ok()?;
            let prim: Arc<dyn Primitive> = match m {
                None => Arc::new(f),
                Some(m) => Arc::new(Transformed::new(f, m).ok()?),
            };
            return Some(Subject {
                prim,
                surface: a.surface.clone(),
                implicit_only: true,
                name: format!("Function({text})"),
            });
        }
        let b = base(closed_kind(self.kinds.1), self.params.1, m)?;
        let scale = a.prim.bounds().diagonal_length();
        let (prim, name): (Arc<dyn Primitive>, &str) = match self.combinator {
            1..=3 => {
                let op = [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference][usize::from(self.combinator - 1)];
                (
                    Arc::new(Csg::new(op, vec![a.prim.clone(), b.prim.clone()]).ok()?),
                    "Csg",
                )
            }
            4 => (
                Arc::new(SmoothUnion::new(a.prim.clone(), b.prim.clone(), scale * (0.01 + self.amount.abs())).ok()?),
                "SmoothUnion",
            ),
            _ => (
                Arc::new(Offset::new(a.prim.clone(), 0.2 * scale * self.amount).ok()?),
                "Offset",
            ),
        };
        Some(Subject {
            prim,
            surface: a.surface.clone(),
            implicit_only: self.combinator >= 4,
            name: format!("{name}({}, {})", a.name, b.name),
        })
    }
}

fn unit_params() -> impl Strategy<Value = [f64; 12]> {
    prop::array::uniform12(-1.0..1.0f64)
}

fn recipe() -> impl Strategy<Value = Recipe> {
    let transform = prop::option::weighted(
        0.5,
        (
            prop::array::uniform3(-1.0..1.0f64),
            prop::array::uniform3(-1.0..1.0f64),
            -4.0..4.0f64,
            prop::array::uniform3(-1e5..1e5f64),
        ),
    );
    (
        prop_oneof![4 => Just(0u8), 1 => 1u8..7],
        (0u8..BASE_KINDS, 0u8..BASE_KINDS),
        (unit_params(), unit_params()),
        transform,
        -1.0..1.0f64,
    )
        .prop_map(|(combinator, kinds, params, transform, amount)| Recipe {
            combinator,
            kinds,
            params,
            transform,
            amount,
        })
}

/// A value for one direction or origin component: ordinary, or an adversarial special.
fn component() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -1.0..1.0f64,
        1 => Just(0.0),
        1 => Just(-0.0),
        1 => Just(5e-324),
        1 => Just(-1e-310),
        1 => Just(1e-200),
        1 => Just(-1e150),
        1 => Just(1.0),
    ]
}

/// How a ray is made relative to the subject.
#[derive(Clone, Debug)]
struct RaySpec {
    /// 0: near the bounds; 1, 2: exactly on the surface; 3: far (up to 1e150); 4: tiny.
    origin: u8,
    uv: (f64, f64),
    near: [f64; 3],
    magnitude: f64,
    /// 0: random; 1: tangent at the surface point; 2: special components; 3: an axis; 4: zero.
    direction: u8,
    dir: [f64; 3],
    special: [f64; 3],
    dir_scale: f64,
    /// 0: [0, ∞]; 1: [t, t]; 2: empty; 3: [−∞, ∞]; 4: [a, b].
    range: u8,
    bounds: (f64, f64),
}

fn ray_spec() -> impl Strategy<Value = RaySpec> {
    (
        (
            prop_oneof![3 => Just(0u8), 4 => Just(1u8), 2 => Just(2u8), 1 => Just(3u8), 1 => Just(4u8)],
            (0.0..1.0f64, 0.0..1.0f64),
            prop::array::uniform3(-2.0..2.0f64),
            -300.0..150.0f64,
        ),
        (
            prop_oneof![4 => Just(0u8), 4 => Just(1u8), 3 => Just(2u8), 1 => Just(3u8), 1 => Just(4u8)],
            prop::array::uniform3(-1.0..1.0f64),
            prop::array::uniform3(component()),
            prop_oneof![4 => Just(0.0), 1 => -300.0..150.0f64],
        ),
        (0u8..5, (-10.0..10.0f64, -10.0..10.0f64)),
    )
        .prop_map(
            |((origin, uv, near, magnitude), (direction, dir, special, dir_scale), (range, bounds))| RaySpec {
                origin,
                uv,
                near,
                magnitude,
                direction,
                dir,
                special,
                dir_scale,
                range,
                bounds,
            },
        )
}

fn make_ray(subject: &Subject, spec: &RaySpec) -> (Ray, Interval) {
    let bounds = subject.prim.bounds();
    let (center, size) = if bounds.is_finite() {
        (bounds.center(), bounds.diagonal_length().max(1e-300))
    } else {
        (DVec3::ZERO, 4.0)
    };
    let on_surface = (subject.surface)(DVec2::new(spec.uv.0, spec.uv.1));
    let origin = match spec.origin {
        0 => center + size * DVec3::from(spec.near),
        1 | 2 => on_surface,
        3 => DVec3::from(spec.near) * 10f64.powf(spec.magnitude.abs().min(150.0)),
        _ => DVec3::from(spec.near) * 10f64.powf(-spec.magnitude.abs().min(300.0)),
    };
    let random = DVec3::from(spec.dir);
    let mut dir = match spec.direction {
        0 => random,
        1 => {
            let g = subject.prim.gradient(origin);
            let t = g.cross(random);
            if t.is_finite() && t != DVec3::ZERO {
                t
            } else {
                random
            }
        }
        2 => DVec3::from(spec.special),
        3 => [DVec3::X, DVec3::NEG_Y, DVec3::Z][(spec.uv.0 * 3.0) as usize % 3],
        _ => DVec3::ZERO,
    };
    if spec.dir_scale != 0.0 {
        dir *= 10f64.powf(spec.dir_scale);
    }
    let (a, b) = spec.bounds;
    let range = match spec.range {
        0 => Interval::POSITIVE,
        1 => Interval::new(a.abs() * size, a.abs() * size),
        2 => Interval::new(a.abs().max(b.abs()) * size + 1.0, a.abs().min(b.abs()) * size),
        3 => Interval::new(f64::NEG_INFINITY, f64::INFINITY),
        _ => Interval::new(a.min(b) * size, a.max(b) * size),
    };
    (Ray::new(origin, dir), range)
}

fn check(subject: &Subject, ray: &Ray, range: Interval) -> Result<(), TestCaseError> {
    let prim = &*subject.prim;
    let Some(raw) = prim.intersect(ray, range) else {
        return Ok(());
    };
    prop_assert!(raw.t.is_finite(), "{}: non-finite t {raw:?} for {ray:?}", subject.name);
    prop_assert!(
        range.contains(raw.t),
        "{}: t {} outside {range:?} for {ray:?}",
        subject.name,
        raw.t
    );
    let n = prim.normal_at(ray, &raw);
    prop_assert!(
        n.is_finite(),
        "{}: non-finite normal {n} for {ray:?} {raw:?}",
        subject.name
    );
    let unit = (n.length() - 1.0).abs() < 1e-9;
    prop_assert!(
        unit || (subject.implicit_only && n == DVec3::ZERO),
        "{}: normal {n} (length {}) for {ray:?} {raw:?}",
        subject.name,
        n.length()
    );
    if let Some(uv) = prim.uv_at(ray, &raw) {
        prop_assert!(
            uv.is_finite(),
            "{}: non-finite uv {uv} for {ray:?} {raw:?}",
            subject.name
        );
    }
    // the hit point itself may lie beyond f64 range for rays whose origin and t·dir are huge
    if ray.at(raw.t).is_finite() {
        let full = SurfaceHit::complete(prim, ray, &raw, HitRequest::ALL);
        prop_assert!(
            full.point.is_finite() && full.t.is_finite(),
            "{}: {full:?} for {ray:?}",
            subject.name
        );
        prop_assert!(
            full.normal.is_some_and(|n| n.is_finite()),
            "{}: {full:?} for {ray:?}",
            subject.name
        );
        prop_assert!(
            full.uv.is_none_or(|uv| uv.is_finite()),
            "{}: {full:?} for {ray:?}",
            subject.name
        );
        prop_assert!(
            full.error.is_finite() && full.error >= 0.0,
            "{}: {full:?} for {ray:?}",
            subject.name
        );
        let o = full.secondary_origin(ray.dir);
        prop_assert!(o.is_finite(), "{}: secondary origin {o} from {full:?}", subject.name);
    }
    Ok(())
}

fn cases() -> u32 {
    std::env::var("ZS_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(FUZZ_CASES)
}

fn runner() -> TestRunner {
    let config = Config {
        cases: cases(),
        failure_persistence: None,
        max_shrink_iters: 2000,
        ..Config::default()
    };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[42; 32]))
}

#[test]
fn every_primitive_survives_adversarial_rays() {
    let built = std::cell::RefCell::new([0usize; 8]);
    let result = runner().run(&(recipe(), prop::collection::vec(ray_spec(), 12)), |(recipe, rays)| {
        let Some(subject) = recipe.build() else {
            built.borrow_mut()[7] += 1;
            return Ok(());
        };
        built.borrow_mut()[usize::from(recipe.combinator)] += 1;
        for spec in &rays {
            let (ray, range) = make_ray(&subject, spec);
            check(&subject, &ray, range)?;
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    let built = built.into_inner();
    println!(
        "[fuzz] {} cases × 12 rays; built: base {}, union {}, intersection {}, difference {}, smooth union {}, offset {}, \
         function {}; rejected by a constructor {}",
        cases(),
        built[0],
        built[1],
        built[2],
        built[3],
        built[4],
        built[5],
        built[6],
        built[7]
    );
}
