/* coverage.c: the boundary correction (coverage.h). */
#include "photonmap/coverage.h"

#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/timer.h"
#include "photonmap/mapbuild.h"

/* Points per coverage gather: bounds the scratch memory (24 bytes each). */
#define COVER_BLOCK 65536u

pm_result_t pm_coverage_level(double h, int *level_out)
{
    if (!(h > 0.0 && isfinite(h)))
        return pm_error_set(PM_ERR_USAGE, "kernel width %g m has no coverage spacing", h);
    double k = floor(2.0 * log2(h / PM_COVERAGE_RATIO));
    /* exp2 of a half-integer rounds: step down while the level's spacing is above h / ratio */
    while (exp2((k + 1.0) / 2.0) <= h / PM_COVERAGE_RATIO)
        k += 1.0;
    while (k > -2200.0 && exp2(k / 2.0) > h / PM_COVERAGE_RATIO)
        k -= 1.0;
    *level_out = (int)k;
    return PM_OK;
}

double pm_coverage_level_spacing(int level) { return exp2(level / 2.0); }

int pm_coverage_finest_level(uint64_t (*count)(const void *user, double spacing), const void *user,
                             uint64_t max_samples)
{
    if (count(user, INFINITY) > max_samples)
        return INT_MAX;
    /* below pm_coverage_level's lowest level (-2200), and a spacing that overflows to infinity */
    int lo = -2400, hi = 2400;
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (count(user, pm_coverage_level_spacing(mid)) > max_samples)
            lo = mid;
        else
            hi = mid;
    }
    return hi;
}

uint64_t pm_coverage_seed(double spacing)
{
    uint64_t bits;
    memcpy(&bits, &spacing, sizeof bits);
    return pm_hash_bytes(&bits, sizeof bits) ^ 0x636f766572616765ull; /* "coverage" */
}

void pm_coverage_free(pm_coverage_t *c)
{
    pm_gather_map_free(&c->map);
    pm_table_free(&c->table);
    free(c->scratch);
    memset(c, 0, sizeof *c);
}

pm_result_t pm_coverage_build(pm_coverage_t *c, const float *pos, const float *normal, const float *area, uint64_t n,
                              double spacing)
{
    double t0 = pm_time_wall();
    pm_gather_map_free(&c->map);
    pm_table_free(&c->table);
    c->spacing = 0.0, c->samples = 0;
    if (n > PM_GATHER_MAX_PHOTONS)
        return pm_error_set(PM_ERR_USAGE, "%" PRIu64 " area samples: a map holds at most %u", n, PM_GATHER_MAX_PHOTONS);
    pm_result_t r = pm_map_build_arrays(pos, area, normal, NULL, n, "area samples", 0, NULL, &c->table);
    if (r == PM_OK)
        r = pm_gather_map_init(&c->map, &c->table, 0);
    if (r != PM_OK) {
        pm_gather_map_free(&c->map);
        pm_table_free(&c->table);
        return r;
    }
    c->spacing = spacing, c->samples = n;
    c->build_s += pm_time_wall() - t0;
    c->builds++;
    return PM_OK;
}

/* The covered part of each of points [begin, end) of q (as plain diffuse queries of weight 1) at
 * params p, a block at a time: f(c, first index, count, user) receives c->scratch's values. */
typedef void (*covered_fn)(const double *cov, uint64_t first, uint64_t count, void *user);
static pm_result_t covered(pm_coverage_t *c, const pm_gather_queries_t *pts, uint64_t begin, uint64_t end,
                           const pm_gather_params_t *p, covered_fn f, void *user)
{
    if (!(c->spacing > 0.0))
        return pm_error_set(PM_ERR_INTERNAL, "the coverage correction has no area samples");
    if (p->variable || p->per_query)
        return pm_error_set(PM_ERR_USAGE, "the coverage correction needs one fixed kernel width");
    if (!c->scratch && !(c->scratch = malloc(3 * sizeof *c->scratch * COVER_BLOCK)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the coverage of %u points", COVER_BLOCK);
    pm_material_t plain;
    memset(&plain, 0, sizeof plain);
    plain.kind = PM_MAT_STANDARD;
    snprintf(plain.name, sizeof plain.name, "coverage");
    pm_gather_queries_t q = {.n = pts->n, .pos = pts->pos, .normal = pts->normal, .materials = &plain, .nmaterials = 1};
    double t0 = pm_time_wall();
    for (uint64_t b = begin; b < end; b += COVER_BLOCK) {
        uint64_t e = end - b > COVER_BLOCK ? b + COVER_BLOCK : end;
        pm_gather_stats_t gs;
        pm_result_t r = pm_gather_run(&c->map, &q, b, e, p, c->scratch, &gs);
        if (r != PM_OK)
            return r;
        c->shader_ops += gs.shader_ops, c->cpu_s += gs.cpu_s, c->points += e - b;
        f(c->scratch, b, e - b, user);
    }
    c->wall_s += pm_time_wall() - t0;
    return PM_OK;
}

static inline double inverse(double f) { return 1.0 / (f > PM_COVERAGE_MIN ? f : PM_COVERAGE_MIN); }

static void scale_powers(const double *cov, uint64_t first, uint64_t count, void *user)
{
    float *power = user;
    for (uint64_t i = 0; i < count; i++) {
        double inv = inverse(cov[3 * i]);
        for (int k = 0; k < 3; k++)
            power[3 * (first + i) + k] = (float)(power[3 * (first + i) + k] * inv);
    }
}

pm_result_t pm_coverage_apply(pm_coverage_t *c, pm_table_t *map, const pm_gather_map_t *m, const pm_gather_params_t *p)
{
    const pm_gather_queries_t pts = {.n = m->n, .pos = m->pos, .normal = m->normal};
    return covered(c, &pts, 0, m->n, p, scale_powers, map->col[PM_MAP_POWER]);
}

typedef struct {
    double *out;
    uint64_t begin;
} scale_out_t;

static void scale_results(const double *cov, uint64_t first, uint64_t count, void *user)
{
    scale_out_t *s = user;
    for (uint64_t i = 0; i < count; i++) {
        double inv = inverse(cov[3 * i]), *o = &s->out[3 * (first + i - s->begin)];
        o[0] *= inv, o[1] *= inv, o[2] *= inv;
    }
}

pm_result_t pm_coverage_apply_queries(pm_coverage_t *c, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                                      const pm_gather_params_t *p, double *out)
{
    scale_out_t s = {out, begin};
    return covered(c, q, begin, end, p, scale_results, &s);
}
