//! # zeroset — ray casting of implicit surfaces with exact depth and normal AOVs
//!
//! Scenes are RON files ([`scene`]), primitives come from the `zeroset-primitives` kernel or
//! from user types registered in the [`registry`]; the renderer ([`render`]) casts one ray per
//! pixel through the pixel centre of a [`camera`] model (or several per pixel through a thin
//! lens over a shutter interval: [`sampling`], [`motion`]), keeps the first hit, and writes the
//! requested [`aov`]s to EXR and PNG and the cameras to JSON ([`output`]), for one view or many
//! ([`views`]). [`query`] answers batches of rays, which [`pixels`] makes from image positions.
//!
//! ## Layers
//!
//! Each module imports only from the layers below it (`grep -n "use crate::" src/*.rs`):
//!
//! 1. **Foundations**, used by every layer: [`aov`], [`camera`], [`sampling`], [`motion`].
//! 2. **Descriptions**, the serde types of the scene file: [`shape_desc`] (the [`SceneShape`]
//!    contract of a primitive's description and [`ShapeDesc`]), [`desc`] (camera, objects,
//!    lights, outputs, the RON options).
//! 3. **Registry**, how a description becomes a primitive: the built-in descriptions [`shapes`],
//!    [`combinators`] and [`mesh_io`], then [`registry`], which maps RON names to their parsers
//!    (and parses a [`ShapeDesc`] by its name).
//! 4. **Built scene**: [`objects`] (an object description built into a placed primitive),
//!    `parallel_parse`, `load_stream` and `fast_sphere` (large `objects` lists parsed on worker
//!    threads, plain spheres without serde), [`scene`] (loading, validation, the
//!    [`scene::Scene`]), [`tracing`] (its hierarchy and ray queries).
//! 5. **Render**: [`render`], [`views`], [`query_rays`], [`query`], [`pixels`], [`diagnostics`].
//! 6. **Output and command line**: [`output`], [`resources`] (the command's up-front checks of
//!    memory, disk and threads), [`cli`].
//!
//! One edge still points up: [`scene::Scene`] holds the hierarchy of [`tracing`], which imports
//! the scene it traces.
//!
//! [`SceneShape`]: shape_desc::SceneShape
//! [`ShapeDesc`]: shape_desc::ShapeDesc

pub mod aov;
pub mod camera;
pub mod cli;
pub mod combinators;
pub mod desc;
pub mod diagnostics;
mod fast_sphere;
mod load_stream;
pub mod mesh_io;
pub mod motion;
pub mod objects;
pub mod output;
mod parallel_parse;
mod piece_bins;
pub mod pixels;
pub mod query;
pub mod query_rays;
pub mod registry;
pub mod render;
pub mod resources;
pub mod sampling;
pub mod scene;
pub mod shape_desc;
pub mod shapes;
pub mod stream;
pub mod tracing;
pub mod views;

pub use zeroset_primitives as primitives;
