/* rt.h: the Embree 3 device and scene behind every ray pmtk casts.
 *
 * One device per process, created with an error callback so that Embree's own
 * messages reach the user; one static scene of the scene's triangles (geometry id 0,
 * primitive id = triangle index in pm_scene_t). Rays are cast by the stages directly
 * with rtcIntersect1/4/8/16 on pm_rt_t.scene. */
#ifndef PM_RT_H
#define PM_RT_H

#include <embree3/rtcore.h>

#include "base/error.h"
#include "render/scene.h"

typedef struct {
    RTCDevice device;
    RTCScene scene;
    float epsilon; /* m: ray-origin offset that scales with the scene (no acne at 1e-4 or 1e5 scale) */
} pm_rt_t;

/* Builds the acceleration structure with `threads` build threads (--threads; 0 lets
 * Embree choose); quality "high" spends more build time for faster rays (many-ray
 * stages), "medium" is Embree's default. */
pm_result_t pm_rt_create(const pm_scene_t *s, int high_quality, int threads, pm_rt_t *out);
void pm_rt_destroy(pm_rt_t *rt);

#endif
