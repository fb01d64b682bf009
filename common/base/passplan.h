/* passplan.h: which progressive passes a resident tracer runs, one document per pass
 * (docs/formats.md, "Streams"; docs/pipelines.md, "Progressive passes").
 *
 *   --passes A:B   passes A to B, each of the size the options give
 *   --plan FILE    one line "PASS [SIZE]" per pass, read when the stage is ready for it: a
 *                  driver (common/engine/progressive.c) writes the next line when it has
 *                  sized the next pass, and closes the pipe to end the stream
 *
 * SIZE is the stage's own measure of a pass (trace-photons: photon paths; trace-gather-points:
 * primary rays per pixel); a line without it takes the options' size. Blank lines and lines
 * starting with '#' are skipped. Passes need not follow one another (a rerun adds passes
 * 5 to 8), but each is at least 1. */
#ifndef PM_BASE_PASSPLAN_H
#define PM_BASE_PASSPLAN_H

#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "base/stage.h"

typedef struct {
    int64_t first, last; /* --passes A:B; with a plan 0 and -1 */
    int64_t next;        /* the next pass of the range */
    FILE *plan;          /* --plan's file (stdin for "-"), NULL for a range */
    const char *path;    /* --plan's path, for messages */
    int64_t line;        /* lines of the plan read */
    const char *ready;   /* --ready FILE, NULL for none: told once the stage is ready for its first pass */
} pm_passplan_t;

/* Sets up from --passes (range, "A:B" with 1 <= A <= B, or NULL) or --plan (plan, a path or
 * "-", or NULL); exactly one of them must be given (a usage error otherwise). A plan that
 * cannot be opened is an input error naming it. */
pm_result_t pm_passplan_open(pm_passplan_t *pp, const char *range, const char *plan);

/* The next pass: *pass_out, *size_out (0 when the line gives none, and always for a range),
 * and *end_out 1 when there is none (the range done, or the plan at its end). A malformed
 * line is an input error naming the plan and the line. */
pm_result_t pm_passplan_next(pm_passplan_t *pp, int64_t *pass_out, int64_t *size_out, int *end_out);

/* 1 when the plan is one pass (--passes A:A): its one document may go to a regular file. */
int pm_passplan_single(const pm_passplan_t *pp);

void pm_passplan_close(pm_passplan_t *pp);

/* --ready FILE (a driver's pipe as /dev/fd/N): once the stage has loaded what every pass shares
 * (the scene, the ray tracer) and before it reads the plan's first line, pm_passplan_run writes
 * the line "PROGRAM ready WALL_S CPU_S" (s since the stage began, s of CPU since it started) to
 * pp->ready and closes it, so that the driver times the passes apart from the stages' start
 * (common/engine/progressive.c). A file that cannot be opened or written is an error of its
 * errno's class naming it. */
pm_result_t pm_passplan_tell_ready(const pm_passplan_t *pp, pm_stage_t *st);

/* One pass of a resident tracer: pass, and size from the plan (0: the options' size). When it
 * is called, the stage's recorded command (st->argc, st->argv) is that pass's alone. */
typedef pm_result_t (*pm_passplan_fn)(void *user, int64_t pass, int64_t size);

/* The one pass loop of the resident tracers (trace-photons, trace-gather-points): fn for each
 * pass of pp in turn, with the stage's recorded command set to what the pass alone would record
 * (pm_stage_pass_command: the options whose destinations are drop[0..ndrop) left out, "--pass
 * P" and, when the plan sizes the pass, "size_opt SIZE" put in; drop's last entry is size_opt's
 * destination, left out only then) and restored after. A size above max_size is an input error
 * naming the plan's line; a pass that fails is named (pm_stage_frame_error); a plan of no pass
 * is an input error. Tells pp->ready first (pm_passplan_tell_ready). Adds the stats "passes"
 * (the passes done), "pass_cpu_s" (the CPU s the stage used in its passes, not in loading),
 * "ready_s" and "ready_cpu_s" (the wall s from the stage's start and the CPU s from its exec
 * to the first pass: its start-up). */
pm_result_t pm_passplan_run(pm_passplan_t *pp, pm_stage_t *st, char **argv, const void *const *drop, size_t ndrop,
                            const char *size_opt, int64_t max_size, pm_passplan_fn fn, void *user);

#endif
