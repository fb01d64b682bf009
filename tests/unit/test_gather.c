/* test_gather.c: the packet gather (common/photonmap/gather.c) against the O(n m) reference for
 * every ISA this CPU runs, both kernels, fixed and variable widths, glossy materials; a
 * uniform photon density gives the exact irradiance; edge cases of the walk. The baselines
 * (group "baselines"): knn-gather against a brute-force k nearest neighbours in double, and
 * reverse-gather against the O(n m) reference; both the same for any thread count. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "photonmap/gather.h"
#include "photonmap/kdtree.h"
#include "photonmap/knn_gather.h"
#include "photonmap/reverse_gather.h"
#include "physics/bsdf.h"
#include "unit.h"

typedef struct {
    uint32_t n;
    pm_kdnode_t *node;
    float *pos, *power, *normal, *dir, *width;
    pm_gather_map_t map;
} test_map_t;

/* A map of n photons given in any order: built, then laid out in node order. */
static void map_make(test_map_t *t, uint32_t n, const float *pos, const float *power, const float *normal,
                     const float *dir, const float *width)
{
    t->n = n;
    t->node = malloc((n ? n : 1) * sizeof *t->node);
    uint32_t *perm = malloc((n ? n : 1) * sizeof *perm);
    assert_int_equal(pm_kd_build(pos, n, t->node, perm, NULL), PM_OK);
    float **dst[] = {&t->pos, &t->power, &t->normal, &t->dir};
    const float *src[] = {pos, power, normal, dir};
    for (int c = 0; c < 4; c++) {
        *dst[c] = NULL;
        if (!src[c])
            continue;
        *dst[c] = malloc((n ? n : 1) * 12);
        for (uint32_t i = 0; i < n; i++)
            memcpy(&(*dst[c])[3 * i], &src[c][3 * (size_t)perm[i]], 12);
    }
    t->width = NULL;
    if (width) {
        t->width = malloc((n ? n : 1) * 4);
        for (uint32_t i = 0; i < n; i++)
            t->width[i] = width[perm[i]];
    }
    free(perm);
    /* pm_gather_map_init reads a table; fill the same fields by hand through one. */
    pm_table_t tab;
    uint32_t ch = pm_schema_required(&pm_photonmap_schema) | (dir ? 1u << PM_MAP_DIRECTION : 0) |
                  (width ? 1u << PM_MAP_WIDTH : 0);
    assert_int_equal(pm_table_alloc(&tab, &pm_photonmap_schema, ch, 0), PM_OK);
    tab.count = n;
    void *saved[PM_MAX_CHANNELS];
    memcpy(saved, tab.col, sizeof saved);
    tab.col[PM_MAP_NODE] = t->node, tab.col[PM_MAP_POSITION] = t->pos, tab.col[PM_MAP_POWER] = t->power;
    tab.col[PM_MAP_NORMAL] = t->normal, tab.col[PM_MAP_DIRECTION] = t->dir, tab.col[PM_MAP_WIDTH] = t->width;
    assert_int_equal(pm_gather_map_init(&t->map, &tab, width != NULL), PM_OK);
    memcpy(tab.col, saved, sizeof saved);
    tab.count = 0;
    pm_table_free(&tab);
}

static void map_free(test_map_t *t)
{
    pm_gather_map_free(&t->map);
    free(t->node), free(t->pos), free(t->power), free(t->normal), free(t->dir), free(t->width);
}

static const pm_material_t lambert = {.name = "folded", .kd = {1, 1, 1}};

static pm_gather_queries_t queries(uint64_t n, const float *pos, const float *normal, const float *weight)
{
    pm_gather_queries_t q = {
        .n = n, .pos = pos, .normal = normal, .weight = weight, .materials = &lambert, .nmaterials = 1};
    return q;
}

/* Random photons and queries on three planes (z = 0 facing +z, y = 0.5 facing -y, x = 0.3
 * facing +x), so that normals reject photons of the other planes; some queries sit exactly
 * on photons (and so on split planes). */
static void random_scene(uint32_t n, uint64_t nq, uint64_t seed, float *pos, float *pow, float *nor, float *qpos,
                         float *qnor, float *qw)
{
    pm_rng_t r;
    pm_rng_init(&r, seed, 0);
    for (uint32_t i = 0; i < n + nq; i++) {
        int plane = (int)(pm_rng_u32(&r) % 3);
        float p[3] = {pm_rng_float(&r), pm_rng_float(&r), pm_rng_float(&r)}, nn[3] = {0, 0, 0};
        if (plane == 0)
            p[2] = 0.0f, nn[2] = 1.0f;
        else if (plane == 1)
            p[1] = 0.5f, nn[1] = -1.0f;
        else
            p[0] = 0.3f, nn[0] = 1.0f;
        if (i < n) {
            memcpy(&pos[3 * i], p, 12), memcpy(&nor[3 * i], nn, 12);
            for (int k = 0; k < 3; k++)
                pow[3 * i + k] = 0.001f * (1.0f + pm_rng_float(&r));
        } else {
            uint64_t j = i - n;
            if (j % 7 == 0 && n) { /* exactly on a photon */
                uint32_t src = pm_rng_u32(&r) % n;
                memcpy(p, &pos[3 * src], 12), memcpy(nn, &nor[3 * src], 12);
            }
            memcpy(&qpos[3 * j], p, 12), memcpy(&qnor[3 * j], nn, 12);
            for (int k = 0; k < 3; k++)
                qw[3 * j + k] = 0.5f + pm_rng_float(&r);
        }
    }
}

static void expect_close(const double *got, const double *want, uint64_t n, double rel, const char *what)
{
    for (uint64_t i = 0; i < 3 * n; i++) {
        double tol = rel * fabs(want[i]) + 1e-12;
        if (!(fabs(got[i] - want[i]) <= tol))
            fail_msg("%s: value %llu is %.9g, reference %.9g", what, (unsigned long long)i, got[i], want[i]);
    }
}

static void test_gather_matches_brute_force_for_every_isa(void **state)
{
    const uint32_t n = 3000;
    const uint64_t nq = 501; /* not a multiple of any packet width */
    float *pos = malloc(n * 12), *pow = malloc(n * 12), *nor = malloc(n * 12), *wid = malloc(n * 4);
    float *qpos = malloc(nq * 12), *qnor = malloc(nq * 12), *qw = malloc(nq * 12);
    random_scene(n, nq, 11, pos, pow, nor, qpos, qnor, qw);
    pm_rng_t r;
    pm_rng_init(&r, 12, 0);
    for (uint32_t i = 0; i < n; i++)
        wid[i] = 0.02f + 0.1f * pm_rng_float(&r);
    double *got = malloc(nq * 24), *want = malloc(nq * 24);
    pm_gather_queries_t q = queries(nq, qpos, qnor, qw);
    for (int variable = 0; variable <= 1; variable++) {
        test_map_t t;
        map_make(&t, n, pos, pow, nor, NULL, variable ? wid : NULL);
        for (int kernel = 0; kernel <= 1; kernel++) {
            pm_gather_params_t p = {
                .radius = 0.07, .kernel = (pm_kernel_t)kernel, .variable = variable, .normal_cos = 0.5f};
            pm_gather_brute(&t.map, &q, 0, nq, &p, want);
            double sum = 0;
            for (uint64_t i = 0; i < 3 * nq; i++)
                sum += want[i];
            assert_true(sum > 0.0); /* the test gathers something */
            for (int isa = 0; isa < PM_ISA_COUNT; isa++) {
                if (!pm_cpu_supports((pm_isa_t)isa))
                    continue;
                p.isa = (pm_isa_t)isa;
                pm_gather_stats_t st;
                memset(got, 0xff, nq * 24);
                assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &p, got, &st), PM_OK);
                char what[96];
                snprintf(what, sizeof what, "%s, %s kernel, %s widths", pm_isa_name(p.isa),
                         kernel ? "epanechnikov" : "uniform", variable ? "variable" : "fixed");
                expect_close(got, want, nq, 2e-5, what);
                assert_true(st.shader_ops > 0);
                assert_true(st.active_lanes >= st.shade_steps); /* a shading step has a live lane */
                assert_true(st.active_lanes <= st.shade_steps * (uint64_t)pm_isa_width(p.isa));
            }
        }
        map_free(&t);
    }
    free(pos), free(pow), free(nor), free(wid), free(qpos), free(qnor), free(qw), free(got), free(want);
}

static void test_gather_glossy_matches_brute_force(void **state)
{
    const uint32_t n = 2000;
    const uint64_t nq = 203;
    float *pos = malloc(n * 12), *pow = malloc(n * 12), *nor = malloc(n * 12), *dir = malloc(n * 12);
    float *qpos = malloc(nq * 12), *qnor = malloc(nq * 12), *qw = malloc(nq * 12), *qdir = malloc(nq * 12);
    uint16_t *qmat = malloc(nq * 2);
    random_scene(n, nq, 21, pos, pow, nor, qpos, qnor, qw);
    pm_rng_t r;
    pm_rng_init(&r, 22, 0);
    for (uint32_t i = 0; i < n + nq; i++) { /* unit directions on the normal's side */
        const float *nn = i < n ? &nor[3 * i] : &qnor[3 * (i - n)];
        float *d = i < n ? &dir[3 * i] : &qdir[3 * (i - n)];
        float v[3] = {pm_rng_float(&r) - 0.5f, pm_rng_float(&r) - 0.5f, pm_rng_float(&r) - 0.5f};
        for (int k = 0; k < 3; k++)
            v[k] += 0.8f * nn[k];
        float len = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int k = 0; k < 3; k++)
            d[k] = v[k] / len;
        if (i >= n)
            qmat[i - n] = (uint16_t)((i - n) % 3);
    }
    /* a Lambertian, a soft and a sharp lobe: the SIMD power must hold for large exponents */
    pm_material_t mats[3] = {{.name = "folded", .kd = {1, 1, 1}},
                             {.name = "gloss", .kd = {0.2f, 0.3f, 0.4f}, .ks = {0.5f, 0.4f, 0.3f}, .ns = 15},
                             {.name = "mirrorish", .kd = {0.05f, 0.05f, 0.05f}, .ks = {0.9f, 0.9f, 0.9f}, .ns = 800}};
    pm_gather_queries_t q = {.n = nq,
                             .pos = qpos,
                             .normal = qnor,
                             .weight = qw,
                             .material = qmat,
                             .dir = qdir,
                             .materials = mats,
                             .nmaterials = 3};
    test_map_t t;
    map_make(&t, n, pos, pow, nor, dir, NULL);
    double *got = malloc(nq * 24), *want = malloc(nq * 24);
    pm_gather_params_t p = {.radius = 0.1, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f};
    pm_gather_brute(&t.map, &q, 0, nq, &p, want);
    for (int isa = 0; isa < PM_ISA_COUNT; isa++) {
        if (!pm_cpu_supports((pm_isa_t)isa))
            continue;
        p.isa = (pm_isa_t)isa;
        pm_gather_stats_t st;
        assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &p, got, &st), PM_OK);
        expect_close(got, want, nq, 1e-4, pm_isa_name(p.isa));
    }
    /* a glossy query needs photon directions */
    test_map_t nodir;
    map_make(&nodir, n, pos, pow, nor, NULL, NULL);
    pm_gather_stats_t st;
    assert_int_equal(pm_gather_run(&nodir.map, &q, 0, nq, &p, got, &st), PM_ERR_INPUT);
    map_free(&nodir);
    map_free(&t);
    free(pos), free(pow), free(nor), free(dir), free(qpos), free(qnor), free(qw), free(qdir), free(qmat);
    free(got), free(want);
}

/* Photons on a regular grid on z = 0, each of power P, spacing s: irradiance E = P / s^2.
 * Both kernels are normalized over the plane, so the estimate at any point well inside is
 * E up to the lattice's discreteness (under 1% at 40 spacings of radius). */
static void test_gather_uniform_density_gives_exact_irradiance(void **state)
{
    const uint32_t side = 201, n = side * side;
    const float s = 0.01f, P = 0.002f;
    float *pos = malloc(n * 12), *pow = malloc(n * 12), *nor = malloc(n * 12);
    for (uint32_t i = 0; i < n; i++) {
        pos[3 * i] = (float)(i % side) * s, pos[3 * i + 1] = (float)(i / side) * s, pos[3 * i + 2] = 0.0f;
        nor[3 * i] = 0, nor[3 * i + 1] = 0, nor[3 * i + 2] = 1;
        pow[3 * i] = P, pow[3 * i + 1] = 2 * P, pow[3 * i + 2] = 3 * P;
    }
    test_map_t t;
    map_make(&t, n, pos, pow, nor, NULL, NULL);
    enum { nq = 64 };
    float qpos[nq * 3], qnor[nq * 3], qw[nq * 3];
    pm_rng_t r;
    pm_rng_init(&r, 5, 0);
    for (uint64_t j = 0; j < nq; j++) {
        qpos[3 * j] = 0.8f + 0.4f * pm_rng_float(&r), qpos[3 * j + 1] = 0.8f + 0.4f * pm_rng_float(&r);
        qpos[3 * j + 2] = 0.0f;
        qnor[3 * j] = 0, qnor[3 * j + 1] = 0, qnor[3 * j + 2] = 1;
        qw[3 * j] = qw[3 * j + 1] = qw[3 * j + 2] = 1.0f;
    }
    pm_gather_queries_t q = queries(nq, qpos, qnor, qw);
    double out[nq * 3], E = P / ((double)s * s);
    for (int kernel = 0; kernel <= 1; kernel++) {
        pm_gather_params_t p = {
            .radius = 0.4, .kernel = (pm_kernel_t)kernel, .normal_cos = 0.5f, .isa = pm_cpu_best_isa()};
        pm_gather_stats_t st;
        assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &p, out, &st), PM_OK);
        for (uint64_t j = 0; j < nq; j++)
            for (int k = 0; k < 3; k++)
                if (!(fabs(out[3 * j + k] / ((k + 1) * E) - 1.0) < 0.01))
                    fail_msg("kernel %d, query %llu channel %d: %.6g W/m^2, expected %.6g", kernel,
                             (unsigned long long)j, k, out[3 * j + k], (k + 1) * E);
    }
    /* --k: about K photons in the kernel at density 1 / s^2 means r = s sqrt(K / pi). */
    double rk = pm_gather_radius_for_k(&t.map, &q, 50.0, 0.5f, 64);
    double want = s * sqrt(50.0 / M_PI);
    assert_true(fabs(rk / want - 1.0) < 0.05);
    map_free(&t);
    free(pos), free(pow), free(nor);
}

static void test_gather_edge_cases(void **state)
{
    /* photons on a lattice of quarter metres: distances and radii are exact in float */
    float pos[27 * 3], pow[27 * 3], nor[27 * 3];
    for (int i = 0; i < 27; i++) {
        pos[3 * i] = 0.25f * (float)(i % 3), pos[3 * i + 1] = 0.25f * (float)(i / 3 % 3);
        pos[3 * i + 2] = 0.25f * (float)(i / 9);
        nor[3 * i] = 0, nor[3 * i + 1] = 0, nor[3 * i + 2] = 1;
        pow[3 * i] = pow[3 * i + 1] = pow[3 * i + 2] = 1.0f;
    }
    test_map_t t;
    map_make(&t, 27, pos, pow, nor, NULL, NULL);
    float qpos[3] = {0.25f, 0.25f, 0.25f}, qnor[3] = {0, 0, 1}, qw[3] = {1, 1, 1};
    pm_gather_queries_t q = queries(1, qpos, qnor, qw);
    double out[3], want[3];
    pm_gather_stats_t st;
    for (int isa = 0; isa < PM_ISA_COUNT; isa++) {
        if (!pm_cpu_supports((pm_isa_t)isa))
            continue;
        /* radius exactly 0.25: the six neighbours lie on the sphere and are outside (d < h) */
        pm_gather_params_t p = {.radius = 0.25, .kernel = PM_KERNEL_UNIFORM, .normal_cos = 0.5f, .isa = (pm_isa_t)isa};
        assert_int_equal(pm_gather_run(&t.map, &q, 0, 1, &p, out, &st), PM_OK);
        assert_int_equal(st.shader_ops, 1); /* only the photon at the query itself */
        assert_float_equal(out[0], 1.0 / (M_PI * 0.0625), 1e-6);
        /* tiny radius between photons: nothing, and zero rather than NaN */
        float qoff[3] = {0.1f, 0.1f, 0.1f};
        pm_gather_queries_t q2 = queries(1, qoff, qnor, qw);
        p.radius = 1e-20;
        assert_int_equal(pm_gather_run(&t.map, &q2, 0, 1, &p, out, &st), PM_OK);
        assert_true(out[0] == 0.0 && out[1] == 0.0 && out[2] == 0.0);
        /* huge radius: every photon, as brute force says */
        p.radius = 1e6;
        assert_int_equal(pm_gather_run(&t.map, &q, 0, 1, &p, out, &st), PM_OK);
        assert_int_equal(st.shader_ops, 27);
        pm_gather_brute(&t.map, &q, 0, 1, &p, want);
        assert_float_equal(out[0], want[0], 1e-6 * want[0]);
        /* a query whose normal faces away takes nothing */
        float down[3] = {0, 0, -1};
        pm_gather_queries_t q3 = queries(1, qpos, down, qw);
        assert_int_equal(pm_gather_run(&t.map, &q3, 0, 1, &p, out, &st), PM_OK);
        assert_int_equal(st.shader_ops, 0);
        /* an empty map gathers nothing */
        test_map_t e;
        map_make(&e, 0, pos, pow, nor, NULL, NULL);
        assert_int_equal(pm_gather_run(&e.map, &q, 0, 1, &p, out, &st), PM_OK);
        assert_true(out[0] == 0.0);
        map_free(&e);
    }
    map_free(&t);
}

static void test_gather_same_result_for_any_thread_count(void **state)
{
    const uint32_t n = 20000;
    const uint64_t nq = 9000;
    float *pos = malloc(n * 12), *pow = malloc(n * 12), *nor = malloc(n * 12);
    float *qpos = malloc(nq * 12), *qnor = malloc(nq * 12), *qw = malloc(nq * 12);
    random_scene(n, nq, 31, pos, pow, nor, qpos, qnor, qw);
    test_map_t t;
    map_make(&t, n, pos, pow, nor, NULL, NULL);
    pm_gather_queries_t q = queries(nq, qpos, qnor, qw);
    double *a = malloc(nq * 24), *b = malloc(nq * 24);
    pm_gather_params_t p = {
        .radius = 0.05, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f, .isa = pm_cpu_best_isa()};
    pm_gather_stats_t st;
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &p, a, &st), PM_OK);
    omp_set_num_threads(2);
    assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &p, b, &st), PM_OK);
    omp_set_num_threads(saved);
    assert_memory_equal(a, b, nq * 24);
    /* a range gathers those queries: the same sums within float rounding (packets form
     * from the range's start, so lanes flush their float sums at other steps) */
    assert_int_equal(pm_gather_run(&t.map, &q, 1000, 3000, &p, b, &st), PM_OK);
    expect_close(b, a + 3000, 2000, 1e-6, "range 1000:3000");
    map_free(&t);
    free(pos), free(pow), free(nor), free(qpos), free(qnor), free(qw), free(a), free(b);
}

/* Millions of equal photons in one query (docs/extreme-cases.md): 2^22 photons of P W on a
 * 2048 x 2048 lattice, one query at its centre whose uniform kernel covers them all. The
 * sum must be n P / (pi h^2) to 1e-6 relative for every ISA: a float accumulator alone
 * stalls once the sum is 2^24 times a photon (here far below the answer), so only the
 * flushes into double (GATHER_FLUSH) keep it. */
static void test_gather_millions_of_photons_in_one_query(void **state)
{
    const uint32_t side = 2048, n = side * side;
    const float P = 1.0f / 3.0f * 1e-6f; /* not a short binary fraction: every addition rounds */
    float *pos = malloc((size_t)n * 12), *pow = malloc((size_t)n * 12), *nor = malloc((size_t)n * 12);
    assert_non_null(pos), assert_non_null(pow), assert_non_null(nor);
    for (uint32_t i = 0; i < n; i++) {
        pos[3 * (size_t)i] = (float)(i % side) * 1e-3f, pos[3 * (size_t)i + 1] = (float)(i / side) * 1e-3f;
        pos[3 * (size_t)i + 2] = 0.0f;
        nor[3 * (size_t)i] = 0, nor[3 * (size_t)i + 1] = 0, nor[3 * (size_t)i + 2] = 1;
        pow[3 * (size_t)i] = pow[3 * (size_t)i + 1] = pow[3 * (size_t)i + 2] = P;
    }
    test_map_t t;
    map_make(&t, n, pos, pow, nor, NULL, NULL);
    float qpos[3] = {1.0f, 1.0f, 0.0f}, qnor[3] = {0, 0, 1}, qw[3] = {1, 1, 1};
    pm_gather_queries_t q = queries(1, qpos, qnor, qw);
    const double h = 10.0, want = (double)n * (double)P / (M_PI * h * h);
    for (int isa = 0; isa < PM_ISA_COUNT; isa++) {
        if (!pm_cpu_supports((pm_isa_t)isa))
            continue;
        pm_gather_params_t p = {.radius = h, .kernel = PM_KERNEL_UNIFORM, .normal_cos = 0.5f, .isa = (pm_isa_t)isa};
        pm_gather_stats_t st;
        double out[3];
        assert_int_equal(pm_gather_run(&t.map, &q, 0, 1, &p, out, &st), PM_OK);
        assert_int_equal(st.shader_ops, n);
        for (int k = 0; k < 3; k++)
            if (!(fabs(out[k] / want - 1.0) < 1e-6))
                fail_msg("isa %d channel %d: %.9g W/m^2 from %u photons, expected %.9g (relative error %.2g)", isa, k,
                         out[k], n, want, out[k] / want - 1.0);
    }
    map_free(&t);
    free(pos), free(pow), free(nor);
}

/* A unit direction uniform on the sphere. */
static void random_unit(pm_rng_t *r, float d[3])
{
    for (;;) {
        float v[3] = {2.0f * pm_rng_float(r) - 1.0f, 2.0f * pm_rng_float(r) - 1.0f, 2.0f * pm_rng_float(r) - 1.0f};
        float l2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        if (l2 > 1e-4f && l2 <= 1.0f) {
            float l = sqrtf(l2);
            for (int k = 0; k < 3; k++)
                d[k] = v[k] / l;
            return;
        }
    }
}

/* A random material of kind `kind`, with parameters over their whole ranges. */
static pm_material_t random_material(pm_rng_t *r, int kind)
{
    pm_material_t m = {.kind = kind, .ior = 1.0f, .tf = {1, 1, 1}};
    float u = pm_rng_float(r);
    for (int k = 0; k < 3; k++) {
        float a = pm_rng_float(r), b = pm_rng_float(r);
        m.kd[k] = kind == PM_MAT_STANDARD ? a * (1.0f - u) : kind == PM_MAT_PLASTIC ? a : 0.0f;
        m.ks[k] = kind == PM_MAT_STANDARD ? b * u : 0.0f;
        m.eta[k] = 0.1f + 3.0f * a; /* the metals' range: silver 0.15, iron 2.9 */
        m.k[k] = 8.0f * b;
        m.f0[k] = pm_rng_float(r);
        m.tf[k] = pm_rng_float(r);
    }
    m.ns = kind == PM_MAT_STANDARD ? powf(10.0f, 4.0f * pm_rng_float(r)) - 1.0f : 0.0f; /* 0 to 10^4 */
    /* GGX widths from the smooth limit to 1, the stiff ends included */
    float t = pm_rng_float(r);
    m.alpha = t < 0.1f ? PM_MAT_ALPHA_DELTA : t > 0.9f ? 1.0f : powf(10.0f, -3.0f * pm_rng_float(r));
    m.ior = kind == PM_MAT_CONDUCTOR ? 1.0f : 1.0f + 2.0f * pm_rng_float(r); /* 1 to 3 */
    if (kind == PM_MAT_CONDUCTOR && pm_rng_float(r) < 0.5f)
        m.eta[0] = m.eta[1] = m.eta[2] = 0.0f; /* Schlick's of f0 */
    snprintf(m.name, sizeof m.name, "kind%d", kind);
    return m;
}

/* The SIMD evaluation of f in the packet kernels mirrors physics/bsdf.h's pm_bsdf_eval for every
 * kind whose surfaces gather: each ISA gathers one photon of power 1 and random direction wi
 * into queries of random kinds (standard, conductor by complex index and by Schlick's f0,
 * plastic, and rough glass, which the module evaluates itself) and random wo at its position;
 * a Lambertian query there gives the kernel's factor, so each query's sum over it is the f the
 * kernel computed. Tolerance: 2e-4 of f plus 1e-6 of the largest f of the trial (the float
 * power of a Phong lobe of exponent 10^4 and the float conductor Fresnel against the module's
 * double; measured worst 3e-5 relative). */
static void test_gather_simd_f_matches_the_bsdf_module(void **state)
{
    (void)state;
    enum { NQ = 67, TRIALS = 300 };
    const int kinds[] = {PM_MAT_STANDARD, PM_MAT_CONDUCTOR, PM_MAT_PLASTIC, PM_MAT_ROUGH_GLASS};
    pm_rng_t r;
    pm_rng_init(&r, 77, 0);
    float qpos[NQ * 3] = {0}, qnor[NQ * 3], qw[NQ * 3], qdir[NQ * 3];
    uint16_t qmat[NQ];
    pm_material_t mats[NQ];
    double got[NQ * 3];
    double worst = 0.0;
    uint64_t checked = 0, nonzero = 0;
    for (int trial = 0; trial < TRIALS; trial++) {
        float n[3], wi[3], pos[3] = {0, 0, 0}, pw[3] = {1, 1, 1};
        random_unit(&r, n);
        random_unit(&r, wi);
        for (int i = 0; i < NQ; i++) {
            memcpy(&qnor[3 * i], n, 12);
            qw[3 * i] = qw[3 * i + 1] = qw[3 * i + 2] = 1.0f;
            random_unit(&r, &qdir[3 * i]);
            /* mostly on wi's side, where reflection happens */
            float s = (qdir[3 * i] * n[0] + qdir[3 * i + 1] * n[1] + qdir[3 * i + 2] * n[2]) *
                      (wi[0] * n[0] + wi[1] * n[1] + wi[2] * n[2]);
            if (s < 0.0f && pm_rng_float(&r) < 0.7f)
                for (int k = 0; k < 3; k++)
                    qdir[3 * i + k] = -qdir[3 * i + k];
            mats[i] = i == 0 ? lambert : random_material(&r, kinds[(i + trial) % 4]);
            qmat[i] = (uint16_t)i;
        }
        /* the standard kind reads n as given: its queries' normal faces wo, as trace-gather-points writes it */
        for (int i = 1; i < NQ; i++)
            if (mats[i].kind == PM_MAT_STANDARD &&
                qdir[3 * i] * n[0] + qdir[3 * i + 1] * n[1] + qdir[3 * i + 2] * n[2] < 0.0f)
                for (int k = 0; k < 3; k++)
                    qnor[3 * i + k] = -n[k];
        test_map_t t;
        map_make(&t, 1, pos, pw, n, wi, NULL);
        pm_gather_queries_t q = {.n = NQ,
                                 .pos = qpos,
                                 .normal = qnor,
                                 .weight = qw,
                                 .material = qmat,
                                 .dir = qdir,
                                 .materials = mats,
                                 .nmaterials = NQ};
        pm_gather_params_t p = {.radius = 1.0, .kernel = PM_KERNEL_UNIFORM, .normal_cos = -2.0f};
        for (int isa = 0; isa < PM_ISA_COUNT; isa++) {
            if (!pm_cpu_supports((pm_isa_t)isa))
                continue;
            p.isa = (pm_isa_t)isa;
            pm_gather_stats_t st;
            assert_int_equal(pm_gather_run(&t.map, &q, 0, NQ, &p, got, &st), PM_OK);
            double kern = got[0]; /* the Lambertian query: the kernel's factor times power 1 */
            assert_true(kern > 0.0);
            double fhi = 0.0, want[NQ][3];
            for (int i = 1; i < NQ; i++) {
                float f[3];
                pm_bsdf_eval(&mats[i], &qnor[3 * i], wi, &qdir[3 * i], PM_BSDF_RADIANCE, f);
                for (int k = 0; k < 3; k++)
                    want[i][k] = f[k], fhi = fhi > f[k] ? fhi : f[k];
            }
            for (int i = 1; i < NQ; i++)
                for (int k = 0; k < 3; k++) {
                    double g = got[3 * i + k] / kern, w = want[i][k];
                    assert_true(isfinite(g));
                    double err = fabs(g - w);
                    if (!(err <= 2e-4 * fabs(w) + 1e-6 * fhi))
                        fail_msg("%s: kind %d (alpha %g, ns %g, ior %g) f %.9g, module %.9g", pm_isa_name(p.isa),
                                 mats[i].kind, mats[i].alpha, mats[i].ns, mats[i].ior, g, w);
                    if (w > 1e-3 * fhi)
                        worst = fmax(worst, err / w);
                    checked++;
                    nonzero += w > 0.0;
                }
        }
        map_free(&t);
    }
    print_message("# simd f against the module: %llu values (%llu nonzero), worst relative error %.2g\n",
                  (unsigned long long)checked, (unsigned long long)nonzero, worst);
    assert_true(nonzero > checked / 4); /* the directions did reach the lobes */
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_gather_matches_brute_force_for_every_isa),
    cmocka_unit_test(test_gather_simd_f_matches_the_bsdf_module),
    cmocka_unit_test(test_gather_glossy_matches_brute_force),
    cmocka_unit_test(test_gather_uniform_density_gives_exact_irradiance),
    cmocka_unit_test(test_gather_edge_cases),
    cmocka_unit_test(test_gather_same_result_for_any_thread_count),
    cmocka_unit_test(test_gather_millions_of_photons_in_one_query),
};
UNIT_GROUP(unit_gather, "gather", tests);

/* ---- the baselines: k-NN gather and reverse gather ---- */

/* Unit directions on each normal's side, and materials cycling over a Lambertian, a soft
 * and a sharp lobe (so that both baselines are checked with the shared glossy BRDF). */
static const pm_material_t baseline_mats[3] = {
    {.name = "folded", .kd = {1, 1, 1}},
    {.name = "gloss", .kd = {0.2f, 0.3f, 0.4f}, .ks = {0.5f, 0.4f, 0.3f}, .ns = 15},
    {.name = "sharp", .kd = {0.05f, 0.05f, 0.05f}, .ks = {0.9f, 0.9f, 0.9f}, .ns = 200}};

static void random_dirs(uint64_t n, const float *nor, float *dir, uint64_t seed)
{
    pm_rng_t r;
    pm_rng_init(&r, seed, 0);
    for (uint64_t i = 0; i < n; i++) {
        float v[3] = {pm_rng_float(&r) - 0.5f, pm_rng_float(&r) - 0.5f, pm_rng_float(&r) - 0.5f};
        for (int k = 0; k < 3; k++)
            v[k] += 0.8f * nor[3 * i + k];
        float len = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int k = 0; k < 3; k++)
            dir[3 * i + k] = v[k] / len;
    }
}

/* Random photons and queries (random_scene) with directions and the three materials above,
 * and its map: the scene both baselines are checked on. */
typedef struct {
    uint32_t n;
    uint64_t nq;
    float *pos, *pow, *nor, *dir, *qpos, *qnor, *qw, *qdir;
    uint16_t *qmat;
    pm_gather_queries_t q;
    test_map_t t;
} glossy_scene_t;

static void glossy_scene_make(glossy_scene_t *g, uint32_t n, uint64_t nq, uint64_t seed)
{
    g->n = n, g->nq = nq;
    g->pos = malloc(n * 12), g->pow = malloc(n * 12), g->nor = malloc(n * 12), g->dir = malloc(n * 12);
    g->qpos = malloc(nq * 12), g->qnor = malloc(nq * 12), g->qw = malloc(nq * 12), g->qdir = malloc(nq * 12);
    g->qmat = malloc(nq * 2);
    random_scene(n, nq, seed, g->pos, g->pow, g->nor, g->qpos, g->qnor, g->qw);
    random_dirs(n, g->nor, g->dir, seed + 1);
    random_dirs(nq, g->qnor, g->qdir, seed + 2);
    for (uint64_t i = 0; i < nq; i++)
        g->qmat[i] = (uint16_t)(i % 3);
    g->q = (pm_gather_queries_t){.n = nq,
                                 .pos = g->qpos,
                                 .normal = g->qnor,
                                 .weight = g->qw,
                                 .material = g->qmat,
                                 .dir = g->qdir,
                                 .materials = baseline_mats,
                                 .nmaterials = 3};
    map_make(&g->t, n, g->pos, g->pow, g->nor, g->dir, NULL);
}

static void glossy_scene_free(glossy_scene_t *g)
{
    map_free(&g->t);
    free(g->pos), free(g->pow), free(g->nor), free(g->dir), free(g->qpos), free(g->qnor), free(g->qw);
    free(g->qdir), free(g->qmat);
}

typedef struct {
    double d2;
    uint32_t j;
} knn_ref_t;

static int knn_ref_cmp(const void *a, const void *b)
{
    double x = ((const knn_ref_t *)a)->d2, y = ((const knn_ref_t *)b)->d2;
    return x < y ? -1 : x > y;
}

/* The k-NN estimate by brute force, in double and without the tree: every photon whose
 * normal agrees, sorted by distance, the first k taken. */
static void knn_brute(const test_map_t *t, const pm_gather_queries_t *q, const pm_knn_params_t *p, double *out)
{
    knn_ref_t *c = malloc((t->n ? t->n : 1) * sizeof *c);
    for (uint64_t i = 0; i < q->n; i++) {
        const float *y = &q->pos[3 * i], *n = &q->normal[3 * i];
        uint32_t m = 0;
        for (uint32_t j = 0; j < t->n; j++) {
            const float *x = &t->pos[3 * j], *pn = &t->normal[3 * j];
            double dn = (double)n[0] * pn[0] + (double)n[1] * pn[1] + (double)n[2] * pn[2];
            double d2 = 0;
            for (int a = 0; a < 3; a++)
                d2 += ((double)y[a] - x[a]) * ((double)y[a] - x[a]);
            if (dn >= p->normal_cos && (p->max_radius == 0.0 || d2 < p->max_radius * p->max_radius))
                c[m++] = (knn_ref_t){d2, j};
        }
        qsort(c, m, sizeof *c, knn_ref_cmp);
        uint32_t k = m < p->k ? m : p->k;
        double r2 = k < p->k && p->max_radius > 0.0 ? p->max_radius * p->max_radius : (k ? c[k - 1].d2 : 1.0);
        const pm_material_t *mt = &q->materials[q->material ? q->material[i] : 0];
        double s[3] = {0, 0, 0};
        for (uint32_t a = 0; a < k; a++) {
            double f[3] = {1, 1, 1}, kv = pm_kernel_value(p->kernel, c[a].d2, r2);
            if (pm_material_is_glossy(mt))
                pm_gather_brdf(mt, n, &t->dir[3 * c[a].j], &q->dir[3 * i], f);
            for (int ch = 0; ch < 3; ch++)
                s[ch] += kv * f[ch] * t->power[3 * c[a].j + ch];
        }
        for (int ch = 0; ch < 3; ch++)
            out[3 * i + ch] = s[ch] * q->weight[3 * i + ch];
    }
    free(c);
}

static void test_knn_gather_matches_brute_force(void **state)
{
    const uint32_t n = 3000;
    const uint64_t nq = 400;
    glossy_scene_t g;
    glossy_scene_make(&g, n, nq, 41);
    const pm_gather_queries_t q = g.q;
    const test_map_t t = g.t;
    double *got = malloc(nq * 24), *want = malloc(nq * 24);
    /* k 2 to 120; unlimited, and a maximum radius that leaves some queries short of k */
    const uint32_t ks[] = {2, 8, 50, 120};
    const double maxr[] = {0.0, 0.06};
    for (int kernel = 0; kernel <= 1; kernel++)
        for (size_t a = 0; a < sizeof ks / sizeof ks[0]; a++)
            for (size_t b = 0; b < 2; b++) {
                pm_knn_params_t p = {
                    .k = ks[a], .max_radius = maxr[b], .kernel = (pm_kernel_t)kernel, .normal_cos = 0.5f};
                pm_knn_stats_t st;
                memset(got, 0xff, nq * 24);
                assert_int_equal(pm_knn_gather(&t.map, &q, 0, nq, &p, got, &st), PM_OK);
                knn_brute(&t, &q, &p, want);
                char what[96];
                snprintf(what, sizeof what, "k %u, max radius %g, %s kernel", p.k, p.max_radius,
                         kernel ? "epanechnikov" : "uniform");
                expect_close(got, want, nq, 1e-5, what);
                assert_true(st.shader_ops <= (uint64_t)p.k * nq);
                if (maxr[b] == 0.0)
                    assert_true(st.shader_ops == (uint64_t)p.k * nq && st.short_queries == 0);
                else if (p.k == 120)
                    assert_true(st.short_queries > 0); /* the case of r = max radius is exercised */
            }
    /* a range gathers the same queries */
    pm_knn_params_t p = {.k = 20, .kernel = PM_KERNEL_UNIFORM, .normal_cos = 0.5f};
    pm_knn_stats_t st;
    assert_int_equal(pm_knn_gather(&t.map, &q, 0, nq, &p, want, &st), PM_OK);
    assert_int_equal(pm_knn_gather(&t.map, &q, 100, 300, &p, got, &st), PM_OK);
    assert_memory_equal(got, want + 300, 200 * 24);
    /* k = 1 at a query that sits on a photon: r = 0, refused rather than infinite */
    p.k = 1;
    assert_int_equal(pm_knn_gather(&t.map, &q, 0, nq, &p, got, &st), PM_ERR_INPUT);
    /* glossy queries need photon directions */
    test_map_t nodir;
    map_make(&nodir, n, g.pos, g.pow, g.nor, NULL, NULL);
    p.k = 10;
    assert_int_equal(pm_knn_gather(&nodir.map, &q, 0, nq, &p, got, &st), PM_ERR_INPUT);
    map_free(&nodir);
    glossy_scene_free(&g);
    free(got), free(want);
}

static void test_reverse_gather_matches_brute_force(void **state)
{
    /* more queries than one subtree holds, so that the tree is cut into subtrees and the
     * nodes above them */
    const uint32_t n = 2000;
    const uint64_t nq = 20000;
    glossy_scene_t g;
    glossy_scene_make(&g, n, nq, 51);
    const pm_gather_queries_t q = g.q;
    const test_map_t t = g.t;
    double *got = malloc(nq * 24), *want = malloc(nq * 24), *again = malloc(nq * 24);
    for (int kernel = 0; kernel <= 1; kernel++) {
        pm_gather_params_t gp = {
            .radius = 0.06, .kernel = (pm_kernel_t)kernel, .normal_cos = 0.5f, .isa = pm_cpu_best_isa()};
        pm_reverse_params_t p = {.radius = gp.radius, .kernel = gp.kernel, .normal_cos = gp.normal_cos};
        pm_gather_brute(&t.map, &q, 0, nq, &gp, want);
        pm_reverse_stats_t st;
        memset(got, 0xff, nq * 24);
        assert_int_equal(pm_reverse_gather(&t.map, &q, 0, nq, &p, got, &st), PM_OK);
        /* the same pairs, kernel values and BRDF in double: only the order of the sums differs */
        expect_close(got, want, nq, 1e-9, kernel ? "reverse, epanechnikov" : "reverse, uniform");
        assert_true(st.subtrees > 2);
        pm_gather_stats_t gs;
        assert_int_equal(pm_gather_run(&t.map, &q, 0, nq, &gp, again, &gs), PM_OK);
        assert_int_equal(st.shader_ops, gs.shader_ops); /* the very same photon-query pairs */
        expect_close(got, again, nq, 1e-4, "reverse against the packet gather");
    }
    /* a range: a tree over those queries only */
    pm_gather_params_t gp = {.radius = 0.06, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f};
    pm_reverse_params_t p = {.radius = 0.06, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f};
    pm_reverse_stats_t st;
    pm_gather_brute(&t.map, &q, 1000, 3000, &gp, want);
    assert_int_equal(pm_reverse_gather(&t.map, &q, 1000, 3000, &p, got, &st), PM_OK);
    expect_close(got, want, 2000, 1e-9, "reverse, range 1000:3000");
    /* glossy queries need photon directions; a radius must be positive */
    test_map_t nodir;
    map_make(&nodir, n, g.pos, g.pow, g.nor, NULL, NULL);
    assert_int_equal(pm_reverse_gather(&nodir.map, &q, 0, nq, &p, got, &st), PM_ERR_INPUT);
    map_free(&nodir);
    p.radius = 0.0;
    assert_int_equal(pm_reverse_gather(&t.map, &q, 0, nq, &p, got, &st), PM_ERR_USAGE);
    /* no photons: zeros */
    test_map_t e;
    map_make(&e, 0, g.pos, g.pow, g.nor, g.dir, NULL);
    p.radius = 0.06;
    assert_int_equal(pm_reverse_gather(&e.map, &q, 0, 10, &p, got, &st), PM_OK);
    for (int i = 0; i < 30; i++)
        assert_true(got[i] == 0.0);
    map_free(&e);
    glossy_scene_free(&g);
    free(got), free(want), free(again);
}

static void test_baselines_same_result_for_any_thread_count(void **state)
{
    const uint64_t nq = 30000;
    glossy_scene_t g;
    glossy_scene_make(&g, 5000, nq, 61);
    const pm_gather_queries_t q = g.q;
    const test_map_t t = g.t;
    double *out[3];
    pm_reverse_params_t rp = {.radius = 0.05, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f};
    pm_knn_params_t kp = {.k = 30, .kernel = PM_KERNEL_UNIFORM, .normal_cos = 0.5f};
    int saved = omp_get_max_threads();
    for (int which = 0; which < 2; which++) {
        for (int th = 1; th <= 3; th++) {
            out[th - 1] = malloc(nq * 24);
            omp_set_num_threads(th);
            pm_reverse_stats_t rs;
            pm_knn_stats_t ks;
            if (which == 0)
                assert_int_equal(pm_reverse_gather(&t.map, &q, 0, nq, &rp, out[th - 1], &rs), PM_OK);
            else
                assert_int_equal(pm_knn_gather(&t.map, &q, 0, nq, &kp, out[th - 1], &ks), PM_OK);
        }
        assert_memory_equal(out[0], out[1], nq * 24);
        assert_memory_equal(out[0], out[2], nq * 24);
        free(out[0]), free(out[1]), free(out[2]);
    }
    omp_set_num_threads(saved);
    glossy_scene_free(&g);
}

static const struct CMUnitTest baseline_tests[] = {
    cmocka_unit_test(test_knn_gather_matches_brute_force),
    cmocka_unit_test(test_reverse_gather_matches_brute_force),
    cmocka_unit_test(test_baselines_same_result_for_any_thread_count),
};
UNIT_GROUP(unit_baselines, "baselines", baseline_tests);
