# progress.sh: pipelines/render and pipelines/frames show progress on a terminal (issue 21,
# point 3): which stage runs, its place, the time left and the stage's own progress line;
# nothing of it off a terminal or with QUIET=1. The terminal is script(1)'s pty.
# programs: pm-render trace-photons trace-gather-points simd-gather
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
TINY="PHOTONS=20000 SPP=4 WIDTH=24 HEIGHT=16"
if ! command -v script >/dev/null; then
    skip "progress on a terminal: script(1) (Debian package bsdutils) is not installed"
else
    O=$TMP/o
    script -qec "$R $CORNELL $O $TINY" /dev/null >"$TMP/tty1.out" 2>&1
    status=$?
    if [ $status = 0 ] && grep -q '^render: stage 1 of 6: ' "$TMP/tty1.out" && grep -q '^render: stage 6 of 6: composite ' "$TMP/tty1.out" &&
        grep -q 'time left not known yet' "$TMP/tty1.out" && grep -q 'photons: 100.0% (20000 of 20000)' "$TMP/tty1.out"; then
        pass "render on a terminal: each stage's place among 6, and trace-photons' own progress line"
    else
        fail "render progress on a terminal" "exit $status: $(head -c 600 "$TMP/tty1.out")"
    fi
    # A second render with another radius: two stages run, the time left by the last run's.
    script -qec "$R $CORNELL $O $TINY RADIUS=0.05" /dev/null >"$TMP/tty2.out" 2>&1
    left=$(sed -n 's/^render: stage 1 of 2: simd-gather (about \([0-9.]*\) s left, by the last run).*/\1/p' "$TMP/tty2.out")
    if [ -n "$left" ] && grep -q '^render: stage 2 of 2: composite' "$TMP/tty2.out" && awk -v l="$left" 'BEGIN { exit !(l >= 0) }'; then
        pass "... a rerun counts only the stages make runs, with the time left by the last run's times ($left s)"
    else
        fail "render rerun progress" "$(head -c 600 "$TMP/tty2.out")"
    fi
    script -qec "$R $CORNELL $O $TINY RADIUS=0.06 QUIET=1" /dev/null >"$TMP/tty3.out" 2>&1
    if grep -q 'render: stage' "$TMP/tty3.out" || grep -q '%' "$TMP/tty3.out"; then
        fail "QUIET=1 on a terminal" "$(head -c 400 "$TMP/tty3.out")"
    else
        pass "... QUIET=1: no progress on a terminal"
    fi
    script -qec "pipelines/frames $CORNELL $TMP/fr FRAMES=3 PHOTONS=5000 SPP=4 WIDTH=24 HEIGHT=16" /dev/null >"$TMP/fr.out" 2>&1
    if grep -q 'frames: frame 1 of 3 (time left known after frame 0)' "$TMP/fr.out" &&
        grep -qE 'frames: frame 3 of 3 \(about [0-9.]+ s left\)' "$TMP/fr.out"; then
        pass "frames on a terminal: which frame runs and the time left"
    else
        fail "frames progress on a terminal" "$(head -c 600 "$TMP/fr.out" | tr '\r' '|')"
    fi
    script -qec "pipelines/frames $CORNELL $TMP/fr FRAMES=2 PHOTONS=5000 SPP=4 WIDTH=24 HEIGHT=16 QUIET=1" /dev/null >"$TMP/fr2.out" 2>&1
    grep -q 'frames: frame' "$TMP/fr2.out" && fail "frames QUIET=1" "$(head -c 300 "$TMP/fr2.out")" || pass "... QUIET=1: none"
fi
# Off a terminal: neither says anything of progress.
$R "$CORNELL" "$TMP/p" $TINY >"$TMP/p.out" 2>&1
pipelines/frames "$CORNELL" "$TMP/pf" FRAMES=2 PHOTONS=5000 SPP=4 WIDTH=24 HEIGHT=16 >>"$TMP/p.out" 2>&1
if grep -q 'render: stage\|frames: frame\|%' "$TMP/p.out" || grep -q $'\r' "$TMP/p.out"; then
    fail "no progress off a terminal" "$(head -c 400 "$TMP/p.out")"
else
    pass "off a terminal, render and frames print no progress"
fi
expect_exit "render QUIET=2 is bad usage" 2 $R "$CORNELL" "$TMP/q" QUIET=2
expect_exit "frames QUIET=2 is bad usage" 2 pipelines/frames "$CORNELL" "$TMP/q" QUIET=2
