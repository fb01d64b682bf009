/* microfacet.c: GGX's distribution, Smith's masking and visible-normal sampling
 * (microfacet.h). */
#include "physics/microfacet.h"

#include <math.h>

#include "math/sampling.h"

float pm_ggx_d(float alpha, float cos_h)
{
    if (!(cos_h > 0.0f))
        return 0.0f;
    float a2 = alpha * alpha, c2 = fminf(cos_h * cos_h, 1.0f), t = c2 * (a2 - 1.0f) + 1.0f;
    /* t >= a2 > 0 for alpha > 0: the peak is 1 / (pi a2). */
    return a2 / (PM_PI * t * t);
}

float pm_ggx_lambda(float alpha, float cos)
{
    /* (sqrt(1 + a2 tan^2) - 1) / 2 without the cancellation of small a2: with s = sqrt(c^2 +
     * a2 (1 - c^2)), Lambda = (s - c) / (2 c) = a2 (1 - c^2) / (2 c (s + c)). c is kept above
     * 1e-7 so that a grazing direction gives a large finite Lambda (G about 0), not Inf. */
    float c = fminf(fmaxf(fabsf(cos), 1e-7f), 1.0f), a2 = alpha * alpha, s2 = 1.0f - c * c;
    float s = sqrtf(c * c + a2 * s2);
    return a2 * s2 / (2.0f * c * (s + c));
}

float pm_ggx_g1(float alpha, float cos) { return 1.0f / (1.0f + pm_ggx_lambda(alpha, cos)); }

float pm_ggx_g2(float alpha, float cos_i, float cos_o)
{
    return 1.0f / (1.0f + pm_ggx_lambda(alpha, cos_i) + pm_ggx_lambda(alpha, cos_o));
}

void pm_ggx_sample_visible(float alpha, const float v[3], float u1, float u2, float h_out[3])
{
    /* Stretch v into the configuration of width 1, where the visible normals are those of a
     * hemisphere seen from v: a disc's point, its second coordinate squeezed onto the part of the
     * disc that v sees unoccluded, lifted onto the hemisphere and unstretched (Heitz 2018). */
    pm_vec3_t vh = pm_v3_normalize(pm_v3(alpha * v[0], alpha * v[1], v[2]));
    float l2 = vh.x * vh.x + vh.y * vh.y;
    pm_vec3_t t1 = l2 > 0.0f ? pm_v3_scale(pm_v3(-vh.y, vh.x, 0.0f), 1.0f / sqrtf(l2)) : pm_v3(1.0f, 0.0f, 0.0f);
    pm_vec3_t t2 = pm_v3_cross(vh, t1);
    float r = sqrtf(u1), phi = 2.0f * PM_PI * u2, p1 = r * cosf(phi), p2 = r * sinf(phi);
    float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrtf(fmaxf(0.0f, 1.0f - p1 * p1)) + s * p2;
    float p3 = sqrtf(fmaxf(0.0f, 1.0f - p1 * p1 - p2 * p2));
    pm_vec3_t nh = pm_v3_add(pm_v3_add(pm_v3_scale(t1, p1), pm_v3_scale(t2, p2)), pm_v3_scale(vh, p3));
    pm_vec3_t h = pm_v3_normalize(pm_v3(alpha * nh.x, alpha * nh.y, fmaxf(1e-7f, nh.z)));
    pm_v3_store(h_out, h);
}

float pm_ggx_visible_pdf(float alpha, float cos_v, float cos_h, float vh)
{
    if (!(cos_v > 0.0f) || !(vh > 0.0f))
        return 0.0f;
    return pm_ggx_g1(alpha, cos_v) * vh * pm_ggx_d(alpha, cos_h) / cos_v;
}
