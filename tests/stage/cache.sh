# cache.sh: pipelines/render's cache cannot be poisoned (issue 17, items 1, 2, 11, 12): one
# render at a time in an OUTDIR (the lock, WAIT), a cached file is kept only when its header
# records what render would do now (files of other parameters with newer dates are remade), a
# corrupt intermediate is named and rebuilt, a failing stage is called failed, paths holding
# '#', '$', ':' and spaces render, every parameter is judged before anything runs (exit 2, one
# line, no OUTDIR), and the scene's unsupported material keys reach the user once per render.
# programs: simd-gather pm-render
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
TINY="PHOTONS=5000 SPP=4 WIDTH=16 HEIGHT=12"
sorted() { tr ' ' '\n' | grep -v '^$' | sort | tr '\n' ' ' | sed 's/ $//'; }
expect_ran() { # expect_ran NAME OUTDIR "STAGES": exactly these stages ran in the last render
    local got want
    got=$(sorted <"$2/ran.txt") want=$(echo "$3" | sorted)
    if [ "$got" = "$want" ]; then pass "$1"; else fail "$1" "ran '$got', expected '$want'"; fi
}
spp_of() { "$BIN/pm-info" --header "$1" | grep -o -- '--spp [0-9]*' | tail -n 1; }
flip() { # flip FILE: one payload byte changed, the checksum trailer left as it was
    local off=$(($(stat -c %s "$1") - 100))
    printf '\x55' | dd of="$1" bs=1 seek=$off conv=notrunc status=none
}

# ---- 12: every parameter is judged before anything runs: exit 2, one line, nothing written
for bad in PHOTONS=abc SPP=5 RADIUS=-1 THREADS=x EXPOSURE=bright WIDTH=-3 K=abc ISA=avx9 VERBOSE=2 WAIT=maybe; do
    rm -rf "$TMP/v"
    $R "$CORNELL" "$TMP/v" $TINY "$bad" >"$TMP/v.out" 2>"$TMP/v.err"
    status=$?
    if [ $status = 2 ] && [ "$(wc -l <"$TMP/v.err")" = 1 ] && grep -q "^render: bad value for ${bad%%=*} '${bad#*=}'" "$TMP/v.err" &&
        [ ! -e "$TMP/v" ]; then
        pass "$bad is refused up front: exit 2, one line, no OUTDIR"
    else
        fail "$bad refused up front" "exit $status, OUTDIR $( [ -e "$TMP/v" ] && echo made || echo absent): $(head -c 300 "$TMP/v.err")"
    fi
done

# ---- 1: the lock. A holder that names itself in OUTDIR/.lock, as render does.
O=$TMP/lk
mkdir -p "$O"
echo "pid 4242: pipelines/render other.json $O" >"$O/.lock"
flock "$O/.lock" sleep 3 &
holder=$!
sleep 0.3
expect_error "WAIT=0: a held OUTDIR is refused, naming the holder" "^render: '$O' is in use by another render \(pid 4242: pipelines/render other.json" \
    $R "$CORNELL" "$O" $TINY GATHER=none WAIT=0
[ ! -e "$O/ran.txt" ] && pass "... and nothing in it is touched" || fail "WAIT=0 touched OUTDIR" "$(ls "$O")"
$R "$CORNELL" "$O" $TINY GATHER=none >"$TMP/lk.out" 2>"$TMP/lk.err"
status=$?
if kill -0 $holder 2>/dev/null; then
    fail "a second render waits for the holder" "it finished while the holder held the lock (exit $status)"
elif [ $status = 0 ] && grep -q "^render: waiting for '$O', in use by another render (pid 4242: " "$TMP/lk.err" && [ -s "$O/image.exr" ]; then
    pass "a second render waits for the holder, saying whom, then renders"
else
    fail "a second render waits" "exit $status: $(head -c 300 "$TMP/lk.err")"
fi
wait $holder 2>/dev/null
grep -q "^pid [0-9]*: .*pipelines/render $CORNELL $O " "$O/.lock" && pass "the lock file names the render that held it last" ||
    fail "lock file" "$(cat "$O/.lock")"

# The issue's repro: two renders into one OUTDIR at once, then the second's parameters again.
O=$TMP/rc
$R "$CORNELL" "$O" PHOTONS=20000 WIDTH=32 HEIGHT=32 SPP=4 >"$TMP/rc1.out" 2>&1 &
first=$!
$R "$CORNELL" "$O" PHOTONS=30000 WIDTH=32 HEIGHT=32 SPP=8 >"$TMP/rc2.out" 2>&1
s2=$?
wait $first
s1=$?
$R "$CORNELL" "$O" PHOTONS=30000 WIDTH=32 HEIGHT=32 SPP=8 >"$TMP/rc3.out" 2>&1
s3=$?
if [ "$s1 $s2 $s3" = "0 0 0" ] && [ "$(spp_of "$O/indirect.pm")" = "--spp 8" ] &&
    "$BIN/pm-info" --header "$O/photonmap.pm" | grep -q -- '--photons 30000'; then
    pass "two renders at once into one OUTDIR, then a third: its files are the third's (--spp 8, 30000 photons)"
else
    fail "concurrent renders" "exits $s1 $s2 $s3, indirect.pm says '$(spp_of "$O/indirect.pm")': $(tail -3 "$TMP/rc3.out")"
fi
grep -q 'mv: cannot stat' "$TMP/rc1.out" "$TMP/rc2.out" && fail "concurrent renders" "mv: cannot stat" ||
    pass "... with no 'mv: cannot stat Makefile.tmp'"

# ---- 1: the cache trusts content, not dates. Files of other parameters, newer than every
# stamp (as a second render would leave them), are remade.
A=$TMP/a B=$TMP/b
$R "$CORNELL" "$A" $TINY >/dev/null 2>&1
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 >/dev/null 2>&1
sleep 1.1 # newer by a whole second, whatever the file system's resolution
cp "$A/queries.pm" "$A/direct.pm" "$A/sorted.pm" "$A/indirect.pm" "$B/"
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 >"$TMP/b.out" 2>&1
expect_ran "newer files made with SPP=4 in an SPP=8 OUTDIR are remade" "$B" \
    "trace-gather-points hilbert-sort simd-gather composite"
[ "$(spp_of "$B/indirect.pm")" = "--spp 8" ] && pass "... and indirect.pm says --spp 8" ||
    fail "poisoned indirect.pm" "it says '$(spp_of "$B/indirect.pm")'"
sleep 1.1
cp "$A/image.exr" "$A/image.png" "$B/"
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 >/dev/null 2>&1
expect_ran "a newer image of other buffers is remade" "$B" "composite"
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 THREADS=1 VERBOSE=1 >/dev/null 2>&1
expect_ran "THREADS and VERBOSE (-q and --threads in the headers) rerun nothing" "$B" ""
# an intermediate another stage made (a gather's output in the photon map's place)
sleep 1.1
cp "$B/indirect.pm" "$B/photonmap.pm"
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 >/dev/null 2>&1
# (what read the map recorded its content, which the remade map has again: nothing after it reruns)
expect_ran "a file made by another command in an intermediate's place is remade" "$B" "build-photonmap"

# ---- 2: a corrupt cached intermediate is named and rebuilt
flip "$B/photonmap.pm"
$R "$CORNELL" "$B" PHOTONS=5000 SPP=8 WIDTH=16 HEIGHT=12 >"$TMP/c.out" 2>"$TMP/c.err"
status=$?
if [ $status = 0 ] && [ "$(grep -c corrupt "$TMP/c.err")" = 1 ] &&
    grep -qx 'render: photonmap.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/c.err" &&
    "$BIN/pm-info" "$B/photonmap.pm" >/dev/null 2>&1; then
    pass "a flipped byte in photonmap.pm: one line, and it is rebuilt"
else
    fail "corrupt photonmap.pm" "exit $status: $(head -c 400 "$TMP/c.err")"
fi
expect_ran "... and nothing after it: the gather recorded the map's content, which is back" "$B" "build-photonmap"
# A failing stage is called failed in the table, not cached.
cat >"$TMP/gather" <<EOF
#!/usr/bin/env bash
[ -e "$TMP/gather.ok" ] || { echo "gather: told to fail" >&2; exit 1; }
exec "$BIN/simd-gather" "\$@"
EOF
chmod +x "$TMP/gather"
touch "$TMP/gather.ok"
$R "$CORNELL" "$TMP/g" $TINY GATHER="$TMP/gather" >/dev/null 2>&1
rm "$TMP/gather.ok"
$R "$CORNELL" "$TMP/g" $TINY GATHER="$TMP/gather" RADIUS=0.05 >"$TMP/g.out" 2>&1
status=$?
[ $status = 1 ] && grep -qE '^  simd-gather +failed +-$' "$TMP/g.out" && grep -qE '^  composite +not made' "$TMP/g.out" &&
    grep -qE '^  hilbert-sort +cached' "$TMP/g.out" &&
    pass "a failing stage is 'failed' in the table, and what it stopped 'not made'" ||
    fail "failed stage in the table" "exit $status: $(cat "$TMP/g.out")"

# A pass's files are checked too (KEEP=all: the pass files; the resident passes of the default
# keep none, and an OUTDIR holding pass directories goes on with them).
P2=$TMP/p2
$R "$CORNELL" "$P2" $TINY PASSES=2 KEEP=all >/dev/null 2>&1
flip "$P2/pass-0002/photonmap.pm"
$R "$CORNELL" "$P2" $TINY PASSES=2 >"$TMP/p2.out" 2>"$TMP/p2.err"
status=$?
[ $status = 0 ] && grep -qx 'render: pass-0002/photonmap.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/p2.err" &&
    "$BIN/pm-info" "$P2/pass-0002/photonmap.pm" >/dev/null 2>&1 && [ ! -s "$P2/pass-0001/ran.txt" ] &&
    pass "passes: a corrupt pass-0002/photonmap.pm is named and rebuilt, pass 1 is kept" ||
    fail "passes: corrupt map" "exit $status: $(head -c 400 "$TMP/p2.err")"

# No seal: a made pass's files are read whole on every rerun, whatever their inode, size and
# date (pm-render's pass files, common/engine/fixed.c): a pass directory keeps no seal
# (.checked), Makefile or stamps, and a flipped byte with its date put back is still found.
redate() { touch -d "@$1" "$2"; } # redate SECONDS.NS FILE: put the date back
mtime() { stat -c %.9Y "$1"; }
P3=$TMP/p3
$R "$CORNELL" "$P3" $TINY PASSES=3 KEEP=all >/dev/null 2>&1
cp "$P3/image.exr" "$TMP/p3.exr"
[ -s "$P3/pass-0002/photonmap.pm" ] && [ ! -e "$P3/pass-0002/.checked" ] && [ ! -e "$P3/pass-0002/Makefile" ] &&
    [ ! -e "$P3/pass-0002/.stamps" ] &&
    pass "passes: a pass keeps its files and records alone (no seal, Makefile or stamps)" ||
    fail "passes: no seal" "$(ls -a "$P3/pass-0002")"
# a flipped byte in a buffer, its date put back: still read whole, named and remade
t=$(mtime "$P3/pass-0002/indirect.pm")
flip "$P3/pass-0002/indirect.pm"
redate "$t" "$P3/pass-0002/indirect.pm"
$R "$CORNELL" "$P3" $TINY PASSES=3 >"$TMP/p3.out" 2>"$TMP/p3.err"
status=$?
[ $status = 0 ] && grep -qx 'render: pass-0002/indirect.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/p3.err" &&
    [ -s "$P3/pass-0002/ran.txt" ] && [ ! -s "$P3/pass-0003/ran.txt" ] && cmp -s "$P3/image.exr" "$TMP/p3.exr" &&
    pass "passes: a flipped byte in a pass's buffer (date put back) is named, the pass remade, the image the same" ||
    fail "passes: corrupt buffer, date put back" "exit $status: $(head -c 400 "$TMP/p3.err")"
# a truncated map, its date put back
t=$(mtime "$P3/pass-0003/photonmap.pm")
truncate -s -44 "$P3/pass-0003/photonmap.pm"
redate "$t" "$P3/pass-0003/photonmap.pm"
$R "$CORNELL" "$P3" $TINY PASSES=3 >"$TMP/p3.out" 2>"$TMP/p3.err"
status=$?
[ $status = 0 ] && grep -q '^render: pass-0003/photonmap.pm is corrupt (truncated' "$TMP/p3.err" &&
    [ -s "$P3/pass-0003/ran.txt" ] && cmp -s "$P3/image.exr" "$TMP/p3.exr" &&
    pass "passes: a truncated map in a pass (date put back) is named and remade" ||
    fail "passes: truncated map, date put back" "exit $status: $(head -c 400 "$TMP/p3.err")"
# a buffer whose input changed: pass 3's map in pass 2's place (cp keeps the inode; its date
# put back): the gather's buffer records another map, so the pass is remade
t=$(mtime "$P3/pass-0002/photonmap.pm")
cp "$P3/pass-0002/photonmap.pm" "$TMP/p3-map2.pm"
cp "$P3/pass-0003/photonmap.pm" "$P3/pass-0002/photonmap.pm"
redate "$t" "$P3/pass-0002/photonmap.pm"
$R "$CORNELL" "$P3" $TINY PASSES=3 >"$TMP/p3.out" 2>"$TMP/p3.err"
status=$?
[ $status = 0 ] && [ -s "$P3/pass-0002/ran.txt" ] && cmp -s "$P3/pass-0002/photonmap.pm" "$TMP/p3-map2.pm" &&
    cmp -s "$P3/image.exr" "$TMP/p3.exr" &&
    pass "passes: another pass's map in a pass (date put back) is found and the pass remade" ||
    fail "passes: replaced map, date put back" "exit $status: $(head -c 400 "$TMP/p3.err")"
$R "$CORNELL" "$P3" $TINY PASSES=3 >"$TMP/p3.out" 2>&1
grep -qE '^  2 +cached' "$TMP/p3.out" && grep -qE '^  3 +cached' "$TMP/p3.out" &&
    pass "... and a rerun after them makes nothing" || fail "passes: rerun after remakes" "$(cat "$TMP/p3.out")"
# With SHARDS a stage reads the map: a flipped byte, the date put back, in a pass whose shard
# is missing is found before the shard's gather runs
P4=$TMP/p4
$R "$CORNELL" "$P4" $TINY PASSES=2 SHARDS=2 >/dev/null 2>&1
cp "$P4/image.exr" "$TMP/p4.exr"
t=$(mtime "$P4/pass-0002/photonmap.pm")
flip "$P4/pass-0002/photonmap.pm"
redate "$t" "$P4/pass-0002/photonmap.pm"
rm "$P4/pass-0002/indirect.1.pm"
$R "$CORNELL" "$P4" $TINY PASSES=2 SHARDS=2 >"$TMP/p4.out" 2>"$TMP/p4.err"
status=$?
[ $status = 0 ] && grep -qx 'render: pass-0002/photonmap.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/p4.err" &&
    cmp -s "$P4/image.exr" "$TMP/p4.exr" &&
    pass "passes: a pass whose stage would read a flipped map is checked first, the map rebuilt" ||
    fail "passes: flipped map read by a shard" "exit $status: $(head -c 400 "$TMP/p4.err")"
# pipelines/slurm's shard tasks (pipelines/lib/slurm-task, run here by hand, no Slurm needed: a
# task is the script, its spec and SLURM_ARRAY_TASK_ID): the task that lands a pass's last shard
# lands the pass whole, and the composite job's render reads every file whole, so that a flipped
# byte in the map, its date put back, is found and remade there, and its files are the local
# render's; so is a flipped byte in a shard's buffer.
P5=$TMP/p5
mkdir -p "$P5/.slurm/logs" "$P5/.slurm/done"
(
    SCENE=$PWD/$CORNELL ROOT=$PWD OUT=$P5 KEY=cache-sh PASSES=2 RANGES=(1:1 2:2) SHARDS=2 GNAME=simd-gather KEEP=all
    read -r -a RPARAMS <<<"$TINY SHARDS=2"
    declare -p SCENE ROOT BIN OUT KEY PASSES RPARAMS RANGES SHARDS GNAME KEEP >"$P5/.slurm/spec"
)
task() { SLURM_ARRAY_TASK_ID=$1 SLURM_JOB_ID=$2 pipelines/lib/slurm-task "$3" "$P5/.slurm/spec" "${@:4}"; }
{ task 0 11 prep && task 0 12 shard 0 && task 1 12 shard 0 && task 1 13 prep && task 1 14 shard 1 && task 0 14 shard 1; } \
    >"$TMP/p5.tasks" 2>&1 || fail "slurm-task by hand" "$(tail -n 3 "$TMP/p5.tasks")"
if [ "$(sorted <"$P5/pass-0002/ran.txt")" = "build-photonmap hilbert-sort simd-gather.0 simd-gather.1 trace-gather-points trace-photons" ] &&
    [ -s "$P5/pass-0002/indirect.1.pm" ] && [ -z "$(ls -A "$P5/.slurm/work")$(ls -A "$P5/.slurm/stage")" ]; then
    pass "slurm shard tasks: the task landing a pass's last shard lands it whole (ran.txt kept, nothing left staged)"
else
    fail "slurm shard tasks: landing" "ran $(paste -sd' ' "$P5/pass-0002/ran.txt"); left $(ls -A "$P5/.slurm/work" "$P5/.slurm/stage" | paste -sd' ')"
fi
cp "$P5/pass-0002/photonmap.pm" "$TMP/p5-map.pm"
t=$(mtime "$P5/pass-0002/photonmap.pm")
flip "$P5/pass-0002/photonmap.pm"
redate "$t" "$P5/pass-0002/photonmap.pm"
task 0 15 composite >"$TMP/p5.out" 2>&1
status=$?
bad=""
for f in pass-0001/direct.pm pass-0002/indirect.0.pm pass-0002/indirect.1.pm running.pm passes.txt image.exr image.png; do
    cmp -s "$P5/$f" "$P4/$f" || bad+=" $f"
done
[ $status = 0 ] && grep -qx 'render: pass-0002/photonmap.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/p5.out" &&
    grep -qE '^  2 +ran, added' "$TMP/p5.out" && [ -z "$bad" ] &&
    pass "... and the composite job's render finds a flipped byte in the map (date put back) and remakes it, its files the local render's" ||
    fail "slurm composite job, flipped map" "exit $status, differ:${bad:- none}: $(grep -m 3 'corrupt\|failed\|  2 ' "$TMP/p5.out")"
t=$(mtime "$P5/pass-0002/indirect.1.pm")
flip "$P5/pass-0002/indirect.1.pm"
redate "$t" "$P5/pass-0002/indirect.1.pm"
task 0 16 composite >"$TMP/p5.out" 2>&1
status=$?
[ $status = 0 ] && grep -qx 'render: pass-0002/indirect.1.pm is corrupt (checksum mismatch): rebuilding it' "$TMP/p5.out" &&
    cmp -s "$P5/pass-0002/indirect.1.pm" "$P4/pass-0002/indirect.1.pm" && cmp -s "$P5/image.exr" "$P4/image.exr" &&
    pass "... and a flipped byte in a shard's buffer (date put back) is named and remade, the image the same" ||
    fail "slurm: corrupt shard, date put back" "exit $status: $(grep -m 3 'corrupt\|failed' "$TMP/p5.out")"

# ---- 11: '#', '$', ':' and spaces in the scene's path and in OUTDIR
D="$TMP/a #b \$c: d"
mkdir -p "$D" && cp -r scenes/cornell-box/. "$D/"
HO="$D/out #1 \$x"
$R "$D/scene.json" "$HO" $TINY SHARDS=2 >"$TMP/h.out" 2>&1
status=$?
[ $status = 0 ] && [ -s "$HO/image.exr" ] && pass "a scene path and OUTDIR with '#', '\$', ':' and spaces render" ||
    fail "odd paths" "exit $status: $(tail -3 "$TMP/h.out")"
$R "$D/scene.json" "$HO" $TINY SHARDS=2 >/dev/null 2>&1
expect_ran "... and the same render again reruns nothing" "$HO" ""
$R "$D/scene.json" "$TMP/hp #2" $TINY PASSES=2 >"$TMP/hp.out" 2>&1 && [ -s "$TMP/hp #2/image.exr" ] &&
    pass "... and with passes" || fail "odd paths with passes" "$(tail -3 "$TMP/hp.out")"

# ---- the scene's warnings, once per render
$R tests/scenes/unsupported-mtl/scene.json "$TMP/w" WIDTH=8 HEIGHT=8 SPP=4 GATHER=none >"$TMP/w.out" 2>"$TMP/w.err"
status=$?
if [ $status = 0 ] && [ "$(grep -c "^render: warning: material 'textured': map_Ka 'tex.png' is not supported (ignored)$" "$TMP/w.err")" = 1 ] &&
    grep -qx "render: warning: material 'textured': d 0.8 is not supported (ignored)" "$TMP/w.err" &&
    ! grep -q "material 'plain'" "$TMP/w.err"; then
    pass "the scene's unsupported material keys are reported once each"
else
    fail "scene warnings" "exit $status: $(head -c 400 "$TMP/w.err")"
fi
