#!/usr/bin/python3
"""pf against Blender's Cycles at equal CPU time, on the scenes built in Blender
(docs/results/blender-cycles.md, "Equal CPU time").

For each scene, Cycles renders the Blender scene itself (tools/blender/*.py, the variant whose BSDFs
pf reads from the exported file) at each sample count of --cycles-spp with seed 2 — not the
reference's seed 1, whose first samples the reference contains — and its CPU time is the process
CPU time of Blender's render call (printed by the script: scene building, export and Blender's
start are left out). Then pf renders the exported scene with `pf render MANIFEST --res <reference's>
--time-budget C/threads --local-only --threads N --seed 1 <config>` for each Cycles CPU time C, and
its CPU time is the child's user + system time (os.wait4: the whole process, scene loading
included). Images are judged with `pf diff --json --scene` (bench/time_budget.py's metrics): each
renderer's convergence against its own converged image — Cycles' against Cycles' reference, pf's
against pf's path-traced reference where the scene has one (where the two renderers' models differ
in known small ways, those differences would otherwise be counted as pf's error; blender-box's
Lambertian variant shares the model exactly and uses Cycles' reference for both) — and pf's image
mean away from the emitters against Cycles' reference too. A pf image's error is compared with
Cycles' curve at pf's own CPU time: the Cycles points interpolated log-log (and extrapolated
along the last segment past the ends).

    bench/cycles_curve.py [--blender blender] [--pf build/client/pf] [--scenes blender-studio,blender-box]
                          [--cycles-spp 64,256,1024,4096] [--configs default,photonmap] [--threads 2]
                          [--json docs/results/cycles-curve.json]

Prints JSON lines as it goes and a Markdown table at the end: per scene and Cycles point, Cycles'
errors and each pf configuration's at about the same CPU time, with the ratio of pf's error to
Cycles' curve at pf's CPU time (below 1: pf's error is lower).
"""
import argparse
import json
import math
import pathlib
import re
import subprocess
import sys
import tempfile

from bench_common import ROOT, exr_string, run
from sppm_compare import timed_wait4
from time_budget import METRICS

# name: the Blender script and its arguments after OUT_DIR for a sample count, the image it writes
# (relative to OUT_DIR), pf's manifest, Cycles' converged reference, pf's own converged path-traced
# reference (None: Cycles' serves both) and the resolution.
SCENES = {
    "blender-studio": {
        "script": "tools/blender/blender_studio.py",
        "arguments": lambda spp, out: ["128", "96", str(spp), "gltf", str(out / "cycles.exr"), "2"],
        "image": "cycles.exr",
        "manifest": "scenes/blender-studio/blender-studio.json",
        "cycles_reference": "scenes/blender-studio/cycles-128x96.exr",
        "pf_reference": "scenes/blender-studio/reference-128x96.exr",
        "res": "128x96",
    },
    "blender-box": {
        "script": "tools/blender/blender_box.py",
        "arguments": lambda spp, out: ["128", str(spp), "lambert", "2"],
        "image": "cycles-lambert-128.exr",
        "manifest": "scenes/blender-box/blender-box-lambert.json",
        "cycles_reference": "scenes/blender-box/cycles-lambert-128.exr",
        "pf_reference": None,
        "res": "128x128",
    },
}
CONFIGS = {"default": [], "photonmap": ["--integrator", "photonmap"], "path": ["--integrator", "path"]}


def judge(pf, exr, reference, manifest):
    d = json.loads(run([pf, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
    return {"mean_ratio": d["mean"] / d["reference_mean"],
            "masked_mean_ratio": d["mean_masked"] / d["reference_mean_masked"], **{m: d[m] for m in METRICS}}


def render_cycles(blender, scene, spp, out):
    s = SCENES[scene]
    cmd = [blender, "--background", "--factory-startup", "--python-exit-code", "1", "--python",
           ROOT / s["script"], "--", out] + s["arguments"](spp, out)
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, cwd=ROOT)
    found = re.search(r"cycles_cpu_seconds=([0-9.]+)", r.stdout)
    if r.returncode != 0 or not found:
        sys.exit(f"Blender failed ({r.returncode}): {' '.join(map(str, cmd))}\n{(r.stdout + r.stderr)[-3000:]}")
    return float(found.group(1)), out / s["image"]


def on_curve(points, cpu, metric):
    """Cycles' error at `cpu` seconds: log-log interpolation between the two nearest points."""
    pts = sorted((p["cpu_s"], p[metric]) for p in points)
    i = max(1, min(len(pts) - 1, sum(1 for c, _ in pts if c <= cpu)))
    (c0, e0), (c1, e1) = pts[i - 1], pts[i]
    slope = math.log(e1 / e0) / math.log(c1 / c0)
    return e0 * math.exp(slope * math.log(cpu / c0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--cycles-spp", default="64,256,1024,4096")
    ap.add_argument("--configs", default="default,photonmap")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    cycles_rows, pf_rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            s = SCENES[scene]
            manifest, res = s["manifest"], s["res"]
            own_reference = s["pf_reference"] or s["cycles_reference"]
            for spp in map(int, args.cycles_spp.split(",")):
                out = pathlib.Path(tmp) / f"{scene}-{spp}"
                out.mkdir()
                cpu, exr = render_cycles(args.blender, scene, spp, out)
                row = {"renderer": "cycles", "scene": scene, "spp": spp, "cpu_s": cpu,
                       **judge(args.pf, exr, s["cycles_reference"], manifest)}
                print(json.dumps(row), flush=True)
                cycles_rows.append(row)
                for config in args.configs.split(","):
                    exr = pathlib.Path(tmp) / f"{scene}-{spp}-{config}.exr"
                    budget = f"{cpu / args.threads:.3f}"
                    cmd = [args.pf, "render", manifest, "--res", res, "--time-budget", budget, "--local-only",
                           "--threads", str(args.threads), "--seed", "1", "--no-png", "-q", "-o", str(exr)]
                    cpu_pf, wall = timed_wait4(cmd + CONFIGS[config], pathlib.Path(tmp) / "pf.log")
                    row = {"renderer": "pf", "scene": scene, "config": config, "cycles_spp": spp,
                           "budget_s": float(budget), "cpu_s": cpu_pf, "wall_s": wall,
                           "integrator": exr_string(exr, "pf:settings.integrator"), "plan": exr_string(exr, "pf:plan"),
                           "reference": own_reference, **judge(args.pf, exr, own_reference, manifest),
                           "against_cycles": judge(args.pf, exr, s["cycles_reference"], manifest)}
                    print(json.dumps(row), flush=True)
                    pf_rows.append(row)
    for r in pf_rows:
        points = [c for c in cycles_rows if c["scene"] == r["scene"]]
        if len(points) >= 2:
            r["cycles_at_same_cpu"] = {m: on_curve(points, r["cpu_s"], m) for m in METRICS}
    if args.json:
        pathlib.Path(args.json).write_text(
            json.dumps({"args": vars(args), "cycles": cycles_rows, "pf": pf_rows}, indent=1) + "\n")
    print("\n| scene | renderer | spp / budget | CPU s | mean / Cycles' away from emitters | display | masked | lowfreq | "
          "display / Cycles | masked / Cycles | lowfreq / Cycles |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for c in cycles_rows:
        print(f"| {c['scene']} | Cycles | {c['spp']} spp | {c['cpu_s']:.1f} | {c['masked_mean_ratio']:.4f} | "
              f"{c['rmse_display']:.5f} | {c['rmse_masked']:.5f} | {c['rmse_lowfreq']:.5f} | | | |")
        for r in pf_rows:
            if r["scene"] != c["scene"] or r["cycles_spp"] != c["spp"]:
                continue
            at = r.get("cycles_at_same_cpu")
            ratios = " | ".join(f"{r[m] / at[m]:.2f}" if at else "-" for m in METRICS)
            name = f"pf {r['config']} ({r['integrator']}, {r['plan']})"
            print(f"| {r['scene']} | {name} | {r['budget_s']:g} s | {r['cpu_s']:.1f} | {r['against_cycles']['masked_mean_ratio']:.4f} | "
                  f"{r['rmse_display']:.5f} | {r['rmse_masked']:.5f} | {r['rmse_lowfreq']:.5f} | {ratios} |")


if __name__ == "__main__":
    main()
