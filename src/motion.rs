//! Moving objects: a primitive keyed by two placements, at frame times 0 and 1.
//!
//! Between the keys the placement is interpolated component by component: scale and translation
//! linearly, rotation by quaternion slerp (the shorter arc), and composed as `T·R·S` like a static
//! `transform`. Outside `[0, 1]` the nearer key holds. A ray at time `τ` is intersected with the
//! primitive placed by the interpolated map (a [`Transformed`] built for that ray), so the kernel's
//! [`Ray`] needs no time field and static objects never see one.
//!
//! **Bounds** (for the scene BVH): the union of the placed bounds at both keys, which contains
//! every in-between placement when the rotation does not change (each local point then moves on
//! the straight segment between its two key positions). When the rotation changes, the union also
//! includes, at both keys' translations, the box of the sphere about the local origin holding the
//! local bounds under the larger of the two scales per axis: the interpolated translation lies on
//! the segment between the keys and a rotation does not move a point off that sphere, so the
//! swept volume is inside (conservative, loose for long thin objects far from their origin).

use glam::{DAffine3, DQuat, DVec2, DVec3};
use std::sync::Arc;
use zeroset_primitives::{Aabb, Implicit, Intersect, Interval, Primitive, RawHit, Ray, RootOptions, Transformed};

/// A placement `T·R·S` as its components, for interpolation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Per-axis scale (no component zero).
    pub scale: DVec3,
    /// Unit rotation.
    pub rotation: DQuat,
    /// Translation.
    pub translation: DVec3,
}

impl Placement {
    /// The identity placement.
    pub const IDENTITY: Self = Self {
        scale: DVec3::ONE,
        rotation: DQuat::IDENTITY,
        translation: DVec3::ZERO,
    };

    /// The affine map `T·R·S`.
    #[must_use]
    pub fn affine(&self) -> DAffine3 {
        DAffine3::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// A primitive moving from placement `start` (time 0) to `end` (time 1).
#[derive(Debug)]
pub struct Moving {
    inner: Arc<dyn Primitive>,
    start: Placement,
    end: Placement,
    /// `inner` placed at time 0, the fallback should an interpolated map be singular.
    at_start: Transformed<Arc<dyn Primitive>>,
}

/// Borrows a primitive as one (for a per-ray [`Transformed`] without reference counting).
#[derive(Debug)]
struct Borrowed<'a>(&'a dyn Primitive);

impl Implicit for Borrowed<'_> {
    fn phi(&self, p: DVec3) -> f64 {
        self.0.phi(p)
    }
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        self.0.gradient(p)
    }
    fn lipschitz(&self) -> Option<f64> {
        self.0.lipschitz()
    }
    fn within_boundary(&self, p: DVec3) -> bool {
        self.0.within_boundary(p)
    }
    fn closest(&self, p: DVec3) -> Option<zeroset_primitives::Closest> {
        self.0.closest(p)
    }
    fn contains(&self, p: DVec3, method: zeroset_primitives::SignMethod) -> bool {
        self.0.contains(p, method)
    }
}

impl Intersect for Borrowed<'_> {
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        self.0.intersect(ray, range)
    }
    fn root_options(&self) -> RootOptions {
        self.0.root_options()
    }
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        self.0.normal_at(ray, raw)
    }
    fn normal_at_f32(&self, ray: &Ray, raw: &RawHit) -> glam::Vec3 {
        self.0.normal_at_f32(ray, raw)
    }
    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        self.0.uv_at(ray, raw)
    }
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        self.0.hit_error(ray, raw)
    }
    fn shading_normal_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec3> {
        self.0.shading_normal_at(ray, raw)
    }
}

impl Moving {
    /// `inner` (in its own frame) moving from `start` to `end`. Errors, naming the field, when a
    /// scale component is zero or changes sign between the keys (the interpolated map would pass
    /// through a singular one) or a placement is not finite.
    pub fn new(inner: Arc<dyn Primitive>, start: Placement, end: Placement) -> Result<Self, String> {
        for (field, p) in [("transform", &start), ("transform_close", &end)] {
            if !(p.scale.is_finite() && p.translation.is_finite() && p.rotation.is_finite()) {
                return Err(format!("field `{field}`: must be finite"));
            }
        }
        if (start.scale * end.scale).cmple(DVec3::ZERO).any() {
            return Err(format!(
                "field `transform_close.scale`: each component must be non-zero with the same sign as \
                 `transform.scale` ({} → {})",
                start.scale, end.scale
            ));
        }
        let at_start =
            Transformed::new(inner.clone(), start.affine()).map_err(|e| format!("transform: {}", e.problem))?;
        Transformed::new(inner.clone(), end.affine()).map_err(|e| format!("transform_close: {}", e.problem))?;
        Ok(Self {
            inner,
            start,
            end,
            at_start,
        })
    }

    /// The placement at frame time `time` (clamped to `[0, 1]`; exactly the keys at 0 and 1).
    #[must_use]
    pub fn placement_at(&self, time: f64) -> DAffine3 {
        let s = time.clamp(0.0, 1.0);
        if s == 0.0 {
            return self.start.affine();
        }
        if s == 1.0 {
            return self.end.affine();
        }
        DAffine3::from_scale_rotation_translation(
            self.start.scale.lerp(self.end.scale, s),
            self.start.rotation.slerp(self.end.rotation, s),
            self.start.translation.lerp(self.end.translation, s),
        )
    }

    /// Calls `f` with the primitive placed at frame time `time`.
    #[inline]
    pub fn with_primitive_at<R>(&self, time: f64, f: impl FnOnce(&dyn Primitive) -> R) -> R {
        match Transformed::new(Borrowed(&*self.inner), self.placement_at(time)) {
            Ok(placed) => f(&placed),
            Err(_) => f(&self.at_start),
        }
    }

    /// A box holding the object at every time (module docs).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let local = self.inner.bounds();
        let mut b = local
            .transformed(&self.start.affine())
            .union(local.transformed(&self.end.affine()));
        if self.start.rotation != self.end.rotation {
            let scale = self.start.scale.abs().max(self.end.scale.abs());
            let radius = [local.min, local.max]
                .into_iter()
                .flat_map(|x| [local.min, local.max].into_iter().map(move |y| (x, y)))
                .flat_map(|(x, y)| {
                    [local.min, local.max]
                        .into_iter()
                        .map(move |z| DVec3::new(x.x, y.y, z.z))
                })
                .map(|corner| (corner * scale).length())
                .fold(0.0, f64::max);
            for t in [self.start.translation, self.end.translation] {
                b = b.union(Aabb::new(t - DVec3::splat(radius), t + DVec3::splat(radius)));
            }
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset_primitives::Sphere;

    fn moving(end: Placement) -> Moving {
        let sphere: Arc<dyn Primitive> = Arc::new(Sphere::new(DVec3::new(0.5, 0.0, 0.0), 0.25).unwrap());
        Moving::new(sphere, Placement::IDENTITY, end).unwrap()
    }

    #[test]
    fn keys_are_exact_and_translation_is_linear() {
        let end = Placement {
            translation: DVec3::new(2.0, 0.0, 0.0),
            ..Placement::IDENTITY
        };
        let m = moving(end);
        assert_eq!(m.placement_at(0.0), DAffine3::IDENTITY);
        assert_eq!(m.placement_at(1.0), end.affine());
        assert_eq!(m.placement_at(7.0), end.affine());
        let mid = m.placement_at(0.25);
        assert!((mid.translation - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        let ray = Ray::new(DVec3::new(1.0, 0.0, -5.0), DVec3::Z);
        let t = m
            .with_primitive_at(0.25, |p| p.intersect(&ray, Interval::POSITIVE))
            .unwrap()
            .t;
        assert!((t - 4.75).abs() < 1e-12, "{t}");
    }

    #[test]
    fn rotating_bounds_hold_every_in_between_placement() {
        let end = Placement {
            scale: DVec3::new(1.0, 2.0, 1.0),
            rotation: DQuat::from_rotation_z(2.5),
            translation: DVec3::new(1.0, -1.0, 0.5),
        };
        let m = moving(end);
        let b = m.bounds();
        for k in 0..=64 {
            let placed = m.inner.bounds().transformed(&m.placement_at(f64::from(k) / 64.0));
            assert!(
                b.contains(placed.min) && b.contains(placed.max),
                "{k}: {placed:?} ⊄ {b:?}"
            );
        }
        assert!(Moving::new(
            m.inner.clone(),
            Placement::IDENTITY,
            Placement {
                scale: DVec3::new(-1.0, 1.0, 1.0),
                ..Placement::IDENTITY
            }
        )
        .is_err());
    }
}
