#!/usr/bin/env bash
# README command 2 (and .ci/run): install what is missing, build, run every test, then a
# bounded libFuzzer smoke of the MGF parser.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
tools/build.sh
ctest --test-dir build --output-on-failure -j "$(nproc)" --timeout 900
if [ -x tests/fuzz/run_mgf_fuzz.sh ]; then
  tests/fuzz/run_mgf_fuzz.sh "${PF_FUZZ_SECONDS:-60}"
fi
