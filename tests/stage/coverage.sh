# coverage.sh: simd-gather --coverage, the density estimate's boundary correction
# (photonmap/coverage.h), against a closed form: the furnace in a closed box (every face emits
# Le = 1 W/(m^2 sr) inward with albedo 0.5, so that the radiance is Le / (1 - 0.5) = 2
# everywhere). The box's twelve edges are what a kernel overhangs: at a kernel 0.4 m wide the
# plain estimate's image is 4% dark in direct-vis mode (measured 1.919 against 2; 2.0% at
# 0.2 m), and the corrected one within 1% (measured 2.002 and 1.998). The gather mode's final
# gather sees the same loss, less of it. Also: the outputs do not depend on the thread count,
# the output's header names the spacing, and bad uses (another scene, no scene, variable
# widths) are a one-line error with the usual exit code. pm-render COVERAGE=1 runs it, and
# COVERAGE=auto for progressive renders but TIME=1 (passes-resident.sh checks its resident passes
# against the pass files); the TIME planner knows at which passes the gather samples anew.
# programs: trace-photons build-photonmap trace-gather-points hilbert-sort simd-gather composite pm-info pm-render
D=$TMP/coverage
mkdir -p "$D"
cat >"$D/box.obj" <<'OBJ'
mtllib box.mtl
usemtl wall
v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
f 1 2 3 4
f 8 7 6 5
f 1 5 6 2
f 4 3 7 8
f 1 4 8 5
f 2 6 7 3
OBJ
printf 'newmtl wall\nKd 0.5 0.5 0.5\nKe 1 1 1\n' >"$D/box.mtl"
# The camera looks into a corner from near the middle: three faces, three edges and the corner.
cat >"$D/scene.json" <<'JSON'
{
  "pmtk_scene": 1,
  "name": "box-furnace",
  "meshes": [ { "file": "box.obj" } ],
  "camera": { "eye": [0.3, 0.2, 0.1], "look_at": [-1, -1, -1], "fov_y": 70, "width": 32, "height": 32 },
  "render": { "photons": 400000, "spp": 4, "seed": 1 }
}
JSON
# A second scene of other geometry, for the mismatch.
sed 's/"box.obj"/"box2.obj"/' "$D/scene.json" >"$D/other.json"
sed 's/^v 1 1 1$/v 1 1 1.5/' "$D/box.obj" >"$D/box2.obj"

# records FILE: a file's records as text, without its header.
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }
# mean EXR: the mean of every pixel's three channels.
mean() { "$BUILD/tests/pm-exrdump" "$1" | awk 'NR > 1 { s += $3 + $4 + $5; n += 3 } END { printf "%.5f", s / n }'; }
# within A B TOL: |A / B - 1| < TOL
within() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a / b - 1; exit !(d < t && -d < t) }'; }
below() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a < b) }'; }
# usage_error NAME PATTERN CMD...: exit 2 and one line on stderr matching PATTERN.
usage_error() {
    local name=$1 pattern=$2
    shift 2
    "$@" >/dev/null 2>"$D/uerr"
    local got=$?
    [ $got = 2 ] && [ "$(wc -l <"$D/uerr")" = 1 ] && grep -qE -- "$pattern" "$D/uerr" && pass "$name" ||
        fail "$name" "exit $got: $(head -c 300 "$D/uerr")"
}

S=$D/scene.json
if "$BIN/trace-photons" "$S" -q -o - | "$BIN/build-photonmap" - -q -o "$D/map.pm" &&
    "$BIN/trace-gather-points" "$S" --mode direct-vis --light-samples 0 -q -o "$D/dv.q.pm" --direct "$D/dv.d.pm" &&
    "$BIN/trace-gather-points" "$S" --spp 16 --light-samples 16 -q -o "$D/g.q.pm" --direct "$D/g.d.pm" &&
    "$BIN/hilbert-sort" "$D/g.q.pm" -q -o "$D/g.qs.pm"; then
    for mode in dv g; do
        q=$D/$mode.q.pm
        [ $mode = g ] && q=$D/g.qs.pm
        if "$BIN/simd-gather" "$D/map.pm" "$q" --radius 0.4 -q -o "$D/$mode.0.pm" &&
            "$BIN/simd-gather" "$D/map.pm" "$q" --radius 0.4 --coverage "$S" -q -o "$D/$mode.1.pm" &&
            "$BIN/composite" "$D/$mode.d.pm" "$D/$mode.0.pm" -q -o "$D/$mode.0.exr" &&
            "$BIN/composite" "$D/$mode.d.pm" "$D/$mode.1.pm" -q -o "$D/$mode.1.exr"; then
            m0=$(mean "$D/$mode.0.exr") m1=$(mean "$D/$mode.1.exr")
            # the plain estimate is dark (the check can fail), the corrected one is right
            if below "$m0" 1.985 && within "$m1" 2 0.01; then
                pass "box furnace, $mode, kernel 0.4 m: plain $m0, corrected $m1, closed form 2"
            else
                fail "box furnace, $mode, kernel 0.4 m" "plain $m0 (below 1.985 expected), corrected $m1 (2 within 1%)"
            fi
        else
            fail "box furnace $mode gathers" "a stage failed"
        fi
    done
    # A narrower kernel: less loss, still corrected.
    if "$BIN/simd-gather" "$D/map.pm" "$D/dv.q.pm" --radius 0.2 --coverage "$S" -q -o "$D/dv.2.pm" &&
        "$BIN/composite" "$D/dv.d.pm" "$D/dv.2.pm" -q -o "$D/dv.2.exr" && within "$(mean "$D/dv.2.exr")" 2 0.01; then
        pass "box furnace, direct-vis, kernel 0.2 m: corrected $(mean "$D/dv.2.exr")"
    else
        fail "box furnace, kernel 0.2 m" "corrected mean $(mean "$D/dv.2.exr" 2>/dev/null) (2 within 1%)"
    fi
    # Threads change nothing; the header names the spacing (0.4 / 2 = 0.2 m: the level below, 2^-2.5 = 0.177 m).
    if "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --coverage "$S" --threads 1 -q -o "$D/t1.pm" &&
        "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --coverage "$S" --threads 2 -q -o "$D/t2.pm" &&
        cmp -s <(records "$D/t1.pm") <(records "$D/t2.pm") &&
        cmp -s <(records "$D/t1.pm") <(records "$D/g.1.pm"); then
        pass "--coverage: the same bytes for 1 and 2 threads"
    else
        fail "--coverage threads" "outputs differ"
    fi
    if "$BIN/pm-info" "$D/g.1.pm" | grep -qx 'coverage=0.176776695' &&
        ! "$BIN/pm-info" "$D/g.0.pm" | grep -q '^coverage='; then
        pass "--coverage: header key coverage, the area samples' spacing"
    else
        fail "--coverage header" "$("$BIN/pm-info" "$D/g.1.pm" | grep -i coverage)"
    fi
    # Progressive pass 1 goes uncorrected (the first image waits for it); pass 2 is corrected.
    if "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --pass 1 -q -o "$D/p1.0.pm" &&
        "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --pass 1 --coverage "$S" -q -o "$D/p1.1.pm" &&
        "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --pass 2 -q -o "$D/p2.0.pm" &&
        "$BIN/simd-gather" "$D/map.pm" "$D/g.qs.pm" --radius 0.4 --pass 2 --coverage "$S" -q -o "$D/p2.1.pm" &&
        cmp -s <(records "$D/p1.0.pm") <(records "$D/p1.1.pm") &&
        ! cmp -s <(records "$D/p2.0.pm") <(records "$D/p2.1.pm") &&
        ! "$BIN/pm-info" "$D/p1.1.pm" | grep -q '^coverage=' && "$BIN/pm-info" "$D/p2.1.pm" | grep -q '^coverage='; then
        pass "--coverage: progressive pass 1 as without it, pass 2 corrected"
    else
        fail "--coverage and pass 1" "pass 1 or 2 not as expected"
    fi
    # Bad uses.
    "$BIN/simd-gather" "$D/map.pm" "$D/dv.q.pm" --radius 0.4 --coverage "$D/other.json" -q -o "$D/bad.pm" 2>"$D/err"
    rc=$?
    if [ $rc = 1 ] && [ "$(wc -l <"$D/err")" = 1 ] && grep -q "coverage.*other.json.*box-furnace" "$D/err" &&
        [ ! -e "$D/bad.pm" ]; then
        pass "--coverage of another scene: exit 1, $(cat "$D/err")"
    else
        fail "--coverage of another scene" "exit $rc: $(cat "$D/err")"
    fi
    "$BIN/simd-gather" "$D/map.pm" "$D/dv.q.pm" --radius 0.4 --coverage "$D/none.json" -q -o "$D/bad.pm" 2>"$D/err"
    rc=$?
    if [ $rc = 1 ] && grep -q "none.json" "$D/err" && [ ! -e "$D/bad.pm" ]; then
        pass "--coverage of a missing scene: exit 1"
    else
        fail "--coverage of a missing scene" "exit $rc: $(cat "$D/err")"
    fi
    mkfifo "$D/fifo.json"
    expect_error "--coverage of a FIFO: refused at once, not waited on" "coverage: scene '.*fifo.json' is not a regular file \\(a FIFO\\)" \
        timeout 10 "$BIN/simd-gather" "$D/map.pm" "$D/dv.q.pm" --radius 0.4 --coverage "$D/fifo.json" -q -o "$D/bad.pm"
    [ ! -e "$D/bad.pm" ] || fail "--coverage of a FIFO" "an output was left"
    "$BIN/trace-photons" "$S" --photons 20000 -q -o - | "$BIN/build-photonmap" - --width-k 20 -q -o "$D/wmap.pm"
    "$BIN/simd-gather" "$D/wmap.pm" "$D/dv.q.pm" --widths variable --coverage "$S" -q -o "$D/bad.pm" 2>"$D/err"
    rc=$?
    if [ $rc = 2 ] && grep -q "coverage.*fixed widths" "$D/err" && [ ! -e "$D/bad.pm" ]; then
        pass "--coverage with variable widths: usage error"
    else
        fail "--coverage with variable widths" "exit $rc: $(cat "$D/err")"
    fi
    # --coverage-plan: a pass held at the samples of the pass before (pm-render's TIME planner,
    # when a new level's sampling does not fit the budget). r_1 0.29 m puts pass 2's kernel at
    # the 0.125-m level and pass 3's one finer (0.0884 m): the plan line "3 1" keeps 0.125 m, and
    # pass 3's recorded command says --coverage-level -6, whose records that command has alone.
    for p in 1 2 3; do
        "$BIN/trace-photons" "$S" --photons 20000 -q --pass $p -o - | "$BIN/build-photonmap" -q - -o "$D/sm$p.pm"
        "$BIN/trace-gather-points" "$S" --width 16 --height 16 --spp 4 -q --pass $p -o "$D/sq$p.pm"
    done
    cat "$D"/sm[123].pm >"$D/smaps.pm"
    cat "$D"/sq[123].pm >"$D/squeries.pm"
    printf '1\n2\n3 1\n' >"$D/hold.txt"
    printf '1\n2\n3\n' >"$D/nohold.txt"
    SG=("$BIN/simd-gather" --stream pairs "$D/smaps.pm" "$D/squeries.pm" --radius 0.29 --coverage "$S")
    if "${SG[@]}" --coverage-plan "$D/hold.txt" -o - >"$D/hold.pm" 2>"$D/hold.err" &&
        "${SG[@]}" --coverage-plan "$D/nohold.txt" -o - >"$D/nohold.pm" 2>"$D/nohold.err" &&
        "$BIN/composite" -q --stream "$D/hold.pm" --radiance "$D/hold-%d.pm" &&
        "$BIN/composite" -q --stream "$D/nohold.pm" --radiance "$D/nohold-%d.pm" &&
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --pass 3 --pass-photons 40000 --unit-photons 20000 --radius 0.29 \
            --coverage "$S" --coverage-level -6 -q -o "$D/held3.pm"; then
        kept=$(grep -o 'area samples [^ ]* m apart' "$D/hold.err" | awk '{print $3}' | tr '\n' ' ')
        made=$(grep -o 'area samples [^ ]* m apart' "$D/nohold.err" | awk '{print $3}' | tr '\n' ' ')
        if [ "$kept" = "0.125 " ] && [ "$made" = "0.125 0.0884 " ] &&
            "$BIN/pm-info" "$D/hold-2.pm" | grep -q '^COMMAND=simd-gather --pass 3 .*--coverage-level -6 ' &&
            ! "$BIN/pm-info" "$D/hold-2.pm" | grep -q 'coverage-plan' &&
            ! "$BIN/pm-info" "$D/nohold-2.pm" | grep -q 'coverage-level' &&
            cmp -s <(records "$D/hold-1.pm") <(records "$D/nohold-1.pm") &&
            cmp -s <(records "$D/hold-2.pm") <(records "$D/held3.pm") &&
            ! cmp -s <(records "$D/hold-2.pm") <(records "$D/nohold-2.pm"); then
            pass "--coverage-plan '3 1': pass 3 keeps the 0.125-m samples (without it: $made), the records of its command --coverage-level -6 alone"
        else
            fail "--coverage-plan hold" "samples kept '$kept', made '$made'"
        fi
    else
        fail "--coverage-plan" "a run failed: $(cat "$D/hold.err" "$D/nohold.err" | tail -2)"
    fi
    usage_error "--coverage-level two levels coarser than the kernel's: usage error" \
        "coverage-level -5: the kernel .* samples at level -7; give -7 or -6" \
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --pass 3 --pass-photons 40000 --unit-photons 20000 --radius 0.29 \
        --coverage "$S" --coverage-level -5 -q -o "$D/bad.pm"
    usage_error "--coverage-level without --coverage: usage error" "need --coverage" \
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --radius 0.29 --coverage-level -6 -q -o "$D/bad.pm"
    usage_error "--coverage-plan without --stream pairs: usage error" "coverage-plan needs --stream pairs" \
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --radius 0.29 --coverage "$S" --coverage-plan "$D/hold.txt" -q \
        -o "$D/bad.pm"
    usage_error "--coverage-level finer than the kernel's own: usage error" \
        "coverage-level -8: the kernel .* samples at level -7; give -7 or -6" \
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --pass 3 --pass-photons 40000 --unit-photons 20000 --radius 0.29 \
        --coverage "$S" --coverage-level -8 -q -o "$D/bad.pm"
    usage_error "--coverage-level x: usage error" "coverage-level 'x': expected a whole number" \
        "$BIN/simd-gather" "$D/sm3.pm" "$D/sq3.pm" --radius 0.29 --coverage "$S" --coverage-level x -q -o "$D/bad.pm"
    usage_error "--coverage-level with --stream pairs: usage error (the plan is the stream's)" \
        "coverage-level is one pass's level: a stream of passes takes --coverage-plan" \
        "${SG[@]}" --coverage-level -6 -q -o -
    printf '1\n3\n' >"$D/badplan.txt"
    expect_error "--coverage-plan naming another pass: the line is named" \
        "coverage-plan '.*badplan.txt' line 2 is pass 3, but the documents are pass 2" \
        "${SG[@]}" --coverage-plan "$D/badplan.txt" -q -o -
    printf '1\n2 2\n' >"$D/twoplan.txt"
    expect_error "--coverage-plan 'PASS 2': input error" "coverage-plan '.*twoplan.txt' line 2: pass 2 2: expected 'PASS' or 'PASS 1'" \
        "${SG[@]}" --coverage-plan "$D/twoplan.txt" -q -o -
    printf '1\n2\n' >"$D/shortplan.txt"
    expect_error "--coverage-plan that ends before the streams: input error" \
        "coverage-plan '.*shortplan.txt' has ended before pass 3" \
        "${SG[@]}" --coverage-plan "$D/shortplan.txt" -q -o -
    rm -f "$D/bad.pm"
else
    fail "box furnace pipeline" "a stage failed"
fi

# pm-render COVERAGE=1: the gathers get --coverage SCENE; auto (the default) gives it to
# progressive renders but TIME under 6 s; a bad value and a gather that cannot take it are usage
# errors.
R=pipelines/render
if "$R" "$S" "$D/r1" PHOTONS=20000 WIDTH=16 HEIGHT=16 COVERAGE=1 >"$D/r1.out" 2>&1 &&
    "$BIN/pm-info" "$D/r1/indirect.pm" | grep -q '^COMMAND=simd-gather .*--coverage .*scene.json' &&
    "$R" "$S" "$D/r2" PHOTONS=20000 WIDTH=16 HEIGHT=16 PASSES=2 >"$D/r2.out" 2>&1 &&
    "$BIN/pm-info" "$D/r2/running.pm" | grep -q 'simd-gather .*--coverage ' &&
    grep -q ' COVERAGE=1' "$D/r2/passes.txt" &&
    "$R" "$S" "$D/r5" PHOTONS=20000 WIDTH=16 HEIGHT=16 >"$D/r5.out" 2>&1 &&
    ! "$BIN/pm-info" "$D/r5/indirect.pm" | grep -q -- '--coverage' &&
    "$R" "$S" "$D/r6" PHOTONS=20000 WIDTH=16 HEIGHT=16 TIME=1 >"$D/r6.out" 2>&1 &&
    ! "$BIN/pm-info" "$D/r6/running.pm" | grep -q -- '--coverage'; then
    pass "pm-render: COVERAGE=1 in one pass; auto on for resident passes (PASSES=2), off for one render and TIME=1"
else
    fail "pm-render COVERAGE=1" "$(tail -2 "$D/r1.out" "$D/r2.out")"
fi
# COVERAGE=auto from TIME=2; the TIME planner's foresight: the passes at which the driver says
# the gather samples a new spacing level, and their spacings, are the gather's own (a PASSES
# render: the same prediction, said under VERBOSE)
"$R" "$S" "$D/r8" PHOTONS=20000 WIDTH=16 HEIGHT=16 TIME=2 >"$D/r8.out" 2>&1 &&
    "$BIN/pm-info" "$D/r8/running.pm" | grep -q 'simd-gather .*--coverage ' &&
    pass "pm-render: COVERAGE=auto on for TIME=2" || fail "COVERAGE=auto TIME=2" "$(tail -2 "$D/r8.out")"
# K, when not given: 2 below TIME=2 (no boundary correction: a smaller kernel darkens less), 5 from it
[ "$(jq '.passes[0].stages["simd-gather"].k' "$D/r6/stats.json")" = 2 ] &&
    [ "$(jq '.passes[0].stages["simd-gather"].k' "$D/r8/stats.json")" = 5 ] &&
    grep -q ' K_DEFAULT=2' "$D/r6/passes.txt" && ! grep -q 'K_DEFAULT' "$D/r8/passes.txt" &&
    pass "pm-render's default K: 2 for TIME=1 (no correction; passes.txt's settings say K_DEFAULT=2), 5 for TIME=2" ||
    fail "default K by TIME" "$(jq -c '.passes[0].stages["simd-gather"]' "$D/r6/stats.json" "$D/r8/stats.json")"
# PHOTONS, when not given: 75000 a full pass below TIME=2 (pass 1, one unit of 16, 4688), 300000
# from it (18750); a given PHOTONS is what it says, with no word in the settings
"$R" "$S" "$D/p1" WIDTH=16 HEIGHT=16 TIME=1 >"$D/p1.out" 2>&1 &&
    "$R" "$S" "$D/p2" WIDTH=16 HEIGHT=16 TIME=2 >"$D/p2.out" 2>&1 &&
    [ "$(awk '$1 == 1 { print $2 }' "$D/p1/passes.txt")" = 4688 ] &&
    [ "$(awk '$1 == 1 { print $2 }' "$D/p2/passes.txt")" = 18750 ] &&
    grep -q ' PHOTONS_DEFAULT=75000' "$D/p1/passes.txt" && ! grep -q 'PHOTONS_DEFAULT' "$D/p2/passes.txt" &&
    ! grep -q 'PHOTONS_DEFAULT' "$D/r6/passes.txt" &&
    pass "pm-render's default PHOTONS: 75000 a full pass for TIME=1 (passes.txt's settings say PHOTONS_DEFAULT=75000), 300000 for TIME=2" ||
    fail "default PHOTONS by TIME" "$(grep -h '^[0-9s]' "$D/p1/passes.txt" "$D/p2/passes.txt" | head -c 600)"
"$R" "$S" "$D/r7" PHOTONS=20000 WIDTH=16 HEIGHT=16 PASSES=12 VERBOSE=1 >"$D/r7.out" 2>&1
said=$(grep -o 'new coverage level, [^ ]* m apart' "$D/r7.out" | awk '{print $4}' | tr '\n' ' ')
built=$(grep -o 'area samples [^ ]* m apart' "$D/r7.out" | awk '{print $3}' | tr '\n' ' ')
if [ "$(echo $said | wc -w)" -ge 2 ] && [ "$said" = "$built" ] &&
    grep -q '^render: .*simd-gather .*--coverage-plan /dev/fd/[0-9]' "$D/r7.out" &&
    ! "$BIN/pm-info" "$D/r7/running.pm" | grep -q 'coverage-plan'; then
    pass "pm-render foresees the gather's coverage levels: spacings $said (its coverage plan a pipe, not in the passes' commands)"
else
    fail "coverage levels foreseen" "driver '$said', gather '$built'"
fi
"$R" "$S" "$D/r3" COVERAGE=2 >"$D/r3.out" 2>&1
rc=$?
"$R" "$S" "$D/r4" COVERAGE=1 WIDTHS=variable >"$D/r4.out" 2>&1
rc4=$?
if [ $rc = 2 ] && grep -q "COVERAGE" "$D/r3.out" && [ $rc4 = 2 ] && grep -q "COVERAGE=1 needs WIDTHS=fixed" "$D/r4.out"; then
    pass "pm-render COVERAGE=2, COVERAGE=1 WIDTHS=variable: usage errors"
else
    fail "pm-render COVERAGE usage" "exit $rc and $rc4: $(cat "$D/r3.out" "$D/r4.out")"
fi
