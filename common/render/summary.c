/* summary.c: a loaded scene summarized as text or JSON, its camera probed with one ray per
 * pixel, and the eye-light preview of what those rays hit (summary.h); the engine of
 * scene-info, which reads a scene file and writes only to stdout (and the preview PNG). */
#include "render/summary.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/image.h"
#include "base/progress.h"
#include "base/timer.h"
#include "formats/describe.h"
#include "math/vec.h"
#include "render/light.h"
#include "render/shade.h"

pm_scene_needs_t pm_scene_needs(const pm_scene_t *s)
{
    /* Light samples are drawn for every light that is not a delta (render/light.h). */
    size_t total, sampled;
    pm_lights_count(s, &total, &sampled);
    /* Material ids where the gather must tell materials apart: more than one with some glossy, or
     * a glossy textured one, whose queries name its lobe apart (render/eyetrace.c). */
    return (pm_scene_needs_t){s->any_glossy, s->any_glossy && (s->nmaterials > 1 || s->any_glossy_textured),
                              sampled > 0};
}

/* ------------------------------------------------------------------ textures and normals */

static const char *const map_keys[5] = {"map_Kd", "map_Ks", "map_d", "norm", "bump"};

/* Texture t's channels as the file has them. */
static const char *texture_channels(const pm_texture_t *t)
{
    return t->grey ? (t->has_alpha ? "grey+alpha" : "grey") : (t->has_alpha ? "rgba" : "rgb");
}

/* 1 when texture t is the magenta stand-in for a missing file (missing_textures "magenta"). */
static int texture_missing(const pm_scene_t *s, const pm_texture_t *t)
{
    for (size_t u = 0; u < s->nunsupported; u++)
        if (s->unsupported[u].missing && strcmp(s->unsupported[u].value, t->path) == 0)
            return 1;
    return 0;
}

/* Calls use(material, key) for every slot of every material that reads texture i. */
static void texture_users(const pm_scene_t *s, size_t i, void (*use)(void *, const char *, const char *), void *user)
{
    for (size_t m = 0; s->maps && m < s->nmaterials; m++) {
        const int32_t slot[5] = {s->maps[m].kd, s->maps[m].ks, s->maps[m].alpha, s->maps[m].normal, s->maps[m].bump};
        for (int k = 0; k < 5; k++)
            if (slot[k] == (int32_t)i)
                use(user, s->materials[m].name, map_keys[k]);
    }
}

/* 1 when texture i is read as a colour (map_Kd, map_Ks), whose 8-bit values are sRGB-decoded;
 * a texture read only as map_d is a mask, its values (or its alpha) linear. */
static int texture_is_colour(const pm_scene_t *s, size_t i)
{
    for (size_t m = 0; s->maps && m < s->nmaterials; m++)
        if (s->maps[m].kd == (int32_t)i || s->maps[m].ks == (int32_t)i)
            return 1;
    return 0;
}

/* How texture t (index i) is decoded: "srgb" for 8-bit colour, else "linear". */
static const char *texture_space(const pm_scene_t *s, const pm_texture_t *t, size_t i)
{
    return t->u8 && texture_is_colour(s, i) ? "srgb" : "linear";
}

/* Vertices with a vertex normal (non-zero) while shading normals are in use, else 0. */
static size_t normal_vertices(const pm_scene_t *s)
{
    size_t n = 0;
    for (size_t v = 0; s->normals && v < s->nverts; v++)
        n += s->normals[3 * v] != 0.0f || s->normals[3 * v + 1] != 0.0f || s->normals[3 * v + 2] != 0.0f;
    return n;
}

typedef struct {
    FILE *out;
    const char *sep;
} text_users_t;

static void text_user(void *user, const char *material, const char *key)
{
    text_users_t *u = user;
    fprintf(u->out, "%s%s of %s", u->sep, key, material);
    u->sep = ", ";
}

/* The lines of the textures and of the shading normals (docs/programs/scene-info.md). */
static void print_textures(FILE *out, const pm_scene_t *s)
{
    fprintf(out, "textures: %zu\n", s->ntextures);
    for (size_t i = 0; i < s->ntextures; i++) {
        const pm_texture_t *t = &s->textures[i];
        fprintf(out, "  %zu '%s' %" PRIu32 "x%" PRIu32 " %s, %s %s%s", i, t->path, t->w, t->h, texture_channels(t),
                t->u8 ? "8-bit" : "float", strcmp(texture_space(s, t, i), "srgb") == 0 ? "sRGB" : "linear",
                texture_missing(s, t) ? " (missing: magenta)" : "");
        text_users_t u = {out, ": "};
        texture_users(s, i, text_user, &u);
        fprintf(out, "\n");
    }
    size_t nv = normal_vertices(s);
    if (s->normals)
        fprintf(out, "shading normals: yes (vertex normals at %zu of %zu vertices)\n", nv, s->nverts);
    else if (s->normals_ignored)
        fprintf(out, "shading normals: no (shading_normals false: the meshes' vertex normals are ignored)\n");
    else
        fprintf(out, "shading normals: no (no mesh has vertex normals)\n");
}

/* ------------------------------------------------------------------ the probe */

/* Eye-light shading of colour component k of a primary ray d that hit triangle tri with
 * geometric normal ng (neither need be unit): the albedo (kd + ks; a mirror's kr, a glass's
 * tf) times 0.2 + 0.8 |cos|, so
 * that surfaces seen edge-on stay visible; an emitter in its emission colour scaled to a
 * maximum of 1; a miss black. */
static float preview_shade(const pm_scene_t *s, uint32_t tri, const float ng[3], const float d[3], int k)
{
    if (tri == PM_RAY_MISS)
        return 0.0f;
    const pm_material_t *m = &s->materials[s->tri_material[tri]];
    if (pm_material_is_emissive(m)) {
        float mx = fmaxf(m->ke[0], fmaxf(m->ke[1], m->ke[2]));
        return m->ke[k] / mx;
    }
    float nn = sqrtf(pm_dot3(ng, ng)), dd = sqrtf(pm_dot3(d, d));
    float c = fabsf(pm_dot3(ng, d)) / (nn * dd);
    float albedo = m->kind == PM_MAT_MIRROR                                   ? m->kr[k]
                   : m->kind == PM_MAT_GLASS || m->kind == PM_MAT_ROUGH_GLASS ? m->tf[k]
                   : m->kind == PM_MAT_CONDUCTOR                              ? m->f0[k]
                                                                              : m->kd[k] + m->ks[k];
    return albedo * (0.2f + 0.8f * c);
}

pm_result_t pm_scene_probe(const pm_scene_t *s, const pm_rt_t *rt, int progress, uint8_t *preview_rgb,
                           pm_probe_t *probe_out)
{
    const pm_camera_t *cam = &s->camera;
    pm_camera_rays_t c;
    pm_camera_setup(cam, cam->width, cam->height, &c);
    uint64_t n = (uint64_t)cam->width * cam->height, hits = 0;
    /* An Embree failure on a worker is kept here with its row; the lowest row's is reported. */
    pm_error_slot_t err;
    pm_error_slot_init(&err);
    pm_progress_t prog;
    pm_progress_begin(&prog, "probe", n, progress);
    double t0 = pm_time_wall();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : hits)
    for (uint32_t y = 0; y < cam->height; y++) {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (uint32_t x = 0; x < cam->width; x++) {
            float d[3], ng[3], t;
            pm_camera_dir(&c, (float)x + 0.5f, (float)y + 0.5f, d);
            uint32_t tri = pm_rt_intersect1(rt, &ctx, cam->eye, d, 0.0f, INFINITY, &t, ng);
            hits += tri != PM_RAY_MISS;
            if (preview_rgb)
                for (int k = 0; k < 3; k++)
                    preview_rgb[3 * ((size_t)y * cam->width + x) + (size_t)k] =
                        pm_srgb8(preview_shade(s, tri, ng, d, k));
        }
        pm_result_t r = pm_rt_thread_error(rt, "probing row %" PRIu32 " of scene '%s'", y, s->path);
        if (r != PM_OK)
            pm_error_slot_record(&err, y, r);
        pm_progress_add(&prog, cam->width);
    }
    double dt = pm_time_wall() - t0;
    pm_progress_end(&prog);
    pm_result_t r = pm_error_slot_raise(&err);
    if (r != PM_OK)
        return r;
    *probe_out = (pm_probe_t){n, hits, dt > 0 ? (double)n / dt : 0.0};
    return PM_OK;
}

/* ------------------------------------------------------------------ text */

static void print_text(FILE *out, const pm_scene_t *s, const pm_rt_t *rt, double load_s, double bvh_s)
{
    double p[3];
    pm_scene_power(s, p);
    char id[200];
    pm_scene_id(s, id, sizeof id);
    pm_scene_needs_t need = pm_scene_needs(s);
    fprintf(out, "scene: %s\n", id);
    fprintf(out, "hash: xxh3:%016llx (the scene file and everything it loads)\n", (unsigned long long)s->hash);
    fprintf(out, "hash parts: geometry xxh3:%016llx, photons xxh3:%016llx, view xxh3:%016llx, eye xxh3:%016llx\n",
            (unsigned long long)s->parts.geometry, (unsigned long long)s->parts.photons,
            (unsigned long long)s->parts.view, (unsigned long long)s->parts.eye);
    fprintf(out, "file: %s\n", s->path);
    fprintf(out, "triangles: %zu (%zu degenerate left out)\n", s->ntris, s->ndropped);
    fprintf(out, "vertices: %zu\n", s->nverts);
    if (s->instances_flat)
        fprintf(out,
                "instancing: %zu placements of repeated meshes built flat (mesh coordinates beyond %g or a scale "
                "outside [%g, %g])\n",
                s->instances_flat, PM_SCENE_INSTANCE_COORD_MAX, PM_SCENE_INSTANCE_SCALE_MIN,
                PM_SCENE_INSTANCE_SCALE_MAX);
    fprintf(out, "materials: %zu%s\n", s->nmaterials,
            s->any_glossy && s->any_specular ? " (some glossy, some specular)"
            : s->any_specular                ? " (some specular)"
            : s->any_glossy                  ? " (some glossy)"
                                             : " (all Lambertian)");
    for (size_t i = 0; i < s->nmaterials; i++) {
        const pm_material_t *m = &s->materials[i];
        char extra[96] = "";
        if (m->kind == PM_MAT_MIRROR)
            snprintf(extra, sizeof extra, " mirror kr %.4g %.4g %.4g", m->kr[0], m->kr[1], m->kr[2]);
        else if (m->kind == PM_MAT_GLASS)
            snprintf(extra, sizeof extra, " glass ior %.4g tf %.4g %.4g %.4g", m->ior, m->tf[0], m->tf[1], m->tf[2]);
        else if (m->kind == PM_MAT_CONDUCTOR)
            snprintf(extra, sizeof extra, " conductor alpha %.4g f0 %.4g %.4g %.4g", m->alpha, m->f0[0], m->f0[1],
                     m->f0[2]);
        else if (m->kind == PM_MAT_ROUGH_GLASS)
            snprintf(extra, sizeof extra, " rough-glass alpha %.4g ior %.4g tf %.4g %.4g %.4g", m->alpha, m->ior,
                     m->tf[0], m->tf[1], m->tf[2]);
        else if (m->kind == PM_MAT_PLASTIC)
            snprintf(extra, sizeof extra, " plastic alpha %.4g ior %.4g", m->alpha, m->ior);
        fprintf(out, "  %zu %s kd %.4g %.4g %.4g ks %.4g %.4g %.4g ns %.4g ke %.4g %.4g %.4g%s\n", i, m->name, m->kd[0],
                m->kd[1], m->kd[2], m->ks[0], m->ks[1], m->ks[2], m->ns, m->ke[0], m->ke[1], m->ke[2], extra);
        /* Only for a material that sets something pmtk ignores, so that other summaries keep their lines. */
        const char *sep = "    unsupported (ignored): ";
        for (size_t u = 0; u < s->nunsupported; u++)
            if (s->unsupported[u].material == i) {
                char text[300];
                pm_scene_unsupported_text(&s->unsupported[u], text, sizeof text);
                fprintf(out, "%s%s", sep, text);
                sep = ", ";
            }
        if (sep[0] == ',')
            fprintf(out, "\n");
    }
    for (size_t i = 0; i < s->nnotes; i++) /* what the loader changed or filled in */
        fprintf(out, "%s: %s\n", s->notes[i].warning ? "changed" : "note", s->notes[i].text);
    /* the caustic branch of pipelines/render runs only where this says yes */
    fprintf(out, "specular: %s\n", s->any_specular ? "yes (mirror or glass: caustic paths)" : "no");
    print_textures(out, s);
    pm_lights_describe_text(s, out);
    uint32_t ft;
    size_t nf = pm_scene_flipped_emitters(s, &ft);
    fprintf(out, "emissive triangles: %zu", s->nemissive);
    if (nf)
        fprintf(out, " (%zu facing away from the whole scene, first triangle %" PRIu32 ")", nf, ft);
    fprintf(out, "\n");
    if (s->two_sided_lights)
        fprintf(out, "two-sided area lights: yes\n");
    {
        /* Kind-free counts for drivers (render/light.h): whether the scene is lit at all, and
         * whether light_samples matters. */
        size_t total, sampled;
        pm_lights_count(s, &total, &sampled);
        fprintf(out, "lights: %zu in all, %zu sampled light_samples times per shading point\n", total, sampled);
    }
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

/* ------------------------------------------------------------------ JSON */

static json_t *floats_json(const float *v, size_t n)
{
    json_t *a = json_array();
    for (size_t i = 0; i < n; i++)
        json_array_append_new(a, json_real(v[i]));
    return a;
}

static json_t *jstr(pm_json_strings_t *js, const char *what, const char *s)
{
    return pm_json_stringn(js, what, s, strlen(s));
}

typedef struct {
    json_t *users;
    pm_json_strings_t *js;
} json_users_t;

static void json_user(void *user, const char *material, const char *key)
{
    json_users_t *u = user;
    json_array_append_new(u->users,
                          json_pack("{s:o, s:s}", "material", jstr(u->js, "a material's name", material), "map", key));
}

pm_result_t pm_summary_json(const pm_scene_t *s, const pm_rt_t *rt, const pm_summary_options_t *o,
                            const pm_probe_t *probe, json_t **j_out)
{
    pm_json_strings_t js = {0};
    double p[3];
    pm_scene_power(s, p);
    char id[200];
    pm_scene_id(s, id, sizeof id);
    pm_scene_needs_t need = pm_scene_needs(s);
    json_t *j = json_object(), *mats = json_array(), *power = json_array(), *cam = json_object(),
           *needs = json_object();
    json_object_set_new(j, "scene", jstr(&js, "the scene's name", id));
    json_object_set_new(j, "name", jstr(&js, "the scene's name", s->name));
    {
        /* Each part of the hash by what reads it (scene.h, pm_scene_t.parts). */
        char hx[5][32];
        const uint64_t v[5] = {s->hash, s->parts.geometry, s->parts.photons, s->parts.view, s->parts.eye};
        const char *names[5] = {"all", "geometry", "photons", "view", "eye"};
        json_t *hashes = json_object();
        for (int i = 0; i < 5; i++) {
            snprintf(hx[i], sizeof hx[i], "xxh3:%016llx", (unsigned long long)v[i]);
            json_object_set_new(hashes, names[i], json_string(hx[i]));
        }
        json_object_set_new(j, "hashes", hashes);
    }
    json_object_set_new(j, "file", jstr(&js, "the scene's path", s->path));
    json_object_set_new(j, "triangles", json_integer((json_int_t)s->ntris));
    json_object_set_new(j, "degenerate_triangles", json_integer((json_int_t)s->ndropped));
    json_object_set_new(j, "vertices", json_integer((json_int_t)s->nverts));
    json_object_set_new(j, "instances_flat", json_integer((json_int_t)s->instances_flat));
    json_object_set_new(j, "glossy", json_boolean(s->any_glossy));
    json_object_set_new(j, "any_specular", json_boolean(s->any_specular));
    for (size_t i = 0; i < s->nmaterials; i++) {
        const pm_material_t *m = &s->materials[i];
        json_t *mj = json_object();
        json_object_set_new(mj, "name", jstr(&js, "a material's name", m->name));
        json_object_set_new(mj, "kd", floats_json(m->kd, 3));
        json_object_set_new(mj, "ks", floats_json(m->ks, 3));
        json_object_set_new(mj, "ns", json_real(m->ns));
        json_object_set_new(mj, "ke", floats_json(m->ke, 3));
        json_object_set_new(mj, "kind",
                            json_string(m->kind == PM_MAT_MIRROR        ? "mirror"
                                        : m->kind == PM_MAT_GLASS       ? "glass"
                                        : m->kind == PM_MAT_CONDUCTOR   ? "conductor"
                                        : m->kind == PM_MAT_ROUGH_GLASS ? "rough-glass"
                                        : m->kind == PM_MAT_PLASTIC     ? "plastic"
                                                                        : "standard"));
        if (m->kind == PM_MAT_MIRROR)
            json_object_set_new(mj, "kr", floats_json(m->kr, 3));
        if (m->kind == PM_MAT_CONDUCTOR || m->kind == PM_MAT_ROUGH_GLASS || m->kind == PM_MAT_PLASTIC)
            json_object_set_new(mj, "alpha", json_real(m->alpha));
        if (m->kind == PM_MAT_CONDUCTOR) {
            json_object_set_new(mj, "f0", floats_json(m->f0, 3));
            if (m->eta[0] > 0.0f) {
                json_object_set_new(mj, "eta", floats_json(m->eta, 3));
                json_object_set_new(mj, "k", floats_json(m->k, 3));
            }
        }
        if (m->kind == PM_MAT_GLASS || m->kind == PM_MAT_ROUGH_GLASS || m->kind == PM_MAT_PLASTIC)
            json_object_set_new(mj, "ior", json_real(m->ior));
        if (m->kind == PM_MAT_GLASS || m->kind == PM_MAT_ROUGH_GLASS)
            json_object_set_new(mj, "tf", floats_json(m->tf, 3));
        json_t *un = json_array();
        for (size_t u = 0; u < s->nunsupported; u++)
            if (s->unsupported[u].material == i)
                json_array_append_new(un, json_pack("{s:o, s:o, s:b}", "key",
                                                    jstr(&js, "a material key", s->unsupported[u].key), "value",
                                                    jstr(&js, "a material value", s->unsupported[u].value), "file",
                                                    s->unsupported[u].is_file));
        json_object_set_new(mj, "unsupported", un);
        json_array_append_new(mats, mj);
    }
    json_object_set_new(j, "materials", mats);
    json_t *texs = json_array();
    for (size_t i = 0; i < s->ntextures; i++) {
        const pm_texture_t *t = &s->textures[i];
        json_users_t u = {json_array(), &js};
        texture_users(s, i, json_user, &u);
        json_t *users = u.users;
        json_array_append_new(texs, json_pack("{s:o, s:I, s:I, s:s, s:s, s:s, s:b, s:o}", "path",
                                              jstr(&js, "a texture's path", t->path), "width", (json_int_t)t->w,
                                              "height", (json_int_t)t->h, "channels", texture_channels(t), "encoding",
                                              t->u8 ? "8-bit" : "float", "colour_space", texture_space(s, t, i),
                                              "missing", texture_missing(s, t), "used_by", users));
    }
    json_object_set_new(j, "textures", texs);
    json_object_set_new(j, "shading_normals",
                        json_pack("{s:b, s:I, s:b}", "in_use", s->normals != NULL, "vertices",
                                  (json_int_t)normal_vertices(s), "ignored", s->normals_ignored));
    json_object_set_new(j, "point_lights", json_integer((json_int_t)s->nlights));
    json_object_set_new(j, "lights", pm_lights_describe_json(s));
    if (s->nportals)
        json_object_set_new(j, "portals", pm_portals_describe_json(s));
    {
        uint32_t ft;
        json_object_set_new(j, "flipped_emitters", json_integer((json_int_t)pm_scene_flipped_emitters(s, &ft)));
    }
    json_object_set_new(j, "emissive_triangles", json_integer((json_int_t)s->nemissive));
    {
        size_t total, sampled;
        pm_lights_count(s, &total, &sampled);
        json_object_set_new(j, "lights_total", json_integer((json_int_t)total));
        json_object_set_new(j, "sampled_lights", json_integer((json_int_t)sampled));
    }
    if (s->two_sided_lights)
        json_object_set_new(j, "two_sided_lights", json_true());
    if (s->nnotes) {
        json_t *notes = json_array();
        for (size_t i = 0; i < s->nnotes; i++)
            json_array_append_new(notes, json_pack("{s:b, s:o}", "changed", s->notes[i].warning, "text",
                                                   jstr(&js, "a loader note", s->notes[i].text)));
        json_object_set_new(j, "notes", notes);
    }
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
    json_object_set_new(j, "load_s", json_real(o->load_s));
    json_object_set_new(j, "bvh_s", json_real(o->bvh_s));
    if (probe)
        json_object_set_new(j, "probe",
                            json_pack("{s:I, s:I, s:f, s:f}", "rays", (json_int_t)probe->rays, "hits",
                                      (json_int_t)probe->hits, "hit_fraction",
                                      probe->rays ? (double)probe->hits / (double)probe->rays : 0.0, "rays_per_s",
                                      probe->rays_per_s));
    return pm_json_strings_finish(&js, j, j_out, "scene '%s'", s->path);
}

/* ------------------------------------------------------------------ the whole summary */

pm_result_t pm_summary_write(FILE *out, const pm_scene_t *s, const pm_rt_t *rt, const pm_summary_options_t *o,
                             pm_probe_t *probe_out)
{
    *probe_out = (pm_probe_t){0};
    /* The text goes out before the probe, so that a slow probe follows what is already known. */
    if (!o->json)
        print_text(out, s, rt, o->load_s, o->bvh_s);
    pm_result_t r = PM_OK;
    int probed = o->probe || o->preview;
    if (probed) {
        const pm_camera_t *c = &s->camera;
        uint8_t *img = o->preview ? calloc((size_t)3 * c->width * c->height, 1) : NULL;
        if (o->preview && !img)
            r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %ux%u preview", c->width, c->height);
        if (r == PM_OK)
            r = pm_scene_probe(s, rt, o->progress, img, probe_out);
        if (r == PM_OK && img)
            r = pm_png_write_rgb8(o->preview, c->width, c->height, img);
        free(img);
        if (r == PM_OK && !o->json)
            fprintf(out, "probe: %" PRIu64 " primary rays, %.1f%% hit geometry, %.2f Mrays/s\n", probe_out->rays,
                    100.0 * (double)probe_out->hits / (double)probe_out->rays, 1e-6 * probe_out->rays_per_s);
    }
    if (r == PM_OK && o->json) {
        json_t *j = NULL;
        r = pm_summary_json(s, rt, o, probed ? probe_out : NULL, &j);
        if (r == PM_OK)
            r = pm_json_write(out, j, "the summary of scene '%s'", s->path);
    }
    return r;
}
