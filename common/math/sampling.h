/* sampling.h: warps from uniform numbers in [0,1)^2 to the distributions the stages need.
 * Directions are in a local frame with +z along the surface normal unless said otherwise. */
#ifndef PM_SAMPLING_H
#define PM_SAMPLING_H

#include <math.h>
#include <stddef.h>

#include "math/vec.h"

#define PM_PI 3.14159265358979323846f

/* An orthonormal basis (t, b, n) around unit n, branch-free and continuous except at
 * n.z = -1 (Duff et al. 2017, "Building an orthonormal basis, revisited"). */
static inline void pm_onb(pm_vec3_t n, pm_vec3_t *t_out, pm_vec3_t *b_out)
{
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    *t_out = pm_v3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *b_out = pm_v3(b, sign + n.y * n.y * a, -n.y);
}

/* Local frame -> world: v.x t + v.y b + v.z n. */
static inline pm_vec3_t pm_onb_to_world(pm_vec3_t v, pm_vec3_t t, pm_vec3_t b, pm_vec3_t n)
{
    return pm_v3_add(pm_v3_add(pm_v3_scale(t, v.x), pm_v3_scale(b, v.y)), pm_v3_scale(n, v.z));
}

/* Concentric map of the square onto the unit disc (Shirley and Chiu 1997): keeps strata
 * compact, which the coherence of stratified secondary rays relies on. */
static inline void pm_sample_disc(float u1, float u2, float *x_out, float *y_out)
{
    float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f, r, phi;
    if (a == 0.0f && b == 0.0f) {
        *x_out = *y_out = 0.0f;
        return;
    }
    if (fabsf(a) > fabsf(b)) {
        r = a;
        phi = (PM_PI / 4.0f) * (b / a);
    } else {
        r = b;
        phi = (PM_PI / 2.0f) - (PM_PI / 4.0f) * (a / b);
    }
    *x_out = r * cosf(phi);
    *y_out = r * sinf(phi);
}

/* Cosine-weighted hemisphere around +z; pdf = cos(theta) / pi per steradian. */
static inline pm_vec3_t pm_sample_cosine_hemisphere(float u1, float u2)
{
    float x, y;
    pm_sample_disc(u1, u2, &x, &y);
    float z2 = 1.0f - x * x - y * y;
    return pm_v3(x, y, z2 > 0.0f ? sqrtf(z2) : 0.0f);
}

/* Uniform on the unit sphere; pdf = 1 / (4 pi). */
static inline pm_vec3_t pm_sample_sphere(float u1, float u2)
{
    float z = 1.0f - 2.0f * u1, r2 = 1.0f - z * z, phi = 2.0f * PM_PI * u2;
    float r = r2 > 0.0f ? sqrtf(r2) : 0.0f;
    return pm_v3(r * cosf(phi), r * sinf(phi), z);
}

/* Index of the interval of a cumulative distribution cdf[0..n) (ascending, cdf[n-1] = 1) that
 * holds u in [0, 1): the first i with u < cdf[i]. n >= 1. */
static inline size_t pm_cdf_pick(const double *cdf, size_t n, double u)
{
    size_t lo = 0, hi = n - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (u < cdf[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* Uniform point on a triangle by area, as barycentrics (b0, b1); b2 = 1 - b0 - b1. */
static inline void pm_sample_triangle(float u1, float u2, float *b0_out, float *b1_out)
{
    float s = sqrtf(u1);
    *b0_out = 1.0f - s;
    *b1_out = u2 * s;
}

/* Point (u1, u2) placed inside cell (cx, cy) of an nx by ny grid over [0,1)^2. */
static inline void pm_stratify(unsigned cx, unsigned cy, unsigned nx, unsigned ny, float u1, float u2, float *s1_out,
                               float *s2_out)
{
    *s1_out = ((float)cx + u1) / (float)nx;
    *s2_out = ((float)cy + u2) / (float)ny;
    /* (cx + u) / n can round up to 1.0 in float; keep the half-open interval. */
    if (*s1_out >= 1.0f)
        *s1_out = 0x1.fffffep-1f;
    if (*s2_out >= 1.0f)
        *s2_out = 0x1.fffffep-1f;
}

#endif
