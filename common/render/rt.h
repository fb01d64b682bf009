/* rt.h: the Embree 3 device and scene behind every ray pmtk casts.
 *
 * One device per process, created with an error callback so that Embree's own
 * messages reach the user; one static scene of the scene's triangles (geometry id 0,
 * primitive id = triangle index in pm_scene_t), or, when a mesh file is placed by several
 * entries, one geometry per placement with the repeated meshes built once and placed by
 * Embree instances; either way a hit names the triangle's index in pm_scene_t. Single rays go through pm_rt_intersect1
 * and pm_rt_occluded1 below; arrays of rays in packets through render/packet.h. */
#ifndef PM_RT_H
#define PM_RT_H

#include <embree3/rtcore.h>
#include <stdint.h>

#include "base/error.h"
#include "render/scene.h"

/* What the cut-out filter needs to name a hit's triangle (rt.c). */
typedef struct pm_rt_filter pm_rt_filter_t;

typedef struct {
    RTCDevice device;
    RTCScene scene;
    float epsilon; /* m: ray-origin offset that scales with the scene (no acne at 1e-4 or 1e5 scale) */
    /* Instanced scenes (a mesh file placed by several entries, pm_placement_t): one top-level
     * geometry per placement, geometry id = placement index; NULL and unused otherwise. */
    uint32_t *base;         /* per placement: its first triangle in pm_scene_t */
    float *nxf;             /* per placement: 3 x 3 cofactor matrix taking Embree's object-space Ng to the scene's */
    pm_rt_filter_t *filter; /* the cut-out filter's view of the scene, or NULL */
} pm_rt_t;

/* The scene's triangle index of a hit on top-level geometry geom_id (instance inst_id, or
 * RTC_INVALID_GEOMETRY_ID) and primitive prim_id; ng (Embree's unnormalized geometric normal,
 * object space for an instance) is turned into scene space in place. */
static inline uint32_t pm_rt_hit_triangle(const pm_rt_t *rt, unsigned geom_id, unsigned inst_id, unsigned prim_id,
                                          float ng[3])
{
    if (!rt->base)
        return prim_id;
    unsigned g = inst_id != RTC_INVALID_GEOMETRY_ID ? inst_id : geom_id;
    const float *m = rt->nxf + 9 * (size_t)g;
    float x = ng[0], y = ng[1], z = ng[2];
    for (int k = 0; k < 3; k++)
        ng[k] = m[3 * k] * x + m[3 * k + 1] * y + m[3 * k + 2] * z;
    return rt->base[g] + prim_id;
}

/* Builds the acceleration structure with `threads` build threads (--threads; 0 lets
 * Embree choose); quality "high" spends more build time for faster rays (many-ray
 * stages), "medium" is Embree's default. A scene with cut-out alpha (map_d) gets a filter
 * that rejects cut-out hits for every ray cast through rt; s must outlive rt. */
pm_result_t pm_rt_create(const pm_scene_t *s, int high_quality, int threads, pm_rt_t *out);
void pm_rt_destroy(pm_rt_t *rt);

#define PM_RAY_MISS 0xffffffffu /* the triangle of a ray that hit nothing */

/* One ray (o, d) over [tnear, tfar] (m along d; d need not be unit) for its closest hit: the
 * triangle index, or PM_RAY_MISS. *t_out becomes the hit distance (tfar when it missed);
 * ng_out, unless NULL, Embree's geometric normal of the hit, unnormalized ((v1 - v0) x (v2 -
 * v0); zero when it missed). ctx is the caller's, one per thread. */
static inline uint32_t pm_rt_intersect1(const pm_rt_t *rt, struct RTCIntersectContext *ctx, const float o[3],
                                        const float d[3], float tnear, float tfar, float *t_out, float ng_out[3])
{
    struct RTCRayHit rh;
    rh.ray.org_x = o[0], rh.ray.org_y = o[1], rh.ray.org_z = o[2], rh.ray.tnear = tnear;
    rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2], rh.ray.time = 0.0f;
    rh.ray.tfar = tfar, rh.ray.mask = 0xffffffffu, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.Ng_x = rh.hit.Ng_y = rh.hit.Ng_z = 0.0f;
    rtcIntersect1(rt->scene, ctx, &rh);
    *t_out = rh.ray.tfar;
    float ng[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
    uint32_t tri = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID
                       ? pm_rt_hit_triangle(rt, rh.hit.geomID, rh.hit.instID[0], rh.hit.primID, ng)
                       : PM_RAY_MISS;
    if (ng_out)
        ng_out[0] = ng[0], ng_out[1] = ng[1], ng_out[2] = ng[2];
    return tri;
}

/* Shadow ray (o, d) over [tnear, tfar]: 1 when anything blocks it. */
static inline int pm_rt_occluded1(const pm_rt_t *rt, struct RTCIntersectContext *ctx, const float o[3],
                                  const float d[3], float tnear, float tfar)
{
    struct RTCRay ray = {.org_x = o[0],
                         .org_y = o[1],
                         .org_z = o[2],
                         .tnear = tnear,
                         .dir_x = d[0],
                         .dir_y = d[1],
                         .dir_z = d[2],
                         .time = 0.0f,
                         .tfar = tfar,
                         .mask = 0xffffffffu,
                         .id = 0,
                         .flags = 0};
    rtcOccluded1(rt->scene, ctx, &ray);
    return ray.tfar < 0.0f; /* Embree sets tfar to -inf on a blocked ray */
}

/* The first Embree error raised on the calling thread since the last call (Embree keeps one
 * per thread and device), as a pm_error_set message "embree failed WHAT: ..." with WHAT
 * formatted from fmt only then; PM_OK when none. Workers call it after their rays and hand a
 * failure to a pm_error_slot_t. */
pm_result_t pm_rt_thread_error(const pm_rt_t *rt, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#endif
