/* packet.h: casting arrays of rays through Embree in packets of 1, 4, 8 or 16 lanes.
 *
 * A stage fills a pm_rays_t (structure of arrays: consecutive rays become the lanes of one
 * packet, so the caller decides coherence by the order it pushes them) and traces the whole
 * array with rtcIntersect1/4/8/16 or rtcOccluded1/4/8/16. The width comes from the CPU
 * (common/base/cpu.h), what the Embree build runs natively, and --isa. Not thread-safe per array:
 * each thread owns its pm_rays_t; the pm_rt_t is shared read-only. */
#ifndef PM_PACKET_H
#define PM_PACKET_H

#include <stddef.h>
#include <stdint.h>

#include "base/cpu.h"
#include "base/error.h"
#include "render/rt.h"

typedef struct {
    size_t n, cap;          /* rays held, rays allocated */
    float *ox, *oy, *oz;    /* in: origin, m */
    float *dx, *dy, *dz;    /* in: direction (unit for the callers of pmtk) */
    float *tnear;           /* in: m along dir */
    float *tfar;            /* in: m; out: hit distance (intersect), -inf when occluded */
    float *ngx, *ngy, *ngz; /* out (intersect): Embree's unnormalized geometric normal */
    uint32_t *prim;         /* out (intersect): triangle index, PM_RAY_MISS (rt.h) for none */
} pm_rays_t;

/* Makes room for cap rays (keeps the first n); arrays padded to whole 16-lane packets. */
pm_result_t pm_rays_reserve(pm_rays_t *r, size_t cap);
void pm_rays_free(pm_rays_t *r);

/* Appends one ray; the caller reserved room. */
static inline void pm_rays_push(pm_rays_t *r, const float o[3], const float d[3], float tnear, float tfar)
{
    size_t i = r->n++;
    r->ox[i] = o[0], r->oy[i] = o[1], r->oz[i] = o[2];
    r->dx[i] = d[0], r->dy[i] = d[1], r->dz[i] = d[2];
    r->tnear[i] = tnear, r->tfar[i] = tfar;
}

/* Packet width for an ISA (1, 4, 8, 16), narrowed to the widest packet the Embree device
 * traces natively (RTC_DEVICE_PROPERTY_NATIVE_RAYn_SUPPORTED): a packet Embree only
 * emulates is slower than the narrower native one. */
int pm_packet_width(const pm_rt_t *rt, pm_isa_t isa);

/* Traces rays [0, n) for their closest hit, `width` lanes at a time. coherent: the rays
 * share origin and direction roughly (camera rays), a hint to Embree. */
void pm_rays_intersect(const pm_rt_t *rt, int width, int coherent, pm_rays_t *r);

/* Shadow rays: tfar becomes -inf for every ray blocked in [tnear, tfar]. */
void pm_rays_occluded(const pm_rt_t *rt, int width, int coherent, pm_rays_t *r);

#endif
