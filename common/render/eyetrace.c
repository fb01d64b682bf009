/* eyetrace.c: the eye tracer behind trace-gather-points (see eyetrace.h): camera rays,
 * shading at the primary hits, direct light with multiple importance sampling, the stratified
 * secondary rays and the query records they leave.
 *
 * Reads a scene and its Embree scene; writes nothing itself: each band of rows is traced in
 * parallel into per-row buffers, then handed to the caller's sink in pixel order. The shading
 * (BRDF, light sampling, MIS weight, camera) is render/shade.h's, shared with trace-reference. */
#include "render/eyetrace.h"

#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "base/progress.h"
#include "base/stage.h"
#include "base/timer.h"
#include "formats/formats.h"
#include "math/rng.h"
#include "math/sampling.h"
#include "math/strata.h"
#include "math/vec.h"
#include "physics/bsdf.h"
#include "render/packet.h"
#include "render/shade.h"

#define BAND_ROWS 32 /* rows traced in parallel before their records go to the sink */
#define PER_CELL PM_EYE_PER_CELL
/* What a Lambertian hit's escaping secondary rays count as in the MIS weights of the sun and the
 * sky they share with its light samples: every ray, spp. (Against emitters they count as their
 * spp / PER_CELL stratum cells; see direct_lights_n.) */
#define ENV_COUNT(c) ((float)(c)->spp)

/* RNG streams: pixel p draws from stream 4p + purpose, so each phase of a pixel is
 * reproducible on its own and no two pixels or phases share numbers. */
enum { STREAM_JITTER = 0, STREAM_LIGHT = 1, STREAM_GATHER = 2, STREAM_SPECULAR = 3 };

/* Eye paths through mirrors and glass: Russian roulette from this specular bounce on, survival
 * the chain's largest channel of energy kept (the product of the weights photons would carry:
 * kr, 1 for a Fresnel reflection, tf; not the radiance's 1/eta^2, which is no loss and would
 * kill paths inside glass for nothing), capped at 1; and a hard stop after PM_EYE_MAX_SPECULAR
 * bounces in a row, whose light is lost (the bias docs/accuracy.md states). */
#define RR_SPECULAR 8

const char *const pm_eye_mode_names[] = {"gather", "direct-vis", NULL};
const char *const pm_eye_schedule_names[] = {"interleave", "tiles", "dynamic", NULL};

/* A row's query records in file layout. Cache-line aligned: each is written by one thread,
 * and neighbours sharing a line would make the threads slow each other down. */
typedef struct {
    _Alignas(64) unsigned char *p;
    size_t n, cap;  /* bytes */
    uint64_t count; /* records */
} bytebuf_t;

/* A worker's scratch, reused row after row. Cache-line aligned like bytebuf_t: each is written
 * on every ray by one thread (false sharing between them costs more than a second thread gains;
 * docs/programs/trace-gather-points.md). */
typedef struct {
    _Alignas(64) pm_rays_t prim;
    pm_rays_t shadow, sec;
    float *hit; /* per primary ray: position[3], normal[3] (facing the ray), wo[3] */
    size_t hit_cap;
    uint32_t *sh_px;  /* shadow ray -> pixel column */
    float *sh_c;      /* shadow ray -> RGB radiance it adds when unblocked, W/(m^2 sr) */
    uint32_t *sec_px; /* secondary ray -> pixel column */
    float *sec_w;     /* secondary ray -> RGB path weight (f cos / pdf / N / primary) */
    float *sec_cos;   /* secondary ray -> pi times its solid-angle pdf (a cosine sample: its cosine), for MIS */
    float *sec_env;   /* secondary ray -> nb pdf and the normal of its start, for the lights at infinity (env_add) */
    size_t sh_px_cap, sh_c_cap, sec_px_cap, sec_w_cap, sec_cos_cap, sec_env_cap; /* elements allocated */
    float *u1, *u2;                                                              /* spp stratified points */
    float *lx, *ly, *lz; /* their cosine-weighted directions in the local frame */
    float *gsel;         /* guided hits: per ray 1 when the guide draws it, 0 when cosine */
    float *thr;          /* per primary ray: RGB throughput of its specular chain (1 1 1 without one) */
    float *emw;          /* per primary ray: the weight of the emission its last ray finds (MIS past a glossy bounce) */
    uint32_t *rx, *rj;   /* per primary ray: its pixel column and its index among the pixel's rays */
    size_t thr_cap, emw_cap, rx_cap, rj_cap;
    /* The pixel's secondary points, stratified over all its primary rays at once (pm_strata_pixel):
     * primary ray j's spp points start at j * spp; blk is the ray being shaded's start, taken by
     * its first secondary directions (a second set at the same ray, past a glossy bounce, draws
     * its own strata), SIZE_MAX when none waits. */
    float *pix_u; /* u1 of the pixel's points, then their u2 from pix_n on */
    uint32_t *pix_perm;
    size_t pix_n, pix_cap, pix_perm_cap, blk;
    /* The same for the light samples of the primary hits: per light that is not a delta, the
     * pixel's rays * light_samples points stratified together (u1 then u2, pix_ln each), dealt
     * to its rays in a random order; lblk is the shaded ray's start in them, taken by its first
     * direct_lights, SIZE_MAX when none waits. */
    float *pix_l;
    size_t pix_ln, pix_l_cap, lblk;
    uint64_t n_primary, n_secondary, n_shadow, n_queries, n_caustic, n_specular, n_specular_cut, n_glossy;
    uint64_t n_guided_hits, n_guided_rays;
    uint32_t row;       /* the row being traced */
    double t_secondary; /* s inside Embree for secondary rays */
    double cpu_rows;    /* s of this thread's CPU time in trace_row */
} scratch_t;

struct pm_eye {
    pm_eye_info_t info;
    const pm_scene_t *s;
    const pm_rt_t *rt;
    pm_shade_geom_t geom; /* front normals (the emitting side) */
    pm_lights_t lights;   /* render/light.h: direct light and the emitters secondary rays find */
    float *fold;          /* per material: kd/pi when Lambertian, 1 1 1 when glossy (the weight contract) */
    /* Glossy materials with a texture (pm_scene_glossy_textured): a hit leaves two records, its
     * diffuse part folded into the weight (material `folded`, kd 1) and its lobe alone (material
     * lobe[mi], kd 0, ks 1, the material's ns) weighted by the textured ks, so that the gathers,
     * which read a material from the header's table, evaluate the texture's albedo. NULL in a
     * scene without such a material: one record per hit, as always. */
    uint32_t *lobe;       /* per material: its lobe-only entry in table, 0 when not split */
    uint32_t folded;      /* the folded entry's index in table */
    pm_material_t *table; /* the queries' material table: the scene's, then folded and the lobes */
    size_t ntable;
    uint32_t w, h;
    unsigned spp, primary, light_samples, nx, ny;
    const uint32_t *counts; /* adaptive passes: each pixel's primary rays (pm_eye_options_t pixel_primary), or NULL */
    int pixel;              /* PM_PIXEL_BOX or PM_PIXEL_CENTER */
    int mode, schedule, width, threads, progress, has_mat, has_dir;
    int specular;            /* the scene has mirrors or glass: eye paths follow them */
    int caustics;            /* also write the caustic queries (the first non-specular hits) */
    int direct_only;         /* pm_eye_options_t's: no queries, secondary rays only for emitters they find */
    unsigned glossy_depth;   /* glossy bounces a secondary path continues through before it gathers */
    unsigned diffuse_depth;  /* Lambertian bounces a secondary path takes before it gathers (0: none) */
    const pm_guide_t *guide; /* photon guide of the Lambertian hits' secondary rays, NULL for none */
    int env_mis;             /* gather mode with a sun or a sky: a Lambertian hit's escaping rays share them */
    int cont;                /* some material continues (continues()): glossy paths are followed */
    int sec_direct;          /* next-event estimation at the gather points too (gather_direct): asked, and lights */
    /* A direct-only run (direct_only) still follows a secondary ray past its hit (to glossy paths
     * or to the gather point's light) when past_hit; it casts secondary rays at all when
     * sec_rays (past_hit, or emitters, a sun or a sky for them to find). Both derived once. */
    int past_hit, sec_rays;
    /* pm_eye_options_t strata_hit 0: the secondary points (gather mode, sec_rays) and the light
     * samples (a light that is not a delta) stratified over each pixel's primary rays */
    int sec_strata, light_strata;
    uint32_t record_size, off_pos, off_nor, off_w, off_pix, off_mat, off_dir; /* bytes */
    uint64_t seed;
    float eps; /* m, ray-origin offset along the normal */
    pm_camera_rays_t cam;
};

/* Primary rays of pixel p: its own in an adaptive pass, else the context's. */
static inline unsigned pixel_rays(const pm_eye_t *c, uint64_t p) { return c->counts ? c->counts[p] : c->primary; }

/* ------------------------------------------------------------------ buffers */

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

static pm_result_t scratch_reserve(scratch_t *sc, uint32_t y, size_t nprim, size_t nshadow, size_t nsec, unsigned spp)
{
    if (pm_rays_reserve(&sc->prim, nprim) != PM_OK || pm_rays_reserve(&sc->shadow, nshadow) != PM_OK ||
        pm_rays_reserve(&sc->sec, nsec) != PM_OK || !grow((void **)&sc->hit, 9 * sizeof(float), &sc->hit_cap, nprim) ||
        !grow((void **)&sc->sh_px, sizeof(uint32_t), &sc->sh_px_cap, nshadow) ||
        !grow((void **)&sc->sh_c, 3 * sizeof(float), &sc->sh_c_cap, nshadow) ||
        !grow((void **)&sc->sec_px, sizeof(uint32_t), &sc->sec_px_cap, nsec) ||
        !grow((void **)&sc->sec_w, 3 * sizeof(float), &sc->sec_w_cap, nsec) ||
        !grow((void **)&sc->sec_cos, sizeof(float), &sc->sec_cos_cap, nsec) ||
        !grow((void **)&sc->sec_env, 4 * sizeof(float), &sc->sec_env_cap, nsec) ||
        !grow((void **)&sc->thr, 3 * sizeof(float), &sc->thr_cap, nprim) ||
        !grow((void **)&sc->emw, sizeof(float), &sc->emw_cap, nprim) ||
        !grow((void **)&sc->rx, sizeof(uint32_t), &sc->rx_cap, nprim) ||
        !grow((void **)&sc->rj, sizeof(uint32_t), &sc->rj_cap, nprim))
        return pm_error_set(PM_ERR_NOMEM,
                            "out of memory for the rays of row %" PRIu32 ": %zu primary, %zu shadow, %zu secondary", y,
                            nprim, nshadow, nsec);
    if (spp) {
        float **a[] = {&sc->u1, &sc->u2, &sc->lx, &sc->ly, &sc->lz, &sc->gsel};
        for (size_t k = 0; k < sizeof a / sizeof a[0]; k++)
            if (!*a[k] && !(*a[k] = malloc(spp * sizeof(float))))
                return pm_error_set(PM_ERR_NOMEM, "out of memory for the directions of row %" PRIu32 ": %u samples", y,
                                    spp);
    }
    return PM_OK;
}

static void scratch_free(scratch_t *sc)
{
    pm_rays_free(&sc->prim), pm_rays_free(&sc->shadow), pm_rays_free(&sc->sec);
    free(sc->hit), free(sc->sh_px), free(sc->sh_c), free(sc->sec_px), free(sc->sec_w), free(sc->sec_cos),
        free(sc->sec_env);
    free(sc->u1), free(sc->u2), free(sc->lx), free(sc->ly), free(sc->lz), free(sc->gsel), free(sc->thr);
    free(sc->emw), free(sc->rx), free(sc->rj), free(sc->pix_u), free(sc->pix_perm), free(sc->pix_l);
}

/* Appends one query record in file layout; 0 when out of memory. */
static inline int put_query(const pm_eye_t *c, bytebuf_t *out, const float p[3], const float n[3], const float w[3],
                            uint32_t pixel, uint32_t mat, const float wo[3])
{
    if (out->n + c->record_size > out->cap && !grow((void **)&out->p, 1, &out->cap, out->n + c->record_size))
        return 0;
    unsigned char *r = out->p + out->n;
    memcpy(r + c->off_pos, p, 12);
    memcpy(r + c->off_nor, n, 12);
    memcpy(r + c->off_w, w, 12);
    memcpy(r + c->off_pix, &pixel, 4);
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

/* ------------------------------------------------------------------ specular chains */

/* Sub-stream k of pixel p's STREAM_SPECULAR: its blocks from k * 2^32 on, so that the chains of
 * the pixel's primary rays (k = 0) and of each of its secondary rays (k = 1 + the ray's index in
 * the pixel) never share numbers. */
static void specular_rng(pm_rng_t *r, uint64_t seed, uint64_t pixel, uint32_t k)
{
    pm_rng_init(r, seed, 4 * pixel + STREAM_SPECULAR);
    r->ctr[1] = k;
}

/* Follows an eye path that hit mirror or glass triangle *tri along unit d from o at distance
 * *t, through every specular bounce (pm_specular_sample with radiance weights), to the first
 * hit on anything else: on return *tri, o, d and *t are that last ray's and its hit (*tri
 * PM_RAY_MISS when the path escaped or ended), and thr has been multiplied by the chain's
 * weights (zeroed when the path ended rather than escaped). u_first, when not negative, is the first bounce's choice
 * between reflection and refraction instead of a fresh number (the primary rays of a pixel stratify it). Single rays:
 * chains are rare and incoherent. */
static void follow_specular(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, pm_rng_t *rng,
                            float u_first, uint32_t *tri, float o[3], float d[3], float *t, float thr[3])
{
    const pm_scene_t *s = c->s;
    float kept[3] = {1.0f, 1.0f, 1.0f}; /* energy the chain has kept, per channel */
    for (unsigned bounce = 0;; bounce++) {
        const pm_material_t *m = &s->materials[s->tri_material[*tri]];
        if (!pm_material_is_specular(m))
            return;
        const float *ng = c->geom.tri_n + 3 * (size_t)*tri;
        float p[3], wo[3], wi[3], wt[3];
        for (int k = 0; k < 3; k++)
            p[k] = o[k] + *t * d[k], wo[k] = -d[k];
        float u = pm_rng_float(rng), v = pm_rng_float(rng);
        if (bounce == 0 && u_first >= 0.0f)
            u = u_first;
        int how = bounce >= PM_EYE_MAX_SPECULAR ? -1 : pm_specular_sample(m, ng, wo, u, 1, wi, wt);
        if (how < 0) {
            sc->n_specular_cut += bounce >= PM_EYE_MAX_SPECULAR;
            *tri = PM_RAY_MISS;
            thr[0] = thr[1] = thr[2] = 0.0f; /* ended, not escaped: no sky seen along d */
            return;
        }
        for (int k = 0; k < 3; k++) {
            thr[k] *= wt[k];
            kept[k] *= how == 1 ? m->tf[k] : wt[k];
        }
        if (bounce >= RR_SPECULAR) {
            float q = fminf(1.0f, fmaxf(kept[0], fmaxf(kept[1], kept[2])));
            if (!(v < q)) {
                *tri = PM_RAY_MISS;
                thr[0] = thr[1] = thr[2] = 0.0f;
                return;
            }
            for (int k = 0; k < 3; k++)
                thr[k] /= q, kept[k] /= q;
        }
        float side = pm_dot3(ng, wi) >= 0.0f ? c->eps : -c->eps;
        for (int k = 0; k < 3; k++)
            o[k] = p[k] + side * ng[k], d[k] = wi[k];
        sc->n_specular++;
        *tri = pm_rt_intersect1(c->rt, ctx, o, d, 0.0f, INFINITY, t, NULL);
        if (*tri == PM_RAY_MISS)
            return;
    }
}

/* ------------------------------------------------------------------ shading */

/* The query's weight from the path weight w: a Lambertian query surface has its BRDF kd/pi
 * folded in, a glossy one keeps f for the gather (docs/formats.md, queries). */
static inline int query_weight(const pm_material_t *m, const float w[3], float out[3])
{
    int glossy = pm_material_is_glossy(m);
    for (int k = 0; k < 3; k++)
        out[k] = glossy ? w[k] : w[k] * m->kd[k] * (1.0f / PM_PI);
    return out[0] > 0.0f || out[1] > 0.0f || out[2] > 0.0f;
}

/* The records of a hit on material mi (m: that material with its textures at p) reached with
 * path weight w: one (query_weight) or, for a glossy textured material (c->lobe), its diffuse
 * part kd/pi folded into the weight and its lobe weighted by the textured ks, whose gathered
 * sum is the textured f's. Returns the records written (0: a black surface), -1 when out of
 * memory. */
static inline int put_hit(const pm_eye_t *c, bytebuf_t *out, const float p[3], const float n[3], const float w[3],
                          uint32_t pixel, uint32_t mi, const pm_material_t *m, const float wo[3])
{
    float qw[3];
    if (!c->lobe || !c->lobe[mi]) {
        if (!query_weight(m, w, qw))
            return 0;
        return put_query(c, out, p, n, qw, pixel, mi, wo) ? 1 : -1;
    }
    int written = 0;
    for (int part = 0; part < 2; part++) {
        for (int k = 0; k < 3; k++)
            qw[k] = part == 0 ? w[k] * m->kd[k] * (1.0f / PM_PI) : w[k] * m->ks[k];
        if (!(qw[0] > 0.0f || qw[1] > 0.0f || qw[2] > 0.0f))
            continue;
        if (!put_query(c, out, p, n, qw, pixel, part == 0 ? c->folded : c->lobe[mi], wo))
            return -1;
        written++;
    }
    return written;
}

/* The fold (query_weight of a unit path weight) of material mi at q on triangle tri, and in *mt
 * the material as the records see it: in a textured scene both come from its textures at q (m,
 * when the caller has looked them up already, else into the caller's textured) and fold_tex;
 * otherwise the untextured ones of c->fold. */
static inline const float *hit_fold(const pm_eye_t *c, uint32_t tri, uint32_t mi, const float q[3],
                                    const pm_material_t *m, pm_material_t *textured, float fold_tex[3],
                                    const pm_material_t **mt)
{
    *mt = &c->s->materials[mi];
    if (!c->s->maps)
        return c->fold + 3 * (size_t)mi;
    static const float one[3] = {1.0f, 1.0f, 1.0f};
    *mt = m ? m : pm_scene_material_at(c->s, tri, q, textured);
    query_weight(*mt, one, fold_tex);
    return fold_tex;
}

/* A query's normal at q on triangle tri: the geometric normal ng turned to the side the query
 * sees (side, +1 or -1), or the shading normal there when the scene has them (render/transport.h). */
static inline void query_normal(const pm_scene_t *s, uint32_t tri, const float q[3], const float ng[3], float side,
                                float n[3])
{
    for (int k = 0; k < 3; k++)
        n[k] = side * ng[k];
    if (s->normals) {
        float gn[3] = {n[0], n[1], n[2]};
        pm_scene_shading_normal(s, tri, q, gn, n);
    }
}

/* A surface point as next-event estimation and the spawned rays see it. */
typedef struct {
    const pm_material_t *m; /* the BSDF there, its textures applied */
    float p[3];             /* the hit point, m */
    float n[3];             /* the shading normal on the viewer's side (gn without vertex normals) */
    float gn[3];            /* the geometric normal on the viewer's side: which side a ray leaves from */
    float o[3];             /* p moved off the surface along gn: where the rays start */
    float wo[3];            /* toward the viewer */
    float bn[3];            /* the normal the BSDF reads (physics/bsdf.h): n, or a dielectric's front normal */
    int shaded;             /* the scene has vertex normals: a direction below gn is never taken */
} surf_t;

/* Whether material m transmits through a non-delta lobe (rough glass): such a surface holds no
 * photons (pm_bsdf_stores_photons), shades with its geometric normal and has its BSDF read the
 * front normal, as trace-reference does. */
static inline int rough_transmits(const pm_material_t *m) { return pm_material_is_glossy(m) && pm_bsdf_transmits(m); }

/* The normals of surface v (v->m, v->p and v->gn set) on triangle tri, seen from side (+1 its
 * front, -1 its back): the shading normal n (gn without vertex normals) and the BSDF's bn. */
static void surf_normals(const pm_scene_t *s, uint32_t tri, float side, surf_t *v)
{
    if (rough_transmits(v->m)) {
        v->shaded = 0;
        for (int k = 0; k < 3; k++)
            v->n[k] = v->gn[k], v->bn[k] = side * v->gn[k];
        return;
    }
    v->shaded = pm_scene_shading_normal(s, tri, v->p, v->gn, v->n);
    memcpy(v->bn, v->n, sizeof v->bn);
}

/* Room for the shadow rays of one more surface point: at most one per delta light and
 * light_samples per other light of the direct list (render/light.h). 0 when out of memory. */
static int shadow_room(const pm_eye_t *c, scratch_t *sc)
{
    const pm_lights_t *lights = &c->lights;
    /* one sample of each light at least: the gather points (gather_direct) and the diffuse
     * bounces take one whatever light_samples is, 0 included */
    size_t ls = c->light_samples > 1 ? c->light_samples : 1;
    size_t want = sc->shadow.n + lights->ndelta + (lights->ndirect - lights->ndelta) * ls;
    return pm_rays_reserve(&sc->shadow, want) == PM_OK &&
           grow((void **)&sc->sh_px, sizeof(uint32_t), &sc->sh_px_cap, want) &&
           grow((void **)&sc->sh_c, 3 * sizeof(float), &sc->sh_c_cap, want);
}

/* The solid-angle pdf of a Lambertian hit's secondary rays at a direction of cosine cosn: cos / pi,
 * or with a guide cell gc the mixture of that and the cell's distribution (spawn_guided). */
static inline float lambert_pdf(const pm_guide_cell_t *gc, float cosn, const float wi[3])
{
    float pc = fmaxf(cosn, 0.0f) * (1.0f / PM_PI);
    return gc ? PM_GUIDE_COSINE * pc + (1.0f - PM_GUIDE_COSINE) * pm_guide_pdf(gc, wi) : pc;
}

/* The guide cell of Lambertian surface v, NULL without a guide or where it has none. */
static inline const pm_guide_cell_t *guide_cell(const pm_eye_t *c, const surf_t *v)
{
    return c->guide && c->mode == PM_EYE_GATHER ? pm_guide_find(c->guide, v->p, v->gn) : NULL;
}

/* Next-event estimation at surface v for pixel column x: a shadow ray per light sample into
 * sc->shadow, with the radiance it adds when unblocked times inv_p and the path weight tp.
 * nb is the number of BSDF samples that can also find an area light from v (the MIS weight's
 * count), nb_inf what they count as against a light at infinity at a Lambertian v; mis 0 gives the light samples weight
 * 1 (no ray leaves v to find a light). ls is the samples per light that is not a delta (direct_lights: the options'
 * light_samples); area 0 keeps only the samples pm_light_at_gather gives the gather point (gather_direct). */
static void direct_lights_n(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float inv_p,
                            const float tp[3], float nb, float nb_inf, int mis, pm_rng_t *light_rng,
                            const pm_guide_cell_t *gc, unsigned ls, int area, size_t lblk)
{
    const pm_lights_t *lights = &c->lights;
    const pm_material_t *m = v->m;
    const float *p = v->p, *n = v->n, *gn = v->gn, *o = v->o, *wo = v->wo, *bn = v->bn;
    int shaded = v->shaded, glossy = pm_material_is_glossy(m);
    /* Each delta light once, every other light ls times, f Li cos / pdf averaged over its
     * samples (render/light.h). */
    for (size_t l = 0; l < lights->ndirect; l++) {
        unsigned nsamples = l < lights->ndelta ? 1 : ls;
        if (!area && lights->direct[l].infinite && !pm_light_at_gather(lights, &lights->direct[l], INFINITY))
            continue; /* a constant sky at a gather point: the map's (rule 2), not even drawn */
        /* the pixel's stratified points of this light (pixel_strata), when the ray has them */
        const float *lu =
            lblk != SIZE_MAX && l >= lights->ndelta ? sc->pix_l + 2 * (l - lights->ndelta) * sc->pix_ln + lblk : NULL;
        for (unsigned q = 0; q < nsamples; q++) {
            pm_light_li_t li;
            float u[2];
            if (lu)
                u[0] = lu[q], u[1] = lu[sc->pix_ln + q];
            if (!pm_lights_sample_li_u(lights, l, light_rng, lu ? u : NULL, p, n, &li) ||
                (shaded && !(pm_dot3(gn, li.wi) > 0.0f)))
                continue; /* behind the shading or the geometric surface */
            if (!area && !pm_light_at_gather(lights, &lights->direct[l], li.r2))
                continue; /* near an area light: the map's */
            float f[3], g = li.cosx / li.pdf / (float)nsamples * inv_p;
            /* MIS (pm_power_heuristic, render/shade.h) of the lights that the BSDF samples from v
             * can find as well: a and b are sample counts times solid-angle pdfs at one
             * direction. Emitters are found by the secondary rays (in gather mode) and by the
             * rays of glossy paths. Lights at infinity (li.infinite) are found only by rays that
             * escape, and share the light with the BSDF samples that escape (env_add): at a glossy
             * surface, whose lobe the cosine-weighted sky samples hardly find (the speckle of a
             * windshield under the sky), and at a Lambertian one in gather mode (c->env_mis),
             * whose spp secondary rays are drawn as the sky's light samples are (cos / pi), or
             * guided: counting the ones that escape takes the speckle of a shadowed floor that
             * sees a sliver of sky out of the direct buffer (docs/accuracy.md, the sky-lit
             * atrium). Any weights that sum to one at every direction keep
             * the estimate unbiased; the counts only tune the variance. The secondary rays count
             * as spp / PER_CELL, their stratum cells (the four rays of a cell land close
             * together), not as spp: counting every ray hands the weight to the rays where a
             * small light is far more often found by the light samples, and counting none leaves
             * a large emitter to light samples alone, whose variance is unbounded next to it (the
             * 1/r^2 of a sample landing beside the receiver). Against the sun and the sky at a
             * Lambertian hit they count as every ray (nb_inf, ENV_COUNT): both sides draw the sky
             * by cos / pi over the pixel's strata, so every sample is worth as much (the sky-lit
             * atrium's direct buffer: relMSE 0.137 by cells, 0.110 by rays). The measurements
             * behind these choices are in docs/programs/trace-gather-points.md. */
            if (mis && !li.delta && (!li.infinite || glossy || (c->env_mis && m->kind == PM_MAT_STANDARD)))
                g *= pm_power_heuristic((float)nsamples * li.pdf,
                                        glossy ? nb * pm_bsdf_pdf(m, bn, li.wi, wo)
                                               : (li.infinite ? nb_inf : nb) * lambert_pdf(gc, li.cosx, li.wi));
            pm_brdf(m, bn, li.wi, wo, f);
            size_t j = sc->shadow.n;
            for (int k = 0; k < 3; k++)
                sc->sh_c[3 * j + k] = f[k] * li.Li[k] * g * tp[k];
            sc->sh_px[j] = x;
            pm_rays_push(&sc->shadow, o, li.wi, 0.0f, pm_light_shadow_tmax(&li, c->eps));
        }
    }
}

static void direct_lights(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float inv_p, const float tp[3],
                          float nb, float nb_inf, int mis, pm_rng_t *light_rng, const pm_guide_cell_t *gc)
{
    size_t lblk = sc->lblk; /* the ray's first light samples take its block of the pixel's */
    sc->lblk = SIZE_MAX;
    direct_lights_n(c, sc, v, x, inv_p, tp, nb, nb_inf, mis, light_rng, gc, c->light_samples, 1, lblk);
}

/* Traces the shadow rays gathered in sc->shadow; each unblocked one adds its radiance to
 * direct, in ray (so pixel) order. Empties the list. */
static void shadow_rays(const pm_eye_t *c, scratch_t *sc, double *direct)
{
    pm_rays_occluded(c->rt, c->width, 0, &sc->shadow);
    sc->n_shadow += sc->shadow.n;
    for (size_t j = 0; j < sc->shadow.n; j++)
        if (sc->shadow.tfar[j] >= 0.0f)
            for (int k = 0; k < 3; k++)
                direct[3 * sc->sh_px[j] + k] += (double)sc->sh_c[3 * j + k];
    sc->shadow.n = 0;
}

/* The lights at infinity of the direct list (render/light.h: the sun, the sky) seen along unit d
 * by a BSDF sample of solid-angle pdf pdf taken nb times at a glossy surface of normal n whose
 * light samples drew them too (direct_lights): each weighted by the power heuristic against
 * those samples, times scale, into direct[3 x ..]. nbpdf is nb pdf; 0 adds nothing (the rays of
 * a Lambertian surface, whose light samples keep weight 1). */
static void env_add(const pm_eye_t *c, const float n[3], const float d[3], float nbpdf, const float scale[3],
                    uint32_t x, double *direct, float ls)
{
    const pm_lights_t *lights = &c->lights;
    float sum[3] = {0.0f, 0.0f, 0.0f};
    int any = 0;
    if (!(nbpdf > 0.0f))
        return;
    for (size_t l = lights->ndelta; l < lights->ndirect; l++) {
        float le[3];
        if (!lights->direct[l].infinite)
            continue;
        pm_lights_le_escape_one(lights, l, d, le);
        if (!(le[0] > 0.0f || le[1] > 0.0f || le[2] > 0.0f))
            continue;
        float w = pm_power_heuristic(nbpdf, ls * pm_lights_pdf_li_escape(lights, l, n, d));
        for (int k = 0; k < 3; k++)
            sum[k] += le[k] * w;
        any = 1;
    }
    if (any)
        for (int k = 0; k < 3; k++)
            direct[3 * x + (uint32_t)k] += (double)(scale[k] * sum[k]);
}

/* What env_add needs of secondary ray j's start, for when it escapes: nb pdf and the normal. */
static void env_keep(scratch_t *sc, size_t j, const float n[3], float pdf, float nb)
{
    float *e = sc->sec_env + 4 * j;
    e[0] = nb * pdf, e[1] = n[0], e[2] = n[1], e[3] = n[2];
}

/* Room for the spp secondary rays of one more surface point; 0 when out of memory. */
static int sec_room(const pm_eye_t *c, scratch_t *sc)
{
    size_t want = sc->sec.n + c->spp;
    return pm_rays_reserve(&sc->sec, want) == PM_OK &&
           grow((void **)&sc->sec_px, sizeof(uint32_t), &sc->sec_px_cap, want) &&
           grow((void **)&sc->sec_w, 3 * sizeof(float), &sc->sec_w_cap, want) &&
           grow((void **)&sc->sec_cos, sizeof(float), &sc->sec_cos_cap, want) &&
           grow((void **)&sc->sec_env, 4 * sizeof(float), &sc->sec_env_cap, want);
}

/* ------------------------------------------------------------------ secondary rays */

/* The spp stratified points of a hit's secondary rays into sc->u1, u2: the primary ray's block of
 * its pixel's points when it has not used it yet, else strata of the hit's own. */
static void secondary_points(const pm_eye_t *c, scratch_t *sc, pm_rng_t *gather_rng)
{
    if (sc->blk != SIZE_MAX) {
        memcpy(sc->u1, sc->pix_u + sc->blk, c->spp * sizeof(float));
        memcpy(sc->u2, sc->pix_u + sc->pix_n + sc->blk, c->spp * sizeof(float));
        sc->blk = SIZE_MAX;
    } else
        pm_strata_fill(gather_rng, c->nx, c->ny, PER_CELL, sc->u1, sc->u2);
}

/* The local frame about n and the spp stratified cosine-weighted directions in it, into sc. */
static void secondary_directions(const pm_eye_t *c, scratch_t *sc, const float n[3], pm_rng_t *gather_rng, float tb[3],
                                 float bb[3])
{
    pm_vec3_t tv, bv;
    pm_onb(pm_v3_load(n), &tv, &bv);
    pm_v3_store(tb, tv), pm_v3_store(bb, bv);
    secondary_points(c, sc, gather_rng);
    pm_strata_cosine(sc->u1, sc->u2, c->spp, sc->lx, sc->ly, sc->lz);
}

/* The guided Lambertian hit (guide cell gc, render/guide.h): ray q is drawn by cosine when its
 * stratified u1 falls under PM_GUIDE_COSINE, u1 rescaled into [0, 1), else from the cell's
 * histogram, u1 rescaled the same way, so that the strata (and the four rays of a cell, mostly of
 * one component) survive. The weight is f cos / p = kd cos / (pi p) over N with the mixture's pdf p
 * (lambert_pdf: one-sample MIS, balance heuristic), and sec_cos pi p for the emitters the ray may
 * find; a guide direction below the surface carries nothing (its pdf still counted) and is not
 * traced. The escaping rays share the sun and the sky as unguided ones do (env_keep). */
static void spawn_guided(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float scale, const float tp[3],
                         pm_rng_t *gather_rng, const pm_guide_cell_t *gc)
{
    const float *n = v->n, *o = v->o, *gn = v->gn;
    const float C = PM_GUIDE_COSINE;
    pm_vec3_t tv, bv;
    pm_onb(pm_v3_load(n), &tv, &bv);
    float tb[3], bb[3];
    pm_v3_store(tb, tv), pm_v3_store(bb, bv);
    secondary_points(c, sc, gather_rng);
    pm_rays_t *sr = &sc->sec;
    size_t j0 = sr->n;
    unsigned nq = c->spp;
    for (unsigned q = 0; q < nq; q++) {
        float u = sc->u1[q];
        sc->gsel[q] = u < C ? 0.0f : 1.0f;
        u = u < C ? u / C : (u - C) / (1.0f - C);
        sc->u1[q] = u < 1.0f ? u : 0x1.fffffep-1f; /* the rescaling can round up to 1 */
    }
    pm_strata_cosine(sc->u1, sc->u2, nq, sc->lx, sc->ly, sc->lz);
    const pm_material_t *m = v->m;
    for (unsigned q = 0; q < nq; q++) {
        size_t j = j0 + q;
        float d[3];
        if (sc->gsel[q] > 0.0f) {
            pm_guide_sample(gc, sc->u1[q], sc->u2[q], d);
            sc->n_guided_rays++;
        } else
            for (int k = 0; k < 3; k++)
                d[k] = sc->lx[q] * tb[k] + sc->ly[q] * bb[k] + sc->lz[q] * n[k];
        float cosn = pm_dot3(d, n), p = lambert_pdf(gc, cosn, d), f = 0.0f;
        int above = cosn > 0.0f && p > 0.0f && (!v->shaded || pm_dot3(d, gn) > 0.0f);
        if (above)
            f = cosn / (PM_PI * p); /* times kd: f cos / p */
        pm_rays_push(sr, o, d, 0.0f, above ? INFINITY : 0.0f);
        float *w = sc->sec_w + 3 * j;
        for (int k = 0; k < 3; k++)
            w[k] = m->kd[k] * f * scale * tp[k];
        sc->sec_px[j] = x;
        sc->sec_cos[j] = PM_PI * p;
        env_keep(sc, j, n, c->env_mis ? p : 0.0f, ENV_COUNT(c)); /* as unguided */
    }
    sc->n_guided_hits++;
}

/* Lambertian primary hit: spp cosine-weighted rays (pdf cos/pi), so f cos / pdf = pi f = kd
 * for every ray, over N; kd > 0 here. Whole arrays at once, in SIMD lanes. With a guide cell gc,
 * the rays of the mixture instead (spawn_guided). */
static void spawn_lambertian(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float scale,
                             const float tp[3], pm_rng_t *gather_rng, const pm_guide_cell_t *gc)
{
    if (gc) {
        spawn_guided(c, sc, v, x, scale, tp, gather_rng, gc);
        return;
    }
    float tb[3], bb[3];
    const float *n = v->n, *o = v->o, *gn = v->gn;
    secondary_directions(c, sc, n, gather_rng, tb, bb);
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
    const pm_material_t *m = v->m;
    float w0 = m->kd[0] * scale * tp[0], w1 = m->kd[1] * scale * tp[1], w2 = m->kd[2] * scale * tp[2],
          *w = sc->sec_w + 3 * j0;
    uint32_t *px = sc->sec_px + j0;
    memcpy(sc->sec_cos + j0, lz, nq * sizeof *lz);
    for (unsigned q = 0; q < nq; q++) {
        w[3 * q] = w0, w[3 * q + 1] = w1, w[3 * q + 2] = w2;
        px[q] = x;
    }
    /* escaping, they find the sun and the sky the light samples drew too (env_add, c->env_mis) */
    for (unsigned q = 0; q < nq; q++)
        env_keep(sc, j0 + q, n, c->env_mis ? lz[q] * (1.0f / PM_PI) : 0.0f, ENV_COUNT(c));
    if (v->shaded) /* drawn about the shading normal: one below the geometric surface is not taken */
        for (unsigned q = 0; q < nq; q++)
            if (!(dx[q] * gn[0] + dy[q] * gn[1] + dz[q] * gn[2] > 0.0f))
                w[3 * q] = w[3 * q + 1] = w[3 * q + 2] = 0.0f, tf[q] = 0.0f;
    sr->n += nq;
}

/* Glossy primary hit: directions drawn from the BSDF mixture (pm_bsdf_sample), the lobe chosen
 * by the stratified u1 itself (rescaled into the chosen lobe's share), so that a sharp lobe gets
 * its rays along the mirror direction and the strata survive. The weight is f cos / pdf over N
 * with the mixture's pdf (one-sample MIS of the two lobes, balance heuristic); a glossy draw
 * below the surface is the lobe's energy loss and carries nothing. */
static void spawn_glossy(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float scale, const float tp[3],
                         pm_rng_t *gather_rng)
{
    float tb[3], bb[3];
    const pm_material_t *m = v->m;
    const float *n = v->n, *wo = v->wo;
    secondary_directions(c, sc, n, gather_rng, tb, bb);
    float sd = pm_bsdf_diffuse_share(m);
    for (unsigned q = 0; q < c->spp; q++) {
        float wi[3], u1 = sc->u1[q], u2 = sc->u2[q];
        pm_lobe_t lobe = u1 < sd ? PM_LOBE_DIFFUSE : PM_LOBE_GLOSSY;
        u1 = lobe == PM_LOBE_DIFFUSE ? u1 / sd : (u1 - sd) / (1.0f - sd);
        if (!(u1 < 1.0f))
            u1 = 0x1.fffffep-1f; /* the rescaling can round up to 1 */
        if (!pm_bsdf_sample_lobe(m, lobe, n, wo, u1, u2, wi) || (v->shaded && !(pm_dot3(v->gn, wi) > 0.0f)))
            continue;
        float pdf = pm_bsdf_pdf(m, n, wi, wo), cosi = pm_dot3(n, wi);
        if (!(pdf > 0.0f))
            continue;
        size_t j = sc->sec.n;
        float *w = sc->sec_w + 3 * j, f[3];
        pm_brdf(m, n, wi, wo, f);
        for (int k = 0; k < 3; k++)
            w[k] = f[k] * cosi / pdf * scale * tp[k];
        if (!(w[0] > 0.0f || w[1] > 0.0f || w[2] > 0.0f))
            continue; /* carries nothing: not traced */
        sc->sec_px[j] = x;
        sc->sec_cos[j] = pdf * PM_PI; /* pi times the pdf: what a cosine sample's cosine is */
        env_keep(sc, j, n, pdf, (float)(c->spp / PER_CELL));
        pm_rays_push(&sc->sec, v->o, wi, 0.0f, INFINITY);
    }
}

/* A primary hit of a kind other than the standard one (conductor, rough glass, plastic):
 * directions from physics/bsdf.h's sampler with the stratified u1, u2 and a lobe choice from the
 * pixel's gather stream; the weight f cos / pdf over N as the sampler gives it (a delta lobe's
 * too). A transmitted ray leaves from the other side. sec_cos is -1 for a ray no light sample of
 * this hit could have drawn (a delta lobe, a transmission): the light it finds is its own. */
static void spawn_module(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, float scale, const float tp[3],
                         pm_rng_t *gather_rng)
{
    float tb[3], bb[3];
    secondary_directions(c, sc, v->n, gather_rng, tb, bb);
    for (unsigned q = 0; q < c->spp; q++) {
        pm_bsdf_sample_t bs;
        float u = pm_rng_float(gather_rng);
        if (!pm_bsdf_sample_wi(v->m, v->bn, v->wo, u, sc->u1[q], sc->u2[q], PM_BSDF_RADIANCE, &bs))
            continue;
        int tr = (bs.lobe & PM_BSDF_TRANSMIT) != 0;
        float cg = pm_dot3(v->gn, bs.wi), o[3];
        if (tr ? !(cg < 0.0f) : (v->shaded && !(cg > 0.0f)))
            continue; /* not on the side of the geometric surface it was drawn for */
        size_t j = sc->sec.n;
        float *w = sc->sec_w + 3 * j;
        for (int k = 0; k < 3; k++) {
            w[k] = bs.weight[k] * scale * tp[k];
            o[k] = tr ? v->p[k] - c->eps * v->gn[k] : v->o[k];
        }
        if (!(w[0] > 0.0f || w[1] > 0.0f || w[2] > 0.0f) || !isfinite(w[0] + w[1] + w[2]))
            continue;
        sc->sec_px[j] = x;
        sc->sec_cos[j] = (bs.lobe & PM_BSDF_DELTA) || tr ? -1.0f : bs.pdf * PM_PI;
        env_keep(sc, j, v->n, bs.pdf, (float)(c->spp / PER_CELL));
        pm_rays_push(&sc->sec, o, bs.wi, 0.0f, INFINITY);
    }
}

/* ------------------------------------------------------------------ primary hits */

/* The surface primary ray i hit: its point, normals, material (textured into *textured) and
 * the side it was seen from (+1 the front, -1 the back). */
static float primary_surface(const pm_eye_t *c, scratch_t *sc, size_t i, pm_material_t *textured, surf_t *v)
{
    const pm_scene_t *s = c->s;
    const pm_rays_t *pr = &sc->prim;
    uint32_t tri = pr->prim[i];
    float d[3] = {pr->dx[i], pr->dy[i], pr->dz[i]}, t = pr->tfar[i];
    float *p = sc->hit + 9 * i, *wo = p + 6;
    const float *ng = c->geom.tri_n + 3 * (size_t)tri;
    for (int k = 0; k < 3; k++) {
        p[k] = (k == 0 ? pr->ox[i] : k == 1 ? pr->oy[i] : pr->oz[i]) + t * d[k];
        wo[k] = -d[k];
    }
    float side = pm_dot3(ng, wo) >= 0.0f ? 1.0f : -1.0f; /* both sides reflect: face the viewer */
    for (int k = 0; k < 3; k++)
        v->gn[k] = side * ng[k];
    v->m = pm_scene_material_at(s, tri, p, textured);
    for (int k = 0; k < 3; k++) {
        v->p[k] = p[k], v->wo[k] = wo[k];
        v->o[k] = p[k] + c->eps * v->gn[k];
    }
    /* n: the shading normal (render/transport.h), gn itself in a scene without vertex normals */
    surf_normals(s, tri, side, v);
    memcpy(p + 3, v->n, 12);
    return side;
}

/* Direct light and spawned rays of primary ray i (pixel column x), and its caustic query into
 * caus when asked for; 0 when out of memory. A primary ray that passed mirrors or glass arrives
 * here as its last ray, with the chain's throughput in sc->thr: every contribution is multiplied
 * by it last, so that without a chain (throughput exactly 1) every number is what it was. */
static int shade_primary(const pm_eye_t *c, scratch_t *sc, size_t i, uint32_t x, uint32_t pixel, pm_rng_t *light_rng,
                         pm_rng_t *gather_rng, double *direct, bytebuf_t *out, bytebuf_t *caus)
{
    static const float one[3] = {1.0f, 1.0f, 1.0f};
    const float *tp = c->specular || c->cont ? sc->thr + 3 * i : one;
    float emw = c->cont ? sc->emw[i] : 1.0f; /* 1 unless the ray left a glossy bounce (primary_glossy) */
    const pm_scene_t *s = c->s;
    uint32_t tri = sc->prim.prim[i];
    float inv_p = 1.0f / (float)pixel_rays(c, pixel);
    pm_material_t textured; /* the material with its textures at p (render/scene.h) */
    surf_t v;
    primary_surface(c, sc, i, &textured, &v); /* the side is the emitter test's own (pm_lights_le_hit) */
    const pm_material_t *m = v.m;

    /* Emission seen directly: emitters radiate from their front side only (both when two-sided). */
    float le[3], cos_emit;
    if (pm_lights_le_hit(&c->lights, tri, pm_dot3(c->geom.tri_n + 3 * (size_t)tri, v.wo), le, &cos_emit) && emw > 0.0f)
        for (int k = 0; k < 3; k++)
            direct[3 * x + k] += (double)(le[k] * inv_p * tp[k] * emw);

    int glossy = pm_material_is_glossy(m);
    int reflects = m->kd[0] > 0.0f || m->kd[1] > 0.0f || m->kd[2] > 0.0f || glossy;
    if (!reflects)
        return 1; /* black: reflects no light, direct or gathered */

    /* The caustic query: this first non-specular hit itself, weighted like a direct-vis query,
     * gathered against the caustic map (L S+ D seen from here). */
    if (c->caustics && !rough_transmits(m)) { /* rough glass holds no photons */
        float w[3] = {inv_p * tp[0], inv_p * tp[1], inv_p * tp[2]};
        int put = put_hit(c, caus, v.p, v.n, w, pixel, s->tri_material[tri], m, v.wo);
        if (put < 0)
            return 0;
        sc->n_caustic += (uint64_t)put;
    }

    /* the row's reservation, unless glossy chains (primary_glossy) took some of it */
    if (c->cont && !shadow_room(c, sc))
        return 0;
    /* a Lambertian hit's secondary rays may be guided: its light samples weigh against their pdf */
    const pm_guide_cell_t *gc = m->kind == PM_MAT_STANDARD && !glossy ? guide_cell(c, &v) : NULL;
    direct_lights(c, sc, &v, x, inv_p, tp, (float)(c->spp / PER_CELL), ENV_COUNT(c), c->mode == PM_EYE_GATHER,
                  light_rng, gc);

    if (c->mode == PM_EYE_DIRECT_VIS) {
        /* The primary hit is the query: path weight 1 (over the primary rays of the pixel). */
        float w[3] = {inv_p * tp[0], inv_p * tp[1], inv_p * tp[2]};
        if (!c->direct_only && !rough_transmits(m)) {
            int put = put_hit(c, out, v.p, v.n, w, pixel, s->tri_material[tri], m, v.wo);
            if (put < 0)
                return 0;
            sc->n_queries += (uint64_t)put;
        }
        return 1;
    }

    if (!c->sec_rays)
        return 1; /* no emitter for a secondary ray to find nor glossy path to follow: no secondary rays */
    float scale = inv_p / (float)c->spp;
    if (c->cont && !sec_room(c, sc)) /* glossy chains (shade_diffuse_part) may have taken the row's */
        return 0;
    if (m->kind != PM_MAT_STANDARD)
        spawn_module(c, sc, &v, x, scale, tp, gather_rng);
    else if (glossy)
        spawn_glossy(c, sc, &v, x, scale, tp, gather_rng);
    else
        spawn_lambertian(c, sc, &v, x, scale, tp, gather_rng, gc);
    return 1;
}

/* ------------------------------------------------------------------ glossy paths */

/* Whether a secondary path continues through a hit on material m instead of gathering there
 * (docs/accuracy.md, glossy paths): a Phong lobe of exponent PM_EYE_GLOSSY_NS or more, a
 * conductor or plastic of GGX width under PM_EYE_GLOSSY_ALPHA (a plastic's smooth coat too: its
 * delta reflection cannot be gathered), with glossy paths on (depth > 0); and a rough glass
 * always, which holds no photons (pm_bsdf_stores_photons). */
static inline int material_continues(const pm_material_t *m, unsigned depth)
{
    switch (m->kind) {
    case PM_MAT_STANDARD: return depth && pm_material_is_glossy(m) && m->ns >= PM_EYE_GLOSSY_NS;
    case PM_MAT_CONDUCTOR: return depth && m->alpha >= PM_MAT_ALPHA_DELTA && m->alpha < PM_EYE_GLOSSY_ALPHA;
    case PM_MAT_PLASTIC: return depth && !(m->alpha >= PM_EYE_GLOSSY_ALPHA);
    case PM_MAT_ROUGH_GLASS: return rough_transmits(m);
    default: return 0;
    }
}

/* A microfacet material with textures (a PBR metal's F0, a plastic's base): it differs at every
 * hit, and a query's material is one entry of the table, so paths never gather on it. */
static inline int varies(const pm_scene_t *s, uint32_t mi)
{
    return s->maps && s->materials[mi].kind != PM_MAT_STANDARD && pm_material_is_glossy(&s->materials[mi]) &&
           (s->maps[mi].kd >= 0 || s->maps[mi].ks >= 0);
}

/* Whether a path goes on through a hit on material mi (m: with its textures there). */
static inline int continues(const pm_eye_t *c, const pm_material_t *m, uint32_t mi)
{
    return c->cont && (material_continues(m, c->glossy_depth) || varies(c->s, mi));
}

/* The glossy bounces a path may take through material mi before it gathers there: rough glass
 * and a textured microfacet material, which no gather can use, to PM_EYE_MAX_SPECULAR (then its
 * light is lost); the others glossy_depth. */
static inline unsigned depth_limit(const pm_eye_t *c, const pm_material_t *m, uint32_t mi)
{
    return rough_transmits(m) || varies(c->s, mi) ? PM_EYE_MAX_SPECULAR : c->glossy_depth;
}

/* Where a secondary path is: the ray that reached hit triangle tri (origin o, unit direction d,
 * distance t), its path weight w (f cos / pdf products over N, the query weight before the fold),
 * the pixel it belongs to and the sub-stream it draws from. */
typedef struct {
    uint32_t tri, pixel, x;
    float o[3], d[3], t, w[3];
    pm_rng_t *rng;
} path_t;

/* The records of path a's hit, a non-specular surface: one query (two for a glossy textured
 * material, put_hit), weighted by the path weight and the fold. m and qn, when not NULL, are the
 * material at the hit (pm_scene_material_at) and the query's normal there (query_normal) that the
 * caller has already (gather_direct's): each texture is read once a hit. 0 when out of memory. */
static int path_query(const pm_eye_t *c, scratch_t *sc, const path_t *a, const pm_material_t *m, const float *qn,
                      bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    uint32_t mi = s->tri_material[a->tri];
    const float *ng = c->geom.tri_n + 3 * (size_t)a->tri;
    float q[3], wo[3] = {-a->d[0], -a->d[1], -a->d[2]}, n[3], fold_tex[3];
    for (int k = 0; k < 3; k++)
        q[k] = a->o[k] + a->t * a->d[k];
    float side = pm_dot3(ng, wo) >= 0.0f ? 1.0f : -1.0f; /* the side the query sees */
    pm_material_t textured;
    const pm_material_t *mt;
    const float *fold = hit_fold(c, a->tri, mi, q, m, &textured, fold_tex, &mt);
    if (qn)
        memcpy(n, qn, sizeof n);
    else
        query_normal(s, a->tri, q, ng, side, n);
    if (!isfinite(a->w[0] + a->w[1] + a->w[2]))
        return 1;
    if (c->lobe && c->lobe[mi]) { /* glossy and textured: two records (put_hit) */
        int put = put_hit(c, out, q, n, a->w, a->pixel, mi, mt, wo);
        if (put < 0)
            return 0;
        sc->n_queries += (uint64_t)put;
        return 1;
    }
    float w[3] = {a->w[0] * fold[0], a->w[1] * fold[1], a->w[2] * fold[2]};
    if (!(w[0] > 0.0f || w[1] > 0.0f || w[2] > 0.0f))
        return 1; /* a black query surface */
    if (!put_query(c, out, q, n, w, a->pixel, mi, wo))
        return 0;
    sc->n_queries++;
    return 1;
}

/* The geometry of path a's hit into v: the point, the direction back along the ray, the
 * geometric normal turned toward it and the lifted ray origin; returns the side (+1 the front,
 * -1 the back) for surf_normals, once the caller has set v->m. */
static float path_hit_surface(const pm_eye_t *c, const path_t *a, surf_t *v)
{
    const float *ng = c->geom.tri_n + 3 * (size_t)a->tri;
    for (int k = 0; k < 3; k++)
        v->p[k] = a->o[k] + a->t * a->d[k], v->wo[k] = -a->d[k];
    float side = pm_dot3(ng, v->wo) >= 0.0f ? 1.0f : -1.0f;
    for (int k = 0; k < 3; k++)
        v->gn[k] = side * ng[k], v->o[k] = v->p[k] + c->eps * v->gn[k];
    return side;
}

/* Secondary direct light (pm_eye_options_t's secondary_direct): next-event estimation at path
 * a's gather point, as at a primary hit (direct_lights, the whole BSDF there), one sample of
 * each light (the pixel's spp gather points are its samples; a point light or spot exactly),
 * weight 1: no ray leaves a gather point to find a light, and the map it is gathered against
 * holds none of the first-hit photons these samples stand for (trace-photons --indirect-only),
 * so this is the only estimate of that light there. A sample of an area light nearer than
 * pm_light_at_gather's radius is dropped and its light left to the map's photons: such a
 * sample carries 1/r^2 and, with no BSDF sample to share it by MIS (as the primary hits'
 * secondary rays do), makes fireflies no pass averages out (measured: the atrium's sky panel
 * sampled at every distance, relative MSE 1.05 after three passes). Times the path weight,
 * shadow rays into sc->shadow. m, when not NULL, is the material at the hit (the caller's); the
 * query's normal there goes to qn_out (*has_qn 1) when this computes it. 0 when out of memory. */
static int gather_direct(const pm_eye_t *c, scratch_t *sc, const path_t *a, const pm_material_t *m, float qn_out[3],
                         int *has_qn)
{
    pm_material_t textured;
    surf_t v;
    if (!isfinite(a->w[0] + a->w[1] + a->w[2]))
        return 1;
    float side = path_hit_surface(c, a, &v);
    v.m = m ? m : pm_scene_material_at(c->s, a->tri, v.p, &textured);
    if (!(v.m->kd[0] > 0.0f || v.m->kd[1] > 0.0f || v.m->kd[2] > 0.0f || pm_material_is_glossy(v.m)))
        return 1; /* black */
    surf_normals(c->s, a->tri, side, &v);
    /* with vertex normals, the query's normal is this shading normal (query_normal) */
    if (c->s->normals && !rough_transmits(v.m)) {
        memcpy(qn_out, v.n, sizeof v.n);
        *has_qn = 1;
    }
    if (!shadow_room(c, sc))
        return 0;
    direct_lights_n(c, sc, &v, a->x, 1.0f, a->w, 0.0f, 0.0f, 0, a->rng, NULL, 1, 0, SIZE_MAX);
    return 1;
}

/* The emission path a's ray found at its hit (front faces, unless lights are two-sided), times
 * the path weight and mis, into direct. */
static void path_emission(const pm_eye_t *c, const path_t *a, float mis, double *direct)
{
    const float *ng = c->geom.tri_n + 3 * (size_t)a->tri;
    float le[3], cos_emit;
    if (!pm_lights_le_hit(&c->lights, a->tri, -pm_dot3(ng, a->d), le, &cos_emit))
        return;
    for (int k = 0; k < 3; k++)
        direct[3 * a->x + (uint32_t)k] += (double)(a->w[k] * le[k] * mis);
}

/* The sky and the sun seen along path a's ray, which escaped, times the path weight, into direct. */
static void path_sky(const pm_eye_t *c, const path_t *a, double *direct)
{
    float le[3];
    pm_lights_le_escape(&c->lights, a->d, le);
    for (int k = 0; k < 3; k++)
        direct[3 * a->x + (uint32_t)k] += (double)(a->w[k] * le[k]);
}

/* The next ray of path a, leaving v along wi with the bounce's f cos / pdf in fc (Russian
 * roulette from PM_EYE_GLOSSY_RR bounces on, u its number), traced to its next hit, whose
 * emission is counted: against v's ls light samples of each light by MIS with the BSDF's pdf, or
 * whole when pdf < 0 (a delta lobe or a transmission, which no light sample of v reaches; such a
 * ray that escapes brings the sky back too). Returns 1 when the path goes on, 0 when it ended. */
static int path_next(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, path_t *a, unsigned depth,
                     const float o[3], const float wi[3], float fc[3], float pdf, const float n[3], float u,
                     double *direct, float ls)
{
    const pm_scene_t *s = c->s;
    if (depth + 1 >= PM_EYE_GLOSSY_RR) {
        /* survival the bounce's largest channel of f cos / pdf, capped at 1 */
        float q = fminf(1.0f, fmaxf(fc[0], fmaxf(fc[1], fc[2])));
        if (!(u < q))
            return 0;
        for (int k = 0; k < 3; k++)
            fc[k] /= q;
    }
    for (int k = 0; k < 3; k++) {
        a->w[k] *= fc[k];
        a->o[k] = o[k], a->d[k] = wi[k];
    }
    if (!(a->w[0] > 0.0f || a->w[1] > 0.0f || a->w[2] > 0.0f) || !isfinite(a->w[0] + a->w[1] + a->w[2]))
        return 0;
    sc->n_glossy++;
    a->tri = pm_rt_intersect1(c->rt, ctx, a->o, a->d, 0.0f, INFINITY, &a->t, NULL);
    if (a->tri == PM_RAY_MISS) {
        /* the lights at infinity: shared with the light samples (env_add), whole when none could see them */
        if (pdf < 0.0f)
            path_sky(c, a, direct);
        else
            env_add(c, n, a->d, pdf, a->w, a->x, direct, ls);
        return 0;
    }
    if (!pm_material_is_specular(&s->materials[s->tri_material[a->tri]]) && pm_lights_has_emitters(&c->lights)) {
        const float *lg = c->geom.tri_n + 3 * (size_t)a->tri;
        float cosy = fabsf(pm_dot3(lg, a->d));
        path_emission(c, a,
                      pdf < 0.0f ? 1.0f : pm_power_heuristic(pdf, ls * pm_lights_pdf_li_hit(&c->lights, a->t, cosy)),
                      direct);
    }
    return 1;
}

/* One bounce of path a at its hit, a material that continues (continues()): next-event
 * estimation there into sc->shadow, then a direction from its BSDF and the ray to the next hit
 * (path_next). A standard material leaves its diffuse part as a query there (folded, a record
 * of its own) and continues along its Phong lobe alone; the other kinds continue along their
 * whole BSDF (physics/bsdf.h's sampler). Returns 1 when the path goes on, 0 when it ended
 * (absorbed, escaped), -1 when out of memory. */
static int glossy_bounce(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, path_t *a, unsigned depth,
                         double *direct, bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    surf_t v;
    pm_material_t textured, lobe;
    float side = path_hit_surface(c, a, &v);
    const pm_material_t *m = pm_scene_material_at(s, a->tri, v.p, &textured);
    v.m = m;
    surf_normals(s, a->tri, side, &v);
    int standard = m->kind == PM_MAT_STANDARD;
    if (standard) {
        /* The diffuse part gathers here, the folded entry of the table: kd / pi in the weight. */
        float wd[3] = {a->w[0] * m->kd[0] * (1.0f / PM_PI), a->w[1] * m->kd[1] * (1.0f / PM_PI),
                       a->w[2] * m->kd[2] * (1.0f / PM_PI)};
        if (!c->direct_only && (wd[0] > 0.0f || wd[1] > 0.0f || wd[2] > 0.0f) && isfinite(wd[0] + wd[1] + wd[2])) {
            if (!put_query(c, out, v.p, v.n, wd, a->pixel, c->folded, v.wo))
                return -1;
            sc->n_queries++;
        }
        if (c->sec_direct && (wd[0] > 0.0f || wd[1] > 0.0f || wd[2] > 0.0f)) {
            /* its direct light, which that query no longer holds (gather_direct) */
            pm_material_t diffuse = *m;
            surf_t vd = v;
            diffuse.ks[0] = diffuse.ks[1] = diffuse.ks[2] = 0.0f;
            vd.m = &diffuse;
            if (!shadow_room(c, sc))
                return -1;
            direct_lights_n(c, sc, &vd, a->x, 1.0f, a->w, 0.0f, 0.0f, 0, a->rng, NULL, 1, 0, SIZE_MAX);
        }
        /* The lobe alone: the material without its diffuse part. */
        lobe = *m;
        lobe.kd[0] = lobe.kd[1] = lobe.kd[2] = 0.0f;
        v.m = &lobe;
    }
    if (!shadow_room(c, sc))
        return -1;
    direct_lights(c, sc, &v, a->x, 1.0f, a->w, 1.0f, 1.0f, 1, a->rng, NULL);
    float wi[3], fc[3], o[3], pdf, u = pm_rng_float(a->rng), u1 = pm_rng_float(a->rng), u2 = pm_rng_float(a->rng),
                                   u3 = pm_rng_float(a->rng);
    memcpy(o, v.o, sizeof o);
    if (standard) {
        if (!pm_bsdf_sample_lobe(&lobe, PM_LOBE_GLOSSY, v.n, v.wo, u1, u2, wi) ||
            (v.shaded && !(pm_dot3(v.gn, wi) > 0.0f)))
            return 0;
        float f[3], cosi = pm_dot3(v.n, wi);
        pdf = pm_bsdf_pdf(&lobe, v.n, wi, v.wo);
        if (!(pdf > 0.0f))
            return 0;
        pm_brdf(&lobe, v.n, wi, v.wo, f);
        for (int k = 0; k < 3; k++)
            fc[k] = f[k] * cosi / pdf;
    } else {
        pm_bsdf_sample_t bs;
        if (!pm_bsdf_sample_wi(m, v.bn, v.wo, u, u1, u2, PM_BSDF_RADIANCE, &bs))
            return 0;
        int tr = (bs.lobe & PM_BSDF_TRANSMIT) != 0;
        float cg = pm_dot3(v.gn, bs.wi);
        if (tr ? !(cg < 0.0f) : (v.shaded && !(cg > 0.0f)))
            return 0; /* not on the side of the geometric surface it was drawn for */
        memcpy(wi, bs.wi, sizeof wi);
        memcpy(fc, bs.weight, sizeof fc);
        pdf = (bs.lobe & PM_BSDF_DELTA) || tr ? -1.0f : bs.pdf;
        if (tr)
            for (int k = 0; k < 3; k++)
                o[k] = v.p[k] - c->eps * v.gn[k];
    }
    return path_next(c, sc, ctx, a, depth, o, wi, fc, pdf, v.n, u3, direct, (float)c->light_samples);
}

/* One diffuse bounce of path a at its hit on a Lambertian surface, before it gathers
 * (pm_eye_options_t diffuse_depth): there all the light of every light comes from one light
 * sample each (an area light's at any distance, the sky whatever the gather rule: this is no
 * gather point), weighed by MIS against the one cosine-weighted ray that goes on (f cos / pdf =
 * kd) to the next hit, where the path gathers or bounces again (path_next, its emitters and the
 * sky it escapes to shared with these samples). Returns 1 when the path goes on, 0 when it
 * ended, -1 when out of memory. */
static int diffuse_bounce(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, path_t *a, unsigned depth,
                          const pm_material_t *m, double *direct)
{
    surf_t v;
    float side = path_hit_surface(c, a, &v);
    v.m = m;
    surf_normals(c->s, a->tri, side, &v);
    if (!shadow_room(c, sc))
        return -1;
    direct_lights_n(c, sc, &v, a->x, 1.0f, a->w, 1.0f, 1.0f, 1, a->rng, NULL, 1, 1, SIZE_MAX);
    float u1 = pm_rng_float(a->rng), u2 = pm_rng_float(a->rng), u3 = pm_rng_float(a->rng), wi[3];
    if (!pm_bsdf_sample_lobe(m, PM_LOBE_DIFFUSE, v.n, v.wo, u1, u2, wi) || (v.shaded && !(pm_dot3(v.gn, wi) > 0.0f)))
        return 0;
    float cosi = pm_dot3(v.n, wi);
    float fc[3] = {m->kd[0], m->kd[1], m->kd[2]};
    return path_next(c, sc, ctx, a, depth, v.o, wi, fc, cosi * (1.0f / PM_PI), v.n, u3, direct, 1.0f);
}

/* Mirrors and glass past a glossy or diffuse bounce of path a: the light at the chain's end is
 * this path's alone (no light sample reaches through them), weight 1; the sky seen escapes too.
 * Returns 1 when the path goes on from the chain's end, 0 when it escaped. */
static int past_specular(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, path_t *a, double *direct)
{
    float thr[3] = {1.0f, 1.0f, 1.0f};
    follow_specular(c, sc, ctx, a->rng, -1.0f, &a->tri, a->o, a->d, &a->t, thr);
    for (int k = 0; k < 3; k++)
        a->w[k] *= thr[k];
    if (a->tri == PM_RAY_MISS) {
        path_sky(c, a, direct);
        return 0;
    }
    path_emission(c, a, 1.0f, direct);
    return 1;
}

/* Follows secondary path a from its hit, a non-specular surface: through every glossy surface
 * that continues (glossy_bounce) and the mirrors and glass behind them, to the first surface
 * that gathers, which gets the path's query; after c->glossy_depth glossy bounces the query is
 * on the glossy surface itself (nothing is lost). Emission found past a glossy bounce is the
 * direct buffer's (docs/accuracy.md). 0 when out of memory. */
static int follow_path(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, path_t *a, double *direct,
                       bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    for (unsigned depth = 0, diffuse = 0;; depth++) {
        pm_material_t textured;
        float q[3];
        for (int k = 0; k < 3; k++)
            q[k] = a->o[k] + a->t * a->d[k];
        const pm_material_t *m = c->cont || c->diffuse_depth ? pm_scene_material_at(s, a->tri, q, &textured) : NULL;
        uint32_t mi = s->tri_material[a->tri];
        if (m && diffuse < c->diffuse_depth && m->kind == PM_MAT_STANDARD && !pm_material_is_glossy(m) &&
            (m->kd[0] > 0.0f || m->kd[1] > 0.0f || m->kd[2] > 0.0f)) {
            int on = diffuse_bounce(c, sc, ctx, a, depth, m, direct);
            if (on <= 0)
                return on == 0;
            diffuse++;
            if (pm_material_is_specular(&s->materials[s->tri_material[a->tri]]) &&
                !past_specular(c, sc, ctx, a, direct))
                return 1;
            continue;
        }
        /* past glossy_depth bounces the path gathers where it is; through rough glass, which
         * holds no photons, it goes on (to PM_EYE_MAX_SPECULAR bounces, then its light is lost) */
        if (!m || !continues(c, m, mi) || depth >= depth_limit(c, m, mi)) {
            if (m && (rough_transmits(m) || varies(s, mi)))
                return 1; /* no query, so no light of its own either */
            /* the material and the normal at the hit, looked up once for both */
            float qn[3];
            int has_qn = 0;
            if (!m && c->sec_direct && s->maps)
                m = pm_scene_material_at(s, a->tri, q, &textured);
            if (c->sec_direct && !gather_direct(c, sc, a, m, qn, &has_qn))
                return 0;
            return c->direct_only || path_query(c, sc, a, m, has_qn ? qn : NULL, out);
        }
        int on = glossy_bounce(c, sc, ctx, a, depth, direct, out);
        if (on <= 0)
            return on == 0;
        if (pm_material_is_specular(&s->materials[s->tri_material[a->tri]]) && !past_specular(c, sc, ctx, a, direct))
            return 1;
    }
}

/* ------------------------------------------------------------------ rows */

/* Casts row y's primary rays, pixel by pixel along the row: coherent packets. */
static void cast_primary(const pm_eye_t *c, scratch_t *sc, uint32_t y)
{
    sc->prim.n = 0;
    for (uint32_t x = 0; x < c->w; x++) {
        uint64_t pixel = (uint64_t)y * c->w + x;
        pm_rng_t jr;
        pm_rng_init(&jr, c->seed, 4 * pixel + STREAM_JITTER);
        uint32_t sx = pm_rng_u32(&jr), sy = pm_rng_u32(&jr); /* the pixel's scramble */
        for (unsigned j = 0, nj = pixel_rays(c, pixel); j < nj; j++) {
            float jx = 0.5f, jy = 0.5f, d[3];
            if (c->pixel == PM_PIXEL_BOX)
                pm_pixel_offset(j, sx, sy, &jx, &jy);
            pm_camera_dir(&c->cam, (float)x + jx, (float)y + jy, d);
            sc->rx[sc->prim.n] = x, sc->rj[sc->prim.n] = j;
            pm_rays_push(&sc->prim, c->cam.eye, d, 0.0f, INFINITY);
        }
    }
    pm_rays_intersect(c->rt, c->width, 1, &sc->prim);
    sc->n_primary += sc->prim.n;
}

/* Primary ray i through mirrors and glass to the first other surface: the ray becomes the
 * chain's last, its throughput in sc->thr. spec_xi is the pixel's rotation of its primary rays'
 * first choices. */
static void primary_chain(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, size_t i,
                          pm_rng_t *spec_rng, float spec_xi)
{
    pm_rays_t *pr = &sc->prim;
    float *thr = sc->thr + 3 * i, o[3] = {pr->ox[i], pr->oy[i], pr->oz[i]}, d[3] = {pr->dx[i], pr->dy[i], pr->dz[i]},
          t = pr->tfar[i];
    thr[0] = thr[1] = thr[2] = 1.0f;
    uint32_t tri = pr->prim[i];
    if (!pm_material_is_specular(&c->s->materials[c->s->tri_material[tri]]))
        return;
    float l = sqrtf(pm_dot3(d, d));
    for (int k = 0; k < 3; k++)
        d[k] /= l;
    t *= l;
    /* The pixel's primary rays take the first choice between reflection and refraction from a
     * rotated grid, {j / P + xi}, so that P rays split about F P to (1 - F) P rather than at
     * random: the glass seen directly is far less noisy. */
    float u_first =
        fmodf((float)sc->rj[i] / (float)pixel_rays(c, (uint64_t)sc->row * c->w + sc->rx[i]) + spec_xi, 1.0f);
    if (!(u_first < 1.0f))
        u_first = 0.0f;
    follow_specular(c, sc, ctx, spec_rng, u_first, &tri, o, d, &t, thr);
    pr->prim[i] = tri;
    pr->ox[i] = o[0], pr->oy[i] = o[1], pr->oz[i] = o[2];
    pr->dx[i] = d[0], pr->dy[i] = d[1], pr->dz[i] = d[2];
    pr->tfar[i] = t;
}

/* The pixel of primary ray i of the row sc holds. */
static inline uint32_t y_pixel(const pm_eye_t *c, const scratch_t *sc, size_t i) { return sc->row * c->w + sc->rx[i]; }

/* The diffuse part of a standard material at a glossy vertex a primary ray passes through
 * (v->m its kd alone), shaded as a Lambertian primary hit with the path's throughput thr: its
 * caustic query (of the table's folded entry, kd / pi in the weight), its light samples and its
 * spp cosine-weighted secondary rays. 0 when out of memory. */
static int shade_diffuse_part(const pm_eye_t *c, scratch_t *sc, const surf_t *v, uint32_t x, uint32_t pixel,
                              const float thr[3], pm_rng_t *light_rng, pm_rng_t *gather_rng, bytebuf_t *caus)
{
    float inv_p = 1.0f / (float)pixel_rays(c, pixel);
    if (c->caustics) {
        float w[3];
        for (int k = 0; k < 3; k++)
            w[k] = inv_p * thr[k] * v->m->kd[k] * (1.0f / PM_PI);
        if (!put_query(c, caus, v->p, v->n, w, pixel, c->folded, v->wo))
            return 0;
        sc->n_caustic++;
    }
    if (!shadow_room(c, sc) || !sec_room(c, sc))
        return 0;
    const pm_guide_cell_t *gc = guide_cell(c, v);
    direct_lights(c, sc, v, x, inv_p, thr, (float)(c->spp / PER_CELL), ENV_COUNT(c), 1, light_rng, gc);
    spawn_lambertian(c, sc, v, x, inv_p / (float)c->spp, thr, gather_rng, gc);
    return 1;
}

/* Primary ray i (pixel column x) at a hit on a surface that continues (continues(): a sharp lobe,
 * rough glass), passed through like a mirror, so that the surface seen in it gets the final
 * gather of a primary hit (light samples, spp secondary rays) instead of one query per secondary
 * ray, a density estimate seen through the lobe (the speckle of a windshield). A standard
 * material whose lobe has at least half its albedo (max(ks) >= max(kd); a mostly diffuse one is
 * shaded whole, its lobe gathered) has its diffuse part shaded at the vertex as a Lambertian
 * primary hit (shade_diffuse_part) and its lobe followed; the other kinds go on along their
 * whole BSDF. At each glossy vertex: its emission, its light samples for the lobe (MIS with the lobe's sample,
 * shadow rays in the row's list), the sample and the ray to the next hit, whose emission weight
 * goes to sc->emw; mirrors and glass on the way are followed; after glossy_depth bounces the last
 * hit is shaded as it is. The ray becomes the chain's last, its throughput in sc->thr (zero when
 * a ray escapes past a bounce whose light samples saw the sky). 0 when out of memory. */
static int primary_glossy(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, size_t i, uint32_t x,
                          pm_rng_t *rng, pm_rng_t *light_rng, pm_rng_t *gather_rng, double *direct, bytebuf_t *caus)
{
    const pm_scene_t *s = c->s;
    pm_rays_t *pr = &sc->prim;
    float *thr = sc->thr + 3 * i, inv_p = 1.0f / (float)pixel_rays(c, y_pixel(c, sc, i));
    float o[3] = {pr->ox[i], pr->oy[i], pr->oz[i]}, d[3] = {pr->dx[i], pr->dy[i], pr->dz[i]}, t = pr->tfar[i];
    float l = sqrtf(pm_dot3(d, d));
    for (int k = 0; k < 3; k++)
        d[k] /= l;
    t *= l;
    uint32_t tri = pr->prim[i];
    unsigned depth = 0;
    for (; tri != PM_RAY_MISS; depth++) {
        pm_material_t textured, lobe;
        surf_t v;
        for (int k = 0; k < 3; k++)
            v.p[k] = o[k] + t * d[k], v.wo[k] = -d[k];
        const pm_material_t *m = pm_scene_material_at(s, tri, v.p, &textured);
        uint32_t mi = s->tri_material[tri];
        if (!continues(c, m, mi) || depth >= depth_limit(c, m, mi))
            break;
        const float *ng = c->geom.tri_n + 3 * (size_t)tri;
        float side = pm_dot3(ng, v.wo) >= 0.0f ? 1.0f : -1.0f, *emw = &sc->emw[i];
        float le[3], cos_emit;
        if (pm_lights_le_hit(&c->lights, tri, pm_dot3(ng, v.wo), le, &cos_emit) && *emw > 0.0f)
            for (int k = 0; k < 3; k++)
                direct[3 * x + k] += (double)(le[k] * inv_p * thr[k] * *emw);
        *emw = 0.0f; /* counted: the hit shades no emission of its own */
        float u = pm_rng_float(rng), u1 = pm_rng_float(rng), u2 = pm_rng_float(rng);
        int standard = m->kind == PM_MAT_STANDARD;
        if (standard) {
            float pd, ps;
            pm_bsdf_albedo(m, &pd, &ps);
            if (ps < pd)
                break; /* a mostly diffuse surface: shaded whole */
            lobe = *m;
            lobe.kd[0] = lobe.kd[1] = lobe.kd[2] = 0.0f;
        }
        for (int k = 0; k < 3; k++)
            v.gn[k] = side * ng[k], v.o[k] = v.p[k] + c->eps * v.gn[k];
        v.m = m;
        surf_normals(s, tri, side, &v);
        if (standard && (m->kd[0] > 0.0f || m->kd[1] > 0.0f || m->kd[2] > 0.0f)) {
            pm_material_t diffuse = *m;
            diffuse.ks[0] = diffuse.ks[1] = diffuse.ks[2] = 0.0f;
            v.m = &diffuse;
            if (!shade_diffuse_part(c, sc, &v, x, y_pixel(c, sc, i), thr, light_rng, gather_rng, caus))
                return 0;
        }
        v.m = standard ? &lobe : m;
        if (!shadow_room(c, sc))
            return 0;
        direct_lights(c, sc, &v, x, inv_p, thr, 1.0f, 1.0f, 1, rng, NULL);
        float wi[3], fc[3], pdf;
        int tr = 0;
        if (standard) {
            float f[3];
            if (!pm_bsdf_sample_lobe(&lobe, PM_LOBE_GLOSSY, v.n, v.wo, u1, u2, wi) ||
                (v.shaded && !(pm_dot3(v.gn, wi) > 0.0f)) || !((pdf = pm_bsdf_pdf(&lobe, v.n, wi, v.wo)) > 0.0f)) {
                tri = PM_RAY_MISS, thr[0] = thr[1] = thr[2] = 0.0f;
                break;
            }
            pm_brdf(&lobe, v.n, wi, v.wo, f);
            for (int k = 0; k < 3; k++)
                fc[k] = f[k] * pm_dot3(v.n, wi) / pdf;
        } else {
            pm_bsdf_sample_t bs;
            int ok = pm_bsdf_sample_wi(m, v.bn, v.wo, u, u1, u2, PM_BSDF_RADIANCE, &bs);
            tr = (bs.lobe & PM_BSDF_TRANSMIT) != 0;
            float cg = pm_dot3(v.gn, bs.wi);
            if (!ok || (tr ? !(cg < 0.0f) : (v.shaded && !(cg > 0.0f)))) {
                tri = PM_RAY_MISS, thr[0] = thr[1] = thr[2] = 0.0f;
                break;
            }
            memcpy(wi, bs.wi, sizeof wi), memcpy(fc, bs.weight, sizeof fc);
            pdf = (bs.lobe & PM_BSDF_DELTA) || tr ? -1.0f : bs.pdf;
        }
        for (int k = 0; k < 3; k++) {
            thr[k] *= fc[k];
            o[k] = tr ? v.p[k] - c->eps * v.gn[k] : v.o[k], d[k] = wi[k];
        }
        sc->n_glossy++;
        tri = pm_rt_intersect1(c->rt, ctx, o, d, 0.0f, INFINITY, &t, NULL);
        if (tri == PM_RAY_MISS && pdf >= 0.0f && isfinite(thr[0] + thr[1] + thr[2])) {
            /* the sky past the lobe: shared with its light samples (env_add) */
            float sc3[3] = {thr[0] * inv_p, thr[1] * inv_p, thr[2] * inv_p};
            env_add(c, v.n, d, pdf, sc3, x, direct, (float)c->light_samples);
        }
        if (!(thr[0] > 0.0f || thr[1] > 0.0f || thr[2] > 0.0f) || !isfinite(thr[0] + thr[1] + thr[2]) ||
            (tri == PM_RAY_MISS && pdf >= 0.0f)) {
            tri = PM_RAY_MISS, thr[0] = thr[1] = thr[2] = 0.0f;
            break;
        }
        if (tri == PM_RAY_MISS)
            break;
        *emw = 1.0f;
        if (pm_material_is_specular(&s->materials[s->tri_material[tri]]))
            follow_specular(c, sc, ctx, rng, -1.0f, &tri, o, d, &t, thr); /* its end's light: weight 1 */
        else if (pdf >= 0.0f && pm_lights_has_emitters(&c->lights))
            *emw = pm_power_heuristic(
                pdf, (float)c->light_samples *
                         pm_lights_pdf_li_hit(&c->lights, t, fabsf(pm_dot3(c->geom.tri_n + 3 * (size_t)tri, d))));
    }
    if (depth == 0 && tri != PM_RAY_MISS)
        return 1; /* not passed through: the ray stays the camera's, bit for bit */
    pr->prim[i] = tri;
    pr->ox[i] = o[0], pr->oy[i] = o[1], pr->oz[i] = o[2];
    pr->dx[i] = d[0], pr->dy[i] = d[1], pr->dz[i] = d[2];
    pr->tfar[i] = t;
    return 1;
}

/* The secondary points of every primary ray of pixel `pixel`, stratified together
 * (pm_strata_pixel), into sc->pix_u. 0 when out of memory. */
static int pixel_strata(const pm_eye_t *c, scratch_t *sc, pm_rng_t *gather_rng, uint64_t pixel)
{
    unsigned rays = pixel_rays(c, pixel);
    size_t n = (size_t)rays * c->spp;
    if (!grow((void **)&sc->pix_u, 2 * sizeof(float), &sc->pix_cap, n) ||
        !grow((void **)&sc->pix_perm, sizeof(uint32_t), &sc->pix_perm_cap, rays))
        return 0;
    sc->pix_n = n;
    _Static_assert(PER_CELL == 4, "a cell's points are its 2 x 2 sub-cells");
    pm_strata_pixel(gather_rng, rays, c->spp / PER_CELL, 2, sc->pix_u, sc->pix_u + n, sc->pix_perm);
    return 1;
}

/* The light samples' points of every primary ray of pixel `pixel` (sc->pix_l), from light_rng:
 * per light that is not a delta, its rays * light_samples points as one stratified set
 * (pm_strata_pixel, cells of one point dealt in a random order). 0 when out of memory. */
static int pixel_light_strata(const pm_eye_t *c, scratch_t *sc, pm_rng_t *light_rng, uint64_t pixel)
{
    size_t nl = c->lights.ndirect - c->lights.ndelta, n = (size_t)pixel_rays(c, pixel) * c->light_samples;
    if (!grow((void **)&sc->pix_l, 2 * sizeof(float), &sc->pix_l_cap, nl * n) ||
        !grow((void **)&sc->pix_perm, sizeof(uint32_t), &sc->pix_perm_cap, n))
        return 0;
    sc->pix_ln = n;
    for (size_t l = 0; l < nl; l++)
        pm_strata_pixel(light_rng, (unsigned)n, 1, 1, sc->pix_l + 2 * l * n, sc->pix_l + (2 * l + 1) * n, sc->pix_perm);
    return 1;
}

/* Every primary ray of row y: chains through mirrors and glass, the sky seen, and the hits'
 * shading (shade_primary). 0 when out of memory. */
static int shade_row(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, uint32_t y, double *direct,
                     bytebuf_t *out, bytebuf_t *caus)
{
    pm_rng_t light_rng, gather_rng, spec_rng;
    float spec_xi = 0.0f;                /* the pixel's rotation of its primary rays' first specular choices */
    pm_rng_init(&light_rng, c->seed, 0); /* re-keyed per pixel below */
    pm_rng_init(&gather_rng, c->seed, 0);
    pm_rng_init(&spec_rng, c->seed, 0);
    for (size_t i = 0; i < sc->prim.n; i++) {
        uint32_t x = sc->rx[i];
        uint32_t pixel = y * c->w + x;
        if (sc->rj[i] == 0) {
            pm_rng_init(&light_rng, c->seed, 4 * (uint64_t)pixel + STREAM_LIGHT);
            pm_rng_init(&gather_rng, c->seed, 4 * (uint64_t)pixel + STREAM_GATHER);
            if ((c->sec_strata && !pixel_strata(c, sc, &gather_rng, pixel)) ||
                (c->light_strata && !pixel_light_strata(c, sc, &light_rng, pixel)))
                return 0;
            if (c->specular || c->cont)
                specular_rng(&spec_rng, c->seed, pixel, 0);
            if (c->specular)
                spec_xi = pm_rng_float(&spec_rng);
        }
        sc->blk = c->sec_strata ? (size_t)sc->rj[i] * c->spp : SIZE_MAX;
        sc->lblk = c->light_strata ? (size_t)sc->rj[i] * c->light_samples : SIZE_MAX;
        if (c->specular || c->cont) {
            float *t0 = sc->thr + 3 * i;
            t0[0] = t0[1] = t0[2] = 1.0f; /* the chain's throughput: none yet */
        }
        if (c->specular && sc->prim.prim[i] != PM_RAY_MISS)
            primary_chain(c, sc, ctx, i, &spec_rng, spec_xi);
        if (c->cont) {
            sc->emw[i] = 1.0f;
            if (sc->prim.prim[i] != PM_RAY_MISS &&
                !primary_glossy(c, sc, ctx, i, x, &spec_rng, &light_rng, &gather_rng, direct, caus))
                return 0;
        }
        if (sc->prim.prim[i] == PM_RAY_MISS) {
            /* Escaped, at once or after mirrors and glass: no query; the sky and the sun seen
             * are direct light, times the chain's throughput. */
            float d[3] = {sc->prim.dx[i], sc->prim.dy[i], sc->prim.dz[i]}, le[3];
            const float *thr = c->specular || c->cont ? sc->thr + 3 * i : NULL;
            pm_lights_le_escape(&c->lights, d, le);
            for (int k = 0; k < 3; k++)
                direct[3 * x + k] += (double)(le[k] * (thr ? thr[k] : 1.0f) / (float)pixel_rays(c, pixel));
            continue;
        }
        if (!shade_primary(c, sc, i, x, pixel, &light_rng, &gather_rng, direct, out, caus))
            return 0;
    }
    sc->blk = sc->lblk = SIZE_MAX; /* the secondary hits draw their own */
    return 1;
}

/* Secondary ray j of row y at its hit: the emitter it found (MIS with the primary hit's light
 * samples), the chain through mirrors and glass it starts, the glossy surfaces it continues
 * through, and the query where it ends. in_px is the ray's index among its pixel's, for its
 * sub-stream. 0 when out of memory. */
static int secondary_hit(const pm_eye_t *c, scratch_t *sc, struct RTCIntersectContext *ctx, uint32_t y, size_t j,
                         uint32_t in_px, double *direct, bytebuf_t *out)
{
    const pm_scene_t *s = c->s;
    const pm_rays_t *sr = &sc->sec;
    pm_rng_t rng;
    path_t a = {
        .tri = sr->prim[j], .x = sc->sec_px[j], .pixel = y * c->w + sc->sec_px[j], .t = sr->tfar[j], .rng = &rng};
    float thr[3] = {1.0f, 1.0f, 1.0f}, o[3] = {sr->ox[j], sr->oy[j], sr->oz[j]},
          d[3] = {sr->dx[j], sr->dy[j], sr->dz[j]};
    memcpy(a.o, o, sizeof o);
    memcpy(a.d, d, sizeof d);
    for (int k = 0; k < 3; k++)
        a.w[k] = sc->sec_w[3 * j + k];
    /* sec_cos < 0: a ray no light sample of the primary hit could have drawn (spawn_module) */
    int own = sc->sec_cos[j] < 0.0f;
    if (a.tri == PM_RAY_MISS) {
        if (own)
            path_sky(c, &a, direct);
        else
            env_add(c, sc->sec_env + 4 * j + 1, a.d, sc->sec_env[4 * j], a.w, a.x, direct, (float)c->light_samples);
        return 1; /* escaped: no query */
    }
    if (c->specular || c->cont || c->sec_direct ||
        c->diffuse_depth) /* a sub-stream of its own for each secondary ray's chain */
        specular_rng(&rng, c->seed, a.pixel, 1 + in_px);
    if (c->specular && pm_material_is_specular(&s->materials[s->tri_material[a.tri]])) {
        /* Through mirrors and glass to the first other surface. Light found at the end of such
         * a chain is L S+ D at the primary hit, the caustic queries' (with the caustic map) or
         * lost without them: never counted here, so a direct-only run, which makes no queries,
         * need not follow the chain unless a glossy surface past it may continue. */
        if (!c->past_hit)
            return 1;
        follow_specular(c, sc, ctx, &rng, -1.0f, &a.tri, a.o, a.d, &a.t, thr);
        if (a.tri == PM_RAY_MISS)
            return 1;
    } else {
        /* An emitter's front seen by a secondary ray: direct light of the primary hit, weighted
         * against the light samples that could have found the same point (MIS, power heuristic). */
        const float *ng = c->geom.tri_n + 3 * (size_t)a.tri;
        float cosy = fabsf(pm_dot3(ng, a.d));
        path_emission(c, &a,
                      own ? 1.0f
                          : pm_power_heuristic((float)(c->spp / PER_CELL) * sc->sec_cos[j] * (1.0f / PM_PI),
                                               (float)c->light_samples * pm_lights_pdf_li_hit(&c->lights, a.t, cosy)),
                      direct);
    }
    if (!c->past_hit)
        return 1; /* the direct buffer alone: the query's normal and fold are not needed */
    for (int k = 0; k < 3; k++)
        a.w[k] = sc->sec_w[3 * j + k] * thr[k];
    return follow_path(c, sc, ctx, &a, direct, out);
}

/* Traces row y: direct radiance into direct[0 .. 3w), queries into out and caustic queries into
 * caus, in pixel order. */
static pm_result_t trace_row_body(const pm_eye_t *c, scratch_t *sc, uint32_t y, double *direct, bytebuf_t *out,
                                  bytebuf_t *caus)
{
    size_t np = (size_t)c->w * c->primary;
    if (c->counts) {
        np = 0;
        for (uint32_t x = 0; x < c->w; x++)
            np += c->counts[(uint64_t)y * c->w + x];
    }
    const pm_lights_t *lights = &c->lights;
    size_t nshadow = np * (lights->ndelta + (lights->ndirect - lights->ndelta) * c->light_samples);
    size_t nsec = c->mode == PM_EYE_GATHER ? np * c->spp : 0;
    pm_result_t r = scratch_reserve(sc, y, np, nshadow, nsec, c->mode == PM_EYE_GATHER ? c->spp : 0);
    if (r != PM_OK)
        return r;
    memset(direct, 0, 3 * sizeof(double) * c->w);
    out->n = 0;
    out->count = 0;
    caus->n = 0;
    caus->count = 0;
    struct RTCIntersectContext ctx; /* the specular chains' and glossy paths' single rays */
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;

    sc->row = y;
    cast_primary(c, sc, y);
    sc->shadow.n = 0;
    sc->sec.n = 0;
    if (!shade_row(c, sc, &ctx, y, direct, out, caus))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the queries of row %" PRIu32 ": %" PRIu64 " records", y,
                            out->count + 1);
    shadow_rays(c, sc, direct);

    /* The secondary rays' only part in the direct light is the emitters, the sun and the sky
     * they find (and the light of the glossy paths they continue, and of the gather points). */
    if (c->mode != PM_EYE_GATHER || !c->sec_rays)
        return PM_OK;
    /* Secondary rays: consecutive rays share a cell or a pixel, so packets stay coherent. */
    double t0 = pm_time_wall();
    pm_rays_intersect(c->rt, c->width, 0, &sc->sec);
    sc->t_secondary += pm_time_wall() - t0;
    sc->n_secondary += sc->sec.n;
    /* Room for every ray's records up front (two where a glossy textured hit splits, put_hit):
     * put_query then only stores, unless glossy paths add their diffuse parts. */
    if (!c->direct_only &&
        !grow((void **)&out->p, 1, &out->cap, out->n + sc->sec.n * c->record_size * (c->lobe ? 2 : 1)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the queries of row %" PRIu32 ": %zu records", y,
                            out->count + sc->sec.n);
    uint32_t last_px = UINT32_MAX, in_px = 0;
    for (size_t j = 0; j < sc->sec.n; j++) {
        in_px = sc->sec_px[j] == last_px ? in_px + 1 : 0;
        last_px = sc->sec_px[j];
        if (!secondary_hit(c, sc, &ctx, y, j, in_px, direct, out))
            return pm_error_set(PM_ERR_NOMEM, "out of memory for the queries of row %" PRIu32, y);
    }
    /* The light samples of the glossy paths' vertices. */
    if (sc->shadow.n)
        shadow_rays(c, sc, direct);
    return PM_OK;
}

/* Row y on the calling worker, its CPU time counted; a failure goes into err, so that its
 * message outlives the worker's thread-local one. */
static void trace_row(const pm_eye_t *c, scratch_t *sc, uint32_t y, double *direct, bytebuf_t *out, bytebuf_t *caus,
                      pm_error_slot_t *err)
{
    double t0 = pm_time_thread_cpu();
    pm_result_t r = trace_row_body(c, sc, y, direct, out, caus);
    sc->cpu_rows += pm_time_thread_cpu() - t0;
    if (r != PM_OK)
        pm_error_slot_record(err, y, r);
}

/* ------------------------------------------------------------------ context */

/* The queries' material table of a scene with glossy textured materials (c->lobe, put_hit) or
 * glossy paths (glossy_bounce's diffuse parts):
 * the scene's materials, then `folded` (kd 1: a weight that carries its BRDF), then per such
 * material its lobe alone (kd 0, ks 1, its ns), named NAME.lobe. */
static pm_result_t split_table(pm_eye_t *c)
{
    const pm_scene_t *s = c->s;
    size_t n = s->nmaterials + 1;
    for (size_t m = 0; m < s->nmaterials; m++)
        n += pm_scene_glossy_textured(s, (uint32_t)m) && s->materials[m].kind == PM_MAT_STANDARD;
    if (n > 65536) /* the material channel is 16 bits */
        return pm_error_set(PM_ERR_INPUT,
                            "scene '%s': %zu materials and their glossy textured lobes do not fit the queries' "
                            "65536 material ids",
                            s->path, n);
    c->table = calloc(n, sizeof *c->table);
    c->lobe = calloc(s->nmaterials, sizeof *c->lobe);
    if (!c->table || !c->lobe)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a table of %zu materials", n);
    memcpy(c->table, s->materials, s->nmaterials * sizeof *c->table);
    c->folded = (uint32_t)s->nmaterials;
    c->table[c->folded] = (pm_material_t){.name = "folded", .kd = {1, 1, 1}};
    size_t at = s->nmaterials + 1;
    for (size_t m = 0; m < s->nmaterials; m++)
        if (pm_scene_glossy_textured(s, (uint32_t)m) && s->materials[m].kind == PM_MAT_STANDARD) {
            pm_material_t *e = &c->table[at];
            snprintf(e->name, sizeof e->name, "%.57s.lobe", s->materials[m].name);
            e->ks[0] = e->ks[1] = e->ks[2] = 1.0f;
            e->ns = s->materials[m].ns;
            c->lobe[m] = (uint32_t)at++;
        }
    c->ntable = n;
    return PM_OK;
}

pm_result_t pm_eye_create(const pm_scene_t *s, const pm_rt_t *rt, const pm_eye_options_t *o, pm_eye_t **out)
{
    *out = NULL;
    pm_eye_t *c = calloc(1, sizeof *c);
    if (!c)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the eye tracer's context");
    c->s = s, c->rt = rt;
    c->w = o->width ? o->width : s->camera.width;
    c->h = o->height ? o->height : s->camera.height;
    c->mode = o->mode;
    c->schedule = o->schedule;
    c->primary = o->primary ? o->primary : 1;
    c->counts = o->pixel_primary;
    c->pixel = o->pixel == PM_PIXEL_CENTER ? PM_PIXEL_CENTER : PM_PIXEL_BOX;
    c->light_samples = o->light_samples;
    c->seed = o->seed;
    c->threads = o->threads > 0 ? o->threads : 1;
    c->progress = o->progress;
    c->eps = rt->epsilon;
    c->width = pm_packet_width(rt, o->isa);
    c->specular = s->any_specular;
    c->caustics = o->caustics;
    c->direct_only = o->direct_only;
    c->glossy_depth = o->glossy_depth;
    c->diffuse_depth = o->mode == PM_EYE_GATHER ? o->diffuse_depth : 0;
    c->guide = o->mode == PM_EYE_GATHER ? o->guide : NULL;
    for (size_t m = 0; c->mode == PM_EYE_GATHER && m < s->nmaterials; m++)
        c->cont |= material_continues(&s->materials[m], c->glossy_depth) || varies(s, (uint32_t)m);
    pm_result_t r = PM_OK;
    if (o->caustics && o->direct_only) {
        pm_eye_destroy(c);
        return pm_error_set(PM_ERR_USAGE, "caustic queries are queries: not with the direct light alone");
    }
    if (o->secondary_direct && o->mode != PM_EYE_GATHER) {
        pm_eye_destroy(c);
        return pm_error_set(PM_ERR_USAGE,
                            "secondary direct light is the gather points' (--mode gather): in %s mode "
                            "the primary hits have their direct light already",
                            pm_eye_mode_names[o->mode]);
    }
    if (o->diffuse_depth && o->mode != PM_EYE_GATHER) {
        pm_eye_destroy(c);
        return pm_error_set(PM_ERR_USAGE,
                            "diffuse bounces come before a gather point (--mode gather): in %s mode the "
                            "primary hits are the queries",
                            pm_eye_mode_names[o->mode]);
    }
    if (o->caustics && !s->any_specular)
        r = pm_error_set(PM_ERR_INPUT, "scene '%s' has no mirror or glass: it has no caustic queries", s->path);
    else if (o->caustics && o->mode != PM_EYE_GATHER)
        r = pm_error_set(PM_ERR_USAGE,
                         "caustic queries need --mode gather: in %s mode the queries at the primary hits "
                         "gather caustic photons already",
                         pm_eye_mode_names[o->mode]);
    if (r == PM_OK && c->mode == PM_EYE_GATHER) {
        int64_t spp = o->spp ? (int64_t)o->spp : s->defaults.spp;
        if (spp <= 0 || spp % PER_CELL != 0 || spp > 65536)
            r = pm_error_set(o->spp ? PM_ERR_USAGE : PM_ERR_INPUT,
                             "%s%s%s %" PRId64
                             " is not a positive multiple of %d up to 65536 (%d samples per stratum cell)",
                             o->spp ? "--spp" : "scene '", o->spp ? "" : s->path, o->spp ? "" : "': render.spp", spp,
                             PER_CELL, PER_CELL);
        else {
            c->spp = (unsigned)spp;
            pm_strata_grid(c->spp / PER_CELL, &c->nx, &c->ny);
        }
    }
    /* Channels: leave out what the scene does not need (docs/formats.md). */
    c->has_dir = s->any_glossy;
    /* A glossy path leaves its diffuse parts as queries of the table's folded entry. */
    c->has_mat = s->any_glossy && (s->nmaterials > 1 || s->any_glossy_textured || c->cont);
    uint32_t mask = pm_schema_required(&pm_queries_schema) | (c->has_mat ? 1u << PM_QUERY_MATERIAL : 0) |
                    (c->has_dir ? 1u << PM_QUERY_DIRECTION : 0);
    c->record_size = pm_schema_record_size(&pm_queries_schema, mask);
    c->off_pos = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_POSITION);
    c->off_nor = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_NORMAL);
    c->off_w = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_WEIGHT);
    c->off_pix = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_PIXEL);
    c->off_mat = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_MATERIAL);
    c->off_dir = pm_schema_offset(&pm_queries_schema, mask, PM_QUERY_DIRECTION);

    pm_camera_setup(&s->camera, c->w, c->h, &c->cam);

    if (r == PM_OK && !(c->fold = malloc((s->nmaterials ? s->nmaterials : 1) * 3 * sizeof(float))))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of %zu materials", s->nmaterials);
    for (size_t m = 0; r == PM_OK && m < s->nmaterials; m++) {
        float one[3] = {1.0f, 1.0f, 1.0f};
        query_weight(&s->materials[m], one, c->fold + 3 * m);
    }
    if (r == PM_OK && (s->any_glossy_textured || c->cont))
        r = split_table(c);
    if (r == PM_OK)
        r = pm_shade_geom_init(s, &c->geom);
    if (r == PM_OK)
        r = pm_lights_init(s, &c->lights);
    c->sec_direct = r == PM_OK && o->secondary_direct && c->lights.ndirect > 0;
    for (size_t l = c->lights.ndelta; r == PM_OK && c->mode == PM_EYE_GATHER && l < c->lights.ndirect; l++)
        c->env_mis |= c->lights.direct[l].infinite;
    c->past_hit = !c->direct_only || c->cont || c->sec_direct || c->diffuse_depth;
    c->sec_rays = c->past_hit || (r == PM_OK && pm_lights_has_emitters(&c->lights)) || c->env_mis;
    c->sec_strata = !o->strata_hit && c->mode == PM_EYE_GATHER && c->sec_rays;
    c->light_strata = r == PM_OK && !o->strata_hit && c->light_samples && c->lights.ndirect > c->lights.ndelta;
    if (r != PM_OK) {
        pm_eye_destroy(c);
        return r;
    }
    c->info = (pm_eye_info_t){.mode = c->mode,
                              .width = c->w,
                              .height = c->h,
                              .spp = c->spp,
                              .primary = c->primary,
                              .light_samples = c->light_samples,
                              .pixel = c->pixel,
                              .seed = c->seed,
                              .packet_width = c->width,
                              .channels = mask,
                              .specular = c->specular,
                              .caustics = c->caustics,
                              .glossy_depth = c->cont ? c->glossy_depth : 0,
                              .secondary_direct = o->secondary_direct,
                              .strata_pixel = c->sec_strata || c->light_strata,
                              .diffuse_depth = c->diffuse_depth,
                              .guided = c->guide != NULL,
                              .record_size = c->record_size};
    *out = c;
    return PM_OK;
}

const pm_eye_info_t *pm_eye_info(const pm_eye_t *e) { return &e->info; }

void pm_eye_destroy(pm_eye_t *e)
{
    if (!e)
        return;
    pm_shade_geom_free(&e->geom);
    pm_lights_free(&e->lights);
    free(e->fold);
    free(e->lobe);
    free(e->table);
    free(e);
}

/* ------------------------------------------------------------------ the trace */

/* Band [y0, y0 + nb)'s records and direct rows to the sink, in pixel order: every row's
 * queries, then every row's caustic queries, then the direct rows. */
static pm_result_t deliver_band(const pm_eye_t *c, const pm_eye_sink_t *sink, const bytebuf_t *rows,
                                const bytebuf_t *crows, const double *direct, uint32_t y0, int nb, uint64_t *delivered)
{
    pm_result_t r = PM_OK;
    for (int b = 0; b < nb && r == PM_OK; b++)
        if (rows[b].count) {
            r = sink->queries(sink->user, rows[b].p, rows[b].count);
            *delivered += rows[b].count;
        }
    for (int b = 0; b < nb && r == PM_OK && c->caustics; b++)
        if (crows[b].count)
            r = sink->caustic(sink->user, crows[b].p, crows[b].count);
    if (r == PM_OK && sink->direct)
        r = sink->direct(sink->user, y0, (uint32_t)nb, direct);
    return r;
}

/* The rows of a band go to the threads by c->schedule. */
static void trace_band(const pm_eye_t *c, scratch_t *sc, uint32_t y0, int nb, double *direct, bytebuf_t *rows,
                       bytebuf_t *crows, pm_progress_t *prog, pm_error_slot_t *err)
{
    if (c->schedule == PM_EYE_INTERLEAVE) {
#pragma omp for schedule(static, 1)
        for (int b = 0; b < nb; b++) {
            trace_row(c, sc, y0 + (uint32_t)b, direct + (size_t)b * c->w * 3, &rows[b], &crows[b], err);
            pm_progress_add(prog, 1);
        }
    } else if (c->schedule == PM_EYE_TILES) {
#pragma omp for schedule(static)
        for (int b = 0; b < nb; b++) {
            trace_row(c, sc, y0 + (uint32_t)b, direct + (size_t)b * c->w * 3, &rows[b], &crows[b], err);
            pm_progress_add(prog, 1);
        }
    } else {
#pragma omp for schedule(dynamic, 1)
        for (int b = 0; b < nb; b++) {
            trace_row(c, sc, y0 + (uint32_t)b, direct + (size_t)b * c->w * 3, &rows[b], &crows[b], err);
            pm_progress_add(prog, 1);
        }
    }
}

pm_result_t pm_eye_trace(pm_eye_t *c, const pm_eye_sink_t *sink, pm_eye_stats_t *stats_out)
{
    memset(stats_out, 0, sizeof *stats_out);
    int nthreads = c->threads;
    pm_result_t r = PM_OK;
    scratch_t *scr = aligned_alloc(64, (size_t)nthreads * sizeof *scr);
    uint32_t band = c->h < BAND_ROWS ? c->h : BAND_ROWS;
    /* Two bands' buffers: the sink takes one band's records on one thread while the others
     * trace the next band into the other set (the sink's copying was 12 to 14% of the
     * tracer's wall, the cores idle but for it). */
    double *direct[2] = {malloc(((size_t)band * c->w * 3 + 1) * sizeof(double)),
                         malloc(((size_t)band * c->w * 3 + 1) * sizeof(double))};
    bytebuf_t rows[2][BAND_ROWS], crows[2][BAND_ROWS]; /* a row's queries and caustic queries */
    memset(rows, 0, sizeof rows);
    memset(crows, 0, sizeof crows);
    if (scr)
        memset(scr, 0, (size_t)nthreads * sizeof *scr);
    if (!scr || !direct[0] || !direct[1])
        r = pm_error_set(PM_ERR_NOMEM,
                         "out of memory for %d threads' buffers and %" PRIu32 " rows of %" PRIu32 " pixels", nthreads,
                         2 * band, c->w);

    pm_progress_t prog;
    pm_progress_begin(&prog, "rows", c->h, c->progress);
    double t0 = pm_time_wall(), t_sink = 0.0, t_last = 0.0;
    uint64_t delivered = 0;
    int cur = 0, prev_nb = 0; /* the band being traced, the one before it (0: none left to deliver) */
    int team = 1;             /* threads OpenMP gave a region that delivered (it may give fewer than asked) */
    uint32_t prev_y0 = 0;
    for (uint32_t y0 = 0; y0 < c->h && r == PM_OK; y0 += BAND_ROWS) {
        int nb = (int)(c->h - y0 < BAND_ROWS ? c->h - y0 : BAND_ROWS);
        /* A row that fails on a worker records its message here; the lowest row's wins. The
         * sink's failure (on whichever thread delivered) has its own slot: it is of the band
         * before, so it comes first. */
        pm_error_slot_t err, sink_err;
        pm_error_slot_init(&err);
        pm_error_slot_init(&sink_err);
#pragma omp parallel num_threads(nthreads)
        {
            pm_cpu_set_ftz_daz(); /* per thread: MXCSR is not inherited by OpenMP workers */
            scratch_t *sc = &scr[omp_get_thread_num()];
            /* The team's last thread delivers (a worker whenever there are two or more), then
             * takes what rows are left; no barrier between, so the others trace meanwhile. */
            if (prev_nb && omp_get_thread_num() == omp_get_num_threads() - 1) {
                double t1 = pm_time_wall();
                pm_result_t rs =
                    deliver_band(c, sink, rows[cur ^ 1], crows[cur ^ 1], direct[cur ^ 1], prev_y0, prev_nb, &delivered);
                if (rs != PM_OK)
                    pm_error_slot_record(&sink_err, 0, rs);
                t_sink += pm_time_wall() - t1;
                team = omp_get_num_threads();
            }
            trace_band(c, sc, y0, nb, direct[cur], rows[cur], crows[cur], &prog, &err);
        }
        r = pm_error_slot_raise(&sink_err);
        if (r == PM_OK)
            r = pm_error_slot_raise(&err);
        prev_nb = nb, prev_y0 = y0;
        cur ^= 1;
    }
    if (r == PM_OK && prev_nb) { /* the last band, with nothing left to trace beside it */
        double t1 = pm_time_wall();
        r = deliver_band(c, sink, rows[cur ^ 1], crows[cur ^ 1], direct[cur ^ 1], prev_y0, prev_nb, &delivered);
        t_last = pm_time_wall() - t1;
        t_sink += t_last;
    }
    /* Ray throughput is measured without the deliveries no tracing hid: the last band's, and on
     * one thread every band's (on more, the others traced beside them, which is in trace_s). */
    stats_out->sink_alone_s = team > 1 ? t_last : t_sink;
    stats_out->trace_s = pm_time_wall() - t0 - stats_out->sink_alone_s;
    stats_out->sink_s = t_sink;
    pm_progress_end(&prog);

    for (int t = 0; t < nthreads && scr; t++) {
        stats_out->trace_cpu_s += scr[t].cpu_rows;
        stats_out->primary_rays += scr[t].n_primary;
        stats_out->secondary_rays += scr[t].n_secondary;
        stats_out->shadow_rays += scr[t].n_shadow;
        stats_out->queries += scr[t].n_queries;
        stats_out->caustic_queries += scr[t].n_caustic;
        stats_out->specular_rays += scr[t].n_specular;
        stats_out->specular_cut += scr[t].n_specular_cut;
        stats_out->glossy_rays += scr[t].n_glossy;
        stats_out->guided_hits += scr[t].n_guided_hits;
        stats_out->guided_rays += scr[t].n_guided_rays;
        stats_out->secondary_embree_s += scr[t].t_secondary;
    }
    if (r == PM_OK && stats_out->queries != delivered)
        r = pm_error_set(PM_ERR_INTERNAL, "counted %" PRIu64 " queries but delivered %" PRIu64, stats_out->queries,
                         delivered);
    for (int t = 0; t < nthreads && scr; t++)
        scratch_free(&scr[t]);
    for (int k = 0; k < 2; k++)
        for (int b = 0; b < BAND_ROWS; b++)
            free(rows[k][b].p), free(crows[k][b].p);
    free(scr);
    free(direct[0]);
    free(direct[1]);
    return r;
}

/* ------------------------------------------------------------------ headers */

/* Provenance and format keys shared by both outputs. */
static pm_result_t header_common(const pm_eye_t *c, int argc, char **argv, pm_header_t *h)
{
    pm_result_t r = pm_image_header_begin(h, argc, argv, c->s, c->w, c->h);
    if (r == PM_OK)
        r = pm_header_set(h, "mode", "%s", pm_eye_mode_names[c->mode]);
    if (r == PM_OK && c->mode == PM_EYE_GATHER)
        r = pm_header_set(h, "spp", "%u", c->spp);
    if (r == PM_OK)
        r = pm_header_set(h, "primary", "%u", c->primary);
    if (r == PM_OK)
        r = pm_header_set(h, "pixel", "%s", pm_pixel_names[c->pixel]);
    if (r == PM_OK)
        r = pm_header_set(h, "seed", "%" PRIu64, c->seed);
    if (r == PM_OK && c->info.secondary_direct) /* absent otherwise: files as they were before */
        r = pm_header_set(h, "secondary_direct", "%d", pm_light_gather_rule(c->s));
    if (r == PM_OK && c->diffuse_depth) /* absent otherwise: files as they were before */
        r = pm_header_set(h, "diffuse_depth", "%u", c->diffuse_depth);
    if (r == PM_OK && c->info.strata_pixel) /* absent otherwise: files as they were before */
        r = pm_header_set(h, "strata", "pixel");
    if (r == PM_OK && c->guide) /* which photons: the stage's INPUT line */
        r = pm_header_set(h, "guide", "photons");
    return r;
}

pm_result_t pm_eye_queries_header(const pm_eye_t *c, int argc, char **argv, uint64_t count, pm_header_t *h)
{
    const pm_scene_t *s = c->s;
    pm_header_init(h, &pm_queries_schema);
    h->count = count;
    h->channels = c->info.channels;
    pm_result_t r = header_common(c, argc, argv, h);
    char id[256]; /* the queries read no point light: a light move keeps them (docs/formats.md, SCENE) */
    pm_scene_id_part(s, PM_SCENE_VIEW, id, sizeof id);
    if (r == PM_OK)
        r = pm_header_set(h, "SCENE", "%s", id);
    if (r == PM_OK && c->table) {
        r = pm_queries_set_materials(h, c->table, c->ntable); /* the glossy textured lobes after the scene's */
    } else if (r == PM_OK && s->any_glossy) {
        r = pm_queries_set_materials(h, s->materials, s->nmaterials);
    } else if (r == PM_OK) {
        /* No glossy material: every query has its BRDF in its weight (docs/formats.md). */
        pm_material_t folded = {.name = "folded", .kd = {1, 1, 1}};
        r = pm_queries_set_materials(h, &folded, 1);
    }
    if (r == PM_OK)
        r = pm_header_set(h, "weights", "lambertian-brdf-folded");
    /* The scene's suggestions for the stages that read this file and not the scene: the
     * gathers' kernel width and hilbert-sort's leaf (docs/formats.md 3.3). */
    if (r == PM_OK)
        r = pm_header_set(h, "render.k", "%" PRId64, s->defaults.k);
    if (r == PM_OK)
        r = pm_header_set(h, "render.radius", "%.9g", s->defaults.radius);
    if (r == PM_OK)
        r = pm_header_set(h, "render.leaf", "%" PRId64, s->defaults.leaf);
    return r;
}

pm_result_t pm_eye_direct_header(const pm_eye_t *c, int argc, char **argv, pm_header_t *h)
{
    pm_header_init(h, &pm_radiance_schema);
    h->count = (uint64_t)c->w * c->h;
    h->channels = pm_schema_required(&pm_radiance_schema);
    pm_result_t r = header_common(c, argc, argv, h);
    if (r == PM_OK)
        r = pm_header_set(h, "component", "direct");
    if (r == PM_OK)
        r = pm_header_set(h, "light_samples", "%u", c->light_samples);
    return r;
}

void pm_eye_report(pm_stage_t *st, const pm_eye_info_t *in, const pm_eye_stats_t *x, int schedule, int spilled,
                   pm_isa_t isa)
{
    uint64_t rays = x->primary_rays + x->secondary_rays + x->shadow_rays;
    double tt = x->trace_s, tc = x->trace_cpu_s, te = x->secondary_embree_s;
    pm_stage_stat_string(st, "mode", pm_eye_mode_names[in->mode]);
    pm_stage_stat_string(st, "isa", pm_isa_name(isa));
    pm_stage_stat_int(st, "packet_width", in->packet_width);
    pm_stage_stat_string(st, "schedule", pm_eye_schedule_names[schedule]);
    pm_stage_stat_int(st, "width", in->width);
    pm_stage_stat_int(st, "height", in->height);
    pm_stage_stat_int(st, "spp", in->spp);
    pm_stage_stat_int(st, "primary", in->primary);
    pm_stage_stat_string(st, "pixel", pm_pixel_names[in->pixel]);
    pm_stage_stat_int(st, "light_samples", in->light_samples);
    pm_stage_stat_int(st, "seed", (int64_t)in->seed);
    pm_stage_stat_int(st, "primary_rays", (int64_t)x->primary_rays);
    pm_stage_stat_int(st, "secondary_rays", (int64_t)x->secondary_rays);
    pm_stage_stat_int(st, "shadow_rays", (int64_t)x->shadow_rays);
    pm_stage_stat_int(st, "queries", (int64_t)x->queries);
    pm_stage_stat_int(st, "spooled_to_file", spilled);
    if (in->specular) {
        pm_stage_stat_int(st, "specular_rays", (int64_t)x->specular_rays);
        pm_stage_stat_int(st, "specular_chains_cut", (int64_t)x->specular_cut);
    }
    if (in->caustics)
        pm_stage_stat_int(st, "caustic_queries", (int64_t)x->caustic_queries);
    if (in->glossy_depth)
        pm_stage_stat_int(st, "glossy_rays", (int64_t)x->glossy_rays);
    if (in->secondary_direct)
        pm_stage_stat_int(st, "secondary_direct", 1);
    if (in->guided) {
        pm_stage_stat_int(st, "guided_hits", (int64_t)x->guided_hits);
        pm_stage_stat_int(st, "guided_rays", (int64_t)x->guided_rays);
    }
    pm_stage_stat_double(st, "trace_s", tt);
    pm_stage_stat_double(st, "spool_s", x->sink_s);
    pm_stage_stat_double(st, "spool_alone_s", x->sink_alone_s);
    pm_stage_stat_double(st, "rays_per_s", tt > 0 ? (double)rays / tt : 0.0);
    pm_stage_stat_double(st, "secondary_rays_per_s", tt > 0 ? (double)x->secondary_rays / tt : 0.0);
    pm_stage_stat_double(st, "trace_cpu_s", tc);
    pm_stage_stat_double(st, "secondary_rays_per_cpu_s", tc > 0 ? (double)x->secondary_rays / tc : 0.0);
    pm_stage_stat_double(st, "secondary_embree_s", te);
    pm_stage_stat_double(st, "secondary_embree_rays_per_core_s", te > 0 ? (double)x->secondary_rays / te : 0.0);
    st->items = x->queries;
    if (in->caustics)
        pm_stage_note(st, "%" PRIu64 " caustic queries, %" PRIu64 " rays through mirrors and glass", x->caustic_queries,
                      x->specular_rays);
    pm_stage_note(st,
                  "%" PRIu64 " primary, %" PRIu64 " secondary, %" PRIu64 " shadow rays in %.3f s (%.2f Mrays/s, %s "
                  "packets of %d); %" PRIu64 " queries",
                  x->primary_rays, x->secondary_rays, x->shadow_rays, tt, tt > 0 ? 1e-6 * (double)rays / tt : 0.0,
                  pm_isa_name(isa), in->packet_width, x->queries);
}
