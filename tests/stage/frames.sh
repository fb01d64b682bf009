# frames.sh: resident stages on streams of documents (issue 21, point 2). pipelines/frames with
# STREAM=1 (one pipeline of resident stages) gives the frames, byte for byte in their pixels and
# PNGs, of the per-frame path (STREAM=0), for camera moves, light moves and direct
# visualization, and for one thread as for two; the kernel width measured on frame 0 is kept by
# both. A stream holding a truncated or corrupt document, or a document of another scene, stops
# the stage with one line naming the frame and exit 1, and the frame is not written.
# programs: build-photonmap composite hilbert-sort simd-gather trace-gather-points trace-photons pm-render pm-frames
F="FRAMES=3 PHOTONS=20000 SPP=4 WIDTH=32 HEIGHT=24"
CB=scenes/cornell-box/scene.json
dump() { "$BUILD/tests/pm-exrdump" "$1"; }
# same_frames NAME DIR1 DIR2 N: frames 0 .. N-1 have the same pixels and the same PNG bytes.
same_frames() {
    local f bad=""
    for ((f = 0; f < $4; f++)); do
        local t
        t=$(printf 'frame-%04d' $f)
        if [ ! -s "$2/$t.exr" ] || ! cmp -s <(dump "$2/$t.exr") <(dump "$3/$t.exr") || ! cmp -s "$2/$t.png" "$3/$t.png"; then
            bad+=" $f"
        fi
    done
    if [ -z "$bad" ]; then pass "$1"; else fail "$1" "frames differ or are missing:$bad"; fi
}
run_frames() { # run_frames OUTDIR SCENE ARGS...: quiet unless it fails
    local out=$1
    shift
    pipelines/frames "$1" "$out" "${@:2}" >"$out.log" 2>&1 || { echo "pipelines/frames failed: $(tail -3 "$out.log")"; return 1; }
}

# ---- camera moves: the map of frame 0, queries streamed ----
run_frames "$TMP/c1" $CB $F && run_frames "$TMP/c0" $CB $F STREAM=0 && run_frames "$TMP/c1t1" $CB $F THREADS=1
if jq -e '.stream == true and ([.per_frame[].map_reused] == [false, true, true]) and .stages["simd-gather"].frames == 3' \
    "$TMP/c1/frames.json" >/dev/null && jq -e '.stream == false' "$TMP/c0/frames.json" >/dev/null; then
    pass "frames STREAM=1 runs one pipeline of resident stages (simd-gather gathered 3 frames)"
else
    fail "frames stream" "$(head -c 300 "$TMP/c1/frames.json")"
fi
same_frames "... camera moves: the streamed frames are the per-frame path's" "$TMP/c1" "$TMP/c0" 3
same_frames "... and the same on one thread" "$TMP/c1" "$TMP/c1t1" 3
cmp -s <(dump "$TMP/c1/frame-0000.exr") <(dump "$TMP/c1/frame-0002.exr") &&
    fail "frames stream" "frames 0 and 2 are the same: the camera did not move" ||
    pass "... and the frames differ"

# ---- direct visualization: the primary hits are the queries, no direct buffer ----
run_frames "$TMP/v1" $CB $F MODE=direct-vis ORDER=none && run_frames "$TMP/v0" $CB $F MODE=direct-vis ORDER=none STREAM=0
same_frames "direct visualization: the streamed frames are the per-frame path's" "$TMP/v1" "$TMP/v0" 3

# ---- light moves: the queries of the still camera, photons and maps streamed ----
D=$TMP/scene
mkdir -p "$D"
cp scenes/cornell-box/cornell-box.obj scenes/cornell-box/cornell-box.mtl "$D"/
jq '.point_lights = [{"position": [0.278, 0.5, 0.28], "intensity": [0.3, 0.3, 0.3]}]' $CB >"$D/scene.json"
run_frames "$TMP/l1" "$D/scene.json" $F MOVE=light && run_frames "$TMP/l0" "$D/scene.json" $F MOVE=light STREAM=0 &&
    run_frames "$TMP/l1t1" "$D/scene.json" $F MOVE=light THREADS=1
if jq -e '.stages["build-photonmap"].frames == 3 and .stages["simd-gather"].stream == "map"' "$TMP/l1/frames.json" >/dev/null; then
    pass "frames MOVE=light streams a map per frame against the kept queries"
else
    fail "frames light stream" "$(head -c 300 "$TMP/l1/frames.json")"
fi
same_frames "... light moves: the streamed frames are the per-frame path's" "$TMP/l1" "$TMP/l0" 3
same_frames "... and the same on one thread" "$TMP/l1" "$TMP/l1t1" 3
cmp -s <(dump "$TMP/l1/frame-0000.exr") <(dump "$TMP/l1/frame-0002.exr") &&
    fail "frames light" "frames 0 and 2 are the same: the light did not move" || pass "... and the frames differ"

# ---- SECONDARY_DIRECT=1: light samples at the gather points, a map without their first hits;
# DIFFUSE_DEPTH=1: a bounce before the gather ----
run_frames "$TMP/sd1" $CB $F SECONDARY_DIRECT=1 && run_frames "$TMP/sd0" $CB $F SECONDARY_DIRECT=1 STREAM=0 &&
    run_frames "$TMP/sdl" "$D/scene.json" $F MOVE=light SECONDARY_DIRECT=1 &&
    run_frames "$TMP/sdl0" "$D/scene.json" $F MOVE=light SECONDARY_DIRECT=1 STREAM=0
if jq -e '.secondary_direct == true and .stages["trace-gather-points"].secondary_direct == 1' "$TMP/sd1/frames.json" \
    >/dev/null && jq -e '.secondary_direct == false' "$TMP/c1/frames.json" >/dev/null &&
    ! cmp -s <(dump "$TMP/sd1/frame-0001.exr") <(dump "$TMP/c1/frame-0001.exr"); then
    pass "frames SECONDARY_DIRECT=1: the gather points sample the lights (frames.json and the tracer's stats say so)"
else
    fail "frames secondary direct" "$(jq -c '{secondary_direct}' "$TMP/sd1/frames.json" 2>&1 | head -c 200)"
fi
same_frames "... camera moves: the streamed frames are the per-frame path's" "$TMP/sd1" "$TMP/sd0" 3
same_frames "... light moves: the streamed frames are the per-frame path's" "$TMP/sdl" "$TMP/sdl0" 3
# The same image either way (the map's first hits or the gather points' light samples): within
# the noise of 200,000 photons and 16 secondary rays at 32 x 24 the two frames' means agree to
# 3% (measured: 0.25%).
run_frames "$TMP/sm1" $CB FRAMES=1 PHOTONS=200000 SPP=16 WIDTH=32 HEIGHT=24 SECONDARY_DIRECT=1 &&
    run_frames "$TMP/sm0" $CB FRAMES=1 PHOTONS=200000 SPP=16 WIDTH=32 HEIGHT=24
means=$("$BIN/measure-error" "$TMP/sm1/frame-0000.exr" "$TMP/sm0/frame-0000.exr" | jq -r '"\(.mean_test) \(.mean_reference)"')
if awk -v m="$means" 'BEGIN { split(m, a, " "); r = a[1] / a[2]; exit !(r > 0.97 && r < 1.03) }'; then
    pass "... and its frame's mean is the plain frame's within 3% ($means)"
else
    fail "frames secondary direct mean" "means $means"
fi
# DIFFUSE_DEPTH=1: a Lambertian bounce before the gather, on every frame
run_frames "$TMP/dd1" $CB $F DIFFUSE_DEPTH=1 && run_frames "$TMP/dd0" $CB $F DIFFUSE_DEPTH=1 STREAM=0
if jq -e '.diffuse_depth == 1' "$TMP/dd1/frames.json" >/dev/null &&
    ! cmp -s <(dump "$TMP/dd1/frame-0001.exr") <(dump "$TMP/c1/frame-0001.exr"); then
    pass "frames DIFFUSE_DEPTH=1: the secondary paths bounce before they gather (frames.json says so, the frames change)"
else
    fail "frames diffuse depth" "$(jq -c '{diffuse_depth}' "$TMP/dd1/frames.json" 2>&1 | head -c 200)"
fi
same_frames "... the streamed frames are the per-frame path's" "$TMP/dd1" "$TMP/dd0" 3
run_frames "$TMP/dm1" $CB FRAMES=1 PHOTONS=200000 SPP=16 WIDTH=32 HEIGHT=24 DIFFUSE_DEPTH=1
means=$("$BIN/measure-error" "$TMP/dm1/frame-0000.exr" "$TMP/sm0/frame-0000.exr" | jq -r '"\(.mean_test) \(.mean_reference)"')
if awk -v m="$means" 'BEGIN { split(m, a, " "); r = a[1] / a[2]; exit !(r > 0.97 && r < 1.03) }'; then
    pass "... and its frame's mean is the plain frame's within 3% ($means)"
else
    fail "frames diffuse depth mean" "means $means"
fi
expect_exit "frames DIFFUSE_DEPTH=3 is bad usage" 2 pipelines/frames $CB "$TMP/sdv" DIFFUSE_DEPTH=3
expect_exit "frames DIFFUSE_DEPTH=1 MODE=direct-vis is bad usage" 2 \
    pipelines/frames $CB "$TMP/sdv" DIFFUSE_DEPTH=1 MODE=direct-vis
expect_exit "frames SECONDARY_DIRECT=1 MODE=direct-vis is bad usage" 2 \
    pipelines/frames $CB "$TMP/sdv" SECONDARY_DIRECT=1 MODE=direct-vis
expect_exit "frames SECONDARY_DIRECT=2 is bad usage" 2 pipelines/frames $CB "$TMP/sdv" SECONDARY_DIRECT=2

# ---- the stages on streams, and bad documents inside them ----
S=$TMP/s
mkdir -p "$S"
for f in 0 2; do
    cp "$TMP/c1/scene-000$f.json" "$S/scene-$f.json"
    "$BIN/trace-gather-points" -q "$S/scene-$f.json" --spp 4 --width 32 --height 24 -o "$S/q$f.pm" --direct "$S/d$f.pm"
done
"$BIN/trace-photons" -q "$S/scene-0.json" --photons 20000 -o "$S/ph.pm"
"$BIN/build-photonmap" -q "$S/ph.pm" -o "$S/map.pm"
cat "$S/q0.pm" "$S/q2.pm" >"$S/qs.pm"
# Each streamed document is the one a run on its own file gives (provenance aside).
"$BIN/hilbert-sort" -q --stream "$S/qs.pm" -o - >"$S/sorted-s.pm"
"$BIN/simd-gather" -q --stream queries --radius 0.02 "$S/map.pm" "$S/sorted-s.pm" -o - >"$S/ind-s.pm"
"$BIN/hilbert-sort" -q "$S/q2.pm" -o "$S/sorted2.pm"
"$BIN/simd-gather" -q --radius 0.02 "$S/map.pm" "$S/sorted2.pm" -o "$S/ind2.pm"
# The second document is the stream's tail: its records (32 x 24 pixels of 3 doubles) before
# its checksum are the single run's.
pay=$((32 * 24 * 24))
if cmp -s <(tail -c $((pay + 8)) "$S/ind-s.pm" | head -c $pay) <(tail -c $((pay + 8)) "$S/ind2.pm" | head -c $pay); then
    pass "hilbert-sort --stream and simd-gather --stream: frame 1's buffer is the one of its own files"
else
    fail "stage streams" "the second streamed radiance document differs from the single run's"
fi

corrupt() { # corrupt IN OUT: one payload byte flipped, 200 bytes before the checksum
    cp "$1" "$2"
    local at=$(($(stat -c %s "$1") - 200)) b
    b=$(od -An -tu1 -j $at -N1 "$1" | tr -d ' ')
    printf "$(printf '\\%03o' $(((b + 1) % 256)))" | dd of="$2" bs=1 seek=$at conv=notrunc status=none
}
head -c $(($(stat -c %s "$S/q2.pm") / 2)) "$S/q2.pm" >"$S/q2-half.pm"
corrupt "$S/q2.pm" "$S/q2-bad.pm"
cat "$S/q0.pm" "$S/q2-half.pm" >"$S/qs-trunc.pm"
cat "$S/q0.pm" "$S/q2-bad.pm" >"$S/qs-bad.pm"
expect_error "hilbert-sort --stream: a truncated document is an error naming the frame" \
    "^hilbert-sort: truncated queries '.*qs-trunc.pm, frame 1'" "$BIN/hilbert-sort" -q --stream "$S/qs-trunc.pm" -o -
expect_error "simd-gather --stream: a corrupt document is an error naming the frame" \
    "^simd-gather: checksum mismatch in queries 'stdin, frame 1'" \
    sh -c "\"$BIN/simd-gather\" -q --stream queries --radius 0.02 \"$S/map.pm\" - -o - <\"$S/qs-bad.pm\" >/dev/null"
# Another scene's queries in the stream: the map's scene is checked against every document.
"$BIN/trace-gather-points" -q tests/scenes/closed-box/scene.json --spp 4 --width 8 --height 8 -o "$S/qx.pm"
cat "$S/q0.pm" "$S/qx.pm" >"$S/qs-other.pm"
expect_error "simd-gather --stream: a document of another scene is an error naming the frame" \
    "^simd-gather: photon map '.*map.pm' is of scene .* but queries '.*qs-other.pm, frame 1' are of scene" \
    "$BIN/simd-gather" -q --stream queries --radius 0.02 "$S/map.pm" "$S/qs-other.pm" -o -
cat "$S/ph.pm" "$S/ph.pm" | head -c $(($(stat -c %s "$S/ph.pm") * 3 / 2)) >"$S/phs-trunc.pm"
expect_error "build-photonmap --stream: a truncated document is an error naming the frame" \
    "^build-photonmap: truncated photons file '.*phs-trunc.pm, frame 1'" \
    "$BIN/build-photonmap" -q --stream "$S/phs-trunc.pm" -o -
: >"$S/empty.pm"
expect_error "simd-gather --stream: an empty stream is an error" "empty stream" \
    "$BIN/simd-gather" -q --stream queries --radius 0.02 "$S/map.pm" "$S/empty.pm" -o -

# composite --stream: frame 0 is written, the corrupt frame 1 is not, and nothing of it is left.
"$BIN/simd-gather" -q --radius 0.02 "$S/map.pm" "$S/q0.pm" -o "$S/i0.pm"
"$BIN/simd-gather" -q --radius 0.02 "$S/map.pm" "$S/q2.pm" -o "$S/i2.pm"
corrupt "$S/i2.pm" "$S/i2-bad.pm"
cat "$S/d0.pm" "$S/d2.pm" >"$S/ds.pm"
cat "$S/i0.pm" "$S/i2-bad.pm" >"$S/is-bad.pm"
mkdir -p "$S/out"
expect_error "composite --stream: a corrupt document is an error naming the frame" \
    "^composite: checksum mismatch in radiance buffer '.*is-bad.pm, frame 1'" \
    "$BIN/composite" -q --stream "$S/ds.pm" "$S/is-bad.pm" -o "$S/out/f-%04d.exr" --png "$S/out/f-%04d.png"
if [ -s "$S/out/f-0000.exr" ] && [ -s "$S/out/f-0000.png" ] && [ "$(ls -A "$S/out" | wc -l)" = 2 ]; then
    pass "... frame 0 is written whole, and nothing of frame 1"
else
    fail "composite stream partial" "$(ls -A "$S/out" | tr '\n' ' ')"
fi
"$BIN/composite" -q --stream "$S/ds.pm" <(cat "$S/i0.pm" "$S/i2.pm") -o "$S/out/g-%04d.exr"
"$BIN/composite" -q "$S/d2.pm" "$S/i2.pm" -o "$S/out/h.exr"
cmp -s <(dump "$S/out/g-0001.exr") <(dump "$S/out/h.exr") &&
    pass "composite --stream: frame 1 is the image of its own two buffers" ||
    fail "composite stream" "frame 1 differs from composite of d2.pm i2.pm"
expect_error "composite --stream: a stream that ends before the others is an error" "has ended at frame 1" \
    "$BIN/composite" -q --stream "$S/ds.pm" "$S/i0.pm" -o "$S/out/e-%04d.exr"
expect_exit "composite --stream: -o without %d is bad usage" 2 \
    "$BIN/composite" -q --stream "$S/ds.pm" "$S/ds.pm" -o "$S/out/plain.exr"
expect_exit "trace-gather-points: several scenes into a regular file is bad usage" 2 \
    "$BIN/trace-gather-points" -q "$S/scene-0.json" "$S/scene-2.json" -o "$S/two.pm"
expect_exit "simd-gather --stream to a file is bad usage (a stream goes to stdout)" 2 \
    "$BIN/simd-gather" -q --stream queries --radius 0.02 "$S/map.pm" "$S/qs.pm" -o "$S/x.pm"
expect_exit "frames STREAM=2 is bad usage" 2 pipelines/frames $CB "$TMP/bad" STREAM=2
# A failing stage inside the pipeline: the script fails and says so.
mkdir -p "$TMP/bin-bad"
for p in "$BIN"/*; do ln -s "$p" "$TMP/bin-bad/"; done
rm "$TMP/bin-bad/hilbert-sort"
printf '#!/bin/sh\necho "hilbert-sort: injected failure" >&2\nexit 1\n' >"$TMP/bin-bad/hilbert-sort"
chmod +x "$TMP/bin-bad/hilbert-sort"
BIN="$TMP/bin-bad" pipelines/frames $CB "$TMP/fb" $F >"$TMP/fb.out" 2>&1
status=$?
if [ $status = 1 ] && grep -q 'injected failure' "$TMP/fb.out" && grep -q 'frame pipeline failed' "$TMP/fb.out" &&
    [ ! -e "$TMP/fb/frame-0000.exr" ] && [ ! -e "$TMP/fb/direct.fifo" ]; then
    pass "frames: a stage failing inside the pipeline fails the run, no frame written"
else
    fail "frames failing stage" "exit $status: $(tail -3 "$TMP/fb.out")"
fi
# composite dying before it opens the direct FIFO (whose writer waits in open() for a reader):
# the run still ends, with exit 1. timeout bounds the wait (124 is a hang), it times nothing.
for move in camera light; do
    mkdir -p "$TMP/bin-nocomp"
    for p in "$BIN"/*; do ln -sf "$p" "$TMP/bin-nocomp/"; done
    rm "$TMP/bin-nocomp/composite"
    printf '#!/bin/sh\necho "composite: injected death" >&2\nkill -9 $$\n' >"$TMP/bin-nocomp/composite"
    chmod +x "$TMP/bin-nocomp/composite"
    scene=$CB
    [ $move = light ] && scene=$D/scene.json
    BIN="$TMP/bin-nocomp" timeout 120 pipelines/frames $scene "$TMP/fc" $F MOVE=$move >"$TMP/fc.out" 2>&1
    status=$?
    if [ $status = 1 ] && grep -q 'frame pipeline failed' "$TMP/fc.out" && [ ! -e "$TMP/fc/direct.fifo" ]; then
        pass "frames MOVE=$move: composite dying before it opens the direct FIFO ends the run with exit 1"
    else
        fail "frames MOVE=$move composite dies early" "exit $status (124: it hung): $(tail -3 "$TMP/fc.out")"
    fi
    rm -rf "$TMP/fc"
done

# ---- issue 28, item 7: settings that are not finite numbers, and two runs into one OUTDIR ----
for v in DEGREES=nan DEGREES=inf DEGREES=-inf DEGREES=1e400 DEGREES=abc SHIFT=nan SHIFT=1e999; do
    rm -rf "$TMP/fn"
    pipelines/frames $CB "$TMP/fn" $F "$v" >"$TMP/fn.out" 2>"$TMP/fn.err"
    status=$?
    if [ $status = 2 ] && [ "$(wc -l <"$TMP/fn.err")" = 1 ] && grep -q "^frames: bad value for ${v%%=*} '${v#*=}'" "$TMP/fn.err" &&
        [ ! -e "$TMP/fn" ]; then
        pass "frames $v: refused, exit 2, one line naming the value, no OUTDIR"
    else
        fail "frames $v" "exit $status: $(head -c 300 "$TMP/fn.err")"
    fi
done
# the first run holds OUTDIR (its lock names it); a second into the same OUTDIR is refused at
# once, one line, exit 1, and the first ends with every frame whole
pipelines/frames $CB "$TMP/fl" FRAMES=12 PHOTONS=200000 SPP=4 WIDTH=64 HEIGHT=48 >"$TMP/fl1.out" 2>&1 &
first=$!
for _ in $(seq 200); do grep -q '^pid ' "$TMP/fl/.lock" 2>/dev/null && break; sleep 0.05; done
pipelines/frames $CB "$TMP/fl" $F >"$TMP/fl2.out" 2>"$TMP/fl2.err"
status=$?
wait $first
status1=$?
if [ $status = 1 ] && [ "$(wc -l <"$TMP/fl2.err")" = 1 ] && grep -q "is in use by another render (pid $first: " "$TMP/fl2.err" &&
    [ $status1 = 0 ] && [ "$(ls "$TMP/fl"/frame-*.exr | wc -l)" = 12 ] && [ "$(ls "$TMP/fl"/frame-*.png | wc -l)" = 12 ]; then
    pass "frames: a second run into a held OUTDIR is refused (exit 1, one line naming the holder); the first ends whole"
else
    fail "frames: two runs into one OUTDIR" "second exit $status: $(head -c 300 "$TMP/fl2.err"); first exit $status1: $(tail -2 "$TMP/fl1.out")"
fi
