# library.sh: libpmtk as a project outside the tree meets it. `make install` lays out the pmtk
# command, the programs in libexec/pmtk, libpmtk.so.1 exporting only pmtk_*, its header,
# pkg-config file and man pages; examples/tiny-tracer builds from `pkg-config --cflags --libs
# pmtk` alone, renders, and gathers pmtk files through the library (the sums themselves are
# checked against brute force in tests/unit/test_api.c).
# programs: libpmtk pmtk composite
SO=$BUILD/libpmtk.so.1.0.0
if [ ! -f "$SO" ]; then
    fail "libpmtk.so.1.0.0 is built" "no $SO"
    return 0 2>/dev/null || exit 0
fi
soname=$(readelf -d "$SO" | sed -n 's/.*Library soname: \[\(.*\)\]/\1/p')
if [ "$soname" = libpmtk.so.1 ]; then pass "libpmtk's soname is libpmtk.so.1"; else fail "soname" "'$soname'"; fi
others=$(nm -D --defined-only "$SO" | awk '$2 != "A" && $3 !~ /^pmtk_/ && $3 != "PMTK_1" { print $3 }' | head -5)
napi=$(nm -D --defined-only "$SO" | awk '$3 ~ /^pmtk_/' | wc -l)
if [ -z "$others" ] && [ "$napi" -ge 25 ]; then
    pass "libpmtk.so exports the $napi pmtk_* functions and nothing else"
else
    fail "libpmtk.so exports" "$napi pmtk_* names; others: $others"
fi
# every function of the header is exported
missing=$(grep -o 'pmtk_[a-z_]*(' include/pmtk.h | tr -d '(' | sort -u | while read -r f; do
    nm -D --defined-only "$SO" | grep -qE " $f(@@PMTK_1)?\$" || echo "$f"
done)
if [ -z "$missing" ]; then pass "every function pmtk.h declares is in libpmtk.so"; else fail "pmtk.h functions missing from the library" "$missing"; fi

# make install builds with the default flags: it runs on the default build only (an ASan run
# has BUILD=build/asan and would rebuild the plain programs under its flags).
if [ "$(cd "$BUILD" && pwd)" != "$(pwd)/build" ]; then
    skip "make install and the example" "BUILD=$BUILD is not the default build (make install uses the default flags)"
    return 0 2>/dev/null || exit 0
fi
INST=$TMP/inst
if make --no-print-directory -s install PREFIX="$INST" >"$TMP/install.log" 2>&1; then
    pass "make install PREFIX=DIR"
else
    fail "make install" "$(tail -n 5 "$TMP/install.log")"
fi
ok=1
for f in bin/pmtk libexec/pmtk/composite libexec/pmtk/simd-gather libexec/pmtk/pm-render lib/libpmtk.so.1.0.0 \
    lib/libpmtk.so.1 lib/libpmtk.so include/pmtk.h lib/pkgconfig/pmtk.pc share/man/man1/pmtk.1 \
    share/man/man1/pmtk-composite.1; do
    [ -e "$INST/$f" ] || { ok=0; fail "make install puts $f" "missing"; }
done
[ -e "$INST/bin/composite" ] && { ok=0; fail "make install keeps bare program names off bin/" "bin/composite"; }
[ $ok = 1 ] && pass "make install: pmtk in bin/, the programs in libexec/pmtk/, library, header, pkg-config, man pages"
if grep -q '^\.SH DESCRIPTION' "$INST/share/man/man1/pmtk-simd-gather.1" && grep -q -- 'radius' "$INST/share/man/man1/pmtk-simd-gather.1"; then
    pass "the man pages are made from --help"
else
    fail "man page of simd-gather" "$(head -c 300 "$INST/share/man/man1/pmtk-simd-gather.1")"
fi
# DESTDIR stages the same tree under another root, the paths inside naming PREFIX
if make --no-print-directory -s install PREFIX=/usr DESTDIR="$TMP/stage" >"$TMP/install2.log" 2>&1 &&
    [ -x "$TMP/stage/usr/bin/pmtk" ] && grep -qx 'prefix=/usr' "$TMP/stage/usr/lib/pkgconfig/pmtk.pc"; then
    pass "make install DESTDIR=ROOT PREFIX=/usr stages under ROOT with /usr in pmtk.pc"
else
    fail "make install DESTDIR" "$(tail -n 5 "$TMP/install2.log")"
fi

# the example, from pkg-config alone
export PKG_CONFIG_PATH=$INST/lib/pkgconfig
if make --no-print-directory -s -C examples OUT="$TMP/tiny-tracer" LDFLAGS="-Wl,-rpath,$INST/lib" >"$TMP/ex.log" 2>&1; then
    pass "examples/tiny-tracer builds with pkg-config --cflags --libs pmtk"
else
    fail "examples/tiny-tracer builds" "$(tail -n 5 "$TMP/ex.log")"
fi
if ldd "$TMP/tiny-tracer" 2>/dev/null | grep -q "libpmtk.so.1 => $INST/lib/libpmtk.so.1"; then
    pass "tiny-tracer links the installed libpmtk.so.1"
else
    fail "tiny-tracer's libpmtk" "$(ldd "$TMP/tiny-tracer" 2>&1 | grep pmtk)"
fi
"$TMP/tiny-tracer" -o "$TMP/tiny.ppm" -n 20000 -s 32 >"$TMP/tt.out" 2>"$TMP/tt.err"
st=$?
if [ $st = 0 ] && [ "$(head -c 2 "$TMP/tiny.ppm")" = P6 ] && [ "$(wc -c <"$TMP/tiny.ppm")" = $((13 + 32 * 32 * 3)) ] &&
    grep -q "queries gathered" "$TMP/tt.out"; then
    pass "tiny-tracer renders its box through the library"
else
    fail "tiny-tracer renders" "exit $st: $(head -c 300 "$TMP/tt.err")"
fi
# its gather of pmtk files (a photon map and queries of the golden set)
G=tests/golden
if "$TMP/tiny-tracer" --gather $G/build-photonmap-cornell.pm $G/queries-all.pm 0.05 1 >"$TMP/g.out" 2>"$TMP/g.err"; then
    pass "tiny-tracer --gather reads pmtk files through the library"
else
    fail "tiny-tracer --gather" "$(head -c 300 "$TMP/g.err")"
fi
expect_exit "tiny-tracer --gather of a missing map fails" 1 "$TMP/tiny-tracer" --gather "$TMP/none.pm" $G/queries-all.pm 0.05 1
if grep -q "none.pm" "$TMP/err"; then pass "the library's message names the file"; else fail "library message" "$(cat "$TMP/err")"; fi

# the installed pmtk runs the installed programs, whatever else is on the PATH
mkdir -p "$TMP/fakebin"
printf '#!/bin/sh\necho imposter\nexit 42\n' >"$TMP/fakebin/composite"
chmod +x "$TMP/fakebin/composite"
out=$(PATH="$TMP/fakebin:$PATH" "$INST/bin/pmtk" composite --version 2>&1)
if [ "$out" = "composite (pmtk) $("$BIN/composite" --version | sed 's/.* //')" ]; then
    pass "installed pmtk composite runs pmtk's composite, not the PATH's"
else
    fail "installed pmtk composite" "$out"
fi
