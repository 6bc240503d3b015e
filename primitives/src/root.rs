//! The generic intersector: first root of Φ along a ray, for any [`Implicit`] type.
//!
//! 1. **Clip** the query interval to the type's bounds (slab test); unbounded types march the
//!    whole query interval, out to the farthest finite point where it runs to `+∞` (see
//!    [`first_root`]).
//! 2. **Bracket** the first sign change of `g(t) = Φ(origin + t·dir)`:
//!    - with a declared Lipschitz bound `L` (|∇Φ| ≤ L), step by `|g(t)| / (L·|dir|)` (sphere
//!      tracing), never less than the tolerance: the ball of that radius holds no root, so no
//!      surface thicker than the tolerance is skipped. Steps are over-relaxed by ω = 1.6 (Keinert et
//!      al., "Enhanced Sphere Tracing", 2014) and kept only where the root-free balls around both
//!      ends cover the step, else retaken at ω = 1. Each step is also sampled at its midpoint; a
//!      slope `|Δg|/(|dir|·Δt)` between any two of the three samples above `L` proves the bound
//!      wrong (the midpoint catches a wrong bound that jumps over a whole thin part): it is
//!      counted (see [`lipschitz_violations`]) and the march goes on with twice the observed
//!      slope, from the last sample;
//!    - without one, sample `g` at [`RootOptions::samples`] evenly spaced points.
//!
//!    A ray that touches the surface without crossing it (exact tangency) is a miss; one that
//!    crosses it over a stretch longer than the tolerance is found.
//! 3. **Refine** the bracket by the Illinois variant of regula falsi, falling back to bisection
//!    whenever an interpolation step fails to halve the bracket, until it is no wider than
//!    [`RootOptions::tolerance`] (in units of `t`). The returned `t` is then within the
//!    tolerance of a root.
//!
//! Points rejected by [`Implicit::within_boundary`] are stepped over and the march continues.
//!
//! Types that enclose Φ along a ray segment ([`Implicit::enclose_along`], e.g. every `Function`
//! expression) skip steps 2–3: their first root is isolated with a guarantee by interval
//! arithmetic instead ([`crate::isolation`]), and no Lipschitz bound is needed.

pub(crate) use crate::finder::{note_uncertain_on_thread, refine_bracket};
pub use crate::finder::{thread_uncertain_events, traced_again, uncertain_while, RootOptions, RootReport};
use crate::hit::RawHit;
use crate::implicit::Implicit;
use crate::ray::{Interval, Ray};
use std::sync::atomic::{AtomicU64, Ordering};

static LIPSCHITZ_VIOLATIONS: AtomicU64 = AtomicU64::new(0);
static BUDGET_EXHAUSTIONS: AtomicU64 = AtomicU64::new(0);

/// How many rays, process-wide, ran out of [`RootOptions::max_evaluations`] before the end of
/// their interval: each was reported as a miss although a surface may lie further on.
#[must_use]
pub fn budget_exhaustions() -> u64 {
    BUDGET_EXHAUSTIONS.load(Ordering::Relaxed)
}

fn record_budget_exhaustion() {
    if crate::finder::counts_process_wide() {
        BUDGET_EXHAUSTIONS.fetch_add(1, Ordering::Relaxed);
    }
    note_uncertain_on_thread();
}

/// Over-relaxation factor ω of the sphere-tracing steps: a step of `ω·|g|/k` is kept only if the
/// root-free balls `|g|/k` around both of its ends cover it; otherwise it is retaken at `ω = 1`.
const RELAXATION: f64 = 1.6;

/// How many rays, process-wide, found Φ steeper than the Lipschitz bound its type declared.
#[must_use]
pub fn lipschitz_violations() -> u64 {
    LIPSCHITZ_VIOLATIONS.load(Ordering::Relaxed)
}

struct Marcher<'a, I: Implicit + ?Sized> {
    surface: &'a I,
    ray: &'a Ray,
    evaluations: u32,
}

impl<I: Implicit + ?Sized> Marcher<'_, I> {
    fn g(&mut self, t: f64) -> f64 {
        self.evaluations = self.evaluations.saturating_add(1);
        self.surface.phi(self.ray.at(t))
    }
}

/// The first point in `range` where Φ crosses zero along `ray` (see the module docs).
///
/// **Unbounded surfaces** (infinite bounds, e.g. an [`crate::Offset`] or [`crate::SmoothUnion`]
/// of a [`crate::Plane`]) whose clipped range runs to `+∞` are marched from `range.min` to the
/// farthest `t` whose point is finite ([`far_end`]): with a Lipschitz bound by sphere tracing
/// over the whole of it (the steps grow with `|Φ|`, so a ray leaving the surface reaches the far
/// end in about `ln(10³⁰⁸) / ln(1 + 1.6·cos θ)` steps), without one by
/// [`RootOptions::samples`] samples over segments that double in length. A ray that runs out of
/// [`RootOptions::max_evaluations`] first (one nearly parallel to a plane) is counted as
/// uncertain, never a silent miss; so is an unbounded range that starts at `−∞`, which has no
/// first point to march from.
pub fn first_root<I: Implicit + ?Sized>(surface: &I, ray: &Ray, range: Interval, options: &RootOptions) -> RootReport {
    let mut report = RootReport {
        hit: None,
        lipschitz_violated: false,
        evaluations: 0,
        uncertain: false,
    };
    // grow the bounds by the tolerance, so that the march starts strictly outside a surface
    // that touches its bounds (a box), not on it with a Φ of either sign from rounding
    let margin = options.tolerance * ray.dir.length();
    let Some(clipped) = surface.bounds().expanded(margin).clip(ray, range) else {
        return report;
    };
    if !ray.is_valid() || clipped.min.is_nan() || clipped.max.is_nan() {
        return report;
    }
    if !clipped.min.is_finite() || !clipped.max.is_finite() {
        return first_root_unbounded(surface, ray, clipped, options);
    }
    if surface.enclose_value_along(ray, clipped).is_some() {
        return crate::isolation::isolate_first_root(surface, ray, clipped, options);
    }
    let mut m = Marcher {
        surface,
        ray,
        evaluations: 0,
    };
    let mut march = March::start(&mut m, clipped.min, options);
    march.segment(&mut m, &mut report, clipped.max, options);
    if report.hit.is_none() && march.t0 < clipped.max && m.evaluations >= options.max_evaluations {
        record_budget_exhaustion();
    }
    report.evaluations = m.evaluations;
    report
}

/// The largest `t` at which `ray.at(t)` is surely finite: `t·|dir|∞ ≤ ½·f64::MAX` (less the
/// origin's magnitude), or `f64::MAX` for a direction so short that this is not representable.
#[must_use]
pub fn far_end(ray: &Ray) -> f64 {
    let room = (0.5 * f64::MAX - ray.origin.abs().max_element()).max(0.0);
    let t = room / ray.dir.abs().max_element();
    if t.is_finite() {
        t
    } else {
        f64::MAX
    }
}

/// [`first_root`] where the clipped range is infinite (see its docs).
fn first_root_unbounded<I: Implicit + ?Sized>(
    surface: &I,
    ray: &Ray,
    clipped: Interval,
    options: &RootOptions,
) -> RootReport {
    let mut report = RootReport {
        hit: None,
        lipschitz_violated: false,
        evaluations: 0,
        uncertain: false,
    };
    let t_far = far_end(ray).min(clipped.max);
    if !clipped.min.is_finite() || clipped.min >= t_far {
        // no first point to march from (or none before the point overflows): undecided
        report.uncertain = clipped.min < clipped.max;
        if report.uncertain {
            note_uncertain_on_thread();
        }
        return report;
    }
    let mut m = Marcher {
        surface,
        ray,
        evaluations: 0,
    };
    let mut march = March::start(&mut m, clipped.min, options);
    if march.slope.is_some() {
        // sphere tracing needs no segments: its steps are safe whatever the length
        march.segment(&mut m, &mut report, t_far, options);
    } else {
        // uniform samples over segments doubling in length, starting at the scale of the origin
        let dir_len = ray.dir.length();
        let mut length = (ray.origin.abs().max_element().max(1.0) / dir_len).max(f64::MIN_POSITIVE);
        while report.hit.is_none() && march.t0 < t_far && m.evaluations < options.max_evaluations {
            let end = if t_far - march.t0 > length {
                march.t0 + length
            } else {
                t_far
            };
            march.segment(&mut m, &mut report, end, options);
            length *= 2.0;
        }
    }
    if report.hit.is_none() && march.t0 < t_far && m.evaluations >= options.max_evaluations {
        record_budget_exhaustion();
        report.uncertain = true;
    }
    report.evaluations = m.evaluations;
    report
}

/// The state of one march along a ray, carried from one segment to the next.
struct March {
    t0: f64,
    g0: f64,
    slope: Option<f64>,
    relax: f64,
    tolerance: f64,
}

impl March {
    fn start<I: Implicit + ?Sized>(m: &mut Marcher<'_, I>, t_start: f64, options: &RootOptions) -> Self {
        let dir_len = m.ray.dir.length();
        let g0 = m.g(t_start);
        Self {
            t0: t_start,
            g0,
            slope: m.surface.lipschitz().map(|l| l * dir_len),
            relax: RELAXATION,
            tolerance: options.tolerance.max(f64::MIN_POSITIVE),
        }
    }

    /// Marches from `self.t0` to `t_end` (steps 2–3 of the module docs), setting `report.hit`
    /// at the first root; stops there, at `t_end`, or when the budget is spent.
    fn segment<I: Implicit + ?Sized>(
        &mut self,
        m: &mut Marcher<'_, I>,
        report: &mut RootReport,
        t_end: f64,
        options: &RootOptions,
    ) {
        let (surface, ray, tolerance) = (m.surface, m.ray, self.tolerance);
        let uniform_step = (t_end - self.t0) / f64::from(options.samples.max(1));
        let Self {
            t0, g0, slope, relax, ..
        } = self;
        while *t0 < t_end && m.evaluations < options.max_evaluations {
            if *g0 == 0.0 && surface.within_boundary(ray.at(*t0)) {
                report.hit = Some(RawHit::at(*t0));
                break;
            }
            let radius = slope.map(|k| g0.abs() / k);
            let step = match radius {
                // over-relaxed step (Keinert et al. 2014); checked below
                Some(r) => (*relax * r).max(tolerance),
                None => uniform_step,
            };
            let mut t1 = (*t0 + step).min(t_end);
            let mut g1 = m.g(t1);
            if let (Some(k), Some(r0)) = (*slope, radius) {
                let same_sign = (*g0 < 0.0) == (g1 < 0.0) && g1 != 0.0;
                if *relax > 1.0 && same_sign && r0 + g1.abs() / k < t1 - *t0 {
                    // the two root-free balls leave a gap: retake the plain sphere-tracing step
                    *relax = 1.0;
                    continue;
                }
                // the midpoint too: a wrong bound can step over a whole thin part between two
                // samples of equal sign and similar value, which the end points alone cannot reveal
                let observed = if t1 - *t0 > 2.0 * tolerance {
                    let mid = 0.5 * (*t0 + t1);
                    let gm = m.g(mid);
                    let observed = ((gm - *g0).abs() / (mid - *t0)).max((g1 - gm).abs() / (t1 - mid));
                    if (*g0 < 0.0) != (gm < 0.0) || gm == 0.0 {
                        // the crossing is in the first half: take that half as the step
                        (t1, g1) = (mid, gm);
                    }
                    observed
                } else {
                    (g1 - *g0).abs() / (t1 - *t0)
                };
                if observed > k * (1.0 + 1e-9) + f64::MIN_POSITIVE {
                    if !report.lipschitz_violated {
                        report.lipschitz_violated = true;
                        if crate::finder::counts_process_wide() {
                            LIPSCHITZ_VIOLATIONS.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    *slope = Some(2.0 * observed);
                    *relax = 1.0;
                    // re-march from t0 with the steeper slope unless the step was already minimal
                    if step > tolerance {
                        continue;
                    }
                }
                *relax = RELAXATION;
            }
            if (*g0 < 0.0) != (g1 < 0.0) || g1 == 0.0 {
                let t = if g1 == 0.0 {
                    t1
                } else {
                    refine_bracket(|t| m.g(t), (*t0, *g0), (t1, g1), tolerance)
                };
                if surface.within_boundary(ray.at(t)) {
                    report.hit = Some(RawHit::at(t));
                    break;
                }
            }
            *t0 = t1;
            *g0 = g1;
        }
    }
}
