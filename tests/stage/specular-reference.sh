# specular-reference.sh: trace-reference with mirrors and glass (issue 18) against closed forms:
# a mirror ceiling doubles a light by its image, a lossless glass sphere leaves the furnace
# unchanged, a glass slab reflects 2R / (1 + R) at normal incidence and conserves energy, index
# 1 is invisible; and the stiff cases: index 3, inverted normals, 100-bounce mirror chains.
# programs: trace-reference
source tests/scenes/make-analytic.sh
R=$BIN/trace-reference
PI=3.141592653589793
# rref SCENE NAME SPP [options]: the render as a radiance buffer dumped to $TMP/NAME.txt
# ("pixel r g b vr vg vb", the variance of each pixel's mean), stats in $TMP/NAME.json.
rref() {
    local scene=$1 name=$2 spp=$3
    shift 3
    "$R" "$scene" -q --spp "$spp" --radiance "$TMP/$name.pm" --stats "$TMP/$name.json" "$@" -o "$TMP/$name.exr" &&
        "$BIN/pm-info" -r "$TMP/$name.pm" | grep -v '^[#A-Za-z]' | grep . >"$TMP/$name.txt"
}
stat() { grep -o "\"$2\": *[-0-9.eE+]*" "$TMP/$1.json" | sed 's/.*: *//'; }
# clean NAME: every sample finite, no path cut by the safety net
clean() {
    [ "$(stat "$1" nonfinite_samples)" = 0 ] && [ "$(stat "$1" capped_paths)" = 0 ] &&
        pass "$1: every sample finite, no path capped" ||
        fail "$1: clean" "nonfinite $(stat "$1" nonfinite_samples), capped $(stat "$1" capped_paths)"
}

# ---- a glass slab at normal incidence ----
# The slab z in [0, D], 10 m wide, between two black emitters 40 m wide: red Le 1 behind the
# camera (z = -2, facing +z), green Le 1 beyond the slab (z = 3, facing -z). The camera at
# z = -1 looks along +z through a 2 degree field: red is the slab's reflectance, green its
# transmittance, over the slab's multiple reflections (R = ((n - 1) / (n + 1))^2 per surface,
# Tf per crossing):  red = R + (1 - R)^2 Tf^2 R / (1 - R^2),  green = (1 - R)^2 Tf^2 / (1 - R^2);
# for Tf 1 red = 2R / (1 + R) and red + green = 1.
make_slab() { # make_slab DIR NI TF [in]: in winds the slab's faces inward (inverted normals)
    local dir=$1 ni=$2 tf=$3 inv=${4:-}
    mkdir -p "$dir"
    awk -v inv="$inv" 'function f(a, b, c, d) { if (inv == "in") print "f", a, d, c, b; else print "f", a, b, c, d }
    BEGIN {
        print "mtllib slab.mtl"
        print "v -5 -5 0\nv 5 -5 0\nv 5 5 0\nv -5 5 0\nv -5 -5 0.1\nv 5 -5 0.1\nv 5 5 0.1\nv -5 5 0.1"
        print "usemtl glass"
        f(1, 4, 3, 2); f(5, 6, 7, 8); f(1, 2, 6, 5); f(2, 3, 7, 6); f(3, 4, 8, 7); f(4, 1, 5, 8)
        print "v -20 -20 -2\nv 20 -20 -2\nv 20 20 -2\nv -20 20 -2"
        print "usemtl red\nf 9 10 11 12"
        print "v -20 -20 3\nv 20 -20 3\nv 20 20 3\nv -20 20 3"
        print "usemtl green\nf 13 16 15 14"
    }' >"$dir/slab.obj"
    printf 'newmtl glass\nKd 0 0 0\nNi %s\nTf %s %s %s\nillum 7\nnewmtl red\nKd 0 0 0\nKe 1 0 0\nnewmtl green\nKd 0 0 0\nKe 0 1 0\n' \
        "$ni" "$tf" "$tf" "$tf" >"$dir/slab.mtl"
    cat >"$dir/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "slab", "meshes": [ { "file": "slab.obj" } ],
  "camera": { "eye": [0, 0, -1], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 2, "width": 16, "height": 16 } }
JSON
}
# slab_check NAME NI TF: the image's mean red and green against the formulas, within 1% of each
# (the estimate's own standard error over the image is about 0.3% of red at 4096 samples)
slab_check() {
    local name=$1 ni=$2 tf=$3
    if awk -v n="$ni" -v tf="$tf" '{ r += $2; g += $3; b += $4; vr += $5; vg += $6; k++ }
        END { R = ((n - 1) / (n + 1)) ^ 2; t2 = tf * tf
            er = R + (1 - R) ^ 2 * t2 * R / (1 - R * R); eg = (1 - R) ^ 2 * t2 / (1 - R * R)
            r /= k; g /= k; b /= k
            printf "reflectance %.5f (formula %.5f, +- %.5f), transmittance %.5f (formula %.5f), sum %.5f", r, er, sqrt(vr) / k, g, eg, r + g
            tol = 0.01 * er + 4 * sqrt(vr) / k
            exit !((r - er) ^ 2 <= tol ^ 2 && (g - eg) ^ 2 <= (0.01 * eg) ^ 2 && b == 0) }' "$TMP/$name.txt" >"$TMP/why"; then
        pass "$name: $(cat "$TMP/why")"
    else
        fail "$name" "$(cat "$TMP/why")"
    fi
}
for c in "slab 1.5 1" "slab-tf 1.5 0.8" "slab-n3 3 1" "slab-inverted 1.5 1 in" "slab-n3-inverted 3 0.5 in"; do
    set -- $c
    make_slab "$TMP/$1" "$2" "$3" "${4:-}"
    if rref "$TMP/$1/scene.json" "$1" 4096 --pixel center; then
        slab_check "$1" "$2" "$3"
    else
        fail "$1 reference" "trace-reference failed: $(head -c 300 "$TMP/err" 2>/dev/null)"
    fi
done
clean slab
# Tf 1: every path ends on one of the two emitters: red + green = 1 within the noise
awk '{ r += $2; g += $3; v += $5 + $6; k++ } END { d = r / k + g / k - 1; printf "R + T = %.5f", 1 + d; exit !(d * d < 16 * v / k / k + 1e-8) }' \
    "$TMP/slab.txt" >"$TMP/why" && pass "slab, Tf 1: energy conserved, $(cat "$TMP/why")" || fail "slab energy" "$(cat "$TMP/why")"
# index 1: nothing reflects, everything passes
make_slab "$TMP/slab1" 1 1
if rref "$TMP/slab1/scene.json" slab1 256 --pixel center &&
    awk '{ if ($2 > 1e-4 || ($3 - 1) ^ 2 > 1e-8) bad++ } END { exit bad > 0 }' "$TMP/slab1.txt"; then
    pass "slab of index 1 is invisible: every pixel reflects < 1e-4 and transmits 1 within 1e-4"
else
    fail "slab of index 1" "$(head -3 "$TMP/slab1.txt")"
fi

# ---- a lossless glass sphere inside the furnace ----
# make_furnace's closed sphere (radius 1, Le 1, albedo 0.5: L = 2 everywhere) with a glass ball
# of radius 0.35 at z = 0.5 in front of the camera, filling most of the view. Lossless
# transport of a uniform radiance field keeps it uniform: every pixel is still 2.
furnace_glass() { # furnace_glass DIR NI WINDING
    make_furnace "$1" 1 0.5
    sphere_obj 0.35 32 "$3" | sed 's/^mtllib sphere.mtl/mtllib glass.mtl/; s/^usemtl wall/usemtl glass/' >"$1/glass.obj"
    printf 'newmtl glass\nKd 0 0 0\nNi %s\nillum 7\n' "$2" >"$1/glass.mtl"
    sed -i 's|"meshes": \[ *{ *"file": "sphere.obj" *} *\]|"meshes": [ { "file": "sphere.obj" }, { "file": "glass.obj", "translate": [0, 0, 0.5] } ]|' "$1/scene.json"
    grep -q glass.obj "$1/scene.json" || echo "furnace_glass: the scene has no glass mesh" >&2
}
# furnace_check NAME: mean within 1% of 2, and the deviations honest against the reported
# variance (RMS of (L - 2) / sigma within 0.75 to 1.33)
furnace_check() {
    # grey: the three channels are the same samples, so the mean's error is one channel's
    if awk '{ for (c = 2; c <= 4; c++) { m += $c; d = $c - 2; z += d * d / $(c + 3) } v += $5; k++ }
        END { m /= 3 * k; zr = sqrt(z / (3 * k)); printf "mean %.5f (+- %.5f), RMS deviation %.3f standard errors", m, sqrt(v) / k, zr
            exit !((m - 2) ^ 2 < (0.01 * 2) ^ 2 && zr > 0.75 && zr < 1.33) }' "$TMP/$1.txt" >"$TMP/why"; then
        pass "$1: L = Le / (1 - rho) = 2 everywhere: $(cat "$TMP/why")"
    else
        fail "$1" "$(cat "$TMP/why")"
    fi
}
for c in "fglass 1.5 out" "fglass-n3 3 out" "fglass-inverted 1.5 in" "fglass-n1 1 out"; do
    set -- $c
    furnace_glass "$TMP/$1" "$2" "$3"
    if rref "$TMP/$1/scene.json" "$1" 128 --width 24 --height 24; then
        furnace_check "$1"
    else
        fail "$1 reference" "trace-reference failed"
    fi
done
clean fglass
clean fglass-n3

# ---- a mirror ceiling: the floor sees the light and its mirror image ----
# A diffuse floor y = 0 (kd 0.5) and a mirror ceiling y = 2 (kr 0.8), both 6 m square, and a
# cube light of side 0.6 m centred at (0, 1, 0), Le 10 on every face, black. The floor's
# irradiance from a face is Lambert's polygon formula, exact for any size and distance:
#     E = Le / 2 |sum over edges of theta_k (u_k x u_k+1)_y / |u_k x u_k+1||
# (u_k unit vectors from the floor point to the face's corners, theta_k the angle between
# consecutive ones), summed over the faces the point sees. The light through the mirror is
# the image cube at (0, 3, 0) times kr. --component direct is the light itself, --component
# caustic the light via the mirror (L S D E): L = kd / pi E each. The camera at y = 1.9 looks
# straight down (fov 90, pixel centres): pixel (i, j) sees the floor at x = 1.9 (1 - (2i + 1) / W),
# z = 1.9 (1 - (2j + 1) / H). Points within 1.5 m of the axis are left out: the cube hides them
# from the camera, or its side hides part of the image.
mkdir -p "$TMP/mc"
awk 'function f(a, b, c, d) { print "f", a, b, c, d }
BEGIN {
    print "mtllib mc.mtl"
    print "v -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nusemtl floor\nf 1 4 3 2"
    print "v -3 2 -3\nv 3 2 -3\nv 3 2 3\nv -3 2 3\nusemtl mirror\nf 5 6 7 8"
    s = 0.3
    for (i = 0; i < 8; i++) printf "v %g %g %g\n", (i % 2 ? s : -s), 1 + (int(i / 2) % 2 ? s : -s), (i >= 4 ? s : -s)
    # corners 9..16: x from bit 0, y from bit 1, z from bit 2; faces wound outward
    print "usemtl light"
    f(9, 11, 12, 10); f(13, 14, 16, 15); f(9, 10, 14, 13); f(11, 15, 16, 12); f(9, 13, 15, 11); f(10, 12, 16, 14)
}' >"$TMP/mc/mc.obj"
printf 'newmtl floor\nKd 0.5 0.5 0.5\nnewmtl mirror\nKd 0 0 0\nKs 0.8 0.8 0.8\nillum 3\nnewmtl light\nKd 0 0 0\nKe 10 10 10\n' >"$TMP/mc/mc.mtl"
cat >"$TMP/mc/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "mirror-ceiling", "meshes": [ { "file": "mc.obj" } ],
  "camera": { "eye": [0, 1.9, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 40, "height": 40 } }
JSON
# mirror_check NAME CY KR TOL: the render against kd / pi KR E(cube at height CY) on the floor
# pixels beyond 1.2 m from the axis: the mean within TOL (relative) plus 4 standard errors,
# and with ZMAX set, each pixel's deviation in standard errors RMS within 0.75 to ZMAX
mirror_check() {
    if awk -v cy="$2" -v kr="$3" -v tol="$4" -v zmax="${5:-0}" -v W=40 -v H=40 -v pi=$PI '
    function face(px, pz, ax, sg,    v, k, ux, uy, uz, wx, wy, wz, l, cx, cy2, cz, sn, sum) {
        # the corners of the face of the cube (side 0.6 at (0, cy, 0)) on axis ax, side sg
        for (k = 0; k < 4; k++) {
            a = (k == 1 || k == 2) ? 0.3 : -0.3; b = (k >= 2) ? 0.3 : -0.3
            if (ax == 0) { X[k] = sg * 0.3; Y[k] = cy + a; Z[k] = b }
            if (ax == 1) { X[k] = a; Y[k] = cy + sg * 0.3; Z[k] = b }
            if (ax == 2) { X[k] = a; Y[k] = cy + b; Z[k] = sg * 0.3 }
        }
        # seen only from in front of it
        if (ax == 0 && sg * (px - sg * 0.3) <= 0) return 0
        if (ax == 1 && sg * (0 - cy - sg * 0.3) <= 0) return 0
        if (ax == 2 && sg * (pz - sg * 0.3) <= 0) return 0
        sum = 0
        for (k = 0; k < 4; k++) {
            n = (k + 1) % 4
            ux = X[k] - px; uy = Y[k]; uz = Z[k] - pz; l = sqrt(ux * ux + uy * uy + uz * uz); ux /= l; uy /= l; uz /= l
            wx = X[n] - px; wy = Y[n]; wz = Z[n] - pz; l = sqrt(wx * wx + wy * wy + wz * wz); wx /= l; wy /= l; wz /= l
            cx = uy * wz - uz * wy; cy2 = uz * wx - ux * wz; cz = ux * wy - uy * wx
            sn = sqrt(cx * cx + cy2 * cy2 + cz * cz)
            sum += atan2(sn, ux * wx + uy * wy + uz * wz) * cy2 / sn
        }
        return 10 / 2 * (sum < 0 ? -sum : sum)
    }
    {
        i = $1 % W; j = int($1 / W)
        px = 1.9 * (1 - (2 * i + 1) / W); pz = 1.9 * (1 - (2 * j + 1) / H)
        if (px * px + pz * pz < 1.5 * 1.5) next
        e = 0
        for (ax = 0; ax < 3; ax++) { e += face(px, pz, ax, 1); e += face(px, pz, ax, -1) }
        want = 0.5 / pi * kr * e
        got += $2; ex += want; var += $5; k++
        if ($5 > 0) { z += ($2 - want) ^ 2 / $5; kz++ }
    }
    END {
        zr = kz ? sqrt(z / kz) : 0
        printf "%d pixels: mean %.6g, formula %.6g (ratio %.4f, standard error %.4f), deviation RMS %.2f standard errors",
            k, got / k, ex / k, got / ex, sqrt(var) / ex, zr
        exit !(k > 500 && (got - ex) ^ 2 < (tol * ex + 4 * sqrt(var)) ^ 2 && (zmax == 0 || (zr > 0.75 && zr < zmax)))
    }' "$TMP/$1.txt" >"$TMP/why"; then
        pass "$1: $(cat "$TMP/why")"
    else
        fail "$1" "$(cat "$TMP/why")"
    fi
}
if rref "$TMP/mc/scene.json" mc-direct 64 --pixel center --component direct; then
    mirror_check mc-direct 1 1 0.005 1.33
else
    fail "mirror ceiling, direct" "trace-reference failed"
fi
if rref "$TMP/mc/scene.json" mc-caustic 1024 --pixel center --component caustic; then
    mirror_check mc-caustic 3 0.8 0.01
else
    fail "mirror ceiling, caustic" "trace-reference failed"
fi
clean mc-caustic

# ---- a 100-bounce mirror chain ----
# Two parallel mirrors (kr 0.99) y = 0 and y = 0.1, x from 0 to 10 m; a black emitter Le 1
# closes the far end (x = 10, facing -x). The camera at (0, 0.05, 0) looks up the corridor at
# 45 degrees through a 0.1 degree field: every ray meets the mirrors at x = 0.05, 0.15, ...,
# 9.95, 100 times, and then the emitter, so every pixel is 0.99^100 = 0.366. Russian roulette
# (survival 0.99 a bounce here) ends the paths that do not get there; none is cut by the
# safety net, and every sample is finite.
mkdir -p "$TMP/chain"
cat >"$TMP/chain/chain.obj" <<'OBJ'
mtllib chain.mtl
v 0 0 -1
v 10 0 -1
v 10 0 1
v 0 0 1
v 0 0.1 -1
v 10 0.1 -1
v 10 0.1 1
v 0 0.1 1
usemtl mirror
f 1 4 3 2
f 5 6 7 8
v 10 -0.1 -1
v 10 0.2 -1
v 10 0.2 1
v 10 -0.1 1
usemtl end
f 9 12 11 10
OBJ
printf 'newmtl mirror\nKd 0 0 0\nKs 0.99 0.99 0.99\nillum 3\nnewmtl end\nKd 0 0 0\nKe 1 1 1\n' >"$TMP/chain/chain.mtl"
cat >"$TMP/chain/scene.json" <<'JSON'
{ "pmtk_scene": 1, "name": "mirror-chain", "meshes": [ { "file": "chain.obj" } ],
  "camera": { "eye": [0, 0.05, 0], "look_at": [1, 1.05, 0], "up": [0, 0, 1], "fov_y": 0.1, "width": 8, "height": 8 } }
JSON
if rref "$TMP/chain/scene.json" chain 1024 --pixel center; then
    awk '{ m += $2; v += $5; k++ } END { m /= k; s = sqrt(v) / k; w = 0.99 ^ 100
        printf "mean %.4f (+- %.4f) against 0.99^100 = %.4f", m, s, w; exit !((m - w) ^ 2 < (4 * s) ^ 2) }' \
        "$TMP/chain.txt" >"$TMP/why" && pass "100 mirror bounces: $(cat "$TMP/why")" || fail "mirror chain" "$(cat "$TMP/why")"
    clean chain
    [ "$(stat chain longest_path)" -ge 100 ] && pass "... paths 100 bounces long (longest $(stat chain longest_path))" ||
        fail "mirror chain length" "longest path $(stat chain longest_path)"
else
    fail "mirror chain reference" "trace-reference failed"
fi

# ---- a lossless mirror cavity: nothing ends the paths but the safety net ----
# A closed cube of kr 1 mirrors around the camera and a small black emitter: the paths that
# never meet the emitter bounce for ever, Russian roulette having nothing to cut (throughput 1).
# --max-bounces ends them, counted; the run ends, every sample finite, the image finite.
mkdir -p "$TMP/cavity"
awk 'BEGIN { print "mtllib cavity.mtl"
    for (i = 0; i < 8; i++) printf "v %d %d %d\n", (i % 2 ? 1 : -1), (int(i / 2) % 2 ? 1 : -1), (i >= 4 ? 1 : -1)
    print "usemtl mirror\nf 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4"
    print "v -0.1 -0.9 -0.1\nv 0.1 -0.9 -0.1\nv 0.1 -0.9 0.1\nv -0.1 -0.9 0.1\nusemtl lamp\nf 9 12 11 10" }' >"$TMP/cavity/cavity.obj"
printf 'newmtl mirror\nKd 0 0 0\nKs 1 1 1\nillum 5\nnewmtl lamp\nKd 0 0 0\nKe 1 1 1\n' >"$TMP/cavity/cavity.mtl"
cat >"$TMP/cavity/scene.json" <<'JSON'
{ "pmtk_scene": 1, "name": "mirror-cavity", "meshes": [ { "file": "cavity.obj" } ],
  "camera": { "eye": [0.3, 0.2, 0.1], "look_at": [0.5, -1, 0.3], "up": [0, 0, 1], "fov_y": 60, "width": 8, "height": 8 } }
JSON
if rref "$TMP/cavity/scene.json" cavity 16 --max-bounces 2000; then
    c=$(stat cavity capped_paths)
    if [ "$c" -gt 0 ] && [ "$(stat cavity nonfinite_samples)" = 0 ] && [ "$(stat cavity longest_path)" = 2000 ] &&
        awk '{ for (c = 2; c <= 7; c++) if (!($c >= 0 && $c < 1e30)) bad++ } END { exit bad > 0 }' "$TMP/cavity.txt"; then
        pass "lossless mirror cavity: $c of 1024 paths cut at 2000 bounces, counted; every sample and pixel finite"
    else
        fail "mirror cavity" "capped $c, nonfinite $(stat cavity nonfinite_samples), longest $(stat cavity longest_path)"
    fi
else
    fail "mirror cavity reference" "trace-reference failed"
fi

# ---- glass of index 1 is invisible ----
# A floor lit by an area light above it, with and without a glass ball of index 1 between them:
# the same image within the noise. With the ball the shadow rays are blocked and the floor
# under it is lit only through the ball, by the paths' own bounces: unbiased, noisier, and
# rare enough per pixel that a pixel's own variance is a poor error bar; so the image is
# compared in blocks of 4 x 4 pixels (36 blocks): each block's difference in combined standard
# errors RMS within 0.4 to 1.5, none beyond 4.5, and the means within 4 standard errors.
mkdir -p "$TMP/inv"
printf 'mtllib inv.mtl\nv -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nusemtl floor\nf 1 4 3 2\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1\nusemtl lamp\nf 5 6 7 8\n' >"$TMP/inv/inv.obj"
printf 'newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 2 2 2\nnewmtl glass\nKd 0 0 0\nNi 1\nillum 7\n' >"$TMP/inv/inv.mtl"
sphere_obj 0.4 24 out | sed 's/^mtllib sphere.mtl/mtllib inv.mtl/; s/^usemtl wall/usemtl glass/' >"$TMP/inv/ball.obj"
for with in 0 1; do
    meshes='{ "file": "inv.obj" }'
    [ $with = 1 ] && meshes="$meshes, { \"file\": \"ball.obj\", \"translate\": [0, 0.8, 0] }"
    cat >"$TMP/inv/scene$with.json" <<JSON
{ "pmtk_scene": 1, "name": "invisible-glass", "meshes": [ $meshes ],
  "camera": { "eye": [0, 1.2, -2.5], "look_at": [0, 0.2, 0], "up": [0, 1, 0], "fov_y": 50, "width": 24, "height": 24 } }
JSON
done
if rref "$TMP/inv/scene0.json" inv0 256 --rr-start 8 && rref "$TMP/inv/scene1.json" inv1 256 --rr-start 8; then
    awk 'NR == FNR { a[$1] = $2; va[$1] = $5; next }
        { b = int($1 % 24 / 4) + 6 * int(int($1 / 24) / 4); d[b] += $2 - a[$1]; v[b] += $5 + va[$1]; ma += a[$1]; mb += $2; vs += $5 + va[$1]; k++ }
        END { for (b in d) { if (!(v[b] > 0)) continue; z = d[b] * d[b] / v[b]; zs += z; nb++; if (z > zmax) zmax = z }
            zr = sqrt(zs / nb); printf "means %.5f and %.5f (+- %.5f), block differences RMS %.2f standard errors, largest %.2f", ma / k, mb / k, sqrt(vs) / k, zr, sqrt(zmax)
            exit !(zr > 0.4 && zr < 1.5 && zmax < 4.5 * 4.5 && (ma - mb) ^ 2 < 16 * vs) }' "$TMP/inv0.txt" "$TMP/inv1.txt" >"$TMP/why" &&
        pass "a glass ball of index 1 is invisible: $(cat "$TMP/why")" || fail "index 1 invisible" "$(cat "$TMP/why")"
    clean inv1
else
    fail "invisible glass reference" "trace-reference failed"
fi
