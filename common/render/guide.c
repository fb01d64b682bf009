/* guide.c: the photon guide of the secondary rays (guide.h): a hashed grid of directional
 * histograms built from a pass's photons, sampled and evaluated by the eye tracer
 * (render/eyetrace.c) at its Lambertian primary hits. Reads arrays, writes nothing. */
#include "render/guide.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/sampling.h"

#define AXIS_BITS 3
#define COORD_BITS 20 /* grid coordinates per axis: up to 2^20 cells */
#define COORD_MAX ((1 << COORD_BITS) - 1)
#define EMPTY UINT64_MAX

struct pm_guide {
    pm_guide_info_t info;
    float lo[3];    /* m, the grid's corner */
    float inv_edge; /* 1/m */
    uint64_t *keys; /* hash table of cell keys (EMPTY where free) */
    uint32_t *slot; /* the cell index of each key, UINT32_MAX for a sparse cell */
    uint64_t mask;  /* table size - 1 */
    pm_guide_cell_t *cells;
};

/* The normal's dominant axis and sign: 0..5. */
static inline unsigned axis_class(const float n[3])
{
    float ax = fabsf(n[0]), ay = fabsf(n[1]), az = fabsf(n[2]);
    unsigned a = ax >= ay && ax >= az ? 0u : ay >= az ? 1u : 2u;
    return 2u * a + (n[a] < 0.0f);
}

static inline uint64_t hash64(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return k;
}

/* The key of point p with normal n on a grid of corner lo and 1/edge inv; EMPTY outside it. */
static inline uint64_t cell_key(const float lo[3], float inv, const float p[3], const float n[3])
{
    uint64_t key = axis_class(n);
    for (int k = 0; k < 3; k++) {
        float c = floorf((p[k] - lo[k]) * inv);
        if (!(c >= 0.0f && c <= (float)COORD_MAX))
            return EMPTY;
        key |= (uint64_t)c << (AXIS_BITS + COORD_BITS * k);
    }
    return key;
}

/* The table position of key (inserted when absent, *added set then). */
static uint64_t table_find(uint64_t *keys, uint64_t mask, uint64_t key, int insert, int *added)
{
    uint64_t h = hash64(key) & mask;
    for (;;) {
        if (keys[h] == key)
            return h;
        if (keys[h] == EMPTY) {
            if (insert) {
                keys[h] = key;
                *added = 1;
            }
            return h;
        }
        h = (h + 1) & mask;
    }
}

static inline float luminance(const float c[3]) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

static inline int usable(const pm_guide_photons_t *ph, uint64_t i)
{
    return ph->depth[i] >= 1 && luminance(ph->power + 3 * i) > 0.0f;
}

/* Occupied cells of edge 1/inv over the usable photons (keys cleared first). */
static uint64_t count_cells(const pm_guide_photons_t *ph, const float lo[3], float inv, uint64_t *keys, uint64_t mask)
{
    memset(keys, 0xff, (mask + 1) * sizeof *keys);
    uint64_t cells = 0;
    for (uint64_t i = 0; i < ph->n; i++) {
        if (!usable(ph, i))
            continue;
        uint64_t key = cell_key(lo, inv, ph->pos + 3 * i, ph->normal + 3 * i);
        int added = 0;
        if (key != EMPTY)
            table_find(keys, mask, key, 1, &added);
        cells += (uint64_t)added;
    }
    return cells;
}

/* The table entry of photon i's cell once the table holds every cell; EMPTY for a photon the
 * guide does not use or outside the grid. */
static uint64_t photon_entry(const pm_guide_t *g, const pm_guide_photons_t *ph, uint64_t i)
{
    if (!usable(ph, i))
        return EMPTY;
    uint64_t key = cell_key(g->lo, g->inv_edge, ph->pos + 3 * i, ph->normal + 3 * i);
    int added = 0;
    return key == EMPTY ? EMPTY : table_find(g->keys, g->mask, key, 0, &added);
}

unsigned pm_guide_bin(const float wi[3])
{
    int iz = (int)((wi[1] + 1.0f) * (0.5f * PM_GUIDE_NZ));
    float phi = atan2f(wi[2], wi[0]); /* [-pi, pi] */
    int ip = (int)((phi + PM_PI) * (PM_GUIDE_NPHI / (2.0f * PM_PI)));
    iz = iz < 0 ? 0 : iz >= PM_GUIDE_NZ ? PM_GUIDE_NZ - 1 : iz;
    ip = ip < 0 ? 0 : ip >= PM_GUIDE_NPHI ? PM_GUIDE_NPHI - 1 : ip;
    return (unsigned)(iz * PM_GUIDE_NPHI + ip);
}

/* Marks each cell used or not (guide.h, PM_GUIDE_GAIN); returns the cells left out, or
 * UINT64_MAX when its moments do not fit in memory. wh holds the
 * cells' bin fluxes of the two halves of their photons (even and odd index: PM_GUIDE_BINS each,
 * half 0 then half 1), axis their normals' classes. For the photons i of a cell, each drawn in
 * proportion to f = L cos, the second moment of f / p is proportional to sum_i w_i f(w_i) / p(w_i).
 * Cross-validated, so that the histogram's noise counts against it: f(w_i) is the flux of photon
 * i's bin in its own half without it, the guide's pdf the other half's histogram. cos is the cell
 * axis's (the surfaces' normals lie near it). */
static uint64_t keep_helpful(pm_guide_t *g, const pm_guide_photons_t *ph, const double *wh, const unsigned char *axis,
                             uint64_t ncells)
{
    double *mom = calloc(4 * (ncells ? ncells : 1), sizeof *mom), *tot = mom ? mom + 2 * ncells : NULL;
    if (!mom)
        return UINT64_MAX;
    for (uint64_t ci = 0; ci < 2 * ncells; ci++)
        for (int k = 0; k < PM_GUIDE_BINS; k++)
            tot[ci] += wh[ci * PM_GUIDE_BINS + k];
    const double omega = 4.0 * PM_PI / PM_GUIDE_BINS, C = PM_GUIDE_COSINE;
    for (uint64_t i = 0; i < ph->n; i++) {
        uint64_t h = photon_entry(g, ph, i);
        if (h == EMPTY)
            continue;
        if (g->slot[h] == UINT32_MAX)
            continue;
        uint32_t ci = g->slot[h];
        const float *d = ph->dir + 3 * i;
        unsigned b = pm_guide_bin(d), a = axis[ci] >> 1;
        size_t own = 2 * (size_t)ci + (i & 1u), other = 2 * (size_t)ci + 1u - (i & 1u);
        double cosn = (axis[ci] & 1u ? -1.0 : 1.0) * d[a];
        double wi = luminance(ph->power + 3 * i), wb = wh[own * PM_GUIDE_BINS + b] - wi;
        if (!(tot[other] > 0.0) || !(wb > 0.0))
            continue; /* alone in its bin: no estimate of f there */
        double f = wb / omega, pc = (cosn > 0.05 ? cosn : 0.05) / PM_PI;
        double pg = wh[other * PM_GUIDE_BINS + b] / tot[other] / omega;
        mom[2 * ci] += wi * f / pc;
        mom[2 * ci + 1] += wi * f / (C * pc + (1.0 - C) * pg);
    }
    uint64_t even = 0;
    for (uint64_t ci = 0; ci < ncells; ci++) {
        g->cells[ci].used = mom[2 * ci + 1] < PM_GUIDE_GAIN * mom[2 * ci];
        even += !g->cells[ci].used;
    }
    free(mom);
    return even;
}

pm_result_t pm_guide_build(const pm_guide_photons_t *ph, int all, pm_guide_t **out)
{
    *out = NULL;
    pm_guide_t *g = calloc(1, sizeof *g);
    if (!g)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the photon guide");
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    uint64_t used = 0;
    for (uint64_t i = 0; i < ph->n; i++) {
        if (!usable(ph, i))
            continue;
        used++;
        for (int k = 0; k < 3; k++)
            lo[k] = fminf(lo[k], ph->pos[3 * i + k]), hi[k] = fmaxf(hi[k], ph->pos[3 * i + k]);
    }
    g->info.photons_used = used;
    if (!used) {
        *out = g;
        return PM_OK;
    }
    uint64_t cap = 16;
    while (cap < 2 * used)
        cap *= 2;
    g->mask = cap - 1;
    g->keys = malloc(cap * sizeof *g->keys);
    g->slot = malloc(cap * sizeof *g->slot);
    if (!g->keys || !g->slot) {
        pm_guide_destroy(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the photon guide's table of %llu entries",
                            (unsigned long long)cap);
    }
    /* The edge: a first guess of 1/128 of the diagonal, then scaled by the square root of the
     * ratio of the photons an occupied cell should hold to those it holds (photons lie on
     * surfaces: occupied cells go as the inverse square of the edge). */
    double diag = 0.0;
    for (int k = 0; k < 3; k++)
        diag += (double)(hi[k] - lo[k]) * (hi[k] - lo[k]);
    diag = sqrt(diag);
    double edge = diag > 0.0 ? diag / 128.0 : 1.0;
    for (int k = 0; k < 3; k++)
        g->lo[k] = lo[k];
    for (int round = 0; round < 2; round++) {
        uint64_t cells = count_cells(ph, g->lo, (float)(1.0 / edge), g->keys, g->mask);
        double per = (double)used / (double)(cells ? cells : 1);
        edge *= sqrt((double)PM_GUIDE_TARGET / per);
        double floor_edge = diag / (double)(COORD_MAX / 2);
        if (!(edge >= floor_edge))
            edge = floor_edge > 0.0 ? floor_edge : 1.0;
    }
    g->info.edge = edge;
    g->inv_edge = (float)(1.0 / edge);
    count_cells(ph, g->lo, g->inv_edge, g->keys, g->mask);
    /* Photons per occupied cell, then cell indices in order of first appearance (deterministic). */
    uint32_t *count = calloc(cap, sizeof *count);
    if (!count) {
        pm_guide_destroy(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the photon guide's counts");
    }
    for (uint64_t i = 0; i < ph->n; i++) {
        uint64_t h = photon_entry(g, ph, i);
        if (h != EMPTY)
            count[h]++;
    }
    uint64_t ncells = 0, sparse = 0;
    for (uint64_t h = 0; h < cap; h++) {
        g->slot[h] = UINT32_MAX;
        if (g->keys[h] != EMPTY) {
            if (count[h] >= PM_GUIDE_MIN)
                ncells++;
            else
                sparse++;
        }
    }
    g->cells = calloc(ncells ? ncells : 1, sizeof *g->cells);
    double *w = calloc((ncells ? ncells : 1) * PM_GUIDE_BINS * 3, sizeof *w),
           *wh = w ? w + ncells * PM_GUIDE_BINS : NULL;
    if (!g->cells || !w) {
        free(count), free(w);
        pm_guide_destroy(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %llu guide cells", (unsigned long long)ncells);
    }
    uint32_t next = 0;
    unsigned char *axis = calloc(ncells ? ncells : 1, 1);
    if (!axis) {
        free(count), free(w);
        pm_guide_destroy(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %llu guide cells", (unsigned long long)ncells);
    }
    for (uint64_t i = 0; i < ph->n; i++) {
        uint64_t h = photon_entry(g, ph, i);
        if (h == EMPTY)
            continue;
        if (count[h] < PM_GUIDE_MIN)
            continue;
        if (g->slot[h] == UINT32_MAX) {
            axis[next] = (unsigned char)(g->keys[h] & 7u);
            g->slot[h] = next++;
        }
        pm_guide_cell_t *c = &g->cells[g->slot[h]];
        c->photons++;
        unsigned b = pm_guide_bin(ph->dir + 3 * i);
        double lum = luminance(ph->power + 3 * i);
        w[(size_t)g->slot[h] * PM_GUIDE_BINS + b] += lum;
        wh[(2 * (size_t)g->slot[h] + (i & 1u)) * PM_GUIDE_BINS + b] += lum;
    }
    for (uint64_t ci = 0; ci < ncells; ci++) {
        pm_guide_cell_t *c = &g->cells[ci];
        const double *wc = w + ci * PM_GUIDE_BINS;
        double total = 0.0, run = 0.0;
        for (int b = 0; b < PM_GUIDE_BINS; b++)
            total += wc[b];
        for (int b = 0; b < PM_GUIDE_BINS; b++) {
            run += wc[b];
            c->pdf[b] = (float)(wc[b] / total);
            c->cdf[b] = (float)(run / total);
        }
        c->cdf[PM_GUIDE_BINS - 1] = 1.0f;
    }
    /* every cell (all), or the ones that help: the test runs only when its answer is used */
    uint64_t even = 0;
    if (all)
        for (uint64_t ci = 0; ci < ncells; ci++)
            g->cells[ci].used = 1;
    else
        even = keep_helpful(g, ph, wh, axis, ncells);
    free(count);
    free(w);
    free(axis);
    if (even == UINT64_MAX) {
        pm_guide_destroy(g);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the moments of %llu guide cells",
                            (unsigned long long)ncells);
    }
    g->info.cells = ncells - even;
    g->info.cells_even = even;
    g->info.cells_sparse = sparse;
    *out = g;
    return PM_OK;
}

void pm_guide_destroy(pm_guide_t *g)
{
    if (!g)
        return;
    free(g->keys);
    free(g->slot);
    free(g->cells);
    free(g);
}

const pm_guide_info_t *pm_guide_info(const pm_guide_t *g) { return &g->info; }

const pm_guide_cell_t *pm_guide_find(const pm_guide_t *g, const float p[3], const float n[3])
{
    if (!g->info.cells)
        return NULL;
    uint64_t key = cell_key(g->lo, g->inv_edge, p, n);
    if (key == EMPTY)
        return NULL;
    int added = 0;
    uint64_t h = table_find(g->keys, g->mask, key, 0, &added);
    if (g->keys[h] != key || g->slot[h] == UINT32_MAX || !g->cells[g->slot[h]].used)
        return NULL;
    return &g->cells[g->slot[h]];
}

void pm_guide_sample(const pm_guide_cell_t *c, float u1, float u2, float wi[3])
{
    /* the first bin whose running sum passes u1 (never an empty one: its sum equals the last) */
    unsigned lo = 0, hi = PM_GUIDE_BINS - 1;
    while (lo < hi) {
        unsigned mid = (lo + hi) / 2;
        if (u1 < c->cdf[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    float below = lo ? c->cdf[lo - 1] : 0.0f, width = c->cdf[lo] - below,
          r = width > 0.0f ? (u1 - below) / width : 0.5f;
    r = r < 0.0f ? 0.0f : r < 1.0f ? r : 0x1.fffffep-1f;
    unsigned iz = lo / PM_GUIDE_NPHI, ip = lo % PM_GUIDE_NPHI;
    float y = -1.0f + ((float)iz + r) * (2.0f / PM_GUIDE_NZ);
    float phi = -PM_PI + ((float)ip + u2) * (2.0f * PM_PI / PM_GUIDE_NPHI);
    float s = sqrtf(fmaxf(0.0f, 1.0f - y * y));
    wi[0] = s * cosf(phi), wi[1] = y, wi[2] = s * sinf(phi);
}

float pm_guide_pdf(const pm_guide_cell_t *c, const float wi[3])
{
    return c->pdf[pm_guide_bin(wi)] * (PM_GUIDE_BINS / (4.0f * PM_PI));
}
