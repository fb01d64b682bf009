#!/usr/bin/env bash
# pipelines/examples.sh: the shell compositions of docs/pipelines.md, runnable.
#
#   pipelines/examples.sh [OUTDIR]      (default out/examples)
#
# Stages chained through pipes with no temporary files, and stages swapped for others. Each
# example prints its name; any failure (a missing program included) stops the script with a
# non-zero status. Small settings, so that the whole script runs in seconds.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PATH=${BIN:-$ROOT/bin}:$PATH
OUT=${1:-out/examples}
SCENE=$ROOT/scenes/cornell-box/scene.json
mkdir -p "$OUT"
cd "$OUT"
example() { echo "== $1"; }

example "1. photons straight into the map: no photons file"
trace-photons -q "$SCENE" --photons 20000 -o - | build-photonmap -q - -o map.pm

example "2. gather points, sorted, gathered: no queries file (the direct light goes to --direct)"
trace-gather-points -q "$SCENE" --width 64 --height 64 --spp 4 -o - --direct direct.pm |
    hilbert-sort -q - -o - |
    simd-gather -q map.pm - -o indirect.pm
composite -q direct.pm indirect.pm -o image.exr --png image.png

example "3. swap the sort: no reordering (queries in pixel order), then Morton order"
trace-gather-points -q "$SCENE" --width 64 --height 64 --spp 4 -o - --direct direct.pm |
    simd-gather -q map.pm - -o indirect-unsorted.pm
trace-gather-points -q "$SCENE" --width 64 --height 64 --spp 4 -o - --direct direct.pm |
    hilbert-sort -q - --order morton -o - |
    simd-gather -q map.pm - -o indirect-morton.pm
# the order changes the speed, not the answer (up to the order of f64 additions)
pm-compare --max-rel 1e-5 --max-abs 1e-12 indirect.pm indirect-morton.pm >/dev/null

example "4. swap the gather's input: the map's own estimate seen directly (direct-vis)"
trace-gather-points -q "$SCENE" --width 64 --height 64 --mode direct-vis -o - |
    simd-gather -q map.pm - -o dv.pm
composite -q dv.pm -o direct-vis.exr --png direct-vis.png

example "5. a gather in two shards, added by composite"
trace-gather-points -q "$SCENE" --width 64 --height 64 --spp 4 -o - | hilbert-sort -q - -o sorted.pm
n=$(pm-info --header --json sorted.pm | jq -e .count)
simd-gather -q map.pm sorted.pm --range 0:$((n / 2)) -o shard0.pm
simd-gather -q map.pm sorted.pm --range $((n / 2)): -o shard1.pm
composite -q direct.pm shard0.pm shard1.pm -o sharded.exr

example "6. the direct light alone, brighter, with the filmic curve; half floats"
composite -q direct.pm --only direct -o direct.exr --half --png direct.png --exposure 1 --tone filmic

example "7. what made a file: its header carries every command line"
pm-info --header --json direct.pm | jq -r '.commands[]'
echo "examples: done; files in $PWD"
