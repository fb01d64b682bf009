# 92-passes.sh: progressive passes (sourced by tests/bench/run). Two sections.
#
# 1. The anytime budget of the resident passes (the default): pipelines/render TIME=T on the
# Cornell box at the scene's size for T in BUDGETS (default 1 2 4 8 16 30 60 120 s; QUICK: 1 2
# 4): the command's wall time against T, when the first image was in place (stats.json
# total.first_image_s), the passes and what OUTDIR keeps (du). The goals: the command ends within
# 5% of T, the first image within 0.5 s, at most 50 MB kept for 60 s.
#
# 2. What a pass costs beyond its computing, on the pass files (KEEP=all):
# pipelines/render PASSES=RUNS+1 on the Cornell box at 256x256 with 500,000 photons per pass;
# the first pass (cold caches, --k measuring r_1) is left out. For each other pass: its wall
# time (render's pass_s: the graph written, make, every stage, composite --accumulate and the
# bookkeeping after it) against the sum of the stages' compute timers from their --stats:
# trace-photons trace_s, build-photonmap build_s + gather_s + width_s, trace-gather-points
# trace_s, hilbert-sort keys_s + sort_s, the gather radius_s + gather_s (composite's work is
# reading and writing). The rest is the overhead, split into the stages' reading and writing
# (read_s + write_s + the spooling no tracing hid, spool_alone_s: checksums included), what else the stages spend unseen by their
# timers (scene loading, Embree's BVH build, allocation: wall_s less compute and I/O), and what
# is outside the stages' own wall_s: process start and exit, render's own work (stamps, make,
# hashing the buffers, pm-info on the running image), less the overlap of the stages that
# run at once (a pass runs trace-photons | build-photonmap beside trace-gather-points |
# hilbert-sort, then the gather). Because the photon pipe runs beside the eye tracer, their
# compute timers can cover the same wall seconds: the overhead is given twice, with the photon
# pipe's compute counted (a lower bound) and not counted (an upper bound, as if all of it were
# hidden under the other stages' timers). The load average when the bench ran goes beside them.
S=scenes/cornell-box/scene.json
BUDGETS=${BUDGETS:-1 2 4 8 16 30 60 120}
[ "$QUICK" = 1 ] && BUDGETS=${BUDGETS_QUICK:-1 2 4}
rows=""
for T in $BUDGETS; do
    rm -rf "$TMP/budget"
    l0=$(cut -d' ' -f1 /proc/loadavg)
    t0=$(date +%s.%N)
    BIN=$BIN pipelines/render $S "$TMP/budget" TIME=$T >"$TMP/budget.log" 2>&1 || { cat "$TMP/budget.log" >&2; exit 1; }
    t1=$(date +%s.%N)
    l1=$(cut -d' ' -f1 /proc/loadavg)
    read -r passes first < <(jq -r '"\(.total.passes) \(.total.first_image_s)"' "$TMP/budget/stats.json")
    kb=$(du -sk "$TMP/budget" | cut -f1)
    rows+=$(awk -v T="$T" -v a="$t0" -v b="$t1" -v f="$first" -v n="$passes" -v kb="$kb" -v l0="$l0" -v l1="$l1" 'BEGIN {
        w = b - a; printf "| %s | %.3f | %+.1f%% | %.3f | %d | %.1f | %s to %s |\n", T, w, 100 * (w - T) / T, f, n, kb / 1024, l0, l1 }')$'\n'
done
rm -rf "$TMP/budget" "$TMP/budget.log"
cat >>"$MD" <<MD

## Progressive passes: the anytime budget

\`pipelines/render scenes/cornell-box/scene.json OUT TIME=T\` (resident passes, the scene's 256x256, the
per-pass defaults), timed from outside: the command's wall time against T (goal: within 5%),
when the first image was in place (\`stats.json\` total.first_image_s; goal: within 0.5 s),
the passes, and what OUTDIR keeps (goal: at most 50 MB for 60 s). The load average (1 min)
from other jobs before and after each run is beside it: every time here stretches with it.

| T s | wall s | off T | first image s | passes | OUTDIR MB | load |
|---|---|---|---|---|---|---|
$rows
MD

P=500000 size=256
[ "$QUICK" = 1 ] && P=100000 size=128
rm -rf "$TMP/passes"
load0=$(cut -d' ' -f1-3 /proc/loadavg)
BIN=$BIN pipelines/render $S "$TMP/passes" PASSES=$((RUNS + 1)) PHOTONS=$P WIDTH=$size HEIGHT=$size KEEP=all >"$TMP/passes.log"
# one line per pass after the first: pass_s, compute, I/O, the sum of the stages' wall_s, the
# photon pipe's compute
for ((p = 2; p <= RUNS + 1; p++)); do
    D=$(printf '%s/passes/pass-%04d' "$TMP" $p)
    jq -s -r '[.[] | {w: .wall_s, io: ((.read_s // 0) + (.write_s // 0) + (.spool_alone_s // .spool_s // 0)),
        c: (if .stage == "trace-photons" or .stage == "trace-gather-points" then .trace_s
            elif .stage == "build-photonmap" then .build_s + (.gather_s // 0) + (.width_s // 0)
            elif .stage == "hilbert-sort" then .keys_s + .sort_s
            elif .stage == "composite" then 0
            else (.radius_s // 0) + .gather_s end),
        ph: (if .stage == "trace-photons" then .trace_s
             elif .stage == "build-photonmap" then .build_s + (.gather_s // 0) + (.width_s // 0) else 0 end)}] |
        "\(map(.c) | add) \(map(.io) | add) \(map(.w) | add) \(map(.ph) | add)"' "$D"/stats/*.json |
        awk -v ps="$(cat "$D/pass_s")" '{ print ps, $1, $2, $3, $4 }'
done >"$TMP/passes.txt"
load1=$(cut -d' ' -f1-3 /proc/loadavg)
med() { awk "{ print $1 }" "$TMP/passes.txt" | sort -g | awk '{ v[NR] = $1 } END { printf "%.3f", v[int((NR + 1) / 2)] }'; }
ps_m=$(med '$1') comp_m=$(med '$2') io_m=$(med '$3') unseen_m=$(med '$4 - $2 - $3') outside_m=$(med '$1 - $4')
photon_m=$(med '$5')
frac=$(med '($1 - $2) / $1')
frac_min=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | head -1)
frac_max=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | tail -1)
ufrac=$(med '($1 - $2 + $5) / $1')
ufrac_min=$(awk '{ print ($1 - $2 + $5) / $1 }' "$TMP/passes.txt" | sort -g | head -1)
ufrac_max=$(awk '{ print ($1 - $2 + $5) / $1 }' "$TMP/passes.txt" | sort -g | tail -1)
pct() { awk -v f="$1" -v a="$2" -v b="$3" 'BEGIN { printf "%.1f%% (%.1f%% to %.1f%%)", 100 * f, 100 * a, 100 * b }'; }
rm -rf "$TMP/passes" "$TMP/passes.txt" "$TMP/passes.log"
cat >>"$MD" <<MD

## Progressive passes: the overhead of a pass

\`pipelines/render PASSES=$((RUNS + 1)) KEEP=all\` (the pass files) on the Cornell box, ${size}x${size} pixels, $P photons per pass,
render's per-pass defaults for the rest (16 primary rays and 4 secondary per pixel, K 5, the boundary correction: \`COVERAGE=auto\`, whose simd-gather samples the scene's surfaces anew in every pass file, about 2 s of the "untimed work" here at the Cornell box's 2-mm kernel; the resident passes sample once a spacing level); the first pass is left out. A pass's wall time is everything render does for
it (the graph, make, every stage, \`composite --accumulate\`, its bookkeeping); the compute is
the sum of the stages' compute timers (tests/bench/92-passes.sh names them). The
overhead is the rest, as a fraction of the pass (median over $RUNS passes, min to max in
brackets); the goal is below 10%. Load average (1, 5, 15 min) from other jobs: $load0 before
the run, $load1 after it; with other jobs on the cores every time here stretches, the compute
timers too.

| pass s | compute s | of which the photon pipe's s | stages' file reading and writing s | stages' untimed work s | outside the stages s | overhead | overhead, the photon pipe's compute not counted |
|---|---|---|---|---|---|---|---|
| $ps_m | $comp_m | $photon_m | $io_m | $unseen_m | $outside_m | $(pct "$frac" "$frac_min" "$frac_max") | $(pct "$ufrac" "$ufrac_min" "$ufrac_max") |

A pass runs trace-photons | build-photonmap beside trace-gather-points | hilbert-sort, and
simd-gather (which streams the sorted queries a chunk at a time) once the map is in place, so
the photon pipe's compute timers and the eye tracer's run at once on the same cores and their
sum can count the same wall seconds twice: the true overhead lies between the two columns, the
last one being what it would be if all of the photon pipe's compute were hidden under the other
stages' timers. "Stages' untimed work" is scene loading and Embree's BVH build in the two
tracers, and the rest of each stage outside its compute and I/O timers; "outside the stages" is
process start and exit, render's own work per pass, less the overlap of the stages that run at
once (negative when they overlap more than render adds). The stages of a pipe also count, in
their read_s and write_s, the time they wait for each other. What a pass spends where, and what
was done about it, is in [pipelines.md](pipelines.md) ("The cost of a pass").
MD
