/* build-photonmap: photons file -> photon map (the paper, section 5.2).
 *
 * Builds the KD-tree with one photon per node on the node's split plane (common/photonmap/kdtree.c)
 * and writes it in depth-first node order: the 8-byte nodes and positions are the hot
 * channels a gather reads on every visit, power and normal the cold ones read only when a
 * photon is shaded, and direction only when the photons file has it (scenes with glossy
 * materials). `--map indirect` leaves out first-hit photons, for renders whose direct
 * light comes from shadow rays. `--width-k K` adds each photon's kernel width for the
 * variable-width estimator: the radius of the disc around it that holds K photons. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/gather.h"
#include "photonmap/kdtree.h"
#include "base/memory.h"
#include "base/stage.h"
#include "formats/formats.h"

static const char *const map_kinds[] = {"global", "indirect", NULL};
static const char *const split_kinds[] = {"median", "vvh", NULL};

typedef struct {
    int map;         /* index into map_kinds */
    int split;       /* index into split_kinds */
    int64_t width_k; /* 0: no width channel */
    double vvh_radius; /* m; 0: from vvh_k */
    int64_t vvh_k;
    double width_max;
} build_options_t;

/* Kernel width of every photon: the radius of the disc around it that holds K photons
 * (itself included, normals agreeing), the k-nearest-neighbour pilot estimate of the
 * local photon density (Silverman's adaptive kernel; h ~ density^-1/2 on a surface,
 * Terrell and Scott's rule in two dimensions). Found in rounds on the same SIMD packets
 * as simd-gather, with the photons as their own queries and unit powers so that a gather
 * counts: every photon still short of K photons is counted at radius r, those with
 * c >= K take h = r sqrt(K / c) (the radius that holds K at the density c / (pi r^2)),
 * the others go on at r sqrt(2). Starting at half the radius that holds K on average, a
 * photon is counted about twice, at a cost near K per round; a k-nearest-neighbour heap
 * search per photon took 2 us each. Clamped to [a millionth of the scene, width_max]. */
enum { WIDTH_STRIDE = 8 };
enum { PILOT_K = 1 << 20 }; /* no cap: counting K itself measured best in dark regions */

static pm_result_t compute_widths(pm_table_t *map, uint32_t k_final, double width_max, double *mean_out,
                                  double *r0_out)
{
    /* A pilot could count fewer photons than K and scale the radius by the square root;
     * on the Cornell box a 16-photon pilot gave 12% more error in dark regions for little
     * time saved, so the pilot counts K. */
    const uint32_t k = k_final < PILOT_K ? k_final : PILOT_K;
    const double scale = sqrt((double)k_final / k);
    uint32_t n = (uint32_t)map->count;
    float *width = map->col[PM_MAP_WIDTH];
    float *bounds = map->hdr.bounds;
    double ext = fmax(fmax(bounds[3] - bounds[0], bounds[4] - bounds[1]), bounds[5] - bounds[2]);
    float floor_w = (float)fmax(ext * 1e-6, 1e-30);
    float cap = width_max > 0 ? (float)width_max : INFINITY;
    *mean_out = *r0_out = 0.0;
    if (n == 0)
        return PM_OK;
    float *ones = pm_alloc_aligned((size_t)n * 3 * sizeof *ones);
    float *qpos = pm_alloc_aligned((size_t)n * 3 * sizeof *qpos), *qnor = pm_alloc_aligned((size_t)n * 3 * sizeof *qnor);
    double *dens = pm_alloc_aligned((size_t)n * 3 * sizeof *dens);
    uint32_t *pending = malloc((size_t)n * sizeof *pending);
    if (!ones || !qpos || !qnor || !dens || !pending) {
        pm_free_aligned(ones), pm_free_aligned(qpos), pm_free_aligned(qnor), pm_free_aligned(dens), free(pending);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the kernel widths of %" PRIu32 " photons", n);
    }
    for (size_t i = 0; i < (size_t)n * 3; i++)
        ones[i] = 1.0f;
    pm_gather_map_t gm;
    pm_result_t r = pm_gather_map_init(&gm, map, 0);
    static const pm_material_t folded = {.name = "folded", .kd = {1, 1, 1}};
    const float normal_cos = 0.5f;
    if (r == PM_OK) {
        gm.power = ones;
        pm_gather_queries_t all = {.n = n, .pos = gm.pos, .normal = gm.normal, .weight = ones, .materials = &folded,
                                   .nmaterials = 1};
        double r0 = pm_gather_radius_for_k(&gm, &all, (double)k, normal_cos, 1000);
        *r0_out = r0;
        double rad = fmax(0.5 * r0, floor_w);
        /* Widths are counted for every STRIDE-th photon in node order and shared with the
         * photons after it: depth-first order keeps them in one small subtree, a few photon
         * spacings apart, where the density K photons measure barely changes. */
        uint32_t np = 0;
        for (uint32_t i = 0; i < n; i += WIDTH_STRIDE)
            pending[np++] = i;
        for (int round = 0; np && r == PM_OK; round++) {
            /* the pending photons as queries, in tree order (coherent packets) */
            for (uint32_t j = 0; j < np; j++) {
                memcpy(&qpos[3 * (size_t)j], &gm.pos[3 * (size_t)pending[j]], 12);
                memcpy(&qnor[3 * (size_t)j], &gm.normal[3 * (size_t)pending[j]], 12);
            }
            pm_gather_queries_t q = {.n = np, .pos = qpos, .normal = qnor, .weight = ones, .materials = &folded,
                                     .nmaterials = 1};
            pm_gather_params_t p = {.radius = rad, .kernel = PM_KERNEL_UNIFORM, .normal_cos = normal_cos,
                                    .isa = pm_cpu_best_isa()};
            pm_gather_stats_t st;
            if ((r = pm_gather_run(&gm, &q, 0, np, &p, dens, &st)) != PM_OK)
                break;
            double area = M_PI * rad * rad;
            int last = round == 40 || rad * M_SQRT2 > cap || rad > 4.0 * ext;
            uint32_t keep = 0;
            for (uint32_t j = 0; j < np; j++) {
                double c = fmax(dens[3 * (size_t)j] * area, 1.0); /* the photon itself is always in */
                if (c >= k || last) {
                    float h = (float)(scale * rad * sqrt((double)k / c));
                    width[pending[j]] = h < floor_w ? floor_w : (h > cap ? cap : h);
                } else {
                    pending[keep++] = pending[j];
                }
            }
            np = keep;
            rad *= M_SQRT2;
        }
        pm_gather_map_free(&gm);
        for (uint32_t i = 0; i < n; i++)
            width[i] = width[i - i % WIDTH_STRIDE];
        double sum = 0.0;
        for (uint32_t i = 0; i < n; i++)
            sum += width[i];
        *mean_out = sum / n;
    }
    pm_free_aligned(ones), pm_free_aligned(qpos), pm_free_aligned(qnor), pm_free_aligned(dens), free(pending);
    return r;
}

/* The photons' channels in node order (node i holds input photon keep[perm[i]]). */
static void layout(pm_table_t *map, const uint32_t *perm, const uint32_t *keep, uint64_t n, const float *ppos,
                   const float *ppow, const float *pnor, const float *pdir)
{
    float *mpos = map->col[PM_MAP_POSITION], *mpow = map->col[PM_MAP_POWER], *mnor = map->col[PM_MAP_NORMAL];
    float *mdir = pdir ? map->col[PM_MAP_DIRECTION] : NULL;
#pragma omp parallel for schedule(static)
    for (uint64_t i = 0; i < n; i++) {
        uint64_t s = keep[perm[i]];
        memcpy(&mpos[3 * i], &ppos[3 * s], 12);
        memcpy(&mpow[3 * i], &ppow[3 * s], 12);
        memcpy(&mnor[3 * i], &pnor[3 * s], 12);
        if (mdir)
            memcpy(&mdir[3 * i], &pdir[3 * s], 12);
    }
}

static pm_result_t run(pm_stage_t *st, const build_options_t *o)
{
    const char *in = st->args.args[0];
    pm_table_t ph = {0}, map = {0};
    uint32_t *keep = NULL, *perm = NULL;
    float *pos = NULL;
    double t0 = pm_time_wall();
    pm_result_t r = pm_table_read(in, &pm_photons_schema, pm_schema_required(&pm_photons_schema), &ph);
    if (r != PM_OK)
        return r;
    double t_read = pm_time_wall() - t0;
    uint64_t n_in = ph.count;

    /* The photons this map holds: all, or those that bounced at least once. */
    const uint32_t *depth = ph.col[PM_PHOTON_DEPTH];
    const float *ppos = ph.col[PM_PHOTON_POSITION];
    uint64_t n = 0;
    int indirect = o->map == 1;
    keep = malloc((n_in ? n_in : 1) * sizeof *keep);
    pos = pm_alloc_aligned((n_in ? n_in : 1) * 3 * sizeof *pos);
    perm = malloc((n_in ? n_in : 1) * sizeof *perm);
    if (!keep || !pos || !perm) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " photons of '%s'", n_in, in);
        goto done;
    }
    for (uint64_t i = 0; i < n_in; i++)
        if (!indirect || depth[i] > 0) {
            keep[n] = (uint32_t)i;
            memcpy(&pos[3 * n], &ppos[3 * i], 3 * sizeof *pos);
            n++;
        }

    int glossy = (ph.hdr.channels >> PM_PHOTON_DIRECTION) & 1u;
    uint32_t channels = pm_schema_required(&pm_photonmap_schema) | (glossy ? 1u << PM_MAP_DIRECTION : 0u) |
                        (o->width_k > 0 ? 1u << PM_MAP_WIDTH : 0u);
    r = pm_table_alloc(&map, &pm_photonmap_schema, channels, n);
    if (r != PM_OK)
        goto done;

    t0 = pm_time_wall();
    pm_kd_build_stats_t bs;
    r = pm_kd_build(pos, n, map.col[PM_MAP_NODE], perm, &bs);
    double t_build = pm_time_wall() - t0;
    if (r != PM_OK)
        goto done;

    /* Photon data in node order: hot positions, then the cold channels. */
    t0 = pm_time_wall();
    const float *ppow = ph.col[PM_PHOTON_POWER], *pnor = ph.col[PM_PHOTON_NORMAL];
    const float *pdir = glossy ? ph.col[PM_PHOTON_DIRECTION] : NULL;
    layout(&map, perm, keep, n, ppos, ppow, pnor, pdir);
    double vvh_r = 0.0;
    if (o->split == 1) {
        /* The heuristic needs the searches' radius: given, or the one at which K photons
         * fall in a photon's kernel, found on the median tree just built. */
        vvh_r = o->vvh_radius;
        if (vvh_r <= 0.0 && n) {
            pm_gather_map_t gm;
            if ((r = pm_gather_map_init(&gm, &map, 0)) != PM_OK)
                goto done;
            static const pm_material_t folded = {.name = "folded", .kd = {1, 1, 1}};
            pm_gather_queries_t q = {.n = n, .pos = gm.pos, .normal = gm.normal, /* radius_for_k reads no weights */
                                     .materials = &folded, .nmaterials = 1};
            vvh_r = pm_gather_radius_for_k(&gm, &q, (double)o->vvh_k, 0.5f, 1000);
            pm_gather_map_free(&gm);
        }
        double t1 = pm_time_wall();
        if ((r = pm_kd_build_vvh(pos, n, (float)vvh_r, map.col[PM_MAP_NODE], perm, &bs)) != PM_OK)
            goto done;
        t_build += pm_time_wall() - t1;
        layout(&map, perm, keep, n, ppos, ppow, pnor, pdir);
    }
    double t_gather = pm_time_wall() - t0;

    /* Header: provenance from the photons file, then what this map is. */
    memcpy(map.hdr.bounds, ph.hdr.bounds, sizeof map.hdr.bounds);
    pm_header_t *h = &map.hdr;
    const char *emitted = pm_header_get(&ph.hdr, "emitted");
    if ((r = pm_header_inherit(h, &ph.hdr)) != PM_OK || (r = pm_header_add_input(h, in, ph.checksum)) != PM_OK ||
        (r = pm_header_add_command(h, st->argc, st->argv)) != PM_OK ||
        (r = pm_header_set(h, "map", "%s", map_kinds[o->map])) != PM_OK ||
        (r = pm_header_set(h, "split", "%s", split_kinds[o->split])) != PM_OK ||
        (o->split == 1 && (r = pm_header_set(h, "vvh_radius", "%.9g", vvh_r)) != PM_OK) ||
        (emitted && (r = pm_header_set(h, "emitted", "%s", emitted)) != PM_OK))
        goto done;

    double t_width = 0.0, mean_width = 0.0, pilot_r = 0.0;
    if (o->width_k > 0) {
        t0 = pm_time_wall();
        r = compute_widths(&map, (uint32_t)o->width_k, o->width_max, &mean_width, &pilot_r);
        t_width = pm_time_wall() - t0;
        if (r != PM_OK)
            goto done;
        if ((r = pm_header_set(h, "width_k", "%" PRId64, o->width_k)) != PM_OK)
            goto done;
    }

    t0 = pm_time_wall();
    r = pm_table_write(&map, st->output);
    double t_write = pm_time_wall() - t0;
    if (r != PM_OK)
        goto done;

    st->items = n;
    pm_stage_stat_int(st, "photons_in", (int64_t)n_in);
    pm_stage_stat_int(st, "photons", (int64_t)n);
    pm_stage_stat_string(st, "map", map_kinds[o->map]);
    pm_stage_stat_int(st, "depth", bs.depth);
    pm_stage_stat_int(st, "leaves", (int64_t)bs.leaves);
    pm_stage_stat_double(st, "read_s", t_read);
    pm_stage_stat_double(st, "build_s", t_build);
    pm_stage_stat_double(st, "build_photons_per_s", t_build > 0 ? (double)n / t_build : 0.0);
    pm_stage_stat_double(st, "gather_s", t_gather);
    if (o->width_k > 0) {
        pm_stage_stat_double(st, "width_s", t_width);
        pm_stage_stat_double(st, "mean_width_m", mean_width);
        pm_stage_stat_double(st, "pilot_radius_m", pilot_r);
    }
    pm_stage_stat_double(st, "write_s", t_write);
    pm_stage_note(st, "%" PRIu64 " photons (%s map of %" PRIu64 "), depth %u, built in %.3f s", n,
                  map_kinds[o->map], n_in, bs.depth, t_build);
done:
    free(keep);
    pm_free_aligned(pos);
    free(perm);
    pm_table_free(&map);
    pm_table_free(&ph);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    build_options_t o = {.map = 0, .split = 0, .width_k = 0, .width_max = 0.0, .vvh_radius = 0.0, .vvh_k = 50};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"map", 0, PM_OPT_CHOICE, &o.map, "KIND",
         "global: every stored photon; indirect: only photons that bounced (direct light from shadow rays)", 0, 0,
         map_kinds},
        {"split", 0, PM_OPT_CHOICE, &o.split, "RULE",
         "median: balanced, the paper's; vvh: the voxel-volume heuristic for searches of one radius", 0, 0,
         split_kinds},
        {"vvh-radius", 0, PM_OPT_DOUBLE, &o.vvh_radius, "R",
         "search radius the vvh split plans for, m (0: the radius holding --vvh-k photons)", 0, 1e30, NULL},
        {"vvh-k", 0, PM_OPT_INT, &o.vvh_k, "K", "photons per search the vvh radius is chosen for", 1, 1e6, NULL},
        {"width-k", 0, PM_OPT_INT, &o.width_k, "K",
         "store each photon's kernel width: the radius holding K photons around it (0: none)", 0, 65536, NULL},
        {"width-max", 0, PM_OPT_DOUBLE, &o.width_max, "M",
         "largest kernel width, m, for --width-k (0: no limit)", 0, 1e30, NULL},
        {0},
    };
    const pm_cli_t cli = {"build-photonmap", "[options] PHOTONS -o MAP",
                          "Build the photon map KD-tree (one photon per node, 8-byte nodes) from a photons file; "
                          "PHOTONS may be - for stdin.",
                          options, 1, 1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
