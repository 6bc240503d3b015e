//! Scene-file descriptions of the built-in primitives, registered under their RON names.
//!
//! Each description is a plain serde struct (unknown fields are errors) whose
//! [`SceneShape::build`] calls the primitive's validating constructor. Defaults are stated per
//! field; see `scenes/README.md` for one example per primitive.

use crate::scene::desc::RotationDesc;
use crate::scene::shape_desc::{BuildContext, ObjectPrimitive, SceneShape};
use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;
use zeroset_primitives::{
    Cone, Cuboid, Cylinder, Disk, Ellipsoid, Plane, Polygon, Primitive, PrimitiveError, Sphere, Triangle,
};

fn origin() -> DVec3 {
    DVec3::ZERO
}
fn unit_y() -> DVec3 {
    DVec3::Y
}
fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
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

impl SphereDesc {
    /// The validated sphere (what every build of the description makes).
    ///
    /// # Errors
    /// A non-finite centre, or a radius that is not finite and positive.
    pub fn sphere(&self) -> Result<Sphere, PrimitiveError> {
        Sphere::new(self.center, self.radius)
    }
}

impl SceneShape for SphereDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(self.sphere()?))
    }

    /// The sphere in place (see [`ObjectPrimitive`]).
    fn build_object_primitive(&self, _: &BuildContext) -> Result<ObjectPrimitive, PrimitiveError> {
        self.sphere().map(ObjectPrimitive::Sphere)
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
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(match (self.offset, self.point) {
            (Some(_), Some(_)) => {
                return Err(PrimitiveError::new(
                    "Plane",
                    "point",
                    "give either `offset` or `point`, not both",
                ))
            }
            (_, Some(p)) => Plane::through(p, self.normal)?,
            (offset, None) => Plane::new(self.normal, offset.unwrap_or(0.0))?,
        }))
    }
}

/// `Box(min: (-1, -1, -1), max: (1, 1, 1))`: the axis-aligned box (use a transform to rotate it).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Box")]
pub struct BoxDesc {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner (greater than `min` on every axis).
    pub max: DVec3,
}

impl SceneShape for BoxDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Cuboid::new(self.min, self.max)?))
    }
}

/// `Cylinder(base: (0, 0, 0), axis: (0, 1, 0), radius: 1, height: 1, capped: true)`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Cylinder")]
pub struct CylinderDesc {
    /// Centre of the bottom cap; default the origin.
    #[serde(default = "origin")]
    pub base: DVec3,
    /// Axis direction from the bottom cap to the top; default +Y.
    #[serde(default = "unit_y")]
    pub axis: DVec3,
    /// Radius; default 1.
    #[serde(default = "one")]
    pub radius: f64,
    /// Height along the axis; default 1.
    #[serde(default = "one")]
    pub height: f64,
    /// Closed by two disks (default) or an open tube.
    #[serde(default = "yes")]
    pub capped: bool,
}

impl SceneShape for CylinderDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Cylinder::new(
            self.base,
            self.axis,
            self.radius,
            self.height,
            self.capped,
        )?))
    }
}

/// `Cone(base: (0, 0, 0), axis: (0, 1, 0), base_radius: 1, top_radius: 0, height: 1, capped: true)`:
/// a pointed cone (`top_radius: 0`, the default) or a frustum.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Cone")]
pub struct ConeDesc {
    /// Centre of the base; default the origin.
    #[serde(default = "origin")]
    pub base: DVec3,
    /// Axis direction from the base to the top; default +Y.
    #[serde(default = "unit_y")]
    pub axis: DVec3,
    /// Radius at the base; default 1.
    #[serde(default = "one")]
    pub base_radius: f64,
    /// Radius at the top; default 0 (a pointed cone).
    #[serde(default)]
    pub top_radius: f64,
    /// Height along the axis; default 1.
    #[serde(default = "one")]
    pub height: f64,
    /// Closed by disks (default) or open.
    #[serde(default = "yes")]
    pub capped: bool,
}

impl SceneShape for ConeDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Cone::new(
            self.base,
            self.axis,
            self.base_radius,
            self.top_radius,
            self.height,
            self.capped,
        )?))
    }
}

/// `Ellipsoid(center: (0, 0, 0), radii: (1, 0.6, 0.4), rotate: (axis: (0, 1, 0), degrees: 30))`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Ellipsoid")]
pub struct EllipsoidDesc {
    /// Centre; default the origin.
    #[serde(default = "origin")]
    pub center: DVec3,
    /// Semi-axis lengths along the (rotated) x, y, z axes.
    pub radii: DVec3,
    /// Orientation; default none.
    #[serde(default)]
    pub rotate: Option<RotationDesc>,
}

impl SceneShape for EllipsoidDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        let orientation = match &self.rotate {
            None => glam::DQuat::IDENTITY,
            Some(r) => r
                .quat()
                .map_err(|problem| PrimitiveError::new("Ellipsoid", "rotate", problem))?,
        };
        Ok(Arc::new(Ellipsoid::new(self.center, self.radii, orientation)?))
    }
}

/// `Triangle(a: (0, 0, 0), b: (1, 0, 0), c: (0, 1, 0))`: counter-clockwise `a → b → c` seen from
/// the front (the side the normal `(b − a) × (c − a)` points to). Collinear or repeated vertices
/// are accepted with a warning: such a triangle has no area and is never hit.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Triangle")]
pub struct TriangleDesc {
    /// First vertex.
    pub a: DVec3,
    /// Second vertex.
    pub b: DVec3,
    /// Third vertex.
    pub c: DVec3,
}

impl SceneShape for TriangleDesc {
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        let triangle = Triangle::new(self.a, self.b, self.c)?;
        if triangle.is_degenerate() {
            context.warn("1 degenerate triangle (collinear or repeated vertices): it is never hit");
        }
        Ok(Arc::new(triangle))
    }
}

/// `Disk(center: (0, 0, 0), normal: (0, 1, 0), radius: 1)`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Disk")]
pub struct DiskDesc {
    /// Centre; default the origin.
    #[serde(default = "origin")]
    pub center: DVec3,
    /// Normal (front side); default +Y.
    #[serde(default = "unit_y")]
    pub normal: DVec3,
    /// Radius; default 1.
    #[serde(default = "one")]
    pub radius: f64,
}

impl SceneShape for DiskDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Disk::new(self.center, self.normal, self.radius)?))
    }
}

/// `Polygon(points: [(x, y, z), …], holes: [[…], …])`: planar, convex or concave; the outer
/// ring counter-clockwise seen from the front; holes by the even-odd rule (either orientation).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Polygon")]
pub struct PolygonDesc {
    /// The outer boundary.
    pub points: Vec<DVec3>,
    /// Holes; default none.
    #[serde(default)]
    pub holes: Vec<Vec<DVec3>>,
}

impl SceneShape for PolygonDesc {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Polygon::new(self.points.clone(), self.holes.clone())?))
    }
}
