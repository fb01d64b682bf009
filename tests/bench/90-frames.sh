# 90-frames.sh: whole-pipeline frames per second (sourced by tests/bench/run), the goals of issue
# 21 point 2: on the Cornell box at 256x256, 16 secondary rays per pixel and 500,000 photons,
# camera moves >= 4 frames/s, light moves >= 2, direct visualization >= 10. pipelines/frames
# runs the frames as one pipeline of resident stages (STREAM=1): camera moves keep the map of
# frame 0, light moves (the box with a point light under its ceiling, moved along x) keep the
# queries of the still camera; the per-frame path (STREAM=0, every stage once per frame) is
# measured beside them. A frame's time is the interval between one frame's last output and the
# next one's (the pipeline holds several frames at once, so that is its throughput); frame 0
# (the map or the queries, cold caches) is left out. One fixed radius per mode (simd-gather
# --k 50 on frame 0's view), given as RADIUS. Also writes where a camera-move frame's time goes,
# from the stages' --stats (CPU seconds per frame).
P=500000 size=256 spp=16
[ "$QUICK" = 1 ] && P=100000 size=128
NF=$((2 * RUNS + 2)) # frames per run; the first is left out
S=scenes/cornell-box/scene.json
widest=$(bench_isas | awk '{ print $NF }')
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
"$BIN/trace-photons" $S --photons $P -q -o "$TMP/f-ph.pm"
"$BIN/build-photonmap" "$TMP/f-ph.pm" -q -o "$TMP/f-map.pm"
declare -A f_radius=()
for mode in gather direct-vis; do
    "$BIN/trace-gather-points" $S --width $size --height $size --spp $spp --mode $mode -q -o "$TMP/f-q.pm"
    "$BIN/simd-gather" "$TMP/f-map.pm" "$TMP/f-q.pm" --k 50 -q -o "$TMP/f-o.pm" --stats "$TMP/stats.json"
    f_radius[$mode]=$(bench_stat radius_m "$TMP/stats.json")
done
rm -f "$TMP"/f-*.pm
# The light-move scene: the box with a point light under its ceiling (its area light stays).
mkdir -p "$TMP/fl-scene"
cp scenes/cornell-box/cornell-box.obj scenes/cornell-box/cornell-box.mtl "$TMP/fl-scene/"
jq '.point_lights = [{"position": [0.278, 0.5, 0.28], "intensity": [0.3, 0.3, 0.3]}]' $S >"$TMP/fl-scene/scene.json"

f_rows="" f_frame_cpu=""
# f_run LABEL GOAL SCENE ARGS...: one pipelines/frames run, one table row.
f_run() {
    local label=$1 goal=$2 scene=$3
    shift 3
    rm -rf "$TMP/frames"
    BIN=$BIN pipelines/frames "$scene" "$TMP/frames" FRAMES=$NF PHOTONS=$P WIDTH=$size HEIGHT=$size SPP=$spp PNG=0 \
        "$@" >"$TMP/frames.log" 2>&1 || { echo "bench: pipelines/frames $* failed: $(tail -3 "$TMP/frames.log")" >&2; return; }
    jq -r '.per_frame[1:][] | .total_s' "$TMP/frames/frames.json" >"$TMP/frames.txt"
    local fps med isa steady met
    fps=$(awk '$1 > 0 { print 1 / $1 }' "$TMP/frames.txt" | sort -g | awk '{ v[NR] = $1 } END {
        printf "%.2f (%.2f to %.2f)", v[int((NR + 1) / 2)], v[1], v[NR] }')
    med=$(sort -g "$TMP/frames.txt" | awk '{ v[NR] = $1 } END { printf "%.3f", v[int((NR + 1) / 2)] }')
    # Frames after the first over the time from the first's end to the last's.
    steady=$(jq -r '.per_frame[1:] | "\(length) \(map(.total_s) | add)"' "$TMP/frames/frames.json" |
        awk '{ printf "%.2f", ($2 > 0 ? $1 / $2 : 0) }')
    isa=$(jq -r '.stages["simd-gather"].isa // "-"' "$TMP/frames/frames.json")
    # Met: the median and the steady rate both at or above the goal.
    met=$(awk -v f="${fps%% *}" -v s="$steady" -v g="$goal" 'BEGIN {
        print (g == "-" ? "-" : (f >= g && s >= g ? "yes" : "no")) }')
    f_rows+="| $label | $(wc -l <"$TMP/frames.txt") | $fps | $steady | $med | ${goal/-/none} | $met | $isa | $widest |"$'\n'
    if [ "$label" = "camera moves, resident stages" ]; then
        # CPU seconds per frame of each stage (frame 0's map aside), and their compute timers.
        f_frame_cpu=$(jq -r --argjson n "$NF" '.stages as $s |
            ["trace-gather-points", "hilbert-sort", "simd-gather", "composite"][] as $k |
            "\($k) \($s[$k].cpu_s / $n) \($s[$k].wall_s)"' "$TMP/frames/frames.json")
        r3() { awk '{ printf "%.3f", $1 }'; }
        f_gather_cpu=$(jq -r --argjson n "$NF" '.stages["simd-gather"].gather_cpu_s / $n' "$TMP/frames/frames.json" | r3)
        f_sort_s=$(jq -r --argjson n "$NF" '.stages["hilbert-sort"] | (.keys_s + .sort_s + .reorder_s) / $n' "$TMP/frames/frames.json" | r3)
        f_trace_cpu=$(jq -r '.stages["trace-gather-points"].trace_cpu_s' "$TMP/frames/frames.json" | r3)
        f_read_s=$(jq -r --argjson n "$NF" '.stages["simd-gather"].read_s / $n' "$TMP/frames/frames.json" | r3)
    fi
}
f_run "camera moves, resident stages" 4 $S RADIUS="${f_radius[gather]}"
f_run "camera moves, every stage per frame (STREAM=0)" - $S RADIUS="${f_radius[gather]}" STREAM=0
f_run "light moves, resident stages" 2 "$TMP/fl-scene/scene.json" MOVE=light RADIUS="${f_radius[gather]}"
f_run "light moves, every stage per frame (STREAM=0)" - "$TMP/fl-scene/scene.json" MOVE=light RADIUS="${f_radius[gather]}" STREAM=0
f_run "direct visualization (camera moves), resident stages" 10 $S MODE=direct-vis ORDER=none RADIUS="${f_radius[direct-vis]}"
f_run "direct visualization, every stage per frame (STREAM=0)" - $S MODE=direct-vis ORDER=none RADIUS="${f_radius[direct-vis]}" STREAM=0
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
rm -rf "$TMP/frames" "$TMP/frames.txt" "$TMP/frames.log" "$TMP/fl-scene"
cpu_rows=$(awk '{ printf "| %s | %.3f |\n", $1, $2; t += $2 } END { printf "| all four | %.3f |\n", t }' <<<"$f_frame_cpu")
cat >>"$MD" <<MD

## Frames per second, the whole pipeline

\`pipelines/frames\` on the Cornell box, ${size}x${size} pixels, $P photons, $spp secondary rays
per pixel, EXR frames (no PNG), every stage on all $(nproc) cores; $NF frames per run, the first
left out. Resident stages (\`STREAM=1\`, the default) run the frames as one pipeline in which
every stage starts once and takes a document per frame: camera moves (the eye orbiting 30
degrees) keep the map of frame 0 and stream the queries; light moves (the box with a point light
under its ceiling, moved 0.1 m along x; the ceiling lamp stays) keep the sorted queries of the
still camera and stream photons, maps and direct buffers; direct visualization gathers at the
primary hits, not reordered (\`MODE=direct-vis ORDER=none\`, the map's estimate alone). The
per-frame path (\`STREAM=0\`) runs every stage once per frame with files between them (it too
keeps the map of frame 0 for camera moves). A frame's time is the interval between the end of
one frame and the end of the next (several frames are in the pipeline at once); frames per second
is one over it (median, min and max over the frames), and "steady" is the frames after the first
over the time from the first's end to the last's; a goal is met when both are at or above it.
One fixed radius per mode (\`--k 50\` once:
${f_radius[gather]} m, direct visualization ${f_radius[direct-vis]} m). The ISA is simd-gather's; the
widest one this CPU runs is beside it. Load average (1, 5, 15 min) from other jobs: $load_before
before, $load_after after (which counts this run's own stages, up to about 2); with other jobs on
the cores every figure here falls. The paper: 4
threads on a 2.66 GHz quad-core, 256x256, 1.14 frames per second at 16 spp and about 10 for
direct visualization.

| frames of | frames timed | frames/s (min to max) | steady frames/s | frame s (median) | goal, frames/s | met | ISA used | widest ISA |
|---|---|---|---|---|---|---|---|---|
${f_rows}
## Where a camera-move frame's time goes (issue 21)

From the stages' \`--stats\` in the camera-move run above (resident stages; $NF frames, map built
once): CPU seconds per frame of each resident stage (all its threads; less sensitive to other
jobs than wall time, not immune to them), and the compute inside them: trace-gather-points'
tracing ${f_trace_cpu} CPU s (the last frame's), hilbert-sort's keys, sort and reorder ${f_sort_s} s
wall per frame, simd-gather's gather ${f_gather_cpu} CPU s per frame and its reading of the
queries ${f_read_s} s wall per frame (most of it waiting for hilbert-sort). The rest of a stage's CPU
is reading, checking and writing its documents and, for composite, the EXR's zip compression.

| stage | CPU s per frame |
|---|---|
${cpu_rows}
MD
