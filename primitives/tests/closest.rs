//! `Implicit::closest` of the analytic primitives against independent references.
//!
//! For every primitive, points at scales `10⁻³`, `1` and `10⁵` (the primitive and the points
//! scaled together): random points around it, points exactly on the surface (from its
//! parametric form), just off it, and the special places where the nearest point changes
//! branch or is not unique (the centre, points on an axis, points equidistant from two faces).
//! Each answer is checked against a distance computed a different way:
//!
//! | primitive | reference |
//! |-----------|-----------|
//! | sphere, cylinder, cone | golden-section minimisation of `|p − point(u*, v)|` over the profile parameter `v` of `Parametric::point`, piece by piece between the profile's corners, in the meridian `u*` of `p` |
//! | plane | the volume formula `|⟨A − p, (B − A)×(C − A)⟩| / |(B − A)×(C − A)|` for three points of the parametric form |
//! | disk | the plane distance where `p` projects inside, else a grid and golden search over the rim circle of the parametric form |
//! | triangle | the minimum over the face (normal equations of the Gram matrix, accepted where the barycentrics are `≥ 0`) and the three edges |
//! | polygon | the test's own frame and even-odd crossing count, then the plane distance or the nearest edge of any ring |
//! | box | the minimum over the six faces, each a rectangle |
//! | ellipsoid | `tests/data/ellipsoid_reference.csv`: 30-digit distances from `make_ellipsoid_reference.py` (mpmath, every stationary point of the Lagrange system); random points checked for stationarity |
//!
//! **Error measure.** `|d − d_ref| / max(d_ref, scale)`: relative error, with an absolute floor
//! of `scale` in the denominator for points nearer the surface than the primitive's size (on the
//! surface the distance is about 0 and only an absolute bound means anything). The bound is
//! `10⁻¹²` (ellipsoid: `|d − d_ref| ≤ max(10⁻¹⁰·d_ref, 10⁻¹²·scale)`).
//!
//! Also checked for every point: the answer is exact (`lower = upper = |p − q|`), `q` lies on
//! the surface (`|Φ(q)| ≤ 10⁻¹²·scale`, and within the boundary up to `10⁻¹²·scale`), the
//! feature names the part `q` lies on (box, cylinder, cone); and for a share of them, that no
//! point of a dense sample of the surface is nearer than the answer.
//!
//! `ZEROSET_CLOSEST_POINTS` sets the number of points per primitive (default 10⁴; the
//! measurements in the commit message used 10⁵ with `--release`).

use glam::{DQuat, DVec2, DVec3};
use zeroset_primitives::cone::{BOTTOM, SIDE, TOP};
use zeroset_primitives::math::orthonormal_basis;
use zeroset_primitives::*;

const SCALES: [f64; 3] = [1e-3, 1.0, 1e5];
const TOLERANCE: f64 = 1e-12;

/// splitmix64: a small seeded generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    fn vec(&mut self, half: f64) -> DVec3 {
        DVec3::new(
            self.range(-half, half),
            self.range(-half, half),
            self.range(-half, half),
        )
    }

    fn direction(&mut self) -> DVec3 {
        loop {
            let v = self.vec(1.0);
            if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    fn index(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn points_per_primitive() -> usize {
    std::env::var("ZEROSET_CLOSEST_POINTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000)
}

/// The largest error seen for one primitive, with where it happened.
struct Report {
    name: &'static str,
    worst: f64,
    at: String,
    count: usize,
    sampled: usize,
}

impl Report {
    fn new(name: &'static str) -> Self {
        Self {
            name,
            worst: 0.0,
            at: String::new(),
            count: 0,
            sampled: 0,
        }
    }

    fn record(&mut self, d: f64, d_ref: f64, scale: f64, context: impl Fn() -> String) {
        let err = (d - d_ref).abs() / d_ref.max(scale);
        assert!(
            err <= TOLERANCE,
            "{}: distance {d:e}, reference {d_ref:e}, error {err:e} at {}",
            self.name,
            context()
        );
        if err > self.worst || self.count == 0 {
            self.worst = self.worst.max(err);
            self.at = context();
        }
        self.count += 1;
    }

    fn print(&self) {
        println!(
            "{}: {} points ({} checked against the surface sample), largest error {:.3e} at {}",
            self.name, self.count, self.sampled, self.worst, self.at
        );
    }
}

/// Golden-section minimum of `f` on `[a, b]` (the smallest value evaluated, ends included).
fn golden_min(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut best = f(a).min(f(b));
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..90 {
        best = best.min(fc).min(fd);
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = f(d);
        }
        if b - a <= 1e-17 * (a.abs() + b.abs()) {
            break;
        }
    }
    best.min(fc).min(fd)
}

/// The minimum of `f` on `[a, b]` by a grid of `n` steps and a golden search around its best
/// point (for a function with one minimum on a circle, where the grid brackets it).
fn grid_golden_min(f: &impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let step = (b - a) / n as f64;
    let best_i = (0..=n)
        .min_by(|&i, &j| f(a + step * i as f64).total_cmp(&f(a + step * j as f64)))
        .unwrap();
    let x = a + step * best_i as f64;
    golden_min(f, x - step, x + step)
}

/// Reference for a surface of revolution: the distance from `p` to the profile curve
/// `v ↦ point(u*, v)` in `p`'s meridian `u*`, by golden search on each piece between `corners`
/// (on each the distance is unimodal: a segment of a line or a half circle).
fn meridian_reference<P: Parametric>(prim: &P, p: DVec3, corners: &[f64]) -> f64 {
    let u = prim.uv(p).x;
    let f = |v: f64| (prim.point(DVec2::new(u, v)) - p).length();
    let (lo, hi) = prim.domain().v;
    let mut cuts = vec![lo];
    cuts.extend(corners.iter().copied().filter(|&c| c > lo && c < hi));
    cuts.push(hi);
    cuts.windows(2)
        .map(|w| golden_min(&f, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

/// The distance from `p` to the segment `[a, b]`.
fn segment_distance(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (p - (a + t * ab)).length()
}

/// Whether `q` satisfies `within_boundary` up to `10⁻¹²·scale`: `q` itself or one of the 26
/// points `10⁻¹²·scale` or `10⁻¹³·scale` away along the directions of a cube's faces, edges and
/// corners.
fn within_up_to_rounding(prim: &dyn Implicit, q: DVec3, scale: f64) -> bool {
    if prim.within_boundary(q) {
        return true;
    }
    for step in [1e-13, 1e-12] {
        for i in -1..=1 {
            for j in -1..=1 {
                for k in -1..=1 {
                    let dir = DVec3::new(f64::from(i), f64::from(j), f64::from(k));
                    if dir != DVec3::ZERO && prim.within_boundary(q + dir.normalize() * step * scale) {
                        return true;
                    }
                }
            }
        }
    }
    false
}

/// Runs `closest` and the checks common to every primitive: exact, `q` on the surface; returns
/// `(d, q, feature)`.
fn closest_checked(prim: &dyn Implicit, p: DVec3, scale: f64, boundary: bool) -> (f64, DVec3, u32) {
    let c = prim.closest(p).expect("closed forms always answer");
    let q = c.point.expect("closed forms always give the point");
    assert!(c.is_exact() && c.lower == (p - q).length(), "{c:?} at {p}");
    let phi = prim.phi(q);
    assert!(phi.abs() <= 1e-12 * scale, "Φ(q) = {phi:e} at q = {q} for p = {p}");
    if boundary {
        assert!(
            within_up_to_rounding(prim, q, scale),
            "q = {q} outside the boundary, p = {p}"
        );
    }
    (c.distance(), q, c.feature)
}

/// The surface sample for the "nothing nearer" check: a `k × k` grid of the parametric
/// domain, less the points outside the boundary.
fn surface_sample<P: Parametric + Implicit>(prim: &P, k: usize) -> Vec<DVec3> {
    let d = prim.domain();
    let mut out = Vec::new();
    for i in 0..=k {
        for j in 0..=k {
            let u = d.u.0 + (d.u.1 - d.u.0) * i as f64 / k as f64;
            let v = d.v.0 + (d.v.1 - d.v.0) * j as f64 / k as f64;
            let q = prim.point(DVec2::new(u, v));
            if prim.within_boundary(q) {
                out.push(q);
            }
        }
    }
    out
}

/// No sample point is nearer to `p` than `d` (beyond `10⁻¹²·max(d, scale)`).
fn nothing_nearer(sample: &[DVec3], p: DVec3, d: f64, scale: f64) {
    let nearest = sample.iter().map(|s| (*s - p).length()).fold(f64::INFINITY, f64::min);
    assert!(
        nearest >= d - TOLERANCE * d.max(scale),
        "a sample point at {nearest:e} is nearer than the answer {d:e} from {p}"
    );
}

/// Query points for a primitive: `special` as given, then random points around `bounds`,
/// surface points and points just off the surface (from `sample_surface`), in that mix.
fn queries(
    rng: &mut Rng,
    n: usize,
    special: &[DVec3],
    center: DVec3,
    half: f64,
    sample_surface: &mut dyn FnMut(&mut Rng) -> DVec3,
) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = special.to_vec();
    while out.len() < n {
        let p = match rng.index(10) {
            0..=5 => center + rng.vec(2.0 * half),
            6 | 7 => sample_surface(rng),
            8 => sample_surface(rng) + rng.direction() * (half * 1e-6 * rng.unit()),
            _ => sample_surface(rng) + rng.direction() * (half * 0.3 * rng.unit()),
        };
        out.push(p);
    }
    out
}

/// A random parametric point of `prim` inside its boundary.
fn random_surface_point<P: Parametric + Implicit>(prim: &P, rng: &mut Rng) -> DVec3 {
    let d = prim.domain();
    loop {
        let q = prim.point(DVec2::new(rng.range(d.u.0, d.u.1), rng.range(d.v.0, d.v.1)));
        if prim.within_boundary(q) {
            return q;
        }
    }
}

/// Runs the checks on `prim` over `n` points: `reference(p)` is the independent distance,
/// `feature_ok(q, feature)` checks the feature; one point in `every` is also checked against
/// the surface sample.
#[allow(clippy::too_many_arguments)]
fn run<P: Parametric + Implicit>(
    report: &mut Report,
    prim: &P,
    scale: f64,
    n: usize,
    special: &[DVec3],
    seed: u64,
    reference: impl Fn(DVec3) -> f64,
    feature_ok: impl Fn(DVec3, u32) -> bool,
) {
    let mut rng = Rng(seed);
    let bounds = prim.bounds();
    let (center, half) = if bounds.min.is_finite() && bounds.max.is_finite() {
        (
            (bounds.min + bounds.max) / 2.0,
            (bounds.max - bounds.min).max_element() / 2.0,
        )
    } else {
        (DVec3::ZERO, 2.0 * scale)
    };
    let sample = surface_sample(prim, 60);
    let points = queries(&mut rng, n, special, center, half, &mut |rng| {
        random_surface_point(prim, rng)
    });
    let every = (n / 200).max(1);
    for (k, &p) in points.iter().enumerate() {
        let (d, q, feature) = closest_checked(prim, p, scale, true);
        assert!(feature_ok(q, feature), "feature {feature} for q = {q}, p = {p}");
        report.record(d, reference(p), scale, || format!("p = {p} (scale {scale:e})"));
        if k % every == 0 || k < special.len() {
            nothing_nearer(&sample, p, d, scale);
            report.sampled += 1;
        }
    }
}

#[test]
fn sphere() {
    let n = points_per_primitive() / 3;
    let mut report = Report::new("sphere");
    for (i, &s) in SCALES.iter().enumerate() {
        let (c, r) = (DVec3::new(0.3, -0.7, 0.2) * s, 1.3 * s);
        let sphere = Sphere::new(c, r).unwrap();
        let special = [
            c,
            c + DVec3::Y * r,
            c - DVec3::Y * r * 0.5,
            c + DVec3::X * 2.0 * r,
            c + DVec3::Z * 1e-9 * r,
            c + DVec3::new(1.0, 1.0, 1.0) * r,
        ];
        run(
            &mut report,
            &sphere,
            s,
            n,
            &special,
            100 + i as u64,
            |p| meridian_reference(&sphere, p, &[]),
            |_, f| f == 0,
        );
    }
    report.print();
}

#[test]
fn plane() {
    let n = points_per_primitive() / 3;
    let mut report = Report::new("plane");
    for (i, &s) in SCALES.iter().enumerate() {
        let plane = Plane::new(DVec3::new(0.3, -1.2, 0.5), 0.7 * s).unwrap();
        let on = plane.point(DVec2::new(0.4 * s, -0.9 * s));
        let special = [DVec3::ZERO, on, on + plane.normal() * s, on - plane.normal() * 1e-9 * s];
        // three points of the parametric form, a scale apart
        let a = plane.point(DVec2::ZERO);
        let b = plane.point(DVec2::new(s, 0.0));
        let c = plane.point(DVec2::new(0.0, s));
        let cross = (b - a).cross(c - a);
        // the surface sample: the parametric grid around the query box
        let plane_window = PlaneWindow(plane, s);
        run(
            &mut report,
            &plane_window,
            s,
            n,
            &special,
            200 + i as u64,
            |p| (a - p).dot(cross).abs() / cross.length(),
            |_, f| f == 0,
        );
    }
    report.print();
}

/// A plane with a finite parametric domain (`±3·scale`), for the surface sample and the
/// query box; everything else is the plane's.
struct PlaneWindow(Plane, f64);

impl Implicit for PlaneWindow {
    fn phi(&self, p: DVec3) -> f64 {
        self.0.phi(p)
    }
    fn bounds(&self) -> Aabb {
        Aabb::new(DVec3::splat(-2.0 * self.1), DVec3::splat(2.0 * self.1))
    }
    fn closest(&self, p: DVec3) -> Option<Closest> {
        self.0.closest(p)
    }
}

impl Parametric for PlaneWindow {
    fn domain(&self) -> UvDomain {
        UvDomain {
            u: (-4.0 * self.1, 4.0 * self.1),
            v: (-4.0 * self.1, 4.0 * self.1),
        }
    }
    fn point(&self, uv: DVec2) -> DVec3 {
        self.0.point(uv)
    }
    fn uv(&self, p: DVec3) -> DVec2 {
        self.0.uv(p)
    }
}

#[test]
fn disk() {
    let n = points_per_primitive() / 3;
    let mut report = Report::new("disk");
    for (i, &s) in SCALES.iter().enumerate() {
        let (c, r) = (DVec3::new(0.5, 0.25, -0.75) * s, 1.5 * s);
        let disk = Disk::new(c, DVec3::new(1.0, 2.0, -2.0), r).unwrap();
        let nrm = disk.normal();
        let (e1, _) = orthonormal_basis(nrm);
        let special = [
            c,
            c + nrm * s,
            c - nrm * 3.0 * s,
            c + e1 * r,
            c + e1 * 2.0 * r,
            c + e1 * r + nrm * s,
            c + e1 * 0.5 * r,
        ];
        let (a, b) = (disk.point(DVec2::new(r, 0.0)) - c, disk.point(DVec2::new(0.0, r)) - c);
        let normal = a.cross(b).normalize();
        let reference = |p: DVec3| {
            let h = (p - c).dot(normal);
            let w = (p - c) - h * normal;
            if w.length() <= r {
                h.abs()
            } else {
                let rim = |angle: f64| (disk.point(r * DVec2::from_angle(angle)) - p).length();
                grid_golden_min(&rim, 0.0, std::f64::consts::TAU, 64)
            }
        };
        run(&mut report, &disk, s, n, &special, 300 + i as u64, reference, |_, f| {
            f == 0
        });
    }
    report.print();
}

/// The triangle reference: the face (where the normal equations give barycentrics `≥ 0`) and
/// the three edges.
fn triangle_reference([a, b, c]: [DVec3; 3], p: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (g11, g12, g22) = (ab.dot(ab), ab.dot(ac), ac.dot(ac));
    let (r1, r2) = (ab.dot(ap), ac.dot(ap));
    let det = g11 * g22 - g12 * g12;
    let s = (r1 * g22 - r2 * g12) / det;
    let t = (g11 * r2 - g12 * r1) / det;
    let mut best = segment_distance(a, b, p)
        .min(segment_distance(b, c, p))
        .min(segment_distance(c, a, p));
    if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
        best = best.min((p - (a + s * ab + t * ac)).length());
    }
    best
}

#[test]
fn triangle() {
    let n = points_per_primitive() / 6;
    let mut report = Report::new("triangle");
    for (i, &s) in SCALES.iter().enumerate() {
        let shapes = [
            [
                DVec3::new(0.1, 0.2, 0.3),
                DVec3::new(1.7, -0.4, 0.9),
                DVec3::new(-0.3, 1.1, -0.6),
            ],
            // obtuse and long
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(3.0, 0.1, 0.2),
                DVec3::new(1.6, 0.3, -0.1),
            ],
        ];
        for (k, shape) in shapes.into_iter().enumerate() {
            let v = shape.map(|x| x * s);
            let tri = Triangle::new(v[0], v[1], v[2]).unwrap();
            let centroid = (v[0] + v[1] + v[2]) / 3.0;
            let nrm = tri.normal();
            let special = [
                v[0],
                v[1],
                v[2],
                (v[0] + v[1]) / 2.0,
                centroid,
                centroid + nrm * s,
                centroid - nrm * 1e-9 * s,
                // beyond a vertex along its bisector (equidistant from two edges' lines)
                v[0] + ((v[0] - v[1]).normalize() + (v[0] - v[2]).normalize()) * s,
                (v[1] + v[2]) / 2.0 + ((v[1] + v[2]) / 2.0 - v[0]) * 0.5,
            ];
            run(
                &mut report,
                &tri,
                s,
                n,
                &special,
                400 + (3 * k + i) as u64,
                |p| triangle_reference(v, p),
                |_, f| f == 0,
            );
        }
    }
    report.print();
}

#[test]
fn degenerate_triangle_closest_is_on_its_segment() {
    let tri = Triangle::new(DVec3::ZERO, DVec3::new(1.0, 2.0, 2.0), DVec3::new(2.0, 4.0, 4.0)).unwrap();
    assert!(tri.is_degenerate());
    let mut rng = Rng(7);
    for _ in 0..1000 {
        let p = rng.vec(5.0);
        let c = tri.closest(p).unwrap();
        let reference = segment_distance(DVec3::ZERO, DVec3::new(2.0, 4.0, 4.0), p);
        assert!((c.distance() - reference).abs() <= 1e-14 * reference.max(1.0));
        assert!(tri.phi(c.point.unwrap()).abs() < 1e-15);
    }
}

/// A polygon built by the test from 2-D rings in its own frame `(o, u, w)`, with its own
/// inside test and edge distances for the reference.
struct PolygonCase {
    polygon: Polygon,
    rings: Vec<Vec<DVec2>>,
    origin: DVec3,
    u: DVec3,
    w: DVec3,
}

impl PolygonCase {
    fn new(rings: Vec<Vec<DVec2>>, origin: DVec3, normal: DVec3) -> Self {
        let (u, w) = orthonormal_basis(normal.normalize());
        let to_3d = |q: &DVec2| origin + q.x * u + q.y * w;
        let points = rings[0].iter().map(to_3d).collect();
        let holes = rings[1..].iter().map(|r| r.iter().map(to_3d).collect()).collect();
        Self {
            polygon: Polygon::new(points, holes).unwrap(),
            rings,
            origin,
            u,
            w,
        }
    }

    /// Even-odd crossing count of a horizontal ray to +x, over every ring.
    fn inside(&self, q: DVec2) -> bool {
        let mut inside = false;
        for ring in &self.rings {
            for (i, &a) in ring.iter().enumerate() {
                let b = ring[(i + 1) % ring.len()];
                if (a.y > q.y) != (b.y > q.y) {
                    let x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
                    if x > q.x {
                        inside = !inside;
                    }
                }
            }
        }
        inside
    }

    fn reference(&self, p: DVec3) -> f64 {
        let n = self.u.cross(self.w);
        let rel = p - self.origin;
        let (q, h) = (DVec2::new(rel.dot(self.u), rel.dot(self.w)), rel.dot(n));
        if self.inside(q) {
            return h.abs();
        }
        let mut best = f64::INFINITY;
        for ring in &self.rings {
            for (i, &a) in ring.iter().enumerate() {
                let b = ring[(i + 1) % ring.len()];
                let d = segment_distance(a.extend(0.0), b.extend(0.0), q.extend(0.0));
                best = best.min(d);
            }
        }
        h.hypot(best)
    }
}

#[test]
fn polygon() {
    let n = points_per_primitive() / 9;
    let mut report = Report::new("polygon");
    let v = |pts: &[(f64, f64)], s: f64| pts.iter().map(|&(x, y)| DVec2::new(x, y) * s).collect::<Vec<_>>();
    for (i, &s) in SCALES.iter().enumerate() {
        let hexagon: Vec<DVec2> = (0..6)
            .map(|k| DVec2::from_angle(0.2 + f64::from(k) * std::f64::consts::TAU / 6.0) * 1.4 * s)
            .collect();
        let cases = [
            // convex
            (vec![hexagon], DVec3::new(0.2, 0.4, 1.0)),
            // concave (an L) with a hole
            (
                vec![
                    v(
                        &[(0.0, 0.0), (2.0, 0.0), (2.0, 0.5), (0.5, 0.5), (0.5, 2.0), (0.0, 2.0)],
                        s,
                    ),
                    v(&[(0.1, 1.0), (0.1, 1.5), (0.3, 1.5), (0.3, 1.0)], s),
                ],
                DVec3::Z,
            ),
            // a concave star with two holes, tilted
            (
                vec![
                    (0..10)
                        .map(|k| {
                            let radius = if k % 2 == 0 { 2.0 } else { 0.9 };
                            DVec2::from_angle(f64::from(k) * std::f64::consts::TAU / 10.0) * radius * s
                        })
                        .collect(),
                    v(&[(-0.3, -0.2), (0.3, -0.2), (0.0, 0.3)], s),
                    v(&[(1.2, 0.1), (1.5, 0.1), (1.5, 0.4), (1.2, 0.4)], s),
                ],
                DVec3::new(-0.5, 0.8, 0.3),
            ),
        ];
        for (k, (rings, normal)) in cases.into_iter().enumerate() {
            let case = PolygonCase::new(rings, DVec3::new(0.3, -0.2, 0.1) * s, normal);
            let nrm = case.polygon.normal();
            let to_3d = |q: DVec2| case.origin + q.x * case.u + q.y * case.w;
            let mut special = vec![case.origin + nrm * s];
            for ring in &case.rings {
                for (j, &a) in ring.iter().enumerate() {
                    let b = ring[(j + 1) % ring.len()];
                    special.push(to_3d(a));
                    special.push(to_3d((a + b) / 2.0) + nrm * 0.1 * s);
                }
                // the ring's centre (inside a hole: equidistant from several edges)
                let centre = ring.iter().copied().sum::<DVec2>() / ring.len() as f64;
                special.push(to_3d(centre));
                special.push(to_3d(centre) - nrm * 0.2 * s);
            }
            run(
                &mut report,
                &case.polygon,
                s,
                n,
                &special,
                500 + (3 * k + i) as u64,
                |p| case.reference(p),
                |_, f| f == 0,
            );
        }
    }
    report.print();
}

#[test]
fn cuboid() {
    let n = points_per_primitive() / 6;
    let mut report = Report::new("box");
    for (i, &s) in SCALES.iter().enumerate() {
        for (k, (lo, hi)) in [
            (DVec3::new(-0.5, 0.25, -1.0), DVec3::new(1.5, 1.0, 0.75)),
            (DVec3::splat(-1.0), DVec3::splat(1.0)),
        ]
        .into_iter()
        .enumerate()
        {
            let (lo, hi) = (lo * s, hi * s);
            let cuboid = Cuboid::new(lo, hi).unwrap();
            let c = (lo + hi) / 2.0;
            let mut special = vec![c, lo, hi, DVec3::new(lo.x, c.y, c.z), DVec3::new(hi.x, hi.y, c.z)];
            // inside, equidistant from two faces (a medial plane), and outside beyond an edge
            let m = (hi - lo).min_element() / 2.0;
            special.push(DVec3::new(lo.x + 0.3 * m, lo.y + 0.3 * m, c.z));
            special.push(DVec3::new(hi.x - 0.1 * m, c.y, hi.z - 0.1 * m));
            special.push(DVec3::new(hi.x + m, hi.y + m, c.z));
            special.push(hi + DVec3::splat(m));
            let reference = |p: DVec3| {
                let mut best = f64::INFINITY;
                for axis in 0..3 {
                    for bound in [lo[axis], hi[axis]] {
                        let mut d2 = (p[axis] - bound).powi(2);
                        for j in (0..3).filter(|&j| j != axis) {
                            let out = (lo[j] - p[j]).max(p[j] - hi[j]).max(0.0);
                            d2 += out * out;
                        }
                        best = best.min(d2.sqrt());
                    }
                }
                best
            };
            let feature_ok = |q: DVec3, f: u32| {
                let axis = (f / 2) as usize;
                f < 6 && q[axis] == if f % 2 == 1 { hi[axis] } else { lo[axis] }
            };
            run(
                &mut report,
                &cuboid,
                s,
                n,
                &special,
                600 + (3 * k + i) as u64,
                reference,
                feature_ok,
            );
        }
    }
    report.print();
}

/// Whether `q` lies on part `feature` of the cone or cylinder `(base, axis, r₀, r₁, H)`.
fn cone_feature_ok(cone: &Cone, q: DVec3, feature: u32, scale: f64) -> bool {
    let (r0, r1) = cone.radii();
    let h = (q - cone.base()).dot(cone.axis());
    let rho = ((q - cone.base()) - h * cone.axis()).length();
    let tol = 1e-12 * scale;
    match feature {
        BOTTOM => h.abs() <= tol && rho <= r0 + tol,
        TOP => (h - cone.height()).abs() <= tol && rho <= r1 + tol,
        SIDE => {
            let (a, b) = (DVec3::new(r0, 0.0, 0.0), DVec3::new(r1, cone.height(), 0.0));
            segment_distance(a, b, DVec3::new(rho, h, 0.0)) <= tol
        }
        _ => false,
    }
}

/// Special points of a cone or cylinder: on the axis (inside and beyond both ends), the rims,
/// and points equidistant from the side and a cap.
fn cone_special(base: DVec3, axis: DVec3, r0: f64, r1: f64, height: f64) -> Vec<DVec3> {
    let (e1, _) = orthonormal_basis(axis);
    let mut out = vec![];
    for h in [-0.5, 0.0, 0.25, 0.5, 1.0, 1.5] {
        out.push(base + axis * h * height);
    }
    out.push(base + e1 * r0);
    out.push(base + axis * height + e1 * r1);
    out.push(base + e1 * r0 * 1.5 - axis * 0.5 * height);
    // on the bisector of the bottom rim's inner corner
    let corner = DVec2::new(r0, 0.0);
    let side = DVec2::new(r1 - r0, height).normalize();
    let bisector = (side + DVec2::new(-1.0, 0.0)).normalize();
    let m = corner + bisector * 0.2 * r0.max(r1);
    out.push(base + e1 * m.x.abs() + axis * m.y);
    out
}

#[test]
fn cylinder() {
    let n = points_per_primitive() / 6;
    let mut report = Report::new("cylinder");
    for (i, &s) in SCALES.iter().enumerate() {
        for capped in [true, false] {
            let (base, axis, r, h) = (
                DVec3::new(0.2, -0.4, 0.1) * s,
                DVec3::new(1.0, 2.0, 3.0),
                0.8 * s,
                1.6 * s,
            );
            let cyl = Cylinder::new(base, axis, r, h, capped).unwrap();
            let as_cone = Cone::new(base, axis, r, r, h, capped).unwrap();
            let special = cone_special(base, cyl.axis(), r, r, h);
            let corners: &[f64] = if capped { &[0.0, 1.0] } else { &[] };
            run(
                &mut report,
                &cyl,
                s,
                n,
                &special,
                700 + (3 * usize::from(capped) + i) as u64,
                |p| meridian_reference(&cyl, p, corners),
                |q, f| cone_feature_ok(&as_cone, q, f, s),
            );
        }
    }
    report.print();
}

#[test]
fn cone() {
    let n = points_per_primitive() / 24;
    let mut report = Report::new("cone");
    for (i, &s) in SCALES.iter().enumerate() {
        let shapes = [(1.0, 0.0), (0.0, 1.2), (1.5, 0.5), (0.4, 1.1)];
        for (k, (r0, r1)) in shapes.into_iter().enumerate() {
            for capped in [true, false] {
                let (base, axis, h) = (DVec3::new(-0.3, 0.5, 0.2) * s, DVec3::new(-1.0, 0.5, 2.0), 1.3 * s);
                let cone = Cone::new(base, axis, r0 * s, r1 * s, h, capped).unwrap();
                let special = cone_special(base, cone.axis(), r0 * s, r1 * s, h);
                let corners: &[f64] = if capped { &[0.0, 1.0] } else { &[] };
                run(
                    &mut report,
                    &cone,
                    s,
                    n,
                    &special,
                    800 + (10 * k + 3 * usize::from(capped) + i) as u64,
                    |p| meridian_reference(&cone, p, corners),
                    |q, f| cone_feature_ok(&cone, q, f, s),
                );
            }
        }
    }
    report.print();
}

/// The checked-in mpmath references (`tests/data/make_ellipsoid_reference.py`).
#[test]
fn ellipsoid_against_mpmath() {
    let csv = include_str!("data/ellipsoid_reference.csv");
    let mut worst = (0.0f64, String::new());
    let mut rows = 0;
    for line in csv
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("ellipsoid"))
    {
        let f: Vec<f64> = line.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
        let (scale, radii, center, p, d_ref) = (
            f[0],
            DVec3::new(f[1], f[2], f[3]),
            DVec3::new(f[4], f[5], f[6]),
            DVec3::new(f[7], f[8], f[9]),
            f[10],
        );
        let e = Ellipsoid::new(center, radii, DQuat::IDENTITY).unwrap();
        let (d, _, _) = closest_checked(&e, p, scale, true);
        let err = (d - d_ref).abs() / d_ref.max(1e-2 * scale);
        assert!(
            err <= 1e-10,
            "distance {d:e}, reference {d_ref:e}, error {err:e}: {line}"
        );
        if err > worst.0 {
            worst = (err, line.to_string());
        }
        rows += 1;
    }
    assert!(rows > 1000);
    println!(
        "ellipsoid (mpmath): {rows} points, largest error {:.3e} at {}",
        worst.0, worst.1
    );
}

/// Random points around rotated ellipsoids: `q` on the surface, `p − q` along the normal at
/// `q` (a stationary point), and nothing on a dense sample nearer.
#[test]
fn ellipsoid_stationary_and_nearest() {
    let n = points_per_primitive() / 12;
    let mut stationarity = 0.0f64;
    let mut report = Report::new("ellipsoid");
    for (i, &s) in SCALES.iter().enumerate() {
        let shapes = [
            DVec3::new(3.0, 2.0, 1.0),
            DVec3::new(1.0, 1.0, 2.5),
            DVec3::new(0.5, 1.5, 1.5),
            DVec3::new(40.0, 1.0, 0.5),
        ];
        for (k, radii) in shapes.into_iter().enumerate() {
            let q = DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 0.3 + k as f64);
            let center = DVec3::new(0.5, -0.25, 0.125) * s;
            let e = Ellipsoid::new(center, radii * s, q).unwrap();
            let rot = glam::DMat3::from_quat(e.orientation());
            let local_axes = [rot.x_axis, rot.y_axis, rot.z_axis];
            let mut special = vec![center];
            for (j, axis) in local_axes.iter().enumerate() {
                for f in [0.3, 1.0, 1.7] {
                    special.push(center + *axis * (f * radii[j] * s));
                }
            }
            let mut rng = Rng(900 + (4 * i + k) as u64);
            let sample = surface_sample(&e, 120);
            let points = queries(&mut rng, n, &special, center, radii.max_element() * s, &mut |rng| {
                random_surface_point(&e, rng)
            });
            let every = (n / 100).max(1);
            for (j, &p) in points.iter().enumerate() {
                let (d, q, _) = closest_checked(&e, p, s, true);
                // stationary: p − q ∥ ∇Φ(q), where p is off the surface
                if d > 1e-9 * s {
                    let normal = e.gradient(q).normalize();
                    let sine = (p - q).cross(normal).length() / d;
                    stationarity = stationarity.max(sine * d / d.max(s));
                    assert!(
                        sine * d <= 1e-10 * d.max(s),
                        "p − q not normal at q = {q}: p = {p}, sine {sine:e}"
                    );
                }
                if j % every == 0 || j < special.len() {
                    // the sample is coarse: its own spacing bounds how near it can come
                    nothing_nearer(&sample, p, d, s);
                    report.sampled += 1;
                }
                report.count += 1;
            }
        }
    }
    println!(
        "ellipsoid: {} points ({} against the sample), largest |(p − q) × n̂| / max(d, scale) {stationarity:.3e}",
        report.count, report.sampled
    );
}
