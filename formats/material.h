/* material.h: the reflectance models of pmtk, and emission (Ke).
 *
 * A standard material (kind PM_MAT_STANDARD) is Lambertian plus an optional normalized Phong
 * lobe (MTL's Kd, Ks, Ns):
 *   f(wi, wo) = kd / pi + ks (ns + 2) / (2 pi) max(0, dot(r(wi), wo))^ns   [1/sr]
 * Energy conservation asks kd + ks <= 1 per channel; the scene loader enforces it.
 *
 * A specular material has a delta BSDF only, and kd = ks = 0 (render/transport.h samples it):
 *   PM_MAT_MIRROR: perfect mirror reflecting the fraction kr (MTL illum 3 or 5 with Ks);
 *   PM_MAT_GLASS: a smooth dielectric of index ior against an outside of index 1 (MTL illum 7,
 *     Ni), Fresnel reflection and refraction from either side, each transmission through its
 *     surface filtered by tf (MTL Tf): a filter per crossing, not an absorption per metre.
 * Microfacet materials (GGX distribution of width alpha, Smith shadowing, visible-normal sampling;
 * physics/bsdf.h evaluates, samples and weighs every kind):
 *   PM_MAT_CONDUCTOR: rough metal; Fresnel of the complex index eta + i k per channel when
 *     eta[0] > 0, else Schlick's with the artist's normal-incidence colour f0;
 *   PM_MAT_ROUGH_GLASS: rough dielectric of index ior, reflection and transmission both ways,
 *     each transmission filtered by tf;
 *   PM_MAT_PLASTIC: a diffuse base kd under a smooth-to-rough GGX dielectric coat of index ior.
 * alpha is GGX's width (glTF's perceptual roughness r gives alpha = r^2), in [0, 1]. */
#ifndef PM_MATERIAL_H
#define PM_MATERIAL_H

typedef struct {
    char name[64];
    float kd[3];  /* diffuse albedo, RGB, in [0, 1] */
    float ks[3];  /* glossy albedo, RGB, in [0, 1]; kd + ks <= 1 */
    float ns;     /* Phong exponent, >= 0; only read where ks > 0 */
    float ke[3];  /* emitted radiance, RGB, W/(m^2 sr); > 0 makes a triangle an area light */
    int kind;     /* PM_MAT_STANDARD, PM_MAT_MIRROR or PM_MAT_GLASS */
    float kr[3];  /* mirror: reflectance, RGB, in [0, 1] (MTL Ks of an illum 3 or 5 material) */
    float ior;    /* glass: index of refraction (MTL Ni), > 0; the outside medium has index 1 */
    float tf[3];  /* glass: transmission filter per surface crossing, RGB, in [0, 1] (MTL Tf) */
    float alpha;  /* conductor, rough glass, plastic: GGX width, in [0, 1] */
    float eta[3]; /* conductor: real part of the complex index, RGB; 0 means use f0 */
    float k[3];   /* conductor: imaginary part (extinction), RGB, >= 0 */
    float f0[3];  /* conductor: reflectance at normal incidence, RGB, in [0, 1], when eta[0] is 0 */
} pm_material_t;

enum {
    PM_MAT_STANDARD = 0,
    PM_MAT_MIRROR = 1,
    PM_MAT_GLASS = 2,
    PM_MAT_CONDUCTOR = 3,
    PM_MAT_ROUGH_GLASS = 4,
    PM_MAT_PLASTIC = 5,
};

/* Mirror or glass: a delta BSDF, no diffuse or Phong part, no light sampling at its hits. */
static inline int pm_material_is_specular(const pm_material_t *m)
{
    return m->kind == PM_MAT_MIRROR || m->kind == PM_MAT_GLASS;
}

static inline int pm_material_is_glossy(const pm_material_t *m)
{
    return m->ks[0] > 0.0f || m->ks[1] > 0.0f || m->ks[2] > 0.0f;
}

static inline int pm_material_is_emissive(const pm_material_t *m)
{
    return m->ke[0] > 0.0f || m->ke[1] > 0.0f || m->ke[2] > 0.0f;
}

#endif
