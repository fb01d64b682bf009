# formats.sh: every format against its golden file, pm-info's text against its golden
# text, version-1 files read as before, and the bad-input corpus: each corrupt file gets
# its one-line error and exit 1.
# programs: build-photonmap hilbert-sort simd-gather trace-photons
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

# ---- version 1 (CHANNELS and CHANNEL_MASK): read, checked and printed as before ----
for f in photons photonmap queries radiance; do
    "$BIN/pm-info" -r "$G/v1/$f-all.pm" >"$TMP/v1.txt" 2>"$TMP/err"
    expect_same "pm-info -r a version-1 $f file matches its golden text" "$G/v1/$f-all.txt" "$TMP/v1.txt"
    cat "$G/v1/$f-all.pm" | "$BIN/pm-info" -r - >"$TMP/v1-pipe.txt" 2>"$TMP/err"
    expect_same "pm-info reads a version-1 $f file from stdin" "$G/v1/$f-all.txt" "$TMP/v1-pipe.txt"
    expect_exit "pm-compare: version-1 and version-2 $f files of one content agree" 0 \
        "$BIN/pm-compare" "$G/v1/$f-all.pm" "$G/$f-all.pm"
    # the records are the same bytes; only the header (and so the checksum) changed
    v1_hdr=$(grep -a -n -m 1 '^$' "$G/v1/$f-all.pm" | cut -d: -f1)
    v2_hdr=$(grep -a -n -m 1 '^$' "$G/$f-all.pm" | cut -d: -f1)
    expect_same "version-1 and version-2 $f records are byte-identical" \
        <(tail -n +$((v1_hdr + 1)) "$G/v1/$f-all.pm" | head -c -8) <(tail -n +$((v2_hdr + 1)) "$G/$f-all.pm" | head -c -8)
done
# a stage reading a version-1 file writes version 2, without the mask
"$BIN/hilbert-sort" --order none -q "$G/v1/queries-all.pm" -o "$TMP/from-v1.pm"
if "$BIN/pm-info" --header "$TMP/from-v1.pm" | grep -qx 'VERSION=2.0' &&
    ! "$BIN/pm-info" --header "$TMP/from-v1.pm" | grep -q '^CHANNEL_MASK='; then
    pass "a version-1 input gives a version-2 output without CHANNEL_MASK"
else
    fail "a version-1 input gives a version-2 output without CHANNEL_MASK" "$("$BIN/pm-info" --header "$TMP/from-v1.pm" 2>&1 | head -9)"
fi
v1=$G/v1/photons-all.pm
for spelling in 0x1f 0x0000001F "0x 000001f" 31; do
    sed "0,/CHANNEL_MASK=0x0000001f/s//CHANNEL_MASK=$spelling/" "$v1" >"$TMP/spelled.pm"
    expect_error "version 1: CHANNEL_MASK spelled '$spelling'" "malformed CHANNEL_MASK" "$BIN/pm-info" "$TMP/spelled.pm"
done
sed '0,/CHANNEL_MASK=0x0000001f/s//CHANNEL_MASK=0x0000003f/' "$v1" >"$TMP/mask.pm"
expect_error "version 1: unknown channel bit" "CHANNEL_MASK 0x0000003f names channels unknown" "$BIN/pm-info" "$TMP/mask.pm"
sed '0,/CHANNEL_MASK=0x0000001f/s//CHANNEL_MASK=0x00000017/' "$v1" >"$TMP/names.pm"
expect_error "version 1: a mask that disagrees with the names" \
    "CHANNELS 'position power normal direction depth' disagrees with CHANNEL_MASK 0x00000017" "$BIN/pm-info" "$TMP/names.pm"
sed '0,/CHANNELS=position power normal direction depth/s//CHANNELS=position power normal depth direction/' "$v1" >"$TMP/names.pm"
expect_error "version 1: names that disagree with the mask" "CHANNELS .* disagrees with CHANNEL_MASK" "$BIN/pm-info" "$TMP/names.pm"
grep -av '^CHANNEL_MASK=' "$v1" >"$TMP/nomask.pm"
expect_error "version 1: CHANNEL_MASK missing" "lacks CHANNEL_MASK" "$BIN/pm-info" "$TMP/nomask.pm"
sed '0,/VERSION=1.0/s//VERSION=2.0/' "$v1" >"$TMP/v2mask.pm"
expect_error "version 2 with a CHANNEL_MASK" "is version 2.0 but has CHANNEL_MASK, a version-1 key" "$BIN/pm-info" "$TMP/v2mask.pm"
sed '0,/VERSION=1.0/s//VERSION=3.0/' "$v1" >"$TMP/v3.pm"
expect_error "version 1 file relabelled 3.0" "version 3.0, newer than this reader" "$BIN/pm-info" "$TMP/v3.pm"

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
sed '0,/VERSION=2.0/s//VERSION=3.0/' "$src" >"$TMP/v3.pm"
expect_error "newer major version" "version 3.0, newer than this reader \(2.x\)" "$BIN/pm-info" "$TMP/v3.pm"
sed '0,/VERSION=2.0/s//VERSION=0.9/' "$src" >"$TMP/v0.pm"
expect_error "older major version" "version 0.9, older than this reader \(1.x to 2.x\)" "$BIN/pm-info" "$TMP/v0.pm"
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
for spelling in +2.0 2 2.0.0 2.x 02.0; do
    sed "0,/VERSION=2.0/s//VERSION=$spelling/" "$src" >"$TMP/spelled.pm"
    expect_error "VERSION spelled '$spelling'" "malformed VERSION" "$BIN/pm-info" "$TMP/spelled.pm"
done
sed '0,/RECORD_SIZE=52/s//RECORD_SIZE=52.0/' "$src" >"$TMP/spelled.pm"
expect_error "RECORD_SIZE spelled '52.0'" "RECORD_SIZE '52.0'" "$BIN/pm-info" "$TMP/spelled.pm"
sed '0,/^width=8$/s//width=8.0/' "$G/queries-all.pm" >"$TMP/spelled.pm"
expect_error "width spelled '8.0'" "header key width='8.0' is not a decimal integer" "$BIN/pm-info" "$TMP/spelled.pm"
sed '0,/^component=indirect$/s//component=glow/' "$G/radiance-all.pm" >"$TMP/comp.pm"
expect_error "radiance component unknown" "component 'glow' is not direct, indirect, caustic or total" "$BIN/pm-info" "$TMP/comp.pm"
sed '0,/RECORD_SIZE=52/s//RECORD_SIZE=48/' "$src" >"$TMP/rsize.pm"
expect_error "record size disagrees with channels" "RECORD_SIZE '48' but its channels take 52 bytes" "$BIN/pm-info" "$TMP/rsize.pm"
ch='position power normal direction depth'
sed "0,/CHANNELS=$ch/s//CHANNELS=position power normal colour depth/" "$src" >"$TMP/names.pm"
expect_error "an unknown channel name" "CHANNELS names 'colour', not a channel of version 2.0" "$BIN/pm-info" "$TMP/names.pm"
for spelling in "position power normal depth direction" "position power power normal direction depth" \
    "position  power normal direction depth" "position power normal direction depth " \
    " position power normal direction depth"; do
    sed "0,/CHANNELS=$ch/s//CHANNELS=$spelling/" "$src" >"$TMP/names.pm"
    expect_error "CHANNELS spelled '$spelling'" "CHANNELS '$spelling' is not spelled '$ch'" "$BIN/pm-info" "$TMP/names.pm"
done
sed "0,/CHANNELS=$ch/s//CHANNELS=position power direction depth/" "$src" >"$TMP/names.pm"
expect_error "a required channel left out of CHANNELS" "lacks required channel 'normal'" "$BIN/pm-info" "$TMP/names.pm"
sed '0,/BYTE_ORDER=little-endian/s//BYTE_ORDER=big-endian/' "$src" >"$TMP/be.pm"
expect_error "big-endian header" "BYTE_ORDER 'big-endian' is not little-endian" "$BIN/pm-info" "$TMP/be.pm"
sed '0,/^BOUNDS=.*/s//BOUNDS=nan 0 0 1 1 1/' "$src" >"$TMP/bounds.pm"
expect_error "NaN bounds" "BOUNDS .* non-finite|BOUNDS .* not six numbers" "$BIN/pm-info" "$TMP/bounds.pm"
sed '0,/^BOUNDS=.*/s//BOUNDS=1 0 0 0 1 1/' "$src" >"$TMP/bounds2.pm"
expect_error "inverted bounds" "min above max on axis x" "$BIN/pm-info" "$TMP/bounds2.pm"
sed '0,/^COUNT=7$/s//COUNT 7/' "$src" >"$TMP/line.pm"
expect_error "header line without =" "malformed header line 5 .*has no '='" "$BIN/pm-info" "$TMP/line.pm"
grep -av '^CHANNELS=' "$src" >"$TMP/nochannels.pm"
expect_error "missing required key" "lacks CHANNELS" "$BIN/pm-info" "$TMP/nochannels.pm"
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

# inputs the fuzzers found (tests/fuzz/regressions, docs/fuzzing.md), each through the stage
# that reads such a file, named by its prefix: success, or exit 1 with one line from that
# stage; never a crash. The gathers' partner files are those the fuzz targets used (the
# queries with the weight contract simd-gather asks for; the records are queries-all's).
"$TG" queries 7 "$TMP/fuzz-partner-q.pm" --all --set weights=lambertian-brdf-folded
for f in tests/fuzz/regressions/*; do
    case $(basename "$f") in
    reader-*) stage=pm-info; set -- "$f" ;;
    photonmap-*) stage=simd-gather; set -- --radius 0.25 -q "$f" "$TMP/fuzz-partner-q.pm" -o "$TMP/fuzz-out.pm" ;;
    queries-*) stage=simd-gather; set -- --radius 0.25 -q "$G/photonmap-all.pm" "$f" -o "$TMP/fuzz-out.pm" ;;
    radiance-*) stage=measure-error; set -- -q "$f" "$f" ;;
    scene-*) stage=scene-info; set -- "$f" ;;
    *) fail "fuzz regression $(basename "$f")" "no stage for its name (reader-, photonmap-, queries-, radiance-, scene-)"; continue ;;
    esac
    "$BIN/$stage" "$@" >"$TMP/out" 2>"$TMP/err"
    got=$?
    if [ $got = 0 ] || { [ $got = 1 ] && [ "$(wc -l <"$TMP/err")" = 1 ] && grep -q "^$stage: " "$TMP/err"; }; then
        pass "fuzz regression $(basename "$f") through $stage: exit $got"
    else
        fail "fuzz regression $(basename "$f") through $stage" "exit $got: $(head -c 300 "$TMP/err")"
    fi
done

# a disk that fills up: one clear line, exit 1, and neither the output nor a temporary left
mkdir -p "$TMP/full"
expect_error "a write that fails (file size limit)" "cannot write '.*full/big.pm': File too large" \
    bash -c "trap '' XFSZ; ulimit -f 64; '$TG' photons 100000 '$TMP/full/big.pm'"
if [ -z "$(ls -A "$TMP/full")" ]; then pass "a failed write leaves nothing behind"; else fail "a failed write leaves nothing behind" "$(ls -A "$TMP/full")"; fi

# ---- the image-size cap (issue 17, item 10) ----------------------------------------------
# A queries header may declare at most 65536 pixels a side and 2^26 in all (docs/formats.md):
# 65536 x 2048 in a 4 KB file made simd-gather write a 3.2 GB buffer. The header is edited
# past the cap and the checksum resealed (no writer writes it), so the readers' own check
# refuses it: pm-info and simd-gather with one line, exit 1, before any buffer is made.
"$TG" queries 100 "$TMP/cap0.pm" --set width=65536
sed 's/^height=4$/height=2048/; s/^COMMAND=.*/&\nweights=lambertian-brdf-folded/' "$TMP/cap0.pm" >"$TMP/cap1.pm"
"$TG" reseal "$TMP/cap1.pm" "$TMP/cap.pm"
expect_error "a queries header of 65536 x 2048 pixels is refused by the reader" \
    "queries '.*cap.pm': image size 65536x2048 outside 1..65536 per side and 67108864 pixels in all \(input error\)$" \
    "$BIN/pm-info" "$TMP/cap.pm"
"$TG" photons 100 "$TMP/cap-ph.pm" && "$BIN/build-photonmap" -q "$TMP/cap-ph.pm" -o "$TMP/cap-map.pm"
expect_error "simd-gather refuses a 65536 x 2048 queries header and writes no buffer" "image size 65536x2048 outside" \
    "$BIN/simd-gather" -q "$TMP/cap-map.pm" "$TMP/cap.pm" --radius 0.1 -o "$TMP/cap-out.pm"
[ -e "$TMP/cap-out.pm" ] && fail "simd-gather past the cap: no output" "cap-out.pm exists" ||
    pass "simd-gather past the cap: no output"
# 8192 x 8192 is the largest square: the header reads (the records need not fill it)
sed 's/^height=4$/height=1024/' "$TMP/cap0.pm" >"$TMP/cap2.pm"
"$TG" reseal "$TMP/cap2.pm" "$TMP/cap-max.pm"
expect_exit "a queries header of 65536 x 1024 pixels (2^26, the cap) reads" 0 "$BIN/pm-info" -q "$TMP/cap-max.pm"
# the stages that take --width/--height refuse beyond the cap, a usage error (exit 2)
for s in trace-gather-points trace-reference; do
    expect_exit "$s --width 65536 --height 2048: refused, exit 2" 2 \
        "$BIN/$s" scenes/cornell-box/scene.json --width 65536 --height 2048 -q -o "$TMP/cap-$s.out"
    grep -q "image size 65536x2048 outside .* (usage error)$" "$TMP/err" && [ "$(wc -l <"$TMP/err")" = 1 ] &&
        pass "$s: one line naming the size and the limits" || fail "$s past the cap" "$(cat "$TMP/err")"
done

# ---- a read error is reported as one (issue 17, item 12) ---------------------------------
# A stream that cannot be read (here stdin closed) is not an "empty input": the line says
# what the system said; a closed descriptor is the caller's doing (EBADF), an input error.
expect_error "closed stdin: the read error and errno, not 'empty input'" \
    "^pm-info: cannot read 'stdin': Bad file descriptor \(input error\)$" bash -c "exec <&-; '$BIN/pm-info' -"
expect_error "an empty file is still an empty input" "empty input '.*empty.pm'" \
    bash -c ": >'$TMP/empty.pm'; '$BIN/pm-info' '$TMP/empty.pm'"

# ---- binary output to a terminal (issue 17, item 13) -------------------------------------
# With no -o and stdout a terminal, a stage refuses as gzip does: one line, usage (exit 2),
# nothing written to the terminal. script(1) (util-linux) gives the program a terminal.
if command -v script >/dev/null; then
    script -qec "'$BIN/trace-photons' scenes/cornell-box/scene.json -n 100 -q" /dev/null >"$TMP/tty.out" 2>&1
    got=$?
    if [ "$got" = 2 ] && grep -q "trace-photons: refusing to write a binary photons file to a terminal (stdout): give -o FILE or pipe it (usage error)" "$TMP/tty.out" &&
        ! grep -aq 'PMTK' "$TMP/tty.out"; then
        pass "trace-photons with stdout on a terminal refuses in one line, exit 2, no bytes of the file"
    else
        fail "trace-photons to a terminal" "exit $got: $(head -c 200 "$TMP/tty.out" | tr -c '[:print:]' '?')"
    fi
    script -qec "'$BIN/hilbert-sort' '$G/queries-all.pm' -q -o -" /dev/null >"$TMP/tty.out" 2>&1
    got=$?
    [ "$got" = 2 ] && grep -q "refusing to write a binary queries file to a terminal" "$TMP/tty.out" &&
        pass "hilbert-sort -o - onto a terminal refuses too" || fail "hilbert-sort to a terminal" "exit $got"
    # refused before any work: two billion photons would take minutes to trace first
    timeout 60 script -qec "'$BIN/trace-photons' scenes/cornell-box/scene.json -n 2000000000 -q" /dev/null >"$TMP/tty.out" 2>&1
    got=$?
    [ "$got" = 2 ] && grep -q "refusing to write a binary photons file to a terminal" "$TMP/tty.out" &&
        pass "trace-photons refuses the terminal before it traces (2e9 photons, no work done)" ||
        fail "trace-photons refuses the terminal before it traces" "exit $got (124: it traced first)"
    # a pipe is not a terminal: the same command writes
    "$BIN/trace-photons" scenes/cornell-box/scene.json -n 100 -q | "$BIN/pm-info" -q - >/dev/null 2>"$TMP/err" &&
        pass "trace-photons into a pipe still writes" || fail "trace-photons into a pipe" "$(cat "$TMP/err")"
else
    skip "binary output to a terminal" "script (util-linux) is not installed"
fi
