//! Barr's superellipsoid, centred at the origin.
//!
//! `F(p) = (|x/a|^(2/e₂) + |z/c|^(2/e₂))^(e₂/e₁) + |y/b|^(2/e₁)`; the surface is `F = 1`.
//! Φ = `(F^(e₁/2) − 1)·min(a, b, c)`, which has the same zero set and sign and grows roughly like
//! distance near the surface. Only Φ and bounds are written: normals and hits are zeroset's
//! defaults.

use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;
use zeroset::scene::registry::{BuildContext, SceneShape};
use zeroset_primitives::{Aabb, Implicit, Intersect, Primitive, PrimitiveError};

/// A superellipsoid with radii `radii` and shape exponents `e1` (north–south, along y) and `e2`
/// (east–west): 1 and 1 is an ellipsoid, small values approach a box, 2 a diamond.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Superellipsoid {
    /// Semi-axes `(a, b, c)` along x, y, z.
    pub radii: DVec3,
    /// North–south exponent ε₁ (along y).
    pub e1: f64,
    /// East–west exponent ε₂.
    pub e2: f64,
}

impl Implicit for Superellipsoid {
    fn phi(&self, p: DVec3) -> f64 {
        let q = (p / self.radii).abs();
        let horizontal = q.x.powf(2.0 / self.e2) + q.z.powf(2.0 / self.e2);
        let f = horizontal.powf(self.e2 / self.e1) + q.y.powf(2.0 / self.e1);
        (f.powf(self.e1 / 2.0) - 1.0) * self.radii.min_element()
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(-self.radii, self.radii)
    }
}

impl Intersect for Superellipsoid {}

impl SceneShape for Superellipsoid {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        if !(self.radii.is_finite() && self.radii.min_element() > 0.0) {
            return Err(PrimitiveError::new(
                "Superellipsoid",
                "radii",
                format!("must be positive and finite, got {}", self.radii),
            ));
        }
        for (field, e) in [("e1", self.e1), ("e2", self.e2)] {
            if !(e.is_finite() && (0.05..=4.0).contains(&e)) {
                return Err(PrimitiveError::new(
                    "Superellipsoid",
                    field,
                    format!("must lie in [0.05, 4], got {e}"),
                ));
            }
        }
        Ok(Arc::new(*self))
    }
}
