#!/usr/bin/env bash
# Wall time of N shards against one process on this machine (docs/campaigns.md): grop hil on
# TASKS tasks (default 16) as one process (--jobs 2), as 2 shards side by side (--jobs 1 each)
# and as 4 shards two at a time (--jobs 1 each), each followed by grop merge; and grop datagen
# (the paper's 96,000 trials) as one process and as 4 shards one after another (every shard uses
# all cores). Binaries: target/<profile> or $CARGO_TARGET_DIR (GROP_PROFILE, default debug).
# Prints a markdown table. Needs nothing but the built binaries.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
bin="${CARGO_TARGET_DIR:-$root/target}/${GROP_PROFILE:-debug}"
tasks="${TASKS:-16}"
work="$(mktemp -d /tmp/grop-measure.XXXXXX)"
trap 'rm -rf "$work"' EXIT
g() { "$bin/grop" --log warn "$@" >/dev/null; }
now() { date +%s.%N; }
row() { printf '| %s | %.1f s |\n' "$1" "$(echo "$3 - $2" | bc)"; }

echo "| run | wall |"
echo "|---|---|"
t0=$(now); g hil --tasks "$tasks" --jobs 2 --no-build --out-dir "$work/h1"; t1=$(now)
row "hil --tasks $tasks, one process, --jobs 2" "$t0" "$t1"
t0=$(now)
for i in 0 1; do g hil --tasks "$tasks" --jobs 1 --no-build --shard "$i/2" --out-dir "$work/h2" & done
wait
g merge --out "$work/h2m" "$work/h2"; t1=$(now)
row "hil --tasks $tasks, 2 shards side by side (--jobs 1 each) + merge" "$t0" "$t1"
t0=$(now)
printf '%s\n' 0 1 2 3 | xargs -P 2 -I{} "$bin/grop" --log warn hil --tasks "$tasks" --jobs 1 --no-build --shard "{}/4" --out-dir "$work/h4" >/dev/null
g merge --out "$work/h4m" "$work/h4"; t1=$(now)
row "hil --tasks $tasks, 4 shards two at a time (--jobs 1 each) + merge" "$t0" "$t1"
cut -d, -f1-10,12- "$work/h1/tasks.csv" >"$work/a"; cut -d, -f1-10,12- "$work/h4m/tasks.csv" >"$work/b"
cmp -s "$work/a" "$work/b" || { echo "merged 4 shards differ from one run" >&2; exit 1; }

t0=$(now); g datagen --out "$work/d1"; t1=$(now)
row "datagen (96,000 trials), one process" "$t0" "$t1"
t0=$(now)
for i in 0 1 2 3; do g datagen --shard "$i/4" --out "$work/d4"; done
g merge --out "$work/d4m" "$work/d4"; t1=$(now)
row "datagen, 4 shards one after another + merge" "$t0" "$t1"
cmp -s "$work/d1/dataset.npz" "$work/d4m/dataset.npz" || { echo "merged datagen differs" >&2; exit 1; }
echo
echo "$(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg) at the end, $(date -u +%Y-%m-%d)"
