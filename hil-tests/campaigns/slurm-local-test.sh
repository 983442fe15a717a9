#!/usr/bin/env bash
# A real Slurm run of a sharded `grop hil` campaign on this machine (docs/campaigns.md):
# installs slurm-wlm and munge from Debian's packages if missing (`apt-get update` once), starts
# a private one-node cluster on loopback (munged, slurmctld, slurmd, each with its own socket,
# ports, state and logs in a temporary folder), submits 4 shards of `grop hil --tasks 8` as one
# job array (hil-tests/campaigns/slurm/grop-shard.sbatch, binaries built once before it, the
# shards run with --no-build; blind, --no-lidar: the sharding is what it checks), merges them with `grop merge`, runs the same 8 tasks unsharded,
# and compares: the per-task simulated results (tasks.csv without its wall-time column) must be
# identical. Stops every daemon it started and removes every file it made, also on failure.
#
# Needs root (the daemons and apt-get). Binaries: target/<profile>/ of the checkout, or
# $CARGO_TARGET_DIR; GROP_PROFILE=release|debug (default debug, what CI has built already).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
start=$(date +%s)
stamp() { echo "== slurm-local-test [$(( $(date +%s) - start )) s] $*"; }
[ "$(id -u)" = 0 ] || { echo "slurm-local-test: needs root (the Slurm and munge daemons, apt-get)" >&2; exit 1; }
profile="${GROP_PROFILE:-debug}"
target="${CARGO_TARGET_DIR:-$root/target}"
bin="$target/$profile"

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null || ! command -v sbatch >/dev/null; then
    stamp "installing slurm-wlm and munge (apt-get)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
fi
stamp "$(slurmctld -V), $(munged -V 2>&1 | head -1)"

stamp "building the binaries once ($profile) before the array"
if [ "$profile" = release ]; then
    cargo build --quiet --release -p grop-cli -p hil-world -p grop-onboard --bins
else
    # The feature set of `cargo test --workspace` (which CI runs first): nothing compiles again.
    cargo build --quiet --workspace --bins --examples
fi

work="$(mktemp -d /tmp/grop-slurm-test.XXXXXX)"
chmod 755 "$work"
pids=()
cleanup() {
    local rc=$?
    if [ -n "${SLURM_CONF:-}" ] && [ -f "$SLURM_CONF" ]; then
        scancel --quiet --user=root >/dev/null 2>&1 || true
    fi
    for pidfile in "$work/slurmd.pid" "$work/slurmctld.pid" "$work/munged.pid"; do
        if [ -s "$pidfile" ]; then
            pid="$(cat "$pidfile")"
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
            kill -9 "$pid" 2>/dev/null || true
        fi
    done
    if [ "$rc" != 0 ]; then
        for log in slurmctld.log slurmd.log munged.log; do
            [ -f "$work/$log" ] && { echo "--- $log (last lines)"; tail -n 15 "$work/$log"; }
        done
        for out in "$work"/campaign-logs/*.out; do
            [ -f "$out" ] && { echo "--- $out"; tail -n 15 "$out"; }
        done
    fi
    rm -rf "$work"
    stamp "cleaned up (exit $rc)"
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# A free loopback TCP port (not listening now, not handed out before).
used_ports=""
free_port() {
    local p
    for _ in $(seq 200); do
        p=$(( 20000 + RANDOM % 30000 ))
        case " $used_ports " in *" $p "*) continue ;; esac
        if ! grep -qi ":$(printf '%04X' "$p") " /proc/net/tcp /proc/net/tcp6 2>/dev/null; then
            used_ports="$used_ports $p"; echo "$p"; return 0
        fi
    done
    echo "no free port found" >&2; return 1
}

stamp "starting munged, slurmctld and slurmd in $work"
mkdir -p "$work/state" "$work/spool" "$work/campaign" "$work/campaign-logs" "$work/munge"
chmod 700 "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
munged --force --socket="$work/munge/munge.sock" --key-file="$work/munge/munge.key" \
    --pid-file="$work/munged.pid" --log-file="$work/munged.log" --seed-file="$work/munge/seed"
for _ in $(seq 50); do [ -S "$work/munge/munge.sock" ] && break; sleep 0.1; done

host="$(hostname -s)"
cpus="$(nproc)"
ctld_port="$(free_port)"
slurmd_port="$(free_port)"
cat >"$work/slurm.conf" <<CONF
ClusterName=grop-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge/munge.sock
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=4000 State=UNKNOWN
PartitionName=grop Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$work/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 100); do
    sinfo --noheader --states=idle --format=%n 2>/dev/null | grep -qx "$host" && break
    sleep 0.2
done
sinfo --noheader --format='%P %a %D %t %N' | sed 's/^/   sinfo: /'
sinfo --noheader --states=idle --format=%n | grep -qx "$host" || { echo "the node did not come up" >&2; exit 1; }

stamp "submitting 4 shards of grop hil --tasks 8 as one array"
t0=$(date +%s.%N)
jid=$(sbatch --parsable --array=0-3 --cpus-per-task=1 --mem=900M --time=00:10:00 \
    --output="$work/campaign-logs/shard-%A_%a.out" \
    --export=ALL,GROP_JOB=hil,GROP_ARGS="--tasks 8 --jobs 1 --no-lidar",CAMPAIGN_DIR="$work/campaign",GROP_BIN="$bin",GROP_WORKDIR="$root" \
    hil-tests/campaigns/slurm/grop-shard.sbatch)
# Until no task of the array is left (sbatch --wait polls at growing intervals, up to 32 s).
for _ in $(seq 1200); do
    [ -z "$(squeue --noheader --jobs="$jid" --format=%i 2>/dev/null)" ] && break
    sleep 0.5
done
t1=$(date +%s.%N)
for m in "$work"/campaign/hil/shard-*/shard.json; do
    printf '   %s: tasks %s, %.1f s wall\n' "$(basename "$(dirname "$m")")" \
        "$(tr -d ' \n' <"$m" | grep -o '"task_ids":\[[0-9,]*\]' | cut -d: -f2)" \
        "$(grep -o '"wall_s": [0-9.]*' "$m" | cut -d' ' -f2)"
done
[ "$(ls -d "$work"/campaign/hil/shard-* | wc -l)" = 4 ] || { echo "not all 4 shards finished" >&2; exit 1; }
"$bin/grop" --log warn merge --out "$work/merged" "$work/campaign/hil" | tail -n 1

stamp "the same 8 tasks unsharded in one process (--jobs $cpus)"
t2=$(date +%s.%N)
"$bin/grop" --log warn hil --tasks 8 --jobs "$cpus" --no-lidar --no-build --out-dir "$work/whole" >/dev/null 2>"$work/whole.err" \
    || { cat "$work/whole.err"; exit 1; }
t3=$(date +%s.%N)

# tasks.csv without its wall_s column (the 11th).
cut -d, -f1-10,12- "$work/whole/tasks.csv" >"$work/whole.csv"
cut -d, -f1-10,12- "$work/merged/tasks.csv" >"$work/merged.csv"
[ "$(wc -l <"$work/whole.csv")" = 9 ] || { echo "the unsharded run has $(($(wc -l <"$work/whole.csv") - 1)) of 8 tasks" >&2; exit 1; }
if ! diff -u "$work/whole.csv" "$work/merged.csv"; then
    echo "slurm-local-test: FAILED: the merged shards' per-task results differ from one run's" >&2
    exit 1
fi
paired() { grep -o 'Paired difference[^:]*: \*\*[^*]*\*\*' "$1"; }
[ "$(paired "$work/whole/summary.md")" = "$(paired "$work/merged/summary.md")" ] \
    || { echo "paired statistics differ" >&2; exit 1; }
printf '   array of 4 shards: %.1f s (submit to last shard done); one process: %.1f s\n' \
    "$(echo "$t1 - $t0" | bc)" "$(echo "$t3 - $t2" | bc)"
echo "   $(paired "$work/merged/summary.md")"
stamp "passed: 8 tasks, 4 Slurm shards merged == one run (per-task simulated results identical)"
