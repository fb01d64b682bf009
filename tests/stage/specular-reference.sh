# specular-reference.sh: trace-reference with mirrors and glass (issue 18) against closed forms:
# a mirror ceiling doubles a light by its image, a lossless glass sphere leaves the furnace
# unchanged, a glass slab reflects 2R / (1 + R) at normal incidence and conserves energy, index
# 1 is invisible; and the stiff cases: index 3, inverted normals, 100-bounce mirror chains.
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
    if awk '{ for (c = 2; c <= 4; c++) { m += $c; d = $c - 2; z += d * d / $(c + 3); v += $(c + 3) } k += 3 }
        END { m /= k; zr = sqrt(z / k); printf "mean %.5f (+- %.5f), RMS deviation %.3f standard errors", m, sqrt(v) / k, zr
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
