//! Scenes: the RON description, its validation, and the loaded scene the renderer traces.
//!
//! The format is documented with one example per primitive in `scenes/README.md`. Parsing is
//! strict: unknown fields and unknown primitive names are errors reported as
//! `file:line:column: message`; after parsing, every value is validated and an error names the
//! object (index and name) and field.

use crate::camera::desc::ModelDesc;
use crate::camera::pose::build_views;
use crate::camera::{Camera, CameraError, Model};
use crate::resources::{open_input, read_input_to_string};
use crate::sampling::Sampling;
use crate::scene::desc::PARSE_STACK_BYTES;
use crate::scene::objects::{BuiltObjects, ObjectBuilder};
use crate::scene::registry::BuildContext;
use hierarchy::Hierarchy;

pub mod combinators;
pub mod desc;
mod fast_sphere;
pub(crate) mod hierarchy;
mod load_stream;
pub mod mesh_io;
pub mod objects;
mod parallel_parse;
pub mod registry;
pub mod shape_desc;
pub mod shapes;
use glam::DVec3;
use ron::extensions::Extensions;
use std::path::{Path, PathBuf};
use zeroset_primitives::Primitive;

// The scene file's types are defined with the other descriptions (`crate::scene::desc`) and the built
// objects with their builder (`crate::scene::objects`); they are re-exported here, where they were first
// defined.
pub use crate::scene::desc::{
    affine_from_rows, ron_options, CameraDesc, Light, Material, ObjectDesc, Outputs, RotationDesc, SceneDesc,
    ShutterDesc, TransformDesc, RON_NESTING_LIMIT,
};
pub use crate::scene::objects::Object;

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

/// Where loading spent its time (for the loading benchmark, `benches/load.rs`).
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadTiming {
    /// Seconds spent on the objects and the checks of the scene's other fields: building them
    /// ([`Scene::from_desc_timed`]), or reading, parsing and building them at once (a streamed
    /// [`Scene::load_timed`]; a load in one piece counts only the build).
    pub objects: f64,
    /// Seconds spent building the hierarchy over the objects' bounds.
    pub hierarchy: f64,
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
    /// What the traversal walks over the objects ([`crate::trace`]).
    pub(crate) hierarchy: Hierarchy,
}

/// Parses scene text with [`ron_options`] on a thread with a stack for [`RON_NESTING_LIMIT`]
/// levels (the caller's may be a 2 MiB worker's). An `objects` list of 20,000 elements or more
/// is split over threads (`parallel_parse`), with the same result.
pub fn parse_scene_desc(text: &str) -> Result<SceneDesc, ron::error::SpannedError> {
    std::thread::scope(|scope| {
        let parser = std::thread::Builder::new()
            .name("scene parser".into())
            .stack_size(PARSE_STACK_BYTES)
            .spawn_scoped(
                scope,
                || match crate::scene::parallel_parse::parse_objects_in_parallel(text) {
                    Some(desc) => Ok(desc),
                    None => ron_options().from_str::<SceneDesc>(text),
                },
            );
        match parser {
            Ok(handle) => handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            // no thread to be had: parse here, within RON's default limit for the caller's stack
            Err(_) => ron::Options::default()
                .with_default_extension(Extensions::IMPLICIT_SOME | Extensions::UNWRAP_VARIANT_NEWTYPES)
                .from_str(text),
        }
    })
}

fn invalid(path: &str, (location, message): (String, String)) -> SceneError {
    SceneError::Invalid {
        path: path.to_string(),
        location,
        message,
    }
}

/// The whole text parsed as one value (the `objects` list split over threads when it is large,
/// see [`parse_scene_desc`]), an error reported with its line and column.
fn parse_in_one_piece(text: &str, path: &str) -> Result<SceneDesc, SceneError> {
    parse_scene_desc(text).map_err(|e| SceneError::Parse {
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
    })
}

/// The camera and the views of a description, with the checks made before the objects'
/// (ambient and background colours).
fn build_cameras(desc: &SceneDesc, context: &BuildContext) -> Result<(Camera, Vec<Camera>), (String, String)> {
    let camera = build_camera(&desc.camera)
        .map_err(|e| ("camera".to_string(), format!("field `{}`: {}", e.field, e.problem)))?;
    let views = build_views(&desc.views, &camera, &context.scene_dir)?;
    check_finite("scene", "ambient", desc.ambient)?;
    check_finite("scene", "background", desc.background)?;
    Ok((camera, views))
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
    ///
    /// A large `objects` list is streamed (`crate::scene::load_stream`): read in blocks, parsed on worker
    /// threads and built in file order, so that neither the text nor the list of descriptions is
    /// ever held whole. Anything unusual (an error above all) loads the whole text in one piece
    /// instead, so messages keep their exact line and column.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        Self::load_timed(path).map(|(scene, _)| scene)
    }

    /// [`Scene::load`], also reporting where the time went.
    pub fn load_timed(path: &Path) -> Result<(Self, LoadTiming), SceneError> {
        let start = std::time::Instant::now();
        let io = |source| SceneError::Io {
            path: path.display().to_string(),
            source,
        };
        let name = path.display().to_string();
        let context = BuildContext::new(path.parent().map(Path::to_path_buf).unwrap_or_default());
        // a regular file within the input limit, read with that bound (never a FIFO or device)
        let mut input = open_input(path, "scene file").map_err(io)?;
        let streamed = crate::scene::load_stream::load_streamed(input.reader(), &context);
        let (mut scene, timing) = match streamed {
            Some(built) => Self::from_built(built, &context, start).map_err(|e| invalid(&name, e))?,
            None => {
                let text = read_input_to_string(path, "scene file").map_err(io)?;
                let desc = parse_in_one_piece(&text, &name)?;
                Self::from_desc_timed(desc, &context).map_err(|e| invalid(&name, e))?
            }
        };
        scene.source = Some(path.to_path_buf());
        Ok((scene, timing))
    }

    /// Parses and validates scene text; `path` is only used in messages, and relative file paths
    /// in the scene resolve against the current directory.
    pub fn from_ron(text: &str, path: &str) -> Result<Self, SceneError> {
        Self::from_ron_in(text, path, &BuildContext::default())
    }

    /// Parses and validates scene text, building primitives in `context` (a large `objects` list
    /// streamed as by [`Scene::load`]).
    pub fn from_ron_in(text: &str, path: &str, context: &BuildContext) -> Result<Self, SceneError> {
        if let Some(built) = crate::scene::load_stream::load_streamed(text.as_bytes(), context) {
            return Self::from_built(built, context, std::time::Instant::now())
                .map(|(scene, _)| scene)
                .map_err(|e| invalid(path, e));
        }
        let desc = parse_in_one_piece(text, path)?;
        Self::from_desc(desc, context).map_err(|e| invalid(path, e))
    }

    /// Validates a parsed description; the error is `(location, message)`.
    pub fn from_desc(desc: SceneDesc, context: &BuildContext) -> Result<Self, (String, String)> {
        Self::from_desc_timed(desc, context).map(|(scene, _)| scene)
    }

    /// [`Scene::from_desc`], also reporting how long the objects and the hierarchy took to build.
    pub fn from_desc_timed(
        mut desc: SceneDesc,
        context: &BuildContext,
    ) -> Result<(Self, LoadTiming), (String, String)> {
        let start = std::time::Instant::now();
        let objects = std::mem::take(&mut desc.objects);
        // the scene's own fields are checked before the objects, as they always were
        let cameras = build_cameras(&desc, context)?;
        let mut builder = ObjectBuilder::new(context, objects.len());
        for object in objects {
            builder.push(object)?;
        }
        let built = BuiltObjects {
            skeleton: desc,
            objects: builder.objects,
            warnings: builder.warnings,
        };
        Self::finish(built, cameras, start)
    }

    /// The scene of objects built by a streamed load, its other fields validated.
    fn from_built(
        built: BuiltObjects,
        context: &BuildContext,
        start: std::time::Instant,
    ) -> Result<(Self, LoadTiming), (String, String)> {
        let cameras = build_cameras(&built.skeleton, context)?;
        Self::finish(built, cameras, start)
    }

    /// The checks that follow the objects' (lights, outputs, sampling), then the hierarchy.
    fn finish(
        built: BuiltObjects,
        (camera, views): (Camera, Vec<Camera>),
        start: std::time::Instant,
    ) -> Result<(Self, LoadTiming), (String, String)> {
        let BuiltObjects {
            skeleton: desc,
            objects,
            warnings,
        } = built;
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
        let objects_done = std::time::Instant::now();
        let mut scene = Self::assemble(
            camera,
            objects,
            desc.lights,
            desc.ambient,
            desc.background,
            desc.outputs,
        );
        let timing = LoadTiming {
            objects: (objects_done - start).as_secs_f64(),
            hierarchy: objects_done.elapsed().as_secs_f64(),
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
