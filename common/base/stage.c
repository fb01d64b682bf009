/* stage.c: the common main skeleton of pmtk programs (see stage.h). */
#include "base/stage.h"

#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/atomic.h"
#include "base/cpu.h"
#include "base/threads.h"
#include "base/version.h"

struct pm_stats {
    json_t *obj;
};

void pm_stage_defaults(pm_stage_t *st)
{
    memset(st, 0, sizeof *st);
    st->out.slot = -1;
    st->output = "-";
    st->seed = 1;
}

/* The one line a failure prints: "PROGRAM: message (CLASS error)". The class word goes last
 * so that the line still reads "program: what 'subject': values" from its start, and a script
 * can take the class from the end without parsing the message. */
static void print_failure(const pm_stage_t *st, pm_result_t code, const char *message)
{
    if (message[0])
        fprintf(stderr, "%s: %s (%s error)\n", st->name, message, pm_result_string(code));
    else
        fprintf(stderr, "%s: %s error\n", st->name, pm_result_string(code));
}

static pm_result_t write_stats(pm_stage_t *st, pm_result_t code, const char *message);

/* A failure before the work starts: message, --stats when the command line named it, and
 * the usage hint for a usage error. Returns the exit status. */
static int begin_fail(pm_stage_t *st, pm_result_t code, int stats_known)
{
    char msg[PM_ERROR_MAX];
    snprintf(msg, sizeof msg, "%s", pm_error_message());
    if (stats_known && st->stats_path)
        write_stats(st, code, msg); /* best effort: the failure being reported is this one */
    print_failure(st, code, msg);
    if (code == PM_ERR_USAGE)
        fprintf(stderr, "usage: %s %s (try --help)\n", st->cli->program, st->cli->synopsis);
    pm_args_free(&st->args);
    return pm_result_exit_code(code);
}

/* Refuses two outputs of this command that name one file (pm_atomic_same_file): the second
 * would replace the first, or both would interleave in one stream. Only options the command
 * line gave count: a default "-" means different things to different programs. */
static pm_result_t check_outputs(const pm_stage_t *st)
{
    const pm_option_t *o = st->cli->options;
    for (size_t i = 0; o[i].name; i++) {
        const char *a = o[i].kind == PM_OPT_OUTPUT && st->args.given[i] ? *(const char **)o[i].dest : NULL;
        /* --stats - is stderr, which no other output names. */
        if (!a || (o[i].dest == &st->stats_path && !strcmp(a, "-")))
            continue;
        for (size_t j = 0; j < i; j++) {
            const char *b = o[j].kind == PM_OPT_OUTPUT && st->args.given[j] ? *(const char **)o[j].dest : NULL;
            if (!b || (o[j].dest == &st->stats_path && !strcmp(b, "-")))
                continue;
            if (pm_atomic_same_file(a, b) && (strcmp(a, "-") == 0) != (strcmp(b, "-") == 0))
                return pm_error_set(PM_ERR_USAGE, "two outputs to one file: stdout and '%s' (--%s and --%s)",
                                    strcmp(b, "-") ? b : a, o[j].name, o[i].name);
            if (pm_atomic_same_file(a, b))
                return pm_error_set(PM_ERR_USAGE, "two outputs to one file '%s': --%s and --%s",
                                    strcmp(b, "-") ? b : "stdout", o[j].name, o[i].name);
        }
    }
    return PM_OK;
}

int pm_stage_begin(pm_stage_t *st, const pm_cli_t *cli, int argc, char **argv)
{
    st->name = cli->program;
    st->cli = cli;
    st->argc = argc;
    st->argv = argv;
    pm_timer_start(&st->timer);
    pm_cpu_set_ftz_daz();
    pm_atomic_install_cleanup();
    pm_result_t r = pm_args_parse(cli, argc, argv, &st->args);
    /* No stats for a command line that does not parse: the --stats it names is in doubt. */
    if (r != PM_OK)
        return begin_fail(st, r, 0);
    if (st->help) {
        pm_args_usage(cli, stdout);
        pm_args_free(&st->args);
        return 0;
    }
    if (st->version) {
        printf("%s (pmtk) %s\n", cli->program, PM_VERSION_STRING);
        pm_args_free(&st->args);
        return 0;
    }
    if (st->print_settings) {
        st->print_settings = 0;
        pm_args_print_settings(cli, stdout);
        pm_args_free(&st->args);
        return 0;
    }
    st->threads_used = pm_threads_use(st->threads);
    /* What the outputs record as their command line: without the options that change no
     * output, so that a file is the same bytes however it was run: --threads (threads.h:
     * whatever the machine's cores or a cluster's CPUs per task), --quiet (what stderr shows)
     * and --stats (a report beside the outputs). docs/cli.md, "Determinism". */
    const void *unrecorded[] = {&st->threads, &st->quiet, &st->stats_path};
    if (pm_args_record(&st->args, argv, unrecorded, sizeof unrecorded / sizeof *unrecorded, &st->argc, &st->argv) !=
        PM_OK)
        return begin_fail(st, PM_ERR_NOMEM, 0);
    int n = st->args.nargs;
    if (n < cli->min_args || (cli->max_args >= 0 && n > cli->max_args)) {
        if (cli->min_args == cli->max_args)
            pm_error_set(PM_ERR_USAGE, "expected %d argument%s, got %d", cli->min_args, cli->min_args == 1 ? "" : "s",
                         n);
        else if (cli->max_args < 0)
            pm_error_set(PM_ERR_USAGE, "expected at least %d argument%s, got %d", cli->min_args,
                         cli->min_args == 1 ? "" : "s", n);
        else
            pm_error_set(PM_ERR_USAGE, "expected %d to %d arguments, got %d", cli->min_args, cli->max_args, n);
        return begin_fail(st, PM_ERR_USAGE, 1);
    }
    /* No stats for a clash: the --stats file may be one of the two. */
    if (check_outputs(st) != PM_OK)
        return begin_fail(st, PM_ERR_USAGE, 0);
    /* Binary records on a terminal: refused here, before any work, as gzip does (the writer
     * refuses again, for library callers). */
    if (cli->binary_output && strcmp(st->output, "-") == 0 && isatty(STDOUT_FILENO)) {
        pm_error_set(PM_ERR_USAGE, "refusing to write a binary %s file to a terminal (stdout): give -o FILE or pipe it",
                     cli->binary_output);
        return begin_fail(st, PM_ERR_USAGE, 0);
    }
    if (st->stats_path) {
        st->stats = calloc(1, sizeof *st->stats);
        if (st->stats)
            st->stats->obj = json_object();
        if (!st->stats || !st->stats->obj) {
            free(st->stats);
            st->stats = NULL;
            return begin_fail(st, pm_error_set(PM_ERR_NOMEM, "out of memory for stats"), 0);
        }
    }
    return -1;
}

void pm_stage_stat_int(pm_stage_t *st, const char *key, int64_t v)
{
    if (st->stats)
        json_object_set_new(st->stats->obj, key, json_integer(v));
}

pm_result_t pm_stage_frame_error(pm_result_t r, int frame, const char *name)
{
    if (r == PM_OK)
        return r;
    char why[PM_ERROR_MAX]; /* the message is rewritten from a copy of itself */
    snprintf(why, sizeof why, "%s", pm_error_message());
    return pm_error_set(r, "frame %d ('%s'): %s", frame, name, why);
}

void pm_stage_stat_double(pm_stage_t *st, const char *key, double v)
{
    /* JSON has no NaN or Inf: a counter that is not finite is written as null. */
    if (st->stats)
        json_object_set_new(st->stats->obj, key, isfinite(v) ? json_real(v) : json_null());
}

void pm_stage_stat_string(pm_stage_t *st, const char *key, const char *v)
{
    if (st->stats)
        json_object_set_new(st->stats->obj, key, json_string(v));
}

void pm_stage_note(const pm_stage_t *st, const char *fmt, ...)
{
    if (st->quiet)
        return;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", st->name);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* Writes --stats: the fixed keys, on failure the error (class and message), then the stage's
 * counters. code is the run's result and message its text (NULL on success). */
static pm_result_t write_stats(pm_stage_t *st, pm_result_t code, const char *message)
{
    double wall = pm_timer_wall(&st->timer), cpu = pm_timer_cpu(&st->timer);
    /* The fixed keys go first so every stats file reads alike. */
    json_t *o = json_object();
    if (!o)
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing stats");
    json_object_set_new(o, "stage", json_string(st->name));
    json_object_set_new(o, "version", json_string(PM_VERSION_STRING));
    json_object_set_new(o, "threads", json_integer(st->threads_used));
    json_object_set_new(o, "wall_s", json_real(wall));
    json_object_set_new(o, "cpu_s", json_real(cpu));
    json_object_set_new(o, "items", json_integer((json_int_t)st->items));
    json_object_set_new(o, "items_per_s", json_real(wall > 0.0 ? (double)st->items / wall : 0.0));
    if (code != PM_OK) {
        /* A message that is not valid UTF-8 (a path's bytes) is kept as far as it is. */
        json_t *err = json_object(), *m = json_string(message);
        if (!m) {
            char clean[PM_ERROR_MAX];
            size_t k = 0;
            for (const unsigned char *c = (const unsigned char *)message; *c && k + 1 < sizeof clean; c++)
                clean[k++] = *c < 0x80 ? (char)*c : '?';
            clean[k] = '\0';
            m = json_string(clean);
        }
        json_object_set_new(err, "class", json_string(pm_result_string(code)));
        json_object_set_new(err, "message", m);
        json_object_set_new(o, "error", err);
    }
    if (st->stats)
        json_object_update(o, st->stats->obj);
    pm_result_t r = PM_OK;
    if (strcmp(st->stats_path, "-") == 0) {
        if (json_dumpf(o, stderr, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0)
            r = pm_error_set(PM_ERR_IO, "cannot write stats to stderr");
        fputc('\n', stderr);
    } else {
        pm_atomic_t a;
        r = pm_atomic_open(st->stats_path, &a);
        if (r == PM_OK) {
            if (json_dumpf(o, a.f, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
                fputc('\n', a.f) == EOF) {
                pm_atomic_abort(&a);
                r = pm_error_set(PM_ERR_IO, "cannot write stats '%s'", st->stats_path);
            } else {
                r = pm_atomic_commit(&a);
            }
        }
    }
    json_decref(o);
    return r;
}

pm_result_t pm_stage_open_output(pm_stage_t *st, FILE **f_out)
{
    pm_result_t r = pm_atomic_open(st->output, &st->out);
    *f_out = r == PM_OK ? st->out.f : NULL;
    return r;
}

void pm_stage_output_set(pm_stage_t *st)
{
    if (!st->outputs.open)
        pm_atomic_set_begin(&st->outputs);
}

int pm_stage_end(pm_stage_t *st, pm_result_t result)
{
    if (st->out.f)
        result = result == PM_OK ? pm_atomic_commit(&st->out) : (pm_atomic_abort(&st->out), result);
    /* The set before the stats: the stats say whether its renames succeeded. */
    if (st->outputs.open)
        result = pm_atomic_set_end(&st->outputs, result);
    int stats_failed = 0;
    if (result == PM_OK && st->stats_path) {
        result = write_stats(st, PM_OK, NULL);
        stats_failed = result != PM_OK;
    }
    if (result != PM_OK) {
        /* Kept before the stats are written: writing them may set a message of its own. */
        char msg[PM_ERROR_MAX];
        snprintf(msg, sizeof msg, "%s", pm_error_message());
        /* Best effort: when the stats cannot be written either, the run's own failure is the
         * one line reported. */
        if (st->stats_path && !stats_failed)
            write_stats(st, result, msg);
        print_failure(st, result, msg);
    }
    if (st->stats) {
        json_decref(st->stats->obj);
        free(st->stats);
        st->stats = NULL;
    }
    pm_args_free(&st->args);
    return pm_result_exit_code(result);
}

pm_result_t pm_stage_pass_command(const pm_stage_t *st, char **argv, const void *const *drop, size_t ndrop,
                                  char *const *add, int nadd, int *argc_out, char ***argv_out)
{
    const pm_args_t *a = &st->args;
    /* the options pm_stage_begin leaves out of every COMMAND line, then the caller's */
    const void *unrecorded[] = {&st->threads, &st->quiet, &st->stats_path};
    char **v = malloc(((size_t)(a->argc > 0 ? a->argc : 1) + (size_t)nadd) * sizeof *v);
    if (!v)
        return pm_error_set(PM_ERR_NOMEM, "out of memory recording %d arguments", a->argc);
    int n = 0, added = 0;
    for (int i = 0; i < a->argc; i++) {
        int oi = a->argv_option ? a->argv_option[i] : -1, skip = 0, dropped = 0;
        for (size_t k = 0; oi >= 0 && k < sizeof unrecorded / sizeof *unrecorded && !skip; k++)
            skip = a->options[oi].dest == unrecorded[k];
        for (size_t k = 0; oi >= 0 && k < ndrop && !skip; k++)
            skip = dropped = a->options[oi].dest == drop[k];
        if (dropped && !added) {
            for (int j = 0; j < nadd; j++)
                v[n++] = add[j];
            added = 1;
        }
        if (!skip)
            v[n++] = argv[i];
    }
    for (int j = 0; !added && j < nadd; j++) /* none of drop given (an @FILE held it): at the end */
        v[n++] = add[j];
    *argc_out = n;
    *argv_out = v;
    return PM_OK;
}

void pm_stage_command_line(const pm_stage_t *st, char *out, size_t cap)
{
    size_t at = 0;
    if (cap)
        out[0] = '\0';
    for (int i = 0; i < st->argc && at + 1 < cap; i++) {
        int n = snprintf(out + at, cap - at, "%s%s", i ? " " : "", st->argv[i]);
        if (n < 0)
            break;
        at += (size_t)n;
    }
}
