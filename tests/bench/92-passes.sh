# 92-passes.sh: what a progressive pass costs beyond its computing (sourced by tests/bench/run).
# pipelines/render PASSES=RUNS+1 on the Cornell box at 256x256 with 500,000 photons per pass;
# the first pass (cold caches, --k measuring r_1) is left out. For each other pass: its wall
# time (render's pass_s: the graph written, make, every stage, composite --accumulate and the
# bookkeeping after it) against the sum of the stages' compute timers, each stage's wall_s
# less the read_s and write_s it reports (what it spends on its own work, from its --stats).
# The rest is the overhead, split into: the stages' reading and writing of their files
# (read_s + write_s, checksums included), process start and exit (the stage times render
# measures from outside, less the stages' own wall_s), and render's own work per pass (stamps,
# make, hashing the buffers, pm-info on the running image).
P=500000 size=256
[ "$QUICK" = 1 ] && P=100000 size=128
S=scenes/cornell-box/scene.json
rm -rf "$TMP/passes"
BIN=$BIN pipelines/render $S "$TMP/passes" PASSES=$((RUNS + 1)) PHOTONS=$P WIDTH=$size HEIGHT=$size >"$TMP/passes.log"
# one line per pass after the first: pass_s compute io stage_times stage_walls
for ((p = 2; p <= RUNS + 1; p++)); do
    D=$(printf '%s/passes/pass-%04d' "$TMP" $p)
    jq -s '[.[] | {w: .wall_s, io: ((.read_s // 0) + (.write_s // 0))}] |
        "\(map(.w - .io) | add) \(map(.io) | add) \(map(.w) | add)"' -r "$D"/stats/*.json |
        awk -v ps="$(cat "$D/pass_s")" -v st="$(cat "$D"/times/* | awk '{ s += $1 } END { print s }')" \
            '{ print ps, $1, $2, st, $3 }'
done >"$TMP/passes.txt"
med() { awk "{ print $1 }" "$TMP/passes.txt" | sort -g | awk '{ v[NR] = $1 } END { printf "%.3f", v[int((NR + 1) / 2)] }'; }
ps_m=$(med '$1') comp_m=$(med '$2') io_m=$(med '$3') start_m=$(med '$4 - $5') own_m=$(med '$1 - $4')
frac=$(med '($1 - $2) / $1')
frac_min=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | head -1)
frac_max=$(awk '{ print ($1 - $2) / $1 }' "$TMP/passes.txt" | sort -g | tail -1)
rm -rf "$TMP/passes" "$TMP/passes.txt" "$TMP/passes.log"
cat >>"$MD" <<MD

## Progressive passes: the overhead of a pass

\`pipelines/render PASSES=$((RUNS + 1))\` on the Cornell box, ${size}x${size} pixels, $P photons per pass,
the scene's spp; the first pass is left out. A pass's wall time is everything render does for
it (the graph, make, every stage, \`composite --accumulate\`, its bookkeeping); the compute is
the sum over the stages of their own wall_s less the read_s and write_s they report. The
overhead is the rest, as a fraction of the pass (median over $RUNS passes, min to max in
brackets); the goal is below 10%.

| pass s | compute s | stages' file reading and writing s | process start and exit s | render's own s | overhead |
|---|---|---|---|---|---|
| $ps_m | $comp_m | $io_m | $start_m | $own_m | $(awk -v f="$frac" -v a="$frac_min" -v b="$frac_max" 'BEGIN { printf "%.1f%% (%.1f%% to %.1f%%)", 100 * f, 100 * a, 100 * b }') |
MD
