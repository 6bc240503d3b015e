#!/usr/bin/env python3
"""A 3840×2160 frame rendered in one process and by zeroset.dask on a two-worker LocalCluster on
the same cores: wall times (medians), their ratio, bit-identity, and the peak RSS of the
single-process render (no copy of the output beyond the returned arrays).

    pip install ./python "dask[array]" distributed
    python3 python/bench/dask_render.py [--scene scenes/bench/quadrics.ron] [--runs 3]
"""
import argparse
import pathlib
import resource
import statistics
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=str(REPO / "scenes" / "bench" / "quadrics.ron"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--chunks", type=int, nargs=2, default=[540, 960])
    ap.add_argument("--aovs", default="Beauty,Alpha,Depth,Normal")
    a = ap.parse_args()
    aovs = a.aovs.split(",")
    import zeroset
    import zeroset.dask as zd
    from distributed import Client, LocalCluster

    scene = zeroset.Scene.load(a.scene)
    scene.render(aovs=aovs, width=8, height=8)  # load everything lazily loaded first
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    single = []
    for k in range(a.runs):
        ref = None  # the previous frame is freed before the next render (peak = one frame)
        t0 = time.perf_counter()
        ref = scene.render(aovs=aovs, width=3840, height=2160)
        single.append(time.perf_counter() - t0)
        if k == 0:
            rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out_bytes = sum(v.nbytes for v in ref.values())

    # each worker renders its tiles on one thread: two workers use the same two cores
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None,
                           env={"RAYON_NUM_THREADS": "1"})
    client = Client(cluster)
    tiled = zd.render(a.scene, chunks=tuple(a.chunks), aovs=aovs, width=3840, height=2160)
    dask_times = []
    for _ in range(a.runs):
        t0 = time.perf_counter()
        got = client.compute(tiled, sync=True)
        dask_times.append(time.perf_counter() - t0)
    identical = all(np.array_equal(got[k], ref[k]) for k in ref)
    client.close()
    cluster.close()
    s, d = statistics.median(single), statistics.median(dask_times)
    print(f"scene {pathlib.Path(a.scene).name}, 3840x2160, AOVs {','.join(aovs)}, chunks {a.chunks}")
    print("| single process (2 threads) | dask LocalCluster 2x1 | ratio | bit-identical | peak RSS growth | output arrays |")
    print("|---|---|---|---|---|---|")
    print(f"| {s:.3f} s | {d:.3f} s | {d / s:.2f} | {identical} | {(rss1 - rss0) / 1024:.0f} MiB | "
          f"{out_bytes / 2**20:.0f} MiB |")


if __name__ == "__main__":
    main()
