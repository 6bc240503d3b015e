//! Scene-file descriptions of the built-in primitives, registered under their RON names.
//!
//! Each description is a plain serde struct (unknown fields are errors) whose
//! [`SceneShape::build`] calls the primitive's validating constructor. Defaults are stated per
//! field; see `scenes/README.md` for one example per primitive.

use crate::registry::{parser_for, SceneShape};
use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;
use zeroset_primitives::{Plane, Primitive, PrimitiveError, Sphere};

/// Calls `add(name, parser)` for every built-in primitive.
pub(crate) fn register_builtins(add: &mut dyn FnMut(&str, crate::registry::ShapeParserFn)) {
    add("Sphere", parser_for::<SphereDesc>());
    add("Plane", parser_for::<PlaneDesc>());
}

fn origin() -> DVec3 {
    DVec3::ZERO
}
fn unit_y() -> DVec3 {
    DVec3::Y
}
fn one() -> f64 {
    1.0
}

/// `Sphere(center: (0, 0, 0), radius: 1)`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Sphere")]
pub struct SphereDesc {
    /// Centre; default the origin.
    #[serde(default = "origin")]
    pub center: DVec3,
    /// Radius; default 1.
    #[serde(default = "one")]
    pub radius: f64,
}

impl SceneShape for SphereDesc {
    fn build(&self) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Sphere::new(self.center, self.radius)?))
    }
}

/// `Plane(normal: (0, 1, 0), offset: 0)` or `Plane(normal: (0, 1, 0), point: (0, 2, 0))`: the
/// infinite plane `⟨p, n⟩ = offset`, or the one through `point`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Plane")]
pub struct PlaneDesc {
    /// Normal (front side); default +Y.
    #[serde(default = "unit_y")]
    pub normal: DVec3,
    /// Offset along the normal; default 0. Not together with `point`.
    #[serde(default)]
    pub offset: Option<f64>,
    /// A point on the plane. Not together with `offset`.
    #[serde(default)]
    pub point: Option<DVec3>,
}

impl SceneShape for PlaneDesc {
    fn build(&self) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(match (self.offset, self.point) {
            (Some(_), Some(_)) => return Err(PrimitiveError::new("Plane", "point", "give either `offset` or `point`, not both")),
            (_, Some(p)) => Plane::through(p, self.normal)?,
            (offset, None) => Plane::new(self.normal, offset.unwrap_or(0.0))?,
        }))
    }
}
