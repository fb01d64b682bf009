/* reverse_gather.c: photons searching a KD-tree of the queries (reverse photon mapping);
 * see reverse_gather.h. The query tree is common/photonmap/kdtree.c's median-split tree built over
 * the query positions; the search is a scalar fixed-radius walk per photon. */
#include "photonmap/reverse_gather.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"
#include "base/timer.h"
#include "photonmap/kdtree.h"

/* About this many queries per subtree (a unit of work): enough subtrees for two threads to
 * balance, few enough that testing every photon against every subtree's box stays a small
 * part of the search. */
enum { SUBTREE_QUERIES = 8192, MAX_CUT_DEPTH = 10 };

typedef struct {
    uint32_t i, e;      /* subtree [i, e) in node order */
    unsigned max_depth; /* levels walked below i: the top task stops above the subtrees */
    float lo[3], hi[3]; /* bounding box of its queries, m */
} task_t;

typedef struct {
    const pm_gather_map_t *m;
    const pm_gather_queries_t *q;
    const pm_kdnode_t *node; /* the query tree */
    const uint32_t *perm;    /* node i holds query begin + perm[i] */
    const float *pos, *nor;  /* node order, n * 3 */
    double *sum;             /* node order, n * 3: the unweighted estimates */
    const unsigned char *mat_glossy;
    uint64_t begin;
    pm_kernel_t kernel;
    float r2, normal_cos;
    double h2; /* h^2 in double, as the kernel value takes it */
} ctx_t;

/* Collects the subtrees at depth `cut` below [i, e) (fewer where the tree is shallower). */
static void collect(const pm_kdnode_t *node, uint32_t i, uint32_t e, unsigned depth, unsigned cut, task_t *tasks,
                    uint32_t *nt)
{
    if (i >= e)
        return;
    if (depth == cut) {
        tasks[(*nt)++] = (task_t){.i = i, .e = e, .max_depth = UINT32_MAX};
        return;
    }
    if (pm_kdnode_axis(node[i]) == PM_KD_LEAF)
        return; /* a leaf above the cut: the top task has it */
    uint32_t c = node[i].child;
    collect(node, i + 1, c == PM_KD_NONE ? e : c, depth + 1, cut, tasks, nt);
    if (c != PM_KD_NONE)
        collect(node, c, e, depth + 1, cut, tasks, nt);
}

/* A pending subtree [i, e) of the query tree, depth levels below the task's root. */
typedef struct {
    uint32_t i, e, depth;
} frame_t;

/* One photon against the queries of subtree t: every query strictly within h whose normal
 * agrees receives the photon's contribution. */
static void search(const ctx_t *c, const task_t *t, uint32_t j, pm_reverse_stats_t *st)
{
    const pm_gather_map_t *m = c->m;
    const float *x = m->hot[j].p, *pn = &m->normal[3 * (size_t)j], *pw = &m->power[3 * (size_t)j];
    frame_t stack[2 * PM_KD_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = (frame_t){t->i, t->e, 0};
    while (top) {
        frame_t s = stack[--top];
        uint32_t i = s.i;
        const float *y = &c->pos[3 * (size_t)i], *n = &c->nor[3 * (size_t)i];
        st->nodes_visited++;
        /* the float arithmetic of pm_gather_brute and the packet kernels, so that pairs on
         * the sphere or at the normal threshold are decided alike */
        float dx = y[0] - x[0], dy = y[1] - x[1], dz = y[2] - x[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < c->r2 && n[0] * pn[0] + n[1] * pn[1] + n[2] * pn[2] >= c->normal_cos) {
            double kv = pm_kernel_value(c->kernel, d2, c->h2), f[3] = {1.0, 1.0, 1.0};
            uint64_t qi = c->begin + c->perm[i];
            if (c->mat_glossy) {
                uint16_t mi = c->q->material ? c->q->material[qi] : 0;
                if (c->mat_glossy[mi])
                    pm_gather_brdf(&c->q->materials[mi], n, &m->dir[3 * (size_t)j], &c->q->dir[3 * qi], f);
            }
            for (int ch = 0; ch < 3; ch++)
                c->sum[3 * (size_t)i + ch] += kv * f[ch] * pw[ch];
            st->shader_ops++;
        }
        uint32_t axis = pm_kdnode_axis(c->node[i]), ch = c->node[i].child;
        if (axis == PM_KD_LEAF || s.depth + 1 >= t->max_depth)
            continue;
        uint32_t lb = i + 1, le = ch == PM_KD_NONE ? s.e : ch, rb = ch == PM_KD_NONE ? s.e : ch;
        /* left-subtree queries lie at or below the node's coordinate, right ones at or above
         * (kdtree.h): the plane distance bounds theirs, exactly in float */
        float diff = x[axis] - y[axis];
        int left_near = diff <= 0.0f;
        int far_in = diff * diff < c->r2;
        if (left_near) {
            if (rb < s.e && far_in)
                stack[top++] = (frame_t){rb, s.e, s.depth + 1};
            if (lb < le)
                stack[top++] = (frame_t){lb, le, s.depth + 1};
        } else {
            if (lb < le && far_in)
                stack[top++] = (frame_t){lb, le, s.depth + 1};
            if (rb < s.e)
                stack[top++] = (frame_t){rb, s.e, s.depth + 1};
        }
    }
}

/* Squared distance from x to the box, m^2: never more than the float distance to any
 * point inside it (each clamped difference is at most the point's). */
static inline float box_d2(const task_t *t, const float x[3])
{
    float d2 = 0.0f;
    for (int a = 0; a < 3; a++) {
        float d = x[a] < t->lo[a] ? t->lo[a] - x[a] : (x[a] > t->hi[a] ? x[a] - t->hi[a] : 0.0f);
        d2 += d * d;
    }
    return d2;
}

pm_result_t pm_reverse_gather(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                              const pm_reverse_params_t *p, double *out, pm_reverse_stats_t *stats)
{
    memset(stats, 0, sizeof *stats);
    pm_result_t res = pm_gather_check_range(q, begin, end);
    if (res == PM_OK)
        res = pm_gather_check_radius(p->radius);
    if (res != PM_OK)
        return res;
    uint64_t n64 = end - begin;
    if (n64 > 0xfffffffeu)
        return pm_error_set(PM_ERR_INPUT, "%" PRIu64 " queries: the query tree takes at most %u", n64, 0xfffffffeu);
    uint32_t n = (uint32_t)n64;
    unsigned char *mat_glossy = NULL;
    int glossy;
    res = pm_gather_glossy_table(m, q, &mat_glossy, &glossy);
    if (res != PM_OK)
        return res;

    /* The tree of the queries and its node-order arrays. */
    double t0 = pm_time_wall();
    size_t nn = n ? n : 1;
    pm_kdnode_t *node = pm_alloc_aligned(nn * sizeof *node);
    uint32_t *perm = pm_alloc_aligned(nn * sizeof *perm);
    float *pos = pm_alloc_aligned(nn * 12), *nor = pm_alloc_aligned(nn * 12);
    double *sum = pm_alloc_aligned(nn * 3 * sizeof *sum);
    unsigned cut = 0;
    while (cut < MAX_CUT_DEPTH && ((uint64_t)SUBTREE_QUERIES << cut) < n)
        cut++;
    task_t *tasks = malloc((((size_t)1 << cut) + 1) * sizeof *tasks);
    pm_kd_build_stats_t bs = {0};
    if (!node || !perm || !pos || !nor || !sum || !tasks) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory for the tree of %" PRIu32 " queries", n);
        goto done;
    }
    if ((res = pm_kd_build(&q->pos[3 * begin], n, node, perm, &bs)) != PM_OK)
        goto done;
#pragma omp parallel for schedule(static)
    for (uint32_t i = 0; i < n; i++) {
        memcpy(&pos[3 * (size_t)i], &q->pos[3 * (begin + perm[i])], 12);
        memcpy(&nor[3 * (size_t)i], &q->normal[3 * (begin + perm[i])], 12);
        sum[3 * (size_t)i] = sum[3 * (size_t)i + 1] = sum[3 * (size_t)i + 2] = 0.0;
    }
    /* The units of work: the nodes above depth `cut` (walked with that depth limit from the
     * root), then each subtree at depth `cut` with its bounding box. */
    uint32_t nt = 0;
    if (n) {
        tasks[nt++] = (task_t){.i = 0, .e = n, .max_depth = cut};
        if (cut == 0)
            tasks[0].max_depth = UINT32_MAX;
        else
            collect(node, 0, n, 0, cut, tasks, &nt);
    }
    for (uint32_t t = 0; t < nt; t++) {
        task_t *tk = &tasks[t];
        for (int a = 0; a < 3; a++)
            tk->lo[a] = -INFINITY, tk->hi[a] = INFINITY;
        if (tk->max_depth != UINT32_MAX)
            continue; /* the top task: no box, every photon walks it */
        memcpy(tk->lo, &pos[3 * (size_t)tk->i], 12);
        memcpy(tk->hi, &pos[3 * (size_t)tk->i], 12);
        for (uint32_t i = tk->i + 1; i < tk->e; i++)
            for (int a = 0; a < 3; a++) {
                float v = pos[3 * (size_t)i + a];
                tk->lo[a] = v < tk->lo[a] ? v : tk->lo[a];
                tk->hi[a] = v > tk->hi[a] ? v : tk->hi[a];
            }
    }
    stats->build_s = pm_time_wall() - t0;
    stats->tree_depth = bs.depth;
    stats->subtrees = nt;

    float h = (float)p->radius;
    ctx_t c = {.m = m,
               .q = q,
               .node = node,
               .perm = perm,
               .pos = pos,
               .nor = nor,
               .sum = sum,
               .mat_glossy = glossy ? mat_glossy : NULL,
               .begin = begin,
               .kernel = p->kernel,
               .r2 = h * h,
               .normal_cos = p->normal_cos,
               .h2 = (double)h * h};
    t0 = pm_time_wall();
    pm_reverse_stats_t total = {0};
#pragma omp parallel
    {
        pm_reverse_stats_t st = {0};
        double cpu0 = pm_time_thread_cpu();
#pragma omp for schedule(dynamic, 1) nowait
        for (uint32_t t = 0; t < nt; t++)
            for (uint32_t j = 0; j < m->n; j++) { /* photon order: each query's sum in the same order */
                st.box_tests++;
                if (!(box_d2(&tasks[t], m->hot[j].p) < c.r2))
                    continue;
                st.searches++;
                search(&c, &tasks[t], j, &st);
            }
        st.cpu_s = pm_time_thread_cpu() - cpu0;
#pragma omp critical
        {
            total.shader_ops += st.shader_ops;
            total.nodes_visited += st.nodes_visited;
            total.searches += st.searches;
            total.box_tests += st.box_tests;
            total.cpu_s += st.cpu_s;
        }
    }
    stats->search_s = pm_time_wall() - t0;
    stats->shader_ops = total.shader_ops;
    stats->nodes_visited = total.nodes_visited;
    stats->searches = total.searches;
    stats->box_tests = total.box_tests;
    stats->cpu_s = total.cpu_s;
    /* Back to query order, times the weights. */
#pragma omp parallel for schedule(static)
    for (uint32_t i = 0; i < n; i++) {
        uint64_t qi = begin + perm[i];
        for (int ch = 0; ch < 3; ch++)
            out[3 * (qi - begin) + ch] = sum[3 * (size_t)i + ch] * q->weight[3 * qi + ch];
    }
done:
    free(tasks);
    pm_free_aligned(sum);
    pm_free_aligned(nor);
    pm_free_aligned(pos);
    pm_free_aligned(perm);
    pm_free_aligned(node);
    free(mat_glossy);
    return res;
}
