//! Bounding volume hierarchies: the scene's over its bounded objects ([`Bvh`]) and each mesh's
//! over its triangles, both made by one builder (`build.rs`: parallel binned SAH, written straight
//! into 4-wide nodes) and walked by one ordered closest-hit walk.
//!
//! Conventions shared by every file here: nodes hold their children's boxes in f32, rounded
//! outward from f64 (`rounding.rs`: toward −∞ and +∞); slab tests are conservative, so the
//! f32 traversal never drops a hit the exact tests would find; the nearest entered child is
//! visited next and the others pushed farthest first, skipped when popped if the closest hit is
//! already nearer; ties of `t` are settled by leaf position (or id), never by the order of visits.
//!
//! # Files
//! - `scene.rs`: [`Bvh`], the scene's hierarchy, its conservative f64-safe slab tests and walks;
//! - `build.rs`: the builder; `quad_bvh.rs`: the built hierarchy and its ray-less queries;
//! - `quad.rs`: the 4-wide node; `quad_array.rs`: its storage; `oct.rs`: the 8-wide nodes a
//!   mesh's single rays walk;
//! - `walk.rs`: one ray's ordered walk; `packet.rs`: a packet's; `slab.rs`: a mesh's f32 slab
//!   tests;
//! - `rounding.rs`, `lanes.rs`, `prefetching.rs`: f64 → f32 rounding, SIMD lane helpers, prefetch.

pub(crate) mod build;
pub(crate) mod lanes;
pub(crate) mod oct;
pub(crate) mod packet;
pub(crate) mod prefetching;
pub(crate) mod quad;
mod quad_array;
pub(crate) mod quad_bvh;
pub(crate) mod rounding;
mod scene;
pub(crate) mod slab;
pub(crate) mod walk;

pub use prefetching::prefetch;
pub use scene::Bvh;

#[cfg(test)]
mod tests;
