/* test_adaptive.c: adaptive passes (common/image/adaptive.c and composite's per-pixel weights):
 * the rays a multiplier gives a pixel, the map made from a running image (uniform where the
 * error is even, a bright spot's neighbours raised, the mean 1 and the clamp kept), the density
 * files' checks, and the per-pixel weighted running mean on a synthetic three-pass example. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/formats.h"
#include "image/adaptive.h"
#include "image/composite.h"
#include "unit.h"

static void tmp_path(char *out, size_t cap, const char *name)
{
    snprintf(out, cap, "%s/adaptive-%s", unit_tmpdir(), name);
}

static void test_adaptive_count(void **state)
{
    (void)state;
    assert_int_equal(pm_adaptive_count(1.0f, 16), 16);
    assert_int_equal(pm_adaptive_count(0.25f, 16), 4);
    assert_int_equal(pm_adaptive_count(8.0f, 16), 128);
    assert_int_equal(pm_adaptive_count(0.3f, 1), 1); /* at least one ray */
    assert_int_equal(pm_adaptive_count(1.5f, 1), 2); /* to the nearest, halves up */
    assert_int_equal(pm_adaptive_count(1.4f, 5), 7);
    assert_int_equal(pm_adaptive_count(1e6f, 16), 0); /* beyond PM_ADAPTIVE_RAYS_MAX: the caller's error */
    assert_int_equal(pm_adaptive_count(NAN, 16), 0);
}

static void test_adaptive_make(void **state)
{
    (void)state;
    enum { W = 8, H = 6, N = W * H };
    double mean[3 * N], var[3 * N];
    float m[N], again[N];
    for (int i = 0; i < 3 * N; i++)
        mean[i] = 1.0, var[i] = 0.01;
    /* one pass: no spread known, the uniform map */
    pm_adaptive_make(mean, var, NULL, 1.0, 1, W, H, m);
    for (int i = 0; i < N; i++)
        assert_true(m[i] == 1.0f);
    /* the same relative error everywhere: uniform too */
    pm_adaptive_make(mean, var, NULL, 4.0, 4, W, H, m);
    for (int i = 0; i < N; i++)
        assert_true(fabsf(m[i] - 1.0f) < 1e-6f);
    /* one noisy pixel (3, 2): it and its 3 x 3 neighbours get the most, the rest no less than a
     * quarter, the mean stays 1 */
    for (int k = 0; k < 3; k++)
        var[3 * (2 * W + 3) + k] = 4.0;
    pm_adaptive_make(mean, var, NULL, 4.0, 4, W, H, m);
    double sum = 0.0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float v = m[y * W + x];
            sum += v;
            assert_true(v >= (float)PM_ADAPTIVE_MIN && v <= (float)PM_ADAPTIVE_MAX);
            if (abs(x - 3) <= 1 && abs(y - 2) <= 1)
                assert_true(v == m[2 * W + 3] && v > 1.0f);
            else
                assert_true(v < 1.0f);
        }
    assert_true(fabs(sum / N - 1.0) < 1e-5);
    /* deterministic; a pixel's earlier weights count: twice the weight, more rays */
    pm_adaptive_make(mean, var, NULL, 4.0, 4, W, H, again);
    assert_memory_equal(m, again, sizeof m);
    double wsum[N];
    for (int i = 0; i < N; i++)
        wsum[i] = 4.0;
    wsum[0] = 16.0;
    for (int k = 0; k < 3; k++)
        var[k] = 0.01;
    pm_adaptive_make(mean, var, wsum, 4.0, 4, W, H, again);
    assert_true(again[0] > again[W - 1]);
    /* nothing but zero spread: uniform */
    memset(var, 0, sizeof var);
    pm_adaptive_make(mean, var, NULL, 4.0, 4, W, H, m);
    for (int i = 0; i < N; i++)
        assert_true(m[i] == 1.0f);
}

/* A w x h radiance buffer of value x[i] per channel value i; with map, an adaptive pass of
 * `primary` rays that map steered. */
static void write_pass(const char *path, uint32_t w, uint32_t h, const double *x, const char *map, uint64_t hash,
                       int primary)
{
    pm_table_t t;
    assert_int_equal(pm_table_alloc(&t, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, (uint64_t)w * h), PM_OK);
    memcpy(t.col[PM_RADIANCE_RGB], x, 3 * sizeof *x * w * h);
    pm_header_set(&t.hdr, "width", "%u", w);
    pm_header_set(&t.hdr, "height", "%u", h);
    pm_header_set(&t.hdr, "component", "direct");
    pm_header_set(&t.hdr, "primary", "%d", primary);
    if (map)
        pm_header_set(&t.hdr, "adaptive", "%s xxh3:%016" PRIx64, map, hash);
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    pm_table_free(&t);
}

static pm_result_t add_pass(const char *buf, const char *st, uint64_t pass)
{
    char arg[700];
    snprintf(arg, sizeof arg, "%s", buf);
    char *args[] = {arg}, *argv[] = {"composite", "test"};
    pm_composite_t *c;
    pm_result_t r = pm_composite_open(&c, args, 1, PM_ONLY_ALL);
    if (r == PM_OK)
        r = pm_composite_sum(c, 2, argv, NULL, NULL);
    if (r == PM_OK)
        r = pm_composite_accumulate(c, st, pass, 1.0);
    if (r == PM_OK)
        r = pm_composite_write_state(c, st);
    pm_composite_free(c);
    return r;
}

/* Three passes of a 2 x 1 image: uniform, adaptive with multipliers 0.5 and 2 at 4 primary
 * rays (2 and 8 rays: weights 0.5 and 2), uniform again; the running image is the per-pixel
 * weighted mean with the weighted variance S / (W (n - 1)), S = sum w (x - mean)^2. */
static void test_weighted_running_mean(void **state)
{
    (void)state;
    char map[600], b1[600], b2[600], b3[600], st[600], wpath[700];
    tmp_path(map, sizeof map, "map.pm");
    tmp_path(b1, sizeof b1, "pass1.pm");
    tmp_path(b2, sizeof b2, "pass2.pm");
    tmp_path(b3, sizeof b3, "pass3.pm");
    tmp_path(st, sizeof st, "running.pm");
    snprintf(wpath, sizeof wpath, "%s.weight", st);
    remove(st);
    const float mult[2] = {0.5f, 2.0f};
    assert_int_equal(pm_adaptive_write(map, PM_DENSITY_MULTIPLIER, 2, 1, mult, NULL, 0, NULL, NULL), PM_OK);
    float *back = NULL;
    uint64_t hash = 0;
    assert_int_equal(pm_adaptive_read(map, PM_DENSITY_MULTIPLIER, 2, 1, &back, &hash, NULL), PM_OK);
    assert_true(back[0] == 0.5f && back[1] == 2.0f);
    free(back);
    const double x[3][6] = {{1, 2, 3, 4, 5, 6}, {2, 2, 2, 8, 8, 8}, {0.5, 1, 1.5, 2, 2.5, 3}};
    const double w[3][2] = {{1, 1}, {0.5, 2}, {1, 1}};
    write_pass(b1, 2, 1, x[0], NULL, 0, 4);
    write_pass(b2, 2, 1, x[1], map, hash, 4);
    write_pass(b3, 2, 1, x[2], NULL, 0, 4);
    const char *bufs[3] = {b1, b2, b3};
    for (int k = 0; k < 3; k++) {
        assert_int_equal(add_pass(bufs[k], st, (uint64_t)k + 1), PM_OK);
        pm_table_t t;
        assert_int_equal(pm_table_read(st, &pm_radiance_schema, 3u, &t), PM_OK);
        const double *mean = t.col[PM_RADIANCE_RGB], *var = t.col[PM_RADIANCE_VARIANCE];
        for (int i = 0; i < 6; i++) {
            double sw = 0.0, swx = 0.0, s = 0.0;
            for (int j = 0; j <= k; j++)
                sw += w[j][i / 3], swx += w[j][i / 3] * x[j][i];
            double mu = swx / sw;
            for (int j = 0; j <= k; j++)
                s += w[j][i / 3] * (x[j][i] - mu) * (x[j][i] - mu);
            assert_true(fabs(mean[i] - mu) < 1e-12 * fabs(mu));
            assert_true(fabs(var[i] - (k ? s / (sw * k) : 0.0)) < 1e-12);
        }
        /* the per-pixel weights beside the state once an adaptive pass is in it */
        assert_int_equal(pm_header_get(&t.hdr, "pixel_weights") != NULL, k >= 1);
        pm_table_free(&t);
        if (k >= 1) {
            float *ws = NULL;
            assert_int_equal(pm_adaptive_read(wpath, PM_DENSITY_WEIGHT, 2, 1, &ws, NULL, NULL), PM_OK);
            assert_true(fabsf(ws[0] - (float)(1.0 + 0.5 + (k >= 2))) < 1e-6f);
            assert_true(fabsf(ws[1] - (float)(1.0 + 2.0 + (k >= 2))) < 1e-6f);
            free(ws);
        }
    }
    /* a map changed after its pass was traced is refused: the weights would not be the rays' */
    remove(st);
    const float other[2] = {1.0f, 1.0f};
    assert_int_equal(pm_adaptive_write(map, PM_DENSITY_MULTIPLIER, 2, 1, other, NULL, 0, NULL, NULL), PM_OK);
    assert_int_equal(add_pass(b2, st, 1), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "is not the one pass"));
}

/* Density files: the wrong kind or size is an input error naming the file. */
static void test_density_checks(void **state)
{
    (void)state;
    char map[600];
    tmp_path(map, sizeof map, "check.pm");
    const float v[6] = {1, 2, 3, 4, 5, 6};
    assert_int_equal(pm_adaptive_write(map, PM_DENSITY_WEIGHT, 3, 2, v, NULL, 0, NULL, NULL), PM_OK);
    float *back = NULL;
    assert_int_equal(pm_adaptive_read(map, PM_DENSITY_MULTIPLIER, 3, 2, &back, NULL, NULL), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "is kind=weight, not multiplier"));
    assert_int_equal(pm_adaptive_read(map, PM_DENSITY_WEIGHT, 2, 3, &back, NULL, NULL), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "is 3x2, the image 2x3"));
    assert_null(back);
    const float bad[6] = {1, 2, -3, 4, 5, 6};
    assert_int_not_equal(pm_adaptive_write(map, PM_DENSITY_WEIGHT, 3, 2, bad, NULL, 0, NULL, NULL), PM_OK);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_adaptive_count),
    cmocka_unit_test(test_adaptive_make),
    cmocka_unit_test(test_weighted_running_mean),
    cmocka_unit_test(test_density_checks),
};

UNIT_GROUP(unit_adaptive, "adaptive", tests);
