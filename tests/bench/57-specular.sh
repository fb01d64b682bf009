# 57-specular.sh: mirrors and glass (issue 18), sourced by tests/bench/run; alone: make bench
# BENCH=specular. Photon tracing through specular bounces with and without the caustic output,
# the eye tracer's chains and caustic queries, and the caustic gather beside the global one, on
# scenes/caustic when it exists, else on a scene made here of the same kind (a glass ball and a
# mirror on the diffuse floor of a closed room lit by an area light in the ceiling).
P=${PHOTONS:-1000000}
[ "$QUICK" = 1 ] && P=100000
SC=scenes/caustic/scene.json
if [ ! -f "$SC" ]; then
    SC=$TMP/caustic/scene.json
    mkdir -p "$TMP/caustic"
    awk -v r=0.3 -v ns=48 'BEGIN {
        pi = 3.141592653589793; nr = ns / 2
        print "mtllib c.mtl"
        print "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2"                        # floor 1-4
        print "v -0.5 2.49 -0.5\nv 0.5 2.49 -0.5\nv 0.5 2.49 0.5\nv -0.5 2.49 0.5" # light 5-8
        print "v 0.4 0 0.8\nv 1.4 0 0.3\nv 1.4 1 0.3\nv 0.4 1 0.8"            # mirror 9-12
        print "v -2 2.5 -2\nv 2 2.5 -2\nv 2 2.5 2\nv -2 2.5 2"                # ceiling 13-16
        print "usemtl floor\nf 1 4 3 2\nusemtl light\nf 5 6 7 8\nusemtl mirror\nf 9 10 11 12"
        # the walls and the ceiling, facing in
        print "usemtl wall\nf 13 14 15 16\nf 1 2 14 13\nf 2 3 15 14\nf 3 4 16 15\nf 4 1 13 16"
        print "v 0 " (0.5 + r) " 0"; base = 18
        for (j = 1; j < nr; j++) for (k = 0; k < ns; k++) {
            t = pi * j / nr; p = 2 * pi * k / ns
            printf "v %.9g %.9g %.9g\n", r * sin(t) * cos(p), 0.5 + r * cos(t), r * sin(t) * sin(p)
        }
        south = base + (nr - 1) * ns; print "v 0 " (0.5 - r) " 0"
        print "usemtl glass"
        for (k = 0; k < ns; k++) {
            k1 = (k + 1) % ns
            printf "f 17 %d %d\n", base + k1, base + k
            for (j = 1; j < nr - 1; j++) { a = base + (j - 1) * ns; b = a + ns
                printf "f %d %d %d %d\n", a + k, a + k1, b + k1, b + k }
            a = base + (nr - 2) * ns
            printf "f %d %d %d\n", south, a + k, a + k1
        }
    }' >"$TMP/caustic/c.obj"
    printf 'newmtl floor\nKd 0.8 0.8 0.8\nnewmtl wall\nKd 0.6 0.6 0.6\nnewmtl light\nKd 0 0 0\nKe 8 8 8
newmtl mirror\nKs 0.9 0.9 0.9\nillum 3
newmtl glass\nNi 1.5\nTf 1 1 1\nillum 7\n' >"$TMP/caustic/c.mtl"
    cat >"$SC" <<JSON
{ "pmtk_scene": 1, "name": "bench-caustic", "meshes": [ { "file": "c.obj" } ],
  "camera": { "eye": [0, 1.4, -1.9], "look_at": [0, 0.3, 0.2], "up": [0, 1, 0], "fov_y": 45, "width": 256, "height": 256 },
  "render": { "photons": 500000, "spp": 16, "seed": 1 } }
JSON
fi
W=256
[ "$QUICK" = 1 ] && W=128

# trace-photons: the same photons with and without the caustic photons file.
tp_rows=""
for caus in no yes; do
    extra=()
    [ $caus = yes ] && extra=(--caustic-output "$TMP/cph.pm")
    for t in 1 2; do
        cmd=("$BIN/trace-photons" "$SC" --photons "$P" --threads $t -q -o "$TMP/ph.pm" "${extra[@]}" --stats "$TMP/stats.json")
        { read -r rate rlo rhi; read -r wall wlo whi; } < <(median_stats "rays_per_s wall_s" "${cmd[@]}")
        tp_rows+=$(awk -v c=$caus -v t=$t -v r=$rate -v lo=$rlo -v hi=$rhi -v w=$wall -v wlo=$wlo -v whi=$whi -v p=$P \
            -v rays="$(bench_stat rays "$TMP/stats.json")" -v sb="$(bench_stat specular_bounces "$TMP/stats.json")" \
            -v st="$(bench_stat stored "$TMP/stats.json")" -v ca="$(bench_stat caustic "$TMP/stats.json")" 'BEGIN {
            printf "| %s | %d | %.2f (%.2f to %.2f) | %.2f | %.3f (%.3f to %.3f) | %.2f | %.2f | %d | %s |\n",
                c, t, r / 1e6, lo / 1e6, hi / 1e6, r / t / 1e6, w, wlo, whi, p / w / 1e6, sb / rays, st, ca == "" ? "-" : ca }')
        tp_rows+=$'\n'
    done
done
"$BIN/build-photonmap" "$TMP/ph.pm" -q -o "$TMP/map.pm"
"$BIN/build-photonmap" "$TMP/cph.pm" -q --map caustic -o "$TMP/cmap.pm"

# trace-gather-points: with and without the caustic queries.
eye_rows=""
for caus in no yes; do
    extra=()
    [ $caus = yes ] && extra=(--caustic-queries "$TMP/cq.pm")
    cmd=("$BIN/trace-gather-points" "$SC" --width $W --height $W --spp 16 -q -o "$TMP/q.pm" --direct "$TMP/d.pm"
        "${extra[@]}" --stats "$TMP/stats.json")
    { read -r sr srlo srhi; read -r wall wlo whi; } < <(median_stats "secondary_rays_per_cpu_s wall_s" "${cmd[@]}")
    eye_rows+=$(awk -v c=$caus -v sr=$sr -v lo=$srlo -v hi=$srhi -v w=$wall -v wlo=$wlo -v whi=$whi \
        -v pr="$(bench_stat primary_rays "$TMP/stats.json")" -v sp="$(bench_stat specular_rays "$TMP/stats.json")" \
        -v q="$(bench_stat queries "$TMP/stats.json")" -v cq="$(bench_stat caustic_queries "$TMP/stats.json")" 'BEGIN {
        printf "| %s | %.2f (%.2f to %.2f) | %.3f (%.3f to %.3f) | %.3f | %d | %s |\n",
            c, sr / 1e6, lo / 1e6, hi / 1e6, w, wlo, whi, sp / pr, q, cq == "" ? "-" : cq }')
    eye_rows+=$'\n'
done

# The two gathers of one render: the global map at the secondary hits, the caustic map at the
# primary hits.
gather_rows=""
for g in global caustic; do
    map=$TMP/map.pm q=$TMP/q.pm
    [ $g = caustic ] && map=$TMP/cmap.pm q=$TMP/cq.pm
    for t in 1 2; do
        cmd=("$BIN/simd-gather" "$map" "$q" --threads $t -q -o "$TMP/g.pm" --stats "$TMP/stats.json")
        { read -r so solo sohi; read -r gs gslo gshi; } < <(median_stats "shader_ops_per_s gather_s" "${cmd[@]}")
        gather_rows+=$(awk -v g=$g -v t=$t -v so=$so -v lo=$solo -v hi=$sohi -v gs=$gs -v gslo=$gslo -v gshi=$gshi \
            -v nq="$(bench_stat queries "$TMP/stats.json")" -v np="$(bench_stat photons "$TMP/stats.json")" \
            -v r="$(bench_stat radius_m "$TMP/stats.json")" 'BEGIN {
            printf "| %s | %d | %d | %d | %.4g | %.1f (%.1f to %.1f) | %.3f (%.3f to %.3f) | %.2f |\n",
                g, t, nq, np, r, so / 1e6, lo / 1e6, hi / 1e6, gs, gslo, gshi, nq / gs / 1e6 }')
        gather_rows+=$'\n'
    done
done
rm -f "$TMP"/ph.pm "$TMP"/cph.pm "$TMP"/map.pm "$TMP"/cmap.pm "$TMP"/q.pm "$TMP"/cq.pm "$TMP"/d.pm "$TMP"/g.pm

cat >>"$MD" <<MD

## Mirrors, glass and caustics

Scene: \`${SC#"$TMP"/}\` ($( [ "$SC" = scenes/caustic/scene.json ] && echo "the shipped caustic scene" || echo "made by tests/bench/57-specular.sh: a 4 x 2.5 x 4 m room of Kd 0.6 walls, a glass ball (Ni 1.5, 2208 triangles) and a Ks 0.9 mirror on its Kd 0.8 floor, a 1 m area light in the ceiling")).
Photon tracing, $P photons: rays are segments, the specular ones included; "specular" is the
share of them that hit a mirror or glass (never stored); "caustic" is the photons stored in the
caustic file (L S+ D), every one of which is in the global file too.

| caustic output | threads | rays/s, M | per thread, M | wall s | photons/s, M | specular hits per ray | stored | caustic |
|---|---|---|---|---|---|---|---|---|
$tp_rows
The eye tracer, $W × $W, spp 16, one primary ray a pixel: secondary rays per CPU second of the
tracing loop; chains through mirrors and glass are single rays ("specular per primary" counts
them, the secondary rays' chains included, per primary ray).

| caustic queries | secondary rays per CPU s, M | wall s | specular per primary | queries | caustic queries |
|---|---|---|---|---|---|
$eye_rows
The gathers (simd-gather, the scene's kernel: about 50 photons), the global map against the
queries at the secondary hits and the caustic map against the caustic queries (one per
primary ray), unsorted:

| map | threads | queries | photons | radius m | shader ops/s, M | gather s | queries/s, M |
|---|---|---|---|---|---|---|---|
$gather_rows
MD
