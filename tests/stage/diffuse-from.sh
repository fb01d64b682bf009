# diffuse-from.sh: a diffuse bounce before the gather from a later pass on (trace-gather-points
# --diffuse-from P; pm-render DIFFUSE_FROM and DIFFUSE_DEPTH=auto; docs/accuracy.md, "A diffuse
# bounce from a later pass on").
#   1. A pass before P is the pass without the bounce, and a pass from P on the pass with it:
#      the same payload (checksum), and the header's diffuse_depth only where it bounces; a
#      render without --pass is pass 1.
#   2. pm-render's resident passes with DIFFUSE_FROM: before P the running image of a render
#      without the bounce, from P on another; a rerun that adds passes across P makes the
#      running image one render of as many passes makes.
#   3. DIFFUSE_DEPTH=auto bounces from pass 32 in progressive renders only (a one-pass render
#      has no bounce), and not in a scene with mirrors or glass or with portals; bad values and
#      DIFFUSE_FROM without a depth are refused.
# programs: trace-gather-points pm-render pm-info
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
SMALL="PHOTONS=20000 SPP=4 WIDTH=32 HEIGHT=24"
# the records alone (a header names the command that made it)
sum() { "$BIN/pm-info" -r "$1" | grep -E "^[0-9-]" | cksum; }
has_depth() { "$BIN/pm-info" --header "$1" | grep -qx 'diffuse_depth=1'; }
tgp() { # NAME ARGS...: trace-gather-points of the Cornell box into $TMP/NAME.{q,d}.pm
    local n=$1
    shift
    "$BIN/trace-gather-points" "$CORNELL" --width 16 --height 12 --spp 4 -q -o "$TMP/$n.q.pm" --direct "$TMP/$n.d.pm" "$@"
}

# ---- 1. trace-gather-points --diffuse-from
tgp p2 --pass 2 && tgp p2f --pass 2 --diffuse-depth 1 --diffuse-from 3 &&
    tgp p3 --pass 3 --diffuse-depth 1 && tgp p3f --pass 3 --diffuse-depth 1 --diffuse-from 3 &&
    tgp p3n --pass 3 && tgp one && tgp onef --diffuse-depth 1 --diffuse-from 2
if [ "$(sum "$TMP/p2.q.pm")" = "$(sum "$TMP/p2f.q.pm")" ] && [ "$(sum "$TMP/p2.d.pm")" = "$(sum "$TMP/p2f.d.pm")" ] &&
    ! has_depth "$TMP/p2f.q.pm"; then
    pass "--diffuse-from 3: pass 2 is the pass without the bounce (queries and direct light), its header says no depth"
else
    fail "--diffuse-from before its pass" "$(sum "$TMP/p2.q.pm") $(sum "$TMP/p2f.q.pm")"
fi
if [ "$(sum "$TMP/p3.q.pm")" = "$(sum "$TMP/p3f.q.pm")" ] && [ "$(sum "$TMP/p3.d.pm")" = "$(sum "$TMP/p3f.d.pm")" ] &&
    has_depth "$TMP/p3f.q.pm" && has_depth "$TMP/p3f.d.pm" && [ "$(sum "$TMP/p3.q.pm")" != "$(sum "$TMP/p3n.q.pm")" ]; then
    pass "--diffuse-from 3: pass 3 is the pass with the bounce (diffuse_depth=1), not the pass without"
else
    fail "--diffuse-from at its pass" "$(sum "$TMP/p3.q.pm") $(sum "$TMP/p3f.q.pm") $(sum "$TMP/p3n.q.pm")"
fi
[ "$(sum "$TMP/one.q.pm")" = "$(sum "$TMP/onef.q.pm")" ] && ! has_depth "$TMP/onef.q.pm" &&
    pass "--diffuse-from 2 on a render without --pass (pass 1): no bounce" ||
    fail "--diffuse-from on one render" "$(sum "$TMP/one.q.pm") $(sum "$TMP/onef.q.pm")"
expect_exit "--diffuse-from without --diffuse-depth is a usage error" 2 \
    "$BIN/trace-gather-points" "$CORNELL" --width 16 --height 12 --spp 4 -q -o "$TMP/x.q.pm" --diffuse-from 3
expect_exit "--diffuse-from 0 is a usage error" 2 \
    "$BIN/trace-gather-points" "$CORNELL" --width 16 --height 12 --spp 4 -q -o "$TMP/x.q.pm" --diffuse-depth 1 --diffuse-from 0
[ ! -e "$TMP/x.q.pm" ] && pass "a refused --diffuse-from writes no output" || fail "refused --diffuse-from" "x.q.pm written"

# ---- 2. pm-render DIFFUSE_FROM, resident passes and a rerun across it
$R "$CORNELL" "$TMP/r0" $SMALL PASSES=2 DIFFUSE_DEPTH=0 >/dev/null 2>&1
$R "$CORNELL" "$TMP/rf" $SMALL PASSES=2 DIFFUSE_DEPTH=1 DIFFUSE_FROM=3 >/dev/null 2>&1
$R "$CORNELL" "$TMP/r3" $SMALL PASSES=3 DIFFUSE_DEPTH=0 >/dev/null 2>&1
$R "$CORNELL" "$TMP/rf3" $SMALL PASSES=4 DIFFUSE_DEPTH=1 DIFFUSE_FROM=3 >/dev/null 2>&1
if [ -s "$TMP/r0/running.pm" ] && [ "$(sum "$TMP/r0/running.pm")" = "$(sum "$TMP/rf/running.pm")" ]; then
    pass "DIFFUSE_FROM=3: 2 passes are the running image without the bounce"
else
    fail "DIFFUSE_FROM before its pass" "$(ls "$TMP/r0" "$TMP/rf")"
fi
if "$BIN/pm-info" --header "$TMP/rf3/running.pm" | grep -q -- '--diffuse-depth 1 --diffuse-from 3 --pass 4' &&
    grep -q 'DIFFUSE_FROM=3' "$TMP/rf3/passes.txt"; then
    pass "DIFFUSE_FROM=3: the stage's command and passes.txt's settings name it"
else
    fail "DIFFUSE_FROM's record" "$("$BIN/pm-info" --header "$TMP/rf3/running.pm" | grep COMMAND=trace-gather | head -1)"
fi
# the rerun: 2 passes then 4 (passes 3 and 4 bounce), against one render of 4
$R "$CORNELL" "$TMP/rf" $SMALL PASSES=4 DIFFUSE_DEPTH=1 DIFFUSE_FROM=3 >"$TMP/rf.rerun" 2>&1
if [ "$(jq .total.passes "$TMP/rf/stats.json")" = 4 ] && [ "$(sum "$TMP/rf/running.pm")" = "$(sum "$TMP/rf3/running.pm")" ] &&
    [ "$(sum "$TMP/rf3/running.pm")" != "$(sum "$TMP/r3/running.pm")" ]; then
    pass "DIFFUSE_FROM=3: 2 passes then 2 more make the running image of one 4-pass render"
else
    fail "DIFFUSE_FROM rerun" "$(tail -2 "$TMP/rf.rerun")"
fi

# ---- 3. DIFFUSE_DEPTH=auto
$R "$CORNELL" "$TMP/auto" $SMALL PASSES=2 DIFFUSE_DEPTH=auto VERBOSE=1 >"$TMP/auto.out" 2>&1
$R "$CORNELL" "$TMP/auto1" $SMALL DIFFUSE_DEPTH=auto >/dev/null 2>&1
if grep 'trace-gather-points' "$TMP/auto.out" | grep -q -- '--diffuse-depth 1 --diffuse-from 32' &&
    [ "$(sum "$TMP/auto/running.pm")" = "$(sum "$TMP/r0/running.pm")" ] && [ -s "$TMP/auto1/queries.pm" ] &&
    ! "$BIN/pm-info" --header "$TMP/auto1/queries.pm" | grep -q -- '--diffuse'; then
    pass "DIFFUSE_DEPTH=auto: progressive passes bounce from pass 32 (2 passes: the image without), one render never"
else
    fail "DIFFUSE_DEPTH=auto" "$(grep 'trace-gather-points' "$TMP/auto.out" | head -1)"
fi
# the scenes auto leaves without the bounce: mirrors or glass (the caustic scene), portals (the
# skylight room); DIFFUSE_DEPTH=1 given still bounces there
tgp_args() { grep 'trace-gather-points' "$1" | head -1; }
$R scenes/caustic/scene.json "$TMP/acau" $SMALL PASSES=2 VERBOSE=1 >"$TMP/acau.out" 2>&1
$R scenes/skylight/scene.json "$TMP/asky" $SMALL PASSES=2 VERBOSE=1 >"$TMP/asky.out" 2>&1
$R scenes/caustic/scene.json "$TMP/acau1" $SMALL PASSES=2 DIFFUSE_DEPTH=1 VERBOSE=1 >"$TMP/acau1.out" 2>&1
if [ -s "$TMP/acau/image.exr" ] && [ -s "$TMP/asky/image.exr" ] && ! tgp_args "$TMP/acau.out" | grep -q -- --diffuse &&
    ! tgp_args "$TMP/asky.out" | grep -q -- --diffuse && tgp_args "$TMP/acau1.out" | grep -q -- '--diffuse-depth 1'; then
    pass "DIFFUSE_DEPTH=auto: no bounce for a scene with glass and mirrors or with portals; DIFFUSE_DEPTH=1 bounces there"
else
    fail "DIFFUSE_DEPTH=auto's scene rule" "$(tgp_args "$TMP/acau.out") / $(tgp_args "$TMP/asky.out")"
fi
expect_exit "DIFFUSE_DEPTH=auto with GATHER=none runs (no bounce: no gather)" 0 \
    $R "$CORNELL" "$TMP/auto-none" $SMALL PASSES=2 DIFFUSE_DEPTH=auto GATHER=none
expect_exit "DIFFUSE_DEPTH=auto with MODE=direct-vis runs (no bounce: no secondary paths)" 0 \
    $R "$CORNELL" "$TMP/auto-dv" $SMALL PASSES=2 DIFFUSE_DEPTH=auto MODE=direct-vis
for v in DIFFUSE_FROM=0 DIFFUSE_FROM=x DIFFUSE_FROM=-1 DIFFUSE_FROM=1e3; do
    expect_exit "pm-render $v with DIFFUSE_DEPTH=1 is refused" 2 $R "$CORNELL" "$TMP/bad" $SMALL PASSES=2 DIFFUSE_DEPTH=1 $v
done
expect_exit "pm-render DIFFUSE_DEPTH=1 with GATHER=none is refused, one render with DIFFUSE_FROM=2 too" 2 \
    $R "$CORNELL" "$TMP/bad" $SMALL GATHER=none DIFFUSE_DEPTH=1 DIFFUSE_FROM=2
expect_exit "pm-render DIFFUSE_FROM=3 with DIFFUSE_DEPTH=0 is refused (nothing to start)" 2 \
    $R "$CORNELL" "$TMP/bad" $SMALL PASSES=2 DIFFUSE_DEPTH=0 DIFFUSE_FROM=3
[ ! -e "$TMP/bad" ] && pass "a refused DIFFUSE_FROM makes no OUTDIR" || fail "refused DIFFUSE_FROM" "$(ls "$TMP/bad")"
