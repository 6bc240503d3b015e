//! Construction errors: every constructor validates its parameters and says which one is wrong.

use glam::DVec3;
use std::fmt;

/// A primitive could not be built from the given parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct PrimitiveError {
    /// Kind of primitive (`"Sphere"`, `"Polygon"`, …).
    pub primitive: &'static str,
    /// The offending parameter (`"radius"`, `"points[3]"`, …).
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

impl PrimitiveError {
    /// An error about `field` of a `primitive`.
    #[must_use]
    pub fn new(primitive: &'static str, field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            primitive,
            field: field.into(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for PrimitiveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: field `{}`: {}", self.primitive, self.field, self.problem)
    }
}

impl std::error::Error for PrimitiveError {}

/// `Ok(x)` if `x` is finite and `> 0`, else an error naming `field`.
pub fn require_positive(primitive: &'static str, field: &str, x: f64) -> Result<f64, PrimitiveError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(PrimitiveError::new(
            primitive,
            field,
            format!("must be positive and finite, got {x}"),
        ))
    }
}

/// `Ok(v)` if every component of `v` is finite, else an error naming `field`.
pub fn require_finite(primitive: &'static str, field: &str, v: DVec3) -> Result<DVec3, PrimitiveError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PrimitiveError::new(
            primitive,
            field,
            format!("must be finite, got {v}"),
        ))
    }
}

/// `Ok(v / |v|)` if `v` is finite and non-zero, else an error naming `field`.
pub fn require_direction(primitive: &'static str, field: &str, v: DVec3) -> Result<DVec3, PrimitiveError> {
    let v = require_finite(primitive, field, v)?;
    let len = v.length();
    if len > 0.0 && len.is_finite() {
        Ok(v / len)
    } else {
        Err(PrimitiveError::new(primitive, field, "must be a non-zero direction"))
    }
}

/// The largest length or coordinate magnitude the quadric primitives (cylinder, cone, ellipsoid,
/// disk) accept: `10¹⁵⁰`. Their intersection squares lengths and multiplies squares (`|f|²·|d|²`),
/// which overflows beyond about `2⁵¹¹ ≈ 6.7·10¹⁵³`; [`crate::Sphere`] and [`crate::Cuboid`]
/// compute at any magnitude and take no limit.
pub const MAX_MAGNITUDE: f64 = 1e150;

/// The smallest non-zero length these primitives accept: `10⁻¹⁵⁰` (squares underflow below
/// about `10⁻¹⁵⁴`).
pub const MIN_LENGTH: f64 = 1e-150;

/// `Ok(x)` if the length `x` lies in [`MIN_LENGTH`]`..=`[`MAX_MAGNITUDE`] (or is zero where
/// `x == 0` is otherwise allowed), else an error naming `field` that gives the limit.
pub fn require_length_in_range(primitive: &'static str, field: &str, x: f64) -> Result<f64, PrimitiveError> {
    if x == 0.0 || (MIN_LENGTH..=MAX_MAGNITUDE).contains(&x.abs()) {
        Ok(x)
    } else {
        Err(PrimitiveError::new(
            primitive,
            field,
            format!("must lie between {MIN_LENGTH:e} and {MAX_MAGNITUDE:e} (squares of it would overflow or underflow), got {x:e}"),
        ))
    }
}

/// `Ok(v)` if no component of `v` exceeds `limit` in magnitude, else an error naming `field`.
pub fn require_coordinates_within(
    primitive: &'static str,
    field: &str,
    v: DVec3,
    limit: f64,
) -> Result<DVec3, PrimitiveError> {
    if v.abs().max_element() <= limit {
        Ok(v)
    } else {
        Err(PrimitiveError::new(
            primitive,
            field,
            format!("coordinates must be at most {limit:e} in magnitude (products of them would overflow), got {v}"),
        ))
    }
}
