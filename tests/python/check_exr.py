"""Reads an EXR written by `zeroset render` with the Python OpenEXR bindings (the ones users
have) and checks what the README promises: channel names, the default (no) compression,
windows, header attributes, and values (coverage 0/1, premultiplied colour: black
on misses, unit normals on hits, +inf depth on misses).

    python3 tests/python/check_exr.py OUT.exr
Prints '<n> passed, <m> failed' and exits non-zero on any failure.
"""
import math
import sys

import numpy as np
import OpenEXR

path = sys.argv[1]
checks = []


def check(name, ok):
    checks.append((name, bool(ok)))
    print(("ok   " if ok else "FAIL ") + name)


f = OpenEXR.File(path)
header = f.header()
channels = f.channels()
names = set()
for key, channel in channels.items():
    pixels = channel.pixels
    if pixels.ndim == 3:  # RGB(A) grouped by the bindings
        names.update(key)
    else:
        names.add(key)
check("channels R G B A Z N.X N.Y N.Z", {"R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z"} <= names)
check("no compression (the default)", str(header["compression"]).endswith("NO_COMPRESSION"))
check("data window = display window", all((a == b).all() for a, b in zip(header["dataWindow"], header["displayWindow"])))
check("worldToCamera and worldToNDC present", "worldToCamera" in header and "worldToNDC" in header)
check("depth convention recorded", "planar depth" in str(header.get("zeroset/depth", "")))

rgba = channels["RGBA"].pixels
alpha = rgba[..., 3]
z = channels["Z"].pixels
n = np.stack([channels["N.X"].pixels, channels["N.Y"].pixels, channels["N.Z"].pixels], axis=-1)
hit = alpha == 1.0
check("coverage is 0 or 1", np.all((alpha == 0.0) | hit))
check("some pixels hit and some miss", hit.any() and (~hit).any())
check("normals unit length on hits", np.allclose(np.linalg.norm(n[hit], axis=-1), 1.0, atol=1e-5))
check("normals zero on misses", np.all(n[~hit] == 0.0))
check("premultiplied colour: R = G = B = 0 on misses", np.all(rgba[~hit][..., :3] == 0.0))
check("depth finite and positive on hits", np.all(np.isfinite(z[hit]) & (z[hit] > 0)))
check("depth +inf on misses", np.all(np.isposinf(z[~hit])))
check("no NaN anywhere", not any(np.isnan(c.pixels).any() for c in channels.values()))

passed = sum(ok for _, ok in checks)
print(f"{passed} passed, {len(checks) - passed} failed")
sys.exit(0 if passed == len(checks) else 1)
