#!/usr/bin/python3
"""CTest e2e.python_client: tools/pf_client.py against a real pf-coordinator and pf-worker.

Starts both on an ephemeral loopback port with a bearer token, runs the Python client on a
small skipping job, and checks that it exits 0, saw image snapshots, and saved exactly the bytes
`pf get` fetches for the same job (the final merged image). Leaves no process behind."""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--pf", "--coordinator-bin", "--worker-bin", "--stubs", "--scene", "--client"):
        ap.add_argument(flag, required=True)
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="pf-e2e-python-")
    procs = []
    ok = False
    try:
        token = os.path.join(tmp, "token")
        with open(token, "w") as f:
            f.write("python-test-token\n")
        worker_token = os.path.join(tmp, "worker-token")
        with open(worker_token, "w") as f:
            f.write("python-worker-token\n")
        env = dict(os.environ, PF_TOKEN="")
        out = open(os.path.join(tmp, "coordinator.out"), "w+")
        coord = subprocess.Popen([a.coordinator_bin, "--listen", "127.0.0.1:0", "--data-dir",
                                  os.path.join(tmp, "data"), "--client-token-file", token,
                                  "--worker-token-file", worker_token],
                                 stdout=out, stderr=open(os.path.join(tmp, "coordinator.log"), "w"), env=env)
        procs.append(coord)
        address = None
        for _ in range(500):
            out.seek(0)
            m = re.search(r"listening on (\S+)", out.read())
            if m:
                address = m.group(1)
                break
            time.sleep(0.02)
        assert address, "coordinator did not start"
        procs.append(subprocess.Popen([a.worker_bin, "--coordinator", address, "--token-file", worker_token, "--threads", "1",
                                       "--cache-dir", os.path.join(tmp, "cache")],
                                      stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, "worker.log"), "w")))
        output = os.path.join(tmp, "python.exr")
        r = subprocess.run([sys.executable, a.client, a.scene, "--coordinator", address, "--token-file", token,
                            "--stubs", a.stubs, "--res", "32x32", "--photons", "5000", "--k", "20", "--stride", "2",
                            "--rounds", "3", "--interval", "0.05", "-o", output],
                           capture_output=True, text=True, timeout=90)
        print(r.stdout)
        print(r.stderr, file=sys.stderr)
        assert r.returncode == 0, f"pf_client.py exited {r.returncode}"
        job_id = r.stdout.strip().splitlines()[-1]
        snapshots = int(re.findall(r"(\d+) snapshots ->", r.stdout)[-1])
        assert snapshots >= 1, "no image snapshot arrived"
        ref = os.path.join(tmp, "pf-get.exr")
        g = subprocess.run([a.pf, "get", job_id, "-o", ref, "--coordinator", address, "--token-file", token],
                           capture_output=True, text=True, timeout=30)
        assert g.returncode == 0, g.stderr
        with open(output, "rb") as f1, open(ref, "rb") as f2:
            b1, b2 = f1.read(), f2.read()
        assert b1[:4] == b"\x76\x2f\x31\x01", "not an OpenEXR file"
        assert b1 == b2, "the Python client's image differs from pf get's"
        ok = True
        print(f"ok: job {job_id}, {snapshots} snapshots, {len(b1)} bytes, identical to pf get")
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if ok:
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            print(f"kept {tmp}", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
