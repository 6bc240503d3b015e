//! Batch first-hit queries: `zeroset query SCENE --rays RAYS.csv -o HITS.csv`.
//!
//! Input: one ray per line, `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]` (default `tmin = 0`,
//! `tmax = +∞`; the range is open at `tmin` unless `--closed-range`, and the normal columns spawn
//! the origin off a surface with `--origin-precision`: see [`crate::query_rays`]); blank lines and
//! lines starting with `#` are skipped, and so is a first line that is not numeric (a header).
//! The direction is used as given: `t` is in units of `|d|`, so normalise directions to get
//! distances.
//!
//! Output: a header line, then one line per input ray, in input order:
//! `hit,t,px,py,pz,nx,ny,nz,id,name,u,v` — `hit` is 1 or 0; on a miss every other field is
//! empty. The normal is the outward unit ∇Φ (not flipped); `id` is the object index, `name` its
//! name from the scene (empty if unnamed); `u,v` are empty where the primitive has none.

use crate::query_rays::{ray_from_fields, RaySetup};
use crate::scene::Scene;
use rayon::prelude::*;
use std::fmt::Write as _;
use zeroset_primitives::{HitRequest, Interval, Ray, SurfaceHit};

/// One query ray with its parameter range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryRay {
    /// The ray.
    pub ray: Ray,
    /// Accepted `t`.
    pub range: Interval,
}

/// A malformed line of the ray file.
#[derive(Debug, thiserror::Error)]
#[error("{path}:{line}: {message}")]
pub struct QueryError {
    /// The ray file.
    pub path: String,
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// Parses the CSV ray list with the default [`RaySetup`] (see the module docs).
pub fn parse_rays(text: &str, path: &str) -> Result<Vec<QueryRay>, QueryError> {
    parse_rays_with(text, path, &RaySetup::default())
}

/// Parses the CSV ray list, building each ray as `setup` says ([`crate::query_rays`]).
pub fn parse_rays_with(text: &str, path: &str, setup: &RaySetup) -> Result<Vec<QueryRay>, QueryError> {
    let mut rays = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
        let numbers: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        let err = |message: String| QueryError {
            path: path.to_string(),
            line: line_no,
            message,
        };
        let Ok(v) = numbers else {
            if rays.is_empty() && index == 0 {
                continue; // header
            }
            return Err(err(format!(
                "expected numbers `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]`, got `{trimmed}`"
            )));
        };
        let (ray, range) = ray_from_fields(&v, setup).map_err(err)?;
        rays.push(QueryRay { ray, range });
    }
    Ok(rays)
}

/// First hits of `rays` in `scene` (in input order), with normal and uv.
#[must_use]
pub fn first_hits(scene: &Scene, rays: &[QueryRay]) -> Vec<Option<(u32, SurfaceHit)>> {
    rays.par_iter()
        .map(|q| {
            scene.intersect(&q.ray, q.range).map(|(object, raw)| {
                (
                    object,
                    SurfaceHit::complete(
                        &*scene.objects[object as usize].primitive,
                        &q.ray,
                        &raw,
                        HitRequest::ALL,
                    ),
                )
            })
        })
        .collect()
}

/// Formats hits as the output CSV (see the module docs).
#[must_use]
pub fn format_hits(scene: &Scene, hits: &[Option<(u32, SurfaceHit)>]) -> String {
    let mut out = String::from("hit,t,px,py,pz,nx,ny,nz,id,name,u,v\n");
    for hit in hits {
        match hit {
            None => out.push_str("0,,,,,,,,,,,\n"),
            Some((object, h)) => {
                let n = h.normal.unwrap_or_default();
                let name = scene.objects[*object as usize]
                    .name
                    .as_deref()
                    .unwrap_or("")
                    .replace([',', '\n'], " ");
                let uv = h.uv.map_or(",".to_string(), |uv| format!("{:e},{:e}", uv.x, uv.y));
                let _ = writeln!(
                    out,
                    "1,{:e},{:e},{:e},{:e},{:e},{:e},{:e},{object},{name},{uv}",
                    h.t, h.point.x, h.point.y, h.point.z, n.x, n.y, n.z
                );
            }
        }
    }
    out
}
