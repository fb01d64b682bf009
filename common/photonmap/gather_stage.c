/* gather_stage.c: reading, kernel width and output shared by the gather stages
 * (simd-gather, knn-gather, reverse-gather); see gather_stage.h. */
#include "photonmap/gather_stage.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/args.h"
#include "base/memory.h"
#include "base/timer.h"

const char *const pm_kernel_names[] = {"uniform", "epanechnikov", NULL};

/* After the map and the queries' header are in: the checks of both headers, the views (the
 * map's only when map_too) and per_query for the rows q_table holds (rows: how many it has
 * room for). */
static pm_result_t inputs_setup(pm_gather_inputs_t *in, int variable, uint64_t rows, int map_too)
{
    pm_result_t r;
    const pm_header_t *mh = &in->map_table.hdr, *qh = &in->q_table.hdr;
    const char *wk = pm_header_get(qh, "weights");
    if (!wk || strcmp(wk, "lambertian-brdf-folded") != 0)
        return pm_error_set(PM_ERR_INPUT,
                            "queries '%s' do not say which weight contract they follow (weights=%s; "
                            "expected lambertian-brdf-folded, docs/formats.md 3.3)",
                            in->q_path, wk ? wk : "missing");
    const char *sm = pm_header_get(mh, "SCENE"), *sq = pm_header_get(qh, "SCENE");
    if (sm && sq && !pm_scene_key_same_scene(sm, sq))
        return pm_error_set(PM_ERR_INPUT, "photon map '%s' is of scene '%s' but queries '%s' are of scene '%s'",
                            in->map_path, sm, in->q_path, sq);
    /* Caustic queries (the first diffuse hits) gather the caustic map and nothing else does:
     * either one against the other kind counts light twice or not at all (docs/accuracy.md). */
    const char *mk = pm_header_get(mh, "map"), *qk = pm_header_get(qh, "kind");
    int cmap = mk && !strcmp(mk, "caustic"), cq = qk && !strcmp(qk, "caustic");
    if (cmap != cq)
        return pm_error_set(PM_ERR_INPUT,
                            "photon map '%s' is %s but queries '%s' are %s: a caustic map gathers the "
                            "caustic queries (trace-gather-points --caustic-queries) and only them",
                            in->map_path, cmap ? "a caustic map" : "not a caustic map", in->q_path,
                            cq ? "caustic queries" : "not caustic queries");
    in->caustic = cq;
    /* Queries with secondary direct light (trace-gather-points --secondary-direct) have the direct
     * light at their points in the direct buffer, but for an area light's near field, and need a
     * global map without the first hits that light stands for (trace-photons --indirect-only,
     * which keeps the near field's); other queries need every first hit, or in direct-vis mode
     * none (docs/accuracy.md). */
    const char *qd = pm_header_get(qh, "secondary_direct"), *qm = pm_header_get(qh, "mode"),
               *mi = pm_header_get(mh, "indirect_only");
    /* 1 or 2: the rule of which light the gather points sample (pm_light_gather_rule); any other
     * value is a rule this pmtk does not know, refused rather than read as none */
    if (qd && strcmp(qd, "1") && strcmp(qd, "2"))
        return pm_error_set(PM_ERR_INPUT,
                            "queries '%s' say secondary_direct='%s': not a rule of this pmtk (1 or 2: which light "
                            "the gather points sample)",
                            in->q_path, qd);
    if (mi && strcmp(mi, "1") && strcmp(mi, "2"))
        return pm_error_set(PM_ERR_INPUT,
                            "photon map '%s' says indirect_only='%s': not a rule of this pmtk (1 or 2: which first "
                            "hits it leaves to the gather points' light samples)",
                            in->map_path, mi);
    int sd = qd ? qd[0] - '0' : 0, io = mi ? mi[0] - '0' : 0;
    int imap = mk && !strcmp(mk, "indirect");
    const char *map = NULL, *queries = NULL; /* what each holds, when they disagree */
    if (cq || cmap)
        map = NULL;
    else if (sd && io && sd != io)
        return pm_error_set(PM_ERR_INPUT,
                            "photon map '%s' says indirect_only=%d but queries '%s' say secondary_direct=%d: made "
                            "under different rules of which light the gather points sample (pmtk versions: rule 2 "
                            "leaves a constant sky to the map); make both again with this pmtk",
                            in->map_path, io, in->q_path, sd);
    else if (sd && !io && !imap)
        map = "holds the first-hit photons of every light",
        queries = "have secondary direct light: the direct light at the gather points would count twice "
                  "(trace-photons --indirect-only)";
    else if (sd && imap)
        map = "holds no first-hit photons",
        queries = "have secondary direct light, which leaves an area light's near field to the map: that light "
                  "would be lost (trace-photons --indirect-only, build-photonmap --map global)";
    else if (!sd && io && !imap)
        map = "lacks the first hits the gather points' light samples stand for (trace-photons --indirect-only)",
        queries = "have no secondary direct light: that light would be lost (trace-gather-points --secondary-direct)";
    else if (!sd && imap && qm && !strcmp(qm, "gather"))
        map = "holds no first-hit photons",
        queries = "are gather-mode queries without secondary direct light: the direct light at the gather points "
                  "would be lost (build-photonmap --map global)";
    if (map)
        return pm_error_set(PM_ERR_INPUT, "photon map '%s' %s but queries '%s' %s", in->map_path, map, in->q_path,
                            queries);
    if ((r = pm_header_get_image_size(qh, in->q_path, &in->width, &in->height)) != PM_OK ||
        (map_too && (r = pm_gather_map_init(&in->map, &in->map_table, variable)) != PM_OK))
        return r;
    free(in->materials);
    in->materials = NULL;
    if ((r = pm_gather_queries_init(&in->q, &in->q_table, in->q_path, &in->materials)) != PM_OK)
        return r;
    pm_free_aligned(in->per_query);
    in->per_query = pm_alloc_aligned((rows ? rows : 1) * 3 * sizeof *in->per_query);
    if (!in->per_query)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " query results", rows);
    return PM_OK;
}

pm_result_t pm_gather_inputs_read(pm_gather_inputs_t *in, const char *map_path, const char *q_path, const char *range,
                                  int variable)
{
    memset(in, 0, sizeof *in);
    in->map_path = map_path;
    in->q_path = q_path;
    in->begin = 0;
    in->end = UINT64_MAX;
    in->ranged = range != NULL;
    pm_result_t r;
    if (in->ranged && (r = pm_args_parse_range(range, &in->begin, &in->end)) != PM_OK)
        return r;
    double t0 = pm_time_wall();
    if ((r = pm_table_read(map_path, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &in->map_table)) !=
        PM_OK)
        return r;
    /* The queries: only [begin, end) is kept, the whole file is checked. */
    pm_reader_t *rd;
    if ((r = pm_reader_open(q_path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &rd)) != PM_OK)
        return r;
    in->total = pm_reader_header(rd)->count;
    r = pm_table_read_from(rd, in->begin, in->end, &in->q_table);
    pm_reader_close(rd);
    if (r != PM_OK)
        return r;
    in->read_s = pm_time_wall() - t0;
    if (in->begin > in->total)
        in->begin = in->total;
    if (in->end > in->total)
        in->end = in->total;
    return inputs_setup(in, variable, in->q_table.count, 1);
}

pm_result_t pm_gather_inputs_open(pm_gather_inputs_t *in, const char *map_path, const char *q_path, int variable)
{
    memset(in, 0, sizeof *in);
    in->map_path = map_path;
    in->q_path = q_path;
    double t0 = pm_time_wall();
    pm_result_t r =
        pm_table_read(map_path, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &in->map_table);
    if (r != PM_OK)
        return r;
    if ((r = pm_reader_open(q_path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &in->stream)) != PM_OK)
        return r;
    in->total = in->end = pm_reader_header(in->stream)->count;
    if ((r = pm_table_chunks_open(in->stream, PM_GATHER_STREAM_ROWS, &in->q_table)) != PM_OK)
        return r;
    in->read_s = pm_time_wall() - t0;
    return inputs_setup(in, variable, PM_GATHER_STREAM_ROWS, 1);
}

pm_result_t pm_gather_inputs_read_rest(pm_gather_inputs_t *in, int variable)
{
    double t0 = pm_time_wall();
    pm_table_free(&in->q_table);
    pm_result_t r = pm_table_read_from(in->stream, 0, UINT64_MAX, &in->q_table);
    pm_reader_close(in->stream);
    in->stream = NULL;
    if (r != PM_OK)
        return r;
    in->read_s += pm_time_wall() - t0;
    return inputs_setup(in, variable, in->q_table.count, 0);
}

pm_result_t pm_gather_inputs_read_map(pm_gather_inputs_t *in, const char *map_path, int variable)
{
    memset(in, 0, sizeof *in);
    in->map_path = map_path;
    double t0 = pm_time_wall();
    pm_result_t r =
        pm_table_read(map_path, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &in->map_table);
    if (r == PM_OK)
        r = pm_gather_map_init(&in->map, &in->map_table, variable);
    in->read_s = pm_time_wall() - t0;
    return r;
}

pm_result_t pm_gather_inputs_next_queries(pm_gather_inputs_t *in, FILE *f, const char *name, int whole, int variable,
                                          int *end_out)
{
    *end_out = 0;
    /* What the last document left: its reader, sums and rows. */
    pm_reader_close(in->stream);
    in->stream = NULL;
    free(in->pixels);
    in->pixels = NULL;
    pm_table_free(&in->q_table);
    memset(&in->q, 0, sizeof in->q);
    in->q_path = name;
    in->begin = 0;
    double t0 = pm_time_wall();
    pm_reader_t *rd;
    pm_result_t r = pm_reader_open_next(f, name, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &rd);
    if (r != PM_OK)
        return r;
    if (!rd) {
        *end_out = 1;
        return PM_OK;
    }
    in->total = in->end = pm_reader_header(rd)->count;
    uint64_t rows = PM_GATHER_STREAM_ROWS;
    if (whole) {
        r = pm_table_read_from(rd, 0, UINT64_MAX, &in->q_table);
        pm_reader_close(rd);
        rows = in->q_table.count;
    } else {
        in->stream = rd;
        r = pm_table_chunks_open(rd, PM_GATHER_STREAM_ROWS, &in->q_table);
    }
    in->read_s = pm_time_wall() - t0;
    return r == PM_OK ? inputs_setup(in, variable, rows, 0) : r;
}

pm_result_t pm_gather_inputs_read_queries(pm_gather_inputs_t *in, const char *q_path)
{
    memset(in, 0, sizeof *in);
    in->q_path = q_path;
    double t0 = pm_time_wall();
    pm_result_t r = pm_table_read(q_path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &in->q_table);
    in->total = in->end = in->q_table.count;
    in->read_s = pm_time_wall() - t0;
    return r;
}

pm_result_t pm_gather_inputs_next_map(pm_gather_inputs_t *in, FILE *f, const char *name, int variable, int *end_out)
{
    *end_out = 0;
    pm_gather_map_free(&in->map);
    memset(&in->map, 0, sizeof in->map);
    pm_table_free(&in->map_table);
    in->map_path = name;
    double t0 = pm_time_wall();
    pm_reader_t *rd;
    pm_result_t r = pm_reader_open_next(f, name, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &rd);
    if (r != PM_OK)
        return r;
    if (!rd) {
        *end_out = 1;
        return PM_OK;
    }
    r = pm_table_read_from(rd, 0, UINT64_MAX, &in->map_table);
    pm_reader_close(rd);
    in->read_s = pm_time_wall() - t0;
    return r == PM_OK ? inputs_setup(in, variable, in->q_table.count, 1) : r;
}

pm_result_t pm_gather_inputs_run(pm_gather_inputs_t *in, uint64_t begin, uint64_t end, const pm_gather_params_t *p,
                                 pm_gather_stats_t *stats)
{
    pm_result_t r = pm_gather_run(&in->map, &in->q, begin, end, p, in->per_query, stats);
    if (r == PM_OK && in->cover)
        r = pm_coverage_apply_queries(in->cover, &in->q, begin, end, p, in->per_query);
    return r;
}

pm_result_t pm_gather_stream(pm_gather_inputs_t *in, const pm_gather_params_t *p, pm_gather_stats_t *stats,
                             double *gather_s_out)
{
    memset(stats, 0, sizeof *stats);
    *gather_s_out = 0.0;
    /* The sums grow with the pixels the queries name, not with the image the header declares:
     * a few records under a header of a large image take little memory. */
    uint64_t npx = (uint64_t)in->width * in->height, cap = 1;
    in->pixels_used = 0;
    if (!(in->pixels = calloc(3 * cap, sizeof *in->pixels)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", in->width, in->height);
    uint64_t n = 0;
    for (;;) {
        uint64_t first;
        double t0 = pm_time_wall();
        pm_result_t r = pm_table_chunks_read(in->stream, &in->q_table, PM_GATHER_STREAM_ROWS, &first);
        double t1 = pm_time_wall();
        in->read_s += t1 - t0;
        if (r != PM_OK)
            return r;
        uint64_t m = in->q_table.count;
        if (!m)
            break;
        in->q.n = m;
        pm_gather_stats_t gs;
        if ((r = pm_gather_inputs_run(in, 0, m, p, &gs)) != PM_OK)
            return r;
        *gather_s_out += pm_time_wall() - t1;
        stats->shader_ops += gs.shader_ops;
        stats->shade_steps += gs.shade_steps;
        stats->active_lanes += gs.active_lanes;
        stats->straddling_lanes += gs.straddling_lanes;
        stats->nodes_visited += gs.nodes_visited;
        stats->packets += gs.packets;
        stats->cpu_s += gs.cpu_s;
        in->begin = first; /* for the message of pm_gather_check_finite */
        if ((r = pm_gather_check_finite(in, "the gather")) != PM_OK)
            return r;
        /* Queries into pixels, in file order: the sums of pm_gather_output_init. */
        const double *pq = in->per_query;
        uint64_t need = in->pixels_used;
        for (uint64_t i = 0; i < m; i++)
            need = in->q.pixel[i] >= need ? (uint64_t)in->q.pixel[i] + 1 : need;
        if (need > cap) {
            uint64_t grow = 2 * cap < npx ? 2 * cap : npx;
            grow = grow > need ? grow : need;
            double *px = realloc(in->pixels, (size_t)grow * 3 * sizeof *px);
            if (!px)
                return pm_error_set(PM_ERR_NOMEM,
                                    "out of memory for %" PRIu64 " pixels of a %" PRIu32 "x%" PRIu32 " image", grow,
                                    in->width, in->height);
            memset(px + 3 * cap, 0, (size_t)(grow - cap) * 3 * sizeof *px);
            in->pixels = px, cap = grow;
        }
        in->pixels_used = need;
        for (uint64_t i = 0; i < m; i++) {
            uint32_t pi = in->q.pixel[i];
            for (int k = 0; k < 3; k++)
                in->pixels[3 * (size_t)pi + k] += pq[3 * i + k];
        }
        n += m;
    }
    in->q.n = n;
    in->begin = 0;
    pm_reader_close(in->stream);
    in->stream = NULL;
    return PM_OK;
}

/* A header key that holds a number in [lo, hi]: 1 when present (its value in *v), 0 when absent. */
static pm_result_t header_number(const pm_gather_inputs_t *in, const char *key, double lo, double hi, double *v,
                                 int *present)
{
    const char *s = pm_header_get(&in->q_table.hdr, key);
    *present = s != NULL;
    if (!s)
        return PM_OK;
    if (pm_parse_double(s, v) != PM_OK || !(*v >= lo && *v <= hi))
        return pm_error_set(PM_ERR_INPUT, "queries '%s': header key %s '%s' is not a number in [%g, %g]", in->q_path,
                            key, s, lo, hi);
    return PM_OK;
}

pm_result_t pm_gather_inputs_scene_kernel(const pm_gather_inputs_t *in, const pm_args_t *args, double *radius,
                                          double *k, const char **from_out)
{
    int radius_given = radius && pm_args_given(args, "radius"), k_given = pm_args_given(args, "k");
    double sr = 0.0, sk = 0.0;
    int has_r = 0, has_k = 0;
    pm_result_t r = PM_OK;
    if (radius && (r = header_number(in, "render.radius", 0.0, 1e18, &sr, &has_r)) != PM_OK)
        return r;
    if ((r = header_number(in, "render.k", 1.0, 1e7, &sk, &has_k)) != PM_OK)
        return r;
    if (radius_given && *radius > 0.0)
        *from_out = "--radius";
    else if (k_given)
        *from_out = "--k";
    else if (!radius_given && has_r && sr > 0.0)
        *radius = sr, *from_out = "render.radius";
    else if (has_k)
        *k = sk, *from_out = "render.k";
    else
        *from_out = "default k";
    /* The scene's k also stands behind a width the scene fixed, for the stats. */
    if (!k_given && has_k)
        *k = sk;
    return PM_OK;
}

void pm_gather_inputs_free(pm_gather_inputs_t *in)
{
    pm_reader_close(in->stream);
    in->stream = NULL;
    free(in->pixels);
    in->pixels = NULL;
    pm_free_aligned(in->per_query);
    free(in->materials);
    pm_gather_map_free(&in->map);
    pm_table_free(&in->q_table);
    pm_table_free(&in->map_table);
    in->materials = NULL;
    in->per_query = NULL;
}

/* ---- the sample of queries that --k measures the radius on ---- */

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

pm_result_t pm_gather_inputs_radius_for_k(const pm_gather_inputs_t *in, double k, float normal_cos, double *radius_out)
{
    const uint32_t samples = 2000;
    sample_t smp = {0};
    pm_result_t r;
    double radius = 0.0;
    if (!in->ranged || (in->begin == 0 && in->end == in->total))
        r = sample_table(&in->q, samples, &smp);
    else if (strcmp(in->q_path, "-") == 0)
        r = pm_error_set(PM_ERR_USAGE, "--k with --range needs the queries as a file, not stdin, so that every "
                                       "shard finds the same radius; or give --radius");
    else
        r = sample_file(in->q_path, samples, &smp);
    if (r == PM_OK) {
        pm_gather_queries_t all = {.n = smp.n, .pos = smp.pos, .normal = smp.nor};
        radius = pm_gather_radius_for_k(&in->map, &all, k, normal_cos, smp.n);
    }
    free(smp.pos), free(smp.nor);
    if (r != PM_OK)
        return r;
    if (!(radius > 0.0) && in->map.n && in->q.n)
        return pm_error_set(PM_ERR_INPUT, "no radius gives %g photons per query", k);
    /* A radius measured on the data (photons spread to near the float range give inf) is
     * a fault of the input, not of the command line: an input error, exit 1. */
    if (radius > 0.0 && !(isfinite((float)(radius * radius))))
        return pm_error_set(PM_ERR_INPUT,
                            "kernel radius %g m for --k %g from the photons of '%s' and the queries of '%s': its "
                            "square does not fit a float (photons or queries spread beyond the float range)",
                            radius, k, in->map_path, in->q_path);
    *radius_out = radius > 0.0 ? radius : 1.0; /* nothing to gather: any width gives zero */
    return PM_OK;
}

pm_result_t pm_gather_output_init(pm_table_t *out, const pm_gather_inputs_t *in, int argc, char **argv, int kernel,
                                  const char *widths)
{
    const double *per_query = in->per_query;
    /* The pixels up to the last one a query names: the rest are zero, written as such by
     * pm_gather_table_write, so that a queries header declaring a large image with few
     * records makes no buffer of its size (the image's pixels past them cost nothing). */
    uint64_t npx = (uint64_t)in->width * in->height, used = in->pixels ? in->pixels_used : 0;
    for (uint64_t i = 0; !in->pixels && i < in->q.n; i++)
        used = in->q.pixel[i] >= used ? (uint64_t)in->q.pixel[i] + 1 : used;
    pm_result_t r = pm_table_alloc(out, &pm_radiance_schema, pm_schema_required(&pm_radiance_schema), used);
    if (r != PM_OK)
        return r;
    out->hdr.count = npx;
    /* Queries into pixels, in file order: the same sums for any thread count. */
    double *px = out->col[PM_RADIANCE_RGB];
    if (in->pixels)
        memcpy(px, in->pixels, (size_t)used * 3 * sizeof *px);
    for (uint64_t i = 0; !in->pixels && i < in->q.n; i++) {
        uint32_t pi = in->q.pixel[i];
        for (int k = 0; k < 3; k++)
            px[3 * (size_t)pi + k] += per_query[3 * i + k];
    }
    pm_header_t *h = &out->hdr;
    memcpy(h->bounds, in->q_table.hdr.bounds, sizeof h->bounds);
    if ((r = pm_header_inherit(h, &in->map_table.hdr)) != PM_OK ||
        (r = pm_header_inherit(h, &in->q_table.hdr)) != PM_OK ||
        (r = pm_header_add_input(h, in->map_path, in->map_table.checksum)) != PM_OK ||
        (r = pm_header_add_input(h, in->q_path, in->q_table.checksum)) != PM_OK ||
        (r = pm_header_add_command(h, argc, argv)) != PM_OK ||
        (r = pm_header_set(h, "width", "%" PRIu32, in->width)) != PM_OK ||
        (r = pm_header_set(h, "height", "%" PRIu32, in->height)) != PM_OK ||
        (r = pm_header_set(h, "component", "%s", in->caustic ? "caustic" : "indirect")) != PM_OK ||
        (r = pm_header_set(h, "kernel", "%s", pm_kernel_names[kernel])) != PM_OK)
        return r;
    return pm_header_set(h, "widths", "%s", widths);
}

pm_result_t pm_gather_table_write(const pm_table_t *out, const char *path)
{
    if (out->count == out->hdr.count)
        return pm_table_write(out, path);
    /* A buffer of pm_gather_output_init: its RGB column is the records (the one channel,
     * f64 x 3 little-endian), then zero records up to the header's count. */
    if (out->hdr.channels != (1u << PM_RADIANCE_RGB) || out->hdr.record_size != 3 * sizeof(double) ||
        out->count > out->hdr.count)
        return pm_error_set(PM_ERR_INTERNAL, "radiance table of %" PRIu64 " records for a header of %" PRIu64,
                            out->count, out->hdr.count);
    enum { ZERO_ROWS = 4096 };
    double *zero = calloc((size_t)ZERO_ROWS * 3, sizeof *zero);
    if (!zero)
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing '%s'", path);
    pm_writer_t *w;
    pm_result_t r = pm_writer_open(path, &out->hdr, &w);
    if (r == PM_OK) {
        r = out->count ? pm_writer_write(w, out->col[PM_RADIANCE_RGB], out->count) : PM_OK;
        for (uint64_t at = out->count; at < out->hdr.count && r == PM_OK; at += ZERO_ROWS)
            r = pm_writer_write_checked(w, zero, out->hdr.count - at < ZERO_ROWS ? out->hdr.count - at : ZERO_ROWS);
        if (r == PM_OK)
            r = pm_writer_commit(w);
        else
            pm_writer_abort(w);
    }
    free(zero);
    return r;
}

pm_result_t pm_gather_output_write(pm_table_t *out, const pm_gather_inputs_t *in, const char *path)
{
    pm_result_t r;
    if (in->ranged && (r = pm_header_set(&out->hdr, "range", "%" PRIu64 ":%" PRIu64, in->begin, in->end)) != PM_OK)
        return r;
    return pm_gather_table_write(out, path);
}

pm_result_t pm_gather_check_finite(const pm_gather_inputs_t *in, const char *what)
{
    const double *per_query = in->per_query;
    for (uint64_t i = 0; i < 3 * in->q.n; i++)
        if (!isfinite(per_query[i]))
            return pm_error_set(PM_ERR_INPUT, "query %" PRIu64 " of '%s': %s gives a non-finite radiance (%g)",
                                in->begin + i / 3, in->q_path, what, per_query[i]);
    return PM_OK;
}

void pm_gather_stage_stats(pm_stage_t *st, const pm_gather_inputs_t *in, int kernel, uint64_t shader_ops,
                           double gather_s, double cpu_s, double write_s)
{
    uint64_t nq = in->q.n;
    st->items = nq;
    pm_stage_stat_int(st, "queries", (int64_t)nq);
    pm_stage_stat_int(st, "photons", in->map.n);
    pm_stage_stat_string(st, "kernel", pm_kernel_names[kernel]);
    pm_stage_stat_int(st, "shader_ops", (int64_t)shader_ops);
    pm_stage_stat_double(st, "shader_ops_per_query", nq ? (double)shader_ops / (double)nq : 0.0);
    pm_stage_stat_double(st, "shader_ops_per_s", gather_s > 0 ? (double)shader_ops / gather_s : 0.0);
    pm_stage_stat_double(st, "shader_ops_per_cpu_s", cpu_s > 0 ? (double)shader_ops / cpu_s : 0.0);
    pm_stage_stat_double(st, "read_s", in->read_s);
    pm_stage_stat_double(st, "gather_s", gather_s);
    pm_stage_stat_double(st, "write_s", write_s);
}

/* ---- the progressive schedule ---- */

double pm_gather_pass_radius(double r1, uint64_t pass, double alpha)
{
    /* The product of the area ratios, in double: after 1e6 passes at alpha 2/3 it is about
     * 1e-2, far from underflow, and each factor is exact to an ulp. */
    double area = 1.0;
    for (uint64_t i = 1; i < pass; i++)
        area *= ((double)i + alpha) / ((double)i + 1.0);
    return r1 * sqrt(area);
}

double pm_gather_schedule_radius(double r1, double n, double alpha)
{
    if (!(n > 1.0))
        return r1;
    /* an integral index: the product itself, so that passes of pass 1's size keep their bytes */
    if (n == floor(n) && n < 9007199254740992.0)
        return pm_gather_pass_radius(r1, (uint64_t)n, alpha);
    double l = lgamma(n + alpha) - lgamma(1.0 + alpha) - lgamma(n + 1.0);
    return r1 * sqrt(exp(l));
}

double pm_gather_pass_index(uint64_t pass, uint64_t before, uint64_t unit)
{
    if (unit == 0)
        return (double)pass;
    return 1.0 + (double)before / (double)unit;
}

pm_result_t pm_gather_pass_header(pm_header_t *h, uint64_t pass, double alpha, double r1, uint64_t before,
                                  uint64_t unit)
{
    if (pass == 0)
        return PM_OK;
    pm_result_t r = pm_header_set(h, "pass", "%" PRIu64, pass);
    if (r == PM_OK)
        r = pm_header_set(h, "alpha", "%.9g", alpha);
    if (r == PM_OK)
        r = pm_header_set(h, "radius1", "%.9g", r1);
    if (r == PM_OK && unit)
        r = pm_header_set(h, "pass_photons", "%" PRIu64, before);
    if (r == PM_OK && unit)
        r = pm_header_set(h, "unit_photons", "%" PRIu64, unit);
    return r;
}

pm_result_t pm_gather_pass_check(int64_t pass, int64_t before, int64_t unit)
{
    if ((before >= 0 || unit > 0) && pass == 0)
        return pm_error_set(PM_ERR_USAGE, "--pass-photons and --unit-photons place a progressive pass: give --pass N");
    if (before >= 0 && unit == 0)
        return pm_error_set(PM_ERR_USAGE, "--pass-photons %" PRId64 " needs --unit-photons U (pass 1's photons)",
                            before);
    if (unit > 0 && before < 0 && pass > 1)
        return pm_error_set(PM_ERR_USAGE,
                            "--unit-photons %" PRId64 " places pass %" PRId64 " with --pass-photons B (the photons "
                            "of the passes before it)",
                            unit, pass);
    if (pass == 1 && before > 0)
        return pm_error_set(PM_ERR_USAGE, "--pass 1 has no photons before it, not --pass-photons %" PRId64, before);
    return PM_OK;
}
