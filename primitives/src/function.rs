//! A user function Φ inside an explicit box: an [`Expr`] (guaranteed roots) or a Rust closure.
//!
//! - **Expression** ([`Function::from_expr`]): Φ and its analytic gradient (forward mode) come
//!   from the expression, and so do interval enclosures of Φ and of `dΦ/dt` along a ray, so the
//!   generic intersector isolates the **first root with a guarantee** ([`crate::isolation`]):
//!   a hit within [`RootOptions::tolerance`] (in units of `t`) of the first root, or a ray
//!   counted as uncertain. No Lipschitz bound is needed, thin shells are not stepped over, and
//!   tangent rays and double roots do not stall the search. [`RootOptions::max_evaluations`] is
//!   the per-ray budget.
//! - **Closure** ([`Function::new`]): only point values; the sampling / sphere-tracing finder of
//!   [`crate::root`] (with an optional Lipschitz bound) and central-difference normals.
//!
//! Where an expression is undefined at a point (`√` of a negative, `ln` of a number ≤ 0, `÷ 0`),
//! Φ there is `+∞` (outside). [`Function::from_expr`] looks for such points at construction:
//! interval evaluation over the whole box decides whether any can exist
//! ([`Function::may_be_undefined`]), and if so a 17³ grid of point evaluations over the box
//! turns a found one into an error naming the operation's column and the point.

use crate::bounds::Aabb;
use crate::error::PrimitiveError;
use crate::expr::{Expr, Jet};
use crate::math::enclosure::Enclosure;
use crate::ray::{Interval, Ray};
use crate::root::RootOptions;
use crate::traits::{Implicit, Intersect};
use glam::DVec3;
use std::fmt;
use std::sync::Arc;

#[derive(Clone)]
enum Phi {
    Expression(Arc<Expr>),
    Closure(Arc<dyn Fn(DVec3) -> f64 + Send + Sync>),
}

/// Φ given by an expression or a closure inside an explicit box (the surface outside the box is
/// ignored).
#[derive(Clone)]
pub struct Function {
    phi: Phi,
    bounds: Aabb,
    lipschitz: Option<f64>,
    options: RootOptions,
    may_be_undefined: bool,
}

impl fmt::Debug for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut d = f.debug_struct("Function");
        if let Phi::Expression(e) = &self.phi {
            d.field("phi", &e.source());
        }
        d.field("bounds", &self.bounds)
            .field("lipschitz", &self.lipschitz)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

fn check_bounds(bounds: &Aabb) -> Result<(), PrimitiveError> {
    if !bounds.is_finite() || bounds.is_empty() {
        return Err(PrimitiveError::new(
            "Function",
            "bounds",
            "must be a finite, non-empty box",
        ));
    }
    Ok(())
}

/// Validates root-finder options for a function: a positive, finite tolerance and a budget ≥ 2.
fn check_options(options: &RootOptions) -> Result<(), PrimitiveError> {
    crate::error::require_positive("Function", "tolerance", options.tolerance)?;
    if options.max_evaluations < 2 {
        return Err(PrimitiveError::new(
            "Function",
            "budget",
            format!("must be at least 2, got {}", options.max_evaluations),
        ));
    }
    Ok(())
}

/// Points per axis of the load-time domain check.
const DOMAIN_GRID: u32 = 17;

impl Function {
    /// Φ = `phi` (a closure) inside `bounds` (finite, non-empty), with an optional Lipschitz bound.
    pub fn new(
        phi: impl Fn(DVec3) -> f64 + Send + Sync + 'static,
        bounds: Aabb,
        lipschitz: Option<f64>,
    ) -> Result<Self, PrimitiveError> {
        check_bounds(&bounds)?;
        if let Some(l) = lipschitz {
            crate::error::require_positive("Function", "lipschitz", l)?;
        }
        Ok(Self {
            phi: Phi::Closure(Arc::new(phi)),
            bounds,
            lipschitz,
            options: RootOptions::default(),
            may_be_undefined: false,
        })
    }

    /// Φ = `expr` inside `bounds`, its first root along a ray isolated by interval arithmetic to
    /// `options.tolerance` (units of `t`) within `options.max_evaluations` (see the module docs).
    ///
    /// # Errors
    /// Non-finite or empty bounds, a non-positive tolerance, a budget below 2, or a point of the
    /// box where the expression is undefined (field `phi`, naming the operation's column).
    pub fn from_expr(expr: Expr, bounds: Aabb, options: RootOptions) -> Result<Self, PrimitiveError> {
        check_bounds(&bounds)?;
        check_options(&options)?;
        let may_be_undefined = expr.enclose(bounds.min, bounds.max).undefined;
        if may_be_undefined {
            let n = DOMAIN_GRID - 1;
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=n {
                        let f = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) / f64::from(n);
                        let p = bounds.min + (bounds.max - bounds.min) * f;
                        if let Err(e) = expr.domain_error(p) {
                            return Err(PrimitiveError::new(
                                "Function",
                                "phi",
                                format!(
                                    "`{}` is undefined inside the bounds: {e} at ({}, {}, {})",
                                    expr.source(),
                                    p.x,
                                    p.y,
                                    p.z
                                ),
                            ));
                        }
                    }
                }
            }
        }
        Ok(Self {
            phi: Phi::Expression(Arc::new(expr)),
            bounds,
            lipschitz: None,
            options,
            may_be_undefined,
        })
    }

    /// The same function declaring a Lipschitz bound `lipschitz > 0` of Φ over the box. An
    /// expression function does not need it (its roots are isolated by interval arithmetic), but
    /// combinators that march their zero set with the generic finder (`SmoothUnion`, `Offset`)
    /// read it from their children.
    ///
    /// # Errors
    /// A bound that is not finite and positive.
    pub fn with_lipschitz(mut self, lipschitz: f64) -> Result<Self, PrimitiveError> {
        crate::error::require_positive("Function", "lipschitz", lipschitz)?;
        self.lipschitz = Some(lipschitz);
        Ok(self)
    }

    /// The expression, for an expression function.
    #[must_use]
    pub fn expr(&self) -> Option<&Expr> {
        match &self.phi {
            Phi::Expression(e) => Some(e),
            Phi::Closure(_) => None,
        }
    }

    /// Whether interval evaluation over the box could not exclude undefined points (none was
    /// found on the load-time grid; any met by a ray are counted, see
    /// [`crate::isolation::UncertainCounts::undefined`]).
    #[must_use]
    pub fn may_be_undefined(&self) -> bool {
        self.may_be_undefined
    }
}

impl Implicit for Function {
    /// Φ at `p`; `+∞` where an expression is undefined or a closure returns a non-finite value
    /// from an expression.
    fn phi(&self, p: DVec3) -> f64 {
        match &self.phi {
            Phi::Expression(e) => {
                let v = e.eval(p);
                if v.is_finite() {
                    v
                } else {
                    f64::INFINITY
                }
            }
            Phi::Closure(f) => f(p),
        }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The analytic gradient of an expression; central differences for a closure (the default
    /// rule of [`Implicit::gradient`]).
    fn gradient(&self, p: DVec3) -> DVec3 {
        match &self.phi {
            Phi::Expression(e) => e.gradient(p),
            Phi::Closure(f) => crate::math::central_difference(|q| f(q), p, 6e-6 * self.bounds.diagonal_length()),
        }
    }

    fn lipschitz(&self) -> Option<f64> {
        self.lipschitz
    }

    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        match &self.phi {
            Phi::Expression(e) => Some(e.enclose_along(ray, segment)),
            Phi::Closure(_) => None,
        }
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        match &self.phi {
            Phi::Expression(e) => Some(e.enclose_value_along(ray, segment)),
            Phi::Closure(_) => None,
        }
    }
}

impl Intersect for Function {
    fn root_options(&self) -> RootOptions {
        self.options
    }
}
