#!/usr/bin/env bash
# Renders a converged path-traced reference: two independent halves (seeds 1 and 2) averaged,
# so the remaining noise can be estimated from their difference (printed and stored in the
# EXR header as pf:estimated_noise_rmse).
#
#   tools/make_reference.sh SCENE.json RESOLUTION SPP_PER_HALF OUT.exr
# e.g. tools/make_reference.sh scenes/cornell-box/cornell-box.json 256x256 4096 scenes/cornell-box/reference-256.exr
set -euo pipefail
scene=$1 res=$2 spp=$3 out=$4
pf=${PF:-build/client/pf}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for seed in 1 2; do
  "$pf" render "$scene" --integrator path --res "$res" --spp "$spp" --seed "$seed" -q --no-png -o "$tmp/half$seed.exr"
done
"$pf" merge "$tmp/half1.exr" "$tmp/half2.exr" -o "$out"
"$pf" info "$scene" >/dev/null
