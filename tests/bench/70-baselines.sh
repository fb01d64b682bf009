# 70-baselines.sh: simd-gather against its two baselines (sourced by tests/bench/run).
# 1. Forward against reverse photon mapping at the same radius: simd-gather (packets walking
#    the photon tree) and reverse-gather (a tree of the queries, each photon searching it) on
#    the fixed gather benchmark of 50-simd-gather.sh; their buffers are checked equal.
# 2. simd-gather (sample-point estimator) against knn-gather (Jensen's k nearest photons,
#    scalar, a heap per query) at equal error: direct visualization of the Cornell box (the
#    queries are the primary hits, so the error is the density estimate's own), both swept
#    over K against two references of REFP photons gathered with K = 400, one by each
#    estimator (a reference made by one estimator shares its kind of bias, so it favours
#    it); the equal-error match uses knn-gather's reference, which favours the baseline.
#    Error by measure-error; time as the gathers' CPU seconds on one thread (less sensitive
#    to other load than wall time), medians of RUNS.
S=scenes/cornell-box/scene.json
P=500000 size=256 REFP=8000000 KS="10 20 50 100 200 400"
[ "$QUICK" = 1 ] && P=100000 size=128 REFP=1000000 KS="10 50 200"
num() { grep -o "\"$1\": *[-0-9.eE+]*" "$2" | head -n 1 | sed 's/.*: *//'; }

# ---- 1. forward against reverse ----
"$BIN/trace-photons" $S --photons $P -q -o "$TMP/b-ph.pm"
"$BIN/build-photonmap" "$TMP/b-ph.pm" -q -o "$TMP/b-map.pm"
"$BIN/trace-gather-points" $S --width $size --height $size --spp 16 -q -o "$TMP/b-q.pm" --direct "$TMP/b-d.pm"
"$BIN/hilbert-sort" "$TMP/b-q.pm" -q -o "$TMP/b-qh.pm"
"$BIN/simd-gather" "$TMP/b-map.pm" "$TMP/b-qh.pm" --k 50 -q -o "$TMP/b-f.pm" --stats "$TMP/stats.json"
R=$(num radius_m "$TMP/stats.json") NQ=$(num queries "$TMP/stats.json") OPQ=$(num shader_ops_per_query "$TMP/stats.json")
"$BIN/reverse-gather" "$TMP/b-map.pm" "$TMP/b-qh.pm" --radius "$R" -q -o "$TMP/b-r.pm" --stats "$TMP/stats.json"
"$BIN/simd-gather" "$TMP/b-map.pm" "$TMP/b-qh.pm" --radius "$R" -q -o "$TMP/b-f.pm"
same=$("$BIN/pm-compare" --max-rel 1e-5 --max-abs 1e-12 "$TMP/b-f.pm" "$TMP/b-r.pm" >/dev/null 2>&1 && echo yes || echo NO)
DEPTH=$(num query_tree_depth "$TMP/stats.json") SUB=$(num subtrees "$TMP/stats.json")
frows="" ratios=""
for t in 1 2; do
    # one set of RUNS runs per program gives all of its figures
    out=$(median_stats "gather_s gather_cpu_s" "$BIN/simd-gather" "$TMP/b-map.pm" "$TMP/b-qh.pm" --radius "$R" \
        --threads $t -q -o "$TMP/b-f.pm" --stats "$TMP/stats.json")
    { read -r fg fglo fghi; read -r fc _ _; } <<<"$out"
    out=$(median_stats "gather_s build_s search_s search_cpu_s" "$BIN/reverse-gather" "$TMP/b-map.pm" "$TMP/b-qh.pm" \
        --radius "$R" --threads $t -q -o "$TMP/b-r.pm" --stats "$TMP/stats.json")
    { read -r rg rglo rghi; read -r rb _ _; read -r rs _ _; read -r rc _ _; } <<<"$out"
    frows+=$(awk -v t=$t -v fg=$fg -v fl=$fglo -v fh=$fghi -v fc=$fc -v rg=$rg -v rl=$rglo -v rh=$rghi -v rb=$rb \
        -v rs=$rs -v rc=$rc 'BEGIN { printf "| %d | %.3f (%.3f to %.3f) | %.3f | %.3f (%.3f to %.3f) | %.3f | %.3f | %.3f | %.1f |\n",
        t, fg, fl, fh, fc, rg, rl, rh, rb, rs, rc, rg / fg }')
    frows+=$'\n'
done

# ---- 2. simd-gather against knn-gather at equal error ----
"$BIN/trace-gather-points" $S --mode direct-vis --width $size --height $size -q -o "$TMP/b-v0.pm" --direct "$TMP/b-vd.pm"
"$BIN/hilbert-sort" "$TMP/b-v0.pm" -q -o "$TMP/b-v.pm"
"$BIN/trace-photons" $S -n $REFP --seed 99 -q -o "$TMP/b-rph.pm"
"$BIN/build-photonmap" "$TMP/b-rph.pm" -q -o "$TMP/b-rmap.pm"
"$BIN/simd-gather" "$TMP/b-rmap.pm" "$TMP/b-v.pm" --k 400 -q -o "$TMP/b-ref-simd.pm"
"$BIN/knn-gather" "$TMP/b-rmap.pm" "$TMP/b-v.pm" --k 400 -q -o "$TMP/b-ref-knn.pm"
rm -f "$TMP/b-rph.pm" "$TMP/b-rmap.pm"
NV=$(grep -a '^COUNT=' "$TMP/b-v.pm" | cut -d= -f2)
erows="" : >"$TMP/b-curve"
for K in $KS; do
    "$BIN/simd-gather" "$TMP/b-map.pm" "$TMP/b-v.pm" --k $K -q -o "$TMP/b-o.pm" --stats "$TMP/stats.json"
    RK=$(num radius_m "$TMP/stats.json")
    for m in simd knn; do
        if [ $m = simd ]; then
            cmd=("$BIN/simd-gather" "$TMP/b-map.pm" "$TMP/b-v.pm" --radius "$RK" --threads 1 -q -o "$TMP/b-o.pm"
                --stats "$TMP/stats.json")
        else
            cmd=("$BIN/knn-gather" "$TMP/b-map.pm" "$TMP/b-v.pm" --k $K --threads 1 -q -o "$TMP/b-o.pm"
                --stats "$TMP/stats.json")
        fi
        read -r c clo chi < <(median_stat gather_cpu_s "${cmd[@]}")
        "$BIN/measure-error" "$TMP/b-o.pm" "$TMP/b-ref-knn.pm" -q -o "$TMP/b-err.json"
        e=$(num relmse "$TMP/b-err.json") rmse=$(num rmse "$TMP/b-err.json")
        "$BIN/measure-error" "$TMP/b-o.pm" "$TMP/b-ref-simd.pm" -q -o "$TMP/b-err.json"
        es=$(num relmse "$TMP/b-err.json")
        echo "$m $K $e $c" >>"$TMP/b-curve"
        erows+=$(awk -v m=$m -v k=$K -v e=$e -v es=$es -v r=$rmse -v c=$c -v lo=$clo -v hi=$chi \
            'BEGIN { printf "| %s | %d | %.5f | %.4g | %.5f | %.4f (%.4f to %.4f) |\n", m, k, e, r, es, c, lo, hi }')
        erows+=$'\n'
    done
done
# For each knn-gather setting: the cheapest simd-gather setting whose error is no larger.
eq=$(awk '{ m[NR] = $1; k[NR] = $2; e[NR] = $3; c[NR] = $4 }
    END { for (i = 1; i <= NR; i++) { if (m[i] != "knn") continue; best = 0
              for (j = 1; j <= NR; j++) if (m[j] == "simd" && e[j] <= e[i] && (!best || c[j] < c[best])) best = j
              if (best) printf "| %d | %.5f | %.4f | %d | %.5f | %.4f | %.1f |\n", k[i], e[i], c[i], k[best], e[best], c[best], c[i] / c[best]
              else printf "| %d | %.5f | %.4f | none | | | |\n", k[i], e[i], c[i] } }' "$TMP/b-curve")
rm -f "$TMP"/b-*

cat >>"$MD" <<MD

## Baselines: forward against reverse, sample points against k nearest

**Forward against reverse photon mapping.** $P photons in the Cornell box, $NQ queries from
${size}x${size} pixels at 16 samples per pixel (Hilbert-sorted), one radius $R m for both
($OPQ shader operations per query). simd-gather walks the photon tree with packets of the
widest ISA; reverse-gather builds a KD-tree of the queries (depth $DEPTH, cut into $SUB units of
work) and lets every photon search it, scalar. Same buffer within float rounding: $same.
Seconds from the stages' own timers (gather: the whole estimate; for reverse, building the
query tree and the search); CPU columns are the threads' CPU seconds.

| threads | simd-gather s | its CPU s | reverse-gather s | query tree s | search s | search CPU s | reverse / forward |
|---|---|---|---|---|---|---|---|
${frows}
**At equal error.** Direct visualization of the Cornell box ($NV queries at the primary hits),
$P photons, against references of $REFP photons gathered with K = 400 by knn-gather and by
simd-gather (each reference shares the bias of the estimator that made it; the match below
uses knn-gather's, so it favours the baseline if anything). K is
the photons per query: simd-gather's radius is the one at which K photons fall in the kernel
on average (\`--k K\`, found once), knn-gather takes the K nearest (uniform kernel, Jensen's
estimate). Error: \`measure-error\` (relative MSE, epsilon 0.01; RMSE in W/(m² sr)). Time: CPU
seconds of the gather on one thread (\`gather_cpu_s\`), reading and writing excluded.

| gather | K | relative MSE, knn reference | RMSE, knn reference | relative MSE, simd reference | gather CPU s |
|---|---|---|---|---|---|
${erows}
For each knn-gather setting, the cheapest simd-gather setting of this run with an error no
larger (relative MSE against knn-gather's reference), and how many times faster it is:

| knn K | knn error | knn CPU s | simd K | simd error | simd CPU s | knn / simd time |
|---|---|---|---|---|---|---|
${eq}
MD
