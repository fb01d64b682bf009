# 35-trace-reference.sh: the path tracer's throughput (sourced by tests/bench/run): what a
# reference costs. Rays are camera and bounce rays (rtcIntersect1) plus shadow rays
# (rtcOccluded1) over the tracing time (the per-pass EXR writes excluded); paths/s is samples
# per second. Medians of RUNS runs with min and max; 2 threads over 1 within this run.
size=128 spp=64
[ "$QUICK" = 1 ] && size=64 spp=16
rows="" ratios=""
for scene in cornell-box atrium; do
    declare -A tr_rate=()
    for t in 1 2; do
        out=$(median_stats "rays_per_s trace_s" "$BIN/trace-reference" scenes/$scene/scene.json -q --width $size \
            --height $size --spp $spp --pass $spp --threads $t -o "$TMP/tr.exr" --stats "$TMP/stats.json")
        { read -r rate lo hi; read -r ts _ _; } <<<"$out"
        tr_rate[$t]=$rate
        rpp=$(bench_stat rays_per_path "$TMP/stats.json")
        srays=$(bench_stat shadow_rays "$TMP/stats.json")
        paths=$(bench_stat paths "$TMP/stats.json")
        se=$(bench_stat stderr_rel "$TMP/stats.json")
        rows+=$(awk -v s=$scene -v t=$t -v r=$rate -v lo=$lo -v hi=$hi -v ts=$ts -v rpp=$rpp -v sr=$srays -v p=$paths \
            -v se=$se 'BEGIN { printf "| %s | %d | %.2f (%.2f to %.2f) | %.2f | %.3f | %.2f | %.2f | %.1f%% |\n",
            s, t, r / 1e6, lo / 1e6, hi / 1e6, r / t / 1e6, ts, rpp, sr / p, 100 * se }')$'\n'
    done
    ratios+="$scene $(awk -v a=${tr_rate[1]} -v b=${tr_rate[2]} 'BEGIN { printf "%.2f", b / a }'), "
    unset tr_rate
done
rm -f "$TMP/tr.exr"
cat >>"$MD" <<MD

## trace-reference

The path tracer behind every error figure (docs/programs/trace-reference.md): ${size}x${size}
pixels, $spp samples per pixel in one pass, single rays (rtcIntersect1 and rtcOccluded1).
"rays" counts camera, bounce and shadow rays; the standard error is the image's own RMS
standard error over its mean radiance, at this sample count.

| scene | threads | rays/s, M | per thread, M | trace s | camera and bounce rays per path | shadow rays per path | standard error |
|---|---|---|---|---|---|---|---|
${rows}
2 threads over 1, within this run: ${ratios%, }.
MD
