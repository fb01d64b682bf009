/* knn_gather.c: the k-nearest-neighbour gather of traditional photon mapping, scalar, one
 * max-heap per query (Jensen, "Realistic Image Synthesis Using Photon Mapping", ch. 6); see
 * knn_gather.h. It walks the same hot records (position and link in 16 bytes) as the packet
 * gather, so the two differ in the estimator and in SIMD, not in the tree or its layout. */
#include "photonmap/knn_gather.h"

#include "base/timer.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Queries per unit of work handed to a thread: small enough that two threads stay
 * balanced, large enough that scheduling costs nothing. */
enum { BLOCK_QUERIES = 1024 };

typedef struct {
    float d2;   /* squared distance to the query, m^2 */
    uint32_t i; /* node index of the photon */
} cand_t;

/* Max-heap on d2 of at most k candidates: adds c when there is room, else replaces the
 * largest when c is nearer. */
static void heap_offer(cand_t *heap, uint32_t *cnt, uint32_t k, cand_t c)
{
    uint32_t at;
    if (*cnt < k) {
        at = (*cnt)++;
        while (at > 0) { /* sift up */
            uint32_t parent = (at - 1) / 2;
            if (heap[parent].d2 >= c.d2)
                break;
            heap[at] = heap[parent];
            at = parent;
        }
        heap[at] = c;
        return;
    }
    at = 0;
    for (;;) { /* sift the new root down */
        uint32_t l = 2 * at + 1, r = l + 1, big = at;
        float vb = c.d2;
        if (l < k && heap[l].d2 > vb)
            big = l, vb = heap[l].d2;
        if (r < k && heap[r].d2 > vb)
            big = r;
        if (big == at)
            break;
        heap[at] = heap[big];
        at = big;
    }
    heap[at] = c;
}

/* A pending subtree: its root node and a lower bound of its squared distance to the query. */
typedef struct {
    uint32_t i;
    float d2;
} pending_t;

/* The k nearest photons of query qi (normals agreeing, nearer than max_r2) into heap;
 * returns how many were found. */
static uint32_t knn_search(const pm_gather_map_t *m, const float y[3], const float n[3], uint32_t k, float max_r2,
                           float normal_cos, cand_t *heap, pm_knn_stats_t *st)
{
    pending_t stack[2 * PM_KD_MAX_DEPTH + 2];
    int top = 0;
    uint32_t cnt = 0;
    if (m->n)
        stack[top++] = (pending_t){0, 0.0f};
    while (top) {
        pending_t s = stack[--top];
        float bound2 = cnt < k ? max_r2 : heap[0].d2;
        if (s.d2 >= bound2) /* every photon of the subtree is at least this far */
            continue;
        const pm_gather_hot_t *h = &m->hot[s.i];
        st->nodes_visited++;
        float dx = y[0] - h->p[0], dy = y[1] - h->p[1], dz = y[2] - h->p[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < bound2) {
            const float *pn = &m->normal[3 * (size_t)s.i];
            if (n[0] * pn[0] + n[1] * pn[1] + n[2] * pn[2] >= normal_cos) {
                heap_offer(heap, &cnt, k, (cand_t){d2, s.i});
                st->heap_pushes++;
                bound2 = cnt < k ? max_r2 : heap[0].d2;
            }
        }
        uint32_t axis = h->link >> 30, c = h->link & PM_GATHER_NO_CHILD;
        if (axis == PM_KD_LEAF)
            continue;
        /* Left-subtree photons lie at or below the node's coordinate, right ones at or above
         * (kdtree.h), so the plane distance is a lower bound of theirs, exactly in float. */
        float diff = y[axis] - h->p[axis], pd2 = diff * diff;
        int has_left = c != s.i + 1, has_right = c != PM_GATHER_NO_CHILD;
        pending_t left = {s.i + 1, diff <= 0.0f ? s.d2 : pd2}, right = {c, diff <= 0.0f ? pd2 : s.d2};
        pending_t far = diff <= 0.0f ? right : left, near = diff <= 0.0f ? left : right;
        int far_ok = diff <= 0.0f ? has_right : has_left, near_ok = diff <= 0.0f ? has_left : has_right;
        if (far_ok && far.d2 < bound2)
            stack[top++] = far;
        if (near_ok) /* popped first */
            stack[top++] = near;
    }
    return cnt;
}

pm_result_t pm_knn_gather(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                          const pm_knn_params_t *p, double *out, pm_knn_stats_t *stats)
{
    memset(stats, 0, sizeof *stats);
    pm_result_t res = pm_gather_check_range(q, begin, end);
    if (res != PM_OK)
        return res;
    if (p->k == 0)
        return pm_error_set(PM_ERR_USAGE, "k = 0: an estimate needs at least one photon");
    float max_r2 = p->max_radius > 0.0 ? (float)(p->max_radius * p->max_radius) : INFINITY;
    if (p->max_radius < 0.0 || !(max_r2 > 0.0f) || (p->max_radius > 0.0 && !isfinite(max_r2)))
        return pm_error_set(PM_ERR_USAGE, "maximum radius %g m is not a positive radius whose square fits a float",
                            p->max_radius);
    unsigned char *mat_glossy = NULL;
    int glossy;
    res = pm_gather_glossy_table(m, q, &mat_glossy, &glossy);
    if (res != PM_OK)
        return res;
    uint64_t nblocks = (end - begin + BLOCK_QUERIES - 1) / BLOCK_QUERIES;
    /* A worker's failure (its heap, a query with r = 0) is recorded under its block's index
     * and raised after the region: the lowest block's, whatever thread met it. A thread's
     * blocks come in increasing order, so its first failure is the only one worth keeping. */
    pm_error_slot_t err;
    pm_error_slot_init(&err);
    pm_knn_stats_t total = {0};
#pragma omp parallel
    {
        pm_knn_stats_t st = {0};
        double cpu0 = pm_time_thread_cpu();
        cand_t *heap = malloc((size_t)p->k * sizeof *heap);
        int failed = 0;
#pragma omp for schedule(dynamic, 1) nowait
        for (uint64_t blk = 0; blk < nblocks; blk++) {
            if (!heap) {
                if (!failed)
                    pm_error_slot_record(
                        &err, blk, pm_error_set(PM_ERR_NOMEM, "out of memory for heaps of %" PRIu32 " photons", p->k));
                failed = 1;
                continue;
            }
            uint64_t b = begin + blk * BLOCK_QUERIES, e = b + BLOCK_QUERIES < end ? b + BLOCK_QUERIES : end;
            for (uint64_t qi = b; qi < e; qi++) {
                const float *y = &q->pos[3 * qi], *n = &q->normal[3 * qi];
                uint32_t cnt = knn_search(m, y, n, p->k, max_r2, p->normal_cos, heap, &st);
                double s[3] = {0.0, 0.0, 0.0};
                st.shader_ops += cnt;
                st.short_queries += cnt < p->k;
                /* r: the k-th distance; with fewer than k found, the search radius (Jensen)
                 * or, unlimited, the farthest found */
                double r2 = cnt < p->k && p->max_radius > 0.0 ? (double)max_r2 : (cnt ? (double)heap[0].d2 : 0.0);
                if (cnt && !(r2 > 0.0)) {
                    if (!failed)
                        pm_error_slot_record(&err, blk,
                                             pm_error_set(PM_ERR_INPUT,
                                                          "query %" PRIu64 ": its %" PRIu32
                                                          " nearest photons all lie at its position (r = 0 m "
                                                          "gives no finite estimate); raise --k",
                                                          qi, p->k));
                    failed = 1;
                    cnt = 0;
                }
                uint16_t mi = q->material ? q->material[qi] : 0;
                const pm_material_t *mt = &q->materials[mi];
                for (uint32_t j = 0; j < cnt; j++) {
                    uint32_t ni = heap[j].i;
                    double kv = pm_kernel_value(p->kernel, heap[j].d2, r2), f[3] = {1.0, 1.0, 1.0};
                    if (glossy && mat_glossy[mi])
                        pm_gather_brdf(mt, n, &m->dir[3 * (size_t)ni], &q->dir[3 * qi], f);
                    const float *pw = &m->power[3 * (size_t)ni];
                    for (int ch = 0; ch < 3; ch++)
                        s[ch] += kv * f[ch] * pw[ch];
                }
                for (int ch = 0; ch < 3; ch++)
                    out[3 * (qi - begin) + ch] = s[ch] * q->weight[3 * qi + ch];
            }
        }
        st.cpu_s = pm_time_thread_cpu() - cpu0;
#pragma omp critical
        {
            total.shader_ops += st.shader_ops;
            total.nodes_visited += st.nodes_visited;
            total.heap_pushes += st.heap_pushes;
            total.short_queries += st.short_queries;
            total.cpu_s += st.cpu_s;
        }
        free(heap);
    }
    free(mat_glossy);
    *stats = total;
    return pm_error_slot_raise(&err);
}
