#!/usr/bin/python3
"""CTest e2e.python_client: tools/pf_client.py against a real pf-coordinator and pf-worker.

Starts both on an ephemeral loopback port with a bearer token, runs the Python client on a
small skipping job, and checks that it exits 0, saw image snapshots, and saved exactly the bytes
`pf get` fetches for the same job (the final merged image). Leaves no process behind.

With --tls (CTest e2e.python_client_tls): the same over TLS with certificates made here by the
openssl CLI (a CA; the coordinator's certificate for 127.0.0.1; client certificates for the
worker and the Python client, mTLS with --tls-client-ca). The Python client connects with
--tls-ca and its certificate; the same client without --tls-ca (plaintext) is refused."""
import argparse
import shutil as _shutil
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time


def make_certificates(folder):
    """A CA, the coordinator's certificate (SAN 127.0.0.1, localhost) and client certificates for
    the worker and the Python client, all made with the openssl CLI (tools/install-deps.sh)."""
    openssl = _shutil.which("openssl")
    assert openssl, "the openssl CLI is missing (tools/install-deps.sh installs it)"
    paths = {}

    def path(name):
        paths[name] = os.path.join(folder, name)
        return paths[name]

    def run(*args):
        subprocess.run([openssl] + list(args), check=True, capture_output=True, timeout=60)

    with open(path("san.cnf"), "w") as f:
        f.write("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", path("ca.key"), "-out", path("ca.pem"),
        "-days", "2", "-subj", "/CN=photonfarm python test CA")
    for who in ("server", "worker", "client"):
        run("req", "-newkey", "rsa:2048", "-nodes", "-keyout", path(who + ".key"), "-out", path(who + ".csr"),
            "-subj", "/CN=" + who)
        sign = ["x509", "-req", "-in", paths[who + ".csr"], "-CA", paths["ca.pem"], "-CAkey", paths["ca.key"],
                "-CAcreateserial", "-out", path(who + ".pem"), "-days", "2"]
        if who == "server":
            sign += ["-extfile", paths["san.cnf"]]
        run(*sign)
    return paths


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--pf", "--coordinator-bin", "--worker-bin", "--stubs", "--scene", "--client"):
        ap.add_argument(flag, required=True)
    ap.add_argument("--tls", action="store_true", help="TLS + mTLS with certificates made by openssl")
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
        for var in ("PF_TLS_CA", "PF_TLS_CERT", "PF_TLS_KEY"):
            env.pop(var, None)
        tls = {}
        if a.tls:
            tls = make_certificates(tmp)
        coordinator_tls = ["--tls-cert", tls["server.pem"], "--tls-key", tls["server.key"],
                           "--tls-client-ca", tls["ca.pem"]] if a.tls else []
        worker_tls = ["--tls-ca", tls["ca.pem"], "--tls-cert", tls["worker.pem"],
                      "--tls-key", tls["worker.key"]] if a.tls else []
        client_tls = ["--tls-ca", tls["ca.pem"], "--tls-cert", tls["client.pem"],
                      "--tls-key", tls["client.key"]] if a.tls else []
        out = open(os.path.join(tmp, "coordinator.out"), "w+")
        coord = subprocess.Popen([a.coordinator_bin, "--listen", "127.0.0.1:0", "--data-dir",
                                  os.path.join(tmp, "data"), "--client-token-file", token,
                                  "--worker-token-file", worker_token] + coordinator_tls,
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
                                       "--cache-dir", os.path.join(tmp, "cache")] + worker_tls,
                                      stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, "worker.log"), "w")))
        output = os.path.join(tmp, "python.exr")
        client = [sys.executable, a.client, a.scene, "--coordinator", address, "--token-file", token,
                  "--stubs", a.stubs, "--res", "32x32", "--photons", "5000", "--k", "20", "--stride", "2",
                  "--rounds", "3", "--interval", "0.05", "--timeout", "10"]
        if a.tls:
            # Plaintext against the TLS coordinator: refused in the handshake, exit 1, nothing submitted.
            r = subprocess.run(client + ["-o", os.path.join(tmp, "plain.exr")], capture_output=True, text=True,
                               timeout=60, env=env)
            print(r.stdout)
            print(r.stderr, file=sys.stderr)
            assert r.returncode == 1, f"a plaintext Python client exited {r.returncode} against a TLS coordinator"
            assert "error: UNAVAILABLE" in r.stderr, r.stderr
            assert not os.path.exists(os.path.join(tmp, "plain.exr"))
        r = subprocess.run(client + client_tls + ["-o", output], capture_output=True, text=True, timeout=90,
                           env=env)
        print(r.stdout)
        print(r.stderr, file=sys.stderr)
        assert r.returncode == 0, f"pf_client.py exited {r.returncode}"
        job_id = r.stdout.strip().splitlines()[-1]
        snapshots = int(re.findall(r"(\d+) snapshots ->", r.stdout)[-1])
        assert snapshots >= 1, "no image snapshot arrived"
        ref = os.path.join(tmp, "pf-get.exr")
        pf_tls = ["--tls-ca", tls["ca.pem"]] if a.tls else []
        g = subprocess.run([a.pf, "get", job_id, "-o", ref, "--coordinator", address, "--token-file", token] + pf_tls,
                           capture_output=True, text=True, timeout=30, env=env)
        assert g.returncode == 0, g.stderr
        with open(output, "rb") as f1, open(ref, "rb") as f2:
            b1, b2 = f1.read(), f2.read()
        assert b1[:4] == b"\x76\x2f\x31\x01", "not an OpenEXR file"
        assert b1 == b2, "the Python client's image differs from pf get's"
        ok = True
        print(f"ok: job {job_id}, {snapshots} snapshots, {len(b1)} bytes, identical to pf get"
              + (" (TLS + mTLS; plaintext refused)" if a.tls else ""))
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
