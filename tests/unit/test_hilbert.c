/* test_hilbert.c: the Hilbert curve's L-system table (common/photonmap/hilbert.c) and the reorder.
 *
 * The table is checked three ways: its rows are permutations and every state is reachable;
 * the curve it draws at levels 1 to 5 visits every cell once, consecutive cells sharing a
 * face (so it is continuous across child boundaries too); and a search over the rotations of
 * the cube derives the same table from the curve's definition. The fast reorder (keys, MSD
 * radix passes of several levels, parallel top) is compared with a plain recursive octree
 * walk of the table, point for point, on several point sets, leaf sizes and thread counts. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "photonmap/hilbert.h"
#include "unit.h"

#define S PM_HILBERT_STATES

static void test_hilbert_table_rows(void **state)
{
    int reached[S] = {1}, grew = 1;
    for (unsigned s = 0; s < S; s++) {
        unsigned seen = 0;
        for (unsigned r = 0; r < 8; r++) {
            seen |= 1u << pm_hilbert_order[s][r];
            assert_true(pm_hilbert_child[s][r] < S);
        }
        assert_int_equal(seen, 0xff); /* every child visited exactly once */
    }
    while (grew) { /* every state is reachable from the root's */
        grew = 0;
        for (unsigned s = 0; s < S; s++)
            for (unsigned r = 0; r < 8 && reached[s]; r++)
                if (!reached[pm_hilbert_child[s][r]])
                    reached[pm_hilbert_child[s][r]] = grew = 1;
    }
    for (unsigned s = 0; s < S; s++)
        assert_true(reached[s]);
}

/* Appends the cells of a cell at (x, y, z) of side 2^levels in state s, in curve order. */
static void walk(unsigned s, unsigned levels, uint32_t x, uint32_t y, uint32_t z, uint32_t (*out)[3], size_t *n)
{
    if (levels == 0) {
        out[*n][0] = x, out[*n][1] = y, out[*n][2] = z;
        (*n)++;
        return;
    }
    uint32_t h = 1u << (levels - 1);
    for (unsigned r = 0; r < 8; r++) {
        unsigned o = pm_hilbert_order[s][r];
        walk(pm_hilbert_child[s][r], levels - 1, x + (o & 1) * h, y + ((o >> 1) & 1) * h, z + ((o >> 2) & 1) * h, out,
             n);
    }
}

static void test_hilbert_curve_is_continuous(void **state)
{
    for (unsigned L = 1; L <= 5; L++) {
        size_t cells = (size_t)1 << (3 * L), n = 0;
        uint32_t(*c)[3] = malloc(cells * sizeof *c);
        unsigned char *seen = calloc(cells, 1);
        walk(0, L, 0, 0, 0, c, &n);
        assert_int_equal(n, cells);
        uint32_t side = 1u << L;
        for (size_t i = 0; i < n; i++) {
            size_t id = ((size_t)c[i][2] * side + c[i][1]) * side + c[i][0];
            assert_int_equal(seen[id], 0); /* every cell once */
            seen[id] = 1;
            if (i == 0)
                continue;
            unsigned dist = 0;
            for (int a = 0; a < 3; a++)
                dist += c[i][a] > c[i - 1][a] ? c[i][a] - c[i - 1][a] : c[i - 1][a] - c[i][a];
            if (dist != 1)
                fail_msg("level %u: cells %zu (%u %u %u) and %zu (%u %u %u) share no face", L, i - 1, c[i - 1][0],
                         c[i - 1][1], c[i - 1][2], i, c[i][0], c[i][1], c[i][2]);
        }
        /* enters at corner (0,0,0), leaves at corner (0,0,1) of the cube */
        assert_true(c[0][0] == 0 && c[0][1] == 0 && c[0][2] == 0);
        assert_true(c[n - 1][0] == 0 && c[n - 1][1] == 0 && c[n - 1][2] == side - 1);
        free(c);
        free(seen);
    }
}

/* ---- the derivation: rotations of the cube as signed permutations ---- */
typedef struct {
    int perm[3], sign[3]; /* out[a] = sign[a] * in[perm[a]] */
} rot_t;

static void rot_apply(const rot_t *m, const int *v, int *out)
{
    for (int a = 0; a < 3; a++)
        out[a] = m->sign[a] * v[m->perm[a]];
}

static rot_t rot_compose(const rot_t *m, const rot_t *n) /* m after n */
{
    rot_t r;
    for (int a = 0; a < 3; a++) {
        r.perm[a] = n->perm[m->perm[a]];
        r.sign[a] = m->sign[a] * n->sign[m->perm[a]];
    }
    return r;
}

typedef struct {
    rot_t rots[24];
    int centre[8][3]; /* child r's centre in a cube [-2, 2]^3: the Gray-code order */
    rot_t child[8];
} derive_t;

static int same3(const int *a, const int *b) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

/* Finds child orientations such that child r enters where child r - 1 left (DFS, first found). */
static int derive_children(derive_t *d, int r, const int *entry)
{
    static const int in[3] = {-1, -1, -1}, out[3] = {-1, -1, 1}, cube_exit[3] = {-2, -2, 2};
    for (int q = 0; q < 24; q++) {
        int t[3], en[3], ex[3];
        rot_apply(&d->rots[q], in, t);
        for (int a = 0; a < 3; a++)
            en[a] = d->centre[r][a] + t[a];
        if (!same3(en, entry))
            continue;
        rot_apply(&d->rots[q], out, t);
        for (int a = 0; a < 3; a++)
            ex[a] = d->centre[r][a] + t[a];
        d->child[r] = d->rots[q];
        if (r == 7) {
            if (same3(ex, cube_exit))
                return 1;
            continue;
        }
        int corner = 1; /* the exit must be a corner of the next child */
        for (int a = 0; a < 3; a++)
            corner &= ex[a] == d->centre[r + 1][a] - 1 || ex[a] == d->centre[r + 1][a] + 1;
        if (corner && derive_children(d, r + 1, ex))
            return 1;
    }
    return 0;
}

static void test_hilbert_table_derivation(void **state)
{
    static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    static const int parity[6] = {1, -1, -1, 1, 1, -1};
    derive_t d;
    int nr = 0;
    for (int p = 0; p < 6; p++)
        for (int sg = 0; sg < 8; sg++) {
            rot_t m;
            for (int a = 0; a < 3; a++)
                m.perm[a] = perms[p][a], m.sign[a] = (sg >> a) & 1 ? -1 : 1;
            int det = parity[p] * m.sign[0] * m.sign[1] * m.sign[2];
            if (det == 1)
                d.rots[nr++] = m;
        }
    assert_int_equal(nr, 24);
    for (int r = 0; r < 8; r++) {
        int g = r ^ (r >> 1);
        for (int a = 0; a < 3; a++)
            d.centre[r][a] = (g >> a) & 1 ? 1 : -1;
    }
    static const int entry[3] = {-2, -2, -2};
    assert_true(derive_children(&d, 0, entry));
    /* States are the orientations reachable from the identity, numbered as found. */
    rot_t st[S + 1];
    int ns = 1;
    st[0] = d.rots[0];
    for (int s = 0; s < ns; s++)
        for (int r = 0; r < 8; r++) {
            int c[3];
            rot_apply(&st[s], d.centre[r], c);
            unsigned o = (c[0] > 0) | (c[1] > 0) << 1 | (c[2] > 0) << 2;
            assert_int_equal(o, pm_hilbert_order[s][r]);
            rot_t m = rot_compose(&st[s], &d.child[r]);
            int found = -1;
            for (int q = 0; q < ns && found < 0; q++)
                if (!memcmp(&st[q], &m, sizeof m))
                    found = q;
            if (found < 0) {
                assert_true(ns < S);
                st[ns] = m;
                found = ns++;
            }
            assert_int_equal(found, pm_hilbert_child[s][r]);
        }
    assert_int_equal(ns, S);
}

static void test_hilbert_key_is_curve_index(void **state)
{
    const unsigned L = 4;
    size_t n = 0;
    uint32_t(*c)[3] = malloc(((size_t)1 << (3 * L)) * sizeof *c);
    walk(0, L, 0, 0, 0, c, &n);
    const double lo[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        /* a point inside cell c[i] of the level-L grid, in a 2^21 grid with scale 1 */
        float p[3];
        for (int a = 0; a < 3; a++)
            p[a] = (float)((c[i][a] << (PM_HILBERT_LEVELS - L)) + 3);
        uint64_t key = pm_reorder_key(PM_ORDER_HILBERT, p, lo, 1.0);
        assert_int_equal(key >> (3 * (PM_HILBERT_LEVELS - L)), i);
        uint64_t morton = pm_reorder_key(PM_ORDER_MORTON, p, lo, 1.0) >> (3 * (PM_HILBERT_LEVELS - L)), want = 0;
        for (int b = (int)L - 1; b >= 0; b--)
            want = want << 3 | ((c[i][0] >> b) & 1) | ((c[i][1] >> b) & 1) << 1 | ((c[i][2] >> b) & 1) << 2;
        assert_int_equal(morton, want);
    }
    free(c);
}

/* ---- the reference: a recursive octree, one level at a time, straight from the table ---- */
typedef struct {
    const uint32_t (*cell)[3];
    pm_order_t order;
    uint64_t leaf;
    unsigned depth;
} ref_t;

static void ref_sort(ref_t *rf, uint32_t *idx, size_t n, unsigned level, unsigned s, uint32_t *tmp)
{
    if (n <= rf->leaf || level == PM_HILBERT_LEVELS) {
        if (level > rf->depth)
            rf->depth = level;
        return; /* input order kept */
    }
    unsigned bit = PM_HILBERT_LEVELS - 1 - level;
    size_t at = 0, start[8], count[8];
    for (unsigned r = 0; r < 8; r++) {
        unsigned o = rf->order == PM_ORDER_HILBERT ? pm_hilbert_order[s][r] : r;
        start[r] = at;
        for (size_t i = 0; i < n; i++) {
            const uint32_t *c = rf->cell[idx[i]];
            unsigned oi = ((c[0] >> bit) & 1) | ((c[1] >> bit) & 1) << 1 | ((c[2] >> bit) & 1) << 2;
            if (oi == o)
                tmp[at++] = idx[i];
        }
        count[r] = at - start[r];
    }
    memcpy(idx, tmp, n * sizeof *idx);
    for (unsigned r = 0; r < 8; r++)
        if (count[r])
            ref_sort(rf, idx + start[r], count[r], level + 1,
                     rf->order == PM_ORDER_HILBERT ? pm_hilbert_child[s][r] : 0, tmp);
}

static void reference(const float *p, size_t n, pm_order_t order, uint64_t leaf, uint32_t *perm, unsigned *depth)
{
    double lo[3], scale;
    pm_reorder_cube(p, 3 * sizeof(float), n, lo, &scale);
    uint32_t(*cell)[3] = malloc((n + 1) * sizeof *cell), *tmp = malloc((n + 1) * sizeof *tmp);
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double c = ((double)p[3 * i + a] - lo[a]) * scale;
            cell[i][a] = c > 0 ? (c < (1 << 21) - 1 ? (uint32_t)c : (1u << 21) - 1) : 0;
        }
    for (size_t i = 0; i < n; i++)
        perm[i] = (uint32_t)i;
    ref_t rf = {(const uint32_t(*)[3])cell, order, leaf, 0};
    if (order != PM_ORDER_NONE)
        ref_sort(&rf, perm, n, 0, 0, tmp);
    *depth = rf.depth;
    free(cell);
    free(tmp);
}

enum { SET_UNIFORM, SET_SKEWED, SET_CLUSTERS, SET_PLANE, SET_LINE, SET_EQUAL, SET_HUGE, SET_DUPLICATES, NSETS };

static void point_set(int set, size_t n, float *p)
{
    pm_rng_t r;
    pm_rng_init(&r, 99, (uint64_t)set);
    for (size_t i = 0; i < n; i++) {
        float *q = p + 3 * i, u = pm_rng_float(&r), v = pm_rng_float(&r), w = pm_rng_float(&r);
        switch (set) {
        case SET_UNIFORM: q[0] = u, q[1] = v, q[2] = w; break;
        case SET_SKEWED: /* sparse points around dense clusters within clusters: cells at every
                          * scale, so that leaves fall inside multi-level passes, top and below */
            if (i % 40 == 0)
                q[0] = u, q[1] = v, q[2] = w;
            else if (i % 40 < 5)
                q[0] = 0.3f + u * 1e-3f, q[1] = 0.3f + v * 1e-3f, q[2] = 0.3f + w * 1e-3f;
            else
                q[0] = 0.3004f + u * 1e-6f, q[1] = 0.3004f + v * 1e-6f, q[2] = 0.3004f + w * 1e-6f;
            break;
        case SET_CLUSTERS: /* a few tight clusters far apart: deep, unbalanced octrees */
            q[0] = (float)(i % 5) * 100.0f + u * 1e-3f, q[1] = v * 1e-3f, q[2] = (float)(i % 3) + w * 1e-4f;
            break;
        case SET_PLANE: q[0] = u, q[1] = 2.0f, q[2] = w; break;
        case SET_LINE: q[0] = q[1] = q[2] = u; break;
        case SET_EQUAL: q[0] = 1.5f, q[1] = -2.0f, q[2] = 3.0f; break;
        case SET_HUGE: /* extent 2e30: must not overflow anything */
            q[0] = (u - 0.5f) * 2e30f, q[1] = v < 0.5f ? -1e30f : 1e30f, q[2] = w;
            break;
        case SET_DUPLICATES: /* many points on few distinct positions */
            q[0] = (float)(i % 7), q[1] = (float)(i % 3), q[2] = 0.0f;
            break;
        }
    }
}

static void test_hilbert_reorder_matches_reference(void **state)
{
    const size_t n = 20000;
    float *p = malloc(n * 3 * sizeof *p);
    uint32_t *want = malloc(n * sizeof *want), *got = malloc(n * sizeof *got);
    static const uint64_t leaves[] = {1, 2, 16, 100, 5000, 30000};
    int saved = omp_get_max_threads();
    for (int set = 0; set < NSETS; set++) {
        point_set(set, n, p);
        for (int order = PM_ORDER_NONE; order <= PM_ORDER_HILBERT; order++)
            for (size_t li = 0; li < sizeof leaves / sizeof leaves[0]; li++) {
                unsigned want_depth;
                reference(p, n, (pm_order_t)order, leaves[li], want, &want_depth);
                for (int threads = 1; threads <= 3; threads++) {
                    omp_set_num_threads(threads);
                    pm_reorder_info_t info;
                    memset(got, 0xff, n * sizeof *got);
                    assert_int_equal(
                        pm_reorder_points(p, 3 * sizeof(float), n, (pm_order_t)order, leaves[li], got, &info), PM_OK);
                    if (memcmp(want, got, n * sizeof *got) != 0)
                        fail_msg("set %d order %d leaf %llu threads %d: order differs from the reference", set, order,
                                 (unsigned long long)leaves[li], threads);
                    if (order != PM_ORDER_NONE && info.depth != want_depth)
                        fail_msg("set %d leaf %llu: depth %u, reference %u", set, (unsigned long long)leaves[li],
                                 info.depth, want_depth);
                }
            }
    }
    omp_set_num_threads(saved);
    free(p);
    free(want);
    free(got);
}

static void test_hilbert_degenerate(void **state)
{
    float p[3 * 4] = {1, 2, 3, -1e30f, 1e30f, 0, 3e38f, -3e38f, 1, 0, 0, 0};
    uint32_t perm[4];
    pm_reorder_info_t info;
    assert_int_equal(pm_reorder_points(p, 12, 0, PM_ORDER_HILBERT, 1, perm, &info), PM_OK); /* no points */
    assert_int_equal(pm_reorder_points(p, 12, 1, PM_ORDER_HILBERT, 1, perm, &info), PM_OK);
    assert_int_equal(perm[0], 0);
    assert_int_equal(pm_reorder_points(p, 12, 4, PM_ORDER_HILBERT, 1, perm, &info), PM_OK);
    unsigned seen = 0;
    for (int i = 0; i < 4; i++)
        seen |= 1u << perm[i];
    assert_int_equal(seen, 0xf);
    /* all points equal: the octree goes to its last level and keeps the input order */
    const size_t n = 1000;
    float *q = malloc(n * 3 * sizeof *q);
    uint32_t *pp = malloc(n * sizeof *pp);
    point_set(SET_EQUAL, n, q);
    assert_int_equal(pm_reorder_points(q, 12, n, PM_ORDER_HILBERT, 16, pp, &info), PM_OK);
    for (size_t i = 0; i < n; i++)
        assert_int_equal(pp[i], i);
    assert_int_equal(info.depth, PM_HILBERT_LEVELS);
    assert_int_equal(info.leaves, 1);
    /* records wider than a position (stride 40) are read in place */
    assert_int_equal(pm_reorder_points(q, 40, n * 12 / 40, PM_ORDER_MORTON, 1, pp, &info), PM_OK);
    free(q);
    free(pp);
    assert_int_equal(pm_reorder_points(p, 12, 4, PM_ORDER_HILBERT, 0, perm, &info), PM_ERR_INTERNAL); /* leaf 0 */
}

static void test_hilbert_auto_leaf(void **state)
{
    assert_int_equal(pm_reorder_auto_leaf(0, 1 << 20), 1);
    assert_int_equal(pm_reorder_auto_leaf(10, 1 << 20), 10);   /* one leaf: nothing to sort */
    assert_int_equal(pm_reorder_auto_leaf(50000, 1 << 20), 1); /* 600 KB of pairs fit in 1 MiB */
    /* 10 million points: 16 needs 7 levels (8^7 cells); 5 points per cell reach the same depth */
    assert_int_equal(pm_reorder_auto_leaf(10000000, 1 << 20), 5);
    for (uint64_t n = 17; n < 100000000; n = n * 3 + 1) {
        uint64_t l = pm_reorder_auto_leaf(n, 1 << 16);
        assert_true(l >= 1 && l <= 16);
    }
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_hilbert_table_rows),
    cmocka_unit_test(test_hilbert_curve_is_continuous),
    cmocka_unit_test(test_hilbert_table_derivation),
    cmocka_unit_test(test_hilbert_key_is_curve_index),
    cmocka_unit_test(test_hilbert_reorder_matches_reference),
    cmocka_unit_test(test_hilbert_degenerate),
    cmocka_unit_test(test_hilbert_auto_leaf),
};
UNIT_GROUP(unit_hilbert, "hilbert", tests);
