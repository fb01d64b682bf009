# trace-gather-points.sh: gather points and direct light on golden files, analytic scenes
# and bad inputs. No timing here: speed is tests/bench/30-trace-gather-points.sh.
# programs: composite trace-gather-points
G=tests/golden
TS=tests/scenes
T=$BIN/trace-gather-points
CORNELL=scenes/cornell-box/scene.json

# records of a pm-info -r listing (lines that start with the record index)
records() { "$BIN/pm-info" -r "$1" | grep -E '^[0-9]'; }
# the bytes after the header, without the checksum (which covers the header's COMMAND line)
payload() {
    local off
    off=$(sed '/^$/q' "$1" | wc -c) # header text up to and including the empty line
    tail -c +$((off + 1)) "$1" | head -c -8
}
same_payload() { cmp -s <(payload "$1") <(payload "$2") && "$BIN/pm-compare" "$1" "$2" >/dev/null 2>&1; }

# ---- golden files: the Cornell box at 16x16, spp 8, seed 1 ----
# --strata hit: each hit's rays stratified alone, the files of before pixel strata (the golden
# files the other stages' tests read); the default, pixel strata, has golden files of its own.
"$T" -q "$CORNELL" --width 16 --height 16 --spp 8 --seed 1 --strata hit -o "$TMP/q.pm" --direct "$TMP/d.pm" 2>"$TMP/err"
if [ $? = 0 ]; then pass "cornell 16x16 spp 8 runs"; else fail "cornell 16x16 spp 8 runs" "$(cat "$TMP/err")"; fi
"$T" -q "$CORNELL" --width 16 --height 16 --spp 8 --seed 1 -o "$TMP/qp.pm" --direct "$TMP/dp.pm" 2>"$TMP/err"
if [ $? = 0 ]; then pass "cornell 16x16 spp 8 pixel strata runs"; else fail "cornell 16x16 spp 8 pixel strata runs" "$(cat "$TMP/err")"; fi
expect_exit "cornell queries with pixel strata match their golden file" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-6 "$G/gather-cornell-16x16-spp8-pixel.pm" "$TMP/qp.pm"
expect_exit "cornell direct radiance with pixel strata matches its golden file" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-7 "$G/direct-cornell-16x16-pixel.pm" "$TMP/dp.pm"
if "$BIN/pm-info" "$TMP/qp.pm" | grep -qx 'strata=pixel' && "$BIN/pm-info" "$TMP/dp.pm" | grep -qx 'strata=pixel' &&
    ! "$BIN/pm-info" "$TMP/q.pm" | grep -q '^strata='; then
    pass "pixel strata are named in the headers (strata=pixel), --strata hit's files are as before"
else
    fail "strata header" "$("$BIN/pm-info" "$TMP/qp.pm" | grep strata)"
fi
# Float channels within 1e-5 relative: Embree may round a hit distance differently on another CPU
# (its AVX2 and AVX-512 kernels). A position's rounding scales with the distance travelled, not
# with the coordinate, so a coordinate near 0 gets an absolute bound: 1e-6 m, a few ulps of the
# 0.56 m box (measured: 2.1e-7 m between two EPYC machines).
expect_exit "cornell queries match the golden file" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-6 "$G/gather-cornell-16x16-spp8.pm" "$TMP/q.pm"
expect_exit "cornell direct radiance matches the golden file" 0 \
    "$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-7 "$G/direct-cornell-16x16.pm" "$TMP/d.pm"
"$BIN/pm-info" "$TMP/q.pm" >"$TMP/hdr" 2>&1
if grep -q '^CHANNELS=position normal weight pixel$' "$TMP/hdr" && grep -q '^materials=1$' "$TMP/hdr" &&
    grep -q '^SCENE=cornell-box xxh3:' "$TMP/hdr" && grep -q '^spp=8$' "$TMP/hdr" && grep -q '^seed=1$' "$TMP/hdr" &&
    grep -q '^COMMAND=trace-gather-points ' "$TMP/hdr" && grep -q '^width=16$' "$TMP/hdr"; then
    pass "a Lambertian scene's queries have no material or direction channel, and carry provenance"
else
    fail "cornell queries header" "$(head -c 600 "$TMP/hdr")"
fi
grep -q '^component=direct$' <("$BIN/pm-info" "$TMP/d.pm") && pass "the direct buffer says component=direct" ||
    fail "direct component" "$("$BIN/pm-info" "$TMP/d.pm" | head -20)"

# ---- determinism: any thread count, any schedule, the same records (the headers differ
# only in the COMMAND line: the output names and --schedule; --threads is not recorded,
# tests/stage/passes.sh compares whole renders' bytes across THREADS) ----
for args in "--spp 16" "--spp 8 --primary 3" "--mode direct-vis"; do
    "$T" -q "$CORNELL" --width 40 --height 24 $args --threads 1 -o "$TMP/t1.pm" --direct "$TMP/t1d.pm"
    "$T" -q "$CORNELL" --width 40 --height 24 $args --threads 2 -o "$TMP/t2.pm" --direct "$TMP/t2d.pm"
    "$T" -q "$CORNELL" --width 40 --height 24 $args --threads 2 --schedule tiles -o "$TMP/t3.pm" --direct "$TMP/t3d.pm"
    "$T" -q "$CORNELL" --width 40 --height 24 $args --threads 2 --schedule dynamic -o "$TMP/t4.pm"
    if same_payload "$TMP/t1.pm" "$TMP/t2.pm" && same_payload "$TMP/t1d.pm" "$TMP/t2d.pm" &&
        same_payload "$TMP/t1.pm" "$TMP/t3.pm" && same_payload "$TMP/t1d.pm" "$TMP/t3d.pm" &&
        same_payload "$TMP/t1.pm" "$TMP/t4.pm" && [ "$(payload "$TMP/t1.pm" | wc -c)" -gt 1000 ]; then
        pass "$args: --threads 1 and 2, every --schedule: byte-identical records"
    else
        fail "$args: threads/schedules identical" "outputs differ"
    fi
done
# secondary direct light (the textured atrium's sun and sky sampled at the gather points): the
# same records and direct buffer for any thread count and schedule, the --no-queries buffer the
# full run's, and a direct buffer other than the run's without it
SKY=scenes/atrium/textured.json
"$T" -q "$SKY" --width 40 --height 24 --spp 8 --secondary-direct --threads 1 -o "$TMP/s1.pm" --direct "$TMP/s1d.pm"
"$T" -q "$SKY" --width 40 --height 24 --spp 8 --secondary-direct --threads 2 --schedule dynamic -o "$TMP/s2.pm" \
    --direct "$TMP/s2d.pm"
"$T" -q "$SKY" --width 40 --height 24 --spp 8 --secondary-direct --threads 2 --no-queries --direct "$TMP/s3d.pm"
"$T" -q "$SKY" --width 40 --height 24 --spp 8 --threads 2 -o "$TMP/s4.pm" --direct "$TMP/s4d.pm"
if same_payload "$TMP/s1.pm" "$TMP/s2.pm" && same_payload "$TMP/s1d.pm" "$TMP/s2d.pm" &&
    same_payload "$TMP/s1d.pm" "$TMP/s3d.pm" && cmp -s <(payload "$TMP/s1.pm") <(payload "$TMP/s4.pm") &&
    ! cmp -s <(payload "$TMP/s1d.pm") <(payload "$TMP/s4d.pm") && "$BIN/pm-info" "$TMP/s1d.pm" | grep -qx 'secondary_direct=2'; then
    pass "--secondary-direct: threads and schedules identical, --no-queries the same buffer, the queries unchanged"
else
    fail "--secondary-direct determinism" "outputs differ (or the direct buffer did not change)"
fi
# records spilled to a temporary file (--spool-mem 0) come out the same
"$T" -q "$CORNELL" --width 40 --height 24 --spp 16 --spool-mem 0 --stats "$TMP/sp.json" -o "$TMP/sp.pm"
"$T" -q "$CORNELL" --width 40 --height 24 --spp 16 -o "$TMP/mem.pm"
if grep -q '"spooled_to_file": 1' "$TMP/sp.json" && same_payload "$TMP/sp.pm" "$TMP/mem.pm" && [ -z "$(ls -A "$TMP" | grep '^\.sp')" ]; then
    pass "records spooled through a temporary file are the same, and no file is left"
else
    fail "--spool-mem 0" "$(cat "$TMP/sp.json" 2>&1 | head -c 300)"
fi
# queries of one pixel are contiguous and pixels come in order
"$T" -q "$CORNELL" --width 40 --height 24 --spp 8 -o "$TMP/o.pm"
if records "$TMP/o.pm" | awk '{ if ($11 < last) bad = 1; last = $11 } END { exit bad }'; then
    pass "queries are in pixel order"
else
    fail "queries in pixel order" "a pixel index decreases"
fi

# ---- closed box: no ray escapes, so each pixel has spp queries summing to kd * kd / pi ----
"$T" -q "$TS/closed-box/scene.json" --spp 16 -o "$TMP/cb.pm" --direct "$TMP/cbd.pm"
records "$TMP/cb.pm" | awk '
    { n[$11]++; r[$11] += $8; g[$11] += $9; b[$11] += $10; if (($6 != 0) + ($7 != 0) + ($5 != 0) != 1) bad = "normal " $0 }
    END {
        pi = 3.14159265358979; er = 0.25 / pi; eg = 0.36 / pi; eb = 0.49 / pi
        for (p = 0; p < 64; p++) {
            if (n[p] != 16) { print "pixel " p " has " n[p] " queries, expected 16"; exit 1 }
            if (r[p] / er - 1 > 1e-5 || 1 - r[p] / er > 1e-5 || g[p] / eg - 1 > 1e-5 || 1 - g[p] / eg > 1e-5 ||
                b[p] / eb - 1 > 1e-5 || 1 - b[p] / eb > 1e-5) {
                printf "pixel %d weights sum to %.9g %.9g %.9g, expected %.9g %.9g %.9g\n", p, r[p], g[p], b[p], er, eg, eb; exit 1
            }
        }
        if (bad != "") { print bad; exit 1 }
    }' >"$TMP/why"
if [ $? = 0 ]; then pass "closed box: every pixel has 16 queries and its weights sum to kd * kd/pi"; else fail "closed box weight sums" "$(cat "$TMP/why")"; fi
# the same with 3 jittered primary rays per pixel: 48 queries, the same sum
"$T" -q "$TS/closed-box/scene.json" --spp 16 --primary 3 -o "$TMP/cb3.pm"
records "$TMP/cb3.pm" | awk '{ n[$11]++; r[$11] += $8 } END { for (p = 0; p < 64; p++) if (n[p] != 48 || r[p] / (0.25 / 3.14159265358979) - 1 > 1e-5 || 1 - r[p] / (0.25 / 3.14159265358979) > 1e-5) { print "pixel " p ": " n[p] " queries, red sum " r[p]; exit 1 } }' >"$TMP/why"
if [ $? = 0 ]; then pass "closed box, --primary 3: 48 queries per pixel, same weight sum"; else fail "closed box --primary 3" "$(cat "$TMP/why")"; fi
# direct-vis: the primary hits are the queries, one per pixel, weight kd/pi
"$T" -q "$TS/closed-box/scene.json" --mode direct-vis -o "$TMP/dv.pm"
records "$TMP/dv.pm" | awk '{ n++; if ($11 != n - 1 || $8 - 0.5 / 3.14159265358979 > 1e-7 || 0.5 / 3.14159265358979 - $8 > 1e-7) bad = $0 } END { if (n != 64 || bad != "") { print n " queries; " bad; exit 1 } }' >"$TMP/why"
if [ $? = 0 ]; then pass "direct-vis: one query per pixel at the primary hit, weight kd/pi"; else fail "direct-vis" "$(cat "$TMP/why")"; fi
grep -q '^mode=direct-vis$' <("$BIN/pm-info" "$TMP/dv.pm") && pass "direct-vis says so in the header" || fail "direct-vis header" "no mode=direct-vis"

# ---- glossy scene: direction and material channels, the full material table ----
"$T" -q "$TS/glossy-box/scene.json" --spp 8 -o "$TMP/gb.pm"
"$BIN/pm-info" "$TMP/gb.pm" >"$TMP/hdr" 2>&1
if grep -q '^CHANNELS=position normal weight pixel material direction$' "$TMP/hdr" && grep -q '^materials=2$' "$TMP/hdr" &&
    grep -q '^material.1=gloss kd .* ks 0.5 0.5 0.5 ns 20$' "$TMP/hdr"; then
    pass "a glossy scene's queries carry material and direction"
else
    fail "glossy queries" "$(head -c 600 "$TMP/hdr")"
fi
# direction points back along the secondary ray, to the side the normal faces
records "$TMP/gb.pm" | awk '{ d = $5 * $13 + $6 * $14 + $7 * $15; if (d <= 0) { print "record " $1 ": normal . direction = " d; exit 1 } }' >"$TMP/why"
if [ $? = 0 ]; then pass "query normals face the direction the query is seen from"; else fail "normal side" "$(cat "$TMP/why")"; fi

# ---- sky: no query and zero direct radiance ----
"$T" -q "$TS/open-floor/scene.json" --spp 8 -o "$TMP/of.pm" --direct "$TMP/ofd.pm"
nsky=$(records "$TMP/of.pm" | awk '$11 < 24' | wc -l)
nground=$(records "$TMP/of.pm" | awk '$11 >= 32' | wc -l)
dsky=$(records "$TMP/ofd.pm" | awk '$1 < 24 && ($2 != 0 || $3 != 0 || $4 != 0)' | wc -l)
dground=$(records "$TMP/ofd.pm" | awk '$1 >= 40 && $2 > 0' | wc -l)
if [ "$nsky" = 0 ] && [ "$dsky" = 0 ] && [ "$nground" -gt 0 ] && [ "$dground" = 24 ]; then
    pass "pixels that see only sky have no query and zero direct radiance"
else
    fail "sky pixels" "$nsky sky queries, $dsky non-zero sky direct values, $nground ground queries, $dground lit ground pixels"
fi

# ---- analytic direct light: kd/pi * I / r^2 with I = pi W/sr at r = 1 m is kd ----
"$T" -q "$TS/lit-floor/scene.json" --pixel center -o "$TMP/lf.pm" --direct "$TMP/lfd.pm"
v=$(records "$TMP/lfd.pm" | awk '{ printf "%.6f %.6f %.6f", $2, $3, $4 }')
if [ "$v" = "0.500000 0.250000 0.125000" ]; then pass "a point light of pi W/sr at 1 m gives direct radiance kd"; else fail "analytic point light" "got '$v', expected 0.5 0.25 0.125"; fi

# ---- bad inputs: one line, the class's exit status, no output ----
expect_error "missing scene" "cannot open scene '/nonexistent/scene.json'" "$T" /nonexistent/scene.json -o "$TMP/x.pm"
[ ! -e "$TMP/x.pm" ] && pass "... and no output file" || fail "missing scene output" "x.pm exists"
"$T" "$CORNELL" --spp 6 -o "$TMP/x.pm" --direct "$TMP/xd.pm" >"$TMP/out" 2>"$TMP/err"
status=$?
if [ $status = 2 ] && [ "$(wc -l <"$TMP/err")" = 1 ] && grep -q -- '--spp 6 is not a multiple of 4' "$TMP/err" &&
    [ ! -e "$TMP/x.pm" ] && [ ! -e "$TMP/xd.pm" ]; then
    pass "--spp 6: one line, usage status 2, no output"
else
    fail "--spp 6" "exit $status: $(cat "$TMP/err")"
fi
expect_exit "--spp -4 is out of range" 2 "$T" "$CORNELL" --spp -4 -o "$TMP/x.pm"
expect_exit "--spp abc is not a number" 2 "$T" "$CORNELL" --spp abc -o "$TMP/x.pm"
expect_exit "--mode other is not a mode" 2 "$T" "$CORNELL" --mode other -o "$TMP/x.pm"
expect_exit "--isa sparc is not an isa" 2 "$T" "$CORNELL" --isa sparc -o "$TMP/x.pm"
expect_exit "-o and --direct both stdout" 2 "$T" "$CORNELL" --direct -
expect_error "output into a missing folder" "cannot create output '/nonexistent/q.pm'" "$T" "$CORNELL" -o /nonexistent/q.pm
mkdir -p "$TMP/s5"
cp "$TS/closed-box/box.obj" "$TS/closed-box/box.mtl" "$TMP/s5/"
sed 's/"spp": 16/"spp": 5/' "$TS/closed-box/scene.json" >"$TMP/s5/scene.json"
expect_error "a scene whose render.spp is not a multiple of 4" "render.spp 5 is not a positive multiple of 4" \
    "$T" "$TMP/s5/scene.json" -o "$TMP/x.pm"
[ ! -e "$TMP/x.pm" ] && pass "... and no output file" || fail "bad scene spp output" "x.pm exists"

# ---- area lights: light samples and secondary rays share the direct light (MIS) ----
# In the furnace (tests/scenes/make-analytic.sh: a closed sphere whose every facet emits Le = 1
# with albedo 0.5) the direct buffer is Le + rho Le = 1.5 at every pixel. Light samples alone,
# uniform by area, have a heavy tail next to a facet's edge (one sample a pixel: RMS 4%, worst
# pixel 1.43); weighted against the cosine-distributed secondary rays by the power heuristic
# (docs/programs/trace-gather-points.md), the RMS must be below 2% and every pixel within 20%
# (measured: RMS 0.24%, worst 0.98).
source tests/scenes/make-analytic.sh
make_furnace "$TMP/fu" 1 0.5
"$T" "$TMP/fu/scene.json" -q --spp 16 --light-samples 1 -o "$TMP/fq.pm" --direct "$TMP/fd.pm" &&
    "$BIN/composite" -q "$TMP/fd.pm" -o "$TMP/fd.exr" && "$BUILD/tests/pm-exrdump" "$TMP/fd.exr" >"$TMP/fd.txt"
why=$(awk '$1 != "size" { for (c = 3; c <= 5; c++) { r = $c / 1.5; n++; ss += (r - 1) ^ 2; if (r > mx || n == 1) mx = r; if (r < mn || n == 1) mn = r } }
    END { printf "rms %.4f, min %.4f, max %.4f over %d values", sqrt(ss / n), mn, mx, n; exit !(n == 3072 && ss / n < 0.02 ^ 2 && mn > 0.8 && mx < 1.2) }' "$TMP/fd.txt")
[ $? = 0 ] && pass "furnace, one light sample a pixel: the MIS direct buffer is Le + rho Le without the light samples' tail ($why)" ||
    fail "furnace direct buffer with MIS" "$why"

# ---- failures while rows are traced reach stderr whole ----
# Inside the parallel row loop a row can fail only for memory: each worker grows its ray buffers
# and the row's records there. A 65536-pixel row at 65536 spp needs 2^32 secondary rays (16 GiB
# per ray array), which an address-space limit of 8 GB refuses at once, on every row and thread.
# The message of the lowest row must come out whole whichever thread traced it: with
# --schedule dynamic any thread may take row 0, and a message set on a worker used to be lost
# with its thread. Repeated to catch the race. Not under AddressSanitizer, whose shadow memory
# does not fit an address-space limit.
if ldd "$T" 2>/dev/null | grep -q libasan; then
    skip "row failures on worker threads" "AddressSanitizer build: no address-space limit"
elif ! (ulimit -v 8000000) 2>/dev/null; then
    skip "row failures on worker threads" "ulimit -v is not available"
else
    want="trace-gather-points: out of memory for the rays of row 0: 65536 primary, 262144 shadow, 4294967296 secondary (nomem error)"
    bad=0 last=""
    for i in $(seq 1 10); do
        for sched in dynamic interleave; do
            (ulimit -v 8000000 && exec "$T" -q "$CORNELL" --width 65536 --height 8 --spp 65536 --threads 2 \
                --schedule $sched -o "$TMP/oom.pm" --direct "$TMP/oomd.pm") >/dev/null 2>"$TMP/oom.err"
            st=$?
            if [ "$st" != 3 ] || [ "$(cat "$TMP/oom.err")" != "$want" ] || [ -e "$TMP/oom.pm" ] || [ -e "$TMP/oomd.pm" ]; then
                bad=$((bad + 1)) last="--schedule $sched: exit $st: $(cat "$TMP/oom.err")"
            fi
        done
    done
    if [ "$bad" = 0 ]; then
        pass "rows out of memory on two threads: row 0's whole message, status 3 (nomem), no output, 20 of 20 runs"
    else
        fail "row failure message" "$bad of 20 runs wrong; last: $last"
    fi
fi
# A band's records go to the spool on one of the threads while the others trace the next band;
# a spill file that cannot grow (here a file-size limit, as on a full disk) in the first band's,
# on a worker, stops the stage with the file's folder and the reason.
mkdir -p "$TMP/spill"
(trap '' XFSZ && ulimit -f 64 && exec "$T" -q "$CORNELL" --width 40 --height 80 --spp 16 --spool-mem 0 --threads 2 \
    -o "$TMP/spill/q.pm") >/dev/null 2>"$TMP/spill.err"
st=$?
if [ "$st" = 3 ] && [ "$(cat "$TMP/spill.err")" = "trace-gather-points: cannot write the spool file in '$TMP/spill': File too large (io error)" ] &&
    [ -z "$(ls -A "$TMP/spill")" ]; then
    pass "a spill file that cannot grow: one whole line, status 3 (io), nothing left in the output folder"
else
    fail "spool write failure" "exit $st: $(cat "$TMP/spill.err"); left: $(ls -A "$TMP/spill")"
fi
