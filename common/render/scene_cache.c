/* scene_cache.c: a loaded scene written to one file and read back (render/scene_cache.h;
 * docs/formats.md, "The scene cache").
 *
 * The file: the magic line "#?PMTK-SCENE-CACHE", header lines KEY=VALUE, an empty line, the
 * payload, and the XXH3-64 of every byte before it, little-endian. The payload is this build's
 * pm_scene_t with its pointers cleared, then each array it points to as a u64 byte count and
 * the bytes, in a fixed order (put_scene). It is the build's own memory layout, which is why
 * the header's BUILD must be this build's: no other program reads it, and nothing in it is
 * an interchange format. The reader still checks every count against the scene's and every
 * index against what it indexes, so that a damaged file with a good checksum is a miss, not
 * a crash. */
#include "render/scene_cache.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <assimp/version.h>
#include <jansson.h>
#include <jpeglib.h>
#include <openexr.h>
#include <png.h>

#include "base/atomic.h"
#include "base/hash.h"
#include "base/version.h"
#include "render/scene_load.h"

/* PM_SCENE_CACHE_BUILD: given by the Makefile, a hash of the library's sources and flags */
#ifndef PM_SCENE_CACHE_BUILD
#error "PM_SCENE_CACHE_BUILD is the Makefile's to define"
#endif
#define MAGIC "#?PMTK-SCENE-CACHE\n"
#define FORMAT_VERSION "1"
#define HEADER_MAX (1 << 20)

/* ---- the key: what a load depends on besides its files ---- */

/* The import limits (render/mesh_guard.c): a load that passed them may fail under others. */
static void limits_text(char *out, size_t cap)
{
    const char *s = getenv("PMTK_IMPORT_SECONDS"), *m = getenv("PMTK_IMPORT_MB");
    snprintf(out, cap, "%s %s", s ? s : "-", m ? m : "-");
}

/* The libraries a load runs through, by their versions at run time: another libassimp, libpng,
 * libjpeg, OpenEXR or jansson may load the same files into another scene. */
static void libs_text(char *out, size_t cap)
{
    int em = 0, en = 0, ep = 0;
    const char *extra = NULL;
    exr_get_library_version(&em, &en, &ep, &extra);
    snprintf(out, cap, "assimp %u.%u.%u.%u libpng %s libjpeg %d OpenEXR %d.%d.%d jansson %s", aiGetVersionMajor(),
             aiGetVersionMinor(), aiGetVersionPatch(), aiGetVersionRevision(), png_get_libpng_ver(NULL),
             JPEG_LIB_VERSION, em, en, ep, jansson_version_str());
}

/* The working directory, which a relative scene path and everything under it depend on; "" for
 * an absolute path. */
static void cwd_for(const char *scene_path, char *out, size_t cap)
{
    out[0] = '\0';
    if (scene_path[0] != '/' && !getcwd(out, cap))
        snprintf(out, cap, "?");
}

/* The file a cache name stands for: the name itself, or, for a directory (one that exists, or
 * a name ending in '/', made here), a file in it named by the hash of the scene's path (absolute:
 * with the working directory for a relative one), so that one directory serves every scene. */
static const char *cache_file(const char *cache, const char *scene_path, char *out, size_t cap)
{
    struct stat sb;
    size_t len = strlen(cache);
    int dir = (len && cache[len - 1] == '/') || (stat(cache, &sb) == 0 && S_ISDIR(sb.st_mode));
    if (!dir)
        return cache;
    if (len && cache[len - 1] == '/')
        mkdir(cache, 0777); /* one level; a failure shows in the read or the write */
    char cwd[PATH_MAX], key[PATH_MAX * 2 + 2];
    cwd_for(scene_path, cwd, sizeof cwd);
    snprintf(key, sizeof key, "%s%s%s", cwd, cwd[0] ? "/" : "", scene_path);
    snprintf(out, cap, "%s%sscene-%016" PRIx64 ".cache", cache, cache[len - 1] == '/' ? "" : "/",
             pm_hash_bytes(key, strlen(key)));
    return out;
}

/* 1 for a byte a header value may not hold */
static int control_byte(char c) { return (unsigned char)c < 0x20 || c == 0x7f; }

/* 1 when text has no such byte (a path with a newline is not cached) */
static int header_safe(const char *text)
{
    for (; *text; text++)
        if (control_byte(*text))
            return 0;
    return 1;
}

/* ---- writing ---- */

typedef struct {
    unsigned char *p;
    size_t n, cap;
    int failed;
    int counting; /* 1: only n counts the bytes (the first of encode's two passes) */
} buf_t;

static void put(buf_t *b, const void *data, size_t n)
{
    if (b->failed)
        return;
    if (b->counting) {
        b->n += n;
        return;
    }
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 1 << 16;
        while (cap < b->n + n)
            cap *= 2;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->failed = 1;
            return;
        }
        b->p = q, b->cap = cap;
    }
    if (n)
        memcpy(b->p + b->n, data, n);
    b->n += n;
}

/* An array: its byte count, then its bytes (none for NULL). */
static void put_array(buf_t *b, const void *data, size_t n)
{
    uint64_t len = data ? (uint64_t)n : 0;
    put(b, &len, sizeof len);
    put(b, data, (size_t)len);
}

/* A field added to these structs may be a pointer, which the cache must write as an array and
 * clear (below): their sizes here make the compiler stop whoever adds one until they have looked
 * (x86-64, the only ABI pmtk builds for). */
_Static_assert(sizeof(pm_scene_t) == 1824, "pm_scene_t changed: serialise its new fields in scene_cache.c");
_Static_assert(sizeof(pm_texture_t) == 1064, "pm_texture_t changed: see put_scene and get_scene");
_Static_assert(sizeof(pm_envmap_t) == 152, "pm_envmap_t changed: see put_scene and get_scene");

/* Every pointer of s set to NULL: a written scene's are this process's (the bytes then depend on
 * the scene alone), and a read one's are whatever the file says until each array is read. */
static void clear_pointers(pm_scene_t *s)
{
    s->verts = NULL, s->tris = NULL, s->tri_material = NULL, s->materials = NULL, s->lights = NULL;
    s->envmap = NULL, s->portals = NULL, s->emissive = NULL, s->unsupported = NULL, s->maps = NULL;
    s->uvs = NULL, s->normals = NULL, s->textures = NULL, s->placements = NULL, s->local_verts = NULL;
    s->notes = NULL, s->sources = NULL;
}

static void put_scene(buf_t *b, const pm_scene_t *s)
{
    pm_scene_t flat = *s;
    clear_pointers(&flat);
    put(b, &flat, sizeof flat);
    put_array(b, s->verts, 3 * s->nverts * sizeof(float));
    put_array(b, s->tris, 3 * s->ntris * sizeof(uint32_t));
    put_array(b, s->tri_material, s->ntris * sizeof(uint32_t));
    put_array(b, s->materials, s->nmaterials * sizeof *s->materials);
    put_array(b, s->lights, s->nlights * sizeof *s->lights);
    put_array(b, s->portals, s->nportals * sizeof *s->portals);
    put_array(b, s->emissive, s->nemissive * sizeof *s->emissive);
    put_array(b, s->unsupported, s->nunsupported * sizeof *s->unsupported);
    put_array(b, s->maps, s->nmaterials * sizeof *s->maps);
    put_array(b, s->uvs, 2 * s->nverts * sizeof(float));
    put_array(b, s->normals, 3 * s->nverts * sizeof(float));
    put_array(b, s->placements, s->nplacements * sizeof *s->placements);
    size_t nlocal = 0;
    for (size_t i = 0; i < s->nplacements; i++)
        if (s->placements[i].proto == (int32_t)i && s->placements[i].local0 + (size_t)s->placements[i].nverts > nlocal)
            nlocal = s->placements[i].local0 + (size_t)s->placements[i].nverts;
    put_array(b, s->local_verts, 3 * nlocal * sizeof(float));
    put_array(b, s->notes, s->nnotes * sizeof *s->notes);
    put_array(b, s->sources, s->nsources * sizeof *s->sources);
    for (size_t i = 0; i < s->ntextures; i++) {
        pm_texture_t t = s->textures[i];
        size_t n = (size_t)t.w * t.h * 4;
        t.u8 = NULL, t.f32 = NULL;
        put(b, &t, sizeof t);
        put_array(b, s->textures[i].u8, n);
        put_array(b, s->textures[i].f32, n * sizeof(float));
    }
    if (s->envmap) {
        pm_envmap_t e = *s->envmap;
        size_t n = (size_t)e.w * e.h;
        e.rgb = NULL, e.row_cdf = NULL, e.col_cdf = NULL, e.pix_p = NULL;
        put_array(b, &e, sizeof e);
        put_array(b, s->envmap->rgb, 3 * n * sizeof(float));
        put_array(b, s->envmap->row_cdf, e.h * sizeof(double));
        put_array(b, s->envmap->col_cdf, n * sizeof(double));
        put_array(b, s->envmap->pix_p, n * sizeof(double));
    } else {
        put_array(b, NULL, 0);
    }
}

/* A header line whose value has no control byte: each one a '?' (and *altered set). */
static void put_line(buf_t *b, const char *key, const char *value, int *altered)
{
    put(b, key, strlen(key));
    put(b, "=", 1);
    for (const char *p = value; *p; p++) {
        int bad = control_byte(*p);
        *altered |= bad;
        put(b, bad ? "?" : p, 1);
    }
    put(b, "\n", 1);
}

/* The header and the payload of s into b. */
static void put_all(buf_t *b, const pm_scene_t *s)
{
    char text[PATH_MAX + 64], id[400];
    int altered = 0;
    put(b, MAGIC, strlen(MAGIC));
    put_line(b, "FORMAT", "scene-cache", &altered);
    put_line(b, "VERSION", FORMAT_VERSION, &altered);
    put_line(b, "SOFTWARE", "pmtk " PM_VERSION_STRING, &altered);
    put_line(b, "BUILD", PM_SCENE_CACHE_BUILD, &altered);
    libs_text(text, sizeof text);
    put_line(b, "LIBS", text, &altered);
    put_line(b, "PATH", s->path, &altered);
    cwd_for(s->path, text, sizeof text);
    if (text[0])
        put_line(b, "CWD", text, &altered);
    limits_text(text, sizeof text);
    put_line(b, "LIMITS", text, &altered);
    pm_scene_id(s, id, sizeof id);
    put_line(b, "SCENE", id, &altered);
    for (size_t i = 0; i < s->nsources; i++) {
        if (s->sources[i].absent)
            snprintf(text, sizeof text, "absent %s", s->sources[i].path);
        else
            snprintf(text, sizeof text, "xxh3:%016" PRIx64 " %s", s->sources[i].hash, s->sources[i].path);
        put_line(b, "SOURCE", text, &altered);
    }
    put(b, "\n", 1);
    if (altered) { /* the bytes carry the scene (a guarded load), but no file may: its key is not whole */
        pm_scene_t copy = *s;
        copy.uncacheable = 1;
        put_scene(b, &copy);
    } else {
        put_scene(b, s);
    }
}

pm_result_t pm_scene_cache_encode(const pm_scene_t *s, unsigned char **out, size_t *n_out)
{
    /* two passes, the first counting: the buffer is the file's size, not up to twice it (the
     * guarded child holds the scene and these bytes under PMTK_IMPORT_MB) */
    buf_t b = {.counting = 1};
    put_all(&b, s);
    size_t total = b.n + sizeof(uint64_t);
    b = (buf_t){.p = malloc(total), .cap = total};
    b.failed = !b.p;
    put_all(&b, s);
    if (!b.failed) {
        uint64_t h = pm_hash_bytes(b.p, b.n);
        put(&b, &h, sizeof h);
    }
    if (b.failed) {
        free(b.p);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the scene cache of '%s'", s->path);
    }
    *out = b.p, *n_out = b.n;
    return PM_OK;
}

/* bytes (n) to path, atomically, without fsync */
static pm_result_t write_bytes(const char *path, const unsigned char *bytes, size_t n)
{
    pm_atomic_t a;
    pm_result_t r = pm_atomic_open(path, &a);
    if (r != PM_OK)
        return r;
    a.no_sync = 1;
    if (fwrite(bytes, 1, n, a.f) != n) {
        int e = errno;
        pm_atomic_abort(&a);
        return pm_error_set(pm_result_of_errno(e), "cannot write '%s': %s", path, strerror(e));
    }
    return pm_atomic_commit(&a);
}

/* why s cannot be cached, or NULL */
static const char *not_cacheable(const pm_scene_t *s)
{
    if (s->uncacheable)
        return "its meshes' import reads files pmtk cannot name (only OBJ, PLY, OFF and STL scenes are cached), or a "
               "path holds a control byte";
    if (!header_safe(s->path))
        return "its path holds a control byte";
    for (size_t i = 0; i < s->nsources; i++)
        if (!header_safe(s->sources[i].path))
            return "the path of a file it reads holds a control byte";
    return NULL;
}

pm_result_t pm_scene_cache_write(const pm_scene_t *s, const char *cache)
{
    char file[PATH_MAX + 64];
    const char *path = cache_file(cache, s->path, file, sizeof file);
    const char *no = not_cacheable(s);
    if (no)
        return pm_error_set(PM_ERR_USAGE, "scene '%s' is not cached: %s", s->path, no);
    unsigned char *bytes;
    size_t n;
    pm_result_t r = pm_scene_cache_encode(s, &bytes, &n);
    if (r == PM_OK)
        r = write_bytes(path, bytes, n);
    free(bytes);
    return r;
}

/* ---- reading ---- */

typedef struct {
    const unsigned char *p;
    size_t n, at;
    int bad;
} rd_t;

/* The next array into a new block (NULL for none); *n_out its bytes. An array longer than
 * what is left marks the reader bad. */
static void *get_array(rd_t *r, size_t *n_out)
{
    uint64_t len = 0;
    *n_out = 0;
    if (r->bad || r->n - r->at < sizeof len) {
        r->bad = 1;
        return NULL;
    }
    memcpy(&len, r->p + r->at, sizeof len);
    r->at += sizeof len;
    if (len > r->n - r->at) {
        r->bad = 1;
        return NULL;
    }
    if (!len)
        return NULL;
    void *q = malloc((size_t)len);
    if (!q) {
        r->bad = 2;
        return NULL;
    }
    memcpy(q, r->p + r->at, (size_t)len);
    r->at += (size_t)len;
    *n_out = (size_t)len;
    return q;
}

/* An array that must hold exactly want bytes (or be absent when may_be_null and it is empty). */
static void *get_exact(rd_t *r, size_t want, int may_be_null)
{
    size_t n;
    void *q = get_array(r, &n);
    if (r->bad)
        return q;
    if (n != want && !(may_be_null && n == 0))
        r->bad = 1;
    return q;
}

static int terminated(const char *s, size_t cap) { return memchr(s, '\0', cap) != NULL; }

/* 1 when every value of m is in the range material.h gives it (what the loader made holds; a
 * damaged file's may not, and the tracers take them as given) */
static int material_sane(const pm_material_t *m)
{
    const float *unit[] = {m->kd, m->ks, m->kr, m->tf, m->f0};
    for (size_t i = 0; i < sizeof unit / sizeof *unit; i++)
        for (int k = 0; k < 3; k++)
            if (!(unit[i][k] >= 0.0f && unit[i][k] <= 1.0f))
                return 0;
    for (int k = 0; k < 3; k++)
        if (!(m->ke[k] >= 0.0f && isfinite(m->ke[k])) || !(m->eta[k] >= 0.0f && isfinite(m->eta[k])) ||
            !(m->k[k] >= 0.0f && isfinite(m->k[k])))
            return 0;
    return m->kind >= PM_MAT_STANDARD && m->kind <= PM_MAT_PLASTIC && m->ns >= 0.0f && isfinite(m->ns) &&
           m->ior >= 0.0f && isfinite(m->ior) /* 0: a kind that has none (the default grey) */ && m->alpha >= 0.0f &&
           m->alpha <= 1.0f && terminated(m->name, sizeof m->name);
}

/* The payload's indices within what they index, names ended: 1 when the scene is whole. */
static int scene_consistent(const pm_scene_t *s)
{
    if (!terminated(s->name, sizeof s->name) || !terminated(s->path, sizeof s->path))
        return 0;
    for (size_t i = 0; i < 3 * s->ntris; i++)
        if (s->tris[i] >= s->nverts)
            return 0;
    for (size_t i = 0; i < s->ntris; i++)
        if (s->tri_material[i] >= s->nmaterials)
            return 0;
    for (size_t i = 0; i < s->nemissive; i++)
        if (s->emissive[i] >= s->ntris)
            return 0;
    for (size_t i = 0; i < s->nmaterials; i++)
        if (!material_sane(&s->materials[i]))
            return 0;
    for (size_t i = 0; i < 3 * s->nverts; i++)
        if (!isfinite(s->verts[i]))
            return 0;
    for (size_t i = 0; s->maps && i < s->nmaterials; i++) {
        int32_t *slot[PM_MAP_SLOTS];
        pm_material_map_slots(&s->maps[i], slot);
        for (int k = 0; k < PM_MAP_SLOTS; k++)
            if (*slot[k] < -1 || *slot[k] >= (int64_t)s->ntextures)
                return 0;
    }
    for (size_t i = 0; i < s->nunsupported; i++)
        if (s->unsupported[i].material >= s->nmaterials ||
            !terminated(s->unsupported[i].key, sizeof s->unsupported[i].key) ||
            !terminated(s->unsupported[i].value, sizeof s->unsupported[i].value) ||
            !terminated(s->unsupported[i].note, sizeof s->unsupported[i].note))
            return 0;
    for (size_t i = 0; i < s->nnotes; i++)
        if (!terminated(s->notes[i].text, sizeof s->notes[i].text))
            return 0;
    for (size_t i = 0; i < s->nsources; i++)
        if (!terminated(s->sources[i].path, sizeof s->sources[i].path))
            return 0;
    for (size_t i = 0; i < s->ntextures; i++)
        if (!terminated(s->textures[i].path, sizeof s->textures[i].path))
            return 0;
    for (size_t i = 0; i < s->nplacements; i++) {
        const pm_placement_t *p = &s->placements[i];
        if ((uint64_t)p->tri0 + p->ntris > s->ntris || (uint64_t)p->vert0 + p->nverts > s->nverts || p->proto < -1 ||
            p->proto >= (int64_t)s->nplacements)
            return 0;
        /* an instance's prototype is its own, of the same size (render/rt.c builds it once) */
        const pm_placement_t *q = p->proto >= 0 ? &s->placements[p->proto] : NULL;
        if (q && (q->proto != p->proto || q->ntris != p->ntris || q->nverts != p->nverts))
            return 0;
        for (size_t t = 3 * (size_t)p->tri0; t < 3 * ((size_t)p->tri0 + p->ntris); t++)
            if (s->tris[t] < p->vert0 || s->tris[t] - p->vert0 >= p->nverts)
                return 0; /* a placement's triangles name its own vertices */
    }
    return 1;
}

/* The payload into *s (zeroed first); 0 on a damaged payload, -1 out of memory. */
static int get_scene(rd_t *r, pm_scene_t *s)
{
    if (r->n - r->at < sizeof *s)
        return 0;
    memcpy(s, r->p + r->at, sizeof *s);
    r->at += sizeof *s;
    clear_pointers(s); /* before anything can fail: pm_scene_free frees only what was read */
    size_t ntextures = s->ntextures;
    /* counts bounded before they are multiplied: each array's bytes are checked against them */
    const size_t lim = PM_SCENE_MAX_TRIS; /* 32-bit indices and Embree's primitive IDs */
    if (s->nverts > lim || s->ntris > lim || s->nmaterials > lim || s->nlights > lim || s->nportals > lim ||
        s->nemissive > lim || s->nunsupported > lim || s->nplacements > lim || s->nnotes > lim || s->nsources > lim ||
        ntextures > lim) {
        memset(s, 0, sizeof *s);
        return 0;
    }
    s->ntextures = 0; /* counted up as they are read, so that a failure frees only those */
    s->verts = get_exact(r, 3 * s->nverts * sizeof(float), 0);
    s->tris = get_exact(r, 3 * s->ntris * sizeof(uint32_t), 0);
    s->tri_material = get_exact(r, s->ntris * sizeof(uint32_t), 0);
    s->materials = get_exact(r, s->nmaterials * sizeof *s->materials, 0);
    s->lights = get_exact(r, s->nlights * sizeof *s->lights, 0);
    s->portals = get_exact(r, s->nportals * sizeof *s->portals, 0);
    s->emissive = get_exact(r, s->nemissive * sizeof *s->emissive, 0);
    s->unsupported = get_exact(r, s->nunsupported * sizeof *s->unsupported, 0);
    s->maps = get_exact(r, s->nmaterials * sizeof *s->maps, 1);
    s->uvs = get_exact(r, 2 * s->nverts * sizeof(float), 1);
    s->normals = get_exact(r, 3 * s->nverts * sizeof(float), 1);
    s->placements = get_exact(r, s->nplacements * sizeof *s->placements, 0);
    size_t nlocal_bytes;
    s->local_verts = get_array(r, &nlocal_bytes);
    s->notes = get_exact(r, s->nnotes * sizeof *s->notes, 0);
    s->sources = get_exact(r, s->nsources * sizeof *s->sources, 0);
    if (!r->bad && ntextures > (r->n - r->at) / sizeof *s->textures)
        r->bad = 1; /* more textures than bytes left for their structs: no allocation on its word */
    if (!r->bad && ntextures && !(s->textures = calloc(ntextures, sizeof *s->textures)))
        r->bad = 2;
    for (size_t i = 0; !r->bad && i < ntextures; i++) {
        pm_texture_t *t = &s->textures[i];
        if (r->n - r->at < sizeof *t) {
            r->bad = 1;
            break;
        }
        memcpy(t, r->p + r->at, sizeof *t);
        r->at += sizeof *t;
        t->u8 = NULL, t->f32 = NULL;
        s->ntextures++;
        if (t->w < 1 || t->h < 1 || t->w > PM_TEXTURE_MAX_SIDE || t->h > PM_TEXTURE_MAX_SIDE) {
            r->bad = 1;
            break;
        }
        size_t n = (size_t)t->w * t->h * 4, nu8, nf;
        t->u8 = get_array(r, &nu8);
        t->f32 = get_array(r, &nf);
        if (!r->bad && !((nu8 == n && nf == 0) || (nu8 == 0 && nf == n * sizeof(float))))
            r->bad = 1;
    }
    size_t ne;
    pm_envmap_t *e = r->bad ? NULL : get_array(r, &ne);
    if (e && ne != sizeof *e) { /* not a map's struct: nothing of it is read */
        free(e);
        e = NULL;
        r->bad = 1;
    }
    if (e) {
        s->envmap = e;
        e->rgb = NULL, e->row_cdf = NULL, e->col_cdf = NULL, e->pix_p = NULL;
        size_t n = (size_t)e->w * e->h;
        if (e->w < 1 || e->h < 1 || e->w > (1u << 20) || e->h > (1u << 20)) {
            r->bad = 1;
        } else {
            e->rgb = get_exact(r, 3 * n * sizeof(float), 0);
            e->row_cdf = get_exact(r, e->h * sizeof(double), 0);
            e->col_cdf = get_exact(r, n * sizeof(double), 0);
            e->pix_p = get_exact(r, n * sizeof(double), 0);
        }
    } else {
        s->envmap = NULL;
    }
    int ok = !r->bad && r->at == r->n && nlocal_bytes % (3 * sizeof(float)) == 0;
    for (size_t i = 0; ok && i < s->nplacements; i++)
        ok = s->placements[i].proto != (int32_t)i ||
             ((uint64_t)s->placements[i].local0 + s->placements[i].nverts) * 3 * sizeof(float) <= nlocal_bytes;
    /* the arrays the loader always makes, even empty (pm_scene_load's malloc of at least one) */
    if (ok && !s->emissive && !(s->emissive = malloc(sizeof *s->emissive)))
        r->bad = 2;
    ok = ok && !r->bad && scene_consistent(s);
    if (ok && s->ntextures)
        pm_texture_prepare();
    int nomem = r->bad == 2;
    if (!ok)
        pm_scene_free(s);
    return ok ? 1 : nomem ? -1 : 0;
}

/* The header's value of key (the first line of it) into out; 0 when absent. */
static int header_value(const char *head, const char *key, char *out, size_t cap)
{
    size_t kn = strlen(key);
    for (const char *line = head; *line && *line != '\n';) {
        const char *eol = strchr(line, '\n');
        if (!eol)
            return 0;
        if ((size_t)(eol - line) > kn && !strncmp(line, key, kn) && line[kn] == '=') {
            snprintf(out, cap, "%.*s", (int)(eol - line - (ptrdiff_t)kn - 1), line + kn + 1);
            return 1;
        }
        line = eol + 1;
    }
    return 0;
}

/* 1 when every SOURCE line names a file that is still the bytes it was (or still absent); else 0
 * with why saying which one changed. */
static int sources_unchanged(const char *head, char *why, size_t cap)
{
    for (const char *line = head; *line && *line != '\n';) {
        const char *eol = strchr(line, '\n');
        if (!eol)
            return 0;
        if (!strncmp(line, "SOURCE=", 7)) {
            char v[1400];
            snprintf(v, sizeof v, "%.*s", (int)(eol - line - 7), line + 7);
            char *sp = strchr(v, ' ');
            if (!sp) {
                snprintf(why, cap, "damaged (a SOURCE line without a path)");
                return 0;
            }
            *sp = '\0';
            const char *path = sp + 1;
            uint64_t h;
            int now = pm_scene_source_now(path, &h);
            char was[40];
            snprintf(was, sizeof was, "xxh3:%016" PRIx64, h);
            if (!strcmp(v, "absent") ? now != 0 : now != 1 || strcmp(was, v)) {
                snprintf(why, cap,
                         now == 1 && strcmp(v, "absent") ? "'%s' has changed"
                         : now == 1                      ? "'%s' has appeared since"
                                                         : "'%s' is gone or unreadable",
                         path);
                return 0;
            }
        }
        line = eol + 1;
    }
    return 1;
}

/* The cache's bytes data (n, the trailer included; changed in place, not freed) into *out: with
 * check_key, only when its key is scene_path's now (above); without (bytes a guarded load made
 * just now), whatever scene they hold. st as pm_scene_cache_read's. */
static pm_result_t decode(unsigned char *data, size_t n, const char *scene_path, int check_key, pm_scene_t *out,
                          pm_scene_cache_status_t *st)
{
    const size_t magic = strlen(MAGIC);
    uint64_t h = 0;
    if (n >= magic + 1 + sizeof h)
        memcpy(&h, data + n - sizeof h, sizeof h);
    if (n < magic + 1 + sizeof h || memcmp(data, MAGIC, magic) || pm_hash_bytes(data, n - sizeof h) != h) {
        snprintf(st->why, sizeof st->why, "damaged (not a scene cache, cut short, or its checksum wrong)");
        return PM_OK;
    }
    n -= sizeof h;
    /* the header: up to the first empty line */
    char *head = (char *)data + magic, *end = NULL;
    for (size_t i = magic; i + 1 < n && i < HEADER_MAX; i++)
        if (data[i] == '\n' && data[i + 1] == '\n') {
            end = (char *)data + i + 1;
            break;
        }
    char v[PATH_MAX + 64], want[PATH_MAX + 64];
    if (!end) {
        snprintf(st->why, sizeof st->why, "damaged (no end of its header)");
        return PM_OK;
    }
    char saved = *end;
    *end = '\0'; /* the header alone, as text: the empty line's \n becomes its end */
    const char *miss = NULL;
    if (!header_value(head, "FORMAT", v, sizeof v) || strcmp(v, "scene-cache") ||
        !header_value(head, "VERSION", v, sizeof v) || strcmp(v, FORMAT_VERSION))
        miss = "of another format version";
    else if (!header_value(head, "BUILD", v, sizeof v) || strcmp(v, PM_SCENE_CACHE_BUILD))
        miss = "made by another build of pmtk";
    else if (libs_text(want, sizeof want), !header_value(head, "LIBS", v, sizeof v) || strcmp(v, want))
        miss = "made with other versions of the libraries that load scenes";
    else if (check_key && (!header_value(head, "PATH", v, sizeof v) || strcmp(v, scene_path)))
        miss = "of another scene path";
    if (!miss && check_key) {
        cwd_for(scene_path, want, sizeof want);
        if ((header_value(head, "CWD", v, sizeof v) ? strcmp(v, want) : want[0] != '\0'))
            miss = "made in another working directory";
    }
    if (!miss && check_key) {
        limits_text(want, sizeof want);
        if (!header_value(head, "LIMITS", v, sizeof v) || strcmp(v, want))
            miss = "made under other PMTK_IMPORT_SECONDS or PMTK_IMPORT_MB";
    }
    if (miss) {
        snprintf(st->why, sizeof st->why, "%s", miss);
        return PM_OK;
    }
    if (check_key && !sources_unchanged(head, st->why, sizeof st->why))
        return PM_OK;
    *end = saved;
    rd_t r = {data, n, (size_t)(end - (char *)data) + 1, 0};
    int got = get_scene(&r, out);
    if (got < 0)
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading the scene cache of '%s'", scene_path);
    if (!got) {
        snprintf(st->why, sizeof st->why, "damaged (its payload does not hold together)");
        return PM_OK;
    }
    if (check_key)
        snprintf(out->path, sizeof out->path, "%s", scene_path);
    st->hit = 1;
    return PM_OK;
}

pm_result_t pm_scene_cache_decode(unsigned char *bytes, size_t n, pm_scene_t *out, pm_scene_cache_status_t *st)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    return decode(bytes, n, "", 0, out, st);
}

pm_result_t pm_scene_cache_read(const char *cache, const char *scene_path, pm_scene_t *out, pm_scene_cache_status_t *st)
{
    char file[PATH_MAX + 64];
    const char *path = cache_file(cache, scene_path, file, sizeof file);
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    /* O_NONBLOCK: a FIFO named as the cache opens at once (and is then no regular file) */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    FILE *f = fd >= 0 ? fdopen(fd, "rb") : NULL;
    if (!f) {
        snprintf(st->why, sizeof st->why, "%s", errno == ENOENT ? "absent" : strerror(errno));
        if (fd >= 0)
            close(fd);
        return PM_OK;
    }
    struct stat sb;
    unsigned char *data = NULL;
    size_t n = 0;
    if (fstat(fileno(f), &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0 &&
        (uint64_t)sb.st_size < ((uint64_t)1 << 40)) {
        n = (size_t)sb.st_size;
        data = malloc(n);
        if (!data) {
            fclose(f);
            return pm_error_set(PM_ERR_NOMEM, "out of memory reading the scene cache '%s' (%zu bytes)", path, n);
        }
        if (fread(data, 1, n, f) != n)
            n = 0;
    }
    fclose(f);
    pm_result_t r = decode(data, n, scene_path, 1, out, st);
    free(data);
    return r;
}

/* The scene from its files, once: in a guarded child (render/mesh_guard.c) whose bytes are
 * decoded here and kept in *bytes_out (NULL when the import limits are off and it was loaded
 * in this process); keyed as pm_scene_load_files. */
static pm_result_t load_once(const char *scene_path, int keyed, pm_scene_t *out, unsigned char **bytes_out,
                             size_t *n_out)
{
    int unguarded = 0;
    pm_result_t r = pm_scene_load_guarded(scene_path, keyed, bytes_out, n_out, &unguarded);
    if (r != PM_OK)
        return r;
    if (unguarded)
        return pm_scene_load_files(scene_path, keyed, out);
    pm_scene_cache_status_t fresh;
    if ((r = pm_scene_cache_decode(*bytes_out, *n_out, out, &fresh)) == PM_OK && !fresh.hit)
        r = pm_error_set(PM_ERR_INTERNAL, "scene '%s': the guarded load's scene is %s", scene_path, fresh.why);
    if (r != PM_OK) {
        free(*bytes_out);
        *bytes_out = NULL;
        return r;
    }
    snprintf(out->path, sizeof out->path, "%s", scene_path);
    return PM_OK;
}

pm_result_t pm_scene_load_cached(const char *scene_path, const char *cache, int write_now, pm_scene_t *out,
                                 pm_scene_cache_status_t *st)
{
    pm_scene_cache_status_t own;
    if (!st)
        st = &own;
    memset(st, 0, sizeof *st);
    unsigned char *bytes = NULL;
    size_t n = 0;
    pm_result_t r;
    int keyed = cache && cache[0];
    if (keyed && ((r = pm_scene_cache_read(cache, scene_path, out, st)) != PM_OK || st->hit))
        return r;
    char why[sizeof st->why];
    snprintf(why, sizeof why, "%s", st->why);
    if ((r = load_once(scene_path, keyed, out, &bytes, &n)) != PM_OK || !keyed || !write_now) {
        free(bytes);
        return r;
    }
    /* the bytes the child made are the file (decode changed none of them) */
    const char *no = not_cacheable(out);
    char file[PATH_MAX + 64];
    r = no      ? PM_ERR_USAGE
        : bytes ? write_bytes(cache_file(cache, scene_path, file, sizeof file), bytes, n)
                : pm_scene_cache_write(out, cache);
    free(bytes);
    if (r == PM_OK)
        st->written = 1;
    else if (!no)
        snprintf(st->why, sizeof st->why, "%s; not written: %s", why, pm_error_message());
    return PM_OK;
}

pm_result_t pm_scene_load(const char *path, pm_scene_t *out)
{
    return pm_scene_load_cached(path, getenv("PMTK_SCENE_CACHE"), 1, out, NULL);
}
