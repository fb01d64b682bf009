# 96-scenes.sh: what real-scene features cost (sourced by tests/bench/run).
#   Instancing: one generated mesh (a UV sphere of 39,600 triangles) placed once and 100 times,
#   built flat ("instancing": false) and with Embree instances: scene-info's BVH build time
#   (medium quality, as scene-info builds it) and load time, and the process's peak memory
#   (GNU time's maximum resident set, which includes pmtk's flattened arrays: the tracers still
#   read every placement's triangles there, docs/scene-format.md); then trace-reference's rays/s
#   over the 100 placements, flat and instanced.
#   Textures: the atrium and the Cornell box as shipped, and with map_Kd (a 512 x 512 PNG) on
#   every material and texture coordinates added to every vertex (u from x + z, v from y, one
#   repeat per 2 m): trace-reference's and trace-gather-points' rays/s and time. The texture
#   darkens the scene (texels below 1 scale Kd), so paths end sooner: the time per ray is the
#   fair figure, and rays/s are given beside it.
# Medians of RUNS runs with min and max.
source tests/scenes/make-analytic.sh
size=96 spp=16
[ "$QUICK" = 1 ] && size=48 spp=4

mkdir -p "$TMP/inst"
sphere_obj 0.4 200 out >"$TMP/inst/sphere.obj"
printf 'newmtl wall\nKd 0.5 0.5 0.5\n' >"$TMP/inst/sphere.mtl"
ntri=
# inst_scene N FLAG: N placements on a 10-wide grid, "instancing": FLAG, into $TMP/inst/N-FLAG.json
inst_scene() {
    local n=$1 flag=$2 i meshes=""
    for i in $(seq 0 $((n - 1))); do
        meshes+="${meshes:+, }{ \"file\": \"sphere.obj\", \"translate\": [$((i % 10)), 0, $((i / 10))] }"
    done
    cat >"$TMP/inst/$n-$flag.json" <<JSON
{ "pmtk_scene": 1, "name": "spheres", "instancing": $flag, "meshes": [ $meshes ],
  "camera": { "eye": [4.5, 6, -6], "look_at": [4.5, 0, 4.5], "fov_y": 60, "width": $size, "height": $size },
  "point_lights": [ { "position": [4.5, 8, 4.5], "intensity": [100, 100, 100] } ] }
JSON
}
rows=""
for n in 1 100; do
    for flag in false true; do
        inst_scene $n $flag
        S=$TMP/inst/$n-$flag.json
        out=$(median_stats "bvh_s load_s" "$BIN/scene-info" "$S" -q --threads 2 --stats "$TMP/stats.json")
        { read -r bvh bvh_lo bvh_hi; read -r load _ _; } <<<"$out"
        [ $n = 1 ] && ntri=$(bench_stat triangles "$TMP/stats.json")
        rss=$(for i in $(seq "$RUNS"); do /usr/bin/time -f %M "$BIN/scene-info" "$S" -q --threads 2 2>&1 >/dev/null | tail -n 1; done |
            sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }')
        rows+=$(awk -v n=$n -v f=$flag -v t=$((n * ntri)) -v b=$bvh -v lo=$bvh_lo -v hi=$bvh_hi -v l=$load -v m=$rss \
            'BEGIN { printf "| %d | %s | %d | %.4f (%.4f to %.4f) | %.3f | %.1f |\n", n, f == "true" ? "instanced" : "flat", t, b, lo, hi, l, m / 1024 }')$'\n'
    done
done
trows=""
for flag in false true; do
    out=$(median_stats "rays_per_s" "$BIN/trace-reference" "$TMP/inst/100-$flag.json" -q --spp $spp --pass $spp --threads 2 \
        -o "$TMP/tr.exr" --stats "$TMP/stats.json")
    read -r rate lo hi <<<"$out"
    trows+=$(awk -v f=$flag -v r=$rate -v lo=$lo -v hi=$hi \
        'BEGIN { printf "| %s | %.2f (%.2f to %.2f) |\n", f == "true" ? "instanced" : "flat", r / 1e6, lo / 1e6, hi / 1e6 }')$'\n'
done

# Textures: a 512 x 512 PNG rendered from a lit floor (composite's preview of its direct light:
# bright in the middle, nowhere black).
make_lit_plane "$TMP/floor" 1 3.14159 0.8
jq '.camera.width = 512 | .camera.height = 512' "$TMP/floor/scene.json" >"$TMP/floor/big.json"
"$BIN/trace-gather-points" "$TMP/floor/big.json" --mode direct-vis -q -o "$TMP/tex.q.pm" --direct "$TMP/tex.d.pm"
"$BIN/composite" "$TMP/tex.d.pm" -q -o "$TMP/tex.exr" --png "$TMP/tex.png"
xrows=""
for scene in cornell-box atrium; do
    rm -rf "$TMP/$scene-tex"
    cp -r scenes/$scene "$TMP/$scene-tex"
    cp "$TMP/tex.png" "$TMP/$scene-tex/tex.png"
    mtl=$(ls "$TMP/$scene-tex"/*.mtl)
    obj=$(ls "$TMP/$scene-tex"/*.obj)
    awk '{ print } /^newmtl / { print "map_Kd tex.png" }' "$mtl" >"$mtl.new" && mv "$mtl.new" "$mtl"
    # a texture coordinate per vertex (the Cornell box is in mm, the atrium in m), faces using them
    unit=$([ $scene = cornell-box ] && echo 1000 || echo 1)
    awk -v k=$unit '$1 == "v" { print; printf "vt %.6f %.6f\n", ($2 + $4) / (2 * k), $3 / (2 * k); next }
        $1 == "f" { printf "f"; for (i = 2; i <= NF; i++) printf " %s/%s", $i, $i; print ""; next } { print }' \
        "$obj" >"$obj.new" && mv "$obj.new" "$obj"
    declare -A rr=() rg=()
    for v in plain textured; do
        S=scenes/$scene/scene.json
        [ $v = textured ] && S=$TMP/$scene-tex/scene.json
        out=$(median_stats "rays_per_s" "$BIN/trace-reference" "$S" -q --width $size --height $size --spp $spp \
            --pass $spp --threads 2 -o "$TMP/tr.exr" --stats "$TMP/stats.json")
        read -r rate lo hi <<<"$out"
        rr[$v]=$rate
        out2=$(median_stats "rays_per_s trace_s" "$BIN/trace-gather-points" "$S" -q --width $size --height $size \
            --spp 16 --threads 2 -o "$TMP/q.pm" --stats "$TMP/stats.json")
        { read -r grate glo ghi; read -r gt _ _; } <<<"$out2"
        rg[$v]=$grate
        xrows+=$(awk -v s=$scene -v v=$v -v r=$rate -v lo=$lo -v hi=$hi -v g=$grate -v glo=$glo -v ghi=$ghi -v gt=$gt \
            'BEGIN { printf "| %s | %s | %.2f (%.2f to %.2f) | %.2f (%.2f to %.2f) | %.3f |\n", s, v, r / 1e6, lo / 1e6, hi / 1e6, g / 1e6, glo / 1e6, ghi / 1e6, gt }')$'\n'
    done
    xrows+=$(awk -v s=$scene -v a=${rr[plain]} -v b=${rr[textured]} -v c=${rg[plain]} -v d=${rg[textured]} \
        'BEGIN { printf "| %s | textured / plain | %.3f | %.3f | |\n", s, b / a, d / c }')$'\n'
    unset rr rg
done
rm -f "$TMP/tr.exr" "$TMP/q.pm"

cat >>"$MD" <<MD

## Real scenes: instancing and textures

Instancing: a UV sphere of $ntri triangles placed once and 100 times (docs/scene-format.md,
Transforms), built flat (\`"instancing": false\`) or with one Embree copy of the mesh and an
instance per placement. scene-info on 2 threads: BVH build (medium quality) and load time, and
the peak resident memory of the whole process, which holds pmtk's flattened arrays for every
placement in both cases (the tracers read a hit's triangle there). With one placement nothing
is repeated, so both rows are the same flat build.

| placements | build | triangles | BVH build s | load s | peak memory, MiB |
|---|---|---|---|---|---|
${rows}
trace-reference over the 100 placements, ${size}x${size} pixels, $spp samples per pixel, 2 threads:

| build | rays/s, M |
|---|---|
${trows}
Textures: the scenes as shipped and with \`map_Kd\` (a 512 x 512 PNG) on every material and
texture coordinates on every vertex (one repeat per 2 m); ${size}x${size} pixels, 2 threads;
trace-reference at $spp samples per pixel, trace-gather-points in gather mode at 16 secondary
rays per pixel (its rays/s counts primary, shadow and secondary rays; a dark texel reflects no
secondary rays, so its ray count and time fall with the texture's mean, and rays/s is the
figure to compare). An untextured scene takes the same code as before the feature (one branch
per hit).

| scene | materials | trace-reference rays/s, M | trace-gather-points rays/s, M | trace-gather-points trace s |
|---|---|---|---|---|
${xrows}
MD
