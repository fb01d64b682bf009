# 55-leaf-gather.sh: hilbert-sort's leaf size against reorder time plus gather time
# (sourced by tests/bench/run): the curve issue 5's --leaf auto is about, with the gather
# half measured. The Cornell box's queries at 256x256 and 16 samples per pixel, 500,000
# photons, the radius for about 50 photons per query; both stages on 2 threads; medians of
# RUNS runs of the stages' own timers (reorder, gather), so that file reading does not count.
P=500000 size=256
[ "$QUICK" = 1 ] && P=100000 size=96
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons $P -q -o "$TMP/l-ph.pm"
"$BIN/build-photonmap" "$TMP/l-ph.pm" -q -o "$TMP/l-map.pm"
"$BIN/trace-gather-points" scenes/cornell-box/scene.json --width $size --height $size --spp 16 -q \
    -o "$TMP/l-q.pm" --direct "$TMP/l-d.pm"
"$BIN/simd-gather" "$TMP/l-map.pm" "$TMP/l-q.pm" --k 50 -q -o "$TMP/l-o.pm" --stats "$TMP/stats.json"
R=$(grep -o '"radius_m": *[0-9.eE+-]*' "$TMP/stats.json" | sed 's/.*: *//')
rows=""
for leaf in 1 2 4 8 16 32 64 256 1024 4096 auto none; do
    if [ $leaf = none ]; then
        cp "$TMP/l-q.pm" "$TMP/l-s.pm"
        sort_s=0 chosen=-
    else
        read -r sort_s _ _ < <(median_stat reorder_s "$BIN/hilbert-sort" "$TMP/l-q.pm" --leaf $leaf -q -o "$TMP/l-s.pm" \
            --stats "$TMP/stats.json")
        chosen=$(grep -o '"leaf": *[0-9]*' "$TMP/stats.json" | sed 's/.*: *//')
    fi
    for isa in avx512 sse4; do
        case $isa in avx512) flag=avx512f ;; *) flag=sse4_1 ;; esac
        grep -qw $flag /proc/cpuinfo || continue
        read -r g _ _ < <(median_stat gather_s "$BIN/simd-gather" "$TMP/l-map.pm" "$TMP/l-s.pm" --radius "$R" --isa $isa -q \
            -o "$TMP/l-o.pm" --stats "$TMP/stats.json")
        lanes=$(grep -o '"active_lane_fraction": *[0-9.eE+-]*' "$TMP/stats.json" | sed 's/.*: *//')
        rows+=$(awk -v l=$leaf -v c="${chosen:--}" -v i=$isa -v s=$sort_s -v g=$g -v f=$lanes 'BEGIN {
            printf "| %s | %s | %s | %.4f | %.4f | %.4f | %.0f%% |\n", l, c, i, s, g, s + g, 100 * f }')
        rows+=$'\n'
    done
done
rm -f "$TMP"/l-*.pm
cat >>"$MD" <<MD

## Reorder leaf against reorder plus gather time

hilbert-sort \`--leaf\` on the Cornell box's queries (${size}x${size}, 16 samples per pixel), then
simd-gather with $P photons and radius $R m; seconds from the stages' own timers (reorder_s,
gather_s), 2 threads. "none" gathers the queries in the order trace-gather-points wrote them.
The sum is what \`--leaf auto\` should minimize (issue 5); "chosen" is the leaf the run used.

| --leaf | chosen | gather ISA | reorder s | gather s | sum s | active lanes |
|---|---|---|---|---|---|---|
${rows}
MD
