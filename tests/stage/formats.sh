# formats.sh: every format against its golden file, pm-info's text against its golden
# text, and the bad-input corpus: each corrupt file gets its one-line error and exit 1.
G=tests/golden
TG=$BUILD/tests/pm-testgen

for f in photons photonmap queries radiance; do
    for v in required all; do
        flag=""; [ $v = all ] && flag=--all
        "$TG" $f 7 "$TMP/$f-$v.pm" $flag
        expect_same "golden $f ($v channels) is byte-identical" "$G/$f-$v.pm" "$TMP/$f-$v.pm"
        "$BIN/pm-info" -r "$G/$f-$v.pm" >"$TMP/$f-$v.txt" 2>"$TMP/err"
        expect_same "pm-info -r $f ($v) matches its golden text" "$G/$f-$v.txt" "$TMP/$f-$v.txt"
    done
    # streamed through a pipe the reader sees the same
    cat "$G/$f-all.pm" | "$BIN/pm-info" -r - >"$TMP/pipe.txt" 2>"$TMP/err"
    expect_same "pm-info reads $f from stdin" "$G/$f-all.txt" "$TMP/pipe.txt"
done

# ---- the bad-input corpus, made from the golden files ----
src=$G/photons-all.pm
size=$(stat -c %s "$src")
head -c $((size - 8)) "$src" >"$TMP/no-checksum.pm"
expect_error "truncated before the checksum" "truncated photons file .*checksum missing" "$BIN/pm-info" "$TMP/no-checksum.pm"
head -c $((size - 100)) "$src" >"$TMP/short.pm"
expect_error "truncated in a record" "truncated photons file .*ends in record [0-9]+ of 7" "$BIN/pm-info" "$TMP/short.pm"
head -c 40 "$src" >"$TMP/header-only.pm"
expect_error "truncated in the header" "truncated header" "$BIN/pm-info" "$TMP/header-only.pm"
cat "$src" | head -c $((size - 100)) >"$TMP/short-pipe"
expect_error "truncated on a pipe" "truncated photons file 'stdin'" sh -c "cat '$TMP/short-pipe' | '$BIN/pm-info' -"
: >"$TMP/empty.pm"
expect_error "empty file" "empty input" "$BIN/pm-info" "$TMP/empty.pm"
printf 'P6\n4 4\n255\n' >"$TMP/ppm.pm"
expect_error "bad magic" "bad magic .*found 'P6" "$BIN/pm-info" "$TMP/ppm.pm"
sed '0,/VERSION=1.0/s//VERSION=2.0/' "$src" >"$TMP/v2.pm"
expect_error "newer major version" "version 2.0, newer than this reader" "$BIN/pm-info" "$TMP/v2.pm"
sed '0,/FORMAT=photons/s//FORMAT=voxels/' "$src" >"$TMP/fmt.pm"
expect_error "unknown format" "unknown format 'voxels'" "$BIN/pm-info" "$TMP/fmt.pm"
sed '0,/COUNT=7/s//COUNT=9/' "$src" >"$TMP/count9.pm"
expect_error "count larger than the payload" "truncated photons file" "$BIN/pm-info" "$TMP/count9.pm"
sed '0,/COUNT=7/s//COUNT=5/' "$src" >"$TMP/count5.pm"
expect_error "count smaller than the payload" "wrong count in photons file .*bytes follow the checksum" "$BIN/pm-info" "$TMP/count5.pm"
sed '0,/COUNT=7/s//COUNT=99999999999999999/' "$src" >"$TMP/absurd.pm"
expect_error "absurd count" "absurd COUNT" "$BIN/pm-info" "$TMP/absurd.pm"
for spelling in -7 +7 7.0 7e0 7E0 0x7 " 7" 07x 07; do
    sed "0,/COUNT=7/s//COUNT=$spelling/" "$src" >"$TMP/spelled.pm"
    expect_error "COUNT spelled '$spelling'" "absurd COUNT" "$BIN/pm-info" "$TMP/spelled.pm"
done
for spelling in 0x1f 0x0000001F "0x 000001f" 31; do
    sed "0,/CHANNEL_MASK=0x0000001f/s//CHANNEL_MASK=$spelling/" "$src" >"$TMP/spelled.pm"
    expect_error "CHANNEL_MASK spelled '$spelling'" "malformed CHANNEL_MASK" "$BIN/pm-info" "$TMP/spelled.pm"
done
for spelling in +1.0 1 1.0.0 1.x; do
    sed "0,/VERSION=1.0/s//VERSION=$spelling/" "$src" >"$TMP/spelled.pm"
    expect_error "VERSION spelled '$spelling'" "malformed VERSION" "$BIN/pm-info" "$TMP/spelled.pm"
done
sed '0,/RECORD_SIZE=52/s//RECORD_SIZE=52.0/' "$src" >"$TMP/spelled.pm"
expect_error "RECORD_SIZE spelled '52.0'" "RECORD_SIZE '52.0'" "$BIN/pm-info" "$TMP/spelled.pm"
sed '0,/^width=8$/s//width=8.0/' "$G/queries-all.pm" >"$TMP/spelled.pm"
expect_error "width spelled '8.0'" "header key width='8.0' is not a decimal integer" "$BIN/pm-info" "$TMP/spelled.pm"
sed '0,/^component=indirect$/s//component=glow/' "$G/radiance-all.pm" >"$TMP/comp.pm"
expect_error "radiance component unknown" "component 'glow' is not direct, indirect or total" "$BIN/pm-info" "$TMP/comp.pm"
sed '0,/RECORD_SIZE=52/s//RECORD_SIZE=48/' "$src" >"$TMP/rsize.pm"
expect_error "record size disagrees with channels" "RECORD_SIZE '48' but its channels take 52 bytes" "$BIN/pm-info" "$TMP/rsize.pm"
sed '0,/CHANNEL_MASK=0x0000001f/s//CHANNEL_MASK=0x0000003f/' "$src" >"$TMP/mask.pm"
expect_error "unknown channel bit" "CHANNEL_MASK 0x0000003f names channels unknown" "$BIN/pm-info" "$TMP/mask.pm"
sed '0,/CHANNELS=position power normal direction depth/s//CHANNELS=position power normal depth direction/' "$src" >"$TMP/names.pm"
expect_error "channel names disagree with the mask" "CHANNELS .* disagrees with CHANNEL_MASK" "$BIN/pm-info" "$TMP/names.pm"
sed '0,/BYTE_ORDER=little-endian/s//BYTE_ORDER=big-endian/' "$src" >"$TMP/be.pm"
expect_error "big-endian header" "BYTE_ORDER 'big-endian' is not little-endian" "$BIN/pm-info" "$TMP/be.pm"
sed '0,/^BOUNDS=.*/s//BOUNDS=nan 0 0 1 1 1/' "$src" >"$TMP/bounds.pm"
expect_error "NaN bounds" "BOUNDS .* non-finite|BOUNDS .* not six numbers" "$BIN/pm-info" "$TMP/bounds.pm"
sed '0,/^BOUNDS=.*/s//BOUNDS=1 0 0 0 1 1/' "$src" >"$TMP/bounds2.pm"
expect_error "inverted bounds" "min above max on axis x" "$BIN/pm-info" "$TMP/bounds2.pm"
sed '0,/^COUNT=7$/s//COUNT 7/' "$src" >"$TMP/line.pm"
expect_error "header line without =" "malformed header line 5 .*has no '='" "$BIN/pm-info" "$TMP/line.pm"
grep -av '^CHANNEL_MASK=' "$src" >"$TMP/nomask.pm"
expect_error "missing required key" "lacks CHANNEL_MASK" "$BIN/pm-info" "$TMP/nomask.pm"
# a flipped byte in the payload where any value is valid: only the checksum catches it
blank=$(grep -a -n -m 1 '^$' "$src" | cut -d: -f1)
hdr_bytes=$(head -n "$blank" "$src" | wc -c)
off=$((hdr_bytes + 4 + 48)) # record 0 depth: no value check can see it
cp "$src" "$TMP/flip.pm"
printf '\x55' | dd of="$TMP/flip.pm" bs=1 seek=$off conv=notrunc status=none
expect_error "flipped payload byte" "checksum mismatch in photons file" "$BIN/pm-info" "$TMP/flip.pm"
# a flipped byte in the byte-order marker
cp "$src" "$TMP/bom.pm"
printf '\x01\x02\x03\x04' | dd of="$TMP/bom.pm" bs=1 seek=$hdr_bytes conv=notrunc status=none
expect_error "big-endian marker" "is big-endian" "$BIN/pm-info" "$TMP/bom.pm"
cat "$src" "$src" >"$TMP/twice.pm"
expect_error "two files concatenated" "wrong count .*bytes follow the checksum" "$BIN/pm-info" "$TMP/twice.pm"
expect_error "directory as input" "is a directory" "$BIN/pm-info" "$TMP"
expect_error "missing file" "cannot open '/nonexistent.pm'" "$BIN/pm-info" /nonexistent.pm

# values: right checksum, wrong content
for p in "photons nan position.*nan" "photons inf position.*inf" "photons negative power.*negative" \
    "photons unit normal.*length" "photonmap nan position.*nan" "photonmap tree right child 1000000 outside" \
    "queries pixel pixel 1000000 outside" "queries nan position.*nan" \
    "photonmap order photon 1 at x = 1000 lies outside .* the planes of its ancestors" \
    "radiance nan rgb.*nan" "radiance inf rgb.*inf"; do
    set -- $p
    "$TG" $1 7 "$TMP/poison.pm" --all --poison $2
    expect_error "$1 with $2 content" "$3" "$BIN/pm-info" "$TMP/poison.pm"
done

# inputs the fuzzer found (tests/fuzz/regressions): each must fail cleanly, never crash
for f in tests/fuzz/regressions/*.pm; do
    expect_error "fuzz regression $(basename "$f")" "^pm-info: " "$BIN/pm-info" "$f"
done

# a disk that fills up: one clear line, exit 1, and neither the output nor a temporary left
mkdir -p "$TMP/full"
expect_error "a write that fails (file size limit)" "cannot write '.*full/big.pm': File too large" \
    bash -c "trap '' XFSZ; ulimit -f 64; '$TG' photons 100000 '$TMP/full/big.pm'"
if [ -z "$(ls -A "$TMP/full")" ]; then pass "a failed write leaves nothing behind"; else fail "a failed write leaves nothing behind" "$(ls -A "$TMP/full")"; fi
