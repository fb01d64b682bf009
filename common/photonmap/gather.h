/* gather.h: the final gather of the paper (sections 3, 5.3): the sample-point estimator
 * evaluated by packets of queries walking the photon KD-tree together.
 *
 * For every query q and every photon i whose kernel covers it (|y_q - x_i| < h) and whose
 * normal agrees with the query's, the estimator adds
 *
 *     f_rest,q(wi, wo) * power_i * K(|y_q - x_i| / h) / h^2          [W / (m^2 sr)]
 *
 * with K normalized so that its integral over the plane is 1: a uniform photon density of
 * E W/m^2 gives exactly E times f. Each pair is independent (no k-nearest-neighbour heap),
 * which is what lets W queries share one walk: a packet descends with a lane mask, a
 * node's photon is shaded when some lane's sphere straddles the node's plane, and the
 * shading applies the exact distance test per lane. The per-query sums are multiplied by
 * the query's weight afterwards (the weight contract of docs/formats.md, section 3.3).
 *
 * Widths: W = 1 (scalar), 4 (SSE4.1, the paper's), 8 (AVX2) and 16 (AVX-512), chosen at
 * run time; all give the same sums within float rounding. */
#ifndef PM_GATHER_H
#define PM_GATHER_H

#include <stdint.h>

#include "base/cpu.h"
#include "base/error.h"
#include "formats/formats.h"

typedef enum { PM_KERNEL_UNIFORM = 0, PM_KERNEL_EPANECHNIKOV = 1 } pm_kernel_t;

/* The hot record of node i, built at load: the photon's position and the node in 16
 * bytes, so that a visit touches one cache line instead of one in the node array and one
 * in the position array. The split plane is the photon's exact coordinate on the axis;
 * `link` holds the axis in its top 2 bits (3: leaf) and the right child in the other 30
 * (PM_GATHER_NO_CHILD: none; i + 1: the left subtree is empty). */
typedef struct {
    float p[3];
    uint32_t link;
} pm_gather_hot_t;
#define PM_GATHER_NO_CHILD 0x3fffffffu
#define PM_GATHER_MAX_PHOTONS 0x3fffffffu

/* The photon map as the gather reads it: node-order arrays (hot: node, pos; cold: the
 * rest). Built from a photon map table by pm_gather_map_init. */
typedef struct {
    uint32_t n;
    const pm_kdnode_t *node;
    const float *pos;     /* n * 3, m */
    const float *power;   /* n * 3, W */
    const float *normal;  /* n * 3 */
    const float *dir;     /* n * 3 or NULL: toward where the photon came from (glossy scenes) */
    const float *width;   /* n or NULL: kernel width h_i, m (variable widths) */
    float *subtree_width; /* n, owned: the largest width in node i's subtree (variable widths) */
    pm_gather_hot_t *hot; /* n, owned: node and position interleaved, the walk's only reads */
    float max_abs;        /* largest |coordinate| of any photon, m: bounds the split planes' slack */
} pm_gather_map_t;

/* The queries as the gather reads them (structure of arrays, from a queries table). */
typedef struct {
    uint64_t n;
    const float *pos, *normal, *weight; /* n * 3 each; weight NULL: 1 (pm_gather_run and brute only) */
    const uint32_t *pixel;
    const uint16_t *material;       /* NULL: every query has material 0 */
    const float *dir;               /* n * 3 or NULL */
    const float *radius;            /* n or NULL: each query's kernel width h, m (params' per_query) */
    const pm_material_t *materials; /* the file's material table */
    uint32_t nmaterials;
} pm_gather_queries_t;

typedef struct {
    double radius; /* m: fixed kernel width h (ignored with variable widths) */
    pm_kernel_t kernel;
    int variable;     /* 1: each photon's own width from the map's width channel */
    int per_query;    /* 1: each query's own width from q->radius (radius ignored; not with variable) */
    float normal_cos; /* a photon counts when dot(n_photon, n_query) >= this */
    pm_isa_t isa;
} pm_gather_params_t;

typedef struct {
    uint64_t shader_ops;       /* photon-query pairs inside the kernel (and normal test) */
    uint64_t shade_steps;      /* calls of the shading step (a node's photon against a packet) */
    uint64_t active_lanes;     /* sum over shading steps of the lanes live in that step */
    uint64_t straddling_lanes; /* ... of those whose sphere straddles the node's plane (or a leaf's live lanes) */
    uint64_t nodes_visited;    /* packet-node visits */
    uint64_t packets;
    double cpu_s; /* CPU seconds the threads spent in the kernels (robust to other load) */
} pm_gather_stats_t;

/* Views the map table's columns (no copy); with variable widths also computes the
 * subtree maxima. Free with pm_gather_map_free. */
pm_result_t pm_gather_map_init(pm_gather_map_t *m, const pm_table_t *map, int variable);
void pm_gather_map_free(pm_gather_map_t *m);

/* Views a queries table's columns and its material table (malloc'd into *materials_out,
 * freed by the caller). */
pm_result_t pm_gather_queries_init(pm_gather_queries_t *q, const pm_table_t *t, const char *path,
                                   pm_material_t **materials_out);

/* Gathers queries [begin, end): out[3 (i - begin) + c] receives query i's weighted
 * radiance (weight times the estimate), W/(m^2 sr), in double. Packets are W consecutive
 * queries; threads take fixed blocks of packets, so the result does not depend on the
 * thread count. */
pm_result_t pm_gather_run(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                          const pm_gather_params_t *p, double *out, pm_gather_stats_t *stats);

/* The radius at which about k photons contribute (inside the kernel, normals agreeing) to a
 * query, on average over a fixed sample of at most `samples` queries; by bisection on
 * exact counts. 0 when the map or the queries are empty. */
double pm_gather_radius_for_k(const pm_gather_map_t *m, const pm_gather_queries_t *q, double k, float normal_cos,
                              uint32_t samples);

/* f(wi, wo) of material mt (its whole Phong BRDF, 1/sr) at a surface of normal n, in double:
 * wi toward where the photon came from, wo toward the viewer. The scalar evaluation every
 * non-SIMD path shares (the references, the baseline gathers). */
void pm_gather_brdf(const pm_material_t *mt, const float n[3], const float wi[3], const float wo[3], double f[3]);

/* Which of the queries' materials are glossy (need the BRDF per pair): a table of
 * q->nmaterials bytes (1: glossy) in *glossy_out, freed by the caller, and in *any_out
 * whether any is. Fails when a glossy material meets queries or a map without the
 * direction channel. */
pm_result_t pm_gather_glossy_table(const pm_gather_map_t *m, const pm_gather_queries_t *q, unsigned char **glossy_out,
                                   int *any_out);

/* The argument checks every gather makes: [begin, end) within the queries (PM_ERR_INTERNAL),
 * and a positive kernel radius whose square fits a float (PM_ERR_USAGE). */
pm_result_t pm_gather_check_range(const pm_gather_queries_t *q, uint64_t begin, uint64_t end);
pm_result_t pm_gather_check_radius(double radius);

/* The O(n m) reference: every photon against every query, in double. For tests. */
void pm_gather_brute(const pm_gather_map_t *m, const pm_gather_queries_t *q, uint64_t begin, uint64_t end,
                     const pm_gather_params_t *p, double *out);

/* Kernel value K(t) / h^2 for t = d / h in [0, 1), normalized over the plane. */
static inline double pm_kernel_value(pm_kernel_t k, double d2, double h2)
{
    const double inv_pi = 0.31830988618379067;
    return k == PM_KERNEL_UNIFORM ? inv_pi / h2 : 2.0 * inv_pi / h2 * (1.0 - d2 / h2);
}

#endif
