/* reverse-gather: photon map + gather points -> indirect radiance buffer, by reverse photon
 * mapping (Havran et al. 2005; the paper's section 4): the baseline of simd-gather's
 * forward gather.
 *
 * A KD-tree is built over the queries, and every photon searches it with the fixed kernel
 * width and adds its contribution to each query it reaches: the sample-point estimator of
 * simd-gather, so the two give the same buffer within float rounding. Same inputs,
 * refusals, weight contract, kernel width from --k and output as simd-gather. The tree is
 * cut into subtrees by depth, never by thread count, and each query sums its photons in
 * photon order, so the buffer is bit-identical for any --threads. common/photonmap/reverse_gather.c
 * does the work. */
#include <inttypes.h>
#include <stdlib.h>

#include "base/stage.h"
#include "base/timer.h"
#include "photonmap/gather_stage.h"
#include "photonmap/reverse_gather.h"

typedef struct {
    double radius;
    double k;
    int kernel;
    double normal_cos;
    const char *range;
    int64_t pass;                       /* progressive pass, 1-based; 0: none */
    double alpha;                       /* the schedule's alpha with pass */
    int64_t pass_photons, unit_photons; /* photons before the pass (-1: not given) and pass 1's (0: not given) */
} reverse_options_t;

static pm_result_t run(pm_stage_t *st, const reverse_options_t *opt)
{
    reverse_options_t oo = *opt, *o = &oo; /* the kernel width may come from the queries header */
    const char *width_from = NULL;
    pm_gather_inputs_t in;
    pm_table_t out = {0};
    if (o->radius == 0.0 && o->k <= 0.0)
        return pm_error_set(PM_ERR_USAGE, "give --radius R or --k K (photons per query) for the kernel width");
    pm_result_t r = pm_gather_pass_check(o->pass, o->pass_photons, o->unit_photons);
    if (r != PM_OK)
        return r;
    r = pm_gather_inputs_read(&in, st->args.args[0], st->args.args[1], o->range, 0);
    if (r != PM_OK || (r = pm_gather_inputs_scene_kernel(&in, &st->args, &o->radius, &o->k, &width_from)) != PM_OK)
        goto done;
    double radius = o->radius, t_radius = 0.0, t0;
    if (radius == 0.0) {
        t0 = pm_time_wall();
        if ((r = pm_gather_inputs_radius_for_k(&in, o->k, (float)o->normal_cos, &radius)) != PM_OK)
            goto done;
        t_radius = pm_time_wall() - t0;
    }
    double radius1 = radius;
    uint64_t before = o->pass_photons > 0 ? (uint64_t)o->pass_photons : 0, unit = (uint64_t)o->unit_photons;
    if (o->pass)
        radius = pm_gather_schedule_radius(radius1, pm_gather_pass_index((uint64_t)o->pass, before, unit), o->alpha);
    uint64_t nq = in.q.n;
    pm_reverse_params_t p = {.radius = radius, .kernel = (pm_kernel_t)o->kernel, .normal_cos = (float)o->normal_cos};
    pm_reverse_stats_t rs;
    t0 = pm_time_wall();
    r = pm_reverse_gather(&in.map, &in.q, 0, nq, &p, in.per_query, &rs);
    double t_gather = pm_time_wall() - t0;
    if (r != PM_OK || (r = pm_gather_check_finite(&in, "the reverse gather")) != PM_OK)
        goto done;

    pm_header_t *h = &out.hdr;
    if ((r = pm_gather_output_init(&out, &in, st->argc, st->argv, o->kernel, "fixed")) != PM_OK ||
        (r = pm_header_set(h, "radius", "%.9g", radius)) != PM_OK ||
        (r = pm_gather_pass_header(h, (uint64_t)o->pass, o->alpha, radius1, before, unit)) != PM_OK)
        goto done;
    t0 = pm_time_wall();
    if ((r = pm_gather_output_write(&out, &in, st->output)) != PM_OK)
        goto done;
    double t_write = pm_time_wall() - t0;

    pm_gather_stage_stats(st, &in, o->kernel, rs.shader_ops, t_gather, rs.cpu_s, t_write);
    pm_stage_stat_double(st, "radius_m", radius);
    pm_stage_stat_string(st, "radius_from", width_from);
    if (o->radius == 0.0)
        pm_stage_stat_double(st, "k", o->k);
    pm_stage_stat_double(st, "shader_ops_per_s_search", rs.search_s > 0 ? (double)rs.shader_ops / rs.search_s : 0.0);
    pm_stage_stat_int(st, "queries_visited", (int64_t)rs.nodes_visited);
    pm_stage_stat_int(st, "subtree_searches", (int64_t)rs.searches);
    pm_stage_stat_int(st, "box_tests", (int64_t)rs.box_tests);
    pm_stage_stat_int(st, "subtrees", rs.subtrees);
    pm_stage_stat_int(st, "query_tree_depth", rs.tree_depth);
    pm_stage_stat_double(st, "radius_s", t_radius);
    if (o->pass) {
        pm_stage_stat_int(st, "pass", o->pass);
        pm_stage_stat_double(st, "radius1_m", radius1);
        pm_stage_stat_double(st, "pass_index", pm_gather_pass_index((uint64_t)o->pass, before, unit));
    }
    pm_stage_stat_double(st, "build_s", rs.build_s);
    pm_stage_stat_double(st, "search_s", rs.search_s);
    pm_stage_stat_double(st, "search_cpu_s", rs.cpu_s);
    pm_stage_note(st, "%" PRIu64 " queries, %" PRIu32 " photons, query tree %.3f s, search %.3f s, %.1f M shader ops/s",
                  nq, in.map.n, rs.build_s, rs.search_s, t_gather > 0 ? rs.shader_ops / t_gather * 1e-6 : 0.0);
done:
    pm_gather_inputs_free(&in);
    pm_table_free(&out);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    reverse_options_t o = {
        .radius = 0.0, .k = 50.0, .kernel = 1, .normal_cos = 0.5, .alpha = PM_PASS_ALPHA_DEFAULT, .pass_photons = -1};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"radius", 'r', PM_OPT_DOUBLE, &o.radius, "R", "kernel width h, m (0: from --k)", 0, 1e18, NULL},
        {"k", 'k', PM_OPT_DOUBLE, &o.k, "K",
         "choose h so that about K photons fall in a query's kernel on average (as simd-gather does)", 0, 1e7, NULL},
        {"kernel", 0, PM_OPT_CHOICE, &o.kernel, "K", "kernel shape, normalized over the plane", 0, 0, pm_kernel_names},
        PM_GATHER_COMMON_OPTIONS(o.normal_cos, o.range),
        PM_GATHER_PASS_OPTIONS(o.pass, o.alpha, o.pass_photons, o.unit_photons),
        {0},
    };
    static const char about[] =
        "Reverse photon mapping: build a KD-tree over the queries and let every photon search it "
        "with the fixed kernel width (simd-gather's estimator); write the indirect radiance per "
        "pixel. QUERIES may be - for stdin.";
    const pm_cli_t cli = {"reverse-gather", "[options] MAP QUERIES -o RADIANCE", about, options, 2, 2, "radiance"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
