//! The primitive registry: RON primitive names → parsers of their descriptions.
//!
//! Every primitive a scene names — built-in or user-defined — is found here by its RON name
//! (`Sphere(...)`, `Torus(...)`). A name maps to a parser that deserialises the entry into a type
//! implementing [`SceneShape`], whose [`SceneShape::build`] validates the parameters and makes the
//! [`Primitive`]. Built-ins are registered the same way as user types (see [`register`]); there is
//! no privileged list.
//!
//! ```
//! use serde::Deserialize;
//! use std::sync::Arc;
//! use zeroset::registry::{register, BuildContext, SceneShape};
//! use zeroset_primitives::{Primitive, PrimitiveError, Sphere};
//!
//! /// A unit sphere with only a centre parameter.
//! #[derive(Debug, Deserialize)]
//! #[serde(deny_unknown_fields)]
//! struct UnitBall { center: (f64, f64, f64) }
//!
//! impl SceneShape for UnitBall {
//!     fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
//!         let (x, y, z) = self.center;
//!         Ok(Arc::new(Sphere::new(glam::DVec3::new(x, y, z), 1.0)?))
//!     }
//! }
//!
//! register::<UnitBall>("UnitBall");
//! assert!(zeroset::registry::registered_names().contains(&"UnitBall".to_string()));
//! ```

use serde::de::{DeserializeOwned, DeserializeSeed, EnumAccess, Error as _, VariantAccess, Visitor};
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;
use std::fmt;
use std::sync::{Arc, LazyLock, RwLock};
use zeroset_primitives::{CsgOp, Primitive, PrimitiveError};

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
    /// degenerate triangles); the scene collects them per object ([`crate::scene::Scene::warnings`]).
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

    /// For a Boolean combinator (`Union`, `Intersection`, `Difference`), its operation and
    /// operands, so that an enclosing combinator can splice same-operation chains at load
    /// (`crate::combinators`); `None` (the default) for everything else.
    fn boolean_operands(&self) -> Option<(CsgOp, &[ShapeDesc])> {
        None
    }
}

pub(crate) type ShapeParserFn =
    for<'a, 'de> fn(&'a mut dyn erased_serde::Deserializer<'de>) -> Result<Box<dyn SceneShape>, erased_serde::Error>;

/// A registered name: its parser, and whether it is still the built-in of that name that
/// [`typed_builtin`] parses without `erased-serde`.
#[derive(Clone, Copy)]
struct Entry {
    parser: ShapeParserFn,
    typed: bool,
}

static REGISTRY: LazyLock<RwLock<BTreeMap<String, Entry>>> = LazyLock::new(|| {
    let mut map = BTreeMap::new();
    crate::shapes::register_builtins(&mut |name, parser| {
        let typed = TYPED_BUILTINS.contains(&name);
        map.insert(name.to_string(), Entry { parser, typed });
    });
    RwLock::new(map)
});

/// The built-in leaf primitives parsed by [`typed_builtin`].
const TYPED_BUILTINS: [&str; 9] = [
    "Sphere",
    "Plane",
    "Box",
    "Cylinder",
    "Cone",
    "Ellipsoid",
    "Triangle",
    "Disk",
    "Polygon",
];

/// Parses the built-in leaf primitive `name` (one of [`TYPED_BUILTINS`]) with the scene's own
/// deserializer, not through `erased-serde`: the same description, without a virtual call and a
/// type-erased boxing per value (a third of the parse of a million spheres).
fn typed_builtin<'de, V: VariantAccess<'de>>(name: &str, variant: V) -> Result<Box<dyn SceneShape>, V::Error> {
    use crate::shapes::{
        BoxDesc, ConeDesc, CylinderDesc, DiskDesc, EllipsoidDesc, PlaneDesc, PolygonDesc, SphereDesc, TriangleDesc,
    };
    fn boxed<T: SceneShape + 'static>(t: T) -> Box<dyn SceneShape> {
        Box::new(t)
    }
    Ok(match name {
        "Sphere" => boxed(variant.newtype_variant::<SphereDesc>()?),
        "Plane" => boxed(variant.newtype_variant::<PlaneDesc>()?),
        "Box" => boxed(variant.newtype_variant::<BoxDesc>()?),
        "Cylinder" => boxed(variant.newtype_variant::<CylinderDesc>()?),
        "Cone" => boxed(variant.newtype_variant::<ConeDesc>()?),
        "Ellipsoid" => boxed(variant.newtype_variant::<EllipsoidDesc>()?),
        "Triangle" => boxed(variant.newtype_variant::<TriangleDesc>()?),
        "Disk" => boxed(variant.newtype_variant::<DiskDesc>()?),
        "Polygon" => boxed(variant.newtype_variant::<PolygonDesc>()?),
        other => return Err(V::Error::custom(format!("`{other}` is not a typed built-in"))),
    })
}

/// The parser for `T`, as stored in the registry.
pub(crate) fn parser_for<T: SceneShape + DeserializeOwned + 'static>() -> ShapeParserFn {
    |d| Ok(Box::new(erased_serde::deserialize::<T>(d)?))
}

/// Registers `T` under the RON name `name` (replacing an earlier registration of that name).
pub fn register<T: SceneShape + DeserializeOwned + 'static>(name: &str) {
    REGISTRY.write().unwrap_or_else(|e| e.into_inner()).insert(
        name.to_string(),
        Entry {
            parser: parser_for::<T>(),
            typed: false,
        },
    );
}

/// Every registered RON name, sorted.
#[must_use]
pub fn registered_names() -> Vec<String> {
    REGISTRY
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .keys()
        .cloned()
        .collect()
}

fn lookup(name: &str) -> Option<Entry> {
    REGISTRY.read().unwrap_or_else(|e| e.into_inner()).get(name).copied()
}

/// A parsed primitive description of any registered type (`Name(field: value, …)` in RON).
#[derive(Debug)]
pub struct ShapeDesc {
    /// The RON name it was given under.
    pub name: String,
    /// The parsed description.
    pub shape: Box<dyn SceneShape>,
}

impl<'de> Deserialize<'de> for ShapeDesc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_enum("Primitive", &[], ShapeVisitor)
    }
}

struct ShapeVisitor;

impl<'de> Visitor<'de> for ShapeVisitor {
    type Value = ShapeDesc;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a primitive such as `Sphere(center: (0, 0, 0), radius: 1)`")
    }

    fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<ShapeDesc, A::Error> {
        let (VariantName(name), variant) = data.variant()?;
        let Some(entry) = lookup(&name) else {
            return Err(A::Error::custom(format!(
                "unknown primitive `{name}`; registered primitives: {}",
                registered_names().join(", ")
            )));
        };
        let shape = if entry.typed {
            typed_builtin(&name, variant)?
        } else {
            variant.newtype_variant_seed(ParserSeed(entry.parser))?
        };
        Ok(ShapeDesc { name, shape })
    }
}

/// A variant name, read as an identifier (not a quoted string).
struct VariantName(String);

impl<'de> Deserialize<'de> for VariantName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct NameVisitor;
        impl Visitor<'_> for NameVisitor {
            type Value = VariantName;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a primitive name")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<VariantName, E> {
                Ok(VariantName(v.to_string()))
            }
        }
        deserializer.deserialize_identifier(NameVisitor)
    }
}

struct ParserSeed(ShapeParserFn);

impl<'de> DeserializeSeed<'de> for ParserSeed {
    type Value = Box<dyn SceneShape>;

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<Self::Value, D::Error> {
        let mut erased = <dyn erased_serde::Deserializer>::erase(deserializer);
        (self.0)(&mut erased).map_err(D::Error::custom)
    }
}
