#!/usr/bin/python3
"""CTest deploy.multihost: a coordinator and two workers on separate hosts, with TLS, mTLS and both
bearer tokens, and worker links cut mid-task (deploy/README.md, "Across hosts").

The hosts are Linux network namespaces joined by a bridge in a fifth namespace (the switch), each
host's link a veth pair whose switch end is its cable:

  coordinator 198.18.0.1   worker-a 198.18.0.2   worker-b 198.18.0.3   client 198.18.0.4

198.18.0.0/15 is the range RFC 2544 sets aside for network tests; it exists only inside the
namespaces this test makes, and they are removed when it ends (also when it fails). The
credentials come from deploy/make-credentials.sh with the coordinator's address as its host, and
every process reads the files it wrote (coordinator.toml, worker.env, client.env), as
deploy/README.md's recipes do; only --lease-seconds is shortened, so the partition below outlasts a
lease in seconds rather than minutes.

A 12-task photon-map job runs on the two workers (one thread each) while
  1. worker-a's cable is pulled for 1.5 s (less than a lease) while it renders a task: it finishes
     that task itself, the lease never runs out;
  2. worker-b's cable is pulled for 2.5 leases while it renders a task: `pf workers` on the client
     host shows worker-b lost within two lease periods, its lease runs out and the task is rendered
     again; the cable is put back, worker-b reports its stale result (kept for --report-retry) and
     is live again.
The job must succeed with every task merged exactly once, its image equal bit for bit to a local
render with the same seed, and every process must stop on SIGTERM with exit 0. Packets on a pulled
cable vanish without an error, the harder case for a TCP connection than a refused one.

Needs root (namespaces, veth) and `ip` (iproute2): without them it exits 77, which CTest reports
as skipped, with the reason. Exit 0 pass, 1 fail."""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

from recipes_test import Failure, base_env, env_file, stop_processes, wait_for

LEASE_SECONDS = 8.0
HOSTS = {"coordinator": "198.18.0.1", "worker-a": "198.18.0.2", "worker-b": "198.18.0.3",
         "client": "198.18.0.4"}
JOB_FLAGS = ["--integrator", "photonmap", "--photons", "400000", "--res", "96x96", "--spp", "48", "--seed", "11",
             "--plan", "multiple-maps", "--maps", "12", "--tile", "0"]
TASKS = 12


def ip(*argv, check=True):
    return subprocess.run(["ip"] + list(argv), capture_output=True, text=True, timeout=30, check=check)


class Network:
    """The switch and the hosts; `cable(host, up)` pulls a host's cable at the switch or puts it
    back."""

    def __init__(self):
        tag = "pfmh%d" % os.getpid()
        self.switch = tag + "-sw"
        self.ns = {host: "%s-%d" % (tag, i) for i, host in enumerate(HOSTS)}
        self.made = []

    def up(self):
        ip("netns", "add", self.switch)
        self.made.append(self.switch)
        ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
        ip("-n", self.switch, "link", "set", "br0", "up")
        for i, (host, address) in enumerate(HOSTS.items()):
            ns = self.ns[host]
            ip("netns", "add", ns)
            self.made.append(ns)
            ip("link", "add", "eth0", "netns", ns, "type", "veth", "peer", "name", "port%d" % i, "netns",
               self.switch)
            ip("-n", self.switch, "link", "set", "port%d" % i, "master", "br0", "up")
            ip("-n", ns, "addr", "add", address + "/24", "dev", "eth0")
            ip("-n", ns, "link", "set", "eth0", "up")
            ip("-n", ns, "link", "set", "lo", "up")

    def cable(self, host, up):
        port = "port%d" % list(HOSTS).index(host)
        ip("-n", self.switch, "link", "set", port, "up" if up else "down")

    def down(self):
        for ns in reversed(self.made):
            ip("netns", "del", ns, check=False)

    def argv(self, host, argv):
        return ["ip", "netns", "exec", self.ns[host]] + argv


def remove_stale_namespaces():
    """Namespaces an earlier run left behind when it was killed (CTest's timeout skips `finally`):
    pfmh<pid>-* of a process that no longer exists."""
    listing = ip("netns", "list", check=False).stdout
    for line in listing.splitlines():
        m = re.match(r"(pfmh(\d+)-\S+)", line)
        if m and not os.path.exists("/proc/" + m.group(2)):
            ip("netns", "del", m.group(1), check=False)


def skip_reason():
    if os.geteuid() != 0:
        return "needs root for network namespaces and veth pairs (CI runs as root)"
    if not shutil.which("ip"):
        return "needs `ip` (Debian iproute2; tools/install-deps.sh installs it)"
    # What the test builds, tried once in a namespace of its own: a kernel or container without
    # namespaces, veth or bridges is a reason to skip, said as such, not a failure of the farm.
    probe = "pfmh%d-probe" % os.getpid()
    r = ip("netns", "add", probe, check=False)
    if r.returncode != 0:
        return "cannot make a network namespace here: " + r.stderr.strip()
    try:
        for what, argv in (("a bridge", ["-n", probe, "link", "add", "br0", "type", "bridge"]),
                           ("a veth pair", ["-n", probe, "link", "add", "a0", "type", "veth", "peer", "name", "b0"])):
            r = ip(*argv, check=False)
            if r.returncode != 0:
                return "cannot make %s in a network namespace here: %s" % (what, r.stderr.strip())
    finally:
        ip("netns", "del", probe, check=False)
    return None


class Farm:
    def __init__(self, args, tmp, net):
        self.args, self.tmp, self.net, self.procs = args, tmp, net, []
        self.credentials = os.path.join(tmp, "credentials")

    def binary(self, name):
        sub = {"pf": "client", "pf-coordinator": "server", "pf-worker": "worker"}[name]
        return os.path.join(self.args.build, sub, name)

    def start(self, name, host, argv, env):
        log = open(os.path.join(self.tmp, name + ".log"), "w")
        p = subprocess.Popen(self.net.argv(host, argv), stdout=log, stderr=subprocess.STDOUT, env=env,
                             cwd=self.tmp)
        self.procs.append((name, p))

    def log(self, name):
        with open(os.path.join(self.tmp, name + ".log")) as f:
            return f.read()

    def client_env(self):
        env = base_env()
        env.update(env_file(os.path.join(self.credentials, "client.env")))
        return env

    def pf(self, *argv, timeout=60, check=True):
        r = subprocess.run(self.net.argv("client", [self.binary("pf")] + list(argv)), env=self.client_env(),
                           capture_output=True, text=True, timeout=timeout, cwd=self.tmp)
        if check and r.returncode != 0:
            raise Failure("pf %s: exit %d: %s" % (" ".join(argv), r.returncode, r.stderr))
        return r

    def workers(self):
        return {w["worker_id"]: w for w in json.loads(self.pf("workers", "--json").stdout)}

    def events(self, job):
        return json.loads(self.pf("events", job, "--json").stdout)["events"]

    def busy_task(self, worker, job, seconds):
        """Waits until `worker` renders a task of `job` (and has rendered it for a moment, so the
        cable is pulled mid-task rather than mid-lease-call); returns the task id."""
        deadline = time.time() + seconds
        while time.time() < deadline:
            w = self.workers().get(worker)
            if w and w["busy"] and w["current_job_id"] == job:
                time.sleep(0.3)
                again = self.workers()[worker]
                if again["busy"] and again["current_task_id"] == w["current_task_id"]:
                    return int(w["current_task_id"])
            time.sleep(0.1)
        raise Failure("%s rendered no task of the job within %d s" % (worker, seconds))

    def stop(self, check=True):
        stop_processes(self.procs, self.log, check)


def run(farm):
    net = farm.net
    coordinator = HOSTS["coordinator"]
    subprocess.run([os.path.join(farm.args.source, "deploy", "make-credentials.sh"), farm.credentials, coordinator],
                   check=True, capture_output=True, timeout=120)
    worker_env = base_env()
    worker_env.update(env_file(os.path.join(farm.credentials, "worker.env")))
    if worker_env["PF_COORDINATOR"] != coordinator + ":7000":
        raise Failure("worker.env names %s, not the coordinator host" % worker_env["PF_COORDINATOR"])

    farm.start("coordinator", "coordinator",
               [farm.binary("pf-coordinator"), "--config", os.path.join(farm.credentials, "coordinator.toml"),
                "--data-dir", os.path.join(farm.tmp, "data"), "--lease-seconds", str(LEASE_SECONDS)], base_env())
    wait_for("the coordinator to listen", lambda: "listening on" in farm.log("coordinator"), 30)
    for name in ("worker-a", "worker-b"):
        farm.start(name, name,
                   [farm.binary("pf-worker"), "--coordinator", worker_env["PF_COORDINATOR"], "--worker-id", name,
                    "--threads", "1", "--cache-dir", os.path.join(farm.tmp, "cache-" + name)], worker_env)

    scene = os.path.join(farm.args.source, "scenes", "cornell-box", "cornell-box.json")
    job = farm.pf("submit", scene, *JOB_FLAGS, timeout=120).stdout.strip().split()[-1]
    print("job %s submitted from %s to %s" % (job, HOSTS["client"], coordinator))

    # 1. A cable pulled for less than a lease.
    task_a = farm.busy_task("worker-a", job, 120)
    net.cable("worker-a", False)
    time.sleep(1.5)
    net.cable("worker-a", True)
    print("worker-a's cable pulled for 1.5 s while it rendered task %d" % task_a)

    # 2. A cable pulled for longer than a lease.
    task_b = farm.busy_task("worker-b", job, 120)
    net.cable("worker-b", False)
    pulled = time.time()
    lost_after = None
    while time.time() - pulled < 2.5 * LEASE_SECONDS:
        if lost_after is None and farm.workers()["worker-b"]["lost"]:
            lost_after = time.time() - pulled
        time.sleep(0.2)
    expired_b = [e for e in farm.events(job) if e["kind"] == "expired" and e["task_id"] == task_b]
    net.cable("worker-b", True)
    print("worker-b's cable pulled for %.0f s while it rendered task %d; shown lost after %s s" %
          (2.5 * LEASE_SECONDS, task_b, "%.1f" % lost_after if lost_after is not None else "never"))
    if lost_after is None or lost_after > 2 * LEASE_SECONDS:
        raise Failure("worker-b was not shown lost within two lease periods (%.0f s)" % (2 * LEASE_SECONDS))
    if not expired_b:
        raise Failure("worker-b's lease of task %d did not run out while its cable was pulled" % task_b)

    farm_exr = os.path.join(farm.tmp, "farm.exr")
    watch = farm.pf("watch", job, "-q", "-o", farm_exr, "--timeout", "60", timeout=300, check=False)
    if watch.returncode != 0 or "succeeded" not in watch.stdout:
        raise Failure("pf watch: exit %d: %s%s" % (watch.returncode, watch.stdout, watch.stderr))
    wait_for("worker-b to be live again", lambda: not farm.workers()["worker-b"]["lost"], 60)
    # Its result of the task it lost was kept through the partition and reported, not merged; or,
    # if its render outlasted the partition (a loaded machine), the coordinator told it the lease
    # was gone and it dropped the task. Either way it heard from the coordinator about that task.
    ctx = "job=%s task=%d attempt=1" % (job, task_b)
    wait_for("worker-b to hear that its task %d was taken from it" % task_b,
             lambda: any(ctx in line and ("merged=false" in line or "abandoned" in line)
                         for line in farm.log("worker-b").splitlines()), 60)

    # Nothing lost, nothing counted twice, the short cut survived.
    events = farm.events(job)
    merged = {}
    for e in events:
        if e["kind"] == "merged":
            merged.setdefault(e["task_id"], []).append(e["worker_id"])
    if sorted(merged) != list(range(TASKS)) or any(len(w) != 1 for w in merged.values()):
        raise Failure("tasks merged (task: workers): %s; want each of %d tasks once" % (merged, TASKS))
    if merged[task_a] != ["worker-a"] or any(e["kind"] == "expired" and e["task_id"] == task_a for e in events):
        raise Failure("task %d, whose worker's cable was out for 1.5 s, was not finished by it: %s" %
                      (task_a, [e for e in events if e["task_id"] == task_a]))

    local_exr = os.path.join(farm.tmp, "local.exr")
    subprocess.run([farm.binary("pf"), "render", scene] + JOB_FLAGS + ["--local-only", "-q", "--no-png", "-o",
                   local_exr], check=True, capture_output=True, timeout=600, cwd=farm.tmp)
    diff = subprocess.run([farm.binary("pf"), "diff", farm_exr, local_exr, "--json"], capture_output=True,
                          text=True, timeout=60, cwd=farm.tmp)
    d = json.loads(diff.stdout)
    if d["max_abs_error"] != 0 or d["rmse"] != 0:
        raise Failure("the farm image differs from the local render: " + diff.stdout)
    print("job %s: %d tasks merged once each (task %d by %s after its lease ran out), image bit-identical "
          "to the local render" % (job, TASKS, task_b, merged[task_b][0]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--source", required=True)
    args = ap.parse_args()
    args.build, args.source = os.path.abspath(args.build), os.path.abspath(args.source)
    reason = skip_reason()
    if reason:
        print("SKIP: " + reason)
        return 77
    remove_stale_namespaces()
    tmp = tempfile.mkdtemp(prefix="pf-multihost-")
    net = Network()
    farm = Farm(args, tmp, net)
    try:
        net.up()
        run(farm)
        farm.stop()
    except Exception as e:  # noqa: BLE001 - every failure is reported with the logs kept
        farm.stop(check=False)
        print("FAIL: %s\n(logs kept in %s)" % (e, tmp), file=sys.stderr)
        return 1
    finally:
        net.down()
    shutil.rmtree(tmp, ignore_errors=True)
    print("PASS: coordinator and workers on separate hosts, links cut mid-task")
    return 0


if __name__ == "__main__":
    sys.exit(main())
