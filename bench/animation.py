#!/usr/bin/python3
"""animation.py — an animation as one job against the same frames as separate jobs.

    bench/animation.py [--build build] [--frames 48] [--repeat 3] [--json-out results.json]

The shipped cornell-box's camera path (scenes/cornell-box/cornell-box.json, "camera_path": a 48-frame
fly-through) on a coordinator with two 1-thread workers (fresh data and cache folders each run):
  animation  one `pf submit --frames 1-N`, then `pf watch` until it is done;
  jobs       N `pf submit`s, one per frame with that frame's camera (read from the animation's frame
             files: camera.eye, camera.look_at), then `pf watch` of each until all are done.
Same settings in both: photon map, multiple maps (2 maps of 100000 photons, 64-pixel tiles), 128x128,
4 spp, k 50, seed 3. Wall time from the first submit to the last job's end; CPU time (user + system)
of every process of the run (coordinator, workers and every pf command, start to stop); maps built on
the coordinator and map pieces uploaded by the workers (counted in their logs); every frame of the
animation must equal its single-frame job bit for bit (checked, exit 1 otherwise). --repeat runs of
the pair, interleaved; the MEDIAN counts, and the ratio jobs / animation per run.
Prints a table and the JSON; --json-out also writes the JSON to a file.
"""
import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from bench_common import exr_string, start_coordinator, stop

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(REPO, "scenes", "cornell-box", "cornell-box.json")
FLAGS = ["--integrator", "photonmap", "--plan", "multiple-maps", "--maps", "2", "--tile", "64", "--res",
         "128x128", "--spp", "4", "--photons", "100000", "--k", "50", "--seed", "3", "--log-level", "warn"]


def pf(binary, *args):
    r = subprocess.run([binary] + list(args), capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): pf {' '.join(args)}\n{r.stderr[-3000:]}")
    return r.stdout.strip()


def farm_run(build, work, submit_all):
    """Starts a coordinator and two workers in `work`, runs submit_all(address) -> job ids, watches every
    job to its end and stops the farm. Returns (wall seconds, CPU seconds, maps built, pieces, ids)."""
    os.makedirs(work)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    coordinator, address = start_coordinator(os.path.join(build, "server", "pf-coordinator"), work, [])
    workers = []
    for w in ("w1", "w2"):
        workers.append(subprocess.Popen(
            [os.path.join(build, "worker", "pf-worker"), "--coordinator", address, "--threads", "1", "--worker-id",
             w, "--cache-dir", os.path.join(work, "cache-" + w)],
            stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, w + ".log"), "w")))
    client = os.path.join(build, "client", "pf")
    try:
        t0 = time.monotonic()
        ids = submit_all(address)
        for job in ids:
            pf(client, "watch", job, "--coordinator", address, "-q")
        wall = time.monotonic() - t0
    finally:
        for p in workers + [coordinator]:
            stop(p)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    log = open(os.path.join(work, "coordinator.log")).read()
    maps = len(re.findall(r"built once from", log))
    pieces = sum(len(re.findall(r"uploaded-piece .* accepted=true", open(os.path.join(work, w + ".log")).read()))
                 for w in ("w1", "w2"))
    return wall, cpu, maps, pieces, ids


def fetch(build, work, fetch_all):
    """Runs fetch_all(address) against a coordinator of its own on work's data (the run's is stopped)."""
    coordinator, address = start_coordinator(os.path.join(build, "server", "pf-coordinator"), work, [])
    try:
        return fetch_all(address)
    finally:
        stop(coordinator)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(REPO, "build"))
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json-out")
    a = ap.parse_args()
    client = os.path.join(a.build, "client", "pf")
    tmp = tempfile.mkdtemp(prefix="pf-animation-bench-")
    runs = {"animation": [], "jobs": []}
    try:
        for rep in range(a.repeat):
            base = os.path.join(tmp, f"run{rep}")
            frames = os.path.join(base, "anim.%04d.exr")

            def submit_animation(address):
                return [pf(client, "submit", SCENE, "--frames", f"1-{a.frames}", "--coordinator", address, *FLAGS)]

            wall, cpu, maps, pieces, ids = farm_run(a.build, os.path.join(base, "animation"), submit_animation)
            runs["animation"].append({"wall": wall, "cpu": cpu, "maps_built": maps, "pieces": pieces})
            print(f"  animation {wall:7.2f} s wall {cpu:7.2f} s CPU  maps {maps} pieces {pieces}", file=sys.stderr)
            fetch(a.build, os.path.join(base, "animation"),
                  lambda address: pf(client, "get", ids[0], "--coordinator", address, "-o", frames))
            cameras = [(exr_string(frames % f, "pf:camera.eye"), exr_string(frames % f, "pf:camera.look_at"))
                       for f in range(1, a.frames + 1)]

            def submit_jobs(address):
                return [pf(client, "submit", SCENE, "--coordinator", address, f"--eye={eye}", f"--look-at={at}",
                           *FLAGS) for eye, at in cameras]

            wall, cpu, maps, pieces, ids = farm_run(a.build, os.path.join(base, "jobs"), submit_jobs)
            runs["jobs"].append({"wall": wall, "cpu": cpu, "maps_built": maps, "pieces": pieces})
            print(f"  jobs      {wall:7.2f} s wall {cpu:7.2f} s CPU  maps {maps} pieces {pieces}", file=sys.stderr)
            def compare_frames(address):
                for f, job in enumerate(ids, start=1):
                    single = os.path.join(base, f"job.{f:04d}.exr")
                    pf(client, "get", job, "--coordinator", address, "-o", single)
                    d = json.loads(pf(client, "diff", frames % f, single, "--json"))
                    if d["max_abs_error"] != 0:
                        sys.exit(f"frame {f}: differs from its single-frame job (max error {d['max_abs_error']})")

            fetch(a.build, os.path.join(base, "jobs"), compare_frames)
        med = {k: {m: statistics.median(r[m] for r in v) for m in ("wall", "cpu", "maps_built", "pieces")}
               for k, v in runs.items()}
        result = {
            "scene": "cornell-box camera_path", "frames": a.frames, "settings": " ".join(FLAGS),
            "machine": {"cores": os.cpu_count(), "load_after": os.getloadavg()},
            "runs": runs, "median": med,
            "wall_ratio_jobs_over_animation": [round(j["wall"] / n["wall"], 3)
                                               for j, n in zip(runs["jobs"], runs["animation"])],
            "cpu_ratio_jobs_over_animation": [round(j["cpu"] / n["cpu"], 3)
                                              for j, n in zip(runs["jobs"], runs["animation"])],
            "frames_bit_identical_to_single_frame_jobs": True,
        }
        result["median_wall_ratio"] = statistics.median(result["wall_ratio_jobs_over_animation"])
        result["median_cpu_ratio"] = statistics.median(result["cpu_ratio_jobs_over_animation"])
        print(f"\n{a.frames} frames of cornell-box, 2 workers x 1 thread, median of {a.repeat}")
        print(f"{'':12s} {'wall s':>8s} {'CPU s':>8s} {'maps built':>11s} {'pieces':>7s}")
        for k in ("animation", "jobs"):
            m = med[k]
            print(f"{k:12s} {m['wall']:8.2f} {m['cpu']:8.2f} {m['maps_built']:11.0f} {m['pieces']:7.0f}")
        print(f"jobs / animation: wall {result['median_wall_ratio']:.2f}x, CPU {result['median_cpu_ratio']:.2f}x; "
              "every frame bit-identical to its single-frame job")
        print(json.dumps(result, indent=1))
        if a.json_out:
            with open(a.json_out, "w") as f:
                json.dump(result, f, indent=1)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
