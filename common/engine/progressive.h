/* progressive.h: pm-render's resident progressive passes (issue 26, items 2 and 3;
 * docs/pipelines.md, "Progressive passes").
 *
 * The stages start once and stay alive across the passes, each taking a stream of documents,
 * a document per pass (docs/formats.md, "Streams"):
 *
 *   plan -> trace-photons --plan - | build-photonmap --stream ------------\
 *   plan -> trace-gather-points --plan - | hilbert-sort --stream -> simd-gather --stream pairs
 *                       \-- direct ---------------------------------------> composite --stream
 *                                                        --accumulate running.pm -> image.exr, image.png
 *
 * with the stages the pass files' driver would run for the settings: for a scene with mirrors
 * or glass in gather mode the caustic branch beside them (trace-photons --caustic-output into
 * build-photonmap --map caustic, trace-gather-points --caustic-queries, both into a second
 * simd-gather --stream pairs --k-each-pass, its buffer composite's third stream); MODE=direct-vis
 * (one query per pixel, no hilbert-sort unless ORDER asks, the direct buffer only over
 * MAP=indirect); ORDER=none (the queries straight into the gather); GATHER=none
 * (trace-gather-points --no-queries: the direct buffer alone). Each pass's records are those
 * of the pass files (KEEP=all) for the same settings.
 *
 * The driver writes a line per pass to the two tracers' plans ("PASS [SIZE]") and waits for
 * composite's pass log to say the pass is in the running image before it sizes the next, so
 * that PASSES, TIME and TARGET_ERROR stop exactly where they say. No pass directories:
 * OUTDIR keeps running.pm (the mean and variance of the passes), passes.txt (the settings the
 * running image was made with, the last request, and a line per pass: its size and the running
 * image's relative error after it), image.exr, image.png and stats.json. A rerun with the same
 * settings adds passes to the running image (PASSES=8 after PASSES=4 traces passes 5 to 8); one
 * that changes only EXPOSURE, TONE or HALF re-tones running.pm and adds no pass.
 *
 * TIME=T is a budget for the whole command, counted from t0: passes start small (1/PRIMARY of
 * the per-pass size: PHOTONS/PRIMARY photons, one primary ray per pixel) and double up to the
 * per-pass size, sized from the wall time of the passes so far on this scene (a bound of
 * each pass's time by every earlier one's); the last pass is sized to end at the budget. */
#ifndef PM_ENGINE_PROGRESSIVE_H
#define PM_ENGINE_PROGRESSIVE_H

#include <stddef.h>

#include "engine/engine.h"

/* 1 when the resident passes render these settings; else 0 and why (the caller then makes
 * the passes as files, pm_render_passes in fixed.c): KEEP=all given on the command line or
 * PASS_RANGE (pass files asked for), and what the resident chain does not run yet (GATHER
 * other than simd-gather or none, SHARDS, WIDTHS=variable, TARGETs), or refuses with the
 * pass files' own message (MAP=indirect in gather mode; GATHER=none with nothing to add). */
int pm_progressive_handles(const pm_settings_t *s, char *why, size_t cap);

/* Renders the progressive passes of s into s->outdir (created), as described above: the lock
 * on OUTDIR/.lock (cmdline is what it records), the scene loaded once for its content hash and
 * what it holds, the stages started from bin (absolute), the passes, the table on stdout and
 * stats.json. t0 is pm_time_wall() at the start of the command (TIME counts from it). me
 * starts every message ("render"). Returns the exit status: 0 ok, 1 a stage or the scene
 * failed, 3 the system (a pipe, a process, the disk); or -1, having written nothing, for a
 * an OUTDIR that holds pass directories (KEEP=all before, pipelines/slurm's tasks): those go
 * on as pass files. RENDER_PASS_HOOK in the environment is run after every pass, as the pass
 * files' driver runs it (HOOK PASS SECONDS IMAGE). */
int pm_render_progressive(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline, double t0);

/* The size of the next pass of a TIME budget, in units of 1/kmax of the per-pass size, given
 * the passes so far (k[i] units took sec[i] s of wall time, i < n), the seconds left
 * (remaining) and kmax (at least 1): the last size doubled, up to kmax, when it and the pass
 * that would follow it fit; else the last pass, the largest whose time bound, plus 5%, ends
 * by the budget (at most kmax units: the time left after it goes to smaller passes); 0 when
 * not even one unit fits. A pass of u units is taken to
 * last at most the least of sec[j] max(1, u / k[j]) over the passes so far. Exposed for the
 * unit tests. */
int pm_progressive_next_size(const int *k, const double *sec, int n, int kmax, double remaining);

/* The same for a pass at which simd-gather --coverage would sample the scene at a new spacing
 * level, whose sampling is foreseen to take `extra` s: the size with that time set aside; or,
 * when the new level is one finer than the last pass's (holdable) and the sampling does not fit
 * or would take half or more of what the pass could do without it, the size without it, and
 * *hold_out 1: the pass keeps the samples it has (simd-gather --coverage-plan). Exposed for the
 * unit tests. */
int pm_progressive_cover_size(const int *k, const double *sec, int n, int kmax, double remaining, double extra,
                              int holdable, int *hold_out);

/* Whether a pass of `units` keeps the caustic gather's coverage samples (its --coverage-plan
 * line "PASS 1"): a pass the budget has cut short, fewer units than a full pass (kmax) and no
 * more than the largest pass so far (k[0..n-1]), is the budget's end. The caustic gather
 * measures its kernel on each pass's own caustic photons, so the driver cannot foresee its next
 * level as it does the global gather's (pm_progressive_cover_size); a new level's sampling in
 * such a pass would run the render past its budget. Exposed for the unit tests. */
int pm_progressive_hold_caustic(const int *k, int n, int kmax, int units);

#endif
