# error-vs-time.sh: pipelines/error-vs-time renders every combination it is asked for, times
# each from its stages, measures each against the reference, and keeps the best per budget.
E=pipelines/error-vs-time
CORNELL=scenes/cornell-box/scene.json
SIZE="WIDTH=16 HEIGHT=16"

# The reference is a render with exactly one of the sweep's settings (and the same seed), so
# that row must measure zero error and every other row more than zero.
pipelines/render "$CORNELL" "$TMP/ref" PHOTONS=20000 SPP=4 K=40 LEAF=16 $SIZE >/dev/null 2>&1 ||
    fail "error-vs-time reference render" "pipelines/render failed"
out=$TMP/sweep
$E "$CORNELL" "$out" PHOTONS=10000,20000 SPP=4 K="10 40" LEAF=16 $SIZE PT_SPP= \
    REFERENCE="$TMP/ref/image.exr" >"$TMP/evt.log" 2>&1
status=$?
csv=$out/results.csv
if [ $status = 0 ] && [ -s "$csv" ] && [ -s "$out/pareto.csv" ] && [ -s "$out/summary.md" ]; then
    pass "error-vs-time writes results.csv, pareto.csv and summary.md"
else
    fail "error-vs-time run" "exit $status: $(tail -3 "$TMP/evt.log")"
fi
if [ "$(head -c 8 "$out/error-vs-time.png" 2>/dev/null | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ]; then
    pass "error-vs-time draws a PNG plot"
else
    fail "error-vs-time plot" "no PNG at $out/error-vs-time.png: $(cat "$out/gnuplot.log" 2>/dev/null | head -3)"
fi
rows=$(tail -n +2 "$csv" | wc -l)
[ "$rows" = 4 ] && pass "one row per combination (2 photon counts x 2 K)" || fail "error-vs-time rows" "$rows rows, expected 4"
# The row rendered exactly as the reference measures zero; every other one more than zero.
zero=$(awk -F, 'NR > 1 && $2 == 20000 && $5 == 40 { print $16 }' "$csv")
others=$(awk -F, 'NR > 1 && !($2 == 20000 && $5 == 40) && $16 > 0 { n++ } END { print n + 0 }' "$csv")
if [ "$zero" = 0 ] && [ "$others" = 3 ]; then
    pass "the reference's own settings measure zero error, the others more"
else
    fail "error-vs-time errors" "same-settings relmse '$zero', $others of 3 others above zero"
fi
# Every number is finite and the total is the sum of the stages.
if awk -F, 'NR > 1 {
        for (i = 6; i <= NF; i++) if ($i !~ /^[0-9.eE+-]+$/) { print "column " i ": " $i; bad = 1 }
        s = $9 + $10 + $11 + $12 + $13 + $14
        if (s - $7 > 1e-6 || $7 - s > 1e-6) { print "total " $7 " != sum " s; bad = 1 }
    } END { exit bad }' "$csv" >"$TMP/evt.bad"; then
    pass "every figure is a finite number and the total is the sum of the stages"
else
    fail "error-vs-time figures" "$(head -3 "$TMP/evt.bad")"
fi
# The front is in increasing time with strictly decreasing error, and holds the best row.
if awk -F, 'NR > 2 && !($7 >= t && $16 < e) { bad = 1 } NR > 1 { t = $7; e = $16 } END { exit bad }' "$out/pareto.csv" &&
    [ "$(tail -n 1 "$out/pareto.csv" | cut -d, -f16)" = 0 ]; then
    pass "pareto.csv runs faster to slower with falling error and ends at the best"
else
    fail "error-vs-time front" "$(cat "$out/pareto.csv")"
fi
grep -q '^| [0-9.e+-]* s | simd-gather, 20000 photons, 4 spp, leaf 16, K 40 |' "$out/summary.md" &&
    pass "summary.md names the best setting at a budget" || fail "error-vs-time summary" "$(cat "$out/summary.md")"

expect_exit "error-vs-time: unknown parameter" 2 $E "$CORNELL" "$TMP/x" NOPE=1
expect_exit "error-vs-time: a list with a word that is not a number" 2 $E "$CORNELL" "$TMP/x" K="10 ten"
expect_exit "error-vs-time: missing scene" 1 $E "$TMP/missing.json" "$TMP/x"
expect_exit "error-vs-time: unreadable reference" 1 $E "$CORNELL" "$TMP/x" REFERENCE="$TMP/none.exr" PT_SPP= PLOT=0 $SIZE

# With trace-reference: its own curve, made against a reference it made itself and kept. 1 and
# 64 samples: with area pixels a pixel that holds a sliver of the light is heavy-tailed in
# relative error at a few samples (one hit of the light in 16 samples is 16 times its mean).
out=$TMP/pt
$E "$CORNELL" "$out" PHOTONS=10000 SPP=4 K=20 PT_SPP="1 64" REF_SPP=64 $SIZE PLOT=0 >"$TMP/pt.log" 2>&1
status=$?
pt1=$(awk -F, '$1 == "trace-reference" && $3 == 1 { print $16 }' "$out/results.csv" 2>/dev/null)
pt16=$(awk -F, '$1 == "trace-reference" && $3 == 64 { print $16 }' "$out/results.csv" 2>/dev/null)
if [ $status = 0 ] && [ -s "$out/reference.exr" ] && [ -n "$pt1" ] && [ -n "$pt16" ] &&
    awk -v a="$pt1" -v b="$pt16" 'BEGIN { exit !(b > 0 && b < a / 4) }'; then
    pass "the path tracer's curve falls with its samples (relmse $pt1 at 1 spp, $pt16 at 64)"
else
    fail "error-vs-time path tracer curve" "exit $status, relmse '$pt1' and '$pt16': $(tail -3 "$TMP/pt.log")"
fi
touch -d '2000-01-01' "$out/reference.exr"
$E "$CORNELL" "$out" PHOTONS=10000 SPP=4 K=20 PT_SPP= REF_SPP=64 $SIZE PLOT=0 >"$TMP/pt2.log" 2>&1
if [ "$(stat -c %Y "$out/reference.exr")" = "$(date -d '2000-01-01' +%s)" ] && ! grep -q 'reference: trace-reference' "$TMP/pt2.log"; then
    pass "the reference is made once and kept for the same scene, size and samples"
else
    fail "error-vs-time reference cache" "the reference was made again: $(head -2 "$TMP/pt2.log")"
fi
