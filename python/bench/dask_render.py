#!/usr/bin/env python3
"""A 3840×2160 frame rendered in one process and by zeroset.dask on a two-worker LocalCluster on
the same cores: wall times (medians), their ratio, bit-identity, and the peak RSS of the
single-process render (no copy of the output beyond the returned arrays). The frame reaches the
client two ways: `zeroset.dask.fetch` (each tile copied into the result as it finishes) and
`client.compute` (Dask's own finalize: the tiles joined on a worker, then sent whole).

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
    ap.add_argument("--runs", type=int, default=5)
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
    ref = scene.render(aovs=aovs, width=3840, height=2160)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # one frame, before any Dask
    out_bytes = sum(v.nbytes for v in ref.values())

    # each worker renders its tiles on one thread (zeroset.dask passes the worker's thread count
    # to the renderer): two workers use the same two cores
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)
    client = Client(cluster)
    tiled = zd.render(a.scene, chunks=tuple(a.chunks), aovs=aovs, width=3840, height=2160)
    def cpu_seconds():
        """CPU time of every process taking part: this one, the scheduler and the workers."""
        workers = client.run(time.process_time)
        return time.process_time() + client.run_on_scheduler(time.process_time) + sum(workers.values())

    single, fetch_times, compute_times = [], [], []
    single_cpu, fetch_cpu, compute_cpu = [], [], []
    # zd.fetch interleaved with the single-process render, so that a load that comes and goes
    # hits both alike; client.compute in rounds of its own after them: interleaved, each compute
    # left the scheduler (a thread of this process) releasing 81 tasks and 253 MB while the next
    # single render held both cores, and that clean-up ran into the fetch after it (its first tile
    # started 80–110 ms late rather than 20 ms)
    for _ in range(a.runs):
        ref = None  # the previous frame is freed before the next render
        c0, t0 = time.process_time(), time.perf_counter()
        ref = scene.render(aovs=aovs, width=3840, height=2160)
        single.append(time.perf_counter() - t0)
        single_cpu.append(time.process_time() - c0)
        c0, t0 = cpu_seconds(), time.perf_counter()
        got = zd.fetch(tiled, client)
        fetch_times.append(time.perf_counter() - t0)
        fetch_cpu.append(cpu_seconds() - c0)
        got = None
    for _ in range(a.runs):
        c0, t0 = cpu_seconds(), time.perf_counter()
        computed = client.compute(tiled, sync=True)
        compute_times.append(time.perf_counter() - t0)
        compute_cpu.append(cpu_seconds() - c0)
        computed = None
    got = zd.fetch(tiled, client)
    identical = all(np.array_equal(got[k], ref[k]) for k in ref)
    client.close()
    cluster.close()
    s, d, c = statistics.median(single), statistics.median(fetch_times), statistics.median(compute_times)
    print(f"scene {pathlib.Path(a.scene).name}, 3840x2160, AOVs {','.join(aovs)}, chunks {a.chunks}, medians of {a.runs}")
    print("| single process (2 threads) | dask 2x1: zd.fetch | ratio | dask 2x1: client.compute | ratio |"
          " bit-identical | peak RSS growth | output arrays |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| {s:.3f} s | {d:.3f} s | {d / s:.2f} | {c:.3f} s | {c / s:.2f} | {identical} | "
          f"{(rss1 - rss0) / 1024:.0f} MiB | {out_bytes / 2**20:.0f} MiB |")
    m = statistics.median
    print(f"CPU seconds (all processes, medians; robust to other load): single {m(single_cpu):.2f}, "
          f"fetch {m(fetch_cpu):.2f} ({m(fetch_cpu) / m(single_cpu):.2f}x), "
          f"client.compute {m(compute_cpu):.2f} ({m(compute_cpu) / m(single_cpu):.2f}x)")
    print("all runs (s): single", " ".join(f"{x:.3f}" for x in single), "| fetch",
          " ".join(f"{x:.3f}" for x in fetch_times), "| compute", " ".join(f"{x:.3f}" for x in compute_times))

if __name__ == "__main__":
    main()
