/* args.c: the option parser behind every pmtk program (see args.h). */
#include "base/args.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PM_ARGS_FILE_MAX (1u << 20) /* bytes: an @file is a settings list, not data */
#define PM_ARGS_EXPANSIONS_MAX 64   /* @files expanded in one command line */

/* Numbers are written in decimal: no leading space, no hex (strtod would take both). */
static int plain_number(const char *s)
{
    if (!((*s >= '0' && *s <= '9') || *s == '-' || *s == '+' || *s == '.'))
        return 0;
    for (; *s; s++)
        if (!strchr("0123456789+-.eE", *s))
            return 0;
    return 1;
}

pm_result_t pm_parse_i64(const char *s, int64_t *out)
{
    char *end;
    if (!s || !*s)
        return pm_error_set(PM_ERR_USAGE, "empty number");
    if (!plain_number(s))
        return pm_error_set(PM_ERR_USAGE, "'%s' is not an integer", s);
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (*end == '\0' && errno == 0) {
        *out = v;
        return PM_OK;
    }
    /* Accept an exact integer written as a float ("5e5"): counts read better so. */
    double d;
    if (pm_parse_double(s, &d) == PM_OK && d == floor(d) && fabs(d) < 9.2e18) {
        *out = (int64_t)d;
        return PM_OK;
    }
    return pm_error_set(PM_ERR_USAGE, "'%s' is not an integer", s);
}

pm_result_t pm_parse_double(const char *s, double *out)
{
    char *end;
    if (!s || !*s)
        return pm_error_set(PM_ERR_USAGE, "empty number");
    if (!plain_number(s))
        return pm_error_set(PM_ERR_USAGE, "'%s' is not a number", s);
    errno = 0;
    double v = strtod(s, &end);
    if (*end != '\0' || end == s)
        return pm_error_set(PM_ERR_USAGE, "'%s' is not a number", s);
    if (errno == ERANGE && fabs(v) > 1.0)
        return pm_error_set(PM_ERR_USAGE, "'%s' is out of range", s);
    if (!isfinite(v))
        return pm_error_set(PM_ERR_USAGE, "'%s' is not finite", s);
    *out = v;
    return PM_OK;
}

pm_result_t pm_args_parse_range(const char *s, uint64_t *begin_out, uint64_t *end_out)
{
    const char *colon = strchr(s, ':');
    if (!colon)
        return pm_error_set(PM_ERR_USAGE, "range '%s' is not BEGIN:END", s);
    char buf[64];
    size_t n = (size_t)(colon - s);
    int64_t b = 0, e = INT64_MAX;
    if (n >= sizeof buf)
        return pm_error_set(PM_ERR_USAGE, "range '%s' is too long", s);
    memcpy(buf, s, n);
    buf[n] = '\0';
    if (n && (pm_parse_i64(buf, &b) != PM_OK || b < 0))
        return pm_error_set(PM_ERR_USAGE, "range '%s': bad begin '%s'", s, buf);
    if (colon[1] && (pm_parse_i64(colon + 1, &e) != PM_OK || e < 0))
        return pm_error_set(PM_ERR_USAGE, "range '%s': bad end '%s'", s, colon + 1);
    if (e < b)
        return pm_error_set(PM_ERR_USAGE, "range '%s': end %" PRId64 " before begin %" PRId64, s, e, b);
    *begin_out = (uint64_t)b;
    *end_out = (uint64_t)e;
    return PM_OK;
}

static const pm_option_t *find_long(const pm_cli_t *cli, const char *name, size_t len)
{
    for (const pm_option_t *o = cli->options; o->name; o++)
        if (strlen(o->name) == len && strncmp(o->name, name, len) == 0)
            return o;
    return NULL;
}

static const pm_option_t *find_short(const pm_cli_t *cli, char c)
{
    for (const pm_option_t *o = cli->options; o->name; o++)
        if (o->short_name && o->short_name == c)
            return o;
    return NULL;
}

static pm_result_t set_value(const pm_option_t *o, const char *v)
{
    switch (o->kind) {
    case PM_OPT_FLAG: *(int *)o->dest = 1; return PM_OK;
    case PM_OPT_INT: {
        int64_t x;
        if (pm_parse_i64(v, &x) != PM_OK)
            return pm_error_set(PM_ERR_USAGE, "option --%s: '%s' is not an integer", o->name, v);
        if (o->min <= o->max && ((double)x < o->min || (double)x > o->max))
            return pm_error_set(PM_ERR_USAGE, "option --%s: %" PRId64 " is outside [%.17g, %.17g]", o->name, x, o->min,
                                o->max);
        *(int64_t *)o->dest = x;
        return PM_OK;
    }
    case PM_OPT_DOUBLE: {
        double x;
        if (pm_parse_double(v, &x) != PM_OK)
            return pm_error_set(PM_ERR_USAGE, "option --%s: '%s' is not a finite number", o->name, v);
        if (o->min <= o->max && (x < o->min || x > o->max))
            return pm_error_set(PM_ERR_USAGE, "option --%s: %.17g is outside [%.17g, %.17g]", o->name, x, o->min,
                                o->max);
        *(double *)o->dest = x;
        return PM_OK;
    }
    case PM_OPT_STRING:
    case PM_OPT_OUTPUT: *(const char **)o->dest = v; return PM_OK;
    case PM_OPT_CHOICE:
        for (int i = 0; o->choices[i]; i++)
            if (strcmp(o->choices[i], v) == 0) {
                *(int *)o->dest = i;
                return PM_OK;
            }
        {
            char list[256] = "";
            for (int i = 0; o->choices[i]; i++) {
                strncat(list, i ? "|" : "", sizeof list - strlen(list) - 1);
                strncat(list, o->choices[i], sizeof list - strlen(list) - 1);
            }
            return pm_error_set(PM_ERR_USAGE, "option --%s: '%s' is not one of %s", o->name, v, list);
        }
    }
    return pm_error_set(PM_ERR_INTERNAL, "option --%s has an unknown kind", o->name);
}

/* Growable vector of words: the argv after @file expansion. from (the expanded argv alone)
 * says where each word came from: its index in argv, or -1 for a word read from an @file. */
typedef struct {
    char **v;
    int *from;
    size_t n, cap;
} words_t;

static pm_result_t words_push_from(words_t *w, char *s, int from)
{
    if (w->n == w->cap) {
        size_t cap = w->cap ? 2 * w->cap : 16;
        char **v = realloc(w->v, cap * sizeof *v);
        if (!v)
            return pm_error_set(PM_ERR_NOMEM, "out of memory expanding arguments");
        w->v = v;
        int *f = realloc(w->from, cap * sizeof *f);
        if (!f)
            return pm_error_set(PM_ERR_NOMEM, "out of memory expanding arguments");
        w->from = f;
        w->cap = cap;
    }
    w->from[w->n] = from;
    w->v[w->n++] = s;
    return PM_OK;
}

static pm_result_t words_push(words_t *w, char *s) { return words_push_from(w, s, -1); }

/* Splits an options file into words: blanks separate words, # starts a comment, '...'
 * quotes literally, a backslash escapes the next character (so '\'' is a quote). */
static pm_result_t split_words(const char *path, char *text, words_t *out, words_t *owned)
{
    char *p = text;
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')
            p++;
        if (*p == '#') {
            while (*p && *p != '\n')
                p++;
            continue;
        }
        if (!*p)
            return PM_OK;
        char *word = malloc(strlen(p) + 1), *o = word;
        if (!word)
            return pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", path);
        while (*p && *p != ' ' && *p != '\t' && *p != '\n' && *p != '\r') {
            if (*p == '\'') {
                char *close = strchr(p + 1, '\'');
                if (!close) {
                    free(word);
                    return pm_error_set(PM_ERR_USAGE, "options file '%s': unterminated quote", path);
                }
                memcpy(o, p + 1, (size_t)(close - p - 1));
                o += close - p - 1;
                p = close + 1;
            } else if (*p == '\\' && p[1]) {
                *o++ = p[1];
                p += 2;
            } else {
                *o++ = *p++;
            }
        }
        *o = '\0';
        if (words_push(owned, word) != PM_OK) {
            free(word);
            return pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", path);
        }
        if (words_push(out, word) != PM_OK)
            return pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", path);
    }
}

static pm_result_t read_words(const char *path, words_t *out, words_t *owned)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(PM_ERR_USAGE, "cannot open options file '%s': %s", path, strerror(errno));
    char *text = malloc(PM_ARGS_FILE_MAX + 1);
    if (!text) {
        fclose(f);
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", path);
    }
    size_t n = fread(text, 1, PM_ARGS_FILE_MAX + 1, f);
    int err = ferror(f);
    fclose(f);
    if (err || n > PM_ARGS_FILE_MAX) {
        free(text);
        return pm_error_set(PM_ERR_USAGE, "options file '%s' is unreadable or over %u bytes", path, PM_ARGS_FILE_MAX);
    }
    text[n] = '\0';
    pm_result_t r = split_words(path, text, out, owned);
    free(text);
    return r;
}

/* Replaces word i of w by the words of the options file it names. */
static pm_result_t splice_file(words_t *w, size_t i, words_t *owned)
{
    words_t file = {0};
    pm_result_t r = read_words(w->v[i] + 1, &file, owned);
    if (r == PM_OK && file.n != 1) {
        size_t n = w->n - 1 + file.n;
        char **v = malloc((n ? n : 1) * sizeof *v);
        int *from = malloc((n ? n : 1) * sizeof *from);
        if (!v || !from) {
            free(v);
            free(from);
            free(file.v);
            free(file.from);
            return pm_error_set(PM_ERR_NOMEM, "out of memory expanding arguments");
        }
        memcpy(v, w->v, i * sizeof *v);
        memcpy(v + i, file.v, file.n * sizeof *v);
        memcpy(v + i + file.n, w->v + i + 1, (w->n - i - 1) * sizeof *v);
        memcpy(from, w->from, i * sizeof *from);
        for (size_t k = 0; k < file.n; k++)
            from[i + k] = -1;
        memcpy(from + i + file.n, w->from + i + 1, (w->n - i - 1) * sizeof *from);
        free(w->v);
        free(w->from);
        w->v = v;
        w->from = from;
        w->n = w->cap = n;
    } else if (r == PM_OK) {
        w->v[i] = file.v[0];
        w->from[i] = -1;
    }
    free(file.v);
    free(file.from);
    return r;
}

void pm_args_free(pm_args_t *a)
{
    for (size_t i = 0; i < a->nowned; i++)
        free(a->owned[i]);
    free(a->owned);
    free(a->argv);
    free(a->args);
    free(a->given);
    free(a->argv_option);
    free(a->recorded);
    memset(a, 0, sizeof *a);
}

int pm_args_given(const pm_args_t *a, const char *name)
{
    for (size_t i = 0; a->options && a->given && a->options[i].name; i++)
        if (strcmp(a->options[i].name, name) == 0)
            return a->given[i];
    return 0;
}

pm_result_t pm_args_parse(const pm_cli_t *cli, int argc, char **argv, pm_args_t *out)
{
    memset(out, 0, sizeof *out);
    words_t w = {0}, owned = {0}, pos = {0};
    pm_result_t r = PM_OK;
    size_t nopt = 0;
    while (cli->options[nopt].name)
        nopt++;
    out->options = cli->options;
    if (!(out->given = calloc(nopt ? nopt : 1, 1)))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for %zu options", nopt);
    if (r == PM_OK && !(out->argv_option = malloc((argc > 0 ? (size_t)argc : 1) * sizeof *out->argv_option)))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for %d arguments", argc);
    for (int i = 0; i < argc && r == PM_OK; i++)
        out->argv_option[i] = -1;
    out->argc = argc;
    for (int i = 1; i < argc && r == PM_OK; i++)
        r = words_push_from(&w, argv[i], i);
    int only_positional = 0, expansions = 0;
    for (size_t i = 0; r == PM_OK && i < w.n; i++) {
        /* @FILE expands where an option or argument may stand: not after "--", not as an
         * option's value. A bounded number of expansions stops files that name themselves. */
        while (r == PM_OK && !only_positional && i < w.n && w.v[i][0] == '@' && w.v[i][1]) {
            if (++expansions > PM_ARGS_EXPANSIONS_MAX)
                r = pm_error_set(PM_ERR_USAGE, "more than %d @files expanded: does one name itself?",
                                 PM_ARGS_EXPANSIONS_MAX);
            else
                r = splice_file(&w, i, &owned);
        }
        if (r != PM_OK || i >= w.n)
            break;
        char *a = w.v[i];
        if (only_positional || a[0] != '-' || a[1] == '\0') {
            r = words_push(&pos, a);
            continue;
        }
        if (strcmp(a, "--") == 0) {
            only_positional = 1;
            continue;
        }
        const pm_option_t *o;
        const char *value = NULL;
        if (a[1] == '-') {
            const char *name = a + 2, *eq = strchr(name, '=');
            size_t len = eq ? (size_t)(eq - name) : strlen(name);
            o = find_long(cli, name, len);
            if (!o) {
                r = pm_error_set(PM_ERR_USAGE, "unknown option '%s'", a);
                break;
            }
            if (eq && o->kind == PM_OPT_FLAG) {
                r = pm_error_set(PM_ERR_USAGE, "option --%s takes no value", o->name);
                break;
            }
            if (eq)
                value = eq + 1;
        } else {
            o = find_short(cli, a[1]);
            if (!o) {
                r = pm_error_set(PM_ERR_USAGE, "unknown option '%s'", a);
                break;
            }
            if (a[2] && o->kind == PM_OPT_FLAG) {
                r = pm_error_set(PM_ERR_USAGE, "option -%c takes no value", a[1]);
                break;
            }
            if (a[2])
                value = a + 2;
        }
        int oi = (int)(o - cli->options);
        if (w.from[i] >= 0)
            out->argv_option[w.from[i]] = oi;
        if (o->kind != PM_OPT_FLAG && !value) {
            if (i + 1 >= w.n) {
                r = pm_error_set(PM_ERR_USAGE, "option --%s needs a value (%s)", o->name,
                                 o->metavar ? o->metavar : "VALUE");
                break;
            }
            value = w.v[++i];
            if (w.from[i] >= 0)
                out->argv_option[w.from[i]] = oi;
        }
        if ((r = set_value(o, value)) == PM_OK)
            out->given[o - cli->options] = 1;
    }
    out->argv = w.v;
    free(w.from);
    free(owned.from);
    free(pos.from);
    out->owned = owned.v;
    out->nowned = owned.n;
    out->args = pos.v;
    out->nargs = (int)pos.n;
    return r;
}

pm_result_t pm_args_record(pm_args_t *a, char **argv, const void *const *dests, size_t ndests, int *argc_out,
                           char ***argv_out)
{
    free(a->recorded);
    a->recorded = malloc((a->argc > 0 ? (size_t)a->argc : 1) * sizeof *a->recorded);
    if (!a->recorded)
        return pm_error_set(PM_ERR_NOMEM, "out of memory recording %d arguments", a->argc);
    int n = 0;
    for (int i = 0; i < a->argc; i++) {
        int skip = 0;
        int oi = a->argv_option ? a->argv_option[i] : -1;
        for (size_t k = 0; oi >= 0 && k < ndests && !skip; k++)
            skip = a->options[oi].dest == dests[k];
        if (!skip)
            a->recorded[n++] = argv[i];
    }
    *argc_out = n;
    *argv_out = a->recorded;
    return PM_OK;
}

/* A word as an options file reads it back: quoted when it holds a blank, a quote, a
 * backslash, or starts a comment or an @file. */
static void print_word(const char *s, FILE *f)
{
    if (*s && !strpbrk(s, " \t\n\r'\\") && *s != '#' && *s != '@') {
        fputs(s, f);
        return;
    }
    fputc('\'', f);
    for (; *s; s++) {
        if (*s == '\'')
            fputs("'\\''", f);
        else
            fputc(*s, f);
    }
    fputc('\'', f);
}

static void print_value(const pm_option_t *o, FILE *f)
{
    switch (o->kind) {
    case PM_OPT_FLAG: fputs(*(int *)o->dest ? "on" : "off", f); break;
    case PM_OPT_INT: fprintf(f, "%" PRId64, *(int64_t *)o->dest); break;
    case PM_OPT_DOUBLE: fprintf(f, "%.9g", *(double *)o->dest); break;
    case PM_OPT_STRING:
    case PM_OPT_OUTPUT: {
        const char *s = *(const char **)o->dest;
        fputs(s ? s : "none", f);
        break;
    }
    case PM_OPT_CHOICE: fputs(o->choices[*(int *)o->dest], f); break;
    }
}

void pm_args_usage(const pm_cli_t *cli, FILE *f)
{
    fprintf(f, "usage: %s %s\n%s\n\noptions:\n", cli->program, cli->synopsis, cli->summary);
    for (const pm_option_t *o = cli->options; o->name; o++) {
        char left[64];
        if (o->short_name)
            snprintf(left, sizeof left, "-%c, --%s%s%s", o->short_name, o->name, o->metavar ? " " : "",
                     o->metavar ? o->metavar : "");
        else
            snprintf(left, sizeof left, "    --%s%s%s", o->name, o->metavar ? " " : "", o->metavar ? o->metavar : "");
        fprintf(f, "  %-26s %s", left, o->help);
        if (o->kind == PM_OPT_CHOICE) {
            fputs(" (", f);
            for (int i = 0; o->choices[i]; i++)
                fprintf(f, "%s%s", i ? "|" : "", o->choices[i]);
            fputs(")", f);
        }
        if (o->kind != PM_OPT_FLAG) {
            fputs(" [default: ", f);
            print_value(o, f);
            fputs("]", f);
        }
        fputc('\n', f);
    }
}

void pm_args_print_settings(const pm_cli_t *cli, FILE *f)
{
    fprintf(f, "# %s settings; read back with %s @FILE\n", cli->program, cli->program);
    for (const pm_option_t *o = cli->options; o->name; o++) {
        if (o->kind == PM_OPT_FLAG) {
            if (*(int *)o->dest)
                fprintf(f, "--%s\n", o->name);
            continue;
        }
        int text = o->kind == PM_OPT_STRING || o->kind == PM_OPT_OUTPUT;
        if (text && !*(const char **)o->dest)
            continue;
        fprintf(f, "--%s ", o->name);
        if (text)
            print_word(*(const char **)o->dest, f);
        else
            print_value(o, f);
        fputc('\n', f);
    }
}
