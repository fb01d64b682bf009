/* fresnel.h: the Fresnel reflectances of the material kinds (physics/bsdf.h): a smooth dielectric
 * boundary, a conductor of complex index per channel, Schlick's approximation from a colour at
 * normal incidence, and the hemispherical average the plastic's base needs. Cosines are taken
 * as |cos| clamped to 1; every result lies in [0, 1] and is never NaN for the ranges given. */
#ifndef PM_PHYSICS_FRESNEL_H
#define PM_PHYSICS_FRESNEL_H

/* Index ratios beyond these are taken as these: their squares stay normal floats, and F and the
 * directions are those of the limit to within float precision. */
#define PM_ETA_MIN 1e-6f
#define PM_ETA_MAX 1e6f

/* Unpolarized reflectance of a smooth dielectric boundary, the mean of the s and p reflectances,
 * for light arriving at cosine cos_i to the normal on its own side, with eta = n_t / n_i the index
 * beyond the boundary over the index on that side (> 0). 1 under total internal reflection
 * (sin_t >= 1) and at cos_i = 0; 0 for eta = 1 up to rounding; 1 for eta <= 0. */
float pm_fresnel_dielectric(float cos_i, float eta);

/* Unpolarized reflectance of a conductor of complex index eta + i k (relative to the outside,
 * eta > 0, k >= 0) at cosine cos_i, exact (complex arithmetic in double). k = 0 gives the
 * dielectric's value. */
float pm_fresnel_conductor(float cos_i, float eta, float k);

/* Schlick's approximation f0 + (1 - f0) (1 - cos_i)^5, f0 in [0, 1]. */
static inline float pm_fresnel_schlick(float cos_i, float f0)
{
    float c = cos_i < 0.0f ? -cos_i : cos_i;
    c = c > 1.0f ? 1.0f : c;
    float m = 1.0f - c, m2 = m * m;
    return f0 + (1.0f - f0) * m2 * m2 * m;
}

/* A conductor material's reflectance at cos_i per channel: pm_fresnel_conductor of (eta[c],
 * k[c]) when eta[0] > 0, else Schlick's of f0[c]. */
void pm_fresnel_conductor_rgb(const float eta[3], const float k[3], const float f0[3], float cos_i, float f_out[3]);

/* The fraction of light coming from a Lambertian (cosine-distributed) hemisphere inside a
 * dielectric of index ior (> 0) against an outside of index 1 that the boundary reflects back in:
 * 2 * integral of F(cos, 1 / ior) cos sin over the inner hemisphere, total internal reflection
 * included (0.596 for ior 1.5). By quadrature (64 points in cos^2, a few 1e-4 absolute);
 * callers that evaluate it often may cache it per material. */
float pm_fresnel_diffuse_inside(float ior);

#endif
