/* bsdf.c: every material kind's scattering (bsdf.h): one dispatch on the kind for the lobes a
 * kind has, f, its pdf and its sampler. Below the tracers (render/) and the gathers
 * (photonmap/): nothing here knows of rays, scenes or photon maps.
 *
 * The standard kind keeps the arithmetic, and the order of operations, the tracers had before
 * this module (the Phong pdf weighted before it is multiplied out, the mirror direction left
 * unnormalized in the pdf and normalized in the sampler), so that their outputs stay
 * bit-identical; the mirror and the smooth glass keep pm_specular_sample's. */
#include "physics/bsdf.h"

#include <math.h>
#include <string.h>

#include "math/sampling.h"
#include "math/vec.h"

/* ---- small helpers ---- */

static inline float max3(const float c[3]) { return fmaxf(c[0], fmaxf(c[1], c[2])); }
static inline int any3(const float c[3]) { return c[0] > 0.0f || c[1] > 0.0f || c[2] > 0.0f; }

static inline void reflect3(const float n[3], const float w[3], float r_out[3])
{
    float c = 2.0f * pm_dot3(n, w);
    for (int k = 0; k < 3; k++)
        r_out[k] = c * n[k] - w[k];
}

/* A microfacet kind in its smooth limit (alpha below PM_MAT_ALPHA_DELTA, or NaN). */
static inline int smooth(const pm_material_t *m) { return !(m->alpha >= PM_MAT_ALPHA_DELTA); }
static inline float width(const pm_material_t *m) { return fminf(m->alpha, 1.0f); }

/* The index ratio across a dielectric, clamped as pm_fresnel_dielectric clamps it. */
static inline float clamp_eta(float e) { return fminf(fmaxf(e, PM_ETA_MIN), PM_ETA_MAX); }

/* A rough dielectric of index 1 maps every microfacet normal onto the one direction -wo (the
 * generalized half vector is undefined): its index is kept this far from 1, which makes the
 * transmission a lobe about 1e-3 rad wide instead of a delta, with finite f and pdf. */
#define ROUGH_ETA_GAP 1e-3f
static inline float rough_ior(float ior)
{
    ior = clamp_eta(ior);
    if (fabsf(ior - 1.0f) < ROUGH_ETA_GAP)
        ior = ior < 1.0f ? 1.0f - ROUGH_ETA_GAP : 1.0f + ROUGH_ETA_GAP;
    return ior;
}

static inline void zero_sample(pm_bsdf_sample_t *s) { memset(s, 0, sizeof *s); }

/* wi = v normalized, or the fallback when rounding left v too short to normalize. */
static void store_unit(const float v[3], const float fallback[3], float wi_out[3])
{
    float l = sqrtf(pm_dot3(v, v));
    for (int k = 0; k < 3; k++)
        wi_out[k] = l > 1e-12f ? v[k] / l : fallback[k];
}

/* An orthonormal frame about unit z: local (x, y, z) <-> world. */
typedef struct {
    pm_vec3_t t, b, n;
} frame_t;

static inline frame_t frame_of(const float n[3])
{
    frame_t f;
    f.n = pm_v3_load(n);
    pm_onb(f.n, &f.t, &f.b);
    return f;
}
static inline void to_local(const frame_t *f, const float w[3], float l_out[3])
{
    pm_vec3_t v = pm_v3_load(w);
    l_out[0] = pm_v3_dot(v, f->t), l_out[1] = pm_v3_dot(v, f->b), l_out[2] = pm_v3_dot(v, f->n);
}
static inline void to_world(const frame_t *f, const float l[3], float w_out[3])
{
    pm_v3_store(w_out, pm_v3_normalize(pm_onb_to_world(pm_v3(l[0], l[1], l[2]), f->t, f->b, f->n)));
}

/* ---- lobes of each kind ---- */

unsigned pm_bsdf_lobes(const pm_material_t *m)
{
    switch (m->kind) {
    case PM_MAT_STANDARD:
        return (any3(m->kd) ? PM_BSDF_REFLECT | PM_BSDF_DIFFUSE : 0u) |
               (any3(m->ks) ? PM_BSDF_REFLECT | PM_BSDF_GLOSSY : 0u);
    case PM_MAT_MIRROR: return PM_BSDF_REFLECT | PM_BSDF_DELTA;
    case PM_MAT_GLASS: return PM_BSDF_REFLECT | PM_BSDF_TRANSMIT | PM_BSDF_DELTA;
    case PM_MAT_CONDUCTOR: return PM_BSDF_REFLECT | (smooth(m) ? PM_BSDF_DELTA : PM_BSDF_GLOSSY);
    case PM_MAT_ROUGH_GLASS: return PM_BSDF_REFLECT | PM_BSDF_TRANSMIT | (smooth(m) ? PM_BSDF_DELTA : PM_BSDF_GLOSSY);
    case PM_MAT_PLASTIC:
        return PM_BSDF_REFLECT | (smooth(m) ? PM_BSDF_DELTA : PM_BSDF_GLOSSY) | (any3(m->kd) ? PM_BSDF_DIFFUSE : 0u);
    default: return 0u;
    }
}

/* ---- the standard kind: Lambert plus normalized Phong ---- */

static void standard_eval(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3],
                          float f_out[3])
{
    float lobe = 0.0f;
    if (any3(m->ks)) {
        float r[3];
        reflect3(n, wi, r);
        float cr = pm_dot3(r, wo);
        if (cr > 0.0f)
            lobe = (m->ns + 2.0f) / (2.0f * PM_PI) * powf(cr, m->ns);
    }
    for (int k = 0; k < 3; k++)
        f_out[k] = m->kd[k] * (1.0f / PM_PI) + m->ks[k] * lobe;
}

int pm_bsdf_standard_sample_lobe(const pm_material_t *m, int lobe, const float n[3], const float wo[3], float u1,
                                 float u2, float wi_out[3])
{
    pm_vec3_t t, b, d;
    if (lobe == 0) {
        pm_vec3_t nn = pm_v3_load(n);
        pm_onb(nn, &t, &b);
        d = pm_onb_to_world(pm_sample_cosine_hemisphere(u1, u2), t, b, nn);
    } else {
        /* Inverting the cdf 1 - cos^(ns+1) of the angle to the mirror direction. */
        float rr[3];
        reflect3(n, wo, rr);
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
    reflect3(n, wo, r);
    float ca = pm_dot3(r, wi);
    return ca > 0.0f ? w * (m->ns + 1.0f) / (2.0f * PM_PI) * powf(ca, m->ns) : 0.0f;
}

float pm_bsdf_standard_lobe_pdf(const pm_material_t *m, int lobe, const float n[3], const float wi[3],
                                const float wo[3])
{
    return lobe == 0 ? diffuse_pdf_w(1.0f, pm_dot3(n, wi)) : glossy_pdf_w(m, 1.0f, n, wi, wo);
}

float pm_bsdf_standard_diffuse_share(const pm_material_t *m)
{
    float pd = max3(m->kd), ps = max3(m->ks);
    return pd + ps > 0.0f ? pd / (pd + ps) : 1.0f;
}

static float standard_pdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    float cosi = pm_dot3(n, wi);
    if (cosi <= 0.0f)
        return 0.0f;
    float sd = pm_bsdf_standard_diffuse_share(m), p = diffuse_pdf_w(sd, cosi);
    if (sd < 1.0f)
        p += glossy_pdf_w(m, 1.0f - sd, n, wi, wo);
    return p;
}

/* ---- delta lobes: mirror, smooth glass, smooth conductor ---- */

/* Mirror and smooth glass (rough glass in its smooth limit too), the arithmetic of the tracers'
 * pm_specular_sample; n the front normal, either side. */
static int specular_sample(const pm_material_t *m, const float ng[3], const float wo[3], float u, pm_bsdf_mode_t mode,
                           pm_bsdf_sample_t *s)
{
    float cos_o = pm_dot3(ng, wo), n[3], r[3];
    /* The normal on wo's side; reflection is the same about either. */
    for (int k = 0; k < 3; k++)
        n[k] = cos_o < 0.0f ? -ng[k] : ng[k];
    cos_o = fminf(fabsf(cos_o), 1.0f);
    reflect3(n, wo, r);
    if (m->kind == PM_MAT_MIRROR) {
        if (!any3(m->kr))
            return 0;
        store_unit(r, n, s->wi);
        for (int k = 0; k < 3; k++)
            s->weight[k] = m->kr[k];
        s->pdf = 1.0f, s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_DELTA;
        return 1;
    }
    float eta = clamp_eta(pm_dot3(ng, wo) < 0.0f ? 1.0f / m->ior : m->ior);
    float f = pm_fresnel_dielectric(cos_o, eta);
    if (u < f) {
        store_unit(r, n, s->wi);
        for (int k = 0; k < 3; k++)
            s->weight[k] = 1.0f;
        s->pdf = f, s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_DELTA;
        return 1;
    }
    /* Snell: the tangential part of -wo shrinks by 1 / eta, the normal part is what is left
     * of the unit length; f < 1 here, so 1 - sin_t^2 > 0 (clamped against rounding). */
    float sin_t2 = (1.0f - cos_o * cos_o) / (eta * eta), ct = sqrtf(fmaxf(0.0f, 1.0f - sin_t2)), t[3], back[3];
    for (int k = 0; k < 3; k++)
        t[k] = -wo[k] / eta + (cos_o / eta - ct) * n[k], back[k] = -n[k];
    store_unit(t, back, s->wi);
    float scale = mode == PM_BSDF_RADIANCE ? 1.0f / (eta * eta) : 1.0f;
    for (int k = 0; k < 3; k++)
        s->weight[k] = m->tf[k] * scale;
    s->pdf = 1.0f - f, s->eta = eta, s->lobe = PM_BSDF_TRANSMIT | PM_BSDF_DELTA;
    return 1;
}

/* ---- the GGX kinds ---- */

/* The plastic's probability of sampling its coat, from wo alone: the coat's Fresnel at n.wo
 * against the base's share of what is left, (1 - F) max(kd). */
static float plastic_coat_share(const pm_material_t *m, float cos_o)
{
    float f = pm_fresnel_dielectric(cos_o, m->ior), wd = (1.0f - f) * max3(m->kd);
    return f + wd > 0.0f ? f / (f + wd) : 1.0f;
}

/* The plastic's base, per channel: kd (1 - F(n.wi)) (1 - F(n.wo)) / (pi ior^2 (1 - kd Fdr_in)). */
static void plastic_base(const pm_material_t *m, float ci, float co, float f_out[3])
{
    /* Fdr_in is a 64-point quadrature; a path meets one plastic many times running (light
     * samples, the BSDF sample, the next bounce), so each thread keeps the last index's value. */
    static _Thread_local float last_ior = -1.0f, last_fdr = 0.0f;
    float ior = clamp_eta(m->ior);
    if (ior != last_ior)
        last_fdr = pm_fresnel_diffuse_inside(ior), last_ior = ior;
    float fdr = last_fdr;
    float t = (1.0f - pm_fresnel_dielectric(ci, ior)) * (1.0f - pm_fresnel_dielectric(co, ior));
    for (int k = 0; k < 3; k++)
        f_out[k] = m->kd[k] * t / (PM_PI * ior * ior * (1.0f - m->kd[k] * fdr));
}

/* GGX reflection's F-free part D G2 / (4 ci co) at the half vector of wi and wo (both above n,
 * ci, co > 0), and the half vector's cosines; 0 when h is degenerate. */
static float ggx_reflect_core(float alpha, const float n[3], const float wi[3], const float wo[3], float ci, float co,
                              float *wh_out)
{
    float h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, l = sqrtf(pm_dot3(h, h));
    if (!(l > 1e-12f))
        return 0.0f;
    float ch = pm_dot3(n, h) / l, wh = pm_dot3(wo, h) / l;
    *wh_out = wh;
    if (!(wh > 0.0f))
        return 0.0f;
    return pm_ggx_d(alpha, ch) * pm_ggx_g2(alpha, ci, co) / (4.0f * ci * co);
}

/* The pdf of reflecting wo into wi through a visible normal: D_wo(h) / (4 wo.h). */
static float ggx_reflect_pdf(float alpha, const float n[3], const float wi[3], const float wo[3], float co)
{
    float h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, l = sqrtf(pm_dot3(h, h));
    if (!(l > 1e-12f))
        return 0.0f;
    float ch = pm_dot3(n, h) / l, wh = pm_dot3(wo, h) / l;
    if (!(wh > 0.0f))
        return 0.0f;
    return pm_ggx_visible_pdf(alpha, co, ch, wh) / (4.0f * wh);
}

/* The rough dielectric's geometry at (wi, wo) about the front normal n: the cosines, the indices
 * on each side, the microfacet normal h oriented to wo's side and its cosines. Returns 1 for a
 * reflection, 2 for a transmission, 0 when the pair has no valid microfacet (grazing, or h
 * facing away from either direction). */
typedef struct {
    float ci, co;   /* n.wi, n.wo, signed */
    float e;        /* n_wi / n_wo */
    float h[3];     /* on wo's side */
    float wih, woh; /* wi.h, wo.h (woh > 0) */
    float cos_h;    /* |n.h| */
} dielectric_pair_t;

static int dielectric_pair(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3],
                           dielectric_pair_t *p)
{
    p->ci = pm_dot3(n, wi), p->co = pm_dot3(n, wo);
    if (p->ci == 0.0f || p->co == 0.0f)
        return 0;
    float ior = rough_ior(m->ior), n_o = p->co > 0.0f ? 1.0f : ior, n_i = p->ci > 0.0f ? 1.0f : ior;
    int transmit = (p->ci > 0.0f) != (p->co > 0.0f);
    p->e = transmit ? n_i / n_o : 1.0f;
    float h[3];
    for (int k = 0; k < 3; k++)
        h[k] = transmit ? -(wo[k] + p->e * wi[k]) : wi[k] + wo[k];
    float l = sqrtf(pm_dot3(h, h));
    if (!(l > 1e-12f))
        return 0;
    float side = (pm_dot3(h, wo) < 0.0f) ? -1.0f : 1.0f; /* h toward wo */
    for (int k = 0; k < 3; k++)
        p->h[k] = side * h[k] / l;
    p->woh = pm_dot3(wo, p->h), p->wih = pm_dot3(wi, p->h);
    float chs = pm_dot3(n, p->h) * (p->co > 0.0f ? 1.0f : -1.0f); /* h's cosine on wo's side */
    p->cos_h = chs;
    /* Each direction on the same side of the microfacet as of the macro surface. */
    if (!(chs > 0.0f) || !(p->woh > 0.0f))
        return 0;
    if (transmit ? !(p->wih < 0.0f) : !(p->wih > 0.0f))
        return 0;
    return transmit ? 2 : 1;
}

/* The microfacet Fresnel of a pair. A transmission's is taken from the outside (index 1), where
 * no total internal reflection makes it ill-conditioned: from inside near the critical angle
 * 1 - sin_t^2 cancels in float, and f(wi, wo) and f(wo, wi) would no longer keep the reciprocity
 * rule to float precision. Both sides give the same F in exact arithmetic. */
static inline float pair_fresnel(const dielectric_pair_t *p, float ior)
{
    if (p->e == 1.0f) /* a reflection: the angle to h is the same for both */
        return pm_fresnel_dielectric(p->woh, p->co > 0.0f ? ior : 1.0f / ior);
    return p->co > 0.0f ? pm_fresnel_dielectric(p->woh, ior) : pm_fresnel_dielectric(fabsf(p->wih), ior);
}

/* The rough dielectric's reflection probability for microfacet Fresnel f: f against the
 * transmission's (1 - f) max(tf), so that a black filter wastes no sample on it. */
static inline float rough_glass_reflect_share(const pm_material_t *m, float f)
{
    float t = (1.0f - f) * max3(m->tf);
    return f + t > 0.0f ? f / (f + t) : 1.0f;
}

static void rough_glass_eval(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3],
                             pm_bsdf_mode_t mode, float f_out[3])
{
    dielectric_pair_t p;
    int how = dielectric_pair(m, n, wi, wo, &p);
    for (int k = 0; k < 3; k++)
        f_out[k] = 0.0f;
    if (!how)
        return;
    float alpha = width(m), ior = rough_ior(m->ior), ci = fabsf(p.ci), co = fabsf(p.co);
    float f = pair_fresnel(&p, ior), d = pm_ggx_d(alpha, p.cos_h), g = pm_ggx_g2(alpha, ci, co);
    if (how == 1) {
        float v = f * d * g / (4.0f * ci * co);
        for (int k = 0; k < 3; k++)
            f_out[k] = v;
        return;
    }
    float den = p.woh + p.e * p.wih; /* of either sign; its square is the Jacobian's */
    if (!(den * den > 0.0f))
        return;
    float v = (1.0f - f) * d * g * fabsf(p.wih) * p.woh / (ci * co * den * den);
    if (mode == PM_BSDF_IMPORTANCE)
        v *= p.e * p.e;
    for (int k = 0; k < 3; k++)
        f_out[k] = v * m->tf[k];
}

static float rough_glass_pdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    dielectric_pair_t p;
    int how = dielectric_pair(m, n, wi, wo, &p);
    if (!how)
        return 0.0f;
    float alpha = width(m), ior = rough_ior(m->ior), co = fabsf(p.co);
    float f = pair_fresnel(&p, ior), pr = rough_glass_reflect_share(m, f);
    float dv = pm_ggx_visible_pdf(alpha, co, p.cos_h, p.woh);
    if (how == 1)
        return pr * dv / (4.0f * p.woh);
    float den = p.woh + p.e * p.wih;
    if (!(den * den > 0.0f))
        return 0.0f;
    return (1.0f - pr) * dv * p.e * p.e * fabsf(p.wih) / (den * den);
}

/* ---- eval, pdf, sample ---- */

/* n flipped to wo's side, and the two cosines about it; reflective kinds only. Returns 0 when
 * wi and wo are not strictly on one side. */
static int reflect_side(const float n[3], const float wi[3], const float wo[3], float nn[3], float *ci, float *co)
{
    float s = pm_dot3(n, wo) < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; k++)
        nn[k] = s * n[k];
    *ci = pm_dot3(nn, wi), *co = pm_dot3(nn, wo);
    return *ci > 0.0f && *co > 0.0f;
}

void pm_bsdf_eval(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3], pm_bsdf_mode_t mode,
                  float f_out[3])
{
    float nn[3], ci, co;
    for (int k = 0; k < 3; k++)
        f_out[k] = 0.0f;
    switch (m->kind) {
    case PM_MAT_STANDARD:
        if (pm_dot3(n, wi) > 0.0f)
            standard_eval(m, n, wi, wo, f_out);
        return;
    case PM_MAT_CONDUCTOR: {
        if (smooth(m) || !reflect_side(n, wi, wo, nn, &ci, &co))
            return;
        float wh, core = ggx_reflect_core(width(m), nn, wi, wo, ci, co, &wh), fr[3];
        if (!(core > 0.0f))
            return;
        pm_fresnel_conductor_rgb(m->eta, m->k, m->f0, wh, fr);
        for (int k = 0; k < 3; k++)
            f_out[k] = fr[k] * core;
        return;
    }
    case PM_MAT_ROUGH_GLASS:
        if (!smooth(m))
            rough_glass_eval(m, n, wi, wo, mode, f_out);
        return;
    case PM_MAT_PLASTIC: {
        if (!reflect_side(n, wi, wo, nn, &ci, &co))
            return;
        plastic_base(m, ci, co, f_out);
        if (smooth(m))
            return;
        float wh, core = ggx_reflect_core(width(m), nn, wi, wo, ci, co, &wh);
        if (core > 0.0f) {
            float spec = pm_fresnel_dielectric(wh, clamp_eta(m->ior)) * core;
            for (int k = 0; k < 3; k++)
                f_out[k] += spec;
        }
        return;
    }
    default: /* mirror, glass: delta lobes only */ return;
    }
}

float pm_bsdf_pdf_wi(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    float nn[3], ci, co;
    switch (m->kind) {
    case PM_MAT_STANDARD: return standard_pdf(m, n, wi, wo);
    case PM_MAT_CONDUCTOR:
        if (smooth(m) || !reflect_side(n, wi, wo, nn, &ci, &co))
            return 0.0f;
        return ggx_reflect_pdf(width(m), nn, wi, wo, co);
    case PM_MAT_ROUGH_GLASS: return smooth(m) ? 0.0f : rough_glass_pdf(m, n, wi, wo);
    case PM_MAT_PLASTIC: {
        if (!reflect_side(n, wi, wo, nn, &ci, &co))
            return 0.0f;
        float ps = plastic_coat_share(m, co), p = (1.0f - ps) * ci * (1.0f / PM_PI);
        if (!smooth(m))
            p += ps * ggx_reflect_pdf(width(m), nn, wi, wo, co);
        return p;
    }
    default: return 0.0f;
    }
}

/* A non-delta sample's pdf and weight f |n.wi| / pdf from eval and pdf_wi (mixtures, whose
 * weight is the whole f over the whole pdf). Returns 0 when the pdf is not positive. */
static int finish_mixture(const pm_material_t *m, const float n[3], const float wo[3], pm_bsdf_mode_t mode,
                          pm_bsdf_sample_t *s)
{
    float pdf = pm_bsdf_pdf_wi(m, n, s->wi, wo), f[3];
    if (!(pdf > 0.0f))
        return 0;
    pm_bsdf_eval(m, n, s->wi, wo, mode, f);
    float c = fabsf(pm_dot3(n, s->wi));
    for (int k = 0; k < 3; k++)
        s->weight[k] = f[k] * c / pdf;
    s->pdf = pdf;
    return 1;
}

static int conductor_sample(const pm_material_t *m, const float n[3], const float wo[3], float u1, float u2,
                            pm_bsdf_sample_t *s)
{
    float nn[3], s_ = pm_dot3(n, wo) < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; k++)
        nn[k] = s_ * n[k];
    float co = pm_dot3(nn, wo);
    if (!(co > 0.0f))
        return 0;
    if (smooth(m)) {
        float r[3];
        reflect3(nn, wo, r);
        store_unit(r, nn, s->wi);
        pm_fresnel_conductor_rgb(m->eta, m->k, m->f0, co, s->weight);
        s->pdf = 1.0f, s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_DELTA;
        return 1;
    }
    float alpha = width(m), lo[3], hl[3], h[3];
    frame_t fr = frame_of(nn);
    to_local(&fr, wo, lo);
    lo[2] = fmaxf(lo[2], 1e-7f);
    pm_ggx_sample_visible(alpha, lo, u1, u2, hl);
    to_world(&fr, hl, h);
    float woh = pm_dot3(wo, h), r[3];
    if (!(woh > 0.0f))
        return 0;
    reflect3(h, wo, r);
    store_unit(r, nn, s->wi);
    float ci = pm_dot3(nn, s->wi);
    if (!(ci > 0.0f))
        return 0; /* below the surface: single scattering's energy loss */
    float fr3[3], g = pm_ggx_g2(alpha, ci, co) / pm_ggx_g1(alpha, co);
    pm_fresnel_conductor_rgb(m->eta, m->k, m->f0, woh, fr3);
    for (int k = 0; k < 3; k++)
        s->weight[k] = fr3[k] * g;
    s->pdf = ggx_reflect_pdf(alpha, nn, s->wi, wo, co);
    s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_GLOSSY;
    return s->pdf > 0.0f;
}

static int rough_glass_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                              pm_bsdf_mode_t mode, pm_bsdf_sample_t *s)
{
    float co = pm_dot3(n, wo);
    if (co == 0.0f)
        return 0;
    float side = co < 0.0f ? -1.0f : 1.0f, nn[3], ior = rough_ior(m->ior);
    for (int k = 0; k < 3; k++)
        nn[k] = side * n[k];
    float e = co > 0.0f ? ior : 1.0f / ior; /* beyond wo's side over wo's side */
    float alpha = width(m), lo[3], hl[3], h[3];
    frame_t fr = frame_of(nn);
    to_local(&fr, wo, lo);
    lo[2] = fmaxf(lo[2], 1e-7f);
    pm_ggx_sample_visible(alpha, lo, u1, u2, hl);
    to_world(&fr, hl, h);
    float woh = pm_dot3(wo, h);
    if (!(woh > 0.0f))
        return 0;
    float f = pm_fresnel_dielectric(woh, e), pr = rough_glass_reflect_share(m, f);
    if (u < pr) {
        float r[3];
        reflect3(h, wo, r);
        store_unit(r, nn, s->wi);
        s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_GLOSSY;
    } else {
        /* Snell through the microfacet: f < 1 here (pr < 1), so no total internal reflection. */
        float sin_t2 = (1.0f - woh * woh) / (e * e), ct = sqrtf(fmaxf(0.0f, 1.0f - sin_t2)), t[3], back[3];
        for (int k = 0; k < 3; k++)
            t[k] = -wo[k] / e + (woh / e - ct) * h[k], back[k] = -nn[k];
        store_unit(t, back, s->wi);
        s->eta = e, s->lobe = PM_BSDF_TRANSMIT | PM_BSDF_GLOSSY;
    }
    float ci = pm_dot3(nn, s->wi);
    if ((s->lobe & PM_BSDF_REFLECT) ? !(ci > 0.0f) : !(ci < 0.0f))
        return 0; /* left on the wrong side: single scattering's energy loss */
    /* The closed form F G2 / G1 / pr (reflection) or (1 - F) tf G2 / G1 / (1 - pr) / e^2
     * (transmission, radiance) is what f |n.wi| / pdf reduces to; computing it from f and the pdf
     * keeps sample, eval and pdf one definition (the unit tests check both). */
    return finish_mixture(m, n, wo, mode, s);
}

static int plastic_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                          pm_bsdf_mode_t mode, pm_bsdf_sample_t *s)
{
    float nn[3], sd = pm_dot3(n, wo) < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; k++)
        nn[k] = sd * n[k];
    float co = pm_dot3(nn, wo);
    if (!(co > 0.0f))
        return 0;
    float ps = plastic_coat_share(m, co);
    if (u < ps) {
        if (smooth(m)) {
            float r[3];
            reflect3(nn, wo, r);
            store_unit(r, nn, s->wi);
            float f = pm_fresnel_dielectric(co, clamp_eta(m->ior));
            for (int k = 0; k < 3; k++)
                s->weight[k] = f / ps;
            s->pdf = ps, s->eta = 1.0f, s->lobe = PM_BSDF_REFLECT | PM_BSDF_DELTA;
            return 1;
        }
        float lo[3], hl[3], h[3], r[3];
        frame_t fr = frame_of(nn);
        to_local(&fr, wo, lo);
        pm_ggx_sample_visible(width(m), lo, u1, u2, hl);
        to_world(&fr, hl, h);
        if (!(pm_dot3(wo, h) > 0.0f))
            return 0;
        reflect3(h, wo, r);
        store_unit(r, nn, s->wi);
        s->lobe = PM_BSDF_REFLECT | PM_BSDF_GLOSSY;
    } else {
        frame_t fr = frame_of(nn);
        pm_v3_store(s->wi, pm_onb_to_world(pm_sample_cosine_hemisphere(u1, u2), fr.t, fr.b, fr.n));
        s->lobe = PM_BSDF_REFLECT | PM_BSDF_DIFFUSE;
    }
    if (!(pm_dot3(nn, s->wi) > 0.0f))
        return 0;
    s->eta = 1.0f;
    return finish_mixture(m, n, wo, mode, s);
}

int pm_bsdf_sample_wi(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                      pm_bsdf_mode_t mode, pm_bsdf_sample_t *out)
{
    int ok = 0;
    zero_sample(out);
    switch (m->kind) {
    case PM_MAT_STANDARD: {
        if (!any3(m->kd) && !any3(m->ks))
            break;
        int lobe = u < pm_bsdf_standard_diffuse_share(m) ? 0 : 1;
        if (!pm_bsdf_standard_sample_lobe(m, lobe, n, wo, u1, u2, out->wi))
            break; /* the Phong lobe's share below the surface: its energy loss */
        out->eta = 1.0f, out->lobe = PM_BSDF_REFLECT | (lobe == 0 ? PM_BSDF_DIFFUSE : PM_BSDF_GLOSSY);
        ok = finish_mixture(m, n, wo, mode, out);
        break;
    }
    case PM_MAT_MIRROR:
    case PM_MAT_GLASS: ok = specular_sample(m, n, wo, u, mode, out); break;
    case PM_MAT_CONDUCTOR: ok = conductor_sample(m, n, wo, u1, u2, out); break;
    case PM_MAT_ROUGH_GLASS:
        ok = smooth(m) ? specular_sample(m, n, wo, u, mode, out) : rough_glass_sample(m, n, wo, u, u1, u2, mode, out);
        break;
    case PM_MAT_PLASTIC: ok = plastic_sample(m, n, wo, u, u1, u2, mode, out); break;
    default: break;
    }
    /* Nothing non-finite leaves: a weight that rounding made Inf or NaN ends the path instead. */
    if (ok && !(isfinite(out->weight[0]) && isfinite(out->weight[1]) && isfinite(out->weight[2]) && isfinite(out->pdf)))
        ok = 0;
    if (!ok)
        zero_sample(out);
    return ok;
}

void pm_bsdf_albedo_wo(const pm_material_t *m, const float n[3], const float wo[3], float a_out[3])
{
    float co = fabsf(pm_dot3(n, wo)), f;
    switch (m->kind) {
    case PM_MAT_STANDARD:
        for (int k = 0; k < 3; k++)
            a_out[k] = fminf(1.0f, m->kd[k] + m->ks[k]);
        return;
    case PM_MAT_MIRROR: memcpy(a_out, m->kr, 3 * sizeof(float)); return;
    case PM_MAT_GLASS:
    case PM_MAT_ROUGH_GLASS:
        f = pm_fresnel_dielectric(co, pm_dot3(n, wo) < 0.0f ? 1.0f / clamp_eta(m->ior) : clamp_eta(m->ior));
        for (int k = 0; k < 3; k++)
            a_out[k] = f + (1.0f - f) * m->tf[k];
        return;
    case PM_MAT_CONDUCTOR: pm_fresnel_conductor_rgb(m->eta, m->k, m->f0, co, a_out); return;
    case PM_MAT_PLASTIC:
        f = pm_fresnel_dielectric(co, clamp_eta(m->ior));
        for (int k = 0; k < 3; k++)
            a_out[k] = f + (1.0f - f) * m->kd[k];
        return;
    default: a_out[0] = a_out[1] = a_out[2] = 0.0f;
    }
}
