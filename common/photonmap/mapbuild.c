/* mapbuild.c: photons file -> photon map (the paper, section 5.2), build-photonmap's work; see
 * mapbuild.h. The tree is kdtree.c's; this file picks the photons, lays their channels out in
 * node order and computes the kernel widths, which count photons with the SIMD packet gather
 * of gather.c. */
#include "photonmap/mapbuild.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/cpu.h"
#include "base/memory.h"
#include "base/timer.h"
#include "photonmap/gather.h"

const char *const pm_map_kind_names[] = {"global", "indirect", "caustic", NULL};
const char *const pm_split_names[] = {"median", "vvh", NULL};

/* Kernel width of every photon: the radius of the disc around it that holds K photons
 * (itself included, normals agreeing), the k-nearest-neighbour pilot estimate of the
 * local photon density (Silverman's adaptive kernel; h ~ density^-1/2 on a surface,
 * Terrell and Scott's rule in two dimensions). Found in rounds on the same SIMD packets
 * as simd-gather, with the photons as their own queries and unit powers so that a gather
 * counts: every photon still short of K photons is counted at radius r, those with
 * c >= K take h = r sqrt(K / c) (the radius that holds K at the density c / (pi r^2)),
 * the others go on at r sqrt(2). Starting at half the radius that holds K on average, a
 * photon is counted about twice, at a cost near K per round, where a k-nearest-neighbour
 * heap search per photon costs more (docs/programs/build-photonmap.md). Clamped to
 * [a millionth of the scene, width_max]. */
enum { WIDTH_STRIDE = 8 };
/* A pilot could count fewer photons than K and scale its radius by sqrt(K / count); this cap
 * would be that count. It is off, and the pilot counts K: a smaller pilot gave more error in
 * dark regions for little time saved (docs/programs/build-photonmap.md). */
enum { PILOT_K = 1 << 20 };

static pm_result_t compute_widths(pm_table_t *map, uint32_t k_final, double width_max, double *mean_out, double *r0_out)
{
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
    float *qpos = pm_alloc_aligned((size_t)n * 3 * sizeof *qpos),
          *qnor = pm_alloc_aligned((size_t)n * 3 * sizeof *qnor);
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
        pm_gather_queries_t all = {
            .n = n, .pos = gm.pos, .normal = gm.normal, .weight = ones, .materials = &folded, .nmaterials = 1};
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
            pm_gather_queries_t q = {
                .n = np, .pos = qpos, .normal = qnor, .weight = ones, .materials = &folded, .nmaterials = 1};
            pm_gather_params_t p = {
                .radius = rad, .kernel = PM_KERNEL_UNIFORM, .normal_cos = normal_cos, .isa = pm_cpu_best_isa()};
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

pm_result_t pm_map_build(const pm_table_t *ph, const char *path, const pm_map_build_params_t *p, pm_table_t *map,
                         pm_map_build_stats_t *stats)
{
    uint32_t *keep = NULL, *perm = NULL;
    float *pos = NULL;
    uint64_t n_in = ph->count, n = 0;
    pm_result_t r = PM_OK;
    memset(map, 0, sizeof *map);
    memset(stats, 0, sizeof *stats);
    stats->photons_in = n_in;

    /* A caustic map is made of caustic photons only, and they make nothing else: the header
     * key kind=caustic that trace-photons --caustic-output writes tells them apart. */
    const char *kind = pm_header_get(&ph->hdr, "kind");
    int caustic_in = kind && !strcmp(kind, "caustic");
    if ((p->map == PM_MAP_CAUSTIC) != caustic_in) {
        r = pm_error_set(PM_ERR_INPUT, "%s '%s': a %s map needs %s (trace-photons %s)",
                         caustic_in ? "caustic photons" : "not caustic photons", path, pm_map_kind_names[p->map],
                         p->map == PM_MAP_CAUSTIC ? "a caustic photons file (kind=caustic)" : "the global photons",
                         p->map == PM_MAP_CAUSTIC ? "--caustic-output" : "-o");
        goto done;
    }
    /* The photons this map holds: all, or those that bounced at least once. */
    const uint32_t *depth = ph->col[PM_PHOTON_DEPTH];
    const float *ppos = ph->col[PM_PHOTON_POSITION];
    int indirect = p->map == PM_MAP_INDIRECT;
    keep = malloc((n_in ? n_in : 1) * sizeof *keep);
    pos = pm_alloc_aligned((n_in ? n_in : 1) * 3 * sizeof *pos);
    perm = malloc((n_in ? n_in : 1) * sizeof *perm);
    if (!keep || !pos || !perm) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " photons of '%s'", n_in, path);
        goto done;
    }
    for (uint64_t i = 0; i < n_in; i++)
        if (!indirect || depth[i] > 0) {
            keep[n] = (uint32_t)i;
            memcpy(&pos[3 * n], &ppos[3 * i], 3 * sizeof *pos);
            n++;
        }
    stats->photons = n;

    int glossy = (ph->hdr.channels >> PM_PHOTON_DIRECTION) & 1u;
    uint32_t channels = pm_schema_required(&pm_photonmap_schema) | (glossy ? 1u << PM_MAP_DIRECTION : 0u) |
                        (p->width_k > 0 ? 1u << PM_MAP_WIDTH : 0u);
    if ((r = pm_table_alloc(map, &pm_photonmap_schema, channels, n)) != PM_OK)
        goto done;

    double t0 = pm_time_wall();
    r = pm_kd_build(pos, n, map->col[PM_MAP_NODE], perm, &stats->tree);
    stats->build_s = pm_time_wall() - t0;
    if (r != PM_OK)
        goto done;

    /* Photon data in node order: hot positions, then the cold channels. */
    t0 = pm_time_wall();
    const float *ppow = ph->col[PM_PHOTON_POWER], *pnor = ph->col[PM_PHOTON_NORMAL];
    const float *pdir = glossy ? ph->col[PM_PHOTON_DIRECTION] : NULL;
    layout(map, perm, keep, n, ppos, ppow, pnor, pdir);
    if (p->split == PM_SPLIT_VVH) {
        /* The heuristic needs the searches' radius: given, or the one at which K photons
         * fall in a photon's kernel, found on the median tree just built. */
        double vvh_r = p->vvh_radius;
        if (vvh_r <= 0.0 && n) {
            pm_gather_map_t gm;
            if ((r = pm_gather_map_init(&gm, map, 0)) != PM_OK)
                goto done;
            static const pm_material_t folded = {.name = "folded", .kd = {1, 1, 1}};
            pm_gather_queries_t q = {.n = n,
                                     .pos = gm.pos,
                                     .normal = gm.normal, /* radius_for_k reads no weights */
                                     .materials = &folded,
                                     .nmaterials = 1};
            vvh_r = pm_gather_radius_for_k(&gm, &q, (double)p->vvh_k, 0.5f, 1000);
            pm_gather_map_free(&gm);
        }
        stats->vvh_radius = vvh_r;
        double t1 = pm_time_wall();
        if ((r = pm_kd_build_vvh(pos, n, (float)vvh_r, map->col[PM_MAP_NODE], perm, &stats->tree)) != PM_OK)
            goto done;
        stats->build_s += pm_time_wall() - t1;
        layout(map, perm, keep, n, ppos, ppow, pnor, pdir);
    }
    stats->layout_s = pm_time_wall() - t0;

    /* The widths are measured against the scene's extent: the photons file's bounds. */
    memcpy(map->hdr.bounds, ph->hdr.bounds, sizeof map->hdr.bounds);
    if (p->width_k > 0) {
        t0 = pm_time_wall();
        r = compute_widths(map, p->width_k, p->width_max, &stats->mean_width, &stats->pilot_radius);
        stats->width_s = pm_time_wall() - t0;
    }
done:
    free(keep);
    pm_free_aligned(pos);
    free(perm);
    if (r != PM_OK) {
        pm_table_free(map);
        memset(map, 0, sizeof *map);
    }
    return r;
}

pm_result_t pm_map_build_header(pm_table_t *map, const pm_table_t *ph, const char *path, int argc, char **argv,
                                const pm_map_build_params_t *p, const pm_map_build_stats_t *stats)
{
    pm_header_t *h = &map->hdr;
    const char *emitted = pm_header_get(&ph->hdr, "emitted");
    const char *pass = pm_header_get(&ph->hdr, "pass"); /* a progressive pass's map says which */
    /* photons without the first hits the gather points sample (trace-photons --indirect-only):
     * the gathers check it against their queries */
    const char *io = pm_header_get(&ph->hdr, "indirect_only");
    pm_result_t r;
    if ((r = pm_header_inherit(h, &ph->hdr)) != PM_OK || (r = pm_header_add_input(h, path, ph->checksum)) != PM_OK ||
        (r = pm_header_add_command(h, argc, argv)) != PM_OK ||
        (r = pm_header_set(h, "map", "%s", pm_map_kind_names[p->map])) != PM_OK ||
        (io && (r = pm_header_set(h, "indirect_only", "%s", io)) != PM_OK) ||
        (r = pm_header_set(h, "split", "%s", pm_split_names[p->split])) != PM_OK ||
        (p->split == PM_SPLIT_VVH && (r = pm_header_set(h, "vvh_radius", "%.9g", stats->vvh_radius)) != PM_OK) ||
        (emitted && (r = pm_header_set(h, "emitted", "%s", emitted)) != PM_OK) ||
        (pass && (r = pm_header_set(h, "pass", "%s", pass)) != PM_OK) ||
        (p->width_k > 0 && (r = pm_header_set(h, "width_k", "%" PRIu32, p->width_k)) != PM_OK))
        return r;
    return PM_OK;
}

pm_result_t pm_map_build_arrays(const float *pos, const float *power, const float *normal, const float *dir, uint64_t n,
                                const char *name, int argc, char **argv, pm_table_t *map_out)
{
    memset(map_out, 0, sizeof *map_out);
    uint32_t ch = pm_schema_required(&pm_photons_schema) | (dir ? 1u << PM_PHOTON_DIRECTION : 0);
    pm_table_t in = {0};
    pm_result_t r = pm_table_alloc(&in, &pm_photons_schema, ch, n);
    if (r != PM_OK)
        return r;
    size_t bytes = 3 * sizeof(float) * n;
    if (bytes) { /* an empty map's arrays may be NULL */
        memcpy(in.col[PM_PHOTON_POSITION], pos, bytes);
        memcpy(in.col[PM_PHOTON_POWER], power, bytes);
        memcpy(in.col[PM_PHOTON_NORMAL], normal, bytes);
        if (dir)
            memcpy(in.col[PM_PHOTON_DIRECTION], dir, bytes);
    }
    float *b = in.hdr.bounds; /* the scene bounds: the photons' own */
    for (int k = 0; k < 3; k++)
        b[k] = n ? INFINITY : 0.0f, b[3 + k] = n ? -INFINITY : 0.0f;
    for (uint64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            b[k] = fminf(b[k], pos[3 * i + k]), b[3 + k] = fmaxf(b[3 + k], pos[3 * i + k]);
    pm_map_build_params_t p = {.map = PM_MAP_GLOBAL, .split = PM_SPLIT_MEDIAN};
    pm_map_build_stats_t st;
    r = pm_map_build(&in, name, &p, map_out, &st);
    if (r == PM_OK && argv && (r = pm_map_build_header(map_out, &in, name, argc, argv, &p, &st)) != PM_OK) {
        pm_table_free(map_out);
        memset(map_out, 0, sizeof *map_out);
    }
    pm_table_free(&in);
    return r;
}
