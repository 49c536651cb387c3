#!/usr/bin/env python3
"""Runs every command of the README's "Using `pf`" block, in order, as written (docs/farm.md, 'Command-line contract').

Only what a reader would fill in is substituted: `build/` becomes the build tree, `scenes/` the
source tree's scenes, ADDR a pf-coordinator started here on loopback with two pf-workers (as the
README's comment line describes), JOB the id the `pf submit` line printed. Outputs land in a
temporary folder. Every command must exit 0; then the images are checked for what the examples
promise: the office3 view shows the room (not a blank wall), pf diff compares equal sizes, pf
info reads the farm image's header.

  tests/readme/readme_examples_test.py --build build --source .
"""
import argparse
import os
import re
import shlex
import struct
import subprocess
import sys
import tempfile
import time
import zlib


def readme_commands(readme_path):
    text = open(readme_path, encoding="utf-8").read()
    section = text[text.index("## Using `pf`"):]
    block = section[section.index("```sh\n") + 6:]
    block = block[:block.index("```")]
    commands, pending = [], ""
    for line in block.splitlines():
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        line = pending + line
        pending = ""
        tokens = shlex.split(line, comments=True)
        if tokens:
            commands.append(tokens)
    return commands


def read_png_luminance(path):
    """8-bit RGB/RGBA PNG (what pf writes) -> list of luminance values."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, width, height, channels = 8, b"", 0, 0, 3
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and colour in (2, 6), (depth, colour)
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = width * channels
    prev = bytearray(stride)
    lum = []
    for y in range(height):
        f = raw[y * (stride + 1)]
        row = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = row[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                row[i] = (row[i] + a) & 255
            elif f == 2:
                row[i] = (row[i] + b) & 255
            elif f == 3:
                row[i] = (row[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                row[i] = (row[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        for x in range(width):
            r, g, bl = row[x * channels:x * channels + 3]
            lum.append(0.2126 * r + 0.7152 * g + 0.0722 * bl)
        prev = row
    return lum


def stddev(values):
    mean = sum(values) / len(values)
    return (sum((v - mean) ** 2 for v in values) / len(values)) ** 0.5


def block_spread(png):
    """Standard deviation of the 8 x 8 block means of a PNG's luminance: structure, not noise."""
    data = open(png, "rb").read()
    width, height = struct.unpack(">II", data[16:24])
    lum = read_png_luminance(png)
    means = []
    for by in range(8):
        for bx in range(8):
            block = [lum[y * width + x] for y in range(by * height // 8, (by + 1) * height // 8)
                     for x in range(bx * width // 8, (bx + 1) * width // 8)]
            means.append(sum(block) / len(block))
    return stddev(means)


def camera_problems(build, argv, shown):
    """A hand-placed camera (--eye, --look-at) must stand and look inside the scene's bounds:
    the old office3 example looked at a point outside the building and saw one wall."""
    info = subprocess.run([os.path.join(build, "client/pf"), "info", argv[2]], capture_output=True, text=True)
    m = re.search(r"bounds\s+\(([^)]*)\) \.\. \(([^)]*)\)", info.stdout)
    if not m:
        return [f"{shown}: pf info printed no bounds"]
    lo = [float(v) for v in m.group(1).split(",")]
    hi = [float(v) for v in m.group(2).split(",")]
    problems = []
    for flag in ("--eye", "--look-at"):
        if flag in argv:
            point = [float(v) for v in argv[argv.index(flag) + 1].split(",")]
            if not all(lo[i] < point[i] < hi[i] for i in range(3)):
                problems.append(f"{shown}: {flag} {point} is outside the scene's bounds {lo} .. {hi}")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", required=True)
    ap.add_argument("--source", required=True)
    args = ap.parse_args()
    build, source = os.path.abspath(args.build), os.path.abspath(args.source)
    commands = readme_commands(os.path.join(source, "README.md"))
    assert len(commands) >= 10, commands
    failures = []
    # The examples run without credentials or a default coordinator: unset, not blank (a blank
    # token is a start-up error, docs/security.md).
    clean_env = {k: v for k, v in os.environ.items()
                 if not (k.startswith("PF_") and (k.endswith("TOKEN") or k == "PF_COORDINATOR"))}
    with tempfile.TemporaryDirectory(prefix="pf-readme-") as tmp:
        coordinator = subprocess.Popen(
            [os.path.join(build, "server/pf-coordinator"), "--listen", "127.0.0.1:0", "--data-dir",
             os.path.join(tmp, "farm")], stdout=subprocess.PIPE, stderr=open(os.path.join(tmp, "coordinator.log"), "w"),
            text=True, env=clean_env)
        workers = []
        try:
            m = re.match(r"listening on (\S+)", coordinator.stdout.readline())
            assert m, "pf-coordinator did not start"
            address = m.group(1)
            for i in range(2):
                workers.append(subprocess.Popen(
                    [os.path.join(build, "worker/pf-worker"), "--coordinator", address, "--threads", "1",
                     "--cache-dir", os.path.join(tmp, f"cache-{i}")],
                    stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, f"worker-{i}.log"), "w")))
            job = None
            for tokens in commands:
                argv = []
                for t in tokens:
                    if t.startswith("build/"):
                        t = os.path.join(build, t[len("build/"):])
                    elif t.startswith("scenes/"):
                        t = os.path.join(source, t)
                    elif t == "ADDR":
                        t = address
                    elif t == "JOB":
                        assert job, "JOB used before pf submit"
                        t = job
                    argv.append(t)
                start = time.monotonic()
                r = subprocess.run(argv, cwd=tmp, capture_output=True, text=True, timeout=300,
                                   env=clean_env)
                shown = " ".join(tokens)
                print(f"[{r.returncode}] {time.monotonic() - start:6.1f} s  {shown}", flush=True)
                if r.returncode != 0:
                    failures.append(f"{shown}: exit {r.returncode}\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
                    continue
                if tokens[1] == "render" and "--eye" in tokens:
                    failures += camera_problems(build, argv, shown)
                if tokens[1] == "submit":
                    job = r.stdout.strip()
                if tokens[1] == "diff" and "RMSE" not in r.stdout:
                    failures.append(f"{shown}: no RMSE in {r.stdout!r}")
                if tokens[1] == "info" and tokens[2].endswith(".exr"):
                    for key in ("seed", "integrator", "camera.eye", "version", "date"):
                        if key not in r.stdout:
                            failures.append(f"{shown}: no {key} in\n{r.stdout}")
                if tokens[1] == "events" and "merged" not in r.stdout:
                    failures.append(f"{shown}: no merged task in\n{r.stdout}")
            # The office3 example shows the room: light, shade and furniture, not one flat wall.
            office = os.path.join(tmp, "office3.png")
            if os.path.exists(office):
                spread = block_spread(office)
                print(f"office3.png: standard deviation of its 8x8 block means {spread:.1f} (of 255)")
                if spread < 5:
                    failures.append(f"office3.png is nearly uniform ({spread:.1f}): a blank wall?")
            else:
                failures.append("office3.png was not written")
        finally:
            for p in workers + [coordinator]:
                p.terminate()
            for p in workers + [coordinator]:
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
    if failures:
        print("FAILED:\n" + "\n".join(failures), file=sys.stderr)
        return 1
    print(f"all {len(commands)} README commands ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
