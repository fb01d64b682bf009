/* envmap_load.c: the sky's lat-long map read from a file (scene.h, pm_envmap_load): OpenEXR or
 * Radiance RGBE (.hdr), one loader for both, within the sky map's byte budget. */
#include "render/scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/imgdecode.h"

pm_result_t pm_envmap_load(const char *path, uint64_t max_bytes, const float scale[3], pm_envmap_t *e)
{
    memset(e, 0, sizeof *e);
    /* The decoder's budget is the pixels' share (3 floats of PM_ENVMAP_BYTES_PER_PIXEL): the
     * tables pm_envmap_init builds take the rest. */
    char budget[96];
    snprintf(budget, sizeof budget, "image_budgets.sky_map_mib: %llu bytes for the pixels and their sampling tables",
             (unsigned long long)max_bytes);
    pm_img_limits_t lim = {PM_IMG_EXR | PM_IMG_HDR, max_bytes / PM_ENVMAP_BYTES_PER_PIXEL * 3 * sizeof(float), 3,
                           "sky map", budget};
    pm_img_t im;
    pm_result_t r = pm_img_load(path, &lim, &im);
    if (r != PM_OK)
        return r;
    float *rgb = im.f32;
    im.f32 = NULL;
    uint32_t w = im.w, h = im.h;
    pm_img_free(&im);
    for (size_t i = 0; i < 3 * (size_t)w * h; i++)
        rgb[i] *= scale[i % 3];
    return pm_envmap_init(e, w, h, rgb); /* its errors name the pixel; the caller names the file */
}
