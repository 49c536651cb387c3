#!/usr/bin/env bash
# README command 2 (and .ci/run): install what is missing, check formatting, build, run every
# test, the Slurm deployment test (as root), then a bounded libFuzzer smoke of the MGF, OBJ and
# manifest parsers.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
tools/check-format.sh   # clang-format 14 clean, or a list of the files that are not
tools/build.sh
ctest --test-dir build --output-on-failure -j "$(nproc)" --timeout 900
# The Slurm deployment (deploy/README.md): a one-node cluster brought up here; needs root.
if [ "$(id -u)" -eq 0 ]; then
  tools/install-deps.sh --slurm
  PF_BUILD_DIR="$PWD/build" deploy/slurm/slurm_array_test.sh
else
  echo "test.sh: deploy/slurm/slurm_array_test.sh needs root (munged, slurmd); run it with sudo"
fi
if [ -x tests/fuzz/run_mgf_fuzz.sh ]; then
  tests/fuzz/run_mgf_fuzz.sh "${PF_FUZZ_SECONDS:-60}"
fi
