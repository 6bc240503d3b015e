"""zeroset on a Dask cluster: frames as dask arrays of crop tiles, ray batches by blocks.

Nothing here schedules anything itself: the functions build ordinary ``dask.array`` graphs, and
whatever scheduler is active runs them — a ``distributed.Client`` on a ``LocalCluster``, a real
cluster (``Client("tcp://scheduler:8786")``), dask-jobqueue on Slurm, or the local threads.

The scene reaches the workers as its recipe (see ``zeroset.Scene``): a path loaded there (the
file and the meshes it names must be on a path the workers share), RON text (its relative mesh
paths resolve against ``base_dir`` on the worker), plus every object added in code, mesh arrays
included. It is one piece of data in the graph, so each worker builds it (load and hierarchy)
once, not once per block; ``fetch`` of a frame sends it with a token, and a worker that built
that token before (an earlier fetch of the same, unchanged scene) uses the scene it has.

Every block is computed by the same code as the single-process call: a tile is a ``crop``
window of the full frame, and crops are exact, so ``render(...)[aov].compute()`` equals
``Scene.render()[aov]`` bit for bit, and ``cast_rays`` equals ``Scene.cast_rays`` on the same
rays.
"""

from __future__ import annotations

import atexit
import contextlib
import mmap
import os
import tempfile
import uuid
import weakref
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import operator

import dask
import dask.array as da
import numpy as np
from dask.base import tokenize
from dask.delayed import Delayed
from dask.highlevelgraph import HighLevelGraph

from . import Scene, ZerosetError, _from_recipe, _real_dtype, _zeroset

SceneLike = Union[Scene, str, "os.PathLike[str]"]

__all__ = ["render", "render_views", "cast_rays", "points", "sample_grid", "fetch"]


def _as_scene(scene: SceneLike) -> Scene:
    """A path (an existing file) is loaded; any other string is RON text; a Scene is kept."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, os.PathLike) or (isinstance(scene, str) and os.path.isfile(scene)):
        return Scene.load(os.path.abspath(os.fspath(scene)))
    if isinstance(scene, str):
        return Scene.from_ron(scene)
    raise ZerosetError(f"scene: expected a Scene, a path or RON text, got {type(scene).__name__}")


def _aov_channels(scene: Scene, aovs: Optional[Sequence[str]]) -> List[Tuple[str, int]]:
    """(name, channel count) of the AOVs a render returns, from a 1×1 render of the scene."""
    probe = scene.render(aovs=aovs, width=None, height=None, crop=(0, 0, 1, 1))
    return [(name, 1 if a.ndim == 2 else a.shape[2]) for name, a in probe.items()]


def _worker_threads() -> Optional[int]:
    """The thread count of the Dask worker running this task (``None`` outside a worker)."""
    try:
        from distributed import get_worker

        return get_worker().state.nthreads
    except (ImportError, ValueError, AttributeError):
        return None


def _render_block(scene: Scene, kwargs: Dict[str, Any]) -> Dict[str, np.ndarray]:
    # on a worker, the render uses as many threads as the worker runs tasks at once, so workers
    # sharing a machine do not oversubscribe its cores (each process would otherwise start one
    # rayon thread per core)
    return scene.render(**kwargs, threads=_worker_threads())


def _assemble(nested: Any, axis: int = 0) -> da.Array:
    """Concatenates nested lists of blocks along the leading axes (``da.block`` would join the
    trailing ones, which are channels here)."""
    if isinstance(nested, list):
        return da.concatenate([_assemble(n, axis + 1) for n in nested], axis=axis)
    return nested


def _splits(total: int, step: int) -> List[Tuple[int, int]]:
    if step < 1:
        raise ZerosetError(f"chunks must be at least 1 pixel, got {step}")
    return [(a, min(a + step, total)) for a in range(0, total, step)]


def render(scene: SceneLike, chunks: Tuple[int, int] = (512, 512), aovs: Optional[Sequence[str]] = None,
           width: Optional[int] = None, height: Optional[int] = None, spp: Optional[int] = None,
           depth_miss: float = float("inf")) -> Dict[str, da.Array]:
    """A frame as ``{AOV name: dask.array}``, shaped ``(H, W)`` or ``(H, W, C)``, float32.

    Each ``chunks = (rows, columns)`` tile is one task: a ``crop`` render of that window on a
    worker. ``.compute()`` assembles the frame; ``dask.array.to_zarr`` writes it tile by tile.

    The graph holds the scene, one task per tile and one per tile and AOV (taking that AOV from
    the tile's result), which are the arrays' blocks themselves: no concatenation layers, so
    Dask has few tasks to schedule (16 tiles of 4 AOVs: 81 tasks rather than 273).
    """
    s = _as_scene(scene)
    cam = s.camera
    w = width or cam.width
    h = height or cam.height
    channels = _aov_channels(s, aovs)
    shared = dask.delayed(s, pure=True)
    rows = _splits(h, chunks[0])
    cols = _splits(w, chunks[1])
    tasks = {}
    for i, (y0, y1) in enumerate(rows):
        for j, (x0, x1) in enumerate(cols):
            kwargs = dict(aovs=aovs, width=w, height=h, crop=(x0, y0, x1, y1), spp=spp, depth_miss=depth_miss)
            tasks[(i, j)] = (_render_block, shared.key, kwargs)
    chunk_sizes = (tuple(b - a for a, b in rows), tuple(b - a for a, b in cols))
    token = tokenize(shared.key, aovs, w, h, spp, depth_miss, rows, cols)
    return _aov_arrays(shared, tasks, channels, chunk_sizes, operator.getitem, token)


def _aov_arrays(shared: Any, tasks: Dict[Tuple[int, ...], Any], channels: List[Tuple[str, int]],
                chunk_sizes: Tuple[Tuple[int, ...], ...], take: Any, token: str) -> Dict[str, da.Array]:
    """``{AOV name: dask.array}`` whose block at ``index`` is ``take(result, name)`` of the render
    task ``tasks[index]`` (a task per render and a task per render and AOV, the blocks
    themselves; no concatenation layers). ``chunk_sizes``: the blocks' sizes along the leading
    axes (a multi-channel AOV adds one block of its channels)."""
    renders = "zeroset-render-" + token
    layers = {**shared.dask.layers, renders: {(renders,) + index: task for index, task in tasks.items()}}
    dependencies = {**shared.dask.dependencies, renders: {shared.key}}
    out = {}
    for name, c in channels:
        blocks_name = f"zeroset-{name.lower()}-{token}"
        extra = (0,) if c > 1 else ()
        blocks = {(blocks_name,) + index + extra: (take, (renders,) + index, name) for index in tasks}
        graph = HighLevelGraph({**layers, blocks_name: blocks}, {**dependencies, blocks_name: {renders}})
        chunks = chunk_sizes + (((c,),) if c > 1 else ())
        out[name] = da.Array(graph, blocks_name, chunks, dtype=np.float32)
    return out


def _view_block(frame: Dict[str, np.ndarray], name: str) -> np.ndarray:
    """AOV ``name`` of one view's frame, as a block of a stack of views (a leading axis of 1)."""
    return frame[name][np.newaxis]


def render_views(scene: SceneLike, cameras: Iterable[Dict[str, Any]], aovs: Optional[Sequence[str]] = None,
                 width: Optional[int] = None, height: Optional[int] = None,
                 spp: Optional[int] = None) -> Dict[str, da.Array]:
    """Many views of one scene: ``{AOV name: dask.array}`` shaped ``(views, H, W[, C])``, one task
    per view. Each camera is a dict ``eye, look_at, up (default +y)`` placing the scene's camera."""
    s = _as_scene(scene)
    cam = s.camera
    w = width or cam.width
    h = height or cam.height
    channels = _aov_channels(s, aovs)
    shared = dask.delayed(s, pure=True)
    views = [dict(view) for view in cameras]
    if not views:
        raise ZerosetError("render_views: no cameras given")
    tasks = {
        (v, 0, 0): (_render_block, shared.key, dict(aovs=aovs, width=w, height=h, spp=spp, view=view))
        for v, view in enumerate(views)
    }
    token = tokenize(shared.key, aovs, w, h, spp, views)
    return _aov_arrays(shared, tasks, channels, ((1,) * len(views), (h,), (w,)), _view_block, token)


def _cast_block(scene: Scene, origins: np.ndarray, directions: np.ndarray, tmin: Any, tmax: Any,
                real: Any) -> Dict[str, np.ndarray]:
    return scene.cast_rays(origins, directions, tmin=tmin, tmax=tmax, dtype=real)


# each field's trailing shape and dtype (`None`: the real dtype asked for)
_CAST_FIELDS = {
    "t": ((), None),
    "hit": ((), np.bool_),
    "point": ((3,), None),
    "normal": ((3,), None),
    "object_id": ((), np.int32),
    "uv": ((2,), None),
    "primitive_id": ((), np.int64),
    "uncertain": ((), np.bool_),
}


def cast_rays(scene: SceneLike, origins: Any, directions: Any, tmin: float = 0.0,
              tmax: float = float("inf"), dtype: Any = np.float64) -> Dict[str, da.Array]:
    """``Scene.cast_rays`` over the blocks of dask arrays of rays (``(..., 3)``; numpy arrays are
    wrapped). Returns the same dict, each value a dask array chunked like the rays' leading
    dimensions; ``dtype`` (float64 or float32) as in ``Scene.cast_rays``."""
    real = _real_dtype(dtype)
    s = _as_scene(scene)
    o = origins if isinstance(origins, da.Array) else da.from_array(np.asarray(origins))
    d = directions if isinstance(directions, da.Array) else da.from_array(np.asarray(directions))
    if o.shape != d.shape or o.shape[-1:] != (3,):
        raise ZerosetError(f"origins and directions must have one shape (..., 3), got {o.shape} and {d.shape}")
    o = o.rechunk(o.chunks[:-1] + ((3,),))
    d = d.rechunk(o.chunks)
    shared = dask.delayed(s, pure=True)
    o_blocks = o.to_delayed()
    d_blocks = d.to_delayed()
    lead_chunks = o.chunks[:-1]
    results = {}
    for index in np.ndindex(*o_blocks.shape[:-1]):
        block = dask.delayed(_cast_block, pure=True)(shared, o_blocks[index + (0,)], d_blocks[index + (0,)],
                                                     float(tmin), float(tmax), real)
        results[index] = block
    out: Dict[str, da.Array] = {}
    for field, (tail, kind) in _CAST_FIELDS.items():
        field_dtype = real if kind is None else kind

        def nest(prefix: Tuple[int, ...]) -> Any:
            level = len(prefix)
            if level == len(lead_chunks):
                shape = tuple(lead_chunks[k][prefix[k]] for k in range(level)) + tail
                return da.from_delayed(results[prefix][field], shape=shape, dtype=field_dtype)
            return [nest(prefix + (i,)) for i in range(len(lead_chunks[level]))]
        out[field] = _assemble(nest(()))
    return out


# what `points` computes: the Scene method, its keyword arguments' use of `sign`, the trailing
# shape and dtype of its answer
_POINT_QUERIES = {
    "closest": (lambda s, p, sign: s.compute_closest_points(p)["points"], (3,), np.float64),
    "distance": (lambda s, p, sign: s.compute_distance(p), (), np.float64),
    "signed": (lambda s, p, sign: s.compute_signed_distance(p, sign=sign), (), np.float64),
    "occupancy": (lambda s, p, sign: s.compute_occupancy(p, sign=sign), (), np.float32),
    "phi": (lambda s, p, sign: s.phi(p), (), np.float64),
    "gradient": (lambda s, p, sign: s.gradient(p), (3,), np.float64),
}


def _point_block(scene: Scene, block: np.ndarray, query: str, sign: str) -> np.ndarray:
    return _POINT_QUERIES[query][0](scene, block, sign)


def points(scene: SceneLike, points: Any, query: str = "distance", sign: str = "fast-winding") -> da.Array:
    """A point query over the blocks of a dask array of points (``(..., 3)``; numpy arrays are
    wrapped): ``query`` is ``"closest"`` (the nearest surface points, ``(..., 3)``),
    ``"distance"``, ``"signed"``, ``"occupancy"``, ``"phi"`` or ``"gradient"``, each block
    answered by the same ``Scene`` method as in one process (``sign`` as there). Returns a dask
    array chunked like the points' leading dimensions: a grid of millions of SDF samples is one
    ``points(scene, grid, "signed")``, stored with ``.to_zarr(...)`` without ever being whole in
    memory."""
    if query not in _POINT_QUERIES:
        raise ZerosetError(f"query: one of {', '.join(_POINT_QUERIES)}, got {query!r}")
    s = _as_scene(scene)
    p = points if isinstance(points, da.Array) else da.from_array(np.asarray(points, dtype=np.float64))
    if p.shape[-1:] != (3,):
        raise ZerosetError(f"points must have shape (..., 3), got {p.shape}")
    p = p.rechunk(p.chunks[:-1] + ((3,),))
    shared = dask.delayed(s, pure=True)
    blocks = p.to_delayed()
    lead_chunks = p.chunks[:-1]
    _, tail, kind = _POINT_QUERIES[query]

    def nest(prefix: Tuple[int, ...]) -> Any:
        level = len(prefix)
        if level == len(lead_chunks):
            shape = tuple(lead_chunks[k][prefix[k]] for k in range(level)) + tail
            block = dask.delayed(_point_block, pure=True)(shared, blocks[prefix + (0,)], query, str(sign))
            return da.from_delayed(block, shape=shape, dtype=kind)
        return [nest(prefix + (i,)) for i in range(len(lead_chunks[level]))]

    return _assemble(nest(()))


def _grid_block(scene: Scene, axes: Tuple[np.ndarray, np.ndarray, np.ndarray], query: str, sign: str) -> np.ndarray:
    x, y, z = np.meshgrid(*axes, indexing="ij")
    block = np.stack([x, y, z], axis=-1)
    return _POINT_QUERIES[query][0](scene, block, sign)


def sample_grid(scene: SceneLike, lo: Sequence[float], hi: Sequence[float], shape: Sequence[int],
                query: str = "signed", sign: str = "fast-winding", chunks: int = 64) -> da.Array:
    """``Scene.sample_grid`` as a dask array of ``chunks``³ blocks: each block makes its own
    sample points on its worker, so neither the points nor the answers of a large grid (an SDF
    volume of 1024³) are ever whole in one memory; ``.to_zarr(path)`` (with ``zarr`` installed)
    writes it block by block."""
    if query not in _POINT_QUERIES:
        raise ZerosetError(f"query: one of {', '.join(_POINT_QUERIES)}, got {query!r}")
    axes = [np.linspace(float(a), float(b), int(n)) for a, b, n in zip(lo, hi, shape)]
    if len(axes) != 3 or any(len(a) < 1 for a in axes):
        raise ZerosetError(f"lo, hi and shape need three entries each, shape at least 1, got {shape}")
    shared = dask.delayed(_as_scene(scene), pure=True)
    _, tail, kind = _POINT_QUERIES[query]
    splits = [_splits(len(a), int(chunks)) for a in axes]
    nested = [[[da.from_delayed(dask.delayed(_grid_block, pure=True)(
        shared, (axes[0][i0:i1], axes[1][j0:j1], axes[2][k0:k1]), query, str(sign)),
        shape=(i1 - i0, j1 - j0, k1 - k0) + tail, dtype=kind)
        for k0, k1 in splits[2]] for j0, j1 in splits[1]] for i0, i1 in splits[0]]
    return _assemble(nested)


def _windows(a: da.Array) -> Iterable[Tuple[Tuple[int, ...], Tuple[slice, ...]]]:
    """``(block index, where that block goes in the array)`` for every block of ``a``, in C
    order."""
    starts = [np.concatenate([[0], np.cumsum(c)[:-1]]).astype(int) for c in a.chunks]
    for index in np.ndindex(*a.numblocks):
        yield index, tuple(slice(starts[k][i], starts[k][i] + a.chunks[k][i]) for k, i in enumerate(index))


def _collect(client: Any, futures: list, direct: Optional[bool], place: Any) -> None:
    """``place(future, result)`` for each of ``futures`` as it finishes, then the future released.

    Each result is gathered from the worker that holds it where ``direct`` (``None``: the
    client's own ``direct_to_workers`` if set, else ``True``); ``distributed`` by default gathers
    through the scheduler, and the bytes then cross the network twice. Two threads gather and
    place, so that one result's copy into place overlaps the next one's transfer. The first
    error (a failed task, a lost worker) is raised once it is seen."""
    from concurrent.futures import ThreadPoolExecutor

    from distributed import as_completed

    if direct is None:
        direct = True if client.direct_to_workers is None else client.direct_to_workers

    def take(future: Any) -> None:
        place(future, client.gather(future, direct=direct))
        future.release()

    with ThreadPoolExecutor(max_workers=2) as pool:
        running: list = []
        for future in as_completed(futures):
            running.append(pool.submit(take, future))
            # the finished ones checked (a failed one raises now) and dropped, so that each
            # arrival looks only at the few still in flight
            unfinished = []
            for r in running:
                if r.done():
                    r.result()
                else:
                    unfinished.append(r)
            running = unfinished
        for r in running:
            r.result()


def _empty(shape: Tuple[int, ...], dtype: Any) -> np.ndarray:
    """An array every element of which ``fetch`` writes: float32 ones (AOVs) in zeroset's pooled
    memory (a loop fetching frames of one size then faults no page in), others numpy's."""
    if np.dtype(dtype) == np.float32:
        return _zeroset._empty_f32(list(shape))
    return np.empty(shape, dtype=dtype)


def fetch(arrays: Dict[str, da.Array], client: Any = None, direct: Optional[bool] = None) -> Dict[str, np.ndarray]:
    """Computes dask arrays into numpy arrays in this process, block by block as they finish.

    ``.compute()`` on a ``distributed`` cluster joins the blocks with a ``finalize`` task on a
    worker — half of the blocks travel to that worker, it copies them into one array, and that
    array travels again to the client. ``fetch`` instead allocates each result here and copies
    every block into it as soon as the block is done, while the workers go on with the others:
    each block crosses the network once, and the transfers overlap the computation. Arrays made
    by ``render`` or ``render_views`` are fetched a render at a time: each tile's (or view's)
    result, every AOV of it, comes in one piece, and the per-AOV tasks never run (16 futures
    instead of 64 for a 4×4-tile frame of 4 AOVs). Where every worker shares this machine's
    memory (a ``LocalCluster``; checked once per client by a token file each worker reads back),
    those renders' tiles travel not at all: the arrays live in one shared-memory file in
    ``/dev/shm``, each worker renders its tiles straight into it (``Scene.render(out=...)``: no
    frame of its own, no copy; two tasks a worker thread, each a share of tiles from all over
    the frame) and returns only an acknowledgement, which is
    waited for, never gathered; the file is kept for the next fetch of the same size once the arrays are gone (unlinked when this
    process ends; files of processes killed before that are unlinked by the next fetch). The
    values are those of ``.compute()``.
    ``client``: a ``distributed.Client`` (default: the current one); ``False``, or no client at
    all, computes the blocks with the local scheduler. ``direct``: gather each block straight
    from the worker that made it (the default, unless the client says otherwise with
    ``direct_to_workers``); ``False`` where this process cannot reach the workers (only the
    scheduler), at the price of every byte crossing the network twice.
    """
    if client is None:
        try:
            from distributed import default_client

            client = default_client()
        except (ImportError, ValueError):
            client = False
    grouped = None if client is False else _by_render(arrays)
    if grouped is not None:
        graph, renders = grouped
        workers = _scheduler_workers(client)
        if _workers_share_memory(client, workers):
            shared = _fetch_in_shared_memory(client, arrays, graph, renders, workers)
            if shared is not None:
                return shared
    # the arrays the blocks are copied into (the shared-memory path returns its own)
    out = {name: _empty(a.shape, a.dtype) for name, a in arrays.items()}
    if grouped is not None:
        # the arrays of `render` / `render_views`: fetch each render's whole result (every AOV
        # of a tile) once, rather than one future and one task per tile and AOV
        futures = client.compute([Delayed(key, graph, layer=key[0]) for key in renders])
        where = {f.key: renders[key] for f, key in zip(futures, renders)}

        def place_render(future: Any, frame: Any) -> None:
            for name, take, aov, window in where[future.key]:
                out[name][window] = take(frame, aov)

        _collect(client, futures, direct, place_render)
        return out
    blocks = []
    places = []
    for name, a in arrays.items():
        delayed_blocks = a.to_delayed(optimize_graph=False)  # fused, a tile would run once per AOV
        for index, window in _windows(a):
            blocks.append(delayed_blocks[index])
            places.append((name, window))
    if client is False:
        for (name, window), block in zip(places, dask.compute(*blocks)):
            out[name][window] = block
        return out
    futures = client.compute(blocks)
    where = {f.key: place for f, place in zip(futures, places)}

    def place_block(future: Any, block: Any) -> None:
        name, window = where[future.key]
        out[name][window] = block

    _collect(client, futures, direct, place_block)
    return out


# -- fetch through shared memory, where the workers share this machine's ------------------------

#: Where files are memory.
_SHARED_DIR = "/dev/shm"
#: Prefix of the files of the output arrays (followed by the creating process's id).
_SHARED_PREFIX = "zeroset-fetch-"
#: The most bytes of shared files kept for reuse once their arrays are gone.
_SHARED_POOL_BYTES = 1 << 30
#: Files whose arrays are gone, by size: reused by the next fetch of that size.
_SHARED_POOL: Dict[int, List[str]] = {}
#: Which clients' workers share this process's memory, by (client, workers).
_SHARING: Dict[Tuple[int, Tuple[str, ...]], bool] = {}
#: On a worker: the shared files mapped so far, most recent last (see `_worker_mapping`).
_WORKER_MAPS: Dict[str, mmap.mmap] = {}


def _unlink(path: str) -> None:
    """Removes the file at ``path``, if it is still there."""
    with contextlib.suppress(OSError):
        os.unlink(path)


def _read_token(path: str) -> Optional[str]:
    try:
        with open(path, encoding="ascii") as f:
            return f.read()
    except OSError:
        return None


def _scheduler_workers(client: Any) -> Dict[str, Any]:
    """The workers of ``client`` as ``scheduler_info`` lists them (a round trip to the
    scheduler), empty for a client that cannot say."""
    try:
        return client.scheduler_info()["workers"]
    except Exception:  # noqa: BLE001 - a client that cannot say: the network path
        return {}


def _workers_share_memory(client: Any, workers: Optional[Dict[str, Any]] = None) -> bool:
    """Whether every worker of ``client`` (``workers``, as ``_scheduler_workers`` gives them;
    asked for when ``None``) sees this process's shared-memory files: a token file written here
    is read back by each worker (``client.run``), once per client and set of workers. True for a
    ``LocalCluster`` and for workers on this machine sharing its ``/dev/shm``; false for workers
    elsewhere and where there is no ``/dev/shm``."""
    if not (os.path.isdir(_SHARED_DIR) and os.access(_SHARED_DIR, os.W_OK)):
        return False
    names = tuple(sorted(_scheduler_workers(client) if workers is None else workers))
    if not names:
        return False
    key = (id(client), names)
    if key not in _SHARING:
        token = uuid.uuid4().hex
        path = os.path.join(_SHARED_DIR, f"zeroset-token-{token}")
        try:
            with open(path, "w", encoding="ascii") as f:
                f.write(token)
            seen = client.run(_read_token, path)
            _SHARING[key] = len(seen) == len(names) and all(t == token for t in seen.values())
        except Exception:  # noqa: BLE001 - any failure: the network path
            _SHARING[key] = False
        finally:
            _unlink(path)
    return _SHARING[key]


def _remove_stale_files() -> None:
    """Unlinks the shared files of processes that are gone (killed before they could)."""
    for name in os.listdir(_SHARED_DIR):
        if name.startswith(_SHARED_PREFIX):
            pid = name[len(_SHARED_PREFIX):].split("-")[0]
            if pid.isdigit() and int(pid) != os.getpid() and not os.path.exists(f"/proc/{pid}"):
                _unlink(os.path.join(_SHARED_DIR, name))


def _release_shared(path: str, size: int) -> None:
    """The arrays over the file at ``path`` are gone: keep it for the next fetch of its size
    (within ``_SHARED_POOL_BYTES``) or, once this process is ending, unlink it."""
    pooled = sum(each * len(paths) for each, paths in _SHARED_POOL.items())
    if not _EXITING and pooled + size <= _SHARED_POOL_BYTES:
        _SHARED_POOL.setdefault(size, []).append(path)
    else:
        _unlink(path)


def _unlink_pool() -> None:
    """Unlinks the pooled files (whose arrays are gone)."""
    for paths in _SHARED_POOL.values():
        for path in paths:
            _unlink(path)
    _SHARED_POOL.clear()


# at exit, the pool is unlinked and every file whose arrays' finalizer runs after that is unlinked
# too (`_EXITING`), whichever order the finalizers' own exit hook and this one run in
_EXITING = False


@atexit.register
def _at_exit() -> None:
    global _EXITING
    _EXITING = True
    _unlink_pool()


def _shared_output(size: int) -> Tuple[str, mmap.mmap]:
    """A shared file of ``size`` bytes and this process's mapping of it: a pooled one whose
    arrays are gone (its pages already in memory), else a new one, its memory reserved at once
    (``posix_fallocate``: a full ``/dev/shm`` is an ``OSError`` here, not a worker killed by
    ``SIGBUS`` when it writes). When the mapping is garbage (every array over it gone), the file
    returns to the pool."""
    pooled = _SHARED_POOL.get(size)
    reused = bool(pooled)
    if pooled:
        path = pooled.pop()
        descriptor = os.open(path, os.O_RDWR)
    else:
        _remove_stale_files()
        descriptor, path = tempfile.mkstemp(prefix=f"{_SHARED_PREFIX}{os.getpid()}-", dir=_SHARED_DIR)
    try:
        os.ftruncate(descriptor, size)
        if not reused:
            os.posix_fallocate(descriptor, 0, size)
        memory = mmap.mmap(descriptor, size)
    except BaseException:
        os.close(descriptor)
        _unlink(path)
        raise
    os.close(descriptor)
    weakref.finalize(memory, _release_shared, path, size)
    return path, memory


def _worker_mapping(path: str) -> mmap.mmap:
    """On a worker: its mapping of the shared file at ``path``, kept for the next fetches into
    the same file; the two most recent are kept. Mapped with every page entered at once
    (``MAP_POPULATE`` on Linux): a worker renders whichever tiles the scheduler hands it, other
    ones from one fetch to the next, and each page of the mapping it touched for the first time
    was a page fault (2.6 µs apiece on this project's VM: about 45,000 a worker in the first
    fetch of a 4K frame of four AOVs, 14,000 in the second, 2,000 in the third, before each
    worker had touched every page); entered together they cost 1.5 µs a page, once."""
    memory = _WORKER_MAPS.pop(path, None)
    if memory is None:
        with open(path, "r+b") as f:
            memory = mmap.mmap(f.fileno(), 0, flags=mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0))
    _WORKER_MAPS[path] = memory
    while len(_WORKER_MAPS) > 2:
        _WORKER_MAPS.pop(next(iter(_WORKER_MAPS))).close()
    return memory


def _shared_array(memory: mmap.mmap, layout: Dict[str, Tuple[int, Tuple[int, ...]]], name: str) -> np.ndarray:
    """Output array ``name`` of the shared file mapped at ``memory`` (``layout``: name → (byte
    offset, shape), float32), as a view of the mapping."""
    offset, shape = layout[name]
    return np.ndarray(shape, np.float32, buffer=memory, offset=offset)


def _render_into(frame: Dict[str, np.ndarray], path: str, layout: Dict[str, Tuple[int, Tuple[int, ...]]],
                 places: list) -> None:
    """On a worker: copies a render's AOVs into the shared file at ``path`` that holds the output
    arrays (``layout`` as in ``_shared_array``), at their windows."""
    memory = _worker_mapping(path)
    for name, take, aov, window in places:
        _shared_array(memory, layout, name)[window] = take(frame, aov)


def _render_direct(scene: Scene, kwargs: Dict[str, Any], path: str, layout: Dict[str, Tuple[int, Tuple[int, ...]]],
                   places: list) -> None:
    """On a worker: ``_render_block`` written straight into the shared file at ``path`` that
    holds the output arrays (``layout`` as in ``_render_into``): each AOV of ``places`` rendered
    into its window there (``Scene.render(out=...)``), with no frame of its own and no copy."""
    memory = _worker_mapping(path)
    scene = getattr(scene, "scene", scene)  # a _SceneOnWorkers or the scene itself
    out = {}
    for name, take, aov, window in places:
        block = _shared_array(memory, layout, name)[window]
        out[aov] = block[0] if take is _view_block else block
    scene.render(**kwargs, threads=_worker_threads(), out=out)


def _direct_task(graph: Any, key: Any, places: list) -> Optional[Tuple[Any, Dict[str, Any]]]:
    """``(scene key, render keyword arguments)`` of the render task ``key`` where it is a
    ``_render_block`` that ``_render_direct`` can replace: every place a different AOV of it."""
    task = graph.layers[key[0]].get(key)
    if not (isinstance(task, tuple) and len(task) == 3 and task[0] is _render_block and isinstance(task[2], dict)):
        return None
    if len({aov for _, _, aov, _ in places}) != len(places):
        return None
    return task[1], task[2]


def _layers_under(graph: Any, names: Iterable[str]) -> set:
    """The layers ``names`` of ``graph`` and every layer they depend on."""
    found: set = set()
    pending = list(names)
    while pending:
        name = pending.pop()
        if name not in found:
            found.add(name)
            pending.extend(graph.dependencies.get(name, ()))
    return found


def _fetch_in_shared_memory(client: Any, arrays: Dict[str, da.Array], graph: Any,
                            renders: Dict[Any, list], workers: Dict[str, Any]) -> Optional[Dict[str, np.ndarray]]:
    """``fetch`` of ``render`` / ``render_views`` arrays where every worker shares this
    machine's memory: the output arrays live in one shared-memory file, each worker renders its
    tiles into it where they go (``_render_direct``; a render it cannot take is rendered, then
    copied in by ``_render_into``), and only an acknowledgement, waited for rather than gathered,
    comes back (no tile is serialised, sent or copied again here). The file is this process's until the arrays are
    gone; it is then kept for the next fetch of the same size (the single-process render's
    pooled memory does the same), and unlinked when this process ends. ``None`` (nothing done)
    where shared memory has no room for the arrays."""
    layout: Dict[str, Tuple[int, Tuple[int, ...]]] = {}
    size = 0
    for name, a in arrays.items():
        layout[name] = (size, tuple(a.shape))
        size += -(-int(np.prod(a.shape, dtype=np.int64)) * 4 // 64) * 64
    try:
        path, memory = _shared_output(max(size, 64))
    except OSError:
        return None  # no room in shared memory: the network path
    out = {name: _shared_array(memory, layout, name) for name in layout}
    futures = _direct_futures(client, workers, graph, renders, path, layout)
    if futures is None:
        futures = _graph_futures(client, graph, renders, path, layout)
    # the results are acknowledgements (None): waited for, never gathered; a failed task (or a
    # lost worker) raises its error here
    from distributed import wait

    wait(futures)
    for future in futures:
        if future.status != "finished":
            future.result()
    return out


def _graph_futures(client: Any, graph: Any, renders: Dict[Any, list], path: str,
                   layout: Dict[str, Tuple[int, Tuple[int, ...]]]) -> list:
    """The tasks of ``_fetch_in_shared_memory`` as one graph over ``graph``'s scene: a render task
    that ``_render_direct`` can take renders into the file itself (one task, no frame, no copy);
    any other is rendered, then copied in by ``_render_into``."""
    layer = "zeroset-into-" + tokenize(path, uuid.uuid4().hex)
    tasks = {}
    needs = set()
    for k, (key, places) in enumerate(renders.items()):
        direct_task = _direct_task(graph, key, places)
        if direct_task is None:
            tasks[(layer, k)] = (_render_into, key, path, layout, places)
            needs.add(key[0])
        else:
            scene_key, kwargs = direct_task
            tasks[(layer, k)] = (_render_direct, scene_key, kwargs, path, layout, places)
            needs.update(graph.dependencies[key[0]])
    kept = _layers_under(graph, needs)
    merged = HighLevelGraph({**{name: graph.layers[name] for name in kept}, layer: tasks},
                            {**{name: graph.dependencies[name] for name in kept}, layer: needs})
    return client.compute([Delayed(key, merged, layer=layer) for key in tasks])


def _literal_scene(graph: Any, key: Any) -> Optional[Scene]:
    """The ``Scene`` that ``graph`` holds as the literal value of ``key`` (``render`` puts the
    scene there), else ``None``."""
    layer = graph.layers.get(key[0] if isinstance(key, tuple) else key)
    node = None if layer is None else layer.get(key)
    value = getattr(node, "value", node)
    return value if isinstance(value, Scene) else None


#: On a worker: the scenes built from ``_SceneOnWorkers`` tokens, most recent last (the two most
#: recent are kept).
_WORKER_SCENES: Dict[str, Scene] = {}


class _SceneOnWorkers:
    """A scene as ``fetch`` hands it to the workers: pickled as a token and the scene's recipe,
    and built on a worker only where that worker has not built the same token before
    (``_scene_for_token``): a task that brings the scene again (each task does, where the scene
    travels by value) or a copy Dask sends between workers finds it built. A worker keeps the
    two scenes it built last, for as long as it lives; each fetch of a scene built afresh on
    every worker was, for the level-8 bench mesh, 0.43 s of load and hierarchy."""

    __slots__ = ("token", "scene")

    def __init__(self, token: str, scene: Scene):
        self.token = token
        self.scene = scene

    def __reduce__(self):
        return (_scene_for_token, (self.token, self.scene._recipe))


def _scene_for_token(token: str, recipe: list) -> _SceneOnWorkers:
    """On a worker: the scene of ``token``, built from ``recipe`` unless this process already has
    it."""
    scene = _WORKER_SCENES.pop(token, None)
    if scene is None:
        scene = _from_recipe(recipe)
    _WORKER_SCENES[token] = scene
    while len(_WORKER_SCENES) > 2:
        _WORKER_SCENES.pop(next(iter(_WORKER_SCENES)))
    return _SceneOnWorkers(token, scene)


#: The token of each scene sent to workers: scene → (its recipe's length then, the token).
_TOKENS: "weakref.WeakKeyDictionary[Scene, Tuple[int, str]]" = weakref.WeakKeyDictionary()

#: Scenes broadcast to the workers of a client: scene → (its token, the client's workers, the
#: future of the scene broadcast to them). Weak: an entry goes (and the workers free the scene)
#: once the scene is gone here, which ``render``'s arrays keep alive while they live.
_ON_WORKERS: "weakref.WeakKeyDictionary[Scene, Tuple[str, Tuple[str, ...], Any]]" = weakref.WeakKeyDictionary()


def _scene_for_tasks(client: Any, scene: Scene, workers: Dict[str, Any]) -> Any:
    """``scene`` as the tasks of a fetch take it: a ``_SceneOnWorkers`` with the same token from
    one fetch to the next while the scene is unchanged (no ``add`` since), so that each worker
    builds it once, not at every fetch (the level-8 bench mesh, 3840×2160: fetch 1.33 → 0.49 s,
    the single-process render 0.40 s).

    A scene whose recipe is a path or RON text goes in every task by value (a few hundred
    bytes), so the tasks depend on nothing and the scheduler spreads them over the workers as
    it likes; one built from arrays (``add_mesh``) is broadcast once (``client.scatter``) and
    its future kept for the next fetches, the arrays not sent with every task. ``workers``: the
    client's, as ``scheduler_info`` lists them."""
    held_token = _TOKENS.get(scene)
    if held_token is not None and held_token[0] == len(scene._recipe):
        token = held_token[1]
    else:
        token = f"{id(scene):x}-{uuid.uuid4().hex}"
        _TOKENS[scene] = (len(scene._recipe), token)
    handle = _SceneOnWorkers(token, scene)
    if not any(step[0] == "mesh" for step in scene._recipe):
        return handle
    names = tuple(sorted(workers))
    held = _ON_WORKERS.get(scene)
    if held is not None:
        held_token, held_workers, future = held
        if (future.client is client and held_token == token and held_workers == names
                and future.status == "finished"):
            return future
    future = client.scatter(handle, broadcast=True, hash=False)
    _ON_WORKERS[scene] = (token, names, future)
    return future


def _direct_futures(client: Any, workers: Dict[str, Any], graph: Any, renders: Dict[Any, list], path: str,
                    layout: Dict[str, Tuple[int, Tuple[int, ...]]]) -> Optional[list]:
    """The tasks of ``_fetch_in_shared_memory`` where every render is a ``_render_direct`` of a
    scene that the graph holds as a literal (``render``'s and ``render_views``' arrays), all
    submitted at once with the scene as ``_scene_for_tasks`` hands it over, so that no
    task waits for another; ``None`` otherwise.

    The renders of a scene go into twice as many tasks as the workers have threads (or one a
    render, where there are fewer), render ``k`` into task ``k mod tasks``: each task takes tiles
    from all over the frame, so the tasks cost about alike and each thread still gets two to
    balance the load with, and the scheduler's and the workers' cost per task (a few ms of Python
    each, on the same cores as the renders) is paid for few tasks. 3840×2160, quadrics, four
    AOVs, 540×960 tiles, LocalCluster of 2 × 1 threads, medians of 9 interleaved with the
    single-process render (0.213 s), the scene then still a dependency of every task: one task a
    tile 0.265 s, two tiles a task 0.253 s, four 0.245 s; with the scene by value as well,
    ``python/bench/dask_render.py``: 1.11× and 1.18× the single-process render (1.29–1.45× with
    a task a tile and the scene as a task of its own)."""
    by_scene: Dict[int, Tuple[Scene, list]] = {}
    for key, places in renders.items():
        direct_task = _direct_task(graph, key, places)
        if direct_task is None:
            return None
        scene_key, kwargs = direct_task
        scene = _literal_scene(graph, scene_key)
        if scene is None:
            return None
        by_scene.setdefault(id(scene), (scene, []))[1].append((kwargs, places))
    threads = max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))
    held, tasks = [], []
    for scene, tiles in by_scene.values():
        count = min(len(tiles), 2 * threads)
        held += [_scene_for_tasks(client, scene, workers)] * count
        tasks += [tiles[k::count] for k in range(count)]
    return client.map(_render_tiles, held, tasks, [path] * len(tasks), [layout] * len(tasks), pure=False)


def _render_tiles(scene: Any, tiles: list, path: str, layout: Dict[str, Tuple[int, Tuple[int, ...]]]) -> None:
    """On a worker: ``_render_direct`` of each ``(kwargs, places)`` of ``tiles`` in turn."""
    for kwargs, places in tiles:
        _render_direct(scene, kwargs, path, layout, places)


def _by_render(arrays: Dict[str, da.Array]) -> Optional[Tuple[Any, Dict[Any, list]]]:
    """For arrays built by ``_aov_arrays`` (every block is ``take(render result, aov)`` of a render
    task): their graph and ``{render key: [(array name, take, aov, window)]}``, the window being
    where that block goes in the array. ``None`` for any other arrays (fetched block by block)."""
    graph = None
    renders: Dict[Any, list] = {}
    for name, a in arrays.items():
        layer = a.dask.layers.get(a.name)
        if layer is None or not a.name.startswith("zeroset-"):
            return None
        for index, window in _windows(a):
            task = layer.get((a.name,) + index)
            if not (isinstance(task, tuple) and len(task) == 3 and task[0] in (operator.getitem, _view_block)
                    and isinstance(task[1], tuple) and str(task[1][0]).startswith("zeroset-render-")):
                return None
            renders.setdefault(task[1], []).append((name, task[0], task[2], window))
        graph = a.dask if graph is None else HighLevelGraph.merge(graph, a.dask)
    return None if graph is None else (graph, renders)
