#!/usr/bin/env bash
# Runs the SLURM job array of docs/sweeps.md ("Shards: a large sweep on many machines") on a
# real, single-node SLURM started on this machine, and checks what the docs promise:
#
#   1. installs Debian's slurm-wlm and munge (apt-get) when missing;
#   2. starts munged, slurmctld and slurmd as root with a config written under a temp dir
#      (proctrack/pgid, task/none, no accounting; pid, log, state and spool files there);
#   3. runs a small sweep unsharded (the reference), submits it as a 4-task job array
#      (one shard per task, one shared output directory), waits, merges with
#      `xtask sweep-merge` and checks runs.csv and points.csv equal the reference bit for bit
#      (the timing columns `wall_*` aside);
#   4. preemption: submits the array again into a fresh directory, cancels array task 2
#      (`scancel JOB_2`) once it has written a point file, lets the others finish, resubmits
#      task 2 alone (it resumes), merges and checks the result is still exact;
#   5. cancels any job of its own controller still queued, stops the daemons it started (by
#      their pid files) and removes the temp dir.
# Every wait on SLURM has a limit (WAIT_LIMIT); a cancel is checked once its state settled.
#
# Needs root (apt-get, the daemons) and a release build of xtask (built when missing).
# Usage: scripts/slurm-sweep.sh          (about 1–3 min on 2 idle cores; see docs/sweeps.md)
# Env: XTASK=path/to/xtask  KEEP=1 (keep the temp dir)  SLURM_PORT_BASE=16817
#      WAIT_LIMIT=900 (seconds any one wait on SLURM may take before the script fails)
# Every failure ends with a line `FAIL: …` and exit status 1: the checks are explicit, and
# anything else that fails under `set -e` is reported by the ERR trap with its line.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT=$PWD
START=$(date +%s)
say() { printf '[slurm-sweep %3ss] %s\n' "$(($(date +%s) - START))" "$*"; }
# To stderr, so a FAIL inside `$(…)` is seen, not captured.
die() { say "FAIL: $*" >&2; exit 1; }
trap 'rc=$?; say "FAIL: line $LINENO: \`$BASH_COMMAND\` exited with status $rc"; exit 1' ERR
WAIT_LIMIT=${WAIT_LIMIT:-900}
case $WAIT_LIMIT in '' | *[!0-9]*) die "WAIT_LIMIT=$WAIT_LIMIT is not a number of seconds" ;; esac

[ "$(id -u)" = 0 ] || die "needs root: it installs packages and starts munged, slurmctld, slurmd"

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    say "installing slurm-wlm and munge with apt-get"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq slurm-wlm munge >/dev/null
fi
say "$(slurmctld -V)"

XTASK=${XTASK:-$ROOT/target/release/xtask}
if [ ! -x "$XTASK" ]; then
    say "building the release xtask"
    cargo build -p xtask --release
fi

TMP=$(mktemp -d /tmp/slurm-sweep.XXXXXX)
chmod 700 "$TMP"
mkdir -p "$TMP/state" "$TMP/spool" "$TMP/out" "$TMP/munge"
PIDS=()
cleanup() {
    local rc=$?
    # Jobs still queued on this script's private controller (a failed wait): cancel them
    # first, so no job step outlives the daemons.
    if [ -s "$TMP/slurmctld.pid" ] && [ -n "${SLURM_CONF:-}" ]; then
        scancel --partition=ci 2>/dev/null || true
        sleep 1
    fi
    # Stop only the daemons this script started, by their pid files.
    for f in "$TMP/slurmd.pid" "$TMP/slurmctld.pid" "$TMP/munge/munged.pid"; do
        if [ -s "$f" ]; then
            pid=$(cat "$f")
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        fi
    done
    if [ "$rc" != 0 ]; then
        say "logs kept in $TMP"
        tail -n 20 "$TMP"/slurmctld.log "$TMP"/slurmd.log 2>/dev/null || true
    elif [ -z "${KEEP:-}" ]; then
        rm -rf "$TMP"
    fi
    exit "$rc"
}
trap cleanup EXIT

# --- munge: a fresh key and a private socket -------------------------------------------
dd if=/dev/urandom of="$TMP/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$TMP/munge/munge.key"
munged --force \
    --key-file="$TMP/munge/munge.key" \
    --socket="$TMP/munge/munge.socket" \
    --pid-file="$TMP/munge/munged.pid" \
    --log-file="$TMP/munge/munged.log" \
    --seed-file="$TMP/munge/munged.seed"
for _ in $(seq 50); do [ -S "$TMP/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$TMP/munge/munge.socket" ] || die "munged did not start"

# --- slurm.conf ------------------------------------------------------------------------
HOST=$(hostname -s)
CPUS=$(nproc)
PORT=${SLURM_PORT_BASE:-16817}
export SLURM_CONF="$TMP/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=sweepci
SlurmctldHost=$HOST
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$TMP/munge/munge.socket
MpiDefault=none
ProctrackType=proctrack/pgid
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MinJobAge=600
MailProg=/bin/true
SlurmctldPidFile=$TMP/slurmctld.pid
SlurmdPidFile=$TMP/slurmd.pid
SlurmctldLogFile=$TMP/slurmctld.log
SlurmdLogFile=$TMP/slurmd.log
StateSaveLocation=$TMP/state
SlurmdSpoolDir=$TMP/spool
NodeName=$HOST CPUs=$CPUS State=UNKNOWN
PartitionName=ci Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF

slurmctld -f "$SLURM_CONF" -i
slurmd -f "$SLURM_CONF"
for _ in $(seq 100); do
    sinfo -h -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)' && break
    sleep 0.2
done
sinfo -h -o '%T' | grep -qE '^(idle|mixed|allocated)' || die "the node did not come up: $(sinfo 2>&1)"
say "single-node SLURM up: node $HOST, $CPUS CPUs, partition ci"

# --- the sweep: a small one, long enough to cancel a shard mid-run ----------------------
CFG="$TMP/sweep.toml"
cat >"$CFG" <<EOF
# A small sweep for the SLURM check: the smoke sweep's grid with more seeds.
name = "slurm-check"
scenario = "$ROOT/scenarios/case-study-certified.toml"
k = { from = 1, to = 2000, points = 6 }
solvers = ["pg", "fista", "admm", "admm-pr"]
seeds = 40
steps = 40
base_seed = 2304062
certificate = false
EOF

say "reference: the unsharded sweep"
"$XTASK" sweep --config "$CFG" --out "$TMP/reference" --threads "$CPUS" >"$TMP/reference.log" 2>&1 \
    || die "the unsharded reference sweep failed: $(tail -n 3 "$TMP/reference.log" | tr '\n' ' ')"

# The job array of docs/sweeps.md, one shard per array task into one shared directory.
ARRAY="$TMP/array.sh"
cat >"$ARRAY" <<EOF
#!/bin/bash
#SBATCH --job-name=sweep-shard
#SBATCH --array=1-4
#SBATCH --cpus-per-task=1
#SBATCH --output=$TMP/out/%x-%A_%a.out
exec "$XTASK" sweep --config "$CFG" --out "\$SWEEP_OUT" \\
    --threads "\$SLURM_CPUS_PER_TASK" --shard "\$SLURM_ARRAY_TASK_ID/4"
EOF

# Compare two assembled sweeps without their timing columns.
strip_timing() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) keep[i] = ($i !~ /^wall_/) }
             { line = ""; for (i = 1; i <= NF; i++) if (keep[i]) line = line $i ","; print line }' "$1"
}
same_as_reference() {
    local dir=$1 f
    for f in runs.csv points.csv; do
        cmp -s <(strip_timing "$TMP/reference/$f") <(strip_timing "$dir/$f") \
            || die "$dir/$f differs from the unsharded run (timing columns aside)"
    done
    say "$dir: runs.csv ($(($(wc -l <"$dir/runs.csv") - 1)) runs) and points.csv equal the unsharded run, timing columns aside"
}
# The state of a job or array task (`JOB_I`) from scontrol (MinJobAge keeps finished jobs
# for 10 min), or UNKNOWN when scontrol has no record; never fails under `set -e`.
state_of() {
    local out
    out=$(scontrol show job "$1" 2>/dev/null || true)
    out=$(printf '%s\n' "$out" | grep -o 'JobState=[A-Z_]*' | head -n 1 || true)
    printf '%s\n' "${out#JobState=}" | sed 's/^$/UNKNOWN/'
}
# Whether a state is final (the job will not change state any more).
is_final() {
    case $1 in
        COMPLETED | CANCELLED | FAILED | TIMEOUT | NODE_FAIL | PREEMPTED | OUT_OF_MEMORY | BOOT_FAIL | DEADLINE) return 0 ;;
        *) return 1 ;;
    esac
}
# Waits until the job (all its array tasks) has left the queue, at most WAIT_LIMIT s.
wait_job() {
    local id=$1 t0=$SECONDS q
    while :; do
        q=$(squeue -h -j "$id" 2>/dev/null || true)
        [ -z "$q" ] && return 0
        [ $((SECONDS - t0)) -lt "$WAIT_LIMIT" ] \
            || die "job $id still queued after WAIT_LIMIT=$WAIT_LIMIT s: $(printf '%s' "$q" | head -n 3 | tr '\n' ';')"
        sleep 0.5
    done
}
# Waits until array task `$1` has a final state (a cancel takes effect asynchronously:
# CANCELLING/COMPLETING come first), at most WAIT_LIMIT s; prints that state.
settled_state() {
    local id=$1 t0=$SECONDS st
    while :; do
        st=$(state_of "$id")
        if is_final "$st"; then
            printf '%s\n' "$st"
            return 0
        fi
        [ $((SECONDS - t0)) -lt "$WAIT_LIMIT" ] \
            || die "job $id did not reach a final state within WAIT_LIMIT=$WAIT_LIMIT s (still $st)"
        sleep 0.2
    done
}
# sbatch --parsable prints `id` or `id;cluster`.
submit() {
    local out
    out=$(sbatch --parsable "$@" 2>&1) || die "sbatch $* failed: $out"
    out=${out%%;*}
    case $out in '' | *[!0-9]*) die "sbatch $* printed no job id: $out" ;; esac
    printf '%s\n' "$out"
}

say "submitting the 4-task job array"
export SWEEP_OUT="$TMP/sharded"
JOB=$(submit "$ARRAY")
wait_job "$JOB"
for i in 1 2 3 4; do
    st=$(settled_state "${JOB}_$i")
    [ "$st" = COMPLETED ] || die "array task ${JOB}_$i: $st (expected COMPLETED)"
done
"$XTASK" sweep-merge --config "$CFG" --out "$TMP/sharded" >"$TMP/merge.log" 2>&1 \
    || die "sweep-merge of the 4 shards failed: $(tail -n 3 "$TMP/merge.log" | tr '\n' ' ')"
same_as_reference "$TMP/sharded"

say "preemption: the array again, task 2 cancelled once it has written a point file"
export SWEEP_OUT="$TMP/preempted"
JOB=$(submit "$ARRAY")
# Shard 2 owns the points with index ≡ 1 (mod 4): p00001, p00005, …
shard2_files() {
    local names
    names=$(ls "$SWEEP_OUT/points/" 2>/dev/null || true)
    printf '%s\n' "$names" | grep -cE '^p000(01|05|09|13|17|21)\.csv$' || true
}
t0=$SECONDS
until [ "$(shard2_files)" -gt 0 ]; do
    [ $((SECONDS - t0)) -lt "$WAIT_LIMIT" ] \
        || die "array task 2 wrote no point file within WAIT_LIMIT=$WAIT_LIMIT s (state $(state_of "${JOB}_2"))"
    sleep 0.1
done
st=$(state_of "${JOB}_2")
[ "$st" = RUNNING ] || die "array task 2 was not running when it was to be cancelled: $st"
scancel "${JOB}_2" || die "scancel ${JOB}_2 failed"
# The cancel is asynchronous: wait for task 2's final state, then for the others.
st=$(settled_state "${JOB}_2")
wait_job "$JOB"
if [ "$st" = COMPLETED ]; then
    die "array task 2 finished between the RUNNING check and scancel: the preemption was not exercised (rerun; a larger sweep makes this rarer)"
fi
[ "$st" = CANCELLED ] || die "array task 2: $st (expected CANCELLED)"
for i in 1 3 4; do
    st=$(settled_state "${JOB}_$i")
    [ "$st" = COMPLETED ] || die "array task ${JOB}_$i: $st (expected COMPLETED)"
done
have=$(ls "$SWEEP_OUT/points/" | grep -cE '^p[0-9]+\.csv$' || true)
say "task 2 cancelled; $have of 24 point files present"
if "$XTASK" sweep-merge --config "$CFG" --out "$SWEEP_OUT" >"$TMP/merge-incomplete.log" 2>&1; then
    die "merging with a cancelled shard succeeded"
fi
why=$(grep -m1 -o 'error: .*' "$TMP/merge-incomplete.log" || true)
[ -n "$why" ] || die "the refused merge printed no error line: $(tail -n 3 "$TMP/merge-incomplete.log" | tr '\n' ' ')"
say "merge refuses the incomplete set: $(printf '%s' "$why" | cut -c1-100)"
JOB2=$(submit --array=2 "$ARRAY")
wait_job "$JOB2"
st=$(settled_state "${JOB2}_2")
[ "$st" = COMPLETED ] || die "resubmitted task 2: $st (expected COMPLETED)"
skipped=$(grep -o '"points_skipped_resumed": [0-9]*' "$SWEEP_OUT/meta.shard-2-of-4.json" || true)
skipped=${skipped##* }
case $skipped in
    '' | *[!0-9]*) die "meta.shard-2-of-4.json records no points_skipped_resumed" ;;
    0) die "resubmitted task 2 resumed nothing (points_skipped_resumed = 0), though it had written a point file" ;;
esac
say "resubmitted task 2 resumed: $skipped of its points were already finished"
"$XTASK" sweep-merge --config "$CFG" --out "$SWEEP_OUT" >"$TMP/merge2.log" 2>&1 \
    || die "sweep-merge after the resumed shard failed: $(tail -n 3 "$TMP/merge2.log" | tr '\n' ' ')"
same_as_reference "$SWEEP_OUT"

say "ok: sharded, merged and preempted runs equal the unsharded one"
