//! Reference arithmetic and bookkeeping for `hard_cases.rs`.
//!
//! The reference is double-double (≈ 106-bit) arithmetic on the **same f64 inputs** zeroset gets
//! (which are f32 values widened, so exact): a value `hi + lo` with `|lo| ≤ ulp(hi)/2`, built from
//! error-free transformations (two-sum; two-product via `f64::mul_add`). Its relative error,
//! ≈ 10⁻³², is negligible next to the f64 errors measured.

#![allow(dead_code, reason = "each test binary uses part of the support code")]

use glam::{DQuat, DVec3};
use std::ops::{Add, Div, Mul, Neg, Sub};
use std::sync::Arc;
use zeroset_primitives::*;

/// A double-double number `hi + lo`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dd {
    pub hi: f64,
    pub lo: f64,
}

fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl Dd {
    pub const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };

    pub fn new(x: f64) -> Self {
        Dd { hi: x, lo: 0.0 }
    }

    fn norm(hi: f64, lo: f64) -> Self {
        let (hi, lo) = quick_two_sum(hi, lo);
        Dd { hi, lo }
    }

    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    pub fn sqrt(self) -> Dd {
        if self.hi <= 0.0 {
            return Dd::ZERO;
        }
        let s = self.hi.sqrt();
        let (p, e) = two_prod(s, s);
        let r = ((self.hi - p) - e + self.lo) / (2.0 * s);
        Dd::norm(s, r)
    }

    pub fn abs(self) -> Dd {
        if self.hi < 0.0 {
            -self
        } else {
            self
        }
    }

    pub fn is_neg(self) -> bool {
        self.hi < 0.0 || (self.hi == 0.0 && self.lo < 0.0)
    }
}

impl From<f64> for Dd {
    fn from(x: f64) -> Self {
        Dd::new(x)
    }
}

impl Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Add for Dd {
    type Output = Dd;
    fn add(self, y: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, y.hi);
        let (t, f) = two_sum(self.lo, y.lo);
        let (s, e) = quick_two_sum(s, e + t);
        Dd::norm(s, e + f)
    }
}

impl Sub for Dd {
    type Output = Dd;
    fn sub(self, y: Dd) -> Dd {
        self + (-y)
    }
}

impl Mul for Dd {
    type Output = Dd;
    fn mul(self, y: Dd) -> Dd {
        let (p, e) = two_prod(self.hi, y.hi);
        Dd::norm(p, e + (self.hi * y.lo + self.lo * y.hi))
    }
}

impl Div for Dd {
    type Output = Dd;
    fn div(self, y: Dd) -> Dd {
        let q1 = self.hi / y.hi;
        let r = self - y * Dd::new(q1);
        let q2 = r.hi / y.hi;
        let r = r - y * Dd::new(q2);
        let q3 = r.hi / y.hi;
        let (a, b) = quick_two_sum(q1, q2);
        Dd::norm(a, b) + Dd::new(q3)
    }
}

/// A 3-vector of double-doubles.
#[derive(Clone, Copy, Debug)]
pub struct V(pub [Dd; 3]);

impl V {
    pub fn from(v: DVec3) -> V {
        V([Dd::new(v.x), Dd::new(v.y), Dd::new(v.z)])
    }
    pub fn dot(self, o: V) -> Dd {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }
    pub fn cross(self, o: V) -> V {
        let (a, b) = (self.0, o.0);
        V([
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ])
    }
    pub fn sub(self, o: V) -> V {
        V([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
    pub fn add(self, o: V) -> V {
        V([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
    pub fn scale(self, s: Dd) -> V {
        V([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
    pub fn div_each(self, r: V) -> V {
        V([self.0[0] / r.0[0], self.0[1] / r.0[1], self.0[2] / r.0[2]])
    }
    pub fn to_f64(self) -> DVec3 {
        DVec3::new(self.0[0].to_f64(), self.0[1].to_f64(), self.0[2].to_f64())
    }
}

/// The reference answer for one ray.
#[derive(Clone, Copy, Debug)]
pub struct Reference {
    /// First hit parameter in the query range, if any.
    pub t: Option<Dd>,
    /// Unit outward normal at the reference hit.
    pub normal: DVec3,
    /// Relative distance of the ray from a decision boundary (tangency, an edge, a rim); the
    /// hit/miss answer may go either way below the case's band.
    pub margin: f64,
}

impl Reference {
    pub const MISS: Reference = Reference {
        t: None,
        normal: DVec3::ZERO,
        margin: f64::INFINITY,
    };
}

/// Roots of `A t² + 2B t + C = 0` in increasing order (stable form), with the relative
/// discriminant `(B² − AC)/(B² + |AC|)` (0 at tangency).
pub fn quadratic(a: Dd, b: Dd, c: Dd) -> (Option<(Dd, Dd)>, f64) {
    let disc = b * b - a * c;
    let scale = (b * b).abs() + (a * c).abs();
    let rel = if scale.hi > 0.0 { disc.hi / scale.hi } else { 0.0 };
    if disc.is_neg() {
        return (None, rel.abs());
    }
    if a.hi == 0.0 {
        if b.hi == 0.0 {
            return (None, rel.abs());
        }
        let t = -c / (b + b);
        return (Some((t, t)), rel.abs());
    }
    let sq = disc.sqrt();
    let q = if b.is_neg() { sq - b } else { -(b + sq) };
    if q.hi == 0.0 {
        return (Some((Dd::ZERO, Dd::ZERO)), 0.0);
    }
    let (t0, t1) = (q / a, c / q);
    (Some(if t0.hi <= t1.hi { (t0, t1) } else { (t1, t0) }), rel.abs())
}

/// Sphere `|p − c| = r` (`t ≥ t_min`).
pub fn sphere(o: DVec3, d: DVec3, c: DVec3, r: f64, t_min: f64) -> Reference {
    let (f, dv) = (V::from(o).sub(V::from(c)), V::from(d));
    let rr = Dd::new(r) * Dd::new(r);
    let (a, b) = (dv.dot(dv), f.dot(dv));
    let (roots, _) = quadratic(a, b, f.dot(f) - rr);
    // relative discriminant a·r² − |f × d|² over a·r²: 0 at tangency
    let w = f.cross(dv);
    let margin = ((a * rr - w.dot(w)).to_f64() / (a * rr).to_f64()).abs();
    let Some((t0, t1)) = roots else {
        return Reference {
            margin,
            ..Reference::MISS
        };
    };
    let t = [t0, t1].into_iter().find(|t| t.to_f64() >= t_min);
    let normal = t.map_or(DVec3::ZERO, |t| f.add(dv.scale(t)).to_f64().normalize());
    Reference { t, normal, margin }
}

/// Axis-aligned ellipsoid with centre `c`, semi-axes `r`.
pub fn ellipsoid(o: DVec3, d: DVec3, c: DVec3, r: DVec3, t_min: f64) -> Reference {
    let rv = V::from(r);
    let f = V::from(o).sub(V::from(c)).div_each(rv);
    let dv = V::from(d).div_each(rv);
    let (roots, _) = quadratic(dv.dot(dv), f.dot(dv), f.dot(f) - Dd::new(1.0));
    let w = f.cross(dv);
    let a = dv.dot(dv);
    let margin = ((a - w.dot(w)).to_f64() / a.to_f64()).abs();
    let Some((t0, t1)) = roots else {
        return Reference {
            margin,
            ..Reference::MISS
        };
    };
    let t = [t0, t1].into_iter().find(|t| t.to_f64() >= t_min);
    let normal = t.map_or(DVec3::ZERO, |t| f.add(dv.scale(t)).div_each(rv).to_f64().normalize());
    Reference { t, normal, margin }
}

/// The plane `⟨p, n⟩ = offset` (n as given, not normalised), `t ≥ t_min`; `None` when parallel.
pub fn plane(o: DVec3, d: DVec3, n: DVec3, offset: f64, t_min: f64) -> Reference {
    let nv = V::from(n);
    let denom = V::from(d).dot(nv);
    if denom.hi == 0.0 {
        return Reference {
            margin: 0.0,
            ..Reference::MISS
        };
    }
    let t = (Dd::new(offset) - V::from(o).dot(nv)) / denom;
    let margin = (denom.hi / (d.length() * n.length())).abs();
    if t.to_f64() < t_min {
        return Reference {
            margin,
            ..Reference::MISS
        };
    }
    Reference {
        t: Some(t),
        normal: n.normalize(),
        margin,
    }
}

/// Closed axis-aligned box `[lo, hi]`: entry, else exit, at `t ≥ t_min`. The margin is the
/// relative gap between the slab intervals (0 when the ray grazes an edge or corner).
pub fn cuboid(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3, t_min: f64) -> Reference {
    let (mut t_near, mut t_far) = (None::<(Dd, usize, f64)>, None::<(Dd, usize, f64)>);
    for axis in 0..3 {
        if d[axis] == 0.0 {
            if o[axis] < lo[axis] || o[axis] > hi[axis] {
                return Reference {
                    margin: 1.0,
                    ..Reference::MISS
                };
            }
            continue;
        }
        let inv = Dd::new(d[axis]);
        let a = (Dd::new(lo[axis]) - Dd::new(o[axis])) / inv;
        let b = (Dd::new(hi[axis]) - Dd::new(o[axis])) / inv;
        let (n, f, sn) = if d[axis] > 0.0 { (a, b, -1.0) } else { (b, a, 1.0) };
        if t_near.is_none_or(|(t, _, _)| n.hi > t.hi || (n.hi == t.hi && n.lo > t.lo)) {
            t_near = Some((n, axis, sn));
        }
        if t_far.is_none_or(|(t, _, _)| f.hi < t.hi || (f.hi == t.hi && f.lo < t.lo)) {
            t_far = Some((f, axis, -sn));
        }
    }
    let (Some((tn, an, sn)), Some((tf, af, sf))) = (t_near, t_far) else {
        return Reference::MISS;
    };
    let gap = (tf - tn).to_f64();
    let scale = tn.to_f64().abs().max(tf.to_f64().abs()).max(1e-300);
    let margin = (gap / scale).abs();
    if gap < 0.0 {
        return Reference {
            margin,
            ..Reference::MISS
        };
    }
    // a ray lying on a face at t_min leaves it across the far edge: the exit below, as for a
    // ray inside the box
    let mut normal = DVec3::ZERO;
    let pick = if tn.to_f64() >= t_min {
        normal[an] = sn;
        Some(tn)
    } else if tf.to_f64() >= t_min {
        normal[af] = sf;
        Some(tf)
    } else {
        None
    };
    Reference {
        t: pick,
        normal,
        margin,
    }
}

/// Capped or open cone frustum on the Z axis: base centre `b`, radii `r0` (at `b`) and `r1`
/// (at `b + H·z`). `t ≥ t_min`.
#[allow(
    clippy::too_many_arguments,
    reason = "a reference mirrors the primitive's parameters"
)]
pub fn cone_z(o: DVec3, d: DVec3, b: DVec3, r0: f64, r1: f64, height: f64, capped: bool, t_min: f64) -> Reference {
    let ol = V::from(o).sub(V::from(b));
    let dv = V::from(d);
    let (ox, oy, oz) = (ol.0[0], ol.0[1], ol.0[2]);
    let (dx, dy, dz) = (dv.0[0], dv.0[1], dv.0[2]);
    let (r0d, r1d, hd) = (Dd::new(r0), Dd::new(r1), Dd::new(height));
    let k = (r0d - r1d) / hd;
    let s0 = r0d - k * oz;
    let ds = -(k * dz);
    let a = dx * dx + dy * dy - ds * ds;
    let bb = ox * dx + oy * dy - s0 * ds;
    let c = ox * ox + oy * oy - s0 * s0;
    let mut margin = f64::INFINITY;
    let mut best: Option<(Dd, DVec3)> = None;
    let consider = |t: Dd, n: DVec3, best: &mut Option<(Dd, DVec3)>| {
        if t.to_f64() >= t_min && best.is_none_or(|(b, _)| t.hi < b.hi) {
            *best = Some((t, n));
        }
    };
    let (roots, rel) = quadratic(a, bb, c);
    let slant = (height * height + (r0 - r1) * (r0 - r1)).sqrt();
    let side_solvable = !(a.hi == 0.0 && bb.hi == 0.0);
    if let Some((t0, t1)) = roots.filter(|_| side_solvable) {
        margin = margin.min(rel);
        for t in [t0, t1] {
            let h = oz + t * dz;
            let hf = h.to_f64();
            margin = margin.min((hf / height).abs()).min(((h - hd).to_f64() / height).abs());
            if hf >= 0.0 && (h - hd).to_f64() <= 0.0 {
                let px = (ox + t * dx).to_f64();
                let py = (oy + t * dy).to_f64();
                let rho = px.hypot(py);
                let radial = if rho > 0.0 {
                    DVec3::new(px / rho, py / rho, 0.0)
                } else {
                    DVec3::ZERO
                };
                let n = (height * radial + (r0 - r1) * DVec3::Z) / slant;
                // s(h) must be ≥ 0 (not the mirrored nappe)
                let s = r0d - k * h;
                if !s.is_neg() {
                    consider(t, n.normalize_or_zero(), &mut best);
                }
            }
        }
    } else if side_solvable {
        margin = margin.min(rel);
    }
    if capped && dz.hi != 0.0 {
        for (h, r, n) in [(Dd::ZERO, r0, -DVec3::Z), (hd, r1, DVec3::Z)] {
            if r == 0.0 {
                continue;
            }
            let t = (h - oz) / dz;
            let px = ox + t * dx;
            let py = oy + t * dy;
            let rho2 = px * px + py * py;
            let gap = (rho2 - Dd::new(r) * Dd::new(r)).to_f64() / (r * r);
            margin = margin.min(gap.abs());
            if gap <= 0.0 {
                consider(t, n, &mut best);
            }
        }
    }
    match best {
        Some((t, normal)) => Reference {
            t: Some(t),
            normal,
            margin,
        },
        None => Reference {
            margin,
            ..Reference::MISS
        },
    }
}

/// Angle between two directions in radians, accurate for tiny angles.
pub fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Accumulated measurements for one case.
#[derive(Debug, Default)]
pub struct Stats {
    pub name: String,
    pub rays: usize,
    pub t_errors: Vec<f64>,
    pub normal_errors: Vec<f64>,
    pub disagreements: usize,
    pub banded: usize,
    pub hits: usize,
    pub non_finite: usize,
    pub out_of_range: usize,
}

fn max_and_median(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    (s[s.len() - 1], s[s.len() / 2])
}

impl Stats {
    pub fn new(name: &str) -> Self {
        Stats {
            name: name.to_string(),
            ..Stats::default()
        }
    }

    pub fn max_t(&self) -> f64 {
        max_and_median(&self.t_errors).0
    }

    pub fn max_normal(&self) -> f64 {
        max_and_median(&self.normal_errors).0
    }

    /// Prints one line in the format the closing note and `docs/numerics.md` quote.
    pub fn report(&self) {
        let (tm, tmed) = max_and_median(&self.t_errors);
        let (nm, nmed) = max_and_median(&self.normal_errors);
        println!(
            "[hard] {:<34} rays {:>7} hits {:>7} | rel t err max {:>9.2e} median {:>9.2e} | normal err max {:>9.2e} rad median {:>9.2e} | disagree {} (banded {}) | non-finite {} | out of range {}",
            self.name, self.rays, self.hits, tm, tmed, nm, nmed, self.disagreements, self.banded, self.non_finite, self.out_of_range
        );
    }

    /// Asserts the stated bounds, after printing.
    pub fn check(&self, max_t: f64, max_normal: f64) {
        self.report();
        assert_eq!(self.non_finite, 0, "{}: non-finite results", self.name);
        assert_eq!(self.out_of_range, 0, "{}: t outside the query range", self.name);
        assert_eq!(
            self.disagreements, 0,
            "{}: hit/miss disagreements outside the band",
            self.name
        );
        assert!(
            self.max_t() <= max_t,
            "{}: max relative t error {:e} > {max_t:e}",
            self.name,
            self.max_t()
        );
        assert!(
            self.max_normal() <= max_normal,
            "{}: max normal error {:e} rad > {max_normal:e}",
            self.name,
            self.max_normal()
        );
    }
}

/// One of every built-in primitive in a general position (rotated, off the origin), with the
/// fraction of its bounds to aim rays at: the shared set of the re-cast tests.
pub fn one_of_each_builtin() -> Vec<(&'static str, Arc<dyn Primitive>, f64)> {
    let quat = DQuat::from_axis_angle(DVec3::new(0.3, -1.0, 0.5).normalize(), 0.7);
    let square: Vec<[f32; 3]> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.1],
        [1.0, 1.0, 0.3],
        [0.0, 1.0, -0.2],
        [0.5, 0.5, 0.9],
    ];
    let pyramid = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]];
    vec![
        (
            "Sphere",
            Arc::new(Sphere::new(DVec3::new(1.0, 2.0, 3.0), 1.5).unwrap()),
            0.9,
        ),
        (
            "Plane",
            Arc::new(Plane::new(DVec3::new(0.2, 1.0, -0.3), 0.7).unwrap()),
            0.9,
        ),
        (
            "Triangle",
            Arc::new(
                Triangle::new(
                    DVec3::new(0.1, 0.2, 0.3),
                    DVec3::new(2.1, -0.4, 0.9),
                    DVec3::new(0.5, 1.9, -0.6),
                )
                .unwrap(),
            ),
            0.3,
        ),
        (
            "Disk",
            Arc::new(Disk::new(DVec3::new(0.3, 0.1, 0.2), DVec3::new(1.0, 2.0, 0.5), 1.3).unwrap()),
            0.5,
        ),
        (
            "Polygon",
            Arc::new(
                Polygon::new(
                    vec![
                        DVec3::new(0.0, 0.0, 1.0),
                        DVec3::new(2.0, 0.1, 1.0),
                        DVec3::new(2.2, 1.9, 1.0),
                        DVec3::new(-0.1, 2.0, 1.0),
                    ],
                    vec![],
                )
                .unwrap(),
            ),
            0.8,
        ),
        (
            "Cuboid",
            Arc::new(Cuboid::new(DVec3::new(-1.0, -0.5, 0.2), DVec3::new(0.7, 1.3, 2.1)).unwrap()),
            1.2,
        ),
        (
            "Cylinder",
            Arc::new(Cylinder::new(DVec3::new(0.2, 0.1, 0.0), DVec3::new(0.3, 1.0, 0.2), 0.8, 2.0, true).unwrap()),
            1.0,
        ),
        (
            "Cone",
            Arc::new(
                Cone::new(
                    DVec3::new(0.2, 0.1, 0.0),
                    DVec3::new(0.3, 1.0, 0.2),
                    0.9,
                    0.0,
                    2.0,
                    true,
                )
                .unwrap(),
            ),
            1.0,
        ),
        (
            "Ellipsoid",
            Arc::new(Ellipsoid::new(DVec3::new(0.5, 0.0, -1.0), DVec3::new(3.0, 0.5, 1.2), quat).unwrap()),
            1.0,
        ),
        ("Mesh", Arc::new(Mesh::new(square, pyramid, None).unwrap()), 1.0),
    ]
}
