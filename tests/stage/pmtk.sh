# pmtk.sh: the pmtk command (git style): `pmtk PROGRAM ARGS` runs the program beside it (or in
# PREFIX/libexec/pmtk once installed, or $PMTK_EXEC_PATH) with ARGS, passing its exit status
# through; an unknown command is a usage error.
# programs: pmtk
P=$BIN/pmtk
"$P" --help >"$TMP/help" 2>"$TMP/err"
if [ $? = 0 ] && grep -q '^usage: pmtk' "$TMP/help" && grep -qx '  simd-gather' "$TMP/help" &&
    ! grep -qx '  pmtk' "$TMP/help" && [ ! -s "$TMP/err" ]; then
    pass "pmtk --help lists the programs to stdout"
else
    fail "pmtk --help" "$(head -c 300 "$TMP/help" "$TMP/err")"
fi
if [ "$("$P" --version)" = "pmtk (pmtk) $("$BIN/composite" --version | sed 's/.* //')" ]; then pass "pmtk --version"; else fail "pmtk --version" "$("$P" --version 2>&1)"; fi
expect_exit "pmtk alone is a usage error" 2 "$P"
expect_exit "pmtk with an unknown command exits 2" 2 "$P" no-such-program
if grep -q "^pmtk: unknown command 'no-such-program'" "$TMP/err"; then pass "pmtk names the unknown command"; else fail "pmtk unknown command message" "$(cat "$TMP/err")"; fi
expect_exit "pmtk refuses a path as a command" 2 "$P" ../bin/pm-info
expect_exit "pmtk refuses itself as a command" 2 "$P" pmtk --help
# arguments and exit status pass through
"$P" pm-info tests/golden/photons-all.pm >"$TMP/a" 2>&1
st=$?
"$BIN/pm-info" tests/golden/photons-all.pm >"$TMP/b" 2>&1
if [ $st = 0 ] && cmp -s "$TMP/a" "$TMP/b"; then pass "pmtk pm-info FILE is pm-info FILE"; else fail "pmtk pm-info" "exit $st"; fi
expect_exit "pmtk passes the program's exit status (1, bad input)" 1 "$P" pm-info /etc/hostname
if grep -q "^pm-info: " "$TMP/err"; then pass "the program's messages keep its own name"; else fail "pmtk pm-info message" "$(cat "$TMP/err")"; fi
expect_exit "pmtk passes the program's usage status (2)" 2 "$P" simd-gather --no-such-option
# the PATH does not matter: an imposter composite first on it is not run
mkdir -p "$TMP/fakebin"
printf '#!/bin/sh\necho imposter\nexit 42\n' >"$TMP/fakebin/composite"
chmod +x "$TMP/fakebin/composite"
out=$(PATH="$TMP/fakebin" "$P" composite --version 2>&1)
if [ "$out" = "$("$BIN/composite" --version)" ]; then pass "pmtk composite ignores a composite first on the PATH"; else fail "pmtk composite with an imposter on PATH" "$out"; fi
# PMTK_EXEC_PATH picks the folder
mkdir -p "$TMP/exec"
printf '#!/bin/sh\necho "other $*"\n' >"$TMP/exec/pm-info"
chmod +x "$TMP/exec/pm-info"
if [ "$(PMTK_EXEC_PATH=$TMP/exec "$P" pm-info x y)" = "other x y" ]; then pass "PMTK_EXEC_PATH names the programs' folder"; else fail "PMTK_EXEC_PATH" "$(PMTK_EXEC_PATH=$TMP/exec "$P" pm-info x y 2>&1)"; fi
# help COMMAND is COMMAND --help
if "$P" help hilbert-sort | grep -q '^usage: hilbert-sort'; then pass "pmtk help PROGRAM prints the program's help"; else fail "pmtk help hilbert-sort" "$("$P" help hilbert-sort 2>&1 | head -c 200)"; fi
