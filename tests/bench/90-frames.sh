# 90-frames.sh: whole-pipeline frames per second (sourced by tests/bench/run). pipelines/frames
# recomputes every stage per frame, as the paper's interactive session did (trace photons,
# build the map, trace primary and secondary rays, reorder, gather, composite), on the Cornell
# box at 256x256, 16 spp and 500,000 photons, the camera orbiting; and in direct visualization
# (the primary hits are the queries, not reordered: they are coherent already). RUNS + 1
# frames; the first (cold caches, first exec of every program) is left out; each remaining
# frame's wall time gives one frames-per-second figure: median, min and max. One fixed radius
# per mode (simd-gather --k 50 once on the first frame's view), given as RADIUS.
P=500000 size=256 spp=16
[ "$QUICK" = 1 ] && P=100000 size=128
S=scenes/cornell-box/scene.json
"$BIN/trace-photons" $S --photons $P -q -o "$TMP/f-ph.pm"
"$BIN/build-photonmap" "$TMP/f-ph.pm" -q -o "$TMP/f-map.pm"
declare -A f_radius=()
for mode in gather direct-vis; do
    "$BIN/trace-gather-points" $S --width $size --height $size --spp $spp --mode $mode -q -o "$TMP/f-q.pm"
    "$BIN/simd-gather" "$TMP/f-map.pm" "$TMP/f-q.pm" --k 50 -q -o "$TMP/f-o.pm" --stats "$TMP/stats.json"
    f_radius[$mode]=$(bench_stat radius_m "$TMP/stats.json")
done
rm -f "$TMP"/f-*.pm
f_rows="" f_rows_all=""
for mode in gather direct-vis; do
    args=(FRAMES=$((RUNS + 1)) PHOTONS=$P WIDTH=$size HEIGHT=$size SPP=$spp RADIUS="${f_radius[$mode]}" PNG=0 MODE=$mode)
    [ $mode = direct-vis ] && args+=(ORDER=none)
    rm -rf "$TMP/frames"
    BIN=$BIN pipelines/frames $S "$TMP/frames" "${args[@]}" >"$TMP/frames.log"
    # one line per frame after the first: total photons eye gather (seconds)
    jq -r '.per_frame[1:][] | "\(.total_s) \(.photons_s) \(.eye_s) \(.gather_composite_s)"' "$TMP/frames/frames.json" >"$TMP/frames.txt"
    all_fps=$(jq -r .fps "$TMP/frames/frames.json")
    med() { awk -v c="$1" '{ print $c }' "$TMP/frames.txt" | sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
    fps=$(awk '{ print 1 / $1 }' "$TMP/frames.txt" | sort -g | awk '{ v[NR] = $1 } END {
        printf "%.2f (%.2f to %.2f)", v[int((NR + 1) / 2)], v[1], v[NR] }')
    label="indirect, $spp spp, Hilbert-sorted"
    paper="1.14 (4 cores)"
    if [ $mode = direct-vis ]; then
        label="direct visualization, as traced"
        paper="about 10 (4 cores)"
    fi
    f_rows+=$(printf '| %s | %s | %.4g | %s | %s | %s | %s | %s | %s |' "$label" "$(wc -l <"$TMP/frames.txt")" \
        "${f_radius[$mode]}" "$fps" "$(med 1)" "$(med 2)" "$(med 3)" "$(med 4)" "$paper")$'\n'
    f_rows_all+="$mode: $all_fps; "
done
rm -rf "$TMP/frames" "$TMP/frames.txt" "$TMP/frames.log"
cat >>"$MD" <<MD

## Frames per second, the whole pipeline

\`pipelines/frames\` on the Cornell box, ${size}x${size} pixels, $P photons, the camera orbiting 30
degrees over the frames: every frame traces the photons and builds the map (one pipe) while
trace-gather-points traces primary, shadow and $spp secondary rays per pixel and hilbert-sort
reorders the queries (the other pipe), then simd-gather (widest ISA) and composite write the
frame (EXR, no PNG); every stage on all $(nproc) cores (\`--threads 0\`). "Direct visualization" gathers at the
primary hits instead, not reordered (\`MODE=direct-vis ORDER=none\`; the image is the map's
estimate alone). One fixed radius per mode (\`--k 50\` once, then \`RADIUS\`). $((RUNS + 1))
frames per mode; the first is left out; frames per second is one over each remaining frame's
wall time (median, min and max). Stage columns are medians: "photons" is the photon pipe's wall
time, "eye" the eye pipe's (the two overlap), "gather" simd-gather plus composite after both.
The paper: 4 threads on a 2.66 GHz quad-core, 256x256, 1.14 frames per second at 16 spp and about
10 for direct visualization.

| frames of | frames timed | radius m | frames/s (min to max) | frame s | photons s | eye s | gather s | paper, frames/s |
|---|---|---|---|---|---|---|---|---|
${f_rows}
pipelines/frames' own figure (every frame, the first included, and writing each frame's scene
file): ${f_rows_all% }
MD
