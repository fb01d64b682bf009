/* gather.c: set-up, threads and references around the per-ISA packet kernels
 * (gather_isa.c, gather_kernel.h). */
#include "photonmap/gather.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"
#include "base/timer.h"
#include "math/sampling.h"
#include "photonmap/gather_impl.h"
#include "photonmap/kdtree.h"
#include "physics/bsdf.h"

/* Queries per unit of work handed to a thread: a multiple of every packet width, small
 * enough that two threads stay balanced, large enough that scheduling costs nothing. */
enum { BLOCK_QUERIES = 2048 };

pm_result_t pm_gather_map_init(pm_gather_map_t *m, const pm_table_t *map, int variable)
{
    memset(m, 0, sizeof *m);
    m->n = (uint32_t)map->count;
    m->node = map->col[PM_MAP_NODE];
    m->pos = map->col[PM_MAP_POSITION];
    m->power = map->col[PM_MAP_POWER];
    m->normal = map->col[PM_MAP_NORMAL];
    m->dir = map->col[PM_MAP_DIRECTION];
    m->width = map->col[PM_MAP_WIDTH];
    if (m->n > PM_GATHER_MAX_PHOTONS)
        return pm_error_set(PM_ERR_INPUT, "photon map of %" PRIu32 " photons: the gather takes at most %u", m->n,
                            PM_GATHER_MAX_PHOTONS);
    m->hot = pm_alloc_aligned((m->n ? m->n : 1) * sizeof *m->hot);
    if (!m->hot)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the hot records of %" PRIu32 " photons", m->n);
    for (uint32_t i = 0; i < m->n; i++) {
        uint32_t axis = pm_kdnode_axis(m->node[i]), c = m->node[i].child;
        pm_gather_hot_t *h = &m->hot[i];
        memcpy(h->p, &m->pos[3 * (size_t)i], 12);
        h->link = axis << 30 | (c == PM_KD_NONE || axis == PM_KD_LEAF ? PM_GATHER_NO_CHILD : c);
    }
    float mx = 0.0f;
    for (uint64_t i = 0; i < 3 * (uint64_t)m->n; i++)
        mx = fabsf(m->pos[i]) > mx ? fabsf(m->pos[i]) : mx; /* fmaxf is a library call without -ffast-math */
    m->max_abs = mx;
    if (variable) {
        if (!m->width)
            return pm_error_set(PM_ERR_INPUT, "variable kernel widths need a photon map with the width channel "
                                              "(build-photonmap --width-k K)");
        m->subtree_width = malloc((m->n ? m->n : 1) * sizeof *m->subtree_width);
        if (!m->subtree_width)
            return pm_error_set(PM_ERR_NOMEM, "out of memory for the subtree widths of %" PRIu32 " photons", m->n);
        /* Depth-first order puts children after their parent: one backward pass. */
        for (uint32_t i = m->n; i-- > 0;) {
            float w = m->width[i];
            uint32_t c = m->node[i].child;
            if (pm_kdnode_axis(m->node[i]) != PM_KD_LEAF) {
                if (c != i + 1)
                    w = fmaxf(w, m->subtree_width[i + 1]);
                uint32_t right = c != i + 1 ? c : i + 1;
                if (right != PM_KD_NONE)
                    w = fmaxf(w, m->subtree_width[right]);
            }
            m->subtree_width[i] = w;
        }
    }
    return PM_OK;
}

void pm_gather_map_free(pm_gather_map_t *m)
{
    free(m->subtree_width);
    pm_free_aligned(m->hot);
    m->subtree_width = NULL;
    m->hot = NULL;
}

pm_result_t pm_gather_queries_init(pm_gather_queries_t *q, const pm_table_t *t, const char *path,
                                   pm_material_t **materials_out)
{
    memset(q, 0, sizeof *q);
    q->n = t->count;
    q->pos = t->col[PM_QUERY_POSITION];
    q->normal = t->col[PM_QUERY_NORMAL];
    q->weight = t->col[PM_QUERY_WEIGHT];
    q->pixel = t->col[PM_QUERY_PIXEL];
    q->material = t->col[PM_QUERY_MATERIAL];
    q->dir = t->col[PM_QUERY_DIRECTION];
    size_t nm = 0;
    pm_result_t r = pm_queries_get_materials(&t->hdr, path, materials_out, &nm);
    if (r != PM_OK)
        return r;
    q->materials = *materials_out;
    q->nmaterials = (uint32_t)nm;
    return PM_OK;
}

/* f(wi, wo) of material mt at a surface of normal n, 1/sr: physics/bsdf.h's, in radiance mode
 * (light arriving along wi, the photon's, leaving along wo, the query's); see gather.h. */
void pm_gather_brdf(const pm_material_t *mt, const float n[3], const float wi[3], const float wo[3], double f[3])
{
    float ff[3];
    pm_bsdf_eval(mt, n, wi, wo, PM_BSDF_RADIANCE, ff);
    for (int k = 0; k < 3; k++)
        f[k] = ff[k];
}

int gather_lane_setup(const gather_ctx_t *c, const pm_material_t *mt, uint32_t mi, const float n[3], const float wo[3],
                      float *gl, uint32_t w, uint32_t l)
{
    float *row[GL_ROWS];
    for (int r = 0; r < GL_ROWS; r++)
        row[r] = gl + (size_t)r * w;
    int kind = GL_KIND_MODULE;
    if (mt->kind == PM_MAT_STANDARD) {
        for (int k = 0; k < 3; k++) {
            row[GL_KD + k][l] = mt->kd[k] * 0.31830988618379067f; /* kd / pi */
            row[GL_KS + k][l] = mt->ks[k];
        }
        row[GL_NS][l] = mt->ns;
        kind = GL_KIND_PHONG;
    } else if ((mt->kind == PM_MAT_CONDUCTOR || mt->kind == PM_MAT_PLASTIC) && mt->alpha >= PM_MAT_ALPHA_DELTA) {
        /* physics/bsdf.c's reflect_side: the normal on wo's side, both cosines about it */
        float co = n[0] * wo[0] + n[1] * wo[1] + n[2] * wo[2], s = co < 0.0f ? -1.0f : 1.0f;
        float alpha = fminf(mt->alpha, 1.0f);
        for (int k = 0; k < 3; k++)
            row[GL_N + k][l] = s * n[k];
        co = row[GL_N][l] * wo[0] + row[GL_N + 1][l] * wo[1] + row[GL_N + 2][l] * wo[2];
        row[GL_CO][l] = co;
        row[GL_A2][l] = alpha * alpha;
        row[GL_LO][l] = pm_ggx_lambda(alpha, co);
        if (mt->kind == PM_MAT_CONDUCTOR) {
            for (int k = 0; k < 3; k++) {
                row[GL_E + k][l] = mt->eta[0] > 0.0f ? fminf(fmaxf(mt->eta[k], PM_ETA_MIN), PM_ETA_MAX) : mt->f0[k];
                row[GL_K + k][l] = fminf(fmaxf(mt->k[k], 0.0f), PM_ETA_MAX);
            }
            kind = mt->eta[0] > 0.0f ? GL_KIND_CONDUCTOR : GL_KIND_SCHLICK;
        } else {
            float ior = fminf(fmaxf(mt->ior, PM_ETA_MIN), PM_ETA_MAX), to = 1.0f - pm_fresnel_dielectric(co, ior);
            for (int k = 0; k < 3; k++)
                row[GL_KD + k][l] = mt->kd[k] * to / (PM_PI * ior * ior * (1.0f - mt->kd[k] * c->mat_fdr[mi]));
            row[GL_IOR][l] = ior;
            kind = GL_KIND_PLASTIC;
        }
    }
    row[GL_KIND][l] = (float)kind;
    return kind;
}

void gather_glossy_lane(const gather_ctx_t *c, uint64_t qi, uint32_t ni, float k, double *dacc, uint32_t w, uint32_t l)
{
    const pm_gather_queries_t *q = c->q;
    const pm_material_t *mt = &q->materials[q->material ? q->material[qi] : 0];
    double f[3];
    pm_gather_brdf(mt, &q->normal[3 * qi], &c->m->dir[3 * (size_t)ni], &q->dir[3 * qi], f);
    const float *pw = &c->m->power[3 * (size_t)ni];
    for (int ch = 0; ch < 3; ch++)
        dacc[ch * w + l] += (double)k * f[ch] * pw[ch];
}

pm_result_t pm_gather_glossy_table(const pm_gather_map_t *m, const pm_gather_queries_t *q, unsigned char **glossy_out,
                                   int *any_out)
{
    unsigned char *g = calloc(q->nmaterials ? q->nmaterials : 1, 1);
    if (!g)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the material table");
    int any = 0;
    for (uint32_t i = 0; i < q->nmaterials; i++) {
        g[i] = pm_material_is_glossy(&q->materials[i]);
        any |= g[i];
    }
    pm_result_t r = PM_OK;
    if (any && !q->dir)
        r = pm_error_set(PM_ERR_INPUT, "the queries have glossy materials but no direction channel");
    else if (any && !m->dir)
        r = pm_error_set(PM_ERR_INPUT, "the queries have glossy materials but the photon map has no direction "
                                       "channel (trace its photons from the same scene)");
    if (r != PM_OK) {
        free(g);
        return r;
    }
    *glossy_out = g;
    *any_out = any;
    return PM_OK;
}

void pm_gather_brute(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                     const pm_gather_params_t *p, double *out)
{
    for (uint64_t i = begin; i < end; i++) {
        const float *y = &q->pos[3 * i], *n = &q->normal[3 * i];
        const pm_material_t *mt = &q->materials[q->material ? q->material[i] : 0];
        int glossy = pm_material_is_glossy(mt) && q->dir && m->dir;
        double s[3] = {0, 0, 0};
        for (uint32_t j = 0; j < m->n; j++) {
            const float *x = &m->pos[3 * (size_t)j], *pn = &m->normal[3 * (size_t)j];
            /* the same float arithmetic as the kernels, so that ties at the sphere agree */
            float dx = y[0] - x[0], dy = y[1] - x[1], dz = y[2] - x[2];
            float d2 = dx * dx + dy * dy + dz * dz;
            float h = p->variable ? m->width[j] : p->per_query ? q->radius[i] : (float)p->radius;
            if (!(d2 < h * h))
                continue;
            if (!(n[0] * pn[0] + n[1] * pn[1] + n[2] * pn[2] >= p->normal_cos))
                continue;
            double kv = pm_kernel_value(p->kernel, d2, (double)h * h), f[3] = {1, 1, 1};
            if (glossy)
                pm_gather_brdf(mt, n, &m->dir[3 * (size_t)j], &q->dir[3 * i], f);
            for (int k = 0; k < 3; k++)
                s[k] += kv * f[k] * m->power[3 * (size_t)j + k];
        }
        for (int k = 0; k < 3; k++)
            out[3 * (i - begin) + k] = q->weight ? s[k] * q->weight[3 * i + k] : s[k];
    }
}

pm_result_t pm_gather_check_range(const pm_gather_queries_t *q, uint64_t begin, uint64_t end)
{
    if (end > q->n || begin > end)
        return pm_error_set(PM_ERR_INTERNAL, "query range %" PRIu64 ":%" PRIu64 " outside 0:%" PRIu64, begin, end,
                            q->n);
    return PM_OK;
}

pm_result_t pm_gather_check_radius(double radius)
{
    if (!(radius > 0.0 && isfinite((float)(radius * radius))))
        return pm_error_set(PM_ERR_USAGE, "kernel radius %g m is not a positive radius whose square fits a float",
                            radius);
    return PM_OK;
}

pm_result_t pm_gather_run(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                          const pm_gather_params_t *p, double *out, pm_gather_stats_t *stats)
{
    memset(stats, 0, sizeof *stats);
    pm_result_t res = pm_gather_check_range(q, begin, end);
    if (res == PM_OK && p->per_query && (p->variable || !q->radius))
        res = pm_error_set(PM_ERR_INTERNAL, "per-query widths need the queries' radius array and fixed photon widths");
    for (uint64_t i = begin; res == PM_OK && p->per_query && i < end; i++)
        if ((res = pm_gather_check_radius(q->radius[i])) != PM_OK)
            pm_error_prefix("query %" PRIu64, i);
    if (res == PM_OK && !p->variable && !p->per_query)
        res = pm_gather_check_radius(p->radius);
    if (res != PM_OK)
        return res;
    if (!pm_cpu_supports(p->isa))
        return pm_error_set(PM_ERR_USAGE, "this CPU cannot run --isa %s", pm_isa_name(p->isa));
    unsigned char *mat_glossy = NULL;
    int glossy;
    res = pm_gather_glossy_table(m, q, &mat_glossy, &glossy);
    if (res != PM_OK)
        return res;
    /* A plastic's base needs its coat's average internal reflectance: once per material. */
    float *fdr = calloc(q->nmaterials ? q->nmaterials : 1, sizeof *fdr);
    if (!fdr) {
        free(mat_glossy);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the material table");
    }
    for (uint32_t i = 0; i < q->nmaterials; i++)
        if (q->materials[i].kind == PM_MAT_PLASTIC)
            fdr[i] = pm_fresnel_diffuse_inside(fminf(fmaxf(q->materials[i].ior, PM_ETA_MIN), PM_ETA_MAX));
    gather_ctx_t c = {.m = m,
                      .q = q,
                      .kernel = p->kernel,
                      .normal_cos = p->normal_cos,
                      .glossy = glossy,
                      .mat_glossy = mat_glossy,
                      .mat_fdr = fdr};
    const double inv_pi = 0.31830988618379067;
    c.kscale_unit = (float)((p->kernel == PM_KERNEL_UNIFORM ? 1.0 : 2.0) * inv_pi);
    double r = p->variable || p->per_query ? 0.0 : p->radius;
    if (p->variable)
        for (uint32_t i = 0; i < m->n; i++)
            r = fmax(r, m->width[i]);
    if (p->per_query)
        for (uint64_t i = begin; i < end; i++)
            r = fmax(r, q->radius[i]);
    /* A plane is the photon's coordinate to within 3 ulp, and q - split rounds by half an
     * ulp of the larger: 2^-20 of the largest magnitude in play covers both. */
    c.slack = (float)(((double)m->max_abs + r) * 0x1p-20);
    if (!p->variable && !p->per_query) {
        c.r = (float)p->radius;
        c.r2 = c.r * c.r;
        c.inv_r2 = 1.0f / c.r2;
        c.r_trav = c.r + c.slack;
        c.kscale = c.kscale_unit * c.inv_r2;
    }
    gather_fn_t fn = gather_kernel_for(p->isa, p->per_query ? 2 : p->variable);
    uint64_t nblocks = (end - begin + BLOCK_QUERIES - 1) / BLOCK_QUERIES;
    pm_gather_stats_t total = {0};
#pragma omp parallel
    {
        pm_gather_stats_t st = {0};
        double cpu0 = pm_time_thread_cpu();
#pragma omp for schedule(dynamic, 1) nowait
        for (uint64_t k = 0; k < nblocks; k++) {
            uint64_t b = begin + k * BLOCK_QUERIES, e = b + BLOCK_QUERIES < end ? b + BLOCK_QUERIES : end;
            fn(&c, b, e, out + 3 * (b - begin), &st);
        }
        st.cpu_s = pm_time_thread_cpu() - cpu0;
#pragma omp critical
        {
            total.cpu_s += st.cpu_s;
            total.shader_ops += st.shader_ops;
            total.shade_steps += st.shade_steps;
            total.active_lanes += st.active_lanes;
            total.straddling_lanes += st.straddling_lanes;
            total.nodes_visited += st.nodes_visited;
            total.packets += st.packets;
        }
    }
    *stats = total;
    free(mat_glossy);
    free(fdr);
    return PM_OK;
}

/* ---- the radius for K photons ---- */

typedef struct {
    const pm_gather_map_t *m;
    const float *n;
    float cos;
    uint64_t count;
} count_ctx_t;

static void count_one(void *ctx, uint32_t i, float d2)
{
    count_ctx_t *c = ctx;
    const float *pn = &c->m->normal[3 * (size_t)i];
    (void)d2;
    c->count += c->n[0] * pn[0] + c->n[1] * pn[1] + c->n[2] * pn[2] >= c->cos;
}

/* Mean number of photons strictly inside radius r (normals agreeing) over the sample. */
static double mean_count(const pm_gather_map_t *m, const pm_gather_queries_t *q, const uint64_t *idx, uint32_t s,
                         float r, float cos)
{
    uint64_t total = 0;
    float r_in = nextafterf(r, 0.0f); /* pm_kd_range includes d = r; the gather does not */
#pragma omp parallel for reduction(+ : total) schedule(dynamic, 16)
    for (uint32_t j = 0; j < s; j++) {
        count_ctx_t c = {m, &q->normal[3 * idx[j]], cos, 0};
        pm_kd_range(m->node, m->pos, m->n, &q->pos[3 * idx[j]], r_in, count_one, &c);
        total += c.count;
    }
    return (double)total / s;
}

double pm_gather_radius_for_k(const pm_gather_map_t *m, const pm_gather_queries_t *q, double k, float normal_cos,
                              uint32_t samples)
{
    if (m->n == 0 || q->n == 0 || samples == 0)
        return 0.0;
    uint32_t s = q->n < samples ? (uint32_t)q->n : samples;
    uint64_t *idx = malloc(s * sizeof *idx);
    float *heap = malloc(((size_t)k + 1) * sizeof *heap), *rk = malloc(s * sizeof *rk);
    if (!idx || !heap || !rk) {
        free(idx), free(heap), free(rk);
        return 0.0;
    }
    for (uint32_t j = 0; j < s; j++)
        idx[j] = (2 * (uint64_t)j + 1) * q->n / (2 * (uint64_t)s);
    /* Start from the median distance to the k-th nearest photon, then bracket and bisect
     * the radius at which the mean count crosses k (counts stay near k, so it is cheap). */
    uint32_t kk = (uint32_t)fmax(1.0, ceil(k));
    for (uint32_t j = 0; j < s; j++)
        rk[j] = pm_kd_knn_radius(m->node, m->pos, m->n, &q->pos[3 * idx[j]], kk, heap);
    for (uint32_t a = 1; a < s; a++) { /* insertion sort: s is small */
        float v = rk[a];
        uint32_t b = a;
        for (; b > 0 && rk[b - 1] > v; b--)
            rk[b] = rk[b - 1];
        rk[b] = v;
    }
    float r = rk[s / 2];
    float ext = 2.0f * m->max_abs + 1e-30f;
    if (!(r > 0.0f))
        r = ext * 1e-6f;
    float lo = 0.0f, hi;
    if (mean_count(m, q, idx, s, r, normal_cos) >= k) { /* halve down to a radius below k */
        hi = r;
        for (int it = 0; it < 200; it++) {
            r *= 0.5f;
            if (r < ext * 1e-12f)
                break;
            if (mean_count(m, q, idx, s, r, normal_cos) < k) {
                lo = r;
                break;
            }
            hi = r;
        }
    } else { /* double up to one above */
        lo = r;
        for (;;) {
            r *= 2.0f;
            if (r > ext * 4.0f || mean_count(m, q, idx, s, r, normal_cos) >= k) /* beyond: fewer than k in reach */
                break;
            lo = r;
        }
        hi = r;
    }
    /* to 0.1%: a radius needs no more (the mean count itself varies by more between runs) */
    for (int it = 0; it < 40 && hi - lo > 1e-3f * hi; it++) {
        float mid = 0.5f * (lo + hi);
        if (mean_count(m, q, idx, s, mid, normal_cos) >= k)
            hi = mid;
        else
            lo = mid;
    }
    free(idx), free(heap), free(rk);
    return hi;
}
