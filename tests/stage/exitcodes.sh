# exitcodes.sh: every program's exit status by the class of its failure (docs/cli.md, "Exit
# status and errors"): 1 bad input (a corrupt file, a path that does not exist), 2 usage, 3 the
# system failed (a full device, a file-size limit: a retry may succeed), and pm-compare's
# answers as cmp's (0 agree, 1 differ, 2 trouble). Internal errors (4) cannot be provoked from
# outside; the unit test of pm_result_exit_code covers their status. Tests run as root, so a
# permission cannot be taken away: the system's failures are /dev/full (ENOSPC) on stdout and
# `ulimit -f` (EFBIG, its SIGXFSZ ignored) for the outputs that need a path (OpenEXR).
# programs: all
G=tests/golden
CB=scenes/cornell-box/scene.json
MAP=$G/build-photonmap-cornell.pm
QUERIES=$G/gather-cornell-16x16-spp8.pm
printf '{ "meshes": [ not json\n' >"$TMP/corrupt.json"
head -c 300 "$G/photons-all.pm" >"$TMP/truncated.pm" # a header without its records and checksum

# expect_status NAME STATUS CLASS CMD...: CMD exits STATUS and its failure's line (the stderr
# line ending in "(... error)"; a usage hint may follow it) ends in "(CLASS error)"; nothing is
# left at $TMP/out.* (outputs appear whole or not at all).
expect_status() {
    local name=$1 status=$2 class=$3
    shift 3
    rm -f "$TMP"/out.*
    "$@" >/dev/null 2>"$TMP/err"
    local got=$? line
    line=$(grep -E ' \([a-z]+ error\)$' "$TMP/err" | head -n 1)
    if [ "$got" != "$status" ]; then
        fail "$name" "exit $got, expected $status: $(head -c 300 "$TMP/err")"
    elif [[ "$line" != *" ($class error)" ]]; then
        fail "$name" "'$line' does not end in '($class error)'"
    elif [ -n "$(ls "$TMP"/out.* 2>/dev/null)" ]; then
        fail "$name" "left $(ls "$TMP"/out.*)"
    else
        pass "$name"
    fi
}
# full CMD...: CMD with its stdout on /dev/full (every write fails with ENOSPC)
full() { "$@" >/dev/full; }
# limited CMD...: CMD under a file-size limit of 0 blocks (every write to a file fails, EFBIG).
# Its stderr goes through a pipe to a cat outside the limit: the limit would stop the message
# itself on its way into a file.
limited() {
    { (trap '' XFSZ && ulimit -f 0 && exec "$@") 2>&1 >&3 | cat >&2; } 3>&1
    return "${PIPESTATUS[0]}"
}

# One row per program: its arguments on a corrupt input, on a missing one, and a run whose
# output the system refuses ('full' for stdout, 'limited' for a path). A program in bin/
# without a row fails, so that a new program gets one.
declare -A BAD MISSING SYSTEM
BAD[trace-photons]="$TMP/corrupt.json -o -"
MISSING[trace-photons]="$TMP/none.json -o -"
SYSTEM[trace-photons]="full $CB --photons 1000 -o -"
BAD[build-photonmap]="$TMP/truncated.pm -o -"
MISSING[build-photonmap]="$TMP/none.pm -o -"
SYSTEM[build-photonmap]="full $G/photons-all.pm -o -"
BAD[trace-gather-points]="$TMP/corrupt.json -o -"
MISSING[trace-gather-points]="$TMP/none.json -o -"
SYSTEM[trace-gather-points]="full $CB --width 8 --height 8 --spp 4 -o -"
BAD[hilbert-sort]="/etc/hostname -o -"
MISSING[hilbert-sort]="$TMP/none.pm -o -"
SYSTEM[hilbert-sort]="full $G/hilbert-input.pm -o -"
BAD[simd-gather]="$TMP/truncated.pm $QUERIES -o -"
MISSING[simd-gather]="$MAP $TMP/none.pm -o -"
SYSTEM[simd-gather]="full $MAP $QUERIES -o -"
BAD[knn-gather]="$TMP/truncated.pm $QUERIES -o -"
MISSING[knn-gather]="$MAP $TMP/none.pm -o -"
SYSTEM[knn-gather]="full $MAP $QUERIES --k 10 -o -"
BAD[reverse-gather]="$TMP/truncated.pm $QUERIES -o -"
MISSING[reverse-gather]="$MAP $TMP/none.pm -o -"
SYSTEM[reverse-gather]="full $MAP $QUERIES -o -"
BAD[composite]="/etc/hostname -o $TMP/out.exr"
MISSING[composite]="$TMP/none.pm -o $TMP/out.exr"
SYSTEM[composite]="limited $G/direct-cornell-16x16.pm -o $TMP/out.exr"
BAD[pm-info]="/etc/hostname"
MISSING[pm-info]="$TMP/none.pm"
SYSTEM[pm-info]="full $G/photons-all.pm"
BAD[trace-reference]="$TMP/corrupt.json -o $TMP/out.exr"
MISSING[trace-reference]="$TMP/none.json -o $TMP/out.exr"
SYSTEM[trace-reference]="limited $CB --width 4 --height 4 --spp 1 -o $TMP/out.exr"
BAD[measure-error]="/etc/hostname $G/radiance-all.pm"
MISSING[measure-error]="$TMP/none.pm $G/radiance-all.pm"
SYSTEM[measure-error]="full $G/radiance-all.pm $G/radiance-all.pm"
BAD[scene-info]="$TMP/corrupt.json"
MISSING[scene-info]="$TMP/none.json"
SYSTEM[scene-info]="full $CB"

for p in "$BIN"/*; do
    n=$(basename "$p")
    [ "$n" = pm-compare ] && continue # below: it answers as cmp does
    [ "$n" = pm-render ] && continue  # below: a driver, whose lines name no class
    [ "$n" = pmtk ] && continue       # the command over the others passes their status on: pmtk.sh
    [ "$n" = pm-frames ] && continue  # below: a driver too (pipelines/frames)
    if [ -z "${BAD[$n]+set}" ]; then
        fail "$n has a row in exitcodes.sh" "no corrupt input, missing input or system failure given for it"
        continue
    fi
    expect_status "$n: usage (an unknown option) exits 2" 2 usage "$p" --no-such-option
    # shellcheck disable=SC2086 # the rows are words
    expect_status "$n: a corrupt input exits 1" 1 input "$p" -q ${BAD[$n]}
    # shellcheck disable=SC2086
    expect_status "$n: an input that does not exist exits 1 (ENOENT: no retry fixes it)" 1 input "$p" -q ${MISSING[$n]}
    set -- ${SYSTEM[$n]}
    how=$1
    shift
    expect_status "$n: an output the system refuses exits 3 ($how)" 3 io "$how" "$p" -q "$@"
done

# An output into a directory that does not exist is the user's path (1), not the system (3).
expect_status "an output in a missing directory exits 1" 1 input \
    "$BIN/hilbert-sort" -q "$G/hilbert-input.pm" -o "$TMP/no-such-dir/out.pm"
# A file the system cannot extend, for a program writing a pmtk file by path (not stdout).
expect_status "a pmtk file under a file-size limit exits 3" 3 io limited "$BIN/hilbert-sort" -q "$G/hilbert-input.pm" \
    -o "$TMP/out.pm"

# ---- pm-compare: 0 agree, 1 differ, 2 trouble of any class ----
"$BUILD/tests/pm-testgen" radiance 1 "$TMP/r1.pm" && "$BUILD/tests/pm-testgen" radiance 1 "$TMP/r2.pm" --poison nudge
PC=$BIN/pm-compare
expect_exit "pm-compare: files that agree exit 0" 0 "$PC" "$TMP/r1.pm" "$TMP/r1.pm"
"$PC" "$TMP/r1.pm" "$TMP/r2.pm" --stats "$TMP/differ.json" >/dev/null 2>"$TMP/err"
st=$?
line=$(cat "$TMP/err")
if [ $st = 1 ] && [ "$(wc -l <"$TMP/err")" = 1 ] && [[ $line == "pm-compare: '$TMP/r1.pm' and '$TMP/r2.pm' differ in channel 'rgb': "* ]] &&
    [[ $line != *" error)" ]] && [ "$(jq 'has("error")' "$TMP/differ.json")" = false ] &&
    [ "$(jq .differ "$TMP/differ.json")" = 1 ]; then
    pass "pm-compare: files that differ exit 1, one line that is no error, --stats differ 1 and no error key"
else
    fail "pm-compare differ" "exit $st, '$line', stats $(head -c 300 "$TMP/differ.json" 2>&1)"
fi
expect_exit "pm-compare: files of two formats differ (1)" 1 "$PC" "$G/photons-all.pm" "$G/queries-all.pm"
expect_status "pm-compare: usage exits 2" 2 usage "$PC" --no-such-option "$TMP/r1.pm" "$TMP/r2.pm"
expect_status "pm-compare: a wrong argument count exits 2" 2 usage "$PC" "$TMP/r1.pm"
expect_status "pm-compare: a corrupt file exits 2, not 1 (trouble, not a difference)" 2 input "$PC" "$TMP/r1.pm" \
    /etc/hostname
expect_status "pm-compare: a truncated file exits 2" 2 input "$PC" "$G/photons-all.pm" "$TMP/truncated.pm"
expect_status "pm-compare: a missing file exits 2" 2 input "$PC" "$TMP/r1.pm" "$TMP/none.pm"
expect_status "pm-compare: a report the system cannot write exits 2" 2 io full "$PC" "$TMP/r1.pm" "$TMP/r1.pm"
expect_status "pm-compare: a report the system cannot write exits 2, also when the files differ" 2 io full "$PC" \
    "$TMP/r1.pm" "$TMP/r2.pm"

# ---- the shell drivers: one scaffolding (pipelines/lib/common.sh), the stages' class passed through ----
# pm_stage_status: the class of a step of stages, a pipe's statuses in order
(
    PM_NAME=test
    source pipelines/lib/common.sh
    bad=""
    check() { # check WANT STATUS...
        local want=$1
        shift
        pm_stage_status "$@"
        local got=$?
        [ "$got" = "$want" ] || bad+=" ($*: $got, expected $want)"
    }
    check 0 0 0 0
    check 1 0 1 0        # bad data
    check 3 3 1 1        # a full disk upstream, then the short stream downstream
    check 3 141 3        # a full disk downstream, then the broken pipe upstream
    check 4 1 4 3        # a bug wins
    check 1 0 2          # a stage's usage error is the driver's command line: 1
    check 1 137          # killed: not known to be the system's
    pm_isint 12 && pm_isint 0 && pm_isint 007 1 && ! pm_isint 0 1 && ! pm_isint 1.5 && ! pm_isint "" && ! pm_isint -3 ||
        bad+=" pm_isint"
    pm_isnum 1.5 && pm_isnum .5 && pm_isnum 5e5 && pm_isnum 3 && ! pm_isnum x && ! pm_isnum "" && ! pm_isnum -1 ||
        bad+=" pm_isnum"
    [ -z "$bad" ] && echo ok || echo "$bad"
) >"$TMP/common.out" 2>&1
[ "$(cat "$TMP/common.out")" = ok ] && pass "common.sh: pm_stage_status, pm_isint and pm_isnum" ||
    fail "common.sh" "$(cat "$TMP/common.out")"
# pm_params: NAME=VALUE into a table, usage (2) for an unknown name or a bare word, one line each
params() ( # a subshell: pm_die exits it, not this script
    PM_NAME=test
    source pipelines/lib/common.sh
    declare -A T=([A]=1 [B]=) GIVEN=()
    pm_params T GIVEN "" -- "$@"
    echo "A=${T[A]} B=${T[B]} given=${!GIVEN[*]}"
)
[ "$(params B=x=y)" = "A=1 B=x=y given=B" ] && pass "common.sh: pm_params sets the table and what was given" ||
    fail "pm_params" "$(params B=x=y 2>&1)"
expect_exit "common.sh: pm_params refuses an unknown name (2)" 2 params C=1
[ "$(cat "$TMP/err")" = "test: unknown parameter 'C' (known: A B )" ] && pass "... in one line naming the known ones" ||
    fail "pm_params message" "$(cat "$TMP/err")"
expect_exit "common.sh: pm_params refuses a word that is not NAME=VALUE (2)" 2 params word

# a stage of the driver that fails for the system (3) or on bad input (1): fake programs in a BIN
# whose stage prints a class and exits with it
fake_bin() { # fake_bin DIR PROGRAM STATUS CLASS: BIN's programs, PROGRAM failing so
    mkdir -p "$1"
    for p in "$BIN"/*; do ln -sf "$p" "$1/"; done
    rm -f "$1/$2"
    printf '#!/bin/sh\necho "%s: injected failure (%s error)" >&2\nexit %s\n' "$2" "$4" "$3" >"$1/$2"
    chmod +x "$1/$2"
}
FR="FRAMES=2 PHOTONS=2000 SPP=4 WIDTH=16 HEIGHT=16"
fake_bin "$TMP/bin-io" hilbert-sort 3 io
for stream in 1 0; do
    # shellcheck disable=SC2086
    BIN=$TMP/bin-io pipelines/frames $CB "$TMP/fio" $FR STREAM=$stream >"$TMP/fio.out" 2>&1
    st=$?
    [ $st = 3 ] && grep -q 'injected failure (io error)' "$TMP/fio.out" && pass "frames STREAM=$stream: a stage's io failure exits 3" ||
        fail "frames STREAM=$stream io failure" "exit $st: $(tail -n 2 "$TMP/fio.out")"
done
fake_bin "$TMP/bin-bad" hilbert-sort 1 input
BIN=$TMP/bin-bad pipelines/frames $CB "$TMP/fbad" $FR STREAM=0 >"$TMP/fbad.out" 2>&1
st=$?
[ $st = 1 ] && pass "frames STREAM=0: a stage's input failure exits 1" || fail "frames input failure" "exit $st: $(tail -n 2 "$TMP/fbad.out")"
fake_bin "$TMP/bin-demo" trace-photons 3 io
BIN=$TMP/bin-demo pipelines/demo "$TMP/demo" >"$TMP/demo.out" 2>&1
st=$?
[ $st = 3 ] && grep -q '^demo: stage trace-photons failed$' "$TMP/demo.out" && pass "demo: a stage's io failure exits 3" ||
    fail "demo io failure" "exit $st: $(tail -n 2 "$TMP/demo.out")"
fake_bin "$TMP/bin-evt" measure-error 3 io
"$BUILD/tests/pm-testgen" radiance 1 "$TMP/ref.pm"
BIN=$TMP/bin-evt pipelines/error-vs-time $CB "$TMP/evt" REFERENCE="$TMP/ref.pm" PT_SPP= PLOT=0 >"$TMP/evt.out" 2>&1
st=$?
[ $st = 3 ] && grep -q 'cannot use the reference: .*injected failure (io error)' "$TMP/evt.out" &&
    pass "error-vs-time: measure-error's io failure on the reference exits 3" ||
    fail "error-vs-time io failure" "exit $st: $(tail -n 2 "$TMP/evt.out")"

# pm-render, the render driver: the same statuses, a stage's class passed through. Its own
# lines are pipelines/render's and carry no "(class error)" suffix, so the status and the
# subject are checked.
expect_render() {
    local name=$1 status=$2 subject=$3
    shift 3
    "$@" >/dev/null 2>"$TMP/err"
    local got=$?
    if [ "$got" != "$status" ]; then
        fail "$name" "exit $got, expected $status: $(head -c 300 "$TMP/err")"
    elif ! grep -q -- "$subject" "$TMP/err"; then
        fail "$name" "no line names '$subject': $(head -c 300 "$TMP/err")"
    else
        pass "$name"
    fi
}
expect_render "pm-render: usage (an unknown option) exits 2" 2 no-such-option "$BIN/pm-render" --no-such-option
expect_render "pm-render: a corrupt scene exits 1" 1 corrupt.json "$BIN/pm-render" -q "$TMP/corrupt.json" "$TMP/r1"
expect_render "pm-render: a scene that does not exist exits 1" 1 none.json "$BIN/pm-render" -q "$TMP/none.json" "$TMP/r2"
expect_render "pm-render: an OUTDIR the system refuses exits 3 (limited)" 3 "File too large" \
    limited "$BIN/pm-render" -q "$CB" "$TMP/r3" WIDTH=4 HEIGHT=4 PHOTONS=100
# pm-frames (pipelines/frames), the frames driver: the same statuses
expect_render "pm-frames: usage (an unknown option) exits 2" 2 no-such-option "$BIN/pm-frames" --no-such-option
expect_render "pm-frames: a bad parameter exits 2" 2 "DEGREES 'nan'" "$BIN/pm-frames" "$CB" "$TMP/f0" DEGREES=nan
expect_render "pm-frames: a corrupt scene exits 1" 1 corrupt.json "$BIN/pm-frames" -q "$TMP/corrupt.json" "$TMP/f1"
expect_render "pm-frames: a scene that does not exist exits 1" 1 none.json "$BIN/pm-frames" -q "$TMP/none.json" "$TMP/f2"
expect_render "pm-frames: an OUTDIR the system refuses exits 3 (limited)" 3 "File too large" \
    limited "$BIN/pm-frames" -q "$CB" "$TMP/f3" FRAMES=2 WIDTH=4 HEIGHT=4 PHOTONS=100
