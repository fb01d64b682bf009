/* coverage.h: the boundary correction of the density estimate.
 *
 * The sample-point estimate at a query adds each photon's power spread over its whole kernel
 * disc, as if the photon's surface covered the disc of radius h around it. Where the disc
 * overhangs an edge, reaches past a concave corner (the wall's queries fail the normal test) or
 * wraps round a column, it does not: the part of the power spread off the surface is lost, and
 * the estimate is low by it, a bias of order h that a final gather sees everywhere the scene
 * has detail finer than the kernel (the sky-lit atrium's indirect light was 3 to 5% dark at 40
 * passes, docs/accuracy.md).
 *
 * The covered part of photon i's disc is the same estimate over area samples (render/
 * areasample.h: points spread evenly over the storing surfaces, each carrying its share of the
 * area as a white power) with the same kernel, width and normal test, at the photon:
 * c_i = sum_j a_j K(|x_i - x_j| / h) / h^2, 1 on an open plane, 1/2 at a straight edge.
 * Dividing each photon's power by max(c_i, PM_COVERAGE_MIN) makes its kernel integrate to its
 * power over the surface it lies on: the estimate conserves the photons' power (the plain
 * one does not), so a final gather, which integrates the estimate over what its rays see, loses
 * nothing at edges. Pointwise, a query at an edge still reads somewhat low and one a kernel in
 * from it somewhat high (the edge's power is spread inward), by less than the plain loss.
 * The cost is one gather of the map's photons against the area samples: photons, not queries,
 * and a final gather has many more queries than photons. */
#ifndef PM_COVERAGE_H
#define PM_COVERAGE_H

#include <stdint.h>

#include "base/error.h"
#include "formats/formats.h"
#include "photonmap/gather.h"

/* The kernel width over the area samples' spacing: about pi 4^2 = 50 samples in a disc. */
#define PM_COVERAGE_RATIO 4.0
/* A photon covered less than this is divided by this: a sliver's photon is not blown up. */
#define PM_COVERAGE_MIN 0.25

typedef struct {
    pm_table_t table; /* the area samples' map (map format, built by mapbuild.c) */
    pm_gather_map_t map;
    double spacing; /* m, between area samples; 0: nothing built */
    uint64_t samples;
    double *scratch; /* 3 per photon of a block */
    /* what the corrections cost, summed over every call */
    uint64_t shader_ops;
    double cpu_s, wall_s;
    double build_s; /* s spent building maps (all of them) */
    uint32_t builds;
} pm_coverage_t;

/* The spacing level for kernel width h: the k of the largest spacing 2^(k/2) m at or below
 * h / PM_COVERAGE_RATIO, so that every run with the same width (a progressive pass alone or in a
 * resident stream) uses the same samples. Fails (PM_ERR_USAGE) when h is not a positive finite
 * width. pm_coverage_level_spacing(k) is that spacing, m. */
pm_result_t pm_coverage_level(double h, int *level_out);
double pm_coverage_level_spacing(int level);

/* A seed for the samples at `spacing`, the same in every process. */
uint64_t pm_coverage_seed(double spacing);

/* Builds c's map from n area samples (positions, unit normals, areas as 3 equal channels, m^2)
 * at `spacing`, replacing what c held. */
pm_result_t pm_coverage_build(pm_coverage_t *c, const float *pos, const float *normal, const float *area, uint64_t n,
                              double spacing);

/* Divides the power of every photon of `map` (a photon map table, its power column changed in
 * place; m is its view) by the covered part of its kernel at the fixed width and the normal test
 * of p. */
pm_result_t pm_coverage_apply(pm_coverage_t *c, pm_table_t *map, const pm_gather_map_t *m, const pm_gather_params_t *p);

void pm_coverage_free(pm_coverage_t *c);

#endif
