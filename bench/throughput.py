#!/usr/bin/env python3
"""Throughput beside the peers (issue #11): one command that times zeroset and the reference
systems of ../shared/anchors/ in one run, on the same 1280×720 pixel-centre rays, and prints one
markdown table with zeroset's ratios and the issue's floors (PASS / FAIL / n/a).

    python3 bench/throughput.py [--runs 5] [--threads 2] [--zeroset PATH] [--scenes ...] [--json FILE]

What it runs (medians of --runs runs each, --threads threads, 1 thread for the scaling row):
- zeroset (`target/release/zeroset`, built here with `cargo build --release` unless --zeroset is
  given): the AOV render `render SCENE --aov Depth,Normal,Alpha --no-previews -t T`, the Depth-only
  render, the default render (the scene's own AOVs, beauty included) and the AOV render on 1
  thread, runs interleaved so that a change in machine load hits all alike; the figure is the trace
  time zeroset prints (`trace 0.296 s (3.11 Mrays/s)`). A 1×1 render times loading alone
  (`load+BVH`, PLY reading included) and its peak RSS. `zeroset query` on 10^6 random rays per
  scene (fixed seed, written to a .npy), end to end and less the loading time of the 1×1 render.
- Mitsuba 3 LLVM (`run_mitsuba.py render` and `rays`) on quadrics, spheres1k and mesh8, with
  Dr.Jit's pool set to T threads and libLLVM 19 (found through --libllvm, $DRJIT_LIBLLVM_PATH, or
  fetched once with `apt-get download libllvm19` into bench-results/libllvm19/).
- Embree `rtcIntersect1` (embreex, `bench_embreex.py`, 2 Python threads) and Open3D `cast_rays`
  (`bench_open3d.py`) on mesh levels 4, 6, 8 with their BVH build times, and both on the random
  rays of the meshes (bench/throughput/peer_batch.py) beside `zeroset query`.
- `cargo bench --bench mesh -- 8` for zeroset's level-8 BVH build alone (`Mesh::new`) and its bytes
  per triangle (skip with --no-mesh-bench).

Child processes are pinned to T CPUs where the machine has more. A peer that is not installed or
fails is an "n/a" with its reason, never a crash. Raw results: --json FILE.
"""
import argparse
import datetime
import hashlib
import json
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(HERE, "throughput"))
import report as R  # noqa: E402
from report import NA, is_num, median  # noqa: E402

SCENE_FILES = {
    "quadrics": "scenes/bench/quadrics.ron",
    "spheres1k": "scenes/bench/spheres1k.ron",
    "mesh4": "scenes/bench/mesh4.ron",
    "mesh6": "scenes/bench/mesh6.ron",
    "mesh8": "scenes/bench/mesh8.ron",
}
MESH_LEVEL = {"mesh4": 4, "mesh6": 6, "mesh8": 8}
# run_mitsuba.py's scene names (its `mesh` is /tmp/mesh8.ply)
MITSUBA_SCENE = {"quadrics": "quadrics", "spheres1k": "spheres1k", "mesh8": "mesh"}
# random query rays: origins uniform in this box, directions uniform on the sphere
RAY_BOXES = {
    "quadrics": ((-5.0, 0.05, -3.0), (5.0, 3.0, 4.0)),
    "spheres1k": ((-10.0, 0.05, -10.0), (10.0, 3.0, 10.0)),
    "mesh4": ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)),
    "mesh6": ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)),
    "mesh8": ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)),
}
SEED = 20261125
AOV = "Depth,Normal,Alpha"


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def tail(text, n=300):
    text = " ".join(text.strip().split())
    return text if len(text) <= n else "…" + text[-n:]


# ---------------------------------------------------------------------------------------------
# child processes
# ---------------------------------------------------------------------------------------------


class Proc:
    def __init__(self, rc, out, err, wall, maxrss, timed_out):
        self.rc, self.out, self.err, self.wall, self.maxrss, self.timed_out = rc, out, err, wall, maxrss, timed_out

    @property
    def text(self):
        return self.out + "\n" + self.err

    def failure(self, what):
        """NA describing why this run failed, or None if it succeeded."""
        if self.timed_out:
            return NA(f"{what}: timed out after {self.wall:.0f} s")
        if self.rc != 0:
            return NA(f"{what}: exit status {self.rc}: {tail(self.err or self.out)}")
        return None


class Runner:
    """Starts child processes pinned to `cpus` (None: not pinned) and returns their output, wall
    time and peak resident memory (os.wait4's ru_maxrss, this child alone)."""

    def __init__(self, cpus):
        self.cpus = cpus

    def run(self, cmd, cwd=ROOT, env=None, timeout=600, pin=True):
        cpus = self.cpus if pin else None

        def pre():
            if cpus:
                os.sched_setaffinity(0, cpus)

        with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe:
            t0 = time.perf_counter()
            try:
                p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=fo, stderr=fe, stdin=subprocess.DEVNULL,
                                     preexec_fn=pre, start_new_session=True)
            except OSError as e:
                return Proc(127, "", f"{cmd[0]}: {e}", 0.0, 0, False)
            fired = []

            def kill():
                fired.append(True)
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass

            timer = threading.Timer(timeout, kill)
            timer.start()
            try:
                _, status, ru = os.wait4(p.pid, 0)
            finally:
                timer.cancel()
            p.returncode = os.waitstatus_to_exitcode(status)
            wall = time.perf_counter() - t0
            fo.seek(0)
            fe.seek(0)
            out = fo.read().decode("utf-8", "replace")
            err = fe.read().decode("utf-8", "replace")
        return Proc(p.returncode, out, err, wall, ru.ru_maxrss * 1024, bool(fired))


# ---------------------------------------------------------------------------------------------
# setup: zeroset binary, meshes, rays
# ---------------------------------------------------------------------------------------------


def build_zeroset(runner):
    log("cargo build --release …")
    p = runner.run(["cargo", "build", "--release"], timeout=3600, pin=False)
    if p.rc != 0:
        raise SystemExit(f"error: `cargo build --release` in {ROOT} failed (exit {p.rc}):\n{p.err[-3000:]}")
    target = os.environ.get("CARGO_TARGET_DIR") or os.path.join(ROOT, "target")
    return os.path.join(target, "release", "zeroset")


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def ensure_meshes(runner, levels, shared):
    """zeroset's PLYs (scenes/bench/meshes/meshN.ply, made with ../shared/bench/gen.py where
    missing) and, for the peers' harnesses, which read /tmp/meshN.ply: True where that file holds
    the same bytes (a link to ours is made where it is absent), else an NA."""
    ours, peers = {}, {}
    mesh_dir = os.path.join(ROOT, "scenes", "bench", "meshes")
    os.makedirs(mesh_dir, exist_ok=True)
    for level in levels:
        path = os.path.join(mesh_dir, f"mesh{level}.ply")
        if not os.path.exists(path) or os.path.getsize(path) == 0:
            log(f"generating {path} (../shared/bench/gen.py, needs numpy and trimesh) …")
            p = runner.run([sys.executable, os.path.join(shared, "bench", "gen.py"), "--mesh", path, str(level)],
                           timeout=600, pin=False)
            if p.rc != 0 or not os.path.exists(path):
                reason = NA(f"mesh{level}.ply could not be generated: {tail(p.err or p.out)}")
                ours[level] = peers[level] = reason
                continue
        ours[level] = path
        tmp = f"/tmp/mesh{level}.ply"
        if not os.path.exists(tmp):
            if os.path.lexists(tmp):
                os.remove(tmp)  # a dangling link
            os.symlink(path, tmp)
        if sha256(tmp) == sha256(path):
            peers[level] = True
        else:
            peers[level] = NA(f"{tmp} (read by the peers' harnesses) differs from zeroset's {path}")
    return ours, peers


def write_rays(scenes, n, tmp, shared):
    """Random query rays per scene (.npy, float64 (n, 6) holding float32 values) and, for the
    meshes, the anchors' own 1280×720 camera rays; {scene: path} and the camera-ray path or NA."""
    import numpy as np

    out = {}
    for k, scene in enumerate(scenes):
        lo, hi = (np.array(b) for b in RAY_BOXES[scene])
        rng = np.random.default_rng(SEED + k * 7919 + sum(map(ord, scene)))
        o = lo + (hi - lo) * rng.random((n, 3))
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        rays = np.concatenate([o, d], axis=1).astype(np.float32).astype(np.float64)
        path = os.path.join(tmp, f"rays_{scene}.npy")
        np.save(path, rays)
        out[scene] = path
    cam = None
    if any(s in MESH_LEVEL for s in scenes):
        try:
            sys.path.insert(0, os.path.join(shared, "anchors", "embree"))
            import camera

            orgs, dirs, _, _ = camera.primary_rays(camera.load_camera("mesh"))
            cam = os.path.join(tmp, "camera_mesh.npy")
            np.save(cam, np.concatenate([orgs, dirs], axis=1).astype(np.float64))
        except Exception as e:  # noqa: BLE001 - any failure is reported, not fatal
            cam = NA(f"camera rays of ../shared/anchors/embree/camera.py: {e}")
    return out, cam


# ---------------------------------------------------------------------------------------------
# zeroset
# ---------------------------------------------------------------------------------------------


def zeroset_renders(runner, zs, scene, threads, runs, outdir, baseline):
    """Interleaved runs of the render configurations of one scene: {config: [parsed summaries]}
    or an NA per configuration that failed."""
    path = os.path.join(ROOT, SCENE_FILES[scene])
    configs = {
        "aov": [zs, "render", path, "--aov", AOV, "--no-previews", "-t", str(threads), "-o", outdir],
        "depth": [zs, "render", path, "--aov", "Depth", "--no-previews", "-t", str(threads), "-o", outdir],
        "default": [zs, "render", path, "--no-previews", "-t", str(threads), "-o", outdir],
        "aov_1t": [zs, "render", path, "--aov", AOV, "--no-previews", "-t", "1", "-o", outdir],
        "load": [zs, "render", path, "--width", "1", "--height", "1", "--aov", "Depth", "--no-previews",
                 "-t", str(threads), "-o", outdir],
    }
    if baseline:
        configs["baseline_default"] = [baseline, "render", path, "--no-previews", "-t", str(threads), "-o", outdir]
    res = {k: [] for k in configs}
    # warm-up: file cache, page faults of a first run
    runner.run(configs["aov"], timeout=600)
    for i in range(runs):
        for k, cmd in configs.items():
            if isinstance(res[k], NA):
                continue
            p = runner.run(cmd, timeout=600)
            bad = p.failure(f"zeroset {' '.join(cmd[1:3])} ({k})")
            if bad is None:
                try:
                    d = R.parse_render(p.out + "\n" + p.err)
                    d["maxrss"] = p.maxrss
                    d["process_wall_s"] = p.wall
                    res[k].append(d)
                    continue
                except ValueError as e:
                    bad = NA(f"zeroset render ({k}): {e}")
            res[k] = bad
        log(f"  {scene}: round {i + 1}/{runs}: " + ", ".join(_last(k, r) for k, r in res.items()))
    return res


def _last(k, r):
    if isinstance(r, NA) or not r:
        return f"{k} n/a"
    return f"load+BVH {r[-1]['load_s']:.3f} s" if k == "load" else f"{k} {r[-1]['mrays']:.2f} Mrays/s"


def zeroset_query(runner, zs, scene, rays, threads, runs, outdir, extra=()):
    return zeroset_queries(runner, zs, scene, rays, threads, runs, outdir, [extra])[0]


def zeroset_queries(runner, zs, scene, rays, threads, runs, outdir, variants):
    """`zeroset query` on `rays` with each of `variants` (extra flags), `runs` times each,
    interleaved run by run (as the renders are) so that a change in machine load hits every
    variant alike: per variant, the parsed runs or an NA."""
    path = os.path.join(ROOT, SCENE_FILES[scene])
    out = os.path.join(outdir, f"hits_{scene}.npy")
    got = [[] for _ in variants]
    for _ in range(runs):
        for k, extra in enumerate(variants):
            if isinstance(got[k], NA):
                continue
            cmd = [zs, "query", path, "--rays", rays, "-o", out, "-t", str(threads), *extra]
            p = runner.run(cmd, timeout=600)
            bad = p.failure(f"zeroset query {' '.join(extra)}".strip())
            if bad is not None:
                got[k] = bad
                continue
            try:
                d = R.parse_query(p.err + "\n" + p.out)
            except ValueError as e:
                got[k] = NA(f"zeroset query: {e}")
                continue
            d["process_wall_s"] = p.wall
            got[k].append(d)
    if os.path.exists(out):
        os.remove(out)
    return got


def summarize_query(runs_, load_s):
    """Median figures of the query runs; `mrays_less_load` subtracts the 1×1 render's median
    load+BVH time (the query's end-to-end time includes loading the scene)."""
    if isinstance(runs_, NA):
        return runs_
    s = {"rays": runs_[0]["rays"], "hits": runs_[0]["hits"],
         "e2e_s": median([r["e2e_s"] for r in runs_]),
         "e2e_mrays": median([r["e2e_mrays"] for r in runs_]),
         "runs": runs_}
    if all("trace_mrays" in r for r in runs_):
        s["trace_mrays"] = median([r["trace_mrays"] for r in runs_])
    if is_num(load_s):
        less = [r["e2e_s"] - load_s for r in runs_]
        if all(x > 0 for x in less):
            s["mrays_less_load"] = median([s["rays"] / x / 1e6 for x in less])
    return s


# ---------------------------------------------------------------------------------------------
# peers
# ---------------------------------------------------------------------------------------------


def python_has(runner, modules):
    p = runner.run([sys.executable, "-c", "import " + ", ".join(modules)], timeout=120, pin=False)
    return None if p.rc == 0 else NA(f"`import {', '.join(modules)}` fails ({tail(p.err, 160)}): "
                                     f"pip install {' '.join(modules)}")


def find_libllvm(runner, explicit):
    """libLLVM 19 for Mitsuba's llvm_ad_rgb (LLVM 15 aborts on meshes): --libllvm, then
    $DRJIT_LIBLLVM_PATH, then bench-results/libllvm19/ (fetched there with apt-get download and
    unpacked with dpkg-deb where missing). A path, or an NA with the reason."""
    if explicit:
        return explicit if os.path.exists(explicit) else NA(f"--libllvm {explicit}: no such file")
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env and os.path.exists(env):
        return env
    cache = os.path.join(ROOT, "bench-results", "libllvm19")
    found = [os.path.join(d, f) for d, _, fs in os.walk(cache) for f in fs if f == "libLLVM.so.19.1"]
    if found:
        return found[0]
    if not (shutil.which("apt-get") and shutil.which("dpkg-deb")):
        return NA("libLLVM 19 not found (give --libllvm PATH or set DRJIT_LIBLLVM_PATH); "
                  "apt-get/dpkg-deb not available to fetch it")
    os.makedirs(cache, exist_ok=True)
    log("fetching libLLVM 19 for Mitsuba (apt-get download libllvm19) …")
    p = runner.run(["apt-get", "download", "libllvm19"], cwd=cache, timeout=600, pin=False)
    debs = [f for f in os.listdir(cache) if f.startswith("libllvm19") and f.endswith(".deb")]
    if p.rc != 0 or not debs:
        return NA(f"libLLVM 19 not found and `apt-get download libllvm19` failed: {tail(p.err, 200)} "
                  "(give --libllvm PATH to a libLLVM.so.19.1)")
    p = runner.run(["dpkg-deb", "-x", debs[0], "root"], cwd=cache, timeout=600, pin=False)
    found = [os.path.join(d, f) for d, _, fs in os.walk(cache) for f in fs if f == "libLLVM.so.19.1"]
    if p.rc != 0 or not found:
        return NA(f"unpacking {debs[0]} gave no libLLVM.so.19.1: {tail(p.err, 200)}")
    return found[0]


def mitsuba(runner, scenes, threads, runs, shared, libllvm, peers_ok):
    """{scene: {"render": RESULT | NA, "rays": RESULT | NA}} from run_mitsuba.py (llvm_ad_rgb)."""
    harness = os.path.join(shared, "anchors", "mitsuba", "run_mitsuba.py")
    launcher = os.path.join(HERE, "throughput", "mitsuba_threads.py")
    out = {}
    missing = python_has(runner, ["mitsuba", "drjit", "numpy"])
    if missing is None and not os.path.exists(harness):
        missing = NA(f"{harness} not found")
    if missing is None and isinstance(libllvm, NA):
        missing = libllvm
    env = dict(os.environ)
    if not isinstance(libllvm, NA):
        env["DRJIT_LIBLLVM_PATH"] = libllvm
    for scene in scenes:
        if scene not in MITSUBA_SCENE:
            continue
        if missing is not None:
            out[scene] = {"render": missing, "rays": missing}
            continue
        level = MESH_LEVEL.get(scene)
        if level is not None and peers_ok.get(level) is not True:
            out[scene] = {"render": peers_ok.get(level), "rays": peers_ok.get(level)}
            continue
        out[scene] = {}
        for mode in ("rays", "render"):
            cmd = [sys.executable, launcher, str(threads), harness, mode, "--scene", MITSUBA_SCENE[scene],
                   "--variant", "llvm_ad_rgb", "--runs", str(runs)]
            if mode == "render":  # pixel-centre rays (stratified, no jitter), as every other figure
                cmd += ["--sampler", "center", "--exr", os.path.join(tempfile.gettempdir(), f"throughput_mitsuba_{scene}.exr")]
            log(f"Mitsuba 3 {mode} {scene} …")
            p = runner.run(cmd, cwd=os.path.dirname(harness), env=env, timeout=900)
            bad = p.failure(f"run_mitsuba.py {mode} --scene {MITSUBA_SCENE[scene]}")
            if bad is None:
                try:
                    out[scene][mode] = R.parse_result_line(p.out)
                    continue
                except ValueError as e:
                    bad = NA(f"run_mitsuba.py {mode}: {e}")
            out[scene][mode] = bad
    return out


def embree(runner, levels, runs, shared, tmp):
    if not levels:
        return {}
    missing = python_has(runner, ["embreex", "numpy"])
    if missing is not None:
        return missing
    js = os.path.join(tmp, "embree.json")
    log(f"Embree (bench_embreex.py --levels {' '.join(map(str, levels))}) …")
    p = runner.run([sys.executable, "bench_embreex.py", "--levels", *map(str, levels), "--runs", str(runs),
                    "--build-runs", str(runs), "--json", js], cwd=os.path.join(shared, "anchors", "embree"),
                   timeout=1200)
    bad = p.failure("bench_embreex.py")
    if bad is not None:
        return bad
    with open(js) as f:
        return {r["level"]: r for r in json.load(f)["levels"]}


def open3d(runner, levels, runs, shared):
    if not levels:
        return {}
    missing = python_has(runner, ["open3d", "numpy"])
    if missing is not None:
        return missing
    log(f"Open3D (bench_open3d.py --levels {' '.join(map(str, levels))}) …")
    p = runner.run([sys.executable, "bench_open3d.py", "--levels", *map(str, levels), "--runs", str(runs)],
                   cwd=os.path.join(shared, "anchors", "open3d"), timeout=1200)
    bad = p.failure("bench_open3d.py")
    if bad is not None:
        return bad
    got = R.parse_open3d(p.out)
    if not got:
        return NA(f"bench_open3d.py printed no 'level N: …' line: {tail(p.out)}")
    return got


def peer_batch(runner, peer, mesh, rays, runs, threads, shared):
    cmd = [sys.executable, os.path.join(HERE, "throughput", "peer_batch.py"), peer, mesh, rays, "--runs", str(runs),
           "--threads", str(threads), "--anchors", os.path.join(shared, "anchors")]
    p = runner.run(cmd, timeout=900)
    bad = p.failure(f"peer_batch.py {peer}")
    if bad is not None:
        return bad
    try:
        return R.parse_result_line(p.out)
    except ValueError as e:
        return NA(f"peer_batch.py {peer}: {e}")


def mesh_bench(runner):
    """zeroset's level-8 BVH build alone (Mesh::new on loaded arrays, 2 threads, median of 5) and
    bytes per triangle, from `cargo bench --bench mesh -- 8` (which also runs Embree's harness)."""
    log("cargo bench --bench mesh -- 8 (zeroset's BVH build alone and bytes per triangle) …")
    p = runner.run(["cargo", "bench", "--bench", "mesh", "--", "8"], timeout=3600, pin=False)
    bad = p.failure("cargo bench --bench mesh -- 8")
    if bad is not None:
        return bad
    for line in p.out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 4 and cells[0] == "8":
            try:
                return {"triangles": int(cells[1]), "build_s": float(cells[2]), "bytes_per_tri": float(cells[3]),
                        "row": line.strip()}
            except ValueError:
                break
    return NA(f"cargo bench --bench mesh printed no level-8 row: {tail(p.out)}")


# ---------------------------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------------------------


def machine():
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "")
    except OSError:
        pass
    return {"host": platform.node(), "cpu": cpu, "cpus": os.cpu_count(), "python": sys.version.split()[0],
            "loadavg_start": os.getloadavg()}


def med_of(runs_, key):
    if isinstance(runs_, NA):
        return runs_
    if not runs_:
        return NA("no run")
    return median([r[key] for r in runs_])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5, help="timed runs per figure, the median is reported (≥ 5 for the floors)")
    ap.add_argument("--threads", type=int, default=2, help="threads for every system (1 as well for the scaling row)")
    ap.add_argument("--zeroset", help="zeroset binary (default: `cargo build --release` here, target/release/zeroset)")
    ap.add_argument("--scenes", nargs="+", default=list(SCENE_FILES), choices=list(SCENE_FILES))
    ap.add_argument("--json", help="write the raw results here")
    ap.add_argument("--query-rays", type=int, default=1_000_000, help="random rays per scene for `zeroset query`")
    ap.add_argument("--baseline-zeroset", help="today's zeroset binary: its default render is timed beside ours "
                                               "for the '2× today's default render' floor")
    ap.add_argument("--query-single-flag", action="append", default=[],
                    help="argument(s) that make `zeroset query` take its single-ray path (repeat for several); "
                         "the sorted-batch floor is measured only when given")
    ap.add_argument("--query-batch-flag", action="append", default=[],
                    help="argument(s) that make `zeroset query` take its sorted-batch path (repeat for several), "
                         "e.g. --query-batch-flag=--ray-order=sorted; the default run uses them")
    ap.add_argument("--libllvm", help="libLLVM.so.19.1 for Mitsuba's llvm_ad_rgb")
    ap.add_argument("--shared", default=os.path.join(ROOT, "..", "shared"), help="the shared directory (anchors, bench)")
    ap.add_argument("--skip", nargs="*", default=[], choices=["mitsuba", "embree", "open3d", "query", "mesh-bench"],
                    help="leave these out (each is reported as n/a)")
    ap.add_argument("--no-pin", action="store_true", help="do not pin the timed processes to --threads CPUs")
    a = ap.parse_args()
    if a.runs < 1 or a.threads < 1 or a.query_rays < 1:
        ap.error("--runs, --threads and --query-rays must be at least 1")
    shared = os.path.abspath(a.shared)
    # the children run in the repository root: paths given relative to the caller's directory
    for k in ("baseline_zeroset", "libllvm"):
        if getattr(a, k):
            setattr(a, k, os.path.abspath(getattr(a, k)))
    if a.baseline_zeroset and not (os.path.isfile(a.baseline_zeroset) and os.access(a.baseline_zeroset, os.X_OK)):
        ap.error(f"--baseline-zeroset {a.baseline_zeroset}: not an executable file")
    started = time.perf_counter()
    meta = machine()
    meta.update({"date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                 "argv": sys.argv, "runs": a.runs, "threads": a.threads})
    if meta["loadavg_start"][0] > 0.5:
        log(f"note: load average {meta['loadavg_start'][0]:.2f} at the start: other work is running, so these "
            "figures show the script works, not how fast anything is")
    cpus = sorted(os.sched_getaffinity(0))
    pin = None if a.no_pin or len(cpus) <= a.threads else cpus[:a.threads]
    meta["pinned_cpus"] = pin
    runner = Runner(pin)

    zs = a.zeroset or build_zeroset(runner)
    if not (os.path.isfile(zs) and os.access(zs, os.X_OK)):
        raise SystemExit(f"error: zeroset binary {zs} not found or not executable")
    zs = os.path.abspath(zs)
    meta["zeroset"] = zs
    meta["zeroset_version"] = runner.run([zs, "--version"], pin=False).out.strip()
    git = runner.run(["git", "rev-parse", "HEAD"], pin=False)
    meta["git_head"] = git.out.strip() if git.rc == 0 else None

    levels = sorted({MESH_LEVEL[s] for s in a.scenes if s in MESH_LEVEL})
    mesh_paths, peers_ok = ensure_meshes(runner, levels, shared)
    tmp = tempfile.mkdtemp(prefix="zeroset-throughput-")
    raw = {"meta": meta, "zeroset": {}, "query": {}, "mitsuba": {}, "embree": {}, "open3d": {}, "batch": {}}
    try:
        rays, cam_rays = ({}, NA("--skip query"))
        if "query" not in a.skip:
            try:
                rays, cam_rays = write_rays(a.scenes, a.query_rays, tmp, shared)
            except ImportError as e:
                rays, cam_rays = {}, NA(f"numpy is needed for the query rays: {e}")
        outdir = os.path.join(tmp, "out")
        os.makedirs(outdir)

        # zeroset renders and queries
        for scene in a.scenes:
            if scene in MESH_LEVEL and isinstance(mesh_paths.get(MESH_LEVEL[scene]), NA):
                raw["zeroset"][scene] = {"error": mesh_paths[MESH_LEVEL[scene]]}
                continue
            log(f"zeroset {scene}: renders (AOV, Depth, default, AOV 1T, 1×1 load{', baseline' if a.baseline_zeroset else ''}) …")
            raw["zeroset"][scene] = zeroset_renders(runner, zs, scene, a.threads, a.runs, outdir, a.baseline_zeroset)
            load_s = med_of(raw["zeroset"][scene]["load"], "load_s")
            if scene in rays:
                log(f"zeroset {scene}: query on {a.query_rays} random rays …")
                # the batch path and the single-ray path interleaved run by run
                variants = [a.query_batch_flag] + ([a.query_single_flag] if a.query_single_flag else [])
                timed = zeroset_queries(runner, zs, scene, rays[scene], a.threads, a.runs, outdir, variants)
                q = {"random": summarize_query(timed[0], load_s)}
                if a.query_single_flag:
                    q["single"] = summarize_query(timed[1], load_s)
                if scene in MESH_LEVEL and not isinstance(cam_rays, NA):
                    q["camera"] = summarize_query(zeroset_query(runner, zs, scene, cam_rays, a.threads, 1, outdir), load_s)
                raw["query"][scene] = q

        # peers
        if "mitsuba" in a.skip:
            raw["mitsuba"] = {s: {"render": NA("--skip mitsuba"), "rays": NA("--skip mitsuba")} for s in a.scenes if s in MITSUBA_SCENE}
        elif any(s in MITSUBA_SCENE for s in a.scenes):
            libllvm = find_libllvm(runner, a.libllvm)
            meta["libllvm"] = libllvm
            raw["mitsuba"] = mitsuba(runner, a.scenes, a.threads, a.runs, shared, libllvm, peers_ok)
        ok_levels = [lv for lv in levels if peers_ok.get(lv) is True]
        raw["embree"] = NA("--skip embree") if "embree" in a.skip else embree(runner, ok_levels, a.runs, shared, tmp)
        raw["open3d"] = NA("--skip open3d") if "open3d" in a.skip else open3d(runner, ok_levels, a.runs, shared)
        for scene in a.scenes:
            lv = MESH_LEVEL.get(scene)
            if lv is None or scene not in rays:
                continue
            raw["batch"][scene] = {}
            for peer in ("embree", "open3d"):
                if peer in a.skip:
                    raw["batch"][scene][peer] = NA(f"--skip {peer}")
                elif peers_ok.get(lv) is not True:
                    raw["batch"][scene][peer] = peers_ok.get(lv)
                else:
                    log(f"{peer} batch on the {scene} random rays …")
                    raw["batch"][scene][peer] = peer_batch(runner, peer, mesh_paths[lv], rays[scene], a.runs, a.threads, shared)
        if "mesh8" in a.scenes:
            raw["mesh_bench"] = NA("--skip mesh-bench") if "mesh-bench" in a.skip else mesh_bench(runner)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    meta["loadavg_end"] = os.getloadavg()
    meta["elapsed_s"] = time.perf_counter() - started
    figs, extra = figures(raw, a)
    print_report(raw, figs, extra, a)
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        with open(a.json, "w") as f:
            json.dump(R.to_json({"raw": raw, "figures": figs, "extra": extra,
                                 "floors": R.floors(figs, extra, a.threads)}), f, indent=1)
        log(f"wrote {a.json}")


def figures(raw, a):
    """The per-scene Mrays/s figures of the table and the extra figures of the floors."""
    figs = {}
    emb, o3d = raw["embree"], raw["open3d"]
    for scene in a.scenes:
        z = raw["zeroset"].get(scene, {})
        f = {}
        if "error" in z:
            for k in ("zeroset_aov", "zeroset_depth", "zeroset_default", "zeroset_aov_1t"):
                f[k] = z["error"]
        else:
            f["zeroset_aov"] = med_of(z["aov"], "mrays")
            f["zeroset_depth"] = med_of(z["depth"], "mrays")
            f["zeroset_default"] = med_of(z["default"], "mrays")
            f["zeroset_aov_1t"] = med_of(z["aov_1t"], "mrays")
        if scene in MITSUBA_SCENE:
            m = raw["mitsuba"].get(scene, {})
            r, rd = m.get("rays", NA("not run")), m.get("render", NA("not run"))
            f["mitsuba_render"] = rd if isinstance(rd, NA) else rd["mrays_per_s_median"]
            f["mitsuba_rays"] = r if isinstance(r, NA) else r["ray_intersect_t_shnormal"]["mrays_per_s_median"]
            f["mitsuba_prelim"] = r if isinstance(r, NA) else r["ray_intersect_preliminary_t"]["mrays_per_s_median"]
        lv = MESH_LEVEL.get(scene)
        if lv is not None:
            for key, src, pick in (("embree", emb, lambda e: e["trace2_full_mrays"]["median"]),
                                   ("open3d", o3d, lambda e: e["mrays2"])):
                if isinstance(src, NA):
                    f[key] = src
                elif lv not in src:
                    f[key] = NA(f"level {lv} not run (mesh missing or differing)")
                elif a.threads != 2:
                    f[key] = NA("the anchor harness times 1 and 2 threads only")
                else:
                    f[key] = pick(src[lv])
        figs[scene] = f

    extra = {}
    if "mesh8" in a.scenes:
        mb = raw.get("mesh_bench", NA("not run"))
        z8 = raw["zeroset"].get("mesh8", {})
        extra["build"] = {
            "zeroset_bvh_s": mb if isinstance(mb, NA) else mb["build_s"],
            "zeroset_load_bvh_s": med_of(z8["load"], "load_s") if "load" in z8 else NA("zeroset mesh8 not run"),
            "embree_s": emb if isinstance(emb, NA) else (emb[8]["build_s"]["median"] if 8 in emb else NA("level 8 not run")),
            "open3d_s": o3d if isinstance(o3d, NA) else (o3d[8]["build_s"] if 8 in o3d else NA("level 8 not run")),
        }
        extra["bytes_per_tri"] = mb if isinstance(mb, NA) else mb["bytes_per_tri"]
        if "load" in z8 and not isinstance(z8["load"], NA) and "load" in raw["zeroset"].get("quadrics", {}) \
                and not isinstance(raw["zeroset"]["quadrics"]["load"], NA):
            rss8 = median([r["maxrss"] for r in z8["load"]])
            rss0 = median([r["maxrss"] for r in raw["zeroset"]["quadrics"]["load"]])
            extra["peak_rss_per_tri_above_quadrics"] = (rss8 - rss0) / 1_310_720
    if a.baseline_zeroset:
        extra["baseline_default"] = {s: med_of(raw["zeroset"][s]["baseline_default"], "mrays")
                                     for s in a.scenes if "baseline_default" in raw["zeroset"].get(s, {})}
    else:
        extra["baseline_default"] = NA("give --baseline-zeroset PATH (a build of today's zeroset) to time it in the same run")
    q = {}
    for scene in a.scenes:
        qq = raw["query"].get(scene)
        if qq is None:
            continue
        if not a.query_single_flag:
            q[scene] = NA("zeroset query has one path here; give --query-single-flag FLAG (the switch to its "
                          "single-ray path) to compare")
            continue
        sr, si = qq["random"], qq.get("single")
        if isinstance(sr, NA) or isinstance(si, NA):
            q[scene] = sr if isinstance(sr, NA) else si
            continue
        # the trace figure where zeroset prints one for both, else end to end less loading
        key = next(k for k in ("trace_mrays", "mrays_less_load", "e2e_mrays") if k in sr and k in si)
        q[scene] = {"sorted": sr[key], "single": si[key], "figure": key}
    extra["query"] = q
    hits = {}
    for scene in a.scenes:
        lv = MESH_LEVEL.get(scene)
        if lv is None or scene not in raw["query"]:
            continue
        cam = raw["query"][scene].get("camera", NA("camera rays not queried"))
        e = emb if isinstance(emb, NA) else (emb[lv]["hits"] if lv in emb else NA(f"level {lv} not run"))
        hits[scene] = {"zeroset": cam if isinstance(cam, NA) else cam["hits"], "embree": e}
    extra["hits"] = hits
    return figs, extra


def seconds(x):
    return f"n/a ({x.reason})" if isinstance(x, NA) else f"{R.fmt(x, 3)} s"


def print_report(raw, figs, extra, a):
    meta = raw["meta"]
    p = print
    p(f"## Throughput beside the peers ({meta['date_utc']}, {meta['cpu']}, {a.threads} threads, "
      f"1280×720 pixel-centre rays, Mrays/s, medians of {a.runs})")
    p()
    p(f"load average {meta['loadavg_start'][0]:.2f} at the start, {meta['loadavg_end'][0]:.2f} at the end; "
      f"{meta['elapsed_s']:.0f} s; {meta['zeroset_version']} ({meta.get('git_head') or 'no git'}); "
      f"pinned to CPUs {meta['pinned_cpus'] or 'all'}")
    p()
    p("In brackets: zeroset's ratio to that peer (AOV render against the AOV peers, Depth-only against "
      "`ray_intersect_preliminary`). zeroset's figures are the trace times it prints.")
    p()
    p(R.main_table(figs, a.threads))
    reasons = R.missing_reasons(figs)
    if reasons:
        p()
        p("\n".join(reasons))

    # query
    p()
    p(f"### `zeroset query` on {a.query_rays:,} random rays (origins in a box around the scene, uniform directions) "
      f"beside the peers' batch calls ({a.threads} threads)")
    p()
    p("| scene | zeroset query end to end | less loading (1×1 render's load+BVH) | zeroset trace figure | hits "
      "| Embree batch 1T / " + f"{a.threads}T | Open3D cast_rays 1T / {a.threads}T | Embree / Open3D hits | camera rays: zeroset / Embree / Open3D hits |")
    p("|---|---|---|---|---|---|---|---|---|")
    for scene in a.scenes:
        q = raw["query"].get(scene)
        if q is None:
            continue
        r = q["random"]
        b = raw["batch"].get(scene, {})

        def peer(x):
            if x is None:
                return "–"
            if isinstance(x, NA):
                return "n/a"
            return f"{x['mrays_1t_median']:.1f} / {x[f'mrays_{a.threads}t_median']:.1f}"

        def hits(x):
            return "–" if x is None else ("n/a" if isinstance(x, NA) else str(x["hits"]))

        cam = q.get("camera")
        lv = MESH_LEVEL.get(scene)
        emb_cam = raw["embree"][lv]["hits"] if lv and isinstance(raw["embree"], dict) and lv in raw["embree"] else None
        o3d_cam = raw["open3d"][lv]["hits"] if lv and isinstance(raw["open3d"], dict) and lv in raw["open3d"] else None
        cam_cell = "–"
        if lv is not None:
            cam_cell = f"{hits(cam)} / {emb_cam if emb_cam is not None else 'n/a'} / {o3d_cam if o3d_cam is not None else 'n/a'}"
        if isinstance(r, NA):
            p(f"| {scene} | n/a | | | | {peer(b.get('embree'))} | {peer(b.get('open3d'))} | | {cam_cell} |")
            continue
        p(f"| {scene} | {r['e2e_mrays']:.2f} | {R.fmt(r.get('mrays_less_load'), 2)} | {R.fmt(r.get('trace_mrays'), 2)} "
          f"| {r['hits']} | {peer(b.get('embree'))} | {peer(b.get('open3d'))} "
          f"| {hits(b.get('embree'))} / {hits(b.get('open3d'))} | {cam_cell} |")
    for scene in a.scenes:
        q = raw["query"].get(scene, {})
        for k, v in list(q.items()) + [(f"{pp} batch", raw["batch"].get(scene, {}).get(pp)) for pp in ("embree", "open3d")]:
            if isinstance(v, NA):
                p(f"- n/a {scene} {k}: {v.reason}")

    # build and memory
    if "build" in extra:
        b = extra["build"]
        p()
        p("### Level-8 mesh (1,310,720 triangles): build and memory")
        p()
        p(f"- zeroset BVH build alone (`Mesh::new`, `cargo bench --bench mesh -- 8`): {seconds(b['zeroset_bvh_s'])}")
        p(f"- zeroset load+BVH of a 1×1 render (PLY reading included): {seconds(b['zeroset_load_bvh_s'])}")
        p(f"- Embree build (rtcCommitScene): {seconds(b['embree_s'])}; Open3D build (first cast_rays): {seconds(b['open3d_s'])}")
        builds = []
        for name, src, pick in (("Embree", raw["embree"], lambda e: e["build_s"]["median"]),
                                ("Open3D", raw["open3d"], lambda e: e["build_s"])):
            if isinstance(src, dict) and src:
                builds.append(f"{name} " + ", ".join(f"level {lv} {pick(src[lv]):.4f} s" for lv in sorted(src)))
        for lv in (4, 6, 8):
            runs_ = raw["zeroset"].get(f"mesh{lv}", {}).get("load")
            if isinstance(runs_, list) and runs_:
                builds.append(f"zeroset load+BVH level {lv} {median([r['load_s'] for r in runs_]):.3f} s")
        if builds:
            p("- builds: " + "; ".join(builds))
        bpt = extra.get("bytes_per_tri")
        p(f"- zeroset bytes per triangle (`Mesh::memory_bytes`): "
          + (f"n/a ({bpt.reason})" if isinstance(bpt, NA) else R.fmt(bpt, 1))
          + (f"; peak RSS of the 1×1 render above the quadrics one, per triangle: "
             f"{extra['peak_rss_per_tri_above_quadrics']:.0f} B" if "peak_rss_per_tri_above_quadrics" in extra else ""))

    # floors
    p()
    p(f"### Floors of issue #11{'' if a.runs >= 5 else ' (runs < 5: not a valid check of the floors)'}")
    p()
    p(R.floors_markdown(R.floors(figs, extra, a.threads)))


if __name__ == "__main__":
    main()
