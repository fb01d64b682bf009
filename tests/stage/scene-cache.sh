# scene-cache.sh: the scene cache (docs/formats.md, "The scene cache"; PMTK_SCENE_CACHE).
#   1. A scene read from the cache is the scene loaded from its files: trace-photons' and
#      trace-gather-points' outputs are the same bytes with no cache, with the cache written
#      and with it read, on scenes that hold each kind of thing the cache carries (textures and
#      their sRGB table, vertex normals, instanced placements, a sky model's map, portals,
#      emitters, glass, the loader's notes).
#   2. A hit does not rewrite the file; every change of what the load read is a miss that
#      loads the files again and rewrites it: an edited .mtl, a texture, a texture that appears
#      where one was missing, the scene file; so are another scene path, a damaged file and a
#      header of another build (its checksum remade). (A payload whose counts or indices do not
#      hold together under a good checksum: the unit test scene_cache.)
#   3. A glTF scene (assimp reads its buffers itself) is not cached; an empty PMTK_SCENE_CACHE
#      turns the cache off.
#   4. pm-render keeps OUTDIR/scene.cache for its stages and its reruns (VERBOSE says written,
#      then read), and its images are the same bytes with the cache off.
# programs: scene-info trace-photons trace-gather-points pm-render
S=$TMP/sc
mkdir -p "$S"
inode() { stat -c %i "$1" 2>/dev/null; }

# outputs NAME SCENE CACHE: trace-photons and trace-gather-points of SCENE into $S/NAME/ (files of
# the same names everywhere: their headers' COMMAND lines name them)
outputs() {
    mkdir -p "$S/$1"
    (cd "$S/$1" && PMTK_SCENE_CACHE=$3 "$BIN/trace-photons" -q "$2" --photons 4000 -o photons &&
        PMTK_SCENE_CACHE=$3 "$BIN/trace-gather-points" -q "$2" --width 24 --height 16 --spp 4 -o queries --direct direct)
}

# ---- a scene with the parts the cache carries: a textured, vertex-normal mesh placed twice
# (an instance), a sky model, a sun, a portal, a mesh lamp (an emitter with a note)
PNG_TILE=89504e470d0a1a0a0000000d4948445200000002000000020802000000fdd49a73000000134944415478da633861a3f1ec4405031003590030a606a530874bc50000000049454e44ae426082
mkdir -p "$S/mix"
printf "$(echo "$PNG_TILE" | sed 's/../\\x&/g')" >"$S/mix/tile.png"
cat >"$S/mix/ball.obj" <<'OBJ'
mtllib ball.mtl
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
vn -0.5 0.7 -0.5
vn 0.5 0.7 -0.5
vn 0.5 0.7 0.5
vn -0.5 0.7 0.5
vn 0 1 0
usemtl tiled
f 1/1/1 5/5/5 2/2/2
f 2/2/2 5/5/5 3/3/3
f 3/3/3 5/5/5 4/4/4
f 4/4/4 5/5/5 1/1/1
OBJ
cat >"$S/mix/ball.mtl" <<'MTL'
newmtl tiled
Kd 0.8 0.7 0.6
Ka 0.1 0.1 0.1
map_Kd tile.png
MTL
cat >"$S/mix/scene.json" <<'JSON'
{
  "pmtk_scene": 1,
  "name": "cache-mix",
  "materials": { "floor": { "kind": "diffuse", "kd": [0.5, 0.5, 0.5] },
                 "glass": { "kind": "glass", "ior": 1.5 } },
  "meshes": [ { "file": "ball.obj", "translate": [-1.5, 0, 0] },
              { "file": "ball.obj", "translate": [1.5, 0, 0] } ],
  "shapes": [ { "type": "box", "size": [8, 0.1, 8], "translate": [0, -0.05, 0], "material": "floor" },
              { "type": "sphere", "radius": 0.4, "translate": [0, 0.6, 1.5], "material": "glass" } ],
  "camera": { "eye": [0, 3, 6], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 50, "width": 24, "height": 16 },
  "sun": { "direction": [0.3, 1, 0.2], "radiance": [1000, 1000, 1000], "solid_angle": 0.001 },
  "sky": { "model": "preetham", "turbidity": 3 },
  "portals": [ { "size": [8, 8], "rotate": { "axis": [1, 0, 0], "degrees": 90 }, "translate": [0, 3, 0] } ],
  "render": { "seed": 3 }
}
JSON
if ! "$BIN/scene-info" "$S/mix/scene.json" >"$S/mix.info" 2>"$S/mix.err"; then
    fail "the cache test's own scene loads" "$(head -c 300 "$S/mix.err")"
fi

for sc in "$S/mix/scene.json" "$PWD/scenes/cornell-box/scene.json" $PWD/scenes/caustic/scene.json \
    "$PWD/scenes/skylight/scene.json" "$PWD/scenes/atrium/textured.json"; do
    n=$(basename "$(dirname "$sc")")
    rm -f "$S/$n.cache"
    outputs "$n-none" "$sc" "" && outputs "$n-write" "$sc" "$S/$n.cache"
    before=$(inode "$S/$n.cache")
    outputs "$n-read" "$sc" "$S/$n.cache"
    if [ -z "$before" ]; then
        fail "$n: the first load writes the cache" "no $S/$n.cache"
    elif [ "$(inode "$S/$n.cache")" != "$before" ]; then
        fail "$n: a hit leaves the cache as it is" "it was rewritten"
    else
        same=1
        for f in photons queries direct; do
            cmp -s "$S/$n-none/$f" "$S/$n-write/$f" && cmp -s "$S/$n-none/$f" "$S/$n-read/$f" || same=0
        done
        [ $same = 1 ] && pass "$n: the stages' outputs are the same bytes without, writing and reading the cache" ||
            fail "$n: outputs through the cache" "some of photons, queries, direct differ"
    fi
done
PMTK_SCENE_CACHE=$S/mix.cache "$BIN/scene-info" "$S/mix/scene.json" 2>"$S/mix2.err" | grep -v '^time' >"$S/mix2.info"
if diff <(grep -v '^time' "$S/mix.info") "$S/mix2.info" >/dev/null && diff "$S/mix.err" "$S/mix2.err" >/dev/null; then
    pass "scene-info says the same of the cached scene, its notes and warnings too"
else
    fail "scene-info from the cache" "$(diff <(grep -v '^time' "$S/mix.info") "$S/mix2.info" | head -5)"
fi

# ---- 2. what makes a miss
# miss NAME SCENE CACHE WANT: scene-info through CACHE rewrites it and prints WANT (a pattern)
miss() {
    local before
    before=$(inode "$3")
    PMTK_SCENE_CACHE=$3 "$BIN/scene-info" "$2" >"$S/miss.out" 2>&1
    if [ "$(inode "$3")" = "$before" ]; then
        fail "$1" "the cache was not rewritten"
    elif ! grep -qE -- "$4" "$S/miss.out"; then
        fail "$1" "scene-info does not say '$4': $(grep -E 'kd|scene:|textures' "$S/miss.out" | head -3)"
    else
        pass "$1"
    fi
}
C=$S/mix.cache
sed -i 's/^Kd 0.8 0.7 0.6/Kd 0.3 0.7 0.6/' "$S/mix/ball.mtl"
miss "an edited .mtl is a miss: the new Kd is read" "$S/mix/scene.json" "$C" "kd 0.3 0.7 0.6"
h_old=$(grep '^hash:' "$S/miss.out")
# a 1 x 1 grey PNG (sRGB 128) in its place
PNG_128=89504e470d0a1a0a0000000d49484452000000010000000108000000003a7e9b550000000a4944415478da6368000000820081da45083b0000000049454e44ae426082
printf "$(echo "$PNG_128" | sed 's/../\\x&/g')" >"$S/mix/tile.png"
miss "a texture of other bytes is a miss" "$S/mix/scene.json" "$C" "tile.png' 1x1"
grep -q "^$h_old\$" "$S/miss.out" && fail "... and the scene's hash is another" "the hash did not change" ||
    pass "... and the scene's hash is another"
sed -i 's/"seed": 3/"seed": 4/' "$S/mix/scene.json"
miss "an edited scene file is a miss" "$S/mix/scene.json" "$C" "^scene: cache-mix"
# a texture missing (magenta) that appears
mkdir -p "$S/mag"
cp "$S/mix/ball.obj" "$S/mag/"
printf 'newmtl tiled\nKd 0.8 0.7 0.6\nmap_Kd late.png\n' >"$S/mag/ball.mtl"
sed 's/"render"/"missing_textures": "magenta", "render"/' "$S/mix/scene.json" >"$S/mag/scene.json"
PMTK_SCENE_CACHE=$S/mag.cache "$BIN/scene-info" "$S/mag/scene.json" >/dev/null 2>&1
cp "$S/mix/tile.png" "$S/mag/late.png"
miss "a missing texture that appears is a miss: it is loaded" "$S/mag/scene.json" "$S/mag.cache" "late.png' 1x1 [a-z]*, 8-bit sRGB"
# the same scene by another path
cp -r "$S/mix" "$S/mix-copy"
miss "another scene path is a miss" "$S/mix-copy/scene.json" "$C" "^scene: cache-mix"
# a damaged cache: one payload byte changed
sz=$(stat -c %s "$C")
printf '\x55' | dd of="$C" bs=1 seek=$((sz - 100)) conv=notrunc status=none
miss "a damaged cache is a miss, loaded from the files" "$S/mix-copy/scene.json" "$C" "^scene: cache-mix"
# another build, and a payload that does not hold together, each with its checksum remade
if /usr/bin/python3 -c 'import xxhash' 2>/dev/null; then
    rehash() { # rehash FILE PYTHON-EXPR: applies the change to the bytes before the trailer, remakes it
        /usr/bin/python3 - "$1" "$2" <<'PY'
import sys, struct, xxhash
p, expr = sys.argv[1], sys.argv[2]
d = bytearray(open(p, 'rb').read()[:-8])
exec(expr)
open(p, 'wb').write(bytes(d) + struct.pack('<Q', xxhash.xxh3_64_intdigest(bytes(d))))
PY
    }
    rehash "$C" "i = d.index(b'BUILD=') + 6; d[i] = ord('0') if d[i] != ord('0') else ord('1')"
    out=$(PMTK_SCENE_CACHE=$C "$BIN/pm-render" -q "$S/mix-copy/scene.json" "$S/o-build" GATHER=none PHOTONS=1000 SPP=4 \
        VERBOSE=1 2>&1 | grep 'scene cache')
    echo "$out" | grep -q "written (made by another build of pmtk)" && pass "a cache of another build is a miss, named" ||
        fail "another build" "'$out'"
else
    skip "a cache of another build" "python3-xxhash is not installed"
fi

# ---- 3. not cached: glTF; none at all with an empty PMTK_SCENE_CACHE
GLTF=/usr/share/assimp/models/glTF2/BoxTextured-glTF/BoxTextured.gltf
if [ -f "$GLTF" ]; then
    mkdir -p "$S/gl"
    cat >"$S/gl/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "gl", "meshes": [ { "file": "$GLTF" } ],
  "camera": { "eye": [2, 2, 2], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 50, "width": 8, "height": 8 },
  "sun": { "direction": [0, 1, 0], "radiance": [100, 100, 100], "solid_angle": 0.001 } }
JSON
    PMTK_SCENE_CACHE=$S/gl.cache "$BIN/scene-info" "$S/gl/scene.json" >/dev/null 2>"$S/gl.err"
    [ $? = 0 ] && [ ! -e "$S/gl.cache" ] && pass "a glTF scene loads and is not cached" ||
        fail "glTF not cached" "$(ls "$S"/gl.cache 2>&1) $(head -c 200 "$S/gl.err")"
else
    skip "a glTF scene is not cached" "no $GLTF (assimp-testmodels)"
fi
rm -rf "$S/o-off"
PMTK_SCENE_CACHE= "$BIN/pm-render" -q scenes/cornell-box/scene.json "$S/o-off" GATHER=none PHOTONS=1000 WIDTH=16 HEIGHT=12 \
    SPP=4 >/dev/null 2>&1
[ -e "$S/o-off/image.exr" ] && [ ! -e "$S/o-off/scene.cache" ] && pass "PMTK_SCENE_CACHE= (empty): no cache" ||
    fail "an empty PMTK_SCENE_CACHE" "$(ls "$S/o-off")"

# ---- 4. pm-render: OUTDIR/scene.cache, written then read; the same image without it
for mode in "" "PASSES=3"; do
    O=$S/o-render${mode:+-p}
    rm -rf "$O" "$O-off"
    first=$(env -u PMTK_SCENE_CACHE pipelines/render scenes/cornell-box/scene.json "$O" PHOTONS=2000 WIDTH=16 HEIGHT=12 SPP=4 $mode VERBOSE=1 2>&1 |
        grep 'scene cache')
    rm -f "$O/image.exr" "$O/image.png" "$O/running.pm" "$O/passes.txt"
    second=$(env -u PMTK_SCENE_CACHE pipelines/render scenes/cornell-box/scene.json "$O" PHOTONS=2000 WIDTH=16 HEIGHT=12 SPP=4 $mode VERBOSE=1 2>&1 |
        grep 'scene cache')
    PMTK_SCENE_CACHE= pipelines/render -q scenes/cornell-box/scene.json "$O-off" PHOTONS=2000 WIDTH=16 HEIGHT=12 SPP=4 \
        $mode >/dev/null 2>&1
    if echo "$first" | grep -q "scene cache $O/scene.cache: written" && echo "$second" | grep -q "scene cache $O/scene.cache: read"; then
        pass "pm-render ${mode:-one render}: OUTDIR/scene.cache written, then read on the rerun"
    else
        fail "pm-render ${mode:-one render} scene cache" "first '$first', second '$second'"
    fi
    "$BUILD/tests/pm-exrdump" "$O/image.exr" >"$S/a.txt" 2>&1
    "$BUILD/tests/pm-exrdump" "$O-off/image.exr" >"$S/b.txt" 2>&1
    expect_same "pm-render ${mode:-one render}: the image is the same with the cache as without" "$S/a.txt" "$S/b.txt"
done

# a render that OUTDIR's lock refuses leaves OUTDIR's cache as it was (the drivers read the cache
# before the lock and write it only after), one render and resident passes alike
for mode in "" PASSES=2; do
    O=$S/o-held${mode:+-p}
    rm -rf "$O"
    env -u PMTK_SCENE_CACHE pipelines/render -q scenes/cornell-box/scene.json "$O" PHOTONS=2000 WIDTH=16 HEIGHT=12 SPP=4 \
        $mode >/dev/null 2>&1
    before=$(inode "$O/scene.cache")
    flock "$O/.lock" sleep 3 &
    holder=$!
    sleep 0.3
    env -u PMTK_SCENE_CACHE pipelines/render -q scenes/skylight/scene.json "$O" PHOTONS=2000 WIDTH=16 HEIGHT=12 SPP=4 \
        $mode WAIT=0 >"$S/held.out" 2>&1
    st=$?
    wait $holder
    if [ $st = 1 ] && [ -n "$before" ] && [ "$(inode "$O/scene.cache")" = "$before" ]; then
        pass "${mode:-one render}: a render refused by OUTDIR's lock leaves its scene cache as it was"
    else
        fail "${mode:-one render}: a refused render and the cache" \
            "exit $st, inode '$before' -> '$(inode "$O/scene.cache")': $(head -c 200 "$S/held.out")"
    fi
done

# a directory as the cache: a file per scene in it, named by the hash of the scene's path
D=$S/cdir/
rm -rf "$D"
for sc in scenes/cornell-box/scene.json scenes/caustic/scene.json; do
    PMTK_SCENE_CACHE=$D "$BIN/scene-info" "$PWD/$sc" >/dev/null 2>&1
done
files=$(ls "$D" 2>/dev/null | grep -c '^scene-[0-9a-f]\{16\}\.cache$')
before=$(stat -c '%i' "$D"/scene-*.cache 2>/dev/null | sort | tr '\n' ' ')
for sc in scenes/cornell-box/scene.json scenes/caustic/scene.json; do
    PMTK_SCENE_CACHE=$D "$BIN/scene-info" "$PWD/$sc" >/dev/null 2>&1
done
after=$(stat -c '%i' "$D"/scene-*.cache 2>/dev/null | sort | tr '\n' ' ')
if [ "$files" = 2 ] && [ "$before" = "$after" ]; then
    pass "PMTK_SCENE_CACHE=DIR/: a cache file per scene, each read on the next load"
else
    fail "a cache directory" "$files files, inodes '$before' then '$after'"
fi
