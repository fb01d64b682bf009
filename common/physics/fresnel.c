/* fresnel.c: the reflectances of smooth boundaries (fresnel.h): dielectric, conductor, and the
 * hemispherical average of a dielectric's inside that the plastic base's bounces need. */
#include "physics/fresnel.h"

#include <complex.h>
#include <math.h>

float pm_fresnel_dielectric(float cos_i, float eta)
{
    float ci = fminf(fabsf(cos_i), 1.0f);
    if (!(eta > 0.0f) || !(ci > 0.0f))
        return 1.0f;
    eta = fminf(fmaxf(eta, PM_ETA_MIN), PM_ETA_MAX);
    float sin_t2 = (1.0f - ci * ci) / (eta * eta);
    if (sin_t2 >= 1.0f)
        return 1.0f;
    float ct = sqrtf(1.0f - sin_t2);
    /* Both denominators are > 0: ci > 0 and ct > 0 here. */
    float rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
    return fminf(1.0f, 0.5f * (rs * rs + rp * rp));
}

float pm_fresnel_conductor(float cos_i, float eta, float k)
{
    double ci = fmin(fabs((double)cos_i), 1.0);
    if (!(ci > 0.0))
        return 1.0f; /* grazing: every boundary reflects all */
    double e = fmin(fmax((double)eta, PM_ETA_MIN), PM_ETA_MAX), kk = fmin(fmax((double)k, 0.0), PM_ETA_MAX);
    /* The complex index N = e + i k; the cosine inside is w / N with w = sqrt(N^2 - sin^2), whose
     * principal root has a nonnegative real and imaginary part for k >= 0, so that neither
     * denominator below vanishes (ci > 0, Re w >= 0, and N^2 ci + w has a positive real part). */
    double complex n = e + kk * I, n2 = n * n, w = csqrt(n2 - (1.0 - ci * ci));
    double complex rs = (ci - w) / (ci + w), rp = (n2 * ci - w) / (n2 * ci + w);
    double r = 0.5 * (creal(rs * conj(rs)) + creal(rp * conj(rp)));
    return (float)fmin(fmax(r, 0.0), 1.0);
}

void pm_fresnel_conductor_rgb(const float eta[3], const float k[3], const float f0[3], float cos_i, float f_out[3])
{
    for (int c = 0; c < 3; c++)
        f_out[c] = eta[0] > 0.0f ? pm_fresnel_conductor(cos_i, eta[c], k[c]) : pm_fresnel_schlick(cos_i, f0[c]);
}

float pm_fresnel_diffuse_inside(float ior)
{
    if (!(ior > 0.0f))
        return 0.0f;
    /* From inside, the boundary's ratio is 1 / ior. With x = cos^2, 2 cos sin dtheta = dx, so the
     * average is the integral of F(sqrt(x)) over x in [0, 1]; below x_c = 1 - ior^2 (ior > 1)
     * every direction is totally reflected. Above it F has a square-root kink at x_c, which the
     * substitution x = x_c + (1 - x_c) t^2 smooths for the midpoint rule. */
    double e = 1.0 / fmin(fmax((double)ior, PM_ETA_MIN), PM_ETA_MAX), xc = fmax(0.0, 1.0 - e * e);
    enum { N = 64 };
    double acc = 0.0;
    for (int j = 0; j < N; j++) {
        double t = (j + 0.5) / N, x = xc + (1.0 - xc) * t * t;
        acc += pm_fresnel_dielectric((float)sqrt(x), (float)e) * 2.0 * t;
    }
    return (float)fmin(1.0, xc + (1.0 - xc) * acc / N);
}
