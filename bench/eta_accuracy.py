#!/usr/bin/env python3
"""How good is the ETA a watcher sees? Runs a coordinator and N workers on loopback, submits the
issue's default job (Cornell box, photon map, 1M photons, k 100, 256x256, 16 spp: 16 tiles of
64x64), follows it with `pf watch --json` and prints, per update, the ETA against the time that
really remained, then the median ratio over the middle of the job (25-75 % of the tiles merged).

    bench/eta_accuracy.py [--workers 1] [--build build] [--json out.json]

Ratios > 1: the ETA was too high. Measured results: docs/farm.md ("ETA").
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--json", help="write the updates and the summary here")
    args = ap.parse_args()
    b = args.build
    tmp = tempfile.mkdtemp(prefix="pf-eta-")
    procs = []
    try:
        coord = subprocess.Popen([f"{b}/server/pf-coordinator", "--listen", "127.0.0.1:0", "--data-dir",
                                  f"{tmp}/data"], stdout=subprocess.PIPE, stderr=open(f"{tmp}/coord.log", "w"),
                                 text=True)
        procs.append(coord)
        m = re.search(r"listening on (\S+)", coord.stdout.readline())
        addr = m.group(1)
        for i in range(args.workers):
            procs.append(subprocess.Popen([f"{b}/worker/pf-worker", "--coordinator", addr, "--threads", "1",
                                           "--cache-dir", f"{tmp}/cache-{i}"],
                                          stdout=subprocess.DEVNULL, stderr=open(f"{tmp}/w{i}.log", "w")))
        job = subprocess.run([f"{b}/client/pf", "submit", f"{ROOT}/scenes/cornell-box/cornell-box.json",
                              "--integrator", "photonmap", "--photons", "1000000", "--k", "100", "--res",
                              "256x256", "--spp", "16", "--coordinator", addr],
                             check=True, capture_output=True, text=True).stdout.split()[0]
        out = subprocess.run([f"{b}/client/pf", "watch", job, "--json", "--interval", "0.25", "-q",
                              "--coordinator", addr], check=True, capture_output=True, text=True).stdout
        updates = [json.loads(l) for l in out.splitlines() if l.startswith("{")]
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait()
        shutil.rmtree(tmp, ignore_errors=True)
    end = updates[-1]["elapsed_seconds"]
    total = updates[-1]["tasks_total"]
    print(f"{'elapsed':>8} {'done':>5} {'eta':>7} {'truth':>7} {'ratio':>6}")
    ratios = []
    for u in updates:
        truth = end - u["elapsed_seconds"]
        eta = u["eta_seconds"]
        ratio = eta / truth if eta >= 0 and truth > 0.05 else None
        if ratio is not None and 0.25 * total <= u["tasks_done"] <= 0.75 * total:
            ratios.append(ratio)
        print(f"{u['elapsed_seconds']:8.2f} {u['tasks_done']:5d} {eta:7.2f} {truth:7.2f} "
              f"{'' if ratio is None else f'{ratio:6.2f}'}")
    summary = {"workers": args.workers, "seconds": end, "median_ratio_25_75": statistics.median(ratios)
               if ratios else None}
    print(json.dumps(summary))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"summary": summary, "updates": updates}, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
