/* knn-gather: photon map + gather points -> indirect radiance buffer, by traditional photon
 * mapping (the paper's equation 1): the baseline simd-gather is measured against.
 *
 * Each query takes its k nearest photons (normals agreeing) from a scalar walk of the
 * photon KD-tree with a max-heap (Jensen), and the estimate sum f power K / r_k^2 with r_k
 * the distance of the k-th. Same inputs, refusals, weight contract and output as
 * simd-gather, so the two swap in a pipeline and their images compare directly. Queries
 * are independent and added to pixels in file order: the buffer is the same for any
 * thread count. common/photonmap/knn_gather.c does the work. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>

#include "base/stage.h"
#include "base/timer.h"
#include "photonmap/gather_stage.h"
#include "photonmap/knn_gather.h"

typedef struct {
    int64_t k;
    double max_radius;
    int kernel;
    double normal_cos;
    const char *range;
} knn_options_t;

static pm_result_t run(pm_stage_t *st, const knn_options_t *opt)
{
    knn_options_t oo = *opt, *o = &oo; /* k may come from the queries header */
    const char *k_from = NULL;
    pm_gather_inputs_t in;
    pm_table_t out = {0};
    double k = (double)o->k;
    pm_result_t r = pm_gather_inputs_read(&in, st->args.args[0], st->args.args[1], o->range, 0);
    if (r != PM_OK || (r = pm_gather_inputs_scene_kernel(&in, &st->args, NULL, &k, &k_from)) != PM_OK)
        goto done;
    if (k != floor(k) || k > 1e6) {
        r = pm_error_set(PM_ERR_INPUT, "queries '%s': render.k %g is not a whole number up to 1000000 (knn-gather)",
                         in.q_path, k);
        goto done;
    }
    o->k = (int64_t)k;
    uint64_t nq = in.q.n;
    pm_knn_params_t p = {.k = (uint32_t)o->k,
                         .max_radius = o->max_radius,
                         .kernel = (pm_kernel_t)o->kernel,
                         .normal_cos = (float)o->normal_cos};
    pm_knn_stats_t ks;
    double t0 = pm_time_wall();
    r = pm_knn_gather(&in.map, &in.q, 0, nq, &p, in.per_query, &ks);
    double t_gather = pm_time_wall() - t0;
    if (r != PM_OK || (r = pm_gather_check_finite(&in, "the k-NN estimate")) != PM_OK)
        goto done;

    pm_header_t *h = &out.hdr;
    if ((r = pm_gather_output_init(&out, &in, st->argc, st->argv, o->kernel, "knn")) != PM_OK ||
        (r = pm_header_set(h, "k", "%" PRId64, o->k)) != PM_OK)
        goto done;
    if (o->max_radius > 0.0 && (r = pm_header_set(h, "max_radius", "%.9g", o->max_radius)) != PM_OK)
        goto done;
    t0 = pm_time_wall();
    if ((r = pm_gather_output_write(&out, &in, st->output)) != PM_OK)
        goto done;
    double t_write = pm_time_wall() - t0;

    pm_gather_stage_stats(st, &in, o->kernel, ks.shader_ops, t_gather, ks.cpu_s, t_write);
    pm_stage_stat_int(st, "k", o->k);
    pm_stage_stat_string(st, "k_from", k_from);
    pm_stage_stat_double(st, "queries_per_s", t_gather > 0 ? (double)nq / t_gather : 0.0);
    pm_stage_stat_double(st, "queries_per_cpu_s", ks.cpu_s > 0 ? (double)nq / ks.cpu_s : 0.0);
    pm_stage_stat_int(st, "photons_visited", (int64_t)ks.nodes_visited);
    pm_stage_stat_double(st, "photons_visited_per_query", nq ? (double)ks.nodes_visited / nq : 0.0);
    pm_stage_stat_int(st, "heap_pushes", (int64_t)ks.heap_pushes);
    pm_stage_stat_int(st, "short_queries", (int64_t)ks.short_queries);
    pm_stage_stat_double(st, "gather_cpu_s", ks.cpu_s);
    pm_stage_note(
        st, "%" PRIu64 " queries, %" PRIu32 " photons, k %" PRId64 ", %.3g photons visited/query, %.2f M queries/s", nq,
        in.map.n, o->k, nq ? (double)ks.nodes_visited / nq : 0.0, t_gather > 0 ? nq / t_gather * 1e-6 : 0.0);
done:
    pm_gather_inputs_free(&in);
    pm_table_free(&out);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    knn_options_t o = {.k = 50, .max_radius = 0.0, .kernel = 0, .normal_cos = 0.5};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"k", 'k', PM_OPT_INT, &o.k, "K", "photons per estimate: the K nearest whose normal agrees", 1, 1e6, NULL},
        {"max-radius", 0, PM_OPT_DOUBLE, &o.max_radius, "R",
         "search no farther than R m; a query with fewer than K photons inside uses r = R (0: unlimited)", 0, 1e18,
         NULL},
        {"kernel", 0, PM_OPT_CHOICE, &o.kernel, "K",
         "kernel shape over the disc of radius r_k, normalized over the plane (uniform: Jensen's 1/(pi r^2))", 0, 0,
         pm_kernel_names},
        PM_GATHER_COMMON_OPTIONS(o.normal_cos, o.range),
        {0},
    };
    static const char about[] =
        "Gather the k nearest photons at every query (traditional photon mapping, a max-heap per "
        "query, scalar); write the indirect radiance per pixel. QUERIES may be - for stdin.";
    const pm_cli_t cli = {"knn-gather", "[options] MAP QUERIES -o RADIANCE", about, options, 2, 2, "radiance"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
