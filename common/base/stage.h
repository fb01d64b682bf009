/* stage.h: the shape every pmtk program's main shares.
 *
 *   int main(int argc, char **argv) {
 *       my_options_t o = {defaults};
 *       pm_stage_t st;
 *       const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(st), {my options...}, {0}};
 *       int rc = pm_stage_begin(&st, &cli, argc, argv);   // parse, --help, --version
 *       if (rc >= 0) return rc;
 *       ... validate, read, process, write ...
 *       return pm_stage_end(&st, result);                  // stats, message, exit code
 *   }
 *
 * Common options: -o/--output, --threads, --seed, --stats, --quiet, --help, --version,
 * --print-settings. Exit status by the failure's class (pm_result_exit_code): 0 ok, 1 bad
 * input, 2 bad usage, 3 io or nomem, 4 internal; the class (usage, input, io, nomem,
 * internal) ends its one-line message and is in --stats (docs/cli.md). */
#ifndef PM_STAGE_H
#define PM_STAGE_H

#include <stddef.h>
#include <stdint.h>

#include "base/args.h"
#include "base/atomic.h"
#include "base/error.h"
#include "base/progress.h"
#include "base/timer.h"

typedef struct pm_stats pm_stats_t;

typedef struct {
    const char *name; /* program name for messages */
    const pm_cli_t *cli;
    pm_args_t args; /* positional arguments after parsing */
    int argc;
    char **argv; /* as given but for --threads, --quiet, --stats (pm_args_record), for the COMMAND line */
    /* common option values */
    const char *output; /* -o; "-" means stdout */
    int64_t threads;    /* 0 = all cores, resolved into threads_used */
    int64_t seed;
    const char *stats_path; /* --stats FILE, NULL when not asked */
    int quiet, help, version, print_settings;
    int threads_used;
    pm_timer_t timer;
    pm_stats_t *stats;       /* the stage's counters, written by pm_stage_end */
    uint64_t items;          /* what items_per_s counts (photons, queries, ...) */
    pm_atomic_t out;         /* the -o output of a text-writing program, once opened */
    pm_atomic_set_t outputs; /* with pm_stage_output_set: every output, renamed at pm_stage_end */
} pm_stage_t;

/* A table, one option a line, as in the stages' own tables; clang-format would set each field on a line of its own. */
/* clang-format off */
#define PM_STAGE_COMMON_OPTIONS(st)                                                                                    \
    {"output", 'o', PM_OPT_OUTPUT, &(st).output, "FILE", "write the output here; - is stdout", 1, 0, NULL},            \
        {"threads", 0, PM_OPT_INT, &(st).threads, "N", "worker threads; 0 uses every core", 0, 4096, NULL},            \
        {"seed", 0, PM_OPT_INT, &(st).seed, "N", "seed of the counter-based random numbers", 0, 9.2e18, NULL},         \
        {"stats", 0, PM_OPT_OUTPUT, &(st).stats_path, "FILE", "write counters and timings as JSON; - is stderr",       \
         1, 0, NULL},                                                                                                  \
        {"quiet", 'q', PM_OPT_FLAG, &(st).quiet, NULL, "no progress bar and no notes on stderr", 1, 0, NULL},          \
        {"print-settings", 0, PM_OPT_FLAG, &(st).print_settings, NULL,                                                 \
         "print the effective settings (readable back as @FILE) and exit", 1, 0, NULL},                                \
        {"help", 'h', PM_OPT_FLAG, &(st).help, NULL, "print this help and exit", 1, 0, NULL},                          \
        {"version", 0, PM_OPT_FLAG, &(st).version, NULL, "print the version and exit", 1, 0, NULL}
/* clang-format on */

/* Call before the option table is built: sets common defaults (output "-", seed 1). */
void pm_stage_defaults(pm_stage_t *st);

/* Parses options and handles --help, --version, --print-settings, positional counts, and
 * refuses (usage error, before any work) two PM_OPT_OUTPUT options given one file
 * (pm_atomic_same_file; "-" twice is stdout twice, except --stats -, which is stderr).
 * Returns -1 to go on, or the exit status to return now. */
int pm_stage_begin(pm_stage_t *st, const pm_cli_t *cli, int argc, char **argv);

/* Opens -o (stdout for "-") for a program whose output is text; pm_stage_end commits it
 * on success and removes it on failure. Stages writing pmtk files use pm_writer instead. */
pm_result_t pm_stage_open_output(pm_stage_t *st, FILE **f_out);

/* Makes every output this program commits from now on part of one set (base/atomic.h),
 * renamed into place by pm_stage_end when the run succeeds and removed when it fails, so that
 * a program of several outputs leaves all of them or none. --stats is not in the set: it is
 * written on failure too. */
void pm_stage_output_set(pm_stage_t *st);

/* Progress bar wish: not quiet. */
static inline int pm_stage_progress(const pm_stage_t *st) { return !st->quiet; }

/* Stage counters for --stats (no-ops when --stats was not given). */
void pm_stage_stat_int(pm_stage_t *st, const char *key, int64_t v);
/* A stage given several inputs as a stream (one document each): r with the current error's
 * message prefixed by which frame ('name') failed; r itself when it is PM_OK. */
pm_result_t pm_stage_frame_error(pm_result_t r, int frame, const char *name);
void pm_stage_stat_double(pm_stage_t *st, const char *key, double v);
void pm_stage_stat_string(pm_stage_t *st, const char *key, const char *v);

/* The command line one document of a --passes or --plan stream records (base/passplan.h):
 * the recorded words (st->argv; argv is main's) without those of the options whose
 * destinations are in drop, and the nadd words of add where the first of them stood, so
 * that each document is the file a run with --pass P alone would write. *argv_out is
 * malloc'd (free it); its words point into argv and add. */
pm_result_t pm_stage_pass_command(const pm_stage_t *st, char **argv, const void *const *drop, size_t ndrop,
                                  char *const *add, int nadd, int *argc_out, char ***argv_out);

/* The command line as given, words joined by spaces and cut to fit cap bytes (an EXR
 * COMMAND attribute; pmtk files keep it with pm_header_add_command). */
void pm_stage_command_line(const pm_stage_t *st, char *out, size_t cap);
/* A note on stderr ("name: ..."), unless --quiet. */
void pm_stage_note(const pm_stage_t *st, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Finishes: writes --stats (stage, version, threads, wall_s, cpu_s, items, items_per_s, on
 * failure "error": {"class", "message"}, then the counters); on failure prints
 * "name: message (CLASS error)" with CLASS from pm_result_string, and returns the exit
 * status of the class (pm_result_exit_code: 0, 1 input, 2 usage, 3 io or nomem, 4 internal). */
int pm_stage_end(pm_stage_t *st, pm_result_t result);

#endif
