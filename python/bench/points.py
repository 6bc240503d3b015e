#!/usr/bin/env python3
"""Point queries beside the peers: zeroset's compute_distance, compute_signed_distance,
compute_occupancy and list_intersections against Open3D's RaycastingScene (and libigl's
signed_distance where libigl is installed) on the benchmark meshes, the same points and rays,
the same process and thread count, runs interleaved.

    bash scenes/bench/make_meshes.sh            # the meshes (needs numpy, trimesh)
    pip install ./python open3d libigl
    python3 python/bench/points.py [--levels 4 6 8] [--points 1000000] [--runs 5] [--threads 2]
                                   [--calls distance signed occupancy intersections libigl]

The points are ../shared/anchors/pointquery/bench_points.py's: 10⁶ uniform in [−1.5, 1.5]³
(numpy seed 7), rays from them in normal-distributed directions. Prints a markdown table: per
mesh and call, the medians of --runs in Mpoints/s (Mrays/s for list_intersections), the ratio
zeroset ÷ peer, and how many answers differ (signs for signed distance and occupancy; crossing
counts for list_intersections; distances beyond 10⁻⁵ relative). libigl runs on the first
200,000 points (it is slow), its rate compared with zeroset's on the same points.
"""
import argparse
import os
import pathlib
import statistics
import sys
import time

ap = argparse.ArgumentParser()
ap.add_argument("--levels", nargs="*", type=int, default=[4, 6, 8])
ap.add_argument("--points", type=int, default=1_000_000)
ap.add_argument("--runs", type=int, default=5)
ap.add_argument("--threads", type=int, default=2)
ap.add_argument("--igl-points", type=int, default=200_000)
CALLS = ["distance", "signed", "occupancy", "intersections", "libigl"]
ap.add_argument("--calls", nargs="*", choices=CALLS, default=CALLS,
                help="which calls to time (default: all)")
args = ap.parse_args()
os.environ["RAYON_NUM_THREADS"] = str(args.threads)
os.environ.setdefault("OMP_NUM_THREADS", str(args.threads))

import numpy as np  # noqa: E402

import zeroset  # noqa: E402

try:
    import open3d as o3d
except ImportError:
    sys.exit("needs open3d (pip install open3d)")
try:
    import igl
except ImportError:
    igl = None

REPO = pathlib.Path(__file__).resolve().parents[2]


def medians(calls, runs):
    """Median seconds of each call, the calls interleaved run by run; the last results."""
    times = [[] for _ in calls]
    results = [None] * len(calls)
    for i, f in enumerate(calls):
        results[i] = f()  # warm-up (lazy structures)
    for _ in range(runs):
        for i, f in enumerate(calls):
            t0 = time.perf_counter()
            results[i] = f()
            times[i].append(time.perf_counter() - t0)
    return [statistics.median(t) for t in times], results


rng = np.random.default_rng(7)
P = rng.uniform(-1.5, 1.5, size=(args.points, 3))
P32 = P.astype(np.float32)
D32 = rng.normal(size=(args.points, 3)).astype(np.float32)
rows = []
for level in args.levels:
    path = REPO / "scenes" / "bench" / "meshes" / f"mesh{level}.ply"
    scene = zeroset.Scene.from_ron(f'Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0)), '
                                   f'objects: [(shape: Mesh(path: "{path}"))])')
    import trimesh

    mesh = trimesh.load(path, process=False)
    V = np.asarray(mesh.vertices, np.float64)
    F = np.asarray(mesh.faces, np.int64)
    o3 = o3d.t.geometry.RaycastingScene(nthreads=args.threads)
    o3.add_triangles(o3d.core.Tensor(V.astype(np.float32)), o3d.core.Tensor(F.astype(np.uint32)))
    q = o3d.core.Tensor(P32)
    P64 = P32.astype(np.float64)
    n = len(P)
    if "distance" in args.calls:
        (tz, to), (dz, do) = medians([lambda: scene.compute_distance(P64),
                                      lambda: o3.compute_distance(q, nthreads=args.threads).numpy()], args.runs)
        off = int(np.sum(np.abs(dz - do) > 1e-5 * np.maximum(do, 1e-3)))
        rows.append((level, "compute_distance", n / tz / 1e6, n / to / 1e6, "Open3D", f"{off} beyond 1e-5"))
    if "signed" in args.calls:
        (tz, to), (sz, so) = medians([lambda: scene.compute_signed_distance(P64),
                                      lambda: o3.compute_signed_distance(q, nthreads=args.threads).numpy()],
                                     args.runs)
        rows.append((level, "compute_signed_distance", n / tz / 1e6, n / to / 1e6, "Open3D",
                     f"{int(np.sum(np.sign(sz) != np.sign(so)))} signs"))
    if "occupancy" in args.calls:
        (tz, to), (oz, oo) = medians([lambda: scene.compute_occupancy(P64),
                                      lambda: o3.compute_occupancy(q, nthreads=args.threads).numpy()], args.runs)
        rows.append((level, "compute_occupancy", n / tz / 1e6, n / to / 1e6, "Open3D",
                     f"{int(np.sum(oz != oo))} differ"))
    if "intersections" in args.calls:
        rays = o3d.core.Tensor(np.concatenate([P32, D32], 1))
        O64, D64 = P32.astype(np.float64), D32.astype(np.float64)
        (tz, to), (lz, lo) = medians([lambda: scene.list_intersections(O64, D64),
                                      lambda: o3.list_intersections(rays, nthreads=args.threads)], args.runs)
        counts_z = np.diff(lz["ray_splits"])
        counts_o = np.diff(lo["ray_splits"].numpy())
        rows.append((level, "list_intersections", n / tz / 1e6, n / to / 1e6, "Open3D",
                     f"{int(np.sum(counts_z != counts_o))} counts differ"))
    if igl is not None and level <= 6 and "libigl" in args.calls:
        m = min(args.igl_points, n)
        Pi = P64[:m].copy()
        for sign, label, igl_type in [("winding", "winding", igl.SIGNED_DISTANCE_TYPE_WINDING_NUMBER),
                                      ("pseudonormal", "pseudonormal", igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL),
                                      ("fast-winding", "fast winding", igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)]:
            if sign == "winding" and level > 4:
                continue
            runs = max(1, args.runs // 2)
            (tz, ti), (sz, si) = medians([lambda: scene.compute_signed_distance(Pi, sign=sign),
                                          lambda: igl.signed_distance(Pi, V, F, sign_type=igl_type)[0]], runs)
            rows.append((level, f"signed distance, {label}", m / tz / 1e6, m / ti / 1e6, "libigl",
                         f"{int(np.sum(np.sign(sz) != np.sign(si)))} signs"))

print(f"| mesh | call | zeroset | peer | ratio | peer | answers |")
print("|---|---|---|---|---|---|---|")
for level, call, z, p, peer, note in rows:
    print(f"| mesh{level} | {call} | {z:.2f} | {p:.3f} | {z / p:.1f}× | {peer} | {note} |")
