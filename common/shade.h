/* shade.h: the eye-side scene model that trace-gather-points and trace-reference share, so
 * that the photon pipeline and its ground truth render exactly one model: the pinhole
 * camera, the BRDF of common/material.h, per-triangle front normals (the emitting side)
 * and area lights sampled uniformly over their total area.
 *
 * Units: metres; radiance W/(m^2 sr); BRDF 1/sr. */
#ifndef PM_SHADE_H
#define PM_SHADE_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "material.h"
#include "scene.h"

/* A pinhole camera for a w x h image: pixel (px, py) in [0, w) x [0, h), y down. */
typedef struct {
    float eye[3], fwd[3], right[3], up[3];
    float tan_half, aspect;
    uint32_t w, h;
} pm_camera_rays_t;

void pm_camera_setup(const pm_camera_t *cam, uint32_t w, uint32_t h, pm_camera_rays_t *out);
/* Unit direction of the ray through image point (px, py). */
void pm_camera_dir(const pm_camera_rays_t *c, float px, float py, float d_out[3]);

/* f(wi, wo) of common/material.h, 1/sr, around unit normal n (wi, wo unit, pointing away). */
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
/* Index into s->emissive of the emissive triangle whose area interval holds u in [0, 1). */
size_t pm_shade_pick_light(const pm_shade_geom_t *g, double u);
/* Point of triangle t at barycentrics (b0, b1), b2 = 1 - b0 - b1. */
void pm_triangle_point(const pm_scene_t *s, uint32_t t, float b0, float b1, float p_out[3]);

#endif
