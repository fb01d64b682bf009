/* test_exr.c: OpenEXR output (common/base/exr.c) read back through the OpenEXR C API: float exactly,
 * half to its rounding, odd sizes across chunk boundaries, string attributes, and the refusals
 * (stdout, a value that is not finite or too large for half, an unwritable directory). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/exr.h"
#include "unit.h"

static float *ramp(uint32_t w, uint32_t h)
{
    float *p = malloc((size_t)3 * w * h * sizeof *p);
    for (size_t i = 0; i < (size_t)3 * w * h; i++)
        p[i] = (float)i * 0.37f + 1e-3f * (float)(i % 7); /* distinct values, not all representable in half */
    return p;
}

static void roundtrip(pm_exr_pixel_t type, pm_exr_compression_t comp, uint32_t w, uint32_t h)
{
    char path[600];
    snprintf(path, sizeof path, "%s/rt-%d-%d-%ux%u.exr", unit_tmpdir(), (int)type, (int)comp, w, h);
    float *src = ramp(w, h);
    if (type == PM_EXR_HALF)
        for (size_t i = 0; i < (size_t)3 * w * h; i++)
            src[i] = fminf(src[i], 60000.0f);
    const pm_exr_attr_t attrs[] = {{"SOFTWARE", "pmtk test"}, {"COMMAND.0", "composite 'a b' -o x.exr"}};
    assert_int_equal(pm_exr_write_rgb(path, w, h, src, type, comp, attrs, 2), PM_OK);
    uint32_t rw, rh;
    float *got;
    assert_int_equal(pm_exr_read_rgb(path, &rw, &rh, &got), PM_OK);
    assert_int_equal(rw, w);
    assert_int_equal(rh, h);
    for (size_t i = 0; i < (size_t)3 * w * h; i++) {
        if (type == PM_EXR_FLOAT)
            assert_true(got[i] == src[i]);
        else /* half: 11 significant bits, relative error at most 2^-11 */
            assert_true(fabsf(got[i] - src[i]) <= fabsf(src[i]) * 0x1p-11f);
    }
    char *v;
    assert_int_equal(pm_exr_read_string_attr(path, "COMMAND.0", &v), PM_OK);
    assert_string_equal(v, "composite 'a b' -o x.exr");
    free(v);
    assert_int_equal(pm_exr_read_string_attr(path, "no-such", &v), PM_ERR_INPUT);
    assert_null(v);
    free(got);
    free(src);
}

static void test_exr_float_roundtrip(void **state)
{
    roundtrip(PM_EXR_FLOAT, PM_EXR_ZIP, 37, 35); /* 35 rows: two whole 16-line chunks and a short one */
    roundtrip(PM_EXR_FLOAT, PM_EXR_NONE, 5, 3);
    roundtrip(PM_EXR_FLOAT, PM_EXR_PIZ, 1, 1);
}

/* One pixel is a 12-byte chunk (6 in half) that zip cannot shrink: the writer must store it
 * uncompressed, not the deflated bytes under the raw size, which reads back as garbage. */
static void test_exr_one_pixel(void **state)
{
    for (int t = 0; t < 2; t++)
        for (int c = 0; c < 3; c++) {
            roundtrip((pm_exr_pixel_t)t, (pm_exr_compression_t)c, 1, 1);
            roundtrip((pm_exr_pixel_t)t, (pm_exr_compression_t)c, 2, 1);
            roundtrip((pm_exr_pixel_t)t, (pm_exr_compression_t)c, 1, 2);
        }
}

/* Named layers beside R G B: the RGB reads back as it was, a repeated name or a NaN in a layer
 * is refused. */
static void test_exr_channels(void **state)
{
    char path[600];
    snprintf(path, sizeof path, "%s/layers.exr", unit_tmpdir());
    float rgb[6] = {1, 2, 3, 4, 5, 6}, nrm[6] = {0, 0, 1, 0, -1, 0}, z[2] = {2.5f, 0};
    pm_exr_channel_t ch[] = {{"R", rgb, 3, 0},        {"G", rgb + 1, 3, 0},        {"B", rgb + 2, 3, 0},
                             {"normal.X", nrm, 3, 1}, {"normal.Y", nrm + 1, 3, 1}, {"normal.Z", nrm + 2, 3, 1},
                             {"Z", z, 1, 1}};
    assert_int_equal(pm_exr_write_channels(path, 2, 1, ch, 7, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    uint32_t w, h;
    float *got;
    assert_int_equal(pm_exr_read_rgb(path, &w, &h, &got), PM_OK);
    assert_int_equal(w, 2);
    for (int i = 0; i < 6; i++)
        assert_true(got[i] == rgb[i]);
    free(got);
    ch[6].name = "R";
    assert_int_equal(pm_exr_write_channels(path, 2, 1, ch, 7, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_ERR_INTERNAL);
    ch[6].name = "Z";
    z[1] = NAN;
    assert_int_equal(pm_exr_write_channels(path, 2, 1, ch, 7, PM_EXR_HALF, PM_EXR_ZIP, NULL, 0), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "channel Z"));
}

/* A ZIP chunk whose deflated bytes come out exactly as long as its packed pixels: OpenEXR Core
 * 3.1 (Debian 12's) stores the deflated bytes, and every reader takes a chunk of that size for
 * raw pixels (OpenEXR issue 2306, fixed in 3.4): a 128 x 128 path-traced image read back rows
 * 64-79 as noise of +-1e38. Images of floats with 1 to 23 random low bits of mantissa straddle
 * the incompressible size; each must read back exactly. */
static void test_exr_zip_incompressible(void **state)
{
    char path[600];
    snprintf(path, sizeof path, "%s/zipsize.exr", unit_tmpdir());
    const uint32_t w = 4, h = 16;
    float src[3 * 4 * 16];
    uint64_t x = 88172645463325252ull;
    int wrong = 0;
    for (int bits = 1; bits <= 23; bits++)
        for (int seed = 0; seed < 24; seed++) {
            for (size_t i = 0; i < sizeof src / sizeof src[0]; i++) {
                x ^= x << 13, x ^= x >> 7, x ^= x << 17;
                uint32_t u = 0x3f800000u | (uint32_t)(x & ((1u << bits) - 1u));
                memcpy(&src[i], &u, 4);
            }
            assert_int_equal(pm_exr_write_rgb(path, w, h, src, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
            uint32_t rw, rh;
            float *got;
            assert_int_equal(pm_exr_read_rgb(path, &rw, &rh, &got), PM_OK);
            wrong += memcmp(got, src, sizeof src) != 0;
            free(got);
        }
    assert_int_equal(wrong, 0);
}

static void test_exr_half_roundtrip(void **state)
{
    roundtrip(PM_EXR_HALF, PM_EXR_ZIP, 17, 33);
    roundtrip(PM_EXR_HALF, PM_EXR_PIZ, 40, 40);
}

static void test_exr_refusals(void **state)
{
    char path[600];
    snprintf(path, sizeof path, "%s/bad.exr", unit_tmpdir());
    float px[3] = {1.0f, NAN, 0.0f};
    assert_int_equal(pm_exr_write_rgb(path, 1, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "channel G is nan"));
    px[1] = 70000.0f; /* fine as float, beyond half */
    assert_int_equal(pm_exr_write_rgb(path, 1, 1, px, PM_EXR_HALF, PM_EXR_ZIP, NULL, 0), PM_ERR_INTERNAL);
    assert_int_equal(access(path, F_OK), -1); /* nothing left behind */
    assert_int_equal(pm_exr_write_rgb(path, 1, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    assert_int_equal(pm_exr_write_rgb("-", 1, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_ERR_USAGE);
    /* a missing directory is the user's input (common/base/atomic.c's class) */
    assert_int_equal(pm_exr_write_rgb("/nonexistent-dir/x.exr", 1, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0),
                     PM_ERR_INPUT);
    uint32_t w, h;
    float *rgb;
    assert_int_not_equal(pm_exr_read_rgb("/nonexistent-dir/x.exr", &w, &h, &rgb), PM_OK);
    assert_null(rgb);
    /* a file that is not an EXR */
    snprintf(path, sizeof path, "%s/not.exr", unit_tmpdir());
    FILE *f = fopen(path, "w");
    fputs("#?PMTK\nnot an image\n", f);
    fclose(f);
    assert_int_equal(pm_exr_read_rgb(path, &w, &h, &rgb), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "not.exr"));
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_exr_float_roundtrip), cmocka_unit_test(test_exr_one_pixel),
    cmocka_unit_test(test_exr_channels),        cmocka_unit_test(test_exr_half_roundtrip),
    cmocka_unit_test(test_exr_refusals),        cmocka_unit_test(test_exr_zip_incompressible),
};
UNIT_GROUP(unit_exr, "exr", tests);
