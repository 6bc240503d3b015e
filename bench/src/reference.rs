//! Reference answers in double-double arithmetic, computed independently of zeroset from the
//! same f64 parameters and rays (rays are f32 values widened, so every method sees them exactly).
//!
//! Each function returns the first hit with `0 ≤ t ≤ t_max`, the analytic normal there, and a
//! margin: how close (relatively) the ray passes to a hit/miss or face decision.

use crate::dd::{at, quadratic, Dd, V3};
use crate::measure::Ref;
use glam::DVec3;
use zeroset_primitives::Ray;

/// The shapes the bench measures, in the parametrisations the references use.
#[derive(Clone, Debug)]
pub enum Shape {
    Sphere {
        c: DVec3,
        r: f64,
    },
    /// `⟨p, n⟩ = offset` with the normal as given (not normalised).
    Plane {
        n: DVec3,
        offset: f64,
    },
    Disk {
        c: DVec3,
        n: DVec3,
        r: f64,
    },
    Triangle([DVec3; 3]),
    /// Convex, planar, counter-clockwise about the normal of its first three vertices.
    Polygon(Vec<DVec3>),
    Cuboid {
        lo: DVec3,
        hi: DVec3,
    },
    /// Capped, axis +Y from `base`.
    Cylinder {
        base: DVec3,
        r: f64,
        h: f64,
    },
    /// Capped and pointed: radius `r` at `base`, apex at `base + h·Y`.
    Cone {
        base: DVec3,
        r: f64,
        h: f64,
    },
    /// Axis-aligned.
    Ellipsoid {
        c: DVec3,
        radii: DVec3,
    },
}

fn d(x: f64) -> Dd {
    Dd::new(x)
}

fn hit(t: Dd, normal: DVec3, margin: f64) -> Ref {
    Ref {
        t: Some(t),
        normal: normal.normalize_or_zero(),
        margin,
    }
}

fn ok(t: Dd, t_max: f64) -> bool {
    !t.is_negative() && t.f64() <= t_max
}

/// The reference for `shape` along `ray`.
pub fn reference(shape: &Shape, ray: &Ray, t_max: f64) -> Ref {
    let (o, dir) = (ray.origin, ray.dir);
    match shape {
        Shape::Sphere { c, r } => {
            let f = V3::new(o).sub(V3::new(*c));
            let dv = V3::new(dir);
            let (roots, margin) = quadratic(dv.dot(dv), f.dot(dv), f.dot(f) - d(*r) * d(*r));
            let Some((t0, t1)) = roots else {
                return Ref::MISS;
            };
            let t = if ok(t0, t_max) {
                t0
            } else if ok(t1, t_max) {
                t1
            } else {
                return Ref::MISS;
            };
            hit(t, at(o, dir, t).sub(V3::new(*c)).f64(), margin)
        }
        Shape::Ellipsoid { c, radii } => {
            let rv = V3::new(*radii);
            let f = V3::new(o).sub(V3::new(*c));
            let f = V3(f.0 / rv.0, f.1 / rv.1, f.2 / rv.2);
            let dv = V3::new(dir);
            let dv = V3(dv.0 / rv.0, dv.1 / rv.1, dv.2 / rv.2);
            let (roots, margin) = quadratic(dv.dot(dv), f.dot(dv), f.dot(f) - d(1.0));
            let Some((t0, t1)) = roots else {
                return Ref::MISS;
            };
            let t = if ok(t0, t_max) {
                t0
            } else if ok(t1, t_max) {
                t1
            } else {
                return Ref::MISS;
            };
            let s = f.add(dv.scale(t)).f64();
            hit(t, s / *radii, margin)
        }
        Shape::Plane { n, offset } => {
            let nv = V3::new(*n);
            let denom = nv.dot(V3::new(dir));
            if denom.hi == 0.0 {
                return Ref::MISS;
            }
            let t = (d(*offset) - nv.dot(V3::new(o))) / denom;
            if ok(t, t_max) {
                // grazing angle as the margin
                hit(t, *n, (denom.f64() / (n.length() * dir.length())).abs())
            } else {
                Ref::MISS
            }
        }
        Shape::Disk { c, n, r } => {
            let nv = V3::new(*n);
            let denom = nv.dot(V3::new(dir));
            if denom.hi == 0.0 {
                return Ref::MISS;
            }
            let cv = V3::new(*c);
            let t = nv.dot(cv.sub(V3::new(o))) / denom;
            if !ok(t, t_max) {
                return Ref::MISS;
            }
            let q = at(o, dir, t).sub(cv);
            let rho2 = q.dot(q);
            let margin = ((d(*r) * d(*r) - rho2).f64() / (r * r)).abs();
            if (d(*r) * d(*r) - rho2).is_negative() {
                Ref::MISS
            } else {
                hit(t, *n, margin)
            }
        }
        Shape::Triangle(v) => convex_polygon(v, o, dir, t_max),
        Shape::Polygon(v) => convex_polygon(v, o, dir, t_max),
        Shape::Cuboid { lo, hi } => {
            // (no infinities in double-double: they turn into NaN, so the slabs start unset)
            let mut near: Option<(Dd, usize, f64)> = None;
            let mut far: Option<Dd> = None;
            let mut ts = [None; 3];
            for i in 0..3 {
                if dir[i] == 0.0 {
                    if !(lo[i] <= o[i] && o[i] <= hi[i]) {
                        return Ref::MISS;
                    }
                    continue;
                }
                let t0 = (d(lo[i]) - d(o[i])) / d(dir[i]);
                let t1 = (d(hi[i]) - d(o[i])) / d(dir[i]);
                let (a, b, s) = if dir[i] > 0.0 { (t0, t1, -1.0) } else { (t1, t0, 1.0) };
                ts[i] = Some(a);
                if near.is_none_or(|(n, _, _)| (n - a).is_negative()) {
                    near = Some((a, i, s));
                }
                if far.is_none_or(|f| (b - f).is_negative()) {
                    far = Some(b);
                }
            }
            let (Some((t_near, near_axis, near_sign)), Some(t_far)) = (near, far) else {
                return Ref::MISS;
            };
            if (t_far - t_near).is_negative() || !ok(t_near, t_max) {
                return Ref::MISS;
            }
            // margin: how close the entry is to an edge (another slab's entry, or the exit)
            let scale = t_near.f64().abs().max(1e-300);
            let mut margin = ((t_far - t_near).f64() / scale).abs();
            for (i, t) in ts.iter().enumerate() {
                if let Some(t) = t {
                    if i != near_axis {
                        margin = margin.min(((t_near - *t).f64() / scale).abs());
                    }
                }
            }
            let mut n = DVec3::ZERO;
            n[near_axis] = near_sign;
            hit(t_near, n, margin)
        }
        Shape::Cylinder { base, r, h } => {
            let f = V3::new(o).sub(V3::new(*base));
            let dv = V3::new(dir);
            let mut best: Option<(Dd, DVec3, f64)> = None;
            let mut consider = |t: Dd, n: DVec3, margin: f64| {
                if ok(t, t_max) && best.is_none_or(|(b, _, _)| (t - b).is_negative()) {
                    best = Some((t, n, margin));
                }
            };
            let (roots, disc_margin) = quadratic(
                dv.0 * dv.0 + dv.2 * dv.2,
                f.0 * dv.0 + f.2 * dv.2,
                f.0 * f.0 + f.2 * f.2 - d(*r) * d(*r),
            );
            if let Some((t0, t1)) = roots {
                for t in [t0, t1] {
                    let y = f.1 + t * dv.1;
                    if !y.is_negative() && !(d(*h) - y).is_negative() {
                        let x = f.0 + t * dv.0;
                        let z = f.2 + t * dv.2;
                        let rim = (y.f64().min(h - y.f64()) / h).abs();
                        consider(t, DVec3::new(x.f64(), 0.0, z.f64()), rim.min(disc_margin));
                    }
                }
            }
            if dir.y != 0.0 {
                for (plane, ny) in [(0.0, -1.0), (*h, 1.0)] {
                    let t = (d(plane) - f.1) / dv.1;
                    let x = f.0 + t * dv.0;
                    let z = f.2 + t * dv.2;
                    let rho2 = x * x + z * z;
                    let inside = d(*r) * d(*r) - rho2;
                    if !inside.is_negative() {
                        consider(t, DVec3::new(0.0, ny, 0.0), (inside.f64() / (r * r)).abs());
                    }
                }
            }
            best.map_or(Ref::MISS, |(t, n, m)| hit(t, n, m))
        }
        Shape::Cone { base, r, h } => {
            let f = V3::new(o).sub(V3::new(*base));
            let dv = V3::new(dir);
            let k = d(*r) / d(*h);
            let mut best: Option<(Dd, DVec3, f64)> = None;
            let mut consider = |t: Dd, n: DVec3, margin: f64| {
                if ok(t, t_max) && best.is_none_or(|(b, _, _)| (t - b).is_negative()) {
                    best = Some((t, n, margin));
                }
            };
            // x² + z² = (s0 + t s')², s0 = r − k·f_y, s' = −k·d_y
            let s0 = d(*r) - k * f.1;
            let s1 = -(k * dv.1);
            let (roots, disc_margin) = quadratic(
                dv.0 * dv.0 + dv.2 * dv.2 - s1 * s1,
                f.0 * dv.0 + f.2 * dv.2 - s0 * s1,
                f.0 * f.0 + f.2 * f.2 - s0 * s0,
            );
            if let Some((t0, t1)) = roots {
                for t in [t0, t1] {
                    let y = f.1 + t * dv.1;
                    if !y.is_negative() && !(d(*h) - y).is_negative() {
                        let x = (f.0 + t * dv.0).f64();
                        let z = (f.2 + t * dv.2).f64();
                        let rho = x.hypot(z);
                        let rim = (y.f64().min(h - y.f64()) / h).abs();
                        let n = if rho > 0.0 {
                            DVec3::new(h * x / rho, *r, h * z / rho)
                        } else {
                            DVec3::Y
                        };
                        consider(t, n, rim.min(disc_margin));
                    }
                }
            }
            if dir.y != 0.0 {
                let t = -f.1 / dv.1;
                let x = f.0 + t * dv.0;
                let z = f.2 + t * dv.2;
                let inside = d(*r) * d(*r) - (x * x + z * z);
                if !inside.is_negative() {
                    consider(t, DVec3::NEG_Y, (inside.f64() / (r * r)).abs());
                }
            }
            best.map_or(Ref::MISS, |(t, n, m)| hit(t, n, m))
        }
    }
}

/// A convex polygon (a triangle included): `t` from its plane, inside when every edge function
/// `((v_{i+1} − v_i) × (p − v_i))·N` is `≥ 0`, all in double-double.
fn convex_polygon(v: &[DVec3], o: DVec3, dir: DVec3, t_max: f64) -> Ref {
    let vs: Vec<V3> = v.iter().map(|p| V3::new(*p)).collect();
    let n = vs[1].sub(vs[0]).cross(vs[2].sub(vs[0]));
    let denom = n.dot(V3::new(dir));
    if denom.hi == 0.0 {
        return Ref::MISS;
    }
    let t = n.dot(vs[0].sub(V3::new(o))) / denom;
    if !ok(t, t_max) {
        return Ref::MISS;
    }
    let p = at(o, dir, t);
    let area = n.dot(n).f64().sqrt();
    let mut margin = f64::INFINITY;
    for i in 0..vs.len() {
        let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
        let e = b.sub(a).cross(p.sub(a)).dot(n);
        if e.is_negative() {
            return Ref::MISS;
        }
        let edge = b.sub(a).f64().length();
        margin = margin.min(e.f64() / (area * edge * edge));
    }
    hit(t, n.f64(), margin)
}
