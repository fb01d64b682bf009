/* reverse_gather.h: reverse photon mapping (Havran, Herzog and Seidel 2005; the paper's
 * section 4): a KD-tree is built over the queries, and each photon searches it with the
 * fixed kernel width and adds its contribution to every query it reaches. The estimator is
 * simd-gather's sample-point estimator (gather.h), so the result equals pm_gather_run's
 * within float rounding: the same pairs (the same float distance and normal tests), the
 * same kernels and BRDF.
 *
 * Determinism: the query tree is cut into subtrees (and the few nodes above them) by depth
 * alone, never by the thread count; a thread takes a whole subtree and runs every photon
 * against it in photon order. So each query's sum is taken in photon order whatever the
 * number of threads, and the buffer is bit-identical for any --threads. */
#ifndef PM_REVERSE_GATHER_H
#define PM_REVERSE_GATHER_H

#include <stdint.h>

#include "base/error.h"
#include "photonmap/gather.h"

typedef struct {
    double radius; /* m: the kernel width h */
    pm_kernel_t kernel;
    float normal_cos; /* a photon counts when dot(n_photon, n_query) >= this */
} pm_reverse_params_t;

typedef struct {
    uint64_t shader_ops;    /* photon-query pairs inside the kernel that pass the normal test */
    uint64_t nodes_visited; /* query-tree nodes the photons' searches looked at */
    uint64_t searches;      /* photon-subtree searches started (the photon's sphere met the subtree's box) */
    uint64_t box_tests;     /* photon-subtree bounding-box tests */
    uint32_t subtrees;      /* units of work the query tree was cut into */
    unsigned tree_depth;    /* levels of the query tree */
    double build_s;         /* wall seconds to build the query tree and its node-order arrays */
    double search_s;        /* wall seconds of the photons' searches */
    double cpu_s;           /* CPU seconds the threads spent in the searches */
} pm_reverse_stats_t;

/* Gathers queries [begin, end) (at most 2^32 - 2 of them): out[3 (i - begin) + c] receives
 * query i's weighted radiance, W/(m^2 sr), in double. */
pm_result_t pm_reverse_gather(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                              const pm_reverse_params_t *p, double *out, pm_reverse_stats_t *stats);

#endif
