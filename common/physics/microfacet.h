/* microfacet.h: the isotropic GGX (Trowbridge-Reitz) distribution of microfacet normals, Smith's
 * masking for it, and sampling of the normals visible from a direction (Heitz 2018, "Sampling the
 * GGX distribution of visible normals"). Used by the conductor, the rough glass and the plastic
 * coat of physics/bsdf.h.
 *
 * Everything is in a frame where the macro normal is +z (cos = z) or takes the cosines directly,
 * so that a SIMD mirror needs only dot products. alpha is the distribution's width in
 * [PM_MAT_ALPHA_DELTA, 1] (callers clamp). */
#ifndef PM_PHYSICS_MICROFACET_H
#define PM_PHYSICS_MICROFACET_H

/* D(h), 1/sr (per unit solid angle of h, projected: integral of D cos_h dw_h = 1), from the
 * cosine of h to the macro normal: alpha^2 / (pi (cos_h^2 (alpha^2 - 1) + 1)^2); 0 for
 * cos_h <= 0. */
float pm_ggx_d(float alpha, float cos_h);

/* Smith's Lambda for a direction at cosine cos to the macro normal:
 * (sqrt(1 + alpha^2 tan^2) - 1) / 2; 0 at cos = +-1, large (not Inf) at grazing. */
float pm_ggx_lambda(float alpha, float cos);

/* Masking G1 = 1 / (1 + Lambda(cos)) of one direction. */
float pm_ggx_g1(float alpha, float cos);

/* Height-correlated masking-shadowing G2 = 1 / (1 + Lambda(cos_i) + Lambda(cos_o)). */
float pm_ggx_g2(float alpha, float cos_i, float cos_o);

/* A microfacet normal h (unit, h.z > 0) from the normals visible from v (unit, local frame,
 * v.z > 0), from u1, u2 in [0, 1): density D_v(h) = G1(v) max(0, v.h) D(h) / v.z. */
void pm_ggx_sample_visible(float alpha, const float v[3], float u1, float u2, float h_out[3]);

/* The density D_v(h) of pm_ggx_sample_visible over solid angle of h, 1/sr, with cos_v = v.z,
 * cos_h = h.z and vh = v.h. */
float pm_ggx_visible_pdf(float alpha, float cos_v, float cos_h, float vh);

#endif
