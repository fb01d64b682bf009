# hostile-meshes.sh: issue 28, meshes and scenes built to break the loader (items 2, 4, 5, 6, 7
# and 8): each case ends in its right answer or in one line naming the file and the value, never
# a crash, a hang or a silently wrong scene.
# programs: scene-info trace-photons trace-gather-points pm-info pm-render

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

# ---- item 7: a FIFO named as a mesh or a material library is refused at once, not waited on
quad_scene "$H/fifo" 'Kd 0.5'
mv "$H/fifo/m.obj" "$H/fifo/real.obj" && mkfifo "$H/fifo/m.obj"
expect_error "a FIFO named as a mesh is refused without blocking" "mesh '.*fifo/m.obj' is not a regular file \\(a FIFO\\)" \
    timeout 10 "$BIN/scene-info" "$H/fifo/scene.json"
rm "$H/fifo/m.obj" && mv "$H/fifo/real.obj" "$H/fifo/m.obj" && mv "$H/fifo/m.mtl" "$H/fifo/real.mtl" && mkfifo "$H/fifo/m.mtl"
expect_error "a FIFO named as an OBJ's mtllib is refused without blocking" \
    "material library '.*fifo/m.mtl' is not a regular file \\(a FIFO\\)" timeout 10 "$BIN/scene-info" "$H/fifo/scene.json"
mkfifo "$H/fifo/fifo.json"
expect_error "a FIFO named as the scene file is refused without blocking" \
    "scene '.*fifo/fifo.json' is not a regular file \\(a FIFO\\)" timeout 10 "$BIN/trace-photons" "$H/fifo/fifo.json" -o "$H/fifo/ph.pm"

# -o - and a name of stdout for another output are one output (they interleaved): usage, exit 2
TGP=("$BIN/trace-gather-points" -q "$H/kd1/scene.json" --spp 4 --width 8 --height 8)
for other in "--direct /dev/stdout" "--direct /dev/fd/1" "--stats /dev/stdout"; do
    "${TGP[@]}" -o - $other 2>"$H/dup.err" | cat >"$H/dup.out"
    st=${PIPESTATUS[0]}
    [ "$st" = 2 ] && grep -q "two outputs to one file: stdout and '/dev/" "$H/dup.err" && [ ! -s "$H/dup.out" ] &&
        pass "-o - with $other is one output: exit 2, nothing written" || fail "-o - with $other" "exit $st: $(head -c 200 "$H/dup.err")"
done
"${TGP[@]}" -o - --direct "$H/d.pm" >"$H/q.pm" 2>"$H/dup.err" && "${TGP[@]}" -o - --direct "$H/q2.pm" >"$H/q2.pm" 2>"$H/dup.err"
[ $? = 2 ] && grep -q "stdout and '.*q2.pm'" "$H/dup.err" && pass "-o - with --direct naming the file stdout goes to: exit 2" ||
    fail "-o - and --direct on stdout's file" "$(head -c 200 "$H/dup.err")"

# a file-size limit: a clean I/O error (exit 3), no hidden temporary file left (SIGXFSZ killed it)
mkdir -p "$H/fsz"
(ulimit -f 8 && exec "$BIN/trace-gather-points" -q "$H/kd1/scene.json" --spp 4 --width 64 --height 64 \
    -o "$H/fsz/q.pm" --direct "$H/fsz/d.pm") 2>"$H/fsz.err"
st=$?
[ "$st" = 3 ] && grep -q "File too large" "$H/fsz.err" && [ -z "$(ls -A "$H/fsz")" ] &&
    pass "ulimit -f: exit 3 'File too large', no file left behind" || fail "file-size limit" "exit $st, left: $(ls -A "$H/fsz") $(head -c 200 "$H/fsz.err")"

# ---- item 2: a mesh in units of its own, placed twice: instancing only within its range
# (mesh coordinates up to 1e8, scales 1e-4 to 1e4), otherwise built flat and said so; the image
# is the flat build's ("instancing": false), never an Embree abort (exit 134) nor black
printf 'mtllib p.mtl\nv -1e14 0 -1e14\nv 1e14 0 -1e14\nv 1e14 0 1e14\nv -1e14 0 1e14\nusemtl grey\nf 1 4 3 2\n' >"$H/p.obj"
printf 'newmtl grey\nKd 0.5 0.5 0.5\n' >"$H/p.mtl"
cat >"$H/inst.json" <<'JSON'
{"pmtk_scene": 1, "name": "inst",
 "meshes": [{"file": "p.obj", "scale": 1e-14}, {"file": "p.obj", "scale": 1e-14, "translate": [0, -0.5, 0]}],
 "point_lights": [{"position": [0, 1, 0], "intensity": [1, 1, 1]}],
 "camera": {"eye": [0, 1, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 60, "width": 16, "height": 16}}
JSON
jq '.instancing = false' "$H/inst.json" >"$H/flat.json"
"$BIN/scene-info" "$H/inst.json" 2>&1 | grep -q '^instancing: 2 placements of repeated meshes built flat' &&
    pass "a plane at +-1e14 placed twice with scale 1e-14: built flat, and scene-info says so" ||
    fail "instancing range" "$("$BIN/scene-info" "$H/inst.json" 2>&1 | head -c 300)"
small="PHOTONS=2000 SPP=4"
pipelines/render "$H/inst.json" "$H/inst" $small >/dev/null 2>"$H/inst.err" &&
    pipelines/render "$H/flat.json" "$H/flat" $small >/dev/null 2>&1 &&
    cmp -s <("$BIN/pm-info" -r "$H/inst/direct.pm" | grep -E '^[0-9]+ ') <("$BIN/pm-info" -r "$H/flat/direct.pm" | grep -E '^[0-9]+ ') &&
    "$BIN/pm-info" -r "$H/inst/direct.pm" | awk '/^[0-9]+ / { s += $2 } END { exit !(s > 0) }' &&
    pass "... and renders as with \"instancing\": false, not black, no abort" ||
    fail "instanced plane of +-1e14" "$(head -c 300 "$H/inst.err")"
# the Cornell box in units of 1e16 mm, placed twice
awk '/^v / { printf "v %.17g %.17g %.17g\n", $2 * 1e16, $3 * 1e16, $4 * 1e16; next } { print }' \
    scenes/cornell-box/cornell-box.obj >"$H/big.obj"
jq '.meshes = [{"file": "big.obj", "scale": 1e-19}, {"file": "big.obj", "scale": 1e-19, "translate": [2, 0, 0]}] | .name = "big"' \
    scenes/cornell-box/scene.json >"$H/big.json"
pipelines/render "$H/big.json" "$H/big" $small WIDTH=16 HEIGHT=12 >/dev/null 2>"$H/big.err" &&
    "$BIN/pm-info" -r "$H/big/direct.pm" | awk '/^[0-9]+ / { s += $2 } END { exit !(s > 0) }' &&
    pass "the Cornell box in units of 1e16 mm placed twice is not black" || fail "Cornell box in 1e16 mm" "$(head -c 300 "$H/big.err")"

# ---- item 4: meshes through assimp. tests/fuzz/meshes: mutants of assimp-testmodels' cube.ply
# that hang (24- and 31-byte headers; end_header at the end of a property line) or abort
# (an ai_assert in TriangulateProcess) inside libassimp 5.2: each is one line, exit 1
mesh_scene() { # mesh_scene JSON MESH: a scene placing MESH (a path) once, lit, seen from z = 3
    printf '{"pmtk_scene": 1, "name": "m", "meshes": [{"file": "%s"}], "point_lights": [{"position": [0, 1, 0], "intensity": [1, 1, 1]}], "camera": {"eye": [0, 0, 3], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60, "width": 8, "height": 8}}\n' "$2" >"$1"
}
for m in ply-header-24-bytes ply-header-31-bytes ply-end-header-in-line; do
    mesh_scene "$H/$m.json" "$PWD/tests/fuzz/meshes/$m.ply"
    expect_error "PLY $m: its header is refused before assimp reads it (assimp looped)" \
        "mesh '.*$m.ply': PLY header has no end_header line" timeout 20 "$BIN/scene-info" "$H/$m.json"
done
mesh_scene "$H/assert.json" "$PWD/tests/fuzz/meshes/ply-assert-triangulate.ply"
expect_error "PLY whose import aborts inside assimp: one line from the guarded load" \
    "mesh '.*ply-assert-triangulate.ply': assimp's import crashed \\(signal 6" timeout 20 "$BIN/scene-info" "$H/assert.json"
M=/usr/share/assimp/models
if [ -d "$M" ]; then
    mesh_scene "$H/oom.json" "$M/invalid/OutOfMemory.off"
    expect_error "assimp's invalid/OutOfMemory.off: its counts are refused (it grew toward 16 GB)" \
        "mesh '.*OutOfMemory.off': OFF header declares 353535235358 vertices and 6 faces, more than its 309 bytes" \
        timeout 20 "$BIN/scene-info" "$H/oom.json"
    mesh_scene "$H/wuson.json" "$M/PLY/Wuson.ply"
    "$BIN/scene-info" "$H/wuson.json" 2>&1 | grep -q '^triangles: 3732 ' && pass "a good PLY (Wuson.ply) loads through the checks" ||
        fail "Wuson.ply" "$("$BIN/scene-info" "$H/wuson.json" 2>&1 | tail -1)"
    PMTK_IMPORT_MB=1 expect_error "PMTK_IMPORT_MB=1: an import that takes more is stopped, one line" \
        "mesh '.*Wuson.ply': assimp's import took more than 1 MiB \\(PMTK_IMPORT_MB\\)" "$BIN/scene-info" "$H/wuson.json"
    PMTK_IMPORT_MB=x expect_exit "PMTK_IMPORT_MB=x is bad usage" 2 "$BIN/scene-info" "$H/wuson.json"
    for s in Spider_binary.stl Spider_ascii.stl; do
        mesh_scene "$H/$s.json" "$M/STL/$s"
        "$BIN/scene-info" "$H/$s.json" 2>&1 | grep -q '^triangles: 1312 ' && pass "STL $s loads through the checks" ||
            fail "STL $s" "$("$BIN/scene-info" "$H/$s.json" 2>&1 | tail -1)"
    done
    head -c 150 "$M/STL/Spider_binary.stl" >"$H/short.stl"
    mesh_scene "$H/short.json" "$H/short.stl"
    expect_error "a binary STL cut short is refused by its size" "STL file of 150 bytes is neither binary" "$BIN/scene-info" "$H/short.json"
    mesh_scene "$H/ior.json" "$M/glTF2/IndexOutOfRange/IndexOutOfRange.gltf"
    expect_error "a glTF face with an out-of-range index is an error naming the face (assimp dropped it)" \
        "mesh '.*IndexOutOfRange.gltf': glTF mesh 0 \\('Mesh'\\) primitive 0: face 0 names vertex 255 of 24" \
        "$BIN/scene-info" "$H/ior.json"
else
    skip "assimp-testmodels" "$M is missing (Debian package assimp-testmodels)"
fi

# ---- item 6: a photon count the machine cannot hold is refused up front (it grew to the OOM killer)
expect_exit "trace-photons --photons 5e11: refused at once, out of memory (exit 3)" 3 \
    timeout 20 "$BIN/trace-photons" scenes/cornell-box/scene.json --photons 500000000000 -o "$H/p.pm"
grep -q "500000000000 photons need at least .* GB .* more than this machine's .* GB of physical memory" "$TMP/err" &&
    [ "$(wc -l <"$TMP/err")" = 1 ] && [ ! -e "$H/p.pm" ] && pass "... in one line naming the count and the memory, no output" ||
    fail "photon count beyond memory" "$(head -c 300 "$TMP/err")"
