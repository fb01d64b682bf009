/* api.c: the public C API (include/pmtk.h) over the library's layers: contexts that carry the
 * error callback and the thread count, photon maps built from a renderer's arrays or read from
 * files, the packet gather and the k-NN baseline on them, Hilbert order, and pmtk files of
 * every format. The top layer of libpmtk: it calls down into photonmap/ and formats/ and
 * nothing calls it; the programs link the same objects. Only the pmtk_* names are exported
 * from libpmtk.so (-fvisibility=hidden and libpmtk.map). */
#include "pmtk.h"

#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "base/cpu.h"
#include "base/error.h"
#include "base/version.h"
#include "formats/formats.h"
#include "photonmap/gather.h"
#include "photonmap/hilbert.h"
#include "photonmap/knn_gather.h"
#include "photonmap/mapbuild.h"

_Static_assert((int)PMTK_OK == (int)PM_OK && (int)PMTK_ERR_USAGE == (int)PM_ERR_USAGE &&
                   (int)PMTK_ERR_INPUT == (int)PM_ERR_INPUT && (int)PMTK_ERR_IO == (int)PM_ERR_IO &&
                   (int)PMTK_ERR_NOMEM == (int)PM_ERR_NOMEM && (int)PMTK_ERR_INTERNAL == (int)PM_ERR_INTERNAL,
               "the public result codes are the library's");
_Static_assert((int)PMTK_ISA_SCALAR == (int)PM_ISA_SCALAR && (int)PMTK_ISA_SSE4 == (int)PM_ISA_SSE4 &&
                   (int)PMTK_ISA_AVX2 == (int)PM_ISA_AVX2 && (int)PMTK_ISA_AVX512 == (int)PM_ISA_AVX512,
               "the public ISAs are the library's");
_Static_assert((int)PMTK_KERNEL_UNIFORM == (int)PM_KERNEL_UNIFORM &&
                   (int)PMTK_KERNEL_EPANECHNIKOV == (int)PM_KERNEL_EPANECHNIKOV,
               "the public kernels are the library's");

struct pmtk_context {
    pmtk_error_fn_t fn;
    void *user;
    int threads; /* 0: OpenMP's default */
    char message[PM_ERROR_MAX];
};

struct pmtk_photonmap {
    pm_table_t table;      /* the photonmap file's records and header */
    pm_gather_map_t gm;    /* the gather's view of it */
    pm_material_t diffuse; /* the queries' one material: f = 1, so sums are densities */
};

struct pmtk_file {
    pm_table_t table;
};

/* Every entry point: a result that is not PMTK_OK takes the thread's message into the context
 * and hands it to the callback. */
static pmtk_result_t report(pmtk_context_t *ctx, pm_result_t r)
{
    if (!ctx)
        return r;
    if (r == PM_OK) {
        ctx->message[0] = '\0';
        return r;
    }
    snprintf(ctx->message, sizeof ctx->message, "%s", pm_error_message());
    if (ctx->fn)
        ctx->fn(ctx->user, r, ctx->message);
    return r;
}

/* The context's thread count for one call, and the caller's back after it. */
static int threads_enter(const pmtk_context_t *ctx)
{
    int before = omp_get_max_threads();
    if (ctx->threads > 0)
        omp_set_num_threads(ctx->threads);
    return before;
}

static void threads_leave(int before) { omp_set_num_threads(before); }

PMTK_API const char *pmtk_result_string(pmtk_result_t code) { return pm_result_string(code); }

PMTK_API const char *pmtk_version(void) { return "pmtk " PM_VERSION_STRING; }

PMTK_API pmtk_result_t pmtk_context_create(pmtk_context_t **ctx_out)
{
    if (!ctx_out)
        return PMTK_ERR_USAGE;
    *ctx_out = calloc(1, sizeof **ctx_out);
    return *ctx_out ? PMTK_OK : PMTK_ERR_NOMEM;
}

PMTK_API void pmtk_context_destroy(pmtk_context_t *ctx) { free(ctx); }

PMTK_API void pmtk_context_set_error_callback(pmtk_context_t *ctx, pmtk_error_fn_t fn, void *user)
{
    if (ctx)
        ctx->fn = fn, ctx->user = user;
}

PMTK_API pmtk_result_t pmtk_context_set_threads(pmtk_context_t *ctx, int threads)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (threads < 0 || threads > 4096)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "thread count %d outside 0..4096", threads));
    ctx->threads = threads;
    return report(ctx, PM_OK);
}

PMTK_API const char *pmtk_context_error(const pmtk_context_t *ctx) { return ctx ? ctx->message : ""; }

PMTK_API int pmtk_isa_supported(pmtk_isa_t isa)
{
    return isa == PMTK_ISA_AUTO || (isa >= PMTK_ISA_SCALAR && isa <= PMTK_ISA_AVX512 && pm_cpu_supports((pm_isa_t)isa));
}

PMTK_API pmtk_isa_t pmtk_isa_best(void) { return (pmtk_isa_t)pm_cpu_best_isa(); }

PMTK_API const char *pmtk_isa_name(pmtk_isa_t isa)
{
    if (isa == PMTK_ISA_AUTO)
        return "auto";
    return isa >= PMTK_ISA_SCALAR && isa <= PMTK_ISA_AVX512 ? pm_isa_name((pm_isa_t)isa) : "unknown";
}

/* ---- argument checks ---- */

/* Whether a vector of 3 floats breaks the rule: finite, and with unit, of length within 1e-3 of
 * 1 (the formats' rule); with nonneg, every component >= 0. */
static int vector_bad(const float *x, int unit, int nonneg)
{
    if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2]))
        return 1;
    if (nonneg && (x[0] < 0.0f || x[1] < 0.0f || x[2] < 0.0f))
        return 1;
    /* |len - 1| <= 1e-3 as the squared length's bounds: no square root per vector */
    double l2 = (double)x[0] * x[0] + (double)x[1] * x[1] + (double)x[2] * x[2];
    return unit && !(l2 >= (1.0 - 1e-3) * (1.0 - 1e-3) && l2 <= (1.0 + 1e-3) * (1.0 + 1e-3));
}

/* Checks n vectors in parallel; the message names the first that breaks the rule. */
static pm_result_t check_vectors(const char *what, const float *v, uint64_t n, int unit, int nonneg)
{
    uint64_t first = n;
#pragma omp parallel for reduction(min : first) schedule(static)
    for (uint64_t i = 0; i < n; i++)
        if (vector_bad(&v[3 * i], unit, nonneg) && i < first)
            first = i;
    if (first == n)
        return PM_OK;
    const float *x = &v[3 * first];
    return pm_error_set(PM_ERR_INPUT, "%s %" PRIu64 " (%g, %g, %g) is not %s", what, first, x[0], x[1], x[2],
                        unit     ? "a unit vector"
                        : nonneg ? "finite and non-negative"
                                 : "finite");
}

static pm_result_t check_queries(const pmtk_queries_t *q)
{
    if (!q || (q->count && (!q->position || !q->normal)))
        return pm_error_set(PM_ERR_USAGE, "queries without positions or normals");
    pm_result_t r = check_vectors("query position", q->position, q->count, 0, 0);
    if (r == PM_OK)
        r = check_vectors("query normal", q->normal, q->count, 1, 0);
    return r;
}

/* ---- photon maps ---- */

static pm_result_t map_view(pmtk_photonmap_t *m)
{
    memset(&m->diffuse, 0, sizeof m->diffuse);
    snprintf(m->diffuse.name, sizeof m->diffuse.name, "api");
    return pm_gather_map_init(&m->gm, &m->table, 0);
}

PMTK_API pmtk_result_t pmtk_photonmap_build(pmtk_context_t *ctx, const pmtk_photons_t *ph, pmtk_photonmap_t **map_out)
{
    if (!ctx || !map_out)
        return PMTK_ERR_USAGE;
    *map_out = NULL;
    if (!ph || (ph->count && (!ph->position || !ph->power || !ph->normal)))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "photons without positions, powers or normals"));
    if (ph->count > PM_GATHER_MAX_PHOTONS)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "%" PRIu64 " photons: a map holds at most %u", ph->count,
                                        PM_GATHER_MAX_PHOTONS));
    pm_result_t r = check_vectors("photon position", ph->position, ph->count, 0, 0);
    if (r == PM_OK)
        r = check_vectors("photon power", ph->power, ph->count, 0, 1);
    if (r == PM_OK)
        r = check_vectors("photon normal", ph->normal, ph->count, 1, 0);
    if (r == PM_OK && ph->direction)
        r = check_vectors("photon direction", ph->direction, ph->count, 1, 0);
    if (r != PM_OK)
        return report(ctx, r);

    pmtk_photonmap_t *m = calloc(1, sizeof *m);
    if (!m)
        return report(ctx, pm_error_set(PM_ERR_NOMEM, "out of memory for a photon map"));
    int before = threads_enter(ctx);
    char *argv[] = {"pmtk_photonmap_build", NULL};
    r = pm_map_build_arrays(ph->position, ph->power, ph->normal, ph->direction, ph->count, "photon arrays", 1, argv,
                            &m->table);
    if (r == PM_OK)
        r = map_view(m);
    threads_leave(before);
    if (r != PM_OK) {
        pmtk_photonmap_destroy(m);
        return report(ctx, r);
    }
    *map_out = m;
    return report(ctx, PM_OK);
}

PMTK_API pmtk_result_t pmtk_photonmap_read(pmtk_context_t *ctx, const char *path, pmtk_photonmap_t **map_out)
{
    if (!ctx || !map_out)
        return PMTK_ERR_USAGE;
    *map_out = NULL;
    if (!path)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "no photon map path"));
    pmtk_photonmap_t *m = calloc(1, sizeof *m);
    if (!m)
        return report(ctx, pm_error_set(PM_ERR_NOMEM, "out of memory for a photon map"));
    int before = threads_enter(ctx);
    pm_result_t r = pm_table_read(path, &pm_photonmap_schema, 0, &m->table);
    if (r == PM_OK && (r = map_view(m)) != PM_OK)
        pm_error_prefix("'%s'", path);
    threads_leave(before);
    if (r != PM_OK) {
        pmtk_photonmap_destroy(m);
        return report(ctx, r);
    }
    *map_out = m;
    return report(ctx, PM_OK);
}

PMTK_API pmtk_result_t pmtk_photonmap_write(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const char *path)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (!map || !path)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "no photon map or no path to write it to"));
    return report(ctx, pm_table_write(&map->table, path));
}

PMTK_API uint64_t pmtk_photonmap_count(const pmtk_photonmap_t *map) { return map ? map->table.count : 0; }

PMTK_API void pmtk_photonmap_destroy(pmtk_photonmap_t *map)
{
    if (!map)
        return;
    pm_gather_map_free(&map->gm);
    pm_table_free(&map->table);
    free(map);
}

/* ---- gathers ---- */

PMTK_API void pmtk_gather_params_init(pmtk_gather_params_t *p)
{
    if (p)
        *p = (pmtk_gather_params_t){
            .radius = 0.0, .kernel = PMTK_KERNEL_UNIFORM, .normal_cos = 0.0f, .isa = PMTK_ISA_AUTO};
}

/* The gather's view of the caller's queries: weights of 1 and the map's one diffuse material,
 * so that the sums are the density estimate. With ones_out, weights of 1 in an array to free
 * (the k-NN gather reads them); without, none. */
static pm_result_t queries_view(const pmtk_photonmap_t *map, const pmtk_queries_t *in, pm_gather_queries_t *q,
                                float **ones_out)
{
    if (ones_out)
        *ones_out = NULL;
    pm_result_t r = check_queries(in);
    if (r != PM_OK)
        return r;
    *q = (pm_gather_queries_t){.n = in->count,
                               .pos = in->position,
                               .normal = in->normal,
                               .radius = in->radius,
                               .materials = &map->diffuse,
                               .nmaterials = 1};
    if (!ones_out)
        return PM_OK; /* the packet gather takes NULL weights as 1 */
    float *ones = malloc((in->count ? in->count : 1) * 3 * sizeof *ones);
    if (!ones)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of %" PRIu64 " queries", in->count);
    for (uint64_t i = 0; i < 3 * in->count; i++)
        ones[i] = 1.0f;
    q->weight = ones;
    *ones_out = ones;
    return PM_OK;
}

PMTK_API pmtk_result_t pmtk_gather(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const pmtk_queries_t *queries,
                                   const pmtk_gather_params_t *params, double *out, pmtk_gather_stats_t *stats_out)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (stats_out)
        memset(stats_out, 0, sizeof *stats_out);
    if (!map || !params || (!out && queries && queries->count))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "pmtk_gather needs a map, parameters and an output array"));
    if (params->kernel != PMTK_KERNEL_UNIFORM && params->kernel != PMTK_KERNEL_EPANECHNIKOV)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "unknown kernel %d", (int)params->kernel));
    pm_isa_t isa = params->isa == PMTK_ISA_AUTO ? pm_cpu_best_isa() : (pm_isa_t)params->isa;
    if (params->isa != PMTK_ISA_AUTO && (params->isa < PMTK_ISA_SCALAR || params->isa > PMTK_ISA_AVX512))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "unknown isa %d", (int)params->isa));
    pm_gather_queries_t q;
    pm_result_t r = queries_view(map, queries, &q, NULL);
    if (r != PM_OK)
        return report(ctx, r);
    pm_gather_params_t p = {.radius = params->radius,
                            .kernel = (pm_kernel_t)params->kernel,
                            .normal_cos = params->normal_cos,
                            .per_query = queries->radius != NULL,
                            .isa = isa};
    pm_gather_stats_t st;
    int before = threads_enter(ctx);
    r = pm_gather_run(&map->gm, &q, 0, q.n, &p, out, &st);
    threads_leave(before);
    if (r == PM_OK && stats_out)
        *stats_out = (pmtk_gather_stats_t){.shader_ops = st.shader_ops,
                                           .nodes_visited = st.nodes_visited,
                                           .packets = st.packets,
                                           .packet_width = pm_isa_width(isa),
                                           .cpu_s = st.cpu_s};
    return report(ctx, r);
}

PMTK_API pmtk_result_t pmtk_knn_gather(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const pmtk_queries_t *queries,
                                       const pmtk_knn_params_t *params, double *out)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (!map || !params || (!out && queries && queries->count))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "pmtk_knn_gather needs a map, parameters and an output array"));
    if (params->k < 1 || !(params->max_radius >= 0.0 && isfinite(params->max_radius)))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "k-NN parameters k %" PRIu32 ", max_radius %g out of range",
                                        params->k, params->max_radius));
    if (params->kernel != PMTK_KERNEL_UNIFORM && params->kernel != PMTK_KERNEL_EPANECHNIKOV)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "unknown kernel %d", (int)params->kernel));
    pm_gather_queries_t q;
    float *ones;
    pm_result_t r = queries_view(map, queries, &q, &ones);
    if (r != PM_OK)
        return report(ctx, r);
    q.radius = NULL;
    pm_knn_params_t p = {.k = params->k,
                         .max_radius = params->max_radius,
                         .kernel = (pm_kernel_t)params->kernel,
                         .normal_cos = params->normal_cos};
    pm_knn_stats_t st;
    int before = threads_enter(ctx);
    r = pm_knn_gather(&map->gm, &q, 0, q.n, &p, out, &st);
    threads_leave(before);
    free(ones);
    return report(ctx, r);
}

PMTK_API pmtk_result_t pmtk_hilbert_order(pmtk_context_t *ctx, const float *position, size_t stride, uint64_t n,
                                          uint64_t leaf, uint32_t *perm_out)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (n && (!position || !perm_out))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "pmtk_hilbert_order needs positions and a permutation array"));
    if (stride < 3 * sizeof(float) || leaf < 1 || n >= UINT32_MAX)
        return report(ctx, pm_error_set(PM_ERR_USAGE,
                                        "pmtk_hilbert_order: stride %zu (at least 12), leaf %" PRIu64
                                        " (at least 1) or %" PRIu64 " points (below 2^32 - 1) out of range",
                                        stride, leaf, n));
    for (uint64_t i = 0; i < n; i++) {
        const float *x = (const float *)((const unsigned char *)position + i * stride);
        if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2]))
            return report(
                ctx, pm_error_set(PM_ERR_INPUT, "point %" PRIu64 " (%g, %g, %g) is not finite", i, x[0], x[1], x[2]));
    }
    int before = threads_enter(ctx);
    pm_result_t r = pm_reorder_points(position, stride, n, PM_ORDER_HILBERT, leaf, perm_out, NULL);
    threads_leave(before);
    return report(ctx, r);
}

/* ---- files ---- */

PMTK_API pmtk_result_t pmtk_file_read(pmtk_context_t *ctx, const char *path, pmtk_file_t **file_out)
{
    if (!ctx || !file_out)
        return PMTK_ERR_USAGE;
    *file_out = NULL;
    if (!path)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "no file path"));
    pmtk_file_t *f = calloc(1, sizeof *f);
    if (!f)
        return report(ctx, pm_error_set(PM_ERR_NOMEM, "out of memory for a file"));
    int before = threads_enter(ctx);
    pm_result_t r = pm_table_read(path, NULL, 0, &f->table);
    threads_leave(before);
    if (r != PM_OK) {
        free(f);
        return report(ctx, r);
    }
    *file_out = f;
    return report(ctx, PM_OK);
}

static int channel_index(const pm_schema_t *s, const char *name)
{
    for (unsigned i = 0; name && i < s->nchannels; i++)
        if (strcmp(s->channels[i].name, name) == 0)
            return (int)i;
    return -1;
}

PMTK_API pmtk_result_t pmtk_file_create(pmtk_context_t *ctx, const char *format, const char *const *channels,
                                        uint64_t count, pmtk_file_t **file_out)
{
    if (!ctx || !file_out)
        return PMTK_ERR_USAGE;
    *file_out = NULL;
    const pm_schema_t *s = format ? pm_schema_find(format) : NULL;
    if (!s)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "unknown format '%s' (photons, photonmap, queries, radiance)",
                                        format ? format : "(null)"));
    if (count > PM_COUNT_MAX)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "%" PRIu64 " records: at most %llu", count, PM_COUNT_MAX));
    uint32_t mask = pm_schema_required(s);
    for (size_t i = 0; channels && channels[i]; i++) {
        int c = channel_index(s, channels[i]);
        if (c < 0)
            return report(ctx, pm_error_set(PM_ERR_USAGE, "no channel '%s' in the %s format", channels[i], s->name));
        mask |= 1u << c;
    }
    pmtk_file_t *f = calloc(1, sizeof *f);
    if (!f)
        return report(ctx, pm_error_set(PM_ERR_NOMEM, "out of memory for a file"));
    pm_result_t r = pm_table_alloc(&f->table, s, mask, count);
    if (r == PM_OK && s == &pm_queries_schema) {
        /* queries carry a material table; one standard material (index 0) until the caller
         * sets its own keys */
        pm_material_t m = {.name = "default"};
        r = pm_queries_set_materials(&f->table.hdr, &m, 1);
        if (r != PM_OK)
            pm_table_free(&f->table);
    }
    if (r != PM_OK) {
        free(f);
        return report(ctx, r);
    }
    *file_out = f;
    return report(ctx, PM_OK);
}

PMTK_API pmtk_result_t pmtk_file_write(pmtk_context_t *ctx, const pmtk_file_t *file, const char *path)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (!file || !path)
        return report(ctx, pm_error_set(PM_ERR_USAGE, "no file or no path to write it to"));
    int before = threads_enter(ctx);
    pm_result_t r = pm_table_write(&file->table, path);
    threads_leave(before);
    /* What the writer refuses as a bug of a program (a header or a record a reader would not
     * take) is here the caller's data. */
    return report(ctx, r == PM_ERR_INTERNAL ? PM_ERR_INPUT : r);
}

PMTK_API void pmtk_file_destroy(pmtk_file_t *file)
{
    if (!file)
        return;
    pm_table_free(&file->table);
    free(file);
}

PMTK_API const char *pmtk_file_format(const pmtk_file_t *file) { return file ? file->table.hdr.schema->name : NULL; }

PMTK_API uint64_t pmtk_file_count(const pmtk_file_t *file) { return file ? file->table.count : 0; }

PMTK_API void *pmtk_file_channel(pmtk_file_t *file, const char *name, pmtk_type_t *type_out, unsigned *components_out)
{
    if (!file)
        return NULL;
    const pm_schema_t *s = file->table.hdr.schema;
    int c = channel_index(s, name);
    if (c < 0 || !file->table.col[c])
        return NULL;
    if (type_out)
        *type_out = (pmtk_type_t)s->channels[c].type;
    if (components_out)
        *components_out = s->channels[c].components;
    return file->table.col[c];
}

PMTK_API const char *pmtk_file_header_get(const pmtk_file_t *file, const char *key)
{
    return file && key ? pm_header_get(&file->table.hdr, key) : NULL;
}

PMTK_API pmtk_result_t pmtk_file_header_set(pmtk_context_t *ctx, pmtk_file_t *file, const char *key, const char *value)
{
    if (!ctx)
        return PMTK_ERR_USAGE;
    if (!file || !key || !value || !*key || strpbrk(key, "=\n\r") || strpbrk(value, "\n\r"))
        return report(ctx, pm_error_set(PM_ERR_USAGE, "header key '%s' or its value is empty or holds '=' or a newline",
                                        key ? key : "(null)"));
    return report(ctx, pm_header_set(&file->table.hdr, key, "%s", value));
}
