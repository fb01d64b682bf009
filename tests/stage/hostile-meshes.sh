# hostile-meshes.sh: issue 28, meshes and scenes built to break the loader (items 2, 4, 5, 6, 7
# and 8): each case ends in its right answer or in one line naming the file and the value, never
# a crash, a hang or a silently wrong scene.
# programs: scene-info trace-photons

# ---- item 8: a correctly facing lamp is not called flipped because a point light is 1 km away
# (the tolerance was 1e-3 of the bounds' diagonal, which the far light made 1 m)
H=$TMP/hostile
mkdir -p "$H"
jq '.point_lights = [{"position": [0, 0, 1000], "intensity": [1, 1, 1]}]' scenes/cornell-box/scene.json >"$H/far.json"
cp scenes/cornell-box/*.obj scenes/cornell-box/*.mtl "$H"/
"$BIN/scene-info" "$H/far.json" >"$H/far.out" 2>"$H/far.err"
grep -q '^emissive triangles: 2$' "$H/far.out" && ! grep -q 'face away' "$H/far.err" &&
    pass "scene-info: the Cornell box's light is not called flipped with a point light 1 km away" ||
    fail "flipped-lamp advice with a far light" "$(head -c 300 "$H/far.err")"
awk '/^g / { light = ($2 == "light") } light && /^f / { print "f", $4, $3, $2; next } { print }' \
    scenes/cornell-box/cornell-box.obj >"$H/flipped.obj"
jq '.meshes[0].file = "flipped.obj"' "$H/far.json" >"$H/farflip.json"
"$BIN/scene-info" "$H/farflip.json" 2>/dev/null | grep -q '^emissive triangles: 2 (2 facing away' &&
    pass "... and a flipped one still is" || fail "flipped lamp with a far light" "not reported"

# ---- item 6: N placements of a lamp that faces away from everything load in linear time
# (every emitter was tried against every vertex: 30,000 placements took about 15 s)
printf 'mtllib lamp.mtl\nv -0.1 0 -0.1\nv 0.1 0 -0.1\nv 0.1 0 0.1\nv -0.1 0 0.1\nusemtl lamp\nf 1 3 2\nf 1 4 3\n' >"$H/lamp.obj"
printf 'newmtl lamp\nKd 0 0 0\nKe 1 1 1\n' >"$H/lamp.mtl"
{
    printf '{"pmtk_scene": 1, "name": "lamps", "meshes": [{"file": "lamp.obj"}'
    awk 'BEGIN { for (i = 1; i < 30000; i++) printf ", {\"file\": \"lamp.obj\", \"translate\": [%d, 0, %d]}", i % 200, int(i / 200) }'
    printf '], "camera": {"eye": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 60, "width": 8, "height": 8}}\n'
} >"$H/lamps.json"
if timeout 10 "$BIN/scene-info" "$H/lamps.json" >"$H/lamps.out" 2>/dev/null; then
    grep -q '^emissive triangles: 60000 (60000 facing away' "$H/lamps.out" &&
        pass "30,000 placements of a flipped lamp: loaded and counted within 10 s" ||
        fail "30,000 placements" "$(grep emissive "$H/lamps.out")"
else
    fail "30,000 placements of a flipped lamp" "scene-info did not finish within 10 s (exit $?)"
fi
