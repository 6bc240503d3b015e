//! A user function Φ inside an explicit box: an [`Expr`] (guaranteed roots) or a Rust closure.
//!
//! - **Expression** ([`Function::from_expr`]): Φ and its analytic gradient (forward mode) come
//!   from the expression, and so do interval enclosures of Φ and of `dΦ/dt` along a ray, so the
//!   generic intersector isolates the **first root with a guarantee** ([`crate::isolation`]):
//!   a hit within [`RootOptions::tolerance`] (in units of `t`) of the first root, or a ray
//!   counted as uncertain. No Lipschitz bound is needed, thin shells are not stepped over, and
//!   tangent rays and double roots do not stall the search. [`RootOptions::max_evaluations`] is
//!   the per-ray budget.
//! - **Closure** ([`Function::new`]): only point values; the sampling / sphere-tracing finder of
//!   [`crate::root`] (with an optional Lipschitz bound) and central-difference normals.
//!
//! Where an expression is undefined at a point (`√` of a negative, `ln` of a number ≤ 0, `0 ÷ 0`:
//! a NaN), Φ there is `+∞` (outside); a value that overflows to `±∞` keeps its sign.
//! [`Function::from_expr`] looks for such points at construction: interval evaluation over the
//! whole box decides whether any can exist ([`Function::may_be_undefined`]), and if so a 17³ grid
//! of point evaluations over the box turns a found one into an error naming the operation's
//! column and the point.

mod along;
mod packet;

use crate::bounds::Aabb;
use crate::error::PrimitiveError;
use crate::expr::cells::{CellTree, Leaf};
use crate::expr::lanes::Lanes;
use crate::expr::tape::Tape;
use crate::expr::{coordinates_along, jets_along, Expr, Jet};
use crate::hit::RawHit;
use crate::isolation::{count_outcome, isolate_in, monotone_root, Isolated};
use crate::math::enclosure::Enclosure;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::root::{RootOptions, RootReport};
use crate::traits::{Implicit, Intersect};
use along::LeafAlong;
use glam::DVec3;
use std::fmt;
use std::sync::Arc;

#[derive(Clone)]
enum Phi {
    Expression(Arc<Compiled>),
    Closure(Arc<dyn Fn(DVec3) -> f64 + Send + Sync>),
}

/// An expression with its tape and the octree of its box ([`crate::expr::cells`]), built when
/// the first ray needs it (a scene's functions that no ray reaches, and point queries, cost
/// nothing).
struct Compiled {
    expr: Expr,
    tape: Tape,
    bounds: Aabb,
    cells: std::sync::OnceLock<CellTree>,
}

/// Scratch space of the tape evaluations, one per thread.
#[derive(Default)]
struct Scratch {
    points: Vec<f64>,
    enclosures: Vec<Enclosure>,
    jets: Vec<Jet<Enclosure>>,
    curvatures: Vec<Jet<Jet<Enclosure>>>,
    hessians: Vec<crate::expr::hessian::SecondOrder>,
    gradients: Vec<Jet<f64, [f64; 3]>>,
    slopes: Vec<Jet<f64>>,
    lanes: Vec<Lanes>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Runs `f` with this thread's scratch space (a fresh one if it is already in use).
fn with_scratch<R>(f: impl FnOnce(&mut Scratch) -> R) -> R {
    SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut scratch) => f(&mut scratch),
        Err(_) => f(&mut Scratch::default()),
    })
}

/// Φ as [`Function::phi`] reports it: `+∞` (outside) where the expression is NaN; an
/// overflow to `±∞` keeps its sign (a huge value on that side of the surface, so a crossing
/// from `+∞` to `−∞` is a sign change like any other).
fn defined_or_outside(v: f64) -> f64 {
    if v.is_nan() {
        f64::INFINITY
    } else {
        v
    }
}

/// Whether `dΦ/dt = ∇Φ·d` along direction `d` is certainly non-zero (of one strict sign) where
/// the partial derivatives lie in `gradient` (a leaf's enclosures over its grown cell).
///
/// The bounds of `Σ gₐ·dₐ` (each enclosure times an exact scalar) are summed in plain f64: three
/// products and two sums each round by at most half an ulp of `s = Σ max(|lo·dₐ|, |hi·dₐ|)`, so
/// a bound farther than `8·ε·s` from 0 keeps its sign exactly (NaN and ∞ certify nothing).
#[inline]
fn monotone_along(gradient: &[Enclosure; 3], dir: DVec3) -> bool {
    Enclosure::weighted_sum_sign(gradient.iter().copied().zip(dir.to_array()), 8.0).is_some()
}

/// One ray's search through the octree's leaves.
#[derive(Clone, Copy)]
struct RayState {
    /// Point values and enclosures spent so far (the per-ray budget).
    evaluations: u32,
    outcome: Isolated,
    /// The last point value `(t, g(t))` (see [`LeafAlong::last`]).
    last: (f64, f64),
}

impl Default for RayState {
    fn default() -> Self {
        Self {
            evaluations: 0,
            outcome: Isolated::default(),
            last: (f64::NAN, 0.0),
        }
    }
}

impl RayState {
    /// The ray's report, its outcome counted process-wide ([`count_outcome`]).
    fn report(&self) -> RootReport {
        let outcome = self.outcome;
        let uncertain = count_outcome(outcome.hit, outcome.exhausted, outcome.undefined_seen);
        RootReport {
            // 1: found in a leaf of the octree (0: without it), for the normal
            hit: outcome.hit.map(|(t, _)| RawHit::on_feature(t, 1)),
            lipschitz_violated: false,
            evaluations: self.evaluations,
            uncertain,
        }
    }
}

impl Compiled {
    /// The octree, its root made on first use; its other cells are made by the walks that reach
    /// them ([`CellTree::walk`]).
    fn cells(&self) -> &CellTree {
        self.cells
            .get_or_init(|| CellTree::new(&self.tape, self.bounds.min, self.bounds.max))
    }

    /// Whether the octree serves `ray` on `segment`: its margin covers the ray's rounding
    /// ([`CellTree::margin_covers`]); otherwise the caller isolates with the full tape.
    fn walks(&self, ray: &Ray, segment: Interval) -> bool {
        let far = segment.min.abs().max(segment.max.abs());
        self.cells().margin_covers(ray.origin, ray.dir, far)
    }

    /// Isolates the first root of `ray` in one leaf's piece `[ta, tb]` (the walk's visitor):
    /// by the end values where the leaf's gradient proves the ray `monotone` across it
    /// ([`monotone_along`], the caller's test), else by interval isolation with the leaf's
    /// pruned tape. Returns whether the ray's search ends here (a root, or the budget spent).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn visit_leaf(
        &self,
        ray: &Ray,
        bounds: &Aabb,
        options: &RootOptions,
        scratch: &mut Scratch,
        state: &mut RayState,
        leaf: &Leaf,
        (ta, tb): (f64, f64),
        monotone: bool,
    ) -> bool {
        let (lo, hi) = leaf.grown();
        let mut along = LeafAlong {
            ray,
            leaf,
            full: &self.tape,
            cell_lo: lo,
            cell_hi: hi,
            bounds,
            scratch,
            last: &mut state.last,
        };
        if monotone {
            // g is strictly monotone over the whole leaf: its end values decide
            let t = monotone_root(&mut along, ta, tb, options.tolerance, &mut state.evaluations);
            state.outcome.hit = t.map(|t| (t, false));
            return state.outcome.hit.is_some();
        }
        let piece = isolate_in(
            &mut along,
            Interval::new(ta, tb),
            options.tolerance,
            options.max_evaluations,
            &mut state.evaluations,
        );
        state.outcome.undefined_seen |= piece.undefined_seen;
        state.outcome.exhausted = piece.exhausted;
        state.outcome.hit = piece.hit;
        piece.hit.is_some() || piece.exhausted
    }

    /// The first root along `ray` in `segment` (clipped to the grown bounds), walking the
    /// octree's leaves front to back and isolating in each with its pruned tape; the per-ray
    /// budget is shared by the leaves. `None` when the octree's margin does not cover the ray's
    /// rounding (the caller then isolates with the full tape).
    fn first_root(&self, ray: &Ray, segment: Interval, bounds: &Aabb, options: &RootOptions) -> Option<RootReport> {
        if !self.walks(ray, segment) {
            return None;
        }
        let mut state = RayState::default();
        with_scratch(|scratch| {
            self.cells()
                .walk(ray.origin, ray.dir, segment.min, segment.max, &mut |leaf, ta, tb| {
                    let monotone = monotone_along(leaf.gradient(), ray.dir);
                    self.visit_leaf(ray, bounds, options, scratch, &mut state, leaf, (ta, tb), monotone)
                });
        });
        Some(state.report())
    }

    /// ∇Φ at `p`, from the tape of the octree's leaf holding `p` where the hit was found in the
    /// octree (`feature` 1) and that leaf's grown cell holds `p` (the same derivatives, see
    /// [`crate::expr::tape`]), else from the full tape.
    fn gradient(&self, p: DVec3, feature: u32) -> DVec3 {
        let tape = (feature == 1)
            .then(|| self.cells.get()?.tape_at(p))
            .flatten()
            .unwrap_or(&self.tape);
        DVec3::from_array(with_scratch(|s| tape.gradient(p.to_array(), &mut s.gradients)))
    }
}

/// The width, relative to the box's diagonal, to which [`Implicit::closest`] narrows its
/// distance bounds.
pub const DISTANCE_TOLERANCE: f64 = 1e-9;

/// The most boxes one [`Implicit::closest`] query examines.
pub const DISTANCE_BUDGET: usize = 20_000;

/// Φ given by an expression or a closure inside an explicit box (the surface outside the box is
/// ignored).
#[derive(Clone)]
pub struct Function {
    phi: Phi,
    bounds: Aabb,
    lipschitz: Option<f64>,
    options: RootOptions,
    may_be_undefined: bool,
}

impl fmt::Debug for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut d = f.debug_struct("Function");
        if let Phi::Expression(e) = &self.phi {
            d.field("phi", &e.expr.source());
        }
        d.field("bounds", &self.bounds)
            .field("lipschitz", &self.lipschitz)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

fn check_bounds(bounds: &Aabb) -> Result<(), PrimitiveError> {
    if !bounds.is_finite() || bounds.is_empty() {
        return Err(PrimitiveError::new(
            "Function",
            "bounds",
            "must be a finite, non-empty box",
        ));
    }
    Ok(())
}

/// Validates root-finder options for a function: a positive, finite tolerance and a budget ≥ 2.
fn check_options(options: &RootOptions) -> Result<(), PrimitiveError> {
    crate::error::require_positive("Function", "tolerance", options.tolerance)?;
    if options.max_evaluations < 2 {
        return Err(PrimitiveError::new(
            "Function",
            "budget",
            format!("must be at least 2, got {}", options.max_evaluations),
        ));
    }
    Ok(())
}

/// Points per axis of the load-time domain check.
const DOMAIN_GRID: u32 = 17;

impl Function {
    /// Φ = `phi` (a closure) inside `bounds` (finite, non-empty), with an optional Lipschitz bound.
    pub fn new(
        phi: impl Fn(DVec3) -> f64 + Send + Sync + 'static,
        bounds: Aabb,
        lipschitz: Option<f64>,
    ) -> Result<Self, PrimitiveError> {
        check_bounds(&bounds)?;
        if let Some(l) = lipschitz {
            crate::error::require_positive("Function", "lipschitz", l)?;
        }
        Ok(Self {
            phi: Phi::Closure(Arc::new(phi)),
            bounds,
            lipschitz,
            options: RootOptions::default(),
            may_be_undefined: false,
        })
    }

    /// Φ = `expr` inside `bounds`, its first root along a ray isolated by interval arithmetic to
    /// `options.tolerance` (units of `t`) within `options.max_evaluations` (see the module docs).
    ///
    /// # Errors
    /// Non-finite or empty bounds, a non-positive tolerance, a budget below 2, or a point of the
    /// box where the expression is undefined (field `phi`, naming the operation's column).
    pub fn from_expr(expr: Expr, bounds: Aabb, options: RootOptions) -> Result<Self, PrimitiveError> {
        check_bounds(&bounds)?;
        check_options(&options)?;
        let may_be_undefined = expr.enclose(bounds.min, bounds.max).undefined();
        if may_be_undefined {
            let n = DOMAIN_GRID - 1;
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=n {
                        let f = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) / f64::from(n);
                        let p = bounds.min + (bounds.max - bounds.min) * f;
                        if let Err(e) = expr.domain_error(p) {
                            return Err(PrimitiveError::new(
                                "Function",
                                "phi",
                                format!(
                                    "`{}` is undefined inside the bounds: {e} at ({}, {}, {})",
                                    crate::expr::excerpt(expr.source(), 1),
                                    p.x,
                                    p.y,
                                    p.z
                                ),
                            ));
                        }
                    }
                }
            }
        }
        let tape = expr.compile();
        Ok(Self {
            phi: Phi::Expression(Arc::new(Compiled {
                expr,
                tape,
                bounds,
                cells: std::sync::OnceLock::new(),
            })),
            bounds,
            lipschitz: None,
            options,
            may_be_undefined,
        })
    }

    /// The same function declaring a Lipschitz bound `lipschitz > 0` of Φ over the box. An
    /// expression function does not need it (its roots are isolated by interval arithmetic), but
    /// combinators that march their zero set with the generic finder (`SmoothUnion`, `Offset`)
    /// read it from their children.
    ///
    /// # Errors
    /// A bound that is not finite and positive.
    pub fn with_lipschitz(mut self, lipschitz: f64) -> Result<Self, PrimitiveError> {
        crate::error::require_positive("Function", "lipschitz", lipschitz)?;
        self.lipschitz = Some(lipschitz);
        Ok(self)
    }

    /// The part of `range` an expression's root search covers along `ray`: clipped to the box
    /// grown by the tolerance (as the generic finder clips, [`crate::root::first_root`]);
    /// `None` where nothing is left, the clip is not finite or the ray is not valid.
    fn clipped(&self, ray: &Ray, range: Interval) -> Option<Interval> {
        let margin = self.options.tolerance * ray.dir.length();
        let clipped = self.bounds.expanded(margin).clip(ray, range)?;
        (clipped.min.is_finite() && clipped.max.is_finite() && ray.is_valid()).then_some(clipped)
    }

    /// The expression, for an expression function.
    #[must_use]
    pub fn expr(&self) -> Option<&Expr> {
        match &self.phi {
            Phi::Expression(e) => Some(&e.expr),
            Phi::Closure(_) => None,
        }
    }

    /// Whether interval evaluation over the box could not exclude undefined points (none was
    /// found on the load-time grid; any met by a ray are counted, see
    /// [`crate::isolation::UncertainCounts::undefined`]).
    #[must_use]
    pub fn may_be_undefined(&self) -> bool {
        self.may_be_undefined
    }
}

impl Implicit for Function {
    /// Φ at `p`; `+∞` where an expression is undefined (NaN), `±∞` where it overflows.
    fn phi(&self, p: DVec3) -> f64 {
        match &self.phi {
            Phi::Expression(e) => defined_or_outside(with_scratch(|s| e.tape.eval_f64(p.to_array(), &mut s.points))),
            Phi::Closure(f) => f(p),
        }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The analytic gradient of an expression; central differences for a closure (the default
    /// rule of [`Implicit::gradient`]).
    fn gradient(&self, p: DVec3) -> DVec3 {
        match &self.phi {
            Phi::Expression(e) => DVec3::from_array(with_scratch(|s| e.tape.gradient(p.to_array(), &mut s.gradients))),
            Phi::Closure(f) => crate::math::central_difference(|q| f(q), p, 6e-6 * self.bounds.diagonal_length()),
        }
    }

    fn lipschitz(&self) -> Option<f64> {
        self.lipschitz
    }

    /// For an expression, guaranteed bounds on the distance to its zero set inside the box, by
    /// branch and bound over boxes with interval arithmetic ([`crate::expr::distance`]) from the
    /// octree the rays walk (its empty cells skipped, its leaves' pruned tapes used), to
    /// within [`DISTANCE_TOLERANCE`] × the box's diagonal (or wider where the search's budget of
    /// [`DISTANCE_BUDGET`] boxes runs out; the bounds stay valid). A closure's Φ cannot be
    /// bounded: `None`.
    fn closest(&self, p: DVec3) -> Option<Closest> {
        match &self.phi {
            Phi::Expression(e) => Some(crate::expr::distance::distance_bounds(
                e.cells(),
                p,
                DISTANCE_TOLERANCE * self.bounds.diagonal_length(),
                DISTANCE_BUDGET,
            )),
            Phi::Closure(_) => None,
        }
    }

    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        match &self.phi {
            // outside the box there is no surface: a piece that misses it is root-free
            Phi::Expression(e) => Some(
                match coordinates_along(ray, segment, self.bounds.min, self.bounds.max) {
                    Some(c) => with_scratch(|s| e.tape.eval(jets_along(c, ray.dir), &mut s.jets)),
                    None => Jet::new(Enclosure::point(f64::INFINITY), Enclosure::ENTIRE),
                },
            ),
            Phi::Closure(_) => None,
        }
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        match &self.phi {
            Phi::Expression(e) => Some(
                match coordinates_along(ray, segment, self.bounds.min, self.bounds.max) {
                    Some(c) => with_scratch(|s| e.tape.eval(c, &mut s.enclosures)),
                    None => Enclosure::point(f64::INFINITY),
                },
            ),
            Phi::Closure(_) => None,
        }
    }
}

impl Intersect for Function {
    /// An expression: the octree's leaves front to back, each isolated with its pruned tape
    /// (see [`crate::expr::cells`]); a closure: the generic finder.
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        if let Phi::Expression(compiled) = &self.phi {
            let segment = self.clipped(ray, range)?;
            if let Some(report) = compiled.first_root(ray, segment, &self.bounds, &self.options) {
                return report.hit;
            }
        }
        crate::root::first_root(self, ray, range, &self.options).hit
    }

    /// [`Function::intersect`] of each ray (the same hits): an expression's rays that the
    /// octree serves walk it together, [`crate::expr::cells::LANES`] at a time ([`CellTree::walk_packet`]).
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        packet::intersect_packet(self, rays, ranges, hits);
    }

    fn root_options(&self) -> RootOptions {
        self.options
    }

    /// The normalised gradient, from the pruned tape of the leaf the hit was found in.
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        match &self.phi {
            Phi::Expression(compiled) => compiled.gradient(ray.at(raw.t), raw.feature).normalize_or_zero(),
            Phi::Closure(_) => self.gradient(ray.at(raw.t)).normalize_or_zero(),
        }
    }

    /// The rounding bound of the default plus the root's own uncertainty: the hit lies within
    /// the tolerance (in units of `t`) of a root along the ray, so within `tolerance·|dir|` of
    /// the surface. Secondary rays ([`crate::SurfaceHit::secondary_origin`]) start beyond it.
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        let magnitude = crate::offset::magnitude(&self.bounds);
        crate::offset::root_error_bound(ray, raw.t, magnitude, self.options.tolerance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Interval;

    fn unit_box() -> Aabb {
        Aabb::new(DVec3::splat(-1.0), DVec3::splat(1.0))
    }

    fn build(text: &str, bounds: Aabb) -> Result<Function, PrimitiveError> {
        Function::from_expr(Expr::parse(text).unwrap(), bounds, RootOptions::default())
    }

    /// Φ that overflows to ±∞ on either side of its zero set (the plane x = 0 of
    /// `x·10³⁰⁸·10³⁰⁸`) is hit where the plane is, like `x` itself, on every ray through the box.
    #[test]
    fn overflowing_phi_keeps_its_sign() {
        let bounds = Aabb::new(DVec3::splat(-1.0), DVec3::splat(1.0));
        let huge = build("x*1e308*1e308", bounds).unwrap();
        for k in 0..200 {
            let f = f64::from(k);
            let origin = DVec3::new(3.0, (0.37 * f).sin() * 0.9, (0.61 * f).cos() * 0.9);
            let target = DVec3::new(-1.0, (0.23 * f).cos() * 0.9, (0.11 * f).sin() * 0.9);
            let ray = Ray::new(origin, target - origin);
            let (hit, uncertain) = crate::root::uncertain_while(|| huge.intersect(&ray, Interval::POSITIVE));
            let expected = origin.x / (origin.x - target.x);
            let t = hit.expect("the plane x = 0 is crossed").t;
            assert!((t - expected).abs() <= 1e-6, "ray {k}: {t} vs {expected}");
            assert!(!uncertain, "ray {k}");
        }
    }

    /// The plain-f64 slope test certifies only what outward-rounded interval arithmetic
    /// certifies, and almost everything it does (pseudo-random enclosures and directions).
    #[test]
    fn monotone_test_agrees_with_interval_arithmetic() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (mut both, mut fast_only, mut interval_only) = (0, 0, 0);
        for _ in 0..100_000 {
            let g: [Enclosure; 3] = std::array::from_fn(|_| {
                let (c, r) = (next() * 3.0, next().abs() * next().abs());
                Enclosure::new(c - r, c + r)
            });
            let d = DVec3::new(next(), next(), next()).normalize();
            let slope = (0..3).fold(Enclosure::point(0.0), |sum, a| sum + g[a] * Enclosure::point(d[a]));
            let exact = !slope.contains_zero();
            match (monotone_along(&g, d), exact) {
                (true, true) => both += 1,
                (true, false) => fast_only += 1,
                (false, true) => interval_only += 1,
                (false, false) => {}
            }
        }
        assert_eq!(fast_only, 0);
        assert!(both > 30_000 && interval_only < 10, "{both} {interval_only}");
    }

    #[test]
    fn domain_errors_are_found_at_construction() {
        let cases = [
            ("x + sqrt(-1)", "sqrt of a negative number (column 5)"),
            ("1/0 + x", "division by zero (column 2)"),
            ("ln(x) - 1", "logarithm of a number ≤ 0 (column 1)"),
            ("x^2 + y^2 - 1/x", "division by zero (column 14)"),
        ];
        for (text, message) in cases {
            let e = build(text, unit_box()).unwrap_err();
            assert_eq!(e.field, "phi", "{text}");
            assert!(e.problem.contains(message), "{text}: {}", e.problem);
        }
        // defined over the whole box: no error, and the interval check says so
        let fine = build("ln(x + 2) + 1/(y + 3) + sqrt(z + 1)", unit_box()).unwrap();
        assert!(!fine.may_be_undefined());
        let away = build("1/x - 1.5", Aabb::new(DVec3::new(0.5, -1.0, -1.0), DVec3::ONE)).unwrap();
        assert!(!away.may_be_undefined());
    }

    #[test]
    fn options_and_bounds_are_validated() {
        let expr = || Expr::parse("x").unwrap();
        let bad_tolerance = RootOptions {
            tolerance: 0.0,
            ..RootOptions::default()
        };
        assert_eq!(
            Function::from_expr(expr(), unit_box(), bad_tolerance)
                .unwrap_err()
                .field,
            "tolerance"
        );
        let bad_budget = RootOptions {
            max_evaluations: 1,
            ..RootOptions::default()
        };
        assert_eq!(
            Function::from_expr(expr(), unit_box(), bad_budget).unwrap_err().field,
            "budget"
        );
        let infinite = Aabb::new(DVec3::splat(-1.0), DVec3::splat(f64::INFINITY));
        assert_eq!(
            Function::from_expr(expr(), infinite, RootOptions::default())
                .unwrap_err()
                .field,
            "bounds"
        );
        assert!(build("x", unit_box()).unwrap().with_lipschitz(-1.0).is_err());
    }

    /// `sqrt(x + 1)` is defined on the whole box `x ≥ −1`; rays entering through the face
    /// `x = −1` (whose clipped start may round a hair outside) are decided without any domain
    /// count.
    #[test]
    fn rays_entering_at_the_domain_edge_of_the_box_are_clean() {
        let f = build("sqrt(x + 1) + y^2 + z^2 - 1.2", unit_box()).unwrap();
        assert!(!f.may_be_undefined());
        let before = crate::isolation::uncertain_counts();
        let mut hits = 0;
        for k in 0..200 {
            let y = -0.9 + 0.009 * f64::from(k);
            let ray = Ray::new(DVec3::new(-3.0, y, 0.1), DVec3::new(1.0, 0.013, -0.007).normalize());
            if let Some(h) = f.intersect(&ray, Interval::POSITIVE) {
                hits += 1;
                assert!(f.phi(ray.at(h.t)).abs() < 1e-6);
            }
        }
        assert!(hits > 100, "{hits}");
        // (no other unit test meets undefined pieces, so the process-wide count is this test's)
        let after = crate::isolation::uncertain_counts();
        assert_eq!(after.undefined, before.undefined, "{before:?} {after:?}");
    }

    #[test]
    fn expression_gradient_and_first_hit() {
        let f = build("x^2 + y^2 + z^2 - 0.25", unit_box()).unwrap();
        let p = DVec3::new(0.3, -0.2, 0.1);
        assert_eq!(f.gradient(p), 2.0 * p);
        let ray = Ray::new(DVec3::new(-3.0, 0.0, 0.0), DVec3::X);
        let hit = f.intersect(&ray, Interval::POSITIVE).unwrap();
        assert!((hit.t - 2.5).abs() <= 1e-7, "{}", hit.t);
        // the range is respected: starting past the front, the back is the first hit
        let back = f.intersect(&ray, Interval::new(3.0, 10.0)).unwrap();
        assert!((back.t - 3.5).abs() <= 1e-7, "{}", back.t);
    }
}
