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
use glam::DVec3;

/// The point of triangle `(a, b, c)` nearest to `p` (Ericson, "Real-Time Collision Detection",
/// §5.1.5, by Voronoi regions).
pub(super) fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

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
