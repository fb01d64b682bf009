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

void pm_strata_fill(pm_rng_t *rng, unsigned nx, unsigned ny, unsigned per_cell, float *u1, float *u2)
{
    size_t n = (size_t)nx * ny * per_cell;
    for (size_t i = 0; i < n; i++) { /* the draws, in order: u1 then u2 of each point */
        u1[i] = pm_rng_float(rng);
        u2[i] = pm_rng_float(rng);
    }
    /* Point i into cell (i / per_cell) % nx, (i / per_cell) / nx. (c + u) / n can round up
     * across the cell's upper edge for u close to 1 (to 1.0 itself in the last cell) or, with
     * the reciprocal, down across the lower one; a step of one ulp puts it back, checked by
     * the same float arithmetic a reader of the cell uses. */
    float fnx = (float)nx, fny = (float)ny, inx = 1.0f / fnx, iny = 1.0f / fny;
    unsigned cells_per_row = nx * per_cell;
#pragma omp simd
    for (size_t i = 0; i < n; i++) {
        unsigned cell = (unsigned)(i / per_cell), cx = cell % nx, cy = (unsigned)(i / cells_per_row);
        float s = ((float)cx + u1[i]) * inx, t = ((float)cy + u2[i]) * iny;
        s = (unsigned)(s * fnx) > cx ? nextafterf(s, 0.0f) : (unsigned)(s * fnx) < cx ? nextafterf(s, 1.0f) : s;
        t = (unsigned)(t * fny) > cy ? nextafterf(t, 0.0f) : (unsigned)(t * fny) < cy ? nextafterf(t, 1.0f) : t;
        u1[i] = s;
        u2[i] = t;
    }
}

/* sin and cos on [-pi/4, pi/4]: Taylor polynomials to degree 9 and 10, whose truncation
 * error there is below 4e-9 and 3e-10, under float rounding. */
static inline float sin_quarter(float a)
{
    float a2 = a * a;
    return a * (1.0f + a2 * (-1.0f / 6 + a2 * (1.0f / 120 + a2 * (-1.0f / 5040 + a2 * (1.0f / 362880)))));
}

static inline float cos_quarter(float a)
{
    float a2 = a * a;
    return 1.0f + a2 * (-0.5f + a2 * (1.0f / 24 + a2 * (-1.0f / 720 + a2 * (1.0f / 40320 + a2 * (-1.0f / 3628800)))));
}

void pm_strata_cosine(const float *u1, const float *u2, unsigned n, float *x_out, float *y_out, float *z_out)
{
#pragma omp simd
    for (unsigned i = 0; i < n; i++) {
        float a = 2.0f * u1[i] - 1.0f, b = 2.0f * u2[i] - 1.0f;
        int wide = fabsf(a) > fabsf(b); /* which triangle pair of the square the point is in */
        float r = wide ? a : b, num = wide ? b : a;
        float t = r != 0.0f ? num / r : 0.0f; /* in [-1, 1]; r = 0 only at the centre */
        float ang = 0.78539816339744831f * t, s = sin_quarter(ang), c = cos_quarter(ang);
        float x = r * (wide ? c : s), y = r * (wide ? s : c);
        float z2 = 1.0f - x * x - y * y;
        x_out[i] = x;
        y_out[i] = y;
        z_out[i] = z2 > 0.0f ? sqrtf(z2) : 0.0f;
    }
}
