/* bsdf.h: the scattering of every material kind of formats/material.h, defined once: evaluation,
 * sampling and pdf behind one dispatch on the kind, used by the photon tracer, the eye-ray
 * tracer, the reference path tracer and (mirrored lane by lane) the SIMD gather.
 *
 * Conventions (every function below):
 *   - Directions are unit vectors pointing away from the surface point. wo is the direction
 *     that is known (an eye path: toward the camera, the previous vertex; a photon: back along
 *     the path it arrived by), wi the other one (the one sampled, or a light's direction).
 *   - n is the unit normal of the surface's front (outside) face. Reflective kinds (mirror,
 *     conductor, plastic) are two-sided: they reflect on whichever side wo lies, as if n were
 *     flipped to that side. Dielectrics (glass, rough glass) read the side: wo on n's side is
 *     outside (index 1), behind it inside (index ior); n.wo = 0 counts as outside. The standard
 *     kind reflects on n's side as given (callers pass it on wo's side; a shading normal may
 *     leave wo below it, and f and the sampler are then what the tracers always made of them:
 *     f is 0 only for n.wi <= 0).
 *   - A reflection has wi on wo's side of the surface; a transmission has it on the other.
 *   - Units: the BSDF f in 1/sr per RGB channel; pdfs over solid angle in 1/sr.
 *
 * Radiance and importance (the adjoint). f(wi, wo) in PM_BSDF_RADIANCE mode is the BSDF of
 * light arriving along wi and leaving along wo: what an eye path multiplies radiance by. A photon
 * carries power the other way: it arrives along wo and leaves along wi, so it needs the adjoint
 * f*(wi, wo) = f(wo, wi), which is what PM_BSDF_IMPORTANCE mode returns. The two differ only in
 * transmission: radiance crossing from index n_wi into index n_wo is scaled by (n_wo / n_wi)^2
 * (a refraction squeezes the solid angle), power is not (Veach's thesis, 5.2). So for a
 * transmission, f_importance(wi, wo) = (n_wi / n_wo)^2 f_radiance(wi, wo), and the reciprocity
 * rule is f_radiance(wi, wo) / n_wo^2 = f_radiance(wo, wi) / n_wi^2. Reflection is symmetric,
 * f(wi, wo) = f(wo, wi), and the same in both modes.
 *
 * Models (docs/materials.md has the derivations and the parameters' ranges):
 *   standard:  Lambert kd / pi plus normalized Phong ks (ns + 2) / (2 pi) cos^ns(angle between
 *              wo and the mirror direction of wi); its sampler is the mixture of the cosine lobe
 *              and the cos^ns lobe about the mirror direction of wo, by max(kd) : max(ks); a
 *              Phong sample below the surface is the lobe's energy loss (no sample).
 *   mirror:    delta reflection, weight kr.
 *   glass:     smooth dielectric, delta reflection with probability F (exact unpolarized
 *              Fresnel, pm_fresnel_dielectric) and delta transmission with 1 - F, filtered by tf.
 *   conductor: GGX microfacet reflection F(wo.h) D(h) G2(wi, wo) / (4 |n.wi| |n.wo|) with
 *              F the conductor Fresnel of eta + i k per channel (eta[0] > 0) or Schlick's of f0.
 *   rough glass: GGX reflection F D G2 / (4 |n.wi| |n.wo|) and transmission (Walter et al. 2007,
 *              generalized half vector h along -(n_wo wo + n_wi wi)):
 *              (1 - F) tf D G2 |wi.h| |wo.h| / (|n.wi| |n.wo| (wo.h + e wi.h)^2), e = n_wi / n_wo,
 *              in radiance mode (times e^2 in importance mode); F = pm_fresnel_dielectric(wo.h).
 *   plastic:   a GGX dielectric coat (index ior, width alpha) over a Lambertian base kd:
 *              F(wo.h) D G2 / (4 |n.wi| |n.wo|)
 *              + kd (1 - F(n.wi)) (1 - F(n.wo)) / (pi ior^2 (1 - kd Fdr_in)),
 *              F the dielectric Fresnel of the coat, Fdr_in the base's light reflected back down
 *              by the coat's inside averaged over a cosine-distributed hemisphere
 *              (pm_fresnel_diffuse_inside): the base's light that bounces between base and coat
 *              summed as a geometric series; reciprocal, and at most 1 - F(n.wo) in albedo.
 *   G2 is Smith's height-correlated masking-shadowing 1 / (1 + Lambda(wo) + Lambda(wi)), for
 *   transmission too; the microfacet samplers draw h from the distribution of normals visible
 *   from wo (Heitz 2018), so the weight of a sample is F G2 / G1(wo) (physics/microfacet.h).
 *
 * The smooth limit: alpha below PM_MAT_ALPHA_DELTA (formats/material.h, 1e-3) makes a conductor
 * a delta reflection (weight F(n.wo)), a rough glass the smooth glass (with its tf) and a
 * plastic's coat a delta reflection (probability and weight from F(n.wo)) over the same base, so
 * that no D of width 0 is ever evaluated. alpha is clamped to [PM_MAT_ALPHA_DELTA, 1] elsewhere.
 * Nothing here returns NaN or Inf for finite unit inputs, alpha in [0, 1], ior or eta in
 * (0, 1e6], k >= 0, grazing directions included (n.w = 0 gives f = 0 and no sample). */
#ifndef PM_PHYSICS_BSDF_H
#define PM_PHYSICS_BSDF_H

#include "formats/material.h"
#include "physics/fresnel.h"
#include "physics/microfacet.h"

/* Which way a path carries light; see the top of this file. */
typedef enum {
    PM_BSDF_RADIANCE = 0,  /* eye paths: f(wi, wo), light arriving along wi, leaving along wo */
    PM_BSDF_IMPORTANCE = 1 /* photons: the adjoint f(wo, wi), power arriving along wo, leaving along wi */
} pm_bsdf_mode_t;

/* Lobe flags: what a sample was drawn from (pm_bsdf_sample_t.lobe), and the union of what a
 * material can draw from (pm_bsdf_lobes). */
enum {
    PM_BSDF_REFLECT = 1u,  /* wi on wo's side */
    PM_BSDF_TRANSMIT = 2u, /* wi on the other side */
    PM_BSDF_DELTA = 4u,    /* a Dirac lobe: f has no value, pm_bsdf_eval and pm_bsdf_pdf_wi give it 0 */
    PM_BSDF_DIFFUSE = 8u,  /* the Lambertian lobe of the standard material and the plastic's base */
    PM_BSDF_GLOSSY = 16u,  /* a Phong or GGX lobe: a density that depends on wo */
};

/* One sample of the BSDF at wo. */
typedef struct {
    float wi[3];     /* the sampled direction, unit, pointing away from the surface */
    float weight[3]; /* f(wi, wo) |n.wi| / pdf in the mode asked for, per channel; for a delta lobe
                        its reflectance or transmittance over the probability of choosing it */
    float pdf;       /* non-delta: pm_bsdf_pdf_wi(wi), the density of the whole sampler at wi,
                        1/sr (what MIS weighs against a light's pdf); delta: the probability that
                        the delta lobe was chosen (not a density; MIS does not apply) */
    float eta;       /* index on wi's side over index on wo's side: 1 for a reflection (the
                        factor by which a transmission scales radiance is 1 / eta^2) */
    unsigned lobe;   /* PM_BSDF_REFLECT or PM_BSDF_TRANSMIT, with PM_BSDF_DELTA or the lobe's
                        PM_BSDF_DIFFUSE / PM_BSDF_GLOSSY */
} pm_bsdf_sample_t;

/* The union of the lobe flags m can sample (after the smooth limit: a conductor of alpha 0 is
 * REFLECT | DELTA). Cheap: reads the kind, alpha and whether kd, ks, kr, tf are nonzero. */
unsigned pm_bsdf_lobes(const pm_material_t *m);

/* Every lobe of m is a delta: mirror, glass, and conductor and rough glass in their smooth limit.
 * Such a surface takes no light sample, no MIS, and stores no photon (no density estimate can
 * use a delta BSDF); it is what pm_material_is_specular says, kept equal by a unit test. */
static inline int pm_bsdf_is_delta(const pm_material_t *m)
{
    unsigned l = pm_bsdf_lobes(m);
    return (l & PM_BSDF_DELTA) && !(l & (PM_BSDF_DIFFUSE | PM_BSDF_GLOSSY));
}

/* m has a non-delta lobe (f has a value somewhere): the surfaces where photons are stored and
 * the gather estimates, and where light sampling and MIS apply (to the non-delta part). */
static inline int pm_bsdf_has_density(const pm_material_t *m)
{
    return (pm_bsdf_lobes(m) & (PM_BSDF_DIFFUSE | PM_BSDF_GLOSSY)) != 0;
}

/* m can send a path through the surface (glass, rough glass). */
static inline int pm_bsdf_transmits(const pm_material_t *m) { return (pm_bsdf_lobes(m) & PM_BSDF_TRANSMIT) != 0; }

/* f(wi, wo) of the non-delta lobes, 1/sr per channel, in the given mode (delta lobes give 0;
 * 0 too when either direction is grazing or a reflective kind sees wi and wo on opposite sides).
 * For the standard kind this is the arithmetic the tracers always used (bit for bit), for n.wi > 0. */
void pm_bsdf_eval(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3], pm_bsdf_mode_t mode,
                  float f_out[3]);

/* The solid-angle pdf, 1/sr, with which pm_bsdf_sample_wi draws wi from a non-delta lobe: the
 * lobe densities weighted by the probabilities of choosing them (which depend on wo only), so it
 * integrates over the sphere to the probability of a non-delta sample that is not absorbed. 0 for
 * a delta-only material. Mode-free: the samplers do not depend on the mode. */
float pm_bsdf_pdf_wi(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3]);

/* Samples wi at wo from three uniforms in [0, 1): u chooses the lobe (and, at a dielectric,
 * reflection or transmission), u1 and u2 the direction. Returns 1 with *out filled, or 0 when
 * the path ends here (a black material, a Phong or GGX sample that fell below the surface, a
 * grazing wo); *out is then zeroed. Deterministic in (m, n, wo, u, u1, u2, mode). For the
 * standard kind: the lobe by u < max(kd) / (max(kd) + max(ks)), the direction from u1, u2, with
 * the arithmetic of the tracers before this module (bit for bit). */
int pm_bsdf_sample_wi(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                      pm_bsdf_mode_t mode, pm_bsdf_sample_t *out);

/* An estimate of the directional albedo at wo per channel, in [0, 1]: the expected weight of a
 * sample. For Russian roulette and lobe choice, not for shading: standard kd + ks; mirror kr;
 * glass and rough glass F + (1 - F) tf, conductor F and plastic F + (1 - F) kd, F at n.wo. */
void pm_bsdf_albedo_wo(const pm_material_t *m, const float n[3], const float wo[3], float a_out[3]);

/* The standard kind's lobes one by one, for callers that choose the lobe themselves (the photon
 * tracer's Russian roulette, the eye tracer's stratified secondary rays). lobe 0 is the
 * Lambertian one (cosine about n, n on wo's side), lobe 1 the Phong one (cos^ns about the mirror
 * direction of wo about n). sample returns whether wi lies above the surface (n.wi > 0); pdf is
 * the lobe's own density, 1/sr: cos / pi above the surface for lobe 0, (ns + 1) / (2 pi) cos^ns
 * within 90 degrees of the mirror direction for lobe 1 (below the surface included; each
 * integrates to 1 over the sphere). */
int pm_bsdf_standard_sample_lobe(const pm_material_t *m, int lobe, const float n[3], const float wo[3], float u1,
                                 float u2, float wi_out[3]);
float pm_bsdf_standard_lobe_pdf(const pm_material_t *m, int lobe, const float n[3], const float wi[3],
                                const float wo[3]);
/* The standard kind's probability of drawing the Lambertian lobe: max(kd) / (max(kd) + max(ks)),
 * 1 when it reflects nothing. */
float pm_bsdf_standard_diffuse_share(const pm_material_t *m);

/* f cos / pdf of the standard kind's Phong lobe alone, over ks, at n.wi = cosi:
 * (ns + 2) / (ns + 1) cosi, in double (the photon tracer's weight for a glossy bounce). */
static inline double pm_bsdf_standard_phong_weight(const pm_material_t *m, float cosi)
{
    return (m->ns + 2.0) / (m->ns + 1.0) * cosi;
}

/* Where photons are stored and the gather estimates: a surface with a non-delta lobe that does
 * not transmit (standard with kd or ks, rough conductor, plastic). Transmitting rough glass
 * stores none: a density estimate on one side of it cannot see the photons that arrive from the
 * other; photons pass it as they pass glass, and eye paths continue through it. */
static inline int pm_bsdf_stores_photons(const pm_material_t *m)
{
    unsigned l = pm_bsdf_lobes(m);
    return (l & (PM_BSDF_DIFFUSE | PM_BSDF_GLOSSY)) && !(l & PM_BSDF_TRANSMIT);
}

#endif
