/* pm-compare: compares two pmtk files of one format within tolerances, the way golden
 * tests and regression checks need: structure (format, count, channels, bounds) and the
 * header keys must agree, except the volatile ones that record who made the file and
 * when (SOFTWARE, COMMAND, INPUT); integer channels must agree exactly; float channels
 * within --max-abs / --max-rel per value and --rms per channel. Prints one line per
 * channel with the largest differences and where they are.
 *
 * It answers as cmp does: exit 0 when the files agree, 1 when they differ (one line on stderr
 * says where first; not an error: the report is kept and --stats has no error key, "differ":
 * 1), 2 when it cannot answer, whatever the failure's class (usage, a file that is not
 * pmtk's or cannot be read, a full disk), so that a script's `if pm-compare A B` never takes
 * trouble for a difference. */
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/stage.h"
#include "formats/formats.h"

typedef struct {
    double max_abs, max_rel, rms;
    const char *ignore; /* comma-separated header keys not compared */
} compare_options_t;

static int ignored(const char *key, const char *list)
{
    if (!strcmp(key, "INPUT") || !strcmp(key, "SOFTWARE"))
        return 1;
    size_t n = strlen(key);
    for (const char *p = list; p && *p;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        if (len == n && !strncmp(p, key, n))
            return 1;
        p = comma ? comma + 1 : p + len;
    }
    return 0;
}

/* Where two files differ first, in the words of the line pm-compare prints (not an error). */
typedef struct {
    int differ;
    char why[PM_ERROR_MAX];
} verdict_t;

/* Records the first difference found; returns 1 so that a caller can stop at it. */
static int differ(verdict_t *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int differ(verdict_t *v, const char *fmt, ...)
{
    if (!v->differ) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(v->why, sizeof v->why, fmt, ap);
        va_end(ap);
        v->differ = 1;
    }
    return 1;
}

/* Every key of a (not ignored) must be in b with the same value; returns 1 when one is not. */
static int keys_differ(const pm_header_t *a, const pm_header_t *b, const char *an, const char *bn,
                       const compare_options_t *o, verdict_t *v)
{
    for (size_t i = 0; i < a->nkeys; i++) {
        const char *k = a->keys[i].key;
        if (ignored(k, o->ignore))
            continue;
        const char *val = pm_header_get(b, k);
        if (!val)
            return differ(v, "header key %s of '%s' is missing from '%s'", k, an, bn);
        if (strcmp(val, pm_header_get(a, k)) != 0)
            return differ(v, "header key %s differs: '%s' in '%s', '%s' in '%s'", k, pm_header_get(a, k), an, val, bn);
    }
    return 0;
}

static double value_at(const pm_channel_t *c, const void *col, uint64_t j)
{
    switch (c->type) {
    case PM_TYPE_U16: return ((const uint16_t *)col)[j];
    case PM_TYPE_U32: return ((const uint32_t *)col)[j];
    case PM_TYPE_F32: return ((const float *)col)[j];
    case PM_TYPE_F64: return ((const double *)col)[j];
    }
    return 0.0;
}

/* Compares a and b, writing the per-channel report to out; a difference is recorded in *v. */
static void compare(FILE *out, const pm_table_t *a, const pm_table_t *b, const char *an, const char *bn,
                    const compare_options_t *o, pm_stage_t *st, verdict_t *v)
{
    const pm_schema_t *s = a->hdr.schema;
    if (s != b->hdr.schema) {
        differ(v, "'%s' is a %s but '%s' is a %s", an, s->title, bn, b->hdr.schema->title);
        return;
    }
    if (a->count != b->count) {
        differ(v, "'%s' has %" PRIu64 " records, '%s' has %" PRIu64, an, a->count, bn, b->count);
        return;
    }
    if (a->hdr.channels != b->hdr.channels) {
        differ(v, "'%s' has channel mask 0x%08" PRIx32 ", '%s' has 0x%08" PRIx32, an, a->hdr.channels, bn,
               b->hdr.channels);
        return;
    }
    if (!ignored("BOUNDS", o->ignore) && memcmp(a->hdr.bounds, b->hdr.bounds, sizeof a->hdr.bounds) != 0) {
        differ(v, "'%s' and '%s' have different BOUNDS", an, bn);
        return;
    }
    if (keys_differ(&a->hdr, &b->hdr, an, bn, o, v) || keys_differ(&b->hdr, &a->hdr, bn, an, o, v))
        return;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!a->col[ci])
            continue;
        const pm_channel_t *c = &s->channels[ci];
        uint64_t n = a->count * c->components, worst = 0, mismatches = 0;
        double max_abs = 0, max_rel = 0, sum2 = 0;
        int is_float = c->type == PM_TYPE_F32 || c->type == PM_TYPE_F64;
        for (uint64_t j = 0; j < n; j++) {
            double x = value_at(c, a->col[ci], j), y = value_at(c, b->col[ci], j), d = fabs(x - y);
            double scale = fmax(fabs(x), fabs(y)), rel = scale > 0 ? d / scale : 0.0;
            sum2 += d * d;
            if (d > max_abs)
                max_abs = d, worst = j;
            max_rel = fmax(max_rel, rel);
            int ok = is_float ? (d <= o->max_abs || rel <= o->max_rel) : d == 0.0;
            mismatches += !ok;
        }
        double rms = n ? sqrt(sum2 / (double)n) : 0.0;
        int rms_ok = o->rms < 0 || rms <= o->rms;
        fprintf(out, "%-10s max_abs %.6g max_rel %.6g rms %.6g worst record %" PRIu64 "%s%s\n", c->name, max_abs,
                max_rel, rms, n ? worst / c->components : 0, mismatches ? " OUT OF TOLERANCE" : "",
                rms_ok ? "" : " RMS OUT OF TOLERANCE");
        char key[64];
        snprintf(key, sizeof key, "%s_max_abs", c->name);
        pm_stage_stat_double(st, key, max_abs);
        snprintf(key, sizeof key, "%s_rms", c->name);
        pm_stage_stat_double(st, key, rms);
        if (mismatches || !rms_ok)
            differ(v,
                   "'%s' and '%s' differ in channel '%s': %" PRIu64 " values out of tolerance, max_abs %.6g at record "
                   "%" PRIu64 ", rms %.6g",
                   an, bn, c->name, mismatches, max_abs, worst / c->components, rms);
    }
    st->items = a->count;
}

/* Reads A and B whole and writes the per-channel report to -o; *v says whether they differ. */
static pm_result_t run(pm_stage_t *st, const compare_options_t *o, verdict_t *v)
{
    const char *an = st->args.args[0], *bn = st->args.args[1];
    if (!strcmp(an, "-") && !strcmp(bn, "-"))
        return pm_error_set(PM_ERR_USAGE, "only one of A and B can be stdin");
    pm_table_t a, b;
    FILE *out;
    pm_result_t r = pm_table_read(an, NULL, 0, &a);
    if (r != PM_OK)
        return r;
    r = pm_table_read(bn, NULL, 0, &b);
    if (r != PM_OK) {
        pm_table_free(&a);
        return r;
    }
    r = pm_stage_open_output(st, &out);
    if (r == PM_OK) {
        compare(out, &a, &b, an, bn, o, st, v);
        pm_stage_stat_int(st, "differ", v->differ);
    }
    pm_table_free(&b);
    pm_table_free(&a);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    compare_options_t o = {.max_abs = 0.0, .max_rel = 0.0, .rms = -1.0};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"max-abs", 0, PM_OPT_DOUBLE, &o.max_abs, "X", "a float pair agrees when |a-b| <= X", 0, 1e300, NULL},
        {"max-rel", 0, PM_OPT_DOUBLE, &o.max_rel, "X", "... or when |a-b| <= X max(|a|,|b|)", 0, 1e300, NULL},
        {"rms", 0, PM_OPT_DOUBLE, &o.rms, "X", "each channel's root-mean-square difference must be <= X; -1: unchecked",
         -1, 1e300, NULL},
        {"ignore-keys", 0, PM_OPT_STRING, &o.ignore, "K1,K2",
         "header keys not compared (besides SOFTWARE, COMMAND, INPUT)", 1, 0, NULL},
        {0},
    };
    static const char about[] =
        "Compare two pmtk files of one format: structure and header keys exactly, values within "
        "tolerances. Exit 0 when they agree, 1 when they differ, 2 on any trouble (bad usage, a file that is not "
        "pmtk's or cannot be read, a failed write).";
    const pm_cli_t cli = {"pm-compare", "[options] A B", about, options, 2, 2, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc ? 2 : 0;
    verdict_t v = {0};
    /* Trouble of any class is 2, as cmp's: 1 is kept for the answer "they differ". */
    if (pm_stage_end(&st, run(&st, &o, &v)) != 0)
        return 2;
    if (v.differ) {
        fprintf(stderr, "pm-compare: %s\n", v.why);
        return 1;
    }
    return 0;
}
