//! Guaranteed first roots by interval root isolation, for types that enclose Φ along a ray
//! ([`Implicit::enclose_along`]; every `Function` expression does).
//!
//! With `g(t) = Φ(o + t·d)` on the clipped segment, a stack of pieces is processed front to back
//! (after Mitchell 1990, "Robust ray intersection with interval arithmetic", and Knoll et al.
//! 2009, "Fast ray tracing of arbitrary implicit surfaces with interval and affine arithmetic"):
//!
//! 1. **Prune.** An enclosure `G ⊇ g([a, b])` with `0 ∉ G` proves the piece root-free.
//! 2. **Certify monotone pieces.** An enclosure `G′ ⊇ g′([a, b])` with `0 ∉ G′` proves `g`
//!    strictly monotone there: it has a root iff `g(a)` and `g(b)` differ in sign, and then
//!    exactly one, refined by regula falsi / bisection ([`crate::root`]) to the tolerance.
//! 3. **Certify convex or concave pieces** (where the evaluator encloses `g″` too: tapes
//!    without `min`, `max` or `abs`, whose second derivative has no kinks). `0 ∉ G″` makes
//!    `h = ±g` strictly convex on the piece, so `{h ≤ 0}` is one interval and `h` has at most two
//!    roots. End values of opposite signs bracket exactly one root; two negative ends exclude a
//!    root; two positive ends are settled by the tangents at the ends, whose pointwise maximum
//!    bounds the convex `h` from below: a lower bound above 0 (with a margin of `1e-10` of the
//!    piece's scale for rounding) excludes a root, else the piece is cut where the tangents meet
//!    (a Newton step towards the minimum) and both halves are examined front first, a negative
//!    value there bracketing the first root. After 16 steps, or on a piece no wider than the
//!    tolerance, the piece goes on to step 4 undecided. An evaluator that knows `g″`'s sign over
//!    a region holding the piece ([`AlongRay::known_convex`]: an octree leaf's Hessian) takes
//!    this step first and skips steps 1 and 2 (interval evaluations over the piece): convexity
//!    alone lets the end values and tangents decide.
//!
//!    Where `g = max(u, v)` (or `min`, with `h = −g`) and jets of `u` and `v` prove one strictly
//!    increasing and the other strictly decreasing on the piece, `h` is strictly **unimodal**:
//!    strictly decreasing, then strictly increasing. `{h ≤ 0}` is again one interval, so the end
//!    values decide as above, but two positive ends send the piece to step 4 (no tangent bounds
//!    a unimodal `h`).
//! 4. **Subdivide** otherwise, at the midpoint, front half first.
//! 5. A piece no wider than the tolerance that can be neither pruned nor certified is
//!    - a **root** if `g` changes sign across it (a crossing within the tolerance);
//!    - else **uncertain**: `g` may touch 0 there without crossing (a tangent ray, a double root,
//!      or a near miss closer than the enclosures can separate). It is returned as the hit, so
//!      there is no hole, and counted ([`uncertain_counts`]).
//!
//! Every piece in front of the returned one was proven root-free, so the result is the **first**
//! root to the tolerance (or the first place a root cannot be excluded). A piece where Φ may be
//! undefined (`√` of a negative…) is subdivided like any other; at the tolerance it is skipped
//! and counted as a domain error. When the budget of enclosure evaluations runs out the ray
//! reports no hit and is counted as exhausted: never a silent hole.
//!
//! The point values `g(a)`, `g(b)` are f64 evaluations: a root closer to an end than the rounding
//! of Φ there may be attributed to the neighbouring piece (the ends are shared, so a sign change
//! is never lost between two pieces).

use crate::expr::Jet;
use crate::finder::{note_uncertain_on_thread, refine_bracket, Refinement, RootOptions, RootReport};
use crate::hit::RawHit;
use crate::implicit::Implicit;
use crate::math::enclosure::Enclosure;
use crate::ray::{Interval, Ray};
use std::sync::atomic::{AtomicU64, Ordering};

static TANGENT: AtomicU64 = AtomicU64::new(0);
static EXHAUSTED: AtomicU64 = AtomicU64::new(0);
static UNDEFINED: AtomicU64 = AtomicU64::new(0);

/// Process-wide counts of rays the interval root finder could not decide exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UncertainCounts {
    /// Rays whose first hit is a place where Φ touches 0 within the tolerance without a proven
    /// crossing (tangent rays, double roots, near misses): reported as hits.
    pub tangent: u64,
    /// Rays that spent their budget before isolating a root: reported as misses.
    pub exhausted: u64,
    /// Rays that met pieces, no wider than the tolerance, where Φ may be undefined (skipped).
    pub undefined: u64,
}

impl UncertainCounts {
    /// Whether every count is 0.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

/// The counts so far in this process.
#[must_use]
pub fn uncertain_counts() -> UncertainCounts {
    UncertainCounts {
        tangent: TANGENT.load(Ordering::Relaxed),
        exhausted: EXHAUSTED.load(Ordering::Relaxed),
        undefined: UNDEFINED.load(Ordering::Relaxed),
    }
}

fn differ(ga: f64, gb: f64) -> bool {
    ga == 0.0 || gb == 0.0 || (ga < 0.0) != (gb < 0.0)
}

/// What the isolation needs of `g(t) = Φ(o + t·d)` on pieces of one ray: enclosures of the
/// value (and of value and slope together) over a piece, point values, and whether a point of
/// the zero set belongs to the surface. [`isolate_first_root`] asks an [`Implicit`] type; the
/// compiled expressions of [`crate::Function`] answer from the tape pruned to the cell a piece
/// lies in (the same numbers there, see [`crate::expr::tape`]).
pub(crate) trait AlongRay {
    /// An enclosure of `g` over `piece` (`ENTIRE` when none is known).
    fn value(&mut self, piece: Interval) -> Enclosure;
    /// Enclosures of `g` and `g′` over `piece`, with what is known of its shape there (one
    /// evaluation may give all of it): [`Shape::Convex`] where an enclosure of `g″` has one
    /// strict sign, [`Shape::Unimodal`] where `g` is a `max` or `min` of two functions proven
    /// strictly monotone in opposite directions, `None` otherwise (then
    /// [`AlongRay::point_slope`] is never asked).
    fn jet_and_curvature(&mut self, piece: Interval) -> (Jet<Enclosure>, Option<Shape>);
    /// [`Shape::Convex`] where `g` is known to be strictly convex or concave over all of
    /// `piece` and defined there without enclosing it over the piece (from what is known of a
    /// region holding it); `None` by default.
    fn known_convex(&mut self, _piece: Interval) -> Option<Shape> {
        None
    }
    /// `g(t)` in f64.
    fn point(&mut self, t: f64) -> f64;
    /// Whether the zero-set point at `t` belongs to the surface.
    fn within_boundary(&mut self, t: f64) -> bool;
    /// `g(t)` (as [`AlongRay::point`] gives it) and `g′(t)` in f64.
    fn point_slope(&mut self, t: f64) -> (f64, f64) {
        (self.point(t), f64::NAN)
    }
}

struct ImplicitAlong<'a, I: Implicit + ?Sized> {
    surface: &'a I,
    ray: &'a Ray,
}

impl<I: Implicit + ?Sized> AlongRay for ImplicitAlong<'_, I> {
    fn value(&mut self, piece: Interval) -> Enclosure {
        self.surface
            .enclose_value_along(self.ray, piece)
            .unwrap_or(Enclosure::ENTIRE)
    }
    fn jet_and_curvature(&mut self, piece: Interval) -> (Jet<Enclosure>, Option<Shape>) {
        let jet = self
            .surface
            .enclose_along(self.ray, piece)
            .unwrap_or(Jet::new(Enclosure::ENTIRE, Enclosure::ENTIRE));
        (jet, None)
    }
    fn point(&mut self, t: f64) -> f64 {
        self.surface.phi(self.ray.at(t))
    }
    fn within_boundary(&mut self, t: f64) -> bool {
        self.surface.within_boundary(self.ray.at(t))
    }
}

/// The outcome of isolating on one segment ([`isolate_in`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Isolated {
    /// The first root (or undecided touch) and whether it is uncertain (a touch).
    pub hit: Option<(f64, bool)>,
    /// The budget ran out before the segment was decided.
    pub exhausted: bool,
    /// A piece no wider than the tolerance where Φ may be undefined was skipped.
    pub undefined_seen: bool,
}

/// The first root of `g` in `segment` by interval isolation (steps 1–4 of the module docs),
/// counting enclosures and point values in `evaluations` against `budget`. Nothing is counted
/// process-wide here: [`count_outcome`] does it once per ray.
pub(crate) fn isolate_in<P: AlongRay>(
    along: &mut P,
    segment: Interval,
    tolerance: f64,
    budget: u32,
    evaluations: &mut u32,
) -> Isolated {
    let tolerance = tolerance.max(f64::MIN_POSITIVE);
    let mut out = Isolated::default();
    let point = |along: &mut P, t: f64, evaluations: &mut u32| {
        *evaluations = evaluations.saturating_add(1);
        along.point(t)
    };
    // pieces to examine, the front one last (popped first)
    let mut stack = PieceStack::new((segment.min, segment.max));
    while let Some((a, b)) = stack.pop() {
        if *evaluations >= budget {
            out.exhausted = true;
            break;
        }
        *evaluations += 1;
        let piece = Interval::new(a, b);
        let mid = 0.5 * (a + b);
        let splittable = b - a > tolerance && mid > a && mid < b;
        let (defined, monotone, curved) = if let Some(convex) = along.known_convex(piece) {
            // 3. strictly convex or concave, known without enclosing g over the piece: its
            // point values decide at least as much as an enclosure would
            (
                true,
                false,
                Some(convex_root(along, a, b, convex, tolerance, evaluations)),
            )
        } else {
            // the value alone first: most pieces (and whole rays that miss) are pruned by it
            let value = along.value(piece);
            if !value.undefined() && !value.contains_zero() {
                continue; // 1. root-free
            }
            let (enclosure, shape) = along.jet_and_curvature(piece);
            let value = enclosure.value;
            let defined = !value.undefined();
            if defined && !value.contains_zero() {
                continue; // 1. root-free
            }
            let monotone = defined && !enclosure.slope.contains_zero();
            // 3. strictly convex or concave (where g″ is enclosed), or unimodal
            let curved = if defined && !monotone {
                shape.map(|shape| convex_root(along, a, b, shape, tolerance, evaluations))
            } else {
                None
            };
            (defined, monotone, curved)
        };
        let (t, uncertain) = if monotone {
            // 2. strictly monotone: a root iff the end values differ in sign
            match monotone_root(along, a, b, tolerance, evaluations) {
                Some(t) => (t, false),
                None => continue,
            }
        } else if let Some(Curved::Root(t)) = curved {
            (t, false)
        } else if curved == Some(Curved::NoRoot) {
            continue;
        } else if splittable {
            // 4. subdivide, front half on top
            stack.push((mid, b));
            stack.push((a, mid));
            continue;
        } else if !defined {
            out.undefined_seen = true;
            continue;
        } else {
            // 5. at the tolerance: a crossing, or a touch that cannot be excluded
            let (ga, gb) = (point(along, a, evaluations), point(along, b, evaluations));
            let t = if ga.abs() <= gb.abs() { a } else { b };
            (t, !differ(ga, gb))
        };
        if along.within_boundary(t) {
            out.hit = Some((t, uncertain));
            break;
        }
        // not part of the surface: go on after it
        let next = t + tolerance;
        if next < b {
            stack.push((next, b));
        }
    }
    out
}

/// The root of `g` on `[a, b]` where `g` is known to be strictly monotone there: a root iff
/// the end values differ in sign, refined by regula falsi / bisection to `tolerance` (step 2
/// of the module docs). Point values are counted in `evaluations`.
pub(crate) fn monotone_root<P: AlongRay>(
    along: &mut P,
    a: f64,
    b: f64,
    tolerance: f64,
    evaluations: &mut u32,
) -> Option<f64> {
    let mut point = |t: f64| {
        *evaluations = evaluations.saturating_add(1);
        along.point(t)
    };
    let (ga, gb) = (point(a), point(b));
    match monotone_ends((a, ga), (b, gb), tolerance) {
        Ends::NoRoot => None,
        Ends::Root(t) => Some(t),
        Ends::Bracket(refinement) => Some(refinement.run(point)),
    }
}

/// What the end values of a piece where `g` is strictly monotone decide ([`monotone_ends`]).
pub(crate) enum Ends {
    /// No root in the piece (the values do not differ in sign).
    NoRoot,
    /// A root at an end, where `g` is exactly 0.
    Root(f64),
    /// One root inside, to refine to `tolerance`.
    Bracket(Refinement),
}

/// Step 2 on a monotone piece `[a, b]` from its end values: [`monotone_root`]'s decision, for
/// callers that evaluate the points themselves (several rays at once).
pub(crate) fn monotone_ends((a, ga): (f64, f64), (b, gb): (f64, f64), tolerance: f64) -> Ends {
    if !differ(ga, gb) {
        Ends::NoRoot
    } else if ga == 0.0 {
        Ends::Root(a)
    } else if gb == 0.0 {
        Ends::Root(b)
    } else {
        Ends::Bracket(Refinement::new((a, ga), (b, gb), tolerance.max(f64::MIN_POSITIVE)))
    }
}

/// The shape of `h = sign·g` on a piece ([`AlongRay::jet_and_curvature`]), `sign` being ±1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Shape {
    /// `h` strictly convex.
    Convex(f64),
    /// `h` strictly decreasing, then strictly increasing (either part possibly empty).
    Unimodal(f64),
}

/// What [`convex_root`] decided about a piece.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Curved {
    /// The first root in the piece.
    Root(f64),
    /// No root in the piece.
    NoRoot,
    /// Neither within its step budget (a nearly tangent ray, a non-finite value).
    Undecided,
}

/// The first root of `g` on `[a, b]` where `h = sign·g` is strictly convex or strictly unimodal
/// there (step 3 of the module docs): brackets by the end values, then, for a convex `h`, Newton
/// steps towards the minimum of `h` from the tangents at the ends of each piece. Point values
/// are counted in `evaluations`.
pub(crate) fn convex_root<P: AlongRay>(
    along: &mut P,
    a: f64,
    b: f64,
    shape: Shape,
    tolerance: f64,
    evaluations: &mut u32,
) -> Curved {
    let (sign, convex) = match shape {
        Shape::Convex(sign) => (sign, true),
        Shape::Unimodal(sign) => (sign, false),
    };
    const STEPS: u32 = 16;
    let tolerance = tolerance.max(f64::MIN_POSITIVE);
    let bracket = |along: &mut P, (t0, h0): (f64, f64), (t1, h1): (f64, f64), evaluations: &mut u32| {
        let g = |t: f64| {
            *evaluations = evaluations.saturating_add(1);
            along.point(t)
        };
        Curved::Root(refine_bracket(g, (t0, sign * h0), (t1, sign * h1), tolerance))
    };
    *evaluations = evaluations.saturating_add(2);
    let (ha, hb) = (sign * along.point(a), sign * along.point(b));
    if !(ha.is_finite() && hb.is_finite()) {
        return Curved::Undecided;
    }
    if ha == 0.0 {
        return Curved::Root(a);
    }
    if ha < 0.0 {
        // {h ≤ 0} is an interval holding a: a root only where it ends
        return if hb < 0.0 {
            Curved::NoRoot
        } else if hb == 0.0 {
            Curved::Root(b)
        } else {
            bracket(along, (a, ha), (b, hb), evaluations)
        };
    }
    if hb < 0.0 {
        return bracket(along, (a, ha), (b, hb), evaluations);
    }
    // h(a) > 0, h(b) ≥ 0: the minimum of h decides, bounded below by tangents if h is convex
    if !convex {
        return Curved::Undecided;
    }
    let slope = |along: &mut P, t: f64, evaluations: &mut u32| {
        *evaluations = evaluations.saturating_add(1);
        let (g, dg) = along.point_slope(t);
        (sign * g, sign * dg)
    };
    let (da, db) = (slope(along, a, evaluations).1, slope(along, b, evaluations).1);
    // pieces (t0, h0, h′0, t1, h1, h′1), the front one last; each step replaces one by two, so
    // at most STEPS + 1 are held
    let mut pieces = [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0); STEPS as usize + 1];
    pieces[0] = (a, ha, da, b, hb, db);
    let mut held = 1;
    let mut steps = 0;
    while held > 0 {
        held -= 1;
        let (t0, h0, d0, t1, h1, d1) = pieces[held];
        if !(d0.is_finite() && d1.is_finite()) {
            return Curved::Undecided;
        }
        if d0 < 0.0 && d1 > 0.0 {
            // the tangents at the ends meet at t0 + u, where their maximum is least
            let width = t1 - t0;
            let u = (h1 - h0 - d1 * width) / (d0 - d1);
            let lower = h0 + d0 * u;
            let scale = h0 + h1 + (d1 - d0) * width;
            if !(lower > 1e-10 * scale) {
                steps += 1;
                let mut tm = t0 + u;
                if !(tm > t0 && tm < t1) {
                    tm = 0.5 * (t0 + t1);
                }
                if steps > STEPS || width <= tolerance || !(tm > t0 && tm < t1) {
                    return Curved::Undecided;
                }
                let (hm, dm) = slope(along, tm, evaluations);
                if !hm.is_finite() {
                    return Curved::Undecided;
                }
                if hm < 0.0 {
                    return bracket(along, (t0, h0), (tm, hm), evaluations);
                }
                if hm == 0.0 {
                    return if dm < 0.0 { Curved::Root(tm) } else { Curved::Undecided };
                }
                pieces[held] = (tm, hm, dm, t1, h1, d1);
                pieces[held + 1] = (t0, h0, d0, tm, hm, dm);
                held += 2;
                continue;
            }
        }
        // h > 0 on [t0, t1): monotone there, or above its tangents; a root only at t1
        if h1 == 0.0 {
            return Curved::Root(t1);
        }
    }
    Curved::NoRoot
}

/// A stack of pieces kept in place for the usual depths (a piece list grows by one per halving
/// level), spilling to the heap past them: no allocation per ray.
struct PieceStack {
    inline: [(f64, f64); 64],
    len: usize,
    spilled: Vec<(f64, f64)>,
}

impl PieceStack {
    fn new(first: (f64, f64)) -> Self {
        let mut inline = [(0.0, 0.0); 64];
        inline[0] = first;
        Self {
            inline,
            len: 1,
            spilled: Vec::new(),
        }
    }

    #[inline]
    fn push(&mut self, piece: (f64, f64)) {
        if self.len < self.inline.len() {
            self.inline[self.len] = piece;
            self.len += 1;
        } else {
            self.spilled.push(piece);
        }
    }

    #[inline]
    fn pop(&mut self) -> Option<(f64, f64)> {
        if let Some(piece) = self.spilled.pop() {
            return Some(piece);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.inline[self.len])
    }
}

/// Counts a ray's outcome process-wide (and on its thread) once: a touch reported as a hit,
/// an exhausted budget, pieces skipped as undefined.
pub(crate) fn count_outcome(hit: Option<(f64, bool)>, exhausted: bool, undefined_seen: bool) -> bool {
    let mut uncertain = false;
    let process_wide = crate::finder::counts_process_wide();
    let count = |counter: &AtomicU64| {
        if process_wide {
            counter.fetch_add(1, Ordering::Relaxed);
        }
        note_uncertain_on_thread();
    };
    if exhausted {
        count(&EXHAUSTED);
        uncertain = true;
    }
    if let Some((_, true)) = hit {
        count(&TANGENT);
        uncertain = true;
    }
    if undefined_seen {
        count(&UNDEFINED);
    }
    uncertain
}

/// The first root of Φ along `ray` in `segment` (already clipped to the bounds), by interval
/// isolation (see the module docs). The budget is [`RootOptions::max_evaluations`], counting
/// enclosures and point values alike.
pub(crate) fn isolate_first_root<I: Implicit + ?Sized>(
    surface: &I,
    ray: &Ray,
    segment: Interval,
    options: &RootOptions,
) -> RootReport {
    let mut evaluations = 0u32;
    let mut along = ImplicitAlong { surface, ray };
    let out = isolate_in(
        &mut along,
        segment,
        options.tolerance,
        options.max_evaluations,
        &mut evaluations,
    );
    let uncertain = count_outcome(out.hit, out.exhausted, out.undefined_seen);
    RootReport {
        hit: out.hit.map(|(t, _)| RawHit::at(t)),
        lipschitz_violated: false,
        evaluations,
        uncertain,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `g(t) = s·((t − c)² − e)` with its exact derivatives (`g″ = 2s`): roots `c ± √e`.
    struct Parabola {
        c: f64,
        e: f64,
        s: f64,
    }

    impl AlongRay for Parabola {
        fn value(&mut self, _piece: Interval) -> Enclosure {
            Enclosure::ENTIRE
        }
        fn jet_and_curvature(&mut self, _piece: Interval) -> (Jet<Enclosure>, Option<Shape>) {
            (
                Jet::new(Enclosure::ENTIRE, Enclosure::ENTIRE),
                Some(Shape::Convex(self.s)),
            )
        }
        fn point(&mut self, t: f64) -> f64 {
            self.s * ((t - self.c) * (t - self.c) - self.e)
        }
        fn within_boundary(&mut self, _t: f64) -> bool {
            true
        }
        fn point_slope(&mut self, t: f64) -> (f64, f64) {
            (self.point(t), self.s * 2.0 * (t - self.c))
        }
    }

    /// The first root of convex and concave parabolas on [0, 1] against the closed form `c − √e`
    /// (or `c + √e` where the first is before the piece), misses where `e < 0` or both roots lie
    /// outside, and an exact double root left undecided or found, never missed.
    #[test]
    fn convex_pieces_give_the_first_root_or_none() {
        let tolerance = 1e-9;
        let mut checked = 0;
        for &s in &[1.0, -1.0] {
            for &c in &[0.05, 0.3, 0.5, 0.77, 0.98, 1.4, -0.2] {
                for &e in &[-0.3, -1e-6, 1e-9, 1e-6, 0.01, 0.05, 0.2, 0.6] {
                    let mut g = Parabola { c, e, s };
                    let mut evaluations = 0;
                    let got = convex_root(&mut g, 0.0, 1.0, Shape::Convex(s), tolerance, &mut evaluations);
                    let expected = if e < 0.0 {
                        None
                    } else {
                        let r = e.sqrt();
                        [c - r, c + r].into_iter().find(|t| (0.0..=1.0).contains(t))
                    };
                    match (got, expected) {
                        (Curved::Root(t), Some(x)) => {
                            assert!((t - x).abs() <= 2.0 * tolerance, "{s} {c} {e}: {t} vs {x}")
                        }
                        (Curved::NoRoot, None) => {}
                        other => panic!("s {s} c {c} e {e}: {other:?}"),
                    }
                    assert!(evaluations < 80, "{s} {c} {e}: {evaluations} evaluations");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 112);
        // a double root at 0.5: never reported as root-free
        let mut touch = Parabola { c: 0.5, e: 0.0, s: 1.0 };
        let got = convex_root(&mut touch, 0.0, 1.0, Shape::Convex(1.0), tolerance, &mut 0);
        assert!(
            matches!(got, Curved::Undecided) || matches!(got, Curved::Root(t) if (t - 0.5).abs() < 1e-6),
            "{got:?}"
        );
    }
    /// `g(t) = s·(max(c − t, 2·(t − c)) − e)`: for `s = 1` a max of a decreasing and an
    /// increasing line, for `s = −1` a min of an increasing and a decreasing one; roots
    /// `c − e` and `c + e/2`.
    struct Vee {
        c: f64,
        e: f64,
        s: f64,
    }

    impl AlongRay for Vee {
        fn value(&mut self, _piece: Interval) -> Enclosure {
            Enclosure::ENTIRE
        }
        fn jet_and_curvature(&mut self, _piece: Interval) -> (Jet<Enclosure>, Option<Shape>) {
            (
                Jet::new(Enclosure::ENTIRE, Enclosure::ENTIRE),
                Some(Shape::Unimodal(self.s)),
            )
        }
        fn point(&mut self, t: f64) -> f64 {
            self.s * ((self.c - t).max(2.0 * (t - self.c)) - self.e)
        }
        fn within_boundary(&mut self, _t: f64) -> bool {
            true
        }
    }

    /// A unimodal piece: ends of opposite signs give the one root between them (against the
    /// closed form), two ends on the inside side give none, two on the outside side are left
    /// undecided (to be split), never answered.
    #[test]
    fn unimodal_pieces_decide_only_from_their_ends() {
        let tolerance = 1e-9;
        let mut outcomes = [0; 3];
        for &s in &[1.0, -1.0] {
            for &c in &[0.05, 0.3, 0.5, 0.77, 0.98, 1.4, -0.2] {
                for &e in &[-0.3, -1e-6, 1e-9, 1e-6, 0.01, 0.05, 0.2, 0.6, 1.5, 3.0] {
                    let mut g = Vee { c, e, s };
                    let (h0, h1) = (g.point(0.0) * s, g.point(1.0) * s);
                    let got = convex_root(&mut g, 0.0, 1.0, Shape::Unimodal(s), tolerance, &mut 0);
                    let first = [c - e, c + 0.5 * e].into_iter().find(|t| (0.0..=1.0).contains(t));
                    match got {
                        Curved::Root(t) => {
                            let ends_decide = h0 == 0.0 || h1 == 0.0 || (h0 < 0.0) != (h1 < 0.0);
                            assert!(ends_decide, "{s} {c} {e}: root from ends {h0} {h1}");
                            let x = first.expect("a root");
                            assert!((t - x).abs() <= 2.0 * tolerance, "{s} {c} {e}: {t} vs {x}");
                            outcomes[0] += 1;
                        }
                        Curved::NoRoot => {
                            assert!(h0 < 0.0 && h1 < 0.0, "{s} {c} {e}: no root from ends {h0} {h1}");
                            assert!(first.is_none(), "{s} {c} {e}: missed {first:?}");
                            outcomes[1] += 1;
                        }
                        Curved::Undecided => {
                            assert!(h0 > 0.0 && h1 > 0.0, "{s} {c} {e}: undecided from ends {h0} {h1}");
                            outcomes[2] += 1;
                        }
                    }
                }
            }
        }
        assert!(outcomes.iter().all(|&n| n > 10), "{outcomes:?}");
    }
}
