//! Timing and error statistics of one intersection method over one ray set.

use crate::dd::Dd;
use glam::DVec3;
use std::hint::black_box;
use std::time::Instant;

/// The reference answer for one ray (double-double; see `reference.rs`).
#[derive(Clone, Copy, Debug)]
pub struct Ref {
    /// First hit in the query range.
    pub t: Option<Dd>,
    /// Unit outward normal at the reference hit.
    pub normal: DVec3,
    /// Relative distance of the ray from a feature boundary (edge, rim, tangency); normals are
    /// compared only where it exceeds [`NORMAL_MARGIN`], since at an edge either face is right.
    pub margin: f64,
}

impl Ref {
    pub const MISS: Ref = Ref {
        t: None,
        normal: DVec3::ZERO,
        margin: f64::INFINITY,
    };
}

/// Hits closer than this (relative) to an edge or rim are left out of the normal statistic.
pub const NORMAL_MARGIN: f64 = 1e-6;

/// What one method did on one ray set.
#[derive(Clone, Debug, Default)]
pub struct Measured {
    /// Median over the passes of the mean time per ray, in nanoseconds.
    pub ns_median: f64,
    /// Fastest and slowest pass.
    pub ns_min: f64,
    pub ns_max: f64,
    pub rays: usize,
    /// Rays the reference hits.
    pub ref_hits: usize,
    /// Largest and median relative `t` error over rays both hit.
    pub max_rel_t: f64,
    pub median_rel_t: f64,
    /// Largest angle between the method's and the reference normal, degrees (away from edges).
    pub max_normal_deg: f64,
    /// Rays where the method hits and the reference misses, or the other way round.
    pub disagreements: usize,
    /// NaN `t` or normal components returned.
    pub nans: usize,
}

/// Times `f` on every ray (`passes` passes, median) and compares its answers with `refs`;
/// `unsigned_normals` compares normals up to sign (open surfaces).
pub fn measure<R, F>(rays: &[R], refs: &[Ref], passes: usize, unsigned_normals: bool, f: F) -> Measured
where
    F: Fn(&R) -> Option<(f64, DVec3)>,
{
    assert_eq!(rays.len(), refs.len());
    // one untimed warm-up pass that also collects the answers
    let answers: Vec<Option<(f64, DVec3)>> = rays.iter().map(&f).collect();
    let mut per_ray = Vec::with_capacity(passes);
    for _ in 0..passes.max(1) {
        let mut sink = 0.0;
        let start = Instant::now();
        for r in rays {
            if let Some((t, n)) = f(black_box(r)) {
                sink += t + n.x;
            }
        }
        let ns = start.elapsed().as_secs_f64() * 1e9 / rays.len().max(1) as f64;
        black_box(sink);
        per_ray.push(ns);
    }
    per_ray.sort_by(f64::total_cmp);
    let mut m = Measured {
        ns_median: per_ray[per_ray.len() / 2],
        ns_min: per_ray[0],
        ns_max: per_ray[per_ray.len() - 1],
        rays: rays.len(),
        ..Measured::default()
    };
    let mut rel = Vec::new();
    for (answer, reference) in answers.iter().zip(refs) {
        if reference.t.is_some() {
            m.ref_hits += 1;
        }
        match (answer, reference.t) {
            (Some((t, n)), Some(t_ref)) => {
                if t.is_nan() || n.is_nan() {
                    m.nans += 1;
                    continue;
                }
                let e = if t_ref.hi == 0.0 {
                    t.abs()
                } else {
                    ((Dd::new(*t) - t_ref) / t_ref).abs().f64()
                };
                rel.push(e);
                if reference.margin > NORMAL_MARGIN {
                    let c = n.normalize_or_zero().dot(reference.normal).clamp(-1.0, 1.0);
                    // the angle from the cross product keeps precision for tiny angles
                    let s = n.normalize_or_zero().cross(reference.normal).length();
                    let mut deg = s.atan2(c).to_degrees();
                    if unsigned_normals {
                        // open surfaces: a normal facing the ray (parry3d's convention) is as right
                        deg = deg.min(180.0 - deg);
                    }
                    m.max_normal_deg = m.max_normal_deg.max(deg);
                }
            }
            (Some((t, n)), None) => {
                if t.is_nan() || n.is_nan() {
                    m.nans += 1;
                } else {
                    m.disagreements += 1;
                }
            }
            (None, Some(_)) => m.disagreements += 1,
            (None, None) => {}
        }
    }
    if !rel.is_empty() {
        rel.sort_by(f64::total_cmp);
        m.max_rel_t = rel[rel.len() - 1];
        m.median_rel_t = rel[rel.len() / 2];
    }
    m
}
