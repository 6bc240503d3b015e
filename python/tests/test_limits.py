"""The bindings never kill the interpreter: what a user's numbers size (a render's planes and
sample buffers, ray and output arrays, a file read) is refused with its estimate as
``MemoryError`` or ``ZerosetError`` before it is allocated, and an allocation that fails anyway
is a ``MemoryError`` too — never an abort (SIGABRT) or a ``PanicException``.

Each case runs in a child interpreter, so that an abort fails the test instead of ending the run,
under an address-space limit (``RLIMIT_AS``, as ``ulimit -v`` sets it) where the case needs one.
"""

import os
import resource
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import zeroset

GB = 1 << 30

#: A small scene: the cases only need something to render and cast rays at.
SCENE = ('Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), '
         'objects: [(shape: Sphere(radius: 1))])')

PRELUDE = f"""
import os, resource, sys, warnings
import numpy as np
import zeroset

scene = zeroset.Scene.from_ron({SCENE!r})

def mapped():
    '''Bytes of address space this process has mapped now.'''
    with open("/proc/self/statm") as f:
        return int(f.read().split()[0]) * resource.getpagesize()

def outcome(call):
    '''Which error `call` raised, and its message, on one line.'''
    try:
        call()
    except MemoryError as e:
        print("MemoryError:", e)
    except zeroset.ZerosetError as e:
        print("ZerosetError:", e)
    except ValueError as e:
        print("ValueError:", e)
    else:
        print("no error")
"""

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc are Linux's")


def run_child(body: str, address_space: int = 0, env: dict = None, timeout: float = 120) -> str:
    """Runs `body` after the prelude in a new interpreter (limited to `address_space` bytes of
    address space from its start when given); fails unless it exits normally. Returns stdout."""

    def limit():
        if address_space:
            resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))

    child_env = dict(os.environ, OPENBLAS_NUM_THREADS="1", **(env or {}))
    proc = subprocess.run([sys.executable, "-c", PRELUDE + textwrap.dedent(body)], capture_output=True, text=True,
                          timeout=timeout, preexec_fn=limit, env=child_env)
    assert "PanicException" not in proc.stderr, proc.stderr[-4000:]
    assert proc.returncode == 0, f"the interpreter died (status {proc.returncode}):\n{proc.stderr[-4000:]}"
    return proc.stdout


def test_a_render_of_a_trillion_pixels_raises_memory_error():
    out = run_child("outcome(lambda: scene.render(width=10**6, height=10**6))")
    assert out.startswith("MemoryError: rendering 1000000x1000000 with"), out
    assert "needs about" in out and " TB of memory but only" in out, out


def test_the_largest_spp_raises_memory_error():
    out = run_child("outcome(lambda: scene.render(width=8, height=8, spp=2**32 - 1))")
    assert out.startswith("MemoryError: rendering 8x8 with"), out
    assert "at 4294967295 spp needs about" in out, out


@linux_only
def test_sample_buffers_beyond_the_address_space_limit_raise_memory_error():
    out = run_child("""
        outcome(lambda: scene.render(width=8, height=8, spp=10**7))
        # the same interpreter still renders what fits
        print(scene.render(aovs=["Depth"], width=8, height=8, spp=4)["Depth"].shape)
        """, address_space=2 * GB)
    lines = out.splitlines()
    assert lines[0].startswith("MemoryError: rendering 8x8 with"), out
    assert "at 10000000 spp" in lines[0] and "address-space limit of 2.1 GB (ulimit -v)" in lines[0], out
    assert lines[1] == "(8, 8)", out


def test_rays_pinhole_of_a_trillion_pixels_raises_memory_error():
    out = run_child("""
        k = [[500.0, 0, 4], [0, 500.0, 4], [0, 0, 1]]
        outcome(lambda: zeroset.rays_pinhole(k, np.eye(4), 10**6, 10**6))
        o, d = zeroset.rays_pinhole(k, np.eye(4), 8, 4)
        print(o.shape, d.shape)
        """)
    lines = out.splitlines()
    assert lines[0].startswith("MemoryError: rays_pinhole of 1000000x1000000 pixels needs about 48.0 TB"), out
    assert lines[1] == "(4, 8, 3) (4, 8, 3)", out


@linux_only
def test_cast_rays_on_a_hundred_million_rays_under_a_limit_raises_memory_error():
    # the rays themselves are mapped but never touched (np.zeros); the limit leaves 2 GB beyond
    # them, far less than the 8.6 GB of outputs
    out = run_child("""
        origins = np.zeros((10**8, 3))
        directions = np.zeros((10**8, 3))
        room = mapped() + 2 * (1 << 30)
        resource.setrlimit(resource.RLIMIT_AS, (room, room))
        outcome(lambda: scene.cast_rays(origins, directions))
        outcome(lambda: scene.cast_rays(origins, directions, outputs=["t", "hit"], dtype=np.float32))
        # still alive, and answering what fits
        print(scene.cast_rays(origins[:4], [0, 0, 1])["hit"].tolist())
        """)
    lines = out.splitlines()
    assert lines[0].startswith("MemoryError: cast_rays of 100000000 rays needs about 8.6 GB"), out
    assert "address-space limit" in lines[0], out
    # 5 bytes a ray of `t` (float32) and `hit` fit in 2 GB: the zero directions are then refused
    assert lines[1].startswith("ZerosetError: ray "), out
    assert lines[2] == "[True, True, True, True]", out


@linux_only
def test_ray_columns_copied_from_strided_arrays_are_guarded():
    # zero-stride (broadcast) arrays of 10^8 rows reach the core uncopied: its own copy of them,
    # 2.4 GB each, is what must be refused under 2 GB
    out = run_child("""
        core = scene._core
        origins = np.broadcast_to(np.zeros(3), (10**8, 3))
        directions = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (10**8, 3))
        tmin, tmax = np.zeros(1), np.full(1, np.inf)
        outcome(lambda: core.cast_rays(origins, directions, tmin, tmax))
        outcome(lambda: core.test_occlusions(origins, directions, tmin, tmax))
        outcome(lambda: core.count_intersections(origins, directions, tmin, tmax))
        """, address_space=2 * GB)
    lines = out.splitlines()
    assert len(lines) == 3, out
    for line in lines:
        assert line.startswith("MemoryError: copying origins (300000000 values, not contiguous) needs about 2.4 GB"), out


@linux_only
def test_a_failed_numpy_allocation_is_memory_error_not_a_panic():
    out = run_child("""
        outcome(lambda: zeroset._zeroset._empty_f32([10**7, 10**7]))
        outcome(lambda: zeroset._zeroset._empty_f32([2**40, 2**40]))
        print(zeroset._zeroset._empty_f32([2, 3]).shape)
        """, address_space=2 * GB)
    lines = out.splitlines()
    assert lines[0].startswith("MemoryError:"), out
    # numpy refuses a size beyond its index type before allocating
    assert lines[1].startswith("MemoryError:") or lines[1].startswith("ValueError: array is too big"), out
    assert lines[2] == "(2, 3)", out


def test_threads_are_capped_as_on_the_command_line():
    out = run_child("""
        import time
        start = time.monotonic()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            depth = scene.render(aovs=["Depth"], width=8, height=8, threads=10**6)["Depth"]
        print(round(time.monotonic() - start, 1))
        print([str(w.message) for w in caught if w.category is RuntimeWarning])
        """, timeout=60)
    seconds, warned = out.splitlines()
    assert float(seconds) < 10, out
    assert "threads 1000000 capped at" in warned and "cores" in warned, out


@linux_only
def test_devices_and_fifos_are_refused_as_scene_files_without_waiting(tmp_path):
    fifo = tmp_path / "scene.ron"
    os.mkfifo(fifo)
    start = time.monotonic()
    out = run_child(f"""
        outcome(lambda: zeroset.Scene.load("/dev/zero"))
        outcome(lambda: zeroset.Scene.load({str(fifo)!r}))
        """, address_space=4 * GB, timeout=60)
    assert time.monotonic() - start < 30
    zero, pipe = out.splitlines()
    assert zero.startswith("ZerosetError: /dev/zero: not a regular file but a character device"), out
    assert "a scene file must be a regular file" in zero, out
    assert pipe.startswith(f"ZerosetError: {fifo}: not a regular file but a FIFO"), out


def test_scene_files_over_the_input_limit_name_the_limit_and_how_to_raise_it(tmp_path):
    path = tmp_path / "scene.ron"
    path.write_text(SCENE)
    size = len(SCENE)
    out = run_child(f"""
        outcome(lambda: zeroset.Scene.load({str(path)!r}))
        os.environ["ZEROSET_MAX_INPUT_BYTES"] = "1000000"
        print(zeroset.Scene.load({str(path)!r}).object_count)
        """, env={"ZEROSET_MAX_INPUT_BYTES": "100"})
    refused, loaded = out.splitlines()
    assert refused.startswith(f"ZerosetError: {path}: the scene file is {size} B ({size} bytes), "
                              "over the limit of 100 B (100 bytes) for input files"), out
    assert "set ZEROSET_MAX_INPUT_BYTES to a larger number of bytes" in refused, out
    assert loaded == "1", out

