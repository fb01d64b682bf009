# 97-environment.sh: what sampling a lat-long OpenEXR sky costs against a constant sky (sourced
# by tests/bench/run). The scene is the atrium's sky-lit, textured variant
# (scenes/atrium/textured.json) lit by its sky alone: a constant one (cosine-weighted sky samples,
# pdf cos / pi), then the same sky as a map (pm_envmap_t: a pixel by luminance, a row then a
# column by binary search, then a point in it; the pdf looked up per BSDF sample too). The map is
# an image rendered here, trace-reference's Cornell box at 256 x 128 (a bright lamp in a dark
# frame: far from uniform, the case importance sampling is for). trace-reference's rays/s and
# paths/s, and trace-photons' photon paths/s (a map's photons are drawn from it as well).
# Medians of RUNS runs with min and max, 2 threads.
size=128 spp=16 photons=1000000
[ "$QUICK" = 1 ] && size=64 spp=4 photons=200000
E=$TMP/env
mkdir -p "$E"
"$BIN/trace-reference" scenes/cornell-box/scene.json -q --width 256 --height 128 --spp 16 -o "$E/sky.exr"
atr=$PWD/scenes/atrium/atrium-sky.obj
for kind in constant map; do
    if [ $kind = constant ]; then sky='"sky": { "radiance": [1, 1, 1] }'; else sky='"sky": { "map": "sky.exr" }'; fi
    cat >"$E/$kind.json" <<JSON
{ "pmtk_scene": 1, "name": "atrium-$kind-sky", "meshes": [ { "file": "$atr" } ],
  "camera": { "eye": [-13.0, 1.7, 0.0], "look_at": [10.0, 4.5, 0.0], "up": [0, 1, 0], "fov_y": 60, "width": $size, "height": $size },
  $sky }
JSON
done
rows=""
declare -A env_rate=()
for kind in constant map; do
    out=$(median_stats "rays_per_s trace_s" "$BIN/trace-reference" "$E/$kind.json" -q --spp $spp --pass $spp --threads 2 \
        -o "$E/r.exr" --stats "$TMP/stats.json")
    { read -r rate lo hi; read -r ts _ _; } <<<"$out"
    paths=$(bench_stat paths "$TMP/stats.json")
    env_rate[$kind]=$rate
    out=$(median_stats "wall_s" "$BIN/trace-photons" "$E/$kind.json" -q --photons $photons --threads 2 -o "$E/p.pm" \
        --stats "$TMP/stats.json")
    read -r pw plo phi <<<"$out"
    rows+=$(awk -v k=$kind -v r=$rate -v lo=$lo -v hi=$hi -v ts=$ts -v p=$paths -v n=$photons -v pw=$pw -v plo=$plo -v phi=$phi \
        'BEGIN { printf "| %s | %.2f (%.2f to %.2f) | %.3f | %.0f | %.2f (%.2f to %.2f) |\n",
        k, r / 1e6, lo / 1e6, hi / 1e6, ts, p / ts, n / pw / 1e6, n / phi / 1e6, n / plo / 1e6 }')$'\n'
done
rm -f "$E/r.exr" "$E/p.pm"
ratio=$(awk -v a=${env_rate[constant]} -v b=${env_rate[map]} 'BEGIN { printf "%.2f", b / a }')
unset env_rate
cat >>"$MD" <<MD

## Environment sampling

trace-reference and trace-photons on the textured atrium (scenes/atrium/textured.json's
geometry) lit by a sky alone, ${size}x${size} pixels, $spp samples per pixel, $photons photon paths,
2 threads: a constant sky against the same sky as a 256 x 128 OpenEXR map (a rendered image, far
from uniform). The map's directions are drawn by luminance and its pdf is looked up for every
BSDF sample that escapes (MIS); paths differ between the two, so rays/s is the fair figure.

| sky | trace-reference rays/s, M | trace s | paths/s | trace-photons paths/s, M |
|---|---|---|---|---|
${rows}
The map's rays/s over the constant sky's, within this run: ${ratio}.
MD
