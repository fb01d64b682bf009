/* args.h: table-driven command-line options shared by every pmtk program.
 *
 * Each program declares its options as a table of pm_option_t, with the help text
 * beside each; defaults are whatever the destinations hold before parsing, so the
 * help shows them as they are. Numbers are parsed with strtoll/strtod, the whole
 * word consumed and the range checked. "@FILE" expands to the words of FILE, so
 * that the output of --print-settings reads back as options. */
#ifndef PM_ARGS_H
#define PM_ARGS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"

typedef enum {
    PM_OPT_FLAG,   /* no value; dest is int*, set to 1 */
    PM_OPT_INT,    /* dest is int64_t*; accepts 500000, 5e5 (an exact integer) */
    PM_OPT_DOUBLE, /* dest is double*; finite values only */
    PM_OPT_STRING, /* dest is const char** (points into argv or the @file words) */
    PM_OPT_CHOICE, /* dest is int*, the index of the word in choices */
    PM_OPT_OUTPUT  /* as STRING, a path the program writes: pm_stage_begin refuses two that name one file */
} pm_opt_kind_t;

typedef struct {
    const char *name; /* long name without "--" */
    char short_name;  /* 0 when none */
    pm_opt_kind_t kind;
    void *dest;
    const char *metavar;        /* shown in help: "N", "FILE" */
    const char *help;           /* one line; the default is appended by the usage printer */
    double min, max;            /* inclusive range for INT and DOUBLE; ignored when min > max */
    const char *const *choices; /* NULL-terminated words, for CHOICE */
} pm_option_t;

typedef struct {
    const char *program;        /* "trace-photons" */
    const char *synopsis;       /* "[options] SCENE" */
    const char *summary;        /* what the program does, one line */
    const pm_option_t *options; /* the table, terminated by an entry whose name is NULL */
    int min_args, max_args;     /* how many positional arguments; max_args < 0 means any */
    const char *binary_output;  /* the pmtk format -o writes ("photons"), or NULL for text or no -o */
} pm_cli_t;

/* Parsed positional arguments, and the storage behind @file words. */
typedef struct {
    char **args;
    int nargs;
    char **owned; /* words read from @files, freed by pm_args_free */
    size_t nowned;
    char **argv;                /* the expanded argument vector */
    const pm_option_t *options; /* the table parsed */
    unsigned char *given;       /* per option of the table: 1 when the words (argv or an @file) set it */
    int argc;                   /* the words of the argv parsed */
    int *argv_option;           /* per word of that argv: the option it names or gives the value of, -1 none */
    char **recorded;            /* pm_args_record's words */
} pm_args_t;

/* Parses argv[1..] into the table's destinations and the positional arguments.
 * A lone "-" is positional (stdin or stdout); "--" ends the options.
 * On failure returns PM_ERR_USAGE (or PM_ERR_IO for an unreadable @file) with
 * a message naming the option and the offending word. */
pm_result_t pm_args_parse(const pm_cli_t *cli, int argc, char **argv, pm_args_t *out);
void pm_args_free(pm_args_t *a);

/* Whether option `name` (long name, no "--") was given, so that a default from elsewhere (a
 * scene's render block, an input's header) applies only when it was not: the command line
 * wins. 0 for a name the table does not have. */
int pm_args_given(const pm_args_t *a, const char *name);

/* The words of argv (the vector a parsed) without those of the options whose destination is
 * one of dests: the command line an output records, left without options that change no
 * output (--threads), so that a file does not depend on the machine that made it. An option
 * given inside an @FILE is not in argv and stays as the @FILE word. The array points into
 * argv and lives until pm_args_free. */
pm_result_t pm_args_record(pm_args_t *a, char **argv, const void *const *dests, size_t ndests, int *argc_out,
                           char ***argv_out);

/* Usage: synopsis, summary and every option with its help and current (default) value. */
void pm_args_usage(const pm_cli_t *cli, FILE *f);

/* The effective settings, one "--name value" per line, readable back through @FILE. */
void pm_args_print_settings(const pm_cli_t *cli, FILE *f);

/* Parses "BEGIN:END" (either side may be empty: ":100", "5:") into a half-open range. */
pm_result_t pm_args_parse_range(const char *s, uint64_t *begin_out, uint64_t *end_out);

/* Strict number parsers used by the table and by format readers. */
pm_result_t pm_parse_i64(const char *s, int64_t *out);
pm_result_t pm_parse_double(const char *s, double *out);

#endif
