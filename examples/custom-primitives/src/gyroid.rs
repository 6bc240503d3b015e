//! A gyroid sheet clipped by a box.
//!
//! `g(p) = sin(ωx)cos(ωy) + sin(ωy)cos(ωz) + sin(ωz)cos(ωx)`; the sheet of half-thickness `τ` is
//! `|g| − τ/2 ≤ 0`, intersected with the box `|p| ≤ half`: Φ = `max((|g| − τ/2)/(2√3·ω), box
//! SDF)`, both branches 1-Lipschitz: each component of ∇g is a sum of two products of sines and
//! cosines times ω, so at most 2ω in size, and `|∇g| ≤ 2√3·ω`. Declaring the bound lets the
//! generic root finder sphere-trace safely.

use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;
use zeroset::scene::registry::{BuildContext, SceneShape};
use zeroset_primitives::{Aabb, Implicit, Intersect, Primitive, PrimitiveError};

/// A gyroid sheet of `thickness` at spatial frequency `frequency`, clipped to the cube of
/// half-size `half_size` centred at the origin.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gyroid {
    /// ω: radians per unit length.
    pub frequency: f64,
    /// Sheet thickness in units of g (0 < τ < 1.5).
    pub thickness: f64,
    /// Half the side of the clipping cube.
    pub half_size: f64,
}

impl Implicit for Gyroid {
    fn phi(&self, p: DVec3) -> f64 {
        let w = self.frequency;
        let (x, y, z) = (w * p.x, w * p.y, w * p.z);
        let g = x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos();
        let sheet = (g.abs() - 0.5 * self.thickness) / (2.0 * 3f64.sqrt() * w);
        let q = p.abs() - DVec3::splat(self.half_size);
        let cube = q.max(DVec3::ZERO).length() + q.max_element().min(0.0);
        sheet.max(cube)
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(DVec3::splat(-self.half_size), DVec3::splat(self.half_size))
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }
}

impl Intersect for Gyroid {}

impl SceneShape for Gyroid {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        for (field, v) in [("frequency", self.frequency), ("half_size", self.half_size)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(PrimitiveError::new(
                    "Gyroid",
                    field,
                    format!("must be positive and finite, got {v}"),
                ));
            }
        }
        if !(self.thickness > 0.0 && self.thickness < 1.5) {
            return Err(PrimitiveError::new(
                "Gyroid",
                "thickness",
                format!("must lie in (0, 1.5), got {}", self.thickness),
            ));
        }
        Ok(Arc::new(*self))
    }
}
