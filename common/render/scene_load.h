/* scene_load.h: what the files of the scene reader share (scene.c, scene_json.c, mesh.c,
 * scene_material.c, mtl.c, scene_maps.c, scene_hash.c): limits, the loader's state and its
 * internal functions. Not for use outside common/render's scene files. */
#ifndef PM_SCENE_LOAD_H
#define PM_SCENE_LOAD_H

#include <jansson.h>
#include <stddef.h>
#include <stdio.h>
#include <sys/types.h>

#include "render/scene.h"
#include "render/scene_cache.h"

struct aiMaterial;
struct aiScene;

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

/* Where an OBJ's material is defined: the first .mtl of its libraries (in mtllib order) with a
 * newmtl of that name, the folder its texture names are relative to. */
typedef struct {
    char name[64]; /* as load_material names it (material_word) */
    char lib[1200];
} mtl_home_t;

/* A mesh file imported once per scene, however many entries place it. */
typedef struct {
    char path[1200];
    const struct aiScene *as;
    char libs[4096];   /* its .mtl files, one a line (check_obj_materials) */
    mtl_home_t *homes; /* each material its .mtl files define, read once at import (mtl_homes) */
    size_t nhomes;
    int no_materials; /* an OBJ without any usemtl: its faces are the default grey */
} import_t;

/* A camera a mesh file carries, placed in the scene (scene_punctual.c). */
typedef struct {
    char name[128];                  /* its node's name */
    float eye[3], look_at[3], up[3]; /* m */
    float hfov;                      /* radians, assimp's horizontal angle (see scene_punctual.c) */
    float aspect;                    /* width / height; 0: not given */
    int gltf, ortho;
} pm_asset_camera_t;

typedef struct {
    const char *file; /* the scene file, for messages */
    pm_scene_t *s;
    int missing_magenta; /* missing_textures "magenta": a missing texture file is a warning */
    import_t *imports;   /* the mesh files imported so far */
    size_t nimports;
    float *local;              /* every vertex loaded, in its mesh's own units (placements share them) */
    int any_normals;           /* some mesh loaded has vertex normals */
    pm_material_t *smats;      /* the scene file's materials section, in file order (scene_assets.c) */
    pm_material_maps_t *smaps; /* their textures */
    size_t nsmats;
    int64_t camera_mesh;      /* camera.mesh: the entry whose file's cameras are read; -1: none */
    pm_asset_camera_t *acams; /* that file's cameras */
    size_t nacams;
    pm_point_light_t *alights; /* the glTF point lights and spots of entries with "lights": true */
    size_t nalights;
    int has_asun; /* a glTF directional light, as the sun asun */
    pm_sun_t asun;
    /* MiB (image_budgets): one texture's texels, all textures' together, the sky map with its
     * tables; 0 until pm_scene_load_image_budgets sets them */
    double texture_mib, textures_mib, sky_map_mib;
} ctx_t;

/* ---- scene_json.c: the scene file's keys. Every error names the scene file, the key path and
 * the value, through pm_scene_bad. */
pm_result_t pm_scene_bad(const ctx_t *c, const char *key, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* Unknown keys of obj are errors listing the known ones (a typo must not fall back to a default). */
pm_result_t pm_scene_only_keys(const ctx_t *c, json_t *obj, const char *where, const char *const *allowed);
/* obj's member name, a finite number in [lo, hi] (an integer; 3 numbers), into *out; left alone when
 * it is absent and not required. path names it in errors. */
pm_result_t pm_scene_get_number(const ctx_t *c, json_t *obj, const char *name, const char *path, int required,
                                double lo, double hi, double *out);
pm_result_t pm_scene_get_int(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, int64_t lo,
                             int64_t hi, int64_t *out);
pm_result_t pm_scene_get_vec3(const ctx_t *c, json_t *obj, const char *name, const char *path, int required, double lo,
                              double hi, float out[3]);
pm_result_t pm_scene_load_camera(const ctx_t *c, json_t *cam);
pm_result_t pm_scene_load_lights(const ctx_t *c, json_t *lights);
pm_result_t pm_scene_load_sun_sky(const ctx_t *c, json_t *sun, json_t *sky);
pm_result_t pm_scene_load_defaults(const ctx_t *c, json_t *d);
/* The portals (after the sun and the sky): s->portals, portal_area and portal_power. */
pm_result_t pm_scene_load_portals(const ctx_t *c, json_t *portals);
/* Mesh entry mj's placement (scale, rotate, translate, matrix) as one affine map, rows of [3x3 | t]. */
pm_result_t pm_scene_load_transform(const ctx_t *c, json_t *mj, const char *where, double xf_out[3][4],
                                    int *general_out);
/* The determinant of m's 3 x 3 part. */
double pm_scene_det3(const double m[3][4]);

/* ---- scene.c: helpers every part uses. */
/* The scene loaded from its files, past any cache (pm_scene_load goes through the cache,
 * render/scene_cache.c). keyed: note every file read with its hash (s->sources), for a cache
 * to be written; 0: none (s->uncacheable). */
pm_result_t pm_scene_load_files(const char *path, int keyed, pm_scene_t *s);
/* path's state now, for a cache's key: 1 a regular file (its XXH3-64 in *hash_out), 0 absent,
 * -1 anything else (unreadable, not a regular file); *hash_out 0 unless 1. */
int pm_scene_source_now(const char *path, uint64_t *hash_out);
/* file resolved against the folder of scene_path (a file name, not a folder). */
void pm_scene_resolve(const char *scene_path, const char *file, char *out, size_t cap);
/* path noted among s->sources (once): its bytes hashed now, or absent when it does not exist;
 * any other failure to read it makes the scene uncacheable (its load fails on it or reads
 * it otherwise). */
pm_result_t pm_scene_add_source(pm_scene_t *s, const char *path);
/* *p reallocated to n (at least 1) elements of size; an out-of-memory error otherwise. */
pm_result_t pm_scene_grow(void **p, size_t n, size_t size);

/* ---- mesh.c: assimp imports. */
pm_result_t pm_scene_load_mesh(ctx_t *c, json_t *mj, size_t index);
void pm_scene_release_import(ctx_t *c, json_t *meshes, size_t i);
pm_result_t pm_scene_find_instances(ctx_t *c, int allowed, size_t *flattened_out);
/* The first word of an OBJ or MTL line into word (cut to cap), and where the rest begins. */
const char *pm_scene_obj_word(const char *line, char *word, size_t cap);

/* ---- scene_material.c: an assimp material into a pm_material_t. */
pm_result_t pm_scene_load_material(const ctx_t *c, const char *mesh, int is_obj, const struct aiMaterial *am,
                                   pm_material_t *m);
/* 1 when am is a metallic-roughness material (glTF; an MTL with Pr or Pm), and its two factors. */
int pm_scene_pbr_inputs(int is_obj, const struct aiMaterial *am, float *metallic_out, float *roughness_out);
/* A material name as pmtk keeps it: spaces and control characters become '_'. */
void pm_scene_material_word(char *name);

/* ---- mesh_guard.c: between an untrusted mesh file and assimp. */
/* The header of a PLY (by content or name), OFF or STL file checked against its size, before assimp
 * reads it (its readers crash, loop or over-allocate on damaged headers). */
pm_result_t pm_scene_mesh_precheck(const char *path);
/* The whole load of scene path (pm_scene_load_files) in a forked child under the same limits,
 * instead of a trial per mesh and the import again: the child sends the scene as the scene
 * cache's bytes (pm_scene_cache_encode) into *bytes_out (malloc'd, *n_out bytes), or its error,
 * which becomes this process's. A crash, a hang or a blow-up inside assimp is the trial's error
 * naming the mesh and the entry; elsewhere in the load, an error naming the scene. With both
 * limits 0: *unguarded_out 1 and nothing done. */
pm_result_t pm_scene_load_guarded(const char *path, int keyed, unsigned char **bytes_out, size_t *n_out,
                                  int *unguarded_out);
/* In a guarded load's child: the entry about to load (scene.c), the mesh file assimp is about
 * to import and the import that came back (mesh.c), and whether this process is such a child.
 * No-ops elsewhere. */
void pm_scene_guard_entry(const char *scene, size_t index);
void pm_scene_guard_importing(const char *path);
void pm_scene_guard_imported(void);
int pm_scene_guarded_child(void);
/* PMTK_IMPORT_MB as the guard reads it (MiB; 0 off). */
long pm_scene_import_mib(void);
/* The scene as the scene cache's bytes (render/scene_cache.c): header, payload, checksum. */
pm_result_t pm_scene_cache_encode(const pm_scene_t *s, unsigned char **out, size_t *n_out);
/* Those bytes (n, the trailer included) back into *out, whatever scene and files they name (a
 * guarded load's own, or a fuzzer's): the checksum, the format, the build and the payload's
 * coherence checked, st->hit 1 when they hold. The bytes are written into and put back. */
pm_result_t pm_scene_cache_decode(unsigned char *bytes, size_t n, pm_scene_t *out, pm_scene_cache_status_t *st);

/* The error for a file whose faces assimp dropped as naming vertices out of range: for glTF, the
 * first such face (mesh, primitive, face, vertex) read from the file itself. */
pm_result_t pm_scene_gltf_bad_face(const char *path);

/* ---- mtl.c: what a material sets and pmtk does not honour. */
pm_result_t pm_scene_scan_material(pm_scene_t *s, int is_obj, const struct aiMaterial *am, uint32_t m);
pm_result_t pm_scene_scan_mtl_dropped(pm_scene_t *s, const char *obj, const char *libs, size_t mat0, size_t n,
                                      const unsigned char *pbr);
pm_result_t pm_scene_mtl_homes(const char *obj, const char *libs, import_t *im);
/* The .mtl values assimp reads wrong: number syntax and counts, one-value colours (made grey in as),
 * texture lines too long for assimp (mtl.c). */
pm_result_t pm_scene_mtl_check(const char *obj, const char *libs, const struct aiScene *as);
pm_result_t pm_scene_note_unsupported(pm_scene_t *s, uint32_t m, const char *key, int is_file, const char *value);

/* ---- scene_maps.c: a material's textures. */
/* The scene's image_budgets (an object of texture_mib, textures_mib, sky_map_mib; b may be
 * NULL) into c's budgets, the defaults where a key is absent. */
pm_result_t pm_scene_load_image_budgets(ctx_t *c, json_t *b);
/* Texture file `name` (relative to the file base) as scene texture *index_out, loaded once per
 * scene; errors name mesh, material m and key. */
pm_result_t pm_scene_texture(const ctx_t *c, const char *base, const char *name, const char *mesh,
                             const pm_material_t *m, uint32_t mi, const char *key, int32_t *index_out);
pm_result_t pm_scene_load_material_maps(const ctx_t *c, const char *mesh, int is_obj, const import_t *im,
                                        const struct aiMaterial *am, uint32_t mi);

/* ---- scene_assets.c: the scene file's materials, overrides and shapes; the loader's notes. */
/* A note (warning 0) or a warning (1) of what the loader changed, kept in s->notes. */
pm_result_t pm_scene_add_note(pm_scene_t *s, int warning, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* The top-level "materials" object into c->smats (every entry checked, used or not). */
pm_result_t pm_scene_load_scene_materials(ctx_t *c, json_t *mats);
/* Mesh entry mj's "material", "materials" and "emission" applied to its materials [mat0, mat0 + n). */
pm_result_t pm_scene_apply_mesh_overrides(ctx_t *c, json_t *mj, const char *where, const char *mesh, size_t mat0,
                                          size_t n);
/* 1 when mesh entry mj replaces its asset's material `word` (as pm_scene_material_word makes it,
 * "default" for assimp's stand-in): a "material" for all, or a "materials" key naming it. */
int pm_scene_overridden(json_t *mj, const char *word);
/* The top-level "shapes" array tessellated into the scene, one placement each. */
pm_result_t pm_scene_load_shapes(ctx_t *c, json_t *shapes);

/* ---- scene_punctual.c: cameras and lights from a mesh file. */
/* Entry mj's file (path; mesh as the scene names it) read again for its cameras (when camera.mesh
 * is index) and its glTF lights ("lights": true), placed by xf; a note when it holds
 * nlights_seen lights the scene does not read. */
pm_result_t pm_scene_load_asset_extras(ctx_t *c, json_t *mj, const char *where, const char *path, const char *mesh,
                                       size_t index, const double xf[3][4], unsigned nlights_seen);
/* The scene camera from c->acams by camera.name or camera.index, with camera.width and height. */
pm_result_t pm_scene_asset_camera(const ctx_t *c, json_t *cam);
/* The assets' lights appended to the scene's point lights, and their sun made the scene's. */
pm_result_t pm_scene_add_asset_lights(ctx_t *c);

/* ---- scene_hash.c: the scene's identity. */
/* Sets s->hash and s->parts from what s holds (its file hashed again for the whole). */
pm_result_t pm_scene_identify(pm_scene_t *s);

#endif
