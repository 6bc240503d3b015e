#!/usr/bin/env python3
"""Converts the shared benchmark scenes (../../../shared/bench/*.json) to zeroset RON, exactly:
same camera, same primitives, same numbers (printed with repr, so every float round-trips).

A JSON `plane` with an `extent` is the square of half-size `extent` centred at `point`; it
becomes a `Polygon` with those four corners, counter-clockwise about the normal.

    python3 scenes/bench/convert.py [SHARED_BENCH_DIR]
"""
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def vec(v):
    return "(" + ", ".join(repr(float(x)) for x in v) + ")"


def basis(n):
    # right-handed (e1, e2, n), Duff et al. 2017
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    e1 = (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    e2 = (b, sign + n[1] * n[1] * a, -n[1])
    return e1, e2


def primitive(p):
    kind = p["type"]
    if kind == "sphere":
        return f"Sphere(center: {vec(p['center'])}, radius: {p['radius']!r})"
    if kind == "plane":
        n = p["normal"]
        length = math.sqrt(sum(x * x for x in n))
        n = [x / length for x in n]
        e1, e2 = basis(n)
        e = float(p["extent"])
        c = p["point"]
        corners = [
            [c[k] + su * e * e1[k] + sv * e * e2[k] for k in range(3)]
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))
        ]
        return "Polygon(points: [" + ", ".join(vec(q) for q in corners) + "])"
    if kind == "box":
        return f"Box(min: {vec(p['min'])}, max: {vec(p['max'])})"
    if kind == "cylinder":
        return (f"Cylinder(base: {vec(p['base'])}, axis: {vec(p['axis'])}, radius: {p['radius']!r}, "
                f"height: {p['height']!r}, capped: {str(p['capped']).lower()})")
    if kind == "ellipsoid":
        return f"Ellipsoid(center: {vec(p['center'])}, radii: {vec(p['radii'])})"
    if kind == "triangle":
        a, b, c = p["v"]
        return f"Triangle(a: {vec(a)}, b: {vec(b)}, c: {vec(c)})"
    raise SystemExit(f"unknown primitive type {kind!r}")


def camera(c):
    return (f"    camera: (\n        eye: {vec(c['eye'])},\n        look_at: {vec(c['look_at'])},\n"
            f"        up: {vec(c['up'])},\n        vfov_deg: {c['vfov_deg']!r},\n"
            f"        width: {c['width']},\n        height: {c['height']},\n    ),\n")


def convert(src, name):
    scene = json.load(open(src))
    out = [f"// {name}: converted from shared/bench/{os.path.basename(src)} by convert.py; do not edit.\n",
           "// Default outputs (beauty, A, Z, N); no lights, so a headlight shades it (no shadow rays).\n",
           "Scene(\n", camera(scene["camera"]), "    objects: [\n"]
    for p in scene.get("primitives", []):
        out.append(f"        (shape: {primitive(p)}),\n")
    out.append("    ],\n)\n")
    path = os.path.join(HERE, name + ".ron")
    open(path, "w").write("".join(out))
    print("wrote", path)


if __name__ == "__main__":
    shared = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "..", "..", "..", "shared", "bench")
    for name in ("spheres1k", "quadrics"):
        convert(os.path.join(shared, name + ".json"), name)
