# textures.sh: image textures through the stages (docs/scene-format.md, Textures).
#   1. A plane whose map_Kd is two bands of grey (sRGB 255 and 128: albedo x1 and x0.2158605),
#      lit by a point light: next-event estimation in trace-gather-points' direct buffer and
#      trace-reference through pixel centres both equal kd * texel / pi * I h / r^3 at every
#      pixel inside a band (to 1e-4: the only light is direct, nothing else to bounce to).
#   2. map_d: the right half of a plane cut out over a floor: the camera rays of the cut half
#      reach the floor 1 m further, the others stop on the plane; the photons and shadow rays
#      pass the same hole.
#   3. A small generated OBJ + MTL with Crytek Sponza's MTL habits (the .mtl in a sub-folder,
#      textures relative to it named with Windows backslashes and spaces, material names with
#      spaces, map_d of a grey TGA, map_Ka, a texture that is missing): an error naming the material and the file;
#      with "missing_textures": "magenta" a warning, and it renders through pipelines/render and
#      trace-reference.
#   4. A glossy textured floor (Kd 0.6 under a map_Kd of sRGB 128, Ks 0.3 under a map_Ks of sRGB
#      188, Ns 20) seen by the secondary rays of a Lambertian ceiling: the gathers' indirect
#      image against trace-reference --component indirect (which textures everything), mean
#      within 5% (measured 1%); gathering with the untextured Kd and Ks gave 3.5 times it.
# The images are written byte by byte (a few dozen bytes each, made once with zlib), so that the
# test needs no image tool.
# programs: build-photonmap composite measure-error scene-info trace-gather-points trace-photons trace-reference pm-render
PI=3.141592653589793

# png NAME HEX: writes the bytes of HEX to NAME.
png() { printf "$(echo "$2" | sed 's/../\\x&/g')" >"$1"; }
# 4 x 1 grey: 255 255 128 128
PNG_AB=89504e470d0a1a0a0000000d4948445200000004000000010800000000dc5750110000000d4944415478da63f8ffbfa10100087e02ff36d0234f0000000049454e44ae426082
# 1 x 1 grey: 128 (linear 0.2158605) and 188 (linear 0.5029)
PNG_128=89504e470d0a1a0a0000000d49484452000000010000000108000000003a7e9b550000000a4944415478da6368000000820081da45083b0000000049454e44ae426082
PNG_188=89504e470d0a1a0a0000000d49484452000000010000000108000000003a7e9b550000000a4944415478da63d8030000be00bd7eba55460000000049454e44ae426082
# 2 x 1 grey: 255 0 (a mask: left opaque, right cut)
PNG_MASK=89504e470d0a1a0a0000000d4948445200000002000000010800000000d14920560000000b4944415478da63f8cf000002010100a11e5c750000000049454e44ae426082
# 2 x 2 RGB checker of (200 60 40) and (230 200 120)
PNG_TILE=89504e470d0a1a0a0000000d4948445200000002000000020802000000fdd49a73000000134944415478da633861a3f1ec4405031003590030a606a530874bc50000000049454e44ae426082
# 2 x 1 grey TGA (type 3, 8 bits), as Crytek Sponza's masks: 255 0
TGA_LEAF=000003000000000000000000020001000800ff00

# textured_plane DIR MTL-LINES [EXTRA-OBJ]: a 4 m square plane y = 0 (u = x/4 + 1/2, v = z/4 + 1/2),
# material "paint" (Kd 0.8 0.8 0.8 and MTL-LINES), a point light of pi W/sr 1 m above the
# centre where the camera sits looking down (fov 90: x, z in [-1, 1]).
textured_plane() {
    local dir=$1 mtl=$2 extra=${3:-}
    mkdir -p "$dir"
    printf 'mtllib plane.mtl\nv -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl paint\nf 1/1 4/4 3/3 2/2\n%s' \
        "$extra" >"$dir/plane.obj"
    printf 'newmtl paint\nKd 0.8 0.8 0.8\n%s\nnewmtl floor\nKd 0.5 0.5 0.5\n' "$mtl" >"$dir/plane.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "textured-plane",
  "meshes": [ { "file": "plane.obj" } ],
  "camera": { "eye": [0, 1, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 32, "height": 32 },
  "point_lights": [ { "position": [0, 1, 0], "intensity": [$PI, $PI, $PI] } ],
  "render": { "photons": 20000, "spp": 4, "seed": 1 }
}
JSON
}

# bands HITS IMAGE: every pixel whose hit lies inside a band (u in [0.15, 0.35]: texel 255,
# x in [-1.4, -0.6]; u in [0.65, 0.85]: texel 128, x in [0.6, 1.4]) against
# 0.8 * texel / pi * I h / r^3; prints a summary, exits 1 when a pixel is off by more than 1e-4.
bands() {
    awk -v I=$PI 'FNR == NR {
            if ($1 ~ /^[0-9]+$/ && NF >= 11) { x[$NF] = $2; y[$NF] = $3; z[$NF] = $4 }
            next
        }
        $1 == "size" { w = $2; next }
        {
            p = $2 * w + $1
            if (!(p in x)) next
            if (x[p] >= -1.4 && x[p] <= -0.6) { tex = 1; na++ }
            else if (x[p] >= 0.6 && x[p] <= 1.4) { tex = 0.21586050011389926; nb++ }
            else next
            d2 = x[p] ^ 2 + (1 - y[p]) ^ 2 + z[p] ^ 2
            want = 0.8 * tex / 3.141592653589793 * I * (1 - y[p]) / (d2 * sqrt(d2))
            for (c = 3; c <= 5; c++) { r = $c / want; if (r - 1 > worst || 1 - r > worst) worst = r > 1 ? r - 1 : 1 - r }
        }
        END {
            printf "%d pixels of texel 255, %d of texel 128, worst relative error %.2g\n", na, nb, worst
            exit !(na >= 100 && nb >= 100 && worst < 1e-4)
        }' "$1" "$2"
}

# ---- 1. map_Kd scales Kd, sRGB-decoded, at every hit
textured_plane "$TMP/ab" "map_Kd ab.png"
png "$TMP/ab/ab.png" $PNG_AB
S=$TMP/ab/scene.json
if "$BIN/trace-gather-points" "$S" --spp 4 --pixel center -q -o "$TMP/ab.q.pm" --direct "$TMP/ab.d.pm" &&
    "$BIN/composite" "$TMP/ab.d.pm" -q -o "$TMP/ab.d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/ab.d.exr" >"$TMP/ab.d.txt" &&
    "$BIN/trace-gather-points" "$S" --mode direct-vis --pixel center -q -o "$TMP/ab.hq.pm" &&
    "$BIN/pm-info" -r "$TMP/ab.hq.pm" >"$TMP/ab.hits.txt"; then
    if bands "$TMP/ab.hits.txt" "$TMP/ab.d.txt" >"$TMP/why"; then
        pass "map_Kd through trace-gather-points: L = Kd * texel / pi * E ($(cat "$TMP/why"))"
    else
        fail "map_Kd through trace-gather-points" "$(cat "$TMP/why")"
    fi
else
    fail "map_Kd pipeline" "a stage failed"
fi
if "$BIN/trace-reference" "$S" --pixel center --spp 4 --pass 4 -q -o "$TMP/ab.ref.exr" &&
    "$BUILD/tests/pm-exrdump" "$TMP/ab.ref.exr" >"$TMP/ab.ref.txt" && bands "$TMP/ab.hits.txt" "$TMP/ab.ref.txt" >"$TMP/why"; then
    pass "map_Kd through trace-reference: L = Kd * texel / pi * E ($(cat "$TMP/why"))"
else
    fail "map_Kd through trace-reference" "$(cat "$TMP/why" 2>/dev/null)"
fi

# ---- 2. map_d cuts holes for every ray
textured_plane "$TMP/cut" "map_d mask.png" 'v -5 -1 -5
v 5 -1 -5
v 5 -1 5
v -5 -1 5
usemtl floor
f 5 8 7 6
'
png "$TMP/cut/mask.png" $PNG_MASK
S=$TMP/cut/scene.json
if "$BIN/trace-gather-points" "$S" --mode direct-vis -q -o "$TMP/cut.q.pm" --direct "$TMP/cut.d.pm" &&
    "$BIN/pm-info" -r "$TMP/cut.q.pm" >"$TMP/cut.hits.txt"; then
    # u = x/4 + 1/2 < 1/2 (x < 0) is opaque, x > 0 cut: hits there lie on the floor y = -1
    if awk '$1 ~ /^[0-9]+$/ && NF >= 11 {
            if ($2 < -0.05) { if ($3 > -1e-4 && $3 < 1e-4) a++; else bad++ }
            else if ($2 > 0.05) { if ($3 < -0.9999 && $3 > -1.0001) b++; else bad++ }
        }
        END { printf "%d hits on the plane, %d through the hole on the floor, %d wrong\n", a, b, bad; exit !(a > 400 && b > 400 && !bad) }' \
        "$TMP/cut.hits.txt" >"$TMP/why"; then
        pass "map_d: camera rays stop on the opaque half and pass the cut half ($(cat "$TMP/why"))"
    else
        fail "map_d camera rays" "$(cat "$TMP/why")"
    fi
else
    fail "map_d pipeline" "a stage failed"
fi
# Shadow rays: the floor under the cut half is lit (the light is above the plane). Photons
# straight from the light (depth 0) reach the floor only through the hole, x > 0 (or beyond the
# plane's edge, |x| or |z| > 4 on the floor); later bounces may land anywhere.
"$BIN/composite" "$TMP/cut.d.pm" -q -o "$TMP/cut.d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/cut.d.exr" >"$TMP/cut.d.txt"
if awk 'FNR == NR { if ($1 ~ /^[0-9]+$/ && NF >= 11) { x[$NF] = $2; y[$NF] = $3 } next }
        $1 == "size" { w = $2; next }
        { p = $2 * w + $1; if ((p in x) && x[p] > 0.05 && !($3 > 0)) dark++; if ((p in x) && x[p] > 0.05) n++ }
        END { exit !(n > 400 && !dark) }' "$TMP/cut.hits.txt" "$TMP/cut.d.txt"; then
    pass "map_d: shadow rays from the floor pass the hole to the light"
else
    fail "map_d shadow rays" "some floor pixel under the hole is dark"
fi
if "$BIN/trace-photons" "$S" --photons 20000 -q -o "$TMP/cut.ph.pm" && "$BIN/pm-info" -r "$TMP/cut.ph.pm" >"$TMP/cut.ph.txt" &&
    awk '$1 ~ /^[0-9]+$/ && NF >= 11 && $NF == 0 && $3 < -0.5 && $4 > -3.9 && $4 < 3.9 {
            if ($2 < 0 && $2 > -3.9) bad++; else if ($2 > 0 && $2 < 3.9) hole++ }
        END { printf "%d photons straight from the light on the floor under the hole, %d under the opaque half\n", hole, bad
            exit !(hole > 1000 && !bad) }' \
        "$TMP/cut.ph.txt" >"$TMP/why"; then
    pass "map_d: photons reach the floor only through the hole ($(cat "$TMP/why"))"
else
    fail "map_d photons" "$(cat "$TMP/why" 2>/dev/null)"
fi

# The same scene with its mesh placed twice (the second copy 100 m away, out of view): Embree
# instances of one mesh, with the cut-out filter on the shared geometry; the same hits.
jq '.meshes += [{file: "plane.obj", translate: [100, 0, 0]}]' "$S" >"$TMP/cut/twice.json"
if "$BIN/trace-gather-points" "$TMP/cut/twice.json" --mode direct-vis -q -o "$TMP/cut2.q.pm" &&
    "$BIN/pm-info" -r "$TMP/cut2.q.pm" >"$TMP/cut2.hits.txt" &&
    awk 'FNR == NR { if ($1 ~ /^[0-9]+$/ && NF >= 11) p[$NF] = $2 " " $3 " " $4; next }
        $1 ~ /^[0-9]+$/ && NF >= 11 { n++; split(p[$NF], a, " "); if ((a[1] - $2) ^ 2 + (a[2] - $3) ^ 2 + (a[3] - $4) ^ 2 > 1e-10) bad++ }
        END { printf "%d hits, %d moved\n", n, bad; exit !(n > 900 && !bad) }' "$TMP/cut.hits.txt" "$TMP/cut2.hits.txt" >"$TMP/why"; then
    pass "map_d on an instanced mesh: the same hits as placed once ($(cat "$TMP/why"))"
else
    fail "map_d on an instanced mesh" "$(cat "$TMP/why" 2>/dev/null)"
fi

# ---- 3. a Sponza-like OBJ + MTL
D="$TMP/my sponza"
mkdir -p "$D/mats/textures"
png "$D/mats/textures/floor tile.png" $PNG_TILE
png "$D/mats/textures/leaf mask.tga" $TGA_LEAF
cat >"$D/mini sponza.obj" <<'OBJ'
# two textured quads and an untextured wall, faces named by groups
mtllib mats/mini sponza.mtl
v -2 0 -2
v 2 0 -2
v 2 0 2
v -2 0 2
v -1 0.5 -1
v 1 0.5 -1
v 1 0.5 1
v -1 0.5 1
v -2 0 2
v 2 0 2
v 2 2 2
v -2 2 2
vt 0 0
vt 4 0
vt 4 4
vt 0 4
g floor
usemtl arch stone
f 1/1 4/4 3/3 2/2
g leaves
usemtl leaf
f 5/1 8/4 7/3 6/2
g back wall
usemtl plain wall
f 9/1 10/2 11/3 12/4
OBJ
cat >"$D/mats/mini sponza.mtl" <<'MTL'
newmtl arch stone
Ns 10
Kd 0.588 0.588 0.588
map_Ka textures\floor tile.png
map_Kd textures\floor tile.png

newmtl leaf
Kd 1 1 1
map_Kd textures\floor tile.png
map_d textures\leaf mask.tga

newmtl plain wall
Kd 0.5 0.5 0.5
map_Kd textures\wall gone.png
MTL
cat >"$D/scene.json" <<'JSON'
{
  "pmtk_scene": 1,
  "name": "mini-sponza",
  "meshes": [ { "file": "mini sponza.obj" } ],
  "camera": { "eye": [0, 1.5, -3.5], "look_at": [0, 0.5, 0], "fov_y": 60, "width": 64, "height": 48 },
  "point_lights": [ { "position": [0, 1.8, -0.5], "intensity": [3, 3, 3] } ],
  "render": { "photons": 50000, "spp": 4, "seed": 1 }
}
JSON
rm -f "$TMP/ms.pm"
expect_error "a missing texture: one line naming the material and the file" \
    "material 'plain_wall': map_Kd 'textures.wall gone.png': cannot open texture '.*mats/textures.wall gone.png'" \
    "$BIN/trace-photons" "$D/scene.json" -q -o "$TMP/ms.pm"
[ -e "$TMP/ms.pm" ] && fail "a refused scene writes nothing" "$TMP/ms.pm exists"
jq '. + {missing_textures: "magenta"}' "$D/scene.json" >"$D/magenta.json"
if "$BIN/scene-info" "$D/magenta.json" >"$TMP/ms.info" 2>"$TMP/ms.err" &&
    grep -q "^scene-info: warning: material 'plain_wall': map_Kd '.*wall gone.png' is missing: rendered magenta (missing_textures)$" "$TMP/ms.err" &&
    grep -q "warning: material 'arch_stone': map_Ka 'textures.floor tile.png' is not supported (ignored)" "$TMP/ms.err" &&
    [ "$(grep -c warning "$TMP/ms.err")" = 2 ]; then
    pass "missing_textures magenta: a warning for the missing file, map_Ka still reported, nothing else"
else
    fail "missing_textures magenta" "$(head -c 600 "$TMP/ms.err")"
fi
# scene-info lists each texture once (however many materials read it) with its size, channels
# and decoding, the materials and maps that read it, and the magenta stand-in as missing.
want="textures: 3
  0 '$D/mats/textures/floor tile.png' 2x2 rgb, 8-bit sRGB: map_Kd of arch_stone, map_Kd of leaf
  1 '$D/mats/textures/leaf mask.tga' 2x1 grey, 8-bit linear: map_d of leaf
  2 '$D/mats/textures\\wall gone.png' 1x1 rgb, float linear (missing: magenta): map_Kd of plain_wall
shading normals: no (no mesh has vertex normals)"
if [ "$(sed -n '/^textures: /,/^shading normals: /p' "$TMP/ms.info")" = "$want" ] &&
    "$BIN/scene-info" -q --json "$D/magenta.json" | jq -e '[.textures[] | [(.path | sub(".*/"; "")), .width, .height, .channels,
        .encoding, .colour_space, .missing, [.used_by[] | "\(.map) of \(.material)"]]] ==
        [["floor tile.png", 2, 2, "rgb", "8-bit", "srgb", false, ["map_Kd of arch_stone", "map_Kd of leaf"]],
         ["leaf mask.tga", 2, 1, "grey", "8-bit", "linear", false, ["map_d of leaf"]],
         ["textures\\wall gone.png", 1, 1, "rgb", "float", "linear", true, ["map_Kd of plain_wall"]]]
        and .shading_normals == {"in_use": false, "vertices": 0, "ignored": false}' >/dev/null; then
    pass "scene-info lists the textures, their users, a mask as linear and the missing one (text and --json)"
else
    fail "scene-info textures" "$(sed -n '/^textures: /,/^shading normals: /p' "$TMP/ms.info")"
fi
if BIN=$BIN pipelines/render "$D/magenta.json" "$TMP/ms-render" PHOTONS=50000 SPP=4 >"$TMP/ms.out" 2>"$TMP/ms.err" &&
    [ -s "$TMP/ms-render/image.png" ] && "$BUILD/tests/pm-exrdump" "$TMP/ms-render/image.exr" >"$TMP/ms.txt"; then
    # the wall is magenta (red and blue, no green) where it is lit; the floor's texture is warm
    if awk '$1 ~ /^[0-9]+$/ && NF == 5 { if ($3 > 0.01 && $5 > 0.01 && $4 < 0.02 * $3) mag++; if ($3 > 1.5 * $5 && $4 > 0.01) warm++; if ($3 != $3 || $4 != $4) nan++ }
        END { printf "%d magenta pixels, %d warm pixels\n", mag, warm; exit !(mag > 50 && warm > 50 && !nan) }' "$TMP/ms.txt" >"$TMP/why"; then
        pass "the Sponza-like scene renders through pipelines/render ($(cat "$TMP/why"))"
    else
        fail "Sponza-like render colours" "$(cat "$TMP/why")"
    fi
else
    fail "Sponza-like render" "$(tail -c 600 "$TMP/ms.err")"
fi
# that it ran is not enough: the same magenta wall and warm floor, and no NaN
if "$BIN/trace-reference" "$D/magenta.json" --spp 16 -q -o "$TMP/ms-ref.exr" 2>"$TMP/msr.err" &&
    "$BUILD/tests/pm-exrdump" "$TMP/ms-ref.exr" >"$TMP/ms-ref.txt" &&
    awk '$1 ~ /^[0-9]+$/ && NF == 5 { if ($3 > 0.01 && $5 > 0.01 && $4 < 0.02 * $3) mag++; if ($3 > 1.5 * $5 && $4 > 0.01) warm++; if ($3 != $3 || $4 != $4 || $5 != $5) nan++ }
        END { printf "%d magenta pixels, %d warm pixels\n", mag, warm; exit !(mag > 50 && warm > 50 && !nan) }' "$TMP/ms-ref.txt" >"$TMP/why"; then
    pass "the Sponza-like scene renders through trace-reference ($(cat "$TMP/why"))"
else
    fail "Sponza-like trace-reference" "$(cat "$TMP/why" 2>/dev/null) $(head -c 300 "$TMP/msr.err")"
fi

# ---- 4. a glossy textured material: the gathers evaluate the textured Kd and Ks
# A floor y = 0 (2 x 2 m) under a ceiling y = 1 (Kd 0.8), a point light between them, the camera
# just above the floor looking up at the ceiling: the ceiling's indirect light is what its
# secondary rays' queries on the floor gather. A glossy textured hit leaves two queries, its
# diffuse part folded into the weight and its lobe apart (docs/formats.md 3.3).
G=$TMP/gt
mkdir -p "$G"
png "$G/dark.png" $PNG_128
png "$G/mid.png" $PNG_188
printf 'mtllib gt.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl floor\nf 1/1 4/4 3/3 2/2\nusemtl ceiling\nf 5 6 7 8\n' >"$G/gt.obj"
printf 'newmtl floor\nKd 0.6 0.6 0.6\nKs 0.3 0.3 0.3\nNs 20\nmap_Kd dark.png\nmap_Ks mid.png\nnewmtl ceiling\nKd 0.8 0.8 0.8\n' >"$G/gt.mtl"
cat >"$G/scene.json" <<'JSON'
{
  "pmtk_scene": 1,
  "name": "glossy-textured",
  "meshes": [ { "file": "gt.obj" } ],
  "camera": { "eye": [0, 0.05, 0], "look_at": [0, 1, 0], "up": [0, 0, 1], "fov_y": 60, "width": 16, "height": 16 },
  "point_lights": [ { "position": [0, 0.5, 0], "intensity": [1, 1, 1] } ],
  "render": { "photons": 200000, "spp": 64, "seed": 1 }
}
JSON
if "$BIN/trace-photons" "$G/scene.json" -q -o - | "$BIN/build-photonmap" - -q -o "$G/map.pm" &&
    "$BIN/trace-gather-points" "$G/scene.json" -q -o "$G/q.pm" --direct "$G/d.pm" &&
    "$BIN/trace-reference" "$G/scene.json" -q --component indirect --spp 256 -o "$G/r.exr" --radiance "$G/r.pm"; then
    "$BIN/pm-info" --header "$G/q.pm" | grep -qx 'material.3=floor.lobe kd 0 0 0 ks 1 1 1 ns 20' &&
        "$BIN/pm-info" --header "$G/q.pm" | grep -qx 'material.2=folded kd 1 1 1 ks 0 0 0 ns 0' &&
        pass "glossy textured: the queries' table names the folded diffuse part and the floor's lobe" ||
        fail "glossy textured table" "$("$BIN/pm-info" --header "$G/q.pm" | grep material)"
    for g in simd-gather knn-gather reverse-gather; do
        if "$BIN/$g" "$G/map.pm" "$G/q.pm" -q -o "$G/i-$g.pm" && "$BIN/composite" "$G/i-$g.pm" -q -o "$G/i-$g.exr" &&
            m=$("$BIN/measure-error" "$G/i-$g.exr" "$G/r.pm" -q | jq -r '"\(.mean_test) \(.mean_reference)"') &&
            awk -v a="${m% *}" -v b="${m#* }" 'BEGIN { exit !(b > 0 && a / b > 0.95 && a / b < 1.05) }'; then
            pass "glossy textured floor through $g: indirect mean ${m% *} against trace-reference's ${m#* } (within 5%)"
        else
            fail "glossy textured floor through $g" "means '${m:-}' (test, reference) differ by more than 5%"
        fi
    done
else
    fail "glossy textured floor" "a stage failed"
fi
