#!/usr/bin/python3
"""Caustic splitting (Wald 1999, 4.6): the caustic's error at the CPU time spent, without
splitting (more photons instead), by brute force and by Metropolis at S = 4..20.

Every row is one `pf render --integrator photonmap` at the reference's resolution, compared with
the scene's converged path-traced reference by `pf diff --json --scene <manifest>` twice: over the
whole image (rmse, rmse_masked: without the emitters seen directly, rmse_lowfreq: 4x4 block means)
and over the scene's caustic region only (`pf diff --region`; CornellBox-Sphere: the floor under
the glass sphere; BATHROOM-like: the lower half of the image, floor, tub and vanity, whose direct
light is all caustic; the bulbs, seen through glass, are not masked as emitters and would dominate). Time: the
CPU time (user + sys) of the whole `pf render` process (getrusage; map tracing included; the
machine is shared, so wall time is not used). Rows without splitting use N, 2N, 4N, 8N photons, so
a split row is compared with the no-splitting row of the same CPU time by interpolation
("equal-time ratio": the no-splitting curve's region RMSE at the split row's CPU time, log-log
interpolated, over the split row's). One map seed per row; --repeat R renders R seeds and
reports medians (default 3).

Writes <out>/caustic_splitting.json, <out>/caustic_splitting.md (table) and, with matplotlib,
<out>/caustic-splitting-<scene>-images.png: a contact sheet (no splitting, brute and Metropolis at
the largest S, Metropolis with N/5 photons — the thesis's artifact case — and no splitting at 8N,
each over its error image) showing Metropolis's artifacts.

    bench/caustic_splitting.py [--scenes cornell-sphere,bathroom] [--splits 4,8,16,20] [--repeat 1]
"""
import argparse
import json
import math
import pathlib
import statistics
import sys
import tempfile

from bench_common import ROOT, run, timed

# name: manifest, reference, caustic region x0,y0,x1,y1 (pixels of the reference), base photons,
# render flags shared by every row.
SCENES = {
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr",
                       "150,195,225,226", 50000, ["--res", "256x256", "--spp", "4", "--k", "50", "--direct", "mc"]),
    "bathroom": ("scenes/bathroom/bathroom.json", "scenes/bathroom/reference-160.exr", "0,55,160,120", 50000,
                 ["--res", "160x120", "--spp", "4", "--k", "50", "--direct", "mc"]),
}


TAG = ""


def diff(pf, image, reference, manifest, region=None):
    cmd = [pf, "diff", image, reference, "--scene", manifest, "--json"]
    if region:
        cmd += ["--region", region]
    d = json.loads(run(cmd).stdout)
    return {k: d.get(k) for k in ("rmse", "rmse_masked", "rmse_lowfreq", "mean", "reference_mean")}


def rows(base, splits):
    """(name, photons as a multiple of the base, S, method); photons may be a fraction."""
    none = [(f"none {m}N", m, 1, "brute") for m in (1, 2, 4, 8, 16)]
    brute = [(f"brute S={s}", 1, s, "brute") for s in splits]
    metropolis = [(f"metropolis S={s}", 1, s, "metropolis") for s in splits]
    # The thesis's artifact case (Figure 4.11): few photons, a high ratio. Not an equal-time row.
    artifact = [(f"metropolis S={max(splits)} at N/5", 0.2, max(splits), "metropolis")]
    return none + brute + metropolis + artifact


def render_row(args, scene, name, mult, split, method, tmp):
    manifest, reference, region, base, flags = SCENES[scene]
    photons = int(round(base * mult))
    cmd_flags = ["--integrator", "photonmap", "--photons", str(photons), *flags, "--threads", str(args.threads)]
    if split > 1:
        cmd_flags += ["--caustic-split", str(split), "--caustic-split-method", method]
    samples = []
    for seed in range(1, args.repeat + 1):
        safe = "".join(c if c.isalnum() else "_" for c in name)
        image = pathlib.Path(tmp) / f"{scene}-{safe}-{seed}.exr"
        cpu, wall = timed([args.pf, "render", manifest, *cmd_flags, "--seed", str(seed), "-o", image, "--no-png",
                           "-q"])
        whole = diff(args.pf, image, reference, manifest)
        part = diff(args.pf, image, reference, manifest, region)
        samples.append({"cpu_s": cpu, "wall_s": wall, "whole": whole, "region": part, "exr": str(image)})
    med = lambda f: statistics.median(f(s) for s in samples)
    row = {"method": name, "photons": photons, "split": split, "split_method": method,
           "flags": " ".join(cmd_flags), "cpu_s": med(lambda s: s["cpu_s"]), "wall_s": med(lambda s: s["wall_s"]),
           "exr": samples[0]["exr"]}
    for part in ("whole", "region"):
        for k in ("rmse", "rmse_masked", "rmse_lowfreq"):
            row[f"{part}_{k}"] = med(lambda s: s[part][k])
        row[f"{part}_mean_ratio"] = med(lambda s: s[part]["mean"] / s[part]["reference_mean"])
    print(f"{scene}: {name}: {row['cpu_s']:.1f} s CPU, region rmse {row['region_rmse']:.4g} "
          f"(mean/ref {row['region_mean_ratio']:.3f}), whole rmse_masked {row['whole_rmse_masked']:.4g}",
          file=sys.stderr, flush=True)
    return row


def equal_time_ratio(none_rows, row, key):
    """The no-splitting curve's `key` at row's CPU time (log-log interpolation, clamped to the
    curve's ends, extrapolated along the last segment) over row's `key`: > 1 = splitting wins."""
    pts = sorted((r["cpu_s"], r[key]) for r in none_rows)
    t = row["cpu_s"]
    if t <= pts[0][0]:
        (t0, e0), (t1, e1) = pts[0], pts[1]
    elif t >= pts[-1][0]:
        (t0, e0), (t1, e1) = pts[-2], pts[-1]
    else:
        i = next(i for i in range(1, len(pts)) if pts[i][0] >= t)
        (t0, e0), (t1, e1) = pts[i - 1], pts[i]
    slope = (math.log(e1) - math.log(e0)) / (math.log(t1) - math.log(t0)) if t1 != t0 else 0.0
    e = math.exp(math.log(e0) + slope * (math.log(t) - math.log(t0)))
    return e / row[key]


def contact_sheet(pf, scene, table, out, work):
    """Whole images (no splitting, brute and Metropolis at the largest S, Metropolis with few
    photons, no splitting at 8N) at the reference's exposure, each over its error image on one
    scale; the caustic region outlined."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.patches as patches
    import matplotlib.pyplot as plt
    manifest, reference, region, _, _ = SCENES[scene]
    x0, y0, x1, y1 = map(int, region.split(","))
    s_max = max(r["split"] for r in table)
    names = ["none 1N", f"brute S={s_max}", f"metropolis S={s_max}", f"metropolis S={s_max} at N/5", "none 8N"]
    shown = [r for n in names for r in table if r["method"] == n]
    scale = 2.0 * diff(pf, reference, reference, manifest, region)["mean"]
    cells = [("reference", reference, "")] + [
        (r["method"], r["exr"], f"{r['photons'] // 1000}k photons, {r['cpu_s']:.1f} s CPU\n"
                                f"region RMSE {r['region_rmse']:.3g}, mean/ref {r['region_mean_ratio']:.3f}")
        for r in shown]
    cols = 3
    grid = (len(cells) + cols - 1) // cols
    fig, axes = plt.subplots(2 * grid, cols, figsize=(3.1 * cols, 2 * grid * 3.25),
                             gridspec_kw={"hspace": 0.22, "wspace": 0.03})
    for ax in axes.flat:
        ax.axis("off")
    for i, (name, exr, caption) in enumerate(cells):
        top, bottom = axes[2 * (i // cols)][i % cols], axes[2 * (i // cols) + 1][i % cols]
        img, err = work / f"{scene}-sheet-{i}.png", work / f"{scene}-sheet-{i}-error.png"
        run([pf, "preview", exr, "-o", img, "--exposure-of", reference])
        top.imshow(mpimg.imread(img), interpolation="nearest")
        top.add_patch(patches.Rectangle((x0 - 0.5, y0 - 0.5), x1 - x0, y1 - y0, fill=False, lw=0.6, ec="yellow"))
        top.set_title(f"{name}\n{caption}" if caption else name, fontsize=7)
        if caption:
            run([pf, "diff", exr, reference, "--error-image", err, "--error-scale", f"{scale:.6g}"])
            bottom.imshow(mpimg.imread(err), interpolation="nearest")
        else:
            bottom.text(0.5, 0.5, f"below each image: |image - reference|\n0 (purple) to {scale:.3g} (yellow:\n"
                                  f"2x the caustic region's mean)", ha="center", va="center", fontsize=7,
                        transform=bottom.transAxes)
    fig.suptitle(f"{scene}: caustic region {region} outlined; one exposure for all.\nMetropolis: the start "
                 f"points of rare chains act as secondary lights (blotches)", fontsize=8)
    path = out / f"caustic-splitting-{scene}{TAG}-images.png"
    fig.subplots_adjust(top=1 - 1.1 / fig.get_figheight(), bottom=0.01, left=0.01, right=0.99)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path.name


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--splits", default="4,8,16,20")
    ap.add_argument("--photons", type=int, default=0, help="base N (default: per scene, 50000)")
    ap.add_argument("--tag", default="", help="suffix of the output names (e.g. --tag=-200k)")
    ap.add_argument("--flags", default="", help="more pf render flags for every row (e.g. '--local-pass 16')")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default="docs/results")
    args = ap.parse_args()
    global TAG
    TAG = args.tag
    splits = [int(s) for s in args.splits.split(",")]
    out = ROOT / args.out
    result, sheets = {}, {}
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for scene in [s for s in args.scenes.split(",") if s]:
            if args.photons:
                SCENES[scene] = SCENES[scene][:3] + (args.photons,) + SCENES[scene][4:]
            if args.flags:
                SCENES[scene] = SCENES[scene][:4] + (SCENES[scene][4] + args.flags.split(),)
            table = [render_row(args, scene, *r, tmp) for r in rows(SCENES[scene][3], splits)]
            none = [r for r in table if r["split"] == 1]
            for r in table:  # (the N/5 artifact row too, for completeness)
                for key in ("region_rmse", "region_rmse_lowfreq", "whole_rmse_masked"):
                    r[f"equal_time_{key}"] = equal_time_ratio(none, r, key)
            result[scene] = {"manifest": SCENES[scene][0], "reference": SCENES[scene][1],
                             "region": SCENES[scene][2], "rows": table}
            try:
                sheets[scene] = contact_sheet(args.pf, scene, table, out, pathlib.Path(tmp))
            except ImportError:
                print("no matplotlib: contact sheet skipped (tools/install-deps.sh --bench)", file=sys.stderr)
    for r in (row for s in result.values() for row in s["rows"]):
        r.pop("exr", None)
    (out / f"caustic_splitting{args.tag}.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = []
    for scene, r in result.items():
        lines += [f"### {scene} (caustic region {r['region']})", "",
                  "| method | photons | CPU s | region rmse | region lowfreq | region mean/ref | whole rmse | "
                  "whole rmse_masked | whole rmse_lowfreq | equal-time gain (region rmse) | (region lowfreq) |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for t in r["rows"]:
            lines.append(f"| {t['method']} | {t['photons']} | {t['cpu_s']:.1f} | {t['region_rmse']:.4g} | "
                         f"{t['region_rmse_lowfreq']:.4g} | {t['region_mean_ratio']:.3f} | {t['whole_rmse']:.4g} | "
                         f"{t['whole_rmse_masked']:.4g} | {t['whole_rmse_lowfreq']:.4g} | "
                         f"{t['equal_time_region_rmse']:.2f} | {t['equal_time_region_rmse_lowfreq']:.2f} |")
        if scene in sheets:
            lines += ["", f"![{scene}: caustic region]({sheets[scene]})"]
        lines.append("")
    (out / f"caustic_splitting{args.tag}_table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
