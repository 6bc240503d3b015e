//! The primitive registry: RON primitive names → parsers of their descriptions.
//!
//! Every primitive a scene names — built-in or user-defined — is found here by its RON name
//! (`Sphere(...)`, `Torus(...)`). A name maps to a parser that deserialises the entry into a type
//! implementing [`SceneShape`], whose [`SceneShape::build`] validates the parameters and makes the
//! primitive. The built-ins (`shapes`, `combinators`, `mesh_io`, the layer below) are listed here
//! and registered the same way as user types (see [`register`]), which may replace them.
//!
//! ```
//! use serde::Deserialize;
//! use std::sync::Arc;
//! use zeroset::scene::registry::{register, BuildContext, SceneShape};
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
//! assert!(zeroset::scene::registry::registered_names().contains(&"UnitBall".to_string()));
//! ```

use crate::scene::combinators::{
    DifferenceDesc, FunctionDesc, IntersectionDesc, OffsetDesc, SmoothUnionDesc, TransformedDesc, UnionDesc,
};
use crate::scene::mesh_io::MeshDesc;
use crate::scene::shapes::{
    BoxDesc, ConeDesc, CylinderDesc, DiskDesc, EllipsoidDesc, PlaneDesc, PolygonDesc, SphereDesc, TriangleDesc,
};
use serde::de::{DeserializeOwned, DeserializeSeed, EnumAccess, Error as _, VariantAccess, Visitor};
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;
use std::fmt;
use std::sync::{LazyLock, RwLock};

pub use crate::scene::shape_desc::{BuildContext, SceneShape, ShapeDesc};

type ShapeParserFn =
    for<'a, 'de> fn(&'a mut dyn erased_serde::Deserializer<'de>) -> Result<Box<dyn SceneShape>, erased_serde::Error>;

/// A registered name: its parser, and whether it is still the built-in of that name that
/// [`typed_builtin`] parses without `erased-serde`.
#[derive(Clone, Copy)]
struct Entry {
    parser: ShapeParserFn,
    typed: bool,
}

/// The table, by name. A name is kept for the life of the program (a user type's is leaked once,
/// when first registered), so that every [`ShapeDesc`] refers to it instead of holding a copy.
static REGISTRY: LazyLock<RwLock<BTreeMap<&'static str, Entry>>> = LazyLock::new(|| {
    let mut map = BTreeMap::new();
    let mut add = |name: &'static str, parser| {
        let typed = TYPED_BUILTINS.contains(&name);
        map.insert(name, Entry { parser, typed });
    };
    add("Sphere", parser_for::<SphereDesc>());
    add("Plane", parser_for::<PlaneDesc>());
    add("Box", parser_for::<BoxDesc>());
    add("Cylinder", parser_for::<CylinderDesc>());
    add("Cone", parser_for::<ConeDesc>());
    add("Ellipsoid", parser_for::<EllipsoidDesc>());
    add("Triangle", parser_for::<TriangleDesc>());
    add("Disk", parser_for::<DiskDesc>());
    add("Polygon", parser_for::<PolygonDesc>());
    add("Union", parser_for::<UnionDesc>());
    add("Intersection", parser_for::<IntersectionDesc>());
    add("Difference", parser_for::<DifferenceDesc>());
    add("SmoothUnion", parser_for::<SmoothUnionDesc>());
    add("Offset", parser_for::<OffsetDesc>());
    add("Transformed", parser_for::<TransformedDesc>());
    add("Function", parser_for::<FunctionDesc>());
    add("Mesh", parser_for::<MeshDesc>());
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
fn parser_for<T: SceneShape + DeserializeOwned + 'static>() -> ShapeParserFn {
    |d| Ok(Box::new(erased_serde::deserialize::<T>(d)?))
}

/// Registers `T` under the RON name `name` (replacing an earlier registration of that name).
pub fn register<T: SceneShape + DeserializeOwned + 'static>(name: &str) {
    let mut map = REGISTRY.write().unwrap_or_else(|e| e.into_inner());
    let key: &'static str = match map.get_key_value(name) {
        Some((&key, _)) => key,
        None => Box::leak(name.into()),
    };
    map.insert(
        key,
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
        .map(|name| (*name).to_string())
        .collect()
}

/// Whether `name` is registered as the built-in primitive of that name (not replaced by a user
/// type).
pub(crate) fn is_builtin(name: &str) -> bool {
    lookup(name).is_some_and(|(_, entry)| entry.typed)
}

/// The entry of `name`, with the registry's copy of the name.
fn lookup(name: &str) -> Option<(&'static str, Entry)> {
    REGISTRY
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .get_key_value(name)
        .map(|(&name, &entry)| (name, entry))
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
        let (name, variant) = data.variant()?;
        let (name, entry) = match name {
            VariantName::Registered(name, entry) => (name, entry),
            VariantName::Unknown(name) => {
                return Err(A::Error::custom(format!(
                    "unknown primitive `{name}`; registered primitives: {}",
                    registered_names().join(", ")
                )))
            }
        };
        let shape = if entry.typed {
            typed_builtin(name, variant)?
        } else {
            variant.newtype_variant_seed(ParserSeed(entry.parser))?
        };
        Ok(ShapeDesc { name, shape })
    }
}

/// A variant name, read as an identifier (not a quoted string), looked up in the registry.
enum VariantName {
    /// A registered name (the registry's copy) and its entry.
    Registered(&'static str, Entry),
    /// A name nobody registered.
    Unknown(String),
}

impl<'de> Deserialize<'de> for VariantName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct NameVisitor;
        impl Visitor<'_> for NameVisitor {
            type Value = VariantName;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a primitive name")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<VariantName, E> {
                Ok(match lookup(v) {
                    Some((name, entry)) => VariantName::Registered(name, entry),
                    None => VariantName::Unknown(v.to_string()),
                })
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
