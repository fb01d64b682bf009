/* tone.c: luminance, tone curves and the 8-bit sRGB preview that composite writes beside its
 * OpenEXR image (see tone.h). The HDR values themselves are never tone mapped: only the
 * preview is, for people who just want to look. */
#include "image/tone.h"

#include <math.h>
#include <stdlib.h>

#include "base/image.h"

const char *const pm_tone_names[] = {"srgb", "filmic", NULL};

double pm_luminance(const double rgb[3]) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

/* Narkowicz's fit (2015) of the ACES reference rendering transform: a shoulder that rolls
 * highlights off instead of clipping them. */
float pm_tone_filmic(float x)
{
    if (!(x > 0.0f))
        return 0.0f;
    float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    return y < 1.0f ? y : 1.0f;
}

uint64_t pm_tone_rgb8(const double *rgb, size_t n, double exposure, pm_tone_t tone, uint8_t *rgb8_out)
{
    double gain = exp2(exposure);
    uint64_t clipped = 0;
    for (size_t i = 0; i < 3 * n; i++) {
        float v = (float)(rgb[i] * gain);
        if (tone == PM_TONE_FILMIC)
            v = pm_tone_filmic(v);
        clipped += v >= 1.0f;
        rgb8_out[i] = pm_srgb8(v);
    }
    return clipped;
}

pm_result_t pm_tone_write_png(const char *path, const double *rgb, uint32_t w, uint32_t h, double exposure,
                              pm_tone_t tone, double *clipped_out)
{
    size_t n = (size_t)w * h;
    uint8_t *img = malloc(3 * n);
    if (!img)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the %ux%u preview '%s'", w, h, path);
    uint64_t clipped = pm_tone_rgb8(rgb, n, exposure, tone, img);
    pm_result_t r = pm_png_write_rgb8(path, w, h, img);
    free(img);
    *clipped_out = n ? (double)clipped / (3.0 * (double)n) : 0.0;
    return r;
}
