/* test_strata.c: the final-gather sampler puts exactly four points in every cell. */
#include <math.h>
#include <stdlib.h>

#include "math/sampling.h"
#include "math/strata.h"
#include "unit.h"

static void test_strata_grid_shapes(void **state)
{
    static const unsigned cases[][3] = {{1, 1, 1},  {2, 2, 1}, {4, 2, 2},     {16, 4, 4}, {25, 5, 5},
                                        {12, 4, 3}, {7, 7, 1}, {144, 12, 12}, {18, 6, 3}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        unsigned nx, ny;
        pm_strata_grid(cases[i][0], &nx, &ny);
        assert_int_equal(nx, cases[i][1]);
        assert_int_equal(ny, cases[i][2]);
        assert_int_equal(nx * ny, cases[i][0]);
    }
}

/* Every spp that is a multiple of 4 up to 256: each cell gets exactly four points, and
 * they come cell by cell, in row-major order. */
static void test_strata_four_per_cell(void **state)
{
    float *u1 = malloc(256 * sizeof *u1), *u2 = malloc(256 * sizeof *u2);
    unsigned *count = malloc(64 * sizeof *count);
    assert_non_null(u1);
    assert_non_null(u2);
    assert_non_null(count);
    for (unsigned spp = 4; spp <= 256; spp += 4) {
        unsigned cells = spp / 4, nx, ny;
        pm_strata_grid(cells, &nx, &ny);
        for (uint64_t pixel = 0; pixel < 50; pixel++) {
            pm_rng_t r;
            pm_rng_init(&r, 7, pixel);
            pm_strata_fill(&r, nx, ny, 4, u1, u2);
            for (unsigned c = 0; c < cells; c++)
                count[c] = 0;
            for (unsigned i = 0; i < spp; i++) {
                assert_true(u1[i] >= 0.0f && u1[i] < 1.0f && u2[i] >= 0.0f && u2[i] < 1.0f);
                unsigned cx = (unsigned)(u1[i] * (float)nx), cy = (unsigned)(u2[i] * (float)ny);
                assert_int_equal(cy * nx + cx, i / 4);
                count[cy * nx + cx]++;
            }
            for (unsigned c = 0; c < cells; c++)
                assert_int_equal(count[c], 4);
        }
    }
    free(u1), free(u2), free(count);
}

/* The block-at-a-time draw hands out the numbers pm_rng_float would, and leaves the
 * generator where sequential draws would. */
static void test_strata_same_draws(void **state)
{
    float a1[64], a2[64];
    for (unsigned spp = 4; spp <= 64; spp += 4) {
        pm_rng_t r, s;
        pm_rng_init(&r, 99, 5);
        pm_rng_init(&s, 99, 5);
        unsigned nx, ny;
        pm_strata_grid(spp / 4, &nx, &ny);
        pm_strata_fill(&r, nx, ny, 4, a1, a2);
        for (unsigned i = 0; i < spp; i++) {
            float u = pm_rng_float(&s), v = pm_rng_float(&s);
            assert_true((unsigned)(a1[i] * nx) == (i / 4) % nx && (unsigned)(a2[i] * ny) == (i / 4) / nx);
            assert_true(fabsf(a1[i] * nx - (float)((i / 4) % nx) - u) < 1e-5f * nx);
            assert_true(fabsf(a2[i] * ny - (float)((i / 4) / nx) - v) < 1e-5f * ny);
        }
        assert_int_equal(pm_rng_u32(&r), pm_rng_u32(&s));
    }
}

/* Points drawn at the very top of a cell stay inside it. */
static void test_strata_cell_edges(void **state)
{
    /* A generator whose words are all ones gives u = 1 - 2^-24 for every draw. */
    pm_rng_t r;
    pm_rng_init(&r, 1, 0);
    r.buf[0] = r.buf[1] = r.buf[2] = r.buf[3] = 0xffffffffu;
    r.used = 0;
    float u1[4], u2[4];
    pm_strata_fill(&r, 3, 1, 1, u1, u2);
    for (unsigned c = 0; c < 2; c++) {
        assert_int_equal((unsigned)(u1[c] * 3.0f), c);
        assert_true(u2[c] < 1.0f);
    }
}

/* The batch warp is the concentric cosine map of sampling.h, within float noise. */
static void test_strata_cosine_matches_concentric(void **state)
{
    enum { N = 4096 };
    static float u1[N], u2[N], x[N], y[N], z[N];
    pm_rng_t r;
    pm_rng_init(&r, 11, 0);
    for (unsigned i = 0; i < N; i++)
        u1[i] = pm_rng_float(&r), u2[i] = pm_rng_float(&r);
    u1[0] = u2[0] = 0.5f; /* the centre */
    u1[1] = 0.0f, u2[1] = 0.5f;
    pm_strata_cosine(u1, u2, N, x, y, z);
    for (unsigned i = 0; i < N; i++) {
        pm_vec3_t d = pm_sample_cosine_hemisphere(u1[i], u2[i]);
        assert_true(fabsf(d.x - x[i]) < 2e-6f && fabsf(d.y - y[i]) < 2e-6f && fabsf(d.z - z[i]) < 2e-3f);
        assert_true(fabsf(x[i] * x[i] + y[i] * y[i] + z[i] * z[i] - 1.0f) < 1e-5f && z[i] >= 0.0f);
    }
}

/* A pixel's points (pm_strata_pixel): for every shape (blocks x block_cells cells of sub x sub),
 * each sub-cell of the pixel's fine grid holds exactly one point; a block's cells are
 * consecutive in row-major order and each cell's points are its sub-cells in row-major order;
 * the blocks are dealt in an order that depends on the stream (every block is first for some
 * seed), and the same stream gives the same points. */
static void test_strata_pixel_cover(void **state)
{
    static const unsigned shapes[][3] = {{16, 1, 2}, {1, 1, 2},  {3, 1, 2},  {8, 2, 2},
                                         {5, 4, 2},  {64, 1, 1}, {12, 1, 1}, {7, 3, 1}};
    enum { MAXN = 256 };
    float u1[MAXN], u2[MAXN], v1[MAXN], v2[MAXN];
    uint32_t perm[MAXN];
    unsigned count[MAXN];
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; s++) {
        unsigned blocks = shapes[s][0], bc = shapes[s][1], sub = shapes[s][2], nx, ny;
        unsigned n = blocks * bc * sub * sub, first_seen = 0;
        pm_strata_grid(blocks * bc, &nx, &ny);
        unsigned fx = nx * sub, fy = ny * sub;
        assert_true(n <= MAXN && fx * fy == n);
        for (uint64_t seed = 1; seed <= 64; seed++) {
            pm_rng_t r, r2;
            pm_rng_init(&r, seed, 3), pm_rng_init(&r2, seed, 3);
            pm_strata_pixel(&r, blocks, bc, sub, u1, u2, perm);
            pm_strata_pixel(&r2, blocks, bc, sub, v1, v2, perm);
            assert_memory_equal(u1, v1, n * sizeof(float));
            assert_memory_equal(u2, v2, n * sizeof(float));
            for (unsigned i = 0; i < n; i++)
                count[i] = 0;
            for (unsigned i = 0; i < n; i++) {
                assert_true(u1[i] >= 0.0f && u1[i] < 1.0f && u2[i] >= 0.0f && u2[i] < 1.0f);
                unsigned cx = (unsigned)(u1[i] * (float)fx), cy = (unsigned)(u2[i] * (float)fy);
                count[cy * fx + cx]++;
                /* the cell and sub-cell point i is dealt: block i / (bc sub^2), its cells in order */
                unsigned k = i % (bc * sub * sub), cell_k = k / (sub * sub), in = k % (sub * sub);
                unsigned cell = (cy / sub) * nx + cx / sub;
                if (k == 0 && cell == 0)
                    first_seen |= 1u << ((i / (bc * sub * sub)) % 32);
                assert_int_equal(cx % sub + sub * (cy % sub), in);
                if (cell_k > 0) { /* the block's previous cell is this one's row-major predecessor */
                    unsigned j = i - sub * sub;
                    unsigned pcell = (unsigned)(u2[j] * (float)fy) / sub * nx + (unsigned)(u1[j] * (float)fx) / sub;
                    assert_int_equal(pcell + 1, cell);
                }
            }
            for (unsigned c = 0; c < n; c++)
                assert_int_equal(count[c], 1);
        }
        /* which ray gets the first block changes with the stream */
        if (blocks > 1 && blocks <= 32)
            assert_int_equal(first_seen, blocks == 32 ? 0xffffffffu : (1u << blocks) - 1u);
    }
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_strata_pixel_cover), cmocka_unit_test(test_strata_cosine_matches_concentric),
    cmocka_unit_test(test_strata_grid_shapes), cmocka_unit_test(test_strata_four_per_cell),
    cmocka_unit_test(test_strata_cell_edges),  cmocka_unit_test(test_strata_same_draws),
};
UNIT_GROUP(unit_strata, "strata", tests);
