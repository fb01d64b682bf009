# assets.sh: what the scene file says about its assets (issue 29; docs/scene-format.md,
# "Materials in the scene file", "Shapes", "Cameras and lights from the asset"):
#   1. An emissive rectangle (a shape, 1 x 0.6 m, radiance L) 0.5 m above a floor whose asset
#      material is overridden by a scene material of albedo KD: the floor's radiance at the point
#      under the centre is KD / pi * E, E = 2 L [X / sqrt(1 + X^2) atan(Y / sqrt(1 + X^2)) + Y /
#      sqrt(1 + Y^2) atan(X / sqrt(1 + Y^2))], X = 0.5 / 0.5, Y = 0.3 / 0.5 (four corner
#      rectangles' form factors), through trace-gather-points' direct buffer and trace-reference
#      (a 1-degree camera looking straight down at that point: every pixel within 4.4 mm of it).
#      Turned to face up it lights nothing (exactly 0); face up and two-sided, the same E again,
#      through the direct buffer and the photon map.
#   2. The power of area lights made of shapes (scene-info): a sphere pi L 4 pi r^2, a two-sided
#      disk 2 pi L pi r^2, exact to float rounding though both are tessellated.
#   3. A glTF file (written here, its buffer a data URI) with a camera and KHR_lights_punctual
#      lights: the camera as the file places it (node rotation and translation, yfov 0.6 rad);
#      a point light of 683 cd is 1 W/sr, a spot of inner angle 0 is a falloff-2 spot; a
#      directional light of 683 lux straight down lights the file's floor (the default grey,
#      0.8) with E = 1 W/m^2: radiance 0.8 / pi.
#   4. Models of assimp-testmodels, unedited, rendered small (OBJ with Kd + Ks > 1, without
#      materials, with a usemtl and no mtllib; PLY, glTF, glb, Collada), the image finite; scene-info says what was scaled (Kd + Ks), filled in and overridden.
#   5. Bad input: one line naming the key and the value, exit 1.
# programs: scene-info trace-gather-points composite trace-reference trace-photons build-photonmap simd-gather pipelines/render
PI=3.141592653589793
MODELS=/usr/share/assimp/models

# mean_of EXR-TXT: the mean of every channel of every pixel of a pm-exrdump listing, and the
# number of values that are not finite numbers.
mean_of() {
    awk '$1 == "size" { next } { for (c = 3; c <= 5; c++) { if ($c !~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/) bad++; s += $c; n++ } }
        END { printf "%.9g %d\n", n ? s / n : 0, bad + 0 }' "$1"
}

# within NAME GOT WANT TOL: |GOT / WANT - 1| <= TOL.
within() {
    if awk -v g="$2" -v w="$3" -v t="$4" 'BEGIN { r = g / w - 1; exit !(r * r <= t * t) }'; then
        pass "$1 ($2, expected $3)"
    else
        fail "$1" "$2, expected $3 within $4"
    fi
}

# direct_mean SCENE NAME: the mean radiance of the direct buffer's image (light_samples from the scene).
direct_mean() {
    "$BIN/trace-gather-points" "$1" --pixel center --mode direct-vis -q -o "$TMP/$2.q.pm" --direct "$TMP/$2.d.pm" &&
        "$BIN/composite" "$TMP/$2.d.pm" -q -o "$TMP/$2.d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/$2.d.exr" >"$TMP/$2.d.txt" &&
        mean_of "$TMP/$2.d.txt"
}

# ---- 1. an emissive rectangle over an overridden floor
mkdir -p "$TMP/rect"
printf 'mtllib floor.mtl\nv -3 0 3\nv 3 0 3\nv 3 0 -3\nv -3 0 -3\nusemtl floor\nf 1 2 3 4\n' >"$TMP/rect/floor.obj"
printf 'newmtl floor\nKd 0.9 0.9 0.9\n' >"$TMP/rect/floor.mtl"
# rect_scene FILE DEGREES TWO-SIDED: the floor, the rectangle turned about x (90: facing down).
rect_scene() {
    cat >"$1" <<JSON
{
  "pmtk_scene": 1, "name": "rect-light",
  "materials": { "grey": { "kind": "diffuse", "kd": [0.5, 0.5, 0.5] }, "black": { "kind": "diffuse", "kd": [0, 0, 0] } },
  "meshes": [ { "file": "floor.obj", "materials": { "floor": "grey" } } ],
  "shapes": [ { "type": "rectangle", "size": [1, 0.6], "rotate": { "axis": [1, 0, 0], "degrees": $2 },
                "translate": [0, 0.5, 0], "material": "black", "emission": { "radiance": [4, 4, 4], "two_sided": $3 } } ],
  "camera": { "eye": [0, 0.25, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 1, "width": 8, "height": 8 },
  "render": { "photons": 400000, "spp": 4, "light_samples": 256, "seed": 1 }
}
JSON
}
RECT_E=$(awk 'BEGIN { X = 1; Y = 0.6; a = sqrt(1 + X * X); b = sqrt(1 + Y * Y); print 2 * 4 * (X / a * atan2(Y, a) + Y / b * atan2(X, b)) }')
RECT_L=$(awk -v e="$RECT_E" -v p=$PI 'BEGIN { print 0.5 / p * e }')
rect_scene "$TMP/rect/down.json" 90 false
if got=$(direct_mean "$TMP/rect/down.json" down); then
    within "rectangle light facing down: direct buffer = kd / pi E, E = $RECT_E W/m^2" "${got% *}" "$RECT_L" 0.02
    [ "${got#* }" = 0 ] && pass "... every value finite" || fail "rectangle values" "${got#* } not finite"
else
    fail "rectangle light facing down" "a stage failed"
fi
if "$BIN/trace-reference" "$TMP/rect/down.json" -q --pixel center --spp 64 -o "$TMP/down.r.exr" &&
    "$BUILD/tests/pm-exrdump" "$TMP/down.r.exr" >"$TMP/down.r.txt"; then
    got=$(mean_of "$TMP/down.r.txt")
    within "rectangle light facing down: trace-reference" "${got% *}" "$RECT_L" 0.03
else
    fail "rectangle light, trace-reference" "it failed"
fi
rect_scene "$TMP/rect/up.json" -90 false
if got=$(direct_mean "$TMP/rect/up.json" up) && [ "${got% *}" = 0 ]; then
    pass "one-sided rectangle facing away lights nothing"
else
    fail "one-sided rectangle facing away" "mean ${got:-?}"
fi
rect_scene "$TMP/rect/two.json" -90 true
if got=$(direct_mean "$TMP/rect/two.json" two); then
    within "two-sided rectangle facing away: its back face lights the floor, direct buffer" "${got% *}" "$RECT_L" 0.02
else
    fail "two-sided rectangle" "a stage failed"
fi
# every pixel's kernel holds nearly the same photons (the pixels lie within 4.4 mm): k = 2000 of
# 1e6 photons (a 3 cm kernel, 2% noise; measured within 1.5% at 2e6)
if "$BIN/trace-photons" "$TMP/rect/two.json" --photons 1000000 -q -o - | "$BIN/build-photonmap" - -q -o "$TMP/two.map.pm" &&
    "$BIN/simd-gather" "$TMP/two.map.pm" "$TMP/two.q.pm" --k 2000 -q -o "$TMP/two.i.pm" &&
    "$BIN/composite" "$TMP/two.i.pm" -q -o "$TMP/two.i.exr" && "$BUILD/tests/pm-exrdump" "$TMP/two.i.exr" >"$TMP/two.i.txt"; then
    got=$(mean_of "$TMP/two.i.txt")
    within "two-sided rectangle facing away: photon map" "${got% *}" "$RECT_L" 0.05
else
    fail "two-sided rectangle, photon map" "a stage failed"
fi
"$BIN/scene-info" "$TMP/rect/down.json" >"$TMP/rect.info" 2>"$TMP/rect.err"
grep -q "^note: meshes\[0\] 'floor.obj': material 'floor' replaced by scene material 'grey'" "$TMP/rect.info" &&
    grep -q "^  0 grey kd 0.5 0.5 0.5 " "$TMP/rect.info" &&
    pass "scene-info says the floor's material was overridden" ||
    fail "scene-info override note" "$(grep -E 'note|grey' "$TMP/rect.info" | head -3)"
"$BIN/scene-info" --json "$TMP/rect/down.json" 2>/dev/null | jq -e '.notes == [{"changed": false, "text": "meshes[0] '"'"'floor.obj'"'"': material '"'"'floor'"'"' replaced by scene material '"'"'grey'"'"'"}]' >/dev/null &&
    pass "... and --json lists it under notes" || fail "scene-info --json notes" "$("$BIN/scene-info" --json "$TMP/rect/down.json" 2>/dev/null | jq -c .notes)"

# an asset material pmtk would refuse (glass of index -1, a missing texture) is not read when the
# scene file replaces it
printf 'mtllib broken.mtl\nv -3 0 3\nv 3 0 3\nv 3 0 -3\nusemtl bad glass\nf 1 2 3\n' >"$TMP/rect/broken.obj"
printf 'newmtl bad glass\nillum 7\nNi -1\nmap_Kd gone.png\n' >"$TMP/rect/broken.mtl"
sed 's/"file": "floor.obj", "materials": { "floor": "grey" }/"file": "broken.obj"/' "$TMP/rect/down.json" >"$TMP/rect/broken.json"
expect_error "an asset material with glass of index -1 is refused as it stands" "material 'bad_glass': Ni -1 must be a finite number > 0" \
    "$BIN/scene-info" "$TMP/rect/broken.json"
sed 's/"file": "floor.obj", "materials": { "floor": "grey" }/"file": "broken.obj", "materials": { "bad glass": "grey" }/' \
    "$TMP/rect/down.json" >"$TMP/rect/fixed.json"
"$BIN/scene-info" "$TMP/rect/fixed.json" >"$TMP/fixed.info" 2>"$TMP/fixed.err" && grep -q "^  0 grey kd 0.5 0.5 0.5 " "$TMP/fixed.info" &&
    pass "... and loads when the scene file replaces it (its texture not looked for)" ||
    fail "an overridden broken asset material" "$(head -c 300 "$TMP/fixed.err")"

# ---- 2. the power of tessellated shape lights
cat >"$TMP/power.json" <<JSON
{ "pmtk_scene": 1, "name": "shape-power",
  "shapes": [ { "type": "sphere", "radius": 0.2, "segments": 16, "emission": { "radiance": [3, 3, 3] } } ],
  "camera": { "eye": [0, 0, 3], "look_at": [0, 0, 0], "fov_y": 40, "width": 8, "height": 8 } }
JSON
p=$("$BIN/scene-info" -q "$TMP/power.json" | awk '/^emitted power:/ { print $3 }')
within "a sphere light of 16 x 8 facets has the sphere's power pi L 4 pi r^2" "$p" "$(awk -v p=$PI 'BEGIN { print p * 3 * 4 * p * 0.04 }')" 1e-5
sed 's/"sphere", "radius": 0.2, "segments": 16, "emission": { "radiance": \[3, 3, 3\] }/"disk", "radius": 0.3, "segments": 7, "emission": { "radiance": [2, 2, 2], "two_sided": true }/' \
    "$TMP/power.json" >"$TMP/disk.json"
p=$("$BIN/scene-info" -q "$TMP/disk.json" | awk '/^emitted power:/ { print $3 }')
within "a two-sided disk light of 7 facets has the disk's power 2 pi L pi r^2" "$p" "$(awk -v p=$PI 'BEGIN { print 2 * p * 2 * p * 0.09 }')" 1e-5

# ---- 3. a glTF camera and KHR_lights_punctual lights
mkdir -p "$TMP/gl"
# a 4 x 4 m floor at y = 0 facing up: 6 uint16 indices, then 4 float positions (made once)
BUF=AAABAAIAAAACAAMAAAAAwAAAAAAAAABAAAAAQAAAAAAAAABAAAAAQAAAAAAAAADAAAAAwAAAAAAAAADA
cat >"$TMP/gl/lit.gltf" <<JSON
{ "asset": { "version": "2.0" }, "scene": 0, "scenes": [ { "nodes": [0, 1, 2, 3, 4] } ],
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": { "KHR_lights_punctual": { "lights": [
    { "type": "directional", "intensity": 683 },
    { "type": "point", "intensity": 683, "color": [1, 0.5, 0.25] },
    { "type": "spot", "intensity": 1366, "spot": { "innerConeAngle": 0, "outerConeAngle": 0.5 } } ] } },
  "nodes": [ { "mesh": 0 },
    { "rotation": [-0.7071068, 0, 0, 0.7071068], "extensions": { "KHR_lights_punctual": { "light": 0 } } },
    { "translation": [0, 30, 0], "extensions": { "KHR_lights_punctual": { "light": 1 } } },
    { "translation": [1, 30, 0], "extensions": { "KHR_lights_punctual": { "light": 2 } } },
    { "name": "top", "translation": [0, 1, 0], "rotation": [-0.7071068, 0, 0, 0.7071068], "camera": 0 } ],
  "cameras": [ { "type": "perspective", "perspective": { "aspectRatio": 1.0, "yfov": 0.6, "znear": 0.01 } } ],
  "meshes": [ { "primitives": [ { "attributes": { "POSITION": 1 }, "indices": 0 } ] } ],
  "buffers": [ { "byteLength": 60, "uri": "data:application/octet-stream;base64,$BUF" } ],
  "bufferViews": [ { "buffer": 0, "byteOffset": 0, "byteLength": 12 }, { "buffer": 0, "byteOffset": 12, "byteLength": 48 } ],
  "accessors": [ { "bufferView": 0, "componentType": 5123, "count": 6, "type": "SCALAR" },
    { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-2, 0, -2], "max": [2, 0, 2] } ] }
JSON
cat >"$TMP/gl/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "gltf-lights",
  "meshes": [ { "file": "lit.gltf", "lights": true } ],
  "camera": { "mesh": 0, "name": "top", "width": 8, "height": 8 },
  "render": { "spp": 4, "light_samples": 4 } }
JSON
if "$BIN/scene-info" "$TMP/gl/scene.json" >"$TMP/gl.info" 2>"$TMP/gl.err"; then
    awk '/^camera:/ { ok = $3 == 0 && $4 == 1 && $5 == 0 && $7 == 0 && $8 == 0 && $9 * $9 < 1e-10 && $11 == 34.3775 } END { exit !ok }' "$TMP/gl.info" &&
        pass "the glTF camera chosen by name: its node's place and turn, yfov 0.6 rad" ||
        fail "glTF camera" "$(grep '^camera' "$TMP/gl.info")"
    grep -q '^  light 0 at 0 30 0 intensity 1 0.5 0.25 W/sr$' "$TMP/gl.info" &&
        pass "a glTF point light of 683 cd is 1 W/sr (683 lm/W), placed by its node" ||
        fail "glTF point light" "$(grep 'light 0' "$TMP/gl.info")"
    grep -q '^  light 1 at 1 30 0 intensity 2 2 2 W/sr spot toward 0 0 -1 cone 28.6479 deg falloff 2$' "$TMP/gl.info" &&
        pass "a glTF spot of inner angle 0 is a falloff-2 spot of its outer angle" ||
        fail "glTF spot" "$(grep 'light 1' "$TMP/gl.info")"
    grep -q "^note: meshes\[0\] 'lit.gltf': directional light '.*' is the sun, 1 W/m^2" "$TMP/gl.info" &&
        pass "scene-info says the directional light became the sun" || fail "sun note" "$(grep -i sun "$TMP/gl.info")"
else
    fail "glTF camera and lights" "$(head -c 300 "$TMP/gl.err")"
fi
# the sun alone over the floor: drop the point and spot nodes
sed 's/"nodes": \[0, 1, 2, 3, 4\]/"nodes": [0, 1, 4]/' "$TMP/gl/lit.gltf" >"$TMP/gl/sun.gltf"
sed 's/lit.gltf/sun.gltf/' "$TMP/gl/scene.json" >"$TMP/gl/sun.json"
if got=$(direct_mean "$TMP/gl/sun.json" glsun); then
    within "a directional light of 683 lux: E = 1 W/m^2 on the default grey floor, radiance 0.8 / pi" "${got% *}" \
        "$(awk -v p=$PI 'BEGIN { print 0.8 / p }')" 1e-3
else
    fail "glTF directional light" "a stage failed"
fi
sed 's/"top"/"side"/' "$TMP/gl/scene.json" >"$TMP/gl/side.json"
expect_error "a camera name the file lacks is named with the ones it has" \
    "camera.name: meshes\[0\] has no camera 'side' \(it has: top\)" "$BIN/scene-info" "$TMP/gl/side.json"
sed 's/"lights": true/"lights": false/' "$TMP/gl/scene.json" >"$TMP/gl/nol.json"
"$BIN/scene-info" "$TMP/gl/nol.json" >"$TMP/gl.nol" 2>&1
grep -q "note: meshes\[0\] 'lit.gltf' holds 3 lights, not read (\"lights\": true reads them)" "$TMP/gl.nol" &&
    pass "a file's lights the scene does not read are noted" || fail "unread lights" "$(grep -i light "$TMP/gl.nol" | head -2)"

# ---- 4. assimp-testmodels, unedited
if [ ! -d "$MODELS" ]; then
    skip "assimp-testmodels" "$MODELS is missing (tests/install-deps.sh installs assimp-testmodels)"
else
    # render_model NAME FILE: a sky-lit 32 x 24 render framed by the model's bounds.
    render_model() {
        local d=$TMP/m-$1
        mkdir -p "$d"
        printf '{ "pmtk_scene": 1, "name": "%s", "meshes": [ { "file": "%s" } ], "sky": { "radiance": [1, 1, 1] },\n' "$1" "$2" >"$d/head"
        cat "$d/head" - >"$d/probe.json" <<JSON
  "camera": { "eye": [0, 0, 1], "look_at": [0, 0, 0], "fov_y": 40, "width": 32, "height": 24 } }
JSON
        local cam
        cam=$("$BIN/scene-info" -q "$d/probe.json" | awk '/^bounds:/ {
            cx = ($2 + $5) / 2; cy = ($3 + $6) / 2; cz = ($4 + $7) / 2
            r = sqrt(($5 - $2) ^ 2 + ($6 - $3) ^ 2 + ($7 - $4) ^ 2) / 2
            printf "\"eye\": [%g, %g, %g], \"look_at\": [%g, %g, %g]", cx + 1.2 * r, cy + 1.5 * r, cz + 2.5 * r, cx, cy, cz }')
        if [ -z "$cam" ]; then
            fail "$1: $2 loads" "$("$BIN/scene-info" -q "$d/probe.json" 2>&1 | head -c 300)"
            return
        fi
        cat "$d/head" - >"$d/scene.json" <<JSON
  "camera": { $cam, "fov_y": 40, "width": 32, "height": 24 },
  "render": { "photons": 20000, "spp": 4 } }
JSON
        if "$ROOT/pipelines/render" "$d/scene.json" "$d/out" >"$d/log" 2>&1 && "$BUILD/tests/pm-exrdump" "$d/out/image.exr" >"$d/img.txt"; then
            local got
            got=$(mean_of "$d/img.txt")
            if [ "${got#* }" = 0 ] && awk -v m="${got% *}" 'BEGIN { exit !(m > 0) }'; then
                pass "$1: $2 renders, unedited (mean ${got% *})"
            else
                fail "$1: $2" "image mean ${got% *}, ${got#* } values not finite"
            fi
        else
            fail "$1: $2 renders" "$(tail -n 3 "$d/log" | head -c 300)"
        fi
    }
    ROOT=$PWD
    render_model obj-kdks "$MODELS/OBJ/box_mat_with_spaces.obj"
    render_model obj-nomtl "$MODELS/OBJ/WusonOBJ.obj"
    render_model obj-usemtl-nolib "$MODELS/OBJ/box.obj"
    render_model ply "$MODELS/PLY/cube_uv.ply"
    render_model gltf "$MODELS/glTF2/BoxTextured-glTF/BoxTextured.gltf"
    render_model glb "$MODELS/glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"
    render_model gltf-specgloss "$MODELS/glTF2/BoxTextured-glTF-pbrSpecularGlossiness/BoxTextured.gltf"
    render_model collada "$MODELS/Collada/duck.dae"
    "$BIN/scene-info" "$TMP/m-obj-kdks/scene.json" >"$TMP/kdks.info" 2>"$TMP/kdks.err"
    grep -q "Kd + Ks 1.1 (channel r) (approximated: Kd and Ks scaled by 0.909091 so that they sum to 1)" "$TMP/kdks.info" &&
        [ "$(grep -c "Kd + Ks 1.1 (channel r) is approximated: Kd and Ks scaled by 0.909091" "$TMP/kdks.err")" = 1 ] &&
        pass "Kd + Ks = 1.1 is scaled by 1 / 1.1: scene-info lists it, and warns once" ||
        fail "Kd + Ks scaling report" "$(grep -i 'kd + ks' "$TMP/kdks.info" "$TMP/kdks.err" | head -3)"
    # the duck's textured material replaced: its texture is neither read nor listed
    sed 's|"meshes": \[ { "file": "\([^"]*\)" } \]|"materials": { "g": { "kind": "diffuse" } }, "meshes": [ { "file": "\1", "material": "g" } ]|' \
        "$TMP/m-collada/scene.json" >"$TMP/m-collada/over.json"
    "$BIN/scene-info" "$TMP/m-collada/over.json" >"$TMP/duck.info" 2>/dev/null
    grep -q "^textures: 0$" "$TMP/duck.info" && grep -q "^  0 g kd 0.8 0.8 0.8 " "$TMP/duck.info" &&
        pass "a textured asset material replaced by a scene material leaves no texture behind" ||
        fail "replaced texture" "$(grep -E '^textures|^  0' "$TMP/duck.info" | head -3)"
    "$BIN/scene-info" "$TMP/m-obj-nomtl/scene.json" >"$TMP/nomtl.info" 2>/dev/null
    grep -q "^note: mesh '.*WusonOBJ.obj' names no material: its faces are the default grey (Kd 0.8)$" "$TMP/nomtl.info" &&
        grep -q "^  0 default kd 0.8 0.8 0.8 ks 0 0 0 " "$TMP/nomtl.info" &&
        pass "an OBJ without materials is the default grey, and scene-info says so" ||
        fail "OBJ without materials" "$(grep -E '^note|^  0' "$TMP/nomtl.info" | head -3)"
fi

# ---- 5. bad input
bad() {
    printf '{ "pmtk_scene": 1, "name": "bad", %s,\n  "camera": { "eye": [0, 0, 3], "look_at": [0, 0, 0], "fov_y": 40, "width": 8, "height": 8 } }\n' "$2" >"$TMP/rect/bad.json"
    expect_error "$1" "$3" "$BIN/scene-info" "$TMP/rect/bad.json"
}
bad "an unknown material kind" '"materials": { "m": { "kind": "velvet" } }' \
    "materials.m.kind: 'velvet' is not a kind \(known: diffuse, phong, mirror"
bad "a key the kind does not take" '"materials": { "m": { "kind": "mirror", "kd": [1, 1, 1] } }' \
    "materials.m: unknown key 'kd' \(known: kind, reflectance\)"
bad "a phong material with kd + ks above 1" '"materials": { "m": { "kind": "phong", "kd": [0.8, 0.5, 0.5], "ks": [0.3, 0.3, 0.3] } }' \
    "materials.m: kd \+ ks = 1.1 in channel r exceeds 1"
bad "a glass index out of range" '"materials": { "m": { "kind": "glass", "ior": -1 } }' "materials.m.ior: -1 is outside"
bad "a mesh naming a scene material that does not exist" '"materials": { "g": { "kind": "glass" } }, "meshes": [ { "file": "floor.obj", "material": "glas" } ]' \
    "meshes\[0\].material: 'glas' is not in the scene's materials \(g\)"
bad "a materials map naming an asset material the mesh lacks" '"materials": { "g": { "kind": "glass" } }, "meshes": [ { "file": "floor.obj", "materials": { "flor": "g" } } ]' \
    "meshes\[0\].materials.flor: mesh 'floor.obj' has no material 'flor' \(it has: default, floor\)"
bad "an unknown shape" '"shapes": [ { "type": "torus" } ]' "shapes\[0\].type: 'torus' is not a shape \(known: rectangle, disk, sphere, box\)"
bad "a shape's key of another type" '"shapes": [ { "type": "sphere", "size": [1, 1, 1] } ]' "shapes\[0\]: a sphere has no 'size' \(it takes 'radius'\)"
bad "an emission without radiance" '"shapes": [ { "type": "disk", "emission": { "two_sided": true } } ]' "shapes\[0\].emission.radiance: missing"
bad "an emission key misspelt" '"shapes": [ { "type": "disk", "emission": { "radiance": [1, 1, 1], "twosided": true } } ]' \
    "shapes\[0\].emission: unknown key 'twosided'"
bad "a negative radiance" '"shapes": [ { "type": "box", "emission": { "radiance": [1, -1, 1] } } ]' \
    "shapes\[0\].emission.radiance: element 1 = -1 is outside"
