/* shade.c: camera rays through pixels and the header keys of image-shaped outputs (shade.h);
 * the BRDF is render/transport.c, the lights render/light.c. */
#include "render/shade.h"

#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "math/sampling.h"
#include "math/vec.h"

/* a times the power of two that brings its largest component into [0.5, 1), when that
 * component lies outside [2^-60, 2^60]: there the squares of a float normalization would
 * underflow or overflow (an eye 1e-25 m from look_at, an up of 1e-30). Scaling by a power of
 * two is exact, so the direction is a's own; vectors inside the range are returned as they
 * are, so that ordinary cameras give the same bits as before. A zero vector stays zero. */
static pm_vec3_t exact_rescale(pm_vec3_t a)
{
    float big = fmaxf(fabsf(a.x), fmaxf(fabsf(a.y), fabsf(a.z)));
    if (!(big > 0.0f) || !isfinite(big) || (big >= 0x1p-60f && big <= 0x1p60f))
        return a;
    int e;
    frexpf(big, &e);
    return pm_v3(ldexpf(a.x, -e), ldexpf(a.y, -e), ldexpf(a.z, -e));
}

void pm_camera_setup(const pm_camera_t *cam, uint32_t w, uint32_t h, pm_camera_rays_t *c)
{
    float len = 0.0f;
    pm_vec3_t f = exact_rescale(pm_v3_sub(pm_v3_load(cam->look_at), pm_v3_load(cam->eye)));
    pm_v3_store(c->fwd, f);
    for (int k = 0; k < 3; k++) {
        c->eye[k] = cam->eye[k];
        len += c->fwd[k] * c->fwd[k];
    }
    for (int k = 0; k < 3; k++)
        c->fwd[k] /= sqrtf(len);
    f = pm_v3_load(c->fwd);
    pm_vec3_t r = pm_v3_normalize(exact_rescale(pm_v3_cross(f, exact_rescale(pm_v3_load(cam->up)))));
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

const char *const pm_pixel_names[] = {"box", "center", NULL};

void pm_pixel_offset(uint32_t k, uint32_t sx, uint32_t sy, float *jx_out, float *jy_out)
{
    /* Bit i of k adds the generator column v_i: 2^-(i+1) for the radical inverse; for Sobol's
     * second dimension (primitive polynomial x + 1) v_i = v_{i-1} xor v_{i-1} / 2. */
    uint32_t x = 0, y = 0;
    for (uint32_t vx = 1u << 31, vy = 1u << 31; k; k >>= 1, vx >>= 1, vy ^= vy >> 1)
        if (k & 1u)
            x ^= vx, y ^= vy;
    x ^= sx, y ^= sy;
    /* The top 24 bits: a float in [0, 1) that never rounds up to 1. */
    *jx_out = (float)(x >> 8) * 0x1p-24f;
    *jy_out = (float)(y >> 8) * 0x1p-24f;
}

pm_result_t pm_image_header_begin(pm_header_t *h, int argc, char **argv, const pm_scene_t *s, uint32_t w, uint32_t ht)
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
