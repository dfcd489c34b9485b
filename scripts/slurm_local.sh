#!/bin/bash
# Runs the README's Slurm job array (scripts/slurm/mpgdrive-array.sbatch, submitted verbatim)
# on a real single-node Slurm and checks it against one machine:
#   1. sets up Slurm and munge when missing (root; otherwise says what to run) and starts the
#      daemons that are not running, with a private slurm.conf (one node, this machine's CPUs);
#   2. makes a small batch in a work folder: 2 demand levels x 2 SUMO seeds x 2 controllers,
#      MPGDRIVE_END (default 600) simulated seconds per run, one run per array task;
#   3. runs the batch unsharded on this machine;
#   4. submits the job array, cancels one task mid-run (scancel), resubmits that shard alone
#      (it resumes), merges the shards and compares the merged summary.csv with the unsharded
#      one byte for byte;
#   5. stops the daemons it started, by their process ids.
# Usage (from the repository root, after `make build` or `make demo`): scripts/slurm_local.sh
# Environment: WORK (work folder, default /tmp/mpgdrive-slurm), MPGDRIVE_END, CANCEL_TASK (2).
# Not part of `make test`: it needs root and daemons.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
work=${WORK:-/tmp/mpgdrive-slurm}
export MPGDRIVE_END=${MPGDRIVE_END:-600}
cancel=${CANCEL_TASK:-2}
sbatch_file=$repo/scripts/slurm/mpgdrive-array.sbatch
bin=$repo/target/release/mpgdrive
started_at=$(date +%s)
say() { echo "slurm_local: $*"; }
die() { echo "slurm_local: $*" >&2; exit 1; }

[ -x "$bin" ] || die "no $bin: run \`make build\` (or \`make demo\`) first"
if ! command -v sbatch >/dev/null || ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    [ "$(id -u)" = 0 ] || die "Slurm is missing: run as root, or install it: apt-get install -y slurm-wlm munge"
    say "installing slurm-wlm and munge"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
fi

rm -rf "$work" && mkdir -p "$work/slurm/state" "$work/slurm/spool" "$work/slurm/log"
# The job file's relative paths resolve in the work folder, which holds the repository's
# binary, networks, policies and configs and the batch's own scenarios and results.
for d in target sumo_nets policies configs; do ln -s "$repo/$d" "$work/$d"; done

# --- Slurm: use a running cluster, or start a private single-node one.
ours=()
stop_daemons() {
    for pid in "${ours[@]}"; do kill "$pid" 2>/dev/null || true; done
    [ ${#ours[@]} = 0 ] || say "stopped the daemons it started (pids ${ours[*]})"
}
trap stop_daemons EXIT
if scontrol ping >/dev/null 2>&1; then
    say "using the running Slurm ($(sinfo -h -o '%P %D nodes' | head -1))"
else
    [ "$(id -u)" = 0 ] || die "no Slurm is running and starting one needs root"
    host=$(hostname -s)
    cpus=$(nproc)
    export SLURM_CONF=$work/slurm/slurm.conf
    cat > "$SLURM_CONF" <<EOF
ClusterName=mpgdrive
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
StateSaveLocation=$work/slurm/state
SlurmdSpoolDir=$work/slurm/spool
SlurmctldPidFile=$work/slurm/slurmctld.pid
SlurmdPidFile=$work/slurm/slurmd.pid
SlurmctldLogFile=$work/slurm/log/slurmctld.log
SlurmdLogFile=$work/slurm/log/slurmd.log
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MpiDefault=none
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        mkdir -p /run/munge && chown munge:munge /run/munge
        [ -f /etc/munge/munge.key ] || { mungekey --create 2>/dev/null || /usr/sbin/create-munge-key -f; }
        runuser -u munge -- munged
        for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
        ours+=("$(cat /run/munge/munged.pid)")
    fi
    slurmctld -f "$SLURM_CONF"
    for _ in $(seq 50); do [ -s "$work/slurm/slurmctld.pid" ] && break; sleep 0.1; done
    ours+=("$(cat "$work/slurm/slurmctld.pid")")
    slurmd -f "$SLURM_CONF"
    for _ in $(seq 50); do [ -s "$work/slurm/slurmd.pid" ] && break; sleep 0.1; done
    ours+=("$(cat "$work/slurm/slurmd.pid")")
    for _ in $(seq 100); do [ "$(sinfo -h -o %t 2>/dev/null)" = idle ] && break; sleep 0.2; done
    [ "$(sinfo -h -o %t)" = idle ] || die "the node did not come up: see $work/slurm/log"
    say "started munged, slurmctld and slurmd (pids ${ours[*]}), node $host with $cpus CPUs"
fi
say "$(sbatch --version), $(munged --version 2>&1 | head -1)"

cd "$work"
# --- The batch: route files, and the same batch unsharded on this machine.
"$bin" routes --base sumo_nets/i80_merge/i80.rou.xml --scales 0.8,1.0 --controllable-share 1.0 \
    --seeds 0 --duration "$MPGDRIVE_END" --out scenarios/i80 >/dev/null
t0=$(date +%s)
"$bin" batch --sumocfg sumo_nets/i80_merge/i80.sumocfg --routes 'scenarios/i80/*.rou.xml' \
    --controllers mpg,sumo --seeds 0,1 --end "$MPGDRIVE_END" --jobs 2 --out results/whole \
    >/dev/null 2>"$work/whole.log"
say "unsharded batch: $(ls results/whole/runs | wc -l) runs in $(( $(date +%s) - t0 )) s"

# --- The job array, verbatim; one task cancelled mid-run.
t0=$(date +%s)
job=$(sbatch --parsable "$sbatch_file")
say "submitted job array $job ($sbatch_file)"
for _ in $(seq 600); do
    [ -n "$(squeue -h -j "${job}_$cancel" -t R 2>/dev/null)" ] && break
    sleep 0.1
done
[ -n "$(squeue -h -j "${job}_$cancel" -t R)" ] || die "task $cancel never ran"
sleep 0.5
runs_before=$(ls "results/shard-$cancel/runs" 2>/dev/null | wc -l)
scancel "${job}_$cancel"
say "cancelled task $cancel while running ($runs_before of its runs finished)"
while [ -n "$(squeue -h -j "$job" 2>/dev/null)" ]; do sleep 0.5; done
left=$(ls "results/shard-$cancel/runs" 2>/dev/null | wc -l)
[ "$left" -lt 1 ] || die "task $cancel finished its run before it was cancelled: raise MPGDRIVE_END"
again=$(sbatch --parsable --wait --array="$cancel" "$sbatch_file")
say "resubmitted shard $cancel as job $again: $(ls "results/shard-$cancel/runs" | wc -l) run(s) now"
for f in slurm-*.out; do
    case $f in
        "slurm-${job}_$cancel.out") say "$f (the cancelled task): $(grep -m1 CANCELLED "$f")" ;;
        *) ! grep -q -i error "$f" || die "$f: $(grep -i -m1 error "$f")" ;;
    esac
done
"$bin" merge results/shard-* --out results/merged >/dev/null
say "job array: $(ls results/shard-*/runs | grep -c json) runs over $(ls -d results/shard-* | wc -l) shards in $(( $(date +%s) - t0 )) s"

# --- The comparison.
if cmp results/merged/summary.csv results/whole/summary.csv; then
    say "merged summary.csv is byte-identical to the unsharded one:"
    cat results/merged/summary.md
    say "done in $(( $(date +%s) - started_at )) s (work folder $work)"
else
    diff results/merged/summary.csv results/whole/summary.csv || true
    die "the merged summary differs from the unsharded one"
fi
