#!/usr/bin/python3
"""RMSE against the path-traced reference and wall time, per chapter-4 estimator.

For every scene (Cornell box, CornellBox-Sphere, scene8, the SCENE10-like rooms, the
INVISIBLEDATE-like pair of rooms, the BATHROOM-like room and the CONFERENCE-like room) and every budget (photons, k, camera samples per pixel), renders
each method with `pf render` (one process, one map, seed 1, all cores), times the whole command
(median of --repeat runs: load, photon tracing, kd-tree build and rendering included) by its CPU
time (user + system of the child: the machines are shared, and wall time counts the waits for a
core; on an idle 2-core machine wall time is about CPU / 2) and by wall time, and compares with
`pf diff --json --scene` against scenes/<scene>/reference-*.exr:

    standalone          --direct photon-map            direct light from the map (2.5)
    standalone+occl     ... --occlusion-test           origin visibility per photon (4.1.1)
    mc                  --direct mc                    Monte Carlo direct light (4.2.1)
    photon-direct       --direct photon-direct         shadow rays split by direct photons (4.2.3)
    photon-direct-each  ... --non-contributing each    the other unbiased variant
    mc+local-pass       --direct mc --local-pass 8     final gathering (4.3)
    mc+local-pass+precomputed  ... --local-pass-lookup precomputed   gather hits read the irradiance
                        precomputed at every 4th photon (Christensen 1999)
    mc+local-pass+precomputed-nosite  ... --site-occlusion-test off   the sites' estimates without
                        the occlusion test (4.1.1): for scenes where nothing bleeds through walls
    mc+occl             --direct mc --occlusion-test
    mc+adaptive-k       --direct mc --adaptive-k-min k/5   (4.8)
    path                --integrator path, 4x the budget's spp (what the same machine does without maps)

plus, where the thesis makes a claim about it: mc+local-pass+occl on the two room scenes, and
PhotonDirect without its neighbour-set cache on scene10; and on scene10 (both budgets) and scene8
(the first budget) a shadow-ray sweep, Monte Carlo at 16/64/256 rays against PhotonDirect at
4/16/64 (the claim of 4.2.3: PhotonDirect reaches Monte Carlo's error in less time).

The methods of Wald 1999, §4.6-4.7 (importance, caustic splitting), on the scenes they are for:
    importance-driven maps (4.7), INVISIBLEDATE-like: mc+occl+importance (the budget's photons) and
        mc+occl+importance x20 (20x the photons, p_min 0.01: docs/results/importance.md's best row);
        scene10: photon-direct+importance and photon-direct+importance x5
    caustic splitting (4.6), CornellBox-Sphere and the BATHROOM-like scene: mc+split-brute S=8 and
        mc+split-metropolis S=8 (`--caustic-split 8`, the budget's photons)
    and the path tracer at about the CPU time of the importance rows: path x6 (INVISIBLEDATE) and
    path x2 (scene10), 6x and 2x the `path` row's spp

Error columns: the display RMSE (pf diff's rmse_display: both images clamped to the reference's
display white w = its median luminance / 0.18, RMSE / w; scale-free, so a dim scene is measured
like a bright one, and lights seen directly, 8-17 in value, count no more than white, instead of
their edge pixels' coverage noise dominating everything), pf diff's rmse_masked (unclamped, without
the emitters seen directly and a 2-pixel band around them: the noise where the eye looks) and
rmse_lowfreq (the masked image's RMSE after 4x4 binning: the photon map's blotches, thesis 3.3.2),
both / w, the raw RMSE / reference mean,
mean / reference mean (bias), and the reference's own noise (RMSE of its two halves / 2, over w;
no row can measure below it).

Writes to --out (default docs/results): estimators.json, estimators_table.md, per scene a plot of
error against time (estimators-<scene>.png) and a contact sheet of the last budget's images, all at
the reference's exposure, over their error images on one scale (estimators-<scene>-images.png).

    tools/install-deps.sh --bench        # matplotlib for the plots
    bench/estimators_rmse.py [--scenes cornell-box,scene10] [--budgets low,high] [--repeat 3]
    bench/estimators_rmse.py --replot    # table and plots again from estimators.json
    bench/estimators_rmse.py --merge --scenes bathroom --budgets low --methods mc,path --repeat 1
                                         # add (or replace) rows in estimators.json, keep the others
"""
import argparse
import json
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_common import timed  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = {  # name: (manifest, reference, resolution)
    "cornell-box": ("scenes/cornell-box/cornell-box.json", "scenes/cornell-box/reference-256.exr", "256x256"),
    "cornell-sphere": ("scenes/cornell-sphere/cornell-sphere.json", "scenes/cornell-sphere/reference-256.exr", "256x256"),
    "scene8": ("scenes/scene8/scene8.json", "scenes/scene8/reference-320.exr", "320x240"),
    "scene10": ("scenes/scene10/scene10.json", "scenes/scene10/reference-320.exr", "320x240"),
    "invisibledate": ("scenes/invisibledate/invisibledate.json", "scenes/invisibledate/reference-320.exr", "320x240"),
    "bathroom": ("scenes/bathroom/bathroom.json", "scenes/bathroom/reference-160.exr", "160x120"),
    "conference": ("scenes/conference/conference.json", "scenes/conference/reference-160.exr", "160x120"),
}
BUDGETS = {  # name: (photons, k, spp)
    "low": (100_000, 50, 4),
    "high": (400_000, 100, 16),
}
PATH_SPP_FACTOR = 4
SHADOW_RAY_SWEEP = {"scene10": ("low", "high"), "scene8": ("low",)}  # scene: budgets swept
MC_RAYS = (16, 64, 256)
PHOTON_DIRECT_RAYS = (4, 16, 64)
# The methods the contact sheets show (the last budget), in this order.
SHEET = ("standalone", "standalone+occl", "mc", "photon-direct", "mc+local-pass", "mc+occl", "mc+adaptive-k", "path",
         "mc+occl+importance x20", "photon-direct+importance x5", "mc+split-brute S=8", "mc+split-metropolis S=8")
CAUSTIC_SPLIT = 8  # a representative S (Wald 1999, 4.6: 4-20 suffice); docs/results/caustic_splitting.md


def methods(scene, k):
    """(name, pf render flags) of every method measured on `scene` at a budget with this k."""
    pm = ["--integrator", "photonmap"]
    rows = [
        ("standalone", pm + ["--direct", "photon-map"]),
        ("standalone+occl", pm + ["--direct", "photon-map", "--occlusion-test"]),
        ("mc", pm + ["--direct", "mc"]),
        ("photon-direct", pm + ["--direct", "photon-direct"]),
        ("photon-direct-each", pm + ["--direct", "photon-direct", "--non-contributing", "each"]),
        ("mc+local-pass", pm + ["--direct", "mc", "--local-pass", "8"]),
        ("mc+local-pass+precomputed",
         pm + ["--direct", "mc", "--local-pass", "8", "--local-pass-lookup", "precomputed"]),
        ("mc+local-pass+precomputed-nosite",
         pm + ["--direct", "mc", "--local-pass", "8", "--local-pass-lookup", "precomputed",
               "--site-occlusion-test", "off"]),
        ("mc+occl", pm + ["--direct", "mc", "--occlusion-test"]),
        ("mc+adaptive-k", pm + ["--direct", "mc", "--adaptive-k-min", str(max(1, k // 5))]),
    ]
    if scene in ("scene10", "invisibledate"):  # bleeding at the gather hits (4.1.1 with 4.3)
        rows.append(("mc+local-pass+occl", pm + ["--direct", "mc", "--local-pass", "8", "--occlusion-test"]))
    if scene == "scene10":  # the thesis's x20 of the neighbour-set cache (4.2.3)
        rows.append(("photon-direct (no cache)", pm + ["--direct", "photon-direct", "--photon-direct-cache", "0"]))
    # Importance-driven maps (4.7) keep fewer photons where the camera does not look, so they are
    # meant to be used with more emitted photons: the "xN" rows emit N times the budget's photons
    # (a --photons in the flags overrides the budget's; importance.md measured 5-20x).
    if scene == "invisibledate":
        occl = pm + ["--direct", "mc", "--occlusion-test", "--importance", "on"]
        rows.append(("mc+occl+importance", occl))
        rows.append(("mc+occl+importance x20", occl + ["--importance-min-probability", "0.01", "--photons", "x20"]))
        # The path tracer at about that row's CPU time (6x the `path` row's spp), measured rather
        # than extrapolated.
        rows.append(("path x6", ["--integrator", "path", "--spp", "x6"]))
    if scene == "scene10":
        pd = pm + ["--direct", "photon-direct", "--importance", "on"]
        rows.append(("photon-direct+importance", pd))
        rows.append(("photon-direct+importance x5", pd + ["--photons", "x5"]))
        rows.append(("path x2", ["--integrator", "path", "--spp", "x2"]))
    if scene in ("cornell-sphere", "bathroom"):  # caustic splitting (4.6) at the budget's photons
        for method in ("brute", "metropolis"):
            rows.append((f"mc+split-{method} S={CAUSTIC_SPLIT}",
                         pm + ["--direct", "mc", "--caustic-split", str(CAUSTIC_SPLIT), "--caustic-split-method", method]))
    return rows


def override(flags, option, base):
    """A row's own value of `option` (--photons, --spp) and its flags without it: "xN" in the
    flags is N times the budget's `base`, a number replaces it, no mention keeps `base`."""
    if option not in flags:
        return base, flags
    i = flags.index(option)
    value = flags[i + 1]
    return (base * int(value[1:]) if value.startswith("x") else int(value)), flags[:i] + flags[i + 2:]


def sweep(scene, budget):
    if budget not in SHADOW_RAY_SWEEP.get(scene, ()):
        return []
    def flags(direct, n):  # pf's default count spelled as the `mc` / `photon-direct` rows spell it
        return ["--integrator", "photonmap", "--direct", direct] + (["--shadow-rays", str(n)] if n != 16 else [])
    return ([(f"mc ({n} rays)", flags("mc", n)) for n in MC_RAYS] +
            [(f"photon-direct ({n} rays)", flags("photon-direct", n)) for n in PHOTON_DIRECT_RAYS])


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}\n{r.stderr}")
    return r


def reference_noise(reference):
    """The reference's pf:estimated_noise_rmse header attribute (written by pf merge): an EXR
    string attribute is name NUL "string" NUL, a 4-byte little-endian length, the bytes."""
    data = (ROOT / reference).read_bytes()[:65536]
    key = b"pf:estimated_noise_rmse\x00string\x00"
    i = data.find(key)
    if i < 0:
        return None
    n = int.from_bytes(data[i + len(key):i + len(key) + 4], "little")
    return float(data[i + len(key) + 4:i + len(key) + 4 + n].decode())


class Measurer:
    """Renders and compares; a flag set measured once is reused by every row naming it (the
    sweep's 16-ray Monte Carlo is the `mc` row)."""

    def __init__(self, args, work):
        self.args, self.work, self.done = args, work, {}

    def measure(self, scene, budget, method, flags):
        manifest, reference, res = SCENES[scene]
        photons, k, spp = BUDGETS[budget]
        if "path" in flags:
            spp *= PATH_SPP_FACTOR
        key = (scene, budget, tuple(flags))
        if key in self.done:
            return dict(self.done[key], method=method)
        exr = self.work / f"{scene}-{budget}-{len(self.done)}.exr"
        photons, render_flags = override(flags, "--photons", photons)
        spp, render_flags = override(render_flags, "--spp", spp)
        cmd = [self.args.pf, "render", manifest, "--spp", str(spp),
               "--res", res, "--seed", "1", "--threads", str(self.args.threads), "-q", "--no-png", "-o", str(exr)]
        if "path" not in flags:  # pf refuses photon-map options for the path tracer
            cmd += ["--photons", str(photons), "--k", str(k)]
        cpus, walls = [], []
        for _ in range(self.args.repeat):
            cpu, wall = timed(cmd + render_flags)
            cpus.append(cpu)
            walls.append(wall)
        diff = json.loads(run([self.args.pf, "diff", str(exr), reference, "--json", "--scene", manifest]).stdout)
        white = diff["display_white"]
        row = {"scene": scene, "budget": budget, "method": method, "flags": " ".join(flags),
               "photons": 0 if "path" in flags else photons, "k": 0 if "path" in flags else k, "spp": spp,
               "cpu_seconds": round(statistics.median(cpus), 3), "cpu_seconds_all": [round(c, 3) for c in cpus],
               "wall_seconds": round(statistics.median(walls), 3), "wall_seconds_all": [round(w, 3) for w in walls],
               "rmse": diff["rmse"], "rmse_clamped": diff["rmse_clamped"], "rmse_display": diff["rmse_display"],
               "rmse_masked": diff["rmse_masked"], "rmse_lowfreq": diff["rmse_lowfreq"],
               "masked_white": diff["rmse_masked"] / white, "lowfreq_white": diff["rmse_lowfreq"] / white,
               "nrmse": diff["rmse"] / diff["reference_mean"], "mean_ratio": diff["mean"] / diff["reference_mean"],
               "exr": str(exr)}
        print(f"{scene:14s} {budget:5s} {method:26s} {row['cpu_seconds']:7.2f} s CPU  RMSE/white "
              f"{row['rmse_display']:.4f}  masked {row['masked_white']:.4f}  lowfreq {row['lowfreq_white']:.4f}  "
              f"mean/ref {row['mean_ratio']:.4f}", flush=True)
        self.done[key] = row
        return dict(row)


def contact_sheet(pf, scene, rows, out, work, white):
    """The last budget's images at the reference's exposure (pf preview --exposure-of), each over
    its absolute error (pf diff --error-image) on one colour scale per scene."""
    import matplotlib.pyplot as plt
    import matplotlib.image as mpimg
    reference = SCENES[scene][1]
    shown = [r for name in SHEET for r in rows if r["method"] == name]
    if not shown:
        return None
    error_scale = 0.25 * white  # yellow = an error of a quarter of the display white
    cells = [("reference", reference, None, "")] + [
        (r["method"], r["exr"], True, f"{r['cpu_seconds']:.1f} s CPU, RMSE/white {r['rmse_display']:.4f}, "
                                      f"mean {r['mean_ratio']:.3f}") for r in shown]
    cols = 3
    rows_of_cells = (len(cells) + cols - 1) // cols
    fig, axes = plt.subplots(2 * rows_of_cells, cols, figsize=(3.4 * cols, 2.75 * 2 * rows_of_cells),
                             gridspec_kw={"hspace": 0.25, "wspace": 0.04})
    for ax in axes.flat:
        ax.axis("off")
    for i, (name, exr, has_error, caption) in enumerate(cells):
        top, bottom = axes[2 * (i // cols)][i % cols], axes[2 * (i // cols) + 1][i % cols]
        img, err = work / f"{scene}-sheet-{i}.png", work / f"{scene}-sheet-{i}-error.png"
        run([pf, "preview", exr, "-o", img, "--exposure-of", reference])
        top.imshow(mpimg.imread(img))
        top.set_title(f"{name}\n{caption}" if caption else name, fontsize=8)
        if has_error:
            run([pf, "diff", exr, reference, "--error-image", err, "--error-scale", f"{error_scale:.6g}"])
            bottom.imshow(mpimg.imread(err))
        else:
            bottom.text(0.5, 0.5, f"below each image: |image - reference|,\nviridis ramp from 0 (purple)\n"
                                  f"to {error_scale:.3g} (yellow, 1/4 of white)", ha="center", va="center",
                        fontsize=8, transform=bottom.transAxes)
    first = shown[0]
    fig.suptitle(f"{scene}, budget {first['budget']}: {first['photons'] // 1000}k photons, k {first['k']}, "
                 f"{first['spp']} spp (path: {first['spp'] * PATH_SPP_FACTOR} spp); one exposure for all", fontsize=9)
    fig.subplots_adjust(top=1 - 0.9 / fig.get_figheight(), bottom=0.01, left=0.01, right=0.99)
    path = out / f"estimators-{scene}-images.png"
    fig.savefig(path, dpi=75)
    plt.close(fig)
    return path.name


def plot(rows, scenes, out):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("no matplotlib: plots skipped (tools/install-deps.sh --bench)", file=sys.stderr)
        return []
    markers = "osD^v<>pPX*h"
    written = []
    for scene in scenes:
        mine = [r for r in rows if r["scene"] == scene]
        swept = [r for r in mine if "rays)" in r["method"]]
        fig, axes = plt.subplots(1, 2 if swept else 1, figsize=(12 if swept else 7, 4.5), squeeze=False)
        ax = axes[0][0]
        names = list(dict.fromkeys(r["method"] for r in mine if "rays)" not in r["method"]))
        cmap = plt.get_cmap("tab20")
        for i, method in enumerate(names):
            pts = sorted((r["cpu_seconds"], r["rmse_display"]) for r in mine if r["method"] == method)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=markers[i % len(markers)], color=cmap(i % 20),
                    label=method, linestyle=":" if method == "path" else "-")
        if mine[0].get("reference_noise_display"):
            ax.axhline(mine[0]["reference_noise_display"], color="grey", linewidth=0.8, linestyle=":",
                       label="reference noise (unclamped)")
        ax.set_title(f"{scene}: every method, budgets {', '.join(dict.fromkeys(r['budget'] for r in mine))}",
                     fontsize=10)
        ax.legend(fontsize=7, ncol=2)
        if swept:
            ax2 = axes[0][1]
            for family, colour in (("mc", "tab:blue"), ("photon-direct", "tab:red")):
                for budget, style in (("low", "-"), ("high", "--")):
                    pts = sorted((r["cpu_seconds"], r["rmse_display"], r["method"].split("(")[1].split()[0])
                                 for r in swept if r["method"].startswith(family + " (") and r["budget"] == budget)
                    if not pts:
                        continue
                    ax2.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=colour, linestyle=style,
                             label=f"{family}, {budget}")
                    for t, e, n in pts:
                        ax2.annotate(n, (t, e), textcoords="offset points", xytext=(4, 4), fontsize=7)
            ax2.set_title(f"{scene}: shadow rays per shading point (numbers at the points)", fontsize=10)
            ax2.legend(fontsize=7)
        for a in axes[0]:
            a.set_xscale("log")
            a.set_yscale("log")
            a.set_xlabel("CPU time of pf render (user + system, both threads), median (s)")
            a.set_ylabel("RMSE / display white (clamped at white)")
            a.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        path = out / f"estimators-{scene}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path.name)
    return written


def write_reports(rows, scenes, out, sheets=()):
    plots = plot(rows, scenes, out)
    lines = []
    for scene in scenes:
        mine = [r for r in rows if r["scene"] == scene]
        lines += [f"### {scene}", "",
                  "| budget (photons / k / spp) | method | CPU s (median) | wall s | RMSE / white | masked / white "
                  "| low-freq / white | RMSE / mean | mean / ref |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for r in mine:
            budget = f"{r['photons'] // 1000}k / {r['k']} / {r['spp']}" if r["photons"] else f"{r['spp']} spp"
            lines.append(f"| {r['budget']} ({budget}) | {r['method']} | {r['cpu_seconds']:.2f} | "
                         f"{r['wall_seconds']:.2f} | {r['rmse_display']:.4f} | {r['masked_white']:.4f} | "
                         f"{r['lowfreq_white']:.4f} | {r['nrmse']:.4f} | {r['mean_ratio']:.3f} |")
        if mine[0].get("reference_noise_nrmse"):
            lines += ["", f"The reference's own noise: RMSE {mine[0]['reference_noise_rmse']:.5f} = "
                          f"{mine[0]['reference_noise_display']:.4f} of white = {mine[0]['reference_noise_nrmse']:.4f} "
                          f"of its mean (unclamped); no row can measure below it."]
        lines += [""]
        if f"estimators-{scene}.png" in plots:
            lines += [f"![{scene}: error against time](estimators-{scene}.png)", ""]
        if f"estimators-{scene}-images.png" in sheets or (out / f"estimators-{scene}-images.png").exists():
            lines += [f"![{scene}: images and errors](estimators-{scene}-images.png)", ""]
    (out / "estimators_table.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'estimators.json'}, {out / 'estimators_table.md'} and {len(plots)} plots")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pf", default="build/client/pf")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--budgets", default=",".join(BUDGETS))
    ap.add_argument("--threads", type=int, default=0, help="render threads (0 = all cores)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per row; the median time counts")
    ap.add_argument("--out", default="docs/results")
    ap.add_argument("--methods", default="", help="only these rows (comma-separated method names; default all)")
    ap.add_argument("--map", default="", help="photon map structure for every photonmap row (pf render --map)")
    ap.add_argument("--replot", action="store_true", help="only rewrite the table and plots from <out>/estimators.json")
    ap.add_argument("--merge", action="store_true",
                    help="add this run's rows to <out>/estimators.json (replacing rows of the same scene, budget "
                         "and method) instead of overwriting it; a scene's contact sheet is redrawn only when this run "
                         "measures all of its rows")
    args = ap.parse_args()
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    if args.replot:
        rows = json.loads((out / "estimators.json").read_text())
        write_reports(rows, list(dict.fromkeys(r["scene"] for r in rows)), out)
        return
    scenes = [s for s in args.scenes.split(",") if s]
    budgets = [b for b in args.budgets.split(",") if b]
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"unknown scene {s} (have {', '.join(SCENES)})")
    for b in budgets:
        if b not in BUDGETS:
            sys.exit(f"unknown budget {b} (have {', '.join(BUDGETS)})")
    wanted = {m for m in args.methods.split(",") if m}
    old = json.loads((out / "estimators.json").read_text()) if args.merge and (out / "estimators.json").exists() else []
    old_scenes = list(dict.fromkeys(r["scene"] for r in old))
    work = pathlib.Path(tempfile.mkdtemp(prefix="pf-estimators-"))
    try:
        measurer = Measurer(args, work)
        rows, sheets = [], []
        for scene in scenes:
            noise = reference_noise(SCENES[scene][1])
            ref = json.loads(run([args.pf, "diff", SCENES[scene][1], SCENES[scene][1], "--json"]).stdout)
            ref_mean, white = ref["mean"], ref["display_white"]
            mine = []
            for budget in budgets:
                for method, flags in (methods(scene, BUDGETS[budget][1]) + [("path", ["--integrator", "path"])] +
                                      sweep(scene, budget)):
                    if wanted and method not in wanted:
                        continue
                    if args.map and "photonmap" in flags:
                        flags = flags + ["--map", args.map]
                    mine.append(measurer.measure(scene, budget, method, flags))
            for r in mine:
                r["reference_noise_rmse"] = noise
                r["reference_noise_nrmse"] = noise / ref_mean if noise else None
                r["reference_noise_display"] = noise / white if noise else None
                r["display_white"] = white
            # A merged run that measures only a slice of a scene's rows keeps the scene's sheet.
            measured = {(r["budget"], r["method"]) for r in mine}
            if not any(r["scene"] == scene and (r["budget"], r["method"]) not in measured for r in old):
                try:
                    sheets.append(contact_sheet(args.pf, scene, [r for r in mine if r["budget"] == budgets[-1]],
                                                out, work, white))
                except ImportError:
                    print("no matplotlib: contact sheets skipped (tools/install-deps.sh --bench)", file=sys.stderr)
            rows += mine
        for r in rows:
            del r["exr"]
        if args.merge:
            # A re-measured row takes the place of the row it replaces; new rows go last.
            new = {(r["scene"], r["budget"], r["method"]): r for r in rows}
            replaced = [new.get((r["scene"], r["budget"], r["method"]), r) for r in old]
            in_old = {(r["scene"], r["budget"], r["method"]) for r in old}
            rows = replaced + [r for r in rows if (r["scene"], r["budget"], r["method"]) not in in_old]
            rows.sort(key=lambda r: (list(dict.fromkeys([*old_scenes, *scenes])).index(r["scene"]),
                                     list(BUDGETS).index(r["budget"])))  # stable: methods keep their order
            scenes = list(dict.fromkeys(r["scene"] for r in rows))
        (out / "estimators.json").write_text(json.dumps(rows, indent=2) + "\n")
        write_reports(rows, scenes, out, sheets)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
