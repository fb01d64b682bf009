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
