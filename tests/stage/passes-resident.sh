# passes-resident.sh: the settings pm-render's resident progressive passes run beside the
# default (issue 26, item 2): the caustic branch of a scene with mirrors or glass, MODE=direct-vis
# (over a global and an indirect map), ORDER=none, GATHER=none, SECONDARY_DIRECT=1, COVERAGE=1 and
# a diffuse bounce from pass 3 (DIFFUSE_FROM=3). Each runs resident (no pass
# directory) and makes the running image and the image the pass files make (KEEP=all,
# pm_render_passes), record for record and pixel for pixel; the caustic branch also
# when a rerun adds a pass, and for any THREADS.
# programs: pm-render simd-gather trace-photons trace-gather-points build-photonmap hilbert-sort composite pm-info
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
CAUSTIC=scenes/caustic/scene.json
SMALL="PHOTONS=20000 SPP=4 WIDTH=32 HEIGHT=24"
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }
pixels() { "$BUILD/tests/pm-exrdump" "$1"; }

# same NAME SCENE NAME=VALUE...: resident against pass files, 3 passes
same() {
    local name=$1 scene=$2 d="$TMP/$1"
    mkdir -p "$d"
    shift 2
    if ! "$R" "$scene" "$d/res" $SMALL PASSES=3 "$@" >"$d.res.out" 2>&1; then
        fail "resident $name" "$(tail -3 "$d.res.out")"
        return
    fi
    if ! "$R" "$scene" "$d/files" $SMALL PASSES=3 KEEP=all "$@" >"$d.files.out" 2>&1; then
        fail "pass files $name" "$(tail -3 "$d.files.out")"
        return
    fi
    if grep -q 'resident stages' "$d.res.out" && ! ls -d "$d/res"/pass-* >/dev/null 2>&1 &&
        [ "$(jq .total.passes "$d/res/stats.json")" = 3 ] &&
        cmp -s <(records "$d/res/running.pm") <(records "$d/files/running.pm") &&
        cmp -s <(pixels "$d/res/image.exr") <(pixels "$d/files/image.exr") && cmp -s "$d/res/image.png" "$d/files/image.png"; then
        pass "resident $name: 3 passes, the running image's records and the image's pixels of the pass files"
    else
        fail "resident $name against pass files" "$(head -1 "$d.res.out"; ls "$d/res")"
    fi
}
same caustic "$CAUSTIC"
same caustic-radius "$CAUSTIC" RADIUS=0.05
same direct-vis "$CORNELL" MODE=direct-vis
same coverage "$CORNELL" COVERAGE=1
same caustic-coverage "$CAUSTIC" COVERAGE=1
same direct-vis-indirect "$CORNELL" MODE=direct-vis MAP=indirect
same order-none "$CORNELL" ORDER=none
same gather-none "$CORNELL" GATHER=none
same secondary-direct tests/scenes/closed-box/scene.json SECONDARY_DIRECT=1
same secondary-direct-sky scenes/atrium/textured.json SECONDARY_DIRECT=1
same caustic-gather-none "$CAUSTIC" GATHER=none
# the caustic gather's coverage plan: with the boundary correction (COVERAGE=auto from TIME=2),
# both gathers read a line a pass from the driver. Which passes keep the caustic gather's
# samples (the budget's last, cut short) is the machine's timing, so the rule itself is a unit
# test (pm_progressive_hold_caustic).
if "$R" "$CAUSTIC" "$TMP/ccp" $SMALL TIME=2 VERBOSE=1 >"$TMP/ccp.out" 2>&1 &&
    grep -q 'simd-gather .*--k-each-pass .*--coverage-plan /dev/fd/' "$TMP/ccp.out" &&
    [ "$(grep -c 'simd-gather .*--coverage-plan /dev/fd/' "$TMP/ccp.out")" = 2 ] &&
    [ "$(jq .total.passes "$TMP/ccp/stats.json")" -ge 1 ]; then
    pass "resident caustic branch, TIME=2: the global and the caustic gather both take the driver's --coverage-plan"
else
    fail "caustic gather's coverage plan" "$(grep -- '--coverage' "$TMP/ccp.out" | head -2; tail -2 "$TMP/ccp.out")"
fi
same diffuse-from "$CORNELL" DIFFUSE_DEPTH=1 DIFFUSE_FROM=3

# the caustic branch's stages, each named in stats.json; GATHER=none warns of the missing caustics
jq -e '.stages | has("build-photonmap.caustic") and has("simd-gather.caustic")' "$TMP/caustic/res/stats.json" >/dev/null &&
    pass "resident caustic branch: build-photonmap.caustic and simd-gather.caustic in stats.json" ||
    fail "resident caustic stats" "$(jq -c '.stages | keys' "$TMP/caustic/res/stats.json")"
grep -q 'warning: GATHER=none: the light mirrors and glass throw' "$TMP/caustic-gather-none.res.out" &&
    pass "resident GATHER=none on mirrors and glass: the missing caustics are reported" ||
    fail "resident GATHER=none caustic warning" "$(head -3 "$TMP/caustic-gather-none.res.out")"
! jq -e '.passes[0].stages | has("trace-photons") or has("simd-gather")' "$TMP/gather-none/res/stats.json" >/dev/null &&
    grep -q 'GATHER=none' "$TMP/gather-none/res/passes.txt" &&
    pass "resident GATHER=none: no photon stage or gather in a pass's stats; passes.txt names it" ||
    fail "resident GATHER=none stats" "$(jq -c '.passes[0].stages | keys' "$TMP/gather-none/res/stats.json")"

# the caustic branch over a rerun: 2 passes, then a third added (its caustic width measured on
# its own map, the gather's from the running image's radius1), with THREADS=1
"$R" "$CAUSTIC" "$TMP/cr" $SMALL PASSES=2 >/dev/null 2>&1
"$R" "$CAUSTIC" "$TMP/cr" $SMALL PASSES=3 THREADS=1 >"$TMP/cr.out" 2>&1
[ "$(jq .total.added "$TMP/cr/stats.json")" = 1 ] && cmp -s <(records "$TMP/cr/running.pm") <(records "$TMP/caustic/files/running.pm") &&
    pass "resident caustic branch: 2 passes, then pass 3 added with THREADS=1, the running image of 3 passes of pass files" ||
    fail "resident caustic rerun" "$(tail -4 "$TMP/cr.out")"

# a settings line that changes MODE starts the passes again
"$R" "$CORNELL" "$TMP/direct-vis/res" $SMALL PASSES=3 >"$TMP/mode.out" 2>&1
grep -q 'does not hold these passes (other settings)' "$TMP/mode.out" && [ "$(jq .total.added "$TMP/direct-vis/res/stats.json")" = 3 ] &&
    pass "MODE=gather on a running image of MODE=direct-vis: the passes start again, and say so" ||
    fail "resident MODE change" "$(tail -4 "$TMP/mode.out")"

# simd-gather --k-each-pass: only with --stream pairs and --k
"$BIN/simd-gather" -q --k-each-pass --k 5 "$TMP/caustic/files/pass-0001/photonmap.pm" x.pm -o - >/dev/null 2>"$TMP/ke.err"
[ $? = 2 ] && grep -q 'needs --stream pairs' "$TMP/ke.err" &&
    pass "simd-gather --k-each-pass without --stream pairs: usage error, exit 2" || fail "--k-each-pass usage" "$(cat "$TMP/ke.err")"

# stats.json: each added pass's CPU by resident stage (stages_cpu_s) and its sum (cpu_s), the
# pass's compute beside its wall_s (no timing is judged here: benchmarks do)
jq -e '[.passes[] | (.cpu_s | type == "number" and . >= 0) and (.stages_cpu_s | has("trace-gather-points") and has("simd-gather.caustic"))] | all and length == 3' \
    "$TMP/caustic/res/stats.json" >/dev/null &&
    pass "resident stats.json: every pass's cpu_s and its stages' stages_cpu_s" ||
    fail "resident per-pass cpu_s" "$(jq -c '.passes[0]' "$TMP/caustic/res/stats.json")"

# A stage that dies during a render (the gather killed from RENDER_PASS_HOOK after pass 2, with
# pass 3 in flight): the message names that stage and the signal, counts as finished only the
# passes running.pm holds (the one in flight pending), and the same request again goes on to
# PASSES=6 (it had found "nothing to add") with the bytes of a render that never failed.
cat >"$TMP/kill-hook" <<'EOF2'
#!/bin/sh
[ "$1" = 2 ] || exit 0
for c in /proc/[0-9]*/cmdline; do
    if tr '\0' ' ' <"$c" 2>/dev/null | grep -q "simd-gather .*$KILL_OUT/.stats-simd-gather"; then
        p=${c#/proc/}
        p=${p%/cmdline}
        kill -KILL "$p" 2>/dev/null
        # gone (or a zombie, its pipes closed) before the driver plans the next pass
        i=0
        while [ $i -lt 500 ] && [ -e "/proc/$p" ] && ! grep -q '^State:.*Z' "/proc/$p/status" 2>/dev/null; do
            sleep 0.01
            i=$((i + 1))
        done
    fi
done
exit 0
EOF2
chmod +x "$TMP/kill-hook"
K="$TMP/killed"
KILL_OUT="$K" RENDER_PASS_HOOK="$TMP/kill-hook" "$R" "$CORNELL" "$K" $SMALL PASSES=6 OVERLAP=1 >"$TMP/killed.out" 2>&1
krc=$?
"$R" "$CORNELL" "$K" $SMALL PASSES=6 OVERLAP=1 >"$TMP/killed2.out" 2>&1
k2=$?
"$R" "$CORNELL" "$TMP/unkilled" $SMALL PASSES=6 OVERLAP=1 >/dev/null 2>&1
if [ $krc = 1 ] && grep -q 'pass 3 failed in simd-gather (ended by signal 9' "$TMP/killed.out" &&
    grep -q 'running.pm hold the 2 finished passes (and 1 pending, which the next run settles)' "$TMP/killed.out" &&
    [ $k2 = 0 ] && grep -q 'stopped by PASSES=6' "$TMP/killed2.out" &&
    cmp -s <(records "$K/running.pm") <(records "$TMP/unkilled/running.pm"); then
    pass "a gather killed after pass 2: named with its signal, 2 passes finished and 1 pending; the same request then ends at pass 6, the bytes of a render never stopped"
else
    fail "a stage killed during a resident render" "$(tail -1 "$TMP/killed.out"; tail -1 "$TMP/killed2.out")"
fi
