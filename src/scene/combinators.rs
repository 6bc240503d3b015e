//! Scene-file descriptions of the implicit combinators (`zeroset_primitives::csg`) and of a
//! user function Φ written as an expression.
//!
//! ```ron
//! Union(children: [Sphere(radius: 1), Box(min: (0, -1, -1), max: (2, 1, 1))])
//! Intersection(children: [...])
//! Difference(children: [Box(...), Sphere(...)])            // first minus the others
//! SmoothUnion(a: Sphere(...), b: Sphere(...), radius: 0.3)
//! Offset(shape: Box(...), distance: 0.1)                    // rounded box
//! Transformed(shape: Cylinder(), transform: (rotate: (axis: (1, 0, 0), degrees: 90)))
//! Function(phi: "x^2 + y^2 + z^2 - 1", min: (-1, -1, -1), max: (1, 1, 1), tolerance: 1e-7)
//! ```

use crate::scene::desc::TransformDesc;
use crate::scene::shape_desc::{BuildContext, SceneShape, ShapeDesc};
use glam::{DAffine3, DVec3};
use serde::Deserialize;
use std::sync::Arc;
use zeroset_primitives::expr::excerpt;
use zeroset_primitives::expr::faces::{negative_faces, FACE_NAMES};
use zeroset_primitives::{
    Aabb, Csg, CsgOp, Expr, Function, Offset, Primitive, PrimitiveError, RootOptions, SmoothUnion, Transformed,
};

/// An operand of a Boolean combinator after flattening, with its path from the combinator for
/// messages (`children[0] (Difference).children[3] (Sphere)`).
struct Operand<'a> {
    path: String,
    desc: &'a ShapeDesc,
}

/// `desc` with single-operand Booleans (`Union(children: [x])` is `x`) and identity transforms
/// (`Transformed(shape: x, transform: ())` is `x`) unwrapped, and its path.
fn unwrap_single(mut desc: &ShapeDesc, mut path: String) -> (&ShapeDesc, String) {
    loop {
        if let Some((_, [only])) = desc.shape.boolean_operands() {
            path = format!("{path}.children[0] ({})", only.name);
            desc = only;
        } else if let Some(inner) = desc.shape.identity_of() {
            path = format!("{path}.shape ({})", inner.name);
            desc = inner;
        } else {
            return (desc, path);
        }
    }
}

/// Appends the operands of `op` over `children` to `out`, splicing nested chains whose meaning
/// is unchanged by it:
/// - a `Union` inside a `Union`, an `Intersection` inside an `Intersection` (associativity);
/// - a `Difference` as the first operand of a `Difference`: `(a − b) − c = a − b − c`;
/// - a `Union` subtracted by a `Difference`: `a − (b ∪ c) = a − b − c`.
///
/// Identity transforms are looked through ([`unwrap_single`]). A left-deep chain of generated
/// `Difference`s thus loads as one flat `Difference`, also where each link is wrapped in a
/// `Transformed` by the identity.
fn flatten<'a>(op: CsgOp, children: &'a [ShapeDesc], prefix: &str, out: &mut Vec<Operand<'a>>) {
    for (i, child) in children.iter().enumerate() {
        let (desc, path) = unwrap_single(child, format!("{prefix}children[{i}] ({})", child.name));
        let first = out.is_empty();
        match (op, desc.shape.boolean_operands()) {
            // an empty operand list is kept, so that its build reports it
            (_, Some((_, []))) => out.push(Operand { path, desc }),
            (CsgOp::Union, Some((CsgOp::Union, inner))) | (CsgOp::Intersection, Some((CsgOp::Intersection, inner))) => {
                flatten(op, inner, &format!("{path}."), out);
            }
            (CsgOp::Difference, Some((CsgOp::Difference, inner))) if first => {
                flatten(CsgOp::Difference, inner, &format!("{path}."), out);
            }
            (CsgOp::Difference, Some((CsgOp::Union, inner))) if !first => {
                flatten(CsgOp::Union, inner, &format!("{path}."), out);
            }
            _ => out.push(Operand { path, desc }),
        }
    }
}

/// Builds `op` over `children`, flattened; a single operand is built as itself.
fn build_boolean(
    op: CsgOp,
    children: &[ShapeDesc],
    context: &BuildContext,
) -> Result<Arc<dyn Primitive>, PrimitiveError> {
    let mut operands = Vec::with_capacity(children.len());
    flatten(op, children, "", &mut operands);
    let mut built = operands
        .iter()
        .map(|o| {
            o.desc
                .shape
                .build(context)
                .map_err(|e| PrimitiveError::new(e.primitive, format!("{}.{}", o.path, e.field), e.problem))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if built.len() == 1 {
        return Ok(built.remove(0));
    }
    Ok(Arc::new(Csg::new(op, built)?))
}

macro_rules! boolean_desc {
    ($desc:ident, $name:literal, $op:expr, $doc:literal) => {
        #[doc = $doc]
        #[derive(Debug, Deserialize)]
        #[serde(deny_unknown_fields, rename = $name)]
        pub struct $desc {
            /// The operands (any registered primitives, combinators included).
            pub children: Vec<ShapeDesc>,
        }

        impl SceneShape for $desc {
            /// The combination with nested same-operation chains spliced (see `flatten`).
            fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
                build_boolean($op, &self.children, context)
            }

            fn boolean_operands(&self) -> Option<(CsgOp, &[ShapeDesc])> {
                Some(($op, &self.children))
            }
        }
    };
}

boolean_desc!(
    UnionDesc,
    "Union",
    CsgOp::Union,
    "`Union(children: [...])`: inside any child."
);
boolean_desc!(
    IntersectionDesc,
    "Intersection",
    CsgOp::Intersection,
    "`Intersection(children: [...])`: inside every child."
);
boolean_desc!(
    DifferenceDesc,
    "Difference",
    CsgOp::Difference,
    "`Difference(children: [a, b, ...])`: inside `a`, outside the rest."
);

/// `SmoothUnion(a: ..., b: ..., radius: r)`: polynomial smooth minimum of radius `r`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "SmoothUnion")]
pub struct SmoothUnionDesc {
    /// First operand.
    pub a: ShapeDesc,
    /// Second operand.
    pub b: ShapeDesc,
    /// Blend radius (> 0).
    pub radius: f64,
}

impl SceneShape for SmoothUnionDesc {
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(SmoothUnion::new(
            self.a.shape.build(context)?,
            self.b.shape.build(context)?,
            self.radius,
        )?))
    }
}

/// `Offset(shape: ..., distance: d)`: the zero set of `Φ − d` (grown for `d > 0`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Offset")]
pub struct OffsetDesc {
    /// The offset primitive.
    pub shape: ShapeDesc,
    /// Offset distance.
    pub distance: f64,
}

impl SceneShape for OffsetDesc {
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        Ok(Arc::new(Offset::new(self.shape.shape.build(context)?, self.distance)?))
    }
}

/// `Transformed(shape: ..., transform: (...))`: a transformed operand inside a combinator.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Transformed")]
pub struct TransformedDesc {
    /// The primitive.
    pub shape: ShapeDesc,
    /// Its placement (as an object's `transform`).
    pub transform: TransformDesc,
}

impl SceneShape for TransformedDesc {
    /// The shape under the placement, nested `Transformed`s composed into one map (one change of
    /// coordinates a ray instead of one a level); the shape itself where the map is the identity.
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        let mut m = self
            .transform
            .to_affine()
            .map_err(|problem| PrimitiveError::new("Transformed", "transform", problem))?;
        let (mut inner, mut field) = (&self.shape, "shape".to_string());
        while let Some((shape, transform)) = inner.shape.placement() {
            let inner_map = transform
                .to_affine()
                .map_err(|problem| PrimitiveError::new("Transformed", format!("{field}.transform"), problem))?;
            m *= inner_map;
            (inner, field) = (shape, format!("{field}.shape"));
        }
        let built = inner.shape.build(context)?;
        if m == DAffine3::IDENTITY {
            return Ok(built);
        }
        Ok(Arc::new(Transformed::new(built, m)?))
    }

    fn identity_of(&self) -> Option<&ShapeDesc> {
        (self.transform.to_affine() == Ok(DAffine3::IDENTITY)).then_some(&self.shape)
    }

    fn placement(&self) -> Option<(&ShapeDesc, &TransformDesc)> {
        Some((&self.shape, &self.transform))
    }
}

/// `Function(phi: "expr in x, y, z", min: (..), max: (..), tolerance: 1e-7, budget: 100000)`: Φ
/// written as an expression in standard notation (`+ - * / ^`, numbers such as `1e-3`,
/// `sqrt exp ln log10 log2 sin cos tan asin acos atan sinh cosh tanh cbrt abs sq min max pow`, constants `pi`, `e`, `tau`; see
/// `zeroset_primitives::expr`), the surface searched inside the box `[min, max]`. The first root
/// along a ray is isolated by interval arithmetic (`zeroset_primitives::isolation`): no
/// Lipschitz bound is needed (an optional `lipschitz` only serves a `SmoothUnion` or `Offset`
/// whose other operand has no interval evaluation, which marches the generic finder with it), thin
/// features are not stepped over, and rays that cannot be decided within `tolerance` (units of
/// `t`) or `budget` (enclosure and point evaluations per ray) are counted and reported after
/// the render or query. Where the expression is undefined Φ is `+∞` (outside); a point of the box
/// where it is undefined is a load error naming the operation's column.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Function")]
pub struct FunctionDesc {
    /// The expression for Φ.
    pub phi: String,
    /// Lower corner of the search box.
    pub min: DVec3,
    /// Upper corner of the search box.
    pub max: DVec3,
    /// Optional bound on |∇Φ| in the box: not needed by the function itself (interval isolation
    /// uses none), only read by a `SmoothUnion` / `Offset` around it whose other operand has no
    /// interval evaluation (those march the generic finder).
    #[serde(default)]
    pub lipschitz: Option<f64>,
    /// Width of the final bracket around a root, in units of `t`; default `1e-7`.
    #[serde(default)]
    pub tolerance: Option<f64>,
    /// Most enclosure and point evaluations per ray; default 100,000.
    #[serde(default)]
    pub budget: Option<u32>,
}

impl SceneShape for FunctionDesc {
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        // a long expression is quoted around the error only (±60 characters)
        let expr = Expr::parse(&self.phi).map_err(|e| {
            let near = excerpt(&self.phi, e.column);
            PrimitiveError::new("Function", "phi", format!("syntax error in `{near}` at {e}"))
        })?;
        if let Some(l) = self.lipschitz {
            zeroset_primitives::error::require_positive("Function", "lipschitz", l)?;
            context
                .warn("`lipschitz` is not needed (roots are isolated by interval arithmetic); it is only used by a SmoothUnion or Offset around this function that mixes it with a closed-form primitive");
        }
        check_search_box(self.min, self.max)?;
        if let Some(warning) = box_cut_warning(&expr, self.min, self.max) {
            context.warn(warning);
        }
        let defaults = RootOptions::default();
        let options = RootOptions {
            tolerance: self.tolerance.unwrap_or(defaults.tolerance),
            max_evaluations: self.budget.unwrap_or(defaults.max_evaluations),
            ..defaults
        };
        let mut function = Function::from_expr(expr, Aabb::new(self.min, self.max), options)?;
        if let Some(l) = self.lipschitz {
            function = function.with_lipschitz(l)?;
        }
        if function.may_be_undefined() {
            context.warn(format!(
                "`{}` may be undefined in parts of its box (interval evaluation could not exclude it); \
                 rays meeting such parts are counted",
                excerpt(&self.phi, 1)
            ));
        }
        Ok(Arc::new(function))
    }
}

/// The warning for a search box that cuts its surface: the faces on which Φ < 0 somewhere
/// (proved by interval evaluation, [`zeroset_primitives::expr::faces`]), each with a point where
/// it is; `None` where no face is cut.
fn box_cut_warning(expr: &Expr, min: DVec3, max: DVec3) -> Option<String> {
    let cuts = negative_faces(expr, min, max);
    if cuts.is_empty() {
        return None;
    }
    let faces: Vec<String> = cuts
        .iter()
        .map(|cut| {
            let axis = cut.face / 2;
            let name = ["x", "y", "z"][axis];
            let at = if cut.face % 2 == 0 { min[axis] } else { max[axis] };
            let w = cut.witness;
            format!(
                "{} ({name} = {at}; Φ < 0 at ({}, {}, {}))",
                FACE_NAMES[cut.face], w.x, w.y, w.z
            )
        })
        .collect();
    Some(format!(
        "the search box cuts the surface: Φ < 0 (inside) on its face{} {}, so the surface is cut open \
         there (searched only inside the box); widen `min`/`max` until Φ > 0 on every face",
        if faces.len() == 1 { "" } else { "s" },
        faces.join(", ")
    ))
}

/// A `Function`'s search box must have finite corners and positive thickness on every axis
/// (`min < max`): the surface is searched only inside it, so a flat or inverted box holds no
/// surface at all.
fn check_search_box(min: DVec3, max: DVec3) -> Result<(), PrimitiveError> {
    if !min.is_finite() || !max.is_finite() {
        return Err(PrimitiveError::new(
            "Function",
            "min`/`max",
            format!("the search box needs finite corners, got min {min} and max {max}"),
        ));
    }
    for (axis, name) in ["x", "y", "z"].into_iter().enumerate() {
        if min[axis] >= max[axis] {
            let what = if min[axis] == max[axis] {
                "has zero thickness"
            } else {
                "is inverted"
            };
            return Err(PrimitiveError::new(
                "Function",
                "min`/`max",
                format!(
                    "the search box {what} along {name} (min.{name} = {}, max.{name} = {}); \
                     each component of `min` must be below that of `max`",
                    min[axis], max[axis]
                ),
            ));
        }
    }
    Ok(())
}
