#!/usr/bin/env bash
# Rebuilds scenes/blender-box from Blender: the glTF export and Cycles' reference renders of both
# variants (tools/blender/blender_box.py; docs/results/blender-cycles.md). Needs Debian's
# `blender` (3.4) and `python3-numpy` (its glTF exporter imports numpy); they are not part of the
# build's dependencies, so this script installs them when missing (apt; sudo only when not root).
#   tools/blender/cycles_reference.sh [OUT_DIR]     (default: scenes/blender-box)
# The references in the repository: 64x64 at 65536 samples and 128x128 at 16384 samples per pixel.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
out="$(realpath -m "${1:-$repo/scenes/blender-box}")"
if ! command -v blender >/dev/null || ! python3 -c 'import numpy' 2>/dev/null; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get install -y --no-install-recommends blender python3-numpy
fi
mkdir -p "$out"
render() {  # RESOLUTION SAMPLES VARIANT
  echo "Cycles: $3 at $1x$1, $2 samples per pixel -> $out/cycles-$3-$1.exr"
  blender --background --factory-startup --python-exit-code 1 --python "$repo/tools/blender/blender_box.py" -- \
    "$out" "$1" "$2" "$3" >"$out/.blender-$3-$1.log" 2>&1 ||
    { tail -20 "$out/.blender-$3-$1.log"; exit 1; }
  rm -f "$out/.blender-$3-$1.log"
}
for variant in lambert principled; do
  render 64 65536 "$variant"
  render 128 16384 "$variant"
done
