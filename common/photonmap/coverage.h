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
 * The covered part of a point's disc is the same estimate over area samples (render/
 * areasample.h: points spread evenly over the storing surfaces, each carrying its share of the
 * area as a white power) with the same kernel, width and normal test: c(x) = sum_j a_j
 * K(|x - x_j| / h) / h^2, 1 on an open plane, 1/2 at a straight edge. It is applied on the
 * smaller side of a gather, both of which remove the loss:
 *   - photons (pm_coverage_apply): each photon's power divided by max(c(x_i), PM_COVERAGE_MIN),
 *     so that its kernel integrates to its power over the surface it lies on: the estimate
 *     conserves the photons' power, and a final gather, which integrates the estimate over what
 *     its rays see, loses nothing at edges (pointwise a query at an edge still reads somewhat
 *     low and one a kernel in from it somewhat high); the side for a final gather's many
 *     queries against a pass's few photons;
 *   - queries (pm_coverage_apply_queries): each query's estimate divided by max(c(y),
 *     PM_COVERAGE_MIN), the ratio estimator, right pointwise for a density that is constant
 *     over the surface; the side for a dense map seen by fewer queries.
 * Either costs one gather of that side's points against the area samples. The remainder is of
 * order h^2 (the density's curvature) plus the area samples' own scatter (a few per cent per
 * point at PM_COVERAGE_RATIO, averaged out over a pixel's many photons and queries). */
#ifndef PM_COVERAGE_H
#define PM_COVERAGE_H

#include <stdint.h>

#include "base/error.h"
#include "formats/formats.h"
#include "photonmap/gather.h"

/* The kernel width over the area samples' spacing, at least: about pi 2^2 = 13 samples in a disc
 * (up to twice that, as levels are sqrt(2) apart), the scatter of c a few per cent. */
#define PM_COVERAGE_RATIO 2.0
/* A point covered less than this is divided by this: a sliver's few photons are not blown up. */
#define PM_COVERAGE_MIN 0.25
/* The most area samples simd-gather --coverage makes (about 90 bytes each with their map): a
 * coarser spacing level is taken above it (and the TIME planner, common/engine/progressive.c,
 * foresees the same levels). */
#define PM_COVERAGE_MAX_SAMPLES (1ull << 22)

typedef struct {
    pm_table_t table; /* the area samples' map (map format, built by mapbuild.c) */
    pm_gather_map_t map;
    double spacing; /* m, between area samples; 0: nothing built */
    uint64_t samples;
    double *scratch; /* 3 per photon of a block */
    /* what the corrections cost, summed over every call */
    uint64_t shader_ops, points; /* pairs, and photons or queries corrected */
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

/* The finest level whose area samples number at most max_samples: the smallest k with
 * count(user, pm_coverage_level_spacing(k)) <= max_samples, count never rising as the spacing
 * grows (pm_area_samples_count); INT_MAX when not even count(user, INFINITY) is. A width's level
 * within the bound is the larger of its own (pm_coverage_level) and this one: simd-gather's
 * --coverage and pm-render's TIME planner, which foresees it, take it so. */
int pm_coverage_finest_level(uint64_t (*count)(const void *user, double spacing), const void *user,
                             uint64_t max_samples);

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

/* The same on the other side: divides out[3 (i - begin) + k], the gather's results for queries
 * [begin, end) of q at params p, by the covered part of each query's kernel (the ratio
 * estimator: right pointwise for a density that is constant over the surface, as an integral
 * too). */
pm_result_t pm_coverage_apply_queries(pm_coverage_t *c, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                                      const pm_gather_params_t *p, double *out);

void pm_coverage_free(pm_coverage_t *c);

#endif
