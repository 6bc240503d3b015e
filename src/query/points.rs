//! Point queries on a loaded [`Scene`]: Φ and ∇Φ, the nearest surface point, distance, signed
//! distance and occupancy, answered by the objects' own [`Implicit::closest`](zeroset_primitives::Implicit::closest) and
//! [`Implicit::contains`](zeroset_primitives::Implicit::contains) (see [`zeroset_primitives::proximity`]).
//!
//! **What the scene's answers mean.** The scene is the set of its objects' surfaces, as for
//! Open3D's `RaycastingScene`:
//! - Φ is the smallest of the objects' Φ (the union's), ∇Φ that object's gradient;
//! - the nearest point is the nearest point of any object's surface, found nearest box first
//!   through the scene's hierarchy (objects whose box lies farther than the best distance so far
//!   are not asked);
//! - a point is inside (occupancy 1) when it is inside any object by the chosen [`SignMethod`];
//! - signed distance is the distance, negated inside.
//!
//! Moving objects answer as placed at frame time 0 (as `Scene::intersect` does). Distances are
//! exact (f64, to rounding) where every object near the point is exact; otherwise the answer is
//! a guaranteed interval `[lower, upper]` ([`Closest`]), never a Φ value. An object that cannot
//! bound its distance at all (a user type without [`Implicit::closest`](zeroset_primitives::Implicit::closest), an unbounded smooth
//! union) makes the query an error naming it ([`PointQueryError`]).

use crate::scene::Scene;
use glam::DVec3;
use zeroset_primitives::{Closest, SignMethod};

/// The nearest surface point of a scene: the object holding it and the object's answer, whose
/// bounds cover every object (`lower` is the smallest lower bound over the objects that could be
/// nearer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneClosest {
    /// Index of the object holding `closest.point`.
    pub object: u32,
    /// The point, its primitive part and the bounds on the distance to the scene.
    pub closest: Closest,
}

/// A point query the scene cannot answer.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PointQueryError {
    /// An object whose type cannot bound the distance to its surface.
    #[error("objects[{index}]{name}: its primitive cannot bound the distance to its surface (no closest-point query); distance queries need every object to answer one")]
    NoDistance {
        /// The object's index.
        index: u32,
        /// ` "name"`, or empty.
        name: String,
    },
    /// The scene has no objects.
    #[error("the scene has no objects: no surface to measure a distance to")]
    Empty,
    /// A query point with a NaN or infinite coordinate.
    #[error("point {0}: coordinates must be finite")]
    NotFinite(String),
}

impl Scene {
    /// Φ of the scene at `p`: the smallest of its objects' Φ (`+∞` for a scene of no objects).
    #[must_use]
    pub fn phi(&self, p: DVec3) -> f64 {
        self.objects
            .iter()
            .map(|o| o.primitive.phi(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// ∇Φ of the scene at `p`: the gradient of the object of smallest Φ (zero for no objects).
    #[must_use]
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        self.phi_and_gradient(p).1
    }

    /// [`Scene::phi`] and [`Scene::gradient`] at `p` together, each object's Φ evaluated once.
    #[must_use]
    pub fn phi_and_gradient(&self, p: DVec3) -> (f64, DVec3) {
        let mut smallest = f64::INFINITY;
        let mut best = (f64::INFINITY, None);
        for o in &self.objects {
            let phi = o.primitive.phi(p);
            smallest = smallest.min(phi);
            if phi < best.0 || best.1.is_none() {
                best = (phi, Some(o));
            }
        }
        (smallest, best.1.map_or(DVec3::ZERO, |o| o.primitive.gradient(p)))
    }

    /// Whether `p` lies inside any object, by `method` (see [`SignMethod`]).
    #[must_use]
    pub fn contains(&self, p: DVec3, method: SignMethod) -> bool {
        self.objects.iter().any(|o| o.primitive.contains(p, method))
    }

    /// The nearest point of any object's surface to `p` (see the module docs).
    ///
    /// # Errors
    /// A point that is not finite, a scene of no objects, or an object that cannot bound its
    /// distance.
    pub fn closest_point(&self, p: DVec3) -> Result<SceneClosest, PointQueryError> {
        if !p.is_finite() {
            return Err(PointQueryError::NotFinite(format!("({}, {}, {})", p.x, p.y, p.z)));
        }
        if self.objects.is_empty() {
            return Err(PointQueryError::Empty);
        }
        let mut best: Option<SceneClosest> = None;
        let mut lower = f64::INFINITY;
        let mut failed = None;
        let mut visit = |id: u32| -> f64 {
            let Some(answer) = self.objects[id as usize].primitive.closest(p) else {
                failed.get_or_insert(id);
                return f64::INFINITY;
            };
            lower = lower.min(answer.lower);
            let better = best
                .is_none_or(|b| answer.upper < b.closest.upper || (answer.upper == b.closest.upper && id < b.object));
            if better {
                best = Some(SceneClosest {
                    object: id,
                    closest: answer,
                });
            }
            best.map_or(f64::INFINITY, |b| b.closest.upper)
        };
        for &id in &self.hierarchy.unbounded {
            visit(id);
        }
        self.hierarchy.bvh.nearest(p, |id, _| visit(id));
        if let Some(id) = failed {
            return Err(self.no_distance(id));
        }
        let mut found = best.ok_or(PointQueryError::Empty)?;
        found.closest.lower = lower.min(found.closest.upper);
        Ok(found)
    }

    /// The signed distance at `p` as bounds `(lower, upper)`, negative inside by `method`: the
    /// distance's bounds, negated and swapped inside. Equal bounds where the distance is exact.
    ///
    /// # Errors
    /// As [`Scene::closest_point`].
    pub fn signed_distance(&self, p: DVec3, method: SignMethod) -> Result<(f64, f64), PointQueryError> {
        let c = self.closest_point(p)?.closest;
        Ok(if self.contains(p, method) {
            (-c.upper, -c.lower)
        } else {
            (c.lower, c.upper)
        })
    }

    fn no_distance(&self, id: u32) -> PointQueryError {
        PointQueryError::NoDistance {
            index: id,
            name: self.objects[id as usize]
                .name
                .as_deref()
                .map_or(String::new(), |n| format!(" \"{n}\"")),
        }
    }
}
