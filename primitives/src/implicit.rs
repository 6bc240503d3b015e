//! [`Implicit`]: a surface as the zero set of a scalar function Φ, what every primitive is.
//!
//! The minimum a type writes is [`Implicit::phi`] and [`Implicit::bounds`]; the gradient has a
//! central-difference default, and a type that can enclose Φ along ray segments by interval
//! arithmetic ([`Implicit::enclose_along`]) gets guaranteed first roots from the generic
//! intersector ([`crate::isolation`]).

use crate::bounds::Aabb;
use crate::expr::Jet;
use crate::math::central_difference;
use crate::math::enclosure::Enclosure;
use crate::proximity::{Closest, SignMethod};
use crate::ray::{Interval, Ray};
use glam::DVec3;

/// A surface given as the zero set of a scalar function Φ.
///
/// Sign convention: **Φ < 0 inside, Φ = 0 on the surface, Φ > 0 outside.** For open surfaces
/// (plane, disk, polygon, triangle) "outside" is the front side, the one the normal points to.
pub trait Implicit {
    /// Φ at `p` (same space as the primitive's parameters).
    fn phi(&self, p: DVec3) -> f64;

    /// A box containing every point of the surface (may be infinite for unbounded surfaces).
    fn bounds(&self) -> Aabb;

    /// Boxes whose union contains every point of the surface, appended to `parts`: [`bounds`]
    /// alone by default. A mesh gives the boxes of its hierarchy's upper nodes, which follow its
    /// shape more closely (a renderer skips the pixels that can see none of them).
    ///
    /// [`bounds`]: Implicit::bounds
    fn bounds_parts(&self, parts: &mut Vec<Aabb>) {
        parts.push(self.bounds());
    }

    /// ∇Φ at `p`. The default is a central difference with step `6·10⁻⁶ ×` the bounds' diagonal
    /// (≈ ∛ε, the optimal step for an O(h²) formula in f64), or `6·10⁻⁶·max(1, |p|)` for unbounded
    /// surfaces. Built-ins override it with the analytic gradient.
    fn gradient(&self, p: DVec3) -> DVec3 {
        let scale = self.bounds().diagonal_length();
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            p.length().max(1.0)
        };
        central_difference(|q| self.phi(q), p, 6e-6 * scale)
    }

    /// A bound `L` with `|Φ(a) − Φ(b)| ≤ L·|a − b|` everywhere in the bounds, if the type knows one.
    ///
    /// With a bound, the generic root finder steps by `|Φ|/L` and cannot step over a surface; a
    /// bound that is too small is detected where it is violated along a ray, counted (see
    /// [`crate::root::lipschitz_violations`]) and the march continues with the larger observed slope.
    /// Without one, the finder samples the ray uniformly ([`crate::RootOptions::samples`]) and can miss
    /// features thinner than one sample spacing.
    fn lipschitz(&self) -> Option<f64> {
        None
    }

    /// Enclosures of `g(t) = Φ(ray.at(t))` (`value`) and of `g′(t) = ∇Φ·dir` (`slope`) valid for
    /// every `t` in `segment`, if the type can bound Φ by interval arithmetic (see
    /// [`crate::math::enclosure`]; [`crate::expr::Expr::enclose_along`] does it for an
    /// expression). A type that returns `Some` gets the guaranteed first root of
    /// [`crate::isolation`] from the generic intersector, without a Lipschitz bound. The default
    /// is `None` (the sampling / sphere-tracing finder of [`crate::root`]).
    ///
    /// The enclosures must be **sound**: a value or slope outside them is a bug that can lose
    /// roots.
    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        let _ = (ray, segment);
        None
    }

    /// The `value` part of [`Implicit::enclose_along`] alone. The interval root finder asks for it
    /// first on every piece, and for the slope only where the value cannot exclude 0, so a type
    /// that can enclose the value more cheaply than value and slope together overrides this.
    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        self.enclose_along(ray, segment).map(|jet| jet.value)
    }

    /// Whether a point of Φ's zero set belongs to the surface. Open surfaces whose Φ describes
    /// their supporting surface (a polygon's plane, a disk's plane, an open cylinder's infinite
    /// tube) restrict it here; the default keeps the whole zero set.
    fn within_boundary(&self, p: DVec3) -> bool {
        let _ = p;
        true
    }

    /// The surface point nearest to `p` and the distance to it, or guaranteed bounds on the
    /// distance where the type cannot be exact (see [`Closest`] and [`crate::proximity`]).
    /// `None` where the type cannot bound the distance at all: the default, since Φ alone says
    /// nothing certain about it (a Φ value is never a distance unless the type proves it).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        let _ = p;
        None
    }

    /// Whether `p` lies inside the solid the surface bounds, decided by `method` where the type
    /// offers a choice (a mesh, see [`SignMethod`]). The default, for every method, is the sign
    /// of Φ: `Φ(p) < 0`. Open surfaces call the side behind their normal inside, as Φ does.
    fn contains(&self, p: DVec3, method: SignMethod) -> bool {
        let _ = method;
        self.phi(p) < 0.0
    }
}
