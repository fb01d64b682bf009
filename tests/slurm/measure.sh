#!/usr/bin/env bash
# tests/slurm/measure.sh: the figures of docs/cluster.md, on the one-node cluster of
# tests/slurm/cluster (run as `tests/slurm/cluster run bash tests/slurm/measure.sh OUTDIR`).
# Slurm's own cost per task (sbatch's latency, and how fast the cluster runs empty array
# tasks), then a progressive render of PASSES passes (default 64) by pipelines/render and by
# pipelines/slurm in each CONFIGS setting, one after the other, with the load (uptime) before
# each. Prints one line per figure; the renders stay in OUTDIR.
set -u
cd "$(dirname "$0")/../.."
OUT=${1:?usage: measure.sh OUTDIR}
PASSES=${PASSES:-64}
SCENE=${SCENE:-scenes/cornell-box/scene.json}
CONFIGS=${CONFIGS:-"CPUS=2 TASK_PASSES=1;CPUS=1 TASK_PASSES=1;CPUS=2 TASK_PASSES=4"}
export BIN=${BIN:-$PWD/bin}
mkdir -p "$OUT"
now() { date +%s.%N; }
dt() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }
load() { uptime | sed 's/.*load average: //'; }

# sbatch's latency: 20 single submissions of a job held back (never started), then cancelled
t0=$(now)
ids=()
for ((i = 0; i < 20; i++)); do ids+=("$(sbatch --parsable --hold -o /dev/null --wrap true)"); done
t1=$(now)
scancel "${ids[@]}"
echo "sbatch: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", (b - a) / 20 * 1000 }') ms a submission (20 held jobs; load $(load))"
# empty tasks: an array of 64 tasks of 1 CPU that do nothing, from sbatch to the queue empty
t0=$(now)
sbatch --parsable -o /dev/null --array=1-64 --wrap true >/dev/null
while [ -n "$(squeue -h -o %i)" ]; do sleep 0.1; done
t1=$(now)
echo "empty tasks: 64 in $(dt "$t0" "$t1") s on 2 CPUs, $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.0f", (b - a) / 64 * 2 * 1000 }') ms of a CPU slot a task (load $(load))"

l0=$(load)
t0=$(now)
rm -rf "$OUT/local"
pipelines/render "$SCENE" "$OUT/local" PASSES="$PASSES" >"$OUT/local.log" 2>&1 || echo "local render failed"
t1=$(now)
echo "pipelines/render PASSES=$PASSES: $(dt "$t0" "$t1") s (load before $l0, after $(load))"
IFS=';' read -r -a cfgs <<<"$CONFIGS"
for c in "${cfgs[@]}"; do
    d=$OUT/slurm-${c// /-}
    rm -rf "$d"
    l0=$(load)
    t0=$(now)
    # shellcheck disable=SC2086
    pipelines/slurm "$SCENE" "$d" PASSES="$PASSES" $c >"$d.log" 2>&1 || echo "slurm render $c failed: $(tail -n 1 "$d.log")"
    t1=$(now)
    same=same
    for f in image.exr running.pm passes.txt; do cmp -s "$OUT/local/$f" "$d/$f" || same="DIFFERENT ($f)"; done
    echo "pipelines/slurm PASSES=$PASSES $c: $(dt "$t0" "$t1") s, image $same as the local one (load before $l0, after $(load))"
done
