/* knn_gather.h: traditional photon mapping's final gather (the paper's equation 1, Jensen's
 * estimator), the baseline that simd-gather's sample-point estimator replaces.
 *
 * For each query, the k nearest photons whose normal agrees with the query's are found by
 * a scalar walk of the photon KD-tree keeping a max-heap of the k best, pruned by the heap's
 * largest distance once it is full; then, with r the distance of the k-th,
 *
 *     L = sum over the k photons of  f(wi, wo) * power_i * K(|y - x_i| / r) / r^2     [W/(m^2 sr)]
 *
 * with K the same plane-normalized kernels as gather.h (uniform: 1/pi, which is Jensen's
 * 1/(pi r^2)). A search limited by max_radius that finds fewer than k photons takes
 * r = max_radius, as Jensen does. The estimate is multiplied by the query's weight (the
 * weight contract of docs/formats.md, section 3.3). */
#ifndef PM_KNN_GATHER_H
#define PM_KNN_GATHER_H

#include <stdint.h>

#include "base/error.h"
#include "photonmap/gather.h"

typedef struct {
    uint32_t k;        /* photons per estimate, >= 1 */
    double max_radius; /* m; 0: unlimited */
    pm_kernel_t kernel;
    float normal_cos; /* a photon counts when dot(n_photon, n_query) >= this */
} pm_knn_params_t;

typedef struct {
    uint64_t shader_ops;    /* photon-query pairs shaded: k per query, fewer where the search found fewer */
    uint64_t nodes_visited; /* KD-tree nodes whose photon the walks looked at */
    uint64_t heap_pushes;   /* photons that entered a heap (k of them per query at least, and each replacement) */
    uint64_t short_queries; /* queries that found fewer than k photons */
    double cpu_s;           /* CPU seconds the threads spent in the searches */
} pm_knn_stats_t;

/* Gathers queries [begin, end): out[3 (i - begin) + c] receives query i's weighted
 * radiance, W/(m^2 sr), in double. Each query is independent of the others, so the result
 * does not depend on the thread count. Fails (PM_ERR_INPUT) when a query's k nearest
 * photons all lie at its position (r = 0 would give an infinite estimate). */
pm_result_t pm_knn_gather(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                          const pm_knn_params_t *p, double *out, pm_knn_stats_t *stats);

#endif
