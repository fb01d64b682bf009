# cli.sh: the command-line conventions every program shares.
for p in "$BIN"/*; do
    n=$(basename "$p")
    "$p" --help >"$TMP/help" 2>"$TMP/err"
    if [ $? = 0 ] && grep -q "^usage: $n" "$TMP/help" && grep -q -- "--threads N" "$TMP/help" && [ ! -s "$TMP/err" ]; then
        pass "$n --help prints usage with every option to stdout"
    else
        fail "$n --help" "$(head -c 200 "$TMP/err")"
    fi
    "$p" --version >"$TMP/v" 2>&1
    if [ $? = 0 ] && grep -qE "^$n \(pmtk\) [0-9]+\.[0-9]+\.[0-9]+$" "$TMP/v"; then pass "$n --version"; else fail "$n --version" "$(cat "$TMP/v")"; fi
    expect_exit "$n unknown option exits 2" 2 "$p" --no-such-option
    expect_exit "$n bad number exits 2" 2 "$p" --threads lots
    "$p" --threads 3 --seed 9 --print-settings >"$TMP/settings" 2>&1
    "$p" @"$TMP/settings" --print-settings >"$TMP/settings2" 2>&1
    expect_same "$n --print-settings reads back through @FILE" "$TMP/settings" "$TMP/settings2"
done

# -o: text-writing programs write there, atomically, and nothing on failure
"$BIN/pm-info" -o "$TMP/info.txt" tests/golden/photons-all.pm >"$TMP/stdout"
if [ -s "$TMP/info.txt" ] && [ ! -s "$TMP/stdout" ] && cmp -s "$TMP/info.txt" <("$BIN/pm-info" tests/golden/photons-all.pm); then
    pass "pm-info -o writes its output there, not to stdout"
else
    fail "pm-info -o" "output missing or also on stdout"
fi
expect_error "pm-info -o leaves nothing when the input is bad" "bad magic" "$BIN/pm-info" -o "$TMP/bad.txt" /etc/hostname
if [ ! -e "$TMP/bad.txt" ]; then pass "... no partial output file"; else fail "... no partial output file" "bad.txt exists"; fi
"$BUILD/tests/pm-testgen" radiance 1 "$TMP/r1.pm" && "$BUILD/tests/pm-testgen" radiance 1 "$TMP/r2.pm" --poison nudge
"$BIN/pm-compare" -o "$TMP/cmp.txt" "$TMP/r1.pm" "$TMP/r2.pm" 2>/dev/null
status=$?
if [ $status = 1 ] && grep -q "OUT OF TOLERANCE" "$TMP/cmp.txt"; then
    pass "pm-compare keeps its report when the files differ"
else
    fail "pm-compare -o report" "exit $status, report: $(cat "$TMP/cmp.txt" 2>&1)"
fi
expect_exit "scene-info --preview - is a usage error" 2 "$BIN/scene-info" --preview - scenes/cornell-box/scene.json

# a stage killed while its output is open leaves no temporary file behind
mkdir -p "$TMP/sig"
mkfifo "$TMP/sig/fifo"
exec 7<>"$TMP/sig/fifo" # opened read-write: neither end blocks, and pm-info waits for data
"$BIN/pm-info" -o "$TMP/sig/out.txt" - <&7 &
pid=$!
for i in $(seq 50); do ls -A "$TMP/sig" | grep -q '^\.out\.txt\.' && break; sleep 0.05; done
seen=$(ls -A "$TMP/sig" | grep -c '^\.out\.txt\.')
kill -TERM $pid
wait $pid 2>/dev/null
exec 7>&-
left=$(ls -A "$TMP/sig" | grep -c '^\.out\.txt\.')
if [ "$seen" = 1 ] && [ "$left" = 0 ] && [ ! -e "$TMP/sig/out.txt" ]; then
    pass "SIGTERM removes the temporary output"
else
    fail "SIGTERM removes the temporary output" "temporary seen $seen, left $left"
fi
