# renderblock.sh: the scene's render block is honoured by every stage that has the matching
# option, and the option given on the command line wins (docs/scene-format.md, "render").
# The stages that read the scene take its values directly; simd-gather, knn-gather,
# reverse-gather and hilbert-sort read them from the queries header (render.k, render.radius,
# render.leaf), which trace-gather-points copies from the scene. One check per key, each with
# a value no default has.
# programs: build-photonmap hilbert-sort knn-gather trace-gather-points trace-photons trace-reference
CB=$PWD/scenes/cornell-box
# scene NAME JQ: the Cornell box with its render block edited by JQ, as $TMP/NAME.json
scene() { jq --arg d "$CB" ".meshes |= map(.file = (\$d + \"/\" + .file)) | $2" "$CB/scene.json" >"$TMP/$1.json"; }
stat() { jq -r ".$2" "$TMP/$1"; }
# check NAME GOT WANT
check() { [ "$2" = "$3" ] && pass "$1 ($2)" || fail "$1" "got '$2', expected '$3'"; }
payload() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }

scene rb '.render = {photons: 3000, spp: 8, primary: 3, light_samples: 2, k: 400, radius: 0, leaf: 4, seed: 7}'
scene rr '.render = {photons: 3000, spp: 8, k: 400, radius: 0.0625, leaf: 4, seed: 7}'
E=(--width 16 --height 16)

# photons: trace-photons
"$BIN/trace-photons" "$TMP/rb.json" -q -o "$TMP/p.pm" --stats "$TMP/p.json"
check "render.photons: trace-photons emits the scene's count" "$(stat p.json emitted)" 3000
"$BIN/trace-photons" "$TMP/rb.json" -q --photons 2000 -o "$TMP/p2.pm" --stats "$TMP/p2.json"
check "render.photons: --photons wins" "$(stat p2.json emitted)" 2000

# seed: trace-photons, trace-gather-points, trace-reference
"$BIN/trace-photons" "$TMP/rb.json" -q --seed 7 -o "$TMP/p7.pm"
"$BIN/trace-photons" "$TMP/rb.json" -q --seed 1 -o "$TMP/p1.pm"
if cmp -s <(payload "$TMP/p.pm") <(payload "$TMP/p7.pm") && ! cmp -s <(payload "$TMP/p.pm") <(payload "$TMP/p1.pm"); then
    pass "render.seed: trace-photons uses the scene's seed, and --seed wins"
else
    fail "render.seed: trace-photons" "the photons without --seed are not those of --seed 7, or --seed 1 changes nothing"
fi
"$BIN/trace-gather-points" "$TMP/rb.json" -q "${E[@]}" -o "$TMP/q.pm" --direct "$TMP/d.pm" --stats "$TMP/q.json"
check "render.seed: trace-gather-points" "$(stat q.json seed)" 7
"$BIN/trace-gather-points" "$TMP/rb.json" -q "${E[@]}" --seed 3 -o "$TMP/q3.pm" --stats "$TMP/q3.json"
check "render.seed: --seed wins in trace-gather-points" "$(stat q3.json seed)" 3
"$BIN/trace-reference" "$TMP/rb.json" -q "${E[@]}" --spp 1 --radiance "$TMP/r.pm" -o "$TMP/r.exr"
"$BIN/trace-reference" "$TMP/rb.json" -q "${E[@]}" --spp 1 --seed 2 --radiance "$TMP/r2.pm" -o "$TMP/r2.exr"
check "render.seed: trace-reference, and --seed wins" "$(grep -a '^seed=' "$TMP/r.pm") $(grep -a '^seed=' "$TMP/r2.pm")" "seed=7 seed=2"

# spp, primary, light_samples: trace-gather-points
check "render.spp, render.primary, render.light_samples: trace-gather-points" \
    "$(jq -r '"\(.spp) \(.primary) \(.light_samples)"' "$TMP/q.json")" "8 3 2"
"$BIN/trace-gather-points" "$TMP/rb.json" -q "${E[@]}" --spp 4 --primary 2 --light-samples 1 -o "$TMP/qo.pm" --stats "$TMP/qo.json"
check "--spp, --primary and --light-samples win" "$(jq -r '"\(.spp) \(.primary) \(.light_samples)"' "$TMP/qo.json")" "4 2 1"
check "the queries header carries render.k, render.radius and render.leaf" \
    "$(grep -a '^render\.' "$TMP/q.pm" | tr '\n' ' ')" "render.k=400 render.radius=0 render.leaf=4 "

# leaf: hilbert-sort, from the queries header
"$BIN/hilbert-sort" "$TMP/q.pm" -q -o "$TMP/s.pm" --stats "$TMP/s.json"
check "render.leaf: hilbert-sort" "$(jq -r '"\(.leaf) \(.leaf_from)"' "$TMP/s.json")" "4 render.leaf"
"$BIN/hilbert-sort" "$TMP/q.pm" -q --leaf 16 -o "$TMP/s16.pm" --stats "$TMP/s16.json"
check "--leaf wins" "$(jq -r '"\(.leaf) \(.leaf_from)"' "$TMP/s16.json")" "16 --leaf"
"$BIN/hilbert-sort" - -q -o - <"$TMP/q.pm" | grep -aq '^render.k=400$' && pass "hilbert-sort passes the render keys on" ||
    fail "hilbert-sort keys" "render.k is not in its output"

# k and radius: the three gathers, from the (sorted) queries header
"$BIN/build-photonmap" "$TMP/p.pm" -q -o "$TMP/map.pm"
for g in simd-gather reverse-gather; do
    "$BIN/$g" "$TMP/map.pm" "$TMP/s.pm" -q -o "$TMP/g.pm" --stats "$TMP/g.json"
    "$BIN/$g" "$TMP/map.pm" "$TMP/s.pm" -q --k 50 -o "$TMP/g50.pm" --stats "$TMP/g50.json"
    check "render.k: $g" "$(jq -r '"\(.k) \(.radius_from)"' "$TMP/g.json")" "400 render.k"
    check "--k wins in $g" "$(jq -r '"\(.k) \(.radius_from)"' "$TMP/g50.json")" "50 --k"
    awk -v a="$(stat g.json radius_m)" -v b="$(stat g50.json radius_m)" 'BEGIN { exit !(a > 2 * b) }' &&
        pass "$g: K 400 gives a wider kernel than K 50 ($(stat g.json radius_m) m against $(stat g50.json radius_m) m)" ||
        fail "$g: K 400 kernel" "$(stat g.json radius_m) m against $(stat g50.json radius_m) m at K 50"
done
"$BIN/knn-gather" "$TMP/map.pm" "$TMP/s.pm" -q -o "$TMP/g.pm" --stats "$TMP/g.json"
check "render.k: knn-gather" "$(jq -r '"\(.k) \(.k_from)"' "$TMP/g.json")" "400 render.k"
"$BIN/knn-gather" "$TMP/map.pm" "$TMP/s.pm" -q --k 20 -o "$TMP/g.pm" --stats "$TMP/g.json"
check "--k wins in knn-gather" "$(jq -r '"\(.k) \(.k_from)"' "$TMP/g.json")" "20 --k"

# (the scene's hash covers its render block: the map is of the same scene as the queries)
"$BIN/trace-photons" "$TMP/rr.json" -q -o - | "$BIN/build-photonmap" - -q -o "$TMP/map.pm"
"$BIN/trace-gather-points" "$TMP/rr.json" -q "${E[@]}" -o - | "$BIN/hilbert-sort" - -q -o "$TMP/sr.pm"
for g in simd-gather reverse-gather; do
    "$BIN/$g" "$TMP/map.pm" "$TMP/sr.pm" -q -o "$TMP/g.pm" --stats "$TMP/g.json"
    check "render.radius: $g" "$(jq -r '"\(.radius_m) \(.radius_from)"' "$TMP/g.json") $(grep -a '^radius=' "$TMP/g.pm")" \
        "0.0625 render.radius radius=0.0625"
    "$BIN/$g" "$TMP/map.pm" "$TMP/sr.pm" -q --radius 0.03 -o "$TMP/g.pm" --stats "$TMP/g.json"
    check "--radius wins in $g" "$(jq -r '"\(.radius_m) \(.radius_from)"' "$TMP/g.json")" "0.03 --radius"
    "$BIN/$g" "$TMP/map.pm" "$TMP/sr.pm" -q --k 50 -o "$TMP/g.pm" --stats "$TMP/g.json"
    check "--k wins over render.radius in $g" "$(jq -r '"\(.k) \(.radius_from)"' "$TMP/g.json")" "50 --k"
done

# A file without the keys (an older trace-gather-points, pm-testgen) keeps the options' defaults.
"$BIN/hilbert-sort" tests/golden/hilbert-input.pm -q -o "$TMP/h.pm" --stats "$TMP/h.json"
check "queries without render keys: hilbert-sort's own default leaf" "$(jq -r '"\(.leaf) \(.leaf_from)"' "$TMP/h.json")" "16 default"

# The loader checks the keys it reads.
scene bad '.render.primary = 0'
expect_error "render.primary 0 is refused by the loader" "render.primary" "$BIN/trace-gather-points" "$TMP/bad.json" -o "$TMP/x.pm"
scene bad '.render.light_samples = -1'
expect_error "render.light_samples -1 is refused by the loader" "render.light_samples" "$BIN/trace-gather-points" "$TMP/bad.json" -o "$TMP/x.pm"
