/* test_image.c: the image layer (common/image): the tone curves and the 8-bit preview, the
 * sum of radiance buffers composite writes (scales, --only, the checks across buffers, the
 * refusal of values beyond half), reading an image from a radiance buffer or an OpenEXR file,
 * and the error metrics against their formulas, with and without the reference's variance. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "formats/formats.h"
#include "image/composite.h"
#include "image/metrics.h"
#include "image/rgb.h"
#include "image/tone.h"
#include "unit.h"

static void tmp_path(char *out, size_t cap, const char *name)
{
    snprintf(out, cap, "%s/image-%s", unit_tmpdir(), name);
}

/* A w x h radiance buffer whose value i (of 3 w h) is base + i / 8, with a variance of
 * var_scale * value when var_scale > 0. */
static void write_buffer(const char *path, uint32_t w, uint32_t h, const char *component, const char *scene,
                         double base, double var_scale)
{
    pm_table_t t;
    uint32_t ch = 1u << PM_RADIANCE_RGB | (var_scale > 0 ? 1u << PM_RADIANCE_VARIANCE : 0u);
    assert_int_equal(pm_table_alloc(&t, &pm_radiance_schema, ch, (uint64_t)w * h), PM_OK);
    double *rgb = t.col[PM_RADIANCE_RGB], *var = t.col[PM_RADIANCE_VARIANCE];
    for (size_t i = 0; i < (size_t)3 * w * h; i++) {
        rgb[i] = base + (double)i / 8;
        if (var)
            var[i] = var_scale * rgb[i];
    }
    pm_header_set(&t.hdr, "width", "%u", w);
    pm_header_set(&t.hdr, "height", "%u", h);
    pm_header_set(&t.hdr, "component", "%s", component);
    if (scene)
        pm_header_set(&t.hdr, "SCENE", "%s", scene);
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    pm_table_free(&t);
}

static void test_tone_curves(void **state)
{
    assert_true(fabs(pm_luminance((double[3]){1, 1, 1}) - 1.0) < 1e-12);
    assert_true(fabs(pm_luminance((double[3]){0, 1, 0}) - 0.7152) < 1e-12);
    assert_true(pm_tone_filmic(0.0f) == 0.0f && pm_tone_filmic(-1.0f) == 0.0f && pm_tone_filmic(NAN) == 0.0f);
    assert_true(fabsf(pm_tone_filmic(1.0f) - 2.54f / 3.16f) < 1e-6f); /* about 0.8 at 1 */
    float prev = 0.0f;
    for (float x = 0.01f; x < 100.0f; x *= 1.5f) { /* rises, never past 1 */
        float y = pm_tone_filmic(x);
        assert_true(y >= prev && y <= 1.0f);
        prev = y;
    }
    assert_true(pm_tone_filmic(1e30f) == 1.0f);
}

static void test_tone_preview(void **state)
{
    const double rgb[6] = {0.0, 0.25, 0.5, 1.0, 2.0, -1.0};
    uint8_t out[6];
    assert_int_equal(pm_tone_rgb8(rgb, 2, 0.0, PM_TONE_SRGB, out), 2); /* 1 and 2 reach white */
    assert_int_equal(out[0], 0);
    assert_int_equal(out[3], 255);
    assert_int_equal(out[4], 255);
    assert_int_equal(out[5], 0);
    assert_true(out[1] > 0 && out[1] < out[2] && out[2] < 255);
    uint8_t brighter[6];
    assert_int_equal(pm_tone_rgb8(rgb, 2, 1.0, PM_TONE_SRGB, brighter), 3); /* 2^1: 0.5 reaches 1 */
    assert_int_equal(brighter[1], out[2]);                                  /* 0.25 x 2 is 0.5 */
    assert_int_equal(pm_tone_rgb8(rgb, 2, 0.0, PM_TONE_FILMIC, out), 0);    /* the shoulder: nothing clips */
    assert_true(out[4] < 255 && out[3] < out[4]);
}

static void test_composite_parse_input(void **state)
{
    char *p;
    double s;
    assert_int_equal(pm_composite_parse_input("a.pm", &p, &s), PM_OK);
    assert_string_equal(p, "a.pm");
    assert_true(s == 1.0);
    free(p);
    assert_int_equal(pm_composite_parse_input("a.pm:0.5", &p, &s), PM_OK);
    assert_string_equal(p, "a.pm");
    assert_true(s == 0.5);
    free(p);
    assert_int_equal(pm_composite_parse_input("a:b.pm", &p, &s), PM_OK); /* not a number: all path */
    assert_string_equal(p, "a:b.pm");
    assert_true(s == 1.0);
    free(p);
    assert_int_equal(pm_composite_parse_input("x:2:1", &p, &s), PM_OK); /* a file named x:2 */
    assert_string_equal(p, "x:2");
    free(p);
    assert_int_equal(pm_composite_parse_input(":3", &p, &s), PM_OK); /* nothing before the colon: a path */
    assert_string_equal(p, ":3");
    free(p);
}

static int notes;
static void count_note(void *ctx, const char *path, const char *same_as, uint64_t hash)
{
    (void)hash;
    assert_string_equal(path, same_as);
    notes += *(int *)ctx;
}

static void test_composite_sum(void **state)
{
    char d[600], ind[600], sum[600], a1[700], a2[700];
    tmp_path(d, sizeof d, "direct.pm");
    tmp_path(ind, sizeof ind, "indirect.pm");
    tmp_path(sum, sizeof sum, "sum.pm");
    write_buffer(d, 3, 2, "direct", "s xxh3:0000000000000001", 1.0, 0);
    write_buffer(ind, 3, 2, "indirect", "s xxh3:0000000000000001", 2.0, 0);
    snprintf(a1, sizeof a1, "%s", d);
    snprintf(a2, sizeof a2, "%s:0.5", ind);
    char *args[] = {a1, a2};
    char *argv[] = {"composite", "test"};
    pm_composite_t *c;
    assert_int_equal(pm_composite_open(&c, args, 2, PM_ONLY_ALL), PM_OK);
    const pm_composite_info_t *in = pm_composite_info(c);
    assert_int_equal(in->width, 3);
    assert_int_equal(in->height, 2);
    assert_int_equal(in->pixels, 6);
    assert_int_equal(in->buffers, 2);
    assert_string_equal(in->components, "total");
    assert_int_equal(pm_composite_sum(c, 2, argv, NULL, NULL), PM_OK);
    assert_int_equal(pm_composite_finish(c, 0), PM_OK);
    assert_int_equal(pm_composite_write_radiance(c, sum), PM_OK);
    pm_table_t t;
    assert_int_equal(pm_table_read(sum, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, &t), PM_OK);
    const double *v = t.col[PM_RADIANCE_RGB];
    double lmax = -1;
    for (int i = 0; i < 18; i++) {
        double want = 0.0 + (1.0 + i / 8.0) + 0.5 * (2.0 + i / 8.0); /* in the order given, from 0 */
        assert_true(v[i] == want);
        if (i % 3 == 2)
            lmax = fmax(lmax, pm_luminance(&v[i - 2]));
    }
    assert_true(fabs(in->luminance_max - lmax) < 1e-12);
    assert_string_equal(pm_header_get(&t.hdr, "component"), "total");
    assert_string_equal(pm_header_get(&t.hdr, "SCENE"), "s xxh3:0000000000000001");
    pm_table_free(&t);
    pm_composite_free(c);

    /* --only direct leaves the indirect buffer out; the same file twice is heard of once */
    char *twice[] = {a1, a2, a1};
    int one = 1;
    notes = 0;
    assert_int_equal(pm_composite_open(&c, twice, 3, PM_ONLY_DIRECT), PM_OK);
    assert_int_equal(pm_composite_info(c)->buffers, 2);
    assert_string_equal(pm_composite_info(c)->components, "direct");
    assert_int_equal(pm_composite_sum(c, 2, argv, count_note, &one), PM_OK);
    assert_int_equal(notes, 1);
    pm_composite_free(c);
}

static void test_composite_refusals(void **state)
{
    char a[600], other[600], big[700];
    tmp_path(a, sizeof a, "a.pm");
    tmp_path(other, sizeof other, "other.pm");
    write_buffer(a, 3, 2, "indirect", NULL, 1.0, 0);
    write_buffer(other, 2, 3, "indirect", NULL, 1.0, 0);
    char *argv[] = {"composite"};
    pm_composite_t *c;
    char *mismatch[] = {a, other};
    assert_int_equal(pm_composite_open(&c, mismatch, 2, PM_ONLY_ALL), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "resolution mismatch"));
    pm_composite_free(c);
    char dash[] = "-";
    char *stdin_twice[] = {dash, dash};
    assert_int_equal(pm_composite_open(&c, stdin_twice, 2, PM_ONLY_ALL), PM_ERR_USAGE);
    pm_composite_free(c);
    char *only[] = {a};
    assert_int_equal(pm_composite_open(&c, only, 1, PM_ONLY_DIRECT), PM_ERR_INPUT);
    assert_string_equal(pm_error_message(), "--only direct: none of the 1 buffers is direct");
    pm_composite_free(c);
    /* 1e5 fits float but not half */
    snprintf(big, sizeof big, "%s:1e5", a);
    char *scaled[] = {big};
    assert_int_equal(pm_composite_open(&c, scaled, 1, PM_ONLY_ALL), PM_OK);
    assert_int_equal(pm_composite_sum(c, 1, argv, NULL, NULL), PM_OK);
    assert_int_equal(pm_composite_finish(c, 1), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "pixel (0, 0) channel R is 100000 after scaling, beyond half"));
    pm_composite_free(c);
    assert_int_equal(pm_composite_open(&c, scaled, 1, PM_ONLY_ALL), PM_OK);
    assert_int_equal(pm_composite_sum(c, 1, argv, NULL, NULL), PM_OK);
    assert_int_equal(pm_composite_finish(c, 0), PM_OK);
    pm_composite_free(c);
}

static void test_rgb_read(void **state)
{
    char rad[600], exr[600];
    tmp_path(rad, sizeof rad, "read.pm");
    tmp_path(exr, sizeof exr, "read.exr");
    write_buffer(rad, 4, 3, "total", NULL, 0.5, 0.25);
    pm_rgb_image_t a, b;
    assert_int_equal(pm_rgb_image_read(rad, &a), PM_OK);
    assert_string_equal(a.kind, "radiance");
    assert_int_equal(a.w, 4);
    assert_int_equal(a.h, 3);
    assert_non_null(a.var);
    float f[36];
    for (int i = 0; i < 36; i++) {
        assert_true(a.rgb[i] == 0.5 + i / 8.0);
        assert_true(a.var[i] == 0.25 * a.rgb[i]);
        f[i] = (float)a.rgb[i];
    }
    assert_int_equal(pm_exr_write_rgb(exr, 4, 3, f, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    assert_int_equal(pm_rgb_image_read(exr, &b), PM_OK);
    assert_string_equal(b.kind, "exr");
    assert_null(b.var);
    for (int i = 0; i < 36; i++)
        assert_true(b.rgb[i] == a.rgb[i]); /* i / 8 is exact in float */
    pm_rgb_image_free(&a);
    pm_rgb_image_free(&b);
    char missing[600];
    tmp_path(missing, sizeof missing, "missing.pm");
    assert_int_not_equal(pm_rgb_image_read(missing, &a), PM_OK);
    assert_null(a.rgb);
}

static void test_metrics(void **state)
{
    /* two pixels: t - r of 1, -2, 0 and 0.5, 0, 4 */
    double tv[6] = {2, 1, 3, 1.5, 0, 4}, rv[6] = {1, 3, 3, 1, 0, 0}, var[6] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
    pm_rgb_image_t t = {.path = "t", .w = 2, .h = 1, .rgb = tv}, r = {.path = "r", .w = 2, .h = 1, .rgb = rv};
    const double eps = 0.01;
    pm_image_errors_t e;
    float *err;
    assert_int_equal(pm_image_errors(&t, &r, eps, PM_ERRIMG_REL, &e, &err), PM_OK);
    double s2 = 0, rel2 = 0, rel = 0;
    for (int i = 0; i < 6; i++) {
        double d = tv[i] - rv[i];
        s2 += d * d, rel2 += d * d / (rv[i] * rv[i] + eps), rel += fabs(d) / (fabs(rv[i]) + eps);
        assert_true(fabsf(err[i] - (float)(fabs(d) / (fabs(rv[i]) + eps))) <= 1e-6f * err[i]);
    }
    free(err);
    assert_int_equal(e.values, 6);
    assert_true(fabs(e.rmse - sqrt(s2 / 6)) < 1e-15);
    assert_true(fabs(e.relmse - rel2 / 6) < 1e-12);
    assert_true(fabs(e.mean_abs_rel - rel / 6) < 1e-12);
    assert_true(e.max_abs == 4.0);
    assert_true(fabs(e.ch_rmse[1] - sqrt(4.0 / 2)) < 1e-15); /* G: -2 and 0 */
    assert_true(fabs(e.mean_test - 11.5 / 6) < 1e-15 && fabs(e.mean_ref - 8.0 / 6) < 1e-15);
    assert_false(e.has_ref_noise);

    /* the reference's variance gives the noise floor; abs errors without it */
    r.var = var;
    assert_int_equal(pm_image_errors(&t, &r, eps, PM_ERRIMG_ABS, &e, &err), PM_OK);
    assert_true(fabs(err[1] - 2.0f) == 0.0f);
    free(err);
    assert_true(e.has_ref_noise);
    assert_true(fabs(e.ref_rmse - sqrt(2.1 / 6)) < 1e-12);
    char path[600];
    tmp_path(path, sizeof path, "errors.json");
    FILE *f = fopen(path, "w");
    assert_int_equal(pm_image_errors_write_json(f, &t, &r, &e), PM_OK);
    fclose(f);
    json_error_t je;
    json_t *j = json_load_file(path, 0, &je);
    assert_non_null(j);
    assert_string_equal(json_string_value(json_object_get(j, "reference")), "r");
    assert_true(fabs(json_real_value(json_object_get(j, "rmse")) - e.rmse) < 1e-8 * e.rmse);
    assert_non_null(json_object_get(j, "reference_rmse"));
    assert_int_equal(json_array_size(json_object_get(j, "rmse_rgb")), 3);
    json_decref(j);

    /* images of two sizes: a usage error (the wrong pair of files) naming both, no error image */
    r.w = 1, r.h = 2;
    err = (float *)&e;
    assert_int_equal(pm_image_errors(&t, &r, eps, PM_ERRIMG_ABS, &e, &err), PM_ERR_USAGE);
    assert_null(err);
    assert_string_equal(pm_error_message(), "'t' is 2x1 but 'r' is 1x2");
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_tone_curves),
    cmocka_unit_test(test_tone_preview),
    cmocka_unit_test(test_composite_parse_input),
    cmocka_unit_test(test_composite_sum),
    cmocka_unit_test(test_composite_refusals),
    cmocka_unit_test(test_rgb_read),
    cmocka_unit_test(test_metrics),
};

UNIT_GROUP(unit_image, "image", tests);
