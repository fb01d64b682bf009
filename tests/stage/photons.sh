# photons.sh: trace-photons and build-photonmap on golden files, closed scenes with known
# answers, degenerate and bad inputs.
# Golden files (regenerate only when a change is meant to alter them, and say why):
#   bin/trace-photons scenes/cornell-box/scene.json --photons 3000 --seed 7 -o tests/golden/trace-photons-cornell.pm
#   bin/build-photonmap tests/golden/trace-photons-cornell.pm -o tests/golden/build-photonmap-cornell.pm
# programs: build-photonmap simd-gather trace-photons
G=tests/golden
source tests/scenes/make-box.sh
PI4=12.566370614359172 # 4 pi: a point light of 1 W/sr per channel emits 4 pi W per channel

# ---- trace-photons ----
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons 3000 --seed 7 -q -o "$TMP/cb.pm"
# Embree's AVX2 and AVX-512 kernels round a hit differently, and a photon's later bounces carry
# the difference on: positions agree within 1e-5 relative or 4e-6 m (measured: 8.6e-7 m between
# the AVX-512 machine that made the golden file and an AVX2 one; the box is 0.56 m).
expect_exit "trace-photons matches its golden file on the Cornell box" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 4e-6 "$G/trace-photons-cornell.pm" "$TMP/cb.pm"
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons 3000 --seed 7 -q --threads 1 -o "$TMP/cb1.pm"
expect_exit "trace-photons: 1 and 2 threads give the same photons" 0 "$BIN/pm-compare" "$TMP/cb.pm" "$TMP/cb1.pm"
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons 3000 --seed 8 -q -o "$TMP/cb8.pm"
# pm-compare answers as cmp does: 1 for files that differ; any other failure (2, a crash) is
# no evidence that the photons differ
expect_exit "another seed gives other photons" 1 "$BIN/pm-compare" "$TMP/cb.pm" "$TMP/cb8.pm"
if grep -aq '^CHANNELS=position power normal depth$' "$TMP/cb.pm" && grep -aq '^emitted=3000$' "$TMP/cb.pm" &&
    grep -aq '^SCENE=cornell-box xxh3:' "$TMP/cb.pm"; then
    pass "an all-Lambertian scene's photons have no direction channel; header has emitted and SCENE"
else
    fail "photons header" "$(head -c 400 "$TMP/cb.pm")"
fi

# Closed box, albedo 0.5, one point light: first hits carry exactly the light's power
# (3 channels of 4 pi W), bounce d carries 0.5^d of it within Monte Carlo error.
make_box "$TMP/box" 0.5 '[{"position":[0.1,0.2,0.3],"intensity":[1,1,1]}]'
"$BIN/trace-photons" "$TMP/box/scene.json" --photons 20000 -q -o "$TMP/box.pm"
phi=$(awk -v a=$PI4 'BEGIN { printf "%.12g", 3 * a }')
if "$BIN/pm-info" -r "$TMP/box.pm" | awk -v n=20000 -v phi=$phi -v rho=0.5 -v dmax=6 -v exact0=1 \
    -f tests/scenes/energy.awk >"$TMP/energy.txt"; then
    pass "closed box, albedo 0.5: first hits carry the light's power, bounce d carries 0.5^d"
else
    fail "energy, albedo 0.5" "$(tr '\n' ';' <"$TMP/energy.txt")"
fi
# Albedo 0.99 with survival capped at 0.95: paths stay short, the estimate stays unbiased.
make_box "$TMP/box99" 0.99 '[{"position":[0.1,0.2,0.3],"intensity":[1,1,1]}]'
"$BIN/trace-photons" "$TMP/box99/scene.json" --photons 20000 --rr-max 0.95 -q -o "$TMP/box99.pm" --stats "$TMP/s99.json"
if "$BIN/pm-info" -r "$TMP/box99.pm" | awk -v n=20000 -v phi=$phi -v rho=0.99 -v dmax=40 -v exact0=1 \
    -f tests/scenes/energy.awk >"$TMP/energy.txt"; then
    pass "closed box, albedo 0.99: Russian roulette at 0.95 keeps bounce d at 0.99^d"
else
    fail "energy, albedo 0.99" "$(grep -v '^bounce [0-9]*: .*tolerance' "$TMP/energy.txt" | head -3; tail -n 3 "$TMP/energy.txt")"
fi
if grep -q '"capped": 0' "$TMP/s99.json" && grep -q '"escaped": 0' "$TMP/s99.json"; then
    pass "closed box: no photon escapes and no path reaches --max-bounces"
else
    fail "closed box counters" "$(tr -d '\n' <"$TMP/s99.json")"
fi
# Two lights of different colour: each channel's first hits add up to that channel's power.
make_box "$TMP/box2" 0.5 '[{"position":[0.5,0,0],"intensity":[3,0,0]},{"position":[-0.5,0,0],"intensity":[0,1,2]}]'
"$BIN/trace-photons" "$TMP/box2/scene.json" --photons 20000 -q -o "$TMP/box2.pm"
"$BIN/pm-info" -r "$TMP/box2.pm" | awk -v a=$PI4 '$1 ~ /^[0-9]+$/ && NF >= 11 && $NF == 0 { r += $5; g += $6; b += $7 }
    END { n = 20000; rel = 5 * sqrt(0.5 / n) + 1e-4  # binomial error of the light choice
          ok = (r + g + b - 6 * a) ^ 2 < (1e-5 * 6 * a) ^ 2
          ok = ok && (r / (3 * a) - 1) ^ 2 < rel ^ 2 && (g / a - 1) ^ 2 < rel ^ 2 && (b / (2 * a) - 1) ^ 2 < rel ^ 2
          printf "r %.5g g %.5g b %.5g\n", r / a, g / a, b / a; exit !ok }' >"$TMP/rgb.txt"
if [ "${PIPESTATUS[1]}" = 0 ]; then
    pass "two coloured lights: the total is exact, each channel within its sampling error"
else
    fail "two coloured lights" "$(cat "$TMP/rgb.txt") (in units of 4 pi W; want 3 1 2)"
fi
# An area light (0.25 m^2, Ke 1): emits pi Ke A per channel from its front face only.
make_box "$TMP/boxa" 0.5 area
"$BIN/trace-photons" "$TMP/boxa/scene.json" --photons 20000 -q -o "$TMP/boxa.pm"
phia=$(awk 'BEGIN { printf "%.12g", 3 * 3.141592653589793 * 0.25 }')
if "$BIN/pm-info" -r "$TMP/boxa.pm" | awk -v n=20000 -v phi=$phia -v rho=1 -v dmax=0 -v exact0=1 \
    -f tests/scenes/energy.awk >"$TMP/energy.txt"; then
    pass "area light: first hits carry pi Ke A"
else
    fail "area light energy" "$(cat "$TMP/energy.txt")"
fi
# The lamp faces down: no first-hit photon may land above it (on the ceiling).
if "$BIN/pm-info" -r "$TMP/boxa.pm" | awk '$1 ~ /^[0-9]+$/ && NF >= 11 && $NF == 0 && $3 > 0.98 { bad++ } END { exit bad > 0 }'; then
    pass "area lights emit from their front face only"
else
    fail "area light side" "first-hit photons above the lamp"
fi
# A glossy scene stores the direction channel.
make_box "$TMP/boxg" 0 '[{"position":[0.1,0.2,0.3],"intensity":[1,1,1]}]' 'Kd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\nNs 20'
"$BIN/trace-photons" "$TMP/boxg/scene.json" --photons 2000 -q -o "$TMP/boxg.pm"
if grep -aq '^CHANNELS=position power normal direction depth$' "$TMP/boxg.pm" && "$BIN/pm-info" "$TMP/boxg.pm" >/dev/null; then
    pass "a glossy scene's photons carry their direction"
else
    fail "glossy direction channel" "$(head -c 300 "$TMP/boxg.pm")"
fi
# Scaled by 1e-4 and 1e5: the same photons up to scale (ray offsets scale with the scene).
for s in 1e-4 1e5; do
    make_box "$TMP/box-$s" 0.5 "[{\"position\":[$(awk -v s=$s 'BEGIN { printf "%g,%g,%g", 0.1*s, 0.2*s, 0.3*s }')],\"intensity\":[1,1,1]}]"
    sed -i "s|\"file\": \"box.obj\"|\"file\": \"box.obj\", \"scale\": $s|" "$TMP/box-$s/scene.json"
    "$BIN/trace-photons" "$TMP/box-$s/scene.json" --photons 20000 -q -o "$TMP/box-$s.pm" --stats "$TMP/s.json"
    if grep -q '"escaped": 0' "$TMP/s.json" && "$BIN/pm-info" -r "$TMP/box-$s.pm" |
        awk -v n=20000 -v phi=$phi -v rho=0.5 -v dmax=4 -v exact0=1 -f tests/scenes/energy.awk >/dev/null; then
        pass "box scaled by $s: no photon leaks out, energy as at scale 1"
    else
        fail "box scaled by $s" "$(tr -d '\n' <"$TMP/s.json" | head -c 300)"
    fi
done

# bad input
expect_error "trace-photons: missing scene" "cannot open scene" "$BIN/trace-photons" /nonexistent.json -o "$TMP/x.pm"
make_box "$TMP/dark" 0.5 '[]'
expect_error "trace-photons: a scene without lights" "no light with positive power" \
    "$BIN/trace-photons" "$TMP/dark/scene.json" -o "$TMP/dark.pm"
[ -e "$TMP/dark.pm" ] && fail "no output after an error" "$TMP/dark.pm exists" || pass "no output after an error"
expect_exit "trace-photons: --photons -1 is a usage error" 2 "$BIN/trace-photons" --photons -1 "$TMP/box/scene.json"
make_box "$TMP/hot" 0.5 '[{"position":[0,0,0],"intensity":[1e30,1e30,1e30]}]'
"$BIN/trace-photons" "$TMP/hot/scene.json" --photons 20000 -q -o "$TMP/hot.pm"
if "$BIN/pm-info" -r "$TMP/hot.pm" | awk -v n=20000 -v phi=$(awk -v a=$PI4 'BEGIN { printf "%.12g", 3e30 * a }') \
    -v rho=0.5 -v dmax=3 -v exact0=1 -f tests/scenes/energy.awk >/dev/null; then
    pass "a 1e30 W/sr light keeps its energy"
else
    fail "bright light" "energy off"
fi
make_box "$TMP/faint" 0.5 '[{"position":[0,0,0],"intensity":[1e-20,1e-20,1e-20]}]'
"$BIN/trace-photons" "$TMP/faint/scene.json" --photons 20000 -q -o "$TMP/faint.pm"
if "$BIN/pm-info" -r "$TMP/faint.pm" | awk -v n=20000 -v phi=$(awk -v a=$PI4 'BEGIN { printf "%.12g", 3e-20 * a }') \
    -v rho=0.5 -v dmax=3 -v exact0=1 -f tests/scenes/energy.awk >/dev/null; then
    pass "a 1e-20 W/sr light keeps its energy"
else
    fail "faint light" "energy off"
fi

# ---- build-photonmap ----
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" -q -o "$TMP/map.pm"
expect_exit "build-photonmap matches its golden file" 0 "$BIN/pm-compare" "$G/build-photonmap-cornell.pm" "$TMP/map.pm"
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" -q --threads 1 -o "$TMP/map1.pm"
expect_exit "build-photonmap: 1 and 2 threads give the same map" 0 "$BIN/pm-compare" "$TMP/map.pm" "$TMP/map1.pm"
# Every photon exactly once: the map's (position, power, normal) multiset is the file's.
# (pm-info -r prints a photon as: index, 9 values, depth; a node as: index, split, child, 9 values)
"$BIN/pm-info" -r "$G/trace-photons-cornell.pm" |
    awk '$1 ~ /^[0-9]+$/ && NF == 11 { for (i = 2; i <= 10; i++) printf "%s ", $i; print "" }' | sort >"$TMP/a.txt"
"$BIN/pm-info" -r "$TMP/map.pm" |
    awk '$1 ~ /^[0-9]+$/ && NF == 12 { for (i = 4; i <= 12; i++) printf "%s ", $i; print "" }' | sort >"$TMP/b.txt"
if [ -s "$TMP/a.txt" ] && cmp -s "$TMP/a.txt" "$TMP/b.txt"; then
    pass "the map holds every photon exactly once"
else
    fail "photon multiset" "$(diff "$TMP/a.txt" "$TMP/b.txt" | head -3)"
fi
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" -q --map indirect -o "$TMP/ind.pm"
want=$("$BIN/pm-info" -r "$G/trace-photons-cornell.pm" | awk '$1 ~ /^[0-9]+$/ && NF >= 11 && $NF > 0' | wc -l)
if grep -aq "^COUNT=$want$" "$TMP/ind.pm" && grep -aq '^map=indirect$' "$TMP/ind.pm" && "$BIN/pm-info" "$TMP/ind.pm" >/dev/null; then
    pass "--map indirect keeps exactly the $want photons that bounced"
else
    fail "--map indirect" "$(grep -a '^COUNT' "$TMP/ind.pm") expected $want"
fi
# --indirect-only drops the first hits of the lights the gather points sample: a point light's
# all (tests/scenes/closed-box: no depth 0 left, every bounced photon kept), an area light's
# only those at least sqrt(A) from where they left it (the Cornell box: A = 0.0137 m^2 under the
# ceiling at y = 0.5488 m, so a first hit kept lies above y = 0.43 m; no wall is that near in
# front of the light, so none is kept, and the file holds fewer photons than the golden one)
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons 3000 --seed 7 --indirect-only -q -o "$TMP/io.pm"
"$BIN/trace-photons" tests/scenes/closed-box/scene.json --photons 3000 --indirect-only -q -o "$TMP/iob.pm"
"$BIN/trace-photons" tests/scenes/closed-box/scene.json --photons 3000 -q -o "$TMP/ob.pm"
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }
nb=$(records "$TMP/ob.pm" | awk '$NF > 0' | wc -l)
near=$(records "$TMP/io.pm" | awk '$NF == 0 { n++; if ($3 < 0.43) far++ } END { print n + 0, far + 0 }')
if [ "$(records "$TMP/io.pm" | wc -l)" -lt "$(records "$G/trace-photons-cornell.pm" | wc -l)" ] &&
    [ "${near#* }" = 0 ] && grep -aq '^indirect_only=1$' "$TMP/io.pm" &&
    [ "$(records "$TMP/iob.pm" | awk '$NF == 0' | wc -l)" = 0 ] && [ "$(records "$TMP/iob.pm" | wc -l)" = "$nb" ] &&
    [ "$nb" -gt 0 ]; then
    pass "--indirect-only: the area light's ${near% *} first hits near it stay, a point light's go ($nb bounced kept)"
else
    fail "--indirect-only" "area light: ${near% *} first hits kept, ${near#* } of them far; or the point light's stayed"
fi
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" -q --width-k 16 -o "$TMP/w.pm"
if grep -aq '^CHANNELS=node position power normal width$' "$TMP/w.pm" && grep -aq '^width_k=16$' "$TMP/w.pm" &&
    "$BIN/pm-info" "$TMP/w.pm" >/dev/null; then
    pass "--width-k adds the width channel"
else
    fail "--width-k" "$(head -c 300 "$TMP/w.pm")"
fi
grep -aq '^CHANNELS=node position power normal$' "$TMP/map.pm" && pass "no width channel unless asked" ||
    fail "no width channel unless asked" "$(grep -a CHANNELS "$TMP/map.pm")"
# the voxel-volume heuristic builds a valid map (unbalanced) that gathers the same image
"$BIN/build-photonmap" "$G/trace-photons-cornell.pm" -q --split vvh -o "$TMP/vvh.pm"
if "$BIN/pm-info" "$TMP/vvh.pm" >/dev/null && grep -aq '^split=vvh$' "$TMP/vvh.pm" && grep -aq '^vvh_radius=' "$TMP/vvh.pm"; then
    pass "--split vvh writes a valid map and says so"
else
    fail "--split vvh" "$(head -c 500 "$TMP/vvh.pm")"
fi
"$BIN/simd-gather" "$TMP/map.pm" "$G/gather-cornell-16x16-spp8.pm" --radius 0.05 -q -o "$TMP/g1.pm"
"$BIN/simd-gather" "$TMP/vvh.pm" "$G/gather-cornell-16x16-spp8.pm" --radius 0.05 -q -o "$TMP/g2.pm"
expect_exit "a vvh map gathers the same image as the median map" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 --ignore-keys x "$TMP/g1.pm" "$TMP/g2.pm"
# the glossy box's photons keep their direction in the map
"$BIN/build-photonmap" "$TMP/boxg.pm" -q -o "$TMP/mapg.pm"
grep -aq '^CHANNELS=node position power normal direction$' "$TMP/mapg.pm" && pass "a glossy scene's map keeps directions" ||
    fail "glossy map" "$(grep -a CHANNELS "$TMP/mapg.pm")"
# streams: photons through a pipe
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons 3000 --seed 7 -q -o - | "$BIN/build-photonmap" - -q -o "$TMP/pipe.pm"
"$BIN/build-photonmap" "$TMP/cb.pm" -q -o "$TMP/cbmap.pm" # this machine's photons, as the pipe's
expect_exit "trace-photons | build-photonmap - gives the same map" 0 "$BIN/pm-compare" "$TMP/cbmap.pm" "$TMP/pipe.pm"
# degenerate inputs through the stage: no photons, one photon
for n in 0 1 2; do
    "$BUILD/tests/pm-testgen" photons $n "$TMP/p$n.pm"
    "$BIN/build-photonmap" "$TMP/p$n.pm" -q -o "$TMP/m$n.pm"
    expect_exit "build-photonmap of $n photons is a valid map" 0 "$BIN/pm-info" "$TMP/m$n.pm"
done
# bad input
expect_error "build-photonmap: not a photons file" "is a queries, expected a photons file" \
    "$BIN/build-photonmap" "$G/queries-all.pm" -o "$TMP/bad.pm"
head -c 2000 "$G/trace-photons-cornell.pm" >"$TMP/short.pm"
expect_error "build-photonmap: truncated photons" "truncated photons file" "$BIN/build-photonmap" "$TMP/short.pm" -o "$TMP/bad.pm"
[ -e "$TMP/bad.pm" ] && fail "build-photonmap leaves no output after an error" "exists" ||
    pass "build-photonmap leaves no output after an error"
