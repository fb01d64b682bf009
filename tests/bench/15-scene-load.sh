# 15-scene-load.sh: what loading a scene costs a program, and what the scene cache saves (sourced
# by tests/bench/run; docs/scene-format.md, "Untrusted meshes" and "The scene cache"). scene-info's
# own `time: load` (pm_scene_load alone, without its ray tracer), three ways: the guarded load (the
# whole load in a forked child within PMTK_IMPORT_SECONDS and PMTK_IMPORT_MB, the scene handed back
# through a pipe: every program's load by default), the load in the process (both limits 0: trusted
# meshes), and a hit of PMTK_SCENE_CACHE (what pm-render's stages and reruns do); and the guarded
# load with malloc on huge pages (GLIBC_TUNABLES=glibc.malloc.hugetlb=1, which pm-render gives
# itself and its stages). Medians of RUNS runs with min and max.
L=$TMP/load
mkdir -p "$L"
# load_time ENV...: scene-info's load seconds, median min max of RUNS runs of SCENE ($scene)
load_time() {
    local i
    for i in $(seq "$RUNS"); do
        env "$@" "$BIN/scene-info" "$scene" | sed -n 's/^time: load \([0-9.]*\) s.*/\1/p'
    done | sort -g | awk '{ v[NR] = $1 } END { printf "%.4f %.4f %.4f\n", v[int((NR + 1) / 2)], v[1], v[NR] }'
}
rows=""
for scene in scenes/cornell-box/scene.json scenes/caustic/scene.json scenes/atrium/scene.json scenes/atrium/textured.json; do
    read -r g glo ghi <<<"$(load_time PMTK_SCENE_CACHE=)"
    read -r h hlo hhi <<<"$(load_time PMTK_SCENE_CACHE= GLIBC_TUNABLES=glibc.malloc.hugetlb=1)"
    read -r p plo phi <<<"$(load_time PMTK_SCENE_CACHE= PMTK_IMPORT_SECONDS=0 PMTK_IMPORT_MB=0)"
    rm -f "$L/c.cache"
    PMTK_SCENE_CACHE=$L/c.cache "$BIN/scene-info" "$scene" >/dev/null
    read -r c clo chi <<<"$(load_time PMTK_SCENE_CACHE="$L/c.cache")"
    tris=$("$BIN/scene-info" "$scene" | sed -n 's/^triangles: \([0-9]*\).*/\1/p')
    mb=$(du -k "$L/c.cache" | awk '{ printf "%.1f", $1 / 1024 }')
    rows+=$(awk -v s="$scene" -v t="$tris" -v g=$g -v glo=$glo -v ghi=$ghi -v h=$h -v hlo=$hlo -v hhi=$hhi -v p=$p -v plo=$plo -v phi=$phi \
        -v c=$c -v clo=$clo -v chi=$chi -v mb=$mb 'BEGIN {
        hit = c > 0 ? sprintf("%.3f (%.3f to %.3f)", c, clo, chi) : "below 0.001 (scene-info says ms)"
        ratio = c > 0 ? sprintf("%.0f", g / c) : sprintf("over %.0f", g / 0.001)
        printf "| %s | %d | %.3f (%.3f to %.3f) | %.3f (%.3f to %.3f) | %.3f (%.3f to %.3f) | %s | %s | %s |\n",
        s, t, g, glo, ghi, h, hlo, hhi, p, plo, phi, hit, mb, ratio }')$'\n'
done
cat >>"$MD" <<MD

## Loading a scene

scene-info's \`time: load\` (the scene loaded, checked and hashed; no ray tracer), seconds:
the guarded load every program makes by default (one forked child imports the meshes, decodes
the textures and hands the scene back through a pipe), the same with glibc's malloc on 2 MiB pages
(\`GLIBC_TUNABLES=glibc.malloc.hugetlb=1\`, which pm-render, pm-frames and trace-reference give
themselves and their stages: docs/cli.md, "Huge pages for malloc"), the load in the process
(\`PMTK_IMPORT_SECONDS=0 PMTK_IMPORT_MB=0\`), and a hit of the scene cache (\`PMTK_SCENE_CACHE\`, as pm-render's stages and
reruns read it). The cache's size on disk, and how many times faster a hit is than the guarded load,
within this run.

| scene | triangles | guarded load | guarded, huge pages | in the process | cache hit | cache MB | guarded / hit |
|---|---|---|---|---|---|---|---|
${rows}
MD
