# pixels.sh: pixels are areas (docs/programs/trace-gather-points.md, --pixel). A sharp vertical
# edge at a known sub-pixel position (tests/scenes/edge: an emitter that reflects nothing, its
# side a quarter into column 2 of 8) has box-filtered pixels known in closed form, the covered
# fraction times Ke: 1, 1, 0.25, 0, ... of Ke = (1, 0.5, 0.25) W/(m^2 sr). Checked through
# trace-gather-points' direct buffer and trace-reference's radiance buffer; --pixel center
# (every ray through the centre, which column 2's misses) must fail the same check.
# programs: measure-error trace-gather-points trace-reference
EDGE=tests/scenes/edge/scene.json
T=$BIN/trace-gather-points
R=$BIN/trace-reference

# covered FILE WIDTH TOL: every pixel of a radiance buffer is Ke times its column's covered
# fraction (the edge at image x = WIDTH * 9 / 32) within TOL, relative to Ke; prints the worst.
covered() {
    "$BIN/pm-info" -r "$1" | grep -E '^[0-9]' | awk -v w="$2" -v tol="$3" '
        BEGIN { split("1 0.5 0.25", ke, " "); e = w * 9 / 32 }
        { c = $1 % w; f = e - c; f = f < 0 ? 0 : f > 1 ? 1 : f
          for (k = 1; k <= 3; k++) { d = $(k + 1) - f * ke[k]; d = (d < 0 ? -d : d) / ke[k]; if (d > worst) { worst = d; at = $1 } }
          n++ }
        END { printf "worst deviation %.3g of Ke at pixel %d over %d pixels", worst, at, n; exit !(n > 0 && worst <= tol) }'
}

# Stratified rays: the first 4 (and 64) rays of a pixel put exactly a quarter of them left of
# a quarter of its width, so the edge column is exact, not only right on average.
for n in 4 64; do
    "$T" "$EDGE" -q --primary $n -o "$TMP/q$n.pm" --direct "$TMP/d$n.pm"
    why=$(covered "$TMP/d$n.pm" 8 1e-6) && pass "trace-gather-points --primary $n: the edge pixels are the covered fraction of Ke ($why)" ||
        fail "trace-gather-points --primary $n: box-filtered edge" "$why"
    "$T" "$EDGE" -q --primary $n --pixel center -o "$TMP/qc.pm" --direct "$TMP/dc$n.pm"
    why=$(covered "$TMP/dc$n.pm" 8 1e-6) && fail "trace-gather-points --primary $n --pixel center" "passed the area check: $why" ||
        pass "trace-gather-points --primary $n --pixel center fails the area check ($why)"
done
# Away from the edge the rule changes nothing (a constant-radiance region is the same image).
if diff <("$BIN/pm-info" -r "$TMP/d4.pm" | grep -E '^[0-9]' | awk '$1 % 8 != 2') \
    <("$BIN/pm-info" -r "$TMP/dc4.pm" | grep -E '^[0-9]' | awk '$1 % 8 != 2') >/dev/null; then
    pass "--pixel box and center agree exactly on every pixel the edge does not cross"
else
    fail "box and center off the edge" "pixels away from the edge differ"
fi
grep -aq '^pixel=box$' "$TMP/d4.pm" && grep -aq '^pixel=box$' "$TMP/q4.pm" && grep -aq '^pixel=center$' "$TMP/qc.pm" &&
    pass "both outputs' headers say the pixel rule" || fail "pixel key" "$(grep -a '^pixel' "$TMP/d4.pm" "$TMP/qc.pm")"

# One ray a pixel (the default) is one uniform point over it: at 40 x 40 the edge column (11,
# a quarter covered) is lit in about a quarter of its 40 pixels, where centres light none.
"$T" "$EDGE" -q --width 40 --height 40 -o "$TMP/q1.pm" --direct "$TMP/d1.pm"
m=$("$BIN/pm-info" -r "$TMP/d1.pm" | grep -E '^[0-9]' | awk '$1 % 40 == 11 { s += $2; n++; if ($2 != 0 && $2 != 1) odd++ }
    END { printf "%.4f", odd ? -1 : s / n }')
awk -v m="$m" 'BEGIN { exit !(m > 0.05 && m < 0.45) }' &&
    pass "one ray a pixel: the edge column's mean is $m of Ke (expected 0.25, standard error 0.07)" ||
    fail "one ray a pixel" "the edge column's mean is $m of Ke, expected 0.25 +- 0.2 (-1: a value neither 0 nor Ke)"
expect_exit "--pixel rejects an unknown rule" 2 "$T" "$EDGE" --pixel gauss -o "$TMP/x.pm"

# trace-reference: sample k of a pixel at point k of its scrambled (0,2)-sequence, so every 4
# samples split a pixel into quarters, across passes too (--pass 2, --pass 16).
for args in "--spp 4 --pass 2" "--spp 64"; do
    "$R" "$EDGE" -q $args --radiance "$TMP/r.pm" -o "$TMP/r.exr"
    why=$(covered "$TMP/r.pm" 8 1e-6) && pass "trace-reference $args: the edge pixels are the covered fraction of Ke ($why)" ||
        fail "trace-reference $args: box-filtered edge" "$why"
done
"$R" "$EDGE" -q --spp 64 --pixel center --radiance "$TMP/rc.pm" -o "$TMP/rc.exr"
why=$(covered "$TMP/rc.pm" 8 1e-6) && fail "trace-reference --pixel center" "passed the area check: $why" ||
    pass "trace-reference --pixel center fails the area check ($why)"
# The two programs agree pixel for pixel: the reference the photon pipeline is measured against
# filters its pixels the same way.
e=$("$BIN/measure-error" "$TMP/d64.pm" "$TMP/r.pm" | jq -r .rmse)
awk -v e="$e" 'BEGIN { exit !(e != "" && e < 1e-6) }' &&
    pass "trace-gather-points --primary 64 and trace-reference --spp 64 give the same image (rmse $e)" ||
    fail "trace-gather-points against trace-reference on the edge" "rmse '$e'"
