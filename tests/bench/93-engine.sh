# 93-engine.sh: what the render driver costs beyond the stages (sourced by tests/bench/run;
# issue 26's goals). Two figures on the Cornell box, each before and after: "before" is the make
# graph of pipelines/lib/render-make (what pipelines/render was, and still is for passes: a
# Makefile, stamps, scene-info and jq, pm-info on every file), "after" is pipelines/render, which
# is bin/pm-render (common/engine: the scene loaded in-process, each file mapped and hashed, the
# stages spawned). (1) A rerun with nothing to do, at the scene's own settings (256x256,
# 500,000 photons; QUICK=1: the small render below): goal at most 0.1 s wall. (2) A 64x48
# render of 2,000 photons from an empty OUTDIR: goal at most 0.5 s. Median of RUNS runs, min to
# max in brackets, with the load average (1, 5, 15 min) before and after.
S=scenes/cornell-box/scene.json
SMALL="WIDTH=64 HEIGHT=48 PHOTONS=2000"
BIG="" what="the scene's settings: 256x256, 500,000 photons"
[ "$QUICK" = 1 ] && BIG=$SMALL what=$SMALL
load0=$(cut -d' ' -f1-3 /proc/loadavg)
# shellcheck disable=SC2086 # the parameter lists are words
engine_fresh() { rm -rf "$TMP/eng-$1" && "$2" $S "$TMP/eng-$1" $SMALL; }
BIN=$BIN pipelines/lib/render-make $S "$TMP/eng-big-before" $BIG >/dev/null
BIN=$BIN pipelines/render $S "$TMP/eng-big-after" $BIG >/dev/null
# shellcheck disable=SC2086
read -r nb_m nb_lo nb_hi < <(median_spread env BIN="$BIN" pipelines/lib/render-make $S "$TMP/eng-big-before" $BIG)
# shellcheck disable=SC2086
read -r na_m na_lo na_hi < <(median_spread env BIN="$BIN" pipelines/render $S "$TMP/eng-big-after" $BIG)
read -r sb_m sb_lo sb_hi < <(median_spread engine_fresh before pipelines/lib/render-make)
read -r sa_m sa_lo sa_hi < <(median_spread engine_fresh after pipelines/render)
load1=$(cut -d' ' -f1-3 /proc/loadavg)
rm -rf "$TMP"/eng-*
f() { awk -v m="$1" -v a="$2" -v b="$3" 'BEGIN { printf "%.3f s (%.3f to %.3f)", m, a, b }'; }
cat >>"$MD" <<MD

## The render driver: a rerun with nothing to do, a small render

\`pipelines/render\` on the Cornell box before (the make graph, now \`pipelines/lib/render-make\`)
and after (\`bin/pm-render\`, provenance alone; tests/bench/93-engine.sh). Wall seconds of the
whole command, median of $RUNS runs (min to max). Load average (1, 5, 15 min) from other jobs:
$load0 before, $load1 after.

| what | before | after | goal |
|---|---|---|---|
| a rerun with nothing to do ($what) | $(f "$nb_m" "$nb_lo" "$nb_hi") | $(f "$na_m" "$na_lo" "$na_hi") | 0.1 s |
| $SMALL from an empty OUTDIR | $(f "$sb_m" "$sb_lo" "$sb_hi") | $(f "$sa_m" "$sa_lo" "$sa_hi") | 0.5 s |
MD
