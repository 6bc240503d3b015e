//! Planar polygon: convex or concave, with any number of holes.
//!
//! | field    | meaning                                             | constraint                       |
//! |----------|-----------------------------------------------------|----------------------------------|
//! | `points` | outer ring, counter-clockwise seen from the front   | ≥ 3 finite points, area > 0      |
//! | `holes`  | inner rings, either orientation                     | ≥ 3 finite points each           |
//!
//! All points must lie within `10⁻⁹ ×` the polygon's size (its bounding-box diagonal) of the
//! plane. Rings are closed implicitly (do not repeat the first point).
//!
//! - **Plane**: the normal `n` is the outer ring's vector area by Newell's method, normalised; by
//!   the right-hand rule it points to the side from which the outer ring runs counter-clockwise.
//!   The plane passes through the outer ring's centroid; `o` is the first outer point moved onto
//!   it (the origin of the plane coordinates).
//! - **Φ(p) = ⟨p − o, n⟩**, the signed plane distance (positive in front; Lipschitz bound 1);
//!   **∇Φ = n**. [`Implicit::within_boundary`] projects `p` to plane coordinates and applies
//!   [`point_in_polygon`] (even-odd rule over the outer ring and the holes, exact predicates; a
//!   boundary point is inside when the polygon lies just up and right of it in plane
//!   coordinates, see [`crate::math::polygon2d`]).
//! - **Parametric form**: plane coordinates `p(u, v) = o + u·e₁ + v·e₂` with `(e₁, e₂, n)` the
//!   right-handed basis of [`orthonormal_basis`]; the domain is the outer ring's bounding
//!   rectangle in `(u, v)`. The rings are projected to these coordinates once, at construction.
//! - **Intersection**: the plane hit `t = ⟨o − origin, n⟩ / ⟨dir, n⟩`, then the 2-D test on the
//!   hit's plane coordinates (kept in [`RawHit::local`]): the same-sign
//!   [`point_in_convex_polygon`] when the polygon is convex without holes (decided exactly at
//!   construction), else [`point_in_polygon`]; both give the same answer. A ray parallel to the
//!   plane, including one lying in it, misses.
//! - **Closest point**: with `h = Φ(p)` and `w` the plane coordinates of `p`'s projection, the
//!   distance is `√(h² + δ²)` with `δ` the 2-D distance from `w` to the region, since every
//!   polygon point lies in the plane. Where `w` is inside by the region's own rule
//!   ([`Implicit::within_boundary`]: even-odd over all rings, exact predicates) `δ = 0` and the
//!   projection `o + w₁e₁ + w₂e₂` is nearest; otherwise the nearest region point lies on the
//!   boundary, and it is the nearest of the clamped projections of `w` on every edge of every
//!   ring (outer ring and holes). For a point whose projection lies on the boundary both give
//!   `δ = 0`, so the rule's choice for boundary points does not matter. Exact to rounding.

use crate::bounds::Aabb;
use crate::error::PrimitiveError;
use crate::hit::RawHit;
use crate::math::dot_minus;
use crate::math::orthonormal_basis;
use crate::math::polygon2d::{orient2d, point_in_convex_polygon, point_in_polygon, ConvexRing};
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};

/// The largest coordinate magnitude a polygon accepts: `10⁷⁵` (its area and planarity tests
/// multiply four coordinates, which overflows beyond about `2²⁵⁵ ≈ 5.8·10⁷⁶`).
pub const MAX_COORDINATE: f64 = 1e75;

/// The smallest extent (bounding-box diagonal) a polygon accepts: `10⁻⁷⁵`, for the same reason.
pub const MIN_EXTENT: f64 = 1e-75;
/// A planar polygon with holes.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    origin: DVec3,
    normal: DVec3,
    e1: DVec3,
    e2: DVec3,
    /// Plane coordinates: `rings[0]` the outer ring (counter-clockwise), then the holes.
    rings: Vec<Vec<DVec2>>,
    convex: bool,
    /// The outer ring prepared for the same-sign test, where `convex`.
    convex_ring: Option<ConvexRing>,
    domain: UvDomain,
    bounds: Aabb,
    /// `(k, s)` where the normal is `s·e_k` (`s = ±1`, a plane across a coordinate axis, a
    /// ground): the plane's equation is then one coordinate ([`Polygon::axis_plane_t`]).
    axis: Option<(usize, f64)>,
}

fn error(field: impl Into<String>, problem: impl Into<String>) -> PrimitiveError {
    PrimitiveError::new("Polygon", field, problem)
}

/// Whether the counter-clockwise ring is convex: every turn is a left turn or straight on (no
/// reversal), and the edge direction turns once around (its `y` component changes sign twice).
fn is_convex(ring: &[DVec2]) -> bool {
    let edges: Vec<DVec2> = (0..ring.len())
        .map(|i| ring[(i + 1) % ring.len()] - ring[i])
        .filter(|d| *d != DVec2::ZERO)
        .collect();
    let mut sign_changes = 0;
    let mut last_sign = edges.iter().rev().find(|d| d.y != 0.0).map_or(0.0, |d| d.y.signum());
    for (i, &d) in edges.iter().enumerate() {
        let next = edges[(i + 1) % edges.len()];
        let turn = orient2d(DVec2::ZERO, d, next);
        if turn < 0.0 || (turn == 0.0 && d.dot(next) < 0.0) {
            return false;
        }
        if d.y != 0.0 {
            if d.y.signum() != last_sign {
                sign_changes += 1;
            }
            last_sign = d.y.signum();
        }
    }
    sign_changes == 2
}

impl Polygon {
    /// A polygon from its outer ring and holes (see the module docs for the conventions).
    ///
    /// # Errors
    /// Names the ring and index (`points[3]`, `holes[0][2]`) of a non-finite point or of a point
    /// off the plane; `points` for fewer than three points or a zero area; `holes[i]` for a hole
    /// with fewer than three points.
    pub fn new(points: Vec<DVec3>, holes: Vec<Vec<DVec3>>) -> Result<Self, PrimitiveError> {
        if points.len() < 3 {
            return Err(error(
                "points",
                format!("needs at least 3 points, got {}", points.len()),
            ));
        }
        for (h, hole) in holes.iter().enumerate() {
            if hole.len() < 3 {
                return Err(error(
                    format!("holes[{h}]"),
                    format!("needs at least 3 points, got {}", hole.len()),
                ));
            }
        }
        let named = || {
            let outer = points.iter().enumerate().map(|(i, p)| (format!("points[{i}]"), *p));
            let inner = holes.iter().enumerate().flat_map(|(h, ring)| {
                ring.iter()
                    .enumerate()
                    .map(move |(i, p)| (format!("holes[{h}][{i}]"), *p))
            });
            outer.chain(inner)
        };
        if let Some((field, p)) = named().find(|(_, p)| !p.is_finite()) {
            return Err(error(field, format!("must be finite, got {p}")));
        }
        // the area test below multiplies four coordinates
        if let Some((field, p)) = named().find(|(_, p)| p.abs().max_element() > MAX_COORDINATE) {
            return Err(error(
                field,
                format!("coordinates must be at most {MAX_COORDINATE:e} in magnitude (products of four would overflow), got {p}"),
            ));
        }
        // Newell's method about the first point: twice the vector area of the outer ring
        let first = points[0];
        let area2: DVec3 = (1..points.len() - 1)
            .map(|i| (points[i] - first).cross(points[i + 1] - first))
            .sum();
        let size = Aabb::from_points(named().map(|(_, p)| p)).diagonal_length();
        if size < MIN_EXTENT {
            return Err(error(
                "points",
                format!("the polygon's extent {size:e} is below {MIN_EXTENT:e} (products of four coordinates would underflow)"),
            ));
        }
        let large_enough = area2.length() > 1e-12 * size * size; // false for NaN
        if !large_enough {
            return Err(error(
                "points",
                format!("the outer ring has (nearly) zero area ({:e})", 0.5 * area2.length()),
            ));
        }
        let normal = area2.normalize();
        // the plane through the outer ring's centroid; report the point farthest from it
        let centroid = points.iter().sum::<DVec3>() / points.len() as f64;
        let tolerance = 1e-9 * size;
        let distance = |p: DVec3| (p - centroid).dot(normal);
        let worst = named().max_by(|(_, p), (_, q)| distance(*p).abs().total_cmp(&distance(*q).abs()));
        if let Some((field, p)) = worst.filter(|(_, p)| distance(*p).abs() > tolerance) {
            return Err(error(
                field,
                format!(
                    "lies {:e} off the plane of the outer ring (tolerance {tolerance:e})",
                    distance(p)
                ),
            ));
        }
        // plane coordinates have their origin at the first point, moved onto the plane
        let origin = first - distance(first) * normal;
        // project once, to plane coordinates
        let (e1, e2) = orthonormal_basis(normal);
        let project = |p: &DVec3| DVec2::new((*p - origin).dot(e1), (*p - origin).dot(e2));
        let rings: Vec<Vec<DVec2>> = std::iter::once(&points)
            .chain(&holes)
            .map(|r| r.iter().map(project).collect())
            .collect();
        let (lo, hi) = rings[0]
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(*q), hi.max(*q))
            });
        let on_plane = rings.iter().flatten().map(|q| origin + q.x * e1 + q.y * e2);
        let bounds = Aabb::from_points(on_plane).expanded(tolerance);
        let convex = holes.is_empty() && is_convex(&rings[0]);
        Ok(Self {
            origin,
            normal,
            e1,
            e2,
            convex_ring: if convex { ConvexRing::new(&rings[0]) } else { None },
            rings,
            convex,
            domain: UvDomain {
                u: (lo.x, hi.x),
                v: (lo.y, hi.y),
            },
            bounds,
            axis: axis_normal(normal),
        })
    }

    /// Unit normal (front side: the outer ring runs counter-clockwise seen from it).
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Whether the polygon is convex without holes (intersection then uses the same-sign test).
    #[must_use]
    pub fn is_convex(&self) -> bool {
        self.convex
    }

    /// The rings in plane coordinates: the outer ring first, then the holes as given.
    #[must_use]
    pub fn rings_2d(&self) -> &[Vec<DVec2>] {
        &self.rings
    }

    /// Whether the plane-coordinate point `q` is inside, by the test intersection uses.
    #[inline(always)]
    #[must_use]
    pub fn contains_2d(&self, q: DVec2) -> bool {
        if let Some(inside) = self.convex_ring.as_ref().and_then(|ring| ring.contains(q)) {
            inside
        } else if self.convex {
            point_in_convex_polygon(q, &self.rings[0])
        } else {
            point_in_polygon(q, &self.rings)
        }
    }
}

impl Implicit for Polygon {
    fn phi(&self, p: DVec3) -> f64 {
        (p - self.origin).dot(self.normal)
    }

    fn gradient(&self, _p: DVec3) -> DVec3 {
        self.normal
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    fn within_boundary(&self, p: DVec3) -> bool {
        point_in_polygon(self.uv(p), &self.rings)
    }

    /// The projection on the plane where it is inside, else the nearest point of any ring's
    /// edges (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let w = self.uv(p);
        let q = if self.contains_2d(w) {
            w
        } else {
            nearest_on_rings(&self.rings, w)
        };
        Some(Closest::exact(p, self.point(q), 0))
    }
}

/// The point of the rings' edges (each ring closed) nearest to `w`: the clamped projection of
/// `w` on each edge `a → b`, `a + clamp(⟨w − a, b − a⟩ / |b − a|², 0, 1)·(b − a)`, the nearest
/// of them (the first on ties; `a` for a zero-length edge).
fn nearest_on_rings(rings: &[Vec<DVec2>], w: DVec2) -> DVec2 {
    let mut best = (f64::INFINITY, w);
    for ring in rings {
        for (i, &a) in ring.iter().enumerate() {
            let edge = ring[(i + 1) % ring.len()] - a;
            let len2 = edge.length_squared();
            let tau = if len2 > 0.0 {
                ((w - a).dot(edge) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = a + tau * edge;
            let d2 = (w - q).length_squared();
            if d2 < best.0 {
                best = (d2, q);
            }
        }
    }
    best.1
}

/// `(k, s)` where `normal` is `s·e_k` with `s = ±1` (its other components zero).
fn axis_normal(normal: DVec3) -> Option<(usize, f64)> {
    let k = normal.abs().max_position();
    let s = normal[k];
    (s.abs() == 1.0 && normal.abs().element_sum() == 1.0).then_some((k, s))
}

impl Polygon {
    /// The hit `t` of `ray` on the plane of a polygon whose normal is `s·e_k`: the same value
    /// the compensated sums of the general test give, from one coordinate. `⟨d, n⟩ = s·d_k`
    /// exactly (the other products are zeros), and `⟨o, n⟩ − ⟨p₀, n⟩ = s·(o_k − p₀_k)` has two
    /// nonzero terms, whose compensated sum is their sum rounded once, `+0` where they cancel
    /// (hence the `+ 0.0`, which turns `−0` into `+0`). `None` for a ray parallel to the plane;
    /// the caller checks the ray is finite (a non-finite other component makes the sums NaN).
    #[inline(always)]
    fn axis_plane_t(&self, k: usize, s: f64, ray: &Ray) -> Option<f64> {
        let denom = ray.dir[k] * s;
        if denom == 0.0 {
            return None;
        }
        Some(-((ray.origin[k] - self.origin[k]) * s + 0.0) / denom)
    }

    /// [`Intersect::intersect`] for a plane of any orientation (compensated dot products), the
    /// whole test inlined into the AVX2+FMA copy where the CPU has them. Out of line: its frame
    /// and register saves would otherwise be paid by every test of a plane across an axis (a
    /// ground polygon under most pixels), which needs none of them.
    #[inline(never)]
    fn intersect_general(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        #[inline(always)]
        fn test(this: &Polygon, ray: &Ray, range: Interval) -> Option<RawHit> {
            let denom = dot_minus(ray.dir, this.normal, 0.0);
            if denom == 0.0 {
                return None;
            }
            let t = -dot_minus(ray.origin, this.normal, this.origin.dot(this.normal)) / denom;
            this.hit_at(ray, range, t)
        }
        crate::with_fma!(test(this: &Polygon = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    /// The hit at `t` on the plane, if `t` is in `range` and the hit inside the polygon.
    #[inline(always)]
    fn hit_at(&self, ray: &Ray, range: Interval, t: f64) -> Option<RawHit> {
        if !range.contains(t) {
            return None;
        }
        let q = self.uv(ray.at(t));
        self.contains_2d(q).then_some(RawHit {
            t,
            feature: 0,
            local: q,
        })
    }
}

impl Intersect for Polygon {
    #[inline]
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // a plane across a coordinate axis needs no compensated sums, hence no FMA copy
        if let Some((k, s)) = self.axis {
            if ray.origin.is_finite() && ray.dir.is_finite() {
                return self.hit_at(ray, range, self.axis_plane_t(k, s, ray)?);
            }
        }
        self.intersect_general(ray, range)
    }

    fn normal_at(&self, _ray: &Ray, _raw: &RawHit) -> DVec3 {
        self.normal
    }

    fn uv_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(raw.local)
    }
}

impl Parametric for Polygon {
    fn domain(&self) -> UvDomain {
        self.domain
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        self.origin + uv.x * self.e1 + uv.y * self.e2
    }

    fn partials(&self, _uv: DVec2) -> (DVec3, DVec3) {
        (self.e1, self.e2)
    }

    #[inline(always)]
    fn uv(&self, p: DVec3) -> DVec2 {
        let q = p - self.origin;
        DVec2::new(q.dot(self.e1), q.dot(self.e2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn xy(points: &[(f64, f64)]) -> Vec<DVec3> {
        points.iter().map(|&(x, y)| DVec3::new(x, y, 1.0)).collect()
    }

    #[test]
    fn constructor_errors_name_the_field() {
        let field = |r: Result<Polygon, PrimitiveError>| r.unwrap_err().field;
        let square = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert_eq!(field(Polygon::new(square[..2].to_vec(), vec![])), "points");
        assert_eq!(
            field(Polygon::new(xy(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]), vec![])),
            "points",
            "collinear"
        );
        let mut nan = square.clone();
        nan[2].y = f64::NAN;
        assert_eq!(field(Polygon::new(nan, vec![])), "points[2]");
        // one point of an octagon lifted (with four points a lifted corner is indistinguishable
        // from the opposite one lowered, so the octagon is the test)
        let octagon: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((f64::from(i) * 0.785).cos(), (f64::from(i) * 0.785).sin(), 1.0))
            .collect();
        let mut bent = octagon.clone();
        bent[3].z += 1e-6;
        assert_eq!(field(Polygon::new(bent, vec![])), "points[3]");
        let hole = xy(&[(0.2, 0.2), (0.4, 0.2), (0.3, 0.4)]);
        assert_eq!(
            field(Polygon::new(square.clone(), vec![hole.clone(), hole[..2].to_vec()])),
            "holes[1]"
        );
        let mut off = hole.clone();
        off[2].z = 1.1;
        assert_eq!(
            field(Polygon::new(square.clone(), vec![hole.clone(), off])),
            "holes[1][2]"
        );
        let mut inf = hole.clone();
        inf[0].x = f64::INFINITY;
        assert_eq!(field(Polygon::new(square.clone(), vec![inf])), "holes[0][0]");
        // within the planarity tolerance: accepted
        let mut slightly = square.clone();
        slightly[3].z += 1e-10;
        assert!(Polygon::new(slightly, vec![hole]).is_ok());
    }

    #[test]
    fn normal_follows_the_outer_ring_and_known_hits() {
        // an L shape in z = 1, counter-clockwise seen from +z, with a square hole
        let l = xy(&[(0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 4.0), (0.0, 4.0)]);
        let hole = xy(&[(0.25, 2.0), (0.25, 3.0), (0.75, 3.0), (0.75, 2.0)]); // clockwise
        let poly = Polygon::new(l.clone(), vec![hole]).unwrap();
        assert_eq!(poly.normal(), DVec3::Z);
        assert!(!poly.is_convex());
        let mut reversed = l.clone();
        reversed.reverse();
        assert_eq!(Polygon::new(reversed, vec![]).unwrap().normal(), -DVec3::Z);
        let down = |x: f64, y: f64| Ray::new(DVec3::new(x, y, 5.0), DVec3::new(0.0, 0.0, -4.0));
        let hit = poly.intersect(&down(3.0, 0.5), Interval::POSITIVE).unwrap();
        assert_eq!(hit.t, 1.0);
        assert!((poly.point(hit.local) - DVec3::new(3.0, 0.5, 1.0)).length() < 1e-15);
        assert!(
            poly.intersect(&down(2.0, 2.0), Interval::POSITIVE).is_none(),
            "notch of the L"
        );
        assert!(poly.intersect(&down(0.5, 2.5), Interval::POSITIVE).is_none(), "hole");
        assert!(poly.intersect(&down(0.5, 3.5), Interval::POSITIVE).is_some());
        assert!(
            poly.intersect(&Ray::new(DVec3::new(0.5, 0.5, 1.0), DVec3::X), Interval::POSITIVE)
                .is_none(),
            "in-plane"
        );
        assert_eq!(poly.phi(DVec3::new(9.0, -3.0, -1.5)), -2.5);
    }

    #[test]
    fn convexity_flag() {
        let convex = |pts: &[(f64, f64)]| Polygon::new(xy(pts), vec![]).unwrap().is_convex();
        assert!(convex(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]));
        assert!(convex(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]));
        assert!(
            convex(&[(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (1.0, 1.0), (1.0, 1.0), (0.0, 1.0)]),
            "collinear, repeated"
        );
        assert!(!convex(&[(0.0, 0.0), (2.0, 0.0), (1.0, 0.5), (1.0, 2.0)]), "dart");
        // a pentagram: every turn is a left turn, but it winds twice
        let star: Vec<(f64, f64)> = (0..5)
            .map(|i| f64::from(i * 2) * 72f64.to_radians())
            .map(|a| (a.cos(), a.sin()))
            .collect();
        assert!(!convex(&star));
        let square = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert!(
            !Polygon::new(square, vec![xy(&[(0.2, 0.2), (0.4, 0.2), (0.3, 0.4)])])
                .unwrap()
                .is_convex(),
            "hole"
        );
    }

    /// Polygons across each coordinate axis, facing either way (a ground square, a concave
    /// ring with a hole, far from the origin or not) take the one-coordinate plane test; its
    /// answers equal the compensated test's bit for bit over random rays, rays from points on
    /// the plane (where `−0` and `+0` differ), nearly parallel and parallel rays, and rays with a
    /// non-finite component.
    #[test]
    fn axis_planes_give_the_compensated_answers() {
        let mut rng = StdRng::seed_from_u64(404);
        let (mut hits, mut on_plane_hits) = (0, 0);
        for case in 0..24 {
            let k = case % 3;
            let flip = (case / 3) % 2 == 1;
            let offset = if case >= 12 { 1.0e6 } else { 0.0 };
            let height = if case % 4 == 0 {
                0.0
            } else {
                rng.random_range(-3.0..3.0)
            };
            // a square and a concave ring with a square hole, in the plane x_k = height
            let at = |u: f64, v: f64| {
                let mut p = [0.0; 3];
                p[k] = height;
                p[(k + 1) % 3] = u + offset;
                p[(k + 2) % 3] = v;
                DVec3::from_array(p)
            };
            let mut outer = if case % 2 == 0 {
                vec![at(-5.0, -5.0), at(5.0, -5.0), at(5.0, 5.0), at(-5.0, 5.0)]
            } else {
                vec![at(-5.0, -5.0), at(5.0, -5.0), at(0.0, 0.5), at(5.0, 5.0), at(-5.0, 5.0)]
            };
            let mut holes = vec![];
            if case % 2 == 1 {
                holes.push(vec![at(-3.0, -1.0), at(-1.0, -1.0), at(-1.0, 1.0), at(-3.0, 1.0)]);
            }
            if flip {
                outer.reverse();
            }
            let polygon = Polygon::new(outer, holes).unwrap();
            assert!(polygon.axis.is_some(), "case {case}: {:?}", polygon.normal);
            let general = Polygon {
                axis: None,
                ..polygon.clone()
            };
            for trial in 0..4000 {
                let target = at(rng.random_range(-6.0..6.0), rng.random_range(-6.0..6.0));
                let origin = match trial % 4 {
                    // on the plane itself
                    0 => at(rng.random_range(-6.0..6.0), rng.random_range(-6.0..6.0)),
                    _ => {
                        target
                            + DVec3::new(
                                rng.random_range(-9.0..9.0),
                                rng.random_range(-9.0..9.0),
                                rng.random_range(-9.0..9.0),
                            )
                    }
                };
                let mut dir = target - origin;
                if trial % 4 == 0 {
                    dir[k] = [0.0, 1e-300, -2.0, 1.0][trial / 4 % 4];
                }
                if trial % 97 == 0 {
                    dir[(k + 1) % 3] = [f64::INFINITY, f64::NAN][trial / 97 % 2];
                }
                let ray = Ray::new(origin, dir);
                for range in [
                    Interval::POSITIVE,
                    Interval::new(-1.0, 1.0),
                    Interval::new(0.0, f64::INFINITY),
                ] {
                    let fast = polygon.intersect(&ray, range);
                    let slow = general.intersect(&ray, range);
                    let bits = |h: Option<RawHit>| h.map(|h| (h.t.to_bits(), h.local.x.to_bits(), h.local.y.to_bits()));
                    assert_eq!(bits(fast), bits(slow), "case {case} trial {trial} {ray:?} {range:?}");
                    hits += usize::from(fast.is_some());
                    on_plane_hits += usize::from(trial % 4 == 0 && fast.is_some_and(|h| h.t == 0.0));
                }
            }
        }
        assert!(hits > 50_000, "{hits} hits");
        assert!(on_plane_hits > 1000, "{on_plane_hits} hits at t = 0 from the plane");
    }

    #[test]
    fn convex_and_general_tests_agree() {
        // a tilted convex octagon with collinear vertices; boundary and vertex queries included
        let mut rng = StdRng::seed_from_u64(3);
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        let (a1, a2) = orthonormal_basis(n);
        let ring2: Vec<DVec2> = (0..8)
            .map(|i| 1.7 * DVec2::from_angle(0.1 + f64::from(i) * std::f64::consts::TAU / 8.0))
            .collect();
        let mut pts: Vec<DVec3> = ring2
            .iter()
            .map(|q| DVec3::new(1.0, 2.0, 3.0) + q.x * a1 + q.y * a2)
            .collect();
        pts.insert(1, 0.5 * (pts[0] + pts[1]));
        let poly = Polygon::new(pts, vec![]).unwrap();
        assert!(poly.is_convex());
        let ring = &poly.rings_2d()[0];
        let mut inside = 0;
        for k in 0..30_000 {
            let q = match k % 3 {
                0 => ring[rng.random_range(0..ring.len())],
                1 => {
                    let i = rng.random_range(0..ring.len());
                    ring[i].lerp(ring[(i + 1) % ring.len()], rng.random())
                }
                _ => DVec2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)),
            };
            let convex = point_in_convex_polygon(q, ring);
            assert_eq!(convex, point_in_polygon(q, poly.rings_2d()), "at {q}");
            assert_eq!(poly.contains_2d(q), convex);
            inside += usize::from(convex);
        }
        assert!(inside > 5_000 && inside < 25_000, "{inside}");
    }
}
