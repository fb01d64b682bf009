/* areasample.h: points spread evenly over the surfaces where photons are stored, each carrying
 * its share of the area, so that the gather's density estimate of them measures how much of a
 * kernel's disc is surface (photonmap/coverage.h: the boundary correction).
 *
 * A density estimate divides the photons' power in a kernel by the kernel's whole disc, pi h^2.
 * Where the disc overhangs an edge, reaches past a corner or wraps round a column, part of it
 * holds no surface that passes the normal test, and the estimate is low by that part: a bias of
 * order h, dark everywhere a final gather looks at geometry finer than the kernel. The same
 * estimate over these samples, with the same kernel and normal test, is that part (1 on an open
 * plane); dividing by it removes the bias's first order.
 *
 * The samples are stratified per triangle (a shifted Hammersley set through the square-root map,
 * n = max(1, round(A / s^2)) samples of A / n each, so that each triangle's area is exact),
 * on each side that stores photons, with the normal the photon tracer stores there (the shading
 * normal turned to that side), cut-outs (map_d) and the insides of solids left out: the back of
 * a slab's underside lies within a kernel of its top and faces the same way, and counting it
 * would darken the top as much as the edges do. */
#ifndef PM_AREASAMPLE_H
#define PM_AREASAMPLE_H

#include <stdint.h>

#include "base/error.h"
#include "render/rt.h"
#include "render/scene.h"

typedef struct {
    uint64_t n;
    float *pos;    /* n * 3, m */
    float *normal; /* n * 3, unit */
    float *area;   /* n * 3, m^2, the sample's share (the same in the three channels: a white "power") */
    double spacing;
    double total_area; /* m^2, one side of every storing triangle */
    uint64_t hidden;   /* sides left out as facing the inside of a solid */
} pm_area_samples_t;

/* Samples with about `spacing` m between neighbours over every triangle of s that stores
 * photons; seed picks the shifts. A side is left out when it faces the inside of a solid, which
 * no photon reaches: a ray from it along its normal meets the back of a face within `reach` m
 * (the slab's other face, a column's far side; 0: every side kept). rt is s's. Refuses
 * (PM_ERR_USAGE) when more than max_samples would be made. Deterministic for any thread count.
 * Free with pm_area_samples_free, also after a failure. */
pm_result_t pm_area_samples_make(const pm_scene_t *s, const pm_rt_t *rt, double spacing, double reach, uint64_t seed,
                                 uint64_t max_samples, pm_area_samples_t *out);

/* The number pm_area_samples_make would make at `spacing` (both sides counted, none left out),
 * without making them; at an infinite spacing, the least at any: two a storing triangle. */
uint64_t pm_area_samples_count(const pm_scene_t *s, double spacing);

void pm_area_samples_free(pm_area_samples_t *a);

#endif
