#!/usr/bin/env bash
# Self-contained test of deploy/slurm/pf-worker.sbatch on this machine (deploy/README.md). As root it
# brings up munge, slurmctld and slurmd (one node: this host and its CPUs, Slurm state in a
# temporary folder), starts a pf-coordinator on loopback, submits a render job, runs the
# workers as a Slurm job array, cancels one array element mid-job (scancel JOB_INDEX), and checks
# that the farm's image is bit-identical to `pf render --local-only` with the same settings.
# Everything it started is stopped again, on success and on failure.
#
#   sudo deploy/slurm/slurm_array_test.sh                 # binaries from ./build
#   PF_BUILD_DIR=/path/to/build deploy/slurm/slurm_array_test.sh
#   PF_KEEP=1 ...                                         # keep the temporary folder (logs)
#
# Needs Debian's slurm-wlm and munge (tools/install-deps.sh --slurm). Exit 0 pass, 1 fail,
# 77 skipped (not root, or Slurm/munge missing).
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
build=${PF_BUILD_DIR:-$repo/build}
pf=$build/client/pf
coordinator_bin=$build/server/pf-coordinator
worker_bin=$build/worker/pf-worker
scene=$repo/scenes/cornell-box/cornell-box.json

log() { echo "slurm-test: $*" >&2; }
fail() { log "FAIL: $*"; exit 1; }

[ "$(id -u)" -eq 0 ] || { log "skipped: must run as root (starts munged, slurmctld, slurmd)"; exit 77; }
for c in munged mungekey slurmctld slurmd sbatch squeue scancel scontrol; do
  command -v "$c" > /dev/null || { log "skipped: $c missing (apt-get install slurm-wlm munge)"; exit 77; }
done
for b in "$pf" "$coordinator_bin" "$worker_bin"; do [ -x "$b" ] || fail "$b not built (PF_BUILD_DIR=$build)"; done

tmp=$(mktemp -d /tmp/pf-slurm-test.XXXXXX)
chmod 755 "$tmp"
pids=()
munged_pid=""
array_job=""
cleanup() {
  local rc=$?
  set +e
  if [ -n "$array_job" ]; then
    # Let slurmd end the array's steps (slurmstepd) before slurmd itself goes: none outlive it.
    scancel "$array_job" 2> /dev/null
    for _ in $(seq 300); do
      [ -z "$(squeue -h -j "$array_job" 2> /dev/null)" ] && break
      sleep 0.1
    done
  fi
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null; done
  for p in "${pids[@]}"; do
    for _ in $(seq 150); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    kill -9 "$p" 2> /dev/null
  done
  if [ -n "$munged_pid" ]; then kill "$munged_pid" 2> /dev/null; fi
  if [ $rc -ne 0 ] || [ "${PF_KEEP:-0}" = 1 ]; then
    log "logs kept in $tmp"
    tail -n 5 "$tmp"/*.log 2> /dev/null | sed 's/^/  /' >&2
  else
    rm -rf "$tmp"
  fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 1' INT TERM

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...
  local seconds=$1 what=$2; shift 2
  local deadline=$((SECONDS + seconds))
  until "$@"; do
    [ $SECONDS -lt $deadline ] || fail "timed out after ${seconds}s waiting for $what"
    sleep 0.2
  done
}

# --- munge: its own key and socket in $tmp, so a munged already running here is not touched.
mkdir -p "$tmp/munge"
chmod 700 "$tmp/munge"
mungekey --create --keyfile="$tmp/munge/munge.key" --force
chmod 600 "$tmp/munge/munge.key"
mkdir -p /run/munge
munge_socket=$tmp/munge/munge.socket
munged --force --key-file="$tmp/munge/munge.key" --socket="$munge_socket" \
  --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munge/seed"
wait_for 10 "munged" test -s "$tmp/munge/munged.pid"
munged_pid=$(cat "$tmp/munge/munged.pid")

# --- slurm.conf: one node, this host with its CPUs, loopback address, fresh ports.
node=$(hostname -s)
cpus=$(nproc)
mkdir -p "$tmp/state" "$tmp/spool"
cat > "$tmp/slurm.conf" << CONF
ClusterName=pftest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge_socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
ReturnToService=2
KillWait=10
SlurmdTimeout=60
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=pftest Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$tmp/slurm.conf
slurmctld -D -i -f "$SLURM_CONF" > "$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N "$node" -f "$SLURM_CONF" > "$tmp/slurmd.out" 2>&1 &
pids+=($!)
node_idle() { scontrol show node "$node" 2> /dev/null | grep -q "State=IDLE"; }
wait_for 60 "node $node IDLE in slurmctld" node_idle
log "slurm up: node $node, $cpus CPUs"

# --- the coordinator on loopback, and the job.
"$coordinator_bin" --listen 127.0.0.1:0 --data-dir "$tmp/data" --lease-seconds 5 > "$tmp/coordinator.out" \
  2> "$tmp/coordinator.log" &
pids+=($!)
wait_for 30 "pf-coordinator" grep -q "listening on" "$tmp/coordinator.out"
address=$(sed -n 's/^listening on //p' "$tmp/coordinator.out")
export PF_COORDINATOR=$address
log "coordinator $address"

# 16 tasks of ~0.3-1 s each on one CPU: long enough to cancel a worker in the middle.
job_flags=(--integrator photonmap --photons 60000 --k 50 --plan skipping --stride 2 --rounds 4 --spp 2
           --res 48x48 --seed 42)
job_id=$("$pf" submit "$scene" "${job_flags[@]}" 2> "$tmp/submit.log")
log "submitted $job_id"

# --- the workers: one array element per CPU, plus one that waits for a free CPU (it starts when
# the cancelled element's CPU is released).
elements=$((cpus + 1))
array_job=$(cd "$tmp" && PF_WORKER_BIN=$worker_bin PF_CACHE_DIR=$tmp \
  sbatch --parsable --array=0-$((elements - 1)) --output="$tmp/worker-%a.log" "$here/pf-worker.sbatch")
array_job=${array_job%%;*}
log "sbatch array $array_job with $elements elements"
running() { [ "$(squeue -h -j "$array_job" -t RUNNING | wc -l)" -ge 1 ]; }
wait_for 60 "a running array element" running

# Cancel element 1 once it holds a task (its log says it leased one that it has not finished).
mid_task() { grep -q "leased job=" "$tmp/worker-1.log" 2> /dev/null; }
wait_for 120 "array element 1 to lease a task" mid_task
scancel "${array_job}_1"
log "cancelled ${array_job}_1 mid-job"
gone() { ! squeue -h -j "${array_job}_1" 2> /dev/null | grep -q .; }
wait_for 60 "element 1 to leave the queue" gone

# --- the job completes without element 1.
"$pf" watch "$job_id" -q -o "$tmp/farm.exr" --timeout 30 > "$tmp/watch.out" 2> "$tmp/watch.log" ||
  fail "pf watch: $(cat "$tmp/watch.out" "$tmp/watch.log")"
grep -q "succeeded" "$tmp/watch.out" || fail "job did not succeed: $(cat "$tmp/watch.out")"
"$pf" events "$job_id" > "$tmp/events.txt"
"$pf" workers > "$tmp/workers.txt"
cat "$tmp/workers.txt" >&2
grep -q "slurm-${array_job}_1@" "$tmp/events.txt" || fail "element 1 never ran a task: $(cat "$tmp/events.txt")"
grep "slurm-${array_job}_1@" "$tmp/events.txt" | grep -Eq "failed|expired|merged" ||
  fail "element 1's task has no ending event"
grep -q "SIGTERM" "$tmp/worker-1.log" || fail "element 1 did not get SIGTERM: $(tail "$tmp/worker-1.log")"

# --- bit-identical to the local render with the same seed and settings.
"$pf" render "$scene" "${job_flags[@]}" --local-only -q --no-png -o "$tmp/local.exr" 2> "$tmp/local.log"
diff_json=$("$pf" diff "$tmp/farm.exr" "$tmp/local.exr" --json)
python3 - "$diff_json" << 'PY' || fail "farm image differs from the local render: $diff_json"
import json, sys
d = json.loads(sys.argv[1])
sys.exit(0 if d["max_abs_error"] == 0 and d["rmse"] == 0 and d["pixels"] == 48 * 48 else 1)
PY
log "PASS: job $job_id through Slurm array $array_job ($elements workers, ${array_job}_1 cancelled mid-job)," \
  "image bit-identical to the local render"
