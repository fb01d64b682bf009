# 60-widths.sh: variable against fixed kernel widths, error against time (sourced by
# tests/bench/run). Direct visualization of the Cornell box (the queries are the primary
# hits, so the error is the density estimate's own, without final-gather noise), against a
# reference of 8 million photons gathered with K = 400. Error: relative RMS error over all
# pixels, and over the darkest quarter of the lit pixels (the sparsely lit regions where the
# variable-width estimator should help). Time: trace-photons + build-photonmap (with the
# widths for the variable estimator) + simd-gather, wall seconds, median of RUNS.
S=scenes/cornell-box/scene.json
REFP=8000000 PS="100000 200000 400000 800000" KS="50 100" DV=256
[ "$QUICK" = 1 ] && REFP=1000000 PS="50000 200000" KS=50 DV=128
"$BIN/trace-gather-points" $S --mode direct-vis --width $DV --height $DV -q -o "$TMP/w-q0.pm" --direct "$TMP/w-d.pm"
"$BIN/hilbert-sort" "$TMP/w-q0.pm" -q -o "$TMP/w-q.pm"
"$BIN/trace-photons" $S -n $REFP --seed 99 -q -o "$TMP/w-ph.pm"
"$BIN/build-photonmap" "$TMP/w-ph.pm" -q -o "$TMP/w-map.pm"
"$BIN/simd-gather" "$TMP/w-map.pm" "$TMP/w-q.pm" --k 400 -q -o "$TMP/w-ref.pm"
"$BIN/pm-info" -r "$TMP/w-ref.pm" | awk '$1 ~ /^[0-9]+$/ { print $2 + $3 + $4 }' >"$TMP/w-ref.txt"
dark=$(awk '$1 > 0' "$TMP/w-ref.txt" | sort -g | awk '{ v[NR] = $1 } END { print v[int(NR / 4)] }')
# errors TEST.pm: "all dark" relative RMS errors against the reference
errors() {
    "$BIN/pm-info" -r "$1" | awk '$1 ~ /^[0-9]+$/ { print $2 + $3 + $4 }' | paste - "$TMP/w-ref.txt" |
        awk -v q="$dark" '{ d = $1 - $2; se += d * d; rs += $2; n++; if ($2 > 0 && $2 <= q) { sd += d * d; nd++; rd += $2 } }
            END { printf "%.4f %.4f\n", sqrt(se / n) / (rs / n), sqrt(sd / nd) / (rd / nd) }'
}
render() { # render P K fixed|variable: one timed pipeline
    "$BIN/trace-photons" $S -n "$1" -q -o "$TMP/w-p.pm"
    if [ "$3" = fixed ]; then
        "$BIN/build-photonmap" "$TMP/w-p.pm" -q -o "$TMP/w-m.pm"
        "$BIN/simd-gather" "$TMP/w-m.pm" "$TMP/w-q.pm" --k "$2" -q -o "$TMP/w-o.pm"
    else
        "$BIN/build-photonmap" "$TMP/w-p.pm" --width-k "$2" -q -o "$TMP/w-m.pm"
        "$BIN/simd-gather" "$TMP/w-m.pm" "$TMP/w-q.pm" --widths variable -q -o "$TMP/w-o.pm"
    fi
}
export -f render
export S
rows=""
for P in $PS; do
    for K in $KS; do
        for mode in fixed variable; do
            read -r t _ _ < <(median_spread bash -c "render $P $K $mode")
            read -r ea ed < <(errors "$TMP/w-o.pm")
            rows+="| $P | $K | $mode | $(printf '%.3f' "$t") | $ea | $ed |"$'\n'
        done
    done
done
rm -f "$TMP"/w-*.pm "$TMP/w-ref.txt"
cat >>"$MD" <<MD

## Variable against fixed kernel widths

Direct visualization of the Cornell box (${DV}x${DV}, queries at the primary hits), against
$REFP photons gathered with K = 400. "fixed": one radius, chosen by \`--k K\`; "variable":
each photon's width holds K photons around it (\`build-photonmap --width-k K\`,
\`simd-gather --widths variable\`). Time: trace-photons + build-photonmap (+ widths) +
simd-gather, wall seconds. Error: relative RMS error over all pixels and over the darkest
quarter of the lit pixels. Goal (issue 6): variable widths more accurate in sparsely lit
regions at equal time.

| photons | K | widths | time s | error, all | error, dark quarter |
|---|---|---|---|---|---|
${rows}
MD
