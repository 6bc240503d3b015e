//! # zeroset — ray casting of implicit surfaces with exact depth and normal AOVs
//!
//! Scenes are RON files ([`scene`]), primitives come from the `zeroset-primitives` kernel or
//! from user types registered in the [`registry`]; the renderer ([`render`]) casts one ray per
//! pixel through the pixel centre of a [`camera`] model (or several per pixel through a thin
//! lens over a shutter interval: [`sampling`], [`motion`]), keeps the first hit, and writes the
//! requested [`aov`]s to EXR and PNG and the cameras to JSON ([`output`]), for one view or many
//! ([`views`]). [`query`] answers batches of rays, which [`pixels`] makes from image positions.

pub mod aov;
pub mod camera;
pub mod cli;
pub mod combinators;
pub mod diagnostics;
pub mod mesh_io;
pub mod motion;
pub mod output;
mod parallel_parse;
pub mod pixels;
pub mod query;
pub mod query_rays;
pub mod registry;
pub mod render;
pub mod resources;
pub mod sampling;
pub mod scene;
pub mod shapes;
pub mod stream;
pub mod tracing;
pub mod views;

pub use zeroset_primitives as primitives;
