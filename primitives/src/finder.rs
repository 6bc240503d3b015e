//! What the root finders share: their options ([`RootOptions`]), their report ([`RootReport`]),
//! the per-thread count of rays whose answer is uncertain, and the refinement of a sign-change
//! bracket. The finders themselves are [`crate::root`] (sampling / sphere tracing) and
//! [`crate::isolation`] (interval isolation); [`crate::root`] re-exports the public items.

use crate::hit::RawHit;

thread_local! {
    static THREAD_UNCERTAIN_EVENTS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Events on the calling thread that leave a ray's answer uncertain: this finder's budget
/// exhaustions ([`crate::root::budget_exhaustions`]) and the interval isolation's undecided cases
/// ([`crate::isolation::uncertain_counts`]). Read it before and after tracing one ray on a
/// thread to learn whether that ray's answer is uncertain.
#[inline]
#[must_use]
pub fn thread_uncertain_events() -> u64 {
    THREAD_UNCERTAIN_EVENTS.with(std::cell::Cell::get)
}

/// Runs `f` and says whether an uncertain event ([`thread_uncertain_events`]) happened on the
/// calling thread meanwhile: whether the answer `f` traced is uncertain.
#[inline]
pub fn uncertain_while<T>(f: impl FnOnce() -> T) -> (T, bool) {
    let before = thread_uncertain_events();
    let value = f();
    (value, thread_uncertain_events() != before)
}

/// Counts one uncertain event on the calling thread (see [`thread_uncertain_events`]).
pub(crate) fn note_uncertain_on_thread() {
    THREAD_UNCERTAIN_EVENTS.with(|c| c.set(c.get() + 1));
}

/// Tolerances of the generic root finder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RootOptions {
    /// Width, in units of `t`, to which the bracket around a root is refined; also the smallest
    /// sphere-tracing step. The default is `1e-7`.
    pub tolerance: f64,
    /// Number of uniform samples over the clipped interval when the type declares no Lipschitz
    /// bound. The default is 512.
    pub samples: u32,
    /// Most Φ evaluations spent on one ray before giving up (a miss; for interval isolation a
    /// miss counted as exhausted, see [`crate::isolation::uncertain_counts`]). The default is
    /// 100,000.
    pub max_evaluations: u32,
}

impl Default for RootOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            samples: 512,
            max_evaluations: 100_000,
        }
    }
}

impl RootOptions {
    /// The defaults with another tolerance.
    #[must_use]
    pub fn with_tolerance(tolerance: f64) -> Self {
        Self {
            tolerance,
            ..Self::default()
        }
    }
}

/// What the root finder found along one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RootReport {
    /// The first root in the interval, if any.
    pub hit: Option<RawHit>,
    /// Whether Φ was seen to change faster than the declared Lipschitz bound.
    pub lipschitz_violated: bool,
    /// Φ evaluations spent (for interval isolation: enclosures and point values).
    pub evaluations: u32,
    /// Whether the interval root finder ([`crate::isolation`]) could not decide this ray exactly:
    /// the hit is a touch within the tolerance (tangent, double root), or the budget ran out.
    pub uncertain: bool,
}

/// Refines a bracket `[a, b]` with `g(a)`, `g(b)` of opposite signs to a width `tolerance` by the
/// Illinois variant of regula falsi: each trial point is kept at least `tolerance / 2` inside the
/// bracket (so that once the estimate is within that of an end, the next value closes the
/// bracket), and the bracket is bisected after two steps in a row that failed to halve it; also
/// stops where no f64 lies strictly between `a` and `b`. Returns the end with the smaller `|g|`
/// (or a point where `g` is exactly 0).
pub(crate) fn refine_bracket(
    mut g: impl FnMut(f64) -> f64,
    (mut a, mut ga): (f64, f64),
    (mut b, mut gb): (f64, f64),
    tolerance: f64,
) -> f64 {
    let mut side = 0i8;
    let mut width = b - a;
    let mut slow_steps = 0;
    let step = 0.5 * tolerance;
    while b - a > tolerance && 0.5 * (a + b) > a && 0.5 * (a + b) < b {
        // secant point, kept strictly inside and half a tolerance from either end
        let mut t = (a * gb - b * ga) / (gb - ga);
        if !(t > a && t < b) {
            t = 0.5 * (a + b);
        }
        if t - a < step {
            t = a + step;
        } else if b - t < step {
            t = b - step;
        }
        if !(t > a && t < b) {
            t = 0.5 * (a + b);
        }
        let gt = g(t);
        if gt == 0.0 {
            return t;
        }
        if (gt < 0.0) == (ga < 0.0) {
            a = t;
            ga = gt;
            if side == -1 {
                gb *= 0.5;
            }
            side = -1;
        } else {
            b = t;
            gb = gt;
            if side == 1 {
                ga *= 0.5;
            }
            side = 1;
        }
        // bisect if the secant made poor progress twice in a row
        if b - a > 0.5 * width {
            slow_steps += 1;
        } else {
            slow_steps = 0;
        }
        if slow_steps >= 2 && b - a > tolerance {
            let m = 0.5 * (a + b);
            let gm = g(m);
            if gm == 0.0 {
                return m;
            }
            if (gm < 0.0) == (ga < 0.0) {
                a = m;
                ga = gm;
            } else {
                b = m;
                gb = gm;
            }
            side = 0;
            slow_steps = 0;
        }
        width = b - a;
    }
    if ga.abs() <= gb.abs() {
        a
    } else {
        b
    }
}
