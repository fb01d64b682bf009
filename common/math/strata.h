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

/* Cosine-weighted directions around +z (pdf cos / pi) for n points of [0,1)^2, by the
 * concentric map like pm_sample_cosine_hemisphere (within 1e-6), but branch-free with
 * polynomial sine and cosine so that the loop runs in SIMD lanes: this warp is on the
 * path of every secondary ray. */
void pm_strata_cosine(const float *u1, const float *u2, unsigned n, float *x_out, float *y_out, float *z_out);

#endif
