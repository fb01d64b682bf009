/* envmap.c: the sky's lat-long environment map (scene.h, pm_envmap_t): its values checked and
 * its sampling tables (rows, then columns, by luminance times solid angle) built. */
#include "render/scene.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/scene_load.h"

pm_result_t pm_envmap_init(pm_envmap_t *e, uint32_t w, uint32_t h, float *rgb)
{
    memset(e, 0, sizeof *e);
    e->w = w, e->h = h, e->rgb = rgb;
    size_t n = (size_t)w * h;
    for (size_t i = 0; i < 3 * n; i++)
        if (!(rgb[i] >= 0.0f && isfinite(rgb[i]))) {
            size_t px = i / 3;
            char v[32];
            snprintf(v, sizeof v, "%g", (double)rgb[i]);
            pm_result_t r =
                pm_error_set(PM_ERR_INPUT, "pixel (%zu, %zu) channel %c = %s is not a radiance (finite, >= 0)", px % w,
                             px / w, "RGB"[i % 3], v);
            pm_envmap_free(e);
            return r;
        }
    e->row_cdf = malloc(h * sizeof(double));
    e->col_cdf = malloc(n * sizeof(double));
    e->pix_p = malloc(n * sizeof(double));
    if (!e->row_cdf || !e->col_cdf || !e->pix_p) {
        pm_envmap_free(e);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the tables of a %" PRIu32 "x%" PRIu32 " map", w, h);
    }
    double acc = 0.0;
    for (uint32_t y = 0; y < h; y++) {
        /* Luminance (Rec. 709) times the pixel's solid angle over 2 pi / w: sin at its centre. */
        double st = sin(M_PI * (y + 0.5) / h), row = 0.0;
        double dom = 2.0 * M_PI / w * (cos(M_PI * y / h) - cos(M_PI * (y + 1.0) / h));
        for (uint32_t x = 0; x < w; x++) {
            const float *p = rgb + 3 * ((size_t)y * w + x);
            double wt = (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) * st;
            e->pix_p[(size_t)y * w + x] = wt;
            e->col_cdf[(size_t)y * w + x] = row += wt;
            for (int k = 0; k < 3; k++)
                e->integral[k] += p[k] * dom;
        }
        e->row_cdf[y] = acc += row;
    }
    e->total = acc;
    for (uint32_t y = 0; y < h && acc > 0.0; y++) {
        double row = e->col_cdf[(size_t)y * w + w - 1];
        for (uint32_t x = 0; x < w; x++) {
            e->pix_p[(size_t)y * w + x] /= acc;
            e->col_cdf[(size_t)y * w + x] = row > 0.0 ? e->col_cdf[(size_t)y * w + x] / row : (x + 1.0) / w;
        }
        e->col_cdf[(size_t)y * w + w - 1] = 1.0;
        e->row_cdf[y] /= acc;
    }
    if (acc > 0.0)
        e->row_cdf[h - 1] = 1.0;
    return PM_OK;
}

void pm_envmap_free(pm_envmap_t *e)
{
    free(e->rgb);
    free(e->row_cdf);
    free(e->col_cdf);
    free(e->pix_p);
    memset(e, 0, sizeof *e);
}
