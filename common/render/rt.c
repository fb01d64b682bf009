/* rt.c: the Embree device and scene every ray is cast into (rt.h), built once per stage from
 * the scene's triangles; the single-ray wrappers are inline in rt.h. */
#include "render/rt.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct pm_rt_filter {
    const pm_scene_t *s;
    const uint32_t *base; /* per placement: its first triangle (instanced scenes), or NULL */
};

/* Embree reports errors through this callback, possibly from its own worker threads, so
 * the first one goes to a process-wide buffer (one device is built at a time). */
static char rt_error[512];
static enum RTCError rt_code;

static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    (void)user;
    if (rt_code != RTC_ERROR_NONE)
        return;
    rt_code = code;
    snprintf(rt_error, sizeof rt_error, "embree error %d: %s", (int)code, str ? str : "(no message)");
}

static pm_result_t fail(pm_rt_t *rt, const char *what)
{
    pm_result_t r = pm_error_set(rt_code == RTC_ERROR_OUT_OF_MEMORY ? PM_ERR_NOMEM : PM_ERR_INTERNAL, "cannot %s: %s",
                                 what, rt_error[0] ? rt_error : "unknown embree error");
    pm_rt_destroy(rt);
    return r;
}

/* Cut-out alpha (MTL map_d): Embree calls this for every candidate hit of every ray, closest-hit
 * and shadow, single and packet, on the geometry of a scene that has some map_d; a hit where
 * the alpha is below 0.5 is rejected and the ray goes on. Scenes without map_d install none. */
static void alpha_filter(const struct RTCFilterFunctionNArguments *args)
{
    const pm_rt_filter_t *f = args->geometryUserPtr;
    const pm_scene_t *s = f->s;
    unsigned n = args->N;
    /* RTCHitN is N lanes of each field in turn: Ng_x, Ng_y, Ng_z, u, v, primID, ... (the
     * C++ accessors of rtcore_ray.h spelled out for C) */
    const float *h = (const float *)args->hit;
    const unsigned *hu = (const unsigned *)args->hit;
    for (unsigned i = 0; i < n; i++) {
        if (args->valid[i] != -1)
            continue;
        uint32_t tri = hu[5 * n + i];
        if (f->base) { /* the placement: the instance being traversed, else the geometry itself */
            unsigned inst = args->context->instID[0];
            tri += f->base[inst != RTC_INVALID_GEOMETRY_ID ? inst : hu[6 * n + i]];
        }
        if (pm_scene_cut_out(s, tri, h[3 * n + i], h[4 * n + i]))
            args->valid[i] = 0;
    }
}

/* A triangle geometry of nverts vertices v (m or mesh units) and the ntris triangles t whose
 * indices count from vert0, with the cut-out filter when the scene has map_d; NULL on failure. */
static RTCGeometry triangles(const pm_rt_t *rt, const float *v, size_t nverts, const uint32_t *t, size_t ntris,
                             uint32_t vert0)
{
    RTCGeometry g = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g)
        return NULL;
    /* Embree reads vertex buffers 16 bytes at a time: one spare vertex of padding. */
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nverts + 1);
    unsigned *tb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), ntris);
    if (!vb || !tb) {
        rtcReleaseGeometry(g);
        return NULL;
    }
    memcpy(vb, v, 3 * nverts * sizeof(float));
    memset(vb + 3 * nverts, 0, 3 * sizeof(float));
    for (size_t i = 0; i < 3 * ntris; i++)
        tb[i] = t[i] - vert0;
    if (rt->filter) {
        rtcSetGeometryUserData(g, rt->filter);
        rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
        rtcSetGeometryOccludedFilterFunction(g, alpha_filter);
    }
    rtcCommitGeometry(g);
    return g;
}

/* The instanced build: a prototype scene per repeated mesh (its vertices in mesh units), an
 * instance of it per placement, and the placements of meshes used once as plain geometry; the
 * top-level geometry id is the placement's index. */
static pm_result_t build_instanced(const pm_scene_t *s, int high_quality, pm_rt_t *out)
{
    size_t np = s->nplacements;
    RTCScene *protos = calloc(np ? np : 1, sizeof *protos);
    out->base = malloc((np ? np : 1) * sizeof *out->base);
    out->nxf = malloc((np ? np : 1) * 9 * sizeof *out->nxf);
    if (!protos || !out->base || !out->nxf) {
        free(protos);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu mesh placements", np);
    }
    if (out->filter)
        out->filter->base = out->base;
    const char *failed = NULL;
    for (size_t i = 0; i < np && !failed; i++) {
        const pm_placement_t *p = &s->placements[i];
        if (p->proto != (int32_t)i)
            continue;
        protos[i] = rtcNewScene(out->device);
        RTCGeometry g = protos[i] ? triangles(out, s->local_verts + 3 * (size_t)p->local0, p->nverts,
                                              s->tris + 3 * (size_t)p->tri0, p->ntris, p->vert0)
                                  : NULL;
        if (!g) {
            failed = "build an instanced mesh";
            break;
        }
        rtcSetSceneBuildQuality(protos[i], high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
        rtcSetSceneFlags(protos[i], RTC_SCENE_FLAG_ROBUST);
        rtcAttachGeometryByID(protos[i], g, 0);
        rtcReleaseGeometry(g);
        rtcCommitScene(protos[i]);
    }
    for (size_t i = 0; i < np && !failed; i++) {
        const pm_placement_t *p = &s->placements[i];
        float *m = out->nxf + 9 * i;
        out->base[i] = p->tri0;
        if (p->ntris == 0)
            continue;
        RTCGeometry g;
        if (p->proto >= 0) {
            g = rtcNewGeometry(out->device, RTC_GEOMETRY_TYPE_INSTANCE);
            if (g) {
                rtcSetGeometryInstancedScene(g, protos[p->proto]);
                rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, p->xf);
                rtcCommitGeometry(g);
            }
            /* (M a) x (M b) = cof(M) (a x b): the cofactor matrix takes the object-space
             * normal to exactly the normal of the placed triangle, mirrors included */
            const float *x = p->xf;
            m[0] = x[5] * x[10] - x[6] * x[9], m[1] = x[6] * x[8] - x[4] * x[10], m[2] = x[4] * x[9] - x[5] * x[8];
            m[3] = x[2] * x[9] - x[1] * x[10], m[4] = x[0] * x[10] - x[2] * x[8], m[5] = x[1] * x[8] - x[0] * x[9];
            m[6] = x[1] * x[6] - x[2] * x[5], m[7] = x[2] * x[4] - x[0] * x[6], m[8] = x[0] * x[5] - x[1] * x[4];
        } else {
            g = triangles(out, s->verts + 3 * (size_t)p->vert0, p->nverts, s->tris + 3 * (size_t)p->tri0, p->ntris,
                          p->vert0);
            memset(m, 0, 9 * sizeof *m);
            m[0] = m[4] = m[8] = 1.0f;
        }
        if (!g) {
            failed = "create mesh geometry";
            break;
        }
        rtcAttachGeometryByID(out->scene, g, (unsigned)i);
        rtcReleaseGeometry(g);
    }
    for (size_t i = 0; i < np; i++)
        if (protos[i])
            rtcReleaseScene(protos[i]); /* the instances hold them now */
    free(protos);
    return failed ? fail(out, failed) : PM_OK;
}

pm_result_t pm_rt_create(const pm_scene_t *s, int high_quality, int threads, pm_rt_t *out)
{
    memset(out, 0, sizeof *out);
    rt_error[0] = '\0';
    rt_code = RTC_ERROR_NONE;
    char config[64];
    snprintf(config, sizeof config, "threads=%d", threads > 0 ? threads : 0); /* 0: Embree's own choice */
    out->device = rtcNewDevice(config);
    if (!out->device) {
        /* Out of memory or a CPU Embree cannot run on is the machine's, not a bug: another
         * node or a later run may succeed (exit 3). */
        enum RTCError e = rtcGetDeviceError(NULL);
        return pm_error_set(e == RTC_ERROR_OUT_OF_MEMORY     ? PM_ERR_NOMEM
                            : e == RTC_ERROR_UNSUPPORTED_CPU ? PM_ERR_IO
                                                             : PM_ERR_INTERNAL,
                            "cannot create the embree device: error %d", (int)e);
    }
    rtcSetDeviceErrorFunction(out->device, on_embree_error, NULL);
    out->scene = rtcNewScene(out->device);
    if (!out->scene)
        return fail(out, "create an embree scene");
    rtcSetSceneBuildQuality(out->scene, high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
    /* Robust traversal and intersection: without it a ray through the shared edge of two
     * triangles can slip between them, and in a closed room a photon or camera ray
     * escapes (seen on rays along a cube's diagonal, docs/extreme-cases.md). */
    rtcSetSceneFlags(out->scene, RTC_SCENE_FLAG_ROBUST);
    if (s->any_alpha) {
        if (!(out->filter = calloc(1, sizeof *out->filter))) {
            pm_rt_destroy(out);
            return pm_error_set(PM_ERR_NOMEM, "out of memory");
        }
        out->filter->s = s;
    }
    if (s->local_verts) {
        pm_result_t r = build_instanced(s, high_quality, out);
        if (r != PM_OK)
            return r;
    } else if (s->ntris) {
        RTCGeometry g = rtcNewGeometry(out->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (!g)
            return fail(out, "create triangle geometry");
        /* Embree reads vertex buffers 16 bytes at a time: one spare vertex of padding. */
        float *v =
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), s->nverts + 1);
        unsigned *t =
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), s->ntris);
        if (!v || !t) {
            rtcReleaseGeometry(g);
            return fail(out, "allocate geometry buffers");
        }
        memcpy(v, s->verts, 3 * s->nverts * sizeof(float));
        memset(v + 3 * s->nverts, 0, 3 * sizeof(float));
        memcpy(t, s->tris, 3 * s->ntris * sizeof(unsigned));
        if (out->filter) {
            rtcSetGeometryUserData(g, out->filter);
            rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
            rtcSetGeometryOccludedFilterFunction(g, alpha_filter);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(out->scene, g, 0);
        rtcReleaseGeometry(g); /* the scene holds it now */
    }
    rtcCommitScene(out->scene);
    if (rtcGetDeviceError(out->device) != RTC_ERROR_NONE)
        return fail(out, "build the embree scene");
    /* Offsets relative to the scene's size: float spacing at the largest coordinate,
     * times a margin, so a ray leaving a surface does not find that surface again. */
    float ext = 0.0f;
    for (int k = 0; k < 6; k++)
        ext = fmaxf(ext, fabsf(s->bounds[k]));
    out->epsilon = fmaxf(ext, 1e-30f) * 0x1p-17f;
    return PM_OK;
}

void pm_rt_destroy(pm_rt_t *rt)
{
    if (rt->scene)
        rtcReleaseScene(rt->scene);
    if (rt->device)
        rtcReleaseDevice(rt->device);
    free(rt->base);
    free(rt->nxf);
    free(rt->filter);
    memset(rt, 0, sizeof *rt);
}

pm_result_t pm_rt_thread_error(const pm_rt_t *rt, const char *fmt, ...)
{
    enum RTCError e = rtcGetDeviceError(rt->device);
    if (e == RTC_ERROR_NONE)
        return PM_OK;
    char what[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    static const char *const names[] = {"none",          "unknown error",   "invalid argument", "invalid operation",
                                        "out of memory", "unsupported cpu", "cancelled"};
    const char *name = (unsigned)e < sizeof names / sizeof names[0] ? names[e] : "unknown error";
    return pm_error_set(e == RTC_ERROR_OUT_OF_MEMORY ? PM_ERR_NOMEM : PM_ERR_INTERNAL,
                        "embree failed %s: %s (error %d)", what, name, (int)e);
}
