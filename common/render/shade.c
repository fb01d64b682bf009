/* shade.c: camera rays, the BRDF, triangle normals and area-light choice (shade.h). */
#include "render/shade.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <inttypes.h>

#include "math/sampling.h"
#include "math/vec.h"

static inline float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

void pm_camera_setup(const pm_camera_t *cam, uint32_t w, uint32_t h, pm_camera_rays_t *c)
{
    float len = 0.0f;
    for (int k = 0; k < 3; k++) {
        c->eye[k] = cam->eye[k];
        c->fwd[k] = cam->look_at[k] - cam->eye[k];
        len += c->fwd[k] * c->fwd[k];
    }
    for (int k = 0; k < 3; k++)
        c->fwd[k] /= sqrtf(len);
    pm_vec3_t f = pm_v3_load(c->fwd), r = pm_v3_normalize(pm_v3_cross(f, pm_v3_load(cam->up)));
    pm_v3_store(c->right, r);
    pm_v3_store(c->up, pm_v3_cross(r, f));
    c->tan_half = tanf(0.5f * cam->fov_y * PM_PI / 180.0f);
    c->aspect = (float)w / (float)h;
    c->w = w, c->h = h;
}

void pm_camera_dir(const pm_camera_rays_t *c, float px, float py, float d_out[3])
{
    float sx = (2.0f * px / (float)c->w - 1.0f) * c->tan_half * c->aspect;
    float sy = (1.0f - 2.0f * py / (float)c->h) * c->tan_half;
    float d[3], len = 0.0f;
    for (int k = 0; k < 3; k++) {
        d[k] = c->fwd[k] + sx * c->right[k] + sy * c->up[k];
        len += d[k] * d[k];
    }
    len = 1.0f / sqrtf(len);
    for (int k = 0; k < 3; k++)
        d_out[k] = d[k] * len;
}

void pm_brdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3], float f_out[3])
{
    float lobe = 0.0f;
    if (pm_material_is_glossy(m)) {
        float c = 2.0f * dot3(n, wi), r[3] = {c * n[0] - wi[0], c * n[1] - wi[1], c * n[2] - wi[2]};
        float cr = dot3(r, wo);
        if (cr > 0.0f)
            lobe = (m->ns + 2.0f) / (2.0f * PM_PI) * powf(cr, m->ns);
    }
    for (int k = 0; k < 3; k++)
        f_out[k] = m->kd[k] * (1.0f / PM_PI) + m->ks[k] * lobe;
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

int pm_point_light_toward(const pm_point_light_t *l, const float p[3], const float n[3], pm_light_sample_t *o)
{
    float v[3] = {l->position[0] - p[0], l->position[1] - p[1], l->position[2] - p[2]};
    o->r2 = dot3(v, v), o->r = sqrtf(o->r2);
    if (!(o->r > 0.0f))
        return 0;
    for (int k = 0; k < 3; k++)
        o->wi[k] = v[k] / o->r;
    o->cosx = dot3(n, o->wi), o->cosy = 1.0f, o->tri = UINT32_MAX;
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
    o->r2 = dot3(v, v), o->r = sqrtf(o->r2);
    if (!(o->r > 0.0f))
        return 0;
    for (int k = 0; k < 3; k++)
        o->wi[k] = v[k] / o->r;
    o->cosx = dot3(n, o->wi), o->cosy = -dot3(g->tri_n + 3 * (size_t)o->tri, o->wi);
    return o->cosx > 0.0f && o->cosy > 0.0f;
}

pm_result_t pm_image_header_begin(pm_header_t *h, int argc, char **argv, const pm_scene_t *s, uint32_t w,
                                  uint32_t ht)
{
    char id[200];
    pm_scene_id(s, id, sizeof id);
    memcpy(h->bounds, s->bounds, sizeof h->bounds);
    pm_result_t r = pm_header_add_command(h, argc, argv);
    if (r == PM_OK)
        r = pm_header_set(h, "SCENE", "%s", id);
    if (r == PM_OK)
        r = pm_header_set(h, "width", "%" PRIu32, w);
    if (r == PM_OK)
        r = pm_header_set(h, "height", "%" PRIu32, ht);
    return r;
}
