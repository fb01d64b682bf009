/* test_imgdecode.c: the image decoders (base/imgdecode.h) on bytes in memory: TGA of every kind
 * pmtk reads placed by its origin bits, truncated and corrupt TGAs refused, a declared size over
 * the budget refused before allocation, formats disguised by their names refused, Radiance RGBE
 * flat and run-length scanlines decoded to Radiance's values, a cut JPEG refused (libjpeg's
 * warning), a FIFO refused without blocking. */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* after stdio.h: jpeglib.h uses FILE without including it */
#include <jpeglib.h>

#include "base/imgdecode.h"
#include "unit.h"

static const pm_img_limits_t tex = {PM_IMG_PNG | PM_IMG_JPEG | PM_IMG_EXR | PM_IMG_TGA, (uint64_t)256 << 20, 4,
                                    "texture", NULL};
static const pm_img_limits_t sky = {PM_IMG_EXR | PM_IMG_HDR, (uint64_t)256 << 20, 3, "sky map", NULL};

static void expect_error(const char *name, const void *d, size_t n, const pm_img_limits_t *lim, const char *needle)
{
    pm_img_t im;
    assert_int_equal(pm_img_decode(name, NULL, d, n, lim, &im), PM_ERR_INPUT);
    if (!strstr(pm_error_message(), needle))
        fail_msg("message '%s' lacks '%s'", pm_error_message(), needle);
    assert_null(im.u8);
    assert_null(im.f32);
}

/* An 18-byte TGA header. */
static void tga_header(uint8_t *h, unsigned type, unsigned w, unsigned hh, unsigned bpp, unsigned desc)
{
    memset(h, 0, 18);
    h[2] = (uint8_t)type;
    h[12] = (uint8_t)w, h[13] = (uint8_t)(w >> 8), h[14] = (uint8_t)hh, h[15] = (uint8_t)(hh >> 8);
    h[16] = (uint8_t)bpp, h[17] = (uint8_t)desc;
}

static void test_tga_kinds(void **state)
{
    (void)state;
    pm_img_t im;
    /* 2 x 2, 24 bits, bottom-left origin: the first pixel in the file is the bottom-left one */
    uint8_t b[18 + 12];
    tga_header(b, 2, 2, 2, 24, 0);
    static const uint8_t px[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}; /* B G R */
    memcpy(b + 18, px, 12);
    assert_int_equal(pm_img_decode("a.tga", NULL, b, sizeof b, &tex, &im), PM_OK);
    assert_int_equal(im.w, 2);
    assert_int_equal(im.format, PM_IMG_TGA);
    static const uint8_t want[16] = {9, 8, 7, 255, 12, 11, 10, 255, 3, 2, 1, 255, 6, 5, 4, 255};
    assert_memory_equal(im.u8, want, 16);
    assert_false(im.has_alpha);
    pm_img_free(&im);
    /* RLE, 32 bits, top-left origin: a run of 3 then one raw pixel */
    uint8_t r[18 + 5 + 5];
    tga_header(r, 10, 2, 2, 32, 0x28);
    static const uint8_t packets[10] = {0x82, 10, 20, 30, 40, 0x00, 50, 60, 70, 80};
    memcpy(r + 18, packets, 10);
    assert_int_equal(pm_img_decode("r.TGA", NULL, r, sizeof r, &tex, &im), PM_OK);
    static const uint8_t want_r[16] = {30, 20, 10, 40, 30, 20, 10, 40, 30, 20, 10, 40, 70, 60, 50, 80};
    assert_memory_equal(im.u8, want_r, 16);
    assert_true(im.has_alpha);
    pm_img_free(&im);
    /* colour-mapped: 2 entries of 24 bits from index 5, indices 6 5 */
    uint8_t m[18 + 6 + 2];
    tga_header(m, 1, 2, 1, 8, 0);
    m[1] = 1, m[3] = 5, m[5] = 2, m[7] = 24;
    static const uint8_t cm[8] = {1, 2, 3, 4, 5, 6, 6, 5};
    memcpy(m + 18, cm, 8);
    assert_int_equal(pm_img_decode("m.tga", NULL, m, sizeof m, &tex, &im), PM_OK);
    static const uint8_t want_m[8] = {6, 5, 4, 255, 3, 2, 1, 255};
    assert_memory_equal(im.u8, want_m, 8);
    pm_img_free(&im);
    m[18 + 6] = 9; /* an index outside the map */
    expect_error("m.tga", m, sizeof m, &tex, "colour index 9 outside the map (5 to 6)");
    /* grey, 8 bits, 16-bit 5-5-5 */
    uint8_t g[18 + 2];
    tga_header(g, 3, 2, 1, 8, 0);
    g[18] = 255, g[19] = 0;
    assert_int_equal(pm_img_decode("g.tga", NULL, g, sizeof g, &tex, &im), PM_OK);
    assert_true(im.grey && im.u8[0] == 255 && im.u8[4] == 0 && im.u8[7] == 255);
    pm_img_free(&im);
    uint8_t s[18 + 2];
    tga_header(s, 2, 1, 1, 16, 0);
    s[18] = 0x1f, s[19] = 0x7c; /* red 31, green 0, blue 31 */
    assert_int_equal(pm_img_decode("s.tga", NULL, s, sizeof s, &tex, &im), PM_OK);
    assert_true(im.u8[0] == 255 && im.u8[1] == 0 && im.u8[2] == 255);
    pm_img_free(&im);
}

static void test_tga_hostile(void **state)
{
    (void)state;
    uint8_t b[18 + 40];
    memset(b, 0x55, sizeof b);
    tga_header(b, 2, 4, 4, 24, 0); /* 48 bytes of pixels declared, 40 given */
    expect_error("cut.tga", b, sizeof b, &tex, "truncated TGA: 40 bytes of pixels for 4 x 4 at 24 bits (48)");
    expect_error("cut.tga", b, 10, &tex, "truncated TGA: 10 bytes, the header alone is 18");
    tga_header(b, 10, 4, 4, 24, 0); /* RLE: a raw packet of 128 pixels in a 16-pixel image */
    b[18] = 0x7f;
    expect_error("run.tga", b, sizeof b, &tex, "corrupt TGA: a run of 128 pixels at pixel 0 of 16");
    b[18] = 0x8f; /* a run of all 16, then nothing: fine */
    pm_img_t im;
    assert_int_equal(pm_img_decode("run.tga", NULL, b, 22, &tex, &im), PM_OK);
    pm_img_free(&im);
    b[18] = 0x0f; /* 16 raw pixels: 48 bytes, 39 there */
    expect_error("run.tga", b, sizeof b, &tex, "truncated TGA: pixel data ends at pixel 13 of 16");
    tga_header(b, 2, 23170, 23170, 24, 0); /* 2 GiB decoded from an 18-byte file */
    expect_error("huge.tga", b, 18, &tex, "23170 x 23170 pixels would take 2047.9 MiB decoded, above its budget");
    tga_header(b, 2, 0, 1, 24, 0);
    expect_error("zero.tga", b, 18, &tex, "0 x 1 pixels");
    tga_header(b, 4, 1, 1, 24, 0);
    expect_error("t4.tga", b, sizeof b, &tex, "image type 4");
    tga_header(b, 2, 1, 1, 12, 0);
    expect_error("b12.tga", b, sizeof b, &tex, "12 bits per pixel");
}

static void test_disguised(void **state)
{
    (void)state;
    static const uint8_t png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    expect_error("x.tga", png, sizeof png, &tex, "named as TGA but holds a PNG image");
    expect_error("x.jpg", png, sizeof png, &tex, "named as JPEG but holds a PNG image");
    expect_error("x.tga", "BM\x36\0\0\0", 6, &tex, "a BMP image named as TGA");
    expect_error("x.tga", "GIF89a", 6, &tex, "a GIF image");
    expect_error("x.tga", "8BPS\0\1", 6, &tex, "a Photoshop (PSD) image");
    expect_error("x.tga", "P6\n1 1\n255\n", 11, &tex, "a netpbm (PNM/PAM) image");
    expect_error("x.tga", "#?RADIANCE\n\n-Y 1 +X 1\n", 22, &tex, "named as TGA but holds a Radiance HDR image");
    expect_error("x.hdr", "#?RADIANCE\n\n-Y 1 +X 1\n\1\1\1\1", 26, &tex,
                 "a Radiance HDR image: a texture is read from PNG, JPEG, OpenEXR, TGA");
    expect_error("x.png", "#?RADIANCE", 10, &tex, "named as PNG but holds a Radiance HDR image");
    expect_error("noext", "hello", 5, &tex, "not a PNG, JPEG, OpenEXR or (named .tga) TGA image (5 bytes");
    /* an embedded image: the hint stands for the extension */
    pm_img_t im;
    assert_int_equal(pm_img_decode("m.glb:*0", "tga", png, sizeof png, &tex, &im), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "named as TGA but holds a PNG"));
}

/* One RGBE file: header lines, resolution, then the scanline bytes. */
static size_t hdr_file(uint8_t *out, const char *header, const uint8_t *px, size_t n)
{
    size_t k = strlen(header);
    memcpy(out, header, k);
    memcpy(out + k, px, n);
    return k + n;
}

static void test_hdr(void **state)
{
    (void)state;
    uint8_t f[512];
    pm_img_t im;
    /* flat, 2 x 1: (128, 64, 0, e=129) = (128.5, 64.5, 0.5) / 2^7; and black */
    static const uint8_t flat[8] = {128, 64, 0, 129, 0, 0, 0, 0};
    size_t n = hdr_file(f, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n", flat, 8);
    assert_int_equal(pm_img_decode("s.hdr", NULL, f, n, &sky, &im), PM_OK);
    assert_true(im.w == 2 && im.h == 1 && im.fchannels == 3);
    assert_true(im.f32[0] == 128.5f / 128 && im.f32[1] == 64.5f / 128 && im.f32[2] == 0.5f / 128 && im.f32[3] == 0.0f);
    pm_img_free(&im);
    /* EXPOSURE=2: the values divided by it; +Y: rows from the bottom */
    static const uint8_t two[8] = {128, 128, 128, 129, 64, 64, 64, 129};
    n = hdr_file(f, "#?RGBE\nEXPOSURE=2\n\n+Y 2 +X 1\n", two, 8);
    assert_int_equal(pm_img_decode("s.hdr", NULL, f, n, &sky, &im), PM_OK);
    assert_true(im.f32[0] == 64.5f / 128 / 2 && im.f32[3] == 128.5f / 128 / 2);
    pm_img_free(&im);
    /* new-style run-length, 8 x 1, exponent 130 (x 2^-6): runs of 8, and a literal pair and a run of 6 */
    static const uint8_t rle[4 + 2 + 2 + 3 + 2 + 2] = {2, 2, 0, 8, 136, 10, 136, 20, 2, 30, 31, 134, 32, 136, 130};
    n = hdr_file(f, "#?RADIANCE\n\n-Y 1 +X 8\n", rle, sizeof rle);
    assert_int_equal(pm_img_decode("r.hdr", NULL, f, n, &sky, &im), PM_OK);
    assert_true(im.f32[0] == 10.5f / 64 && im.f32[3 * 7 + 1] == 20.5f / 64 && im.f32[2] == 30.5f / 64 &&
                im.f32[5] == 31.5f / 64 && im.f32[3 * 7 + 2] == 32.5f / 64);
    pm_img_free(&im);
    /* old-style run: (1, 1, 1, 3) repeats the previous pixel 3 times */
    static const uint8_t old[8] = {100, 100, 100, 128, 1, 1, 1, 3};
    n = hdr_file(f, "#?RADIANCE\n\n-Y 1 +X 4\n", old, 8);
    assert_int_equal(pm_img_decode("o.hdr", NULL, f, n, &sky, &im), PM_OK);
    assert_true(im.f32[9] == 100.5f / 256 && im.f32[11] == 100.5f / 256);
    pm_img_free(&im);
    /* refused: truncated, a run past the line, other formats and orientations, too big */
    n = hdr_file(f, "#?RADIANCE\n\n-Y 1 +X 8\n", rle, sizeof rle - 1);
    expect_error("r.hdr", f, n, &sky, "Radiance HDR: truncated in scanline 0");
    static const uint8_t over[6] = {2, 2, 0, 8, 137, 10};
    n = hdr_file(f, "#?RADIANCE\n\n-Y 1 +X 8\n", over, 6);
    expect_error("r.hdr", f, n, &sky, "corrupt run in scanline 0 at pixel 0");
    n = hdr_file(f, "#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 8\n", rle, sizeof rle);
    expect_error("x.hdr", f, n, &sky, "FORMAT=32-bit_rle_xyze: only 32-bit_rle_rgbe is read");
    n = hdr_file(f, "#?RADIANCE\n\n+X 8 -Y 1\n", rle, sizeof rle);
    expect_error("x.hdr", f, n, &sky, "resolution '+X 8 -Y 1'");
    n = hdr_file(f, "#?RADIANCE\n\n-Y 60000 +X 60000\n", rle, sizeof rle);
    expect_error("x.hdr", f, n, &sky, "60000 x 60000 pixels would take 41198.7 MiB decoded, above its budget");
    n = hdr_file(f, "#?RADIANCE\nno end", rle, 0);
    expect_error("x.hdr", f, n, &sky, "header without an end");
}

static void test_budget_and_jpeg(void **state)
{
    (void)state;
    /* a 16 x 16 JPEG made here; its budget 1024 bytes exactly, then one less */
    unsigned char *jpg = NULL;
    unsigned long size = 0;
    struct jpeg_compress_struct ci;
    struct jpeg_error_mgr je;
    ci.err = jpeg_std_error(&je);
    jpeg_create_compress(&ci);
    jpeg_mem_dest(&ci, &jpg, &size);
    ci.image_width = ci.image_height = 16, ci.input_components = 3, ci.in_color_space = JCS_RGB;
    jpeg_set_defaults(&ci);
    jpeg_start_compress(&ci, TRUE);
    uint8_t row[48];
    for (int x = 0; x < 48; x++)
        row[x] = (uint8_t)(x * 5);
    while (ci.next_scanline < 16) {
        JSAMPROW rp = row;
        jpeg_write_scanlines(&ci, &rp, 1);
    }
    jpeg_finish_compress(&ci);
    jpeg_destroy_compress(&ci);
    pm_img_limits_t lim = tex;
    lim.max_bytes = 16 * 16 * 4;
    pm_img_t im;
    assert_int_equal(pm_img_decode("j.jpg", NULL, jpg, size, &lim, &im), PM_OK);
    pm_img_free(&im);
    lim.max_bytes--;
    lim.budget = "image_budgets.texture_mib 0.001";
    expect_error("j.jpg", jpg, size, &lim,
                 "16 x 16 pixels would take 0.0 MiB decoded, above its budget "
                 "(image_budgets.texture_mib 0.001)");
    /* cut short: libjpeg's "premature end" warning is an error, not grey texels */
    expect_error("j.jpg", jpg, size - 40, &tex, "libjpeg: Premature end of JPEG file");
    free(jpg);
}

static void test_read_file(void **state)
{
    (void)state;
    char p[512];
    snprintf(p, sizeof p, "%s/imgdecode.fifo", unit_tmpdir());
    unlink(p);
    assert_int_equal(mkfifo(p, 0600), 0);
    void *d = NULL;
    size_t n = 0;
    assert_int_equal(pm_img_read_file(p, "texture", 1 << 20, &d, &n), PM_ERR_INPUT); /* without waiting */
    assert_non_null(strstr(pm_error_message(), "is not a regular file (a FIFO)"));
    assert_null(d);
    unlink(p);
    snprintf(p, sizeof p, "%s/imgdecode.big", unit_tmpdir());
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fseek(f, 4096, SEEK_SET), 0);
    fputc(1, f);
    fclose(f);
    assert_int_equal(pm_img_read_file(p, "texture", 4096, &d, &n), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "4097 bytes, above the"));
    assert_int_equal(pm_img_read_file(p, "texture", 4097, &d, &n), PM_OK);
    assert_int_equal(n, 4097);
    free(d);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_tga_kinds), cmocka_unit_test(test_tga_hostile),     cmocka_unit_test(test_disguised),
    cmocka_unit_test(test_hdr),       cmocka_unit_test(test_budget_and_jpeg), cmocka_unit_test(test_read_file),
};
UNIT_GROUP(unit_imgdecode, "imgdecode", tests);
