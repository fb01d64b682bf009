/* scene_assets.c: what the scene file says about its assets (docs/scene-format.md, "Materials
 * in the scene file" and "Shapes"): its `materials` section (a name for each material of the BSDF
 * module's kinds, with a base-colour texture), a mesh entry's `material`, `materials` and
 * `emission` that override what the asset's own files say, the `shapes` (rectangle, disk, sphere,
 * box) tessellated into the scene's triangles, and the loader's notes of what it changed. */
#include "render/scene.h"

#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/scene_load.h"

pm_result_t pm_scene_add_note(pm_scene_t *s, int warning, const char *fmt, ...)
{
    char text[sizeof s->notes[0].text];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    for (size_t i = 0; i < s->nnotes; i++) /* a mesh placed twice is said once */
        if (strcmp(s->notes[i].text, text) == 0)
            return PM_OK;
    pm_result_t r = pm_scene_grow((void **)&s->notes, s->nnotes + 1, sizeof *s->notes);
    if (r != PM_OK)
        return r;
    pm_scene_note_t *n = &s->notes[s->nnotes++];
    n->warning = warning;
    memcpy(n->text, text, sizeof text);
    return PM_OK;
}

/* ------------------------------------------------------------------ the materials section */

/* A material kind as the scene file names it, the keys it takes besides "kind", and the
 * pm_material_t kind it makes. */
typedef struct {
    const char *name;
    int kind;
    const char *const keys[8];
} kind_t;

static const kind_t kinds[] = {
    {"diffuse", PM_MAT_STANDARD, {"kind", "kd", "texture", NULL}},
    {"phong", PM_MAT_STANDARD, {"kind", "kd", "ks", "ns", "texture", NULL}},
    {"mirror", PM_MAT_MIRROR, {"kind", "reflectance", NULL}},
    {"glass", PM_MAT_GLASS, {"kind", "ior", "filter", NULL}},
    {"conductor", PM_MAT_CONDUCTOR, {"kind", "alpha", "f0", "eta", "k", "texture", NULL}},
    {"rough_glass", PM_MAT_ROUGH_GLASS, {"kind", "alpha", "ior", "filter", NULL}},
    {"plastic", PM_MAT_PLASTIC, {"kind", "kd", "alpha", "ior", "texture", NULL}},
};
#define NKINDS (sizeof kinds / sizeof kinds[0])

/* Scene material `name` (the JSON object v) into *m and *mm (its texture, if any). */
static pm_result_t load_one(ctx_t *c, const char *name, json_t *v, pm_material_t *m, pm_material_maps_t *mm)
{
    char where[160], p[200];
    snprintf(where, sizeof where, "materials.%s", name);
    if (!json_is_object(v))
        return pm_scene_bad(c, where, "must be an object with a \"kind\"");
    const char *kn = json_string_value(json_object_get(v, "kind"));
    const kind_t *k = NULL;
    for (size_t i = 0; kn && i < NKINDS && !k; i++)
        if (strcmp(kinds[i].name, kn) == 0)
            k = &kinds[i];
    snprintf(p, sizeof p, "%s.kind", where);
    if (!k)
        return pm_scene_bad(c, p,
                            "'%s' is not a kind (known: diffuse, phong, mirror, glass, conductor, rough_glass, "
                            "plastic)",
                            kn ? kn : "(missing or not a string)");
    pm_result_t r = pm_scene_only_keys(c, v, where, k->keys);
    if (r != PM_OK)
        return r;
    memset(m, 0, sizeof *m);
    *mm = (pm_material_maps_t){-1, -1, -1, -1, -1, 1.0f, 0, {0}};
    snprintf(m->name, sizeof m->name, "%s", name);
    m->kind = k->kind;
    m->ior = 1.5f;
    m->kd[0] = m->kd[1] = m->kd[2] = 0.8f;
    m->tf[0] = m->tf[1] = m->tf[2] = 1.0f;
    m->kr[0] = m->kr[1] = m->kr[2] = 1.0f;
    m->f0[0] = m->f0[1] = m->f0[2] = 1.0f;
    double ns = 0.0, alpha = 0.0, ior = 1.5;
    int is_std = k->kind == PM_MAT_STANDARD, is_phong = strcmp(k->name, "phong") == 0;
#define GETV(key, lo, hi, dst)                                                                                         \
    do {                                                                                                               \
        snprintf(p, sizeof p, "%s." key, where);                                                                       \
        if (r == PM_OK)                                                                                                \
            r = pm_scene_get_vec3(c, v, key, p, 0, lo, hi, dst);                                                       \
    } while (0)
#define GETN(key, lo, hi, dst)                                                                                         \
    do {                                                                                                               \
        snprintf(p, sizeof p, "%s." key, where);                                                                       \
        if (r == PM_OK)                                                                                                \
            r = pm_scene_get_number(c, v, key, p, 0, lo, hi, dst);                                                     \
    } while (0)
    GETV("kd", 0.0, 1.0, m->kd);
    if (is_phong) {
        m->kd[0] = m->kd[1] = m->kd[2] = 0.5f;
        m->ks[0] = m->ks[1] = m->ks[2] = 0.3f;
        ns = 50.0;
        GETV("kd", 0.0, 1.0, m->kd);
        GETV("ks", 0.0, 1.0, m->ks);
        GETN("ns", 0.0, 1e6, &ns);
    }
    GETV("reflectance", 0.0, 1.0, m->kr);
    GETV("filter", 0.0, 1.0, m->tf);
    GETV("f0", 0.0, 1.0, m->f0);
    GETV("eta", 1e-3, 1e6, m->eta);
    GETV("k", 0.0, 1e6, m->k);
    GETN("alpha", 0.0, 1.0, &alpha);
    /* a dielectric's index; a plastic's coat index 1 would reflect nothing: the diffuse kind */
    if (k->kind == PM_MAT_PLASTIC)
        GETN("ior", 1.0, 10.0, &ior);
    else
        GETN("ior", 1e-3, 1e6, &ior);
    if (r != PM_OK)
        return r;
    if (json_object_get(v, "eta") && !json_object_get(v, "k"))
        return pm_scene_bad(c, where, "'eta' without 'k': a conductor's complex index needs both (or give 'f0')");
    if (json_object_get(v, "k") && !json_object_get(v, "eta"))
        return pm_scene_bad(c, where, "'k' without 'eta': a conductor's complex index needs both (or give 'f0')");
    if (json_object_get(v, "eta") && json_object_get(v, "f0"))
        return pm_scene_bad(c, where, "'f0' and 'eta'/'k' both given: a conductor's Fresnel is one or the other");
    for (int i = 0; is_phong && i < 3; i++)
        if (m->kd[i] + m->ks[i] > 1.0f + 1e-6f)
            return pm_scene_bad(c, where, "kd + ks = %g in channel %c exceeds 1 (not energy conserving)",
                                (double)(m->kd[i] + m->ks[i]), "rgb"[i]);
    m->ns = is_phong ? (float)ns : 0.0f;
    m->alpha = (float)alpha;
    m->ior = (float)ior;
    if (!is_std && k->kind != PM_MAT_PLASTIC)
        m->kd[0] = m->kd[1] = m->kd[2] = 0.0f;
    if (k->kind != PM_MAT_MIRROR)
        m->kr[0] = m->kr[1] = m->kr[2] = 0.0f;
    if (k->kind != PM_MAT_GLASS && k->kind != PM_MAT_ROUGH_GLASS)
        m->tf[0] = m->tf[1] = m->tf[2] = 0.0f;
    if (k->kind != PM_MAT_CONDUCTOR || m->eta[0] > 0.0f)
        m->f0[0] = m->f0[1] = m->f0[2] = 0.0f;
    if (k->kind == PM_MAT_CONDUCTOR && m->eta[0] > 0.0f)
        for (int i = 0; i < 3; i++)
            if (!(m->eta[i] > 0.0f))
                return pm_scene_bad(c, where, "eta %g in channel %c must be > 0", (double)m->eta[i], "rgb"[i]);
    json_t *tex = json_object_get(v, "texture");
    if (tex) {
        snprintf(p, sizeof p, "%s.texture", where);
        if (!json_is_string(tex) || !*json_string_value(tex))
            return pm_scene_bad(c, p, "must be a file name (PNG, JPEG, ...; relative to the scene file)");
        if (k->kind == PM_MAT_CONDUCTOR && m->eta[0] > 0.0f)
            return pm_scene_bad(c, p, "a texture scales a conductor's f0: give 'f0', not 'eta' and 'k'");
        /* a missing file is an error here whatever missing_textures says: the magenta stand-in's
         * note belongs to a material slot, and a scene material has none yet */
        ctx_t strict = *c;
        strict.missing_magenta = 0;
        r = pm_scene_texture(&strict, c->file, json_string_value(tex), c->file, m, 0, p, &mm->kd);
    }
    return r;
#undef GETV
#undef GETN
}

pm_result_t pm_scene_load_scene_materials(ctx_t *c, json_t *mats)
{
    if (!mats)
        return PM_OK;
    if (!json_is_object(mats))
        return pm_scene_bad(c, "materials", "must be an object: name -> {\"kind\": ..., parameters}");
    size_t n = json_object_size(mats), i = 0;
    c->smats = calloc(n ? n : 1, sizeof *c->smats);
    c->smaps = calloc(n ? n : 1, sizeof *c->smaps);
    if (!c->smats || !c->smaps)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu scene materials", n);
    const char *name;
    json_t *v;
    json_object_foreach(mats, name, v)
    {
        if (!*name || strlen(name) >= sizeof c->smats[0].name || strpbrk(name, " \t\n"))
            return pm_scene_bad(c, "materials", "name '%s' must be non-empty, without spaces, under %zu bytes", name,
                                sizeof c->smats[0].name);
        pm_result_t r = load_one(c, name, v, &c->smats[i], &c->smaps[i]);
        if (r != PM_OK)
            return r;
        c->nsmats = ++i;
    }
    return PM_OK;
}

/* The scene material named by JSON string v at path, or an error naming the known ones. */
static pm_result_t find_material(const ctx_t *c, json_t *v, const char *path, size_t *index_out)
{
    const char *name = json_string_value(v);
    for (size_t i = 0; name && i < c->nsmats; i++)
        if (strcmp(c->smats[i].name, name) == 0) {
            *index_out = i;
            return PM_OK;
        }
    char list[256] = "";
    for (size_t i = 0; i < c->nsmats; i++) {
        strncat(list, i ? ", " : "", sizeof list - strlen(list) - 1);
        strncat(list, c->smats[i].name, sizeof list - strlen(list) - 1);
    }
    return pm_scene_bad(c, path, "'%s' is not in the scene's materials (%s)", name ? name : "(not a string)",
                        c->nsmats ? list : "the scene file has no \"materials\" section");
}

int pm_scene_overridden(json_t *mj, const char *word)
{
    json_t *map = json_object_get(mj, "materials");
    if (json_object_get(mj, "material"))
        return 1;
    const char *an;
    json_t *v;
    json_object_foreach(map, an, v)
    {
        char key[64];
        snprintf(key, sizeof key, "%s", an);
        pm_scene_material_word(key);
        if (strcmp(key, word) == 0)
            return 1;
    }
    return 0;
}

/* Scene material si in place of scene material slot mi: its parameters and texture; what the
 * asset's material set and pmtk did not honour no longer applies and is dropped. */
static void use_material(ctx_t *c, size_t si, uint32_t mi)
{
    pm_scene_t *s = c->s;
    s->materials[mi] = c->smats[si];
    s->maps[mi] = c->smaps[si];
    size_t nu = 0;
    for (size_t i = 0; i < s->nunsupported; i++)
        if (s->unsupported[i].material != mi)
            s->unsupported[nu++] = s->unsupported[i];
    s->nunsupported = nu;
}

/* emission {radiance, two_sided} at path into ke and *two_sided_out. */
static pm_result_t load_emission(const ctx_t *c, json_t *e, const char *path, float ke[3], int *two_sided_out)
{
    static const char *const keys[] = {"radiance", "two_sided", NULL};
    char p[200];
    if (!json_is_object(e))
        return pm_scene_bad(c, path, "must be an object {\"radiance\": [r, g, b], \"two_sided\": false}");
    pm_result_t r = pm_scene_only_keys(c, e, path, keys);
    snprintf(p, sizeof p, "%s.radiance", path);
    if (r == PM_OK)
        r = pm_scene_get_vec3(c, e, "radiance", p, 1, 0.0, 1e30, ke);
    json_t *two = json_object_get(e, "two_sided");
    snprintf(p, sizeof p, "%s.two_sided", path);
    if (r == PM_OK && two && !json_is_boolean(two))
        r = pm_scene_bad(c, p, "must be true or false (the default: the front face emits)");
    *two_sided_out = two && json_is_true(two);
    return r;
}

pm_result_t pm_scene_apply_mesh_overrides(ctx_t *c, json_t *mj, const char *where, const char *mesh, size_t mat0,
                                          size_t n)
{
    pm_scene_t *s = c->s;
    json_t *one = json_object_get(mj, "material"), *map = json_object_get(mj, "materials"),
           *em = json_object_get(mj, "emission");
    char p[200];
    pm_result_t r = PM_OK;
    if (one && map)
        return pm_scene_bad(c, where,
                            "'material' and 'materials' both given: one material for every face, or a "
                            "map from the asset's material names");
    if (one) {
        size_t si;
        snprintf(p, sizeof p, "%s.material", where);
        if ((r = find_material(c, one, p, &si)) != PM_OK)
            return r;
        r = pm_scene_add_note(s, 0, "%s '%s': every face takes scene material '%s' (the asset's materials replaced)",
                              where, mesh, c->smats[si].name);
        for (size_t i = mat0; i < mat0 + n; i++)
            use_material(c, si, (uint32_t)i);
    }
    if (map) {
        snprintf(p, sizeof p, "%s.materials", where);
        if (!json_is_object(map))
            return pm_scene_bad(c, p, "must be an object: the asset's material name -> a scene material");
        const char *an;
        json_t *v;
        json_object_foreach(map, an, v)
        {
            char pk[300], word[64];
            snprintf(pk, sizeof pk, "%s.materials.%s", where, an);
            snprintf(word, sizeof word, "%s", an);
            pm_scene_material_word(word); /* as the loader keeps asset names */
            size_t si, hits = 0;
            if ((r = find_material(c, v, pk, &si)) != PM_OK)
                return r;
            for (size_t i = mat0; i < mat0 + n && r == PM_OK; i++)
                if (strcmp(s->materials[i].name, word) == 0) {
                    hits++;
                    r = pm_scene_add_note(s, 0, "%s '%s': material '%s' replaced by scene material '%s'", where, mesh,
                                          word, c->smats[si].name);
                    use_material(c, si, (uint32_t)i);
                }
            if (r == PM_OK && !hits) {
                char list[256] = "";
                for (size_t i = mat0; i < mat0 + n; i++) {
                    strncat(list, i > mat0 ? ", " : "", sizeof list - strlen(list) - 1);
                    strncat(list, s->materials[i].name, sizeof list - strlen(list) - 1);
                }
                return pm_scene_bad(c, pk, "mesh '%s' has no material '%s' (it has: %s)", mesh, an, list);
            }
            if (r != PM_OK)
                return r;
        }
    }
    if (em) {
        float ke[3];
        int two;
        snprintf(p, sizeof p, "%s.emission", where);
        if ((r = load_emission(c, em, p, ke, &two)) != PM_OK)
            return r;
        for (size_t i = mat0; i < mat0 + n; i++) {
            memcpy(s->materials[i].ke, ke, sizeof ke);
            s->materials[i].two_sided = two;
            if (s->maps[i].alpha >= 0) { /* light sampling covers the whole area: no cut-outs */
                s->maps[i].alpha = -1;
                if ((r = pm_scene_note_unsupported(s, (uint32_t)i, "map_d on an emitter", 0, "(emission)")) != PM_OK)
                    return r;
            }
        }
    }
    return r;
}

/* ------------------------------------------------------------------ shapes */

/* A shape's triangles in its own units before its transform: positions, texture coordinates. */
typedef struct {
    double *p; /* 3 per vertex */
    float *uv; /* 2 per vertex */
    uint32_t *t;
    size_t nv, nt;
} tess_t;

static pm_result_t tess_alloc(tess_t *m, size_t nv, size_t nt)
{
    m->p = calloc(3 * nv, sizeof *m->p);
    m->uv = calloc(2 * nv, sizeof *m->uv);
    m->t = calloc(3 * nt, sizeof *m->t);
    m->nv = m->nt = 0;
    return m->p && m->uv && m->t ? PM_OK : pm_error_set(PM_ERR_NOMEM, "out of memory for a shape");
}

static void tess_vert(tess_t *m, double x, double y, double z, float u, float v)
{
    m->p[3 * m->nv] = x, m->p[3 * m->nv + 1] = y, m->p[3 * m->nv + 2] = z;
    m->uv[2 * m->nv] = u, m->uv[2 * m->nv + 1] = v;
    m->nv++;
}

/* Triangle (a, b, c), wound so that its right-hand-rule normal points along `out` (the
 * outward direction at its centroid). */
static void tess_tri(tess_t *m, uint32_t a, uint32_t b, uint32_t c, const double out[3])
{
    const double *A = &m->p[3 * a], *B = &m->p[3 * b], *C = &m->p[3 * c];
    double e1[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, e2[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    int flip = n[0] * out[0] + n[1] * out[1] + n[2] * out[2] < 0.0;
    uint32_t *t = &m->t[3 * m->nt++];
    t[0] = a, t[1] = flip ? c : b, t[2] = flip ? b : c;
}

static double tess_area(const tess_t *m)
{
    double a = 0.0;
    for (size_t i = 0; i < m->nt; i++) {
        const double *A = &m->p[3 * m->t[3 * i]], *B = &m->p[3 * m->t[3 * i + 1]], *C = &m->p[3 * m->t[3 * i + 2]];
        double e1[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, e2[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        a += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    return a;
}

/* Scales the tessellation about the origin so that its area is `area`: a polygon inscribed in a
 * disk or a sphere has less area than the curved surface, and an area light's power is pi Ke A. */
static void tess_fix_area(tess_t *m, double area)
{
    double f = sqrt(area / tess_area(m));
    for (size_t i = 0; i < 3 * m->nv; i++)
        m->p[i] *= f;
}

/* rectangle: sx by sy in the z = 0 plane, centred on the origin, front face +z. */
static pm_result_t tess_rectangle(tess_t *m, double sx, double sy)
{
    pm_result_t r = tess_alloc(m, 4, 2);
    if (r != PM_OK)
        return r;
    static const double up[3] = {0, 0, 1};
    tess_vert(m, -0.5 * sx, -0.5 * sy, 0, 0, 0);
    tess_vert(m, 0.5 * sx, -0.5 * sy, 0, 1, 0);
    tess_vert(m, 0.5 * sx, 0.5 * sy, 0, 1, 1);
    tess_vert(m, -0.5 * sx, 0.5 * sy, 0, 0, 1);
    tess_tri(m, 0, 1, 2, up);
    tess_tri(m, 0, 2, 3, up);
    return PM_OK;
}

/* disk: radius rad in the z = 0 plane, centred on the origin, front face +z; a fan of seg
 * triangles whose area is pi rad^2. */
static pm_result_t tess_disk(tess_t *m, double rad, int seg)
{
    pm_result_t r = tess_alloc(m, (size_t)seg + 1, (size_t)seg);
    if (r != PM_OK)
        return r;
    static const double up[3] = {0, 0, 1};
    tess_vert(m, 0, 0, 0, 0.5f, 0.5f);
    for (int i = 0; i < seg; i++) {
        double a = 2.0 * M_PI * i / seg;
        tess_vert(m, rad * cos(a), rad * sin(a), 0, (float)(0.5 + 0.5 * cos(a)), (float)(0.5 + 0.5 * sin(a)));
    }
    for (int i = 0; i < seg; i++)
        tess_tri(m, 0, (uint32_t)(1 + i), (uint32_t)(1 + (i + 1) % seg), up);
    tess_fix_area(m, M_PI * rad * rad);
    return PM_OK;
}

/* sphere: radius rad about the origin, front faces outward; seg / 2 bands of seg quads in
 * latitude-longitude (poles on +-y), whose area is 4 pi rad^2. */
static pm_result_t tess_sphere(tess_t *m, double rad, int seg)
{
    int nlat = seg / 2, nlon = seg;
    pm_result_t r = tess_alloc(m, (size_t)(nlat + 1) * (size_t)(nlon + 1), 2 * (size_t)nlat * (size_t)nlon);
    if (r != PM_OK)
        return r;
    for (int i = 0; i <= nlat; i++)
        for (int j = 0; j <= nlon; j++) {
            double th = M_PI * i / nlat, ph = 2.0 * M_PI * j / nlon;
            tess_vert(m, rad * sin(th) * cos(ph), rad * cos(th), rad * sin(th) * sin(ph), (float)j / nlon,
                      1.0f - (float)i / nlat);
        }
    for (int i = 0; i < nlat; i++)
        for (int j = 0; j < nlon; j++) {
            uint32_t a = (uint32_t)(i * (nlon + 1) + j), b = a + 1, d = a + (uint32_t)(nlon + 1), cc = d + 1;
            double th = M_PI * (i + 0.5) / nlat, ph = 2.0 * M_PI * (j + 0.5) / nlon;
            double out[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            if (i > 0) /* the first band's top edge is the pole: one triangle */
                tess_tri(m, a, b, cc, out);
            if (i < nlat - 1)
                tess_tri(m, a, cc, d, out);
        }
    tess_fix_area(m, 4.0 * M_PI * rad * rad);
    return PM_OK;
}

/* box: sx by sy by sz centred on the origin, front faces outward. */
static pm_result_t tess_box(tess_t *m, const float size[3])
{
    pm_result_t r = tess_alloc(m, 24, 12);
    if (r != PM_OK)
        return r;
    for (int axis = 0; axis < 3; axis++)
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            double out[3] = {0, 0, 0};
            out[axis] = sgn;
            uint32_t v0 = (uint32_t)m->nv;
            for (int q = 0; q < 4; q++) {
                double p[3];
                float su = (q == 1 || q == 2) ? 1.0f : 0.0f, sv = q >= 2 ? 1.0f : 0.0f;
                p[axis] = 0.5 * sgn * size[axis];
                p[u] = (su - 0.5) * size[u];
                p[v] = (sv - 0.5) * size[v];
                tess_vert(m, p[0], p[1], p[2], su, sv);
            }
            tess_tri(m, v0, v0 + 1, v0 + 2, out);
            tess_tri(m, v0, v0 + 2, v0 + 3, out);
        }
    return PM_OK;
}

/* Appends tessellation m, placed by xf, as one placement of material mi. */
static pm_result_t append_shape(ctx_t *c, const tess_t *m, const double xf[3][4], uint32_t mi, const char *where)
{
    pm_scene_t *s = c->s;
    size_t v0 = s->nverts, t0 = s->ntris;
    pm_result_t r;
    if (s->ntris + m->nt > PM_SCENE_MAX_TRIS)
        return pm_scene_bad(c, where, "more than %u triangles in the scene", PM_SCENE_MAX_TRIS);
    if ((r = pm_scene_grow((void **)&s->verts, 3 * (v0 + m->nv), sizeof(float))) != PM_OK ||
        (r = pm_scene_grow((void **)&s->uvs, 2 * (v0 + m->nv), sizeof(float))) != PM_OK ||
        (r = pm_scene_grow((void **)&s->normals, 3 * (v0 + m->nv), sizeof(float))) != PM_OK ||
        (r = pm_scene_grow((void **)&c->local, 3 * (v0 + m->nv), sizeof(float))) != PM_OK ||
        (r = pm_scene_grow((void **)&s->tris, 3 * (t0 + m->nt), sizeof(uint32_t))) != PM_OK ||
        (r = pm_scene_grow((void **)&s->tri_material, t0 + m->nt, sizeof(uint32_t))) != PM_OK ||
        (r = pm_scene_grow((void **)&s->placements, s->nplacements + 1, sizeof *s->placements)) != PM_OK)
        return r;
    int flip = pm_scene_det3(xf) < 0.0; /* a mirroring map keeps the front faces outward */
    for (size_t v = 0; v < m->nv; v++) {
        const double *p = &m->p[3 * v];
        for (int k = 0; k < 3; k++) {
            double x = xf[k][0] * p[0] + xf[k][1] * p[1] + xf[k][2] * p[2] + xf[k][3];
            if (!isfinite(x) || fabs(x) > PM_SCENE_COORD_MAX)
                return pm_scene_bad(c, where, "vertex coordinate %g is not finite or beyond %g", x, PM_SCENE_COORD_MAX);
            s->verts[3 * (v0 + v) + k] = (float)x;
            c->local[3 * (v0 + v) + k] = (float)p[k];
            s->normals[3 * (v0 + v) + k] = 0.0f; /* flat: the geometric normal shades */
        }
        s->uvs[2 * (v0 + v)] = m->uv[2 * v];
        s->uvs[2 * (v0 + v) + 1] = m->uv[2 * v + 1];
    }
    s->nverts += m->nv;
    for (size_t i = 0; i < m->nt; i++) {
        uint32_t *t = &s->tris[3 * s->ntris];
        for (int k = 0; k < 3; k++)
            t[k] = (uint32_t)v0 + m->t[3 * i + (flip && k ? 3 - k : k)];
        s->tri_material[s->ntris++] = mi;
        double area = pm_scene_triangle_area(s, s->ntris - 1);
        if (area > PM_SCENE_AREA_MAX)
            return pm_scene_bad(c, where, "a triangle of %g m^2 is beyond %g m^2: make the shape smaller", area,
                                PM_SCENE_AREA_MAX);
        if (!(area >= PM_SCENE_AREA_MIN)) {
            s->ntris--;
            s->ndropped++;
        }
    }
    pm_placement_t *pl = &s->placements[s->nplacements];
    memset(pl, 0, sizeof *pl);
    /* a key no mesh file has: a shape is never instanced */
    pl->key = 0x5ea9e000000000ull + s->nplacements;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            pl->xf[4 * i + j] = (float)xf[i][j];
    pl->tri0 = (uint32_t)t0, pl->ntris = (uint32_t)(s->ntris - t0);
    pl->vert0 = (uint32_t)v0, pl->nverts = (uint32_t)(s->nverts - v0);
    pl->proto = -1;
    s->nplacements++;
    return PM_OK;
}

static pm_result_t load_shape(ctx_t *c, json_t *sj, size_t index)
{
    static const char *const keys[] = {"type",  "size",   "radius",    "segments", "material", "emission",
                                       "scale", "rotate", "translate", "matrix",   NULL};
    pm_scene_t *s = c->s;
    char where[64], p[96];
    snprintf(where, sizeof where, "shapes[%zu]", index);
    if (!json_is_object(sj))
        return pm_scene_bad(c, where, "must be an object");
    pm_result_t r = pm_scene_only_keys(c, sj, where, keys);
    if (r != PM_OK)
        return r;
    const char *type = json_string_value(json_object_get(sj, "type"));
    snprintf(p, sizeof p, "%s.type", where);
    int is_rect = type && strcmp(type, "rectangle") == 0, is_disk = type && strcmp(type, "disk") == 0,
        is_sphere = type && strcmp(type, "sphere") == 0, is_box = type && strcmp(type, "box") == 0;
    if (!is_rect && !is_disk && !is_sphere && !is_box)
        return pm_scene_bad(c, p, "'%s' is not a shape (known: rectangle, disk, sphere, box)",
                            type ? type : "(missing or not a string)");
    /* the keys each type reads; another's is an error, not silently unused */
    const char *size_key = is_rect || is_box ? "size" : "radius", *other = is_rect || is_box ? "radius" : "size";
    if (json_object_get(sj, other))
        return pm_scene_bad(c, where, "a %s has no '%s' (it takes '%s')", type, other, size_key);
    if ((is_rect || is_box) && json_object_get(sj, "segments"))
        return pm_scene_bad(c, where, "a %s has no 'segments' (only a disk and a sphere are tessellated)", type);
    double xf[3][4];
    int general;
    if ((r = pm_scene_load_transform(c, sj, where, xf, &general)) != PM_OK)
        return r;
    tess_t m = {0};
    float size[3] = {1, 1, 1};
    double rad = 1.0;
    int64_t seg = is_disk ? 64 : 32;
    snprintf(p, sizeof p, "%s.%s", where, size_key);
    if (is_box)
        r = pm_scene_get_vec3(c, sj, "size", p, 0, 1e-9, PM_SCENE_COORD_MAX, size);
    else if (is_rect) {
        json_t *sz = json_object_get(sj, "size");
        if (sz && (!json_is_array(sz) || json_array_size(sz) != 2 || !json_is_number(json_array_get(sz, 0)) ||
                   !json_is_number(json_array_get(sz, 1))))
            return pm_scene_bad(c, p, "must be an array of 2 numbers (width along x, height along y)");
        for (size_t i = 0; sz && i < 2; i++) {
            double v = json_number_value(json_array_get(sz, i));
            if (!(v >= 1e-9 && v <= PM_SCENE_COORD_MAX))
                return pm_scene_bad(c, p, "element %zu = %.9g is outside [1e-09, %g]", i, v, PM_SCENE_COORD_MAX);
            size[i] = (float)v;
        }
    } else
        r = pm_scene_get_number(c, sj, "radius", p, 0, 1e-9, PM_SCENE_COORD_MAX, &rad);
    snprintf(p, sizeof p, "%s.segments", where);
    if (r == PM_OK && (is_disk || is_sphere))
        r = pm_scene_get_int(c, sj, "segments", p, 0, is_disk ? 3 : 4, 4096, &seg);
    if (r != PM_OK)
        return r;
    if (is_sphere && seg % 2)
        return pm_scene_bad(c, p, "%lld must be even (a sphere has segments / 2 bands)", (long long)seg);
    /* its material: a scene material, or the grey default */
    uint32_t mi = (uint32_t)s->nmaterials;
    if ((r = pm_scene_grow((void **)&s->materials, s->nmaterials + 1, sizeof *s->materials)) != PM_OK ||
        (r = pm_scene_grow((void **)&s->maps, s->nmaterials + 1, sizeof *s->maps)) != PM_OK)
        return r;
    s->materials[mi] = (pm_material_t){.kd = {0.8f, 0.8f, 0.8f}};
    snprintf(s->materials[mi].name, sizeof s->materials[mi].name, "shape%zu", index);
    s->maps[mi] = (pm_material_maps_t){-1, -1, -1, -1, -1, 1.0f, 0, {0}};
    s->nmaterials++;
    json_t *mat = json_object_get(sj, "material");
    size_t si = 0;
    if (mat) {
        snprintf(p, sizeof p, "%s.material", where);
        if ((r = find_material(c, mat, p, &si)) != PM_OK)
            return r;
        s->materials[mi] = c->smats[si];
        s->maps[mi] = c->smaps[si];
    }
    json_t *em = json_object_get(sj, "emission");
    if (em) {
        snprintf(p, sizeof p, "%s.emission", where);
        if ((r = load_emission(c, em, p, s->materials[mi].ke, &s->materials[mi].two_sided)) != PM_OK)
            return r;
    }
    if (is_rect)
        r = tess_rectangle(&m, size[0], size[1]);
    else if (is_disk)
        r = tess_disk(&m, rad, (int)seg);
    else if (is_sphere)
        r = tess_sphere(&m, rad, (int)seg);
    else
        r = tess_box(&m, size);
    if (r == PM_OK)
        r = append_shape(c, &m, xf, mi, where);
    free(m.p);
    free(m.uv);
    free(m.t);
    return r;
}

pm_result_t pm_scene_load_shapes(ctx_t *c, json_t *shapes)
{
    if (!shapes)
        return PM_OK;
    if (!json_is_array(shapes))
        return pm_scene_bad(c, "shapes", "must be an array");
    pm_result_t r = PM_OK;
    for (size_t i = 0; i < json_array_size(shapes) && r == PM_OK; i++)
        r = load_shape(c, json_array_get(shapes, i), i);
    return r;
}
