//! The scene file's descriptions: the serde types a RON scene parses into, before anything is
//! built (the camera, objects, lights, outputs), and the RON options every scene parse uses.
//!
//! These are the descriptions layer of the crate (see the crate docs): besides the foundations
//! (AOV names, camera models and poses, sampling), this imports only [`ShapeDesc`], the parsed
//! description of a primitive ([`crate::scene::shape_desc`]). The format is documented with one example
//! per primitive in `scenes/README.md`.

use crate::aov::Aov;
use crate::camera::desc::ModelDesc;
use crate::camera::pose::ViewDesc;
use crate::sampling::Sampling;
use crate::scene::shape_desc::ShapeDesc;
use glam::{DAffine3, DQuat, DVec3};
use ron::extensions::Extensions;
use serde::Deserialize;

fn default_vfov() -> Option<f64> {
    None
}
fn default_up() -> DVec3 {
    DVec3::Y
}
fn default_eye() -> DVec3 {
    DVec3::new(0.0, 0.0, -5.0)
}
fn default_width() -> u32 {
    640
}
fn default_height() -> u32 {
    480
}
fn default_ambient() -> DVec3 {
    DVec3::splat(0.1)
}
fn default_color() -> DVec3 {
    DVec3::splat(0.8)
}
fn default_white() -> DVec3 {
    DVec3::ONE
}
fn default_shininess() -> f64 {
    32.0
}
fn default_aovs() -> Vec<Aov> {
    Aov::DEFAULT.to_vec()
}
fn default_true() -> bool {
    true
}
fn default_scale() -> DVec3 {
    DVec3::ONE
}

/// `shutter: (open: 0, close: 1)`: the frame times the shutter is open.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShutterDesc {
    /// Opening time; default 0.
    #[serde(default)]
    pub open: f64,
    /// Closing time; default 1.
    #[serde(default = "default_one")]
    pub close: f64,
}

fn default_one() -> f64 {
    1.0
}

/// `camera: (eye: …, look_at: … | direction: …, up: …, vfov_deg: … | hfov_deg: …, width, height,
/// model: Perspective(), aperture: 0, focus_distance: …, shutter: (open: 0, close: 1))`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position; default `(0, 0, −5)`.
    #[serde(default = "default_eye")]
    pub eye: DVec3,
    /// Point looked at; default the origin unless `direction` is given.
    #[serde(default)]
    pub look_at: Option<DVec3>,
    /// View direction (instead of `look_at`).
    #[serde(default)]
    pub direction: Option<DVec3>,
    /// Up vector (orthonormalised against the view); default +Y.
    #[serde(default = "default_up")]
    pub up: DVec3,
    /// Vertical field of view in degrees; default 45 unless `hfov_deg` is given.
    #[serde(default = "default_vfov")]
    pub vfov_deg: Option<f64>,
    /// Horizontal field of view in degrees (square pixels).
    #[serde(default)]
    pub hfov_deg: Option<f64>,
    /// Width in pixels; default 640.
    #[serde(default = "default_width")]
    pub width: u32,
    /// Height in pixels; default 480.
    #[serde(default = "default_height")]
    pub height: u32,
    /// Thin-lens radius (world units); default 0, the pinhole.
    #[serde(default)]
    pub aperture: f64,
    /// Distance of the plane in focus along the view axis; default the distance to `look_at`
    /// (required with `direction` and `aperture > 0`).
    #[serde(default)]
    pub focus_distance: Option<f64>,
    /// Shutter interval in frame time; default `(open: 0, close: 1)`.
    #[serde(default)]
    pub shutter: Option<ShutterDesc>,
    /// Projection model; default `Perspective()` (fields of view from `vfov_deg`/`hfov_deg`,
    /// which the other models do not take).
    #[serde(default)]
    pub model: Option<ModelDesc>,
}

/// `material: (color: (r, g, b), specular: 0, shininess: 32)`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Diffuse reflectance (linear RGB); default 0.8 grey.
    #[serde(default = "default_color")]
    pub color: DVec3,
    /// Blinn-Phong specular weight; default 0 (pure Lambert).
    #[serde(default)]
    pub specular: f64,
    /// Blinn-Phong exponent; default 32.
    #[serde(default = "default_shininess")]
    pub shininess: f64,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            color: default_color(),
            specular: 0.0,
            shininess: default_shininess(),
        }
    }
}

/// `(axis: (0, 1, 0), degrees: 30)`: a rotation about `axis`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotationDesc {
    /// Rotation axis (any length > 0).
    pub axis: DVec3,
    /// Angle in degrees, counter-clockwise looking down the axis.
    pub degrees: f64,
}

impl RotationDesc {
    /// The rotation as a unit quaternion; errors on a zero or non-finite axis or angle.
    pub fn quat(&self) -> Result<DQuat, String> {
        if !self.axis.is_finite() || self.axis.length() == 0.0 || !self.degrees.is_finite() {
            return Err("axis must be finite and non-zero, degrees finite".into());
        }
        Ok(DQuat::from_axis_angle(self.axis.normalize(), self.degrees.to_radians()))
    }
}

/// `transform: (translate: …, rotate: (axis: …, degrees: …), scale: (sx, sy, sz))`: applied as
/// scale, then rotation, then translation (`world_from_local = T·R·S`); or
/// `transform: (matrix: [[m00, m01, m02, m03], [m10, …], [m20, …]])`: the affine map
/// `world_from_local` itself, row-major, 3×4 or 4×4 with last row `[0, 0, 0, 1]`, used as given
/// (no decomposition): finite, invertible; any linear part (shears and mirrors included).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDesc {
    /// A row-major affine matrix, exclusive with the other fields; default none.
    #[serde(default)]
    pub matrix: Option<Vec<Vec<f64>>>,
    /// Translation; default none.
    #[serde(default)]
    pub translate: DVec3,
    /// Rotation; default none.
    #[serde(default)]
    pub rotate: Option<RotationDesc>,
    /// Per-axis scale; default `(1, 1, 1)`.
    #[serde(default = "default_scale")]
    pub scale: DVec3,
}

/// One entry of `objects`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// Optional name, used in messages and the query output.
    #[serde(default)]
    pub name: Option<String>,
    /// The primitive: any registered name, e.g. `Sphere(radius: 1)`.
    pub shape: ShapeDesc,
    /// Placement (at frame time 0 when `transform_close` is given); default identity.
    #[serde(default)]
    pub transform: Option<TransformDesc>,
    /// Placement at frame time 1 for a moving object (interpolated in between, see
    /// [`crate::motion`]); default none (static).
    #[serde(default)]
    pub transform_close: Option<TransformDesc>,
    /// Surface material.
    #[serde(default)]
    pub material: Material,
}

/// A light source.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum Light {
    /// A point light; irradiance falls off as `intensity / d²`.
    Point {
        /// Position.
        position: DVec3,
        /// Radiant intensity (linear RGB); default white.
        #[serde(default = "default_white")]
        intensity: DVec3,
    },
    /// A light at infinity shining along `direction`.
    Directional {
        /// Direction the light travels (from the light towards the scene).
        direction: DVec3,
        /// Irradiance on a surface facing the light (linear RGB); default white.
        #[serde(default = "default_white")]
        intensity: DVec3,
    },
}

/// `outputs: (aovs: [Beauty, Alpha, Depth, Normal], previews: true)`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Outputs {
    /// AOVs written to the EXR; default beauty, alpha, depth, normal.
    #[serde(default = "default_aovs")]
    pub aovs: Vec<Aov>,
    /// Whether PNG previews (beauty, depth, normals) are written; default true.
    #[serde(default = "default_true")]
    pub previews: bool,
}

impl Default for Outputs {
    fn default() -> Self {
        Self {
            aovs: default_aovs(),
            previews: true,
        }
    }
}

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Scene")]
pub struct SceneDesc {
    /// The camera.
    pub camera: CameraDesc,
    /// The objects.
    #[serde(default)]
    pub objects: Vec<ObjectDesc>,
    /// Light sources; with none, a headlight at the eye lights the scene (no shadows).
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Ambient light (linear RGB); default 0.1 grey.
    #[serde(default = "default_ambient")]
    pub ambient: DVec3,
    /// Colour of rays that hit nothing (linear RGB); default black.
    #[serde(default)]
    pub background: DVec3,
    /// What to write.
    #[serde(default)]
    pub outputs: Outputs,
    /// Samples per pixel, filter and seed; default one sample at each pixel centre.
    #[serde(default)]
    pub sampling: Sampling,
    /// Camera poses to render, one image each, with the camera's model and resolution (see
    /// [`crate::camera::pose`]); default none: the camera's own pose, one image.
    #[serde(default)]
    pub views: Vec<ViewDesc>,
}

/// How deeply RON values may nest in a scene file (RON's default is 128). A combinator level
/// takes four (its name, its fields, the `children` list, the operand), so this admits generated
/// trees of 1,000 levels; [`crate::scene::parse_scene_desc`] parses on a thread whose stack holds that depth.
pub const RON_NESTING_LIMIT: usize = 4_000;

/// Stack of the parsing thread for [`RON_NESTING_LIMIT`] levels: serde through `erased-serde`
/// takes about 60 KiB of stack per RON level (measured: a 64 MiB stack holds 250 `Difference`
/// levels but not 300), so 1 GiB leaves a margin of four. Only the pages a parse touches are
/// ever committed.
pub(crate) const PARSE_STACK_BYTES: usize = 1 << 30;

/// RON options used for scene files: `Some(…)` may be omitted, a primitive's fields may be
/// written directly inside its name's parentheses, and values may nest [`RON_NESTING_LIMIT`] deep.
#[must_use]
pub fn ron_options() -> ron::Options {
    ron::Options::default()
        .with_default_extension(Extensions::IMPLICIT_SOME | Extensions::UNWRAP_VARIANT_NEWTYPES)
        .with_recursion_limit(RON_NESTING_LIMIT)
}

impl TransformDesc {
    /// The affine map `T·R·S`; errors on non-finite values or a zero scale.
    pub fn to_affine(&self) -> Result<DAffine3, String> {
        build_transform(self)
    }
}

/// The affine map of a `matrix:` (see [`TransformDesc`]), validated: 3 or 4 rows of 4 finite
/// numbers, a 4th row of exactly `[0, 0, 0, 1]`, an invertible linear part (checked again, with
/// the same rule, by `Transformed::new`).
pub fn affine_from_rows(rows: &[Vec<f64>]) -> Result<DAffine3, String> {
    let field = "field `transform.matrix`";
    if rows.len() != 3 && rows.len() != 4 {
        return Err(format!(
            "{field}: expected 3 or 4 rows of 4 numbers (row-major affine), got {} rows",
            rows.len()
        ));
    }
    for (i, row) in rows.iter().enumerate() {
        if row.len() != 4 {
            return Err(format!("{field}: row {i} has {} numbers, expected 4", row.len()));
        }
        if let Some(j) = row.iter().position(|x| !x.is_finite()) {
            return Err(format!("{field}: entry [{i}][{j}] must be finite, got {}", row[j]));
        }
    }
    if rows.len() == 4 && rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "{field}: the last row must be [0, 0, 0, 1] (an affine map, not a projection), got {:?}",
            rows[3]
        ));
    }
    let column = |j: usize| DVec3::new(rows[0][j], rows[1][j], rows[2][j]);
    let linear = glam::DMat3::from_cols(column(0), column(1), column(2));
    let det = linear.determinant();
    let frobenius = (column(0).length_squared() + column(1).length_squared() + column(2).length_squared()).sqrt();
    // NaN-rejecting: a NaN determinant is singular too
    if det.abs().partial_cmp(&(1e-12 * frobenius.powi(3))) != Some(std::cmp::Ordering::Greater) {
        return Err(format!(
            "{field}: the 3×3 linear part is singular (determinant {det:e}); a transform must be invertible"
        ));
    }
    Ok(DAffine3::from_mat3_translation(linear, column(3)))
}

fn build_transform(t: &TransformDesc) -> Result<DAffine3, String> {
    if let Some(rows) = &t.matrix {
        if t.translate != DVec3::ZERO || t.rotate.is_some() || t.scale != DVec3::ONE {
            return Err("field `transform.matrix`: cannot be combined with translate, rotate or scale".into());
        }
        return affine_from_rows(rows);
    }
    if !t.translate.is_finite() {
        return Err(format!(
            "field `transform.translate`: must be finite, got {}",
            t.translate
        ));
    }
    if !t.scale.is_finite() || t.scale.x * t.scale.y * t.scale.z == 0.0 {
        return Err(format!(
            "field `transform.scale`: must be finite and non-zero, got {}",
            t.scale
        ));
    }
    let rotation = match &t.rotate {
        None => DQuat::IDENTITY,
        Some(r) => r
            .quat()
            .map_err(|problem| format!("field `transform.rotate`: {problem}"))?,
    };
    Ok(DAffine3::from_scale_rotation_translation(
        t.scale,
        rotation,
        t.translate,
    ))
}
