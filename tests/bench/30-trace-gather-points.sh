# 30-trace-gather-points.sh: ray throughput of trace-gather-points (sourced by tests/bench/run).
# The same rays traced as 16-, 8- and 4-lane Embree packets and as single rays
# (rtcIntersect1, --isa scalar): the RNG does not depend on the packet width, so every
# variant traces exactly the same rays. Figures are medians of RUNS runs with min and max.
#   rays/s (wall): all rays (primary, shadow, secondary) over the tracing loop's wall time
#   secondary/s per core: secondary rays over the CPU seconds the workers spent in the
#     tracing loop (generation, Embree, shading, query records; spooling and writing the
#     file excluded); less disturbed by other processes than wall time
#   Embree secondary/s per core: secondary rays over the time spent inside rtcIntersect*
size=256 spp=16
[ "$QUICK" = 1 ] && size=128
tgp() { "$BIN/trace-gather-points" -q --width "$size" --height "$size" --spp "$spp" --stats "$TMP/stats.json" -o "$TMP/q.pm" "$@"; }
rows=""
declare -A embree_s
for scene in cornell-box atrium; do
    for isa in avx512 avx2 sse4 scalar; do
        case $isa in avx512) flag=avx512f ;; avx2) flag=avx2 ;; sse4) flag=sse4_2 ;; *) flag="" ;; esac
        [ -n "$flag" ] && ! grep -qw "$flag" /proc/cpuinfo && continue
        for threads in 1 2; do
            [ "$threads" = 2 ] && [ "$isa" != avx512 ] && [ "$isa" != scalar ] && continue
            args=(scenes/$scene/scene.json --isa "$isa" --threads "$threads")
            # one set of RUNS runs, three figures from each run's stats
            : >"$TMP/tgp-runs"
            for i in $(seq "$RUNS"); do
                tgp "${args[@]}"
                for k in rays_per_s secondary_rays_per_cpu_s secondary_embree_rays_per_core_s; do
                    printf '%s ' "$(grep -o "\"$k\": *[-0-9.eE+]*" "$TMP/stats.json" | sed 's/.*: *//')"
                done >>"$TMP/tgp-runs"
                echo >>"$TMP/tgp-runs"
            done
            med() { awk -v c="$1" '{ print $c }' "$TMP/tgp-runs" | sort -g | awk '{ v[NR] = $1 } END { printf "%s %s %s\n", v[int((NR + 1) / 2)], v[1], v[NR] }'; }
            read -r wall _ _ < <(med 1)
            read -r per_core lo hi < <(med 2)
            read -r emb _ _ < <(med 3)
            width=$(grep -o '"packet_width": *[0-9]*' "$TMP/stats.json" | sed 's/.*: *//')
            nsec=$(grep -o '"secondary_rays": *[0-9]*' "$TMP/stats.json" | sed 's/.*: *//')
            [ "$threads" = 1 ] && embree_s[$scene.$isa]=$emb
            rows+=$(awk -v s="$scene" -v i="$isa" -v w="$width" -v t="$threads" -v n="$nsec" -v a="$wall" -v p="$per_core" \
                -v lo="$lo" -v hi="$hi" -v e="$emb" 'BEGIN {
                printf "| %s | %s (%s) | %s | %.2f | %.2f | %.2f (%.2f to %.2f) | %.2f |\n", s, i, w, t, n / 1e6, a / 1e6, p / 1e6, lo / 1e6, hi / 1e6, e / 1e6 }')
            rows+=$'\n'
        done
    done
done
ratios=""
for scene in cornell-box atrium; do
    if [ -n "${embree_s[$scene.scalar]:-}" ] && [ -n "${embree_s[$scene.avx512]:-}" ]; then
        ratios+=$(awk -v s="$scene" -v a="${embree_s[$scene.avx512]}" -v b="${embree_s[$scene.scalar]}" 'BEGIN {
            printf "%s: 16-lane packets / single rays, inside Embree, 1 thread: %.2f. ", s, a / b }')
    fi
done
rm -f "$TMP/q.pm"
cat >>"$MD" <<MD

## trace-gather-points: primary, shadow and secondary rays

\`trace-gather-points --width $size --height $size --spp $spp --isa ISA --threads T\` on each scene (one primary ray per
pixel, 4 area-light samples per primary hit where the scene has area lights). The same rays for every ISA:
\`scalar\` is single rays (\`rtcIntersect1\`/\`rtcOccluded1\`), the others Embree packets of the width in
brackets. "secondary/s per core" is secondary rays over the CPU seconds of the tracing loop (generation,
Embree, shading and query records; not the spool or file writing); "Embree secondary/s per core" counts
only the time inside \`rtcIntersect*\` for secondary rays. "all rays/s, wall" is over the tracing loop's wall
time (\`trace_s\`): on two threads that includes the spooling of each band, which runs on one thread beside
the tracing of the next (the default \`--schedule dynamic\`), so it is the loop's real rate, a little below
the tracing's alone; on one thread the spooling is left out. Other processes on this machine make wall-time
figures noisy. Goal (issue 4): 10 million secondary rays per second per core on the Cornell box, and
packets no slower per ray than single rays.

| scene | isa (lanes) | threads | secondary rays (M) | all rays/s, wall (M) | secondary/s per core (M), median (min to max) | Embree secondary/s per core (M) |
|---|---|---|---|---|---|---|
${rows}
${ratios}
MD
