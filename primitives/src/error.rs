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
