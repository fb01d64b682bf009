/* kdtree.c: median-split build of the paper's photon KD-tree, and the scalar searches.
 *
 * The build works on a copy of the photons as 16-byte {x, y, z, index} elements, so that a
 * bounding box is one SSE min/max per element and a swap moves one aligned 16-byte value;
 * each level partitions its subtree's elements in place around the median (Hoare's FIND,
 * Wirth's formulation), and the two halves become independent subarrays, built as OpenMP
 * tasks while they are large. Depth-first output order falls out of the recursion: node
 * `at` is the median, its left subtree [at + 1, at + 1 + m), its right after that. */
#include "photonmap/kdtree.h"

#include <immintrin.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"

typedef struct {
    float p[3];
    uint32_t id;
} elem_t;
_Static_assert(sizeof(elem_t) == 16, "one element is one SSE register");

typedef struct {
    pm_kdnode_t *node;
    uint32_t *perm;
    float vvh_r; /* m: the query radius of the voxel-volume heuristic; 0: median splits */
} build_t;

/* Subtrees of at least this many photons are handed to another thread: below it a task
 * costs more than it saves (measured: 16K to 64K photons are the flat part of the curve). */
enum { TASK_MIN = 32768 };

/* Longest axis of the bounding box of a[0, n). Ties go to the lowest axis, so all-equal
 * photons split on x, which is as good as any. */
static uint32_t longest_axis(const elem_t *a, uint32_t n)
{
    /* Two independent min/max chains: one chain waits on the previous min's latency. */
    __m128 lo = _mm_load_ps(a[0].p), hi = lo, lo2 = lo, hi2 = lo;
    uint32_t i = 1;
    for (; i + 1 < n; i += 2) {
        __m128 v = _mm_load_ps(a[i].p), w = _mm_load_ps(a[i + 1].p);
        lo = _mm_min_ps(lo, v);
        hi = _mm_max_ps(hi, v);
        lo2 = _mm_min_ps(lo2, w);
        hi2 = _mm_max_ps(hi2, w);
    }
    if (i < n) {
        __m128 v = _mm_load_ps(a[i].p);
        lo = _mm_min_ps(lo, v);
        hi = _mm_max_ps(hi, v);
    }
    lo = _mm_min_ps(lo, lo2);
    hi = _mm_max_ps(hi, hi2);
    float l[4], h[4];
    _mm_storeu_ps(l, lo);
    _mm_storeu_ps(h, hi);
    /* In double: the extent of coordinates near +-1e30 or 3e38 would overflow a float. */
    double e0 = (double)h[0] - l[0], e1 = (double)h[1] - l[1], e2 = (double)h[2] - l[2];
    return e0 >= e1 ? (e0 >= e2 ? 0u : 2u) : (e1 >= e2 ? 1u : 2u);
}

/* Branch-free Lomuto partition of a[0, n): moves the elements whose key satisfies
 * `key < p` (le = 0) or `key <= p` (le = 1) to the front, returns how many. Every element
 * is swapped unconditionally and the cursor advances by the comparison, so a random
 * order costs no mispredicted branches (the scanning loops of Hoare's partition miss
 * about once per element, which made them three quarters of the build). */
static uint32_t partition_front(elem_t *a, uint32_t n, uint32_t axis, float p, int le)
{
    uint32_t j = 0;
    if (le) {
        for (uint32_t i = 0; i < n; i++) {
            __m128 v = _mm_load_ps(a[i].p);
            float k = a[i].p[axis];
            _mm_store_ps(a[i].p, _mm_load_ps(a[j].p));
            _mm_store_ps(a[j].p, v);
            j += k <= p;
        }
    } else {
        for (uint32_t i = 0; i < n; i++) {
            __m128 v = _mm_load_ps(a[i].p);
            float k = a[i].p[axis];
            _mm_store_ps(a[i].p, _mm_load_ps(a[j].p));
            _mm_store_ps(a[j].p, v);
            j += k < p;
        }
    }
    return j;
}

static int cmp_x(const void *a, const void *b)
{
    float x = ((const elem_t *)a)->p[0], y = ((const elem_t *)b)->p[0];
    return (x > y) - (x < y);
}
static int cmp_y(const void *a, const void *b)
{
    float x = ((const elem_t *)a)->p[1], y = ((const elem_t *)b)->p[1];
    return (x > y) - (x < y);
}
static int cmp_z(const void *a, const void *b)
{
    float x = ((const elem_t *)a)->p[2], y = ((const elem_t *)b)->p[2];
    return (x > y) - (x < y);
}

/* Reorders a[0, n) so that a[m] holds the element of rank m on `axis`, those before it
 * are <= it and those after >= (quickselect). Each round splits into keys < pivot, == and
 * >, so runs of equal keys end the search at once instead of splitting forever. The pivot
 * is the median of three; should an input defeat it (more rounds than a good pivot
 * needs), the rest is sorted, which bounds the worst case by O(n log n). */
static void select_rank(elem_t *a, uint32_t n, uint32_t m, uint32_t axis)
{
    unsigned rounds = 0, limit = 16;
    for (uint32_t t = n; t; t >>= 1)
        limit += 2;
    while (n > 1) {
        if (++rounds > limit) {
            static int (*const cmp[3])(const void *, const void *) = {cmp_x, cmp_y, cmp_z};
            qsort(a, n, sizeof *a, cmp[axis]);
            return;
        }
        float x = a[0].p[axis], y = a[n / 2].p[axis], z = a[n - 1].p[axis];
        /* median of three, by comparisons (fminf and fmaxf are library calls here) */
        float lo = x < y ? x : y, hi = x < y ? y : x;
        float p = z < lo ? lo : (z > hi ? hi : z);
        uint32_t nlt = partition_front(a, n, axis, p, 0);
        if (m < nlt) {
            n = nlt;
            continue;
        }
        uint32_t neq = partition_front(a + nlt, n - nlt, axis, p, 1); /* >= 1: the pivot is there */
        if (m < nlt + neq)
            return;
        a += nlt + neq;
        m -= nlt + neq;
        n -= nlt + neq;
    }
}

/* Below this many photons a subtree's median is found in place by select_rank; above
 * it, by one sampled three-way partition into the other buffer (see split_sampled). */
enum { SAMPLED_MIN = 256, SAMPLE_MIN = 32 };

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Moves src[0, n) into dst[0, n) as three groups on `axis`: keys < p1 first, then keys in
 * [p1, p2], then keys > p2; returns the sizes of the first two. One branch-free pass: each
 * element is stored once, through a pointer picked by conditional moves, the first group
 * forward from the front of dst and the last backward from its end; the middle group
 * (small, by the choice of p1 and p2) goes to the front of src, whose elements are
 * already read, and is copied into the gap at the end. src is clobbered. */
static void partition3(elem_t *restrict src, elem_t *restrict dst, uint32_t n, uint32_t axis, float p1, float p2,
                       uint32_t *nlt_out, uint32_t *nmid_out)
{
    elem_t *lt = dst, *gt = dst + n - 1, *mid = src;
    for (uint32_t i = 0; i < n; i++) {
        __m128 v = _mm_load_ps(src[i].p);
        float k = src[i].p[axis];
        int is_lt = k<p1, is_gt = k> p2;
        elem_t *d = is_lt ? lt : mid;
        d = is_gt ? gt : d;
        _mm_store_ps(d->p, v);
        lt += is_lt;
        gt -= is_gt;
        mid += !is_lt & !is_gt;
    }
    uint32_t nlt = (uint32_t)(lt - dst), nmid = (uint32_t)(mid - src);
    memcpy(lt, src, (size_t)nmid * sizeof *src);
    *nlt_out = nlt;
    *nmid_out = nmid;
}

/* Sample size for a subtree of n photons: about sqrt(n), at most 1024, so that sorting it
 * stays far below a pass over n. The sample is the keys at (2 i + 1) n / (2 s). */
static uint32_t sample_size(uint32_t n)
{
    uint32_t s = SAMPLE_MIN;
    while (s < 1024 && (uint64_t)s * s < n)
        s *= 2;
    return s;
}

static inline uint64_t sample_index(uint32_t i, uint32_t s, uint32_t n) { return (uint64_t)(2 * i + 1) * n / (2 * s); }

/* Sorts the sample and picks two pivots around rank m's place in it, +- 3 standard
 * deviations of a sample rank (sqrt(s)/2), so that rank m falls between them almost always. */
static void pick_pivots(float *sample, uint32_t s, uint32_t n, uint32_t m, float *p1, float *p2)
{
    if (s <= 64) { /* insertion sort: small samples are most of the calls */
        for (uint32_t i = 1; i < s; i++) {
            float v = sample[i];
            uint32_t j = i;
            for (; j > 0 && sample[j - 1] > v; j--)
                sample[j] = sample[j - 1];
            sample[j] = v;
        }
    } else {
        qsort(sample, s, sizeof sample[0], cmp_float);
    }
    int64_t c = (int64_t)((uint64_t)m * s / n), g = 1;
    while (4 * g * g < 9 * (int64_t)s)
        g++;
    int64_t lo = c - g < 0 ? 0 : c - g, hi = c + g >= s ? s - 1 : c + g;
    *p1 = sample[lo];
    *p2 = sample[hi];
}

/* After a three-way partition of dst[0, n) into nlt, nmid and the rest: the exact
 * selection of rank m inside the group that holds it. */
static void finish_select(elem_t *dst, uint32_t n, uint32_t m, uint32_t axis, uint32_t nlt, uint32_t nmid, float p1,
                          float p2)
{
    if (m < nlt)
        select_rank(dst, nlt, m, axis); /* the pivots missed (rare): the group still holds rank m */
    else if (m >= nlt + nmid)
        select_rank(dst + nlt + nmid, n - nlt - nmid, m - nlt - nmid, axis);
    else if (p1 != p2) /* all keys of the middle group equal p1 when p1 == p2: any is rank m */
        select_rank(dst + nlt, nmid, m - nlt, axis);
}

/* Puts the element of rank m on `axis` of src[0, n) at dst[m], with smaller-or-equal keys
 * before it and greater-or-equal after (Floyd and Rivest's idea): two pivots from a
 * sorted sample bracket rank m with high probability, one three-way partition moves
 * everything into dst, and only the small middle group needs an exact selection. */
static void split_sampled(elem_t *src, elem_t *dst, uint32_t n, uint32_t m, uint32_t axis)
{
    float sample[1024], p1, p2;
    uint32_t s = sample_size(n), nlt, nmid;
    for (uint32_t i = 0; i < s; i++)
        sample[i] = src[sample_index(i, s, n)].p[axis];
    pick_pivots(sample, s, n, m, &p1, &p2);
    partition3(src, dst, n, axis, p1, p2, &nlt, &nmid);
    finish_select(dst, n, m, axis, nlt, nmid, p1, p2);
}

/* Builds the subtree of the photons in a[0, n) at node index `at`; `spare` is a scratch
 * buffer of the same n elements. Returns the subtree's depth. */
static inline void leaf(const build_t *b, const elem_t *e, uint32_t at)
{
    b->node[at] = pm_kdnode_make(e->p[0], PM_KD_LEAF, PM_KD_NONE);
    b->perm[at] = e->id;
}

/* Subtrees of 2 and 3 photons, half of all calls, without the general machinery: the
 * per-call work of bounds and selection cost 20 cycles per photon there. */
static unsigned build_tiny(const build_t *b, const elem_t *a, uint32_t n, uint32_t at)
{
    __m128 p0 = _mm_load_ps(a[0].p), p1 = _mm_load_ps(a[1].p);
    __m128 lo = _mm_min_ps(p0, p1), hi = _mm_max_ps(p0, p1);
    if (n == 3) {
        __m128 p2 = _mm_load_ps(a[2].p);
        lo = _mm_min_ps(lo, p2);
        hi = _mm_max_ps(hi, p2);
    }
    float l[4], h[4];
    _mm_storeu_ps(l, lo);
    _mm_storeu_ps(h, hi);
    double e0 = (double)h[0] - l[0], e1 = (double)h[1] - l[1], e2 = (double)h[2] - l[2];
    uint32_t axis = e0 >= e1 ? (e0 >= e2 ? 0u : 2u) : (e1 >= e2 ? 1u : 2u);
    /* Ranks on the axis by comparisons; ties keep input order (rank by (key, index)). */
    const elem_t *s0 = &a[0], *s1 = &a[1], *s2 = n == 3 ? &a[2] : NULL;
    if (s1->p[axis] < s0->p[axis]) {
        const elem_t *t = s0;
        s0 = s1;
        s1 = t;
    }
    if (n == 2) { /* median is the larger; the smaller is its left leaf */
        b->node[at] = pm_kdnode_make(s1->p[axis], axis, PM_KD_NONE);
        b->perm[at] = s1->id;
        leaf(b, s0, at + 1);
        return 2;
    }
    if (s2->p[axis] < s1->p[axis]) {
        const elem_t *t = s1;
        s1 = s2;
        s2 = t;
        if (s1->p[axis] < s0->p[axis]) {
            t = s0;
            s0 = s1;
            s1 = t;
        }
    }
    b->node[at] = pm_kdnode_make(s1->p[axis], axis, at + 2);
    b->perm[at] = s1->id;
    leaf(b, s0, at + 1);
    leaf(b, s2, at + 2);
    return 2;
}

/* The voxel-volume heuristic (Wald, Guenther and Slusallek 2004): a search of radius r
 * visits a subtree about as often as a query falls in its box grown by r, and then looks
 * at its photons, so a split should make N_L V_L + N_R V_R small, with V the grown
 * volumes. Candidates are the boundaries of 32 bins per axis; the split photon is the
 * one of rank N_L on the chosen axis, so it lies on the plane as the format wants. Below
 * VVH_MIN photons, and past VVH_MAX_DEPTH levels (to stay inside the format's 128), the
 * median is used. Returns the rank; sets *axis_out. */
enum { VVH_BINS = 32, VVH_MIN = 64, VVH_MAX_DEPTH = 90 };

static uint32_t vvh_split(const elem_t *a, uint32_t n, float r, uint32_t *axis_out)
{
    float lo[3] = {a[0].p[0], a[0].p[1], a[0].p[2]}, hi[3] = {lo[0], lo[1], lo[2]};
    for (uint32_t i = 1; i < n; i++)
        for (int k = 0; k < 3; k++) {
            float v = a[i].p[k];
            lo[k] = v < lo[k] ? v : lo[k];
            hi[k] = v > hi[k] ? v : hi[k];
        }
    double ext[3], scale[3];
    for (int k = 0; k < 3; k++) {
        ext[k] = (double)hi[k] - lo[k];
        scale[k] = ext[k] > 0 ? VVH_BINS / ext[k] : 0.0;
    }
    uint32_t hist[3][VVH_BINS] = {{0}};
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            int bin = (int)(((double)a[i].p[k] - lo[k]) * scale[k]);
            hist[k][bin < 0 ? 0 : (bin >= VVH_BINS ? VVH_BINS - 1 : bin)]++;
        }
    double g[3] = {ext[0] + 2.0 * r, ext[1] + 2.0 * r, ext[2] + 2.0 * r}, best = INFINITY;
    uint32_t best_axis = 0, best_m = n / 2;
    for (int k = 0; k < 3; k++) {
        if (!(ext[k] > 0))
            continue;
        double side = g[(k + 1) % 3] * g[(k + 2) % 3];
        uint32_t left = 0;
        for (int bnd = 1; bnd < VVH_BINS; bnd++) {
            left += hist[k][bnd - 1];
            if (left == 0 || left >= n)
                continue;
            double x = ext[k] * bnd / VVH_BINS; /* from lo */
            double cost = ((x + 2.0 * r) * left + (ext[k] - x + 2.0 * r) * (n - left)) * side;
            if (cost < best)
                best = cost, best_axis = (uint32_t)k, best_m = left;
        }
    }
    *axis_out = best_axis;
    return best_m;
}

static unsigned build(const build_t *b, elem_t *a, elem_t *spare, uint32_t n, uint32_t at, unsigned depth)
{
    if (n == 1) {
        leaf(b, a, at);
        return 1;
    }
    if (n <= 3)
        return build_tiny(b, a, n, at);
    uint32_t axis, m;
    if (b->vvh_r > 0.0f && n >= VVH_MIN && depth < VVH_MAX_DEPTH) {
        m = vvh_split(a, n, b->vvh_r, &axis);
    } else {
        axis = longest_axis(a, n);
        m = n / 2;
    }
    uint32_t nr = n - m - 1; /* m >= 1 photons go left, nr >= 0 right */
    if (n >= SAMPLED_MIN) {
        split_sampled(a, spare, n, m, axis);
        elem_t *t = a; /* the photons are now in spare: swap roles for the children */
        a = spare;
        spare = t;
    } else {
        select_rank(a, n, m, axis);
    }
    b->node[at] = pm_kdnode_make(a[m].p[axis], axis, nr ? at + 1 + m : PM_KD_NONE);
    b->perm[at] = a[m].id;
    unsigned dl = 0, dr = 0;
    if (n >= TASK_MIN) {
#pragma omp task default(none) shared(dl) firstprivate(b, a, spare, m, at, depth)
        dl = build(b, a, spare, m, at + 1, depth + 1);
        if (nr)
            dr = build(b, a + m + 1, spare + m + 1, nr, at + 1 + m, depth + 1);
#pragma omp taskwait
    } else {
        dl = build(b, a, spare, m, at + 1, depth + 1);
        if (nr)
            dr = build(b, a + m + 1, spare + m + 1, nr, at + 1 + m, depth + 1);
    }
    return 1 + (dl > dr ? dl : dr);
}

/* The root level of a large tree, on all threads and straight from the caller's
 * positions: the same split as build() would make after copying them into elements (the
 * same sample, the same groups in the same order), but the copy is fused into the
 * partition and the pass is shared by the threads instead of running on one while the
 * other waits. Blocks are fixed, not per thread, so the result is the same for any
 * thread count. */
enum { ROOT_PARALLEL_MIN = 1 << 18, ROOT_BLOCKS = 64 };

static unsigned build_root(const build_t *b, const float *pos, elem_t *a, elem_t *spare, uint32_t n)
{
    /* bounds, in blocks */
    float blo[ROOT_BLOCKS][3], bhi[ROOT_BLOCKS][3];
    uint32_t bs = (n + ROOT_BLOCKS - 1) / ROOT_BLOCKS;
#pragma omp parallel for schedule(static)
    for (int k = 0; k < ROOT_BLOCKS; k++) {
        uint64_t i0 = (uint64_t)k * bs, i1 = i0 + bs < n ? i0 + bs : n;
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint64_t i = i0; i < i1; i++)
            for (int c = 0; c < 3; c++) {
                float v = pos[3 * i + c];
                lo[c] = v < lo[c] ? v : lo[c];
                hi[c] = v > hi[c] ? v : hi[c];
            }
        for (int c = 0; c < 3; c++)
            blo[k][c] = lo[c], bhi[k][c] = hi[c];
    }
    double ext[3];
    for (int c = 0; c < 3; c++) {
        float lo = INFINITY, hi = -INFINITY;
        for (int k = 0; k < ROOT_BLOCKS; k++)
            lo = blo[k][c] < lo ? blo[k][c] : lo, hi = bhi[k][c] > hi ? bhi[k][c] : hi;
        ext[c] = (double)hi - lo;
    }
    uint32_t axis = ext[0] >= ext[1] ? (ext[0] >= ext[2] ? 0u : 2u) : (ext[1] >= ext[2] ? 1u : 2u);
    uint32_t m = n / 2, nr = n - m - 1;
    float sample[1024], p1, p2;
    uint32_t s = sample_size(n);
    for (uint32_t i = 0; i < s; i++)
        sample[i] = pos[3 * sample_index(i, s, n) + axis];
    pick_pivots(sample, s, n, m, &p1, &p2);
    /* count, then place: the groups in the order partition3 gives them */
    uint32_t cnt[ROOT_BLOCKS][2], off[ROOT_BLOCKS][3];
#pragma omp parallel for schedule(static)
    for (int k = 0; k < ROOT_BLOCKS; k++) {
        uint64_t i0 = (uint64_t)k * bs, i1 = i0 + bs < n ? i0 + bs : n;
        uint32_t lt = 0, gt = 0;
        for (uint64_t i = i0; i < i1; i++) {
            float key = pos[3 * i + axis];
            lt += key < p1;
            gt += key > p2;
        }
        cnt[k][0] = lt, cnt[k][1] = gt;
    }
    uint32_t nlt = 0, ngt = 0, nmid = 0;
    for (int k = 0; k < ROOT_BLOCKS; k++) {
        uint64_t i0 = (uint64_t)k * bs, i1 = i0 + bs < n ? i0 + bs : n, len = i1 > i0 ? i1 - i0 : 0;
        off[k][0] = nlt, off[k][1] = nmid, off[k][2] = ngt;
        nlt += cnt[k][0], ngt += cnt[k][1], nmid += (uint32_t)len - cnt[k][0] - cnt[k][1];
    }
#pragma omp parallel for schedule(static)
    for (int k = 0; k < ROOT_BLOCKS; k++) {
        uint64_t i0 = (uint64_t)k * bs, i1 = i0 + bs < n ? i0 + bs : n;
        elem_t *lt = spare + off[k][0], *gt = spare + n - 1 - off[k][2], *mid = a + off[k][1];
        for (uint64_t i = i0; i < i1; i++) {
            elem_t e = {{pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]}, (uint32_t)i};
            float key = e.p[axis];
            int is_lt = key<p1, is_gt = key> p2;
            elem_t *d = is_lt ? lt : mid;
            d = is_gt ? gt : d;
            *d = e;
            lt += is_lt;
            gt -= is_gt;
            mid += !is_lt & !is_gt;
        }
    }
    memcpy(spare + nlt, a, (size_t)nmid * sizeof *a);
    finish_select(spare, n, m, axis, nlt, nmid, p1, p2);
    b->node[0] = pm_kdnode_make(spare[m].p[axis], axis, nr ? 1 + m : PM_KD_NONE);
    b->perm[0] = spare[m].id;
    unsigned dl = 0, dr = 0;
#pragma omp parallel default(none) shared(b, a, spare, m, nr, dl, dr)
#pragma omp single
    {
#pragma omp task default(none) shared(b, a, spare, m, dl)
        dl = build(b, spare, a, m, 1, 1);
        if (nr)
            dr = build(b, spare + m + 1, a + m + 1, nr, 1 + m, 1);
#pragma omp taskwait
    }
    return 1 + (dl > dr ? dl : dr);
}

pm_result_t pm_kd_build(const float *pos, uint64_t n, pm_kdnode_t *node_out, uint32_t *perm_out,
                        pm_kd_build_stats_t *stats_out)
{
    return pm_kd_build_vvh(pos, n, 0.0f, node_out, perm_out, stats_out);
}

pm_result_t pm_kd_build_vvh(const float *pos, uint64_t n, float vvh_radius, pm_kdnode_t *node_out, uint32_t *perm_out,
                            pm_kd_build_stats_t *stats_out)
{
    pm_kd_build_stats_t st = {0};
    if (n > (uint64_t)UINT32_MAX - 1)
        return pm_error_set(PM_ERR_INPUT, "%llu photons are more than a photon map holds (4294967294)",
                            (unsigned long long)n);
    if (n == 0) {
        if (stats_out)
            *stats_out = st;
        return PM_OK;
    }
    elem_t *a = pm_alloc_aligned(n * sizeof *a), *spare = pm_alloc_aligned(n * sizeof *spare);
    if (!a || !spare) {
        pm_free_aligned(a);
        pm_free_aligned(spare);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the KD-tree build of %llu photons (%.1f MB)",
                            (unsigned long long)n, 2.0 * (double)n * sizeof *a / 1e6);
    }
    build_t b = {node_out, perm_out, vvh_radius > 0.0f ? vvh_radius : 0.0f};
    unsigned depth = 0;
    if (n < ROOT_PARALLEL_MIN || b.vvh_r > 0.0f) {
        for (uint64_t i = 0; i < n; i++) {
            a[i].p[0] = pos[3 * i], a[i].p[1] = pos[3 * i + 1], a[i].p[2] = pos[3 * i + 2];
            a[i].id = (uint32_t)i;
        }
#pragma omp parallel default(none) shared(b, a, spare, n, depth)
#pragma omp single
        depth = build(&b, a, spare, (uint32_t)n, 0, 0);
    } else {
        depth = build_root(&b, pos, a, spare, (uint32_t)n);
    }
    pm_free_aligned(a);
    pm_free_aligned(spare);
    st.depth = depth;
    for (uint64_t i = 0; i < n; i++)
        st.leaves += pm_kdnode_axis(node_out[i]) == PM_KD_LEAF;
    if (stats_out)
        *stats_out = st;
    return PM_OK;
}

/* ---- searches ---- */

/* A pending subtree [i, e) and a lower bound of its squared distance to the query. */
typedef struct {
    uint32_t i, e;
    float d2;
} pending_t;

/* Pushes the children of inner node i (subtree [i, e)) in the order near side last, so
 * that it is popped first. `far_d2` is the squared distance from the query to the plane. */
static inline int push_children(pending_t *stack, int top, const pm_kdnode_t *node, const float *pos, uint32_t i,
                                uint32_t e, const float q[3], float bound2)
{
    uint32_t axis = pm_kdnode_axis(node[i]), c = node[i].child;
    uint32_t lb = i + 1, le = c == PM_KD_NONE ? e : c; /* left [lb, le), maybe empty */
    uint32_t rb = c == PM_KD_NONE ? e : c;             /* right [rb, e), maybe empty */
    float diff = q[axis] - pos[3 * (size_t)i + axis], d2 = diff * diff;
    int left_near = diff <= 0.0f;
    pending_t l = {lb, le, left_near ? 0.0f : d2}, r = {rb, e, left_near ? d2 : 0.0f};
    pending_t first = left_near ? r : l, second = left_near ? l : r; /* far, then near */
    if (first.i < first.e && first.d2 <= bound2)
        stack[top++] = first;
    if (second.i < second.e)
        stack[top++] = second;
    return top;
}

/* Max-heap of squared distances, heap[0] the largest. */
static void heap_push(float *heap, uint32_t *cnt, uint32_t k, float d2)
{
    if (*cnt < k) {
        uint32_t c = (*cnt)++;
        while (c > 0) {
            uint32_t p = (c - 1) / 2;
            if (heap[p] >= d2)
                break;
            heap[c] = heap[p];
            c = p;
        }
        heap[c] = d2;
        return;
    }
    if (d2 >= heap[0])
        return;
    uint32_t c = 0;
    for (;;) {
        uint32_t l = 2 * c + 1, r = l + 1, big = c;
        float vb = d2;
        if (l < k && heap[l] > vb)
            big = l, vb = heap[l];
        if (r < k && heap[r] > vb)
            big = r;
        if (big == c)
            break;
        heap[c] = heap[big];
        c = big;
    }
    heap[c] = d2;
}

float pm_kd_knn_radius(const pm_kdnode_t *node, const float *pos, uint32_t n, const float q[3], uint32_t k, float *heap)
{
    if (n == 0 || k == 0)
        return 0.0f;
    pending_t stack[2 * PM_KD_MAX_DEPTH + 2];
    int top = 0;
    uint32_t cnt = 0;
    stack[top++] = (pending_t){0, n, 0.0f};
    while (top) {
        pending_t s = stack[--top];
        float bound2 = cnt < k ? INFINITY : heap[0];
        if (s.d2 > bound2)
            continue;
        uint32_t i = s.i;
        const float *p = &pos[3 * (size_t)i];
        float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
        heap_push(heap, &cnt, k, dx * dx + dy * dy + dz * dz);
        if (pm_kdnode_axis(node[i]) != PM_KD_LEAF)
            top = push_children(stack, top, node, pos, i, s.e, q, cnt < k ? INFINITY : heap[0]);
    }
    return sqrtf(heap[0]);
}

void pm_kd_range(const pm_kdnode_t *node, const float *pos, uint32_t n, const float q[3], float r,
                 void (*fn)(void *ctx, uint32_t i, float d2), void *ctx)
{
    if (n == 0)
        return;
    pending_t stack[2 * PM_KD_MAX_DEPTH + 2];
    int top = 0;
    float r2 = r * r;
    stack[top++] = (pending_t){0, n, 0.0f};
    while (top) {
        pending_t s = stack[--top];
        uint32_t i = s.i;
        const float *p = &pos[3 * (size_t)i];
        float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2], d2 = dx * dx + dy * dy + dz * dz;
        if (d2 <= r2)
            fn(ctx, i, d2);
        if (pm_kdnode_axis(node[i]) != PM_KD_LEAF)
            top = push_children(stack, top, node, pos, i, s.e, q, r2);
    }
}
