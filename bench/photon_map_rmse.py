#!/usr/bin/env python3
"""RMSE of the standalone photon-map image against the converged path-traced reference.

N in {100k, 1M} x k in {50, 200} on the Cornell box and CornellBox-Sphere, with
times. Renders with `pf render --integrator photonmap`, compares with `pf diff --json`, and
writes a Markdown table and JSON (docs/results/photon_map_rmse.{md,json}) plus PNG previews
of every image so the artifacts of Wald 1999 §3.3 can be looked at.

    bench/photon_map_rmse.py [--pf build/client/pf] [--spp 4] [--res 256x256]
"""
import argparse
import json
import pathlib
import subprocess
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = {
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr"),
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr"),
}


def run(cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--spp", type=int, default=4, help="camera samples per pixel (one map)")
    ap.add_argument("--res", default="256x256")
    ap.add_argument("--photons", default="100000,1000000")
    ap.add_argument("--k", default="50,200")
    ap.add_argument("--out", default="docs/results")
    ap.add_argument("--direct", default="photon-map",
                    help="pf render --direct: photon-map (the standalone map, §2.5; the default) or mc/auto")
    args = ap.parse_args()
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for scene, (manifest, reference) in SCENES.items():
        for n in [int(x) for x in args.photons.split(",")]:
            for k in [int(x) for x in args.k.split(",")]:
                stem = f"{scene}-pm-n{n // 1000}k-k{k}"
                exr = out / f"{stem}.exr"
                t0 = time.monotonic()
                run([args.pf, "render", manifest, "--integrator", "photonmap", "--photons", str(n), "--k", str(k),
                     "--spp", str(args.spp), "--res", args.res, "--kd-split", "widest", "--direct", args.direct, "-q", "-o", str(exr), "--png", str(out / f"{stem}.png")])
                wall = time.monotonic() - t0
                diff = json.loads(run([args.pf, "diff", str(exr), reference, "--json", "--scene", manifest,
                                       "--error-image", str(out / f"{stem}-error.png")]).stdout)
                rows.append({"scene": scene, "photons": n, "k": k, "spp": args.spp, "rmse": diff["rmse"],
                             "rmse_clamped": diff["rmse_clamped"], "rmse_masked": diff["rmse_masked"],
                             "rmse_lowfreq": diff["rmse_lowfreq"],
                             "relative_mse": diff["relative_mse"], "mean": diff["mean"],
                             "reference_mean": diff["reference_mean"], "wall_seconds": wall})
                exr.unlink()  # keep the PNGs, not the EXRs
                print(f"{scene:15s} N={n:>8d} k={k:>4d}  RMSE [0,1] {diff['rmse_clamped']:.4f}  RMSE {diff['rmse']:.4f}"
                      f"  masked {diff['rmse_masked']:.4f}  lowfreq {diff['rmse_lowfreq']:.4f}  relMSE {diff['relative_mse']:.4f}"
                      f"  mean {diff['mean']:.4f} (ref {diff['reference_mean']:.4f})  {wall:6.1f} s", flush=True)
    (out / "photon_map_rmse.json").write_text(json.dumps(rows, indent=2) + "\n")
    lines = ["| scene | photons N | k | RMSE, display range [0,1] | RMSE | rmse_masked | rmse_lowfreq | relative MSE | mean / reference mean | wall time (s) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['photons']:,} | {r['k']} | {r['rmse_clamped']:.4f} | {r['rmse']:.4f} | "
                     f"{r['rmse_masked']:.4f} | {r['rmse_lowfreq']:.4f} | {r['relative_mse']:.4f} | "
                     f"{r['mean']:.4f} / {r['reference_mean']:.4f} | {r['wall_seconds']:.1f} |")
    (out / "photon_map_rmse.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
