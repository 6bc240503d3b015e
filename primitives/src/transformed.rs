//! Any primitive under an affine transform.
//!
//! `Transformed<P>` stores `world_from_local` (the affine map taking the primitive's own space to
//! the world), its inverse `local_from_world`, and `normal_from_local`, the inverse transpose of the
//! linear part. A world ray is mapped into local space **without renormalising its direction**,
//! so the ray parameter `t` of a hit is the same in both spaces and stays a world-space distance
//! for a unit world direction. Normals map by `normal_from_local` and are renormalised, so they
//! still point to the `Φ > 0` side (also under a reflection).
//!
//! Φ_world(p) = Φ_local(local_from_world · p): the same zero set and sign, but not a distance when
//! the transform scales; its Lipschitz bound is `L_local · ‖local_from_world‖` (Frobenius norm of
//! the linear part, an upper bound of the spectral norm).

use crate::bounds::Aabb;
use crate::crossings::Crossings;
use crate::error::PrimitiveError;
use crate::expr::Jet;
use crate::hit::RawHit;
use crate::math::enclosure::Enclosure;
use crate::proximity::{Closest, SignMethod};
use crate::ray::{Interval, Ray};
use crate::root::RootOptions;
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DAffine3, DMat3, DVec2, DVec3};

/// `inner` placed in the world by `world_from_local`.
#[derive(Clone, Debug)]
pub struct Transformed<P> {
    inner: P,
    world_from_local: DAffine3,
    local_from_world: DAffine3,
    normal_from_local: DMat3,
    /// `(σ_min, σ_max)`: a lower bound of the smallest and an upper bound of the largest factor
    /// by which `world_from_local` stretches lengths, equal for a similarity (see [`stretch`]).
    stretch: (f64, f64),
}

fn frobenius(m: &DMat3) -> f64 {
    (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt()
}

/// Bounds `(σ_min, σ_max)` on the singular values of `m` (`inverse` its inverse): by how much
/// the map can shorten or lengthen a segment. Where `mᵀm = s²·I` to within `10⁻¹³·s²` (a rigid
/// motion times a uniform scale, up to the rounding of its entries) both are `s`, and distances
/// map exactly. Otherwise the eigenvalues of `mᵀm` by Smith's closed form (1961), each widened
/// by `64ε·λ_max` for its rounding, and the Frobenius norms (`σ_max ≤ ‖m‖_F`,
/// `σ_min ≥ 1/‖m⁻¹‖_F`) as a second bound: the tighter of the two valid bounds is kept.
fn stretch(m: &DMat3, inverse: &DMat3) -> (f64, f64) {
    let a = m.transpose() * *m;
    let s2 = (a.x_axis.x + a.y_axis.y + a.z_axis.z) / 3.0;
    let off = (a - DMat3::from_diagonal(DVec3::splat(s2))).to_cols_array();
    if off.iter().all(|e| e.abs() <= 1e-13 * s2) {
        let s = s2.sqrt();
        return (s, s);
    }
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let p2 = (a00 - s2).powi(2) + (a11 - s2).powi(2) + (a22 - s2).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (a - DMat3::from_diagonal(DVec3::splat(s2))) * (1.0 / p);
    let phi = (b.determinant() / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let largest = s2 + 2.0 * p * phi.cos();
    let smallest = s2 + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let slack = 64.0 * f64::EPSILON * largest;
    let upper = (largest + slack).sqrt().min(frobenius(m));
    let lower = (smallest - slack).max(0.0).sqrt().max(1.0 / frobenius(inverse));
    (lower, upper)
}

impl<P> Transformed<P> {
    /// `inner` under `world_from_local`; errors on a non-finite or singular transform.
    pub fn new(inner: P, world_from_local: DAffine3) -> Result<Self, PrimitiveError> {
        let m = world_from_local.matrix3;
        if !world_from_local.is_finite() {
            return Err(PrimitiveError::new("Transform", "matrix", "must be finite"));
        }
        let det = m.determinant();
        let scale = frobenius(&m);
        if !(det.abs() > 1e-12 * scale * scale * scale) {
            return Err(PrimitiveError::new(
                "Transform",
                "matrix",
                format!("is singular (determinant {det:e})"),
            ));
        }
        let local_from_world = world_from_local.inverse();
        Ok(Self {
            inner,
            world_from_local,
            local_from_world,
            normal_from_local: local_from_world.matrix3.transpose(),
            stretch: stretch(&m, &local_from_world.matrix3),
        })
    }

    /// The untransformed primitive.
    #[must_use]
    pub fn inner(&self) -> &P {
        &self.inner
    }

    /// Local → world map.
    #[must_use]
    pub fn world_from_local(&self) -> &DAffine3 {
        &self.world_from_local
    }

    /// World → local map.
    #[must_use]
    pub fn local_from_world(&self) -> &DAffine3 {
        &self.local_from_world
    }

    /// The world ray expressed in local space, with the same parameter `t`.
    #[inline]
    #[must_use]
    pub fn local_ray(&self, ray: &Ray) -> Ray {
        Ray::new(
            self.local_point(ray.origin),
            self.local_from_world.transform_vector3(ray.dir),
        )
    }

    /// `W⁻¹(p − translation)`: the translation is removed before the linear map, so a point near
    /// a far-translated object (`10⁵` away from the origin) keeps its offset from the object
    /// exactly instead of rounding at the translation's magnitude (`local_from_world`'s own
    /// translation, `−W⁻¹·translation`, can be `10⁸` for a scale of `10⁻³`).
    #[inline]
    #[must_use]
    pub fn local_point(&self, p: DVec3) -> DVec3 {
        self.local_from_world.matrix3 * (p - self.world_from_local.translation)
    }
}

impl<P: Implicit> Implicit for Transformed<P> {
    fn phi(&self, p: DVec3) -> f64 {
        self.inner.phi(self.local_point(p))
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.normal_from_local * self.inner.gradient(self.local_point(p))
    }

    fn bounds(&self) -> Aabb {
        self.inner.bounds().transformed(&self.world_from_local)
    }

    fn lipschitz(&self) -> Option<f64> {
        self.inner
            .lipschitz()
            .map(|l| l * frobenius(&self.local_from_world.matrix3))
    }

    fn within_boundary(&self, p: DVec3) -> bool {
        self.inner.within_boundary(self.local_point(p))
    }

    /// The inner answer at the local point, mapped back: exact under a similarity (rigid motion
    /// and uniform scale, distances times `s`); under any other map the inner witness mapped to
    /// the world bounds the distance from above and `σ_min ×` the inner lower bound from below
    /// (no world point is nearer than that, since no local segment shrinks by more than
    /// `σ_min`).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let local = self.inner.closest(self.local_point(p))?;
        let (lower, upper) = self.stretch;
        Some(local.mapped(|q| self.world_from_local.transform_point3(q), p, lower, upper))
    }

    fn contains(&self, p: DVec3, method: SignMethod) -> bool {
        self.inner.contains(self.local_point(p), method)
    }

    /// The inner enclosures along the local ray (the same `t`).
    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        self.inner.enclose_along(&self.local_ray(ray), segment)
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        self.inner.enclose_value_along(&self.local_ray(ray), segment)
    }
}

impl<P: Intersect> Intersect for Transformed<P> {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        self.inner.intersect(&self.local_ray(ray), range)
    }

    /// The inner packet test on the local rays (the same `t`), [`crate::PACKET`] rays at a time.
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        let mut local = [Ray::new(glam::DVec3::ZERO, glam::DVec3::Z); crate::PACKET];
        for ((rays, ranges), hits) in rays
            .chunks(crate::PACKET)
            .zip(ranges.chunks_mut(crate::PACKET))
            .zip(hits.chunks_mut(crate::PACKET))
        {
            for (l, ray) in local.iter_mut().zip(rays) {
                *l = self.local_ray(ray);
            }
            self.inner.intersect_packet(&local[..rays.len()], ranges, hits);
        }
    }

    fn root_options(&self) -> RootOptions {
        self.inner.root_options()
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        (self.normal_from_local * self.inner.normal_at(&self.local_ray(ray), raw)).normalize_or_zero()
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        self.inner.uv_at(&self.local_ray(ray), raw)
    }

    /// The inner primitive's, at the local origin, mapped back to world lengths by `‖W‖_F`.
    fn origin_rounding(&self, origin: glam::DVec3) -> f64 {
        frobenius(&self.world_from_local.matrix3)
            * self
                .inner
                .origin_rounding(self.local_from_world.transform_point3(origin))
    }

    /// The inner bound mapped to the world by `‖W‖_F`, plus the rounding of the maps themselves:
    /// `γ₃₂·κ_F·(‖p‖∞ + ‖o‖∞ + ‖translation‖∞)`, `κ_F = ‖W‖_F·‖W⁻¹‖_F` (see [`crate::offset`]).
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        let w = frobenius(&self.world_from_local.matrix3);
        let kappa = w * frobenius(&self.local_from_world.matrix3);
        let inner = self.inner.hit_error(&self.local_ray(ray), raw);
        let magnitudes = ray.at(raw.t).abs().max_element()
            + ray.origin.abs().max_element()
            + self.world_from_local.translation.abs().max_element();
        w * inner + crate::math::gamma(crate::offset::OFFSET_GAMMA) * kappa * magnitudes
    }

    fn shading_normal_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec3> {
        let n = self.inner.shading_normal_at(&self.local_ray(ray), raw)?;
        Some((self.normal_from_local * n).normalize_or_zero())
    }

    /// The inner crossings along the local ray: the same `t`, and the same side
    /// (`dir · M⁻ᵀn = M⁻¹dir · n`).
    fn crossings<'a>(&'a self, ray: &Ray, range: Interval) -> Crossings<'a> {
        self.inner.crossings(&self.local_ray(ray), range)
    }
}

impl<P: Parametric> Parametric for Transformed<P> {
    fn domain(&self) -> UvDomain {
        self.inner.domain()
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        self.world_from_local.transform_point3(self.inner.point(uv))
    }

    /// The local partials mapped by the linear part. Under a reflection (negative determinant)
    /// their cross product points to the `Φ < 0` side.
    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let (du, dv) = self.inner.partials(uv);
        (self.world_from_local.matrix3 * du, self.world_from_local.matrix3 * dv)
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        self.inner.uv(self.local_point(p))
    }
}
