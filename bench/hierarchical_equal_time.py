#!/usr/bin/python3
"""Hierarchical photon map vs skipping vs multiple maps at equal time (Wald 1999, 4.4-4.5; docs/results/hierarchical-equal-time.md).

For each scene (Cornell box, CornellBox-Sphere, scene8) every plan is rendered at several budgets
with `pf render --plan P --local-only --threads 1`, with the same photons per map and the same k
for all plans, and its error is measured with `pf diff --json --scene` (all three metrics: rmse,
rmse_masked = without the lights and a 2-pixel band, rmse_lowfreq = 4x4 block means outside that
mask) against two references:

  * the converged path-traced reference scenes/<scene>/reference-*.exr: the total error a user
    sees (photon-map bias included; the bias is the same for every plan, since all average maps
    of the same size);
  * the mean of --reference-maps independent maps of the same size ("noise reference"): the same
    bias as every image here, so the error is the noise the plans leave, which is what they differ in.

Plans (the budgets sweep the number of samples, hence maps, per pixel):

    multiple-maps   --maps M                         M maps, every pixel sees all of them
    skipping        --stride 4 --rounds R            R rounds of 16 maps, each on 1/16 of the pixels
    hierarchical    --dims 2 --levels L  n_l = max(n_min, ceil(n0 / decay^l)) with n0 = 32 n_min
                    (decay = 32^(1/L)): the thesis-like schedule
    hierarchical-flat   the same with n0 = 4 n_min (fewer maps on the coarse levels)
    hierarchical-shallow  --levels 3, n0 = 16 n_min, decay 2 (n_l = 16, 8, 4, 2 x n_min): details
                    no wider than 8 pixels, where the map's error is correlated
    hierarchical-shallow-indirect  the same over the photon-map part only (--hier-part indirect);
                    emission + direct light per pixel, DIRECT_PER_NMIN x n_min samples

Time: the CPU time (user + system) of the whole `pf render` process, single-threaded: the machine
is shared and its wall time says more about the neighbours than about the plan. Map building is
included (the hierarchy builds Nmax maps, and the level-0 maps again for localization).

Equal time: per plan, log(error) is interpolated piecewise-linearly in log(CPU time); at every
multiple-maps point whose time lies inside another plan's measured range, the ratio
error_plan(t) / error_mm(t) is the ratio of error x time at equal time (the issue's target:
hierarchical low-frequency error x time <= 0.8 x that of multiple maps). The median ratio over
those points is reported per scene, metric and reference.

    tools/install-deps.sh --bench                  # matplotlib for the plots
    bench/hierarchical_equal_time.py [--scenes cornell-box,cornell-sphere,scene8] [--seeds 1]
    bench/hierarchical_equal_time.py --replot      # tables and plots again from the JSON

--scale N renders every image at N times the scene's resolution (hierarchy levels + log2 N), where
a map costs less against a pass over the image (the thesis measured at 513x513); the path-traced
references exist at the native resolution only, so at N > 1 only the noise reference is used.

Writes <out>/hierarchical-equal-time.json, .md and hierarchical-equal-time-<scene>.png.
"""
import argparse
import json
import math
import pathlib
import statistics
import sys
import tempfile
import time

from bench_common import exr_string, run, timed

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = {  # name: (manifest, path-traced reference, resolution, hierarchy levels)
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr", "256x256", 8),
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr",
                       "256x256", 8),
    "scene8": ("scenes/scene8/scene8.json", "scenes/scene8/reference-320.exr", "320x240", 8),
}
MM_MAPS = (1, 2, 4, 8, 16, 32)
SKIP_STRIDE = 4
SKIP_ROUNDS = (1, 2, 4, 8, 16)
HIER_MIN = (1, 2, 4)
# Schedule families: plan family -> n0 / n_min (decay = that ^ (1/L)). "hierarchical" is the shape
# that reproduced the thesis's table in 2-D (docs/results/hierarchical-2d.md: n0 / n_min = 38 over
# 9 levels); "hierarchical-flat" spends fewer maps on the coarse levels (4x the finest level's
# samples instead of 32x): chosen a priori from the cost of a map (see the .md), not from results.
SCHEDULES = {  # family: (n0 / n_min, levels (None: the scene's), decay (None: (n0 / n_min)^(1/L)))
    "hierarchical": (32, None, None),
    "hierarchical-flat": (4, None, None),
    # Fewer levels (docs/results/hierarchical-equal-time-crn.md, "Fewer levels"): level-0 points
    # every 8 pixels, so every detail spans at most 8 pixels, less than a 10k-photon, k = 50
    # estimate's radius on these images: the map's error is correlated across a detail and cancels.
    # n_l = 16, 8, 4, 2 (x n_min): chosen on the Cornell box (seed 1) among L = 3..5, n0 = 8..32,
    # decay 1.5..4.
    "hierarchical-shallow": (16, 3, 2.0),
    # The same schedule over the photon-map part only (--hier-part indirect; common/plan/hierarchical.h,
    # "Parts"): emission + direct light per pixel with DIRECT_PER_NMIN x n_min samples, added at assembly.
    "hierarchical-shallow-indirect": (16, 3, 2.0),
}
# hierarchical-shallow-indirect: emission + direct light samples per pixel per n_min. 2, 4 and 8 were
# run on all three scenes (seeds 1 and 2): 2 leaves the light seen in CornellBox-Sphere's spheres
# noisy, 8 costs too much on the Cornell box; 4 is the default (docs/results/hierarchical-equal-time.md).
DIRECT_PER_NMIN = 4
METRICS = ("rmse", "rmse_masked", "rmse_lowfreq")
REFERENCES = ("path", "noise")





def plans(levels, scale_levels=0):
    out = [(f"multiple maps ({m})", "multiple-maps", ["--plan", "multiple-maps", "--maps", str(m), "--tile", "64"])
           for m in MM_MAPS]
    out += [(f"skipping (S {SKIP_STRIDE}, {r} rounds)", "skipping",
             ["--plan", "skipping", "--stride", str(SKIP_STRIDE), "--rounds", str(r)]) for r in SKIP_ROUNDS]
    for family, (ratio, fixed_levels, fixed_decay) in SCHEDULES.items():
        lv = levels if fixed_levels is None else fixed_levels + scale_levels
        decay = fixed_decay if fixed_decay is not None else ratio ** (1.0 / lv)
        def part(n):
            if not family.endswith("-indirect"):
                return []
            return ["--hier-part", "indirect", "--hier-direct-samples", str(DIRECT_PER_NMIN * n)]
        out += [(f"{family} (n_min {n})", family,
                 ["--plan", "hierarchical", "--dims", "2", "--levels", str(lv), "--base-samples", str(ratio * n),
                  "--min-samples", str(n), "--decay", f"{decay:.6f}", "--tile", "0"] + part(n)) for n in HIER_MIN]
    return out


def set_direct_per_nmin(n):
    global DIRECT_PER_NMIN
    DIRECT_PER_NMIN = n


def interpolate(points, t):
    """log-log piecewise-linear interpolation of (time, error) points at time t; None outside."""
    pts = sorted(points)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1:
            if t1 == t0:
                return e0
            a = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp((1 - a) * math.log(e0) + a * math.log(e1))
    return None


def equal_time(rows, scene, family, metric, reference):
    """Median over the multiple-maps points of error_family(t) / error_mm(t), and the points."""
    def curve(f):
        return [(r["cpu_seconds"], r[reference][metric]) for r in rows
                if r["scene"] == scene and r["family"] == f and r.get(reference) is not None]
    mm = curve("multiple-maps")
    other = curve(family)
    ratios = []
    for t, e in mm:
        o = interpolate(other, t)
        if o is not None:
            ratios.append((t, o / e))
    return (statistics.median(r for _, r in ratios) if ratios else None), ratios


def stem(tag):
    return "hierarchical-equal-time" + (f"-{tag}" if tag else "")


def plot(rows, scenes, out, name):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("no matplotlib: plots skipped (tools/install-deps.sh --bench)", file=sys.stderr)
        return []
    written = []
    colours = {"multiple-maps": "tab:blue", "skipping": "tab:green", "hierarchical": "tab:red",
               "hierarchical-flat": "tab:orange", "hierarchical-shallow": "tab:purple",
               "hierarchical-shallow-indirect": "tab:brown"}
    for scene in scenes:
        mine = [r for r in rows if r["scene"] == scene]
        fig, axes = plt.subplots(2, 3, figsize=(13, 7.5), squeeze=False)
        for i, reference in enumerate(REFERENCES):
            for j, metric in enumerate(METRICS):
                ax = axes[i][j]
                for family, colour in colours.items():
                    pts = sorted((r["cpu_seconds"], r[reference][metric]) for r in mine
                                 if r["family"] == family and r.get(reference) is not None)
                    if pts:
                        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=colour, label=family)
                ax.set_xscale("log")
                ax.set_yscale("log")
                ax.grid(True, which="both", alpha=0.3)
                ax.set_title(f"{metric} vs {'path-traced' if reference == 'path' else 'many-map'} reference",
                             fontsize=9)
                ax.set_xlabel("CPU seconds of pf render (1 thread)", fontsize=8)
                ax.tick_params(labelsize=7)
                if i == 0 and j == 0:
                    ax.legend(fontsize=8)
        first = mine[0]
        fig.suptitle(f"{scene} {first['res']}: {first['photons']} photons per map, k {first['k']}; "
                     "error against CPU time (lower left is better)", fontsize=10)
        fig.tight_layout()
        path = out / f"{name}-{scene}.png"
        fig.savefig(path, dpi=80)
        plt.close(fig)
        written.append(path.name)
    return written


def write_reports(result, out):
    rows, scenes = result["rows"], result["scenes"]
    a = result["args"]
    name = stem(a.get("tag", ""))
    plots = plot(rows, scenes, out, name)
    default_families = ["multiple-maps", "skipping"] + list(SCHEDULES)
    families = [f for f in default_families if any(r["family"] == f for r in rows)]
    lines = [
        "# Hierarchical vs skipping vs multiple maps at equal time (docs/renderer.md, 'Hierarchical plan')",
        "",
        f"{a['photons']} photons per map and k = {a['k']} for every plan; seed(s) {a['seeds']}; `pf render "
        "--local-only --threads 1`; time = CPU seconds (user + system) of the whole process, map building "
        "included. Reproduce: `bench/hierarchical_equal_time.py "
        f"--scenes {','.join(scenes)} --photons {a['photons']} --k {a['k']} --seeds {a['seeds']} "
        f"--reference-maps {a['reference_maps']}"
        + (f" --plans {','.join(families)}" if families != default_families else "")
        + (f" --scale {a['scale']}" if a.get("scale", 1) != 1 else "")
        + (f" --direct-per-nmin {a['direct_per_nmin']}"
           if "hierarchical-shallow-indirect" in families and a.get("direct_per_nmin", 4) != 4 else "")
        + (f" --extra '{a['extra']}' --tag {a['tag']}" if a.get("extra") or a.get("tag") else "")
        + f"` (writes this file, {name}.json and the plots)." + (f" Every image with `{a['extra']}`." if a.get("extra") else ""),
        "",
        "Two references: *path* = the converged path-traced scenes/<scene>/reference-*.exr (total error, the "
        "photon-map bias included: the same for every plan); *noise* = the mean of "
        f"{a['reference_maps']} maps of the same size (same bias: the error is the plans' noise).",
        "",
        "## Equal time: error ratio to multiple maps",
        "",
        "Median over the multiple-maps budgets inside the other plan's time range of error_plan(t) / "
        "error_mm(t), log-log interpolated: the ratio of error × time at equal time. Target (docs/renderer.md, 'Hierarchical plan'): "
        "hierarchical `rmse_lowfreq` ≤ 0.8.",
        "",
        "| scene | plan | reference | rmse | rmse_masked | rmse_lowfreq | MM points compared |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for scene in scenes:
        for family in [f for f in ("skipping",) + tuple(SCHEDULES) if any(r["family"] == f for r in rows)]:
            for reference in REFERENCES:
                cells, count = [], 0
                for metric in METRICS:
                    med, pts = equal_time(rows, scene, family, metric, reference)
                    cells.append("–" if med is None else f"{med:.2f}")
                    count = max(count, len(pts))
                lines.append(f"| {scene} | {family} | {reference} | {' | '.join(cells)} | {count} |")
    lines += ["", "## Every run", ""]
    for scene in scenes:
        mine = [r for r in rows if r["scene"] == scene]
        lines += [f"### {scene} ({mine[0]['res']})", "",
                  "| plan | maps built | tasks | CPU s | wall s | rmse path | masked path | lowfreq path | "
                  "rmse noise | masked noise | lowfreq noise |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in mine:
            def cells(d):
                return " | ".join("–" if d is None else f"{d[m]:.4f}" for m in METRICS)
            lines.append(f"| {r['method']} | {r['maps_built']} | {r['tasks']} | {r['cpu_seconds']:.2f} | "
                         f"{r['wall_seconds']:.1f} | {cells(r['path'])} | {cells(r['noise'])} |")
        lines.append("")
        if f"{name}-{scene}.png" in plots:
            lines += [f"![{scene}: error against CPU time]({name}-{scene}.png)", ""]
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / (name + '.md')} and {len(plots)} plots")


def merge_runs(results):
    """One result from runs with disjoint seeds: per (scene, method) the RMS error over every seed
    (each run's row is already the RMS over its seeds) and the median of every CPU time."""
    first = results[0]
    seeds = [s for r in results for s in str(r["args"]["seeds"]).split(",")]
    if len(set(seeds)) != len(seeds):
        sys.exit("--merge: the runs share a seed")
    for r in results[1:]:
        if {k: v for k, v in r["args"].items() if k != "seeds"} != \
                {k: v for k, v in first["args"].items() if k != "seeds"}:
            sys.exit("--merge: the runs differ in more than their seeds")
    rows = []
    for row in first["rows"]:
        same = [x for r in results for x in r["rows"] if x["scene"] == row["scene"] and x["method"] == row["method"]]
        if len(same) != len(results):
            sys.exit(f"--merge: {row['scene']} {row['method']} is not in every run")
        n = [len(str(r["args"]["seeds"]).split(",")) for r in results]
        merged = dict(row)
        merged["cpu_seconds_all"] = [t for x in same for t in x["cpu_seconds_all"]]
        merged["cpu_seconds"] = statistics.median(merged["cpu_seconds_all"])
        merged["wall_seconds"] = statistics.median(x["wall_seconds"] for x in same)
        for ref in REFERENCES:
            if row.get(ref) is None:
                continue
            merged[ref] = {m: math.sqrt(sum(k * x[ref][m] ** 2 for k, x in zip(n, same)) / sum(n)) for m in METRICS}
        rows.append(merged)
    return {"args": dict(first["args"], seeds=",".join(seeds)), "scenes": first["scenes"], "rows": rows}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--photons", type=int, default=10000)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--seeds", default="1", help="comma-separated; errors are the RMS over seeds, time the median")
    ap.add_argument("--reference-maps", type=int, default=64)
    ap.add_argument("--plans", default="multiple-maps,skipping," + ",".join(SCHEDULES))
    ap.add_argument("--work", help="folder for the images (kept; noise references are reused from it)")
    ap.add_argument("--out", default=str(ROOT / "docs/results"))
    ap.add_argument("--extra", default="", help="more pf render flags for every image (e.g. '--local-pass 4')")
    ap.add_argument("--scale", type=int, default=1, choices=(1, 2, 4),
                    help="render at this multiple of each scene's resolution (path reference skipped if > 1)")
    ap.add_argument("--tag", default="", help="output names hierarchical-equal-time-<tag>.* (default: no tag)")
    ap.add_argument("--direct-per-nmin", type=int, default=DIRECT_PER_NMIN,
                    help="hierarchical-shallow-indirect: emission + direct light samples per pixel per n_min")
    ap.add_argument("--replot", action="store_true")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="combine runs of the same plans with different --seeds (e.g. run in parallel): errors "
                         "RMS over all seeds, CPU time the median over all; writes the tables and plots to --out")
    args = ap.parse_args()
    set_direct_per_nmin(args.direct_per_nmin)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.merge:
        merged = merge_runs([json.loads(pathlib.Path(f).read_text()) for f in args.merge])
        (out / f"{stem(merged['args'].get('tag', ''))}.json").write_text(json.dumps(merged, indent=2) + "\n")
        write_reports(merged, out)
        return
    if args.replot:
        write_reports(json.loads((out / f"{stem(args.tag)}.json").read_text()), out)
        return
    work = pathlib.Path(args.work) if args.work else pathlib.Path(tempfile.mkdtemp(prefix="pf-hier-eq-"))
    work.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    wanted = set(args.plans.split(","))
    scenes = [s for s in args.scenes.split(",") if s]
    rows = []
    for scene in scenes:
        manifest, path_ref, res, levels = SCENES[scene]
        if args.scale != 1:
            w, h = (int(v) * args.scale for v in res.split("x"))
            res, levels, path_ref = f"{w}x{h}", levels + int(math.log2(args.scale)), None
        common = [args.pf, "render", manifest, "--integrator", "photonmap", "--photons", str(args.photons), "--k",
                  str(args.k), "--res", res, "--spp", "1", "--local-only", "--threads", "1", "--no-png", "-q"]
        common += args.extra.split()
        extra_key = args.extra.replace(" ", "").replace("-", "")
        noise_ref = work / f"{scene}-noise-ref-{args.photons}-{args.k}-{args.reference_maps}{extra_key}.exr"
        if not noise_ref.exists():
            print(f"{scene}: noise reference, {args.reference_maps} maps ...", flush=True)
            run(common + ["--plan", "multiple-maps", "--maps", str(args.reference_maps), "--tile", "64", "--seed",
                          "999", "-o", str(noise_ref)])

        def judge(exr, ref):
            d = json.loads(run([args.pf, "diff", exr, ref, "--json", "--scene", manifest]).stdout)
            return {k: d[k] for k in METRICS}

        for method, family, flags in plans(levels, int(math.log2(args.scale))):
            if family not in wanted:
                continue
            cpus, walls, errs = [], [], {ref: {m: [] for m in METRICS} for ref in REFERENCES}
            for seed in seeds:
                exr = work / f"{scene}-{method.replace(' ', '_').replace(',', '')}-s{seed}.exr"
                cpu, wall = timed(common + flags + ["--seed", str(seed), "-o", str(exr)])
                cpus.append(cpu)
                walls.append(wall)
                for ref, path in (("path", path_ref), ("noise", noise_ref)):
                    if path is None:
                        continue
                    d = judge(exr, path)
                    for m in METRICS:
                        errs[ref][m].append(d[m])
            row = {"scene": scene, "res": res, "photons": args.photons, "k": args.k, "method": method,
                   "family": family, "flags": " ".join(flags), "cpu_seconds": statistics.median(cpus),
                   "cpu_seconds_all": cpus, "wall_seconds": statistics.median(walls),
                   "maps_built": int(exr_string(exr, "photons.maps_built") or 0),
                   "tasks": int(exr_string(exr, "tasks") or 0)}
            for ref in REFERENCES:  # RMS over seeds
                row[ref] = {m: math.sqrt(sum(v * v for v in errs[ref][m]) / len(errs[ref][m])) for m in METRICS} \
                    if errs[ref][METRICS[0]] else None
            rows.append(row)
            pr = row["path"] or {m: float("nan") for m in METRICS}
            print(f"{scene:14s} {method:28s} maps {row['maps_built']:5d} cpu {row['cpu_seconds']:7.2f} s  "
                  f"path {pr['rmse']:.4f}/{pr['rmse_masked']:.4f}/{pr['rmse_lowfreq']:.4f}"
                  f"  noise {row['noise']['rmse']:.4f}/{row['noise']['rmse_masked']:.4f}/"
                  f"{row['noise']['rmse_lowfreq']:.4f}", flush=True)
    result = {"args": {"photons": args.photons, "k": args.k, "seeds": args.seeds,
                       "reference_maps": args.reference_maps, "extra": args.extra, "tag": args.tag,
                       "scale": args.scale, "direct_per_nmin": args.direct_per_nmin},
              "scenes": scenes, "rows": rows}
    (out / f"{stem(args.tag)}.json").write_text(json.dumps(result, indent=2) + "\n")
    write_reports(result, out)


if __name__ == "__main__":
    main()
