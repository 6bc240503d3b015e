"""The Python API against independent references: `zeroset query` and `zeroset render` output
(the same rays through the CLI), closed forms in float64, and every error path."""

import math
import pickle
import re
import subprocess

import numpy as np
import pytest

import zeroset

SPHERE_SCENE = """Scene(
    camera: (eye: (0, 0, -6), look_at: (0, 0, 0), width: 48, height: 32),
    objects: [
        (name: "ball", shape: Sphere(center: (0.25, -0.5, 1), radius: 1.5)),
        (name: "crate", shape: Box(min: (1, 1, 0), max: (2, 2, 1))),
    ],
)"""


def random_rays(n, seed=1):
    rng = np.random.default_rng(seed)
    origins = rng.uniform(-4, 4, (n, 3))
    targets = rng.uniform(-1.5, 1.5, (n, 3))
    return origins, targets - origins


def test_cast_rays_equals_zeroset_query(cli, tmp_path, repo):
    scene_path = repo / "scenes" / "default.ron"
    scene = zeroset.Scene.load(scene_path)
    origins, directions = random_rays(2000)
    rays_csv = tmp_path / "rays.csv"
    np.savetxt(rays_csv, np.hstack([origins, directions]), delimiter=",", fmt="%.17g")
    hits_csv = tmp_path / "hits.csv"
    subprocess.run([cli, "query", str(scene_path), "--rays", str(rays_csv), "-o", str(hits_csv)], check=True,
                   capture_output=True)
    lines = hits_csv.read_text().splitlines()
    assert lines[0].startswith("hit,t,px,py,pz,nx,ny,nz,id")
    header = lines[0].split(",")
    rows = [dict(zip(header, line.split(","))) for line in lines[1:]]
    assert len(rows) == len(origins)
    got = scene.cast_rays(origins, directions)
    assert got["hit"].sum() > 500, "the rays should hit the scene often"
    for i, row in enumerate(rows):
        assert bool(int(row["hit"])) == bool(got["hit"][i])
        if got["hit"][i]:
            assert float(row["t"]) == got["t"][i]
            assert [float(row[k]) for k in ("px", "py", "pz")] == got["point"][i].tolist()
            assert [float(row[k]) for k in ("nx", "ny", "nz")] == got["normal"][i].tolist()
            assert int(row["id"]) == got["object_id"][i]
        else:
            assert got["t"][i] == math.inf and got["object_id"][i] == -1


def test_cast_rays_sphere_closed_form():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    rng = np.random.default_rng(7)
    centre = np.array([0.25, -0.5, 1.0])
    origins = rng.uniform(-6, 6, (5000, 3)).astype(np.float32)  # float32 input accepted
    targets = centre + rng.normal(size=(5000, 3)) * 0.8
    directions = targets - origins
    got = scene.cast_rays(origins, directions, tmax=1e9)
    # float64 closed form of the same rays: |o + t d - c|² = r²
    o = origins.astype(np.float64)
    oc = o - centre
    a = np.einsum("ij,ij->i", directions, directions)
    b = np.einsum("ij,ij->i", oc, directions)
    c = np.einsum("ij,ij->i", oc, oc) - 1.5 ** 2
    disc = b * b - a * c
    t_near = (-b - np.sqrt(np.maximum(disc, 0))) / a
    t_far = (-b + np.sqrt(np.maximum(disc, 0))) / a
    t_ref = np.where(t_near >= 0, t_near, t_far)
    on_sphere = got["object_id"] == 0
    assert on_sphere.sum() > 3000
    np.testing.assert_allclose(got["t"][on_sphere], t_ref[on_sphere], rtol=1e-12)
    p = o[on_sphere] + got["t"][on_sphere, None] * directions[on_sphere]
    np.testing.assert_allclose(got["normal"][on_sphere], (p - centre) / 1.5, atol=1e-9)
    np.testing.assert_allclose(got["point"][on_sphere], p, atol=1e-9)


def test_leading_dimensions_and_broadcast():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    origins = np.zeros((4, 5, 3)) + [0.25, -0.5, -6.0]
    got = scene.cast_rays(origins, [0.0, 0.0, 1.0])
    assert got["t"].shape == (4, 5)
    assert got["point"].shape == (4, 5, 3)
    assert got["uv"].shape == (4, 5, 2)
    np.testing.assert_array_equal(got["t"], np.full((4, 5), 7.0 - 1.5))
    per_ray_tmax = np.full((4, 5), 5.0)
    assert not scene.cast_rays(origins, [0.0, 0.0, 1.0], tmax=per_ray_tmax)["hit"].any()


def test_occlusion_and_intersection_counts():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    inside = np.array([[0.25, -0.5, 1.0], [0.5, -0.5, 1.0]])
    outside = np.array([[0.25, -0.5, -6.0], [0.25, -0.5, -3.0]])
    d = np.array([[0.0, 0.0, 1.0]] * 2)
    np.testing.assert_array_equal(scene.count_intersections(inside, d), [1, 1])
    np.testing.assert_array_equal(scene.count_intersections(outside, d), [2, 2])
    np.testing.assert_array_equal(scene.test_occlusions(outside, d, tmax=[4.0, 3.0]), [False, True])


def closed_icosahedron():
    p = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0], [0, -1, p], [0, 1, p],
                  [0, -1, -p], [0, 1, -p], [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], dtype=np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    return v, f


def test_mesh_in_code_inside_test_and_primitive_ids():
    scene = zeroset.Scene.empty()
    v, f = closed_icosahedron()
    mesh_id = scene.add_mesh(v, f, name="ico")
    assert mesh_id == 0 and scene.object_names == ["ico"]
    rng = np.random.default_rng(3)
    points = rng.uniform(-0.7, 0.7, (500, 3))  # inside the inscribed sphere (radius ≈ 1.51)
    dirs = rng.normal(size=(500, 3))
    counts = scene.count_intersections(points, dirs)
    np.testing.assert_array_equal(counts, 1)
    far = points * 0 + [0.0, 0.0, 10.0]
    hits = scene.cast_rays(far, -far)
    assert hits["hit"].all()
    # the face hit is the one whose plane is at the reported t: check with float64 geometry
    for i in range(5):
        a, b, c = v[f[hits["primitive_id"][i]]]
        n = np.cross(b - a, c - a)
        assert abs(np.dot(hits["point"][i] - a, n)) < 1e-6 * np.linalg.norm(n)


def test_add_with_keywords_and_transform():
    scene = zeroset.Scene.empty()
    moved = np.eye(4)
    moved[:3, 3] = [0, 0, 3]
    scene.add("Sphere", radius=1.0, name="a", transform=moved)
    scene.add("Box(min: (-1, -1, -1), max: (1, 1, 1))", transform=np.diag([2.0, 1.0, 1.0, 1.0]))
    got = scene.cast_rays([[0, 0, -10], [0, 0, 10], [-10, 0, 0]], [[0, 0, 1], [0, 0, -1], [1, 0, 0]])
    np.testing.assert_array_equal(got["object_id"], [1, 0, 1])
    np.testing.assert_allclose(got["t"], [9.0, 6.0, 8.0], rtol=0, atol=1e-12)


def test_render_equals_the_exr_of_the_cli(cli, tmp_path, repo):
    scene_path = repo / "scenes" / "default.ron"
    aovs = ["Beauty", "Alpha", "Depth", "Normal", "Position", "PrimitiveId", "Uv"]
    subprocess.run([cli, "render", str(scene_path), "-o", str(tmp_path / "f.exr"), "--width", "96", "--height",
                    "54", "--no-previews", "--aov", ",".join(aovs)], check=True, capture_output=True)
    from_cli, header = zeroset.read_exr(tmp_path / "f.exr")
    got = zeroset.Scene.load(scene_path).render(aovs=aovs, width=96, height=54)
    assert set(got) == set(aovs)
    for name in aovs:
        assert got[name].dtype == np.float32
        np.testing.assert_array_equal(got[name], from_cli[name], err_msg=name)
    assert header["display_window"] == (0, 0, 96, 54)
    # write_exr round trip keeps every value, +inf depth included
    zeroset.write_exr(tmp_path / "again.exr", got)
    back, _ = zeroset.read_exr(tmp_path / "again.exr")
    for name in aovs:
        np.testing.assert_array_equal(back[name], got[name], err_msg=name)
    assert np.isinf(got["Depth"]).any()


def test_crop_matches_full_frame():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    full = scene.render(aovs=["Depth", "Normal"])
    part = scene.render(aovs=["Depth", "Normal"], crop=(10, 5, 30, 20))
    np.testing.assert_array_equal(part["Depth"], full["Depth"][5:20, 10:30])
    np.testing.assert_array_equal(part["Normal"], full["Normal"][5:20, 10:30])


def test_render_into_views_of_larger_arrays():
    """``out`` takes views into larger arrays (rows contiguous, the views themselves not): the
    window's AOVs land there, equal to the returned arrays of a plain render, nothing around
    them is touched, and AOVs the render makes but ``out`` lacks are dropped."""
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    aovs = ["Depth", "Normal", "Alpha"]
    crop = (10, 5, 30, 20)
    ref = scene.render(aovs=aovs, crop=crop)
    depth = np.full((40, 60), -7.0, np.float32)
    normal = np.full((40, 60, 3), -7.0, np.float32)
    out = {"Depth": depth[3:18, 20:40], "Normal": normal[10:25, 1:21]}
    assert not out["Depth"].flags.c_contiguous
    got = scene.render(aovs=aovs, crop=crop, out=out)
    assert got is out
    np.testing.assert_array_equal(depth[3:18, 20:40], ref["Depth"])
    np.testing.assert_array_equal(normal[10:25, 1:21], ref["Normal"])
    assert np.isfinite(ref["Depth"]).any() and np.isinf(ref["Depth"]).any()
    depth[3:18, 20:40] = -7.0
    normal[10:25, 1:21] = -7.0
    assert (depth == -7.0).all() and (normal == -7.0).all()


def test_render_into_rejects_arrays_it_cannot_fill():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    kw = dict(aovs=["Depth", "Normal"], width=20, height=10)

    def fails(out, pattern):
        with pytest.raises(zeroset.ZerosetError, match=pattern):
            scene.render(**kw, out=out)

    fails({"Depth": np.zeros((10, 21), np.float32)}, r'out\["Depth"\]: shape \[10, 21\], the render.s is \[10, 20\]')
    fails({"Normal": np.zeros((10, 20), np.float32)}, r'out\["Normal"\]: shape \[10, 20\], the render.s is \[10, 20, 3\]')
    fails({"Depth": np.zeros((10, 20), np.float64)}, r'out\["Depth"\]: a float32 numpy array expected')
    fails({"Alpha": np.zeros((10, 20), np.float32)}, r'out\["Alpha"\]: not an AOV of this render \(it makes Depth, Normal\)')
    fails({"Depth": np.zeros((20, 10), np.float32).T}, r'out\["Depth"\]: each row must be contiguous')
    fails({"Depth": np.zeros(200, np.float32)}, r'out\["Depth"\]: shape \[200\] is not \(H, W\) or \(H, W, C\)')
    frozen = np.zeros((10, 20), np.float32)
    frozen.flags.writeable = False
    fails({"Depth": frozen}, r'out\["Depth"\]: cannot be written')
    shared = np.zeros((10, 20, 3), np.float32)
    fails({"Depth": shared[:, :, 0].copy(), "Normal": shared, "Alpha": shared}, "cannot be written")


def test_rays_pinhole_reproduce_the_render():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    cam = scene.camera
    origins, directions = zeroset.rays_pinhole(cam.intrinsics(), cam.world_to_camera(), cam.width, cam.height)
    assert origins.shape == (32, 48, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, atol=1e-15)
    hits = scene.cast_rays(origins, directions)
    frame = scene.render(aovs=["Depth", "Distance"])
    hit = hits["hit"]
    assert (np.isfinite(frame["Depth"]) == hit).all()
    planar = hits["t"] * (directions @ cam.forward)
    np.testing.assert_allclose(frame["Depth"][hit], planar[hit], rtol=1e-6)
    np.testing.assert_allclose(frame["Distance"][hit], hits["t"][hit], rtol=1e-6)


def test_rays_pinhole_opencv_convention():
    k = np.array([[100.0, 0, 2.0], [0, 50.0, 1.0], [0, 0, 1]])
    world_to_camera = np.eye(4)
    world_to_camera[:3, 3] = [1.0, 2.0, 3.0]  # the camera sits at (-1, -2, -3)
    o, d = zeroset.rays_pinhole(k, world_to_camera, 5, 3)
    np.testing.assert_array_equal(o[0, 0], [-1.0, -2.0, -3.0])
    np.testing.assert_allclose(d[1, 2], [0, 0, 1], atol=0)  # pixel (u=2, v=1) is the principal point
    ref = np.array([(4 - 2.0) / 100, (0 - 1.0) / 50, 1.0])  # pixel (u=4, v=0): right and up (−y)
    np.testing.assert_allclose(d[0, 4], ref / np.linalg.norm(ref), rtol=1e-15)


def test_pickle_rebuilds_identically():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    v, f = closed_icosahedron()
    scene.add_mesh(v * 0.3, f, transform=np.array([[1, 0, 0, -2], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    scene.add("Cylinder", radius=0.2, height=1.0)
    copy = pickle.loads(pickle.dumps(scene))
    assert copy.object_count == scene.object_count == 4
    a = scene.render(aovs=["Depth", "PrimitiveId"])
    b = copy.render(aovs=["Depth", "PrimitiveId"])
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


def test_add_mesh_refuses_float_indices_that_are_not_integers():
    vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    scene = zeroset.Scene.empty()
    for bad, shown in [([[0, 1.7, 2.9]], "1.7 at (0, 1)"), ([[0, 1, np.nan]], "nan at (0, 2)"),
                       ([[0.0, 1.0, 2.5]], "2.5 at (0, 2)")]:
        expected = re.escape("add_mesh: triangle indices must be integers, got " + shown)
        with pytest.raises(zeroset.ZerosetError, match=expected):
            scene.add_mesh(vertices, bad)
    with pytest.raises(zeroset.ZerosetError, match="must be integers, got dtype bool"):
        scene.add_mesh(vertices, np.array([[True, False, True]]))
    assert scene.object_count == 0
    # floats with integer values are indices
    assert scene.add_mesh(vertices, np.array([[0.0, 1.0, 2.0]])) == 0
    hits = scene.cast_rays([[0.2, 0.2, -1.0]], [[0.0, 0.0, 1.0]])
    assert hits["hit"][0] and hits["t"][0] == pytest.approx(1.0)


def test_add_mesh_with_degenerate_triangles_warns_as_a_scene_file_does():
    # every triangle of zero area: a mesh with no surface, never hit, with the loader's warning
    flat = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]
    scene = zeroset.Scene.empty()
    with pytest.warns(UserWarning, match=re.escape(
            "add_mesh: all 2 triangles are degenerate (zero area): the mesh has no surface and is never hit")):
        assert scene.add_mesh(flat, [[0, 1, 2], [0, 0, 3]]) == 0
    assert scene.object_count == 1
    hits = scene.cast_rays([[0.5, 0.0, -1.0], [0.0, 0.0, -1.0]], [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    assert not hits["hit"].any()
    # some of them: the others are hit, and the degenerate ones are counted
    with pytest.warns(UserWarning, match=re.escape(
            "add_mesh: 1 of 2 triangles are degenerate (zero area) and are never hit")):
        assert scene.add_mesh(flat, [[0, 1, 3], [0, 1, 2]]) == 1
    hits = scene.cast_rays([[0.2, 0.2, -1.0]], [[0.0, 0.0, 1.0]])
    assert hits["hit"][0] and hits["t"][0] == pytest.approx(1.0)
    assert scene.object_count == 2


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: zeroset.Scene.from_ron("Scene(camera: (eye: (0, 0, 1)), objcts: [])", "bad.ron"),
         "bad.ron:1:33: Unexpected field named `objcts`"),
        (lambda: zeroset.Scene.from_ron("Scene(camera: (eye: (0,0,1)), objects: [(shape: Sphere(radius: -1))])"),
         "objects[0] (Sphere): field `radius`"),
        (lambda: zeroset.Scene.load("/nonexistent/scene.ron"), "/nonexistent/scene.ron"),
        (lambda: zeroset.Scene.empty().add("Sphere(radius: 0)"), "field `radius`"),
        (lambda: zeroset.Scene.empty().add("Shpere(radius: 1)"), "unknown primitive `Shpere`"),
        (lambda: zeroset.Scene.empty().add("Sphere", radius=1, transform=np.zeros((4, 4))), "last row"),
        (lambda: zeroset.Scene.empty().add("Sphere", radius=1, transform=np.diag([1, 1, 0, 1.0])), "transform"),
        (lambda: zeroset.Scene.empty().add_mesh([[0, 0, 0]], [[0, 1, 2]]), "triangle indices"),
        (lambda: zeroset.Scene.empty().add_mesh([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]), "add_mesh"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).cast_rays([[0, 0, 0]], [[0, 0, 0]]), "non-zero"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).cast_rays([[0, 0, np.nan]], [[0, 0, 1]]), "finite"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).cast_rays([[0, 0]], [[0, 0]]), "dimension of 3"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).cast_rays([[0, 0, 0]], [[0, 0, 1]], tmin=2, tmax=1),
         "invalid t range"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).cast_rays(np.zeros((3, 3)), [[0, 0, 1]] * 3,
                                                                tmax=[1.0, 2.0]), "tmax"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(aovs=["Depht"]), "Depht: unknown AOV"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(crop=(0, 0, 100, 10)), "crop"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(spp=0), "spp"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(width=0), "width"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(depth_miss=float("nan")), "NaN"),
        (lambda: zeroset.Scene.from_ron(SPHERE_SCENE).render(view=dict(eye=(0, 0, 0), look_at=(0, 0, 0))), "view"),
        (lambda: zeroset.rays_pinhole(np.eye(3) * [0, 1, 1], np.eye(4), 4, 4), "fx"),
        (lambda: zeroset.rays_pinhole([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]], np.eye(4), 4, 4), "skew"),
        (lambda: zeroset.rays_pinhole(np.eye(3), np.zeros((4, 4)), 4, 4), "extrinsics"),
        (lambda: zeroset.write_exr("/tmp/x.exr", {"Depht": np.zeros((2, 2))}), "not an AOV"),
        (lambda: zeroset.write_exr("/tmp/x.exr", {"Normal": np.zeros((2, 2))}), "Normal"),
    ],
)
def test_errors_are_exceptions_with_the_cli_messages(call, message):
    with pytest.raises((zeroset.ZerosetError, OSError)) as info:
        call()
    assert message in str(info.value)


def test_same_message_as_the_cli(cli, tmp_path):
    bad = tmp_path / "bad.ron"
    bad.write_text("Scene(camera: (eye: (0, 0, 1)),\n  objects: [(shape: Sphere(radius: 1, colour: 2))])")
    run = subprocess.run([cli, "render", str(bad), "-o", str(tmp_path)], capture_output=True, text=True)
    assert run.returncode != 0
    with pytest.raises(zeroset.ZerosetError) as info:
        zeroset.Scene.load(bad)
    assert str(info.value) in run.stderr


def test_help_explains_conventions():
    doc = zeroset.Scene.cast_rays.__doc__
    assert "+inf" in doc and "primitive_id" in doc and "tmin" in doc


def test_rays_pinhole_with_distortion_reproduce_an_opencv_render(repo):
    scene = zeroset.Scene.load(repo / "scenes" / "cameras" / "opencv.ron")
    cam = scene.camera
    assert cam.model == "OpenCv" and np.any(cam.distortion() != 0)
    w, h = 64, 48
    k = cam.intrinsics() * [[w / cam.width], [h / cam.height], [1]]
    k[0, 2] = (cam.intrinsics()[0, 2] + 0.5) * w / cam.width - 0.5
    k[1, 2] = (cam.intrinsics()[1, 2] + 0.5) * h / cam.height - 0.5
    origins, directions = zeroset.rays_pinhole(k, cam.world_to_camera(), w, h, distortion=cam.distortion())
    hits = scene.cast_rays(origins, directions)
    frame = scene.render(aovs=["Distance"], width=w, height=h)
    assert hits["hit"].sum() > 100
    np.testing.assert_array_equal(np.isfinite(frame["Distance"]), hits["hit"])
    np.testing.assert_allclose(frame["Distance"][hits["hit"]], hits["t"][hits["hit"]], rtol=1e-6)


def test_range_is_open_at_tmin_unless_closed():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    on_surface = np.array([[0.25, -0.5, -0.5]])  # the sphere's front pole, exactly
    inward = np.array([[0.0, 0.0, 1.0]])
    open_hit = scene.cast_rays(on_surface, inward)
    assert open_hit["t"][0] == 3.0  # the far side: |2r|
    assert scene.cast_rays(on_surface, inward, closed=True)["t"][0] == 0.0


def test_spawned_rays_from_float32_points_equal_the_cli(cli, tmp_path):
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    rng = np.random.default_rng(21)
    origins = rng.uniform(-5, 5, (3000, 3))
    centre = np.array([0.25, -0.5, 1.0])
    hits = scene.cast_rays(origins, centre - origins)
    hit = hits["hit"] & (hits["object_id"] == 0)
    points = hits["point"][hit].astype(np.float32).astype(np.float64)  # stored as float32
    normals = hits["normal"][hit]
    leaving = normals + rng.normal(size=normals.shape) * 0.3  # rays leaving the sphere
    leaving[np.einsum("ij,ij->i", leaving, normals) <= 0] *= -1
    naive = scene.cast_rays(points, leaving)
    assert (naive["object_id"] == 0).sum() > 50, "float32 points re-hit their own sphere"
    spawned = scene.cast_rays(points, leaving, origin_precision="f32", normals=normals)
    assert (spawned["object_id"] == 0).sum() == 0
    # the same rays through `zeroset query --origin-precision f32`
    rays_csv = tmp_path / "rays.csv"
    np.savetxt(rays_csv, np.hstack([points, leaving, normals]), delimiter=",", fmt="%.17g")
    out = tmp_path / "hits.csv"
    scene_file = tmp_path / "s.ron"
    scene_file.write_text(SPHERE_SCENE)
    subprocess.run([cli, "query", str(scene_file), "--rays", str(rays_csv), "--origin-precision", "f32", "-o",
                    str(out)], check=True, capture_output=True)
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    assert [r[0] == "1" for r in rows] == spawned["hit"].tolist()
    t_cli = np.array([float(r[1]) if r[0] == "1" else np.inf for r in rows])
    np.testing.assert_array_equal(t_cli, spawned["t"])


def test_cast_rays_over_many_chunks_equals_rays_cast_one_by_one():
    # more than four chunks of rays (the last one partial), per-ray ranges: each ray's answer is
    # the one it gets alone
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    origins, directions = random_rays(4500, seed=11)
    tmax = np.where(np.arange(4500) % 7 == 0, 2.0, np.inf)
    got = scene.cast_rays(origins, directions, tmax=tmax)
    assert 1000 < got["hit"].sum() < 4400
    assert (got["t"][~got["hit"]] == np.inf).all() and (got["object_id"][~got["hit"]] == -1).all()
    for i in range(0, 4500, 37):
        alone = scene.cast_rays(origins[i], directions[i], tmax=tmax[i])
        for k in alone:
            np.testing.assert_array_equal(got[k][i], alone[k], err_msg=f"{k} of ray {i}")


def test_uncertain_misses_among_certain_ones():
    # a root finder with the smallest budget, 2 evaluations, runs out on rays that cross a thin
    # shell (the walls 2e-4 apart need more): they are misses flagged uncertain, written row by
    # row among the certain misses (which cast_rays writes a column at a time); each row is what
    # the ray gets alone
    scene = zeroset.Scene.from_ron(
        'Scene(camera: (), objects: [(shape: Function(phi: "abs(sqrt(x^2 + y^2 + z^2) - 1) - 1e-4", '
        "min: (-2, -2, -2), max: (2, 2, 2), budget: 2))])"
    )
    rng = np.random.default_rng(5)
    n = 3000
    origins = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), np.full(n, -4.0)])
    directions = np.tile([0.0, 0.0, 1.0], (n, 1))
    got = scene.cast_rays(origins, directions)
    assert 100 < got["uncertain"].sum() < n
    # flagged rays are the budget's misses; rays missing the box are never flagged
    assert not got["hit"][got["uncertain"]].any()
    outside_box = (np.abs(origins[:, 0]) > 2) | (np.abs(origins[:, 1]) > 2)
    assert outside_box.sum() > 100 and not got["uncertain"][outside_box].any()
    miss = ~got["hit"]
    assert (got["t"][miss] == math.inf).all() and (got["point"][miss] == 0).all()
    assert (got["normal"][miss] == 0).all() and (got["uv"][miss] == 0).all()
    assert (got["object_id"][miss] == -1).all() and (got["primitive_id"][miss] == -1).all()
    for i in range(0, n, 23):
        alone = scene.cast_rays(origins[i], directions[i])
        for k in alone:
            np.testing.assert_array_equal(got[k][i], alone[k], err_msg=f"{k} of ray {i}")


def test_cast_rays_outputs_asked_for_only():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    origins, directions = random_rays(3000, seed=12)
    full = scene.cast_rays(origins, directions)
    assert list(full) == ["t", "hit", "point", "normal", "object_id", "uv", "primitive_id", "uncertain"]
    some = scene.cast_rays(origins, directions, outputs=["normal", "t"])
    assert sorted(some) == ["normal", "t"]
    np.testing.assert_array_equal(some["t"], full["t"])
    np.testing.assert_array_equal(some["normal"], full["normal"])
    # without a normal (not computed then) and without uv: the rest unchanged
    for names in (["uv", "point", "primitive_id"], ["t", "hit", "object_id"]):
        some = scene.cast_rays(origins, directions, outputs=names)
        for name in names:
            np.testing.assert_array_equal(some[name], full[name], err_msg=name)
    assert scene.cast_rays(origins[:5], directions[:5], outputs=[]) == {}
    with pytest.raises(zeroset.ZerosetError, match="outputs: unknown field `depth`"):
        scene.cast_rays(origins, directions, outputs=["t", "depth"])


def test_cast_rays_float32_is_float64_rounded():
    # the real fields in float32 are the float64 answers rounded to nearest, misses included
    # (+inf, zeros); the other fields are the same arrays; a batch large enough for memory of its
    # own (4 MiB and more) and a small one
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    for n, seed in ((3000, 31), (400_000, 32)):
        origins, directions = random_rays(n, seed=seed)
        wide = scene.cast_rays(origins, directions)
        narrow = scene.cast_rays(origins, directions, dtype=np.float32)
        assert list(narrow) == list(wide)
        assert 0 < wide["hit"].sum() < n
        for name in ("t", "point", "normal", "uv"):
            assert narrow[name].dtype == np.float32, name
            np.testing.assert_array_equal(narrow[name], wide[name].astype(np.float32), err_msg=name)
        for name in ("hit", "object_id", "primitive_id", "uncertain"):
            assert narrow[name].dtype == wide[name].dtype, name
            np.testing.assert_array_equal(narrow[name], wide[name], err_msg=name)
        assert np.isinf(narrow["t"][~wide["hit"]]).all()
    some = scene.cast_rays(origins[:50], directions[:50], outputs=["uv"], dtype="float32")
    assert list(some) == ["uv"] and some["uv"].dtype == np.float32
    with pytest.raises(zeroset.ZerosetError, match="dtype: expected numpy.float64 or numpy.float32, got float16"):
        scene.cast_rays(origins[:5], directions[:5], dtype=np.float16)


def test_large_outputs_reused_memory_keeps_every_answer():
    # arrays of 4 MiB and more live in memory of their own, kept for the next batch once their
    # arrays are gone: a batch written into memory another batch left behind, a batch whose
    # memory another one still holds, and a batch after an error all give exactly the answers
    # of the same rays cast in small pieces (numpy's own arrays)
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    n = 200_000  # point and normal (4.8 MB) in mappings of their own, t (1.6 MB) numpy's
    a_rays = random_rays(n, seed=21)
    b_rays = random_rays(n, seed=22)

    def pieces(rays):
        parts = [scene.cast_rays(o, d) for o, d in zip(np.array_split(rays[0], 60), np.array_split(rays[1], 60))]
        return {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}

    a_expected, b_expected = pieces(a_rays), pieces(b_rays)
    kept = scene.cast_rays(*a_rays)
    for _ in range(3):
        b = scene.cast_rays(*b_rays)  # into memory B's last batch left behind, A's still held
        for k in b_expected:
            np.testing.assert_array_equal(b[k], b_expected[k], err_msg=k)
        del b
    for k in a_expected:
        np.testing.assert_array_equal(kept[k], a_expected[k], err_msg=k)
    bad = (a_rays[0].copy(), a_rays[1].copy())
    bad[1][n - 3] = 0.0
    with pytest.raises(zeroset.ZerosetError, match=f"^ray {n - 3}: direction must be non-zero"):
        scene.cast_rays(*bad)
    del kept
    again = scene.cast_rays(*a_rays)
    assert again["point"].base is not None and again["point"].flags["WRITEABLE"]
    for k in a_expected:
        np.testing.assert_array_equal(again[k], a_expected[k], err_msg=k)


def test_first_bad_ray_by_index_over_chunks():
    # bad rays in the fourth chunk and in the second: the message names the earlier one
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    origins, directions = random_rays(5000, seed=13)
    directions[3500] = 0.0
    origins[1500, 1] = np.inf
    with pytest.raises(zeroset.ZerosetError, match=r"^ray 1500: origin and direction must be finite"):
        scene.cast_rays(origins, directions)
    with pytest.raises(zeroset.ZerosetError, match=r"^ray 1500: "):
        scene.test_occlusions(origins, directions)


def test_render_threads_gives_the_same_frame():
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    aovs = ["Depth", "Normal", "PrimitiveId"]
    default = scene.render(aovs=aovs, width=61, height=47)
    for threads in (1, 3):
        got = scene.render(aovs=aovs, width=61, height=47, threads=threads)
        for k in aovs:
            np.testing.assert_array_equal(got[k], default[k], err_msg=f"{k}, {threads} threads")
    assert np.isfinite(default["Depth"]).sum() > 100
    with pytest.raises(zeroset.ZerosetError, match="threads must be at least 1"):
        scene.render(aovs=aovs, width=8, height=8, threads=0)


def test_large_renders_keep_their_own_memory():
    """Planes of 4 MiB and more are rendered into pooled mappings: a frame still held keeps its
    values while later renders of the same size (another view, then the first again) reuse
    memory freed in between. The frame (1.2 million pixels) is rendered in two bands through one
    reused band buffer, and equals crops of it rendered alone."""
    scene = zeroset.Scene.from_ron(SPHERE_SCENE)
    aovs = ["Depth", "Normal"]
    size = dict(width=1600, height=750)
    first = scene.render(aovs=aovs, **size)
    kept = {k: v.copy() for k, v in first.items()}
    assert first["Normal"].nbytes >= 4 << 20 and first["Normal"].flags.c_contiguous
    other = scene.render(aovs=aovs, view=dict(eye=(0.5, 0.3, -4.0)), **size)
    assert not np.array_equal(other["Depth"], first["Depth"])
    for k in aovs:
        np.testing.assert_array_equal(first[k], kept[k], err_msg=k)
    other = None  # its memory back to the pool, for the next render to reuse
    again = scene.render(aovs=aovs, **size)
    for k in aovs:
        np.testing.assert_array_equal(again[k], kept[k], err_msg=k)
    # the same pixels as crops rendered one by one (each a single band)
    for y0, y1 in ((0, 300), (300, 750)):
        crop = scene.render(aovs=aovs, crop=(0, y0, 1600, y1), **size)
        for k in aovs:
            np.testing.assert_array_equal(crop[k], kept[k][y0:y1], err_msg=f"{k} rows {y0}..{y1}")
    assert np.isfinite(kept["Depth"]).sum() > 10_000
