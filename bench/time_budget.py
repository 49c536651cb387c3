#!/usr/bin/python3
"""The best image in a time budget: `pf render SCENE --time-budget T` with no method flags (the
`auto` integrator and plan) against the path tracer and hand-picked photon-map configurations
at the same budget, on every shipped scene with a converged reference
(docs/results/time-budget.md).

Every image is `pf render SCENE --res <reference's> --time-budget T --local-only --threads N
--seed S <flags>`, judged with `pf diff --json --scene` against the scene's reference: rmse_display
(luminance clamped to the display white), rmse_masked (without the lights seen directly and a
2-pixel band), rmse_lowfreq (4x4 block means outside that mask). The budget is wall time inside pf
(it stops at the first whole pass past it), so the CPU time of each run is recorded too; run it on
an otherwise idle machine.

    bench/time_budget.py [--scenes cornell-box,...] [--budgets 10,60] [--configs default,path,...]
                         [--threads 2] [--json docs/results/time-budget.json]

Prints a Markdown table: each error and its ratio to the best configuration of that scene and budget.
A configuration that `default` resolved to (the same integrator and occlusion test) is not run again:
the default's row stands for it, marked "(= default)".
"""
import argparse
import json
import pathlib
import tempfile

from bench_common import ROOT, exr_string, run, timed

SCENES = {  # name: (manifest, converged path-traced reference, its resolution)
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr", "256x256"),
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr",
                       "256x256"),
    "scene5": ("scenes/scene5/scene5.json", "scenes/scene5/reference-160.exr", "160x120"),
    "scene8": ("scenes/scene8/scene8.json", "scenes/scene8/reference-320.exr", "320x240"),
    "scene10": ("scenes/scene10/scene10.json", "scenes/scene10/reference-320.exr", "320x240"),
    "invisibledate": ("scenes/invisibledate/invisibledate.json", "scenes/invisibledate/reference-320.exr",
                      "320x240"),
    "bathroom": ("scenes/bathroom/bathroom.json", "scenes/bathroom/reference-160.exr", "160x120"),
    "conference": ("scenes/conference/conference.json", "scenes/conference/reference-160.exr", "160x120"),
    "blender-studio": ("scenes/blender-studio/blender-studio.json", "scenes/blender-studio/reference-128x96.exr",
                       "128x96"),
}
CONFIGS = {  # name: pf render flags
    "default": [],
    "path": ["--integrator", "path"],
    "photonmap": ["--integrator", "photonmap"],
    "photonmap-occl": ["--integrator", "photonmap", "--set", "occlusion-test=true"],
    # The progressive photon map with a local pass (final gather, Wald 1999, 4.3) of 16 rays.
    "photonmap-occl-local16": ["--integrator", "photonmap", "--set", "occlusion-test=true", "--plan", "progressive",
                               "--spp", "4", "--set", "local-pass-rays=16"],
    # Fewer samples per pass: more passes in the budget, so a smaller last radius (less bias).
    "default-spp4": ["--spp", "4"],
    "default-spp1": ["--spp", "1"],
    # The progressive radius schedule's alpha, 1/2 (the default since 2026-11-29) or the former 2/3
    # (docs/results/progressive-photon-mapping.md), with the plan the budget gives the photon map.
    "default-alpha-half": ["--plan", "progressive", "--spp", "4", "--set", "progressive-alpha=0.5"],
    "default-alpha-two-thirds": ["--plan", "progressive", "--spp", "4", "--set",
                                 "progressive-alpha=0.6666666666666666"],
}
# What each named configuration is after resolution: (integrator, occlusion test).
RESOLVED = {"path": ("path", False), "photonmap": ("photonmap", False), "photonmap-occl": ("photonmap", True)}
METRICS = ("rmse_display", "rmse_masked", "rmse_lowfreq")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--budgets", default="10")
    ap.add_argument("--configs", default="default,path,photonmap")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            manifest, reference, res = SCENES[scene]
            for budget in args.budgets.split(","):
                default_resolved = None
                for config in args.configs.split(","):
                    # A configuration that `default` resolved to is the same command: its row stands for both.
                    if default_resolved is not None and RESOLVED.get(config) == default_resolved[0]:
                        row = dict(default_resolved[1], config=config, same_as="default")
                        print(json.dumps(row), flush=True)
                        rows.append(row)
                        continue
                    exr = pathlib.Path(tmp) / f"{scene}-{budget}-{config}.exr"
                    cmd = [args.pf, "render", manifest, "--res", res, "--time-budget", budget, "--local-only",
                           "--threads", str(args.threads), "--seed", str(args.seed), "--no-png", "-q", "-o",
                           str(exr)] + CONFIGS[config]
                    cpu, wall = timed(cmd)
                    d = json.loads(run([args.pf, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
                    row = {"scene": scene, "budget_s": float(budget), "config": config, "cpu_s": cpu,
                           "wall_s": wall, "integrator": exr_string(exr, "pf:settings.integrator"),
                           "plan": exr_string(exr, "pf:plan"), "auto": [exr_string(exr, f"pf:auto.{k}") for k in ("integrator", "occlusion-test")],
                           "mean_ratio": d["mean"] / d["reference_mean"], **{m: d[m] for m in METRICS}}
                    print(json.dumps(row), flush=True)
                    rows.append(row)
                    if config == "default":
                        occlusion = exr_string(exr, "pf:settings.occlusion-test")
                        default_resolved = ((row["integrator"], occlusion == "true"), row)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1) + "\n")
    print("\n| scene | budget s | config | CPU s | mean/ref | display | masked | lowfreq | "
          "display/best | masked/best | lowfreq/best |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        peers = [p for p in rows if p["scene"] == r["scene"] and p["budget_s"] == r["budget_s"]]
        best = {m: min(p[m] for p in peers) for m in METRICS}
        ratios = " | ".join(f"{r[m] / best[m]:.2f}" if best[m] > 0 else "-" for m in METRICS)
        config = r["config"] + (" (= default)" if r.get("same_as") else "")
        print(f"| {r['scene']} | {r['budget_s']:g} | {config} | {r['cpu_s']:.1f} | {r['mean_ratio']:.3f} | "
              f"{r['rmse_display']:.5f} | {r['rmse_masked']:.5f} | {r['rmse_lowfreq']:.5f} | {ratios} |")


if __name__ == "__main__":
    main()
