//! Per-primitive rays, references and every intersection method: zeroset's robust closed form
//! (the default), the generic root finder at tolerances 10⁻¹…10⁻⁷, the textbook closed form in
//! f64 and f32, f32 ports of the robust forms, and parry3d in f32 and f64.

use crate::baselines::{self as bl, RayR, V};
use crate::measure::{measure, Measured, Ref};
use crate::reference::{reference, Shape};
use glam::DVec3;
use rayon::prelude::*;
use zeroset_primitives::{
    first_root, Cone, Cuboid, Cylinder, Disk, Ellipsoid, Intersect, Interval, Plane, Polygon, Ray, RootOptions, Sphere,
    Triangle,
};

/// Every query asks for the first hit in `[0, T_MAX]` (finite, so the root finder can march
/// unbounded surfaces too).
pub const T_MAX: f64 = 1e4;

/// The generic root finder's tolerances.
pub const TOLERANCES: [f64; 7] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7];

/// One line of the results table.
#[derive(Clone, Debug)]
pub struct Row {
    pub primitive: &'static str,
    pub method: String,
    /// `robust`, `generic`, `textbook`, `robust-port` or `parry3d`.
    pub family: &'static str,
    pub precision: &'static str,
    /// zeroset's default for this primitive.
    pub default: bool,
    pub m: Measured,
}

/// SplitMix64: small, seeded, reproducible.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    pub fn f(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }
    /// Log-uniform in `[a, b]`.
    pub fn log(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.f()).exp()
    }
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
    /// A random unit vector perpendicular to `n`.
    pub fn perpendicular(&mut self, n: DVec3) -> DVec3 {
        let n = n.normalize();
        loop {
            let v = self.unit();
            let p = v - n * v.dot(n);
            if p.length() > 0.1 {
                return p.normalize();
            }
        }
    }
}

/// `v` rounded to f32 and widened: every method, f32 or f64, then sees exactly the same ray.
pub fn f32_exact(v: DVec3) -> DVec3 {
    DVec3::new(f64::from(v.x as f32), f64::from(v.y as f32), f64::from(v.z as f32))
}

fn ray_between(origin: DVec3, target: DVec3) -> Ray {
    let o = f32_exact(origin);
    Ray::new(o, f32_exact((target - o).normalize()))
}

/// Where hard rays aim and what kind they are.
enum Hard {
    /// A tangent ray at surface point `p` with normal `n`, tilted by ±δ towards the normal.
    Grazing(DVec3, DVec3),
    /// A ray through a point on an edge, rim or vertex, moved by a tiny random offset.
    Feature(DVec3),
}

/// The ray set of one primitive: `random` share through the bounds (hits and misses), the rest
/// hard rays. Origins lie outside the shape (on a sphere of 3× the bounds' radius, or on the
/// front side of a plane).
fn make_rays(
    rng: &mut Rng,
    n: usize,
    centre: DVec3,
    radius: f64,
    plane_normal: Option<DVec3>,
    mut hard: impl FnMut(&mut Rng) -> Hard,
) -> Vec<Ray> {
    let origin_for = |rng: &mut Rng, towards: Option<DVec3>| -> DVec3 {
        let mut u = rng.unit();
        if let Some(pn) = plane_normal {
            if u.dot(pn) < 0.0 {
                u -= 2.0 * u.dot(pn) * pn;
            }
            // keep clear of the plane itself
            u = (u + 0.2 * pn).normalize();
        }
        let _ = towards;
        centre + 3.0 * radius * u
    };
    let mut rays = Vec::with_capacity(n);
    for i in 0..n {
        if i % 10 < 7 {
            let o = origin_for(rng, None);
            let target =
                centre + 1.2 * radius * DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            rays.push(ray_between(o, target));
        } else {
            match hard(rng) {
                Hard::Grazing(p, normal) => {
                    let tangent = rng.perpendicular(normal);
                    let delta = rng.log(1e-10, 1e-7) * rng.sign();
                    let dir = (tangent + delta * normal.normalize()).normalize();
                    let o = p - 3.0 * radius * dir;
                    let ray = Ray::new(f32_exact(o), f32_exact(dir));
                    if plane_normal.is_some_and(|pn| ray.origin.dot(pn) < p.dot(pn)) {
                        rays.push(Ray::new(f32_exact(p + 3.0 * radius * dir), f32_exact(-dir)));
                    } else {
                        rays.push(ray);
                    }
                }
                Hard::Feature(q) => {
                    let target = q + rng.log(1e-10, 1e-6) * radius * rng.unit();
                    let o = origin_for(rng, Some(target));
                    rays.push(ray_between(o, target));
                }
            }
        }
    }
    rays
}

/// Runs one method and pushes its row.
struct Bench {
    primitive: &'static str,
    rays: Vec<Ray>,
    refs: Vec<Ref>,
    passes: usize,
    rows: Vec<Row>,
    progress: bool,
    /// Open surfaces: normals compared up to sign.
    unsigned_normals: bool,
}

impl Bench {
    fn run<R, F>(
        &mut self,
        rays: &[R],
        method: &str,
        family: &'static str,
        precision: &'static str,
        default: bool,
        f: F,
    ) where
        F: Fn(&R) -> Option<(f64, DVec3)>,
    {
        let m = measure(rays, &self.refs, self.passes, self.unsigned_normals, f);
        if self.progress {
            eprintln!(
                "  {:<10} {:<28} {:>9.1} ns/ray  max rel t {:.2e}  disagree {}",
                self.primitive, method, m.ns_median, m.max_rel_t, m.disagreements
            );
        }
        self.rows.push(Row {
            primitive: self.primitive,
            method: method.to_owned(),
            family,
            precision,
            default,
            m,
        });
    }

    /// zeroset's robust closed form (the default) and the generic root finder on `prim`.
    fn zeroset<P: Intersect>(&mut self, prim: &P, generic_cap: u32) {
        let range = Interval::new(0.0, T_MAX);
        let rays = std::mem::take(&mut self.rays);
        let rays = &rays[..];
        self.run(rays, "zeroset robust closed form", "robust", "f64", true, |r: &Ray| {
            prim.intersect(r, range).map(|h| (h.t, prim.normal_at(r, &h)))
        });
        for tol in TOLERANCES {
            let options = RootOptions {
                tolerance: tol,
                max_evaluations: generic_cap,
                ..RootOptions::default()
            };
            self.run(
                rays,
                &format!("zeroset generic tol {tol:.0e}"),
                "generic",
                "f64",
                false,
                |r: &Ray| {
                    first_root(prim, r, range, &options)
                        .hit
                        .map(|h| (h.t, prim.gradient(r.at(h.t)).normalize_or_zero()))
                },
            );
        }
        self.rays = rays.to_vec();
    }

    fn textbook<R32, R64>(&mut self, f32_fn: R32, f64_fn: R64)
    where
        R32: Fn(&RayR<f32>) -> bl::Answer,
        R64: Fn(&RayR<f64>) -> bl::Answer,
    {
        let r64: Vec<RayR<f64>> = self.rays.iter().map(RayR::of).collect();
        let r32: Vec<RayR<f32>> = self.rays.iter().map(RayR::of).collect();
        self.run(&r64, "textbook f64", "textbook", "f64", false, f64_fn);
        self.run(&r32, "textbook f32", "textbook", "f32", false, f32_fn);
    }

    fn robust_port_f32<R32: Fn(&RayR<f32>) -> bl::Answer>(&mut self, f: R32) {
        let r32: Vec<RayR<f32>> = self.rays.iter().map(RayR::of).collect();
        self.run(&r32, "robust port f32", "robust-port", "f32", false, f);
    }

    /// parry3d (f32) and parry3d-f64 on the same rays; the shape is placed by a translation.
    fn parry<S32, S64>(&mut self, s32: &S32, s64: &S64, translation: DVec3)
    where
        S32: parry3d::query::RayCast,
        S64: parry3d_f64::query::RayCast,
    {
        let t = translation;
        let pose32 =
            parry3d::math::Pose::from_translation(parry3d::math::Vector::new(t.x as f32, t.y as f32, t.z as f32));
        let pose64 = parry3d_f64::math::Pose::from_translation(parry3d_f64::math::Vector::new(t.x, t.y, t.z));
        let r32: Vec<parry3d::query::Ray> = self
            .rays
            .iter()
            .map(|r| {
                let (o, d) = (r.origin.as_vec3(), r.dir.as_vec3());
                parry3d::query::Ray::new(
                    parry3d::math::Vector::new(o.x, o.y, o.z),
                    parry3d::math::Vector::new(d.x, d.y, d.z),
                )
            })
            .collect();
        let r64: Vec<parry3d_f64::query::Ray> = self
            .rays
            .iter()
            .map(|r| {
                parry3d_f64::query::Ray::new(
                    parry3d_f64::math::Vector::new(r.origin.x, r.origin.y, r.origin.z),
                    parry3d_f64::math::Vector::new(r.dir.x, r.dir.y, r.dir.z),
                )
            })
            .collect();
        self.run(
            &r32,
            "parry3d f32",
            "parry3d",
            "f32",
            false,
            |r: &parry3d::query::Ray| {
                s32.cast_ray_and_get_normal(&pose32, r, T_MAX as f32, true).map(|h| {
                    (
                        f64::from(h.time_of_impact),
                        DVec3::new(f64::from(h.normal.x), f64::from(h.normal.y), f64::from(h.normal.z)),
                    )
                })
            },
        );
        self.run(
            &r64,
            "parry3d f64",
            "parry3d",
            "f64",
            false,
            |r: &parry3d_f64::query::Ray| {
                s64.cast_ray_and_get_normal(&pose64, r, T_MAX, true)
                    .map(|h| (h.time_of_impact, DVec3::new(h.normal.x, h.normal.y, h.normal.z)))
            },
        );
    }
}

fn references(shape: &Shape, rays: &[Ray]) -> Vec<Ref> {
    rays.par_iter().map(|r| reference(shape, r, T_MAX)).collect()
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct CaseOptions {
    pub rays: usize,
    pub passes: usize,
    pub seed: u64,
    /// Φ evaluations the generic finder may spend on one ray (planar primitives meet it on
    /// rays nearly parallel to their plane).
    pub generic_cap: u32,
    pub only: Option<Vec<String>>,
    pub progress: bool,
}

/// Runs every primitive; returns the rows in table order.
pub fn run_all(opt: &CaseOptions) -> Vec<Row> {
    let mut rows = Vec::new();
    let wanted = |name: &str| {
        opt.only
            .as_ref()
            .is_none_or(|o| o.iter().any(|w| w.eq_ignore_ascii_case(name)))
    };
    let v32 = |v: DVec3| V::<f32>::of(v);
    let v64 = |v: DVec3| V::<f64>::of(v);
    let new_bench = |primitive: &'static str, (rays, refs): (Vec<Ray>, Vec<Ref>)| Bench {
        primitive,
        rays,
        refs,
        passes: opt.passes,
        rows: Vec::new(),
        progress: opt.progress,
        unsigned_normals: matches!(primitive, "Plane" | "Triangle" | "Disk" | "Polygon"),
    };
    let with_refs = |rays: Vec<Ray>, shape: &Shape| -> (Vec<Ray>, Vec<Ref>) {
        let refs = references(shape, &rays);
        (rays, refs)
    };
    let t32 = T_MAX as f32;

    // ── Sphere ──
    if wanted("Sphere") {
        let (c, r) = (DVec3::new(0.25, -0.5, 0.125), 1.25);
        let shape = Shape::Sphere { c, r };
        let mut rng = Rng::new(opt.seed ^ 1);
        let rays = make_rays(&mut rng, opt.rays, c, r, None, |g| {
            let u = g.unit();
            Hard::Grazing(c + r * u, u)
        });
        let mut b = new_bench("Sphere", with_refs(rays, &shape));
        b.zeroset(&Sphere::new(c, r).unwrap(), opt.generic_cap);
        let (c32, c64) = (v32(c), v64(c));
        b.textbook(
            |ray| bl::sphere_textbook(c32, r as f32, ray, t32),
            |ray| bl::sphere_textbook(c64, r, ray, T_MAX),
        );
        b.robust_port_f32(|ray| bl::sphere_robust(c32, r as f32, ray, t32));
        b.parry(
            &parry3d::shape::Ball::new(r as f32),
            &parry3d_f64::shape::Ball::new(r),
            c,
        );
        rows.extend(b.rows);
    }

    // ── Plane ──
    if wanted("Plane") {
        let (n_in, offset) = (DVec3::new(1.0, 2.0, 2.0), 0.75);
        let shape = Shape::Plane { n: n_in, offset };
        let nh = n_in.normalize();
        let p0 = nh * (offset / n_in.length());
        let mut rng = Rng::new(opt.seed ^ 2);
        let rays = make_rays(&mut rng, opt.rays, p0, 2.0, Some(nh), |g| {
            let q = p0 + 2.0 * g.range(0.0, 1.0) * g.perpendicular(nh);
            Hard::Grazing(q, nh)
        });
        let mut b = new_bench("Plane", with_refs(rays, &shape));
        b.zeroset(&Plane::new(n_in, offset).unwrap(), opt.generic_cap);
        let (n32, n64) = (v32(nh), v64(nh));
        let (o32, o64) = ((offset / n_in.length()) as f32, offset / n_in.length());
        b.textbook(
            |ray| bl::plane_textbook(n32, o32, ray, t32),
            |ray| bl::plane_textbook(n64, o64, ray, T_MAX),
        );
        let n32p = parry3d::math::Vector::new(nh.x as f32, nh.y as f32, nh.z as f32);
        let n64p = parry3d_f64::math::Vector::new(nh.x, nh.y, nh.z);
        b.parry(
            &parry3d::shape::HalfSpace::new(n32p),
            &parry3d_f64::shape::HalfSpace::new(n64p),
            p0,
        );
        rows.extend(b.rows);
    }

    // ── Triangle ──
    if wanted("Triangle") {
        let v = [
            DVec3::new(-1.0, -0.5, 0.25),
            DVec3::new(1.25, -0.75, 0.5),
            DVec3::new(0.125, 1.0, -0.5),
        ];
        let shape = Shape::Triangle(v);
        let centre = (v[0] + v[1] + v[2]) / 3.0;
        let mut rng = Rng::new(opt.seed ^ 3);
        let rays = make_rays(&mut rng, opt.rays, centre, 1.5, None, |g| {
            let i = (g.next_u64() % 3) as usize;
            let s = if g.f() < 0.2 { 0.0 } else { g.f() };
            Hard::Feature(v[i] + s * (v[(i + 1) % 3] - v[i]))
        });
        let mut b = new_bench("Triangle", with_refs(rays, &shape));
        b.zeroset(&Triangle::new(v[0], v[1], v[2]).unwrap(), opt.generic_cap);
        let (w32, w64) = (v.map(v32), v.map(v64));
        b.textbook(
            |ray| bl::triangle_moller_trumbore(w32, ray, t32),
            |ray| bl::triangle_moller_trumbore(w64, ray, T_MAX),
        );
        b.robust_port_f32(|ray| bl::triangle_robust(w32, ray, t32));
        let p = |x: DVec3| parry3d::math::Vector::new(x.x as f32, x.y as f32, x.z as f32);
        let q = |x: DVec3| parry3d_f64::math::Vector::new(x.x, x.y, x.z);
        b.parry(
            &parry3d::shape::Triangle::new(p(v[0]), p(v[1]), p(v[2])),
            &parry3d_f64::shape::Triangle::new(q(v[0]), q(v[1]), q(v[2])),
            DVec3::ZERO,
        );
        rows.extend(b.rows);
    }

    // ── Disk ──
    if wanted("Disk") {
        let (c, n_in, r) = (DVec3::new(0.5, 0.25, -0.25), DVec3::new(1.0, 2.0, 2.0), 1.0);
        let shape = Shape::Disk { c, n: n_in, r };
        let nh = n_in.normalize();
        let mut rng = Rng::new(opt.seed ^ 4);
        let rays = make_rays(&mut rng, opt.rays, c, r, None, |g| {
            Hard::Feature(c + r * g.perpendicular(nh))
        });
        let mut b = new_bench("Disk", with_refs(rays, &shape));
        b.zeroset(&Disk::new(c, n_in, r).unwrap(), opt.generic_cap);
        let (c32, c64, n32, n64) = (v32(c), v64(c), v32(nh), v64(nh));
        b.textbook(
            |ray| bl::disk_textbook(c32, n32, r as f32, ray, t32),
            |ray| bl::disk_textbook(c64, n64, r, ray, T_MAX),
        );
        rows.extend(b.rows);
    }

    // ── Polygon ── (convex pentagon in the plane y = x/2 + z/4 + 1/8)
    if wanted("Polygon") {
        let plane = |x: f64, z: f64| DVec3::new(x, 0.5 * x + 0.25 * z + 0.125, z);
        let v = vec![
            plane(1.0, 0.0),
            plane(0.25, -1.0),
            plane(-0.75, -0.5),
            plane(-0.75, 0.5),
            plane(0.25, 1.0),
        ];
        let shape = Shape::Polygon(v.clone());
        let centre = v.iter().copied().sum::<DVec3>() / v.len() as f64;
        let mut rng = Rng::new(opt.seed ^ 5);
        let vv = v.clone();
        let rays = make_rays(&mut rng, opt.rays, centre, 1.2, None, move |g| {
            let i = (g.next_u64() % vv.len() as u64) as usize;
            let s = if g.f() < 0.2 { 0.0 } else { g.f() };
            Hard::Feature(vv[i] + s * (vv[(i + 1) % vv.len()] - vv[i]))
        });
        let mut b = new_bench("Polygon", with_refs(rays, &shape));
        b.zeroset(&Polygon::new(v.clone(), Vec::new()).unwrap(), opt.generic_cap);
        let w32: Vec<V<f32>> = v.iter().map(|p| v32(*p)).collect();
        let w64: Vec<V<f64>> = v.iter().map(|p| v64(*p)).collect();
        b.textbook(
            |ray| bl::polygon_textbook(&w32, ray, t32),
            |ray| bl::polygon_textbook(&w64, ray, T_MAX),
        );
        rows.extend(b.rows);
    }

    // ── Box ──
    if wanted("Box") {
        let (lo, hi) = (DVec3::new(-1.0, -0.5, -0.75), DVec3::new(0.5, 1.0, 0.25));
        let shape = Shape::Cuboid { lo, hi };
        let (centre, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
        let mut rng = Rng::new(opt.seed ^ 6);
        let rays = make_rays(&mut rng, opt.rays, centre, half.length(), None, |g| {
            // a point on one of the 12 edges (a corner one time in five)
            let axis = (g.next_u64() % 3) as usize;
            let mut p = DVec3::new(
                if g.f() < 0.5 { lo.x } else { hi.x },
                if g.f() < 0.5 { lo.y } else { hi.y },
                if g.f() < 0.5 { lo.z } else { hi.z },
            );
            if g.f() > 0.2 {
                p[axis] = g.range(lo[axis], hi[axis]);
            }
            Hard::Feature(p)
        });
        let mut b = new_bench("Box", with_refs(rays, &shape));
        b.zeroset(&Cuboid::new(lo, hi).unwrap(), opt.generic_cap);
        let (l32, h32, l64, h64) = (v32(lo), v32(hi), v64(lo), v64(hi));
        b.textbook(
            |ray| bl::box_textbook(l32, h32, ray, t32),
            |ray| bl::box_textbook(l64, h64, ray, T_MAX),
        );
        b.robust_port_f32(|ray| bl::box_robust(l32, h32, ray, t32));
        b.parry(
            &parry3d::shape::Cuboid::new(parry3d::math::Vector::new(half.x as f32, half.y as f32, half.z as f32)),
            &parry3d_f64::shape::Cuboid::new(parry3d_f64::math::Vector::new(half.x, half.y, half.z)),
            centre,
        );
        rows.extend(b.rows);
    }

    // ── Cylinder ── (capped, axis +Y)
    if wanted("Cylinder") {
        let (base, r, h) = (DVec3::new(0.25, -1.0, 0.5), 0.75, 2.0);
        let shape = Shape::Cylinder { base, r, h };
        let centre = base + DVec3::Y * (h / 2.0);
        let mut rng = Rng::new(opt.seed ^ 7);
        let rays = make_rays(&mut rng, opt.rays, centre, (r * r + h * h / 4.0).sqrt(), None, |g| {
            let a = g.range(0.0, std::f64::consts::TAU);
            let radial = DVec3::new(a.cos(), 0.0, a.sin());
            if g.f() < 0.5 {
                let y = if g.f() < 0.5 { 0.0 } else { h };
                Hard::Feature(base + r * radial + y * DVec3::Y)
            } else {
                Hard::Grazing(base + r * radial + g.range(0.0, h) * DVec3::Y, radial)
            }
        });
        let mut b = new_bench("Cylinder", with_refs(rays, &shape));
        b.zeroset(&Cylinder::new(base, DVec3::Y, r, h, true).unwrap(), opt.generic_cap);
        let (b32, b64) = (v32(base), v64(base));
        b.textbook(
            |ray| bl::cylinder_textbook(b32, r as f32, h as f32, ray, t32),
            |ray| bl::cylinder_textbook(b64, r, h, ray, T_MAX),
        );
        b.parry(
            &parry3d::shape::Cylinder::new((h / 2.0) as f32, r as f32),
            &parry3d_f64::shape::Cylinder::new(h / 2.0, r),
            centre,
        );
        rows.extend(b.rows);
    }

    // ── Cone ── (capped, pointed, axis +Y: parry's cone)
    if wanted("Cone") {
        let (base, r, h) = (DVec3::new(0.25, -1.0, 0.5), 1.0, 2.0);
        let shape = Shape::Cone { base, r, h };
        let centre = base + DVec3::Y * (h / 2.0);
        let slant = DVec3::new(h, r, 0.0).normalize();
        let mut rng = Rng::new(opt.seed ^ 8);
        let rays = make_rays(&mut rng, opt.rays, centre, (r * r + h * h / 4.0).sqrt(), None, |g| {
            let a = g.range(0.0, std::f64::consts::TAU);
            let radial = DVec3::new(a.cos(), 0.0, a.sin());
            let u = g.f();
            if u < 0.35 {
                Hard::Feature(base + r * radial)
            } else if u < 0.5 {
                Hard::Feature(base + h * DVec3::Y)
            } else {
                let y = g.range(0.0, h);
                let n = radial * slant.x + DVec3::Y * slant.y;
                Hard::Grazing(base + (r * (1.0 - y / h)) * radial + y * DVec3::Y, n)
            }
        });
        let mut b = new_bench("Cone", with_refs(rays, &shape));
        b.zeroset(&Cone::new(base, DVec3::Y, r, 0.0, h, true).unwrap(), opt.generic_cap);
        let (b32, b64) = (v32(base), v64(base));
        b.textbook(
            |ray| bl::cone_textbook(b32, r as f32, h as f32, ray, t32),
            |ray| bl::cone_textbook(b64, r, h, ray, T_MAX),
        );
        b.parry(
            &parry3d::shape::Cone::new((h / 2.0) as f32, r as f32),
            &parry3d_f64::shape::Cone::new(h / 2.0, r),
            centre,
        );
        rows.extend(b.rows);
    }

    // ── Ellipsoid ── (axis-aligned)
    if wanted("Ellipsoid") {
        let (c, radii) = (DVec3::new(0.25, -0.5, 0.125), DVec3::new(1.5, 1.0, 0.625));
        let shape = Shape::Ellipsoid { c, radii };
        let mut rng = Rng::new(opt.seed ^ 9);
        let rays = make_rays(&mut rng, opt.rays, c, radii.max_element(), None, |g| {
            let u = g.unit();
            Hard::Grazing(c + radii * u, u / radii)
        });
        let mut b = new_bench("Ellipsoid", with_refs(rays, &shape));
        b.zeroset(
            &Ellipsoid::new(c, radii, glam::DQuat::IDENTITY).unwrap(),
            opt.generic_cap,
        );
        let (c32, c64, r32, r64) = (v32(c), v64(c), v32(radii), v64(radii));
        b.textbook(
            |ray| bl::ellipsoid_textbook(c32, r32, ray, t32),
            |ray| bl::ellipsoid_textbook(c64, r64, ray, T_MAX),
        );
        rows.extend(b.rows);
    }
    rows
}
