/* test_kdtree.c: the photon KD-tree build and searches (common/photonmap/kdtree.c).
 *
 * Every tree is checked by an invariant walk written here, independent of the photon-map
 * reader's: node i holds input photon perm[i] and perm is a permutation; every photon of a
 * left subtree is <= its ancestor's photon on the ancestor's axis and every right one >=;
 * the split value is the photon's coordinate with the axis in the low 2 mantissa bits; a
 * balanced tree of n photons is ceil(log2(n + 1)) levels deep. The reader's check must
 * accept the same tree. Searches are compared with brute force. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "photonmap/kdtree.h"
#include "unit.h"

typedef struct {
    pm_kdnode_t *node;
    uint32_t *perm;
    float *pos;      /* input order */
    float *tree_pos; /* node order */
    uint32_t n;
} tree_t;

static void tree_build(tree_t *t, const float *pos, uint32_t n)
{
    t->n = n;
    t->pos = malloc((n ? n : 1) * 12);
    t->tree_pos = malloc((n ? n : 1) * 12);
    t->node = malloc((n ? n : 1) * sizeof *t->node);
    t->perm = malloc((n ? n : 1) * sizeof *t->perm);
    assert_non_null(t->pos);
    memcpy(t->pos, pos, (size_t)n * 12);
    pm_kd_build_stats_t st;
    assert_int_equal(pm_kd_build(pos, n, t->node, t->perm, &st), PM_OK);
    for (uint32_t i = 0; i < n; i++)
        memcpy(&t->tree_pos[3 * i], &pos[3 * (size_t)t->perm[i]], 12);
    unsigned balanced = 0;
    while ((1ull << balanced) < (uint64_t)n + 1)
        balanced++;
    assert_int_equal(st.depth, balanced);
}

static void tree_free(tree_t *t)
{
    free(t->pos);
    free(t->tree_pos);
    free(t->node);
    free(t->perm);
}

/* Checks subtree [i, e) against the box lo..hi its ancestors allow; returns its depth. */
static unsigned check_subtree(const tree_t *t, uint32_t i, uint32_t e, const float lo[3], const float hi[3])
{
    assert_true(i < e);
    const float *p = &t->tree_pos[3 * (size_t)i];
    for (int k = 0; k < 3; k++) {
        assert_true(p[k] >= lo[k]);
        assert_true(p[k] <= hi[k]);
    }
    uint32_t axis = pm_kdnode_axis(t->node[i]), c = t->node[i].child;
    if (axis == PM_KD_LEAF) {
        assert_int_equal(c, PM_KD_NONE);
        assert_int_equal(e, i + 1);
        return 1;
    }
    assert_true(axis < 3);
    uint32_t sb, pb;
    memcpy(&sb, &t->node[i].split, 4);
    memcpy(&pb, &p[axis], 4);
    assert_int_equal(sb & ~3u, pb & ~3u); /* the axis decodes back and the rest is the photon */
    uint32_t le = c == PM_KD_NONE ? e : c;
    unsigned dl = 0, dr = 0;
    float l_hi[3] = {hi[0], hi[1], hi[2]}, r_lo[3] = {lo[0], lo[1], lo[2]};
    l_hi[axis] = p[axis];
    r_lo[axis] = p[axis];
    assert_true(le > i + 1 || c != PM_KD_NONE); /* an inner node has a child */
    if (le > i + 1)
        dl = check_subtree(t, i + 1, le, lo, l_hi);
    if (c != PM_KD_NONE)
        dr = check_subtree(t, c, e, r_lo, hi);
    return 1 + (dl > dr ? dl : dr);
}

static void check_tree(const tree_t *t)
{
    uint32_t n = t->n;
    unsigned char *seen = calloc(n ? n : 1, 1);
    for (uint32_t i = 0; i < n; i++) {
        assert_true(t->perm[i] < n);
        assert_int_equal(seen[t->perm[i]], 0); /* every photon exactly once */
        seen[t->perm[i]] = 1;
    }
    free(seen);
    if (n) {
        float lo[3] = {-INFINITY, -INFINITY, -INFINITY}, hi[3] = {INFINITY, INFINITY, INFINITY};
        check_subtree(t, 0, n, lo, hi);
    }
    /* The photon-map reader accepts it too. */
    pm_table_t map;
    assert_int_equal(pm_table_alloc(&map, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), n), PM_OK);
    memcpy(map.col[PM_MAP_NODE], t->node, (size_t)n * 8);
    memcpy(map.col[PM_MAP_POSITION], t->tree_pos, (size_t)n * 12);
    assert_int_equal(pm_photonmap_schema.validate_table(&map, "test"), PM_OK);
    pm_table_free(&map);
}

static float *random_points(uint32_t n, uint64_t seed, float lo, float hi)
{
    float *p = malloc((n ? n : 1) * 12);
    pm_rng_t r;
    pm_rng_init(&r, seed, 0);
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = lo + (hi - lo) * pm_rng_float(&r);
    return p;
}

static void build_and_check(const float *pos, uint32_t n)
{
    tree_t t;
    tree_build(&t, pos, n);
    check_tree(&t);
    tree_free(&t);
}

static void test_kd_node_is_8_bytes_and_axis_round_trips(void **state)
{
    assert_int_equal(sizeof(pm_kdnode_t), 8);
    const float v[] = {0.0f, -0.0f, 1.0f, -3.5f, 1e-30f, -1e30f, 3.3e38f, 1.4e-45f};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
        for (uint32_t a = 0; a < 4; a++) {
            pm_kdnode_t n = pm_kdnode_make(v[i], a, 1234u);
            assert_int_equal(pm_kdnode_axis(n), a);
            assert_int_equal(n.child, 1234u);
            if (v[i] != 0.0f && isnormal(v[i])) /* the plane moves by at most 3 ulp */
                assert_true(fabsf(n.split - v[i]) <= 3.0f * fabsf(nextafterf(v[i], copysignf(INFINITY, v[i])) - v[i]));
        }
}

static void test_kd_small_counts(void **state)
{
    for (uint32_t n = 0; n <= 70; n++) {
        float *p = random_points(n, n, -1.0f, 1.0f);
        build_and_check(p, n);
        free(p);
    }
}

static void test_kd_random_large(void **state)
{
    /* Above the sizes that switch to sampled partitions and to parallel tasks. */
    const uint32_t sizes[] = {255, 256, 257, 1000, 4097, 40000, 100000, 300000};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        float *p = random_points(sizes[s], 100 + s, -10.0f, 10.0f);
        build_and_check(p, sizes[s]);
        free(p);
    }
}

static void test_kd_degenerate_inputs(void **state)
{
    const uint32_t n = 5000;
    float *p = malloc(n * 12);
    pm_rng_t r;
    pm_rng_init(&r, 9, 0);
    /* all at one point */
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = 0.25f;
    build_and_check(p, n);
    /* all on one plane, z = 2 */
    for (uint32_t i = 0; i < n; i++)
        p[3 * i] = pm_rng_float(&r), p[3 * i + 1] = pm_rng_float(&r), p[3 * i + 2] = 2.0f;
    build_and_check(p, n);
    /* on a line */
    for (uint32_t i = 0; i < n; i++)
        p[3 * i] = 1.0f, p[3 * i + 1] = pm_rng_float(&r), p[3 * i + 2] = -1.0f;
    build_and_check(p, n);
    /* many duplicates on every split plane: three values per axis */
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = (float)(pm_rng_u32(&r) % 3);
    build_and_check(p, n);
    /* sorted and reverse-sorted along x (a pivot rule's classic worst cases) */
    for (uint32_t i = 0; i < n; i++)
        p[3 * i] = (float)i, p[3 * i + 1] = 0.0f, p[3 * i + 2] = 0.0f;
    build_and_check(p, n);
    for (uint32_t i = 0; i < n; i++)
        p[3 * i] = (float)(n - i);
    build_and_check(p, n);
    /* coordinates near +-1e30, near 1e-30, and both at once */
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = (pm_rng_float(&r) * 2.0f - 1.0f) * 1e30f;
    build_and_check(p, n);
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = pm_rng_float(&r) * 1e-30f;
    build_and_check(p, n);
    for (uint32_t i = 0; i < 3 * n; i++)
        p[i] = (i % 2 ? 1e-30f : -3e38f) * pm_rng_float(&r);
    build_and_check(p, n);
    free(p);
}

static void test_kd_same_tree_for_any_thread_count(void **state)
{
    const uint32_t n = 300000; /* large enough for parallel tasks and the parallel root level */
    float *p = random_points(n, 5, 0.0f, 1.0f);
    pm_kdnode_t *a = malloc(n * 8), *b = malloc(n * 8);
    uint32_t *pa = malloc(n * 4), *pb = malloc(n * 4);
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    assert_int_equal(pm_kd_build(p, n, a, pa, NULL), PM_OK);
    omp_set_num_threads(2);
    assert_int_equal(pm_kd_build(p, n, b, pb, NULL), PM_OK);
    omp_set_num_threads(saved);
    assert_memory_equal(a, b, (size_t)n * 8);
    assert_memory_equal(pa, pb, (size_t)n * 4);
    free(p), free(a), free(b), free(pa), free(pb);
}

typedef struct {
    uint32_t count;
    unsigned char *hit;
} range_ctx_t;

static void on_range(void *ctx, uint32_t i, float d2)
{
    range_ctx_t *c = ctx;
    c->count++;
    c->hit[i]++;
}

static void test_kd_searches_match_brute_force(void **state)
{
    const uint32_t n = 3000;
    float *p = random_points(n, 77, 0.0f, 1.0f);
    /* some duplicates, so that ties on planes are searched too */
    for (uint32_t i = 0; i < 300; i++)
        memcpy(&p[3 * (i + 300)], &p[3 * i], 12);
    tree_t t;
    tree_build(&t, p, n);
    pm_rng_t r;
    pm_rng_init(&r, 3, 0);
    float heap[64], *d2 = malloc(n * sizeof *d2);
    unsigned char *hit = malloc(n);
    for (int q = 0; q < 200; q++) {
        float x[3] = {pm_rng_float(&r), pm_rng_float(&r), pm_rng_float(&r)};
        if (q % 4 == 0) /* a query exactly on a photon */
            memcpy(x, &t.tree_pos[3 * (pm_rng_u32(&r) % n)], 12);
        for (uint32_t i = 0; i < n; i++) {
            float dx = t.tree_pos[3 * i] - x[0], dy = t.tree_pos[3 * i + 1] - x[1], dz = t.tree_pos[3 * i + 2] - x[2];
            d2[i] = dx * dx + dy * dy + dz * dz;
        }
        /* k-th nearest: sort the distances */
        float *s = malloc(n * sizeof *s);
        memcpy(s, d2, n * sizeof *s);
        for (uint32_t k = 1; k <= 64; k *= 4) {
            /* partial selection sort up to k */
            for (uint32_t a = 0; a < k; a++)
                for (uint32_t b = a + 1; b < n; b++)
                    if (s[b] < s[a]) {
                        float tmp = s[a];
                        s[a] = s[b];
                        s[b] = tmp;
                    }
            float got = pm_kd_knn_radius(t.node, t.tree_pos, n, x, k, heap);
            assert_float_equal(got, sqrtf(s[k - 1]), 0.0f);
        }
        free(s);
        float radius = 0.02f + 0.1f * pm_rng_float(&r);
        memset(hit, 0, n);
        range_ctx_t c = {0, hit};
        pm_kd_range(t.node, t.tree_pos, n, x, radius, on_range, &c);
        uint32_t want = 0;
        for (uint32_t i = 0; i < n; i++) {
            int inside = d2[i] <= radius * radius;
            want += inside;
            assert_int_equal(hit[i], inside); /* found once if inside, never if outside */
        }
        assert_int_equal(c.count, want);
    }
    free(d2);
    free(hit);
    free(p);
    tree_free(&t);
}

/* The voxel-volume heuristic: unbalanced but valid trees, within the depth limit, on
 * random, clustered and degenerate inputs. */
static void test_kd_vvh_trees_are_valid(void **state)
{
    const uint32_t n = 50000;
    float *p = random_points(n, 41, 0.0f, 1.0f);
    for (uint32_t i = 0; i < n / 2; i++) /* a dense cluster in one corner */
        for (int k = 0; k < 3; k++)
            p[3 * i + k] *= 0.01f;
    const float radii[] = {1e-4f, 0.01f, 0.3f, 100.0f};
    for (size_t r = 0; r < sizeof radii / sizeof radii[0]; r++)
        for (int shape = 0; shape < 2; shape++) {
            if (shape == 1) /* all on one plane, many duplicates */
                for (uint32_t i = 0; i < n; i++)
                    p[3 * i + 2] = 0.5f, p[3 * i] = (float)(i % 7);
            tree_t t;
            t.n = n;
            t.node = malloc(n * sizeof *t.node), t.perm = malloc(n * 4), t.pos = NULL, t.tree_pos = malloc(n * 12);
            pm_kd_build_stats_t st;
            assert_int_equal(pm_kd_build_vvh(p, n, radii[r], t.node, t.perm, &st), PM_OK);
            assert_true(st.depth <= PM_KD_MAX_DEPTH);
            for (uint32_t i = 0; i < n; i++)
                memcpy(&t.tree_pos[3 * i], &p[3 * (size_t)t.perm[i]], 12);
            check_tree(&t);
            free(t.node), free(t.perm), free(t.tree_pos);
        }
    free(p);
}

/* A valid but degenerate tree, a chain of right children, is refused past the depth that
 * searches' fixed stacks hold. */
static void test_kd_reader_refuses_too_deep_trees(void **state)
{
    for (uint32_t n = PM_KD_MAX_DEPTH; n <= PM_KD_MAX_DEPTH + 1; n++) {
        pm_table_t map;
        assert_int_equal(pm_table_alloc(&map, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), n),
                         PM_OK);
        pm_kdnode_t *node = map.col[PM_MAP_NODE];
        float *p = map.col[PM_MAP_POSITION];
        for (uint32_t i = 0; i < n; i++) {
            p[3 * i] = (float)i;
            node[i] = i + 1 < n ? pm_kdnode_make(p[3 * i], 0, i + 1) : pm_kdnode_make(0.0f, PM_KD_LEAF, PM_KD_NONE);
        }
        pm_result_t r = pm_photonmap_schema.validate_table(&map, "chain");
        assert_int_equal(r, n <= PM_KD_MAX_DEPTH ? PM_OK : PM_ERR_INPUT);
        if (r != PM_OK)
            assert_non_null(strstr(pm_error_message(), "deeper than 128 levels"));
        pm_table_free(&map);
    }
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_kd_vvh_trees_are_valid),
    cmocka_unit_test(test_kd_reader_refuses_too_deep_trees),
    cmocka_unit_test(test_kd_node_is_8_bytes_and_axis_round_trips),
    cmocka_unit_test(test_kd_small_counts),
    cmocka_unit_test(test_kd_random_large),
    cmocka_unit_test(test_kd_degenerate_inputs),
    cmocka_unit_test(test_kd_same_tree_for_any_thread_count),
    cmocka_unit_test(test_kd_searches_match_brute_force),
};
UNIT_GROUP(unit_kdtree, "kdtree", tests);
