//! # zeroset — ray casting of implicit surfaces with exact depth and normal AOVs
//!
//! Scenes are RON files ([`scene`]), primitives come from the `zeroset-primitives` kernel or
//! from user types registered in the [`scene::registry`]; rays are traced through the scene's
//! hierarchy ([`trace`]); the renderer ([`render`]) casts one ray per pixel through the pixel
//! centre of a [`camera`] model (or several per pixel through a thin lens over a shutter
//! interval: [`sampling`], [`motion`]), keeps the first hit, and computes the requested
//! [`aov`]s, which [`output`] writes to EXR and PNG (and the cameras to JSON), for one view or
//! many ([`render::views`]). [`query`] answers batches of rays, which [`query::pixels`] makes
//! from image positions. [`cli`] is the command line.
//!
//! ## Layers
//!
//! The top-level modules form a pipeline; each imports only from its own layer's modules or
//! from the layers below it, and no two modules import each other, even through others (the
//! test `tests/layers.rs` checks both, and that no source file is over 800 lines):
//!
//! 1. **Foundations**, used by every layer: [`motion`], [`sampling`], [`camera`] (camera
//!    models only), [`aov`] (the output channels), [`resources`] (the one guarded entry for
//!    what a user's numbers size: memory estimates against the room the process has, fallible
//!    reservations, thread caps and bounded reads of input files).
//! 2. **Scene**: [`scene`], the RON descriptions ([`scene::desc`], [`scene::shape_desc`]), the
//!    built-in shapes ([`scene::shapes`], [`scene::combinators`], [`scene::mesh_io`]), the
//!    [`scene::registry`] of parsers, the built [`scene::objects`], loading and the
//!    [`scene::Scene`] with its hierarchy.
//! 3. **Trace**: [`trace`], the scene's closest-hit and occlusion queries over its hierarchy,
//!    and packets ([`trace::packet`]); [`diagnostics`] (load warnings, uncertain roots).
//! 4. **Render and query**, side by side, neither importing the other: [`render`] (the tracer,
//!    pixels to AOV values, shading, culling in [`render::cull`], bands in [`render::stream`],
//!    [`render::views`]) and [`query`] (batches of rays: order, CSV, NPY, rays from columns and
//!    from pixels).
//! 5. **Output**: [`output`], EXR, PNG and camera files.
//! 6. **Command line**: [`cli`], with the command's up-front checks of memory, disk and
//!    threads (through [`resources`]).

pub mod aov;
pub mod camera;
pub mod cli;
pub mod diagnostics;
pub mod motion;
pub mod output;
pub mod query;
pub mod render;
pub mod resources;
pub mod sampling;
pub mod scene;
pub mod trace;

pub use zeroset_primitives as primitives;
