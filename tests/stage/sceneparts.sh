# sceneparts.sh: the scene hash in parts (issue 21, point 1). A camera move or a new image size
# keeps the photon map (no photon stage runs); a point light's move retraces the photons and
# regathers, and trace-gather-points reruns for the direct light but leaves the queries as
# they were, so hilbert-sort does not run; scene-info reports each part; the gather takes a
# map and queries of the same scene whose keys name different parts, and refuses another
# scene's.
# programs: scene-info simd-gather trace-reference pm-render trace-photons build-photonmap trace-gather-points composite
R=pipelines/render
TINY="PHOTONS=5000 SPP=4"
sorted() { tr ' ' '\n' | grep -v '^$' | sort | tr '\n' ' ' | sed 's/ $//'; }
expect_ran() { # expect_ran NAME OUTDIR "STAGES": exactly these stages ran in the last render
    local got want
    got=$(sorted <"$2/ran.txt") want=$(echo "$3" | sorted)
    if [ "$got" = "$want" ]; then pass "$1"; else fail "$1" "ran '$got', expected '$want'"; fi
}
# A Cornell box lit by one point light under its ceiling, camera and light placed by jq.
D=$TMP/scene
mkdir -p "$D"
cp scenes/cornell-box/cornell-box.obj scenes/cornell-box/*.mtl "$D"/ 2>/dev/null
base() { # base EYE_X LIGHT_Y WIDTH
    jq --argjson ex "$1" --argjson ly "$2" --argjson w "$3" '.camera.eye[0] = $ex | .camera.width = $w |
        .camera.height = 12 | .point_lights = [{"position": [0.278, $ly, 0.279], "intensity": [0.5, 0.5, 0.5]}]' \
        scenes/cornell-box/scene.json >"$D/scene.json"
}
part() { "$BIN/scene-info" -q --json "$D/scene.json" | jq -r ".hashes.$1"; }

base 0.278 0.5 16
O=$TMP/o
$R "$D/scene.json" "$O" $TINY >"$TMP/r.out" 2>&1 || fail "first render" "$(tail -n 3 "$TMP/r.out")"
g0=$(part geometry) p0=$(part photons) v0=$(part view) e0=$(part eye) a0=$(part all)
$R "$D/scene.json" "$O" $TINY >"$TMP/r.out" 2>&1
expect_ran "nothing changed: nothing runs" "$O" ""

# The camera moves: the photon part stays, so no photon stage runs.
base 0.25 0.5 16
$R "$D/scene.json" "$O" $TINY >"$TMP/r.out" 2>&1 || fail "camera-moved render" "$(tail -n 3 "$TMP/r.out")"
expect_ran "a camera move reruns no photon stage" "$O" "trace-gather-points hilbert-sort simd-gather composite"
if [ "$(part photons)" = "$p0" ] && [ "$(part geometry)" = "$g0" ] && [ "$(part view)" != "$v0" ] &&
    [ "$(part eye)" != "$e0" ] && [ "$(part all)" != "$a0" ]; then
    pass "scene-info: a camera move changes the view, eye and whole hashes, not the photons' or the geometry's"
else
    fail "scene-info parts after a camera move" "$(part geometry) $(part photons) $(part view) vs $g0 $p0 $v0"
fi
# A new image size (the scene's camera size, then WIDTH=): the map stays again.
base 0.25 0.5 20
$R "$D/scene.json" "$O" $TINY >"$TMP/r.out" 2>&1
expect_ran "a new image size in the scene reruns no photon stage" "$O" "trace-gather-points hilbert-sort simd-gather composite"
$R "$D/scene.json" "$O" $TINY WIDTH=24 >"$TMP/r.out" 2>&1
expect_ran "WIDTH= reruns no photon stage" "$O" "trace-gather-points hilbert-sort simd-gather composite"
v1=$(part view) p1=$(part photons)

# The light moves: photons, map, the direct light and the gather run; the queries are the
# same bytes, so hilbert-sort does not.
sortsum=$(sha1sum <"$O/sorted.pm")
base 0.25 0.45 20
$R "$D/scene.json" "$O" $TINY WIDTH=24 >"$TMP/r.out" 2>&1 || fail "light-moved render" "$(tail -n 3 "$TMP/r.out")"
expect_ran "a light move keeps the queries: hilbert-sort does not run" "$O" \
    "trace-photons build-photonmap trace-gather-points simd-gather composite"
[ "$(sha1sum <"$O/sorted.pm")" = "$sortsum" ] && pass "the sorted queries are the same file after a light move" ||
    fail "sorted queries after a light move" "changed"
if [ "$(part view)" = "$v1" ] && [ "$(part photons)" != "$p1" ]; then
    pass "scene-info: a light move changes the photons' part, not the view's"
else
    fail "scene-info parts after a light move" "view $(part view) vs $v1, photons $(part photons) vs $p1"
fi
$R "$D/scene.json" "$O" $TINY WIDTH=24 >"$TMP/r.out" 2>&1
expect_ran "after a light move, a rerun runs nothing" "$O" ""
# The image is not the one before the move: the direct light was recomputed.
cp "$O/direct.pm" "$TMP/direct-after.pm"
base 0.25 0.5 20
$R "$D/scene.json" "$O" $TINY WIDTH=24 >"$TMP/r.out" 2>&1
if cmp -s "$O/direct.pm" "$TMP/direct-after.pm"; then
    fail "the direct light follows the light" "direct.pm is the same for two light positions"
else
    pass "the direct light follows the light"
fi

# The files name their parts; the gather's output and the direct light name both.
sc() { "$BIN/pm-info" --header --json "$1" | jq -r .keys.SCENE; }
s_map=$(sc "$O/photonmap.pm") s_q=$(sc "$O/sorted.pm") s_ind=$(sc "$O/indirect.pm") s_dir=$(sc "$O/direct.pm")
all=$("$BIN/scene-info" -q --json "$D/scene.json" | jq -r .scene)
if [[ $s_map == *" photons:xxh3:"* && $s_map != *view:* && $s_q == *" view:xxh3:"* && $s_q != *photons:* &&
    $s_ind = "$all" && $s_dir = "$all" ]]; then
    pass "SCENE: the map names the photons' part, the queries the view's, the buffers both"
else
    fail "SCENE keys by part" "map '$s_map' queries '$s_q' indirect '$s_ind' direct '$s_dir' scene '$all'"
fi
# Another scene's map (other triangles) is refused by the gather, naming both scenes.
O2=$TMP/o2
$R scenes/caustic/scene.json "$O2" $TINY WIDTH=24 HEIGHT=12 photonmap.pm >/dev/null 2>&1
"$BIN/simd-gather" -q "$O2/photonmap.pm" "$O/sorted.pm" -o "$TMP/x.pm" 2>"$TMP/x.err"
status=$?
if [ $status = 1 ] && grep -q "is of scene" "$TMP/x.err" && [ ! -e "$TMP/x.pm" ]; then
    pass "the gather refuses another scene's map"
else
    fail "another scene's map" "exit $status: $(head -c 300 "$TMP/x.err")"
fi

# pipelines/frames MOVE=camera: the map of frame 0 serves every frame (the photons' part does
# not change with the camera), and a frame from the kept map is the frame traced afresh.
F="FRAMES=3 PHOTONS=5000 SPP=4 WIDTH=24 HEIGHT=16"
pipelines/frames scenes/cornell-box/scene.json "$TMP/fr1" $F >"$TMP/fr1.out" 2>&1 &&
    pipelines/frames scenes/cornell-box/scene.json "$TMP/fr0" $F REUSE=0 >"$TMP/fr0.out" 2>&1
status=$?
if [ $status = 0 ] && jq -e '[.per_frame[].map_reused] == [false, true, true]' "$TMP/fr1/frames.json" >/dev/null &&
    jq -e '[.per_frame[].map_reused] == [false, false, false]' "$TMP/fr0/frames.json" >/dev/null &&
    [ "$(grep -c ' reused ' "$TMP/fr1.out")" = 2 ]; then
    pass "frames MOVE=camera traces the photons once (REUSE=0: every frame)"
else
    fail "frames map reuse" "exit $status: $(tail -n 3 "$TMP/fr1.out")"
fi
if cmp -s "$TMP/fr1/frame-0002.png" "$TMP/fr0/frame-0002.png" && ! cmp -s "$TMP/fr1/frame-0000.png" "$TMP/fr1/frame-0002.png"; then
    pass "... a frame from the kept map is the frame traced afresh, and the frames differ"
else
    fail "frames from the kept map" "frame 2 differs from REUSE=0's, or frames 0 and 2 are the same"
fi
expect_exit "frames REUSE=2 is bad usage" 2 pipelines/frames scenes/cornell-box/scene.json "$TMP/fr2" REUSE=2

# A file of the one-hash form (written before the parts: the golden reference as of commit
# fc104bf, 8 samples) names the scene by an identity older than version 2 (scene_hash.c):
# trace-reference refuses to resume it, naming both forms, and writes nothing.
if git show fc104bf:tests/golden/trace-reference-cornell.pm >"$TMP/oldref.pm" 2>/dev/null &&
    grep -aq '^SCENE=cornell-box xxh3:[0-9a-f]*$' "$TMP/oldref.pm"; then
    expect_error "trace-reference refuses a buffer of an older scene identity" \
        "is of scene 'cornell-box xxh3:1e6c424fe164f12c', not 'cornell-box xxh3:[0-9a-f]* photons:xxh3:" \
        "$BIN/trace-reference" scenes/cornell-box/scene.json -q --width 16 --height 16 --spp 16 \
        --resume "$TMP/oldref.pm" --radiance "$TMP/newref.pm" -o "$TMP/newref.exr"
    [ ! -e "$TMP/newref.pm" ] && [ ! -e "$TMP/newref.exr" ] && pass "... and writes nothing" ||
        fail "refused resume's output" "$TMP/newref.pm or .exr exists"
else
    skip "resume of a one-hash SCENE: commit fc104bf is not in this checkout"
fi

# A sky, a sun or two-sided emitters are lights: they change the photons' part (and the
# whole hash), not the view's, and not each other's.
sky() { # sky JSON-MEMBERS: the Cornell box with these top-level members added
    jq ". + {$1}" scenes/cornell-box/scene.json >"$D/scene.json"
}
sky '"sky": {"radiance": [1, 1, 1]}'
p1=$(part photons) v1=$(part view) a1=$(part all)
sky '"sky": {"radiance": [2, 2, 2]}'
p2=$(part photons) v2=$(part view) a2=$(part all)
sky '"sun": {"direction": [0, 1, 0], "radiance": [9, 9, 9], "solid_angle": 0.01}'
p3=$(part photons) v3=$(part view)
sky '"two_sided_lights": true'
p4=$(part photons) v4=$(part view)
sky '"two_sided_lights": false'
p5=$(part photons)
if [ "$p1" != "$p2" ] && [ "$a1" != "$a2" ] && [ "$v1" = "$v2" ] && [ "$v2" = "$v3" ] && [ "$v3" = "$v4" ] &&
    [ "$p3" != "$p1" ] && [ "$p4" != "$p5" ] && [ "$p4" != "$p3" ]; then
    pass "a sky, a sun and two-sided lights change the photons' part, not the view's"
else
    fail "sky/sun/two-sided parts" "photons $p1 $p2 $p3 $p4 $p5, view $v1 $v2 $v3 $v4"
fi
