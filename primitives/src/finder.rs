//! What the root finders share: their options ([`RootOptions`]), their report ([`RootReport`]),
//! the per-thread count of rays whose answer is uncertain, and the refinement of a sign-change
//! bracket. The finders themselves are [`crate::root`] (sampling / sphere tracing) and
//! [`crate::isolation`] (interval isolation); [`crate::root`] re-exports the public items.

use crate::hit::RawHit;

thread_local! {
    static THREAD_UNCERTAIN_EVENTS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    /// Whether the rays traced now on this thread were counted already ([`traced_again`]).
    static TRACED_AGAIN: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`, which traces again rays whose outcomes were counted already (a packet traced ray
/// by ray to tell which of its rays is uncertain): the per-thread events
/// ([`thread_uncertain_events`]) still move, the process-wide counts
/// ([`crate::root::budget_exhaustions`], [`crate::isolation::uncertain_counts`], Lipschitz
/// violations) do not, so that each ray is counted once.
pub fn traced_again<T>(f: impl FnOnce() -> T) -> T {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            TRACED_AGAIN.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(TRACED_AGAIN.with(|c| c.replace(true)));
    f()
}

/// Whether a ray's outcome counts process-wide: not inside [`traced_again`].
#[inline]
pub(crate) fn counts_process_wide() -> bool {
    !TRACED_AGAIN.with(std::cell::Cell::get)
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
pub(crate) fn refine_bracket(mut g: impl FnMut(f64) -> f64, a: (f64, f64), b: (f64, f64), tolerance: f64) -> f64 {
    Refinement::new(a, b, tolerance).run(&mut g)
}

/// [`refine_bracket`] one step at a time, for callers that evaluate many rays' points together:
/// [`Refinement::next_point`] names the point whose value [`Refinement::take`] wants, until it
/// returns `None` and [`Refinement::root`] is the result (the same points and result as
/// [`refine_bracket`], which runs it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Refinement {
    a: f64,
    ga: f64,
    b: f64,
    gb: f64,
    tolerance: f64,
    /// Which end moved last (−1: `a`, 1: `b`, 0: after a bisection), for the Illinois halving.
    side: i8,
    /// The bracket's width before the last step.
    width: f64,
    slow_steps: u8,
    /// The point asked for, and whether it is a bisection's midpoint.
    pending: Option<(f64, bool)>,
    /// A point where `g` is exactly 0.
    zero: Option<f64>,
}

impl Refinement {
    /// The refinement of the bracket `(a, g(a))`, `(b, g(b))` (values of opposite signs).
    pub(crate) fn new((a, ga): (f64, f64), (b, gb): (f64, f64), tolerance: f64) -> Self {
        let mut refinement = Self {
            a,
            ga,
            b,
            gb,
            tolerance,
            side: 0,
            width: b - a,
            slow_steps: 0,
            pending: None,
            zero: None,
        };
        refinement.pending = refinement.secant_point().map(|t| (t, false));
        refinement
    }

    /// The next secant point, or `None` when the bracket is refined.
    fn secant_point(&self) -> Option<f64> {
        let (a, b, ga, gb) = (self.a, self.b, self.ga, self.gb);
        if !(b - a > self.tolerance && 0.5 * (a + b) > a && 0.5 * (a + b) < b) {
            return None;
        }
        // secant point, kept strictly inside and half a tolerance from either end
        let step = 0.5 * self.tolerance;
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
        Some(t)
    }

    /// Runs the refinement to its end with `g` at each point asked for; returns
    /// [`Refinement::root`].
    pub(crate) fn run(mut self, mut g: impl FnMut(f64) -> f64) -> f64 {
        while let Some(t) = self.next_point() {
            self.take(g(t));
        }
        self.root()
    }

    /// The point whose value is wanted next (`None`: done).
    #[inline]
    pub(crate) fn next_point(&self) -> Option<f64> {
        self.pending.map(|(t, _)| t)
    }

    /// Takes `g` at [`Refinement::next_point`].
    pub(crate) fn take(&mut self, gt: f64) {
        let Some((t, bisection)) = self.pending.take() else {
            return;
        };
        if gt == 0.0 {
            self.zero = Some(t);
            return;
        }
        if bisection {
            if (gt < 0.0) == (self.ga < 0.0) {
                (self.a, self.ga) = (t, gt);
            } else {
                (self.b, self.gb) = (t, gt);
            }
            self.side = 0;
            self.slow_steps = 0;
        } else {
            if (gt < 0.0) == (self.ga < 0.0) {
                (self.a, self.ga) = (t, gt);
                if self.side == -1 {
                    self.gb *= 0.5;
                }
                self.side = -1;
            } else {
                (self.b, self.gb) = (t, gt);
                if self.side == 1 {
                    self.ga *= 0.5;
                }
                self.side = 1;
            }
            // bisect if the secant made poor progress twice in a row
            if self.b - self.a > 0.5 * self.width {
                self.slow_steps += 1;
            } else {
                self.slow_steps = 0;
            }
            if self.slow_steps >= 2 && self.b - self.a > self.tolerance {
                self.pending = Some((0.5 * (self.a + self.b), true));
                return;
            }
        }
        self.width = self.b - self.a;
        self.pending = self.secant_point().map(|t| (t, false));
    }

    /// The result once [`Refinement::next_point`] is `None`: a point where `g` is 0, else the
    /// end with the smaller `|g|`.
    pub(crate) fn root(&self) -> f64 {
        match self.zero {
            Some(t) => t,
            None if self.ga.abs() <= self.gb.abs() => self.a,
            None => self.b,
        }
    }
}
