//! Boundary crossings along a ray: the span lists CSG evaluates.
//!
//! A ray meets a closed primitive's boundary at a sequence of parameters `t₁ < t₂ < …`; at each
//! the ray enters (`dir · n < 0`) or leaves (`dir · n > 0`) the set `Φ < 0`. [`Crossings`] gives
//! whether the ray starts inside (at `range.min`) and then those crossings, **lazily** and in
//! increasing `t`, so a consumer that stops at the first interesting one pays for no more.
//!
//! Any primitive has them through [`crate::Intersect::crossings`]'s default, [`crate::traits::repeated_intersection`]:
//! the first hit, then the first hit a small relative step past it, and so on. Tangential contacts
//! (`dir · n = 0`) change nothing and are skipped. [`crate::Csg`] overrides it by merging its
//! children's streams, so each child is walked once per ray whatever the nesting depth.

use crate::hit::RawHit;

/// One boundary crossing: the primitive's own raw hit and which side the ray is on after it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// The hit, as [`crate::Intersect::intersect`] would return it (pass it to `normal_at`, `uv_at`).
    pub hit: RawHit,
    /// Whether the ray is inside (`Φ < 0`) just after the crossing.
    pub inside_after: bool,
}

/// The crossings of one primitive along one ray, in increasing `t`.
pub struct Crossings<'a> {
    start: Start<'a>,
    rest: Rest<'a>,
}

/// Whether a stream starts inside: known, or worked out when first asked.
enum Start<'a> {
    Known(bool),
    Later(Box<dyn FnOnce() -> bool + 'a>),
    /// `surface.inside(point)`, asked without a closure to box.
    Point(&'a dyn InsideTest, glam::DVec3),
}

/// The crossings after the start: a list made at once (no allocation where it is empty), or
/// any iterator.
enum Rest<'a> {
    Listed(std::vec::IntoIter<Crossing>),
    Lazy(Box<dyn Iterator<Item = Crossing> + 'a>),
}

/// An inside test a stream can defer ([`Crossings::listed`]): whether `p` is inside the solid.
pub trait InsideTest {
    /// Whether `p` is inside.
    fn inside(&self, p: glam::DVec3) -> bool;
}

impl<'a> Crossings<'a> {
    /// A stream that starts inside or outside and then yields `rest` (which must be sorted by `t`).
    pub fn new(starts_inside: bool, rest: impl Iterator<Item = Crossing> + 'a) -> Self {
        Self {
            start: Start::Known(starts_inside),
            rest: Rest::Lazy(Box::new(rest)),
        }
    }

    /// The crossings `list` (sorted by `t`), with whether the ray starts inside worked out as
    /// `surface.inside(start)` only if someone asks ([`Crossings::starts_inside`]). Nothing is
    /// allocated beyond the list itself (none where it is empty).
    pub fn listed(surface: &'a dyn InsideTest, start: glam::DVec3, list: Vec<Crossing>) -> Self {
        Self {
            start: Start::Point(surface, start),
            rest: Rest::Listed(list.into_iter()),
        }
    }

    /// [`Crossings::new`] with whether the ray starts inside worked out by `starts_inside` only
    /// if someone asks ([`Crossings::starts_inside`]): a consumer that wants the crossings alone
    /// (every hit along a ray) does not pay for it.
    pub fn with_lazy_start(
        starts_inside: impl FnOnce() -> bool + 'a,
        rest: impl Iterator<Item = Crossing> + 'a,
    ) -> Self {
        Self {
            start: Start::Later(Box::new(starts_inside)),
            rest: Rest::Lazy(Box::new(rest)),
        }
    }

    /// No crossing at all: the state at the start holds along the whole range.
    #[must_use]
    pub fn constant(inside: bool) -> Self {
        Self::new(inside, std::iter::empty())
    }

    /// Whether the ray starts inside (`Φ(ray.at(range.min)) < 0`, or the primitive's own
    /// inside test where it states one).
    pub fn starts_inside(&mut self) -> bool {
        let inside = match std::mem::replace(&mut self.start, Start::Known(false)) {
            Start::Known(inside) => inside,
            Start::Later(decide) => decide(),
            Start::Point(surface, point) => surface.inside(point),
        };
        self.start = Start::Known(inside);
        inside
    }
}

impl std::fmt::Debug for Crossings<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let start = match self.start {
            Start::Known(inside) => Some(inside),
            Start::Later(_) | Start::Point(..) => None,
        };
        f.debug_struct("Crossings")
            .field("starts_inside", &start)
            .finish_non_exhaustive()
    }
}

impl Iterator for Crossings<'_> {
    type Item = Crossing;

    fn next(&mut self) -> Option<Crossing> {
        match &mut self.rest {
            Rest::Listed(list) => list.next(),
            Rest::Lazy(rest) => rest.next(),
        }
    }
}

/// The smallest parameter after `t` at which the next crossing is searched: `t` plus a relative
/// step of 2⁻⁴⁰ (crossings closer than that are merged).
#[must_use]
pub fn step_past(t: f64) -> f64 {
    t + (t.abs().max(f64::MIN_POSITIVE.sqrt())) * (2.0f64).powi(-40)
}
