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

pm_result_t pm_header_check_pixels(const pm_header_t *h, const char *path)
{
    uint32_t w, ht;
    pm_result_t r = pm_header_get_image_size(h, path, &w, &ht);
    if (r == PM_OK && h->count != (uint64_t)w * ht)
        r = pm_error_set(PM_ERR_INPUT, "wrong count in %s '%s': COUNT=%" PRIu64 " for a %" PRIu32 "x%" PRIu32 " image",
                         h->schema->title, path, h->count, w, ht);
    return r;
}

pm_result_t pm_queries_set_materials(pm_header_t *h, const pm_material_t *m, size_t n)
{
    pm_result_t r = pm_header_set(h, "materials", "%zu", n);
    for (size_t i = 0; i < n && r == PM_OK; i++) {
        char key[32];
        snprintf(key, sizeof key, "material.%zu", i);
        /* a mirror, glass or microfacet kind says so after the standard part; other materials
         * read as they always did */
        char extra[256] = "";
        const pm_material_t *q = &m[i];
        if (q->kind == PM_MAT_MIRROR)
            snprintf(extra, sizeof extra, " mirror kr %.9g %.9g %.9g", q->kr[0], q->kr[1], q->kr[2]);
        else if (q->kind == PM_MAT_GLASS)
            snprintf(extra, sizeof extra, " glass ior %.9g tf %.9g %.9g %.9g", q->ior, q->tf[0], q->tf[1], q->tf[2]);
        else if (q->kind == PM_MAT_CONDUCTOR)
            snprintf(extra, sizeof extra, " conductor alpha %.9g eta %.9g %.9g %.9g k %.9g %.9g %.9g f0 %.9g %.9g %.9g",
                     q->alpha, q->eta[0], q->eta[1], q->eta[2], q->k[0], q->k[1], q->k[2], q->f0[0], q->f0[1],
                     q->f0[2]);
        else if (q->kind == PM_MAT_ROUGH_GLASS)
            snprintf(extra, sizeof extra, " roughglass alpha %.9g ior %.9g tf %.9g %.9g %.9g", q->alpha, q->ior,
                     q->tf[0], q->tf[1], q->tf[2]);
        else if (q->kind == PM_MAT_PLASTIC)
            snprintf(extra, sizeof extra, " plastic alpha %.9g ior %.9g", q->alpha, q->ior);
        r = pm_header_set(h, key, "%s kd %.9g %.9g %.9g ks %.9g %.9g %.9g ns %.9g%s", m[i].name[0] ? m[i].name : "-",
                          m[i].kd[0], m[i].kd[1], m[i].kd[2], m[i].ks[0], m[i].ks[1], m[i].ks[2], m[i].ns, extra);
    }
    return r;
}

/* The microfacet kinds' fields (formats/material.h): one line naming the key, the field and its
 * value when one is out of range or not a number. */
static pm_result_t check_microfacet(const char *path, const char *key, const pm_material_t *m)
{
    if (m->kind != PM_MAT_CONDUCTOR && m->kind != PM_MAT_ROUGH_GLASS && m->kind != PM_MAT_PLASTIC)
        return PM_OK;
    const char *what = m->kind == PM_MAT_CONDUCTOR ? "conductor" : m->kind == PM_MAT_PLASTIC ? "plastic" : "roughglass";
    if (!(m->alpha >= 0.0f && m->alpha <= 1.0f))
        return pm_error_set(PM_ERR_INPUT, "queries '%s': %s %s alpha %g outside [0, 1]", path, key, what, m->alpha);
    if (m->kind != PM_MAT_CONDUCTOR && !(m->ior > 0.0f && m->ior <= 1e6f))
        return pm_error_set(PM_ERR_INPUT, "queries '%s': %s %s ior %g outside (0, 1e6]", path, key, what, m->ior);
    for (int k = 0; k < 3; k++) {
        /* kd is the plastic's base; no kind here has a Phong lobe */
        if (m->ks[k] != 0.0f || (m->kind != PM_MAT_PLASTIC && m->kd[k] != 0.0f))
            return pm_error_set(PM_ERR_INPUT, "queries '%s': %s %s has kd %g, ks %g (channel %d); want %s", path, key,
                                what, m->kd[k], m->ks[k], k, m->kind == PM_MAT_PLASTIC ? "ks 0" : "kd 0 and ks 0");
        if (m->kind == PM_MAT_ROUGH_GLASS && !(m->tf[k] >= 0.0f && m->tf[k] <= 1.0f))
            return pm_error_set(PM_ERR_INPUT, "queries '%s': %s roughglass tf %g (channel %d) outside [0, 1]", path,
                                key, m->tf[k], k);
        if (m->kind != PM_MAT_CONDUCTOR)
            continue;
        /* either an index in every channel or none (eta 0 0 0: the f0 colour instead) */
        int index = m->eta[0] > 0.0f;
        if (!(index ? m->eta[k] > 0.0f && m->eta[k] <= 1e6f : m->eta[k] == 0.0f) ||
            !(m->k[k] >= 0.0f && m->k[k] <= 1e6f))
            return pm_error_set(PM_ERR_INPUT,
                                "queries '%s': %s conductor eta %g k %g (channel %d): want eta in (0, 1e6] in every "
                                "channel or 0 in all, k in [0, 1e6]",
                                path, key, m->eta[k], m->k[k], k);
        if (!(m->f0[k] >= 0.0f && m->f0[k] <= 1.0f))
            return pm_error_set(PM_ERR_INPUT, "queries '%s': %s conductor f0 %g (channel %d) outside [0, 1]", path, key,
                                m->f0[k], k);
    }
    return PM_OK;
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
        } else if (ok && v[used] == ' ' && strncmp(v + used, " conductor", 10) == 0) {
            m[i].kind = PM_MAT_CONDUCTOR;
            float *e = m[i].eta, *kk = m[i].k, *f = m[i].f0;
            ok = sscanf(v + used, " conductor alpha %f eta %f %f %f k %f %f %f f0 %f %f %f%n", &m[i].alpha, &e[0],
                        &e[1], &e[2], &kk[0], &kk[1], &kk[2], &f[0], &f[1], &f[2], &more) == 10;
        } else if (ok && v[used] == ' ' && strncmp(v + used, " roughglass", 11) == 0) {
            m[i].kind = PM_MAT_ROUGH_GLASS;
            ok = sscanf(v + used, " roughglass alpha %f ior %f tf %f %f %f%n", &m[i].alpha, &m[i].ior, &m[i].tf[0],
                        &m[i].tf[1], &m[i].tf[2], &more) == 5;
        } else if (ok && v[used] == ' ' && strncmp(v + used, " plastic", 8) == 0) {
            m[i].kind = PM_MAT_PLASTIC;
            ok = sscanf(v + used, " plastic alpha %f ior %f%n", &m[i].alpha, &m[i].ior, &more) == 2;
        }
        if (!ok || v[used + more] != '\0') {
            free(m);
            return pm_error_set(PM_ERR_INPUT, "queries '%s': header key %s is %s", path, key,
                                v ? "not 'NAME kd R G B ks R G B ns E', then optionally 'mirror kr R G B', "
                                    "'glass ior N tf R G B', 'conductor alpha A eta R G B k R G B f0 R G B', "
                                    "'roughglass alpha A ior N tf R G B' or 'plastic alpha A ior N'"
                                  : "missing");
        }
        if ((r = check_microfacet(path, key, &m[i])) != PM_OK) {
            free(m);
            return r;
        }
        /* a specular entry has no standard part, a reflectance in [0, 1] and an index > 0 */
        for (int k = 0; k < 3 && (m[i].kind == PM_MAT_MIRROR || m[i].kind == PM_MAT_GLASS); k++)
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
