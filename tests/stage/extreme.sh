# extreme.sh: the stiff and extreme cases of issue 8 (docs/extreme-cases.md), through every
# stage: trace-photons, build-photonmap, trace-gather-points, hilbert-sort, simd-gather,
# composite, measure-error. `make test-extreme` runs this script alone. Each check's message
# says what must hold. Scenes come from tests/scenes/make-box.sh and make-extreme.sh.
#
# Everywhere: no NaN or Inf in any output. The readers reject a non-finite value in any
# channel of any pmtk file, so `pm-info FILE` exiting 0 proves a file finite; EXR images are
# read back with pm-exrdump and every value checked.
# programs: build-photonmap composite hilbert-sort measure-error scene-info simd-gather trace-gather-points trace-photons trace-reference
source tests/scenes/make-box.sh
source tests/scenes/make-extreme.sh
PI=3.141592653589793
LIGHT='[{"position":[0.1,0.2,0.3],"intensity":[1,1,1]}]'

# stat FILE KEY: a number from a --stats JSON file.
stat() { jq -r ".$2" "$1"; }

# finite NAME FILES...: every pmtk file reads back whole (so holds no NaN/Inf), every EXR's
# pixels are finite numbers.
finite() {
    local name=$1 f bad=""
    shift
    for f in "$@"; do
        case "$f" in
        *.exr)
            "$BUILD/tests/pm-exrdump" "$f" >"$TMP/dump.txt" 2>&1 &&
                awk 'NR > 1 { for (i = 3; i <= 5; i++) if ($i !~ /^-?[0-9.]+(e[-+][0-9]+)?$/) exit 1 }' \
                    "$TMP/dump.txt" || bad+=" $(basename "$f")" ;;
        *) "$BIN/pm-info" -q "$f" >/dev/null 2>&1 || bad+=" $(basename "$f")" ;;
        esac
    done
    if [ -z "$bad" ]; then pass "$name: every output finite (no NaN or Inf)"; else fail "$name" "not finite or unreadable:$bad"; fi
}

# chain SCENE NAME [trace-photons options]: the whole pipeline in gather mode into $TMP/NAME.*:
# photons without the first hits of point lights, sun and sky and queries with secondary direct
# light (that light comes from trace-gather-points' shadow rays, at the gather points too; an
# indirect map with plain queries, as here before, lost it, which simd-gather now refuses),
# queries sorted along the Hilbert curve, the gather ($GATHER, default k 50), composite to
# EXR and PNG.
# Fails (returns non-zero) when any stage does; NAME.err holds the stages' stderr.
# Pixel centres (--pixel center): the checks hold pixels against values at the pixel's centre
# (the lamp's pixel is Ke only where its centre sees the 0.1 mm lamp).
chain() {
    local scene=$1 n=$2; shift 2
    local o=$TMP/$n
    {
        "$BIN/trace-photons" "$scene" -q --stats "$o.tp.json" --indirect-only "$@" -o "$o.ph.pm" &&
            "$BIN/build-photonmap" "$o.ph.pm" -q -o "$o.map.pm" &&
            "$BIN/trace-gather-points" "$scene" --spp 8 --pixel center --secondary-direct -q -o "$o.q.pm" \
                --direct "$o.d.pm" &&
            "$BIN/hilbert-sort" "$o.q.pm" -q -o "$o.s.pm" &&
            "$BIN/simd-gather" "$o.map.pm" "$o.s.pm" ${GATHER:---k 50} -q -o "$o.i.pm" &&
            "$BIN/composite" "$o.d.pm" "$o.i.pm" -q -o "$o.exr" --png "$o.png" &&
            "$BUILD/tests/pm-exrdump" "$o.exr" >"$o.txt"
    } 2>"$o.err"
}
outputs() { local o=$TMP/$1; echo "$o.ph.pm $o.map.pm $o.q.pm $o.d.pm $o.s.pm $o.i.pm $o.exr"; }

# ratio A B R TOL: every pixel of image A is R times that of B within relative TOL (both
# zero passes); prints the worst deviation.
ratio() {
    awk -v r="$3" -v tol="$4" 'FNR == 1 { next } NR == FNR { v[FNR] = $3 " " $4 " " $5; next }
        { split(v[FNR], a, " "); for (i = 1; i <= 3; i++) { w = r * $(i + 2); d = a[i] - w; if (d < 0) d = -d
              e = (w == 0) ? (a[i] == 0 ? 0 : 1) : d / (w < 0 ? -w : w); if (e > worst) worst = e; n++ } }
        END { printf "worst relative deviation %.3g over %d values", worst, n; exit !(n > 0 && worst <= tol) }' "$1" "$2"
}

# mean FILE: the mean of all channels of an EXR dump.
mean() { awk 'NR > 1 { s += $3 + $4 + $5; n += 3 } END { printf "%.9g", s / n }' "$1"; }

# ---- 1. Albedo 0.999 in a closed room -------------------------------------------------
# The bounce series sum rho^d converges slowly: the room holds Phi / (1 - rho) = 1000 Phi.
# Russian roulette survives with the albedo, so photons keep their power, paths end by
# themselves (mean 1000 bounces) and the sum over bounces is unbiased: the total power of
# the stored photons must match 3 * 4 pi / (1 - rho) W within 4 standard errors of the
# per-path sums (and that error must be small enough, < 6%, for the check to mean
# something). Before the fix, a survival cap of 0.95 gave 15% of it, 57 errors low.
make_box "$TMP/r999" 0.999 "$LIGHT"
"$BIN/trace-photons" "$TMP/r999/scene.json" -n 1000 -q --stats "$TMP/r999.json" -o "$TMP/r999.ph.pm"
want=$(awk -v p=$PI 'BEGIN { printf "%.9g", 3 * 4 * p / (1 - 0.999) }')
if "$BIN/pm-info" -r "$TMP/r999.ph.pm" | awk -v want="$want" -v n=1000 '
        $1 !~ /^[0-9]+$/ || NF < 11 { next }
        $NF == 0 && seen { q += path * path; path = 0 }
        { p = $5 + $6 + $7; s += p; path += p; seen = 1 }
        END { q += path * path; se = sqrt(q - s * s / n)
              printf "stored %.6g W, closed form %.6g W, standard error %.3g W", s, want, se
              exit !((s - want) ^ 2 < (4 * se) ^ 2 && se < 0.06 * want) }' >"$TMP/why"; then
    pass "albedo 0.999: the stored power sums over bounces to Phi / (1 - rho) within 4 standard errors ($(cat "$TMP/why"))"
else
    fail "albedo 0.999 energy" "$(cat "$TMP/why")"
fi
# Paths bounded: none reached --max-bounces (16384, a cut would bias), none escaped the
# closed room, and the longest is far beyond the 180 bounces a 0.95 cap allowed.
cap=$(stat "$TMP/r999.json" capped) esc=$(stat "$TMP/r999.json" escaped) long=$(stat "$TMP/r999.json" longest_path)
if [ "$cap" = 0 ] && [ "$esc" = 0 ] && [ "$long" -gt 2000 ] && [ "$long" -lt 16384 ]; then
    pass "albedo 0.999: no path capped or escaped; the longest ($long bounces) ended by Russian roulette"
else
    fail "albedo 0.999 paths" "capped $cap, escaped $esc, longest $long"
fi
# The image (direct-vis, global map): radiance rho / pi * E, where E is near uniform at
# rho = 0.999 (direct light is 0.1% of it) and averages the photons' total power over the
# walls' 24 m^2. Mean within 5% (kernel losses at the room's edges are about 1%).
"$BIN/build-photonmap" "$TMP/r999.ph.pm" -q -o "$TMP/r999.map.pm" &&
    "$BIN/trace-gather-points" "$TMP/r999/scene.json" --mode direct-vis -q -o "$TMP/r999.q.pm" &&
    "$BIN/simd-gather" "$TMP/r999.map.pm" "$TMP/r999.q.pm" --k 100 -q -o "$TMP/r999.i.pm" &&
    "$BIN/composite" "$TMP/r999.i.pm" -q -o "$TMP/r999.exr" && "$BUILD/tests/pm-exrdump" "$TMP/r999.exr" >"$TMP/r999.txt"
stored=$("$BIN/pm-info" -r "$TMP/r999.ph.pm" | awk '$1 ~ /^[0-9]+$/ && NF >= 11 { s += $5 } END { printf "%.9g", s }')
L=$(awk -v p=$PI -v s="$stored" 'BEGIN { printf "%.6g", 0.999 / p * s / 24 }')
m=$(mean "$TMP/r999.txt")
if awk -v m="$m" -v l="$L" 'BEGIN { exit !((m / l - 1) ^ 2 < 0.05 ^ 2) }'; then
    pass "albedo 0.999: mean image radiance $m = rho/pi * (stored W per channel) / 24 m^2 = $L within 5%"
else
    fail "albedo 0.999 image" "mean $m, expected $L"
fi
finite "albedo 0.999" "$TMP/r999.ph.pm" "$TMP/r999.map.pm" "$TMP/r999.q.pm" "$TMP/r999.i.pm" "$TMP/r999.exr"

# ---- 2. Lights from 1e-20 W to 1e20 W ---------------------------------------------------
# Everything is linear in the light's power and the random numbers do not depend on it, so
# each image is exactly the 1 W image times the power, to float rounding (1e-5 relative,
# every pixel); nothing underflows to zero or overflows.
for pw in 1 1e-20 1e20; do
    make_box "$TMP/w$pw" 0.5 "[{\"position\":[0.1,0.2,0.3],\"intensity\":[$(awk -v w=$pw -v p=$PI 'BEGIN { i = w / (4 * p); printf "%.17g,%.17g,%.17g", i, i, i }')]}]"
    chain "$TMP/w$pw/scene.json" "w$pw" -n 20000 || fail "light of $pw W: a stage failed" "$(head -c 300 "$TMP/w$pw.err")"
done
for pw in 1e-20 1e20; do
    if ratio "$TMP/w$pw.txt" "$TMP/w1.txt" "$pw" 1e-5 >"$TMP/why"; then
        pass "light of $pw W per channel: every pixel is $pw times the 1 W image ($(cat "$TMP/why"))"
    else
        fail "light of $pw W" "$(cat "$TMP/why")"
    fi
    finite "light of $pw W" $(outputs "w$pw")
done
if awk 'NR > 1 && $3 > 0 { n++ } END { exit !(n > 200) }' "$TMP/w1e-20.txt"; then
    pass "light of 1e-20 W: the image is not flushed to zero (more than 200 of 256 pixels lit)"
else
    fail "light of 1e-20 W" "the image is (nearly) black"
fi

# ---- 3. Scenes scaled by 1e-4 and 1e5 ----------------------------------------------------
# Ray offsets scale with the scene, so the same photons land on the same walls (no acne: no
# photon re-hits its own surface, none leaks out of the closed room) and, with the light's
# intensity scaled by s^2, every irradiance and so every pixel is as at scale 1: the direct
# buffer within 1e-4 per pixel (shadow-ray acne would blacken pixels), the whole image
# within rounding (relative MSE below 1e-6 against the unscaled image: the same random
# numbers trace the same paths; measured 1e-13). The camera is moved off the room's axis: from the centre, the rays of
# the diagonal pixels meet the room's edges exactly, and which wall they hit is decided by
# rounding (case 7 checks that they hit one).
offaxis() { jq '.camera.eye = [0.0123, 0.0071, 0.9]' "$1/scene.json" >"$1/s.tmp" && mv "$1/s.tmp" "$1/scene.json"; }
make_box "$TMP/s1" 0.5 "$LIGHT"
offaxis "$TMP/s1"
chain "$TMP/s1/scene.json" s1 -n 20000 || fail "unscaled box: a stage failed" "$(head -c 300 "$TMP/s1.err")"
"$BIN/composite" "$TMP/s1.d.pm" -q -o "$TMP/s1.d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/s1.d.exr" >"$TMP/s1.d.txt"
for s in 1e-4 1e5; do
    make_box "$TMP/s$s" 0.5 "$LIGHT"
    offaxis "$TMP/s$s"
    scale_scene "$TMP/s$s" "$s"
    if ! chain "$TMP/s$s/scene.json" "s$s" -n 20000; then
        fail "box scaled by $s: a stage failed" "$(head -c 300 "$TMP/s$s.err")"
        continue
    fi
    esc=$(stat "$TMP/s$s.tp.json" escaped) st=$(stat "$TMP/s$s.tp.json" stored) st1=$(stat "$TMP/s1.tp.json" stored)
    if [ "$esc" = 0 ] && awk -v a="$st" -v b="$st1" 'BEGIN { exit !((a / b - 1) ^ 2 < 0.01 ^ 2) }'; then
        pass "box scaled by $s: no photon lost ($esc escaped), $st stored against $st1 unscaled"
    else
        fail "box scaled by $s: photons" "escaped $esc, stored $st (unscaled $st1)"
    fi
    "$BIN/composite" "$TMP/s$s.d.pm" -q -o "$TMP/s$s.d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/s$s.d.exr" >"$TMP/s$s.d.txt"
    if ratio "$TMP/s$s.d.txt" "$TMP/s1.d.txt" 1 1e-4 >"$TMP/why"; then
        pass "box scaled by $s: direct light equals the unscaled box's, no shadow acne ($(cat "$TMP/why"))"
    else
        fail "box scaled by $s: direct light" "$(cat "$TMP/why")"
    fi
    "$BIN/measure-error" "$TMP/s$s.exr" "$TMP/s1.exr" -q -o "$TMP/me$s.json"
    rel=$(stat "$TMP/me$s.json" relmse)
    if awk -v r="$rel" 'BEGIN { exit !(r < 1e-6) }'; then
        pass "box scaled by $s: the image equals the unscaled one within rounding (relative MSE $rel < 1e-6)"
    else
        fail "box scaled by $s: image" "relative MSE $rel"
    fi
    finite "box scaled by $s" $(outputs "s$s")
done

# ---- 4. The gather radius a millionth and a thousand times the scene's size --------------
# Direct-vis queries (one per pixel, weight kd/pi) against the global map of each box above
# (scene size D = 2 s m). Radius 1e-6 D: no photon lies that close to a query, every pixel
# is exactly 0 (not NaN). Radius 1e3 D: every photon is in every query's kernel, and with
# the uniform kernel the estimate is the closed form for a uniform density, kd/pi * P /
# (pi h^2), P the power of the photons on the query's wall (the normal test leaves out the
# others): every pixel within 1e-5.
for s in 1 1e-4 1e5; do
    sc=$TMP/s$s/scene.json
    D=$(awk -v s=$s 'BEGIN { printf "%.9g", 2 * s }')
    "$BIN/build-photonmap" "$TMP/s$s.ph.pm" --map indirect -q -o "$TMP/g$s.map.pm" &&
        "$BIN/trace-gather-points" "$sc" --mode direct-vis -q -o "$TMP/g$s.q.pm" || fail "radius, scale $s" "map or queries failed"
    for f in 1e-6 1e3; do
        h=$(awk -v d=$D -v f=$f 'BEGIN { printf "%.9g", d * f }')
        "$BIN/simd-gather" "$TMP/g$s.map.pm" "$TMP/g$s.q.pm" --radius "$h" --kernel uniform -q \
            --stats "$TMP/g$s-$f.json" -o "$TMP/g$s-$f.pm" 2>"$TMP/err" || fail "radius $h m" "$(cat "$TMP/err")"
        "$BIN/composite" "$TMP/g$s-$f.pm" -q -o "$TMP/g$s-$f.exr" && "$BUILD/tests/pm-exrdump" "$TMP/g$s-$f.exr" >"$TMP/g$s-$f.txt"
        finite "scale $s, radius $h m" "$TMP/g$s-$f.pm" "$TMP/g$s-$f.exr"
    done
    h=$(awk -v d=$D 'BEGIN { printf "%.9g", d * 1e-6 }')
    if awk 'NR > 1 && ($3 != 0 || $4 != 0 || $5 != 0) { exit 1 }' "$TMP/g$s-1e-6.txt" &&
        [ "$(stat "$TMP/g$s-1e-6.json" shader_ops)" = 0 ]; then
        pass "scale $s, radius $h m (1e-6 of the scene): no photon in any kernel, every pixel exactly 0"
    else
        fail "scale $s, radius $h m" "nonzero pixels or shader_ops $(stat "$TMP/g$s-1e-6.json" shader_ops)"
    fi
    h=$(awk -v d=$D 'BEGIN { printf "%.9g", d * 1e3 }')
    # per wall (the photon normal), the summed power; each pixel's wall from its query's normal
    { "$BIN/pm-info" -r "$TMP/g$s.map.pm"; echo "@@"; "$BIN/pm-info" -r "$TMP/g$s.q.pm"; echo "@@"; cat "$TMP/g$s-1e3.txt"; } |
        awk -v h="$h" -v p=$PI '
            /^@@/ { part++; if (part == 1) for (k in P) { kk = k; gsub(/-0/, "0", kk); Q[kk] += P[k] }; next }
            part == 0 && $1 ~ /^[0-9]+$/ && NF >= 12 { w = $10 " " $11 " " $12; P[w] += $7; next }
            part == 1 && $1 ~ /^[0-9]+$/ && NF >= 11 { wall[$11] = $5 " " $6 " " $7; next }
            part == 2 && $1 ~ /^[0-9]+$/ && NF == 5 {
                px = $2 * 16 + $1; w = wall[px]; gsub(/-0/, "0", w)
                want = 0.5 / p * Q[w] / (p * h * h); if (want == 0) { bad++; next }
                e = $3 / want - 1; if (e < 0) e = -e; if (e > worst) worst = e; n++ }
            END { printf "worst relative deviation %.3g over %d pixels, %d without a wall", worst, n, bad
                  exit !(n == 256 && bad == 0 && worst < 1e-5) }' >"$TMP/why"
    if [ "${PIPESTATUS[1]}" = 0 ]; then
        pass "scale $s, radius $h m (1e3 of the scene): every photon of the wall in every query, kd/pi * P_wall / (pi h^2) ($(cat "$TMP/why"))"
    else
        fail "scale $s, radius $h m" "$(cat "$TMP/why")"
    fi
done

# ---- 5. A billion-to-one dynamic range -----------------------------------------------------
# A 0.1 mm emitter of Ke 1e9 W/(m^2 sr) (31 W per channel) is the only light; the centre
# pixel sees it, the walls are about 0.4 W/(m^2 sr) on average (the camera sees those lit
# only indirectly: the lamp faces it, and lights the wall behind it): the centre pixel is Ke
# to float rounding, every other pixel finite and between 1e-3 and 10 (lit, and nothing of
# the lamp's radiance smeared into them), so the image spans more than 1e9 to 1. A half-float
# EXR cannot hold 1e9: composite --half refuses with one line, and writes nothing.
make_tiny_light "$TMP/tiny" 1e9 1e-4
if chain "$TMP/tiny/scene.json" tiny -n 20000; then
    if awk 'NR == 1 { next } $1 == 7 && $2 == 7 { c = $3; next } { if (!($3 > 1e-3 && $3 < 10)) bad++; if ($3 < lo || !lo) lo = $3 }
            END { printf "centre %.9g, dimmest %.3g, %d others outside [1e-3, 10]", c, lo, bad
                  exit !(bad == 0 && (c / 1e9 - 1) ^ 2 < 1e-12 && c / lo > 1e9) }' "$TMP/tiny.txt" >"$TMP/why"; then
        pass "billion-to-one: the lamp's pixel is Ke = 1e9, the walls lit and unsmeared ($(cat "$TMP/why"))"
    else
        fail "billion-to-one image" "$(cat "$TMP/why")"
    fi
    finite "billion-to-one" $(outputs tiny)
    expect_error "billion-to-one: composite --half refuses a pixel beyond the half range" "beyond half" \
        "$BIN/composite" "$TMP/tiny.d.pm" "$TMP/tiny.i.pm" --half -o "$TMP/tiny-half.exr"
    [ -e "$TMP/tiny-half.exr" ] && fail "composite --half: no partial file" "tiny-half.exr exists" ||
        pass "composite --half: no file after the refusal"
else
    fail "billion-to-one: a stage failed" "$(head -c 300 "$TMP/tiny.err")"
fi

# ---- 6. Degenerate and sliver triangles, coincident surfaces -------------------------------
# The box of case 3 plus zero-area triangles (left out and counted), slivers 1e-6 to 1e-9 m
# wide (one of them an emitter), and a second floor coincident with the first: every stage
# runs, every output is finite, and the image is the plain box's within 5% on average (the
# sliver lamp adds 1.3% of the power; the doubled floor has the same albedo).
make_box "$TMP/odd" 0.5 "$LIGHT"
offaxis "$TMP/odd"
add_oddities "$TMP/odd"
if "$BIN/scene-info" "$TMP/odd/scene.json" | grep -q '^triangles: 16 (3 degenerate left out)$'; then
    pass "oddities: the three zero-area triangles (one only in float) are left out and counted"
else
    fail "oddities: scene-info" "$("$BIN/scene-info" "$TMP/odd/scene.json" 2>&1 | head -3 | tr '\n' ' ')"
fi
if chain "$TMP/odd/scene.json" odd -n 20000; then
    a=$(mean "$TMP/odd.txt") b=$(mean "$TMP/s1.txt")
    if awk -v a="$a" -v b="$b" 'BEGIN { exit !((a / b - 1) ^ 2 < 0.05 ^ 2) }'; then
        pass "oddities: the image's mean $a is the plain box's $b within 5%"
    else
        fail "oddities: image" "mean $a against $b"
    fi
    finite "oddities" $(outputs odd)
else
    fail "oddities: a stage failed" "$(head -c 300 "$TMP/odd.err")"
fi

# ---- 7. Empty scene, no lights, camera inside geometry -----------------------------------
# (docs/extreme-cases.md says why each is what it is.)
# An empty scene with a light: valid and black. Every photon escapes (0 stored), every
# camera ray too (0 queries), the gather of nothing is 0, the image exactly 0.
mkdir -p "$TMP/empty"
cat >"$TMP/empty/scene.json" <<'JSON'
{ "pmtk_scene": 1, "name": "empty",
  "camera": { "eye": [0, 0, 1], "look_at": [0, 0, 0], "fov_y": 60, "width": 8, "height": 8 },
  "point_lights": [ { "position": [0, 0, 0], "intensity": [1, 1, 1] } ] }
JSON
if chain "$TMP/empty/scene.json" empty -n 1000; then
    if [ "$(stat "$TMP/empty.tp.json" stored)" = 0 ] && [ "$(stat "$TMP/empty.tp.json" escaped)" = 1000 ] &&
        awk 'NR > 1 && ($3 != 0 || $4 != 0 || $5 != 0) { exit 1 } END { exit NR != 65 }' "$TMP/empty.txt"; then
        pass "empty scene: every stage succeeds, all 1000 photons escape, the 8 x 8 image is exactly black"
    else
        fail "empty scene" "stored $(stat "$TMP/empty.tp.json" stored), image $(head -3 "$TMP/empty.txt" | tr '\n' ' ')"
    fi
    finite "empty scene" $(outputs empty)
else
    fail "empty scene: a stage failed" "$(head -c 300 "$TMP/empty.err")"
fi
# No lights: trace-photons refuses with one line and exit 1 (a lightless scene is almost
# always a forgotten light or a missing Ke, and its photon map would be empty); the camera
# side needs no light and gives a black direct buffer.
make_box "$TMP/dark" 0.5 '[]'
expect_error "no lights: trace-photons says so in one line and exits 1" "no light with positive power" \
    "$BIN/trace-photons" "$TMP/dark/scene.json" -o "$TMP/dark.ph.pm"
[ -e "$TMP/dark.ph.pm" ] && fail "no lights: no partial file" "dark.ph.pm exists" || pass "no lights: no photons file left behind"
if "$BIN/trace-gather-points" "$TMP/dark/scene.json" -q -o "$TMP/dark.q.pm" --direct "$TMP/dark.d.pm" &&
    "$BIN/pm-info" -r "$TMP/dark.d.pm" | awk '$1 ~ /^[0-9]+$/ && ($2 != 0 || $3 != 0 || $4 != 0) { exit 1 }'; then
    pass "no lights: trace-gather-points writes queries and an all-zero direct buffer"
else
    fail "no lights: trace-gather-points" "failed or direct light without a light"
fi
# Camera inside a closed box within a lit room: the right answer is black. No light may
# leak through the zero-thickness walls: not by shadow rays (acne), not by photons (none
# gets in), not by the gather at a radius below the gaps (0.02 m): photons on the outer faces
# face the other way, and the nearest photons that face the same way as an inner face lie
# on the room's wall 0.04 m behind the box's back face. At 0.05 m the gather reaches them
# (842 photon-query pairs), and with --k the radius grows until the dark queries find
# photons (0.23 m here): the known leak of radius-based gathering (docs/extreme-cases.md).
make_box "$TMP/cell" 0.5 "$LIGHT"
add_cube_around_camera "$TMP/cell"
if GATHER="--radius 0.02" chain "$TMP/cell/scene.json" cell -n 20000; then
    nq=$("$BIN/pm-info" --header "$TMP/cell.q.pm" | sed -n 's/^COUNT=//p')
    if [ "$nq" -gt 0 ] && awk 'NR > 1 && ($3 != 0 || $4 != 0 || $5 != 0) { exit 1 }' "$TMP/cell.txt"; then
        pass "camera inside a closed box: $nq queries on its inner walls, every pixel exactly black"
    else
        fail "camera inside a closed box" "$nq queries; light leaks: $(awk 'NR > 1 && $3 != 0' "$TMP/cell.txt" | head -2 | tr '\n' ' ')"
    fi
    finite "camera inside a closed box" $(outputs cell)
else
    fail "camera inside a closed box: a stage failed" "$(head -c 300 "$TMP/cell.err")"
fi
# Rays that meet an edge of a closed room exactly (from the centre of make_box's room, the
# diagonal pixels' rays do) still hit a wall: every one of the 256 primary rays gives a query,
# at every scale (robust intersection; without it 1 and 2 rays slipped out at 1e5 and 1e-4).
for s in 1 1e-4 1e5; do
    make_box "$TMP/edge$s" 0.5 "$LIGHT"
    scale_scene "$TMP/edge$s" "$s"
    "$BIN/trace-gather-points" "$TMP/edge$s/scene.json" --mode direct-vis -q -o "$TMP/edge$s.q.pm"
    nq=$("$BIN/pm-info" --header "$TMP/edge$s.q.pm" | sed -n 's/^COUNT=//p')
    if [ "$nq" = 256 ]; then
        pass "closed room at scale $s: all 256 camera rays hit, those through the edges too"
    else
        fail "closed room at scale $s: camera rays" "$nq of 256 hit"
    fi
done

# ---- 8. Scene size, coordinate and camera limits (issue 17, item 9) ----------------------
# Before: a camera eye 1e-25 m from look_at and scenes scaled to 1e-23 aborted inside Embree
# (exit 134), and scales 1e-10 to 1e-21 made trace-photons refuse its own output (a float
# normal of length 4e-20). Now the camera's frame is normalized after an exact power-of-two
# rescale (bit-identical for ordinary cameras), and scenes beyond what float normals and
# Embree hold are refused up front in one line naming the value and the limit
# (docs/extreme-cases.md): geometry spanning less than 1e-8 m, a triangle over 1e18 m^2, a
# coordinate beyond 1e18 m. Nothing may exit 134: a clean render or a one-line refusal.
#
# The camera 1e-25 m from its look_at sees exactly what the camera 1 m from it in the same
# direction sees: the same direct buffer and reference image, record for record; and an up
# vector of 1e-30 or 1e18 is the same as (0, 1, 0).
records() { "$BIN/pm-info" -r "$1" | grep -E '^ *[0-9]+ '; }
make_box "$TMP/eye" 0.5 "$LIGHT"
set -f # the up vectors below are words, not globs
for v in "near -1e-25 [0,1,0]" "far -1 [0,1,0]" "tinyup -1e-25 [0,1e-30,0]" "hugeup -1 [0,1e18,0]"; do
    set -- $v
    jq ".camera.eye = [0.0123, 0.0071, 0] | .camera.look_at = [0.0123, 0.0071, $2] | .camera.up = $3" \
        "$TMP/eye/scene.json" >"$TMP/eye/$1.json"
    expect_exit "camera $1 (look_at $2 m along z from the eye, up $3): trace-gather-points renders" 0 \
        "$BIN/trace-gather-points" "$TMP/eye/$1.json" -q -o "$TMP/eye-$1.q.pm" --direct "$TMP/eye-$1.d.pm"
    expect_exit "camera $1: trace-reference renders" 0 \
        "$BIN/trace-reference" "$TMP/eye/$1.json" --spp 4 -q -o "$TMP/eye-$1.exr" --radiance "$TMP/eye-$1.r.pm"
    expect_exit "camera $1: scene-info --probe runs" 0 "$BIN/scene-info" --probe "$TMP/eye/$1.json"
done
set +f
for v in near tinyup hugeup; do
    if cmp -s <(records "$TMP/eye-$v.d.pm") <(records "$TMP/eye-far.d.pm") &&
        cmp -s <(records "$TMP/eye-$v.r.pm") <(records "$TMP/eye-far.r.pm") &&
        [ -n "$(records "$TMP/eye-far.d.pm")" ]; then
        pass "camera $v: its direct buffer and reference image equal the ordinary camera's, record for record"
    else
        fail "camera $v" "its images differ from the ordinary camera's"
    fi
done
# Scenes too small (1e-9: geometry 2e-9 m; 1e-12 and 1e-23, which failed or aborted) or with
# triangles too large (1e9: 2e18 m^2; 1e15): every stage that loads the scene refuses, one
# line, exit 1.
for s in 1e-9 1e-12 1e-23 1e9 1e15; do
    make_box "$TMP/lim$s" 0.5 "$LIGHT"
    scale_scene "$TMP/lim$s" "$s"
    case $s in
    *e-*) want="the geometry spans [0-9.e+-]+ m, below the smallest scene pmtk renders, 1e-08 m" ;;
    *) want="face 0 has an area of [0-9.e+]+ m\^2, beyond 1e\+18 m\^2" ;;
    esac
    expect_error "scale $s: trace-photons refuses the scene in one line" "$want" \
        "$BIN/trace-photons" "$TMP/lim$s/scene.json" -n 1000 -q -o "$TMP/lim.ph.pm"
    expect_error "scale $s: trace-gather-points refuses the scene in one line" "$want" \
        "$BIN/trace-gather-points" "$TMP/lim$s/scene.json" -q -o "$TMP/lim.q.pm"
    expect_error "scale $s: trace-reference refuses the scene in one line" "$want" \
        "$BIN/trace-reference" "$TMP/lim$s/scene.json" --spp 4 -q -o "$TMP/lim.exr"
    expect_error "scale $s: scene-info --probe refuses the scene in one line" "$want" \
        "$BIN/scene-info" --probe "$TMP/lim$s/scene.json"
done
# Within the limits, at both ends (geometry 2e-8 m and triangles of 2e16 m^2): the whole
# chain renders the unscaled box's image (case 3's s1) within rounding.
for s in 1e-8 1e8; do
    make_box "$TMP/in$s" 0.5 "$LIGHT"
    offaxis "$TMP/in$s"
    scale_scene "$TMP/in$s" "$s"
    if chain "$TMP/in$s/scene.json" "in$s" -n 20000 && "$BIN/measure-error" "$TMP/in$s.exr" "$TMP/s1.exr" -q -o "$TMP/in$s.json" &&
        awk -v r="$(stat "$TMP/in$s.json" relmse)" 'BEGIN { exit !(r < 1e-6) }'; then
        pass "scale $s, inside the limits: the image equals the unscaled box's (relative MSE $(stat "$TMP/in$s.json" relmse))"
    else
        fail "scale $s, inside the limits" "$(head -c 300 "$TMP/in$s.err") relmse $(stat "$TMP/in$s.json" relmse 2>/dev/null)"
    fi
done
# A camera or light beyond 1e18 m (Embree aborts on a ray starting there): refused.
make_box "$TMP/far" 0.5 "$LIGHT"
jq '.camera.eye = [0, 0, 1e20]' "$TMP/far/scene.json" >"$TMP/far/eye.json"
expect_error "camera eye at 1e20 m: refused in one line" "camera.eye: element 2 = 1e\+20 is outside \[-1e\+18, 1e\+18\]" \
    "$BIN/trace-gather-points" "$TMP/far/eye.json" -q -o "$TMP/far.q.pm"
# A triangle below 1e-18 m^2 in an ordinary room (its float normal underflows) is left out and
# counted like a zero-area one; the rest renders.
make_box "$TMP/speck" 0.5 "$LIGHT"
printf 'v 0 0 0\nv 1e-10 0 0\nv 0 1e-9 0\nf 9 10 11\n' >>"$TMP/speck/box.obj"
if "$BIN/scene-info" "$TMP/speck/scene.json" | grep -q '^triangles: 12 (1 degenerate left out)$' &&
    "$BIN/trace-photons" "$TMP/speck/scene.json" -n 2000 -q -o "$TMP/speck.ph.pm"; then
    pass "a triangle of 5e-20 m^2 is left out and counted; trace-photons runs"
else
    fail "a triangle of 5e-20 m^2" "$("$BIN/scene-info" "$TMP/speck/scene.json" 2>&1 | head -2 | tr '\n' ' ')"
fi

# ---- 9. A kernel radius the data makes infinite (issue 17, item 12) -----------------------
# Queries spread to 3e38 m: the radius --k finds is inf. The data is at fault, not the
# command line: an input error, exit 1 (it was a usage error, exit 2).
"$BUILD/tests/pm-testgen" photons 100 "$TMP/inf.ph.pm" && "$BIN/build-photonmap" -q "$TMP/inf.ph.pm" -o "$TMP/inf.map.pm"
"$BUILD/tests/pm-testgen" queries 10 "$TMP/inf.q.pm" --shape huge --set weights=lambertian-brdf-folded
for g in simd-gather reverse-gather; do
    expect_error "$g --k on queries near 3e38 m: an input error, exit 1" \
        "kernel radius inf m for --k 5 from the photons of .* \(input error\)$" \
        "$BIN/$g" "$TMP/inf.map.pm" "$TMP/inf.q.pm" --k 5 -q -o "$TMP/inf.out.pm"
done
