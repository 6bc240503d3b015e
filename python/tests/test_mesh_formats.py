"""Mesh files of every format through the RON path route (`Scene.from_ron` / `Scene.add`
with `Mesh(path: ...)`, relative to `base_dir`): the STL, ASCII STL, OFF and GLB twins of
scenes/meshes/icosphere2.ply give the PLY's hits exactly; a malformed file's error names it."""

import numpy as np
import pytest

import zeroset

FORMATS = ["icosphere2.stl", "icosphere2_ascii.stl", "icosphere2.off", "icosphere2.glb"]


def scene_of(repo, name):
    text = f'Scene(camera: (), objects: [(shape: Mesh(path: "{name}", normals: false))])'
    return zeroset.Scene.from_ron(text, base_dir=str(repo / "scenes" / "meshes"))


def rays(n=5000, seed=45):
    rng = np.random.default_rng(seed)
    origins = rng.normal(size=(n, 3))
    origins *= rng.uniform(1.5, 4.0, (n, 1)) / np.linalg.norm(origins, axis=1)[:, None]
    targets = rng.normal(size=(n, 3)) * 0.5
    return origins, targets - origins


@pytest.mark.parametrize("name", FORMATS)
def test_each_format_gives_the_plys_hits(repo, name):
    origins, directions = rays()
    want = scene_of(repo, "icosphere2.ply").cast_rays(origins, directions)
    got = scene_of(repo, name).cast_rays(origins, directions)
    assert want["hit"].sum() > 2000
    np.testing.assert_array_equal(got["hit"], want["hit"])
    np.testing.assert_array_equal(got["t"], want["t"])


def test_add_loads_a_glb_node_and_a_bad_stl_names_its_file(repo, tmp_path):
    scene = zeroset.Scene.from_ron("Scene(camera: (), objects: [])")
    base = str(repo / "scenes" / "meshes")
    scene.add('Mesh(path: "icosphere2.glb", node: "root")', base_dir=base)
    assert scene.object_count == 1
    bad = tmp_path / "short.stl"
    bad.write_bytes(b"\0" * 84 + b"\1\0\0")
    with pytest.raises(Exception, match="short.stl.*84-byte header|short.stl.*binary STL"):
        scene.add('Mesh(path: "short.stl")', base_dir=str(tmp_path))
