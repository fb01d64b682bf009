/* transport.h: the light transport of the scene model, defined once for every tracer: the
 * photon tracer (render/photontrace.h), the eye-ray tracer of trace-gather-points and the
 * reference path tracer (render/pathtrace.h) evaluate, sample and weigh reflection and lights
 * only through these functions, so that an estimate and its ground truth cannot drift apart.
 *
 * The BSDF of every material kind is physics/bsdf.h's; this header keeps the names the tracers
 * call it by. Directions are unit vectors pointing away from the surface point; n is the unit
 * normal on the side that is lit. The lights are render/light.h's.
 *
 * Units: metres; BSDF 1/sr; pdfs over solid angle 1/sr, over area 1/m^2. */
#ifndef PM_TRANSPORT_H
#define PM_TRANSPORT_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "formats/material.h"
#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "physics/bsdf.h"
#include "render/scene.h"

/* ---- the BSDF ----
 *
 * Every material kind's scattering is physics/bsdf.h's (pm_bsdf_eval, pm_bsdf_sample_wi,
 * pm_bsdf_pdf_wi in a radiance or importance mode); the functions here are the names the tracers
 * used before it, kept as thin calls into it: pm_brdf and pm_bsdf_pdf serve every kind, the lobe
 * functions the standard kind's two lobes, pm_specular_sample every delta-only kind. */

/* The standard kind's lobes a direction is sampled from. */
typedef enum { PM_LOBE_DIFFUSE = 0, PM_LOBE_GLOSSY = 1 } pm_lobe_t;

/* Mirror direction of w about n: 2 (n.w) n - w (unit up to rounding for unit n and w). */
static inline void pm_reflect(const float n[3], const float w[3], float r_out[3])
{
    float c = 2.0f * pm_dot3(n, w);
    for (int k = 0; k < 3; k++)
        r_out[k] = c * n[k] - w[k];
}

/* f(wi, wo), 1/sr, radiance mode, of any kind's non-delta lobes around n (pm_bsdf_eval): for the
 * standard kind kd / pi + ks (ns + 2) / (2 pi) cos^ns(alpha) (0 when wi and wo are on opposite
 * sides of n). */
static inline void pm_brdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3],
                           float f_out[3])
{
    pm_bsdf_eval(m, n, wi, wo, PM_BSDF_RADIANCE, f_out);
}

/* Samples direction wi from one lobe of a standard material with the uniforms u1, u2 in [0, 1):
 * the diffuse lobe cosine-weighted about n, the glossy one as cos^ns about the mirror direction of
 * wo. Returns whether wi lies above the surface (n.wi > 0); a glossy sample below it is the lobe's
 * energy loss, which callers treat as absorption (pm_bsdf_standard_sample_lobe). */
static inline int pm_bsdf_sample_lobe(const pm_material_t *m, pm_lobe_t lobe, const float n[3], const float wo[3],
                                      float u1, float u2, float wi_out[3])
{
    return pm_bsdf_standard_sample_lobe(m, (int)lobe, n, wo, u1, u2, wi_out);
}

/* Solid-angle pdf, 1/sr, of pm_bsdf_sample_lobe producing wi (pm_bsdf_standard_lobe_pdf). */
static inline float pm_bsdf_lobe_pdf(const pm_material_t *m, pm_lobe_t lobe, const float n[3], const float wi[3],
                                     const float wo[3])
{
    return pm_bsdf_standard_lobe_pdf(m, (int)lobe, n, wi, wo);
}

/* The standard kind's lobes' albedos as the samplers weigh them: max(kd) and max(ks). */
static inline void pm_bsdf_albedo(const pm_material_t *m, float *pd_out, float *ps_out)
{
    *pd_out = fmaxf(m->kd[0], fmaxf(m->kd[1], m->kd[2]));
    *ps_out = fmaxf(m->ks[0], fmaxf(m->ks[1], m->ks[2]));
}

/* Whether a surface of material m (its textured values at a point) keeps photons, the photon
 * tracer's test at a hit and the area samples' (render/areasample.c): no delta BSDF, no
 * transmission (pm_bsdf_stores_photons), and for the standard kind some kd or ks. */
static inline int pm_material_keeps_photons(const pm_material_t *m)
{
    if (pm_material_is_specular(m))
        return 0;
    if (m->kind != PM_MAT_STANDARD)
        return pm_bsdf_stores_photons(m);
    float pd, ps;
    pm_bsdf_albedo(m, &pd, &ps);
    return pd + ps > 0.0f;
}

/* Probability that the standard kind's mixture sampler picks the diffuse lobe. */
static inline float pm_bsdf_diffuse_share(const pm_material_t *m) { return pm_bsdf_standard_diffuse_share(m); }

/* The BSDF sampled as its mixture (pm_bsdf_sample_wi, radiance mode) from u, u1, u2. Returns
 * whether a direction was drawn (for the standard kind: above the surface). */
int pm_bsdf_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                   float wi_out[3]);

/* Solid-angle pdf, 1/sr, of pm_bsdf_sample producing wi (pm_bsdf_pdf_wi): 0 below the surface
 * for the reflective kinds. */
static inline float pm_bsdf_pdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    return pm_bsdf_pdf_wi(m, n, wi, wo);
}

/* ---- shading normals ----
 *
 * A mesh's vertex normals, interpolated (pm_scene_shading_normal), shade: the BSDF, its
 * sampling and every cosine of the rendering equation use the shading normal ns, while the
 * geometric normal ng still decides which side is which: a direction below the geometric
 * surface is never taken (it would leak light through it), and a ray leaves from ng's side.
 * The rendering equation then has the kernel f(wi, wo) |ns.wi| over directions, that is, the
 * BSDF with respect to the geometric cosine is F(wi -> wo) = f(wi, wo) |ns.wi| / |ng.wi| for
 * light arriving along wi. That F is not symmetric, so the adjoint equation photons follow is
 * not the one radiance follows: a photon arriving from wi and leaving along wo is weighted by
 * F(wi -> wo) |ng.wo| / pdf(wo) = (|ns.wi| / |ng.wi|) f |ng.wo| / pdf(wo), not by f |ns.wo| /
 * pdf(wo) as an eye ray would be (Veach's thesis, 5.3, on the non-symmetric scattering that
 * shading normals make). The first factor is also what a stored photon needs: a density
 * estimate counts flux through the geometric area, so f sum(Phi) / (pi r^2) estimates the
 * integral of f L cos_g, where the eye side's integrand is f L cos_s. Both helpers take ng unit
 * on the side the ray came from and ns on that side too; both return 0 when the path must end. */

/* Both factors are capped at PM_SHADING_FACTOR_MAX. Unbounded, each is a ratio of cosines whose
 * denominator a photon can make as small as it likes (a grazing arrival at the geometric
 * surface, a departure grazing the shading one): its mean is finite but its variance is not
 * (it grows as the log of the cap), and one photon of a million times its power is a bright
 * disc of the kernel's size in the image. The cap is a bias, always a loss of light: in light
 * of uniform radiance it drops, per factor, 0.02% of the reflected light where the shading
 * normal leans 5 degrees from the geometric one, 0.08% at 10, 0.33% at 20, 0.73% at 30, 1.6%
 * at 45 and 2.6% at 60 (docs/scene-format.md, Shading normals, has the table and how it was
 * computed; tests/stage/normals.sh checks the bound and the loss). */
#define PM_SHADING_FACTOR_MAX 10.0

/* At a photon's arrival from direction wi (unit, pointing back along its path): power *=
 * min(ns.wi / ng.wi, PM_SHADING_FACTOR_MAX). 0 when wi is below the shading surface or not
 * above the geometric one (the photon reflects nothing there: an eye ray sees a zero cosine
 * toward it). */
static inline int pm_shading_adjoint(const float ng[3], const float ns[3], const float wi[3], double power[3])
{
    float cs = pm_dot3(ns, wi), cg = pm_dot3(ng, wi);
    if (!(cs > 0.0f && cg > 0.0f))
        return 0;
    double a = fmin((double)cs / (double)cg, PM_SHADING_FACTOR_MAX);
    for (int k = 0; k < 3; k++)
        power[k] *= a;
    return 1;
}

/* At a photon's departure along wo (unit), sampled about ns with weight f ns.wo / pdf:
 * power *= min(ng.wo / ns.wo, PM_SHADING_FACTOR_MAX). 0 when wo is not above both surfaces
 * (below the geometric one it is not taken). */
static inline int pm_shading_leave(const float ng[3], const float ns[3], const float wo[3], double power[3])
{
    float cs = pm_dot3(ns, wo), cg = pm_dot3(ng, wo);
    if (!(cg > 0.0f && cs > 0.0f))
        return 0;
    double a = fmin((double)cg / (double)cs, PM_SHADING_FACTOR_MAX);
    for (int k = 0; k < 3; k++)
        power[k] *= a;
    return 1;
}

/* ---- delta-only materials (mirror, glass, smooth conductor and rough glass) ---- */

/* Samples the delta BSDF of a material whose lobes are all deltas (pm_bsdf_is_delta) at a hit
 * with unit geometric normal ng, as the mesh stores it (either side: the side wo lies on, by the
 * sign of dot(ng, wo), tells entering from leaving; dot 0 counts as the front), wo unit and
 * pointing away from the surface, u one uniform in [0, 1). Writes wi (unit) and weight = f cos /
 * pdf per channel (pm_bsdf_sample_wi):
 *   mirror: wi the mirror direction of wo, weight kr; smooth conductor: weight F(n.wo);
 *   glass: reflect when u < F = pm_fresnel_dielectric(|ng.wo|, eta) (eta = ior on the front,
 *     1 / ior behind it), weight 1; else refract by Snell's law, weight tf, times 1 / eta^2
 *     when `radiance` is 1 (eye paths carry radiance, whose density changes with the solid
 *     angle a refraction squeezes; photons carry power: radiance 0).
 * Returns 1 when wi was transmitted, 0 when reflected, -1 when nothing leaves (a black
 * mirror, or a material that is not delta-only; wi and weight are then zero). */
int pm_specular_sample(const pm_material_t *m, const float ng[3], const float wo[3], float u, int radiance,
                       float wi_out[3], float weight_out[3]);

/* ---- triangles ---- */

/* Per-triangle unit front normals (the lights themselves are render/light.h's). */
typedef struct {
    float *tri_n; /* ntris * 3: (v1 - v0) x (v2 - v0), normalized; the side that emits */
} pm_shade_geom_t;

pm_result_t pm_shade_geom_init(const pm_scene_t *s, pm_shade_geom_t *out);
void pm_shade_geom_free(pm_shade_geom_t *g);

/* Veach's power heuristic: the weight of strategy a against b, each a sample count times a
 * solid-angle pdf at one direction; 0 when neither could have produced it. */
static inline float pm_power_heuristic(float a, float b)
{
    float d = a * a + b * b;
    return d > 0.0f ? a * a / d : 0.0f;
}

#endif
