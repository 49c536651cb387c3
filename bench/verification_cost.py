#!/usr/bin/python3
"""verification_cost.py — what result verification costs a real farm job (docs/farm.md "Result
verification").

    bench/verification_cost.py [--build build] [--repeat 3] [--fractions 0,0.03,0.1] [--json-out FILE]

One farm on this machine per run: pf-coordinator, two pf-workers of one thread each, loopback, one
job — cornell-box 128x128, photon-map skipping S=4 x 8 rounds = 128 tasks, 100k photons per map,
k 50, 2 spp (the skipping job of bench/farm_bench.py with 2 spp) — submitted with `pf submit` and
waited for. Variants: `--verify-fraction F` for each F of --fractions, the outlier test on
(the default) except for F = 0, which is the baseline with verification off entirely
(`--no-verify-outliers`). --repeat interleaved runs of each variant; MEDIANS count.
Measured per run, from /proc just before the processes are stopped: the CPU seconds (user +
system) of the two workers and of the coordinator; the job's wall time (submit to SUCCEEDED);
from the coordinator's log, the verification leases handed out and the tasks the coordinator
rendered itself (the referee). Extra work = median worker + coordinator CPU of a variant over
the baseline's, minus 1. The images of all runs must be identical (verification never changes
the image; checked pixel for pixel with `pf diff`, exit 1 otherwise).
Prints a table and the JSON; --json-out also writes the JSON to a file.
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from bench_common import start_coordinator, stop

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(REPO, "scenes", "cornell-box", "cornell-box.json")
JOB = ["--integrator", "photonmap", "--photons", "100000", "--k", "50", "--plan", "skipping", "--stride", "4",
       "--rounds", "8", "--spp", "2", "--res", "128x128", "--seed", "3"]
TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    """User + system CPU seconds of a live process (its threads included)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def one_run(build, fraction, work, reference):
    pf = os.path.join(build, "client", "pf")
    coord_args = ["--verify-fraction", str(fraction)] + (["--no-verify-outliers"] if fraction == 0 else [])
    log = os.path.join(work, "coordinator.log")
    coord, address = start_coordinator(os.path.join(build, "server", "pf-coordinator"), work, coord_args)
    workers = [subprocess.Popen([os.path.join(build, "worker", "pf-worker"), "--coordinator", address, "--threads",
                                 "1", "--worker-id", f"w{i}", "--cache-dir", os.path.join(work, f"cache{i}")],
                                stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, f"w{i}.log"), "w"))
               for i in range(2)]
    try:
        t0 = time.monotonic()
        r = subprocess.run([pf, "submit", SCENE] + JOB + ["--coordinator", address], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit("pf submit failed: " + r.stderr)
        job = r.stdout.strip()
        deadline = time.monotonic() + 600
        while True:
            if time.monotonic() > deadline:
                sys.exit("the job did not end within 600 s")
            s = subprocess.run([pf, "list", "--all", "--json", "--coordinator", address], capture_output=True,
                               text=True)
            listed = json.loads(s.stdout)
            listed = listed.get("jobs", listed) if isinstance(listed, dict) else listed
            st = next(j for j in listed if j["job_id"] == job)
            if st["state"].upper() in ("SUCCEEDED", "FAILED", "CANCELLED"):
                break
            time.sleep(0.1)
        wall = time.monotonic() - t0
        if st["state"].upper() != "SUCCEEDED":
            sys.exit(f"job {st['state']}: {st['failure_reason']}")
        image = os.path.join(work, "out.exr")
        subprocess.run([pf, "get", job, "-o", image, "--coordinator", address], check=True,
                       capture_output=True)
        # The pixels, not the file: the EXR's header names the job.
        if not os.path.exists(reference):
            shutil.copy(image, reference)
        d = subprocess.run([pf, "diff", image, reference, "--json"], capture_output=True, text=True, check=True)
        identical = json.loads(d.stdout)["max_abs_error"] == 0
        worker_cpu = sum(cpu_seconds(w.pid) for w in workers)
        coord_cpu = cpu_seconds(coord.pid)
    finally:
        for w in workers:
            stop(w)
        stop(coord)
    text = open(log).read()
    return {"wall_seconds": round(wall, 3), "worker_cpu": round(worker_cpu, 3), "coordinator_cpu": round(coord_cpu, 3),
            "tasks": st["tasks_total"], "verification_leases": len(re.findall(r"verification leased to", text)),
            "referee_renders": len(re.findall(r"referee: job \S+ task \d+ rendered", text)),
            "results_verified": st.get("results_verified", 0), "image_identical": identical}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(REPO, "build"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fractions", default="0,0.03,0.1")
    ap.add_argument("--json-out")
    a = ap.parse_args()
    fractions = [float(f) for f in a.fractions.split(",")]
    results = {"machine": {"cores": os.cpu_count(), "load_before": os.getloadavg()}, "job": JOB, "runs": {}}
    keep = tempfile.mkdtemp(prefix="pf-verify-cost-ref-")
    reference = os.path.join(keep, "first.exr")  # the first run's image: every run's must equal it
    for rep in range(a.repeat):
        for f in fractions:
            work = tempfile.mkdtemp(prefix="pf-verify-cost-")
            try:
                run = one_run(a.build, f, work, reference)
            finally:
                shutil.rmtree(work, ignore_errors=True)
            results["runs"].setdefault(str(f), []).append(run)
            print(f"run {rep + 1} fraction {f}: {run}", file=sys.stderr)
    results["machine"]["load_after"] = os.getloadavg()
    shutil.rmtree(keep, ignore_errors=True)
    results["images_identical"] = all(r["image_identical"] for runs in results["runs"].values() for r in runs)
    base = None
    print(f"{'fraction':>9} {'tasks':>6} {'verif. leases':>14} {'referee':>8} {'worker CPU s':>13} "
          f"{'coord. CPU s':>13} {'extra work':>11} {'wall s':>8}")
    summary = {}
    for f in fractions:
        runs = results["runs"][str(f)]
        med = {k: statistics.median(r[k] for r in runs)
               for k in ("wall_seconds", "worker_cpu", "coordinator_cpu", "verification_leases", "referee_renders",
                         "tasks")}
        total = med["worker_cpu"] + med["coordinator_cpu"]
        if base is None:
            base = total
        med["extra_work"] = round(total / base - 1, 4)
        summary[str(f)] = med
        print(f"{f:>9} {med['tasks']:>6.0f} {med['verification_leases']:>14.0f} {med['referee_renders']:>8.0f} "
              f"{med['worker_cpu']:>13.2f} {med['coordinator_cpu']:>13.2f} {100 * med['extra_work']:>10.1f}% "
              f"{med['wall_seconds']:>8.2f}")
    results["median"] = summary
    print(json.dumps(results, indent=2))
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(results, f, indent=2)
            f.write("\n")
    if not results["images_identical"]:
        sys.exit("the images differ between runs")


if __name__ == "__main__":
    main()
