/* kdtree.h: the photon map's KD-tree (the paper, section 5.2), built and searched.
 *
 * One photon per node, on the node's split plane; nodes are the 8-byte pm_kdnode_t of
 * formats.h in depth-first order, so a tree of n photons is exactly n nodes and node i's
 * photon is input photon perm[i]. The build splits at the median of the longest axis of
 * the photons' bounding box (a balanced tree, depth ceil(log2(n + 1))); subtrees are
 * built in parallel with OpenMP tasks, and the result does not depend on the thread
 * count.
 *
 * Searches compare against the photons' exact coordinates, not the split values, whose
 * low 2 mantissa bits hold the axis: left-subtree photons are <= their ancestor's
 * coordinate on its axis and right-subtree ones >=, so pruning by the coordinate is exact. */
#ifndef PM_KDTREE_H
#define PM_KDTREE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "formats/formats.h"

typedef struct {
    unsigned depth; /* levels: 0 for an empty tree, 1 for a single leaf */
    uint64_t leaves;
} pm_kd_build_stats_t;

/* Builds the tree of n photons at pos (n * 3 floats, m, finite). Writes n nodes and the
 * permutation: node i holds photon perm[i]. n may be 0. Fails only for out of memory or
 * n > 2^32 - 2 (node indices are u32 and 0xFFFFFFFF means none). */
pm_result_t pm_kd_build(const float *pos, uint64_t n, pm_kdnode_t *node_out, uint32_t *perm_out,
                        pm_kd_build_stats_t *stats_out);

/* The same with the voxel-volume heuristic of Wald et al. 2004 (the paper's reference 22)
 * for searches of radius vvh_radius (m): unbalanced splits that make searches visit fewer
 * photons; vvh_radius 0 is pm_kd_build. The tree stays within PM_KD_MAX_DEPTH levels. */
pm_result_t pm_kd_build_vvh(const float *pos, uint64_t n, float vvh_radius, pm_kdnode_t *node_out, uint32_t *perm_out,
                            pm_kd_build_stats_t *stats_out);

/* Distance (m) from photon `self` (a node index) to its k-th nearest photon, itself
 * counted as the first; so k = 1 gives 0. pos is in node order (pos[3 i] is node i's
 * photon). If the tree holds fewer than k photons, the farthest distance. `heap` is
 * scratch of k floats (squared distances). */
float pm_kd_knn_radius(const pm_kdnode_t *node, const float *pos, uint32_t n, const float q[3], uint32_t k,
                       float *heap);

/* Calls fn(ctx, i, d2) for every node i whose photon lies within radius r of q (d2 <= r^2,
 * squared distance in m^2), in depth-first order. The scalar reference search that the
 * SIMD gathers and the tests compare against. */
void pm_kd_range(const pm_kdnode_t *node, const float *pos, uint32_t n, const float q[3], float r,
                 void (*fn)(void *ctx, uint32_t i, float d2), void *ctx);

#endif
