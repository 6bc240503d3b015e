//! The generic implicit intersector against a closed form, on the torus `R = 1`, `r = 0.35`
//! (POV-Ray's isosurface reference case): `examples/custom-primitives`' Φ-only `Torus` marched by
//! `first_root` with a declared Lipschitz bound, against its `QuarticTorus` (Ferrari + Newton).
//! Also a wrong bound (0.25 < 1), counting holes and the violations `RootReport` reports, and
//! the same Φ written as a `Function` expression, whose first root is isolated by interval
//! arithmetic without any Lipschitz bound (the "interval" rows; `violations` counts the rays it
//! flags uncertain there).

use crate::cases::{f32_exact, Rng, T_MAX};
use crate::dd::{Dd, V3};
use crate::measure::{measure, Measured, Ref};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use zeroset_custom_primitives::{solve_quartic, QuarticTorus, Torus};
use zeroset_primitives::expr::Scalar;
use zeroset_primitives::root::uncertain_while;
use zeroset_primitives::{
    first_root, Aabb, Expr, FieldSurface, Function, Implicit, Intersect, Interval, Ray, RootOptions, ScalarField,
};

const MAJOR: f64 = 1.0;
const MINOR: f64 = 0.35;

/// The Φ-only torus with a declared Lipschitz bound.
#[derive(Debug)]
struct Declared {
    torus: FieldSurface<Torus>,
    lipschitz: f64,
}

impl Implicit for Declared {
    fn phi(&self, p: DVec3) -> f64 {
        self.torus.phi(p)
    }
    fn bounds(&self) -> Aabb {
        self.torus.bounds()
    }
    fn lipschitz(&self) -> Option<f64> {
        Some(self.lipschitz)
    }
}

/// The example crate's generic torus with a root-finder tolerance of its own.
#[derive(Debug)]
struct ScalarTolerance {
    torus: Torus,
    tolerance: f64,
}

impl ScalarField for ScalarTolerance {
    fn phi<T: Scalar>(&self, p: [T; 3]) -> T {
        self.torus.phi(p)
    }
    fn bounds(&self) -> Aabb {
        self.torus.bounds()
    }
    fn root_options(&self) -> RootOptions {
        RootOptions::with_tolerance(self.tolerance)
    }
}

/// One method on the torus.
#[derive(Clone, Debug)]
pub struct TorusRow {
    pub method: String,
    pub tolerance: Option<f64>,
    pub declared_lipschitz: Option<f64>,
    pub m: Measured,
    /// Largest |t − t_ref| over rays both hit.
    pub max_abs_t: f64,
    /// Reference hits, penetrating the tube deeper than the tolerance, that the method missed.
    pub holes: usize,
    /// Rays on which the finder reported its declared bound violated.
    pub violations: usize,
}

/// The torus study's result.
#[derive(Clone, Debug)]
pub struct TorusResult {
    pub rays: usize,
    pub rows: Vec<TorusRow>,
}

impl TorusResult {
    /// The closed form's row.
    pub fn closed(&self) -> &TorusRow {
        &self.rows[0]
    }
    /// The loosest tolerance of the correct-bound generic path with max |t err| ≤ 10⁻⁶.
    pub fn generic_at_1e6(&self) -> Option<&TorusRow> {
        self.rows
            .iter()
            .filter(|r| r.declared_lipschitz == Some(1.0) && r.max_abs_t <= 1e-6)
            .min_by(|a, b| a.m.ns_median.total_cmp(&b.m.ns_median))
    }
}

/// The quartic `(|p|² + R² − r²)² − 4R²(x² + z²)` along the ray and its derivative, in
/// double-double.
fn quartic_dd(o: DVec3, d: DVec3, t: Dd) -> (Dd, Dd) {
    let p = V3::new(o).add(V3::new(d).scale(t));
    let dv = V3::new(d);
    let k = p.dot(p) + Dd::new(MAJOR * MAJOR) - Dd::new(MINOR) * Dd::new(MINOR);
    let four_r2 = Dd::new(4.0 * MAJOR * MAJOR);
    let f = k * k - four_r2 * (p.0 * p.0 + p.2 * p.2);
    let df = Dd::new(4.0) * k * p.dot(dv) - Dd::new(2.0) * four_r2 * (p.0 * dv.0 + p.2 * dv.2);
    (f, df)
}

/// All real roots along the ray: Ferrari in f64 on the unshifted ray, then Newton in
/// double-double on the quartic; ascending.
fn roots(ray: &Ray) -> Vec<Dd> {
    let (o, d) = (ray.origin, ray.dir);
    let a = d.length_squared();
    let k = o.length_squared() + MAJOR * MAJOR - MINOR * MINOR;
    let b = 2.0 * o.dot(d);
    let four_r2 = 4.0 * MAJOR * MAJOR;
    let c = [
        k * k - four_r2 * (o.x * o.x + o.z * o.z),
        2.0 * b * k - 2.0 * four_r2 * (o.x * d.x + o.z * d.z),
        b * b + 2.0 * a * k - four_r2 * (d.x * d.x + d.z * d.z),
        2.0 * a * b,
        a * a,
    ];
    let mut out: Vec<Dd> = solve_quartic(c[3] / c[4], c[2] / c[4], c[1] / c[4], c[0] / c[4])
        .into_iter()
        .filter(|t| t.is_finite())
        .map(|t| {
            let mut t = Dd::new(t);
            for _ in 0..6 {
                let (f, df) = quartic_dd(o, d, t);
                if df.hi == 0.0 {
                    break;
                }
                let step = f / df;
                if !step.hi.is_finite() || step.hi.abs() > 1e-2 {
                    break;
                }
                t = t - step;
            }
            t
        })
        .collect();
    out.sort_by(|a, b| a.f64().total_cmp(&b.f64()));
    out
}

/// Reference hit and how deep the ray goes into the tube between its first two crossings.
fn reference(ray: &Ray) -> (Ref, f64) {
    let r = roots(ray);
    let Some(i) = r.iter().position(|t| !t.is_negative() && t.f64() <= T_MAX) else {
        return (Ref::MISS, 0.0);
    };
    let t = r[i];
    let p = ray.at(t.f64());
    let ring = DVec2::new(p.x, p.z);
    let centre = ring * (MAJOR / ring.length());
    let normal = (p - DVec3::new(centre.x, 0.0, centre.y)).normalize_or_zero();
    let depth = r.get(i + 1).map_or(0.0, |t1| {
        let mid = ray.at(0.5 * (t.f64() + t1.f64()));
        -FieldSurface::new(Torus {
            major: MAJOR,
            minor: MINOR,
        })
        .phi(mid)
    });
    (
        Ref {
            t: Some(t),
            normal,
            margin: depth / MINOR,
        },
        depth,
    )
}

/// Runs the study on `n` random rays through the torus' bounds.
pub fn run(n: usize, passes: usize, seed: u64) -> TorusResult {
    let mut rng = Rng::new(seed ^ 0x7075);
    let e = MAJOR + MINOR;
    let rays: Vec<Ray> = (0..n)
        .map(|_| {
            let o = f32_exact(3.0 * e * rng.unit());
            let target = DVec3::new(rng.range(-e, e), rng.range(-MINOR, MINOR) * 1.2, rng.range(-e, e));
            Ray::new(o, f32_exact((target - o).normalize()))
        })
        .collect();
    let refs: Vec<(Ref, f64)> = rays.par_iter().map(reference).collect();
    let depth: Vec<f64> = refs.iter().map(|r| r.1).collect();
    let refs: Vec<Ref> = refs.into_iter().map(|r| r.0).collect();
    let range = Interval::new(0.0, T_MAX);
    let mut rows = Vec::new();

    let abs_errors = |answers: &[Option<f64>], tolerance: f64| -> (f64, usize) {
        let (mut max_abs, mut holes) = (0.0f64, 0);
        for ((a, r), dep) in answers.iter().zip(&refs).zip(&depth) {
            match (a, r.t) {
                (Some(t), Some(t_ref)) => max_abs = max_abs.max((Dd::new(*t) - t_ref).abs().f64()),
                (None, Some(_)) if *dep > tolerance => holes += 1,
                _ => {}
            }
        }
        (max_abs, holes)
    };

    let quartic = QuarticTorus {
        major: MAJOR,
        minor: MINOR,
    };
    let m = measure(&rays, &refs, passes, false, |r: &Ray| {
        quartic.intersect(r, range).map(|h| (h.t, quartic.normal_at(r, &h)))
    });
    let answers: Vec<Option<f64>> = rays.iter().map(|r| quartic.intersect(r, range).map(|h| h.t)).collect();
    let (max_abs_t, holes) = abs_errors(&answers, 1e-9);
    rows.push(TorusRow {
        method: "QuarticTorus closed form (Ferrari + Newton)".into(),
        tolerance: None,
        declared_lipschitz: None,
        m,
        max_abs_t,
        holes,
        violations: 0,
    });

    let mut generic = |lipschitz: f64, tolerance: f64, label: &str| {
        let surface = Declared {
            torus: FieldSurface::new(Torus {
                major: MAJOR,
                minor: MINOR,
            }),
            lipschitz,
        };
        let options = RootOptions::with_tolerance(tolerance);
        let m = measure(&rays, &refs, passes, false, |r: &Ray| {
            first_root(&surface, r, range, &options)
                .hit
                .map(|h| (h.t, surface.torus.normal_at(r, &h)))
        });
        let reports: Vec<_> = rays.iter().map(|r| first_root(&surface, r, range, &options)).collect();
        let answers: Vec<Option<f64>> = reports.iter().map(|x| x.hit.map(|h| h.t)).collect();
        let violations = reports.iter().filter(|x| x.lipschitz_violated).count();
        let (max_abs_t, holes) = abs_errors(&answers, tolerance);
        rows.push(TorusRow {
            method: format!("{label} tol {tolerance:.0e}"),
            tolerance: Some(tolerance),
            declared_lipschitz: Some(lipschitz),
            m,
            max_abs_t,
            holes,
            violations,
        });
    };
    for tolerance in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7] {
        generic(1.0, tolerance, "generic Torus, L = 1 (true)");
    }
    generic(0.25, 1e-6, "generic Torus, L = 0.25 (wrong)");

    // interval isolation of the same Φ as an expression: no Lipschitz bound
    // interval isolation without a Lipschitz bound: the answers, holes and uncertain flags are
    // those of the `intersect` that is timed
    let mut interval = |label: &str, surface: &dyn Intersect, tolerance: f64| {
        let m = measure(&rays, &refs, passes, false, |r: &Ray| {
            surface.intersect(r, range).map(|h| (h.t, surface.normal_at(r, &h)))
        });
        let traced: Vec<_> = rays
            .iter()
            .map(|r| uncertain_while(|| surface.intersect(r, range)))
            .collect();
        let answers: Vec<Option<f64>> = traced.iter().map(|(hit, _)| hit.map(|h| h.t)).collect();
        let uncertain = traced.iter().filter(|(_, flagged)| *flagged).count();
        let (max_abs_t, holes) = abs_errors(&answers, tolerance);
        rows.push(TorusRow {
            method: format!("{label}, no bound, tol {tolerance:.0e}"),
            tolerance: Some(tolerance),
            declared_lipschitz: None,
            m,
            max_abs_t,
            holes,
            violations: uncertain,
        });
    };
    // Φ written once (generic over the number type): exact normals
    let torus = Torus {
        major: MAJOR,
        minor: MINOR,
    };
    for tolerance in [1e-3, 1e-5, 1e-7] {
        let field = FieldSurface::new(ScalarTolerance { torus, tolerance });
        interval("generic ScalarField Torus", &field, tolerance);
    }
    // the same Φ as a `Function` expression (compiled tape, pruned octree)
    let torus_box = FieldSurface::new(torus).bounds();
    for tolerance in [1e-3, 1e-5, 1e-7] {
        let expr = Expr::parse(&format!("sqrt((sqrt(x^2 + z^2) - {MAJOR})^2 + y^2) - {MINOR}"))
            .expect("the torus expression parses");
        let options = RootOptions::with_tolerance(tolerance);
        let surface = Function::from_expr(expr, torus_box, options).expect("a valid function");
        interval("interval Function expression", &surface, tolerance);
    }
    TorusResult { rays: n, rows }
}
