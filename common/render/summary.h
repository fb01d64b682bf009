/* summary.h: what a loaded scene holds and needs, the engine of scene-info.
 *
 * The summary (triangles, materials and the properties they set that pmtk ignores, the textures and who reads
 * them, whether shading normals are in use, lights and their power, bounds,
 * camera, what the stages downstream need of the scene, the ray epsilon, load and build times) as text or as one JSON
 * object (docs/programs/scene-info.md); the probe, one primary ray through each pixel's
 * centre, as a check that the camera sees the geometry; and the eye-light preview those rays
 * can shade, each pixel its surface's albedo times |cos| to the eye. */
#ifndef PM_SUMMARY_H
#define PM_SUMMARY_H

#include <jansson.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "render/rt.h"
#include "render/scene.h"

/* What the stages downstream need of a scene. */
typedef struct {
    int directions;   /* direction channels: some material is glossy */
    int material_ids; /* material ids: only where the gather must tell glossy materials apart; an
                       * all-Lambertian scene folds its BRDFs into the query weights (docs/formats.md 3.3) */
    int area_lights;  /* area-light sampling: some triangle emits */
} pm_scene_needs_t;

pm_scene_needs_t pm_scene_needs(const pm_scene_t *s);

/* What one probe found. */
typedef struct {
    uint64_t rays, hits;
    double rays_per_s; /* wall clock */
} pm_probe_t;

/* Casts one primary ray through the centre of every pixel of the scene's camera, rows in
 * parallel (OpenMP, its default team), with a progress line when progress is set and stderr is
 * a terminal. preview_rgb, unless NULL, receives 3 * width * height sRGB bytes, rows top to
 * bottom: the eye-light shading of each pixel (emitters in their normalized emission colour,
 * misses black), the same bytes for any thread count. */
pm_result_t pm_scene_probe(const pm_scene_t *s, const pm_rt_t *rt, int progress, uint8_t *preview_rgb,
                           pm_probe_t *probe_out);

/* What scene-info prints, and the inputs it prints that the scene does not hold. */
typedef struct {
    int json;             /* one JSON object instead of lines of text */
    int probe;            /* probe the camera's view and report the hit rate */
    const char *preview;  /* write the eye-light preview to this PNG path (probes too); NULL for none */
    int progress;         /* the probe's progress line (not --quiet) */
    double load_s, bvh_s; /* s (wall) the scene took to load and its BVH to build */
} pm_summary_options_t;

/* The summary of s as text or JSON on out, after the probe and the preview when asked.
 * *probe_out becomes what the probe found (all zero when there was none). */
pm_result_t pm_summary_write(FILE *out, const pm_scene_t *s, const pm_rt_t *rt, const pm_summary_options_t *o,
                             pm_probe_t *probe_out);

/* The summary as a new JSON object (the caller owns *j_out), numbers at full float precision,
 * units in the key names where they are not counts; with a "probe" object when probe is not NULL. */
pm_result_t pm_summary_json(const pm_scene_t *s, const pm_rt_t *rt, const pm_summary_options_t *o,
                            const pm_probe_t *probe, json_t **j_out);

#endif
