#!/usr/bin/env python3
"""zeroset.Scene.cast_rays beside Open3D's RaycastingScene.cast_rays on the benchmark meshes,
10⁶ random rays each (or, with --camera, each scene's camera rays from `rays_pinhole`, 1280×720
in pixel order), and the Python overhead against the Rust query path on the same batch.

    bash scenes/bench/make_meshes.sh            # the meshes (needs numpy, trimesh)
    pip install ./python open3d
    python3 python/bench/cast_rays.py [--rays 1000000] [--runs 5] [--threads 2] [--camera]

With --camera a last column times `Scene.render(aovs=["Depth", "Normal", "Alpha"])` of the same
camera (the render's own coherent path, its outputs written), and gives cast_rays ÷ render.

Prints one row per scene: Mrays/s medians of --runs (min–max in brackets) for zeroset's
cast_rays (float64 outputs, the default), the Rust API alone on the same rays, zeroset's
cast_rays with `dtype=np.float32` (the output dtype Open3D returns: half the bytes to write), and
Open3D cast_rays; the Python overhead; the ratios to Open3D (float64, float32); and the hit counts
(which must agree but for a few grazing rays).

What the overhead compares (the same N rays, same process, same thread pool, runs interleaved):
- Python: the wall time of `scene.cast_rays(origins, directions)` seen from Python
  (`time.perf_counter` around the call): float64 (N, 3) arrays in, the dict of every output
  array out — argument checks, building the rays, tracing, filling the arrays;
- Rust: `zeroset::query::trace_batch(&scene, &rays)` on the same rays already built as a
  `Vec<QueryRay>`, timed in Rust around that one call (`Scene._core.time_first_hits`), its
  `Vec<QueryHit>` (every hit record complete with normal and uv) returned.
Overhead = median(Python) / median(Rust) − 1, medians of --runs.
"""
import argparse
import os
import pathlib
import statistics
import time

import numpy as np

import zeroset

REPO = pathlib.Path(__file__).resolve().parents[2]


def timed(f, runs):
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        f()
        out.append(time.perf_counter() - t0)
    return out


def mrays(n, seconds):
    rates = [n / s / 1e6 for s in seconds]
    return statistics.median(rates), min(rates), max(rates)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--levels", type=int, nargs="+", default=[4, 6, 8])
    ap.add_argument("--camera", action="store_true",
                    help="each scene's camera rays (rays_pinhole, pixel order) instead of random rays")
    a = ap.parse_args()
    try:
        import open3d as o3d
    except ImportError:
        o3d = None
        print("open3d not installed: its column is empty")
    rng = np.random.default_rng(2026)
    origins = rng.uniform(-2.5, 2.5, (a.rays, 3))
    directions = rng.normal(size=(a.rays, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    kind = "camera rays (1280×720, pixel order)" if a.camera else f"{a.rays} random rays"
    print(f"{kind}, {a.threads} threads, medians of {a.runs} (Mrays/s)")
    extra = " render Depth, Normal, Alpha | cast_rays ÷ render time |" if a.camera else ""
    print("| scene | zeroset cast_rays | Rust trace_batch | zeroset cast_rays float32 | Open3D cast_rays | Python overhead "
          "| ratio to Open3D | float32 ratio to Open3D | hits zeroset / Open3D |" + extra)
    print("|---|---|---|---|---|---|---|---|---|" + ("---|---|" if a.camera else ""))
    for level in a.levels:
        path = REPO / "scenes" / "bench" / f"mesh{level}.ron"
        scene = zeroset.Scene.load(path)
        if a.camera:
            cam = scene.camera
            o, d = zeroset.rays_pinhole(cam.intrinsics(), cam.world_to_camera(), cam.width, cam.height)
            origins, directions = o.reshape(-1, 3), d.reshape(-1, 3)
        n = len(origins)
        scene.cast_rays(origins, directions)  # warm: the hierarchy, the thread pool, the pages
        scene.cast_rays(origins, directions, dtype=np.float32)
        z, rust, z32 = [], [], []
        for _ in range(a.runs):  # interleaved, so a load that comes and goes hits all alike
            z += timed(lambda: scene.cast_rays(origins, directions), 1)
            rust.append(scene._core.time_first_hits(origins, directions))
            z32 += timed(lambda: scene.cast_rays(origins, directions, dtype=np.float32), 1)
        hits = int(scene.cast_rays(origins, directions)["hit"].sum())
        row = [f"mesh{level}", "%.2f [%.2f–%.2f]" % mrays(n, z), "%.2f [%.2f–%.2f]" % mrays(n, rust),
               "%.2f [%.2f–%.2f]" % mrays(n, z32)]
        if o3d is not None:
            mesh = o3d.io.read_triangle_mesh(str(REPO / "scenes" / "bench" / "meshes" / f"mesh{level}.ply"))
            o_scene = o3d.t.geometry.RaycastingScene()
            o_scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                                  o3d.core.Tensor(np.asarray(mesh.triangles, np.uint32)))
            rays = o3d.core.Tensor(np.hstack([origins, directions]).astype(np.float32))
            o_scene.cast_rays(rays, nthreads=a.threads)
            o = timed(lambda: o_scene.cast_rays(rays, nthreads=a.threads), a.runs)
            o_hits = int(np.isfinite(o_scene.cast_rays(rays, nthreads=a.threads)["t_hit"].numpy()).sum())
            row.append("%.2f [%.2f–%.2f]" % mrays(n, o))
        else:
            o, o_hits = None, None
            row.append("–")
        overhead = statistics.median(z) / statistics.median(rust) - 1
        row.append(f"{overhead * 100:+.1f} %")
        row.append("–" if o is None else f"{statistics.median(o) / statistics.median(z):.2f}")
        row.append("–" if o is None else f"{statistics.median(o) / statistics.median(z32):.2f}")
        row.append(f"{hits} / {o_hits}")
        if a.camera:
            aovs = ["Depth", "Normal", "Alpha"]
            scene.render(aovs=aovs, threads=a.threads)
            r = []
            for _ in range(a.runs):  # interleaved with cast_rays again, for the ratio
                r += timed(lambda: scene.render(aovs=aovs, threads=a.threads), 1)
                z += timed(lambda: scene.cast_rays(origins, directions), 1)
            row.append("%.2f [%.2f–%.2f]" % mrays(n, r))
            row.append(f"{statistics.median(z) / statistics.median(r):.2f}")
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
