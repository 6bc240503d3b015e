//! A gyroid sheet clipped by a box.
//!
//! `g(p) = sin(ωx)cos(ωy) + sin(ωy)cos(ωz) + sin(ωz)cos(ωx)`; the sheet of half-thickness `τ` is
//! `|g| − τ/2 ≤ 0`, intersected with the box `|p| ≤ half`: Φ = `max((|g| − τ/2)/(2√3·ω),
//! max|pᵢ| − half)`, both branches 1-Lipschitz: each component of ∇g is a sum of two products of sines and
//! cosines times ω, so at most 2ω in size, and `|∇g| ≤ 2√3·ω`.
//!
//! Φ is written once, generically ([`ScalarField`]): the first roots are isolated by interval
//! arithmetic (no Lipschitz bound needed) and the normals are the exact gradient.

use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;
use zeroset::scene::registry::{BuildContext, SceneShape};
use zeroset_primitives::expr::Scalar;
use zeroset_primitives::{Aabb, FieldSurface, Primitive, PrimitiveError, ScalarField};

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

impl ScalarField for Gyroid {
    fn phi<T: Scalar>(&self, [px, py, pz]: [T; 3]) -> T {
        let w = T::constant(self.frequency);
        let (x, y, z) = (w * px, w * py, w * pz);
        let g = x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos();
        let sheet = (g.abs() - T::constant(0.5 * self.thickness)) / T::constant(2.0 * 3f64.sqrt() * self.frequency);
        // the cube as max |pᵢ| − half: the cube's zero set and sign, 1-Lipschitz, and
        // differentiable on its faces (the Euclidean distance's √ is not, at 0)
        let cube = px.abs().max(py.abs()).max(pz.abs()) - T::constant(self.half_size);
        sheet.max(cube)
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(DVec3::splat(-self.half_size), DVec3::splat(self.half_size))
    }
}

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
        Ok(Arc::new(FieldSurface::new(*self)))
    }
}
