/* mtl.c: what a material sets and pmtk does not honour, reported once per material and key
 * (docs/scene-format.md, "What the loader reads and what it honours"): assimp's properties, and
 * the lines of an OBJ's .mtl files that assimp drops, read from the files themselves. */
#include "render/scene.h"

#include <assimp/material.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "render/scene_load.h"

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
        pm_scene_resolve(obj, name, path, cap);
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

/* What each_mtl_line calls for every line of an .mtl that has a word and is no comment: the
 * library's path, the line's number, its first word and the rest. Non-OK stops the walk. */
typedef pm_result_t (*mtl_line_fn)(void *ctx, const char *path, uint64_t lineno, const char *word, const char *rest);

/* Walks the lines of the .mtl files an OBJ names (libs as check_obj_materials lists them; one
 * that cannot be opened is left to assimp, which has said so already). */
static pm_result_t each_mtl_line(const char *obj, const char *libs, mtl_line_fn fn, void *ctx)
{
    pm_result_t r = PM_OK;
    char path[1200];
    const char *lib = libs;
    for (FILE *f; r == PM_OK && (f = next_mtl(obj, &lib, path, sizeof path));) {
        char *line = NULL, word[64];
        size_t cap = 0;
        for (uint64_t lineno = 1; r == PM_OK && mtl_getline(&line, &cap, f) >= 0; lineno++) {
            const char *rest = pm_scene_obj_word(line, word, sizeof word);
            if (word[0] && word[0] != '#')
                r = fn(ctx, path, lineno, word, rest);
        }
        free(line);
        fclose(f);
    }
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
pm_result_t pm_scene_note_unsupported(pm_scene_t *s, uint32_t m, const char *key, int is_file, const char *value)
{
    for (size_t i = 0; i < s->nunsupported; i++)
        if (s->unsupported[i].material == m && strcmp(s->unsupported[i].key, key) == 0)
            return PM_OK;
    pm_result_t r = pm_scene_grow((void **)&s->unsupported, s->nunsupported + 1, sizeof *s->unsupported);
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
    int pbr = pm_scene_pbr_inputs(is_obj, am, &metallic, &roughness);
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
pm_result_t pm_scene_scan_material(pm_scene_t *s, int is_obj, const struct aiMaterial *am, uint32_t m)
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
            /* Honoured (load_material_maps): MTL map_Kd, map_Ks, map_d, norm, bump; the base colour and
             * the normal texture elsewhere. */
            if (sem == aiTextureType_DIFFUSE || sem == aiTextureType_NORMALS ||
                (is_obj &&
                 (sem == aiTextureType_SPECULAR || sem == aiTextureType_OPACITY || sem == aiTextureType_HEIGHT)))
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
            r = pm_scene_note_unsupported(s, m, name, 1, value);
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
            r = pm_scene_note_unsupported(s, m, is_obj ? "Pm" : "metallicFactor", 0, value);
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
            r = pm_scene_note_unsupported(s, m, name, 0, value);
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

typedef struct {
    pm_scene_t *s;
    size_t mat0, n;
    const unsigned char *pbr;
    uint32_t current; /* the material the lines belong to, none (UINT32_MAX) before newmtl */
} scan_ctx_t;

static pm_result_t scan_line(void *ctx, const char *path, uint64_t lineno, const char *word, const char *rest)
{
    scan_ctx_t *x = ctx;
    pm_scene_t *s = x->s;
    (void)path, (void)lineno;
    if (strcmp(word, "newmtl") == 0) {
        char mname[sizeof s->materials[0].name]; /* named as load_material names it */
        snprintf(mname, sizeof mname, "%s", rest);
        pm_scene_material_word(mname);
        x->current = UINT32_MAX;
        for (size_t m = x->mat0; m < x->mat0 + x->n && x->current == UINT32_MAX; m++)
            if (strcmp(s->materials[m].name, mname) == 0)
                x->current = (uint32_t)m;
        return PM_OK;
    }
    uint32_t current = x->current;
    if (current == UINT32_MAX)
        return PM_OK;
    if (!mtl_key_exposed(word))
        return pm_scene_note_unsupported(s, current, word, 0, rest);
    if (rest[0] == '-' && (strcmp(word, "map_Kd") == 0 || strcmp(word, "map_Ks") == 0 || strcmp(word, "map_d") == 0)) {
        /* a texture pmtk reads, with options it does not (-clamp, -o, -s, -imfchan, ...;
         * assimp drops most without a word): the texture is used as if they were absent */
        char key[64];
        snprintf(key, sizeof key, "%s options", word);
        return pm_scene_note_unsupported(s, current, key, 0, rest);
    }
    if (unused_colour(&s->materials[current], x->pbr[current - x->mat0], word, rest))
        return pm_scene_note_unsupported(s, current, word, 0, rest);
    return PM_OK;
}

/* Reads the .mtl files an OBJ names (libs: one a line, relative to the OBJ) for the keys assimp
 * drops, and notes each against the material of this mesh (materials mat0 to mat0 + n - 1) its
 * newmtl names; pbr[i] is 1 when material mat0 + i has a Pr or a Pm. */
pm_result_t pm_scene_scan_mtl_dropped(pm_scene_t *s, const char *obj, const char *libs, size_t mat0, size_t n,
                                      const unsigned char *pbr)
{
    scan_ctx_t x = {s, mat0, n, pbr, UINT32_MAX};
    return each_mtl_line(obj, libs, scan_line, &x);
}

static pm_result_t home_line(void *ctx, const char *path, uint64_t lineno, const char *word, const char *rest)
{
    import_t *im = ctx;
    (void)lineno;
    if (strcmp(word, "newmtl") != 0)
        return PM_OK;
    char mname[sizeof im->homes[0].name];
    snprintf(mname, sizeof mname, "%s", rest);
    pm_scene_material_word(mname);
    for (size_t i = 0; i < im->nhomes; i++)
        if (strcmp(im->homes[i].name, mname) == 0)
            return PM_OK;
    pm_result_t r = pm_scene_grow((void **)&im->homes, im->nhomes + 1, sizeof *im->homes);
    if (r != PM_OK)
        return r;
    mtl_home_t *h = &im->homes[im->nhomes++];
    snprintf(h->name, sizeof h->name, "%s", mname);
    snprintf(h->lib, sizeof h->lib, "%s", path);
    return PM_OK;
}

/* Reads the .mtl files an OBJ names (libs as check_obj_materials lists them), each once, into
 * im->homes: every material name they define and the first library defining it. */
pm_result_t pm_scene_mtl_homes(const char *obj, const char *libs, import_t *im)
{
    return each_mtl_line(obj, libs, home_line, im);
}

/* The MTL keys whose values are numbers (assimp reads them with fast_atof, which takes "0.5,"
 * as 0.5, "0x1p-1" as 0 and "inf" as a number), and among them the colours, whose g and b
 * default to r when only r is given (assimp 5.2 leaves them 0: Kd 0.5 was red). */
static const struct {
    const char *word, *ai_key; /* as MTL names it; assimp's colour key, NULL for a scalar */
} mtl_numbers[] = {
    {"Ka", "$clr.ambient"},
    {"Kd", "$clr.diffuse"},
    {"Ks", "$clr.specular"},
    {"Ke", "$clr.emissive"},
    {"Tf", "$clr.transparent"},
    {"Ns", NULL},
    {"Ni", NULL},
    {"d", NULL},
    {"Tr", NULL},
    {"Pr", NULL},
    {"Pm", NULL},
    {"Ps", NULL},
    {"Pc", NULL},
    {"Pcr", NULL},
    {"aniso", NULL},
    {"illum", NULL},
};

/* Whether token t (len bytes) is a plain finite decimal number: digits, one point, an exponent;
 * no comma, no hex float, no inf or nan. */
static int mtl_plain_number(const char *t, size_t len, double *out)
{
    char buf[64];
    if (len == 0 || len >= sizeof buf)
        return 0;
    memcpy(buf, t, len);
    buf[len] = '\0';
    for (size_t i = 0; i < len; i++)
        if (!strchr("0123456789+-.eE", buf[i]))
            return 0;
    char *end;
    double v = strtod(buf, &end);
    if (*end || end == buf || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

/* The assimp material of as that newmtl line rest defines, or NULL. */
static struct aiMaterial *mtl_material(const struct aiScene *as, const char *rest)
{
    for (unsigned i = 0; i < as->mNumMaterials; i++) {
        struct aiString an;
        if (aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &an) == aiReturn_SUCCESS &&
            strcmp(an.data, rest) == 0)
            return as->mMaterials[i];
    }
    return NULL;
}

/* Reads the .mtl files an OBJ names (libs as check_obj_materials lists them) for the values assimp
 * reads wrong without a word: a number key's values must be one or three plain decimal numbers
 * (a comma, a hex float, inf or nan is an error naming the file, line and value); a colour given
 * as one number is grey (assimp's material as is changed so: g and b take r); a texture line of
 * 1024 bytes or more (assimp's aiString drops it) is an error. */
typedef struct {
    const char *obj;
    const struct aiScene *as;
    struct aiMaterial *cur; /* the material of newmtl's lines, NULL before one (or one assimp lacks) */
} check_ctx_t;

static pm_result_t check_line(void *ctx, const char *path, uint64_t lineno, const char *word, const char *rest)
{
    check_ctx_t *x = ctx;
    const char *obj = x->obj;
    if (strcmp(word, "newmtl") == 0) {
        x->cur = mtl_material(x->as, rest);
        return PM_OK;
    }
    if (strncmp(word, "map_", 4) == 0 || !strcmp(word, "bump") || !strcmp(word, "norm") || !strcmp(word, "disp") ||
        !strcmp(word, "refl")) {
        if (strlen(rest) >= 1024)
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': '%s' line %" PRIu64 ": %s path of %zu bytes, beyond the 1023 assimp keeps",
                                obj, path, lineno, word, strlen(rest));
        return PM_OK;
    }
    size_t k = 0, nk = sizeof mtl_numbers / sizeof *mtl_numbers;
    while (k < nk && strcasecmp(mtl_numbers[k].word, word) != 0)
        k++;
    if (k == nk || !strncmp(rest, "spectral", 8) || !strncmp(rest, "xyz", 3))
        return PM_OK; /* not a number key; or Kd spectral / xyz, reported as it is */
    const char *colour = mtl_numbers[k].ai_key;
    double v[4];
    int n = 0;
    for (const char *t = rest; *t; n++) {
        size_t tl = strcspn(t, " \t");
        if (n == 4 || !mtl_plain_number(t, tl, &v[n]))
            return pm_error_set(PM_ERR_INPUT,
                                "mesh '%s': '%s' line %" PRIu64 ": %s '%s' is not %s plain decimal number%s (no "
                                "commas, hex floats, inf or nan)",
                                obj, path, lineno, word, rest, colour ? "one or three" : "a", colour ? "s" : "");
        t += tl;
        t += strspn(t, " \t");
    }
    if (n == 0 || n == 2 || n > 3 || (!colour && n != 1))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': '%s' line %" PRIu64 ": %s '%s' has %d values, expected %s", obj,
                            path, lineno, word, rest, n, colour ? "1 or 3" : "1");
    /* One value of a colour: grey. The import is this loader's own (aiImportFile's result). */
    struct aiMaterialProperty *p = NULL;
    if (n == 1 && colour && x->cur &&
        aiGetMaterialProperty(x->cur, colour, 0, 0, (const struct aiMaterialProperty **)&p) == aiReturn_SUCCESS &&
        p->mType == aiPTI_Float && p->mDataLength >= 3 * sizeof(float)) {
        float *c = (float *)(void *)p->mData;
        c[1] = c[2] = c[0];
    }
    return PM_OK;
}

pm_result_t pm_scene_mtl_check(const char *obj, const char *libs, const struct aiScene *as)
{
    check_ctx_t x = {obj, as, NULL};
    return each_mtl_line(obj, libs, check_line, &x);
}
