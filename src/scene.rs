//! Scenes: the RON description, its validation, and the loaded scene the renderer traces.
//!
//! The format is documented with one example per primitive in `scenes/README.md`. Parsing is
//! strict: unknown fields and unknown primitive names are errors reported as
//! `file:line:column: message`; after parsing, every value is validated and an error names the
//! object (index and name) and field.

use crate::aov::Aov;
use crate::camera::desc::ModelDesc;
use crate::camera::pose::{build_views, ViewDesc};
use crate::camera::{Camera, CameraError, Model};
use crate::motion::{Moving, Placement};
use crate::registry::{BuildContext, ShapeDesc};
use crate::sampling::Sampling;
use glam::{DAffine3, DQuat, DVec3};
use ron::extensions::Extensions;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zeroset_primitives::{Primitive, Transformed};

use crate::tracing::Hierarchy;

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The scene file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// RON syntax, an unknown field or primitive, a wrong type.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// The scene file.
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser said.
        message: String,
    },
    /// A value that parsed but is impossible (zero radius, NaN, up parallel to the view…).
    #[error("{path}: {location}: {message}")]
    Invalid {
        /// The scene file.
        path: String,
        /// What is wrong: `camera`, `objects[3] "ball"`, `lights[0]`, ….
        location: String,
        /// Field and problem.
        message: String,
    },
}

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

/// Where loading spent its time (for the loading benchmark, `benches/load.rs`).
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadTiming {
    /// Seconds spent building the hierarchy over the objects' bounds.
    pub hierarchy: f64,
}

/// A placed primitive with its material: 48 bytes, plus the primitive's own allocation (a
/// million spheres take about 150 B each with the hierarchy).
#[derive(Clone, Debug)]
pub struct Object {
    /// Name from the scene file, if any.
    pub name: Option<Box<str>>,
    /// The primitive in world space (its transform applied; for a moving object, placed at frame
    /// time 0, which is what time-less queries such as [`Scene::intersect`] see).
    pub primitive: Arc<dyn Primitive>,
    /// The motion of a moving object; `None` for a static one (which ignores ray times).
    pub motion: Option<Arc<Moving>>,
    /// Surface material, shared by the objects that have equal ones.
    pub material: Arc<Material>,
}

/// The bits of a material's fields: equal keys, equal materials.
fn material_key(m: &Material) -> [u64; 5] {
    [m.color.x, m.color.y, m.color.z, m.specular, m.shininess].map(f64::to_bits)
}

/// A loaded, validated scene.
#[derive(Debug)]
pub struct Scene {
    /// Where it was loaded from (for messages and the EXR header).
    pub source: Option<PathBuf>,
    /// The camera.
    pub camera: Camera,
    /// Objects, in file order (the `PrimitiveId` AOV is an index into this).
    pub objects: Vec<Object>,
    /// Light sources.
    pub lights: Vec<Light>,
    /// Ambient light.
    pub ambient: DVec3,
    /// Background colour.
    pub background: DVec3,
    /// Requested outputs.
    pub outputs: Outputs,
    /// Samples per pixel, filter and seed.
    pub sampling: Sampling,
    /// The cameras of the scene's `views`, in order; empty when there are none (then `camera`
    /// is the one view).
    pub views: Vec<Camera>,
    /// Warnings about valid but noteworthy input, each prefixed by its object (degenerate
    /// triangles left out, a `Function` that may be undefined in parts of its box, …); the CLI
    /// prints them.
    pub warnings: Vec<String>,
    /// What the traversal walks over the objects ([`crate::tracing`]).
    pub(crate) hierarchy: Hierarchy,
}

/// How deeply RON values may nest in a scene file (RON's default is 128). A combinator level
/// takes four (its name, its fields, the `children` list, the operand), so this admits generated
/// trees of 1,000 levels; [`parse_scene_desc`] parses on a thread whose stack holds that depth.
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

/// Parses scene text with [`ron_options`] on a thread with a stack for [`RON_NESTING_LIMIT`]
/// levels (the caller's may be a 2 MiB worker's). An `objects` list of 20,000 elements or more
/// is split over threads (`parallel_parse`), with the same result.
pub fn parse_scene_desc(text: &str) -> Result<SceneDesc, ron::error::SpannedError> {
    std::thread::scope(|scope| {
        let parser = std::thread::Builder::new()
            .name("scene parser".into())
            .stack_size(PARSE_STACK_BYTES)
            .spawn_scoped(scope, || match crate::parallel_parse::parse_objects_in_parallel(text) {
                Some(desc) => Ok(desc),
                None => ron_options().from_str::<SceneDesc>(text),
            });
        match parser {
            Ok(handle) => handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            // no thread to be had: parse here, within RON's default limit for the caller's stack
            Err(_) => ron::Options::default()
                .with_default_extension(Extensions::IMPLICIT_SOME | Extensions::UNWRAP_VARIANT_NEWTYPES)
                .from_str(text),
        }
    })
}

fn check_finite(location: &str, field: &str, v: DVec3) -> Result<(), (String, String)> {
    if v.is_finite() {
        Ok(())
    } else {
        Err((
            location.to_string(),
            format!("field `{field}`: must be finite, got {v}"),
        ))
    }
}

impl Scene {
    /// Reads, parses and validates a scene file.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut scene = Self::from_ron_in(&text, &path.display().to_string(), &BuildContext::new(dir))?;
        scene.source = Some(path.to_path_buf());
        Ok(scene)
    }

    /// Parses and validates scene text; `path` is only used in messages, and relative file paths
    /// in the scene resolve against the current directory.
    pub fn from_ron(text: &str, path: &str) -> Result<Self, SceneError> {
        Self::from_ron_in(text, path, &BuildContext::default())
    }

    /// Parses and validates scene text, building primitives in `context`.
    pub fn from_ron_in(text: &str, path: &str, context: &BuildContext) -> Result<Self, SceneError> {
        let desc: SceneDesc = parse_scene_desc(text).map_err(|e| SceneError::Parse {
            path: path.to_string(),
            line: e.span.start.line,
            column: e.span.start.col,
            // the limit's error reaches here as a message when raised below a registered
            // primitive (through `erased-serde`), so it is recognised by its text too
            message: match e.code.to_string() {
                m if m == ron::Error::ExceededRecursionLimit.to_string() => format!(
                    "values nest more than {RON_NESTING_LIMIT} levels deep (about 650 nested \
                     combinators); write a chain of the same operation as one combinator with \
                     many `children`"
                ),
                m => m,
            },
        })?;
        Self::from_desc(desc, context).map_err(|(location, message)| SceneError::Invalid {
            path: path.to_string(),
            location,
            message,
        })
    }

    /// Validates a parsed description; the error is `(location, message)`.
    pub fn from_desc(desc: SceneDesc, context: &BuildContext) -> Result<Self, (String, String)> {
        Self::from_desc_timed(desc, context).map(|(scene, _)| scene)
    }

    /// [`Scene::from_desc`], also reporting how long the hierarchy took to build.
    pub fn from_desc_timed(desc: SceneDesc, context: &BuildContext) -> Result<(Self, LoadTiming), (String, String)> {
        let camera = build_camera(&desc.camera)
            .map_err(|e| ("camera".to_string(), format!("field `{}`: {}", e.field, e.problem)))?;
        let views = build_views(&desc.views, &camera, &context.scene_dir)?;
        check_finite("scene", "ambient", desc.ambient)?;
        check_finite("scene", "background", desc.background)?;
        let mut objects = Vec::with_capacity(desc.objects.len());
        let mut warnings = Vec::new();
        // equal materials share one allocation
        let mut materials: std::collections::HashMap<[u64; 5], Arc<Material>> = std::collections::HashMap::new();
        for (index, object) in desc.objects.into_iter().enumerate() {
            // formatted only for an error (a million objects need no million strings)
            let location = || match &object.name {
                Some(name) => format!("objects[{index}] {name:?} ({})", object.shape.name),
                None => format!("objects[{index}] ({})", object.shape.name),
            };
            let mut primitive = object
                .shape
                .shape
                .build(context)
                .map_err(|e| (location(), format!("field `{}`: {}", e.field, e.problem)))?;
            warnings.extend(
                context
                    .take_warnings()
                    .into_iter()
                    .map(|w| format!("{}: {w}", location())),
            );
            let motion = match &object.transform_close {
                None => None,
                Some(close) => {
                    let start = match &object.transform {
                        None => Placement::IDENTITY,
                        Some(t) => placement(t).map_err(|m| (location(), m))?,
                    };
                    let end =
                        placement(close).map_err(|m| (location(), m.replace("`transform.", "`transform_close.")))?;
                    // a "motion" to the same placement is a static object, bit for bit
                    if start == end {
                        None
                    } else {
                        Some(Arc::new(
                            Moving::new(primitive.clone(), start, end).map_err(|m| (location(), m))?,
                        ))
                    }
                }
            };
            if let Some(t) = &object.transform {
                let m = build_transform(t).map_err(|m| (location(), m))?;
                primitive = Arc::new(
                    Transformed::new(primitive, m).map_err(|e| (location(), format!("transform: {}", e.problem)))?,
                );
            }
            let m = object.material;
            if !m.color.is_finite() {
                check_finite(&location(), "material.color", m.color)?;
            }
            if !(m.specular.is_finite() && m.specular >= 0.0 && m.shininess.is_finite() && m.shininess > 0.0) {
                return Err((
                    location(),
                    "field `material`: specular must be ≥ 0 and shininess > 0, both finite".into(),
                ));
            }
            let material = match materials.entry(material_key(&m)) {
                std::collections::hash_map::Entry::Occupied(e) => e.get().clone(),
                std::collections::hash_map::Entry::Vacant(e) => e.insert(Arc::new(m)).clone(),
            };
            objects.push(Object {
                name: object.name.map(String::into_boxed_str),
                primitive,
                motion,
                material,
            });
        }
        for (index, light) in desc.lights.iter().enumerate() {
            let location = format!("lights[{index}]");
            match *light {
                Light::Point { position, intensity } => {
                    check_finite(&location, "position", position)?;
                    check_finite(&location, "intensity", intensity)?;
                }
                Light::Directional { direction, intensity } => {
                    if !direction.is_finite() || direction.length() == 0.0 {
                        return Err((location, "field `direction`: must be finite and non-zero".into()));
                    }
                    check_finite(&location, "intensity", intensity)?;
                }
            }
        }
        if desc.outputs.aovs.is_empty() {
            return Err(("outputs".into(), "field `aovs`: list at least one AOV".into()));
        }
        desc.sampling.validate().map_err(|m| ("sampling".to_string(), m))?;
        let start = std::time::Instant::now();
        let mut scene = Self::assemble(
            camera,
            objects,
            desc.lights,
            desc.ambient,
            desc.background,
            desc.outputs,
        );
        let timing = LoadTiming {
            hierarchy: start.elapsed().as_secs_f64(),
        };
        scene.sampling = desc.sampling;
        scene.views = views;
        scene.warnings = warnings;
        Ok((scene, timing))
    }

    /// Builds the acceleration structure over validated parts.
    #[must_use]
    pub fn assemble(
        camera: Camera,
        objects: Vec<Object>,
        lights: Vec<Light>,
        ambient: DVec3,
        background: DVec3,
        outputs: Outputs,
    ) -> Self {
        let hierarchy = Hierarchy::build(&objects);
        Self {
            source: None,
            camera,
            objects,
            lights,
            ambient,
            background,
            outputs,
            sampling: Sampling::default(),
            views: Vec::new(),
            warnings: Vec::new(),
            hierarchy,
        }
    }

    /// Whether any object moves (then the time of a ray matters).
    #[must_use]
    pub fn has_motion(&self) -> bool {
        self.objects.iter().any(|o| o.motion.is_some())
    }

    /// Calls `f` with object `object`'s primitive as placed at frame time `time` (static objects
    /// ignore the time).
    #[inline]
    pub fn with_primitive_at<R>(&self, object: u32, time: f64, f: impl FnOnce(&dyn Primitive) -> R) -> R {
        let o = &self.objects[object as usize];
        match &o.motion {
            None => f(&*o.primitive),
            Some(m) => m.with_primitive_at(time, f),
        }
    }
}

fn build_camera(c: &CameraDesc) -> Result<Camera, CameraError> {
    let direction = match (c.look_at, c.direction) {
        (Some(_), Some(_)) => {
            return Err(CameraError {
                field: "direction",
                problem: "give either `look_at` or `direction`, not both".into(),
            })
        }
        (Some(target), None) => {
            if !target.is_finite() {
                return Err(CameraError {
                    field: "look_at",
                    problem: format!("must be finite, got {target}"),
                });
            }
            target - c.eye
        }
        (None, Some(d)) => d,
        (None, None) => -c.eye,
    };
    let vfov = match (c.vfov_deg, c.hfov_deg) {
        (Some(v), None) => v,
        (None, Some(h)) => {
            if !(h > 0.0 && h < 180.0) {
                return Err(CameraError {
                    field: "hfov_deg",
                    problem: format!("must lie in (0, 180) degrees, got {h}"),
                });
            }
            Camera::vfov_from_hfov(h, c.width.max(1), c.height.max(1))
        }
        (None, None) => 45.0,
        (Some(v), Some(h)) => {
            let implied = Camera::vfov_from_hfov(h, c.width.max(1), c.height.max(1));
            if (implied - v).abs() > 1e-6 * v.abs().max(1.0) {
                return Err(CameraError {
                    field: "hfov_deg",
                    problem: format!(
                        "{h}° is inconsistent with vfov_deg {v}° at {}×{} with square pixels",
                        c.width, c.height
                    ),
                });
            }
            v
        }
    };
    let model = c.model.as_ref().map(ModelDesc::build).transpose()?;
    if let Some(model) = &model {
        if !matches!(model, Model::Perspective(_)) && (c.vfov_deg.is_some() || c.hfov_deg.is_some()) {
            return Err(CameraError {
                field: if c.vfov_deg.is_some() { "vfov_deg" } else { "hfov_deg" },
                problem: format!(
                    "is a Perspective setting; the {} model takes its field in `model`",
                    model.name()
                ),
            });
        }
    }
    let mut camera = Camera::new(c.eye, direction, c.up, vfov, c.width, c.height)?;
    if let Some(model) = model {
        camera = camera.with_model(model)?;
    }
    let focus = match (c.focus_distance, c.look_at) {
        (Some(f), _) => f,
        (None, Some(target)) => (target - c.eye).dot(camera.forward),
        (None, None) if c.aperture == 0.0 || c.direction.is_none() => camera.focus_distance,
        (None, None) => {
            return Err(CameraError {
                field: "focus_distance",
                problem: "is required with `direction` and a non-zero `aperture`".into(),
            })
        }
    };
    let shutter = c.shutter.unwrap_or(ShutterDesc { open: 0.0, close: 1.0 });
    camera
        .with_lens(c.aperture, focus)?
        .with_shutter(shutter.open, shutter.close)
}

impl TransformDesc {
    /// The affine map `T·R·S`; errors on non-finite values or a zero scale.
    pub fn to_affine(&self) -> Result<DAffine3, String> {
        build_transform(self)
    }
}

/// The components of a transform description, validated as [`TransformDesc::to_affine`] does.
fn placement(t: &TransformDesc) -> Result<Placement, String> {
    build_transform(t)?;
    if t.matrix.is_some() {
        return Err(
            "field `transform.matrix`: a moving object (with `transform_close`) needs translate/rotate/scale \
             placements, which are interpolated; a matrix is not decomposed"
                .into(),
        );
    }
    Ok(Placement {
        scale: t.scale,
        rotation: match &t.rotate {
            None => DQuat::IDENTITY,
            Some(r) => r.quat()?,
        },
        translation: t.translate,
    })
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
