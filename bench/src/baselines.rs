//! Baseline intersectors that are not zeroset's: the textbook closed forms of the classic
//! course (written once, generic over f32/f64) and f32 ports of zeroset's robust sphere, box and
//! triangle. They live here, not in the kernel, and exist only to be measured against.

#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "`!(a <= b)` rejects NaN too, as in zeroset's kernel"
)]

use glam::DVec3;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic the baselines need, for `f32` and `f64`.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    const ZERO: Self;
    const ONE: Self;
    const INF: Self;
    fn of(x: f64) -> Self;
    fn wide(self) -> f64;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn copysign(self, s: Self) -> Self;
}

macro_rules! real {
    ($t:ty) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const INF: Self = <$t>::INFINITY;
            #[inline]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline]
            fn wide(self) -> f64 {
                f64::from(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn copysign(self, s: Self) -> Self {
                <$t>::copysign(self, s)
            }
        }
    };
}
real!(f32);
real!(f64);

/// A 3-vector of `R`.
#[derive(Clone, Copy, Debug)]
pub struct V<R>(pub R, pub R, pub R);

impl<R: Real> V<R> {
    #[inline]
    pub fn of(v: DVec3) -> Self {
        V(R::of(v.x), R::of(v.y), R::of(v.z))
    }
    #[inline]
    pub fn wide(self) -> DVec3 {
        DVec3::new(self.0.wide(), self.1.wide(), self.2.wide())
    }
    #[inline]
    pub fn dot(self, o: Self) -> R {
        self.0 * o.0 + self.1 * o.1 + self.2 * o.2
    }
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        V(
            self.1 * o.2 - self.2 * o.1,
            self.2 * o.0 - self.0 * o.2,
            self.0 * o.1 - self.1 * o.0,
        )
    }
    #[inline]
    pub fn sub(self, o: Self) -> Self {
        V(self.0 - o.0, self.1 - o.1, self.2 - o.2)
    }
    #[inline]
    pub fn add(self, o: Self) -> Self {
        V(self.0 + o.0, self.1 + o.1, self.2 + o.2)
    }
    #[inline]
    pub fn scale(self, s: R) -> Self {
        V(self.0 * s, self.1 * s, self.2 * s)
    }
    #[inline]
    pub fn get(self, i: usize) -> R {
        match i {
            0 => self.0,
            1 => self.1,
            _ => self.2,
        }
    }
}

/// A ray in `R`.
#[derive(Clone, Copy, Debug)]
pub struct RayR<R> {
    pub o: V<R>,
    pub d: V<R>,
}

impl<R: Real> RayR<R> {
    pub fn of(ray: &zeroset_primitives::Ray) -> Self {
        RayR {
            o: V::of(ray.origin),
            d: V::of(ray.dir),
        }
    }
    #[inline]
    fn at(&self, t: R) -> V<R> {
        self.o.add(self.d.scale(t))
    }
}

/// What every baseline returns: `t` and the unit normal, widened to f64.
pub type Answer = Option<(f64, DVec3)>;

#[inline]
fn answer<R: Real>(t: R, n: V<R>) -> Answer {
    Some((t.wide(), n.wide().normalize_or_zero()))
}

#[inline]
fn in_range<R: Real>(t: R, t_max: R) -> bool {
    t >= R::ZERO && t <= t_max
}

/// Textbook sphere: `b² − 4ac`, near root `(−b − √disc)/2a`, else the far one.
#[inline]
pub fn sphere_textbook<R: Real>(c: V<R>, r: R, ray: &RayR<R>, t_max: R) -> Answer {
    let oc = ray.o.sub(c);
    let a = ray.d.dot(ray.d);
    let b = R::of(2.0) * oc.dot(ray.d);
    let cc = oc.dot(oc) - r * r;
    let disc = b * b - R::of(4.0) * a * cc;
    if disc < R::ZERO {
        return None;
    }
    let s = disc.sqrt();
    let mut t = (-b - s) / (R::of(2.0) * a);
    if !in_range(t, t_max) {
        t = (-b + s) / (R::of(2.0) * a);
        if !in_range(t, t_max) {
            return None;
        }
    }
    answer(t, ray.at(t).sub(c))
}

/// f32 port of zeroset's robust sphere: Lagrange discriminant `a r² − |f × d|²`, roots `c/q`,
/// `q/a` (without the compensated sums, which f32 has no cheap fused form for here).
#[inline]
pub fn sphere_robust<R: Real>(c: V<R>, r: R, ray: &RayR<R>, t_max: R) -> Answer {
    let f = ray.o.sub(c);
    let d = ray.d;
    let a = d.dot(d);
    let b = f.dot(d);
    let c0 = f.dot(f) - r * r;
    let w = f.cross(d);
    let disc = a * r * r - w.dot(w);
    if !(disc >= R::ZERO) {
        return None;
    }
    let q = -(b + disc.sqrt().copysign(b));
    if q == R::ZERO {
        return None;
    }
    let (mut t0, mut t1) = (c0 / q, q / a);
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    let t = if in_range(t0, t_max) {
        t0
    } else if in_range(t1, t_max) {
        t1
    } else {
        return None;
    };
    answer(t, f.add(d.scale(t)))
}

/// Textbook ellipsoid (axis-aligned): scale into the unit sphere, then the textbook sphere.
#[inline]
pub fn ellipsoid_textbook<R: Real>(c: V<R>, radii: V<R>, ray: &RayR<R>, t_max: R) -> Answer {
    let o = ray.o.sub(c);
    let o = V(o.0 / radii.0, o.1 / radii.1, o.2 / radii.2);
    let d = V(ray.d.0 / radii.0, ray.d.1 / radii.1, ray.d.2 / radii.2);
    let unit = RayR { o, d };
    let (t, _) = sphere_textbook(V(R::ZERO, R::ZERO, R::ZERO), R::ONE, &unit, t_max)?;
    let t = R::of(t);
    let s = unit.at(t);
    answer(t, V(s.0 / radii.0, s.1 / radii.1, s.2 / radii.2))
}

/// Textbook plane: unit normal `n`, `⟨p, n⟩ = offset`; `t = (offset − ⟨o, n⟩)/⟨d, n⟩`.
#[inline]
pub fn plane_textbook<R: Real>(n: V<R>, offset: R, ray: &RayR<R>, t_max: R) -> Answer {
    let denom = n.dot(ray.d);
    if denom == R::ZERO {
        return None;
    }
    let t = (offset - n.dot(ray.o)) / denom;
    in_range(t, t_max).then(|| (t.wide(), n.wide()))
}

/// Textbook disk: the plane, then `|p − c|² ≤ r²`.
#[inline]
pub fn disk_textbook<R: Real>(c: V<R>, n: V<R>, r: R, ray: &RayR<R>, t_max: R) -> Answer {
    let (t, normal) = plane_textbook(n, n.dot(c), ray, t_max)?;
    let q = ray.at(R::of(t)).sub(c);
    (q.dot(q) <= r * r).then_some((t, normal))
}

/// Möller–Trumbore (1997), `|det| < 10⁻⁸` treated as parallel, as in the paper's code.
#[inline]
pub fn triangle_moller_trumbore<R: Real>(v: [V<R>; 3], ray: &RayR<R>, t_max: R) -> Answer {
    let e1 = v[1].sub(v[0]);
    let e2 = v[2].sub(v[0]);
    let p = ray.d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < R::of(1e-8) {
        return None;
    }
    let inv = R::ONE / det;
    let s = ray.o.sub(v[0]);
    let u = s.dot(p) * inv;
    if u < R::ZERO || u > R::ONE {
        return None;
    }
    let q = s.cross(e1);
    let w = ray.d.dot(q) * inv;
    if w < R::ZERO || u + w > R::ONE {
        return None;
    }
    let t = e2.dot(q) * inv;
    in_range(t, t_max).then(|| (t.wide(), e1.cross(e2).wide().normalize_or_zero()))
}

/// f32 port of zeroset's robust triangle: edge functions of the vertices translated to the ray
/// origin (each depends on its own edge only, so shared edges are watertight), `t` from the
/// plane through `a`.
#[inline]
pub fn triangle_robust<R: Real>(v: [V<R>; 3], ray: &RayR<R>, t_max: R) -> Answer {
    let a = v[0].sub(ray.o);
    let b = v[1].sub(ray.o);
    let c = v[2].sub(ray.o);
    let d = ray.d;
    let e0 = d.dot(b.cross(c));
    let e1 = d.dot(c.cross(a));
    let e2 = d.dot(a.cross(b));
    let all_pos = e0 >= R::ZERO && e1 >= R::ZERO && e2 >= R::ZERO;
    let all_neg = e0 <= R::ZERO && e1 <= R::ZERO && e2 <= R::ZERO;
    if !(all_pos || all_neg) {
        return None;
    }
    let n = v[1].sub(v[0]).cross(v[2].sub(v[0]));
    let denom = d.dot(n);
    if denom == R::ZERO {
        return None;
    }
    let t = a.dot(n) / denom;
    in_range(t, t_max).then(|| (t.wide(), n.wide().normalize_or_zero()))
}

/// Textbook convex polygon: plane through `v[0]`, then `p` on the inner side of every edge.
#[inline]
pub fn polygon_textbook<R: Real>(v: &[V<R>], ray: &RayR<R>, t_max: R) -> Answer {
    let n = v[1].sub(v[0]).cross(v[2].sub(v[0]));
    let denom = n.dot(ray.d);
    if denom == R::ZERO {
        return None;
    }
    let t = n.dot(v[0].sub(ray.o)) / denom;
    if !in_range(t, t_max) {
        return None;
    }
    let p = ray.at(t);
    for i in 0..v.len() {
        let (a, b) = (v[i], v[(i + 1) % v.len()]);
        if b.sub(a).cross(p.sub(a)).dot(n) < R::ZERO {
            return None;
        }
    }
    Some((t.wide(), n.wide().normalize_or_zero()))
}

/// Textbook slab box: reciprocal direction, `max` of the near planes, `min` of the far ones
/// (a zero direction component gives `0·∞ = NaN` on a face plane, as in the classic code).
#[inline]
pub fn box_textbook<R: Real>(lo: V<R>, hi: V<R>, ray: &RayR<R>, t_max: R) -> Answer {
    let mut t_near = -R::INF;
    let mut t_far = R::INF;
    let mut axis = 0;
    let mut sign = R::ZERO;
    for i in 0..3 {
        let inv = R::ONE / ray.d.get(i);
        let mut t0 = (lo.get(i) - ray.o.get(i)) * inv;
        let mut t1 = (hi.get(i) - ray.o.get(i)) * inv;
        let mut s = -R::ONE;
        if inv < R::ZERO {
            std::mem::swap(&mut t0, &mut t1);
            s = R::ONE;
        }
        if t0 > t_near {
            t_near = t0;
            axis = i;
            sign = s;
        }
        if t1 < t_far {
            t_far = t1;
        }
        if t_far < t_near {
            return None;
        }
    }
    if !in_range(t_near, t_max) {
        return None;
    }
    let mut n = DVec3::ZERO;
    n[axis] = sign.wide();
    Some((t_near.wide(), n))
}

/// f32 port of zeroset's robust box: division per axis, zero components skipped (inside the
/// slab constrains nothing, outside misses), the entry face tracked.
#[inline]
pub fn box_robust<R: Real>(lo: V<R>, hi: V<R>, ray: &RayR<R>, t_max: R) -> Answer {
    let (mut t_near, mut near_face) = (-R::INF, 0usize);
    let (mut t_far, mut far_face) = (R::INF, 0usize);
    for i in 0..3 {
        let (o, d) = (ray.o.get(i), ray.d.get(i));
        let (l, h) = (lo.get(i), hi.get(i));
        if d == R::ZERO {
            if !(l <= o && o <= h) {
                return None;
            }
            continue;
        }
        let (mut t0, mut f0, mut t1, mut f1) = ((l - o) / d, 2 * i, (h - o) / d, 2 * i + 1);
        if d < R::ZERO {
            std::mem::swap(&mut t0, &mut t1);
            std::mem::swap(&mut f0, &mut f1);
        }
        if t0 > t_near {
            (t_near, near_face) = (t0, f0);
        }
        if t1 < t_far {
            (t_far, far_face) = (t1, f1);
        }
    }
    if !(t_near <= t_far) {
        return None;
    }
    let (t, face) = if in_range(t_near, t_max) {
        (t_near, near_face)
    } else if in_range(t_far, t_max) {
        (t_far, far_face)
    } else {
        return None;
    };
    let mut n = DVec3::ZERO;
    n[face / 2] = if face % 2 == 1 { 1.0 } else { -1.0 };
    Some((t.wide(), n))
}

/// Textbook capped cylinder about +Y from `base`: side quadratic `b² − 4ac`, `0 ≤ y ≤ H`, caps.
#[inline]
pub fn cylinder_textbook<R: Real>(base: V<R>, r: R, h: R, ray: &RayR<R>, t_max: R) -> Answer {
    let o = ray.o.sub(base);
    let d = ray.d;
    let mut best = t_max;
    let mut normal = V(R::ZERO, R::ZERO, R::ZERO);
    let mut found = false;
    let a = d.0 * d.0 + d.2 * d.2;
    let b = R::of(2.0) * (o.0 * d.0 + o.2 * d.2);
    let c = o.0 * o.0 + o.2 * o.2 - r * r;
    let disc = b * b - R::of(4.0) * a * c;
    if disc >= R::ZERO && a != R::ZERO {
        let s = disc.sqrt();
        for t in [(-b - s) / (R::of(2.0) * a), (-b + s) / (R::of(2.0) * a)] {
            let y = o.1 + t * d.1;
            if t >= R::ZERO && t <= best && y >= R::ZERO && y <= h {
                best = t;
                normal = V(o.0 + t * d.0, R::ZERO, o.2 + t * d.2);
                found = true;
            }
        }
    }
    if d.1 != R::ZERO {
        for (plane, ny) in [(R::ZERO, -R::ONE), (h, R::ONE)] {
            let t = (plane - o.1) / d.1;
            let (x, z) = (o.0 + t * d.0, o.2 + t * d.2);
            if t >= R::ZERO && t <= best && x * x + z * z <= r * r {
                best = t;
                normal = V(R::ZERO, ny, R::ZERO);
                found = true;
            }
        }
    }
    found.then(|| (best.wide(), normal.wide().normalize_or_zero()))
}

/// Textbook capped pointed cone about +Y from `base` (radius `r` at the base, apex at height
/// `h`): `x² + z² = k²(h − y)²` by `b² − 4ac`, `0 ≤ y ≤ h`, and the base disk.
#[inline]
pub fn cone_textbook<R: Real>(base: V<R>, r: R, h: R, ray: &RayR<R>, t_max: R) -> Answer {
    let o = ray.o.sub(base);
    let d = ray.d;
    let k = r / h;
    let k2 = k * k;
    let mut best = t_max;
    let mut normal = V(R::ZERO, R::ZERO, R::ZERO);
    let mut found = false;
    let w = h - o.1;
    let a = d.0 * d.0 + d.2 * d.2 - k2 * d.1 * d.1;
    let b = R::of(2.0) * (o.0 * d.0 + o.2 * d.2 + k2 * w * d.1);
    let c = o.0 * o.0 + o.2 * o.2 - k2 * w * w;
    let disc = b * b - R::of(4.0) * a * c;
    if disc >= R::ZERO && a != R::ZERO {
        let s = disc.sqrt();
        for t in [(-b - s) / (R::of(2.0) * a), (-b + s) / (R::of(2.0) * a)] {
            let y = o.1 + t * d.1;
            if t >= R::ZERO && t <= best && y >= R::ZERO && y <= h {
                best = t;
                let (x, z) = (o.0 + t * d.0, o.2 + t * d.2);
                let rho = (x * x + z * z).sqrt();
                normal = V(h * x / rho, r, h * z / rho);
                found = true;
            }
        }
    }
    if d.1 != R::ZERO {
        let t = -o.1 / d.1;
        let (x, z) = (o.0 + t * d.0, o.2 + t * d.2);
        if t >= R::ZERO && t <= best && x * x + z * z <= r * r {
            best = t;
            normal = V(R::ZERO, -R::ONE, R::ZERO);
            found = true;
        }
    }
    found.then(|| (best.wide(), normal.wide().normalize_or_zero()))
}
