# compare.sh: pm-compare agrees with itself, sees differences, honours tolerances and
# ignores only the volatile header keys.
# programs: pm-compare pm-info
G=tests/golden
TG=$BUILD/tests/pm-testgen
expect_exit "identical files agree" 0 "$BIN/pm-compare" "$G/photons-all.pm" "$G/photons-all.pm"
expect_error "different channels differ" "channel mask 0x0000001f, .* has 0x00000017" \
    "$BIN/pm-compare" "$G/photons-all.pm" "$G/photons-required.pm"
expect_error "different formats differ" "is a photons file but .* is a queries" \
    "$BIN/pm-compare" "$G/photons-all.pm" "$G/queries-all.pm"
# a version-1 file (CHANNEL_MASK beside CHANNELS) and a version-2 one of the same content
for f in photons photonmap queries radiance; do
    expect_exit "version-1 and version-2 $f files agree" 0 "$BIN/pm-compare" "$G/v1/$f-all.pm" "$G/$f-all.pm"
    expect_exit "... in either order" 0 "$BIN/pm-compare" "$G/$f-all.pm" "$G/v1/$f-all.pm"
done
expect_error "a version-1 file with other channels differs" "channel mask 0x0000001f, .* has 0x00000017" \
    "$BIN/pm-compare" "$G/v1/photons-all.pm" "$G/photons-required.pm"
# the same content made by another command line: volatile keys are ignored
"$TG" photons 7 "$TMP/again.pm" --all
expect_exit "a regenerated file agrees" 0 "$BIN/pm-compare" "$G/photons-all.pm" "$TMP/again.pm"
"$TG" photons 7 "$TMP/key.pm" --all --set emitted=15
expect_error "a changed header key is reported" "header key emitted differs: '14' in .*, '15' in" \
    "$BIN/pm-compare" "$G/photons-all.pm" "$TMP/key.pm"
expect_exit "... unless --ignore-keys names it" 0 "$BIN/pm-compare" --ignore-keys SCENE,emitted "$G/photons-all.pm" "$TMP/key.pm"
"$TG" photons 7 "$TMP/extra.pm" --all --set note=extra
expect_error "a key only one file has is reported" "header key note of .* is missing from" \
    "$BIN/pm-compare" "$TMP/extra.pm" "$G/photons-all.pm"
# numeric tolerance: the radiance golden file against one whose values moved by 1e-9
"$TG" radiance 1 "$TMP/r.pm"
"$BIN/pm-info" -r "$TMP/r.pm" >/dev/null
expect_exit "a file agrees with itself at zero tolerance" 0 "$BIN/pm-compare" "$TMP/r.pm" "$G/radiance-required.pm"
"$TG" radiance 1 "$TMP/r2.pm" --poison nudge
expect_error "a nudged value is out of zero tolerance" "differ in channel 'rgb': 1 values out of tolerance" \
    "$BIN/pm-compare" "$TMP/r.pm" "$TMP/r2.pm"
expect_exit "... and within --max-abs 1e-6" 0 "$BIN/pm-compare" --max-abs 1e-6 "$TMP/r.pm" "$TMP/r2.pm"
expect_exit "... and within --max-rel 1e-3" 0 "$BIN/pm-compare" --max-rel 1e-3 "$TMP/r.pm" "$TMP/r2.pm"
expect_error "... but not within --rms 1e-12" "rms" "$BIN/pm-compare" --max-abs 1 --rms 1e-12 "$TMP/r.pm" "$TMP/r2.pm"
expect_exit "pm-compare needs two files" 2 "$BIN/pm-compare" "$G/photons-all.pm"
