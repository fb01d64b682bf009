# aov.sh: the layers a denoiser reads (issue 31 item 3). trace-gather-points --aov writes the aov
# format (per pixel the first surface's albedo, shading normal and distance), the same bytes for
# any thread count; composite --aov lays them beside R G B as Open Image Denoise and Blender name
# them (albedo.R/G/B, normal.X/Y/Z, Z, variance.R/G/B) and only when asked; trace-reference --aov
# and pm-render AOV= likewise; what cannot be done is refused with exit 2 and says why.
# programs: composite trace-gather-points trace-reference pm-render
BOX=tests/scenes/closed-box/scene.json
DUMP=$BUILD/tests/pm-exrdump
TGP=$BIN/trace-gather-points

# ---- trace-gather-points --aov ----
"$TGP" -q "$BOX" --primary 4 -o "$TMP/q.pm" --direct "$TMP/d.pm" --aov "$TMP/aov.pm" --threads 1 2>"$TMP/err" &&
    "$BIN/pm-info" -r "$TMP/aov.pm" >"$TMP/aov.txt" 2>>"$TMP/err"
if [ $? = 0 ] && grep -qx 'FORMAT=aov' "$TMP/aov.txt" && grep -qx 'CHANNELS=albedo normal depth' "$TMP/aov.txt" &&
    grep -qx 'COUNT=64' "$TMP/aov.txt" && grep -qx 'primary=4' "$TMP/aov.txt"; then
    pass "trace-gather-points --aov writes an aov file pm-info reads (8x8: 64 records)"
else
    fail "trace-gather-points --aov" "$(head -c 300 "$TMP/err")"
fi
# the closed box is one Lambertian kd 0.5 0.6 0.7 all round, seen from inside: every pixel's
# albedo is kd, its normal a unit vector facing the eye (z < 0 on the far wall), its distance
# between the eye's to the nearest and farthest wall
sed -n '/^# record/,/^# ok/p' "$TMP/aov.txt" | grep -v '^#' >"$TMP/rows.txt"
bad=$(awk '$2 != 0.5 || $3 != 0.600000024 || $4 != 0.699999988 { n++ }
           { l = sqrt($5 * $5 + $6 * $6 + $7 * $7); if (l < 0.999 || l > 1.001 || $8 < 0.5 || $8 > 2.5) n++ }
           END { print n + 0 }' "$TMP/rows.txt")
[ "$(wc -l <"$TMP/rows.txt")" = 64 ] && [ "$bad" = 0 ] &&
    pass "... every pixel: albedo kd, a unit normal, a distance inside the box" ||
    fail "... albedo, normal, distance" "$bad bad rows: $(head -3 "$TMP/rows.txt")"
centre=$(awk '$1 == 36 { print (($7 < -0.99 && $8 > 1.49 && $8 < 1.6) ? 1 : 0) }' "$TMP/rows.txt")
[ "$centre" = 1 ] && pass "... a centre pixel sees the far wall 1.5 m away, its normal toward the eye" ||
    fail "... centre pixel" "$(grep '^36 ' "$TMP/rows.txt")"
# (the same command in another folder: COMMAND names the outputs, and leaves --threads out)
mkdir -p "$TMP/t4"
"$TGP" -q "$BOX" --primary 4 -o "$TMP/t4/../q.pm" --direct "$TMP/t4/../d.pm" --aov "$TMP/t4/aov.pm" --threads 4 2>"$TMP/err"
"$BIN/pm-info" -r "$TMP/t4/aov.pm" | sed -n '/^# record/,/^# ok/p' | grep -v '^# ok' >"$TMP/t4.txt"
sed -n '/^# record/,/^# ok/p' "$TMP/aov.txt" | grep -v '^# ok' >"$TMP/t1.txt"
expect_same "... the same records with --threads 4 (the checksums differ by COMMAND alone)" "$TMP/t1.txt" "$TMP/t4.txt"
expect_exit "trace-gather-points --aov with --passes is refused (usage, exit 2)" 2 \
    "$TGP" -q "$BOX" --passes 1:2 -o "$TMP/qp.pm" --aov "$TMP/ap.pm"
expect_exit "trace-gather-points --aov - is refused (usage, exit 2)" 2 "$TGP" -q "$BOX" -o "$TMP/qp.pm" --aov -

# ---- composite --aov ----
"$BIN/composite" -q "$TMP/d.pm" -o "$TMP/plain.exr" 2>"$TMP/err"
[ "$("$DUMP" --channels "$TMP/plain.exr" | head -n 1)" = "channels B G R" ] &&
    pass "composite without --aov writes R G B alone" || fail "composite without --aov" "$("$DUMP" --channels "$TMP/plain.exr" | head -n 1)"
"$BIN/composite" -q "$TMP/d.pm" -o "$TMP/aov.exr" --aov albedo,normal,depth --aov-buffer "$TMP/aov.pm" 2>"$TMP/err"
"$DUMP" --channels "$TMP/aov.exr" >"$TMP/layers.txt" 2>>"$TMP/err"
if [ "$(head -n 1 "$TMP/layers.txt")" = "channels B G R Z albedo.B albedo.G albedo.R normal.X normal.Y normal.Z" ]; then
    pass "composite --aov albedo,normal,depth: layers albedo.R/G/B, normal.X/Y/Z and Z beside R G B"
else
    fail "composite --aov albedo,normal,depth" "$(head -n 1 "$TMP/layers.txt") $(head -c 300 "$TMP/err")"
fi
# the layers hold the aov file's values: pixel 36 (x 4, y 4) in both
exr_px=$(awk '$1 == 4 && $2 == 4 { print $7, $8, $9, $10, $11, $12, $6 }' "$TMP/layers.txt")
aov_px=$(awk '$1 == 36 { print $4, $3, $2, $5, $6, $7, $8 }' "$TMP/rows.txt")
[ -n "$exr_px" ] && [ "$exr_px" = "$aov_px" ] && pass "... holding the aov file's values" ||
    fail "... holding the aov file's values" "EXR '$exr_px', aov '$aov_px'"
rgb_plain=$("$DUMP" "$TMP/plain.exr" | md5sum) rgb_aov=$("$DUMP" "$TMP/aov.exr" | md5sum)
[ "$rgb_plain" = "$rgb_aov" ] && pass "... and R G B as without them" || fail "... R G B" "differ"
"$BIN/composite" -q "$TMP/d.pm" -o "$TMP/depth.exr" --aov depth --aov-buffer "$TMP/aov.pm" --half 2>"$TMP/err"
[ "$("$DUMP" --channels "$TMP/depth.exr" | head -n 1)" = "channels B G R Z" ] &&
    pass "composite --aov depth --half: Z alone" || fail "composite --aov depth" "$(head -c 300 "$TMP/err")"
rm -f "$TMP/state.pm"
"$BIN/composite" -q "$TMP/d.pm" -o "$TMP/v1.exr" --accumulate "$TMP/state.pm" 2>"$TMP/err"
"$TGP" -q "$BOX" --pass 2 -o "$TMP/q2.pm" --direct "$TMP/d2.pm" 2>>"$TMP/err"
"$BIN/composite" -q "$TMP/d2.pm" -o "$TMP/var.exr" --accumulate "$TMP/state.pm" --aov variance 2>>"$TMP/err"
"$DUMP" --channels "$TMP/var.exr" >"$TMP/var.txt" 2>>"$TMP/err"
exr_var=$(awk '$1 == 3 && $2 == 5 { printf "%.6g %.6g %.6g", $8, $7, $6 }' "$TMP/var.txt")
state_var=$("$BIN/pm-info" -r "$TMP/state.pm" | awk '$1 == 43 { printf "%.6g %.6g %.6g", $5, $6, $7 }')
if [ "$(head -n 1 "$TMP/var.txt")" = "channels B G R variance.B variance.G variance.R" ] && [ -n "$exr_var" ] &&
    [ "$exr_var" = "$state_var" ]; then
    pass "composite --accumulate --aov variance: variance.R/G/B, the running image's ($exr_var)"
else
    fail "composite --aov variance" "$(head -n 1 "$TMP/var.txt"): EXR '$exr_var', state '$state_var' $(head -c 200 "$TMP/err")"
fi
expect_exit "composite --aov variance without --accumulate is usage, exit 2" 2 \
    "$BIN/composite" "$TMP/d.pm" -o "$TMP/x.exr" --aov variance
expect_exit "composite --aov albedo without --aov-buffer is usage, exit 2" 2 \
    "$BIN/composite" "$TMP/d.pm" -o "$TMP/x.exr" --aov albedo
expect_exit "composite --aov with an unknown layer is usage, exit 2" 2 \
    "$BIN/composite" "$TMP/d.pm" -o "$TMP/x.exr" --aov albedo,specular --aov-buffer "$TMP/aov.pm"
expect_exit "composite --aov-buffer without --aov is usage, exit 2" 2 \
    "$BIN/composite" "$TMP/d.pm" -o "$TMP/x.exr" --aov-buffer "$TMP/aov.pm"
expect_exit "composite --aov with --stream is usage, exit 2" 2 \
    "$BIN/composite" --stream "$TMP/d.pm" -o "$TMP/f%04d.exr" --aov depth --aov-buffer "$TMP/aov.pm"
"$TGP" -q "$BOX" --width 4 --height 4 -o "$TMP/qs.pm" --aov "$TMP/aov-small.pm" 2>"$TMP/err"
expect_error "composite: an aov file of another size is named" "resolution mismatch: AOV buffer '.*aov-small.pm' is 4x4" \
    "$BIN/composite" "$TMP/d.pm" -o "$TMP/x.exr" --aov normal --aov-buffer "$TMP/aov-small.pm"
[ ! -e "$TMP/x.exr" ] && pass "... and writes no image" || fail "... writes no image" "x.exr exists"

# ---- trace-reference --aov ----
"$BIN/trace-reference" -q "$BOX" --spp 8 --pass 8 -o "$TMP/ref.exr" --radiance "$TMP/ref.pm" \
    --aov albedo,normal,depth,variance 2>"$TMP/err"
"$DUMP" --channels "$TMP/ref.exr" >"$TMP/ref.txt" 2>>"$TMP/err"
ref_var=$(awk '$1 == 2 && $2 == 6 { printf "%.6g %.6g %.6g %.6g", $15, $14, $13, $9 }' "$TMP/ref.txt")
pm_var=$("$BIN/pm-info" -r "$TMP/ref.pm" | awk '$1 == 50 { printf "%.6g %.6g %.6g", $5, $6, $7 }')
if [ "$(head -n 1 "$TMP/ref.txt")" = \
    "channels B G R Z albedo.B albedo.G albedo.R normal.X normal.Y normal.Z variance.B variance.G variance.R" ] &&
    [ "$ref_var" = "$pm_var 0.5" ]; then
    pass "trace-reference --aov: every layer; variance its radiance buffer's, albedo the box's kd"
else
    fail "trace-reference --aov" "$(head -n 1 "$TMP/ref.txt"): '$ref_var' vs '$pm_var 0.5' $(head -c 200 "$TMP/err")"
fi
"$BIN/trace-reference" -q "$BOX" --spp 4 --pass 4 -o "$TMP/ref0.exr" 2>"$TMP/err"
[ "$("$DUMP" --channels "$TMP/ref0.exr" | head -n 1)" = "channels B G R" ] &&
    pass "trace-reference without --aov: R G B alone" || fail "trace-reference without --aov" "$(head -c 300 "$TMP/err")"
expect_exit "trace-reference --aov with a repeated layer is usage, exit 2" 2 \
    "$BIN/trace-reference" "$BOX" --spp 4 -o "$TMP/x.exr" --aov depth,depth

# ---- pm-render AOV= ----
"$BIN/pm-render" "$BOX" "$TMP/r" PHOTONS=2000 SPP=4 AOV=albedo,normal >"$TMP/out" 2>"$TMP/err"
[ $? = 0 ] && [ "$("$DUMP" --channels "$TMP/r/image.exr" | head -n 1)" = "channels B G R albedo.B albedo.G albedo.R normal.X normal.Y normal.Z" ] &&
    pass "pm-render AOV=albedo,normal: image.exr carries the layers" || fail "pm-render AOV=" "$(tail -c 300 "$TMP/err")"
"$BIN/pm-render" "$BOX" "$TMP/r2" PASSES=2 AOV=albedo >"$TMP/out" 2>"$TMP/err"
st=$?
[ $st = 2 ] && grep -q "AOV=albedo is done for a one-pass render only" "$TMP/err" && [ ! -e "$TMP/r2/image.exr" ] &&
    pass "pm-render AOV= with PASSES is refused with exit 2, saying why" || fail "pm-render AOV= PASSES" "exit $st: $(head -c 300 "$TMP/err")"
expect_exit "pm-render AOV=variance for one pass is usage, exit 2" 2 "$BIN/pm-render" "$BOX" "$TMP/r2" AOV=variance

# ---- the reader: an aov file whose header disagrees with its records is named ----
sed '0,/^width=8$/s//width=4/' "$TMP/aov.pm" >"$TMP/w4.pm"
"$BUILD/tests/pm-testgen" reseal "$TMP/w4.pm" "$TMP/w4s.pm"
expect_error "pm-info: an aov file of COUNT other than width x height" \
    "wrong count in AOV buffer '.*w4s.pm': COUNT=64 for a 4x8 image" "$BIN/pm-info" "$TMP/w4s.pm"

# ---- the EXR writer at one pixel (issue 31: a 1x1 zip image was reported as garbage), read back by
# OpenEXR's own C++ library (exrmaketiled rewrites it tiled) as well as by pmtk's reader ----
for half in "" --half; do
    "$BIN/trace-reference" -q "$BOX" --width 1 --height 1 --spp 4 --pass 4 -o "$TMP/one.exr" --radiance "$TMP/one.pm" 2>"$TMP/err"
    "$BIN/composite" -q "$TMP/one.pm" -o "$TMP/one-c.exr" $half --aov variance --accumulate "$TMP/one-state$half.pm" 2>>"$TMP/err"
    if command -v exrmaketiled >/dev/null; then
        exrmaketiled "$TMP/one-c.exr" "$TMP/one-t.exr" >/dev/null 2>>"$TMP/err"
        a=$("$DUMP" --channels "$TMP/one-c.exr" 2>>"$TMP/err" | tail -n 1) b=$("$DUMP" "$TMP/one-t.exr" 2>>"$TMP/err" | tail -n 1)
        want=$("$BIN/pm-info" -r "$TMP/one.pm" | awk '$1 == 0 { printf "%.3g %.3g %.3g", $2, $3, $4 }')
        got=$(echo "$b" | awk '{ printf "%.3g %.3g %.3g", $3, $4, $5 }')
        [ -n "$want" ] && [ "$got" = "$want" ] && [ "$(echo "$a" | wc -w)" = 8 ] &&
            pass "a 1x1 image ${half:-float} with a layer reads back through OpenEXR's C++ library ($got)" ||
            fail "a 1x1 image ${half:-float}" "got '$got' want '$want' ($a) $(head -c 200 "$TMP/err")"
    else
        skip "a 1x1 image through OpenEXR's C++ library" "no exrmaketiled (Debian package openexr)"
    fi
done
