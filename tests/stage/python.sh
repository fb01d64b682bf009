# python.sh: the pmtk Python package (python/pmtk, docs/python.md, issue 31 item 2): every format's
# golden files read into numpy and written back byte for byte, version 1 included; files made in
# Python are read by the programs; bad files give one line naming the file and the value, as
# pm-info does; the writer refuses what a reader would; the programs run from Python with their
# exit class; a 1M-record photon map read in under 0.1 s (reported; checked against a loose 1 s
# here, since the machine is shared); libpmtk through ctypes when it is built.
# programs: libpmtk build-photonmap trace-gather-points pm-info
PY=/usr/bin/python3
export PYTHONPATH=$PWD/python PMTK_BIN=$BIN
G=tests/golden
TG=$BUILD/tests/pm-testgen

if ! "$PY" -c 'import numpy, xxhash' 2>"$TMP/err"; then
    skip "python: pmtk package" "no numpy or xxhash for $PY (apt-get install python3-numpy python3-xxhash): $(tail -n 1 "$TMP/err")"
    return 0 2>/dev/null || exit 0
fi

# ---- every golden file: read, checked, written back the same bytes ----
for f in $G/photons-*.pm $G/photonmap-*.pm $G/queries-*.pm $G/radiance-*.pm $G/v1/*.pm $G/*-cornell*.pm; do
    b=$(basename "$f")
    if "$PY" -c 'import pmtk, sys; pmtk.write(sys.argv[2], pmtk.read(sys.argv[1]))' "$f" "$TMP/rt-$b" 2>"$TMP/err"; then
        expect_same "python: $f read and written back is byte-identical" "$f" "$TMP/rt-$b"
    else
        fail "python: $f round trip" "$(head -c 300 "$TMP/err")"
    fi
done

# an aov file (trace-gather-points --aov) too
"$BIN/trace-gather-points" -q tests/scenes/closed-box/scene.json -o "$TMP/aq.pm" --aov "$TMP/aov.pm" 2>"$TMP/err"
"$PY" -c '
import sys, numpy as np, pmtk
a = pmtk.read(sys.argv[1])
assert a.format == "aov" and a.records["albedo"].shape == (64, 3) and np.allclose(a.records["albedo"], [0.5, 0.6, 0.7])
pmtk.write(sys.argv[2], a)' "$TMP/aov.pm" "$TMP/aov-rt.pm" 2>>"$TMP/err" &&
    expect_same "python: an aov file reads (albedo the box kd) and writes back the same bytes" "$TMP/aov.pm" "$TMP/aov-rt.pm" ||
    fail "python: aov file" "$(head -c 300 "$TMP/err")"

# ---- the records are the values pm-info prints ----
for f in photons photonmap queries radiance; do
    "$PY" - "$G/$f-all.pm" >"$TMP/py.txt" 2>"$TMP/err" <<'EOF'
import sys, numpy as np, pmtk
m = pmtk.read(sys.argv[1])
for r in m.records:
    print(" ".join(repr(float(x)) if isinstance(x, np.floating) else str(int(x)) for c in m.channels for x in np.atleast_1d(r[c])))
EOF
    # pm-info -r prints each value with its shortest round-trip spelling; compare as numbers
    # (pm-info prints a map's node decoded, as split and child: compared from position on)
    skipcols=1; [ $f = photonmap ] && skipcols=3
    sed -n '/^# record/,/^# ok/p' "$G/$f-all.txt" | grep -v '^#' | cut -d' ' -f$((skipcols + 1))- >"$TMP/pminfo.txt"
    [ $f = photonmap ] && cut -d' ' -f3- "$TMP/py.txt" >"$TMP/py2.txt" && mv "$TMP/py2.txt" "$TMP/py.txt"
    if "$PY" -c '
import sys
import numpy as np
a = np.array([[float(x) for x in l.split()] for l in open(sys.argv[1])])
b = np.array([[float(x) for x in l.split()] for l in open(sys.argv[2]) if l.strip()])
sys.exit(0 if a.shape == b.shape and np.allclose(a, b, rtol=1e-7, atol=0) else 1)' "$TMP/py.txt" "$TMP/pminfo.txt" 2>>"$TMP/err"; then
        pass "python: $f records equal pm-info -r's"
    else
        fail "python: $f records equal pm-info -r's" "$(head -3 "$TMP/py.txt") vs $(head -3 "$TMP/pminfo.txt") $(head -c 200 "$TMP/err")"
    fi
done

# ---- header: a dict, COMMAND and INPUT lists; an edited header is written as a writer writes it ----
"$PY" - "$G/queries-all.pm" "$TMP/edited.pm" >"$TMP/out" 2>"$TMP/err" <<'EOF'
import sys, pmtk
q = pmtk.read(sys.argv[1])
assert q.header["FORMAT"] == "queries" and q.header["width"] == "8", q.header
assert q.header["COMMAND"] == ["pm-testgen queries --all"], q.header["COMMAND"]
assert q.records.flags.writeable is False  # memory-mapped read-only
q.header["note"] = "from python"
q.header["COMMAND"].append("python edit")
pmtk.write(sys.argv[2], q)
EOF
if [ $? = 0 ] && "$BIN/pm-info" --header "$TMP/edited.pm" >"$TMP/h.txt" 2>"$TMP/err" &&
    grep -qx 'note=from python' "$TMP/h.txt" && grep -qx 'COMMAND=python edit' "$TMP/h.txt"; then
    pass "python: an edited header is written and pm-info reads it"
else
    fail "python: an edited header is written and pm-info reads it" "$(head -c 300 "$TMP/err")"
fi

# ---- files made in Python feed the programs ----
"$PY" - "$TMP/made.pm" >"$TMP/out" 2>"$TMP/err" <<'EOF'
import sys, numpy as np, pmtk
rng = np.random.default_rng(1)
rec, hdr = pmtk.empty("photons", 2000)
rec["position"] = rng.uniform(-1, 1, (2000, 3))
rec["power"] = 1e-3
n = rng.normal(size=(2000, 3)); rec["normal"] = n / np.linalg.norm(n, axis=1, keepdims=True)
hdr["BOUNDS"] = "-1 -1 -1 1 1 1"
hdr["COMMAND"] = ["python made"]
pmtk.write(sys.argv[1], rec, hdr)
EOF
expect_exit "python: a photons file made in Python passes pm-info" 0 "$BIN/pm-info" "$TMP/made.pm"
expect_exit "python: ... and build-photonmap builds a map of it" 0 "$BIN/build-photonmap" -q "$TMP/made.pm" -o "$TMP/made-map.pm"
"$PY" -c 'import pmtk, sys; m = pmtk.read(sys.argv[1]); assert m.format == "photonmap" and len(m) == 2000' "$TMP/made-map.pm" 2>"$TMP/err" &&
    pass "python: ... whose map Python reads back" || fail "python: ... whose map Python reads back" "$(head -c 300 "$TMP/err")"

# ---- the writer refuses what a reader would, and leaves nothing ----
"$PY" - "$TMP/nan.pm" >"$TMP/out" 2>"$TMP/err" <<'EOF'
import sys, numpy as np, pmtk
rec, hdr = pmtk.empty("radiance", 2, width=2, height=1, component="total")
rec["rgb"][1, 2] = np.nan
try:
    pmtk.write(sys.argv[1], rec, hdr)
except pmtk.FormatError as e:
    print(e)
    sys.exit(0)
sys.exit(1)
EOF
if [ $? = 0 ] && [ ! -e "$TMP/nan.pm" ] && grep -q "record 1 channel rgb" "$TMP/out" && [ -z "$(ls -A "$TMP" | grep '^\.nan')" ]; then
    pass "python: writing a NaN is refused, naming the record, and writes nothing"
else
    fail "python: writing a NaN is refused" "$(cat "$TMP/out" "$TMP/err" | head -c 300)"
fi

# ---- bad files: one line naming the file and the value, exit 1 (python3 -m pmtk check) ----
pycheck() { "$PY" -m pmtk check "$@"; }
cp "$G/photons-all.pm" "$TMP/flip.pm"
printf '\x55' | dd of="$TMP/flip.pm" bs=1 seek=300 conv=notrunc 2>/dev/null
expect_error "python: a flipped byte is a checksum mismatch" "photons file '.*flip.pm': checksum mismatch" pycheck "$TMP/flip.pm"
head -c 200 "$G/photonmap-all.pm" >"$TMP/trunc.pm"
expect_error "python: a truncated map is named truncated" "'.*trunc.pm': truncated header" pycheck "$TMP/trunc.pm"
echo "hello" >"$TMP/text.pm"
expect_error "python: a text file is not a pmtk file" "not a pmtk file" pycheck "$TMP/text.pm"
sed '0,/^VERSION=2.0/s//VERSION=3.0/' "$G/radiance-all.pm" >"$TMP/v3.pm"
"$TG" reseal "$TMP/v3.pm" "$TMP/v3s.pm"
expect_error "python: a newer major version is refused" "version 3.0 not supported" pycheck "$TMP/v3s.pm"
sed '0,/^CHANNELS=position power normal direction depth/s//CHANNELS=position power direction normal depth/' \
    "$G/photons-all.pm" >"$TMP/order.pm"
"$TG" reseal "$TMP/order.pm" "$TMP/orders.pm"
expect_error "python: channels out of order are refused" "malformed CHANNELS" pycheck "$TMP/orders.pm"
cat "$G/radiance-all.pm" "$G/radiance-all.pm" >"$TMP/two.pm"
expect_error "python: a stream is not one file (read_stream says how)" "read_stream" pycheck "$TMP/two.pm"
n=$("$PY" -c 'import pmtk, sys; print(sum(len(d) for d in pmtk.read_stream(sys.argv[1])))' "$TMP/two.pm" 2>"$TMP/err")
[ "$n" = 24 ] && pass "python: read_stream reads both documents" || fail "python: read_stream" "got '$n': $(head -c 300 "$TMP/err")"
for p in nan inf negative unit; do
    "$TG" photons 5 "$TMP/p-$p.pm" --poison $p
    expect_error "python: poisoned photons ($p) named by record and channel" "bad value in photons file '.*p-$p.pm': record 0 channel (position|power|normal)" \
        pycheck "$TMP/p-$p.pm"
done
"$TG" queries 5 "$TMP/q-pixel.pm" --poison pixel
expect_error "python: a query outside the image" "record 0 pixel 1000000 outside the 8x4 image" pycheck "$TMP/q-pixel.pm"
expect_exit "python: python3 -m pmtk with no file is usage, exit 2" 2 "$PY" -m pmtk check

# ---- the programs from Python: output, and failures by class ----
"$PY" - "$BIN" "$G/photons-all.pm" "$TMP/text.pm" >"$TMP/out" 2>"$TMP/err" <<'EOF'
import sys, pmtk
assert pmtk.bin_dir() == sys.argv[1], pmtk.bin_dir()
assert b"# ok: 7 records" in pmtk.run("pm-info", sys.argv[2])
try:
    pmtk.run("pm-info", sys.argv[3])
    sys.exit(1)
except pmtk.RunError as e:
    assert e.status == 1 and e.klass == "input" and not e.retryable, (e.status, e.klass)
    assert "pm-info:" in str(e), str(e)
EOF
[ $? = 0 ] && pass "python: run() returns stdout and raises RunError by class" || fail "python: run()" "$(head -c 300 "$TMP/err")"
cp scenes/cornell-box/*.obj scenes/cornell-box/*.mtl scenes/cornell-box/scene.json "$TMP/" 2>/dev/null
"$PY" - "$TMP/scene.json" "$TMP/r" >"$TMP/out" 2>"$TMP/err" <<'EOF'
import os, sys, pmtk
s = pmtk.render(sys.argv[1], sys.argv[2], PHOTONS=4000, SPP=4, WIDTH=16, HEIGHT=12)
assert os.path.getsize(os.path.join(sys.argv[2], "image.exr")) > 0 and s["python_seconds"] > 0
img = pmtk.read(os.path.join(sys.argv[2], "indirect.pm"))
assert img.records["rgb"].shape == (16 * 12, 3) and img.records["rgb"].sum() > 0
EOF
[ $? = 0 ] && pass "python: render() runs pm-render and its buffers read as numpy" || fail "python: render()" "$(tail -c 300 "$TMP/err")"

# ---- a 1M-record photon map: memory-mapped, checked, timed ----
if "$TG" photonmap 1000000 "$TMP/1m.pm" 2>"$TMP/err"; then
    t=$("$PY" -c '
import sys, time, pmtk
best = 9.0
for _ in range(3):
    t0 = time.perf_counter(); m = pmtk.read(sys.argv[1]); best = min(best, time.perf_counter() - t0)
assert len(m) == 1000000
print("%.3f" % best)' "$TMP/1m.pm" 2>"$TMP/err")
    if [ -n "$t" ] && awk -v t="$t" 'BEGIN { exit !(t < 1.0) }'; then
        pass "python: a 1M-record photon map read and checked in $t s (goal 0.1 s; load $(cut -d' ' -f1 /proc/loadavg))"
    else
        fail "python: 1M-record photon map" "took '$t' s: $(head -c 300 "$TMP/err")"
    fi
    rm -f "$TMP/1m.pm"
else
    fail "python: 1M-record photon map" "pm-testgen failed: $(head -c 200 "$TMP/err")"
fi

# ---- libpmtk through ctypes, where it is built ($PMTK_LIB, the tree's build/, the system's) ----
PMTK_LIB=$TMP/text.pm "$PY" -c 'import pmtk, sys; sys.exit(0 if pmtk.lib() is None or pmtk.lib() else 1)' 2>"$TMP/err" &&
    pass "python: a PMTK_LIB that is not a library is passed over, not a crash" || fail "python: bad PMTK_LIB" "$(head -c 300 "$TMP/err")"
if "$PY" -c 'import pmtk, sys; sys.exit(0 if pmtk.lib() else 1)' 2>/dev/null; then
    "$PY" - "$G/build-photonmap-cornell.pm" >"$TMP/out" 2>"$TMP/err" <<'EOF2'
import sys, numpy as np, pmtk
nat = pmtk.native()
rng = np.random.default_rng(3)
n, h = 20000, 0.05
pos = rng.uniform(0, 1, (n, 3)).astype(np.float32); pos[:, 2] = 0
power = rng.uniform(0, 1e-3, (n, 3)).astype(np.float32)
up = np.tile(np.float32([0, 0, 1]), (n, 1))
m = nat.build_map(pos, power, up)
qp = rng.uniform(0.1, 0.9, (500, 3)).astype(np.float32); qp[:, 2] = 0
E, st = nat.gather(m, qp, up[:500], h)
# the estimator by brute force: every photon within h, uniform kernel 1 / (pi h^2)
d2 = ((qp[:, None, :2].astype(np.float64) - pos[None, :, :2]) ** 2).sum(-1)
ref = ((d2 <= h * h)[:, :, None] * power[None].astype(np.float64)).sum(1) / (np.pi * h * h)
assert np.abs(E - ref).max() <= 1e-5 * ref.max(), np.abs(E - ref).max()
assert sorted(nat.hilbert_order(qp).tolist()) == list(range(500))
assert len(nat.read_map(sys.argv[1])) == 5525
try:
    nat.gather(m, qp, up[:500], 0.0)
    sys.exit(1)
except pmtk.native.LibError as e:
    assert e.code == 1 and "radius" in str(e), (e.code, str(e))
print(st["packet_width"])
EOF2
    [ $? = 0 ] && pass "python: libpmtk's packet gather from numpy equals the estimator by brute force ($(cat "$TMP/out")-wide packets)" ||
        fail "python: libpmtk gather" "$(tail -c 300 "$TMP/err")"
else
    skip "python: libpmtk through ctypes" "no libpmtk.so built or installed (issue 31 item 1)"
fi
