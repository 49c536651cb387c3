#!/usr/bin/python3
"""pf's defaults against pbrt-v3's SPPM integrator at equal CPU time, on shipped scenes with
converged path-traced references (docs/results/sppm.md).

For each scene and budget B (CPU seconds):
  pf    `pf render MANIFEST --res <reference's> --time-budget B/2 --local-only --threads 2 --seed S
        -o X.exr --no-png -q` (no method flags: pf's defaults; B/2 wall seconds on 2 threads);
  pbrt  the scene exported by bench/pbrt_scene_export_bench.cpp, `pbrt --nthreads 2 --quiet`,
        Integrator "sppm" with maxdepth 64, photonsperiteration = pbrt's default (one per pixel),
        its iteration count calibrated so that its CPU time matches pf's measured CPU time (median
        over the repeats) for that scene and budget (two short runs per radius give the fixed cost
        and the cost per iteration; the count is then corrected by the CPU time each render took,
        up to 3 renders, until within 10 %), and its initial radius tuned per scene: a sweep over
        radii of 1, 2, 4, 8 pixel footprints at the look-at point, at the smallest budget, extended
        (twice at most each way) past the end of the range while any metric's best radius sits at
        an end; the best by rmse_display is used at every budget. A second table repeats the comparison with pbrt's radius
        chosen per metric (the sweep's best radius for that metric, rendered once per budget).
Both images are judged with `pf diff --json --scene` against the reference (bench/time_budget.py's
metrics: rmse_display, rmse_masked, rmse_lowfreq). CPU time = user + system time of the child
(os.wait4), since the machine is shared. pbrt-v3 has no seed: its repeats render the same samples,
they measure the CPU time only; pf's repeats use seeds S, S+1, ... Medians over the repeats.

    bench/sppm_compare.py --pbrt /tmp/pbrt-v3-build/pbrt --pf build/client/pf
        [--exporter build/bench/pbrt_scene_export_bench] [--scenes cornell-box,cornell-sphere,scene10]
        [--budgets 10,60] [--repeat 3] [--radii SCENE:R1,R2,...;...] [--verify-spp 64]
        [--json docs/results/sppm.json]

--verify-spp N first renders each exported scene with pbrt's path tracer at N spp and reports its
mean and RMSE against the reference (does the export show the same scene?). Prints JSON lines as
it goes and a Markdown table at the end: per scene and budget, each metric for pf and pbrt and the
ratio pf/pbrt (below 1: pf's error is lower).
"""
import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

from bench_common import ROOT, exr_string, run
from time_budget import METRICS, SCENES

DEFAULT_SCENES = "cornell-box,cornell-sphere,scene10"
RADIUS_FACTORS = (1, 2, 4, 8)  # the sweep, in pixel footprints


def timed_wait4(cmd, log):
    """Runs cmd in the repository root, its output to the file `log`; returns (CPU s of the child,
    user + system, from os.wait4, wall s). Exits with the log's tail if it fails."""
    with open(log, "w") as out:
        t0 = time.monotonic()
        p = subprocess.Popen([str(c) for c in cmd], cwd=ROOT, stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(map(str, cmd))}\n{pathlib.Path(log).read_text()[-3000:]}")
    return usage.ru_utime + usage.ru_stime, wall


def judge(pf, exr, reference, manifest):
    d = json.loads(run([pf, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
    return {"mean_ratio": d["mean"] / d["reference_mean"], **{m: d[m] for m in METRICS}}


def pixel_footprint(manifest, res):
    """The width of one pixel at the look-at point of the manifest's first camera (world units,
    times the manifest's scale): the natural unit of an SPPM radius."""
    m = json.loads((ROOT / manifest).read_text())
    cam = m["cameras"][0]
    scale = m.get("scale", 1.0)
    dist = math.dist(cam["eye"], cam["look_at"]) * scale
    height = int(res.split("x")[1])
    return 2.0 * dist * math.tan(math.radians(cam.get("fov", 45.0)) / 2.0) / height


class Pbrt:
    """Exports a scene for pbrt-v3 and renders it with SPPM or the path tracer."""

    def __init__(self, args, tmp, scene):
        self.args, self.tmp, self.scene = args, pathlib.Path(tmp), scene
        self.manifest, self.reference, self.res = SCENES[scene]
        self.n = 0

    def render(self, integrator, **params):
        self.n += 1
        stem = self.tmp / f"{self.scene}-pbrt-{self.n}"
        flags = ["--integrator", integrator, "--res", self.res, "--image", f"{stem}.exr", "-o", f"{stem}.pbrt"]
        for k, v in params.items():
            flags += [f"--{k.replace('_', '-')}", str(v)]
        run([self.args.exporter, self.manifest] + flags)
        cpu, wall = timed_wait4([self.args.pbrt, "--nthreads", str(self.args.threads), "--quiet", f"{stem}.pbrt"],
                                f"{stem}.log")
        row = {"cpu_s": cpu, "wall_s": wall, **judge(self.args.pf, f"{stem}.exr", self.reference, self.manifest)}
        if not self.args.keep:
            for ext in (".exr", ".pbrt"):
                pathlib.Path(f"{stem}{ext}").unlink(missing_ok=True)
        return row


def calibrate(pbrt, radius):
    """pbrt's fixed CPU cost (parse, BVH, final write) and CPU s per SPPM iteration at this initial
    radius, from two short runs. The cost per iteration grows with the radius (more photons land
    within each visible point's radius), so it is measured per radius."""
    a = pbrt.render("sppm", iterations=4, radius=radius)
    b = pbrt.render("sppm", iterations=16, radius=radius)
    per = max((b["cpu_s"] - a["cpu_s"]) / 12.0, 1e-4)
    fixed = max(a["cpu_s"] - 4 * per, 0.0)
    return fixed, per


def iterations_for(target, fixed, per):
    return max(1, round((target - fixed) / per))


def render_at_cpu(pbrt, target, radius, fixed, per, tolerance=0.1, attempts=3):
    """An SPPM render whose CPU time is within `tolerance` of `target`: later iterations cost less
    than the first ones (the radius shrinks), so the count from the short runs is corrected by the
    CPU time each attempt took, up to `attempts` renders. Returns (row, CPU s per iteration of the
    last run); the row is the last attempt's, with "attempts" and the other attempts' CPU times."""
    n, tried = iterations_for(target, fixed, per), []
    for _ in range(attempts):
        r = {"iterations": n, **pbrt.render("sppm", iterations=n, radius=radius)}
        tried.append({"iterations": n, "cpu_s": r["cpu_s"]})
        per = max((r["cpu_s"] - fixed) / n, 1e-4)
        if abs(r["cpu_s"] - target) <= tolerance * target:
            break
        n = iterations_for(target, fixed, per)
    return {**r, "attempts": tried}, per


def median_row(rows, keys):
    return {k: statistics.median(r[k] for r in rows) for k in keys}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pbrt", required=True, help="the pbrt-v3 binary (bench/sppm/build_pbrt.sh builds one)")
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--exporter", default=str(ROOT / "build/bench/pbrt_scene_export_bench"))
    ap.add_argument("--scenes", default=DEFAULT_SCENES)
    ap.add_argument("--budgets", default="10,60", help="CPU seconds, comma-separated (5-60)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radii", default="", help="fixed sweeps: 'cornell-box:0.01,0.02;scene10:0.05' (world units)")
    ap.add_argument("--verify-spp", type=int, default=0, help="check each export with pbrt's path tracer first")
    ap.add_argument("--keep", default="", help="keep the images and pbrt scenes in this folder")
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    budgets = [float(b) for b in args.budgets.split(",")]
    fixed_radii = {s: [float(r) for r in rs.split(",")] for s, rs in
                   (item.split(":") for item in args.radii.split(";") if item)}
    rows, sweeps, verifications, calibrations = [], [], [], {}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = pathlib.Path(args.keep or tmpdir)
        tmp.mkdir(parents=True, exist_ok=True)
        for scene in args.scenes.split(","):
            manifest, reference, res = SCENES[scene]
            pbrt = Pbrt(args, tmp, scene)
            if args.verify_spp > 0:
                v = {"scene": scene, "spp": args.verify_spp, **pbrt.render("path", spp=args.verify_spp)}
                print(json.dumps({"verify": v}), flush=True)
                verifications.append(v)

            # pf first: its measured CPU time is the target of pbrt's calibration.
            pf_runs = {}
            for budget in budgets:
                runs = []
                for i in range(args.repeat):
                    exr = tmp / f"{scene}-pf-{budget:g}-{i}.exr"
                    cpu, wall = timed_wait4([args.pf, "render", manifest, "--res", res, "--time-budget",
                                             f"{budget / args.threads:g}", "--local-only", "--threads",
                                             str(args.threads), "--seed", str(args.seed + i), "-o", exr,
                                             "--no-png", "-q"], tmp / f"{scene}-pf.log")
                    r = {"cpu_s": cpu, "wall_s": wall, "seed": args.seed + i,
                         "integrator": exr_string(exr, "pf:settings.integrator"), "plan": exr_string(exr, "pf:plan"),
                         **judge(args.pf, exr, reference, manifest)}
                    print(json.dumps({"scene": scene, "budget_s": budget, "renderer": "pf", **r}), flush=True)
                    runs.append(r)
                    if not args.keep:
                        exr.unlink(missing_ok=True)
                pf_runs[budget] = runs

            # pbrt's radius: a sweep at the smallest budget, at pf's CPU time there.
            footprint = pixel_footprint(manifest, res)
            radii = fixed_radii.get(scene) or [round(footprint * f, 5) for f in RADIUS_FACTORS]
            small = min(budgets)
            target = statistics.median(r["cpu_s"] for r in pf_runs[small])
            tried, per_radius = {}, {}

            def sweep_one(radius):
                fixed, per = calibrate(pbrt, radius)
                r, per = render_at_cpu(pbrt, target, radius, fixed, per)
                r = {"scene": scene, "budget_s": small, "target_cpu_s": target, "radius": radius,
                     "fixed_cpu_s": fixed, **r}
                print(json.dumps({"sweep": r}), flush=True)
                sweeps.append(r)
                tried[radius], per_radius[radius] = r, (fixed, per)

            for radius in radii:
                sweep_one(radius)
            # Extend the range (at most twice each way) while the best radius of any metric is at an
            # end of it: the metrics disagree (display favours wide radii), and the per-metric table
            # below should not be limited by the grid either.
            extended = {"up": 0, "down": 0}
            while not fixed_radii.get(scene):
                bests = {min(tried, key=lambda x: tried[x][m]) for m in METRICS}
                if max(tried) in bests and extended["up"] < 2:
                    extended["up"] += 1
                    sweep_one(round(max(tried) * 2, 5))
                elif min(tried) in bests and extended["down"] < 2:
                    extended["down"] += 1
                    sweep_one(round(min(tried) / 2, 5))
                else:
                    break
            radius = min(tried, key=lambda x: tried[x]["rmse_display"])
            # The radius each metric prefers: the display error favours wide radii (less noise on
            # the bright directly lit pixels), the masked and low-frequency errors may prefer
            # narrower ones (less blur and bias).
            best_by = {m: min(tried, key=lambda x: tried[x][m]) for m in METRICS}
            calibrations[scene] = {"radius": radius, "best_radius_by_metric": best_by,
                                   "per_radius": {str(r): {"fixed_cpu_s": f, "cpu_s_per_iteration": p}
                                                  for r, (f, p) in per_radius.items()}}

            for budget in budgets:
                target = statistics.median(r["cpu_s"] for r in pf_runs[budget])
                by_radius = {}
                # The display radius with every repeat; another metric's radius once (pbrt-v3 has no
                # seed: a repeat renders the same image and measures the CPU time only).
                for rad in [radius] + sorted({best_by[m] for m in METRICS} - {radius}):
                    fixed, per_r = per_radius[rad]
                    runs = []
                    for i in range(args.repeat if rad == radius else 1):
                        if i == 0:  # calibrated on this budget's length; the repeats reuse its count
                            r, per_r = render_at_cpu(pbrt, target, rad, fixed, per_r)
                            n = r["iterations"]
                        else:
                            r = {"iterations": n, **pbrt.render("sppm", iterations=n, radius=rad)}
                        print(json.dumps({"scene": scene, "budget_s": budget, "renderer": "pbrt-sppm", "radius": rad,
                                          "target_cpu_s": target, **r}), flush=True)
                        runs.append(r)
                    by_radius[rad] = runs
                keys = ("cpu_s", "wall_s", "mean_ratio") + METRICS
                pf_med = median_row(pf_runs[budget], keys)
                pbrt_med = median_row(by_radius[radius], keys + ("iterations",))
                tuned = {}
                for m in METRICS:
                    med = median_row(by_radius[best_by[m]], keys + ("iterations",))
                    tuned[m] = {"radius": best_by[m], "value": med[m], "cpu_s": med["cpu_s"],
                                "iterations": med["iterations"], "ratio_pf_over_pbrt": pf_med[m] / med[m] if med[m] > 0 else None}
                rows.append({"scene": scene, "budget_s": budget, "pf": pf_med, "pbrt": pbrt_med, "pbrt_radius": radius,
                             "pf_runs": pf_runs[budget], "pbrt_runs": by_radius[radius],
                             "ratio_pf_over_pbrt": {m: pf_med[m] / pbrt_med[m] if pbrt_med[m] > 0 else None
                                                    for m in METRICS},
                             "pbrt_radius_per_metric": tuned,
                             "pbrt_runs_other_radii": {str(k): v for k, v in by_radius.items() if k != radius}})

    if args.json:
        out = {"args": vars(args), "pbrt_settings": {"integrator": "sppm", "maxdepth": 64, "nthreads": args.threads,
                                                      "photonsperiteration": "default (pixels)"},
               "verifications": verifications, "calibrations": calibrations, "sweeps": sweeps, "rows": rows}
        pathlib.Path(args.json).write_text(json.dumps(out, indent=1) + "\n")

    if verifications:
        print("\n| scene | pbrt path spp | CPU s | mean/ref | display | masked | lowfreq |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for v in verifications:
            print(f"| {v['scene']} | {v['spp']} | {v['cpu_s']:.1f} | {v['mean_ratio']:.3f} | {v['rmse_display']:.5f} | "
                  f"{v['rmse_masked']:.5f} | {v['rmse_lowfreq']:.5f} |")
    print("\n| scene | radius | iterations | CPU s | mean/ref | display | masked | lowfreq |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for s in sweeps:
        print(f"| {s['scene']} | {s['radius']:g} | {s['iterations']} | {s['cpu_s']:.1f} | {s['mean_ratio']:.3f} | "
              f"{s['rmse_display']:.5f} | {s['rmse_masked']:.5f} | {s['rmse_lowfreq']:.5f} |")
    print("\n| scene | budget CPU s | CPU s pf / pbrt | pbrt r0, iterations | mean/ref pf / pbrt | "
          "display pf / pbrt (ratio) | masked pf / pbrt (ratio) | lowfreq pf / pbrt (ratio) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        pf, pb, q = r["pf"], r["pbrt"], r["ratio_pf_over_pbrt"]
        cells = " | ".join(f"{pf[m]:.5f} / {pb[m]:.5f} (**{q[m]:.2f}**)" for m in METRICS)
        print(f"| {r['scene']} | {r['budget_s']:g} | {pf['cpu_s']:.1f} / {pb['cpu_s']:.1f} | {r['pbrt_radius']:g}, "
              f"{pb['iterations']:.0f} | {pf['mean_ratio']:.3f} / {pb['mean_ratio']:.3f} | {cells} |")

    print("\nThe same with pbrt's radius chosen per metric (the sweep's best for that metric; its own runs):")
    print("\n| scene | budget CPU s | " + " | ".join(f"{m.split('_')[1]}: r0, CPU s pf / pbrt, pf / pbrt (ratio)" for m in METRICS) + " |")
    print("|---|---:|" + "---:|" * len(METRICS))
    for r in rows:
        cells = " | ".join(f"{t['radius']:g}, {r['pf']['cpu_s']:.1f} / {t['cpu_s']:.1f}, {r['pf'][m]:.5f} / {t['value']:.5f} "
                           f"(**{t['ratio_pf_over_pbrt']:.2f}**)" for m, t in r["pbrt_radius_per_metric"].items())
        print(f"| {r['scene']} | {r['budget_s']:g} | {cells} |")


if __name__ == "__main__":
    main()
