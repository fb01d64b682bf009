/* scene_punctual.c: the cameras and the lights a mesh file carries (docs/scene-format.md,
 * "Cameras and lights from the asset"): a glTF camera the scene file chooses by name or index,
 * and glTF's KHR_lights_punctual lights (point, spot, directional) in the units glTF gives them
 * (candela, lux; 683 lm/W), placed by their nodes and the mesh entry's transform. Read through
 * assimp's scene graph, imported again without pre-transforming (which moves cameras twice). */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "formats/formats.h"
#include "render/scene_load.h"

/* lm/W: glTF's photometric units to pmtk's radiometric ones (KHR_lights_punctual says 683). */
#define PM_LUMENS_PER_WATT 683.0
/* sr: the solid angle of a directional light's sun, the real sun's. */
#define PM_SUN_SOLID_ANGLE 6.8e-5

/* The node named `name` below n, or NULL. */
static const struct aiNode *find_node(const struct aiNode *n, const char *name)
{
    if (strcmp(n->mName.data, name) == 0)
        return n;
    for (unsigned i = 0; i < n->mNumChildren; i++) {
        const struct aiNode *f = find_node(n->mChildren[i], name);
        if (f)
            return f;
    }
    return NULL;
}

/* The node's transform to the mesh file's space, times the entry's map xf (rows of [3x3 | t]):
 * out = xf * parent^k * ... * node. */
static void node_to_scene(const struct aiNode *n, const double xf[3][4], double out[3][4])
{
    double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    for (; n; n = n->mParent) {
        const struct aiMatrix4x4 *t = &n->mTransformation;
        double a[4][4] = {{t->a1, t->a2, t->a3, t->a4},
                          {t->b1, t->b2, t->b3, t->b4},
                          {t->c1, t->c2, t->c3, t->c4},
                          {t->d1, t->d2, t->d3, t->d4}},
               r[4][4];
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++)
                r[i][j] = a[i][0] * m[0][j] + a[i][1] * m[1][j] + a[i][2] * m[2][j] + a[i][3] * m[3][j];
        memcpy(m, r, sizeof m);
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            out[i][j] = xf[i][0] * m[0][j] + xf[i][1] * m[1][j] + xf[i][2] * m[2][j] + (j == 3 ? xf[i][3] : 0.0);
}

static void apply_point(const double m[3][4], const double p[3], float out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = (float)(m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]);
}

/* m's 3 x 3 part times d, normalized; 0 when it vanishes. */
static int apply_dir(const double m[3][4], const double d[3], double out[3])
{
    double l = 0.0;
    for (int i = 0; i < 3; i++) {
        out[i] = m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2];
        l += out[i] * out[i];
    }
    l = sqrt(l);
    if (!(l > 0.0) || !isfinite(l))
        return 0;
    for (int i = 0; i < 3; i++)
        out[i] /= l;
    return 1;
}

static pm_result_t read_cameras(ctx_t *c, const struct aiScene *as, const char *mesh, int gltf, const double xf[3][4])
{
    if ((c->acams = calloc(as->mNumCameras ? as->mNumCameras : 1, sizeof *c->acams)) == NULL)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %u cameras", as->mNumCameras);
    for (unsigned i = 0; i < as->mNumCameras; i++) {
        const struct aiCamera *k = as->mCameras[i];
        pm_asset_camera_t *o = &c->acams[c->nacams++];
        snprintf(o->name, sizeof o->name, "%s", k->mName.data);
        const struct aiNode *n = find_node(as->mRootNode, k->mName.data);
        double m[3][4], d[3], u[3];
        node_to_scene(n, xf, m);
        /* assimp 5.2's glTF importer puts the node's translation into mPosition as well as in the
         * node (counted twice through the graph); a glTF camera sits at its node's origin looking
         * down -z with +y up, so that is read instead. Other formats: relative to the node. */
        double p0[3] = {gltf ? 0 : k->mPosition.x, gltf ? 0 : k->mPosition.y, gltf ? 0 : k->mPosition.z},
               l0[3] = {gltf ? 0 : k->mLookAt.x, gltf ? 0 : k->mLookAt.y, gltf ? -1 : k->mLookAt.z},
               u0[3] = {gltf ? 0 : k->mUp.x, gltf ? 1 : k->mUp.y, gltf ? 0 : k->mUp.z};
        apply_point(m, p0, o->eye);
        if (!apply_dir(m, l0, d) || !apply_dir(m, u0, u))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': camera '%s': its node's transform is singular", mesh,
                                o->name);
        for (int k3 = 0; k3 < 3; k3++) {
            o->look_at[k3] = o->eye[k3] + (float)d[k3];
            o->up[k3] = (float)u[k3];
        }
        /* assimp gives the full horizontal angle; its glTF importer as glTF's yfov times the
         * aspect ratio (not through the tangents), which is undone exactly here */
        o->hfov = k->mHorizontalFOV;
        o->aspect = k->mAspect;
        o->gltf = gltf;
        o->ortho = k->mHorizontalFOV == 0.0f || k->mOrthographicWidth > 0.0f;
    }
    (void)mesh;
    return PM_OK;
}

static pm_result_t read_lights(ctx_t *c, const struct aiScene *as, const char *mesh, const char *where,
                               const double xf[3][4])
{
    pm_scene_t *s = c->s;
    pm_result_t r = pm_scene_grow((void **)&c->alights, c->nalights + as->mNumLights, sizeof *c->alights);
    for (unsigned i = 0; i < as->mNumLights && r == PM_OK; i++) {
        const struct aiLight *l = as->mLights[i];
        const struct aiNode *n = find_node(as->mRootNode, l->mName.data);
        double m[3][4], d[3];
        node_to_scene(n, xf, m);
        double p0[3] = {l->mPosition.x, l->mPosition.y, l->mPosition.z},
               d0[3] = {l->mDirection.x, l->mDirection.y, l->mDirection.z};
        float col[3] = {l->mColorDiffuse.r, l->mColorDiffuse.g, l->mColorDiffuse.b}; /* color x intensity */
        for (int k = 0; k < 3; k++)
            if (!(col[k] >= 0.0f && col[k] <= 1e30f))
                return pm_error_set(PM_ERR_INPUT,
                                    "mesh '%s': light '%s': intensity %g in channel %c must lie in [0, 1e30]", mesh,
                                    l->mName.data, (double)col[k], "rgb"[k]);
        if (l->mType == aiLightSource_POINT || l->mType == aiLightSource_SPOT) {
            pm_point_light_t *pl = &c->alights[c->nalights++];
            memset(pl, 0, sizeof *pl);
            apply_point(m, p0, pl->position);
            for (int k = 0; k < 3; k++) /* candela (lm/sr) to W/sr */
                pl->intensity[k] = (float)(col[k] / PM_LUMENS_PER_WATT);
            pl->cos_cone = -1.0f;
            if (l->mType == aiLightSource_SPOT) {
                float outer = l->mAngleOuterCone, inner = l->mAngleInnerCone;
                if (!(outer > 0.0f && outer <= (float)M_PI) || !apply_dir(m, d0, d))
                    return pm_error_set(PM_ERR_INPUT,
                                        "mesh '%s': spot light '%s': outer cone angle %g rad must lie in (0, pi] and "
                                        "its axis be non-zero",
                                        mesh, l->mName.data, (double)outer);
                for (int k = 0; k < 3; k++)
                    pl->axis[k] = (float)d[k];
                pl->cos_cone = cosf(outer);
                /* glTF's edge: (t clamped to [0, 1])^2, t = (cos - cos outer) / (cos inner - cos outer).
                 * Exact as pmtk's falloff 2 when the inner angle is 0, falloff 0 when it equals the
                 * outer one; between them falloff 2, a softer edge, and a note. */
                if (inner >= outer * 0.9999f)
                    pl->falloff = 0.0f;
                else {
                    pl->falloff = 2.0f;
                    if (inner > 0.0f && (r = pm_scene_add_note(
                                             s, 1,
                                             "%s '%s': spot light '%s': inner cone %.4g rad approximated by a falloff "
                                             "of 2 from the axis to the outer cone %.4g rad",
                                             where, mesh, l->mName.data, (double)inner, (double)outer)) != PM_OK)
                        return r;
                }
            }
        } else if (l->mType == aiLightSource_DIRECTIONAL) {
            if (c->has_asun)
                return pm_error_set(PM_ERR_INPUT,
                                    "mesh '%s': light '%s': a second directional light (pmtk has one sun)", mesh,
                                    l->mName.data);
            if (!apply_dir(m, d0, d))
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': light '%s': its direction is the zero vector", mesh,
                                    l->mName.data);
            c->has_asun = 1;
            double omega = PM_SUN_SOLID_ANGLE, cos_a = 1.0 - omega / (2.0 * M_PI), sin2 = 1.0 - cos_a * cos_a;
            for (int k = 0; k < 3; k++) {
                c->asun.direction[k] = (float)-d[k]; /* toward the light */
                /* lux (lm/m^2) to W/m^2, then the radiance whose disc gives that irradiance: E = L pi sin^2 a */
                c->asun.radiance[k] = (float)(col[k] / PM_LUMENS_PER_WATT / (M_PI * sin2));
            }
            c->asun.solid_angle = (float)omega;
            c->asun.cos_max = (float)cos_a;
            r = pm_scene_add_note(s, 0,
                                  "%s '%s': directional light '%s' is the sun, %.6g W/m^2 in green, as a disc of "
                                  "%.2g sr (the real sun's)",
                                  where, mesh, l->mName.data, col[1] / PM_LUMENS_PER_WATT, omega);
        } else {
            r = pm_scene_add_note(s, 1, "%s '%s': light '%s' of assimp type %d is not supported (ignored)", where, mesh,
                                  l->mName.data, (int)l->mType);
        }
    }
    return r;
}

pm_result_t pm_scene_load_asset_extras(ctx_t *c, json_t *mj, const char *where, const char *path, const char *mesh,
                                       size_t index, const double xf[3][4], unsigned nlights_seen)
{
    json_t *lj = json_object_get(mj, "lights");
    char p[96];
    snprintf(p, sizeof p, "%s.lights", where);
    if (lj && !json_is_boolean(lj))
        return pm_scene_bad(c, p, "must be true (read the file's glTF lights) or false (the default)");
    int want_lights = lj && json_is_true(lj), want_camera = c->camera_mesh == (int64_t)index;
    size_t n = strlen(path);
    int gltf = (n > 5 && strcasecmp(path + n - 5, ".gltf") == 0) || (n > 4 && strcasecmp(path + n - 4, ".glb") == 0);
    pm_result_t r = PM_OK;
    if (!want_lights && nlights_seen &&
        (r = pm_scene_add_note(c->s, 0, "%s '%s' holds %u light%s, not read (%s)", where, mesh, nlights_seen,
                               nlights_seen == 1 ? "" : "s",
                               gltf ? "\"lights\": true reads them"
                                    : "pmtk reads glTF's lights only: they say their units")) != PM_OK)
        return r;
    if (!want_lights && !want_camera)
        return PM_OK;
    if (want_lights && !gltf)
        return pm_scene_bad(c, p, "mesh '%s' is not glTF: only glTF's lights (KHR_lights_punctual) say their units",
                            mesh);
    const struct aiScene *as = aiImportFile(path, aiProcess_ValidateDataStructure);
    if (!as)
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", mesh, aiGetErrorString());
    if (want_camera)
        r = read_cameras(c, as, mesh, gltf, xf);
    if (r == PM_OK && want_lights)
        r = read_lights(c, as, mesh, where, xf);
    aiReleaseImport(as);
    return r;
}

pm_result_t pm_scene_asset_camera(const ctx_t *c, json_t *cam)
{
    static const char *const keys[] = {"mesh", "name", "index", "width", "height", NULL};
    pm_camera_t *k = &c->s->camera;
    pm_result_t r = pm_scene_only_keys(c, cam, "camera (from a mesh: eye, look_at, up and fov_y come from it)", keys);
    int64_t w = 0, h = 0, idx = -1;
    json_t *name = json_object_get(cam, "name");
    if (r == PM_OK)
        r = pm_scene_get_int(c, cam, "width", "camera.width", 1, 1, 65536, &w);
    if (r == PM_OK)
        r = pm_scene_get_int(c, cam, "height", "camera.height", 1, 1, 65536, &h);
    if (r == PM_OK)
        r = pm_scene_get_int(c, cam, "index", "camera.index", 0, 0, 1 << 20, &idx);
    if (r == PM_OK && name && !json_is_string(name))
        r = pm_scene_bad(c, "camera.name", "must be a string (the camera's node name in the mesh file)");
    if (r == PM_OK && name && idx >= 0)
        r = pm_scene_bad(c, "camera", "'name' and 'index' both given: choose the camera by one");
    if (r == PM_OK && (r = pm_image_size_check((uint64_t)w, (uint64_t)h)) != PM_OK)
        pm_error_prefix("scene '%s': camera", c->file);
    if (r != PM_OK)
        return r;
    char list[256] = "";
    for (size_t i = 0; i < c->nacams; i++) {
        strncat(list, i ? ", " : "", sizeof list - strlen(list) - 1);
        strncat(list, c->acams[i].name, sizeof list - strlen(list) - 1);
    }
    const pm_asset_camera_t *a = NULL;
    if (name) {
        for (size_t i = 0; i < c->nacams && !a; i++)
            if (strcmp(c->acams[i].name, json_string_value(name)) == 0)
                a = &c->acams[i];
        if (!a)
            return pm_scene_bad(c, "camera.name", "meshes[%lld] has no camera '%s' (it has: %s)",
                                (long long)c->camera_mesh, json_string_value(name), c->nacams ? list : "none");
    } else {
        if (idx < 0)
            idx = 0;
        if ((size_t)idx >= c->nacams)
            return pm_scene_bad(c, "camera.index", "%lld, but meshes[%lld] has %zu camera%s%s%s%s", (long long)idx,
                                (long long)c->camera_mesh, c->nacams, c->nacams == 1 ? "" : "s", c->nacams ? " (" : "",
                                list, c->nacams ? ")" : "");
        a = &c->acams[idx];
    }
    if (a->ortho)
        return pm_scene_bad(c, "camera", "camera '%s' of meshes[%lld] is orthographic: pmtk's camera is a pinhole",
                            a->name, (long long)c->camera_mesh);
    double aspect = a->aspect > 0.0f ? a->aspect : (double)w / (double)h;
    double fov = a->gltf ? a->hfov / aspect : 2.0 * atan(tan(0.5 * a->hfov) / aspect);
    fov *= 180.0 / M_PI;
    if (!(fov >= 1e-3 && fov <= 179.0))
        return pm_scene_bad(c, "camera", "camera '%s': vertical field of view %.6g degrees is outside [0.001, 179]",
                            a->name, fov);
    memcpy(k->eye, a->eye, sizeof k->eye);
    memcpy(k->look_at, a->look_at, sizeof k->look_at);
    memcpy(k->up, a->up, sizeof k->up);
    k->fov_y = (float)fov;
    k->width = (uint32_t)w;
    k->height = (uint32_t)h;
    return PM_OK;
}

pm_result_t pm_scene_add_asset_lights(ctx_t *c)
{
    pm_scene_t *s = c->s;
    if (c->nalights) {
        if (s->nlights + c->nalights > PM_SCENE_MAX_LIGHTS)
            return pm_scene_bad(c, "meshes", "%zu point lights with the assets', more than %u",
                                s->nlights + c->nalights, PM_SCENE_MAX_LIGHTS);
        pm_result_t r = pm_scene_grow((void **)&s->lights, s->nlights + c->nalights, sizeof *s->lights);
        if (r != PM_OK)
            return r;
        memcpy(s->lights + s->nlights, c->alights, c->nalights * sizeof *s->lights);
        s->nlights += c->nalights;
    }
    if (c->has_asun) {
        if (s->has_sun)
            return pm_scene_bad(c, "sun", "given, and a mesh's directional light is a sun too (pmtk has one sun)");
        s->sun = c->asun;
        s->has_sun = 1;
    }
    return PM_OK;
}
