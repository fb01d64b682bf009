# adaptive.sh: adaptive progressive passes (issue 30, item 2): trace-gather-points --adaptive
# gives pixel p round(m_p x primary) primary rays from a density map, composite weighs each
# pixel's pass by its rays, pm-render ADAPTIVE makes the map from the running image.
#   - a map of 1 everywhere traces the records of the run without one, byte for byte, and the
#     running image it makes is the uniform one's;
#   - the furnace (tests/scenes/make-analytic.sh: L = Le / (1 - rho) everywhere) under an uneven
#     map, alone and averaged with a uniform pass, stays within analytic.sh's gather tolerances;
#   - a bad map (wrong size, NaN, negative, truncated, changed after its pass) is one line and exit 1;
#   - pm-render ADAPTIVE=1 makes OUTDIR/adaptive.pm, running.pm.weight and the same image for any
#     THREADS and when a rerun adds passes; ADAPTIVE=1 where it cannot run is a usage error (2).
# programs: trace-gather-points composite pm-render simd-gather hilbert-sort trace-photons build-photonmap
source tests/scenes/make-analytic.sh
TG=$BUILD/tests/pm-testgen
CORNELL=scenes/cornell-box/scene.json
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }
TOL_G="-v tmean=0.01 -v trms=0.05 -v tmax=0.25"

# ---- a map of 1: the same records, the same running image
"$TG" density 0 "$TMP/one.pm" --size 32x24 --range 1:1
"$TG" density 0 "$TMP/uneven.pm" --size 32x24 --range 0.25:4
tgp() { "$BIN/trace-gather-points" "$CORNELL" --width 32 --height 24 --primary 4 --spp 4 -q "$@"; }
if tgp -o "$TMP/q0.pm" --direct "$TMP/d0.pm" && tgp -o "$TMP/q1.pm" --direct "$TMP/d1.pm" --adaptive "$TMP/one.pm"; then
    if cmp -s <(records "$TMP/q0.pm") <(records "$TMP/q1.pm") && cmp -s <(records "$TMP/d0.pm") <(records "$TMP/d1.pm"); then
        pass "a map of 1 everywhere traces the queries and direct light of the run without a map"
    else
        fail "a map of 1" "the records differ"
    fi
    if "$BIN/pm-info" --header "$TMP/d1.pm" | grep -q "^adaptive=$TMP/one.pm xxh3:" &&
        "$BIN/pm-info" --header "$TMP/q1.pm" | grep -q "^INPUT=$TMP/one.pm xxh3:"; then
        pass "the map is in the headers: adaptive=MAP HASH and an INPUT line"
    else
        fail "the map in the headers" "$("$BIN/pm-info" --header "$TMP/d1.pm" | tail -3)"
    fi
    rm -f "$TMP"/s0.pm* "$TMP"/s1.pm*
    "$BIN/composite" -q "$TMP/d0.pm" --accumulate "$TMP/s0.pm" -o "$TMP/x.exr" &&
        "$BIN/composite" -q "$TMP/d0.pm" --accumulate "$TMP/s0.pm" -o "$TMP/x.exr" &&
        "$BIN/composite" -q "$TMP/d0.pm" --accumulate "$TMP/s1.pm" -o "$TMP/x.exr" &&
        "$BIN/composite" -q "$TMP/d1.pm" --accumulate "$TMP/s1.pm" -o "$TMP/x.exr"
    if cmp -s <(records "$TMP/s0.pm") <(records "$TMP/s1.pm"); then
        pass "a pass under a map of 1 enters the running image as a uniform pass does"
    else
        fail "running image under a map of 1" "the records differ"
    fi
    tgp -o "$TMP/q2.pm" --direct "$TMP/d2.pm" --adaptive "$TMP/uneven.pm" --stats "$TMP/s2.json"
    n0=$("$BIN/pm-info" --header "$TMP/q0.pm" | sed -n 's/^COUNT=//p')
    n2=$("$BIN/pm-info" --header "$TMP/q2.pm" | sed -n 's/^COUNT=//p')
    if [ "$(jq .adaptive "$TMP/s2.json")" = 1 ] && [ "$n2" != "$n0" ]; then
        pass "an uneven map changes the rays ($n0 queries uniform, $n2 adaptive; mean primary $(jq .adaptive_primary_mean "$TMP/s2.json"))"
    else
        fail "an uneven map" "stats $(jq -c '{adaptive, adaptive_primary_mean}' "$TMP/s2.json"), queries $n0 and $n2"
    fi
else
    fail "trace-gather-points --adaptive" "$(cat "$TMP/err" 2>/dev/null)"
fi

# ---- bad maps: one line, exit 1
rm -f "$TMP/q.pm"
"$TG" density 0 "$TMP/small.pm" --size 16x24 --range 1:1
"$TG" density 0 "$TMP/nan.pm" --size 32x24 --poison nan
"$TG" density 0 "$TMP/neg.pm" --size 32x24 --poison negative
"$TG" density 0 "$TMP/huge.pm" --size 32x24 --range 20000:20000
head -c -100 "$TMP/uneven.pm" >"$TMP/trunc.pm"
expect_error "a map of another size" "density map '.*small.pm' is 16x24, the image 32x24" \
    tgp -o "$TMP/q.pm" --adaptive "$TMP/small.pm"
expect_error "a map holding NaN" "density map '.*nan.pm'.*nan" tgp -o "$TMP/q.pm" --adaptive "$TMP/nan.pm"
expect_error "a map holding a negative multiplier" "density map '.*neg.pm'.*-1" tgp -o "$TMP/q.pm" --adaptive "$TMP/neg.pm"
expect_error "a map asking for more rays than a pass may have" \
    "density map '.*huge.pm': pixel 0 multiplier 20000 times 4 primary rays is above 65536 rays" \
    tgp -o "$TMP/q.pm" --adaptive "$TMP/huge.pm"
expect_error "a truncated map" "trunc.pm" tgp -o "$TMP/q.pm" --adaptive "$TMP/trunc.pm"
expect_error "a missing map (not a resident pass)" "cannot open '.*missing.pm'" \
    tgp -o "$TMP/q.pm" --adaptive "$TMP/missing.pm"
[ -e "$TMP/q.pm" ] && fail "no output after a bad map" "$TMP/q.pm was written" || pass "no output after a bad map"
cp "$TMP/uneven.pm" "$TMP/moved.pm"
tgp -o "$TMP/q3.pm" --direct "$TMP/d3.pm" --adaptive "$TMP/moved.pm"
"$TG" density 0 "$TMP/moved.pm" --size 32x24 --range 1:2
expect_error "composite: a map changed after its pass was traced" "density map '.*moved.pm' is not the one pass" \
    "$BIN/composite" "$TMP/d3.pm" --accumulate "$TMP/s3.pm" -o "$TMP/x3.exr"
[ -e "$TMP/s3.pm" ] && fail "no running image after a changed map" "$TMP/s3.pm written" ||
    pass "no running image after a changed map"
expect_exit "composite --adaptive-map needs --accumulate (usage)" 2 \
    "$BIN/composite" "$TMP/d0.pm" -o "$TMP/x.exr" --adaptive-map "$TMP/m.pm"

# ---- the furnace under an uneven map: unbiased, alone and beside a uniform pass
make_furnace "$TMP/furnace" 1 0.5
F=$TMP/furnace/scene.json
"$TG" density 0 "$TMP/fmap.pm" --size 32x32 --range 0.25:4
fpass() { # NAME [trace-gather-points options]: direct buffer, gathered buffer, hits
    local name=$1; shift
    "$BIN/trace-gather-points" "$F" --spp 16 --primary 4 --light-samples 16 -q "$@" -o "$TMP/$name.q.pm" \
        --direct "$TMP/$name.d.pm" &&
        "$BIN/hilbert-sort" "$TMP/$name.q.pm" -q -o "$TMP/$name.qs.pm" &&
        "$BIN/simd-gather" "$TMP/f.map.pm" "$TMP/$name.qs.pm" --k 200 -q -o "$TMP/$name.i.pm"
}
if "$BIN/trace-photons" "$F" --photons 400000 -q -o - | "$BIN/build-photonmap" - -q -o "$TMP/f.map.pm" &&
    "$BIN/trace-gather-points" "$F" --mode direct-vis -q -o "$TMP/fh.q.pm" &&
    "$BIN/pm-info" -r "$TMP/fh.q.pm" >"$TMP/fh.hits.txt" &&
    fpass fu --pass 1 && fpass fa --pass 2 --adaptive "$TMP/fmap.pm" &&
    image fa "$TMP/fa.d.pm" "$TMP/fa.i.pm" && rm -f "$TMP/fs.pm" &&
    "$BIN/composite" -q "$TMP/fu.d.pm" "$TMP/fu.i.pm" --accumulate "$TMP/fs.pm" --pass 1 -o "$TMP/fs1.exr" &&
    "$BIN/composite" -q "$TMP/fa.d.pm" "$TMP/fa.i.pm" --accumulate "$TMP/fs.pm" --pass 2 -o "$TMP/fs.exr" &&
    "$BUILD/tests/pm-exrdump" "$TMP/fs.exr" >"$TMP/fs.txt"; then
    check "furnace rho 0.5, one pass under an uneven map (1 to 16 rays a pixel): L = 2" fh fa $TOL_G \
        -v kind=const -v le=1 -v kd=0.5 -v e=6.283185307179586
    check "furnace rho 0.5, a uniform and an adaptive pass weighed per pixel: L = 2" fh fs $TOL_G \
        -v kind=const -v le=1 -v kd=0.5 -v e=6.283185307179586
    "$BIN/pm-info" --header "$TMP/fs.pm" | grep -qx 'pixel_weights=1' && [ -s "$TMP/fs.pm.weight" ] &&
        pass "the running image keeps its per-pixel weights beside it (fs.pm.weight)" ||
        fail "per-pixel weights beside the running image" "no pixel_weights=1 or no fs.pm.weight"
else
    fail "furnace pipeline under an adaptive map" "a stage failed"
fi

# ---- pm-render ADAPTIVE
R=pipelines/render
SMALL="PHOTONS=20000 SPP=4 WIDTH=32 HEIGHT=24 PRIMARY=4"
if "$R" "$CORNELL" "$TMP/r1" $SMALL PASSES=6 ADAPTIVE=1 THREADS=1 >"$TMP/r1.out" 2>&1 &&
    "$R" "$CORNELL" "$TMP/r2" $SMALL PASSES=6 ADAPTIVE=1 THREADS=2 >"$TMP/r2.out" 2>&1; then
    if [ -f "$TMP/r1/adaptive.pm" ] && [ -f "$TMP/r1/running.pm.weight" ] &&
        [ "$(jq .total.adaptive "$TMP/r1/stats.json")" = true ] &&
        "$BIN/pm-info" --header "$TMP/r1/running.pm" | grep -qx 'pixel_weights=1'; then
        pass "pm-render ADAPTIVE=1: adaptive.pm, running.pm.weight and stats.json's total.adaptive"
    else
        fail "pm-render ADAPTIVE=1" "$(ls "$TMP/r1") $(tail -2 "$TMP/r1.out")"
    fi
    if cmp -s <(records "$TMP/r1/running.pm") <(records "$TMP/r2/running.pm") &&
        cmp -s <(records "$TMP/r1/running.pm.weight") <(records "$TMP/r2/running.pm.weight"); then
        pass "pm-render ADAPTIVE=1: the same running image for THREADS=1 and 2"
    else
        fail "pm-render ADAPTIVE=1 across THREADS" "the running images differ"
    fi
else
    fail "pm-render ADAPTIVE=1" "$(tail -3 "$TMP/r1.out" "$TMP/r2.out")"
fi
# a rerun that adds passes 7 and 8 makes its map from the 6 passes held: the bytes of one run of 8
if "$R" "$CORNELL" "$TMP/r1" $SMALL PASSES=8 ADAPTIVE=1 THREADS=1 >"$TMP/r1b.out" 2>&1 &&
    "$R" "$CORNELL" "$TMP/r8" $SMALL PASSES=8 ADAPTIVE=1 THREADS=1 >"$TMP/r8.out" 2>&1 &&
    grep -qE '^ +8 +added' "$TMP/r1b.out" && cmp -s <(records "$TMP/r1/running.pm") <(records "$TMP/r8/running.pm") &&
    cmp -s <(records "$TMP/r1/running.pm.weight") <(records "$TMP/r8/running.pm.weight"); then
    pass "pm-render ADAPTIVE=1: 6 passes and a rerun to 8 make the running image of one run of 8"
else
    fail "pm-render ADAPTIVE=1 rerun" "$(tail -3 "$TMP/r1b.out")"
fi
if "$R" "$CORNELL" "$TMP/r0" $SMALL PASSES=6 >"$TMP/r0.out" 2>&1 && [ ! -e "$TMP/r0/adaptive.pm" ] &&
    [ "$(jq .total.adaptive "$TMP/r0/stats.json")" = false ]; then
    pass "pm-render PASSES=6 (ADAPTIVE=auto): uniform passes"
else
    fail "pm-render ADAPTIVE=auto with PASSES" "$(ls "$TMP/r0") $(tail -2 "$TMP/r0.out")"
fi
expect_exit "ADAPTIVE=1 for one pass is a usage error" 2 "$R" "$CORNELL" "$TMP/u1" $SMALL ADAPTIVE=1
expect_exit "ADAPTIVE=1 with KEEP=all (the pass files) is a usage error" 2 \
    "$R" "$CORNELL" "$TMP/u2" $SMALL PASSES=2 KEEP=all ADAPTIVE=1
expect_exit "ADAPTIVE=maybe is a usage error" 2 "$R" "$CORNELL" "$TMP/u3" $SMALL PASSES=2 ADAPTIVE=maybe

# ---- pm-render OVERLAP: the next pass planned and traced while the one before is sorted and
# gathered (auto: a TIME budget's, whose sizes are the machine's; forced here on PASSES renders,
# which plan every pass ahead). The passes before the first adaptive one (the 5th) are the same
# bytes either way. An overlapped adaptive pass takes the map of the image one pass older, read
# from a map of its own (adaptive-P.pm, gone once its pass is in the running image), so the
# running image is the same for any THREADS and differs from one pass at a time.
if "$R" "$CORNELL" "$TMP/o4" $SMALL PASSES=4 OVERLAP=1 >"$TMP/o4.out" 2>&1 &&
    "$R" "$CORNELL" "$TMP/s4" $SMALL PASSES=4 OVERLAP=0 >"$TMP/s4.out" 2>&1 &&
    cmp -s <(records "$TMP/o4/running.pm") <(records "$TMP/s4/running.pm"); then
    pass "pm-render OVERLAP=1, 4 uniform passes: the running image of one pass at a time"
else
    fail "pm-render OVERLAP=1 uniform passes" "$(tail -2 "$TMP/o4.out" "$TMP/s4.out")"
fi
if "$R" "$CORNELL" "$TMP/o1" $SMALL PASSES=7 ADAPTIVE=1 OVERLAP=1 THREADS=1 >"$TMP/o1.out" 2>&1 &&
    "$R" "$CORNELL" "$TMP/o2" $SMALL PASSES=7 ADAPTIVE=1 OVERLAP=1 THREADS=2 >"$TMP/o2.out" 2>&1 &&
    "$R" "$CORNELL" "$TMP/s7" $SMALL PASSES=7 ADAPTIVE=1 OVERLAP=0 >"$TMP/s7.out" 2>&1 &&
    [ "$(jq .total.passes "$TMP/o1/stats.json")" = 7 ] && [ -f "$TMP/o1/adaptive.pm" ] &&
    ! ls "$TMP"/o1/adaptive-*.pm >/dev/null 2>&1 &&
    cmp -s <(records "$TMP/o1/running.pm") <(records "$TMP/o2/running.pm") &&
    cmp -s <(records "$TMP/o1/running.pm.weight") <(records "$TMP/o2/running.pm.weight") &&
    ! cmp -s <(records "$TMP/o1/running.pm") <(records "$TMP/s7/running.pm"); then
    pass "pm-render OVERLAP=1 ADAPTIVE=1, 7 passes: the same running image for THREADS=1 and 2, no per-pass map left, adaptive.pm kept"
else
    fail "pm-render OVERLAP=1 ADAPTIVE=1" "$(ls "$TMP/o1"; tail -2 "$TMP/o1.out")"
fi
# an OUTDIR whose name holds "%d": the pass number goes into the map's file name only
if "$R" "$CORNELL" "$TMP/o%d" $SMALL PASSES=7 ADAPTIVE=1 OVERLAP=1 THREADS=1 >"$TMP/od.out" 2>&1 &&
    cmp -s <(records "$TMP/o1/running.pm") <(records "$TMP/o%d/running.pm"); then
    pass "pm-render OVERLAP=1 ADAPTIVE=1 in an OUTDIR named o%d: the running image of any other OUTDIR"
else
    fail "pm-render OVERLAP=1 in an OUTDIR with %d" "$(tail -2 "$TMP/od.out")"
fi
expect_exit "OVERLAP=maybe is a usage error" 2 "$R" "$CORNELL" "$TMP/u4" $SMALL PASSES=2 OVERLAP=maybe
