/* strata.h: the stratified sampler of the final-gather rays (the paper, section 6.1).
 *
 * The unit square is cut into a grid of nx by ny cells and each cell gets `per_cell`
 * independent uniform points (four in trace-gather-points), cell after cell in row-major
 * order. Mapped through the cosine-weighted hemisphere warp, the points of one cell become
 * rays with one origin and similar directions, and consecutive cells are neighbours, so
 * consecutive rays make coherent packets. */
#ifndef PM_STRATA_H
#define PM_STRATA_H

#include "math/rng.h"

/* The most nearly square grid of exactly `cells` cells: ny is the largest divisor of
 * cells not above sqrt(cells), nx = cells / ny (so nx >= ny; a prime count gives a row). */
void pm_strata_grid(unsigned cells, unsigned *nx_out, unsigned *ny_out);

/* Fills u1[i], u2[i] for i < nx * ny * per_cell: point i lies in cell i / per_cell, that is
 * column (i / per_cell) % nx and row (i / per_cell) / nx, and inside it the float
 * arithmetic keeps it: (unsigned)(u1 * nx) is the column and (unsigned)(u2 * ny) the row.
 * Draws 2 numbers per point from rng, in order. */
void pm_strata_fill(pm_rng_t *rng, unsigned nx, unsigned ny, unsigned per_cell, float *u1, float *u2);

/* The points of a whole pixel's secondary rays at once: `blocks` primary rays, each with
 * block_cells cells of sub * sub points (trace-gather-points: spp / 4 cells of 2 x 2). The
 * pixel's blocks * block_cells cells make one grid (pm_strata_grid), each cell cut into sub x sub
 * sub-cells holding a point each, so the pixel's points are stratified together, not a ray's
 * alone: where its rays' hits share a surface (most pixels), their gather rays cover the
 * hemisphere as one set of blocks * block_cells * sub^2 strata instead of blocks independent
 * sets. A block is block_cells consecutive cells in row-major order (neighbours, for coherent
 * packets), and the blocks are dealt to the primary rays in a random order, so that a ray's
 * place in the pixel and its directions are independent and each point is uniform on the
 * square: unbiased. Block b's points are u1, u2[b * block_cells * sub^2 ...], cell after cell,
 * a cell's sub-cells in row-major order. perm has room for `blocks` entries. Draws from rng:
 * 2 numbers per point as pm_strata_fill does, then blocks - 1 words for the order. */
void pm_strata_pixel(pm_rng_t *rng, unsigned blocks, unsigned block_cells, unsigned sub, float *u1, float *u2,
                     uint32_t *perm);

/* Cosine-weighted directions around +z (pdf cos / pi) for n points of [0,1)^2, by the
 * concentric map like pm_sample_cosine_hemisphere (within 1e-6), but branch-free with
 * polynomial sine and cosine so that the loop runs in SIMD lanes: this warp is on the
 * path of every secondary ray. */
void pm_strata_cosine(const float *u1, const float *u2, unsigned n, float *x_out, float *y_out, float *z_out);

#endif
