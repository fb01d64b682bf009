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
 * alpha is GGX's width (glTF's perceptual roughness r gives alpha = r^2), in [0, 1]; below
 * PM_MAT_ALPHA_DELTA a conductor or rough glass is its smooth (delta) limit and a plastic's coat
 * a smooth one. docs/materials.md describes every kind, its parameters and units. */
#ifndef PM_MATERIAL_H
#define PM_MATERIAL_H

typedef struct {
    char name[64];
    float kd[3];   /* diffuse albedo, RGB, in [0, 1] */
    float ks[3];   /* glossy albedo, RGB, in [0, 1]; kd + ks <= 1 */
    float ns;      /* Phong exponent, >= 0; only read where ks > 0 */
    float ke[3];   /* emitted radiance, RGB, W/(m^2 sr); > 0 makes a triangle an area light */
    int kind;      /* PM_MAT_STANDARD, MIRROR, GLASS, CONDUCTOR, ROUGH_GLASS or PLASTIC */
    float kr[3];   /* mirror: reflectance, RGB, in [0, 1] (MTL Ks of an illum 3 or 5 material) */
    float ior;     /* glass, rough glass, plastic's coat: index of refraction (MTL Ni), > 0; outside 1 */
    float tf[3];   /* glass, rough glass: transmission filter per surface crossing, RGB, in [0, 1] */
    float alpha;   /* conductor, rough glass, plastic: GGX width, in [0, 1] */
    float eta[3];  /* conductor: real part of the complex index, RGB; 0 means use f0 */
    float k[3];    /* conductor: imaginary part (extinction), RGB, >= 0 */
    float f0[3];   /* conductor: reflectance at normal incidence, RGB, in [0, 1], when eta[0] is 0 */
    int two_sided; /* an emitter lighting from both faces (the scene file's emission.two_sided) */
} pm_material_t;

enum {
    PM_MAT_STANDARD = 0,
    PM_MAT_MIRROR = 1,
    PM_MAT_GLASS = 2,
    PM_MAT_CONDUCTOR = 3,
    PM_MAT_ROUGH_GLASS = 4,
    PM_MAT_PLASTIC = 5,
};

/* GGX widths below this are the smooth limit (a delta BSDF): D of a width near 0 overflows a
 * float (its peak is 1 / (pi alpha^2)) and no sampler or density estimate can resolve it. */
#define PM_MAT_ALPHA_DELTA 1e-3f

/* A delta BSDF only (mirror, glass, and a conductor or rough glass of alpha below
 * PM_MAT_ALPHA_DELTA): no diffuse or glossy part, no light sampling at its hits, no photon
 * stored. physics/bsdf.h's pm_bsdf_is_delta says the same (a unit test keeps them equal). */
static inline int pm_material_is_specular(const pm_material_t *m)
{
    if (m->kind == PM_MAT_CONDUCTOR || m->kind == PM_MAT_ROUGH_GLASS)
        return !(m->alpha >= PM_MAT_ALPHA_DELTA);
    return m->kind == PM_MAT_MIRROR || m->kind == PM_MAT_GLASS;
}

/* The BSDF's non-delta part depends on the direction light arrives from (a Phong lobe, a GGX
 * lobe, or the plastic's base seen through its coat's Fresnel): photons need their direction,
 * queries theirs. */
static inline int pm_material_is_glossy(const pm_material_t *m)
{
    if (m->kind == PM_MAT_PLASTIC)
        return 1;
    if (m->kind == PM_MAT_CONDUCTOR || m->kind == PM_MAT_ROUGH_GLASS)
        return m->alpha >= PM_MAT_ALPHA_DELTA;
    return m->ks[0] > 0.0f || m->ks[1] > 0.0f || m->ks[2] > 0.0f;
}

static inline int pm_material_is_emissive(const pm_material_t *m)
{
    return m->ke[0] > 0.0f || m->ke[1] > 0.0f || m->ke[2] > 0.0f;
}

#endif
