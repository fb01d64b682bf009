#!/usr/bin/env bash
# tests/slurm/measure.sh: the figures of docs/cluster.md, on the one-node cluster of
# tests/slurm/cluster (run as `tests/slurm/cluster run bash tests/slurm/measure.sh OUTDIR`, on
# a quiet machine: every figure is a wall time). Slurm's own cost per task (sbatch's latency,
# and how fast the cluster runs empty array tasks), then a progressive render of PASSES passes
# (default 64) of a few seconds each by pipelines/render and by pipelines/slurm in each CONFIGS
# setting, one after the other, with the load (uptime) before and after each. For each cluster
# render: its wall time against the local one (the overhead; issue 20's goal is under 10%),
# when its last pass landed, how long the composite job's render took, and whether every file
# of every pass and the images are the local render's, byte for byte. Prints one line per
# figure, and a summary to paste; the logs stay in OUTDIR (the renders too with KEEP_RENDERS=1).
#
# Environment: PASSES (64), SCENE (the Cornell box), PARAMS (render's parameters of a pass,
# default PHOTONS=1000000 SPP=8: some 2 to 3 s a pass on this 2-core machine), CONFIGS
# (pipelines/slurm settings separated by ';', default "CPUS=2;CPUS=1": one task at a time with
# two threads a stage, as the local render runs, and two tasks at once of one thread each),
# LOCAL (the local render's extra parameters, default none), KEEP_RENDERS (0: remove each
# render's pass directories once compared, some 2 GB each at the defaults).
set -u
cd "$(dirname "$0")/../.."
OUT=${1:?usage: measure.sh OUTDIR}
PASSES=${PASSES:-64}
SCENE=${SCENE:-scenes/cornell-box/scene.json}
PARAMS=${PARAMS:-PHOTONS=1000000 SPP=8}
CONFIGS=${CONFIGS:-"CPUS=2;CPUS=1"}
LOCAL=${LOCAL:-}
KEEP_RENDERS=${KEEP_RENDERS:-0}
export BIN=${BIN:-$PWD/bin}
[ -n "${SLURM_CONF:-}" ] && sinfo -h >/dev/null 2>&1 || { echo "measure: no cluster (run through tests/slurm/cluster run)" >&2; exit 1; }
mkdir -p "$OUT" || exit 1
OUT=$(cd "$OUT" && pwd)
now() { date +%s.%N; }
dt() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }
load() { uptime | sed 's/.*load average: //'; }
summary=()
say() { echo "$*"; summary+=("$*"); }

say "machine: $(nproc) CPUs, $(grep -m 1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'); pmtk $(git describe --always --dirty 2>/dev/null); $(date -u '+%Y-%m-%d %H:%M UTC')"
say "render: $SCENE, PASSES=$PASSES $PARAMS${LOCAL:+ (local: $LOCAL)}"

# sbatch's latency: 20 single submissions of a job held back (never started), then cancelled
t0=$(now)
ids=()
for ((i = 0; i < 20; i++)); do ids+=("$(sbatch --parsable --hold -o /dev/null --wrap true)"); done
t1=$(now)
scancel "${ids[@]}"
say "sbatch: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", (b - a) / 20 * 1000 }') ms a submission (20 held jobs; load $(load))"
# empty tasks: an array of 64 tasks of 1 CPU that do nothing, from sbatch to the queue empty
cpus=$(sinfo -h -o %C | awk -F/ '{ t += $4 } END { print t }')
t0=$(now)
sbatch --parsable -o /dev/null --array=1-64 --wrap true >/dev/null
while [ -n "$(squeue -h -o %i)" ]; do sleep 0.1; done
t1=$(now)
say "empty tasks: 64 in $(dt "$t0" "$t1") s on $cpus CPUs, $(awk -v a="$t0" -v b="$t1" -v c="$cpus" 'BEGIN { printf "%.0f", (b - a) / 64 * c * 1000 }') ms of a CPU slot a task (load $(load))"

# shellcheck disable=SC2206
P=($PARAMS)
# shellcheck disable=SC2206
L=($LOCAL)
l0=$(load)
t0=$(now)
rm -rf "$OUT/local"
pipelines/render "$SCENE" "$OUT/local" PASSES="$PASSES" "${P[@]}" "${L[@]}" >"$OUT/local.log" 2>&1 || say "local render failed: $(tail -n 1 "$OUT/local.log")"
t1=$(now)
TL=$(dt "$t0" "$t1")
pass_s=$(jq -r '[.passes[].wall_s] | "\(add / length | . * 100 | round / 100) s a pass (\(min | . * 100 | round / 100) to \(max | . * 100 | round / 100))"' "$OUT/local/stats.json" 2>/dev/null)
say "pipelines/render PASSES=$PASSES: $TL s, $pass_s (load before $l0, after $(load))"
IFS=';' read -r -a cfgs <<<"$CONFIGS"
for c in "${cfgs[@]}"; do
    d=$OUT/slurm-${c// /-}
    rm -rf "$d"
    l0=$(load)
    t0=$(now)
    # shellcheck disable=SC2086
    pipelines/slurm "$SCENE" "$d" PASSES="$PASSES" "${P[@]}" $c >"$d.log" 2>&1 || say "slurm render $c failed: $(tail -n 1 "$d.log")"
    t1=$(now)
    T=$(dt "$t0" "$t1")
    same=0 differ=()
    for f in $(cd "$OUT/local" && ls pass-*/*.pm running.pm passes.txt image.exr image.png); do
        if cmp -s "$OUT/local/$f" "$d/$f"; then same=$((same + 1)); else differ+=("$f"); fi
    done
    # when every pass had landed: the first look at the queue (every POLL seconds) that saw no
    # task pending or running
    landed=$(grep -m 1 -E "tasks: 0 pending, 0 running, [0-9]+ done, 0 failed" "$d.log" | sed -n 's/^slurm: \([0-9.]*\) s:.*/\1/p')
    comp=$(sed -n 's/^  total *\([0-9.]*\) .*/\1/p' "$d.log" | tail -n 1)
    # what was submitted, as pipelines/slurm's start line says it (pass 1 is a task of its own)
    tasks=$(sed -n 's/^slurm: .*; submitted \(.*\); logs in .*/\1/p' "$d.log" | head -n 1)
    say "pipelines/slurm PASSES=$PASSES $c (${tasks:-? tasks}): $T s: $(awk -v a="$T" -v b="$TL" 'BEGIN { printf "%+.1f%%", (a / b - 1) * 100 }') against pipelines/render (goal under +10%); every task done at ${landed:-?} s, the composite job's render ${comp:-?} s; ${same} files the same as the local render's$( [ ${#differ[@]} = 0 ] || echo ", DIFFERENT: ${differ[*]:0:5}") (load before $l0, after $(load))"
    [ "$KEEP_RENDERS" = 1 ] || rm -rf "$d"/pass-* "$d/.slurm/stage" "$d/.slurm/work"
done
[ "$KEEP_RENDERS" = 1 ] || rm -rf "$OUT/local"/pass-*
echo
echo "summary (for docs/cluster.md):"
printf '  %s\n' "${summary[@]}"
