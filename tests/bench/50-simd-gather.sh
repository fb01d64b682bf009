# 50-simd-gather.sh: the gather's shader operations per second (sourced by tests/bench/run).
# The fixed benchmark of issue 6: 500,000 photons traced in the Cornell box, the queries of
# 256x256 pixels at 16 samples per pixel (the Cornell box is open at the front, so rays that
# leave it give no query), Hilbert-sorted with the default leaf, and the radius at which about
# 50 photons contribute per query (found once with --k 50, then fixed for every run).
# shader ops/s counts photon-query pairs inside the kernel over the gather's wall time
# (reading, radius search and writing excluded); active lanes is the mean number of live
# lanes per shading step (the paper's Table 1 metric). "image order" gathers the queries as
# trace-gather-points wrote them, pixel by pixel.
P=500000 size=256
[ "$QUICK" = 1 ] && P=100000 size=96
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons $P -q -o "$TMP/g-ph.pm"
"$BIN/build-photonmap" "$TMP/g-ph.pm" -q -o "$TMP/g-map.pm"
"$BIN/trace-gather-points" scenes/cornell-box/scene.json --width $size --height $size --spp 16 -q \
    -o "$TMP/g-q.pm" --direct "$TMP/g-d.pm"
"$BIN/hilbert-sort" "$TMP/g-q.pm" -q -o "$TMP/g-qh.pm"
"$BIN/simd-gather" "$TMP/g-map.pm" "$TMP/g-qh.pm" --k 50 -q -o "$TMP/g-out.pm" --stats "$TMP/stats.json"
R=$(grep -o '"radius_m": *[0-9.eE+-]*' "$TMP/stats.json" | sed 's/.*: *//')
NQ=$(grep -o '"queries": *[0-9]*' "$TMP/stats.json" | sed 's/.*: *//')
OPQ=$(grep -o '"shader_ops_per_query": *[0-9.eE+-]*' "$TMP/stats.json" | sed 's/.*: *//')
rows=""
declare -A rate
for order in hilbert image; do
    q=$TMP/g-qh.pm
    [ $order = image ] && q=$TMP/g-q.pm
    for isa in avx512 avx2 sse4 scalar; do
        case $isa in avx512) flag=avx512f ;; avx2) flag=avx2 ;; sse4) flag=sse4_1 ;; *) flag="" ;; esac
        [ -n "$flag" ] && ! grep -qw "$flag" /proc/cpuinfo && continue
        for t in 1 2; do
            [ $order = image ] && [ $t = 2 ] && continue
            cmd=("$BIN/simd-gather" "$TMP/g-map.pm" "$q" --radius "$R" --isa $isa --threads $t -q -o "$TMP/g-out.pm"
                --stats "$TMP/stats.json")
            read -r med lo hi < <(median_stat shader_ops_per_s "${cmd[@]}")
            lanes=$(grep -o '"active_lanes": *[0-9.eE+-]*' "$TMP/stats.json" | sed 's/.*: *//')
            rate[$order-$isa-$t]=$med
            rows+=$(awk -v o=$order -v i=$isa -v t=$t -v m=$med -v lo=$lo -v hi=$hi -v l=$lanes 'BEGIN {
                w = (i == "avx512") ? 16 : (i == "avx2") ? 8 : (i == "sse4") ? 4 : 1
                printf "| %s | %s (%d) | %d | %.0f (%.0f to %.0f) | %.0f | %.2f | %.0f%% |\n",
                    o, i, w, t, m / 1e6, lo / 1e6, hi / 1e6, m / t / 1e6, l, 100 * l / w }')
            rows+=$'\n'
        done
    done
done
ratios=""
for isa in avx512 avx2 sse4 scalar; do
    [ -n "${rate[hilbert-$isa-1]:-}" ] || continue
    ratios+=$(awk -v i=$isa -v a=${rate[hilbert-$isa-1]} -v b=${rate[hilbert-$isa-2]} -v s=${rate[hilbert-scalar-1]} \
        -v u=${rate[image-$isa-1]} 'BEGIN { printf "| %s | %.2f | %.2f | %.2f |\n", i, b / a, a / s, a / u }')
    ratios+=$'\n'
done
rm -f "$TMP"/g-*.pm
cat >>"$MD" <<MD

## simd-gather

$P photons in the Cornell box, $NQ queries from ${size}x${size} pixels at 16 samples per pixel,
radius $R m (found by \`--k 50\`: $OPQ shader operations per query). Goals (issue 6): 300 million
shader operations per second per core with the widest ISA; 90% active lanes with 4-wide packets;
1.9x on 2 cores. For scale: the paper reached 8 to 12 million per core in 2008.

| query order | ISA (lanes) | threads | shader ops/s, M | per thread, M | active lanes | of W |
|---|---|---|---|---|---|---|
${rows}
Ratios within this run (1 thread unless said): 2 threads over 1; this ISA over scalar; Hilbert
order over image order.

| ISA | 2 threads / 1 | over scalar | Hilbert / image order |
|---|---|---|---|
${ratios}
MD
