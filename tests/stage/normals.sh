# normals.sh: shading normals from a mesh's vertex normals (docs/scene-format.md, Shading
# normals). A UV sphere of radius 1 at the origin, 24 x 12 facets (15 degrees each), written
# with vertex normals equal to its vertices (radial), lit by a point light of intensity I at
# LP and seen from (0, 0, 4). The vertex normals interpolated at a point p of a facet are p's
# barycentric mix of the vertices over the radius, so the normalized shading normal is exactly
# p / |p|, and the closed form of the radiance at a hit p is
#   L = KD / pi * I * max(0, ns . w) / r^2, ns = p / |p|, w = (LP - p) / r, r = |LP - p|,
# where the faceted sphere (geometric normals) is off by up to sin(7.5 deg) in the cosine. The
# sphere is convex: no light reaches it twice, so L is the whole answer. Checked through the
# direct buffer of trace-gather-points and trace-reference (exact up to rounding: 1e-3) and
# the photon pipeline (a density estimate: mean within 3%, RMS below 15%), over the pixels whose
# hit has ns . w >= 0.3 (away from the terminator, where a kernel straddles the dark side).
# Then: with "shading_normals": false the images equal, pixel for pixel, those of the same
# sphere written without normals, and they are off the smooth closed form; a light at the
# horizon of every hit (grazing) gives finite pixels everywhere, and photons grazing a plane whose
# normals lean 60 degrees carry the adjoint factor capped at 10.
# programs: build-photonmap composite scene-info simd-gather trace-gather-points trace-photons trace-reference
PI=3.141592653589793

# sphere DIR WITH-VN: the sphere's OBJ and MTL (KD 0.6) in DIR.
sphere() {
    mkdir -p "$1"
    awk -v vn="$2" 'BEGIN {
        pi = 3.141592653589793; nu = 24; nv = 12
        print "mtllib s.mtl"
        for (j = 0; j <= nv; j++) for (i = 0; i < nu; i++) {
            th = pi * j / nv; ph = 2 * pi * i / nu
            x = sin(th) * cos(ph); y = cos(th); z = sin(th) * sin(ph)
            printf "v %.9f %.9f %.9f\n", x, y, z
            if (vn) printf "vn %.9f %.9f %.9f\n", x, y, z
        }
        print "usemtl white"
        for (j = 0; j < nv; j++) for (i = 0; i < nu; i++) {
            a = j * nu + i + 1; b = j * nu + (i + 1) % nu + 1; c = a + nu; d = b + nu
            if (vn) printf "f %d//%d %d//%d %d//%d\nf %d//%d %d//%d %d//%d\n", a, a, b, b, d, d, a, a, d, d, c, c
            else printf "f %d %d %d\nf %d %d %d\n", a, b, d, a, d, c
        }
    }' >"$1/s.obj"
    printf 'newmtl white\nKd 0.6 0.6 0.6\n' >"$1/s.mtl"
}

# scene DIR LIGHT-POS [EXTRA]: the scene file (EXTRA: more top-level members).
scene() {
    cat >"$1/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "smooth-sphere",
  "meshes": [ { "file": "s.obj" } ],
  "camera": { "eye": [0, 0, 4], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 36, "width": 32, "height": 32 },
  "point_lights": [ { "position": [$2], "intensity": [4, 4, 4] } ],
  "render": { "photons": 400000, "spp": 4, "seed": 1 }${3:+, $3}
}
JSON
}

# Radiance expected at each hit (pm-info -r of direct-vis queries), then the image (pm-exrdump):
# one summary line; exit 1 on failure. -v lx ly lz: the light; tmean, trms, tmax; -v faceted=1:
# the image must be off the smooth closed form (RMS above 3%) instead.
cat >"$TMP/normals.awk" <<'AWK'
FNR == NR {
    if ($1 ~ /^[0-9]+$/ && NF >= 11) {
        px = $NF; x = $2; y = $3; z = $4
        if (tilt) { nx = sin(tilt * pi / 180); ny = cos(tilt * pi / 180); nz = 0 } # the tilted plane's ns
        else if (nsy) { l = sqrt(nsx * nsx + nsy * nsy + nsz * nsz); nx = nsx / l; ny = nsy / l; nz = nsz / l } # or one given
        else { l = sqrt(x * x + y * y + z * z); nx = x / l; ny = y / l; nz = z / l }
        dx = lx - x; dy = ly - y; dz = lz - z; r2 = dx * dx + dy * dy + dz * dz; r = sqrt(r2)
        c = (nx * dx + ny * dy + nz * dz) / r
        want[px] = c > 0 ? 0.6 / pi * 4 * c / r2 : 0; inside[px] = c >= 0.3
    }
    next
}
$1 == "size" { w = $2; h = $3; next }
{
    p = $2 * w + $1; seen++
    for (k = 3; k <= 5; k++) {
        v = $k
        if (v !~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/) { why = why sprintf(" pixel %d value %s;", p, v); bad = 1; continue }
        if (!(p in want) && v != 0) { why = why sprintf(" pixel %d misses the sphere but is %s;", p, v); bad = 1 }
        if (!inside[p]) continue
        q = v / want[p]; n++; s += q; ss += (q - 1) ^ 2
        if (n == 1 || q < mn) mn = q
        if (n == 1 || q > mx) mx = q
    }
}
END {
    if (seen != w * h || n < 200) { print "failed: " seen " of " w * h " pixels read, " n " values inside"; exit 1 }
    mean = s / n; rms = sqrt(ss / n)
    printf "ratio measured/smooth closed form: mean %.5f, rms dev %.5f, min %.4f, max %.4f over %d values\n", mean, rms, mn, mx, n
    if (faceted) { if (!(rms > 0.03)) { why = why " as smooth as the shading normals;"; bad = 1 } }
    else {
        if ((mean - 1) ^ 2 > tmean ^ 2) { why = why " mean off;"; bad = 1 }
        if (!(rms <= trms)) { why = why " rms too large;"; bad = 1 }
        if (!(mn >= 1 - tmax && mx <= 1 + tmax)) { why = why " a pixel too far off;"; bad = 1 }
    }
    if (bad) print "failed:" why
    exit bad
}
AWK

judge() {
    local name=$1 hits=$2 img=$3; shift 3
    if awk -v pi=$PI "$@" -f "$TMP/normals.awk" "$hits" "$img" >"$TMP/why"; then
        pass "$name ($(cat "$TMP/why"))"
    else
        fail "$name" "$(tr '\n' ' ' <"$TMP/why")"
    fi
}

# render NAME SCENE: photon image, direct buffer and trace-reference of SCENE as text in
# $TMP/NAME.{i,d,r}.txt, the hits in $TMP/NAME.hits.
render() {
    local t=$TMP/$1 scene=$2
    "$BIN/trace-photons" "$scene" -q -o - | "$BIN/build-photonmap" - -q -o "$t.map.pm" &&
        "$BIN/trace-gather-points" "$scene" --pixel center --mode direct-vis -q -o "$t.q.pm" --direct "$t.d.pm" &&
        "$BIN/simd-gather" "$t.map.pm" "$t.q.pm" --k 200 -q -o "$t.i.pm" &&
        "$BIN/pm-info" -r "$t.q.pm" >"$t.hits" &&
        "$BIN/composite" "$t.i.pm" -q -o "$t.i.exr" && "$BUILD/tests/pm-exrdump" "$t.i.exr" >"$t.i.txt" &&
        "$BIN/composite" "$t.d.pm" -q -o "$t.d.exr" && "$BUILD/tests/pm-exrdump" "$t.d.exr" >"$t.d.txt" &&
        "$BIN/trace-reference" "$scene" -q --pixel center --spp 4 -o "$t.r.exr" &&
        "$BUILD/tests/pm-exrdump" "$t.r.exr" >"$t.r.txt"
}

LIGHT="0, 2.5, 1.5"
LV="-v lx=0 -v ly=2.5 -v lz=1.5"
sphere "$TMP/smooth" 1
scene "$TMP/smooth" "$LIGHT"
if render smooth "$TMP/smooth/scene.json"; then
    judge "smooth sphere, photon map" "$TMP/smooth.hits" "$TMP/smooth.i.txt" $LV -v tmean=0.03 -v trms=0.15 -v tmax=0.6
    judge "smooth sphere, direct buffer" "$TMP/smooth.hits" "$TMP/smooth.d.txt" $LV -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
    judge "smooth sphere, trace-reference" "$TMP/smooth.hits" "$TMP/smooth.r.txt" $LV -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
else
    fail "smooth sphere" "a stage failed"
fi

# A plane y = 0 (half-width 3 m) whose four vertex normals all lean 30 degrees toward +x: the
# shading normal is that one direction everywhere, far from the geometric (0, 1, 0), and a
# density estimate cannot blur the difference away as it does a sphere's facets. The light at
# (0, 1, 0), the camera 1.5 m above, looking down. Photons arrive with the geometric cosine and
# must be weighed by ns.w / ng.w (the adjoint correction, render/transport.h) to agree.
mkdir -p "$TMP/tilt"
printf 'mtllib s.mtl\nv -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nvn 0.5 0.8660254 0\nusemtl white\nf 1//1 4//1 3//1 2//1\n' >"$TMP/tilt/s.obj"
printf 'newmtl white\nKd 0.6 0.6 0.6\n' >"$TMP/tilt/s.mtl"
scene "$TMP/tilt" "0, 1, 0"
sed -i 's|"eye": \[0, 0, 4\], "look_at": \[0, 0, 0\], "up": \[0, 1, 0\], "fov_y": 36|"eye": [0, 1.5, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90|' "$TMP/tilt/scene.json"
TV="-v lx=0 -v ly=1 -v lz=0 -v tilt=30"
# judge_plane NAME T AWK-VARS...: render T's photon map (a density estimate: mean within 3%,
# RMS below 15%), direct buffer and trace-reference (exact up to rounding) against the closed form.
judge_plane() {
    local name=$1 t=$TMP/$2
    shift 2
    judge "$name, photon map" "$t.hits" "$t.i.txt" "$@" -v tmean=0.03 -v trms=0.15 -v tmax=0.6
    judge "$name, direct buffer" "$t.hits" "$t.d.txt" "$@" -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
    judge "$name, trace-reference" "$t.hits" "$t.r.txt" "$@" -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
}
if render tilt "$TMP/tilt/scene.json"; then
    judge_plane "plane with normals tilted 30 degrees" tilt $TV
else
    fail "plane with tilted normals" "a stage failed"
fi

# Normal maps and bump maps (docs/scene-format.md, Normal and bump maps): the same plane without
# vertex normals, its texture coordinates u along +x and v along +z over its 6 m, bent by
# - a normal map (MTL norm) of one texel value everywhere, (191, 128, 238) of 255: the tangent-
#   space normal (2 c / 255 - 1) = (0.49804, 0.00392, 0.86667) with x along dp/du (+x), y along
#   dp/dv (+z), z the surface's normal (+y): 29.9 degrees toward +x, the world normal
#   (0.49804, 0.86667, 0.00392) normalized;
# - a bump map (MTL bump -bm B) of heights B (255 - x) / 255 m along its 256 columns: with
#   bilinear lookup the height falls by B 256 / 255 m per unit of u, that is per 6 m, so that
#   the bumped surface leans toward +x by atan(B 256 / (255 * 6)): 30 degrees for B = 3.4505859.
# Each must shade as a tilted plane: the closed form of the tilted plane above with that normal,
# in the direct buffer and trace-reference (exact up to rounding) and the photon map (a density
# estimate: photons arrive with the geometric cosine and are weighed by ns.w / ng.w, as for
# vertex normals). The camera sees u in [0.25, 0.75], away from the map's wrap at the edges.
# tga FILE W H HEX-PIXELS: an uncompressed 24-bit TGA, top row first (BGR per pixel)
tga() {
    local hdr
    hdr=$(printf '000002000000000000000000%02x%02x%02x%02x1820' $(($2 & 255)) $(($2 >> 8)) $(($3 & 255)) $(($3 >> 8)))
    printf "$(echo "$hdr$4" | sed 's/../\\x&/g')" >"$1"
}
bent_plane() {
    mkdir -p "$1"
    printf 'mtllib s.mtl\nv -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl white\nf 1/1 4/4 3/3 2/2\n' >"$1/s.obj"
    printf 'newmtl white\nKd 0.6 0.6 0.6\n%s\n' "$2" >"$1/s.mtl"
    cp "$TMP/tilt/scene.json" "$1/scene.json"
}
bent_plane "$TMP/nmap" "norm n.tga"
tga "$TMP/nmap/n.tga" 2 2 "$(printf 'ee80bf%.0s' 1 2 3 4)"
ramp=$(awk 'BEGIN { for (r = 0; r < 2; r++) for (x = 0; x < 256; x++) printf "%02x%02x%02x", 255 - x, 255 - x, 255 - x }')
for key in bump map_Bump; do
    bent_plane "$TMP/bmap-$key" "$key -bm 3.4505859 ramp.tga"
    tga "$TMP/bmap-$key/ramp.tga" 256 2 "$ramp"
done
NV="-v lx=0 -v ly=1 -v lz=0 -v nsx=0.49803922 -v nsy=0.86666667 -v nsz=0.00392157"
if render nmap "$TMP/nmap/scene.json"; then
    judge_plane "flat plane, normal map of a 29.9 degree slope = the tilted plane" nmap $NV
else
    fail "plane with a normal map" "a stage failed: $("$BIN/scene-info" "$TMP/nmap/scene.json" 2>&1 >/dev/null | head -c 300)"
fi
for key in bump map_Bump; do
    if render bmap-$key "$TMP/bmap-$key/scene.json"; then
        judge_plane "flat plane, $key ramp of a 30 degree slope = the tilted plane" bmap-$key $TV
    else
        fail "plane with a bump map ($key)" "a stage failed: $("$BIN/scene-info" "$TMP/bmap-$key/scene.json" 2>&1 >/dev/null | head -c 300)"
    fi
done
# glTF's normalTexture: the same plane and normal map as glTF (texture coordinates in
# TEXCOORD_0, u along +x; glTF's v runs down the image, which assimp turns to run up, so that
# dp/dv is -z and the map's small green component leans the normal toward -z).
mkdir -p "$TMP/nmapgl" && cp "$TMP/nmap/n.tga" "$TMP/nmapgl/"
printf '{"asset":{"version":"2.0"},"extensionsUsed":["KHR_materials_ior"],"scenes":[{"nodes":[0]}],"scene":0,"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
"materials":[{"name":"white","normalTexture":{"index":0},"pbrMetallicRoughness":{"baseColorFactor":[0.6,0.6,0.6,1],"metallicFactor":0,"roughnessFactor":1},"extensions":{"KHR_materials_ior":{"ior":1}}}],
"textures":[{"source":0}],"images":[{"uri":"n.tga"}],
"buffers":[{"byteLength":92,"uri":"data:application/octet-stream;base64,AABAwAAAAAAAAEDAAABAQAAAAAAAAEDAAABAQAAAAAAAAEBAAABAwAAAAAAAAEBAAAAAAAAAAAAAAIA/AAAAAAAAgD8AAIA/AAAAAAAAgD8AAAMAAgAAAAIAAQA="}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":32},{"buffer":0,"byteOffset":80,"byteLength":12}],
"accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-3,0,-3],"max":[3,0,3]},
{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"},{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}]}\n' >"$TMP/nmapgl/s.gltf"
sed 's/"s.obj"/"s.gltf"/' "$TMP/tilt/scene.json" >"$TMP/nmapgl/scene.json"
NVG="-v lx=0 -v ly=1 -v lz=0 -v nsx=0.49803922 -v nsy=0.86666667 -v nsz=-0.00392157"
if render nmapgl "$TMP/nmapgl/scene.json"; then
    judge_plane "glTF flat plane, normalTexture of a 29.9 degree slope = the tilted plane" nmapgl $NVG
else
    fail "glTF plane with a normal texture" "a stage failed: $("$BIN/scene-info" "$TMP/nmapgl/scene.json" 2>&1 >/dev/null | head -c 300)"
fi
# A colour image in map_Bump (Blender's OBJ exporter writes normal maps so) is read as a normal
# map, and scene-info says so: the normal map's plane again, through the direct buffer.
bent_plane "$TMP/nbump" "map_Bump n.tga"
cp "$TMP/nmap/n.tga" "$TMP/nbump/"
if "$BIN/trace-gather-points" "$TMP/nbump/scene.json" --pixel center --mode direct-vis -q -o "$TMP/nbump.q.pm" --direct "$TMP/nbump.d.pm" &&
    "$BIN/pm-info" -r "$TMP/nbump.q.pm" >"$TMP/nbump.hits" && "$BIN/composite" "$TMP/nbump.d.pm" -q -o "$TMP/nbump.d.exr" &&
    "$BUILD/tests/pm-exrdump" "$TMP/nbump.d.exr" >"$TMP/nbump.d.txt"; then
    judge "map_Bump holding a colour normal map = the normal map's tilted plane, direct buffer" "$TMP/nbump.hits" "$TMP/nbump.d.txt" $NV -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
else
    fail "map_Bump holding a colour normal map" "a stage failed"
fi
if "$BIN/scene-info" -q "$TMP/nbump/scene.json" | grep -q "bump '.*n.tga' (approximated: a colour image: read as a tangent-space normal map)"; then
    pass "scene-info: a colour map_Bump is listed as read as a normal map"
else
    fail "scene-info on a colour map_Bump" "$("$BIN/scene-info" -q "$TMP/nbump/scene.json" | grep -i -A1 unsupported)"
fi
# scene-info lists the maps as used (norm, bump) and reports nothing of them unsupported
si_maps() { "$BIN/scene-info" -q --json "$1" | jq -r '[(.textures[].used_by[] | "\(.material) \(.map)"), (.materials[].unsupported // [] | length | tostring)] | join(" ")'; }
got="$(si_maps "$TMP/nmap/scene.json"); $(si_maps "$TMP/bmap-bump/scene.json")"
if [ "$got" = "white norm 0; white bump 0" ]; then
    pass "scene-info: the normal map and the bump map used by their material, nothing unsupported"
else
    fail "scene-info on normal and bump maps" "'$got', want 'white norm 0; white bump 0'"
fi
# The same tilted plane as glTF (vertex normals in its NORMAL attribute, a base colour of 0.6,
# not metallic, fully rough, of index 1 by KHR_materials_ior: Lambertian, where glTF's default
# index 1.5 would put a coat over it, docs/materials.md): assimp reads them as it reads OBJ's
# vn, and the direct buffer and trace-reference match the same closed form.
mkdir -p "$TMP/tiltgl"
printf '{"asset":{"version":"2.0"},"extensionsUsed":["KHR_materials_ior"],"scenes":[{"nodes":[0]}],"scene":0,"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":2,"material":0}]}],
"materials":[{"name":"white","pbrMetallicRoughness":{"baseColorFactor":[0.6,0.6,0.6,1],"metallicFactor":0,"roughnessFactor":1},"extensions":{"KHR_materials_ior":{"ior":1}}}],
"buffers":[{"byteLength":108,"uri":"data:application/octet-stream;base64,AABAwAAAAAAAAEDAAABAQAAAAAAAAEDAAABAQAAAAAAAAEBAAABAwAAAAAAAAEBAAAAAP9ezXT8AAAAAAAAAP9ezXT8AAAAAAAAAP9ezXT8AAAAAAAAAP9ezXT8AAAAAAAADAAIAAAACAAEA"}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":48},{"buffer":0,"byteOffset":96,"byteLength":12}],
"accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-3,0,-3],"max":[3,0,3]},
{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"},{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}]}\n' >"$TMP/tiltgl/s.gltf"
sed 's/"s.obj"/"s.gltf"/' "$TMP/tilt/scene.json" >"$TMP/tiltgl/scene.json"
if render tiltgl "$TMP/tiltgl/scene.json"; then
    judge "glTF plane with normals tilted 30 degrees, direct buffer" "$TMP/tiltgl.hits" "$TMP/tiltgl.d.txt" $TV -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
    judge "glTF plane with normals tilted 30 degrees, trace-reference" "$TMP/tiltgl.hits" "$TMP/tiltgl.r.txt" $TV -v tmean=1e-3 -v trms=1e-3 -v tmax=1e-3
else
    fail "glTF plane with tilted normals" "a stage failed: $("$BIN/scene-info" "$TMP/tiltgl/scene.json" 2>&1 >/dev/null | head -c 300)"
fi

# Bounces: a floor y = 0 (x in [-2, 1], kd 0.8) whose vertex normals lean 30 degrees toward the
# wall x = 1 (facing -x, kd 0.8, no vertex normals), lit by a spot at (-1, 1.5, 0) pointing
# down with a 40 degree cone, which never reaches the wall: all the wall's light has bounced
# off the floor once or more, where photons leave with the adjoint correction ng.wo / ns.wo and
# trace-reference's paths weigh the floor with the shading cosine. The camera sees only the
# wall. The photon map (direct-vis, the global map) and trace-reference (256 samples) must
# agree in the mean within 3% (a photon tracer without the departure correction fails by far).
mkdir -p "$TMP/bounce"
printf 'mtllib s.mtl\nv -2 0 -2\nv 1 0 -2\nv 1 0 2\nv -2 0 2\nvn 0.5 0.8660254 0\nv 1 0 -2\nv 1 2 -2\nv 1 2 2\nv 1 0 2\nusemtl white\nf 1//1 4//1 3//1 2//1\nf 5 6 7 8\n' >"$TMP/bounce/s.obj"
printf 'newmtl white\nKd 0.8 0.8 0.8\n' >"$TMP/bounce/s.mtl"
cat >"$TMP/bounce/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "tilted-bounce",
  "meshes": [ { "file": "s.obj" } ],
  "camera": { "eye": [-1, 1, 0], "look_at": [1, 1, 0], "up": [0, 1, 0], "fov_y": 40, "width": 32, "height": 32 },
  "point_lights": [ { "position": [-1, 1.5, 0], "intensity": [10, 10, 10], "direction": [0, -1, 0], "cone": 40 } ],
  "render": { "photons": 400000, "spp": 4, "seed": 1 }
}
JSON
B=$TMP/bounce
if "$BIN/trace-photons" "$B/scene.json" -q -o - | "$BIN/build-photonmap" - -q -o "$B.map.pm" &&
    "$BIN/trace-gather-points" "$B/scene.json" --pixel center --mode direct-vis -q -o "$B.q.pm" --direct "$B.d.pm" &&
    "$BIN/simd-gather" "$B.map.pm" "$B.q.pm" --k 100 -q -o "$B.i.pm" &&
    "$BIN/composite" "$B.i.pm" -q -o "$B.i.exr" && "$BUILD/tests/pm-exrdump" "$B.i.exr" >"$B.i.txt" &&
    "$BIN/trace-reference" "$B/scene.json" -q --pixel center --spp 256 -o "$B.r.exr" &&
    "$BUILD/tests/pm-exrdump" "$B.r.exr" >"$B.r.txt"; then
    mean_of() { awk '$1 != "size" { s += $3 + $4 + $5; n += 3 } END { printf "%.6g", s / n }' "$1"; }
    mi=$(mean_of "$B.i.txt") mr=$(mean_of "$B.r.txt")
    if awk -v a="$mi" -v b="$mr" 'BEGIN { exit !(a > 0 && b > 0 && a / b > 0.97 && a / b < 1.03) }'; then
        pass "photons bouncing off tilted normals: means $mi (photon map) and $mr (trace-reference)"
    else
        fail "photons bouncing off tilted normals" "means $mi (photon map) and $mr (trace-reference) differ by more than 3%"
    fi
else
    fail "photons bouncing off tilted normals" "a stage failed"
fi

# The cap on the adjoint factors (render/transport.h, PM_SHADING_FACTOR_MAX 10): a spot 0.1 m
# above a plane whose normals lean 60 degrees toward it, 1 to 7 m away, so that every photon
# arrives at a geometric cosine of 0.1 / r or less with a shading cosine near 0.87: ns.wi / ng.wi
# is 8.7 to 60 (61 measured uncapped, mean 20). Every photon stored at its first hit carries at
# most 10 times the power it was emitted with, and none is lost for it.
mkdir -p "$TMP/graze60"
printf 'mtllib s.mtl\nv -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nvn 0.8660254 0.5 0\nusemtl white\nf 1//1 4//1 3//1 2//1\n' >"$TMP/graze60/s.obj"
printf 'newmtl white\nKd 0.6 0.6 0.6\n' >"$TMP/graze60/s.mtl"
cat >"$TMP/graze60/scene.json" <<'JSON'
{
  "pmtk_scene": 1,
  "name": "grazing",
  "meshes": [ { "file": "s.obj" } ],
  "camera": { "eye": [0, 1.5, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 16, "height": 16 },
  "point_lights": [ { "position": [4, 0.1, 0], "intensity": [1, 1, 1], "direction": [-1, -0.03, 0], "cone": 30 } ],
  "render": { "photons": 20000, "seed": 1 }
}
JSON
if "$BIN/trace-photons" "$TMP/graze60/scene.json" -q -o "$TMP/g60.pm" &&
    P=$("$BIN/scene-info" -q --json "$TMP/graze60/scene.json" | jq '.power_w[0]') &&
    N=$("$BIN/pm-info" --header "$TMP/g60.pm" | sed -n 's/^emitted=//p') &&
    "$BIN/pm-info" -r "$TMP/g60.pm" | awk -v P="$P" -v N="$N" 'NF == 11 && $1 ~ /^[0-9]+$/ && $11 == 0 {
            r = $5 / (P / N); if (r > m) m = r; if (r < lo || n == 0) lo = r; n++ }
        END { printf "%d photons, %.4g to %.4g times their emitted power\n", n, lo, m; exit !(n > 1000 && m <= 10 * (1 + 1e-6) && lo > 8) }' >"$TMP/why"; then
    pass "grazing photons on normals leaning 60 degrees: the adjoint factor is capped at 10 ($(cat "$TMP/why"))"
else
    fail "adjoint factor cap" "$(cat "$TMP/why" 2>/dev/null)"
fi

# The same sphere with shading_normals false, and written without normals: the same pixels.
mkdir -p "$TMP/off" && cp "$TMP/smooth/s.obj" "$TMP/smooth/s.mtl" "$TMP/off/"
scene "$TMP/off" "$LIGHT" '"shading_normals": false'
sphere "$TMP/flat" 0
scene "$TMP/flat" "$LIGHT"
if render off "$TMP/off/scene.json" && render flat "$TMP/flat/scene.json"; then
    for k in i d r; do
        if cmp -s "$TMP/off.$k.txt" "$TMP/flat.$k.txt"; then
            pass "shading_normals false: image $k equals the sphere without normals"
        else
            fail "shading_normals false, image $k" "differs from the sphere without normals"
        fi
    done
    judge "faceted sphere, direct buffer, off the smooth closed form" "$TMP/off.hits" "$TMP/off.d.txt" $LV -v faceted=1
else
    fail "shading_normals false" "a stage failed"
fi

# scene-info says whether shading normals are in use: the sphere's 266 vertices (poles merged) all carry one;
# with shading_normals false they are ignored; the sphere written without them has none.
si_normals() { "$BIN/scene-info" -q "$1" | grep '^shading normals: '; }
if [ "$(si_normals "$TMP/smooth/scene.json")" = "shading normals: yes (vertex normals at 266 of 266 vertices)" ] &&
    [ "$(si_normals "$TMP/off/scene.json")" = "shading normals: no (shading_normals false: the meshes' vertex normals are ignored)" ] &&
    [ "$(si_normals "$TMP/flat/scene.json")" = "shading normals: no (no mesh has vertex normals)" ] &&
    [ "$("$BIN/scene-info" -q --json "$TMP/off/scene.json" | jq -c .shading_normals)" = '{"in_use":false,"vertices":0,"ignored":true}' ] &&
    [ "$("$BIN/scene-info" -q --json "$TMP/smooth/scene.json" | jq -c .shading_normals)" = '{"in_use":true,"vertices":266,"ignored":false}' ]; then
    pass "scene-info: shading normals in use (266 of 266 vertices), ignored by the scene key, or absent"
else
    fail "scene-info shading normals" "$(si_normals "$TMP/smooth/scene.json"); $(si_normals "$TMP/off/scene.json"); $(si_normals "$TMP/flat/scene.json")"
fi

# Grazing: the light in the plane z = 0 far to the side, so that every hit near x = 0 sees it at
# the horizon of its shading or its geometric normal; every pixel finite, the three ways.
mkdir -p "$TMP/graze" && cp "$TMP/smooth/s.obj" "$TMP/smooth/s.mtl" "$TMP/graze/"
scene "$TMP/graze" "1000, 0.01, 0"
if render graze "$TMP/graze/scene.json"; then
    bad=$(cat "$TMP/graze.i.txt" "$TMP/graze.d.txt" "$TMP/graze.r.txt" | awk '$1 != "size" { for (k = 3; k <= 5; k++) if ($k !~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/) n++ } END { print n + 0 }')
    if [ "$bad" = 0 ]; then pass "light at the horizon: every pixel finite"; else fail "light at the horizon" "$bad values not finite"; fi
else
    fail "light at the horizon" "a stage failed"
fi

# Bad value of the key: one line, exit 1.
scene "$TMP/smooth" "$LIGHT" '"shading_normals": 1'
expect_error "shading_normals must be a boolean" "shading_normals: must be true" "$BIN/trace-reference" "$TMP/smooth/scene.json" -q --spp 1 -o "$TMP/bad.exr"

# The atrium's sky-lit, textured variant (scenes/atrium/README.md) loads with its two textures
# and its sun and sky, without a warning (a texture file missing or a key unread would warn).
if "$BIN/scene-info" --json scenes/atrium/textured.json >"$TMP/atr.json" 2>"$TMP/atr.err" && [ ! -s "$TMP/atr.err" ] &&
    [ "$(jq -r '[.emissive_triangles, (.lights | map(.kind) | join(" "))] | join(" ")' "$TMP/atr.json")" = "0 sun sky" ]; then
    pass "scenes/atrium/textured.json: no emitter, a sun and a sky, no warning"
else
    fail "scenes/atrium/textured.json" "$(head -c 300 "$TMP/atr.err") $(jq -c '[.emissive_triangles, .lights]' "$TMP/atr.json" 2>/dev/null)"
fi
