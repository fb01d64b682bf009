# texture-transform.sh: glTF KHR_texture_transform (issue 28 item 5, issue 29 item 4), as assimp
# 5.2 gives it ($tex.uvtrafo): BoxTextured (Debian's assimp-testmodels) with a transform on its
# base colour renders byte-identical (pixels of image.exr) to the same box whose TEXCOORD_0 holds
# the transformed coordinates (u' = T R S u, computed here from the extension's own definition),
# and the transform is part of the scene's identity. A texCoord other than 0 is reported, not
# dropped; a textured OBJ is not touched. Before: the transform was dropped without a word.
# (The rotation's direction was checked on Khronos's TextureTransformTest sample of the same
# package: every arrow points at its green marker.)
# programs: scene-info
M=/usr/share/assimp/models/glTF2/BoxTextured-glTF
if [ ! -f "$M/BoxTextured.gltf" ]; then
    skip "glTF texture transforms" "assimp-testmodels is not installed (make deps)"
else
    for d in plain xf baked tc; do
        mkdir -p "$TMP/uvx-$d"
        cp "$M/BoxTextured.gltf" "$M/BoxTextured0.bin" "$M/CesiumLogoFlat.png" "$TMP/uvx-$d/"
    done
    # offset (0.25, 0.5), scale (2, -1): exact in floats, so the two paths round alike
    jq '.extensionsUsed = ["KHR_texture_transform"] |
        .materials[0].pbrMetallicRoughness.baseColorTexture.extensions =
        {"KHR_texture_transform": {"offset": [0.25, 0.5], "scale": [2, -1]}}' \
        "$M/BoxTextured.gltf" >"$TMP/uvx-xf/BoxTextured.gltf"
    jq '.materials[0].pbrMetallicRoughness.baseColorTexture.texCoord = 1' \
        "$M/BoxTextured.gltf" >"$TMP/uvx-tc/BoxTextured.gltf"
    # the reference: TEXCOORD_0 rewritten in the .bin by the extension's matrix
    python3 - "$TMP/uvx-baked" <<'PY'
import json, math, struct, sys
d = sys.argv[1]
g = json.load(open(d + "/BoxTextured.gltf"))
a = g["accessors"][g["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]]
v = g["bufferViews"][a["bufferView"]]
b = bytearray(open(d + "/BoxTextured0.bin", "rb").read())
off, stride = v.get("byteOffset", 0) + a.get("byteOffset", 0), v.get("byteStride", 8)
o, r, s = (0.25, 0.5), 0.0, (2.0, -1.0)
for i in range(a["count"]):
    u, w = struct.unpack_from("<2f", b, off + i * stride)
    x, y = s[0] * u, s[1] * w  # S, then R (u' = cos u + sin v, v' = -sin u + cos v), then T
    x, y = math.cos(r) * x + math.sin(r) * y + o[0], -math.sin(r) * x + math.cos(r) * y + o[1]
    struct.pack_into("<2f", b, off + i * stride, x, y)
open(d + "/BoxTextured0.bin", "wb").write(b)
PY
    # box NAME: a scene of $TMP/uvx-NAME's box, rendered into $TMP/uvx-NAME/out
    box() {
        cat >"$TMP/uvx-$1/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "box", "meshes": [ { "file": "$TMP/uvx-$1/BoxTextured.gltf" } ],
  "camera": { "eye": [1.5, 1.2, 2.0], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40, "width": 32, "height": 32 },
  "point_lights": [ { "position": [2, 3, 3], "intensity": [10, 10, 10] } ], "sky": { "radiance": [0.2, 0.2, 0.2] },
  "render": { "photons": 2000, "spp": 4 } }
JSON
        PATH="$BIN:$PATH" pipelines/render "$TMP/uvx-$1/scene.json" "$TMP/uvx-$1/out" >/dev/null 2>"$TMP/uvx-$1.err" &&
            "$BUILD/tests/pm-exrdump" "$TMP/uvx-$1/out/image.exr" >"$TMP/uvx-$1.txt"
    }
    if box plain && box xf && box baked; then
        expect_same "a KHR_texture_transform renders byte-identical to its transformed coordinates" \
            "$TMP/uvx-xf.txt" "$TMP/uvx-baked.txt"
        if cmp -s "$TMP/uvx-xf.txt" "$TMP/uvx-plain.txt"; then
            fail "the transform changes the image" "the same pixels as without it"
        else
            pass "the transform changes the image"
        fi
    else
        fail "glTF texture transforms render" "$(cat "$TMP"/uvx-*.err | head -c 400)"
    fi
    # the geometry part (the full hash covers the scene file, whose mesh path differs here)
    hash() { "$BIN/scene-info" -q "$TMP/uvx-$1/scene.json" 2>/dev/null | sed -n 's/^hash parts: geometry \(xxh3:[0-9a-f]*\).*/\1/p'; }
    hp=$(hash plain) hx=$(hash xf) hb=$(hash baked)
    if [ -n "$hp" ] && [ "$hx" != "$hp" ] && [ "$hx" = "$hb" ]; then
        pass "the transform is part of the scene hash (geometry $hx as the transformed coordinates, untransformed $hp)"
    else
        fail "the transform is part of the scene hash" "plain '$hp' transformed '$hx' baked '$hb'"
    fi
    sed "s|uvx-plain|uvx-tc|" "$TMP/uvx-plain/scene.json" >"$TMP/uvx-tc/scene.json"
    "$BIN/scene-info" -q "$TMP/uvx-tc/scene.json" >"$TMP/uvx-tc.info" 2>&1
    if grep -qi "texCoord 1 on the diffuse texture (set 0 used)" "$TMP/uvx-tc.info"; then
        pass "a texCoord other than 0 is reported"
    else
        fail "a texCoord other than 0 is reported" "$(head -c 400 "$TMP/uvx-tc.info")"
    fi
    if "$BIN/scene-info" -q "$TMP/uvx-xf/scene.json" 2>&1 | grep -qi "transform"; then
        fail "an honoured transform is not reported as unsupported" "scene-info mentions it"
    else
        pass "an honoured transform is not reported as unsupported"
    fi
    # an OBJ: MTL's -o/-s stay reported and unapplied, its coordinates as they were
    mkdir -p "$TMP/uvx-obj"
    cp "$M/CesiumLogoFlat.png" "$TMP/uvx-obj/tex.png"
    printf 'mtllib q.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 4/4 3/3 2/2\n' \
        >"$TMP/uvx-obj/q.obj"
    for o in plain opts; do
        mkdir -p "$TMP/uvx-$o-obj"
        cp "$TMP/uvx-obj/q.obj" "$TMP/uvx-obj/tex.png" "$TMP/uvx-$o-obj/"
        opt=$([ $o = opts ] && echo "-o 0.5 0.5 0 -s 2 2 1 ")
        printf 'newmtl m\nKd 1 1 1\nmap_Kd %stex.png\n' "$opt" >"$TMP/uvx-$o-obj/q.mtl"
        sed "s|$TMP/uvx-plain/BoxTextured.gltf|$TMP/uvx-$o-obj/q.obj|" "$TMP/uvx-plain/scene.json" \
            >"$TMP/uvx-$o-obj/scene.json"
    done
    "$BIN/scene-info" -q "$TMP/uvx-opts-obj/scene.json" >"$TMP/uvx-obj.info" 2>&1
    if [ -n "$(hash plain-obj)" ] && [ "$(hash plain-obj)" = "$(hash opts-obj)" ] &&
        grep -q "unsupported (ignored): map_Kd options -o 0.5 0.5 0 -s 2 2 1 tex.png" "$TMP/uvx-obj.info" &&
        ! grep -qi "transform" "$TMP/uvx-obj.info"; then
        pass "an OBJ's map_Kd -o/-s: reported as before, its coordinates untouched"
    else
        fail "an OBJ's map_Kd -o/-s untouched" "$(hash plain-obj) $(hash opts-obj) $(head -c 300 "$TMP/uvx-obj.info")"
    fi
fi
