/* scene_hash.c: the scene's identity (scene.h: hash, parts, pm_scene_id): hashes of what was
 * loaded, so that a file's SCENE key says which scene, and which part of it, made it. */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <errno.h>
#include <inttypes.h>
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "base/exr.h"
#include "base/hash.h"
#include "formats/formats.h"
#include "math/vec.h"
#include "render/scene_load.h"

void pm_scene_id(const pm_scene_t *s, char *out, size_t cap) { pm_scene_id_part(s, PM_SCENE_ALL, out, cap); }

int pm_scene_id_matches(const pm_scene_t *s, const char *key)
{
    char id[300], old[200];
    pm_scene_id(s, id, sizeof id);
    snprintf(old, sizeof old, "%s xxh3:%016llx", s->name, (unsigned long long)s->hash);
    return strcmp(key, id) == 0 || strcmp(key, old) == 0;
}

void pm_scene_id_part(const pm_scene_t *s, pm_scene_part_t part, char *out, size_t cap)
{
    int n = snprintf(out, cap, "%s xxh3:%016llx", s->name, (unsigned long long)s->parts.geometry);
    if (n >= 0 && (size_t)n < cap && part != PM_SCENE_VIEW)
        n += snprintf(out + n, cap - (size_t)n, " photons:xxh3:%016llx", (unsigned long long)s->parts.photons);
    if (n >= 0 && (size_t)n < cap && part != PM_SCENE_PHOTONS)
        snprintf(out + n, cap - (size_t)n, " view:xxh3:%016llx", (unsigned long long)s->parts.view);
}

/* The materials' share of the scene hash. Without a mirror or glass, each material's bytes up
 * to its specular fields (name to ke, no padding), as the hash took them before those fields
 * existed, so that such a scene's identity, and every file naming it, stays what it was. */
pm_result_t pm_scene_hash_materials(const pm_scene_t *s, uint64_t *out)
{
    int specular = 0;
    for (size_t m = 0; m < s->nmaterials; m++)
        specular |= pm_material_is_specular(&s->materials[m]);
    if (specular) {
        *out = pm_hash_bytes(s->materials, s->nmaterials * sizeof *s->materials);
        return PM_OK;
    }
    size_t head = offsetof(pm_material_t, kind);
    unsigned char *buf = malloc(s->nmaterials ? s->nmaterials * head : 1);
    if (!buf)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    for (size_t m = 0; m < s->nmaterials; m++)
        memcpy(buf + m * head, &s->materials[m], head);
    *out = pm_hash_bytes(buf, s->nmaterials * head);
    free(buf);
    return PM_OK;
}

/* The point lights' hash: position and intensity of each, the bytes a scene without spots
 * always hashed (its hash stays what it was), then the spots' axes, cones and falloffs when
 * there is any spot. */
pm_result_t pm_scene_hash_lights(const pm_scene_t *s, uint64_t *hash_out)
{
    float *b = calloc((s->nlights ? s->nlights : 1) * 6, sizeof(float));
    if (!b)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the hash of %zu lights", s->nlights);
    int spot = 0;
    for (size_t i = 0; i < s->nlights; i++) {
        memcpy(b + 6 * i, s->lights[i].position, 3 * sizeof(float));
        memcpy(b + 6 * i + 3, s->lights[i].intensity, 3 * sizeof(float));
        spot |= pm_point_light_is_spot(&s->lights[i]);
    }
    uint64_t h[2] = {pm_hash_bytes(b, s->nlights * 6 * sizeof(float)), 0};
    free(b);
    *hash_out = h[0];
    if (!spot)
        return PM_OK;
    for (size_t i = 0; i < s->nlights; i++) {
        const pm_point_light_t *l = &s->lights[i];
        float v[5] = {l->axis[0], l->axis[1], l->axis[2], l->cos_cone, l->falloff};
        h[1] = pm_hash_bytes((uint64_t[2]){h[1], pm_hash_bytes(v, sizeof v)}, 2 * sizeof(uint64_t));
    }
    *hash_out = pm_hash_bytes(h, sizeof h);
    return PM_OK;
}

/* The scene's parts (scene.h, pm_scene_hash_t), from what was loaded rather than the scene
 * file's bytes, so that an edit to the camera leaves the photons' part alone. h: the hashes
 * of the geometry, triangle materials, materials and point lights the whole hash took. */
void pm_scene_hash_parts(pm_scene_t *s, const uint64_t h[6])
{
    uint64_t g[6] = {h[1], h[2], h[3], h[4], 0, 0};
    if (s->maps) {
        g[4] = pm_hash_bytes(s->uvs, 2 * s->nverts * sizeof(float));
        g[5] = pm_hash_bytes(s->maps, s->nmaterials * sizeof *s->maps);
        for (size_t i = 0; i < s->ntextures; i++)
            g[5] = pm_hash_bytes((uint64_t[2]){g[5], s->textures[i].hash}, 2 * sizeof(uint64_t));
    }
    s->parts.geometry = pm_hash_bytes(g, sizeof g);
    if (s->normals) /* shading normals shade both sides' files; a scene without them keeps its hash */
        s->parts.geometry =
            pm_hash_bytes((uint64_t[2]){s->parts.geometry, pm_hash_bytes(s->normals, 3 * s->nverts * sizeof(float))},
                          2 * sizeof(uint64_t));
    /* The render block's keys each side reads as a default: the photons' count and seed,
     * the eye side's rays, seed and the query order's leaf; the gather's width (radius, k)
     * goes with both, as the map and the queries both carry it on. */
    const pm_render_defaults_t *d = &s->defaults;
    int64_t pk[4] = {d->photons, d->seed, d->k, 0},
            ek[6] = {d->spp, d->primary, d->light_samples, d->seed, d->leaf, d->k};
    memcpy(&pk[3], &d->radius, sizeof pk[3]);
    uint64_t p[4] = {s->parts.geometry, h[5], pm_hash_bytes(pk, sizeof pk), 0};
    s->parts.photons = pm_hash_bytes(p, sizeof p);
    const pm_camera_t *c = &s->camera;
    float cam[12] = {c->eye[0],     c->eye[1],     c->eye[2], c->look_at[0],
                     c->look_at[1], c->look_at[2], c->up[0],  c->up[1],
                     c->up[2],      c->fov_y,      0,         0};
    uint32_t size[2] = {c->width, c->height};
    uint64_t v[5] = {s->parts.geometry, pm_hash_bytes(cam, sizeof cam), pm_hash_bytes(size, sizeof size),
                     pm_hash_bytes(ek, sizeof ek), 0};
    memcpy(&v[4], &d->radius, sizeof v[4]);
    s->parts.view = pm_hash_bytes(v, sizeof v);
    uint64_t e[2] = {s->parts.photons, s->parts.view};
    s->parts.eye = pm_hash_bytes(e, sizeof e);
}
