/* scene.c: the scene reader (docs/scene-format.md): pm_scene_load reads the scene file (scene_json.c),
 * imports its meshes (mesh.c, scene_material.c, mtl.c, scene_maps.c), keeps the materials some
 * triangle uses and hashes what was loaded (scene_hash.c); and what a loaded scene derives: its
 * power, bounds, bounding sphere and flipped emitters, and its warnings. */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <errno.h>
#include <inttypes.h>
#include <jansson.h>
#include <malloc.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/hash.h"
#include "math/vec.h"
#include "render/scene_load.h"

/* Resolves a mesh file name relative to the scene file's folder. */
void pm_scene_resolve(const char *scene_path, const char *file, char *out, size_t cap)
{
    const char *slash = strrchr(scene_path, '/');
    if (file[0] == '/' || !slash)
        snprintf(out, cap, "%s", file);
    else
        snprintf(out, cap, "%.*s/%s", (int)(slash - scene_path), scene_path, file);
}

int pm_scene_source_now(const char *path, uint64_t *hash_out)
{
    struct stat st;
    *hash_out = 0;
    if (stat(path, &st) != 0)
        return errno == ENOENT ? 0 : -1;
    return S_ISREG(st.st_mode) && pm_hash_file(path, hash_out) == PM_OK ? 1 : -1;
}

pm_result_t pm_scene_add_source(pm_scene_t *s, const char *path)
{
    if (s->uncacheable)
        return PM_OK; /* no cache will be written: nothing to hash */
    for (size_t i = 0; i < s->nsources; i++)
        if (strcmp(s->sources[i].path, path) == 0)
            return PM_OK;
    if (strlen(path) >= sizeof s->sources->path) {
        s->uncacheable = 1; /* a path the cache cannot name */
        return PM_OK;
    }
    pm_result_t r = pm_scene_grow((void **)&s->sources, s->nsources + 1, sizeof *s->sources);
    if (r != PM_OK)
        return r;
    pm_scene_source_t *src = &s->sources[s->nsources];
    memset(src, 0, sizeof *src);
    snprintf(src->path, sizeof src->path, "%s", path);
    int now = pm_scene_source_now(path, &src->hash);
    if (now < 0) {
        s->uncacheable = 1; /* the load refuses it or reads it its own way */
        return PM_OK;
    }
    src->absent = now == 0;
    s->nsources++;
    return PM_OK;
}

pm_result_t pm_scene_grow(void **p, size_t n, size_t size)
{
    /* Geometric: the loaders grow their arrays an element or a mesh at a time, and a realloc
     * that copies every time (AddressSanitizer's always does) made N placements quadratic
     * (30,000: 269 s under ASan). The block's usable size is its capacity. */
    size_t want = (n ? n : 1) * size, have = *p ? malloc_usable_size(*p) : 0;
    if (want <= have)
        return PM_OK;
    size_t cap = want < 2 * have ? 2 * have : want;
    void *q = realloc(*p, cap);
    if (!q && cap > want)
        q = realloc(*p, cap = want);
    if (!q)
        return pm_error_set(PM_ERR_NOMEM, "out of memory loading meshes");
    *p = q;
    return PM_OK;
}

/* Shrinks the block at *p to bytes (at least 1) when that frees much; a failure keeps it. */
static void trim(void **p, size_t bytes)
{
    if (!*p || malloc_usable_size(*p) < bytes + bytes / 8 + 4096)
        return;
    void *q = realloc(*p, bytes ? bytes : 1);
    if (q)
        *p = q;
}

void pm_scene_sphere(const pm_scene_t *s, double c[3], double *radius_out)
{
    double r2 = 0.0;
    for (int k = 0; k < 3; k++) {
        double h = 0.5 * ((double)s->bounds[k + 3] - s->bounds[k]);
        c[k] = 0.5 * ((double)s->bounds[k] + s->bounds[k + 3]);
        r2 += h * h;
    }
    /* 1% and a millimetre beyond the box's corners: photons start clear of every surface. */
    *radius_out = 1.01 * sqrt(r2) + 1e-3;
}

double pm_sun_power(const pm_scene_t *s, int k)
{
    if (s->nportals)
        return s->portal_power[0][k];
    double c[3], r;
    pm_scene_sphere(s, c, &r);
    /* L times the cone's solid angle times the disc's area pi R^2 (render/transport.h, pm_env_emit). */
    return s->sun.radiance[k] * (double)s->sun.solid_angle * M_PI * r * r;
}

double pm_sky_power(const pm_scene_t *s, int k)
{
    if (s->nportals)
        return s->portal_power[1][k];
    double c[3], r;
    pm_scene_sphere(s, c, &r);
    if (s->envmap)
        return s->envmap->integral[k] * M_PI * r * r;
    return s->sky[k] * M_PI * r * r * 4.0 * M_PI;
}

double pm_point_light_power(const pm_point_light_t *l, int k)
{
    if (!pm_point_light_is_spot(l))
        return 4.0 * M_PI * l->intensity[k];
    /* The integral of s over the sphere: 2 pi times that of ((c - cc) / (1 - cc))^e dc over [cc, 1]. */
    return 2.0 * M_PI * l->intensity[k] * (1.0 - (double)l->cos_cone) / ((double)l->falloff + 1.0);
}

double pm_scene_triangle_area(const pm_scene_t *s, size_t t)
{
    const float *a = &s->verts[3 * s->tris[3 * t]], *b = &s->verts[3 * s->tris[3 * t + 1]],
                *c = &s->verts[3 * s->tris[3 * t + 2]];
    double e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

void pm_scene_power(const pm_scene_t *s, double p[3])
{
    p[0] = p[1] = p[2] = 0.0;
    for (size_t i = 0; i < s->nlights; i++)
        for (int k = 0; k < 3; k++)
            p[k] += pm_point_light_power(&s->lights[i], k);
    for (size_t i = 0; i < s->nemissive; i++) {
        size_t t = s->emissive[i];
        double a = pm_scene_triangle_area(s, t);
        for (int k = 0; k < 3; k++)
            p[k] +=
                (pm_scene_emits_both(s, (uint32_t)t) ? 2.0 : 1.0) * M_PI * s->materials[s->tri_material[t]].ke[k] * a;
    }
    for (int k = 0; k < 3 && s->has_sun; k++)
        p[k] += pm_sun_power(s, k);
    for (int k = 0; k < 3 && s->has_sky; k++)
        p[k] += pm_sky_power(s, k);
}

/* The box around every vertex loaded (those of left-out triangles too), m; inverted when none. */
static void vertex_box(const pm_scene_t *s, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; k++)
        lo[k] = INFINITY, hi[k] = -INFINITY;
    for (size_t v = 0; v < s->nverts; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], s->verts[3 * v + k]);
            hi[k] = fmax(hi[k], s->verts[3 * v + k]);
        }
}

/* Whether vertex p lies in front of the plane of a triangle (corner a, unit normal n): by more
 * than 1e-2 of its distance from a (0.6 degrees: a ceiling a hair above a lamp set into it does not count,
 * whatever the scene's size or where its lights are) plus the rounding of float coordinates of
 * magnitude mag. */
static int sees_vertex(const double a[3], const double n[3], const float *p, double mag)
{
    double d[3] = {(double)p[0] - a[0], (double)p[1] - a[1], (double)p[2] - a[2]};
    double h = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    return h > 1e-2 * sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-6 * mag;
}

typedef struct {
    int32_t key[3]; /* the unit normal on a grid of 1/4096 */
    uint32_t tri;   /* an emissive triangle */
} flip_item_t;

static int flip_item_cmp(const void *pa, const void *pb)
{
    const flip_item_t *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a->key[k] != b->key[k])
            return a->key[k] < b->key[k] ? -1 : 1;
    return a->tri < b->tri ? -1 : a->tri > b->tri;
}

/* The unit normal of triangle t in double; 0 when it has none. */
static int unit_normal(const pm_scene_t *s, uint32_t t, double a_out[3], double n_out[3])
{
    const uint32_t *v = &s->tris[3 * (size_t)t];
    const float *a = &s->verts[3 * (size_t)v[0]], *b = &s->verts[3 * (size_t)v[1]], *c = &s->verts[3 * (size_t)v[2]];
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) {
        a_out[k] = a[k];
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
    }
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !isfinite(len))
        return 0;
    for (int k = 0; k < 3; k++)
        n_out[k] = n[k] / len;
    return 1;
}

/* Emitters facing one way (a lamp placed N times) share one pass over the vertices: sorted by
 * their normal on a grid, each run keeps the first member's normal n0, the vertex farthest
 * along it and that distance M. A member (corner a, normal n) sees the scene when that vertex
 * is in front of it; it sees nothing when even the bound M - a.n0 + R |n - n0| on every
 * vertex's height above its plane (R: the largest distance of a vertex from a) is within the
 * rounding allowance; only between the two are all vertices tried. So N placements of a lamp
 * cost N + the vertices, not N times them. */
size_t pm_scene_flipped_emitters(const pm_scene_t *s, uint32_t *first_out)
{
    size_t n = 0;
    *first_out = 0;
    if (s->two_sided_lights || !s->nemissive)
        return 0; /* both faces emit: no winding faces away */
    double lo[3], hi[3], mag = 0.0;
    vertex_box(s, lo, hi);
    for (int k = 0; k < 3; k++)
        mag = fmax(mag, fmax(fabs(lo[k]), fabs(hi[k])));
    flip_item_t *items = malloc(s->nemissive * sizeof *items);
    size_t ni = 0;
    for (size_t i = 0; i < s->nemissive; i++) {
        if (pm_scene_emits_both(s, s->emissive[i]))
            continue; /* both faces emit: no winding faces away */
        double a[3], nrm[3];
        if (!unit_normal(s, s->emissive[i], a, nrm))
            continue;
        if (!items) { /* no memory for the shortcut: every vertex for every emitter */
            int sees = 0;
            for (size_t v = 0; v < s->nverts && !sees; v++)
                sees = sees_vertex(a, nrm, &s->verts[3 * v], mag);
            if (!sees && n++ == 0)
                *first_out = s->emissive[i];
            continue;
        }
        items[ni].tri = s->emissive[i];
        for (int k = 0; k < 3; k++)
            items[ni].key[k] = (int32_t)lround(nrm[k] * 4096.0);
        ni++;
    }
    if (!items)
        return n;
    qsort(items, ni, sizeof *items, flip_item_cmp);
    uint32_t first = UINT32_MAX;
    double n0[3] = {0, 0, 0}, top = 0.0;
    size_t far = 0;
    for (size_t i = 0; i < ni; i++) {
        double a[3], nrm[3];
        unit_normal(s, items[i].tri, a, nrm);
        if (i == 0 || memcmp(items[i].key, items[i - 1].key, sizeof items[i].key) != 0) {
            memcpy(n0, nrm, sizeof n0);
            top = -INFINITY;
            for (size_t v = 0; v < s->nverts; v++) {
                const float *p = &s->verts[3 * v];
                double h = p[0] * n0[0] + p[1] * n0[1] + p[2] * n0[2];
                if (h > top)
                    top = h, far = v;
            }
        }
        if (sees_vertex(a, nrm, &s->verts[3 * far], mag))
            continue;
        double dn = 0.0, r2 = 0.0;
        for (int k = 0; k < 3; k++) {
            dn += (nrm[k] - n0[k]) * (nrm[k] - n0[k]);
            double ext = fmax(fabs(hi[k] - a[k]), fabs(lo[k] - a[k]));
            r2 += ext * ext;
        }
        double bound = top - (a[0] * n0[0] + a[1] * n0[1] + a[2] * n0[2]) + sqrt(r2) * sqrt(dn);
        int sees = 0;
        if (!(bound <= 1e-6 * mag))
            for (size_t v = 0; v < s->nverts && !sees; v++)
                sees = sees_vertex(a, nrm, &s->verts[3 * v], mag);
        if (!sees) {
            n++;
            first = items[i].tri < first ? items[i].tri : first;
        }
    }
    free(items);
    *first_out = n ? first : 0;
    return n;
}

/* Keeps only materials some triangle uses (assimp adds a default one to every OBJ),
 * so that a scene of one material needs no material ids downstream. */
static pm_result_t compact_materials(pm_scene_t *s)
{
    uint32_t *map = malloc((s->nmaterials ? s->nmaterials : 1) * sizeof *map);
    if (!map)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    for (size_t m = 0; m < s->nmaterials; m++)
        map[m] = UINT32_MAX;
    for (size_t t = 0; t < s->ntris; t++)
        map[s->tri_material[t]] = 0;
    size_t n = 0;
    for (size_t m = 0; m < s->nmaterials; m++)
        if (map[m] == 0) {
            s->materials[n] = s->materials[m];
            if (s->maps)
                s->maps[n] = s->maps[m];
            map[m] = (uint32_t)n++;
        }
    for (size_t t = 0; t < s->ntris; t++)
        s->tri_material[t] = map[s->tri_material[t]];
    /* What a dropped material would not honour matters to no triangle. */
    size_t nu = 0;
    for (size_t i = 0; i < s->nunsupported; i++)
        if (map[s->unsupported[i].material] != UINT32_MAX) {
            s->unsupported[nu] = s->unsupported[i];
            s->unsupported[nu++].material = map[s->unsupported[i].material];
        }
    s->nunsupported = nu;
    s->nmaterials = n;
    free(map);
    return PM_OK;
}

/* Frees the texture tables of a scene whose materials (those kept) use no texture, so that it
 * pays nothing for the feature. */
static pm_result_t drop_unused_maps(pm_scene_t *s)
{
    int any = 0;
    for (size_t m = 0; s->maps && m < s->nmaterials; m++) {
        int32_t *slot[PM_MAP_SLOTS];
        pm_material_map_slots(&s->maps[m], slot);
        for (int k = 0; k < PM_MAP_SLOTS; k++)
            any |= *slot[k] >= 0;
    }
    if (!any) {
        free(s->maps);
        free(s->uvs);
        s->maps = NULL;
        s->uvs = NULL;
        s->any_alpha = 0;
    } else {
        s->any_alpha = 0;
        for (size_t m = 0; m < s->nmaterials; m++)
            s->any_alpha |= s->maps[m].alpha >= 0;
    }
    /* Textures no kept material reads (an asset material the scene file replaced, or one no
     * triangle uses) are freed, so that they are neither listed nor hashed. */
    int32_t *keep = calloc(s->ntextures ? s->ntextures : 1, sizeof *keep);
    if (!keep)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    for (size_t m = 0; s->maps && m < s->nmaterials; m++) {
        int32_t *slot[PM_MAP_SLOTS];
        pm_material_map_slots(&s->maps[m], slot);
        for (int k = 0; k < PM_MAP_SLOTS; k++)
            if (*slot[k] >= 0)
                keep[*slot[k]] = 1;
    }
    size_t n = 0;
    for (size_t i = 0; i < s->ntextures; i++) {
        if (!keep[i]) {
            pm_texture_free(&s->textures[i]);
            continue;
        }
        s->textures[n] = s->textures[i];
        keep[i] = (int32_t)n++;
    }
    s->ntextures = n;
    for (size_t m = 0; s->maps && m < s->nmaterials; m++) {
        int32_t *slot[PM_MAP_SLOTS];
        pm_material_map_slots(&s->maps[m], slot);
        for (int k = 0; k < PM_MAP_SLOTS; k++)
            if (*slot[k] >= 0)
                *slot[k] = keep[*slot[k]];
    }
    free(keep);
    return PM_OK;
}

static void finish(pm_scene_t *s)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t t = 0; t < s->ntris; t++)
        for (int v = 0; v < 3; v++)
            for (int k = 0; k < 3; k++) {
                float x = s->verts[3 * s->tris[3 * t + v] + k];
                lo[k] = fminf(lo[k], x);
                hi[k] = fmaxf(hi[k], x);
            }
    for (size_t i = 0; i < s->nlights; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fminf(lo[k], s->lights[i].position[k]);
            hi[k] = fmaxf(hi[k], s->lights[i].position[k]);
        }
    for (int k = 0; k < 3; k++) {
        s->bounds[k] = lo[k] <= hi[k] ? lo[k] : 0.0f;
        s->bounds[k + 3] = lo[k] <= hi[k] ? hi[k] : 0.0f;
    }
    for (size_t m = 0; m < s->nmaterials; m++) {
        s->any_glossy |= pm_material_is_glossy(&s->materials[m]);
        s->any_specular |= pm_material_is_specular(&s->materials[m]);
        s->any_glossy_textured |= pm_scene_glossy_textured(s, (uint32_t)m);
    }
}

/* Refuses geometry too small to render: the longest side of the box around every vertex
 * loaded (those of left-out triangles too), so that a scene scaled below the limit is named
 * and refused rather than rendered black with every triangle left out. */
static pm_result_t check_size(const ctx_t *c)
{
    const pm_scene_t *s = c->s;
    if (!s->nverts)
        return PM_OK;
    double lo[3], hi[3], size = 0.0;
    vertex_box(s, lo, hi);
    for (int k = 0; k < 3; k++)
        size = fmax(size, hi[k] - lo[k]);
    if (size < PM_SCENE_SIZE_MIN)
        return pm_scene_bad(c, "meshes",
                            "the geometry spans %g m, below the smallest scene pmtk renders, %g m (float normals "
                            "and ray hits fail below it): scale it up with meshes[].scale",
                            size, PM_SCENE_SIZE_MIN);
    return PM_OK;
}

pm_result_t pm_scene_load_files(const char *path, int keyed, pm_scene_t *s)
{
    memset(s, 0, sizeof *s);
    s->uncacheable = !keyed; /* a load no cache will hold hashes none of its files */
    ctx_t c = {.file = path, .s = s, .camera_mesh = -1};
    snprintf(s->path, sizeof s->path, "%s", path);
    json_error_t je;
    pm_result_t r0 = pm_scene_check_regular(path, "scene"); /* a FIFO would block every stage */
    if (r0 == PM_OK)
        r0 = pm_scene_add_source(s, path);
    if (r0 != PM_OK) {
        pm_scene_free(s);
        return r0;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        pm_scene_free(s);
        return pm_error_set(pm_result_of_errno(e), "cannot open scene '%s': %s", path, strerror(e));
    }
    json_t *root = json_loadf(f, JSON_REJECT_DUPLICATES, &je);
    fclose(f);
    if (!root) {
        pm_scene_free(s);
        return pm_error_set(PM_ERR_INPUT, "scene '%s' line %d column %d: %s", path, je.line, je.column, je.text);
    }
    /* clang-format off */
    static const char *const keys[] = {
        "pmtk_scene", "name",   "meshes",           "camera",     "point_lights",     "sun",
        "sky",        "render", "missing_textures", "instancing", "two_sided_lights", "shading_normals",
        "materials",  "shapes", "image_budgets",    "portals",    NULL};
    /* clang-format on */
    pm_result_t r = json_is_object(root) ? pm_scene_only_keys(&c, root, "top level", keys)
                                         : pm_scene_bad(&c, "top level", "must be a JSON object");
    int64_t version = 0;
    if (r == PM_OK)
        r = pm_scene_get_int(&c, root, "pmtk_scene", "pmtk_scene", 1, 1, 1, &version);
    const char *name = json_string_value(json_object_get(root, "name"));
    int name_control = 0; /* a control byte (files and terminals would show it as a space) */
    for (const char *p = name; p && *p; p++)
        name_control |= (unsigned char)*p < 0x20 || *p == 0x7f;
    if (r == PM_OK && (!name || !*name || strlen(name) >= sizeof s->name || strchr(name, ' ') || name_control))
        r = pm_scene_bad(&c, "name", "must be a non-empty string without spaces or control bytes, under %zu bytes",
                         sizeof s->name);
    if (r == PM_OK)
        snprintf(s->name, sizeof s->name, "%s", name);
    json_t *mt = json_object_get(root, "missing_textures");
    if (r == PM_OK && mt) {
        const char *v = json_string_value(mt);
        if (v && strcmp(v, "magenta") == 0)
            c.missing_magenta = 1;
        else if (!v || strcmp(v, "error") != 0)
            r = pm_scene_bad(&c, "missing_textures", "must be \"error\" (the default) or \"magenta\"");
    }
    if (r == PM_OK)
        r = pm_scene_load_image_budgets(&c, json_object_get(root, "image_budgets"));
    if (r == PM_OK)
        r = pm_scene_load_scene_materials(&c, json_object_get(root, "materials"));
    json_t *meshes = json_object_get(root, "meshes");
    if (r == PM_OK && meshes && !json_is_array(meshes))
        r = pm_scene_bad(&c, "meshes", "must be an array");
    json_t *cam = json_object_get(root, "camera");
    size_t nmeshes = meshes ? json_array_size(meshes) : 0;
    if (r == PM_OK && json_is_object(cam) && json_object_get(cam, "mesh"))
        r = nmeshes ? pm_scene_get_int(&c, cam, "mesh", "camera.mesh", 1, 0, (int64_t)nmeshes - 1, &c.camera_mesh)
                    : pm_scene_bad(&c, "camera.mesh", "names a mesh entry, and the scene has none");
    for (size_t i = 0; r == PM_OK && meshes && i < json_array_size(meshes); i++) {
        pm_scene_guard_entry(path, i);
        r = pm_scene_load_mesh(&c, json_array_get(meshes, i), i);
        pm_scene_release_import(&c, meshes, i);
        /* Mesh and material faults name the mesh; say which scene entry brought it in. */
        if (r == PM_ERR_INPUT && strncmp(pm_error_message(), "scene '", 7) != 0)
            pm_error_prefix("scene '%s': meshes[%zu]", path, i);
    }
    if (r == PM_OK)
        r = pm_scene_load_shapes(&c, json_object_get(root, "shapes"));
    /* the arrays grew geometrically (pm_scene_grow): give the slack back for the render */
    if (r == PM_OK) {
        trim((void **)&s->verts, 3 * s->nverts * sizeof(float));
        trim((void **)&s->uvs, 2 * s->nverts * sizeof(float));
        trim((void **)&s->normals, 3 * s->nverts * sizeof(float));
        trim((void **)&s->tris, 3 * s->ntris * sizeof(uint32_t));
        trim((void **)&s->tri_material, s->ntris * sizeof(uint32_t));
    }
    json_t *two = json_object_get(root, "two_sided_lights");
    if (r == PM_OK && two && !json_is_boolean(two))
        r = pm_scene_bad(&c, "two_sided_lights",
                         "must be true or false (the default: emitters light from their front face)");
    s->two_sided_lights = two && json_is_true(two);
    json_t *shn = json_object_get(root, "shading_normals");
    if (r == PM_OK && shn && !json_is_boolean(shn))
        r = pm_scene_bad(&c, "shading_normals",
                         "must be true (the default: the meshes' vertex normals shade) or false");
    s->normals_ignored = shn && json_is_false(shn) && c.any_normals;
    if (r == PM_OK && ((shn && json_is_false(shn)) || !c.any_normals)) {
        /* Ignored, or no mesh has any: geometric normals, and nothing to pay for the feature. */
        free(s->normals);
        s->normals = NULL;
    }
    json_t *inst = json_object_get(root, "instancing");
    if (r == PM_OK && inst && !json_is_boolean(inst))
        r = pm_scene_bad(&c, "instancing", "must be true (the default) or false");
    if (r == PM_OK)
        r = pm_scene_find_instances(&c, !inst || json_is_true(inst), &s->instances_flat);
    for (size_t i = 0; i < c.nimports; i++) {
        if (c.imports[i].as)
            aiReleaseImport(c.imports[i].as);
        free(c.imports[i].homes);
    }
    free(c.imports);
    free(c.local);
    free(c.smats);
    free(c.smaps);
    if (r == PM_OK)
        r = check_size(&c);
    if (r == PM_OK)
        r = pm_scene_load_camera(&c, json_object_get(root, "camera"));
    free(c.acams);
    if (r == PM_OK)
        r = pm_scene_load_lights(&c, json_object_get(root, "point_lights"));
    if (r == PM_OK)
        r = pm_scene_load_sun_sky(&c, json_object_get(root, "sun"), json_object_get(root, "sky"));
    if (r == PM_OK)
        r = pm_scene_load_portals(&c, json_object_get(root, "portals"));
    if (r == PM_OK)
        r = pm_scene_add_asset_lights(&c);
    free(c.alights);
    if (r == PM_OK)
        r = pm_scene_load_defaults(&c, json_object_get(root, "render"));
    json_decref(root);
    if (r == PM_OK)
        r = compact_materials(s);
    if (r == PM_OK) {
        s->emissive = malloc((s->ntris ? s->ntris : 1) * sizeof *s->emissive);
        if (!s->emissive)
            r = pm_error_set(PM_ERR_NOMEM, "out of memory");
        for (size_t t = 0; r == PM_OK && t < s->ntris; t++)
            if (pm_material_is_emissive(&s->materials[s->tri_material[t]]))
                s->emissive[s->nemissive++] = (uint32_t)t;
    }
    /* The scene's identity: its file's bytes plus everything loaded through it, so a change to a
     * mesh or an .mtl changes the hash even when scene.json does not (scene_hash.c). */
    if (r == PM_OK && (r = drop_unused_maps(s)) == PM_OK)
        r = pm_scene_identify(s);
    if (r == PM_OK)
        finish(s);
    /* a file edited while the scene loaded: what was read may be neither its old nor its new
     * bytes, and no cache may say it is either */
    for (size_t i = 0; r == PM_OK && !s->uncacheable && i < s->nsources; i++) {
        uint64_t h;
        int now = pm_scene_source_now(s->sources[i].path, &h);
        if (now != !s->sources[i].absent || h != s->sources[i].hash)
            s->uncacheable = 1;
    }
    if (r != PM_OK)
        pm_scene_free(s);
    return r;
}

void pm_scene_free(pm_scene_t *s)
{
    free(s->verts);
    free(s->tris);
    free(s->tri_material);
    free(s->materials);
    free(s->lights);
    if (s->envmap)
        pm_envmap_free(s->envmap);
    free(s->envmap);
    free(s->portals);
    free(s->emissive);
    free(s->unsupported);
    free(s->maps);
    free(s->uvs);
    free(s->normals);
    free(s->placements);
    free(s->local_verts);
    free(s->notes);
    free(s->sources);
    for (size_t i = 0; i < s->ntextures; i++)
        pm_texture_free(&s->textures[i]);
    free(s->textures);
    memset(s, 0, sizeof *s);
}

void pm_scene_unsupported_text(const pm_scene_unsupported_t *u, char *out, size_t cap)
{
    int n = snprintf(out, cap, u->is_file ? "%s '%s'" : "%s %s", u->key, u->value);
    if (u->note[0] && n >= 0 && (size_t)n < cap)
        snprintf(out + n, cap - (size_t)n, " (approximated: %s)", u->note);
}

void pm_scene_warn_flipped(const pm_scene_t *s, const pm_stage_t *st)
{
    uint32_t ft;
    size_t nf = pm_scene_flipped_emitters(s, &ft);
    if (nf)
        pm_stage_note(st,
                      "warning: %zu emissive triangle%s face%s away from the whole scene (first: triangle %" PRIu32
                      ", material '%s'): %s light reaches nothing but leaks out as fireflies; reverse the winding "
                      "in the mesh file",
                      nf, nf == 1 ? "" : "s", nf == 1 ? "s" : "", ft, s->materials[s->tri_material[ft]].name,
                      nf == 1 ? "its" : "their");
}

void pm_scene_warn_unsupported(const pm_scene_t *s, const pm_stage_t *st)
{
    for (size_t i = 0; i < s->nnotes; i++)
        pm_stage_note(st, "%s: %s", s->notes[i].warning ? "warning" : "note", s->notes[i].text);
    for (size_t i = 0; i < s->nunsupported; i++) {
        char text[300];
        pm_scene_unsupported_text(&s->unsupported[i], text, sizeof text);
        const pm_scene_unsupported_t *u = &s->unsupported[i];
        if (u->note[0])
            pm_stage_note(st, "warning: material '%s': %s %s is approximated: %s", s->materials[u->material].name,
                          u->key, u->value, u->note);
        else if (s->unsupported[i].missing)
            pm_stage_note(st, "warning: material '%s': %s is missing: rendered magenta (missing_textures)",
                          s->materials[s->unsupported[i].material].name, text);
        else
            pm_stage_note(st, "warning: material '%s': %s is not supported (ignored)",
                          s->materials[s->unsupported[i].material].name, text);
    }
}
