/* queries.c: the gather-points format, written by trace-gather-points, reordered by
 * hilbert-sort and read by simd-gather. Header keys width and height give the image,
 * materials and material.K the reflectance table the material channel indexes. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/formats.h"

static const pm_channel_t query_channels[] = {
    {"position", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_FINITE, "m", "where the radiance estimate is made"},
    {"normal", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_UNIT, "1", "unit surface normal at the query"},
    {"weight", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "1",
     "RGB path weight from the query's radiance to its pixel"},
    {"pixel", PM_TYPE_U32, 1, PM_CH_REQUIRED, "1", "pixel index y * width + x"},
    {"material", PM_TYPE_U16, 1, 0, "1", "index into the material table (scenes with several materials)"},
    {"direction", PM_TYPE_F32, 3, PM_CH_UNIT, "1", "unit outgoing direction at the query (glossy scenes)"},
};

pm_result_t pm_image_size_check(uint64_t w, uint64_t h)
{
    if (w < 1 || h < 1 || w > PM_IMAGE_SIDE_MAX || h > PM_IMAGE_SIDE_MAX || w * h > PM_IMAGE_PIXELS_MAX)
        return pm_error_set(PM_ERR_INPUT,
                            "image size %" PRIu64 "x%" PRIu64 " outside 1..%u per side and %u pixels in all", w, h,
                            PM_IMAGE_SIDE_MAX, PM_IMAGE_PIXELS_MAX);
    return PM_OK;
}

pm_result_t pm_header_get_image_size(const pm_header_t *h, const char *path, uint32_t *w_out, uint32_t *h_out)
{
    uint64_t w, ht;
    pm_result_t r = pm_header_get_u64(h, path, "width", &w);
    if (r == PM_OK)
        r = pm_header_get_u64(h, path, "height", &ht);
    if (r != PM_OK)
        return r;
    if ((r = pm_image_size_check(w, ht)) != PM_OK) {
        pm_error_prefix("%s '%s'", h->schema->title, path);
        return r;
    }
    *w_out = (uint32_t)w;
    *h_out = (uint32_t)ht;
    return PM_OK;
}

pm_result_t pm_queries_set_materials(pm_header_t *h, const pm_material_t *m, size_t n)
{
    pm_result_t r = pm_header_set(h, "materials", "%zu", n);
    for (size_t i = 0; i < n && r == PM_OK; i++) {
        char key[32];
        snprintf(key, sizeof key, "material.%zu", i);
        /* a mirror or glass says so after the standard part; other materials read as they always did */
        char extra[96] = "";
        if (m[i].kind == PM_MAT_MIRROR)
            snprintf(extra, sizeof extra, " mirror kr %.9g %.9g %.9g", m[i].kr[0], m[i].kr[1], m[i].kr[2]);
        else if (m[i].kind == PM_MAT_GLASS)
            snprintf(extra, sizeof extra, " glass ior %.9g tf %.9g %.9g %.9g", m[i].ior, m[i].tf[0], m[i].tf[1],
                     m[i].tf[2]);
        r = pm_header_set(h, key, "%s kd %.9g %.9g %.9g ks %.9g %.9g %.9g ns %.9g%s", m[i].name[0] ? m[i].name : "-",
                          m[i].kd[0], m[i].kd[1], m[i].kd[2], m[i].ks[0], m[i].ks[1], m[i].ks[2], m[i].ns, extra);
    }
    return r;
}

pm_result_t pm_queries_get_materials(const pm_header_t *h, const char *path, pm_material_t **m_out, size_t *n_out)
{
    uint64_t n;
    pm_result_t r = pm_header_get_u64(h, path, "materials", &n);
    if (r != PM_OK)
        return r;
    if (n < 1 || n > 65536)
        return pm_error_set(PM_ERR_INPUT, "queries '%s': materials=%" PRIu64 " outside 1..65536", path, n);
    pm_material_t *m = calloc(n, sizeof *m);
    if (!m)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " materials", n);
    for (uint64_t i = 0; i < n; i++) {
        char key[32];
        snprintf(key, sizeof key, "material.%" PRIu64, i);
        const char *v = pm_header_get(h, key);
        int used = 0, more = 0;
        m[i].ior = 1.0f, m[i].tf[0] = m[i].tf[1] = m[i].tf[2] = 1.0f;
        int ok = v && sscanf(v, "%63s kd %f %f %f ks %f %f %f ns %f%n", m[i].name, &m[i].kd[0], &m[i].kd[1],
                             &m[i].kd[2], &m[i].ks[0], &m[i].ks[1], &m[i].ks[2], &m[i].ns, &used) == 8;
        if (ok && v[used] == ' ' && strncmp(v + used, " mirror", 7) == 0) {
            m[i].kind = PM_MAT_MIRROR;
            ok = sscanf(v + used, " mirror kr %f %f %f%n", &m[i].kr[0], &m[i].kr[1], &m[i].kr[2], &more) == 3;
        } else if (ok && v[used] == ' ' && strncmp(v + used, " glass", 6) == 0) {
            m[i].kind = PM_MAT_GLASS;
            ok = sscanf(v + used, " glass ior %f tf %f %f %f%n", &m[i].ior, &m[i].tf[0], &m[i].tf[1], &m[i].tf[2],
                        &more) == 4;
        }
        if (!ok || v[used + more] != '\0') {
            free(m);
            return pm_error_set(PM_ERR_INPUT, "queries '%s': header key %s is %s", path, key,
                                v ? "not 'NAME kd R G B ks R G B ns E', then optionally 'mirror kr R G B' or "
                                    "'glass ior N tf R G B'"
                                  : "missing");
        }
        /* a specular entry has no standard part, a reflectance in [0, 1] and an index > 0 */
        for (int k = 0; k < 3 && m[i].kind != PM_MAT_STANDARD; k++)
            if (!(m[i].kr[k] >= 0.0f && m[i].kr[k] <= 1.0f && m[i].tf[k] >= 0.0f && m[i].tf[k] <= 1.0f) ||
                !(m[i].ior > 0.0f && m[i].ior < INFINITY) || m[i].kd[k] != 0.0f || m[i].ks[k] != 0.0f) {
                free(m);
                return pm_error_set(PM_ERR_INPUT, "queries '%s': %s is not a physical mirror or glass", path, key);
            }
        for (int k = 0; k < 3; k++)
            if (!(m[i].kd[k] >= 0.0f && m[i].ks[k] >= 0.0f && m[i].kd[k] + m[i].ks[k] <= 1.0f + 1e-6f) ||
                !(m[i].ns >= 0.0f && m[i].ns <= 1e6f)) {
                free(m);
                return pm_error_set(PM_ERR_INPUT, "queries '%s': %s is not an energy-conserving material", path, key);
            }
    }
    *m_out = m;
    *n_out = (size_t)n;
    return PM_OK;
}

static pm_result_t validate_header(const pm_header_t *h, const char *path)
{
    uint32_t w, ht;
    pm_result_t r = pm_header_get_image_size(h, path, &w, &ht);
    if (r != PM_OK)
        return r;
    pm_material_t *m;
    size_t n;
    if ((r = pm_queries_get_materials(h, path, &m, &n)) != PM_OK)
        return r;
    free(m);
    if (n > 1 && !(h->channels & (1u << PM_QUERY_MATERIAL)))
        return pm_error_set(PM_ERR_INPUT, "queries '%s': %zu materials but no material channel", path, n);
    return PM_OK;
}

static pm_result_t validate_records(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                    uint64_t first)
{
    uint32_t w, ht;
    pm_result_t r = pm_header_get_image_size(h, path, &w, &ht);
    if (r != PM_OK)
        return r;
    uint64_t npix = (uint64_t)w * ht, nmat = 1;
    if ((r = pm_header_get_u64(h, path, "materials", &nmat)) != PM_OK)
        return r;
    const pm_schema_t *s = h->schema;
    size_t rs = h->record_size, pix_off = pm_schema_offset(s, h->channels, PM_QUERY_PIXEL);
    int has_mat = (h->channels >> PM_QUERY_MATERIAL) & 1;
    size_t mat_off = pm_schema_offset(s, h->channels, PM_QUERY_MATERIAL);
    for (uint64_t i = 0; i < n; i++) {
        uint32_t pix;
        memcpy(&pix, rec + i * rs + pix_off, 4);
        if (pix >= npix)
            return pm_error_set(PM_ERR_INPUT,
                                "bad value in queries '%s': record %" PRIu64 " pixel %" PRIu32 " outside the %" PRIu32
                                "x%" PRIu32 " image",
                                path, first + i, pix, w, ht);
        if (has_mat) {
            uint16_t m;
            memcpy(&m, rec + i * rs + mat_off, 2);
            if (m >= nmat)
                return pm_error_set(PM_ERR_INPUT,
                                    "bad value in queries '%s': record %" PRIu64 " material %u of %" PRIu64, path,
                                    first + i, m, nmat);
        }
    }
    return PM_OK;
}

const pm_schema_t pm_queries_schema = {
    .name = "queries",
    .major = 2,
    .minor = 0,
    .oldest_major = 1,
    .title = "queries",
    .channels = query_channels,
    .nchannels = sizeof query_channels / sizeof query_channels[0],
    .validate_header = validate_header,
    .validate_records = validate_records,
};
