"""zeroset.dask on a real two-worker LocalCluster: results bit-identical to the single-process
calls (tiles are exact crops; ray blocks go through the same query path)."""

import gc
import os
import pickle
import weakref

import numpy as np
import pytest

import zeroset

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")
import dask.array as da  # noqa: E402

import zeroset.dask as zdask  # noqa: E402


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    c.cluster_for_tests = cluster
    yield c
    c.close()
    cluster.close()


def test_render_tiles_equal_the_single_process_render(client, repo):
    path = str(repo / "scenes" / "default.ron")
    aovs = ["Beauty", "Alpha", "Depth", "Normal", "PrimitiveId"]
    tiled = zdask.render(path, chunks=(50, 70), aovs=aovs, width=160, height=120)
    assert tiled["Depth"].chunks == ((50, 50, 20), (70, 70, 20))
    assert tiled["Normal"].shape == (120, 160, 3)
    computed = dask.compute(tiled)[0]
    single = zeroset.Scene.load(path).render(aovs=aovs, width=160, height=120)
    for name in aovs:
        np.testing.assert_array_equal(computed[name], single[name], err_msg=name)
    # the work really ran on the cluster's workers
    assert sum(len(v) for v in client.run(lambda dask_worker: list(dask_worker.data.keys())).values()) >= 0


def test_render_graph_renders_each_tile_once(repo, monkeypatch):
    """The arrays' blocks take their AOV from one render per tile: a task per tile, a task per
    tile and AOV, the scene, and nothing else; computing every AOV renders each tile once."""
    crops = []
    render_block = zdask._render_block

    def counting(scene, kwargs):
        crops.append(kwargs["crop"])
        return render_block(scene, kwargs)

    monkeypatch.setattr(zdask, "_render_block", counting)
    path = str(repo / "scenes" / "default.ron")
    aovs = ["Depth", "Normal", "Alpha"]
    tiled = zdask.render(path, chunks=(60, 50), aovs=aovs, width=150, height=120)
    tasks = {}
    for name in aovs:
        tasks.update(dict(tiled[name].__dask_graph__()))
    tiles = [k for k in tasks if isinstance(k, tuple) and str(k[0]).startswith("zeroset-render-")]
    assert len(tiles) == 2 * 3
    assert len(tasks) == 1 + 2 * 3 + 2 * 3 * len(aovs)
    computed = dask.compute(tiled, scheduler="synchronous")[0]
    assert sorted(crops) == sorted(set(crops)) and len(crops) == 6
    single = zeroset.Scene.load(path).render(aovs=aovs, width=150, height=120)
    for name in aovs:
        np.testing.assert_array_equal(computed[name], single[name], err_msg=name)


def test_scene_built_in_code_ships_to_workers(client):
    scene = zeroset.Scene.empty(eye=(0, 0, -4), width=64, height=48)
    scene.add("Sphere", radius=1.0)
    scene.add_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], transform=np.diag([1.0, 1.0, 1.0, 1.0]) + 0)
    tiled = zdask.render(scene, chunks=(16, 16), aovs=["Depth", "PrimitiveId"])
    got = {k: v.compute() for k, v in tiled.items()}
    ref = scene.render(aovs=["Depth", "PrimitiveId"])
    for k in ref:
        np.testing.assert_array_equal(got[k], ref[k])


def test_cast_rays_over_ray_blocks(client, repo):
    scene = zeroset.Scene.load(repo / "scenes" / "default.ron")
    rng = np.random.default_rng(5)
    origins = rng.uniform(-4, 4, (3000, 3))
    directions = rng.uniform(-1, 1, (3000, 3)) - origins * 0.2
    o = da.from_array(origins, chunks=(700, 3))
    d = da.from_array(directions, chunks=(700, 3))
    lazy = zdask.cast_rays(scene, o, d)
    assert lazy["point"].chunks == ((700, 700, 700, 700, 200), (3,))
    got = dask.compute(lazy)[0]
    ref = scene.cast_rays(origins, directions)
    assert ref["hit"].sum() > 100
    for k in ref:
        np.testing.assert_array_equal(got[k], ref[k], err_msg=k)
    # float32: the dask arrays say so before they are computed, and hold the single call's values
    lazy32 = zdask.cast_rays(scene, o, d, dtype=np.float32)
    assert lazy32["t"].dtype == np.float32 and lazy32["object_id"].dtype == np.int32
    got32 = dask.compute(lazy32)[0]
    ref32 = scene.cast_rays(origins, directions, dtype=np.float32)
    for k in ref32:
        assert got32[k].dtype == ref32[k].dtype, k
        np.testing.assert_array_equal(got32[k], ref32[k], err_msg=k)


def test_point_queries_and_grids_over_blocks(client):
    scene = zeroset.Scene.empty()
    scene.add("Sphere(center: (0, 0, 0), radius: 1)")
    scene.add("Box(min: (1.5, -0.5, -0.5), max: (2.5, 0.5, 0.5))")
    rng = np.random.default_rng(6)
    p = rng.uniform(-3, 3, (5000, 3))
    for query, ref in [("distance", scene.compute_distance(p)), ("signed", scene.compute_signed_distance(p)),
                       ("occupancy", scene.compute_occupancy(p)),
                       ("closest", scene.compute_closest_points(p)["points"])]:
        lazy = zdask.points(scene, da.from_array(p, chunks=(1200, 3)), query)
        assert lazy.chunks[0] == (1200, 1200, 1200, 1200, 200)
        np.testing.assert_array_equal(lazy.compute(), ref, err_msg=query)
    grid = scene.sample_grid((-2, -2, -2), (3, 2, 2), (21, 17, 9))
    assert grid.shape == (21, 17, 9)
    # the node (i, j, k) of the grid is lo + (hi − lo)·(i, j, k)/(n − 1)
    x = np.linspace(-2, 3, 21)[:, None, None]
    y = np.linspace(-2, 2, 17)[None, :, None]
    z = np.linspace(-2, 2, 9)[None, None, :]
    sphere = np.sqrt(x * x + y * y + z * z) - 1
    far_from_box = (x < 1.0)
    np.testing.assert_allclose(grid[np.broadcast_to(far_from_box, grid.shape)],
                               np.broadcast_to(sphere, grid.shape)[np.broadcast_to(far_from_box, grid.shape)],
                               rtol=1e-12, atol=1e-12)
    lazy = zdask.sample_grid(scene, (-2, -2, -2), (3, 2, 2), (21, 17, 9), chunks=8)
    assert lazy.chunks == ((8, 8, 5), (8, 8, 1), (8, 1))
    np.testing.assert_array_equal(lazy.compute(), grid)


def test_render_views_stack(client, repo):
    path = str(repo / "scenes" / "default.ron")
    views = [dict(eye=(0, 2.5, -7), look_at=(0, 0, 0)), dict(eye=(3, 2, -5), look_at=(0, 0.5, 0))]
    stack = zdask.render_views(path, views, aovs=["Depth", "Normal"], width=80, height=60)
    assert stack["Depth"].shape == (2, 60, 80)
    assert stack["Normal"].shape == (2, 60, 80, 3)
    got = dask.compute(stack)[0]
    scene = zeroset.Scene.load(path)
    for i, v in enumerate(views):
        ref = scene.render(aovs=["Depth", "Normal"], width=80, height=60, view=v)
        for name in ref:
            np.testing.assert_array_equal(got[name][i], ref[name], err_msg=name)
    assert not np.array_equal(got["Depth"][0], got["Depth"][1])


def test_fetch_equals_compute_block_by_block(client, repo):
    # tiles copied into the result as they finish: the same arrays as Dask's own assembly, for a
    # frame (2-D and 3-D AOVs, ragged edge tiles) and for ray blocks (1-D and 2-D outputs)
    path = str(repo / "scenes" / "default.ron")
    aovs = ["Depth", "Normal"]
    tiled = zdask.render(path, chunks=(40, 64), aovs=aovs, width=150, height=100)
    fetched = zdask.fetch(tiled, client)
    single = zeroset.Scene.load(path).render(aovs=aovs, width=150, height=100)
    for name in aovs:
        assert fetched[name].dtype == np.float32 and fetched[name].shape == single[name].shape
        np.testing.assert_array_equal(fetched[name], single[name], err_msg=name)
    # a frame's arrays are fetched a whole tile (every AOV) at a time, views a whole view at a time
    assert zdask._by_render(tiled) is not None
    views = [dict(eye=[0, 1, -6]), dict(eye=[2, 1, -5])]
    stack = zdask.render_views(path, views, aovs=aovs, width=48, height=32)
    assert zdask._by_render(stack) is not None
    got_views = zdask.fetch(stack, client)
    for i, v in enumerate(views):
        ref = zeroset.Scene.load(path).render(aovs=aovs, width=48, height=32, view=v)
        for name in aovs:
            np.testing.assert_array_equal(got_views[name][i], ref[name], err_msg=name)
    scene = zeroset.Scene.load(path)
    rng = np.random.default_rng(9)
    origins = rng.uniform(-4, 4, (2500, 3))
    directions = -origins + rng.uniform(-1, 1, (2500, 3))
    lazy = zdask.cast_rays(scene, da.from_array(origins, chunks=(600, 3)), da.from_array(directions, chunks=(600, 3)))
    assert zdask._by_render(lazy) is None  # ray blocks: fetched block by block
    got = zdask.fetch(lazy)  # the current client
    ref = scene.cast_rays(origins, directions)
    assert ref["hit"].sum() > 500
    for k in ref:
        assert got[k].dtype == ref[k].dtype, k
        np.testing.assert_array_equal(got[k], ref[k], err_msg=k)


def test_fetch_gathers_from_the_workers_not_through_the_scheduler(client, repo, monkeypatch):
    """Over the network (workers that do not share this machine's memory: forced here) each tile
    comes straight from the worker that rendered it by default: the scheduler (here in this
    process) is never asked to gather, which would make every byte cross twice. ``direct=False``
    goes through it, with the same arrays."""
    monkeypatch.setattr(zdask, "_workers_share_memory", lambda client, workers=None: False)
    scheduler = client.cluster_for_tests.scheduler
    relayed = []
    gather = scheduler.handlers["gather"]

    async def counting(*args, **kwargs):
        relayed.append(kwargs.get("keys"))
        return await gather(*args, **kwargs)

    scheduler.handlers["gather"] = counting
    try:
        path = str(repo / "scenes" / "default.ron")
        tiled = zdask.render(path, chunks=(40, 64), aovs=["Depth", "Normal"], width=150, height=100)
        straight = zdask.fetch(tiled, client)
        assert relayed == []
        relayed_arrays = zdask.fetch(tiled, client, direct=False)
        # every tile through the scheduler (concurrent requests may share one call)
        assert sum(len(keys) for keys in relayed) == 3 * 3
    finally:
        scheduler.handlers["gather"] = gather
    ref = zeroset.Scene.load(path).render(aovs=["Depth", "Normal"], width=150, height=100)
    for name in ref:
        np.testing.assert_array_equal(straight[name], ref[name], err_msg=name)
        np.testing.assert_array_equal(relayed_arrays[name], ref[name], err_msg=name)


def _shared_files():
    prefix = f"{zdask._SHARED_PREFIX}{os.getpid()}-"
    return sorted(name for name in os.listdir(zdask._SHARED_DIR) if name.startswith(prefix))


@pytest.mark.skipif(not os.path.isdir("/dev/shm"), reason="no /dev/shm")
def test_fetch_through_shared_memory(client, repo):
    """Workers on this machine write their tiles into one shared-memory file that holds the
    arrays: the arrays equal the single-process render; the file is kept for the next fetch of
    that size once the arrays are gone (and reused by it), and unlinked with the pool."""
    assert zdask._workers_share_memory(client)
    path = str(repo / "scenes" / "default.ron")
    aovs = ["Beauty", "Depth", "Normal"]
    tiled = zdask.render(path, chunks=(40, 64), aovs=aovs, width=150, height=100)
    ref = zeroset.Scene.load(path).render(aovs=aovs, width=150, height=100)
    zdask._unlink_pool()
    before = _shared_files()
    first = zdask.fetch(tiled, client)
    held = _shared_files()
    assert len(held) == len(before) + 1
    for name in ref:
        np.testing.assert_array_equal(first[name], ref[name], err_msg=name)
    del first
    gc.collect()
    assert sum(len(paths) for paths in zdask._SHARED_POOL.values()) == 1
    again = zdask.fetch(tiled, client)
    assert _shared_files() == held  # the pooled file, reused
    for name in ref:
        np.testing.assert_array_equal(again[name], ref[name], err_msg=name)
    del again
    gc.collect()
    zdask._unlink_pool()
    assert _shared_files() == before


@pytest.mark.skipif(not os.path.isdir("/dev/shm"), reason="no /dev/shm")
def test_fetch_through_shared_memory_renders_into_place(client, repo, monkeypatch):
    """Tiles and views are rendered straight into the shared arrays (``_render_direct``, one
    task a render, no render task before it), also where only some of a render's AOVs are
    fetched; one array fetched under two names takes the render-then-copy path. Every way gives
    the single-process arrays."""
    assert zdask._workers_share_memory(client)
    path = str(repo / "scenes" / "default.ron")
    scene = zeroset.Scene.load(path)
    aovs = ["Depth", "Normal"]
    tiled = zdask.render(path, chunks=(40, 64), aovs=aovs, width=150, height=100)
    ref = scene.render(aovs=aovs, width=150, height=100)
    graph, renders = zdask._by_render(tiled)
    assert all(zdask._direct_task(graph, key, places) is not None for key, places in renders.items())
    got = zdask.fetch({"Depth": tiled["Depth"]}, client)
    assert list(got) == ["Depth"]
    np.testing.assert_array_equal(got["Depth"], ref["Depth"])
    twice = {"a": tiled["Normal"], "b": tiled["Normal"]}
    graph, renders = zdask._by_render(twice)
    assert all(zdask._direct_task(graph, key, places) is None for key, places in renders.items())
    got = zdask.fetch(twice, client)
    np.testing.assert_array_equal(got["a"], ref["Normal"])
    np.testing.assert_array_equal(got["b"], ref["Normal"])
    views = [dict(eye=(0, 2.5, -7), look_at=(0, 0, 0)), dict(eye=(3, 2, -5), look_at=(0, 0.5, 0))]
    stack = zdask.render_views(path, views, aovs=aovs, width=80, height=60)
    got = zdask.fetch(stack, client)
    for i, v in enumerate(views):
        one = scene.render(aovs=aovs, width=80, height=60, view=v)
        for name in aovs:
            np.testing.assert_array_equal(got[name][i], one[name], err_msg=f"{name}, view {i}")
    assert np.isfinite(got["Depth"]).sum() > 1000
    del got
    gc.collect()
    zdask._unlink_pool()


def _loaded_scene(repo):
    return zeroset.Scene.load(str(repo / "scenes" / "default.ron"))


def _mesh_scene(repo):
    scene = zeroset.Scene.empty(eye=(0.0, 0.5, 4.0), width=150, height=100)
    vertices = [(-1.0, 0.0, -1.0), (1.0, 0.0, -1.0), (0.0, 0.0, 1.0), (0.0, 1.5, 0.0)]
    scene.add_mesh(vertices, [(0, 2, 1), (0, 1, 3), (1, 2, 3), (2, 0, 3)])
    return scene


@pytest.mark.skipif(not os.path.isdir("/dev/shm"), reason="no /dev/shm")
@pytest.mark.parametrize("make", [_loaded_scene, _mesh_scene], ids=["recipe by value", "arrays broadcast"])
def test_fetch_builds_the_scene_once_per_worker(client, repo, make):
    """A scene fetched again is not built again on the workers (each keeps the one it built for
    the scene's token), whether it travels in every task (a path or RON text) or is broadcast
    once (mesh arrays); once the scene changes (``add``), the next fetch sends the new one and
    renders it; once the scene and its arrays are gone here, nothing holds it on their behalf."""
    scene = make(repo)
    aovs = ["Depth", "PrimitiveId"]
    tiled = zdask.render(scene, chunks=(40, 64), aovs=aovs, width=150, height=100)

    def built():
        import zeroset.dask as zd

        return {token: id(scene) for token, scene in zd._WORKER_SCENES.items()}

    # a copy that lands where the token was built before is that scene, not a new build
    handle = zdask._SceneOnWorkers("test-token", scene)
    one, two = (pickle.loads(pickle.dumps(handle)) for _ in range(2))
    assert one.scene is two.scene and one.scene is not scene
    assert one.scene.object_count == scene.object_count
    zdask._WORKER_SCENES.pop("test-token")
    del handle, one, two
    first = zdask.fetch(tiled, client)
    after_first = client.run(built)
    second = zdask.fetch(tiled, client)
    after_second = client.run(built)
    # every worker built the scene once, under one token, and still has that very object
    tokens = {frozenset(b) for b in after_first.values()}
    assert len(tokens) == 1 and len(next(iter(tokens))) >= 1
    assert after_second == after_first
    ref = scene.render(aovs=aovs, width=150, height=100)
    for name in aovs:
        np.testing.assert_array_equal(first[name], ref[name], err_msg=name)
        np.testing.assert_array_equal(second[name], ref[name], err_msg=name)
    assert np.isfinite(first["Depth"]).sum() > 500
    # a sphere in front of the camera: the next fetch renders it, as the single process does
    scene.add("Sphere", center=tuple(scene.camera.eye + 0.2 * scene.camera.forward), radius=0.05)
    changed = zdask.render(scene, chunks=(40, 64), aovs=aovs, width=150, height=100)
    third = zdask.fetch(changed, client)
    ref = scene.render(aovs=aovs, width=150, height=100)
    for name in aovs:
        np.testing.assert_array_equal(third[name], ref[name], err_msg=name)
    assert not np.array_equal(third["PrimitiveId"], first["PrimitiveId"])
    assert all(set(b) - set(after_first[w]) for w, b in client.run(built).items())
    scene_ref = weakref.ref(scene)
    del scene, tiled, changed, first, second, third
    gc.collect()
    assert scene_ref() is None


def test_fetch_without_room_in_shared_memory_takes_the_network(client, repo, monkeypatch):
    """Where the shared file cannot be made (a full ``/dev/shm``), fetch takes the network path
    with the same arrays, leaving no file behind."""

    def full(size):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(zdask, "_shared_output", full)
    path = str(repo / "scenes" / "default.ron")
    tiled = zdask.render(path, chunks=(40, 64), aovs=["Depth"], width=150, height=100)
    before = _shared_files()
    got = zdask.fetch(tiled, client)
    ref = zeroset.Scene.load(path).render(aovs=["Depth"], width=150, height=100)
    np.testing.assert_array_equal(got["Depth"], ref["Depth"])
    assert _shared_files() == before


def test_fetch_raises_a_failed_tile_s_error(client):
    """A block whose task fails makes fetch raise that error (not hang, not return a partial
    result)."""

    def broken(block):
        if block.sum() > 10:
            raise ValueError("tile went wrong")
        return block

    lazy = da.ones((40, 40), chunks=(10, 10)).map_blocks(broken)
    with pytest.raises(ValueError, match="tile went wrong"):
        zdask.fetch({"x": lazy}, client)


def test_fetch_without_a_cluster_uses_the_local_scheduler(repo):
    path = str(repo / "scenes" / "default.ron")
    tiled = zdask.render(path, chunks=(30, 50), aovs=["Depth"], width=90, height=60)
    with dask.config.set(scheduler="threads"):
        got = zdask.fetch(tiled, client=False)
    ref = zeroset.Scene.load(path).render(aovs=["Depth"], width=90, height=60)["Depth"]
    np.testing.assert_array_equal(got["Depth"], ref)
