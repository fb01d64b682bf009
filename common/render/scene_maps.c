/* scene_maps.c: the textures a material honours (MTL map_Kd, map_Ks, map_d, norm, bump; glTF's
 * base colour and normal texture), each file loaded once per scene, relative to the .mtl that
 * names it, or decoded from the mesh file itself (a .glb's or data-URI glTF's "*N"), within the
 * scene's image budgets. */
#include "render/scene.h"

#include <assimp/material.h>
#include <assimp/scene.h>
#include <assimp/texture.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "render/scene_load.h"

/* The folder texture names of material `name` are relative to: the .mtl that defines it (an
 * OBJ; im->homes) or the mesh file itself (glTF and the rest, and a name no .mtl defines). */
static void texture_base(const char *mesh, const import_t *im, const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s", mesh);
    for (size_t i = 0; i < im->nhomes; i++)
        if (strcmp(im->homes[i].name, name) == 0) {
            snprintf(out, cap, "%s", im->homes[i].lib);
            return;
        }
}

static double mib(uint64_t b) { return b / (1024.0 * 1024.0); }
static uint64_t bytes(double mib) { return (uint64_t)(mib * (1 << 20)); }

/* Texture t decoded from file path (tx NULL) or from assimp's embedded texture tx (size bytes
 * when compressed; path names it), within the smaller of the per-texture budget and what the
 * all-textures budget has left. */
static pm_result_t budget_for(const ctx_t *c, const char *path, const struct aiTexture *tx, size_t size,
                              pm_texture_t *t)
{
    uint64_t used = 0;
    for (size_t i = 0; i < c->s->ntextures; i++)
        used += pm_texture_bytes(&c->s->textures[i]);
    uint64_t all = bytes(c->textures_mib), left = used < all ? all - used : 0, max = bytes(c->texture_mib);
    char budget[160];
    if (left < max) {
        max = left;
        snprintf(budget, sizeof budget, "image_budgets.textures_mib %.6g over all textures, %llu bytes of it taken",
                 c->textures_mib, (unsigned long long)used);
    } else {
        snprintf(budget, sizeof budget, "image_budgets.texture_mib %.6g", c->texture_mib);
    }
    if (!tx)
        return pm_texture_load_budget(path, max, budget, t);
    if (tx->mHeight == 0) /* compressed: mWidth bytes of a PNG, JPEG, ... file */
        return pm_texture_decode(path, tx->achFormatHint, tx->pcData, size, max, budget, t);
    return pm_texture_from_bgra(path, tx->mWidth, tx->mHeight, (const uint8_t *)tx->pcData, max, budget, t);
}

pm_result_t pm_scene_load_image_budgets(ctx_t *c, json_t *b)
{
    static const char *const keys[] = {"texture_mib", "textures_mib", "sky_map_mib", NULL};
    double tex = mib(PM_TEXTURE_BUDGET_DEFAULT), all = 4.0 * tex, sky = mib(PM_ENVMAP_BUDGET_DEFAULT);
    pm_result_t r = PM_OK;
    if (b && !json_is_object(b))
        return pm_scene_bad(c, "image_budgets", "must be an object of texture_mib, textures_mib, sky_map_mib");
    /* MiB: up to 1 TiB, and at least one byte */
    if (b && (r = pm_scene_only_keys(c, b, "image_budgets", keys)) == PM_OK)
        r = pm_scene_get_number(c, b, "texture_mib", "image_budgets.texture_mib", 0, 1.0 / (1 << 20), 1 << 20, &tex);
    if (b && r == PM_OK)
        r = pm_scene_get_number(c, b, "textures_mib", "image_budgets.textures_mib", 0, 1.0 / (1 << 20), 1 << 20, &all);
    if (b && r == PM_OK)
        r = pm_scene_get_number(c, b, "sky_map_mib", "image_budgets.sky_map_mib", 0, 1.0 / (1 << 20), 1 << 20, &sky);
    c->texture_mib = tex, c->textures_mib = all, c->sky_map_mib = sky;
    return r;
}

/* The scene texture named key as *index_out (*loaded_out 1), or room for one more (0). */
static pm_result_t find_or_grow(pm_scene_t *s, const char *key, int32_t *index_out, int *loaded_out)
{
    for (size_t i = 0; i < s->ntextures; i++)
        if (strcmp(s->textures[i].path, key) == 0) {
            *index_out = (int32_t)i;
            *loaded_out = 1;
            return PM_OK;
        }
    *loaded_out = 0;
    return pm_scene_grow((void **)&s->textures, s->ntextures + 1, sizeof *s->textures);
}

/* The texture embedded in mesh file `mesh` as name ("*N": aiScene::mTextures[N]) as scene
 * texture *index_out, decoded once per scene through the same decoders as files. */
static pm_result_t embedded_texture(const ctx_t *c, const import_t *im, const char *name, const char *mesh,
                                    const pm_material_t *m, const char *key, int32_t *index_out)
{
    pm_scene_t *s = c->s;
    char *end = NULL;
    unsigned long n = strtoul(name + 1, &end, 10);
    if (name[1] < '0' || name[1] > '9' || *end || !im->as || n >= im->as->mNumTextures || !im->as->mTextures[n])
        return pm_error_set(PM_ERR_INPUT,
                            "mesh '%s': material '%s': %s '%s': no such embedded texture (the file has %u)", mesh,
                            m->name, key, name, im->as ? im->as->mNumTextures : 0);
    char label[1300];
    snprintf(label, sizeof label, "%s:%s", mesh, name);
    int loaded = 0;
    pm_result_t r = find_or_grow(s, label, index_out, &loaded);
    if (r != PM_OK || loaded)
        return r;
    const struct aiTexture *tx = im->as->mTextures[n];
    if ((r = budget_for(c, label, tx, tx->mHeight == 0 ? tx->mWidth : 0, &s->textures[s->ntextures])) != PM_OK) {
        pm_error_prefix("mesh '%s': material '%s': %s '%s'", mesh, m->name, key, name);
        return r;
    }
    *index_out = (int32_t)s->ntextures++;
    return PM_OK;
}

/* The texture file `name` (relative to the file base) as scene texture *index_out, loaded once
 * per scene. A name with Windows separators (Crytek Sponza's "textures\\x.png") is read with
 * '/' when it does not open as written. A missing file is an error naming the material, or
 * under missing_textures "magenta" a magenta texture and a warning. */
pm_result_t pm_scene_texture(const ctx_t *c, const char *base, const char *name, const char *mesh,
                             const pm_material_t *m, uint32_t mi, const char *key, int32_t *index_out)
{
    pm_scene_t *s = c->s;
    char path[1200];
    pm_scene_resolve(base, name, path, sizeof path);
    /* stat, not open: a FIFO must not block here (pm_texture_load_budget refuses it) */
    struct stat st;
    int found = stat(path, &st) == 0;
    if (!found && strchr(name, '\\')) {
        char alt[1024];
        snprintf(alt, sizeof alt, "%s", name);
        for (char *q = alt; *q; q++)
            if (*q == '\\')
                *q = '/';
        char altpath[1200];
        pm_scene_resolve(base, alt, altpath, sizeof altpath);
        if ((found = stat(altpath, &st) == 0) != 0)
            snprintf(path, sizeof path, "%s", altpath);
    }
    int missing = !found && errno == ENOENT;
    /* both names when the second was tried: the first's appearing would change the scene */
    char first[1200], alt[1024], second[1200];
    pm_scene_resolve(base, name, first, sizeof first);
    pm_result_t r0 = pm_scene_add_source(s, first);
    if (r0 == PM_OK && strchr(name, '\\')) {
        snprintf(alt, sizeof alt, "%s", name);
        for (char *q = alt; *q; q++)
            if (*q == '\\')
                *q = '/';
        pm_scene_resolve(base, alt, second, sizeof second);
        r0 = pm_scene_add_source(s, second);
    }
    if (r0 != PM_OK)
        return r0;
    int loaded = 0;
    pm_result_t r = find_or_grow(s, path, index_out, &loaded);
    if (r != PM_OK || loaded)
        return r;
    pm_texture_t *t = &s->textures[s->ntextures];
    if (missing && c->missing_magenta) {
        static const float magenta[3] = {1, 0, 1};
        if ((r = pm_texture_solid(path, magenta, t)) != PM_OK)
            return r;
        if ((r = pm_scene_note_unsupported(s, mi, key, 1, path)) != PM_OK) {
            pm_texture_free(t);
            return r;
        }
        s->unsupported[s->nunsupported - 1].missing = 1;
    } else if ((r = budget_for(c, path, NULL, 0, t)) != PM_OK) {
        pm_error_prefix("mesh '%s': material '%s': %s '%s'", mesh, m->name, key, name);
        return r;
    }
    *index_out = (int32_t)s->ntextures++;
    return PM_OK;
}

/* Whether texture t has colour: a texel whose channels differ. */
static int is_colour(const pm_texture_t *t)
{
    size_t n = (size_t)t->w * t->h;
    if (t->grey)
        return 0;
    for (size_t i = 0; i < n; i++) {
        if (t->u8 && (t->u8[4 * i] != t->u8[4 * i + 1] || t->u8[4 * i + 1] != t->u8[4 * i + 2]))
            return 1;
        if (t->f32 && (t->f32[4 * i] != t->f32[4 * i + 1] || t->f32[4 * i + 1] != t->f32[4 * i + 2]))
            return 1;
    }
    return 0;
}

/* glTF's KHR_texture_transform of texture slot `type`, as assimp 5.2's glTF 2 importer stores it
 * ($tex.uvtrafo: scaling, the rotation negated, and a translation that folds in its flip of v and
 * a turn about the image centre), taken back to the extension's offset o, rotation r and scale s
 * and then into pmtk's uv space (v = 1 - v_glTF): the extension's T(o) R(r) S(s) acting on
 * (u, 1 - v), R's columns (cos r, -sin r) and (sin r, cos r) (u' = cos r u + sin r v: Khronos's
 * TextureTransformTest sample shows its green markers so; the other sign shows the red one), as
 * xf (pm_material_maps_t uvxf). 1: a finite transform; 0: none; -1: one with a value that is
 * not finite. */
static int gltf_uv_transform(const struct aiMaterial *am, enum aiTextureType type, float xf[6])
{
    ai_real t[5]; /* aiUVTransform: mTranslation x, y; mScaling x, y; mRotation */
    unsigned n = 5;
    if (aiGetMaterialFloatArray(am, _AI_MATKEY_UVTRANSFORM_BASE, type, 0, t, &n) != aiReturn_SUCCESS || n != 5)
        return 0;
    double sx = t[2], sy = t[3], r = -(double)t[4], c = cos(r), sn = sin(r);
    double ox = t[0] - 0.5 * sx * (1.0 - c + sn), oy = 0.5 * sy * (sn + c - 1.0) + 1.0 - sy - t[1];
    /* u' = ox + c sx u_g + sn sy v_g, v_g' = oy - sn sx u_g + c sy v_g, with v_g = 1 - v, v' = 1 - v_g' */
    double m[6] = {c * sx, -sn * sy, ox + sn * sy, sn * sx, c * sy, 1.0 - oy - c * sy};
    for (int k = 0; k < 6; k++) {
        if (!isfinite(m[k]) || fabs(m[k]) > 1e30)
            return -1;
        xf[k] = (float)m[k];
    }
    return 1;
}

/* The texture transform (glTF KHR_texture_transform) and texture coordinate set of material
 * mi's textured slots: pmtk reads the first set, transformed per material (it moves the
 * vertices' coordinates), so the first textured slot's transform is the material's; a slot that
 * names another set or another transform, or a transform in a format whose convention pmtk does
 * not know, is reported once per material. */
static pm_result_t uv_transform(pm_scene_t *s, const struct aiMaterial *am, int gltf, uint32_t mi,
                                const enum aiTextureType *types, const int32_t *tex, size_t nslots)
{
    pm_material_maps_t *mm = &s->maps[mi];
    pm_result_t r = PM_OK;
    int seen = 0;
    for (size_t k = 0; k < nslots && r == PM_OK; k++) {
        if (tex[k] < 0)
            continue;
        int src = 0;
        char value[160];
        const char *slot = aiTextureTypeToString(types[k]);
        if (aiGetMaterialInteger(am, _AI_MATKEY_UVWSRC_BASE, types[k], 0, &src) == aiReturn_SUCCESS && src != 0) {
            snprintf(value, sizeof value, "%d on the %s texture (set 0 used)", src, slot);
            if ((r = pm_scene_note_unsupported(s, mi, "texCoord", 0, value)) != PM_OK)
                break;
        }
        float xf[6];
        int got = gltf_uv_transform(am, types[k], xf);
        if (got != 0 && !gltf) {
            snprintf(value, sizeof value, "on the %s texture (not applied)", slot);
            r = pm_scene_note_unsupported(s, mi, "texture transform", 0, value);
        } else if (got < 0) {
            snprintf(value, sizeof value, "not finite on the %s texture (not applied)", slot);
            r = pm_scene_note_unsupported(s, mi, "KHR_texture_transform", 0, value);
        } else if (!seen) {
            if ((mm->has_uvxf = got) != 0)
                memcpy(mm->uvxf, xf, sizeof xf);
        } else if (got != mm->has_uvxf || (got && memcmp(mm->uvxf, xf, sizeof xf) != 0)) {
            snprintf(value, sizeof value, "differs on the %s texture (the first textured slot's used)", slot);
            r = pm_scene_note_unsupported(s, mi, "KHR_texture_transform", 0, value);
        }
        seen = 1;
    }
    return r;
}

/* The textures pmtk honours of assimp material am (scene material mi): map_Kd, map_Ks, map_d,
 * norm and bump/map_Bump (with its -bm) of an MTL, the base colour and the normal texture of
 * glTF and the rest (assimp's diffuse and normals slots). */
pm_result_t pm_scene_load_material_maps(const ctx_t *c, const char *mesh, int is_obj, const import_t *im,
                                        const struct aiMaterial *am, uint32_t mi)
{
    pm_scene_t *s = c->s;
    pm_material_maps_t *mm = &s->maps[mi];
    const pm_material_t *m = &s->materials[mi];
    static const struct {
        enum aiTextureType type;
        const char *obj_key, *other_key;
    } slots[] = {{aiTextureType_DIFFUSE, "map_Kd", "diffuse texture"},
                 {aiTextureType_SPECULAR, "map_Ks", NULL},
                 {aiTextureType_OPACITY, "map_d", NULL},
                 {aiTextureType_NORMALS, "norm", "normal texture"},
                 {aiTextureType_HEIGHT, "bump", NULL}};
    _Static_assert(sizeof slots / sizeof slots[0] == PM_MAP_SLOTS, "a texture slot per map slot");
    int32_t *where[PM_MAP_SLOTS]; /* the slots in the order of slots[] */
    pm_material_map_slots(mm, where);
    char base[1200] = "";
    pm_result_t r = PM_OK;
    for (size_t k = 0; k < sizeof slots / sizeof slots[0] && r == PM_OK; k++) {
        const char *key = is_obj ? slots[k].obj_key : slots[k].other_key;
        struct aiString tp;
        if (!key ||
            aiGetMaterialTexture(am, slots[k].type, 0, &tp, NULL, NULL, NULL, NULL, NULL, NULL) != aiReturn_SUCCESS ||
            tp.length == 0)
            continue;
        if (slots[k].type == aiTextureType_OPACITY && pm_material_is_emissive(m)) {
            /* light sampling draws points over an emitter's whole area: cut-outs would not match */
            r = pm_scene_note_unsupported(s, mi, "map_d on an emitter", 1, tp.data);
            continue;
        }
        if (!base[0])
            texture_base(mesh, im, m->name, base, sizeof base);
        r = tp.data[0] == '*' ? embedded_texture(c, im, tp.data, mesh, m, key, where[k]) /* in the glTF or .glb */
                              : pm_scene_texture(c, base, tp.data, mesh, m, mi, key, where[k]);
        if (r == PM_OK && slots[k].type == aiTextureType_OPACITY)
            s->any_alpha = 1;
    }
    /* glTF keeps its normal texture in the glTF 2 slot as well (mtl.c maps it the same way) */
    struct aiString tp;
    int from_camera = 0;
    if (r == PM_OK && !is_obj && mm->normal < 0 &&
        aiGetMaterialTexture(am, aiTextureType_NORMAL_CAMERA, 0, &tp, NULL, NULL, NULL, NULL, NULL, NULL) ==
            aiReturn_SUCCESS &&
        tp.length > 0) {
        if (!base[0])
            texture_base(mesh, im, m->name, base, sizeof base);
        r = tp.data[0] == '*' ? embedded_texture(c, im, tp.data, mesh, m, "normal texture", &mm->normal)
                              : pm_scene_texture(c, base, tp.data, mesh, m, mi, "normal texture", &mm->normal);
        from_camera = 1;
    }
    /* texture transforms, from the slots as assimp filled them (the normal texture in one of two) */
    const enum aiTextureType types[] = {aiTextureType_DIFFUSE, aiTextureType_SPECULAR, aiTextureType_OPACITY,
                                        aiTextureType_NORMALS, aiTextureType_HEIGHT,   aiTextureType_NORMAL_CAMERA};
    const int32_t tex[] = {
        mm->kd, mm->ks, mm->alpha, from_camera ? -1 : mm->normal, mm->bump, from_camera ? mm->normal : -1};
    size_t n = strlen(mesh);
    int gltf = (n > 5 && strcasecmp(mesh + n - 5, ".gltf") == 0) || (n > 4 && strcasecmp(mesh + n - 4, ".glb") == 0);
    if (r == PM_OK)
        r = uv_transform(s, am, gltf, mi, types, tex, sizeof tex / sizeof tex[0]);
    /* A colour image in the bump slot is a normal map (Blender's OBJ exporter writes its normal
     * maps as map_Bump): read as one, and said so. Heights are grey, R = G = B in every texel. */
    if (r == PM_OK && mm->bump >= 0 && mm->normal < 0 && is_colour(&s->textures[mm->bump])) {
        mm->normal = mm->bump, mm->bump = -1;
        if ((r = pm_scene_note_unsupported(s, mi, "bump", 1, s->textures[mm->normal].path)) == PM_OK)
            snprintf(s->unsupported[s->nunsupported - 1].note, sizeof s->unsupported[0].note,
                     "a colour image: read as a tangent-space normal map");
    }
    /* MTL's -bm: assimp 5.2 puts it on the texture ($tex.bumpmult), some importers on the material */
    float bm = 1.0f;
    if (mm->bump >= 0 &&
        (aiGetMaterialFloat(am, "$tex.bumpmult", aiTextureType_HEIGHT, 0, &bm) == aiReturn_SUCCESS ||
         aiGetMaterialFloat(am, "$mat.bumpscaling", 0, 0, &bm) == aiReturn_SUCCESS) &&
        isfinite(bm))
        mm->bump_scale = bm;
    return r;
}
