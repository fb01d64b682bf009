/* texture.c: image textures for the scene loader (texture.h): files and embedded images decoded
 * by base/imgdecode.h (PNG, JPEG, OpenEXR, TGA) within a byte budget; all become 4 channels per
 * texel, and lookups filter bilinearly with repeat addressing. Read once per stage by
 * pm_scene_load; read-only afterwards, so lookups are safe from any thread. */
#include "render/texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/imgdecode.h"

static float srgb_table[256];
static int srgb_ready;

/* Fills the table once; called by the loader (and the scene cache's reader, through
 * pm_texture_prepare) before any thread looks a texel up. */
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

void pm_texture_prepare(void) { srgb_init(); }

float pm_srgb_to_linear(uint8_t c)
{
    srgb_init();
    return srgb_table[c];
}

/* A decoded image (base/imgdecode.h) as a texture: 8-bit texels kept, OpenEXR values checked. */
static pm_result_t from_image(pm_img_t *im, pm_texture_t *t)
{
    t->w = im->w, t->h = im->h, t->grey = im->grey, t->has_alpha = im->has_alpha;
    t->u8 = im->u8, t->f32 = im->f32;
    im->u8 = NULL, im->f32 = NULL;
    for (size_t i = 0; t->f32 && i < (size_t)t->w * t->h; i++)
        for (int c = 0; c < 3; c++) {
            float v = t->f32[4 * i + c];
            /* a texture scales an albedo in [0, 1]: anything else breaks energy conservation */
            if (!(v >= 0.0f && v <= 1.0f))
                return pm_error_set(PM_ERR_INPUT, "texture '%s': pixel (%zu, %zu) channel %c = %g is outside [0, 1]",
                                    t->path, i % t->w, i / t->w, "rgb"[c], v);
        }
    return PM_OK;
}

static void texture_hash(pm_texture_t *t)
{
    uint64_t h[3] = {t->w, t->h, 0};
    h[2] = t->u8 ? pm_hash_bytes(t->u8, (size_t)t->w * t->h * 4)
                 : pm_hash_bytes(t->f32, (size_t)t->w * t->h * 4 * sizeof(float));
    t->hash = pm_hash_bytes(h, sizeof h);
}

static pm_img_limits_t texture_limits(uint64_t max_bytes, const char *budget)
{
    pm_img_limits_t lim = {PM_IMG_PNG | PM_IMG_JPEG | PM_IMG_EXR | PM_IMG_TGA, max_bytes, 4, "texture", budget};
    return lim;
}

static pm_result_t finish(pm_result_t r, pm_img_t *im, pm_texture_t *out)
{
    if (r == PM_OK)
        r = from_image(im, out);
    pm_img_free(im);
    if (r == PM_OK)
        texture_hash(out);
    else
        pm_texture_free(out);
    return r;
}

pm_result_t pm_texture_load_budget(const char *path, uint64_t max_bytes, const char *budget, pm_texture_t *out)
{
    memset(out, 0, sizeof *out);
    snprintf(out->path, sizeof out->path, "%s", path);
    srgb_init();
    pm_img_limits_t lim = texture_limits(max_bytes, budget);
    pm_img_t im;
    return finish(pm_img_load(path, &lim, &im), &im, out);
}

pm_result_t pm_texture_load(const char *path, pm_texture_t *out)
{
    return pm_texture_load_budget(path, PM_TEXTURE_BUDGET_DEFAULT, NULL, out);
}

pm_result_t pm_texture_decode(const char *name, const char *hint, const void *data, size_t size, uint64_t max_bytes,
                              const char *budget, pm_texture_t *out)
{
    memset(out, 0, sizeof *out);
    snprintf(out->path, sizeof out->path, "%s", name);
    srgb_init();
    pm_img_limits_t lim = texture_limits(max_bytes, budget);
    pm_img_t im;
    return finish(pm_img_decode(name, hint, data, size, &lim, &im), &im, out);
}

pm_result_t pm_texture_from_bgra(const char *name, uint32_t w, uint32_t h, const uint8_t *bgra, uint64_t max_bytes,
                                 const char *budget, pm_texture_t *out)
{
    memset(out, 0, sizeof *out);
    snprintf(out->path, sizeof out->path, "%s", name);
    srgb_init();
    if (w == 0 || h == 0 || w > PM_TEXTURE_MAX_SIDE || h > PM_TEXTURE_MAX_SIDE || (uint64_t)w * h * 4 > max_bytes)
        return pm_error_set(PM_ERR_INPUT,
                            "texture '%s': %u x %u texels: each side must be 1 to %u, within its budget (%s)", name, w,
                            h, PM_TEXTURE_MAX_SIDE, budget ? budget : "image_budgets");
    out->w = w, out->h = h, out->has_alpha = 1;
    if (!(out->u8 = malloc((size_t)w * h * 4)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for texture '%s' (%u x %u)", name, w, h);
    for (size_t i = 0; i < (size_t)w * h; i++) {
        out->u8[4 * i] = bgra[4 * i + 2], out->u8[4 * i + 1] = bgra[4 * i + 1];
        out->u8[4 * i + 2] = bgra[4 * i], out->u8[4 * i + 3] = bgra[4 * i + 3];
    }
    texture_hash(out);
    return PM_OK;
}

uint64_t pm_texture_bytes(const pm_texture_t *t) { return (uint64_t)t->w * t->h * (t->u8 ? 4u : 4u * sizeof(float)); }

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
