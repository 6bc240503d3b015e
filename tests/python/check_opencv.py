"""Projects every hit of a distorted `OpenCv` render with OpenCV itself: reads the camera from
`NAME.cameras.json` (K, R, t, distortion) and the hit points from the EXR's `P` AOV, runs
`cv2.projectPoints`, and checks that each hit lands on its own pixel (pixel (i, j) is at (i, j) in
OpenCV's convention) within 1e-4 px.

    python3 tests/python/check_opencv.py OUT/NAME.cameras.json OUT/NAME.exr
The render must hold the `A` and `P` AOVs. Prints '<n> passed, <m> failed' and exits non-zero on
any failure.
"""
import json
import sys

import cv2
import numpy as np
import OpenEXR

cameras_path, exr_path = sys.argv[1], sys.argv[2]
checks = []


def check(name, ok):
    checks.append((name, bool(ok)))
    print(("ok   " if ok else "FAIL ") + name)


view = json.load(open(cameras_path))["views"][0]
check("model is OpenCv", view["model"] == "OpenCv")
K = np.array(view["K"], dtype=np.float64)
R = np.array(view["R"], dtype=np.float64)
t = np.array(view["t"], dtype=np.float64)
dist = np.array(view["distortion"], dtype=np.float64)
check("the lens is distorted", np.any(dist != 0.0))

channels = OpenEXR.File(exr_path).channels()


def channel(name):
    if name in channels:
        return channels[name].pixels
    for key, c in channels.items():  # grouped by the bindings, e.g. "RGBA"
        if c.pixels.ndim == 3 and name in key:
            return c.pixels[..., key.index(name)]
    raise KeyError(name)


alpha = channel("A")
points = np.stack([channel("P.X"), channel("P.Y"), channel("P.Z")], axis=-1).astype(np.float64)
height, width = alpha.shape
check("resolution matches cameras.json", (width, height) == (view["width"], view["height"]))
hit = alpha == 1.0
check("most pixels hit", hit.sum() > 0.5 * width * height)

rvec, _ = cv2.Rodrigues(R)
projected, _ = cv2.projectPoints(points[hit].reshape(-1, 1, 3), rvec, t, K, dist)
projected = projected.reshape(-1, 2)
rows, cols = np.nonzero(hit)
error = np.hypot(projected[:, 0] - cols, projected[:, 1] - rows)
print(f"{hit.sum()} hit pixels: cv2.projectPoints lands within {error.max():.3e} px of the pixel (mean {error.mean():.3e})")
check("cv2.projectPoints agrees within 1e-4 px on every hit pixel", error.max() < 1e-4)

passed = sum(ok for _, ok in checks)
print(f"{passed} passed, {len(checks) - passed} failed")
sys.exit(0 if passed == len(checks) else 1)
