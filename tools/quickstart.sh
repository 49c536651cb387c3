#!/usr/bin/env bash
# README command 1: install what is missing, build, start a coordinator with two local worker
# processes, render the Cornell box with the photon map (skipping, Wald 1999 §4.4) to
# out/cornell-box.exr (+ .png preview), and shut the farm down again.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
tools/build.sh
mkdir -p out
./build/client/pf render scenes/cornell-box/cornell-box.json --workers 2 \
  --integrator photonmap --photons 200000 --k 100 --plan skipping --stride 2 --rounds 4 --spp 4 \
  --res 256x256 -o out/cornell-box.exr --png out/cornell-box.png "$@"
echo "quickstart: wrote out/cornell-box.exr and out/cornell-box.png"
