//! Scene objects built from their descriptions: an [`ObjectDesc`] (primitive description,
//! transform, motion, material) becomes an [`Object`], the placed primitive the tracer tests.
//!
//! `ObjectBuilder` builds them one at a time in file order, so that the whole description list
//! never has to exist at once (a streamed load builds each parsed batch and drops it), while the
//! messages stay those of a build over the whole list: every error names the object by its index
//! in `objects`, its name and its primitive, then the field.

use crate::motion::{Moving, Placement};
use crate::scene::desc::{Material, ObjectDesc, SceneDesc, TransformDesc};
use crate::scene::shape_desc::BuildContext;
pub use crate::scene::shape_desc::ObjectPrimitive;
use glam::DQuat;
use std::collections::hash_map::{Entry, HashMap};
use std::sync::Arc;
use zeroset_primitives::{Sphere, Transformed};

/// A placed primitive with its material: 72 bytes, a sphere included (other primitives add
/// their own shared allocation).
#[derive(Clone, Debug)]
pub struct Object {
    /// Name from the scene file, if any.
    pub name: Option<Box<str>>,
    /// The primitive in world space (its transform applied; for a moving object, placed at frame
    /// time 0, which is what time-less queries such as `Scene::intersect` see).
    pub primitive: ObjectPrimitive,
    /// The motion of a moving object; `None` for a static one (which ignores ray times).
    pub motion: Option<Arc<Moving>>,
    /// Surface material, shared by the objects that have equal ones.
    pub material: Arc<Material>,
}

/// The bits of a material's fields: equal keys, equal materials.
fn material_key(m: &Material) -> [u64; 5] {
    [m.color.x, m.color.y, m.color.z, m.specular, m.shininess].map(f64::to_bits)
}

/// Objects built in file order, with the rest of the description (its `objects` empty) and the
/// warnings the builds raised.
pub(crate) struct BuiltObjects {
    /// The scene description without its objects.
    pub(crate) skeleton: SceneDesc,
    /// The objects, in file order.
    pub(crate) objects: Vec<Object>,
    /// Build warnings, each prefixed by its object.
    pub(crate) warnings: Vec<String>,
}

/// Builds objects from their descriptions in file order, sharing equal materials and collecting
/// the build warnings prefixed by their object.
#[derive(Debug)]
pub(crate) struct ObjectBuilder<'c> {
    context: &'c BuildContext,
    /// One allocation per distinct material.
    materials: HashMap<[u64; 5], Arc<Material>>,
    /// The last material asked for, with its key.
    last_material: Option<([u64; 5], Arc<Material>)>,
    /// The objects built so far; the next one is `objects[objects.len()]` of the file.
    pub(crate) objects: Vec<Object>,
    /// Warnings, each prefixed by its object.
    pub(crate) warnings: Vec<String>,
}

impl<'c> ObjectBuilder<'c> {
    /// A builder for about `capacity` objects in `context`.
    pub(crate) fn new(context: &'c BuildContext, capacity: usize) -> Self {
        Self {
            context,
            materials: HashMap::new(),
            last_material: None,
            objects: Vec::with_capacity(capacity),
            warnings: Vec::new(),
        }
    }

    /// The next object, a sphere already built (from a plain sphere element, which gives no
    /// warnings): exactly what [`ObjectBuilder::push`] builds from its description.
    pub(crate) fn push_sphere(
        &mut self,
        name: Option<String>,
        sphere: Sphere,
        material: Material,
    ) -> Result<(), (String, String)> {
        let material = self
            .material(material)
            .map_err(|m| (location(self.objects.len(), name.as_deref(), "Sphere"), m))?;
        self.objects.push(Object {
            name: name.map(String::into_boxed_str),
            primitive: ObjectPrimitive::Sphere(sphere),
            motion: None,
            material,
        });
        Ok(())
    }

    /// Checks a material and gives the shared allocation of its value (the previous object's
    /// when equal, without hashing: runs of one material are the common case).
    fn material(&mut self, m: Material) -> Result<Arc<Material>, String> {
        if !m.color.is_finite() {
            return Err(format!("field `material.color`: must be finite, got {}", m.color));
        }
        if !(m.specular.is_finite() && m.specular >= 0.0 && m.shininess.is_finite() && m.shininess > 0.0) {
            return Err("field `material`: specular must be ≥ 0 and shininess > 0, both finite".into());
        }
        let key = material_key(&m);
        if let Some((last, shared)) = &self.last_material {
            if *last == key {
                return Ok(shared.clone());
            }
        }
        let shared = match self.materials.entry(key) {
            Entry::Occupied(e) => e.get().clone(),
            Entry::Vacant(e) => e.insert(Arc::new(m)).clone(),
        };
        self.last_material = Some((key, shared.clone()));
        Ok(shared)
    }

    /// Validates and builds the next object; the error is `(location, message)`, the location
    /// `objects[index] "name" (Primitive)`.
    pub(crate) fn push(&mut self, object: ObjectDesc) -> Result<(), (String, String)> {
        let index = self.objects.len();
        // formatted only for an error (a million objects need no million strings)
        let location = || location(index, object.name.as_deref(), object.shape.name);
        let context = self.context;
        let mut primitive = object
            .shape
            .shape
            .build_object_primitive(context)
            .map_err(|e| (location(), format!("field `{}`: {}", e.field, e.problem)))?;
        self.warnings.extend(
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
                let end = placement(close).map_err(|m| (location(), m.replace("`transform.", "`transform_close.")))?;
                // a "motion" to the same placement is a static object, bit for bit
                if start == end {
                    None
                } else {
                    Some(Arc::new(
                        Moving::new(primitive.clone().into_shared(), start, end).map_err(|m| (location(), m))?,
                    ))
                }
            }
        };
        if let Some(t) = &object.transform {
            let m = t.to_affine().map_err(|m| (location(), m))?;
            primitive = ObjectPrimitive::Shared(Arc::new(
                Transformed::new(primitive.into_shared(), m)
                    .map_err(|e| (location(), format!("transform: {}", e.problem)))?,
            ));
        }
        let material = self.material(object.material).map_err(|m| (location(), m))?;
        self.objects.push(Object {
            name: object.name.map(String::into_boxed_str),
            primitive,
            motion,
            material,
        });
        Ok(())
    }
}

/// Where an error is, for object `index` of the file with its name and primitive:
/// `objects[index] "name" (Primitive)`.
fn location(index: usize, name: Option<&str>, primitive: &str) -> String {
    match name {
        Some(name) => format!("objects[{index}] {name:?} ({primitive})"),
        None => format!("objects[{index}] ({primitive})"),
    }
}

/// The components of a transform description, validated as [`TransformDesc::to_affine`] does.
fn placement(t: &TransformDesc) -> Result<Placement, String> {
    t.to_affine()?;
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
