/* fixed.c: one render (no passes) of the whole chain into OUTDIR, deciding by provenance alone
 * what to rerun (engine.h, pm_render_fixed; docs/pipelines.md, "How reuse is decided").
 *
 *   trace-photons -> build-photonmap ---------------------------\
 *   trace-gather-points -> hilbert-sort -> gather ------------> composite -> image.exr, image.png
 *                      \-> direct.pm -------------------------/
 *
 * The graph is a list of jobs in the order they run, each a stage's argv with the files it
 * reads and makes. First every file a needed job makes is read whole and judged by its header
 * (pm_prov_check); then each job runs when a file it makes is not what the settings would make,
 * or when a file it reads was remade with other bytes than the file it replaced (so a
 * trace-gather-points rerun for a moved light that gives the same queries reruns no sort). Every
 * intermediate stays in OUTDIR as the cache; OUTDIR/ran.txt, failed.txt, times/ and stats/ are
 * records of what ran, never read to decide anything. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <jansson.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/args.h"
#include "base/exr.h"
#include "base/hash.h"
#include "base/stage.h"
#include "base/timer.h"
#include "engine/engine.h"
#include "formats/formats.h"
#include "formats/pmfile.h"
#include "render/light.h"
#include "render/scene.h"
#include "render/scene_cache.h"
#include "render/summary.h"

#define MAX_JOBS 80
#define MAX_ARGS 48
#define MAX_FILES 4

typedef struct {
    char name[96];            /* its row: "trace-photons", "simd-gather.1" */
    char *argv[MAX_ARGS + 1]; /* the command, argv[0] a path; words owned by the job */
    int argc;
    const char *outs[MAX_FILES]; /* files it makes, in OUTDIR */
    int nouts;
    const char *ins[MAX_FILES]; /* files of the graph it reads */
    int nins;
    int external;              /* a gather outside the program directory: judged by being whole */
    int shard;                 /* -1, or the shard index (its --range is known once the queries are) */
    int needed;                /* made for the targets */
    int run;                   /* planned to run (phase 2) */
    int state;                 /* 0 not made, 1 cached, 2 ran, 3 failed */
    int active;                /* running now */
    double wall_s;             /* s (wall), this run or the last run's (times/NAME) */
    int have_time;             /* wall_s is known */
    pm_prov_t prov[MAX_FILES]; /* each output as found before this run */
    int changed[MAX_FILES];    /* after it ran: the output's bytes differ from what was there */
} job_t;

typedef struct {
    const pm_settings_t *s;
    const char *me; /* the name messages start with: "render" or "pm-render" */
    char bin[PATH_MAX], out[PATH_MAX], scene[PATH_MAX];
    char gather_bin[PATH_MAX], gname[64];
    int ext_gather, knn;
    pm_scene_t sc;
    char scene_all[256], scene_photons[256], scene_view[256];
    char mode[16], map[16], order[16], light_samples[32], width_k[32];
    int secondary_direct; /* SECONDARY_DIRECT on, and the scene has a light the gather points sample */
    int diffuse_depth;    /* trace-gather-points --diffuse-depth, 0 none (pm_diffuse_depth_for) */
    int need_direct, need_gather, need_caustic;
    const char *queries; /* queries.pm or sorted.pm: what the gather reads */
    const char *buffers[72];
    int nbuffers;
    job_t jobs[MAX_JOBS];
    int njobs;
    char notes[16][320];
    int nnotes;
    int progress; /* stderr is a terminal and QUIET=0: stage lines, and the stages' own bars */
    int lock_fd;
} render_t;

/* the driver's lines on stderr, "ME: ..." (pm_engine_say) */
#define say(r, ...) pm_engine_say((r)->me, __VA_ARGS__)

static void note(render_t *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note(render_t *r, const char *fmt, ...)
{
    if (r->nnotes >= 16)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->notes[r->nnotes++], sizeof r->notes[0], fmt, ap);
    va_end(ap);
}

/* ---- the jobs ---- */

static job_t *job_new(render_t *r, const char *name)
{
    job_t *j = &r->jobs[r->njobs++];
    memset(j, 0, sizeof *j);
    snprintf(j->name, sizeof j->name, "%s", name);
    j->shard = -1;
    return j;
}

static void arg(job_t *j, const char *w)
{
    if (j->argc < MAX_ARGS)
        j->argv[j->argc++] = strdup(w);
}

/* --flag VALUE when the value is set */
static void arg_opt(job_t *j, const char *flag, const char *v)
{
    if (v && v[0]) {
        arg(j, flag);
        arg(j, v);
    }
}

/* trace-gather-points' diffuse bounces, one render's and a pass's: --diffuse-depth N, and
 * --diffuse-from P from a later pass on */
static void arg_diffuse(const render_t *r, job_t *j)
{
    char v[24];
    if (!r->diffuse_depth)
        return;
    snprintf(v, sizeof v, "%d", r->diffuse_depth);
    arg(j, "--diffuse-depth");
    arg(j, v);
    if (r->s->diffuse_from > 1) {
        snprintf(v, sizeof v, "%d", r->s->diffuse_from);
        arg(j, "--diffuse-from");
        arg(j, v);
    }
}

static void arg_prog(render_t *r, job_t *j, const char *program)
{
    char p[PATH_MAX + 64];
    snprintf(p, sizeof p, "%s/%s", r->bin, program);
    arg(j, p);
}

/* -q (unless VERBOSE), --threads, --stats stats/NAME.json: change no output and are not recorded */
static void arg_common(render_t *r, job_t *j)
{
    if (!r->s->verbose)
        arg(j, "-q");
    arg_opt(j, "--threads", r->s->value[PM_P_THREADS]);
    char st[160];
    snprintf(st, sizeof st, "stats/%s.json", j->name);
    arg(j, "--stats");
    arg(j, st);
}

static void gather_opts(render_t *r, job_t *j, int widths)
{
    arg_opt(j, r->knn ? "--max-radius" : "--radius", r->s->value[PM_P_RADIUS]);
    arg_opt(j, "--k", r->s->value[PM_P_K]);
    arg_opt(j, "--kernel", r->s->value[PM_P_KERNEL]);
    arg_opt(j, "--isa", r->s->value[PM_P_ISA]);
    if (r->s->coverage && !r->knn)
        arg_opt(j, "--coverage", r->scene);
    if (widths && strcmp(r->s->value[PM_P_WIDTHS], "variable") == 0) {
        arg(j, "--widths");
        arg(j, "variable");
    }
}

/* The graph of one render, in the order its jobs run (pipelines/render's, command for command). */
static void build_graph(render_t *r)
{
    const pm_settings_t *s = r->s;
    static char shard_out[64][32];
    int N = s->shards;
    if (r->need_gather) {
        job_t *j = job_new(r, "trace-photons");
        arg_prog(r, j, "trace-photons");
        arg(j, r->scene);
        arg(j, "-o");
        arg(j, "photons.pm");
        j->outs[j->nouts++] = "photons.pm";
        if (r->need_caustic) {
            arg(j, "--caustic-output");
            arg(j, "caustic-photons.pm");
            j->outs[j->nouts++] = "caustic-photons.pm";
        }
        arg_opt(j, "--photons", s->value[PM_P_PHOTONS]);
        arg_opt(j, "--seed", s->value[PM_P_SEED]);
        if (r->secondary_direct)
            arg(j, "--indirect-only");
        if (s->guide) /* the guide reads where each photon came from */
            arg(j, "--direction");
        arg_common(r, j);

        j = job_new(r, "build-photonmap");
        arg_prog(r, j, "build-photonmap");
        arg(j, "photons.pm");
        arg(j, "-o");
        arg(j, "photonmap.pm");
        arg(j, "--map");
        arg(j, r->map);
        arg_opt(j, "--width-k", r->width_k);
        arg_common(r, j);
        j->ins[j->nins++] = "photons.pm";
        j->outs[j->nouts++] = "photonmap.pm";
        if (r->need_caustic) {
            j = job_new(r, "build-photonmap.caustic");
            arg_prog(r, j, "build-photonmap");
            arg(j, "caustic-photons.pm");
            arg(j, "-o");
            arg(j, "caustic-map.pm");
            arg(j, "--map");
            arg(j, "caustic");
            arg_common(r, j);
            j->ins[j->nins++] = "caustic-photons.pm";
            j->outs[j->nouts++] = "caustic-map.pm";
        }
    }
    job_t *j = job_new(r, "trace-gather-points");
    arg_prog(r, j, "trace-gather-points");
    arg(j, r->scene);
    arg(j, "-o");
    arg(j, "queries.pm");
    j->outs[j->nouts++] = "queries.pm";
    if (r->need_direct) {
        arg(j, "--direct");
        arg(j, "direct.pm");
        j->outs[j->nouts++] = "direct.pm";
    }
    if (r->need_caustic) {
        arg(j, "--caustic-queries");
        arg(j, "caustic-queries.pm");
        j->outs[j->nouts++] = "caustic-queries.pm";
    }
    if (s->aov & PM_EXR_AOV_SURFACE) { /* AOV: the denoiser's surfaces beside the queries */
        arg(j, "--aov");
        arg(j, "aov.pm");
        j->outs[j->nouts++] = "aov.pm";
    }
    arg(j, "--mode");
    arg(j, r->mode);
    arg_opt(j, "--spp", s->value[PM_P_SPP]);
    arg_opt(j, "--width", s->value[PM_P_WIDTH]);
    arg_opt(j, "--height", s->value[PM_P_HEIGHT]);
    arg_opt(j, "--primary", s->value[PM_P_PRIMARY]);
    arg_opt(j, "--light-samples", r->light_samples);
    arg_opt(j, "--seed", s->value[PM_P_SEED]);
    if (r->secondary_direct)
        arg(j, "--secondary-direct");
    arg_diffuse(r, j);
    if (s->guide && r->need_gather) { /* GUIDE=1: after trace-photons, from its photons */
        arg(j, "--guide");
        arg(j, "photons.pm");
        j->ins[j->nins++] = "photons.pm";
    }
    arg_common(r, j);
    if (strcmp(r->order, "none") != 0) {
        j = job_new(r, "hilbert-sort");
        arg_prog(r, j, "hilbert-sort");
        arg(j, "queries.pm");
        arg(j, "-o");
        arg(j, "sorted.pm");
        arg(j, "--order");
        arg(j, r->order);
        arg_opt(j, "--leaf", s->value[PM_P_LEAF]);
        arg_common(r, j);
        j->ins[j->nins++] = "queries.pm";
        j->outs[j->nouts++] = "sorted.pm";
    }
    if (r->need_direct)
        r->buffers[r->nbuffers++] = "direct.pm";
    if (r->need_gather) {
        for (int i = 0; i < N && i < 64; i++) {
            char name[96];
            if (N == 1)
                snprintf(name, sizeof name, "%s", r->gname);
            else
                snprintf(name, sizeof name, "%s.%d", r->gname, i);
            if (N == 1)
                snprintf(shard_out[i], sizeof shard_out[i], "indirect.pm");
            else
                snprintf(shard_out[i], sizeof shard_out[i], "indirect.%d.pm", i);
            j = job_new(r, name);
            arg(j, r->gather_bin);
            arg(j, "photonmap.pm");
            arg(j, r->queries);
            arg(j, "-o");
            arg(j, shard_out[i]);
            if (N > 1) {
                j->shard = i;
                arg(j, "--range");
                arg(j, "0:0"); /* set when the queries' count is known (set_ranges) */
            }
            gather_opts(r, j, 1);
            arg_common(r, j);
            j->external = r->ext_gather;
            j->ins[j->nins++] = "photonmap.pm";
            j->ins[j->nins++] = r->queries;
            j->outs[j->nouts++] = shard_out[i];
            r->buffers[r->nbuffers++] = shard_out[i];
        }
    }
    if (r->need_caustic) {
        j = job_new(r, "simd-gather.caustic");
        arg(j, r->gather_bin);
        arg(j, "caustic-map.pm");
        arg(j, "caustic-queries.pm");
        arg(j, "-o");
        arg(j, "caustic.pm");
        gather_opts(r, j, 0);
        arg_common(r, j);
        j->external = r->ext_gather;
        j->ins[j->nins++] = "caustic-map.pm";
        j->ins[j->nins++] = "caustic-queries.pm";
        j->outs[j->nouts++] = "caustic.pm";
        r->buffers[r->nbuffers++] = "caustic.pm";
    }
    j = job_new(r, "composite");
    arg_prog(r, j, "composite");
    for (int i = 0; i < r->nbuffers; i++)
        arg(j, r->buffers[i]);
    arg(j, "-o");
    arg(j, "image.exr");
    arg(j, "--png");
    arg(j, "image.png");
    arg(j, "--exposure");
    arg(j, s->value[PM_P_EXPOSURE]);
    arg(j, "--tone");
    arg(j, s->value[PM_P_TONE]);
    if (strcmp(s->value[PM_P_HALF], "1") == 0)
        arg(j, "--half");
    if (s->aov) {
        arg(j, "--aov");
        arg(j, s->value[PM_P_AOV]);
        arg(j, "--aov-buffer");
        arg(j, "aov.pm");
        j->ins[j->nins++] = "aov.pm";
    }
    arg_common(r, j);
    j->outs[j->nouts++] = "image.exr";
    j->outs[j->nouts++] = "image.png";
}

static job_t *producer(render_t *r, const char *file)
{
    for (int i = 0; i < r->njobs; i++)
        for (int k = 0; k < r->jobs[i].nouts; k++)
            if (strcmp(r->jobs[i].outs[k], file) == 0)
                return &r->jobs[i];
    return NULL;
}

static void need(render_t *r, job_t *j)
{
    if (j->needed)
        return;
    j->needed = 1;
    if (strcmp(j->name, "composite") == 0) {
        for (int i = 0; i < r->nbuffers; i++) {
            job_t *p = producer(r, r->buffers[i]);
            if (p)
                need(r, p);
        }
        for (int i = 0; i < j->nins; i++) { /* aov.pm, with AOV */
            job_t *p = producer(r, j->ins[i]);
            if (p)
                need(r, p);
        }
        return;
    }
    for (int i = 0; i < j->nins; i++) {
        job_t *p = producer(r, j->ins[i]);
        if (p)
            need(r, p);
    }
}

/* The records in a pmtk file by its header alone; 0 and PM_ERR_* when it cannot be read. */
static pm_result_t count_records(const render_t *r, const char *name, uint64_t *n_out)
{
    char p[PATH_MAX + 64];
    snprintf(p, sizeof p, "%s/%s", r->out, name);
    pm_reader_t *rd;
    pm_result_t res = pm_reader_open(p, NULL, 0, &rd);
    if (res != PM_OK)
        return res;
    *n_out = pm_reader_header(rd)->count;
    pm_reader_close(rd);
    return PM_OK;
}

/* Each shard's --range from the queries' count n: [i n / N, (i + 1) n / N). */
static void set_range(render_t *r, job_t *j, uint64_t n)
{
    uint64_t N = (uint64_t)r->s->shards, i = (uint64_t)j->shard;
    char range[64];
    snprintf(range, sizeof range, "%" PRIu64 ":%" PRIu64, n * i / N, n * (i + 1) / N);
    for (int k = 0; k < j->argc; k++)
        if (strcmp(j->argv[k], "--range") == 0) {
            free(j->argv[k + 1]);
            j->argv[k + 1] = strdup(range);
        }
}

/* ---- provenance of the images: composite records its command and each buffer's content hash
 * in the EXR's attributes (COMMAND.N, INPUT.N); the PNG has no room for them, and counts as
 * made with the EXR when it is a whole PNG of the same size. ---- */

static uint32_t crc_table[256];
static uint32_t png_crc(const unsigned char *p, size_t n, uint32_t c)
{
    if (!crc_table[1])
        for (uint32_t i = 0; i < 256; i++) {
            uint32_t v = i;
            for (int k = 0; k < 8; k++)
                v = v & 1 ? 0xedb88320u ^ (v >> 1) : v >> 1;
            crc_table[i] = v;
        }
    for (size_t i = 0; i < n; i++)
        c = crc_table[(c ^ p[i]) & 0xff] ^ (c >> 8);
    return c;
}

static uint32_t be32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* 1 when path is a whole PNG (signature, every chunk's CRC, IEND last) of w x h pixels. */
static int png_whole(const char *path, uint32_t w, uint32_t h, char *why, size_t cap)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(why, cap, "missing");
        return 0;
    }
    unsigned char sig[8], hd[8];
    int ok = fread(sig, 1, 8, f) == 8 && memcmp(sig, "\x89PNG\r\n\x1a\n", 8) == 0, end = 0, first = 1;
    unsigned char *buf = NULL;
    while (ok && !end && fread(hd, 1, 8, f) == 8) {
        uint32_t len = be32(hd);
        if (len > (1u << 28)) {
            ok = 0;
            break;
        }
        unsigned char *nb = realloc(buf, len + 4u);
        if (!nb) {
            ok = 0;
            break;
        }
        buf = nb;
        if (fread(buf, 1, len + 4u, f) != len + 4u) {
            ok = 0;
            break;
        }
        uint32_t c = png_crc(hd + 4, 4, 0xffffffffu);
        c = png_crc(buf, len, c) ^ 0xffffffffu;
        if (c != be32(buf + len)) {
            ok = 0;
            break;
        }
        if (first && (memcmp(hd + 4, "IHDR", 4) != 0 || len < 8 || be32(buf) != w || be32(buf + 4) != h)) {
            ok = 0;
            break;
        }
        first = 0;
        end = memcmp(hd + 4, "IEND", 4) == 0;
    }
    ok = ok && end && fgetc(f) == EOF;
    free(buf);
    fclose(f);
    if (!ok)
        snprintf(why, cap, "not a whole PNG of the image's size");
    return ok;
}

static void image_check(render_t *r, job_t *j, const char *want_cmd)
{
    char exr[PATH_MAX + 64], png[PATH_MAX + 64];
    snprintf(exr, sizeof exr, "%s/image.exr", r->out);
    snprintf(png, sizeof png, "%s/image.png", r->out);
    pm_prov_t *pe = &j->prov[0], *pp = &j->prov[1];
    struct stat sb;
    pe->verdict = stat(exr, &sb) == 0 ? PM_PROV_OK : PM_PROV_MISSING;
    pp->verdict = stat(png, &sb) == 0 ? PM_PROV_OK : PM_PROV_MISSING;
    if (pe->verdict != PM_PROV_OK || pp->verdict != PM_PROV_OK)
        return;
    uint32_t w, h;
    float *rgb = NULL;
    if (pm_exr_read_rgb(exr, &w, &h, &rgb) != PM_OK) {
        pe->verdict = PM_PROV_CORRUPT;
        snprintf(pe->why, sizeof pe->why, "%s", pm_error_message());
        return;
    }
    free(rgb);
    if (!png_whole(png, w, h, pp->why, sizeof pp->why)) {
        pp->verdict = PM_PROV_CORRUPT;
        return;
    }
    char *last = NULL;
    for (int i = 0;; i++) {
        char key[32], *v;
        snprintf(key, sizeof key, "COMMAND.%d", i);
        if (pm_exr_read_string_attr(exr, key, &v) != PM_OK)
            break;
        free(last);
        last = v;
    }
    if (!last || strcmp(last, want_cmd) != 0) {
        pe->verdict = PM_PROV_OTHER;
        snprintf(pe->why, sizeof pe->why, "command '%.400s'", last ? last : "");
        free(last);
        return;
    }
    free(last);
    int ninputs = 0;
    for (int i = 0;; i++) {
        char key[32], *v;
        snprintf(key, sizeof key, "INPUT.%d", i);
        if (pm_exr_read_string_attr(exr, key, &v) != PM_OK)
            break;
        ninputs++;
        char *sp = strrchr(v, ' ');
        uint64_t want = 0, now = 0;
        char in[PATH_MAX + 64];
        int same = 0;
        if (sp && sscanf(sp + 1, "xxh3:%" SCNx64, &want) == 1) {
            snprintf(in, sizeof in, "%s/%.*s", r->out, (int)(sp - v), v);
            same = pm_prov_trailer(in, &now) == PM_OK && now == want;
        }
        if (!same) {
            pe->verdict = PM_PROV_OTHER;
            snprintf(pe->why, sizeof pe->why, "input '%.*s' has changed", sp ? (int)(sp - v) : 0, v);
            free(v);
            return;
        }
        free(v);
    }
    if (ninputs != r->nbuffers) {
        pe->verdict = PM_PROV_OTHER;
        snprintf(pe->why, sizeof pe->why, "%d inputs", ninputs);
    }
}

/* The scene part each file records (docs/formats.md, "The parts of SCENE"): the photon side
 * the photons', the queries the view's, the buffers both. */
static const char *scene_of(const render_t *r, const char *file)
{
    if (!strcmp(file, "photons.pm") || !strcmp(file, "photonmap.pm") || !strcmp(file, "caustic-photons.pm") ||
        !strcmp(file, "caustic-map.pm"))
        return r->scene_photons;
    if (!strcmp(file, "queries.pm") || !strcmp(file, "sorted.pm") || !strcmp(file, "caustic-queries.pm"))
        return r->scene_view;
    return r->scene_all;
}

static double read_time(const render_t *r, const char *name, int *ok)
{
    char p[PATH_MAX + 160];
    snprintf(p, sizeof p, "%s/times/%s", r->out, name);
    FILE *f = fopen(p, "r");
    double t = 0;
    *ok = f && fscanf(f, "%lf", &t) == 1 && t >= 0 && t < 1e9;
    if (f)
        fclose(f);
    return *ok ? t : 0;
}

/* Judges every output of j (phase 1). Returns PM_OK or out of memory. */
static pm_result_t check_job(render_t *r, job_t *j)
{
    char *cmd = NULL;
    pm_result_t res = pm_prov_command_line(j->argc, j->argv, &cmd);
    if (res != PM_OK)
        return res;
    if (strcmp(j->name, "composite") == 0) {
        image_check(r, j, cmd);
    } else {
        for (int k = 0; k < j->nouts; k++) {
            const char *cmds[1] = {cmd};
            pm_prov_want_t w = {.dir = r->out,
                                .name = j->outs[k],
                                .commands = cmds,
                                .ncommands = 1,
                                .scene = scene_of(r, j->outs[k]),
                                .external = j->external,
                                .scene_arg =
                                    !strcmp(j->name, "trace-photons") || !strcmp(j->name, "trace-gather-points")};
            res = pm_prov_check(&w, &j->prov[k]);
            if (res != PM_OK)
                break;
        }
    }
    free(cmd);
    for (int k = 0; k < j->nouts && res == PM_OK; k++) {
        const pm_prov_t *p = &j->prov[k];
        int before;
        if (p->verdict == PM_PROV_CORRUPT)
            say(r, "%s is corrupt (%s): rebuilding it", j->outs[k], p->why);
        else if (p->verdict == PM_PROV_MISSING && (read_time(r, j->name, &before), before))
            /* made here before (its stage's time is on record) and gone since: said, as a
             * corrupt file is, so that a file removed by hand is seen to come back */
            say(r, "%s is missing: remaking it", j->outs[k]);
        else if (p->verdict == PM_PROV_OTHER && r->s->verbose)
            say(r, "%s was made otherwise (%s): remaking it", j->outs[k], p->why);
    }
    return res;
}

static int job_outputs_ok(const job_t *j)
{
    for (int k = 0; k < j->nouts; k++)
        if (j->prov[k].verdict != PM_PROV_OK)
            return 0;
    return 1;
}

/* The files job j reads: its own list, or for composite the buffers this render adds. */
static const char *const *job_inputs(const render_t *r, const job_t *j, int *n_out)
{
    if (strcmp(j->name, "composite") == 0) {
        *n_out = r->nbuffers;
        return r->buffers;
    }
    *n_out = j->nins;
    return j->ins;
}

/* An input of j was remade in this run with other bytes than it had. */
static int input_changed(render_t *r, const job_t *j)
{
    int nins;
    const char *const *ins = job_inputs(r, j, &nins);
    for (int i = 0; i < nins; i++) {
        job_t *p = producer(r, ins[i]);
        if (!p)
            continue;
        for (int k = 0; k < p->nouts; k++)
            if (strcmp(p->outs[k], ins[i]) == 0 && p->changed[k])
                return 1;
    }
    return 0;
}

/* Every stage that makes an input of j has ended (or is not part of this render). */
static int inputs_ready(render_t *r, const job_t *j)
{
    int nins;
    const char *const *ins = job_inputs(r, j, &nins);
    for (int i = 0; i < nins; i++) {
        job_t *p = producer(r, ins[i]);
        if (p && p->needed && (p->state == 0 || p->active))
            return 0;
    }
    return 1;
}

/* After a failure: every stage that makes an input of j is cached or ran (none failed or was
 * left unmade), so what j made is current. */
static int inputs_settled(render_t *r, const job_t *j)
{
    int nins;
    const char *const *ins = job_inputs(r, j, &nins);
    for (int i = 0; i < nins; i++) {
        job_t *p = producer(r, ins[i]);
        if (p && p->needed && p->state != 1 && p->state != 2)
            return 0;
    }
    return 1;
}

/* Would j run if what came before it ran as planned (phase 2, for the progress count)? */
static int input_planned(render_t *r, const job_t *j)
{
    int nins;
    const char *const *ins = job_inputs(r, j, &nins);
    for (int i = 0; i < nins; i++) {
        job_t *p = producer(r, ins[i]);
        if (p && p->run)
            return 1;
    }
    return 0;
}

static void append_line(const render_t *r, const char *file, const char *line)
{
    char p[PATH_MAX + 64];
    snprintf(p, sizeof p, "%s/%s", r->out, file);
    FILE *f = fopen(p, "a");
    if (f) {
        fprintf(f, "%s\n", line);
        fclose(f);
    }
}

/* Starts j in OUTDIR (phase 3): *proc_out is the running stage. Returns 0, or the exit status
 * when it cannot be started. */
static int start_job(render_t *r, job_t *j, int index, int total, pm_proc_t **proc_out)
{
    char *argv[MAX_ARGS + 1];
    int n = 0;
    for (int k = 0; k < j->argc; k++) {
        if (r->progress && strcmp(j->argv[k], "-q") == 0)
            continue; /* on a terminal each stage draws its own progress line */
        argv[n++] = j->argv[k];
    }
    argv[n] = NULL;
    if (r->progress) {
        double left = 0;
        int known = 1;
        for (int i = 0; i < r->njobs; i++) {
            job_t *o = &r->jobs[i];
            if (!o->run || o->state != 0 || o->active)
                continue;
            int ok;
            left += read_time(r, o->name, &ok);
            known = known && ok;
        }
        if (known)
            say(r, "stage %d of %d: %s (about %.1f s left, by the last run)", index, total, j->name, left);
        else
            say(r, "stage %d of %d: %s (time left not known yet (no earlier run of every stage here))", index, total,
                j->name);
    }
    if (r->s->verbose) {
        fputs("+", stderr);
        for (int k = 0; k < n; k++)
            fprintf(stderr, " %s", argv[k]);
        fputc('\n', stderr);
    }
    pm_spawn_t sp = {.argv = argv, .cwd = r->out, .stdin_fd = -1, .stdout_fd = -1};
    if (pm_proc_spawn(&sp, proc_out) != PM_OK) {
        say(r, "%s", pm_error_message());
        say(r, "stage %s failed (exit %d)", j->name, 3);
        append_line(r, "failed.txt", j->name);
        j->state = 3;
        return 3;
    }
    j->active = 1;
    return 0;
}

/* j has ended as st says: its records, and its outputs' change flags from their content hashes.
 * Returns its exit status. */
static int finish_job(render_t *r, job_t *j, const pm_proc_status_t *st)
{
    j->active = 0;
    if (st->exit_code != 0) {
        /* what a failed stage leaves is not what the settings make: removed, as make's
         * .DELETE_ON_ERROR did (the stages themselves write through temporary files) */
        for (int k = 0; k < j->nouts; k++) {
            char op[PATH_MAX + 64];
            snprintf(op, sizeof op, "%s/%s", r->out, j->outs[k]);
            unlink(op);
        }
        say(r, "stage %s failed (exit %d)", j->name, st->exit_code);
        append_line(r, "failed.txt", j->name);
        j->state = 3;
        return st->exit_code;
    }
    j->state = 2;
    j->wall_s = st->wall_s;
    j->have_time = 1;
    char p[PATH_MAX + 160];
    snprintf(p, sizeof p, "%s/times", r->out);
    mkdir(p, 0777);
    snprintf(p, sizeof p, "%s/times/%s", r->out, j->name);
    FILE *f = fopen(p, "w");
    if (f) {
        fprintf(f, "%.6f\n", st->wall_s);
        fclose(f);
    }
    append_line(r, "ran.txt", j->name);
    for (int k = 0; k < j->nouts; k++) {
        char op[PATH_MAX + 64];
        snprintf(op, sizeof op, "%s/%s", r->out, j->outs[k]);
        uint64_t h;
        j->changed[k] = 1;
        if (j->prov[k].verdict == PM_PROV_OK && pm_prov_trailer(op, &h) == PM_OK && h == j->prov[k].hash)
            j->changed[k] = 0; /* the same bytes as the file it replaced: what reads it stays */
    }
    return 0;
}

/* ---- the table and stats.json ---- */

/* OUTDIR/stats.json, whole or not at all: {"scene", "params", KEY: items, "total": tot}
 * (items and tot are taken over). */
static void stats_write(render_t *r, const pm_settings_t *s, const char *key, json_t *items, json_t *tot)
{
    json_t *params = json_object(), *root = json_object();
    for (int p = 0; p < PM_P_COUNT; p++)
        json_object_set_new(params, pm_param_name((pm_param_t)p), json_string(s->value[p]));
    json_object_set_new(root, "scene", json_string(r->scene_all));
    json_object_set_new(root, "params", params);
    json_object_set_new(root, key, items);
    json_object_set_new(root, "total", tot);
    char tmp[PATH_MAX + 64], dst[PATH_MAX + 64];
    snprintf(tmp, sizeof tmp, "%s/.stats.json.tmp", r->out);
    snprintf(dst, sizeof dst, "%s/stats.json", r->out);
    if (json_dump_file(root, tmp, JSON_SORT_KEYS | JSON_INDENT(1)) != 0 || rename(tmp, dst) != 0) {
        unlink(tmp);
        say(r, "could not write '%s'", dst);
    }
    json_decref(root);
}

static void report(render_t *r, double run_s)
{
    int sw = r->need_caustic ? 24 : 22;
    printf("  %-*s %-8s %9s\n", sw, "stage", "status", "wall s");
    double total = 0;
    json_t *stages = json_object(), *ran = json_array();
    double wall = 0, cpu = 0;
    for (int i = 0; i < r->njobs; i++) {
        job_t *j = &r->jobs[i];
        const char *status = j->state == 2 ? "ran" : j->state == 3 ? "failed" : j->state == 1 ? "cached" : "not made";
        if (j->state == 1 && !j->have_time) {
            int ok;
            j->wall_s = read_time(r, j->name, &ok);
            j->have_time = ok;
        }
        int show = (j->state == 1 || j->state == 2) && j->have_time;
        if (show)
            total += j->wall_s;
        char t[32] = "-";
        if (show)
            snprintf(t, sizeof t, "%.3f", j->wall_s);
        printf("  %-*s %-8s %9s\n", sw, j->name, status, t);
        if (j->state == 2)
            json_array_append_new(ran, json_string(j->name));
        char sp[PATH_MAX + 160];
        snprintf(sp, sizeof sp, "%s/stats/%s.json", r->out, j->name);
        json_t *st = NULL;
        pm_proc_stats_load(sp, &st);
        if (st) {
            json_t *o = json_object();
            json_object_set_new(o, "status", json_string(status));
            json_object_set_new(o, "pipeline_wall_s", show ? json_real(j->wall_s) : json_null());
            json_t *w = json_object_get(st, "wall_s"), *c = json_object_get(st, "cpu_s");
            wall += json_is_number(w) ? json_number_value(w) : 0;
            cpu += json_is_number(c) ? json_number_value(c) : 0;
            json_object_set_new(o, "stats", st);
            json_object_set_new(stages, j->name, o);
        }
    }
    printf("  %-*s %-8s %9.3f   (this run: %.3f s)\n", sw, "total of the stages", "", total, run_s);
    fflush(stdout);
    json_t *tot = json_object();
    json_object_set_new(tot, "pipeline_wall_s", json_real(total));
    json_object_set_new(tot, "wall_s", json_real(wall));
    json_object_set_new(tot, "cpu_s", json_real(cpu));
    json_object_set_new(tot, "this_run_s", json_real(run_s));
    json_object_set_new(tot, "ran", ran);
    stats_write(r, r->s, "stages", stages, tot);
}

/* ---- KEEP: what OUTDIR keeps after a render that succeeded (only files render makes, by name) ---- */

/* Removes path: a file, or a directory and all it holds. */
static void remove_tree(const char *path)
{
    struct stat sb;
    if (lstat(path, &sb) != 0)
        return;
    if (!S_ISDIR(sb.st_mode)) {
        unlink(path);
        return;
    }
    DIR *d = opendir(path);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            char p[PATH_MAX + 300];
            snprintf(p, sizeof p, "%s/%s", path, e->d_name);
            remove_tree(p);
        }
        closedir(d);
    }
    rmdir(path);
}

static void keep_only(render_t *r)
{
    if (r->s->keep == PM_KEEP_ALL)
        return;
    static const char *const made[] = {"photons.pm", "photonmap.pm", "caustic-photons.pm", "caustic-map.pm",
                                       "queries.pm", "sorted.pm", "caustic-queries.pm", "direct.pm", "indirect.pm",
                                       "caustic.pm", "ran.txt", "failed.txt", "scene.cache",
                                       /* what the make graph that pipelines/render was left here */
                                       "Makefile", "scene-info.json", "scene-info.err", NULL};
    char p[PATH_MAX + 64];
    for (int i = 0; made[i]; i++) {
        int keep = 0;
        for (int b = 0; b < r->nbuffers && r->s->keep == PM_KEEP_BUFFERS; b++)
            keep |= !strcmp(r->buffers[b], made[i]);
        if (keep)
            continue;
        snprintf(p, sizeof p, "%s/%s", r->out, made[i]);
        unlink(p);
    }
    for (int i = 0; i < 64; i++) {
        char name[32];
        snprintf(name, sizeof name, "indirect.%d.pm", i);
        int keep = 0;
        for (int b = 0; b < r->nbuffers && r->s->keep == PM_KEEP_BUFFERS; b++)
            keep |= !strcmp(r->buffers[b], name);
        if (!keep) {
            snprintf(p, sizeof p, "%s/%s", r->out, name);
            unlink(p);
        }
    }
    snprintf(p, sizeof p, "%s/times", r->out);
    remove_tree(p);
    snprintf(p, sizeof p, "%s/stats", r->out);
    remove_tree(p);
    snprintf(p, sizeof p, "%s/.stamps", r->out);
    remove_tree(p);
}

/* ---- the whole render ---- */

/* The lights that need direct-light samples at each primary hit: emissive triangles, a sun, a
 * sky (point lights are sampled exactly, one shadow ray each). One question, asked in one place:
 * when branch light lands, this is pm_lights_count's sampled_out (render/light.h), and the
 * "no lights" note its total_out. */
/* Lights whose direct light takes LIGHT_SAMPLES samples, and all lights, asked of the light
 * module without naming a kind (render/light.h), so that a new kind of light gets its samples. */
static size_t sampled_lights(const pm_scene_t *sc, size_t *total_out)
{
    size_t total = 0, sampled = 0;
    pm_lights_count(sc, &total, &sampled);
    *total_out = total;
    return sampled;
}

/* The decisions pipelines/render made from the scene and the parameters, and the notes it
 * printed for them (docs/pipelines.md, "What it leaves out"). PM_ERR_USAGE for a combination
 * that leaves nothing to render. */
static pm_result_t decide(render_t *r)
{
    const pm_settings_t *s = r->s;
    snprintf(r->mode, sizeof r->mode, "%s", s->value[PM_P_MODE]);
    snprintf(r->map, sizeof r->map, "%s", strcmp(s->value[PM_P_MAP], "auto") ? s->value[PM_P_MAP] : "global");
    int gathermode = strcmp(r->mode, "gather") == 0;
    if (gathermode && strcmp(r->map, "indirect") == 0)
        return pm_error_set(PM_ERR_USAGE, "MAP=indirect with MODE=gather: the gather asks the map for all light at "
                                          "secondary hits, so it needs the first-hit photons (MAP=global)");
    snprintf(r->order, sizeof r->order, "%s", s->value[PM_P_ORDER]);
    if (strcmp(r->order, "auto") == 0) {
        if (!gathermode) {
            snprintf(r->order, sizeof r->order, "none");
            note(r, "skipped hilbert-sort: direct-vis queries are one per pixel in scanline order, already coherent "
                    "(ORDER=hilbert sorts them anyway)");
        } else {
            snprintf(r->order, sizeof r->order, "hilbert");
        }
    } else if (strcmp(r->order, "none") == 0) {
        note(r, "skipped hilbert-sort: ORDER=none (the gather reads the queries in pixel order)");
    }
    const char *g = s->value[PM_P_GATHER];
    if (strcmp(g, "none") == 0)
        snprintf(r->order, sizeof r->order, "none"); /* nothing reads the queries */
    r->need_direct = 1;
    if (!gathermode && strcmp(r->map, "global") == 0) {
        r->need_direct = 0;
        note(r, "skipped the direct buffer: direct-vis over a global map shows the map's own estimate of direct light "
                "(emitters look black; MAP=indirect adds shadow-ray direct light)");
    }
    r->need_gather = 1;
    if (strcmp(g, "none") == 0) {
        r->need_gather = 0;
        note(r, "skipped trace-photons, build-photonmap, hilbert-sort and the gather: GATHER=none, the image is the "
                "direct light alone");
        if (!r->need_direct)
            return pm_error_set(PM_ERR_USAGE,
                                "GATHER=none with MODE=direct-vis and MAP=global leaves nothing to composite");
    }
    r->queries = strcmp(r->order, "none") ? "sorted.pm" : "queries.pm";
    return PM_OK;
}

/* What the loaded scene changes: the caustic branch, light sampling, and the notes. */
static void decide_scene(render_t *r)
{
    const pm_scene_t *sc = &r->sc;
    int gathermode = strcmp(r->mode, "gather") == 0;
    r->need_caustic = 0;
    if (sc->any_specular && gathermode && r->need_gather)
        r->need_caustic = 1;
    else if (sc->any_specular && !gathermode && r->need_gather)
        note(r, "no caustic branch: direct-vis queries gather the caustic photons from the global map already");
    else if (sc->any_specular)
        note(r, "warning: GATHER=none: the light mirrors and glass throw onto diffuse surfaces (caustics) is missing");
    if (!sc->any_glossy)
        note(r, "left out direction channels: every material is Lambertian (the stages decide this themselves)");
    if (!pm_scene_needs(sc).material_ids)
        note(r, "left out the material channel: %s",
             !sc->any_glossy ? "a Lambertian query carries its BRDF in its weight" : "one material");
    snprintf(r->light_samples, sizeof r->light_samples, "%s", r->s->value[PM_P_LIGHT_SAMPLES]);
    size_t lights_total = 0;
    if (sampled_lights(sc, &lights_total) == 0) {
        snprintf(r->light_samples, sizeof r->light_samples, "0");
        note(r, "skipped area-light sampling: no emissive triangles, sun or sky (%zu point lights)", lights_total);
        if (lights_total == 0)
            note(r, "warning: the scene has no lights; the image is black");
    }
    r->secondary_direct = (r->s->secondary_direct || (r->s->secondary_direct_sky && (sc->has_sun || sc->has_sky))) &&
                          r->need_gather && pm_lights_count_at_gather(sc) > 0;
    r->diffuse_depth = pm_diffuse_depth_for(r->s, sc->any_specular, sc->nportals > 0);
    if (r->s->secondary_direct && r->need_gather && !r->secondary_direct)
        note(r, "skipped secondary direct light: the scene has no lights");
    r->width_k[0] = '\0';
    if (strcmp(r->s->value[PM_P_WIDTHS], "variable") == 0)
        snprintf(r->width_k, sizeof r->width_k, "%s",
                 r->s->value[PM_P_WIDTH_K][0] ? r->s->value[PM_P_WIDTH_K]
                 : r->s->value[PM_P_K][0]     ? r->s->value[PM_P_K]
                                              : "50");
}

/* The gather's program: a name in the program directory, or a path (which stands in for
 * simd-gather, under that name, unless it is in the program directory). */
static pm_result_t find_gather(render_t *r)
{
    const char *g = r->s->value[PM_P_GATHER];
    if (strchr(g, '/'))
        snprintf(r->gather_bin, sizeof r->gather_bin, "%s", g);
    else
        snprintf(r->gather_bin, sizeof r->gather_bin, "%s/%s", r->bin, g);
    const char *base = strrchr(g, '/');
    snprintf(r->gname, sizeof r->gname, "%s", base ? base + 1 : g);
    r->ext_gather = 0;
    if (strchr(g, '/')) {
        char *dir = strdup(g), *slash = strrchr(dir, '/');
        *slash = '\0';
        char *real = realpath(dir[0] ? dir : "/", NULL);
        if (!real || strcmp(real, r->bin) != 0) {
            snprintf(r->gname, sizeof r->gname, "simd-gather");
            r->ext_gather = 1;
        }
        free(real);
        free(dir);
    }
    r->knn = strcmp(r->gname, "knn-gather") == 0;
    if (!r->need_gather)
        return PM_OK;
    struct stat sb;
    if (stat(r->gather_bin, &sb) != 0 || !S_ISREG(sb.st_mode) || access(r->gather_bin, X_OK) != 0)
        return pm_error_set(PM_ERR_INPUT,
                            "the gather program '%s' is not an executable file (GATHER=none renders the direct light "
                            "alone)",
                            r->gather_bin);
    return PM_OK;
}

/* The exit status for a stage's: its class passed through (docs/cli.md): 1 input, 2 usage (a
 * value given that the stage refuses only once it runs, LEAF=x say), 3 I/O or out of memory,
 * 4 internal; a signal is the system's (3), which a retry may cure. */
static int stage_status(int code)
{
    switch (pm_proc_class(code)) {
    case PM_ERR_INPUT: return 1;
    case PM_ERR_USAGE: return 2;
    case PM_ERR_INTERNAL: return 4;
    default: return 3;
    }
}

static int mkdir_p(const char *path)
{
    char p[PATH_MAX];
    snprintf(p, sizeof p, "%s", path);
    for (char *s = p + 1; *s; s++)
        if (*s == '/') {
            *s = '\0';
            if (mkdir(p, 0777) != 0 && errno != EEXIST)
                return -1;
            *s = '/';
        }
    return mkdir(p, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

/* What one render and a render of pass files share before any graph: the scene by its absolute
 * path, the decisions and their notes, the programs, the scene loaded, OUTDIR made and locked,
 * its records started, the scene's warnings said. Returns 0, or the exit status (what it took is
 * undone by render_end). */
static int render_begin(render_t *r, const pm_settings_t *s, const char *me, const char *bin, const char *cmdline)
{
    memset(r, 0, sizeof *r);
    r->s = s;
    r->me = me;
    r->lock_fd = -1;
    snprintf(r->bin, sizeof r->bin, "%s", bin);
    int status = 0;
    pm_result_t res;
    /* the scene by its absolute path, so that the stages, run in OUTDIR, find it */
    {
        char dir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s", s->scene);
        char *slash = strrchr(dir, '/');
        const char *base = slash ? slash + 1 : s->scene;
        if (slash)
            *slash = '\0';
        char *real = realpath(slash ? (dir[0] ? dir : "/") : ".", NULL);
        if (!real) {
            say(r, "cannot read scene '%s'", s->scene);
            return 1;
        }
        snprintf(r->scene, sizeof r->scene, "%s%s%s", real, strcmp(real, "/") ? "/" : "", base);
        free(real);
    }
    if ((res = decide(r)) != PM_OK || (res = find_gather(r)) != PM_OK) {
        say(r, "%s", pm_error_message());
        return res == PM_ERR_USAGE ? 2 : 1;
    }
    static const char *const progs[] = {"trace-photons", "build-photonmap", "trace-gather-points",
                                        "hilbert-sort",  "composite",       NULL};
    for (int i = 0; progs[i]; i++) {
        char p[PATH_MAX + 64];
        snprintf(p, sizeof p, "%s/%s", r->bin, progs[i]);
        if (access(p, X_OK) != 0) {
            say(r, "'%s' is not built (make)", p);
            return 1;
        }
    }
    /* The scene through the library (scene-info's engine): what it holds and needs, its
     * content hash in parts, its warnings once per render. */
    /* through the scene cache (render/scene_cache.h): a rerun reads it in milliseconds; a miss
     * is written once the lock below is this render's */
    char cache[PATH_MAX + 64] = "";
    pm_scene_cache_status_t cst;
    if ((res = pm_engine_scene_load(s->outdir, r->scene, cache, sizeof cache, &r->sc, &cst)) != PM_OK) {
        say(r, "cannot load scene '%s': %s", s->scene, pm_error_message());
        return res == PM_ERR_INPUT || res == PM_ERR_USAGE ? 1 : 3;
    }
    pm_scene_id(&r->sc, r->scene_all, sizeof r->scene_all);
    pm_scene_id_part(&r->sc, PM_SCENE_PHOTONS, r->scene_photons, sizeof r->scene_photons);
    pm_scene_id_part(&r->sc, PM_SCENE_VIEW, r->scene_view, sizeof r->scene_view);
    decide_scene(r);
    /* OUTDIR, the lock, the records of this run */
    if (mkdir_p(s->outdir) != 0) {
        say(r, "cannot create '%s': %s", s->outdir, strerror(errno));
        status = 3;
        goto done;
    }
    {
        char *real = realpath(s->outdir, NULL);
        if (!real) {
            say(r, "cannot create '%s'", s->outdir);
            status = 3;
            goto done;
        }
        snprintf(r->out, sizeof r->out, "%s", real);
        free(real);
    }
    if ((status = pm_engine_lock(r->me, r->out, r->s->wait, cmdline, &r->lock_fd)) != 0)
        goto done;
    /* the stages, run in OUTDIR, read the scene from the cache the driver's load left */
    if (!getenv("PMTK_SCENE_CACHE")) {
        pm_engine_scene_cache(r->out, cache, sizeof cache);
        setenv("PMTK_SCENE_CACHE", cache, 1);
    }
    pm_engine_scene_keep(r->me, r->s->verbose, cache, &r->sc, &cst);
    {
        char p[PATH_MAX + 64];
        snprintf(p, sizeof p, "%s/stats", r->out);
        if (mkdir(p, 0777) != 0 && errno != EEXIST) {
            say(r, "cannot create '%s': %s", p, strerror(errno));
            status = 3;
            goto done;
        }
        snprintf(p, sizeof p, "%s/ran.txt", r->out);
        FILE *f = fopen(p, "w");
        if (!f) {
            say(r, "cannot write '%s': %s", p, strerror(errno));
            status = 3;
            goto done;
        }
        fclose(f);
        snprintf(p, sizeof p, "%s/failed.txt", r->out);
        unlink(p);
    }
    {
        pm_stage_t st;
        memset(&st, 0, sizeof st);
        st.name = r->me;
        pm_scene_warn_unsupported(&r->sc, &st);
        uint32_t first;
        size_t nf = pm_scene_flipped_emitters(&r->sc, &first);
        if (nf)
            say(r,
                "warning: %zu emissive triangle(s) face away from the whole scene: their light reaches nothing but "
                "leaks out as fireflies (scene-info names the first)",
                nf);
    }
done:
    return status;
}

/* Frees what render_begin and the graph took, and lets OUTDIR go. */
static void render_end(render_t *r)
{
    fflush(stdout);
    for (int i = 0; i < r->njobs; i++)
        for (int k = 0; k < r->jobs[i].argc; k++)
            free(r->jobs[i].argv[k]);
    pm_scene_free(&r->sc);
    if (r->lock_fd >= 0)
        close(r->lock_fd);
}

int pm_render_fixed(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline)
{
    static render_t rr;
    render_t *r = &rr;
    pm_result_t res;
    int status = render_begin(r, s, me, bin, cmdline);
    if (status != 0)
        goto done;
    printf("%s: %s -> %s (MODE=%s MAP=%s ORDER=%s GATHER=%s SHARDS=%d)\n", r->me, r->scene_all, r->out, r->mode, r->map,
           r->order, s->value[PM_P_GATHER], s->shards);
    for (int i = 0; i < r->nnotes; i++)
        printf("%s: %s\n", r->me, r->notes[i]);
    fflush(stdout);
    build_graph(r);
    /* the targets: files of the graph, or all (the images) */
    int all = s->ntargets == 0;
    for (int t = 0; t < s->ntargets; t++) {
        if (strcmp(s->targets[t], "all") == 0) {
            all = 1;
            continue;
        }
        job_t *p = producer(r, s->targets[t]);
        if (!p) {
            say(r, "no target '%s' in this render's graph", s->targets[t]);
            status = 2;
            goto done;
        }
        need(r, p);
    }
    if (all)
        need(r, &r->jobs[r->njobs - 1]);
    r->progress = isatty(STDERR_FILENO) && !s->quiet;
    /* phase 1: what is there, read whole and judged by its header */
    uint64_t nqueries = 0;
    int have_count = 0;
    for (int i = 0; i < r->njobs; i++) {
        job_t *j = &r->jobs[i];
        if (!j->needed)
            continue;
        if (j->shard >= 0 && !have_count) {
            job_t *q = producer(r, r->queries);
            int k = 0;
            while (q && k < q->nouts && strcmp(q->outs[k], r->queries) != 0)
                k++;
            if (q && k < q->nouts && q->prov[k].verdict == PM_PROV_OK) {
                nqueries = q->prov[k].count;
                have_count = 1;
            }
        }
        if (j->shard >= 0 && !have_count) {
            /* no whole queries: they are remade, and so is every shard */
            for (int k = 0; k < j->nouts; k++)
                j->prov[k].verdict = PM_PROV_MISSING;
            continue;
        }
        if (j->shard >= 0)
            set_range(r, j, nqueries);
        if ((res = check_job(r, j)) != PM_OK) {
            say(r, "%s", pm_error_message());
            status = 3;
            goto done;
        }
    }
    /* A file judged against an input that is itself not what the settings make is judged again
     * once that input is remade (phase 3): its verdict waits for the new bytes. */
    for (int i = 0; i < r->njobs; i++) {
        job_t *j = &r->jobs[i];
        for (int k = 0; k < j->nouts && j->needed; k++) {
            pm_prov_t *pv = &j->prov[k];
            if (pv->verdict != PM_PROV_OTHER || !pv->input[0])
                continue;
            job_t *p = producer(r, pv->input);
            int m = 0;
            while (p && m < p->nouts && strcmp(p->outs[m], pv->input) != 0)
                m++;
            if (p && p->needed && m < p->nouts && p->prov[m].verdict != PM_PROV_OK)
                pv->verdict = PM_PROV_OK; /* for now: its input will be remade, and it judged again */
        }
    }
    /* phase 2: the plan, as if every job that runs changed what it makes (the progress count) */
    int total = 0;
    for (int i = 0; i < r->njobs; i++) {
        job_t *j = &r->jobs[i];
        j->run = j->needed && (!job_outputs_ok(j) || input_planned(r, j));
        total += j->run;
    }
    /* phase 3: run what is not what the settings would make, or whose inputs changed; up to
     * JOBS stages at once, each when the stages that make its inputs have ended */
    double t0 = pm_time_wall();
    int index = 0, running = 0, stop = 0, jobs_max = atoi(s->value[PM_P_JOBS]);
    if (jobs_max < 1)
        jobs_max = 1;
    static pm_proc_t *procs[MAX_JOBS];
    memset(procs, 0, sizeof procs);
    for (;;) {
        for (int i = 0; i < r->njobs && !stop; i++) {
            job_t *j = &r->jobs[i];
            if (!j->needed || j->state != 0 || j->active || !inputs_ready(r, j))
                continue;
            if (job_outputs_ok(j) && !input_changed(r, j)) {
                j->state = 1;
                i = -1; /* what waited on it may be ready now */
                continue;
            }
            if (job_outputs_ok(j)) {
                /* An input was remade with other bytes than the file it replaced (a corrupt one,
                 * say): what j made is judged again against the inputs now here, and kept when
                 * they are the bytes it recorded (a map rebuilt the same keeps its gather). */
                if ((res = check_job(r, j)) != PM_OK) {
                    say(r, "%s", pm_error_message());
                    status = 3;
                    stop = 1;
                    break;
                }
                if (job_outputs_ok(j)) {
                    j->state = 1;
                    i = -1;
                    continue;
                }
            }
            if (running >= jobs_max)
                continue;
            if (j->shard >= 0) {
                if (!have_count) {
                    if (count_records(r, r->queries, &nqueries) != PM_OK) {
                        say(r, "%s", pm_error_message());
                        status = 1;
                        stop = 1;
                        break;
                    }
                    have_count = 1;
                }
                set_range(r, j, nqueries);
            }
            int code = start_job(r, j, ++index, total, &procs[i]);
            if (code != 0) {
                status = code;
                stop = 1;
                break;
            }
            running++;
        }
        if (running == 0)
            break;
        int which;
        pm_proc_status_t st;
        if (pm_proc_wait_any(procs, r->njobs, &which, &st) != PM_OK) {
            say(r, "%s", pm_error_message());
            status = 4;
            break;
        }
        procs[which] = NULL;
        running--;
        int code = finish_job(r, &r->jobs[which], &st);
        pm_proc_status_free(&st);
        if (code != 0 && !stop) {
            status = stage_status(code);
            stop = 1; /* no stage starts after a failure; those running end */
        }
    }
    double run_s = pm_time_wall() - t0;
    /* a job after a failure that was not reached is cached only when its files are whole and current */
    for (int i = 0; i < r->njobs; i++) {
        job_t *j = &r->jobs[i];
        if (j->state == 0 && !j->needed && j->nouts) {
            if (strcmp(j->name, "composite") != 0 && j->shard < 0 && check_job(r, j) == PM_OK && job_outputs_ok(j))
                j->state = 1;
        } else if (j->state == 0 && status != 0 && job_outputs_ok(j) && !input_changed(r, j) && inputs_settled(r, j)) {
            j->state = 1;
        }
    }
    report(r, run_s);
    if (status != 0) {
        say(r, "stopped: a stage failed (exit %d); what ran is in %s/ran.txt", status, r->out);
        goto done;
    }
    keep_only(r);
    if (all)
        printf("%s: wrote %s/image.exr, %s/image.png, %s/stats.json%s%s%s\n", r->me, r->out, r->out, r->out,
               s->keep != PM_KEEP_ALL ? " (KEEP=" : "", s->keep != PM_KEEP_ALL ? s->value[PM_P_KEEP] : "",
               s->keep != PM_KEEP_ALL ? ": the rest removed)" : "");
done:
    render_end(r);
    return status;
}

/* ---- pass files: progressive passes kept as files, OUTDIR/pass-NNNN/ (KEEP=all given, PASS_RANGE
 * for pipelines/slurm's tasks, and what the resident passes of progressive.c do not run) ----
 *
 * Pass p is the chain above in its own directory with --pass p on the tracers and the gather (and
 * from pass 2 on --radius r_1, pass 1's width), ending at the pass's buffers, which composite
 * --accumulate adds to OUTDIR/running.pm and the images. Within a pass the photons are piped into
 * the map and, when they are sorted, the queries into hilbert-sort and on into the gather, so no
 * photons.pm or queries.pm is written: the pipe is the unit a pass keeps or remakes, judged by
 * the provenance of the files it makes (the COMMAND lines of every stage of the pipe). */

#define MAX_CMDS 6
#define MAX_UNITS 72

enum { U_PHOTONS, U_QUERIES, U_FUSED, U_ONE };

typedef job_t pcmd_t; /* a command of a pass: its name (row, stats/NAME.json) and argv */

/* A pipe of stages and the files it makes. U_PHOTONS: cmd 0 | cmd 1, then cmd 2 (the caustic map)
 * when there is one; U_QUERIES: cmd 0, or cmd 0 | cmd 1 (the sort); U_FUSED: U_PHOTONS's commands
 * (nph of them) beside cmd nph | cmd nph+1 | cmd nph+2 (the gather, started once the map is made);
 * U_ONE: cmd 0. */
typedef struct {
    int kind, nph;
    pcmd_t cmd[MAX_CMDS];
    int ncmd;
    const char *outs[MAX_FILES + 2];
    int first[MAX_FILES + 2], nwant[MAX_FILES + 2]; /* the COMMAND lines output k records: cmd[first..first+nwant) */
    int nouts;
    const char *ins[MAX_FILES];
    int nins;
    int external;      /* its last command is a gather outside the program directory */
    int shard;         /* -1 or the shard (its --range is set from the queries' count) */
    int needed, state; /* state: 0 not made, 1 cached, 2 ran, 3 failed */
} unit_t;

typedef struct {
    render_t *r;
    unit_t u[MAX_UNITS];
    int nu;
    char dir[PATH_MAX + 32]; /* the pass's directory */
    int pass;
    char r1[64]; /* pass 1's radius1, for passes after it */
    const char *shards[64];
    int nshards;
    int dry; /* pass_make only judges: 0 when nothing would run, 1 when something would */
} passgraph_t;

static pcmd_t *pc_new(render_t *r, unit_t *u, const char *name, const char *program)
{
    pcmd_t *c = &u->cmd[u->ncmd++];
    memset(c, 0, sizeof *c);
    snprintf(c->name, sizeof c->name, "%s", name);
    if (program[0] == '/')
        arg(c, program);
    else
        arg_prog(r, c, program);
    return c;
}
static void pc_pass(pcmd_t *c, int pass)
{
    char p[32];
    snprintf(p, sizeof p, "%d", pass);
    arg(c, "--pass");
    arg(c, p);
}
static void unit_out(unit_t *u, const char *file, int first, int n)
{
    u->outs[u->nouts] = file;
    u->first[u->nouts] = first;
    u->nwant[u->nouts++] = n;
}
static unit_t *unit_new(passgraph_t *g, int kind)
{
    unit_t *u = &g->u[g->nu++];
    memset(u, 0, sizeof *u);
    u->kind = kind;
    u->shard = -1;
    return u;
}

/* The photon side of a pass: trace-photons | build-photonmap, then the caustic map. */
static void pass_photons(passgraph_t *g, unit_t *u)
{
    render_t *r = g->r;
    const pm_settings_t *s = r->s;
    pcmd_t *c = pc_new(r, u, "trace-photons", "trace-photons");
    arg(c, r->scene);
    arg(c, "-o");
    arg(c, "-");
    if (r->need_caustic) {
        arg(c, "--caustic-output");
        arg(c, "caustic-photons.pm");
    }
    arg_opt(c, "--photons", s->value[PM_P_PHOTONS]);
    arg_opt(c, "--seed", s->value[PM_P_SEED]);
    if (r->secondary_direct)
        arg(c, "--indirect-only");
    pc_pass(c, g->pass);
    arg_common(r, c);
    c = pc_new(r, u, "build-photonmap", "build-photonmap");
    arg(c, "-");
    arg(c, "-o");
    arg(c, "photonmap.pm");
    arg(c, "--map");
    arg(c, r->map);
    arg_opt(c, "--width-k", r->width_k);
    arg_common(r, c);
    unit_out(u, "photonmap.pm", 0, 2);
    if (r->need_caustic) {
        unit_out(u, "caustic-photons.pm", 0, 1);
        c = pc_new(r, u, "build-photonmap.caustic", "build-photonmap");
        arg(c, "caustic-photons.pm");
        arg(c, "-o");
        arg(c, "caustic-map.pm");
        arg(c, "--map");
        arg(c, "caustic");
        arg_common(r, c);
        unit_out(u, "caustic-map.pm", 2, 1);
    }
    u->nph = u->ncmd;
}

/* The queries of a pass: trace-gather-points, into hilbert-sort when they are sorted. */
static void pass_queries(passgraph_t *g, unit_t *u)
{
    render_t *r = g->r;
    const pm_settings_t *s = r->s;
    int sorted = strcmp(r->order, "none") != 0, first = u->ncmd;
    pcmd_t *c = pc_new(r, u, "trace-gather-points", "trace-gather-points");
    arg(c, r->scene);
    arg(c, "-o");
    arg(c, sorted ? "-" : "queries.pm");
    if (r->need_direct) {
        arg(c, "--direct");
        arg(c, "direct.pm");
    }
    if (r->need_caustic) {
        arg(c, "--caustic-queries");
        arg(c, "caustic-queries.pm");
    }
    arg(c, "--mode");
    arg(c, r->mode);
    arg_opt(c, "--spp", s->value[PM_P_SPP]);
    arg_opt(c, "--width", s->value[PM_P_WIDTH]);
    arg_opt(c, "--height", s->value[PM_P_HEIGHT]);
    arg_opt(c, "--primary", s->value[PM_P_PRIMARY]);
    arg_opt(c, "--light-samples", r->light_samples);
    arg_opt(c, "--seed", s->value[PM_P_SEED]);
    if (r->secondary_direct)
        arg(c, "--secondary-direct");
    arg_diffuse(r, c);
    pc_pass(c, g->pass);
    arg_common(r, c);
    if (!sorted)
        unit_out(u, "queries.pm", first, 1);
    if (r->need_direct)
        unit_out(u, "direct.pm", first, 1);
    if (r->need_caustic)
        unit_out(u, "caustic-queries.pm", first, 1);
    if (sorted) {
        c = pc_new(r, u, "hilbert-sort", "hilbert-sort");
        arg(c, "-");
        arg(c, "-o");
        arg(c, u->kind == U_FUSED ? "-" : "sorted.pm");
        arg(c, "--order");
        arg(c, r->order);
        arg_opt(c, "--leaf", s->value[PM_P_LEAF]);
        arg_common(r, c);
        if (u->kind != U_FUSED)
            unit_out(u, "sorted.pm", first, 2);
    }
}

/* The gather's options in a pass: pass 1's radius or K, from pass 2 on r_1; the schedule. */
static void pass_gather_opts(passgraph_t *g, pcmd_t *c, int caustic)
{
    render_t *r = g->r;
    const pm_settings_t *s = r->s;
    if (g->pass == 1 || caustic) {
        arg_opt(c, r->knn ? "--max-radius" : "--radius", s->value[PM_P_RADIUS]);
        arg_opt(c, "--k", s->value[PM_P_K]);
    } else {
        arg_opt(c, "--radius", g->r1);
    }
    arg_opt(c, "--kernel", s->value[PM_P_KERNEL]);
    arg_opt(c, "--isa", s->value[PM_P_ISA]);
    if (s->coverage && !r->knn)
        arg_opt(c, "--coverage", r->scene);
    pc_pass(c, g->pass);
    arg_opt(c, "--alpha", s->value[PM_P_ALPHA]);
    /* the pass's place on the schedule by photons: every pass file has PHOTONS (or the scene's
     * count), so pass p has (p - 1) of them before it, the schedule's r_p as ever */
    int64_t n = 0;
    if (!s->value[PM_P_PHOTONS][0] || pm_parse_i64(s->value[PM_P_PHOTONS], &n) != PM_OK || n < 1)
        n = r->sc.defaults.photons;
    if (n >= 1) {
        char b[32], u[32];
        snprintf(b, sizeof b, "%" PRId64, n * (g->pass - 1));
        snprintf(u, sizeof u, "%" PRId64, n);
        arg(c, "--pass-photons");
        arg(c, b);
        arg(c, "--unit-photons");
        arg(c, u);
    }
}

/* The graph of pass g->pass in g->dir, as units in the order they run. */
static void pass_graph(passgraph_t *g)
{
    render_t *r = g->r;
    static char shard_out[64][32];
    int N = r->s->shards, sorted = strcmp(r->order, "none") != 0;
    g->nu = 0;
    g->nshards = 0;
    int fused = sorted && N == 1 && r->need_gather;
    if (fused) {
        unit_t *u = unit_new(g, U_FUSED);
        pass_photons(g, u);
        pass_queries(g, u);
        int q0 = u->nph;
        pcmd_t *c = pc_new(r, u, r->gname, r->gather_bin);
        arg(c, "photonmap.pm");
        arg(c, "-");
        arg(c, "-o");
        arg(c, "indirect.pm");
        pass_gather_opts(g, c, 0);
        arg_common(r, c);
        unit_out(u, "indirect.pm", q0, 3);
        u->external = r->ext_gather;
        g->shards[g->nshards++] = "indirect.pm";
    } else {
        if (r->need_gather)
            pass_photons(g, unit_new(g, U_PHOTONS));
        pass_queries(g, unit_new(g, U_QUERIES));
        for (int i = 0; r->need_gather && i < N && i < 64; i++) {
            unit_t *u = unit_new(g, U_ONE);
            char name[96];
            if (N == 1) {
                snprintf(name, sizeof name, "%s", r->gname);
                snprintf(shard_out[i], sizeof shard_out[i], "indirect.pm");
            } else {
                snprintf(name, sizeof name, "%s.%d", r->gname, i);
                snprintf(shard_out[i], sizeof shard_out[i], "indirect.%d.pm", i);
            }
            pcmd_t *c = pc_new(r, u, name, r->gather_bin);
            arg(c, "photonmap.pm");
            arg(c, r->queries);
            arg(c, "-o");
            arg(c, shard_out[i]);
            if (N > 1) {
                u->shard = i;
                arg(c, "--range");
                arg(c, "0:0");
            }
            pass_gather_opts(g, c, 0);
            arg_common(r, c);
            u->external = r->ext_gather;
            u->ins[u->nins++] = "photonmap.pm";
            u->ins[u->nins++] = r->queries;
            unit_out(u, shard_out[i], 0, 1);
            g->shards[g->nshards++] = shard_out[i];
        }
    }
    if (r->need_caustic) {
        unit_t *u = unit_new(g, U_ONE);
        pcmd_t *c = pc_new(r, u, "simd-gather.caustic", r->gather_bin);
        arg(c, "caustic-map.pm");
        arg(c, "caustic-queries.pm");
        arg(c, "-o");
        arg(c, "caustic.pm");
        pass_gather_opts(g, c, 1);
        arg_common(r, c);
        u->external = r->ext_gather;
        u->ins[u->nins++] = "caustic-map.pm";
        u->ins[u->nins++] = "caustic-queries.pm";
        unit_out(u, "caustic.pm", 0, 1);
    }
}

static void pass_graph_free(passgraph_t *g)
{
    for (int i = 0; i < g->nu; i++)
        for (int k = 0; k < g->u[i].ncmd; k++)
            for (int a = 0; a < g->u[i].cmd[k].argc; a++)
                free(g->u[i].cmd[k].argv[a]);
    g->nu = 0;
}

static unit_t *unit_making(passgraph_t *g, const char *file)
{
    for (int i = 0; i < g->nu; i++)
        for (int k = 0; k < g->u[i].nouts; k++)
            if (!strcmp(g->u[i].outs[k], file))
                return &g->u[i];
    return NULL;
}

static void unit_need(passgraph_t *g, unit_t *u)
{
    if (u->needed)
        return;
    u->needed = 1;
    for (int i = 0; i < u->nins; i++) {
        unit_t *p = unit_making(g, u->ins[i]);
        if (p)
            unit_need(g, p);
    }
}

/* The targets of a pass (PASS_RANGE's): all, gather-inputs (with SHARDS, all a pass makes but
 * the gather's shards) or a file of the graph and what it needs. PM_ERR_USAGE for another. */
static pm_result_t pass_targets(passgraph_t *g)
{
    const pm_settings_t *s = g->r->s;
    int all = s->ntargets == 0;
    for (int t = 0; t < s->ntargets; t++) {
        const char *w = s->targets[t];
        if (!strcmp(w, "all")) {
            all = 1;
        } else if (!strcmp(w, "gather-inputs") && s->shards > 1 && g->r->need_gather) {
            for (int i = 0; i < g->nu; i++)
                if (g->u[i].shard < 0)
                    unit_need(g, &g->u[i]);
        } else {
            unit_t *u = unit_making(g, w);
            if (!u)
                return pm_error_set(PM_ERR_USAGE, "no target '%s' in a pass's graph", w);
            unit_need(g, u);
        }
    }
    for (int i = 0; all && i < g->nu; i++)
        unit_need(g, &g->u[i]);
    return PM_OK;
}

/* Judges the outputs of u as they are now (after the units before it). 1 when all are what the
 * settings would make; says why a file is remade as the single render does. */
static int unit_current(passgraph_t *g, unit_t *u, int *err)
{
    render_t *r = g->r;
    int ok = 1;
    for (int k = 0; k < u->nouts; k++) {
        char *lines[MAX_CMDS] = {0};
        int n = u->nwant[k];
        for (int i = 0; i < n; i++)
            if (pm_prov_command_line(u->cmd[u->first[k] + i].argc, u->cmd[u->first[k] + i].argv, &lines[i]) != PM_OK)
                *err = 1;
        pm_prov_want_t w = {.dir = g->dir,
                            .name = u->outs[k],
                            .commands = (const char *const *)lines,
                            .ncommands = (size_t)n,
                            .scene = scene_of(r, u->outs[k]),
                            .external = u->external && u->first[k] + n == u->ncmd,
                            .scene_arg = n == 1 && (!strcmp(u->cmd[u->first[k]].name, "trace-photons") ||
                                                    !strcmp(u->cmd[u->first[k]].name, "trace-gather-points"))};
        pm_prov_t p;
        if (*err || pm_prov_check(&w, &p) != PM_OK)
            *err = 1;
        for (int i = 0; i < n; i++)
            free(lines[i]);
        if (*err)
            return 0;
        if (g->dry)
            ;
        else if (p.verdict == PM_PROV_CORRUPT)
            say(r, "pass-%04d/%s is corrupt (%s): rebuilding it", g->pass, u->outs[k], p.why);
        else if (p.verdict == PM_PROV_OTHER && r->s->verbose)
            say(r, "pass-%04d/%s was made otherwise (%s): remaking it", g->pass, u->outs[k], p.why);
        if (p.verdict != PM_PROV_OK)
            ok = 0;
    }
    return ok;
}

static void pass_record(const passgraph_t *g, const char *file, const char *line)
{
    char p[PATH_MAX + 96];
    snprintf(p, sizeof p, "%s/%s", g->dir, file);
    FILE *f = fopen(p, "a");
    if (f) {
        fprintf(f, "%s\n", line);
        fclose(f);
    }
}

/* A command of u has ended as st says: its time, ran.txt or failed.txt. */
static void cmd_ended(passgraph_t *g, const pcmd_t *c, const pm_proc_status_t *st)
{
    if (st->exit_code != 0) {
        say(g->r, "pass %d: stage %s failed (exit %d)", g->pass, c->name, st->exit_code);
        pass_record(g, "failed.txt", c->name);
        return;
    }
    char p[PATH_MAX + 200];
    snprintf(p, sizeof p, "%s/times/%s", g->dir, c->name);
    FILE *f = fopen(p, "w");
    if (f) {
        fprintf(f, "%.6f\n", st->wall_s);
        fclose(f);
    }
    pass_record(g, "ran.txt", c->name);
}

/* Starts command i of u with the given stdin and stdout (-1: none), closing the fds in cl in it. */
static int cmd_start(passgraph_t *g, unit_t *u, int i, int in, int out, const int *cl, int ncl, pm_proc_t **p)
{
    pcmd_t *c = &u->cmd[i];
    if (g->r->s->verbose) {
        fputs("+", stderr);
        for (int k = 0; k < c->argc; k++)
            fprintf(stderr, " %s", c->argv[k]);
        fputc('\n', stderr);
    }
    pm_spawn_t sp = {.argv = c->argv, .cwd = g->dir, .stdin_fd = in, .stdout_fd = out, .close_fds = cl, .nclose = ncl};
    if (pm_proc_spawn(&sp, p) != PM_OK) {
        say(g->r, "%s", pm_error_message());
        pass_record(g, "failed.txt", c->name);
        *p = NULL;
        return 3;
    }
    return 0;
}

/* Waits for p (command i of u); its exit status (3 when it cannot be waited for). */
static int cmd_wait(passgraph_t *g, unit_t *u, int i, pm_proc_t *p)
{
    if (!p)
        return 3;
    pm_proc_status_t st;
    if (pm_proc_wait(p, &st) != PM_OK) {
        say(g->r, "%s", pm_error_message());
        return 3;
    }
    cmd_ended(g, &u->cmd[i], &st);
    int code = st.exit_code;
    pm_proc_status_free(&st);
    return code;
}

static void close_fd(int *fd)
{
    if (*fd >= 0)
        close(*fd);
    *fd = -1;
}

/* Runs commands [a, b) of u as one pipe, the last one's stdout into out_fd (-1: its own -o);
 * the first failure's status, from the right as bash's pipefail reports it. */
static int run_pipe(passgraph_t *g, unit_t *u, int a, int b, int out_fd, int extra_close)
{
    pm_proc_t *p[MAX_CMDS] = {0};
    int in = -1, status = 0;
    for (int i = a; i < b; i++) {
        int fds[2] = {-1, -1};
        if (i + 1 < b && pm_proc_pipe(fds) != PM_OK) {
            say(g->r, "%s", pm_error_message());
            status = 3;
            break;
        }
        int cl[2], ncl = 0; /* the pipes close on exec; named too, for a spawn that dup2s */
        if (fds[0] >= 0)
            cl[ncl++] = fds[0];
        if (extra_close >= 0)
            cl[ncl++] = extra_close;
        int code = cmd_start(g, u, i, in, i + 1 < b ? fds[1] : out_fd, cl, ncl, &p[i]);
        close_fd(&in);
        close_fd(&fds[1]);
        in = fds[0];
        if (code) {
            status = code;
            break;
        }
    }
    close_fd(&in);
    int right = 0; /* the rightmost failure, as bash's pipefail reports it */
    for (int i = a; i < b; i++) {
        int code = p[i] ? cmd_wait(g, u, i, p[i]) : 0;
        if (code)
            right = code;
    }
    return status ? status : right;
}

/* The fused pass: the photon side beside the queries' pipe, the gather started on the sorted
 * queries once the map is made (nothing, and a failed pass, when it is not). */
static int run_fused(passgraph_t *g, unit_t *u)
{
    int q0 = u->nph, fds[2], qp[2];
    if (pm_proc_pipe(fds) != PM_OK || pm_proc_pipe(qp) != PM_OK) {
        say(g->r, "%s", pm_error_message());
        return 3;
    }
    /* trace-gather-points | hilbert-sort > qp[1] */
    pm_proc_t *tg = NULL, *hs = NULL;
    int cl1[2] = {fds[0], qp[0]};
    int status = cmd_start(g, u, q0, -1, fds[1], cl1, 2, &tg);
    close_fd(&fds[1]);
    int cl2[1] = {qp[0]};
    if (!status)
        status = cmd_start(g, u, q0 + 1, fds[0], qp[1], cl2, 1, &hs);
    close_fd(&fds[0]);
    close_fd(&qp[1]);
    int w = status ? status : run_pipe(g, u, 0, 2, -1, qp[0]);
    if (!w && !status && u->nph > 2)
        w = run_pipe(g, u, 2, 3, -1, qp[0]);
    int s = 0;
    pm_proc_t *ga = NULL;
    if (!w && !status)
        s = cmd_start(g, u, q0 + 2, qp[0], -1, NULL, 0, &ga);
    close_fd(&qp[0]); /* without a gather the sort's writes fail: it ends quietly */
    int c = cmd_wait(g, u, q0, tg), h = cmd_wait(g, u, q0 + 1, hs), x = ga ? cmd_wait(g, u, q0 + 2, ga) : 0;
    if (status)
        return status;
    if (w)
        return w;
    return s ? s : x ? x : h ? h : c;
}

/* Runs u; its exit status. What a failed unit leaves is removed, as make's .DELETE_ON_ERROR did. */
static int run_unit(passgraph_t *g, unit_t *u)
{
    int status;
    switch (u->kind) {
    case U_FUSED: status = run_fused(g, u); break;
    case U_PHOTONS:
        status = run_pipe(g, u, 0, 2, -1, -1);
        if (!status && u->ncmd > 2)
            status = run_pipe(g, u, 2, 3, -1, -1);
        break;
    default: status = run_pipe(g, u, 0, u->ncmd, -1, -1); break;
    }
    if (status) {
        for (int k = 0; k < u->nouts; k++) {
            char p[PATH_MAX + 96];
            snprintf(p, sizeof p, "%s/%s", g->dir, u->outs[k]);
            unlink(p);
        }
    }
    return status;
}

/* Makes pass g->pass in g->dir (created): each needed unit whose files are not what the settings
 * make runs. *ran_out: a stage ran. Returns the exit status. */
static int pass_make(passgraph_t *g, int *ran_out)
{
    render_t *r = g->r;
    *ran_out = 0;
    pass_graph_free(g);
    char p[PATH_MAX + 96];
    snprintf(p, sizeof p, "%s/stats", g->dir);
    if (g->dry) {
        struct stat sb;
        if (stat(g->dir, &sb) != 0) {
            *ran_out = 1;
            return 0;
        }
    } else if (mkdir_p(p) != 0) {
        say(r, "cannot create '%s': %s", p, strerror(errno));
        return 3;
    }
    if (!g->dry) {
        snprintf(p, sizeof p, "%s/times", g->dir);
        mkdir(p, 0777);
        snprintf(p, sizeof p, "%s/ran.txt", g->dir);
        FILE *f = fopen(p, "w");
        if (!f) {
            say(r, "cannot write '%s': %s", p, strerror(errno));
            return 3;
        }
        fclose(f);
        snprintf(p, sizeof p, "%s/failed.txt", g->dir);
        unlink(p);
    }
    pass_graph(g);
    if (pass_targets(g) != PM_OK) {
        say(r, "%s", pm_error_message());
        return 2;
    }
    for (int i = 0; i < g->nu; i++) {
        unit_t *u = &g->u[i];
        if (!u->needed)
            continue;
        if (u->shard >= 0) {
            char rel[PATH_MAX + 96];
            snprintf(rel, sizeof rel, "pass-%04d/%s", g->pass, r->queries);
            uint64_t n;
            if (count_records(r, rel, &n) != PM_OK) {
                if (g->dry) {
                    *ran_out = 1;
                    return 0;
                }
                say(r, "%s", pm_error_message());
                return 1;
            }
            char range[64];
            uint64_t N = (uint64_t)r->s->shards, s = (uint64_t)u->shard;
            snprintf(range, sizeof range, "%" PRIu64 ":%" PRIu64, n * s / N, n * (s + 1) / N);
            pcmd_t *c = &u->cmd[0];
            for (int k = 0; k < c->argc; k++)
                if (!strcmp(c->argv[k], "--range")) {
                    free(c->argv[k + 1]);
                    c->argv[k + 1] = strdup(range);
                }
        }
        int err = 0;
        if (unit_current(g, u, &err)) {
            u->state = 1;
            continue;
        }
        if (err) {
            say(r, "%s", pm_error_message());
            return 3;
        }
        *ran_out = 1;
        if (g->dry)
            return 0;
        int code = run_unit(g, u);
        if (code) {
            u->state = 3;
            return stage_status(code);
        }
        u->state = 2;
    }
    return 0;
}

/* ---- the passes' driver ---- */

typedef struct {
    render_t *r;
    passgraph_t g;
    char state[PATH_MAX + 32], list[PATH_MAX + 32];
    char **lines; /* passes.txt: "PASS HASH ERROR" */
    int nlines;
    long st_passes; /* the running image's passes, relative error and radius1 */
    char st_err[64], st_r1[64];
    const char *buffers[72];
    int nbuffers;
    double t0;
} passes_t;

static double since(const passes_t *P) { return pm_time_wall() - P->t0; }

static void pass_dir(const passes_t *P, int pass, char *out, size_t cap)
{
    snprintf(out, cap, "%s/pass-%04d", P->r->out, pass);
}

static void list_read(passes_t *P)
{
    for (int i = 0; i < P->nlines; i++)
        free(P->lines[i]);
    P->nlines = 0;
    FILE *f = fopen(P->list, "r");
    if (!f)
        return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = '\0';
        char **nl = realloc(P->lines, sizeof *nl * (size_t)(P->nlines + 1));
        if (!nl)
            break;
        P->lines = nl;
        P->lines[P->nlines++] = strdup(line);
    }
    fclose(f);
}

/* The running image's header, read whole: a damaged one is removed, and the passes rebuild it. */
static void state_read(passes_t *P)
{
    P->st_passes = 0;
    P->st_err[0] = P->st_r1[0] = '\0';
    struct stat sb;
    if (stat(P->state, &sb) != 0)
        return;
    pm_table_t t = {0};
    if (pm_table_read(P->state, &pm_radiance_schema, 0, &t) != PM_OK) {
        say(P->r, "the running image is damaged (%s): rebuilding it from the passes", pm_error_message());
        unlink(P->state);
        return;
    }
    const char *v = pm_header_get(&t.hdr, "passes");
    P->st_passes = v ? strtol(v, NULL, 10) : 0;
    v = pm_header_get(&t.hdr, "relative_error");
    snprintf(P->st_err, sizeof P->st_err, "%s", v ? v : "");
    v = pm_header_get(&t.hdr, "radius1");
    snprintf(P->st_r1, sizeof P->st_r1, "%s", v ? v : "");
    pm_table_free(&t);
}

/* The content hash of a pass's buffers (of their checksums), as hex; "" when one cannot be read. */
static void buffers_hash(passes_t *P, int pass, char *out, size_t cap)
{
    uint64_t h[72];
    char d[PATH_MAX + 32], f[PATH_MAX + 128];
    pass_dir(P, pass, d, sizeof d);
    out[0] = '\0';
    for (int i = 0; i < P->nbuffers; i++) {
        snprintf(f, sizeof f, "%s/%s", d, P->buffers[i]);
        if (pm_prov_trailer(f, &h[i]) != PM_OK)
            return;
    }
    snprintf(out, cap, "xxh3:%016" PRIx64, pm_hash_bytes(h, sizeof h[0] * (size_t)P->nbuffers));
}

/* Adds pass p's buffers to the running image (composite --accumulate), writes the images beside
 * their names and renames them once composite has written every output, then passes.txt. */
static int accumulate(passes_t *P, int p, const char *hash)
{
    render_t *r = P->r;
    char h[64], d[32], pp[32], st[96];
    if (!hash) {
        buffers_hash(P, p, h, sizeof h);
        hash = h;
    }
    snprintf(d, sizeof d, "pass-%04d", p);
    snprintf(pp, sizeof pp, "%d", p);
    snprintf(st, sizeof st, "%s/stats/composite.json", d);
    char *argv[MAX_ARGS + 80];
    char bufs[72][128], prog[PATH_MAX + 32];
    int n = 0;
    snprintf(prog, sizeof prog, "%s/composite", r->bin);
    argv[n++] = prog;
    for (int i = 0; i < P->nbuffers; i++) {
        snprintf(bufs[i], sizeof bufs[i], "%s/%s", d, P->buffers[i]);
        argv[n++] = bufs[i];
    }
    const char *fixed[] = {"--accumulate", "running.pm",
                           "--pass",       pp,
                           "-o",           ".pass.exr",
                           "--png",        ".pass.png",
                           "--exposure",   r->s->value[PM_P_EXPOSURE],
                           "--tone",       r->s->value[PM_P_TONE]};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        argv[n++] = (char *)fixed[i];
    if (!strcmp(r->s->value[PM_P_HALF], "1"))
        argv[n++] = "--half";
    if (!r->s->verbose)
        argv[n++] = "-q";
    if (r->s->value[PM_P_THREADS][0]) {
        argv[n++] = "--threads";
        argv[n++] = (char *)r->s->value[PM_P_THREADS];
    }
    argv[n++] = "--stats";
    argv[n++] = st;
    argv[n] = NULL;
    pm_spawn_t sp = {.argv = argv, .cwd = r->out, .stdin_fd = -1, .stdout_fd = -1};
    pm_proc_status_t ps;
    if (pm_proc_run(&sp, &ps) != PM_OK) {
        say(r, "%s", pm_error_message());
        return 3;
    }
    int code = ps.exit_code;
    double wall = ps.wall_s;
    pm_proc_status_free(&ps);
    if (code != 0)
        return stage_status(code);
    char a[PATH_MAX + 32], b[PATH_MAX + 32];
    snprintf(a, sizeof a, "%s/.pass.exr", r->out);
    snprintf(b, sizeof b, "%s/image.exr", r->out);
    if (rename(a, b) != 0)
        return 3;
    snprintf(a, sizeof a, "%s/.pass.png", r->out);
    snprintf(b, sizeof b, "%s/image.png", r->out);
    if (rename(a, b) != 0)
        return 3;
    snprintf(a, sizeof a, "%s/%s/times/composite", r->out, d);
    FILE *f = fopen(a, "w");
    if (f) {
        fprintf(f, "%.6f\n", wall);
        fclose(f);
    }
    state_read(P);
    list_read(P);
    snprintf(a, sizeof a, "%s.tmp", P->list);
    f = fopen(a, "w");
    if (!f)
        return 3;
    for (int i = 0; i < p - 1 && i < P->nlines; i++)
        fprintf(f, "%s\n", P->lines[i]);
    fprintf(f, "%d %s %s\n", p, hash, P->st_err);
    if (fclose(f) != 0 || rename(a, P->list) != 0)
        return 3;
    list_read(P);
    return 0;
}

/* The running image of passes 1 to k alone, from their buffers. */
static int rebuild(passes_t *P, int k)
{
    unlink(P->state);
    unlink(P->list);
    for (int q = 1; q <= k; q++) {
        int code = accumulate(P, q, NULL);
        if (code)
            return code;
    }
    return 0;
}

/* A header key of a pmtk file ("" when it has none or cannot be read). */
static void header_key(const char *path, const char *key, char *out, size_t cap)
{
    out[0] = '\0';
    pm_reader_t *rd;
    if (pm_reader_open(path, NULL, 0, &rd) != PM_OK)
        return;
    const char *v = pm_header_get(pm_reader_header(rd), key);
    snprintf(out, cap, "%s", v ? v : "");
    pm_reader_close(rd);
}

/* Whether the gather takes --pass (its --help says so): the schedule needs it. */
static int gather_takes_pass(const render_t *r)
{
    int fds[2];
    if (pm_proc_pipe(fds) != PM_OK)
        return 0;
    char *argv[] = {(char *)r->gather_bin, "--help", NULL};
    pm_spawn_t sp = {.argv = argv, .stdin_fd = -1, .stdout_fd = fds[1], .capture_stderr = 1};
    pm_proc_t *p;
    if (pm_proc_spawn(&sp, &p) != PM_OK) {
        close(fds[0]);
        close(fds[1]);
        return 0;
    }
    close(fds[1]);
    char buf[4096], tail[16] = "";
    int found = 0;
    ssize_t n;
    while ((n = read(fds[0], buf, sizeof buf - 1)) > 0) {
        buf[n] = '\0';
        char joined[sizeof tail + sizeof buf];
        snprintf(joined, sizeof joined, "%s%s", tail, buf);
        found = found || strstr(joined, "--pass");
        size_t len = strlen(joined);
        snprintf(tail, sizeof tail, "%s", len > 8 ? joined + len - 8 : joined);
    }
    close(fds[0]);
    pm_proc_status_t st;
    if (pm_proc_wait(p, &st) == PM_OK)
        pm_proc_status_free(&st);
    return found;
}

/* The stats of every stage of a pass (its stats/NAME.json), by name. */
static json_t *pass_stats(const passes_t *P, int pass)
{
    char d[PATH_MAX + 32], f[PATH_MAX + 400];
    pass_dir(P, pass, d, sizeof d);
    json_t *o = json_object();
    snprintf(f, sizeof f, "%s/stats", d);
    DIR *dir = opendir(f);
    if (!dir)
        return o;
    struct dirent *e;
    while ((e = readdir(dir))) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".json") != 0)
            continue;
        snprintf(f, sizeof f, "%s/stats/%s", d, e->d_name);
        json_t *j = NULL;
        if (pm_proc_stats_load(f, &j) == PM_OK && j) {
            char name[256];
            snprintf(name, sizeof name, "%.*s", (int)(len - 5), e->d_name);
            json_object_set_new(o, name, j);
        }
    }
    closedir(dir);
    return o;
}

/* KEEP for passes: buffers keeps running.pm, passes.txt and each pass's buffers; image the images
 * and stats.json alone. Only what render makes is removed, by name. */
static void keep_passes(passes_t *P)
{
    render_t *r = P->r;
    if (r->s->keep == PM_KEEP_ALL)
        return;
    static const char *const made[] = {"photons.pm",
                                       "photonmap.pm",
                                       "caustic-photons.pm",
                                       "caustic-map.pm",
                                       "queries.pm",
                                       ".queries.new.pm",
                                       "sorted.pm",
                                       "caustic-queries.pm",
                                       "direct.pm",
                                       "indirect.pm",
                                       "caustic.pm",
                                       "Makefile",
                                       "ran.txt",
                                       "failed.txt",
                                       "scene.cache",
                                       "scene-info.json",
                                       "scene-info.err",
                                       ".state.err",
                                       ".prov.err",
                                       ".pass.exr",
                                       ".pass.png",
                                       ".stamps",
                                       "stats",
                                       "times",
                                       NULL};
    char p[PATH_MAX + 300];
    for (int i = 0; made[i]; i++) {
        snprintf(p, sizeof p, "%s/%s", r->out, made[i]);
        remove_tree(p);
    }
    for (int i = 0; i < 64; i++) {
        snprintf(p, sizeof p, "%s/indirect.%d.pm", r->out, i);
        unlink(p);
    }
    if (r->s->keep == PM_KEEP_IMAGE) {
        unlink(P->state);
        unlink(P->list);
    }
    DIR *d = opendir(r->out);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        const char *n = e->d_name;
        size_t len = strlen(n);
        int digits = len >= 9 && strncmp(n, "pass-", 5) == 0;
        for (size_t k = 5; digits && k < len; k++)
            digits = n[k] >= '0' && n[k] <= '9';
        if (!digits)
            continue;
        snprintf(p, sizeof p, "%s/%s", r->out, n);
        if (r->s->keep == PM_KEEP_IMAGE) {
            remove_tree(p);
            continue;
        }
        DIR *pd = opendir(p);
        if (!pd)
            continue;
        struct dirent *f;
        while ((f = readdir(pd))) {
            if (!strcmp(f->d_name, ".") || !strcmp(f->d_name, ".."))
                continue;
            int keep = 0;
            for (int b = 0; b < P->nbuffers; b++)
                keep |= !strcmp(f->d_name, P->buffers[b]);
            if (!keep) {
                char q[PATH_MAX + 600];
                snprintf(q, sizeof q, "%s/%s", p, f->d_name);
                remove_tree(q);
            }
        }
        closedir(pd);
    }
    closedir(d);
}

static void fsync_path(const char *path)
{
    int fd = open(path, O_RDONLY);
    if (fd >= 0) {
        fsync(fd);
        close(fd);
    }
}

/* Makes pass p into P->g (directory, number, r_1 given). Returns the exit status; *ran_out. */
static int make_pass(passes_t *P, int p, int *ran_out)
{
    pass_dir(P, p, P->g.dir, sizeof P->g.dir);
    P->g.pass = p;
    P->g.dry = 0;
    return pass_make(&P->g, ran_out);
}

/* pass 1's radius1, for the passes after it */
static int read_r1(passes_t *P, const char *why_prefix)
{
    if (!P->r->need_gather || P->g.r1[0])
        return 0;
    char f[PATH_MAX + 200];
    snprintf(f, sizeof f, "%s/pass-0001/%s", P->r->out, P->g.shards[0] ? P->g.shards[0] : "indirect.pm");
    header_key(f, "radius1", P->g.r1, sizeof P->g.r1);
    if (P->g.r1[0])
        return 0;
    say(P->r, "%s'%s' does not give radius1 %s", why_prefix, f,
        why_prefix[0] == 'P' ? "(make pass 1 first)" : "(does GATHER take --pass?)");
    return 1;
}

typedef struct {
    int pass;
    char status[32];
    double wall;
    char err[64];
} row_t;

int pm_render_passes(const pm_settings_t *s_in, const char *me, const char *bin, const char *cmdline, double t0)
{
    row_t *rows = NULL;
    int nrows = 0;
    static render_t rr;
    static passes_t PP;
    static pm_settings_t ps;
    render_t *r = &rr;
    passes_t *P = &PP;
    ps = *s_in;
    const pm_settings_t *s = &ps;
    if (s->guide) { /* the resident passes have a guide (progressive.c, make_guide); the pass files not */
        pm_engine_say(me, "GUIDE=1 with pass files (KEEP=all, SHARDS, WIDTHS=variable, another GATHER or "
                          "TARGETs with passes): not done; the resident passes and one-pass renders are guided");
        return 2;
    }
    /* Per-pass defaults for the parameters not given (the scene's render block sizes one render,
     * not a pass): docs/accuracy.md, "Progressive defaults". */
    const char *const defaults[][2] = {{"PHOTONS", pm_progressive_default_photons(&ps)},
                                       {"PRIMARY", PM_PROGRESSIVE_PRIMARY_TEXT},
                                       {"SPP", PM_PROGRESSIVE_SPP_TEXT},
                                       {"K", pm_progressive_default_k(&ps)}};
    char defaulted[160] = "";
    for (size_t i = 0; i < sizeof defaults / sizeof defaults[0]; i++) {
        pm_param_t k = pm_param_find(defaults[i][0]);
        if (strcmp(ps.value[PM_P_MODE], "direct-vis") == 0 && k != PM_P_PHOTONS)
            continue; /* one query per primary hit: no SPP */
        if (ps.value[k][0])
            continue;
        ps.value[k] = defaults[i][1];
        size_t len = strlen(defaulted);
        snprintf(defaulted + len, sizeof defaulted - len, "%s%s=%s", len ? " " : "", defaults[i][0], defaults[i][1]);
    }
    memset(P, 0, sizeof *P);
    P->r = r;
    P->g.r = r;
    P->t0 = t0;
    int status = render_begin(r, s, me, bin, cmdline);
    if (status != 0)
        goto done;
    if (defaulted[0])
        note(r, "per-pass defaults: %s (give them to change them)", defaulted);
    if (r->need_gather && !gather_takes_pass(r)) {
        say(r,
            "GATHER=%s does not take --pass: progressive passes need a gather with the radius schedule (simd-gather, "
            "reverse-gather)",
            s->value[PM_P_GATHER]);
        status = 2;
        goto done;
    }
    /* What a pass's stages run with: no fsync (every file is read whole, checksum included,
     * before it is trusted; the running image and the images are synced once at the end), and
     * threads that wait without spinning, since a pass runs the stages of a pipe at once. */
    setenv("PMTK_FSYNC", "0", 1);
    setenv("OMP_WAIT_POLICY", "passive", 0);
    snprintf(P->state, sizeof P->state, "%s/running.pm", r->out);
    snprintf(P->list, sizeof P->list, "%s/passes.txt", r->out);
    if (r->need_direct)
        P->buffers[P->nbuffers++] = "direct.pm";
    static char shard_names[64][32];
    for (int i = 0; r->need_gather && i < s->shards && i < 64; i++) {
        if (s->shards == 1)
            snprintf(shard_names[i], sizeof shard_names[i], "indirect.pm");
        else
            snprintf(shard_names[i], sizeof shard_names[i], "indirect.%d.pm", i);
        P->buffers[P->nbuffers++] = shard_names[i];
    }
    P->g.shards[0] = r->need_gather ? shard_names[0] : NULL;
    if (r->need_caustic)
        P->buffers[P->nbuffers++] = "caustic.pm";
    const char *range = s->value[PM_P_PASS_RANGE];
    if (range[0]) {
        /* PASS_RANGE=A:B (pipelines/slurm's tasks): passes A to B alone, nothing added to the
         * running image; TARGETs stop each pass's graph there. */
        int first = atoi(range), last = atoi(strchr(range, ':') + 1);
        for (int p = first; p <= last; p++) {
            char prefix[128];
            snprintf(prefix, sizeof prefix, "PASS_RANGE=%s: pass 1's gather ", range);
            if (p > 1 && read_r1(P, prefix)) {
                status = 1;
                goto done;
            }
            double ts = pm_time_wall();
            int ran;
            status = make_pass(P, p, &ran);
            if (status) {
                say(r, "pass %d failed", p);
                goto done;
            }
            double t = pm_time_wall() - ts;
            char f[PATH_MAX + 64];
            snprintf(f, sizeof f, "%s/pass_s", P->g.dir);
            if (ran) {
                FILE *fp = fopen(f, "w");
                if (fp) {
                    fprintf(fp, "%.6f\n", t);
                    fclose(fp);
                }
            }
            /* the stages that ran, as ran.txt lists them */
            char made[1024] = "";
            snprintf(f, sizeof f, "%s/ran.txt", P->g.dir);
            FILE *fr = fopen(f, "r");
            char line[160];
            while (fr && fgets(line, sizeof line, fr)) {
                line[strcspn(line, "\n")] = '\0';
                size_t len = strlen(made);
                snprintf(made + len, sizeof made - len, "%s%s", len ? " " : "", line);
            }
            if (fr)
                fclose(fr);
            printf("%s: pass %d made (%s)\n", me, p, made);
            fflush(stdout);
        }
        goto done;
    }
    char alpha_show[64];
    snprintf(alpha_show, sizeof alpha_show, "%s", s->value[PM_P_ALPHA][0] ? s->value[PM_P_ALPHA] : "2/3");
    printf("%s: %s -> %s (MODE=%s MAP=%s ORDER=%s GATHER=%s SHARDS=%d, progressive: PASSES=%s TIME=%s "
           "TARGET_ERROR=%s ALPHA=%s)\n",
           me, r->scene_all, r->out, r->mode, r->map, r->order, s->value[PM_P_GATHER], s->shards,
           s->value[PM_P_PASSES][0] ? s->value[PM_P_PASSES] : "unlimited",
           s->value[PM_P_TIME][0] ? s->value[PM_P_TIME] : "none",
           s->value[PM_P_TARGET_ERROR][0] ? s->value[PM_P_TARGET_ERROR] : "none", alpha_show);
    for (int i = 0; i < r->nnotes; i++)
        printf("%s: %s\n", me, r->notes[i]);
    fflush(stdout);
    long maxp = s->value[PM_P_PASSES][0] ? atol(s->value[PM_P_PASSES]) : 0;
    double limit = 0, target = 0;
    if (s->value[PM_P_TIME][0])
        pm_parse_double(s->value[PM_P_TIME], &limit);
    if (s->value[PM_P_TARGET_ERROR][0])
        pm_parse_double(s->value[PM_P_TARGET_ERROR], &target);
    int p = 0;
    double longest = 0;
    char stop[96] = "";
    for (;;) {
        p++;
        if (maxp && p > maxp) {
            snprintf(stop, sizeof stop, "PASSES=%ld", maxp);
            p--;
            break;
        }
        /* TIME: the next pass must fit; a pass whose graph is current costs only its composite */
        if (p > 1 && s->value[PM_P_TIME][0]) {
            double est = longest;
            pass_dir(P, p, P->g.dir, sizeof P->g.dir);
            P->g.pass = p;
            P->g.dry = 1;
            int would;
            if (pass_make(&P->g, &would) == 0 && !would)
                est = 0;
            P->g.dry = 0;
            if (!(since(P) + est <= limit)) {
                snprintf(stop, sizeof stop, "TIME=%s", s->value[PM_P_TIME]);
                p--;
                break;
            }
        }
        double ts = pm_time_wall();
        int ran;
        int code = make_pass(P, p, &ran);
        if (code) {
            say(r, "pass %d failed; %s/image.exr and running.pm hold the %d finished passes", p, r->out, p - 1);
            status = code;
            goto done;
        }
        if (p == 1 && read_r1(P, "pass 1's gather ")) {
            status = 1;
            goto done;
        }
        if (p == 1)
            state_read(P);
        list_read(P);
        char hash[64];
        buffers_hash(P, p, hash, sizeof hash);
        char want[128];
        snprintf(want, sizeof want, "%d %s", p, hash);
        const char *line = p - 1 < P->nlines ? P->lines[p - 1] : "";
        const char *sp = strrchr(line, ' ');
        int held = P->st_passes >= p && sp && (size_t)(sp - line) == strlen(want) && !strncmp(line, want, strlen(want));
        char status_s[32];
        snprintf(status_s, sizeof status_s, "%s", ran ? "ran" : "cached");
        if (!held) {
            if (P->st_passes != p - 1 || P->nlines != p - 1) {
                if ((code = rebuild(P, p - 1)) != 0) {
                    say(r, "could not rebuild the running image of passes 1 to %d", p - 1);
                    status = code;
                    goto done;
                }
            }
            if ((code = accumulate(P, p, hash)) != 0) {
                say(r, "pass %d: composite failed; %s/image.exr and running.pm hold the %d finished passes", p, r->out,
                    p - 1);
                status = code;
                goto done;
            }
            snprintf(status_s + strlen(status_s), sizeof status_s - strlen(status_s), ", added");
            /* RENDER_PASS_HOOK (pipelines/error-vs-time): run as HOOK PASS SECONDS IMAGE once the
             * image holds passes 1 to PASS alone; a failing hook is reported and the render goes on */
            const char *hook = getenv("RENDER_PASS_HOOK");
            if (hook && hook[0]) {
                char pa[32], sec[32], img[PATH_MAX + 32];
                snprintf(pa, sizeof pa, "%d", p);
                snprintf(sec, sizeof sec, "%.3f", since(P));
                snprintf(img, sizeof img, "%s/image.exr", r->out);
                char *hv[] = {(char *)hook, pa, sec, img, NULL};
                pm_spawn_t sp2 = {.argv = hv, .stdin_fd = -1, .stdout_fd = -1};
                pm_proc_status_t hs;
                if (pm_proc_run(&sp2, &hs) == PM_OK) {
                    if (hs.exit_code)
                        say(r, "pass %d: RENDER_PASS_HOOK '%s' failed (exit %d)", p, hook, hs.exit_code);
                    pm_proc_status_free(&hs);
                } else {
                    say(r, "pass %d: RENDER_PASS_HOOK '%s' failed (exit %d)", p, hook, 127);
                }
            }
        }
        double t = pm_time_wall() - ts;
        char f[PATH_MAX + 64];
        snprintf(f, sizeof f, "%s/pass_s", P->g.dir);
        if (ran) {
            FILE *fp = fopen(f, "w");
            if (fp) {
                fprintf(fp, "%.6f\n", t);
                fclose(fp);
            }
        }
        FILE *fp = fopen(f, "r");
        double pst;
        if (fp && fscanf(fp, "%lf", &pst) == 1 && pst > longest && pst < 1e9)
            longest = pst;
        if (fp)
            fclose(fp);
        list_read(P);
        char err[64] = "";
        if (p - 1 < P->nlines) {
            const char *e = strrchr(P->lines[p - 1], ' ');
            int spaces = 0;
            for (const char *c = P->lines[p - 1]; *c; c++)
                spaces += *c == ' ';
            if (e && spaces >= 2)
                snprintf(err, sizeof err, "%s", e + 1);
        }
        row_t *nr = realloc(rows, sizeof *rows * (size_t)(nrows + 1));
        if (!nr) {
            status = 3;
            goto done;
        }
        rows = nr;
        rows[nrows].pass = p;
        snprintf(rows[nrows].status, sizeof rows[nrows].status, "%s", status_s);
        rows[nrows].wall = t;
        snprintf(rows[nrows].err, sizeof rows[nrows].err, "%s", err[0] ? err : "-");
        nrows++;
        double e;
        if (s->value[PM_P_TARGET_ERROR][0] && err[0] && pm_parse_double(err, &e) == PM_OK && e <= target) {
            snprintf(stop, sizeof stop, "TARGET_ERROR=%s", s->value[PM_P_TARGET_ERROR]);
            break;
        }
    }
    /* a rerun with fewer passes than the running image holds shows those passes alone */
    state_read(P);
    if (P->st_passes > p && (status = rebuild(P, p)) != 0) {
        say(r, "could not rebuild the running image of passes 1 to %d", p);
        goto done;
    }
    /* synced once here, not after every pass: a power loss mid-run leaves them torn, which the
     * next run finds (running.pm's checksum, passes.txt against it) and mends from the passes */
    const char *sync_files[] = {P->state, P->list, NULL, NULL};
    char ie[PATH_MAX + 32], ip[PATH_MAX + 32];
    snprintf(ie, sizeof ie, "%s/image.exr", r->out);
    snprintf(ip, sizeof ip, "%s/image.png", r->out);
    sync_files[2] = ie;
    for (int i = 0; i < 3; i++)
        fsync_path(sync_files[i]);
    fsync_path(ip);
    fsync_path(r->out);
    printf("  %-6s %-14s %9s %12s\n", "pass", "status", "wall s", "rel. error");
    for (int i = 0; i < nrows; i++)
        printf("  %-6d %-14s %9.3f %12s\n", rows[i].pass, rows[i].status, rows[i].wall, rows[i].err);
    double total = since(P);
    printf("  %-21s %9.3f   (%d passes, stopped by %s)\n", "total", total, p, stop);
    fflush(stdout);
    /* stats.json: {"scene", "params", "passes": [{"pass", "status", "wall_s", "relative_error",
     * "stages": {NAME: STATS}}], "total": {"passes", "relative_error", "wall_s", "stopped_by",
     * "alpha", "radius1"}} */
    {
        json_t *arr = json_array(), *tot = json_object();
        for (int i = 0; i < nrows; i++) {
            json_t *o = json_object();
            double e;
            json_object_set_new(o, "pass", json_integer(rows[i].pass));
            json_object_set_new(o, "status", json_string(rows[i].status));
            json_object_set_new(o, "wall_s", json_real(rows[i].wall));
            json_object_set_new(o, "relative_error",
                                pm_parse_double(rows[i].err, &e) == PM_OK ? json_real(e) : json_null());
            json_object_set_new(o, "stages", pass_stats(P, rows[i].pass));
            json_array_append_new(arr, o);
        }
        double e, a = 0.666666667, r1;
        json_object_set_new(tot, "passes", json_integer(p));
        json_object_set_new(tot, "relative_error",
                            pm_parse_double(P->st_err, &e) == PM_OK ? json_real(e) : json_null());
        json_object_set_new(tot, "wall_s", json_real(total));
        json_object_set_new(tot, "stopped_by", json_string(stop));
        if (s->value[PM_P_ALPHA][0])
            pm_parse_double(s->value[PM_P_ALPHA], &a);
        json_object_set_new(tot, "alpha", json_real(a));
        json_object_set_new(tot, "radius1", pm_parse_double(P->st_r1, &r1) == PM_OK ? json_real(r1) : json_null());
        stats_write(r, s, "passes", arr, tot);
    }
    keep_passes(P);
    if (s->keep == PM_KEEP_ALL)
        printf("%s: wrote %s/image.exr, %s/image.png (%d passes), %s/running.pm, %s/stats.json\n", me, r->out, r->out,
               p, r->out, r->out);
    else if (s->keep == PM_KEEP_BUFFERS)
        printf("%s: wrote %s/image.exr, %s/image.png (%d passes), %s/running.pm, %s/stats.json (KEEP=buffers: each "
               "pass's buffers kept, the rest removed)\n",
               me, r->out, r->out, p, r->out, r->out);
    else
        printf("%s: wrote %s/image.exr, %s/image.png (%d passes), %s/stats.json (KEEP=image: the rest removed)\n", me,
               r->out, r->out, p, r->out);
    free(rows);
    rows = NULL;
done:
    free(rows);
    pass_graph_free(&P->g);
    for (int i = 0; i < P->nlines; i++)
        free(P->lines[i]);
    free(P->lines);
    P->lines = NULL;
    render_end(r);
    return status;
}
