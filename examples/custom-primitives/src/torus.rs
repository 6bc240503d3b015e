//! A torus around the y axis: ring (major) radius `major`, tube (minor) radius `minor`, centred
//! at the origin (place it with an object `transform`).
//!
//! Φ(p) = √((√(x² + z²) − R)² + y²) − r, the signed distance (Lipschitz bound 1).
//!
//! [`Torus`] writes Φ once, generically ([`ScalarField`]): zeroset evaluates it at points, over
//! intervals (guaranteed first roots) and with forward-mode derivatives (exact normals).
//! [`QuarticTorus`] is the same surface in closed form.

use glam::{DVec2, DVec3};
use serde::Deserialize;
use std::sync::Arc;
use zeroset::scene::registry::{BuildContext, SceneShape};
use zeroset_primitives::expr::Scalar;
use zeroset_primitives::{
    Aabb, FieldSurface, Implicit, Intersect, Interval, Primitive, PrimitiveError, RawHit, Ray, ScalarField,
};

fn validate(major: f64, minor: f64, name: &'static str) -> Result<(), PrimitiveError> {
    if !(minor.is_finite() && minor > 0.0) {
        return Err(PrimitiveError::new(
            name,
            "minor",
            format!("must be positive and finite, got {minor}"),
        ));
    }
    if !(major.is_finite() && major > minor) {
        return Err(PrimitiveError::new(
            name,
            "major",
            format!("must be finite and larger than minor ({minor}), got {major}"),
        ));
    }
    Ok(())
}

fn torus_phi(major: f64, minor: f64, p: DVec3) -> f64 {
    DVec2::new(DVec2::new(p.x, p.z).length() - major, p.y).length() - minor
}

fn torus_bounds(major: f64, minor: f64) -> Aabb {
    let e = major + minor;
    Aabb::new(DVec3::new(-e, -minor, -e), DVec3::new(e, minor, e))
}

/// The torus as a user writes it with the least code: Φ once, generic over the number type, and
/// bounds. Everything else — exact normals (forward-mode gradient) and guaranteed first roots
/// (interval isolation) — comes from [`FieldSurface`].
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Torus {
    /// Ring radius R.
    pub major: f64,
    /// Tube radius r (< R).
    pub minor: f64,
}

impl ScalarField for Torus {
    fn phi<T: Scalar>(&self, [x, y, z]: [T; 3]) -> T {
        let ring = (x * x + z * z).sqrt() - T::constant(self.major);
        (ring * ring + y * y).sqrt() - T::constant(self.minor)
    }

    fn bounds(&self) -> Aabb {
        torus_bounds(self.major, self.minor)
    }
}

impl SceneShape for Torus {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        validate(self.major, self.minor, "Torus")?;
        Ok(Arc::new(FieldSurface::new(*self)))
    }
}

/// The same torus with the analytic gradient and the closed-form intersection: the quartic
/// `(|p|² + R² − r²)² = 4R²(x² + z²)` along the ray, solved by [`crate::solve_quartic`] after
/// moving the ray origin to where it enters the bounding sphere (which keeps the coefficients
/// well scaled), each root polished by Newton steps on the quartic.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuarticTorus {
    /// Ring radius R.
    pub major: f64,
    /// Tube radius r (< R).
    pub minor: f64,
}

impl Implicit for QuarticTorus {
    fn phi(&self, p: DVec3) -> f64 {
        torus_phi(self.major, self.minor, p)
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let ring = DVec2::new(p.x, p.z);
        let rho = ring.length();
        // nearest point of the ring circle; on the axis every ring point is nearest
        let centre = if rho > 0.0 {
            ring * (self.major / rho)
        } else {
            DVec2::new(self.major, 0.0)
        };
        (p - DVec3::new(centre.x, 0.0, centre.y)).normalize_or_zero()
    }

    fn bounds(&self) -> Aabb {
        torus_bounds(self.major, self.minor)
    }

    fn lipschitz(&self) -> Option<f64> {
        Some(1.0)
    }
}

impl Intersect for QuarticTorus {
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        let (big_r, r) = (self.major, self.minor);
        // shift the origin to the bounding sphere's entry (never past the range start)
        let bound = big_r + r;
        let a = ray.dir.length_squared();
        let b_half = ray.origin.dot(ray.dir);
        let disc = a * bound * bound - ray.origin.cross(ray.dir).length_squared();
        if !(disc >= 0.0) {
            return None;
        }
        let shift = ((-b_half - disc.sqrt()) / a)
            .max(range.min)
            .max(0.0)
            .min(range.max.max(range.min));
        let o = ray.at(shift);
        let d = ray.dir;
        let k = o.length_squared() + big_r * big_r - r * r;
        let b = 2.0 * o.dot(d);
        let four_r2 = 4.0 * big_r * big_r;
        let coefficients = [
            k * k - four_r2 * (o.x * o.x + o.z * o.z),
            2.0 * b * k - 2.0 * four_r2 * (o.x * d.x + o.z * d.z),
            b * b + 2.0 * a * k - four_r2 * (d.x * d.x + d.z * d.z),
            2.0 * a * b,
            a * a,
        ];
        let mut best: Option<f64> = None;
        for s in solve_quartic_roots(&coefficients) {
            let t = s + shift;
            if range.contains(t) && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        }
        best.map(RawHit::at)
    }

    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        self.gradient(ray.at(raw.t))
    }
}

fn solve_quartic_roots(c: &[f64; 5]) -> Vec<f64> {
    let evaluate = |t: f64| (((c[4] * t + c[3]) * t + c[2]) * t + c[1]) * t + c[0];
    let derivative = |t: f64| ((4.0 * c[4] * t + 3.0 * c[3]) * t + 2.0 * c[2]) * t + c[1];
    let mut roots = crate::solve_quartic(c[3] / c[4], c[2] / c[4], c[1] / c[4], c[0] / c[4]);
    for t in &mut roots {
        for _ in 0..3 {
            let slope = derivative(*t);
            if slope == 0.0 {
                break;
            }
            let next = *t - evaluate(*t) / slope;
            if !next.is_finite() || (next - *t).abs() > 1e-3 * (1.0 + t.abs()) {
                break;
            }
            *t = next;
        }
    }
    roots
}

impl SceneShape for QuarticTorus {
    fn build(&self, _: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        validate(self.major, self.minor, "QuarticTorus")?;
        Ok(Arc::new(*self))
    }
}
