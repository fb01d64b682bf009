/* mesh.c: a scene's mesh entries imported through assimp's C API: each file once, its OBJ
 * order checked (faces before usemtl, late mtllib), its materials, vertices, texture coordinates,
 * vertex normals and triangles flattened into the scene, and its placements found for instancing. */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/hash.h"
#include "render/scene_load.h"

/* assimp reports some faults only to its log and carries on: a usemtl the .mtl does not
 * define, a missing .mtl (it then makes up a grey material). The first "Error" it logs
 * during an import fails the load. Scenes load on one thread, so one buffer serves. */
static char ai_first_error[512];
/* 1 while importing an OBJ without any mtllib: its usemtl names name nothing, and assimp's
 * "failed to locate material" for each is expected (the faces are the default grey). */
static int ai_obj_without_mtllib;

/* Errors assimp 5.2 logs for legal input and then handles right: a usemtl before any
 * group, object or face (the next face makes the default object, with that material), and
 * an illum outside 0 to 2 (kept in the material, and reported as unsupported). */
static const char *const ai_benign_errors[] = {
    "OBJ: No object detected to attach a new mesh instance",
    "OBJ: unexpected illumination model",
    NULL,
};

/* assimp's warning that it dropped faces naming vertices out of range (glTF): an error. */
static int ai_dropped_faces;

static void on_assimp_log(const char *msg, char *user)
{
    (void)user;
    if (strncmp(msg, "Warn,", 5) == 0 && strstr(msg, "faces had out-of-range indices"))
        ai_dropped_faces = 1;
    if (ai_first_error[0] || strncmp(msg, "Error,", 6) != 0)
        return;
    for (const char *const *b = ai_benign_errors; *b; b++)
        if (strstr(msg, *b))
            return;
    if (ai_obj_without_mtllib && strstr(msg, "OBJ: failed to locate material"))
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
const char *pm_scene_obj_word(const char *line, char *word, size_t cap)
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
static pm_result_t check_obj_materials(const char *path, char *libs_out, size_t libs_cap, int *no_materials_out)
{
    size_t libs_len = 0;
    libs_out[0] = '\0';
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(pm_result_of_errno(errno), "cannot open mesh '%s': %s", path, strerror(errno));
    char *line = NULL, word[16], group[128] = "";
    size_t cap = 0;
    uint64_t lineno = 0, faces = 0, first_usemtl = 0, bare_face = 0, bare_line = 0;
    char bare_group[128] = "";
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
        const char *rest = pm_scene_obj_word(line, word, sizeof word);
        if (strcmp(word, "g") == 0 || strcmp(word, "o") == 0) {
            snprintf(group, sizeof group, "%s", rest);
            for (char *p = group; *p; p++)
                if ((unsigned char)*p < 0x20 || *p == '\\')
                    *p = ' ';
        } else if (strcmp(word, "usemtl") == 0) {
            if (!rest[0])
                r = pm_error_set(PM_ERR_INPUT,
                                 "mesh '%s': usemtl on line %" PRIu64 " names no material (assimp would take the "
                                 "last one of the .mtl)",
                                 path, lineno);
            if (!first_usemtl)
                first_usemtl = lineno;
        } else if (strcmp(word, "f") == 0 || strcmp(word, "fo") == 0) {
            faces++;
            if (!first_usemtl && !bare_face) { /* an error only if some usemtl comes later */
                bare_face = faces, bare_line = lineno;
                snprintf(bare_group, sizeof bare_group, "%s", group);
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
        r = pm_error_set(pm_result_of_errno(errno), "cannot read mesh '%s': %s", path, strerror(errno));
    /* No mtllib: geometry only, every face the default grey whatever its usemtl says (load_materials
     * notes it). With an mtllib, faces before the first usemtl would silently take a material
     * they do not name (the .mtl's last one). */
    *no_materials_out = r == PM_OK && !libs_len;
    if (r == PM_OK && bare_face && !*no_materials_out) {
        char where[200] = "";
        if (bare_group[0])
            snprintf(where, sizeof where, ", group '%s'", bare_group);
        r = pm_error_set(PM_ERR_INPUT,
                         "mesh '%s': face %" PRIu64 " (line %" PRIu64 "%s) comes before any usemtl: every OBJ face "
                         "needs a material from the .mtl (an OBJ with no mtllib is the default grey)",
                         path, bare_face, bare_line, where);
    }
    free(line);
    fclose(f);
    return r;
}

pm_result_t pm_scene_check_regular(const char *path, const char *what)
{
    /* O_NONBLOCK: a FIFO opens at once instead of waiting for a writer, and is then refused */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return pm_error_set(pm_result_of_errno(errno), "cannot open %s '%s': %s", what, path, strerror(errno));
    struct stat st;
    int ok = fstat(fd, &st) == 0;
    int e = errno;
    close(fd);
    if (!ok)
        return pm_error_set(pm_result_of_errno(e), "cannot read %s '%s': %s", what, path, strerror(e));
    if (!S_ISREG(st.st_mode))
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is not a regular file (a %s)", what, path,
                            S_ISFIFO(st.st_mode)   ? "FIFO"
                            : S_ISDIR(st.st_mode)  ? "directory"
                            : S_ISCHR(st.st_mode)  ? "character device"
                            : S_ISBLK(st.st_mode)  ? "block device"
                            : S_ISSOCK(st.st_mode) ? "socket"
                                                   : "special file");
    return PM_OK;
}

/* The import of mesh file path, made now unless an earlier entry made it: assimp's scene, the OBJ
 * order checked (faces before usemtl, late mtllib), the .mtl files' materials located. */
static pm_result_t import_file(ctx_t *c, const char *path, int is_obj, import_t **im_out)
{
    pm_result_t r;
    for (size_t i = 0; i < c->nimports; i++)
        if (strcmp(c->imports[i].path, path) == 0) {
            *im_out = &c->imports[i];
            return PM_OK;
        }
    if ((r = pm_scene_check_regular(path, "mesh")) != PM_OK || (r = pm_scene_add_source(c->s, path)) != PM_OK)
        return r;
    /* assimp reads an OBJ's .mtl files (noted below) and nothing else of these formats; others
     * open what they refer to themselves, which the scene cache cannot name */
    const char *dot = strrchr(path, '.');
    if (!dot ||
        (strcasecmp(dot, ".obj") && strcasecmp(dot, ".ply") && strcasecmp(dot, ".off") && strcasecmp(dot, ".stl")))
        c->s->uncacheable = 1;
    /* assimp opens an OBJ's .mtl files itself: each must be a regular file too (a missing one
     * is assimp's to report) */
    char libs_read[4096] = "";
    int no_materials = 0;
    pm_result_t r_obj = is_obj ? check_obj_materials(path, libs_read, sizeof libs_read, &no_materials) : PM_OK;
    if (r_obj == PM_OK)
        for (const char *lib = libs_read, *eol; (eol = strchr(lib, '\n')); lib = eol + 1) {
            char name[1024], lpath[1200];
            snprintf(name, sizeof name, "%.*s", (int)(eol - lib), lib);
            pm_scene_resolve(path, name, lpath, sizeof lpath);
            if (access(lpath, F_OK) == 0 && (r = pm_scene_check_regular(lpath, "material library")) != PM_OK)
                return r;
            if ((r = pm_scene_add_source(c->s, lpath)) != PM_OK)
                return r;
            /* a library that is not there: assimp reads the OBJ's own name with .mtl instead */
            size_t pl = strlen(path);
            if (access(lpath, F_OK) != 0 && pl > 4 && pl < sizeof lpath) {
                snprintf(lpath, sizeof lpath, "%.*s.mtl", (int)(pl - 4), path);
                if ((r = pm_scene_add_source(c->s, lpath)) != PM_OK)
                    return r;
            }
        }
    if (strlen(libs_read) + 1200 > sizeof libs_read)
        c->s->uncacheable = 1; /* near the list's end: a library may have been left off it */
    if ((r = pm_scene_grow((void **)&c->imports, c->nimports + 1, sizeof *c->imports)) != PM_OK)
        return r;
    /* Triangulate polygons, merge shared vertices, flatten node transforms, drop points
     * and lines; vertex normals come as the file has them (none are made up). */
    const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                           aiProcess_SortByPType | aiProcess_ValidateDataStructure;
    if ((r = pm_scene_mesh_precheck(path)) != PM_OK)
        return r;
    pm_scene_guard_importing(path);
    struct aiLogStream log = {on_assimp_log, NULL};
    ai_first_error[0] = '\0';
    ai_dropped_faces = 0;
    ai_obj_without_mtllib = no_materials;
    aiAttachLogStream(&log);
    const struct aiScene *imported = aiImportFile(path, flags);
    aiDetachAllLogStreams();
    pm_scene_guard_imported();
    /* in a guarded load's child, assimp's own std::bad_alloc is the memory limit (as the trial's
     * exit 11) */
    if (!imported && pm_scene_guarded_child() && strstr(aiGetErrorString(), "alloc"))
        return pm_error_set(PM_ERR_INPUT,
                            "mesh '%s': assimp's import took more than %ld MiB (PMTK_IMPORT_MB) and was stopped", path,
                            pm_scene_import_mib());
    if (!imported)
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, aiGetErrorString());
    if (ai_dropped_faces) {
        aiReleaseImport(imported);
        return pm_scene_gltf_bad_face(path);
    }
    if (ai_first_error[0]) {
        aiReleaseImport(imported);
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': %s", path, ai_first_error);
    }
    /* An OBJ whose faces name no material (no mtllib, or a usemtl the .mtl lacks) gets
     * assimp's default material, or the .mtl's last one; rendering either would be
     * silently wrong. The OBJ's own order of lines tells; the default material is checked
     * after it. */
    if (r_obj != PM_OK) { /* its message stands: nothing since has set one */
        aiReleaseImport(imported);
        return r_obj;
    }
    import_t *im = &c->imports[c->nimports++];
    *im = (import_t){.as = imported, .no_materials = no_materials};
    snprintf(im->path, sizeof im->path, "%s", path);
    snprintf(im->libs, sizeof im->libs, "%s", libs_read);
    *im_out = im;
    if (is_obj && (r = pm_scene_mtl_check(path, libs_read, im->as)) != PM_OK)
        return r;
    return is_obj ? pm_scene_mtl_homes(path, libs_read, im) : PM_OK;
}

/* The materials of import im appended to the scene from index *mat0_out: each read, what it
 * does not honour reported, the textures of those some triangle uses loaded. */
static pm_result_t load_materials(ctx_t *c, json_t *mj, const char *path, int is_obj, const import_t *im,
                                  size_t *mat0_out)
{
    pm_scene_t *s = c->s;
    const struct aiScene *as = im->as;
    pm_result_t r;
    for (unsigned mi = 0; is_obj && !im->no_materials && mi < as->mNumMeshes; mi++) {
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
    for (unsigned i = 0; i < as->mNumMaterials; i++) {
        struct aiString an;
        int used = 0;
        for (unsigned mi = 0; mi < as->mNumMeshes && !used; mi++)
            used =
                as->mMeshes[mi]->mMaterialIndex == i && (as->mMeshes[mi]->mPrimitiveTypes & aiPrimitiveType_TRIANGLE);
        if (used &&
            (im->no_materials || aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &an) != aiReturn_SUCCESS ||
             !an.length || strcmp(an.data, AI_DEFAULT_MATERIAL_NAME) == 0) &&
            (r = pm_scene_add_note(s, 0, "mesh '%s' names no material: its faces are the default grey (Kd 0.8)",
                                   path)) != PM_OK)
            return r;
    }
    size_t mat0 = *mat0_out = s->nmaterials;
    if ((r = pm_scene_grow((void **)&s->materials, mat0 + as->mNumMaterials, sizeof *s->materials)) != PM_OK ||
        (r = pm_scene_grow((void **)&s->maps, mat0 + as->mNumMaterials, sizeof *s->maps)) != PM_OK)
        return r;
    for (size_t i = mat0; i < mat0 + as->mNumMaterials; i++)
        s->maps[i] = (pm_material_maps_t){-1, -1, -1, -1, -1, 1.0f, 0, {0}};
    for (unsigned i = 0; i < as->mNumMaterials && r == PM_OK; i++) {
        /* one the scene file replaces is not read (nor refused, nor its textures loaded): a
         * placeholder of its name until pm_scene_apply_mesh_overrides puts the scene's in */
        pm_material_t *slot = &s->materials[mat0 + i];
        struct aiString an0;
        char word[sizeof slot->name] = "";
        if (aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &an0) == aiReturn_SUCCESS)
            snprintf(word, sizeof word, "%s", an0.data);
        pm_scene_material_word(word);
        if (!word[0] || strcmp(word, AI_DEFAULT_MATERIAL_NAME) == 0)
            snprintf(word, sizeof word, "default"); /* as pm_scene_load_material names the stand-in */
        if (pm_scene_overridden(mj, word)) {
            *slot = (pm_material_t){.kd = {0.8f, 0.8f, 0.8f}};
            memcpy(slot->name, word, sizeof word);
            continue;
        }
        r = pm_scene_load_material(c, path, is_obj, as->mMaterials[i], &s->materials[mat0 + i]);
        if (r == PM_OK && im->no_materials) { /* a usemtl name without a library: the grey, by that name */
            pm_material_t *g = &s->materials[mat0 + i];
            char name[sizeof g->name];
            memcpy(name, g->name, sizeof name);
            *g = (pm_material_t){.kd = {0.8f, 0.8f, 0.8f}};
            memcpy(g->name, name, sizeof name);
            continue;
        }
        /* assimp's stand-in material is pmtk's grey default whatever it holds: nothing to report */
        struct aiString an;
        int stand_in = aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &an) != aiReturn_SUCCESS ||
                       an.length == 0 || strcmp(an.data, AI_DEFAULT_MATERIAL_NAME) == 0;
        if (r == PM_OK && !stand_in)
            r = pm_scene_scan_material(s, is_obj, as->mMaterials[i], (uint32_t)(mat0 + i));
        /* only the textures of a material some triangle uses: an unused one is dropped unread */
        int used = 0;
        for (unsigned mi = 0; mi < as->mNumMeshes && !used; mi++)
            used =
                as->mMeshes[mi]->mMaterialIndex == i && (as->mMeshes[mi]->mPrimitiveTypes & aiPrimitiveType_TRIANGLE);
        if (r == PM_OK && !stand_in && used)
            r = pm_scene_load_material_maps(c, path, is_obj, im, as->mMaterials[i], (uint32_t)(mat0 + i));
    }
    if (r == PM_OK && is_obj) {
        unsigned char *pbr = malloc(as->mNumMaterials ? as->mNumMaterials : 1);
        float metallic, roughness;
        if (!pbr)
            return pm_error_set(PM_ERR_NOMEM, "out of memory");
        for (unsigned i = 0; i < as->mNumMaterials; i++)
            pbr[i] = (unsigned char)pm_scene_pbr_inputs(1, as->mMaterials[i], &metallic, &roughness);
        r = pm_scene_scan_mtl_dropped(s, path, im->libs, mat0, as->mNumMaterials, pbr);
        free(pbr);
    }
    if (r == PM_OK)
        s->nmaterials += as->mNumMaterials;
    return r;
}

/* The vertices of assimp mesh m into the scene from index v0 (room made by the caller): placed
 * by xf (rows of [3x3 | t]; general 0: scale and translate only), with their first texture
 * coordinates (through the texture transform of their material's maps mm, if it has one) and
 * their normals (by the cofactor matrix of xf), and in mesh units in c->local. */
static pm_result_t load_vertices(ctx_t *c, const struct aiMesh *m, const char *path, const double xf[3][4], int general,
                                 const pm_material_maps_t *mm, size_t v0)
{
    pm_scene_t *s = c->s;
    for (unsigned v = 0; v < m->mNumVertices; v++) {
        double p[3] = {m->mVertices[v].x, m->mVertices[v].y, m->mVertices[v].z};
        for (int k = 0; k < 3; k++)
            c->local[3 * (v0 + v) + k] = (float)p[k];
        for (int k = 0; k < 3; k++) {
            double x =
                general ? xf[k][0] * p[0] + xf[k][1] * p[1] + xf[k][2] * p[2] + xf[k][3] : p[k] * xf[k][k] + xf[k][3];
            if (!isfinite(x) || fabs(x) > PM_SCENE_COORD_MAX)
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': vertex %u coordinate %c = %g is not finite or beyond %g",
                                    path, v, "xyz"[k], x, PM_SCENE_COORD_MAX);
            s->verts[3 * (v0 + v) + k] = (float)x;
        }
        /* the first set of texture coordinates; none: every point reads texel (0, 0) */
        const struct aiVector3D *uv = m->mTextureCoords[0] ? &m->mTextureCoords[0][v] : NULL;
        float uu = uv ? uv->x : 0.0f, vv = uv ? uv->y : 0.0f;
        if (mm->has_uvxf) { /* glTF KHR_texture_transform (scene_maps.c) */
            const float *a = mm->uvxf;
            float u1 = a[0] * uu + a[1] * vv + a[2], v1 = a[3] * uu + a[4] * vv + a[5];
            uu = u1, vv = v1;
        }
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
    }
    return PM_OK;
}

/* The triangles of assimp mesh mi (m; its vertices from v0, its material scene material mat):
 * wound the other way when flip, degenerate ones left out (counted), too large ones refused;
 * *kept folds in which faces were kept. */
static pm_result_t load_faces(pm_scene_t *s, const struct aiMesh *m, unsigned mi, const char *path, int flip, size_t v0,
                              uint32_t mat, uint64_t *kept)
{
    for (unsigned f = 0; f < m->mNumFaces; f++) {
        const struct aiFace *face = &m->mFaces[f];
        if (face->mNumIndices != 3)
            continue;
        uint32_t *t = &s->tris[3 * s->ntris];
        for (int k = 0; k < 3; k++) {
            if (face->mIndices[k] >= m->mNumVertices)
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': face %u names vertex %u of %u", path, f,
                                    face->mIndices[k], m->mNumVertices);
            t[k] = (uint32_t)(v0 + face->mIndices[flip && k ? 3 - k : k]);
        }
        s->tri_material[s->ntris] = mat;
        s->ntris++;
        /* Zero-area triangles scatter nothing and have no normal: leave them out, and
         * those too small for a float normal with them. One too large for a float normal
         * cannot be left out without changing the scene: refuse it. */
        double area = pm_scene_triangle_area(s, s->ntris - 1);
        if (area > PM_SCENE_AREA_MAX)
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': face %u has an area of %g m^2, beyond %g m^2 (its normal overflows a "
                                "float): scale the scene down",
                                path, f, area, PM_SCENE_AREA_MAX);
        if (!(area >= PM_SCENE_AREA_MIN)) {
            s->ntris--;
            s->ndropped++;
        } else {
            uint64_t id[3] = {*kept, mi, f};
            *kept = pm_hash_bytes(id, sizeof id);
        }
    }
    return PM_OK;
}

/* Every triangle mesh of the import into the scene's flattened arrays, its materials from mat0;
 * *kept as load_faces makes it. */
static pm_result_t load_meshes(ctx_t *c, const struct aiScene *as, const char *path, const double xf[3][4], int general,
                               int flip, size_t mat0, uint64_t *kept)
{
    pm_scene_t *s = c->s;
    pm_result_t r = PM_OK;
    for (unsigned mi = 0; mi < as->mNumMeshes && r == PM_OK; mi++) {
        const struct aiMesh *m = as->mMeshes[mi];
        if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE))
            continue;
        if (m->mMaterialIndex >= as->mNumMaterials)
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': material index %u of %u", path, m->mMaterialIndex,
                                as->mNumMaterials);
        const pm_material_maps_t *mm = &s->maps[mat0 + m->mMaterialIndex];
        if (!m->mTextureCoords[0] &&
            (mm->kd >= 0 || mm->ks >= 0 || mm->alpha >= 0 || mm->normal >= 0 || mm->bump >= 0) &&
            (r = pm_scene_note_unsupported(s, (uint32_t)(mat0 + m->mMaterialIndex), "texture coordinates", 0,
                                           "missing (texel 0 0 used)")) != PM_OK)
            return r;
        size_t v0 = s->nverts;
        if (s->ntris + m->mNumFaces > PM_SCENE_MAX_TRIS)
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': more than %u triangles in the scene", path,
                                PM_SCENE_MAX_TRIS);
        if ((r = pm_scene_grow((void **)&s->verts, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = pm_scene_grow((void **)&s->uvs, 2 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = pm_scene_grow((void **)&s->normals, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = pm_scene_grow((void **)&c->local, 3 * (v0 + m->mNumVertices), sizeof(float))) != PM_OK ||
            (r = pm_scene_grow((void **)&s->tris, 3 * (s->ntris + m->mNumFaces), sizeof(uint32_t))) != PM_OK ||
            (r = pm_scene_grow((void **)&s->tri_material, s->ntris + m->mNumFaces, sizeof(uint32_t))) != PM_OK ||
            (r = load_vertices(c, m, path, xf, general, mm, v0)) != PM_OK)
            return r;
        s->nverts += m->mNumVertices;
        r = load_faces(s, m, mi, path, flip, v0, (uint32_t)(mat0 + m->mMaterialIndex), kept);
    }
    return r;
}

pm_result_t pm_scene_load_mesh(ctx_t *c, json_t *mj, size_t index)
{
    static const char *const keys[] = {"file",     "scale",     "rotate",   "translate", "matrix",
                                       "material", "materials", "emission", "lights",    NULL};
    pm_scene_t *s = c->s;
    char where[64], path[1200];
    snprintf(where, sizeof where, "meshes[%zu]", index);
    if (!json_is_object(mj))
        return pm_scene_bad(c, where, "must be an object");
    pm_result_t r = pm_scene_only_keys(c, mj, where, keys);
    if (r != PM_OK)
        return r;
    const char *file = json_string_value(json_object_get(mj, "file"));
    if (!file)
        return pm_scene_bad(c, where, "'file' is missing or not a string");
    double xf[3][4];
    int general;
    if ((r = pm_scene_load_transform(c, mj, where, xf, &general)) != PM_OK)
        return r;
    /* A mirroring map (negative determinant) turns the right-hand-rule normal of every
     * triangle inward: its vertex order is swapped so that the front face (the side an
     * emitter lights) stays the mirror image of the mesh's own. */
    int flip = pm_scene_det3(xf) < 0.0;
    pm_scene_resolve(c->file, file, path, sizeof path);
    size_t ext = strlen(path);
    int is_obj = ext > 4 && strcasecmp(path + ext - 4, ".obj") == 0;
    import_t *im = NULL;
    size_t tri_start = s->ntris, vert_start = s->nverts, mat0 = 0;
    uint64_t kept = 0; /* which faces are kept (degenerate ones left out): a placement's key */
    /* the import is the scene's until pm_scene_load ends: it serves every entry placing it */
    if ((r = import_file(c, path, is_obj, &im)) != PM_OK ||
        (r = load_materials(c, mj, path, is_obj, im, &mat0)) != PM_OK ||
        (r = pm_scene_apply_mesh_overrides(c, mj, where, file, mat0, im->as->mNumMaterials)) != PM_OK ||
        (r = load_meshes(c, im->as, path, xf, general, flip, mat0, &kept)) != PM_OK ||
        (r = pm_scene_load_asset_extras(c, mj, where, path, file, index, xf, im->as->mNumLights)) != PM_OK)
        return r;
    /* This entry's placement: entries with equal keys hold the same triangles in the same mesh
     * units and winding, so that Embree can keep one copy and place it by instances. */
    if ((r = pm_scene_grow((void **)&s->placements, s->nplacements + 1, sizeof *s->placements)) != PM_OK)
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
void pm_scene_release_import(ctx_t *c, json_t *meshes, size_t i)
{
    const char *file = json_string_value(json_object_get(json_array_get(meshes, i), "file"));
    if (!file)
        return;
    char path[1200], later[1200];
    pm_scene_resolve(c->file, file, path, sizeof path);
    for (size_t j = i + 1; j < json_array_size(meshes); j++) {
        const char *f = json_string_value(json_object_get(json_array_get(meshes, j), "file"));
        if (!f)
            continue;
        pm_scene_resolve(c->file, f, later, sizeof later);
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

/* Which placements Embree may instance: those whose mesh units and transform keep Embree in
 * the range it is built for (docs/scene-format.md, Instancing). A prototype with a coordinate
 * beyond PM_SCENE_INSTANCE_COORD_MAX, or a transform whose scale (each column's length and the
 * cube root of the determinant) lies outside [PM_SCENE_INSTANCE_SCALE_MIN,
 * PM_SCENE_INSTANCE_SCALE_MAX], is built flat in scene units instead: Embree aborted on a
 * plane at +-1e14 placed with scale 1e-14, and rendered a box in units of 1e16 mm black. */
static int instance_xf_ok(const float xf[12])
{
    double det = 0.0;
    for (int j = 0; j < 3; j++) {
        double len = sqrt((double)xf[j] * xf[j] + (double)xf[4 + j] * xf[4 + j] + (double)xf[8 + j] * xf[8 + j]);
        if (!(len >= PM_SCENE_INSTANCE_SCALE_MIN && len <= PM_SCENE_INSTANCE_SCALE_MAX))
            return 0;
    }
    det = (double)xf[0] * ((double)xf[5] * xf[10] - (double)xf[6] * xf[9]) -
          (double)xf[1] * ((double)xf[4] * xf[10] - (double)xf[6] * xf[8]) +
          (double)xf[2] * ((double)xf[4] * xf[9] - (double)xf[5] * xf[8]);
    double s = cbrt(fabs(det));
    return s >= PM_SCENE_INSTANCE_SCALE_MIN && s <= PM_SCENE_INSTANCE_SCALE_MAX;
}

static int local_ok(const float *local, size_t n)
{
    for (size_t i = 0; i < 3 * n; i++)
        if (!(fabsf(local[i]) <= (float)PM_SCENE_INSTANCE_COORD_MAX))
            return 0;
    return 1;
}

static const pm_placement_t *sort_placements; /* qsort's context: scenes load on one thread */

static int placement_cmp(const void *pa, const void *pb)
{
    uint32_t ia = *(const uint32_t *)pa, ib = *(const uint32_t *)pb;
    const pm_placement_t *a = &sort_placements[ia], *b = &sort_placements[ib];
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    if (a->ntris != b->ntris)
        return a->ntris < b->ntris ? -1 : 1;
    if (a->nverts != b->nverts)
        return a->nverts < b->nverts ? -1 : 1;
    return ia < ib ? -1 : ia > ib;
}

/* Marks the placements Embree may instance (a key placed more than once, unless the scene
 * says "instancing": false, within the range above) and keeps their prototype's vertices in
 * mesh units. Placements are grouped by sorting, in time N log N; each group's prototype is
 * its first placement in scene order. *flattened_out: how many placements of repeated meshes
 * were built flat for the range. */
pm_result_t pm_scene_find_instances(ctx_t *c, int allowed, size_t *flattened_out)
{
    pm_scene_t *s = c->s;
    size_t nlocal = 0, n = s->nplacements;
    *flattened_out = 0;
    if (!allowed || n < 2)
        return PM_OK;
    uint32_t *order = malloc(n * sizeof *order);
    if (!order)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu placements", n);
    for (size_t i = 0; i < n; i++)
        order[i] = (uint32_t)i;
    sort_placements = s->placements;
    qsort(order, n, sizeof *order, placement_cmp);
    for (size_t g = 0, e; g < n; g = e) {
        const pm_placement_t *first = &s->placements[order[g]];
        int ok = first->ntris > 0 && local_ok(c->local + 3 * (size_t)first->vert0, first->nverts);
        for (e = g; e < n; e++) {
            const pm_placement_t *p = &s->placements[order[e]];
            if (p->key != first->key || p->ntris != first->ntris || p->nverts != first->nverts)
                break;
            ok &= instance_xf_ok(p->xf);
        }
        if (e - g < 2)
            continue;
        if (!ok) {
            *flattened_out += e - g;
            continue;
        }
        for (size_t k = g; k < e; k++)
            s->placements[order[k]].proto = (int32_t)order[g];
        s->placements[order[g]].local0 = (uint32_t)nlocal;
        nlocal += first->nverts;
    }
    free(order);
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
