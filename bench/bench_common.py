"""Helpers the Python benchmark drivers share: running a tool from the repository root, timing it
by the CPU time of the child (the machines are shared: wall time counts the waits for a core), and
reading a string attribute of an EXR header (pf writes its counters there), and starting and
stopping a coordinator process."""
import os
import pathlib
import re
import resource
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent


def run(cmd):
    """Runs cmd in the repository root; exits with its stderr's tail if it fails."""
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}\n{r.stderr[-3000:]}")
    return r


def timed(cmd):
    """Runs cmd; returns (CPU seconds of the child, user + system, wall seconds)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    run(cmd)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def exr_string(path, name):
    """An EXR string attribute: name NUL "string" NUL, a 4-byte little-endian length, the bytes."""
    data = pathlib.Path(path).read_bytes()[:65536]
    key = name.encode() + b"\x00string\x00"
    i = data.find(key)
    if i < 0:
        return None
    n = int.from_bytes(data[i + len(key):i + len(key) + 4], "little")
    return data[i + len(key) + 4:i + len(key) + 4 + n].decode()


def start_coordinator(coordinator_bin, work, args):
    """Starts pf-coordinator on a free port with its data in work/data (stdout in work/coordinator.out,
    the log in work/coordinator.log); returns (process, address) once it says where it listens."""
    out = open(os.path.join(work, "coordinator.out"), "w+")
    p = subprocess.Popen([coordinator_bin, "--listen", "127.0.0.1:0", "--data-dir", os.path.join(work, "data")] + args,
                         stdout=out, stderr=open(os.path.join(work, "coordinator.log"), "w"))
    for _ in range(1000):
        out.seek(0)
        m = re.search(r"listening on (\S+)", out.read())
        if m:
            return p, m.group(1)
        time.sleep(0.01)
    p.kill()
    sys.exit("coordinator did not start")


def stop(p):
    """Ends a process: SIGTERM, then SIGKILL if it has not exited within 20 s."""
    p.terminate()
    try:
        p.wait(timeout=20)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
