/* simd-gather: photon map + gather points -> indirect radiance buffer (the paper,
 * sections 3, 5.3 and 7).
 *
 * Every query receives the sample-point estimate of the photons around it, multiplied by
 * its weight, and each query's result is added to its pixel. Packets of W consecutive
 * queries (W = 16, 8, 4 or 1 by --isa) walk the KD-tree together; hilbert-sort is what
 * makes consecutive queries close, so that the lanes of a packet stay live together. The
 * sums per query are in double, and queries are added to pixels in file order, so the
 * buffer is the same for any thread count. common/photonmap/gather.c does the work. With a
 * width known before the queries arrive (--radius, a later progressive pass, variable widths)
 * they stream through a chunk at a time (gather_stage.h), gathered while the stage before
 * writes the next.
 *
 * With --stream one input is kept in memory and the other is a stream of documents (docs/formats.md,
 * "Streams"), one frame each: --stream queries keeps the map and gathers every queries document
 * that arrives (a moving camera), --stream map keeps the queries and gathers them against every
 * map document (moving lights); one radiance document per frame goes to stdout, each the bytes
 * the same gather of that frame's two files would write but for its provenance. The kernel
 * width is measured once, on the first frame, when not given.
 *
 * --stream pairs takes both inputs as streams, a map document and a queries document per
 * progressive pass (resident passes: common/engine/progressive.c), and gathers each pair with
 * the width of the pass its documents name (header key pass): r_1 from --radius, else measured
 * by --k on the first pair (which must be pass 1), then r_p of the schedule (--alpha). Each
 * radiance document records the command of that pass alone (--pass P, and --radius r_1 after
 * pass 1), so it is the bytes `simd-gather MAP QUERIES --pass P` writes, but for the inputs'
 * names. */
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"
#include "base/passplan.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "photonmap/coverage.h"
#include "photonmap/gather.h"
#include "photonmap/gather_stage.h"
#include "render/areasample.h"
#include "render/scene.h"

static const char *const width_names[] = {"fixed", "variable", NULL};

/* --coverage SCENE: the scene, loaded at the first gather it corrects, and the area samples' map
 * for the spacing level of the width in use, made again when a pass's width reaches another
 * level. The first pass of a progressive render is not corrected: it is the pass the first image
 * waits for, and the scene's load and the first level's samples would delay it (by 0.3 s on the
 * sky-lit atrium, where the tracers load the same scene on the same cores), while its weight in
 * the running mean is its share of the photons, 1/16 of a full pass at TIME's first size. A
 * resident gather loads the scene once pass 1 is written, while pass 2 is traced. */
typedef struct {
    const char *path;
    pm_scene_t scene;
    pm_rt_t rt;
    int loaded, traced;
    int per_query; /* the last map's side: its queries' results divided, not its photons' powers */
    int applied;   /* the last gather was corrected (not progressive pass 1) */
    int off;       /* the scene has too many triangles to sample within PM_COVERAGE_MAX_SAMPLES */
    int finest;    /* the finest spacing level within that bound (pm_coverage_finest_level) */
    pm_coverage_t cov;
    int level; /* the level of cov's samples (when cov.spacing > 0) */
    double load_s;
    /* --coverage-level L (INT64_MAX: not given): the samples of level L, the kernel's own or one
     * coarser; --coverage-plan FILE: a line per pass of a stream, "PASS 1" to keep the samples
     * the pass before had when the kernel's own level is one finer (hold). held: the last
     * gather's samples are coarser than its kernel's own level. */
    int64_t level_opt;
    const char *level_text, *plan_path;
    pm_passplan_t plan;
    int hold, held;
} cover_t;
static const char *const stream_names[] = {"none", "queries", "map", "pairs", NULL};
enum { STREAM_NONE = 0, STREAM_QUERIES = 1, STREAM_MAP = 2, STREAM_PAIRS = 3 };

typedef struct {
    double radius;
    double k;
    int kernel, widths;
    double normal_cos;
    const char *isa;
    const char *range;
    int64_t pass; /* progressive pass, 1-based; 0: none */
    double alpha; /* the schedule's alpha with pass */
    int stream;   /* STREAM_*: which input is a stream of documents */
    int k_each;   /* --k-each-pass: --stream pairs measures r_1 by --k on every pass's documents */
    int64_t pass_photons, unit_photons; /* photons before the pass (-1: not given) and pass 1's (0: not given) */
    cover_t *cover;                     /* --coverage, or NULL */
} gather_options_t;

static uint64_t count_samples(const void *scene, double spacing) { return pm_area_samples_count(scene, spacing); }

/* --coverage's scene and its rays' structure, once. Every storing triangle has a sample a side at
 * least: a scene of more than PM_COVERAGE_MAX_SAMPLES / 2 of them cannot be sampled within the bound at
 * any spacing, and goes uncorrected (off), with a word. */
static pm_result_t cover_load(pm_stage_t *st, cover_t *c)
{
    if (c->loaded)
        return PM_OK;
    double t0 = pm_time_wall();
    pm_result_t r = pm_scene_load(c->path, &c->scene);
    if (r != PM_OK) {
        pm_error_prefix("--coverage");
        return r;
    }
    c->loaded = 1;
    if ((r = pm_rt_create(&c->scene, 0, 0, &c->rt)) != PM_OK)
        return r;
    c->traced = 1;
    c->load_s = pm_time_wall() - t0;
    if ((c->finest = pm_coverage_finest_level(count_samples, &c->scene, PM_COVERAGE_MAX_SAMPLES)) == INT_MAX) {
        c->off = 1;
        pm_stage_note(st,
                      "warning: --coverage: scene '%s' has too many triangles for %llu area samples (one a side "
                      "each at least): its boundary correction is off",
                      c->path, (unsigned long long)PM_COVERAGE_MAX_SAMPLES);
    }
    return PM_OK;
}

/* With --coverage, the boundary correction (photonmap/coverage.h) of in's map for the gather
 * of params p, when the map is new to the gather (new_map). The scene must be the queries' own
 * (the geometry part of their SCENE key). */
static pm_result_t cover_map(pm_stage_t *st, cover_t *c, pm_gather_inputs_t *in, const pm_gather_params_t *p,
                             int new_map, uint64_t pass)
{
    in->cover = NULL;
    if (c)
        c->applied = 0, c->held = 0;
    if (!c || pass == 1) /* progressive pass 1 goes uncorrected (cover_t) */
        return PM_OK;
    if (!new_map) { /* a kept map: corrected already, or its queries are */
        c->applied = !c->off;
        in->cover = c->applied && c->per_query ? &c->cov : NULL;
        return PM_OK;
    }
    double h = p->radius;
    pm_result_t r = cover_load(st, c);
    if (r != PM_OK || c->off)
        return r;
    /* "NAME xxh3:GEOMETRY" begins both keys when the triangles, materials and textures agree */
    char id[300];
    pm_scene_id(&c->scene, id, sizeof id);
    const char *key = pm_header_get(&in->q_table.hdr, "SCENE");
    if (!key || !pm_scene_key_same_scene(id, key))
        return pm_error_set(PM_ERR_INPUT, "--coverage '%s' is scene '%s', but the queries '%s' are of '%s'", c->path,
                            id, in->q_path ? in->q_path : "stdin", key ? key : "(no SCENE key)");
    int level;
    if ((r = pm_coverage_level(h, &level)) != PM_OK)
        return r;
    int own = level > c->finest ? level : c->finest, use = own; /* within the bound */
    if (c->level_opt != INT64_MAX) {
        if (c->level_opt < own || c->level_opt > (int64_t)own + 1)
            return pm_error_set(PM_ERR_USAGE,
                                "--coverage-level %" PRId64 ": the kernel %.9g m wide samples at level %d; give %d or "
                                "%d (one level coarser)",
                                c->level_opt, h, own, own, own + 1);
        use = (int)c->level_opt;
    } else if (c->hold && c->cov.spacing > 0.0 && c->level == own + 1) {
        use = c->level; /* the plan's hold: the last pass's samples, one level coarser */
    } else if (c->hold && !(c->cov.spacing > 0.0 && c->level == own)) {
        pm_stage_note(st,
                      "coverage: the plan keeps the samples of the pass before, but %s; the kernel's own level %d "
                      "is sampled",
                      c->cov.spacing > 0.0 ? "they are not one level coarser" : "there are none", own);
    }
    c->held = use != own;
    double spacing = pm_coverage_level_spacing(use);
    if (c->cov.spacing != spacing) {
        pm_area_samples_t a;
        /* A side within two kernel widths of a solid's far face is what a kernel would count: the
         * widest kernel of the level, so that the samples depend on the level alone. */
        double reach = 2.0 * PM_COVERAGE_RATIO * 1.4142135623730951 * spacing;
        r = pm_area_samples_make(&c->scene, &c->rt, spacing, reach, pm_coverage_seed(spacing), PM_COVERAGE_MAX_SAMPLES,
                                 &a);
        if (r == PM_OK)
            r = pm_coverage_build(&c->cov, a.pos, a.normal, a.area, a.n, spacing);
        uint64_t hidden = a.hidden;
        pm_area_samples_free(&a);
        if (r != PM_OK)
            return r;
        c->level = use;
        pm_stage_note(st,
                      "coverage: %" PRIu64 " area samples %.3g m apart for a kernel %.3g m wide (%" PRIu64
                      " sides facing the inside of a solid left out)",
                      c->cov.samples, spacing, h, hidden);
    }
    /* The smaller side carries the division (photonmap/coverage.h): each photon's power where the
     * queries outnumber the photons (a final gather), else each query's result. A kept map keeps
     * the side it was first given. */
    c->applied = 1;
    c->per_query = in->total < (uint64_t)in->map.n;
    in->cover = c->per_query ? &c->cov : NULL;
    return c->per_query ? PM_OK : pm_coverage_apply(&c->cov, &in->map_table, &in->map, p);
}

/* The output's header keys coverage (the area samples' spacing, m) and coverage_side, when its
 * gather was corrected. */
static pm_result_t cover_header(pm_header_t *h, const cover_t *c)
{
    if (!c || !c->applied)
        return PM_OK;
    pm_result_t r = pm_header_set(h, "coverage", "%.9g", c->cov.spacing);
    return r == PM_OK ? pm_header_set(h, "coverage_side", "%s", c->per_query ? "queries" : "photons") : r;
}

/* The real pass index of o's pass on the schedule (pm_gather_pass_index). */
static double pass_index(const gather_options_t *o)
{
    return pm_gather_pass_index((uint64_t)o->pass, o->pass_photons > 0 ? (uint64_t)o->pass_photons : 0,
                                (uint64_t)o->unit_photons);
}

/* The stats both paths report once the gather is done (t_* in wall seconds; with a stream,
 * the sums over its frames). */
static void report(pm_stage_t *st, const gather_options_t *o, const pm_gather_inputs_t *in, pm_isa_t isa,
                   const pm_gather_stats_t *gs, double radius, double radius1, const char *width_from, double t_radius,
                   double t_gather, double t_write)
{
    uint64_t nq = in->q.n;
    int w = pm_isa_width(isa);
    uint32_t np = in->map.n;
    pm_gather_stage_stats(st, in, o->kernel, gs->shader_ops, t_gather, gs->cpu_s, t_write);
    pm_stage_stat_string(st, "isa", pm_isa_name(isa));
    pm_stage_stat_int(st, "packet_width", w);
    if (!o->widths)
        pm_stage_stat_double(st, "radius_m", radius);
    pm_stage_stat_string(st, "radius_from", width_from);
    if (!o->widths && o->radius == 0.0)
        pm_stage_stat_double(st, "k", o->k);
    pm_stage_stat_double(st, "shader_ops_per_s_per_thread",
                         t_gather > 0 ? (double)gs->shader_ops / t_gather / st->threads_used : 0.0);
    pm_stage_stat_int(st, "photons_visited", (int64_t)gs->nodes_visited);
    pm_stage_stat_int(st, "shade_steps", (int64_t)gs->shade_steps);
    pm_stage_stat_double(st, "active_lanes", gs->shade_steps ? (double)gs->active_lanes / gs->shade_steps : 0.0);
    pm_stage_stat_double(st, "active_lane_fraction",
                         gs->shade_steps ? (double)gs->active_lanes / gs->shade_steps / w : 0.0);
    pm_stage_stat_double(st, "straddling_lanes",
                         gs->shade_steps ? (double)gs->straddling_lanes / gs->shade_steps : 0.0);
    pm_stage_stat_double(st, "useful_lanes", gs->shade_steps ? (double)gs->shader_ops / gs->shade_steps : 0.0);
    pm_stage_stat_double(st, "radius_s", t_radius);
    if (o->pass) {
        pm_stage_stat_int(st, "pass", o->pass);
        pm_stage_stat_double(st, "radius1_m", radius1);
        pm_stage_stat_double(st, "pass_index", pass_index(o));
    }
    pm_stage_stat_double(st, "gather_cpu_s", gs->cpu_s);
    if (o->cover && o->cover->loaded) {
        const pm_coverage_t *c = &o->cover->cov;
        pm_stage_stat_double(st, "coverage_spacing_m", c->spacing);
        pm_stage_stat_int(st, "coverage_samples", (int64_t)c->samples);
        pm_stage_stat_int(st, "coverage_builds", (int64_t)c->builds);
        pm_stage_stat_double(st, "coverage_scene_s", o->cover->load_s);
        pm_stage_stat_double(st, "coverage_build_s", c->build_s);
        pm_stage_stat_int(st, "coverage_shader_ops", (int64_t)c->shader_ops);
        pm_stage_stat_int(st, "coverage_points", (int64_t)c->points);
        pm_stage_stat_string(st, "coverage_side", o->cover->per_query ? "queries" : "photons");
        pm_stage_stat_double(st, "coverage_s", c->wall_s);
        pm_stage_stat_double(st, "coverage_cpu_s", c->cpu_s);
    }
    pm_stage_note(st,
                  "%" PRIu64 " queries, %" PRIu32
                  " photons, %s, %.3g shader ops/query, %.1f M shader ops/s, %.2f of %d lanes",
                  nq, np, pm_isa_name(isa), nq ? (double)gs->shader_ops / nq : 0.0,
                  t_gather > 0 ? gs->shader_ops / t_gather * 1e-6 : 0.0,
                  gs->shade_steps ? (double)gs->active_lanes / gs->shade_steps : 0.0, w);
}

static void stats_add(pm_gather_stats_t *sum, const pm_gather_stats_t *gs)
{
    sum->shader_ops += gs->shader_ops;
    sum->shade_steps += gs->shade_steps;
    sum->active_lanes += gs->active_lanes;
    sum->straddling_lanes += gs->straddling_lanes;
    sum->nodes_visited += gs->nodes_visited;
    sum->packets += gs->packets;
    sum->cpu_s += gs->cpu_s;
}

/* --stream: one input kept, the other read a document (a frame) at a time until its end. */
static pm_result_t run_stream(pm_stage_t *st, const gather_options_t *opt, pm_isa_t isa)
{
    gather_options_t oo = *opt, *o = &oo;
    const char *width_from = "--widths";
    if (o->widths)
        return pm_error_set(PM_ERR_USAGE, "--stream needs fixed widths (variable widths are measured per map)");
    if (o->range)
        return pm_error_set(PM_ERR_USAGE, "--stream gathers whole frames: --range is for one file's shards");
    if (strcmp(st->output, "-") != 0)
        return pm_error_set(PM_ERR_USAGE,
                            "--stream writes one radiance document per frame to stdout: give -o - (not '%s')",
                            st->output);
    int by_queries = o->stream == STREAM_QUERIES;
    const char *spath = st->args.args[by_queries ? 1 : 0], *kept = st->args.args[by_queries ? 0 : 1];
    const char *sname = strcmp(spath, "-") ? spath : "stdin";
    if (!strcmp(kept, "-"))
        return pm_error_set(PM_ERR_USAGE, "--stream %s: the kept %s must be a file, not stdin", stream_names[o->stream],
                            by_queries ? "map" : "queries");
    FILE *f;
    pm_result_t r = pm_stream_open(spath, &f);
    if (r != PM_OK)
        return r;
    pm_memory_reuse(
        PM_MEMORY_STREAM_REUSE); /* a frame's arrays are allocated again for the next: its freed mappings serve them */
    pm_gather_inputs_t in;
    pm_table_t out = {0};
    pm_gather_stats_t sum = {0};
    double t_radius = 0.0, t_gather = 0.0, t_write = 0.0, t_read = 0.0, radius = o->radius, radius1 = 0.0;
    uint64_t frames = 0, queries = 0;
    char name[1200];
    r = by_queries ? pm_gather_inputs_read_map(&in, kept, 0) : pm_gather_inputs_read_queries(&in, kept);
    t_read = in.read_s;
    for (int end = 0; r == PM_OK;) {
        pm_stream_frame_name(name, sizeof name, spath, frames);
        if (by_queries)
            r = pm_gather_inputs_next_queries(&in, f, name, frames == 0, 0, &end);
        else
            r = pm_gather_inputs_next_map(&in, f, name, 0, &end);
        if (r != PM_OK || end)
            break;
        /* The first frame settles the width: the options, else the scene's, else --k measured
         * on that frame (read whole for it); the later frames keep it. */
        double t0 = pm_time_wall();
        if (frames == 0) {
            if ((r = pm_gather_inputs_scene_kernel(&in, &st->args, &radius, &o->k, &width_from)) != PM_OK)
                break;
            if (radius == 0.0 && (r = pm_gather_inputs_radius_for_k(&in, o->k, (float)o->normal_cos, &radius)) != PM_OK)
                break;
            t_radius = pm_time_wall() - t0;
            radius1 = radius;
            if (o->pass)
                radius = pm_gather_schedule_radius(radius1, pass_index(o), o->alpha);
        }
        pm_gather_params_t p = {.radius = radius,
                                .kernel = (pm_kernel_t)o->kernel,
                                .variable = 0,
                                .normal_cos = (float)o->normal_cos,
                                .isa = isa};
        pm_gather_stats_t gs;
        double tg = 0.0;
        if ((r = cover_map(st, o->cover, &in, &p, frames == 0 || !by_queries, (uint64_t)o->pass)) != PM_OK)
            break;
        if (in.stream) {
            r = pm_gather_stream(&in, &p, &gs, &tg);
        } else {
            t0 = pm_time_wall();
            r = pm_gather_inputs_run(&in, 0, in.q.n, &p, &gs);
            tg = pm_time_wall() - t0;
            if (r == PM_OK)
                r = pm_gather_check_finite(&in, "the gather");
        }
        if (r != PM_OK)
            break;
        t_gather += tg;
        t_read += in.read_s;
        stats_add(&sum, &gs);
        queries += in.q.n;
        pm_table_free(&out);
        memset(&out, 0, sizeof out);
        t0 = pm_time_wall();
        if ((r = pm_gather_output_init(&out, &in, st->argc, st->argv, o->kernel, width_names[0])) != PM_OK ||
            (r = pm_header_set(&out.hdr, "radius", "%.9g", radius)) != PM_OK ||
            (r = pm_gather_pass_header(&out.hdr, (uint64_t)o->pass, o->alpha, radius1,
                                       o->pass_photons > 0 ? (uint64_t)o->pass_photons : 0,
                                       (uint64_t)o->unit_photons)) != PM_OK ||
            (r = cover_header(&out.hdr, o->cover)) != PM_OK || (r = pm_gather_table_write(&out, st->output)) != PM_OK)
            break;
        t_write += pm_time_wall() - t0;
        frames++;
    }
    if (r == PM_OK && frames == 0)
        r = pm_error_set(PM_ERR_INPUT, "empty stream '%s': no %s document", sname,
                         by_queries ? "queries" : "photon map");
    if (r == PM_OK) {
        in.read_s = t_read;
        in.q.n = queries;
        report(st, o, &in, isa, &sum, radius, radius1, width_from, t_radius, t_gather, t_write);
        pm_stage_stat_int(st, "frames", (int64_t)frames);
        pm_stage_stat_string(st, "stream", stream_names[o->stream]);
    }
    pm_stream_close(f);
    pm_gather_inputs_free(&in);
    pm_table_free(&out);
    return r;
}

/* The pass a document of --stream pairs names (header key pass, at least 1); 0 when absent. */
static pm_result_t doc_pass(const pm_header_t *h, const char *name, uint64_t *pass_out)
{
    *pass_out = 0;
    const char *v = pm_header_get(h, "pass");
    int64_t p;
    if (!v)
        return PM_OK;
    if (pm_parse_i64(v, &p) != PM_OK || p < 1)
        return pm_error_set(PM_ERR_INPUT, "'%s': header key pass '%s' is not a pass of at least 1", name, v);
    *pass_out = (uint64_t)p;
    return PM_OK;
}

/* --stream pairs: a map document and a queries document per pass, gathered with the pass's
 * width of the schedule; a radiance document per pass to stdout. opt is main's (its option
 * addresses name the words each pass's command leaves out), argv main's. */
static pm_result_t run_pairs(pm_stage_t *st, const gather_options_t *opt, pm_isa_t isa, char **argv)
{
    gather_options_t oo = *opt, *o = &oo;
    const char *mpath = st->args.args[0], *qpath = st->args.args[1];
    FILE *mf = NULL, *qf = NULL;
    pm_result_t r;
    if (!strcmp(mpath, "-") && !strcmp(qpath, "-"))
        return pm_error_set(PM_ERR_USAGE, "--stream pairs reads two streams: MAP and QUERIES cannot both be stdin");
    if ((r = pm_stream_open(mpath, &mf)) != PM_OK)
        return r;
    if ((r = pm_stream_open(qpath, &qf)) != PM_OK) {
        pm_stream_close(mf);
        return r;
    }
    pm_memory_reuse(PM_MEMORY_STREAM_REUSE); /* a pass's arrays are allocated again for the next */
    pm_gather_inputs_t in;
    memset(&in, 0, sizeof in);
    pm_table_t out = {0};
    pm_gather_stats_t sum = {0};
    double t_radius = 0.0, t_gather = 0.0, t_write = 0.0, t_read = 0.0, radius = 0.0, radius1 = opt->radius;
    const char *width_from = opt->radius > 0.0 ? "--radius" : "--k";
    uint64_t passes = 0, queries = 0, pass = 0;
    /* the photons emitted before this pass and pass 1's: given for a stream that begins after
     * pass 1, else counted from the maps' `emitted` */
    uint64_t unit = (uint64_t)opt->unit_photons, before = opt->pass_photons > 0 ? (uint64_t)opt->pass_photons : 0;
    char mname[1200], qname[1200];
    for (;;) {
        if (opt->k_each) /* r_1 of this pass's own map (the caustic gather's, as a pass file's --k --pass P) */
            radius1 = 0.0;
        pm_stream_frame_name(mname, sizeof mname, mpath, passes);
        pm_stream_frame_name(qname, sizeof qname, qpath, passes);
        /* The map first (the queries are checked against it), read whole in place of the last. */
        double t0 = pm_time_wall();
        pm_reader_t *rd;
        if ((r = pm_reader_open_next(mf, mname, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &rd)) !=
            PM_OK)
            break;
        int qend = 0;
        if (!rd) { /* the map stream has ended: the queries must end too */
            if (getc(qf) != EOF)
                r = pm_error_set(PM_ERR_INPUT, "stream '%s' has ended at pass document %" PRIu64 " while '%s' goes on",
                                 mpath, passes, qpath);
            break;
        }
        pm_gather_map_free(&in.map);
        memset(&in.map, 0, sizeof in.map);
        pm_table_free(&in.map_table);
        in.map_path = mname;
        r = pm_table_read_from(rd, 0, UINT64_MAX, &in.map_table);
        pm_reader_close(rd);
        t_read += pm_time_wall() - t0;
        uint64_t mpass = 0, qpass = 0;
        if (r != PM_OK || (r = doc_pass(&in.map_table.hdr, mname, &mpass)) != PM_OK)
            break;
        /* r_1 unknown: the first pass's queries are read whole, for --k to measure it on. */
        int whole = radius1 == 0.0;
        if ((r = pm_gather_inputs_next_queries(&in, qf, qname, whole, 0, &qend)) != PM_OK)
            break;
        if (qend) {
            r = pm_error_set(PM_ERR_INPUT, "stream '%s' has ended at pass document %" PRIu64 " while '%s' goes on",
                             qpath, passes, mpath);
            break;
        }
        t_read += in.read_s;
        if ((r = doc_pass(&in.q_table.hdr, qname, &qpass)) != PM_OK ||
            (r = pm_gather_map_init(&in.map, &in.map_table, 0)) != PM_OK)
            break;
        pass = qpass ? qpass : mpass;
        if (!pass) {
            r = pm_error_set(PM_ERR_INPUT, "--stream pairs: neither '%s' nor '%s' names its pass (header key pass)",
                             mname, qname);
            break;
        }
        if (mpass && qpass && mpass != qpass) {
            r = pm_error_set(PM_ERR_INPUT, "--stream pairs: '%s' is pass %" PRIu64 " but '%s' is pass %" PRIu64, mname,
                             mpass, qname, qpass);
            break;
        }
        const char *ev = pm_header_get(&in.map_table.hdr, "emitted");
        int64_t emitted = 0;
        if (!ev || pm_parse_i64(ev, &emitted) != PM_OK || emitted < 1) {
            r = pm_error_set(PM_ERR_INPUT, "--stream pairs: '%s' has no photon count (header key emitted '%s')", mname,
                             ev ? ev : "absent");
            break;
        }
        if (passes == 0 && pass > 1 && (unit == 0 || opt->pass_photons < 0)) {
            r = pm_error_set(PM_ERR_INPUT,
                             "--stream pairs begins at pass %" PRIu64 ": give --unit-photons U (pass 1's photons) "
                             "and --pass-photons B (the photons of the passes before it)",
                             pass);
            break;
        }
        if (passes == 0 && pass == 1 && before > 0) {
            r = pm_error_set(PM_ERR_INPUT,
                             "--stream pairs begins at pass 1, which has no photons before it, not "
                             "--pass-photons %" PRIu64,
                             before);
            break;
        }
        if (unit == 0)
            unit = (uint64_t)emitted;
        if (radius1 == 0.0) {
            if (pass != 1 && !opt->k_each) {
                r = pm_error_set(PM_ERR_INPUT,
                                 "--stream pairs begins at pass %" PRIu64 ": r_1 is measured on pass 1, so give "
                                 "--radius R1 (the running image's radius1)",
                                 pass);
                break;
            }
            t0 = pm_time_wall();
            if ((r = pm_gather_inputs_scene_kernel(&in, &st->args, &radius1, &o->k, &width_from)) != PM_OK)
                break;
            if (radius1 == 0.0 &&
                (r = pm_gather_inputs_radius_for_k(&in, o->k, (float)o->normal_cos, &radius1)) != PM_OK)
                break;
            t_radius = pm_time_wall() - t0;
        }
        radius = pm_gather_schedule_radius(radius1, pm_gather_pass_index(pass, before, unit), o->alpha);
        pm_gather_params_t p = {.radius = radius,
                                .kernel = (pm_kernel_t)o->kernel,
                                .variable = 0,
                                .normal_cos = (float)o->normal_cos,
                                .isa = isa};
        pm_gather_stats_t gs;
        double tg = 0.0;
        if (o->cover && o->cover->plan_path) { /* this pass's line of --coverage-plan */
            int64_t ppass = 0, hold = 0;
            int pend = 0;
            if ((r = pm_passplan_next(&o->cover->plan, &ppass, &hold, &pend)) != PM_OK)
                break;
            if (pend) {
                r = pm_error_set(PM_ERR_INPUT, "--coverage-plan '%s' has ended before pass %" PRIu64,
                                 o->cover->plan_path, pass);
                break;
            }
            if (ppass != (int64_t)pass) {
                r = pm_error_set(PM_ERR_INPUT,
                                 "--coverage-plan '%s' line %" PRId64 " is pass %" PRId64
                                 ", but the documents are pass %" PRIu64,
                                 o->cover->plan_path, o->cover->plan.line, ppass, pass);
                break;
            }
            if (hold > 1) {
                r = pm_error_set(PM_ERR_INPUT,
                                 "--coverage-plan '%s' line %" PRId64 ": pass %" PRId64 " %" PRId64
                                 ": expected 'PASS' or 'PASS 1' (1: keep the samples)",
                                 o->cover->plan_path, o->cover->plan.line, ppass, hold);
                break;
            }
            o->cover->hold = hold == 1;
        }
        if ((r = cover_map(st, o->cover, &in, &p, 1, pass)) != PM_OK)
            break;
        if (in.stream) {
            r = pm_gather_stream(&in, &p, &gs, &tg);
        } else {
            t0 = pm_time_wall();
            r = pm_gather_inputs_run(&in, 0, in.q.n, &p, &gs);
            tg = pm_time_wall() - t0;
            if (r == PM_OK)
                r = pm_gather_check_finite(&in, "the gather");
        }
        if (r != PM_OK)
            break;
        t_gather += tg;
        stats_add(&sum, &gs);
        queries += in.q.n;
        /* The command of this pass alone: --pass P for --stream pairs, and after pass 1 (or
         * with r_1 given) --radius r_1 for --radius and --k; --coverage-level L for a pass the
         * plan held at the samples of the pass before. */
        char pw[32], rw[40], bw[32], uw[32], lw[32];
        snprintf(pw, sizeof pw, "%" PRIu64, pass);
        snprintf(rw, sizeof rw, "%.9g", radius1);
        snprintf(bw, sizeof bw, "%" PRIu64, before);
        snprintf(uw, sizeof uw, "%" PRIu64, unit);
        int keep_k = (pass == 1 || opt->k_each) && opt->radius == 0.0, held = o->cover && o->cover->held;
        if (held)
            snprintf(lw, sizeof lw, "%d", o->cover->level);
        char *add[] = {"--pass", pw, "--pass-photons", bw, "--unit-photons", uw, "--radius", rw, NULL, NULL};
        int nadd = keep_k ? 6 : 8;
        if (held) {
            add[nadd] = "--coverage-level";
            add[nadd + 1] = lw;
            nadd += 2;
        }
        const void *drop[] = {&opt->stream, &opt->k_each, &opt->pass_photons, &opt->unit_photons, &opt->radius,
                              &opt->k,      NULL};
        size_t ndrop = keep_k ? 4 : 6;
        if (o->cover && o->cover->plan_path) /* the plan's path is the stream's alone */
            drop[ndrop++] = &o->cover->plan_path;
        int argc1;
        char **argv1 = NULL;
        if ((r = pm_stage_pass_command(st, argv, drop, ndrop, add, nadd, &argc1, &argv1)) != PM_OK)
            break;
        pm_table_free(&out);
        memset(&out, 0, sizeof out);
        t0 = pm_time_wall();
        if ((r = pm_gather_output_init(&out, &in, argc1, argv1, o->kernel, width_names[0])) == PM_OK &&
            (r = pm_header_set(&out.hdr, "radius", "%.9g", radius)) == PM_OK &&
            (r = pm_gather_pass_header(&out.hdr, pass, o->alpha, radius1, before, unit)) == PM_OK &&
            (r = cover_header(&out.hdr, o->cover)) == PM_OK)
            r = pm_gather_table_write(&out, st->output);
        free(argv1);
        if (r != PM_OK)
            break;
        t_write += pm_time_wall() - t0;
        o->pass_photons = (int64_t)before;
        o->unit_photons = (int64_t)unit;
        before += (uint64_t)emitted;
        passes++;
        /* pass 1 is out: load --coverage's scene while pass 2 is traced (cover_t) */
        if (o->cover && pass == 1 && (r = cover_load(st, o->cover)) != PM_OK)
            break;
    }
    if (r == PM_OK && passes == 0)
        r = pm_error_set(PM_ERR_INPUT, "empty streams '%s' and '%s': no pass", mpath, qpath);
    if (r == PM_OK) {
        in.read_s = t_read;
        in.q.n = queries;
        o->pass = (int64_t)pass;
        report(st, o, &in, isa, &sum, radius, radius1, width_from, t_radius, t_gather, t_write);
        pm_stage_stat_int(st, "passes", (int64_t)passes);
        pm_stage_stat_string(st, "stream", stream_names[o->stream]);
    }
    pm_stream_close(mf);
    pm_stream_close(qf);
    pm_gather_inputs_free(&in);
    pm_table_free(&out);
    return r;
}

static pm_result_t run(pm_stage_t *st, const gather_options_t *opt, char **argv)
{
    gather_options_t oo = *opt, *o = &oo; /* the kernel width may come from the queries header */
    const char *width_from = "--widths";
    pm_gather_inputs_t in;
    pm_table_t out = {0};
    pm_isa_t isa;
    pm_result_t r = pm_isa_parse(o->isa, &isa);
    if (r != PM_OK)
        return r;
    if (o->k_each && o->stream != STREAM_PAIRS)
        return pm_error_set(PM_ERR_USAGE, "--k-each-pass measures each pass's width: it needs --stream pairs");
    if (o->k_each && o->radius > 0.0)
        return pm_error_set(PM_ERR_USAGE, "--k-each-pass measures r_1 by --k: not with --radius %g", o->radius);
    if (o->stream == STREAM_PAIRS) {
        if (o->widths || o->range || o->pass || strcmp(st->output, "-") != 0)
            return pm_error_set(PM_ERR_USAGE, "--stream pairs gathers whole passes of one width to stdout: no "
                                              "--widths variable, --range or --pass, and -o -");
        if (o->pass_photons >= 0 && o->unit_photons == 0)
            return pm_error_set(PM_ERR_USAGE, "--pass-photons %" PRId64 " needs --unit-photons U (pass 1's photons)",
                                o->pass_photons);
        return run_pairs(st, opt, isa, argv);
    }
    if ((r = pm_gather_pass_check(o->pass, o->pass_photons, o->unit_photons)) != PM_OK)
        return r;
    if (o->stream != STREAM_NONE)
        return run_stream(st, o, isa);
    if (o->radius == 0.0 && o->k <= 0.0 && !o->widths)
        return pm_error_set(PM_ERR_USAGE, "give --radius R or --k K (photons per query) for a fixed kernel width");
    if (o->pass && o->widths)
        return pm_error_set(PM_ERR_USAGE, "--pass %" PRId64 " needs fixed widths: the schedule shrinks one width",
                            o->pass);
    /* The whole file is read for a shard; else the queries stream through a chunk at a time,
     * unless --k must measure the width on all of them first. */
    r = o->range ? pm_gather_inputs_read(&in, st->args.args[0], st->args.args[1], o->range, o->widths)
                 : pm_gather_inputs_open(&in, st->args.args[0], st->args.args[1], o->widths);
    if (r != PM_OK)
        goto done;
    if (!o->widths && (r = pm_gather_inputs_scene_kernel(&in, &st->args, &o->radius, &o->k, &width_from)) != PM_OK)
        goto done;
    if (in.stream && !o->widths && o->radius == 0.0 && (r = pm_gather_inputs_read_rest(&in, o->widths)) != PM_OK)
        goto done;

    /* The kernel width. */
    double radius = o->radius, t_radius = 0.0, t0;
    if (!o->widths && radius == 0.0) {
        t0 = pm_time_wall();
        if ((r = pm_gather_inputs_radius_for_k(&in, o->k, (float)o->normal_cos, &radius)) != PM_OK)
            goto done;
        t_radius = pm_time_wall() - t0;
    }
    double radius1 = radius;
    if (o->pass)
        radius = pm_gather_schedule_radius(radius1, pass_index(o), o->alpha);

    pm_gather_params_t p = {.radius = radius,
                            .kernel = (pm_kernel_t)o->kernel,
                            .variable = o->widths,
                            .normal_cos = (float)o->normal_cos,
                            .isa = isa};
    pm_gather_stats_t gs;
    double t_gather;
    if (o->cover && o->widths) {
        r = pm_error_set(PM_ERR_USAGE, "--coverage needs fixed widths (one kernel width for every query)");
        goto done;
    }
    if ((r = cover_map(st, o->cover, &in, &p, 1, (uint64_t)o->pass)) != PM_OK)
        goto done;
    if (in.stream) {
        if ((r = pm_gather_stream(&in, &p, &gs, &t_gather)) != PM_OK)
            goto done;
    } else {
        t0 = pm_time_wall();
        r = pm_gather_inputs_run(&in, 0, in.q.n, &p, &gs);
        t_gather = pm_time_wall() - t0;
        if (r != PM_OK || (r = pm_gather_check_finite(&in, "the gather")) != PM_OK)
            goto done;
    }
    pm_header_t *h = &out.hdr;
    if ((r = pm_gather_output_init(&out, &in, st->argc, st->argv, o->kernel, width_names[o->widths])) != PM_OK)
        goto done;
    if (!o->widths && (r = pm_header_set(h, "radius", "%.9g", radius)) != PM_OK)
        goto done;
    if ((r = pm_gather_pass_header(h, (uint64_t)o->pass, o->alpha, radius1,
                                   o->pass_photons > 0 ? (uint64_t)o->pass_photons : 0, (uint64_t)o->unit_photons)) !=
        PM_OK)
        goto done;
    if ((r = cover_header(h, o->cover)) != PM_OK)
        goto done;
    t0 = pm_time_wall();
    if ((r = pm_gather_output_write(&out, &in, st->output)) != PM_OK)
        goto done;
    double t_write = pm_time_wall() - t0;

    report(st, o, &in, isa, &gs, radius, radius1, width_from, t_radius, t_gather, t_write);
done:
    pm_gather_inputs_free(&in);
    pm_table_free(&out);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    cover_t cover;
    memset(&cover, 0, sizeof cover);
    cover.level_opt = INT64_MAX; /* from level_text */
    gather_options_t o = {.radius = 0.0,
                          .k = 50.0,
                          .kernel = 1,
                          .widths = 0,
                          .normal_cos = 0.5,
                          .isa = "auto",
                          .alpha = PM_PASS_ALPHA_DEFAULT,
                          .pass_photons = -1};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"radius", 'r', PM_OPT_DOUBLE, &o.radius, "R", "kernel width h, m (0: from --k)", 0, 1e18, NULL},
        {"k", 'k', PM_OPT_DOUBLE, &o.k, "K", "choose h so that about K photons fall in a query's kernel on average", 0,
         1e7, NULL},
        {"kernel", 0, PM_OPT_CHOICE, &o.kernel, "K", "kernel shape, normalized over the plane", 0, 0, pm_kernel_names},
        {"widths", 0, PM_OPT_CHOICE, &o.widths, "W",
         "fixed: one h for all; variable: each photon's own h (a map built with --width-k)", 0, 0, width_names},
        {"isa", 0, PM_OPT_STRING, &o.isa, "ISA", "auto, scalar, sse4 (4 lanes), avx2 (8) or avx512 (16)", 1, 0, NULL},
        PM_GATHER_COMMON_OPTIONS(o.normal_cos, o.range),
        PM_GATHER_PASS_OPTIONS(o.pass, o.alpha, o.pass_photons, o.unit_photons),
        {"coverage", 0, PM_OPT_STRING, &cover.path, "SCENE",
         "divide each query's estimate by the part of its kernel that is surface, measured on area samples of SCENE "
         "(the queries' own scene): no darkening where the kernel overhangs an edge or reaches past a corner "
         "(docs/programs/simd-gather.md, \"Coverage\")",
         1, 0, NULL},
        {"stream", 0, PM_OPT_CHOICE, &o.stream, "WHICH",
         "none; queries: keep MAP, gather each queries document of the stream QUERIES (a frame each); map: keep "
         "QUERIES, gather them against each map document of the stream MAP; pairs: MAP and QUERIES both streams, a "
         "document of each per progressive pass, gathered with that pass's width of the schedule; one radiance "
         "document per frame or pass to stdout",
         1, 0, stream_names},
        {"coverage-level", 0, PM_OPT_STRING, &cover.level_text, "L",
         "with --coverage: the area samples of spacing level L (2^(L/2) m apart), the kernel's own level or one "
         "coarser (a pass pm-render held at the samples it had; its command records it); not with --stream pairs",
         1, 0, NULL},
        {"coverage-plan", 0, PM_OPT_STRING, &cover.plan_path, "FILE",
         "with --stream pairs and --coverage: a line 'PASS [1]' per pass, read before the pass is gathered; 1 keeps "
         "the area samples of the pass before when they are one level coarser than the kernel's own (pm-render's TIME "
         "planner, when a new level's sampling does not fit the budget)",
         1, 0, NULL},
        {"k-each-pass", 0, PM_OPT_FLAG, &o.k_each, NULL,
         "with --stream pairs: measure r_1 by --k on every pass's documents, not on pass 1 alone (each pass then is "
         "the bytes of its own --k K --pass P; the caustic gather of progressive passes)",
         0, 0, NULL},
        {0},
    };
    static const char about[] = "Gather photons at every query with SIMD packets and the sample-point estimator; write "
                                "the indirect radiance per pixel. QUERIES may be - for stdin.";
    const pm_cli_t cli = {"simd-gather", "[options] MAP QUERIES -o RADIANCE", about, options, 2, 2, "radiance"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    pm_result_t r = PM_OK;
    if (cover.path) { /* loaded when first used; a file that cannot be read is refused now */
        o.cover = &cover;
        if ((r = pm_scene_check_regular(cover.path, "scene")) != PM_OK)
            pm_error_prefix("--coverage");
    }
    if (r == PM_OK && cover.level_text &&
        (pm_parse_i64(cover.level_text, &cover.level_opt) != PM_OK || cover.level_opt < -4000 ||
         cover.level_opt > 4000))
        r = pm_error_set(PM_ERR_USAGE, "--coverage-level '%s': expected a whole number from -4000 to 4000 (a level)",
                         cover.level_text);
    else if (r == PM_OK && (cover.level_text || cover.plan_path) && !cover.path)
        r = pm_error_set(PM_ERR_USAGE, "--coverage-level and --coverage-plan need --coverage");
    else if (r == PM_OK && cover.level_text && o.stream == STREAM_PAIRS)
        r = pm_error_set(PM_ERR_USAGE,
                         "--coverage-level is one pass's level: a stream of passes takes --coverage-plan");
    else if (r == PM_OK && cover.plan_path && o.stream != STREAM_PAIRS)
        r = pm_error_set(PM_ERR_USAGE, "--coverage-plan needs --stream pairs (a line per pass)");
    else if (r == PM_OK && cover.plan_path)
        r = pm_passplan_open(&cover.plan, NULL, cover.plan_path);
    rc = pm_stage_end(&st, r != PM_OK ? r : run(&st, &o, argv));
    if (cover.traced)
        pm_rt_destroy(&cover.rt);
    if (cover.loaded)
        pm_scene_free(&cover.scene);
    pm_coverage_free(&cover.cov);
    pm_passplan_close(&cover.plan);
    return rc;
}
