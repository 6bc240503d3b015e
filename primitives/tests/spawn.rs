//! Spawning rays from points known only to float32 (`zeroset_primitives::offset::spawn_origin`).
//!
//! For every built-in primitive, placed at scales `10⁻³ … 10⁵`: primary rays find a hit; its
//! point and normal are **rounded to float32** (as a user reading an EXR or float32 CSV has them);
//! a new ray is spawned from them with `PointPrecision::F32`, and
//! - a ray leaving to the arrival side (cos to the normal log-uniform in `[10⁻⁶, 1]`: grazing
//!   included) must not hit the surface again unless Φ confirms a real crossing beyond the hit
//!   (a chord through a concave side or another part): **0 self-hits**;
//! - a ray crossing the surface (transmission, cos log-uniform in `[−1, −10⁻⁶]`) starts on the far
//!   side and must not hit it again either (same Φ check);
//! - a plane parallel to the tangent plane at a height `h ∈ [1.5·D, 10³·D]` on the leaving side,
//!   `D` the documented spawn distance, must be hit by the leaving ray at `t ≤ h/cos` (up to
//!   rounding): **0 hits lost beyond the offset**.
//!
//! The reference is Φ itself (the implicit definition, evaluated independently of the
//! intersectors), as in the `recast_*` test of `hard_cases.rs`.

mod support;
use glam::{DAffine3, DQuat, DVec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use zeroset_primitives::offset::{magnitude, spawn_distance, spawn_origin, PointPrecision};
use zeroset_primitives::testing::random_unit;
use zeroset_primitives::*;

fn to_f32(v: DVec3) -> DVec3 {
    DVec3::new(f64::from(v.x as f32), f64::from(v.y as f32), f64::from(v.z as f32))
}

fn log_uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo.ln()..hi.ln()).exp()
}

/// Whether Φ shows the ray `origin + s·dir` strictly on the side opposite to `arrival` at some
/// `s` near `hi` (just beyond it with `after`, or before it), inside the surface's region.
fn crosses(prim: &dyn Primitive, origin: DVec3, dir: DVec3, arrival: f64, hi: f64, after: bool) -> bool {
    (0..=40).any(|k| {
        let step = 0.5f64.powi(k);
        let s = if after { hi * (1.0 + step) } else { hi * step };
        let q = origin + s * dir;
        prim.phi(q) * arrival < 0.0 && prim.within_boundary(q)
    })
}

#[derive(Default, Debug)]
struct Counts {
    leaving: usize,
    self_hits: usize,
    genuine: usize,
    /// Leaving rays checked against a plane beyond the offset.
    entering: usize,
    missed: usize,
}

fn spawn_rays(prim: &dyn Primitive, rng: &mut StdRng, rays: usize, shrink: f64) -> Counts {
    let bounds = prim.bounds();
    let bounds = if bounds.is_finite() {
        bounds
    } else {
        Aabb::new(DVec3::splat(-2.0), DVec3::splat(2.0))
    };
    let m = magnitude(&prim.bounds());
    let mut c = Counts::default();
    let mut attempts = 0;
    while c.leaving < rays && attempts < 20 * rays {
        attempts += 1;
        let target = bounds.center()
            + bounds.extent()
                * 0.5
                * shrink
                * DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
        let eye = target + random_unit(rng) * bounds.diagonal_length() * rng.random_range(0.6..3.0);
        let ray = Ray::new(eye, (target - eye).normalize());
        let Some(raw) = prim.intersect(&ray, Interval::POSITIVE) else {
            continue;
        };
        let hit = SurfaceHit::complete(prim, &ray, &raw, HitRequest::ALL);
        let Some(normal) = hit.normal else { continue };
        if normal == DVec3::ZERO {
            continue;
        }
        // what a user has: float32 point and normal
        let (p, n32) = (to_f32(hit.point), to_f32(normal));
        let facing = if n32.dot(ray.dir) > 0.0 { -n32 } else { n32 }.normalize();
        let arrival = if facing.dot(normal) > 0.0 { 1.0 } else { -1.0 };
        let tangent = random_unit(rng)
            .cross(facing)
            .normalize_or(facing.any_orthonormal_vector());
        let d_spawn = spawn_distance(p, PointPrecision::F32, m);

        // leaving, grazing included
        let cos = log_uniform(rng, 1e-6, 1.0);
        let dir = (facing * cos + tangent * (1.0 - cos * cos).sqrt()).normalize();
        let origin = spawn_origin(p, n32, dir, PointPrecision::F32, m);
        c.leaving += 1;
        if let Some(h) = prim.intersect(&Ray::new(origin, dir), Interval::POSITIVE) {
            if crosses(prim, origin, dir, arrival, h.t, true) {
                c.genuine += 1;
            } else {
                c.self_hits += 1;
                if std::env::var_os("ZS_DEBUG").is_some() {
                    eprintln!("SELF {prim:?} p {p} n {n32} dir {dir} t {:e} D {d_spawn:e}", h.t);
                }
            }
        }

        // no hit beyond the offset is lost: a plane parallel to the tangent plane at a height
        // h ∈ [1.5·D, 10³·D] on the leaving side is hit, at t ≤ (h + ulps)/cos
        let h = d_spawn * log_uniform(rng, 1.5, 1e3);
        let wall_point = p + h * facing;
        let wall = Plane::new(facing, facing.dot(wall_point)).unwrap();
        c.entering += 1;
        match wall.intersect(&Ray::new(origin, dir), Interval::new(0f64.next_up(), f64::INFINITY)) {
            Some(w) if w.t <= (h + 4.0 * f64::EPSILON * p.abs().max_element()) / cos * (1.0 + 1e-9) => {}
            other => {
                c.missed += 1;
                if std::env::var_os("ZS_DEBUG").is_some() {
                    eprintln!("LOST {prim:?} p {p} dir {dir} h {h:e} got {other:?}");
                }
            }
        }

        // crossing rays (transmission) start on the far side and do not re-hit either
        let cos_in = -log_uniform(rng, 1e-6, 1.0);
        let dir_in = (facing * cos_in + tangent * (1.0 - cos_in * cos_in).sqrt()).normalize();
        let origin_in = spawn_origin(p, n32, dir_in, PointPrecision::F32, m);
        c.leaving += 1;
        if let Some(h) = prim.intersect(&Ray::new(origin_in, dir_in), Interval::POSITIVE) {
            if crosses(prim, origin_in, dir_in, -arrival, h.t, true) {
                c.genuine += 1;
            } else {
                c.self_hits += 1;
                if std::env::var_os("ZS_DEBUG").is_some() {
                    eprintln!("SELF-IN {prim:?} p {p} n {n32} dir {dir_in} t {:e} D {d_spawn:e}", h.t);
                }
            }
        }
    }
    assert!(c.leaving >= rays, "{prim:?}: too few primary hits ({c:?})");
    c
}

#[test]
fn spawned_from_f32_points_never_self_hit_and_never_miss_beyond_the_offset() {
    let mut rng = StdRng::seed_from_u64(131);
    let quat = DQuat::from_axis_angle(DVec3::new(-0.4, 0.2, 1.0).normalize(), 1.1);
    let mut total = Counts::default();
    for (name, prim, shrink) in support::one_of_each_builtin() {
        for scale in [1e-3, 1.0, 1e3, 1e5] {
            // placed at a distance proportional to its size (f32 resolves a shape only relative
            // to its own coordinates)
            let m = DAffine3::from_scale_rotation_translation(
                DVec3::splat(scale),
                quat,
                DVec3::new(3.0, -2.0, 1.5) * scale,
            );
            let placed: Arc<dyn Primitive> = Arc::new(Transformed::new(prim.clone(), m).unwrap());
            let c = spawn_rays(&*placed, &mut rng, 6_000, shrink);
            println!(
                "[spawn] {name:<9} scale {scale:>6e}: spawned {:>5} self-hits {} (genuine re-hits {}) | planes beyond D {:>5} lost {}",
                c.leaving, c.self_hits, c.genuine, c.entering, c.missed
            );
            total.leaving += c.leaving;
            total.self_hits += c.self_hits;
            total.entering += c.entering;
            total.missed += c.missed;
        }
    }
    println!(
        "[spawn] total spawned {} self-hits {} | planes beyond D {} lost {}",
        total.leaving, total.self_hits, total.entering, total.missed
    );
    assert_eq!((total.self_hits, total.missed), (0, 0));
}

/// Without spawning (the point used as the origin, as `zeroset query` did), the same f32 points
/// re-hit their surface: the failure the spawning API removes, measured on the same rays.
#[test]
fn unspawned_f32_origins_do_self_hit() {
    let mut rng = StdRng::seed_from_u64(7);
    let sphere = Sphere::new(DVec3::new(1.0, 2.0, 3.0), 1.5).unwrap();
    let mut self_hits = 0;
    for _ in 0..2000 {
        let target = DVec3::new(1.0, 2.0, 3.0) + random_unit(&mut rng) * 1.5;
        let eye = target + (target - DVec3::new(1.0, 2.0, 3.0)).normalize() * 4.0;
        let ray = Ray::new(eye, (target - eye).normalize());
        let Some(raw) = sphere.intersect(&ray, Interval::POSITIVE) else {
            continue;
        };
        let hit = SurfaceHit::complete(&sphere, &ray, &raw, HitRequest::ALL);
        let n = hit.normal.unwrap();
        let dir = (n + 0.3 * n.any_orthonormal_vector()).normalize();
        let p = to_f32(hit.point);
        if sphere.phi(p) < 0.0
            && sphere
                .intersect(&Ray::new(p, dir), Interval::new(f64::MIN_POSITIVE, f64::INFINITY))
                .is_some()
        {
            self_hits += 1;
        }
    }
    println!("[spawn] unspawned f32 origins on a sphere: {self_hits} self-hits of 2000");
    assert!(self_hits > 100, "{self_hits}");
}

/// Origins exactly on faces, caps and planes: with the open range (`t > 0`, what `zeroset
/// query` uses by default) no hit at `t = 0` is reported.
#[test]
fn origins_exactly_on_faces_report_no_hit_at_zero() {
    let mut rng = StdRng::seed_from_u64(3);
    let open = Interval::new(0f64.next_up(), f64::INFINITY);
    let cuboid = Cuboid::new(DVec3::new(-1.0, -0.5, 0.25), DVec3::new(0.75, 1.5, 2.0)).unwrap();
    let cylinder = Cylinder::new(DVec3::ZERO, DVec3::Y, 0.75, 2.0, true).unwrap();
    let plane = Plane::new(DVec3::Y, 0.5).unwrap();
    let disk = Disk::new(DVec3::new(0.0, 1.0, 0.0), DVec3::Y, 1.0).unwrap();
    let mut checked = 0;
    let mut zero_hits = 0;
    let mut closed_zero_hits = 0;
    for _ in 0..20_000 {
        let (u, v): (f64, f64) = (rng.random_range(-0.7..0.7), rng.random_range(-0.7..0.7));
        let dir = random_unit(&mut rng);
        let cases: [(&dyn Primitive, DVec3); 6] = [
            (&cuboid, DVec3::new(-1.0, u, 1.0 + v)),        // face x = −1
            (&cuboid, DVec3::new(u, 1.5, 1.0 + v)),         // face y = 1.5
            (&cylinder, DVec3::new(u, 2.0, v)),             // top cap
            (&cylinder, DVec3::new(u * 0.9, 0.0, v * 0.9)), // bottom cap
            (&plane, DVec3::new(u * 100.0, 0.5, v)),        // the plane
            (&disk, DVec3::new(u, 1.0, v)),                 // the disk
        ];
        for (prim, origin) in cases {
            if !prim.within_boundary(origin) {
                continue;
            }
            checked += 1;
            let ray = Ray::new(origin, dir);
            if let Some(h) = prim.intersect(&ray, open) {
                if h.t <= 0.0 {
                    zero_hits += 1;
                }
            }
            // the closed range [0, ∞] reports the contact at t = 0 (what the open range removes)
            if prim.intersect(&ray, Interval::POSITIVE).is_some_and(|h| h.t == 0.0) {
                closed_zero_hits += 1;
            }
        }
    }
    println!(
        "[spawn] origins on faces/caps/planes: {checked} rays, {zero_hits} hits at t ≤ 0 in the open range \
         ({closed_zero_hits} at t = 0 in the closed range)"
    );
    assert!(checked > 50_000);
    assert!(closed_zero_hits > checked / 4, "{closed_zero_hits}");
    assert_eq!(zero_hits, 0);
}
