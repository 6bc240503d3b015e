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
//! Soundness: the interval evaluations are as sound as the operations of [`Scalar`] for
//! [`Enclosure`]: every rounded operation is rounded outward, and a branch (`min`, `max`, an
//! `if` on [`Scalar::certain_order`]) that cannot be decided over a segment covers both sides
//! ([`Scalar::either`]). A user's Φ must use only these operations on its arguments (constants
//! through [`Scalar::constant`]) for the guarantee to hold.

use crate::bounds::Aabb;
use crate::expr::{coordinates_along, jets_along, Jet, Scalar};
use crate::hit::RawHit;
use crate::math::enclosure::Enclosure;
use crate::ray::{Interval, Ray};
use crate::root::RootOptions;
use crate::traits::{Implicit, Intersect};
use glam::DVec3;

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
/// its one generic Φ (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct FieldSurface<F> {
    field: F,
}

impl<F: ScalarField> FieldSurface<F> {
    /// The surface of `field`.
    pub fn new(field: F) -> Self {
        Self { field }
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
}

impl<F: ScalarField> Intersect for FieldSurface<F> {
    fn root_options(&self) -> RootOptions {
        self.field.root_options()
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
