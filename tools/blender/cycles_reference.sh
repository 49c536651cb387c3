#!/usr/bin/env bash
# Rebuilds a scene made in Blender: its glTF export and Cycles' reference renders
# (docs/results/blender-cycles.md). Needs Debian's `blender` (3.4) and `python3-numpy` (its glTF
# exporter imports numpy); they are not part of the build's dependencies, so this script installs
# them when missing (apt; sudo only when not root).
#   tools/blender/cycles_reference.sh SCENE [OUT_DIR]     (default OUT_DIR: scenes/SCENE)
# SCENE blender-box (tools/blender/blender_box.py): both variants, 64x64 at 65536 and 128x128 at
#   16384 samples per pixel; ~40 min on 2 cores.
# SCENE blender-studio (tools/blender/blender_studio.py): the `gltf` variant, 64x48 and 128x96 at
#   65536 samples per pixel; ~12 min on 2 cores.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
scene="${1:-}"
case "$scene" in
  blender-box | blender-studio) ;;
  *) echo "usage: $0 blender-box|blender-studio [OUT_DIR]" >&2; exit 2 ;;
esac
out="$(realpath -m "${2:-$repo/scenes/$scene}")"
if ! command -v blender >/dev/null || ! python3 -c 'import numpy' 2>/dev/null; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get install -y --no-install-recommends blender python3-numpy
fi
mkdir -p "$out"
blender_run() {  # LOG SCRIPT ARGUMENTS...
  local log="$out/.blender-$1.log" script="$2"
  shift 2
  blender --background --factory-startup --python-exit-code 1 --python "$repo/tools/blender/$script" -- \
    "$out" "$@" >"$log" 2>&1 || { tail -20 "$log"; exit 1; }
  rm -f "$log"
}
if [ "$scene" = blender-box ]; then
  for variant in lambert principled; do
    for spec in "64 65536" "128 16384"; do
      set -- $spec
      echo "Cycles: $variant at ${1}x$1, $2 samples per pixel -> $out/cycles-$variant-$1.exr"
      blender_run "$variant-$1" blender_box.py "$1" "$2" "$variant"
    done
  done
else
  for size in "64 48" "128 96"; do
    set -- $size
    echo "Cycles: ${1}x$2, 65536 samples per pixel -> $out/cycles-${1}x$2.exr"
    blender_run "$1" blender_studio.py "$1" "$2" 65536 gltf "$out/cycles-${1}x$2.exr"
  done
fi
