#!/usr/bin/python3
"""Emitters seen directly: the error and CPU time of the photon-map integrator with and without
the split estimate of directly seen emission (docs/renderer.md, "Emitters seen directly"), at the
same samples per pixel, against each scene's converged path-traced reference
(docs/results/emitter-split.md).

Two pf binaries, A (before) and B (after), render the same command — `pf render SCENE --res
<reference's> --integrator photonmap --spp N --local-only --threads 1 --seed S` — for several
seeds, interleaved so that both see the same machine load; judged by `pf diff --json --scene`:
rmse (linear, where the lights' edges dominate), rmse_display (luminance clamped to the display
white), rmse_masked (without the lights seen directly) and rmse_lowfreq. Medians over seeds.

    bench/emitter_split.py --a OLD_PF --b NEW_PF [--scenes cornell-box,cornell-sphere] [--spp 16]
                           [--seeds 1,2,3] [--json docs/results/emitter-split.json]
"""
import argparse
import json
import pathlib
import statistics
import tempfile

from bench_common import run, timed
from time_budget import SCENES

METRICS = ("rmse", "rmse_display", "rmse_masked", "rmse_lowfreq")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="pf before")
    ap.add_argument("--b", required=True, help="pf after")
    ap.add_argument("--scenes", default="cornell-box,cornell-sphere")
    ap.add_argument("--spp", default="16")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            manifest, reference, res = SCENES[scene]
            runs = {"a": [], "b": []}
            for seed in args.seeds.split(","):
                for side in ("a", "b"):
                    exr = pathlib.Path(tmp) / f"{scene}-{side}-{seed}.exr"
                    cmd = [getattr(args, side), "render", manifest, "--res", res, "--integrator", "photonmap",
                           "--spp", args.spp, "--local-only", "--threads", "1", "--seed", seed, "--no-png", "-q",
                           "-o", str(exr)]
                    cpu, _ = timed(cmd)
                    d = json.loads(run([args.b, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
                    runs[side].append({"cpu_s": cpu, **{m: d[m] for m in METRICS}})
            row = {"scene": scene, "spp": int(args.spp), "runs": runs}
            for side in ("a", "b"):
                for key in ("cpu_s",) + METRICS:
                    row[f"{key}_{side}"] = statistics.median(r[key] for r in runs[side])
            print(json.dumps(row), flush=True)
            rows.append(row)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1) + "\n")
    print("\n| scene | spp | CPU s A / B | " + " | ".join(f"{m} A / B (B/A)" for m in METRICS) + " |")
    print("|---|---:|---:|" + "---:|" * len(METRICS))
    for r in rows:
        cells = " | ".join(f"{r[m + '_a']:.5f} / {r[m + '_b']:.5f} ({r[m + '_b'] / r[m + '_a']:.2f})" for m in METRICS)
        print(f"| {r['scene']} | {r['spp']} | {r['cpu_s_a']:.1f} / {r['cpu_s_b']:.1f} | {cells} |")


if __name__ == "__main__":
    main()
