/* test_api.c: the public C API (include/pmtk.h, common/api/api.c) as a renderer uses it: a
 * photon map built from arrays and gathered (fixed and per-query widths, every ISA this CPU
 * runs, one and two threads) against a brute-force sum in double; the k-NN baseline against a
 * sort; Hilbert order as a permutation; files of every format written and read back; and every
 * bad argument refused with its class and a message through the error callback. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "pmtk.h"
#include "unit.h"

enum { NP = 3000, NQ = 515 }; /* NQ: not a multiple of any packet width */

typedef struct {
    float pos[3 * NP], pow[3 * NP], nor[3 * NP];
    float qpos[3 * NQ], qnor[3 * NQ], qrad[NQ];
} scene_t;

/* Photons on two perpendicular unit squares (floor z = 0 facing +z, wall x = 0 facing +x), and
 * queries on the same, so the normal test matters near the edge. */
static scene_t *make_scene(void)
{
    scene_t *s = calloc(1, sizeof *s);
    pm_rng_t rng;
    pm_rng_init(&rng, 7, 0);
    for (int i = 0; i < NP + NQ; i++) {
        int wall = i % 3 == 0;
        float u = pm_rng_float(&rng), v = pm_rng_float(&rng);
        float p[3] = {wall ? 0.0f : u, v, wall ? u : 0.0f}, n[3] = {wall ? 1.0f : 0.0f, 0.0f, wall ? 0.0f : 1.0f};
        float *dp = i < NP ? &s->pos[3 * i] : &s->qpos[3 * (i - NP)];
        float *dn = i < NP ? &s->nor[3 * i] : &s->qnor[3 * (i - NP)];
        memcpy(dp, p, sizeof p);
        memcpy(dn, n, sizeof n);
        if (i < NP)
            for (int k = 0; k < 3; k++)
                s->pow[3 * i + k] = 0.001f * (1.0f + (float)k) * pm_rng_float(&rng);
        else
            s->qrad[i - NP] = 0.03f + 0.1f * pm_rng_float(&rng);
    }
    return s;
}

/* The estimator in double, every photon against every query (uniform kernel). */
static void brute(const scene_t *s, const float *radius, double h, double *out)
{
    for (int q = 0; q < NQ; q++) {
        double r = radius ? radius[q] : h, sum[3] = {0, 0, 0};
        for (int i = 0; i < NP; i++) {
            float dx = s->qpos[3 * q] - s->pos[3 * i], dy = s->qpos[3 * q + 1] - s->pos[3 * i + 1],
                  dz = s->qpos[3 * q + 2] - s->pos[3 * i + 2];
            float d2 = dx * dx + dy * dy + dz * dz, rf = (float)r;
            float c = s->qnor[3 * q] * s->nor[3 * i] + s->qnor[3 * q + 1] * s->nor[3 * i + 1] +
                      s->qnor[3 * q + 2] * s->nor[3 * i + 2];
            if (d2 < rf * rf && c >= 0.5f)
                for (int k = 0; k < 3; k++)
                    sum[k] += s->pow[3 * i + k] / (M_PI * (double)rf * rf);
        }
        for (int k = 0; k < 3; k++)
            out[3 * q + k] = sum[k];
    }
}

static void check_close(const double *a, const double *b, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (fabs(a[i] - b[i]) > 1e-5 * fabs(b[i]) + 1e-9) {
            fprintf(stderr, "value %zu: %.9g, expected %.9g\n", i, a[i], b[i]);
            fail();
        }
}

static pmtk_context_t *context(void)
{
    pmtk_context_t *ctx = NULL;
    assert_int_equal(pmtk_context_create(&ctx), PMTK_OK);
    return ctx;
}

static pmtk_photonmap_t *build(pmtk_context_t *ctx, const scene_t *s)
{
    pmtk_photons_t ph = {.count = NP, .position = s->pos, .power = s->pow, .normal = s->nor};
    pmtk_photonmap_t *map = NULL;
    assert_int_equal(pmtk_photonmap_build(ctx, &ph, &map), PMTK_OK);
    assert_int_equal(pmtk_photonmap_count(map), NP);
    return map;
}

static void test_api_gather_fixed_and_per_query(void **state)
{
    scene_t *s = make_scene();
    pmtk_context_t *ctx = context();
    pmtk_photonmap_t *map = build(ctx, s);
    double *want = malloc(3 * NQ * sizeof *want), *got = malloc(3 * NQ * sizeof *got),
           *first = malloc(3 * NQ * sizeof *first);
    for (int per_query = 0; per_query < 2; per_query++) {
        brute(s, per_query ? s->qrad : NULL, 0.08, want);
        pmtk_queries_t q = {.count = NQ, .position = s->qpos, .normal = s->qnor, .radius = per_query ? s->qrad : NULL};
        pmtk_gather_params_t p;
        pmtk_gather_params_init(&p);
        p.radius = 0.08;
        p.normal_cos = 0.5f;
        int runs = 0;
        for (int isa = PMTK_ISA_SCALAR; isa <= PMTK_ISA_AVX512; isa++) {
            if (!pmtk_isa_supported((pmtk_isa_t)isa))
                continue;
            for (int threads = 1; threads <= 2; threads++) {
                p.isa = (pmtk_isa_t)isa;
                assert_int_equal(pmtk_context_set_threads(ctx, threads), PMTK_OK);
                pmtk_gather_stats_t st;
                assert_int_equal(pmtk_gather(ctx, map, &q, &p, got, &st), PMTK_OK);
                check_close(got, want, 3 * NQ);
                assert_true(st.shader_ops > 0);
                if (threads == 1)
                    memcpy(first, got, 3 * NQ * sizeof *got);
                else /* the thread count changes nothing, bit for bit */
                    assert_memory_equal(first, got, 3 * NQ * sizeof *got);
                runs++;
            }
        }
        assert_true(runs >= 2);
    }
    /* per-query widths all equal to the fixed one give the fixed gather's sums exactly */
    float *same = malloc(NQ * sizeof *same);
    for (int i = 0; i < NQ; i++)
        same[i] = 0.08f;
    pmtk_queries_t q = {.count = NQ, .position = s->qpos, .normal = s->qnor};
    pmtk_gather_params_t p;
    pmtk_gather_params_init(&p);
    p.radius = 0.08f;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, want, NULL), PMTK_OK);
    q.radius = same;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, got, NULL), PMTK_OK);
    assert_memory_equal(want, got, 3 * NQ * sizeof *got);
    free(same);
    free(want), free(got), free(first);
    pmtk_photonmap_destroy(map);
    pmtk_context_destroy(ctx);
    free(s);
}

static int by_d2(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void test_api_knn(void **state)
{
    scene_t *s = make_scene();
    pmtk_context_t *ctx = context();
    pmtk_photonmap_t *map = build(ctx, s);
    enum { K = 20 };
    double *got = malloc(3 * NQ * sizeof *got);
    pmtk_queries_t q = {.count = NQ, .position = s->qpos, .normal = s->qnor};
    pmtk_knn_params_t p = {.k = K, .kernel = PMTK_KERNEL_UNIFORM, .normal_cos = 0.5f};
    assert_int_equal(pmtk_knn_gather(ctx, map, &q, &p, got), PMTK_OK);
    /* query 0 by a sort: the K nearest photons whose normals agree, over pi r_K^2 */
    double(*d)[4] = malloc(NP * sizeof *d);
    int n = 0;
    for (int i = 0; i < NP; i++) {
        float c = s->qnor[0] * s->nor[3 * i] + s->qnor[1] * s->nor[3 * i + 1] + s->qnor[2] * s->nor[3 * i + 2];
        if (c < 0.5f)
            continue;
        double d2 = 0;
        for (int k = 0; k < 3; k++)
            d2 += ((double)s->qpos[k] - s->pos[3 * i + k]) * ((double)s->qpos[k] - s->pos[3 * i + k]);
        d[n][0] = d2;
        for (int k = 0; k < 3; k++)
            d[n][1 + k] = s->pow[3 * i + k];
        n++;
    }
    qsort(d, (size_t)n, sizeof *d, by_d2);
    for (int k = 0; k < 3; k++) {
        double sum = 0;
        for (int i = 0; i < K; i++)
            sum += d[i][1 + k];
        double want = sum / (M_PI * d[K - 1][0]);
        assert_true(fabs(got[k] - want) <= 1e-4 * want);
    }
    free(d);
    free(got);
    pmtk_photonmap_destroy(map);
    pmtk_context_destroy(ctx);
    free(s);
}

static void test_api_hilbert(void **state)
{
    scene_t *s = make_scene();
    pmtk_context_t *ctx = context();
    uint32_t *perm = malloc(NP * sizeof *perm);
    unsigned char *seen = calloc(NP, 1);
    assert_int_equal(pmtk_hilbert_order(ctx, s->pos, 12, NP, 1, perm), PMTK_OK);
    for (int i = 0; i < NP; i++) {
        assert_true(perm[i] < NP && !seen[perm[i]]);
        seen[perm[i]] = 1;
    }
    /* consecutive points are near: the mean step is far below a random order's (~0.6) */
    double step = 0;
    for (int i = 1; i < NP; i++) {
        const float *a = &s->pos[3 * perm[i - 1]], *b = &s->pos[3 * perm[i]];
        step += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
    }
    assert_true(step / (NP - 1) < 0.1);
    assert_int_equal(pmtk_hilbert_order(ctx, s->pos, 8, NP, 1, perm), PMTK_ERR_USAGE);
    free(perm), free(seen);
    pmtk_context_destroy(ctx);
    free(s);
}

static void test_api_files(void **state)
{
    pmtk_context_t *ctx = context();
    char path[600];
    snprintf(path, sizeof path, "%s/api-queries.pm", unit_tmpdir());
    const char *chans[] = {"material", NULL};
    pmtk_file_t *f = NULL;
    assert_int_equal(pmtk_file_create(ctx, "queries", chans, 4, &f), PMTK_OK);
    assert_string_equal(pmtk_file_format(f), "queries");
    pmtk_type_t type;
    unsigned comps;
    float *pos = pmtk_file_channel(f, "position", &type, &comps);
    float *nor = pmtk_file_channel(f, "normal", NULL, NULL);
    float *w = pmtk_file_channel(f, "weight", NULL, NULL);
    uint32_t *pix = pmtk_file_channel(f, "pixel", &type, NULL);
    assert_non_null(pos), assert_non_null(nor), assert_non_null(w), assert_non_null(pix);
    assert_int_equal(type, PMTK_TYPE_U32);
    assert_non_null(pmtk_file_channel(f, "material", &type, &comps));
    assert_int_equal(type, PMTK_TYPE_U16);
    assert_int_equal(comps, 1);
    assert_null(pmtk_file_channel(f, "direction", NULL, NULL));
    for (int i = 0; i < 4; i++) {
        pos[3 * i] = (float)i;
        nor[3 * i + 2] = 1.0f;
        w[3 * i] = w[3 * i + 1] = w[3 * i + 2] = 0.5f;
        pix[i] = (uint32_t)i;
    }
    assert_int_equal(pmtk_file_header_set(ctx, f, "width", "2"), PMTK_OK);
    assert_int_equal(pmtk_file_header_set(ctx, f, "height", "2"), PMTK_OK);
    assert_int_equal(pmtk_file_header_set(ctx, f, "bad\nkey", "1"), PMTK_ERR_USAGE);
    pmtk_result_t r = pmtk_file_write(ctx, f, path);
    if (r != PMTK_OK)
        fprintf(stderr, "write: %s\n", pmtk_context_error(ctx));
    assert_int_equal(r, PMTK_OK);
    pmtk_file_t *g = NULL;
    assert_int_equal(pmtk_file_read(ctx, path, &g), PMTK_OK);
    assert_int_equal(pmtk_file_count(g), 4);
    assert_string_equal(pmtk_file_header_get(g, "width"), "2");
    assert_memory_equal(pmtk_file_channel(g, "position", NULL, NULL), pos, 12 * sizeof(float));
    pmtk_file_destroy(g);
    /* a value a reader refuses is refused on write, and no file is left */
    nor[2] = 0.0f;
    char bad[600];
    snprintf(bad, sizeof bad, "%s/api-bad.pm", unit_tmpdir());
    assert_int_equal(pmtk_file_write(ctx, f, bad), PMTK_ERR_INPUT);
    assert_true(strlen(pmtk_context_error(ctx)) > 0);
    FILE *probe = fopen(bad, "rb");
    assert_null(probe);
    pmtk_file_destroy(f);
    /* a golden file of each format reads */
    const char *golden[] = {"photons", "photonmap", "queries", "radiance"};
    for (int i = 0; i < 4; i++) {
        char gp[128];
        snprintf(gp, sizeof gp, "tests/golden/%s-all.pm", golden[i]);
        assert_int_equal(pmtk_file_read(ctx, gp, &g), PMTK_OK);
        assert_string_equal(pmtk_file_format(g), golden[i]);
        pmtk_file_destroy(g);
    }
    assert_int_equal(pmtk_file_create(ctx, "nope", NULL, 1, &f), PMTK_ERR_USAGE);
    assert_int_equal(pmtk_file_create(ctx, "photons", (const char *[]){"colour", NULL}, 1, &f), PMTK_ERR_USAGE);
    pmtk_context_destroy(ctx);
}

static void test_api_photonmap_file_round_trip(void **state)
{
    scene_t *s = make_scene();
    pmtk_context_t *ctx = context();
    pmtk_photonmap_t *map = build(ctx, s), *back = NULL;
    char path[600];
    snprintf(path, sizeof path, "%s/api.pmap", unit_tmpdir());
    assert_int_equal(pmtk_photonmap_write(ctx, map, path), PMTK_OK);
    assert_int_equal(pmtk_photonmap_read(ctx, path, &back), PMTK_OK);
    double *a = malloc(3 * NQ * sizeof *a), *b = malloc(3 * NQ * sizeof *b);
    pmtk_queries_t q = {.count = NQ, .position = s->qpos, .normal = s->qnor};
    pmtk_gather_params_t p;
    pmtk_gather_params_init(&p);
    p.radius = 0.05;
    p.kernel = PMTK_KERNEL_EPANECHNIKOV;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, a, NULL), PMTK_OK);
    assert_int_equal(pmtk_gather(ctx, back, &q, &p, b, NULL), PMTK_OK);
    assert_memory_equal(a, b, 3 * NQ * sizeof *a);
    /* the file is one pm-info checks: a photonmap */
    pmtk_file_t *f = NULL;
    assert_int_equal(pmtk_file_read(ctx, path, &f), PMTK_OK);
    assert_string_equal(pmtk_file_format(f), "photonmap");
    pmtk_file_destroy(f);
    free(a), free(b);
    pmtk_photonmap_destroy(map);
    pmtk_photonmap_destroy(back);
    pmtk_context_destroy(ctx);
    free(s);
}

typedef struct {
    int calls;
    pmtk_result_t code;
    char message[256];
} seen_t;

static void on_error(void *user, pmtk_result_t code, const char *message)
{
    seen_t *s = user;
    s->calls++;
    s->code = code;
    snprintf(s->message, sizeof s->message, "%s", message);
}

static void test_api_errors(void **state)
{
    scene_t *s = make_scene();
    pmtk_context_t *ctx = context(), *other = context();
    seen_t seen = {0};
    pmtk_context_set_error_callback(ctx, on_error, &seen);
    assert_int_equal(pmtk_context_create(NULL), PMTK_ERR_USAGE);
    assert_int_equal(pmtk_context_set_threads(ctx, -1), PMTK_ERR_USAGE);
    assert_int_equal(seen.calls, 1);
    assert_int_equal(seen.code, PMTK_ERR_USAGE);
    assert_string_equal(pmtk_result_string(PMTK_ERR_INPUT), "input");
    assert_non_null(strstr(pmtk_version(), "pmtk "));

    /* a NaN photon: input, and the message names the photon and its value */
    s->pos[3 * 17 + 1] = NAN;
    pmtk_photons_t ph = {.count = NP, .position = s->pos, .power = s->pow, .normal = s->nor};
    pmtk_photonmap_t *map = (pmtk_photonmap_t *)&seen;
    assert_int_equal(pmtk_photonmap_build(ctx, &ph, &map), PMTK_ERR_INPUT);
    assert_null(map);
    assert_non_null(strstr(seen.message, "photon position 17"));
    assert_string_equal(pmtk_context_error(ctx), seen.message);
    assert_string_equal(pmtk_context_error(other), ""); /* no global state */
    s->pos[3 * 17 + 1] = 0.5f;
    s->nor[3 * 5] = 2.0f; /* not a unit normal */
    assert_int_equal(pmtk_photonmap_build(ctx, &ph, &map), PMTK_ERR_INPUT);
    s->nor[3 * 5] = s->nor[3 * 5 + 2] == 0.0f ? 1.0f : 0.0f;
    ph.power = NULL;
    assert_int_equal(pmtk_photonmap_build(ctx, &ph, &map), PMTK_ERR_USAGE);
    ph.power = s->pow;
    map = build(ctx, s);

    double out[3 * NQ];
    pmtk_queries_t q = {.count = NQ, .position = s->qpos, .normal = s->qnor};
    pmtk_gather_params_t p;
    pmtk_gather_params_init(&p);
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, out, NULL), PMTK_ERR_USAGE); /* radius 0 */
    assert_non_null(strstr(seen.message, "radius"));
    p.radius = 0.1;
    p.isa = (pmtk_isa_t)9;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, out, NULL), PMTK_ERR_USAGE);
    p.isa = PMTK_ISA_AUTO;
    s->qrad[300] = -1.0f; /* a bad per-query width names its query */
    q.radius = s->qrad;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, out, NULL), PMTK_ERR_USAGE);
    assert_non_null(strstr(seen.message, "query 300"));
    q.radius = NULL;
    s->qpos[3 * 4] = INFINITY;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, out, NULL), PMTK_ERR_INPUT);
    assert_non_null(strstr(seen.message, "query position 4"));
    s->qpos[3 * 4] = 0.5f;
    assert_int_equal(pmtk_gather(ctx, map, &q, &p, NULL, NULL), PMTK_ERR_USAGE);
    pmtk_knn_params_t kp = {.k = 0};
    assert_int_equal(pmtk_knn_gather(ctx, map, &q, &kp, out), PMTK_ERR_USAGE);
    /* an empty query set and an empty map are fine */
    pmtk_queries_t none = {0};
    assert_int_equal(pmtk_gather(ctx, map, &none, &p, NULL, NULL), PMTK_OK);
    pmtk_photons_t empty = {0};
    pmtk_photonmap_t *em = NULL;
    assert_int_equal(pmtk_photonmap_build(ctx, &empty, &em), PMTK_OK);
    assert_int_equal(pmtk_gather(ctx, em, &q, &p, out, NULL), PMTK_OK);
    assert_true(out[0] == 0.0 && out[3 * NQ - 1] == 0.0);
    pmtk_photonmap_destroy(em);

    pmtk_photonmap_t *r = NULL;
    assert_int_equal(pmtk_photonmap_read(ctx, "tests/golden/photons-all.pm", &r), PMTK_ERR_INPUT);
    assert_non_null(strstr(seen.message, "photons-all.pm"));
    assert_int_equal(pmtk_photonmap_read(ctx, "/nonexistent/x.pmap", &r), PMTK_ERR_INPUT);
    assert_null(r);
    pmtk_photonmap_destroy(map);
    pmtk_context_destroy(ctx);
    pmtk_context_destroy(other);
    free(s);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_api_gather_fixed_and_per_query),
    cmocka_unit_test(test_api_knn),
    cmocka_unit_test(test_api_hilbert),
    cmocka_unit_test(test_api_files),
    cmocka_unit_test(test_api_photonmap_file_round_trip),
    cmocka_unit_test(test_api_errors),
};
UNIT_GROUP(api_group, "api", tests)
