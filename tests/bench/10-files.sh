# 10-files.sh: the cost of reading and checking each file format (sourced by tests/bench/run).
rows=""
for f in queries photons photonmap; do
    "$BUILD/tests/pm-testgen" $f "$N" "$TMP/$f.pm" --all
    bytes=$(stat -c %s "$TMP/$f.pm")
    read -r med lo hi < <(median_spread "$BIN/pm-info" "$TMP/$f.pm")
    rows+=$(awk -v f="$f" -v n="$N" -v b="$bytes" -v m="$med" -v lo="$lo" -v hi="$hi" 'BEGIN {
        printf "| %s | %d | %.1f | %.2f | %.3f (%.3f to %.3f) |\n", f, n, b / 1e6, n / m / 1e6, m, lo, hi }')
    rows+=$'\n'
    rm -f "$TMP/$f.pm"
done
cat >>"$MD" <<MD

## Reading and checking files

\`pm-info FILE\` reads every record, checks every value (finite, non-negative, unit
vectors), the tree shape of a photon map and the XXH3 checksum: the cost a stage pays to
trust a cached intermediate. All optional channels present.

| format | records | file MB | records/s (millions) | wall s, median (min to max) |
|---|---|---|---|---|
${rows}
MD
