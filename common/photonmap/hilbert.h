/* hilbert.h: reordering points along a 3-D Hilbert curve (or Morton order), for hilbert-sort.
 *
 * The order is that of an octree over the points' bounding cube whose children are visited
 * in curve order, the order given by a compact table of the curve's L-system: for each of
 * PM_HILBERT_STATES orientations, the octant visited r-th and the orientation of that child
 * (the paper, section 6.2). Recursion stops at cells of `leaf` points or fewer (partial
 * reordering), or at depth PM_HILBERT_LEVELS, where cells are 1/2^21 of the cube's side and
 * cannot be split further; the points of one leaf keep their input order. The result is a
 * permutation of point indices, the same for any thread count. */
#ifndef PM_HILBERT_H
#define PM_HILBERT_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

#define PM_HILBERT_LEVELS 21 /* octree levels: 21 bits per axis, a 63-bit key */
#define PM_HILBERT_STATES 12 /* orientations of the curve reachable from the base one */

/* The L-system. Octant o of a cell is x | y << 1 | z << 2, each bit 1 for the upper half.
 * A cell in state s visits octant pm_hilbert_order[s][r] r-th (r = 0..7), and that child is
 * in state pm_hilbert_child[s][r]. The root is in state 0, which enters the cube at corner
 * (0,0,0) and leaves it at corner (0,0,1). */
extern const uint8_t pm_hilbert_order[PM_HILBERT_STATES][8];
extern const uint8_t pm_hilbert_child[PM_HILBERT_STATES][8];

typedef enum {
    PM_ORDER_NONE = 0,   /* input order, unchanged */
    PM_ORDER_MORTON = 1, /* Z-order: octants in the fixed order 0..7 at every level */
    PM_ORDER_HILBERT = 2 /* the Hilbert curve of the table above */
} pm_order_t;

/* Words for the --order option, indexed by pm_order_t, NULL-terminated. */
extern const char *const pm_order_names[];

typedef struct {
    unsigned depth;  /* deepest level at which a leaf was made (0: the root was a leaf) */
    uint64_t leaves; /* leaf cells */
    double keys_s;   /* s: bounds, quantization and curve keys */
    double sort_s;   /* s: the octree (MSD radix) passes */
} pm_reorder_info_t;

/* The leaf size --leaf auto picks for n points with the given cache (bytes; see
 * docs/programs/hilbert-sort.md for the model). Never below 1. */
uint64_t pm_reorder_auto_leaf(uint64_t n, uint64_t cache_bytes);

/* The cube's key of one position: its 63-bit curve index at full depth, for tests.
 * lo and scale map a coordinate to a cell (cell = (x - lo) * scale, clamped to 2^21-1). */
uint64_t pm_reorder_key(pm_order_t order, const float xyz[3], const double lo[3], double scale);

/* Computes the order of n points whose x, y, z floats start every `stride` bytes at pos:
 * perm_out[i] is the index of the point that goes to place i. Runs on the OpenMP default
 * thread count. leaf >= 1. n < 2^32. Fails only for memory (PM_ERR_NOMEM) or bad arguments
 * (PM_ERR_INTERNAL). info_out may be NULL. Positions must be finite. */
pm_result_t pm_reorder_points(const void *pos, size_t stride, uint64_t n, pm_order_t order, uint64_t leaf,
                              uint32_t *perm_out, pm_reorder_info_t *info_out);

/* The points' bounding cube as pm_reorder_points uses it: lo (the minimum per axis, in
 * double) and scale = 2^21 / (longest side), 0 when every point is the same. */
void pm_reorder_cube(const void *pos, size_t stride, uint64_t n, double lo_out[3], double *scale_out);

#endif
