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
//! **Intersection.** [`Csg`] does not root-find: it walks the children's own (closed-form)
//! boundary crossings along the ray in order, tracking which children the ray is inside
//! (entering where `dir · n < 0`, leaving where `> 0`, tangent contacts ignored), and reports the
//! first crossing where the Boolean combination changes. Its `t` is therefore exactly a child's
//! `t`, and its normal that child's normal (negated for subtracted children). [`SmoothUnion`] and
//! [`Offset`] change the zero set itself, so they use the generic root finder
//! ([`crate::root`]).

use crate::bounds::Aabb;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Primitive};
use glam::{DVec2, DVec3};
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
        Ok(Self { op, children })
    }

    /// The operation.
    #[must_use]
    pub fn op(&self) -> CsgOp {
        self.op
    }

    fn combine(&self, inside: impl Fn(usize) -> bool) -> bool {
        let n = self.children.len();
        match self.op {
            CsgOp::Union => (0..n).any(inside),
            CsgOp::Intersection => (0..n).all(inside),
            CsgOp::Difference => inside(0) && !(1..n).any(inside),
        }
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

/// The smallest parameter after `t` at which the next crossing is searched: `t` plus a relative
/// step of 2⁻⁴⁰ (crossings closer than that are merged).
fn step_past(t: f64) -> f64 {
    t + (t.abs().max(f64::MIN_POSITIVE.sqrt())) * (2.0f64).powi(-40)
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
        let mut boxes = self.children.iter().map(|c| c.bounds());
        match self.op {
            CsgOp::Union => boxes.fold(Aabb::EMPTY, Aabb::union),
            CsgOp::Intersection => boxes.fold(Aabb::EVERYTHING, |a, b| Aabb::new(a.min.max(b.min), a.max.min(b.max))),
            CsgOp::Difference => boxes.next().unwrap_or(Aabb::EMPTY),
        }
    }

    fn lipschitz(&self) -> Option<f64> {
        self.children
            .iter()
            .map(|c| c.lipschitz())
            .try_fold(0.0f64, |m, l| l.map(|l| m.max(l)))
    }
}

impl Intersect for Csg {
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        let start = ray.at(range.min);
        let mut inside: Vec<bool> = self.children.iter().map(|c| c.phi(start) < 0.0).collect();
        let mut state = self.combine(|i| inside[i]);
        let mut next: Vec<Option<RawHit>> = self.children.iter().map(|c| c.intersect(ray, range)).collect();
        // per child, the step taken past its last hit: it doubles while the child keeps
        // reporting tangential contacts (`dir · n = 0`), so a ray lying in a face plane (a
        // contact segment, reported at every `t_min`) is left in at most ~2,100 steps instead
        // of one ulp at a time
        let mut steps: Vec<f64> = vec![0.0; self.children.len()];
        loop {
            let (child, hit) = next
                .iter()
                .enumerate()
                .filter_map(|(i, h)| h.map(|h| (i, h)))
                .min_by(|a, b| a.1.t.total_cmp(&b.1.t))?;
            let facing = ray.dir.dot(self.children[child].normal_at(ray, &hit));
            if facing != 0.0 {
                inside[child] = facing < 0.0;
                let new_state = self.combine(|i| inside[i]);
                if new_state != state {
                    return Some(RawHit {
                        t: hit.t,
                        feature: child as u32,
                        local: DVec2::ZERO,
                    });
                }
                state = new_state;
            }
            let mut after = step_past(hit.t);
            if facing == 0.0 {
                steps[child] = (2.0 * steps[child]).max(after - hit.t);
                after = hit.t + steps[child];
            } else {
                steps[child] = 0.0;
            }
            next[child] = if after.is_finite() && after > hit.t && after <= range.max {
                self.children[child].intersect(ray, Interval::new(after, range.max))
            } else {
                None
            };
        }
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
}

impl Intersect for Offset {}
