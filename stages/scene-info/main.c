/* scene-info: loads a scene file, builds its Embree BVH and prints what it holds:
 * triangles, materials, lights and their power, bounds, camera, and which optional
 * channels and stages the scene needs, as text or (--json) as one JSON object that
 * pipelines/render reads. With --probe it casts one primary ray per pixel as a check that
 * the camera sees the geometry. The first stage of every pipeline in spirit: if
 * scene-info is happy, the stages can load the scene. */
#include <inttypes.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/image.h"
#include "render/rt.h"
#include "base/stage.h"

typedef struct {
    int probe;
    const char *preview; /* PNG path, NULL for none */
    int json;            /* the summary as one JSON object instead of text */
} scene_info_options_t;

typedef struct {
    uint64_t rays, hits;
    double rays_per_s;
} probe_result_t;

/* What the stages downstream need of a scene. */
typedef struct {
    int directions;   /* direction channels: some material is glossy */
    int material_ids; /* material ids: only where the gather must tell glossy materials apart; an
                       * all-Lambertian scene folds its BRDFs into the query weights (docs/formats.md 3.3) */
    int area_lights;  /* area-light sampling: some triangle emits */
} scene_needs_t;

static scene_needs_t scene_needs(const pm_scene_t *s)
{
    return (scene_needs_t){s->any_glossy, s->any_glossy && s->nmaterials > 1, s->nemissive > 0};
}

/* Primary ray direction through pixel (x, y)'s centre of a pinhole camera. */
static void camera_ray(const pm_camera_t *c, uint32_t x, uint32_t y, float dir_out[3])
{
    float f[3], r[3], u[3], len;
    for (int k = 0; k < 3; k++)
        f[k] = c->look_at[k] - c->eye[k];
    len = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    for (int k = 0; k < 3; k++)
        f[k] /= len;
    r[0] = f[1] * c->up[2] - f[2] * c->up[1];
    r[1] = f[2] * c->up[0] - f[0] * c->up[2];
    r[2] = f[0] * c->up[1] - f[1] * c->up[0];
    len = sqrtf(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    for (int k = 0; k < 3; k++)
        r[k] /= len;
    u[0] = r[1] * f[2] - r[2] * f[1];
    u[1] = r[2] * f[0] - r[0] * f[2];
    u[2] = r[0] * f[1] - r[1] * f[0];
    float t = tanf(0.5f * c->fov_y * (float)M_PI / 180.0f), aspect = (float)c->width / (float)c->height;
    float sx = (2.0f * ((float)x + 0.5f) / (float)c->width - 1.0f) * t * aspect;
    float sy = (1.0f - 2.0f * ((float)y + 0.5f) / (float)c->height) * t;
    for (int k = 0; k < 3; k++)
        dir_out[k] = f[k] + sx * r[k] + sy * u[k];
}

/* An eye-light preview: each pixel shows its surface's albedo times |cos| to the eye
 * (emitters in their normalized emission colour, misses black), so the camera, the
 * geometry and the materials can be checked by eye before anything is rendered. */
static float preview_shade(const pm_scene_t *s, const struct RTCRayHit *rh, const float d[3], int k)
{
    if (rh->hit.geomID == RTC_INVALID_GEOMETRY_ID)
        return 0.0f;
    const pm_material_t *m = &s->materials[s->tri_material[rh->hit.primID]];
    if (pm_material_is_emissive(m)) {
        float mx = fmaxf(m->ke[0], fmaxf(m->ke[1], m->ke[2]));
        return m->ke[k] / mx;
    }
    float n[3] = {rh->hit.Ng_x, rh->hit.Ng_y, rh->hit.Ng_z};
    float nn = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), dd = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    float c = fabsf(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / (nn * dd);
    return (m->kd[k] + m->ks[k]) * (0.2f + 0.8f * c);
}

static pm_result_t probe(const pm_scene_t *s, const pm_rt_t *rt, pm_stage_t *st, uint8_t *preview,
                         probe_result_t *res_out)
{
    const pm_camera_t *c = &s->camera;
    uint64_t n = (uint64_t)c->width * c->height, hits = 0;
    pm_progress_t prog;
    pm_progress_begin(&prog, "probe", n, pm_stage_progress(st));
    double t0 = pm_time_wall();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : hits)
    for (uint32_t y = 0; y < c->height; y++) {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (uint32_t x = 0; x < c->width; x++) {
            struct RTCRayHit rh;
            float d[3];
            camera_ray(c, x, y, d);
            rh.ray.org_x = c->eye[0], rh.ray.org_y = c->eye[1], rh.ray.org_z = c->eye[2];
            rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2];
            rh.ray.tnear = 0.0f, rh.ray.tfar = INFINITY, rh.ray.time = 0.0f;
            rh.ray.mask = 0xffffffffu, rh.ray.id = 0, rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(rt->scene, &ctx, &rh);
            hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            if (preview)
                for (int k = 0; k < 3; k++)
                    preview[3 * ((size_t)y * c->width + x) + (size_t)k] = pm_srgb8(preview_shade(s, &rh, d, k));
        }
        pm_progress_add(&prog, c->width);
    }
    double dt = pm_time_wall() - t0;
    pm_progress_end(&prog);
    *res_out = (probe_result_t){n, hits, dt > 0 ? (double)n / dt : 0.0};
    pm_stage_stat_int(st, "probe_rays", (int64_t)n);
    pm_stage_stat_int(st, "probe_hits", (int64_t)hits);
    pm_stage_stat_double(st, "probe_rays_per_s", dt > 0 ? (double)n / dt : 0.0);
    st->items = n;
    return PM_OK;
}

static void print_text(FILE *out, const pm_scene_t *s, const pm_rt_t *rt, double load_s, double bvh_s)
{
    double p[3];
    pm_scene_power(s, p);
    char id[200];
    pm_scene_id(s, id, sizeof id);
    scene_needs_t need = scene_needs(s);
    fprintf(out, "scene: %s\n", id);
    fprintf(out, "file: %s\n", s->path);
    fprintf(out, "triangles: %zu (%zu degenerate left out)\n", s->ntris, s->ndropped);
    fprintf(out, "vertices: %zu\n", s->nverts);
    fprintf(out, "materials: %zu%s\n", s->nmaterials, s->any_glossy ? " (some glossy)" : " (all Lambertian)");
    for (size_t i = 0; i < s->nmaterials; i++) {
        const pm_material_t *m = &s->materials[i];
        fprintf(out, "  %zu %s kd %.4g %.4g %.4g ks %.4g %.4g %.4g ns %.4g ke %.4g %.4g %.4g\n", i, m->name, m->kd[0],
                m->kd[1], m->kd[2], m->ks[0], m->ks[1], m->ks[2], m->ns, m->ke[0], m->ke[1], m->ke[2]);
    }
    fprintf(out, "point lights: %zu\n", s->nlights);
    fprintf(out, "emissive triangles: %zu\n", s->nemissive);
    fprintf(out, "emitted power: %.6g %.6g %.6g W\n", p[0], p[1], p[2]);
    fprintf(out, "bounds: %.9g %.9g %.9g  %.9g %.9g %.9g m\n", s->bounds[0], s->bounds[1], s->bounds[2], s->bounds[3],
            s->bounds[4], s->bounds[5]);
    fprintf(out, "camera: eye %.6g %.6g %.6g look_at %.6g %.6g %.6g fov_y %.6g deg %ux%u\n", s->camera.eye[0],
            s->camera.eye[1], s->camera.eye[2], s->camera.look_at[0], s->camera.look_at[1], s->camera.look_at[2],
            s->camera.fov_y, s->camera.width, s->camera.height);
    fprintf(out, "needs: direction channels %s, material ids %s, area-light sampling %s\n",
            need.directions ? "yes" : "no", need.material_ids ? "yes" : "no", need.area_lights ? "yes" : "no");
    fprintf(out, "ray epsilon: %.3g m\n", rt->epsilon);
    fprintf(out, "time: load %.3f s, bvh %.3f s\n", load_s, bvh_s);
}

/* Strings go into JSON through one door that remembers the first that failed: JSON carries
 * UTF-8 only, and a name in another encoding (a material from an MTL file, a path) must be an
 * error naming it, not a key silently left out. */
typedef struct {
    const char *failed; /* what the first string that could not be made was, or NULL */
    int nomem;          /* it failed for want of memory, not for its encoding */
} json_strings_t;

static json_t *jstr(json_strings_t *js, const char *what, const char *s)
{
    json_t *v = json_string(s);
    if (!v && !js->failed) {
        json_t *raw = json_string_nocheck(s); /* succeeds unless memory is short */
        js->failed = what;
        js->nomem = raw == NULL;
        json_decref(raw);
    }
    return v;
}

static json_t *floats_json(const float *v, size_t n)
{
    json_t *a = json_array();
    for (size_t i = 0; i < n; i++)
        json_array_append_new(a, json_real(v[i]));
    return a;
}

/* The facts of print_text as one object, numbers at full float precision; units in the key
 * names where they are not counts. */
static pm_result_t summary_json(const pm_scene_t *s, const pm_rt_t *rt, double load_s, double bvh_s,
                                const probe_result_t *pr, json_t **out)
{
    json_strings_t js = {0};
    double p[3];
    pm_scene_power(s, p);
    char id[200];
    pm_scene_id(s, id, sizeof id);
    scene_needs_t need = scene_needs(s);
    json_t *j = json_object(), *mats = json_array(), *power = json_array(), *cam = json_object(),
           *needs = json_object();
    json_object_set_new(j, "scene", jstr(&js, "the scene's name", id));
    json_object_set_new(j, "name", jstr(&js, "the scene's name", s->name));
    json_object_set_new(j, "file", jstr(&js, "the scene's path", s->path));
    json_object_set_new(j, "triangles", json_integer((json_int_t)s->ntris));
    json_object_set_new(j, "degenerate_triangles", json_integer((json_int_t)s->ndropped));
    json_object_set_new(j, "vertices", json_integer((json_int_t)s->nverts));
    json_object_set_new(j, "glossy", json_boolean(s->any_glossy));
    for (size_t i = 0; i < s->nmaterials; i++) {
        const pm_material_t *m = &s->materials[i];
        json_t *mj = json_object();
        json_object_set_new(mj, "name", jstr(&js, "a material's name", m->name));
        json_object_set_new(mj, "kd", floats_json(m->kd, 3));
        json_object_set_new(mj, "ks", floats_json(m->ks, 3));
        json_object_set_new(mj, "ns", json_real(m->ns));
        json_object_set_new(mj, "ke", floats_json(m->ke, 3));
        json_array_append_new(mats, mj);
    }
    json_object_set_new(j, "materials", mats);
    json_object_set_new(j, "point_lights", json_integer((json_int_t)s->nlights));
    json_object_set_new(j, "emissive_triangles", json_integer((json_int_t)s->nemissive));
    for (int k = 0; k < 3; k++)
        json_array_append_new(power, json_real(p[k]));
    json_object_set_new(j, "power_w", power);
    json_object_set_new(j, "bounds_m", floats_json(s->bounds, 6));
    json_object_set_new(cam, "eye", floats_json(s->camera.eye, 3));
    json_object_set_new(cam, "look_at", floats_json(s->camera.look_at, 3));
    json_object_set_new(cam, "up", floats_json(s->camera.up, 3));
    json_object_set_new(cam, "fov_y_deg", json_real(s->camera.fov_y));
    json_object_set_new(cam, "width", json_integer(s->camera.width));
    json_object_set_new(cam, "height", json_integer(s->camera.height));
    json_object_set_new(j, "camera", cam);
    json_object_set_new(needs, "direction_channels", json_boolean(need.directions));
    json_object_set_new(needs, "material_ids", json_boolean(need.material_ids));
    json_object_set_new(needs, "area_light_sampling", json_boolean(need.area_lights));
    json_object_set_new(j, "needs", needs);
    json_object_set_new(j, "ray_epsilon_m", json_real(rt->epsilon));
    json_object_set_new(j, "load_s", json_real(load_s));
    json_object_set_new(j, "bvh_s", json_real(bvh_s));
    if (pr)
        json_object_set_new(j, "probe",
                            json_pack("{s:I, s:I, s:f, s:f}", "rays", (json_int_t)pr->rays, "hits",
                                      (json_int_t)pr->hits, "hit_fraction",
                                      pr->rays ? (double)pr->hits / (double)pr->rays : 0.0, "rays_per_s",
                                      pr->rays_per_s));
    if (js.failed && !js.nomem) {
        json_decref(j);
        return pm_error_set(PM_ERR_INPUT, "cannot describe scene '%s' as JSON: %s is not UTF-8", s->path, js.failed);
    }
    if (!j || js.failed) {
        json_decref(j);
        return pm_error_set(PM_ERR_NOMEM, "out of memory describing scene '%s' as JSON", s->path);
    }
    *out = j;
    return PM_OK;
}

static pm_result_t run(pm_stage_t *st, const scene_info_options_t *o)
{
    if (o->preview && strcmp(o->preview, "-") == 0)
        return pm_error_set(PM_ERR_USAGE, "--preview needs a file: stdout carries the summary");
    pm_scene_t s;
    pm_rt_t rt;
    FILE *out;
    double t0 = pm_time_wall();
    pm_result_t r = pm_scene_load(st->args.args[0], &s);
    if (r != PM_OK)
        return r;
    double t_load = pm_time_wall() - t0;
    t0 = pm_time_wall();
    r = pm_rt_create(&s, 0, st->threads_used, &rt);
    double t_bvh = pm_time_wall() - t0;
    if (r == PM_OK)
        r = pm_stage_open_output(st, &out);
    if (r == PM_OK) {
        if (!o->json)
            print_text(out, &s, &rt, t_load, t_bvh);
        if (s.nlights == 0 && s.nemissive == 0)
            pm_stage_note(st, "warning: scene '%s' has no lights; every image of it is black", s.path);
        double p[3];
        pm_scene_power(&s, p);
        pm_stage_stat_int(st, "triangles", (int64_t)s.ntris);
        pm_stage_stat_int(st, "degenerate_triangles", (int64_t)s.ndropped);
        pm_stage_stat_int(st, "materials", (int64_t)s.nmaterials);
        pm_stage_stat_int(st, "point_lights", (int64_t)s.nlights);
        pm_stage_stat_int(st, "emissive_triangles", (int64_t)s.nemissive);
        pm_stage_stat_double(st, "power_w", p[0] + p[1] + p[2]);
        pm_stage_stat_double(st, "load_s", t_load);
        pm_stage_stat_double(st, "bvh_s", t_bvh);
        st->items = s.ntris;
        probe_result_t pr = {0};
        if (o->probe || o->preview) {
            uint8_t *img = o->preview ? calloc((size_t)3 * s.camera.width * s.camera.height, 1) : NULL;
            if (o->preview && !img)
                r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %ux%u preview", s.camera.width, s.camera.height);
            if (r == PM_OK)
                r = probe(&s, &rt, st, img, &pr);
            if (r == PM_OK && img)
                r = pm_png_write_rgb8(o->preview, s.camera.width, s.camera.height, img);
            free(img);
            if (r == PM_OK && !o->json)
                fprintf(out, "probe: %" PRIu64 " primary rays, %.1f%% hit geometry, %.2f Mrays/s\n", pr.rays,
                        100.0 * (double)pr.hits / (double)pr.rays, 1e-6 * pr.rays_per_s);
        }
        if (r == PM_OK && o->json) {
            json_t *j = NULL;
            r = summary_json(&s, &rt, t_load, t_bvh, o->probe || o->preview ? &pr : NULL, &j);
            if (r == PM_OK && (json_dumpf(j, out, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
                               fputc('\n', out) == EOF))
                r = pm_error_set(PM_ERR_IO, "cannot write the summary of scene '%s'", s.path);
            json_decref(j);
        }
    }
    pm_rt_destroy(&rt); /* safe after a failed create: it zeroes rt */
    pm_scene_free(&s);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    scene_info_options_t o = {0};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"probe", 0, PM_OPT_FLAG, &o.probe, NULL, "cast one primary ray per pixel and report the hit rate", 1, 0,
         NULL},
        {"preview", 0, PM_OPT_STRING, &o.preview, "PNG",
         "also write an eye-light preview (albedo times cosine) of the camera's view", 1, 0, NULL},
        {"json", 0, PM_OPT_FLAG, &o.json, NULL, "print the summary as one JSON object instead of text", 1, 0, NULL},
        {0},
    };
    const pm_cli_t cli = {"scene-info", "[options] SCENE",
                          "Load a scene file, build its ray-tracing structure and summarize it.", options, 1, 1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
