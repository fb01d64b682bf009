/* scene_material.c: one assimp material into a pm_material_t (docs/scene-format.md, Materials):
 * MTL's Kd, Ks, Ns, Ke, its mirrors and glass (illum, Ni, Tf), its PBR extension (Pr, Pm) and
 * glTF's metallic-roughness, transmission and ior mapped onto the material kinds, with every
 * value range-checked. */
#include "render/scene.h"

#include <assimp/material.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "render/scene_load.h"

/* The PBR inputs of assimp material am: 1 when it is a metallic-roughness material, that is when
 * the importer gives a metallic or a roughness factor (assimp's glTF 2 importer gives both for
 * every material; an MTL material has them with a Pr or a Pm line, the PBR extension), with its
 * metallic and roughness factors (glTF's defaults where one is absent: metallic 1, or 0 in an
 * MTL, whose materials are dielectrics unless Pm says otherwise; roughness 1 in both). A glTF 1
 * (KHR_materials_common), Collada or PLY material has neither and stays the Phong material its
 * format describes: reading it as glTF 2's default, a rough metal, would turn a milk truck's
 * paint to chrome. */
int pm_scene_pbr_inputs(int is_obj, const struct aiMaterial *am, float *metallic_out, float *roughness_out)
{
    ai_real metallic = is_obj ? 0 : 1, roughness = 1;
    int has_m = aiGetMaterialFloatArray(am, AI_MATKEY_METALLIC_FACTOR, &metallic, NULL) == aiReturn_SUCCESS;
    int has_r = aiGetMaterialFloatArray(am, AI_MATKEY_ROUGHNESS_FACTOR, &roughness, NULL) == aiReturn_SUCCESS;
    *metallic_out = (float)metallic;
    *roughness_out = (float)roughness;
    return has_m || has_r;
}

/* The specular part of a material (docs/scene-format.md, "Mirrors and glass"): from an OBJ,
 * illum 7 is glass (Ni, Tf; rough glass of width Pr^2 with a Pr above 0) and illum 3 or 5 with
 * some Ks a mirror (Ks); from glTF, a transmissionFactor above 0 is glass (ior, baseColorFactor
 * as the filter), rough glass with a roughnessFactor above 0. Sets m->kind, kr, ior, tf and
 * alpha; refuses an index that is not a finite number > 0, a filter outside [0, 1], a roughness
 * outside [0, 1], and glass that is also a metal. */
static pm_result_t load_specular(const char *mesh, int is_obj, const struct aiMaterial *am, const float kd[3],
                                 const float ks[3], pm_material_t *m)
{
    int illum = 0, glass = 0, mirror = 0;
    ai_real ior = 1, transmission = 0;
    float metallic = 0, roughness = 0;
    struct aiColor4D tf = {1, 1, 1, 1};
    unsigned one = 1;
    m->ior = 1.0f;
    m->tf[0] = m->tf[1] = m->tf[2] = 1.0f;
    aiGetMaterialFloatArray(am, AI_MATKEY_REFRACTI, &ior, NULL);
    int pbr = pm_scene_pbr_inputs(is_obj, am, &metallic, &roughness);
    if (is_obj) {
        aiGetMaterialIntegerArray(am, "$mat.illum", 0, 0, &illum, &one);
        aiGetMaterialColor(am, AI_MATKEY_COLOR_TRANSPARENT, &tf);
        glass = illum == 7;
        /* a PBR material's kind comes from Pm (load_pbr), not from illum */
        mirror = !pbr && (illum == 3 || illum == 5) && (ks[0] > 0.0f || ks[1] > 0.0f || ks[2] > 0.0f);
        for (int k = 0; k < 3; k++)
            m->kr[k] = mirror ? ks[k] : 0.0f;
        if (!pbr || !glass)
            roughness = 0;
    } else {
        /* glTF's index defaults to 1.5 where KHR_materials_ior is absent */
        if (aiGetMaterialFloatArray(am, AI_MATKEY_REFRACTI, &ior, NULL) != aiReturn_SUCCESS)
            ior = 1.5f;
        aiGetMaterialFloatArray(am, AI_MATKEY_TRANSMISSION_FACTOR, &transmission, NULL);
        if (!(transmission >= 0 && transmission <= 1))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': transmissionFactor %g must lie in [0, 1]",
                                mesh, m->name, transmission);
        glass = transmission > 0;
        /* the base colour tints what glass transmits */
        tf = (struct aiColor4D){kd[0], kd[1], kd[2], 1};
        /* only glTF can say both (an OBJ material has one illum) */
        if (glass && metallic == 1.0f)
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': material '%s': transmissionFactor %g makes it glass, and metallicFactor 1 "
                                "with roughnessFactor %g a %s: it cannot be both",
                                mesh, m->name, transmission, roughness, roughness == 0.0f ? "mirror" : "metal");
    }
    if (glass) {
        if (!(isfinite(ior) && ior > 0))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g must be a finite number > 0", mesh,
                                m->name, is_obj ? "Ni" : "ior", ior);
        if (!(roughness >= 0.0f && roughness <= 1.0f))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g must lie in [0, 1]", mesh, m->name,
                                is_obj ? "Pr" : "roughnessFactor", roughness);
        float tv[3] = {tf.r, tf.g, tf.b};
        for (int k = 0; k < 3; k++)
            if (!(tv[k] >= 0.0f && tv[k] <= 1.0f))
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g in channel %c must lie in [0, 1]",
                                    mesh, m->name, is_obj ? "Tf" : "baseColorFactor", tv[k], "rgb"[k]);
        /* smooth glass stays the delta BSDF the tracers follow in specular chains */
        m->kind = roughness > 0.0f ? PM_MAT_ROUGH_GLASS : PM_MAT_GLASS;
        m->alpha = roughness * roughness;
        m->ior = (float)ior;
        for (int k = 0; k < 3; k++)
            m->tf[k] = tv[k];
    } else if (mirror) {
        m->kind = PM_MAT_MIRROR;
    }
    /* A specular material is its delta BSDF alone (the Kd and Ks it sets besides are
     * reported by scan_material and scan_mtl_dropped). */
    if (m->kind != PM_MAT_STANDARD)
        for (int k = 0; k < 3; k++)
            m->kd[k] = m->ks[k] = 0.0f;
    return PM_OK;
}

/* glTF's F0 of a dielectric: an index of 1.5 reflects ((1.5 - 1) / (1.5 + 1))^2 = 0.04 at normal
 * incidence, the value its metallic-roughness model mixes toward the base colour. */
#define PM_PBR_DIELECTRIC_F0 0.04f

/* The metallic-roughness part of a material that is not glass (docs/scene-format.md, "PBR
 * materials"): metallic 1 is a conductor of F0 the base colour (Schlick's Fresnel, as glTF
 * says) and GGX width roughness^2, its smooth (delta) limit at roughness 0; metallic 0 is
 * plastic, the base colour under a dielectric coat of index 1.5 (glTF's ior when
 * KHR_materials_ior gives one, an MTL's Ni when not 1; index 1 makes it Lambertian, exactly).
 * A metallic strictly between is the nearer kind with glTF's mix of that kind's own lobe:
 * F0 = lerp(0.04, base, metallic) for a metal, kd = (1 - metallic) base for plastic; the other
 * lobe is lost, and scan_material says so. */
static pm_result_t load_pbr(const char *mesh, int is_obj, const struct aiMaterial *am, const float base[3],
                            pm_material_t *m)
{
    float metallic, roughness;
    if (!pm_scene_pbr_inputs(is_obj, am, &metallic, &roughness))
        return PM_OK;
    if (!(metallic >= 0.0f && metallic <= 1.0f))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g must lie in [0, 1]", mesh, m->name,
                            is_obj ? "Pm" : "metallicFactor", metallic);
    if (!(roughness >= 0.0f && roughness <= 1.0f))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g must lie in [0, 1]", mesh, m->name,
                            is_obj ? "Pr" : "roughnessFactor", roughness);
    memset(m->kd, 0, sizeof m->kd);
    memset(m->ks, 0, sizeof m->ks);
    m->ns = 0.0f;
    m->alpha = roughness * roughness;
    if (metallic >= 0.5f) {
        for (int k = 0; k < 3; k++)
            m->f0[k] = metallic * base[k] + (1.0f - metallic) * PM_PBR_DIELECTRIC_F0;
        m->kind = PM_MAT_CONDUCTOR;
        return PM_OK;
    }
    ai_real ior = 1.5f, given = 1;
    if (aiGetMaterialFloatArray(am, AI_MATKEY_REFRACTI, &given, NULL) == aiReturn_SUCCESS && (!is_obj || given != 1))
        ior = given; /* assimp gives an MTL without Ni the index 1: that is no coat index */
    if (!(isfinite(ior) && ior >= 1 && ior <= 10))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': %s %g must lie in [1, 10] (the coat's index)",
                            mesh, m->name, is_obj ? "Ni" : "ior", ior);
    for (int k = 0; k < 3; k++)
        m->kd[k] = (1.0f - metallic) * base[k];
    m->kind = ior == 1 ? PM_MAT_STANDARD : PM_MAT_PLASTIC;
    m->ior = (float)ior;
    if (ior == 1)
        m->alpha = 0.0f; /* no coat: no width to read */
    return PM_OK;
}

/* A material name as pmtk keeps it: spaces and control characters become '_', since names
 * travel as one word in file headers (load_material, and the .mtl scans that match names). */
void pm_scene_material_word(char *name)
{
    for (char *p = name; *p; p++)
        if (*p == ' ' || (unsigned char)*p < 0x20 || *p == 0x7f)
            *p = '_';
}

/* Reads one material's reflectance from assimp and checks it is physical. */
pm_result_t pm_scene_load_material(const ctx_t *c, const char *mesh, int is_obj, const struct aiMaterial *am,
                                   pm_material_t *m)
{
    struct aiString name;
    struct aiColor4D kd = {0.8f, 0.8f, 0.8f, 1}, ks = {0, 0, 0, 1}, ke = {0, 0, 0, 1};
    ai_real ns = 0;
    memset(m, 0, sizeof *m);
    if (aiGetMaterialString(am, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS)
        snprintf(m->name, sizeof m->name, "%s", name.data);
    pm_scene_material_word(m->name);
    aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &kd);
    aiGetMaterialColor(am, AI_MATKEY_COLOR_SPECULAR, &ks);
    aiGetMaterialColor(am, AI_MATKEY_COLOR_EMISSIVE, &ke);
    aiGetMaterialFloatArray(am, AI_MATKEY_SHININESS, &ns, NULL);
    int stand_in = !m->name[0] || strcmp(m->name, AI_DEFAULT_MATERIAL_NAME) == 0;
    if (stand_in) {
        /* assimp's stand-in for a mesh that names no material (PLY, STL): a plain grey
         * Lambertian surface, whatever the importer filled in (some set Ks to 1). */
        kd = (struct aiColor4D){0.8f, 0.8f, 0.8f, 1};
        ks = ke = (struct aiColor4D){0, 0, 0, 1};
        snprintf(m->name, sizeof m->name, "default");
    }
    float kdv[3] = {kd.r, kd.g, kd.b}, ksv[3] = {ks.r, ks.g, ks.b}, kev[3] = {ke.r, ke.g, ke.b};
    float metallic, roughness;
    int pbr = !stand_in && pm_scene_pbr_inputs(is_obj, am, &metallic, &roughness);
    pm_result_t r = PM_OK;
    if (!stand_in && (r = load_specular(mesh, is_obj, am, kdv, ksv, m)) != PM_OK)
        return r;
    int specular = m->kind != PM_MAT_STANDARD;
    /* Kd + Ks above 1 (common in exported assets) is scaled down to 1 in the worst channel, both
     * lobes by one factor so that the colour stays, with a warning naming the factor; a mirror's
     * Ks is its reflectance and a PBR material's Ks unused: their sum is no constraint. */
    float sum = 0.0f;
    int worst = 0;
    for (int i = 0; i < 3 && !specular && !pbr; i++)
        if (kdv[i] + ksv[i] > sum && kdv[i] >= 0.0f && kdv[i] <= 1.0f && ksv[i] >= 0.0f && ksv[i] <= 1.0f)
            sum = kdv[i] + ksv[i], worst = i;
    if (sum > 1.0f + 1e-6f) {
        float f = 1.0f / sum;
        for (int i = 0; i < 3; i++)
            kdv[i] *= f, ksv[i] *= f;
        /* said once per material some triangle uses (an unused one is dropped with its notes) */
        char value[64];
        snprintf(value, sizeof value, "%.6g (channel %c)", (double)sum, "rgb"[worst]);
        if ((r = pm_scene_note_unsupported(c->s, (uint32_t)(m - c->s->materials), "Kd + Ks", 0, value)) != PM_OK)
            return r;
        pm_scene_unsupported_t *u = &c->s->unsupported[c->s->nunsupported - 1];
        if (strcmp(u->key, "Kd + Ks") == 0) /* the entry just made (not one kept from before) */
            snprintf(u->note, sizeof u->note, "Kd and Ks scaled by %.6g so that they sum to 1", (double)f);
    }
    for (int i = 0; i < 3; i++) {
        if (!(kdv[i] >= 0.0f && kdv[i] <= 1.0f) || !(ksv[i] >= 0.0f && ksv[i] <= 1.0f))
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': material '%s': Kd %g and Ks %g in channel %c must lie in [0, 1]", mesh,
                                m->name, kdv[i], ksv[i], "rgb"[i]);
        if (!(kev[i] >= 0.0f && kev[i] <= 1e30f))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': Ke %g in channel %c must lie in [0, 1e30]",
                                mesh, m->name, kev[i], "rgb"[i]);
        m->kd[i] = specular ? 0.0f : kdv[i];
        m->ks[i] = specular || pbr ? 0.0f : ksv[i];
        m->ke[i] = kev[i];
    }
    if (!(ns >= 0 && ns <= 1e6))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': Ns %g must lie in [0, 1e6]", mesh, m->name, ns);
    /* a Phong exponent matters only where there is a Phong lobe */
    m->ns = specular || pbr ? 0.0f : (float)ns;
    if (pbr && !specular && (r = load_pbr(mesh, is_obj, am, kdv, m)) != PM_OK)
        return r;
    return PM_OK;
}
