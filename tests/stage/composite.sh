# composite.sh: radiance buffers into OpenEXR and PNG. The EXR is read back two ways: pixel
# values through the OpenEXR C API (build/tests/pm-exrdump, common/base/exr.c's reader), channels
# and attributes through OpenEXR's own exrheader. No timing here.
# programs: composite
G=tests/golden
C=$BIN/composite
GEN=$BUILD/tests/pm-testgen
DUMP=$BUILD/tests/pm-exrdump

"$GEN" radiance 1 "$TMP/r.pm"                                     # 4x3, component=indirect, SCENE=test
"$GEN" radiance 1 "$TMP/rd.pm" --set component=direct
"$GEN" radiance 1 "$TMP/other.pm" --set 'SCENE=other xxh3:fedcba9876543210'
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }

# ---- golden values: r + 0.5 r, in float ----
"$C" -q "$TMP/r.pm" "$TMP/r.pm:0.5" -o "$TMP/g.exr" --stats "$TMP/g.json"
"$DUMP" "$TMP/g.exr" >"$TMP/g.txt"
# -q and --stats change no output, so the file records neither (docs/formats.md, COMMAND): the
# same command without them, and with --quiet, writes the same bytes
cp "$TMP/g.exr" "$TMP/g-quiet.exr"
"$C" "$TMP/r.pm" "$TMP/r.pm:0.5" -o "$TMP/g.exr" 2>/dev/null && cmp -s "$TMP/g.exr" "$TMP/g-quiet.exr" &&
    "$C" --quiet "$TMP/r.pm" --stats=- "$TMP/r.pm:0.5" -o "$TMP/g.exr" 2>/dev/null && cmp -s "$TMP/g.exr" "$TMP/g-quiet.exr" &&
    pass "composite with and without -q, --quiet and --stats writes the same bytes" ||
    fail "-q and --stats change the file" "$(cmp "$TMP/g.exr" "$TMP/g-quiet.exr")"
expect_same "r + r:0.5 gives the golden EXR pixels" "$TMP/g.txt" "$G/composite-testgen-1.5.txt"
# and the golden file itself is 1.5 x the records, to float rounding (not merely self-consistent)
if paste -d' ' <(records "$TMP/r.pm") <(tail -n +2 "$TMP/g.txt") | awk '
    { for (c = 0; c < 3; c++) { e = 1.5 * $(2 + c); g = $(7 + c); if (g - e > 1e-7 * e || e - g > 1e-7 * e) bad = 1 } n++ }
    END { exit bad || n != 12 }'; then
    pass "the golden pixels are 1.5 x the input records"
else
    fail "golden pixels = 1.5 x input" "$(head -3 "$TMP/g.txt")"
fi
# the same through stdin, and as one buffer scaled by 1.5
cat "$TMP/r.pm" | "$C" -q - "$TMP/r.pm:0.5" -o "$TMP/s.exr" && "$DUMP" "$TMP/s.exr" >"$TMP/s.txt"
expect_same "a buffer on stdin ('-') adds the same" "$TMP/s.txt" "$G/composite-testgen-1.5.txt"
"$C" -q "$TMP/r.pm:1.5" -o "$TMP/one.exr" && "$DUMP" "$TMP/one.exr" >"$TMP/one.txt"
expect_same "FILE:1.5 equals FILE + FILE:0.5" "$TMP/one.txt" "$G/composite-testgen-1.5.txt"

# ---- half: each value within half's rounding of the float one ----
"$C" -q "$TMP/r.pm" "$TMP/r.pm:0.5" --half -o "$TMP/h.exr" && "$DUMP" "$TMP/h.exr" >"$TMP/h.txt"
if paste -d' ' "$TMP/g.txt" "$TMP/h.txt" | awk 'NR > 1 {
        for (c = 3; c <= 5; c++) { f = $c; h = $(c + 5); if (h - f > f / 2048 || f - h > f / 2048) bad = 1 }
        if (f != h) differ = 1 }
    END { exit bad || !differ }'; then
    pass "--half stores every value to within 2^-11, and is not float"
else
    fail "--half values" "$(head -3 "$TMP/h.txt")"
fi

# ---- OpenEXR's own tool reads it: channels, provenance attributes ----
if command -v exrheader >/dev/null; then
    exrheader "$TMP/g.exr" >"$TMP/hdr" 2>&1
    hash=$("$BIN/pm-info" "$TMP/r.pm" | sed -n 's/^# ok: .*checksum //p')
    if grep -qE '^ +B, 32-bit floating-point' "$TMP/hdr" && grep -qE '^ +G, 32-bit floating-point' "$TMP/hdr" &&
        grep -qE '^ +R, 32-bit floating-point' "$TMP/hdr" && grep -q '^SOFTWARE (type string): "pmtk ' "$TMP/hdr" &&
        grep -q '^SCENE (type string): "test xxh3:0123456789abcdef"' "$TMP/hdr" &&
        grep -q '^COMMAND.0 (type string): "pm-testgen radiance --required"' "$TMP/hdr" &&
        grep -qxF "COMMAND.1 (type string): \"composite $TMP/r.pm $TMP/r.pm:0.5 -o $TMP/g.exr\"" "$TMP/hdr" &&
        grep -q "^INPUT.0 (type string): \"$TMP/r.pm $hash\"" "$TMP/hdr" &&
        grep -q "^INPUT.1 (type string): \"$TMP/r.pm $hash\"" "$TMP/hdr" &&
        grep -q '^dataWindow (type box2i): (0 0) - (3 2)' "$TMP/hdr"; then
        pass "exrheader reads R G B float channels and the provenance (SOFTWARE, SCENE, COMMAND, INPUT)"
    else
        fail "exrheader channels and attributes" "$(head -c 800 "$TMP/hdr")"
    fi
    exrheader "$TMP/h.exr" 2>&1 | grep -qE '^ +R, 16-bit floating-point' && pass "exrheader sees --half as 16-bit" ||
        fail "exrheader --half" "$(exrheader "$TMP/h.exr" 2>&1 | head -c 400)"
else
    skip "exrheader reads the EXR" "exrheader not installed (Debian package openexr; make deps)"
fi

# ---- --only, components ----
"$C" -q "$TMP/rd.pm" "$TMP/r.pm:0.5" --only direct -o "$TMP/od.exr" --stats "$TMP/od.json"
"$C" -q "$TMP/r.pm:1" -o "$TMP/r1.exr"
if cmp -s <("$DUMP" "$TMP/od.exr") <("$DUMP" "$TMP/r1.exr") && grep -q '"buffers": 1' "$TMP/od.json" &&
    grep -q '"components": "direct"' "$TMP/od.json" && [ "$("$DUMP" "$TMP/od.exr" components)" = direct ]; then
    pass "--only direct adds the direct buffer and leaves the indirect one out"
else
    fail "--only direct" "$(cat "$TMP/od.json")"
fi
"$C" -q "$TMP/rd.pm" "$TMP/r.pm" -o "$TMP/both.exr"
[ "$("$DUMP" "$TMP/both.exr" components)" = total ] && pass "direct + indirect is components=total" ||
    fail "components total" "$("$DUMP" "$TMP/both.exr" components 2>&1)"
expect_error "--only with no buffer of that component" "--only direct: none of the 1 buffers is direct" \
    "$C" -q "$TMP/r.pm" --only direct -o "$TMP/none.exr"

# ---- refusals: one line, exit 1, no output ----
expect_error "buffers of different resolution" \
    "^composite: resolution mismatch: '$G/direct-cornell-16x16.pm' is 16x16, '$TMP/r.pm' is 4x3 \(input error\)$" \
    "$C" "$TMP/r.pm" "$G/direct-cornell-16x16.pm" -o "$TMP/bad.exr" --png "$TMP/bad.png"
expect_error "buffers of different scenes" \
    "^composite: scene mismatch: '$TMP/other.pm' is of scene 'other xxh3:fedcba9876543210', '$TMP/r.pm' of scene 'test xxh3:0123456789abcdef' \(input error\)$" \
    "$C" "$TMP/r.pm" "$TMP/other.pm" -o "$TMP/bad.exr"
expect_error "a scale that overflows float is refused, not written as Inf" \
    "^composite: pixel \([0-9], [0-9]\) channel [RGB] is .*e\+38 after scaling, beyond float \(largest 3.40282e\+38\) \(input error\)$" \
    "$C" "$TMP/r.pm:3.5e38" -o "$TMP/bad.exr"
expect_error "a sum that overflows f64 is refused" "^composite: pixel \(0, 0\) channel R is inf after scaling" \
    "$C" -q "$TMP/r.pm:1.5e308" "$TMP/r.pm:1.5e308" -o "$TMP/bad.exr"
expect_error "a value beyond half is refused with --half" "^composite: pixel \(0, 0\) channel R is 95.*beyond half" \
    "$C" "$TMP/r.pm:1e5" --half -o "$TMP/bad.exr"
expect_error "an unreadable buffer" "cannot open '$TMP/missing.pm'" "$C" "$TMP/r.pm" "$TMP/missing.pm" -o "$TMP/bad.exr"
expect_error "a file of another format" "radiance" "$C" "$G/photons-all.pm" -o "$TMP/bad.exr"
if [ -z "$(ls -A "$TMP" | grep -E '^(bad|none)\.|^\.bad')" ]; then pass "... no output or temporary file left"; else
    fail "no output left" "$(ls -A "$TMP")"; fi
expect_exit "no output at all is a usage error" 2 "$C" "$TMP/r.pm"
expect_exit "stdin twice is a usage error" 2 "$C" - - -o "$TMP/bad.exr"

# ---- PNG preview, exposure, tone, the sum as a radiance buffer ----
"$C" -q "$TMP/r.pm" --png "$TMP/p0.png" --radiance "$TMP/sum.pm"
"$C" -q "$TMP/r.pm" --png "$TMP/p1.png" --exposure 2
"$C" -q "$TMP/r.pm" --png "$TMP/pf.png" --tone filmic
if [ "$(head -c 8 "$TMP/p0.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] && ! cmp -s "$TMP/p0.png" "$TMP/p1.png" &&
    ! cmp -s "$TMP/p0.png" "$TMP/pf.png" && [ ! -e "$TMP/-" ]; then
    pass "--png writes a PNG that --exposure and --tone change"
else
    fail "--png" "missing or unchanged previews"
fi
if cmp -s <(records "$TMP/sum.pm") <(records "$TMP/r.pm") && "$BIN/pm-info" "$TMP/sum.pm" | grep -q '^component=indirect$'; then
    pass "--radiance writes the sum as a radiance buffer with the inputs' component"
else
    fail "--radiance" "$("$BIN/pm-info" "$TMP/sum.pm" 2>&1 | head -20)"
fi

# ---- stats: luminance of the golden image (Rec. 709 weights) ----
want=$(tail -n +2 "$TMP/g.txt" | awk '{ l = 0.2126 * $3 + 0.7152 * $4 + 0.0722 * $5; s += l; if (NR == 1 || l > mx) mx = l }
    END { printf "%.5g %.5g", mx, s / NR }')
got=$(jq -r '"\(.luminance_max) \(.luminance_mean)"' "$TMP/g.json" | awk '{ printf "%.5g %.5g", $1, $2 }')
if [ "$want" = "$got" ] && [ "$(jq .pixels "$TMP/g.json")" = 12 ]; then pass "stats: pixels and luminance max/mean"; else
    fail "stats luminance" "want $want, got $got"; fi

# ---- the Cornell box's direct light: a real buffer with the scene's provenance ----
"$C" -q "$G/direct-cornell-16x16.pm" -o "$TMP/c.exr" --png "$TMP/c.png"
if [ "$("$DUMP" "$TMP/c.exr" SCENE)" = "$("$BIN/pm-info" "$G/direct-cornell-16x16.pm" | sed -n 's/^SCENE=//p')" ] &&
    [ "$("$DUMP" "$TMP/c.exr" | head -1)" = "size 16 16" ]; then
    pass "the Cornell box direct buffer composites with its SCENE"
else
    fail "cornell composite" "$("$DUMP" "$TMP/c.exr" SCENE 2>&1)"
fi
