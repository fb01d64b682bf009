/* aov.c: the denoiser's surface buffers (render/aov.h): each row's primary rays cast as one
 * coherent packet batch, and at each hit the material's directional albedo toward the eye
 * (render/transport.h's pm_bsdf_albedo_wo, textures included), the shading normal facing the
 * eye and the distance, averaged over the pixel's rays. */
#include "render/aov.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "formats/formats.h"
#include "math/rng.h"
#include "physics/bsdf.h"
#include "render/packet.h"
#include "render/shade.h"

pm_result_t pm_aov_trace(const pm_scene_t *s, const pm_rt_t *rt, uint32_t w, uint32_t h, uint32_t primary, int pixel,
                         uint64_t seed, int threads, float *out)
{
    pm_camera_rays_t cam;
    pm_camera_setup(&s->camera, w, h, &cam);
    pm_shade_geom_t geom;
    pm_result_t r = pm_shade_geom_init(s, &geom);
    if (r != PM_OK)
        return r;
    int failed = 0;
    float inv_p = 1.0f / (float)primary;
#pragma omp parallel num_threads(threads) reduction(| : failed)
    {
        pm_rays_t rays;
        memset(&rays, 0, sizeof rays);
        failed = pm_rays_reserve(&rays, (size_t)w * primary) != PM_OK;
#pragma omp for schedule(dynamic, 1)
        for (uint32_t y = 0; y < h; y++) {
            if (failed)
                continue;
            rays.n = 0;
            for (uint32_t x = 0; x < w; x++) {
                pm_rng_t jr;
                pm_rng_init(&jr, seed, 4 * ((uint64_t)y * w + x)); /* the eye tracer's jitter stream */
                uint32_t sx = pm_rng_u32(&jr), sy = pm_rng_u32(&jr);
                for (uint32_t j = 0; j < primary; j++) {
                    float jx = 0.5f, jy = 0.5f, d[3];
                    if (pixel == PM_PIXEL_BOX)
                        pm_pixel_offset(j, sx, sy, &jx, &jy);
                    pm_camera_dir(&cam, (float)x + jx, (float)y + jy, d);
                    pm_rays_push(&rays, cam.eye, d, 0.0f, INFINITY);
                }
            }
            pm_rays_intersect(rt, 1, 1, &rays);
            for (uint32_t x = 0; x < w; x++) {
                double acc[PM_AOV_FLOATS] = {0};
                for (uint32_t j = 0; j < primary; j++) {
                    size_t i = (size_t)x * primary + j;
                    uint32_t tri = rays.prim[i];
                    if (tri == PM_RAY_MISS)
                        continue;
                    float d[3] = {rays.dx[i], rays.dy[i], rays.dz[i]}, t = rays.tfar[i], p[3], wo[3], gn[3], n[3], a[3];
                    const float *ng = geom.tri_n + 3 * (size_t)tri;
                    for (int k = 0; k < 3; k++)
                        p[k] = cam.eye[k] + t * d[k], wo[k] = -d[k];
                    float side = pm_dot3(ng, wo) >= 0.0f ? 1.0f : -1.0f; /* face the viewer */
                    for (int k = 0; k < 3; k++)
                        gn[k] = side * ng[k];
                    pm_material_t scratch;
                    const pm_material_t *m = pm_scene_material_at(s, tri, p, &scratch);
                    pm_scene_shading_normal(s, tri, p, gn, n);
                    pm_bsdf_albedo_wo(m, n, wo, a);
                    for (int k = 0; k < 3; k++)
                        acc[k] += fmin(fmax((double)a[k], 0.0), 1.0), acc[3 + k] += n[k];
                    acc[6] += (double)t * sqrt((double)pm_dot3(d, d));
                }
                float *o = out + (size_t)PM_AOV_FLOATS * ((size_t)y * w + x);
                for (int k = 0; k < PM_AOV_FLOATS; k++)
                    o[k] = (float)(acc[k] * inv_p);
            }
        }
        pm_rays_free(&rays);
    }
    pm_shade_geom_free(&geom);
    if (failed)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the AOV rays of a %ux%u image", w, h);
    return PM_OK;
}

pm_result_t pm_aov_header(pm_header_t *hd, int argc, char **argv, const pm_scene_t *s, uint32_t w, uint32_t h,
                          uint32_t primary, int pixel, uint64_t seed)
{
    hd->count = (uint64_t)w * h;
    hd->channels = pm_schema_required(&pm_aov_schema); /* albedo, normal, depth: all of them */
    pm_result_t r = pm_image_header_begin(hd, argc, argv, s, w, h);
    if (r == PM_OK)
        r = pm_header_set(hd, "primary", "%u", primary);
    if (r == PM_OK)
        r = pm_header_set(hd, "pixel", "%s", pm_pixel_names[pixel]);
    if (r == PM_OK)
        r = pm_header_set(hd, "seed", "%" PRIu64, seed);
    return r;
}
