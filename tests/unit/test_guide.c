/* test_guide.c: the photon guide of the secondary rays (render/guide.h): its pdf integrates to
 * one over the sphere, its samples follow its pdf (chi-square over the bins and inside them),
 * first-hit photons and sparse cells are left out, and the normal's axis splits a cell. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "math/sampling.h"
#include "render/guide.h"
#include "unit.h"

/* n photons on the floor y = 0 within [0, size)^2 in x and z, normal +y, each arriving from a
 * direction drawn from two lobes (toward +x+y, and straight up, 3:1 in power), depth 1 unless
 * depth0 says which share comes straight from a light (depth 0). */
typedef struct {
    float *pos, *power, *normal, *dir;
    uint32_t *depth;
    uint64_t n;
} photons_t;

static void photons_make(photons_t *p, uint64_t n, float size, const float nrm[3], float depth0)
{
    p->n = n;
    p->pos = malloc(n * 3 * sizeof(float));
    p->power = malloc(n * 3 * sizeof(float));
    p->normal = malloc(n * 3 * sizeof(float));
    p->dir = malloc(n * 3 * sizeof(float));
    p->depth = malloc(n * sizeof(uint32_t));
    assert_non_null(p->pos), assert_non_null(p->power), assert_non_null(p->normal), assert_non_null(p->dir);
    assert_non_null(p->depth);
    pm_rng_t r;
    pm_rng_init(&r, 5, 0);
    for (uint64_t i = 0; i < n; i++) {
        p->pos[3 * i] = pm_rng_float(&r) * size, p->pos[3 * i + 1] = 0.0f, p->pos[3 * i + 2] = pm_rng_float(&r) * size;
        int a = pm_rng_float(&r) < 0.75f;
        float d[3] = {a ? 0.7071f : 0.0f, a ? 0.7071f : 1.0f, 0.0f};
        d[0] += 0.1f * (pm_rng_float(&r) - 0.5f), d[2] += 0.1f * (pm_rng_float(&r) - 0.5f);
        float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; k++)
            p->dir[3 * i + k] = d[k] / l, p->power[3 * i + k] = 0.01f, p->normal[3 * i + k] = nrm[k];
        p->depth[i] = pm_rng_float(&r) < depth0 ? 0u : 1u;
    }
}

static void photons_free(photons_t *p) { free(p->pos), free(p->power), free(p->normal), free(p->dir), free(p->depth); }

static pm_guide_t *build(const photons_t *p)
{
    const pm_guide_photons_t ph = {p->pos, p->power, p->normal, p->dir, p->depth, p->n};
    pm_guide_t *g = NULL;
    assert_int_equal(pm_guide_build(&ph, 0, &g), PM_OK);
    assert_non_null(g);
    return g;
}

static const float up[3] = {0.0f, 1.0f, 0.0f};

/* The two-lobed floor of 20,000 photons (photons_make), its guide in *g and the cell at its middle. */
static const pm_guide_cell_t *floor_cell(photons_t *p, pm_guide_t **g)
{
    photons_make(p, 20000, 1.0f, up, 0.0f);
    *g = build(p);
    float at[3] = {0.5f, 0.0f, 0.5f};
    const pm_guide_cell_t *c = pm_guide_find(*g, at, up);
    assert_non_null(c);
    return c;
}

/* The pdf over a fine equal-area grid of the sphere sums to one. */
static void test_guide_pdf_integrates_to_one(void **state)
{
    photons_t p;
    pm_guide_t *g;
    const pm_guide_cell_t *c = floor_cell(&p, &g);
    enum { NZ = 256, NP = 512 };
    double sum = 0.0, dA = 4.0 * PM_PI / (NZ * NP);
    for (int i = 0; i < NZ; i++)
        for (int j = 0; j < NP; j++) {
            float y = -1.0f + (i + 0.5f) * 2.0f / NZ, phi = -PM_PI + (j + 0.5f) * 2.0f * PM_PI / NP;
            float s = sqrtf(1.0f - y * y), w[3] = {s * cosf(phi), y, s * sinf(phi)};
            sum += pm_guide_pdf(c, w) * dA;
        }
    assert_true(fabs(sum - 1.0) < 1e-3);
    pm_guide_destroy(g);
    photons_free(&p);
}

/* Samples fall in the bins as the pdf says (chi-square), are unit vectors whose pdf is
 * positive, and spread evenly inside a bin (the two halves of the busiest bin by height). */
static void test_guide_samples_follow_pdf(void **state)
{
    photons_t p;
    pm_guide_t *g;
    const pm_guide_cell_t *c = floor_cell(&p, &g);
    enum { N = 200000 };
    static unsigned hist[PM_GUIDE_BINS];
    memset(hist, 0, sizeof hist);
    unsigned best = 0, lower = 0, inbest = 0;
    for (unsigned b = 0; b < PM_GUIDE_BINS; b++)
        if (c->pdf[b] > c->pdf[best])
            best = b;
    pm_rng_t r;
    pm_rng_init(&r, 9, 1);
    for (unsigned i = 0; i < N; i++) {
        float w[3];
        pm_guide_sample(c, pm_rng_float(&r), pm_rng_float(&r), w);
        assert_true(fabsf(w[0] * w[0] + w[1] * w[1] + w[2] * w[2] - 1.0f) < 1e-4f);
        assert_true(pm_guide_pdf(c, w) > 0.0f);
        unsigned b = pm_guide_bin(w);
        hist[b]++;
        if (b == best) {
            inbest++;
            float y0 = -1.0f + (float)(b / PM_GUIDE_NPHI) * 2.0f / PM_GUIDE_NZ;
            lower += w[1] < y0 + 1.0f / PM_GUIDE_NZ;
        }
    }
    double chi2 = 0.0;
    int dof = -1;
    for (unsigned b = 0; b < PM_GUIDE_BINS; b++) {
        double e = (double)c->pdf[b] * N;
        if (e == 0.0) {
            assert_int_equal(hist[b], 0); /* an empty bin is never drawn */
            continue;
        }
        chi2 += (hist[b] - e) * (hist[b] - e) / e;
        dof++;
    }
    /* chi-square with dof degrees of freedom: mean dof, sd sqrt(2 dof); 5 sd is far out */
    assert_true(dof > 0);
    assert_true(chi2 < dof + 5.0 * sqrt(2.0 * dof));
    assert_true(fabs((double)lower / inbest - 0.5) < 0.02);
    pm_guide_destroy(g);
    photons_free(&p);
}

/* First hits (depth 0) are not used; with no others the guide has no cell and finds none. */
static void test_guide_first_hits_left_out(void **state)
{
    photons_t p;
    photons_make(&p, 5000, 1.0f, up, 1.0f);
    pm_guide_t *g = build(&p);
    assert_int_equal(pm_guide_info(g)->photons_used, 0);
    assert_int_equal(pm_guide_info(g)->cells, 0);
    float at[3] = {0.5f, 0.0f, 0.5f};
    assert_null(pm_guide_find(g, at, up));
    pm_guide_destroy(g);
    photons_free(&p);
    photons_make(&p, 20000, 1.0f, up, 0.5f);
    g = build(&p);
    assert_true(pm_guide_info(g)->photons_used > 9000 && pm_guide_info(g)->photons_used < 11000);
    pm_guide_destroy(g);
    photons_free(&p);
}

/* A cell with fewer than PM_GUIDE_MIN photons falls back (no cell); far from every photon too;
 * the other side of the floor (normal -y) is another cell, absent here. */
static void test_guide_sparse_and_sides(void **state)
{
    photons_t p;
    photons_make(&p, 20000, 1.0f, up, 0.0f);
    /* one far photon group below the minimum */
    for (int i = 0; i < PM_GUIDE_MIN - 1; i++)
        p.pos[3 * i] = 50.0f, p.pos[3 * i + 2] = 50.0f;
    pm_guide_t *g = build(&p);
    float far[3] = {50.0f, 0.0f, 50.0f}, out[3] = {-10.0f, 0.0f, -10.0f}, at[3] = {0.5f, 0.0f, 0.5f};
    float down[3] = {0.0f, -1.0f, 0.0f};
    assert_null(pm_guide_find(g, far, up));
    assert_true(pm_guide_info(g)->cells_sparse >= 1);
    assert_null(pm_guide_find(g, out, up));
    assert_non_null(pm_guide_find(g, at, up));
    assert_null(pm_guide_find(g, at, down));
    pm_guide_destroy(g);
    photons_free(&p);
}

/* Light that arrives evenly (photon directions cosine-weighted about the normal): cosine
 * sampling is exact there, the cell is left out (cells_even), unless every cell is asked for. */
static void test_guide_even_light_left_out(void **state)
{
    photons_t p;
    photons_make(&p, 20000, 1.0f, up, 0.0f);
    pm_rng_t r;
    pm_rng_init(&r, 3, 0);
    for (uint64_t i = 0; i < p.n; i++) {
        pm_vec3_t d = pm_sample_cosine_hemisphere(pm_rng_float(&r), pm_rng_float(&r)); /* about +z */
        p.dir[3 * i] = d.x, p.dir[3 * i + 1] = d.z, p.dir[3 * i + 2] = d.y;
    }
    float at[3] = {0.5f, 0.0f, 0.5f};
    pm_guide_t *g = build(&p);
    assert_null(pm_guide_find(g, at, up));
    assert_true(pm_guide_info(g)->cells_even >= 1);
    pm_guide_destroy(g);
    const pm_guide_photons_t ph = {p.pos, p.power, p.normal, p.dir, p.depth, p.n};
    assert_int_equal(pm_guide_build(&ph, 1, &g), PM_OK);
    assert_non_null(pm_guide_find(g, at, up));
    assert_int_equal(pm_guide_info(g)->cells_even, 0);
    pm_guide_destroy(g);
    photons_free(&p);
}

/* No photons at all: an empty guide, no lookups. */
static void test_guide_empty(void **state)
{
    const pm_guide_photons_t ph = {0};
    pm_guide_t *g = NULL;
    assert_int_equal(pm_guide_build(&ph, 0, &g), PM_OK);
    float at[3] = {0, 0, 0};
    assert_null(pm_guide_find(g, at, up));
    pm_guide_destroy(g);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_guide_pdf_integrates_to_one), cmocka_unit_test(test_guide_samples_follow_pdf),
    cmocka_unit_test(test_guide_first_hits_left_out),   cmocka_unit_test(test_guide_sparse_and_sides),
    cmocka_unit_test(test_guide_even_light_left_out),   cmocka_unit_test(test_guide_empty),
};
UNIT_GROUP(unit_guide, "guide", tests);
