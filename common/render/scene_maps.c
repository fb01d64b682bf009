/* scene_maps.c: the textures a material honours (MTL map_Kd, map_Ks, map_d; glTF's base colour),
 * each file loaded once per scene, relative to the .mtl that names it. */
#include "render/scene.h"

#include <assimp/material.h>
#include <errno.h>
#include <stdio.h>
#include <string.h>

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
    FILE *probe = fopen(path, "rb");
    if (!probe && strchr(name, '\\')) {
        char alt[1024];
        snprintf(alt, sizeof alt, "%s", name);
        for (char *q = alt; *q; q++)
            if (*q == '\\')
                *q = '/';
        char altpath[1200];
        pm_scene_resolve(base, alt, altpath, sizeof altpath);
        if ((probe = fopen(altpath, "rb")) != NULL)
            snprintf(path, sizeof path, "%s", altpath);
    }
    int missing = !probe && errno == ENOENT;
    if (probe)
        fclose(probe);
    for (size_t i = 0; i < s->ntextures; i++)
        if (strcmp(s->textures[i].path, path) == 0) {
            *index_out = (int32_t)i;
            return PM_OK;
        }
    pm_result_t r = pm_scene_grow((void **)&s->textures, s->ntextures + 1, sizeof *s->textures);
    if (r != PM_OK)
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
    } else if ((r = pm_texture_load(path, t)) != PM_OK) {
        pm_error_prefix("mesh '%s': material '%s': %s '%s'", mesh, m->name, key, name);
        return r;
    }
    *index_out = (int32_t)s->ntextures++;
    return PM_OK;
}

/* The textures pmtk honours of assimp material am (scene material mi): map_Kd, map_Ks and map_d
 * of an MTL, the base colour of glTF and the rest (assimp's diffuse slot). */
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
                 {aiTextureType_OPACITY, "map_d", NULL}};
    char base[1200] = "";
    pm_result_t r = PM_OK;
    for (size_t k = 0; k < 3 && r == PM_OK; k++) {
        const char *key = is_obj ? slots[k].obj_key : slots[k].other_key;
        struct aiString tp;
        if (!key ||
            aiGetMaterialTexture(am, slots[k].type, 0, &tp, NULL, NULL, NULL, NULL, NULL, NULL) != aiReturn_SUCCESS ||
            tp.length == 0)
            continue;
        if (tp.data[0] == '*') { /* a texture inside the glTF (or .glb): not read */
            r = pm_scene_note_unsupported(s, mi, "embedded texture", 1, tp.data);
            continue;
        }
        if (slots[k].type == aiTextureType_OPACITY && pm_material_is_emissive(m)) {
            /* light sampling draws points over an emitter's whole area: cut-outs would not match */
            r = pm_scene_note_unsupported(s, mi, "map_d on an emitter", 1, tp.data);
            continue;
        }
        if (!base[0])
            texture_base(mesh, im, m->name, base, sizeof base);
        int32_t *slot = k == 0 ? &mm->kd : k == 1 ? &mm->ks : &mm->alpha;
        r = pm_scene_texture(c, base, tp.data, mesh, m, mi, key, slot);
        if (r == PM_OK && k == 2)
            s->any_alpha = 1;
    }
    return r;
}
