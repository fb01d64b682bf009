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

# ---- item 5: MTL values assimp reads wrong without a word, and a scene name with a control byte
# quad_scene DIR MTL-BODY [OBJ-USEMTL]: a floor quad (material 'grey' from m.mtl = MTL-BODY) seen
# from above, lit by a point light
quad_scene() {
    mkdir -p "$1"
    printf 'mtllib m.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n%s\nf 1 4 3 2\n' "${3:-usemtl grey}" >"$1/m.obj"
    printf 'newmtl lamp\nKd 0 0 0\nKe 1 1 1\nnewmtl grey\n%s\n' "$2" >"$1/m.mtl"
    printf '{"pmtk_scene": 1, "name": "quad", "meshes": [{"file": "m.obj"}], "point_lights": [{"position": [0, 1, 0], "intensity": [1, 1, 1]}], "camera": {"eye": [0, 1, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 60, "width": 8, "height": 8}}\n' >"$1/scene.json"
}
quad_scene "$H/kd1" 'Kd 0.5'
"$BIN/scene-info" "$H/kd1/scene.json" 2>"$H/kd1.err" | grep -q '^  0 grey kd 0.5 0.5 0.5 ' &&
    pass "MTL: Kd 0.5 is grey (g and b default to r)" || fail "Kd with one value" "$("$BIN/scene-info" "$H/kd1/scene.json" 2>&1 | grep grey)"
quad_scene "$H/ke1" 'Kd 0.2 0.3 0.4
Ke 2'
"$BIN/scene-info" "$H/ke1/scene.json" 2>/dev/null | grep -q ' ke 2 2 2$' && pass "MTL: Ke 2 is white" ||
    fail "Ke with one value" "$("$BIN/scene-info" "$H/ke1/scene.json" 2>&1 | grep grey)"
n=0
for v in 'Kd 0.5,0.5,0.5' 'Kd 0x1p-1 0.5 0.5' 'Kd inf 0.5 0.5' 'Kd 0.5 nan 0.5' 'Ks 0.1 0.1 0.1 0.1' 'Ns 1,5' 'Ns 10 20'; do
    n=$((n + 1))
    quad_scene "$H/bad$n" "$v"
    expect_error "MTL: '$v' is refused naming the file, line and value" \
        "mesh '.*m.obj': '.*m.mtl' line 5: ${v%% *} '${v#* }' (is not|has)" "$BIN/scene-info" "$H/bad$n/scene.json"
done
quad_scene "$H/long" "Kd 0.5
map_Kd $(head -c 1100 /dev/zero | tr '\0' a).png"
expect_error "MTL: a map_Kd path of 1104 bytes is refused, not dropped" \
    "'.*m.mtl' line 6: map_Kd path of 1104 bytes, beyond the 1023 assimp keeps" "$BIN/scene-info" "$H/long/scene.json"
quad_scene "$H/bare" 'Kd 0.5' 'usemtl'
expect_error "OBJ: a bare usemtl is an error, not the .mtl's last material" \
    "mesh '.*m.obj': usemtl on line 6 names no material" "$BIN/scene-info" "$H/bare/scene.json"
quad_scene "$H/ctl" 'Kd 0.5'
jq '.name = "a\u0001b"' "$H/ctl/scene.json" >"$H/ctl/c.json"
expect_error "a scene name with a control byte is refused" "scene '.*c.json': name: .*control bytes" \
    "$BIN/scene-info" "$H/ctl/c.json"
# TARGET_ERROR below the smallest normal double: bad usage, not a stop "as if met" after pass 2
expect_exit "TARGET_ERROR=1e-320 (subnormal) is bad usage" 2 pipelines/render "$H/kd1/scene.json" "$H/te" TARGET_ERROR=1e-320
grep -q "bad value for TARGET_ERROR '1e-320'.*at least 2.22507e-308" "$TMP/err" && pass "... named with the smallest it takes" ||
    fail "TARGET_ERROR subnormal message" "$(cat "$TMP/err")"
