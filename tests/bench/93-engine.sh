# 93-engine.sh: what the render driver costs beyond the stages (sourced by tests/bench/run;
# issue 26's goals), pipelines/render being bin/pm-render (common/engine: the scene loaded
# in-process, each file hashed whole, the stages spawned; no make, stamps or seals). On the
# Cornell box: (1) a rerun with nothing to do, at the scene's own settings (256x256, 500,000
# photons; QUICK=1: the small render below): goal at most 0.1 s wall. (2) A 64x48 render of
# 2,000 photons from an empty OUTDIR: goal at most 0.5 s. (3) A rerun with nothing to do of
# four progressive passes kept as files (KEEP=all, the small render's settings): every pass's
# files read whole, each pass added to the running image again only when it is not in it.
# Median of RUNS runs, min to max in brackets, with the load average (1, 5, 15 min) before
# and after.
S=scenes/cornell-box/scene.json
SMALL="WIDTH=64 HEIGHT=48 PHOTONS=2000"
BIG="" what="the scene's settings: 256x256, 500,000 photons"
[ "$QUICK" = 1 ] && BIG=$SMALL what=$SMALL
load0=$(cut -d' ' -f1-3 /proc/loadavg)
# shellcheck disable=SC2086 # the parameter lists are words
engine_fresh() { rm -rf "$TMP/eng-small" && pipelines/render $S "$TMP/eng-small" $SMALL; }
# shellcheck disable=SC2086
BIN=$BIN pipelines/render $S "$TMP/eng-big" $BIG >/dev/null
# shellcheck disable=SC2086
BIN=$BIN pipelines/render $S "$TMP/eng-passes" $SMALL PASSES=4 KEEP=all >/dev/null
# shellcheck disable=SC2086
read -r na_m na_lo na_hi < <(median_spread env BIN="$BIN" pipelines/render $S "$TMP/eng-big" $BIG)
read -r sa_m sa_lo sa_hi < <(median_spread engine_fresh)
# shellcheck disable=SC2086
read -r pa_m pa_lo pa_hi < <(median_spread env BIN="$BIN" pipelines/render $S "$TMP/eng-passes" $SMALL PASSES=4 KEEP=all)
load1=$(cut -d' ' -f1-3 /proc/loadavg)
rm -rf "$TMP"/eng-*
f() { awk -v m="$1" -v a="$2" -v b="$3" 'BEGIN { printf "%.3f s (%.3f to %.3f)", m, a, b }'; }
cat >>"$MD" <<MD

## The render driver: a rerun with nothing to do, a small render

\`pipelines/render\` (\`bin/pm-render\`, provenance alone; tests/bench/93-engine.sh) on the
Cornell box. Wall seconds of the whole command, median of $RUNS runs (min to max). Load
average (1, 5, 15 min) from other jobs: $load0 before, $load1 after.

| what | wall | goal |
|---|---|---|
| a rerun with nothing to do ($what) | $(f "$na_m" "$na_lo" "$na_hi") | 0.1 s |
| $SMALL from an empty OUTDIR | $(f "$sa_m" "$sa_lo" "$sa_hi") | 0.5 s |
| a rerun with nothing to do, $SMALL PASSES=4 KEEP=all (pass files) | $(f "$pa_m" "$pa_lo" "$pa_hi") | |
MD
