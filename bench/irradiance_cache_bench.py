#!/usr/bin/python3
"""Irradiance caching for the local pass: time and error against the local pass without it.

For each scene (Cornell box, scene8, the INVISIBLEDATE-like pair of rooms) renders the local
pass (Wald 1999, 4.3: `--direct mc --local-pass N`) without the cache and with it
(`--irradiance-cache --irradiance-cache-error a`) at the reference's resolution with one map
(seed 1), and compares each image with scenes/<scene>/reference-*.exr by
`pf diff --json --scene <manifest>`: rmse, rmse_masked (without the emitters seen directly) and
rmse_lowfreq (4x4 block means: the blotches). Times: the CPU time (user + sys) of the whole
`pf render` process (resource.getrusage of the children: less disturbed by other engineers' jobs
than the wall time on this shared machine; map tracing and building included, the same in every
row of a scene) and its wall time. Repeats are interleaved (repeat r of every row before repeat
r + 1 of any), medians reported. Gathers and cache interpolations come from the EXR header
(photons.local_pass_gathers, photons.cache_interpolations).

Writes <out>/irradiance_cache.json and prints a table with each row's ratios to the uncached
local pass of its scene.

    bench/irradiance_cache_bench.py [--scenes cornell-box,scene8,invisibledate] [--repeat 3]
        [--photons 100000] [--k 50] [--spp 2] [--rays 8] [--errors 0.1,0.2,0.4] [--threads 2]
"""
import argparse
import json
import pathlib
import resource
import statistics
import sys
import tempfile
import time

from bench_common import exr_string, run, timed

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = {  # name: (manifest, reference, resolution)
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr", "256x256"),
    "scene8": ("scenes/scene8/scene8.json", "scenes/scene8/reference-320.exr", "320x240"),
    "invisibledate": ("scenes/invisibledate/invisibledate.json", "scenes/invisibledate/reference-320.exr",
                      "320x240"),
}





def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--photons", type=int, default=100_000)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--spp", type=int, default=2)
    ap.add_argument("--rays", default="8", help="gather rays per local pass (comma-separated: one row each)")
    ap.add_argument("--cache-rays", default="", help="gather rays of the cached rows (default: --rays)")
    ap.add_argument("--errors", default="0.1,0.2,0.4", help="Ward's a of the cached rows")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    scenes = [s for s in args.scenes.split(",") if s]
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"unknown scene {s} (have {', '.join(SCENES)})")
    rays = [int(n) for n in args.rays.split(",")]
    cache_rays = [int(n) for n in args.cache_rays.split(",")] if args.cache_rays else rays
    errors = [float(a) for a in args.errors.split(",") if a]
    methods = [(f"local pass {n}", n, 0.0) for n in rays]
    methods += [(f"cache a={a:g}, {n} rays", n, a) for n in cache_rays for a in errors]
    work = pathlib.Path(tempfile.mkdtemp(prefix="pf-irrcache-"))
    rows = {}
    for rep in range(args.repeat):
        for scene in scenes:
            manifest, reference, res = SCENES[scene]
            for i, (name, n, a) in enumerate(methods):
                exr = work / f"{scene}-{i}.exr"  # each repeat writes the same bits again
                cmd = [args.pf, "render", manifest, "--integrator", "photonmap", "--direct", "mc", "--photons",
                       args.photons, "--k", args.k, "--spp", args.spp, "--res", res, "--seed", 1, "--threads",
                       args.threads, "--local-pass", n, "-q", "--no-png", "-o", exr]
                if a > 0:
                    cmd += ["--irradiance-cache", "--irradiance-cache-error", a]
                cpu, wall = timed(cmd)
                row = rows.setdefault((scene, name), {"scene": scene, "method": name, "rays": n, "error": a,
                                                      "cpu": [], "wall": [], "exr": str(exr)})
                row["cpu"].append(round(cpu, 3))
                row["wall"].append(round(wall, 3))
                if rep == 0:  # the image is the same bits every repeat (deterministic)
                    d = json.loads(run([args.pf, "diff", exr, reference, "--json", "--scene", manifest]).stdout)
                    row.update({k: d[k] for k in ("rmse", "rmse_masked", "rmse_lowfreq")})
                    row["mean_ratio"] = d["mean"] / d["reference_mean"]
                    row["gathers"] = int(exr_string(exr, "photons.local_pass_gathers") or 0)
                    row["interpolations"] = int(exr_string(exr, "photons.cache_interpolations") or 0)
                print(f"rep {rep} {scene:13s} {name:22s} cpu {cpu:7.2f} s wall {wall:7.2f} s", flush=True)
    out = []
    print()
    print(f"{args.photons} photons, k {args.k}, {args.spp} spp, --direct mc, {args.threads} threads, "
          f"medians of {args.repeat}; ratios to the uncached local pass with the same scene "
          f"(first --rays value)")
    print(f"{'scene':13s} {'method':22s} {'cpu s':>8s} {'wall s':>8s} {'gathers':>9s} {'rmse':>8s} "
          f"{'masked':>8s} {'lowfreq':>8s} {'mean/ref':>8s} | {'cpu x':>6s} {'rmse x':>6s} {'mask x':>6s} "
          f"{'lowf x':>6s}")
    for scene in scenes:
        base = rows[(scene, methods[0][0])]
        base_cpu = statistics.median(base["cpu"])
        for name, _, _ in methods:
            r = rows[(scene, name)]
            r["cpu_median"] = statistics.median(r["cpu"])
            r["wall_median"] = statistics.median(r["wall"])
            r["cpu_ratio"] = r["cpu_median"] / base_cpu
            for k in ("rmse", "rmse_masked", "rmse_lowfreq"):
                r[k + "_ratio"] = r[k] / base[k]
            print(f"{scene:13s} {name:22s} {r['cpu_median']:8.2f} {r['wall_median']:8.2f} {r['gathers']:9d} "
                  f"{r['rmse']:8.4f} {r['rmse_masked']:8.4f} {r['rmse_lowfreq']:8.4f} {r['mean_ratio']:8.3f} | "
                  f"{r['cpu_ratio']:6.2f} {r['rmse_ratio']:6.2f} {r['rmse_masked_ratio']:6.2f} "
                  f"{r['rmse_lowfreq_ratio']:6.2f}")
            out.append(r)
    result = {"photons": args.photons, "k": args.k, "spp": args.spp, "threads": args.threads,
              "repeat": args.repeat, "load_average": list(__import__("os").getloadavg()), "rows": out}
    text = json.dumps(result, indent=1)
    if args.out:
        pathlib.Path(args.out).write_text(text + "\n")
        print(f"wrote {args.out}")
    else:
        print(text)


if __name__ == "__main__":
    main()
