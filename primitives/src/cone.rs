//! Cone and cone frustum about an arbitrary axis, capped (a solid) or open (the lateral surface).
//!
//! | field         | meaning                                  | constraint                          |
//! |---------------|------------------------------------------|-------------------------------------|
//! | `base`        | centre `b` of the base disk              | finite                              |
//! | `axis`        | axis direction `a` (normalised on input) | finite, non-zero                    |
//! | `base_radius` | radius `r₀` at the base                  | finite, `≥ 0`                       |
//! | `top_radius`  | radius `r₁` at `b + H·a`                 | finite, `≥ 0`, not both radii zero  |
//! | `height`      | axial length `H`                         | finite, `> 0`                       |
//! | `capped`      | closed solid (`true`) or open lateral surface | —                              |
//!
//! `r₁ = 0` is a pointed cone with its apex at `b + H·a`; `r₀ = 0` points the other way; `r₀ = r₁`
//! is a cylinder (what [`crate::Cylinder`] is built on).
//!
//! **Local frame.** `(x, y, h) = ((p − b)·e₁, (p − b)·e₂, (p − b)·a)` with `(e₁, e₂, a)` the
//! right-handed basis of [`orthonormal_basis`]; `ρ = |(x, y)|`, `ρ̂` the radial unit vector. The
//! side has radius `s(h) = r₀ − k·h`, `k = (r₀ − r₁)/H`, and outward normal
//! `n = (H·ρ̂ + (r₀ − r₁)·a)/S` with the slant length `S = √(H² + (r₀ − r₁)²)`.
//!
//! - **Φ, capped**: the exact signed distance of the solid. A solid of revolution's distance is
//!   its meridian section's: the trapezoid `(0,0), (r₀,0), (r₁,H), (0,H)` in the `(ρ, h)`
//!   half-plane, whose boundary is the bottom segment, the side segment and the top segment (the
//!   axis edge is interior). `|Φ|` is the distance to the nearest of the three, negative inside.
//!   `∇Φ` is that segment's outward normal where the nearest point is inside the segment, and the
//!   direction from the nearest rim (or apex) otherwise. Lipschitz bound 1.
//! - **Φ, open**: the infinite double cone through the side, `Φ = (ρ − |s(h)|)·H/S`: the distance
//!   to the nearer of the two meridian lines `ρ = ±s(h)` (each `(ρ ∓ s)·H/S` is a line distance),
//!   so Lipschitz 1; `∇Φ = (H·ρ̂ + sign(s)·(r₀ − r₁)·a)/S`, equal to `n` on the surface.
//!   [`Implicit::within_boundary`] keeps `0 ≤ h ≤ H`.
//! - **Parametric form**: `u ∈ [0, 1]` is the angle `φ = 2πu` from `e₁` towards `e₂` (seam at
//!   `u = 0`, the `e₁` side). Side `v ∈ [0, 1]`: `ρ = (1 − v)·r₀ + v·r₁`, `h = v·H`. Capped, `v`
//!   extends to `[−1, 2]` continuously through the rims: `v ∈ [−1, 0)` is the bottom disk at
//!   `ρ = (1 + v)·r₀` (centre at `v = −1`), `v ∈ (1, 2]` the top disk at `ρ = (2 − v)·r₁`
//!   (centre at `v = 2`; a capped pointed cone has no disk at its apex end, whose half of the
//!   range is dropped: `v ∈ [−1, 1]` for `r₁ = 0`, `v ∈ [0, 2]` for `r₀ = 0`). Point
//!   `b + ρ·(cos φ e₁ + sin φ e₂) + h·a`; `∂p/∂u × ∂p/∂v` points outward on all three parts. `uv`
//!   assigns a point to the part its Φ is nearest to.
//! - **Intersection**: in the local frame, with `o`, `d` the ray's local origin and direction,
//!   the radius along the ray is `s(t) = s₀ + t·s′` (`s₀ = s(o_h)`, `s′ = −k·d_h`) and the side
//!   is `|o⊥ + t·d⊥|² = s(t)²`: `A t² + 2B t + C = 0`, `A = |d⊥|² − s′²`, `B = o⊥·d⊥ − s₀s′`,
//!   `C = |o⊥|² − s₀²`. The discriminant is formed as `B² − AC = |s₀·d⊥ − s′·o⊥|² − (o⊥ × d⊥)²`
//!   (Lagrange's identity, as for the sphere: no `B²` against `AC` cancellation for a small, distant
//!   cone) and solved by [`solve_quadratic`] (`q/A`, `C/q`; `A = 0` for a ray parallel to a side
//!   line or, for a cylinder, to the axis is the linear case, `A = B = 0` a miss). A side root
//!   counts if `0 ≤ h ≤ H`. Caps are the planes `h = 0`, `h = H` with `ρ ≤ r` (closed); a ray in
//!   a cap plane meets the side at the rim instead. The apex of a pointed cone is a double root of
//!   the double cone, which rounding can turn into a miss, so it is tested directly, open or
//!   capped, as the degenerate disk it is: a ray whose radial distance in the apex plane is within
//!   rounding error, `8ε·(|o| + |t·d|)`, of the axis hits it, reported with that end's cap feature
//!   and normal (`+a` for `r₁ = 0`, the limit of the side normal there). On a line through the apex
//!   the side equation is `A·(t − t_apex)² = 0`, so the side is then not solved: its computed
//!   double root would only be the apex again, off by rounding and with a radial normal pointing
//!   anywhere. (A ray running exactly along a generator, `A = B = C = 0`, lies in the surface and
//!   is reported only where it meets the apex or a cap.) Features: `0` side,
//!   `1` bottom cap (or apex), `2` top cap (or apex).
//! - **Closest point**: a surface of revolution's nearest point to `p` lies in `p`'s meridian
//!   half-plane (for a surface point at angle `Δφ` from it, `|p − q|² = (h − h′)² + ρ² + ρ′² −
//!   2ρρ′·cos Δφ`, smallest at `Δφ = 0`), so it is the nearest point `(ρ′, h′)` of the meridian
//!   profile to `(ρ, h)`, mapped back as `b + ρ′·ρ̂ + h′·a`. The profile is the side segment
//!   `(r₀, 0) → (r₁, H)`, and capped also the bottom `(0, 0) → (r₀, 0)` and top
//!   `(0, H) → (r₁, H)` segments (the axis is no part of the surface); on each the nearest point
//!   is the clamped projection `s + clamp(⟨m − s, e⟩/|e|², 0, 1)·e`, and the nearest of them
//!   wins (the side on ties, as in Φ). Exact to rounding. On the axis (`ρ = 0`) every meridian
//!   is nearest and `ρ̂ = e₁` is taken. The feature is the segment's part, and an apex (the
//!   nearest point the pointed end `ρ′ = 0` of the side) takes that end's cap feature, as hits
//!   there do.

use crate::bounds::Aabb;
use crate::error::{
    require_coordinates_within, require_direction, require_finite, require_length_in_range, require_positive,
    PrimitiveError, MAX_MAGNITUDE,
};
use crate::hit::RawHit;
use crate::math::{
    difference_of_products, is_square_safe, orthonormal_basis, power_of_two_scale, solve_quadratic, sum_of_products,
};
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect, Parametric, UvDomain};
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

/// [`RawHit::feature`] of a hit on the lateral surface.
pub const SIDE: u32 = 0;
/// [`RawHit::feature`] of a hit on the base disk (`h = 0`).
pub const BOTTOM: u32 = 1;
/// [`RawHit::feature`] of a hit on the top disk (`h = H`).
pub const TOP: u32 = 2;

/// A cone or frustum (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    base: DVec3,
    axis: DVec3,
    e1: DVec3,
    e2: DVec3,
    r0: f64,
    r1: f64,
    height: f64,
    capped: bool,
    /// Side normal in the meridian plane, `(H, r₀ − r₁)/S`.
    side_normal: DVec2,
}

impl Cone {
    /// A cone; errors on a non-finite base, a zero axis, a negative radius, both radii zero or a
    /// height that is not finite and positive.
    pub fn new(
        base: DVec3,
        axis: DVec3,
        base_radius: f64,
        top_radius: f64,
        height: f64,
        capped: bool,
    ) -> Result<Self, PrimitiveError> {
        let base = require_finite("Cone", "base", base)?;
        let axis = require_direction("Cone", "axis", axis)?;
        for (field, r) in [("base_radius", base_radius), ("top_radius", top_radius)] {
            if !(r.is_finite() && r >= 0.0) {
                return Err(PrimitiveError::new(
                    "Cone",
                    field,
                    format!("must be finite and ≥ 0, got {r}"),
                ));
            }
        }
        if base_radius == 0.0 && top_radius == 0.0 {
            return Err(PrimitiveError::new(
                "Cone",
                "top_radius",
                "base and top radius are both zero",
            ));
        }
        let height = require_positive("Cone", "height", height)?;
        require_coordinates_within("Cone", "base", base, MAX_MAGNITUDE)?;
        require_length_in_range("Cone", "base_radius", base_radius)?;
        require_length_in_range("Cone", "top_radius", top_radius)?;
        require_length_in_range("Cone", "height", height)?;
        Ok(Self::from_valid(base, axis, base_radius, top_radius, height, capped))
    }

    /// Builds from parameters already validated (`axis` unit length).
    pub(crate) fn from_valid(base: DVec3, axis: DVec3, r0: f64, r1: f64, height: f64, capped: bool) -> Self {
        let (e1, e2) = orthonormal_basis(axis);
        let side_normal = DVec2::new(height, r0 - r1) / height.hypot(r0 - r1);
        Self {
            base,
            axis,
            e1,
            e2,
            r0,
            r1,
            height,
            capped,
            side_normal,
        }
    }

    /// Centre of the base disk.
    #[must_use]
    pub fn base(&self) -> DVec3 {
        self.base
    }

    /// Unit axis, from the base towards the top.
    #[must_use]
    pub fn axis(&self) -> DVec3 {
        self.axis
    }

    /// `(base_radius, top_radius)`.
    #[must_use]
    pub fn radii(&self) -> (f64, f64) {
        (self.r0, self.r1)
    }

    /// Axial length.
    #[must_use]
    pub fn height(&self) -> f64 {
        self.height
    }

    /// Whether the cone is a closed solid.
    #[must_use]
    pub fn capped(&self) -> bool {
        self.capped
    }

    fn local_vector(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.e1), v.dot(self.e2), v.dot(self.axis))
    }

    fn local(&self, p: DVec3) -> DVec3 {
        self.local_vector(p - self.base)
    }

    /// Side radius at height `h` (negative beyond the apex).
    fn radius_at(&self, h: f64) -> f64 {
        self.r0 - (self.r0 - self.r1) / self.height * h
    }

    /// World vector from meridian components `(along ρ̂, along a)` at local `(x, y)`; on the axis
    /// the radial part is dropped.
    fn meridian_to_world(&self, l: DVec3, m: DVec2) -> DVec3 {
        let rho = l.truncate().length();
        let radial = if rho > 0.0 {
            (l.x * self.e1 + l.y * self.e2) / rho
        } else {
            DVec3::ZERO
        };
        m.x * radial + m.y * self.axis
    }

    /// Capped solid in the meridian half-plane at `(ρ, h)`: `(Φ, nearest part, ∇Φ as (∂ρ, ∂h))`.
    fn meridian_sdf(&self, rho: f64, h: f64) -> (f64, u32, DVec2) {
        let (r0, r1, big_h) = (self.r0, self.r1, self.height);
        let m = DVec2::new(rho, h);
        let segments = [
            (SIDE, DVec2::new(r0, 0.0), DVec2::new(r1 - r0, big_h), self.side_normal),
            (BOTTOM, DVec2::ZERO, DVec2::new(r0, 0.0), DVec2::NEG_Y),
            (TOP, DVec2::new(0.0, big_h), DVec2::new(r1, 0.0), DVec2::Y),
        ];
        let mut best = (f64::INFINITY, SIDE, DVec2::ZERO, DVec2::ZERO, false);
        for (part, start, edge, normal) in segments {
            let len2 = edge.length_squared();
            let tau = if len2 > 0.0 {
                ((m - start).dot(edge) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let offset = m - (start + tau * edge);
            let dist = offset.length();
            if dist < best.0 {
                best = (dist, part, offset, normal, tau > 0.0 && tau < 1.0);
            }
        }
        let (dist, part, offset, normal, interior) = best;
        let inside = (0.0..=big_h).contains(&h) && big_h * (rho - r0) + (r0 - r1) * h <= 0.0;
        let sign = if inside { -1.0 } else { 1.0 };
        let gradient = if interior || dist == 0.0 {
            normal
        } else {
            sign * offset / dist
        };
        (sign * dist, part, gradient)
    }

    /// The point of the meridian profile nearest to `m = (ρ, h)` and its feature (module docs:
    /// the side segment, and capped also the two cap segments; clamped projections, the side
    /// first on ties, an apex reported with its end's cap feature).
    fn meridian_nearest(&self, m: DVec2) -> (DVec2, u32) {
        let (r0, r1, big_h) = (self.r0, self.r1, self.height);
        let side = (SIDE, DVec2::new(r0, 0.0), DVec2::new(r1, big_h));
        let caps = [
            (BOTTOM, DVec2::ZERO, DVec2::new(r0, 0.0)),
            (TOP, DVec2::new(0.0, big_h), DVec2::new(r1, big_h)),
        ];
        let count = if self.capped { 3 } else { 1 };
        let mut best = (f64::INFINITY, m, SIDE);
        for (part, start, end) in std::iter::once(side).chain(caps).take(count) {
            let edge = end - start;
            let len2 = edge.length_squared();
            let tau = if len2 > 0.0 {
                ((m - start).dot(edge) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            // the end points exactly (a rim keeps its height and radius)
            let q = if tau == 0.0 {
                start
            } else if tau == 1.0 {
                end
            } else {
                start + tau * edge
            };
            let d2 = (m - q).length_squared();
            if d2 < best.0 {
                best = (d2, q, part);
            }
        }
        let (_, q, mut part) = best;
        if q.x == 0.0 && part == SIDE {
            // the apex of a pointed end
            part = if q.y == 0.0 { BOTTOM } else { TOP };
        }
        (q, part)
    }

    /// `(ρ, h, ∂ρ/∂v, ∂h/∂v)` of the profile at `v` (module docs).
    fn profile(&self, v: f64) -> (f64, f64, f64, f64) {
        if self.capped && v < 0.0 {
            ((1.0 + v) * self.r0, 0.0, self.r0, 0.0)
        } else if self.capped && v > 1.0 {
            ((2.0 - v) * self.r1, self.height, -self.r1, 0.0)
        } else {
            (
                (1.0 - v) * self.r0 + v * self.r1,
                v * self.height,
                self.r1 - self.r0,
                self.height,
            )
        }
    }
}

impl Implicit for Cone {
    fn phi(&self, p: DVec3) -> f64 {
        let l = self.local(p);
        let rho = l.truncate().length();
        if self.capped {
            self.meridian_sdf(rho, l.z).0
        } else {
            (rho - self.radius_at(l.z).abs()) * self.side_normal.x
        }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let l = self.local(p);
        let m = if self.capped {
            self.meridian_sdf(l.truncate().length(), l.z).2
        } else {
            let n = self.side_normal;
            DVec2::new(n.x, if self.radius_at(l.z) < 0.0 { -n.y } else { n.y })
        };
        self.meridian_to_world(l, m)
    }

    fn bounds(&self) -> Aabb {
        // a disk of radius r with normal a reaches r·√(1 − aᵢ²) along world axis i
        let reach = (DVec3::ONE - self.axis * self.axis).max(DVec3::ZERO);
        let reach = DVec3::new(reach.x.sqrt(), reach.y.sqrt(), reach.z.sqrt());
        let top = self.base + self.height * self.axis;
        Aabb::from_points([self.base - self.r0 * reach, self.base + self.r0 * reach])
            .union(Aabb::from_points([top - self.r1 * reach, top + self.r1 * reach]))
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }

    fn within_boundary(&self, p: DVec3) -> bool {
        self.capped || (0.0..=self.height).contains(&self.local(p).z)
    }

    /// The nearest point of the meridian profile in `p`'s meridian half-plane, mapped back
    /// (module docs).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let l = self.local(p);
        let rho = l.truncate().length();
        let (m, part) = self.meridian_nearest(DVec2::new(rho, l.z));
        let radial = if rho > 0.0 {
            (l.x * self.e1 + l.y * self.e2) / rho
        } else {
            self.e1
        };
        Some(Closest::exact(p, self.base + m.x * radial + m.y * self.axis, part))
    }
}

impl Intersect for Cone {
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        // the whole test inlined into the AVX2+FMA copy where the CPU has them
        #[inline(always)]
        fn test(this: &Cone, ray: &Ray, range: Interval) -> Option<RawHit> {
            let dir_size = ray.dir.abs().max_element();
            if !is_square_safe(dir_size) && dir_size > 0.0 && dir_size.is_finite() {
                // |d|² and its products would overflow or underflow: the same line with d/k (k a
                // power of two, exact), whose parameters are t·k
                let k = power_of_two_scale(dir_size);
                let scaled = Ray::new(ray.origin, ray.dir / k);
                let hit = this.intersect(&scaled, Interval::new(range.min * k, range.max * k))?;
                return Some(RawHit { t: hit.t / k, ..hit }).filter(|h| range.contains(h.t));
            }
            let (o, d) = (this.local(ray.origin), this.local_vector(ray.dir));
            let (o2, d2) = (o.truncate(), d.truncate());
            let mut best: Option<RawHit> = None;
            let mut consider = |t: f64, feature: u32| {
                // a finite t only: a denormal axial direction puts a cap at t = ±∞
                if t.is_finite() && range.contains(t) && best.is_none_or(|b| t < b.t) {
                    best = Some(RawHit::on_feature(t, feature));
                }
            };
            // caps, and the apex of a pointed end
            let mut through_apex = false;
            if d.z != 0.0 {
                for (feature, h, r) in [(BOTTOM, 0.0, this.r0), (TOP, this.height, this.r1)] {
                    let t = (h - o.z) / d.z;
                    let at = o2 + t * d2;
                    if r == 0.0 {
                        // the local origin and direction carry rounding of order ε·|o| and ε·|t·d|
                        let rounding = 8.0 * f64::EPSILON * (o.length() + (t * d).length());
                        if at.length() <= rounding {
                            through_apex = true;
                            consider(t, feature);
                        }
                    } else if this.capped && at.length_squared() <= r * r {
                        consider(t, feature);
                    }
                }
            }
            if through_apex {
                // on a line through the apex the side equation is A·(t − t_apex)² = 0: no other root
                return best;
            }
            // solve the side quadratic
            let s0 = this.radius_at(o.z);
            let ds = -(this.r0 - this.r1) / this.height * d.z;
            // compensated sums of products (no cancellation loss for a far cone, an origin close
            // to the side, or a ray nearly parallel to a side line)
            let a = sum_of_products([(d2.x, d2.x), (d2.y, d2.y), (ds, -ds)]);
            let b = sum_of_products([(o2.x, d2.x), (o2.y, d2.y), (s0, -ds)]);
            let c = sum_of_products([(o2.x, o2.x), (o2.y, o2.y), (s0, -s0)]);
            let cross = difference_of_products(o2.x, d2.y, o2.y, d2.x);
            let m = DVec2::new(
                difference_of_products(s0, d2.x, ds, o2.x),
                difference_of_products(s0, d2.y, ds, o2.y),
            );
            let disc = sum_of_products([(m.x, m.x), (m.y, m.y), (cross, -cross)]);
            if let Some((t0, t1)) = solve_quadratic(a, b, c, disc) {
                for t in [t0, t1] {
                    if (0.0..=this.height).contains(&(o.z + t * d.z)) {
                        consider(t, SIDE);
                    }
                }
            }
            best
        }
        crate::with_fma!(test(this: &Cone = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        match raw.feature {
            BOTTOM => -self.axis,
            TOP => self.axis,
            _ => {
                let n = self.meridian_to_world(self.local(ray.at(raw.t)), self.side_normal);
                // on the axis (an apex) only the axial part remains: ±a
                n.normalize_or_zero()
            }
        }
    }

    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(self.uv(ray.at(raw.t)))
    }
}

impl Parametric for Cone {
    fn domain(&self) -> UvDomain {
        let bottom = if self.capped && self.r0 > 0.0 { -1.0 } else { 0.0 };
        let top = if self.capped && self.r1 > 0.0 { 2.0 } else { 1.0 };
        UvDomain {
            u: (0.0, 1.0),
            v: (bottom, top),
        }
    }

    fn point(&self, uv: DVec2) -> DVec3 {
        let (rho, h, _, _) = self.profile(uv.y);
        let (sin, cos) = (TAU * uv.x).sin_cos();
        self.base + rho * (cos * self.e1 + sin * self.e2) + h * self.axis
    }

    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let (rho, _, drho, dh) = self.profile(uv.y);
        let (sin, cos) = (TAU * uv.x).sin_cos();
        let radial = cos * self.e1 + sin * self.e2;
        (
            TAU * rho * (cos * self.e2 - sin * self.e1),
            drho * radial + dh * self.axis,
        )
    }

    fn uv(&self, p: DVec3) -> DVec2 {
        let l = self.local(p);
        let rho = l.truncate().length();
        let mut u = l.y.atan2(l.x) / TAU;
        if u < 0.0 {
            u += 1.0;
        }
        let part = if self.capped {
            self.meridian_sdf(rho, l.z).1
        } else {
            SIDE
        };
        let v = match part {
            BOTTOM => rho / self.r0 - 1.0,
            TOP => 2.0 - rho / self.r1,
            _ => l.z / self.height,
        };
        let domain = self.domain();
        DVec2::new(u, v.clamp(domain.v.0, domain.v.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::SQRT_2;

    /// Pointed cone: base disk of radius 1 at the origin, apex at (0, 0, 1).
    fn pointed(capped: bool) -> Cone {
        Cone::new(DVec3::ZERO, DVec3::Z, 1.0, 0.0, 1.0, capped).unwrap()
    }

    fn hit(cone: &Cone, ray: Ray) -> Option<(f64, u32, DVec3)> {
        cone.intersect(&ray, Interval::POSITIVE)
            .map(|h| (h.t, h.feature, cone.normal_at(&ray, &h)))
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-15
    }

    #[test]
    fn rejects_bad_parameters() {
        let ok = |r0, r1, h| Cone::new(DVec3::ZERO, DVec3::Z, r0, r1, h, true);
        assert!(ok(1.0, 0.0, 1.0).is_ok() && ok(0.0, 1.0, 1.0).is_ok() && ok(1.0, 1.0, 1.0).is_ok());
        assert!(ok(-1.0, 0.5, 1.0).is_err());
        assert!(ok(1.0, -0.5, 1.0).is_err());
        assert!(ok(0.0, 0.0, 1.0).is_err(), "both radii zero");
        assert!(ok(1.0, 0.5, 0.0).is_err(), "zero height");
        assert!(ok(f64::NAN, 0.5, 1.0).is_err());
        assert!(ok(1.0, f64::INFINITY, 1.0).is_err());
        assert!(Cone::new(DVec3::ZERO, DVec3::ZERO, 1.0, 0.0, 1.0, true).is_err());
        assert!(Cone::new(DVec3::NAN, DVec3::Z, 1.0, 0.0, 1.0, true).is_err());
    }

    #[test]
    fn side_hit_and_normal_are_exact() {
        for capped in [true, false] {
            let (t, feature, n) = hit(&pointed(capped), Ray::new(DVec3::new(-2.0, 0.0, 0.5), DVec3::X)).unwrap();
            assert_eq!((t, feature), (1.5, SIDE));
            assert!(close(n, DVec3::new(-1.0, 0.0, 1.0) / SQRT_2), "{n}");
        }
        // frustum r₀ = 2, r₁ = 1, H = 2: radius 1.5 at h = 1, normal (2, 1)/√5 in (ρ, h)
        let frustum = Cone::new(DVec3::ZERO, DVec3::Z, 2.0, 1.0, 2.0, true).unwrap();
        let (t, _, n) = hit(&frustum, Ray::new(DVec3::new(0.0, -5.0, 1.0), DVec3::Y)).unwrap();
        assert_eq!(t, 3.5);
        assert!(close(n, DVec3::new(0.0, -2.0, 1.0) / 5f64.sqrt()), "{n}");
        // widening frustum r₀ = 1, r₁ = 2, H = 1: the side faces downwards
        let widening = Cone::new(DVec3::ZERO, DVec3::Z, 1.0, 2.0, 1.0, false).unwrap();
        let (t, _, n) = hit(&widening, Ray::new(DVec3::new(3.0, 0.0, 0.5), -DVec3::X)).unwrap();
        assert_eq!(t, 1.5);
        assert!(close(n, DVec3::new(1.0, 0.0, -1.0) / SQRT_2), "{n}");
    }

    #[test]
    fn phi_values_and_gradients() {
        let solid = pointed(true);
        assert_eq!(solid.phi(DVec3::new(0.0, 0.0, -1.0)), 1.0);
        assert_eq!(
            solid.phi(DVec3::new(0.0, 0.0, 3.0)),
            2.0,
            "above the apex: distance to it"
        );
        assert_eq!(solid.gradient(DVec3::new(0.0, 0.0, 3.0)), DVec3::Z);
        assert_eq!(solid.phi(DVec3::new(0.0, 0.0, 0.25)), -0.25, "nearest: the base");
        assert_eq!(solid.phi(DVec3::new(2.0, 0.0, 0.0)), 1.0, "beyond the rim");
        assert_eq!(solid.gradient(DVec3::new(2.0, 0.0, 0.0)), DVec3::X);
        let p = DVec3::new(0.0, 1.0, 1.0);
        assert!((solid.phi(p) - SQRT_2 / 2.0).abs() < 1e-15);
        assert!(close(solid.gradient(p), DVec3::new(0.0, 1.0, 1.0) / SQRT_2));
        // open: the double cone; above the apex the upper nappe's inside is negative
        let open = pointed(false);
        assert!((open.phi(DVec3::new(0.0, 0.0, 3.0)) + SQRT_2).abs() < 1e-15);
        assert!((open.phi(p) - SQRT_2 / 2.0).abs() < 1e-15);
        assert!(!open.within_boundary(DVec3::new(0.0, 0.0, 3.0)));
    }

    #[test]
    fn rays_along_the_axis_hit_the_apex_or_a_cap() {
        for capped in [true, false] {
            let cone = pointed(capped);
            // from above: the apex (the degenerate top disk) at t = 2, normal +axis
            assert_eq!(
                hit(&cone, Ray::new(DVec3::new(0.0, 0.0, 3.0), -DVec3::Z)),
                Some((2.0, TOP, DVec3::Z))
            );
            // from below: the base disk if capped, else the apex from inside
            let from_below = hit(&cone, Ray::new(DVec3::new(0.0, 0.0, -1.0), DVec3::Z)).unwrap();
            assert_eq!(
                from_below,
                if capped {
                    (1.0, BOTTOM, -DVec3::Z)
                } else {
                    (2.0, TOP, DVec3::Z)
                }
            );
            // parallel to the axis, off it: side (open) or base (capped)
            let (t, feature, _) = hit(&cone, Ray::new(DVec3::new(0.5, 0.0, -1.0), DVec3::Z)).unwrap();
            assert_eq!((t, feature), if capped { (1.0, BOTTOM) } else { (1.5, SIDE) });
            assert_eq!(hit(&cone, Ray::new(DVec3::new(1.5, 0.0, -1.0), DVec3::Z)), None);
        }
    }

    #[test]
    fn ray_through_the_apex_of_a_tilted_cone() {
        // a tilted axis, so that nothing below is exactly representable; the ray enters the solid
        // through the apex at 5° to the axis. Without the apex test the side's double root there
        // is found or lost by rounding, and comes with a radial normal pointing anywhere.
        let axis = DVec3::new(1.0, 2.0, 3.0).normalize();
        let (e1, _) = orthonormal_basis(axis);
        let base = DVec3::new(0.3, -1.7, 2.9);
        let apex = base + 2.5 * axis;
        let angle = 5f64.to_radians();
        let w = angle.cos() * axis + angle.sin() * e1;
        for capped in [true, false] {
            let cone = Cone::new(base, axis, 1.5, 0.0, 2.5, capped).unwrap();
            let ray = Ray::new(apex + 3.0 * w, -w);
            let (t, feature, n) = hit(&cone, ray).unwrap();
            assert!((t - 3.0).abs() < 1e-14, "t = {t}");
            assert_eq!(feature, TOP);
            assert_eq!(n, axis);
        }
    }

    #[test]
    fn rays_parallel_to_a_side_line() {
        // direction (−1, 0, 1) is parallel to the generator from (1, 0, 0) to the apex: A = 0
        let ray = Ray::new(DVec3::new(1.5, 0.0, -1.0), DVec3::new(-1.0, 0.0, 1.0));
        // open: the linear root, at (−0.25, 0, 0.75), leaving from inside after crossing the axis
        let (t, feature, n) = hit(&pointed(false), ray).unwrap();
        assert_eq!((t, feature), (1.75, SIDE));
        assert!(close(n, DVec3::new(-1.0, 0.0, 1.0) / SQRT_2), "{n}");
        // capped: the base disk first, at (0.5, 0, 0)
        assert_eq!(hit(&pointed(true), ray), Some((1.0, BOTTOM, -DVec3::Z)));
        // the generator itself, shifted outwards: never meets the cone
        assert_eq!(
            hit(
                &pointed(true),
                Ray::new(DVec3::new(2.5, 0.0, -1.0), DVec3::new(-1.0, 0.0, 1.0))
            ),
            None
        );
    }

    #[test]
    fn caps_and_the_rim() {
        let frustum = Cone::new(DVec3::ZERO, DVec3::Z, 2.0, 1.0, 2.0, true).unwrap();
        assert_eq!(
            hit(&frustum, Ray::new(DVec3::new(0.5, 0.5, 5.0), -DVec3::Z)),
            Some((3.0, TOP, DVec3::Z))
        );
        // from inside, through the top disk
        assert_eq!(
            hit(&frustum, Ray::new(DVec3::new(0.5, 0.5, 1.0), DVec3::Z)),
            Some((1.0, TOP, DVec3::Z))
        );
        // at the top rim (1, 0, 2): side and cap agree on t
        let (t, _, _) = hit(
            &frustum,
            Ray::new(DVec3::new(-2.0, 0.0, 5.0), DVec3::new(3.0, 0.0, -3.0)),
        )
        .unwrap();
        assert_eq!(t, 1.0);
    }

    #[test]
    fn parametric_form_is_continuous_through_the_rims() {
        let frustum = Cone::new(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(0.0, 1.0, 1.0),
            2.0,
            1.0,
            2.0,
            true,
        )
        .unwrap();
        assert_eq!(frustum.domain().v, (-1.0, 2.0));
        assert_eq!(pointed(true).domain().v, (-1.0, 1.0));
        for u in [0.0, 0.3, 0.9] {
            for v in [0.0, 1.0] {
                let (below, above) = (
                    frustum.point(DVec2::new(u, v - 1e-12)),
                    frustum.point(DVec2::new(u, v + 1e-12)),
                );
                assert!((below - above).length() < 1e-11, "jump at v = {v}");
            }
            // disk centres at v = −1 and v = 2
            assert!((frustum.point(DVec2::new(u, -1.0)) - frustum.base()).length() < 1e-15);
            let top = frustum.base() + 2.0 * frustum.axis();
            assert!((frustum.point(DVec2::new(u, 2.0)) - top).length() < 1e-15);
        }
    }
}
