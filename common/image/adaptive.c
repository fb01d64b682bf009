/* adaptive.c: the sample-count multiplier of adaptive progressive passes and the density
 * files that carry it (adaptive.h). composite --adaptive-map and pm-render make the map from
 * the running image; trace-gather-points --adaptive reads it to give each pixel its rays;
 * composite --accumulate reads it again to weigh each pixel's pass by those rays. */
#include "image/adaptive.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/args.h"
#include "formats/formats.h"

#define BISECT_STEPS 64 /* the normalising scale's bisection: far below a float's resolution */

/* The mean of clamp(c s_i) over the n pixels. */
static double clamped_mean(const double *s, uint64_t n, double c)
{
    double sum = 0.0;
    for (uint64_t i = 0; i < n; i++) {
        double v = c * s[i];
        sum += v < PM_ADAPTIVE_MIN ? PM_ADAPTIVE_MIN : v > PM_ADAPTIVE_MAX ? PM_ADAPTIVE_MAX : v;
    }
    return sum / (double)n;
}

void pm_adaptive_make(const double *mean, const double *var, const double *wsum, double w0, uint64_t passes, uint32_t w,
                      uint32_t h, float *m)
{
    static const double lum[3] = {0.2126, 0.7152, 0.0722}; /* Rec. 709, as measure-error's luminance */
    uint64_t n = (uint64_t)w * h;
    double *s = n && passes >= 2 ? calloc(2 * n, sizeof *s) : NULL;
    for (uint64_t i = 0; i < n; i++)
        m[i] = 1.0f;
    if (!s) /* one pass (no spread known), an empty image, or no memory: the uniform map, still right */
        return;
    double *t = s + n, total = 0.0;
    for (uint64_t i = 0; i < n; i++) {
        double l = 0.0, sd = 0.0, wp = wsum ? wsum[i] : w0;
        for (int k = 0; k < 3; k++) {
            l += lum[k] * mean[3 * i + (uint64_t)k];
            sd += lum[k] * sqrt(var[3 * i + (uint64_t)k] > 0.0 ? var[3 * i + (uint64_t)k] : 0.0);
        }
        double v = sd * sqrt(wp > 0.0 ? wp : 0.0) / sqrt(l * l + PM_ADAPTIVE_EPS);
        t[i] = isfinite(v) ? v : 0.0;
    }
    /* 3 x 3 maximum */
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            double v = 0.0;
            for (uint32_t yy = y ? y - 1 : 0; yy <= y + 1 && yy < h; yy++)
                for (uint32_t xx = x ? x - 1 : 0; xx <= x + 1 && xx < w; xx++)
                    v = fmax(v, t[(uint64_t)yy * w + xx]);
            s[(uint64_t)y * w + x] = v;
            total += v;
        }
    if (total > 0.0) {
        /* the scale c with mean(clamp(c s)) = 1: the mean rises with c, from PM_ADAPTIVE_MIN */
        double lo = 0.0, hi = (double)n / total;
        while (clamped_mean(s, n, hi) < 1.0 && hi < 1e300)
            hi *= 2.0;
        for (int it = 0; it < BISECT_STEPS; it++) {
            double mid = 0.5 * (lo + hi);
            if (clamped_mean(s, n, mid) < 1.0)
                lo = mid;
            else
                hi = mid;
        }
        for (uint64_t i = 0; i < n; i++) {
            double v = hi * s[i];
            m[i] = (float)(v < PM_ADAPTIVE_MIN ? PM_ADAPTIVE_MIN : v > PM_ADAPTIVE_MAX ? PM_ADAPTIVE_MAX : v);
        }
    }
    free(s);
}

uint32_t pm_adaptive_count(float m, uint32_t primary)
{
    double x = floor((double)m * (double)primary + 0.5);
    if (!(x <= (double)PM_ADAPTIVE_RAYS_MAX))
        return 0;
    return x < 1.0 ? 1u : (uint32_t)x;
}

pm_result_t pm_adaptive_read(const char *path, int kind, uint32_t w, uint32_t h, float **v_out, uint64_t *hash_out,
                             pm_header_t *hdr_out)
{
    *v_out = NULL;
    pm_table_t t;
    pm_result_t r = pm_table_read(path, &pm_density_schema, pm_schema_required(&pm_density_schema), &t);
    if (r != PM_OK)
        return r;
    uint32_t fw, fh;
    const char *k = pm_header_get(&t.hdr, "kind");
    if ((r = pm_header_get_image_size(&t.hdr, path, &fw, &fh)) != PM_OK)
        goto done;
    if (strcmp(k, pm_density_kind_names[kind])) {
        r = pm_error_set(PM_ERR_INPUT, "density map '%s' is kind=%s, not %s", path, k, pm_density_kind_names[kind]);
        goto done;
    }
    if ((w || h) && (fw != w || fh != h)) {
        r = pm_error_set(PM_ERR_INPUT, "density map '%s' is %" PRIu32 "x%" PRIu32 ", the image %" PRIu32 "x%" PRIu32,
                         path, fw, fh, w, h);
        goto done;
    }
    uint64_t n = (uint64_t)fw * fh;
    if (!(*v_out = malloc((n ? n : 1) * sizeof **v_out))) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for density map '%s'", path);
        goto done;
    }
    memcpy(*v_out, t.col[PM_DENSITY_VALUE], n * sizeof **v_out);
    if (hash_out)
        *hash_out = t.checksum;
    if (hdr_out) {
        *hdr_out = t.hdr;
        memset(&t.hdr, 0, sizeof t.hdr);
        pm_header_init(&t.hdr, &pm_density_schema);
    }
done:
    pm_table_free(&t);
    return r;
}

pm_result_t pm_adaptive_write(const char *path, int kind, uint32_t w, uint32_t h, const float *v,
                              const pm_header_t *prov, int argc, char **argv, const char *const *extra)
{
    pm_table_t t;
    uint64_t n = (uint64_t)w * h;
    pm_result_t r = pm_table_alloc(&t, &pm_density_schema, pm_schema_required(&pm_density_schema), n);
    if (r != PM_OK)
        return r;
    if (prov)
        memcpy(t.hdr.bounds, prov->bounds, sizeof t.hdr.bounds), r = pm_header_inherit(&t.hdr, prov);
    if (r == PM_OK && argv)
        r = pm_header_add_command(&t.hdr, argc, argv);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "width", "%" PRIu32, w);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "height", "%" PRIu32, h);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "kind", "%s", pm_density_kind_names[kind]);
    for (size_t i = 0; extra && extra[i] && r == PM_OK; i++) {
        const char *eq = strchr(extra[i], '=');
        char key[64];
        snprintf(key, sizeof key, "%.*s", eq ? (int)(eq - extra[i]) : 0, extra[i]);
        r = pm_header_add(&t.hdr, key, "%s", eq ? eq + 1 : "");
    }
    if (r == PM_OK) {
        memcpy(t.col[PM_DENSITY_VALUE], v, n * sizeof *v);
        r = pm_table_write(&t, path);
    }
    pm_table_free(&t);
    return r;
}

pm_result_t pm_adaptive_weight_path(const char *state, char **out)
{
    size_t len = strlen(state) + sizeof ".weight";
    if (!(*out = malloc(len)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    snprintf(*out, len, "%s.weight", state);
    return PM_OK;
}

pm_result_t pm_adaptive_from_state(const char *state, const char *map, int argc, char **argv, uint64_t *passes_out)
{
    pm_table_t t;
    const uint32_t need = 1u << PM_RADIANCE_RGB | 1u << PM_RADIANCE_VARIANCE;
    pm_result_t r = pm_table_read(state, &pm_radiance_schema, need, &t);
    if (r != PM_OK)
        return r;
    uint32_t w = 0, h = 0;
    uint64_t passes = 0;
    float *ws = NULL, *m = NULL;
    double *wd = NULL, w0 = 0.0;
    char *wpath = NULL, hash[64], *extra[2] = {hash, NULL};
    if ((r = pm_header_get_image_size(&t.hdr, state, &w, &h)) != PM_OK ||
        (r = pm_header_get_u64(&t.hdr, state, "passes", &passes)) != PM_OK)
        goto done;
    w0 = (double)passes;
    const char *wk = pm_header_get(&t.hdr, "weight"), *pw = pm_header_get(&t.hdr, "pixel_weights");
    if (wk && (pm_parse_double(wk, &w0) != PM_OK || !(w0 > 0.0 && isfinite(w0)))) {
        r = pm_error_set(PM_ERR_INPUT, "running image '%s': weight '%s' is not a number above 0", state, wk);
        goto done;
    }
    uint64_t n = (uint64_t)w * h;
    if (pw && (r = pm_adaptive_weight_path(state, &wpath)) == PM_OK &&
        (r = pm_adaptive_read(wpath, PM_DENSITY_WEIGHT, w, h, &ws, NULL, NULL)) == PM_OK &&
        !(wd = malloc((n ? n : 1) * sizeof *wd)))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " map", w, h);
    if (r != PM_OK)
        goto done;
    for (uint64_t i = 0; ws && i < n; i++)
        wd[i] = ws[i];
    if (!(m = malloc((n ? n : 1) * sizeof *m))) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " map", w, h);
        goto done;
    }
    pm_adaptive_make(t.col[PM_RADIANCE_RGB], t.col[PM_RADIANCE_VARIANCE], wd, w0, passes, w, h, m);
    snprintf(hash, sizeof hash, "INPUT=%s xxh3:%016" PRIx64, state, t.checksum);
    r = pm_adaptive_write(map, PM_DENSITY_MULTIPLIER, w, h, m, &t.hdr, argc, argv, (const char *const *)extra);
    if (passes_out)
        *passes_out = passes;
done:
    free(m);
    free(ws);
    free(wd);
    free(wpath);
    pm_table_free(&t);
    return r;
}
