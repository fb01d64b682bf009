# hilbert-sort.sh: the output is a permutation of the input, in the golden order; --order none
# passes records through byte for byte; degenerate inputs end with a valid file; bad input
# gives one line, exit 1 and no output; pipes work; thread counts agree bit for bit.
# programs: hilbert-sort
G=tests/golden
TG=$BUILD/tests/pm-testgen
HS=$BIN/hilbert-sort

# payload FILE: the records (after the header and byte-order marker, before the checksum)
payload() {
    local blank hb
    blank=$(grep -a -n -m 1 '^$' "$1" | cut -d: -f1)
    hb=$(head -n "$blank" "$1" | wc -c)
    tail -c +$((hb + 5)) "$1" | head -c -8
}
# records FILE: the records as text without their index, one per line
records() { "$BIN/pm-info" -r "$1" | grep '^[0-9]' | cut -d' ' -f2-; }
# order IN OUT: for each record of OUT, the index of the record of IN with the same content
order() {
    awk 'NR == FNR { sub(/^[0-9]+ /, ""); idx[$0] = FNR - 1; next } { sub(/^[0-9]+ /, ""); printf "%s ", idx[$0] } END { print "" }' \
        <("$BIN/pm-info" -r "$1" | grep '^[0-9]') <("$BIN/pm-info" -r "$2" | grep '^[0-9]')
}

# ---- a permutation of the input, and a real reordering ----
"$TG" queries 3000 "$TMP/q.pm" --all
"$HS" "$TMP/q.pm" -o "$TMP/s.pm" 2>"$TMP/err"
if "$BIN/pm-info" "$TMP/s.pm" >/dev/null 2>&1 && cmp -s <(records "$TMP/q.pm" | sort) <(records "$TMP/s.pm" | sort); then
    pass "the output is a valid permutation of the input (same multiset of records)"
else
    fail "permutation" "sorted record dumps differ or the output is invalid: $(head -c 300 "$TMP/err")"
fi
if ! cmp -s <(records "$TMP/q.pm") <(records "$TMP/s.pm"); then pass "... and not the input order"; else fail "reordering" "output in input order"; fi
for o in morton hilbert; do
    for leaf in 1 7 16 5000; do
        "$HS" --order $o --leaf $leaf "$TMP/q.pm" -o "$TMP/p.pm" 2>/dev/null
        if cmp -s <(records "$TMP/q.pm" | sort) <(records "$TMP/p.pm" | sort); then
            pass "--order $o --leaf $leaf is a permutation"
        else
            fail "--order $o --leaf $leaf" "not a permutation of the input"
        fi
    done
done
# leaf >= COUNT: one leaf, input order kept
"$HS" --leaf 3000 "$TMP/q.pm" -o "$TMP/big.pm" 2>/dev/null
if cmp -s <(payload "$TMP/q.pm") <(payload "$TMP/big.pm"); then pass "--leaf COUNT keeps the input order"; else fail "--leaf COUNT" "order changed"; fi

# ---- provenance ----
hdr=$("$BIN/pm-info" --header "$TMP/s.pm")
sum=$("$BIN/pm-info" "$TMP/q.pm" | sed -n 's/^# ok: .*checksum \(xxh3:[0-9a-f]*\)$/\1/p')
if echo "$hdr" | grep -qx "INPUT=$TMP/q.pm $sum" && echo "$hdr" | grep -qx 'order=hilbert leaf=16' &&
    echo "$hdr" | grep -q '^COMMAND=pm-testgen queries --all$' && echo "$hdr" | grep -q '^COMMAND=.*hilbert-sort ' &&
    echo "$hdr" | grep -qx 'width=8' && echo "$hdr" | grep -q '^material.1=gloss'; then
    pass "the header inherits the input's, adds INPUT with its checksum, COMMAND and order=hilbert leaf=16"
else
    fail "header" "$hdr"
fi
"$HS" --order morton --leaf 4 "$TMP/s.pm" -o "$TMP/s2.pm"
if [ "$("$BIN/pm-info" --header "$TMP/s2.pm" | grep -c '^order=')" = 1 ] &&
    "$BIN/pm-info" --header "$TMP/s2.pm" | grep -qx 'order=morton leaf=4'; then
    pass "sorting a sorted file replaces its order key"
else
    fail "order key on re-sort" "$("$BIN/pm-info" --header "$TMP/s2.pm" | grep '^order=')"
fi

# ---- --order none: the records pass through unchanged ----
"$HS" --order none "$TMP/q.pm" -o "$TMP/none.pm"
if cmp -s <(payload "$TMP/q.pm") <(payload "$TMP/none.pm") && "$BIN/pm-info" --header "$TMP/none.pm" | grep -qx 'order=none'; then
    pass "--order none: records byte-identical, order=none in the header"
else
    fail "--order none" "records differ"
fi
"$TG" queries 50 "$TMP/req.pm"
"$HS" --order none "$TMP/req.pm" -o "$TMP/req-none.pm"
expect_same "--order none on required channels only (40-byte records)" <(payload "$TMP/req.pm") <(payload "$TMP/req-none.pm")

# ---- golden: a fixed input, its outputs and their order ----
for v in leaf1:--leaf=1 leaf4:--leaf=4 morton1:"--order=morton --leaf=1"; do
    name=${v%%:*}
    # shellcheck disable=SC2086
    "$HS" ${v#*:} "$G/hilbert-input.pm" -o "$TMP/g-$name.pm"
    expect_exit "golden $name matches tests/golden/hilbert-$name.pm" 0 "$BIN/pm-compare" "$G/hilbert-$name.pm" "$TMP/g-$name.pm"
    want=$(grep "^$name:" "$G/hilbert-order.txt" | cut -d: -f2)
    got=$(order "$G/hilbert-input.pm" "$TMP/g-$name.pm")
    if [ "$got" = "$want" ]; then pass "golden $name order matches hilbert-order.txt"; else fail "golden $name order" "got '$got', want '$want'"; fi
done

# ---- degenerate inputs: valid output, and a permutation ----
for shape in equal line plane huge; do
    "$TG" queries 400 "$TMP/d-$shape.pm" --all --shape $shape
    for leaf in 1 16; do
        if timeout 20 "$HS" --leaf $leaf "$TMP/d-$shape.pm" -o "$TMP/ds.pm" 2>"$TMP/err" && "$BIN/pm-info" "$TMP/ds.pm" >/dev/null &&
            cmp -s <(records "$TMP/d-$shape.pm" | sort) <(records "$TMP/ds.pm" | sort); then
            pass "points $shape (--leaf $leaf): valid output, a permutation"
        else
            fail "points $shape --leaf $leaf" "$(head -c 300 "$TMP/err")"
        fi
    done
done
"$HS" --leaf 1 --stats "$TMP/eq.json" "$TMP/d-equal.pm" -o "$TMP/ds.pm"
if cmp -s <(payload "$TMP/d-equal.pm") <(payload "$TMP/ds.pm") && grep -q '"octree_depth": 21' "$TMP/eq.json"; then
    pass "all points equal: input order kept, the octree stops at its last level (21)"
else
    fail "all points equal" "$(cat "$TMP/eq.json")"
fi
for n in 0 1; do
    "$TG" queries $n "$TMP/n$n.pm" --all
    if "$HS" --leaf 1 "$TMP/n$n.pm" -o "$TMP/ns.pm" && "$BIN/pm-info" "$TMP/ns.pm" | grep -q "^# ok: $n records"; then
        pass "$n points: a valid file of $n records"
    else
        fail "$n points" "no valid output"
    fi
done

# ---- bad input: one line, exit 1, no output file ----
size=$(stat -c %s "$TMP/q.pm")
head -c $((size - 100)) "$TMP/q.pm" >"$TMP/short.pm"
expect_error "truncated input" "^hilbert-sort: truncated queries 'short.pm'|^hilbert-sort: truncated queries '.*short.pm': ends in record" \
    "$HS" "$TMP/short.pm" -o "$TMP/bad-out.pm"
if [ ! -e "$TMP/bad-out.pm" ] && [ -z "$(ls -A "$TMP" | grep '^\.bad-out')" ]; then pass "... and no output file"; else fail "no output on bad input" "$(ls -A "$TMP")"; fi
expect_error "a photons file is refused" "^hilbert-sort: .*photons" "$HS" "$G/photons-all.pm" -o "$TMP/bad-out.pm"
expect_error "a missing input" "^hilbert-sort: cannot open '/nonexistent.pm'" "$HS" /nonexistent.pm -o "$TMP/bad-out.pm"
expect_error "truncated on a pipe" "^hilbert-sort: truncated queries 'stdin'" sh -c "cat '$TMP/short.pm' | '$HS' - -o '$TMP/bad-out.pm'"
if [ ! -e "$TMP/bad-out.pm" ]; then pass "... no output file after any of them"; else fail "no output on bad input" "bad-out.pm exists"; fi
expect_exit "--leaf 0 is bad usage" 2 "$HS" --leaf 0 "$TMP/q.pm" -o "$TMP/x.pm"
expect_exit "--leaf lots is bad usage" 2 "$HS" --leaf lots "$TMP/q.pm" -o "$TMP/x.pm"
expect_exit "--order random is bad usage" 2 "$HS" --order random "$TMP/q.pm" -o "$TMP/x.pm"
expect_exit "two inputs is bad usage" 2 "$HS" "$TMP/q.pm" "$TMP/q.pm" -o "$TMP/x.pm"

# ---- pipes, threads, stats ----
cat "$TMP/q.pm" | "$HS" - -o - 2>"$TMP/err" | "$BIN/pm-info" -r - >"$TMP/pipe.txt" 2>>"$TMP/err"
if cmp -s <(grep '^[0-9]' "$TMP/pipe.txt") <("$BIN/pm-info" -r "$TMP/s.pm" | grep '^[0-9]') &&
    grep -qx 'INPUT=stdin .*' "$TMP/pipe.txt"; then
    pass "stdin to stdout: the same records as file to file, INPUT=stdin"
else
    fail "pipe" "$(head -c 300 "$TMP/err")"
fi
"$TG" queries 200000 "$TMP/big-in.pm" --all
for o in hilbert morton; do
    "$HS" --order $o --threads 1 "$TMP/big-in.pm" -o "$TMP/t1.pm"
    "$HS" --order $o --threads 2 "$TMP/big-in.pm" -o "$TMP/t2.pm"
    "$HS" --order $o --threads 3 --leaf 1 "$TMP/big-in.pm" -o "$TMP/t3.pm"
    "$HS" --order $o --threads 1 --leaf 1 "$TMP/big-in.pm" -o "$TMP/t4.pm"
    if cmp -s <(payload "$TMP/t1.pm") <(payload "$TMP/t2.pm") && cmp -s <(payload "$TMP/t3.pm") <(payload "$TMP/t4.pm"); then
        pass "--order $o: records bit-identical for --threads 1, 2 and 3"
    else
        fail "--order $o threads" "records differ between thread counts"
    fi
done
"$HS" --leaf auto --cache 1048576 --stats "$TMP/st.json" "$TMP/big-in.pm" -o "$TMP/auto.pm"
if grep -q '"points": 200000' "$TMP/st.json" && grep -q '"points_per_s"' "$TMP/st.json" &&
    grep -q '"octree_depth": [0-9]' "$TMP/st.json" && grep -q '"leaf_rule": "auto"' "$TMP/st.json" &&
    "$BIN/pm-info" --header "$TMP/auto.pm" | grep -qx 'order=hilbert leaf=[0-9]* auto'; then
    pass "--leaf auto, and --stats has points, points_per_s and octree_depth"
else
    fail "--leaf auto / stats" "$(cat "$TMP/st.json")"
fi

# A failed write on the worker thread that writes while the next chunk is gathered: the
# message must reach the user whole every time (it once came out as "hilbert-sort: " with
# nothing after it, the worker's thread-local message lost). Repeated to catch the race.
if [ -w /dev/full ]; then
    bad=0
    for i in $(seq 1 20); do
        "$HS" -q --threads 2 "$TMP/big-in.pm" -o - >/dev/full 2>"$TMP/full.err"
        st=$?
        if [ "$st" != 3 ] || ! grep -qx "hilbert-sort: cannot write 'stdout': No space left on device (io error)" "$TMP/full.err"; then
            bad=$((bad + 1)) last="exit $st: $(cat "$TMP/full.err")"
        fi
    done
    if [ "$bad" = 0 ]; then
        pass "a full disk (/dev/full) gives the whole message from the writing thread, 20 of 20 runs"
    else
        fail "full disk message" "$bad of 20 runs wrong; last: $last"
    fi
else
    skip "full disk message" "no writable /dev/full"
fi
