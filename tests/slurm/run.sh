#!/usr/bin/env bash
# tests/slurm/run.sh: pipelines/slurm on a real Slurm, the one-node cluster of
# tests/slurm/cluster (make test-slurm runs `tests/slurm/cluster run bash tests/slurm/run.sh`).
# A small progressive render through the cluster against the same passes by pipelines/render
# (byte for byte), a task killed with scancel while it runs, a task that fails once for the
# system and one that keeps failing so (resubmitted), one that fails on bad input (not
# resubmitted), two renders into two OUTDIRs at once, the cache (nothing resubmitted,
# then only the new passes), the gather in shard tasks (one killed, one missing shard alone
# resubmitted), the same bytes for any CPUS and THREADS, a job cancelled after its work landed
# (the jobs waiting for it resubmitted), TARGET_ERROR and TIME in waves, KEEP=image, and the bad
# input refused before anything is submitted. Every render has a time limit (SLURM_TEST_LIMIT).
# The last line is "slurm: N passed, N failed"; the exit status is 1 when any check failed.
set -u
cd "$(dirname "$0")/../.."
BIN=${BIN:-$PWD/bin}
export BIN
[ -n "${SLURM_CONF:-}" ] && sinfo -h >/dev/null 2>&1 || {
    echo "FAIL slurm: no cluster (run through tests/slurm/cluster run)"
    exit 1
}
TMP=$(mktemp -d "${TMPDIR:-/tmp}"/pmtk-slurm-XXXXXX)
trap 'rm -rf "$TMP"' EXIT
source tests/lib.sh

SCENE=scenes/cornell-box/scene.json
# passes of about a third of a second here: the checks are about the jobs, not the image
PR=(WIDTH=48 HEIGHT=48 PHOTONS=20000 PRIMARY=4 SPP=4 PASSES=6)
SL=(POLL=0.3)
same_image() { # same_image NAME DIR REFDIR: the images, the running image and passes.txt, byte for byte
    local f bad=""
    for f in image.exr image.png running.pm passes.txt; do cmp -s "$2/$f" "$3/$f" || bad+=" $f"; done
    if [ -z "$bad" ]; then pass "$1"; else fail "$1" "differ from the local render's:$bad"; fi
}
queue_empty() { [ -z "$(squeue -h -o %i 2>/dev/null)" ]; }
# Every pipelines/slurm and pipelines/render here runs under a time limit, generous for a slow
# machine (a run here takes seconds): a render that hangs is killed (pipelines/slurm cancels its
# jobs on the signal), says so in its log and on this script's output, and fails its check, and
# the suite goes on. make test-slurm has a limit of its own for the whole run.
LIMIT=${SLURM_TEST_LIMIT:-240}
exec 3>&1 # this script's output, past a command's redirections
limit() { # limit CMD [ARG ...]: CMD under timeout; a time-out is status 124
    local rc
    timeout -k 20 "$LIMIT" "$@" 3>&-
    rc=$?
    if [ $rc = 124 ] || [ $rc = 137 ]; then
        echo "TIMEOUT: '$*' did not end in $LIMIT s: killed" >&2
        echo "TIMEOUT: ${1##*/} ${2##*/} ... did not end in $LIMIT s: killed (the check after it fails)" >&3
        rc=124
    fi
    return $rc
}

# ---- the local references ----
# The cluster's tasks write the pass files, so a local render that writes them too (KEEP=all) is
# the one their files match byte for byte; the default resident render holds the same records
# and pixels under other provenance (tests/stage/passes.sh compares the two).
limit pipelines/render "$SCENE" "$TMP/local" "${PR[@]}" KEEP=all >"$TMP/local.log" 2>&1 || fail "local render" "$(tail -n 3 "$TMP/local.log")"
limit pipelines/render "$SCENE" "$TMP/local7" "${PR[@]}" SEED=7 KEEP=all >"$TMP/local7.log" 2>&1 || fail "local render SEED=7" "$(tail -n 3 "$TMP/local7.log")"

# ---- a render through the cluster, with one task killed while it runs ----
# Up to three tries: the task's log, as the test reads it, can lag behind the task, so that a task
# found with no pass made may have landed its pass already; then nothing is resubmitted, the
# image is right all the same, and the render is tried again for the resubmission.
for try in 1 2 3; do
    rm -rf "$TMP/a"
    limit pipelines/slurm "$SCENE" "$TMP/a" "${PR[@]}" "${SL[@]}" >"$TMP/a.log" 2>&1 &
    pid=$!
    # The task is killed for sure before it lands its pass: suspended first (scontrol suspend stops
    # its processes), killed when its log shows no pass made yet, else resumed and another one tried.
    # (A task killed as it ends may land its pass all the same, and its job end CANCELLED: the
    # checks after "a job that ends CANCELLED after it landed its work" below.)
    killed=""
    for ((i = 0; i < 600; i++)); do # up to 60 s
        j=$(squeue -h -r -n pm-pass -t RUNNING -o %i 2>/dev/null | grep -E '_[1-9][0-9]*$' | head -n 1)
        if [ -n "$j" ] && scontrol suspend "$j" 2>/dev/null; then
            if grep -qs '^slurm-task: passes [0-9]* to [0-9]* on ' "$TMP/a/.slurm/logs/task-${j#*_}.${j%_*}.out" &&
                ! grep -qs '^render: pass' "$TMP/a/.slurm/logs/task-${j#*_}.${j%_*}.out"; then
                scancel "$j" && killed=$j && break
            fi
            scontrol resume "$j" 2>/dev/null
        fi
        kill -0 $pid 2>/dev/null || break
        sleep 0.1
    done
    wait $pid
    rc=$?
    [ $rc = 0 ] && [ -n "$killed" ] && ! grep -q "ended without its passes.*resubmitting" "$TMP/a.log" &&
        [ $try -lt 3 ] && continue
    break
done
if [ $rc = 0 ] && [ -n "$killed" ] && grep -q "ended without its passes.*resubmitting" "$TMP/a.log"; then
    pass "a task killed while running ($killed) is resubmitted and the render finishes"
else
    fail "killed task" "exit $rc, killed '${killed:-none}' (try $try): $(tail -n 5 "$TMP/a.log")"
fi
same_image "cluster image = pipelines/render's, after a killed task" "$TMP/a" "$TMP/local"
grep -q 'tasks: [0-9]* pending, [0-9]* running, [0-9]* done, [0-9]* failed' "$TMP/a.log" &&
    grep -qE 'image: [1-5] of 6 passes' "$TMP/a.log" &&
    pass "progress: pending, running, done, failed counts, and the running image before the end" ||
    fail "progress" "no counts or no partial image in the log: $(head -n 5 "$TMP/a.log")"
[ "$(jq -r .total.passes "$TMP/a/stats.json" 2>/dev/null)" = 6 ] && pass "stats.json from the composite job" ||
    fail "stats.json" "$(head -c 200 "$TMP/a/stats.json" 2>&1)"

# ---- the cache: nothing is resubmitted, then only the new passes ----
limit pipelines/slurm "$SCENE" "$TMP/a" "${PR[@]}" "${SL[@]}" >"$TMP/a2.log" 2>&1
rc=$?
if [ $rc = 0 ] && grep -q '6 made before; submitted 0 task' "$TMP/a2.log"; then
    pass "a rerun submits no pass"
else
    fail "rerun" "exit $rc: $(head -n 2 "$TMP/a2.log")"
fi
same_image "a rerun leaves the same image" "$TMP/a" "$TMP/local"
PR8=("${PR[@]/PASSES=6/PASSES=8}")
limit pipelines/slurm "$SCENE" "$TMP/a" "${PR8[@]}" "${SL[@]}" TASK_PASSES=2 >"$TMP/a3.log" 2>&1
rc=$?
limit pipelines/render "$SCENE" "$TMP/local" "${PR8[@]}" KEEP=all >"$TMP/local8.log" 2>&1
if [ $rc = 0 ] && grep -q '8 passes, 6 made before; submitted 1 task' "$TMP/a3.log"; then
    pass "PASSES=8 after 6 submits one task of passes 7 and 8"
else
    fail "PASSES=8 after 6" "exit $rc: $(head -n 2 "$TMP/a3.log")"
fi
same_image "8 passes: the same image as pipelines/render's" "$TMP/a" "$TMP/local"
PR=("${PR8[@]}")

# ---- two renders into two OUTDIRs at once ----
limit pipelines/slurm "$SCENE" "$TMP/b" "${PR[@]}" "${SL[@]}" CPUS=2 >"$TMP/b.log" 2>&1 &
pb=$!
limit pipelines/slurm "$SCENE" "$TMP/c" "${PR[@]}" "${SL[@]}" SEED=7 TASK_PASSES=3 >"$TMP/c.log" 2>&1 &
pc=$!
wait $pb
rb=$?
wait $pc
rc=$?
limit pipelines/render "$SCENE" "$TMP/local7" "${PR[@]}" SEED=7 KEEP=all >"$TMP/local7b.log" 2>&1
[ $rb = 0 ] && [ $rc = 0 ] && pass "two renders at once, two OUTDIRs" ||
    fail "two renders" "exits $rb $rc: $(tail -n 2 "$TMP/b.log" "$TMP/c.log")"
same_image "two at once: the first's image (CPUS=2)" "$TMP/b" "$TMP/local"
same_image "two at once: the second's image (SEED=7, 3 passes a task)" "$TMP/c" "$TMP/local7"

# ---- a task that fails once, and one that keeps failing (a gather that refuses pass 3), for
# the system (an io error, exit 3: resubmitted) or on bad input (exit 1: not resubmitted) ----
cat >"$TMP/flaky-gather" <<EOF
#!/usr/bin/env bash
# simd-gather, but pass 3 fails while the flag file is there (and the flag 'once' removes it),
# as a stage fails for the system, or with the flag 'input' as one fails on bad data
case " \$* " in
*" --pass 3 "*)
    if [ -e "$TMP/fail-3" ]; then
        if grep -q input "$TMP/fail-3"; then
            echo "flaky-gather: pass 3 is bad on purpose (input error)" >&2
            exit 1
        fi
        grep -q once "$TMP/fail-3" && rm -f "$TMP/fail-3"
        echo "flaky-gather: pass 3 fails on purpose: Input/output error (io error)" >&2
        exit 3
    fi ;;
esac
exec "$BIN/simd-gather" "\$@"
EOF
chmod +x "$TMP/flaky-gather"
rm -f "$TMP/fail-3"
limit pipelines/render "$SCENE" "$TMP/localf" "${PR[@]}" GATHER="$TMP/flaky-gather" KEEP=all >"$TMP/localf.log" 2>&1 ||
    fail "local render with the flaky gather" "$(tail -n 2 "$TMP/localf.log")"
echo once >"$TMP/fail-3"
limit pipelines/slurm "$SCENE" "$TMP/f" "${PR[@]}" "${SL[@]}" GATHER="$TMP/flaky-gather" >"$TMP/f.log" 2>&1
rc=$?
if [ $rc = 0 ] && grep -q "task 2 (passes 3 to 3) ended without its passes" "$TMP/f.log"; then
    pass "a task that fails once is resubmitted"
else
    fail "a task failing once" "exit $rc: $(tail -n 4 "$TMP/f.log")"
fi
same_image "after a failed task, the image is the local render's" "$TMP/f" "$TMP/localf"
# A task of passes 2 to 4 lands pass 2 as soon as it is made; failing at pass 3, its next run
# starts at pass 3. The task of passes 5 and 6 lands pass 5 a pass's time before pass 6.
echo once >"$TMP/fail-3"
limit pipelines/slurm "$SCENE" "$TMP/f3" "${PR[@]}" "${SL[@]}" GATHER="$TMP/flaky-gather" TASK_PASSES=3 >"$TMP/f3.log" 2>&1
rc=$?
logs=("$TMP/f3/.slurm/logs"/task-1.*.out)
if [ $rc = 0 ] && [ ${#logs[@]} = 2 ] && grep -q '^slurm-task: passes 2 to 4 ' "${logs[0]}" &&
    grep -q '^render: pass 2 made' "${logs[0]}" && grep -q '^slurm-task: passes 3 to 4 ' "${logs[1]}"; then
    pass "a task that failed at its second pass runs again from that pass (the first had landed)"
else
    fail "a task resumed after its landed passes" "exit $rc, logs ${logs[*]##*/}: $(head -n 3 "${logs[@]}" 2>&1)"
fi
same_image "... and the image is the local render's" "$TMP/f3" "$TMP/localf"
# The order, not a time: the task's log says pass 5 landed before render said pass 6 was made
# (a task that landed its passes at its end would say it after).
log56=$(grep -l '^slurm-task: passes 5 to ' "$TMP/f3/.slurm/logs"/task-*.out | head -n 1)
order=$(grep -E '^(render: pass [56] made|slurm-task: pass [56] landed)' "$log56" 2>/dev/null | sed 's/ made.*/ made/' |
    tr '\n' ';')
[ "$order" = "render: pass 5 made;slurm-task: pass 5 landed;render: pass 6 made;slurm-task: pass 6 landed;" ] &&
    pass "a task lands each pass as it is made (its log: $order)" ||
    fail "passes land as made" "log '${log56##*/}': $order"
echo always >"$TMP/fail-3"
limit pipelines/slurm "$SCENE" "$TMP/g" "${PR[@]}" "${SL[@]}" GATHER="$TMP/flaky-gather" RETRIES=1 >"$TMP/g.out" 2>"$TMP/g.err"
rc=$?
log=$(sed -n 's/.*; log: \(.*\)$/\1/p' "$TMP/g.err")
if [ $rc = 3 ] && [ "$(wc -l <"$TMP/g.err")" = 1 ] &&
    grep -q "task 2 (passes 3 to 3) failed 2 times (last: .*); log: " "$TMP/g.err" &&
    [ -f "$log" ] && grep -q 'fails on purpose' "$log"; then
    pass "a task that keeps failing for the system stops the render, one line with its log, exit 3"
else
    fail "a task that keeps failing" "exit $rc: $(cat "$TMP/g.err")"
fi
sleep 1
queue_empty && pass "nothing of the stopped render left in the queue" || fail "queue after a stop" "$(squeue -h)"
echo input >"$TMP/fail-3"
limit pipelines/slurm "$SCENE" "$TMP/gi" "${PR[@]}" "${SL[@]}" GATHER="$TMP/flaky-gather" RETRIES=2 >"$TMP/gi.out" 2>"$TMP/gi.err"
rc=$?
logs=("$TMP/gi/.slurm/logs"/task-2.*.out)
if [ $rc = 1 ] && [ "$(wc -l <"$TMP/gi.err")" = 1 ] && [ ${#logs[@]} = 1 ] &&
    grep -q "task 2 (passes 3 to 3) failed with exit 1, which a retry would not fix .*; log: " "$TMP/gi.err" &&
    ! grep -q 'resubmitting' "$TMP/gi.out"; then
    pass "a task that fails on bad input is not resubmitted: the render stops at once, exit 1"
else
    fail "a task failing on bad input" "exit $rc, logs ${logs[*]##*/}: $(cat "$TMP/gi.err")"
fi
rm -f "$TMP/fail-3"
sleep 1
queue_empty && pass "... and nothing of it left in the queue" || fail "queue after a stop on bad input" "$(squeue -h)"

# ---- the gather of a pass in shards, as array tasks after the pass's map and sorted queries:
# a shard task killed while it runs is resubmitted; every file of every pass is the local
# render's, byte for byte; a shard already landed is not submitted again ----
PS=("${PR[@]/PASSES=8/PASSES=4}" SHARDS=3)
all_same() { # all_same NAME DIR REFDIR: every file of every pass, and the images, byte for byte
    local f bad="" n=0
    for f in $(cd "$3" && ls pass-*/*.pm running.pm passes.txt image.exr image.png); do
        n=$((n + 1))
        cmp -s "$2/$f" "$3/$f" || bad+=" $f"
    done
    if [ -z "$bad" ] && [ $n -gt 4 ]; then pass "$1 ($n files)"; else fail "$1" "differ:${bad:- none, but $n files}"; fi
}
limit pipelines/render "$SCENE" "$TMP/locals" "${PS[@]}" THREADS=1 KEEP=all >"$TMP/locals.log" 2>&1 || fail "local render SHARDS=3" "$(tail -n 3 "$TMP/locals.log")"
limit pipelines/slurm "$SCENE" "$TMP/s" "${PS[@]}" "${SL[@]}" CPUS=2 THREADS=2 >"$TMP/s.log" 2>&1 &
pid=$!
# The shard task is killed for sure before it lands its shard: this script holds the lock a
# shard task takes to land (OUTDIR/.slurm/land.lock), kills a task that has made its shard and
# waits for the lock, and lets the lock go once the task is gone. (A task killed as it ends may
# land its shard all the same, and its job end CANCELLED: the checks after
# "a job that ends CANCELLED after it landed its work" below.)
for ((i = 0; i < 600; i++)); do # up to 60 s
    [ -d "$TMP/s/.slurm" ] && exec 9<>"$TMP/s/.slurm/land.lock" && flock -n 9 && break
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
done
killed=""
for ((i = 0; i < 600; i++)); do # up to 60 s
    j=$(squeue -h -r -n pm-shard -t RUNNING -o %i 2>/dev/null | head -n 1)
    if [ -n "$j" ] && grep -qs '^render: pass' "$TMP/s/.slurm/logs/shard-"*".${j#*_}.${j%_*}.out"; then
        scancel "$j" && killed=$j
        for ((k = 0; k < 300; k++)); do # up to 30 s: the task gone
            [ -z "$(squeue -h -r -j "$j" -t RUNNING,COMPLETING -o %i 2>/dev/null)" ] && break
            sleep 0.1
        done
        break
    fi
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
done
exec 9>&-
wait $pid
rc=$?
if [ $rc = 0 ] && [ -n "$killed" ] && grep -q "shard task .* ended without its passes.*resubmitting" "$TMP/s.log" &&
    grep -q "shard task(s), 3 a pass" "$TMP/s.log" && [ "$(ls "$TMP/s/.slurm/logs" | grep -c '^shard-')" -ge 13 ]; then
    pass "SHARDS=3: 3 shard tasks a pass; one killed while running ($killed) is resubmitted and the render finishes"
else
    fail "SHARDS=3 with a killed shard" "exit $rc, killed '${killed:-none}': $(tail -n 5 "$TMP/s.log")"
fi
all_same "SHARDS=3 through Slurm, CPUS=2 THREADS=2 = pipelines/render THREADS=1" "$TMP/s" "$TMP/locals"
# the task that lands a pass's last shard lands it as it is: no seal (the composite job's render
# reads every pass whole, by provenance)
nseal=0
for d in "$TMP/s"/pass-*; do [ -e "$d/.checked" ] && nseal=$((nseal + 1)); done
[ $nseal = 0 ] && pass "SHARDS=3: no pass carries a seal" || fail "SHARDS=3 seals" "$nseal passes carry a .checked"
# ... and a flipped byte in pass 2's map, its date put back, is found and the map remade (by
# the render of the running image while the jobs run, or by the composite job's): nothing is
# trusted by date or seal
cp "$TMP/s/pass-0002/photonmap.pm" "$TMP/map2.pm"
t=$(stat -c %.9Y "$TMP/s/pass-0002/photonmap.pm")
printf '\x55' | dd of="$TMP/s/pass-0002/photonmap.pm" bs=1 seek=$(($(stat -c %s "$TMP/map2.pm") - 100)) conv=notrunc status=none
touch -d "@$t" "$TMP/s/pass-0002/photonmap.pm"
# pass 3 back to the stage with shard 1 missing, as if its task had been killed: only it goes again
mv "$TMP/s/pass-0003" "$TMP/s/.slurm/stage/pass-0003" && rm "$TMP/s/.slurm/stage/pass-0003/indirect.1.pm" &&
    mv "$TMP/s/.slurm/done/pass-0003" "$TMP/s/.slurm/done/prep-pass-0003"
before=$(ls "$TMP/s/.slurm/logs" | grep -E '^(shard|task)-')
limit pipelines/slurm "$SCENE" "$TMP/s" "${PS[@]}" "${SL[@]}" CPUS=2 THREADS=2 >"$TMP/s2.log" 2>&1
rc=$?
if [ $rc = 0 ] && grep -q "3 made before; submitted 1 task(s)" "$TMP/s2.log" &&
    new=$(ls "$TMP/s/.slurm/logs" | grep -E '^(shard|task)-' | grep -vxF "$before") &&
    [[ $new =~ ^shard-1\.1\.[0-9]+\.out$ ]] && [ -e "$TMP/s/pass-0003/indirect.1.pm" ]; then
    pass "a pass's landed shards are not resubmitted: one shard task, for the missing shard"
else
    fail "landed shards kept" "exit $rc: $(head -n 1 "$TMP/s2.log"); new logs: $(echo $new)"
fi
clog=$(ls -t "$TMP/s/.slurm/logs"/composite.*.out | head -n 1)
if [ $rc = 0 ] && cmp -s "$TMP/s/pass-0002/photonmap.pm" "$TMP/map2.pm"; then
    pass "a flipped byte in a landed pass's map (date put back) is found and the map remade"
else
    fail "composite job and a flipped map" "$(grep -m 2 'corrupt\|  2 ' "$clog")"
fi
all_same "after the one shard, the same files as pipelines/render's" "$TMP/s" "$TMP/locals"

# ---- any number of CPUs a task, the same bytes: CPUS=1 (one thread a stage) against the
# CPUS=2 THREADS=2 render above, every pass file included ----
limit pipelines/slurm "$SCENE" "$TMP/s1" "${PS[@]}" "${SL[@]}" CPUS=1 >"$TMP/s1.log" 2>&1 || fail "CPUS=1 render" "$(tail -n 3 "$TMP/s1.log")"
all_same "CPUS=1 and CPUS=2 THREADS=2 on the cluster: the same bytes" "$TMP/s1" "$TMP/s"

# ---- a job that ends CANCELLED after it landed its work (a scancel that reaches the controller
# as the job ends): Slurm never starts the jobs that wait for it (afterok; the reason
# DependencyNeverSatisfied), and pipelines/slurm resubmits them after the jobs not done rather
# than wait for ever. An sbatch first on PATH runs the jobs named as $TMP/late-name says through
# late-cancel: slurm-task, then the array task given in $TMP/late-once (once) cancels its job ----
mkdir -p "$TMP/fakebin"
cat >"$TMP/late-cancel" <<EOF
#!/usr/bin/env bash
bash "$PWD/pipelines/lib/slurm-task" "\$@"
rc=\$?
if [ \$rc = 0 ] && [ "\${SLURM_ARRAY_TASK_ID:-}" = "\$(cat "$TMP/late-once" 2>/dev/null)" ] && rm "$TMP/late-once" 2>/dev/null; then
    echo "late-cancel: job \${SLURM_ARRAY_JOB_ID}_\$SLURM_ARRAY_TASK_ID cancels itself after its work"
    scancel "\${SLURM_ARRAY_JOB_ID}_\$SLURM_ARRAY_TASK_ID"
    sleep 60
fi
exit \$rc
EOF
cat >"$TMP/fakebin/sbatch" <<EOF
#!/usr/bin/env bash
a=()
for x in "\$@"; do
    [[ \$x == */pipelines/lib/slurm-task ]] && [[ " \$* " == *" -J \$(cat "$TMP/late-name") "* ]] && x=$TMP/late-cancel
    a+=("\$x")
done
exec $(command -v sbatch) "\${a[@]}"
EOF
chmod +x "$TMP/fakebin/sbatch"
late_cancel() { # late_cancel NAME I CHECK DIR PATTERN ARG...: pipelines/slurm into DIR, the array
    # task I of a job named NAME cancelled after its work; PATTERN names the job resubmitted
    local name=$1 check=$3 dir=$4 pat=$5 rc
    echo "$name" >"$TMP/late-name"
    echo "$2" >"$TMP/late-once"
    shift 5
    PATH="$TMP/fakebin:$PATH" limit pipelines/slurm "$SCENE" "$dir" "$@" "${SL[@]}" >"$dir.log" 2>&1
    rc=$?
    if [ $rc = 0 ] && [ ! -e "$TMP/late-once" ] &&
        grep -q "$pat waits on a job that ended without success although that job's work is done (Slurm: DependencyNeverSatisfied); resubmitting" "$dir.log"; then
        pass "$check"
    else
        fail "$check" "exit $rc: $(grep -v '^  ' "$dir.log" | tail -n 4)"
    fi
}
late_cancel pm-shard 0 "SHARDS=3: a shard job of pass 1 ends CANCELLED after it landed its shard; the pass task waiting for it is resubmitted and the render ends" \
    "$TMP/sc" "task 1 (passes 2 to 4, the gather inputs)" "${PS[@]}" CPUS=2
all_same "... the same files as pipelines/render's" "$TMP/sc" "$TMP/locals"
late_cancel pm-pass 3 "the job of task 3 ends CANCELLED after it landed pass 4; the composite job waiting for it is resubmitted and the render ends" \
    "$TMP/pc" "the composite job" "${PR[@]}"
same_image "... the image is pipelines/render's" "$TMP/pc" "$TMP/local"

# ---- the controller lost while a render waits: pipelines/slurm stops once squeue has failed for
# QUEUE_WAIT seconds, in one line, exit 3 (a second cluster, stopped under the render) ----
if tests/slurm/cluster start "$TMP/cl2" >/dev/null 2>"$TMP/cl2.err"; then
    SLURM_CONF=$TMP/cl2/slurm.conf limit pipelines/slurm "$SCENE" "$TMP/q" "${PR[@]}" "${SL[@]}" QUEUE_WAIT=2 >"$TMP/q.out" 2>"$TMP/q.err" &
    pid=$!
    for ((i = 0; i < 600; i++)); do # up to 60 s: its jobs submitted
        grep -qs '^slurm: .* submitted ' "$TMP/q.out" && break
        kill -0 $pid 2>/dev/null || break
        sleep 0.1
    done
    tests/slurm/cluster stop "$TMP/cl2"
    wait $pid
    rc=$?
    if [ $rc = 3 ] && [ "$(wc -l <"$TMP/q.err")" = 1 ] && grep -q "^slurm: cannot read the queue for 2 s (squeue: .*); this render's jobs may still be queued" "$TMP/q.err"; then
        pass "the controller gone while the render waits: it stops after QUEUE_WAIT=2 s, one line, exit 3"
    else
        fail "the controller gone" "exit $rc: $(tail -n 2 "$TMP/q.err")"
    fi
else
    fail "a second cluster, for the controller gone" "$(tail -n 1 "$TMP/cl2.err")"
fi

# ---- TARGET_ERROR and TIME: passes in waves ----
PT=("${PR[@]:0:5}") # PR without PASSES
[ "${PT[*]}" = "WIDTH=48 HEIGHT=48 PHOTONS=20000 PRIMARY=4 SPP=4" ] || fail "test set-up" "PT is '${PT[*]}'"
limit pipelines/render "$SCENE" "$TMP/locale" "${PT[@]}" PASSES=12 TARGET_ERROR=0.2 KEEP=all >"$TMP/locale.log" 2>&1
limit pipelines/slurm "$SCENE" "$TMP/e" "${PT[@]}" PASSES=12 "${SL[@]}" TARGET_ERROR=0.2 >"$TMP/e.log" 2>&1
rc=$?
n=$(wc -l <"$TMP/locale/passes.txt")
if [ $rc = 0 ] && grep -q "stopped by TARGET_ERROR=0.2" "$TMP/locale.log" && [ "$n" -ge 3 ] && [ "$n" -lt 12 ] &&
    grep -q "stopped submitting (TARGET_ERROR=0.2 after pass $n)" "$TMP/e.log"; then
    pass "TARGET_ERROR=0.2: the cluster stops after pass $n, where pipelines/render stops"
else
    fail "TARGET_ERROR on the cluster" "exit $rc, local $n passes: $(grep -v '^  ' "$TMP/e.log" | tail -n 3)"
fi
same_image "TARGET_ERROR: the image is pipelines/render's" "$TMP/e" "$TMP/locale"
t0=$(date +%s)
limit pipelines/slurm "$SCENE" "$TMP/t" "${PT[@]}" "${SL[@]}" TIME=6 >"$TMP/t.log" 2>&1
rc=$?
t1=$(date +%s)
n=$(wc -l 2>/dev/null <"$TMP/t/passes.txt")
last=$(grep -o 'stopped submitting (TIME=6); composite of passes 1 to [0-9]*' "$TMP/t.log")
limit pipelines/render "$SCENE" "$TMP/localt" "${PT[@]}" PASSES="${n:-2}" KEEP=all >/dev/null 2>&1
# the passes' part: from the start to the line that says submitting stopped, at most the budget
# and one wave's overrun (slurm prints the time on each line)
spent=$(sed -n 's/^slurm: \([0-9.]*\) s: stopped submitting.*/\1/p' "$TMP/t.log")
if [ $rc = 0 ] && [ -n "$last" ] && [ "${last##* }" = "$n" ] && [ "$n" -ge 3 ] &&
    awk -v s="$spent" 'BEGIN { exit !(s > 3 && s < 12) }'; then
    pass "TIME=6: passes submitted in waves for ${spent} s ($n passes), then composite ($((t1 - t0)) s in all)"
else
    fail "TIME on the cluster" "exit $rc, $n passes, '$last', stopped at '${spent}': $(grep -v '^  ' "$TMP/t.log" | tail -n 3)"
fi
same_image "TIME=6: the image is pipelines/render PASSES=$n's" "$TMP/t" "$TMP/localt"

# ---- KEEP=image: the image and stats.json alone, and the logs ----
limit pipelines/slurm "$SCENE" "$TMP/k" "${PT[@]}" PASSES=3 "${SL[@]}" KEEP=image >"$TMP/k.log" 2>&1
rc=$?
limit pipelines/render "$SCENE" "$TMP/localk" "${PT[@]}" PASSES=3 KEEP=all >/dev/null 2>&1
left=$(cd "$TMP/k" && find . -mindepth 1 ! -path './.slurm/logs/*' | sort | tr '\n' ' ')
if [ $rc = 0 ] && [ "$left" = "./.lock ./.slurm ./.slurm/lock ./.slurm/logs ./image.exr ./image.png ./stats.json " ] &&
    cmp -s "$TMP/k/image.exr" "$TMP/localk/image.exr"; then
    pass "KEEP=image: OUTDIR holds the image, stats.json and the logs; the image is pipelines/render's"
else
    fail "KEEP=image on the cluster" "exit $rc, left: $left"
fi

# ---- bad input: refused before anything is submitted ----
before=$(squeue -h -o %i | wc -l)
expect_error "unknown partition" "unknown partition 'nosuch'" limit pipelines/slurm "$SCENE" "$TMP/h" "${PR[@]}" PARTITION=nosuch
mkdir -p "$TMP/nopath"
for f in /usr/bin/* /bin/*; do
    case "${f##*/}" in sbatch | squeue | scancel | sinfo | srun | scontrol | sacct) continue ;; esac
    [ -e "$TMP/nopath/${f##*/}" ] || ln -s "$f" "$TMP/nopath/${f##*/}"
done
expect_error "no sbatch on PATH" "no 'sbatch' on PATH" limit env PATH="$TMP/nopath" pipelines/slurm "$SCENE" "$TMP/h" "${PR[@]}"
# an OUTDIR the nodes do not see: a tmpfs mounted in a mount namespace of the submitting side alone
mkdir -p "$TMP/private"
expect_error "an OUTDIR the tasks cannot see" "OUTDIR must be on a filesystem the compute nodes share" \
    limit unshare -m --propagation private bash -c 'mount -t tmpfs pmtk "$1" && shift && exec "$@"' - "$TMP/private" \
    pipelines/slurm "$SCENE" "$TMP/private/out" "${PR[@]}"
expect_exit "PASSES, TIME and TARGET_ERROR all missing" 2 limit pipelines/slurm "$SCENE" "$TMP/h" WIDTH=48
expect_exit "a bad TIME" 2 limit pipelines/slurm "$SCENE" "$TMP/h" TIME=soon
expect_exit "TARGET_ERROR=0" 2 limit pipelines/slurm "$SCENE" "$TMP/h" TARGET_ERROR=0
expect_exit "a bad KEEP" 2 limit pipelines/slurm "$SCENE" "$TMP/h" PASSES=4 KEEP=most
expect_exit "TIME=nan (pm-render --check-settings)" 2 limit pipelines/slurm "$SCENE" "$TMP/h" TIME=nan
expect_exit "a value a stage refuses (RADIUS=-1), before anything is submitted" 2 limit pipelines/slurm "$SCENE" "$TMP/h" PASSES=4 RADIUS=-1
[ "$(wc -l <"$TMP/err")" = 1 ] && grep -q "^slurm: bad value for RADIUS '-1': " "$TMP/err" &&
    pass "... in one line naming the value" || fail "RADIUS=-1 message" "$(head -c 300 "$TMP/err")"
expect_exit "WIDTHS=variable with passes" 2 limit pipelines/slurm "$SCENE" "$TMP/h" PASSES=4 WIDTHS=variable
expect_exit "PASS_RANGE is pipelines/slurm's own" 2 limit pipelines/slurm "$SCENE" "$TMP/h" PASSES=4 PASS_RANGE=1:2
expect_exit "unknown parameter" 2 limit pipelines/slurm "$SCENE" "$TMP/h" PASSES=4 NOSUCH=1
[ ! -e "$TMP/h" ] && pass "bad input: no OUTDIR made" || fail "bad input" "'$TMP/h' was made"
[ "$(squeue -h -o %i | wc -l)" = "$before" ] && [ "$(squeue -h -o %i | wc -l)" = 0 ] &&
    pass "bad input: nothing submitted" || fail "bad input" "jobs in the queue: $(squeue -h)"

echo "slurm: $PASS passed, $FAIL failed"
[ "$FAIL" = 0 ]
