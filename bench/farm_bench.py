#!/usr/bin/python3
"""farm_bench.py — the farm's benchmark: scaling, overhead and coordinator throughput.

    bench/farm_bench.py [--build build] [--quick] [--json-out results.json]

1. Scaling and overhead on one machine, the same photon-map skipping job throughout (cornell-box
   128x128, S=4 x 8 rounds = 128 tasks, 100k photons per map, 4 spp; >= 20 s on one core):
     local-1   pf render --local-only --threads 1      (the single-process renderer, one core)
     farm-1    pf render --workers 1 --threads 1       (coordinator + 1 worker of 1 thread)
     farm-2    pf render --workers 2 --threads 1       (coordinator + 2 workers of 1 thread)
     local-2   pf render --local-only --threads 2      (the single-process renderer, two cores)
   Wall time of the whole command (farm start-up, upload, scheduling and shutdown included);
   --repeat interleaved runs of each, the fastest counts (the machine may be shared). Also the CPU
   time (user + system) of all processes of a run: on a shared machine the cleaner measure of
   what the farm adds (coordinator, client, RPCs).
   speedup = farm-1 / farm-2; overhead = farm-N / local-N - 1. All four images must be
   bit-identical (checked).
2. The coordinator alone with instant workers (tests/e2e/pf_fake_worker --mode instant: lease,
   answer zeros of the right size at once, 4 connections in parallel), loopback only, bounded by
   a task count and a time limit: task completions per second, with durable acknowledgements
   (--checkpoint-ms 0: every merge checkpointed before the result is acknowledged) and with
   checkpoints batched every 100 ms; bytes on the wire per task (the CompleteTask payload and the
   leased Task message) against the pixels in the subset.
Prints a table and the JSON; --json-out also writes the JSON to a file.
"""
import argparse
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(REPO, "scenes", "cornell-box", "cornell-box.json")


def run(cmd, cpu=None, **kw):
    """Runs cmd; returns (wall seconds, result). `cpu` (a list) receives the CPU seconds (user +
    system) of the command and every process it started and reaped (pf reaps its farm)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    dt = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if cpu is not None:
        cpu.append(round((after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), 3))
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr}")
    return dt, r


def start_coordinator(coord, data_dir, extra):
    out = open(os.path.join(data_dir, "coordinator.out"), "w+")
    p = subprocess.Popen([coord, "--listen", "127.0.0.1:0", "--data-dir", os.path.join(data_dir, "data"),
                          "--log-level", "warn"] + extra,
                         stdout=out, stderr=open(os.path.join(data_dir, "coordinator.log"), "w"))
    for _ in range(1000):
        out.seek(0)
        m = re.search(r"listening on (\S+)", out.read())
        if m:
            return p, m.group(1)
        time.sleep(0.01)
    p.kill()
    sys.exit("coordinator did not start")


def stop(p):
    p.terminate()
    try:
        p.wait(timeout=20)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()


def main():
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # run the clean-up below
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(REPO, "build"))
    ap.add_argument("--quick", action="store_true", help="a 4x smaller render job (for a smoke run)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each render configuration (the fastest counts)")
    ap.add_argument("--json-out")
    a = ap.parse_args()
    pf = os.path.join(a.build, "client", "pf")
    coord = os.path.join(a.build, "server", "pf-coordinator")
    fake = os.path.join(a.build, "tests", "e2e", "pf_fake_worker")
    for b in (pf, coord, fake):
        if not os.access(b, os.X_OK):
            sys.exit(f"missing {b}: build first (cmake --build {a.build})")
    tmp = tempfile.mkdtemp(prefix="pf-farm-bench-")
    results = {"machine": {"cores": os.cpu_count()}, "render": {}, "coordinator": []}
    try:
        rounds = 2 if a.quick else 8
        job = ["--integrator", "photonmap", "--photons", "100000", "--k", "50", "--res", "128x128",
               "--plan", "skipping", "--stride", "4", "--rounds", str(rounds), "--spp", "4", "--seed", "11",
               "-q", "--no-png", "--log-level", "warn"]
        results["render"]["job"] = f"cornell-box 128x128, skipping S=4 x {rounds} rounds ({16 * rounds} tasks), " \
                                   "100k photons/map, k=50, 4 spp"
        runs = [("local-1", ["--local-only", "--threads", "1"]), ("farm-1", ["--workers", "1", "--threads", "1"]),
                ("farm-2", ["--workers", "2", "--threads", "1"]), ("local-2", ["--local-only", "--threads", "2"])]
        # Interleaved repetitions, fastest of each: the machine may be shared.
        times = {name: [] for name, _ in runs}
        cpus = {name: [] for name, _ in runs}
        for rep in range(a.repeat):
            for name, flags in runs:
                out = os.path.join(tmp, name + ".exr")
                dt, _ = run([pf, "render", SCENE, "-o", out] + job + flags, cpu=cpus[name])
                times[name].append(round(dt, 3))
                print(f"  {name:8s} {dt:8.2f} s wall {cpus[name][-1]:8.2f} s CPU", file=sys.stderr, flush=True)
        for name, _ in runs:
            results["render"][name + "_seconds"] = min(times[name])
            results["render"][name + "_all_seconds"] = times[name]
            results["render"][name + "_cpu_seconds"] = min(cpus[name])
        for name, _ in runs[1:]:
            _, r = run([pf, "diff", os.path.join(tmp, name + ".exr"), os.path.join(tmp, "local-1.exr"), "--json"])
            if json.loads(r.stdout)["max_abs_error"] != 0:
                sys.exit(f"{name}: image differs from local-1")
        r = results["render"]
        r["bit_identical"] = True
        r["speedup_2_vs_1_workers"] = round(r["farm-1_seconds"] / r["farm-2_seconds"], 3)
        r["overhead_farm1_vs_local1"] = round(r["farm-1_seconds"] / r["local-1_seconds"] - 1, 4)
        r["overhead_farm2_vs_local2"] = round(r["farm-2_seconds"] / r["local-2_seconds"] - 1, 4)
        r["cpu_overhead_farm1_vs_local1"] = round(r["farm-1_cpu_seconds"] / r["local-1_cpu_seconds"] - 1, 4)
        r["cpu_overhead_farm2_vs_local1"] = round(r["farm-2_cpu_seconds"] / r["local-1_cpu_seconds"] - 1, 4)

        for ckpt in ("0", "100"):
            for stride, res in ((8, 64), (2, 64)):
                d = tempfile.mkdtemp(dir=tmp)
                p, addr = start_coordinator(coord, d, ["--checkpoint-ms", ckpt])
                try:
                    rounds = 2000 // (stride * stride) + 1
                    _, s = run([pf, "submit", SCENE, "--coordinator", addr, "--integrator", "photonmap",
                                "--res", f"{res}x{res}", "--plan", "skipping", "--stride", str(stride),
                                "--rounds", str(rounds), "--spp", "1"])
                    _, f = run([fake, "--coordinator", addr, "--mode", "instant", "--concurrency", "4",
                                "--tasks", "2000", "--seconds", "20"])
                    j = json.loads(f.stdout)
                    row = {"checkpoint_ms": int(ckpt), "pixels_per_task": j["pixels_per_task"],
                           "completions_per_second": round(j["completions_per_second"], 1),
                           "completed": j["completed"], "seconds": round(j["seconds"], 2),
                           "result_bytes_per_task": round(j["result_bytes_per_task"], 1),
                           "result_bytes_per_pixel": round(j["result_bytes_per_task"] / j["pixels_per_task"], 2),
                           "task_bytes_per_lease": round(j["task_bytes_per_lease"], 1)}
                    results["coordinator"].append(row)
                    print(f"  coordinator ckpt={ckpt} px/task={row['pixels_per_task']:.0f}: "
                          f"{row['completions_per_second']} completions/s", file=sys.stderr, flush=True)
                finally:
                    stop(p)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    r = results["render"]
    print(f"\nRender: {r['job']} on {os.cpu_count()} cores (wall time of the whole command)")
    print(f"  {'run':<40}{'wall s':>9}{'CPU s':>9}")
    for name, label in (("local-1", "local, 1 thread"), ("farm-1", "pf render --workers 1 (1 thread)"),
                        ("farm-2", "pf render --workers 2 (1 thread each)"), ("local-2", "local, 2 threads")):
        print(f"  {label:<40}{r[name + '_seconds']:>9.2f}{r[name + '_cpu_seconds']:>9.2f}")
    print(f"  speedup 2 vs 1 workers {r['speedup_2_vs_1_workers']:.2f}x;  farm overhead, wall: "
          f"{100 * r['overhead_farm1_vs_local1']:+.1f} % (1 worker vs 1 thread), "
          f"{100 * r['overhead_farm2_vs_local2']:+.1f} % (2 workers vs 2 threads);  CPU: "
          f"{100 * r['cpu_overhead_farm1_vs_local1']:+.1f} % (1 worker), "
          f"{100 * r['cpu_overhead_farm2_vs_local1']:+.1f} % (2 workers); images bit-identical")
    print("\nCoordinator alone, 4 instant fake workers on loopback:")
    print(f"  {'checkpoints':<14}{'px/task':>8}{'tasks/s':>10}{'result B/task':>15}{'B/pixel':>9}{'task B':>8}")
    for row in results["coordinator"]:
        ck = "every merge" if row["checkpoint_ms"] == 0 else f"every {row['checkpoint_ms']} ms"
        print(f"  {ck:<14}{row['pixels_per_task']:>8.0f}{row['completions_per_second']:>10.1f}"
              f"{row['result_bytes_per_task']:>15.1f}{row['result_bytes_per_pixel']:>9.2f}"
              f"{row['task_bytes_per_lease']:>8.1f}")
    print("\n" + json.dumps(results, indent=2))
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
