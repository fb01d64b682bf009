# lib.sh: helpers for the stage tests (sourced by tests/stage/*.sh).
# Each check prints "ok NAME", "FAIL NAME: why" or "skip NAME: why" and counts into
# PASS/FAIL/SKIP; a skipped check is reported by tests/run, never counted as passed.
PASS=${PASS:-0}
FAIL=${FAIL:-0}
SKIP=${SKIP:-0}
TMP=${TMP:-$(mktemp -d "${TMPDIR:-/tmp}"/pmtk-stage-XXXXXX)}

pass() { PASS=$((PASS + 1)); echo "ok $1"; }
fail() { FAIL=$((FAIL + 1)); echo "FAIL $1: $2"; }
# skip NAME WHY: a check that cannot run here (a program not built yet, a missing tool).
skip() { SKIP=$((SKIP + 1)); echo "skip $1: $2"; }

# expect_exit NAME CODE CMD...: CMD exits with CODE.
expect_exit() {
    local name=$1 code=$2
    shift 2
    "$@" >"$TMP/out" 2>"$TMP/err"
    local got=$?
    if [ "$got" = "$code" ]; then pass "$name"; else fail "$name" "exit $got, expected $code: $(head -c 300 "$TMP/err")"; fi
}

# expect_error NAME PATTERN CMD...: CMD exits 1 with exactly one stderr line matching PATTERN.
expect_error() {
    local name=$1 pattern=$2
    shift 2
    "$@" >"$TMP/out" 2>"$TMP/err"
    local got=$? lines
    lines=$(wc -l <"$TMP/err")
    if [ "$got" != 1 ]; then
        fail "$name" "exit $got, expected 1: $(head -c 300 "$TMP/err")"
    elif [ "$lines" != 1 ]; then
        fail "$name" "$lines lines on stderr, expected one: $(head -c 300 "$TMP/err")"
    elif ! grep -qE -- "$pattern" "$TMP/err"; then
        fail "$name" "stderr '$(cat "$TMP/err")' does not match '$pattern'"
    else
        pass "$name"
    fi
}

# expect_same NAME FILE1 FILE2: the files are byte-identical.
expect_same() {
    if cmp -s "$2" "$3"; then pass "$1"; else fail "$1" "$2 and $3 differ"; fi
}

# lamp_box_obj FILE FLOOR: the closed 2 m box of glossy.sh and glossy-kinds.sh (materials from
# box.mtl: the floor's name FLOOR, walls 'wall', a 0.6 m square ceiling lamp 'lamp' facing down).
lamp_box_obj() {
    cat >"$1" <<OBJ
mtllib box.mtl
v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
v -0.3 0.99 -0.3
v 0.3 0.99 -0.3
v 0.3 0.99 0.3
v -0.3 0.99 0.3
usemtl $2
f 1 5 6
f 1 6 2
usemtl wall
f 4 3 7
f 4 7 8
f 1 4 8
f 1 8 5
f 2 6 7
f 2 7 3
f 5 8 7
f 5 7 6
f 1 2 3
f 1 3 4
usemtl lamp
f 9 10 11
f 9 11 12
OBJ
}
