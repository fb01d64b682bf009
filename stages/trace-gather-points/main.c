/* trace-gather-points: the eye side of the final gather (the paper, sections 5.1 and 6.1).
 *
 * Reads a scene; traces primary, shadow and stratified secondary rays with the eye tracer
 * (common/render/eyetrace.h); writes a queries file (-o), one gather point per secondary hit
 * for hilbert-sort and simd-gather, and with --direct the direct radiance buffer
 * (component=direct). In a scene with mirrors or glass, eye paths pass through them to the first
 * other surface, and --caustic-queries writes those first hits as queries of their own
 * (kind=caustic), for simd-gather against the caustic map. docs/programs/trace-gather-points.md
 * and docs/formats.md (queries) give the weight contract.
 *
 * The queries header's COUNT must be known before the first record, so records are spooled
 * (common/base/spool.h: memory, then an unlinked temporary file past --spool-mem) and copied
 * into the output when tracing ends; the direct buffer is kept whole. Both outputs are
 * committed only when both are complete.
 *
 * Given several scenes (the frames of a camera or light path), it renders them one after the
 * other and writes one document per scene to each output, a stream of documents
 * (docs/formats.md, "Streams") for the resident stages downstream (hilbert-sort --stream,
 * simd-gather --stream, composite --stream). --no-queries writes the direct buffer alone (a
 * light path whose queries are kept from the still camera). With --passes A:B or --plan FILE
 * (base/passplan.h) it loads the scene once and traces progressive passes, a document per
 * pass to each output, each the bytes `trace-gather-points --pass P` alone writes (its COMMAND
 * says --pass P, and --primary N when the plan sized the pass). With --guide PHOTONS it reads a
 * photons file of the same scene (trace-photons --direction) and draws part of the secondary rays
 * at Lambertian hits from the photons' directions (render/guide.h); every output names that
 * file as an INPUT. */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/memory.h"
#include "base/passplan.h"
#include "base/spool.h"
#include "base/stage.h"
#include "base/timer.h"
#include "formats/formats.h"
#include "image/adaptive.h"
#include "render/aov.h"
#include "render/eyetrace.h"
#include "render/photontrace.h"
#include "render/rt.h"
#include "render/scene.h"
#include "render/shade.h"

static const char *const guide_cells_names[] = {"helpful", "all", NULL};
static const char *const strata_names[] = {"pixel", "hit", NULL};

typedef struct {
    const char *direct;    /* --direct FILE, NULL for none */
    const char *caustic;   /* --caustic-queries FILE, NULL for none */
    const char *aov;       /* --aov FILE: the denoiser's surface buffers (render/aov.h), NULL for none */
    int64_t spp;           /* secondary rays per primary hit; 0: the scene's render.spp */
    int64_t primary;       /* primary rays per pixel */
    int64_t light_samples; /* area-light samples per primary hit */
    int64_t width, height; /* image size; 0: the scene camera's */
    int64_t spool_mb;      /* MiB of records held in memory before they spill to a temporary file */
    int64_t pass;          /* progressive pass, 1-based; 0: none */
    int mode, schedule;
    int pixel; /* PM_PIXEL_BOX or PM_PIXEL_CENTER */
    const char *isa;
    int no_queries;          /* --no-queries: the direct buffer alone */
    const char *passes;      /* --passes A:B, NULL for none */
    const char *ready;       /* --ready FILE: told when the first pass may come (passplan.h) */
    const char *plan;        /* --plan FILE, NULL for none */
    int64_t plan_primary;    /* the pass's primary rays per pixel from the plan; 0: the options' */
    int single;              /* one document per output: the outputs are one set */
    int64_t glossy_depth;    /* glossy bounces a secondary path continues through; 0 gathers on them */
    const char *guide;       /* --guide PHOTONS, NULL for none */
    int guide_cells;         /* --guide-cells: 0 helpful, 1 all */
    uint64_t guide_hash;     /* its content hash, once read */
    const pm_guide_t *built; /* with --passes or --plan: the guide built once for every pass */
    int secondary_direct;    /* --secondary-direct: light samples at the gather points too */
    int strata;              /* --strata: 0 pixel, 1 hit */
    int64_t diffuse_depth;   /* --diffuse-depth: Lambertian bounces before the gather */
    int64_t diffuse_from;    /* --diffuse-from: the first pass that takes them (1: every pass) */
    const char *adaptive;    /* --adaptive MAP: each pixel's primary rays times its multiplier, NULL for none */
    uint64_t adaptive_hash;  /* the pass's map's content hash; adaptive_used: a map was read for the pass */
    int adaptive_used;
    char adaptive_path[4200]; /* the pass's map: --adaptive with its "%d" (if any) the pass number */
} tgp_options_t;

/* Where the eye tracer's results go: the queries into the spool, the direct rows into one
 * image-sized buffer. */
typedef struct {
    pm_spool_t spool, cspool; /* queries, caustic queries */
    double *direct;           /* width * height RGB, W/(m^2 sr) */
    uint32_t width;
} tgp_sink_t;

static pm_result_t sink_queries(void *user, const void *records, uint64_t count)
{
    return pm_spool_add(&((tgp_sink_t *)user)->spool, records, count);
}

static pm_result_t sink_caustic(void *user, const void *records, uint64_t count)
{
    return pm_spool_add(&((tgp_sink_t *)user)->cspool, records, count);
}

static pm_result_t sink_direct(void *user, uint32_t y0, uint32_t rows, const double *rgb)
{
    tgp_sink_t *k = user;
    memcpy(k->direct + (size_t)y0 * k->width * 3, rgb, (size_t)rows * k->width * 3 * sizeof *rgb);
    return PM_OK;
}

static pm_result_t write_records(void *writer, const void *records, uint64_t count)
{
    return pm_writer_write(writer, records, count);
}

/* A writable output path is checked before minutes of tracing, not after. */
static pm_result_t check_writable(const char *path) { return path ? pm_atomic_check(path) : PM_OK; }

/* The adaptive pass's map in a header: key adaptive (its path and content hash, which composite
 * reads to weigh the pixels) and an INPUT line (provenance). */
static pm_result_t set_adaptive(pm_header_t *h, const tgp_options_t *o)
{
    pm_result_t r = pm_header_set(h, "adaptive", "%s xxh3:%016" PRIx64, o->adaptive_path, o->adaptive_hash);
    return r == PM_OK ? pm_header_add_input(h, o->adaptive_path, o->adaptive_hash) : r;
}

/* The caustic queries: their header (the queries header, kind=caustic) and records. */
static pm_result_t write_caustic(pm_stage_t *st, const tgp_options_t *o, const pm_eye_t *e, tgp_sink_t *k)
{
    pm_header_t h;
    pm_writer_t *w = NULL;
    pm_result_t r = pm_eye_queries_header(e, st->argc, st->argv, k->cspool.count, &h);
    if (r == PM_OK)
        r = pm_header_set(&h, "kind", "caustic");
    if (r == PM_OK && o->adaptive_used)
        r = set_adaptive(&h, o);
    if (r == PM_OK && o->guide)
        r = pm_header_add_input(&h, o->guide, o->guide_hash);
    if (r == PM_OK && o->pass)
        r = pm_header_set(&h, "pass", "%" PRId64, o->pass);
    if (r == PM_OK)
        r = pm_writer_open(o->caustic, &h, &w);
    if (r == PM_OK)
        r = pm_spool_replay(&k->cspool, write_records, w);
    if (r == PM_OK) {
        r = pm_writer_commit(w);
        w = NULL;
    }
    pm_writer_abort(w);
    pm_header_free(&h);
    return r;
}

/* Every output: headers, then records; all renamed into place together by pm_stage_end. */
static pm_result_t write_aov(pm_stage_t *st, const tgp_options_t *o, const pm_eye_t *e, const pm_scene_t *s,
                             const pm_rt_t *rt)
{
    const pm_eye_info_t *in = pm_eye_info(e);
    float *v = malloc((size_t)in->width * in->height * PM_AOV_FLOATS * sizeof *v);
    if (!v)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " AOV buffer", in->width,
                            in->height);
    pm_header_t h;
    pm_header_init(&h, &pm_aov_schema);
    pm_writer_t *w = NULL;
    pm_result_t r = pm_aov_trace(s, rt, in->width, in->height, in->primary, in->pixel, in->seed, st->threads_used, v);
    if (r == PM_OK)
        r = pm_aov_header(&h, st->argc, st->argv, s, in->width, in->height, in->primary, in->pixel, in->seed);
    if (r == PM_OK)
        r = pm_writer_open(o->aov, &h, &w);
    if (r == PM_OK) /* the record is albedo, normal, depth: the 7 floats a pixel as they lie */
        r = pm_writer_write(w, v, h.count);
    if (r == PM_OK) {
        r = pm_writer_commit(w);
        w = NULL;
    }
    pm_writer_abort(w);
    pm_header_free(&h);
    free(v);
    return r;
}

/* --adaptive's map for this pass into *counts_out (malloc'd, w x h primary rays), or NULL when
 * resident passes find no map yet (the passes before the driver's first: uniform). */
static pm_result_t load_adaptive(pm_stage_t *st, tgp_options_t *o, uint32_t w, uint32_t h, uint32_t primary,
                                 uint32_t **counts_out)
{
    *counts_out = NULL;
    o->adaptive_used = 0;
    if (!o->adaptive)
        return PM_OK;
    /* "%d" in MAP: the pass's own map (pm-render's overlapped passes, each traced before the image
     * its map would be made from is done: a map per pass, written before its plan line) */
    const char *base = strrchr(o->adaptive, '/'), *d = strstr(base ? base + 1 : o->adaptive, "%d"); /* the name's */
    if (d)
        snprintf(o->adaptive_path, sizeof o->adaptive_path, "%.*s%" PRId64 "%s", (int)(d - o->adaptive), o->adaptive,
                 o->pass, d + 2);
    else
        snprintf(o->adaptive_path, sizeof o->adaptive_path, "%s", o->adaptive);
    if ((o->passes || o->plan) && access(o->adaptive_path, F_OK) != 0 && errno == ENOENT)
        return PM_OK;
    float *m = NULL;
    pm_result_t r = pm_adaptive_read(o->adaptive_path, PM_DENSITY_MULTIPLIER, w, h, &m, &o->adaptive_hash, NULL);
    uint64_t n = (uint64_t)w * h, rays = 0;
    uint32_t *cnt = r == PM_OK ? malloc((n ? n : 1) * sizeof *cnt) : NULL;
    if (r == PM_OK && !cnt)
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for the counts of a %" PRIu32 "x%" PRIu32 " map", w, h);
    for (uint64_t i = 0; r == PM_OK && i < n; i++) {
        if (!(cnt[i] = pm_adaptive_count(m[i], primary)))
            r = pm_error_set(PM_ERR_INPUT,
                             "density map '%s': pixel %" PRIu64 " multiplier %g times %" PRIu32
                             " primary rays is above %d rays",
                             o->adaptive_path, i, (double)m[i], primary, PM_ADAPTIVE_RAYS_MAX);
        rays += cnt[i];
    }
    free(m);
    if (r != PM_OK) {
        free(cnt);
        return r;
    }
    o->adaptive_used = 1;
    pm_stage_stat_int(st, "adaptive", 1);
    pm_stage_stat_double(st, "adaptive_primary_mean", n ? (double)rays / (double)n : 0.0);
    *counts_out = cnt;
    return PM_OK;
}

static pm_result_t write_outputs(pm_stage_t *st, const tgp_options_t *o, const pm_eye_t *e, tgp_sink_t *k,
                                 const pm_scene_t *s, const pm_rt_t *rt)
{
    pm_header_t qh, dh;
    pm_writer_t *qw = NULL, *dw = NULL;
    if (o->single)
        pm_stage_output_set(st);
    pm_result_t r = pm_eye_queries_header(e, st->argc, st->argv, k->spool.count, &qh);
    pm_header_init(&dh, &pm_radiance_schema);
    if (r == PM_OK && o->direct) {
        pm_header_free(&dh);
        r = pm_eye_direct_header(e, st->argc, st->argv, &dh);
    }
    if (r == PM_OK && o->guide)
        r = pm_header_add_input(&qh, o->guide, o->guide_hash);
    if (r == PM_OK && o->guide && o->direct)
        r = pm_header_add_input(&dh, o->guide, o->guide_hash);
    if (r == PM_OK && o->adaptive_used) /* composite weighs each pixel of the pass by the map's counts */
        r = set_adaptive(&qh, o);
    if (r == PM_OK && o->adaptive_used && o->direct)
        r = set_adaptive(&dh, o);
    if (r == PM_OK && o->pass)
        r = pm_header_set(&qh, "pass", "%" PRId64, o->pass);
    if (r == PM_OK && o->pass && o->direct)
        r = pm_header_set(&dh, "pass", "%" PRId64, o->pass);
    if (r == PM_OK && !o->no_queries)
        r = pm_writer_open(st->output, &qh, &qw);
    if (r == PM_OK && o->direct)
        r = pm_writer_open(o->direct, &dh, &dw);
    /* The queries are committed (flushed, on a stream) before the direct buffer is written: a
     * reader of the two streams must find each document whole before it waits on the other. */
    if (r == PM_OK && qw)
        r = pm_spool_replay(&k->spool, write_records, qw);
    if (r == PM_OK && qw) {
        r = pm_writer_commit(qw);
        qw = NULL;
    }
    if (r == PM_OK && dw)
        r = pm_writer_write(dw, k->direct, dh.count);
    if (r == PM_OK && dw) {
        r = pm_writer_commit(dw);
        dw = NULL;
    }
    pm_writer_abort(qw);
    pm_writer_abort(dw);
    pm_header_free(&qh);
    pm_header_free(&dh);
    if (r == PM_OK && o->caustic)
        r = write_caustic(st, o, e, k);
    if (r == PM_OK && o->aov)
        r = write_aov(st, o, e, s, rt);
    return r;
}

/* The guide from --guide's photons file: the scene's own photons (its SCENE key names this
 * scene's photon part: the same geometry and lights), with the direction channel. */
static pm_result_t load_guide(pm_stage_t *st, tgp_options_t *o, const pm_scene_t *s, pm_guide_t **out)
{
    *out = NULL;
    double t0 = pm_time_wall();
    pm_table_t t;
    pm_result_t r = pm_table_read(o->guide, &pm_photons_schema, pm_schema_required(&pm_photons_schema), &t);
    if (r != PM_OK)
        return r;
    char id[256];
    pm_scene_id_part(s, PM_SCENE_PHOTONS, id, sizeof id);
    const char *key = pm_header_get(&t.hdr, "SCENE"), *kind = pm_header_get(&t.hdr, "kind");
    if (!key || strcmp(key, id) != 0)
        r = pm_error_set(PM_ERR_INPUT, "--guide '%s' holds the photons of scene '%s', not of '%s' ('%s')", o->guide,
                         key ? key : "(none)", s->path, id);
    else if (kind && strcmp(kind, "caustic") == 0)
        r = pm_error_set(PM_ERR_INPUT, "--guide '%s' is a caustic photons file: give the global photons", o->guide);
    else if (!((t.hdr.channels >> PM_PHOTON_DIRECTION) & 1u))
        r = pm_error_set(PM_ERR_INPUT,
                         "--guide '%s' has no direction channel: trace its photons with trace-photons --direction",
                         o->guide);
    if (r == PM_OK) {
        const pm_guide_photons_t ph = {.pos = t.col[PM_PHOTON_POSITION],
                                       .power = t.col[PM_PHOTON_POWER],
                                       .normal = t.col[PM_PHOTON_NORMAL],
                                       .dir = t.col[PM_PHOTON_DIRECTION],
                                       .depth = t.col[PM_PHOTON_DEPTH],
                                       .n = t.count};
        r = pm_guide_build(&ph, o->guide_cells, out);
        o->guide_hash = t.checksum;
    }
    if (r == PM_OK) {
        const pm_guide_info_t *gi = pm_guide_info(*out);
        pm_stage_stat_int(st, "guide_photons", (int64_t)gi->photons_used);
        pm_stage_stat_int(st, "guide_cells", (int64_t)gi->cells);
        pm_stage_stat_int(st, "guide_cells_sparse", (int64_t)gi->cells_sparse);
        pm_stage_stat_int(st, "guide_cells_even", (int64_t)gi->cells_even);
        pm_stage_stat_double(st, "guide_cell_edge_m", gi->edge);
        pm_stage_stat_double(st, "guide_s", pm_time_wall() - t0); /* reading the photons and building */
        pm_stage_note(st,
                      "guide: %" PRIu64 " indirect photons, %" PRIu64 " cells of %.3g m used (%" PRIu64
                      " too sparse, %" PRIu64 " lit so evenly that cosine sampling does better)",
                      gi->photons_used, gi->cells, gi->edge, gi->cells_sparse, gi->cells_even);
    }
    pm_table_free(&t);
    return r;
}

static pm_result_t run(pm_stage_t *st, tgp_options_t *o, const pm_scene_t *s, const pm_rt_t *rt, pm_isa_t isa)
{
    /* One scene or a frame of several: the settings are the same for each. */
    /* The scene's render block stands in for an option not given: the command line wins. */
    const pm_args_t *a = &st->args;
    const pm_eye_options_t eo = {
        .mode = o->mode,
        .schedule = o->schedule,
        .width = (uint32_t)o->width,
        .height = (uint32_t)o->height,
        .spp = (uint32_t)o->spp,
        .primary = (uint32_t)(o->plan_primary               ? o->plan_primary
                              : pm_args_given(a, "primary") ? o->primary
                                                            : s->defaults.primary),
        .pixel = o->pixel,
        .light_samples = (uint32_t)(pm_args_given(a, "light-samples") ? o->light_samples : s->defaults.light_samples),
        .seed =
            pm_trace_pass_seed((uint64_t)(pm_args_given(a, "seed") ? st->seed : s->defaults.seed), (uint64_t)o->pass),
        .isa = isa,
        .threads = st->threads_used,
        .progress = pm_stage_progress(st),
        .caustics = o->caustic != NULL,
        .direct_only = o->no_queries,
        .glossy_depth = (unsigned)o->glossy_depth,
        .secondary_direct = o->secondary_direct,
        .strata_hit = o->strata == 1,
        /* a one-pass render (no --pass) is pass 1 */
        .diffuse_depth = (o->pass ? o->pass : 1) >= o->diffuse_from ? (unsigned)o->diffuse_depth : 0};
    pm_eye_options_t eo_g = eo;
    /* The scene's own camera is within the image limits (scene.c): only --width or --height
     * can take it beyond them, a usage error. */
    if (pm_image_size_check(o->width ? (uint64_t)o->width : s->camera.width,
                            o->height ? (uint64_t)o->height : s->camera.height) != PM_OK) {
        char why[PM_ERROR_MAX];
        snprintf(why, sizeof why, "%s", pm_error_message());
        return pm_error_set(PM_ERR_USAGE, "--width %" PRId64 " --height %" PRId64 " (0: the camera's): %s", o->width,
                            o->height, why);
    }
    uint32_t *counts = NULL, iw = o->width ? (uint32_t)o->width : s->camera.width,
             ih = o->height ? (uint32_t)o->height : s->camera.height;
    pm_result_t ra = load_adaptive(st, o, iw, ih, eo.primary ? eo.primary : 1, &counts);
    if (ra != PM_OK)
        return ra;
    eo_g.pixel_primary = counts;
    pm_guide_t *guide = NULL;
    eo_g.guide = o->built;
    if (o->guide && !o->built) {
        pm_result_t rg = load_guide(st, o, s, &guide);
        if (rg != PM_OK) {
            free(counts);
            return rg;
        }
        eo_g.guide = guide;
    }
    pm_eye_t *e;
    pm_result_t r = pm_eye_create(s, rt, &eo_g, &e);
    if (r != PM_OK) {
        pm_guide_destroy(guide);
        free(counts);
        return r;
    }
    const pm_eye_info_t *in = pm_eye_info(e);
    tgp_sink_t k = {.width = in->width};
    char dir[1024];
    pm_spool_dir_for(st->output, dir, sizeof dir);
    pm_spool_init(&k.spool, in->record_size, (size_t)o->spool_mb << 20, dir);
    pm_spool_init(&k.cspool, in->record_size, (size_t)o->spool_mb << 20, dir);
    if (!(k.direct = malloc((size_t)in->width * in->height * 3 * sizeof(double))))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " direct buffer", in->width,
                         in->height);
    pm_eye_stats_t x;
    const pm_eye_sink_t sink = {sink_queries, sink_direct, sink_caustic, &k};
    if (r == PM_OK)
        r = pm_eye_trace(e, &sink, &x);
    if (r == PM_OK)
        r = write_outputs(st, o, e, &k, s, rt);
    if (r == PM_OK)
        pm_eye_report(st, in, &x, o->schedule, pm_spool_spilled(&k.spool), isa);
    pm_spool_free(&k.spool);
    pm_spool_free(&k.cspool);
    free(k.direct);
    pm_eye_destroy(e);
    pm_guide_destroy(guide);
    free(counts);
    return r;
}

/* One pass of a plan (pm_passplan_run): the pass's documents. */
typedef struct {
    pm_stage_t *st;
    tgp_options_t *o;
    const pm_scene_t *s;
    const pm_rt_t *rt;
    pm_isa_t isa;
} tgp_pass_t;

static pm_result_t tgp_pass(void *user, int64_t pass, int64_t size)
{
    tgp_pass_t *t = user;
    t->o->pass = pass;
    t->o->plan_primary = size;
    return run(t->st, t->o, t->s, t->rt, t->isa);
}

/* --passes or --plan: the scene and its ray tracer made once, a document per pass to each
 * output, each recording the command line of that pass alone. */
static pm_result_t run_passes(pm_stage_t *st, tgp_options_t *o, char **argv, pm_isa_t isa)
{
    pm_passplan_t pp;
    pm_result_t r = pm_passplan_open(&pp, o->passes, o->plan);
    if (r != PM_OK)
        return r;
    pp.ready = o->ready;
    o->single = pm_passplan_single(&pp);
    if (!o->single && ((r = pm_writer_check_stream("-o", o->no_queries ? NULL : st->output)) != PM_OK ||
                       (r = pm_writer_check_stream("--direct", o->direct)) != PM_OK ||
                       (r = pm_writer_check_stream("--caustic-queries", o->caustic)) != PM_OK)) {
        pm_passplan_close(&pp);
        return r;
    }
    if (!o->single) /* a pass's arrays are allocated again for the next: its freed mappings serve them */
        pm_memory_reuse(PM_MEMORY_STREAM_REUSE);
    pm_scene_t s;
    pm_rt_t rt;
    if ((r = pm_scene_load(st->args.args[0], &s)) != PM_OK) {
        pm_passplan_close(&pp);
        return r;
    }
    pm_scene_warn_unsupported(&s, st);
    r = pm_rt_create(&s, 1, st->threads_used, &rt);
    pm_guide_t *guide = NULL; /* one guide for every pass */
    if (r == PM_OK && o->guide && (r = load_guide(st, o, &s, &guide)) == PM_OK)
        o->built = guide;
    if (r == PM_OK) {
        const void *drop[] = {&o->passes, &o->plan, &o->ready, &o->primary};
        tgp_pass_t tp = {st, o, &s, &rt, isa};
        r = pm_passplan_run(&pp, st, argv, drop, 4, "--primary", 4096, tgp_pass, &tp); /* --primary's own limit */
    }
    o->built = NULL;
    pm_guide_destroy(guide);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    pm_passplan_close(&pp);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    tgp_options_t o = {.primary = 1,
                       .pixel = PM_PIXEL_BOX,
                       .light_samples = 4,
                       .isa = "auto",
                       .spool_mb = 256,
                       .schedule = PM_EYE_DYNAMIC,
                       .glossy_depth = PM_EYE_GLOSSY_DEPTH,
                       .diffuse_from = 1};
    char **argv0 = argv;
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"direct", 0, PM_OPT_OUTPUT, &o.direct, "FILE",
         "also write the direct radiance buffer (emission seen directly plus direct light) here", 1, 0, NULL},
        {"aov", 0, PM_OPT_OUTPUT, &o.aov, "FILE",
         "also write the denoiser's surface buffers here (format aov: per pixel the first surface's albedo, shading "
         "normal and distance, for composite --aov-buffer); one scene, no passes",
         1, 0, NULL},
        {"caustic-queries", 0, PM_OPT_OUTPUT, &o.caustic, "FILE",
         "also write the caustic queries here: the first hit past mirrors and glass of every primary ray, for "
         "simd-gather against the caustic map (a scene with mirrors or glass; --mode gather)",
         1, 0, NULL},
        {"mode", 0, PM_OPT_CHOICE, &o.mode, "MODE",
         "gather: queries at secondary hits; direct-vis: the primary hits are the queries", 1, 0, pm_eye_mode_names},
        {"spp", 0, PM_OPT_INT, &o.spp, "N",
         "secondary rays per primary hit, a multiple of 4; 0 takes the scene's render.spp", 0, 65536, NULL},
        {"primary", 0, PM_OPT_INT, &o.primary, "N",
         "primary rays per pixel, each weighted 1/N; not given: the scene's render.primary", 1, 4096, NULL},
        {"pixel", 0, PM_OPT_CHOICE, &o.pixel, "HOW",
         "box: rays stratified and jittered over the pixel, which is the mean over its area; center: every ray "
         "through the pixel's centre",
         1, 0, pm_pixel_names},
        {"light-samples", 0, PM_OPT_INT, &o.light_samples, "N",
         "points sampled on area lights per primary hit; not given: the scene's render.light_samples", 0, 65536, NULL},
        {"width", 0, PM_OPT_INT, &o.width, "N", "image width in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"height", 0, PM_OPT_INT, &o.height, "N", "image height in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"isa", 0, PM_OPT_STRING, &o.isa, "ISA",
         "packet width: auto (widest this cpu and embree run), scalar (single rays), sse4 (4), avx2 (8), avx512 (16)",
         1, 0, NULL},
        {"schedule", 0, PM_OPT_CHOICE, &o.schedule, "HOW",
         "rows to threads: interleave (row i to thread i mod T), tiles (contiguous blocks), dynamic (as threads "
         "free up, so that they take the rows of the one spooling a band)",
         1, 0, pm_eye_schedule_names},
        {"spool-mem", 0, PM_OPT_INT, &o.spool_mb, "MIB",
         "MiB of query records held in memory; past that they go to a temporary file beside the output", 0, 1 << 20,
         NULL},
        {"pass", 0, PM_OPT_INT, &o.pass, "N",
         "progressive pass N (1-based): eye rays from streams of their own, independent of other passes'; 0: none", 0,
         (double)((int64_t)1 << 40), NULL},
        {"no-queries", 0, PM_OPT_FLAG, &o.no_queries, NULL,
         "write the --direct buffer alone, no queries (no -o): secondary rays are traced only in a scene with "
         "emissive triangles, a sun or a sky, for the light they find there; the buffer is the one a full run writes",
         1, 0, NULL},
        {"passes", 0, PM_OPT_STRING, &o.passes, "A:B",
         "progressive passes A to B, the scene loaded once: a document per pass to each output (streams), each the "
         "bytes --pass P alone writes",
         1, 0, NULL},
        {"ready", 0, PM_OPT_STRING, &o.ready, "FILE",
         "with --passes or --plan: once the scene is loaded and the ray tracer built, write 'PROGRAM ready WALL_S "
         "CPU_S' to FILE (a driver's pipe) and close it, before the first pass",
         1, 0, NULL},
        {"plan", 0, PM_OPT_STRING, &o.plan, "FILE",
         "progressive passes as a driver asks for them: a line 'PASS [PRIMARY]' per pass (- is stdin), a document "
         "each to each output, until the plan ends",
         1, 0, NULL},
        {"guide", 0, PM_OPT_STRING, &o.guide, "PHOTONS",
         "guide the secondary rays at Lambertian hits by this photons file of the same scene (trace-photons "
         "--direction): half of them drawn from the incoming directions of the indirect photons nearby, weighted "
         "by multiple importance sampling; one scene (with --passes or --plan, one guide for every pass)",
         1, 0, NULL},
        {"guide-cells", 0, PM_OPT_CHOICE, &o.guide_cells, "WHICH",
         "with --guide: helpful (the cells where the guide lowers the variance, estimated from their photons) or "
         "all (every cell of enough photons: tests of the weights)",
         1, 0, guide_cells_names},
        {"glossy-depth", 0, PM_OPT_INT, &o.glossy_depth, "N",
         "glossy bounces (a Phong Ns of 50 or more) a secondary ray continues through before it gathers, the "
         "light found on the way into the direct buffer; 0 gathers on the glossy surface",
         0, 64, NULL},
        {"adaptive", 0, PM_OPT_STRING, &o.adaptive, "MAP",
         "adaptive pass: pixel p gets round(m_p x primary) primary rays (at least 1), m_p from this density map "
         "(kind=multiplier, the image's size; composite --adaptive-map); headers say adaptive=MAP HASH; with "
         "--passes or --plan it is read before each pass, a %d in MAP's file name standing for the pass's number, "
         "and a pass that finds no MAP is uniform",
         1, 0, NULL},
        {"secondary-direct", 0, PM_OPT_FLAG, &o.secondary_direct, NULL,
         "also take a light sample of each light at every gather point into the direct buffer (an area light's "
         "near field and a constant sky stay the map's): gather the queries against a map without the first hits "
         "they stand for (trace-photons --indirect-only); headers say secondary_direct=1, or 2 under a constant sky",
         1, 0, NULL},
        {"diffuse-depth", 0, PM_OPT_INT, &o.diffuse_depth, "N",
         "Lambertian bounces a secondary path takes before it gathers (--mode gather): at each, a light sample of "
         "every light (the sky's too) and one cosine-weighted ray on, so the photon map is read one bounce later; 0 "
         "gathers at the secondary hits (the paper's final gather); headers say diffuse_depth=N",
         0, 8, NULL},
        {"diffuse-from", 0, PM_OPT_INT, &o.diffuse_from, "P",
         "--diffuse-depth's bounces from pass P on (--pass, --passes or --plan; a render without is pass 1): the "
         "earlier passes gather at the secondary hits, so that a long progressive render spends its first passes on "
         "the map's low noise and its later ones on a lower bias (pm-render DIFFUSE_DEPTH=auto)",
         1, INT32_MAX, NULL},
        {"strata", 0, PM_OPT_CHOICE, &o.strata, "HOW",
         "pixel: the secondary rays and the light samples of all a pixel's primary rays stratified as one set "
         "(headers say strata=pixel); hit: each hit's alone (the files of before, but for the constant sky's rule "
         "under --secondary-direct)",
         1, 0, strata_names},
        {0},
    };
    static const char about[] =
        "Trace primary and stratified secondary rays as packets; write gather points and direct light.";
    const pm_cli_t cli = {"trace-gather-points",
                          "[options] SCENE... -o QUERIES [--direct RADIANCE] [--caustic-queries QUERIES]",
                          about,
                          options,
                          1,
                          -1,
                          "queries"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    pm_isa_t isa;
    pm_result_t r = pm_isa_parse(o.isa, &isa);
    if (r != PM_OK)
        return pm_stage_end(&st, r);
    if (o.direct && !strcmp(o.direct, "-") && !strcmp(st.output, "-"))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "-o and --direct cannot both be stdout"));
    if (o.caustic && !strcmp(o.caustic, "-") && (!strcmp(st.output, "-") || (o.direct && !strcmp(o.direct, "-"))))
        return pm_stage_end(&st,
                            pm_error_set(PM_ERR_USAGE, "--caustic-queries and another output cannot both be stdout"));
    if (o.spp % PM_EYE_PER_CELL != 0)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE,
                                              "--spp %" PRId64 " is not a multiple of %d (%d samples per stratum cell)",
                                              o.spp, PM_EYE_PER_CELL, PM_EYE_PER_CELL));
    if (o.aov && (st.args.nargs != 1 || o.passes || o.plan || !strcmp(o.aov, "-")))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--aov writes one file for one scene: not with several "
                                                            "scenes, --passes, --plan or stdout"));
    if (pm_args_given(&st.args, "diffuse-from") && !o.diffuse_depth)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE,
                                              "--diffuse-from %" PRId64
                                              " says from which pass --diffuse-depth's bounces are "
                                              "taken: give --diffuse-depth N (1 or more)",
                                              o.diffuse_from));
    if (o.guide && o.mode != PM_EYE_GATHER)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE,
                                              "--guide guides the secondary rays of --mode gather, "
                                              "not --mode %s",
                                              pm_eye_mode_names[o.mode]));
    if (!o.guide && pm_args_given(&st.args, "guide-cells"))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--guide-cells chooses the cells of --guide: give "
                                                            "--guide PHOTONS"));
    if (o.guide && st.args.nargs != 1)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE,
                                              "--guide reads the photons of one scene: not with %d "
                                              "scenes",
                                              st.args.nargs));
    if (o.no_queries && (!o.direct || o.caustic || pm_args_given(&st.args, "output")))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--no-queries writes the --direct buffer alone: give "
                                                            "--direct FILE and neither -o nor --caustic-queries"));
    const char *qout = o.no_queries ? NULL : st.output;
    if ((r = check_writable(qout)) != PM_OK || (r = check_writable(o.direct)) != PM_OK ||
        (r = check_writable(o.caustic)) != PM_OK || (r = check_writable(o.aov)) != PM_OK)
        return pm_stage_end(&st, r);
    int frames = st.args.nargs;
    o.single = frames == 1;
    if (o.passes || o.plan) {
        if (o.passes && o.plan)
            r = pm_error_set(PM_ERR_USAGE, "--passes and --plan both name the passes: give one");
        else if (frames > 1)
            r = pm_error_set(PM_ERR_USAGE, "--%s traces the passes of one scene, not %d scenes",
                             o.passes ? "passes" : "plan", frames);
        else if (o.pass)
            r = pm_error_set(PM_ERR_USAGE, "--pass %" PRId64 " with --%s: the passes come from --%s", o.pass,
                             o.passes ? "passes" : "plan", o.passes ? "passes" : "plan");
        else
            r = run_passes(&st, &o, argv0, isa);
        return pm_stage_end(&st, r);
    }
    if (o.ready)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--ready tells a driver of --passes or --plan: give one"));
    if (frames > 1 && ((r = pm_writer_check_stream("-o", qout)) != PM_OK ||
                       (r = pm_writer_check_stream("--direct", o.direct)) != PM_OK ||
                       (r = pm_writer_check_stream("--caustic-queries", o.caustic)) != PM_OK))
        return pm_stage_end(&st, r);
    if (frames > 1) /* a frame's arrays are allocated again for the next: its freed mappings serve them */
        pm_memory_reuse(PM_MEMORY_STREAM_REUSE);
    /* A scene at a time, each with its own geometry: a frame may move anything. */
    for (int i = 0; i < frames && r == PM_OK; i++) {
        pm_scene_t s;
        if ((r = pm_scene_load(st.args.args[i], &s)) == PM_OK) {
            if (i == 0)
                pm_scene_warn_unsupported(&s, &st);
            pm_rt_t rt;
            r = pm_rt_create(&s, 1, st.threads_used, &rt);
            if (r == PM_OK)
                r = run(&st, &o, &s, &rt, isa);
            pm_rt_destroy(&rt);
            pm_scene_free(&s);
        }
        if (r != PM_OK && frames > 1) /* which frame of the stream failed */
            r = pm_stage_frame_error(r, i, st.args.args[i]);
    }
    if (frames > 1)
        pm_stage_stat_int(&st, "frames", frames);
    return pm_stage_end(&st, r);
}
