//! How a line of `zeroset query` input becomes a ray: its parameter range and, for rays that
//! start on a surface, a spawned origin.
//!
//! **Columns.** `ox,oy,oz,dx,dy,dz`, optionally `,tmin,tmax`, optionally followed by the surface
//! normal at the origin `,nx,ny,nz` (6, 8, 9 or 11 numbers).
//!
//! **Range.** By default the range is open at its start, `tmin < t ≤ tmax` (`tmin = 0`,
//! `tmax = +∞` when not given): the first hit with `t > 0`, the classic definition, so an origin
//! lying exactly on a face, cap or plane does not report that surface at `t = 0`. With
//! [`RangeConvention::Closed`] (`--closed-range`) it is `tmin ≤ t ≤ tmax`.
//!
//! **Spawned origins.** With a [`PointPrecision`] (`--origin-precision f32|f64|E`) every line must
//! carry the normal, and the origin is replaced by
//! `zeroset_primitives::offset::spawn_origin(origin, normal, dir, precision, magnitude)`, with
//! `magnitude` the largest coordinate magnitude of the scene's bounded objects: a ray cast from a
//! stored (e.g. float32) hit point cannot re-hit the surface it starts on through rounding, and
//! loses no hit farther than `spawn_distance` from the point (see `docs/numerics.md`).

use crate::scene::Scene;
use glam::DVec3;
use zeroset_primitives::offset::{spawn_origin, PointPrecision};
use zeroset_primitives::{Interval, Ray};

/// Whether the query range includes its start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RangeConvention {
    /// `tmin < t ≤ tmax` (the default).
    #[default]
    OpenStart,
    /// `tmin ≤ t ≤ tmax`.
    Closed,
}

impl RangeConvention {
    /// `Closed` when `closed`, else the default `OpenStart` (the `--closed-range` flag).
    #[must_use]
    pub fn closed_if(closed: bool) -> Self {
        if closed {
            Self::Closed
        } else {
            Self::OpenStart
        }
    }
}

/// How input lines become rays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RaySetup {
    /// The range convention.
    pub range: RangeConvention,
    /// The precision of the origins, when they are points on surfaces to spawn from.
    pub origin_precision: Option<PointPrecision>,
    /// Largest coordinate magnitude the scene's closed forms compute with (for spawning).
    pub magnitude: f64,
}

/// The largest coordinate magnitude over the scene's bounded objects (`offset::magnitude` of
/// their world bounds; unbounded ones, planes, contribute 0).
#[must_use]
pub fn scene_magnitude(scene: &Scene) -> f64 {
    scene
        .objects
        .iter()
        .map(|o| zeroset_primitives::offset::magnitude(&o.primitive.bounds()))
        .fold(0.0, f64::max)
}

/// A ray with its accepted `t` range, from one line's numbers (see the module docs); the error
/// says what is wrong with the line.
pub fn ray_from_fields(v: &[f64], setup: &RaySetup) -> Result<(Ray, Interval), String> {
    if ![6, 8, 9, 11].contains(&v.len()) {
        return Err(format!(
            "expected 6, 8, 9 or 11 fields `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]`, got {}",
            v.len()
        ));
    }
    let origin = DVec3::new(v[0], v[1], v[2]);
    let dir = DVec3::new(v[3], v[4], v[5]);
    let (tmin, tmax) = if v.len() == 8 || v.len() == 11 {
        (v[6], v[7])
    } else {
        (0.0, f64::INFINITY)
    };
    let normal = (v.len() == 9 || v.len() == 11).then(|| DVec3::new(v[v.len() - 3], v[v.len() - 2], v[v.len() - 1]));
    if !origin.is_finite() || !dir.is_finite() {
        return Err("origin and direction must be finite".into());
    }
    if dir == DVec3::ZERO {
        return Err("direction must be non-zero".into());
    }
    if tmin.is_nan() || tmax.is_nan() || tmin > tmax {
        return Err(format!("invalid t range [{tmin}, {tmax}]"));
    }
    let origin = match (setup.origin_precision, normal) {
        (None, None) => origin,
        (None, Some(_)) => {
            return Err("normal columns nx,ny,nz are only used with --origin-precision f32|f64|E".into());
        }
        (Some(_), None) => {
            return Err("--origin-precision needs the surface normal: add columns nx,ny,nz".into());
        }
        (Some(precision), Some(n)) => {
            if !n.is_finite() || n == DVec3::ZERO {
                return Err(format!("normal must be finite and non-zero, got {n}"));
            }
            spawn_origin(origin, n, dir, precision, setup.magnitude)
        }
    };
    let min = match setup.range {
        RangeConvention::OpenStart => tmin.next_up(),
        RangeConvention::Closed => tmin,
    };
    Ok((Ray::new(origin, dir), Interval::new(min, tmax)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_range_excludes_the_start_and_closed_keeps_it() {
        let (_, open) = ray_from_fields(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], &RaySetup::default()).unwrap();
        assert!(!open.contains(0.0) && open.contains(f64::from_bits(1)) && open.contains(1e300));
        let closed = RaySetup {
            range: RangeConvention::Closed,
            ..RaySetup::default()
        };
        let (_, r) = ray_from_fields(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 3.0], &closed).unwrap();
        assert!(r.contains(2.0) && r.contains(3.0) && !r.contains(3.0f64.next_up()));
    }

    #[test]
    fn spawned_origin_needs_normals_and_moves_along_them() {
        let f32_setup = RaySetup {
            origin_precision: Some(PointPrecision::F32),
            ..RaySetup::default()
        };
        assert!(ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], &f32_setup)
            .unwrap_err()
            .contains("needs the surface normal"));
        assert!(
            ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0], &RaySetup::default())
                .unwrap_err()
                .contains("only used with --origin-precision")
        );
        let (ray, _) = ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 1.0, -0.5, 0.0, 0.0, 1.0], &f32_setup).unwrap();
        // leaving downwards (d·n < 0): moved below z = 1 by the spawn distance
        assert!(
            ray.origin.z < 1.0 - 2.0 * 2f64.powi(-24) && ray.origin.z > 1.0 - 1e-6,
            "{}",
            ray.origin
        );
        assert!(ray_from_fields(&[0.0; 7], &RaySetup::default()).is_err());
    }
}
