#!/usr/bin/python3
"""The noise of a converged path-traced reference, per error metric, and the progressive plan's
convergence with it taken out (docs/results/progressive-photon-mapping.md, "The reference's noise").

An error measured against a reference R of the image I is E[(I − R)²] = (I − truth)² + Var(R) per
pixel: the reference's own noise is a floor under every method's error. To measure Var(R) for each
metric of `pf diff --scene` (rmse, rmse_masked, rmse_lowfreq), pf's path tracer renders the scene
twice more, A and B, with two other seeds: D(A, R)² = Var(A) + Var(R) and D(A, B)² = 2·Var(A), so
Var(R) = (D(A, R)² + D(B, R)²)/2 − D(A, B)²/2, with no assumption on how the noise falls with
the samples (pf's sampler is quasi-random: it falls faster than 1/spp). Then each error e of the
progressive run recorded in progressive-photon-mapping.json becomes sqrt(e² − Var(R)) and the
slopes are fitted again.

    bench/reference_noise.py [--scenes cornell-box,cornell-sphere] [--spp 1024] [--seeds 7,8]
                             [--progressive docs/results/progressive-photon-mapping.json]
                             [--json docs/results/reference-noise.json]
"""
import argparse
import json
import math
import pathlib
import tempfile

from bench_common import ROOT, exr_string, run, timed
from progressive_convergence import METRICS, SCENES, slope


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pf", default=str(ROOT / "build/client/pf"))
    ap.add_argument("--scenes", default="cornell-box,cornell-sphere")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--seeds", default="7,8", help="two seeds, not the reference's")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--progressive", default=str(ROOT / "docs/results/progressive-photon-mapping.json"))
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    noise = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            manifest, reference, res = SCENES[scene]
            ref_spp = float(exr_string(ROOT / reference, "spp"))
            seeds = args.seeds.split(",")
            if len(seeds) != 2 or set(seeds) & set((exr_string(ROOT / reference, "seeds") or "").split(",")):
                raise SystemExit(f"--seeds: two seeds that are not {reference}'s")
            images, cpu = [], 0.0
            for seed in seeds:
                images.append(pathlib.Path(tmp) / f"{scene}-{seed}.exr")
                cpu += timed([args.pf, "render", manifest, "--integrator", "path", "--spp", str(args.spp), "--res",
                              res, "--local-only", "--threads", str(args.threads), "--seed", seed, "--no-png", "-q",
                              "-o", str(images[-1])])[0]

            def between(a, b):
                return json.loads(run([args.pf, "diff", a, b, "--json", "--scene", manifest]).stdout)

            ar, br, ab = between(images[0], reference), between(images[1], reference), between(images[0], images[1])
            noise[scene] = {"reference_spp": ref_spp, "spp": args.spp, "seeds": seeds, "cpu_s": cpu}
            for m in METRICS:
                var_ref = (ar[m] ** 2 + br[m] ** 2) / 2 - ab[m] ** 2 / 2
                noise[scene].update({f"{m}_a_ref": ar[m], f"{m}_b_ref": br[m], f"{m}_a_b": ab[m],
                                     f"{m}_image": ab[m] / math.sqrt(2.0),
                                     f"{m}_reference": math.sqrt(max(var_ref, 0.0))})
            print(json.dumps({"scene": scene, **noise[scene]}), flush=True)
    recorded = json.loads(pathlib.Path(args.progressive).read_text())
    rows, slopes = [], []
    for r in recorded["rows"]:
        if r["scene"] not in noise:
            continue
        row = dict(r)
        for m in METRICS:
            floor = noise[r["scene"]][f"{m}_reference"]
            row[f"{m}_corrected"] = math.sqrt(max(r[m] ** 2 - floor ** 2, 0.0))
        rows.append(row)
    print("\n| scene | metric | reference noise | 8 passes: measured → corrected | 512 passes: measured → corrected |")
    print("|---|---|---:|---|---|")
    for scene in noise:
        for m in METRICS:
            pts = {r["maps"]: r for r in rows if r["scene"] == scene and r["plan"] == "progressive"}
            lo, hi = pts[min(pts)], pts[max(pts)]
            print(f"| {scene} | {m} | {noise[scene][f'{m}_reference']:.5f} | {lo[m]:.5f} → {lo[f'{m}_corrected']:.5f} | "
                  f"{hi[m]:.5f} → {hi[f'{m}_corrected']:.5f} |")
    print("\n| scene | plan | range | slope masked | corrected | slope lowfreq | corrected |")
    print("|---|---|---|---:|---:|---:|---:|")
    for scene in noise:
        for plan in ("progressive", "multiple-maps"):
            pts = sorted((r for r in rows if r["scene"] == scene and r["plan"] == plan), key=lambda r: r["maps"])
            for lo, hi in ((8, 128), (8, 512), (64, 512)):
                sel = [r for r in pts if lo <= r["maps"] <= hi]
                if len(sel) < 2:
                    continue
                ns = [r["maps"] for r in sel]
                s = {m: slope(ns, [r[m] for r in sel]) for m in ("rmse_masked", "rmse_lowfreq")}
                c = {m: slope(ns, [max(r[f"{m}_corrected"], 1e-12) for r in sel]) for m in ("rmse_masked", "rmse_lowfreq")}
                slopes.append({"scene": scene, "plan": plan, "range": f"{lo}-{hi}", "measured": s, "corrected": c})
                print(f"| {scene} | {plan} | {lo}–{hi} | {s['rmse_masked']:.3f} | {c['rmse_masked']:.3f} | "
                      f"{s['rmse_lowfreq']:.3f} | {c['rmse_lowfreq']:.3f} |")
    if args.json:
        pathlib.Path(args.json).write_text(
            json.dumps({"args": vars(args), "noise": noise, "rows": rows, "slopes": slopes}, indent=1) + "\n")


if __name__ == "__main__":
    main()
