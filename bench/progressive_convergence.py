#!/usr/bin/python3
"""Progressive photon mapping (Knaus & Zwicker 2011; docs/renderer.md "Progressive plan") against
multiple maps of the same photons per map: error against the converged path-traced reference as the
passes (maps) grow, and its log-log slope (docs/results/progressive-photon-mapping.md).

Every image is `pf render SCENE --integrator photonmap --photons P --k K --spp 1 --local-only
--plan progressive --passes N` or `--plan multiple-maps --maps N`, the same seed, judged with
`pf diff --json --scene` (rmse, rmse_masked = without the lights seen directly and a 2-pixel band,
rmse_lowfreq = 4x4 block means outside that mask). The slope is the least-squares fit of
log(error) on log(N) over all N.

    bench/progressive_convergence.py [--scenes cornell-box] [--passes 8,16,32,64,128] [--photons 10000]
                                     [--k 50] [--threads 2] [--plans progressive,multiple-maps]
                                     [--extra "--set progressive-alpha=0.5"] [--out docs/results]

Writes <out>/progressive-photon-mapping.json and prints a Markdown table.
"""
import argparse
import json
import math
import pathlib
import tempfile

from bench_common import ROOT, run, timed

SCENES = {  # name: (manifest, path-traced reference, resolution)
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr", "256x256"),
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr",
                       "256x256"),
}
METRICS = ("rmse", "rmse_masked", "rmse_lowfreq")
PLANS = {"progressive": "--passes", "multiple-maps": "--maps"}


def slope(ns, errors):
    xs, ys = [math.log(n) for n in ns], [math.log(e) for e in errors]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--scenes", default="cornell-box")
    ap.add_argument("--passes", default="8,16,32,64,128")
    ap.add_argument("--photons", type=int, default=10000)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--extra", default="", help="more pf render flags for every image")
    ap.add_argument("--plans", default=",".join(PLANS), help="progressive, multiple-maps or both")
    ap.add_argument("--out", default=str(ROOT / "docs/results"))
    args = ap.parse_args()
    ns = [int(n) for n in args.passes.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            manifest, reference, res = SCENES[scene]
            for plan in args.plans.split(","):
                flag = PLANS[plan]
                for n in ns:
                    exr = pathlib.Path(tmp) / f"{scene}-{plan}-{n}.exr"
                    cmd = [args.pf, "render", manifest, "--integrator", "photonmap", "--photons", str(args.photons),
                           "--k", str(args.k), "--res", res, "--spp", "1", "--local-only", "--threads",
                           str(args.threads), "--seed", str(args.seed), "--plan", plan, flag, str(n), "--tile", "64",
                           "--no-png", "-q", "-o", str(exr)] + args.extra.split()
                    cpu, wall = timed(cmd)
                    d = json.loads(run([args.pf, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
                    row = {"scene": scene, "plan": plan, "maps": n, "cpu_s": cpu, "wall_s": wall,
                           **{m: d[m] for m in METRICS}}
                    print(json.dumps(row), flush=True)
                    rows.append(row)
    slopes = []
    for scene in args.scenes.split(","):
        for plan in args.plans.split(","):
            pts = [r for r in rows if r["scene"] == scene and r["plan"] == plan]
            slopes.append({"scene": scene, "plan": plan,
                           **{m: slope([r["maps"] for r in pts], [r[m] for r in pts]) for m in METRICS}})
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "progressive-photon-mapping.json").write_text(
        json.dumps({"args": vars(args), "rows": rows, "slopes": slopes}, indent=1) + "\n")
    print("\n| scene | plan | passes/maps | CPU s | rmse | rmse_masked | rmse_lowfreq |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['plan']} | {r['maps']} | {r['cpu_s']:.1f} | {r['rmse']:.5f} | "
              f"{r['rmse_masked']:.5f} | {r['rmse_lowfreq']:.5f} |")
    print("\n| scene | plan | slope rmse | slope masked | slope lowfreq |")
    print("|---|---|---|---|---|")
    for s in slopes:
        print(f"| {s['scene']} | {s['plan']} | {s['rmse']:.3f} | {s['rmse_masked']:.3f} | {s['rmse_lowfreq']:.3f} |")


if __name__ == "__main__":
    main()
