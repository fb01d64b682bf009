/* scene.c: the scene file reader (JSON through jansson, meshes through assimp's C API). */
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

#define PM_SCENE_MAX_TRIS (1u << 30) /* triangles: 32-bit indices with room to spare */
#define PM_SCENE_MAX_LIGHTS 65536
/* m: Embree refuses (aborts on) a ray whose origin lies beyond 1.844e18 m, and camera and
 * photon rays start at the eye, the lights and on the geometry. */
#define PM_SCENE_COORD_MAX 1e18
/* m^2: a triangle's normal is its edges' cross product, whose squared length must be a
 * normal float (4 A^2 within [1.2e-38, 3.4e38]); these keep a margin of 50 below and 9
 * above. Smaller triangles are left out as degenerate, larger ones refused. */
#define PM_SCENE_AREA_MIN 1e-18
#define PM_SCENE_AREA_MAX 1e18
/* m: the smallest geometry pmtk renders (its bounding box's longest side); every triangle of
 * a scene much smaller would be left out by PM_SCENE_AREA_MIN, and the image silently black. */
#define PM_SCENE_SIZE_MIN 1e-8

/* A mesh file imported once per scene, however many entries place it. */
/* Where an OBJ's material is defined: the first .mtl of its libraries (in mtllib order) with a
 * newmtl of that name, the folder its texture names are relative to. */
typedef struct {
    char name[64]; /* as load_material names it (material_word) */
    char lib[1200];
} mtl_home_t;

typedef struct {
    char path[1200];
    const struct aiScene *as;
    char libs[4096];   /* its .mtl files, one a line (check_obj_materials) */
    mtl_home_t *homes; /* each material its .mtl files define, read once at import (mtl_homes) */
    size_t nhomes;
} import_t;

typedef struct {
    const char *file; /* the scene file, for messages */
    pm_scene_t *s;
    int missing_magenta; /* missing_textures "magenta": a missing texture file is a warning */
    import_t *imports;   /* the mesh files imported so far */
    size_t nimports;
    float *local;    /* every vertex loaded, in its mesh's own units (placements share them) */
    int any_normals; /* some mesh loaded has vertex normals */
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
    if (r == PM_OK && (r = pm_image_size_check((uint64_t)w, (uint64_t)h)) != PM_OK)
        pm_error_prefix("scene '%s': camera", c->file);
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

/* The spot keys of point light l (direction, cone, falloff); none of them leaves it isotropic. */
static pm_result_t load_spot(const ctx_t *c, json_t *l, const char *where, pm_point_light_t *pl)
{
    char pd[80], pc[80], pf[80];
    snprintf(pd, sizeof pd, "%s.direction", where);
    snprintf(pc, sizeof pc, "%s.cone", where);
    snprintf(pf, sizeof pf, "%s.falloff", where);
    pl->cos_cone = -1.0f;
    json_t *cone = json_object_get(l, "cone"), *dir = json_object_get(l, "direction"),
           *fall = json_object_get(l, "falloff");
    if (!cone && !dir && !fall)
        return PM_OK;
    if (!dir)
        return bad(c, pd, "missing (a light with a cone or a falloff is a spot and needs an axis)");
    if (cone && json_is_number(cone)) {
        /* The half-angle's own range, stated as users read it: (0, 180] degrees. */
        double a = json_number_value(cone);
        if (!(a > 0.0 && a <= 180.0))
            return bad(c, pc, "%.9g degrees is outside (0, 180]", a);
    }
    double a = 180.0, e = 0.0;
    float d[3];
    pm_result_t r = get_vec3(c, l, "direction", pd, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, d);
    if (r == PM_OK)
        r = get_number(c, l, "cone", pc, 0, 0.0, 180.0, &a);
    if (r == PM_OK)
        r = get_number(c, l, "falloff", pf, 0, 0.0, 1e4, &e);
    if (r != PM_OK)
        return r;
    double dl = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
    if (!(dl > 0.0))
        return bad(c, pd, "is the zero vector");
    for (int k = 0; k < 3; k++)
        pl->axis[k] = (float)(d[k] / dl);
    pl->cos_cone = a >= 180.0 ? -1.0f : (float)cos(a * M_PI / 180.0);
    pl->falloff = (float)e;
    if (!(pl->cos_cone < 1.0f))
        return bad(c, pc, "%.9g degrees is too narrow: its cosine rounds to 1", a);
    return PM_OK;
}

static pm_result_t load_lights(const ctx_t *c, json_t *lights)
{
    static const char *const keys[] = {"position", "intensity", "direction", "cone", "falloff", NULL};
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
        if ((r = load_spot(c, l, where, pl)) != PM_OK)
            return r;
    }
    c->s->nlights = n;
    return PM_OK;
}

pm_result_t pm_envmap_init(pm_envmap_t *e, uint32_t w, uint32_t h, float *rgb)
{
    memset(e, 0, sizeof *e);
    e->w = w, e->h = h, e->rgb = rgb;
    size_t n = (size_t)w * h;
    for (size_t i = 0; i < 3 * n; i++)
        if (!(rgb[i] >= 0.0f && isfinite(rgb[i]))) {
            size_t px = i / 3;
            char v[32];
            snprintf(v, sizeof v, "%g", (double)rgb[i]);
            pm_result_t r =
                pm_error_set(PM_ERR_INPUT, "pixel (%zu, %zu) channel %c = %s is not a radiance (finite, >= 0)", px % w,
                             px / w, "RGB"[i % 3], v);
            pm_envmap_free(e);
            return r;
        }
    e->row_cdf = malloc(h * sizeof(double));
    e->col_cdf = malloc(n * sizeof(double));
    e->pix_p = malloc(n * sizeof(double));
    if (!e->row_cdf || !e->col_cdf || !e->pix_p) {
        pm_envmap_free(e);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the tables of a %" PRIu32 "x%" PRIu32 " map", w, h);
    }
    double acc = 0.0;
    for (uint32_t y = 0; y < h; y++) {
        /* Luminance (Rec. 709) times the pixel's solid angle over 2 pi / w: sin at its centre. */
        double st = sin(M_PI * (y + 0.5) / h), row = 0.0;
        double dom = 2.0 * M_PI / w * (cos(M_PI * y / h) - cos(M_PI * (y + 1.0) / h));
        for (uint32_t x = 0; x < w; x++) {
            const float *p = rgb + 3 * ((size_t)y * w + x);
            double wt = (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) * st;
            e->pix_p[(size_t)y * w + x] = wt;
            e->col_cdf[(size_t)y * w + x] = row += wt;
            for (int k = 0; k < 3; k++)
                e->integral[k] += p[k] * dom;
        }
        e->row_cdf[y] = acc += row;
    }
    e->total = acc;
    for (uint32_t y = 0; y < h && acc > 0.0; y++) {
        double row = e->col_cdf[(size_t)y * w + w - 1];
        for (uint32_t x = 0; x < w; x++) {
            e->pix_p[(size_t)y * w + x] /= acc;
            e->col_cdf[(size_t)y * w + x] = row > 0.0 ? e->col_cdf[(size_t)y * w + x] / row : (x + 1.0) / w;
        }
        e->col_cdf[(size_t)y * w + w - 1] = 1.0;
        e->row_cdf[y] /= acc;
    }
    if (acc > 0.0)
        e->row_cdf[h - 1] = 1.0;
    return PM_OK;
}

void pm_envmap_free(pm_envmap_t *e)
{
    free(e->rgb);
    free(e->row_cdf);
    free(e->col_cdf);
    free(e->pix_p);
    memset(e, 0, sizeof *e);
}

static void resolve(const char *scene_path, const char *file, char *out, size_t cap);

/* The sky's map: an OpenEXR file relative to the scene, each value times sky.radiance. */
static pm_result_t load_envmap(const ctx_t *c, const char *file)
{
    char path[2048];
    resolve(c->file, file, path, sizeof path);
    uint32_t w = 0, h = 0;
    float *rgb = NULL;
    pm_result_t r = pm_exr_read_rgb(path, &w, &h, &rgb);
    if (r != PM_OK) {
        pm_error_prefix("scene '%s': sky.map", c->file);
        return r;
    }
    for (size_t i = 0; i < 3 * (size_t)w * h; i++)
        rgb[i] *= c->s->sky[i % 3];
    c->s->envmap = calloc(1, sizeof *c->s->envmap);
    if (!c->s->envmap) {
        free(rgb);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the sky's map");
    }
    if ((r = pm_envmap_init(c->s->envmap, w, h, rgb)) != PM_OK)
        pm_error_prefix("scene '%s': sky.map '%s'", c->file, file);
    return r;
}

/* The sun (direction, radiance, solid_angle) and the sky (radiance, map), all optional. */
static pm_result_t load_sun_sky(const ctx_t *c, json_t *sun, json_t *sky)
{
    static const char *const sun_keys[] = {"direction", "radiance", "solid_angle", NULL};
    static const char *const sky_keys[] = {"radiance", "map", NULL};
    pm_scene_t *s = c->s;
    pm_result_t r = PM_OK;
    if (sun) {
        if (!json_is_object(sun))
            return bad(c, "sun", "must be an object");
        float d[3];
        double omega = 0.0;
        json_t *om = json_object_get(sun, "solid_angle");
        /* Stated as users read it: the solid angle must be positive, and a hemisphere at most. */
        if (om && json_is_number(om) && !(json_number_value(om) > 0.0 && json_number_value(om) <= 2.0 * M_PI))
            return bad(c, "sun.solid_angle", "%.9g sr is outside (0, 2 pi]", json_number_value(om));
        if ((r = only_keys(c, sun, "sun", sun_keys)) == PM_OK)
            r = get_vec3(c, sun, "direction", "sun.direction", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, d);
        if (r == PM_OK)
            r = get_vec3(c, sun, "radiance", "sun.radiance", 1, 0.0, 1e30, s->sun.radiance);
        if (r == PM_OK)
            r = get_number(c, sun, "solid_angle", "sun.solid_angle", 1, 0.0, 2.0 * M_PI, &omega);
        if (r != PM_OK)
            return r;
        double dl = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
        if (!(dl > 0.0))
            return bad(c, "sun.direction", "is the zero vector");
        for (int k = 0; k < 3; k++)
            s->sun.direction[k] = (float)(d[k] / dl);
        s->sun.solid_angle = (float)omega;
        s->sun.cos_max = (float)(1.0 - omega / (2.0 * M_PI));
        if (!(s->sun.cos_max < 1.0f))
            return bad(c, "sun.solid_angle", "%.9g sr is too small: the cone's cosine rounds to 1", omega);
        s->has_sun = 1;
    }
    if (sky) {
        if (!json_is_object(sky))
            return bad(c, "sky", "must be an object");
        json_t *map = json_object_get(sky, "map");
        s->sky[0] = s->sky[1] = s->sky[2] = 1.0f; /* a map's scale when radiance is not given */
        if ((r = only_keys(c, sky, "sky", sky_keys)) == PM_OK)
            r = get_vec3(c, sky, "radiance", "sky.radiance", !map, 0.0, 1e30, s->sky);
        if (r == PM_OK && map && (!json_is_string(map) || !*json_string_value(map)))
            r = bad(c, "sky.map", "must be a file name (an OpenEXR lat-long map)");
        if (r == PM_OK && map)
            r = load_envmap(c, json_string_value(map));
        if (r != PM_OK)
            return r;
        s->has_sky = 1;
    }
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

/* The PBR inputs of assimp material am: 1 when it is a metallic-roughness material (every glTF
 * material; an MTL material with a Pr or a Pm line, the PBR extension), with its metallic and
 * roughness factors (glTF's defaults where one is absent: metallic 1 in glTF, 0 in an MTL,
 * whose materials are dielectrics unless Pm says otherwise; roughness 1 in both). */
static int pbr_inputs(int is_obj, const struct aiMaterial *am, float *metallic_out, float *roughness_out)
{
    ai_real metallic = is_obj ? 0 : 1, roughness = 1;
    int has_m = aiGetMaterialFloatArray(am, AI_MATKEY_METALLIC_FACTOR, &metallic, NULL) == aiReturn_SUCCESS;
    int has_r = aiGetMaterialFloatArray(am, AI_MATKEY_ROUGHNESS_FACTOR, &roughness, NULL) == aiReturn_SUCCESS;
    *metallic_out = (float)metallic;
    *roughness_out = (float)roughness;
    return !is_obj || has_m || has_r;
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
    int pbr = pbr_inputs(is_obj, am, &metallic, &roughness);
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
 * materials"): metallic 1 is a conductor of F0 the base colour and GGX width roughness^2 (a
 * mirror of reflectance the base colour at roughness 0, the delta the tracers follow); metallic
 * 0 is plastic, the base colour under a dielectric coat of index 1.5 (glTF's ior when
 * KHR_materials_ior gives one, an MTL's Ni when not 1; index 1 makes it Lambertian, exactly).
 * A metallic strictly between is the nearer kind with glTF's mix of that kind's own lobe:
 * F0 = lerp(0.04, base, metallic) for a metal, kd = (1 - metallic) base for plastic; the other
 * lobe is lost, and scan_material says so. */
static pm_result_t load_pbr(const char *mesh, int is_obj, const struct aiMaterial *am, const float base[3],
                            pm_material_t *m)
{
    float metallic, roughness;
    if (!pbr_inputs(is_obj, am, &metallic, &roughness))
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
    if (metallic >= 0.5f) {
        for (int k = 0; k < 3; k++) {
            float f0 = metallic * base[k] + (1.0f - metallic) * PM_PBR_DIELECTRIC_F0;
            if (roughness == 0.0f)
                m->kr[k] = f0;
            else
                m->f0[k] = f0;
        }
        m->kind = roughness == 0.0f ? PM_MAT_MIRROR : PM_MAT_CONDUCTOR;
        m->alpha = roughness * roughness;
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
    m->alpha = ior == 1 ? 0.0f : roughness * roughness;
    return PM_OK;
}

/* A material name as pmtk keeps it: spaces and control characters become '_', since names
 * travel as one word in file headers (load_material, and the .mtl scans that match names). */
static void material_word(char *name)
{
    for (char *p = name; *p; p++)
        if (*p == ' ' || (unsigned char)*p < 0x20 || *p == 0x7f)
            *p = '_';
}

/* The next library of libs (mtllib names, one a line, as check_obj_materials lists them) that
 * opens, resolved against the OBJ's path into path; NULL when none is left. *lib moves past
 * it. A file that cannot be opened is left to assimp, which has said so already. */
static FILE *next_mtl(const char *obj, const char **lib, char *path, size_t cap)
{
    while (**lib) {
        const char *eol = strchr(*lib, '\n');
        char name[1024];
        snprintf(name, sizeof name, "%.*s", (int)(eol - *lib), *lib);
        *lib = eol + 1;
        resolve(obj, name, path, cap);
        FILE *f = fopen(path, "rb");
        if (f)
            return f;
    }
    return NULL;
}

/* One line of an .mtl without its line end and trailing spaces; -1 at the end of f. */
static ssize_t mtl_getline(char **line, size_t *cap, FILE *f)
{
    ssize_t len = getline(line, cap, f);
    while (len > 0 && ((*line)[len - 1] == '\n' || (*line)[len - 1] == '\r' || (*line)[len - 1] == ' '))
        (*line)[--len] = '\0';
    return len;
}

/* Reads one material's reflectance from assimp and checks it is physical. */
static pm_result_t load_material(const ctx_t *c, const char *mesh, int is_obj, const struct aiMaterial *am,
                                 pm_material_t *m)
{
    struct aiString name;
    struct aiColor4D kd = {0.8f, 0.8f, 0.8f, 1}, ks = {0, 0, 0, 1}, ke = {0, 0, 0, 1};
    ai_real ns = 0;
    memset(m, 0, sizeof *m);
    if (aiGetMaterialString(am, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS)
        snprintf(m->name, sizeof m->name, "%s", name.data);
    material_word(m->name);
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
    int pbr = !stand_in && pbr_inputs(is_obj, am, &metallic, &roughness);
    pm_result_t r = PM_OK;
    if (!stand_in && (r = load_specular(mesh, is_obj, am, kdv, ksv, m)) != PM_OK)
        return r;
    int specular = m->kind != PM_MAT_STANDARD;
    for (int i = 0; i < 3; i++) {
        if (!(kdv[i] >= 0.0f && kdv[i] <= 1.0f) || !(ksv[i] >= 0.0f && ksv[i] <= 1.0f))
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': material '%s': Kd %g and Ks %g in channel %c must lie in [0, 1]", mesh,
                                m->name, kdv[i], ksv[i], "rgb"[i]);
        /* a mirror's Ks is its reflectance and its Kd unused; a PBR material's Ks is unused (its
         * metal or its dielectric coat replaces the Phong lobe): their sum is no constraint */
        if (!specular && !pbr && kdv[i] + ksv[i] > 1.0f + 1e-6f)
            return pm_error_set(
                PM_ERR_INPUT, "mesh '%s': material '%s': Kd + Ks = %g in channel %c exceeds 1 (not energy conserving)",
                mesh, m->name, kdv[i] + ksv[i], "rgb"[i]);
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

/* Errors assimp 5.2 logs for legal input and then handles right: a usemtl before any
 * group, object or face (the next face makes the default object, with that material), and
 * an illum outside 0 to 2 (kept in the material, and reported as unsupported). */
static const char *const ai_benign_errors[] = {
    "OBJ: No object detected to attach a new mesh instance",
    "OBJ: unexpected illumination model",
    NULL,
};

static void on_assimp_log(const char *msg, char *user)
{
    (void)user;
    if (ai_first_error[0] || strncmp(msg, "Error,", 6) != 0)
        return;
    for (const char *const *b = ai_benign_errors; *b; b++)
        if (strstr(msg, *b))
            return;
    const char *colon = strchr(msg, ':'); /* "Error, T0: OBJ: ..." -> "OBJ: ..." */
    snprintf(ai_first_error, sizeof ai_first_error, "%s", colon ? colon + 2 : msg);
    for (char *p = ai_first_error; *p; p++)
        if (*p == '\n' || *p == '\r')
            *p = ' ';
    for (size_t n = strlen(ai_first_error); n && ai_first_error[n - 1] == ' '; n--)
        ai_first_error[n - 1] = '\0';
}

/* The first word of an OBJ line into word (cut to cap), and where the rest begins. */
static const char *obj_word(const char *line, char *word, size_t cap)
{
    while (*line == ' ' || *line == '\t')
        line++;
    size_t n = 0;
    while (line[n] && line[n] != ' ' && line[n] != '\t' && line[n] != '\r' && line[n] != '\n')
        n++;
    snprintf(word, cap, "%.*s", (int)n, line);
    line += n;
    while (*line == ' ' || *line == '\t')
        line++;
    return line;
}

/* Reads the OBJ's own lines for the two orders assimp 5.2 gets silently wrong: a face before
 * the first usemtl takes whichever material was current (the last one of the .mtl, or
 * assimp's grey default), and an mtllib after a usemtl makes the last material of that
 * library the material of the faces already read. Both are errors naming the line. */
static pm_result_t check_obj_materials(const char *path, char *libs_out, size_t libs_cap)
{
    size_t libs_len = 0;
    libs_out[0] = '\0';
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(PM_ERR_IO, "cannot open mesh '%s': %s", path, strerror(errno));
    char *line = NULL, word[16], group[128] = "";
    size_t cap = 0;
    uint64_t lineno = 0, faces = 0, first_usemtl = 0;
    int continued = 0; /* the previous line ended in a backslash: this one goes on with it */
    pm_result_t r = PM_OK;
    for (ssize_t len; r == PM_OK && (len = getline(&line, &cap, f)) >= 0;) {
        lineno++;
        while (len > 0 && (line[len - 1] == '\n' || line[len - 1] == '\r'))
            line[--len] = '\0';
        int was_continued = continued;
        continued = len > 0 && line[len - 1] == '\\';
        if (was_continued)
            continue;
        const char *rest = obj_word(line, word, sizeof word);
        if (strcmp(word, "g") == 0 || strcmp(word, "o") == 0) {
            snprintf(group, sizeof group, "%s", rest);
            for (char *p = group; *p; p++)
                if ((unsigned char)*p < 0x20 || *p == '\\')
                    *p = ' ';
        } else if (strcmp(word, "usemtl") == 0) {
            if (!first_usemtl)
                first_usemtl = lineno;
        } else if (strcmp(word, "f") == 0 || strcmp(word, "fo") == 0) {
            faces++;
            if (!first_usemtl) {
                char where[200] = "";
                if (group[0])
                    snprintf(where, sizeof where, ", group '%s'", group);
                r = pm_error_set(PM_ERR_INPUT,
                                 "mesh '%s': face %" PRIu64 " (line %" PRIu64 "%s) comes before any usemtl: every "
                                 "OBJ face needs a material from the .mtl",
                                 path, faces, lineno, where);
            }
        } else if (strcmp(word, "mtllib") == 0 && !first_usemtl) {
            /* assimp takes the rest of the line as one file name; kept one a line */
            size_t n = strlen(rest);
            while (n && (rest[n - 1] == ' ' || rest[n - 1] == '\t'))
                n--;
            if (n && libs_len + n + 2 <= libs_cap)
                libs_len += (size_t)snprintf(libs_out + libs_len, libs_cap - libs_len, "%.*s\n", (int)n, rest);
        } else if (strcmp(word, "mtllib") == 0) {
            r = pm_error_set(PM_ERR_INPUT,
                             "mesh '%s': mtllib on line %" PRIu64 " comes after the usemtl on line %" PRIu64
                             ": assimp would give the faces before it that library's last material; put every "
                             "mtllib before the first usemtl",
                             path, lineno, first_usemtl);
        }
    }
    if (r == PM_OK && ferror(f))
        r = pm_error_set(PM_ERR_IO, "cannot read mesh '%s': %s", path, strerror(errno));
    free(line);
    fclose(f);
    return r;
}

/* How the loader treats an assimp material key (the table below). */
enum {
    KEY_HONOURED,  /* read into pm_material_t */
    KEY_SKIP,      /* bookkeeping, or a no-op for pmtk (assimp derives shadingm from illum; both
                    * sides of every triangle reflect, so twosided changes nothing) */
    KEY_ZERO,      /* ignored; reported unless every component is 0 (what pmtk does anyway) */
    KEY_ONE,       /* ignored; reported unless every component is 1 */
    KEY_ANY,       /* ignored; always reported */
    KEY_ILLUM,     /* reported unless 1 or 2 (diffuse; diffuse and Phong highlight) */
    KEY_ALPHAMODE, /* reported unless OPAQUE */
    KEY_APPROX,    /* honoured approximately; reported with a note saying how */
};

typedef struct {
    const char *ai_key;                /* assimp's key, AI_MATKEY_* */
    const char *obj_name, *other_name; /* as MTL names it; as glTF and other formats name it */
    int obj_kind, other_kind;
} material_key_t;

static const material_key_t material_keys[] = {
    {"?mat.name", "newmtl", "name", KEY_HONOURED, KEY_HONOURED},
    {"$clr.diffuse", "Kd", "baseColorFactor", KEY_HONOURED, KEY_HONOURED},
    {"$clr.base", "Kd", "baseColorFactor", KEY_HONOURED, KEY_HONOURED},
    {"$clr.specular", "Ks", "specularColor", KEY_HONOURED, KEY_HONOURED},
    {"$mat.shininess", "Ns", "shininess", KEY_HONOURED, KEY_HONOURED},
    {"$clr.emissive", "Ke", "emissiveFactor", KEY_HONOURED, KEY_HONOURED},
    {"$mat.shadingm", "illum", "shadingModel", KEY_SKIP, KEY_SKIP},
    {"$mat.twosided", "twosided", "doubleSided", KEY_SKIP, KEY_SKIP},
    {"$mat.gltf.alphaCutoff", "alphaCutoff", "alphaCutoff", KEY_SKIP, KEY_SKIP},
    {"$mat.bumpscaling", "-bm", "bumpScaling", KEY_SKIP, KEY_SKIP},
    {"$mat.illum", "illum", "illum", KEY_ILLUM, KEY_ILLUM},
    {"$clr.ambient", "Ka", "ambientColor", KEY_ZERO, KEY_ZERO},
    {"$mat.opacity", "d", "opacity", KEY_ONE, KEY_ONE},
    {"$clr.transparent", "Tf", "transparentColor", KEY_ONE, KEY_ONE},
    {"$mat.refracti", "Ni", "ior", KEY_ONE, KEY_ONE},
    {"$mat.anisotropyFactor", "aniso", "anisotropy", KEY_ZERO, KEY_ZERO},
    {"$mat.roughnessFactor", "Pr", "roughnessFactor", KEY_ANY, KEY_ONE},
    {"$mat.metallicFactor", "Pm", "metallicFactor", KEY_ZERO, KEY_ZERO},
    {"$clr.sheen.factor", "Ps", "sheenColorFactor", KEY_ZERO, KEY_ZERO},
    {"$mat.clearcoat.factor", "Pc", "clearcoatFactor", KEY_ZERO, KEY_ZERO},
    {"$mat.clearcoat.roughnessFactor", "Pcr", "clearcoatRoughnessFactor", KEY_ANY, KEY_ANY},
    {"$mat.gltf.alphaMode", "alphaMode", "alphaMode", KEY_ALPHAMODE, KEY_ALPHAMODE},
    {"$mat.emissiveIntensity", "emissiveIntensity", "emissiveStrength", KEY_ONE, KEY_ONE},
    {"$mat.reflectivity", "reflectivity", "reflectivity", KEY_ZERO, KEY_ZERO},
    {"$clr.reflective", "reflective", "reflectiveColor", KEY_ZERO, KEY_ZERO},
    {"$mat.transparencyfactor", "transparencyfactor", "transparencyFactor", KEY_ZERO, KEY_ZERO},
    {"$mat.transmission.factor", "transmission", "transmissionFactor", KEY_ZERO, KEY_ZERO},
};

/* A texture slot as MTL names it (assimp 5.2's ObjFileMtlImporter mapping), or NULL. */
static const char *mtl_texture_name(unsigned semantic)
{
    switch (semantic) {
    case aiTextureType_DIFFUSE: return "map_Kd";
    case aiTextureType_SPECULAR: return "map_Ks";
    case aiTextureType_AMBIENT: return "map_Ka";
    case aiTextureType_EMISSIVE: return "map_Ke";
    case aiTextureType_HEIGHT: return "bump";
    case aiTextureType_NORMALS: return "norm";
    case aiTextureType_SHININESS: return "map_Ns";
    case aiTextureType_OPACITY: return "map_d";
    case aiTextureType_DISPLACEMENT: return "disp";
    case aiTextureType_REFLECTION: return "refl";
    case aiTextureType_METALNESS: return "map_Pm";
    case aiTextureType_DIFFUSE_ROUGHNESS: return "map_Pr";
    case aiTextureType_SHEEN: return "map_Ps";
    default: return NULL;
    }
}

/* Adds one unsupported property of material index m, unless that material has its key already. */
static pm_result_t note_unsupported(pm_scene_t *s, uint32_t m, const char *key, int is_file, const char *value)
{
    for (size_t i = 0; i < s->nunsupported; i++)
        if (s->unsupported[i].material == m && strcmp(s->unsupported[i].key, key) == 0)
            return PM_OK;
    pm_result_t r = grow((void **)&s->unsupported, s->nunsupported + 1, sizeof *s->unsupported);
    if (r != PM_OK)
        return r;
    pm_scene_unsupported_t *u = &s->unsupported[s->nunsupported++];
    memset(u, 0, sizeof *u);
    u->material = m;
    u->is_file = is_file;
    snprintf(u->key, sizeof u->key, "%s", key);
    snprintf(u->value, sizeof u->value, "%s", value);
    for (char *p = u->value; *p; p++) /* one line per warning */
        if ((unsigned char)*p < 0x20 || *p == 0x7f)
            *p = ' ';
    return PM_OK;
}

/* A property's value as text: floats (a colour's first 3), integers, or a string; *neutral_out
 * tells whether it is what pmtk does anyway for its kind. */
static void property_text(const struct aiMaterialProperty *p, int kind, char *out, size_t cap, int *neutral_out)
{
    size_t len = 0;
    int all0 = 1, all1 = 1;
    out[0] = '\0';
    if (p->mType == aiPTI_Float || p->mType == aiPTI_Double || p->mType == aiPTI_Integer) {
        size_t size = p->mType == aiPTI_Double ? sizeof(double) : 4, n = p->mDataLength / size;
        if (n > 3)
            n = 3; /* RGBA: pmtk's colours are RGB */
        for (size_t i = 0; i < n && len < cap; i++) {
            double v;
            if (p->mType == aiPTI_Float) {
                float x;
                memcpy(&x, p->mData + 4 * i, 4);
                v = x;
            } else if (p->mType == aiPTI_Double) {
                memcpy(&v, p->mData + sizeof(double) * i, sizeof(double));
            } else {
                int32_t x;
                memcpy(&x, p->mData + 4 * i, 4);
                v = x;
            }
            all0 &= v == 0.0;
            all1 &= v == 1.0;
            len += (size_t)snprintf(out + len, cap - len, "%s%g", i ? " " : "", v);
        }
        *neutral_out = (kind == KEY_ZERO && all0) || (kind == KEY_ONE && all1) ||
                       (kind == KEY_ILLUM && n == 1 && (all1 || strcmp(out, "2") == 0));
    } else if (p->mType == aiPTI_String && p->mDataLength > 4) {
        uint32_t n;
        memcpy(&n, p->mData, 4);
        if (n > p->mDataLength - 4)
            n = p->mDataLength - 4;
        snprintf(out, cap, "%.*s", (int)n, p->mData + 4);
        *neutral_out = kind == KEY_ALPHAMODE && strcmp(out, "OPAQUE") == 0;
    } else {
        snprintf(out, cap, "(set)");
        *neutral_out = 0;
    }
}

/* How scan_material treats assimp key (of table kind `kind`) of a material the loader made a
 * mirror, glass or a metallic-roughness material: what made it so is honoured (load_specular,
 * load_pbr). A glass is wholly transmissive (transmission 1) and not metallic; a PBR material's
 * Ks and Ns are replaced by its metal or its coat; a metallic factor strictly between 0 and 1
 * is approximated (KEY_APPROX). */
static int honoured_kind(int is_obj, const struct aiMaterial *am, const pm_material_t *mat, const char *key, int kind)
{
    float metallic, roughness;
    int pbr = pbr_inputs(is_obj, am, &metallic, &roughness);
    int glass = mat->kind == PM_MAT_GLASS || mat->kind == PM_MAT_ROUGH_GLASS;
    int is_illum = strcmp(key, "$mat.illum") == 0, is_ior = strcmp(key, "$mat.refracti") == 0,
        is_metallic = strcmp(key, "$mat.metallicFactor") == 0, is_rough = strcmp(key, "$mat.roughnessFactor") == 0;
    if (glass) {
        if (is_illum || is_ior || is_rough || (is_obj && strcmp(key, "$clr.transparent") == 0))
            return KEY_SKIP;
        if (is_metallic)
            return KEY_ZERO;
        if (!is_obj && strcmp(key, "$mat.transmission.factor") == 0)
            return KEY_ONE;
        return kind;
    }
    if (!pbr)
        return mat->kind == PM_MAT_MIRROR && is_illum ? KEY_SKIP : kind;
    if (is_metallic)
        return metallic > 0.0f && metallic < 1.0f ? KEY_APPROX : KEY_SKIP;
    if (is_rough || strcmp(key, "$mat.shininess") == 0)
        return KEY_SKIP;
    if (is_ior) /* the coat's index of plastic; a metal has none (glTF's ior is the dielectric's) */
        return mat->kind == PM_MAT_PLASTIC || !is_obj ? KEY_SKIP : kind;
    if (is_obj && strcmp(key, "$clr.specular") == 0)
        return KEY_ZERO;
    return kind;
}

/* Every property of assimp material am that pmtk does not honour, noted against material m. */
static pm_result_t scan_material(pm_scene_t *s, int is_obj, const struct aiMaterial *am, uint32_t m)
{
    pm_result_t r = PM_OK;
    for (unsigned i = 0; i < am->mNumProperties && r == PM_OK; i++) {
        const struct aiMaterialProperty *p = am->mProperties[i];
        const char *key = p->mKey.data;
        char name[64], value[256];
        int neutral = 0;
        if (strncmp(key, "$tex.", 5) == 0) {
            /* A texture is its file; its options ($tex.uvwsrc, $tex.mapmodeu, ...) go with it. */
            if (strcmp(key, "$tex.file") != 0)
                continue;
            unsigned sem = p->mSemantic;
            /* glTF's base colour, emission and normal textures come in two slots each. */
            if (!is_obj)
                sem = sem == aiTextureType_BASE_COLOR       ? aiTextureType_DIFFUSE
                      : sem == aiTextureType_EMISSION_COLOR ? aiTextureType_EMISSIVE
                      : sem == aiTextureType_NORMAL_CAMERA  ? aiTextureType_NORMALS
                                                            : sem;
            /* Honoured (load_material_maps): MTL map_Kd, map_Ks, map_d; the base colour elsewhere. */
            if (sem == aiTextureType_DIFFUSE ||
                (is_obj && (sem == aiTextureType_SPECULAR || sem == aiTextureType_OPACITY)))
                continue;
            const char *mtl = is_obj ? mtl_texture_name(sem) : NULL;
            if (mtl)
                snprintf(name, sizeof name, "%s", mtl);
            else {
                snprintf(name, sizeof name, "%s texture", aiTextureTypeToString((enum aiTextureType)sem));
                for (char *q = name; *q; q++)
                    *q = (char)tolower((unsigned char)*q);
            }
            property_text(p, KEY_ANY, value, sizeof value, &neutral);
            r = note_unsupported(s, m, name, 1, value);
            continue;
        }
        const material_key_t *k = NULL;
        for (size_t j = 0; j < sizeof material_keys / sizeof material_keys[0] && !k; j++)
            if (strcmp(material_keys[j].ai_key, key) == 0)
                k = &material_keys[j];
        int kind = k ? (is_obj ? k->obj_kind : k->other_kind) : KEY_ANY;
        kind = honoured_kind(is_obj, am, &s->materials[m], key, kind);
        if (kind == KEY_APPROX) {
            property_text(p, KEY_ANY, value, sizeof value, &neutral);
            r = note_unsupported(s, m, is_obj ? "Pm" : "metallicFactor", 0, value);
            if (r == PM_OK)
                snprintf(s->unsupported[s->nunsupported - 1].note, sizeof s->unsupported[0].note,
                         "rendered as %s, the nearer of dielectric and metal: the %s lobe is lost",
                         s->materials[m].kind == PM_MAT_PLASTIC ? "plastic" : "metal",
                         s->materials[m].kind == PM_MAT_PLASTIC ? "metallic" : "diffuse");
            continue;
        }
        if (kind == KEY_HONOURED || kind == KEY_SKIP)
            continue;
        /* A key pmtk does not know: named without assimp's "$mat." or "$clr." prefix. */
        const char *bare = strlen(key) > 5 && key[4] == '.' ? key + 5 : key;
        snprintf(name, sizeof name, "%s", k ? (is_obj ? k->obj_name : k->other_name) : bare);
        property_text(p, kind, value, sizeof value, &neutral);
        if (!neutral)
            r = note_unsupported(s, m, name, 0, value);
    }
    return r;
}

/* MTL keys assimp 5.2 turns into a material property or texture slot; scan_material sees those.
 * Any other key (refl, sharpness, Km, ...) assimp drops without a word. */
static int mtl_key_exposed(const char *word)
{
    static const char *const keys[] = {"newmtl", "Ka", "Kd", "Ks", "Ke", "Ns",  "Ni",   "d",    "Tr",   "Tf",
                                       "illum",  "Pr", "Pm", "Ps", "Pc", "Pcr", "bump", "norm", "disp", NULL};
    /* assimp takes K and N in either case (kd, ns), map_ only in lower case */
    char w[64];
    snprintf(w, sizeof w, "%s", word);
    if (w[0] == 'k' || w[0] == 'n')
        w[0] = (char)toupper((unsigned char)w[0]);
    for (const char *const *k = keys; *k; k++)
        if (strcmp(*k, w) == 0 || strcmp(*k, word) == 0)
            return 1;
    return strncmp(word, "map_", 4) == 0;
}

/* Whether an MTL line sets a colour a specular material does not use: a mirror's or a glass's
 * Kd, a glass's Ks, at a value other than 0 (a PBR mirror's Kd is its reflectance: pbr 1). Read
 * from the .mtl itself: assimp fills in a Kd of 0.6 where the .mtl gives none. */
static int unused_colour(const pm_material_t *m, int pbr, const char *word, const char *rest)
{
    int kd = strcasecmp(word, "Kd") == 0, ks = strcasecmp(word, "Ks") == 0;
    int glass = m->kind == PM_MAT_GLASS || m->kind == PM_MAT_ROUGH_GLASS;
    if (!(glass && (kd || ks)) && !(m->kind == PM_MAT_MIRROR && !pbr && kd))
        return 0;
    float v[3] = {0, 0, 0};
    int n = sscanf(rest, "%f %f %f", &v[0], &v[1], &v[2]);
    return n < 1 || v[0] != 0.0f || v[1] != 0.0f || v[2] != 0.0f;
}

/* Reads the .mtl files an OBJ names (libs: one a line, relative to the OBJ) for the keys assimp
 * drops, and notes each against the material of this mesh (materials mat0 to mat0 + n - 1) its
 * newmtl names; pbr[i] is 1 when material mat0 + i has a Pr or a Pm. A file that cannot be
 * opened is left to assimp, which has said so already. */
static pm_result_t scan_mtl_dropped(pm_scene_t *s, const char *obj, const char *libs, size_t mat0, size_t n,
                                    const unsigned char *pbr)
{
    pm_result_t r = PM_OK;
    char path[1200];
    const char *lib = libs;
    for (FILE *f; r == PM_OK && (f = next_mtl(obj, &lib, path, sizeof path));) {
        char *line = NULL, word[64];
        size_t cap = 0;
        uint32_t current = UINT32_MAX; /* the material the lines belong to, none before newmtl */
        while (r == PM_OK && mtl_getline(&line, &cap, f) >= 0) {
            const char *rest = obj_word(line, word, sizeof word);
            if (!word[0] || word[0] == '#')
                continue;
            if (strcmp(word, "newmtl") == 0) {
                char mname[sizeof s->materials[0].name]; /* named as load_material names it */
                snprintf(mname, sizeof mname, "%s", rest);
                material_word(mname);
                current = UINT32_MAX;
                for (size_t m = mat0; m < mat0 + n && current == UINT32_MAX; m++)
                    if (strcmp(s->materials[m].name, mname) == 0)
                        current = (uint32_t)m;
            } else if (current != UINT32_MAX && !mtl_key_exposed(word)) {
                r = note_unsupported(s, current, word, 0, rest);
            } else if (current != UINT32_MAX && rest[0] == '-' &&
                       (strcmp(word, "map_Kd") == 0 || strcmp(word, "map_Ks") == 0 || strcmp(word, "map_d") == 0)) {
                /* a texture pmtk reads, with options it does not (-clamp, -o, -s, -imfchan, ...;
                 * assimp drops most without a word): the texture is used as if they were absent */
                char key[64];
                snprintf(key, sizeof key, "%s options", word);
                r = note_unsupported(s, current, key, 0, rest);
            } else if (current != UINT32_MAX &&
                       unused_colour(&s->materials[current], pbr[current - mat0], word, rest)) {
                r = note_unsupported(s, current, word, 0, rest);
            }
        }
        free(line);
        fclose(f);
    }
    return r;
}

/* Reads the .mtl files an OBJ names (libs as check_obj_materials lists them), each once, into
 * im->homes: every material name they define and the first library defining it. */
static pm_result_t mtl_homes(const char *obj, const char *libs, import_t *im)
{
    pm_result_t r = PM_OK;
    char lpath[1200];
    const char *lib = libs;
    for (FILE *f; r == PM_OK && (f = next_mtl(obj, &lib, lpath, sizeof lpath));) {
        char *line = NULL, word[16];
        size_t lcap = 0;
        while (r == PM_OK && mtl_getline(&line, &lcap, f) >= 0) {
            const char *rest = obj_word(line, word, sizeof word);
            if (strcmp(word, "newmtl") != 0)
                continue;
            char mname[sizeof im->homes[0].name];
            snprintf(mname, sizeof mname, "%s", rest);
            material_word(mname);
            int known = 0;
            for (size_t i = 0; i < im->nhomes && !known; i++)
                known = strcmp(im->homes[i].name, mname) == 0;
            if (known || (r = grow((void **)&im->homes, im->nhomes + 1, sizeof *im->homes)) != PM_OK)
                continue;
            mtl_home_t *h = &im->homes[im->nhomes++];
            snprintf(h->name, sizeof h->name, "%s", mname);
            snprintf(h->lib, sizeof h->lib, "%s", lpath);
        }
        free(line);
        fclose(f);
    }
    return r;
}

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
static pm_result_t scene_texture(const ctx_t *c, const char *base, const char *name, const char *mesh,
                                 const pm_material_t *m, uint32_t mi, const char *key, int32_t *index_out)
{
    pm_scene_t *s = c->s;
    char path[1200];
    resolve(base, name, path, sizeof path);
    FILE *probe = fopen(path, "rb");
    if (!probe && strchr(name, '\\')) {
        char alt[1024];
        snprintf(alt, sizeof alt, "%s", name);
        for (char *q = alt; *q; q++)
            if (*q == '\\')
                *q = '/';
        char altpath[1200];
        resolve(base, alt, altpath, sizeof altpath);
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
    pm_result_t r = grow((void **)&s->textures, s->ntextures + 1, sizeof *s->textures);
    if (r != PM_OK)
        return r;
    pm_texture_t *t = &s->textures[s->ntextures];
    if (missing && c->missing_magenta) {
        static const float magenta[3] = {1, 0, 1};
        if ((r = pm_texture_solid(path, magenta, t)) != PM_OK)
            return r;
        if ((r = note_unsupported(s, mi, key, 1, path)) != PM_OK) {
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
static pm_result_t load_material_maps(const ctx_t *c, const char *mesh, int is_obj, const import_t *im,
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
            r = note_unsupported(s, mi, "embedded texture", 1, tp.data);
            continue;
        }
        if (slots[k].type == aiTextureType_OPACITY && pm_material_is_emissive(m)) {
            /* light sampling draws points over an emitter's whole area: cut-outs would not match */
            r = note_unsupported(s, mi, "map_d on an emitter", 1, tp.data);
            continue;
        }
        if (!base[0])
            texture_base(mesh, im, m->name, base, sizeof base);
        int32_t *slot = k == 0 ? &mm->kd : k == 1 ? &mm->ks : &mm->alpha;
        r = scene_texture(c, base, tp.data, mesh, m, mi, key, slot);
        if (r == PM_OK && k == 2)
            s->any_alpha = 1;
    }
    return r;
}

/* sin and cos of an angle in degrees, exact at multiples of 90 (so that a quarter turn maps a
 * coordinate axis onto another with no 6e-17 residue, and a typed matrix can match it). */
static void sincos_degrees(double deg, double *s_out, double *c_out)
{
    double r = fmod(deg, 360.0);
    if (r < 0)
        r += 360.0;
    if (r == 0.0 || r == 90.0 || r == 180.0 || r == 270.0) {
        static const double s4[4] = {0, 1, 0, -1}, c4[4] = {1, 0, -1, 0};
        int q = (int)(r / 90.0);
        *s_out = s4[q], *c_out = c4[q];
        return;
    }
    *s_out = sin(r * (M_PI / 180.0)), *c_out = cos(r * (M_PI / 180.0));
}

/* a = b * a for affine 3x4 matrices (rows of [3x3 | t]): b applied after a. */
static void affine_after(double a[3][4], const double b[3][4])
{
    double o[3][4];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            o[i][j] = b[i][0] * a[0][j] + b[i][1] * a[1][j] + b[i][2] * a[2][j] + (j == 3 ? b[i][3] : 0.0);
    memcpy(a, o, sizeof o);
}

static double det3(const double m[3][4])
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* A mesh entry's placement (docs/scene-format.md, Transforms): scale, then rotate, then
 * translate, then matrix, composed into one affine map xf_out. *general_out is 0 when only scale
 * and translate are given: those scenes keep the arithmetic they always had (same vertices to
 * the bit). */
static pm_result_t load_transform(const ctx_t *c, json_t *mj, const char *where, double xf_out[3][4], int *general_out)
{
    double scale = 1.0;
    float tr[3] = {0, 0, 0};
    char p1[96], p2[96], p3[96];
    snprintf(p1, sizeof p1, "%s.scale", where);
    snprintf(p2, sizeof p2, "%s.translate", where);
    pm_result_t r;
    if ((r = get_number(c, mj, "scale", p1, 0, 1e-30, PM_SCENE_COORD_MAX, &scale)) != PM_OK ||
        (r = get_vec3(c, mj, "translate", p2, 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, tr)) != PM_OK)
        return r;
    memset(xf_out, 0, 12 * sizeof(double));
    for (int i = 0; i < 3; i++)
        xf_out[i][i] = scale;
    *general_out = 0;
    json_t *rot = json_object_get(mj, "rotate");
    if (rot) {
        static const char *const rkeys[] = {"axis", "degrees", NULL};
        snprintf(p1, sizeof p1, "%s.rotate", where);
        if (!json_is_object(rot))
            return bad(c, p1, "must be an object {\"axis\": [x, y, z], \"degrees\": angle}");
        float axis[3];
        double deg = 0;
        snprintf(p2, sizeof p2, "%s.rotate.axis", where);
        snprintf(p3, sizeof p3, "%s.rotate.degrees", where);
        if ((r = only_keys(c, rot, p1, rkeys)) != PM_OK ||
            (r = get_vec3(c, rot, "axis", p2, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, axis)) != PM_OK ||
            (r = get_number(c, rot, "degrees", p3, 1, -1e6, 1e6, &deg)) != PM_OK)
            return r;
        double a[3] = {axis[0], axis[1], axis[2]}, len = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        if (!(len > 0) || !isfinite(len))
            return bad(c, p2, "is the zero vector: a rotation needs an axis");
        for (int k = 0; k < 3; k++)
            a[k] /= len;
        double sn, cs;
        sincos_degrees(deg, &sn, &cs);
        /* Rodrigues: R = cos I + sin [a]x + (1 - cos) a a^T, counter-clockwise seen from the tip of a. */
        double R[3][4] = {
            {cs + a[0] * a[0] * (1 - cs), a[0] * a[1] * (1 - cs) - a[2] * sn, a[0] * a[2] * (1 - cs) + a[1] * sn, 0},
            {a[1] * a[0] * (1 - cs) + a[2] * sn, cs + a[1] * a[1] * (1 - cs), a[1] * a[2] * (1 - cs) - a[0] * sn, 0},
            {a[2] * a[0] * (1 - cs) - a[1] * sn, a[2] * a[1] * (1 - cs) + a[0] * sn, cs + a[2] * a[2] * (1 - cs), 0}};
        affine_after(xf_out, R);
        *general_out = 1;
    }
    for (int k = 0; k < 3; k++)
        xf_out[k][3] = tr[k];
    json_t *mat = json_object_get(mj, "matrix");
    if (mat) {
        snprintf(p1, sizeof p1, "%s.matrix", where);
        if (!json_is_array(mat) || json_array_size(mat) != 16)
            return bad(c, p1, "must be an array of 16 numbers (4 x 4, row-major), not %zu",
                       json_is_array(mat) ? json_array_size(mat) : (size_t)0);
        double m[16];
        for (size_t i = 0; i < 16; i++) {
            json_t *e = json_array_get(mat, i);
            if (!json_is_number(e))
                return bad(c, p1, "element %zu is not a number", i);
            m[i] = json_number_value(e);
            if (!isfinite(m[i]) || fabs(m[i]) > PM_SCENE_COORD_MAX)
                return bad(c, p1, "element %zu = %.9g is not finite or beyond %g", i, m[i], PM_SCENE_COORD_MAX);
        }
        if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0)
            return bad(c, p1, "last row %.9g %.9g %.9g %.9g is not 0 0 0 1: only affine maps are supported", m[12],
                       m[13], m[14], m[15]);
        double M[3][4] = {{m[0], m[1], m[2], m[3]}, {m[4], m[5], m[6], m[7]}, {m[8], m[9], m[10], m[11]}};
        /* Singular, or so near it that float vertices collapse: |det| against the product of
         * the rows' lengths (the volume of the unit cube's image against the most it could be). */
        double rows = 1.0;
        for (int i = 0; i < 3; i++)
            rows *= sqrt(M[i][0] * M[i][0] + M[i][1] * M[i][1] + M[i][2] * M[i][2]);
        double d = det3(M);
        if (!(fabs(d) > 1e-9 * rows))
            return bad(c, p1, "is singular (determinant %.9g of its 3 x 3 part): it flattens the mesh", d);
        affine_after(xf_out, M);
        *general_out = 1;
    }
    return PM_OK;
}

static pm_result_t load_mesh(ctx_t *c, json_t *mj, size_t index)
{
    static const char *const keys[] = {"file", "scale", "rotate", "translate", "matrix", NULL};
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
    double xf[3][4];
    int general;
    if ((r = load_transform(c, mj, where, xf, &general)) != PM_OK)
        return r;
    /* A mirroring map (negative determinant) turns the right-hand-rule normal of every
     * triangle inward: its vertex order is swapped so that the front face (the side an
     * emitter lights) stays the mirror image of the mesh's own. */
    int flip = det3(xf) < 0.0;
    resolve(c->file, file, path, sizeof path);
    size_t ext = strlen(path);
    int is_obj = ext > 4 && strcasecmp(path + ext - 4, ".obj") == 0;
    import_t *im = NULL;
    for (size_t i = 0; i < c->nimports && !im; i++)
        if (strcmp(c->imports[i].path, path) == 0)
            im = &c->imports[i];
    if (!im) {
        FILE *probe = fopen(path, "rb");
        if (!probe)
            return pm_error_set(PM_ERR_INPUT, "cannot open mesh '%s': %s", path, strerror(errno));
        fclose(probe);
        if ((r = grow((void **)&c->imports, c->nimports + 1, sizeof *c->imports)) != PM_OK)
            return r;
        /* Triangulate polygons, merge shared vertices, flatten node transforms, drop points
         * and lines; vertex normals come as the file has them (none are made up). */
        struct aiLogStream log = {on_assimp_log, NULL};
        ai_first_error[0] = '\0';
        aiAttachLogStream(&log);
        const struct aiScene *imported = aiImportFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                                                aiProcess_PreTransformVertices | aiProcess_SortByPType |
                                                                aiProcess_ValidateDataStructure);
        aiDetachAllLogStreams();
        if (!imported)
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, aiGetErrorString());
        if (ai_first_error[0]) {
            aiReleaseImport(imported);
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, ai_first_error);
        }
        /* An OBJ whose faces name no material (no mtllib, or a usemtl the .mtl lacks) gets
         * assimp's default material, or the .mtl's last one; rendering either would be
         * silently wrong. The OBJ's own order of lines tells; the default material is checked
         * after it. */
        char libs_read[4096] = "";
        if (is_obj && (r = check_obj_materials(path, libs_read, sizeof libs_read)) != PM_OK) {
            aiReleaseImport(imported);
            return r;
        }
        im = &c->imports[c->nimports++];
        *im = (import_t){.as = imported};
        snprintf(im->path, sizeof im->path, "%s", path);
        snprintf(im->libs, sizeof im->libs, "%s", libs_read);
        if (is_obj && (r = mtl_homes(path, libs_read, im)) != PM_OK)
            return r;
    }
    /* the import is the scene's until pm_scene_load ends: it serves every entry placing it */
    const struct aiScene *as = im->as;
    const char *libs = im->libs;
    size_t tri_start = s->ntris, vert_start = s->nverts;
    uint64_t kept = 0; /* which faces are kept (degenerate ones left out): a placement's key */
    for (unsigned mi = 0; is_obj && mi < as->mNumMeshes; mi++) {
        const struct aiMesh *m = as->mMeshes[mi];
        struct aiString mname;
        if (m->mMaterialIndex < as->mNumMaterials &&
            aiGetMaterialString(as->mMaterials[m->mMaterialIndex], AI_MATKEY_NAME, &mname) == aiReturn_SUCCESS &&
            strcmp(mname.data, AI_DEFAULT_MATERIAL_NAME) == 0) {
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': %u faces of '%s' have no material (no mtllib, or no usemtl before them)",
                                path, m->mNumFaces, m->mName.length ? m->mName.data : "(unnamed)");
        }
    }
    size_t mat0 = s->nmaterials;
    if ((r = grow((void **)&s->materials, mat0 + as->mNumMaterials, sizeof *s->materials)) != PM_OK ||
        (r = grow((void **)&s->maps, mat0 + as->mNumMaterials, sizeof *s->maps)) != PM_OK)
        return r;
    for (size_t i = mat0; i < mat0 + as->mNumMaterials; i++)
        s->maps[i] = (pm_material_maps_t){-1, -1, -1};
    for (unsigned i = 0; i < as->mNumMaterials && r == PM_OK; i++) {
        r = load_material(c, path, is_obj, as->mMaterials[i], &s->materials[mat0 + i]);
        /* assimp's stand-in material is pmtk's grey default whatever it holds: nothing to report */
        struct aiString an;
        int stand_in = aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &an) != aiReturn_SUCCESS ||
                       an.length == 0 || strcmp(an.data, AI_DEFAULT_MATERIAL_NAME) == 0;
        if (r == PM_OK && !stand_in)
            r = scan_material(s, is_obj, as->mMaterials[i], (uint32_t)(mat0 + i));
        /* only the textures of a material some triangle uses: an unused one is dropped unread */
        int used = 0;
        for (unsigned mi = 0; mi < as->mNumMeshes && !used; mi++)
            used =
                as->mMeshes[mi]->mMaterialIndex == i && (as->mMeshes[mi]->mPrimitiveTypes & aiPrimitiveType_TRIANGLE);
        if (r == PM_OK && !stand_in && used)
            r = load_material_maps(c, path, is_obj, im, as->mMaterials[i], (uint32_t)(mat0 + i));
    }
    if (r == PM_OK && is_obj) {
        unsigned char *pbr = malloc(as->mNumMaterials ? as->mNumMaterials : 1);
        float metallic, roughness;
        if (!pbr)
            return pm_error_set(PM_ERR_NOMEM, "out of memory");
        for (unsigned i = 0; i < as->mNumMaterials; i++)
            pbr[i] = (unsigned char)pbr_inputs(1, as->mMaterials[i], &metallic, &roughness);
        r = scan_mtl_dropped(s, path, libs, mat0, as->mNumMaterials, pbr);
        free(pbr);
    }
    if (r != PM_OK)
        return r;
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
        const pm_material_maps_t *mm = &s->maps[mat0 + m->mMaterialIndex];
        if (!m->mTextureCoords[0] && (mm->kd >= 0 || mm->ks >= 0 || mm->alpha >= 0) &&
            (r = note_unsupported(s, (uint32_t)(mat0 + m->mMaterialIndex), "texture coordinates", 0,
                                  "missing (texel 0 0 used)")) != PM_OK)
            break;
        size_t v0 = s->nverts;
        if (s->ntris + m->mNumFaces > PM_SCENE_MAX_TRIS) {
            r = pm_error_set(PM_ERR_INPUT, "mesh '%s': more than %u triangles in the scene", path, PM_SCENE_MAX_TRIS);
            break;
        }
        if ((r = grow((void **)&s->verts, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = grow((void **)&s->uvs, 2 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = grow((void **)&s->normals, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = grow((void **)&c->local, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = grow((void **)&s->tris, 3 * (s->ntris + m->mNumFaces), sizeof(uint32_t))) != PM_OK ||
            (r = grow((void **)&s->tri_material, s->ntris + m->mNumFaces, sizeof(uint32_t))) != PM_OK)
            break;
        for (unsigned v = 0; v < m->mNumVertices; v++) {
            double p[3] = {m->mVertices[v].x, m->mVertices[v].y, m->mVertices[v].z};
            for (int k = 0; k < 3; k++)
                c->local[3 * (v0 + v) + k] = (float)p[k];
            for (int k = 0; k < 3; k++) {
                double x = general ? xf[k][0] * p[0] + xf[k][1] * p[1] + xf[k][2] * p[2] + xf[k][3]
                                   : p[k] * xf[k][k] + xf[k][3];
                if (!isfinite(x) || fabs(x) > PM_SCENE_COORD_MAX) {
                    r = pm_error_set(PM_ERR_INPUT, "mesh '%s': vertex %u coordinate %c = %g is not finite or beyond %g",
                                     path, v, "xyz"[k], x, PM_SCENE_COORD_MAX);
                    break;
                }
                s->verts[3 * (v0 + v) + k] = (float)x;
            }
            /* the first set of texture coordinates; none: every point reads texel (0, 0) */
            const struct aiVector3D *uv = m->mTextureCoords[0] ? &m->mTextureCoords[0][v] : NULL;
            float uu = uv ? uv->x : 0.0f, vv = uv ? uv->y : 0.0f;
            s->uvs[2 * (v0 + v)] = isfinite(uu) ? uu : 0.0f;
            s->uvs[2 * (v0 + v) + 1] = isfinite(vv) ? vv : 0.0f;
            /* The vertex normal by the cofactor matrix of the map (normals transform by the
             * inverse transpose; its scale and sign do not matter: pm_scene_shading_normal
             * normalizes it and turns it to the side the ray came from). None, or one that is
             * not finite: zero, which falls back to the geometric normal. */
            float *nv = &s->normals[3 * (v0 + v)];
            nv[0] = nv[1] = nv[2] = 0.0f;
            if (m->mNormals) {
                double a[3] = {m->mNormals[v].x, m->mNormals[v].y, m->mNormals[v].z}, q[3];
                for (int k = 0; k < 3; k++) {
                    int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
                    double c0 = xf[k1][1] * xf[k2][2] - xf[k1][2] * xf[k2][1],
                           c1 = xf[k1][2] * xf[k2][0] - xf[k1][0] * xf[k2][2],
                           c2 = xf[k1][0] * xf[k2][1] - xf[k1][1] * xf[k2][0];
                    q[k] = c0 * a[0] + c1 * a[1] + c2 * a[2];
                }
                double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
                if (isfinite(len) && len > 0.0)
                    for (int k = 0; k < 3; k++)
                        nv[k] = (float)(q[k] / len);
                c->any_normals = 1;
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
                t[k] = (uint32_t)(v0 + face->mIndices[flip && k ? 3 - k : k]);
            }
            if (r != PM_OK)
                break;
            s->tri_material[s->ntris] = (uint32_t)(mat0 + m->mMaterialIndex);
            s->ntris++;
            /* Zero-area triangles scatter nothing and have no normal: leave them out, and
             * those too small for a float normal with them. One too large for a float normal
             * cannot be left out without changing the scene: refuse it. */
            double area = pm_scene_triangle_area(s, s->ntris - 1);
            if (area > PM_SCENE_AREA_MAX) {
                r = pm_error_set(PM_ERR_INPUT,
                                 "mesh '%s': face %u has an area of %g m^2, beyond %g m^2 (its normal overflows a "
                                 "float): scale the scene down",
                                 path, f, area, PM_SCENE_AREA_MAX);
                break;
            }
            if (!(area >= PM_SCENE_AREA_MIN)) {
                s->ntris--;
                s->ndropped++;
            } else {
                uint64_t id[3] = {kept, mi, f};
                kept = pm_hash_bytes(id, sizeof id);
            }
        }
    }
    if (r != PM_OK)
        return r;
    /* This entry's placement: entries with equal keys hold the same triangles in the same mesh
     * units and winding, so that Embree can keep one copy and place it by instances. */
    if ((r = grow((void **)&s->placements, s->nplacements + 1, sizeof *s->placements)) != PM_OK)
        return r;
    pm_placement_t *pl = &s->placements[s->nplacements++];
    memset(pl, 0, sizeof *pl);
    uint64_t id[4] = {pm_hash_bytes(path, strlen(path)), kept, (uint64_t)flip, s->ntris - tri_start};
    pl->key = pm_hash_bytes(id, sizeof id);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            pl->xf[4 * i + j] = (float)xf[i][j];
    pl->tri0 = (uint32_t)tri_start, pl->ntris = (uint32_t)(s->ntris - tri_start);
    pl->vert0 = (uint32_t)vert_start, pl->nverts = (uint32_t)(s->nverts - vert_start);
    pl->proto = -1;
    return PM_OK;
}

/* Releases the import of entry i's mesh file unless a later entry places the same file, so
 * that a scene of many different files holds one import at a time. */
static void release_import(ctx_t *c, json_t *meshes, size_t i)
{
    const char *file = json_string_value(json_object_get(json_array_get(meshes, i), "file"));
    if (!file)
        return;
    char path[1200], later[1200];
    resolve(c->file, file, path, sizeof path);
    for (size_t j = i + 1; j < json_array_size(meshes); j++) {
        const char *f = json_string_value(json_object_get(json_array_get(meshes, j), "file"));
        if (!f)
            continue;
        resolve(c->file, f, later, sizeof later);
        if (strcmp(later, path) == 0)
            return;
    }
    for (size_t k = 0; k < c->nimports; k++)
        if (c->imports[k].as && strcmp(c->imports[k].path, path) == 0) {
            aiReleaseImport(c->imports[k].as);
            c->imports[k].as = NULL;
            c->imports[k].path[0] = '\0'; /* never found again */
            free(c->imports[k].homes);
            c->imports[k].homes = NULL;
            c->imports[k].nhomes = 0;
        }
}

/* Marks the placements Embree may instance (a key placed more than once, unless the scene
 * says "instancing": false) and keeps their prototype's vertices in mesh units. */
static pm_result_t find_instances(ctx_t *c, int allowed)
{
    pm_scene_t *s = c->s;
    size_t nlocal = 0;
    for (size_t i = 0; allowed && i < s->nplacements; i++) {
        pm_placement_t *p = &s->placements[i];
        for (size_t j = 0; j < i && p->proto < 0; j++) {
            pm_placement_t *q = &s->placements[j];
            if (q->key == p->key && q->ntris == p->ntris && q->nverts == p->nverts && p->ntris > 0) {
                if (q->proto < 0) { /* q becomes the prototype */
                    q->proto = (int32_t)j;
                    q->local0 = (uint32_t)nlocal;
                    nlocal += q->nverts;
                }
                p->proto = q->proto;
            }
        }
    }
    if (!nlocal)
        return PM_OK;
    s->local_verts = malloc(3 * nlocal * sizeof(float));
    if (!s->local_verts)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu instanced vertices", nlocal);
    for (size_t i = 0; i < s->nplacements; i++) {
        const pm_placement_t *p = &s->placements[i];
        if (p->proto == (int32_t)i)
            memcpy(s->local_verts + 3 * (size_t)p->local0, c->local + 3 * (size_t)p->vert0,
                   3 * (size_t)p->nverts * sizeof(float));
    }
    return PM_OK;
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
    double c[3], r;
    pm_scene_sphere(s, c, &r);
    /* L times the cone's solid angle times the disc's area pi R^2 (render/transport.h, pm_env_emit). */
    return s->sun.radiance[k] * (double)s->sun.solid_angle * M_PI * r * r;
}

double pm_sky_power(const pm_scene_t *s, int k)
{
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
            p[k] += (s->two_sided_lights ? 2.0 : 1.0) * M_PI * s->materials[s->tri_material[t]].ke[k] * a;
    }
    for (int k = 0; k < 3 && s->has_sun; k++)
        p[k] += pm_sun_power(s, k);
    for (int k = 0; k < 3 && s->has_sky; k++)
        p[k] += pm_sky_power(s, k);
}

size_t pm_scene_flipped_emitters(const pm_scene_t *s, uint32_t *first_out)
{
    float ext[3] = {s->bounds[3] - s->bounds[0], s->bounds[4] - s->bounds[1], s->bounds[5] - s->bounds[2]};
    float eps = 1e-3f * sqrtf(pm_dot3(ext, ext)); /* m */
    size_t n = 0;
    *first_out = 0;
    if (s->two_sided_lights)
        return 0; /* both faces emit: no winding faces away */
    for (size_t i = 0; i < s->nemissive; i++) {
        const uint32_t *t = &s->tris[3 * (size_t)s->emissive[i]];
        const float *a = &s->verts[3 * (size_t)t[0]], *b = &s->verts[3 * (size_t)t[1]],
                    *c = &s->verts[3 * (size_t)t[2]];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        float len = sqrtf(pm_dot3(nrm, nrm));
        if (!(len > 0.0f))
            continue;
        int sees = 0;
        for (size_t v = 0; v < s->nverts && !sees; v++) {
            const float *p = &s->verts[3 * v];
            float d[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
            sees = pm_dot3(d, nrm) > eps * len;
        }
        if (!sees && n++ == 0)
            *first_out = s->emissive[i];
    }
    return n;
}

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
    for (size_t m = 0; s->maps && m < s->nmaterials; m++)
        any |= s->maps[m].kd >= 0 || s->maps[m].ks >= 0 || s->maps[m].alpha >= 0;
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
    return PM_OK;
}

/* The materials' share of the scene hash. Without a mirror or glass, each material's bytes up
 * to its specular fields (name to ke, no padding), as the hash took them before those fields
 * existed, so that such a scene's identity, and every file naming it, stays what it was. */
static pm_result_t hash_materials(const pm_scene_t *s, uint64_t *out)
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
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, size = 0.0;
    for (size_t v = 0; v < s->nverts; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], s->verts[3 * v + k]);
            hi[k] = fmax(hi[k], s->verts[3 * v + k]);
        }
    for (int k = 0; k < 3; k++)
        size = fmax(size, hi[k] - lo[k]);
    if (size < PM_SCENE_SIZE_MIN)
        return bad(c, "meshes",
                   "the geometry spans %g m, below the smallest scene pmtk renders, %g m (float normals "
                   "and ray hits fail below it): scale it up with meshes[].scale",
                   size, PM_SCENE_SIZE_MIN);
    return PM_OK;
}

/* The point lights' hash: position and intensity of each, the bytes a scene without spots
 * always hashed (its hash stays what it was), then the spots' axes, cones and falloffs when
 * there is any spot. */
static pm_result_t hash_lights(const pm_scene_t *s, uint64_t *hash_out)
{
    float *b = malloc((s->nlights ? s->nlights : 1) * 6 * sizeof(float));
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
static void hash_parts(pm_scene_t *s, const uint64_t h[6])
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

pm_result_t pm_scene_load(const char *path, pm_scene_t *s)
{
    memset(s, 0, sizeof *s);
    ctx_t c = {path, s, 0, NULL, 0, NULL, 0};
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
    static const char *const keys[] = {
        "pmtk_scene", "name",   "meshes",           "camera",     "point_lights",     "sun",
        "sky",        "render", "missing_textures", "instancing", "two_sided_lights", "shading_normals",
        NULL};
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
    json_t *mt = json_object_get(root, "missing_textures");
    if (r == PM_OK && mt) {
        const char *v = json_string_value(mt);
        if (v && strcmp(v, "magenta") == 0)
            c.missing_magenta = 1;
        else if (!v || strcmp(v, "error") != 0)
            r = bad(&c, "missing_textures", "must be \"error\" (the default) or \"magenta\"");
    }
    json_t *meshes = json_object_get(root, "meshes");
    if (r == PM_OK && meshes && !json_is_array(meshes))
        r = bad(&c, "meshes", "must be an array");
    for (size_t i = 0; r == PM_OK && meshes && i < json_array_size(meshes); i++) {
        r = load_mesh(&c, json_array_get(meshes, i), i);
        release_import(&c, meshes, i);
        /* Mesh and material faults name the mesh; say which scene entry brought it in. */
        if (r == PM_ERR_INPUT && strncmp(pm_error_message(), "scene '", 7) != 0)
            pm_error_prefix("scene '%s': meshes[%zu]", path, i);
    }
    json_t *two = json_object_get(root, "two_sided_lights");
    if (r == PM_OK && two && !json_is_boolean(two))
        r = bad(&c, "two_sided_lights", "must be true or false (the default: emitters light from their front face)");
    s->two_sided_lights = two && json_is_true(two);
    json_t *shn = json_object_get(root, "shading_normals");
    if (r == PM_OK && shn && !json_is_boolean(shn))
        r = bad(&c, "shading_normals", "must be true (the default: the meshes' vertex normals shade) or false");
    s->normals_ignored = shn && json_is_false(shn) && c.any_normals;
    if (r == PM_OK && ((shn && json_is_false(shn)) || !c.any_normals)) {
        /* Ignored, or no mesh has any: geometric normals, and nothing to pay for the feature. */
        free(s->normals);
        s->normals = NULL;
    }
    json_t *inst = json_object_get(root, "instancing");
    if (r == PM_OK && inst && !json_is_boolean(inst))
        r = bad(&c, "instancing", "must be true (the default) or false");
    if (r == PM_OK)
        r = find_instances(&c, !inst || json_is_true(inst));
    for (size_t i = 0; i < c.nimports; i++) {
        if (c.imports[i].as)
            aiReleaseImport(c.imports[i].as);
        free(c.imports[i].homes);
    }
    free(c.imports);
    free(c.local);
    if (r == PM_OK)
        r = check_size(&c);
    if (r == PM_OK)
        r = load_camera(&c, json_object_get(root, "camera"));
    if (r == PM_OK)
        r = load_lights(&c, json_object_get(root, "point_lights"));
    if (r == PM_OK)
        r = load_sun_sky(&c, json_object_get(root, "sun"), json_object_get(root, "sky"));
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
        if (r == PM_OK)
            r = hash_materials(s, &h[4]);
        if (r == PM_OK)
            r = hash_lights(s, &h[5]);
        s->hash = pm_hash_bytes(h, sizeof h);
        if (r == PM_OK && (r = drop_unused_maps(s)) == PM_OK && s->maps) {
            /* Textured: their texels, the coordinates and which material uses which. A scene
             * without textures keeps the hash it always had. */
            uint64_t t[4] = {s->hash, pm_hash_bytes(s->uvs, 2 * s->nverts * sizeof(float)),
                             pm_hash_bytes(s->maps, s->nmaterials * sizeof *s->maps), 0};
            for (size_t i = 0; i < s->ntextures; i++)
                t[3] = pm_hash_bytes((uint64_t[2]){t[3], s->textures[i].hash}, 2 * sizeof(uint64_t));
            s->hash = pm_hash_bytes(t, sizeof t);
        }
        if (r == PM_OK)
            hash_parts(s, h);
    }
    if (r == PM_OK && s->normals) /* shading normals: folded in only when used, other scenes keep their hash */
        s->hash = pm_hash_bytes((uint64_t[2]){s->hash, pm_hash_bytes(s->normals, 3 * s->nverts * sizeof(float))},
                                2 * sizeof(uint64_t));
    if (r == PM_OK && s->two_sided_lights) /* folded in only when set: other scenes keep their hash */
        s->hash = pm_hash_bytes((uint64_t[2]){s->hash, 2}, 2 * sizeof(uint64_t));
    if (r == PM_OK && (s->has_sun || s->has_sky)) {
        /* A sun or a sky: folded into the hash; a scene without either keeps the hash it had. */
        uint64_t e[3] = {s->hash, s->has_sun ? pm_hash_bytes(&s->sun, sizeof s->sun) : 0,
                         s->has_sky ? pm_hash_bytes(s->sky, sizeof s->sky) : 0};
        if (s->envmap) /* the map's texels (already scaled) and size */
            e[2] = pm_hash_bytes(
                (uint64_t[3]){e[2],
                              pm_hash_bytes(s->envmap->rgb, 3 * sizeof(float) * s->envmap->w * (size_t)s->envmap->h),
                              (uint64_t)s->envmap->w << 32 | s->envmap->h},
                3 * sizeof(uint64_t));
        s->hash = pm_hash_bytes(e, sizeof e);
    }
    if (r == PM_OK && (s->two_sided_lights || s->has_sun || s->has_sky)) {
        /* Two-sided emitters, a sun or a sky are the photons' part (and the direct light's,
         * which names both parts); the queries do not read them, so the view keeps its hash. */
        uint64_t x[4] = {s->parts.photons, (uint64_t)s->two_sided_lights,
                         s->has_sun ? pm_hash_bytes(&s->sun, sizeof s->sun) : 0,
                         s->has_sky ? pm_hash_bytes(s->sky, sizeof s->sky) : 0};
        if (s->envmap)
            x[3] = pm_hash_bytes((uint64_t[2]){x[3], pm_hash_bytes(s->envmap->rgb, 3 * sizeof(float) * s->envmap->w *
                                                                                       (size_t)s->envmap->h)},
                                 2 * sizeof(uint64_t));
        s->parts.photons = pm_hash_bytes(x, sizeof x);
        s->parts.eye = pm_hash_bytes((uint64_t[2]){s->parts.photons, s->parts.view}, 2 * sizeof(uint64_t));
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
    if (s->envmap)
        pm_envmap_free(s->envmap);
    free(s->envmap);
    free(s->emissive);
    free(s->unsupported);
    free(s->maps);
    free(s->uvs);
    free(s->normals);
    free(s->placements);
    free(s->local_verts);
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

void pm_scene_barycentrics(const pm_scene_t *s, uint32_t tri, const float p[3], float b_out[2])
{
    const float *a = &s->verts[3 * s->tris[3 * tri]], *b = &s->verts[3 * s->tris[3 * tri + 1]],
                *c = &s->verts[3 * s->tris[3 * tri + 2]];
    float e1[3], e2[3], d[3];
    for (int k = 0; k < 3; k++)
        e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], d[k] = p[k] - a[k];
    float d11 = pm_dot3(e1, e1), d12 = pm_dot3(e1, e2), d22 = pm_dot3(e2, e2), p1 = pm_dot3(d, e1), p2 = pm_dot3(d, e2),
          det = d11 * d22 - d12 * d12;
    float b1 = det > 0.0f ? (d22 * p1 - d12 * p2) / det : 0.0f, b2 = det > 0.0f ? (d11 * p2 - d12 * p1) / det : 0.0f;
    /* a point found by a ray lies in the triangle up to rounding: clamp it back in */
    b1 = b1 > 0.0f ? b1 : 0.0f;
    b2 = b2 > 0.0f ? b2 : 0.0f;
    if (b1 + b2 > 1.0f) {
        float t = b1 + b2;
        b1 /= t, b2 /= t;
    }
    b_out[0] = b1, b_out[1] = b2;
}

void pm_scene_uv(const pm_scene_t *s, uint32_t tri, float b1, float b2, float uv_out[2])
{
    uv_out[0] = uv_out[1] = 0.0f;
    if (!s->uvs)
        return;
    const float *t0 = &s->uvs[2 * s->tris[3 * tri]], *t1 = &s->uvs[2 * s->tris[3 * tri + 1]],
                *t2 = &s->uvs[2 * s->tris[3 * tri + 2]];
    float b0 = 1.0f - b1 - b2;
    for (int k = 0; k < 2; k++)
        uv_out[k] = b0 * t0[k] + b1 * t1[k] + b2 * t2[k];
}

const pm_material_t *pm_scene_material_textured(const pm_scene_t *s, uint32_t tri, const float p[3],
                                                pm_material_t *scratch)
{
    uint32_t mi = s->tri_material[tri];
    const pm_material_maps_t *mm = &s->maps[mi];
    *scratch = s->materials[mi];
    float b[2], uv[2], texel[4];
    pm_scene_barycentrics(s, tri, p, b);
    pm_scene_uv(s, tri, b[0], b[1], uv);
    if (mm->kd >= 0) {
        pm_texture_lookup(&s->textures[mm->kd], uv[0], uv[1], 1, texel);
        for (int k = 0; k < 3; k++)
            scratch->kd[k] *= fminf(texel[k], 1.0f);
    }
    if (mm->ks >= 0) {
        pm_texture_lookup(&s->textures[mm->ks], uv[0], uv[1], 1, texel);
        for (int k = 0; k < 3; k++)
            scratch->ks[k] *= fminf(texel[k], 1.0f);
    }
    return scratch;
}

int pm_scene_cut_out(const pm_scene_t *s, uint32_t tri, float b1, float b2)
{
    int32_t a = s->maps ? s->maps[s->tri_material[tri]].alpha : -1;
    if (a < 0)
        return 0;
    const pm_texture_t *t = &s->textures[a];
    float uv[2], texel[4];
    pm_scene_uv(s, tri, b1, b2, uv);
    pm_texture_lookup(t, uv[0], uv[1], 0, texel);
    /* the alpha channel when the image has one, else its grey (a mask image) */
    return (t->has_alpha ? texel[3] : texel[0]) < 0.5f;
}

int pm_scene_shading_normal(const pm_scene_t *s, uint32_t tri, const float p[3], const float n[3], float ns_out[3])
{
    ns_out[0] = n[0], ns_out[1] = n[1], ns_out[2] = n[2];
    if (!s->normals)
        return 0;
    const float *n0 = &s->normals[3 * s->tris[3 * tri]], *n1 = &s->normals[3 * s->tris[3 * tri + 1]],
                *n2 = &s->normals[3 * s->tris[3 * tri + 2]];
    float b[2], q[3];
    pm_scene_barycentrics(s, tri, p, b);
    float b0 = 1.0f - b[0] - b[1];
    for (int k = 0; k < 3; k++)
        q[k] = b0 * n0[k] + b[0] * n1[k] + b[1] * n2[k];
    float len2 = pm_dot3(q, q);
    /* No normals at this triangle (zero), or ones that cancel: the geometric normal. */
    if (!(len2 > 1e-12f) || !isfinite(len2))
        return 0;
    float inv = 1.0f / sqrtf(len2);
    if (pm_dot3(q, n) < 0.0f) /* the side n is on: the mesh's normals may face the other way */
        inv = -inv;
    for (int k = 0; k < 3; k++)
        ns_out[k] = q[k] * inv;
    return 1;
}
