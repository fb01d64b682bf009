# lights.sh: spot lights, suns and the sky (docs/scene-format.md, Lights) against their closed
# forms, through the photon pipeline (trace-photons, build-photonmap, trace-gather-points
# --mode direct-vis, simd-gather), through trace-gather-points' direct buffer (next-event
# estimation) and through trace-reference (pixel centres), on a lone diffuse plane y = 0 of
# albedo KD seen from 1 m above (fov 90: x, z in [-1, 1]):
#   spot at (0, 1, 0) pointing down, intensity I, half-angle C, falloff e:
#     E = I s(theta) cos(theta) / r^2, s = ((cos theta - cos C) / (1 - cos C))^e inside, 0 outside
#   (the plane's normal and the spot's axis are the same line, so theta is also the angle of
#   incidence);
#   sun of radiance L and solid angle omega at angle theta_s from the normal (its cone above the
#   horizon): E = L pi sin^2(a) cos(theta_s), a the cone's half-angle (cos a = 1 - omega / 2 pi),
#   which is L omega cos(theta_s) (1 + cos a) / 2, L omega cos(theta_s) for a small sun;
#   constant sky of radiance L: E = pi L, so the plane reflects L_out = KD L.
# Reflected light escapes: there is nothing else, so E is the whole answer.
# Expected radiance L = KD / pi * E. The photon estimate's tolerances are those of analytic.sh
# (k = 200 photons per kernel: about 9% per pixel, mean within 2%); pixels within a kernel's
# reach of the cone's edge (3 degrees) are left out of the ratio, and beyond it the photon
# image must be exactly 0 (no photon leaves the cone). Next-event estimation of a delta light
# is exact up to float rounding (1e-4).
# programs: build-photonmap composite scene-info simd-gather trace-gather-points trace-photons trace-reference
PI=3.141592653589793

# lit_plane DIR KD LIGHTS-JSON [HALF]: the plane (half-width HALF m, default 20) and the camera,
# with LIGHTS-JSON (top-level members, e.g. "point_lights": [...]) as its lights; $LS, when set,
# its render.light_samples.
lit_plane() {
    local dir=$1 kd=$2 lights=$3 h=${4:-20}
    mkdir -p "$dir"
    printf 'mtllib plane.mtl\nv -%s 0 -%s\nv %s 0 -%s\nv %s 0 %s\nv -%s 0 %s\nusemtl floor\nf 1 4 3 2\n' \
        $h $h $h $h $h $h $h $h >"$dir/plane.obj"
    printf 'newmtl floor\nKd %s %s %s\n' "$kd" "$kd" "$kd" >"$dir/plane.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "lights-plane",
  "meshes": [ { "file": "plane.obj" } ],
  "camera": { "eye": [0, 1, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 32, "height": 32 },
  $lights,
  "render": { "photons": 200000, "spp": 4, "seed": 1${LS:+, \"light_samples\": $LS} }
}
JSON
}

# The expected radiance at each pixel's primary hit and the comparison (one summary line, exit
# 1 on failure). Inputs: `pm-info -r` of direct-vis queries, then `pm-exrdump` of the image.
#   -v kind=spot -v I= -v cone=DEG -v e= (spot at (0, 1, 0) pointing down) | kind=const -v E=
#   -v kd= -v tmean= -v trms= -v tmax= [-v margin=DEG: spot pixels this close to the edge skipped]
cat >"$TMP/lights.awk" <<'AWK'
FNR == NR {
    if ($1 ~ /^[0-9]+$/ && NF >= 11) {
        px = $NF; x = $2; y = $3; z = $4
        if (kind == "spot") {
            d2 = x * x + (1 - y) ^ 2 + z * z; c = (1 - y) / sqrt(d2); cc = cos(cone * pi / 180)
            a = atan2(sqrt(1 - c * c), c) * 180 / pi
            zone[px] = a < cone - margin ? 1 : a > cone + margin ? 0 : -1
            E = c > cc ? I * ((c - cc) / (1 - cc)) ^ e * c / d2 : 0
        } else { E = Ec; zone[px] = 1 }
        want[px] = kd / pi * E
    }
    next
}
$1 == "size" { w = $2; h = $3; next }
{
    p = $2 * w + $1; seen++
    if (!(p in want)) { why = why sprintf(" pixel %d has no hit;", p); bad = 1; next }
    for (c = 3; c <= 5; c++) {
        v = $c
        if (v !~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/) { why = why sprintf(" pixel %d value %s;", p, v); bad = 1; continue }
        if (zone[p] == 0) { nout++; if (v != 0) { nz++; if (v > vmax) vmax = v } continue }
        if (zone[p] < 0) continue
        r = v / want[p]; n++; s += r; ss += (r - 1) ^ 2
        if (n == 1 || r < mn) mn = r
        if (n == 1 || r > mx) mx = r
    }
}
END {
    if (seen != w * h || n == 0) { print "failed: " seen " of " w * h " pixels read, " n " values inside"; exit 1 }
    mean = s / n; rms = sqrt(ss / n)
    printf "ratio measured/expected: mean %.5f, rms dev %.5f, min %.4f, max %.4f over %d values; %d outside, %d of them lit (max %g)\n",
        mean, rms, mn, mx, n, nout, nz, vmax
    if ((mean - 1) ^ 2 > tmean ^ 2) { why = why " mean off;"; bad = 1 }
    if (!(rms <= trms)) { why = why " rms too large;"; bad = 1 }
    if (!(mn >= 1 - tmax && mx <= 1 + tmax)) { why = why " a pixel too far off;"; bad = 1 }
    if (nz) { why = why " light outside the cone;"; bad = 1 }
    if (bad) print "failed:" why
    exit bad
}
AWK

# judge NAME HITS IMAGE-TXT awk-options...: the image against the closed form.
judge() {
    local name=$1 hits=$2 img=$3; shift 3
    if awk -v pi=$PI "$@" -f "$TMP/lights.awk" "$hits" "$img" >"$TMP/why"; then
        pass "$name ($(cat "$TMP/why"))"
    else
        fail "$name" "$(tr '\n' ' ' <"$TMP/why")"
    fi
}

# three_ways NAME SCENE KD awk-options...: the photon pipeline (direct-vis gather of the global
# map), the direct buffer and trace-reference, each judged.
# render_three T SCENE: the photon image, direct buffer and trace-reference (REF_SPP paths, 4 by
# default) of SCENE as pm-exrdump text in T.{i,d,r}.txt, the hits in T.hits.
render_three() {
    local t=$1 scene=$2
    "$BIN/trace-photons" "$scene" --photons 400000 -q -o - | "$BIN/build-photonmap" - -q -o "$t.map.pm" &&
        "$BIN/trace-gather-points" "$scene" --pixel center --mode direct-vis -q -o "$t.q.pm" --direct "$t.d.pm" &&
        "$BIN/simd-gather" "$t.map.pm" "$t.q.pm" --k 200 -q -o "$t.i.pm" &&
        "$BIN/pm-info" -r "$t.q.pm" >"$t.hits" &&
        "$BIN/composite" "$t.i.pm" -q -o "$t.i.exr" && "$BUILD/tests/pm-exrdump" "$t.i.exr" >"$t.i.txt" &&
        "$BIN/composite" "$t.d.pm" -q -o "$t.d.exr" && "$BUILD/tests/pm-exrdump" "$t.d.exr" >"$t.d.txt" &&
        "$BIN/trace-reference" "$scene" -q --pixel center --spp "${REF_SPP:-4}" -o "$t.r.exr" &&
        "$BUILD/tests/pm-exrdump" "$t.r.exr" >"$t.r.txt"
}
three_ways() {
    local name=$1 scene=$2; shift 2
    local t=$TMP/$name
    if render_three "$t" "$scene"; then
        judge "$name, photon map" "$t.hits" "$t.i.txt" -v tmean=0.02 -v trms=0.15 -v tmax=0.5 "$@"
        judge "$name, direct buffer" "$t.hits" "$t.d.txt" ${TOL_D:--v tmean=1e-4 -v trms=1e-4 -v tmax=1e-3} "$@"
        judge "$name, trace-reference" "$t.hits" "$t.r.txt" ${TOL_R:--v tmean=1e-4 -v trms=1e-4 -v tmax=1e-3} "$@"
    else
        fail "$name" "a stage failed"
    fi
}

# ---- 1. spot lights
lit_plane "$TMP/spot" 0.5 '"point_lights": [ { "position": [0, 1, 0], "intensity": [3, 3, 3], "direction": [0, -1, 0], "cone": 30, "falloff": 1 } ]'
three_ways "spot of 30 degrees, falloff 1, over a plane" "$TMP/spot/scene.json" -v kd=0.5 -v kind=spot -v I=3 -v cone=30 -v e=1 -v margin=3
lit_plane "$TMP/spot2" 0.8 '"point_lights": [ { "position": [0, 1, 0], "intensity": [2, 2, 2], "direction": [0, -1, 0], "cone": 40 } ]'
three_ways "spot of 40 degrees, hard edge, over a plane" "$TMP/spot2/scene.json" -v kd=0.8 -v kind=spot -v I=2 -v cone=40 -v e=0 -v margin=3

# ---- 2. a sun: omega 0.01 sr, L 100 W/(m^2 sr), from (1, 2, 0.5) (cos 0.8729 to the normal).
# Next-event estimation samples directions in the cone (half-angle 3.2 degrees): the cosine to
# the normal varies across it by +-2.7%, so each pixel of the direct buffer (4 samples) and of
# trace-reference (4 paths) is off by about 0.8% RMS (measured), and the mean over 1024 pixels
# within 0.03%: the mean must be within 0.2%, the RMS below 1.5%, every pixel within 5%.
SUN_E=$(awk -v p=$PI 'BEGIN { cm = 1 - 0.01 / (2 * p); print 100 * p * (1 - cm * cm) * 2 / sqrt(5.25) }')
lit_plane "$TMP/sun" 0.5 '"sun": { "direction": [1, 2, 0.5], "radiance": [100, 100, 100], "solid_angle": 0.01 }' 3
TOL_D="-v tmean=2e-3 -v trms=0.015 -v tmax=0.05" TOL_R="-v tmean=2e-3 -v trms=0.015 -v tmax=0.05" \
    three_ways "sun of 0.01 sr at 29.2 degrees over a plane, E = L pi sin^2(a) cos = $SUN_E" "$TMP/sun/scene.json" \
    -v kd=0.5 -v kind=const -v Ec=$SUN_E

# ---- 2b. the sun as a user gives it (docs/scene-format.md, Sun): by its irradiance E_n on a
# surface facing it (radiance E_n / (pi sin^2 a)), by elevation and azimuth (elevation
# asin(2 / sqrt 5.25) = 60.7947 degrees, azimuth atan2(0.5, 1) = 26.5651 degrees: the direction
# (1, 2, 0.5) of section 2), the plane receiving E_n cos(theta_s).
SUN_C=$(awk 'BEGIN { print 2 / sqrt(5.25) }')
lit_plane "$TMP/sunE" 0.5 '"sun": { "elevation": 60.794709, "azimuth": 26.565051, "irradiance": [3, 3, 3], "solid_angle": 0.01 }' 3
TOL_D="-v tmean=2e-3 -v trms=0.015 -v tmax=0.05" TOL_R="-v tmean=2e-3 -v trms=0.015 -v tmax=0.05" \
    three_ways "sun of irradiance 3 W per m^2 at elevation 60.79, azimuth 26.57 over a plane, E = 3 cos = $(awk -v c=$SUN_C 'BEGIN { print 3 * c }')" \
    "$TMP/sunE/scene.json" -v kd=0.5 -v kind=const -v Ec=$(awk -v c=$SUN_C 'BEGIN { print 3 * c }')
# scene-info shows the direction and the radiance it resolved to; with sky.up +z and rotate 90,
# elevation 30 and azimuth 0 point to the frame's +x turned 90 degrees about +z the way azimuth
# grows (+x toward the frame's +z, which is -y): (0, -0.866, 0.5).
sun_info() {
    lit_plane "$TMP/suninfo" 0.5 "$1" 3
    "$BIN/scene-info" -q --json "$TMP/suninfo/scene.json" |
        jq -r '.lights[] | select(.kind == "sun") | [.direction[], .radiance_w_m2_sr[0]] | map(. * 10000 | round / 10000) | join(" ")'
}
want_l=$(awk -v p=$PI 'BEGIN { f = 0.01 / (2 * p); printf "%.4f", 3 / (p * f * (2 - f)) }')
for c in "elevation and azimuth, irradiance|\"elevation\": 60.794709, \"azimuth\": 26.565051, \"irradiance\": [3, 3, 3], \"solid_angle\": 0.01|0.4364 0.8729 0.2182 $want_l" \
    "elevation and azimuth in a +z-up sky rotated 90|\"elevation\": 30, \"azimuth\": 0, \"radiance\": [1, 1, 1], \"solid_angle\": 0.01 }, \"sky\": { \"radiance\": [0, 0, 0], \"up\": [0, 0, 1], \"rotate\": 90|0 -0.866 0.5 1"; do
    name=${c%%|*}; rest=${c#*|}; json=${rest%%|*}; want=${rest#*|}
    got=$(sun_info "\"sun\": { $json }")
    got=$(echo "$got" | sed 's/-0 /0 /g')
    if [ "$got" = "$want" ]; then
        pass "sun by $name: direction and radiance $got"
    else
        fail "sun by $name" "scene-info says '$got', want '$want'"
    fi
done

# ---- 3. a constant sky of L 1 over a plane of albedo 0.5: L_out = 0.5 (E = pi). Cosine-
# weighted sky samples on a diffuse plane have zero variance (f L cos / pdf = KD L), and
# trace-reference's light and BSDF samples are then the same strategy, weighted half and half.
lit_plane "$TMP/sky" 0.5 '"sky": { "radiance": [1, 1, 1] }' 3
three_ways "constant sky of L 1 over a plane of albedo 0.5, L_out = rho L" "$TMP/sky/scene.json" \
    -v kd=0.5 -v kind=const -v Ec=$PI

# ---- which first hits the gather points' light samples stand for (render/light.h,
# pm_light_at_gather): the sun's are theirs, a constant sky's stay in the map (rule 2), and a
# gather takes a map and queries of one rule only. Photon records end with their depth.
first_hits() { "$BIN/pm-info" -r "$1" | awk '$1 ~ /^[0-9]+$/ && $NF == 0' | wc -l; }
if "$BIN/trace-photons" "$TMP/sky/scene.json" --photons 20000 -q -o "$TMP/sky.all.pm" &&
    "$BIN/trace-photons" "$TMP/sky/scene.json" --photons 20000 --indirect-only -q -o "$TMP/sky.io.pm" &&
    "$BIN/trace-photons" "$TMP/sun/scene.json" --photons 20000 --indirect-only -q -o "$TMP/sun.io.pm"; then
    ka=$(first_hits "$TMP/sky.all.pm") ki=$(first_hits "$TMP/sky.io.pm") ks=$(first_hits "$TMP/sun.io.pm")
    ri=$("$BIN/pm-info" "$TMP/sky.io.pm" | sed -n 's/^indirect_only=//p')
    rs=$("$BIN/pm-info" "$TMP/sun.io.pm" | sed -n 's/^indirect_only=//p')
    if [ "$ka" -gt 1000 ] && [ "$ki" = "$ka" ] && [ "$ks" = 0 ] && [ "$ri" = 2 ] && [ "$rs" = 1 ]; then
        pass "--indirect-only keeps a constant sky's $ki first hits (indirect_only=2) and drops the sun's (indirect_only=1)"
    else
        fail "--indirect-only by light" "sky first hits $ki of $ka (indirect_only=$ri), sun's $ks (indirect_only=$rs)"
    fi
else
    fail "--indirect-only by light" "trace-photons failed"
fi
"$BIN/trace-gather-points" "$TMP/sky/scene.json" --width 8 --height 8 --spp 4 --secondary-direct -q \
    -o "$TMP/skyq.pm" --direct "$TMP/skyd.pm"
"$BIN/trace-gather-points" "$TMP/sun/scene.json" --width 8 --height 8 --spp 4 --secondary-direct -q \
    -o "$TMP/sunq.pm" --direct "$TMP/sund.pm"
if "$BIN/pm-info" "$TMP/skyq.pm" | grep -qx 'secondary_direct=2' && "$BIN/pm-info" "$TMP/skyd.pm" | grep -qx 'secondary_direct=2' &&
    "$BIN/pm-info" "$TMP/sunq.pm" | grep -qx 'secondary_direct=1'; then
    pass "queries with secondary direct light name the rule: 2 under a constant sky, 1 under a sun alone"
else
    fail "secondary_direct rule" "$("$BIN/pm-info" "$TMP/skyq.pm" "$TMP/sunq.pm" | grep secondary_direct | tr '\n' ' ')"
fi
"$BIN/build-photonmap" "$TMP/sun.io.pm" -q -o "$TMP/sun.map.pm"
"$BIN/build-photonmap" "$TMP/sky.io.pm" -q -o "$TMP/sky.map.pm"
expect_error "a map of rule 1 with queries of rule 2 is refused, naming both" \
    "photon map '.*sun.map.pm' says indirect_only=1 but queries '.*skyq.pm' say secondary_direct=2: made under different rules" \
    "$BIN/simd-gather" "$TMP/sun.map.pm" "$TMP/skyq.pm" --radius 0.1 -o "$TMP/mix.pm"
[ -e "$TMP/mix.pm" ] && fail "a refused gather wrote its output" "$TMP/mix.pm exists"
expect_exit "a map and queries of rule 2 gather" 0 "$BIN/simd-gather" "$TMP/sky.map.pm" "$TMP/skyq.pm" --radius 0.1 -q -o "$TMP/sky.g.pm"
# a rule this pmtk does not know (a header value other than 1 or 2, its checksum remade) is
# refused in one line, not read as none
if /usr/bin/python3 -c 'import xxhash' 2>/dev/null; then
    for f in skyq:secondary_direct sky.map:indirect_only; do
        /usr/bin/python3 - "$TMP/${f%%:*}.pm" "$TMP/${f%%:*}.7.pm" "${f#*:}" <<'PY'
import struct, sys, xxhash
d = open(sys.argv[1], 'rb').read()[:-8].replace(('\n%s=2\n' % sys.argv[3]).encode(), ('\n%s=7\n' % sys.argv[3]).encode())
open(sys.argv[2], 'wb').write(d + struct.pack('<Q', xxhash.xxh3_64_intdigest(d)))
PY
    done
    expect_error "queries of an unknown rule (secondary_direct=7) are refused" \
        "queries '.*skyq.7.pm' say secondary_direct='7': not a rule of this pmtk" \
        "$BIN/simd-gather" "$TMP/sky.map.pm" "$TMP/skyq.7.pm" --radius 0.1 -o "$TMP/mix7.pm"
    expect_error "a map of an unknown rule (indirect_only=7) is refused" \
        "photon map '.*sky.map.7.pm' says indirect_only='7': not a rule of this pmtk" \
        "$BIN/simd-gather" "$TMP/sky.map.7.pm" "$TMP/skyq.pm" --radius 0.1 -o "$TMP/mix7.pm"
else
    skip "headers of an unknown rule are refused" "python3-xxhash is not installed"
fi

# ---- bad lights: one line naming the light, the key and the value, exit 1, nothing written
# bad_light NAME PATTERN LIGHTS-JSON: trace-photons and trace-reference both refuse the scene.
bad_light() {
    local name=$1 pattern=$2
    lit_plane "$TMP/bad" 0.5 "$3" 3
    rm -f "$TMP/bad.pm" "$TMP/bad.exr"
    expect_error "$name (trace-photons)" "$pattern" "$BIN/trace-photons" "$TMP/bad/scene.json" -q -o "$TMP/bad.pm"
    expect_error "$name (trace-reference)" "$pattern" "$BIN/trace-reference" "$TMP/bad/scene.json" -q --spp 1 -o "$TMP/bad.exr"
    if [ -e "$TMP/bad.pm" ] || [ -e "$TMP/bad.exr" ]; then fail "$name: nothing written" "an output exists"; fi
}
SPOT='"position": [0, 1, 0], "intensity": [1, 1, 1], "direction": [0, -1, 0]'
bad_light "spot cone 0" "point_lights\[0\]\.cone: 0 degrees is outside \(0, 180\]" "\"point_lights\": [ { $SPOT, \"cone\": 0 } ]"
bad_light "spot cone 200" "point_lights\[0\]\.cone: 200 degrees is outside \(0, 180\]" "\"point_lights\": [ { $SPOT, \"cone\": 200 } ]"
bad_light "spot cone -5" "point_lights\[0\]\.cone: -5 degrees is outside \(0, 180\]" "\"point_lights\": [ { $SPOT, \"cone\": -5 } ]"
bad_light "spot without a direction" "point_lights\[0\]\.direction: missing" \
    '"point_lights": [ { "position": [0, 1, 0], "intensity": [1, 1, 1], "cone": 30 } ]'
bad_light "spot of direction 0" "point_lights\[0\]\.direction: is the zero vector" "\"point_lights\": [ { \"position\": [0, 1, 0], \"intensity\": [1, 1, 1], \"direction\": [0, 0, 0] } ]"
bad_light "spot of negative falloff" "point_lights\[0\]\.falloff: -1 is outside" "\"point_lights\": [ { $SPOT, \"falloff\": -1 } ]"
bad_light "sun of zero solid angle" "sun\.solid_angle: 0 sr is outside \(0, 2 pi\]" \
    '"sun": { "direction": [0, 1, 0], "radiance": [1, 1, 1], "solid_angle": 0 }'
bad_light "sun of negative radiance" "sun\.radiance: element 2 = -1 is outside \[0, 1e\+30\]" \
    '"sun": { "direction": [0, 1, 0], "radiance": [1, 1, -1], "solid_angle": 0.01 }'
bad_light "sun without a solid angle" "sun\.solid_angle: missing" '"sun": { "direction": [0, 1, 0], "radiance": [1, 1, 1] }'
bad_light "sun with direction and elevation" "sun: needs exactly one of 'direction' and 'elevation', not both" \
    '"sun": { "direction": [0, 1, 0], "elevation": 30, "azimuth": 0, "radiance": [1, 1, 1], "solid_angle": 0.01 }'
bad_light "sun with neither radiance nor irradiance" "sun: needs exactly one of 'radiance' and 'irradiance', found neither" \
    '"sun": { "direction": [0, 1, 0], "solid_angle": 0.01 }'
bad_light "sun elevation without azimuth" "sun\.azimuth: missing" '"sun": { "elevation": 30, "radiance": [1, 1, 1], "solid_angle": 0.01 }'
bad_light "sun elevation 100" "sun\.elevation: 100 .*outside" '"sun": { "elevation": 100, "azimuth": 0, "radiance": [1, 1, 1], "solid_angle": 0.01 }'
bad_light "sun of negative irradiance" "sun\.irradiance: element 0 = -3 is outside" \
    '"sun": { "direction": [0, 1, 0], "irradiance": [-3, 1, 1], "solid_angle": 0.01 }'
bad_light "sky of negative radiance" "sky\.radiance: element 0 = -0\.5 is outside" '"sky": { "radiance": [-0.5, 1, 1] }'
# JSON has no NaN; a NaN written as the bare word is a syntax error naming the line.
bad_light "sky of NaN radiance" "scene '.*' line [0-9]+ column [0-9]+" '"sky": { "radiance": [NaN, 1, 1] }'
bad_light "sky with an unknown key" "sky: unknown key 'color'" '"sky": { "radiance": [1, 1, 1], "color": 1 }'

# ---- scene-info lists the lights, and their power
lit_plane "$TMP/all" 0.5 "\"point_lights\": [ { \"position\": [0, 1, 0], \"intensity\": [1, 2, 3] }, { $SPOT, \"cone\": 60, \"falloff\": 2 } ],
  \"sun\": { \"direction\": [0, 2, 0], \"radiance\": [5, 5, 5], \"solid_angle\": 0.5 }, \"sky\": { \"radiance\": [0.25, 0.25, 0.25] }" 3
if "$BIN/scene-info" -q "$TMP/all/scene.json" >"$TMP/all.txt" && "$BIN/scene-info" -q --json "$TMP/all/scene.json" >"$TMP/all.json"; then
    if grep -q "^  light 0 at 0 1 0 intensity 1 2 3 W/sr$" "$TMP/all.txt" &&
        grep -q "^  light 1 at 0 1 0 intensity 1 1 1 W/sr spot toward 0 -1 0 cone 60 deg falloff 2$" "$TMP/all.txt" &&
        grep -q "^sun: toward 0 1 0 radiance 5 5 5 W/(m^2 sr) solid angle 0.5 sr$" "$TMP/all.txt" &&
        grep -q "^sky: radiance 0.25 0.25 0.25 W/(m^2 sr)$" "$TMP/all.txt" &&
        [ "$(jq -r '[.lights[].kind] | join(" ")' "$TMP/all.json")" = "point spot sun sky" ]; then
        pass "scene-info lists a point light, a spot, the sun and the sky (text and JSON)"
    else
        fail "scene-info light listing" "$(grep -E '^(  light|sun|sky)' "$TMP/all.txt" | tr '\n' ';')"
    fi
    # Power, channel 0: 4 pi 1 + 2 pi 1 (1 - cos 60) / 3 + the sun's 5 * 0.5 * pi R^2 + the sky's
    # 0.25 * 4 pi * pi R^2, R = 1.01 * sqrt(3^2 + 0.5^2 + 3^2) + 0.001 (the sphere around the box
    # of the plane and the point lights 1 m above it).
    want=$(awk -v p=$PI 'BEGIN { r = 1.01 * sqrt(18.25) + 0.001; printf "%.17g", 4 * p + 2 * p * 0.5 / 3 + 5 * 0.5 * p * r * r + 0.25 * 4 * p * p * r * r }')
    got=$(jq '.power_w[0]' "$TMP/all.json")
    if awk -v a="$got" -v b="$want" 'BEGIN { exit !(a / b > 1 - 1e-6 && a / b < 1 + 1e-6) }'; then
        pass "scene power of a point light, a spot, the sun and the sky: $got W (formula $want)"
    else
        fail "scene power" "$got W, formula $want W"
    fi
else
    fail "scene-info of a scene with every light" "$(cat "$TMP/all.txt" | head -3)"
fi

# ---- 4. a lat-long OpenEXR sky (docs/scene-format.md, Lights): row 0 is the zenith, columns
# turn about +y. The files are written byte by byte (uncompressed float RGB, made once with
# pm_exr_write_rgb), so that the test needs no image tool.
# 4 x 2, top row 2 (the upper hemisphere), bottom row 0
EXR_A=762f3101020000007479706500737472696e67000d0000007363616e6c696e65696d6167656e616d6500737472696e670003000000726762636f6d7072657373696f6e00636f6d7072657373696f6e0001000000006461746157696e646f7700626f783269001000000000000000000000000300000001000000646973706c617957696e646f7700626f7832690010000000000000000000000003000000010000006c696e654f72646572006c696e654f72646572000100000000706978656c417370656374526174696f00666c6f617400040000000000803f73637265656e57696e646f7743656e746572007632660008000000000000000000000073637265656e57696e646f77576964746800666c6f617400040000000000803f6368616e6e656c730063686c697374003700000042000200000000000000010000000100000047000200000000000000010000000100000052000200000000000000010000000100000000007901000000000000b10100000000000000000000300000000000004000000040000000400000004000000040000000400000004000000040000000400000004000000040000000400100000030000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000
# 4 x 2, top row 1 2 3 4 (quarters of the upper hemisphere by azimuth), bottom row 0
EXR_B=762f3101020000007479706500737472696e67000d0000007363616e6c696e65696d6167656e616d6500737472696e670003000000726762636f6d7072657373696f6e00636f6d7072657373696f6e0001000000006461746157696e646f7700626f783269001000000000000000000000000300000001000000646973706c617957696e646f7700626f7832690010000000000000000000000003000000010000006c696e654f72646572006c696e654f72646572000100000000706978656c417370656374526174696f00666c6f617400040000000000803f73637265656e57696e646f7743656e746572007632660008000000000000000000000073637265656e57696e646f77576964746800666c6f617400040000000000803f6368616e6e656c730063686c697374003700000042000200000000000000010000000100000047000200000000000000010000000100000052000200000000000000010000000100000000007901000000000000b10100000000000000000000300000000000803f0000004000004040000080400000803f0000004000004040000080400000803f0000004000004040000080400100000030000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000
# 2 x 1, pixel 1 channel G 7.0 (bytes 0000e040), the rest 1: made NaN or negative below
EXR_NAN=762f3101020000007479706500737472696e67000d0000007363616e6c696e65696d6167656e616d6500737472696e670003000000726762636f6d7072657373696f6e00636f6d7072657373696f6e0001000000006461746157696e646f7700626f783269001000000000000000000000000100000000000000646973706c617957696e646f7700626f7832690010000000000000000000000001000000000000006c696e654f72646572006c696e654f72646572000100000000706978656c417370656374526174696f00666c6f617400040000000000803f73637265656e57696e646f7743656e746572007632660008000000000000000000000073637265656e57696e646f77576964746800666c6f617400040000000000803f6368616e6e656c730063686c69737400370000004200020000000000000001000000010000004700020000000000000001000000010000005200020000000000000001000000010000000000710100000000000000000000180000000000803f0000803f0000803f0000e0400000803f0000803f
bin_file() { printf "$(echo "$2" | sed 's/../\\x&/g')" >"$1"; }
# With sky.radiance 0.5 the first map is 1 above the horizon: E = pi, L_out = 0.5 on albedo 0.5.
# The second, unscaled: each quarter of the upper hemisphere gives its radiance times pi / 4,
# E = 2.5 pi, L_out = 1.25 on albedo 0.5 (a sampler that ignored its luminance weights or a
# pdf off by the sine of the row would move it). Next-event estimation by the map's pixels is
# not cosine-weighted: with 64 light samples the direct buffer is off by about 6% RMS per pixel
# and trace-reference with 64 paths by 2.5 to 4% (measured), so their means over 1024 pixels
# have standard errors near 0.2% and 0.1%: the mean must be within 1%, the RMS below 12%,
# every pixel within 50%.
TOL_MAP="-v tmean=0.01 -v trms=0.12 -v tmax=0.5"
mkdir -p "$TMP/mapa" "$TMP/mapb"
bin_file "$TMP/mapa/sky.exr" "$EXR_A"
bin_file "$TMP/mapb/sky.exr" "$EXR_B"
LS=64 lit_plane "$TMP/mapa" 0.5 '"sky": { "map": "sky.exr", "radiance": [0.5, 0.5, 0.5] }' 3
TOL_D=$TOL_MAP TOL_R=$TOL_MAP REF_SPP=64 three_ways "EXR sky, 1 above the horizon, over a plane of albedo 0.5: L_out 0.5" \
    "$TMP/mapa/scene.json" -v kd=0.5 -v kind=const -v Ec=$PI
LS=64 lit_plane "$TMP/mapb" 0.5 '"sky": { "map": "sky.exr" }' 3
TOL_D=$TOL_MAP TOL_R=$TOL_MAP REF_SPP=64 three_ways "EXR sky, quarters of 1 2 3 4 above the horizon: L_out 1.25" \
    "$TMP/mapb/scene.json" -v kd=0.5 -v kind=const -v Ec=$(awk -v p=$PI 'BEGIN { print 2.5 * p }')
# bad maps: a NaN, a negative value, a missing file: one line naming the scene key and the file
bin_file "$TMP/nan.exr" "$(echo "$EXR_NAN" | sed 's/0000e040/0000c07f/')"
bin_file "$TMP/neg.exr" "$(echo "$EXR_NAN" | sed 's/0000e040/0000c0c0/')"
bad_light "EXR sky with a NaN" "sky\.map '\.\./nan\.exr': pixel \(1, 0\) channel G = nan is not a radiance" '"sky": { "map": "../nan.exr" }'
bad_light "EXR sky with a negative value" "sky\.map '\.\./neg\.exr': pixel \(1, 0\) channel G = -6 is not a radiance" \
    '"sky": { "map": "../neg.exr" }'
bad_light "EXR sky missing" "sky\.map.*missing\.exr" '"sky": { "map": "missing.exr" }'

# ---- 4b. the sky's frame (sky.rotate, sky.up): a rotated map is the rotated scene. The quarters
# map over a plane of albedo 0.5 seen from 0.5 m above, looking toward azimuth 45 degrees (fov 90:
# azimuths 0 to 90, the map's first column, 1). rotate 90 adds 90 to every azimuth of the map, so
# the camera sees the map's longitude 315 (the last column, 4); the same scene with the plane and
# the camera turned by rotate {axis: up, degrees: 90} under the unrotated map must give the same
# image, and so must the rotated scene turned onto +z up (plane and camera turned 90 degrees
# about +x) with sky.up [0, 0, 1]. The samplers draw the same numbers in both scenes and the turn maps
# one's directions onto the other's, so the direct buffer agrees pixel by pixel up to float
# rounding (1e-4 relative), where a wrong pdf, lookup or sampler would differ by the map's
# factors of 2 to 4; trace-reference agrees in the mean.
# sky_scene DIR SKY-EXTRA MESH-EXTRA EYE LOOK UP
sky_scene() {
    mkdir -p "$1"
    cp "$TMP/mapb/sky.exr" "$TMP/mapb/plane.obj" "$TMP/mapb/plane.mtl" "$1/"
    cat >"$1/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "sky-frame",
  "meshes": [ { "file": "plane.obj"$3 } ],
  "camera": { "eye": [$4], "look_at": [$5], "up": [$6], "fov_y": 90, "width": 24, "height": 24 },
  "sky": { "map": "sky.exr"$2 },
  "render": { "photons": 20000, "spp": 4, "seed": 1, "light_samples": 4 }
}
JSON
}
sky_scene "$TMP/fr-plain" "" "" "0, 0.5, 0" "1, 0.5, 1" "0, 1, 0"
sky_scene "$TMP/fr-rot" ', "rotate": 90' "" "0, 0.5, 0" "1, 0.5, 1" "0, 1, 0"
sky_scene "$TMP/fr-turned" "" ', "rotate": { "axis": [0, 1, 0], "degrees": 90 }' "0, 0.5, 0" "1, 0.5, -1" "0, 1, 0"
sky_scene "$TMP/fr-zup" ', "up": [0, 0, 1], "rotate": 90' \
    ', "matrix": [1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1]' \
    "0, 0, 0.5" "1, -1, 0.5" "0, 0, 1"
# frame_render NAME: its direct buffer (pixel centres) and trace-reference, as pm-exrdump text.
# The direct buffer of direct-vis mode: the light samples alone. In gather mode the secondary
# rays that escape share the sky with them (trace-gather-points.md, step 2), and those rays take
# a tangent frame fixed in the world, as trace-reference's do, which the turn does not carry.
frame_render() {
    local t=$TMP/fr-$1
    "$BIN/trace-gather-points" "$t/scene.json" --mode direct-vis --pixel center -q -o "$t.q.pm" --direct "$t.d.pm" &&
        "$BIN/composite" "$t.d.pm" -q -o "$t.d.exr" && "$BUILD/tests/pm-exrdump" "$t.d.exr" >"$t.d.txt" &&
        "$BIN/trace-reference" "$t/scene.json" -q --pixel center --spp 16 -o "$t.r.exr" &&
        "$BUILD/tests/pm-exrdump" "$t.r.exr" >"$t.r.txt"
}
# same_image A B: the largest relative difference of two pm-exrdump texts, and the top-left pixel of each
same_image() {
    awk 'FNR == NR { if (NF >= 5 && $1 != "size") for (c = 3; c <= 5; c++) a[FNR, c] = $c; next }
        NF >= 5 && $1 != "size" { for (c = 3; c <= 5; c++) { d = $c - a[FNR, c]; if (d < 0) d = -d
            m = (a[FNR, c] > $c ? a[FNR, c] : $c); r = m > 0 ? d / m : 0; if (r > worst) worst = r } }
        END { printf "%.3g\n", worst }' "$1" "$2"
}
if frame_render plain && frame_render rot && frame_render turned && frame_render zup; then
    sky_plain=$(awk '$1 == 0 && $2 == 0 { print $4 }' "$TMP/fr-plain.d.txt")
    sky_rot=$(awk '$1 == 0 && $2 == 0 { print $4 }' "$TMP/fr-rot.d.txt")
    if [ "$sky_plain" = 1 ] && [ "$sky_rot" = 4 ]; then
        pass "sky.rotate 90: the camera toward azimuth 45 sees the map's column of 1 unrotated, of 4 rotated"
    else
        fail "sky.rotate 90 turns the map the way azimuth grows" "top-left pixel: unrotated $sky_plain (want 1), rotated $sky_rot (want 4)"
    fi
    for pair in "rot turned" "rot zup"; do
        set -- $pair
        worst=$(same_image "$TMP/fr-$1.d.txt" "$TMP/fr-$2.d.txt")
        if awk -v w="$worst" 'BEGIN { exit !(w <= 1e-4) }'; then
            pass "rotated sky map = rotated scene ($1 vs $2, direct buffer: largest relative difference $worst)"
        else
            fail "rotated sky map = rotated scene ($1 vs $2, direct buffer)" "largest relative difference $worst"
        fi
        # trace-reference's BSDF samples take a tangent frame fixed in the world, which the turn
        # does not carry: the images agree in the mean (16 paths: about 0.4% over the plane).
        means=$(awk 'FNR == NR { if (NF >= 5 && $1 != "size") { a += $3 + $4 + $5; n++ } next }
            NF >= 5 && $1 != "size" { b += $3 + $4 + $5 } END { printf "%.5f %.5f\n", a / n, b / n }' \
            "$TMP/fr-$1.r.txt" "$TMP/fr-$2.r.txt")
        if echo "$means" | awk '{ d = $1 / $2 - 1; exit !(d * d < 0.015 ^ 2) }'; then
            pass "rotated sky map = rotated scene ($1 vs $2, trace-reference: mean pixel sums $means)"
        else
            fail "rotated sky map = rotated scene ($1 vs $2, trace-reference)" "mean pixel sums $means"
        fi
    done
else
    fail "sky frame scenes" "a stage failed"
fi
bad_light "sky.up of zero length" "sky\.up: is the zero vector" '"sky": { "radiance": [1, 1, 1], "up": [0, 0, 0] }'
bad_light "sky.rotate not a number" "sky\.rotate" '"sky": { "radiance": [1, 1, 1], "rotate": "east" }'
bad_light "preetham sky without a sun" "sky\.model: 'preetham' is lit by the scene's sun, and the scene has none" \
    '"sky": { "model": "preetham" }'
bad_light "preetham sky, sun below the horizon" "sky\.model: 'preetham' needs the sun above the horizon: its elevation is -10 degrees" \
    '"sun": { "elevation": -10, "azimuth": 0, "radiance": [1, 1, 1], "solid_angle": 0.01 }, "sky": { "model": "preetham" }'
bad_light "preetham sky of turbidity 1" "sky\.turbidity: 1 .*outside" \
    '"sun": { "elevation": 10, "azimuth": 0, "radiance": [1, 1, 1], "solid_angle": 0.01 }, "sky": { "model": "preetham", "turbidity": 1 }'
bad_light "unknown sky model" "sky\.model: 'hosek' is not a sky model" \
    '"sun": { "elevation": 10, "azimuth": 0, "radiance": [1, 1, 1], "solid_angle": 0.01 }, "sky": { "model": "hosek" }'
bad_light "turbidity without a model" "sky\.turbidity: goes with a sky model" '"sky": { "radiance": [1, 1, 1], "turbidity": 3 }'

# ---- 4c. the Preetham sky (sky.model, docs/scene-format.md): a sun of irradiance 100 W/m^2 at
# elevation 40 and the model's sky of turbidity 3 in a frame rotated 30 degrees, over the plane of
# albedo 0.5. No closed form for the sky's share; the photon pipeline and the direct buffer are
# held to trace-reference (64 paths; pixel centres) in the mean over the image (within 2% and
# 1%: the photon estimate's kernel and the samples' noise are well below that over 1024 pixels),
# and the sun's share alone must be its closed form 100 sin 40 (the model scaled to 0).
# (The model's formulas themselves: tests/unit/test_skymodel.c.)
PREETHAM='"sun": { "elevation": 40, "azimuth": 200, "irradiance": [100, 100, 100], "solid_angle": 6.8e-5 },
  "sky": { "model": "preetham", "turbidity": 3, "rotate": 30'
LS=16 lit_plane "$TMP/preetham" 0.5 "$PREETHAM }" 3
LS=16 lit_plane "$TMP/preetham0" 0.5 "$PREETHAM, \"radiance\": [0, 0, 0] }" 3
t=$TMP/preetham
mean_of() { awk 'NF >= 5 && $1 != "size" { s += $3 + $4 + $5; n += 3 } END { printf "%.6g\n", s / n }' "$1"; }
if REF_SPP=64 render_three "$t" "$t/scene.json" &&
    "$BIN/trace-reference" "$TMP/preetham0/scene.json" -q --pixel center --spp 4 -o "$t.s.exr" &&
    "$BUILD/tests/pm-exrdump" "$t.s.exr" >"$t.s.txt"; then
    ref=$(mean_of "$t.r.txt") pmap=$(mean_of "$t.i.txt") dbuf=$(mean_of "$t.d.txt") sunonly=$(mean_of "$t.s.txt")
    sunwant=$(awk -v p=$PI 'BEGIN { printf "%.6g", 0.5 / p * 100 * sin(40 * p / 180) }')
    for c in "photon map|$pmap|$ref|0.02" "direct buffer|$dbuf|$ref|0.01" "the sun alone, trace-reference|$sunonly|$sunwant|0.002"; do
        IFS='|' read -r name got want tol <<<"$c"
        if awk -v a="$got" -v b="$want" -v t="$tol" 'BEGIN { d = a / b - 1; exit !(d * d <= t * t) }'; then
            pass "preetham sky and sun over a plane: $name mean $got against $want (within $tol)"
        else
            fail "preetham sky and sun over a plane: $name" "mean $got, want $want within $tol"
        fi
    done
    if awk -v a="$ref" -v b="$sunonly" 'BEGIN { exit !(a > 1.1 * b) }'; then
        pass "the preetham sky adds light to the sun's ($ref against $sunonly)"
    else
        fail "the preetham sky adds light" "$ref with the sky, $sunonly without"
    fi
else
    fail "preetham sky and sun over a plane" "a stage failed"
fi

# ---- 5. two-sided area lights (top-level "two_sided_lights": true): the furnace of analytic.sh
# wound outward, so that every emitter's front faces away from the centre. One-sided, the
# inside is black; two-sided, it is the furnace again: L = Le / (1 - rho) = 2 for Le 1 and
# rho 0.5 everywhere inside (half of the photons leave outward and are lost, which the doubled
# power accounts for). The direct buffer without light samples is the emission Le = 1 seen
# from the back faces; the photon map's gather adds rho / pi * pi L = 1.
source tests/scenes/make-analytic.sh
two_sided() {
    local dir=$1 flag=$2
    mkdir -p "$dir"
    sphere_obj 1 48 out >"$dir/sphere.obj"
    printf 'newmtl wall\nKd 0.5 0.5 0.5\nKe 1 1 1\n' >"$dir/sphere.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "furnace-out",
  "two_sided_lights": $flag,
  "meshes": [ { "file": "sphere.obj" } ],
  "camera": { "eye": [0, 0, 0], "look_at": [0, 0, 1], "fov_y": 60, "width": 32, "height": 32 },
  "render": { "photons": 200000, "spp": 4, "seed": 1 }
}
JSON
}
two_sided "$TMP/two" true
two_sided "$TMP/one" false
t=$TMP/two
if "$BIN/trace-photons" "$t/scene.json" --photons 400000 -q -o - | "$BIN/build-photonmap" - -q -o "$t.map.pm" &&
    "$BIN/trace-gather-points" "$t/scene.json" --pixel center --mode direct-vis --light-samples 0 -q -o "$t.q.pm" --direct "$t.d.pm" &&
    "$BIN/simd-gather" "$t.map.pm" "$t.q.pm" --k 200 -q -o "$t.i.pm" && "$BIN/pm-info" -r "$t.q.pm" >"$t.hits" &&
    "$BIN/composite" "$t.d.pm" -q -o "$t.d.exr" && "$BUILD/tests/pm-exrdump" "$t.d.exr" >"$t.d.txt" &&
    "$BIN/composite" "$t.d.pm" "$t.i.pm" -q -o "$t.f.exr" && "$BUILD/tests/pm-exrdump" "$t.f.exr" >"$t.f.txt" &&
    "$BIN/trace-reference" "$t/scene.json" -q --pixel center --spp 64 -o "$t.r.exr" && "$BUILD/tests/pm-exrdump" "$t.r.exr" >"$t.r.txt" &&
    "$BIN/trace-reference" "$TMP/one/scene.json" -q --pixel center --spp 4 -o "$TMP/one.r.exr" &&
    "$BUILD/tests/pm-exrdump" "$TMP/one.r.exr" >"$TMP/one.r.txt"; then
    judge "two-sided emitters seen from behind: the direct buffer is Le = 1" "$t.hits" "$t.d.txt" \
        -v tmean=1e-6 -v trms=1e-6 -v tmax=1e-6 -v kd=1 -v kind=const -v Ec=$PI
    judge "two-sided furnace wound outward, photon map + emission: L = Le / (1 - rho) = 2" "$t.hits" "$t.f.txt" \
        -v tmean=0.02 -v trms=0.15 -v tmax=0.5 -v kd=1 -v kind=const -v Ec=$(awk -v p=$PI 'BEGIN { print 2 * p }')
    judge "two-sided furnace wound outward, trace-reference: L = 2" "$t.hits" "$t.r.txt" \
        -v tmean=0.02 -v trms=0.15 -v tmax=0.5 -v kd=1 -v kind=const -v Ec=$(awk -v p=$PI 'BEGIN { print 2 * p }')
    # One-sided, a few paths escape through the seams between facets and find a front face
    # outside (measured: 5e-6 at most): black means below 1e-4 here, against 2 two-sided.
    if awk 'NR > 1 && ($3 > 1e-4 || $4 > 1e-4 || $5 > 1e-4) { bad = 1 } END { exit bad }' "$TMP/one.r.txt"; then
        pass "the same sphere one-sided: black inside (trace-reference, every pixel below 1e-4)"
    else
        fail "one-sided emitters wound outward" "light inside"
    fi
else
    fail "two-sided furnace" "a stage failed"
fi
sed 's/"two_sided_lights": true/"two_sided_lights": 1/' "$t/scene.json" >"$t/bad.json"
expect_error "two_sided_lights must be a boolean" "two_sided_lights: must be true or false" \
    "$BIN/trace-reference" "$t/bad.json" -q -o "$TMP/x.exr"

# ---- 6. one light module (render/light.{c,h}): nothing outside it names a light kind ----
# light_kind_names DIR...: every line of C code (comments left out) under DIR that names a light
# kind outside light.c and light.h: the kind enum (PM_LIGHT_POINT ...), the per-kind samplers and
# pdfs light.c switches over, a light kind as a bare number (the photon tracer's old
# "kind == 2"), and in the three tracers the scene's own light fields (s->has_sun,
# s->lights[i], ...), which only light.c reads. Each line is printed as FILE:LINE:code.
# The awk program that prints each line's code, /* comments */ (across lines too) removed.
LIGHT_CODE='FNR == 1 { inc = 0 }
    { line = $0; out = ""
      while (length(line)) {
          if (inc) { i = index(line, "*/"); if (!i) { line = "" } else { line = substr(line, i + 2); inc = 0 } }
          else { i = index(line, "/*"); if (!i) { out = out line; line = "" }
                 else { out = out substr(line, 1, i - 1); line = substr(line, i + 2); inc = 1 } } }
      if (out ~ /[^ \t]/) print FILENAME ":" FNR ":" out }'
light_kind_names() {
    local kinds='PM_LIGHT_(POINT|SPOT|AREA|SUN|SKY|KINDS)\b'
    local prims='\bpm_(point_light_emit|point_light_emit_pdf|point_light_toward|spot_factor|area_light_sample|area_light_pdf|sun_sample|sun_pdf|sky_sample|sky_pdf|sky_radiance|env_emit|env_radiance|envmap_sample|envmap_pdf|envmap_pixel)\b'
    local bare='\bkind\s*(==|!=|>=|<=|<|>|=)\s*[0-9]'
    local fields='\bs(->|\.)(lights|nlights|emissive|nemissive|has_sun|has_sky|sun|sky|envmap|two_sided_lights)\b'
    find "$@" -name '*.[ch]' ! -name light.c ! -name light.h -print0 | xargs -0 -r awk "$LIGHT_CODE" |
        grep -E "$kinds|$prims|$bare"
    find "$@" \( -name photontrace.c -o -name eyetrace.c -o -name pathtrace.c \) -print0 |
        xargs -0 -r awk "$LIGHT_CODE" | grep -E "$fields"
    return 0
}
out=$(light_kind_names common stages)
if [ -n "$out" ]; then
    fail "a light kind named outside render/light.c" "$(echo "$out" | head -5 | tr '\n' ' ')"
else
    pass "no light kind named outside render/light.c (common/, stages/)"
fi
# The check itself: a planted tracer and stage that name kinds are caught, line by line; light.c's
# own switch and a comment that names a sampler are not.
mkdir -p "$TMP/kinds/render" "$TMP/kinds/stage"
printf 'int a(const light_t *l) { return l->kind == 2; }\nint b(int k) { return k == PM_LIGHT_SUN; }\n' \
    >"$TMP/kinds/stage/main.c"
printf 'void c(const pm_scene_t *s) { if (s->has_sky) pm_sky_sample(s, 0, 0, 0, 0); }\nint kindness = 3;\n' \
    >"$TMP/kinds/render/pathtrace.c"
printf '/* pm_env_emit of old,\n * pm_sky_pdf too */ int e; /* s->has_sun */\n' >"$TMP/kinds/render/scene.c"
printf 'int d(int k) { return k == PM_LIGHT_SUN; }\n' >"$TMP/kinds/render/light.c"
got=$(light_kind_names "$TMP/kinds" | sed 's|.*/kinds/||' | cut -d: -f1,2 | sort | tr '\n' ' ')
if [ "$got" = "render/pathtrace.c:1 render/pathtrace.c:1 stage/main.c:1 stage/main.c:2 " ]; then
    pass "the kind check catches a bare kind number, the enum, a per-kind sampler and a scene light field"
else
    fail "the kind check on planted violations" "found '$got'"
fi

# scene-info's kind-free counts for drivers: every light, and those that take light_samples.
lit_plane "$TMP/cnt1" 0.5 '"point_lights": [ { "position": [0, 1, 0], "intensity": [1, 1, 1] },
    { "position": [0, 1, 0], "intensity": [1, 1, 1], "direction": [0, -1, 0], "cone": 30 } ]'
lit_plane "$TMP/cnt2" 0.5 '"sun": { "direction": [0, 1, 0], "radiance": [1, 1, 1], "solid_angle": 0.01 },
  "sky": { "radiance": [1, 1, 1] }, "point_lights": [ { "position": [0, 1, 0], "intensity": [1, 1, 1] } ]'
# cnt1: a point light and a spot (delta lights: no light samples); cnt2: a point light, the sun
# and the sky; the Cornell box: two emissive triangles.
for c in "cnt1 2 0" "cnt2 3 2" "cornell 2 2"; do
    set -- $c
    scene=$TMP/$1/scene.json
    [ "$1" = cornell ] && scene=scenes/cornell-box/scene.json
    json=$("$BIN/scene-info" -q --json "$scene" | jq -r '"\(.lights_total) \(.sampled_lights)"')
    text=$("$BIN/scene-info" -q "$scene" | sed -n 's/^lights: \([0-9]*\) in all, \([0-9]*\) sampled .*/\1 \2/p')
    if [ "$json" = "$2 $3" ] && [ "$text" = "$json" ]; then
        pass "scene-info $1: lights_total $2, sampled_lights $3 (text and JSON)"
    else
        fail "scene-info $1 light counts" "json '$json' text '$text', want '$2 $3'"
    fi
done
