/* strata.c: stratified points on the unit square, whole cells at a time (see strata.h). */
#include "strata.h"

#include <math.h>
#include <stddef.h>

void pm_strata_grid(unsigned cells, unsigned *nx_out, unsigned *ny_out)
{
    unsigned ny = 1;
    for (unsigned d = 1; (unsigned long long)d * d <= cells; d++)
        if (cells % d == 0)
            ny = d;
    *ny_out = ny;
    *nx_out = cells ? cells / ny : 0;
}

/* (c + u) / n rounds up across the cell's upper edge for u close to 1 (and to 1.0 itself
 * in the last cell); step down to the largest float still inside cell c. */
static float in_cell(unsigned c, unsigned n, float u)
{
    float s = ((float)c + u) / (float)n;
    while (s > 0.0f && (unsigned)(s * (float)n) > c)
        s = nextafterf(s, 0.0f);
    return s;
}

void pm_strata_fill(pm_rng_t *rng, unsigned nx, unsigned ny, unsigned per_cell, float *u1, float *u2)
{
    size_t i = 0;
    for (unsigned cy = 0; cy < ny; cy++)
        for (unsigned cx = 0; cx < nx; cx++)
            for (unsigned k = 0; k < per_cell; k++, i++) {
                float a = pm_rng_float(rng), b = pm_rng_float(rng);
                u1[i] = in_cell(cx, nx, a);
                u2[i] = in_cell(cy, ny, b);
            }
}
