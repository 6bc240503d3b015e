//! What a primitive's description is: the [`SceneShape`] contract (validate the parameters,
//! build the [`Primitive`]), the [`BuildContext`] a build may use, and [`ShapeDesc`], a parsed
//! description of any registered type.
//!
//! This is the bottom of the loading layers (see the crate docs): the built-in descriptions
//! (`shapes`, `combinators`, `mesh_io`) implement [`SceneShape`], and the registry above them
//! maps RON names to their parsers (it implements `Deserialize` for [`ShapeDesc`]).

use std::collections::BTreeMap;
use std::fmt;
use std::sync::Arc;
use zeroset_primitives::{CsgOp, Primitive, PrimitiveError, Sphere};

/// What a [`SceneShape`] may need from the scene being loaded.
#[derive(Debug, Default)]
pub struct BuildContext {
    /// Directory of the scene file: relative paths in a description (mesh files) are resolved
    /// against it.
    pub scene_dir: std::path::PathBuf,
    /// Primitives already built from files, by resolved path, so that objects naming the same file
    /// share one copy (instancing without copying).
    pub loaded: std::sync::Mutex<BTreeMap<std::path::PathBuf, Arc<dyn Primitive>>>,
    /// Warnings raised while building (valid input the user may want to know about, such as
    /// degenerate triangles); the scene collects them per object (`Scene::warnings`).
    pub warnings: std::sync::Mutex<Vec<String>>,
}

impl BuildContext {
    /// A context for a scene in `scene_dir`.
    #[must_use]
    pub fn new(scene_dir: impl Into<std::path::PathBuf>) -> Self {
        Self {
            scene_dir: scene_dir.into(),
            loaded: std::sync::Mutex::default(),
            warnings: std::sync::Mutex::default(),
        }
    }

    /// Records a warning about the primitive being built.
    pub fn warn(&self, message: impl Into<String>) {
        self.warnings
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(message.into());
    }

    /// Takes the warnings recorded so far.
    pub fn take_warnings(&self) -> Vec<String> {
        std::mem::take(&mut *self.warnings.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// `path` resolved against the scene's directory (absolute paths are kept).
    #[must_use]
    pub fn resolve(&self, path: &std::path::Path) -> std::path::PathBuf {
        self.scene_dir.join(path)
    }
}

/// A scene-file description of a primitive: parsed from RON, validated and built into a
/// [`Primitive`] after the whole file has parsed.
pub trait SceneShape: fmt::Debug + Send + Sync {
    /// Validates the parameters and builds the primitive (in the object's local space; the
    /// object's transform is applied by the scene).
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError>;

    /// [`SceneShape::build`] as a scene object stores it: shared behind an `Arc` (the default),
    /// or held in the object itself where the primitive is small (a sphere), which saves an
    /// allocation per object.
    fn build_object_primitive(&self, context: &BuildContext) -> Result<ObjectPrimitive, PrimitiveError> {
        self.build(context).map(ObjectPrimitive::Shared)
    }

    /// For a Boolean combinator (`Union`, `Intersection`, `Difference`), its operation and
    /// operands, so that an enclosing combinator can splice same-operation chains at load
    /// (`combinators`); `None` (the default) for everything else.
    fn boolean_operands(&self) -> Option<(CsgOp, &[ShapeDesc])> {
        None
    }

    /// For a wrapper that leaves its shape as it is (a `Transformed` by the identity), that
    /// shape, so that load-time flattening looks through the wrapper (`combinators`); `None`
    /// (the default) for everything else.
    fn identity_of(&self) -> Option<&ShapeDesc> {
        None
    }

    /// For a `Transformed`, its shape and placement, so that nested placements are composed into
    /// one at load; `None` (the default) for everything else.
    fn placement(&self) -> Option<(&ShapeDesc, &crate::scene::desc::TransformDesc)> {
        None
    }
}

/// A parsed primitive description of any registered type (`Name(field: value, …)` in RON).
#[derive(Debug)]
pub struct ShapeDesc {
    /// The RON name it was given under (the registry's copy).
    pub name: &'static str,
    /// The parsed description.
    pub shape: Box<dyn SceneShape>,
}

/// A scene object's primitive: a sphere held in place (40 bytes in the object, where an `Arc`
/// would cost 16 bytes plus a 64-byte allocation; a million spheres: 40 MB less), anything else
/// shared. It dereferences to the primitive.
#[derive(Clone, Debug)]
pub enum ObjectPrimitive {
    /// A sphere, in place.
    Sphere(Sphere),
    /// Any primitive, shared.
    Shared(Arc<dyn Primitive>),
}

impl ObjectPrimitive {
    /// The primitive behind an `Arc` (a sphere moved into a new one), for wrappers that share
    /// it (transforms, motion).
    #[must_use]
    pub fn into_shared(self) -> Arc<dyn Primitive> {
        match self {
            ObjectPrimitive::Sphere(sphere) => Arc::new(sphere),
            ObjectPrimitive::Shared(primitive) => primitive,
        }
    }
}

impl std::ops::Deref for ObjectPrimitive {
    type Target = dyn Primitive;

    #[inline]
    fn deref(&self) -> &(dyn Primitive + 'static) {
        match self {
            ObjectPrimitive::Sphere(sphere) => sphere,
            ObjectPrimitive::Shared(primitive) => &**primitive,
        }
    }
}

impl From<Arc<dyn Primitive>> for ObjectPrimitive {
    fn from(primitive: Arc<dyn Primitive>) -> Self {
        ObjectPrimitive::Shared(primitive)
    }
}
