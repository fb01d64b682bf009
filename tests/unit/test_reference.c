/* test_reference.c: reference images from other renderers, as measure-error reads them
 * (common/base/exr.c, common/image/pfm.c through common/image/rgb.c). OpenEXR files in the
 * layouts pbrt-v4 and Mitsuba 3 write (half, float and uint; RGB and RGBA; scanline in either
 * line order and tiled, one level and mipmapped; a data window off the origin; Y
 * alone) are written here through the OpenEXR Core API and read back value by value, and the
 * layouts pmtk refuses (deep, luminance-chroma, no colour channels, subsampled) are refused
 * with a message naming them. PFM files are written byte by byte: both byte orders, colour and
 * grey, the rows stored bottom first, the scale's magnitude, and every refusal (truncated,
 * trailing bytes, bad sizes, bad scale, NaN, Inf, negative). */
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "image/metrics.h"
#include "image/pfm.h"
#include "image/rgb.h"
#include "unit.h"

static void ref_path(char *out, size_t cap, const char *name)
{
    snprintf(out, cap, "%s/reference-%s", unit_tmpdir(), name);
}

/* ---- OpenEXR files of a chosen layout ---- */

typedef struct {
    exr_storage_t storage;
    exr_pixel_type_t type;
    const char *channels; /* space-separated, e.g. "R G B A" */
    exr_compression_t comp;
    exr_lineorder_t order;
    int tile_w, tile_h; /* tiled only */
    exr_tile_level_mode_t levels;
    int x0, y0, w, h; /* data window */
    int sampling;     /* x and y sampling of every channel (0 is 1) */
} layout_t;

/* The value written at pixel (x, y) of level (lx, ly) in channel k (its place in `channels`),
 * before rounding to the channel's type: distinct for every pixel, channel and level. */
static double value(int x, int y, int k, int lx, int ly)
{
    return x + 61.0 * y + 1000.0 * k + 0.5 + 7.0 * (lx + 3 * ly);
}

/* What the reader gives back for v written as type t. */
static float as_read(double v, exr_pixel_type_t t)
{
    return t == EXR_PIXEL_HALF ? (float)(_Float16)v : t == EXR_PIXEL_UINT ? (float)(uint32_t)v : (float)v;
}

static void store(uint8_t *p, double v, exr_pixel_type_t t)
{
    if (t == EXR_PIXEL_HALF) {
        _Float16 h = (_Float16)v;
        memcpy(p, &h, 2);
    } else if (t == EXR_PIXEL_UINT) {
        uint32_t u = (uint32_t)v;
        memcpy(p, &u, 4);
    } else {
        float f = (float)v;
        memcpy(p, &f, 4);
    }
}

/* Encodes one chunk, whose first pixel is (px, py): every channel's values, in planes. */
static void write_chunk(exr_context_t ctx, exr_chunk_info_t *ci, exr_encode_pipeline_t *enc, int *live,
                        const layout_t *L, char names[][16], int nch, int px, int py, int lx, int ly)
{
    size_t esize = L->type == EXR_PIXEL_HALF ? 2 : 4;
    uint8_t *planes[8];
    assert_int_equal(*live ? exr_encoding_update(ctx, 0, ci, enc) : exr_encoding_initialize(ctx, 0, ci, enc),
                     EXR_ERR_SUCCESS);
    *live = 1;
    for (int k = 0; k < enc->channel_count; k++) {
        exr_coding_channel_info_t *ch = &enc->channels[k];
        int idx = -1;
        for (int n = 0; n < nch; n++)
            if (!strcmp(ch->channel_name, names[n]))
                idx = n;
        assert_true(idx >= 0);
        /* a subsampled channel has fewer values than the chunk has pixels */
        planes[k] = malloc((size_t)ch->width * (size_t)ch->height * esize + 1);
        for (int y = 0; y < ch->height; y++)
            for (int x = 0; x < ch->width; x++)
                store(planes[k] + ((size_t)y * (size_t)ch->width + (size_t)x) * esize,
                      value(px + x, py + y, idx, lx, ly), L->type);
        ch->user_bytes_per_element = (int16_t)esize;
        ch->user_data_type = (uint16_t)L->type;
        ch->user_pixel_stride = (int32_t)esize;
        ch->user_line_stride = (int32_t)(esize * (size_t)ch->width);
        ch->encode_from_ptr = planes[k];
    }
    assert_int_equal(exr_encoding_choose_default_routines(ctx, 0, enc), EXR_ERR_SUCCESS);
    assert_int_equal(exr_encoding_run(ctx, 0, enc), EXR_ERR_SUCCESS);
    for (int k = 0; k < enc->channel_count; k++)
        free(planes[k]);
}

static void write_layout(const char *path, const layout_t *L)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_context_t ctx = NULL;
    int part = 0;
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), EXR_ERR_SUCCESS);
    assert_int_equal(exr_add_part(ctx, "reference", L->storage, &part), EXR_ERR_SUCCESS);
    exr_attr_box2i_t dw;
    dw.min.x = L->x0, dw.min.y = L->y0, dw.max.x = L->x0 + L->w - 1, dw.max.y = L->y0 + L->h - 1;
    exr_attr_v2f_t centre;
    centre.x = centre.y = 0;
    assert_int_equal(exr_initialize_required_attr(ctx, part, &dw, &dw, 1.0f, &centre, 1.0f, L->order, L->comp),
                     EXR_ERR_SUCCESS);
    if (L->storage == EXR_STORAGE_TILED)
        assert_int_equal(exr_set_tile_descriptor(ctx, part, (uint32_t)L->tile_w, (uint32_t)L->tile_h, L->levels,
                                                 EXR_TILE_ROUND_DOWN),
                         EXR_ERR_SUCCESS);
    char names[8][16];
    int nch = 0;
    char list[64];
    snprintf(list, sizeof list, "%s", L->channels);
    for (char *s = strtok(list, " "); s; s = strtok(NULL, " ")) {
        snprintf(names[nch], sizeof names[nch], "%s", s);
        int samp = L->sampling ? L->sampling : 1;
        assert_int_equal(exr_add_channel(ctx, part, names[nch], L->type, EXR_PERCEPTUALLY_LOGARITHMIC, samp, samp),
                         EXR_ERR_SUCCESS);
        nch++;
    }
    assert_int_equal(exr_write_header(ctx), EXR_ERR_SUCCESS);
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int live = 0;
    if (L->storage == EXR_STORAGE_DEEP_SCANLINE) {
        /* every pixel with no sample: a cumulative sample count table of zeros, no data (one
         * line per chunk, uncompressed) */
        int32_t *counts = calloc((size_t)L->w, sizeof *counts);
        for (int y = L->y0; y < L->y0 + L->h; y++)
            assert_int_equal(
                exr_write_deep_scanline_chunk(ctx, part, y, NULL, 0, 0, counts, (uint64_t)L->w * sizeof *counts),
                EXR_ERR_SUCCESS);
        free(counts);
    } else if (L->storage == EXR_STORAGE_SCANLINE) {
        int32_t lines;
        assert_int_equal(exr_get_scanlines_per_chunk(ctx, part, &lines), EXR_ERR_SUCCESS);
        int n = (L->h + lines - 1) / lines;
        for (int c = 0; c < n; c++) { /* OpenEXR takes the chunks in order whatever the line order */
            exr_chunk_info_t ci;
            assert_int_equal(exr_write_scanline_chunk_info(ctx, part, L->y0 + c * lines, &ci), EXR_ERR_SUCCESS);
            write_chunk(ctx, &ci, &enc, &live, L, names, nch, L->x0, ci.start_y, 0, 0);
        }
    } else {
        int32_t nlx = 1, nly = 1;
        assert_int_equal(exr_get_tile_levels(ctx, part, &nlx, &nly), EXR_ERR_SUCCESS);
        for (int ly = 0; ly < nly; ly++)
            for (int lx = 0; lx < nlx; lx++) {
                if (L->levels == EXR_TILE_MIPMAP_LEVELS && lx != ly)
                    continue;
                int32_t lw, lh;
                assert_int_equal(exr_get_level_sizes(ctx, part, lx, ly, &lw, &lh), EXR_ERR_SUCCESS);
                for (int ty = 0; ty < (lh + L->tile_h - 1) / L->tile_h; ty++)
                    for (int tx = 0; tx < (lw + L->tile_w - 1) / L->tile_w; tx++) {
                        exr_chunk_info_t ci;
                        assert_int_equal(exr_write_tile_chunk_info(ctx, part, tx, ty, lx, ly, &ci), EXR_ERR_SUCCESS);
                        write_chunk(ctx, &ci, &enc, &live, L, names, nch, L->x0 + tx * L->tile_w,
                                    L->y0 + ty * L->tile_h, lx, ly);
                    }
            }
    }
    if (live)
        exr_encoding_destroy(ctx, &enc);
    assert_int_equal(exr_finish(&ctx), EXR_ERR_SUCCESS);
}

/* Reads L's file back through pm_exr_read_rgb and rgb.c and checks every value of R, G, B
 * (channels 0, 1, 2 of the list, or Y in all three). */
static void check_layout(const char *name, const layout_t *L)
{
    char path[600];
    ref_path(path, sizeof path, name);
    write_layout(path, L);
    uint32_t w, h;
    float *rgb;
    if (pm_exr_read_rgb(path, &w, &h, &rgb) != PM_OK)
        fail_msg("%s: %s", name, pm_error_message());
    assert_int_equal(w, L->w);
    assert_int_equal(h, L->h);
    /* channel k of the list feeds R, G, B: OpenEXR sorts the names, the list names them in
     * the order written, so find each */
    int idx[3];
    char list[64];
    snprintf(list, sizeof list, "%s", L->channels);
    int n = 0;
    for (char *s = strtok(list, " "); s; s = strtok(NULL, " "), n++)
        for (int c = 0; c < 3; c++)
            if (!strcmp(s, (const char *[]){"R", "G", "B"}[c]) || !strcmp(s, "Y"))
                idx[c] = n;
    for (int y = 0; y < L->h; y++)
        for (int x = 0; x < L->w; x++)
            for (int c = 0; c < 3; c++) {
                float want = as_read(value(L->x0 + x, L->y0 + y, idx[c], 0, 0), L->type);
                float got = rgb[3 * ((size_t)y * w + (size_t)x) + (size_t)c];
                if (got != want)
                    fail_msg("%s: pixel (%d, %d) channel %d is %g, wrote %g", name, x, y, c, (double)got, (double)want);
            }
    free(rgb);
    pm_rgb_image_t im;
    assert_int_equal(pm_rgb_image_read(path, &im), PM_OK);
    assert_string_equal(im.kind, "exr");
    assert_true(im.w == w && im.h == h && im.var == NULL);
    pm_rgb_image_free(&im);
}

static void test_exr_layouts(void **state)
{
    (void)state;
    const layout_t base = {.storage = EXR_STORAGE_SCANLINE,
                           .type = EXR_PIXEL_FLOAT,
                           .channels = "R G B",
                           .comp = EXR_COMPRESSION_ZIP,
                           .order = EXR_LINEORDER_INCREASING_Y,
                           .w = 37,
                           .h = 21};
    layout_t L = base;
    check_layout("float-rgb-zip.exr", &L); /* 21 rows: a whole 16-line chunk and a short one */
    L.type = EXR_PIXEL_HALF, L.channels = "R G B A", L.comp = EXR_COMPRESSION_NONE;
    check_layout("half-rgba-none.exr", &L);
    L.type = EXR_PIXEL_UINT, L.channels = "B G R", L.comp = EXR_COMPRESSION_PIZ;
    check_layout("uint-rgb-piz.exr", &L);
    L = base, L.type = EXR_PIXEL_HALF, L.order = EXR_LINEORDER_DECREASING_Y, L.comp = EXR_COMPRESSION_RLE;
    check_layout("half-decreasing-rle.exr", &L);
    /* pbrt-v4 and Mitsuba write AOVs beside the colour: a layer's channels are ignored */
    L = base, L.channels = "A Albedo.B Albedo.G Albedo.R B G R", L.x0 = 5, L.y0 = -3;
    check_layout("float-aov-window.exr", &L);
    L = base, L.channels = "Y";
    check_layout("float-grey.exr", &L);
    /* tiled: partial tiles at the right and bottom, then mipmapped (level 0 read) */
    L = base, L.storage = EXR_STORAGE_TILED, L.tile_w = 16, L.tile_h = 8, L.channels = "R G B A";
    check_layout("float-tiled.exr", &L);
    L.type = EXR_PIXEL_HALF, L.levels = EXR_TILE_MIPMAP_LEVELS, L.comp = EXR_COMPRESSION_PIZ, L.tile_w = 8;
    check_layout("half-mipmap.exr", &L);
    /* OpenEXR 3.1's Core numbers ripmap chunks wrongly when writing, so ripmaps are written by
     * exrmaketiled in tests/stage/measure-error.sh */
    L.type = EXR_PIXEL_UINT, L.levels = EXR_TILE_ONE_LEVEL, L.x0 = -2, L.y0 = 9, L.channels = "R G B";
    check_layout("uint-tiled-window.exr", &L);
}

/* A layout pmtk does not read: refused as input, with words of the message. */
static void refused(const char *name, const layout_t *L, const char *words)
{
    char path[600];
    ref_path(path, sizeof path, name);
    write_layout(path, L);
    uint32_t w, h;
    float *rgb = (float *)&w;
    pm_result_t r = pm_exr_read_rgb(path, &w, &h, &rgb);
    if (r != PM_ERR_INPUT)
        fail_msg("%s: result %d, message '%s'", name, (int)r, pm_error_message());
    assert_null(rgb);
    if (!strstr(pm_error_message(), words) || !strstr(pm_error_message(), name))
        fail_msg("%s: message '%s' lacks '%s'", name, pm_error_message(), words);
}

static void test_exr_refusals(void **state)
{
    (void)state;
    const layout_t base = {.storage = EXR_STORAGE_SCANLINE,
                           .type = EXR_PIXEL_HALF,
                           .channels = "R G B",
                           .comp = EXR_COMPRESSION_ZIP,
                           .w = 8,
                           .h = 4};
    layout_t L = base;
    L.channels = "Y RY BY";
    refused("lumchroma.exr", &L, "luminance-chroma (channels BY RY Y)");
    L.channels = "R G";
    refused("no-blue.exr", &L, "has no channels R, G and B (channels G R)");
    L.channels = "Z";
    refused("depth.exr", &L, "(channels Z)");
    L = base, L.sampling = 2;
    refused("subsampled.exr", &L, "channel R is subsampled 2x2");
    L = base, L.storage = EXR_STORAGE_DEEP_SCANLINE, L.comp = EXR_COMPRESSION_NONE;
    refused("deep.exr", &L, "is a deep scanline image; pmtk reads flat scanline or tiled images");

    /* a negative value, as a Mitchell or Lanczos filter leaves, is no pixel mean */
    char path[600];
    ref_path(path, sizeof path, "negative.exr");
    float px[6] = {1, 2, 3, 4, -0.25f, 6};
    assert_int_equal(pm_exr_write_rgb(path, 2, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    pm_rgb_image_t im;
    assert_int_equal(pm_rgb_image_read(path, &im), PM_ERR_INPUT);
    assert_null(im.rgb);
    assert_non_null(strstr(pm_error_message(), "pixel (1, 0) channel G is -0.25: radiance cannot be negative"));
}

/* ---- PFM files, byte by byte ---- */

typedef struct {
    const char *header; /* the whole header text; NULL: made from the fields below */
    int grey;
    uint32_t w, h;
    double scale; /* its sign: the byte order of the values */
    long cut;     /* bytes dropped from the end */
    long extra;   /* bytes added at the end */
    int bad_at;   /* value index (file order) replaced by bad, or -1 */
    float bad;
} pfm_t;

/* The value of image pixel (x, y) from the top, channel c: the row from the top is in it, so
 * that reading the rows in file order (bottom first) without flipping them is seen. */
static float pfm_value(uint32_t x, uint32_t y, int c) { return (float)(x + 100 * y) + 0.25f * (float)c; }

static void write_pfm(const char *path, const pfm_t *p)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    if (p->header)
        fputs(p->header, f);
    else
        fprintf(f, "%s\n%u %u\n%g\n", p->grey ? "Pf" : "PF", p->w, p->h, p->scale);
    int nc = p->grey ? 1 : 3, little = p->scale < 0;
    long total = (long)p->w * p->h * nc * 4 - p->cut, put = 0, index = 0;
    for (uint32_t k = 0; k < p->h; k++) /* file row k is image row h - 1 - k */
        for (uint32_t x = 0; x < p->w; x++)
            for (int c = 0; c < nc; c++, index++) {
                float v = index == p->bad_at ? p->bad : pfm_value(x, p->h - 1 - k, c);
                uint32_t u;
                memcpy(&u, &v, 4);
                for (int b = 0; b < 4 && put < total; b++, put++)
                    fputc(little ? (int)(u >> (8 * b) & 255) : (int)(u >> (8 * (3 - b)) & 255), f);
            }
    for (long i = 0; i < p->extra; i++)
        fputc(0, f);
    fclose(f);
}

static void test_pfm_read(void **state)
{
    (void)state;
    char path[600];
    const pfm_t cases[] = {
        {.w = 5, .h = 3, .scale = -1, .bad_at = -1},                            /* little-endian colour */
        {.w = 5, .h = 3, .scale = 1, .bad_at = -1},                             /* big-endian colour */
        {.w = 4, .h = 6, .scale = -1, .grey = 1, .bad_at = -1},                 /* little-endian grey */
        {.w = 1, .h = 2, .scale = 1.0, .grey = 1, .bad_at = -1},                /* big-endian grey */
        {.w = 3, .h = 2, .scale = -2.0, .bad_at = -1},                          /* the scale's magnitude multiplies */
        {.header = "PF 3 2 -1.0\n", .w = 3, .h = 2, .scale = -1, .bad_at = -1}, /* one line, spaces */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const pfm_t *p = &cases[i];
        snprintf(path, sizeof path, "%s/reference-%zu.pfm", unit_tmpdir(), i);
        write_pfm(path, p);
        uint32_t w, h;
        int nc;
        double *rgb;
        if (pm_pfm_read(path, &w, &h, &nc, &rgb) != PM_OK)
            fail_msg("case %zu: %s", i, pm_error_message());
        assert_int_equal(w, p->w);
        assert_int_equal(h, p->h);
        assert_int_equal(nc, p->grey ? 1 : 3);
        for (uint32_t y = 0; y < h; y++)
            for (uint32_t x = 0; x < w; x++)
                for (int c = 0; c < 3; c++) {
                    double want = (double)pfm_value(x, y, p->grey ? 0 : c) * fabs(p->scale);
                    if (rgb[3 * (y * w + x) + (size_t)c] != want)
                        fail_msg("case %zu: pixel (%u, %u) channel %d is %g, want %g", i, x, y, c,
                                 rgb[3 * (y * w + x) + (size_t)c], want);
                }
        free(rgb);
        pm_rgb_image_t im;
        assert_int_equal(pm_rgb_image_read(path, &im), PM_OK);
        assert_string_equal(im.kind, "pfm");
        assert_true(im.w == p->w && im.h == p->h &&
                    im.rgb[3 * (size_t)im.w] == (double)pfm_value(0, 1, 0) * fabs(p->scale));
        pm_rgb_image_free(&im);
    }
}

/* A PFM pmtk refuses: PM_ERR_INPUT, a message naming the file and holding words. */
static void pfm_refused(const char *name, const pfm_t *p, const char *words)
{
    char path[600];
    ref_path(path, sizeof path, name);
    write_pfm(path, p);
    uint32_t w, h;
    int nc;
    double *rgb = (double *)&w;
    assert_int_equal(pm_pfm_read(path, &w, &h, &nc, &rgb), PM_ERR_INPUT);
    assert_null(rgb);
    if (!strstr(pm_error_message(), words) || !strstr(pm_error_message(), name))
        fail_msg("%s: message '%s' lacks '%s'", name, pm_error_message(), words);
    pm_rgb_image_t im;
    assert_int_equal(pm_rgb_image_read(path, &im), PM_ERR_INPUT); /* by its magic, not as a pmtk file */
    assert_non_null(strstr(pm_error_message(), words));
}

static void test_pfm_refusals(void **state)
{
    (void)state;
    const pfm_t ok = {.w = 4, .h = 3, .scale = -1, .bad_at = -1};
    pfm_t p = ok;
    p.cut = 5;
    pfm_refused("truncated.pfm", &p, "truncated PFM image");
    pfm_refused("truncated.pfm", &p, "139 of 144 bytes of pixels (4x3, 3 channels)");
    p = ok, p.grey = 1, p.cut = 48;
    pfm_refused("empty.pfm", &p, "0 of 48 bytes of pixels (4x3, 1 channel)");
    p = ok, p.extra = 12;
    pfm_refused("long.pfm", &p, "12 bytes after the last pixel of 4x3 (3 channels)");
    p = ok, p.header = "PF\n0 3\n-1\n";
    pfm_refused("zero.pfm", &p, "bad size '0' x '3'");
    p = ok, p.header = "PF\n4 70000\n-1\n";
    pfm_refused("tall.pfm", &p, "bad size '4' x '70000': expected whole numbers from 1 to 65536");
    p = ok, p.header = "PF\n4x 3\n-1\n";
    pfm_refused("word.pfm", &p, "bad size '4x' x '3'");
    p = ok, p.header = "PF\n-4 3\n-1\n";
    pfm_refused("minus.pfm", &p, "bad size '-4' x '3'");
    p = ok, p.header = "PF\n4 3\n0\n";
    pfm_refused("scale0.pfm", &p, "bad scale '0'");
    p = ok, p.header = "PF\n4 3\nnan\n";
    pfm_refused("scalenan.pfm", &p, "bad scale 'nan'");
    p = ok, p.header = "PF\n4 3", p.cut = 144;
    pfm_refused("short.pfm", &p, "the header ends early");
    /* values, counted in file order: index 3 * (4 * 2 + 1) + 1 is the top row's (1, 0), G */
    p = ok, p.bad_at = 28, p.bad = NAN;
    pfm_refused("nan.pfm", &p, "pixel (1, 0) channel G is nan");
    p = ok, p.bad_at = 0, p.bad = INFINITY;
    pfm_refused("inf.pfm", &p, "pixel (0, 2) channel R is inf");
    p = ok, p.bad_at = 35, p.bad = -1.5f;
    pfm_refused("negative.pfm", &p, "pixel (3, 0) channel B is -1.5: radiance must be finite and not negative");
    p = ok, p.grey = 1, p.bad_at = 2, p.bad = -1;
    pfm_refused("negative-grey.pfm", &p, "pixel (2, 2) channel Y is -1");
}

/* A reference of another size than the test: the command line is at fault (exit 2), and the
 * message names both files and sizes. An EXR and a PFM of the same pixels measure zero. */
static void test_reference_size(void **state)
{
    (void)state;
    char exr[600], pfm[600], small[600];
    ref_path(exr, sizeof exr, "size.exr");
    ref_path(pfm, sizeof pfm, "size.pfm");
    ref_path(small, sizeof small, "size-small.pfm");
    pfm_t p = {.w = 6, .h = 4, .scale = 1, .bad_at = -1};
    write_pfm(pfm, &p);
    float px[72];
    for (uint32_t y = 0; y < 4; y++)
        for (uint32_t x = 0; x < 6; x++)
            for (int c = 0; c < 3; c++)
                px[3 * (y * 6 + x) + (uint32_t)c] = pfm_value(x, y, c);
    assert_int_equal(pm_exr_write_rgb(exr, 6, 4, px, PM_EXR_FLOAT, PM_EXR_PIZ, NULL, 0), PM_OK);
    p.h = 3;
    write_pfm(small, &p);
    pm_rgb_image_t t, r, s;
    assert_int_equal(pm_rgb_image_read(exr, &t), PM_OK);
    assert_int_equal(pm_rgb_image_read(pfm, &r), PM_OK);
    assert_int_equal(pm_rgb_image_read(small, &s), PM_OK);
    pm_image_errors_t e;
    assert_int_equal(pm_image_errors(&t, &r, 0.01, PM_ERRIMG_ABS, &e, NULL), PM_OK);
    assert_true(e.rmse == 0 && e.max_abs == 0);
    assert_int_equal(pm_image_errors(&t, &s, 0.01, PM_ERRIMG_ABS, &e, NULL), PM_ERR_USAGE);
    assert_non_null(strstr(pm_error_message(), "size.exr' is 6x4 but '"));
    assert_non_null(strstr(pm_error_message(), "size-small.pfm' is 6x3"));
    pm_rgb_image_free(&t);
    pm_rgb_image_free(&r);
    pm_rgb_image_free(&s);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_exr_layouts),  cmocka_unit_test(test_exr_refusals),   cmocka_unit_test(test_pfm_read),
    cmocka_unit_test(test_pfm_refusals), cmocka_unit_test(test_reference_size),
};
UNIT_GROUP(unit_refimage, "refimage", tests);
