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
 * The fields are laid out so that a standard material's first bytes (name to ke) are what
 * they were before specular materials existed: scene hashes of such scenes do not change. */
#ifndef PM_MATERIAL_H
#define PM_MATERIAL_H

typedef struct {
    char name[64];
    float kd[3]; /* diffuse albedo, RGB, in [0, 1] */
    float ks[3]; /* glossy albedo, RGB, in [0, 1]; kd + ks <= 1 */
    float ns;    /* Phong exponent, >= 0; only read where ks > 0 */
    float ke[3]; /* emitted radiance, RGB, W/(m^2 sr); > 0 makes a triangle an area light */
    int kind;    /* PM_MAT_STANDARD, PM_MAT_MIRROR or PM_MAT_GLASS */
    float kr[3]; /* mirror: reflectance, RGB, in [0, 1] (MTL Ks of an illum 3 or 5 material) */
    float ior;   /* glass: index of refraction (MTL Ni), > 0; the outside medium has index 1 */
    float tf[3]; /* glass: transmission filter per surface crossing, RGB, in [0, 1] (MTL Tf) */
} pm_material_t;

enum { PM_MAT_STANDARD = 0, PM_MAT_MIRROR = 1, PM_MAT_GLASS = 2 };

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
