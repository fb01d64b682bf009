/* envmap.c: the sky's lat-long environment map (scene.h, pm_envmap_t): its values checked and
 * its sampling tables (rows, then columns, by luminance times solid angle) built; the sky's
 * frame (sky.up, sky.rotate) that turns the map and places a sun by elevation and azimuth. */
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
    e->frame[0] = e->frame[4] = e->frame[8] = 1.0;
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

/* v turned by angle a (radians) about unit axis k, right-hand rule (Rodrigues' formula). */
static void turn(const double k[3], double a, const double v[3], double out[3])
{
    double c = cos(a), sn = sin(a), kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
    double kx[3] = {k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]};
    for (int i = 0; i < 3; i++)
        out[i] = v[i] * c + kx[i] * sn + k[i] * kv * (1.0 - c);
}

void pm_sky_frame(const double up[3], double rotate_deg, double f[9])
{
    double ul = sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2]);
    double u[3] = {up[0] / ul, up[1] / ul, up[2] / ul};
    /* The shortest turn of +y onto u: about y x u = (u_z, 0, -u_x) by the angle between them. */
    double ax[3] = {u[2], 0.0, -u[0]}, sl = sqrt(u[2] * u[2] + u[0] * u[0]);
    double a = atan2(sl, u[1]);
    if (sl > 0.0)
        ax[0] /= sl, ax[2] /= sl;
    else
        ax[0] = 1.0, ax[2] = 0.0; /* +y: no turn (a = 0); -y: half a turn about +x */
    for (int i = 0; i < 3; i++) {
        double e[3] = {i == 0, i == 1, i == 2}, t[3];
        turn(ax, a, e, t);
        /* Azimuth grows from x toward z, which is a turn by -rotate about up by the right-hand rule. */
        turn(u, -rotate_deg * M_PI / 180.0, t, f + 3 * i);
    }
}

void pm_sky_frame_direction(const double f[9], double el_deg, double az_deg, double w_out[3])
{
    double el = el_deg * M_PI / 180.0, az = az_deg * M_PI / 180.0;
    double m[3] = {cos(el) * cos(az), sin(el), cos(el) * sin(az)};
    for (int k = 0; k < 3; k++)
        w_out[k] = m[0] * f[k] + m[1] * f[3 + k] + m[2] * f[6 + k];
}

void pm_envmap_set_frame(pm_envmap_t *e, const double f[9])
{
    static const double id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(e->frame, f, sizeof e->frame);
    e->framed = 0;
    for (int i = 0; i < 9; i++)
        e->framed |= f[i] != id[i];
}
