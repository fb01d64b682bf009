/* scene.c: the scene file reader (JSON through jansson, meshes through assimp's C API). */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "base/hash.h"

#define PM_SCENE_MAX_TRIS (1u << 30) /* triangles: 32-bit indices with room to spare */
#define PM_SCENE_MAX_LIGHTS 65536
#define PM_SCENE_COORD_MAX 1e30 /* m: beyond this, float products overflow */

typedef struct {
    const char *file; /* the scene file, for messages */
    pm_scene_t *s;
} ctx_t;

static pm_result_t bad(const ctx_t *c, const char *key, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static pm_result_t bad(const ctx_t *c, const char *key, const char *fmt, ...)
{
    char detail[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    return pm_error_set(PM_ERR_INPUT, "scene '%s': %s: %s", c->file, key, detail);
}

/* Unknown keys are errors: a typo must not silently fall back to a default. */
static pm_result_t only_keys(const ctx_t *c, json_t *obj, const char *where, const char *const *allowed)
{
    const char *k;
    json_t *v;
    json_object_foreach(obj, k, v)
    {
        int ok = 0;
        for (const char *const *a = allowed; *a && !ok; a++)
            ok = strcmp(*a, k) == 0;
        if (!ok) {
            char list[256] = "";
            for (const char *const *a = allowed; *a; a++) {
                strncat(list, a == allowed ? "" : ", ", sizeof list - strlen(list) - 1);
                strncat(list, *a, sizeof list - strlen(list) - 1);
            }
            return bad(c, where, "unknown key '%s' (known: %s)", k, list);
        }
    }
    return PM_OK;
}

/* obj's member name into *v_out: NULL when it is absent and optional (leave the
 * default), an error naming path when it is absent and required. */
static pm_result_t member(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, json_t **v_out)
{
    *v_out = json_object_get(obj, name);
    return !*v_out && required ? bad(c, path, "missing") : PM_OK;
}

static pm_result_t get_number(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, double lo,
                              double hi, double *out)
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_number(v))
        return bad(c, path, "must be a number");
    double x = json_number_value(v);
    if (!isfinite(x) || x < lo || x > hi)
        return bad(c, path, "%.9g is outside [%.9g, %.9g]", x, lo, hi);
    *out = x;
    return PM_OK;
}

static pm_result_t get_int(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, int64_t lo,
                           int64_t hi, int64_t *out)
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_integer(v))
        return bad(c, path, "must be an integer");
    int64_t x = json_integer_value(v);
    if (x < lo || x > hi)
        return bad(c, path, "%lld is outside [%lld, %lld]", (long long)x, (long long)lo, (long long)hi);
    *out = x;
    return PM_OK;
}

static pm_result_t get_vec3(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, double lo,
                            double hi, float out[3])
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_array(v) || json_array_size(v) != 3)
        return bad(c, path, "must be an array of 3 numbers");
    for (size_t i = 0; i < 3; i++) {
        json_t *e = json_array_get(v, i);
        if (!json_is_number(e))
            return bad(c, path, "element %zu is not a number", i);
        double x = json_number_value(e);
        if (!isfinite(x) || x < lo || x > hi)
            return bad(c, path, "element %zu = %.9g is outside [%.9g, %.9g]", i, x, lo, hi);
        out[i] = (float)x;
    }
    return PM_OK;
}

static pm_result_t load_camera(const ctx_t *c, json_t *cam)
{
    static const char *const keys[] = {"eye", "look_at", "up", "fov_y", "width", "height", NULL};
    pm_camera_t *k = &c->s->camera;
    if (!json_is_object(cam))
        return bad(c, "camera", "missing or not an object");
    pm_result_t r = only_keys(c, cam, "camera", keys);
    double fov = 0;
    int64_t w = 0, h = 0;
    k->up[0] = 0, k->up[1] = 1, k->up[2] = 0;
    if (r == PM_OK)
        r = get_vec3(c, cam, "eye", "camera.eye", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, k->eye);
    if (r == PM_OK)
        r = get_vec3(c, cam, "look_at", "camera.look_at", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, k->look_at);
    if (r == PM_OK)
        r = get_vec3(c, cam, "up", "camera.up", 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, k->up);
    if (r == PM_OK)
        r = get_number(c, cam, "fov_y", "camera.fov_y", 1, 1e-3, 179.0, &fov);
    if (r == PM_OK)
        r = get_int(c, cam, "width", "camera.width", 1, 1, 65536, &w);
    if (r == PM_OK)
        r = get_int(c, cam, "height", "camera.height", 1, 1, 65536, &h);
    if (r != PM_OK)
        return r;
    k->fov_y = (float)fov;
    k->width = (uint32_t)w;
    k->height = (uint32_t)h;
    double d[3], up[3] = {k->up[0], k->up[1], k->up[2]}, dl = 0, ul = 0, dot = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = (double)k->look_at[i] - k->eye[i];
        dl += d[i] * d[i];
        ul += up[i] * up[i];
        dot += d[i] * up[i];
    }
    if (!(dl > 0))
        return bad(c, "camera.look_at", "equals camera.eye: no view direction");
    if (!(ul > 0))
        return bad(c, "camera.up", "is the zero vector");
    if (fabs(dot) >= 0.999999 * sqrt(dl * ul))
        return bad(c, "camera.up", "is parallel to the view direction");
    return PM_OK;
}

static pm_result_t load_lights(const ctx_t *c, json_t *lights)
{
    static const char *const keys[] = {"position", "intensity", NULL};
    if (!lights)
        return PM_OK;
    if (!json_is_array(lights))
        return bad(c, "point_lights", "must be an array");
    size_t n = json_array_size(lights);
    if (n > PM_SCENE_MAX_LIGHTS)
        return bad(c, "point_lights", "%zu lights, more than %u", n, PM_SCENE_MAX_LIGHTS);
    c->s->lights = calloc(n ? n : 1, sizeof *c->s->lights);
    if (!c->s->lights)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu lights", n);
    for (size_t i = 0; i < n; i++) {
        json_t *l = json_array_get(lights, i);
        char where[64], p1[80], p2[80];
        snprintf(where, sizeof where, "point_lights[%zu]", i);
        snprintf(p1, sizeof p1, "%s.position", where);
        snprintf(p2, sizeof p2, "%s.intensity", where);
        if (!json_is_object(l))
            return bad(c, where, "must be an object");
        pm_point_light_t *pl = &c->s->lights[i];
        pm_result_t r = only_keys(c, l, where, keys);
        if (r == PM_OK)
            r = get_vec3(c, l, "position", p1, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, pl->position);
        /* 1e30 W/sr: far beyond any light, still leaves headroom in float products. */
        if (r == PM_OK)
            r = get_vec3(c, l, "intensity", p2, 1, 0.0, 1e30, pl->intensity);
        if (r != PM_OK)
            return r;
    }
    c->s->nlights = n;
    return PM_OK;
}

static pm_result_t load_defaults(const ctx_t *c, json_t *d)
{
    static const char *const keys[] = {"photons", "spp",  "primary", "light_samples", "radius", "k",
                                       "leaf",    "seed", NULL};
    pm_render_defaults_t *o = &c->s->defaults;
    o->photons = 200000;
    o->spp = 16;
    o->primary = 1;
    o->light_samples = 4;
    o->radius = 0.0;
    o->k = 50;
    o->leaf = 16;
    o->seed = 1;
    if (!d)
        return PM_OK;
    if (!json_is_object(d))
        return bad(c, "render", "must be an object");
    pm_result_t r = only_keys(c, d, "render", keys);
    if (r == PM_OK)
        r = get_int(c, d, "photons", "render.photons", 0, 0, (int64_t)1 << 40, &o->photons);
    if (r == PM_OK)
        r = get_int(c, d, "spp", "render.spp", 0, 1, 1 << 20, &o->spp);
    if (r == PM_OK)
        r = get_int(c, d, "primary", "render.primary", 0, 1, 4096, &o->primary);
    if (r == PM_OK)
        r = get_int(c, d, "light_samples", "render.light_samples", 0, 0, 65536, &o->light_samples);
    if (r == PM_OK)
        r = get_number(c, d, "radius", "render.radius", 0, 0.0, PM_SCENE_COORD_MAX, &o->radius);
    if (r == PM_OK)
        r = get_int(c, d, "k", "render.k", 0, 1, 1 << 20, &o->k);
    if (r == PM_OK)
        r = get_int(c, d, "leaf", "render.leaf", 0, 1, 1 << 30, &o->leaf);
    if (r == PM_OK)
        r = get_int(c, d, "seed", "render.seed", 0, 0, INT64_MAX, &o->seed);
    return r;
}

/* Reads one material's reflectance from assimp and checks it is physical. */
static pm_result_t load_material(const ctx_t *c, const char *mesh, const struct aiMaterial *am, pm_material_t *m)
{
    struct aiString name;
    struct aiColor4D kd = {0.8f, 0.8f, 0.8f, 1}, ks = {0, 0, 0, 1}, ke = {0, 0, 0, 1};
    ai_real ns = 0;
    memset(m, 0, sizeof *m);
    if (aiGetMaterialString(am, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS)
        snprintf(m->name, sizeof m->name, "%s", name.data);
    /* Names travel as one word in file headers. */
    for (char *p = m->name; *p; p++)
        if (*p == ' ' || (unsigned char)*p < 0x20 || *p == 0x7f)
            *p = '_';
    aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &kd);
    aiGetMaterialColor(am, AI_MATKEY_COLOR_SPECULAR, &ks);
    aiGetMaterialColor(am, AI_MATKEY_COLOR_EMISSIVE, &ke);
    aiGetMaterialFloatArray(am, AI_MATKEY_SHININESS, &ns, NULL);
    if (!m->name[0] || strcmp(m->name, AI_DEFAULT_MATERIAL_NAME) == 0) {
        /* assimp's stand-in for a mesh that names no material (PLY, STL): a plain grey
         * Lambertian surface, whatever the importer filled in (some set Ks to 1). */
        kd = (struct aiColor4D){0.8f, 0.8f, 0.8f, 1};
        ks = ke = (struct aiColor4D){0, 0, 0, 1};
        snprintf(m->name, sizeof m->name, "default");
    }
    float kdv[3] = {kd.r, kd.g, kd.b}, ksv[3] = {ks.r, ks.g, ks.b}, kev[3] = {ke.r, ke.g, ke.b};
    for (int i = 0; i < 3; i++) {
        if (!(kdv[i] >= 0.0f && kdv[i] <= 1.0f) || !(ksv[i] >= 0.0f && ksv[i] <= 1.0f))
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': material '%s': Kd %g and Ks %g in channel %c must lie in [0, 1]", mesh,
                                m->name, kdv[i], ksv[i], "rgb"[i]);
        if (kdv[i] + ksv[i] > 1.0f + 1e-6f)
            return pm_error_set(
                PM_ERR_INPUT, "mesh '%s': material '%s': Kd + Ks = %g in channel %c exceeds 1 (not energy conserving)",
                mesh, m->name, kdv[i] + ksv[i], "rgb"[i]);
        if (!(kev[i] >= 0.0f && kev[i] <= 1e30f))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': Ke %g in channel %c must lie in [0, 1e30]",
                                mesh, m->name, kev[i], "rgb"[i]);
        m->kd[i] = kdv[i];
        m->ks[i] = ksv[i];
        m->ke[i] = kev[i];
    }
    if (!(ns >= 0 && ns <= 1e6))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': material '%s': Ns %g must lie in [0, 1e6]", mesh, m->name, ns);
    m->ns = (float)ns;
    (void)c;
    return PM_OK;
}

/* Resolves a mesh file name relative to the scene file's folder. */
static void resolve(const char *scene_path, const char *file, char *out, size_t cap)
{
    const char *slash = strrchr(scene_path, '/');
    if (file[0] == '/' || !slash)
        snprintf(out, cap, "%s", file);
    else
        snprintf(out, cap, "%.*s/%s", (int)(slash - scene_path), scene_path, file);
}

static pm_result_t grow(void **p, size_t n, size_t size)
{
    void *q = realloc(*p, (n ? n : 1) * size);
    if (!q)
        return pm_error_set(PM_ERR_NOMEM, "out of memory loading meshes");
    *p = q;
    return PM_OK;
}

/* assimp reports some faults only to its log and carries on: a usemtl the .mtl does not
 * define, a missing .mtl (it then makes up a grey material). The first "Error" it logs
 * during an import fails the load. Scenes load on one thread, so one buffer serves. */
static char ai_first_error[512];

static void on_assimp_log(const char *msg, char *user)
{
    (void)user;
    if (ai_first_error[0] || strncmp(msg, "Error,", 6) != 0)
        return;
    const char *colon = strchr(msg, ':'); /* "Error, T0: OBJ: ..." -> "OBJ: ..." */
    snprintf(ai_first_error, sizeof ai_first_error, "%s", colon ? colon + 2 : msg);
    for (char *p = ai_first_error; *p; p++)
        if (*p == '\n' || *p == '\r')
            *p = ' ';
    for (size_t n = strlen(ai_first_error); n && ai_first_error[n - 1] == ' '; n--)
        ai_first_error[n - 1] = '\0';
}

static pm_result_t load_mesh(const ctx_t *c, json_t *mj, size_t index)
{
    static const char *const keys[] = {"file", "scale", "translate", NULL};
    pm_scene_t *s = c->s;
    char where[64], path[1200];
    snprintf(where, sizeof where, "meshes[%zu]", index);
    if (!json_is_object(mj))
        return bad(c, where, "must be an object");
    pm_result_t r = only_keys(c, mj, where, keys);
    if (r != PM_OK)
        return r;
    const char *file = json_string_value(json_object_get(mj, "file"));
    if (!file)
        return bad(c, where, "'file' is missing or not a string");
    double scale = 1.0;
    float tr[3] = {0, 0, 0};
    char p1[80], p2[80];
    snprintf(p1, sizeof p1, "%s.scale", where);
    snprintf(p2, sizeof p2, "%s.translate", where);
    if ((r = get_number(c, mj, "scale", p1, 0, 1e-30, 1e30, &scale)) != PM_OK ||
        (r = get_vec3(c, mj, "translate", p2, 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, tr)) != PM_OK)
        return r;
    resolve(c->file, file, path, sizeof path);
    FILE *probe = fopen(path, "rb");
    if (!probe)
        return pm_error_set(PM_ERR_INPUT, "cannot open mesh '%s': %s", path, strerror(errno));
    fclose(probe);
    /* Triangulate polygons, merge shared vertices, flatten node transforms, drop points
     * and lines; normals are not needed: pmtk shades with geometric normals. */
    struct aiLogStream log = {on_assimp_log, NULL};
    ai_first_error[0] = '\0';
    aiAttachLogStream(&log);
    const struct aiScene *as =
        aiImportFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                               aiProcess_SortByPType | aiProcess_ValidateDataStructure);
    aiDetachAllLogStreams();
    if (!as)
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, aiGetErrorString());
    if (ai_first_error[0]) {
        aiReleaseImport(as);
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, ai_first_error);
    }
    /* An OBJ whose faces name no material (no mtllib, or a usemtl the .mtl lacks) gets
     * assimp's default material; rendering it grey would be silently wrong. */
    size_t ext = strlen(path);
    int is_obj = ext > 4 && strcasecmp(path + ext - 4, ".obj") == 0;
    for (unsigned mi = 0; is_obj && mi < as->mNumMeshes; mi++) {
        const struct aiMesh *m = as->mMeshes[mi];
        struct aiString mname;
        if (m->mMaterialIndex < as->mNumMaterials &&
            aiGetMaterialString(as->mMaterials[m->mMaterialIndex], AI_MATKEY_NAME, &mname) == aiReturn_SUCCESS &&
            strcmp(mname.data, AI_DEFAULT_MATERIAL_NAME) == 0) {
            r = pm_error_set(PM_ERR_INPUT,
                             "mesh '%s': %u faces of '%s' have no material (no mtllib, or no usemtl before them)", path,
                             m->mNumFaces, m->mName.length ? m->mName.data : "(unnamed)");
            aiReleaseImport(as);
            return r;
        }
    }
    size_t mat0 = s->nmaterials;
    if ((r = grow((void **)&s->materials, mat0 + as->mNumMaterials, sizeof *s->materials)) != PM_OK) {
        aiReleaseImport(as);
        return r;
    }
    for (unsigned i = 0; i < as->mNumMaterials && r == PM_OK; i++)
        r = load_material(c, path, as->mMaterials[i], &s->materials[mat0 + i]);
    if (r != PM_OK) {
        aiReleaseImport(as);
        return r;
    }
    s->nmaterials += as->mNumMaterials;
    for (unsigned mi = 0; mi < as->mNumMeshes && r == PM_OK; mi++) {
        const struct aiMesh *m = as->mMeshes[mi];
        if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE))
            continue;
        if (m->mMaterialIndex >= as->mNumMaterials) {
            r = pm_error_set(PM_ERR_INPUT, "mesh '%s': material index %u of %u", path, m->mMaterialIndex,
                             as->mNumMaterials);
            break;
        }
        size_t v0 = s->nverts;
        if (s->ntris + m->mNumFaces > PM_SCENE_MAX_TRIS) {
            r = pm_error_set(PM_ERR_INPUT, "mesh '%s': more than %u triangles in the scene", path, PM_SCENE_MAX_TRIS);
            break;
        }
        if ((r = grow((void **)&s->verts, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = grow((void **)&s->tris, 3 * (s->ntris + m->mNumFaces), sizeof(uint32_t))) != PM_OK ||
            (r = grow((void **)&s->tri_material, s->ntris + m->mNumFaces, sizeof(uint32_t))) != PM_OK)
            break;
        for (unsigned v = 0; v < m->mNumVertices; v++) {
            double p[3] = {m->mVertices[v].x, m->mVertices[v].y, m->mVertices[v].z};
            for (int k = 0; k < 3; k++) {
                double x = p[k] * scale + tr[k];
                if (!isfinite(x) || fabs(x) > PM_SCENE_COORD_MAX) {
                    r = pm_error_set(PM_ERR_INPUT,
                                     "mesh '%s': vertex %u coordinate %c = %g is not finite or beyond 1e30", path, v,
                                     "xyz"[k], x);
                    break;
                }
                s->verts[3 * (v0 + v) + k] = (float)x;
            }
            if (r != PM_OK)
                break;
        }
        s->nverts += m->mNumVertices;
        for (unsigned f = 0; f < m->mNumFaces && r == PM_OK; f++) {
            const struct aiFace *face = &m->mFaces[f];
            if (face->mNumIndices != 3)
                continue;
            uint32_t *t = &s->tris[3 * s->ntris];
            for (int k = 0; k < 3; k++) {
                if (face->mIndices[k] >= m->mNumVertices) {
                    r = pm_error_set(PM_ERR_INPUT, "mesh '%s': face %u names vertex %u of %u", path, f,
                                     face->mIndices[k], m->mNumVertices);
                    break;
                }
                t[k] = (uint32_t)(v0 + face->mIndices[k]);
            }
            if (r != PM_OK)
                break;
            s->tri_material[s->ntris] = (uint32_t)(mat0 + m->mMaterialIndex);
            s->ntris++;
            /* Zero-area triangles scatter nothing and have no normal: leave them out. */
            if (!(pm_scene_triangle_area(s, s->ntris - 1) > 0.0)) {
                s->ntris--;
                s->ndropped++;
            }
        }
    }
    aiReleaseImport(as);
    return r;
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
            p[k] += 4.0 * M_PI * s->lights[i].intensity[k];
    for (size_t i = 0; i < s->nemissive; i++) {
        size_t t = s->emissive[i];
        double a = pm_scene_triangle_area(s, t);
        for (int k = 0; k < 3; k++)
            p[k] += M_PI * s->materials[s->tri_material[t]].ke[k] * a;
    }
}

void pm_scene_id(const pm_scene_t *s, char *out, size_t cap)
{
    snprintf(out, cap, "%s xxh3:%016llx", s->name, (unsigned long long)s->hash);
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
            map[m] = (uint32_t)n++;
        }
    for (size_t t = 0; t < s->ntris; t++)
        s->tri_material[t] = map[s->tri_material[t]];
    s->nmaterials = n;
    free(map);
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
    for (size_t m = 0; m < s->nmaterials; m++)
        s->any_glossy |= pm_material_is_glossy(&s->materials[m]);
}

pm_result_t pm_scene_load(const char *path, pm_scene_t *s)
{
    memset(s, 0, sizeof *s);
    ctx_t c = {path, s};
    snprintf(s->path, sizeof s->path, "%s", path);
    json_error_t je;
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(errno == ENOENT ? PM_ERR_INPUT : PM_ERR_IO, "cannot open scene '%s': %s", path,
                            strerror(errno));
    json_t *root = json_loadf(f, JSON_REJECT_DUPLICATES, &je);
    fclose(f);
    if (!root)
        return pm_error_set(PM_ERR_INPUT, "scene '%s' line %d column %d: %s", path, je.line, je.column, je.text);
    static const char *const keys[] = {"pmtk_scene", "name", "meshes", "camera", "point_lights", "render", NULL};
    pm_result_t r =
        json_is_object(root) ? only_keys(&c, root, "top level", keys) : bad(&c, "top level", "must be a JSON object");
    int64_t version = 0;
    if (r == PM_OK)
        r = get_int(&c, root, "pmtk_scene", "pmtk_scene", 1, 1, 1, &version);
    const char *name = json_string_value(json_object_get(root, "name"));
    if (r == PM_OK && (!name || !*name || strlen(name) >= sizeof s->name || strpbrk(name, " \t\n")))
        r = bad(&c, "name", "must be a non-empty string without spaces, under %zu bytes", sizeof s->name);
    if (r == PM_OK)
        snprintf(s->name, sizeof s->name, "%s", name);
    json_t *meshes = json_object_get(root, "meshes");
    if (r == PM_OK && meshes && !json_is_array(meshes))
        r = bad(&c, "meshes", "must be an array");
    for (size_t i = 0; r == PM_OK && meshes && i < json_array_size(meshes); i++) {
        r = load_mesh(&c, json_array_get(meshes, i), i);
        /* Mesh and material faults name the mesh; say which scene entry brought it in. */
        if (r == PM_ERR_INPUT && strncmp(pm_error_message(), "scene '", 7) != 0)
            pm_error_prefix("scene '%s': meshes[%zu]", path, i);
    }
    if (r == PM_OK)
        r = load_camera(&c, json_object_get(root, "camera"));
    if (r == PM_OK)
        r = load_lights(&c, json_object_get(root, "point_lights"));
    if (r == PM_OK)
        r = load_defaults(&c, json_object_get(root, "render"));
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
    if (r == PM_OK) {
        /* The scene's identity: its file's bytes plus everything loaded through it, so a
         * change to a mesh or an .mtl changes the hash even when scene.json does not. */
        uint64_t h[6] = {0};
        r = pm_hash_file(path, &h[0]);
        h[1] = pm_hash_bytes(s->verts, 3 * s->nverts * sizeof(float));
        h[2] = pm_hash_bytes(s->tris, 3 * s->ntris * sizeof(uint32_t));
        h[3] = pm_hash_bytes(s->tri_material, s->ntris * sizeof(uint32_t));
        h[4] = pm_hash_bytes(s->materials, s->nmaterials * sizeof *s->materials);
        h[5] = pm_hash_bytes(s->lights, s->nlights * sizeof *s->lights);
        s->hash = pm_hash_bytes(h, sizeof h);
    }
    if (r == PM_OK)
        finish(s);
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
    free(s->emissive);
    memset(s, 0, sizeof *s);
}
