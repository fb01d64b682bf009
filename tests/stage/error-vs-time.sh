# error-vs-time.sh: pipelines/error-vs-time renders every combination it is asked for (primary
# rays among them), times each from its stages, measures each against the reference (an EXR
# written by composite, a PFM, or trace-reference's own with area pixels), keeps the best per
# budget, refuses a reference of another size before writing anything, and draws the
# progressive curve (a row per pass of one render) falling.
# programs: pm-render measure-error
E=pipelines/error-vs-time
CORNELL=scenes/cornell-box/scene.json
SIZE="WIDTH=16 HEIGHT=16"

# The reference is a render with exactly one of the sweep's settings (and the same seed), so
# that row must measure zero error and every other row more than zero.
pipelines/render "$CORNELL" "$TMP/ref" PHOTONS=20000 PRIMARY=1 SPP=4 K=40 LEAF=16 $SIZE >/dev/null 2>&1 ||
    fail "error-vs-time reference render" "pipelines/render failed"
out=$TMP/sweep
$E "$CORNELL" "$out" PHOTONS=10000,20000 PRIMARY="1 4" SPP=4 K="10 40" LEAF=16 $SIZE PT_SPP= PROGRESSIVE=0 \
    REFERENCE="$TMP/ref/image.exr" >"$TMP/evt.log" 2>&1
status=$?
csv=$out/results.csv
if [ $status = 0 ] && [ -s "$csv" ] && [ -s "$out/pareto.csv" ] && [ -s "$out/summary.md" ]; then
    pass "error-vs-time writes results.csv, pareto.csv and summary.md"
else
    fail "error-vs-time run" "exit $status: $(tail -3 "$TMP/evt.log")"
fi
if [ "$(head -c 8 "$out/error-vs-time.png" 2>/dev/null | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] &&
    grep -q "^set title \"cornell-box: error against run time" "$out/error-vs-time.gp"; then
    pass "error-vs-time draws a PNG plot titled with the scene's name"
else
    fail "error-vs-time plot" "no PNG at $out/error-vs-time.png or no title: $(cat "$out/gnuplot.log" 2>/dev/null | head -3)"
fi
# The title and summary name the scene by its "name", not its folder: a copy of the Cornell box
# named renamed-box in a folder called box-folder.
mkdir -p "$TMP/box-folder" && cp scenes/cornell-box/* "$TMP/box-folder/" &&
    jq '.name = "renamed-box"' scenes/cornell-box/scene.json >"$TMP/box-folder/scene.json"
$E "$TMP/box-folder/scene.json" "$TMP/named" PHOTONS=10000 PRIMARY=1 SPP=4 K=40 LEAF=16 $SIZE PT_SPP= PROGRESSIVE=0 \
    REFERENCE="$TMP/ref/image.exr" >"$TMP/named.log" 2>&1
if grep -q '^set title "renamed-box: error against run time' "$TMP/named/error-vs-time.gp" 2>/dev/null &&
    grep -q '^Scene: renamed-box\. ' "$TMP/named/summary.md" && ! grep -q 'box-folder' "$TMP/named/error-vs-time.gp"; then
    pass "error-vs-time titles the plot and the summary with the scene's name, not its folder's"
else
    fail "error-vs-time scene name" "$(grep '^set title' "$TMP/named/error-vs-time.gp" 2>/dev/null) $(tail -2 "$TMP/named.log")"
fi
# column NAME: the column of NAME in results.csv
column() { head -1 "$csv" | tr , '\n' | grep -nx "$1" | cut -d: -f1; }
ct=$(column total_s) ce=$(column relmse) cp=$(column primary)
rows=$(tail -n +2 "$csv" | wc -l)
primaries=$(tail -n +2 "$csv" | cut -d, -f"$cp" | sort -u | tr '\n' ' ')
[ "$rows" = 8 ] && [ "$primaries" = "1 4 " ] && pass "one row per combination (2 photon counts x 2 primary x 2 K)" ||
    fail "error-vs-time rows" "$rows rows (primary: $primaries), expected 8"
# The row rendered exactly as the reference measures zero; every other one more than zero.
zero=$(awk -F, -v c="$ce" -v p="$cp" 'NR > 1 && $2 == 20000 && $p == 1 && $6 == 40 { print $c }' "$csv")
others=$(awk -F, -v c="$ce" -v p="$cp" 'NR > 1 && !($2 == 20000 && $p == 1 && $6 == 40) && $c > 0 { n++ } END { print n + 0 }' "$csv")
if [ "$zero" = 0 ] && [ "$others" = 7 ]; then
    pass "the reference's own settings measure zero error, the others more"
else
    fail "error-vs-time errors" "same-settings relmse '$zero', $others of 7 others above zero"
fi
# Every number is finite, printed with a sensible number of digits (no float noise such as
# 2.1297200000000003), and the total is the sum of the stages to their rounding (1 ms each).
if awk -F, -v ct="$ct" 'NR > 1 {
        for (i = 7; i <= NF; i++) if ((i <= 20 && $i !~ /^[0-9.eE+-]+$/) || $i ~ /[0-9]{8}/) { print "column " i ": " $i; bad = 1 }
        if ($21 != "" || $22 != "") { print "passes, alpha: " $21 ", " $22; bad = 1 }
        s = 0; for (i = ct + 2; i <= ct + 7; i++) s += $i
        if ((s - $ct) ^ 2 > 0.0035 ^ 2) { print "total " $ct " != sum " s; bad = 1 }
    } END { exit bad }' "$csv" >"$TMP/evt.bad"; then
    pass "every figure is a short finite number and the total is the sum of the stages"
else
    fail "error-vs-time figures" "$(head -3 "$TMP/evt.bad")"
fi
if grep -qE '[0-9]{8}' "$TMP/evt.log"; then
    fail "error-vs-time log" "a number with float noise: $(grep -E '[0-9]{8}' "$TMP/evt.log" | head -2)"
else
    pass "the log prints its numbers to a few digits"
fi
# The front is in increasing time with strictly decreasing error, and holds the best row.
if awk -F, -v ct="$ct" -v ce="$ce" 'NR > 2 && !($ct >= t && $ce < e) { bad = 1 } NR > 1 { t = $ct; e = $ce } END { exit bad }' "$out/pareto.csv" &&
    [ "$(tail -n 1 "$out/pareto.csv" | cut -d, -f"$ce")" = 0 ]; then
    pass "pareto.csv runs faster to slower with falling error and ends at the best"
else
    fail "error-vs-time front" "$(cat "$out/pareto.csv")"
fi
grep -q '^| [0-9.e+-]* s | simd-gather, 20000 photons, 1 primary, 4 spp, leaf 16, K 40 |' "$out/summary.md" &&
    pass "summary.md names the best setting at a budget" || fail "error-vs-time summary" "$(cat "$out/summary.md")"

# A PFM reference (the same image, rows bottom first, little-endian; perl packs it): the
# renders take its size, and the reference's own settings measure zero against it. MAX_RAYS
# skips PRIMARY 4 x SPP 4.
"$BUILD/tests/pm-exrdump" "$TMP/ref/image.exr" | perl -e '
    my ($w, $h, @px); while (<STDIN>) { my @f = split; if ($f[0] eq "size") { ($w, $h) = @f[1, 2]; next }
        $px[$f[1] * $w + $f[0]] = [@f[2 .. 4]] }
    binmode STDOUT; printf "PF\n%d %d\n-1.0\n", $w, $h;
    for (my $y = $h - 1; $y >= 0; $y--) { print pack("f<" x 3, @{$px[$y * $w + $_]}) for 0 .. $w - 1 }' >"$TMP/ref.pfm"
out=$TMP/pfm
$E "$CORNELL" "$out" PHOTONS=20000 PRIMARY="1 4" SPP=4 MAX_RAYS=4 K=40 LEAF=16 PT_SPP= PLOT=0 PROGRESSIVE=0 \
    REFERENCE="$TMP/ref.pfm" >"$TMP/pfm.log" 2>&1
status=$?
row=$(tail -n +2 "$out/results.csv" 2>/dev/null)
if [ $status = 0 ] && [ "$(echo "$row" | wc -l)" = 1 ] && [ "$(echo "$row" | cut -d, -f"$ce")" = 0 ] &&
    [ "$("$BUILD/tests/pm-exrdump" "$out/runs/p20000-r1-s4/image.exr" | head -1)" = "size 16 16" ] &&
    grep -q 'skipped, more than MAX_RAYS=4 secondary rays per pixel: PRIMARY=4 SPP=4' "$TMP/pfm.log" &&
    grep -q "Reference: '.*ref.pfm' (16x16)" "$out/summary.md"; then
    pass "a PFM reference: renders at its size, the same image measures zero, MAX_RAYS skips"
else
    fail "error-vs-time PFM reference" "exit $status, row '$row': $(tail -3 "$TMP/pfm.log")"
fi
# A reference of another size than WIDTH x HEIGHT: one line, exit 2, nothing written.
$E "$CORNELL" "$TMP/wrong" PHOTONS=20000 SPP=4 K=40 WIDTH=32 HEIGHT=16 PT_SPP= PLOT=0 \
    REFERENCE="$TMP/ref.pfm" >"$TMP/wrong.out" 2>"$TMP/wrong.err"
status=$?
if [ $status = 2 ] && [ "$(wc -l <"$TMP/wrong.err")" = 1 ] && [ ! -e "$TMP/wrong" ] && [ ! -s "$TMP/wrong.out" ] &&
    grep -q "reference '.*ref.pfm' is 16x16 but the renders are 32x16" "$TMP/wrong.err"; then
    pass "a reference of another size: one line, exit 2, nothing written"
else
    fail "error-vs-time reference size" "exit $status: $(cat "$TMP/wrong.err")"
fi

expect_exit "error-vs-time: unknown parameter" 2 $E "$CORNELL" "$TMP/x" NOPE=1
expect_exit "error-vs-time: a list with a word that is not a number" 2 $E "$CORNELL" "$TMP/x" K="10 ten"
expect_exit "error-vs-time: a bad PIXEL" 2 $E "$CORNELL" "$TMP/x" PIXEL=corner
expect_exit "error-vs-time: PROG_ALPHA outside (0, 1)" 2 $E "$CORNELL" "$TMP/x" PROG_ALPHA="0.5 1"
expect_exit "error-vs-time: missing scene" 1 $E "$TMP/missing.json" "$TMP/x"
expect_exit "error-vs-time: unreadable reference" 1 $E "$CORNELL" "$TMP/x" REFERENCE="$TMP/none.exr" PT_SPP= PLOT=0 $SIZE

# With trace-reference: its own curve, made against a reference it made itself and kept. 1 and
# 64 samples: with area pixels a pixel that holds a sliver of the light is heavy-tailed in
# relative error at a few samples (one hit of the light in 16 samples is 16 times its mean).
out=$TMP/pt
$E "$CORNELL" "$out" PHOTONS=10000 SPP=4 K=20 PT_SPP="1 64" REF_SPP=64 $SIZE PLOT=0 PROGRESSIVE=0 >"$TMP/pt.log" 2>&1
status=$?
pt1=$(awk -F, -v c="$ce" '$1 == "trace-reference" && $4 == 1 { print $c }' "$out/results.csv" 2>/dev/null)
pt16=$(awk -F, -v c="$ce" '$1 == "trace-reference" && $4 == 64 { print $c }' "$out/results.csv" 2>/dev/null)
if [ $status = 0 ] && [ -s "$out/reference.exr" ] && [ -n "$pt1" ] && [ -n "$pt16" ] &&
    awk -v a="$pt1" -v b="$pt16" 'BEGIN { exit !(b > 0 && b < a / 4) }' &&
    [ "$("$BUILD/tests/pm-exrdump" "$out/reference.exr" pixel)" = box ] &&
    [ "$("$BUILD/tests/pm-exrdump" "$out/runs/pt-64.exr" pixel)" = box ]; then
    pass "the reference and the path tracer's curve have area pixels; the curve falls (relmse $pt1 at 1 spp, $pt16 at 64)"
else
    fail "error-vs-time path tracer curve" "exit $status, relmse '$pt1' and '$pt16': $(tail -3 "$TMP/pt.log")"
fi
touch -d '2000-01-01' "$out/reference.exr"
$E "$CORNELL" "$out" PHOTONS=10000 SPP=4 K=20 PT_SPP= REF_SPP=64 $SIZE PLOT=0 PROGRESSIVE=0 >"$TMP/pt2.log" 2>&1
if [ "$(stat -c %Y "$out/reference.exr")" = "$(date -d '2000-01-01' +%s)" ] && ! grep -q 'reference: trace-reference' "$TMP/pt2.log"; then
    pass "the reference is made once and kept for the same scene, size and samples"
else
    fail "error-vs-time reference cache" "the reference was made again: $(head -2 "$TMP/pt2.log")"
fi

# The progressive curve: one render of 6 passes gives 6 rows, pass 1 to 6 in growing wall time
# from the start of that render (the last within the render's own total), drawn as one line;
# the error falls with the passes. The reference has 256 samples per pixel (its floor is well
# below the sixth pass's error), and 6 passes of a noisy 16 x 16 image should cut the relative
# MSE about 4 times: the check asks for 2, and fails when the rows repeat pass 1's image.
out=$TMP/prog
$E "$CORNELL" "$out" PHOTONS=10000 PRIMARY=1 SPP=4 K=20 PT_SPP= REF_SPP=256 $SIZE \
    PROG_PASSES=6 PROG_PHOTONS=20000 PROG_PRIMARY=1 PROG_SPP=4 PROG_K=20 >"$TMP/prog.log" 2>&1
status=$?
cpass=$(column passes)
prog=$(awk -F, -v ct="$ct" -v ce="$ce" -v cp="$cpass" '$1 == "progressive" { print $cp, $ct, $ce }' "$out/results.csv" 2>/dev/null)
render_s=$(jq -r .total.wall_s "$out/runs/prog-photons20000-primary1-spp4-k20/stats.json" 2>/dev/null)
if [ $status = 0 ] && [ "$(echo "$prog" | cut -d' ' -f1 | tr '\n' ' ')" = "1 2 3 4 5 6 " ] &&
    echo "$prog" | awk -v r="$render_s" 'NR > 1 && $2 <= t { bad = 1 } { t = $2 } NR == 1 { e1 = $3 } END { exit bad || !(t <= r && $3 < e1 / 2) }' &&
    [ "$(wc -l <"$out/curve-progressive-3.csv" 2>/dev/null)" = 6 ] &&
    grep -q "curve-progressive-3.csv' using .* title 'progressive, 20000 photons, 1 primary, 4 spp per pass, K 20, alpha 0.6667'" "$out/error-vs-time.gp" &&
    [ "$(head -c 8 "$out/error-vs-time.png" 2>/dev/null | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ]; then
    pass "the progressive curve: a row per pass in growing time within the render's, falling ($(echo "$prog" | awk 'NR == 1 { a = $3 } END { print a " to " $3 }'))"
else
    fail "error-vs-time progressive curve" "exit $status, rows (pass, s, relmse): $(echo $prog), render $render_s s: $(tail -3 "$TMP/prog.log")"
fi

# error-vs-time-all: every scene's curves (SWEEP=0: the path tracer's and the progressive
# alone), then one table of progressive / path tracer per budget and the fitted slopes. Two
# scenes on tiny images: the Cornell box and the skylight room (by folder name).
out=$TMP/all
pipelines/error-vs-time-all "$out" SCENES="cornell-box skylight" $SIZE REF_SPP=64 PT_SPP="1 16" PROG_TIME=30 PROG_PASSES=3 \
    PROG_PHOTONS=20000 PROG_PRIMARY=1 PROG_SPP=4 PROG_K=20 BUDGETS="0.5 1 30" SLOPE_FROM=0.01 SLOPE_TO=30 PLOT=0 \
    >"$TMP/all.log" 2>&1
status=$?
# every ratio is the progressive relMSE over the path tracer's of its row, and at 30 s (after
# every image) the progressive one is its last pass and the path tracer's its best
last_prog=$(awk -F, -v ce="$ce" -v cp="$cpass" '$1 == "progressive" { e = $ce; p = $cp } END { print e, p }' "$out/cornell-box/results.csv" 2>/dev/null)
best_pt=$(awk -F, -v ce="$ce" '$1 == "trace-reference" && (b == "" || $ce < b) { b = $ce } END { print b }' "$out/cornell-box/results.csv" 2>/dev/null)
row30=$(awk -F, '$1 == "cornell-box" && $2 == 30 { print $3, $4, $6 }' "$out/ratios.csv" 2>/dev/null)
if [ $status = 0 ] && [ "$(grep -c '^cornell-box,\|^skylight,' "$out/ratios.csv")" = 6 ] &&
    awk -F, 'NR > 1 && $9 != "" { r = $3 / $6; if ((r - $9) ^ 2 > (0.006 * r) ^ 2) bad = 1; n++ } END { exit bad || n < 4 }' "$out/ratios.csv" &&
    [ "$row30" = "$last_prog $best_pt" ] &&
    ! awk -F, '$1 == "simd-gather"' "$out"/*/results.csv | grep -q . &&
    grep -q '^| budget | cornell-box | skylight |$' "$out/summary.md" && grep -q '^| 30 s | [0-9.e-]* (' "$out/summary.md" &&
    awk -F, '$1 == "cornell-box" && $2 == "progressive" { exit !($3 < 0 && $4 >= 2) }' "$out/slopes.csv" &&
    awk -F, '$1 == "cornell-box" && $2 == "progressive" { exit !(NF == 9 && $9 > 0 && $7 != "" && $7 <= $3) }' "$out/slopes.csv"; then
    pass "error-vs-time-all: two scenes, ratios.csv (progressive / path tracer per budget), slopes.csv (also above the reference's floor), summary.md"
else
    fail "error-vs-time-all" "exit $status, 30 s row '$row30' (want '$last_prog $best_pt'): $(tail -3 "$TMP/all.log")"
fi
expect_exit "error-vs-time-all: REFERENCE is one scene's" 2 pipelines/error-vs-time-all "$TMP/x" REFERENCE=a.exr
expect_exit "error-vs-time-all: SLOPE_FROM not below SLOPE_TO" 2 pipelines/error-vs-time-all "$TMP/x" SLOPE_FROM=8 SLOPE_TO=8
expect_exit "error-vs-time-all: a scene that is not there" 1 pipelines/error-vs-time-all "$TMP/x" SCENES="cornell-box nowhere"
expect_exit "error-vs-time: a bad SWEEP" 2 $E "$CORNELL" "$TMP/x" SWEEP=2
