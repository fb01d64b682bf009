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
    const unsigned char *mat_glossy; /* per material: 1 when its f depends on wi (pm_material_is_glossy) */
    const float *mat_fdr;            /* per material: a plastic's pm_fresnel_diffuse_inside(ior), else 0 */
} gather_ctx_t;

/* The per-lane parameters of the SIMD evaluation of f (gather_kernel.h), one row of W floats
 * each, filled per packet for its glossy lanes by gather_lanes_setup:
 *   standard (Phong): GL_KD kd / pi, GL_KS ks, GL_NS ns;
 *   conductor and plastic (GGX): GL_N the query normal turned to wo's side, GL_CO its cosine
 *   to wo, GL_A2 alpha^2, GL_LO Smith's Lambda at wo; a conductor's GL_E eta (or f0 under
 *   Schlick) and GL_K k; a plastic's GL_IOR and in GL_KD its base kd (1 - F(n.wo)) / (pi ior^2
 *   (1 - kd Fdr_in)), the factors of physics/bsdf.c's plastic_base that do not depend on wi.
 * GL_KIND is one of the GL_KIND_* codes. */
enum {
    GL_KD = 0,
    GL_KS = 3,
    GL_NS = 6,
    GL_N = 7,
    GL_CO = 10,
    GL_A2 = 11,
    GL_LO = 12,
    GL_IOR = 13,
    GL_E = 14,
    GL_K = 17,
    GL_KIND = 20,
    GL_ROWS = 21
};
enum { GL_KIND_PHONG = 0, GL_KIND_CONDUCTOR = 1, GL_KIND_SCHLICK = 2, GL_KIND_PLASTIC = 3, GL_KIND_MODULE = 4 };

/* Lane l's row entries for query qi (material mt, normal n, outgoing wo) into gl (GL_ROWS rows
 * of w floats); returns its GL_KIND_* code. GL_KIND_MODULE: a kind the SIMD code does not
 * evaluate (rough glass, whose surfaces hold no photons and get no queries from trace-gather-points),
 * evaluated by physics/bsdf.h itself, pair by pair (gather_glossy_lane). */
int gather_lane_setup(const gather_ctx_t *c, const pm_material_t *mt, uint32_t mi, const float n[3], const float wo[3],
                      float *gl, uint32_t w, uint32_t l);

typedef void (*gather_fn_t)(const gather_ctx_t *c, uint64_t begin, uint64_t end, double *out, pm_gather_stats_t *st);

/* One glossy pair: query qi (lane l of a W-lane packet) and photon node ni with kernel
 * value k (K / h^2): adds k f(wi, wo) power to dacc[channel * w + l]. */
void gather_glossy_lane(const gather_ctx_t *c, uint64_t qi, uint32_t ni, float k, double *dacc, uint32_t w, uint32_t l);

/* The kernels of gather_isa.c: [isa][widths], widths 0 fixed, 1 per photon, 2 per query. */
gather_fn_t gather_kernel_for(pm_isa_t isa, int widths);

#endif
