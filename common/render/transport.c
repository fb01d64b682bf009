/* transport.c: the BSDF (evaluation, lobe sampling and pdfs, the mixture), the delta BSDFs
 * of mirrors and glass (Fresnel, reflection and refraction) and the triangles' front normals that
 * every tracer shares (transport.h); the lights are render/light.c's.
 *
 * The arithmetic keeps the order of operations the tracers had before they shared it (the
 * glossy pdf weighted before it is multiplied out, the mirror direction left unnormalized
 * in the pdf and normalized in the sampler), so that their outputs stay bit-identical. */
#include "render/transport.h"

#include <math.h>
#include <stdlib.h>

#include "math/sampling.h"

void pm_brdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3], float f_out[3])
{
    float lobe = 0.0f;
    if (pm_material_is_glossy(m)) {
        float r[3];
        pm_reflect(n, wi, r);
        float cr = pm_dot3(r, wo);
        if (cr > 0.0f)
            lobe = (m->ns + 2.0f) / (2.0f * PM_PI) * powf(cr, m->ns);
    }
    for (int k = 0; k < 3; k++)
        f_out[k] = m->kd[k] * (1.0f / PM_PI) + m->ks[k] * lobe;
}

int pm_bsdf_sample_lobe(const pm_material_t *m, pm_lobe_t lobe, const float n[3], const float wo[3], float u1, float u2,
                        float wi_out[3])
{
    pm_vec3_t t, b, d;
    if (lobe == PM_LOBE_DIFFUSE) {
        pm_vec3_t nn = pm_v3_load(n);
        pm_onb(nn, &t, &b);
        d = pm_onb_to_world(pm_sample_cosine_hemisphere(u1, u2), t, b, nn);
    } else {
        /* Inverting the cdf 1 - cos^(ns+1) of the angle to the mirror direction. */
        float rr[3];
        pm_reflect(n, wo, rr);
        pm_vec3_t r = pm_v3_normalize(pm_v3_load(rr));
        float ca = powf(u1, 1.0f / (m->ns + 1.0f)), sa = sqrtf(fmaxf(0.0f, 1.0f - ca * ca)), phi = 2.0f * PM_PI * u2;
        pm_onb(r, &t, &b);
        d = pm_v3_normalize(pm_onb_to_world(pm_v3(sa * cosf(phi), sa * sinf(phi), ca), t, b, r));
    }
    pm_v3_store(wi_out, d);
    return pm_dot3(n, wi_out) > 0.0f;
}

/* The lobe's pdf at wi times w, multiplied in the order the mixture needs (w first). */
static inline float diffuse_pdf_w(float w, float cosi) { return cosi > 0.0f ? w * cosi * (1.0f / PM_PI) : 0.0f; }

static inline float glossy_pdf_w(const pm_material_t *m, float w, const float n[3], const float wi[3],
                                 const float wo[3])
{
    float r[3];
    pm_reflect(n, wo, r);
    float ca = pm_dot3(r, wi);
    return ca > 0.0f ? w * (m->ns + 1.0f) / (2.0f * PM_PI) * powf(ca, m->ns) : 0.0f;
}

float pm_bsdf_lobe_pdf(const pm_material_t *m, pm_lobe_t lobe, const float n[3], const float wi[3], const float wo[3])
{
    return lobe == PM_LOBE_DIFFUSE ? diffuse_pdf_w(1.0f, pm_dot3(n, wi)) : glossy_pdf_w(m, 1.0f, n, wi, wo);
}

float pm_bsdf_diffuse_share(const pm_material_t *m)
{
    float pd, ps;
    pm_bsdf_albedo(m, &pd, &ps);
    return pd + ps > 0.0f ? pd / (pd + ps) : 1.0f;
}

int pm_bsdf_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                   float wi_out[3])
{
    pm_lobe_t lobe = u < pm_bsdf_diffuse_share(m) ? PM_LOBE_DIFFUSE : PM_LOBE_GLOSSY;
    return pm_bsdf_sample_lobe(m, lobe, n, wo, u1, u2, wi_out);
}

float pm_bsdf_pdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    float cosi = pm_dot3(n, wi);
    if (cosi <= 0.0f)
        return 0.0f;
    float sd = pm_bsdf_diffuse_share(m), p = diffuse_pdf_w(sd, cosi);
    if (sd < 1.0f)
        p += glossy_pdf_w(m, 1.0f - sd, n, wi, wo);
    return p;
}

/* Index ratios beyond these are taken as these: their squares stay normal floats, and F and the
 * directions are those of the limit to within float precision. */
#define PM_ETA_MIN 1e-6f
#define PM_ETA_MAX 1e6f

float pm_fresnel_dielectric(float cos_i, float eta)
{
    float ci = fminf(fabsf(cos_i), 1.0f);
    if (!(eta > 0.0f) || !(ci > 0.0f))
        return 1.0f;
    eta = fminf(fmaxf(eta, PM_ETA_MIN), PM_ETA_MAX);
    float sin_t2 = (1.0f - ci * ci) / (eta * eta);
    if (sin_t2 >= 1.0f)
        return 1.0f;
    float ct = sqrtf(1.0f - sin_t2);
    /* Both denominators are > 0: ci > 0 and ct > 0 here. */
    float rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
    return fminf(1.0f, 0.5f * (rs * rs + rp * rp));
}

/* wi = v normalized, or the fallback when rounding left v too short to normalize. */
static void store_unit(const float v[3], const float fallback[3], float wi_out[3])
{
    float l = sqrtf(pm_dot3(v, v));
    for (int k = 0; k < 3; k++)
        wi_out[k] = l > 1e-12f ? v[k] / l : fallback[k];
}

int pm_specular_sample(const pm_material_t *m, const float ng[3], const float wo[3], float u, int radiance,
                       float wi_out[3], float weight_out[3])
{
    float cos_o = pm_dot3(ng, wo), n[3], r[3];
    /* The normal on wo's side; reflection is the same about either. */
    for (int k = 0; k < 3; k++)
        n[k] = cos_o < 0.0f ? -ng[k] : ng[k];
    cos_o = fminf(fabsf(cos_o), 1.0f);
    pm_reflect(n, wo, r);
    if (m->kind == PM_MAT_MIRROR) {
        int black = !(m->kr[0] > 0.0f || m->kr[1] > 0.0f || m->kr[2] > 0.0f);
        store_unit(r, n, wi_out);
        for (int k = 0; k < 3; k++)
            weight_out[k] = black ? 0.0f : m->kr[k], wi_out[k] = black ? 0.0f : wi_out[k];
        return black ? -1 : 0;
    }
    if (m->kind != PM_MAT_GLASS) {
        for (int k = 0; k < 3; k++)
            wi_out[k] = weight_out[k] = 0.0f;
        return -1;
    }
    float eta = fminf(fmaxf(pm_dot3(ng, wo) < 0.0f ? 1.0f / m->ior : m->ior, PM_ETA_MIN), PM_ETA_MAX);
    float f = pm_fresnel_dielectric(cos_o, eta);
    if (u < f) {
        store_unit(r, n, wi_out);
        for (int k = 0; k < 3; k++)
            weight_out[k] = 1.0f;
        return 0;
    }
    /* Snell: the tangential part of -wo shrinks by 1 / eta, the normal part is what is left
     * of the unit length; f < 1 here, so 1 - sin_t^2 > 0 (clamped against rounding). */
    float sin_t2 = (1.0f - cos_o * cos_o) / (eta * eta), ct = sqrtf(fmaxf(0.0f, 1.0f - sin_t2)), t[3], back[3];
    for (int k = 0; k < 3; k++)
        t[k] = -wo[k] / eta + (cos_o / eta - ct) * n[k], back[k] = -n[k];
    store_unit(t, back, wi_out);
    float scale = radiance ? 1.0f / (eta * eta) : 1.0f;
    for (int k = 0; k < 3; k++)
        weight_out[k] = m->tf[k] * scale;
    return 1;
}

pm_result_t pm_shade_geom_init(const pm_scene_t *s, pm_shade_geom_t *g)
{
    g->tri_n = malloc((s->ntris ? s->ntris : 1) * 3 * sizeof(float));
    if (!g->tri_n)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu triangle normals", s->ntris);
    /* In double: a sliver's cross product loses every digit in float. */
    for (size_t t = 0; t < s->ntris; t++) {
        const float *a = s->verts + 3 * s->tris[3 * t], *b = s->verts + 3 * s->tris[3 * t + 1],
                    *cc = s->verts + 3 * s->tris[3 * t + 2];
        double e1[3], e2[3], nn[3];
        for (int k = 0; k < 3; k++)
            e1[k] = (double)b[k] - a[k], e2[k] = (double)cc[k] - a[k];
        nn[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nn[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        for (int k = 0; k < 3; k++)
            g->tri_n[3 * t + k] = l > 0.0 ? (float)(nn[k] / l) : (k == 2 ? 1.0f : 0.0f);
    }
    return PM_OK;
}

void pm_shade_geom_free(pm_shade_geom_t *g)
{
    free(g->tri_n);
    g->tri_n = NULL;
}
