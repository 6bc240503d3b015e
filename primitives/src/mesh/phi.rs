//! Φ's nearest-point query: the point of the mesh nearest to `p` and its triangle, found by the
//! 4-wide hierarchy's depth-first walk ([`QuadBvh::nearest`](crate::bvh::quad_bvh::QuadBvh::nearest))
//! pruned by the squared distance to each box, with [`closest_on_triangle`] at the leaves.
//!
//! Φ (see the module docs of [`crate::mesh`]) is `±|p − q|` for that nearest point `q`, signed by
//! its triangle's face normal. Where several triangles are within a relative `10⁻¹⁰` of the same
//! squared distance (`q` on a shared edge or vertex), the one whose plane is most nearly
//! perpendicular to `p − q` (largest `|n̂·(p − q)| / |p − q|`) decides, which gives the right sign
//! for a closed, consistently oriented mesh.

use super::storage::{v64, Mesh};
use crate::bvh::quad_bvh::Node;
pub(super) use crate::triangle::closest_on_triangle;
use glam::DVec3;

impl Mesh {
    /// Nearest surface point to `p`: `(q, leaf position of its triangle)`.
    pub(super) fn nearest(&self, p: DVec3) -> (DVec3, usize) {
        let best_d2 = std::cell::Cell::new(f64::INFINITY);
        let mut best = (p, 0usize, -1.0f64); // (q, k, |cos| tie-break key)
        let tol = 1e-10;
        self.bvh.nearest(
            |node: &Node| {
                let d = (v64(node.lo) - p).max(p - v64(node.hi)).max(DVec3::ZERO);
                let d2 = d.length_squared();
                (d2 <= best_d2.get() * (1.0 + tol)).then_some(d2)
            },
            |first, count| {
                for k in first as usize..(first + count) as usize {
                    let [a, b, c] = self.tris[k].map(|i| v64(self.vertices[i as usize]));
                    let q = closest_on_triangle(p, a, b, c);
                    let d2 = (p - q).length_squared();
                    if d2 > best_d2.get() * (1.0 + tol) {
                        continue;
                    }
                    let n = (b - a).cross(c - a).normalize_or_zero();
                    let len = d2.sqrt();
                    let key = if len > 0.0 { (n.dot(p - q) / len).abs() } else { 1.0 };
                    if d2 < best_d2.get() * (1.0 - tol) || key > best.2 {
                        best = (q, k, key);
                    }
                    best_d2.set(best_d2.get().min(d2));
                }
            },
        );
        (best.0, best.1)
    }
}
