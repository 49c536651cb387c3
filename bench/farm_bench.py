#!/usr/bin/python3
"""farm_bench.py — the farm's benchmark: scaling, overhead and coordinator throughput.

    bench/farm_bench.py [--build build] [--job default|skipping] [--repeat 3] [--render-only]
                        [--quick] [--json-out results.json]

1. Scaling and overhead on one machine (docs/farm.md, "Measured"), one render job throughout:
     --job default (the default): the issue's default farm job — cornell-box 256x256, one photon map
       of 1M photons, k 100, 16 spp, the default plan;
     --job skipping: cornell-box 128x128, photon-map skipping S=4 x 8 rounds = 128 tasks, 100k
       photons per map, 4 spp (--quick: 2 rounds).
   Runs, each the whole `pf` command (farm start-up, upload, scheduling and shutdown included):
     process-1  pf render --threads 1                 (one process, one thread)
     process-2  pf render --threads 2                 (one process, two threads)
     farm-1     pf render --workers 1 --threads 1     (coordinator + 1 worker of 1 thread)
     farm-2     pf render --workers 2 --threads 1     (coordinator + 2 workers of 1 thread)
     farm-2-local  the same with --map-tracing local  (each worker traces and balances the map, as
                before maps were traced once (docs/farm.md, "Photon maps traced once"); for the side-by-side ratio)
   --repeat interleaved runs of each (so that load changes hit every variant alike); the MEDIAN
   counts, the fastest is reported too. Also the CPU time (user + system) of all processes of a
   run. Ratios: process-1/process-2 (target >= 1.85), farm-1/farm-2 (target >= 1.8), farm-2 vs
   process-2 (target within 10 %). Images: process-2 must equal process-1 and farm-2 farm-1
   bit for bit (checked, exit 1 otherwise); whether the farm's image equals the single process's
   is reported. The load average before and after is recorded: on a shared 2-core machine the
   wall-clock ratios are only meaningful when it is idle. Hence, when `perf` is installed (not a
   dependency; --no-span to skip), every run is also sampled (perf record -e cpu-clock, 499 Hz,
   all processes and threads of the command) and its SPAN is reported: the on-CPU time of its
   busiest thread (single process) or busiest process (farm: 1-thread workers, each task on a
   thread of its own), i.e. the wall time the run would take on an idle machine if that thread or
   worker never waits (true of the single process, whose calling thread runs the serial parts; a
   lower bound for the farm, whose workers may wait for leases or idle at the end). Span ratios
   are what load cannot distort.
2. The coordinator alone with instant workers (tests/e2e/pf_fake_worker --mode instant: lease,
   answer zeros of the right size at once, 4 connections in parallel), loopback only, bounded by
   a task count and a time limit: task completions per second, with durable acknowledgements
   (--checkpoint-ms 0: every merge checkpointed before the result is acknowledged) and with
   checkpoints batched every 100 ms; bytes on the wire per task (the CompleteTask payload and the
   leased Task message) against the pixels in the subset. Skipped with --render-only.
Prints a table and the JSON; --json-out also writes the JSON to a file.
"""
import argparse
import json
import os
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from bench_common import start_coordinator, stop

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


def span_of(perf_data, by_process):
    """(On-CPU seconds of the busiest thread (by_process: of the busiest worker process), on-CPU
    seconds of the pf-coordinator process) in a `perf record -F 499` of a command and everything
    it started."""
    r = subprocess.run(["perf", "script", "-i", perf_data, "-F", "pid,tid,comm"], capture_output=True, text=True)
    counts, coordinator_pids = {}, set()
    for line in r.stdout.splitlines():  # "comm pid/tid" per sample (comm may hold spaces)
        fields = line.split()
        ids = fields[-1].split("/") if fields else []
        if len(ids) != 2 or not ids[0].isdigit():
            continue
        if " ".join(fields[:-1]) == "pf-coordinator":
            coordinator_pids.add(ids[0])
        key = ids[0] if by_process else ids[1]
        counts[key] = counts.get(key, 0) + 1
    # The coordinator now balances distributed maps, on the critical path while the
    # workers wait; it is reported apart and not counted as a worker.
    coordinator = sum(counts.get(pid, 0) for pid in coordinator_pids) if by_process else 0
    workers = [n for key, n in counts.items() if key not in coordinator_pids] if by_process else list(counts.values())
    return (max(workers) / 499.0 if workers else 0.0), coordinator / 499.0


def main():
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # run the clean-up below
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(REPO, "build"))
    ap.add_argument("--quick", action="store_true", help="--job skipping: 2 rounds instead of 8 (a smoke run)")
    ap.add_argument("--job", choices=("default", "skipping"), default="default")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each render configuration (the median counts)")
    ap.add_argument("--render-only", action="store_true", help="skip the coordinator throughput part")
    ap.add_argument("--no-span", action="store_true", help="do not sample runs with perf")
    ap.add_argument("--json-out")
    a = ap.parse_args()
    pf = os.path.join(a.build, "client", "pf")
    coord = os.path.join(a.build, "server", "pf-coordinator")
    fake = os.path.join(a.build, "tests", "e2e", "pf_fake_worker")
    for b in (pf, coord, fake):
        if not os.access(b, os.X_OK):
            sys.exit(f"missing {b}: build first (cmake --build {a.build})")
    tmp = tempfile.mkdtemp(prefix="pf-farm-bench-")
    results = {"machine": {"cores": os.cpu_count(), "load_before": os.getloadavg()}, "render": {},
               "coordinator": []}
    try:
        common = ["-q", "--no-png", "--log-level", "warn"]
        if a.job == "default":
            job = ["--integrator", "photonmap", "--photons", "1000000", "--k", "100", "--res", "256x256",
                   "--spp", "16", "--seed", "11"] + common
            results["render"]["job"] = "cornell-box 256x256, one map of 1M photons, k 100, 16 spp, --plan multiple-maps"
        else:
            rounds = 2 if a.quick else 8
            job = ["--integrator", "photonmap", "--photons", "100000", "--k", "50", "--res", "128x128",
                   "--plan", "skipping", "--stride", "4", "--rounds", str(rounds), "--spp", "4",
                   "--seed", "11"] + common
            results["render"]["job"] = f"cornell-box 128x128, skipping S=4 x {rounds} rounds ({16 * rounds} " \
                                       "tasks), 100k photons/map, k=50, 4 spp"
        # A skipping job in one process needs --local-only (a plain render runs no plan).
        local = ["--local-only"] if a.job == "skipping" else []
        if a.job == "default":
            # The job is one shared 1M-photon map: name its plan, since the farm's own
            # default is now --plan auto (which would cut the budget into per-task maps).
            job += ["--plan", "multiple-maps"]
        runs = [("process-1", local + ["--threads", "1"]), ("process-2", local + ["--threads", "2"]),
                ("farm-1", ["--workers", "1", "--threads", "1"]), ("farm-2", ["--workers", "2", "--threads", "1"]),
                # Every worker traces and balances the map itself (as before distributed tracing).
                ("farm-2-local", ["--workers", "2", "--threads", "1", "--map-tracing", "local"])]
        use_span = not a.no_span and shutil.which("perf") is not None
        times = {name: [] for name, _ in runs}
        cpus = {name: [] for name, _ in runs}
        spans = {name: [] for name, _ in runs}
        coordinator_cpu = {name: [] for name, _ in runs}
        for rep in range(a.repeat):
            for name, flags in runs:
                out = os.path.join(tmp, name + ".exr")
                data = os.path.join(tmp, name + ".perf")
                prefix = ["perf", "record", "-q", "-F", "499", "-e", "cpu-clock", "-o", data, "--"] if use_span else []
                dt, _ = run(prefix + [pf, "render", SCENE, "-o", out] + job + flags, cpu=cpus[name])
                times[name].append(round(dt, 3))
                if use_span:
                    # A 1-thread worker renders each task on a thread of its own: its busy time is
                    # that of its process.
                    span, coord_s = span_of(data, by_process=name.startswith("farm"))
                    spans[name].append(round(span, 3))
                    coordinator_cpu[name].append(round(coord_s, 3))
                print(f"  {name:9s} {dt:8.2f} s wall {cpus[name][-1]:8.2f} s CPU"
                      + (f" {spans[name][-1]:8.2f} s span" if use_span else ""), file=sys.stderr, flush=True)
        r = results["render"]
        for name, _ in runs:
            r[name + "_seconds"] = statistics.median(times[name])
            r[name + "_fastest_seconds"] = min(times[name])
            r[name + "_all_seconds"] = times[name]
            r[name + "_cpu_seconds"] = statistics.median(cpus[name])
            if use_span:
                r[name + "_span_seconds"] = statistics.median(spans[name])
                r[name + "_all_span_seconds"] = spans[name]
                if name.startswith("farm"):
                    # Upper bound of the critical path: the busiest worker plus all the coordinator's
                    # CPU (its map balance is serial while the workers wait; the rest overlaps).
                    r[name + "_coordinator_cpu_seconds"] = statistics.median(coordinator_cpu[name])
                    r[name + "_span_plus_coordinator_seconds"] = statistics.median(
                        [x + y for x, y in zip(spans[name], coordinator_cpu[name])])
        if use_span:
            r["span_speedup_farm_2_vs_2_local"] = round(r["farm-2-local_span_seconds"] / r["farm-2_span_seconds"], 3)
            r["span_plus_coordinator_speedup_farm_2_vs_1_workers"] = round(
                r["farm-1_span_plus_coordinator_seconds"] / r["farm-2_span_plus_coordinator_seconds"], 3)
            r["span_speedup_process_2_vs_1_threads"] = round(r["process-1_span_seconds"] / r["process-2_span_seconds"], 3)
            r["span_speedup_farm_2_vs_1_workers"] = round(r["farm-1_span_seconds"] / r["farm-2_span_seconds"], 3)
            r["span_farm2_vs_process2"] = round(r["farm-2_span_seconds"] / r["process-2_span_seconds"] - 1, 4)

        def identical(x, y):
            _, d = run([pf, "diff", os.path.join(tmp, x + ".exr"), os.path.join(tmp, y + ".exr"), "--json"])
            return json.loads(d.stdout)["max_abs_error"] == 0

        for x, y in (("process-2", "process-1"), ("farm-2", "farm-1"), ("farm-2-local", "farm-1")):
            if not identical(x, y):
                sys.exit(f"{x}: image differs from {y}")
        r["bit_identical_threads_and_workers"] = True
        r["farm_equals_process"] = identical("farm-1", "process-1")
        r["speedup_process_2_vs_1_threads"] = round(r["process-1_seconds"] / r["process-2_seconds"], 3)
        r["speedup_farm_2_vs_1_workers"] = round(r["farm-1_seconds"] / r["farm-2_seconds"], 3)
        r["speedup_farm_2_vs_2_local"] = round(r["farm-2-local_seconds"] / r["farm-2_seconds"], 3)
        r["farm2_vs_process2"] = round(r["farm-2_seconds"] / r["process-2_seconds"] - 1, 4)
        # The same ratios per repetition (each repetition runs every configuration back to back,
        # so a pair shares the host's speed of that moment, which drifts by ±8 % over minutes on
        # this shared VM), then the median of those: less sensitive to the drift than the ratio
        # of the medians above, which is reported first and is what the targets are read on.
        def paired(x, y):
            return round(statistics.median(a / b for a, b in zip(times[x], times[y])), 3)
        r["paired_speedup_process_2_vs_1_threads"] = paired("process-1", "process-2")
        r["paired_speedup_farm_2_vs_1_workers"] = paired("farm-1", "farm-2")
        r["paired_farm2_vs_process2"] = round(paired("farm-2", "process-2") - 1, 4)
        r["overhead_farm1_vs_process1"] = round(r["farm-1_seconds"] / r["process-1_seconds"] - 1, 4)
        r["cpu_overhead_farm1_vs_process1"] = round(r["farm-1_cpu_seconds"] / r["process-1_cpu_seconds"] - 1, 4)
        r["cpu_overhead_farm2_vs_process1"] = round(r["farm-2_cpu_seconds"] / r["process-1_cpu_seconds"] - 1, 4)
        results["machine"]["load_after_render"] = os.getloadavg()

        for ckpt in () if a.render_only else ("0", "100"):
            for stride, res in ((8, 64), (2, 64)):
                d = tempfile.mkdtemp(dir=tmp)
                p, addr = start_coordinator(coord, d, ["--log-level", "warn", "--checkpoint-ms", ckpt])
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
    print(f"\nRender: {r['job']} on {os.cpu_count()} cores, median of {a.repeat} (wall time of the whole "
          f"command); load {results['machine']['load_before'][0]:.2f} before, "
          f"{results['machine']['load_after_render'][0]:.2f} after")
    spanned = "process-1_span_seconds" in r
    print(f"  {'run':<58}{'median s':>9}{'fastest s':>10}{'CPU s':>9}"
          + (f"{'span s':>9}{'coord s':>9}" if spanned else ""))
    for name, label in (("process-1", "pf render --threads 1"), ("process-2", "pf render --threads 2"),
                        ("farm-1", "pf render --workers 1 --threads 1"),
                        ("farm-2", "pf render --workers 2 --threads 1"),
                        ("farm-2-local", "pf render --workers 2 --threads 1 --map-tracing local")):
        coord = f"{r[name + '_coordinator_cpu_seconds']:>9.2f}" if spanned and name.startswith("farm") else f"{'':>9}"
        print(f"  {label:<58}{r[name + '_seconds']:>9.2f}{r[name + '_fastest_seconds']:>10.2f}"
              f"{r[name + '_cpu_seconds']:>9.2f}" + (f"{r[name + '_span_seconds']:>9.2f}{coord}" if spanned else ""))
    sp = (lambda key, fmt: f"; span {fmt(r['span_' + key])}" if spanned else "")
    print(f"  1 process, 2 vs 1 threads: wall {r['speedup_process_2_vs_1_threads']:.2f}x"
          f"{sp('speedup_process_2_vs_1_threads', lambda v: f'{v:.2f}x')} (target >= 1.85)")
    print(f"  2 vs 1 workers x 1 thread: wall {r['speedup_farm_2_vs_1_workers']:.2f}x"
          f"{sp('speedup_farm_2_vs_1_workers', lambda v: f'{v:.2f}x')} (target >= 1.8)")
    if spanned:
        print(f"  2 vs 1 workers, busiest worker + all coordinator CPU: "
              f"{r['span_plus_coordinator_speedup_farm_2_vs_1_workers']:.2f}x (the pessimistic bound)")
    print(f"  2 workers, map traced once vs by each worker: wall {r['speedup_farm_2_vs_2_local']:.2f}x"
          f"{sp('speedup_farm_2_vs_2_local', lambda v: f'{v:.2f}x')}")
    print(f"  2 workers vs 1 process of 2 threads: wall {100 * r['farm2_vs_process2']:+.1f} %"
          f"{sp('farm2_vs_process2', lambda v: f'{100 * v:+.1f} %')} (target within 10 %)")
    print(f"  paired per repetition (median): 2 vs 1 threads {r['paired_speedup_process_2_vs_1_threads']:.2f}x, "
          f"2 vs 1 workers {r['paired_speedup_farm_2_vs_1_workers']:.2f}x, 2 workers vs 1 process "
          f"{100 * r['paired_farm2_vs_process2']:+.1f} %")
    print(f"  farm overhead (1 worker vs 1 thread): wall {100 * r['overhead_farm1_vs_process1']:+.1f} %, CPU "
          f"{100 * r['cpu_overhead_farm1_vs_process1']:+.1f} %; CPU of 2 workers vs 1 thread "
          f"{100 * r['cpu_overhead_farm2_vs_process1']:+.1f} %")
    print(f"  images bit-identical for 1/2 threads and 1/2 workers; farm image == process image: "
          f"{'yes' if r['farm_equals_process'] else 'no'}")
    if results["coordinator"]:
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
