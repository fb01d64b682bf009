/* packet.c: Embree packet tracing of structure-of-arrays ray buffers (see packet.h).
 * The 4-, 8- and 16-lane versions differ only in the Embree types and calls, so one
 * macro writes all three; a full packet is copied with memcpy, a partial last packet
 * lane by lane with its idle lanes masked off. */
#include "render/packet.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"

pm_result_t pm_rays_reserve(pm_rays_t *r, size_t cap)
{
    if (cap <= r->cap)
        return PM_OK;
    size_t want = r->cap ? r->cap : 256;
    while (want < cap)
        want *= 2;
    float **f[] = {&r->ox, &r->oy, &r->oz, &r->dx, &r->dy, &r->dz, &r->tnear, &r->tfar, &r->ngx, &r->ngy, &r->ngz};
    size_t padded = (want + 15) & ~(size_t)15; /* whole packets: a lane past n is never out of bounds */
    for (size_t k = 0; k < sizeof f / sizeof f[0]; k++) {
        float *p = pm_alloc_aligned(padded * sizeof(float));
        if (!p)
            return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu rays", want);
        if (*f[k] && r->n)
            memcpy(p, *f[k], r->n * sizeof(float));
        pm_free_aligned(*f[k]);
        *f[k] = p;
    }
    uint32_t *p = pm_alloc_aligned(padded * sizeof(uint32_t));
    if (!p)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu rays", want);
    if (r->prim && r->n)
        memcpy(p, r->prim, r->n * sizeof(uint32_t));
    pm_free_aligned(r->prim);
    r->prim = p;
    r->cap = want;
    return PM_OK;
}

void pm_rays_free(pm_rays_t *r)
{
    pm_free_aligned(r->ox), pm_free_aligned(r->oy), pm_free_aligned(r->oz);
    pm_free_aligned(r->dx), pm_free_aligned(r->dy), pm_free_aligned(r->dz);
    pm_free_aligned(r->tnear), pm_free_aligned(r->tfar);
    pm_free_aligned(r->ngx), pm_free_aligned(r->ngy), pm_free_aligned(r->ngz), pm_free_aligned(r->prim);
    memset(r, 0, sizeof *r);
}

int pm_packet_width(const pm_rt_t *rt, pm_isa_t isa)
{
    int w = pm_isa_width(isa);
    /* Embree answers 1 when the packet size runs natively in the ISA it picked at run time. */
    if (w >= 16 && !rtcGetDeviceProperty(rt->device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED))
        w = 8;
    if (w >= 8 && !rtcGetDeviceProperty(rt->device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED))
        w = 4;
    if (w >= 4 && !rtcGetDeviceProperty(rt->device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED))
        w = 1;
    return w;
}

/* Lane k of the packet reads ray b + k; the idle lanes of a partial packet repeat ray b so
 * that they hold valid numbers, and the valid mask turns them off. */
#define PM_FILL_RAY(P, W, r, b, n)                                                                                     \
    do {                                                                                                               \
        if ((n) == (W)) {                                                                                              \
            memcpy((P).org_x, (r)->ox + (b), sizeof(float) * (W));                                                     \
            memcpy((P).org_y, (r)->oy + (b), sizeof(float) * (W));                                                     \
            memcpy((P).org_z, (r)->oz + (b), sizeof(float) * (W));                                                     \
            memcpy((P).dir_x, (r)->dx + (b), sizeof(float) * (W));                                                     \
            memcpy((P).dir_y, (r)->dy + (b), sizeof(float) * (W));                                                     \
            memcpy((P).dir_z, (r)->dz + (b), sizeof(float) * (W));                                                     \
            memcpy((P).tnear, (r)->tnear + (b), sizeof(float) * (W));                                                  \
            memcpy((P).tfar, (r)->tfar + (b), sizeof(float) * (W));                                                    \
        } else {                                                                                                       \
            for (unsigned k = 0; k < (W); k++) {                                                                       \
                size_t i = (b) + (k < (n) ? k : 0);                                                                    \
                (P).org_x[k] = (r)->ox[i], (P).org_y[k] = (r)->oy[i], (P).org_z[k] = (r)->oz[i];                       \
                (P).dir_x[k] = (r)->dx[i], (P).dir_y[k] = (r)->dy[i], (P).dir_z[k] = (r)->dz[i];                       \
                (P).tnear[k] = (r)->tnear[i], (P).tfar[k] = (r)->tfar[i];                                              \
            }                                                                                                          \
        }                                                                                                              \
        for (unsigned k = 0; k < (W); k++) {                                                                           \
            (P).time[k] = 0.0f, (P).mask[k] = 0xffffffffu, (P).id[k] = k, (P).flags[k] = 0;                            \
            valid[k] = k < (n) ? -1 : 0;                                                                               \
        }                                                                                                              \
    } while (0)

#define PM_DEFINE_PACKETS(W)                                                                                           \
    static void intersect##W(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t b, unsigned n)   \
    {                                                                                                                  \
        struct RTCRayHit##W rh;                                                                                        \
        _Alignas(64) int valid[W];                                                                                     \
        PM_FILL_RAY(rh.ray, W, r, b, n);                                                                               \
        for (unsigned k = 0; k < (W); k++)                                                                             \
            rh.hit.geomID[k] = rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;                                          \
        rtcIntersect##W(valid, rt->scene, ctx, &rh);                                                                   \
        for (unsigned k = 0; k < n; k++) {                                                                             \
            size_t i = b + k;                                                                                          \
            int hit = rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;                                                     \
            float ng[3] = {rh.hit.Ng_x[k], rh.hit.Ng_y[k], rh.hit.Ng_z[k]};                                            \
            r->tfar[i] = rh.ray.tfar[k];                                                                               \
            r->prim[i] = hit ? pm_rt_hit_triangle(rt, rh.hit.geomID[k], rh.hit.instID[0][k], rh.hit.primID[k], ng)     \
                             : PM_RAY_MISS;                                                                            \
            r->ngx[i] = ng[0], r->ngy[i] = ng[1], r->ngz[i] = ng[2];                                                   \
        }                                                                                                              \
    }                                                                                                                  \
    static void occluded##W(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t b, unsigned n)    \
    {                                                                                                                  \
        struct RTCRay##W ray;                                                                                          \
        _Alignas(64) int valid[W];                                                                                     \
        PM_FILL_RAY(ray, W, r, b, n);                                                                                  \
        rtcOccluded##W(valid, rt->scene, ctx, &ray);                                                                   \
        memcpy(r->tfar + b, ray.tfar, sizeof(float) * n);                                                              \
    }

PM_DEFINE_PACKETS(4)
PM_DEFINE_PACKETS(8)
PM_DEFINE_PACKETS(16)

/* Width 1: a lane of the arrays through the single-ray wrappers of rt.h. */
static void intersect1(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t i)
{
    float o[3] = {r->ox[i], r->oy[i], r->oz[i]}, d[3] = {r->dx[i], r->dy[i], r->dz[i]}, ng[3];
    r->prim[i] = pm_rt_intersect1(rt, ctx, o, d, r->tnear[i], r->tfar[i], &r->tfar[i], ng);
    r->ngx[i] = ng[0], r->ngy[i] = ng[1], r->ngz[i] = ng[2];
}

static void occluded1(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t i)
{
    float o[3] = {r->ox[i], r->oy[i], r->oz[i]}, d[3] = {r->dx[i], r->dy[i], r->dz[i]};
    if (pm_rt_occluded1(rt, ctx, o, d, r->tnear[i], r->tfar[i]))
        r->tfar[i] = -INFINITY;
}

static void context(struct RTCIntersectContext *ctx, int coherent)
{
    rtcInitIntersectContext(ctx);
    ctx->flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}

typedef void (*packet_fn)(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t b, unsigned n);

/* Single rays as a "packet" of one, so that one loop serves every width. */
static void intersect1p(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t b, unsigned n)
{
    (void)n;
    intersect1(rt, ctx, r, b);
}
static void occluded1p(const pm_rt_t *rt, struct RTCIntersectContext *ctx, pm_rays_t *r, size_t b, unsigned n)
{
    (void)n;
    occluded1(rt, ctx, r, b);
}

/* Traces r->n rays in packets of `width` (1, 4, 8 or 16) with fn[0..3], one per width. */
static void trace_packets(const pm_rt_t *rt, int width, int coherent, pm_rays_t *r, const packet_fn fn[4])
{
    struct RTCIntersectContext ctx;
    context(&ctx, coherent);
    unsigned w = width == 16 || width == 8 || width == 4 ? (unsigned)width : 1u;
    packet_fn f = fn[w == 16 ? 3 : w == 8 ? 2 : w == 4 ? 1 : 0];
    size_t n = r->n;
    for (size_t b = 0; b < n; b += w)
        f(rt, &ctx, r, b, (unsigned)(n - b < w ? n - b : w));
}

void pm_rays_intersect(const pm_rt_t *rt, int width, int coherent, pm_rays_t *r)
{
    static const packet_fn fn[4] = {intersect1p, intersect4, intersect8, intersect16};
    trace_packets(rt, width, coherent, r, fn);
}

void pm_rays_occluded(const pm_rt_t *rt, int width, int coherent, pm_rays_t *r)
{
    static const packet_fn fn[4] = {occluded1p, occluded4, occluded8, occluded16};
    trace_packets(rt, width, coherent, r, fn);
}
