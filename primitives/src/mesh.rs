//! Triangle meshes: a shared f32 vertex buffer, 32-bit index triples, optional per-vertex
//! normals, a per-mesh BVH and a watertight ray/triangle test.
//!
//! # Conventions
//! - **Orientation.** A triangle `(a, b, c)` faces the side from which it is seen
//!   counter-clockwise; its geometric normal is `(b − a) × (c − a)` normalised. A closed mesh
//!   wound consistently counter-clockwise seen from outside has outward normals.
//! - **Hits.** [`RawHit::feature`] is the triangle's index in the order given to [`Mesh::new`]
//!   (the file's face order), [`RawHit::local`] its barycentrics `(u, v)`: the hit point is
//!   `(1 − u − v)·a + u·b + v·c`. [`Intersect::uv_at`] returns the same `(u, v)`.
//! - **Normals.** [`Intersect::normal_at`] is the hit triangle's geometric normal (never
//!   interpolated); [`Mesh::shading_normal`] / [`Intersect::shading_normal_at`] interpolate the
//!   per-vertex normals with the barycentrics, where the mesh has them.
//! - **Φ.** The exact unsigned distance to the nearest triangle, signed by that triangle's face
//!   normal: `Φ(p) = ±|p − q|` with `q` the nearest surface point, `+` on the side the normal points
//!   to. Where several triangles are (nearly) equally near (`q` on an edge or vertex), the one
//!   whose plane is most nearly perpendicular to `p − q` decides, which gives the right sign for a
//!   closed, consistently oriented mesh. Near the surface this is the signed distance; far from a
//!   mesh that is not closed the sign is only "which side of the nearest face". Φ costs a BVH
//!   nearest-point query (it is not on the hot path: intersection never evaluates it).
//! - **Precision.** Storage is f32. Each query converts the f64 ray once to an f32 ray (its
//!   direction scaled by a power of two, exactly, so that its largest component lies in `[1, 2)`)
//!   and precomputes the data of the watertight test of Woop, Benthin and Wald (2013,
//!   "Watertight Ray/Triangle Intersection", JCGT 2(1)): the axis `k_z` of the largest direction
//!   component, the permuted axes and the shear constants. Edge functions that evaluate to exactly
//!   zero are recomputed in f64, and a ray through a shared edge or vertex hits at least one of
//!   the triangles sharing it: closed meshes do not leak. The reported `t` is recomputed in f64
//!   from the hit triangle's plane (exact f32 vertices, f64 ray), so depth is accurate to f64
//!   rounding rather than f32; hits within `10⁻⁵` of the scene scale of `t_min` are re-decided
//!   with that f64 `t` so that rays leaving the surface do not re-hit it.
//! - **Degenerate triangles** (zero area, exactly) are **skipped**: they keep their index (so
//!   `feature` still matches the file) but are left out of the BVH, so they are never hit and do
//!   not take part in Φ. [`Mesh::skipped_triangles`] counts them. A mesh whose triangles all
//!   have zero area has no surface ([`Mesh::has_surface`]): it is never hit, holds no point,
//!   and its Φ is the unsigned distance to what its triangles collapse to.
//!
//! # Storage
//! Vertices `12 B` each (plus `12 B` with normals), triangles `12 B` (index triple, kept in BVH
//! leaf order) plus `8 B` (leaf ↔ file order maps), their corners again in the leaves' rows
//! (`36 B`, see `rows.rs`: a leaf test reads its triangles' coordinates eight at a time,
//! without going through the indices), each triangle's unit normal rounded to f32 (`12 B`, for
//! [`Intersect::normal_at_f32`]; meshes of up to 2¹⁸ triangles), 4-wide BVH nodes `128 B` each, about
//! `0.07 N` of them for `N` triangles on the benchmark meshes, which packets walk, and the same
//! hierarchy collapsed into 8-wide nodes of `256 B`, about half as many, which single rays walk,
//! made when the first single ray needs them (see [`Mesh::memory_bytes`]). The BVH is described
//! in `bvh/build.rs`, the 8-wide nodes in `bvh/oct.rs`.
//!
//! One mesh can be placed many times without copying: wrap an `Arc<Mesh>` in
//! [`crate::Transformed`] per instance; the scene BVH holds the instances, each instance's mesh
//! its own BVH (two levels).
//!
//! # Files
//! - `storage.rs`: [`Mesh`], its constructor, accessors and per-triangle geometry;
//! - `rows.rs`: the leaves' corner rows the leaf tests read;
//! - `watertight.rs`: the f32 watertight triangle test, single and eight lanes at once;
//! - `query.rs`: a ray's set-up, the early outs, the closest-candidate rule and the finish;
//! - `walk.rs`: the single-ray walk over the 8-wide nodes;
//! - `stream.rs`: a batch's single-ray walks interleaved; `packet.rs`: packets walking together;
//! - `pieces.rs`: the hierarchy's leaves as pieces; `phi.rs`: Φ's nearest-point query;
//! - `winding.rs`: the exact and the fast (hierarchical) generalized winding numbers;
//! - `inside.rs`: inside / outside by a [`SignMethod`](crate::SignMethod) (winding numbers,
//!   the nearest feature's pseudo-normal, ray parity);
//! - `impls.rs`: the `Implicit` and `Intersect` implementations.

/// `$mesh.$method::<KX, KY, KZ>(args…)` for the watertight test's axes `$k` (`[KX, KY, KZ]`,
/// one of the six orders): each order has its own copy of the method, its permutations resolved
/// at compile time.
macro_rules! by_axes {
    ($k:expr, $mesh:ident.$method:ident($($arg:expr),* $(,)?)) => {
        match $k {
            [1, 2, 0] => $mesh.$method::<1, 2, 0>($($arg),*),
            [2, 1, 0] => $mesh.$method::<2, 1, 0>($($arg),*),
            [2, 0, 1] => $mesh.$method::<2, 0, 1>($($arg),*),
            [0, 2, 1] => $mesh.$method::<0, 2, 1>($($arg),*),
            [0, 1, 2] => $mesh.$method::<0, 1, 2>($($arg),*),
            _ => $mesh.$method::<1, 0, 2>($($arg),*),
        }
    };
}

mod crossings;
mod impls;
mod inside;
mod packet;
mod phi;
mod pieces;
mod query;
mod regions;
mod rows;
mod storage;
mod stream;
mod walk;
mod watertight;
mod winding;

pub use storage::{is_degenerate_triangle, Mesh};

// names the module docs link to
#[cfg(doc)]
use crate::{hit::RawHit, traits::Intersect};

#[cfg(test)]
mod tests;
