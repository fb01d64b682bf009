/* surface.c: hit-time queries on a loaded scene: barycentrics, texture coordinates, a textured
 * material, cut-outs (map_d) and shading normals at a point of a triangle. */
#include "render/scene.h"

#include <math.h>

#include "math/vec.h"
#include "render/scene_load.h"

void pm_scene_barycentrics(const pm_scene_t *s, uint32_t tri, const float p[3], float b_out[2])
{
    const float *a = &s->verts[3 * s->tris[3 * tri]], *b = &s->verts[3 * s->tris[3 * tri + 1]],
                *c = &s->verts[3 * s->tris[3 * tri + 2]];
    float e1[3], e2[3], d[3];
    for (int k = 0; k < 3; k++)
        e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], d[k] = p[k] - a[k];
    float d11 = pm_dot3(e1, e1), d12 = pm_dot3(e1, e2), d22 = pm_dot3(e2, e2), p1 = pm_dot3(d, e1), p2 = pm_dot3(d, e2),
          det = d11 * d22 - d12 * d12;
    float b1 = det > 0.0f ? (d22 * p1 - d12 * p2) / det : 0.0f, b2 = det > 0.0f ? (d11 * p2 - d12 * p1) / det : 0.0f;
    /* a point found by a ray lies in the triangle up to rounding: clamp it back in */
    b1 = b1 > 0.0f ? b1 : 0.0f;
    b2 = b2 > 0.0f ? b2 : 0.0f;
    if (b1 + b2 > 1.0f) {
        float t = b1 + b2;
        b1 /= t, b2 /= t;
    }
    b_out[0] = b1, b_out[1] = b2;
}

void pm_scene_uv(const pm_scene_t *s, uint32_t tri, float b1, float b2, float uv_out[2])
{
    uv_out[0] = uv_out[1] = 0.0f;
    if (!s->uvs)
        return;
    const float *t0 = &s->uvs[2 * s->tris[3 * tri]], *t1 = &s->uvs[2 * s->tris[3 * tri + 1]],
                *t2 = &s->uvs[2 * s->tris[3 * tri + 2]];
    float b0 = 1.0f - b1 - b2;
    for (int k = 0; k < 2; k++)
        uv_out[k] = b0 * t0[k] + b1 * t1[k] + b2 * t2[k];
}

const pm_material_t *pm_scene_material_textured(const pm_scene_t *s, uint32_t tri, const float p[3],
                                                pm_material_t *scratch)
{
    uint32_t mi = s->tri_material[tri];
    const pm_material_maps_t *mm = &s->maps[mi];
    *scratch = s->materials[mi];
    float b[2], uv[2], texel[4];
    pm_scene_barycentrics(s, tri, p, b);
    pm_scene_uv(s, tri, b[0], b[1], uv);
    if (mm->kd >= 0) {
        /* the base colour's texture: a PBR metal's base colour is its F0 (scene_material.c) */
        pm_texture_lookup(&s->textures[mm->kd], uv[0], uv[1], 1, texel);
        for (int k = 0; k < 3; k++) {
            scratch->kd[k] *= fminf(texel[k], 1.0f);
            if (scratch->kind == PM_MAT_CONDUCTOR)
                scratch->f0[k] *= fminf(texel[k], 1.0f);
        }
    }
    if (mm->ks >= 0) {
        pm_texture_lookup(&s->textures[mm->ks], uv[0], uv[1], 1, texel);
        for (int k = 0; k < 3; k++)
            scratch->ks[k] *= fminf(texel[k], 1.0f);
    }
    return scratch;
}

int pm_scene_cut_out(const pm_scene_t *s, uint32_t tri, float b1, float b2)
{
    int32_t a = s->maps ? s->maps[s->tri_material[tri]].alpha : -1;
    if (a < 0)
        return 0;
    const pm_texture_t *t = &s->textures[a];
    float uv[2], texel[4];
    pm_scene_uv(s, tri, b1, b2, uv);
    pm_texture_lookup(t, uv[0], uv[1], 0, texel);
    /* the alpha channel when the image has one, else its grey (a mask image) */
    return (t->has_alpha ? texel[3] : texel[0]) < 0.5f;
}

int pm_scene_shading_normal(const pm_scene_t *s, uint32_t tri, const float p[3], const float n[3], float ns_out[3])
{
    ns_out[0] = n[0], ns_out[1] = n[1], ns_out[2] = n[2];
    if (!s->normals)
        return 0;
    const float *n0 = &s->normals[3 * s->tris[3 * tri]], *n1 = &s->normals[3 * s->tris[3 * tri + 1]],
                *n2 = &s->normals[3 * s->tris[3 * tri + 2]];
    float b[2], q[3];
    pm_scene_barycentrics(s, tri, p, b);
    float b0 = 1.0f - b[0] - b[1];
    for (int k = 0; k < 3; k++)
        q[k] = b0 * n0[k] + b[0] * n1[k] + b[1] * n2[k];
    float len2 = pm_dot3(q, q);
    /* No normals at this triangle (zero), or ones that cancel: the geometric normal. */
    if (!(len2 > 1e-12f) || !isfinite(len2))
        return 0;
    float inv = 1.0f / sqrtf(len2);
    if (pm_dot3(q, n) < 0.0f) /* the side n is on: the mesh's normals may face the other way */
        inv = -inv;
    for (int k = 0; k < 3; k++)
        ns_out[k] = q[k] * inv;
    return 1;
}
