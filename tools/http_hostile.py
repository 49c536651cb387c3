#!/usr/bin/env python3
"""Hostile clients against a coordinator's status page, with the coordinator's memory.

Starts COORDINATOR (a pf-coordinator binary) with a client token and --http on loopback, then:
  body      two 400 MiB POSTs without a token (Content-Length, the body streamed after the head)
  slow N    N connections that send a request head one header line a second, and meanwhile five
            authenticated GETs with a 3 s timeout
and prints what came back, how long it took, and VmRSS/VmHWM of the coordinator before and after
(docs/security.md, "The web status page"). Usage:
  tools/http_hostile.py build/server/pf-coordinator body
  tools/http_hostile.py build/server/pf-coordinator slow 50
"""
import os
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

TOKEN = "hostile-test-token"


def memory(pid):
    status = open(f"/proc/{pid}/status").read()
    return {k: int(re.search(k + r":\s+(\d+)", status).group(1)) // 1024 for k in ("VmRSS", "VmHWM")}


def bodies(port):
    for _ in range(2):
        s = socket.create_connection(("127.0.0.1", port))
        start = time.time()
        s.sendall(b"POST /api/status HTTP/1.1\r\nHost: x\r\nContent-Length: 419430400\r\n\r\n")
        s.settimeout(10)
        sent, chunk = 0, b"a" * (1 << 20)
        try:
            while sent < 400 << 20:
                sent += s.send(chunk)
        except OSError as e:
            print("  body refused:", e)
        try:
            print("  answer:", s.recv(64).split(b"\r\n")[0].decode())
        except OSError as e:
            print("  no answer:", e)
        print(f"  {sent >> 20} MiB of the body taken in {time.time() - start:.2f} s")
        s.close()


def slow(port, n):
    socks = []
    for _ in range(n):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
        socks.append(s)
    stop = threading.Event()

    def trickle():
        while not stop.is_set():
            for s in socks:
                try:
                    s.send(b"X-Slow: 1\r\n")
                except OSError:
                    pass
            stop.wait(1)

    t = threading.Thread(target=trickle)
    t.start()
    for _ in range(5):
        start = time.time()
        req = urllib.request.Request(f"http://127.0.0.1:{port}/api/status",
                                     headers={"Authorization": "Bearer " + TOKEN})
        try:
            r = urllib.request.urlopen(req, timeout=3)
            print(f"  GET {r.status} in {time.time() - start:.3f} s")
        except Exception as e:  # noqa: BLE001 - the outcome is what we report
            print(f"  GET failed after {time.time() - start:.3f} s: {e}")
        time.sleep(0.5)
    stop.set()
    t.join()


def main():
    if len(sys.argv) < 3 or sys.argv[2] not in ("body", "slow"):
        sys.exit(__doc__)
    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "token"), "w") as f:
            f.write(TOKEN + "\n")
        p = subprocess.Popen([sys.argv[1], "--data-dir", os.path.join(d, "data"), "--client-token-file",
                              os.path.join(d, "token"), "--http", "127.0.0.1:0"],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            p.stdout.readline()
            port = int(p.stdout.readline().split()[2].rsplit(":", 1)[1])
            print("before:", memory(p.pid))
            if sys.argv[2] == "body":
                bodies(port)
            else:
                slow(port, int(sys.argv[3]) if len(sys.argv) > 3 else 50)
            time.sleep(0.5)
            print("after: ", memory(p.pid))
        finally:
            p.kill()
            p.wait()


if __name__ == "__main__":
    main()
