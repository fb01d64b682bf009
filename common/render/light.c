/* light.c: the lights of the scene model (light.h): the light set built from a loaded scene,
 * photon emission, direct-light sampling and its pdfs, emitted radiance for rays that hit an
 * emitter or escape. The one place that switches on a light's kind: every tracer loops over a
 * pm_lights_t and calls these functions.
 *
 * The arithmetic keeps the order of operations photon emission had when it was written inline
 * in render/photontrace.c, so that trace-photons' output is bit-identical across the move. */
#include "render/light.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/sampling.h"
#include "math/vec.h"

static const char *const kind_names[PM_LIGHT_KINDS] = {"point", "spot", "area", "sun", "sky"};

const char *pm_light_kind_name(pm_light_kind_t kind)
{
    return (unsigned)kind < PM_LIGHT_KINDS ? kind_names[kind] : "unknown";
}

double pm_light_power(const pm_scene_t *s, pm_light_kind_t kind, uint32_t index, int k)
{
    switch (kind) {
    case PM_LIGHT_POINT:
    case PM_LIGHT_SPOT: return pm_point_light_power(&s->lights[index], k);
    case PM_LIGHT_AREA:
        /* pi Ke A from one face: the integral of Ke cos over the hemisphere, times the area. */
        return (pm_scene_emits_both(s, index) ? 2.0 : 1.0) * M_PI * s->materials[s->tri_material[index]].ke[k] *
               pm_scene_triangle_area(s, index);
    case PM_LIGHT_SUN: return pm_sun_power(s, k);
    case PM_LIGHT_SKY: return pm_sky_power(s, k);
    default: return 0.0;
    }
}

/* A light of kind and index with its power, its flags set by kind. */
static pm_light_t make_light(const pm_scene_t *s, pm_light_kind_t kind, uint32_t index)
{
    pm_light_t l = {.kind = kind, .index = index};
    for (int c = 0; c < 3; c++)
        l.power[c] = pm_light_power(s, kind, index, c);
    l.weight = l.power[0] + l.power[1] + l.power[2];
    l.delta = kind == PM_LIGHT_POINT || kind == PM_LIGHT_SPOT;
    l.infinite = kind == PM_LIGHT_SUN || kind == PM_LIGHT_SKY;
    return l;
}

pm_result_t pm_lights_init(const pm_scene_t *s, pm_lights_t *L)
{
    memset(L, 0, sizeof *L);
    L->s = s;
    size_t n = s->nlights + s->nemissive + 2;
    L->light = calloc(n, sizeof *L->light);
    L->cdf = calloc(n, sizeof *L->cdf);
    L->direct = calloc(s->nlights + 3, sizeof *L->direct);
    L->area_cdf = calloc(s->nemissive ? s->nemissive : 1, sizeof *L->area_cdf);
    L->front = calloc(s->nemissive ? 3 * s->nemissive : 1, sizeof *L->front);
    if (!L->light || !L->cdf || !L->direct || !L->area_cdf || !L->front) {
        pm_lights_free(L);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the %zu lights of scene '%s'", n, s->name);
    }
    /* Every light the scene holds, in one order for emission and next-event estimation. */
    size_t nd = 0;
    for (size_t i = 0; i < s->nlights; i++) {
        pm_light_kind_t kind = pm_point_light_is_spot(&s->lights[i]) ? PM_LIGHT_SPOT : PM_LIGHT_POINT;
        L->light[L->n] = L->direct[nd++] = make_light(s, kind, (uint32_t)i);
        L->n += L->light[L->n].weight > 0.0;
    }
    L->ndelta = nd;
    for (size_t i = 0; i < s->nemissive; i++) {
        L->light[L->n] = make_light(s, PM_LIGHT_AREA, s->emissive[i]);
        L->n += L->light[L->n].weight > 0.0;
    }
    if (s->nemissive) {
        /* The area lights as one, by area; its power the triangles' together. */
        pm_light_t a = {.kind = PM_LIGHT_AREA, .index = 0};
        for (size_t i = 0; i < s->nemissive; i++)
            for (int c = 0; c < 3; c++)
                a.power[c] += pm_light_power(s, PM_LIGHT_AREA, s->emissive[i], c);
        a.weight = a.power[0] + a.power[1] + a.power[2];
        L->direct[nd++] = a;
    }
    /* The sun and the sky last: a scene without them keeps its table. */
    for (int e = 0; e < 2; e++) {
        if (!(e == 0 ? s->has_sun : s->has_sky))
            continue;
        L->light[L->n] = L->direct[nd++] = make_light(s, e == 0 ? PM_LIGHT_SUN : PM_LIGHT_SKY, 0);
        L->n += L->light[L->n].weight > 0.0;
    }
    L->ndirect = nd;
    pm_vec3_t st, sb;
    pm_onb(pm_v3_load(s->sun.direction), &st, &sb);
    pm_v3_store(L->sun_t, st), pm_v3_store(L->sun_b, sb);
    size_t sampled;
    pm_lights_count(s, &L->nlights, &sampled);
    L->total = 0.0;
    for (size_t i = 0; i < L->n; i++)
        L->total += L->light[i].weight;
    double acc = 0.0;
    for (size_t i = 0; i < L->n; i++) {
        acc += L->light[i].weight;
        L->cdf[i] = acc / L->total;
    }
    if (L->n)
        L->cdf[L->n - 1] = 1.0;

    /* Area lights: cumulative area, and front normals in double (a sliver's cross product loses
     * every digit in float). */
    acc = 0.0;
    for (size_t e = 0; e < s->nemissive; e++) {
        uint32_t t = s->emissive[e];
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
            L->front[3 * e + k] = l > 0.0 ? (float)(nn[k] / l) : (k == 2 ? 1.0f : 0.0f);
        L->area_cdf[e] = acc += pm_scene_triangle_area(s, t);
    }
    for (size_t e = 0; e < s->nemissive; e++)
        L->area_cdf[e] /= acc;
    if (s->nemissive)
        L->area_cdf[s->nemissive - 1] = 1.0;
    L->area = acc;
    return PM_OK;
}

void pm_lights_free(pm_lights_t *L)
{
    free(L->light);
    free(L->cdf);
    free(L->direct);
    free(L->area_cdf);
    free(L->front);
    memset(L, 0, sizeof *L);
}

void pm_lights_count(const pm_scene_t *s, size_t *total_out, size_t *sampled_out)
{
    /* Point lights and spots are the delta kinds: one sample each, whatever light_samples says. */
    *total_out = s->nlights + s->nemissive + (size_t)(s->has_sun != 0) + (size_t)(s->has_sky != 0);
    *sampled_out = *total_out - s->nlights;
}

size_t pm_lights_pick(const pm_lights_t *L, double u) { return pm_cdf_pick(L->cdf, L->n, u); }

size_t pm_lights_sampled(const pm_lights_t *L) { return L->nlights - L->ndelta; }

int pm_lights_has_emitters(const pm_lights_t *L) { return L->s->nemissive > 0; }

int pm_light_at_gather(const pm_lights_t *L, const pm_light_t *l, float r2)
{
    if (l->kind == PM_LIGHT_SKY)
        return L->s->envmap != NULL; /* a constant sky: the map's */
    return l->kind != PM_LIGHT_AREA || r2 >= (float)L->area;
}

int pm_light_gather_rule(const pm_scene_t *s) { return s->has_sky && !s->envmap ? 2 : 1; }

size_t pm_lights_count_at_gather(const pm_scene_t *s)
{
    size_t total, sampled;
    pm_lights_count(s, &total, &sampled);
    (void)sampled;
    return total - (size_t)(pm_light_gather_rule(s) == 2); /* a constant sky is the map's (rule 2) */
}

/* ------------------------------------------------------------------ per kind */

float pm_spot_factor(const pm_point_light_t *l, const float w[3])
{
    if (!pm_point_light_is_spot(l))
        return 1.0f;
    float c = pm_dot3(l->axis, w);
    if (!(c > l->cos_cone))
        return 0.0f;
    float x = fminf(1.0f, (c - l->cos_cone) / (1.0f - l->cos_cone));
    return l->falloff == 0.0f ? 1.0f : powf(x, l->falloff);
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

/* pm_sun_sample in the cone's frame t, b (pm_onb of the direction), which the caller keeps: the
 * light set's (pm_lights_t sun_t, sun_b), for its light samples and its sun's photons alike. */
static void sun_sample_in(const pm_sun_t *sun, pm_vec3_t t, pm_vec3_t b, float u1, float u2, float wi_out[3])
{
    float c = 1.0f - u1 * (1.0f - sun->cos_max), sn = sqrtf(fmaxf(0.0f, 1.0f - c * c)), phi = 2.0f * PM_PI * u2;
    pm_v3_store(wi_out, pm_v3_normalize(pm_onb_to_world(pm_v3(sn * cosf(phi), sn * sinf(phi), c), t, b,
                                                        pm_v3_load(sun->direction))));
}

void pm_sun_sample(const pm_sun_t *sun, float u1, float u2, float wi_out[3])
{
    pm_vec3_t t, b;
    pm_onb(pm_v3_load(sun->direction), &t, &b);
    sun_sample_in(sun, t, b, u1, u2, wi_out);
}

float pm_sun_pdf(const pm_sun_t *sun, const float w[3])
{
    return pm_dot3(sun->direction, w) >= sun->cos_max ? 1.0f / sun->solid_angle : 0.0f;
}

/* Direction w in the map's frame (w itself for an unframed map). */
static void to_map(const pm_envmap_t *e, const float w[3], double m_out[3])
{
    for (int k = 0; k < 3; k++)
        m_out[k] = e->framed ? e->frame[3 * k] * w[0] + e->frame[3 * k + 1] * w[1] + e->frame[3 * k + 2] * w[2] : w[k];
}

/* The pixel of direction m in the map's frame. */
static void map_pixel(const pm_envmap_t *e, const double m[3], uint32_t *x_out, uint32_t *y_out)
{
    /* theta from the horizontal length, not acos(y): near the poles y rounds to 1 first. */
    double st = sqrt(m[0] * m[0] + m[2] * m[2]);
    double th = atan2(st, m[1]), ph = atan2(m[2], m[0]);
    if (ph < 0.0)
        ph += 2.0 * M_PI;
    double fx = ph / (2.0 * M_PI) * e->w, fy = th / M_PI * e->h;
    *x_out = fx >= e->w ? e->w - 1 : (uint32_t)fx;
    *y_out = fy >= e->h ? e->h - 1 : (uint32_t)fy;
}

void pm_envmap_pixel(const pm_envmap_t *e, const float w[3], uint32_t *x_out, uint32_t *y_out)
{
    double m[3];
    to_map(e, w, m);
    map_pixel(e, m, x_out, y_out);
}

/* The world direction of the map's polar angle th and azimuth ph (radians, y up in the map's
 * own frame): back to the world by the frame's rows weighted by the map direction. */
static void map_direction(const pm_envmap_t *e, double th, double ph, double w_out[3])
{
    double m[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
    for (int k = 0; k < 3; k++)
        w_out[k] = e->framed ? m[0] * e->frame[k] + m[1] * e->frame[3 + k] + m[2] * e->frame[6 + k] : m[k];
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
    double w[3];
    map_direction(e, M_PI * (y + fy) / e->h, 2.0 * M_PI * (x + fx) / e->w, w);
    for (int k = 0; k < 3; k++)
        wi_out[k] = (float)w[k];
}

float pm_envmap_pdf(const pm_envmap_t *e, const float w[3])
{
    if (!(e->total > 0.0))
        return 0.0f;
    uint32_t x, y;
    double m[3];
    to_map(e, w, m);
    map_pixel(e, m, &x, &y);
    double st = sqrt(m[0] * m[0] + m[2] * m[2]) / sqrt(pm_dot3(w, w)); /* a turn keeps the length */
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

/* Point of triangle t at barycentrics (b0, b1), b2 = 1 - b0 - b1. */
static void triangle_point(const pm_scene_t *s, uint32_t t, float b0, float b1, float p_out[3])
{
    const float *a = s->verts + 3 * s->tris[3 * t], *b = s->verts + 3 * s->tris[3 * t + 1],
                *c = s->verts + 3 * s->tris[3 * t + 2];
    float b2 = 1.0f - b0 - b1;
    for (int k = 0; k < 3; k++)
        p_out[k] = b0 * a[k] + b1 * b[k] + b2 * c[k];
}

/* ------------------------------------------------------------------ emission */

/* A point uniform over the portals' total area from u (picking the portal, then reused) and v;
 * the index of its portal in *i_out. */
static void portal_point(const pm_scene_t *s, float u, float v, float p_out[3], size_t *i_out)
{
    double target = (double)u * s->portal_area, acc = 0.0;
    size_t i = 0;
    while (i + 1 < s->nportals && acc + s->portals[i].area <= target)
        acc += s->portals[i++].area;
    const pm_portal_t *q = &s->portals[i];
    double a = fmin(fmax((target - acc) / q->area, 0.0), 1.0);
    for (int k = 0; k < 3; k++)
        p_out[k] = (float)(q->corner[k] + a * q->edge_u[k] + (double)v * q->edge_v[k]);
    *i_out = i;
}

/* A photon of the sun (sun 1) or of the sky (sun 0): the direction w it comes from, uniform in
 * the sun's cone, over the sphere (a constant sky) or by the map's pixels, then a point uniform on
 * the disc of radius R perpendicular to w, tangent to the scene's bounding sphere on w's side; the
 * photon starts there and travels along -w, so that every point of the ball receives radiance L
 * from each direction of the light. flux_out: L(w) pi R^2 / pdf(w), W.
 * With portals the point is uniform over their total area A instead and the flux L(w) A
 * max(0, cos) / pdf(w), cos between -w and the portal's inward normal: the irradiance of every
 * point the portals let light reach is the same in expectation; a constant sky's directions are
 * then cosine-distributed about the inward normal (flux L pi A, none wasted leaving outward). */
static void env_emit(const pm_lights_t *L, int sun, float u1, float u2, float u3, float u4, float org_out[3],
                     float dir_out[3], double flux_out[3])
{
    const pm_scene_t *s = L->s;
    float w[3], x, y;
    double c[3], r;
    pm_scene_sphere(s, c, &r);
    double disc = M_PI * r * r;
    size_t pi = 0;
    if (s->nportals) {
        portal_point(s, u3, u4, org_out, &pi);
        disc = s->portal_area;
    }
    if (sun) {
        sun_sample_in(&s->sun, pm_v3_load(L->sun_t), pm_v3_load(L->sun_b), u1, u2, w);
        for (int k = 0; k < 3; k++)
            flux_out[k] = s->sun.radiance[k] * (double)s->sun.solid_angle * disc;
    } else if (s->envmap) {
        pm_envmap_sample(s->envmap, u1, u2, w);
        float le[3], p = pm_envmap_pdf(s->envmap, w);
        pm_sky_radiance(s, w, le);
        for (int k = 0; k < 3; k++)
            flux_out[k] = p > 0.0f ? le[k] / (double)p * disc : 0.0;
    } else if (s->nportals) {
        float d[3];
        pm_sky_sample(s, s->portals[pi].inward, u1, u2, d); /* cosine about the inward normal */
        for (int k = 0; k < 3; k++)
            w[k] = -d[k], flux_out[k] = s->sky[k] * M_PI * disc, dir_out[k] = d[k];
        return;
    } else {
        pm_v3_store(w, pm_sample_sphere(u1, u2));
        for (int k = 0; k < 3; k++)
            flux_out[k] = s->sky[k] * 4.0 * M_PI * disc;
    }
    if (s->nportals) {
        float cs = -pm_dot3(w, s->portals[pi].inward);
        for (int k = 0; k < 3; k++)
            flux_out[k] = cs > 0.0f ? flux_out[k] * cs : 0.0, dir_out[k] = -w[k];
        return;
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

void pm_portals_power(const pm_scene_t *s, double power_out[2][3])
{
    memset(power_out, 0, 6 * sizeof(double));
    const pm_envmap_t *e = s->envmap;
    for (size_t i = 0; i < s->nportals; i++) {
        const pm_portal_t *q = &s->portals[i];
        /* The sun: E = L omega (1 + cos_max) / 2 at normal incidence, times the axis' cosine. */
        double cs = -(double)pm_dot3(s->sun.direction, q->inward), e_sun = 0.5 * (1.0 + (double)s->sun.cos_max);
        for (int k = 0; k < 3 && s->has_sun && cs > 0.0; k++)
            power_out[0][k] += s->sun.radiance[k] * (double)s->sun.solid_angle * e_sun * cs * q->area;
        if (!s->has_sky)
            continue;
        if (!e) { /* the integral of L cos over the hemisphere: pi L */
            for (int k = 0; k < 3; k++)
                power_out[1][k] += M_PI * s->sky[k] * q->area;
            continue;
        }
        for (uint32_t py = 0; py < e->h; py++) {
            double th = M_PI * (py + 0.5) / e->h, dw = (2.0 * M_PI / e->w) * (M_PI / e->h) * sin(th);
            for (uint32_t px = 0; px < e->w; px++) {
                double m[3], c = 0.0;
                map_direction(e, th, 2.0 * M_PI * (px + 0.5) / e->w, m);
                for (int k = 0; k < 3; k++)
                    c -= m[k] * q->inward[k];
                if (!(c > 0.0))
                    continue;
                const float *L = e->rgb + 3 * ((size_t)py * e->w + px);
                for (int k = 0; k < 3; k++)
                    power_out[1][k] += L[k] * dw * c * q->area;
            }
        }
    }
}

void pm_light_sample_le(const pm_lights_t *L, const pm_light_t *l, float u1, float u2, float u3, float u4, float eps,
                        float org_out[3], float dir_out[3], double flux_out[3])
{
    const pm_scene_t *s = L->s;
    for (int k = 0; k < 3; k++)
        flux_out[k] = l->power[k];
    switch (l->kind) {
    case PM_LIGHT_POINT:
    case PM_LIGHT_SPOT:
        memcpy(org_out, s->lights[l->index].position, 3 * sizeof(float));
        pm_point_light_emit(&s->lights[l->index], u1, u2, dir_out);
        return;
    case PM_LIGHT_AREA: {
        const uint32_t *tri = &s->tris[3 * (size_t)l->index];
        pm_vec3_t v0 = pm_v3_load(&s->verts[3 * (size_t)tri[0]]), v1 = pm_v3_load(&s->verts[3 * (size_t)tri[1]]),
                  v2 = pm_v3_load(&s->verts[3 * (size_t)tri[2]]);
        float b0, b1, p[3];
        pm_sample_triangle(u1, u2, &b0, &b1);
        triangle_point(s, l->index, b0, b1, p);
        /* The front face: the right-hand-rule normal of (v0, v1, v2). */
        pm_vec3_t n = pm_v3_normalize(pm_v3_cross(pm_v3_sub(v1, v0), pm_v3_sub(v2, v0))), tb, bb;
        if (pm_scene_emits_both(s, l->index)) { /* either face, by half of u3; the other half stays uniform */
            if (u3 < 0.5f)
                n = pm_v3_scale(n, -1.0f), u3 = 2.0f * u3;
            else
                u3 = 2.0f * u3 - 1.0f;
        }
        pm_onb(n, &tb, &bb);
        pm_v3_store(dir_out, pm_onb_to_world(pm_sample_cosine_hemisphere(u3, u4), tb, bb, n));
        pm_v3_store(org_out, pm_v3_add(pm_v3_load(p), pm_v3_scale(n, eps)));
        return;
    }
    case PM_LIGHT_SUN:
    case PM_LIGHT_SKY: env_emit(L, l->kind == PM_LIGHT_SUN, u1, u2, u3, u4, org_out, dir_out, flux_out); return;
    default:
        for (int k = 0; k < 3; k++)
            org_out[k] = dir_out[k] = 0.0f, flux_out[k] = 0.0;
        return;
    }
}

/* ------------------------------------------------------------------ direct light */

/* The unit direction, distance and cosine at the surface from p toward point y; 0 when y is p. */
static int toward(const float p[3], const float n[3], const float y[3], pm_light_li_t *o)
{
    float v[3] = {y[0] - p[0], y[1] - p[1], y[2] - p[2]};
    o->r2 = pm_dot3(v, v), o->r = sqrtf(o->r2);
    if (!(o->r > 0.0f))
        return 0;
    for (int k = 0; k < 3; k++)
        o->wi[k] = v[k] / o->r;
    o->cosx = pm_dot3(n, o->wi);
    return 1;
}

int pm_lights_sample_li(const pm_lights_t *L, size_t i, pm_rng_t *rng, const float p[3], const float n[3],
                        pm_light_li_t *o)
{
    return pm_lights_sample_li_u(L, i, rng, NULL, p, n, o);
}

int pm_lights_sample_li_u(const pm_lights_t *L, size_t i, pm_rng_t *rng, const float *u, const float p[3],
                          const float n[3], pm_light_li_t *o)
{
    const pm_scene_t *s = L->s;
    const pm_light_t *l = &L->direct[i];
    o->delta = l->delta, o->infinite = l->infinite, o->cosy = 1.0f, o->pdf = 1.0f;
    switch (l->kind) {
    case PM_LIGHT_POINT:
    case PM_LIGHT_SPOT: {
        /* Intensity I s (W/sr) at distance r: irradiance I s / r^2 at normal incidence. */
        const pm_point_light_t *pl = &s->lights[l->index];
        if (!toward(p, n, pl->position, o) || !(o->cosx > 0.0f))
            return 0;
        float w[3] = {-o->wi[0], -o->wi[1], -o->wi[2]}, sf = pm_spot_factor(pl, w);
        for (int k = 0; k < 3; k++)
            o->Li[k] = pl->intensity[k] * sf / o->r2;
        return o->Li[0] > 0.0f || o->Li[1] > 0.0f || o->Li[2] > 0.0f;
    }
    case PM_LIGHT_AREA: {
        /* A point uniform over the total emissive area A (pdf 1/A per m^2): over solid angle
         * r^2 / (cos_y A). The triangle from a double, then two floats for the point, u2 drawn
         * before u1 (the order trace-gather-points has always drawn them in). */
        size_t e = pm_cdf_pick(L->area_cdf, s->nemissive, pm_rng_double(rng));
        uint32_t tri = s->emissive[e];
        float u2 = u ? u[1] : pm_rng_float(rng), u1 = u ? u[0] : pm_rng_float(rng), b0, b1, y[3];
        pm_sample_triangle(u1, u2, &b0, &b1);
        triangle_point(s, tri, b0, b1, y);
        if (!toward(p, n, y, o))
            return 0;
        o->cosy = -pm_dot3(L->front + 3 * e, o->wi);
        if (pm_scene_emits_both(s, tri)) /* either face lights */
            o->cosy = fabsf(o->cosy);
        if (!(o->cosx > 0.0f && o->cosy > 0.0f))
            return 0;
        o->pdf = o->r2 / (o->cosy * (float)L->area);
        memcpy(o->Li, s->materials[s->tri_material[tri]].ke, sizeof o->Li);
        return o->pdf > 0.0f && isfinite(o->pdf);
    }
    case PM_LIGHT_SUN:
    case PM_LIGHT_SKY: {
        float u1 = u ? u[0] : pm_rng_float(rng), u2 = u ? u[1] : pm_rng_float(rng);
        if (l->kind == PM_LIGHT_SUN)
            sun_sample_in(&s->sun, pm_v3_load(L->sun_t), pm_v3_load(L->sun_b), u1, u2, o->wi);
        else
            pm_sky_sample(s, n, u1, u2, o->wi);
        o->r = o->r2 = INFINITY;
        o->cosx = pm_dot3(n, o->wi);
        o->pdf = l->kind == PM_LIGHT_SUN ? pm_sun_pdf(&s->sun, o->wi) : pm_sky_pdf(s, n, o->wi);
        if (!(o->cosx > 0.0f && o->pdf > 0.0f))
            return 0;
        if (l->kind == PM_LIGHT_SUN)
            memcpy(o->Li, s->sun.radiance, sizeof o->Li);
        else
            pm_sky_radiance(s, o->wi, o->Li);
        return 1;
    }
    default: return 0;
    }
}

float pm_light_shadow_tmax(const pm_light_li_t *li, float eps)
{
    if (li->infinite)
        return INFINITY;
    if (li->delta)
        return li->r - eps;
    return li->r * (1.0f - 1e-4f) - 2.0f * eps; /* short of the light's own surface */
}

float pm_lights_pdf_li_escape(const pm_lights_t *L, size_t i, const float n[3], const float w[3])
{
    switch (L->direct[i].kind) {
    case PM_LIGHT_SUN: return pm_sun_pdf(&L->s->sun, w);
    case PM_LIGHT_SKY: return pm_sky_pdf(L->s, n, w);
    default: return 0.0f;
    }
}

float pm_lights_pdf_li_hit(const pm_lights_t *L, float dist, float cos_emit)
{
    return dist * dist / (cos_emit * (float)L->area);
}

void pm_lights_le_escape_one(const pm_lights_t *L, size_t i, const float w[3], float le_out[3])
{
    const pm_scene_t *s = L->s;
    switch (L->direct[i].kind) {
    case PM_LIGHT_SUN: {
        int in = pm_dot3(s->sun.direction, w) >= s->sun.cos_max;
        for (int k = 0; k < 3; k++)
            le_out[k] = in ? s->sun.radiance[k] : 0.0f;
        return;
    }
    case PM_LIGHT_SKY: pm_sky_radiance(s, w, le_out); return;
    default: le_out[0] = le_out[1] = le_out[2] = 0.0f; return;
    }
}

void pm_lights_le_escape(const pm_lights_t *L, const float w[3], float le_out[3])
{
    le_out[0] = le_out[1] = le_out[2] = 0.0f;
    for (size_t i = L->ndelta; i < L->ndirect; i++) {
        if (!L->direct[i].infinite)
            continue;
        float le[3];
        pm_lights_le_escape_one(L, i, w, le);
        for (int k = 0; k < 3; k++)
            le_out[k] += le[k];
    }
}

int pm_lights_le_hit(const pm_lights_t *L, uint32_t tri, float cos_front, float le_out[3], float *cos_emit_out)
{
    const pm_scene_t *s = L->s;
    const pm_material_t *m = &s->materials[s->tri_material[tri]];
    if (!pm_material_is_emissive(m) || !(cos_front >= 0.0f || pm_scene_emits_both(s, tri)))
        return 0;
    *cos_emit_out = fabsf(cos_front);
    memcpy(le_out, m->ke, 3 * sizeof(float));
    return 1;
}

/* ------------------------------------------------------------------ description */

/* The lights scene-info describes one by one, in scene order: every point light and spot, the
 * sun, the sky (not the triangles); kind_out and index_out of the i-th, 0 past the last. */
static int described(const pm_scene_t *s, size_t i, pm_light_kind_t *kind_out, uint32_t *index_out)
{
    *index_out = 0;
    if (i < s->nlights) {
        *kind_out = pm_point_light_is_spot(&s->lights[i]) ? PM_LIGHT_SPOT : PM_LIGHT_POINT;
        *index_out = (uint32_t)i;
        return 1;
    }
    i -= s->nlights;
    if (s->has_sun && i-- == 0) {
        *kind_out = PM_LIGHT_SUN;
        return 1;
    }
    if (s->has_sky && i == 0) {
        *kind_out = PM_LIGHT_SKY;
        return 1;
    }
    return 0;
}

/* A spot's cone half-angle, degrees. */
static double cone_deg(const pm_point_light_t *l)
{
    return acos(fmax(-1.0, fmin(1.0, (double)l->cos_cone))) * 180.0 / M_PI;
}

void pm_lights_describe_text(const pm_scene_t *s, FILE *out)
{
    fprintf(out, "point lights: %zu\n", s->nlights);
    pm_light_kind_t kind;
    uint32_t i;
    for (size_t d = 0; described(s, d, &kind, &i); d++) {
        switch (kind) {
        case PM_LIGHT_POINT:
        case PM_LIGHT_SPOT: {
            const pm_point_light_t *l = &s->lights[i];
            fprintf(out, "  light %" PRIu32 " at %.6g %.6g %.6g intensity %.6g %.6g %.6g W/sr", i, l->position[0],
                    l->position[1], l->position[2], l->intensity[0], l->intensity[1], l->intensity[2]);
            if (kind == PM_LIGHT_SPOT)
                fprintf(out, " spot toward %.6g %.6g %.6g cone %.6g deg falloff %.6g", l->axis[0], l->axis[1],
                        l->axis[2], cone_deg(l), l->falloff);
            fprintf(out, "\n");
            break;
        }
        case PM_LIGHT_SUN:
            fprintf(out, "sun: toward %.6g %.6g %.6g radiance %.6g %.6g %.6g W/(m^2 sr) solid angle %.6g sr\n",
                    s->sun.direction[0], s->sun.direction[1], s->sun.direction[2], s->sun.radiance[0],
                    s->sun.radiance[1], s->sun.radiance[2], s->sun.solid_angle);
            break;
        case PM_LIGHT_SKY:
            if (s->envmap)
                fprintf(
                    out,
                    "sky: map %" PRIu32 "x%" PRIu32 " times %.6g %.6g %.6g, mean radiance %.6g %.6g %.6g W/(m^2 sr)",
                    s->envmap->w, s->envmap->h, s->sky[0], s->sky[1], s->sky[2], s->envmap->integral[0] / (4.0 * M_PI),
                    s->envmap->integral[1] / (4.0 * M_PI), s->envmap->integral[2] / (4.0 * M_PI));
            if (s->sky_turbidity > 0.0)
                fprintf(out, ", the preetham model of turbidity %.6g", s->sky_turbidity);
            if (s->envmap && s->envmap->framed)
                fprintf(out, ", turned to up %.6g %.6g %.6g, rotate %.6g deg", s->sky_up[0], s->sky_up[1], s->sky_up[2],
                        s->sky_rotate);
            if (s->envmap)
                fprintf(out, "\n");
            else
                fprintf(out, "sky: radiance %.6g %.6g %.6g W/(m^2 sr)\n", s->sky[0], s->sky[1], s->sky[2]);
            break;
        default: break;
        }
    }
    if (s->nportals)
        fprintf(out,
                "portals: %zu, %.6g m^2 in all (the sun's and the sky's photons enter through them only; power "
                "through them: sun %.6g W, sky %.6g W)\n",
                s->nportals, s->portal_area, s->portal_power[0][0] + s->portal_power[0][1] + s->portal_power[0][2],
                s->portal_power[1][0] + s->portal_power[1][1] + s->portal_power[1][2]);
    for (size_t j = 0; j < s->nportals; j++) {
        const pm_portal_t *q = &s->portals[j];
        fprintf(out, "  portal %zu at %.6g %.6g %.6g edges %.6g %.6g %.6g and %.6g %.6g %.6g inward %.6g %.6g %.6g\n",
                j, q->corner[0], q->corner[1], q->corner[2], q->edge_u[0], q->edge_u[1], q->edge_u[2], q->edge_v[0],
                q->edge_v[1], q->edge_v[2], q->inward[0], q->inward[1], q->inward[2]);
    }
}

static json_t *floats_json(const float *v, size_t n)
{
    json_t *a = json_array();
    for (size_t i = 0; i < n; i++)
        json_array_append_new(a, json_real(v[i]));
    return a;
}

json_t *pm_lights_describe_json(const pm_scene_t *s)
{
    json_t *lights = json_array();
    pm_light_kind_t kind;
    uint32_t i;
    for (size_t d = 0; described(s, d, &kind, &i); d++) {
        json_t *lj = NULL;
        switch (kind) {
        case PM_LIGHT_POINT:
        case PM_LIGHT_SPOT: {
            const pm_point_light_t *l = &s->lights[i];
            lj = json_pack("{s:s, s:o, s:o}", "kind", pm_light_kind_name(kind), "position_m",
                           floats_json(l->position, 3), "intensity_w_sr", floats_json(l->intensity, 3));
            if (lj && kind == PM_LIGHT_SPOT) {
                json_object_set_new(lj, "direction", floats_json(l->axis, 3));
                json_object_set_new(lj, "cone_deg", json_real(cone_deg(l)));
                json_object_set_new(lj, "falloff", json_real(l->falloff));
            }
            break;
        }
        case PM_LIGHT_SUN:
            lj = json_pack("{s:s, s:o, s:o, s:f}", "kind", pm_light_kind_name(kind), "direction",
                           floats_json(s->sun.direction, 3), "radiance_w_m2_sr", floats_json(s->sun.radiance, 3),
                           "solid_angle_sr", s->sun.solid_angle);
            break;
        case PM_LIGHT_SKY:
            lj = json_pack("{s:s, s:o}", "kind", pm_light_kind_name(kind), "radiance_w_m2_sr", floats_json(s->sky, 3));
            if (lj && s->envmap) { /* radiance is then the map's scale */
                json_object_set_new(lj, "map_pixels",
                                    json_pack("[I, I]", (json_int_t)s->envmap->w, (json_int_t)s->envmap->h));
                json_object_set_new(lj, "up", json_pack("[f, f, f]", s->sky_up[0], s->sky_up[1], s->sky_up[2]));
                json_object_set_new(lj, "rotate_deg", json_real(s->sky_rotate));
                if (s->sky_turbidity > 0.0) {
                    json_object_set_new(lj, "model", json_string("preetham"));
                    json_object_set_new(lj, "turbidity", json_real(s->sky_turbidity));
                }
            }
            break;
        default: break;
        }
        if (lj)
            json_array_append_new(lights, lj);
    }
    return lights;
}

json_t *pm_portals_describe_json(const pm_scene_t *s)
{
    json_t *a = json_array();
    for (size_t i = 0; i < s->nportals; i++) {
        const pm_portal_t *q = &s->portals[i];
        json_array_append_new(a, json_pack("{s:o, s:o, s:o, s:o, s:f}", "corner_m", floats_json(q->corner, 3),
                                           "edge_u_m", floats_json(q->edge_u, 3), "edge_v_m", floats_json(q->edge_v, 3),
                                           "inward", floats_json(q->inward, 3), "area_m2", q->area));
    }
    return a;
}
