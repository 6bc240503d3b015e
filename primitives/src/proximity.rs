//! Point queries: the surface point nearest to a point, the distance to it, and inside / outside.
//!
//! Every primitive answers them beside its Φ, in its own file, through two methods of
//! [`crate::Implicit`]:
//! - [`Implicit::closest`](crate::Implicit::closest) gives a [`Closest`]: the nearest surface
//!   point and its distance, exact (to rounding in f64) for the closed forms, meshes and
//!   transforms by rigid motions and uniform scales; a guaranteed interval `[lower, upper]` on
//!   the distance where exactness cannot be had (a general affine map, CSG, an expression). A Φ
//!   value is never presented as a distance: a type that cannot bound the distance answers
//!   `None` (the default).
//! - [`Implicit::contains`](crate::Implicit::contains) says whether a point lies inside the
//!   solid, by a [`SignMethod`] where the type offers a choice (a mesh); analytic solids use the
//!   sign of Φ whatever the method.
//!
//! Signed distance is the distance times the sign of `contains` (negative inside, as Φ);
//! occupancy is `contains` alone and needs no distance.

use glam::DVec3;

/// The answer to "where is the surface nearest to `p`": a surface point and bounds on the
/// distance `d(p) = min over surface points q of |p − q|`.
///
/// Invariants: `0 ≤ lower ≤ upper`; where `point` is `Some(q)`, `q` lies on the surface (to the
/// rounding of the type's arithmetic) and `upper = |p − q|`, so `q` witnesses the upper bound;
/// `lower` is a guaranteed lower bound. [`Closest::is_exact`] (`lower == upper`) means `point` is
/// the nearest point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// A surface point at distance `upper` from the query point: the nearest one when exact.
    /// `None` only when an interval search found no surface point within its budget (then
    /// `upper` is `+∞`).
    pub point: Option<DVec3>,
    /// The part of the primitive `point` lies on, numbered as [`crate::RawHit::feature`] (a
    /// mesh's triangle, a box's face); 0 where unused.
    pub feature: u32,
    /// A guaranteed lower bound on the distance.
    pub lower: f64,
    /// A guaranteed upper bound on the distance (`|p − point|`).
    pub upper: f64,
}

impl Closest {
    /// The nearest point `q` of the surface to `p`, on part `feature`: `lower = upper = |p − q|`.
    #[must_use]
    pub fn exact(p: DVec3, q: DVec3, feature: u32) -> Self {
        let d = (p - q).length();
        Self {
            point: Some(q),
            feature,
            lower: d,
            upper: d,
        }
    }

    /// Whether the distance is known exactly (and `point` is the nearest point).
    #[must_use]
    pub fn is_exact(&self) -> bool {
        self.lower == self.upper
    }

    /// The distance where exact, the upper bound otherwise (a distance reached by `point`).
    #[must_use]
    pub fn distance(&self) -> f64 {
        self.upper
    }

    /// Bounds scaled by `factor_lower` and `factor_upper` (both ≥ 0) and the point mapped by `map`:
    /// the answer of a transformed surface whose map stretches distances by a factor between the
    /// two. Exact stays exact where the factors are equal (a similarity).
    #[must_use]
    pub fn mapped(self, map: impl Fn(DVec3) -> DVec3, query: DVec3, factor_lower: f64, factor_upper: f64) -> Self {
        let point = self.point.map(&map);
        if factor_lower == factor_upper && self.is_exact() {
            if let Some(q) = point {
                return Self::exact(query, q, self.feature);
            }
        }
        let upper = point.map_or(self.upper * factor_upper, |q| (query - q).length());
        Self {
            point,
            feature: self.feature,
            lower: (self.lower * factor_lower).min(upper),
            upper,
        }
    }
}

/// How a mesh decides inside from outside (for [`crate::Implicit::contains`]); analytic solids
/// use the sign of Φ whatever the method.
///
/// | method | inside when | right on | fails on |
/// |---|---|---|---|
/// | `Winding` | `|w(p)| > ½`, `w` the exact generalized winding number (Jacobson et al. 2013) | open meshes, holes, duplicated or inner faces, wholly flipped orientation | inconsistently oriented faces |
/// | `FastWinding` (default) | the same with `w` by the hierarchy's dipole expansion (Barill et al. 2018), exact sums for nearby boxes | as `Winding`, error below `3·10⁻³` at β = 2 (second-order expansion) | as `Winding`, and points whose `w` is within its error of `½` |
/// | `PseudoNormal` | the angle-weighted pseudo-normal at the nearest feature points away (Bærentzen & Aanæs 2005) | closed, consistently oriented, manifold meshes | open meshes, duplicated faces, flipped orientation |
/// | `Parity` | an odd number of crossings along a ray, each counted once at shared edges, re-cast when a ray grazes an edge | closed meshes of any orientation | open meshes, duplicated (coincident) faces, self-intersections |
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SignMethod {
    /// The exact generalized winding number.
    Winding,
    /// The hierarchical (fast) winding number.
    #[default]
    FastWinding,
    /// The angle-weighted pseudo-normal of the nearest point.
    PseudoNormal,
    /// Ray parity.
    Parity,
}

impl SignMethod {
    /// Every method, in the order of the table above.
    pub const ALL: [Self; 4] = [Self::Winding, Self::FastWinding, Self::PseudoNormal, Self::Parity];

    /// The method's name on the command line and in Python: `winding`, `fast-winding`,
    /// `pseudonormal`, `parity`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Winding => "winding",
            Self::FastWinding => "fast-winding",
            Self::PseudoNormal => "pseudonormal",
            Self::Parity => "parity",
        }
    }

    /// The method named `name` (see [`SignMethod::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

impl std::str::FromStr for SignMethod {
    type Err = String;

    /// The method of [`SignMethod::name`] `name`; otherwise an error listing the names.
    fn from_str(name: &str) -> Result<Self, String> {
        Self::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|m| m.name()).collect();
            format!("unknown sign method `{name}`; one of {}", names.join(", "))
        })
    }
}
