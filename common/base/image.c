/* image.c: PNG previews (see image.h). */
#include "base/image.h"

#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <string.h>

#include "base/atomic.h"

uint8_t pm_srgb8(float v)
{
    if (!(v > 0.0f))
        return 0; /* negative and NaN */
    if (v >= 1.0f)
        return 255;
    float s = v <= 0.0031308f ? 12.92f * v : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
    return (uint8_t)lrintf(255.0f * s);
}

static void png_error_fn(png_structp png, png_const_charp msg)
{
    pm_error_set(PM_ERR_IO, "libpng: %s", msg);
    longjmp(png_jmpbuf(png), 1);
}

static void png_warning_fn(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

pm_result_t pm_png_write_rgb8(const char *path, uint32_t w, uint32_t h, const uint8_t *rgb)
{
    pm_atomic_t out;
    pm_result_t r = pm_atomic_open(path, &out);
    if (r != PM_OK)
        return r;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, png_error_fn, png_warning_fn);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        pm_atomic_abort(&out);
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing '%s'", path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        pm_atomic_abort(&out);
        pm_error_prefix("cannot write '%s'", path);
        return PM_ERR_IO;
    }
    png_init_io(png, out.f);
    png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (uint32_t y = 0; y < h; y++)
        png_write_row(png, (png_const_bytep)(rgb + (size_t)3 * w * y));
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return pm_atomic_commit(&out);
}
