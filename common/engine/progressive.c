/* progressive.c: pm-render's resident progressive passes (progressive.h): six stage programs
 * started once with pipes between them, a pass at a time through them on streams of
 * documents, the running image in OUTDIR/running.pm, what it holds in OUTDIR/passes.txt, the
 * TIME budget sized from the passes' own wall times. docs/pipelines.md, "Progressive passes". */
#include "engine/progressive.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/args.h"
#include "base/timer.h"
#include "formats/formats.h"
#include "image/adaptive.h"
#include "photonmap/coverage.h"
#include "photonmap/gather_stage.h"
#include "render/areasample.h"
#include "render/light.h"
#include "render/scene.h"
#include "render/scene_cache.h"

extern char **environ;

/* Per-pass defaults for the parameters not given (the scene's render block sizes one render,
 * not a pass): PM_PROGRESSIVE_* in engine.h, pm_progressive_default_k and _photons. */
/* s the driver keeps for what follows the last pass (the stages' exit, the sync, stats.json),
 * measured by tests/bench/92-passes.sh */
#define TAIL_S 0.04
#define MAX_PASSES 100000 /* passes.txt lines read back; far beyond any budget */
#define LAST_MARGIN 1.05  /* a TIME budget's last pass: its bound times this must fit */
/* ... plus this for each multiple of the largest pass so far that it goes beyond it, up to
 * GROW_MARGIN_MAX: a pass larger than any before it touches arrays no earlier pass freed for
 * it, and its cost per unit grows (measured at load 3.8 on the Cornell box at 128 x 128, the
 * stages' start out of pass 1's time: 9 to 11 units after 4 took 1% to 24% more than their
 * bounds, and 2 of 5 TIME=1 renders ended 5% to 7% late) */
/* ADAPTIVE: the first pass whose rays follow the running image's error (the map is made from
 * the passes before it) and how often the map is made again, in passes */
#define ADAPTIVE_FROM_PASS 5
#define ADAPTIVE_EVERY 1
#define GROW_MARGIN 0.10
#define GROW_MARGIN_MAX 1.25
/* A new coverage level's sampling set aside: the last level's cost times this for each level
 * finer (cover_level). Twice the samples a level, but measured 2.2 to 3.5 times the gather's CPU
 * (the atrium's 0.3, 0.6 and 1.2 million samples about 0.2, 0.4 and 0.7 s, the Cornell box's 0.5
 * and 1.0 million 0.15 and 0.53 s; the skylight room's 0.8 and 1.6 million 0.24 to 0.27 and 0.54
 * to 1.0 s), and a new level near the end is what overruns a budget. Erring high costs little
 * since a level that does not fit is held (pm_progressive_cover_size): at 2.5 the skylight
 * room's TIME=2 ended at 2.02 to 2.22 s in 3 runs of 9, at 3.5 within 2.01 s in 9 runs. */
#define COVER_GROWTH 3.5
/* A bouncing pass's time over a pass's of the same size without the bounce, at most (measured
 * 1.40 and 1.53 on the atria, docs/accuracy.md, "A diffuse bounce before the gather") */
#define DIFFUSE_COST 1.6

/* The stages: the caustic map (CB) and the caustic gather (CG) run for a scene with mirrors or
 * glass in gather mode; the photon stages and the gathers not with GATHER=none; hilbert-sort
 * not with ORDER=none. stage_names name their --stats and their column in stats.json. */
enum { TP, BM, CB, TG, HS, SG, CG, CO, NSTAGE };
static const char *const stage_names[NSTAGE] = {"trace-photons",       "build-photonmap", "build-photonmap.caustic",
                                                "trace-gather-points", "hilbert-sort",    "simd-gather",
                                                "simd-gather.caustic", "composite"};
static const char *const stage_progs[NSTAGE] = {"trace-photons",       "build-photonmap", "build-photonmap",
                                                "trace-gather-points", "hilbert-sort",    "simd-gather",
                                                "simd-gather",         "composite"};
/* The pipes: the plans (the tracers', and the gathers' coverage plans), the photons (global,
 * caustic), the maps (global, caustic), the queries (as traced, sorted, caustic), the buffers
 * (direct, indirect, caustic), the pass log, the passes' weights, the tracers' word that they
 * are ready for pass 1 (--ready). */
enum {
    P_PLAN_TP,
    P_PLAN_TG,
    P_PLAN_SG,
    P_PLAN_CG,
    P_PH,
    P_CPH,
    P_MAP,
    P_CMAP,
    P_Q,
    P_SQ,
    P_CQ,
    P_DIR,
    P_IND,
    P_CAU,
    P_LOG,
    P_WTS,
    P_RDY,
    NPIPE
};

/* An argv with its words' storage. */
typedef struct {
    char *v[64];
    int n;
    char store[8192];
    size_t used;
} argv_t;

static void push(argv_t *a, const char *w)
{
    size_t len = strlen(w) + 1;
    if (a->n >= 63 || a->used + len > sizeof a->store)
        return; /* the words pm-render gives are few and short; a longer one is cut (and refused by its stage) */
    char *d = a->store + a->used;
    memcpy(d, w, len);
    a->used += len;
    a->v[a->n++] = d;
    a->v[a->n] = NULL;
}

static void pushf(argv_t *a, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void pushf(argv_t *a, const char *fmt, ...)
{
    char w[4200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w, sizeof w, fmt, ap);
    va_end(ap);
    push(a, w);
}

/* --opt VALUE when the parameter is given */
static void opt(argv_t *a, const char *name, const char *value)
{
    if (value && value[0]) {
        push(a, name);
        push(a, value);
    }
}

typedef struct {
    int pass;
    int64_t photons;
    int primary;
    char err[32]; /* the running image's relative error after it, "-" after one pass */
    double wall_s;
    int added;            /* by this run */
    double cpu_s[NSTAGE]; /* s of CPU each stage used in the pass (-1: not run or not known) */
} pass_t;

typedef struct {
    const pm_settings_t *s;
    const char *me, *bin;
    char out[4096];
    char scene[4096];
    char scene_id[512];
    int64_t photons; /* per full pass */
    int kmax;        /* PRIMARY per full pass: the units a full pass has */
    const char *spp, *k;
    int light_samples_zero; /* no emissive triangle, sun or sky: LIGHT_SAMPLES=0 */
    int secondary_direct;   /* SECONDARY_DIRECT on, and the scene has a light the gather points sample */
    int diffuse_depth;      /* trace-gather-points --diffuse-depth, 0 none (pm_diffuse_depth_for) */
    char settings[8192];    /* what the running image depends on, one line */
    char request[512];      /* PASSES, TIME, TARGET_ERROR, EXPOSURE, TONE, HALF of this run */
    char old_request[512];  /* passes.txt's, when the state is kept */
    int finished;           /* the request is met: passes.txt names it (else its request is empty) */
    pass_t *passes;         /* passes.txt's and this run's */
    int npasses, cap;
    char radius1[64];
    int lock_fd;
    int on[NSTAGE];         /* the stages this render runs */
    int direct;             /* the direct buffer: not with MODE=direct-vis over a global map */
    const char *mode, *map; /* trace-gather-points --mode, build-photonmap --map (MAP=auto resolved) */
    const char *order;      /* hilbert-sort --order (ORDER=auto resolved; hilbert-sort off for none) */
    int adaptive;           /* ADAPTIVE on, with a direct buffer for composite to weigh the pixels by */
    double adapt_s;         /* s the driver spent making the adaptive maps */
    double adapt_last;      /* s the last map took: the next one's time, which a TIME budget sets aside */
    double spawn_s;         /* s from the command's start to the stages' start: pm-render's own */
    double ready_s[NSTAGE]; /* s from the command's start to a tracer's --ready line (-1: none) */
    int cover_plan;         /* the global gather has --coverage: a TIME render's planner foresees the
                             * passes at which it samples the scene at a new level (cover_level) */
    int cover_finest;       /* the finest level it samples at (PM_COVERAGE_MAX_SAMPLES); INT_MAX: none */
    int cover_plan_cg;      /* the caustic gather has --coverage: a TIME render's last passes keep its
                             * samples (pm_progressive_hold_caustic) */
} prog_t;

/* the driver's lines on stderr, "ME: ..." (pm_engine_say) */
#define say(p, ...) pm_engine_say((p)->me, __VA_ARGS__)

static const char *val(const prog_t *p, pm_param_t k) { return p->s->value[k]; }

int pm_progressive_handles(const pm_settings_t *s, char *why, size_t cap)
{
    const char *w = NULL;
    /* KEEP=all is the default value of KEEP: given on the command line (a pointer into argv,
     * not the table's default), it asks for the pass files */
    if (s->value[PM_P_PASS_RANGE][0])
        w = "PASS_RANGE makes pass files";
    else if (s->keep == PM_KEEP_ALL && s->value[PM_P_KEEP] != pm_param_default(PM_P_KEEP))
        w = "KEEP=all keeps every pass's files";
    else if (strcmp(s->value[PM_P_GATHER], "simd-gather") && strcmp(s->value[PM_P_GATHER], "none"))
        w = "GATHER other than simd-gather or none";
    else if (s->shards != 1)
        w = "SHARDS";
    else if (strcmp(s->value[PM_P_WIDTHS], "fixed"))
        w = "WIDTHS=variable";
    else if (!strcmp(s->value[PM_P_MAP], "indirect") && !strcmp(s->value[PM_P_MODE], "gather"))
        w = "MAP=indirect with MODE=gather"; /* refused, with the reason, by the pass files' driver */
    else if (!strcmp(s->value[PM_P_GATHER], "none") && !strcmp(s->value[PM_P_MODE], "direct-vis") &&
             strcmp(s->value[PM_P_MAP], "indirect"))
        w = "GATHER=none with MODE=direct-vis over a global map"; /* nothing to composite: refused there too */
    else if (s->ntargets)
        w = "TARGETs";
    if (why && cap)
        snprintf(why, cap, "%s", w ? w : "");
    return w == NULL;
}

/* ---- the size of the next pass (TIME) ---- */

/* An upper bound of the wall time of a pass of u units, from the passes so far (k[j] units in
 * sec[j] s). A pass costs c + b k with c, b >= 0 (a fixed part: the pipes' latency, the map's
 * tree, composite's images; a part in proportion to its photons, rays and queries), so every
 * pass bounds every other: t(u) <= sec[j] max(1, u / k[j]). The tightest of these bounds holds
 * whatever c is, where a line fitted through two passes of nearby sizes on a busy machine can
 * put nearly all of the time in c and promise a large pass for nothing (measured: a 41-unit
 * pass predicted at 4 s took 23.6 s at load 12). The first pass, which also pays the stages'
 * start, only loosens it. */
static double time_bound(const int *k, const double *sec, int n, int u)
{
    double t = INFINITY;
    for (int j = 0; j < n; j++) {
        double kj = k[j] > 0 ? k[j] : 1, bj = sec[j] * (u > kj ? u / kj : 1.0);
        t = bj < t ? bj : t;
    }
    return t;
}

int pm_progressive_next_size(const int *k, const double *sec, int n, int kmax, double remaining)
{
    if (kmax < 1)
        kmax = 1;
    if (n <= 0)
        return 1;
    int next = 2 * k[n - 1];
    next = next > kmax ? kmax : next < 1 ? 1 : next;
    int after = 2 * next > kmax ? kmax : 2 * next;
    if (time_bound(k, sec, n, 1) > remaining)
        return 0;
    if (time_bound(k, sec, n, next) + time_bound(k, sec, n, after) <= remaining) /* it and the one after it */
        return next;
    /* the last pass: the largest that ends by the budget with 5% to spare (a pass on a machine
     * shared with other work took up to 12% longer than its bound, measured at load 7), and
     * no larger than a full pass: a pass above kmax units cost more than its share (at load 3
     * on the Cornell box, 25 units 4.28 s where 16 took 1.80 s, 18 units 2.57 s where 16 took
     * 1.94 s: the stages' arrays outgrow what the passes before them freed), so TIME=8 and
     * TIME=16 ended 6.5% and 7.7% late; more to spare when it is larger than any pass before
     * it (GROW_MARGIN). What is left after it goes to smaller passes, until not even a unit
     * fits. */
    int largest = 1;
    for (int j = 0; j < n; j++)
        largest = k[j] > largest ? k[j] : largest;
    for (int u = kmax; u > 1; u--) {
        double m = u > largest ? LAST_MARGIN + GROW_MARGIN * ((double)u / largest - 1.0) : LAST_MARGIN;
        if ((m < GROW_MARGIN_MAX ? m : GROW_MARGIN_MAX) * time_bound(k, sec, n, u) <= remaining)
            return u;
    }
    return 1;
}

int pm_progressive_cover_size(const int *k, const double *sec, int n, int kmax, double remaining, double extra,
                              int holdable, int *hold_out)
{
    int units = pm_progressive_next_size(k, sec, n, kmax, remaining - extra);
    *hold_out = 0;
    if (extra > 0.0 && holdable && n > 0) {
        int keep = pm_progressive_next_size(k, sec, n, kmax, remaining);
        if (keep > 0 && 2 * units <= keep)
            units = keep, *hold_out = 1;
    }
    return units;
}

int pm_progressive_hold_caustic(const int *k, int n, int kmax, int units)
{
    int largest = 0;
    for (int j = 0; j < n; j++)
        largest = k[j] > largest ? k[j] : largest;
    return units > 0 && units < kmax && n > 0 && units <= largest;
}

/* ---- the coverage levels of the passes (TIME) ---- */

/* simd-gather --coverage samples the scene's surfaces again each time a pass's kernel reaches a
 * finer spacing level, twice the samples a level: on the atrium 0.3, 0.6 and 1.2 million area
 * samples at passes 2, 4 and 9 of a TIME=4 render, the last 0.7 s of gather in a pass of 1 unit
 * that took 0.08 s without, which ended the render 15% late. The levels are known ahead: a
 * pass's kernel width follows from r_1 and the photons before it (the schedule), so the planner
 * sets the next new level's sampling aside (run_passes, COVER_GROWTH). */

static uint64_t count_samples(const void *scene, double spacing) { return pm_area_samples_count(scene, spacing); }

/* The level simd-gather samples at for pass `next` (the schedule's width from the running
 * image's radius1 and the photons before it, as the stage computes it), INT_MIN when there is
 * none yet (pass 1 goes uncorrected; r_1 is known after it). */
static int cover_level(const prog_t *p, int next)
{
    double r1 = 0.0, alpha = PM_PASS_ALPHA_DEFAULT;
    const char *r1s = val(p, PM_P_RADIUS)[0] ? val(p, PM_P_RADIUS) : p->radius1; /* RADIUS: the gather's own text */
    if (next < 2 || p->npasses < 1 || !r1s[0] || pm_parse_double(r1s, &r1) != PM_OK || !(r1 > 0.0))
        return INT_MIN;
    if (val(p, PM_P_ALPHA)[0] && pm_parse_double(val(p, PM_P_ALPHA), &alpha) != PM_OK)
        return INT_MIN;
    uint64_t before = 0;
    for (int j = 0; j < p->npasses; j++)
        if (p->passes[j].pass < next)
            before += (uint64_t)p->passes[j].photons;
    double h = pm_gather_schedule_radius(
        r1, pm_gather_pass_index((uint64_t)next, before, (uint64_t)p->passes[0].photons), alpha);
    int level;
    if (pm_coverage_level(h, &level) != PM_OK)
        return INT_MIN;
    return level > p->cover_finest ? level : p->cover_finest;
}

/* The passes at the end of p->passes[0..n-1] still "pending" (planned, not logged). */
static int trailing_pending(const prog_t *p, int n)
{
    int m = 0;
    while (m < n && !strcmp(p->passes[n - 1 - m].err, "pending"))
        m++;
    return m;
}

/* ---- the state: running.pm and passes.txt ---- */

static int add_pass(prog_t *p, const pass_t *ps)
{
    if (p->npasses == p->cap) {
        int cap = p->cap ? 2 * p->cap : 64;
        pass_t *n = realloc(p->passes, (size_t)cap * sizeof *n);
        if (!n)
            return -1;
        p->passes = n, p->cap = cap;
    }
    p->passes[p->npasses++] = *ps;
    return 0;
}

/* passes.txt, written beside and renamed: the settings, the request, a line per pass. */
static int write_list(prog_t *p)
{
    char path[4200], tmp[4300];
    snprintf(path, sizeof path, "%s/passes.txt", p->out);
    snprintf(tmp, sizeof tmp, "%s/.passes.txt.%d", p->out, (int)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f)
        return -1;
    fprintf(f,
            "# pm-render's resident passes: what running.pm holds (docs/pipelines.md, \"Progressive passes\")\n"
            "settings %s\nrequest %s\n# pass photons primary relative_error\n",
            p->settings, p->finished ? p->request : "");
    for (int i = 0; i < p->npasses; i++)
        fprintf(f, "%d %" PRId64 " %d %s\n", p->passes[i].pass, p->passes[i].photons, p->passes[i].primary,
                p->passes[i].err);
    int bad = ferror(f);
    if (fclose(f) != 0 || bad || rename(tmp, path) != 0) {
        unlink(tmp);
        return -1;
    }
    return 0;
}

/* Keeps the state when passes.txt names these settings and running.pm is whole and holds its
 * passes; else removes both (the passes start again). Returns the passes kept. */
static int read_state(prog_t *p)
{
    char path[4200], line[9000];
    snprintf(path, sizeof path, "%s/passes.txt", p->out);
    FILE *f = fopen(path, "r");
    int ok = f != NULL, n = 0, named = 0;
    const char *why = NULL;
    while (ok && fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = 0;
        if (line[0] == '#')
            continue;
        if (!strncmp(line, "settings ", 9)) {
            if (strcmp(line + 9, p->settings))
                ok = 0, why = "other settings";
            named = 1;
            continue;
        }
        if (!strncmp(line, "request ", 8)) {
            snprintf(p->old_request, sizeof p->old_request, "%s", line + 8);
            continue;
        }
        pass_t ps = {0};
        if (!named) /* the settings come first: a list without them is another driver's */
            ok = 0, why = "passes.txt names no settings";
        else if (sscanf(line, "%d %" SCNd64 " %d %31s", &ps.pass, &ps.photons, &ps.primary, ps.err) != 4 ||
                 ps.pass != n + 1 || n >= MAX_PASSES || add_pass(p, &ps) != 0)
            ok = 0, why = "a damaged passes.txt";
        n++;
    }
    if (f)
        fclose(f);
    pm_table_t t = {0};
    char state[4200];
    snprintf(state, sizeof state, "%s/running.pm", p->out);
    if (ok && n > 0) {
        uint64_t held = 0;
        int pending = 0;
        const uint32_t need = 1u << PM_RADIANCE_RGB | 1u << PM_RADIANCE_VARIANCE;
        if (pm_table_read(state, &pm_radiance_schema, need, &t) != PM_OK) {
            ok = 0, why = "a damaged running.pm";
            say(p, "the running image is damaged (%s): the passes start again", pm_error_message());
            why = NULL;
        } else if ((pending = trailing_pending(p, n)), pm_header_get_u64(&t.hdr, state, "passes", &held) != PM_OK ||
                                                           held > (uint64_t)n ||
                                                           held + (uint64_t)pending < (uint64_t)n) {
            ok = 0, why = "running.pm and passes.txt disagree";
        } else {
            /* passes under way when the last run stopped (two with OVERLAP): in the running image
             * or not; the last one in it has the image's error, one before it none on record */
            if (pending) {
                p->npasses = n = (int)held;
                for (int j = n - pending > 0 ? n - pending : 0; j < n; j++)
                    if (!strcmp(p->passes[j].err, "pending")) {
                        const char *e = j == n - 1 ? pm_header_get(&t.hdr, "relative_error") : NULL;
                        snprintf(p->passes[j].err, sizeof p->passes[j].err, "%s", e ? e : "-");
                    }
            }
            const char *r1 = pm_header_get(&t.hdr, "radius1");
            snprintf(p->radius1, sizeof p->radius1, "%s", r1 ? r1 : "");
        }
        pm_table_free(&t);
    }
    if (!ok || n == 0) {
        if (why)
            say(p, "the running image does not hold these passes (%s): the passes start again", why);
        unlink(state);
        unlink(path);
        p->npasses = 0;
        p->old_request[0] = 0;
        p->radius1[0] = 0;
        return 0;
    }
    return n;
}

/* ---- OUTDIR ---- */

/* The stages' environment: the driver's, with PMTK_FSYNC=0 (the running image and the images
 * are rewritten after every pass and synced once at the end: a power loss in between leaves
 * a running.pm whose checksum the next run checks) and OMP_WAIT_POLICY=passive unless set
 * (six programs share the cores, and a thread spinning for work takes one from a stage that
 * has work). envp is malloc'd. */
static char **stage_env(const char *out_dir)
{
    size_t n = 0;
    while (environ[n])
        n++;
    char **e = calloc(n + 4, sizeof *e);
    if (!e)
        return NULL;
    size_t k = 0;
    int omp = 0;
    /* the scene from the cache the driver's load left (render/scene_cache.h), unless the
     * environment names one (or none) */
    static char cache[PATH_MAX + 64] = "PMTK_SCENE_CACHE=";
    int own_cache = !getenv("PMTK_SCENE_CACHE");
    if (own_cache)
        pm_engine_scene_cache(out_dir, cache + 17, sizeof cache - 17);
    for (size_t i = 0; i < n; i++) {
        if (!strncmp(environ[i], "PMTK_FSYNC=", 11))
            continue;
        omp |= !strncmp(environ[i], "OMP_WAIT_POLICY=", 16);
        e[k++] = environ[i];
    }
    e[k++] = "PMTK_FSYNC=0";
    if (own_cache)
        e[k++] = cache;
    if (!omp)
        e[k++] = "OMP_WAIT_POLICY=passive";
    e[k] = NULL;
    return e;
}

/* -q, --threads, and --stats into OUTDIR/.stats-NAME.json (none of which a file records),
 * which stats.json takes in under "stages" */
static void common_opts(const prog_t *p, argv_t *a, int stage)
{
    if (strcmp(val(p, PM_P_VERBOSE), "1"))
        push(a, "-q");
    opt(a, "--threads", val(p, PM_P_THREADS));
    push(a, "--stats");
    pushf(a, "%s/.stats-%s.json", p->out, stage_names[stage]);
}

/* The command lines of the stages this render runs (p->on). fd[] holds the pipes' ends a
 * stage names as /dev/fd/N (the caustic photons', the direct buffer's, the caustic queries'
 * write ends; the maps', the direct buffer's, the caustic buffer's, the weights' read ends;
 * the pass log's write end). first: the first pass of this run. */
static void stage_argv(const prog_t *p, argv_t a[NSTAGE], const int fd[NPIPE][2], int first)
{
    char path[4200];
    memset(a, 0, sizeof(argv_t) * NSTAGE);
    for (int i = 0; i < NSTAGE; i++) {
        if (!p->on[i])
            continue;
        snprintf(path, sizeof path, "%s/%s", p->bin, stage_progs[i]);
        push(&a[i], path);
    }
    if (p->on[TP]) {
        push(&a[TP], p->scene);
        pushf(&a[TP], "--photons");
        pushf(&a[TP], "%" PRId64, p->photons);
        opt(&a[TP], "--seed", val(p, PM_P_SEED));
        if (p->secondary_direct)
            push(&a[TP], "--indirect-only");
        push(&a[TP], "--plan");
        push(&a[TP], "-");
        push(&a[TP], "--ready");
        pushf(&a[TP], "/dev/fd/%d", fd[P_RDY][1]);
        push(&a[TP], "-o");
        push(&a[TP], "-");
        if (p->on[CB]) {
            push(&a[TP], "--caustic-output");
            pushf(&a[TP], "/dev/fd/%d", fd[P_CPH][1]);
        }
    }
    for (int i = BM; i <= CB; i++) {
        if (!p->on[i])
            continue;
        push(&a[i], "--stream");
        push(&a[i], "-");
        push(&a[i], "-o");
        push(&a[i], "-");
        push(&a[i], "--map");
        push(&a[i], i == CB ? "caustic" : p->map);
    }

    push(&a[TG], p->scene);
    push(&a[TG], "--mode");
    push(&a[TG], p->mode);
    opt(&a[TG], "--spp", p->spp);
    opt(&a[TG], "--width", val(p, PM_P_WIDTH));
    opt(&a[TG], "--height", val(p, PM_P_HEIGHT));
    pushf(&a[TG], "--primary");
    pushf(&a[TG], "%d", p->kmax);
    opt(&a[TG], "--light-samples", p->light_samples_zero ? "0" : val(p, PM_P_LIGHT_SAMPLES));
    opt(&a[TG], "--seed", val(p, PM_P_SEED));
    if (p->secondary_direct)
        push(&a[TG], "--secondary-direct");
    if (p->diffuse_depth) {
        push(&a[TG], "--diffuse-depth");
        pushf(&a[TG], "%d", p->diffuse_depth);
        if (p->s->diffuse_from > 1) {
            push(&a[TG], "--diffuse-from");
            pushf(&a[TG], "%d", p->s->diffuse_from);
        }
    }
    if (p->s->guide) { /* GUIDE=1: every pass guided by the guide's photons (make_guide) */
        push(&a[TG], "--guide");
        pushf(&a[TG], "%s/guide-photons.pm", p->out);
    }
    if (p->adaptive) { /* read before each pass; none yet: a uniform pass (adapt) */
        push(&a[TG], "--adaptive");
        pushf(&a[TG], p->s->overlap ? "%s/adaptive-%%d.pm" : "%s/adaptive.pm", p->out);
    }
    push(&a[TG], "--plan");
    push(&a[TG], "-");
    push(&a[TG], "--ready");
    pushf(&a[TG], "/dev/fd/%d", fd[P_RDY][1]);
    if (p->on[SG]) {
        push(&a[TG], "-o");
        push(&a[TG], "-");
    } else {
        push(&a[TG], "--no-queries"); /* GATHER=none: the direct light alone */
    }
    if (p->direct) {
        push(&a[TG], "--direct");
        pushf(&a[TG], "/dev/fd/%d", fd[P_DIR][1]);
    }
    if (p->on[CG]) {
        push(&a[TG], "--caustic-queries");
        pushf(&a[TG], "/dev/fd/%d", fd[P_CQ][1]);
    }

    if (p->on[HS]) {
        push(&a[HS], "--stream");
        push(&a[HS], "-");
        push(&a[HS], "-o");
        push(&a[HS], "-");
        push(&a[HS], "--order");
        push(&a[HS], p->order);
        opt(&a[HS], "--leaf", val(p, PM_P_LEAF));
    }

    for (int i = SG; i <= CG; i++) {
        if (!p->on[i])
            continue;
        push(&a[i], "--stream");
        push(&a[i], "pairs");
        pushf(&a[i], "/dev/fd/%d", fd[i == CG ? P_CMAP : P_MAP][0]);
        push(&a[i], "-");
        push(&a[i], "-o");
        push(&a[i], "-");
        if (val(p, PM_P_RADIUS)[0]) /* r_1: RADIUS */
            opt(&a[i], "--radius", val(p, PM_P_RADIUS));
        else if (i == CG) /* the caustic map's own density, measured on every pass as the pass files do */
            opt(&a[i], "--k", p->k), push(&a[i], "--k-each-pass");
        else if (first > 1) /* a rerun: the running image's r_1 */
            opt(&a[i], "--radius", p->radius1);
        else /* measured by K on pass 1 */
            opt(&a[i], "--k", p->k);
        opt(&a[i], "--kernel", val(p, PM_P_KERNEL));
        opt(&a[i], "--isa", val(p, PM_P_ISA));
        if (p->s->coverage)
            opt(&a[i], "--coverage", p->scene);
        if ((i == SG && p->cover_plan) || (i == CG && p->cover_plan_cg)) { /* a line a pass: whether it
                                                                            * keeps the samples it has */
            push(&a[i], "--coverage-plan");
            pushf(&a[i], "/dev/fd/%d", fd[i == CG ? P_PLAN_CG : P_PLAN_SG][0]);
        }
        opt(&a[i], "--alpha", val(p, PM_P_ALPHA));
        /* a rerun: where its first pass sits on the schedule, from the photons of the passes
         * the running image holds (the stage counts on from the maps' own photon counts) */
        if (first > 1 && p->npasses >= first - 1) {
            int64_t before = 0;
            for (int j = 0; j < first - 1; j++)
                before += p->passes[j].photons;
            pushf(&a[i], "--unit-photons");
            pushf(&a[i], "%" PRId64, p->passes[0].photons);
            pushf(&a[i], "--pass-photons");
            pushf(&a[i], "%" PRId64, before);
        }
    }

    /* the buffers in the order the pass files add them: direct, indirect, caustic */
    push(&a[CO], "--stream");
    if (p->direct)
        pushf(&a[CO], "/dev/fd/%d", fd[P_DIR][0]);
    if (p->on[SG])
        push(&a[CO], "-");
    if (p->on[CG])
        pushf(&a[CO], "/dev/fd/%d", fd[P_CAU][0]);
    push(&a[CO], "--accumulate");
    push(&a[CO], "running.pm");
    push(&a[CO], "-o");
    push(&a[CO], "image.exr");
    push(&a[CO], "--png");
    push(&a[CO], "image.png");
    push(&a[CO], "--exposure");
    push(&a[CO], val(p, PM_P_EXPOSURE));
    push(&a[CO], "--tone");
    push(&a[CO], val(p, PM_P_TONE));
    if (!strcmp(val(p, PM_P_HALF), "1"))
        push(&a[CO], "--half");
    push(&a[CO], "--pass-log");
    pushf(&a[CO], "/dev/fd/%d", fd[P_LOG][1]);
    push(&a[CO], "--weights");
    pushf(&a[CO], "/dev/fd/%d", fd[P_WTS][0]);
    for (int i = 0; i < NSTAGE; i++)
        if (p->on[i])
            common_opts(p, &a[i], i);
}

/* What the running image depends on, as one line: the scene's content (not its path) and
 * every parameter a pass's bytes follow. PASSES, TIME, TARGET_ERROR (how many passes),
 * EXPOSURE, TONE, HALF (the images alone), THREADS, VERBOSE, QUIET, WAIT, JOBS and KEEP are
 * not in it. */
static void make_settings(prog_t *p)
{
    static const pm_param_t keys[] = {PM_P_PHOTONS,       PM_P_SPP,   PM_P_WIDTH, PM_P_HEIGHT, PM_P_PRIMARY,
                                      PM_P_LIGHT_SAMPLES, PM_P_ORDER, PM_P_LEAF,  PM_P_RADIUS, PM_P_K,
                                      PM_P_KERNEL,        PM_P_ISA,   PM_P_SEED,  PM_P_ALPHA};
    size_t at = (size_t)snprintf(p->settings, sizeof p->settings, "scene=%s", p->scene_id);
    for (size_t i = 0; i < sizeof keys / sizeof *keys && at < sizeof p->settings; i++)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " %s=%s", pm_param_name(keys[i]),
                               val(p, keys[i]));
    /* what else a pass's bytes follow, named only when not the default (the line of a running
     * image made before these ran resident stays the same): K's default when it is not
     * PM_PROGRESSIVE_K (a TIME below 2 s, pm_progressive_default_k; the caustic gather measures
     * r_1 by it on every pass) */
    if (!val(p, PM_P_K)[0] && p->k[0] && strcmp(p->k, PM_PROGRESSIVE_K_TEXT) && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " K_DEFAULT=%s", p->k);
    /* and PHOTONS's when it is not PM_PROGRESSIVE_PHOTONS (the same short budgets) */
    if (!val(p, PM_P_PHOTONS)[0] && p->photons != PM_PROGRESSIVE_PHOTONS && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " PHOTONS_DEFAULT=%" PRId64, p->photons);
    if (strcmp(p->mode, "gather") && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " MODE=%s", p->mode);
    if (strcmp(p->map, "global") && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " MAP=%s", p->map);
    if (!p->on[SG] && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " GATHER=none");
    if (p->secondary_direct && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " SECONDARY_DIRECT=1");
    if (p->s->guide && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " GUIDE=1");
    if (p->diffuse_depth && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " DIFFUSE_DEPTH=%d", p->diffuse_depth);
    if (p->diffuse_depth && p->s->diffuse_from > 1 && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " DIFFUSE_FROM=%d", p->s->diffuse_from);
    if (p->s->coverage && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " COVERAGE=1");
    if (p->adaptive && at < sizeof p->settings)
        at += (size_t)snprintf(p->settings + at, sizeof p->settings - at, " ADAPTIVE=1");
    snprintf(p->request, sizeof p->request, "PASSES=%s TIME=%s TARGET_ERROR=%s EXPOSURE=%s TONE=%s HALF=%s",
             val(p, PM_P_PASSES), val(p, PM_P_TIME), val(p, PM_P_TARGET_ERROR), val(p, PM_P_EXPOSURE),
             val(p, PM_P_TONE), val(p, PM_P_HALF));
}

/* The request's words before EXPOSURE: how many passes it asks for. */
static int same_passes_asked(const char *a, const char *b)
{
    const char *ea = strstr(a, " EXPOSURE="), *eb = strstr(b, " EXPOSURE=");
    return ea && eb && ea - a == eb - b && !strncmp(a, b, (size_t)(ea - a));
}

/* composite on running.pm alone: the images at a new EXPOSURE, TONE or HALF, no pass. */
static int retone(prog_t *p, char **env)
{
    argv_t a = {0};
    char path[4200];
    snprintf(path, sizeof path, "%s/composite", p->bin);
    push(&a, path);
    push(&a, "running.pm");
    push(&a, "-o");
    push(&a, "image.exr");
    push(&a, "--png");
    push(&a, "image.png");
    push(&a, "--exposure");
    push(&a, val(p, PM_P_EXPOSURE));
    push(&a, "--tone");
    push(&a, val(p, PM_P_TONE));
    if (!strcmp(val(p, PM_P_HALF), "1"))
        push(&a, "--half");
    common_opts(p, &a, CO);
    pm_spawn_t sp = {.argv = a.v, .cwd = p->out, .stdin_fd = -1, .stdout_fd = -1, .capture_stderr = 1, .env = env};
    pm_proc_status_t st;
    if (pm_proc_run(&sp, &st) != PM_OK) {
        say(p, "%s", pm_error_message());
        return 3;
    }
    int code = st.exit_code;
    if (code)
        say(p, "re-toning the running image failed: %s", st.err && st.err[0] ? st.err : "composite failed");
    pm_proc_status_free(&st);
    return code ? 1 : 0;
}

static void sync_file(const char *dir, const char *name)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd >= 0) {
        (void)fsync(fd);
        close(fd);
    }
}

/* stats.json: {"scene", "params", "passes": [{"pass", "status", "photons", "primary", "wall_s",
 * "relative_error", "cpu_s", "stages_cpu_s", "stages"}], "stages": {NAME: the stage's --stats over every pass of this
 * run}, "total": {"passes", "added", "relative_error", "wall_s",
 * "first_image_s", "stopped_by", "alpha", "radius1", "resident": true}}. A pass's "stages" holds,
 * in the words of the stages' own --stats, what the driver asked each stage for in that pass
 * (trace-photons emitted, trace-gather-points primary and spp, simd-gather k and radius_m, the
 * schedule's r_p of radius1): the resident stages write their --stats once, at their end, so
 * a pass has no stats file of its own (pipelines/error-vs-time reads these; hilbert-sort's leaf
 * is the stage's own, from its --stats). */
static void write_stats(prog_t *p, double wall, double first_image, const char *stop)
{
    json_t *root = json_object(), *params = json_object(), *passes = json_array(), *total = json_object();
    json_object_set_new(root, "scene", json_string(p->scene_id));
    for (int k = 0; k < PM_P_COUNT; k++)
        json_object_set_new(params, pm_param_name((pm_param_t)k), json_string(val(p, (pm_param_t)k)));
    json_object_set_new(root, "params", params);
    int added = 0;
    double a, r1 = 0.0;
    if (!(val(p, PM_P_ALPHA)[0] && pm_parse_double(val(p, PM_P_ALPHA), &a) == PM_OK))
        a = PM_PASS_ALPHA_DEFAULT;
    if (p->radius1[0] && pm_parse_double(p->radius1, &r1) != PM_OK)
        r1 = 0.0;
    int64_t spp = 0;
    pm_parse_i64(p->spp, &spp);
    uint64_t before = 0; /* the photons of the passes before pass i: its place on the schedule */
    for (int i = 0; i < p->npasses; before += (uint64_t)p->passes[i].photons, i++) {
        const pass_t *ps = &p->passes[i];
        json_t *o = json_object(), *st = json_object(), *tp = json_object(), *tg = json_object(), *sg = json_object();
        json_object_set_new(tp, "emitted", json_integer(ps->photons));
        json_object_set_new(tp, "pass", json_integer(ps->pass));
        json_object_set_new(tg, "primary", json_integer(ps->primary));
        if (spp > 0)
            json_object_set_new(tg, "spp", json_integer(spp));
        json_object_set_new(tg, "pass", json_integer(ps->pass));
        if (!val(p, PM_P_RADIUS)[0]) {
            double kk;
            if (pm_parse_double(p->k, &kk) == PM_OK)
                json_object_set_new(sg, "k", json_real(kk));
        }
        if (r1 > 0.0)
            json_object_set_new(
                sg, "radius_m",
                json_real(pm_gather_schedule_radius(
                    r1, pm_gather_pass_index((uint64_t)ps->pass, before, (uint64_t)p->passes[0].photons), a)));
        json_object_set_new(sg, "pass", json_integer(ps->pass));
        if (p->on[TP])
            json_object_set_new(st, "trace-photons", tp);
        else
            json_decref(tp);
        json_object_set_new(st, "trace-gather-points", tg);
        if (p->on[SG])
            json_object_set_new(st, "simd-gather", sg);
        else
            json_decref(sg);
        json_object_set_new(o, "pass", json_integer(ps->pass));
        json_object_set_new(o, "status", json_string(ps->added ? "added" : "kept"));
        json_object_set_new(o, "photons", json_integer(ps->photons));
        json_object_set_new(o, "primary", json_integer(ps->primary));
        json_object_set_new(o, "wall_s", ps->added ? json_real(ps->wall_s) : json_null());
        /* the CPU each resident stage used in the pass (/proc, in clock ticks) and their sum:
         * the pass's compute, against which its wall time is the pipeline's overhead */
        json_t *cpu = json_object();
        double csum = 0.0;
        int known = 0;
        for (int k = 0; ps->added && k < NSTAGE; k++)
            if (ps->cpu_s[k] >= 0.0) {
                json_object_set_new(cpu, stage_names[k], json_real(round(ps->cpu_s[k] * 100.0) / 100.0));
                csum += ps->cpu_s[k], known++;
            }
        json_object_set_new(o, "cpu_s", known ? json_real(round(csum * 100.0) / 100.0) : json_null());
        json_object_set_new(o, "stages_cpu_s", cpu);
        double e;
        json_object_set_new(o, "relative_error", pm_parse_double(ps->err, &e) == PM_OK ? json_real(e) : json_null());
        json_object_set_new(o, "stages", st);
        json_array_append_new(passes, o);
        added += ps->added;
    }
    json_object_set_new(root, "passes", passes);
    /* each resident stage's --stats, for all its passes; hilbert-sort's leaf into every pass */
    json_t *stages = json_object();
    for (int i = 0; i < NSTAGE; i++) {
        char sp[4200];
        snprintf(sp, sizeof sp, "%s/.stats-%s.json", p->out, stage_names[i]);
        json_t *j = json_load_file(sp, 0, NULL);
        unlink(sp);
        if (j)
            json_object_set_new(stages, stage_names[i], j);
    }
    json_t *leaf = json_object_get(json_object_get(stages, "hilbert-sort"), "leaf");
    for (size_t i = 0; leaf && i < json_array_size(passes); i++) {
        json_t *hs = json_object();
        json_object_set(hs, "leaf", leaf);
        json_object_set_new(json_object_get(json_array_get(passes, i), "stages"), "hilbert-sort", hs);
    }
    json_object_set_new(root, "stages", stages);
    double e;
    json_object_set_new(total, "passes", json_integer(p->npasses));
    json_object_set_new(total, "added", json_integer(added));
    json_object_set_new(total, "relative_error",
                        p->npasses && pm_parse_double(p->passes[p->npasses - 1].err, &e) == PM_OK ? json_real(e)
                                                                                                  : json_null());
    json_object_set_new(total, "wall_s", json_real(wall));
    json_object_set_new(total, "first_image_s", first_image >= 0 ? json_real(first_image) : json_null());
    /* the start-up: pm-render's own (to the stages' start), then each tracer's scene and ray
     * tracer until it said it was ready for pass 1 (s from the command's start) */
    json_t *ready = json_object();
    double last = -1.0;
    for (int i = 0; i < NSTAGE; i++)
        if (p->ready_s[i] >= 0.0) {
            json_object_set_new(ready, stage_names[i], json_real(p->ready_s[i]));
            last = p->ready_s[i] > last ? p->ready_s[i] : last;
        }
    json_object_set_new(total, "start_s", p->spawn_s > 0.0 ? json_real(p->spawn_s) : json_null());
    json_object_set_new(total, "ready_s", last >= 0.0 ? json_real(last) : json_null());
    json_object_set_new(total, "stages_ready_s", ready);
    json_object_set_new(total, "stopped_by", json_string(stop));
    json_object_set_new(total, "alpha", json_real(a));
    json_object_set_new(total, "radius1", r1 > 0.0 ? json_real(r1) : json_null());
    json_object_set_new(total, "resident", json_true());
    json_object_set_new(total, "adaptive", json_boolean(p->adaptive));
    if (p->adaptive) /* the driver's time making the maps (image/adaptive.h), in the passes' wall times */
        json_object_set_new(total, "adaptive_s", json_real(p->adapt_s));
    json_object_set_new(root, "total", total);
    char path[4200], tmp[4300];
    snprintf(path, sizeof path, "%s/stats.json", p->out);
    snprintf(tmp, sizeof tmp, "%s/.stats.json.%d", p->out, (int)getpid());
    if (json_dump_file(root, tmp, JSON_INDENT(2)) != 0 || rename(tmp, path) != 0) {
        unlink(tmp);
        say(p, "could not write '%s'", path);
    }
    json_decref(root);
}

/* Reads the running image's radius1 after pass 1 (the gather measured it). */
static void read_radius1(prog_t *p)
{
    char state[4200];
    snprintf(state, sizeof state, "%s/running.pm", p->out);
    pm_reader_t *rd;
    if (pm_reader_open(state, &pm_radiance_schema, 0, &rd) == PM_OK) {
        const char *r1 = pm_header_get(pm_reader_header(rd), "radius1");
        snprintf(p->radius1, sizeof p->radius1, "%s", r1 ? r1 : "");
        pm_reader_close(rd);
    }
}

/* RENDER_PASS_HOOK (environment; pipelines/error-vs-time sets it): an executable run as HOOK
 * PASS SECONDS IMAGE once the image holds passes 1 to PASS, SECONDS the wall time since the
 * command started; its time counts in the render's. A failing hook is reported and the passes
 * go on. */
/* GUIDE=1: the guide's photons, made before the passes into OUTDIR/guide-photons.pm (removed
 * after them): pass 1's photon stream at a full pass's size, with their directions
 * (trace-photons --pass 1 --direction). Every pass's trace-gather-points reads it, so pass 1 is
 * guided by photons like its own and the later passes by pass 1's; any guide keeps each pass's
 * estimate unbiased. Returns 0, or the exit status (1 the stage failed, 3 it could not run). */
static int make_guide(const prog_t *p, char **env)
{
    argv_t a = {0};
    pushf(&a, "%s/trace-photons", p->bin);
    push(&a, p->scene);
    push(&a, "--photons");
    pushf(&a, "%" PRId64, p->photons);
    opt(&a, "--seed", val(p, PM_P_SEED));
    push(&a, "--pass");
    push(&a, "1");
    push(&a, "--direction");
    push(&a, "-q");
    opt(&a, "--threads", val(p, PM_P_THREADS));
    push(&a, "-o");
    pushf(&a, "%s/guide-photons.pm", p->out);
    pm_spawn_t sp = {.argv = a.v, .stdin_fd = -1, .stdout_fd = -1, .env = env, .capture_stderr = 1};
    pm_proc_status_t st;
    if (pm_proc_run(&sp, &st) != PM_OK) {
        say(p, "cannot run trace-photons for the guide: %s", pm_error_message());
        return 3;
    }
    int rc = st.exit_code == 0 ? 0 : st.exit_code == 3 ? 3 : 1;
    if (rc)
        say(p, "trace-photons for the guide failed (exit %d): %.400s", st.exit_code, st.err ? st.err : "");
    pm_proc_status_free(&st);
    return rc;
}

static void run_hook(const prog_t *p, char **env, int pass, double seconds)
{
    const char *hook = getenv("RENDER_PASS_HOOK");
    if (!hook || !hook[0])
        return;
    argv_t a = {0};
    push(&a, hook);
    pushf(&a, "%d", pass);
    pushf(&a, "%.3f", seconds);
    pushf(&a, "%s/image.exr", p->out);
    pm_spawn_t sp = {.argv = a.v, .stdin_fd = -1, .stdout_fd = -1, .env = env};
    pm_proc_status_t st;
    if (pm_proc_run(&sp, &st) != PM_OK)
        say(p, "pass %d: RENDER_PASS_HOOK '%s' failed (%s)", pass, hook, pm_error_message());
    else if (st.exit_code)
        say(p, "pass %d: RENDER_PASS_HOOK '%s' failed (exit %d)", pass, hook, st.exit_code);
    pm_proc_status_free(&st);
}

/* Waits until the tracers have loaded the scene and built their ray tracers (each writes
 * "PROGRAM ready WALL_S CPU_S" to --ready and closes it; a tracer that fails first just closes
 * it), so that pass 1 is asked for, and timed, from there: its wall time is then its own, not
 * the stages' start-up, and a TIME budget's next passes are sized from what passes cost
 * (docs/pipelines.md, "Progressive passes"). Closes rfd. */
static void wait_ready(prog_t *p, int rfd, double t0)
{
    FILE *f = fdopen(rfd, "r");
    if (!f) {
        close(rfd);
        return;
    }
    char line[256];
    int want = p->on[TP] + p->on[TG], got = 0;
    while (got < want && fgets(line, sizeof line, f)) {
        char name[64]; /* the stage's own wall and CPU s go to its --stats (ready_s, ready_cpu_s) */
        if (sscanf(line, "%63s ready", name) != 1 || !strstr(line, " ready"))
            continue;
        for (int j = 0; j < 2; j++) {
            int i = j ? TG : TP;
            if (p->on[i] && !strcmp(name, stage_progs[i]) && p->ready_s[i] < 0.0)
                p->ready_s[i] = pm_time_wall() - t0, got++;
        }
    }
    fclose(f);
}

/* The passes: the six stages started, a pass at a time, the stages ended. Returns the exit
 * status; *stop_out says what stopped the passes, *first_out when the first image was in
 * place (s from t0; -1 if none). */
/* ADAPTIVE: the multiplier trace-gather-points reads before pass `for_pass`, made from
 * running.pm once it holds `held` passes for the passes from ADAPTIVE_FROM_PASS on, again every
 * ADAPTIVE_EVERY passes; removed before then, so that the first passes (and a rerun's before its
 * state is that far) are uniform. One pass at a time it is OUTDIR/adaptive.pm; with OVERLAP,
 * OUTDIR/adaptive-P.pm for pass P (trace-gather-points --adaptive OUTDIR/adaptive-%d.pm), since a
 * pass is traced while the one before it is still being composited against its own map.
 * for_pass 0: OUTDIR/adaptive.pm, the map the next pass would take (left at the end of a run). 0,
 * or 3 when it cannot be written. */
static void adapt_path(const prog_t *p, int for_pass, char *out, size_t size)
{
    if (p->s->overlap && for_pass > 0)
        snprintf(out, size, "%s/adaptive-%d.pm", p->out, for_pass);
    else
        snprintf(out, size, "%s/adaptive.pm", p->out);
}

static int adapt(prog_t *p, int held, int for_pass)
{
    if (!p->adaptive)
        return 0;
    char map[4200], state[4200];
    adapt_path(p, for_pass, map, sizeof map);
    snprintf(state, sizeof state, "%s/running.pm", p->out);
    if (held < ADAPTIVE_FROM_PASS - 1) {
        if (unlink(map) != 0 && errno != ENOENT) {
            say(p, "cannot remove '%s': %s", map, strerror(errno));
            return 3;
        }
        return 0;
    }
    if ((held - (ADAPTIVE_FROM_PASS - 1)) % ADAPTIVE_EVERY != 0)
        return 0;
    double t = pm_time_wall();
    char *argv[] = {(char *)p->me, "ADAPTIVE", state};
    pm_result_t r = pm_adaptive_from_state(state, map, 3, argv, NULL);
    p->adapt_last = pm_time_wall() - t;
    p->adapt_s += p->adapt_last;
    if (r != PM_OK) {
        say(p, "cannot make the adaptive map: %s", pm_error_message());
        return r == PM_ERR_INPUT ? 1 : 3;
    }
    return 0;
}

/* With OVERLAP: pass P's map, once composite has weighed the pass by it. */
static void unadapt(const prog_t *p, int pass)
{
    char map[4200];
    adapt_path(p, pass, map, sizeof map);
    if (p->adaptive && p->s->overlap)
        unlink(map);
}

static int run_passes(prog_t *p, char **env, double t0, int first, const char **stop_out, double *first_out)
{
    const pm_settings_t *s = p->s;
    int64_t maxp = 0;
    double budget = -1.0, target = 0.0;
    if (s->value[PM_P_PASSES][0])
        pm_parse_i64(s->value[PM_P_PASSES], &maxp);
    if (s->value[PM_P_TIME][0])
        pm_parse_double(s->value[PM_P_TIME], &budget);
    if (s->value[PM_P_TARGET_ERROR][0])
        pm_parse_double(s->value[PM_P_TARGET_ERROR], &target);
    static char stopbuf[96];
    *first_out = -1.0;
    /* the pipes; the ends a stage names as /dev/fd/N are inherited (stage_argv), and each stage
     * closes those it does not use, so that a reader sees the end of its pipe when its writer
     * exits; every other end is close-on-exec */
    int fd[NPIPE][2];
    for (int i = 0; i < NPIPE; i++)
        fd[i][0] = fd[i][1] = -1;
    for (int i = 0; i < NPIPE; i++)
        if (pm_proc_pipe(fd[i]) != PM_OK) {
            say(p, "%s", pm_error_message());
            for (int j = 0; j < i; j++)
                close(fd[j][0]), close(fd[j][1]);
            return 3;
        }
    /* each stage: stdin, stdout, and the ends it names (-1: none) */
    int in_fd[NSTAGE] = {fd[P_PLAN_TP][0], fd[P_PH][0], fd[P_CPH][0], fd[P_PLAN_TG][0],
                         fd[P_Q][0],       -1,          fd[P_CQ][0],  p->on[SG] ? fd[P_IND][0] : -1};
    in_fd[SG] = p->on[HS] ? fd[P_SQ][0] : fd[P_Q][0];
    int out_fd[NSTAGE] = {fd[P_PH][1], fd[P_MAP][1], fd[P_CMAP][1], p->on[SG] ? fd[P_Q][1] : -1,
                          fd[P_SQ][1], fd[P_IND][1], fd[P_CAU][1],  -1};
    int uses[NSTAGE][4] = {{p->on[CB] ? fd[P_CPH][1] : -1, fd[P_RDY][1], -1, -1},
                           {-1, -1, -1, -1},
                           {-1, -1, -1, -1},
                           {p->direct ? fd[P_DIR][1] : -1, p->on[CG] ? fd[P_CQ][1] : -1, fd[P_RDY][1], -1},
                           {-1, -1, -1, -1},
                           {fd[P_MAP][0], p->cover_plan ? fd[P_PLAN_SG][0] : -1, -1, -1},
                           {fd[P_CMAP][0], p->cover_plan_cg ? fd[P_PLAN_CG][0] : -1, -1, -1},
                           {p->direct ? fd[P_DIR][0] : -1, p->on[CG] ? fd[P_CAU][0] : -1, fd[P_LOG][1], fd[P_WTS][0]}};
    int inherit[NSTAGE * 4], ninherit = 0;
    for (int i = 0; i < NSTAGE; i++)
        for (int j = 0; j < 4; j++)
            if (p->on[i] && uses[i][j] >= 0) {
                fcntl(uses[i][j], F_SETFD, 0);
                inherit[ninherit++] = uses[i][j];
            }
    argv_t a[NSTAGE];
    stage_argv(p, a, (const int(*)[2])fd, first);
    int rc = 0;
    pm_proc_t *proc[NSTAGE] = {0};
    p->spawn_s = pm_time_wall() - t0;
    for (int i = 0; i < NSTAGE && rc == 0; i++) {
        if (!p->on[i])
            continue;
        int closes[NSTAGE * 4], nclose = 0;
        for (int k = 0; k < ninherit; k++) {
            int mine = 0;
            for (int j = 0; j < 4; j++)
                mine |= uses[i][j] == inherit[k];
            if (!mine)
                closes[nclose++] = inherit[k];
        }
        if (!strcmp(val(p, PM_P_VERBOSE), "1")) {
            fprintf(stderr, "%s:", p->me);
            for (int w = 0; w < a[i].n; w++)
                fprintf(stderr, " %s", a[i].v[w]);
            fputc('\n', stderr);
        }
        /* stderr captured (read when the stage ends: with -q a stage says nothing until it
         * fails, so its pipe never fills), or passed through with VERBOSE=1, whose notes, a
         * few a pass, could fill it over a long render */
        pm_spawn_t sp = {.argv = a[i].v,
                         .cwd = i == CO ? p->out : NULL,
                         .stdin_fd = in_fd[i],
                         .stdout_fd = out_fd[i],
                         .capture_stderr = strcmp(val(p, PM_P_VERBOSE), "1") != 0,
                         .close_fds = closes,
                         .nclose = nclose,
                         .env = env};
        if (pm_proc_spawn(&sp, &proc[i]) != PM_OK) {
            say(p, "%s", pm_error_message());
            rc = 3;
        }
    }
    /* the driver keeps the plans' write ends (of the tracers it runs), the weights' write end
     * and the log's read end */
    int plan_tp = p->on[TP] ? fd[P_PLAN_TP][1] : -1, plan_tg = fd[P_PLAN_TG][1], wts = fd[P_WTS][1];
    int plan_sg = p->cover_plan ? fd[P_PLAN_SG][1] : -1, plan_cg = p->cover_plan_cg ? fd[P_PLAN_CG][1] : -1;
    for (int i = 0; i < NPIPE; i++) {
        if (fd[i][1] != plan_tp && fd[i][1] != plan_tg && fd[i][1] != wts && fd[i][1] != plan_sg && fd[i][1] != plan_cg)
            close(fd[i][1]);
        if (i != P_LOG && i != P_RDY)
            close(fd[i][0]);
    }
    FILE *logf = rc == 0 ? fdopen(fd[P_LOG][0], "r") : NULL;
    if (!logf)
        close(fd[P_LOG][0]);
    if (rc == 0)
        wait_ready(p, fd[P_RDY][0], t0);
    else
        close(fd[P_RDY][0]);
    void (*old_pipe)(int) = signal(SIGPIPE, SIG_IGN); /* a plan whose tracer failed: EPIPE, not death */
    int k[4096 + 1];
    double sec[4096 + 1];
    int nk = 0;
    const char *stop = "";
    int pass = first - 1, failed = 0;
    /* the coverage level of the last pass logged, and what sampling the scene at a new level last
     * cost beyond the pass's bound, at which level (-1: not yet measured); the level of the last
     * pass planned (the one before the next, with a pass in flight) */
    int cov_level = INT_MIN, cov_cost_level = 0, cov_units = 0, cov_plan_level = INT_MIN;
    double cov_sg = -1.0, sg_rate = INFINITY; /* the gather's CPU in that pass; its cheapest CPU s a unit */
    /* OVERLAP: the next pass is planned as soon as the last one's log line is read, while the one
     * between them is still in the stages, so that the tracers trace it while the gathers finish
     * the one before (a pass's tail: the sort waits for every query, the gather for every sorted
     * one). At most `depth` passes are in flight; the planner counts the one in flight at its
     * bound. Each pass's wall time is then from the log line before it to its own, and its CPU the
     * stages' in that span. */
    int depth = p->s->overlap ? 2 : 1, planned = first - 1, inflight = 0, stopping = 0, diffuse_scaled = 0;
    struct {
        int units, hold, cov_next, shared; /* shared: in flight beside another pass */
        int held_weight;                   /* its weight line not yet written (below) */
        double cov_extra, ts;
        char weight[64];
    } fl[2];
    double t_log = -1.0, c_log[NSTAGE];
    for (int i = 0; i < NSTAGE; i++)
        c_log[i] = proc[i] ? pm_proc_cpu_s(proc[i]) : -1.0;
    while (rc == 0 && logf) {
        while (!stopping && inflight < depth) {
            int next = planned + 1, units = p->kmax, cov_next = INT_MIN, hold = 0;
            double cov_extra = 0.0;
            if (maxp && next > maxp) {
                snprintf(stopbuf, sizeof stopbuf, "PASSES=%" PRId64, maxp);
                stop = stopbuf;
                stopping = 1;
                break;
            }
            if (budget >= 0.0) {
                /* the next pass's adaptive map is made once it is sized: as long as the last */
                double left = budget - (pm_time_wall() - t0) - TAIL_S - p->adapt_last;
                /* the passes from DIFFUSE_FROM on cost more per unit than those before it (1.4 to
                 * 1.5 times, docs/accuracy.md): the earlier passes bound them at DIFFUSE_COST
                 * times their time, so that the first bouncing pass is sized (or the render
                 * ended) by the budget as any other, and the bouncing passes' own times bound
                 * the rest */
                if (p->diffuse_depth && s->diffuse_from > 1 && next == s->diffuse_from && next > first &&
                    !diffuse_scaled)
                    for (int j = 0; j < nk; j++)
                        sec[j] *= DIFFUSE_COST;
                diffuse_scaled |= next == s->diffuse_from; /* once, though the pass may wait to be planned */
                /* Ahead of a pass in flight, only a full pass after a full pass (the passes'
                 * steady state): its bound comes off what is left. The growing passes and the
                 * budget's last ones wait for the log line before them, as they always did, so
                 * that the bounds the planner sizes them by are measured one pass at a time
                 * (overlapped passes do not enter k and sec: the span from one log line to the
                 * next was as short as 0.03 s for a pass traced during the tail before it). */
                if (inflight && (nk == 0 || fl[planned % 2].units != p->kmax))
                    break;
                int n = nk;
                if (inflight) {
                    double t = time_bound(k, sec, nk, p->kmax);
                    left -= t + (fl[planned % 2].hold ? 0.0 : fl[planned % 2].cov_extra);
                    k[n] = p->kmax, sec[n] = t, n++;
                }
                /* a pass at a new coverage level: its sampling, the last one's cost (measured with
                 * the gather's cheapest rate so far) times COVER_GROWTH a level finer */
                if (p->cover_plan && (cov_next = cover_level(p, next)) != INT_MIN && cov_next != INT_MAX &&
                    cov_next != cov_plan_level && cov_sg >= 0.0 && isfinite(sg_rate)) {
                    double cost = cov_sg - sg_rate * cov_units;
                    cov_extra = (cost > 0.0 ? cost : 0.0) * pow(COVER_GROWTH, (double)(cov_cost_level - cov_next));
                }
                /* A new level one finer than the last pass's that does not fit, or would take half
                 * or more of the pass it comes with: the pass keeps the samples it has (a kernel
                 * 1.4 to 2 spacings wide instead of 2 to 2.8), and the budget goes to rays and
                 * photons. Measured: the skylight room's TIME=4 ended at 2.8 to 3.0 s when a
                 * 3.2-million-sample level, foreseen at 1.1 to 2.2 s, did not fit; with the hold,
                 * at 3.9 s. */
                units = nk == 0 ? 1
                                : pm_progressive_cover_size(k, sec, n, p->kmax, left, cov_extra,
                                                            cov_plan_level != INT_MIN && cov_next == cov_plan_level - 1,
                                                            &hold);
                if (inflight && units != p->kmax) /* not room for a full pass after the one in flight */
                    break;
                if (units <= 0) {
                    if (inflight) /* the pass in flight may leave room for one more: wait for it */
                        break;
                    snprintf(stopbuf, sizeof stopbuf, "TIME=%s", val(p, PM_P_TIME));
                    stop = stopbuf;
                    stopping = 1;
                    break;
                }
            }
            if (p->cover_plan && cov_next != INT_MIN && cov_next != INT_MAX && !hold)
                cov_plan_level = cov_next;
            /* the plan lines: the full pass's size needs no word (the options say it) */
            int64_t photons = units == p->kmax ? p->photons : (p->photons * units + p->kmax / 2) / p->kmax;
            if (photons < 1)
                photons = 1;
            char l1[64], l2[64], l3[64], l4[64], l5[64];
            /* the pass's weight in the running image: its size against a full pass's (exactly 1
             * for a full pass, so that passes of one size average as they always did) */
            snprintf(l3, sizeof l3, "%d %.17g\n", next, (double)units / p->kmax);
            if (units == p->kmax) {
                snprintf(l1, sizeof l1, "%d\n", next);
                snprintf(l2, sizeof l2, "%d\n", next);
            } else {
                snprintf(l1, sizeof l1, "%d %" PRId64 "\n", next, photons);
                snprintf(l2, sizeof l2, "%d %d\n", next, units);
            }
            /* passes.txt names the pass before it is asked for: a run stopped while it is under
             * way leaves "pending", which the next run settles by running.pm's count */
            pass_t ps = {.pass = next, .photons = photons, .primary = units, .added = 1};
            for (int i = 0; i < NSTAGE; i++)
                ps.cpu_s[i] = -1.0;
            snprintf(ps.err, sizeof ps.err, "pending");
            if (add_pass(p, &ps) != 0 || write_list(p) != 0) {
                say(p, "cannot write '%s/passes.txt': %s", p->out, strerror(errno));
                rc = 3;
                break;
            }
            /* its adaptive map, from the running image as it is now (the passes logged) */
            if ((rc = adapt(p, pass, next)) != 0)
                break;
            snprintf(l4, sizeof l4, hold ? "%d 1\n" : "%d\n", next);
            /* the caustic gather's levels are not foreseen: the budget's last passes keep its
             * samples */
            int hold_cg = budget >= 0.0 && pm_progressive_hold_caustic(k, nk, p->kmax, units);
            snprintf(l5, sizeof l5, hold_cg ? "%d 1\n" : "%d\n", next);
            if (hold_cg && s->verbose)
                say(p,
                    "pass %d: the caustic gather keeps its coverage samples if they are one level coarser (the pass "
                    "is cut short by the budget: %d of %d units)",
                    next, units, p->kmax);
            double ts = pm_time_wall();
            if ((plan_sg >= 0 && write(plan_sg, l4, strlen(l4)) != (ssize_t)strlen(l4)) ||
                (plan_cg >= 0 && write(plan_cg, l5, strlen(l5)) != (ssize_t)strlen(l5)) ||
                (!inflight && write(wts, l3, strlen(l3)) != (ssize_t)strlen(l3)) ||
                (plan_tp >= 0 && write(plan_tp, l1, strlen(l1)) != (ssize_t)strlen(l1)) ||
                write(plan_tg, l2, strlen(l2)) != (ssize_t)strlen(l2)) {
                failed = next;
                break;
            }
            /* A pass planned ahead of another has its weight line held back until the log line
             * of the pass before the one in flight has been read and the maps made from the
             * image after it: composite waits for a pass's weight before it adds the pass, so
             * running.pm cannot move on under the driver's map (the map of a pass planned ahead
             * is the image's after the pass before the one in flight, exactly). */
            fl[next % 2].held_weight = inflight > 0;
            snprintf(fl[next % 2].weight, sizeof fl[next % 2].weight, "%s", l3);
            fl[next % 2].shared = inflight > 0; /* planned ahead of another pass */
            if (inflight)
                fl[planned % 2].shared = 1;
            fl[next % 2].units = units, fl[next % 2].hold = hold;
            fl[next % 2].cov_next = cov_next, fl[next % 2].cov_extra = cov_extra, fl[next % 2].ts = ts;
            planned = next;
            inflight++;
        }
        if (rc != 0 || failed || inflight == 0)
            break;
        /* the oldest pass in flight: its weight line, if held back (the maps from the image
         * before it are made) */
        if (fl[(pass + 1) % 2].held_weight) {
            const char *w = fl[(pass + 1) % 2].weight;
            if (write(wts, w, strlen(w)) != (ssize_t)strlen(w)) {
                failed = pass + 1;
                break;
            }
            fl[(pass + 1) % 2].held_weight = 0;
        }
        /* the oldest pass in flight: its log line */
        int next = pass + 1, units = fl[next % 2].units, hold = fl[next % 2].hold, cov_next = fl[next % 2].cov_next;
        double cov_extra = fl[next % 2].cov_extra, ts = fl[next % 2].ts;
        char line[256];
        uint64_t lp = 0, ln = 0;
        char err[32] = "";
        if (!fgets(line, sizeof line, logf) || sscanf(line, "%" SCNu64 " %" SCNu64 " %31s", &lp, &ln, err) != 3 ||
            lp != (uint64_t)next) {
            failed = next;
            break;
        }
        double te = pm_time_wall();
        if (*first_out < 0)
            *first_out = te - t0;
        pass_t *pp = &p->passes[p->npasses - (planned - next) - 1];
        pp->wall_s = te - (t_log > ts ? t_log : ts);
        t_log = te;
        /* each stage's CPU in the pass: since the log line before it (one pass at a time: all of
         * it lies between the plan lines and the log line, since the next pass is asked for
         * only now) */
        for (int i = 0; i < NSTAGE; i++) {
            double c1 = proc[i] ? pm_proc_cpu_s(proc[i]) : -1.0;
            pp->cpu_s[i] = c_log[i] >= 0.0 && c1 >= c_log[i] ? c1 - c_log[i] : -1.0;
            c_log[i] = c1;
        }
        snprintf(pp->err, sizeof pp->err, "%s", err);
        inflight--;
        if (next == 1 || !p->radius1[0])
            read_radius1(p);
        if (write_list(p) != 0) {
            say(p, "cannot write '%s/passes.txt': %s", p->out, strerror(errno));
            rc = 3;
            break;
        }
        /* a pass that sampled the scene at a new coverage level: the gather's CPU in it beyond
         * its cheapest rate in the passes that did not is that sampling's cost (its own thread:
         * the pass waits for it when the pass is small), for the next level's. Not the pass's
         * wall time beyond its bound: in a large pass the tracers hide most of it. */
        if (p->cover_plan && cov_next == INT_MIN)
            cov_next = cover_level(p, next);
        double sg = pp->cpu_s[SG];
        if (hold && s->verbose)
            say(p,
                "pass %d: the gather keeps its coverage samples, %.3g m apart (a new level's, about %.2g s, does not "
                "fit the budget or would take half the pass)",
                next, pm_coverage_level_spacing(cov_level), cov_extra);
        int alone = !fl[next % 2].shared; /* a shared pass's CPU span holds parts of its neighbours */
        if (!hold && p->cover_plan && cov_next != INT_MIN && cov_next != INT_MAX && cov_next != cov_level) {
            if (sg >= 0.0 && alone)
                cov_sg = sg, cov_units = units, cov_cost_level = cov_next;
            cov_level = cov_next;
            if (cov_plan_level == INT_MIN)
                cov_plan_level = cov_next;
            if (s->verbose) { /* what was set aside against what it took (the next level's foresight) */
                char fore[96] = "", took[96] = "";
                if (cov_extra > 0.0)
                    snprintf(fore, sizeof fore, " (foreseen at %.2g s)", cov_extra);
                if (sg >= 0.0 && isfinite(sg_rate))
                    snprintf(took, sizeof took, "; it took %.2g s of the gather's CPU beyond its rate",
                             sg - sg_rate * units);
                say(p, "pass %d: the gather samples the scene at a new coverage level, %.3g m apart%s%s", next,
                    pm_coverage_level_spacing(cov_next), fore, took);
            }
        } else if (sg >= 0.0 && alone && sg / units < sg_rate) {
            sg_rate = sg / units;
        }
        /* A pass that ran alone enters the bounds with its wall time. One in flight beside
         * another enters at the bound the others give it, which tightens no bound but keeps its
         * size (the largest pass so far, the caustic gather's holds); its span from one log line
         * to the next bounds nothing (a pass traced during the tail before it logged 0.03 s). A
         * pass before DIFFUSE_FROM logged after the bouncing passes' scaling is scaled too. */
        if (nk < 4096) {
            double t = fl[next % 2].shared && nk > 0 ? time_bound(k, sec, nk, units) : pp->wall_s;
            if (diffuse_scaled && next < s->diffuse_from && !(fl[next % 2].shared && nk > 0))
                t *= DIFFUSE_COST;
            k[nk] = units, sec[nk] = t, nk++;
        }
        pass = next;
        if (depth > 1)
            unadapt(p, next); /* composite has weighed the pass by its map */
        run_hook(p, env, next, te - t0);
        double e;
        if (target > 0.0 && pm_parse_double(err, &e) == PM_OK && e <= target && !stopping) {
            snprintf(stopbuf, sizeof stopbuf, "TARGET_ERROR=%s", val(p, PM_P_TARGET_ERROR));
            stop = stopbuf;
            stopping = 1;
        }
    }
    /* the map the next pass would take, as OUTDIR/adaptive.pm */
    if (rc == 0 && !failed && p->adaptive)
        rc = adapt(p, pass, 0);
    if (p->npasses && !strcmp(p->passes[p->npasses - 1].err, "pending")) { /* passes that did not land */
        /* Those never asked for go; those in flight when a failure ended the loop stay
         * "pending" (composite may still add them), for the next run to settle by running.pm's
         * count, as it settles a stopped run's. */
        while (p->npasses && !strcmp(p->passes[p->npasses - 1].err, "pending") &&
               p->passes[p->npasses - 1].pass > planned)
            p->npasses--;
        for (int j = pass + 1; j <= planned; j++)
            unadapt(p, j);
        if (write_list(p) != 0 && rc == 0)
            say(p, "cannot write '%s/passes.txt': %s", p->out, strerror(errno)), rc = 3;
    }
    /* the end of the plans ends every stage in turn */
    if (plan_tp >= 0)
        close(plan_tp);
    close(plan_tg);
    if (plan_sg >= 0)
        close(plan_sg);
    if (plan_cg >= 0)
        close(plan_cg);
    close(wts);
    if (logf) {
        char rest[256];
        while (fgets(rest, sizeof rest, logf)) /* nothing more is expected; the pipe's end is */
            ;
        fclose(logf);
    }
    signal(SIGPIPE, old_pipe);
    int first_bad = -1;
    char *errs[NSTAGE] = {0};
    int codes[NSTAGE] = {0}, sigs[NSTAGE] = {0};
    for (int i = 0; i < NSTAGE; i++) {
        if (!proc[i])
            continue;
        pm_proc_status_t st;
        if (pm_proc_wait(proc[i], &st) != PM_OK)
            st.exit_code = 4;
        codes[i] = st.exit_code;
        sigs[i] = st.signal;
        errs[i] = st.err;
        if (st.exit_code && first_bad < 0)
            first_bad = i;
    }
    if (rc == 0 && (failed || first_bad >= 0)) {
        /* the stage that failed first names the cause; the others then fail on its pipes. A
         * stage a signal other than SIGPIPE ended (killed, or crashed) is it: its neighbours
         * then fail writing to it or reading from it, some with messages of their own. Else the
         * stage that says why. */
        int killed = 0;
        for (int i = 0; i < NSTAGE; i++)
            if (sigs[i] && sigs[i] != SIGPIPE) {
                first_bad = i, killed = 1;
                break;
            }
        for (int i = 0; i < NSTAGE && !killed; i++)
            if (codes[i] && errs[i] && errs[i][0] && !strstr(errs[i], "Broken pipe") && !strstr(errs[i], "truncated") &&
                !strstr(errs[i], "has ended")) {
                first_bad = i;
                break;
            }
        if (first_bad >= 0 && errs[first_bad] && errs[first_bad][0])
            fputs(errs[first_bad], stderr);
        char how[64] = "";
        if (killed)
            snprintf(how, sizeof how, " (ended by signal %d, %s)", sigs[first_bad], strsignal(sigs[first_bad]));
        /* passes in flight when it failed stay pending (composite may have added them): the
         * next run settles them by running.pm's count */
        int pending = trailing_pending(p, p->npasses);
        char more[96] = "";
        if (pending)
            snprintf(more, sizeof more, " (and %d pending, which the next run settles)", pending);
        say(p, "pass %d failed%s%s%s; %s/image.exr and running.pm hold the %d finished passes%s", pass + 1,
            first_bad >= 0 ? " in " : "", first_bad >= 0 ? stage_names[first_bad] : "", how, p->out,
            p->npasses - pending, more);
        rc = first_bad >= 0 && codes[first_bad] == 3 ? 3 : 1;
    }
    for (int i = 0; i < NSTAGE; i++)
        free(errs[i]);
    *stop_out = stop;
    return rc;
}

int pm_render_progressive(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline, double t0)
{
    prog_t p = {.s = s, .me = me, .bin = bin, .lock_fd = -1};
    for (int i = 0; i < NSTAGE; i++)
        p.ready_s[i] = -1.0;
    /* an OUTDIR that holds pass directories (KEEP=all, pipelines/slurm's tasks) goes on with them */
    char pass1[4200];
    struct stat sb;
    snprintf(pass1, sizeof pass1, "%s/pass-0001", s->outdir);
    if (stat(pass1, &sb) == 0 && S_ISDIR(sb.st_mode))
        return -1;
    if (mkdir(s->outdir, 0777) != 0 && errno != EEXIST) {
        say(&p, "cannot create '%s': %s", s->outdir, strerror(errno));
        return 1;
    }
    char *out = realpath(s->outdir, NULL), *scene = realpath(s->scene, NULL);
    if (!out || !scene) {
        say(&p, "cannot find '%s': %s", out ? s->scene : s->outdir, strerror(errno));
        free(out), free(scene);
        return 1;
    }
    snprintf(p.out, sizeof p.out, "%s", out);
    snprintf(p.scene, sizeof p.scene, "%s", scene);
    free(out), free(scene);
    /* the scene once: its content hash (the running image's identity) and what it holds */
    /* through the cache, written on a miss only once OUTDIR is this render's (the lock, below):
     * a render the lock refuses leaves it as it was */
    pm_scene_t sc;
    char cache[PATH_MAX + 64];
    pm_scene_cache_status_t cst;
    if (pm_engine_scene_load(p.out, p.scene, cache, sizeof cache, &sc, &cst) != PM_OK) {
        say(&p, "cannot load the scene '%s': %s", s->scene, pm_error_message());
        return 1;
    }
    pm_scene_id(&sc, p.scene_id, sizeof p.scene_id);
    int specular = sc.any_specular, scene_primary = (int)sc.defaults.primary;
    p.light_samples_zero = sc.nemissive == 0 && !sc.has_sun && !sc.has_sky;
    p.secondary_direct = (s->secondary_direct || (s->secondary_direct_sky && (sc.has_sun || sc.has_sky))) &&
                         strcmp(s->value[PM_P_GATHER], "none") && pm_lights_count_at_gather(&sc);
    p.diffuse_depth = pm_diffuse_depth_for(s, specular, sc.nportals > 0);
    /* the stages, as the pass files' driver (pm_render_passes in fixed.c) chooses them */
    p.mode = s->value[PM_P_MODE];
    int vis = !strcmp(p.mode, "direct-vis"), gather = strcmp(s->value[PM_P_GATHER], "none") != 0;
    p.map = strcmp(s->value[PM_P_MAP], "auto") ? s->value[PM_P_MAP] : "global";
    p.order = strcmp(s->value[PM_P_ORDER], "auto") ? s->value[PM_P_ORDER] : vis ? "none" : "hilbert";
    if (!gather)
        p.order = "none"; /* nothing reads the queries */
    p.direct = !(vis && !strcmp(p.map, "global"));
    p.on[TP] = p.on[BM] = p.on[SG] = gather;
    p.on[CB] = p.on[CG] = gather && specular && !vis;
    p.on[TG] = p.on[CO] = 1;
    p.on[HS] = strcmp(p.order, "none") != 0;
    if (specular && !gather)
        say(&p, "warning: GATHER=none: the light mirrors and glass throw onto diffuse surfaces (caustics) is missing");
    /* Per-pass defaults (docs/accuracy.md): direct-vis has one query per primary hit, so no
     * SPP, and it takes PRIMARY and K from the scene as the pass files do. */
    int64_t v = 0;
    p.photons = pm_parse_i64(s->value[PM_P_PHOTONS][0] ? s->value[PM_P_PHOTONS] : pm_progressive_default_photons(s),
                             &v) == PM_OK
                    ? v
                    : PM_PROGRESSIVE_PHOTONS;
    p.kmax = s->value[PM_P_PRIMARY][0] && pm_parse_i64(s->value[PM_P_PRIMARY], &v) == PM_OK ? (int)v
             : vis                                                                          ? scene_primary
                                                                                            : PM_PROGRESSIVE_PRIMARY;
    p.spp = s->value[PM_P_SPP][0] ? s->value[PM_P_SPP] : vis ? "" : PM_PROGRESSIVE_SPP_TEXT;
    p.k = s->value[PM_P_K][0] ? s->value[PM_P_K] : vis ? "" : pm_progressive_default_k(s);
    /* composite weighs an adaptive pass's pixels by the map its direct buffer's header names */
    p.adaptive = s->adaptive && p.direct;
    if (s->adaptive && !p.direct && !strcmp(s->value[PM_P_ADAPTIVE], "1")) {
        say(&p, "ADAPTIVE=1 needs the direct buffer, which MODE=direct-vis over a global map has not");
        pm_scene_free(&sc);
        return 2;
    }
    make_settings(&p);
    p.cover_plan = s->coverage && p.on[SG];
    p.cover_plan_cg = s->coverage && p.on[CG];
    if (p.cover_plan)
        p.cover_finest = pm_coverage_finest_level(count_samples, &sc, PM_COVERAGE_MAX_SAMPLES);
    int locked = pm_engine_lock(p.me, p.out, p.s->wait, cmdline, &p.lock_fd);
    if (locked != 0) {
        pm_scene_free(&sc);
        return locked;
    }
    pm_engine_scene_keep(me, s->verbose, cache, &sc, &cst);
    pm_scene_free(&sc);
    char **env = stage_env(p.out);
    if (!env) {
        say(&p, "out of memory");
        close(p.lock_fd);
        return 3;
    }
    int held = read_state(&p);
    int64_t maxp = 0;
    double target = 0.0, e = 0.0;
    if (s->value[PM_P_PASSES][0])
        pm_parse_i64(s->value[PM_P_PASSES], &maxp);
    if (s->value[PM_P_TARGET_ERROR][0])
        pm_parse_double(s->value[PM_P_TARGET_ERROR], &target);
    /* more passes held than PASSES asks for: the image of PASSES passes is made anew */
    if (held && maxp && held > maxp && !s->value[PM_P_TIME][0] && !s->value[PM_P_TARGET_ERROR][0]) {
        char path[4200];
        snprintf(path, sizeof path, "%s/running.pm", p.out);
        unlink(path);
        snprintf(path, sizeof path, "%s/running.pm.weight", p.out);
        unlink(path);
        p.npasses = held = 0;
        p.radius1[0] = 0;
    }
    int no_pass = 0;
    if (held) {
        /* nothing more asked for: the same request (but for the images), PASSES met, or the
         * error reached */
        no_pass = same_passes_asked(p.request, p.old_request) || (maxp && held >= maxp) ||
                  (target > 0.0 && pm_parse_double(p.passes[held - 1].err, &e) == PM_OK && e <= target);
    }
    printf("%s: %s -> %s (MODE=%s MAP=%s ORDER=%s GATHER=%s, progressive, resident stages: PASSES=%s TIME=%s "
           "TARGET_ERROR=%s ALPHA=%s)\n",
           me, p.scene_id, p.out, p.mode, p.map, p.order, p.on[SG] ? "simd-gather" : "none",
           s->value[PM_P_PASSES][0] ? s->value[PM_P_PASSES] : "unlimited",
           s->value[PM_P_TIME][0] ? s->value[PM_P_TIME] : "none",
           s->value[PM_P_TARGET_ERROR][0] ? s->value[PM_P_TARGET_ERROR] : "none",
           s->value[PM_P_ALPHA][0] ? s->value[PM_P_ALPHA] : "2/3");
    fflush(stdout);
    const char *stop = "";
    double first_image = -1.0;
    int rc = 0;
    if (no_pass) {
        char exr[4200], png[4200];
        snprintf(exr, sizeof exr, "%s/image.exr", p.out);
        snprintf(png, sizeof png, "%s/image.png", p.out);
        stop = "nothing to add";
        /* the images as they are when the request is the same, EXPOSURE, TONE and HALF too */
        if (strcmp(p.request, p.old_request) || access(exr, F_OK) || access(png, F_OK))
            rc = retone(&p, env);
    } else if (!s->guide || (rc = make_guide(&p, env)) == 0) {
        rc = run_passes(&p, env, t0, held + 1, &stop, &first_image);
    }
    /* only now does passes.txt name the request: a run that failed or was stopped left it
     * empty, so that the same request again goes on instead of finding nothing to add */
    p.finished = rc == 0;
    if (rc == 0 && write_list(&p) != 0)
        say(&p, "cannot write '%s/passes.txt'", p.out), rc = 3;
    if (s->guide) {
        char path[4200];
        snprintf(path, sizeof path, "%s/guide-photons.pm", p.out);
        unlink(path);
    }
    free(env);
    if (p.npasses) {
        /* synced once here, not after every pass (the stages ran with PMTK_FSYNC=0) */
        sync_file(p.out, "running.pm");
        if (p.adaptive)
            sync_file(p.out, "running.pm.weight");
        sync_file(p.out, "passes.txt");
        sync_file(p.out, "image.exr");
        sync_file(p.out, "image.png");
        sync_file(p.out, ".");
    }
    double wall = pm_time_wall() - t0;
    if (rc == 0) {
        printf("  %-6s %-8s %9s %9s %9s %12s\n", "pass", "status", "photons", "primary", "wall s", "rel. error");
        for (int i = 0; i < p.npasses; i++) {
            const pass_t *ps = &p.passes[i];
            if (ps->added)
                printf("  %-6d %-8s %9" PRId64 " %9d %9.3f %12s\n", ps->pass, "added", ps->photons, ps->primary,
                       ps->wall_s, ps->err);
            else
                printf("  %-6d %-8s %9" PRId64 " %9d %9s %12s\n", ps->pass, "kept", ps->photons, ps->primary, "-",
                       ps->err);
        }
        printf("  %-34s %9.3f   (%d passes, stopped by %s)\n", "total", wall, p.npasses, stop);
        write_stats(&p, wall, first_image, stop);
        if (s->keep != PM_KEEP_ALL && !getenv("PMTK_SCENE_CACHE")) {
            char path[4200]; /* the scene cache is OUTDIR's only under KEEP=all */
            snprintf(path, sizeof path, "%s/scene.cache", p.out);
            unlink(path);
        }
        if (s->keep == PM_KEEP_IMAGE) {
            char path[4200];
            snprintf(path, sizeof path, "%s/running.pm", p.out);
            unlink(path);
            snprintf(path, sizeof path, "%s/running.pm.weight", p.out);
            unlink(path);
            snprintf(path, sizeof path, "%s/adaptive.pm", p.out);
            unlink(path);
            snprintf(path, sizeof path, "%s/passes.txt", p.out);
            unlink(path);
            printf("%s: wrote %s/image.exr, %s/image.png (%d passes), %s/stats.json (KEEP=image: the rest removed)\n",
                   me, p.out, p.out, p.npasses, p.out);
        } else {
            printf("%s: wrote %s/image.exr, %s/image.png (%d passes), %s/running.pm, %s/stats.json\n", me, p.out, p.out,
                   p.npasses, p.out, p.out);
        }
    }
    free(p.passes);
    if (p.lock_fd >= 0)
        close(p.lock_fd);
    return rc;
}
