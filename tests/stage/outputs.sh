# outputs.sh: outputs never clobber (issue 17, items 5 to 8). Special files (a FIFO, a device,
# /dev/fd/1) are written through and stay what they are; a symbolic link stays a link and its
# target is replaced; two outputs of one command naming one file are refused with exit 2
# before any work; several outputs of one command appear together or not at all; a 250-byte
# output name works; the file is fsync'ed before its rename.
# Device nodes are made here with mknod (as root): an unfixed program would replace the node it
# writes to, so the system's /dev/null and /dev/full are never named as outputs by root.
# programs: composite hilbert-sort measure-error trace-gather-points trace-reference
TG=$BUILD/tests/pm-testgen
HS=$BIN/hilbert-sort
C=$BIN/composite
S=scenes/cornell-box/scene.json

"$TG" queries 500 "$TMP/q.pm" --all
"$TG" radiance 1 "$TMP/r.pm"
"$HS" -q "$TMP/q.pm" -o "$TMP/want.pm"
# same_pm A B: A is a valid pmtk file with the records of B (the COMMAND lines name the outputs).
same_pm() { "$BIN/pm-compare" -q "$1" "$2" >/dev/null 2>&1; }

# A null and a full device of our own (root), or the system's when an unfixed program cannot
# replace them (not root).
NULLDEV="" FULLDEV=""
if [ "$(id -u)" = 0 ]; then
    mknod "$TMP/null" c 1 3 2>/dev/null && NULLDEV=$TMP/null
    mknod "$TMP/full" c 1 7 2>/dev/null && FULLDEV=$TMP/full
else
    NULLDEV=/dev/null FULLDEV=/dev/full
fi

# ---- item 5: special files are written through, links followed ----
# fifo_read NAME FIFO OUT CMD...: CMD writes into FIFO while cat reads it into OUT; the FIFO
# stays a FIFO and CMD exits 0.
fifo_read() {
    local name=$1 fifo=$2 got=$3
    shift 3
    rm -f "$fifo" "$got"
    mkfifo "$fifo"
    timeout 10 cat "$fifo" >"$got" &
    local reader=$!
    timeout 20 "$@" >/dev/null 2>"$TMP/err"
    local rc=$?
    # An unfixed program renames over the FIFO and the reader waits on the old one: end it.
    [ -p "$fifo" ] || kill "$reader" 2>/dev/null
    wait "$reader" 2>/dev/null
    if [ "$rc" != 0 ]; then
        fail "$name" "exit $rc: $(head -c 300 "$TMP/err")"
    elif [ ! -p "$fifo" ]; then
        fail "$name" "the FIFO was replaced by a $(stat -c %F "$fifo")"
    else
        return 0
    fi
    return 1
}
if fifo_read "-o onto a FIFO" "$TMP/f" "$TMP/got.pm" "$HS" -q "$TMP/q.pm" -o "$TMP/f"; then
    same_pm "$TMP/got.pm" "$TMP/want.pm" && pass "-o onto a FIFO: written through, the FIFO stays a FIFO" ||
        fail "-o onto a FIFO" "the reader got other bytes than a file output holds"
fi
if fifo_read "--stats onto a FIFO" "$TMP/f" "$TMP/got.json" "$HS" -q "$TMP/q.pm" -o "$TMP/s.pm" --stats "$TMP/f"; then
    grep -q '"stage": "hilbert-sort"' "$TMP/got.json" && pass "--stats onto a FIFO: written through" ||
        fail "--stats onto a FIFO" "the reader got: $(head -c 200 "$TMP/got.json")"
fi
if fifo_read "--png onto a FIFO" "$TMP/f" "$TMP/got.png" "$C" -q "$TMP/r.pm" --png "$TMP/f"; then
    [ "$(head -c 4 "$TMP/got.png" | tail -c 3)" = PNG ] && pass "--png onto a FIFO: written through" ||
        fail "--png onto a FIFO" "the reader got no PNG"
fi
# OpenEXR writes by name and seeks: through a temporary file, then copied into the FIFO.
if fifo_read "an EXR onto a FIFO" "$TMP/f" "$TMP/got.exr" "$C" -q "$TMP/r.pm" -o "$TMP/f"; then
    "$C" -q "$TMP/r.pm" -o "$TMP/file.exr"
    if "$BUILD/tests/pm-exrdump" "$TMP/got.exr" >"$TMP/a.txt" 2>&1 && "$BUILD/tests/pm-exrdump" "$TMP/file.exr" >"$TMP/b.txt" &&
        cmp -s "$TMP/a.txt" "$TMP/b.txt"; then
        pass "an EXR onto a FIFO: copied through, the same pixels as a file"
    else
        fail "an EXR onto a FIFO" "$(head -c 200 "$TMP/a.txt")"
    fi
fi
if [ -n "$NULLDEV" ]; then
    for args in "-o $NULLDEV" "-o $TMP/s.pm --stats $NULLDEV"; do
        "$HS" -q "$TMP/q.pm" $args 2>"$TMP/err"
        rc=$?
        [ "$rc" = 0 ] && [ -c "$NULLDEV" ] && pass "hilbert-sort $args: exit 0, still a device" ||
            fail "hilbert-sort $args" "exit $rc, $(stat -c %F "$NULLDEV"): $(head -c 200 "$TMP/err")"
    done
    "$C" -q "$TMP/r.pm" -o "$NULLDEV" --png "$TMP/p.png" 2>"$TMP/err"
    rc=$?
    [ "$rc" = 0 ] && [ -c "$NULLDEV" ] && pass "composite -o DEVICE (an EXR): exit 0, still a device" ||
        fail "composite -o DEVICE" "exit $rc, $(stat -c %F "$NULLDEV"): $(head -c 200 "$TMP/err")"
else
    skip "outputs onto a device" "mknod failed"
fi
# /dev/fd/1 (as /dev/stdout) on a pipe: written through. (An unfixed program fails here: it
# cannot create its temporary file in /proc/self/fd.)
"$HS" -q "$TMP/q.pm" -o /dev/fd/1 2>"$TMP/err" | cat >"$TMP/fd1.pm"
same_pm "$TMP/fd1.pm" "$TMP/want.pm" && pass "-o /dev/fd/1 on a pipe is written through" ||
    fail "-o /dev/fd/1" "$(head -c 200 "$TMP/err")"
# /dev/fd/1 on a regular file: written into the file the shell opened (the same inode), appended
# to for '>>'.
: >"$TMP/fd1file.pm"
ino=$(stat -c %i "$TMP/fd1file.pm")
"$HS" -q "$TMP/q.pm" -o /dev/fd/1 2>"$TMP/err" >"$TMP/fd1file.pm"
same_pm "$TMP/fd1file.pm" "$TMP/want.pm" && [ "$(stat -c %i "$TMP/fd1file.pm")" = "$ino" ] &&
    pass "-o /dev/fd/1 on a file ('>'): the shell's file gets the output, not replaced" ||
    fail "-o /dev/fd/1 on a file" "$(head -c 200 "$TMP/err")"
echo first >"$TMP/fd1log"
"$HS" -q "$TMP/q.pm" -o /dev/fd/1 2>"$TMP/err" >>"$TMP/fd1log"
tail -c +7 "$TMP/fd1log" >"$TMP/fd1tail.pm"
[ "$(head -n 1 "$TMP/fd1log")" = first ] && same_pm "$TMP/fd1tail.pm" "$TMP/want.pm" &&
    pass "-o /dev/fd/1 on a file ('>>'): appended" || fail "-o /dev/fd/1 '>>'" "$(head -c 200 "$TMP/err")"
# A link to a regular file: the link stays, its target gets the output.
echo old >"$TMP/real.pm"
ln -sf real.pm "$TMP/link.pm"
"$HS" -q "$TMP/q.pm" -o "$TMP/link.pm" 2>"$TMP/err"
if [ -L "$TMP/link.pm" ] && same_pm "$TMP/real.pm" "$TMP/want.pm"; then
    pass "-o onto a symbolic link: the link stays, its target is replaced"
else
    fail "-o onto a symbolic link" "link $([ -L "$TMP/link.pm" ] && echo kept || echo replaced): $(head -c 200 "$TMP/err")"
fi
mkdir -p "$TMP/sub"
ln -sf ../new.pm "$TMP/sub/dangling.pm"
"$HS" -q "$TMP/q.pm" -o "$TMP/sub/dangling.pm" 2>"$TMP/err"
if [ -L "$TMP/sub/dangling.pm" ] && same_pm "$TMP/new.pm" "$TMP/want.pm"; then
    pass "-o onto a dangling relative link: the link stays, the file it names is created"
else
    fail "-o onto a dangling link" "$(ls -l "$TMP/sub" | tail -n +2) $(head -c 200 "$TMP/err")"
fi
mkdir -p "$TMP/adir"
expect_exit "-o onto a directory: usage error" 2 "$HS" -q "$TMP/q.pm" -o "$TMP/adir"

# ---- item 6: two outputs naming one file: exit 2 before any work ----
# clash NAME FILE CMD...: CMD exits 2 with a usage error naming both options, FILE not made.
clash() {
    local name=$1 file=$2
    shift 2
    rm -f "$file"
    "$@" >/dev/null 2>"$TMP/err"
    local rc=$?
    if [ "$rc" = 2 ] && head -n 1 "$TMP/err" | grep -qE 'two outputs to one file .*\(usage error\)$' && [ ! -e "$file" ]; then
        pass "$name: refused, exit 2"
    else
        fail "$name" "exit $rc, $([ -e "$file" ] && echo "file made" || echo "no file"): $(head -c 300 "$TMP/err")"
    fi
}
clash "trace-gather-points -o X --direct X" "$TMP/x.pm" \
    "$BIN/trace-gather-points" -q "$S" --width 4 --height 4 --spp 4 -o "$TMP/x.pm" --direct "$TMP/x.pm"
clash "composite -o X --png X" "$TMP/x.exr" "$C" -q "$TMP/r.pm" -o "$TMP/x.exr" --png "$TMP/x.exr"
clash "hilbert-sort --stats X -o X" "$TMP/x.pm" "$HS" -q "$TMP/q.pm" --stats "$TMP/x.pm" -o "$TMP/x.pm"
clash "composite -o X --radiance DIR/./X (one name, two spellings)" "$TMP/x.pm" \
    "$C" -q "$TMP/r.pm" -o "$TMP/x.pm" --radiance "$TMP/sub/../x.pm"
echo keep >"$TMP/h1"
ln -f "$TMP/h1" "$TMP/h2"
"$HS" -q "$TMP/q.pm" -o "$TMP/h1" --stats "$TMP/h2" >/dev/null 2>"$TMP/err"
rc=$?
[ "$rc" = 2 ] && [ "$(cat "$TMP/h1")" = keep ] && pass "-o and --stats on two hard links of one file: refused, untouched" ||
    fail "hard links" "exit $rc: $(head -c 200 "$TMP/err")"
"$C" -q "$TMP/r.pm" --png - --radiance - >/dev/null 2>"$TMP/err"
rc=$?
[ "$rc" = 2 ] && grep -q "two outputs to one file 'stdout'" "$TMP/err" && pass "composite --png - --radiance -: stdout twice, refused" ||
    fail "stdout twice" "exit $rc: $(head -c 200 "$TMP/err")"
"$HS" -q "$TMP/q.pm" -o - --stats - 2>"$TMP/err" >"$TMP/o.pm"
same_pm "$TMP/o.pm" "$TMP/want.pm" && grep -q '"stage"' "$TMP/err" && pass "-o - --stats -: stdout and stderr, no clash" ||
    fail "-o - --stats -" "$(head -c 200 "$TMP/err")"

# ---- item 7: several outputs appear together or not at all ----
rm -f "$TMP/i.exr" "$TMP/i.png"
expect_exit "composite with its last output failing exits 1" 1 \
    "$C" -q "$TMP/r.pm" -o "$TMP/i.exr" --png "$TMP/i.png" --radiance "$TMP/nodir/i.pm"
[ ! -e "$TMP/i.exr" ] && [ ! -e "$TMP/i.png" ] && pass "... and leaves neither the EXR nor the PNG" ||
    fail "composite output set" "$(ls "$TMP"/i.* 2>&1)"
if [ -n "$FULLDEV" ]; then
    "$C" -q "$TMP/r.pm" -o "$TMP/i.exr" --png "$TMP/i.png" --radiance "$FULLDEV" 2>"$TMP/err"
    rc=$?
    if [ "$rc" = 3 ] && grep -q 'No space left on device (io error)$' "$TMP/err" && [ ! -e "$TMP/i.exr" ] &&
        [ ! -e "$TMP/i.png" ] && [ -c "$FULLDEV" ]; then
        pass "composite onto a full device: io error, no EXR, no PNG, the device kept"
    else
        fail "composite onto a full device" "exit $rc, $(ls "$TMP"/i.* 2>&1): $(head -c 200 "$TMP/err")"
    fi
else
    skip "composite onto a full device" "mknod failed"
fi
"$BIN/measure-error" -q "$TMP/r.pm" "$TMP/r.pm" --error-image "$TMP/e.exr" -o "$TMP/nodir/e.json" >/dev/null 2>&1
rc=$?
[ "$rc" = 1 ] && [ ! -e "$TMP/e.exr" ] && pass "measure-error: the JSON fails, no error image left" ||
    fail "measure-error output set" "exit $rc, $(ls "$TMP"/e.* 2>&1)"
"$BIN/trace-reference" -q "$S" --width 4 --height 4 --spp 1 --pass 1 -o "$TMP/ref.exr" --radiance "$TMP/nodir/ref.pm" \
    >/dev/null 2>&1
rc=$?
[ "$rc" = 1 ] && [ ! -e "$TMP/ref.exr" ] && pass "trace-reference: --radiance fails, no EXR left" ||
    fail "trace-reference output set" "exit $rc, $(ls "$TMP"/ref.* 2>&1)"
"$C" -q "$TMP/r.pm" -o "$TMP/i.exr" --png "$TMP/i.png" --radiance "$TMP/i.pm"
[ -s "$TMP/i.exr" ] && [ -s "$TMP/i.png" ] && "$BIN/pm-info" "$TMP/i.pm" >/dev/null 2>&1 &&
    [ -z "$(ls -A "$TMP" | grep '^\.')" ] && pass "composite's three outputs in place, no temporary left" ||
    fail "composite three outputs" "$(ls -A "$TMP")"

# ---- item 8: long names, fsync ----
long=$(printf 'n%.0s' $(seq 250))
"$HS" -q "$TMP/q.pm" -o "$TMP/$long" 2>"$TMP/err" && same_pm "$TMP/$long" "$TMP/want.pm" &&
    pass "a 250-byte output name works" || fail "250-byte name" "$(head -c 200 "$TMP/err")"
long=$(printf 'm%.0s' $(seq 255))
"$C" -q "$TMP/r.pm" -o "$TMP/$long" 2>"$TMP/err" && [ -s "$TMP/$long" ] &&
    pass "a 255-byte (NAME_MAX) EXR output name works" || fail "255-byte name" "$(head -c 200 "$TMP/err")"
rm -f "$TMP/$long"
# (LeakSanitizer cannot run under ptrace: off for this one run.)
if command -v strace >/dev/null && ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0 strace -f -o "$TMP/trace" -e trace=fsync,rename,renameat,renameat2 \
    "$HS" -q "$TMP/q.pm" -o "$TMP/synced.pm" 2>/dev/null; then
    # the file's fsync, then its rename onto synced.pm, then the directory's fsync
    grep -E 'fsync\(|rename[a-z0-9]*\(' "$TMP/trace" >"$TMP/calls"
    n=$(grep -n 'rename.*synced\.pm' "$TMP/calls" | head -n 1 | cut -d: -f1)
    if [ -n "$n" ] && head -n $((n - 1)) "$TMP/calls" | grep -q 'fsync(' &&
        tail -n +$((n + 1)) "$TMP/calls" | grep -q 'fsync('; then
        pass "the output is fsync'ed before its rename and its directory after"
    else
        fail "fsync around the rename" "$(head -c 300 "$TMP/calls")"
    fi
else
    skip "fsync around the rename" "strace cannot trace here"
fi
