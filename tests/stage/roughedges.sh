# roughedges.sh: the rough edges a new user hit (issue 21, point 4): GATHER=knn-gather in
# pipelines/render (its own command line, rows labelled by program, bad usage exit 2 before
# anything runs), composite's PNG preview of an OpenEXR image, the warning for an emitter
# wound away from the scene, and a glTF metallic factor between 0 and 1 reported where pmtk approximates it.
# programs: composite scene-info trace-photons pm-render
R=pipelines/render
CORNELL=scenes/cornell-box/scene.json
TINY="PHOTONS=5000 SPP=4 WIDTH=16 HEIGHT=12"

# ---- GATHER=knn-gather
O=$TMP/k
$R "$CORNELL" "$O" $TINY >/dev/null 2>&1
$R "$CORNELL" "$O" $TINY GATHER=knn-gather RADIUS=0.2 K=20 >"$TMP/k.out" 2>&1
status=$?
if [ $status = 0 ] && grep -qE '^  knn-gather +ran ' "$TMP/k.out" && ! grep -q 'simd-gather' "$TMP/k.out" &&
    jq -e '.stages | has("knn-gather") and (has("simd-gather") | not)' "$O/stats.json" >/dev/null &&
    "$BIN/pm-info" --header "$O/indirect.pm" | grep -q '^COMMAND=knn-gather .*--max-radius 0.2 --k 20'; then
    pass "GATHER=knn-gather: RADIUS is its --max-radius, the row and stats.json say knn-gather"
else
    fail "GATHER=knn-gather" "exit $status: $(cat "$TMP/k.out")"
fi
$R "$CORNELL" "$O" $TINY GATHER=knn-gather RADIUS=0.2 K=20 >"$TMP/k2.out" 2>&1
grep -qE '^  knn-gather +cached ' "$TMP/k2.out" && [ ! -s "$O/ran.txt" ] && pass "... a rerun runs nothing and calls it cached" ||
    fail "knn-gather rerun" "$(cat "$TMP/k2.out")"
for bad in "RADIUS=-1:bad value for RADIUS '-1'" "ISA=avx2:ISA with GATHER=knn-gather" "WIDTHS=variable:WIDTHS=variable with GATHER=knn-gather" \
    "KERNEL=box:bad value for KERNEL 'box'"; do
    : >"$O/ran.txt"
    $R "$CORNELL" "$O" $TINY GATHER=knn-gather "${bad%%:*}" >"$TMP/kb.out" 2>"$TMP/kb.err"
    status=$?
    if [ $status = 2 ] && [ "$(wc -l <"$TMP/kb.err")" = 1 ] && grep -qF "render: ${bad#*:}" "$TMP/kb.err" && [ ! -s "$TMP/kb.out" ] &&
        [ ! -s "$O/ran.txt" ]; then
        pass "GATHER=knn-gather ${bad%%:*}: exit 2, one line, no table, nothing run"
    else
        fail "GATHER=knn-gather ${bad%%:*}" "exit $status: $(head -c 300 "$TMP/kb.err") / $(head -c 300 "$TMP/kb.out")"
    fi
done

# ---- composite: the PNG preview of an OpenEXR image is the PNG composite made beside it
$R "$CORNELL" "$TMP/e" $TINY >/dev/null 2>&1
if "$BIN/composite" -q "$TMP/e/image.exr" --png "$TMP/prev.png" && cmp -s "$TMP/prev.png" "$TMP/e/image.png" &&
    "$BIN/composite" -q "$TMP/e/image.exr:2" --exposure -1 --png "$TMP/prev2.png" && cmp -s "$TMP/prev2.png" "$TMP/e/image.png" &&
    "$BIN/composite" -q "$TMP/e/image.exr" --exposure 1 --png "$TMP/prev3.png" && ! cmp -s "$TMP/prev3.png" "$TMP/e/image.png"; then
    pass "composite IMAGE.exr --png: the preview composite wrote from the buffers, SCALE and --exposure applied"
else
    fail "composite EXR preview" "differs from image.png"
fi
expect_exit "composite IMAGE.exr -o OTHER.exr is bad usage" 2 "$BIN/composite" "$TMP/e/image.exr" -o "$TMP/x.exr" --png "$TMP/x.png"
[ ! -e "$TMP/x.png" ] && [ ! -e "$TMP/x.exr" ] && pass "... and writes nothing" || fail "composite EXR usage" "wrote output"
expect_exit "composite IMAGE.exr with a buffer beside it is bad usage" 2 "$BIN/composite" "$TMP/e/image.exr" "$TMP/e/direct.pm" --png "$TMP/x.png"

# ---- a flipped emitter: the Cornell box with its light's faces reversed
F=$TMP/flip
mkdir -p "$F"
cp scenes/cornell-box/scene.json scenes/cornell-box/*.mtl "$F"/
awk '/^g / { light = ($2 == "light") } light && /^f / { print "f", $4, $3, $2; next } { print }' \
    scenes/cornell-box/cornell-box.obj >"$F/cornell-box.obj"
msg="2 emissive triangles face away from the whole scene (first: triangle 30, material 'light')"
"$BIN/scene-info" "$F/scene.json" >"$TMP/f.out" 2>"$TMP/f.err"
grep -qF "scene-info: warning: $msg" "$TMP/f.err" && grep -q '^emissive triangles: 2 (2 facing away' "$TMP/f.out" &&
    [ "$("$BIN/scene-info" -q --json "$F/scene.json" | jq .flipped_emitters)" = 2 ] &&
    pass "scene-info warns of a light wound away from the scene (text, stderr and --json)" ||
    fail "scene-info flipped light" "$(cat "$TMP/f.err")"
"$BIN/trace-photons" "$F/scene.json" --photons 2000 -o "$TMP/f.pm" 2>"$TMP/ft.err"
grep -qF "trace-photons: warning: $msg" "$TMP/ft.err" && pass "trace-photons warns of it too" ||
    fail "trace-photons flipped light" "$(cat "$TMP/ft.err")"
$R "$F/scene.json" "$TMP/fr" $TINY >"$TMP/fr.out" 2>&1
grep -q '^render: warning: 2 emissive triangle(s) face away' "$TMP/fr.out" && pass "... and render" ||
    fail "render flipped light" "$(head -c 300 "$TMP/fr.out")"
"$BIN/scene-info" "$CORNELL" >/dev/null 2>"$TMP/ok.err"
"$BIN/trace-photons" "$CORNELL" --photons 2000 -o "$TMP/ok.pm" 2>>"$TMP/ok.err"
grep -q 'face away' "$TMP/ok.err" && fail "the Cornell box's own light" "warned: $(cat "$TMP/ok.err")" ||
    pass "... and not of the Cornell box's own light, 0.5 mm under the ceiling and facing down"
# The flipped light delivers next to nothing to the room (stored photon power on surfaces
# below y = 0.5 m): the warning is about a real loss.
"$BIN/trace-photons" -q "$CORNELL" --photons 20000 -o "$TMP/a.pm" && "$BIN/trace-photons" -q "$F/scene.json" --photons 20000 -o "$TMP/b.pm"
room() { "$BIN/pm-info" -r "$1" | awk 'NF == 11 && $1 ~ /^[0-9]+$/ && $3 < 0.5 { p += $5 } END { printf "%.6g", p }'; }
pa=$(room "$TMP/a.pm") pb=$(room "$TMP/b.pm")
awk -v a="$pa" -v b="$pb" 'BEGIN { exit !(a > 0 && b < 0.1 * a) }' &&
    pass "the flipped light puts under a tenth of the power on the room below 0.5 m ($pb W against $pa W, red channel)" ||
    fail "flipped light power" "$pb W against $pa W"

# ---- glTF: a metallic factor pmtk approximates (the nearer kind) is reported, not dropped in silence
G=$TMP/gl
mkdir -p "$G"
printf '{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"scene":0,"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0}]}],
"materials":[{"name":"m","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0.5,"roughnessFactor":0.3}}],
"buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/"}],
"bufferViews":[{"buffer":0,"byteLength":36}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}]}\n' >"$G/t.gltf"
printf '{"pmtk_scene": 1, "name": "gl", "meshes": [{"file": "t.gltf"}], "point_lights": [{"position": [0.3, 1, 0.3], "intensity": [1, 1, 1]}],
"camera": {"eye": [0.5, 1, -1], "look_at": [0.5, 0, 0.5], "up": [0, 1, 0], "fov_y": 40, "width": 8, "height": 8}}\n' >"$G/scene.json"
"$BIN/scene-info" "$G/scene.json" >/dev/null 2>"$TMP/gl.err"
grep -q "material 'm': metallicFactor 0.5 is approximated: rendered as metal" "$TMP/gl.err" && ! grep -q "roughnessFactor" "$TMP/gl.err" &&
    pass "glTF metallicFactor 0.5 (neither metal nor dielectric) is reported as approximated, roughnessFactor 0.3 is honoured" ||
    fail "glTF metallic/roughness" "$(cat "$TMP/gl.err")"
