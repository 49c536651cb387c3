#!/usr/bin/python3
"""Convergence of the independent and the Sobol sampler (docs/renderer.md, 'Sampling and determinism').

Runs build/bench/sampler_convergence_bench (one progressive path-traced render per scene and
sampler, 1 ... --max-spp samples per pixel, plus the photon-map emission experiment), keeps every
JSON line in docs/results/sampler_convergence.json, and writes the table
docs/results/sampler_convergence.md (the prose around it lives in docs/results/sampler.md) and
the plot docs/results/sampler_convergence.png.

  bench/sampler_convergence.py                # run everything (1 thread), then report
  bench/sampler_convergence.py --report-only  # redo table and plot from the JSON
  bench/sampler_convergence.py --only cornell-sphere --no-photons
                                              # rerun one scene; keep the JSON's other lines

RMSE against scenes/*/reference-256.exr has the reference's own noise in it; it is taken out in
quadrature: rmse_true = sqrt(max(rmse^2 - noise^2, 0)). The reference noise per metric comes from
the independent sampler's own run: it is unbiased Monte Carlo like the reference (R spp), so at N
spp rmse^2 = s^2 (1/N + 1/R), s^2 = rmse^2 / (1/N + 1/R) and noise = s / sqrt(R) (N = 64).
"""
import argparse
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "docs", "results")
SCENES = [
    ("cornell-box", "scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr"),
    ("cornell-sphere", "scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr"),
]
# Samples per pixel of each reference (independent path tracing; scenes/*/README.md).
REFERENCE_SPP = {"cornell-box": 8192, "cornell-sphere": 6144}
NOISE_FROM_SPP = 64
SAMPLERS = ["independent", "sobol"]
METRICS = ["rmse", "rmse_edge", "rmse_masked", "rmse_lowfreq"]


def run(args):
    tool = os.path.join(ROOT, args.build, "bench", "sampler_convergence_bench")
    lines = []
    if args.only:
        # Keep what is not rerun: the other scenes' lines and (with --no-photons) the photon rows.
        old = json.load(open(os.path.join(RESULTS, "sampler_convergence.json")))
        lines = [l for l in old if not (l["mode"] == "progressive" and l["name"] in args.only) and
                 not (l["mode"] != "progressive" and not args.no_photons)]
    for name, scene, ref in SCENES:
        if args.only and name not in args.only:
            continue
        max_spp = args.max_spp if name == "cornell-box" else args.sphere_max_spp
        for sampler in SAMPLERS:
            cmd = [tool, "--scene", scene, "--reference", ref, "--sampler", sampler, "--max-spp",
                   str(max_spp), "--threads", str(args.threads)]
            print(" ".join(cmd), file=sys.stderr, flush=True)
            out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
            lines += [dict(json.loads(l), name=name) for l in out.splitlines() if l.strip()]
            save(lines)
    name, scene, ref = SCENES[0]
    for standalone in ([] if args.no_photons else ["1"]):
        for sampler in SAMPLERS:
            cmd = [tool, "--scene", scene, "--reference", ref, "--photon-sampler", sampler, "--photons",
                   str(args.photons), "--spp", str(args.photon_spp), "--maps", str(args.maps), "--standalone",
                   standalone, "--threads", str(args.threads)]
            print(" ".join(cmd), file=sys.stderr, flush=True)
            out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
            lines += [dict(json.loads(l), name=name) for l in out.splitlines() if l.strip()]
            save(lines)
    return lines


def save(lines):
    with open(os.path.join(RESULTS, "sampler_convergence.json"), "w") as f:
        json.dump(lines, f, indent=1)


def slope(points):
    """Least-squares slope of log(rmse) over log(spp)."""
    xs = [math.log(p[0]) for p in points if p[1] > 0]
    ys = [math.log(p[1]) for p in points if p[1] > 0]
    if len(xs) < 2:
        return float("nan")
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def report(lines, args):
    prog = [l for l in lines if l["mode"] == "progressive"]
    noise = {}
    for name, _, _ in SCENES:
        r = REFERENCE_SPP[name]
        row = [l for l in prog if l["name"] == name and l["sampler"] == "independent" and l["spp"] == NOISE_FROM_SPP]
        if row:
            noise[name] = {m: math.sqrt(row[0][m] ** 2 / (1 / NOISE_FROM_SPP + 1 / r) / r) for m in METRICS}
    md = ["| scene | metric | sampler | " + " | ".join(f"{s} spp" for s in sorted({l['spp'] for l in prog}))
          + f" | slope {args.fit_from}–{args.fit_to} spp | raw slope |",
          "|---|---|---|" + "---|" * (len(sorted({l['spp'] for l in prog})) + 2)]
    curves = {}
    for name, _, _ in SCENES:
        for metric in METRICS:
            for sampler in SAMPLERS:
                pts = sorted((l["spp"], l[metric]) for l in prog if l["name"] == name and l["sampler"] == sampler)
                if not pts:
                    continue
                n = noise.get(name, {}).get(metric, 0.0)
                true = [(s, math.sqrt(max(v * v - n * n, 0.0))) for s, v in pts]
                curves[(name, metric, sampler)] = true
                fit = slope([p for p in true if args.fit_from <= p[0] <= args.fit_to])
                raw = slope([p for p in pts if args.fit_from <= p[0] <= args.fit_to])
                md.append(f"| {name} | {metric} | {sampler} | " + " | ".join(f"{v:.4g}" for _, v in true)
                          + f" | {fit:.2f} | {raw:.2f} |")
    md.append("")
    md.append("Reference noise taken out (estimated from the independent run at "
              f"{NOISE_FROM_SPP} spp): " + "; ".join(
                  f"{n}: " + ", ".join(f"{m} {v:.3g}" for m, v in noise[n].items()) for n in noise))
    md.append("")
    md.append("Ratio independent / sobol of the noise-corrected RMSE:")
    md.append("")
    md.append("| scene | metric | " + " | ".join(f"{s} spp" for s in sorted({l['spp'] for l in prog})) + " |")
    md.append("|---|---|" + "---|" * len(sorted({l['spp'] for l in prog})))
    for name, _, _ in SCENES:
        for metric in METRICS:
            a, b = curves.get((name, metric, "independent")), curves.get((name, metric, "sobol"))
            if not a or not b:
                continue
            md.append(f"| {name} | {metric} | " + " | ".join(
                (f"{x[1] / y[1]:.2f}" if y[1] > 0 else "∞") for x, y in zip(a, b)) + " |")
    pm = [l for l in lines if l["mode"] == "photon-emission"]
    if pm:
        md.append("")
        md.append("Photon map, quasi-random vs random emission and scattering at fixed N "
                  f"({pm[0]['photons']} photons, {pm[0]['spp']} spp Sobol pixel samples, mean ± standard "
                  "error over the maps):")
        md.append("")
        md.append("| direct light | photon sampler | maps | " + " | ".join(METRICS) + " |")
        md.append("|---|---|---|" + "---|" * len(METRICS))
        for direct in ["photon-map", "auto"]:
            for sampler in SAMPLERS:
                rows = [l for l in pm if l["direct"] == direct and l["photon_sampler"] == sampler]
                if not rows:
                    continue
                cells = []
                for m in METRICS:
                    v = [r[m] for r in rows]
                    mean = sum(v) / len(v)
                    se = math.sqrt(sum((x - mean) ** 2 for x in v) / max(len(v) - 1, 1) / len(v))
                    cells.append(f"{mean:.4g} ± {se:.2g}")
                md.append(f"| {direct} | {sampler} | {len(rows)} | " + " | ".join(cells) + " |")
    with open(os.path.join(RESULTS, "sampler_convergence.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(md))
    plot(curves)


def plot(curves):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing (tools/install-deps.sh --bench): no plot", file=sys.stderr)
        return
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    panels = [("cornell-box", ["rmse", "rmse_masked", "rmse_lowfreq"], "Cornell box, whole image / masked / low-freq"),
              ("cornell-box", ["rmse_edge"], "Emitter-edge pixels (Cornell; Sphere dotted)"),
              ("cornell-sphere", ["rmse", "rmse_masked"], "CornellBox-Sphere")]
    styles = {"independent": "--", "sobol": "-"}
    for ax, (name, metrics, title) in zip(axes, panels):
        for metric in metrics:
            for sampler in SAMPLERS:
                c = curves.get((name, metric, sampler))
                if not c:
                    continue
                c = [p for p in c if p[1] > 0]  # 0: below the reference's own noise
                ax.loglog([p[0] for p in c], [p[1] for p in c], styles[sampler], marker="o", ms=3,
                          label=f"{metric} {sampler}")
                if metric == "rmse_edge":
                    e = [p for p in curves.get(("cornell-sphere", metric, sampler), []) if p[1] > 0]
                    ax.loglog([p[0] for p in e], [p[1] for p in e], ":", marker="s", ms=3,
                              label=f"sphere {metric} {sampler}")
        ax.set_title(title)
        ax.set_xlabel("samples per pixel")
        ax.set_ylabel("RMSE vs reference (reference noise removed)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(RESULTS, "sampler_convergence.png"), dpi=110)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build", default="build")
    p.add_argument("--max-spp", type=int, default=1024)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--sphere-max-spp", type=int, default=1024)
    p.add_argument("--photons", type=int, default=50000)
    p.add_argument("--photon-spp", type=int, default=4)
    p.add_argument("--maps", type=int, default=3)
    p.add_argument("--fit-from", type=int, default=16)
    p.add_argument("--fit-to", type=int, default=1024)
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--only", nargs="+", choices=[s[0] for s in SCENES],
                   help="run only these scenes' progressive renders; the JSON's other lines are kept")
    p.add_argument("--no-photons", action="store_true", help="skip the photon-emission experiment")
    args = p.parse_args()
    if args.report_only:
        lines = json.load(open(os.path.join(RESULTS, "sampler_convergence.json")))
    else:
        lines = run(args)
    report(lines, args)


if __name__ == "__main__":
    main()
