//! Implicit combinators: Boolean set operations, smooth blend and offset (a user function Φ is
//! [`crate::Function`], in `function.rs`).
//!
//! | combinator            | Φ                                                   | ∇Φ (active branch)               |
//! |-----------------------|-----------------------------------------------------|----------------------------------|
//! | [`Csg`] `Union`       | `min Φᵢ`                                            | `∇Φᵢ` of the smallest            |
//! | [`Csg`] `Intersection`| `max Φᵢ`                                            | `∇Φᵢ` of the largest             |
//! | [`Csg`] `Difference`  | `max(Φ₀, −min_{i≥1} Φᵢ)` (first minus all others)   | `∇Φ₀` or `−∇Φᵢ`                  |
//! | [`SmoothUnion`]       | `min(a, b) − k·h²/4` with `h = max(k − |a − b|, 0)/k` (polynomial smooth minimum of radius `k`) | `w∇a + (1 − w)∇b`, `w = clamp(½ + (b − a)/(2k), 0, 1)` |
//! | [`Offset`]            | `Φ − r`                                             | `∇Φ`                             |
//!
//! Each keeps the sign convention (Φ < 0 inside) and a Lipschitz bound `max Lᵢ` when every child
//! declares one (min, max, negation and the polynomial smooth minimum do not increase it).
//!
//! **Intersection.** [`Csg`] does not root-find: it merges its children's boundary-crossing
//! streams ([`Intersect::crossings`], each computed once per ray and consumed lazily) in order of
//! `t`, tracking which children the ray is inside (entering where `dir · n < 0`, leaving where
//! `> 0`, tangent contacts ignored) with counters, and reports the crossings where the Boolean
//! combination changes. A nested [`Csg`] child offers its own merged stream, so a tree is walked
//! once per ray whatever its depth (the old re-query of children from each crossing doubled the
//! work per level). Children whose bounds the ray misses contribute only their state at the
//! start. Its `t` is therefore exactly a child's `t`, and its normal that child's normal (negated
//! for subtracted children), re-found in a window of a few ulps around `t` (for a nesting of
//! depth `d` that costs `O(d²)` per hit: load-time flattening of same-operation chains keeps `d`
//! small). [`SmoothUnion`] and [`Offset`] change the zero set itself, so they use the generic root
//! finder
//! ([`crate::root`]).

use crate::bounds::Aabb;
use crate::crossings::{step_past, Crossing, Crossings};
use crate::expr::{Jet, Scalar};
use crate::hit::RawHit;
use crate::math::enclosure::Enclosure;
use crate::proximity::{Closest, SignMethod};
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Primitive};
use glam::{DVec2, DVec3};
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;

/// Which Boolean combination a [`Csg`] node forms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CsgOp {
    /// Inside any child.
    Union,
    /// Inside every child.
    Intersection,
    /// Inside the first child and outside all others.
    Difference,
}

/// A Boolean combination of closed primitives.
#[derive(Clone, Debug)]
pub struct Csg {
    op: CsgOp,
    children: Vec<Arc<dyn Primitive>>,
    /// Each child's bounds, computed once (a nested child's bounds fold its whole subtree).
    child_bounds: Vec<Aabb>,
    bounds: Aabb,
}

impl Csg {
    /// `op` over `children` (at least one; a difference needs at least two to subtract anything).
    pub fn new(op: CsgOp, children: Vec<Arc<dyn Primitive>>) -> Result<Self, crate::PrimitiveError> {
        if children.is_empty() {
            return Err(crate::PrimitiveError::new(
                "Csg",
                "children",
                "needs at least one child",
            ));
        }
        let child_bounds: Vec<Aabb> = children.iter().map(|c| c.bounds()).collect();
        let mut boxes = child_bounds.iter().copied();
        let bounds = match op {
            CsgOp::Union => boxes.fold(Aabb::EMPTY, Aabb::union),
            CsgOp::Intersection => boxes.fold(Aabb::EVERYTHING, |a, b| Aabb::new(a.min.max(b.min), a.max.min(b.max))),
            CsgOp::Difference => boxes.next().unwrap_or(Aabb::EMPTY),
        };
        Ok(Self {
            op,
            children,
            child_bounds,
            bounds,
        })
    }

    /// The operation.
    #[must_use]
    pub fn op(&self) -> CsgOp {
        self.op
    }

    /// The operands, in order (for a difference, the first is the one subtracted from).
    #[must_use]
    pub fn children(&self) -> &[Arc<dyn Primitive>] {
        &self.children
    }

    /// `(child index, sign)` of the branch that determines Φ at `p`.
    fn active(&self, p: DVec3) -> (usize, f64) {
        let phis = self.children.iter().map(|c| c.phi(p));
        let arg = |better: fn(f64, f64) -> bool| {
            phis.clone().enumerate().fold(
                (0, f64::NAN),
                |(bi, bv), (i, v)| if i == 0 || better(v, bv) { (i, v) } else { (bi, bv) },
            )
        };
        match self.op {
            CsgOp::Union => (arg(|v, b| v < b).0, 1.0),
            CsgOp::Intersection => (arg(|v, b| v > b).0, 1.0),
            CsgOp::Difference => {
                let first = self.children[0].phi(p);
                let rest = self.children[1..]
                    .iter()
                    .map(|c| c.phi(p))
                    .enumerate()
                    .fold((0, f64::INFINITY), |b, (i, v)| if v < b.1 { (i + 1, v) } else { b });
                if first >= -rest.1 {
                    (0, 1.0)
                } else {
                    (rest.0, -1.0)
                }
            }
        }
    }

    fn sign_of(&self, child: usize) -> f64 {
        if self.op == CsgOp::Difference && child > 0 {
            -1.0
        } else {
            1.0
        }
    }

    /// The child's own raw hit at parameter `t` (re-found in a tight window around it).
    fn child_hit(&self, child: usize, ray: &Ray, t: f64) -> Option<RawHit> {
        let slack = step_past(t) - t;
        self.children[child].intersect(ray, Interval::new(t - slack, t + slack))
    }
}

/// Membership of a [`Csg`] from counts: how many children the ray is inside (for a difference,
/// how many of the subtracted ones) and whether it is inside the first.
#[derive(Clone, Copy, Debug)]
struct Membership {
    op: CsgOp,
    children: usize,
    inside_first: bool,
    /// Children inside (union, intersection) or subtracted children inside (difference).
    inside_count: usize,
}

impl Membership {
    fn new(op: CsgOp, inside: &[bool]) -> Self {
        let counted = if op == CsgOp::Difference { &inside[1..] } else { inside };
        Self {
            op,
            children: inside.len(),
            inside_first: inside[0],
            inside_count: counted.iter().filter(|&&b| b).count(),
        }
    }

    /// Records that the ray moved into (`inside`) or out of child `child`.
    fn set(&mut self, child: usize, inside: bool) {
        if child == 0 {
            self.inside_first = inside;
        }
        if child > 0 || self.op != CsgOp::Difference {
            if inside {
                self.inside_count += 1;
            } else {
                self.inside_count -= 1;
            }
        }
    }

    fn inside(&self) -> bool {
        match self.op {
            CsgOp::Union => self.inside_count > 0,
            CsgOp::Intersection => self.inside_count == self.children,
            CsgOp::Difference => self.inside_first && self.inside_count == 0,
        }
    }
}

/// `f64` ordered by [`f64::total_cmp`], for the merge heap.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ordered(f64);

impl Eq for Ordered {}

impl PartialOrd for Ordered {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ordered {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// The merge of a [`Csg`]'s children's crossing streams: yields the crossings where membership
/// of the combination changes, each child's stream advanced only as far as consumed.
struct MergedCrossings<'a> {
    streams: Vec<Crossings<'a>>,
    /// The next crossing of each child, also queued in `queue` by `(t, child)`.
    heads: Vec<Option<Crossing>>,
    queue: BinaryHeap<Reverse<(Ordered, usize)>>,
    inside: Vec<bool>,
    membership: Membership,
}

impl MergedCrossings<'_> {
    fn advance(&mut self, child: usize) {
        self.heads[child] = self.streams[child].next();
        if let Some(c) = self.heads[child] {
            self.queue.push(Reverse((Ordered(c.hit.t), child)));
        }
    }
}

impl Iterator for MergedCrossings<'_> {
    type Item = Crossing;

    fn next(&mut self) -> Option<Crossing> {
        loop {
            let Reverse((_, child)) = self.queue.pop()?;
            let crossing = self.heads[child].take()?;
            self.advance(child);
            let before = self.membership.inside();
            if self.inside[child] != crossing.inside_after {
                self.inside[child] = crossing.inside_after;
                self.membership.set(child, crossing.inside_after);
            }
            let after = self.membership.inside();
            if after != before {
                return Some(Crossing {
                    hit: RawHit::on_feature(crossing.hit.t, child as u32),
                    inside_after: after,
                });
            }
        }
    }
}

impl Implicit for Csg {
    fn phi(&self, p: DVec3) -> f64 {
        let mut phis = self.children.iter().map(|c| c.phi(p));
        match self.op {
            CsgOp::Union => phis.fold(f64::INFINITY, f64::min),
            CsgOp::Intersection => phis.fold(f64::NEG_INFINITY, f64::max),
            CsgOp::Difference => {
                let first = phis.next().unwrap_or(f64::INFINITY);
                first.max(-phis.fold(f64::INFINITY, f64::min))
            }
        }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let (child, sign) = self.active(p);
        sign * self.children[child].gradient(p)
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn lipschitz(&self) -> Option<f64> {
        self.children
            .iter()
            .map(|c| c.lipschitz())
            .try_fold(0.0f64, |m, l| l.map(|l| m.max(l)))
    }

    /// The combination's surface lies in the union of its children's surfaces, so the smallest
    /// of the children's lower bounds is a lower bound. A child's nearest point `qᵢ` lies on the
    /// combination's surface when the other children's signs at `qᵢ` make the membership change
    /// across child `i` ([`Csg::keeps_point`]); the nearest such point bounds the distance from
    /// above, and is the nearest point (exact) when no child's lower bound is below it. Where no
    /// child's nearest point is kept (a sphere's nearest part cut away), rays from `p` towards
    /// each `qᵢ` find points of the combination's surface, the nearest of which bounds the
    /// distance from above: the answer is then a guaranteed interval, not exact. `None` if a
    /// child cannot bound its distance.
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let answers = self
            .children
            .iter()
            .map(|c| c.closest(p))
            .collect::<Option<Vec<Closest>>>()?;
        let lower = answers.iter().map(|a| a.lower).fold(f64::INFINITY, f64::min);
        let mut best: Option<Closest> = None;
        for (i, a) in answers.iter().enumerate() {
            let Some(q) = a.point else { continue };
            if self.keeps_point(i, q) && best.is_none_or(|b| a.upper < b.upper) {
                best = Some(*a);
            }
        }
        if best.is_none() {
            for a in &answers {
                let Some(q) = a.point else { continue };
                let dir = q - p;
                if dir == DVec3::ZERO {
                    continue;
                }
                let ray = Ray::new(p, dir);
                if let Some(hit) = self.intersect(&ray, Interval::new(0.0, f64::INFINITY)) {
                    let point = ray.at(hit.t);
                    let upper = (point - p).length();
                    if best.is_none_or(|b| upper < b.upper) {
                        best = Some(Closest {
                            point: Some(point),
                            feature: hit.feature,
                            lower: 0.0,
                            upper,
                        });
                    }
                }
            }
        }
        Some(match best {
            Some(b) if b.is_exact() && b.upper <= lower => b,
            Some(b) => Closest {
                lower: lower.min(b.upper),
                ..b
            },
            None => Closest {
                point: None,
                feature: 0,
                lower,
                upper: f64::INFINITY,
            },
        })
    }

    /// Inside the combination by the children's own tests (`method` for meshes).
    fn contains(&self, p: DVec3, method: SignMethod) -> bool {
        let inside: Vec<bool> = self.children.iter().map(|c| c.contains(p, method)).collect();
        Membership::new(self.op, &inside).inside()
    }
}

impl Csg {
    /// Whether a point `q` of child `child`'s surface is a point of the combination's surface:
    /// the membership, with the other children's sides at `q` by the sign of their Φ, differs
    /// between just inside and just outside child `child`.
    fn keeps_point(&self, child: usize, q: DVec3) -> bool {
        let mut inside: Vec<bool> = self.children.iter().map(|c| c.phi(q) < 0.0).collect();
        inside[child] = true;
        let within = Membership::new(self.op, &inside).inside();
        inside[child] = false;
        within != Membership::new(self.op, &inside).inside()
    }
}

impl Intersect for Csg {
    /// The first crossing of [`Intersect::crossings`].
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        self.crossings(ray, range).next().map(|c| c.hit)
    }

    /// The largest of the children's.
    fn origin_rounding(&self, origin: DVec3) -> f64 {
        self.children
            .iter()
            .map(|c| c.origin_rounding(origin))
            .fold(0.0, f64::max)
    }

    /// The children's crossing streams merged in order of `t`. A child whose bounds the ray
    /// misses in `range` has no crossing there: only its state at the start counts, which is
    /// "outside" when the start lies outside its finite bounds (children are closed, their inside
    /// is within their bounds) and else the sign of its Φ.
    fn crossings<'a>(&'a self, ray: &Ray, range: Interval) -> Crossings<'a> {
        let mut streams: Vec<Crossings<'a>> = self
            .children
            .iter()
            .zip(&self.child_bounds)
            .map(|(child, bounds)| match bounds.clip(ray, range) {
                Some(_) => child.crossings(ray, range),
                // a closed child's inside lies within its bounds
                None if bounds.is_finite() && !bounds.contains(ray.at(range.min)) => Crossings::constant(false),
                None => Crossings::constant(child.phi(ray.at(range.min)) < 0.0),
            })
            .collect();
        let inside: Vec<bool> = streams.iter_mut().map(Crossings::starts_inside).collect();
        let membership = Membership::new(self.op, &inside);
        let mut merged = MergedCrossings {
            heads: vec![None; streams.len()],
            queue: BinaryHeap::with_capacity(streams.len()),
            streams,
            inside,
            membership,
        };
        for child in 0..merged.streams.len() {
            merged.advance(child);
        }
        Crossings::new(membership.inside(), merged)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        let child = raw.feature as usize;
        let n = match self.child_hit(child, ray, raw.t) {
            Some(hit) => self.children[child].normal_at(ray, &hit),
            None => self.children[child].gradient(ray.at(raw.t)).normalize_or_zero(),
        };
        self.sign_of(child) * n
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        let child = raw.feature as usize;
        self.child_hit(child, ray, raw.t)
            .and_then(|hit| self.children[child].uv_at(ray, &hit))
    }

    /// The bound of the child whose crossing this is.
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        let child = raw.feature as usize;
        let own = RawHit::at(raw.t);
        let hit = self.child_hit(child, ray, raw.t).unwrap_or(own);
        self.children[child].hit_error(ray, &hit)
    }
}

/// The polynomial smooth union of two primitives with blend radius `radius`.
#[derive(Clone, Debug)]
pub struct SmoothUnion {
    a: Arc<dyn Primitive>,
    b: Arc<dyn Primitive>,
    radius: f64,
}

impl SmoothUnion {
    /// Blends `a` and `b` over `radius > 0`.
    pub fn new(a: Arc<dyn Primitive>, b: Arc<dyn Primitive>, radius: f64) -> Result<Self, crate::PrimitiveError> {
        crate::error::require_positive("SmoothUnion", "radius", radius)?;
        Ok(Self { a, b, radius })
    }

    fn weight(&self, pa: f64, pb: f64) -> f64 {
        (0.5 + (pb - pa) / (2.0 * self.radius)).clamp(0.0, 1.0)
    }
}

impl Implicit for SmoothUnion {
    fn phi(&self, p: DVec3) -> f64 {
        let (pa, pb) = (self.a.phi(p), self.b.phi(p));
        let h = (self.radius - (pa - pb).abs()).max(0.0) / self.radius;
        pa.min(pb) - 0.25 * self.radius * h * h
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let w = self.weight(self.a.phi(p), self.b.phi(p));
        w * self.a.gradient(p) + (1.0 - w) * self.b.gradient(p)
    }

    /// Both children's bounds, grown by the radius (the blend adds at most `radius/4` to Φ's
    /// depression, which moves an SDF's surface by at most that much).
    fn bounds(&self) -> Aabb {
        self.a.bounds().union(self.b.bounds()).expanded(self.radius)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(self.a.lipschitz()?.max(self.b.lipschitz()?))
    }

    /// The blend evaluated on both children's enclosures (when both have them), so a smooth
    /// union of `Function`s gets the interval root isolation, with no Lipschitz bound.
    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        let (a, b) = (self.a.enclose_along(ray, segment)?, self.b.enclose_along(ray, segment)?);
        let k = Jet::constant(self.radius);
        let h = (k - (a - b).abs()).max(Jet::constant(0.0)) / k;
        Some(a.min(b) - Jet::constant(0.25) * k * h * h)
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        let (a, b) = (
            self.a.enclose_value_along(ray, segment)?,
            self.b.enclose_value_along(ray, segment)?,
        );
        let k = Enclosure::constant(self.radius);
        let h = (k - (a - b).abs()).max(Enclosure::constant(0.0)) / k;
        Some(a.min(b) - Enclosure::constant(0.25) * k * h * h)
    }
}

impl Intersect for SmoothUnion {}

/// A primitive grown (`distance > 0`) or shrunk (`< 0`) along its Φ: the zero set of `Φ − distance`.
#[derive(Clone, Debug)]
pub struct Offset {
    inner: Arc<dyn Primitive>,
    distance: f64,
}

impl Offset {
    /// Offsets `inner` by `distance` (finite).
    pub fn new(inner: Arc<dyn Primitive>, distance: f64) -> Result<Self, crate::PrimitiveError> {
        if !distance.is_finite() {
            return Err(crate::PrimitiveError::new(
                "Offset",
                "distance",
                format!("must be finite, got {distance}"),
            ));
        }
        Ok(Self { inner, distance })
    }
}

impl Implicit for Offset {
    fn phi(&self, p: DVec3) -> f64 {
        self.inner.phi(p) - self.distance
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.inner.gradient(p)
    }

    /// The inner bounds grown by `distance` (exact when Φ is a signed distance; a Φ growing more
    /// slowly than distance may reach further and is then clipped to these bounds).
    fn bounds(&self) -> Aabb {
        self.inner.bounds().expanded(self.distance.max(0.0))
    }

    fn lipschitz(&self) -> Option<f64> {
        self.inner.lipschitz()
    }

    /// The inner enclosure shifted by the distance (an offset `Function` keeps the interval root
    /// isolation).
    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        Some(self.inner.enclose_along(ray, segment)? - Jet::constant(self.distance))
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        Some(self.inner.enclose_value_along(ray, segment)? - Enclosure::constant(self.distance))
    }
}

impl Intersect for Offset {}
