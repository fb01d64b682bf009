/* guide.h: photon-guided secondary rays (issue 30; Jensen 1995, "Importance driven path tracing
 * using the photon map"), the guide trace-gather-points --guide builds from a pass's photons.
 *
 * The photons that arrived at a surface after at least one bounce (depth >= 1) say where the
 * indirect light there comes from: their incoming directions (the photons format's direction
 * channel), weighted by their power's luminance, are a histogram of L cos over the sphere, the
 * shape of the final gather's integrand at a Lambertian surface. Photons of depth 0 came straight
 * from a light: that light is the light samples' (next-event estimation), and a secondary ray
 * sent toward it finds nothing the gather counts, so they are left out.
 *
 * Space is cut into a uniform grid of cubic cells (the edge chosen from the photons so that an
 * occupied cell holds about PM_GUIDE_TARGET of them), each further split by the dominant axis
 * and sign of the photons' normals, so that the floor and the wall of one corner cell keep
 * histograms of their own. Cells live in a hash table: the build is O(photons), a lookup O(1).
 * Each cell's histogram is an equal-area sphere map about the y axis, PM_GUIDE_NZ bands of
 * y = cos theta in [-1, 1] times PM_GUIDE_NPHI sectors of phi = atan2(z, x), every bin of solid
 * angle 4 pi / PM_GUIDE_BINS; with y as the pole and sector edges at multiples of 22.5 degrees,
 * the hemisphere above a surface facing any axis is exactly half the bins (none straddle it).
 * A cell with fewer than PM_GUIDE_MIN photons is left out: its lookups find nothing, and the
 * caller falls back to cosine sampling alone. So is a cell where the guide would not help: cosine
 * sampling is exact for light that arrives evenly (the furnace), and a mixture with a histogram
 * only adds its own spread there. The build estimates, from the cell's photons themselves (each
 * a sample of L cos, its bin's flux without it standing in for the integrand), the second moment
 * of one secondary ray's estimate under cosine sampling and under the mixture, and keeps the cell
 * only when the mixture's is below PM_GUIDE_GAIN times the cosine's.
 *
 * The guide is read-only once built: any number of threads may look up, sample and evaluate it. */
#ifndef PM_GUIDE_H
#define PM_GUIDE_H

#include <stdint.h>

#include "base/error.h"

#define PM_GUIDE_NZ 8
#define PM_GUIDE_NPHI 16
#define PM_GUIDE_BINS (PM_GUIDE_NZ * PM_GUIDE_NPHI)
#define PM_GUIDE_TARGET 128 /* photons an occupied cell holds on average, about */
#define PM_GUIDE_MIN 32     /* fewer photons: the cell is not used (cosine sampling alone there) */
/* Share of the secondary rays drawn by cosine at a guided surface: the mixture
 * p = PM_GUIDE_COSINE cos / pi + (1 - PM_GUIDE_COSINE) p_guide keeps every direction above the
 * surface reachable, so the estimate stays unbiased whatever the histogram says. */
#define PM_GUIDE_COSINE 0.5f
#define PM_GUIDE_GAIN 0.7f /* a cell is kept when the mixture's second moment is below this times cosine's */

/* The photons a guide is built from: n records as the photons format's columns. */
typedef struct {
    const float *pos;      /* 3n, m */
    const float *power;    /* 3n, W */
    const float *normal;   /* 3n, unit */
    const float *dir;      /* 3n, unit: toward where each photon came from */
    const uint32_t *depth; /* n */
    uint64_t n;
} pm_guide_photons_t;

/* One cell's directional distribution. */
typedef struct {
    float pdf[PM_GUIDE_BINS]; /* each bin's probability (they sum to 1) */
    float cdf[PM_GUIDE_BINS]; /* running sums, the last exactly 1 */
    uint32_t photons;         /* photons it holds */
    int used;                 /* the guide helps here (PM_GUIDE_GAIN); else lookups find nothing */
} pm_guide_cell_t;

typedef struct pm_guide pm_guide_t;

/* What a guide holds, for headers and --stats. */
typedef struct {
    uint64_t photons_used; /* depth >= 1 photons of non-zero power */
    uint64_t cells;        /* cells with at least PM_GUIDE_MIN photons */
    uint64_t cells_sparse; /* occupied cells left out for holding fewer */
    uint64_t cells_even;   /* cells left out for light so even that cosine sampling does better */
    double edge;           /* m, a cell's edge */
} pm_guide_info_t;

/* Builds the guide; PM_ERR_NOMEM. A set with no usable photon gives a guide of no cells. With
 * all, every cell of PM_GUIDE_MIN photons is used, whether it helps or not (tests of the weights). */
pm_result_t pm_guide_build(const pm_guide_photons_t *ph, int all, pm_guide_t **out);
void pm_guide_destroy(pm_guide_t *g);
const pm_guide_info_t *pm_guide_info(const pm_guide_t *g);

/* The cell of a surface at p with geometric normal n (unit); NULL where there is none
 * (outside the photons' cells, or a sparse one). */
const pm_guide_cell_t *pm_guide_find(const pm_guide_t *g, const float p[3], const float n[3]);

/* A direction from the cell's distribution for (u1, u2) in [0,1)^2: u1 picks the bin by the
 * cdf and, rescaled, the band's height inside it; u2 the angle inside it (stratified points stay
 * stratified). Writes a unit wi. */
void pm_guide_sample(const pm_guide_cell_t *c, float u1, float u2, float wi[3]);

/* The cell's solid-angle density at unit direction wi, 1/sr. */
float pm_guide_pdf(const pm_guide_cell_t *c, const float wi[3]);

/* The bin of unit direction wi (the map above). */
unsigned pm_guide_bin(const float wi[3]);

#endif
