/* scene.h: the scene model every stage shares, loaded from a scene file
 * (docs/scene-format.md): triangle meshes (OBJ/MTL and whatever else assimp reads),
 * materials, point lights, emissive triangles as area lights, a pinhole camera and
 * render defaults. Units: metres, watts, W/sr for point-light intensity, W/(m^2 sr)
 * for emitted radiance. */
#ifndef PM_SCENE_H
#define PM_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "base/stage.h"
#include "formats/material.h"
#include "render/texture.h"

/* A point light, isotropic or a spot: intensity I s(theta) in the direction at angle theta
 * to the axis, with s = ((cos theta - cos_cone) / (1 - cos_cone))^falloff inside the cone and
 * 0 outside it (docs/scene-format.md). An isotropic light has cos_cone -1 and falloff 0 (s = 1
 * everywhere); its power is 4 pi I, a spot's 2 pi I (1 - cos_cone) / (falloff + 1). */
typedef struct {
    float position[3];  /* m */
    float intensity[3]; /* W/sr, RGB, on the axis */
    float axis[3];      /* unit, where a spot points; (0, 0, 0) for an isotropic light */
    float cos_cone;     /* cosine of the cone's half-angle, in [-1, 1) */
    float falloff;      /* exponent >= 0 of s, dimensionless */
} pm_point_light_t;

/* 1 when l is a spot (has a cone or a falloff), 0 for an isotropic point light. */
static inline int pm_point_light_is_spot(const pm_point_light_t *l)
{
    return l->cos_cone > -1.0f || l->falloff != 0.0f;
}

/* A sun: a disc of uniform radiance at infinity, seen under a cone of solid angle omega about
 * `direction`; lights every point from that cone (irradiance L pi sin^2(half-angle) cos on a
 * surface at angle cos to the direction, L omega cos for a small disc). */
typedef struct {
    float direction[3]; /* unit, from the scene toward the sun */
    float radiance[3];  /* W/(m^2 sr), RGB */
    float solid_angle;  /* sr, in (0, 2 pi] */
    float cos_max;      /* cosine of the cone's half-angle: 1 - omega / (2 pi) */
} pm_sun_t;

/* A portal (the scene key portals): a parallelogram through which alone the sun's and the sky's
 * photons enter the scene (render/light.c, env_emit). Points corner + a edge_u + b edge_v for a,
 * b in [0, 1]; the photons cross it toward `inward`, its front face (the rectangle's +z). */
typedef struct {
    float corner[3], edge_u[3], edge_v[3]; /* m */
    float inward[3];                       /* unit */
    double area;                           /* m^2 */
} pm_portal_t;

#define PM_SCENE_PORTALS_MAX 64

/* A lat-long environment map (the sky's `map`): pixel (x, y) of w x h covers the directions of
 * polar angle theta from +y in [pi y / h, pi (y + 1) / h) and azimuth phi in [2 pi x / w,
 * 2 pi (x + 1) / w), direction (sin theta cos phi, cos theta, sin theta sin phi); radiance is
 * constant over a pixel. Sampled by pixel in proportion to luminance times sin(theta) at the
 * pixel's centre (a row, then a column in it), then uniformly in (theta, phi) within it. */
typedef struct {
    uint32_t w, h;
    float *rgb;         /* w * h * 3, W/(m^2 sr), top row (theta 0) first, times sky.radiance */
    double *row_cdf;    /* h: cumulative probability of rows 0..y, the last 1 */
    double *col_cdf;    /* h * w: within each row, cumulative over columns 0..x, the last 1 */
    double *pix_p;      /* h * w: probability of each pixel */
    double integral[3]; /* W/m^2 per channel: the map's radiance integrated over the sphere */
    double total;       /* the sum of the weights; 0 when the map is black */
    /* The sky's frame (pm_sky_frame): rows are the map's x, y, z axes in world coordinates, so
     * that a world direction w is (frame[0..2] . w, frame[3..5] . w, frame[6..8] . w) in the
     * map; used only when framed is 1 (an identity frame leaves the map's arithmetic as it was). */
    int framed;
    double frame[9];
} pm_envmap_t;

/* Builds e's tables from rgb (w x h, owned by e from here, freed by pm_envmap_free); an
 * error on a value that is NaN, infinite or negative (named with its pixel and channel). */
pm_result_t pm_envmap_init(pm_envmap_t *e, uint32_t w, uint32_t h, float *rgb);
void pm_envmap_free(pm_envmap_t *e);
/* Bytes a map takes a pixel with its tables (what the sky_map budget counts), and the budget
 * when the scene sets none (image_budgets.sky_map_mib). */
#define PM_ENVMAP_BYTES_PER_PIXEL (3 * sizeof(float) + 3 * sizeof(double))
#define PM_ENVMAP_BUDGET_DEFAULT ((uint64_t)1024 << 20)
/* Reads the lat-long map path (OpenEXR or Radiance HDR, by content, through base/imgdecode.h),
 * each value times scale, into e (pm_envmap_init), taking at most max_bytes with its tables:
 * the declared size is checked before the pixels are allocated. Errors of reading name the
 * file; a bad value (pm_envmap_init) names its pixel only. */
pm_result_t pm_envmap_load(const char *path, uint64_t max_bytes, const float scale[3], pm_envmap_t *e);

/* The sky's frame (scene keys sky.up and sky.rotate, docs/scene-format.md): +y turned onto unit
 * vector up by the shortest turn (half a turn about +x when up is -y), then turned about up by
 * rotate_deg degrees the way azimuth grows (from +x toward +z when up is +y; clockwise seen
 * from up's tip). frame_out: rows are the turned x, y (= up), z axes in world coordinates. */
void pm_sky_frame(const double up[3], double rotate_deg, double frame_out[9]);
/* World direction of elevation el_deg above the horizon and azimuth az_deg in frame f: the
 * frame's (cos el cos az, sin el, cos el sin az); a map's pixel at longitude az_deg and
 * latitude el_deg looks along it. */
void pm_sky_frame_direction(const double f[9], double el_deg, double az_deg, double w_out[3]);
/* Uses frame f for map e (framed unless f is the identity). */
void pm_envmap_set_frame(pm_envmap_t *e, const double f[9]);

typedef struct {
    float eye[3], look_at[3], up[3]; /* m */
    float fov_y;                     /* degrees, vertical, in (0, 180) */
    uint32_t width, height;          /* pixels */
} pm_camera_t;

/* Render defaults a scene suggests; stages use them when their option is not given. */
typedef struct {
    int64_t photons;       /* photons emitted */
    int64_t spp;           /* secondary rays per pixel */
    int64_t primary;       /* primary rays per pixel */
    int64_t light_samples; /* area-light samples per primary hit */
    double radius;         /* m, fixed kernel width; 0 = choose from k */
    int64_t k;             /* photons per query the radius aims at */
    int64_t leaf;          /* hilbert-sort leaf size */
    int64_t seed;
} pm_render_defaults_t;

/* A material property the mesh file sets and the loader reads but does not honour (a texture,
 * an opacity, an illumination model other than 1 or 2, ...; docs/scene-format.md lists them):
 * kept, once per material and key, so that scene-info and the stages can say so. */
typedef struct {
    uint32_t material; /* index into pm_scene_t.materials */
    int is_file;       /* value is a file name (a texture), quoted when printed */
    int missing;       /* a texture file that is missing, rendered magenta (missing_textures) */
    char key[32];      /* as the mesh format names it: "map_Kd", "illum", "metallicFactor" */
    char value[224];   /* as assimp read it: "tex.png", "7", "0.75" */
    char note[96];     /* empty: ignored; else honoured approximately, and how ("rendered as plastic, ...") */
} pm_scene_unsupported_t;

/* The textures of one material: indices into pm_scene_t.textures, -1 for none. The texel
 * scales the material's own value (MTL and glTF both say so): kd = Kd map_Kd, ks = Ks map_Ks;
 * alpha (map_d) below 0.5 makes a hit no hit, for every ray. normal (MTL norm, glTF
 * normalTexture) is a tangent-space normal map and bump (MTL map_Bump, bump) a height map of
 * heights texel * bump_scale m; both bend the shading normal (pm_scene_shading_normal). */
typedef struct {
    int32_t kd, ks, alpha;
    int32_t normal, bump;
    float bump_scale; /* MTL -bm: m of height per unit of texel, 1 by default */
    /* glTF KHR_texture_transform of the material's textures, as assimp gives it ($tex.uvtrafo),
     * turned into pmtk's uv space: u' = uvxf[0] u + uvxf[1] v + uvxf[2], v' = uvxf[3] u + uvxf[4] v
     * + uvxf[5]. mesh.c applies it to the vertices' texture coordinates at load (so they hash with
     * it); has_uvxf 0: none (the identity). */
    int has_uvxf;
    float uvxf[6];
} pm_material_maps_t;

/* A material's texture slots in one order, kd, ks, alpha, normal, bump (each an index into
 * pm_scene_t.textures or -1): what every walk over the textures a material reads goes through. */
enum { PM_MAP_SLOTS = 5 };
static inline void pm_material_map_slots(pm_material_maps_t *mm, int32_t *slot[PM_MAP_SLOTS])
{
    slot[0] = &mm->kd, slot[1] = &mm->ks, slot[2] = &mm->alpha, slot[3] = &mm->normal, slot[4] = &mm->bump;
}

/* The range Embree's instances are built in (mesh.c, instance_xf_ok): a prototype's coordinates in
 * its own units, and each placement's scale; outside it a repeated mesh is built flat. */
#define PM_SCENE_INSTANCE_COORD_MAX 1e8
#define PM_SCENE_INSTANCE_SCALE_MIN 1e-4
#define PM_SCENE_INSTANCE_SCALE_MAX 1e4

/* Where one mesh entry of the scene file put its triangles. Every triangle is also in the
 * flattened arrays (verts, tris, tri_material) that the tracers read; a mesh file placed by
 * several entries is, in addition, built into Embree once and placed by instances (rt.c). */
typedef struct {
    uint64_t key;                        /* mesh file, faces kept, winding: equal keys, same triangles */
    float xf[12];                        /* mesh units -> m, rows of [3 x 3 | translation] */
    uint32_t tri0, ntris, vert0, nverts; /* its range in tris and verts */
    int32_t proto;                       /* the placement Embree holds its triangles from; -1: built flat */
    uint32_t local0;                     /* when proto is itself: its first vertex in local_verts */
} pm_placement_t;

/* What the loader did to the assets on the user's behalf (a scene material put in place of an
 * asset's, Kd + Ks scaled down to 1, a default grey given to a mesh without materials): one line
 * each, printed by scene-info and, through pm_scene_warn_unsupported, by every stage. */
typedef struct {
    int warning;    /* 1: the asset was changed (a warning); 0: a note */
    char text[320]; /* "meshes[0] 'box.obj': material 'red' replaced by scene material 'glass'" */
} pm_scene_note_t;

/* A file the load read (render/scene_cache.h): its path as the loader opened it and the XXH3-64
 * of its bytes then; absent 1 for a file it looked for and did not find (a missing .mtl or
 * texture), whose appearing changes the scene. */
typedef struct {
    char path[1200];
    uint64_t hash;
    int absent;
} pm_scene_source_t;

typedef struct {
    char name[128];  /* "cornell-box" */
    char path[1024]; /* the scene file */
    uint64_t hash;   /* XXH3-64 of the scene file and everything loaded from it */
    /* The hash's parts by what reads them (XXH3-64 of a canonical serialisation of the loaded
     * content, not of the file nor of C structs' bytes: render/scene_hash.c):
     * geometry: triangles, materials, textures, vertex normals; photons: that, every light
     * (point lights, sun, sky, portals, two-sided emitters) and the render block's photon keys (photon tracing and the
     * map); view: the geometry part, the camera, the image size and the render block's eye keys (the eye side's
     * queries, which no point light changes); eye: photons and view (the direct light, the image). */
    struct {
        uint64_t geometry, photons, view, eye;
    } parts;
    size_t nverts, ntris;
    float *verts;           /* nverts * 3, m */
    uint32_t *tris;         /* ntris * 3 vertex indices */
    uint32_t *tri_material; /* ntris material indices */
    pm_material_t *materials;
    size_t nmaterials;
    pm_point_light_t *lights;
    size_t nlights;
    int has_sun, has_sky; /* 1 when the scene file names a sun / a sky */
    int two_sided_lights; /* 1: emissive triangles emit from both faces (scene key two_sided_lights) */
    pm_sun_t sun;
    float sky[3];         /* W/(m^2 sr), RGB: radiance of a constant sky, seen by every ray that escapes */
    double sky_up[3];     /* unit, the sky's zenith (sky.up, default +y) */
    double sky_rotate;    /* degrees about sky_up (sky.rotate, default 0) */
    double sky_frame[9];  /* pm_sky_frame of the two: a map's and the sun's elevation/azimuth frame */
    double sky_turbidity; /* > 0: envmap is the Preetham model of this turbidity (sky.model), else 0 */
    pm_envmap_t *envmap;  /* the sky's lat-long map (its radiance then scales it), or NULL */
    pm_portal_t *portals; /* the sun's and the sky's photons enter through these only, or NULL */
    size_t nportals;
    double portal_area;        /* m^2, the portals' total */
    double portal_power[2][3]; /* W, RGB: the sun's [0] and the sky's [1] power through the portals */
    uint32_t *emissive;        /* indices of triangles whose material emits */
    size_t nemissive;
    size_t ndropped; /* degenerate (zero-area) triangles left out at load */
    pm_camera_t camera;
    pm_render_defaults_t defaults;
    float bounds[6];                     /* min xyz, max xyz of all triangles and point lights, m */
    int any_glossy;                      /* 1 when some material has ks > 0: direction channels are needed */
    int any_specular;                    /* 1 when some material is a mirror or glass */
    int any_glossy_textured;             /* 1 when some material is glossy and textured (pm_scene_glossy_textured) */
    pm_scene_unsupported_t *unsupported; /* of the materials kept, in material order */
    size_t nunsupported;
    /* Textures: all NULL and 0 in a scene without any (it pays nothing for the feature). */
    pm_material_maps_t *maps; /* nmaterials, or NULL when no material has a texture */
    float *uvs;               /* nverts * 2 texture coordinates (u, v), or NULL with maps */
    float *normals;           /* nverts * 3 unit vertex normals in scene space (zero where a mesh has none), or
                                 NULL: no mesh has any, or the scene key shading_normals is false */
    pm_texture_t *textures;   /* each file once, however many materials use it */
    size_t ntextures;
    int normals_ignored;        /* 1: some mesh has vertex normals and the scene key shading_normals is false */
    int any_alpha;              /* some material has map_d: render/rt.c installs the cut-out filter */
    pm_placement_t *placements; /* one per mesh entry */
    size_t nplacements;
    size_t instances_flat;  /* placements of repeated meshes built flat: outside instancing's range */
    float *local_verts;     /* prototypes' vertices in mesh units; NULL when no mesh is instanced */
    pm_scene_note_t *notes; /* what the loader changed or filled in, in load order */
    size_t nnotes;
    /* Every file the load read, in the order it read them, for the scene cache; uncacheable 1
     * when it read files it cannot name (assimp's import of a format other than OBJ, PLY, OFF
     * and STL opens what the file refers to itself: glTF buffers, Collada images), when one
     * changed while it loaded, or when no cache was to be written (then none is noted). */
    pm_scene_source_t *sources;
    size_t nsources;
    int uncacheable;
} pm_scene_t;

/* 1 when emissive triangle tri lights from both faces: the scene key two_sided_lights, or its
 * material's two_sided (a scene file's emission.two_sided). */
static inline int pm_scene_emits_both(const pm_scene_t *s, uint32_t tri)
{
    return s->two_sided_lights || s->materials[s->tri_material[tri]].two_sided;
}

/* Refuses a file to read that is not a regular file (a FIFO would block the load; opened without
 * blocking to find out); what names it in the message ("mesh", "scene"). render/mesh.c. */
pm_result_t pm_scene_check_regular(const char *path, const char *what);

/* Loads and checks a scene file. Errors name the file and the line (JSON syntax) or the
 * key path ("camera.fov_y") and the offending value. */
pm_result_t pm_scene_load(const char *path, pm_scene_t *out);
void pm_scene_free(pm_scene_t *s);

/* Prints each of s->unsupported as a warning on stderr through pm_stage_note (nothing under
 * --quiet): "NAME: warning: material 'X': map_Kd 'tex.png' is not supported (ignored)", or for
 * one with a note "... metallicFactor 0.3 is approximated: rendered as plastic, ...". Every
 * stage that loads a scene calls it once after pm_scene_load. */
void pm_scene_warn_unsupported(const pm_scene_t *s, const pm_stage_t *st);

/* Warns once on stderr through pm_stage_note (nothing under --quiet) when emissive triangles
 * face away from the whole scene (pm_scene_flipped_emitters): their light leaks out as
 * fireflies. scene-info and trace-photons call it after pm_scene_load. */
void pm_scene_warn_flipped(const pm_scene_t *s, const pm_stage_t *st);

/* "map_Kd 'tex.png'" or "illum 7", or with a note "metallicFactor 0.3 (approximated: NOTE)": one
 * unsupported property as scene-info prints it. */
void pm_scene_unsupported_text(const pm_scene_unsupported_t *u, char *out, size_t cap);

/* Total emitted power, W, RGB: point lights (4 pi I, spots less: pm_point_light_power)
 * plus area lights (pi Ke area, twice that when two-sided) plus the sun's and the sky's power into the scene's bounding
 * sphere (pm_scene_sphere): L omega pi R^2 and L 4 pi pi R^2; with portals, their power through
 * the portals instead (portal_power, render/light.h pm_portals_power). */
void pm_scene_power(const pm_scene_t *s, double power_out[3]);

/* Power of point light l in channel k, W: 4 pi I isotropic, 2 pi I (1 - cos_cone) /
 * (falloff + 1) for a spot. */
double pm_point_light_power(const pm_point_light_t *l, int k);

/* The sphere the sun's and the sky's photons are aimed at: centre (m) and radius (m) around
 * s->bounds, a little larger, so that every photon starts outside the geometry. */
void pm_scene_sphere(const pm_scene_t *s, double centre_out[3], double *radius_out);

/* Power of the sun and of the sky in channel k, W, as their photons carry it (above). */
double pm_sun_power(const pm_scene_t *s, int k);
double pm_sky_power(const pm_scene_t *s, int k);

/* Area of triangle t, m^2. */
double pm_scene_triangle_area(const pm_scene_t *s, size_t t);

/* The material at point p (m, on or near triangle tri) with its Kd and Ks (and a conductor's
 * F0 with Kd: its base colour) scaled by their textures there: the scene's own material when it
 * has no texture (no copy, no cost), else *scratch filled and returned. Every tracer reads a
 * hit's reflectance through this. */
const pm_material_t *pm_scene_material_textured(const pm_scene_t *s, uint32_t tri, const float p[3],
                                                pm_material_t *scratch);
static inline const pm_material_t *pm_scene_material_at(const pm_scene_t *s, uint32_t tri, const float p[3],
                                                        pm_material_t *scratch)
{
    uint32_t mi = s->tri_material[tri];
    if (!s->maps || (s->maps[mi].kd < 0 && s->maps[mi].ks < 0))
        return &s->materials[mi];
    return pm_scene_material_textured(s, tri, p, scratch);
}

/* 1 when material mi is glossy (ks > 0) and has a map_Kd or map_Ks: its reflectance varies over
 * the surface in both lobes, so that the eye tracer's queries carry its diffuse part in the
 * weight and its lobe apart (render/eyetrace.c, docs/formats.md 3.3). */
static inline int pm_scene_glossy_textured(const pm_scene_t *s, uint32_t mi)
{
    return s->maps && pm_material_is_glossy(&s->materials[mi]) && (s->maps[mi].kd >= 0 || s->maps[mi].ks >= 0);
}

/* Texture coordinates of triangle tri at barycentrics (b1, b2) of its second and third vertex
 * (Embree's u, v); (0, 0) in a scene without textures. */
void pm_scene_uv(const pm_scene_t *s, uint32_t tri, float b1, float b2, float uv_out[2]);

/* Barycentrics (b1, b2) of point p projected onto triangle tri, clamped into the triangle. */
void pm_scene_barycentrics(const pm_scene_t *s, uint32_t tri, const float p[3], float b_out[2]);

/* 1 when the hit at barycentrics (b1, b2) of triangle tri is cut out (its material's map_d
 * below 0.5 there). */
int pm_scene_cut_out(const pm_scene_t *s, uint32_t tri, float b1, float b2);

/* The shading normal at point p (m, on triangle tri): the vertex normals interpolated at p's
 * barycentrics and normalized (or the triangle's own normal without them), bent by its
 * material's normal map or bump map when it has one and the triangle has texture coordinates,
 * turned to the side of n (the unit geometric normal on the side the ray came from). Returns 1
 * then; 0 with n itself copied, bit for bit, when none of these applies (no vertex normals or
 * they cancel at p, and no map). */
int pm_scene_shading_normal(const pm_scene_t *s, uint32_t tri, const float p[3], const float n[3], float ns_out[3]);

/* The emissive triangles whose front face (the side their winding's normal points to, the
 * only side that emits) sees none of the scene: no vertex of the scene lies in front of
 * their plane by more than 1e-2 of its distance (plus float rounding; a lamp far from the rest
 * of the scene changes nothing) (a light wound the wrong way under
 * a ceiling sees only the ceiling's underside a hair above it, and its light leaks out as
 * sparse fireflies). Returns how many; *first_out the first of them (a triangle index). Time
 * linear in emitters and vertices for emitters facing few ways (a lamp placed N times). */
size_t pm_scene_flipped_emitters(const pm_scene_t *s, uint32_t *first_out);

/* Which parts of the scene a file's SCENE key names (docs/formats.md, SCENE): what photon
 * tracing and the map read, what the eye side's queries read, or both. */
typedef enum { PM_SCENE_ALL, PM_SCENE_PHOTONS, PM_SCENE_VIEW } pm_scene_part_t;

/* The value of a file header's SCENE key for a file made from part of the scene:
 * "NAME xxh3:GEOMETRY[ photons:xxh3:PHOTONS][ view:xxh3:VIEW]" (PM_SCENE_ALL names both). */
void pm_scene_id(const pm_scene_t *s, char *out, size_t cap);
void pm_scene_id_part(const pm_scene_t *s, pm_scene_part_t part, char *out, size_t cap);

/* XXH3-64 of materials m[0..n-1] (point lights l[0..n-1]) by the canonical serialisation the
 * scene's identity is made of (render/scene_hash.c): the fields each kind reads, in a fixed order,
 * floats as their IEEE bits little-endian, behind a version tag; padding, the bytes after a
 * name's end and the fields a kind does not read are not read. */
uint64_t pm_scene_materials_hash(const pm_material_t *m, size_t n);
uint64_t pm_scene_lights_hash(const pm_point_light_t *l, size_t n);

/* 1 when SCENE value key is this scene whole: pm_scene_id's value. A file written before the
 * scene identity's version 2 (the one-hash form "NAME xxh3:HASH" before the parts, or the parts
 * of the older identity) names another scene and is not matched. */
int pm_scene_id_matches(const pm_scene_t *s, const char *key);

#endif
