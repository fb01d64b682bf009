# baselines.sh: knn-gather and reverse-gather, the baselines of simd-gather, on the golden
# Cornell box inputs: reverse equals simd-gather (same radius, both kernels, and --k);
# knn-gather equals an O(n m) k-nearest-neighbour reference written here in awk; both are
# bit-identical over thread counts; bad inputs are refused with one line and no file.
# programs: knn-gather reverse-gather simd-gather trace-gather-points
G=tests/golden
MAP=$G/build-photonmap-cornell.pm
Q=$G/gather-cornell-16x16-spp8.pm
SG=$BIN/simd-gather
RG=$BIN/reverse-gather
KG=$BIN/knn-gather

# reverse-gather: the forward gather's image, photon by photon instead of query by query
for kernel in uniform epanechnikov; do
    "$SG" "$MAP" "$Q" --radius 0.05 --kernel $kernel -q -o "$TMP/s-$kernel.pm"
    "$RG" "$MAP" "$Q" --radius 0.05 --kernel $kernel -q -o "$TMP/r-$kernel.pm" --stats "$TMP/r-$kernel.json"
    expect_exit "reverse-gather equals simd-gather within float rounding (--kernel $kernel)" 0 \
        "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$TMP/s-$kernel.pm" "$TMP/r-$kernel.pm"
done
"$SG" "$MAP" "$Q" --radius 0.05 -q -o "$TMP/s.pm" --stats "$TMP/s.json"
so=$(grep -o '"shader_ops": *[0-9]*' "$TMP/s.json" | sed 's/.*: *//')
ro=$(grep -o '"shader_ops": *[0-9]*' "$TMP/r-epanechnikov.json" | sed 's/.*: *//')
[ -n "$so" ] && [ "$so" = "$ro" ] && pass "reverse-gather shades the same photon-query pairs ($ro)" ||
    fail "reverse shader ops" "simd-gather $so, reverse-gather $ro"
missing=
for key in build_s search_s shader_ops_per_s radius_m queries_visited; do
    grep -q "\"$key\"" "$TMP/r-epanechnikov.json" || missing+=" $key"
done
[ -z "$missing" ] && pass "reverse-gather's stats report the query tree's build time, the search time and shader ops/s" ||
    fail "reverse stats" "missing$missing: $(head -c 300 "$TMP/r-epanechnikov.json")"
"$SG" "$MAP" "$Q" --k 20 -q -o "$TMP/sk.pm"
"$RG" "$MAP" "$Q" --k 20 -q -o "$TMP/rk.pm"
r1=$(grep -a '^radius=' "$TMP/sk.pm"); r2=$(grep -a '^radius=' "$TMP/rk.pm")
[ -n "$r1" ] && [ "$r1" = "$r2" ] && pass "reverse-gather --k finds simd-gather's radius ($r2)" || fail "--k radius" "$r1 vs $r2"
expect_exit "and then the same image" 0 "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$TMP/sk.pm" "$TMP/rk.pm"
for t in 1 3; do
    "$RG" "$MAP" "$Q" --radius 0.05 -q --threads $t -o "$TMP/r$t.pm"
    expect_exit "reverse-gather: $t thread(s) give the same buffer as 2, bit for bit" 0 \
        "$BIN/pm-compare" "$TMP/r-epanechnikov.pm" "$TMP/r$t.pm"
done
"$RG" "$MAP" "$Q" --radius 0.05 -q --range 0:700 -o "$TMP/ra.pm"
"$SG" "$MAP" "$Q" --radius 0.05 -q --range 0:700 -o "$TMP/sa.pm"
expect_exit "reverse-gather --range 0:700 equals simd-gather's shard" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$TMP/sa.pm" "$TMP/ra.pm"

# knn-gather against a brute-force k-NN in awk (double), on the first 60 queries: every
# photon whose normal agrees, the K nearest, uniform kernel: sum of power / (pi r_K^2)
K=10
"$KG" "$MAP" "$Q" --k $K --range 0:60 -q -o "$TMP/k60.pm" --stats "$TMP/k.json"
"$BIN/pm-info" -r "$MAP" | awk '$1 ~ /^[0-9]+$/ { print "P", $4, $5, $6, $7, $8, $9, $10, $11, $12 }' >"$TMP/ref-in"
"$BIN/pm-info" -r "$Q" | awk '$1 ~ /^[0-9]+$/ && $1 < 60 { print "Q", $2, $3, $4, $5, $6, $7, $8, $9, $10, $11 }' >>"$TMP/ref-in"
"$BIN/pm-info" -r "$TMP/k60.pm" | awk '$1 ~ /^[0-9]+$/ { print "G", $1, $2, $3, $4 }' >>"$TMP/ref-in"
awk -v K=$K '
$1 == "P" { n++; for (a = 0; a < 9; a++) p[n, a] = $(a + 2); next }
$1 == "Q" {
    m = 0
    for (j = 1; j <= n; j++) {
        if ($5 * p[j, 6] + $6 * p[j, 7] + $7 * p[j, 8] < 0.5) continue
        d = ($2 - p[j, 0]) ^ 2 + ($3 - p[j, 1]) ^ 2 + ($4 - p[j, 2]) ^ 2
        # insertion into the sorted list of the K nearest
        if (m == K && d >= dd[m]) continue
        if (m < K) m++
        for (i = m; i > 1 && dd[i - 1] > d; i--) { dd[i] = dd[i - 1]; id[i] = id[i - 1] }
        dd[i] = d; id[i] = j
    }
    for (c = 0; c < 3; c++) {
        s = 0
        for (i = 1; i <= m; i++) s += p[id[i], 3 + c]
        want[$11, c] += s / (3.141592653589793 * dd[m]) * $(8 + c)
    }
    next
}
$1 == "G" { for (c = 0; c < 3; c++) { w = want[$2, c] + 0; d = $(3 + c) - w; if (d < 0) d = -d
            if (d > 1e-6 * (w < 0 ? -w : w) + 1e-15) { bad++; if (bad < 3) print "pixel", $2, c, $(3 + c), "want", w } }
            if (want[$2, 0] > 0) lit++ }
END { if (lit < 3) { print "too few pixels with queries:", lit; exit 1 } exit bad > 0 }' "$TMP/ref-in" >"$TMP/ref-out"
[ $? = 0 ] && pass "knn-gather --k $K equals a brute-force k-NN reference in awk (60 queries)" ||
    fail "knn-gather against brute force" "$(head -c 300 "$TMP/ref-out")"
"$KG" "$MAP" "$Q" --k 30 -q -o "$TMP/k.pm" --stats "$TMP/k.json"
awk '/"shader_ops_per_query"/ { exit !($2 + 0 == 30) }' "$TMP/k.json" && pass "knn-gather shades exactly k photons per query" ||
    fail "knn shader ops" "$(grep shader_ops "$TMP/k.json")"
grep -aq '^widths=knn$' "$TMP/k.pm" && grep -aq '^k=30$' "$TMP/k.pm" && grep -aq '^component=indirect$' "$TMP/k.pm" &&
    [ "$(grep -ac '^INPUT=' "$TMP/k.pm")" = 2 ] && pass "knn-gather's header says knn, k, indirect and both inputs" ||
    fail "knn header" "$(head -c 600 "$TMP/k.pm")"
for t in 1 3; do
    "$KG" "$MAP" "$Q" --k 30 -q --threads $t -o "$TMP/k$t.pm"
    expect_exit "knn-gather: $t thread(s) give the same buffer as 2, bit for bit" 0 "$BIN/pm-compare" "$TMP/k.pm" "$TMP/k$t.pm"
done
"$KG" "$MAP" "$Q" --k 30 --max-radius 0.03 -q -o "$TMP/km.pm" --stats "$TMP/km.json"
awk '/"short_queries"/ { exit !($2 + 0 > 0) }' "$TMP/km.json" && expect_exit "--max-radius: queries short of k use r = R" 0 \
    "$BIN/pm-info" "$TMP/km.pm" || fail "--max-radius" "$(grep short "$TMP/km.json")"
# the estimators agree on the whole: the image means within 15% at about the same photons per query
mean() { "$BIN/pm-info" -r "$1" | awk '$1 ~ /^[0-9]+$/ { s += $2 + $3 + $4 } END { printf "%.9g\n", s }'; }
ms=$(mean "$TMP/sk.pm") mk=$(mean "$TMP/k.pm")
awk -v a="$ms" -v b="$mk" 'BEGIN { exit !(a > 0 && b / a > 0.85 && b / a < 1.15) }' &&
    pass "knn-gather's image is simd-gather's on the whole (sums $mk and $ms)" || fail "knn against simd" "$mk vs $ms"

# bad input, for both
for prog in "$KG" "$RG"; do
    name=$(basename "$prog")
    expect_error "$name: queries without the weight contract key" "weight contract" \
        "$prog" "$MAP" "$G/queries-all.pm" -o "$TMP/x.pm"
    expect_error "$name: a photon map given as queries" "is a photon map, expected a queries" \
        "$prog" "$MAP" "$MAP" -o "$TMP/x.pm"
done
"$BIN/trace-gather-points" tests/scenes/closed-box/scene.json --width 8 --height 8 --spp 4 -q -o "$TMP/other.pm" \
    --direct "$TMP/od.pm"
expect_error "knn-gather: queries of another scene" "is of scene 'cornell-box .*but queries .* are of scene 'closed-box" \
    "$KG" "$MAP" "$TMP/other.pm" -o "$TMP/x.pm"
expect_error "reverse-gather: queries of another scene" "is of scene 'cornell-box .*but queries .* are of scene 'closed-box" \
    "$RG" "$MAP" "$TMP/other.pm" --radius 0.05 -o "$TMP/x.pm"
expect_exit "knn-gather --k 0 is a usage error" 2 "$KG" "$MAP" "$Q" --k 0 -o "$TMP/x.pm"
expect_exit "reverse-gather without --radius or --k is a usage error" 2 "$RG" "$MAP" "$Q" --k 0 -o "$TMP/x.pm"
[ -e "$TMP/x.pm" ] && fail "no output after an error" "$TMP/x.pm exists" || pass "no output after an error"
