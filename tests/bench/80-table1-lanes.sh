# 80-table1-lanes.sh: the paper's Table 1, active lanes per shading step (sourced by
# tests/bench/run). For each scene: P photons, the queries of direct visualization (the
# primary hits) and of 16, 64 and 100 samples per pixel at size x size, gathered as
# trace-gather-points wrote them (pixel by pixel) and Hilbert-sorted (hilbert-sort's default
# leaf of 16, the paper's partial reordering), with every packet width the CPU has.
# active_lanes (simd-gather --stats) is the mean number of live lanes per shading step, the
# paper's metric; it is a count, the same for every run and every --threads, so each figure
# is one run. One radius per scene: the one at which about 50 photons fall in the kernel of a
# 16 spp query (simd-gather --k 50 once), then fixed with --radius for every row.
P=500000 size=256
[ "$QUICK" = 1 ] && P=50000 size=48
ISAS=$(bench_isas)
# The paper's Table 1 (4-wide SSE packets, 256x256): as traced / with reordering. Its Sponza
# rows stand beside our atrium (a procedural stand-in, scenes/atrium).
declare -A t1_paper=(
    [cornell-box.dv]="3.18 / n/a" [cornell-box.16]="1.07 / 2.84" [cornell-box.64]="1.16 / 3.32" [cornell-box.100]="1.20 / 3.41"
    [atrium.dv]="3.74 / n/a" [atrium.16]="1.41 / 3.83" [atrium.64]="1.72 / 3.92" [atrium.100]="1.84 / 3.93")
t1_rows="" t1_radii=""
declare -A t1_mode_rows
for scene in cornell-box atrium; do
    S=scenes/$scene/scene.json
    "$BIN/trace-photons" "$S" --photons $P -q -o "$TMP/t1-ph.pm"
    "$BIN/build-photonmap" "$TMP/t1-ph.pm" -q -o "$TMP/t1-map.pm"
    rm -f "$TMP/t1-ph.pm"
    R=""
    for mode in 16 dv 64 100; do # dv: direct visualization; 16 first: it sets the radius
        if [ $mode = dv ]; then
            margs=(--mode direct-vis) label="direct visualization"
        else
            margs=(--spp $mode) label="$mode spp"
        fi
        "$BIN/trace-gather-points" "$S" --width $size --height $size "${margs[@]}" -q -o "$TMP/t1-q.pm" \
            --stats "$TMP/stats.json"
        nq=$(bench_stat queries "$TMP/stats.json")
        "$BIN/hilbert-sort" "$TMP/t1-q.pm" -q -o "$TMP/t1-qh.pm"
        if [ -z "$R" ]; then
            "$BIN/simd-gather" "$TMP/t1-map.pm" "$TMP/t1-qh.pm" --k 50 -q -o "$TMP/t1-o.pm" --stats "$TMP/stats.json"
            R=$(bench_stat radius_m "$TMP/stats.json")
            t1_radii+="$(printf '%s %.4g m, ' $scene "$R")"
        fi
        first=1
        for isa in $ISAS; do
            declare -A t1_l=()
            for order in image hilbert; do
                q=$TMP/t1-q.pm
                [ $order = hilbert ] && q=$TMP/t1-qh.pm
                "$BIN/simd-gather" "$TMP/t1-map.pm" "$q" --radius "$R" --isa $isa -q -o "$TMP/t1-o.pm" --stats "$TMP/stats.json"
                t1_l[$order]=$(bench_stat active_lanes "$TMP/stats.json")
                w=$(bench_stat packet_width "$TMP/stats.json")
                k=$(bench_stat shader_ops_per_query "$TMP/stats.json")
            done
            paper=""
            [ "$w" = 4 ] && paper=${t1_paper[$scene.$mode]}
            [ $first = 1 ] && sc=$scene md="$label" nqs=$nq || sc="" md="" nqs=""
            first=0
            t1_mode_rows[$mode]+=$(awk -v s="$sc" -v m="$md" -v n="$nqs" -v i=$isa -v w="$w" -v k="$k" -v a="${t1_l[image]}" \
                -v h="${t1_l[hilbert]}" -v p="$paper" 'BEGIN {
                printf "| %s | %s | %s | %s (%d) | %.1f | %.2f | %.0f%% | %.2f | %.0f%% | %s |\n",
                    s, m, n, i, w, k, a, 100 * a / w, h, 100 * h / w, p }')
            t1_mode_rows[$mode]+=$'\n'
        done
    done
    for mode in dv 16 64 100; do t1_rows+=${t1_mode_rows[$mode]}; done
    t1_mode_rows=()
done
rm -f "$TMP"/t1-*.pm
cat >>"$MD" <<MD

## Table 1: active lanes per shading step

The paper's Table 1 metric: the mean number of queries of a packet that are live when a
photon is shaded against it (simd-gather's \`active_lanes\`), from 1 (only one query left)
to W, the packet width (4 for SSE, 8 for AVX2, 16 for AVX-512; ISAs this CPU lacks are left
out: $ISAS here). $P photons per scene, ${size}x${size} pixels; the queries of direct
visualization (\`trace-gather-points --mode direct-vis\`: the primary hits) and of 16, 64 and
100 secondary rays per pixel (the Cornell box is open at the front, so rays that leave it give
no query). "As traced" gathers them in the order trace-gather-points wrote them (pixel by
pixel, a pixel's rays together); "Hilbert" after \`hilbert-sort\` with its default leaf of 16
points, the paper's partial reordering. One fixed radius per scene, the one at which about 50
photons fall in a 16 spp query's kernel (\`--k 50\`, once), for every row; "k" is the
resulting mean shader operations per query. Lane counts are deterministic (the same in every
run and for any \`--threads\`), so each is one run. The paper's figures are for 4-wide packets
at 256x256 (its Sponza atrium beside our atrium, a procedural stand-in); it gives no reordered
figure for direct visualization.

Radius: ${t1_radii%, }.

| scene | queries of | queries | ISA (W) | k | as traced: lanes | of W | Hilbert: lanes | of W | paper, W = 4: as traced / Hilbert |
|---|---|---|---|---|---|---|---|---|---|
${t1_rows}
MD
