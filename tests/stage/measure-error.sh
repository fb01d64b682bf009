# measure-error.sh: measure-error on images whose errors are known: an image against itself,
# against twice itself (error = the reference), an EXR against its own radiance file, references
# as another renderer writes them (PFM in both byte orders, tiled and ripmapped EXR), and bad
# inputs (a reference of another size, a truncated PFM).
# programs: build-photonmap composite measure-error simd-gather trace-gather-points trace-photons
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

# References from other renderers. A PFM made here from composite's EXR (pm-exrdump's text
# packed by perl, rows bottom first), in each byte order: the same values, so zero error.
# to_pfm EXR PFM ORDER: ORDER '<' writes little-endian (scale -1), '>' big-endian (scale 1).
to_pfm() {
    "$BUILD/tests/pm-exrdump" "$1" | perl -e '
        my ($order) = @ARGV; my ($w, $h, @px);
        while (<STDIN>) { my @f = split; if ($f[0] eq "size") { ($w, $h) = @f[1, 2]; next }
            $px[$f[1] * $w + $f[0]] = [@f[2 .. 4]] }
        binmode STDOUT; printf "PF\n%d %d\n%s\n", $w, $h, $order eq "<" ? "-1.0" : "1.0";
        for (my $y = $h - 1; $y >= 0; $y--) { print pack("f$order" x 3, @{$px[$y * $w + $_]}) for 0 .. $w - 1 }' "$3" >"$2"
}
to_pfm "$TMP/a.exr" "$TMP/le.pfm" '<'
to_pfm "$TMP/a.exr" "$TMP/be.pfm" '>'
for order in le be; do
    if "$ME" "$TMP/a.exr" "$TMP/$order.pfm" >"$TMP/pfm.json" && [ "$(field max_abs "$TMP/pfm.json")" = 0 ] &&
        [ "$(field width "$TMP/pfm.json")" = 8 ] && [ "$(field height "$TMP/pfm.json")" = 6 ]; then
        pass "a PFM reference ($order): composite's EXR measures zero against it"
    else
        fail "PFM reference ($order)" "$(tr -d '\n' <"$TMP/pfm.json")"
    fi
done
# The rows of a PFM run bottom to top: a PFM whose rows were not flipped when written differs.
"$BUILD/tests/pm-exrdump" "$TMP/a.exr" | perl -e '
    my ($w, $h, @px); while (<STDIN>) { my @f = split; if ($f[0] eq "size") { ($w, $h) = @f[1, 2]; next }
        $px[$f[1] * $w + $f[0]] = [@f[2 .. 4]] }
    binmode STDOUT; printf "PF\n%d %d\n-1.0\n", $w, $h; print pack("f<" x 3, @$_) for @px' >"$TMP/unflipped.pfm"
if "$ME" "$TMP/a.exr" "$TMP/unflipped.pfm" >"$TMP/unflipped.json" &&
    awk -v m="$(field max_abs "$TMP/unflipped.json")" 'BEGIN { exit !(m > 0) }'; then
    pass "a PFM's rows are read bottom to top (an unflipped copy does not measure zero)"
else
    fail "PFM row order" "$(tr -d '\n' <"$TMP/unflipped.json")"
fi
# The EXR reference as composite writes it, tiled and ripmapped (exrmaketiled, Debian openexr).
if command -v exrmaketiled >/dev/null; then
    exrmaketiled -t 4 4 "$TMP/a.exr" "$TMP/tiled.exr" >/dev/null 2>&1
    exrmaketiled -r -t 4 2 -z piz "$TMP/a.exr" "$TMP/rip.exr" >/dev/null 2>&1
    if "$ME" "$TMP/a.exr" "$TMP/tiled.exr" >"$TMP/tiled.json" && [ "$(field max_abs "$TMP/tiled.json")" = 0 ] &&
        "$ME" "$TMP/rip.exr" "$TMP/a.pm" >"$TMP/rip.json" &&
        awk -v e="$(field mean_abs_rel "$TMP/rip.json")" 'BEGIN { exit !(e < 1e-6) }'; then
        pass "tiled and ripmapped EXR references are read (level 0, the same values)"
    else
        fail "tiled EXR reference" "$(tr -d '\n' <"$TMP/tiled.json") $(tr -d '\n' <"$TMP/rip.json" 2>/dev/null)"
    fi
else
    skip "tiled EXR reference" "no exrmaketiled (Debian package openexr)"
fi

# Bad inputs: one line on stderr, exit 1 (2 for usage).
"$BIN/trace-gather-points" "$TMP/plane/scene.json" --mode direct-vis --width 8 --height 8 -q -o - |
    "$BIN/simd-gather" "$TMP/map.pm" - --k 50 -q -o "$TMP/b.pm"
# A reference of another size: the wrong pair of files, so a usage error (exit 2), one line
# naming both, and nothing written (neither -o nor --error-image).
"$BIN/composite" "$TMP/b.pm" -q -o "$TMP/b.exr"
to_pfm "$TMP/b.exr" "$TMP/b.pfm" '<'
for ref in b.pm b.exr b.pfm; do
    "$ME" "$TMP/a.pm" "$TMP/$ref" -o "$TMP/size.json" --error-image "$TMP/size.exr" >/dev/null 2>"$TMP/size.err"
    status=$?
    if [ $status = 2 ] && [ "$(wc -l <"$TMP/size.err")" = 1 ] &&
        grep -qE "'.*a.pm' is 8x6 but '.*$ref' is 8x8 \(usage error\)$" "$TMP/size.err" &&
        [ ! -e "$TMP/size.json" ] && [ ! -e "$TMP/size.exr" ]; then
        pass "a reference of another size ($ref): one line naming both, exit 2, nothing written"
    else
        fail "reference of another size ($ref)" "exit $status: $(cat "$TMP/size.err")"
    fi
done
head -c 100 "$TMP/le.pfm" >"$TMP/cut.pfm"
expect_error "a truncated PFM is an error saying how much is there" "truncated PFM image '.*cut.pfm': [0-9]+ of 576 bytes" \
    "$ME" "$TMP/a.pm" "$TMP/cut.pfm"
expect_error "a file that is no radiance buffer is an error" "is a photon map, expected a radiance|expected a radiance" \
    "$ME" "$TMP/map.pm" "$TMP/a.pm"
expect_error "a missing file is an error" "cannot open" "$ME" "$TMP/nope.exr" "$TMP/a.pm"
expect_exit "both inputs on stdin is a usage error" 2 "$ME" - -
expect_exit "epsilon 0 is refused (it would divide by zero)" 2 "$ME" --epsilon 0 "$TMP/a.pm" "$TMP/a.pm"
expect_exit "--help exits 0" 0 "$ME" --help
