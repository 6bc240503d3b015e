//! Primitive types defined outside zeroset's crates, using only their public API — the worked
//! examples of `docs/adding-a-primitive.md`.
//!
//! | RON name        | type                 | what the type writes                                        |
//! |-----------------|----------------------|-------------------------------------------------------------|
//! | `Torus`         | [`Torus`]            | Φ once, generically, and bounds: exact normals, guaranteed first roots |
//! | `QuarticTorus`  | [`QuarticTorus`]     | the same torus with its analytic gradient and closed-form quartic intersection |
//! | `Superellipsoid`| [`Superellipsoid`]   | Φ and bounds (Barr's superquadric, rescaled to be distance-like) |
//! | `Gyroid`        | [`Gyroid`]           | Φ once, generically, and bounds: a gyroid sheet clipped by a box |
//!
//! [`register_all`] registers them; `src/main.rs` is a complete `zeroset` binary with them.

// `!(x >= 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod gyroid;
mod quartic;
mod superellipsoid;
mod torus;

pub use gyroid::Gyroid;
pub use quartic::solve_quartic;
pub use superellipsoid::Superellipsoid;
pub use torus::{QuarticTorus, Torus};

/// Registers every type of this crate under its RON name.
pub fn register_all() {
    zeroset::scene::registry::register::<Torus>("Torus");
    zeroset::scene::registry::register::<QuarticTorus>("QuarticTorus");
    zeroset::scene::registry::register::<Superellipsoid>("Superellipsoid");
    zeroset::scene::registry::register::<Gyroid>("Gyroid");
}
