# textures-embedded.sh: textures embedded in glTF 2 (issue 29 item 4): a .glb and a glTF with a
# data-URI image (Debian's assimp-testmodels, BoxTextured) read through assimp's embedded-texture
# API ("*0", aiScene::mTextures) and the same decoders as files; each renders byte-identical
# (pixels of image.exr) to the same model with its texture as an external PNG (the .gltf of
# BoxTextured-glTF beside the PNG taken out of the data URI). Before: "embedded texture '*0'"
# was reported and the box rendered untextured.
# programs: scene-info
M=/usr/share/assimp/models/glTF2
if [ ! -f "$M/BoxTextured-glTF-Binary/BoxTextured.glb" ]; then
    skip "embedded glTF textures" "assimp-testmodels is not installed (make deps)"
else
    mkdir -p "$TMP/ext"
    cp "$M/BoxTextured-glTF/BoxTextured.gltf" "$M/BoxTextured-glTF/BoxTextured0.bin" "$TMP/ext/"
    jq -r '.images[0].uri' "$M/BoxTextured-glTF-Embedded/BoxTextured.gltf" | sed 's/^data:[^,]*,//' |
        base64 -d >"$TMP/ext/CesiumLogoFlat.png"
    # box MODEL NAME: a scene of MODEL (a point light and a grey sky), rendered into $TMP/NAME
    box() {
        cat >"$TMP/$2.json" <<JSON
{ "pmtk_scene": 1, "name": "box", "meshes": [ { "file": "$1" } ],
  "camera": { "eye": [1.5, 1.2, 2.0], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40, "width": 32, "height": 32 },
  "point_lights": [ { "position": [2, 3, 3], "intensity": [10, 10, 10] } ], "sky": { "radiance": [0.2, 0.2, 0.2] },
  "render": { "photons": 2000, "spp": 4 } }
JSON
        PATH="$BIN:$PATH" pipelines/render "$TMP/$2.json" "$TMP/$2" >/dev/null 2>"$TMP/$2.err" &&
            "$BUILD/tests/pm-exrdump" "$TMP/$2/image.exr" >"$TMP/$2.txt"
    }
    if box "$TMP/ext/BoxTextured.gltf" ext && box "$M/BoxTextured-glTF-Binary/BoxTextured.glb" glb &&
        box "$M/BoxTextured-glTF-Embedded/BoxTextured.gltf" uri; then
        expect_same "a .glb renders byte-identical to its external-texture glTF" "$TMP/ext.txt" "$TMP/glb.txt"
        expect_same "a data-URI glTF renders byte-identical to its external-texture glTF" "$TMP/ext.txt" "$TMP/uri.txt"
        # the texture shows: the lit faces hold more than a handful of distinct colours
        n=$(awk 'NR > 1 { print $3, $4, $5 }' "$TMP/glb.txt" | sort -u | wc -l)
        if [ "$n" -gt 100 ]; then pass "the .glb's texture shows ($n distinct pixels)"; else fail "the .glb's texture shows" "$n distinct pixels"; fi
        "$BIN/scene-info" -q "$TMP/glb.json" >"$TMP/glb.info" 2>&1
        if grep -q "BoxTextured.glb:\*0' 211x211 rgb, 8-bit sRGB: map_Kd of Texture" "$TMP/glb.info" &&
            ! grep -q "embedded texture" "$TMP/glb.info"; then
            pass "scene-info lists the embedded texture as FILE:*0"
        else
            fail "scene-info lists the embedded texture" "$(head -c 400 "$TMP/glb.info")"
        fi
    else
        fail "embedded glTF textures render" "$(cat "$TMP"/*.err | head -c 400)"
    fi
    # an embedded image gets the checks of a file: a BMP behind image/png, a PNG declaring
    # 30000 x 30000 (refused against the budget)
    # embed NAME HEX-BYTES: the data-URI glTF with its image replaced, and its scene
    embed() {
        mkdir -p "$TMP/$1"
        cp "$M/BoxTextured-glTF-Embedded/BoxTextured.gltf" "$TMP/$1/in.gltf"
        printf "$(echo "$2" | sed 's/../\\x&/g')" >"$TMP/$1/img"
        jq --arg uri "data:image/png;base64,$(base64 -w0 "$TMP/$1/img")" ".images[0].uri = \$uri" \
            "$TMP/$1/in.gltf" >"$TMP/$1/box.gltf"
        sed "s|\"file\": \"[^\"]*\"|\"file\": \"$TMP/$1/box.gltf\"|" "$TMP/ext.json" >"$TMP/$1/scene.json"
    }
    embed bmp 424d3a000000000000003600000028000000010000000100000001001800000000000400000000000000000000000000000000000000ffffff00
    expect_error "an embedded BMP behind image/png" "texture '.*box\.gltf:\*0': a BMP image named as PNG" \
        "$BIN/scene-info" -q "$TMP/bmp/scene.json"
    embed huge 89504e470d0a1a0a0000000d4948445200007530000075300802000000e9456fed0000000049444154""35af061e
    expect_error "an embedded PNG of 30000 x 30000" \
        "texture '.*box\.gltf:\*0': 30000 x 30000 pixels would take 3433\.2 MiB decoded, above its budget" \
        "$BIN/scene-info" -q "$TMP/huge/scene.json"
fi
