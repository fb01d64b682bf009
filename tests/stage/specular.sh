# specular.sh: mirrors and glass (issue 18): what the loader makes of MTL illum 3, 5 and 7, Ni
# and Tf, and of glTF transmission, ior, metallic and roughness; bad values fail with one line
# naming the material, the key and the value, and nothing is written.
# programs: scene-info trace-gather-points trace-photons trace-reference
D=$TMP/spec
mkdir -p "$D"
# one triangle per material, facing +y, side by side along x
spec_scene() { # spec_scene NAME MTL-TEXT MATERIAL...
    local name=$1 mtl=$2 i=0 obj="mtllib $1.mtl"$'\n'
    shift 2
    for m in "$@"; do
        obj+="v $i 0 0"$'\n'"v $((i + 1)) 0 1"$'\n'"v $((i + 1)) 0 0"$'\n'"usemtl $m"$'\n'
        obj+="f $((3 * i + 1)) $((3 * i + 2)) $((3 * i + 3))"$'\n'
        i=$((i + 1))
    done
    printf '%s' "$mtl" >"$D/$name.mtl"
    printf '%s' "$obj" >"$D/$name.obj"
    printf '{"pmtk_scene": 1, "name": "%s", "meshes": [{"file": "%s.obj"}],
 "camera": {"eye": [1, 2, 0.5], "look_at": [1, 0, 0.5], "up": [0, 0, 1], "fov_y": 60, "width": 8, "height": 8},
 "point_lights": [{"position": [1, 1, 0.5], "intensity": [1, 1, 1]}], "render": {"photons": 1000, "spp": 4}}\n' \
        "$name" "$name" >"$D/$name.json"
}

spec_scene ok 'newmtl glass
Kd 0 0 0
Ni 1.5
Tf 0.9 0.8 0.7
illum 7
newmtl mirror
Ks 0.9 0.8 0.7
illum 3
newmtl mirror5
Kd 0 0 0
Ks 1 1 1
illum 5
newmtl dull
Kd 0.5 0.5 0.5
illum 3
newmtl plain
Kd 0.5 0.5 0.5
illum 2
' glass mirror mirror5 dull plain
if "$BIN/scene-info" --json "$D/ok.json" >"$D/ok.out" 2>"$D/ok.err" && [ "$(grep -vc "material 'dull'" "$D/ok.err")" = 0 ]; then
    pass "MTL illum 7 and illum 3/5 with Ks load without a warning"
else
    fail "specular MTL loads" "$(head -c 400 "$D/ok.err")"
fi
# the summary as JSON: kind, reflectance, index and filter per material
jq_kind() {
    python3 -c "import json; d=json.load(open('$D/ok.out')); m=[x for x in d['materials'] if x['name']=='$1'][0]
v=m.get('$2'); v=v if isinstance(v, list) else [v]; print(m.get('kind'), ' '.join('%.4g' % x for x in v))"
}
check_field() { # check_field MATERIAL FIELD EXPECTED
    local got
    got=$(jq_kind "$1" "$2" 2>&1)
    [ "$got" = "$3" ] && pass "scene-info: $1 $2 is '$3'" || fail "scene-info: $1 $2" "got '$got', expected '$3'"
}
check_field glass ior "glass 1.5"
check_field glass tf "glass 0.9 0.8 0.7"
check_field mirror kr "mirror 0.9 0.8 0.7"
check_field mirror5 kr "mirror 1 1 1"
check_field plain kd "standard 0.5 0.5 0.5"
grep -q '"any_specular": true' "$D/ok.out" && pass "scene-info --json says any_specular" ||
    fail "any_specular" "$(head -c 300 "$D/ok.out")"
# illum 3 without Ks reflects nothing: it stays Lambertian, and its illum is reported
check_field dull kd "standard 0.5 0.5 0.5"
"$BIN/scene-info" "$D/ok.json" >"$D/ok.txt" 2>"$D/ok.err"
grep -q "warning: material 'dull': illum 3 is not supported" "$D/ok.err" && pass "illum 3 without Ks is reported" ||
    fail "illum 3 without Ks" "$(cat "$D/ok.err")"
grep -q '^specular: yes' "$D/ok.txt" && pass "scene-info says the scene has specular materials" ||
    fail "scene-info specular line" "$(cat "$D/ok.txt")"
"$BIN/scene-info" scenes/cornell-box/scene.json >"$D/cb.txt" 2>&1
grep -q '^specular: no' "$D/cb.txt" && pass "scene-info says the Cornell box has none" ||
    fail "scene-info specular line (cornell-box)" "$(cat "$D/cb.txt")"

# the parts of a specular material pmtk does not render are reported, not dropped
spec_scene extra 'newmtl g
Kd 0.3 0.3 0.3
Ks 0.5 0.5 0.5
Ni 1.33
illum 7
newmtl m
Kd 0.2 0.2 0.2
Ks 0.7 0.7 0.7
illum 5
' g m
"$BIN/scene-info" "$D/extra.json" >/dev/null 2>"$D/extra.err"
if grep -q "material 'g': Kd 0.3 0.3 0.3 is not supported" "$D/extra.err" &&
    grep -q "material 'g': Ks 0.5 0.5 0.5 is not supported" "$D/extra.err" &&
    grep -q "material 'm': Kd 0.2 0.2 0.2 is not supported" "$D/extra.err" &&
    ! grep -q "material 'm': Ks" "$D/extra.err" && ! grep -q "Ni\|illum" "$D/extra.err"; then
    pass "a glass's Kd and Ks and a mirror's Kd are reported; what makes them specular is not"
else
    fail "specular extras reported" "$(cat "$D/extra.err")"
fi

# bad values: one line naming the material, the key and the value; nothing written
bad_mtl() { # bad_mtl NAME PATTERN MTL-TEXT
    spec_scene "$1" "$3" x
    rm -f "$D/$1.pm"
    expect_error "$1: trace-photons refuses it" "material 'x': $2" "$BIN/trace-photons" "$D/$1.json" -o "$D/$1.pm"
    [ ! -e "$D/$1.pm" ] && pass "... and writes nothing" || fail "$1 output" "$D/$1.pm exists"
}
bad_mtl ni-negative "Ni -1 must be a finite number > 0" $'newmtl x\nNi -1\nillum 7\n'
bad_mtl ni-zero "Ni 0 must be a finite number > 0" $'newmtl x\nNi 0\nillum 7\n'
# nan is refused as it is read from the .mtl (mtl.c), before the material exists: its line
spec_scene ni-nan $'newmtl x\nNi nan\nillum 7\n' x
expect_error "ni-nan: trace-photons refuses it" "ni-nan.mtl' line 2: Ni 'nan' is not a plain decimal number" \
    "$BIN/trace-photons" "$D/ni-nan.json" -o "$D/ni-nan.pm"
[ ! -e "$D/ni-nan.pm" ] && pass "... and writes nothing" || fail "ni-nan output" "$D/ni-nan.pm exists"
bad_mtl ni-inf "Ni inf must be a finite number > 0" $'newmtl x\nNi 1e39\nillum 7\n'
bad_mtl tf-high "Tf 1.5 in channel r must lie in \[0, 1\]" $'newmtl x\nNi 1.5\nTf 1.5 1 1\nillum 7\n'
bad_mtl tf-negative "Tf -0.25 in channel b must lie in \[0, 1\]" $'newmtl x\nNi 1.5\nTf 1 1 -0.25\nillum 7\n'
expect_error "Ni 0 refused by trace-reference too" "material 'x': Ni 0 must be" \
    "$BIN/trace-reference" "$D/ni-zero.json" -o "$D/ni-zero.pm"

# glTF: transmission with ior is glass, metallic 1 roughness 0 a smooth conductor (F0 the base
# colour, alpha 0: the delta limit), both at once an error
gltf() { # gltf NAME MATERIAL-JSON
    printf '{"asset":{"version":"2.0"},"extensionsUsed":["KHR_materials_transmission","KHR_materials_ior"],"scenes":[{"nodes":[0]}],"scene":0,"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0}]}],"materials":[%s],
"buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/"}],
"bufferViews":[{"buffer":0,"byteLength":36}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}]}\n' "$2" >"$D/$1.gltf"
    sed "s/\"ok.obj\"/\"$1.gltf\"/" "$D/ok.json" >"$D/$1.json"
}
gltf gl-glass '{"name":"gl","pbrMetallicRoughness":{"baseColorFactor":[0.9,0.8,0.7,1],"metallicFactor":0,"roughnessFactor":0},
 "extensions":{"KHR_materials_transmission":{"transmissionFactor":1},"KHR_materials_ior":{"ior":1.7}}}'
if "$BIN/scene-info" --json "$D/gl-glass.json" >"$D/ok.out" 2>"$D/gl.err" && [ ! -s "$D/gl.err" ]; then
    check_field gl ior "glass 1.7"
    check_field gl tf "glass 0.9 0.8 0.7"
else
    fail "glTF glass" "$(cat "$D/gl.err")"
fi
gltf gl-mirror '{"name":"gm","pbrMetallicRoughness":{"baseColorFactor":[0.95,0.9,0.5,1],"metallicFactor":1,"roughnessFactor":0}}'
if "$BIN/scene-info" --json "$D/gl-mirror.json" >"$D/ok.out" 2>"$D/gl.err" && [ ! -s "$D/gl.err" ]; then
    check_field gm f0 "conductor 0.95 0.9 0.5"
    check_field gm alpha "conductor 0"
else
    fail "glTF smooth metal" "$(cat "$D/gl.err")"
fi
gltf gl-both '{"name":"gb","pbrMetallicRoughness":{"metallicFactor":1,"roughnessFactor":0},
 "extensions":{"KHR_materials_transmission":{"transmissionFactor":1}}}'
rm -f "$D/gb.pm"
expect_error "glTF mirror and glass at once is refused" "material 'gb': transmissionFactor 1 makes it glass, and metallicFactor 1 with roughnessFactor 0 a mirror" \
    "$BIN/trace-photons" "$D/gl-both.json" -o "$D/gb.pm"
[ ! -e "$D/gb.pm" ] && pass "... and writes nothing" || fail "gl-both output" "$D/gb.pm exists"

# the shipped caustic scene: built by make, a glass and a mirror material, nothing unsupported
if [ -f scenes/caustic/caustic.obj ]; then
    "$BIN/scene-info" --json scenes/caustic/scene.json >"$D/caustic.json" 2>"$D/caustic.err"
    if [ $? = 0 ] && [ ! -s "$D/caustic.err" ] && grep -q '"any_specular": true' "$D/caustic.json" &&
        [ "$(grep -o '"kind": "glass"' "$D/caustic.json" | wc -l)" = 1 ] && [ "$(grep -o '"kind": "mirror"' "$D/caustic.json" | wc -l)" = 1 ]; then
        pass "scenes/caustic loads with one glass and one mirror material and no warning"
    else
        fail "scenes/caustic" "$(head -c 300 "$D/caustic.err")"
    fi
else
    fail "scenes/caustic" "scenes/caustic/caustic.obj was not generated by make"
fi

# the queries' material table: a mirror or glass entry says so after the standard part, and a
# reader takes it back (trace-gather-points writes the table when some material is glossy)
spec_scene table 'newmtl gloss
Kd 0.3 0.3 0.3
Ks 0.5 0.5 0.5
Ns 20
newmtl chrome
Ks 0.9 0.8 0.7
illum 5
newmtl glass
Ni 1.33
Tf 0.5 0.6 0.7
illum 7
' gloss chrome glass
if "$BIN/trace-gather-points" -q "$D/table.json" -o "$D/table.q.pm" 2>"$D/table.err" &&
    "$BIN/pm-info" "$D/table.q.pm" >"$D/table.info" 2>>"$D/table.err" &&
    grep -q '^material.0=gloss kd 0.300000012 0.300000012 0.300000012 ks 0.5 0.5 0.5 ns 20$' "$D/table.info" &&
    grep -q '^material.1=chrome kd 0 0 0 ks 0 0 0 ns 0 mirror kr 0.899999976 0.800000012 0.699999988$' "$D/table.info" &&
    grep -q '^material.2=glass kd 0 0 0 ks 0 0 0 ns 0 glass ior 1.33000004 tf 0.5 0.600000024 0.699999988$' "$D/table.info"; then
    pass "queries material table: mirror and glass entries written and read back; the glossy one as before"
else
    fail "queries material table" "$(cat "$D/table.err") $(grep '^material' "$D/table.info" 2>/dev/null)"
fi
# a reader refuses a specular entry out of range
if [ -s "$D/table.q.pm" ]; then
    sed 's/mirror kr 0.899999976/mirror kr 1.89999998/' "$D/table.q.pm" >"$D/bad.q.pm"
    expect_error "a queries file with a mirror of kr 1.9 is refused" "material.1 is not a physical mirror or glass" \
        "$BIN/pm-info" "$D/bad.q.pm"
fi
