#!/usr/bin/python3
"""Overmodulation (Wald 1999, 3.3.5) on the CONFERENCE-like scene: the photon map against the path
tracer next to the exit signs.

The exit signs are tiny (0.28 x 0.08 m) and bright (luminance 100, ten times the ceiling panels);
the underside of each sign's hood, 5 cm below the ceiling, catches a dense cluster of their
photons. The radiance estimate divides the power of the k nearest photons by pi r^2; on the
ceiling next to the hood the cluster is inside the disk (its photons arrive from below, the
ceiling's front side, so the direction test of 4.1 keeps them), r is small, and the ceiling
turns into a bright halo that the path tracer does not see.
The thesis: it "can only be removed by a local pass" (5, CONFERENCE), which reads the map one
diffuse bounce later.

Every row is one `pf render` of scenes/conference at the reference's 160 x 120 (seed 1, k 50,
4 spp), compared by `pf diff --json --scene` with scenes/conference/reference-160.exr over the
whole image and over three regions per sign (pixels of the 160 x 120 image): `halo` = the ceiling
in front of each sign's hood and `below` = the wall under it (no emitter pixel in either, so their
mean/ref > 1 = overmodulated), and `around` = a box around each sign and its hood (rmse_masked
leaves the sign's own pixels out). Time: CPU (user + sys) of the whole process. Writes
<out>/conference.json and, with matplotlib, <out>/conference-signs.png (crops around the left sign,
one exposure, each over its error).

    bench/conference_overmodulation.py [--photons 100000] [--out docs/results]
"""
import argparse
import json
import pathlib
import sys
import tempfile

from bench_common import ROOT, run, timed

MANIFEST = "scenes/conference/conference.json"
REFERENCE = "scenes/conference/reference-160.exr"
RES = "160x120"
# Pixel boxes x0,y0,x1,y1 of the 160 x 120 image (the camera of conference.json): the signs'
# emitters are at about (47, 39) and (113, 39), their hoods span x 42-50 / 110-118, y 36.5-40.5.
# `halo`: the ceiling in front of each sign's hood (up to 1 m out, 0.9 m wide), where the hood's
# cluster is read; `below`: the wall under each sign (no emitter pixel in either, so their means
# are the estimate's brightness there); `around`: a box around each sign and its hood
# (rmse_masked leaves the sign's own pixels out).
REGIONS = {
    "halo": ("36,29,58,36", "102,29,124,36"),
    "below": ("40,42,54,48", "106,42,120,48"),
    "around": ("32,26,62,50", "98,26,128,50"),
}
CROP = (26, 20, 68, 54)  # the left sign, for the figure


def rows(photons, path_spp):
    pm = ["--integrator", "photonmap", "--photons", str(photons), "--k", "50", "--spp", "4"]
    return [
        # Without the feasibility test (4.1) photons count whatever side they came from: the
        # surfaces around the sign read the cluster on its hood whichever way they face.
        ("standalone, no direction test", pm + ["--direct", "photon-map", "--direction-test", "none"]),
        ("standalone", pm + ["--direct", "photon-map"]),
        ("mc", pm + ["--direct", "mc"]),
        ("mc+local-pass", pm + ["--direct", "mc", "--local-pass", "8"]),
        ("mc+local-pass+precomputed", pm + ["--direct", "mc", "--local-pass", "8", "--local-pass-lookup",
                                            "precomputed"]),
        (f"path {path_spp} spp", ["--integrator", "path", "--spp", str(path_spp)]),
    ]


def diff(pf, image, region=None):
    cmd = [pf, "diff", image, REFERENCE, "--json", "--scene", MANIFEST]
    if region:
        cmd += ["--region", region]
    d = json.loads(run(cmd).stdout)
    return {k: d[k] for k in ("rmse", "rmse_display", "rmse_masked", "rmse_lowfreq", "mean", "reference_mean",
                              "display_white")}


def sheet(pf, table, out, work):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    x0, y0, x1, y1 = CROP
    cells = [("reference", REFERENCE, None)] + [(r["method"], r["exr"], r) for r in table]
    fig, axes = plt.subplots(2, len(cells), figsize=(2.2 * len(cells), 4.4), gridspec_kw={"wspace": 0.04,
                                                                                         "hspace": 0.3})
    white = table[0]["whole"]["display_white"]
    for i, (name, exr, r) in enumerate(cells):
        img, err = work / f"sheet-{i}.png", work / f"sheet-{i}-error.png"
        run([pf, "preview", exr, "-o", img, "--exposure-of", REFERENCE])
        axes[0][i].imshow(mpimg.imread(img)[y0:y1, x0:x1], interpolation="nearest")
        caption = name if r is None else (f"{name}\n{r['cpu_s']:.1f} s CPU, halo "
                                          f"{r['halo'][0]['mean'] / r['halo'][0]['reference_mean']:.2f}x")
        axes[0][i].set_title(caption, fontsize=7)
        if r is not None:
            run([pf, "diff", exr, REFERENCE, "--error-image", err, "--error-scale", f"{0.5 * white:.6g}"])
            axes[1][i].imshow(mpimg.imread(err)[y0:y1, x0:x1], interpolation="nearest")
        else:
            axes[1][i].text(0.5, 0.5, f"|image - reference|\n0 (purple) to\n{0.5 * white:.3g} (yellow,\n"
                                      f"1/2 of white)", ha="center", va="center", fontsize=7,
                            transform=axes[1][i].transAxes)
    for ax in axes.flat:
        ax.axis("off")
    fig.suptitle(f"CONFERENCE-like, the left exit sign (pixels {x0}-{x1} x {y0}-{y1} of 160 x 120), one exposure; "
                 "halo = mean of the ceiling in front of the hood / reference's", fontsize=8)
    path = out / "conference-signs.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path.name


def main():
    global REFERENCE
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--photons", type=int, default=100000)
    ap.add_argument("--path-spp", type=int, default=64, help="the path tracer's row")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", default="docs/results")
    ap.add_argument("--reference", default="", help="another reference EXR (default: " + REFERENCE + ")")
    args = ap.parse_args()
    REFERENCE = args.reference or REFERENCE
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    table = []
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        for i, (name, flags) in enumerate(rows(args.photons, args.path_spp)):
            exr = work / f"row-{i}.exr"
            cpu, wall = timed([args.pf, "render", MANIFEST, "--res", RES, "--seed", "1", "--threads",
                               str(args.threads), "-q", "--no-png", "-o", exr, *flags])
            r = {"method": name, "flags": " ".join(flags), "cpu_s": round(cpu, 3), "wall_s": round(wall, 3),
                 "whole": diff(args.pf, exr), "exr": str(exr)}
            for key, boxes in REGIONS.items():
                r[key] = [dict(diff(args.pf, exr, box), region=box) for box in boxes]
            table.append(r)
            halo = [h["mean"] / h["reference_mean"] for h in r["halo"]]
            print(f"{name:28s} {cpu:6.2f} s CPU  whole RMSE/white {r['whole']['rmse_display']:.4f}  "
                  f"mean/ref {r['whole']['mean'] / r['whole']['reference_mean']:.3f}  halo mean/ref "
                  f"{halo[0]:.3f} {halo[1]:.3f}  around masked RMSE {r['around'][0]['rmse_masked']:.4f} "
                  f"{r['around'][1]['rmse_masked']:.4f}", flush=True)
        figure = None
        try:
            figure = sheet(args.pf, table, out, work)
        except ImportError:
            print("no matplotlib: figure skipped (tools/install-deps.sh --bench)", file=sys.stderr)
    for r in table:
        del r["exr"]
    (out / "conference.json").write_text(json.dumps({"manifest": MANIFEST, "reference": REFERENCE, "res": RES,
                                                     "regions": REGIONS, "figure": figure, "rows": table},
                                                    indent=1) + "\n")
    print(f"wrote {out / 'conference.json'}" + (f" and {out / figure}" if figure else ""))


if __name__ == "__main__":
    main()
