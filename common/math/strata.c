/* strata.c: stratified points on the unit square, whole cells at a time (see strata.h). */
#include "math/strata.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

void pm_strata_grid(unsigned cells, unsigned *nx_out, unsigned *ny_out)
{
    unsigned ny = 1;
    for (unsigned d = 1; (unsigned long long)d * d <= cells; d++)
        if (cells % d == 0)
            ny = d;
    *ny_out = ny;
    *nx_out = cells ? cells / ny : 0;
}

/* (c + u) / n for u in [0, 1), kept inside cell c: the product with the reciprocal can land
 * an ulp outside it either way, and (c + u) rounds up to the upper edge for u near 1. One
 * ulp is a step of 1 in the bits of a positive float; two steps cover every case. */
static inline float in_cell(unsigned c, float fn, float inv_n, float u)
{
    float s = ((float)c + u) * inv_n;
    if ((unsigned)(s * fn) == c)
        return s; /* the common case: neither step below would move it */
    for (int step = 0; step < 2; step++) {
        unsigned cell = (unsigned)(s * fn);
        uint32_t bits;
        memcpy(&bits, &s, 4);
        bits += cell < c ? 1u : 0u;
        bits -= cell > c && bits > 0 ? 1u : 0u;
        memcpy(&s, &bits, 4);
    }
    return s;
}

void pm_strata_fill(pm_rng_t *rng, unsigned nx, unsigned ny, unsigned per_cell, float *u1, float *u2)
{
    size_t n = (size_t)nx * ny * per_cell;
    if (rng->used == 4 && n % 2 == 0) {
        /* The same words pm_rng_float would hand out, whole Philox blocks at a time: each
         * block is a function of its counter alone, so they run in SIMD lanes. Block j gives
         * points 2j and 2j + 1: u1, u2, u1, u2. */
        uint64_t first = (uint64_t)rng->ctr[0] | (uint64_t)rng->ctr[1] << 32;
        size_t nb = n / 2;
        uint32_t k0 = rng->key[0], k1 = rng->key[1], c2 = rng->ctr[2], c3 = rng->ctr[3];
#pragma omp simd
        for (size_t j = 0; j < nb; j++) {
            uint64_t b = first + j;
            uint32_t x0 = (uint32_t)b, x1 = (uint32_t)(b >> 32), x2 = c2, x3 = c3, y0 = k0, y1 = k1;
            /* pm_philox4x32_10 of rng.h, its rounds written out so the loop has no inner loop */
#define PHILOX_ROUND                                                                                                   \
    do {                                                                                                               \
        uint64_t p0 = (uint64_t)0xD2511F53u * x0, p1 = (uint64_t)0xCD9E8D57u * x2;                                     \
        uint32_t n0 = (uint32_t)(p1 >> 32) ^ x1 ^ y0, n1 = (uint32_t)p1;                                               \
        uint32_t n2 = (uint32_t)(p0 >> 32) ^ x3 ^ y1, n3 = (uint32_t)p0;                                               \
        x0 = n0, x1 = n1, x2 = n2, x3 = n3;                                                                            \
        y0 += 0x9E3779B9u, y1 += 0xBB67AE85u;                                                                          \
    } while (0)
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
            PHILOX_ROUND;
#undef PHILOX_ROUND
            u1[2 * j] = (float)(x0 >> 8) * 0x1p-24f;
            u2[2 * j] = (float)(x1 >> 8) * 0x1p-24f;
            u1[2 * j + 1] = (float)(x2 >> 8) * 0x1p-24f;
            u2[2 * j + 1] = (float)(x3 >> 8) * 0x1p-24f;
        }
        first += nb;
        rng->ctr[0] = (uint32_t)first;
        rng->ctr[1] = (uint32_t)(first >> 32);
    } else {
        for (size_t i = 0; i < n; i++) { /* the draws, in order: u1 then u2 of each point */
            u1[i] = pm_rng_float(rng);
            u2[i] = pm_rng_float(rng);
        }
    }
    /* Point i into cell (i / per_cell) % nx, (i / per_cell) / nx. (c + u) / n can round up
     * across the cell's upper edge for u close to 1 (to 1.0 itself in the last cell) or, with
     * the reciprocal, down across the lower one; a step of one ulp puts it back, checked by
     * the same float arithmetic a reader of the cell uses. */
    if (nx == 1 && ny == 1)
        return; /* one cell: (0 + u) * 1 is u, below 1, already in it */
    float fnx = (float)nx, fny = (float)ny, inx = 1.0f / fnx, iny = 1.0f / fny;
    size_t i = 0;
    for (unsigned cy = 0; cy < ny; cy++)
        for (unsigned cx = 0; cx < nx; cx++)
            for (unsigned k = 0; k < per_cell; k++, i++) {
                u1[i] = in_cell(cx, fnx, inx, u1[i]);
                u2[i] = in_cell(cy, fny, iny, u2[i]);
            }
}

void pm_strata_pixel(pm_rng_t *rng, unsigned blocks, unsigned block_cells, unsigned sub, float *u1, float *u2,
                     uint32_t *perm)
{
    unsigned nx, ny, per = sub * sub;
    pm_strata_grid(blocks * block_cells, &nx, &ny);
    /* the uniform numbers first, whole Philox blocks at a time (pm_strata_fill's SIMD path, one
     * cell of them all), then the order, then each point into its sub-cell */
    size_t n = (size_t)blocks * block_cells * per;
    pm_strata_fill(rng, 1, 1, (unsigned)n, u1, u2);
    for (unsigned b = 0; b < blocks; b++)
        perm[b] = b;
    for (unsigned b = blocks; b > 1; b--) { /* Fisher-Yates: a uniform order of the blocks */
        unsigned k = (unsigned)(((uint64_t)pm_rng_u32(rng) * b) >> 32);
        uint32_t t = perm[b - 1];
        perm[b - 1] = perm[k], perm[k] = t;
    }
    /* the fine grid: nx * sub columns, ny * sub rows */
    float fnx = (float)(nx * sub), fny = (float)(ny * sub), inx = 1.0f / fnx, iny = 1.0f / fny;
    size_t i = 0;
    for (unsigned b = 0; b < blocks; b++)
        for (unsigned k = 0; k < block_cells; k++) {
            unsigned cell = perm[b] * block_cells + k, cx = cell % nx, cy = cell / nx;
            for (unsigned sy = 0; sy < sub; sy++)
                for (unsigned sx = 0; sx < sub; sx++, i++) {
                    u1[i] = in_cell(cx * sub + sx, fnx, inx, u1[i]);
                    u2[i] = in_cell(cy * sub + sy, fny, iny, u2[i]);
                }
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
        float t = num / (r != 0.0f ? r : 1.0f); /* in [-1, 1]; r = 0 only at the centre, where num = 0 */
        float ang = 0.78539816339744831f * t, s = sin_quarter(ang), c = cos_quarter(ang);
        float x = r * (wide ? c : s), y = r * (wide ? s : c);
        x_out[i] = x;
        y_out[i] = y;
        z_out[i] = sqrtf(fmaxf(1.0f - x * x - y * y, 0.0f));
    }
}
