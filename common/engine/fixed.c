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

#include "base/exr.h"
#include "base/stage.h"
#include "base/timer.h"
#include "engine/engine.h"
#include "formats/pmfile.h"
#include "render/light.h"
#include "render/scene.h"
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

static void say(const render_t *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(const render_t *r, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", r->me);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

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
    json_t *params = json_object();
    for (int p = 0; p < PM_P_COUNT; p++)
        json_object_set_new(params, pm_param_name((pm_param_t)p), json_string(r->s->value[p]));
    json_t *tot = json_object();
    json_object_set_new(tot, "pipeline_wall_s", json_real(total));
    json_object_set_new(tot, "wall_s", json_real(wall));
    json_object_set_new(tot, "cpu_s", json_real(cpu));
    json_object_set_new(tot, "this_run_s", json_real(run_s));
    json_object_set_new(tot, "ran", ran);
    json_t *root = json_object();
    json_object_set_new(root, "scene", json_string(r->scene_all));
    json_object_set_new(root, "params", params);
    json_object_set_new(root, "stages", stages);
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

/* ---- KEEP: what OUTDIR keeps after a render that succeeded (only files render makes, by name) ---- */

static void remove_dir_files(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        char p[PATH_MAX + 300];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        unlink(p);
    }
    closedir(d);
    rmdir(dir);
}

static void keep_only(render_t *r)
{
    if (r->s->keep == PM_KEEP_ALL)
        return;
    static const char *const made[] = {"photons.pm", "photonmap.pm", "caustic-photons.pm", "caustic-map.pm",
                                       "queries.pm", "sorted.pm", "caustic-queries.pm", "direct.pm", "indirect.pm",
                                       "caustic.pm", "ran.txt", "failed.txt",
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
    remove_dir_files(p);
    snprintf(p, sizeof p, "%s/stats", r->out);
    remove_dir_files(p);
    snprintf(p, sizeof p, "%s/.stamps", r->out);
    remove_dir_files(p);
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

int pm_render_fixed(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline)
{
    static render_t rr;
    render_t *r = &rr;
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
    if ((res = pm_scene_load(r->scene, &r->sc)) != PM_OK) {
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
    fflush(stdout);
    for (int i = 0; i < r->njobs; i++)
        for (int k = 0; k < r->jobs[i].argc; k++)
            free(r->jobs[i].argv[k]);
    pm_scene_free(&r->sc);
    if (r->lock_fd >= 0)
        close(r->lock_fd);
    return status;
}
