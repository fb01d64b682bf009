/* gather_impl.h: what gather.c and the per-ISA kernels (gather_isa.c) share. Private to
 * the library. */
#ifndef PM_GATHER_IMPL_H
#define PM_GATHER_IMPL_H

#include "photonmap/gather.h"

/* Shading steps between moving the float accumulators into double ones: at most 16 float
 * additions per lane, each rounding by at most half an ulp of the partial sum, so the sum
 * of any number of photons is good to 16/2 * 2^-24 = 5e-7 relative (the double sums then
 * lose nothing). At 256 a sum of 4M equal photons was 3e-6 off (tests/unit/test_gather.c,
 * docs/extreme-cases.md); a flush every 16 steps costs a few vector adds per 16 shadings. */
#define GATHER_FLUSH 16

typedef struct {
    const pm_gather_map_t *m;
    const pm_gather_queries_t *q;
    pm_kernel_t kernel;
    float r, r2, inv_r2, r_trav; /* fixed width h, h^2, 1/h^2, h grown by the slack (m) */
    float kscale;                /* K(0) / h^2: 1/(pi h^2) uniform, 2/(pi h^2) Epanechnikov */
    float kscale_unit;           /* the same for h = 1 (variable widths divide by h_i^2) */
    float slack;                 /* m: the split planes' and distances' rounding, see gather.c */
    float normal_cos;
    int glossy;                      /* some query material is glossy */
    const unsigned char *mat_glossy; /* per material: 1 when ks > 0 */
} gather_ctx_t;

typedef void (*gather_fn_t)(const gather_ctx_t *c, uint64_t begin, uint64_t end, double *out, pm_gather_stats_t *st);

/* One glossy pair: query qi (lane l of a W-lane packet) and photon node ni with kernel
 * value k (K / h^2): adds k f(wi, wo) power to dacc[channel * w + l]. */
void gather_glossy_lane(const gather_ctx_t *c, uint64_t qi, uint32_t ni, float k, double *dacc, uint32_t w, uint32_t l);

/* The kernels of gather_isa.c: [isa][variable]. */
gather_fn_t gather_kernel_for(pm_isa_t isa, int variable);

#endif
