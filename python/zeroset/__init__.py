"""zeroset for Python: exact ray casting of implicit surfaces, numpy arrays in and out.

A thin layer over the Rust crate: scenes load with the same parser as the ``zeroset`` command
(errors carry the same ``file:line:col`` messages), ``Scene.cast_rays`` runs the same query path
as ``zeroset query`` and ``Scene.render`` the same renderer that writes the EXR, with the GIL
released while rays are traced.

Conventions (the same as the command line's):

* Φ < 0 inside, 0 on the surface, > 0 outside; normals are the outward unit ∇Φ, never flipped
  toward the ray.
* ``t`` is in units of the direction you pass (metric distance for unit directions); a miss has
  ``t = +inf``.
* The default range of ``cast_rays`` is ``tmin=0, tmax=inf``.
* Camera space of ``Camera.world_to_camera`` / ``rays_pinhole`` is OpenCV's: +x right, +y down,
  +z forward, the centre of pixel (u, v) at the integer point (u, v).

Example::

    import zeroset, numpy as np
    scene = zeroset.Scene.load("scenes/default.ron")
    hits = scene.cast_rays(np.zeros((4, 3)), [[0, 0, 1]] * 4)
    depth = scene.render(aovs=["Depth"], width=320, height=180)["Depth"]
"""

from __future__ import annotations

import os
from typing import Any, Dict, Iterable, Optional, Sequence, Tuple

import numpy as np

from . import _zeroset
from ._zeroset import ZerosetError

__all__ = [
    "Scene",
    "Camera",
    "ZerosetError",
    "rays_pinhole",
    "write_exr",
    "read_exr",
    "shape_ron",
]


def _ron_value(value: Any) -> str:
    """A Python value written as RON: tuples and 1-D arrays of length ≤ 4 become tuples, lists
    and longer arrays become lists, dicts become structs, strings are quoted."""
    if isinstance(value, np.ndarray):
        if value.ndim == 1 and value.shape[0] <= 4:
            return "(" + ", ".join(_ron_value(v) for v in value.tolist()) + ")"
        return "[" + ", ".join(_ron_value(np.asarray(v)) if np.ndim(v) else _ron_value(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.integer, np.floating)):
        return repr(float(value)) if isinstance(value, (float, np.floating)) else str(int(value))
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, tuple):
        return "(" + ", ".join(_ron_value(v) for v in value) + ")"
    if isinstance(value, list):
        return "[" + ", ".join(_ron_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "(" + ", ".join(f"{k}: {_ron_value(v)}" for k, v in value.items()) + ")"
    if value is None:
        return "None"
    raise TypeError(f"cannot write {type(value).__name__} as a scene value")


def shape_ron(kind: str, **fields: Any) -> str:
    """``shape_ron("Sphere", center=(0, 0, 0), radius=1)`` → ``'Sphere(center: (0.0, ...), radius: 1)'``."""
    return f"{kind}(" + ", ".join(f"{k}: {_ron_value(v)}" for k, v in fields.items()) + ")"


def _rays(origins: Any, directions: Any) -> Tuple[np.ndarray, np.ndarray, Tuple[int, ...]]:
    o = np.asarray(origins)
    d = np.asarray(directions)
    if o.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ZerosetError(f"origins and directions must end in a dimension of 3, got {o.shape} and {d.shape}")
    o, d = np.broadcast_arrays(o, d)
    lead = o.shape[:-1]
    o = np.ascontiguousarray(o.reshape(-1, 3), dtype=np.float64)
    d = np.ascontiguousarray(d.reshape(-1, 3), dtype=np.float64)
    return o, d, lead


def _real_dtype(dtype: Any) -> np.dtype:
    """``dtype`` of ``cast_rays``' real outputs as a numpy dtype: float64 or float32, else an error."""
    real = np.dtype(dtype)
    if real not in (np.dtype(np.float64), np.dtype(np.float32)):
        raise ZerosetError(f"dtype: expected numpy.float64 or numpy.float32, got {real}")
    return real


def _range(value: Any, lead: Tuple[int, ...], name: str) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == 0:
        return v.reshape(1)
    try:
        return np.ascontiguousarray(np.broadcast_to(v, lead).reshape(-1))
    except ValueError:
        raise ZerosetError(f"{name}: shape {v.shape} does not match the rays' {lead}") from None


class Camera:
    """The scene's camera: ``intrinsics()`` (3×3 K) and ``world_to_camera()`` (4×4) in the OpenCV
    convention, so ``rays_pinhole(cam.intrinsics(), cam.world_to_camera(), cam.width,
    cam.height)`` gives the rays ``Scene.render`` traces (up to rounding)."""

    def __init__(self, info: Dict[str, Any]):
        self._info = info
        self.width: int = info["width"]
        self.height: int = info["height"]
        self.eye = np.array(info["eye"])
        self.forward = np.array(info["forward"])
        self.up = np.array(info["up"])
        self.right = np.array(info["right"])

    @property
    def model(self) -> str:
        """The projection model: Perspective, Orthographic, Equirectangular, Fisheye or OpenCv."""
        return self._info["model"]

    def intrinsics(self) -> np.ndarray:
        """3×3 K ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` (OpenCV: pixel centres at integers);
        raises for the equirectangular model, which has none."""
        if self._info["intrinsics"] is None:
            raise ZerosetError(f"the {self.model} camera has no intrinsic matrix")
        return np.array(self._info["intrinsics"])

    def distortion(self) -> np.ndarray:
        """OpenCV's ``[k1, k2, p1, p2, k3]`` of an ``OpenCv`` camera (zeros for the other models)."""
        return np.array(self._info["distortion"])

    def world_to_camera(self) -> np.ndarray:
        """4×4 world → camera (OpenCV: +x right, +y down, +z forward)."""
        return np.array(self._info["world_to_camera"])

    def world_to_camera_gl(self) -> np.ndarray:
        """4×4 world → camera as the EXR ``worldToCamera`` holds it (+y up, looking along −z)."""
        return np.array(self._info["world_to_camera_gl"])

    def __repr__(self) -> str:
        return f"Camera(eye={self.eye.tolist()}, forward={self.forward.tolist()}, {self.width}x{self.height})"


class Scene:
    """A zeroset scene: loaded from RON, built in code, or both.

    The recipe (RON text or path, plus every ``add``/``add_mesh``) is kept so a scene can be
    pickled to Dask workers and rebuilt there identically.
    """

    def __init__(self, core: "_zeroset._Scene", recipe: list):
        self._core = core
        self._recipe = recipe

    # construction ------------------------------------------------------------------------

    @staticmethod
    def load(path: "os.PathLike[str] | str") -> "Scene":
        """Reads, parses and validates a scene file (errors: ``ZerosetError`` with ``file:line:col``)."""
        path = os.fspath(path)
        return Scene(_zeroset._Scene.load(path), [("load", path)])

    @staticmethod
    def from_ron(text: str, path: str = "<string>", base_dir: Optional[str] = None) -> "Scene":
        """Parses scene text; ``path`` names it in messages, relative mesh paths resolve against
        ``base_dir`` (default: the current directory)."""
        return Scene(_zeroset._Scene.from_ron(text, path, base_dir), [("ron", text, path, base_dir)])

    @staticmethod
    def empty(eye=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), width: int = 640, height: int = 480,
              vfov_deg: float = 45.0) -> "Scene":
        """A scene with a pinhole camera and no objects, to fill with ``add``/``add_mesh``."""
        text = (f"Scene(camera: (eye: {_ron_value(tuple(map(float, eye)))}, "
                f"look_at: {_ron_value(tuple(map(float, look_at)))}, width: {int(width)}, "
                f"height: {int(height)}, vfov_deg: {float(vfov_deg)!r}), objects: [])")
        return Scene.from_ron(text, "<empty>")

    def add(self, shape: str, transform: Any = None, name: Optional[str] = None,
            material: Optional[Dict[str, Any]] = None, base_dir: Optional[str] = None, **fields: Any) -> int:
        """Adds a primitive and returns its object id.

        ``shape`` is RON (``"Sphere(radius: 1)"``) or a primitive name with its fields as keyword
        arguments (``scene.add("Sphere", center=(0, 0, 0), radius=1)``). ``transform`` is a 4×4
        affine world-from-local matrix (row-major, last row 0 0 0 1).
        """
        if fields:
            shape = shape_ron(shape, **fields)
        entry = f"(shape: {shape}"
        if name is not None:
            entry += f", name: {_ron_value(name)}"
        if material is not None:
            entry += f", material: {_ron_value(material)}"
        entry += ")"
        matrix = None if transform is None else _matrix4(transform, "transform")
        object_id = self._core.add_object(entry, matrix, base_dir)
        self._recipe.append(("add", entry, matrix, base_dir))
        return object_id

    def add_mesh(self, vertices: Any, triangles: Any, transform: Any = None, name: Optional[str] = None) -> int:
        """Adds a triangle mesh from ``(N, 3)`` vertices (stored as float32) and ``(M, 3)`` vertex
        indices (counter-clockwise seen from outside; integers, or floats with integer values);
        returns its object id. The arrays are converted without a per-element Python loop.
        Degenerate (zero-area) triangles are never hit, with a ``UserWarning`` giving their count;
        a mesh of nothing else is added as an object that is never hit, as a scene file's is."""
        v = np.ascontiguousarray(vertices, dtype=np.float32)
        t = np.asarray(triangles)
        if t.dtype.kind == "f":
            bad = ~np.isfinite(t) | (t != np.trunc(t))
            if bad.any():
                at = tuple(int(i) for i in np.argwhere(bad)[0])
                raise ZerosetError(f"add_mesh: triangle indices must be integers, got {float(t[at])} at {at}")
        elif t.size and t.dtype.kind not in "iu":
            raise ZerosetError(f"add_mesh: triangle indices must be integers, got dtype {t.dtype}")
        if t.size and (t.min() < 0 or t.max() >= len(v)):
            raise ZerosetError(f"add_mesh: triangle indices must lie in [0, {len(v)}), got [{t.min()}, {t.max()}]")
        t = np.ascontiguousarray(t, dtype=np.uint32)
        if v.ndim != 2 or t.ndim != 2:
            raise ZerosetError(f"add_mesh: expected vertices (N, 3) and triangles (M, 3), got {v.shape} and {t.shape}")
        matrix = None if transform is None else _matrix4(transform, "transform")
        object_id = self._core.add_mesh(v, t, matrix, name)
        self._recipe.append(("mesh", v, t, matrix, name))
        return object_id

    # pickling (Dask ships scenes to workers as their recipe) ------------------------------

    def __reduce__(self):
        return (_from_recipe, (self._recipe,))

    # queries -----------------------------------------------------------------------------

    @property
    def object_count(self) -> int:
        """Number of objects (ids run from 0)."""
        return self._core.object_count()

    @property
    def object_names(self) -> list:
        """Object names by id (``None`` where unnamed)."""
        return self._core.object_names()

    @property
    def camera(self) -> Camera:
        """The scene's camera."""
        return Camera(self._core.camera())

    def cast_rays(self, origins: Any, directions: Any, tmin: Any = 0.0, tmax: Any = np.inf, closed: bool = False,
                  origin_precision: Any = None, normals: Any = None,
                  outputs: Optional[Sequence[str]] = None, dtype: Any = np.float64) -> Dict[str, np.ndarray]:
        """First hits of rays ``origins + t·directions`` with ``tmin < t ≤ tmax`` — the range of
        ``zeroset query``: open at ``tmin`` (an origin lying on a surface does not report it at
        ``t = 0``), closed at both ends with ``closed=True``.

        Rays cast from stored hit points (a ``P`` read from an EXR, points saved as float32):
        pass their surface ``normals`` ``(..., 3)`` and ``origin_precision`` (``"f32"``,
        ``"f64"`` or an absolute error bound); each origin is moved off the surface exactly as
        ``zeroset query --origin-precision`` does, so the ray cannot re-hit it through rounding.

        ``origins`` and ``directions``: array-likes of float32/float64 shaped ``(..., 3)``
        (broadcast against each other); ``tmin``/``tmax``: scalars or arrays of the leading shape.
        Returns a dict of arrays shaped like the leading dimensions:

        * ``t`` float64, ``+inf`` on a miss (in units of ``|direction|``);
        * ``hit`` bool;
        * ``point`` float64 ``(..., 3)`` and ``normal`` float64 ``(..., 3)`` (outward unit ∇Φ),
          zero on a miss;
        * ``object_id`` int32, the object's index (-1 on a miss);
        * ``uv`` float64 ``(..., 2)``, the primitive's surface parameters (0 where it has none);
        * ``primitive_id`` int64: the part hit — a mesh's triangle index, a box's face, a
          cylinder's side or cap (-1 on a miss);
        * ``uncertain`` bool: the answer is not guaranteed (a root finder ran out of its budget or
          a ``Function`` root could not be decided exactly; ``zeroset query --uncertain``).

        ``outputs``: the names of the arrays wanted (default all of the above); the others are
        neither computed into nor allocated.

        ``dtype``: ``numpy.float64`` (default) or ``numpy.float32``, the type of ``t``,
        ``point``, ``normal`` and ``uv``. float32 values are the float64 ones rounded to nearest
        (``+inf`` stays ``+inf``): half the memory, and the dtype Open3D's ``cast_rays`` returns;
        the rays are traced exactly as with float64.

        The values equal ``zeroset query``'s on the same rays. The call runs without the GIL: rays
        are built from the arrays, traced and written into the returned arrays chunk by chunk on
        all cores (do not modify the input arrays from another thread meanwhile).
        """
        o, d, lead = _rays(origins, directions)
        n = None
        if normals is not None:
            n = np.ascontiguousarray(np.broadcast_to(np.asarray(normals, dtype=np.float64), lead + (3,)).reshape(-1, 3))
        precision = None if origin_precision is None else str(origin_precision)
        wanted = None if outputs is None else [str(name) for name in outputs]
        real = _real_dtype(dtype)
        out = self._core.cast_rays(o, d, _range(tmin, lead, "tmin"), _range(tmax, lead, "tmax"), bool(closed),
                                   precision, n, wanted, real == np.dtype(np.float32))
        return {k: v.reshape(lead + v.shape[1:]) for k, v in out.items()}

    def test_occlusions(self, origins: Any, directions: Any, tmin: Any = 0.0, tmax: Any = np.inf,
                        closed: bool = False) -> np.ndarray:
        """Whether any surface is hit with ``tmin < t ≤ tmax`` (``closed=True``: ``tmin ≤ t``),
        shaped like the leading dimensions."""
        o, d, lead = _rays(origins, directions)
        return self._core.test_occlusions(o, d, _range(tmin, lead, "tmin"), _range(tmax, lead, "tmax"),
                                          bool(closed)).reshape(lead)

    def count_intersections(self, origins: Any, directions: Any, tmin: Any = 0.0, tmax: Any = np.inf,
                            closed: bool = False) -> np.ndarray:
        """Number of surface crossings with ``tmin < t ≤ tmax`` (``closed=True``: ``tmin ≤ t``; an
        odd count: the origin is inside a closed surface). Crossings at one ``t`` (a shared mesh
        edge) count once."""
        o, d, lead = _rays(origins, directions)
        return self._core.count_intersections(o, d, _range(tmin, lead, "tmin"), _range(tmax, lead, "tmax"),
                                              bool(closed)).reshape(lead)

    def _points(self, points: Any, query: str, sign: str = "fast-winding") -> Tuple[np.ndarray, Tuple[int, ...]]:
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ZerosetError(f"points must end in a dimension of 3, got {p.shape}")
        lead = p.shape[:-1]
        rows = self._core.point_query(np.ascontiguousarray(p.reshape(-1, 3)), query, str(sign))
        return rows, lead

    def compute_closest_points(self, query_points: Any) -> Dict[str, np.ndarray]:
        """The nearest surface point to each of ``query_points`` (``(..., 3)``), over every
        object (Open3D's ``RaycastingScene.compute_closest_points``): a dict of arrays shaped like
        the leading dimensions, ``points`` ``(..., 3)``, ``geometry_ids`` (object index, uint32),
        ``primitive_ids`` (the part: a mesh's triangle, a box's face; uint32), ``distance``, and
        ``lower``/``upper``, bounds on the distance: equal where it is exact (closed forms,
        meshes, similarity transforms, in float64), a guaranteed interval otherwise (CSG,
        general affine maps), ``distance`` then being ``upper``, reached by ``points``."""
        rows, lead = self._points(query_points, "closest")
        return {
            "points": rows[:, 0:3].reshape(lead + (3,)),
            "distance": rows[:, 3].reshape(lead),
            "lower": rows[:, 4].reshape(lead),
            "upper": rows[:, 5].reshape(lead),
            "geometry_ids": rows[:, 6].astype(np.uint32).reshape(lead),
            "primitive_ids": rows[:, 7].astype(np.uint32).reshape(lead),
        }

    def compute_distance(self, query_points: Any, bounds: bool = False) -> Any:
        """Distance from each of ``query_points`` (``(..., 3)``) to the nearest surface, float64,
        shaped like the leading dimensions. Exact (to rounding) where the objects are; where one
        is not (see ``compute_closest_points``) the value is the upper bound, reached by a real
        surface point: ``bounds=True`` returns ``(distance, lower, upper)``."""
        rows, lead = self._points(query_points, "distance")
        if bounds:
            return tuple(rows[:, k].reshape(lead) for k in range(3))
        return rows[:, 0].reshape(lead)

    def compute_signed_distance(self, query_points: Any, sign: str = "fast-winding", bounds: bool = False) -> Any:
        """``compute_distance``, negative inside. ``sign``: how a mesh decides inside —
        ``"fast-winding"`` (default; hierarchical generalized winding number, right on open
        meshes, holes and duplicated faces), ``"winding"`` (exact winding number),
        ``"pseudonormal"`` (angle-weighted pseudo-normal; closed consistently oriented meshes) or
        ``"parity"`` (ray crossings, re-cast where a ray grazes an edge). Analytic solids use the
        sign of Φ. ``bounds=True`` returns ``(signed, lower, upper)``."""
        rows, lead = self._points(query_points, "signed", sign)
        if bounds:
            return tuple(rows[:, k].reshape(lead) for k in range(3))
        return rows[:, 0].reshape(lead)

    def compute_occupancy(self, query_points: Any, sign: str = "fast-winding") -> np.ndarray:
        """1.0 where a point is inside any object, 0.0 outside (float32, as Open3D's); ``sign``
        as for ``compute_signed_distance``. No distance is computed."""
        rows, lead = self._points(query_points, "occupancy", sign)
        return rows[:, 0].astype(np.float32).reshape(lead)

    def phi(self, query_points: Any) -> np.ndarray:
        """Φ of the scene (the smallest of its objects' Φ) at each point, float64."""
        rows, lead = self._points(query_points, "phi")
        return rows[:, 0].reshape(lead)

    def gradient(self, query_points: Any) -> np.ndarray:
        """∇Φ of the scene at each point (the gradient of the object of smallest Φ), ``(..., 3)``."""
        rows, lead = self._points(query_points, "phi")
        return rows[:, 1:4].reshape(lead + (3,))

    def sample_grid(self, lo: Sequence[float], hi: Sequence[float], shape: Sequence[int],
                    query: str = "signed", sign: str = "fast-winding") -> np.ndarray:
        """A point query on the regular grid of ``shape`` samples spanning the box ``[lo, hi]``
        (both ends included along each axis, as ``numpy.linspace``): an SDF or occupancy volume
        shaped ``shape`` (``(*shape, 3)`` for ``"closest"`` and ``"gradient"``). ``query``:
        ``"signed"`` (default), ``"distance"``, ``"occupancy"``, ``"phi"``, ``"closest"`` or
        ``"gradient"``; ``sign`` as for ``compute_signed_distance``. ``numpy.save`` writes it as
        ``.npy``; past memory, ``zeroset.dask.sample_grid`` makes it block by block."""
        axes = [np.linspace(float(a), float(b), int(n)) for a, b, n in zip(lo, hi, shape)]
        if len(axes) != 3 or any(len(a) < 1 for a in axes):
            raise ZerosetError(f"lo, hi and shape need three entries each, shape at least 1, got {shape}")
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        calls = {
            "signed": lambda: self.compute_signed_distance(grid, sign=sign),
            "distance": lambda: self.compute_distance(grid),
            "occupancy": lambda: self.compute_occupancy(grid, sign=sign),
            "phi": lambda: self.phi(grid),
            "closest": lambda: self.compute_closest_points(grid)["points"],
            "gradient": lambda: self.gradient(grid),
        }
        if query not in calls:
            raise ZerosetError(f"query: one of {', '.join(calls)}, got {query!r}")
        return calls[query]()

    def list_intersections(self, origins: Any, directions: Any, tmin: Any = 0.0, tmax: Any = np.inf,
                           closed: bool = False) -> Dict[str, np.ndarray]:
        """Every surface crossing along each ray with ``tmin < t ≤ tmax`` (``closed=True``:
        ``tmin ≤ t``), in increasing ``t`` per ray, in Open3D's flat layout: ``ray_splits``
        (``N + 1`` offsets: ray ``i``'s crossings are ``ray_splits[i]:ray_splits[i+1]``),
        ``ray_ids``, ``t_hit``, ``geometry_ids``, ``primitive_ids``, ``primitive_uvs`` (NaN where
        the primitive has none), plus ``normals`` (outward unit ∇Φ) and ``entering`` (the ray
        enters the solid there). A crossing at an edge shared by triangles is reported once;
        ``count_intersections`` is the count per ray. Rays are flattened over the leading
        dimensions."""
        o, d, lead = _rays(origins, directions)
        return self._core.list_intersections(o, d, _range(tmin, lead, "tmin").reshape(-1),
                                             _range(tmax, lead, "tmax").reshape(-1), bool(closed))

    def render(self, aovs: Optional[Sequence[str]] = None, width: Optional[int] = None,
               height: Optional[int] = None, crop: Optional[Tuple[int, int, int, int]] = None,
               spp: Optional[int] = None, depth_miss: float = float("inf"),
               view: Optional[Dict[str, Any]] = None, background: bool = False,
               threads: Optional[int] = None, out: Optional[Dict[str, np.ndarray]] = None) -> Dict[str, np.ndarray]:
        """Renders the scene's camera; returns ``{AOV name: float32 array}``, ``(H, W)`` for one
        channel and ``(H, W, C)`` for several, bit-identical to the EXR's channels.

        ``aovs``: names as on the command line (``Beauty, Alpha, Depth, Distance, Normal,
        Position, CameraNormal, PrimitiveId, Uv, ShadingNormal``; default the scene's outputs).
        ``crop=(x0, y0, x1, y1)`` renders that window of the full frame (pixels, half-open),
        exactly as the full render has it there. ``view=dict(eye=..., look_at=..., up=(0, 1, 0))``
        places the scene's camera (its model, field of view and resolution kept) for this render.
        ``Beauty`` is premultiplied by coverage (a miss is black), as in the EXR;
        ``background=True`` fills the uncovered part with the scene's background instead.
        ``threads``: how many threads render (default: one per core, or ``RAYON_NUM_THREADS``);
        ``zeroset.dask`` passes a worker's thread count, so workers sharing a machine share its
        cores instead of each starting one thread per core.
        ``out={AOV name: array}`` writes those AOVs into the given writable float32 arrays (each
        shaped as it would be returned; a view into a larger array will do, as long as each of its
        rows is contiguous) instead of new ones, and returns ``out``; AOVs rendered but not in
        ``out`` are dropped. ``zeroset.dask.fetch`` renders tiles straight into the shared output
        this way.
        """
        pose = None
        if view is not None:
            unknown = set(view) - {"eye", "look_at", "up"}
            if unknown:
                raise ZerosetError(f"view: unknown fields {sorted(unknown)}")
            pose = (tuple(map(float, view["eye"])), tuple(map(float, view.get("look_at", (0, 0, 0)))),
                    tuple(map(float, view.get("up", (0, 1, 0)))))
        return self._core.render(None if aovs is None else list(aovs), width, height,
                                 None if crop is None else tuple(int(c) for c in crop), spp, float(depth_miss),
                                 pose, bool(background), None if threads is None else int(threads), out)

    def __repr__(self) -> str:
        return f"Scene({self.object_count} objects, camera {self.camera.width}x{self.camera.height})"


def _matrix4(m: Any, what: str) -> list:
    a = np.asarray(m, dtype=np.float64)
    if a.shape == (3, 4):
        a = np.vstack([a, [0.0, 0.0, 0.0, 1.0]])
    if a.shape != (4, 4):
        raise ZerosetError(f"{what}: expected a 4×4 or 3×4 matrix, got shape {a.shape}")
    return a.tolist()


def _from_recipe(recipe: list) -> Scene:
    scene: Optional[Scene] = None
    for step in recipe:
        kind = step[0]
        if kind == "load":
            scene = Scene.load(step[1])
        elif kind == "ron":
            scene = Scene.from_ron(step[1], step[2], step[3])
        elif kind == "add":
            object_id = scene._core.add_object(step[1], step[2], step[3])
            scene._recipe.append(step)
        elif kind == "mesh":
            scene._core.add_mesh(step[1], step[2], step[3], step[4])
            scene._recipe.append(step)
    assert scene is not None, "a recipe starts with a load"
    return scene


def rays_pinhole(intrinsics: Any, extrinsics: Any, width: int, height: int,
                 distortion: Optional[Sequence[float]] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Pixel-centre rays of a calibrated pinhole camera in the OpenCV convention.

    ``intrinsics``: 3×3 K ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``; ``extrinsics``: 4×4
    world → camera (+x right, +y down, +z forward; the 3×3 part a rotation); ``distortion``:
    OpenCV's ``[k1, k2, p1, p2, k3]`` (default none), inverted exactly as zeroset's ``OpenCv``
    camera does. Pixel (u, v) — column u, row v — has its centre at the integer point (u, v), as
    in OpenCV. Returns ``(origins, directions)``, each float64 ``(height, width, 3)``, directions
    of unit length (so ``t`` is metric distance).
    """
    k = np.asarray(intrinsics, dtype=np.float64)
    if k.shape != (3, 3):
        raise ZerosetError(f"intrinsics: expected a 3×3 matrix, got shape {k.shape}")
    dist = [0.0] * 5 if distortion is None else [float(x) for x in distortion]
    if len(dist) != 5:
        raise ZerosetError(f"distortion: expected [k1, k2, p1, p2, k3], got {len(dist)} values")
    o, d = _zeroset.rays_pinhole(k.tolist(), _matrix4(extrinsics, "extrinsics"), int(width), int(height), dist)
    return o.reshape(height, width, 3), d.reshape(height, width, 3)


def write_exr(path: "os.PathLike[str] | str", arrays: Dict[str, Any], header: Optional[Dict[str, Any]] = None) -> None:
    """Writes AOV arrays as zeroset's EXR (FLOAT channels, the renderer's channel names).

    ``arrays``: ``{AOV name: (H, W) or (H, W, C) array}`` as ``Scene.render`` returns them.
    ``header`` may hold ``world_to_camera`` (4×4, the EXR's +y-up convention), ``scene_file`` and
    ``depth_miss``.
    """
    header = dict(header or {})
    items = []
    for name, a in arrays.items():
        a = np.ascontiguousarray(a, dtype=np.float32)
        if a.ndim == 2:
            shape = (a.shape[0], a.shape[1], 1)
        elif a.ndim == 3:
            shape = a.shape
        else:
            raise ZerosetError(f"write_exr: `{name}` must be (H, W) or (H, W, C), got {a.shape}")
        items.append((name, a.reshape(-1), shape))
    w2c = header.pop("world_to_camera", None)
    _zeroset.write_exr(os.fspath(path), items, None if w2c is None else _matrix4(w2c, "world_to_camera"),
                       str(header.pop("scene_file", "")), float(header.pop("depth_miss", float("inf"))))
    if header:
        raise ZerosetError(f"write_exr: unknown header fields {sorted(header)}")


_AOV_CHANNELS: Dict[str, list] = _zeroset.aov_channels()


def read_exr(path: "os.PathLike[str] | str") -> Tuple[Dict[str, np.ndarray], Dict[str, Any]]:
    """Reads an EXR: ``(arrays, header)``. Channels that form a zeroset AOV are returned under the
    AOV's name, shaped as ``Scene.render`` returns them; any other channel under its own name.
    ``header`` has ``display_window``/``data_window`` ``(x, y, width, height)`` and the matrices
    and text attributes."""
    channels, header = _zeroset.read_exr(os.fspath(path))
    arrays: Dict[str, np.ndarray] = {}
    for aov, names in _AOV_CHANNELS.items():
        if all(n in channels for n in names):
            planes = [channels.pop(n) for n in names]
            arrays[aov] = planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)
    arrays.update(channels)
    return arrays, header
