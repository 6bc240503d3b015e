#!/usr/bin/env python3
"""Reference distances from points to ellipsoids, for primitives/tests/closest.rs.

Writes ellipsoid_reference.csv beside this script: one row per (ellipsoid, scale, point) with
the f64 inputs exactly as Python prints them (shortest round-trip decimal) and the distance to
30 significant digits, computed with mpmath at 60 digits.

Method (independent of the kernel's bracketed bisection): every nearest point x of the
ellipsoid sum(x_i^2 / a_i) = 1 (a_i = e_i^2) to y = p - c is a stationary point of
|x - y|^2 on it: x_i (t + a_i) = a_i y_i for a Lagrange parameter t. Either t differs from
every -a_i, so x_i = a_i y_i / (t + a_i) and t is a real root of
F(t) = sum(a_i y_i^2 / (t + a_i)^2) = 1, or t = -a_k for an axis k with y_k = 0 and x_k free.
All real roots of F = 1 are found on every interval between the poles -a_i (y_i != 0): F is
monotone on the two outer intervals (one root each) and convex between two poles (its minimum
by bisection on F', then one root on each side if that minimum is below 1). Each family
t = -a_k gives x_i = a_i y_i / (a_i - a_k) on the other axes and x_k = e_k sqrt(rest) where
feasible. The distance is the smallest |x - y| over all these candidates.

Run: python3 make_ellipsoid_reference.py   (needs mpmath; about a minute)
"""

import os
import random

import mpmath
from mpmath import mpf

mpmath.mp.dps = 60
EPS_STOP = mpf(10) ** -56


def bisect(f, lo, hi):
    """A root of f in [lo, hi] with f(lo), f(hi) of opposite signs (or zero)."""
    flo = f(lo)
    for _ in range(400):
        mid = (lo + hi) / 2
        if abs(hi - lo) <= EPS_STOP * (1 + abs(mid)):
            break
        fm = f(mid)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return (lo + hi) / 2


def stationary_candidates(e, y):
    a = [ei * ei for ei in e]
    active = [i for i in range(3) if y[i] != 0]
    cands = []

    def point_at(t):
        return [a[i] * y[i] / (t + a[i]) if y[i] != 0 else mpf(0) for i in range(3)]

    if active:
        F = lambda t: sum(a[i] * y[i] ** 2 / (t + a[i]) ** 2 for i in active) - 1
        dF = lambda t: sum(-2 * a[i] * y[i] ** 2 / (t + a[i]) ** 3 for i in active)
        poles = sorted(set(-a[i] for i in active))
        roots = []
        # left of every pole: F rises from -1 to +inf
        p0 = poles[0]
        w = mpf(1)
        while F(p0 - w) > 0:
            w *= 2
        d = mpf(1)
        while F(p0 - d) <= 0:
            d /= 2
        roots.append(bisect(F, p0 - w, p0 - d))
        # right of every pole: F falls from +inf to -1
        p1 = poles[-1]
        w = mpf(1)
        while F(p1 + w) > 0:
            w *= 2
        d = mpf(1)
        while F(p1 + d) <= 0:
            d /= 2
        roots.append(bisect(F, p1 + d, p1 + w))
        # between poles: convex, minimum where F' = 0
        for lo, hi in zip(poles, poles[1:]):
            d = (hi - lo) / 4
            while dF(lo + d) >= 0:
                d /= 2
            l = lo + d
            d = (hi - lo) / 4
            while dF(hi - d) <= 0:
                d /= 2
            h = hi - d
            m = bisect(dF, l, h)
            if F(m) < 0:
                d = (m - lo) / 2
                while F(lo + d) <= 0:
                    d /= 2
                roots.append(bisect(F, lo + d, m))
                d = (hi - m) / 2
                while F(hi - d) <= 0:
                    d /= 2
                roots.append(bisect(F, m, hi - d))
        for t in roots:
            cands.append(point_at(t))
    # the families t = -a_k, y_k = 0
    for k in range(3):
        if y[k] != 0:
            continue
        x = [mpf(0)] * 3
        ok = True
        rest = mpf(1)
        for i in range(3):
            if i == k or y[i] == 0:
                continue
            if a[i] == a[k]:
                ok = False
                break
            x[i] = a[i] * y[i] / (a[i] - a[k])
            rest -= x[i] ** 2 / a[i]
        if ok and rest >= 0:
            x[k] = e[k] * mpmath.sqrt(rest)
            cands.append(x)
    return cands


def distance(e, y):
    best = None
    for x in stationary_candidates(e, y):
        g = sum(x[i] ** 2 / e[i] ** 2 for i in range(3))
        assert abs(g - 1) < mpf(10) ** -30, (e, y, x, g)
        d = mpmath.sqrt(sum((x[i] - y[i]) ** 2 for i in range(3)))
        if best is None or d < best:
            best = d
    return best


def points(rng, e):
    """Local offsets (as floats) for semi-axes e: random, inside, centre, axes, coordinate
    planes, the medial region of the plane of the two larger axes, near the surface."""
    big = max(e)
    out = []
    for _ in range(24):
        out.append([rng.uniform(-2.5 * big, 2.5 * big) for _ in range(3)])
    for _ in range(8):
        out.append([rng.uniform(-0.9, 0.9) * ei / 3 ** 0.5 for ei in e])
    out.append([0.0, 0.0, 0.0])
    for k in range(3):
        for f in (0.3, 0.999, 1.0, 1.7):
            v = [0.0, 0.0, 0.0]
            v[k] = f * e[k] * rng.choice((-1, 1))
            out.append(v)
    for k in range(3):
        for _ in range(3):
            v = [rng.uniform(-1.5, 1.5) * ei for ei in e]
            v[k] = 0.0
            out.append(v)
    # the medial region: in the plane of the two larger axes, close to the centre
    order = sorted(range(3), key=lambda i: -e[i])
    small = order[2]
    for _ in range(5):
        v = [0.0, 0.0, 0.0]
        for i in order[:2]:
            width = max(e[i] - e[small] ** 2 / e[i], 0.0)
            v[i] = rng.uniform(-0.7, 0.7) * width
        out.append(v)
    # next to an axis and next to the plane of the two larger axes (tiny nonzero coordinates)
    for k in range(3):
        for tiny in (1e-9, 1e-17):
            v = [rng.uniform(-1, 1) * tiny * ei for ei in e]
            v[k] = rng.choice((0.4, 1.3)) * e[k]
            out.append(v)
    for _ in range(3):
        v = [0.0, 0.0, 0.0]
        for i in order[:2]:
            width = max(e[i] - e[small] ** 2 / e[i], 0.0)
            v[i] = rng.uniform(-0.7, 0.7) * width
        v[small] = rng.choice((1e-9, 1e-17)) * e[small]
        out.append(v)
    # on the surface, up to the rounding of the construction
    for _ in range(6):
        while True:
            u = [rng.gauss(0, 1) for _ in range(3)]
            n = sum(c * c for c in u) ** 0.5
            if n > 1e-3:
                break
        out.append([e[i] * u[i] / n for i in range(3)])
    return out


def main():
    rng = random.Random(20240611)
    ellipsoids = [
        (3.0, 2.0, 1.0),
        (1.0, 3.0, 2.0),
        (2.0, 2.0, 1.0),
        (1.0, 1.0, 4.0),
        (1.0, 1.0, 1.0),
        (0.5, 100.0, 1.0),
    ]
    scales = (1e-3, 1.0, 1e5)
    rows = []
    for ei, radii in enumerate(ellipsoids):
        for scale in scales:
            e_f = [r * scale for r in radii]
            c_f = [0.5 * scale, -0.25 * scale, 0.125 * scale]
            for off in points(rng, radii):
                p_f = [c_f[i] + off[i] * scale for i in range(3)]
                e = [mpf(v) for v in e_f]
                y = [mpf(p_f[i]) - mpf(c_f[i]) for i in range(3)]
                d = distance(e, y)
                rows.append([ei, repr(scale)] + [repr(v) for v in e_f + c_f + p_f] + [mpmath.nstr(d, 30)])
    here = os.path.dirname(os.path.abspath(__file__))
    with open(os.path.join(here, "ellipsoid_reference.csv"), "w") as f:
        f.write("# generated by make_ellipsoid_reference.py; distances to 30 digits (mpmath, 60 digits)\n")
        f.write("ellipsoid,scale,rx,ry,rz,cx,cy,cz,px,py,pz,distance\n")
        for r in rows:
            f.write(",".join(str(v) for v in r) + "\n")
    print(f"{len(rows)} rows")


if __name__ == "__main__":
    main()
