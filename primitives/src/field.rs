//! Φ written once: a user type writes Φ generically over [`Scalar`], and [`FieldSurface`] turns
//! it into a primitive with exact gradients and guaranteed first roots.
//!
//! The one generic function is evaluated in three number types:
//! - `f64` at points: [`Implicit::phi`];
//! - [`Jet`]`<f64>` along each axis (forward-mode differentiation): the **exact** gradient
//!   [`Implicit::gradient`] (no finite differences), so normals are the analytic ones;
//! - [`Enclosure`] and [`Jet`]`<`[`Enclosure`]`>` over a ray segment (outward-rounded interval
//!   arithmetic): [`Implicit::enclose_value_along`] and [`Implicit::enclose_along`], with which the
//!   default intersector isolates the **first root with a guarantee** ([`crate::isolation`]): no
//!   Lipschitz constant, no hand-written enclosure, thin features not stepped over, tangent rays
//!   counted as uncertain rather than lost.
//!
//! ```
//! use zeroset_primitives::expr::Scalar;
//! use zeroset_primitives::{Aabb, FieldSurface, Intersect, Interval, Ray, ScalarField};
//! use glam::DVec3;
//!
//! /// A torus around the y axis: Φ = √((√(x² + z²) − R)² + y²) − r.
//! #[derive(Debug)]
//! struct Torus { major: f64, minor: f64 }
//!
//! impl ScalarField for Torus {
//!     fn phi<T: Scalar>(&self, [x, y, z]: [T; 3]) -> T {
//!         let ring = (x * x + z * z).sqrt() - T::constant(self.major);
//!         (ring * ring + y * y).sqrt() - T::constant(self.minor)
//!     }
//!     fn bounds(&self) -> Aabb {
//!         let e = self.major + self.minor;
//!         Aabb::new(DVec3::new(-e, -self.minor, -e), DVec3::new(e, self.minor, e))
//!     }
//! }
//!
//! let torus = FieldSurface::new(Torus { major: 1.0, minor: 0.25 });
//! let ray = Ray::new(DVec3::new(-3.0, 0.0, 0.0), DVec3::X);
//! let hit = torus.intersect(&ray, Interval::POSITIVE).unwrap();
//! assert!((hit.t - 1.75).abs() < 1e-7);
//! ```
//!
//! **Compiled.** [`FieldSurface::new`] runs Φ once in a recording number type
//! ([`crate::expr::record`]) and, where Φ is made of the operations expressions have (no branch
//! on its values, no [`Scalar::sign`]), compiles what it recorded as a [`Function`] expression
//! does: an instruction tape, pruned over an octree of the box, which rays walk (in packets
//! where they point alike) and point queries search ([`Implicit::closest`]). The tape computes
//! the generic Φ's operations in its order, so its values are Φ's; Φ, its gradient and its
//! enclosures along rays are still the generic function's own. A Φ that cannot be recorded (or
//! is undefined somewhere in its box) is traced by the generic finder from its enclosures
//! along each ray, as before; [`FieldSurface::is_compiled`] says which.
//!
//! Soundness: the interval evaluations are as sound as the operations of [`Scalar`] for
//! [`Enclosure`]: every rounded operation is rounded outward, and a branch (`min`, `max`, an
//! `if` on [`Scalar::certain_order`]) that cannot be decided over a segment covers both sides
//! ([`Scalar::either`]). A user's Φ must use only these operations on its arguments (constants
//! through [`Scalar::constant`]) for the guarantee to hold.

use crate::bounds::Aabb;
use crate::expr::record::record;
use crate::expr::{coordinates_along, jets_along, Expr, Jet, Scalar};
use crate::function::Function;
use crate::hit::RawHit;
use crate::math::enclosure::Enclosure;
use crate::proximity::Closest;
use crate::ray::{Interval, Ray};
use crate::root::RootOptions;
use crate::traits::{Implicit, Intersect};
use glam::DVec3;
use std::sync::Arc;

/// A scalar field Φ (negative inside, zero on the surface, positive outside), written once for
/// every [`Scalar`] type, inside a box. Wrap it in [`FieldSurface`] to render it.
pub trait ScalarField: Send + Sync {
    /// Φ at `[x, y, z]` in any number type (f64, intervals, jets).
    fn phi<T: Scalar>(&self, p: [T; 3]) -> T;

    /// A finite box holding every point of the surface (the surface outside it is ignored).
    fn bounds(&self) -> Aabb;

    /// Tolerances of the root isolation (the default: `1e-7` in units of `t`).
    fn root_options(&self) -> RootOptions {
        RootOptions::default()
    }
}

/// A [`ScalarField`] as a primitive: point values, exact gradients and interval enclosures from
/// its one generic Φ, traced as a compiled expression where Φ can be recorded (see the module
/// docs).
#[derive(Clone, Debug)]
pub struct FieldSurface<F> {
    field: F,
    /// Φ recorded and compiled, where it could be.
    compiled: Option<Arc<Function>>,
}

impl<F: ScalarField> FieldSurface<F> {
    /// The surface of `field`, its Φ recorded and compiled where it can be (see the module docs).
    pub fn new(field: F) -> Self {
        let compiled = record(|p| field.phi(p)).and_then(|root| {
            let expr = Expr::recorded(root, std::any::type_name::<F>().to_string());
            Function::from_expr(expr, field.bounds(), field.root_options())
                .ok()
                .map(Arc::new)
        });
        Self { field, compiled }
    }

    /// Whether Φ was recorded and compiled (rays walk its octree), rather than traced by the
    /// generic finder from its enclosures.
    #[must_use]
    pub fn is_compiled(&self) -> bool {
        self.compiled.is_some()
    }

    /// The field.
    pub fn field(&self) -> &F {
        &self.field
    }
}

impl<F: ScalarField> Implicit for FieldSurface<F> {
    fn phi(&self, p: DVec3) -> f64 {
        self.field.phi([p.x, p.y, p.z])
    }

    fn bounds(&self) -> Aabb {
        self.field.bounds()
    }

    /// The exact gradient by forward-mode differentiation (the three partial derivatives in one
    /// pass, the same bits as one pass per axis).
    fn gradient(&self, p: DVec3) -> DVec3 {
        DVec3::from_array(self.field.phi(Jet::axes(p.to_array())).slope)
    }

    /// Enclosures of Φ and of `dΦ/dt` over the points of the segment inside the box (`+∞`,
    /// root-free, where none is inside).
    fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> {
        let bounds = self.field.bounds();
        Some(match coordinates_along(ray, segment, bounds.min, bounds.max) {
            Some(c) => self.field.phi(jets_along(c, ray.dir)),
            None => Jet::new(Enclosure::point(f64::INFINITY), Enclosure::ENTIRE),
        })
    }

    fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> {
        let bounds = self.field.bounds();
        Some(match coordinates_along(ray, segment, bounds.min, bounds.max) {
            Some(c) => self.field.phi(c),
            None => Enclosure::point(f64::INFINITY),
        })
    }

    /// Compiled: guaranteed bounds on the distance to the zero set inside the box, by the
    /// expression's branch and bound over its octree ([`Function`]'s `closest`); otherwise
    /// none (the default).
    fn closest(&self, p: DVec3) -> Option<Closest> {
        self.compiled.as_ref().and_then(|f| f.closest(p))
    }
}

impl<F: ScalarField> Intersect for FieldSurface<F> {
    /// Compiled: the octree's leaves front to back, as a [`Function`] expression; otherwise the
    /// generic finder on the enclosures along the ray.
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        match &self.compiled {
            Some(f) => f.intersect(ray, range),
            None => crate::root::first_root(self, ray, range, &self.field.root_options()).hit,
        }
    }

    /// Compiled: the rays walk the octree together, as a [`Function`]'s packets do (the same
    /// hits as [`FieldSurface::intersect`] ray by ray).
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        match &self.compiled {
            Some(f) => f.intersect_packet(rays, ranges, hits),
            None => crate::traits::packet_lane_by_lane(self, rays, ranges, hits),
        }
    }

    fn root_options(&self) -> RootOptions {
        self.field.root_options()
    }

    /// Compiled: the gradient from the pruned tape of the leaf the hit was found in (Φ's
    /// gradient, the same operations); otherwise the normalised gradient (the default).
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        match &self.compiled {
            Some(f) => f.normal_at(ray, raw),
            None => self.gradient(ray.at(raw.t)).normalize_or_zero(),
        }
    }

    /// The rounding bound plus the root finder's tolerance along the ray: a hit is within the
    /// tolerance of a root, so secondary rays start beyond it (no shadow acne).
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        let magnitude = crate::offset::magnitude(&self.field.bounds());
        crate::offset::root_error_bound(ray, raw.t, magnitude, self.field.root_options().tolerance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct Torus {
        major: f64,
        minor: f64,
    }

    impl ScalarField for Torus {
        fn phi<T: Scalar>(&self, [x, y, z]: [T; 3]) -> T {
            let ring = (x * x + z * z).sqrt() - T::constant(self.major);
            (ring * ring + y * y).sqrt() - T::constant(self.minor)
        }
        fn bounds(&self) -> Aabb {
            let e = self.major + self.minor;
            Aabb::new(DVec3::new(-e, -self.minor, -e), DVec3::new(e, self.minor, e))
        }
    }

    /// Hits against the closed form of the torus's first crossing along axis-parallel and
    /// oblique rays (f64 reference by bisection on the exact Φ), and normals against the
    /// analytic gradient.
    #[test]
    fn generic_torus_hits_and_exact_normals() {
        let (major, minor) = (1.0, 0.25);
        let torus = FieldSurface::new(Torus { major, minor });
        // along x through the centre: the outer wall at t = 3 − 1.25
        let ray = Ray::new(DVec3::new(-3.0, 0.0, 0.0), DVec3::X);
        let hit = torus.intersect(&ray, Interval::POSITIVE).unwrap();
        assert!((hit.t - 1.75).abs() <= 1e-7, "{}", hit.t);
        // straight down the hole: a miss
        assert!(torus
            .intersect(&Ray::new(DVec3::new(0.0, 3.0, 0.0), -DVec3::Y), Interval::POSITIVE)
            .is_none());
        // oblique rays: Φ at the hit is ~0 and the normal is the analytic one
        for k in 0..200 {
            let a = f64::from(k) * 0.0314;
            let o = DVec3::new(3.0 * a.cos(), 1.0 + 0.3 * (3.0 * a).sin(), 3.0 * a.sin());
            let target = DVec3::new(0.9 * (a + 0.5).cos(), 0.1 * a.cos(), 0.9 * (a + 0.5).sin());
            let ray = Ray::new(o, (target - o).normalize());
            let Some(hit) = torus.intersect(&ray, Interval::POSITIVE) else {
                continue;
            };
            let p = ray.at(hit.t);
            // the exact distance to the tube's centre circle, in f64
            let q = DVec3::new(p.x, 0.0, p.z).normalize() * major;
            assert!(((p - q).length() - minor).abs() < 1e-6, "{p}");
            let analytic = ((p - q) / (p - q).length()).normalize();
            assert!((torus.normal_at(&ray, &hit) - analytic).length() <= 1e-12, "{p}");
        }
    }

    /// A shell thinner than any sampling step is found by every ray that crosses it.
    #[test]
    fn thin_shells_are_not_stepped_over() {
        #[derive(Debug)]
        struct Shell;
        impl ScalarField for Shell {
            fn phi<T: Scalar>(&self, [x, y, z]: [T; 3]) -> T {
                // |  |p| − 1 | − 1e-6: a shell 2·10⁻⁶ thick
                ((x * x + y * y + z * z).sqrt() - T::constant(1.0)).abs() - T::constant(1e-6)
            }
            fn bounds(&self) -> Aabb {
                Aabb::new(DVec3::splat(-1.1), DVec3::splat(1.1))
            }
        }
        let shell = FieldSurface::new(Shell);
        for k in 0..100 {
            let y = -0.95 + 0.019 * f64::from(k);
            let ray = Ray::new(DVec3::new(-3.0, y, 0.0), DVec3::X);
            let hit = shell.intersect(&ray, Interval::POSITIVE).expect("the shell is crossed");
            let exact = 3.0 - (1.0 + 1e-6_f64).mul_add(1.0 + 1e-6, -y * y).sqrt();
            assert!((hit.t - exact).abs() <= 1e-6, "y = {y}: {} vs {exact}", hit.t);
        }
    }
}

/// The recording and the compiled path: what is recorded evaluates as the generic Φ does (bit
/// for bit, in points, intervals and jets), what cannot be recorded falls back to the generic
/// finder, and both find the same roots.
#[cfg(test)]
mod compiled_tests {
    use super::*;
    use crate::expr::record::record;
    use glam::DVec2;
    use rand::{Rng, SeedableRng};
    use std::cmp::Ordering;

    /// A torus around the y axis, and a shape using every recordable operation.
    #[derive(Clone, Copy, Debug)]
    enum Shape {
        Torus,
        Everything,
        /// The torus behind a branch on Φ's value: not recordable.
        Branching,
        /// The torus times `sign(1 + x²)` (= 1): not recordable.
        Signed,
    }

    impl ScalarField for Shape {
        fn phi<T: Scalar>(&self, [x, y, z]: [T; 3]) -> T {
            let c = T::constant;
            let ring = (x * x + z * z).sqrt() - c(1.0);
            let torus = (ring * ring + y * y).sqrt() - c(0.3);
            match self {
                Shape::Torus => torus,
                Shape::Everything => {
                    let wobble = (x.sin() * y.cos() + z.tan().atan() * c(0.1)).tanh()
                        + (x * c(0.2)).asin() * (y * c(0.2)).acos() * c(0.01)
                        + ((x * c(0.3)).sinh() + (y * c(0.3)).cosh()).cbrt() * c(0.01)
                        + (x * x + c(1.0)).ln() * c(0.01)
                        + (y * y + c(2.0)).log10() * (z * z + c(2.0)).log2() * c(0.01)
                        + (-(x * x)).exp() * c(0.02)
                        + (z * z + c(1.0)).pow(c(0.5)) * c(0.01)
                        + x.powi(3) * c(0.001)
                        - (y / c(3.0)).abs();
                    (torus + wobble * c(0.05)).min(torus + c(0.5)).max(-torus - c(2.0))
                }
                Shape::Branching => match torus.certain_order(c(100.0)) {
                    Some(Ordering::Greater) => c(100.0),
                    Some(_) => torus,
                    None => torus.either(c(100.0)),
                },
                Shape::Signed => torus * (x * x + c(1.0)).sign(),
            }
        }

        fn bounds(&self) -> Aabb {
            Aabb::new(DVec3::new(-1.5, -0.5, -1.5), DVec3::new(1.5, 0.5, 1.5))
        }
    }

    fn random_box(rng: &mut impl Rng) -> [Enclosure; 3] {
        let mut axis = || {
            let (a, b) = (rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
            Enclosure::new(f64::min(a, b), f64::max(a, b))
        };
        [axis(), axis(), axis()]
    }

    #[test]
    fn recorded_phi_evaluates_as_the_generic_one_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for shape in [Shape::Torus, Shape::Everything] {
            let root = record(|p| shape.phi(p)).expect("recordable");
            let expr = Expr::recorded(root, "shape".into());
            let tape = expr.compile();
            for _ in 0..2000 {
                let p = [
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-1.5..1.5),
                ];
                let generic = shape.phi(p);
                assert_eq!(
                    expr.eval(DVec3::from_array(p)).to_bits(),
                    generic.to_bits(),
                    "{shape:?} at {p:?}"
                );
                assert_eq!(
                    tape.eval_f64(p, &mut Vec::new()).to_bits(),
                    generic.to_bits(),
                    "{shape:?} tape at {p:?}"
                );
                let jets = Jet::axes(p);
                let (a, b) = (expr.eval_in(jets), shape.phi(jets));
                assert_eq!(a.value.to_bits(), b.value.to_bits());
                for (u, v) in a.slope.iter().zip(b.slope) {
                    assert_eq!(u.to_bits(), v.to_bits(), "{shape:?} gradient at {p:?}");
                }
                let cell = random_box(&mut rng);
                let (a, b) = (expr.eval_in(cell), shape.phi(cell));
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "{shape:?} over {cell:?}");
            }
            assert!(FieldSurface::new(shape).is_compiled(), "{shape:?}");
        }
        // branches and `sign` are not recorded
        assert!(record(|p| Shape::Branching.phi(p)).is_none());
        assert!(record(|p| Shape::Signed.phi(p)).is_none());
        assert!(!FieldSurface::new(Shape::Branching).is_compiled());
        assert!(!FieldSurface::new(Shape::Signed).is_compiled());
    }

    /// The compiled torus and the generic finder on the same torus (through a branch it cannot
    /// record) find the same first roots, within the tolerance, hit and miss alike, and the
    /// compiled one bounds the exact distance to the torus.
    #[test]
    fn compiled_and_generic_surfaces_agree() {
        let compiled = FieldSurface::new(Shape::Torus);
        let generic = FieldSurface::new(Shape::Branching);
        assert!(compiled.is_compiled() && !generic.is_compiled());
        let mut rng = rand::rngs::StdRng::seed_from_u64(6);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = DVec3::new(rng.random_range(-3.0..3.0), rng.random_range(-2.0..2.0), -3.0);
            let aim = DVec3::new(
                rng.random_range(-1.4..1.4),
                rng.random_range(-0.4..0.4),
                rng.random_range(-1.4..1.4),
            );
            let ray = Ray::new(o, (aim - o).normalize());
            let (a, b) = (
                compiled.intersect(&ray, Interval::POSITIVE),
                generic.intersect(&ray, Interval::POSITIVE),
            );
            match (a, b) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert!((a.t - b.t).abs() <= 2e-7, "{} vs {}", a.t, b.t);
                    let n = compiled.normal_at(&ray, &a);
                    let exact = compiled.gradient(ray.at(a.t)).normalize();
                    assert!((n - exact).length() <= 1e-12, "{n:?} vs {exact:?}");
                }
                (None, None) => {}
                _ => panic!("{ray:?}: {a:?} vs {b:?}"),
            }
        }
        assert!(hits > 500, "{hits} hits");
        for _ in 0..200 {
            let p = DVec3::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-0.5..0.5),
                rng.random_range(-1.5..1.5),
            );
            let exact = ((DVec2::new(p.x, p.z).length() - 1.0).hypot(p.y) - 0.3).abs();
            let bounds = compiled.closest(p).expect("a compiled field bounds its distance");
            assert!(
                bounds.lower <= exact + 1e-12 && exact <= bounds.upper + 1e-12,
                "{p:?}: {exact} not in {bounds:?}"
            );
        }
        assert!(generic.closest(DVec3::ZERO).is_none());
    }
}
