/* shade.h: the eye-side scene model that trace-gather-points and trace-reference share, so
 * that the photon pipeline and its ground truth render exactly one model: the pinhole
 * camera, the BRDF of formats/material.h, per-triangle front normals (the emitting side)
 * and area lights sampled uniformly over their total area.
 *
 * Units: metres; radiance W/(m^2 sr); BRDF 1/sr. */
#ifndef PM_SHADE_H
#define PM_SHADE_H

#include <stddef.h>
#include <stdint.h>

#include "formats/pmfile.h"
#include "base/error.h"
#include "formats/material.h"
#include "math/rng.h"
#include "render/scene.h"

/* A pinhole camera for a w x h image: pixel (px, py) in [0, w) x [0, h), y down. */
typedef struct {
    float eye[3], fwd[3], right[3], up[3];
    float tan_half, aspect;
    uint32_t w, h;
} pm_camera_rays_t;

void pm_camera_setup(const pm_camera_t *cam, uint32_t w, uint32_t h, pm_camera_rays_t *out);
/* Unit direction of the ray through image point (px, py). */
void pm_camera_dir(const pm_camera_rays_t *c, float px, float py, float d_out[3]);

/* f(wi, wo) of formats/material.h, 1/sr, around unit normal n (wi, wo unit, pointing away). */
void pm_brdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3], float f_out[3]);

/* Per-triangle unit front normals and the area lights of a scene. */
typedef struct {
    float *tri_n;      /* ntris * 3: (v1 - v0) x (v2 - v0), normalized; the side that emits */
    double *cdf;       /* nemissive: cumulative emissive area, ending at exactly 1 */
    double area;       /* m^2, all emissive triangles */
    size_t nemissive;
} pm_shade_geom_t;

pm_result_t pm_shade_geom_init(const pm_scene_t *s, pm_shade_geom_t *out);
void pm_shade_geom_free(pm_shade_geom_t *g);
/* Point of triangle t at barycentrics (b0, b1), b2 = 1 - b0 - b1. */
void pm_triangle_point(const pm_scene_t *s, uint32_t t, float b0, float b1, float p_out[3]);

/* A light as seen from a surface point: unit direction wi toward it, distance r (m), squared
 * distance r2 (m^2) and the cosine at the surface; for an area light also the triangle and the
 * cosine at the light (its front face toward the surface). */
typedef struct {
    float wi[3], r, r2, cosx, cosy;
    uint32_t tri;
} pm_light_sample_t;

/* Point light l from p with normal n (geometry from p itself; only a shadow ray starts off the
 * surface); 0 when l is at p or behind the surface. */
int pm_point_light_toward(const pm_point_light_t *l, const float p[3], const float n[3], pm_light_sample_t *out);
/* One point on the area lights, uniform over their total area g->area (pdf 1/A per m^2), from
 * three numbers of rng: the triangle (a double), then two floats for the point. 0 when the point
 * is at p, behind the surface, or sees its back. The scene must have emissive triangles. */
int pm_area_light_sample(const pm_scene_t *s, const pm_shade_geom_t *g, pm_rng_t *rng, const float p[3],
                         const float n[3], pm_light_sample_t *out);

/* Veach's power heuristic: the weight of strategy a against b, each a sample count times a
 * solid-angle pdf at one direction; 0 when neither could have produced it. */
static inline float pm_power_heuristic(float a, float b)
{
    float d = a * a + b * b;
    return d > 0.0f ? a * a / d : 0.0f;
}

/* The keys every image-shaped output of a scene starts with: this command's COMMAND line, the
 * scene bounds, SCENE (name and content hash), width and height. */
pm_result_t pm_image_header_begin(pm_header_t *h, int argc, char **argv, const pm_scene_t *s, uint32_t w,
                                  uint32_t ht);

#endif
