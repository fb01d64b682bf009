/* trace-gather-points: the eye side of the final gather (the paper, sections 5.1 and 6.1).
 *
 * Reads a scene; casts one primary ray per pixel (or --primary jittered ones) as Embree
 * packets; at each primary hit adds emission seen directly and direct light (shadow rays to
 * point lights and to sampled points of emissive triangles) into a direct radiance buffer
 * (--direct, component=direct); and spawns --spp cosine-weighted secondary rays, stratified
 * with four samples per cell so that groups of four share origin and direction, also traced
 * as packets. Each secondary hit becomes one gather point (a query) in the queries file
 * (-o), which hilbert-sort reorders and simd-gather answers against the photon map.
 * --mode direct-vis makes the primary hits themselves the queries (the paper's Figure 4,
 * left). docs/programs/trace-gather-points.md and docs/formats.md (queries) give the
 * weight contract.
 *
 * Rows are the unit of work; rows of a band run in parallel and their records are emitted
 * in pixel order, so the output is the same bytes for any --threads. Records are spooled
 * (memory, then an unlinked temporary file past --spool-mem) because the header's COUNT
 * must be known before the first record is written. */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "base/cpu.h"
#include "base/memory.h"
#include "render/packet.h"
#include "math/rng.h"
#include "render/rt.h"
#include "math/sampling.h"
#include "render/shade.h"
#include "base/stage.h"
#include "math/strata.h"
#include "formats/formats.h"

#define BAND_ROWS 32                      /* rows traced in parallel before their records are emitted */
#define PER_CELL 4                        /* samples per stratum cell: the paper's four */

/* RNG streams: pixel p draws from stream 4p + purpose, so each phase of a pixel is
 * reproducible on its own and no two pixels or phases share numbers. */
enum { STREAM_JITTER = 0, STREAM_LIGHT = 1, STREAM_GATHER = 2 };

enum { MODE_GATHER = 0, MODE_DIRECT_VIS = 1 };
static const char *const mode_names[] = {"gather", "direct-vis", NULL};
enum { SCHED_INTERLEAVE = 0, SCHED_TILES = 1, SCHED_DYNAMIC = 2 };
static const char *const schedule_names[] = {"interleave", "tiles", "dynamic", NULL};

typedef struct {
    const char *direct;    /* --direct FILE, NULL for none */
    int64_t spp;           /* secondary rays per primary hit; 0: the scene's render.spp */
    int64_t primary;       /* primary rays per pixel */
    int64_t light_samples; /* area-light samples per primary hit */
    int64_t width, height; /* image size; 0: the scene camera's */
    int64_t spool_mb;      /* MiB of records held in memory before they spill to a temporary file */
    int mode, schedule;
    const char *isa;
} tgp_options_t;

/* What every worker reads; nothing here changes while rows are traced. */
typedef struct {
    const pm_scene_t *s;
    const pm_rt_t *rt;
    pm_shade_geom_t geom;  /* front normals (the emitting side) and area lights */
    float *fold;           /* per material: kd/pi when Lambertian, 1 1 1 when glossy (the weight contract) */
    uint32_t w, h;
    unsigned spp, primary, light_samples, nx, ny;
    int mode, width, has_mat, has_dir;
    uint32_t record_size, off_mat, off_dir;
    uint64_t seed;
    float eps;             /* m, ray-origin offset along the normal */
    pm_camera_rays_t cam;
} tgp_ctx_t;

/* A worker's scratch, reused row after row. Cache-line aligned, like bytebuf_t: each is
 * written on every ray by one thread, and neighbours sharing a line made two threads slower
 * than one on the atrium. */
typedef struct {
    _Alignas(64) pm_rays_t prim;
    pm_rays_t shadow, sec;
    float *hit;            /* per primary ray: position[3], normal[3] (facing the ray), wo[3] */
    size_t hit_cap;
    uint32_t *sh_px;       /* shadow ray -> pixel column */
    float *sh_c;           /* shadow ray -> RGB radiance it adds when unblocked, W/(m^2 sr) */
    uint32_t *sec_px;      /* secondary ray -> pixel column */
    float *sec_w;          /* secondary ray -> RGB path weight (f cos / pdf / N / primary) */
    float *sec_cos;        /* secondary ray -> cosine at the primary hit (its pdf is cos / pi), for MIS */
    size_t sh_px_cap, sh_c_cap, sec_px_cap, sec_w_cap, sec_cos_cap; /* elements allocated */
    float *u1, *u2;        /* spp stratified points */
    float *lx, *ly, *lz;   /* their cosine-weighted directions in the local frame */
    uint64_t n_primary, n_secondary, n_shadow, n_queries;
    double t_secondary;    /* s inside Embree for secondary rays */
    double cpu_rows;       /* s of this thread's CPU time in trace_row: immune to other processes' load */
} tgp_scratch_t;

typedef struct {
    _Alignas(64) unsigned char *p;
    size_t n, cap;         /* bytes */
    uint64_t count;        /* records */
} bytebuf_t;

/* ------------------------------------------------------------------ spool */

typedef struct {
    unsigned char **chunk; /* records in memory, chunk_bytes each (whole records), the last one filling */
    size_t nchunks, chunk_cap, fill, chunk_bytes;
    size_t held;           /* bytes in memory */
    size_t mem_max;        /* bytes held in memory before spilling */
    FILE *f;               /* spilled records, NULL while they fit in memory */
    const char *dir;       /* where a spill file goes */
    uint64_t count;
} spool_t;

static pm_result_t spool_spill(spool_t *sp)
{
    int fd = open(sp->dir, O_TMPFILE | O_RDWR, 0600);
    if (fd >= 0)
        sp->f = fdopen(fd, "w+b");
    else
        sp->f = tmpfile();
    if (!sp->f)
        return pm_error_set(PM_ERR_IO, "cannot create a spool file in '%s': %s", sp->dir, strerror(errno));
    for (size_t i = 0; i < sp->nchunks; i++) {
        size_t n = i + 1 < sp->nchunks ? sp->chunk_bytes : sp->fill;
        if (n && fwrite(sp->chunk[i], 1, n, sp->f) != n)
            return pm_error_set(PM_ERR_IO, "cannot write the spool file: %s", strerror(errno));
        pm_free_aligned(sp->chunk[i]);
    }
    sp->nchunks = sp->fill = sp->held = 0;
    return PM_OK;
}

static pm_result_t spool_add(spool_t *sp, const bytebuf_t *b)
{
    sp->count += b->count;
    if (!sp->f && sp->held + b->n > sp->mem_max) {
        pm_result_t r = spool_spill(sp);
        if (r != PM_OK)
            return r;
    }
    if (sp->f) {
        if (b->n && fwrite(b->p, 1, b->n, sp->f) != b->n)
            return pm_error_set(PM_ERR_IO, "cannot write the spool file: %s", strerror(errno));
        return PM_OK;
    }
    /* Fixed chunks rather than one realloc'd block: no copying of what is already held. */
    for (size_t at = 0; at < b->n;) {
        if (sp->nchunks == 0 || sp->fill == sp->chunk_bytes) {
            if (sp->nchunks == sp->chunk_cap) {
                size_t cap = sp->chunk_cap ? 2 * sp->chunk_cap : 64;
                unsigned char **p = realloc(sp->chunk, cap * sizeof *p);
                if (!p)
                    return pm_error_set(PM_ERR_NOMEM, "out of memory for the query spool");
                sp->chunk = p, sp->chunk_cap = cap;
            }
            if (!(sp->chunk[sp->nchunks] = pm_alloc_aligned(sp->chunk_bytes)))
                return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu bytes of queries", sp->held + sp->chunk_bytes);
            sp->nchunks++;
            sp->fill = 0;
        }
        size_t n = b->n - at < sp->chunk_bytes - sp->fill ? b->n - at : sp->chunk_bytes - sp->fill;
        memcpy(sp->chunk[sp->nchunks - 1] + sp->fill, b->p + at, n);
        sp->fill += n, sp->held += n, at += n;
    }
    return PM_OK;
}

static pm_result_t spool_replay(spool_t *sp, pm_writer_t *w, uint32_t record_size)
{
    pm_result_t r = PM_OK;
    if (!sp->f) {
        for (size_t i = 0; i < sp->nchunks && r == PM_OK; i++)
            r = pm_writer_write(w, sp->chunk[i], (i + 1 < sp->nchunks ? sp->chunk_bytes : sp->fill) / record_size);
        return r;
    }
    if (fflush(sp->f) != 0 || fseek(sp->f, 0, SEEK_SET) != 0)
        return pm_error_set(PM_ERR_IO, "cannot rewind the spool file: %s", strerror(errno));
    const uint64_t chunk = 65536;
    unsigned char *buf = malloc(chunk * record_size);
    if (!buf)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    for (uint64_t at = 0; at < sp->count && r == PM_OK; at += chunk) {
        uint64_t n = sp->count - at < chunk ? sp->count - at : chunk;
        if (fread(buf, record_size, n, sp->f) != n)
            r = pm_error_set(PM_ERR_IO, "cannot read the spool file back: %s", ferror(sp->f) ? strerror(errno) : "short");
        else
            r = pm_writer_write(w, buf, n);
    }
    free(buf);
    return r;
}

static void spool_free(spool_t *sp)
{
    for (size_t i = 0; i < sp->nchunks; i++)
        pm_free_aligned(sp->chunk[i]);
    free(sp->chunk);
    if (sp->f)
        fclose(sp->f);
    memset(sp, 0, sizeof *sp);
}

/* ------------------------------------------------------------------ shading */

static inline float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static int grow(void **p, size_t elem, size_t *cap, size_t want)
{
    if (want <= *cap)
        return 1;
    size_t c = *cap ? *cap : 256;
    while (c < want)
        c *= 2;
    void *q = realloc(*p, c * elem);
    if (!q)
        return 0;
    *p = q;
    *cap = c;
    return 1;
}

static pm_result_t scratch_reserve(tgp_scratch_t *sc, size_t nprim, size_t nshadow, size_t nsec, unsigned spp)
{
    if (pm_rays_reserve(&sc->prim, nprim) != PM_OK || pm_rays_reserve(&sc->shadow, nshadow) != PM_OK ||
        pm_rays_reserve(&sc->sec, nsec) != PM_OK || !grow((void **)&sc->hit, 9 * sizeof(float), &sc->hit_cap, nprim) ||
        !grow((void **)&sc->sh_px, sizeof(uint32_t), &sc->sh_px_cap, nshadow) ||
        !grow((void **)&sc->sh_c, 3 * sizeof(float), &sc->sh_c_cap, nshadow) ||
        !grow((void **)&sc->sec_px, sizeof(uint32_t), &sc->sec_px_cap, nsec) ||
        !grow((void **)&sc->sec_w, 3 * sizeof(float), &sc->sec_w_cap, nsec) ||
        !grow((void **)&sc->sec_cos, sizeof(float), &sc->sec_cos_cap, nsec))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a row of %zu rays", nprim + nshadow + nsec);
    if (!sc->u1 && spp) {
        sc->u1 = malloc(spp * sizeof(float));
        sc->u2 = malloc(spp * sizeof(float));
        sc->lx = malloc(spp * sizeof(float));
        sc->ly = malloc(spp * sizeof(float));
        sc->lz = malloc(spp * sizeof(float));
        if (!sc->u1 || !sc->u2 || !sc->lx || !sc->ly || !sc->lz)
            return pm_error_set(PM_ERR_NOMEM, "out of memory");
    }
    return PM_OK;
}

static void scratch_free(tgp_scratch_t *sc)
{
    pm_rays_free(&sc->prim), pm_rays_free(&sc->shadow), pm_rays_free(&sc->sec);
    free(sc->hit), free(sc->sh_px), free(sc->sh_c), free(sc->sec_px), free(sc->sec_w), free(sc->sec_cos), free(sc->u1), free(sc->u2);
    free(sc->lx), free(sc->ly), free(sc->lz);
}

/* Appends one query record in file layout. */
static inline int put_query(const tgp_ctx_t *c, bytebuf_t *out, const float p[3], const float n[3], const float w[3],
                     uint32_t pixel, uint32_t mat, const float wo[3])
{
    if (out->n + c->record_size > out->cap && !grow((void **)&out->p, 1, &out->cap, out->n + c->record_size))
        return 0;
    unsigned char *r = out->p + out->n;
    memcpy(r, p, 12);
    memcpy(r + 12, n, 12);
    memcpy(r + 24, w, 12);
    memcpy(r + 36, &pixel, 4);
    if (c->has_mat) {
        uint16_t m16 = (uint16_t)mat;
        memcpy(r + c->off_mat, &m16, 2);
    }
    if (c->has_dir)
        memcpy(r + c->off_dir, wo, 12);
    out->n += c->record_size;
    out->count++;
    return 1;
}

/* The query's weight from the path weight w: a Lambertian query surface has its BRDF kd/pi
 * folded in, a glossy one keeps f for the gather (docs/formats.md, queries). */
static inline int query_weight(const pm_material_t *m, const float w[3], float out[3])
{
    int glossy = pm_material_is_glossy(m);
    for (int k = 0; k < 3; k++)
        out[k] = glossy ? w[k] : w[k] * m->kd[k] * (1.0f / PM_PI);
    return out[0] > 0.0f || out[1] > 0.0f || out[2] > 0.0f;
}


/* Direct light and spawned rays of primary ray i (pixel column x); 0 when out of memory. */
static int shade_primary(const tgp_ctx_t *c, tgp_scratch_t *sc, size_t i, uint32_t x, uint32_t pixel,
                          pm_rng_t *light_rng, pm_rng_t *gather_rng, double *direct, bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    const pm_rays_t *pr = &sc->prim;
    uint32_t tri = pr->prim[i];
    float inv_p = 1.0f / (float)c->primary;
    float d[3] = {pr->dx[i], pr->dy[i], pr->dz[i]}, t = pr->tfar[i];
    float *p = sc->hit + 9 * i, *n = p + 3, *wo = p + 6;
    const float *ng = c->geom.tri_n + 3 * (size_t)tri;
    for (int k = 0; k < 3; k++) {
        p[k] = (k == 0 ? pr->ox[i] : k == 1 ? pr->oy[i] : pr->oz[i]) + t * d[k];
        wo[k] = -d[k];
    }
    float side = dot3(ng, wo) >= 0.0f ? 1.0f : -1.0f; /* both sides reflect: face the viewer */
    for (int k = 0; k < 3; k++)
        n[k] = side * ng[k];
    const pm_material_t *m = &s->materials[s->tri_material[tri]];
    float o[3];
    for (int k = 0; k < 3; k++)
        o[k] = p[k] + c->eps * n[k];

    /* Emission seen directly: emitters radiate from their front side only. */
    if (side > 0.0f && pm_material_is_emissive(m))
        for (int k = 0; k < 3; k++)
            direct[3 * x + k] += (double)(m->ke[k] * inv_p);

    int reflects = m->kd[0] > 0.0f || m->kd[1] > 0.0f || m->kd[2] > 0.0f || pm_material_is_glossy(m);
    if (!reflects)
        return 1; /* black: reflects no light, direct or gathered */

    /* Point lights: intensity I (W/sr) at distance r gives irradiance I cos / r^2. */
    pm_light_sample_t ls;
    for (size_t l = 0; l < s->nlights; l++) {
        const pm_point_light_t *L = &s->lights[l];
        if (!pm_point_light_toward(L, p, n, &ls))
            continue;
        float f[3];
        pm_brdf(m, n, ls.wi, wo, f);
        size_t j = sc->shadow.n;
        for (int k = 0; k < 3; k++)
            sc->sh_c[3 * j + k] = f[k] * L->intensity[k] * ls.cosx / ls.r2 * inv_p;
        sc->sh_px[j] = x;
        pm_rays_push(&sc->shadow, o, ls.wi, 0.0f, ls.r - c->eps);
    }
    /* Area lights: points uniform over the total emissive area A, pdf 1/A per m^2;
     * L = f Ke cos_x cos_y / r^2 * A, averaged over the samples. */
    for (unsigned q = 0; q < c->light_samples && s->nemissive; q++) {
        if (!pm_area_light_sample(s, &c->geom, light_rng, p, n, &ls))
            continue;
        const pm_material_t *lm = &s->materials[s->tri_material[ls.tri]];
        float f[3], g = ls.cosx * ls.cosy / ls.r2 * (float)c->geom.area / (float)c->light_samples * inv_p;
        /* MIS of area lights (pm_power_heuristic, common/render/shade.h): a and b are sample counts times
         * solid-angle pdfs at one direction. Light samples and the secondary rays both find area
         * lights in gather mode. Any weights that sum to one at every direction keep the estimate unbiased; the counts
         * only tune the variance. The secondary rays count as spp / PER_CELL, their stratum cells (the
         * four rays of a cell land close together), not spp: measured on the direct buffer against
         * trace-reference (relative MSE, 128 x 128), counting every ray hands the weight to the rays on
         * the Cornell box, which find its small light far less often than the light samples do (256 spp:
         * 0.0049 by rays, 0.0026 by cells, 0.0029 with no rays counted), and counting none loses on the
         * atrium's large sky (64 spp: 0.033 none, 0.014 cells, 0.011 rays). Without the rays, light
         * samples have unbounded variance next to a light (the 1/r^2 of a sample landing beside the
         * receiver): the atrium's walls touch its sky, and its direct buffer read 2.58. */
        if (c->mode == MODE_GATHER) /* shared with the secondary rays that find the light (MIS) */
            g *= pm_power_heuristic((float)c->light_samples * ls.r2 / (ls.cosy * (float)c->geom.area),
                            (float)(c->spp / PER_CELL) * ls.cosx * (1.0f / PM_PI));
        pm_brdf(m, n, ls.wi, wo, f);
        size_t j = sc->shadow.n;
        for (int k = 0; k < 3; k++)
            sc->sh_c[3 * j + k] = f[k] * lm->ke[k] * g;
        sc->sh_px[j] = x;
        /* Stop short of the light's own surface, by the offset and a relative margin. */
        pm_rays_push(&sc->shadow, o, ls.wi, 0.0f, ls.r * (1.0f - 1e-4f) - 2.0f * c->eps);
    }

    if (c->mode == MODE_DIRECT_VIS) {
        /* The primary hit is the query: path weight 1 (over the primary rays of the pixel). */
        float w[3] = {inv_p, inv_p, inv_p}, qw[3];
        if (query_weight(m, w, qw)) {
            if (!put_query(c, out, p, n, qw, pixel, s->tri_material[tri], wo))
                return 0;
            sc->n_queries++;
        }
        return 1;
    }

    /* Secondary rays: cosine-weighted (pdf cos/pi), so f cos / pdf = pi f, over N. */
    float tb[3], bb[3];
    {
        pm_vec3_t tv, bv;
        pm_onb(pm_v3_load(n), &tv, &bv);
        pm_v3_store(tb, tv), pm_v3_store(bb, bv);
    }
    pm_strata_fill(gather_rng, c->nx, c->ny, PER_CELL, sc->u1, sc->u2);
    pm_strata_cosine(sc->u1, sc->u2, c->spp, sc->lx, sc->ly, sc->lz);
    int glossy = pm_material_is_glossy(m);
    float scale = inv_p / (float)c->spp;
    if (!glossy) {
        /* Lambertian: (kd/pi) cos / (cos/pi) = kd for every ray; kd > 0 here. Whole
         * arrays at once, in SIMD lanes. */
        pm_rays_t *sr = &sc->sec;
        size_t j0 = sr->n;
        unsigned nq = c->spp;
        float *dx = sr->dx + j0, *dy = sr->dy + j0, *dz = sr->dz + j0, *ox = sr->ox + j0, *oy = sr->oy + j0,
              *oz = sr->oz + j0, *tn = sr->tnear + j0, *tf = sr->tfar + j0;
        const float *lx = sc->lx, *ly = sc->ly, *lz = sc->lz;
#pragma omp simd
        for (unsigned q = 0; q < nq; q++) {
            dx[q] = lx[q] * tb[0] + ly[q] * bb[0] + lz[q] * n[0];
            dy[q] = lx[q] * tb[1] + ly[q] * bb[1] + lz[q] * n[1];
            dz[q] = lx[q] * tb[2] + ly[q] * bb[2] + lz[q] * n[2];
            ox[q] = o[0], oy[q] = o[1], oz[q] = o[2];
            tn[q] = 0.0f, tf[q] = INFINITY;
        }
        float w0 = m->kd[0] * scale, w1 = m->kd[1] * scale, w2 = m->kd[2] * scale, *w = sc->sec_w + 3 * j0;
        uint32_t *px = sc->sec_px + j0;
        memcpy(sc->sec_cos + j0, lz, nq * sizeof *lz);
        for (unsigned q = 0; q < nq; q++) {
            w[3 * q] = w0, w[3 * q + 1] = w1, w[3 * q + 2] = w2;
            px[q] = x;
        }
        sr->n += nq;
        return 1;
    }
    for (unsigned q = 0; q < c->spp; q++) {
        float wi[3];
        for (int k = 0; k < 3; k++)
            wi[k] = sc->lx[q] * tb[k] + sc->ly[q] * bb[k] + sc->lz[q] * n[k];
        size_t j = sc->sec.n;
        float *w = sc->sec_w + 3 * j, f[3];
        pm_brdf(m, n, wi, wo, f); /* glossy: weight pi f / N per ray */
        for (int k = 0; k < 3; k++)
            w[k] = f[k] * PM_PI * scale;
        if (!(w[0] > 0.0f || w[1] > 0.0f || w[2] > 0.0f))
            continue; /* carries nothing: not traced */
        sc->sec_px[j] = x;
        sc->sec_cos[j] = sc->lz[q];
        pm_rays_push(&sc->sec, o, wi, 0.0f, INFINITY);
    }
    return 1;
}

/* Traces row y: direct radiance into direct[0 .. 3w), queries appended to out in pixel order. */
static double thread_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static pm_result_t trace_row_body(const tgp_ctx_t *c, tgp_scratch_t *sc, uint32_t y, double *direct, bytebuf_t *out);

static pm_result_t trace_row(const tgp_ctx_t *c, tgp_scratch_t *sc, uint32_t y, double *direct, bytebuf_t *out)
{
    double t0 = thread_cpu();
    pm_result_t r = trace_row_body(c, sc, y, direct, out);
    sc->cpu_rows += thread_cpu() - t0;
    return r;
}

static pm_result_t trace_row_body(const tgp_ctx_t *c, tgp_scratch_t *sc, uint32_t y, double *direct, bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    size_t np = (size_t)c->w * c->primary;
    size_t nshadow = np * (s->nlights + (s->nemissive ? c->light_samples : 0));
    size_t nsec = c->mode == MODE_GATHER ? np * c->spp : 0;
    pm_result_t r = scratch_reserve(sc, np, nshadow, nsec, c->mode == MODE_GATHER ? c->spp : 0);
    if (r != PM_OK)
        return r;
    memset(direct, 0, 3 * sizeof(double) * c->w);
    out->n = 0;
    out->count = 0;

    /* Primary rays, pixel by pixel along the row: coherent packets. */
    sc->prim.n = 0;
    for (uint32_t x = 0; x < c->w; x++) {
        uint64_t pixel = (uint64_t)y * c->w + x;
        pm_rng_t jr;
        pm_rng_init(&jr, c->seed, 4 * pixel + STREAM_JITTER);
        for (unsigned j = 0; j < c->primary; j++) {
            float jx = 0.5f, jy = 0.5f, d[3];
            if (c->primary > 1)
                jx = pm_rng_float(&jr), jy = pm_rng_float(&jr);
            pm_camera_dir(&c->cam, (float)x + jx, (float)y + jy, d);
            pm_rays_push(&sc->prim, c->cam.eye, d, 0.0f, INFINITY);
        }
    }
    pm_rays_intersect(c->rt, c->width, 1, &sc->prim);
    sc->n_primary += np;

    sc->shadow.n = 0;
    sc->sec.n = 0;
    pm_rng_t light_rng, gather_rng;
    pm_rng_init(&light_rng, c->seed, 0); /* re-keyed per pixel below */
    pm_rng_init(&gather_rng, c->seed, 0);
    for (size_t i = 0; i < np; i++) {
        uint32_t x = (uint32_t)(i / c->primary);
        uint32_t pixel = y * c->w + x;
        if (i % c->primary == 0) {
            pm_rng_init(&light_rng, c->seed, 4 * (uint64_t)pixel + STREAM_LIGHT);
            pm_rng_init(&gather_rng, c->seed, 4 * (uint64_t)pixel + STREAM_GATHER);
        }
        if (sc->prim.prim[i] == PM_RAY_MISS)
            continue; /* sky: no query, no direct light */
        if (!shade_primary(c, sc, i, x, pixel, &light_rng, &gather_rng, direct, out))
            return pm_error_set(PM_ERR_NOMEM, "out of memory for the queries of row %" PRIu32, y);
    }

    /* Shadow rays; each unblocked one adds its radiance, in ray (so pixel) order. */
    pm_rays_occluded(c->rt, c->width, 0, &sc->shadow);
    sc->n_shadow += sc->shadow.n;
    for (size_t j = 0; j < sc->shadow.n; j++)
        if (sc->shadow.tfar[j] >= 0.0f)
            for (int k = 0; k < 3; k++)
                direct[3 * sc->sh_px[j] + k] += (double)sc->sh_c[3 * j + k];

    if (c->mode != MODE_GATHER)
        return PM_OK;
    /* Secondary rays: consecutive rays share a cell or a pixel, so packets stay coherent. */
    double t0 = pm_time_wall();
    pm_rays_intersect(c->rt, c->width, 0, &sc->sec);
    sc->t_secondary += pm_time_wall() - t0;
    sc->n_secondary += sc->sec.n;
    const pm_rays_t *sr = &sc->sec;
    /* Room for every ray's record up front: the loop below then only stores. */
    if (!grow((void **)&out->p, 1, &out->cap, out->n + sr->n * c->record_size))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the queries of row %" PRIu32, y);
    for (size_t j = 0; j < sr->n; j++) {
        uint32_t tri = sr->prim[j];
        if (tri == PM_RAY_MISS)
            continue; /* escaped: no query */
        float d[3] = {sr->dx[j], sr->dy[j], sr->dz[j]}, t = sr->tfar[j];
        float q[3] = {sr->ox[j] + t * d[0], sr->oy[j] + t * d[1], sr->oz[j] + t * d[2]};
        float wo[3] = {-d[0], -d[1], -d[2]}, n[3];
        const float *ng = c->geom.tri_n + 3 * (size_t)tri;
        float side = dot3(ng, wo) >= 0.0f ? 1.0f : -1.0f; /* the side the query sees */
        for (int k = 0; k < 3; k++)
            n[k] = side * ng[k];
        uint32_t mi = s->tri_material[tri];
        const float *fold = c->fold + 3 * (size_t)mi, *rw = sc->sec_w + 3 * j;
        /* An emitter's front seen by a secondary ray: direct light of the primary hit, weighted
         * against the light samples that could have found the same point (MIS, power heuristic). */
        if (side > 0.0f && pm_material_is_emissive(&s->materials[mi])) {
            const float *ke = s->materials[mi].ke, cosy = dot3(ng, wo);
            float wb = pm_power_heuristic((float)(c->spp / PER_CELL) * sc->sec_cos[j] * (1.0f / PM_PI),
                                  (float)c->light_samples * t * t / (cosy * (float)c->geom.area));
            for (int k = 0; k < 3; k++)
                direct[3 * sc->sec_px[j] + (uint32_t)k] += (double)(rw[k] * ke[k] * wb);
        }
        float w[3] = {rw[0] * fold[0], rw[1] * fold[1], rw[2] * fold[2]};
        if (!(w[0] > 0.0f || w[1] > 0.0f || w[2] > 0.0f))
            continue; /* a black query surface */
        put_query(c, out, q, n, w, y * c->w + sc->sec_px[j], mi, wo); /* room reserved above */
        sc->n_queries++;
    }
    return PM_OK;
}

/* ------------------------------------------------------------------ setup */

static pm_result_t setup(tgp_ctx_t *c, const pm_scene_t *s, const pm_rt_t *rt, const tgp_options_t *o,
                         const pm_stage_t *st, pm_isa_t isa)
{
    memset(c, 0, sizeof *c);
    c->s = s, c->rt = rt;
    c->w = o->width ? (uint32_t)o->width : s->camera.width;
    c->h = o->height ? (uint32_t)o->height : s->camera.height;
    c->mode = o->mode;
    c->primary = (unsigned)o->primary;
    c->light_samples = (unsigned)o->light_samples;
    c->seed = (uint64_t)st->seed;
    c->eps = rt->epsilon;
    c->width = pm_packet_width(rt, isa);
    if (c->mode == MODE_GATHER) {
        int64_t spp = o->spp ? o->spp : s->defaults.spp;
        if (spp <= 0 || spp % PER_CELL != 0 || spp > 65536)
            return pm_error_set(o->spp ? PM_ERR_USAGE : PM_ERR_INPUT,
                                "%s%s%s %" PRId64 " is not a positive multiple of %d up to 65536 (%d samples per stratum cell)",
                                o->spp ? "--spp" : "scene '", o->spp ? "" : s->path, o->spp ? "" : "': render.spp", spp,
                                PER_CELL, PER_CELL);
        c->spp = (unsigned)spp;
        pm_strata_grid(c->spp / PER_CELL, &c->nx, &c->ny);
    }
    /* Channels: leave out what the scene does not need (docs/formats.md). */
    c->has_dir = s->any_glossy;
    c->has_mat = s->any_glossy && s->nmaterials > 1;
    uint32_t mask = pm_schema_required(&pm_queries_schema) | (c->has_mat ? 1u << PM_QUERY_MATERIAL : 0) |
                    (c->has_dir ? 1u << PM_QUERY_DIRECTION : 0);
    c->record_size = pm_schema_record_size(&pm_queries_schema, mask);
    c->off_mat = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_MATERIAL);
    c->off_dir = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_DIRECTION);

    pm_camera_setup(&s->camera, c->w, c->h, &c->cam);

    c->fold = malloc((s->nmaterials ? s->nmaterials : 1) * 3 * sizeof(float));
    if (!c->fold)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    for (size_t m = 0; m < s->nmaterials; m++) {
        float one[3] = {1.0f, 1.0f, 1.0f};
        query_weight(&s->materials[m], one, c->fold + 3 * m);
    }
    return pm_shade_geom_init(s, &c->geom);
}

/* Provenance and format keys shared by both outputs. */
static pm_result_t header_common(pm_header_t *h, const pm_stage_t *st, const tgp_ctx_t *c, const pm_scene_t *s)
{
    pm_result_t r = pm_image_header_begin(h, st->argc, st->argv, s, c->w, c->h);
    if (r == PM_OK)
        r = pm_header_set(h, "mode", "%s", mode_names[c->mode]);
    if (r == PM_OK && c->mode == MODE_GATHER)
        r = pm_header_set(h, "spp", "%u", c->spp);
    if (r == PM_OK)
        r = pm_header_set(h, "primary", "%u", c->primary);
    if (r == PM_OK)
        r = pm_header_set(h, "seed", "%" PRIu64, c->seed);
    return r;
}

/* A writable output path is checked before minutes of tracing, not after. */
static pm_result_t check_writable(const char *path)
{
    if (!path || strcmp(path, "-") == 0)
        return PM_OK;
    pm_atomic_t a;
    pm_result_t r = pm_atomic_open(path, &a);
    if (r == PM_OK)
        pm_atomic_abort(&a);
    return r;
}

static pm_result_t run(pm_stage_t *st, const tgp_options_t *o, const pm_scene_t *s, const pm_rt_t *rt, pm_isa_t isa)
{
    tgp_ctx_t c;
    pm_result_t r = setup(&c, s, rt, o, st, isa);
    int nthreads = st->threads_used > 0 ? st->threads_used : 1;
    tgp_scratch_t *scr = aligned_alloc(64, (size_t)nthreads * sizeof *scr);
    if (scr)
        memset(scr, 0, (size_t)nthreads * sizeof *scr);
    bytebuf_t rows[BAND_ROWS];
    pm_result_t row_r[BAND_ROWS];
    memset(rows, 0, sizeof rows);
    double *direct = malloc((size_t)c.w * c.h * 3 * sizeof(double));
    spool_t sp = {0};
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", strcmp(st->output, "-") ? st->output : (getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp"));
    if (strcmp(st->output, "-")) {
        char *slash = strrchr(dir, '/');
        if (slash)
            slash[slash == dir ? 1 : 0] = '\0';
        else
            strcpy(dir, ".");
    }
    sp.dir = dir;
    sp.mem_max = (size_t)o->spool_mb << 20;
    sp.chunk_bytes = (size_t)c.record_size << 17; /* whole records, >= 4 MiB: huge pages (common/base/memory.h) */
    if (r == PM_OK && (!scr || !direct))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " direct buffer", c.w, c.h);

    pm_progress_t prog;
    pm_progress_begin(&prog, "rows", c.h, pm_stage_progress(st));
    double t0 = pm_time_wall(), t_spool = 0.0;
    for (uint32_t y0 = 0; y0 < c.h && r == PM_OK; y0 += BAND_ROWS) {
        int nb = (int)(c.h - y0 < BAND_ROWS ? c.h - y0 : BAND_ROWS);
#pragma omp parallel num_threads(nthreads)
        {
            pm_cpu_set_ftz_daz(); /* per thread: MXCSR is not inherited by OpenMP workers */
            tgp_scratch_t *sc = &scr[omp_get_thread_num()];
            if (o->schedule == SCHED_INTERLEAVE) {
#pragma omp for schedule(static, 1)
                for (int b = 0; b < nb; b++) {
                    row_r[b] = trace_row(&c, sc, y0 + (uint32_t)b, direct + (size_t)(y0 + (uint32_t)b) * c.w * 3, &rows[b]);
                    pm_progress_add(&prog, 1);
                }
            } else if (o->schedule == SCHED_TILES) {
#pragma omp for schedule(static)
                for (int b = 0; b < nb; b++) {
                    row_r[b] = trace_row(&c, sc, y0 + (uint32_t)b, direct + (size_t)(y0 + (uint32_t)b) * c.w * 3, &rows[b]);
                    pm_progress_add(&prog, 1);
                }
            } else {
#pragma omp for schedule(dynamic, 1)
                for (int b = 0; b < nb; b++) {
                    row_r[b] = trace_row(&c, sc, y0 + (uint32_t)b, direct + (size_t)(y0 + (uint32_t)b) * c.w * 3, &rows[b]);
                    pm_progress_add(&prog, 1);
                }
            }
        }
        double t1 = pm_time_wall();
        for (int b = 0; b < nb && r == PM_OK; b++) {
            r = row_r[b];
            if (r == PM_OK)
                r = spool_add(&sp, &rows[b]);
        }
        t_spool += pm_time_wall() - t1;
    }
    /* Ray throughput is measured without the spool's copying, which is output cost. */
    double t_trace = pm_time_wall() - t0 - t_spool;
    pm_progress_end(&prog);

    uint64_t np = 0, nsec = 0, nsh = 0, nq = 0;
    double t_sec = 0.0, cpu_rows = 0.0;
    for (int t = 0; t < nthreads && scr; t++) {
        cpu_rows += scr[t].cpu_rows;
        np += scr[t].n_primary, nsec += scr[t].n_secondary, nsh += scr[t].n_shadow, nq += scr[t].n_queries;
        t_sec += scr[t].t_secondary;
    }
    if (r == PM_OK && nq != sp.count)
        r = pm_error_set(PM_ERR_INTERNAL, "counted %" PRIu64 " queries but spooled %" PRIu64, nq, sp.count);

    /* Outputs: both headers, then records; the queries file is committed first. */
    pm_header_t qh, dh;
    pm_header_init(&qh, &pm_queries_schema);
    pm_header_init(&dh, &pm_radiance_schema);
    pm_writer_t *qw = NULL, *dw = NULL;
    if (r == PM_OK) {
        qh.count = sp.count;
        qh.channels = pm_schema_required(&pm_queries_schema) | (c.has_mat ? 1u << PM_QUERY_MATERIAL : 0) |
                      (c.has_dir ? 1u << PM_QUERY_DIRECTION : 0);
        r = header_common(&qh, st, &c, s);
        if (r == PM_OK && s->any_glossy) {
            r = pm_queries_set_materials(&qh, s->materials, s->nmaterials);
        } else if (r == PM_OK) {
            /* No glossy material: every query has its BRDF in its weight (docs/formats.md). */
            pm_material_t folded = {.name = "folded", .kd = {1, 1, 1}};
            r = pm_queries_set_materials(&qh, &folded, 1);
        }
        if (r == PM_OK)
            r = pm_header_set(&qh, "weights", "lambertian-brdf-folded");
    }
    if (r == PM_OK && o->direct) {
        dh.count = (uint64_t)c.w * c.h;
        dh.channels = pm_schema_required(&pm_radiance_schema);
        r = header_common(&dh, st, &c, s);
        if (r == PM_OK)
            r = pm_header_set(&dh, "component", "direct");
        if (r == PM_OK)
            r = pm_header_set(&dh, "light_samples", "%u", c.light_samples);
    }
    if (r == PM_OK)
        r = pm_writer_open(st->output, &qh, &qw);
    if (r == PM_OK && o->direct)
        r = pm_writer_open(o->direct, &dh, &dw);
    if (r == PM_OK)
        r = spool_replay(&sp, qw, c.record_size);
    if (r == PM_OK && dw)
        r = pm_writer_write(dw, direct, dh.count);
    if (r == PM_OK) {
        r = pm_writer_commit(qw);
        qw = NULL;
    }
    if (r == PM_OK && dw) {
        r = pm_writer_commit(dw);
        dw = NULL;
    }
    pm_writer_abort(qw);
    pm_writer_abort(dw);
    pm_header_free(&qh);
    pm_header_free(&dh);

    if (r == PM_OK) {
        uint64_t rays = np + nsec + nsh;
        pm_stage_stat_string(st, "mode", mode_names[c.mode]);
        pm_stage_stat_string(st, "isa", pm_isa_name(isa));
        pm_stage_stat_int(st, "packet_width", c.width);
        pm_stage_stat_string(st, "schedule", schedule_names[o->schedule]);
        pm_stage_stat_int(st, "width", c.w);
        pm_stage_stat_int(st, "height", c.h);
        pm_stage_stat_int(st, "spp", c.spp);
        pm_stage_stat_int(st, "primary_rays", (int64_t)np);
        pm_stage_stat_int(st, "secondary_rays", (int64_t)nsec);
        pm_stage_stat_int(st, "shadow_rays", (int64_t)nsh);
        pm_stage_stat_int(st, "queries", (int64_t)nq);
        pm_stage_stat_int(st, "spooled_to_file", sp.f != NULL);
        pm_stage_stat_double(st, "trace_s", t_trace);
        pm_stage_stat_double(st, "spool_s", t_spool);
        pm_stage_stat_double(st, "rays_per_s", t_trace > 0 ? (double)rays / t_trace : 0.0);
        pm_stage_stat_double(st, "secondary_rays_per_s", t_trace > 0 ? (double)nsec / t_trace : 0.0);
        pm_stage_stat_double(st, "trace_cpu_s", cpu_rows);
        pm_stage_stat_double(st, "secondary_rays_per_cpu_s", cpu_rows > 0 ? (double)nsec / cpu_rows : 0.0);
        pm_stage_stat_double(st, "secondary_embree_s", t_sec);
        pm_stage_stat_double(st, "secondary_embree_rays_per_core_s", t_sec > 0 ? (double)nsec / t_sec : 0.0);
        st->items = nq;
        pm_stage_note(st, "%" PRIu64 " primary, %" PRIu64 " secondary, %" PRIu64 " shadow rays in %.3f s (%.2f Mrays/s, %s packets of %d); %" PRIu64 " queries",
                      np, nsec, nsh, t_trace, t_trace > 0 ? 1e-6 * (double)rays / t_trace : 0.0, pm_isa_name(isa), c.width, nq);
    }
    for (int t = 0; t < nthreads && scr; t++)
        scratch_free(&scr[t]);
    for (int b = 0; b < BAND_ROWS; b++)
        free(rows[b].p);
    free(scr);
    free(direct);
    pm_shade_geom_free(&c.geom);
    free(c.fold);
    spool_free(&sp);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    tgp_options_t o = {.primary = 1, .light_samples = 4, .isa = "auto", .spool_mb = 256};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"direct", 0, PM_OPT_STRING, &o.direct, "FILE",
         "also write the direct radiance buffer (emission seen directly plus direct light) here", 1, 0, NULL},
        {"mode", 0, PM_OPT_CHOICE, &o.mode, "MODE",
         "gather: queries at secondary hits; direct-vis: the primary hits are the queries", 1, 0, mode_names},
        {"spp", 0, PM_OPT_INT, &o.spp, "N",
         "secondary rays per primary hit, a multiple of 4; 0 takes the scene's render.spp", 0, 65536, NULL},
        {"primary", 0, PM_OPT_INT, &o.primary, "N", "primary rays per pixel; more than 1 are jittered", 1, 4096, NULL},
        {"light-samples", 0, PM_OPT_INT, &o.light_samples, "N", "points sampled on area lights per primary hit", 0,
         65536, NULL},
        {"width", 0, PM_OPT_INT, &o.width, "N", "image width in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"height", 0, PM_OPT_INT, &o.height, "N", "image height in pixels; 0 takes the scene camera's", 0, 65536,
         NULL},
        {"isa", 0, PM_OPT_STRING, &o.isa, "ISA",
         "packet width: auto (widest this cpu and embree run), scalar (single rays), sse4 (4), avx2 (8), avx512 (16)",
         1, 0, NULL},
        {"schedule", 0, PM_OPT_CHOICE, &o.schedule, "HOW",
         "rows to threads: interleave (row i to thread i mod T), tiles (contiguous blocks), dynamic", 1, 0,
         schedule_names},
        {"spool-mem", 0, PM_OPT_INT, &o.spool_mb, "MIB",
         "MiB of query records held in memory; past that they go to a temporary file beside the output", 0, 1 << 20,
         NULL},
        {0},
    };
    const pm_cli_t cli = {"trace-gather-points", "[options] SCENE -o QUERIES [--direct RADIANCE]",
                          "Trace primary and stratified secondary rays as packets; write gather points and direct light.",
                          options, 1, 1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    pm_isa_t isa;
    pm_result_t r = pm_isa_parse(o.isa, &isa);
    if (r != PM_OK)
        return pm_stage_end(&st, r);
    if (o.direct && !strcmp(o.direct, "-") && !strcmp(st.output, "-"))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "-o and --direct cannot both be stdout"));
    if (o.spp % PER_CELL != 0)
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--spp %" PRId64 " is not a multiple of %d (%d samples per stratum cell)",
                                              o.spp, PER_CELL, PER_CELL));
    if ((r = check_writable(st.output)) != PM_OK || (r = check_writable(o.direct)) != PM_OK)
        return pm_stage_end(&st, r);
    pm_scene_t s;
    if ((r = pm_scene_load(st.args.args[0], &s)) != PM_OK)
        return pm_stage_end(&st, r);
    pm_rt_t rt;
    r = pm_rt_create(&s, 1, st.threads_used, &rt);
    if (r == PM_OK)
        r = run(&st, &o, &s, &rt, isa);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    return pm_stage_end(&st, r);
}
