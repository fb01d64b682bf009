/* texture.c: image textures for the scene loader (texture.h): PNG through libpng's simplified
 * reader, JPEG through libjpeg(-turbo), OpenEXR through base/exr.h, Truevision TGA (Crytek
 * Sponza's textures) through stb_image (Debian's libstb); all become 4 channels per
 * texel, and lookups filter bilinearly with repeat addressing. Read once per stage by
 * pm_scene_load; read-only afterwards, so lookups are safe from any thread. */
#include "render/texture.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* after stdio.h: jpeglib.h uses FILE without including it */
#include <jpeglib.h>
#include <stb_image.h>

#include "base/exr.h"
#include "base/hash.h"

static float srgb_table[256];
static int srgb_ready;

/* Fills the table once; called by the loader before any thread looks a texel up. */
static void srgb_init(void)
{
    if (srgb_ready)
        return;
    for (int i = 0; i < 256; i++) {
        double c = i / 255.0;
        srgb_table[i] = (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
    }
    srgb_ready = 1;
}

float pm_srgb_to_linear(uint8_t c)
{
    srgb_init();
    return srgb_table[c];
}

static pm_result_t check_size(const char *path, uint64_t w, uint64_t h)
{
    if (w == 0 || h == 0 || w > PM_TEXTURE_MAX_SIDE || h > PM_TEXTURE_MAX_SIDE)
        return pm_error_set(PM_ERR_INPUT, "texture '%s': %llu x %llu pixels: each side must be 1 to %u", path,
                            (unsigned long long)w, (unsigned long long)h, PM_TEXTURE_MAX_SIDE);
    return PM_OK;
}

static pm_result_t load_png(const char *path, pm_texture_t *t)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return pm_error_set(PM_ERR_INPUT, "texture '%s': libpng: %s", path, im.message);
    pm_result_t r = check_size(path, im.width, im.height);
    if (r != PM_OK) {
        png_image_free(&im);
        return r;
    }
    t->has_alpha = (im.format & PNG_FORMAT_FLAG_ALPHA) != 0;
    t->grey = (im.format & PNG_FORMAT_FLAG_COLOR) == 0;
    t->w = im.width, t->h = im.height;
    im.format = PNG_FORMAT_RGBA; /* 8-bit sRGB colour, linear alpha */
    t->u8 = malloc((size_t)t->w * t->h * 4);
    if (!t->u8) {
        png_image_free(&im);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for texture '%s' (%u x %u)", path, t->w, t->h);
    }
    if (!png_image_finish_read(&im, NULL, t->u8, 0, NULL))
        return pm_error_set(PM_ERR_INPUT, "texture '%s': libpng: %s", path, im.message);
    return PM_OK;
}

typedef struct {
    struct jpeg_error_mgr pub;
    jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
} jpeg_fail_t;

static void jpeg_on_error(j_common_ptr cinfo)
{
    jpeg_fail_t *f = (jpeg_fail_t *)cinfo->err;
    f->pub.format_message(cinfo, f->message);
    longjmp(f->jump, 1);
}

static void jpeg_on_message(j_common_ptr cinfo, int level)
{
    (void)cinfo, (void)level; /* warnings about recoverable corruption: the decoder goes on */
}

static pm_result_t load_jpeg(const char *path, FILE *f, pm_texture_t *t)
{
    struct jpeg_decompress_struct cinfo;
    jpeg_fail_t err;
    memset(&err, 0, sizeof err);
    cinfo.err = jpeg_std_error(&err.pub);
    err.pub.error_exit = jpeg_on_error;
    err.pub.emit_message = jpeg_on_message;
    uint8_t *row = NULL;
    if (setjmp(err.jump)) {
        jpeg_destroy_decompress(&cinfo);
        free(row);
        return pm_error_set(PM_ERR_INPUT, "texture '%s': libjpeg: %s", path, err.message);
    }
    jpeg_create_decompress(&cinfo);
    jpeg_stdio_src(&cinfo, f);
    jpeg_read_header(&cinfo, TRUE);
    if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK) {
        jpeg_destroy_decompress(&cinfo);
        return pm_error_set(PM_ERR_INPUT, "texture '%s': a CMYK JPEG: only grey and RGB JPEGs are read", path);
    }
    pm_result_t r = check_size(path, cinfo.image_width, cinfo.image_height);
    if (r != PM_OK) {
        jpeg_destroy_decompress(&cinfo);
        return r;
    }
    t->grey = cinfo.num_components == 1;
    cinfo.out_color_space = JCS_RGB;
    jpeg_start_decompress(&cinfo);
    t->w = cinfo.output_width, t->h = cinfo.output_height;
    t->u8 = malloc((size_t)t->w * t->h * 4);
    row = malloc((size_t)t->w * 3);
    if (!t->u8 || !row) {
        jpeg_destroy_decompress(&cinfo);
        free(row);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for texture '%s' (%u x %u)", path, t->w, t->h);
    }
    while (cinfo.output_scanline < cinfo.output_height) {
        uint32_t y = cinfo.output_scanline;
        JSAMPROW rp = row;
        jpeg_read_scanlines(&cinfo, &rp, 1);
        uint8_t *o = t->u8 + (size_t)4 * t->w * y;
        for (uint32_t x = 0; x < t->w; x++)
            o[4 * x] = row[3 * x], o[4 * x + 1] = row[3 * x + 1], o[4 * x + 2] = row[3 * x + 2], o[4 * x + 3] = 255;
    }
    jpeg_finish_decompress(&cinfo);
    jpeg_destroy_decompress(&cinfo);
    free(row);
    return PM_OK;
}

static pm_result_t load_exr(const char *path, pm_texture_t *t)
{
    uint32_t w = 0, h = 0;
    float *rgb = NULL;
    pm_result_t r = pm_exr_read_rgb(path, &w, &h, &rgb);
    if (r != PM_OK) {
        pm_error_prefix("texture '%s'", path);
        return r;
    }
    if ((r = check_size(path, w, h)) != PM_OK) {
        free(rgb);
        return r;
    }
    t->w = w, t->h = h;
    t->f32 = malloc((size_t)w * h * 4 * sizeof(float));
    if (!t->f32) {
        free(rgb);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for texture '%s' (%u x %u)", path, w, h);
    }
    for (size_t i = 0; i < (size_t)w * h; i++) {
        for (int c = 0; c < 3; c++) {
            float v = rgb[3 * i + c];
            /* a texture scales an albedo in [0, 1]: anything else breaks energy conservation */
            if (!(v >= 0.0f && v <= 1.0f)) {
                free(rgb);
                return pm_error_set(PM_ERR_INPUT, "texture '%s': pixel (%zu, %zu) channel %c = %g is outside [0, 1]",
                                    path, i % w, i / w, "rgb"[c], v);
            }
            t->f32[4 * i + c] = v;
        }
        t->f32[4 * i + 3] = 1.0f;
    }
    free(rgb);
    return PM_OK;
}

/* TGA has no signature: a file named .tga that is none of the others. stb_image reads its
 * size first, so that a huge image is refused before it is decoded. */
static pm_result_t load_tga(const char *path, pm_texture_t *t)
{
    int w = 0, h = 0, n = 0;
    if (!stbi_info(path, &w, &h, &n))
        return pm_error_set(PM_ERR_INPUT, "texture '%s': stb_image: %s", path, stbi_failure_reason());
    pm_result_t r = check_size(path, (uint64_t)(w > 0 ? w : 0), (uint64_t)(h > 0 ? h : 0));
    if (r != PM_OK)
        return r;
    stbi_uc *px = stbi_load(path, &w, &h, &n, 4); /* rows from the top, RGBA */
    if (!px)
        return pm_error_set(PM_ERR_INPUT, "texture '%s': stb_image: %s", path, stbi_failure_reason());
    t->w = (uint32_t)w, t->h = (uint32_t)h;
    t->has_alpha = n == 2 || n == 4;
    t->grey = n <= 2;
    t->u8 = malloc((size_t)t->w * t->h * 4);
    if (t->u8)
        memcpy(t->u8, px, (size_t)t->w * t->h * 4);
    stbi_image_free(px);
    return t->u8 ? PM_OK : pm_error_set(PM_ERR_NOMEM, "out of memory for texture '%s' (%u x %u)", path, t->w, t->h);
}

static void texture_hash(pm_texture_t *t)
{
    uint64_t h[3] = {t->w, t->h, 0};
    h[2] = t->u8 ? pm_hash_bytes(t->u8, (size_t)t->w * t->h * 4)
                 : pm_hash_bytes(t->f32, (size_t)t->w * t->h * 4 * sizeof(float));
    t->hash = pm_hash_bytes(h, sizeof h);
}

pm_result_t pm_texture_load(const char *path, pm_texture_t *out)
{
    memset(out, 0, sizeof *out);
    snprintf(out->path, sizeof out->path, "%s", path);
    srgb_init();
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(pm_result_of_errno(errno), "cannot open texture '%s': %s", path, strerror(errno));
    uint8_t magic[8] = {0};
    size_t n = fread(magic, 1, sizeof magic, f);
    pm_result_t r;
    if (n >= 8 && memcmp(magic, "\x89PNG\r\n\x1a\n", 8) == 0) {
        fclose(f);
        r = load_png(path, out);
    } else if (n >= 3 && magic[0] == 0xff && magic[1] == 0xd8 && magic[2] == 0xff) {
        rewind(f);
        r = load_jpeg(path, f, out);
        fclose(f);
    } else if (n >= 4 && memcmp(magic, "\x76\x2f\x31\x01", 4) == 0) {
        fclose(f);
        r = load_exr(path, out);
    } else if (strlen(path) > 4 && strcasecmp(path + strlen(path) - 4, ".tga") == 0) {
        fclose(f);
        r = load_tga(path, out);
    } else {
        int was_error = ferror(f);
        fclose(f);
        r = was_error ? pm_error_set(PM_ERR_IO, "cannot read texture '%s'", path)
                      : pm_error_set(PM_ERR_INPUT,
                                     "texture '%s': not a PNG, JPEG, OpenEXR or TGA image (%zu bytes read; convert "
                                     "other formats, DDS or BMP, to PNG)",
                                     path, n);
    }
    if (r == PM_OK)
        texture_hash(out);
    else
        pm_texture_free(out);
    return r;
}

pm_result_t pm_texture_solid(const char *name, const float rgb[3], pm_texture_t *out)
{
    memset(out, 0, sizeof *out);
    snprintf(out->path, sizeof out->path, "%s", name);
    out->w = out->h = 1;
    out->f32 = malloc(4 * sizeof(float));
    if (!out->f32)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    memcpy(out->f32, rgb, 3 * sizeof(float));
    out->f32[3] = 1.0f;
    texture_hash(out);
    return PM_OK;
}

void pm_texture_free(pm_texture_t *t)
{
    free(t->u8);
    free(t->f32);
    t->u8 = NULL;
    t->f32 = NULL;
}

/* Texel (x, y) (y from the top) as 4 linear floats. */
static inline void texel(const pm_texture_t *t, uint32_t x, uint32_t y, int srgb, float o[4])
{
    size_t i = 4 * ((size_t)y * t->w + x);
    if (t->f32) {
        memcpy(o, t->f32 + i, 4 * sizeof(float));
        return;
    }
    const uint8_t *p = t->u8 + i;
    for (int c = 0; c < 3; c++)
        o[c] = srgb ? srgb_table[p[c]] : p[c] * (1.0f / 255.0f);
    o[3] = p[3] * (1.0f / 255.0f);
}

void pm_texture_lookup(const pm_texture_t *t, float u, float v, int srgb, float rgba_out[4])
{
    if (!isfinite(u) || !isfinite(v))
        u = v = 0.0f;
    /* repeat: the fraction in [0, 1); texel centres at (i + 1/2) / w, v up from the bottom row */
    u -= floorf(u);
    v -= floorf(v);
    float x = u * (float)t->w - 0.5f, y = (1.0f - v) * (float)t->h - 0.5f;
    float fx0 = floorf(x), fy0 = floorf(y), fx = x - fx0, fy = y - fy0;
    /* x in [-1/2, w - 1/2]: the left texel is -1 (the last, wrapped) to w - 1 */
    long x0 = (long)fx0, y0 = (long)fy0;
    uint32_t xa = x0 < 0 ? t->w - 1 : x0 >= (long)t->w ? t->w - 1 : (uint32_t)x0, xb = xa + 1 == t->w ? 0 : xa + 1;
    uint32_t ya = y0 < 0 ? t->h - 1 : y0 >= (long)t->h ? t->h - 1 : (uint32_t)y0, yb = ya + 1 == t->h ? 0 : ya + 1;
    float a[4], b[4], c[4], d[4];
    texel(t, xa, ya, srgb, a);
    texel(t, xb, ya, srgb, b);
    texel(t, xa, yb, srgb, c);
    texel(t, xb, yb, srgb, d);
    for (int k = 0; k < 4; k++)
        rgba_out[k] = (1.0f - fy) * ((1.0f - fx) * a[k] + fx * b[k]) + fy * ((1.0f - fx) * c[k] + fx * d[k]);
}
