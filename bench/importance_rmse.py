#!/usr/bin/python3
"""Importance-driven photon maps (Wald 1999, 4.7): where the photons land, and the error at the
CPU time spent, against the path tracer.

Part 1 (bench/importance_map_bench, C++): the maps of the scene's camera with importance off and
on (`--direct mc` maps, seed 1), and the fraction of the stored photons inside the viewed room's
box (INVISIBLEDATE-like x in [0, 3.99], z in [0, 4]: the dividing wall at x = 4 is one plane,
whose lit side must not count; SCENE10-like the camera's room, x, z in [16.01, 19.99]).

Part 2: `pf render` rows at the reference's resolution, each compared with
scenes/<scene>/reference-320.exr by `pf diff --json --scene <manifest>` (rmse_display = RMSE of
white, rmse, rmse_masked: without the emitters seen directly, rmse_lowfreq: 4x4 block means).
Time: the CPU time (user + sys) of the whole `pf render` process from getrusage (the machine is
shared: wall time counts the waits for a core), map tracing and building included. The path
tracer's rows are sized to the CPU time of the importance rows (its spp scaled from a 64-spp
probe), so the comparison is at equal CPU time. One map (seed 1), one run per row (--repeat
for medians).

Writes <out>/importance.json and prints a table.

    bench/importance_rmse.py [--scenes invisibledate,scene10] [--repeat 1] [--threads 2]
"""
import argparse
import json
import pathlib
import statistics
import sys
import tempfile

from bench_common import ROOT, run, timed

SCENES = {  # name: (manifest, reference, viewed box x0,x1,z0,z1, direct light of the photon rows)
    "invisibledate": ("scenes/invisibledate/invisibledate.json", "scenes/invisibledate/reference-320.exr",
                      "0,3.99,0,4", "mc"),
    "scene10": ("scenes/scene10/scene10.json", "scenes/scene10/reference-320.exr", "16.01,19.99,16.01,19.99",
                "photon-direct"),
}


def rows(scene, direct, row_set):
    """(name, pf render flags) of the photon-map rows."""
    pm = ["--integrator", "photonmap", "--direct", direct, "--k", "100", "--spp", "16"]
    if row_set == "more-photons":  # where the importance rows go with more photons
        occl = ["--occlusion-test"] if scene == "invisibledate" else []
        tag = "+occl" if occl else ""
        return [
            (f"{direct}{tag} 8M +importance", pm + ["--photons", "8000000", "--importance", "on"] + occl),
            (f"{direct}{tag} 8M +importance p_min 0.01",
             pm + ["--photons", "8000000", "--importance", "on", "--importance-min-probability", "0.01"] + occl),
        ]
    out = [
        (f"{direct} 400k", pm + ["--photons", "400000"]),
        (f"{direct} 2M +importance", pm + ["--photons", "2000000", "--importance", "on"]),
    ]
    if scene == "invisibledate":  # the best row of docs/results/estimators.md (mc+occl, high budget)
        out += [
            (f"{direct}+occl 400k", pm + ["--photons", "400000", "--occlusion-test"]),
            (f"{direct}+occl 2M +importance", pm + ["--photons", "2000000", "--importance", "on", "--occlusion-test"]),
        ]
    return out


def diff(pf, image, reference, manifest):
    r = run([pf, "diff", image, reference, "--scene", manifest, "--json"])
    d = json.loads(r.stdout)
    return {k: d[k] for k in ("rmse_display", "rmse", "rmse_masked", "rmse_lowfreq", "mean", "reference_mean")}


def render_row(pf, manifest, reference, flags, tmp, name, repeat):
    image = pathlib.Path(tmp) / (name.replace(" ", "_").replace("+", "p") + ".exr")
    cpu, wall = [], []
    for _ in range(repeat):
        c, w = timed([pf, "render", manifest, *flags, "-o", image, "--no-png", "-q"])
        cpu.append(c)
        wall.append(w)
    row = {"method": name, "flags": " ".join(flags), "cpu_s": statistics.median(cpu), "wall_s": statistics.median(wall)}
    row.update(diff(pf, image, reference, manifest))
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--map-bench", default="build/bench/importance_map_bench")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--out", default="docs/results")
    ap.add_argument("--rows", default="main", choices=("main", "more-photons"),
                    help="main: 400k without and 2M with importance; more-photons: 8M with importance "
                         "(written to importance-more-photons.json)")
    args = ap.parse_args()
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in [s for s in args.scenes.split(",") if s]:
            manifest, reference, box, direct = SCENES[scene]
            maps = []
            counts = "400000,2000000" if args.rows == "main" else "8000000"
            for line in run([args.map_bench, "--scene", manifest, "--box", box, "--photons", counts,
                             "--threads", str(args.threads)]).stdout.splitlines():
                if line.startswith("JSON "):
                    maps.append(json.loads(line[5:]))
            table = []
            for name, flags in rows(scene, direct, args.rows):
                row = render_row(args.pf, manifest, reference, flags + ["--threads", str(args.threads)], tmp, name,
                                 args.repeat)
                table.append(row)
                print(f"{scene}: {name}: {row['cpu_s']:.1f} s CPU, rmse/white {row['rmse_display']:.4f}", file=sys.stderr)
            # The path tracer at the CPU time of each importance row: spp scaled from a 64-spp probe.
            probe = render_row(args.pf, manifest, reference, ["--integrator", "path", "--spp", "64", "--threads",
                                                               str(args.threads)], tmp, "path 64 spp", args.repeat)
            table.append(probe)
            for target in [r for r in table if "importance" in r["method"] and "400k" not in r["method"]]:
                spp = max(1, int(round(64 * target["cpu_s"] / probe["cpu_s"])))
                row = render_row(args.pf, manifest, reference, ["--integrator", "path", "--spp", str(spp), "--threads",
                                                                 str(args.threads)], tmp,
                                 f"path {spp} spp (= CPU of '{target['method']}')", args.repeat)
                table.append(row)
            result[scene] = {"maps": maps, "renders": table}
    out = ROOT / args.out / ("importance.json" if args.rows == "main" else "importance-more-photons.json")
    out.write_text(json.dumps(result, indent=1) + "\n")
    for scene, r in result.items():
        print(f"\n### {scene}\n")
        print("| importance | photons emitted | stored | in the viewed room | fraction | trace s |")
        print("|---|---:|---:|---:|---:|---:|")
        for m in r["maps"]:
            print(f"| {m['importance']} | {m['photons']} | {m['stored']} | {m['stored_in_box']} | "
                  f"{m['fraction_in_box']:.3f} | {m['trace_seconds']:.2f} |")
        print("\n| method | CPU s | wall s | RMSE / white | rmse | rmse_masked | rmse_lowfreq | mean / ref |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
        for t in r["renders"]:
            print(f"| {t['method']} | {t['cpu_s']:.1f} | {t['wall_s']:.1f} | {t['rmse_display']:.4f} | {t['rmse']:.3g} | "
                  f"{t['rmse_masked']:.3g} | {t['rmse_lowfreq']:.3g} | {t['mean'] / t['reference_mean']:.3f} |")
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
