# pm-render.sh: bin/pm-render (and pipelines/render, which is it under another name) decides
# what to rerun by provenance alone (issue 26): a second scene file with only the camera moved
# keeps the photon side and remakes the eye side, a scene file at another path is the same
# scene, a deleted, truncated or corrupt intermediate is named and remade (issue 28 item 1: a
# lost queries.pm never blocks a later render), and a rerun with nothing to do runs nothing and
# touches no file. Outputs are the same bytes for any THREADS and VERBOSE.
# programs: pm-render
PR=$BIN/pm-render
TINY="PHOTONS=4000 SPP=4 WIDTH=16 HEIGHT=12"
sorted() { tr ' ' '\n' | grep -v '^$' | sort | tr '\n' ' ' | sed 's/ $//'; }
expect_ran() { # expect_ran NAME OUTDIR "STAGES": exactly these stages ran in the last render
    local got want
    got=$(sorted <"$2/ran.txt") want=$(echo "$3" | sorted)
    if [ "$got" = "$want" ]; then pass "$1"; else fail "$1" "ran '$got', expected '$want'"; fi
}

# Two shots of one scene: shot2.json moves the camera alone.
S=$TMP/shots
mkdir -p "$S"
cp scenes/cornell-box/cornell-box.obj scenes/cornell-box/*.mtl "$S/" 2>/dev/null
cp scenes/cornell-box/scene.json "$S/shot1.json"
sed 's/"eye": \[0.278, 0.273, -0.800\]/"eye": [0.300, 0.260, -0.790]/' scenes/cornell-box/scene.json >"$S/shot2.json"
cmp -s "$S/shot1.json" "$S/shot2.json" && fail "shot2.json" "the camera did not move"
O=$TMP/o
"$PR" "$S/shot1.json" "$O" $TINY >"$TMP/1.out" 2>"$TMP/1.err"
status=$?
[ $status = 0 ] && [ -s "$O/image.exr" ] && [ -s "$O/image.png" ] && [ -s "$O/stats.json" ] &&
    pass "pm-render renders shot1.json: image.exr, image.png, stats.json" || fail "first render" "exit $status: $(head -c 300 "$TMP/1.err")"
expect_ran "... every stage ran" "$O" "trace-photons build-photonmap trace-gather-points hilbert-sort simd-gather composite"
cp "$O/photonmap.pm" "$TMP/map1.pm"
"$PR" "$S/shot2.json" "$O" $TINY >"$TMP/2.out" 2>"$TMP/2.err"
expect_ran "shot2.json (the camera moved) keeps the photon map and remakes the eye side" "$O" \
    "trace-gather-points hilbert-sort simd-gather composite"
cmp -s "$O/photonmap.pm" "$TMP/map1.pm" && pass "... the photon map is shot1's, byte for byte" ||
    fail "photon map of shot2" "it changed"
grep -qE '^  trace-photons +cached' "$TMP/2.out" && grep -qE '^  trace-gather-points +ran' "$TMP/2.out" &&
    pass "... and the table says so" || fail "table for shot2" "$(cat "$TMP/2.out")"
cp "$S/shot2.json" "$S/another name.json"
"$PR" "$S/another name.json" "$O" $TINY >/dev/null 2>&1
expect_ran "the same scene under another path reruns nothing (its path is no part of any identity)" "$O" ""

# Nothing to do: nothing runs, no file is rewritten.
before=$(cd "$O" && stat -c '%n %i %.9Y' ./*.pm image.exr image.png)
"$PR" "$S/shot2.json" "$O" $TINY >"$TMP/3.out" 2>"$TMP/3.err"
status=$?
after=$(cd "$O" && stat -c '%n %i %.9Y' ./*.pm image.exr image.png)
[ $status = 0 ] && [ ! -s "$O/ran.txt" ] && [ "$before" = "$after" ] && [ ! -s "$TMP/3.err" ] &&
    pass "a rerun with nothing to do runs nothing, rewrites no file and says nothing on stderr" ||
    fail "rerun with nothing to do" "exit $status, ran '$(cat "$O/ran.txt")', stderr $(head -c 200 "$TMP/3.err")"
[ ! -e "$O/Makefile" ] && [ ! -e "$O/.stamps" ] && pass "... and OUTDIR holds no Makefile and no stamps" ||
    fail "no make" "$(ls -a "$O")"

# Issue 28 item 1: a deleted, truncated or corrupt queries.pm is remade, and blocks nothing.
cp "$O/image.exr" "$TMP/img.exr"
rm "$O/queries.pm"
"$PR" "$S/shot2.json" "$O" $TINY >"$TMP/4.out" 2>"$TMP/4.err"
status=$?
[ $status = 0 ] && grep -qx 'render: queries.pm is missing: remaking it\|pm-render: queries.pm is missing: remaking it' "$TMP/4.err" &&
    [ -s "$O/queries.pm" ] && cmp -s "$O/image.exr" "$TMP/img.exr" &&
    pass "a deleted queries.pm is named and remade, the image the same" ||
    fail "deleted queries.pm" "exit $status: $(head -c 300 "$TMP/4.err")"
expect_ran "... by trace-gather-points alone: the sorted queries recorded its content, which is back" "$O" "trace-gather-points"
truncate -s -100 "$O/queries.pm"
"$PR" "$S/shot2.json" "$O" $TINY >"$TMP/5.out" 2>"$TMP/5.err"
status=$?
[ $status = 0 ] && grep -q '^pm-render: queries.pm is corrupt (truncated' "$TMP/5.err" && "$BIN/pm-info" -q "$O/queries.pm" >/dev/null &&
    pass "a truncated queries.pm is named and remade" || fail "truncated queries.pm" "exit $status: $(head -c 300 "$TMP/5.err")"
"$PR" "$S/shot2.json" "$O" $TINY >/dev/null 2>&1
expect_ran "... and the render after it runs nothing" "$O" ""
off=$(($(stat -c %s "$O/sorted.pm") - 100))
printf '\x55' | dd of="$O/sorted.pm" bs=1 seek=$off conv=notrunc status=none
"$PR" "$S/shot2.json" "$O" $TINY >"$TMP/6.out" 2>"$TMP/6.err"
status=$?
[ $status = 0 ] && grep -qx 'pm-render: sorted.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/6.err" &&
    cmp -s "$O/image.exr" "$TMP/img.exr" && pass "a flipped byte in sorted.pm is named and remade, the image the same" ||
    fail "corrupt sorted.pm" "exit $status: $(head -c 300 "$TMP/6.err")"
expect_ran "... and nothing after it: the gather recorded the sorted queries' content, which is back" "$O" "hilbert-sort"
rm "$O/image.png"
"$PR" "$S/shot2.json" "$O" $TINY >/dev/null 2>&1
expect_ran "a deleted image.png is remade by composite alone" "$O" "composite"

# Byte-identical outputs for any THREADS and VERBOSE (the stages record neither).
"$PR" "$S/shot1.json" "$TMP/t1" $TINY THREADS=1 >/dev/null 2>&1
"$PR" "$S/shot1.json" "$TMP/t2" $TINY THREADS=2 VERBOSE=1 >"$TMP/t2.out" 2>"$TMP/t2.err"
bad=""
for f in photons.pm photonmap.pm queries.pm sorted.pm direct.pm indirect.pm image.exr image.png; do
    cmp -s "$TMP/t1/$f" "$TMP/t2/$f" || bad+=" $f"
done
[ -z "$bad" ] && grep -q '^+ .*/trace-photons ' "$TMP/t2.err" && pass "THREADS=1 and THREADS=2 VERBOSE=1 make the same bytes; VERBOSE prints each command" ||
    fail "THREADS and VERBOSE" "differ:$bad"
"$PR" "$S/shot1.json" "$TMP/t1" $TINY THREADS=2 VERBOSE=1 >/dev/null 2>&1
expect_ran "... and a rerun with other THREADS and VERBOSE runs nothing" "$TMP/t1" ""
# JOBS=2: the photon side and the eye side at once, the same files
"$PR" "$S/shot1.json" "$TMP/j2" $TINY JOBS=2 >/dev/null 2>&1
bad=""
for f in photons.pm photonmap.pm queries.pm sorted.pm direct.pm indirect.pm image.exr image.png; do
    cmp -s "$TMP/t1/$f" "$TMP/j2/$f" || bad+=" $f"
done
[ -z "$bad" ] && [ "$(sorted <"$TMP/j2/ran.txt")" = "build-photonmap composite hilbert-sort simd-gather trace-gather-points trace-photons" ] &&
    pass "JOBS=2 runs every stage and makes the same bytes as one at a time" || fail "JOBS=2" "differ:$bad"

# Exit statuses: usage 2 (nothing made), bad input 1.
expect_exit "pm-render with one argument is bad usage" 2 "$PR" "$S/shot1.json"
rm -rf "$TMP/u"
expect_exit "an unknown parameter is bad usage" 2 "$PR" "$S/shot1.json" "$TMP/u" NOPE=1
[ ! -e "$TMP/u" ] && pass "... and makes no OUTDIR" || fail "usage made OUTDIR" "$(ls -a "$TMP/u")"
expect_exit "a missing scene is bad input" 1 "$PR" "$TMP/none.json" "$TMP/u"
printf '{"pmtk_scene": 1, "name": "x", "meshes": [' >"$TMP/bad.json"
expect_exit "a scene that does not load is bad input" 1 "$PR" "$TMP/bad.json" "$TMP/u" $TINY
expect_exit "an unknown TARGET is bad usage" 2 "$PR" "$S/shot1.json" "$TMP/u" $TINY nothing.pm

# --check-settings: the settings judged as a render would (each stage's values by the stage),
# nothing rendered, no OUTDIR made (pipelines/slurm asks it before it submits anything).
rm -rf "$TMP/cs"
expect_exit "--check-settings: good settings, exit 0" 0 "$PR" --check-settings "$S/shot1.json" "$TMP/cs" $TINY PASSES=3 SHARDS=2
for v in TIME=nan TIME=1e400 TARGET_ERROR=inf RADIUS=-1 KEEP=most WIDTHS=variable PASS_RANGE=2:1 PASS_RANGE=1; do
    "$PR" --check-settings "$S/shot1.json" "$TMP/cs" $TINY PASSES=3 "$v" >"$TMP/cs.out" 2>"$TMP/cs.err"
    status=$?
    [ $status = 2 ] && [ "$(wc -l <"$TMP/cs.err")" = 1 ] && grep -q "^pm-render: .*${v%%=*}" "$TMP/cs.err" && [ ! -s "$TMP/cs.out" ] &&
        pass "--check-settings $v: exit 2, one line naming it" || fail "--check-settings $v" "exit $status: $(head -c 300 "$TMP/cs.err")"
done
[ ! -e "$TMP/cs" ] && pass "--check-settings makes no OUTDIR" || fail "--check-settings made OUTDIR" "$(ls -a "$TMP/cs")"
