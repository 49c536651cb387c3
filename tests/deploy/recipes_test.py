#!/usr/bin/python3
"""CTest deploy.*: the deployment recipes of deploy/README.md, started as they are written.

Each recipe is read from its file, not restated here, and run on this machine with real
processes, TLS, mTLS and both bearer tokens (deploy/make-credentials.sh):

  --recipe slurm-head  the shell block after `<!-- recipe: slurm-head -->` in deploy/README.md,
                       run by bash; `sbatch` stands in for Slurm by running the array script
                       itself for two elements (deploy/slurm/slurm_array_test.sh runs real Slurm).
  --recipe systemd     deploy/systemd/*.service: `systemd-analyze verify` in a scratch root, then
                       the coordinator's and two workers' ExecStart= lines with their
                       EnvironmentFile=, after the make-credentials line of the unit's header.
  --recipe compose     deploy/container/compose.yaml: the coordinator's and the workers' `command`
                       (replicas of them), with the compose file's secrets as files.

What is changed, and only this, to run on one machine beside other tests: absolute paths of the
recipe (/etc/photonfarm, /var/lib/photonfarm, /usr/local/bin, /run/secrets, /data, /cache) map into a
scratch folder or the build tree, the ports 7000 and 8080 become free ports, the compose service
name and `hostname -f` become localhost. Then a small job is submitted with the client
credentials the recipe made, must succeed, and its image must equal a local render bit for bit;
SIGTERM must stop every process with exit 0. Exit 0 pass, 1 fail."""
import argparse
import json
import os
import random
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

import yaml


class Failure(Exception):
    pass


def free_port(taken=()):
    """A port no one listens on, below the kernel's ephemeral range: a recipe's ports are fixed
    in its files before its coordinator starts (seconds later, after make-credentials), and a port
    from that range could meanwhile go to another test's coordinator on port 0 — gRPC binds with
    SO_REUSEPORT, so both would listen and loopback calls would reach the other one."""
    with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
        low = int(f.read().split()[0])
    rng = random.Random()
    for _ in range(1000):
        port = rng.randrange(max(1024, low - 12000), low)
        if port in taken:
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("0.0.0.0", port))
            except OSError:
                continue
        return port
    raise Failure("no free port below the ephemeral range")


def wait_for(what, predicate, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.1)
    raise Failure("timed out waiting for " + what)


class Farm:
    """The processes a recipe started, their logs, and the checks every recipe ends with."""

    def __init__(self, args, tmp):
        self.args, self.tmp, self.procs = args, tmp, []
        self.port = free_port()
        self.http_port = free_port(taken=(self.port,))

    def binary(self, name):
        return {"pf": os.path.join(self.args.build, "client", "pf"),
                "pf-coordinator": os.path.join(self.args.build, "server", "pf-coordinator"),
                "pf-worker": os.path.join(self.args.build, "worker", "pf-worker")}[name]

    def start(self, name, argv, env=None):
        log = open(os.path.join(self.tmp, name + ".log"), "w")
        p = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=self.tmp)
        self.procs.append((name, p))
        return p

    def log(self, name):
        with open(os.path.join(self.tmp, name + ".log")) as f:
            return f.read()

    def wait_listening(self, name):
        wait_for(name + " to listen", lambda: "listening on" in self.log(name), 30)

    def check_job(self, client_env):
        """A small job through the recipe's client credentials: it succeeds, and its image is the
        local render's bit for bit."""
        pf = self.binary("pf")
        flags = ["--integrator", "photonmap", "--photons", "20000", "--k", "30", "--spp", "2",
                 "--res", "24x24", "--seed", "5", "--plan", "skipping", "--stride", "2"]
        scene = os.path.join(self.args.source, "scenes", "cornell-box", "cornell-box.json")
        submit = subprocess.run([pf, "submit", scene] + flags, env=client_env, capture_output=True,
                                text=True, timeout=120, cwd=self.tmp)
        if submit.returncode != 0:
            raise Failure("pf submit: " + submit.stderr)
        job = submit.stdout.strip().split()[-1]
        farm_exr, local_exr = os.path.join(self.tmp, "farm.exr"), os.path.join(self.tmp, "local.exr")
        watch = subprocess.run([pf, "watch", job, "-q", "-o", farm_exr, "--timeout", "60"], env=client_env,
                               capture_output=True, text=True, timeout=180, cwd=self.tmp)
        if watch.returncode != 0 or "succeeded" not in watch.stdout:
            raise Failure("pf watch: " + watch.stdout + watch.stderr)
        subprocess.run([pf, "render", scene] + flags + ["--local-only", "-q", "--no-png", "-o", local_exr],
                       check=True, capture_output=True, timeout=180, cwd=self.tmp)
        diff = subprocess.run([pf, "diff", farm_exr, local_exr, "--json"], capture_output=True, text=True,
                              timeout=60, cwd=self.tmp)
        d = json.loads(diff.stdout)
        if d["max_abs_error"] != 0 or d["rmse"] != 0 or d["pixels"] != 24 * 24:
            raise Failure("the farm image differs from the local render: " + diff.stdout)
        # A client without the token is refused: the recipe's coordinator is not open.
        anonymous = {k: v for k, v in client_env.items() if k not in ("PF_TOKEN_FILE", "PF_TOKEN")}
        listing = subprocess.run([pf, "list"], env=anonymous, capture_output=True, text=True, timeout=60,
                                 cwd=self.tmp)
        if listing.returncode == 0 or "UNAUTHENTICATED" not in listing.stderr:
            raise Failure("a client without the token was not refused: " + listing.stderr)
        print("job " + job + ": succeeded, bit-identical to the local render")

    def stop(self, check=True):
        stop_processes(self.procs, self.log, check)


def stop_processes(procs, log, check=True):
    """SIGTERM to every (name, Popen) of `procs`, workers before the coordinator; each must exit 0
    (`log(name)`: its log, quoted when it did not)."""
    problems = []
    for name, p in sorted(procs, key=lambda np: "coordinator" in np[0]):
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
        try:
            rc = p.wait(timeout=90)
        except subprocess.TimeoutExpired:
            p.kill()
            rc = "hung"
        if rc != 0:
            problems.append("%s exited %s:\n%s" % (name, rc, log(name)[-3000:]))
    if check and problems:
        raise Failure("\n".join(problems))


def env_file(path):
    values = {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                key, _, value = line.partition("=")
                values[key] = value
    return values


def base_env():
    env = {k: v for k, v in os.environ.items() if not k.startswith("PF_")}
    return env


def make_credentials(farm, folder, host):
    subprocess.run([os.path.join(farm.args.source, "deploy", "make-credentials.sh"), "--port", str(farm.port),
                    "--http-port", str(farm.http_port), folder, host], check=True, capture_output=True,
                   timeout=120)


def run_in_background_and_wait_epilogue(pids_file):
    """Bash lines after a recipe block: record the jobs it left running, forward SIGTERM to them,
    and exit with the first non-zero status among them (0 when every one stopped cleanly)."""
    return """
pids=$(jobs -p); echo $pids > "%s"
trap 'kill -TERM $pids 2>/dev/null' TERM
status=0
for pid in $pids; do
  while :; do wait $pid; rc=$?; kill -0 $pid 2>/dev/null || break; done
  [ $rc -eq 0 ] || status=$rc
done
exit $status
""" % pids_file


def recipe_slurm_head(farm):
    with open(os.path.join(farm.args.source, "deploy", "README.md")) as f:
        text = f.read()
    m = re.search(r"<!-- recipe: slurm-head -->\s*```sh\n(.*?)```", text, re.S)
    if not m:
        raise Failure("deploy/README.md has no block after <!-- recipe: slurm-head -->")
    # The README's own example submission is left out: the check submits a smaller job.
    lines = [l for l in m.group(1).splitlines() if not l.lstrip().startswith("build/client/pf ")]
    block = "\n".join(lines)
    block = block.replace("deploy/make-credentials.sh",
                          "deploy/make-credentials.sh --port %d --http-port %d" % (farm.port, farm.http_port))
    build = farm.args.build.rstrip("/") + "/"
    block = re.sub(r"(\$PWD/|(?<![\w/.$-]))build/", lambda _: build, block)
    # Slurm's stand-in: the array script itself for elements 0 and 1, in the background.
    prelude = """set -uo pipefail
hostname() { echo localhost; }
sbatch() {
  local script=${@: -1} i
  for i in 0 1; do
    SLURM_ARRAY_JOB_ID=77 SLURM_ARRAY_TASK_ID=$i PF_CACHE_DIR="%s" bash "$script" > "%s/worker-$i.log" 2>&1 &
  done
}
cd "%s"
""" % (farm.tmp, farm.tmp, farm.args.source)
    client_env_file = os.path.join(farm.tmp, "client-env")
    script = (prelude + block + "\nenv | grep '^PF_' > '%s'\n" % client_env_file +
              run_in_background_and_wait_epilogue(os.path.join(farm.tmp, "pids")))
    env = base_env()
    env["HOME"] = farm.tmp
    farm.start("recipe", ["bash", "-c", script], env=env)
    wait_for("the recipe's client environment", lambda: os.path.exists(client_env_file), 60)
    wait_for("the recipe's coordinator", lambda: "listening on" in farm.log("recipe"), 30)
    client_env = base_env()
    client_env.update(env_file(client_env_file))
    farm.check_job(client_env)
    for i in (0, 1):
        if "completed job=" not in open(os.path.join(farm.tmp, "worker-%d.log" % i)).read():
            print("note: array element %d ran no task (the other was faster)" % i)


def map_paths(text, mapping):
    for prefix, target in mapping:
        text = text.replace(prefix, target)
    return text


def recipe_systemd(farm):
    units = os.path.join(farm.args.source, "deploy", "systemd")
    root = os.path.join(farm.tmp, "root")
    etc = os.path.join(root, "etc", "photonfarm")
    mapping = [("/etc/photonfarm", etc),
               ("/var/lib/photonfarm", os.path.join(root, "var", "lib", "photonfarm")),
               ("/var/cache/photonfarm", os.path.join(root, "var", "cache", "photonfarm")),
               ("/usr/local/bin/pf-coordinator", farm.binary("pf-coordinator")),
               ("/usr/local/bin/pf-worker", farm.binary("pf-worker"))]
    text = open(os.path.join(units, "pf-coordinator.service")).read()
    m = re.search(r"^#\s+sudo (deploy/make-credentials\.sh .*)$", text, re.M)
    if not m:
        raise Failure("pf-coordinator.service's header has no make-credentials line")
    argv = shlex.split(m.group(1).replace('"$(hostname -f)"', "localhost"))
    subprocess.run([os.path.join(farm.args.source, argv[0]), "--port", str(farm.port), "--http-port",
                    str(farm.http_port)] + [map_paths(a, mapping) for a in argv[1:]], check=True,
                   capture_output=True, timeout=120)

    # systemd's own check of the units, in a scratch root holding the binaries they start.
    analyze = shutil.which("systemd-analyze")
    if not analyze:
        raise Failure("systemd-analyze is missing (tools/install-deps.sh installs systemd)")
    os.makedirs(os.path.join(root, "usr", "local", "bin"))
    for name in ("pf-coordinator", "pf-worker"):
        shutil.copy(farm.binary(name), os.path.join(root, "usr", "local", "bin", name))
    system = next(d for d in ("/usr/lib/systemd/system", "/lib/systemd/system") if os.path.isdir(d))
    shutil.copytree(system, os.path.join(root, "usr", "lib", "systemd", "system"), symlinks=True)
    os.makedirs(os.path.join(root, "etc", "systemd", "system"))
    for unit in ("pf-coordinator.service", "pf-worker@.service"):
        shutil.copy(os.path.join(units, unit), os.path.join(root, "etc", "systemd", "system", unit))
    verify = subprocess.run([analyze, "verify", "--root=" + root, "pf-coordinator.service", "pf-worker@1.service"],
                            capture_output=True, text=True, timeout=120, cwd=farm.tmp)
    if verify.returncode != 0 or verify.stderr.strip() or verify.stdout.strip():
        raise Failure("systemd-analyze verify: " + verify.stdout + verify.stderr)

    def service(unit):
        section, values = None, {}
        for line in open(os.path.join(units, unit)):
            line = line.strip()
            if line.startswith("["):
                section = line
            elif section == "[Service]" and "=" in line and not line.startswith("#"):
                key, _, value = line.partition("=")
                values[key] = value
        return values

    def exec_start(values, instance):
        env = base_env()
        if "EnvironmentFile" in values:
            env.update(env_file(map_paths(values["EnvironmentFile"], mapping)))
        line = values["ExecStart"].replace("%i", instance).replace("%H", "localhost")
        line = re.sub(r"\$\{(\w+)\}", lambda v: env[v.group(1)], line)
        for key in ("StateDirectory", "CacheDirectory"):
            if key in values:
                base = {"StateDirectory": "/var/lib/", "CacheDirectory": "/var/cache/"}[key]
                os.makedirs(map_paths(base + values[key].replace("%i", instance), mapping), exist_ok=True)
        return [map_paths(a, mapping) for a in shlex.split(line)], env

    argv, env = exec_start(service("pf-coordinator.service"), "")
    farm.start("coordinator", argv, env)
    farm.wait_listening("coordinator")
    for i in ("1", "2"):
        argv, env = exec_start(service("pf-worker@.service"), i)
        farm.start("worker-" + i, argv, env)
    client_env = base_env()
    client_env.update(env_file(os.path.join(etc, "client.env")))
    farm.check_job(client_env)


def recipe_compose(farm):
    folder = os.path.join(farm.args.source, "deploy", "container")
    compose = yaml.safe_load(open(os.path.join(folder, "compose.yaml")))
    text = open(os.path.join(folder, "compose.yaml")).read()
    m = re.search(r"^#\s+(deploy/make-credentials\.sh \S+)\s*$", text, re.M)
    if not m:
        raise Failure("compose.yaml's header has no make-credentials line")
    credentials = os.path.join(farm.tmp, "credentials")
    make_argv = shlex.split(m.group(1))
    if make_argv[1] != "deploy/container/credentials":
        raise Failure("compose.yaml makes its credentials elsewhere than its secrets read them: " + m.group(1))
    subprocess.run([os.path.join(farm.args.source, make_argv[0]), "--port", str(farm.port), "--http-port",
                    str(farm.http_port), credentials], check=True, capture_output=True, timeout=120)
    secret_files = {}
    for name, spec in compose["secrets"].items():
        if not spec["file"].startswith("./credentials/"):
            raise Failure("secret %s is not a file of the credentials folder: %s" % (name, spec["file"]))
        secret_files["/run/secrets/" + name] = os.path.join(credentials, spec["file"][len("./credentials/"):])

    def command(service_name, index):
        service = compose["services"][service_name]
        argv = []
        for a in service["command"]:
            for path in re.findall(r"/run/secrets/[\w.-]+", a):
                if path[len("/run/secrets/"):] not in service.get("secrets", []):
                    raise Failure("%s reads %s, a secret it is not given" % (service_name, path))
            a = map_paths(a, sorted(secret_files.items(), key=lambda kv: -len(kv[0])))
            if a == "/data":
                a = os.path.join(farm.tmp, "data")
            elif a == "/cache":
                a = os.path.join(farm.tmp, "cache-%d" % index)
            a = a.replace("coordinator:7000", "localhost:%d" % farm.port)
            a = a.replace(":7000", ":%d" % farm.port).replace(":8080", ":%d" % farm.http_port)
            argv.append(a)
        argv[0] = farm.binary(argv[0])
        return argv

    published = compose["services"]["coordinator"]["ports"]
    if "127.0.0.1:7000:7000" not in published or "127.0.0.1:8080:8080" not in published:
        raise Failure("the coordinator's ports are not published on loopback as documented: %s" % published)
    farm.start("coordinator", command("coordinator", 0), base_env())
    farm.wait_listening("coordinator")
    for i in range(compose["services"]["worker"]["deploy"]["replicas"]):
        farm.start("worker-%d" % i, command("worker", i), base_env())
    client_env = base_env()
    client_env.update(env_file(os.path.join(credentials, "client.env")))
    farm.check_job(client_env)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--recipe", required=True, choices=["slurm-head", "systemd", "compose"])
    args = ap.parse_args()
    args.build, args.source = os.path.abspath(args.build), os.path.abspath(args.source)
    tmp = tempfile.mkdtemp(prefix="pf-deploy-" + args.recipe + "-")
    farm = Farm(args, tmp)
    try:
        {"slurm-head": recipe_slurm_head, "systemd": recipe_systemd, "compose": recipe_compose}[args.recipe](farm)
        farm.stop()
    except Exception as e:  # noqa: BLE001 - every failure is reported with the logs kept
        farm.stop(check=False)
        print("FAIL: %s\n(logs kept in %s)" % (e, tmp), file=sys.stderr)
        return 1
    shutil.rmtree(tmp, ignore_errors=True)
    print("PASS: recipe " + args.recipe)
    return 0


if __name__ == "__main__":
    sys.exit(main())
