"""Point queries and every crossing along rays from Python: closed forms for analytic shapes,
signs on a mesh against the sphere it approximates, Open3D's layout and (where Open3D installs)
its distances and crossing counts on the same mesh."""

import numpy as np
import pytest

import zeroset


def icosphere(levels=3):
    g = (1 + 5 ** 0.5) / 2
    v = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g), (0, -1, -g), (0, 1, -g),
         (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                mid[key] = len(v) - 1
            return mid[key]

        f = [t for a, b, c in f for t in ((a, middle(a, b), middle(c, a)), (b, middle(b, c), middle(a, b)),
                                          (c, middle(c, a), middle(b, c)),
                                          (middle(a, b), middle(b, c), middle(c, a)))]
    return np.array(v, np.float32), np.array(f, np.uint32)


def test_distances_to_a_sphere_and_a_box_are_their_closed_forms():
    scene = zeroset.Scene.empty()
    scene.add("Sphere(center: (0, 0, 0), radius: 1)")
    scene.add("Box(min: (2, -1, -1), max: (4, 1, 1))")
    rng = np.random.default_rng(3)
    p = rng.uniform(-3, 5, (5000, 3))
    sphere = np.abs(np.linalg.norm(p, axis=1) - 1)
    outside = np.maximum(np.maximum(np.array([2, -1, -1]) - p, p - np.array([4, 1, 1])), 0)
    inside = np.minimum(np.min(p - np.array([2, -1, -1]), axis=1), np.min(np.array([4, 1, 1]) - p, axis=1))
    box = np.where(np.all(outside == 0, axis=1), np.abs(inside), np.linalg.norm(outside, axis=1))
    expected = np.minimum(sphere, box)
    np.testing.assert_allclose(scene.compute_distance(p), expected, rtol=1e-12, atol=1e-12)
    closest = scene.compute_closest_points(p)
    np.testing.assert_allclose(np.linalg.norm(closest["points"] - p, axis=1), expected, rtol=1e-12, atol=1e-12)
    assert np.array_equal(closest["lower"], closest["upper"])
    assert np.array_equal(closest["geometry_ids"], (box < sphere).astype(np.uint32))
    occupied = (np.linalg.norm(p, axis=1) < 1) | np.all((p > [2, -1, -1]) & (p < [4, 1, 1]), axis=1)
    assert np.array_equal(scene.compute_occupancy(p), occupied.astype(np.float32))
    signed = scene.compute_signed_distance(p)
    np.testing.assert_allclose(signed, np.where(occupied, -expected, expected), rtol=1e-12, atol=1e-12)
    # Φ of the scene is negative exactly inside, and its gradient at the sphere's points is radial
    assert np.array_equal(scene.phi(p) < 0, occupied)
    near_sphere = sphere < box
    g = scene.gradient(p[near_sphere])
    np.testing.assert_allclose(g / np.linalg.norm(g, axis=1)[:, None],
                               p[near_sphere] / np.linalg.norm(p[near_sphere], axis=1)[:, None], atol=1e-9)


@pytest.mark.parametrize("sign", ["fast-winding", "winding", "pseudonormal", "parity"])
def test_signs_on_a_sphere_mesh_agree_with_the_sphere_outside_a_band(sign):
    v, f = icosphere(3)
    scene = zeroset.Scene.empty()
    scene.add_mesh(v, f)
    rng = np.random.default_rng(5)
    p = rng.uniform(-1.5, 1.5, (20000, 3))
    r = np.linalg.norm(p, axis=1)
    away = np.abs(r - 1) > 0.05  # beyond the chords' sag (edge ≈ 0.16)
    occupancy = scene.compute_occupancy(p, sign=sign)
    assert np.array_equal(occupancy[away], (r[away] < 1).astype(np.float32))
    signed = scene.compute_signed_distance(p, sign=sign)
    assert np.array_equal(signed[away] < 0, r[away] < 1)
    np.testing.assert_allclose(np.abs(signed), scene.compute_distance(p))


def test_list_intersections_is_open3d_s_layout_and_count_intersections_its_length():
    v, f = icosphere(2)
    scene = zeroset.Scene.empty()
    scene.add_mesh(v, f)
    scene.add("Sphere(center: (3, 0, 0), radius: 0.5)")
    rng = np.random.default_rng(8)
    origins = rng.uniform(-4, 4, (4000, 3))
    directions = rng.uniform(-1, 1, (4000, 3)) * [3, 1, 1] + [1, 0, 0] - origins
    lists = scene.list_intersections(origins, directions)
    splits = lists["ray_splits"]
    assert splits[0] == 0 and splits[-1] == len(lists["t_hit"]) and len(splits) == 4001
    counts = np.diff(splits)
    assert np.array_equal(counts, scene.count_intersections(origins, directions))
    assert np.array_equal(lists["ray_ids"], np.repeat(np.arange(4000), counts.astype(np.int64)))
    for i in range(4000):
        t = lists["t_hit"][splits[i]:splits[i + 1]]
        assert np.all(np.diff(t) > 0)
    # along each ray, for each object, crossings alternate entering and leaving; the first
    # from outside enters
    first = scene.cast_rays(origins, directions)
    has = counts > 0
    np.testing.assert_allclose(lists["t_hit"][splits[:-1][has]], first["t"][has], rtol=1e-12)
    assert counts.sum() > 3000


def test_distances_and_crossings_agree_with_open3d():
    o3d = pytest.importorskip("open3d")
    v, f = icosphere(3)
    scene = zeroset.Scene.empty()
    scene.add_mesh(v, f)
    theirs = o3d.t.geometry.RaycastingScene()
    theirs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f))
    rng = np.random.default_rng(9)
    p = rng.uniform(-1.5, 1.5, (20000, 3)).astype(np.float32)
    ours = scene.compute_distance(p)
    o3 = theirs.compute_distance(o3d.core.Tensor(p)).numpy()
    # Open3D computes in float32
    np.testing.assert_allclose(ours, o3, rtol=1e-4, atol=1e-5)
    d = rng.normal(size=(20000, 3)).astype(np.float32)
    lists = scene.list_intersections(p, d)
    o3_lists = theirs.list_intersections(o3d.core.Tensor(np.hstack([p, d])))
    differ = np.diff(lists["ray_splits"]) != np.diff(o3_lists["ray_splits"].numpy())
    assert differ.sum() <= 2, f"{differ.sum()} crossing counts differ"
