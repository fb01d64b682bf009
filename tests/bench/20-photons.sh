# 20-photons.sh: trace-photons and build-photonmap (sourced by tests/bench/run).
# trace-photons: ray segments per second per thread, beside Embree's own rtcIntersect1 rate
# on exactly the same rays (trace-photons --baseline re-traces every ray it cast, bare) and
# beside coherent primary rays (scene-info --probe). build-photonmap: the tree build alone
# (its build_s counter) and the whole stage (read, build, write), for 1 million photons.
P=${PHOTONS:-1000000}
[ "$QUICK" = 1 ] && P=100000
trace_rows=""
for scene in cornell-box atrium; do
    for t in 1 2; do
        cmd=("$BIN/trace-photons" "scenes/$scene/scene.json" --photons "$P" --threads $t -q -o "$TMP/ph.pm" --stats "$TMP/stats.json")
        read -r rate rlo rhi < <(median_stat rays_per_s "${cmd[@]}")
        # photons emitted per ray segment: fixed by the seed, so photons/s = rays/s times it
        ppr=$(awk -v e="$(bench_stat emitted "$TMP/stats.json")" -v r="$(bench_stat rays "$TMP/stats.json")" 'BEGIN { print e / r }')
        read -r base blo bhi < <(median_stat embree_rays_per_s "${cmd[@]}" --baseline)
        read -r probe _ _ < <(median_stat probe_rays_per_s "$BIN/scene-info" --probe --threads $t -q -o /dev/null \
            --stats "$TMP/stats.json" "scenes/$scene/scene.json")
        trace_rows+=$(awk -v s=$scene -v t=$t -v r=$rate -v lo=$rlo -v hi=$rhi -v b=$base -v blo=$blo -v bhi=$bhi -v p=$probe \
            -v f="$ppr" 'BEGIN {
            printf "| %s | %d | %.2f (%.2f to %.2f) | %.2f | %.2f (%.2f to %.2f) | %.2f | %.2f (%.2f to %.2f) | %.2f | %.2f |\n",
                s, t, r * f / 1e6, lo * f / 1e6, hi * f / 1e6, r * f / t / 1e6, r / 1e6, lo / 1e6, hi / 1e6, r / t / 1e6,
                b / 1e6, blo / 1e6, bhi / 1e6, r / b, p / 1e6 }')
        trace_rows+=$'\n'
    done
done
"$BIN/trace-photons" scenes/cornell-box/scene.json --photons "$P" -q -o "$TMP/ph.pm" --stats "$TMP/stats.json"
stored=$(grep -o '"stored": *[0-9]*' "$TMP/stats.json" | grep -o '[0-9]*$')

M=1000000
[ "$QUICK" = 1 ] && M=100000
"$BUILD/tests/pm-testgen" photons $M "$TMP/uniform.pm"
build_rows=""
for input in uniform cornell; do
    f=$TMP/uniform.pm n=$M label="$M photons, uniform in a box (pm-testgen)"
    [ $input = cornell ] && f=$TMP/ph.pm n=$stored label="$stored photons traced in the Cornell box"
    for t in 1 2; do
        cmd=("$BIN/build-photonmap" "$f" --threads $t -q -o "$TMP/map.pm" --stats "$TMP/stats.json")
        read -r b blo bhi < <(median_stat build_photons_per_s "${cmd[@]}")
        read -r w wlo whi < <(median_stat wall_s "${cmd[@]}")
        build_rows+=$(awk -v l="$label" -v t=$t -v b=$b -v blo=$blo -v bhi=$bhi -v n=$n -v w=$w -v wlo=$wlo -v whi=$whi 'BEGIN {
            printf "| %s | %d | %.1f (%.1f to %.1f) | %.3f (%.3f to %.3f) | %.1f |\n",
                l, t, b / 1e6, blo / 1e6, bhi / 1e6, w, wlo, whi, n / w / 1e6 }')
        build_rows+=$'\n'
    done
done
rm -f "$TMP/ph.pm" "$TMP/uniform.pm" "$TMP/map.pm"

cat >>"$MD" <<MD

## trace-photons

$P photons emitted per run. Photons/s counts photons emitted (each traced to its end) over
the tracing loop's time. Rays are ray segments (one per bounce). "Embree, same rays" re-traces
every ray the run cast with bare \`rtcIntersect1\` (\`trace-photons --baseline\`), so the ratio is
what emission, shading, Russian roulette and storing cost on top of Embree. Primary rays are
coherent camera rays (\`scene-info --probe\`), an upper bound for single rays on the scene.
Goal (issue 3): rays per second per core at least Embree's single-ray rate.

| scene | threads | photons/s, M | per thread, M | rays/s, M | per thread, M | Embree, same rays, M/s | ratio | primary rays, M/s |
|---|---|---|---|---|---|---|---|---|
${trace_rows}
## build-photonmap

The paper's KD-tree, median splits. "Build" is the tree alone (the \`build_photons_per_s\`
counter: balanced tree and permutation, in memory); "stage" is the whole program: read and
check the photons, build, lay out hot and cold data, write and checksum the map.
Goal (issue 3): 30 million photons per second for 1 million photons.

| input | threads | build, M photons/s | stage wall s | stage, M photons/s |
|---|---|---|---|---|
${build_rows}
MD
