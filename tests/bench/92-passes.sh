# 92-passes.sh: what a progressive pass costs beyond its computing (sourced by tests/bench/run).
# pipelines/render PASSES=RUNS+1 on the Cornell box at 256x256 with 500,000 photons per pass;
# the first pass (cold caches, --k measuring r_1) is left out. For each other pass: its wall
# time (render's pass_s: the graph written, make, every stage, composite --accumulate and the
# bookkeeping after it) against the sum of the stages' compute timers from their --stats:
# trace-photons trace_s, build-photonmap build_s + gather_s + width_s, trace-gather-points
# trace_s, hilbert-sort keys_s + sort_s, the gather radius_s + gather_s (composite's work is
# reading and writing). The rest is the overhead, split into the stages' reading and writing
# (read_s + write_s + spool_s: checksums included), what else the stages spend unseen by their
# timers (scene loading, Embree's BVH build, allocation: wall_s less compute and I/O), and what
# is outside the stages' own wall_s: process start and exit, render's own work (stamps, make,
# hashing the buffers, pm-info on the running image), less the overlap of the stages that
# run at once in a pipe (a pass pipes trace-photons into build-photonmap, and
# trace-gather-points into hilbert-sort into the gather).
P=500000 size=256
[ "$QUICK" = 1 ] && P=100000 size=128
S=scenes/cornell-box/scene.json
rm -rf "$TMP/passes"
BIN=$BIN pipelines/render $S "$TMP/passes" PASSES=$((RUNS + 1)) PHOTONS=$P WIDTH=$size HEIGHT=$size >"$TMP/passes.log"
# one line per pass after the first: pass_s, compute, I/O, the sum of the stages' wall_s
for ((p = 2; p <= RUNS + 1; p++)); do
    D=$(printf '%s/passes/pass-%04d' "$TMP" $p)
    jq -s -r '[.[] | {w: .wall_s, io: ((.read_s // 0) + (.write_s // 0) + (.spool_s // 0)),
        c: (if .stage == "trace-photons" or .stage == "trace-gather-points" then .trace_s
            elif .stage == "build-photonmap" then .build_s + (.gather_s // 0) + (.width_s // 0)
            elif .stage == "hilbert-sort" then .keys_s + .sort_s
            elif .stage == "composite" then 0
            else (.radius_s // 0) + .gather_s end)}] |
        "\(map(.c) | add) \(map(.io) | add) \(map(.w) | add)"' "$D"/stats/*.json |
        awk -v ps="$(cat "$D/pass_s")" '{ print ps, $1, $2, $3 }'
done >"$TMP/passes.txt"
med() { awk "{ print $1 }" "$TMP/passes.txt" | sort -g | awk '{ v[NR] = $1 } END { printf "%.3f", v[int((NR + 1) / 2)] }'; }
ps_m=$(med '$1') comp_m=$(med '$2') io_m=$(med '$3') unseen_m=$(med '$4 - $2 - $3') outside_m=$(med '$1 - $4')
frac=$(med '($1 - $2) / $1')
frac_min=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | head -1)
frac_max=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | tail -1)
rm -rf "$TMP/passes" "$TMP/passes.txt" "$TMP/passes.log"
cat >>"$MD" <<MD

## Progressive passes: the overhead of a pass

\`pipelines/render PASSES=$((RUNS + 1))\` on the Cornell box, ${size}x${size} pixels, $P photons per pass,
render's per-pass defaults for the rest (16 primary rays and 4 secondary per pixel, K 5); the first pass is left out. A pass's wall time is everything render does for
it (the graph, make, every stage, \`composite --accumulate\`, its bookkeeping); the compute is
the sum of the stages' compute timers (tests/bench/92-passes.sh names them). The
overhead is the rest, as a fraction of the pass (median over $RUNS passes, min to max in
brackets); the goal is below 10%.

| pass s | compute s | stages' file reading and writing s | stages' untimed work s | outside the stages s | overhead |
|---|---|---|---|---|---|
| $ps_m | $comp_m | $io_m | $unseen_m | $outside_m | $(awk -v f="$frac" -v a="$frac_min" -v b="$frac_max" 'BEGIN { printf "%.1f%% (%.1f%% to %.1f%%)", 100 * f, 100 * a, 100 * b }') |

"Stages' untimed work" is scene loading and Embree's BVH build in the two tracers, and the
rest of each stage outside its compute and I/O timers; "outside the stages" is process start
and exit, render's own work per pass, less the overlap of the two pipes of a pass
(trace-photons into build-photonmap, trace-gather-points into hilbert-sort into the gather),
which run their stages at once. The stages of a pipe also count, in their read_s and
write_s, the time they wait for each other.
MD
