//! Axis-aligned box (`Box` in scene files; `Cuboid` in Rust, to keep clear of `std::boxed::Box`).
//!
//! | field | meaning        | constraint                              |
//! |-------|----------------|-----------------------------------------|
//! | `min` | lower corner   | finite                                  |
//! | `max` | upper corner   | finite, `min < max` in every component  |
//!
//! - **Faces**, in this order (the [`RawHit::feature`] of a hit and `⌊u⌋` of the parametric form):
//!   `0: −X, 1: +X, 2: −Y, 3: +Y, 4: −Z, 5: +Z`; face `2i + s` lies on axis `i`, `s = 1` the upper.
//! - **Φ(p)**, the exact signed distance: with the per-axis slab distances
//!   `dᵢ = max(minᵢ − pᵢ, pᵢ − maxᵢ)` (exact for a point on a face plane, no centre/half-size
//!   rounding), `Φ = |max(d, 0)| + min(maxᵢ dᵢ, 0)`. Lipschitz bound 1.
//! - **∇Φ**, analytic: outside, `max(d, 0)` with each component signed towards its face side,
//!   normalised (the direction from the nearest box point); inside or on the surface, the normal
//!   of the face with the largest `dᵢ` (the nearest face; ties go to the lower axis).
//! - **Parametric form**: `u ∈ [0, 6]`, `v ∈ [0, 1]`; `⌊u⌋` is the face (`u = 6` is face 5) and
//!   `(u − ⌊u⌋, v)` are coordinates on it, linear from `min` to `max`. With `(i, j, k)` the axes in
//!   cyclic order, an upper face runs `u` along `j` and `v` along `k`, a lower face `u` along `k`
//!   and `v` along `j`, so `∂p/∂u × ∂p/∂v` points outward. Seams at every edge. `uv(p)` takes
//!   the face of the largest `dᵢ`, as the gradient does.
//! - **Intersection**: slab test by division, `tᵢ = (boundᵢ − oᵢ) / dᵢ`, for non-zero `dᵢ` only, so
//!   no `0·∞` NaN arises; the entry face is the one that raised `t_near` last (strictly, so an edge
//!   or corner hit gets the face of the lowest axis among the tied ones), and the hit's normal
//!   is that face's normal, exact. A direction component of `±0` leaves that slab unconstrained
//!   if `minᵢ ≤ oᵢ ≤ maxᵢ` and misses otherwise: the box is closed, so **a ray lying in a face
//!   plane touches the box**; it hits where it enters the closed face (an edge, reported with
//!   the face it crossed there), and a ray that already lies on the face at `t_min` hits where
//!   it leaves it, the far edge (with the face it crosses there): the answer a ray nudged into
//!   the box would give, whatever `t_min` is (answering `t_min` itself gave `t = 5·10⁻³²⁴` for an
//!   open range starting at 0, which flipped under any perturbation).
//!   Returns the entry `t_near` if it is in the query interval, else the exit `t_far`.
//! - **Closest point**: outside or on the surface (some `dᵢ ≥ 0`), `p` clamped to the box,
//!   `qᵢ = clamp(pᵢ, minᵢ, maxᵢ)`, at distance `|max(d, 0)|` (the box is convex; clamping is the
//!   projection onto a product of intervals). Inside (every `dᵢ < 0`), the foot on the nearest
//!   face: `p` with the coordinate of the axis of the largest `dᵢ` replaced by that face's bound,
//!   at distance `−maxᵢ dᵢ` (any point of another face is at least its own `−dⱼ` away). Exact:
//!   the point copies `p`'s coordinates and the box's bounds, no arithmetic. The feature is the
//!   face of the largest `dᵢ` (as the gradient's, ties to the lower axis): the face `q` lies on
//!   (outside, the face across whose plane `p` is farthest).

use crate::bounds::Aabb;
use crate::error::{require_finite, PrimitiveError};
use crate::hit::RawHit;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};

/// The axis-aligned box `min ≤ p ≤ max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    min: DVec3,
    max: DVec3,
}

impl Cuboid {
    /// The box with corners `min` and `max`; errors unless both are finite and `min < max` in
    /// every component.
    pub fn new(min: DVec3, max: DVec3) -> Result<Self, PrimitiveError> {
        let min = require_finite("Cuboid", "min", min)?;
        let max = require_finite("Cuboid", "max", max)?;
        if !min.cmplt(max).all() {
            return Err(PrimitiveError::new(
                "Cuboid",
                "max",
                format!("must exceed `min` in every component, got min {min}, max {max}"),
            ));
        }
        Ok(Self { min, max })
    }

    /// Lower corner.
    #[must_use]
    pub fn min(&self) -> DVec3 {
        self.min
    }

    /// Upper corner.
    #[must_use]
    pub fn max(&self) -> DVec3 {
        self.max
    }

    /// Outward unit normal of face `face` (see the module docs for the order; `face < 6`).
    #[must_use]
    pub fn face_normal(face: u32) -> DVec3 {
        let mut n = DVec3::ZERO;
        n[(face / 2) as usize] = if face % 2 == 1 { 1.0 } else { -1.0 };
        n
    }

    /// Per-axis slab distances `dᵢ` and, for each axis, whether the upper face is the nearer.
    fn slabs(&self, p: DVec3) -> (DVec3, [bool; 3]) {
        let below = self.min - p;
        let above = p - self.max;
        (
            below.max(above),
            [above.x >= below.x, above.y >= below.y, above.z >= below.z],
        )
    }

    /// The face `p` lies on (or is nearest to, from inside): the largest slab distance.
    fn nearest_face(&self, p: DVec3) -> u32 {
        let (d, upper) = self.slabs(p);
        let axis = if d.x >= d.y && d.x >= d.z {
            0
        } else if d.y >= d.z {
            1
        } else {
            2
        };
        2 * axis as u32 + u32::from(upper[axis])
    }

    /// The axes `u` and `v` run along on face `face`.
    fn face_axes(face: u32) -> (usize, usize, usize) {
        let i = (face / 2) as usize;
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        if face % 2 == 1 {
            (i, j, k)
        } else {
            (i, k, j)
        }
    }

    /// `(u, v)` of `p` on face `face`.
    fn uv_on(&self, face: u32, p: DVec3) -> DVec2 {
        let (_, ju, jv) = Self::face_axes(face);
        let fraction = |a: usize| ((p[a] - self.min[a]) / (self.max[a] - self.min[a])).clamp(0.0, 1.0);
        DVec2::new(f64::from(face) + fraction(ju), fraction(jv))
    }
}

impl Implicit for Cuboid {
    fn phi(&self, p: DVec3) -> f64 {
        let (d, _) = self.slabs(p);
        d.max(DVec3::ZERO).length() + d.max_element().min(0.0)
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let (d, upper) = self.slabs(p);
        let sign = DVec3::new(
            if upper[0] { 1.0 } else { -1.0 },
            if upper[1] { 1.0 } else { -1.0 },
            if upper[2] { 1.0 } else { -1.0 },
        );
        let outside = (d.max(DVec3::ZERO) * sign).normalize_or_zero();
        if outside != DVec3::ZERO {
            outside
        } else {
            Self::face_normal(self.nearest_face(p))
        }
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(self.min, self.max)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    /// `p` clamped to the box from outside, its foot on the nearest face from inside (module
    /// docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let face = self.nearest_face(p);
        let (d, _) = self.slabs(p);
        let q = if d.max_element() >= 0.0 {
            p.clamp(self.min, self.max)
        } else {
            let mut q = p;
            let axis = (face / 2) as usize;
            q[axis] = if face % 2 == 1 { self.max[axis] } else { self.min[axis] };
            q
        };
        Some(Closest::exact(p, q, face))
    }
}

impl Intersect for Cuboid {
    #[allow(
        clippy::neg_cmp_op_on_partial_ord,
        reason = "`!(t_near <= t_far)` rejects NaN as well"
    )]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Cuboid, ray: &Ray, range: Interval) -> Option<RawHit> {
            let (mut t_near, mut near_face) = (f64::NEG_INFINITY, 0);
            let (mut t_far, mut far_face) = (f64::INFINITY, 0);
            for axis in 0..3 {
                let (o, d) = (ray.origin[axis], ray.dir[axis]);
                let (lo, hi) = (this.min[axis], this.max[axis]);
                let lower = 2 * axis as u32;
                if d == 0.0 {
                    // parallel to this slab (±0): inside or on it constrains nothing, else a miss
                    if !(lo <= o && o <= hi) {
                        return None;
                    }
                    continue;
                }
                let (mut t0, mut f0, mut t1, mut f1) = ((lo - o) / d, lower, (hi - o) / d, lower + 1);
                if d < 0.0 {
                    std::mem::swap(&mut t0, &mut t1);
                    std::mem::swap(&mut f0, &mut f1);
                }
                if t0 > t_near {
                    (t_near, near_face) = (t0, f0);
                }
                if t1 < t_far {
                    (t_far, far_face) = (t1, f1);
                }
            }
            if !(t_near <= t_far) {
                return None;
            }
            if t_near.is_finite() && range.contains(t_near) {
                return Some(RawHit::on_feature(t_near, near_face));
            }
            if t_far.is_finite() && range.contains(t_far) {
                return Some(RawHit::on_feature(t_far, far_face));
            }
            None
        }
        crate::with_fma!(test(this: &Cuboid = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    fn normal_at(&self, _ray: &Ray, raw: &RawHit) -> DVec3 {
        Self::face_normal(raw.feature.min(5))
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(self.uv_on(raw.feature.min(5), ray.at(raw.t)))
    }
}

impl Parametric for Cuboid {
    fn domain(&self) -> UvDomain {
        UvDomain {
            u: (0.0, 6.0),
            v: (0.0, 1.0),
        }
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        let face = uv.x.floor().clamp(0.0, 5.0);
        let (i, ju, jv) = Self::face_axes(face as u32);
        let lerp = |a: usize, f: f64| (1.0 - f) * self.min[a] + f * self.max[a];
        let mut p = DVec3::ZERO;
        p[i] = if face as u32 % 2 == 1 { self.max[i] } else { self.min[i] };
        p[ju] = lerp(ju, uv.x - face);
        p[jv] = lerp(jv, uv.y);
        p
    }

    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let (_, ju, jv) = Self::face_axes(uv.x.floor().clamp(0.0, 5.0) as u32);
        let extent = self.max - self.min;
        let (mut du, mut dv) = (DVec3::ZERO, DVec3::ZERO);
        du[ju] = extent[ju];
        dv[jv] = extent[jv];
        (du, dv)
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        self.uv_on(self.nearest_face(p), p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box `[1, 2] × [2, 4] × [3, 7]`.
    fn cuboid() -> Cuboid {
        Cuboid::new(DVec3::new(1.0, 2.0, 3.0), DVec3::new(2.0, 4.0, 7.0)).unwrap()
    }

    fn hit(ray: Ray) -> Option<(f64, u32, DVec3)> {
        let b = cuboid();
        b.intersect(&ray, Interval::POSITIVE)
            .map(|h| (h.t, h.feature, b.normal_at(&ray, &h)))
    }

    #[test]
    fn rejects_bad_corners() {
        let one = DVec3::ONE;
        assert!(Cuboid::new(DVec3::ZERO, one).is_ok());
        assert!(
            Cuboid::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0)).is_err(),
            "min = max on y"
        );
        assert!(Cuboid::new(one, DVec3::ZERO).is_err(), "min > max");
        assert!(Cuboid::new(DVec3::new(f64::NAN, 0.0, 0.0), one).is_err());
        assert!(Cuboid::new(DVec3::ZERO, DVec3::new(1.0, f64::INFINITY, 1.0)).is_err());
    }

    #[test]
    fn phi_is_the_exact_distance_and_gradient_the_face_or_corner_direction() {
        let b = cuboid();
        assert_eq!(b.phi(DVec3::new(1.5, 3.0, 5.0)), -0.5);
        assert_eq!(b.phi(DVec3::new(3.0, 3.0, 5.0)), 1.0);
        assert_eq!(b.gradient(DVec3::new(3.0, 3.0, 5.0)), DVec3::X);
        assert_eq!(b.phi(DVec3::new(3.0, 5.0, 8.0)), 3f64.sqrt());
        assert!((b.gradient(DVec3::new(3.0, 5.0, 8.0)) - DVec3::ONE / 3f64.sqrt()).length() < 1e-15);
        // inside: the nearest face's normal (+X at distance 0.25, the others ≥ 0.75)
        assert_eq!(b.phi(DVec3::new(1.75, 3.0, 5.0)), -0.25);
        assert_eq!(b.gradient(DVec3::new(1.75, 3.0, 5.0)), DVec3::X);
        assert_eq!(b.gradient(DVec3::new(1.5, 3.0, 6.9)), DVec3::Z);
    }

    #[test]
    fn face_hits_are_exact() {
        assert_eq!(
            hit(Ray::new(DVec3::new(0.0, 3.0, 5.0), DVec3::X)),
            Some((1.0, 0, -DVec3::X))
        );
        assert_eq!(
            hit(Ray::new(DVec3::new(1.5, 3.0, 10.0), -2.0 * DVec3::Z)),
            Some((1.5, 5, DVec3::Z))
        );
        // from inside: the exit face
        assert_eq!(
            hit(Ray::new(DVec3::new(1.5, 3.0, 5.0), DVec3::Z)),
            Some((2.0, 5, DVec3::Z))
        );
        assert_eq!(
            hit(Ray::new(DVec3::new(1.5, 3.0, 5.0), -DVec3::Y)),
            Some((1.0, 2, -DVec3::Y))
        );
        assert_eq!(hit(Ray::new(DVec3::new(0.0, 5.0, 5.0), DVec3::X)), None);
    }

    #[test]
    fn signed_zero_direction_components_give_no_nan() {
        for (y, z) in [(0.0, 0.0), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0)] {
            let dir = DVec3::new(1.0, y, z);
            assert_eq!(hit(Ray::new(DVec3::new(0.0, 3.0, 5.0), dir)), Some((1.0, 0, -DVec3::X)));
            // origin exactly on the lower/upper slab planes of y and z: lies in a face plane
            assert_eq!(hit(Ray::new(DVec3::new(0.0, 2.0, 7.0), dir)), Some((1.0, 0, -DVec3::X)));
            // outside the y slab: a miss, not a NaN comparison accident
            assert_eq!(hit(Ray::new(DVec3::new(0.0, 4.5, 5.0), dir)), None);
            assert_eq!(hit(Ray::new(DVec3::new(0.0, 1.5, 5.0), -dir)), None);
        }
        let b = cuboid();
        // a ray along −X starting beyond the +X face, with −0 components
        let ray = Ray::new(DVec3::new(5.0, 4.0, 3.0), DVec3::new(-1.0, -0.0, -0.0));
        let h = b.intersect(&ray, Interval::POSITIVE).unwrap();
        assert_eq!((h.t, h.feature), (3.0, 1));
    }

    #[test]
    fn ray_in_a_face_plane_touches_the_closed_box_and_leaves_it_stably() {
        let b = cuboid();
        // in the plane y = 4 (the +Y face): enters the face across the edge x = 1 at t = 1
        let ray = Ray::new(DVec3::new(0.0, 4.0, 5.0), DVec3::X);
        let h = b.intersect(&ray, Interval::POSITIVE).unwrap();
        assert_eq!((h.t, h.feature), (1.0, 0));
        // starting on that face: it leaves the face across the far edge x = 2 at t = 0.5 (+X),
        // whatever t_min is: not t_min itself (5e-324 for the open range from 0)
        let ray = Ray::new(DVec3::new(1.5, 4.0, 5.0), DVec3::X);
        for t_min in [f64::from_bits(1), 1e-300, 1e-9, 0.25, 0.5] {
            let h = b.intersect(&ray, Interval::new(t_min, 10.0)).unwrap();
            assert_eq!((h.t, h.feature), (0.5, 1), "t_min {t_min}");
            assert_eq!(b.normal_at(&ray, &h), DVec3::X);
        }
        // the same ray nudged into the box by an ulp: the same exit
        let nudged = Ray::new(DVec3::new(1.5, 4.0f64.next_down(), 5.0), DVec3::X);
        let h = b.intersect(&nudged, Interval::new(f64::from_bits(1), 10.0)).unwrap();
        assert_eq!((h.t, h.feature), (0.5, 1));
        // along −Z on the face: leaves across the edge z = 3 at t = 2 (−Z face)
        let down = Ray::new(DVec3::new(1.5, 4.0, 5.0), -DVec3::Z);
        let h = b.intersect(&down, Interval::new(f64::from_bits(1), 10.0)).unwrap();
        assert_eq!((h.t, h.feature), (2.0, 4));
        // past the face's end: nothing
        assert!(b.intersect(&ray, Interval::new(0.75, 10.0)).is_none());
        // in the face plane but beside the face
        assert!(b
            .intersect(&Ray::new(DVec3::new(0.0, 4.0, 8.0), DVec3::X), Interval::POSITIVE)
            .is_none());
    }

    #[test]
    fn edge_and_corner_hits_get_an_exact_face_normal() {
        // through the edge x = 1, y = 2 at t = 1; ties go to the lower axis (face 0, −X)
        assert_eq!(
            hit(Ray::new(DVec3::new(0.0, 1.0, 5.0), DVec3::new(1.0, 1.0, 0.0))),
            Some((1.0, 0, -DVec3::X))
        );
        // through the corner (1, 2, 3) at t = 1
        assert_eq!(
            hit(Ray::new(DVec3::new(0.0, 1.0, 2.0), DVec3::ONE)),
            Some((1.0, 0, -DVec3::X))
        );
        // through the corner (2, 4, 7) from the other side: all three faces tie, +X wins
        assert_eq!(
            hit(Ray::new(DVec3::new(3.0, 5.0, 8.0), -DVec3::ONE)),
            Some((1.0, 1, DVec3::X))
        );
    }

    #[test]
    fn faces_follow_the_documented_order_and_orientation() {
        let b = cuboid();
        for face in 0..6u32 {
            let uv = DVec2::new(f64::from(face) + 0.25, 0.5);
            let p = b.point(uv);
            let n = Cuboid::face_normal(face);
            assert_eq!(b.gradient(p), n, "face {face}");
            let (du, dv) = b.partials(uv);
            assert_eq!(du.cross(dv).normalize(), n, "face {face}");
            assert!((b.uv(p) - uv).length() < 1e-15, "face {face}");
        }
        assert_eq!(b.point(DVec2::new(0.0, 0.0)), DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.point(DVec2::new(6.0, 1.0)), DVec3::new(2.0, 4.0, 7.0));
    }
}
