#!/usr/bin/env bash
# Builds the scene fuzzers with clang (libFuzzer + ASan + UBSan) and runs them within one time
# budget: the MGF loader half of it, the OBJ loader, the manifest parser and the glTF loader a
# sixth each.
#   tests/fuzz/run_mgf_fuzz.sh [seconds]      (default 30, total)
# Environment: PF_FUZZ_BUILD_DIR (default <repo>/build-fuzz), PF_FUZZ_JOBS (build jobs, 2).
# Exits non-zero on a finding; the reproducer is left in <build>/mgf_fuzz_run/artifacts/ and can
# be replayed with: <build>/tests/fuzz/mgf_fuzz <artifact>   (run from <build>/mgf_fuzz_run).
set -euo pipefail

seconds="${1:-30}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${PF_FUZZ_BUILD_DIR:-$repo/build-fuzz}"
jobs="${PF_FUZZ_JOBS:-2}"

mkdir -p "$build"
CC=clang CXX=clang++ cmake -S "$repo" -B "$build" -G Ninja \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPF_BUILD_FUZZ=ON -DPF_BUILD_TESTS=OFF -DPF_BUILD_BENCH=OFF \
  >"$build/configure.log" 2>&1 || { cat "$build/configure.log"; exit 2; }
cmake --build "$build" --target mgf_fuzz obj_fuzz manifest_fuzz gltf_fuzz -j "$jobs"
mgf_seconds=$(( (seconds + 1) / 2 ))
other_seconds=$(( (seconds - mgf_seconds + 2) / 3 ))
[ "$other_seconds" -ge 1 ] || other_seconds=1

# Scratch directory: the harness only lets includes resolve inside its working directory, and
# the seeds include these files (a plain one, one with an include cycle, one in a subfolder).
run="$build/mgf_fuzz_run"
mkdir -p "$run/corpus" "$run/artifacts" "$run/sub"
printf 'v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 0 1 0\nf a b c\n' >"$run/inc.mgf"
printf 'i cycle.mgf\n' >"$run/cycle.mgf"
printf 'xf -t 0 0 1\ni ../inc.mgf\nxf\n' >"$run/sub/part.mgf"

# fuzz TARGET SECONDS [libFuzzer options...]: runs <build>/tests/fuzz/TARGET_fuzz in the current
# directory on ./corpus and tests/fuzz/TARGET_corpus; exits with its status on a finding.
fuzz() {
  local target="$1" secs="$2" status=0
  shift 2
  "$build/tests/fuzz/${target}_fuzz" corpus "$repo/tests/fuzz/${target}_corpus" \
    -max_total_time="$secs" -max_len=4096 -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix=artifacts/ -print_final_stats=1 "$@" || status=$?
  if [ "$status" -ne 0 ]; then
    echo "${target}_fuzz: FINDING (exit $status); reproducer(s) in $PWD/artifacts:" >&2
    ls -1 artifacts >&2 || true
    exit "$status"
  fi
  echo "${target}_fuzz: no findings in ${secs}s"
}

cd "$run"
fuzz mgf "$mgf_seconds" -dict="$repo/tests/fuzz/mgf.dict"

# The OBJ loader, the manifest parser and the glTF loader, each in its own scratch folder (the OBJ
# and glTF harnesses write their input to a file there; `mtllib m.mtl` and the buffer `m.bin`
# resolve inside it, anything else must be refused).
for target in obj manifest gltf; do
  dir="$build/${target}_fuzz_run"
  mkdir -p "$dir/corpus" "$dir/artifacts"
  [ "$target" = obj ] && printf 'newmtl lamp\nKe 1 1 1\nnewmtl wall\nKd .5 .5 .5\n' >"$dir/m.mtl"
  # gltf_corpus/external.gltf's buffer: one triangle's positions, normals (+z) and u16 indices.
  [ "$target" = gltf ] && python3 -c 'import struct,sys; sys.stdout.buffer.write(struct.pack("<9f", 0,0,0, 1,0,0, 0,1,0) + struct.pack("<9f", 0,0,1, 0,0,1, 0,0,1) + struct.pack("<3H", 0,1,2) + bytes(2))' >"$dir/m.bin"
  cd "$dir"
  fuzz "$target" "$other_seconds"
done
