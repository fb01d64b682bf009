# simd-gather.sh: the gather on golden inputs, across ISAs, threads and shards; variable
# widths; pipes; bad inputs.
# Golden file (regenerate only when a change is meant to alter it, and say why):
#   bin/simd-gather tests/golden/build-photonmap-cornell.pm tests/golden/gather-cornell-16x16-spp8.pm \
#       --radius 0.05 -o tests/golden/simd-gather-cornell.pm
# programs: build-photonmap hilbert-sort simd-gather trace-gather-points
G=tests/golden
MAP=$G/build-photonmap-cornell.pm
Q=$G/gather-cornell-16x16-spp8.pm
SG=$BIN/simd-gather

"$SG" "$MAP" "$Q" --radius 0.05 -q -o "$TMP/ind.pm" --stats "$TMP/s.json"
expect_exit "simd-gather matches its golden file (within float rounding across ISAs)" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$G/simd-gather-cornell.pm" "$TMP/ind.pm"
missing=$(jq -r '[("shader_ops", "shader_ops_per_s", "queries", "photons_visited", "active_lanes", "packet_width",
    "radius_m") as $k | select(has($k) | not) | $k] | join(" ")' "$TMP/s.json")
[ $? = 0 ] && [ -z "$missing" ] && pass "stats report shader operations, their rate, queries, photons visited and active lanes" ||
    fail "stats keys" "missing '$missing': $(tr -d '\n' <"$TMP/s.json" | head -c 300)"
if grep -aq '^component=indirect$' "$TMP/ind.pm" && grep -aq '^radius=0.05$' "$TMP/ind.pm" &&
    [ "$(grep -ac '^INPUT=' "$TMP/ind.pm")" = 2 ]; then
    pass "the radiance header says indirect, the radius, and both inputs"
else
    fail "radiance header" "$(head -c 600 "$TMP/ind.pm")"
fi

# every ISA this CPU runs gives the same image within float rounding; threads change nothing
for isa in scalar sse4 avx2 avx512; do
    if "$SG" "$MAP" "$Q" --radius 0.05 -q --isa $isa -o "$TMP/ind-$isa.pm" 2>"$TMP/err"; then
        expect_exit "--isa $isa agrees with the default" 0 "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 \
            "$TMP/ind.pm" "$TMP/ind-$isa.pm"
    else
        grep -qE "cannot run|is not supported by this cpu" "$TMP/err" && pass "--isa $isa: not on this CPU, refused clearly" ||
            fail "--isa $isa" "$(cat "$TMP/err")"
    fi
done
"$SG" "$MAP" "$Q" --radius 0.05 -q --threads 1 -o "$TMP/ind1.pm"
expect_exit "1 and 2 threads give the same buffer" 0 "$BIN/pm-compare" "$TMP/ind.pm" "$TMP/ind1.pm"

# shards: two ranges add up to the whole
n=$(grep -a '^COUNT=' "$Q" | cut -d= -f2)
"$SG" "$MAP" "$Q" --radius 0.05 -q --range 0:700 -o "$TMP/a.pm"
"$SG" "$MAP" "$Q" --radius 0.05 -q --range 700: -o "$TMP/b.pm"
# Each shard is a whole image with zeros outside its range; a missing or short listing fails
# (every pixel of the 16 x 16 image must be seen).
paste <("$BIN/pm-info" -r "$TMP/a.pm" | awk '$1 ~ /^[0-9]+$/') <("$BIN/pm-info" -r "$TMP/b.pm" | awk '$1 ~ /^[0-9]+$/') \
    <("$BIN/pm-info" -r "$TMP/ind.pm" | awk '$1 ~ /^[0-9]+$/') |
    awk 'NF == 12 { n++; for (k = 2; k <= 4; k++) { s = $k + $(k + 4); w = $(k + 8); d = s - w; if (d < 0) d = -d
           if (d > 1e-6 * (w < 0 ? -w : w) + 1e-15) bad++ } } END { exit bad > 0 || n != 256 }'
[ "${PIPESTATUS[1]}" = 0 ] && pass "--range 0:700 and 700: add up to the whole gather ($n queries)" ||
    fail "shards" "the two halves do not add up"
grep -aq '^range=700:1359$' "$TMP/b.pm" && pass "a shard records its range" || fail "range key" "$(grep -a range "$TMP/b.pm")"

# --k picks a radius; the same for a shard (sampled from the whole file)
"$SG" "$MAP" "$Q" --k 20 -q -o "$TMP/k.pm" --stats "$TMP/k.json"
"$SG" "$MAP" "$Q" --k 20 -q --range 100:200 -o "$TMP/k2.pm"
r1=$(grep -a '^radius=' "$TMP/k.pm"); r2=$(grep -a '^radius=' "$TMP/k2.pm")
[ -n "$r1" ] && [ "$r1" = "$r2" ] && pass "--k: every shard uses the radius of the whole file ($r1)" ||
    fail "--k shards" "$r1 vs $r2"
"$BIN/hilbert-sort" "$Q" -q -o "$TMP/qh.pm"
"$SG" "$MAP" "$TMP/qh.pm" --k 20 -q -o "$TMP/k3.pm"
r3=$(grep -a '^radius=' "$TMP/k3.pm")
[ "$r1" = "$r3" ] && pass "--k: the radius does not depend on the order of the queries" || fail "--k order" "$r1 vs $r3"
awk '/"shader_ops_per_query"/ { v = $2 + 0; exit !(v > 10 && v < 40) }' "$TMP/k.json" &&
    pass "--k 20 gives about 20 photons per query" || fail "--k 20" "$(grep shader_ops_per_query "$TMP/k.json")"

# kernels and variable widths
"$SG" "$MAP" "$Q" --radius 0.05 --kernel uniform -q -o "$TMP/u.pm"
expect_exit "--kernel uniform runs and writes a valid buffer" 0 "$BIN/pm-info" "$TMP/u.pm"
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" --width-k 16 -q -o "$TMP/wmap.pm"
"$SG" "$TMP/wmap.pm" "$Q" --widths variable -q -o "$TMP/v.pm" --stats "$TMP/v.json"
expect_exit "--widths variable on a map with widths" 0 "$BIN/pm-info" "$TMP/v.pm"
expect_error "--widths variable needs the width channel" "width channel" "$SG" "$MAP" "$Q" --widths variable -o "$TMP/x.pm"

# through pipes: trace-gather-points | hilbert-sort | simd-gather
"$BIN/trace-gather-points" scenes/cornell-box/scene.json --width 16 --height 16 --spp 8 --seed 1 --strata hit -q -o - \
    --direct "$TMP/d.pm" | "$BIN/hilbert-sort" - -q -o - | "$SG" "$MAP" - --radius 0.05 -q -o "$TMP/piped.pm"
expect_exit "trace-gather-points | hilbert-sort | simd-gather gives the same image" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$TMP/ind.pm" "$TMP/piped.pm"

# bad input
expect_error "queries without the weight contract key" "weight contract" \
    "$SG" "$MAP" "$G/queries-all.pm" --radius 0.05 -o "$TMP/x.pm"
"$BIN/trace-gather-points" tests/scenes/closed-box/scene.json --width 8 --height 8 --spp 4 -q -o "$TMP/other.pm" \
    --direct "$TMP/od.pm"
expect_error "queries of another scene" "is of scene 'cornell-box .*but queries .* are of scene 'closed-box" \
    "$SG" "$MAP" "$TMP/other.pm" --radius 0.05 -o "$TMP/x.pm"
expect_error "a photon map given as queries" "is a photon map, expected a queries" "$SG" "$MAP" "$MAP" -o "$TMP/x.pm"
expect_exit "--k with --range from stdin is a usage error" 2 sh -c "'$SG' '$MAP' - --k 10 --range 0:10 -o '$TMP/x.pm' <'$Q'"
[ -e "$TMP/x.pm" ] && fail "no output after an error" "$TMP/x.pm exists" || pass "no output after an error"

# Streaming: with the width given, the queries go through a chunk at a time (PM_GATHER_STREAM_ROWS,
# 131072); more than two chunks give the very bytes of the whole-file read (--range 0: reads it
# whole), a bad value past the first chunk is named by its record, and a checksum that fails at
# the end leaves no output although every chunk was gathered.
"$BUILD/tests/pm-testgen" queries 300000 "$TMP/sq.pm" --set weights=lambertian-brdf-folded &&
    "$BUILD/tests/pm-testgen" photonmap 20000 "$TMP/sm.pm" || fail "streaming inputs" "pm-testgen failed"
"$SG" "$TMP/sm.pm" - --radius 0.05 -q -o "$TMP/s1.pm" <"$TMP/sq.pm" &&
    "$SG" "$TMP/sm.pm" "$TMP/sq.pm" --radius 0.05 -q --range 0: -o "$TMP/s2.pm" &&
    n=$(grep -a '^COUNT=' "$TMP/s1.pm" | cut -d= -f2) &&
    cmp -s <(tail -c $((n * 24 + 8)) "$TMP/s1.pm" | head -c $((n * 24))) \
        <(tail -c $((n * 24 + 8)) "$TMP/s2.pm" | head -c $((n * 24))) &&
    "$BIN/pm-info" -r "$TMP/s1.pm" | awk '$1 ~ /^[0-9]+$/ && $2 > 0 { lit++ } END { exit lit < 1 }' &&
    pass "300000 streamed queries give the whole-file gather's records, bit for bit" ||
    fail "streaming" "the streamed gather differs from the whole-file one"
hdr=$(($(head -c 100000 "$TMP/sq.pm" | grep -a -b -m 1 -x '' | cut -d: -f1) + 1))
cp "$TMP/sq.pm" "$TMP/bad.pm"
printf '\000\000\300\177' | dd of="$TMP/bad.pm" bs=1 seek=$((hdr + 4 + 200000 * 40)) conv=notrunc status=none
expect_error "a NaN in record 200000 of a stream is named" "record 200000 channel 'position'\[0\] is nan" \
    sh -c "'$SG' '$TMP/sm.pm' - --radius 0.05 -q -o '$TMP/s3.pm' <'$TMP/bad.pm'"
cp "$TMP/sq.pm" "$TMP/bad.pm"
printf '\001' | dd of="$TMP/bad.pm" bs=1 seek=$((hdr + 4 + 250000 * 40 + 36)) conv=notrunc status=none
expect_error "a stream whose checksum fails at its end" "checksum mismatch" \
    sh -c "'$SG' '$TMP/sm.pm' - --radius 0.05 -q -o '$TMP/s3.pm' <'$TMP/bad.pm'"
[ -e "$TMP/s3.pm" ] && fail "no output from a bad stream" "$TMP/s3.pm exists" || pass "no output from a bad stream"
