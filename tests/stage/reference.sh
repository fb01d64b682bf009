# reference.sh: trace-reference, the path tracer that is the photon pipeline's ground truth.
# Against closed-form scenes (tests/scenes/make-analytic.sh) pixel by pixel, with tolerances
# from its own reported standard error; against the photon pipeline on the Cornell box; and
# its contract: bit-identical for any --threads, --resume continues exactly, refusals.
# programs: build-photonmap composite hilbert-sort measure-error simd-gather trace-gather-points trace-photons trace-reference
source tests/scenes/make-analytic.sh
PI=3.141592653589793
R=$BIN/trace-reference
DUMP=$BUILD/tests/pm-exrdump

# ref SCENE NAME SPP [options]: the reference into $TMP/NAME.exr and .pm, the direct-vis
# queries (each pixel's primary hit) as text in $TMP/NAME.q.txt, the image in $TMP/NAME.txt.
# Through pixel centres (--pixel center): the formulas are checked at each pixel's primary hit.
ref() {
    local scene=$1 name=$2 spp=$3; shift 3
    "$R" "$scene" -q --pixel center --spp "$spp" --radiance "$TMP/$name.pm" --stats "$TMP/$name.json" "$@" -o "$TMP/$name.exr" &&
    "$BIN/trace-gather-points" "$scene" --pixel center --mode direct-vis -q -o "$TMP/$name.q.pm" &&
    "$BIN/pm-info" -r "$TMP/$name.q.pm" >"$TMP/$name.q.txt" && "$DUMP" "$TMP/$name.exr" >"$TMP/$name.txt"
}
stat() { grep -o "\"$2\": *[-0-9.eE+]*" "$TMP/$1.json" | sed 's/.*: *//'; }
# means_agree NAME JSON TOL: measure-error's JSON says the test's mean is within TOL (relative)
# of the reference's.
means_agree() {
    local mt mr
    mt=$(grep -o '"mean_test": *[-0-9.eE+]*' "$2" | sed 's/.*: *//')
    mr=$(grep -o '"mean_reference": *[-0-9.eE+]*' "$2" | sed 's/.*: *//')
    if awk -v a="$mt" -v b="$mr" -v t="$3" 'BEGIN { exit !(b > 0 && a / b > 1 - t && a / b < 1 + t) }'; then
        pass "$1: mean $mt within $3 of the reference's $mr"
    else
        fail "$1" "means $mt and $mr (tolerance $3)"
    fi
}

# check NAME RENDER TOL awk-options...: the image against the formula (analytic.awk); then,
# where the estimate is noisy, its RMS deviation against the standard error it reports.
check() {
    local name=$1 r=$2 tol=$3; shift 3
    if awk "$@" $tol -f tests/scenes/analytic.awk "$TMP/$r.q.txt" "$TMP/$r.txt" >"$TMP/why"; then
        pass "$name ($(cat "$TMP/why"); reported standard error $(stat "$r" stderr_rel))"
    else
        fail "$name" "$(tr '\n' ' ' <"$TMP/why")"
    fi
    local dev se
    dev=$(sed -n 's/.*rms dev \([0-9.]*\).*/\1/p' "$TMP/why") se=$(stat "$r" stderr_rel)
    if awk -v d="$dev" -v s="$se" 'BEGIN { exit !(s > 1e-3) }'; then
        if awk -v d="$dev" -v s="$se" 'BEGIN { exit !(d >= 0.75 * s && d <= 1.33 * s) }'; then
            pass "$name: the reported standard error is honest (measured $dev, reported $se)"
        else
            fail "$name: reported standard error" "measured RMS deviation $dev, reported $se"
        fi
    fi
}

# ---- closed forms ----
# A point light over a plane: light reflected by the plane escapes, so each sample's light
# sample is the whole answer; only float rounding separates it from the formula.
make_lit_plane "$TMP/plane" 1 $PI 0.5
if ref "$TMP/plane/scene.json" plane 4; then
    check "plane: L = kd/pi * I h / (h^2 + x^2)^(3/2) to 1e-4" plane "-v tmean=1e-4 -v trms=1e-4 -v tmax=1e-3" \
        -v kind=point -v kd=0.5 -v I=$PI -v lx=0 -v ly=1 -v lz=0
    awk -v v="$(stat plane stderr_rms)" 'BEGIN { exit !(v == 0) }' && pass "plane: a noiseless estimate reports zero standard error" ||
        fail "plane: standard error" "$(stat plane stderr_rms), expected 0"
else
    fail "plane reference" "trace-reference failed"
fi
# Extremes on the same plane (docs/extreme-cases.md): the estimate is linear in power, so lights
# of 1e-20 and 1e20 W/sr give the pi W/sr image times 1e-20/pi and 1e20/pi; and scaled by 1e-4 and
# 1e5 with the intensity by the square, the image is the same (ray offsets scale with the scene).
for case in "1e-20 1" "1e20 1" "3.141592653589793e-8 1e-4" "3.141592653589793e10 1e5"; do
    set -- $case
    make_lit_plane "$TMP/px" "$2" "$1" 0.5 "$(awk -v s="$2" 'BEGIN { print 20 * s }')"
    "$R" "$TMP/px/scene.json" -q --pixel center --spp 4 --stats "$TMP/px.json" -o "$TMP/px.exr" && "$DUMP" "$TMP/px.exr" >"$TMP/px.txt"
    f=$(awk -v i="$1" -v s="$2" -v p=$PI 'BEGIN { printf "%.17g", i / p / (s * s) }')
    if awk -v f="$f" 'NR == FNR { if ($1 != "size") a[$1 " " $2] = $3 " " $4 " " $5; next }
        $1 != "size" { split(a[$1 " " $2], v, " ")
            for (c = 3; c <= 5; c++) { w = v[c - 2] * f; if (!($c > 0) || ($c - w) ^ 2 > (1e-5 * w) ^ 2) bad++ } }
        END { exit bad > 0 }' "$TMP/plane.txt" "$TMP/px.txt" && [ "$(stat px nonfinite_samples)" = 0 ]; then
        pass "plane, I $1 W/sr at scale $2: every pixel is the I pi image times $f within 1e-5"
    else
        fail "plane, I $1 at scale $2" "pixels differ from $f times the reference image (or not finite)"
    fi
done

# A point light inside a closed sphere: E = I / R^2 / (1 - kd) everywhere. At 256 samples per
# pixel the reported relative standard error is about 2% (kd 0.5) and 4% (kd 0.9) per pixel,
# so over 32 x 32 pixels the mean ratio has a standard error near 0.1%: the mean within 1%
# (the inscribed 48 x 24 sphere is 0.6% off a true one), each pixel's RMS deviation within
# 1.5 reported standard errors (measured: 1.02 of it), no pixel beyond 30% and 60%. Then the
# reported error itself must be honest: the measured RMS deviation from the formula within
# 0.75 to 1.33 of the standard error trace-reference reports.
make_lit_sphere "$TMP/sphere" 1 $PI 0.5
if ref "$TMP/sphere/scene.json" sphere 256; then
    check "sphere, kd 0.5: E = I / R^2 / (1 - kd), every bounce" sphere "-v tmean=0.01 -v trms=0.04 -v tmax=0.3" \
        -v kind=const -v kd=0.5 -v e=$(awk -v p=$PI 'BEGIN { print p / 0.5 }')
else
    fail "sphere reference" "trace-reference failed"
fi
make_lit_sphere "$TMP/sphere9" 2 1 0.9
if ref "$TMP/sphere9/scene.json" sphere9 256; then
    check "sphere, R 2 m, kd 0.9: E = I / R^2 / (1 - kd) = 2.5 W/m^2 (ten times the direct light)" sphere9 \
        "-v tmean=0.01 -v trms=0.09 -v tmax=0.6" -v kind=const -v kd=0.9 -v e=2.5
    [ "$(stat sphere9 capped_paths)" = 0 ] && pass "kd 0.9: Russian roulette ends every path (none capped)" ||
        fail "kd 0.9 capped paths" "$(stat sphere9 capped_paths)"
else
    fail "sphere 0.9 reference" "trace-reference failed"
fi
# The furnace: every surface of a closed sphere emits Le = 1 W/(m^2 sr) with albedo rho, so
# L = Le / (1 - rho) everywhere, for any closed shape (no facet bias). Emission is found both by
# light samples and by BRDF samples here, so this checks the MIS weights sum to one.
for rho in 0.5 0.9; do
    make_furnace "$TMP/furnace$rho" 1 $rho
    if ref "$TMP/furnace$rho/scene.json" f$rho 128; then
        check "furnace, rho $rho: L = Le / (1 - rho) = $(awk -v r=$rho 'BEGIN { print 1 / (1 - r) }')" f$rho \
            "-v tmean=0.01 -v trms=0.1 -v tmax=0.6" -v kind=const -v kd=$rho -v le=1 \
            -v e=$(awk -v p=$PI -v r=$rho 'BEGIN { print p / (1 - r) }')
    else
        fail "furnace $rho reference" "trace-reference failed"
    fi
done
# The split the photon pipeline makes (docs/accuracy.md): --component direct is the emission
# seen and the direct light (trace-gather-points' direct buffer), indirect the rest (simd-gather's).
# Sphere kd 0.5: direct kd/pi I/R^2, indirect kd/pi kd I/R^2/(1 - kd); furnace rho 0.5:
# direct Le + rho Le, indirect rho^2 Le/(1 - rho).
if ref "$TMP/sphere/scene.json" sphi 256 --component indirect; then
    check "sphere, kd 0.5, indirect only: kd/pi * kd I / R^2 / (1 - kd)" sphi "-v tmean=0.01 -v trms=0.06 -v tmax=0.4" \
        -v kind=const -v kd=0.5 -v e=$PI
else
    fail "sphere indirect reference" "trace-reference failed"
fi
if ref "$TMP/furnace0.5/scene.json" f5d 64 --component direct && ref "$TMP/furnace0.5/scene.json" f5i 256 --component indirect; then
    check "furnace rho 0.5, direct only: Le + rho Le = 1.5" f5d "-v tmean=0.01 -v trms=0.05 -v tmax=0.4" \
        -v kind=const -v kd=0.5 -v le=1 -v e=$PI
    check "furnace rho 0.5, indirect only: rho^2 Le / (1 - rho) = 0.5" f5i "-v tmean=0.01 -v trms=0.1 -v tmax=0.6" \
        -v kind=const -v kd=0.5 -v e=$PI
    awk -v d="$(stat f5d rays_per_path)" 'BEGIN { exit !(d <= 2) }' &&
        pass "--component direct traces no further than the first bounce ($(stat f5d rays_per_path) rays a path)" ||
        fail "direct component rays" "$(stat f5d rays_per_path) rays per path"
else
    fail "furnace component references" "trace-reference failed"
fi

# Albedo 0.999: a thousand bounces a path (the slow bounce series of a closed white room). Russian
# roulette with survival = throughput keeps every path's weight at most 1, so the answer stays
# unbiased with no bounce cap: 8 x 8 pixels at 32 samples, per-sample spread about 1 (the path
# length is geometric), so the mean has a standard error near 2% and must be within 8% of 1000
# (a cap at 100 bounces would give a tenth of it), with no path capped.
make_furnace "$TMP/f999" 1 0.999
"$R" "$TMP/f999/scene.json" -q --width 8 --height 8 --spp 32 --stats "$TMP/f999.json" -o "$TMP/f999.exr"
m=$(stat f999 mean_radiance) se=$(stat f999 stderr_rel)
if awk -v m="$m" 'BEGIN { exit !(m > 920 && m < 1080) }' && [ "$(stat f999 capped_paths)" = 0 ] &&
    [ "$(stat f999 nonfinite_samples)" = 0 ]; then
    pass "furnace, albedo 0.999: mean $m against Le / (1 - rho) = 1000 (reported error $se of a pixel), no path capped, all finite"
else
    fail "furnace 0.999" "mean $m (expected 1000), capped $(stat f999 capped_paths), reported error $se"
fi

# ---- the photon pipeline against the reference: the Cornell box at 64 x 64 ----
# Both render one model, so the means agree within the photon estimate's kernel bias and the
# reference's noise (measured at 256 x 256: 0.3% apart); each is within 3% of the other. Both
# box-filter their pixels; 4 primary rays a pixel keep the light's edge pixels from dominating
# the noise of the photon image's mean (one ray a pixel spreads it by about 5%).
C=scenes/cornell-box/scene.json
"$R" "$C" -q --width 64 --height 64 --spp 256 --pass 64 --radiance "$TMP/cref.pm" -o "$TMP/cref.exr"
"$BIN/trace-photons" "$C" -q --photons 200000 -o - | "$BIN/build-photonmap" - -q -o "$TMP/cmap.pm" &&
    "$BIN/trace-gather-points" "$C" -q --width 64 --height 64 --primary 4 --spp 16 -o - --direct "$TMP/cd.pm" |
    "$BIN/hilbert-sort" - -q -o - | "$BIN/simd-gather" "$TMP/cmap.pm" - --k 50 -q -o "$TMP/ci.pm" &&
    "$BIN/composite" -q "$TMP/cd.pm" "$TMP/ci.pm" -o "$TMP/cpm.exr" &&
    "$BIN/measure-error" "$TMP/cpm.exr" "$TMP/cref.pm" >"$TMP/cerr.json"
means_agree "Cornell box, photon pipeline against trace-reference" "$TMP/cerr.json" 0.03
# ... and the gather's part alone, against the reference's indirect component.
"$R" "$C" -q --width 64 --height 64 --spp 256 --pass 64 --component indirect --radiance "$TMP/crefi.pm" -o "$TMP/crefi.exr" &&
    "$BIN/measure-error" "$TMP/ci.pm" "$TMP/crefi.pm" >"$TMP/cerri.json"
means_agree "Cornell box, indirect only: simd-gather against trace-reference --component indirect" "$TMP/cerri.json" 0.05

# A glossy floor (normalized Phong, Ns 20) in a closed box: the two renderers sample and
# evaluate the lobe by separate code (trace-photons and simd-gather; trace-reference's BRDF
# mixture), so agreement of the means (measured at 64 x 64: 0.2% apart) checks both.
GL=tests/scenes/glossy-box/scene.json
"$R" "$GL" -q --width 32 --height 32 --spp 512 --pass 256 --radiance "$TMP/gref.pm" -o "$TMP/gref.exr"
"$BIN/trace-photons" "$GL" -q --photons 300000 -o - | "$BIN/build-photonmap" - -q -o "$TMP/gmap.pm" &&
    "$BIN/trace-gather-points" "$GL" -q --width 32 --height 32 --spp 64 -o "$TMP/gq.pm" --direct "$TMP/gd.pm" &&
    "$BIN/simd-gather" "$TMP/gmap.pm" "$TMP/gq.pm" --k 50 -q -o "$TMP/gi.pm" &&
    "$BIN/composite" -q "$TMP/gd.pm" "$TMP/gi.pm" -o "$TMP/gpm.exr" &&
    "$BIN/measure-error" "$TMP/gpm.exr" "$TMP/gref.pm" >"$TMP/gerr.json"
means_agree "glossy box, photon pipeline against trace-reference" "$TMP/gerr.json" 0.03

# ---- golden file and determinism ----
# The Cornell box at 16 x 16, 8 samples, seed 1 (regenerate: bin/trace-reference
# scenes/cornell-box/scene.json --width 16 --height 16 --spp 8 --radiance
# tests/golden/trace-reference-cornell.pm -o /tmp/x.exr). Embree may round a hit differently
# on another CPU, hence the tolerances (as for trace-gather-points' golden files).
G=tests/golden
for t in 1 2; do
    "$R" "$C" -q --width 16 --height 16 --spp 8 --pass 3 --threads $t --radiance "$TMP/g$t.pm" -o "$TMP/g$t.exr"
done
expect_exit "Cornell 16x16, 8 samples: matches the golden buffer" 0 \
    "$BIN/pm-compare" --max-rel 1e-4 --max-abs 1e-6 "$G/trace-reference-cornell.pm" "$TMP/g1.pm"
expect_exit "... bit-identical over 1 and 2 threads" 0 "$BIN/pm-compare" "$TMP/g1.pm" "$TMP/g2.pm"
"$DUMP" "$TMP/g1.exr" >"$TMP/g1.txt"; "$DUMP" "$TMP/g2.exr" >"$TMP/g2.txt"
expect_same "... and so are the EXR pixels" "$TMP/g1.txt" "$TMP/g2.txt"
if [ "$("$DUMP" "$TMP/g1.exr" samples)" = 8 ] && [ "$("$DUMP" "$TMP/g1.exr" estimator)" = path-tracer ] &&
    "$BIN/pm-info" "$TMP/g1.pm" | grep -q '^CHANNELS=rgb variance$'; then
    pass "the EXR says its samples and estimator; the buffer carries the variance"
else
    fail "provenance" "$("$BIN/pm-info" "$TMP/g1.pm" | head -20 | tr '\n' ' ')"
fi

# ---- progressive: --resume continues exactly, --time stops at a pass ----
"$R" "$C" -q --width 16 --height 16 --spp 4 --radiance "$TMP/r4.pm" -o "$TMP/r4.exr"
"$R" "$C" -q --width 16 --height 16 --spp 8 --resume "$TMP/r4.pm" --radiance "$TMP/r8.pm" -o "$TMP/r8.exr" \
    --stats "$TMP/r8.json"
"$R" "$C" -q --width 16 --height 16 --spp 8 --pass 4 --radiance "$TMP/s8.pm" -o "$TMP/s8.exr"
# The means are carried bit for bit; the variance is rebuilt from its rounded self.
expect_exit "4 samples resumed to 8 equal 8 in two passes of 4 (mean exactly)" 0 \
    "$BIN/pm-compare" --max-rel 1e-12 "$TMP/s8.pm" "$TMP/r8.pm"
"$BIN/pm-compare" --max-rel 1e-12 --stats "$TMP/rc.json" "$TMP/s8.pm" "$TMP/r8.pm" >/dev/null 2>&1
awk -v v="$(grep -o '"rgb_max_abs": *[-0-9.eE+]*' "$TMP/rc.json" | sed 's/.*: *//')" 'BEGIN { exit !(v != "" && v == 0) }' &&
    pass "... the mean bit-identical" || fail "resumed mean" "$(cat "$TMP/rc.json")"
[ "$(stat r8 samples_resumed)" = 4 ] && pass "--stats counts the resumed samples" || fail "samples_resumed" "$(stat r8 samples_resumed)"
"$R" "$C" -q --width 16 --height 16 --spp 100000 --pass 1 --time 0.2 --stats "$TMP/t.json" -o "$TMP/t.exr"
n=$(grep -o '"samples": *[0-9]*' "$TMP/t.json" | sed 's/.*: *//')
if [ "$(grep -o '"timed_out": *[0-9]' "$TMP/t.json" | sed 's/.*: *//')" = 1 ] && [ "$n" -ge 1 ] && [ "$n" -lt 100000 ] &&
    [ "$("$DUMP" "$TMP/t.exr" samples)" = "$n" ]; then
    pass "--time stops after a whole pass, and the image says how many samples it holds ($n)"
else
    fail "--time" "samples $n: $(cat "$TMP/t.json")"
fi

# ---- refusals: one line, exit 1 or 2, no output ----
make_lit_plane "$TMP/dark" 1 0 0.5
expect_error "a scene without lights" "^trace-reference: scene '.*' has no lights" "$R" "$TMP/dark/scene.json" -o "$TMP/no.exr"
expect_error "--resume of another seed" "^trace-reference: --resume '.*' has seed 1, this render 2" \
    "$R" "$C" --width 16 --height 16 --resume "$TMP/r4.pm" --seed 2 -o "$TMP/no.exr"
expect_error "--resume of another size" "^trace-reference: --resume '.*' is 16x16, this render 8x8" \
    "$R" "$C" --width 8 --height 8 --resume "$TMP/r4.pm" -o "$TMP/no.exr"
expect_error "--resume of a gather's buffer" "^trace-reference: radiance buffer '.*' lacks channel 'variance'" \
    "$R" "$C" --width 16 --height 16 --resume "$TMP/cd.pm" -o "$TMP/no.exr"
expect_exit "an EXR to stdout is a usage error" 2 "$R" "$C"
grep -q "^trace-reference: an OpenEXR output needs a file name" "$TMP/err" && pass "... which says so" || fail "stdout message" "$(cat "$TMP/err")"
expect_exit "the output given twice is a usage error" 2 "$R" "$C" "$TMP/no.exr" -o "$TMP/no.exr"
[ ! -e "$TMP/no.exr" ] && pass "no output file after a refusal" || fail "refusal output" "$TMP/no.exr exists"

# ---- measure-error against a reference that reports its variance ----
"$BIN/measure-error" "$TMP/cpm.exr" "$TMP/cref.pm" >"$TMP/cerr2.json"
rr=$(grep -o '"reference_rmse": *[-0-9.eE+]*' "$TMP/cerr2.json" | sed 's/.*: *//')
"$R" "$C" -q --width 64 --height 64 --spp 256 --pass 64 --stats "$TMP/cref.json" -o "$TMP/cref2.exr"
se=$(grep -o '"stderr_rms": *[-0-9.eE+]*' "$TMP/cref.json" | sed 's/.*: *//')
if awk -v a="$rr" -v b="$se" 'BEGIN { exit !(a > 0 && (a - b) ^ 2 < (1e-6 * b) ^ 2) }'; then
    pass "measure-error reports the reference's own error floor ($rr, trace-reference's stderr_rms)"
else
    fail "measure-error reference_rmse" "'$rr' against stderr_rms '$se'"
fi
"$BIN/measure-error" "$TMP/cpm.exr" "$TMP/cref.exr" | grep -q reference_rmse &&
    fail "an EXR reference has no variance" "reference_rmse reported" || pass "an EXR reference reports no floor it does not know"
