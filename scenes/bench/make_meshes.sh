#!/usr/bin/env bash
# Generates the benchmark meshes scenes/bench/meshes/mesh{4,6,8}.ply (binary little-endian PLY,
# the displaced icosphere of ../shared/bench/gen.py; 5,120 / 81,920 / 1,310,720 triangles) and
# links them as /tmp/mesh{4,6,8}.ply, where ../shared/anchors/embree/bench_embreex.py reads them.
# Needs python3 with numpy and trimesh (`pip install numpy trimesh`). Run from anywhere.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
gen="$repo/../shared/bench/gen.py"
mkdir -p "$here/meshes"
for level in "${@:-4 6 8}"; do
  for l in $level; do
    out="$here/meshes/mesh$l.ply"
    [ -s "$out" ] || python3 "$gen" --mesh "$out" "$l"
    ln -sf "$out" "/tmp/mesh$l.ply"
  done
done
