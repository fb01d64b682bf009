/* settings.c: pm-render's NAME=VALUE parameters (engine.h, "settings"), the checks that need
 * no program, the stages' own checks of their values (--print-settings), and the table of
 * stages. The names, defaults and messages are pipelines/render's, which pm-render replaces. */
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <regex.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/exr.h"
#include "engine/engine.h"

static const struct {
    const char *name, *def;
} params[PM_P_COUNT] = {
    [PM_P_PHOTONS] = {"PHOTONS", ""},
    [PM_P_MAP] = {"MAP", "auto"},
    [PM_P_MODE] = {"MODE", "gather"},
    [PM_P_SPP] = {"SPP", ""},
    [PM_P_WIDTH] = {"WIDTH", ""},
    [PM_P_HEIGHT] = {"HEIGHT", ""},
    [PM_P_PRIMARY] = {"PRIMARY", ""},
    [PM_P_LIGHT_SAMPLES] = {"LIGHT_SAMPLES", ""},
    [PM_P_GUIDE] = {"GUIDE", "0"},
    [PM_P_ORDER] = {"ORDER", "auto"},
    [PM_P_LEAF] = {"LEAF", ""},
    [PM_P_RADIUS] = {"RADIUS", ""},
    [PM_P_K] = {"K", ""},
    [PM_P_KERNEL] = {"KERNEL", ""},
    [PM_P_WIDTHS] = {"WIDTHS", "fixed"},
    [PM_P_ISA] = {"ISA", ""},
    [PM_P_WIDTH_K] = {"WIDTH_K", ""},
    [PM_P_SHARDS] = {"SHARDS", "1"},
    [PM_P_GATHER] = {"GATHER", "simd-gather"},
    [PM_P_EXPOSURE] = {"EXPOSURE", "0"},
    [PM_P_TONE] = {"TONE", "srgb"},
    [PM_P_HALF] = {"HALF", "0"},
    [PM_P_AOV] = {"AOV", ""},
    [PM_P_SEED] = {"SEED", ""},
    [PM_P_PASSES] = {"PASSES", ""},
    [PM_P_TIME] = {"TIME", ""},
    [PM_P_TARGET_ERROR] = {"TARGET_ERROR", ""},
    [PM_P_ALPHA] = {"ALPHA", ""},
    [PM_P_PASS_RANGE] = {"PASS_RANGE", ""},
    [PM_P_THREADS] = {"THREADS", ""},
    [PM_P_JOBS] = {"JOBS", "1"},
    [PM_P_VERBOSE] = {"VERBOSE", "0"},
    [PM_P_QUIET] = {"QUIET", "0"},
    [PM_P_WAIT] = {"WAIT", "1"},
    [PM_P_KEEP] = {"KEEP", "all"},
    [PM_P_SECONDARY_DIRECT] = {"SECONDARY_DIRECT", "auto"},
    [PM_P_COVERAGE] = {"COVERAGE", "auto"},
    [PM_P_ADAPTIVE] = {"ADAPTIVE", "auto"},
    [PM_P_DIFFUSE_DEPTH] = {"DIFFUSE_DEPTH", "auto"},
    [PM_P_DIFFUSE_FROM] = {"DIFFUSE_FROM", ""},
    [PM_P_OVERLAP] = {"OVERLAP", "auto"},
};

const char *pm_param_name(pm_param_t p) { return p < PM_P_COUNT ? params[p].name : ""; }
const char *pm_param_default(pm_param_t p) { return p < PM_P_COUNT ? params[p].def : ""; }

pm_param_t pm_param_find(const char *name)
{
    for (int p = 0; p < PM_P_COUNT; p++)
        if (strcmp(params[p].name, name) == 0)
            return (pm_param_t)p;
    return PM_P_COUNT;
}

void pm_settings_init(pm_settings_t *s)
{
    memset(s, 0, sizeof *s);
    for (int p = 0; p < PM_P_COUNT; p++)
        s->value[p] = params[p].def;
    s->shards = 1;
    s->wait = 1;
}

static int cmp_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* The value is one of the words (a NULL-terminated list), else a usage error naming them. */
static pm_result_t choice(const pm_settings_t *s, pm_param_t p, const char *const *words)
{
    char list[256] = "";
    for (int i = 0; words[i]; i++) {
        if (strcmp(s->value[p], words[i]) == 0)
            return PM_OK;
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", i ? " " : "", words[i]);
    }
    return pm_error_set(PM_ERR_USAGE, "bad value for %s '%s': expected one of %s", params[p].name, s->value[p], list);
}

static int matches(const char *re, const char *s)
{
    regex_t rx;
    if (regcomp(&rx, re, REG_EXTENDED | REG_NOSUB) != 0)
        return 0;
    int ok = regexec(&rx, s, 0, NULL, 0) == 0;
    regfree(&rx);
    return ok;
}

#define COUNT_RE "^[1-9][0-9]*$"
#define SECONDARY_DIRECT_TIME 10.0 /* s: SECONDARY_DIRECT=auto's TIME from which it is on */
#define COVERAGE_TIME 2.0          /* s: COVERAGE=auto's TIME from which it is on */
/* A number of at least 0 as pipelines/render's isnum took it (no sign, no hex, no inf). */
#define NUM_RE "^([0-9]+([.][0-9]*)?|[.][0-9]+)([eE][-+]?[0-9]+)?$"

pm_result_t pm_settings_parse(pm_settings_t *s, int argc, char **argv)
{
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *eq = strchr(a, '=');
        if (!eq) {
            if (s->ntargets >= PM_ENGINE_MAX_TARGETS)
                return pm_error_set(PM_ERR_USAGE, "more than %d TARGETs", PM_ENGINE_MAX_TARGETS);
            s->targets[s->ntargets++] = a;
            continue;
        }
        char name[64];
        snprintf(name, sizeof name, "%.*s", (int)(eq - a), a);
        pm_param_t p = pm_param_find(name);
        if (p == PM_P_COUNT) {
            const char *names[PM_P_COUNT];
            for (int k = 0; k < PM_P_COUNT; k++)
                names[k] = params[k].name;
            qsort(names, PM_P_COUNT, sizeof names[0], cmp_names);
            char known[512] = "";
            for (int k = 0; k < PM_P_COUNT; k++)
                snprintf(known + strlen(known), sizeof known - strlen(known), "%s ", names[k]);
            return pm_error_set(PM_ERR_USAGE, "unknown parameter '%.*s' (known: %s)", (int)(eq - a), a, known);
        }
        if (strchr(eq + 1, '\n'))
            return pm_error_set(PM_ERR_USAGE, "parameter %s: a value cannot hold a newline", name);
        s->value[p] = eq + 1;
    }
    static const char *const modes[] = {"gather", "direct-vis", NULL},
                             *const maps[] = {"auto", "global", "indirect", NULL},
                             *const orders[] = {"auto", "hilbert", "morton", "none", NULL},
                             *const widths[] = {"fixed", "variable", NULL}, *const tones[] = {"srgb", "filmic", NULL},
                             *const bits[] = {"0", "1", NULL}, *const keeps[] = {"all", "buffers", "image", NULL},
                             *const autobits[] = {"auto", "0", "1", NULL},
                             *const depths[] = {"auto", "0", "1", "2", NULL};
    pm_result_t r;
    if ((r = choice(s, PM_P_MODE, modes)) || (r = choice(s, PM_P_MAP, maps)) || (r = choice(s, PM_P_ORDER, orders)) ||
        (r = choice(s, PM_P_WIDTHS, widths)) || (r = choice(s, PM_P_TONE, tones)) || (r = choice(s, PM_P_HALF, bits)) ||
        (r = choice(s, PM_P_VERBOSE, bits)) || (r = choice(s, PM_P_WAIT, bits)) || (r = choice(s, PM_P_QUIET, bits)) ||
        (r = choice(s, PM_P_GUIDE, bits)) || (r = choice(s, PM_P_KEEP, keeps)) ||
        (r = choice(s, PM_P_SECONDARY_DIRECT, autobits)) || (r = choice(s, PM_P_COVERAGE, autobits)) ||
        (r = choice(s, PM_P_ADAPTIVE, autobits)) || (r = choice(s, PM_P_OVERLAP, autobits)) ||
        (r = choice(s, PM_P_DIFFUSE_DEPTH, depths)))
        return r;
    const char *dd = s->value[PM_P_DIFFUSE_DEPTH];
    int dd_auto = !strcmp(dd, "auto");
    if (strcmp(dd, "0") && !dd_auto && !strcmp(s->value[PM_P_MODE], "direct-vis"))
        return pm_error_set(PM_ERR_USAGE,
                            "DIFFUSE_DEPTH=%s with MODE=direct-vis: diffuse bounces come before a gather point, and "
                            "direct-vis has none",
                            s->value[PM_P_DIFFUSE_DEPTH]);
    s->keep = strcmp(s->value[PM_P_KEEP], "all") == 0       ? PM_KEEP_ALL
              : strcmp(s->value[PM_P_KEEP], "buffers") == 0 ? PM_KEEP_BUFFERS
                                                            : PM_KEEP_IMAGE;
    if (s->keep != PM_KEEP_ALL && s->ntargets)
        return pm_error_set(PM_ERR_USAGE, "KEEP=%s with TARGETs: a TARGET is made to be kept", s->value[PM_P_KEEP]);
    if (!matches(COUNT_RE, s->value[PM_P_SHARDS]) || strlen(s->value[PM_P_SHARDS]) > 6)
        return pm_error_set(PM_ERR_USAGE, "bad value for SHARDS '%s': expected a count of at least 1",
                            s->value[PM_P_SHARDS]);
    if (!matches(COUNT_RE, s->value[PM_P_JOBS]))
        return pm_error_set(PM_ERR_USAGE, "bad value for JOBS '%s': expected a count of at least 1",
                            s->value[PM_P_JOBS]);
    if (s->value[PM_P_PASSES][0] && !matches(COUNT_RE, s->value[PM_P_PASSES]))
        return pm_error_set(PM_ERR_USAGE, "bad value for PASSES '%s': expected a count of at least 1",
                            s->value[PM_P_PASSES]);
    if (s->value[PM_P_TIME][0] &&
        (!matches(NUM_RE, s->value[PM_P_TIME]) || !isfinite(strtod(s->value[PM_P_TIME], NULL))))
        return pm_error_set(PM_ERR_USAGE, "bad value for TIME '%s': expected seconds, a number of at least 0",
                            s->value[PM_P_TIME]);
    /* At least the smallest normal double: a subnormal one would be compared as 0 (the stages
     * set DAZ) or, by a driver reading it as text, as a string; either stops wrong. */
    if (s->value[PM_P_TARGET_ERROR][0] &&
        (!matches(NUM_RE, s->value[PM_P_TARGET_ERROR]) || !(strtod(s->value[PM_P_TARGET_ERROR], NULL) >= DBL_MIN)))
        return pm_error_set(PM_ERR_USAGE,
                            "bad value for TARGET_ERROR '%s': expected a relative error above 0, at least %g",
                            s->value[PM_P_TARGET_ERROR], DBL_MIN);
    if (s->value[PM_P_ALPHA][0]) {
        double a = strtod(s->value[PM_P_ALPHA], NULL);
        if (!matches(NUM_RE, s->value[PM_P_ALPHA]) || !(a > 0 && a < 1))
            return pm_error_set(PM_ERR_USAGE, "bad value for ALPHA '%s': expected a number in (0, 1)",
                                s->value[PM_P_ALPHA]);
    }
    /* Secondary direct light: gather mode only (direct-vis queries are the primary hits, which have
     * their light samples already); auto turns it on for a TIME budget of SECONDARY_DIRECT_TIME s or
     * more, where it measured better (docs/accuracy.md: it costs more per pass and wins from the
     * passes of about 8 to 10 s on; below, the passes it loses cost more than it gains), and for any
     * progressive render of a scene with a sun or a sky (secondary_direct_sky, settled by the
     * drivers once the scene is read): the sun's light at a gather point is one shadow ray instead
     * of a density of sparse photons, and the sky-lit atrium measured better at every budget from
     * 4 s (docs/accuracy.md). */
    const char *sd = s->value[PM_P_SECONDARY_DIRECT];
    int gather = !strcmp(s->value[PM_P_MODE], "gather"), sd_auto = !strcmp(sd, "auto");
    s->secondary_direct = gather && (!strcmp(sd, "1") || (sd_auto && s->value[PM_P_TIME][0] &&
                                                          strtod(s->value[PM_P_TIME], NULL) >= SECONDARY_DIRECT_TIME));
    s->shards = atoi(s->value[PM_P_SHARDS]);
    s->verbose = s->value[PM_P_VERBOSE][0] == '1';
    s->quiet = s->value[PM_P_QUIET][0] == '1';
    s->wait = s->value[PM_P_WAIT][0] == '1';
    s->progressive = s->value[PM_P_TIME][0] || s->value[PM_P_TARGET_ERROR][0] || s->value[PM_P_PASS_RANGE][0] ||
                     (s->value[PM_P_PASSES][0] && strcmp(s->value[PM_P_PASSES], "1") != 0);
    s->secondary_direct_sky = gather && sd_auto && !s->secondary_direct && s->progressive;
    /* A diffuse bounce before the gather. From the first pass it wins the atria's long budgets and
     * loses the Cornell box's and the skylight room's at every budget measured (docs/accuracy.md,
     * "A diffuse bounce before the gather"). auto takes it in a progressive render's passes from
     * PM_DIFFUSE_AUTO_FROM on: the first passes keep the map's low noise, which is what short
     * budgets need, and the later ones the bounce's lower bias, which is what is left of the error
     * at long ones ("A diffuse bounce from a later pass on"); a render of fewer passes is the same
     * as with 0. */
    const char *df = s->value[PM_P_DIFFUSE_FROM];
    if (df[0] && (!matches(COUNT_RE, df) || strlen(df) > 9))
        return pm_error_set(PM_ERR_USAGE, "bad value for DIFFUSE_FROM '%s': expected a pass number of at least 1", df);
    if (df[0] && !strcmp(dd, "0"))
        return pm_error_set(PM_ERR_USAGE,
                            "DIFFUSE_FROM=%s says from which pass DIFFUSE_DEPTH's bounces are taken: "
                            "give DIFFUSE_DEPTH=1, 2 or auto",
                            df);
    if (dd_auto)
        s->diffuse_depth = gather && s->progressive && strcmp(s->value[PM_P_GATHER], "none") != 0 ? 1 : 0;
    else
        s->diffuse_depth = atoi(dd);
    s->diffuse_from = df[0] ? atoi(df) : dd_auto ? PM_DIFFUSE_AUTO_FROM : 1;
    if (s->diffuse_from > 1 && !s->progressive) /* a one-pass render is pass 1 */
        s->diffuse_depth = 0;
    if (!s->diffuse_depth)
        s->diffuse_from = 1;
    s->diffuse_auto = dd_auto;
    /* Adaptive passes: the resident passes only (pm-render refuses ADAPTIVE=1 for the pass files);
     * auto is on for a TIME budget (docs/accuracy.md, "Adaptive sampling"), so that PASSES and
     * TARGET_ERROR renders keep their bytes. */
    s->adaptive = s->progressive && (!strcmp(s->value[PM_P_ADAPTIVE], "1") ||
                                     (!strcmp(s->value[PM_P_ADAPTIVE], "auto") && s->value[PM_P_TIME][0]));
    if (!strcmp(s->value[PM_P_ADAPTIVE], "1") && !s->progressive)
        return pm_error_set(PM_ERR_USAGE, "ADAPTIVE=1 adapts progressive passes: give PASSES (above 1), TIME or "
                                          "TARGET_ERROR");
    if (!strcmp(s->value[PM_P_ADAPTIVE], "1") && s->value[PM_P_PASS_RANGE][0])
        return pm_error_set(PM_ERR_USAGE, "ADAPTIVE=1 with PASS_RANGE: the pass files are not adaptive (the resident "
                                          "passes are)");
    /* Overlapped passes: the resident passes only; auto for a TIME budget, whose passes' sizes
     * depend on the machine anyway, so that PASSES and TARGET_ERROR renders keep their bytes (an
     * overlapped adaptive pass takes the map of the image one pass older). */
    s->overlap = s->progressive && (!strcmp(s->value[PM_P_OVERLAP], "1") ||
                                    (!strcmp(s->value[PM_P_OVERLAP], "auto") && s->value[PM_P_TIME][0]));
    s->guide = s->value[PM_P_GUIDE][0] == '1';
    /* The boundary correction divides by the covered part of one kernel width: simd-gather with
     * fixed widths only (docs/programs/simd-gather.md, "Coverage"). auto turns it on for
     * progressive renders but a TIME below COVERAGE_TIME s: it costs the gather the scene's load
     * and its area samples at each spacing level, and pays where the bias it removes outweighs
     * the passes it costs (docs/accuracy.md, "The boundary correction": the atria's relMSE 2.5 to
     * 3.7 times lower from 8 s on, the Cornell box, caustic and skylight scenes within 0.8 to 1.2
     * times from 4 s on, and one render loses more to the start-up than it gains). From 2 s since
     * the scene cache (the gather's load 6 ms) and the TIME planner's foreseeing the passes at
     * which the gather samples a new spacing level (progressive.c, cover_level): the atria's
     * TIME=2 and TIME=4 relMSE 1.2 to 2.9 times lower (the sky-lit atrium's TIME=4 had been even
     * with the path tracer), the Cornell box's, the caustic scene's and the skylight room's 1.1
     * to 2 times higher, all of them below the path tracer's ("The boundary correction from
     * 2 s"); TIME=1 lost on the atrium and the Cornell box. */
    const char *cv = s->value[PM_P_COVERAGE];
    int cv_fit = !strcmp(s->value[PM_P_GATHER], "simd-gather") && !strcmp(s->value[PM_P_WIDTHS], "fixed");
    s->coverage = !strcmp(cv, "1") || (!strcmp(cv, "auto") && cv_fit && s->progressive &&
                                       !(s->value[PM_P_TIME][0] && strtod(s->value[PM_P_TIME], NULL) < COVERAGE_TIME));
    if (!strcmp(cv, "1") && strcmp(s->value[PM_P_GATHER], "simd-gather") != 0)
        return pm_error_set(PM_ERR_USAGE, "COVERAGE=1 is simd-gather's boundary correction, not GATHER=%s's",
                            s->value[PM_P_GATHER]);
    if (!strcmp(cv, "1") && strcmp(s->value[PM_P_WIDTHS], "fixed") != 0)
        return pm_error_set(PM_ERR_USAGE, "COVERAGE=1 needs WIDTHS=fixed (one kernel width for every query)");
    if (s->guide && strcmp(s->value[PM_P_MODE], "gather") != 0)
        return pm_error_set(PM_ERR_USAGE, "GUIDE=1 guides the secondary rays of MODE=gather, not MODE=%s",
                            s->value[PM_P_MODE]);
    if (s->guide && strcmp(s->value[PM_P_GATHER], "none") == 0)
        return pm_error_set(PM_ERR_USAGE,
                            "GUIDE=1 guides by the pass's photons: not with GATHER=none, which traces none");
    if (!dd_auto && atoi(dd) && strcmp(s->value[PM_P_GATHER], "none") == 0)
        return pm_error_set(PM_ERR_USAGE,
                            "DIFFUSE_DEPTH=%s bounces before a gather: not with GATHER=none, whose "
                            "image is the direct light alone",
                            dd);
    /* The pass files (PASS_RANGE, KEEP=all given, ...) have no guide: resident passes only. */
    if (s->guide && s->value[PM_P_PASS_RANGE][0])
        return pm_error_set(PM_ERR_USAGE, "GUIDE=1 with PASS_RANGE: the pass files have no guide (the resident "
                                          "passes and one-pass renders have)");
    if (s->value[PM_P_AOV][0]) {
        if ((r = pm_exr_aov_parse("AOV", s->value[PM_P_AOV], &s->aov)) != PM_OK)
            return r;
        /* The running image's layers need composite --stream --accumulate --aov, not done yet. */
        if (s->progressive)
            return pm_error_set(PM_ERR_USAGE,
                                "AOV=%s is done for a one-pass render only, not with PASSES, TIME, "
                                "TARGET_ERROR or PASS_RANGE",
                                s->value[PM_P_AOV]);
        if (s->aov & PM_EXR_AOV_VARIANCE)
            return pm_error_set(PM_ERR_USAGE,
                                "AOV=%s: variance is a progressive render's (the spread of its passes), "
                                "and AOV is done for one pass only: ask for albedo, normal or depth",
                                s->value[PM_P_AOV]);
    }
    const char *range = s->value[PM_P_PASS_RANGE];
    if (range[0]) {
        if (!matches("^[1-9][0-9]{0,8}:[1-9][0-9]{0,8}$", range) ||
            strtol(range, NULL, 10) > strtol(strchr(range, ':') + 1, NULL, 10))
            return pm_error_set(PM_ERR_USAGE, "bad value for PASS_RANGE '%s': expected A:B, passes 1 <= A <= B", range);
        if (s->value[PM_P_TIME][0] || s->value[PM_P_TARGET_ERROR][0])
            return pm_error_set(PM_ERR_USAGE, "PASS_RANGE with TIME or TARGET_ERROR: a range is a fixed set of passes");
        if (s->keep != PM_KEEP_ALL)
            return pm_error_set(PM_ERR_USAGE,
                                "KEEP=%s with PASS_RANGE: the passes of a range are made to be added later",
                                s->value[PM_P_KEEP]);
    }
    if (s->progressive && strcmp(s->value[PM_P_WIDTHS], "variable") == 0)
        return pm_error_set(PM_ERR_USAGE,
                            "WIDTHS=variable with progressive passes: the schedule shrinks one fixed width");
    if (s->progressive && s->ntargets && !s->value[PM_P_PASS_RANGE][0])
        return pm_error_set(PM_ERR_USAGE, "TARGETs with progressive passes: every pass makes its whole graph (a "
                                          "TARGET is for PASS_RANGE)");
    return PM_OK;
}

/* PROGRAM OPTION VALUE --print-settings: PM_OK, or a usage error with the stage's message. */
static pm_result_t check_opt(const pm_settings_t *s, const char *bin, pm_param_t p, const char *program,
                             const char *option)
{
    const char *v = s->value[p];
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", bin, program);
    if (!v[0] || access(path, X_OK) != 0)
        return PM_OK; /* a missing program is named when the stages are looked for */
    char *argv[] = {path, (char *)option, (char *)v, "--print-settings", NULL};
    int devnull[2];
    if (pm_proc_pipe(devnull) != PM_OK)
        return PM_ERR_IO;
    pm_spawn_t sp = {.argv = argv, .stdin_fd = -1, .stdout_fd = devnull[1], .capture_stderr = 1};
    pm_proc_t *proc;
    pm_result_t r = pm_proc_spawn(&sp, &proc);
    close(devnull[1]);
    if (r != PM_OK) {
        close(devnull[0]);
        return r;
    }
    char sink[4096];
    while (read(devnull[0], sink, sizeof sink) > 0)
        ;
    close(devnull[0]);
    pm_proc_status_t st;
    r = pm_proc_wait(proc, &st);
    if (r == PM_OK && st.exit_code != 0) {
        /* the stage's first line, without "PROGRAM: " and " (usage error)" */
        char msg[1024];
        snprintf(msg, sizeof msg, "%s", st.err ? st.err : "");
        msg[strcspn(msg, "\n")] = '\0';
        const char *m = msg;
        size_t pl = strlen(program);
        if (strncmp(m, program, pl) == 0 && strncmp(m + pl, ": ", 2) == 0)
            m += pl + 2;
        char *tail = strstr(msg, " (usage error)");
        if (tail && tail[14] == '\0')
            *tail = '\0';
        r = pm_error_set(PM_ERR_USAGE, "bad value for %s '%s': %s", params[p].name, v, m);
    }
    pm_proc_status_free(&st);
    return r;
}

/* One program's values at once (one process instead of one per value, some 20 ms each, and
 * the programs side by side), and one at a time only when that fails, to name the first the
 * program refuses. */
typedef struct {
    const char *program;
    const int *params; /* ending in PM_P_COUNT */
    const char *const *options;
    pm_proc_t *proc; /* running, or NULL: nothing to check */
} check_group_t;

static pm_result_t group_start(const pm_settings_t *s, const char *bin, check_group_t *g, int devnull)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", bin, g->program);
    char *argv[24];
    int n = 0;
    argv[n++] = path;
    for (int i = 0; g->params[i] != PM_P_COUNT && n < 20; i++)
        if (s->value[g->params[i]][0]) {
            argv[n++] = (char *)g->options[i];
            argv[n++] = (char *)s->value[g->params[i]];
        }
    g->proc = NULL;
    if (n == 1 || access(path, X_OK) != 0)
        return PM_OK; /* nothing given, or a missing program, named when the stages are looked for */
    argv[n++] = "--print-settings";
    argv[n] = NULL;
    pm_spawn_t sp = {.argv = argv, .stdin_fd = -1, .stdout_fd = devnull, .capture_stderr = 1};
    return pm_proc_spawn(&sp, &g->proc);
}

static pm_result_t group_finish(const pm_settings_t *s, const char *bin, check_group_t *g)
{
    if (!g->proc)
        return PM_OK;
    pm_proc_status_t st;
    pm_result_t r = pm_proc_wait(g->proc, &st);
    g->proc = NULL;
    int failed = r == PM_OK && st.exit_code != 0;
    pm_proc_status_free(&st);
    if (r != PM_OK || !failed)
        return r;
    for (int i = 0; g->params[i] != PM_P_COUNT; i++)
        if ((r = check_opt(s, bin, (pm_param_t)g->params[i], g->program, g->options[i])) != PM_OK)
            return r;
    return pm_error_set(PM_ERR_USAGE, "%s refuses the values given together (%s --print-settings)", g->program,
                        g->program);
}

pm_result_t pm_settings_check_stages(const pm_settings_t *s, const char *bin)
{
    /* The gather's options by program: knn-gather's radius is its --max-radius, and it has
     * no ISA and no variable widths (docs/pipelines.md, "The gather"). */
    const char *g = s->value[PM_P_GATHER], *base = strrchr(g, '/');
    base = base ? base + 1 : g;
    int knn = strcmp(base, "knn-gather") == 0;
    if (knn && strchr(g, '/')) { /* a knn-gather outside the program directory stands in for simd-gather */
        char *a = realpath(g, NULL), *b = realpath(bin, NULL);
        size_t bl = b ? strlen(b) : 0;
        knn = a && b && strncmp(a, b, bl) == 0 && a[bl] == '/' && !strchr(a + bl + 1, '/');
        free(a);
        free(b);
    }
    const char *family = knn ? "knn-gather" : "simd-gather";
    char fp[4096];
    snprintf(fp, sizeof fp, "%s/%s", bin, family);
    if (access(fp, X_OK) != 0)
        family = "simd-gather";
    static const int tp[] = {PM_P_PHOTONS, PM_P_SEED, PM_P_THREADS, PM_P_COUNT};
    static const char *const tpo[] = {"--photons", "--seed", "--threads"};
    static const int tg[] = {PM_P_SPP, PM_P_WIDTH, PM_P_HEIGHT, PM_P_PRIMARY, PM_P_LIGHT_SAMPLES, PM_P_COUNT};
    static const char *const tgo[] = {"--spp", "--width", "--height", "--primary", "--light-samples"};
    static const int lp[] = {PM_P_LEAF, PM_P_COUNT}, wp[] = {PM_P_WIDTH_K, PM_P_COUNT};
    static const char *const lpo[] = {"--leaf"}, *const wpo[] = {"--width-k"};
    static const int gp[] = {PM_P_RADIUS, PM_P_K, PM_P_KERNEL, PM_P_COUNT}, ep[] = {PM_P_EXPOSURE, PM_P_COUNT};
    const char *const go[] = {knn ? "--max-radius" : "--radius", "--k", "--kernel"};
    static const char *const epo[] = {"--exposure"};
    check_group_t groups[] = {{"trace-photons", tp, tpo, NULL}, {"trace-gather-points", tg, tgo, NULL},
                              {"hilbert-sort", lp, lpo, NULL},  {"build-photonmap", wp, wpo, NULL},
                              {family, gp, go, NULL},           {"composite", ep, epo, NULL}};
    enum { NG = sizeof groups / sizeof groups[0] };
    int devnull = open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (devnull < 0)
        return pm_error_set(PM_ERR_IO, "cannot open /dev/null: %s", strerror(errno));
    pm_result_t r = PM_OK;
    for (int i = 0; i < NG && r == PM_OK; i++)
        r = group_start(s, bin, &groups[i], devnull);
    close(devnull);
    /* every started check is waited for, whatever the first says; the first error in the order
     * pipelines/render judged them wins */
    pm_result_t first = r;
    char msg[PM_ERROR_MAX] = "";
    if (first != PM_OK)
        snprintf(msg, sizeof msg, "%s", pm_error_message());
    for (int i = 0; i < NG; i++) {
        pm_result_t ri = group_finish(s, bin, &groups[i]);
        if (first == PM_OK && ri != PM_OK) {
            first = ri;
            snprintf(msg, sizeof msg, "%s", pm_error_message());
        }
        if (i == 1 && first == PM_OK) {
            const char *spp = s->value[PM_P_SPP];
            if (matches("^[0-9]+$", spp) && strtoull(spp, NULL, 10) % 4 != 0) {
                first = PM_ERR_USAGE;
                snprintf(msg, sizeof msg,
                         "bad value for SPP '%s': expected a multiple of 4 (the secondary rays are traced in fours)",
                         spp);
            }
        }
        if (i == 3 && first == PM_OK) {
            if (knn && s->value[PM_P_ISA][0]) {
                first = PM_ERR_USAGE;
                snprintf(msg, sizeof msg, "ISA with GATHER=knn-gather: knn-gather is scalar (it has no --isa)");
            } else if (knn && strcmp(s->value[PM_P_WIDTHS], "fixed") != 0) {
                first = PM_ERR_USAGE;
                snprintf(msg, sizeof msg,
                         "WIDTHS=variable with GATHER=knn-gather: its width is the k-th photon's distance");
            }
        }
        if (i == 4 && first == PM_OK && s->value[PM_P_ISA][0]) {
            static const char *const isas[] = {"auto", "scalar", "sse4", "avx2", "avx512", NULL};
            if (choice(s, PM_P_ISA, isas) != PM_OK) {
                first = PM_ERR_USAGE;
                snprintf(msg, sizeof msg, "%s", pm_error_message());
            }
        }
    }
    if (first != PM_OK)
        return pm_error_set(first, "%s", msg);
    return PM_OK;
}

static const pm_stage_info_t stage_table[] = {
    {"trace-photons", "trace-photons", 1},
    {"build-photonmap", "build-photonmap", 1},
    {"build-photonmap.caustic", "build-photonmap", 1},
    {"trace-gather-points", "trace-gather-points", 2},
    {"hilbert-sort", "hilbert-sort", 2},
    {"simd-gather", "simd-gather", 0},
    {"simd-gather.caustic", "simd-gather", 0},
    {"composite", "composite", 0},
};

const pm_stage_info_t *pm_stage_table(size_t *n_out)
{
    *n_out = sizeof stage_table / sizeof stage_table[0];
    return stage_table;
}

int pm_diffuse_depth_for(const pm_settings_t *s, int specular, int portals)
{
    return s->diffuse_auto && (specular || portals) ? 0 : s->diffuse_depth;
}

/* A TIME budget below COVERAGE_TIME (and no boundary correction): the short budgets whose
 * per-pass defaults differ (pm_progressive_default_k, pm_progressive_default_photons). */
static int short_budget(const pm_settings_t *s)
{
    return !s->coverage && s->value[PM_P_TIME][0] && strtod(s->value[PM_P_TIME], NULL) < COVERAGE_TIME;
}

const char *pm_progressive_default_k(const pm_settings_t *s) { return short_budget(s) ? "2" : PM_PROGRESSIVE_K_TEXT; }

const char *pm_progressive_default_photons(const pm_settings_t *s)
{
    return short_budget(s) ? "75000" : PM_PROGRESSIVE_PHOTONS_TEXT;
}
