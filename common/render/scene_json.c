/* scene_json.c: the scene file's own keys (docs/scene-format.md): its JSON helpers, which name
 * the key path and the value in every error, the camera, point lights and spots, the sun and the
 * sky, the render defaults, and a mesh entry's placement (scale, rotate, translate, matrix). */
#include "render/scene.h"

#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/formats.h"
#include "render/light.h"
#include "render/scene_load.h"
#include "render/skymodel.h"

pm_result_t pm_scene_bad(const ctx_t *c, const char *key, const char *fmt, ...)
{
    char detail[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    return pm_error_set(PM_ERR_INPUT, "scene '%s': %s: %s", c->file, key, detail);
}

/* Unknown keys are errors: a typo must not silently fall back to a default. */
pm_result_t pm_scene_only_keys(const ctx_t *c, json_t *obj, const char *where, const char *const *allowed)
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
            return pm_scene_bad(c, where, "unknown key '%s' (known: %s)", k, list);
        }
    }
    return PM_OK;
}

/* obj's member name into *v_out: NULL when it is absent and optional (leave the
 * default), an error naming path when it is absent and required. */
static pm_result_t member(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, json_t **v_out)
{
    *v_out = json_object_get(obj, name);
    return !*v_out && required ? pm_scene_bad(c, path, "missing") : PM_OK;
}

pm_result_t pm_scene_get_number(const ctx_t *c, json_t *obj, const char *name, const char *path, int required,
                                double lo, double hi, double *out)
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_number(v))
        return pm_scene_bad(c, path, "must be a number");
    double x = json_number_value(v);
    if (!isfinite(x) || x < lo || x > hi)
        return pm_scene_bad(c, path, "%.9g is outside [%.9g, %.9g]", x, lo, hi);
    *out = x;
    return PM_OK;
}

pm_result_t pm_scene_get_int(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, int64_t lo,
                             int64_t hi, int64_t *out)
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_integer(v))
        return pm_scene_bad(c, path, "must be an integer");
    int64_t x = json_integer_value(v);
    if (x < lo || x > hi)
        return pm_scene_bad(c, path, "%lld is outside [%lld, %lld]", (long long)x, (long long)lo, (long long)hi);
    *out = x;
    return PM_OK;
}

pm_result_t pm_scene_get_vec3(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, double lo,
                              double hi, float out[3])
{
    json_t *v;
    pm_result_t r = member(c, obj, name, path, required, &v);
    if (r != PM_OK || !v)
        return r;
    if (!json_is_array(v) || json_array_size(v) != 3)
        return pm_scene_bad(c, path, "must be an array of 3 numbers");
    for (size_t i = 0; i < 3; i++) {
        json_t *e = json_array_get(v, i);
        if (!json_is_number(e))
            return pm_scene_bad(c, path, "element %zu is not a number", i);
        double x = json_number_value(e);
        if (!isfinite(x) || x < lo || x > hi)
            return pm_scene_bad(c, path, "element %zu = %.9g is outside [%.9g, %.9g]", i, x, lo, hi);
        out[i] = (float)x;
    }
    return PM_OK;
}

pm_result_t pm_scene_load_camera(const ctx_t *c, json_t *cam)
{
    static const char *const keys[] = {"eye", "look_at", "up", "fov_y", "width", "height", NULL};
    pm_camera_t *k = &c->s->camera;
    if (!json_is_object(cam))
        return pm_scene_bad(c, "camera", "missing or not an object");
    if (json_object_get(cam, "mesh")) /* a camera the mesh file carries (scene_punctual.c) */
        return pm_scene_asset_camera(c, cam);
    pm_result_t r = pm_scene_only_keys(c, cam, "camera", keys);
    double fov = 0;
    int64_t w = 0, h = 0;
    k->up[0] = 0, k->up[1] = 1, k->up[2] = 0;
    if (r == PM_OK)
        r = pm_scene_get_vec3(c, cam, "eye", "camera.eye", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, k->eye);
    if (r == PM_OK)
        r = pm_scene_get_vec3(c, cam, "look_at", "camera.look_at", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX,
                              k->look_at);
    if (r == PM_OK)
        r = pm_scene_get_vec3(c, cam, "up", "camera.up", 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, k->up);
    if (r == PM_OK)
        r = pm_scene_get_number(c, cam, "fov_y", "camera.fov_y", 1, 1e-3, 179.0, &fov);
    if (r == PM_OK)
        r = pm_scene_get_int(c, cam, "width", "camera.width", 1, 1, 65536, &w);
    if (r == PM_OK)
        r = pm_scene_get_int(c, cam, "height", "camera.height", 1, 1, 65536, &h);
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
        return pm_scene_bad(c, "camera.look_at", "equals camera.eye: no view direction");
    if (!(ul > 0))
        return pm_scene_bad(c, "camera.up", "is the zero vector");
    if (fabs(dot) >= 0.999999 * sqrt(dl * ul))
        return pm_scene_bad(c, "camera.up", "is parallel to the view direction");
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
        return pm_scene_bad(c, pd, "missing (a light with a cone or a falloff is a spot and needs an axis)");
    if (cone && json_is_number(cone)) {
        /* The half-angle's own range, stated as users read it: (0, 180] degrees. */
        double a = json_number_value(cone);
        if (!(a > 0.0 && a <= 180.0))
            return pm_scene_bad(c, pc, "%.9g degrees is outside (0, 180]", a);
    }
    double a = 180.0, e = 0.0;
    float d[3];
    pm_result_t r = pm_scene_get_vec3(c, l, "direction", pd, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, d);
    if (r == PM_OK)
        r = pm_scene_get_number(c, l, "cone", pc, 0, 0.0, 180.0, &a);
    if (r == PM_OK)
        r = pm_scene_get_number(c, l, "falloff", pf, 0, 0.0, 1e4, &e);
    if (r != PM_OK)
        return r;
    double dl = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
    if (!(dl > 0.0))
        return pm_scene_bad(c, pd, "is the zero vector");
    for (int k = 0; k < 3; k++)
        pl->axis[k] = (float)(d[k] / dl);
    pl->cos_cone = a >= 180.0 ? -1.0f : (float)cos(a * M_PI / 180.0);
    pl->falloff = (float)e;
    if (!(pl->cos_cone < 1.0f))
        return pm_scene_bad(c, pc, "%.9g degrees is too narrow: its cosine rounds to 1", a);
    return PM_OK;
}

pm_result_t pm_scene_load_lights(const ctx_t *c, json_t *lights)
{
    static const char *const keys[] = {"position", "intensity", "direction", "cone", "falloff", NULL};
    if (!lights)
        return PM_OK;
    if (!json_is_array(lights))
        return pm_scene_bad(c, "point_lights", "must be an array");
    size_t n = json_array_size(lights);
    if (n > PM_SCENE_MAX_LIGHTS)
        return pm_scene_bad(c, "point_lights", "%zu lights, more than %u", n, PM_SCENE_MAX_LIGHTS);
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
            return pm_scene_bad(c, where, "must be an object");
        pm_point_light_t *pl = &c->s->lights[i];
        pm_result_t r = pm_scene_only_keys(c, l, where, keys);
        if (r == PM_OK)
            r = pm_scene_get_vec3(c, l, "position", p1, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, pl->position);
        /* 1e30 W/sr: far beyond any light, still leaves headroom in float products. */
        if (r == PM_OK)
            r = pm_scene_get_vec3(c, l, "intensity", p2, 1, 0.0, 1e30, pl->intensity);
        if (r != PM_OK)
            return r;
        if ((r = load_spot(c, l, where, pl)) != PM_OK)
            return r;
    }
    c->s->nlights = n;
    return PM_OK;
}

/* The sky's map: an OpenEXR or Radiance HDR file relative to the scene, each value times
 * sky.radiance, within image_budgets.sky_map_mib. */
static pm_result_t load_envmap(const ctx_t *c, const char *file)
{
    char path[2048];
    pm_scene_resolve(c->file, file, path, sizeof path);
    pm_result_t r0 = pm_scene_add_source(c->s, path);
    if (r0 != PM_OK)
        return r0;
    c->s->envmap = calloc(1, sizeof *c->s->envmap);
    if (!c->s->envmap)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the sky's map");
    pm_result_t r = pm_envmap_load(path, (uint64_t)(c->sky_map_mib * (1 << 20)), c->s->sky, c->s->envmap);
    if (r != PM_OK)
        pm_error_prefix("scene '%s': sky.map '%s'", c->file, file);
    return r;
}

/* The sky's frame (sky.up, default +y; sky.rotate, degrees, default 0): a map is turned by it
 * and the sun's elevation and azimuth are measured in it. */
static pm_result_t load_sky_frame(const ctx_t *c, json_t *sky)
{
    pm_scene_t *s = c->s;
    float up[3] = {0.0f, 1.0f, 0.0f};
    pm_result_t r = PM_OK;
    s->sky_rotate = 0.0;
    if (json_is_object(sky)) {
        r = pm_scene_get_vec3(c, sky, "up", "sky.up", 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, up);
        if (r == PM_OK)
            r = pm_scene_get_number(c, sky, "rotate", "sky.rotate", 0, -1e6, 1e6, &s->sky_rotate);
        if (r != PM_OK)
            return r;
    }
    double ul = sqrt((double)up[0] * up[0] + (double)up[1] * up[1] + (double)up[2] * up[2]);
    if (!(ul > 0.0))
        return pm_scene_bad(c, "sky.up", "is the zero vector");
    for (int k = 0; k < 3; k++)
        s->sky_up[k] = up[k] / ul;
    pm_sky_frame(s->sky_up, s->sky_rotate, s->sky_frame);
    return PM_OK;
}

/* Exactly one of keys a and b of obj (named where.a, where.b in the error). */
static pm_result_t one_of(const ctx_t *c, json_t *obj, const char *where, const char *a, const char *b)
{
    int ha = json_object_get(obj, a) != NULL, hb = json_object_get(obj, b) != NULL;
    if (ha == hb)
        return pm_scene_bad(c, where, "needs exactly one of '%s' and '%s', %s", a, b,
                            ha ? "not both" : "found neither");
    return PM_OK;
}

/* The sun: its direction (a vector, or elevation and azimuth in the sky's frame), its radiance
 * or its irradiance on a surface facing it, and its solid angle. */
static pm_result_t load_sun(const ctx_t *c, json_t *sun)
{
    static const char *const sun_keys[] = {"direction",  "elevation",   "azimuth", "radiance",
                                           "irradiance", "solid_angle", NULL};
    pm_scene_t *s = c->s;
    pm_result_t r;
    if (!json_is_object(sun))
        return pm_scene_bad(c, "sun", "must be an object");
    double omega = 0.0, d[3] = {0.0, 0.0, 0.0};
    json_t *om = json_object_get(sun, "solid_angle");
    /* Stated as users read it: the solid angle must be positive, and a hemisphere at most. */
    if (om && json_is_number(om) && !(json_number_value(om) > 0.0 && json_number_value(om) <= 2.0 * M_PI))
        return pm_scene_bad(c, "sun.solid_angle", "%.9g sr is outside (0, 2 pi]", json_number_value(om));
    if ((r = pm_scene_only_keys(c, sun, "sun", sun_keys)) != PM_OK ||
        (r = one_of(c, sun, "sun", "direction", "elevation")) != PM_OK ||
        (r = one_of(c, sun, "sun", "radiance", "irradiance")) != PM_OK)
        return r;
    if (json_object_get(sun, "direction")) {
        float df[3];
        if (json_object_get(sun, "azimuth"))
            return pm_scene_bad(c, "sun.azimuth", "goes with elevation, not with direction");
        if ((r = pm_scene_get_vec3(c, sun, "direction", "sun.direction", 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX,
                                   df)) != PM_OK)
            return r;
        for (int k = 0; k < 3; k++)
            d[k] = df[k];
    } else {
        double el = 0.0, az = 0.0;
        if ((r = pm_scene_get_number(c, sun, "elevation", "sun.elevation", 1, -90.0, 90.0, &el)) != PM_OK ||
            (r = pm_scene_get_number(c, sun, "azimuth", "sun.azimuth", 1, -360.0, 360.0, &az)) != PM_OK)
            return r;
        pm_sky_frame_direction(s->sky_frame, el, az, d);
    }
    if ((r = pm_scene_get_number(c, sun, "solid_angle", "sun.solid_angle", 1, 0.0, 2.0 * M_PI, &omega)) != PM_OK)
        return r;
    if (json_object_get(sun, "radiance")) {
        if ((r = pm_scene_get_vec3(c, sun, "radiance", "sun.radiance", 1, 0.0, 1e30, s->sun.radiance)) != PM_OK)
            return r;
    } else {
        /* E = L pi sin^2(a) at normal incidence, cos a = 1 - omega / (2 pi): sin^2 a = f (2 - f). */
        float e[3];
        if ((r = pm_scene_get_vec3(c, sun, "irradiance", "sun.irradiance", 1, 0.0, 1e30, e)) != PM_OK)
            return r;
        double f = omega / (2.0 * M_PI), s2 = f * (2.0 - f);
        for (int k = 0; k < 3; k++)
            s->sun.radiance[k] = (float)(e[k] / (M_PI * s2));
        for (int k = 0; k < 3; k++)
            if (!isfinite(s->sun.radiance[k]))
                return pm_scene_bad(c, "sun.irradiance", "%.9g W/m^2 over %.9g sr is a radiance beyond a float",
                                    (double)e[k], omega);
    }
    double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(dl > 0.0))
        return pm_scene_bad(c, "sun.direction", "is the zero vector");
    for (int k = 0; k < 3; k++)
        s->sun.direction[k] = (float)(d[k] / dl);
    s->sun.solid_angle = (float)omega;
    s->sun.cos_max = (float)(1.0 - omega / (2.0 * M_PI));
    if (!(s->sun.cos_max < 1.0f))
        return pm_scene_bad(c, "sun.solid_angle", "%.9g sr is too small: the cone's cosine rounds to 1", omega);
    s->has_sun = 1;
    return PM_OK;
}

/* The sky's physical model (sky.model "preetham", sky.turbidity) as its map: tabulated in the
 * sky's frame about the scene's sun, times sky.radiance. */
static pm_result_t load_sky_model(const ctx_t *c, json_t *sky, json_t *model)
{
    enum { W = 512, H = 256 }; /* 0.7 degree pixels: the circumsolar glow spans tens of degrees */
    pm_scene_t *s = c->s;
    pm_result_t r;
    if (!json_is_string(model) || strcmp(json_string_value(model), "preetham") != 0)
        return pm_scene_bad(c, "sky.model", "'%s' is not a sky model (the one there is: \"preetham\")",
                            json_is_string(model) ? json_string_value(model) : "(not a string)");
    if (json_object_get(sky, "map"))
        return pm_scene_bad(c, "sky", "needs one of 'map' and 'model', not both");
    if (!s->has_sun)
        return pm_scene_bad(c, "sky.model", "'preetham' is lit by the scene's sun, and the scene has none");
    double t = 3.0, sun[3];
    if ((r = pm_scene_get_number(c, sky, "turbidity", "sky.turbidity", 0, PM_PREETHAM_T_MIN, PM_PREETHAM_T_MAX, &t)) !=
        PM_OK)
        return r;
    for (int k = 0; k < 3; k++) /* the sun in the sky's frame */
        sun[k] = s->sky_frame[3 * k] * s->sun.direction[0] + s->sky_frame[3 * k + 1] * s->sun.direction[1] +
                 s->sky_frame[3 * k + 2] * s->sun.direction[2];
    if (!(sun[1] > 0.0))
        return pm_scene_bad(c, "sky.model", "'preetham' needs the sun above the horizon: its elevation is %.6g degrees",
                            asin(fmax(-1.0, fmin(1.0, sun[1]))) * 180.0 / M_PI);
    float *rgb;
    if ((r = pm_preetham_map(t, sun, W, H, &rgb)) != PM_OK)
        return r;
    for (size_t i = 0; i < 3 * (size_t)W * H; i++)
        rgb[i] *= s->sky[i % 3];
    if (!(s->envmap = calloc(1, sizeof *s->envmap))) {
        free(rgb);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the sky's map");
    }
    if ((r = pm_envmap_init(s->envmap, W, H, rgb)) != PM_OK)
        pm_error_prefix("scene '%s': sky.model", c->file);
    s->sky_turbidity = t;
    return r;
}

/* The sun (load_sun) and the sky (radiance, map or model, up, rotate), both optional. */
pm_result_t pm_scene_load_sun_sky(const ctx_t *c, json_t *sun, json_t *sky)
{
    static const char *const sky_keys[] = {"radiance", "map", "model", "turbidity", "up", "rotate", NULL};
    pm_scene_t *s = c->s;
    pm_result_t r = PM_OK;
    if (sky && !json_is_object(sky))
        return pm_scene_bad(c, "sky", "must be an object");
    if (sky && (r = pm_scene_only_keys(c, sky, "sky", sky_keys)) != PM_OK)
        return r;
    if ((r = load_sky_frame(c, sky)) != PM_OK)
        return r;
    if (sun && (r = load_sun(c, sun)) != PM_OK)
        return r;
    if (sky) {
        json_t *map = json_object_get(sky, "map"), *model = json_object_get(sky, "model");
        s->sky[0] = s->sky[1] = s->sky[2] = 1.0f; /* a map's or a model's scale when radiance is not given */
        r = pm_scene_get_vec3(c, sky, "radiance", "sky.radiance", !map && !model, 0.0, 1e30, s->sky);
        if (r == PM_OK && !model && json_object_get(sky, "turbidity"))
            r = pm_scene_bad(c, "sky.turbidity", "goes with a sky model (\"model\": \"preetham\")");
        if (r == PM_OK && model)
            r = load_sky_model(c, sky, model);
        if (r == PM_OK && map && (!json_is_string(map) || !*json_string_value(map)))
            r = pm_scene_bad(c, "sky.map", "must be a file name (an OpenEXR or Radiance HDR lat-long map)");
        if (r == PM_OK && map)
            r = load_envmap(c, json_string_value(map));
        if (r != PM_OK)
            return r;
        if (s->envmap)
            pm_envmap_set_frame(s->envmap, s->sky_frame);
        s->has_sky = 1;
    }
    return PM_OK;
}

pm_result_t pm_scene_load_defaults(const ctx_t *c, json_t *d)
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
        return pm_scene_bad(c, "render", "must be an object");
    pm_result_t r = pm_scene_only_keys(c, d, "render", keys);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "photons", "render.photons", 0, 0, (int64_t)1 << 40, &o->photons);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "spp", "render.spp", 0, 1, 1 << 20, &o->spp);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "primary", "render.primary", 0, 1, 4096, &o->primary);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "light_samples", "render.light_samples", 0, 0, 65536, &o->light_samples);
    if (r == PM_OK)
        r = pm_scene_get_number(c, d, "radius", "render.radius", 0, 0.0, PM_SCENE_COORD_MAX, &o->radius);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "k", "render.k", 0, 1, 1 << 20, &o->k);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "leaf", "render.leaf", 0, 1, 1 << 30, &o->leaf);
    if (r == PM_OK)
        r = pm_scene_get_int(c, d, "seed", "render.seed", 0, 0, INT64_MAX, &o->seed);
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

double pm_scene_det3(const double m[3][4])
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* A mesh entry's placement (docs/scene-format.md, Transforms): scale, then rotate, then
 * translate, then matrix, composed into one affine map xf_out. *general_out is 0 when only scale
 * and translate are given: those scenes keep the arithmetic they always had (same vertices to
 * the bit). */
pm_result_t pm_scene_load_transform(const ctx_t *c, json_t *mj, const char *where, double xf_out[3][4],
                                    int *general_out)
{
    double scale = 1.0;
    float tr[3] = {0, 0, 0};
    char p1[96], p2[96], p3[96];
    snprintf(p1, sizeof p1, "%s.scale", where);
    snprintf(p2, sizeof p2, "%s.translate", where);
    pm_result_t r;
    if ((r = pm_scene_get_number(c, mj, "scale", p1, 0, 1e-30, PM_SCENE_COORD_MAX, &scale)) != PM_OK ||
        (r = pm_scene_get_vec3(c, mj, "translate", p2, 0, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, tr)) != PM_OK)
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
            return pm_scene_bad(c, p1, "must be an object {\"axis\": [x, y, z], \"degrees\": angle}");
        float axis[3];
        double deg = 0;
        snprintf(p2, sizeof p2, "%s.rotate.axis", where);
        snprintf(p3, sizeof p3, "%s.rotate.degrees", where);
        if ((r = pm_scene_only_keys(c, rot, p1, rkeys)) != PM_OK ||
            (r = pm_scene_get_vec3(c, rot, "axis", p2, 1, -PM_SCENE_COORD_MAX, PM_SCENE_COORD_MAX, axis)) != PM_OK ||
            (r = pm_scene_get_number(c, rot, "degrees", p3, 1, -1e6, 1e6, &deg)) != PM_OK)
            return r;
        double a[3] = {axis[0], axis[1], axis[2]}, len = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        if (!(len > 0) || !isfinite(len))
            return pm_scene_bad(c, p2, "is the zero vector: a rotation needs an axis");
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
            return pm_scene_bad(c, p1, "must be an array of 16 numbers (4 x 4, row-major), not %zu",
                                json_is_array(mat) ? json_array_size(mat) : (size_t)0);
        double m[16];
        for (size_t i = 0; i < 16; i++) {
            json_t *e = json_array_get(mat, i);
            if (!json_is_number(e))
                return pm_scene_bad(c, p1, "element %zu is not a number", i);
            m[i] = json_number_value(e);
            if (!isfinite(m[i]) || fabs(m[i]) > PM_SCENE_COORD_MAX)
                return pm_scene_bad(c, p1, "element %zu = %.9g is not finite or beyond %g", i, m[i],
                                    PM_SCENE_COORD_MAX);
        }
        if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0)
            return pm_scene_bad(c, p1, "last row %.9g %.9g %.9g %.9g is not 0 0 0 1: only affine maps are supported",
                                m[12], m[13], m[14], m[15]);
        double M[3][4] = {{m[0], m[1], m[2], m[3]}, {m[4], m[5], m[6], m[7]}, {m[8], m[9], m[10], m[11]}};
        /* Singular, or so near it that float vertices collapse: |det| against the product of
         * the rows' lengths (the volume of the unit cube's image against the most it could be). */
        double rows = 1.0;
        for (int i = 0; i < 3; i++)
            rows *= sqrt(M[i][0] * M[i][0] + M[i][1] * M[i][1] + M[i][2] * M[i][2]);
        double d = pm_scene_det3(M);
        if (!(fabs(d) > 1e-9 * rows))
            return pm_scene_bad(c, p1, "is singular (determinant %.9g of its 3 x 3 part): it flattens the mesh", d);
        affine_after(xf_out, M);
        *general_out = 1;
    }
    return PM_OK;
}

/* The portals (docs/scene-format.md, Portals): rectangles in the shapes' syntax (size, then the
 * placement), each a parallelogram in the world whose front face looks into the scene. They need
 * a sun or a sky to admit; their power per light is worked out here once (pm_portals_power). */
pm_result_t pm_scene_load_portals(const ctx_t *c, json_t *portals)
{
    static const char *const keys[] = {"size", "scale", "rotate", "translate", "matrix", NULL};
    pm_scene_t *s = c->s;
    if (!portals)
        return PM_OK;
    if (!json_is_array(portals))
        return pm_scene_bad(c, "portals", "must be an array of rectangles (size, rotate, translate, ...)");
    if (json_array_size(portals) == 0 || json_array_size(portals) > PM_SCENE_PORTALS_MAX)
        return pm_scene_bad(c, "portals", "holds %zu rectangles, not 1 to %d", json_array_size(portals),
                            PM_SCENE_PORTALS_MAX);
    if (!s->has_sun && !s->has_sky)
        return pm_scene_bad(c, "portals", "let the sun and the sky in, and the scene has neither");
    size_t n = json_array_size(portals);
    s->portals = calloc(n, sizeof *s->portals);
    if (!s->portals)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu portals", n);
    s->portal_area = 0.0;
    for (size_t i = 0; i < n; i++) {
        json_t *pj = json_array_get(portals, i);
        char where[64], p[96];
        snprintf(where, sizeof where, "portals[%zu]", i);
        if (!json_is_object(pj))
            return pm_scene_bad(c, where, "must be an object (a rectangle: size, rotate, translate, ...)");
        pm_result_t r = pm_scene_only_keys(c, pj, where, keys);
        double xf[3][4], size[2] = {1.0, 1.0};
        int general;
        if (r != PM_OK || (r = pm_scene_load_transform(c, pj, where, xf, &general)) != PM_OK)
            return r;
        json_t *sz = json_object_get(pj, "size");
        snprintf(p, sizeof p, "%s.size", where);
        if (sz && (!json_is_array(sz) || json_array_size(sz) != 2 || !json_is_number(json_array_get(sz, 0)) ||
                   !json_is_number(json_array_get(sz, 1))))
            return pm_scene_bad(c, p, "must be an array of 2 numbers (width along x, height along y)");
        for (size_t k = 0; sz && k < 2; k++) {
            size[k] = json_number_value(json_array_get(sz, k));
            if (!(size[k] >= 1e-9 && size[k] <= PM_SCENE_COORD_MAX))
                return pm_scene_bad(c, p, "element %zu = %.9g is outside [1e-09, %g]", k, size[k], PM_SCENE_COORD_MAX);
        }
        /* The rectangle's corner (-w/2, -h/2, 0) and edges (w, 0, 0), (0, h, 0) placed by xf; its
         * front is +z as a normal transforms (the edges' cross product, turned by det's sign). */
        double o[3], eu[3], ev[3], nn[3];
        for (int k = 0; k < 3; k++) {
            o[k] = xf[k][3] - 0.5 * size[0] * xf[k][0] - 0.5 * size[1] * xf[k][1];
            eu[k] = size[0] * xf[k][0], ev[k] = size[1] * xf[k][1];
        }
        nn[0] = eu[1] * ev[2] - eu[2] * ev[1];
        nn[1] = eu[2] * ev[0] - eu[0] * ev[2];
        nn[2] = eu[0] * ev[1] - eu[1] * ev[0];
        double a = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]), sg = pm_scene_det3(xf) < 0.0 ? -1.0 : 1.0;
        if (!(a >= 1e-12) || !isfinite(a))
            return pm_scene_bad(c, where, "has area %.9g m^2 once placed: a portal must not be degenerate", a);
        pm_portal_t *q = &s->portals[i];
        for (int k = 0; k < 3; k++) {
            q->corner[k] = (float)o[k], q->edge_u[k] = (float)eu[k], q->edge_v[k] = (float)ev[k];
            q->inward[k] = (float)(sg * nn[k] / a);
        }
        q->area = a;
        s->portal_area += a;
        s->nportals = i + 1;
    }
    pm_portals_power(s, s->portal_power);
    return PM_OK;
}
