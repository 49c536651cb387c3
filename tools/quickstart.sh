#!/usr/bin/env bash
# README command 1: install what is missing, build, and render the Cornell box to
# out/cornell-box.exr (+ .png preview) with the reference path tracer.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
tools/build.sh
mkdir -p out
./build/client/pf render scenes/cornell-box/cornell-box.json --integrator path --spp 64 \
  -o out/cornell-box.exr --png out/cornell-box.png "$@"
echo "quickstart: wrote out/cornell-box.exr and out/cornell-box.png"
