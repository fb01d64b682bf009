# json.sh: pm-info --json and scene-info --json, the outputs the pipelines read with jq. Every
# value is checked against the text the same program prints for the same file or scene (whose
# bytes tests/golden/*.txt and scenes.sh pin down), so the two outputs cannot drift apart.
# programs: pm-info scene-info
command -v jq >/dev/null || { fail "json.sh needs jq" "jq is not installed (make deps)"; return; }
G=tests/golden
PI=$BIN/pm-info
SI=$BIN/scene-info

# ---- pm-info --json against pm-info's own header text, for every golden file ----
# The header lines rebuilt from the JSON, except BOUNDS (numbers, checked apart) and a version-1
# file's CHANNEL_MASK (the channel names say the same; --json gives only the names).
rebuild='"FORMAT=\(.format)", "VERSION=\(.version)", "BYTE_ORDER=\(.byte_order)", "COUNT=\(.count)",
    "RECORD_SIZE=\(.record_size)", "CHANNELS=\(.channels | join(" "))", "SOFTWARE=\(.software)",
    (.commands[] | "COMMAND=\(.)"), (.inputs[] | "INPUT=\(.path) \(.hash)"),
    (.keys | to_entries[] | "\(.key)=\(.value)")'
bad=
nfiles=0
for f in "$G"/*.pm; do
    nfiles=$((nfiles + 1))
    "$PI" --json "$f" >"$TMP/j.json" 2>"$TMP/err" && "$PI" "$f" >"$TMP/t.txt" 2>>"$TMP/err" ||
        { bad+=" $f: $(head -c 200 "$TMP/err")"; continue; }
    jq -e 'type == "object" and .checked == true and .file == $f' --arg f "$f" "$TMP/j.json" >/dev/null ||
        { bad+=" $f: not one checked object"; continue; }
    sed -n '2,/^$/p' "$TMP/t.txt" | grep -v -E '^(BOUNDS|CHANNEL_MASK)=|^$' | sort >"$TMP/want"
    jq -r "$rebuild" "$TMP/j.json" | sort >"$TMP/got"
    cmp -s "$TMP/want" "$TMP/got" || { bad+=" $f: header lines differ: $(diff "$TMP/want" "$TMP/got" | head -4 | tr '\n' ' ')"; continue; }
    # BOUNDS prints floats with %.9g, which reads back to the same float: equal as numbers.
    paste <(sed -n 's/^BOUNDS=//p' "$TMP/t.txt" | tr ' ' '\n') <(jq '.bounds[]' "$TMP/j.json") |
        awk 'NF == 2 && $1 + 0 == $2 + 0 { n++ } END { exit n != 6 }' || { bad+=" $f: bounds"; continue; }
    [ "# ok: $(jq -r '"\(.count) records, checksum \(.checksum)"' "$TMP/j.json")" = "$(tail -n 1 "$TMP/t.txt")" ] ||
        { bad+=" $f: checksum or count"; continue; }
done
[ -z "$bad" ] && [ "$nfiles" -ge 8 ] &&
    pass "pm-info --json holds every header line, the count and the checksum of the $nfiles golden files" ||
    fail "pm-info --json against its text" "$bad"

# Known values of one golden file, written out: a gather's radiance buffer with two inputs.
"$PI" --json "$G/simd-gather-cornell.pm" >"$TMP/sg.json"
jq -e '.format == "radiance" and .version == "2.0" and .count == 256 and .record_size == 24 and
    .channels == ["rgb"] and (has("channel_mask") | not) and (.commands | length) == 4 and
    ([.inputs[].path] == ["tests/golden/build-photonmap-cornell.pm", "tests/golden/gather-cornell-16x16-spp8.pm"]) and
    (.inputs[0].hash | test("^xxh3:[0-9a-f]{16}$")) and .keys.component == "indirect" and .keys.radius == "0.05" and
    (.keys.SCENE | startswith("cornell-box xxh3:")) and (.checksum | test("^xxh3:[0-9a-f]{16}$"))' "$TMP/sg.json" >/dev/null &&
    pass "pm-info --json of simd-gather-cornell.pm: radiance 2.0, 256 records of 24 bytes, rgb, 4 commands, 2 inputs" ||
    fail "pm-info --json values" "$(head -c 600 "$TMP/sg.json")"

"$PI" --json --header "$G/photonmap-all.pm" >"$TMP/h.json"
jq -e '.checked == false and (has("checksum") | not) and .count == 7 and
    .channels == ["node", "position", "power", "normal", "direction", "width"]' "$TMP/h.json" >/dev/null &&
    pass "pm-info --json --header: the header alone, marked unchecked, with no checksum" ||
    fail "pm-info --json --header" "$(head -c 400 "$TMP/h.json")"
"$PI" --json - <"$G/queries-all.pm" | jq -e '.file == "-" and .format == "queries" and .count == 7' >/dev/null &&
    pass "pm-info --json reads stdin" || fail "pm-info --json stdin" "wrong or no object"
n=$("$PI" --json "$G/photons-all.pm" "$G/radiance-all.pm" | jq -s 'map(.format) | join(" ")')
[ "$n" = '"photons radiance"' ] && pass "pm-info --json: one object per file, in order" || fail "pm-info --json two files" "$n"
expect_exit "pm-info --json with --records is a usage error" 2 "$PI" --json -r "$G/photons-all.pm"
head -c 300 "$G/photons-all.pm" >"$TMP/short.pm"
expect_error "pm-info --json of a truncated file fails" "pm-info: .*short.pm" "$PI" --json "$TMP/short.pm"
[ ! -s "$TMP/out" ] && pass "... and prints no partial JSON" || fail "pm-info --json partial output" "$(head -c 200 "$TMP/out")"
# JSON carries UTF-8 only: a header value in another encoding is an error that names its key.
# (--header: the checksum, which the edit breaks, is not read.)
LC_ALL=C sed 's/^SCENE=test /SCENE=t\xe9s /' "$G/photons-all.pm" >"$TMP/latin1.pm"
expect_error "pm-info --json: a header value that is not UTF-8 is named, not left out" \
    "cannot describe '.*latin1.pm' as JSON: SCENE is not UTF-8" "$PI" --json --header "$TMP/latin1.pm"

# ---- scene-info --json against scene-info's text, for every scene it can load here ----
scenes=(scenes/cornell-box/scene.json tests/scenes/glossy-box/scene.json tests/scenes/lit-floor/scene.json
    tests/scenes/closed-box/scene.json tests/scenes/open-floor/scene.json)
# The lines of the text whose every figure is a count, a name or a yes/no, rebuilt from the JSON.
rebuild='def yn: if . then "yes" else "no" end;
    "scene: \(.scene)", "file: \(.file)",
    "triangles: \(.triangles) (\(.degenerate_triangles) degenerate left out)", "vertices: \(.vertices)",
    "materials: \(.materials | length) \(if .glossy then "(some glossy)" else "(all Lambertian)" end)",
    "point lights: \(.point_lights)", "emissive triangles: \(.emissive_triangles)",
    "needs: direction channels \(.needs.direction_channels | yn), material ids \(.needs.material_ids | yn), area-light sampling \(.needs.area_light_sampling | yn)"'
bad=
for s in "${scenes[@]}"; do
    "$SI" -q --json "$s" >"$TMP/s.json" 2>"$TMP/err" && "$SI" -q "$s" >"$TMP/s.txt" 2>>"$TMP/err" ||
        { bad+=" $s: $(head -c 200 "$TMP/err")"; continue; }
    grep -E '^(scene|file|triangles|vertices|materials|point lights|emissive triangles|needs): ' "$TMP/s.txt" >"$TMP/want"
    jq -r "$rebuild" "$TMP/s.json" >"$TMP/got"
    cmp -s "$TMP/want" "$TMP/got" || { bad+=" $s: $(diff "$TMP/want" "$TMP/got" | head -4 | tr '\n' ' ')"; continue; }
    # Numbers the text rounds (%.4g materials, %.6g power and camera, %.9g bounds): equal to
    # the text's digits within that rounding.
    {
        grep -E '^  [0-9]+ ' "$TMP/s.txt" | awk '{ print $4, $5, $6, $8, $9, $10, $12, $14, $15, $16 }' | tr ' ' '\n' | sed 's/$/ 5e-4/'
        sed -n 's/^emitted power: \(.*\) W$/\1/p' "$TMP/s.txt" | tr ' ' '\n' | sed 's/$/ 5e-6/'
        sed -n 's/^bounds: \(.*\) m$/\1/p' "$TMP/s.txt" | tr -s ' ' '\n' | sed 's/$/ 5e-9/'
        sed -n 's/^camera: eye \(.*\) \(.*\) \(.*\) look_at \(.*\) \(.*\) \(.*\) fov_y \(.*\) deg .*/\1 \2 \3 \4 \5 \6 \7/p' \
            "$TMP/s.txt" | tr ' ' '\n' | sed 's/$/ 5e-6/'
    } >"$TMP/text-nums"
    jq -r '(.materials[] | .kd[], .ks[], .ns, .ke[]), .power_w[], .bounds_m[], .camera.eye[], .camera.look_at[],
        .camera.fov_y_deg' "$TMP/s.json" >"$TMP/json-nums"
    paste -d' ' "$TMP/text-nums" "$TMP/json-nums" | awk '
        { t = $1; r = $2; j = $3; d = t - j; if (d < 0) d = -d; a = j < 0 ? -j : j
          if (NF != 3 || d > r * a + 1e-30) { print "text " t " json " j; bad = 1 } }
        END { exit bad || NR == 0 }' >"$TMP/why" || { bad+=" $s numbers: $(head -2 "$TMP/why" | tr '\n' ' ')"; continue; }
    [ "$(wc -l <"$TMP/text-nums")" = "$(wc -l <"$TMP/json-nums")" ] || { bad+=" $s: number counts differ"; continue; }
    grep -q "^camera: .* $(jq -r '"\(.camera.width)x\(.camera.height)"' "$TMP/s.json")$" "$TMP/s.txt" ||
        { bad+=" $s: camera size"; continue; }
done
[ -z "$bad" ] && pass "scene-info --json holds the facts of its text for ${#scenes[@]} scenes" ||
    fail "scene-info --json against its text" "$bad"

# Known values of the Cornell box, written out.
"$SI" -q --json --probe --stats "$TMP/st.json" scenes/cornell-box/scene.json >"$TMP/cb.json"
jq -e '.name == "cornell-box" and (.scene | test("^cornell-box xxh3:[0-9a-f]{16} photons:xxh3:[0-9a-f]{16} view:xxh3:[0-9a-f]{16}$")) and (.hashes | keys) == ["all", "eye", "geometry", "photons", "view"] and .triangles == 32 and
    .vertices == 36 and .degenerate_triangles == 0 and .glossy == false and .point_lights == 0 and
    .emissive_triangles == 2 and (.materials | length) >= 2 and
    .needs == {"direction_channels": false, "material_ids": false, "area_light_sampling": true} and
    .camera.width == 256 and .camera.height == 256 and (.power_w | length) == 3 and (.power_w | min) > 0 and
    .bounds_m == [0, 0, 0, 0.555999994, 0.548799992, 0.559199989] and .ray_epsilon_m > 0 and
    .probe.rays == 65536 and .probe.hits > 0 and .probe.hits <= .probe.rays and
    (.probe.hit_fraction - .probe.hits / .probe.rays | fabs) < 1e-8' "$TMP/cb.json" >/dev/null &&
    pass "scene-info --json --probe of the Cornell box: 32 triangles, 2 emitters, its needs, 65536 probe rays" ||
    fail "scene-info --json values" "$(head -c 800 "$TMP/cb.json")"
jq -e '.stage == "scene-info" and .triangles == 32 and .probe_rays == 65536' "$TMP/st.json" >/dev/null &&
    pass "scene-info --json keeps --stats" || fail "scene-info --json --stats" "$(head -c 300 "$TMP/st.json")"
"$SI" -q --json tests/scenes/glossy-box/scene.json |
    jq -e '.glossy and .needs == {"direction_channels": true, "material_ids": true, "area_light_sampling": false} and
        .point_lights == 1 and (has("probe") | not)' >/dev/null &&
    pass "scene-info --json of a glossy scene with a point light: directions and material ids, no area lights" ||
    fail "scene-info --json glossy-box" "wrong needs"
cp -r tests/scenes/lit-floor "$TMP/latin1"
LC_ALL=C sed -i 's/mtl floor/mtl fl\xe9or/' "$TMP/latin1/floor.mtl" "$TMP/latin1/floor.obj"
expect_error "scene-info --json: a material name that is not UTF-8 is an error" \
    "cannot describe scene '.*' as JSON: a material's name is not UTF-8" "$SI" -q --json "$TMP/latin1/scene.json"
printf '{\n  "pmtk_scene": 1,\n  "name": "x"\n  "camera": {}\n}\n' >"$TMP/bad.json"
expect_error "scene-info --json of a bad scene fails with one line" "scene '.*bad.json' line 4" "$SI" --json "$TMP/bad.json"
[ ! -s "$TMP/out" ] && pass "... and prints no JSON" || fail "scene-info --json partial output" "$(head -c 200 "$TMP/out")"
