/* trace-photons: scene -> photons file (the paper, section 5.1).
 *
 * Emits photons from the scene's point lights and emissive triangles, traces each with
 * single Embree rays (packets would bias which photons travel together; the paper keeps
 * single rays for that reason) and writes every photon stored at a reflecting surface,
 * first hits included with depth 0, in watts. The direction channel is written for scenes with
 * glossy materials, where the gather needs it, and with --direction (trace-gather-points --guide
 * reads it). Photons pass mirrors and glass
 * without being stored there; with --caustic-output (a scene with mirrors or glass only) the
 * caustic photons, those that reached a diffuse or glossy surface through specular bounces
 * alone (L S+ D), go to a second photons file (kind=caustic) as well, and both files are
 * committed together. common/render/photontrace.c does the work; this main reads options,
 * loads the scene and writes the files. Given several scenes (the frames of a light path), it
 * traces each in turn and writes one photons document per scene, a stream of documents
 * (docs/formats.md, "Streams") for build-photonmap --stream. With --passes A:B or --plan FILE
 * (base/passplan.h) it loads the scene once and traces progressive passes one after another,
 * a photons document per pass, each the bytes `trace-photons --pass P` alone writes (its
 * COMMAND line says --pass P, and --photons N when the plan sized the pass). */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"
#include "base/passplan.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "render/light.h"
#include "render/photontrace.h"
#include "render/rt.h"

typedef struct {
    int64_t photons; /* 0: the scene's render.photons */
    int64_t max_bounces;
    double rr_max;
    int baseline;
    int64_t pass;        /* progressive pass, 1-based; 0: none */
    const char *caustic; /* --caustic-output FILE, NULL for none */
    const char *passes;  /* --passes A:B, NULL for none */
    const char *ready;   /* --ready FILE: told when the first pass may come (passplan.h) */
    const char *plan;    /* --plan FILE, NULL for none */
    int indirect_only;   /* --indirect-only: no first hits in -o */
    int direction;       /* --direction: the direction channel whatever the scene */
} trace_options_t;

/* One photons file: the global photons (caustic 0) or the caustic ones (caustic 1), whose
 * header says kind=caustic so that build-photonmap --map caustic can insist on it. */
static pm_result_t write_photons(pm_stage_t *st, const trace_options_t *o, const pm_scene_t *s,
                                 const pm_trace_result_t *tr, int caustic)
{
    pm_header_t h;
    pm_header_init(&h, &pm_photons_schema);
    h.count = caustic ? tr->caustic : tr->count;
    h.channels = tr->channels;
    h.record_size = tr->record_size;
    memcpy(h.bounds, s->bounds, sizeof h.bounds);
    char id[256];
    pm_scene_id_part(s, PM_SCENE_PHOTONS, id, sizeof id);
    pm_writer_t *w = NULL;
    pm_result_t r;
    if ((r = pm_header_add_command(&h, st->argc, st->argv)) == PM_OK &&
        (r = pm_header_set(&h, "SCENE", "%s", id)) == PM_OK &&
        (r = pm_header_set(&h, "emitted", "%" PRIu64, tr->emitted)) == PM_OK &&
        (!o->pass || (r = pm_header_set(&h, "pass", "%" PRId64, o->pass)) == PM_OK) &&
        (!caustic || (r = pm_header_set(&h, "kind", "caustic")) == PM_OK) &&
        (caustic || !o->indirect_only ||
         (r = pm_header_set(&h, "indirect_only", "%d", pm_light_gather_rule(s))) == PM_OK) &&
        (r = pm_writer_open(caustic ? o->caustic : st->output, &h, &w)) == PM_OK) {
        const unsigned char **data = caustic ? tr->caustic_data : tr->chunk_data;
        const uint64_t *count = caustic ? tr->caustic_count : tr->chunk_count;
        for (uint64_t c = 0; c < tr->nchunks && r == PM_OK; c++)
            r = pm_writer_write(w, data[c], count[c]);
        if (r == PM_OK)
            r = pm_writer_commit(w); /* frees the writer, committed or not */
        else
            pm_writer_abort(w);
    }
    pm_header_free(&h);
    return r;
}

/* Loads scene `frame` of the arguments and its ray tracer; frees both on failure. */
static pm_result_t load(pm_stage_t *st, const trace_options_t *o, int frame, pm_scene_t *s, pm_rt_t *rt)
{
    pm_result_t r = pm_scene_load(st->args.args[frame], s);
    if (r != PM_OK)
        return r;
    if (frame == 0)
        pm_scene_warn_unsupported(s, st);
    if (o->caustic && !s->any_specular) {
        r = pm_error_set(PM_ERR_INPUT,
                         "scene '%s' has no mirror or glass: no caustic photons for --caustic-output '%s'", s->path,
                         o->caustic);
        pm_scene_free(s);
        return r;
    }
    if (frame == 0)
        pm_scene_warn_flipped(s, st);
    r = pm_rt_create(s, 1, st->threads_used, rt);
    if (r != PM_OK)
        pm_scene_free(s);
    return r;
}

/* Traces the photons of one document (o->pass, o->photons) and writes them. */
static pm_result_t trace(pm_stage_t *st, const trace_options_t *o, const pm_scene_t *s, const pm_rt_t *rt, int single)
{
    pm_result_t r;
    pm_trace_options_t to = {
        .photons = (uint64_t)(o->photons > 0 ? o->photons : s->defaults.photons),
        .seed = pm_trace_pass_seed((uint64_t)(pm_args_given(&st->args, "seed") ? st->seed : s->defaults.seed),
                                   (uint64_t)o->pass),
        .max_bounces = (uint32_t)o->max_bounces,
        .rr_max = o->rr_max,
        .direction = s->any_glossy || o->direction,
        .caustics = o->caustic != NULL,
        .indirect_only = o->indirect_only,
        .record_rays = o->baseline,
        .progress = pm_stage_progress(st),
    };
    pm_trace_result_t tr;
    r = pm_trace_photons(s, rt, &to, &tr);
    if (r == PM_OK) {
        double t0 = pm_time_wall();
        if (o->caustic && single)
            pm_stage_output_set(st); /* both files or neither */
        r = write_photons(st, o, s, &tr, 0);
        if (r == PM_OK && o->caustic)
            r = write_photons(st, o, s, &tr, 1);
        double t_write = pm_time_wall() - t0;
        if (r == PM_OK) {
            double rays_s = tr.trace_s > 0 ? (double)tr.rays / tr.trace_s : 0.0;
            st->items = tr.emitted;
            pm_stage_stat_int(st, "emitted", (int64_t)tr.emitted);
            pm_stage_stat_int(st, "stored", (int64_t)tr.count);
            pm_stage_stat_int(st, "first_hits", (int64_t)tr.first_hits);
            pm_stage_stat_int(st, "rays", (int64_t)tr.rays);
            pm_stage_stat_double(st, "rays_per_s", rays_s);
            pm_stage_stat_double(st, "rays_per_s_per_thread", rays_s / st->threads_used);
            pm_stage_stat_int(st, "escaped", (int64_t)tr.escaped);
            pm_stage_stat_int(st, "absorbed", (int64_t)tr.absorbed);
            pm_stage_stat_int(st, "capped", (int64_t)tr.capped);
            if (s->nportals)
                pm_stage_stat_int(st, "portal_back", (int64_t)tr.portal_back);
            pm_stage_stat_int(st, "longest_path", (int64_t)tr.longest);
            pm_stage_stat_double(st, "power_emitted_w",
                                 tr.power_emitted[0] + tr.power_emitted[1] + tr.power_emitted[2]);
            pm_stage_stat_double(st, "power_first_hits_w", tr.power_first[0] + tr.power_first[1] + tr.power_first[2]);
            if (s->any_specular)
                pm_stage_stat_int(st, "specular_bounces", (int64_t)tr.specular_bounces);
            if (o->caustic) {
                pm_stage_stat_int(st, "caustic", (int64_t)tr.caustic);
                pm_stage_stat_double(st, "power_caustic_w",
                                     tr.power_caustic[0] + tr.power_caustic[1] + tr.power_caustic[2]);
            }
            if (o->pass)
                pm_stage_stat_int(st, "pass", o->pass);
            pm_stage_stat_double(st, "trace_s", tr.trace_s);
            pm_stage_stat_double(st, "write_s", t_write);
            if (o->baseline) {
                double base = pm_trace_replay(rt, &tr);
                pm_stage_stat_double(st, "embree_rays_per_s", base);
                pm_stage_stat_double(st, "rays_per_s_over_embree", base > 0 ? rays_s / base : 0.0);
            }
            pm_stage_note(st, "%" PRIu64 " photons emitted, %" PRIu64 " stored (%" PRIu64 " first hits), %.2f Mrays/s",
                          tr.emitted, tr.count, tr.first_hits, rays_s * 1e-6);
            if (o->caustic)
                pm_stage_note(st, "%" PRIu64 " caustic photons (L S+ D) to '%s'", tr.caustic, o->caustic);
            if (tr.capped)
                pm_stage_note(st, "%" PRIu64 " paths reached --max-bounces %" PRId64 " and were cut (a small bias)",
                              tr.capped, o->max_bounces);
        }
        pm_trace_free(&tr);
    }
    return r;
}

static pm_result_t run(pm_stage_t *st, const trace_options_t *o, int frame)
{
    pm_scene_t s;
    pm_rt_t rt;
    pm_result_t r = load(st, o, frame, &s, &rt);
    if (r != PM_OK)
        return r;
    r = trace(st, o, &s, &rt, st->args.nargs == 1);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    return r;
}

/* One pass of a plan (pm_passplan_run): its photons, of the plan's size or the options'. */
typedef struct {
    pm_stage_t *st;
    trace_options_t *o;
    const pm_scene_t *s;
    const pm_rt_t *rt;
    int single;
    int64_t photons0;
} tp_pass_t;

static pm_result_t tp_pass(void *user, int64_t pass, int64_t size)
{
    tp_pass_t *t = user;
    t->o->pass = pass;
    t->o->photons = size ? size : t->photons0;
    return trace(t->st, t->o, t->s, t->rt, t->single);
}

/* --passes or --plan: the scene loaded once, a document per pass, each recording the command
 * line of that pass alone. */
static pm_result_t run_passes(pm_stage_t *st, trace_options_t *o, char **argv)
{
    pm_passplan_t pp;
    pm_result_t r = pm_passplan_open(&pp, o->passes, o->plan);
    if (r != PM_OK)
        return r;
    pp.ready = o->ready;
    int single = pm_passplan_single(&pp);
    if (!single && ((r = pm_writer_check_stream("-o", st->output)) != PM_OK ||
                    (r = pm_writer_check_stream("--caustic-output", o->caustic)) != PM_OK)) {
        pm_passplan_close(&pp);
        return r;
    }
    if (!single) /* a pass's arrays are allocated again for the next: its freed mappings serve them */
        pm_memory_reuse(PM_MEMORY_STREAM_REUSE);
    pm_scene_t s;
    pm_rt_t rt;
    if ((r = load(st, o, 0, &s, &rt)) != PM_OK) {
        pm_passplan_close(&pp);
        return r;
    }
    const void *drop[] = {&o->passes, &o->plan, &o->ready, &o->photons};
    tp_pass_t tp = {st, o, &s, &rt, single, o->photons};
    r = pm_passplan_run(&pp, st, argv, drop, 4, "--photons", INT64_MAX, tp_pass, &tp);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    pm_passplan_close(&pp);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    trace_options_t o = {.photons = 0, .max_bounces = 16384, .rr_max = 1.0, .baseline = 0, .pass = 0, .caustic = NULL};
    char **argv0 = argv;
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"photons", 'n', PM_OPT_INT, &o.photons, "N", "photon paths to emit; 0: the scene's render.photons", 0,
         (double)((int64_t)1 << 40), NULL},
        {"max-bounces", 0, PM_OPT_INT, &o.max_bounces, "N",
         "cut a path after N bounces (a safety net; Russian roulette ends paths long before: at albedo 0.999 one "
         "path in 1e7 reaches the default)",
         1, 1e6, NULL},
        {"rr-max", 0, PM_OPT_DOUBLE, &o.rr_max, "Q",
         "highest Russian-roulette survival probability; below albedo^2 the photons' powers grow from bounce to "
         "bounce and the total's variance is unbounded (1: survival is the albedo, powers stay equal)",
         0.01, 1.0, NULL},
        {"caustic-output", 0, PM_OPT_OUTPUT, &o.caustic, "FILE",
         "also write the caustic photons (reached a diffuse or glossy surface through mirrors or glass alone since "
         "the light) here, for build-photonmap --map caustic; only for a scene with mirrors or glass",
         1, 0, NULL},
        {"indirect-only", 0, PM_OPT_FLAG, &o.indirect_only, NULL,
         "store in -o no first hit (depth 0) whose light the gather points sample with shadow rays (all but an "
         "area light's near field and a constant sky; trace-gather-points --secondary-direct); the header says "
         "indirect_only=1, or 2 under a constant sky",
         1, 0, NULL},
        {"direction", 0, PM_OPT_FLAG, &o.direction, NULL,
         "write the direction channel (where each photon came from) in any scene, not only a glossy one: for "
         "trace-gather-points --guide",
         1, 0, NULL},
        {"baseline", 0, PM_OPT_FLAG, &o.baseline, NULL,
         "also re-trace every ray with bare rtcIntersect1 and report Embree's rate (for benchmarks)", 1, 0, NULL},
        {"pass", 0, PM_OPT_INT, &o.pass, "N",
         "progressive pass N (1-based): photons drawn from streams of their own, independent of other passes'; "
         "0: none",
         0, (double)((int64_t)1 << 40), NULL},
        {"passes", 0, PM_OPT_STRING, &o.passes, "A:B",
         "progressive passes A to B, the scene loaded once: a photons document per pass (a stream), each the bytes "
         "--pass P alone writes",
         1, 0, NULL},
        {"ready", 0, PM_OPT_STRING, &o.ready, "FILE",
         "with --passes or --plan: once the scene is loaded and the ray tracer built, write 'PROGRAM ready WALL_S "
         "CPU_S' to FILE (a driver's pipe) and close it, before the first pass",
         1, 0, NULL},
        {"plan", 0, PM_OPT_STRING, &o.plan, "FILE",
         "progressive passes as a driver asks for them: a line 'PASS [PHOTONS]' per pass (- is stdin), a photons "
         "document each, until the plan ends",
         1, 0, NULL},
        {0},
    };
    static const char about[] = "Trace photons from the scene's lights and write where they land (watts).";
    const pm_cli_t cli = {"trace-photons", "[options] SCENE... -o PHOTONS", about, options, 1, -1, "photons"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    int frames = st.args.nargs;
    pm_result_t r = PM_OK;
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
            r = run_passes(&st, &o, argv0);
        return pm_stage_end(&st, r);
    }
    if (o.ready)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--ready tells a driver of --passes or --plan: give one"));
    if (frames > 1 && ((r = pm_writer_check_stream("-o", st.output)) != PM_OK ||
                       (r = pm_writer_check_stream("--caustic-output", o.caustic)) != PM_OK))
        return pm_stage_end(&st, r);
    if (frames > 1) /* a frame's arrays are allocated again for the next: its freed mappings serve them */
        pm_memory_reuse(PM_MEMORY_STREAM_REUSE);
    for (int i = 0; i < frames && r == PM_OK; i++)
        if ((r = run(&st, &o, i)) != PM_OK && frames > 1) /* which frame of the stream failed */
            r = pm_stage_frame_error(r, i, st.args.args[i]);
    if (frames > 1)
        pm_stage_stat_int(&st, "frames", frames);
    return pm_stage_end(&st, r);
}
