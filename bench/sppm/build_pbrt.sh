#!/usr/bin/env bash
# Builds pbrt-v3 (https://github.com/mmp/pbrt-v3) for the SPPM comparison in docs/results/sppm.md.
# pbrt is never vendored into this repository: this script compiles a source tree you extracted
# elsewhere, e.g.
#   git clone https://github.com/mmp/pbrt-v3 /tmp/pbrt-v3-src     (submodules NOT needed)
#   bench/sppm/build_pbrt.sh /tmp/pbrt-v3-src /tmp/pbrt-v3-build
# and leaves the binary at BUILD_DIR/pbrt.
#
# Why not pbrt's own CMakeLists: it insists on its git submodules (src/ext/glog, openexr, zlib,
# ptex), which a plain archive of the repository does not contain. Debian packages supply glog,
# OpenEXR and zlib instead:
#   apt-get install -y libgoogle-glog-dev libopenexr-dev zlib1g-dev
# Ptex has no use here (our scenes have no ptex textures), so it is left out.
#
# The one patch, applied to a copy of src/core/api.cpp inside BUILD_DIR (the source tree is not
# modified): delete the #include of textures/ptex.h and the two `name == "ptex"` branches that
# create ptex float/spectrum textures, so a "ptex" texture is reported as unknown instead of
# needing libPtex. textures/ptex.cpp is not compiled.
#
# The preprocessor definitions are the ones pbrt's CMakeLists derives for GCC on Linux (float as
# float, RGB spectra; the feature probes all succeed with GCC 12). Built with -O2 -DNDEBUG.
# JOBS=N runs N compilers at once (default 1, to leave the other core to whoever shares the box).
# Re-running recompiles only objects older than their source.
set -euo pipefail

if [[ $# -ne 2 ]]; then
  echo "usage: $0 PBRT_V3_SRC_DIR BUILD_DIR" >&2
  exit 2
fi
src=$(cd "$1" && pwd)/src
mkdir -p "$2"
build=$(cd "$2" && pwd)
jobs=${JOBS:-1}
[[ -f "$src/core/api.cpp" ]] || { echo "$src/core/api.cpp not found: not a pbrt-v3 tree" >&2; exit 2; }

mkdir -p "$build/obj" "$build/patched/core"
sed -e '/#include "textures\/ptex.h"/d' -e '/else if (name == "ptex")/,+1d' \
  "$src/core/api.cpp" > "$build/patched/core/api.cpp"
if grep -qi 'ptex' "$build/patched/core/api.cpp"; then
  echo "ptex patch did not apply cleanly to core/api.cpp" >&2
  exit 1
fi

defs=(-DNDEBUG -DPBRT_HAVE_ALLOCA_H -DPBRT_HAVE_MEMORY_H -DPBRT_HAVE_HEX_FP_CONSTANTS
  -DPBRT_HAVE_BINARY_CONSTANTS -DPBRT_HAVE_CONSTEXPR -DPBRT_CONSTEXPR=constexpr
  -DPBRT_HAVE_ALIGNAS -DPBRT_HAVE_ALIGNOF -DPBRT_HAVE_ITIMER -DPBRT_HAVE_NONPOD_IN_UNIONS
  -DPBRT_HAVE_MMAP "-DPBRT_NOINLINE=__attribute__((noinline))" -DPBRT_HAVE_POSIX_MEMALIGN
  -DPBRT_THREAD_LOCAL=thread_local)
# gnu++11 as upstream (CMake default extensions; hex float literals need them); -w because 2017 code warns a lot under GCC 12 and we do not maintain it.
cxxflags=(-std=gnu++11 -O2 -w -pthread "${defs[@]}" -I"$src" -I"$src/core" -I"$src/ext"
  $(pkg-config --cflags OpenEXR) $(pkg-config --cflags libglog 2>/dev/null || true))
libs=($(pkg-config --libs OpenEXR) -lglog -lz -pthread)

sources=()
for dir in core accelerators cameras filters integrators lights materials samplers shapes \
  textures media; do
  for f in "$src/$dir"/*.cpp; do
    case "$f" in
      */textures/ptex.cpp | */core/api.cpp) ;;
      *) sources+=("$f") ;;
    esac
  done
done
sources+=("$build/patched/core/api.cpp" "$src/main/pbrt.cpp" "$src/ext/lodepng.cpp"
  "$src/ext/rply.cpp" "$src/ext/targa.cpp")

compile_one() {
  local in=$1 obj
  obj="$build/obj/$(echo "${in#"$build/"}" | sed -e "s|^$src/||" -e 's|/|_|g').o"
  if [[ ! -f "$obj" || "$in" -nt "$obj" ]]; then
    echo "  c++ ${in#"$src/"}"
    g++ "${cxxflags[@]}" -c "$in" -o "$obj"
  fi
  echo "$obj" >> "$build/objects.list.tmp"
}
export -f compile_one
export build src
: > "$build/objects.list.tmp"
printf '%s\n' "${sources[@]}" | CXXFLAGS_SERIALIZED="$(printf '%q ' "${cxxflags[@]}")" \
  xargs -P "$jobs" -I{} bash -c 'eval "cxxflags=($CXXFLAGS_SERIALIZED)"; compile_one "$1"' _ {}
gcc -O2 -w -c "$src/ext/ArHosekSkyModel.c" -o "$build/obj/ext_ArHosekSkyModel.o"
echo "$build/obj/ext_ArHosekSkyModel.o" >> "$build/objects.list.tmp"

sort -u "$build/objects.list.tmp" > "$build/objects.list"
rm -f "$build/objects.list.tmp"
g++ -O2 -o "$build/pbrt" $(cat "$build/objects.list") "${libs[@]}"
echo "built $build/pbrt"
