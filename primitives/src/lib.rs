//! # zeroset-primitives — the geometry kernel of zeroset
//!
//! Rays, hit records, the traits a primitive implements, the built-in primitives and the generic
//! root finder. It depends on glam alone and knows nothing of scenes or files.
//!
//! ## Conventions (stated once, used everywhere)
//! - **Precision.** Parameters, rays and results are `f64` (glam's `DVec3`). On the scalar code
//!   paths here an f64 operation costs the same as an f32 one, and f64 keeps closed forms within a
//!   few f32 ulp of exact for inputs that are themselves f32-accurate; see `docs/numerics.md`.
//! - **Φ sign.** `Φ < 0` inside, `Φ = 0` on the surface, `Φ > 0` outside. Open surfaces (plane,
//!   triangle, disk, polygon, open cylinder and cone) call the side their normal points to
//!   "outside".
//! - **Normal.** `∇Φ / |∇Φ|`, pointing to `Φ > 0`; never flipped toward the viewer
//!   ([`SurfaceHit::facing_normal`] gives the viewer-facing one).
//! - **t.** A [`Ray`] is `origin + t·dir`; `t` is in units of `dir` (metric distance when `dir` is
//!   unit, as for every camera ray). Queries take a closed [`Interval`] `t_min ≤ t ≤ t_max`.
//! - **(u, v).** Each [`Parametric`] type states its domain ([`Parametric::domain`]) and seams in
//!   its module docs; `∂p/∂u × ∂p/∂v` points to `Φ > 0`.
//! - **Frames.** Each primitive is defined by world-space parameters as listed in its module;
//!   [`Transformed`] places any primitive under an affine map, preserving `t`.
//!
//! ## Expressions and guaranteed roots
//! [`Expr`] parses Φ written in standard notation and evaluates it at points, over boxes
//! (interval arithmetic, [`math::enclosure`]) and along rays with its derivative; a [`Function`]
//! built from one has its first root along each ray isolated with a guarantee
//! ([`isolation`]), or the ray counted as uncertain ([`uncertain_counts`]).
//!
//! ## Rays from stored points
//! [`offset::spawn_origin`] starts a ray from a point known only to f32, f64 or an explicit
//! error bound, so that it cannot re-hit the surface it starts on through rounding.
//!
//! ## Two-stage intersection
//! [`Intersect::intersect`] returns a cheap [`RawHit`]; the closest one is finished once with
//! [`SurfaceHit::complete`], computing only what a [`HitRequest`] asks for.

#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "`!(a <= b)` is the kernel's idiom for a comparison that also rejects NaN"
)]

// infrastructure
pub mod bounds;
pub mod bvh;
pub mod cpu;
pub mod crossings;
pub mod error;
pub mod expr;
pub mod finder;
pub mod hit;
pub mod implicit;
pub mod isolation;
pub mod math;
pub mod offset;
pub mod proximity;
pub mod ray;
pub mod root;
pub mod traits;
pub mod transformed;

// built-in primitives, one file each
pub mod cone;
pub mod cuboid;
pub mod cylinder;
pub mod disk;
pub mod ellipsoid;
pub mod mesh;
pub mod plane;
pub mod polygon;
pub mod sphere;
pub mod triangle;

// implicit combinators and user functions
pub mod csg;
pub mod field;
pub mod function;

#[cfg(feature = "testing")]
pub mod testing;

pub use bounds::Aabb;
pub use bvh::Bvh;
pub use crossings::{Crossing, Crossings};
pub use error::PrimitiveError;
pub use hit::{facing, HitRequest, RawHit, SurfaceHit};
pub use proximity::{Closest, SignMethod};
pub use ray::{Interval, Ray};
pub use root::{first_root, RootOptions, RootReport};
pub use traits::{Implicit, Intersect, Parametric, Pieces, Primitive, UvDomain, Wanted};
pub use transformed::Transformed;

/// Most rays in one [`Intersect::intersect_packet`] call: one per lane of a 256-bit f32 vector.
pub const PACKET: usize = 8;

pub use cone::Cone;
pub use cuboid::Cuboid;
pub use cylinder::Cylinder;
pub use disk::Disk;
pub use ellipsoid::Ellipsoid;
pub use mesh::Mesh;
pub use plane::Plane;
pub use polygon::Polygon;
pub use sphere::Sphere;
pub use triangle::Triangle;

pub use csg::{Csg, CsgOp, Offset, SmoothUnion};
pub use expr::Expr;
pub use field::{FieldSurface, ScalarField};
pub use function::Function;
pub use isolation::{uncertain_counts, UncertainCounts};

pub use glam;
