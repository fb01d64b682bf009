# portals.sh: portals for the sun and the sky (docs/scene-format.md, Portals; render/light.c,
# env_emit) on scenes/skylight, a closed room lit through a 1 m opening in its ceiling, with and
# without its portal over the opening:
#   - the same light inside: the photon map seen directly (pm-render MODE=direct-vis, one kernel
#     radius for both) at 64 x 48 gives the same mean within 6% (measured 0.1% and 2% over two
#     seeds; a flux off by a factor of two fails) and a relative MSE of one against the other
#     below 0.1 (measured 0.02), with a constant sky and with a sky map (the Preetham model);
#   - the photons' power: trace-photons' emitted power is the power through the portals that
#     scene-info reports (within 2%; a map's is summed over its pixels);
#   - far more photons inside: 200,000 photon paths store over 30 times as many photons inside
#     the room with the portal (measured some 110 times);
#   - scene-info lists the portal; it changes the photons hash and not the view hash;
#   - deterministic for any thread count; bad portals are a one-line error naming the key, exit 1.
# programs: trace-photons scene-info pm-render measure-error pm-compare pm-info
SKY=scenes/skylight/scene.json
jq 'del(.portals)' "$SKY" >"$TMP/without.json"
cp "$SKY" "$TMP/with.json"
jq '.sky = {"model": "preetham", "turbidity": 3}' "$SKY" >"$TMP/mwith.json"
jq 'del(.portals)' "$TMP/mwith.json" >"$TMP/mwithout.json"

# ---- scene-info and the hash

if "$BIN/scene-info" "$TMP/with.json" >"$TMP/wi.txt" && "$BIN/scene-info" "$TMP/without.json" >"$TMP/wo.txt"; then
    if grep -q '^portals: 1, 1 m^2 in all' "$TMP/wi.txt" && grep -q 'portal 0 at -0.5 3.3 -0.5 edges 1 0 0 and 0 0 1 inward 0 -1 0' "$TMP/wi.txt"; then
        pass "scene-info lists the portal"
    else
        fail "scene-info lists the portal" "$(grep -i portal "$TMP/wi.txt" | tr '\n' ' ')"
    fi
    hw=$(sed -n 's/^scene: //p' "$TMP/wi.txt") ho=$(sed -n 's/^scene: //p' "$TMP/wo.txt")
    if [ "${hw#* }" != "${ho#* }" ] && [ "${hw##* }" = "${ho##* }" ]; then
        pass "the portal changes the photons hash, not the view hash"
    else
        fail "the portal changes the photons hash, not the view hash" "with '$hw', without '$ho'"
    fi
else
    fail "scene-info with and without portals" "$(head -c 300 "$TMP/err" 2>/dev/null)"
fi
"$BIN/scene-info" --json "$TMP/with.json" >"$TMP/wi.json" 2>/dev/null
if [ "$(jq '.portals[0].area_m2' "$TMP/wi.json" 2>/dev/null)" = 1 ]; then pass "scene-info --json: the portal's area"; else
    fail "scene-info --json: the portal's area" "$(jq -c '.portals' "$TMP/wi.json" 2>&1 | head -c 200)"
fi

# ---- photons inside, the power, determinism

# inside PHOTONS: photons stored inside the room (x, z in [-3, 3], y in [0, 3]).
inside() {
    "$BIN/pm-info" -r "$1" | awk '/^[0-9]/ && $2 >= -3.001 && $2 <= 3.001 && $4 >= -3.001 && $4 <= 3.001 &&
        $3 >= -0.001 && $3 <= 3.001 { n++ } END { print n + 0 }'
}
if "$BIN/trace-photons" "$TMP/with.json" -n 200000 -q --threads 1 --stats "$TMP/pw.json" -o "$TMP/pw.pm" &&
    "$BIN/trace-photons" "$TMP/with.json" -n 200000 -q --threads 2 -o "$TMP/pw2.pm" &&
    "$BIN/trace-photons" "$TMP/without.json" -n 200000 -q -o "$TMP/po.pm"; then
    expect_exit "portal photons: the same for 1 and 2 threads" 0 "$BIN/pm-compare" "$TMP/pw.pm" "$TMP/pw2.pm"
    a=$(inside "$TMP/pw.pm") b=$(inside "$TMP/po.pm")
    if [ "$a" -gt $((30 * b)) ]; then pass "photons inside: $a with the portal, $b without"; else
        fail "photons inside: over 30 times as many with the portal" "$a with, $b without"
    fi
else
    fail "trace-photons with and without the portal" "a stage failed"
fi

# power SCENE-INFO STATS: trace-photons' emitted power against scene-info's through the portals.
power() {
    local want got
    want=$(sed -n 's/.*power through them: sun \([0-9.e+]*\) W, sky \([0-9.e+]*\) W.*/\1 \2/p' "$1" |
        awk '{ print $1 + $2 }')
    got=$(jq '.power_emitted_w' "$2")
    awk -v a="$got" -v b="$want" 'BEGIN { exit !(b > 0 && a / b > 0.98 && a / b < 1.02) }' &&
        echo "$got W emitted, $want W through the portal"
}
if why=$(power "$TMP/wi.txt" "$TMP/pw.json"); then pass "constant sky: $why"; else
    fail "constant sky: the emitted power is the power through the portal" "$(jq -c . "$TMP/pw.json" | head -c 300)"
fi
if "$BIN/scene-info" "$TMP/mwith.json" >"$TMP/mwi.txt" &&
    "$BIN/trace-photons" "$TMP/mwith.json" -n 200000 -q --stats "$TMP/mpw.json" -o "$TMP/mpw.pm" &&
    why=$(power "$TMP/mwi.txt" "$TMP/mpw.json"); then
    pass "sky map: $why"
else
    fail "sky map: the emitted power is the power through the portal" "$(grep portals "$TMP/mwi.txt")"
fi

# ---- the same light inside

# agree NAME WITH WITHOUT: the photon map seen directly, 200,000 photon paths through the portal
# against 2,000,000 without it (some 45,000 of which land inside), one radius.
agree() {
    local name=$1 with=$2 without=$3 m
    if "$BIN/pm-render" "$with" "$TMP/$name-w" WIDTH=64 HEIGHT=48 MODE=direct-vis RADIUS=0.25 PHOTONS=200000 \
        QUIET=1 >/dev/null 2>"$TMP/err" &&
        "$BIN/pm-render" "$without" "$TMP/$name-o" WIDTH=64 HEIGHT=48 MODE=direct-vis RADIUS=0.25 \
            PHOTONS=2000000 QUIET=1 >/dev/null 2>"$TMP/err" &&
        "$BIN/measure-error" "$TMP/$name-w/indirect.pm" "$TMP/$name-o/indirect.pm" >"$TMP/$name.json"; then
        m=$(jq -r '"\(.mean_test) \(.mean_reference) \(.relmse)"' "$TMP/$name.json")
        if echo "$m" | awk '{ exit !($2 > 0 && $1 / $2 > 0.94 && $1 / $2 < 1.06 && $3 < 0.1) }'; then
            pass "$name: the light inside, mean with and without the portal and relMSE: $m"
        else
            fail "$name: the same light inside with the portal" "mean with, without, relMSE: $m"
        fi
    else
        fail "$name: pm-render with and without the portal" "$(head -c 300 "$TMP/err")"
    fi
}
agree "constant sky" "$TMP/with.json" "$TMP/without.json"
agree "sky map" "$TMP/mwith.json" "$TMP/mwithout.json"

# ---- bad portals

# bad NAME PATTERN JQ-FILTER: the skylight scene changed by JQ-FILTER is refused.
bad() {
    jq "$3" "$SKY" >"$TMP/bad.json"
    expect_error "portals refused: $1" "$2" "$BIN/trace-photons" "$TMP/bad.json" -n 1000 -q -o "$TMP/bad.pm"
}
bad "not an array" "portals: must be an array" '.portals = {}'
bad "empty" "portals: holds 0 rectangles, not 1 to 64" '.portals = []'
bad "too many" "portals: holds 65 rectangles" '.portals = [range(65) | {}]'
bad "a number" "portals\[0\]: must be an object" '.portals = [5]'
bad "zero width" "portals\[0\]\.size: element 0 = 0 is outside" '.portals[0].size = [0, 1]'
bad "one size" "portals\[0\]\.size: must be an array of 2 numbers" '.portals[0].size = [1]'
bad "an unknown key" "portals\[0\]: unknown key 'normal'" '.portals[0].normal = [0, -1, 0]'
bad "zero area" "portals\[0\]: has area 1e-60 m\^2 once placed" '.portals[0].scale = 1e-30'
bad "a singular matrix" "portals\[0\]\.matrix: is singular" \
    '.portals[0].matrix = [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]'
bad "no sun and no sky" "portals: let the sun and the sky in, and the scene has neither" \
    'del(.sun, .sky) | .point_lights = [{"position": [0, 2, 0], "intensity": [1, 1, 1]}]'
