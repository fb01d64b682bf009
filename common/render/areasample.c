/* areasample.c: area samples over the photon-storing surfaces (areasample.h). */
#include "render/areasample.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "render/transport.h"

/* Samples on triangle t at spacing s (at least one: a triangle smaller than s^2 keeps its own
 * area as one sample, so that fine meshes are not thinned into noise). */
static uint64_t tri_count(double area, double s)
{
    double n = floor(area / (s * s) + 0.5);
    return n < 1.0 ? 1 : n > 1e12 ? (uint64_t)1e12 : (uint64_t)n;
}

/* A textured material can store nowhere (kd and ks textures aside, its own values): the
 * untextured values decide whether a triangle is sampled; a texel of zero then only costs. */
uint64_t pm_area_samples_count(const pm_scene_t *s, double spacing)
{
    uint64_t n = 0;
    for (size_t t = 0; t < s->ntris; t++)
        if (pm_material_keeps_photons(&s->materials[s->tri_material[t]]))
            n += 2 * tri_count(pm_scene_triangle_area(s, t), spacing);
    return n;
}

void pm_area_samples_free(pm_area_samples_t *a)
{
    free(a->pos);
    free(a->normal);
    free(a->area);
    memset(a, 0, sizeof *a);
}

/* Van der Corput's radical inverse of i in base 2: the Hammersley set's second coordinate. */
static double radical2(uint64_t i)
{
    uint64_t b = i;
    b = (b << 32) | (b >> 32);
    b = ((b & 0x0000ffff0000ffffull) << 16) | ((b >> 16) & 0x0000ffff0000ffffull);
    b = ((b & 0x00ff00ff00ff00ffull) << 8) | ((b >> 8) & 0x00ff00ff00ff00ffull);
    b = ((b & 0x0f0f0f0f0f0f0f0full) << 4) | ((b >> 4) & 0x0f0f0f0f0f0f0f0full);
    b = ((b & 0x3333333333333333ull) << 2) | ((b >> 2) & 0x3333333333333333ull);
    b = ((b & 0x5555555555555555ull) << 1) | ((b >> 1) & 0x5555555555555555ull);
    return (double)(b >> 11) * 0x1p-53;
}

/* 1 when the side of point p whose unit normal is n faces the inside of a solid: the ray along n
 * meets the back of a face within reach. */
static int faces_inside(const pm_rt_t *rt, struct RTCIntersectContext *ctx, const float p[3], const float n[3],
                        float reach)
{
    float t, ng[3];
    uint32_t hit = pm_rt_intersect1(rt, ctx, p, n, rt->epsilon, reach, &t, ng);
    return hit != PM_RAY_MISS && n[0] * ng[0] + n[1] * ng[1] + n[2] * ng[2] > 0.0f;
}

/* A sample slot's fate (pm_area_samples_make): kept, its side facing the inside of a solid, or
 * no sample (a cut-out, or a texel that keeps no photon). */
enum { SLOT_KEPT, SLOT_INSIDE, SLOT_NONE };

pm_result_t pm_area_samples_make(const pm_scene_t *s, const pm_rt_t *rt, double spacing, double reach, uint64_t seed,
                                 uint64_t max_samples, pm_area_samples_t *out)
{
    memset(out, 0, sizeof *out);
    if (!(spacing > 0.0 && isfinite(spacing)))
        return pm_error_set(PM_ERR_USAGE, "area sample spacing %g m is not a positive length", spacing);
    uint64_t cap = pm_area_samples_count(s, spacing);
    if (cap > max_samples)
        return pm_error_set(PM_ERR_USAGE,
                            "%" PRIu64 " area samples at a spacing of %g m over scene '%s' is more than %" PRIu64, cap,
                            spacing, s->name, max_samples);
    out->spacing = spacing;
    /* Each triangle's slots (two sides a sample) from a prefix sum, so that threads fill them in
     * any order and the kept samples come out in triangle order whatever the thread count; the
     * inside test runs where the sample is made (no geometric normals kept for a second pass:
     * 12 bytes a slot of fresh pages, which the kernel zeroes). */
    size_t alloc = cap ? (size_t)cap : 1;
    uint64_t *first = malloc((s->ntris + 1) * sizeof *first);
    unsigned char *slot = malloc(alloc);
    out->pos = malloc(alloc * 3 * sizeof *out->pos);
    out->normal = malloc(alloc * 3 * sizeof *out->normal);
    out->area = malloc(alloc * 3 * sizeof *out->area);
    if (!first || !slot || !out->pos || !out->normal || !out->area) {
        free(first);
        free(slot);
        pm_area_samples_free(out);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " area samples", cap);
    }
    first[0] = 0;
    for (size_t t = 0; t < s->ntris; t++) {
        uint64_t n = 0;
        if (pm_material_keeps_photons(&s->materials[s->tri_material[t]])) {
            double a = pm_scene_triangle_area(s, t);
            out->total_area += a;
            n = tri_count(a, spacing);
        }
        first[t + 1] = first[t] + 2 * n;
    }
    int inside_test = rt && reach > 0.0;
#pragma omp parallel
    {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
#pragma omp for schedule(dynamic, 64)
        for (size_t t = 0; t < s->ntris; t++) {
            uint64_t n = (first[t + 1] - first[t]) / 2, j = first[t];
            if (n == 0)
                continue;
            double a = pm_scene_triangle_area(s, t);
            const float *v0 = &s->verts[3 * (size_t)s->tris[3 * t]], *v1 = &s->verts[3 * (size_t)s->tris[3 * t + 1]],
                        *v2 = &s->verts[3 * (size_t)s->tris[3 * t + 2]];
            pm_vec3_t e1 = pm_v3_sub(pm_v3_load(v1), pm_v3_load(v0)), e2 = pm_v3_sub(pm_v3_load(v2), pm_v3_load(v0));
            float ng[3];
            pm_v3_store(ng, pm_v3_normalize(pm_v3_cross(e1, e2)));
            /* one shift per triangle: the triangles' patterns are independent of each other */
            pm_rng_t rng;
            pm_rng_init(&rng, seed, t);
            double du = pm_rng_double(&rng), dv = pm_rng_double(&rng);
            float w = (float)(a / (double)n);
            for (uint64_t i = 0; i < n; i++, j += 2) {
                double u = ((double)i + 0.5) / (double)n + du, v = radical2(i) + dv;
                u -= floor(u), v -= floor(v);
                float b0, b1, b2, p[3]; /* (b1, b2): the weights of v1 and v2, Embree's (u, v) */
                pm_sample_triangle((float)u, (float)v, &b0, &b2);
                b1 = 1.0f - b0 - b2;
                for (int c = 0; c < 3; c++)
                    p[c] = v0[c] + b1 * (v1[c] - v0[c]) + b2 * (v2[c] - v0[c]);
                pm_material_t scratch;
                if ((s->any_alpha && pm_scene_cut_out(s, (uint32_t)t, b1, b2)) ||
                    !pm_material_keeps_photons(pm_scene_material_at(s, (uint32_t)t, p, &scratch))) {
                    slot[j] = slot[j + 1] = SLOT_NONE; /* a cut-out, or a texel that keeps no photon */
                    continue;
                }
                for (int side = 0; side < 2; side++) {
                    float n_side[3] = {side ? -ng[0] : ng[0], side ? -ng[1] : ng[1], side ? -ng[2] : ng[2]}, ns[3];
                    uint64_t q = j + (uint64_t)side;
                    pm_scene_shading_normal(s, (uint32_t)t, p, n_side, ns);
                    memcpy(&out->pos[3 * q], p, sizeof p);
                    memcpy(&out->normal[3 * q], ns, sizeof ns);
                    out->area[3 * q] = out->area[3 * q + 1] = out->area[3 * q + 2] = w;
                    /* the geometric side normal, not the shading one: the ray leaves the triangle */
                    slot[q] = inside_test && faces_inside(rt, &ctx, p, n_side, (float)reach) ? SLOT_INSIDE : SLOT_KEPT;
                }
            }
        }
    }
    /* the kept slots moved down, in order */
    uint64_t k = 0;
    for (uint64_t i = 0; i < cap; i++) {
        if (slot[i] != SLOT_KEPT) {
            out->hidden += slot[i] == SLOT_INSIDE;
            continue;
        }
        if (k != i) {
            memcpy(&out->pos[3 * k], &out->pos[3 * i], 3 * sizeof(float));
            memcpy(&out->normal[3 * k], &out->normal[3 * i], 3 * sizeof(float));
            memcpy(&out->area[3 * k], &out->area[3 * i], 3 * sizeof(float));
        }
        k++;
    }
    out->n = k;
    free(first);
    free(slot);
    return PM_OK;
}
