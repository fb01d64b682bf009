/* surface.c: hit-time queries on a loaded scene: barycentrics, texture coordinates, a textured
 * material, cut-outs (map_d) and shading normals (vertex normals, normal and bump maps) at a
 * point of a triangle. */
#include "render/scene.h"

#include <math.h>
#include <string.h>

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

/* v normalized in place; 0 (v left alone) when its squared length is not above min2 or not finite. */
static int unit(float v[3], float min2)
{
    float l2 = pm_dot3(v, v);
    if (!(l2 > min2) || !isfinite(l2))
        return 0;
    float inv = 1.0f / sqrtf(l2);
    for (int k = 0; k < 3; k++)
        v[k] *= inv;
    return 1;
}

/* The vertex normals of triangle tri interpolated at p and normalized into q_out; 0 when the
 * scene has none or they cancel there. */
static int vertex_normal(const pm_scene_t *s, uint32_t tri, const float p[3], float q_out[3])
{
    if (!s->normals)
        return 0;
    const float *n0 = &s->normals[3 * s->tris[3 * tri]], *n1 = &s->normals[3 * s->tris[3 * tri + 1]],
                *n2 = &s->normals[3 * s->tris[3 * tri + 2]];
    float b[2], *q = q_out;
    pm_scene_barycentrics(s, tri, p, b);
    float b0 = 1.0f - b[0] - b[1];
    for (int k = 0; k < 3; k++)
        q[k] = b0 * n0[k] + b[0] * n1[k] + b[1] * n2[k];
    /* No normals at this triangle (zero), or ones that cancel: the geometric normal. */
    return unit(q, 1e-12f);
}

/* Triangle tri's position derivatives along its texture coordinates, m per unit of u and of v:
 * the edges solved against the UV edges. 0 without UVs or when they are degenerate. */
static int uv_derivatives(const pm_scene_t *s, uint32_t tri, float dpdu[3], float dpdv[3])
{
    if (!s->uvs)
        return 0;
    const uint32_t *t = &s->tris[3 * tri];
    const float *p0 = &s->verts[3 * t[0]], *p1 = &s->verts[3 * t[1]], *p2 = &s->verts[3 * t[2]];
    const float *t0 = &s->uvs[2 * t[0]], *t1 = &s->uvs[2 * t[1]], *t2 = &s->uvs[2 * t[2]];
    float du1 = t1[0] - t0[0], dv1 = t1[1] - t0[1], du2 = t2[0] - t0[0], dv2 = t2[1] - t0[1];
    float det = du1 * dv2 - dv1 * du2;
    if (!(fabsf(det) > 1e-12f * (fabsf(du1 * dv2) + fabsf(dv1 * du2))) || !isfinite(det))
        return 0;
    for (int k = 0; k < 3; k++) {
        float e1 = p1[k] - p0[k], e2 = p2[k] - p0[k];
        dpdu[k] = (dv2 * e1 - dv1 * e2) / det;
        dpdv[k] = (du1 * e2 - du2 * e1) / det;
    }
    return 1;
}

/* Bends unit normal q at p by material maps mm: a normal map's texel t (linear, 2 t - 1 per
 * channel) in the tangent frame (x along dp/du, y along dp/dv made orthogonal, z q), or a bump
 * map's height h (m: texel * bump_scale) as the normal of p + h q, cross(dp/du + dh/du q,
 * dp/dv + dh/dv q) on q's side, its slopes by central differences one texel apart. 0 (q
 * unchanged) without UVs or when the result degenerates. */
static int bend(const pm_scene_t *s, const pm_material_maps_t *mm, uint32_t tri, const float p[3], float q[3])
{
    float dpdu[3], dpdv[3], b[2], uv[2], tx[4], out[3];
    if (!uv_derivatives(s, tri, dpdu, dpdv))
        return 0;
    pm_scene_barycentrics(s, tri, p, b);
    pm_scene_uv(s, tri, b[0], b[1], uv);
    if (mm->normal >= 0) {
        float T[3], B[3], tu = pm_dot3(q, dpdu), tv = pm_dot3(q, dpdv);
        for (int k = 0; k < 3; k++)
            T[k] = dpdu[k] - q[k] * tu;
        if (!unit(T, 1e-30f))
            return 0;
        float bt = pm_dot3(T, dpdv);
        for (int k = 0; k < 3; k++)
            B[k] = dpdv[k] - q[k] * tv - T[k] * bt;
        if (!unit(B, 1e-30f))
            return 0;
        pm_texture_lookup(&s->textures[mm->normal], uv[0], uv[1], 0, tx);
        for (int k = 0; k < 3; k++)
            out[k] = (2.0f * tx[0] - 1.0f) * T[k] + (2.0f * tx[1] - 1.0f) * B[k] + (2.0f * tx[2] - 1.0f) * q[k];
    } else {
        const pm_texture_t *t = &s->textures[mm->bump];
        float du = 1.0f / (float)t->w, dv = 1.0f / (float)t->h, h[4];
        const float off[4][2] = {{du, 0}, {-du, 0}, {0, dv}, {0, -dv}};
        for (int i = 0; i < 4; i++) {
            pm_texture_lookup(t, uv[0] + off[i][0], uv[1] + off[i][1], 0, tx);
            h[i] = tx[0] * mm->bump_scale;
        }
        float hu = (h[0] - h[1]) / (2.0f * du), hv = (h[2] - h[3]) / (2.0f * dv), a[3], c[3];
        for (int k = 0; k < 3; k++)
            a[k] = dpdu[k] + hu * q[k], c[k] = dpdv[k] + hv * q[k];
        pm_v3_store(out, pm_v3_cross(pm_v3_load(a), pm_v3_load(c)));
        if (pm_dot3(out, q) < 0.0f)
            for (int k = 0; k < 3; k++)
                out[k] = -out[k];
    }
    if (!unit(out, 1e-30f))
        return 0;
    memcpy(q, out, sizeof out);
    return 1;
}

int pm_scene_shading_normal(const pm_scene_t *s, uint32_t tri, const float p[3], const float n[3], float ns_out[3])
{
    ns_out[0] = n[0], ns_out[1] = n[1], ns_out[2] = n[2];
    const pm_material_maps_t *mm = s->maps ? &s->maps[s->tri_material[tri]] : NULL;
    float q[3];
    int have = vertex_normal(s, tri, p, q);
    if (mm && (mm->normal >= 0 || mm->bump >= 0)) {
        if (!have) { /* the triangle's own normal, front by the right-hand rule, bent */
            const uint32_t *t = &s->tris[3 * tri];
            pm_vec3_t a = pm_v3_load(&s->verts[3 * t[0]]), b = pm_v3_load(&s->verts[3 * t[1]]),
                      c = pm_v3_load(&s->verts[3 * t[2]]);
            pm_v3_store(q, pm_v3_cross(pm_v3_sub(b, a), pm_v3_sub(c, a)));
            if (!unit(q, 1e-30f))
                return 0;
        }
        have = bend(s, mm, tri, p, q) || have;
    }
    if (!have)
        return 0;
    if (pm_dot3(q, n) < 0.0f) /* the side n is on: the mesh's normals may face the other way */
        for (int k = 0; k < 3; k++)
            q[k] = -q[k];
    memcpy(ns_out, q, sizeof q);
    return 1;
}
