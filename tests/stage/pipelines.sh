# pipelines.sh: pipelines/render reruns exactly the stages whose inputs changed, says what it
# left out, and writes image.exr, image.png and stats.json; pipelines/frames and the documented
# examples run. The dependency logic is checked with a stand-in gather (GATHER=PATH) that is
# fast and whose output is known, then the whole render with the real simd-gather.
# programs: pm-render trace-photons build-photonmap trace-gather-points hilbert-sort simd-gather composite trace-reference measure-error
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
SMALL="PHOTONS=20000 SPP=4 WIDTH=32 HEIGHT=24"
sorted() { tr ' ' '\n' | grep -v '^$' | sort | tr '\n' ' ' | sed 's/ $//'; }
# expect_ran NAME OUTDIR "STAGES": exactly these stages ran in the last render (in any order:
# make may take independent stages in either order)
expect_ran() {
    local got want
    got=$(sorted <"$2/ran.txt") want=$(echo "$3" | sorted)
    if [ "$got" = "$want" ]; then pass "$1"; else fail "$1" "ran '$got', expected '$want'"; fi
}

# A stand-in for simd-gather (GATHER=PATH outside the program directory): a wrapper that logs
# where it ran and runs simd-gather, whose output records simd-gather's command line; pm-render
# judges a stand-in's output by that line without the program's name (a stand-in that records
# no command line of its own is remade on every render: no provenance says what made it).
cp -r scenes/cornell-box "$TMP/scene"
SCENE=$TMP/scene/scene.json
cat >"$TMP/fake-gather" <<FAKE
#!/usr/bin/env bash
echo "\$(basename "\$PWD")" >>"$TMP/fake-gather.log"
exec "$BIN/simd-gather" "\$@"
FAKE
chmod +x "$TMP/fake-gather"
FAKE="GATHER=$TMP/fake-gather"
O=$TMP/r

$R "$SCENE" "$O" $SMALL $FAKE >"$TMP/out1" 2>&1
status=$?
if [ $status = 0 ] && [ -s "$O/image.exr" ] && [ -s "$O/image.png" ] && [ -s "$O/stats.json" ]; then
    pass "render writes image.exr, image.png and stats.json"
else
    fail "render first run" "exit $status: $(tail -5 "$TMP/out1")"
fi
expect_ran "the first render runs every stage" "$O" \
    "trace-photons build-photonmap trace-gather-points hilbert-sort simd-gather composite"
if [ "$(jq -r '.stages | keys | join(" ")' "$O/stats.json")" = "build-photonmap composite hilbert-sort simd-gather trace-gather-points trace-photons" ] &&
    [ "$(jq -r '.stages["trace-photons"].stats.photons_emitted // .stages["trace-photons"].stats.stage' "$O/stats.json")" != null ] &&
    jq -e '.total.wall_s > 0 and .total.pipeline_wall_s > 0 and (.total.ran | length) == 6' "$O/stats.json" >/dev/null; then
    pass "stats.json holds every stage's stats and the total"
else
    fail "stats.json" "$(head -c 600 "$O/stats.json")"
fi
if grep -qE '^  trace-photons +ran +[0-9.]+$' "$TMP/out1" && grep -q '^  total of the stages' "$TMP/out1" &&
    grep -q 'left out direction channels: every material is Lambertian' "$TMP/out1"; then
    pass "render prints a per-stage time table and what it left out"
else
    fail "render table" "$(cat "$TMP/out1")"
fi
# What made a file is in its own header (the image: composite's COMMAND in the EXR's attributes).
image_command() { # image_command DIR: the last COMMAND.N attribute of DIR/image.exr
    local i=0 c last=""
    while c=$("$BUILD/tests/pm-exrdump" "$1/image.exr" "COMMAND.$i" 2>/dev/null) && [ -n "$c" ]; do last=$c i=$((i + 1)); done
    printf '%s' "$last"
}
image_command "$O" | grep -q '^composite direct.pm indirect.pm -o image.exr' && pass "the image adds direct and indirect" ||
    fail "image of direct and indirect" "$(image_command "$O")"

$R "$SCENE" "$O" $SMALL $FAKE >"$TMP/out2" 2>&1
expect_ran "nothing changed: nothing reruns" "$O" ""
grep -qE '^  simd-gather +cached' "$TMP/out2" && pass "... and the table says cached" || fail "cached" "$(cat "$TMP/out2")"
$R "$SCENE" "$O" $SMALL $FAKE RADIUS=0.02 >/dev/null 2>&1
expect_ran "RADIUS reruns only the gather and composite" "$O" "simd-gather composite"
$R "$SCENE" "$O" $SMALL $FAKE RADIUS=0.02 EXPOSURE=1 >/dev/null 2>&1
expect_ran "EXPOSURE reruns only composite" "$O" "composite"
$R "$SCENE" "$O" PHOTONS=30000 SPP=4 WIDTH=32 HEIGHT=24 $FAKE RADIUS=0.02 EXPOSURE=1 >/dev/null 2>&1
expect_ran "PHOTONS reruns the photon stages, the gather and composite" "$O" \
    "trace-photons build-photonmap simd-gather composite"
$R "$SCENE" "$O" PHOTONS=30000 SPP=8 WIDTH=32 HEIGHT=24 $FAKE RADIUS=0.02 EXPOSURE=1 >/dev/null 2>&1
expect_ran "SPP reruns the eye stages, the gather and composite" "$O" \
    "trace-gather-points hilbert-sort simd-gather composite"
ARGS="PHOTONS=30000 SPP=8 WIDTH=32 HEIGHT=24 $FAKE RADIUS=0.02 EXPOSURE=1"
$R "$SCENE" "$O" $ARGS ORDER=morton >/dev/null 2>&1
expect_ran "ORDER=morton reruns the sort, the gather and composite" "$O" "hilbert-sort simd-gather composite"
touch "$SCENE" "$TMP/scene/cornell-box.obj"
$R "$SCENE" "$O" $ARGS ORDER=morton >/dev/null 2>&1
expect_ran "touching the scene files (same content) reruns nothing" "$O" ""
sed -i 's/"k": 50/"k": 40/' "$SCENE"
$R "$SCENE" "$O" $ARGS ORDER=morton >/dev/null 2>&1
expect_ran "a changed scene file reruns everything" "$O" \
    "trace-photons build-photonmap trace-gather-points hilbert-sort simd-gather composite"
rm "$O/photonmap.pm"
$R "$SCENE" "$O" $ARGS ORDER=morton >/dev/null 2>&1
# (the gather recorded the map's content, which the remade map has again: it is kept)
expect_ran "a deleted intermediate is remade, and nothing after it whose inputs are the same bytes" "$O" "build-photonmap"
cp "$O/stats.json" "$TMP/stats-before.json"
$R "$SCENE" "$O" $ARGS ORDER=morton SHARDS=2 >/dev/null 2>&1
expect_ran "SHARDS=2 runs two gathers and composite" "$O" "simd-gather.0 simd-gather.1 composite"
image_command "$O" | grep -q '^composite direct.pm indirect.0.pm indirect.1.pm ' && pass "... composite adds the shards" ||
    fail "shards in composite" "$(image_command "$O")"

# ---- what the pipeline leaves out ----
$R "$SCENE" "$TMP/dv" $SMALL $FAKE MODE=direct-vis >"$TMP/dv.out" 2>&1
expect_ran "MODE=direct-vis runs no hilbert-sort" "$TMP/dv" "trace-photons build-photonmap trace-gather-points simd-gather composite"
if grep -q 'skipped hilbert-sort: direct-vis' "$TMP/dv.out" && grep -q 'skipped the direct buffer' "$TMP/dv.out" &&
    [ ! -e "$TMP/dv/direct.pm" ] && [ "$("$BUILD/tests/pm-exrdump" "$TMP/dv/image.exr" components)" = indirect ]; then
    pass "... says so, and composites the map's estimate alone (no direct buffer)"
else
    fail "direct-vis notes" "$(cat "$TMP/dv.out")"
fi
$R "$SCENE" "$TMP/dvi" $SMALL $FAKE MODE=direct-vis MAP=indirect >/dev/null 2>&1
"$BIN/pm-info" --header "$TMP/dvi/photonmap.pm" | grep -q -- '--map indirect' && [ -e "$TMP/dvi/direct.pm" ] &&
    pass "direct-vis over an indirect map adds the direct buffer" || fail "direct-vis MAP=indirect" "$(ls "$TMP/dvi")"
# SECONDARY_DIRECT=1: light samples at the gather points, photons without the first hits they
# take (here a point light's)
$R tests/scenes/closed-box/scene.json "$TMP/sd" $SMALL SECONDARY_DIRECT=1 >/dev/null 2>&1
"$BIN/pm-info" --header "$TMP/sd/photons.pm" | grep -q -- '--indirect-only' &&
    "$BIN/pm-info" --header "$TMP/sd/photonmap.pm" | grep -qx 'indirect_only=1' &&
    "$BIN/pm-info" --header "$TMP/sd/queries.pm" | grep -qx 'secondary_direct=1' &&
    "$BIN/pm-info" --header "$TMP/sd/direct.pm" | grep -qx 'secondary_direct=1' && [ -s "$TMP/sd/image.exr" ] &&
    pass "SECONDARY_DIRECT=1: --indirect-only photons and map, queries and direct light with secondary_direct=1" ||
    fail "SECONDARY_DIRECT=1" "$(ls "$TMP/sd")"
# Under a sun and a constant sky, SECONDARY_DIRECT=1 samples the sun at the gather points and
# leaves the sky's first hits to the map (render/light.h, pm_light_at_gather): each path once,
# so the image's mean is trace-reference's (the sky-lit atrium, 48 x 48; the sky's light after
# one bounce is 3.7% of it, which a path counted by neither side would take out; the render's
# mean is within 0.5% of the reference's, measured, and this asks 1.5%). DIFFUSE_DEPTH=1: the
# same with one diffuse bounce before the gather (the sun and the sky sampled at the bounce,
# shared by MIS with the ray that goes on and may escape to them).
"$BIN/trace-reference" scenes/atrium/textured.json --width 48 --height 48 --spp 256 -q -o "$TMP/sky.ref.exr"
# sky_mean NAME FILE LINE [SETTINGS...]: the render's mean within 1.5% of the reference's, and
# the header FILE (photonmap.pm, queries.pm) holds LINE
sky_mean() {
    local name=$1 file=$2 line=$3 m
    shift 3
    $R scenes/atrium/textured.json "$TMP/$name" WIDTH=48 HEIGHT=48 PHOTONS=200000 PRIMARY=4 SPP=4 K=10 \
        SECONDARY_DIRECT=1 COVERAGE=1 "$@" >/dev/null 2>&1
    m=$("$BIN/measure-error" "$TMP/$name/image.exr" "$TMP/sky.ref.exr" -q 2>/dev/null |
        jq -r '"\(.mean_test) \(.mean_reference)"')
    if awk -v m="$m" 'BEGIN { split(m, a, " "); exit !(a[2] > 0 && a[1] / a[2] > 0.985 && a[1] / a[2] < 1.015) }' &&
        "$BIN/pm-info" --header "$TMP/$name/$file" | grep -qx "$line"; then
        pass "SECONDARY_DIRECT=1${*:+ $*} under a sun and a sky: the image's mean is trace-reference's (means $m)"
    else
        fail "SECONDARY_DIRECT=1${*:+ $*} under a sun and a sky" "means $m"
    fi
}
sky_mean sdm photonmap.pm indirect_only=2
sky_mean sdd queries.pm diffuse_depth=1 DIFFUSE_DEPTH=1
expect_exit "DIFFUSE_DEPTH=1 with MODE=direct-vis is refused" 2 $R "$SCENE" "$TMP/ddv" MODE=direct-vis DIFFUSE_DEPTH=1
expect_exit "a DIFFUSE_DEPTH other than 0, 1 or 2 is refused" 2 $R "$SCENE" "$TMP/ddv" DIFFUSE_DEPTH=3
expect_exit "DIFFUSE_DEPTH=1 with GATHER=none is refused (its image is the direct light alone)" 2 \
    $R "$SCENE" "$TMP/ddv" GATHER=none DIFFUSE_DEPTH=1
# SECONDARY_DIRECT=auto: on for a progressive render of a scene with a sun or a sky, off for its
# one render and for a progressive render of a scene lit otherwise (below TIME=10)
$R scenes/atrium/textured.json "$TMP/sda" $SMALL PASSES=2 >/dev/null 2>&1
$R scenes/atrium/textured.json "$TMP/sdf" $SMALL >/dev/null 2>&1
$R tests/scenes/closed-box/scene.json "$TMP/sdc" $SMALL PASSES=2 >/dev/null 2>&1
"$BIN/pm-info" "$TMP/sda/running.pm" | grep -q -- '--indirect-only' &&
    "$BIN/pm-info" "$TMP/sda/running.pm" | grep -q -- '--secondary-direct' &&
    [ -s "$TMP/sdf/photons.pm" ] && ! "$BIN/pm-info" --header "$TMP/sdf/photons.pm" | grep -q -- '--indirect-only' &&
    [ -s "$TMP/sdc/running.pm" ] && ! "$BIN/pm-info" "$TMP/sdc/running.pm" | grep -q -- '--indirect-only' &&
    pass "SECONDARY_DIRECT=auto: on for passes of a sun- and sky-lit scene, off for its one render and for a closed box's passes" ||
    fail "SECONDARY_DIRECT=auto" "$(ls "$TMP/sda" "$TMP/sdf" "$TMP/sdc")"
$R "$SCENE" "$TMP/none" $SMALL GATHER=none >"$TMP/none.out" 2>&1
expect_ran "GATHER=none runs the eye tracer and composite only" "$TMP/none" "trace-gather-points composite"
$R tests/scenes/lit-floor/scene.json "$TMP/lf" WIDTH=8 HEIGHT=8 SPP=4 GATHER=none >"$TMP/lf.out" 2>&1
grep -q 'skipped area-light sampling: no emissive triangles' "$TMP/lf.out" && "$BIN/pm-info" --header "$TMP/lf/direct.pm" | grep -q -- '--light-samples 0' &&
    pass "a scene without emissive triangles gets no area-light sampling" || fail "no area lights" "$(cat "$TMP/lf.out")"
$R tests/scenes/glossy-box/scene.json "$TMP/gb" WIDTH=8 HEIGHT=8 SPP=4 GATHER=none >"$TMP/gb.out" 2>&1
! grep -q 'left out direction channels' "$TMP/gb.out" && pass "a glossy scene keeps its direction channels" ||
    fail "glossy scene" "$(cat "$TMP/gb.out")"

# ---- usage and failures ----
expect_exit "an unknown parameter is a usage error" 2 $R "$SCENE" "$TMP/u" RADIUSS=1
expect_exit "MAP=indirect in gather mode is refused" 2 $R "$SCENE" "$TMP/u" MAP=indirect
expect_exit "MAP=indirect with SECONDARY_DIRECT=1 is refused (the area lights need their first hits)" 2 $R "$SCENE" "$TMP/u" MAP=indirect SECONDARY_DIRECT=1
expect_exit "a SECONDARY_DIRECT other than auto, 0 or 1 is refused" 2 $R "$SCENE" "$TMP/u" SECONDARY_DIRECT=yes
# a gather that writes part of its output and fails (SPP=5, which once failed trace-gather-points
# here, is now refused before any stage runs: cache.sh)
printf '#!/bin/sh\nwhile [ "$1" != -o ]; do shift; done\necho partial >"$2"\nexit 1\n' >"$TMP/fail-gather"
chmod +x "$TMP/fail-gather"
$R "$SCENE" "$TMP/f" $SMALL GATHER="$TMP/fail-gather" >"$TMP/f.out" 2>&1
status=$?
if [ $status = 1 ] && grep -q 'render: stage simd-gather failed' "$TMP/f.out" && [ ! -e "$TMP/f/indirect.pm" ]; then
    pass "a failing stage stops the render, named, with no output left"
else
    fail "failing stage" "exit $status: $(cat "$TMP/f.out")"
fi
$R "$SCENE" "$TMP/t" $SMALL photonmap.pm sorted.pm direct.pm >/dev/null 2>&1
expect_ran "targets build only what they need" "$TMP/t" "trace-photons build-photonmap trace-gather-points hilbert-sort"
expect_error "a gather program that is not there is a failure, named" "gather program '$TMP/no-such-gather' is not an executable" \
    $R "$SCENE" "$TMP/t" $SMALL GATHER="$TMP/no-such-gather"
# Every program is built; one missing is a failure of every pipeline, never a skip.
mkdir -p "$TMP/bin-partial"
ln -s "$BIN"/* "$TMP/bin-partial/" && rm "$TMP/bin-partial/hilbert-sort"
expect_error "a missing stage program is a failure, named" "bin-partial/hilbert-sort' is not built" \
    env BIN="$TMP/bin-partial" $R "$SCENE" "$TMP/t" $SMALL

# ---- with the real simd-gather ----
G=$TMP/real
$R "$CORNELL" "$G" $SMALL >"$TMP/real.out" 2>&1 && [ -s "$G/image.exr" ] &&
    [ "$("$BUILD/tests/pm-exrdump" "$G/image.exr" components)" = total ] && pass "the full render with simd-gather" ||
    fail "render with simd-gather" "$(tail -5 "$TMP/real.out")"
$R "$CORNELL" "$G" $SMALL RADIUS=0.03 >/dev/null 2>&1
expect_ran "simd-gather: RADIUS reruns only simd-gather and composite" "$G" "simd-gather composite"
$R "$CORNELL" "$G" $SMALL RADIUS=0.03 >/dev/null 2>&1
expect_ran "simd-gather: nothing changed, nothing reruns" "$G" ""
$R "$CORNELL" "$G" $SMALL RADIUS=0.03 SHARDS=3 >/dev/null 2>&1
cp "$G/image.exr" "$TMP/sharded.exr"
$R "$CORNELL" "$G" $SMALL RADIUS=0.03 SHARDS=1 >/dev/null 2>&1
if paste -d' ' <("$BUILD/tests/pm-exrdump" "$TMP/sharded.exr") <("$BUILD/tests/pm-exrdump" "$G/image.exr") | awk 'NR > 1 {
        for (c = 3; c <= 5; c++) { a = $c; b = $(c + 5); d = a - b; if (d < 0) d = -d; if (d > 1e-5 * (a + b) + 1e-12) bad = 1 } }
    END { exit bad }'; then
    pass "simd-gather: three shards composite to the image of one gather"
else
    fail "shards add up" "images differ"
fi

# ---- pipelines/frames: a camera path, every stage per frame ----
pipelines/frames "$CORNELL" "$TMP/fr" FRAMES=3 PHOTONS=5000 SPP=4 WIDTH=24 HEIGHT=16 >"$TMP/fr.out" 2>&1
status=$?
if [ $status = 0 ] && [ -s "$TMP/fr/frame-0002.exr" ] && [ -s "$TMP/fr/frame-0000.png" ] &&
    jq -e '.frames == 3 and .fps > 0 and (.per_frame | length) == 3' "$TMP/fr/frames.json" >/dev/null &&
    grep -qE '^frames: 3 frames in [0-9.]+ s: [0-9.]+ frames per second' "$TMP/fr.out"; then
    pass "frames renders 3 frames and reports frames per second"
else
    fail "frames" "exit $status: $(tail -5 "$TMP/fr.out")"
fi
eye() { jq -c .camera.eye "$1"; }
if [ "$(eye "$TMP/fr/scene-0000.json")" != "$(eye "$TMP/fr/scene-0002.json")" ] &&
    [ "$(jq -c .camera.eye "$TMP/fr/scene-0001.json")" = "$(jq -c .camera.eye "$CORNELL")" ] &&
    ! cmp -s <("$BUILD/tests/pm-exrdump" "$TMP/fr/frame-0000.exr") <("$BUILD/tests/pm-exrdump" "$TMP/fr/frame-0002.exr"); then
    pass "... the eye moves along the path (the middle frame is the scene's own camera) and the frames differ"
else
    fail "frames camera path" "$(eye "$TMP/fr/scene-0000.json") $(eye "$TMP/fr/scene-0001.json") $(eye "$TMP/fr/scene-0002.json")"
fi
expect_exit "frames MOVE=light needs point lights" 1 pipelines/frames "$CORNELL" "$TMP/fl" MOVE=light FRAMES=1
expect_exit "frames MODE=bad is a usage error" 2 pipelines/frames "$CORNELL" "$TMP/fm" MODE=bad FRAMES=1
pipelines/frames "$CORNELL" "$TMP/fdv" MODE=direct-vis ORDER=none FRAMES=1 PHOTONS=20000 WIDTH=32 HEIGHT=32 \
    >"$TMP/fdv.out" 2>&1 && [ -s "$TMP/fdv/frame-0000.exr" ] &&
    pass "frames MODE=direct-vis renders the map's estimate at the primary hits" ||
    fail "frames direct-vis" "$(tail -3 "$TMP/fdv.out")"
expect_error "frames: a missing stage program is a failure, named" "bin-partial/hilbert-sort' is not built" \
    env BIN="$TMP/bin-partial" pipelines/frames "$CORNELL" "$TMP/fp" FRAMES=1

# ---- the documented examples run ----
pipelines/examples.sh "$TMP/ex" >"$TMP/ex.out" 2>&1 && [ -s "$TMP/ex/direct.exr" ] && [ -s "$TMP/ex/map.pm" ] &&
    [ -s "$TMP/ex/image.exr" ] && [ -s "$TMP/ex/direct-vis.exr" ] && [ -s "$TMP/ex/sharded.exr" ] &&
    grep -q '^trace-gather-points ' "$TMP/ex.out" &&
    pass "pipelines/examples.sh runs every example" || fail "examples.sh" "$(tail -5 "$TMP/ex.out")"
if env BIN="$TMP/bin-partial" pipelines/examples.sh "$TMP/exp" >"$TMP/exp.out" 2>&1; then
    fail "examples.sh without hilbert-sort" "exit 0: $(tail -3 "$TMP/exp.out")"
else
    grep -q 'hilbert-sort: command not found' "$TMP/exp.out" && pass "examples.sh: a missing program stops it with a failure" ||
        fail "examples.sh without hilbert-sort" "$(tail -3 "$TMP/exp.out")"
fi

# ---- KEEP: after a render that succeeded, OUTDIR holds what was asked for and nothing else
# render made; the image is the one KEEP=all makes; a file of the user's in OUTDIR stays
keep_ls() { (cd "$1" && find . -mindepth 1 ! -name .lock | sed 's|^\./||' | sort | tr '\n' ' ' | sed 's/ $//'); }
"$R" "$CORNELL" "$TMP/ka" $SMALL >/dev/null 2>&1 && "$R" "$CORNELL" "$TMP/kpa" $SMALL PASSES=2 >/dev/null 2>&1 ||
    fail "KEEP=all renders" "a render failed"
for k in image buffers; do
    mkdir -p "$TMP/k$k" "$TMP/kp$k" && echo mine >"$TMP/k$k/notes.txt" && echo mine >"$TMP/kp$k/notes.txt"
    "$R" "$CORNELL" "$TMP/k$k" $SMALL KEEP=$k >"$TMP/k$k.out" 2>&1 || fail "KEEP=$k" "$(tail -2 "$TMP/k$k.out")"
    "$R" "$CORNELL" "$TMP/kp$k" $SMALL PASSES=2 KEEP=$k >"$TMP/kp$k.out" 2>&1 || fail "KEEP=$k PASSES=2" "$(tail -2 "$TMP/kp$k.out")"
done
want_s="image.exr image.png notes.txt stats.json"
want_b="direct.pm image.exr image.png indirect.pm notes.txt stats.json"
# (progressive passes are resident, no pass directories: KEEP=buffers keeps the running image
# and its list, which composite re-tones)
want_pb="image.exr image.png notes.txt passes.txt running.pm stats.json"
if [ "$(keep_ls "$TMP/kimage")" = "$want_s" ] && [ "$(keep_ls "$TMP/kpimage")" = "$want_s" ] &&
    [ "$(keep_ls "$TMP/kbuffers")" = "$want_b" ] && [ "$(keep_ls "$TMP/kpbuffers")" = "$want_pb" ]; then
    pass "KEEP=image and KEEP=buffers keep exactly their files (single render and passes), and the user's"
else
    fail "KEEP contents" "image '$(keep_ls "$TMP/kimage")' / '$(keep_ls "$TMP/kpimage")'; buffers '$(keep_ls "$TMP/kbuffers")' / '$(keep_ls "$TMP/kpbuffers")'"
fi
bad=""
for d in kimage kbuffers; do cmp -s "$TMP/$d/image.exr" "$TMP/ka/image.exr" || bad+=" $d"; done
for d in kpimage kpbuffers; do cmp -s "$TMP/$d/image.exr" "$TMP/kpa/image.exr" || bad+=" $d"; done
cmp -s "$TMP/kpbuffers/running.pm" "$TMP/kpa/running.pm" && cmp -s "$TMP/kbuffers/indirect.pm" "$TMP/ka/indirect.pm" || bad+=" buffers"
[ -z "$bad" ] && pass "KEEP: the images (and kept buffers) are KEEP=all's, byte for byte" || fail "KEEP images" "differ:$bad"
"$R" "$CORNELL" "$TMP/kimage" $SMALL >"$TMP/kr.out" 2>&1 && [ -s "$TMP/kimage/photonmap.pm" ] &&
    cmp -s "$TMP/kimage/image.exr" "$TMP/ka/image.exr" && pass "after KEEP=image, a render with KEEP=all makes it all again" ||
    fail "rerun after KEEP=image" "$(tail -2 "$TMP/kr.out")"
expect_exit "KEEP=everything is refused" 2 "$R" "$CORNELL" "$TMP/kx" KEEP=everything
expect_exit "KEEP=image with a TARGET is refused" 2 "$R" "$CORNELL" "$TMP/kx" KEEP=image photonmap.pm
