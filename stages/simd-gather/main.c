/* simd-gather: photon map + gather points -> indirect radiance buffer (the paper,
 * sections 3, 5.3 and 7).
 *
 * Every query receives the sample-point estimate of the photons around it, multiplied by
 * its weight, and each query's result is added to its pixel. Packets of W consecutive
 * queries (W = 16, 8, 4 or 1 by --isa) walk the KD-tree together; hilbert-sort is what
 * makes consecutive queries close, so that the lanes of a packet stay live together. The
 * sums per query are in double, and queries are added to pixels in file order, so the
 * buffer is the same for any thread count. common/gather.c does the work. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../common/gather.h"
#include "../../common/memory.h"
#include "../../common/stage.h"
#include "../../formats/formats.h"

static const char *const kernel_names[] = {"uniform", "epanechnikov", NULL};
static const char *const width_names[] = {"fixed", "variable", NULL};

typedef struct {
    double radius;
    double k;
    int kernel, widths;
    double normal_cos;
    const char *isa;
    const char *range;
} gather_options_t;

/* The queries the radius of --k is measured on: those of the pixels a hash of the pixel
 * index picks, about `want` in all. Chosen by pixel, not by position in the file, so that
 * the radius is the same whatever order hilbert-sort (or none) gave the queries, and the
 * same for every shard of a file. */
static inline int sample_pixel(uint32_t pixel, uint64_t total, uint32_t want)
{
    uint32_t h = pixel * 2654435761u; /* Knuth's multiplicative hash: spreads pixels evenly */
    h ^= h >> 16;
    return total <= want || (double)h < (double)want / (double)total * 4294967296.0;
}

typedef struct {
    float *pos, *nor;
    uint32_t n, cap;
} sample_t;

static int sample_add(sample_t *s, const float *p, const float *n)
{
    if (s->n == s->cap) {
        uint32_t cap = s->cap ? 2 * s->cap : 1024;
        float *np = realloc(s->pos, (size_t)cap * 12), *nn = np ? realloc(s->nor, (size_t)cap * 12) : NULL;
        if (np)
            s->pos = np;
        if (!nn)
            return -1;
        s->nor = nn;
        s->cap = cap;
    }
    memcpy(&s->pos[3 * (size_t)s->n], p, 12);
    memcpy(&s->nor[3 * (size_t)s->n], n, 12);
    s->n++;
    return 0;
}

/* The sample from the queries in memory (the whole file was read). */
static pm_result_t sample_table(const pm_gather_queries_t *q, uint32_t want, sample_t *s)
{
    for (uint64_t i = 0; i < q->n; i++)
        if (sample_pixel(q->pixel[i], q->n, want) && sample_add(s, &q->pos[3 * i], &q->normal[3 * i]) != 0)
            return pm_error_set(PM_ERR_NOMEM, "out of memory for the radius sample");
    return PM_OK;
}

/* The same sample read from the whole file in one streaming pass (a shard holds only its
 * range in memory). */
static pm_result_t sample_file(const char *path, uint32_t want, sample_t *s)
{
    pm_reader_t *r;
    pm_result_t res = pm_reader_open(path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &r);
    if (res != PM_OK)
        return res;
    const pm_header_t *h = pm_reader_header(r);
    uint64_t n = h->count;
    uint32_t rs = h->record_size, op = pm_schema_offset(&pm_queries_schema, h->channels, PM_QUERY_POSITION),
             on = pm_schema_offset(&pm_queries_schema, h->channels, PM_QUERY_NORMAL),
             ox = pm_schema_offset(&pm_queries_schema, h->channels, PM_QUERY_PIXEL);
    const uint64_t chunk = 65536;
    unsigned char *buf = malloc(chunk * rs);
    if (!buf) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory sampling '%s'", path);
    } else {
        uint64_t got;
        while (res == PM_OK && (res = pm_reader_read(r, buf, chunk, &got)) == PM_OK && got)
            for (uint64_t i = 0; i < got && res == PM_OK; i++) {
                const unsigned char *rec = buf + i * rs;
                uint32_t px;
                float p[3], nn[3];
                memcpy(&px, rec + ox, 4);
                if (!sample_pixel(px, n, want))
                    continue;
                memcpy(p, rec + op, 12);
                memcpy(nn, rec + on, 12);
                if (sample_add(s, p, nn) != 0)
                    res = pm_error_set(PM_ERR_NOMEM, "out of memory for the radius sample");
            }
        if (res == PM_OK)
            res = pm_reader_finish(r, NULL);
    }
    pm_reader_close(r);
    free(buf);
    return res;
}

static pm_result_t run(pm_stage_t *st, const gather_options_t *o)
{
    const char *map_path = st->args.args[0], *q_path = st->args.args[1];
    pm_table_t mt = {0}, qt = {0}, out = {0};
    pm_gather_map_t map = {0};
    pm_gather_queries_t q = {0};
    pm_material_t *mats = NULL;
    double *per_query = NULL;
    pm_isa_t isa;
    pm_result_t r = pm_isa_parse(o->isa, &isa);
    if (r != PM_OK)
        return r;
    uint64_t begin = 0, end = UINT64_MAX;
    int ranged = o->range != NULL;
    if (ranged && (r = pm_args_parse_range(o->range, &begin, &end)) != PM_OK)
        return r;
    if (o->radius == 0.0 && o->k <= 0.0 && !o->widths)
        return pm_error_set(PM_ERR_USAGE, "give --radius R or --k K (photons per query) for a fixed kernel width");

    double t0 = pm_time_wall();
    if ((r = pm_table_read(map_path, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &mt)) != PM_OK)
        return r;
    /* The queries: only [begin, end) is kept, the whole file is checked. */
    pm_reader_t *rd;
    if ((r = pm_reader_open(q_path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &rd)) != PM_OK)
        goto done;
    uint64_t total_queries = pm_reader_header(rd)->count;
    r = pm_table_read_from(rd, begin, end, &qt);
    pm_reader_close(rd);
    if (r != PM_OK)
        goto done;
    double t_read = pm_time_wall() - t0;
    if (begin > total_queries)
        begin = total_queries;
    if (end > total_queries)
        end = total_queries;
    const char *wk = pm_header_get(&qt.hdr, "weights");
    if (!wk || strcmp(wk, "lambertian-brdf-folded") != 0) {
        r = pm_error_set(PM_ERR_INPUT, "queries '%s' do not say which weight contract they follow (weights=%s; "
                         "expected lambertian-brdf-folded, docs/formats.md 3.3)", q_path, wk ? wk : "missing");
        goto done;
    }
    const char *sm = pm_header_get(&mt.hdr, "SCENE"), *sq = pm_header_get(&qt.hdr, "SCENE");
    if (sm && sq && strcmp(sm, sq) != 0) {
        r = pm_error_set(PM_ERR_INPUT, "photon map '%s' is of scene '%s' but queries '%s' are of scene '%s'", map_path,
                         sm, q_path, sq);
        goto done;
    }
    uint32_t width, height;
    if ((r = pm_header_get_image_size(&qt.hdr, q_path, &width, &height)) != PM_OK)
        goto done;
    if ((r = pm_gather_map_init(&map, &mt, o->widths)) != PM_OK ||
        (r = pm_gather_queries_init(&q, &qt, q_path, &mats)) != PM_OK)
        goto done;

    /* The kernel width. */
    double radius = o->radius, t_radius = 0.0;
    if (!o->widths && radius == 0.0) {
        t0 = pm_time_wall();
        const uint32_t samples = 2000;
        sample_t smp = {0};
        if (!ranged || (begin == 0 && end == total_queries)) {
            r = sample_table(&q, samples, &smp);
        } else if (strcmp(q_path, "-") == 0) {
            r = pm_error_set(PM_ERR_USAGE, "--k with --range needs the queries as a file, not stdin, so that every "
                             "shard finds the same radius; or give --radius");
        } else {
            r = sample_file(q_path, samples, &smp);
        }
        if (r == PM_OK) {
            pm_gather_queries_t sq_all = {.n = smp.n, .pos = smp.pos, .normal = smp.nor};
            radius = pm_gather_radius_for_k(&map, &sq_all, o->k, (float)o->normal_cos, smp.n);
        }
        free(smp.pos), free(smp.nor);
        if (r != PM_OK)
            goto done;
        t_radius = pm_time_wall() - t0;
        if (!(radius > 0.0) && map.n && q.n) {
            r = pm_error_set(PM_ERR_INPUT, "no radius gives %g photons per query", o->k);
            goto done;
        }
        if (!(radius > 0.0))
            radius = 1.0; /* nothing to gather: any width gives zero */
    }

    pm_gather_params_t p = {.radius = radius, .kernel = (pm_kernel_t)o->kernel, .variable = o->widths,
                            .normal_cos = (float)o->normal_cos, .isa = isa};
    uint64_t nq = end - begin;
    per_query = pm_alloc_aligned((nq ? nq : 1) * 3 * sizeof *per_query);
    if (!per_query) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " query results", nq);
        goto done;
    }
    pm_gather_stats_t gs;
    t0 = pm_time_wall();
    /* The table holds only [begin, end): its rows are the range, from 0. */
    const uint64_t row0 = 0;
    r = pm_gather_run(&map, &q, row0, row0 + nq, &p, per_query, &gs);
    double t_gather = pm_time_wall() - t0;
    if (r != PM_OK)
        goto done;

    /* Queries into pixels, in file order: the same sums for any thread count. */
    if ((r = pm_table_alloc(&out, &pm_radiance_schema, pm_schema_required(&pm_radiance_schema),
                            (uint64_t)width * height)) != PM_OK)
        goto done;
    double *px = out.col[PM_RADIANCE_RGB];
    for (uint64_t i = 0; i < nq; i++) {
        uint32_t pi = q.pixel[row0 + i];
        for (int k = 0; k < 3; k++)
            px[3 * (size_t)pi + k] += per_query[3 * i + k];
    }
    pm_header_t *h = &out.hdr;
    memcpy(h->bounds, qt.hdr.bounds, sizeof h->bounds);
    if ((r = pm_header_inherit(h, &mt.hdr)) != PM_OK || (r = pm_header_inherit(h, &qt.hdr)) != PM_OK ||
        (r = pm_header_add_input(h, map_path, mt.checksum)) != PM_OK ||
        (r = pm_header_add_input(h, q_path, qt.checksum)) != PM_OK ||
        (r = pm_header_add_command(h, st->argc, st->argv)) != PM_OK ||
        (r = pm_header_set(h, "width", "%" PRIu32, width)) != PM_OK ||
        (r = pm_header_set(h, "height", "%" PRIu32, height)) != PM_OK ||
        (r = pm_header_set(h, "component", "indirect")) != PM_OK ||
        (r = pm_header_set(h, "kernel", "%s", kernel_names[o->kernel])) != PM_OK ||
        (r = pm_header_set(h, "widths", "%s", width_names[o->widths])) != PM_OK)
        goto done;
    if (!o->widths && (r = pm_header_set(h, "radius", "%.9g", radius)) != PM_OK)
        goto done;
    if (ranged && (r = pm_header_set(h, "range", "%" PRIu64 ":%" PRIu64, begin, end)) != PM_OK)
        goto done;
    t0 = pm_time_wall();
    if ((r = pm_table_write(&out, st->output)) != PM_OK)
        goto done;
    double t_write = pm_time_wall() - t0;

    int w = pm_isa_width(isa);
    st->items = nq;
    pm_stage_stat_string(st, "isa", pm_isa_name(isa));
    pm_stage_stat_int(st, "packet_width", w);
    pm_stage_stat_int(st, "queries", (int64_t)nq);
    pm_stage_stat_int(st, "photons", map.n);
    if (!o->widths)
        pm_stage_stat_double(st, "radius_m", radius);
    pm_stage_stat_string(st, "kernel", kernel_names[o->kernel]);
    pm_stage_stat_int(st, "shader_ops", (int64_t)gs.shader_ops);
    pm_stage_stat_double(st, "shader_ops_per_s", t_gather > 0 ? (double)gs.shader_ops / t_gather : 0.0);
    pm_stage_stat_double(st, "shader_ops_per_s_per_thread",
                         t_gather > 0 ? (double)gs.shader_ops / t_gather / st->threads_used : 0.0);
    pm_stage_stat_double(st, "shader_ops_per_cpu_s", gs.cpu_s > 0 ? (double)gs.shader_ops / gs.cpu_s : 0.0);
    pm_stage_stat_double(st, "shader_ops_per_query", nq ? (double)gs.shader_ops / nq : 0.0);
    pm_stage_stat_int(st, "photons_visited", (int64_t)gs.nodes_visited);
    pm_stage_stat_int(st, "shade_steps", (int64_t)gs.shade_steps);
    pm_stage_stat_double(st, "active_lanes", gs.shade_steps ? (double)gs.active_lanes / gs.shade_steps : 0.0);
    pm_stage_stat_double(st, "active_lane_fraction",
                         gs.shade_steps ? (double)gs.active_lanes / gs.shade_steps / w : 0.0);
    pm_stage_stat_double(st, "straddling_lanes", gs.shade_steps ? (double)gs.straddling_lanes / gs.shade_steps : 0.0);
    pm_stage_stat_double(st, "useful_lanes", gs.shade_steps ? (double)gs.shader_ops / gs.shade_steps : 0.0);
    pm_stage_stat_double(st, "read_s", t_read);
    pm_stage_stat_double(st, "radius_s", t_radius);
    pm_stage_stat_double(st, "gather_s", t_gather);
    pm_stage_stat_double(st, "write_s", t_write);
    pm_stage_note(st, "%" PRIu64 " queries, %" PRIu32 " photons, %s, %.3g shader ops/query, %.1f M shader ops/s, %.2f of %d lanes",
                  nq, map.n, pm_isa_name(isa), nq ? (double)gs.shader_ops / nq : 0.0,
                  t_gather > 0 ? gs.shader_ops / t_gather * 1e-6 : 0.0,
                  gs.shade_steps ? (double)gs.active_lanes / gs.shade_steps : 0.0, w);
done:
    pm_free_aligned(per_query);
    free(mats);
    pm_gather_map_free(&map);
    pm_table_free(&out);
    pm_table_free(&qt);
    pm_table_free(&mt);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    gather_options_t o = {.radius = 0.0, .k = 50.0, .kernel = 1, .widths = 0, .normal_cos = 0.5, .isa = "auto"};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"radius", 'r', PM_OPT_DOUBLE, &o.radius, "R", "kernel width h, m (0: from --k)", 0, 1e18, NULL},
        {"k", 'k', PM_OPT_DOUBLE, &o.k, "K", "choose h so that about K photons fall in a query's kernel on average", 0,
         1e7, NULL},
        {"kernel", 0, PM_OPT_CHOICE, &o.kernel, "K", "kernel shape, normalized over the plane", 0, 0, kernel_names},
        {"widths", 0, PM_OPT_CHOICE, &o.widths, "W",
         "fixed: one h for all; variable: each photon's own h (a map built with --width-k)", 0, 0, width_names},
        {"normal-cos", 0, PM_OPT_DOUBLE, &o.normal_cos, "C",
         "a photon counts when the cosine between its normal and the query's is at least C", -1, 1, NULL},
        {"isa", 0, PM_OPT_STRING, &o.isa, "ISA", "auto, scalar, sse4 (4 lanes), avx2 (8) or avx512 (16)", 1, 0, NULL},
        {"range", 0, PM_OPT_STRING, &o.range, "B:E", "gather only queries [B, E) (shards; composite adds them)", 1, 0,
         NULL},
        {0},
    };
    const pm_cli_t cli = {"simd-gather", "[options] MAP QUERIES -o RADIANCE",
                          "Gather photons at every query with SIMD packets and the sample-point estimator; write "
                          "the indirect radiance per pixel. QUERIES may be - for stdin.",
                          options, 2, 2};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
