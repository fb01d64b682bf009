# analytic.sh: the photon pipeline against scenes with closed-form answers
# (tests/scenes/make-analytic.sh): trace-photons | build-photonmap, trace-gather-points
# --mode direct-vis, simd-gather, composite; the EXR is read back and every pixel compared
# with L = kd / pi * E (tests/scenes/analytic.awk).
#
# Tolerances: with k = 200 photons per kernel the per-pixel noise is about 9% (measured;
# 1/sqrt(200) = 7% for a box kernel, more for Epanechnikov), so over 32 x 32 pixels the mean
# ratio has a standard error near 0.3%: the mean (and each half by brightness) must be within
# 2%, the RMS deviation below 15% and every pixel within 50%. Kernel bias is negligible here:
# on the plane the box-kernel bias is r^2/8 * Laplacian(E)/E = -0.2% at the centre for r = 0.05
# m, and the plane reaches 20 m past the view so no kernel touches an edge; the sphere is
# closed. The triangulated sphere (48 x 24) differs from a true one by about 0.6%.
source tests/scenes/make-analytic.sh
PI=3.141592653589793
TOL="-v tmean=0.02 -v trms=0.15 -v tmax=0.5"

# render SCENE NAME [trace-photons options] [-- build-photonmap options]: the direct-vis
# pipeline into $TMP/NAME.exr, and $TMP/NAME.q.txt (the queries) and $TMP/NAME.txt (the image).
render() {
    local scene=$1 name=$2; shift 2
    local tp=() bp=()
    while [ $# -gt 0 ] && [ "$1" != -- ]; do tp+=("$1"); shift; done
    [ "${1:-}" = -- ] && shift
    bp=("$@")
    "$BIN/trace-photons" "$scene" --photons 400000 -q "${tp[@]}" -o - |
        "$BIN/build-photonmap" - -q "${bp[@]}" -o "$TMP/$name.map.pm" &&
    "$BIN/trace-gather-points" "$scene" --mode direct-vis -q -o "$TMP/$name.q.pm" &&
    "$BIN/simd-gather" "$TMP/$name.map.pm" "$TMP/$name.q.pm" --k 200 -q -o "$TMP/$name.dv.pm" &&
    "$BIN/composite" "$TMP/$name.dv.pm" -q -o "$TMP/$name.exr" &&
    "$BIN/pm-info" -r "$TMP/$name.q.pm" >"$TMP/$name.q.txt" &&
    "$BUILD/tests/pm-exrdump" "$TMP/$name.exr" >"$TMP/$name.txt"
}

# check NAME RENDER awk-options...: the image of RENDER against the formula.
check() {
    local name=$1 r=$2; shift 2
    if awk "$@" $TOL -f tests/scenes/analytic.awk "$TMP/$r.q.txt" "$TMP/$r.txt" >"$TMP/why"; then
        pass "$name ($(cat "$TMP/why"))"
    else
        fail "$name" "$(tr '\n' ' ' <"$TMP/why")"
    fi
}

# (b) A point light of pi W/sr 1 m above an albedo-0.5 plane: E(x) = I h / (h^2 + x^2)^(3/2),
# L = 0.5 at the foot of the light falling to 0.096 in the image corners.
make_lit_plane "$TMP/plane" 1 $PI 0.5
if render "$TMP/plane/scene.json" plane; then
    check "point light over a plane: L = kd/pi * I h / (h^2 + x^2)^(3/2)" plane \
        -v kind=point -v kd=0.5 -v I=$PI -v lx=0 -v ly=1 -v lz=0
else
    fail "plane pipeline" "a stage failed"
fi
# The same at another height, power and albedo (h = 2 m, I = 10 W/sr, kd = 0.8).
make_lit_plane "$TMP/plane2" 2 10 0.8
if render "$TMP/plane2/scene.json" plane2; then
    check "point light over a plane, h 2 m, I 10 W/sr, kd 0.8" plane2 \
        -v kind=point -v kd=0.8 -v I=10 -v lx=0 -v ly=2 -v lz=0
else
    fail "plane2 pipeline" "a stage failed"
fi

# (a) A point light of pi W/sr at the centre of a closed unit sphere of albedo 0.5:
# direct E_d = I / R^2 (per facet I cos / d^2), total E_d / (1 - kd), indirect kd E_d / (1 - kd).
make_lit_sphere "$TMP/sphere" 1 $PI 0.5
if render "$TMP/sphere/scene.json" sd --max-bounces 1; then
    check "sphere, first-hit photons only: direct E = I cos / d^2 on each facet" sd \
        -v kind=point -v kd=0.5 -v I=$PI -v lx=0 -v ly=0 -v lz=0
else
    fail "sphere direct pipeline" "a stage failed"
fi
if render "$TMP/sphere/scene.json" st; then
    check "sphere, global map: E = I / R^2 / (1 - kd)" st -v kind=const -v kd=0.5 -v e=$(awk -v p=$PI 'BEGIN { print p / 0.5 }')
else
    fail "sphere total pipeline" "a stage failed"
fi
if render "$TMP/sphere/scene.json" si -- --map indirect; then
    check "sphere, indirect map: E = kd I / R^2 / (1 - kd)" si -v kind=const -v kd=0.5 -v e=$PI
else
    fail "sphere indirect pipeline" "a stage failed"
fi
# Albedo 0.9 and radius 2 m: the bounce series is 10 times the direct light.
make_lit_sphere "$TMP/sphere9" 2 1 0.9
if render "$TMP/sphere9/scene.json" s9; then
    check "sphere, R 2 m, kd 0.9: E = I / R^2 / (1 - kd) = 2.5 W/m^2" s9 -v kind=const -v kd=0.9 -v e=2.5
else
    fail "sphere 0.9 pipeline" "a stage failed"
fi
