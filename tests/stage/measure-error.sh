# measure-error.sh: measure-error on images whose errors are known: an image against itself,
# against twice itself (error = the reference), an EXR against its own radiance file, and bad
# inputs.
source tests/scenes/make-analytic.sh
ME=$BIN/measure-error
make_lit_plane "$TMP/plane" 1 3.141592653589793 0.5
"$BIN/trace-photons" "$TMP/plane/scene.json" --photons 20000 -q -o - | "$BIN/build-photonmap" - -q -o "$TMP/map.pm"
"$BIN/trace-gather-points" "$TMP/plane/scene.json" --mode direct-vis --width 8 --height 6 -q -o - |
    "$BIN/simd-gather" "$TMP/map.pm" - --k 50 -q -o "$TMP/a.pm"
"$BIN/composite" "$TMP/a.pm" -q -o "$TMP/a.exr"
"$BIN/composite" "$TMP/a.pm:2" -q -o "$TMP/a2.exr" --radiance "$TMP/a2.pm"
"$BIN/pm-info" -r "$TMP/a.pm" | awk '$1 ~ /^[0-9]+$/ { print $2; print $3; print $4 }' >"$TMP/r.txt"

# field NAME FILE: a number from measure-error's JSON
field() { jq -r ".$1" "$2"; }

if "$ME" "$TMP/a.pm" "$TMP/a.pm" >"$TMP/same.json" && [ "$(field rmse "$TMP/same.json")" = 0 ] &&
    [ "$(field relmse "$TMP/same.json")" = 0 ] && [ "$(field mean_abs_rel "$TMP/same.json")" = 0 ] &&
    [ "$(field values "$TMP/same.json")" = 144 ] && [ "$(field width "$TMP/same.json")" = 8 ]; then
    pass "an image against itself: every error is 0, 8x6 pixels, 144 values"
else
    fail "image against itself" "$(tr -d '\n' <"$TMP/same.json")"
fi

# Twice the reference: t - r = r, so rmse = sqrt(mean r^2), relmse = mean r^2 / (r^2 + eps),
# mean_abs_rel = mean r / (r + eps); computed here from the values and compared to 1e-9.
want=$(awk '{ n++; s2 += $1 * $1; q += $1 * $1 / ($1 * $1 + 0.01); a += $1 / ($1 + 0.01) }
    END { printf "%.17g %.17g %.17g\n", sqrt(s2 / n), q / n, a / n }' "$TMP/r.txt")
if "$ME" "$TMP/a2.pm" "$TMP/a.pm" >"$TMP/twice.json"; then
    got="$(field rmse "$TMP/twice.json") $(field relmse "$TMP/twice.json") $(field mean_abs_rel "$TMP/twice.json")"
    if awk -v w="$want" -v g="$got" 'BEGIN { split(w, a); split(g, b)
            for (i = 1; i <= 3; i++) if ((a[i] - b[i]) ^ 2 > (1e-9 * a[i]) ^ 2) exit 1 }'; then
        pass "twice the reference: rmse, relmse and mean_abs_rel match their formulas"
    else
        fail "twice the reference" "got $got, want $want"
    fi
else
    fail "twice the reference" "$(cat "$TMP/twice.json")"
fi

# An EXR (float) against the radiance file it was made from: only float rounding.
if "$ME" "$TMP/a.exr" "$TMP/a.pm" >"$TMP/exr.json" &&
    awk -v e="$(field mean_abs_rel "$TMP/exr.json")" 'BEGIN { exit !(e < 1e-6) }'; then
    pass "EXR against its radiance file: mean_abs_rel below 1e-6"
else
    fail "EXR against radiance" "$(tr -d '\n' <"$TMP/exr.json")"
fi
# EXR against EXR, and --error-image: |t - r| = r for twice the reference.
if "$ME" "$TMP/a2.exr" "$TMP/a.exr" --error-image "$TMP/err.exr" >/dev/null &&
    "$BUILD/tests/pm-exrdump" "$TMP/err.exr" | awk 'NR > 1 { print $3; print $4; print $5 }' >"$TMP/e.txt" &&
    paste "$TMP/e.txt" "$TMP/r.txt" | awk '{ n++; if (($1 - $2) ^ 2 > (1e-6 * $2 + 1e-12) ^ 2) bad++ } END { exit bad || n != 144 }'; then
    pass "--error-image holds |t - r| per pixel and channel"
else
    fail "--error-image" "$(head -5 "$TMP/e.txt" | tr '\n' ' ')"
fi
if "$ME" "$TMP/a2.exr" "$TMP/a.exr" --error-image "$TMP/rel.exr" --error-kind rel >/dev/null &&
    [ "$("$BUILD/tests/pm-exrdump" "$TMP/rel.exr" components)" = error-rel ]; then
    pass "--error-kind rel is written and named in the EXR"
else
    fail "--error-kind rel" "no components=error-rel"
fi

# Bad inputs: one line on stderr, exit 1 (2 for usage).
"$BIN/trace-gather-points" "$TMP/plane/scene.json" --mode direct-vis --width 8 --height 8 -q -o - |
    "$BIN/simd-gather" "$TMP/map.pm" - --k 50 -q -o "$TMP/b.pm"
expect_error "different sizes are an error naming both" "'.*a.pm' is 8x6 but '.*b.pm' is 8x8" "$ME" "$TMP/a.pm" "$TMP/b.pm"
expect_error "a file that is no radiance buffer is an error" "is a photon map, expected a radiance|expected a radiance" \
    "$ME" "$TMP/map.pm" "$TMP/a.pm"
expect_error "a missing file is an error" "cannot open" "$ME" "$TMP/nope.exr" "$TMP/a.pm"
expect_exit "both inputs on stdin is a usage error" 2 "$ME" - -
expect_exit "epsilon 0 is refused (it would divide by zero)" 2 "$ME" --epsilon 0 "$TMP/a.pm" "$TMP/a.pm"
expect_exit "--help exits 0" 0 "$ME" --help
