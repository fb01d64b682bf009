# declared-size.sh: memory that grows with the records read, not with the image a header
# declares (issue 28 item 6): a 4 KB queries file of 100 queries whose header declares 65536 x
# 1024 pixels (2^26, the cap) made every gather allocate the whole radiance buffer up front, 1.5
# GiB, so under a 512 MiB address-space limit simd-gather, knn-gather and reverse-gather failed
# (out of memory, exit 3). Now the sums hold the pixels up to the last one a query names and the
# rest of the image is written as zero records: each works under the limit, its buffer's first
# pixels equal those of the same queries under a small header, and the file reads back whole.
# A radiance buffer whose header declares 2^26 pixels and holds 12 is refused as truncated,
# with one line, before any buffer of its size is made.
# programs: simd-gather knn-gather reverse-gather pm-info composite
TG="$BUILD/tests/pm-testgen"
"$TG" queries 100 "$TMP/ds0.pm" --set width=65536
sed 's/^COMMAND=.*/&\nweights=lambertian-brdf-folded/' "$TMP/ds0.pm" >"$TMP/ds1.pm"
sed 's/^height=4$/height=1024/' "$TMP/ds1.pm" >"$TMP/ds2.pm"
"$TG" reseal "$TMP/ds1.pm" "$TMP/ds-small.pm"
"$TG" reseal "$TMP/ds2.pm" "$TMP/ds-cap.pm"
"$TG" photons 100 "$TMP/ds-ph.pm" && "$BIN/build-photonmap" -q "$TMP/ds-ph.pm" -o "$TMP/ds-map.pm"
LIMIT=524288 # KiB: 512 MiB of address space
# a sanitizer build reserves terabytes of address space: the limit then applies to nothing
if (ulimit -v $LIMIT && exec "$BIN/pm-info" -q "$TMP/ds-small.pm") >/dev/null 2>&1; then
    under() { (ulimit -v $LIMIT && exec "$@"); }
    note="under ulimit -v $LIMIT"
else
    under() { "$@"; }
    note="(no address-space limit: a sanitizer build)"
fi
# first NAME FILE: the first 1000 records of radiance buffer FILE as text
first() { "$BIN/pm-info" -r -n 1000 "$2" | grep -E '^[0-9]+ ' >"$TMP/ds-$1.txt"; }
gathers=("simd-gather --radius 0.1" "knn-gather --k 5" "reverse-gather --radius 0.1")
for g in "${gathers[@]}"; do
    set -- $g
    prog=$1
    shift
    "$BIN/$prog" -q "$TMP/ds-map.pm" "$TMP/ds-small.pm" "$@" -o "$TMP/ds-$prog-small.pm"
    under "$BIN/$prog" -q "$TMP/ds-map.pm" "$TMP/ds-cap.pm" "$@" -o "$TMP/ds-$prog-cap.pm" 2>"$TMP/ds-$prog.err"
    code=$?
    if [ $code != 0 ]; then
        fail "$prog: 100 queries under a 2^26-pixel header $note" "exit $code: $(head -c 300 "$TMP/ds-$prog.err")"
        continue
    fi
    pass "$prog: 100 queries under a 2^26-pixel header $note"
    first small "$TMP/ds-$prog-small.pm"
    first cap "$TMP/ds-$prog-cap.pm"
    if [ -s "$TMP/ds-small.txt" ] && cmp -s "$TMP/ds-small.txt" "$TMP/ds-cap.txt"; then
        pass "$prog: its first 1000 pixels equal those under a 65536 x 4 header"
    else
        fail "$prog: its first 1000 pixels equal those under a 65536 x 4 header" "they differ"
    fi
    if "$BIN/pm-info" -q "$TMP/ds-$prog-cap.pm" >"$TMP/ds.info" 2>&1 &&
        grep -q "^COUNT=67108864$" "$TMP/ds-$prog-cap.pm" 2>/dev/null; then
        pass "$prog: the 2^26-pixel buffer reads back whole (checksum)"
    else
        fail "$prog: the 2^26-pixel buffer reads back whole" "$(head -c 300 "$TMP/ds.info")"
    fi
    rm -f "$TMP/ds-$prog-cap.pm"
done
# a radiance buffer declaring 2^26 pixels with 12 records: truncated, one line, exit 1
"$TG" radiance 4 "$TMP/ds-r0.pm"
LC_ALL=C sed 's/^COUNT=12$/COUNT=67108864/; s/^width=4$/width=8192/; s/^height=3$/height=8192/' "$TMP/ds-r0.pm" \
    >"$TMP/ds-r1.pm"
"$TG" reseal "$TMP/ds-r1.pm" "$TMP/ds-rcap.pm"
for prog in pm-info composite; do
    args=("$TMP/ds-rcap.pm")
    [ $prog = composite ] && args=("$TMP/ds-rcap.pm" "$TMP/ds-rcap.pm" -o "$TMP/ds-c.exr")
    expect_error "$prog: a radiance header of 2^26 pixels over 12 records, $note" \
        "truncated radiance buffer '.*ds-rcap.pm': ends in record 12 of 67108864 \(input error\)$" \
        under "$BIN/$prog" "${args[@]}"
done
