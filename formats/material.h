/* material.h: the one reflectance model of pmtk: Lambertian plus an optional
 * normalized Phong lobe (MTL's Kd, Ks, Ns), and emission (Ke).
 *
 * f(wi, wo) = kd / pi + ks (ns + 2) / (2 pi) max(0, dot(r(wi), wo))^ns   [1/sr]
 * Energy conservation asks kd + ks <= 1 per channel; the scene loader enforces it. */
#ifndef PM_MATERIAL_H
#define PM_MATERIAL_H

typedef struct {
    char name[64];
    float kd[3]; /* diffuse albedo, RGB, in [0, 1] */
    float ks[3]; /* glossy albedo, RGB, in [0, 1]; kd + ks <= 1 */
    float ns;    /* Phong exponent, >= 0; only read where ks > 0 */
    float ke[3]; /* emitted radiance, RGB, W/(m^2 sr); > 0 makes a triangle an area light */
} pm_material_t;

static inline int pm_material_is_glossy(const pm_material_t *m)
{
    return m->ks[0] > 0.0f || m->ks[1] > 0.0f || m->ks[2] > 0.0f;
}

static inline int pm_material_is_emissive(const pm_material_t *m)
{
    return m->ke[0] > 0.0f || m->ke[1] > 0.0f || m->ke[2] > 0.0f;
}

#endif
