# cli.sh: the command-line conventions every program shares.
# programs: all
for p in "$BIN"/*; do
    n=$(basename "$p")
    [ "$n" = pmtk ] && continue # the command that runs the others: tests/stage/pmtk.sh
    "$p" --help >"$TMP/help" 2>"$TMP/err"
    if [ $? = 0 ] && grep -q "^usage: $n" "$TMP/help" && grep -q -- "--threads N" "$TMP/help" && [ ! -s "$TMP/err" ]; then
        pass "$n --help prints usage with every option to stdout"
    else
        fail "$n --help" "$(head -c 200 "$TMP/err")"
    fi
    "$p" --version >"$TMP/v" 2>&1
    if [ $? = 0 ] && grep -qE "^$n \(pmtk\) [0-9]+\.[0-9]+\.[0-9]+$" "$TMP/v"; then pass "$n --version"; else fail "$n --version" "$(cat "$TMP/v")"; fi
    expect_exit "$n unknown option exits 2" 2 "$p" --no-such-option
    if [ "$(sed -n 1p "$TMP/err")" = "$n: unknown option '--no-such-option' (usage error)" ] &&
        grep -q "^usage: $n " <(sed -n 2p "$TMP/err") && [ "$(wc -l <"$TMP/err")" = 2 ]; then
        pass "$n: a usage error says its class, then the usage line"
    else
        fail "$n usage error message" "$(head -c 300 "$TMP/err")"
    fi
    expect_exit "$n bad number exits 2" 2 "$p" --threads lots
    # Both runs must succeed (exit 0, nothing on stderr) and print the same settings: two
    # identical error messages are no round trip.
    "$p" --threads 3 --seed 9 --print-settings >"$TMP/settings" 2>"$TMP/serr"
    s1=$?
    "$p" @"$TMP/settings" --print-settings >"$TMP/settings2" 2>>"$TMP/serr"
    s2=$?
    if [ $s1 = 0 ] && [ $s2 = 0 ] && [ ! -s "$TMP/serr" ] && grep -q 'threads' "$TMP/settings" &&
        cmp -s "$TMP/settings" "$TMP/settings2"; then
        pass "$n --print-settings reads back through @FILE"
    else
        fail "$n --print-settings @FILE round trip" "exits $s1, $s2: $(head -c 300 "$TMP/serr")"
    fi
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

# ---- error classes: the one line ends in "(CLASS error)" and --stats has error.class ----
# expect_class NAME CLASS STATUS CMD...: CMD (run with --stats) exits STATUS, its first stderr
# line ends in "(CLASS error)" and the stats file's error.class and error.message agree with it.
expect_class() {
    local name=$1 class=$2 status=$3
    shift 3
    rm -f "$TMP/class.json"
    "$@" --stats "$TMP/class.json" >"$TMP/out" 2>"$TMP/err"
    local got=$? line
    line=$(head -n 1 "$TMP/err")
    if [ "$got" != "$status" ]; then
        fail "$name" "exit $got, expected $status: $(head -c 300 "$TMP/err")"
    elif [[ "$line" != *" ($class error)" ]]; then
        fail "$name" "'$line' does not end in '($class error)'"
    elif [ ! -s "$TMP/class.json" ] || [ "$(jq -r .error.class "$TMP/class.json")" != "$class" ] ||
        [ "$(jq -r .stage "$TMP/class.json"): $(jq -r .error.message "$TMP/class.json") ($class error)" != "$line" ]; then
        fail "$name" "stats: $(head -c 400 "$TMP/class.json" 2>&1)"
    else
        pass "$name"
    fi
}
expect_class "usage: hilbert-sort --leaf x, in the message and in --stats" usage 2 \
    "$BIN/hilbert-sort" --leaf x tests/golden/hilbert-input.pm -o "$TMP/cls.pm"
expect_class "usage: a wrong argument count, in the message and in --stats" usage 2 \
    "$BIN/pm-compare" tests/golden/photons-all.pm
expect_class "input: pm-info on a file that is not pmtk's" input 1 "$BIN/pm-info" /etc/hostname
expect_class "input: pm-compare on a file that is not pmtk's is trouble, 2 (cmp's)" input 2 \
    "$BIN/pm-compare" "$TMP/r1.pm" /etc/hostname
if [ -w /dev/full ]; then
    expect_class "io: pm-info writing to a full disk (/dev/full), exit 3" io 3 \
        bash -c '"$0" "$@" >/dev/full' "$BIN/pm-info" tests/golden/photons-all.pm
else
    skip "io: pm-info writing to a full disk" "no writable /dev/full"
fi
"$BIN/pm-info" tests/golden/photons-all.pm --stats "$TMP/ok.json" >/dev/null
[ "$(jq 'has("error")' "$TMP/ok.json")" = false ] && pass "a successful run's stats have no error key" ||
    fail "no error key on success" "$(head -c 300 "$TMP/ok.json")"
"$BIN/pm-info" tests/golden/photons-all.pm --bogus --stats "$TMP/none.json" >/dev/null 2>&1
[ ! -e "$TMP/none.json" ] && pass "a command line that does not parse writes no stats" ||
    fail "no stats on a bad command line" "$(head -c 300 "$TMP/none.json")"

# nomem, from a worker thread: knn-gather allocates a heap of k photons on every thread inside
# its parallel region. The address-space limit (ulimit -v) is set to what a run with small
# heaps needs plus 12 MiB: room for one heap of 10^6 photons (7.6 MiB) but not for two, so that
# one of the two threads fails, the worker about half the time; its message must arrive whole
# every time. A program that cannot run under a limit at all (a sanitizer build) skips.
KNN_ARGS=(tests/golden/build-photonmap-cornell.pm tests/golden/gather-cornell-16x16-spp8.pm -q --threads 2 -o "$TMP/knn.pm")
# (the outer 2>/dev/null keeps bash's "Aborted" notice of a sanitizer build off the output)
knn_under() { { (ulimit -v "$1" && exec "$BIN/knn-gather" "${KNN_ARGS[@]}" --k "$2" "${@:3}") >/dev/null 2>&1; } 2>/dev/null; }
lo=0 hi=1048576 # KiB
if knn_under $hi 50; then
    while [ $((hi - lo)) -gt 256 ]; do
        mid=$(((lo + hi) / 2))
        if knn_under $mid 50; then hi=$mid; else lo=$mid; fi
    done
    bad=0 last=
    for i in $(seq 1 10); do
        (ulimit -v $((hi + 12288)) && exec "$BIN/knn-gather" "${KNN_ARGS[@]}" --k 1000000) >/dev/null 2>"$TMP/knn.err"
        st=$?
        if [ "$st" != 3 ] || ! grep -qx "knn-gather: out of memory for heaps of 1000000 photons (nomem error)" "$TMP/knn.err"; then
            bad=$((bad + 1)) last="exit $st: $(cat "$TMP/knn.err")"
        fi
    done
    [ "$bad" = 0 ] && pass "nomem: knn-gather's heap failing on a thread gives the whole message, 10 of 10 runs" ||
        fail "knn-gather heap out of memory" "$bad of 10 runs wrong (limit $((hi + 12288)) KiB); last: $last"
    ulimit_v=$((hi + 12288))
    expect_class "nomem: knn-gather under ulimit -v, in the message and in --stats, exit 3" nomem 3 \
        bash -c 'ulimit -v "$0" && exec "$@"' "$ulimit_v" "$BIN/knn-gather" "${KNN_ARGS[@]}" --k 1000000
else
    skip "nomem: knn-gather under ulimit -v" "knn-gather does not run under a 1 GiB address-space limit (sanitizer build?)"
fi
