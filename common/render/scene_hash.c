/* scene_hash.c: the scene's identity (scene.h: hash, parts, pm_scene_id): XXH3-64 of a canonical
 * serialisation of what was loaded, so that a file's SCENE key says which scene, and which part
 * of it, made it. Every value is written field by field in a fixed order and byte order (integers
 * and IEEE float bits little-endian, strings as a length and their bytes) behind a version tag,
 * never as the bytes of a C struct: padding, the bytes after a name's end and the fields a kind
 * does not use are never read, and a new field changes nothing until it is written here (with
 * the tag's version raised). */
#include "render/scene.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>
#define XXH_STATIC_LINKING_ONLY /* XXH3_state_t on the stack: no allocation, no failure */
#include <xxhash.h>

#include "base/hash.h"
#include "render/scene_load.h"

/* The serialisation's version: raised whenever what is written, or its order, changes, so that
 * an old identity can never be mistaken for a new one. */
#define PM_SCENE_IDENTITY_TAG "pmtk scene identity 2"

/* A serialisation being hashed: bytes staged in buf and fed to XXH3's streaming state. */
typedef struct {
    XXH3_state_t st;
    unsigned char buf[4096];
    size_t n;
} ident_t;

static void put(ident_t *w, const void *data, size_t n)
{
    const unsigned char *p = data;
    if (n >= sizeof w->buf) { /* a large array: straight through, after what is staged */
        XXH3_64bits_update(&w->st, w->buf, w->n);
        w->n = 0;
        XXH3_64bits_update(&w->st, p, n);
        return;
    }
    if (w->n + n > sizeof w->buf) {
        XXH3_64bits_update(&w->st, w->buf, w->n);
        w->n = 0;
    }
    memcpy(w->buf + w->n, p, n);
    w->n += n;
}

static void put_u32(ident_t *w, uint32_t v)
{
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    put(w, b, sizeof b);
}

static void put_u64(ident_t *w, uint64_t v)
{
    put_u32(w, (uint32_t)v);
    put_u32(w, (uint32_t)(v >> 32));
}

static void put_f32(ident_t *w, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(w, u);
}

static void put_f64(ident_t *w, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    put_u64(w, u);
}

/* n floats (or 32-bit integers: u32 1), their count first. On a little-endian host an array's
 * bytes are its serialisation; elsewhere each value is written in turn. */
static void put_array32(ident_t *w, const void *a, size_t n)
{
    put_u64(w, n);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    if (n)
        put(w, a, 4 * n);
#else
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, (const unsigned char *)a + 4 * i, sizeof u);
        put_u32(w, u);
    }
#endif
}

static void put_f32s(ident_t *w, const float *f, size_t n)
{
    for (size_t i = 0; i < n; i++)
        put_f32(w, f[i]);
}

/* A string up to its end (a fixed-size field's bytes after the terminator are not read). */
static void put_str(ident_t *w, const char *s, size_t cap)
{
    size_t n = strnlen(s, cap);
    put_u32(w, (uint32_t)n);
    put(w, s, n);
}

/* A section's name, so that the sections of a serialisation can never run into each other. */
static void put_section(ident_t *w, const char *name) { put_str(w, name, 64); }

static void ident_begin(ident_t *w, const char *section)
{
    XXH3_64bits_reset(&w->st);
    w->n = 0;
    put_section(w, PM_SCENE_IDENTITY_TAG);
    put_section(w, section);
}

static uint64_t ident_end(ident_t *w)
{
    XXH3_64bits_update(&w->st, w->buf, w->n);
    w->n = 0;
    return XXH3_64bits_digest(&w->st);
}

/* One material: its name, kind and emission, then the fields its kind reads (material.h), in
 * this order. A standard material's Phong exponent only where it has a Phong lobe. */
static void put_material(ident_t *w, const pm_material_t *m)
{
    put_str(w, m->name, sizeof m->name);
    put_u32(w, (uint32_t)m->kind);
    put_f32s(w, m->ke, 3);
    if (m->two_sided && pm_material_is_emissive(m)) /* only then: other scenes keep their identity */
        put_str(w, "two-sided", 10);
    switch (m->kind) {
    case PM_MAT_STANDARD:
        put_f32s(w, m->kd, 3);
        put_f32s(w, m->ks, 3);
        if (pm_material_is_glossy(m))
            put_f32(w, m->ns);
        break;
    case PM_MAT_MIRROR: put_f32s(w, m->kr, 3); break;
    case PM_MAT_GLASS:
        put_f32(w, m->ior);
        put_f32s(w, m->tf, 3);
        break;
    case PM_MAT_CONDUCTOR:
        put_f32(w, m->alpha);
        put_u32(w, m->eta[0] > 0.0f); /* a complex index, or Schlick's F0 */
        if (m->eta[0] > 0.0f) {
            put_f32s(w, m->eta, 3);
            put_f32s(w, m->k, 3);
        } else {
            put_f32s(w, m->f0, 3);
        }
        break;
    case PM_MAT_ROUGH_GLASS:
        put_f32(w, m->alpha);
        put_f32(w, m->ior);
        put_f32s(w, m->tf, 3);
        break;
    case PM_MAT_PLASTIC:
        put_f32s(w, m->kd, 3);
        put_f32(w, m->ior);
        put_f32(w, m->alpha);
        break;
    default: /* a kind this file does not know yet: every field, so that none is left out */
        put_f32s(w, m->kd, 3);
        put_f32s(w, m->ks, 3);
        put_f32(w, m->ns);
        put_f32s(w, m->kr, 3);
        put_f32(w, m->ior);
        put_f32s(w, m->tf, 3);
        put_f32(w, m->alpha);
        put_f32s(w, m->eta, 3);
        put_f32s(w, m->k, 3);
        put_f32s(w, m->f0, 3);
        break;
    }
}

static void put_materials(ident_t *w, const pm_material_t *m, size_t n)
{
    put_section(w, "materials");
    put_u64(w, n);
    for (size_t i = 0; i < n; i++)
        put_material(w, &m[i]);
}

/* One point light: position and intensity; a spot's axis, cone and falloff (an isotropic
 * light does not read them). */
static void put_light(ident_t *w, const pm_point_light_t *l)
{
    put_f32s(w, l->position, 3);
    put_f32s(w, l->intensity, 3);
    put_u32(w, (uint32_t)pm_point_light_is_spot(l));
    if (pm_point_light_is_spot(l)) {
        put_f32s(w, l->axis, 3);
        put_f32(w, l->cos_cone);
        put_f32(w, l->falloff);
    }
}

static void put_lights(ident_t *w, const pm_point_light_t *l, size_t n)
{
    put_section(w, "point lights");
    put_u64(w, n);
    for (size_t i = 0; i < n; i++)
        put_light(w, &l[i]);
}

uint64_t pm_scene_materials_hash(const pm_material_t *m, size_t n)
{
    ident_t w;
    ident_begin(&w, "materials only");
    put_materials(&w, m, n);
    return ident_end(&w);
}

uint64_t pm_scene_lights_hash(const pm_point_light_t *l, size_t n)
{
    ident_t w;
    ident_begin(&w, "point lights only");
    put_lights(&w, l, n);
    return ident_end(&w);
}

/* The geometry part: triangles, their materials, textures (coordinates, which material uses
 * which, each texture's texels by its hash) and vertex normals. */
static uint64_t geometry_part(const pm_scene_t *s)
{
    ident_t w;
    ident_begin(&w, "geometry");
    put_section(&w, "vertices");
    put_array32(&w, s->verts, 3 * s->nverts);
    put_section(&w, "triangles");
    put_array32(&w, s->tris, 3 * s->ntris);
    put_array32(&w, s->tri_material, s->ntris);
    put_materials(&w, s->materials, s->nmaterials);
    put_section(&w, "textures");
    put_u32(&w, s->maps != NULL);
    if (s->maps) {
        put_array32(&w, s->uvs, 2 * s->nverts);
        for (size_t m = 0; m < s->nmaterials; m++) {
            put_u32(&w, (uint32_t)s->maps[m].kd);
            put_u32(&w, (uint32_t)s->maps[m].ks);
            put_u32(&w, (uint32_t)s->maps[m].alpha);
            if (s->maps[m].normal >= 0 || s->maps[m].bump >= 0) { /* (a material without either hashes as before) */
                put_u32(&w, (uint32_t)s->maps[m].normal);
                put_u32(&w, (uint32_t)s->maps[m].bump);
                put_f32(&w, s->maps[m].bump_scale);
            }
        }
        put_u64(&w, s->ntextures);
        for (size_t i = 0; i < s->ntextures; i++)
            put_u64(&w, s->textures[i].hash);
    }
    put_section(&w, "vertex normals");
    put_u32(&w, s->normals != NULL);
    if (s->normals)
        put_array32(&w, s->normals, 3 * s->nverts);
    return ident_end(&w);
}

/* The photons' part: the geometry part, every light (point lights, two-sided emitters, the sun,
 * the sky and its map, the portals) and the render block's keys photon tracing and the map read. */
static uint64_t photons_part(const pm_scene_t *s)
{
    const pm_render_defaults_t *d = &s->defaults;
    ident_t w;
    ident_begin(&w, "photons");
    put_u64(&w, s->parts.geometry);
    put_lights(&w, s->lights, s->nlights);
    put_section(&w, "emitters");
    put_u32(&w, (uint32_t)s->two_sided_lights);
    put_section(&w, "sun");
    put_u32(&w, (uint32_t)s->has_sun);
    if (s->has_sun) {
        put_f32s(&w, s->sun.direction, 3);
        put_f32s(&w, s->sun.radiance, 3);
        put_f32(&w, s->sun.solid_angle);
    }
    put_section(&w, "sky");
    put_u32(&w, (uint32_t)s->has_sky);
    put_u32(&w, s->envmap != NULL);
    if (s->has_sky && !s->envmap)
        put_f32s(&w, s->sky, 3);
    if (s->envmap) { /* its texels, already scaled by the sky's radiance */
        put_u32(&w, s->envmap->w);
        put_u32(&w, s->envmap->h);
        put_array32(&w, s->envmap->rgb, 3 * (size_t)s->envmap->w * s->envmap->h);
        if (s->envmap->framed) /* turned by sky.up and sky.rotate (an unturned map hashes as before) */
            for (int i = 0; i < 9; i++)
                put_f64(&w, s->envmap->frame[i]);
    }
    if (s->nportals) { /* where the sun's and the sky's photons enter (a scene without keeps its hash) */
        put_section(&w, "portals");
        put_u64(&w, (uint64_t)s->nportals);
        for (size_t i = 0; i < s->nportals; i++) {
            put_f32s(&w, s->portals[i].corner, 3);
            put_f32s(&w, s->portals[i].edge_u, 3);
            put_f32s(&w, s->portals[i].edge_v, 3);
            put_f32s(&w, s->portals[i].inward, 3);
        }
    }
    put_section(&w, "photon keys");
    put_u64(&w, (uint64_t)d->photons);
    put_u64(&w, (uint64_t)d->seed);
    put_u64(&w, (uint64_t)d->k);
    put_f64(&w, d->radius);
    return ident_end(&w);
}

/* The view's part: the geometry part, the camera, the image size and the render block's keys
 * the eye side reads (its rays, seed, the queries' order, the gather's width). */
static uint64_t view_part(const pm_scene_t *s)
{
    const pm_camera_t *c = &s->camera;
    const pm_render_defaults_t *d = &s->defaults;
    ident_t w;
    ident_begin(&w, "view");
    put_u64(&w, s->parts.geometry);
    put_section(&w, "camera");
    put_f32s(&w, c->eye, 3);
    put_f32s(&w, c->look_at, 3);
    put_f32s(&w, c->up, 3);
    put_f32(&w, c->fov_y);
    put_u32(&w, c->width);
    put_u32(&w, c->height);
    put_section(&w, "eye keys");
    put_u64(&w, (uint64_t)d->spp);
    put_u64(&w, (uint64_t)d->primary);
    put_u64(&w, (uint64_t)d->light_samples);
    put_u64(&w, (uint64_t)d->seed);
    put_u64(&w, (uint64_t)d->leaf);
    put_u64(&w, (uint64_t)d->k);
    put_f64(&w, d->radius);
    return ident_end(&w);
}

pm_result_t pm_scene_identify(pm_scene_t *s)
{
    uint64_t file;
    pm_result_t r = pm_hash_file(s->path, &file);
    if (r != PM_OK)
        return r;
    s->parts.geometry = geometry_part(s);
    s->parts.photons = photons_part(s);
    s->parts.view = view_part(s);
    ident_t w;
    ident_begin(&w, "eye");
    put_u64(&w, s->parts.photons);
    put_u64(&w, s->parts.view);
    s->parts.eye = ident_end(&w);
    /* the whole: the scene file's own bytes (any edit to it) and everything loaded through it */
    ident_begin(&w, "scene");
    put_u64(&w, file);
    put_u64(&w, s->parts.eye);
    s->hash = ident_end(&w);
    return PM_OK;
}

void pm_scene_id(const pm_scene_t *s, char *out, size_t cap) { pm_scene_id_part(s, PM_SCENE_ALL, out, cap); }

int pm_scene_id_matches(const pm_scene_t *s, const char *key)
{
    char id[300];
    pm_scene_id(s, id, sizeof id);
    return strcmp(key, id) == 0;
}

void pm_scene_id_part(const pm_scene_t *s, pm_scene_part_t part, char *out, size_t cap)
{
    int n = snprintf(out, cap, "%s xxh3:%016llx", s->name, (unsigned long long)s->parts.geometry);
    if (n >= 0 && (size_t)n < cap && part != PM_SCENE_VIEW)
        n += snprintf(out + n, cap - (size_t)n, " photons:xxh3:%016llx", (unsigned long long)s->parts.photons);
    if (n >= 0 && (size_t)n < cap && part != PM_SCENE_PHOTONS)
        snprintf(out + n, cap - (size_t)n, " view:xxh3:%016llx", (unsigned long long)s->parts.view);
}
