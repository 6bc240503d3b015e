#!/usr/bin/env python3
"""The random-ray batch through the mesh peers: Embree (embreex `EmbreeScene.run`, one
`rtcIntersect1` per ray in compiled code) and Open3D (`RaycastingScene.cast_rays`) on the same
float32 rays that `zeroset query` reads, for bench/throughput.py.

    python3 peer_batch.py embree|open3d MESH.ply RAYS.npy --runs 5 --threads 2

RAYS.npy: float64 (N, 6) `ox, oy, oz, dx, dy, dz`, every value a float32 (the driver rounds them),
so all systems trace the same rays. Prints one line `RESULT {json}`: build seconds (first query
included, as the anchor harnesses time it), Mrays/s per run at 1 and THREADS threads, and the hit
count. Run by the driver in its own process so that a peer that is missing or crashes is a
reported "n/a", never a crash of the driver.
"""
import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

ANCHORS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "anchors")


def load_ply(path, anchors):
    sys.path.insert(0, os.path.join(anchors, "embree"))
    from camera import load_ply as lp  # the anchors' own reader, so the peers see what they always see
    return lp(path)


def timed(fn, runs):
    fn()  # warm-up
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def embree(v, f, orgs, dirs, runs, threads):
    from concurrent.futures import ThreadPoolExecutor
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    t0 = time.perf_counter()
    sc = rtcs.EmbreeScene()
    TriangleMesh(sc, v, f.astype(np.int32))
    sc.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32), output=1)  # commit = BVH build
    build = time.perf_counter() - t0
    n = len(orgs)
    res = {"build_s": build, "rays": n}
    hits = int((sc.run(orgs, dirs, output=1)["primID"] >= 0).sum())
    res["hits"] = hits
    res["mrays_1t"] = [n / t / 1e6 for t in timed(lambda: sc.run(orgs, dirs, output=1), runs)]
    bounds = np.linspace(0, n, threads + 1).astype(int)
    parts = [(orgs[a:b], dirs[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
    with ThreadPoolExecutor(threads) as pool:
        def many():
            list(pool.map(lambda p: sc.run(p[0], p[1], output=1), parts))
        res[f"mrays_{threads}t"] = [n / t / 1e6 for t in timed(many, runs)]
    return res


def open3d(v, f, orgs, dirs, runs, threads):
    import open3d as o3d

    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    scene.cast_rays(o3d.core.Tensor(np.array([[0, 0, 0, 0, 0, 1]], np.float32)))  # forces the build
    build = time.perf_counter() - t0
    rays = o3d.core.Tensor(np.concatenate([orgs, dirs], axis=1).astype(np.float32))
    n = len(orgs)
    res = {"build_s": build, "rays": n}
    th = scene.cast_rays(rays, nthreads=threads)["t_hit"].numpy()
    res["hits"] = int(np.isfinite(th).sum())
    res["mrays_1t"] = [n / t / 1e6 for t in timed(lambda: scene.cast_rays(rays, nthreads=1), runs)]
    res[f"mrays_{threads}t"] = [n / t / 1e6 for t in timed(lambda: scene.cast_rays(rays, nthreads=threads), runs)]
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("peer", choices=["embree", "open3d"])
    ap.add_argument("mesh")
    ap.add_argument("rays")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--anchors", default=ANCHORS, help="the anchors directory (default ../shared/anchors)")
    a = ap.parse_args()
    v, f = load_ply(a.mesh, a.anchors)
    r = np.load(a.rays)
    if r.ndim != 2 or r.shape[1] != 6:
        raise SystemExit(f"{a.rays}: expected an (N, 6) array, got {r.shape}")
    orgs = np.ascontiguousarray(r[:, :3], dtype=np.float32)
    dirs = np.ascontiguousarray(r[:, 3:], dtype=np.float32)
    res = (embree if a.peer == "embree" else open3d)(v, f, orgs, dirs, a.runs, a.threads)
    for k in list(res):
        if k.startswith("mrays_"):
            res[k + "_median"] = statistics.median(res[k])
    res["peer"] = a.peer
    print("RESULT " + json.dumps(res))


if __name__ == "__main__":
    main()
