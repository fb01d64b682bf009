/* test_coverage.c: the density estimate's boundary correction (photonmap/coverage.h) and its
 * area samples (render/areasample.h): the spacing levels; samples that carry a mesh's area
 * exactly, on both sides of an open surface and on the outside only of a solid; and a photon's
 * power divided by the part of its kernel that lies on its surface (1 on an open plane, 1/2 at a
 * straight edge, nothing for a side with no surface). */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "math/rng.h"
#include "photonmap/coverage.h"
#include "render/areasample.h"
#include "render/rt.h"
#include "render/scene.h"
#include "unit.h"

#define CLOSED_BOX "tests/scenes/closed-box/scene.json"

static void test_coverage_levels(void **state)
{
    (void)state;
    const double hs[] = {1e-6, 1e-3, 0.3, 1.0, 4.0, 7.77, 1e4};
    for (size_t i = 0; i < sizeof hs / sizeof hs[0]; i++) {
        int k;
        assert_int_equal(pm_coverage_level(hs[i], &k), PM_OK);
        double s = pm_coverage_level_spacing(k), want = hs[i] / PM_COVERAGE_RATIO;
        assert_true(s <= want);
        assert_true(pm_coverage_level_spacing(k + 1) > want);
    }
    int k;
    assert_int_equal(pm_coverage_level(0.0, &k), PM_ERR_USAGE);
    assert_int_equal(pm_coverage_level(-1.0, &k), PM_ERR_USAGE);
    assert_int_equal(pm_coverage_level(NAN, &k), PM_ERR_USAGE);
    assert_int_equal(pm_coverage_level(INFINITY, &k), PM_ERR_USAGE);
    /* the seed is a function of the spacing alone */
    assert_true(pm_coverage_seed(0.25) == pm_coverage_seed(0.25));
    assert_true(pm_coverage_seed(0.25) != pm_coverage_seed(0.125));
}

static double area_sum(const pm_area_samples_t *a)
{
    double s = 0.0;
    for (uint64_t i = 0; i < a->n; i++)
        s += a->area[3 * i];
    return s;
}

/* The inward-wound closed box: 24 m^2 a side; a ray from either side of a face meets the front
 * of another face or nothing, so no side is left out, with or without the test. */
static void test_area_samples_open_sides(void **state)
{
    (void)state;
    pm_scene_t s;
    pm_rt_t rt;
    if (pm_scene_load(CLOSED_BOX, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(pm_rt_create(&s, 0, 0, &rt), PM_OK);
    pm_area_samples_t a, b;
    assert_int_equal(pm_area_samples_make(&s, NULL, 0.1, 0.0, 7, 1u << 20, &a), PM_OK);
    assert_true(fabs(area_sum(&a) - 48.0) < 48.0 * 1e-5);
    assert_int_equal(a.n, pm_area_samples_count(&s, 0.1));
    assert_true(fabs(a.total_area - 24.0) < 24.0 * 1e-9);
    assert_int_equal(pm_area_samples_make(&s, &rt, 0.1, 4.0, 7, 1u << 20, &b), PM_OK);
    assert_int_equal(b.hidden, 0);
    assert_int_equal(b.n, a.n);
    assert_memory_equal(b.pos, a.pos, 3 * sizeof(float) * a.n); /* the same seed: the same samples */
    /* every sample lies on the box and its normal is a face's, on one side or the other */
    for (uint64_t i = 0; i < a.n; i++) {
        const float *p = &a.pos[3 * i], *n = &a.normal[3 * i];
        double on = fmax(fabs(p[0]), fmax(fabs(p[1]), fabs(p[2])));
        assert_true(fabs(on - 1.0) < 1e-5);
        assert_true(fabs(fabs(n[0]) + fabs(n[1]) + fabs(n[2]) - 1.0) < 1e-5);
    }
    pm_area_samples_free(&b);
    pm_area_samples_free(&a);
    /* too many: refused, nothing made */
    assert_int_equal(pm_area_samples_make(&s, NULL, 0.001, 0.0, 7, 1000, &a), PM_ERR_USAGE);
    assert_null(a.pos);
    pm_area_samples_free(&a);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

/* A solid cube wound outward: the inner sides face the inside, which no photon reaches, and are
 * left out; the outer sides keep their 24 m^2. A reach shorter than the cube keeps both. */
static void test_area_samples_solid(void **state)
{
    (void)state;
    char dir[600], path[700];
    snprintf(dir, sizeof dir, "%s/coverage-solid", unit_tmpdir());
    assert_int_equal(mkdir(dir, 0755), 0);
    snprintf(path, sizeof path, "%s/cube.obj", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("mtllib cube.mtl\nusemtl grey\n"
          "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
          "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n",
          f);
    fclose(f);
    snprintf(path, sizeof path, "%s/cube.mtl", dir);
    assert_non_null(f = fopen(path, "w"));
    fputs("newmtl grey\nKd 0.5 0.5 0.5\n", f);
    fclose(f);
    snprintf(path, sizeof path, "%s/scene.json", dir);
    assert_non_null(f = fopen(path, "w"));
    fputs("{\"pmtk_scene\": 1, \"name\": \"cube\", \"meshes\": [{\"file\": \"cube.obj\"}],\n"
          " \"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_y\": 40, \"width\": 8, \"height\": 8},\n"
          " \"point_lights\": [{\"position\": [0, 4, 0], \"intensity\": [1, 1, 1]}]}\n",
          f);
    fclose(f);
    pm_scene_t s;
    pm_rt_t rt;
    if (pm_scene_load(path, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(pm_rt_create(&s, 0, 0, &rt), PM_OK);
    pm_area_samples_t a;
    assert_int_equal(pm_area_samples_make(&s, &rt, 0.1, 4.0, 3, 1u << 20, &a), PM_OK);
    assert_true(fabs(area_sum(&a) - 24.0) < 24.0 * 1e-5);
    assert_int_equal(a.hidden, a.n);
    for (uint64_t i = 0; i < a.n; i++) { /* outward: the normal points the way the point lies */
        const float *p = &a.pos[3 * i], *n = &a.normal[3 * i];
        assert_true(p[0] * n[0] + p[1] * n[1] + p[2] * n[2] > 0.99f);
    }
    pm_area_samples_free(&a);
    assert_int_equal(pm_area_samples_make(&s, &rt, 0.1, 1.0, 3, 1u << 20, &a), PM_OK);
    assert_int_equal(a.hidden, 0);
    assert_true(fabs(area_sum(&a) - 48.0) < 48.0 * 1e-5);
    pm_area_samples_free(&a);
    /* the same samples, in the same order, on one thread as on several (the inner sides left out
     * between kept ones: the compaction's order is tested too) */
    pm_area_samples_t one, many;
    int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    assert_int_equal(pm_area_samples_make(&s, &rt, 0.1, 4.0, 3, 1u << 20, &one), PM_OK);
    omp_set_num_threads(threads > 1 ? threads : 2);
    assert_int_equal(pm_area_samples_make(&s, &rt, 0.1, 4.0, 3, 1u << 20, &many), PM_OK);
    omp_set_num_threads(threads);
    assert_int_equal(one.n, many.n);
    assert_int_equal(one.hidden, many.hidden);
    assert_memory_equal(one.pos, many.pos, 3 * sizeof(float) * one.n);
    assert_memory_equal(one.normal, many.normal, 3 * sizeof(float) * one.n);
    assert_memory_equal(one.area, many.area, 3 * sizeof(float) * one.n);
    pm_area_samples_free(&one);
    pm_area_samples_free(&many);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

/* Area samples of the square [0, 10]^2 of the plane z = 0, upward, stratified per cell of s. */
static void plane_samples(double s, float **pos, float **normal, float **area, uint64_t *n)
{
    uint64_t side = (uint64_t)(10.0 / s + 0.5), k = 0;
    *n = side * side;
    *pos = malloc(*n * 3 * sizeof(float)), *normal = malloc(*n * 3 * sizeof(float));
    *area = malloc(*n * 3 * sizeof(float));
    assert_non_null(*pos), assert_non_null(*normal), assert_non_null(*area);
    pm_rng_t rng;
    pm_rng_init(&rng, 11, 0);
    for (uint64_t i = 0; i < side; i++)
        for (uint64_t j = 0; j < side; j++, k++) {
            (*pos)[3 * k] = (float)((i + pm_rng_double(&rng)) * s);
            (*pos)[3 * k + 1] = (float)((j + pm_rng_double(&rng)) * s);
            (*pos)[3 * k + 2] = 0.0f;
            (*normal)[3 * k] = (*normal)[3 * k + 1] = 0.0f, (*normal)[3 * k + 2] = 1.0f;
            (*area)[3 * k] = (*area)[3 * k + 1] = (*area)[3 * k + 2] = (float)(s * s);
        }
}

static void test_coverage_plane_edge(void **state)
{
    (void)state;
    float *pos, *normal, *area;
    uint64_t n;
    plane_samples(0.05, &pos, &normal, &area, &n);
    pm_coverage_t cov;
    memset(&cov, 0, sizeof cov);
    assert_int_equal(pm_coverage_build(&cov, pos, normal, area, n, 0.05), PM_OK);
    /* photons: the middle, an edge's middle, the middle facing down (no surface on that side) */
    const float ppos[] = {5, 5, 0, 0, 5, 0, 5, 5, 0}, pnrm[] = {0, 0, 1, 0, 0, 1, 0, 0, -1};
    const float ppow[] = {1, 2, 3, 1, 1, 1, 1, 1, 1};
    for (int kernel = 0; kernel < 2; kernel++) {
        pm_coverage_t ph;
        memset(&ph, 0, sizeof ph);
        assert_int_equal(pm_coverage_build(&ph, ppos, pnrm, ppow, 3, 1.0), PM_OK);
        const pm_gather_params_t p = {
            .radius = 0.5, .kernel = (pm_kernel_t)kernel, .normal_cos = 0.5f, .isa = PM_ISA_SCALAR};
        assert_int_equal(pm_coverage_apply(&cov, &ph.table, &ph.map, &p), PM_OK);
        /* the map's node order is its own: find each photon by its normal and x */
        int seen = 0;
        for (uint32_t i = 0; i < ph.map.n; i++) {
            const float *x = &ph.map.pos[3 * i], *nm = &ph.map.normal[3 * i], *w = &ph.map.power[3 * i];
            if (nm[2] < 0.0f) { /* nothing under it: divided by the floor PM_COVERAGE_MIN */
                assert_float_equal(w[0], 1.0 / PM_COVERAGE_MIN, 1e-5);
                seen |= 4;
            } else if (x[0] > 1.0f) { /* open plane: c = 1 within the samples' scatter */
                assert_float_equal(w[0], 1.0f, 0.02f);
                assert_float_equal(w[2], 3.0f, 0.06f); /* each channel alike */
                seen |= 1;
            } else { /* a straight edge: half the disc */
                assert_float_equal(w[0], 2.0f, 0.06f);
                seen |= 2;
            }
        }
        assert_int_equal(seen, 7);
        pm_coverage_free(&ph);
    }
    /* the queries' side: each query's result divided by its own disc's covered part */
    const pm_gather_queries_t q = {.n = 3, .pos = ppos, .normal = pnrm};
    double out[9] = {1, 1, 1, 1, 1, 1, 1, 1, 1};
    const pm_gather_params_t pq = {
        .radius = 0.5, .kernel = PM_KERNEL_EPANECHNIKOV, .normal_cos = 0.5f, .isa = PM_ISA_SCALAR};
    assert_int_equal(pm_coverage_apply_queries(&cov, &q, 1, 3, &pq, out), PM_OK); /* queries 1 and 2 */
    assert_float_equal(out[0], 2.0, 0.06);                                        /* the edge */
    assert_float_equal(out[5], 1.0 / PM_COVERAGE_MIN, 1e-9);                      /* facing down */
    assert_float_equal(out[6], 1.0, 0.0);                                         /* not in the range */
    /* fixed widths only */
    const pm_gather_params_t pv = {.radius = 0.5, .variable = 1, .isa = PM_ISA_SCALAR};
    pm_coverage_t ph;
    memset(&ph, 0, sizeof ph);
    assert_int_equal(pm_coverage_build(&ph, ppos, pnrm, ppow, 3, 1.0), PM_OK);
    assert_int_equal(pm_coverage_apply(&cov, &ph.table, &ph.map, &pv), PM_ERR_USAGE);
    pm_coverage_free(&ph);
    pm_coverage_free(&cov);
    free(pos), free(normal), free(area);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_coverage_levels),
    cmocka_unit_test(test_area_samples_open_sides),
    cmocka_unit_test(test_area_samples_solid),
    cmocka_unit_test(test_coverage_plane_edge),
};
UNIT_GROUP(unit_coverage, "coverage", tests);
