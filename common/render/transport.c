/* transport.c: the tracers' names for the BSDF (calls into physics/bsdf.h, which defines every
 * kind once), and the light samplers (point lights and spots, area lights uniform by area) that
 * every tracer shares (transport.h). */
#include "render/transport.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/sampling.h"

int pm_bsdf_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                   float wi_out[3])
{
    if (m->kind == PM_MAT_STANDARD) {
        pm_lobe_t lobe = u < pm_bsdf_standard_diffuse_share(m) ? PM_LOBE_DIFFUSE : PM_LOBE_GLOSSY;
        return pm_bsdf_standard_sample_lobe(m, (int)lobe, n, wo, u1, u2, wi_out);
    }
    pm_bsdf_sample_t s;
    int ok = pm_bsdf_sample_wi(m, n, wo, u, u1, u2, PM_BSDF_RADIANCE, &s);
    memcpy(wi_out, s.wi, sizeof s.wi);
    return ok;
}

int pm_specular_sample(const pm_material_t *m, const float ng[3], const float wo[3], float u, int radiance,
                       float wi_out[3], float weight_out[3])
{
    pm_bsdf_sample_t s;
    /* u1, u2 are unused by delta lobes. */
    if (!pm_bsdf_is_delta(m) ||
        !pm_bsdf_sample_wi(m, ng, wo, u, 0.0f, 0.0f, radiance ? PM_BSDF_RADIANCE : PM_BSDF_IMPORTANCE, &s)) {
        for (int k = 0; k < 3; k++)
            wi_out[k] = weight_out[k] = 0.0f;
        return -1;
    }
    memcpy(wi_out, s.wi, sizeof s.wi);
    memcpy(weight_out, s.weight, sizeof s.weight);
    return (s.lobe & PM_BSDF_TRANSMIT) ? 1 : 0;
}

pm_result_t pm_shade_geom_init(const pm_scene_t *s, pm_shade_geom_t *g)
{
    g->tri_n = malloc((s->ntris ? s->ntris : 1) * 3 * sizeof(float));
    g->cdf = malloc((s->nemissive ? s->nemissive : 1) * sizeof(double));
    g->nemissive = s->nemissive;
    if (!g->tri_n || !g->cdf) {
        pm_shade_geom_free(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu triangle normals", s->ntris);
    }
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
    double acc = 0.0;
    for (size_t e = 0; e < s->nemissive; e++)
        g->cdf[e] = acc += pm_scene_triangle_area(s, s->emissive[e]);
    for (size_t e = 0; e < s->nemissive; e++)
        g->cdf[e] /= acc;
    if (s->nemissive)
        g->cdf[s->nemissive - 1] = 1.0;
    g->area = acc;
    return PM_OK;
}

void pm_shade_geom_free(pm_shade_geom_t *g)
{
    free(g->tri_n);
    free(g->cdf);
    g->tri_n = NULL, g->cdf = NULL;
}

void pm_triangle_point(const pm_scene_t *s, uint32_t t, float b0, float b1, float p_out[3])
{
    const float *a = s->verts + 3 * s->tris[3 * t], *b = s->verts + 3 * s->tris[3 * t + 1],
                *c = s->verts + 3 * s->tris[3 * t + 2];
    float b2 = 1.0f - b0 - b1;
    for (int k = 0; k < 3; k++)
        p_out[k] = b0 * a[k] + b1 * b[k] + b2 * c[k];
}

void pm_point_light_emit(const pm_point_light_t *l, float u1, float u2, float dir_out[3])
{
    if (!pm_point_light_is_spot(l)) {
        pm_v3_store(dir_out, pm_sample_sphere(u1, u2));
        return;
    }
    /* Inverting the cdf of cos(theta), whose density is ((c - cc) / (1 - cc))^e on [cc, 1]. */
    float cc = l->cos_cone, c = cc + (1.0f - cc) * powf(u1, 1.0f / (l->falloff + 1.0f));
    c = fminf(1.0f, fmaxf(-1.0f, c));
    float sn = sqrtf(fmaxf(0.0f, 1.0f - c * c)), phi = 2.0f * PM_PI * u2;
    pm_vec3_t a = pm_v3_load(l->axis), t, b;
    pm_onb(a, &t, &b);
    pm_v3_store(dir_out, pm_v3_normalize(pm_onb_to_world(pm_v3(sn * cosf(phi), sn * sinf(phi), c), t, b, a)));
}

float pm_point_light_emit_pdf(const pm_point_light_t *l, const float w[3])
{
    if (!pm_point_light_is_spot(l))
        return 1.0f / (4.0f * PM_PI);
    return pm_spot_factor(l, w) * (l->falloff + 1.0f) / (2.0f * PM_PI * (1.0f - l->cos_cone));
}

void pm_sun_sample(const pm_sun_t *sun, float u1, float u2, float wi_out[3])
{
    float c = 1.0f - u1 * (1.0f - sun->cos_max), sn = sqrtf(fmaxf(0.0f, 1.0f - c * c)), phi = 2.0f * PM_PI * u2;
    pm_vec3_t a = pm_v3_load(sun->direction), t, b;
    pm_onb(a, &t, &b);
    pm_v3_store(wi_out, pm_v3_normalize(pm_onb_to_world(pm_v3(sn * cosf(phi), sn * sinf(phi), c), t, b, a)));
}

void pm_envmap_pixel(const pm_envmap_t *e, const float w[3], uint32_t *x_out, uint32_t *y_out)
{
    /* theta from the horizontal length, not acos(y): near the poles y rounds to 1 first. */
    double st = sqrt((double)w[0] * w[0] + (double)w[2] * w[2]);
    double th = atan2(st, (double)w[1]), ph = atan2((double)w[2], (double)w[0]);
    if (ph < 0.0)
        ph += 2.0 * M_PI;
    double fx = ph / (2.0 * M_PI) * e->w, fy = th / M_PI * e->h;
    *x_out = fx >= e->w ? e->w - 1 : (uint32_t)fx;
    *y_out = fy >= e->h ? e->h - 1 : (uint32_t)fy;
}

void pm_envmap_sample(const pm_envmap_t *e, float u1, float u2, float wi_out[3])
{
    /* A row, a column in it, and the position within the pixel from what is left of u1, u2. */
    size_t y = pm_cdf_pick(e->row_cdf, e->h, u1);
    const double *cc = e->col_cdf + y * e->w;
    size_t x = pm_cdf_pick(cc, e->w, u2);
    double r0 = y ? e->row_cdf[y - 1] : 0.0, c0 = x ? cc[x - 1] : 0.0;
    double fy = e->row_cdf[y] > r0 ? (u1 - r0) / (e->row_cdf[y] - r0) : 0.5;
    double fx = cc[x] > c0 ? (u2 - c0) / (cc[x] - c0) : 0.5;
    fy = fmin(fmax(fy, 0.0), 1.0), fx = fmin(fmax(fx, 0.0), 1.0);
    double th = M_PI * (y + fy) / e->h, ph = 2.0 * M_PI * (x + fx) / e->w;
    wi_out[0] = (float)(sin(th) * cos(ph)), wi_out[1] = (float)cos(th), wi_out[2] = (float)(sin(th) * sin(ph));
}

float pm_envmap_pdf(const pm_envmap_t *e, const float w[3])
{
    if (!(e->total > 0.0))
        return 0.0f;
    uint32_t x, y;
    pm_envmap_pixel(e, w, &x, &y);
    double st = sqrt((double)w[0] * w[0] + (double)w[2] * w[2]) / sqrt(pm_dot3(w, w));
    if (!(st > 0.0))
        return 0.0f;
    return (float)(e->pix_p[(size_t)y * e->w + x] * e->w * e->h / (2.0 * M_PI * M_PI * st));
}

void pm_sky_radiance(const pm_scene_t *s, const float w[3], float L_out[3])
{
    if (s->envmap) {
        uint32_t x, y;
        pm_envmap_pixel(s->envmap, w, &x, &y);
        for (int k = 0; k < 3; k++)
            L_out[k] = s->envmap->rgb[3 * ((size_t)y * s->envmap->w + x) + k];
        return;
    }
    for (int k = 0; k < 3; k++)
        L_out[k] = s->has_sky ? s->sky[k] : 0.0f;
}

void pm_env_radiance(const pm_scene_t *s, const float w[3], float L_out[3])
{
    pm_sky_radiance(s, w, L_out);
    if (s->has_sun && pm_dot3(s->sun.direction, w) >= s->sun.cos_max)
        for (int k = 0; k < 3; k++)
            L_out[k] += s->sun.radiance[k];
}

void pm_sky_sample(const pm_scene_t *s, const float n[3], float u1, float u2, float wi_out[3])
{
    if (s->envmap) {
        pm_envmap_sample(s->envmap, u1, u2, wi_out);
        return;
    }
    pm_vec3_t nn = pm_v3_load(n), t, b;
    pm_onb(nn, &t, &b);
    pm_v3_store(wi_out, pm_onb_to_world(pm_sample_cosine_hemisphere(u1, u2), t, b, nn));
}

float pm_sky_pdf(const pm_scene_t *s, const float n[3], const float w[3])
{
    if (s->envmap)
        return pm_envmap_pdf(s->envmap, w);
    float c = pm_dot3(n, w);
    return c > 0.0f ? c * (1.0f / PM_PI) : 0.0f;
}

void pm_env_emit(const pm_scene_t *s, int sun, float u1, float u2, float u3, float u4, float org_out[3],
                 float dir_out[3], double flux_out[3])
{
    float w[3], x, y;
    double c[3], r;
    pm_scene_sphere(s, c, &r);
    double disc = M_PI * r * r;
    if (sun) {
        pm_sun_sample(&s->sun, u1, u2, w);
        for (int k = 0; k < 3; k++)
            flux_out[k] = s->sun.radiance[k] * (double)s->sun.solid_angle * disc;
    } else if (s->envmap) {
        pm_envmap_sample(s->envmap, u1, u2, w);
        float L[3], p = pm_envmap_pdf(s->envmap, w);
        pm_sky_radiance(s, w, L);
        for (int k = 0; k < 3; k++)
            flux_out[k] = p > 0.0f ? L[k] / (double)p * disc : 0.0;
    } else {
        pm_v3_store(w, pm_sample_sphere(u1, u2));
        for (int k = 0; k < 3; k++)
            flux_out[k] = s->sky[k] * 4.0 * M_PI * disc;
    }
    pm_vec3_t wv = pm_v3_load(w), t, b;
    pm_onb(wv, &t, &b);
    pm_sample_disc(u3, u4, &x, &y);
    float tt[3], bb[3];
    pm_v3_store(tt, t), pm_v3_store(bb, b);
    for (int k = 0; k < 3; k++) {
        org_out[k] = (float)(c[k] + r * ((double)w[k] + x * (double)tt[k] + y * (double)bb[k]));
        dir_out[k] = -w[k];
    }
}

int pm_point_light_toward(const pm_point_light_t *l, const float p[3], const float n[3], pm_light_sample_t *o)
{
    float v[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
    o->r2 = pm_dot3(v, v), o->r = sqrtf(o->r2);
    if (!(o->r > 0.0f))
        return 0;
    for (int k = 0; k < 3; k++)
        o->wi[k] = v[k] / o->r;
    o->cosx = pm_dot3(n, o->wi), o->cosy = 1.0f, o->tri = UINT32_MAX;
    return o->cosx > 0.0f;
}

int pm_area_light_sample(const pm_scene_t *s, const pm_shade_geom_t *g, pm_rng_t *rng, const float p[3],
                         const float n[3], pm_light_sample_t *o)
{
    o->tri = s->emissive[pm_cdf_pick(g->cdf, g->nemissive, pm_rng_double(rng))];
    /* u2 is drawn before u1: the order gcc gave trace-gather-points' unsequenced arguments before
     * this was shared, kept so that its outputs (and golden files) stay what they were. */
    float u2 = pm_rng_float(rng), u1 = pm_rng_float(rng), b0, b1, y[3];
    pm_sample_triangle(u1, u2, &b0, &b1);
    pm_triangle_point(s, o->tri, b0, b1, y);
    float v[3] = {y[0] - p[0], y[1] - p[1], y[2] - p[2]};
    o->r2 = pm_dot3(v, v), o->r = sqrtf(o->r2);
    if (!(o->r > 0.0f))
        return 0;
    for (int k = 0; k < 3; k++)
        o->wi[k] = v[k] / o->r;
    o->cosx = pm_dot3(n, o->wi), o->cosy = -pm_dot3(g->tri_n + 3 * (size_t)o->tri, o->wi);
    if (s->two_sided_lights) /* either face lights */
        o->cosy = fabsf(o->cosy);
    return o->cosx > 0.0f && o->cosy > 0.0f;
}
