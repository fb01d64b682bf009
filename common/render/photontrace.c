/* photontrace.c: photons from the lights through the scene, stored where they land.
 *
 * Work is split into chunks of consecutive photon indices; a chunk's photons go into the
 * chunk's own buffer, and the buffers are joined in chunk order, so which thread traced a
 * chunk never shows in the output. Path state (power) is in double: a photon of a 1e20 W
 * light or one that has bounced a thousand times keeps its digits until it is stored. */
#include "render/photontrace.h"

#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/memory.h"
#include "base/progress.h"
#include "base/timer.h"
#include "formats/formats.h"
#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "render/light.h"
#include "render/transport.h"

/* Photons per chunk: large enough that the per-chunk bookkeeping vanishes, small enough
 * that two threads stay balanced on 100,000 photons. */
enum { CHUNK = 2048 };

/* A thread's storage: big blocks (huge pages, see memory.h) that chunks append to, so
 * that storing a photon neither reallocates nor copies, and first-touch page faults come
 * 2 MiB at a time. A chunk's records stay contiguous: a chunk that outgrows its block
 * moves, with the records it has so far, to a fresh block. */
/* Arenas and chunks are written on every stored photon and every ray by the thread that
 * owns them: each starts on a cache line of its own, or two threads writing neighbours
 * pass the line back and forth (measured: two threads used 1.8 times the CPU of one). */
struct pm_trace_arena {
    _Alignas(64) unsigned char **blocks;
    size_t nblocks;
    unsigned char *cur;
    size_t used, cap; /* bytes of the current block */
};

/* bytes: an arena's first block at most, and at least (a small pass's first block is sized to
 * its photons: a TIME budget's first pass of 4,688 photons stored 190 KB and populated two
 * 16-MiB blocks, which took its trace from 0.002 s to 0.035 s) */
enum { ARENA_BLOCK = 16 << 20, ARENA_BLOCK_MIN = 64 << 10 };

/* One output of a chunk: its records, contiguous inside its arena's current block. */
typedef struct {
    pm_trace_arena_t *arena;
    unsigned char *buf;
    size_t n; /* photons stored */
} run_t;

/* The outputs of a chunk: every stored photon, and the caustic photons (L S+ D). */
enum { OUT_GLOBAL = 0, OUT_CAUSTIC = 1, NOUT = 2, OUT_DROP = 3 /* a first hit counted, not stored */ };

typedef struct {
    _Alignas(64) run_t out[NOUT];
    float *rays;
    size_t nrays, rays_cap;
    uint64_t rays_traced, escaped, absorbed, capped, first, longest, specular, portal_back;
    double power_emitted[3], power_first[3], power_caustic[3];
    int failed;
} chunk_t;

typedef struct {
    const pm_scene_t *s;
    const pm_rt_t *rt;
    const pm_trace_options_t *o;
    pm_lights_t lights; /* chosen in proportion to power (render/light.h) */
    uint32_t rs, off_pos, off_pow, off_nor, off_dir, off_depth;
} tracer_t;

/* The bytes the arenas of the running trace hold, and the most they may: the physical memory,
 * so that a photon count too large for the machine ends in an out-of-memory error (exit 3)
 * instead of the OOM killer. One trace runs at a time in a process. */
static size_t arena_bytes, arena_budget;
/* The running trace's first block: room for twice the records its photons would store on
 * one thread at one record a path, ARENA_BLOCK_MIN to ARENA_BLOCK. */
static size_t arena_first = ARENA_BLOCK;

/* This machine's physical memory, bytes (SIZE_MAX when unknown). */
static size_t physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || page <= 0)
        return SIZE_MAX;
    return (double)pages * (double)page >= (double)SIZE_MAX ? SIZE_MAX : (size_t)pages * (size_t)page;
}

/* Room for one more record of rs bytes at the end of run c. */
static int run_reserve(run_t *c, size_t rs)
{
    pm_trace_arena_t *a = c->arena;
    if (a->used + rs <= a->cap)
        return 0;
    size_t have = c->n * rs, cap = arena_first;
    while (cap < 2 * (have + rs))
        cap *= 2;
    if (__atomic_add_fetch(&arena_bytes, cap, __ATOMIC_RELAXED) > arena_budget)
        return -1;
    unsigned char **bl = realloc(a->blocks, (a->nblocks + 1) * sizeof *bl);
    if (!bl)
        return -1;
    a->blocks = bl;
    unsigned char *b = pm_alloc_aligned(cap);
    if (!b)
        return -1;
    if (have)
        memcpy(b, c->buf, have);
    a->blocks[a->nblocks++] = b;
    a->cur = b;
    a->cap = cap;
    a->used = have;
    c->buf = b;
    return 0;
}

static int keep_ray(chunk_t *c, const float o[3], const float d[3], float tnear)
{
    if (c->nrays == c->rays_cap) {
        size_t cap = c->rays_cap ? 2 * c->rays_cap : 4 * CHUNK;
        float *p = realloc(c->rays, cap * 7 * sizeof *p);
        if (!p)
            return -1;
        c->rays = p;
        c->rays_cap = cap;
    }
    float *p = &c->rays[7 * c->nrays++];
    p[0] = o[0], p[1] = o[1], p[2] = o[2];
    p[3] = d[0], p[4] = d[1], p[5] = d[2], p[6] = tnear;
    return 0;
}

/* A photon at p (m) of `power` (W) on the side n faces, arrived from direction back, into
 * output `which` of chunk c (OUT_DROP: a first hit only counted, pm_trace_options_t's
 * indirect_only). */
static void store_photon(const tracer_t *t, chunk_t *c, int which, const float p[3], const double power[3],
                         const float n[3], const float back[3], uint32_t depth)
{
    if (which == OUT_DROP) {
        c->first++;
        for (int k = 0; k < 3; k++)
            c->power_first[k] += (float)power[k];
        return;
    }
    run_t *run = &c->out[which];
    if (run_reserve(run, t->rs) != 0) {
        c->failed = 1;
        return;
    }
    unsigned char *rec = run->buf + run->n++ * t->rs;
    run->arena->used += t->rs;
    float pw[3] = {(float)power[0], (float)power[1], (float)power[2]};
    memcpy(rec + t->off_pos, p, 12);
    memcpy(rec + t->off_pow, pw, 12);
    memcpy(rec + t->off_nor, n, 12);
    if (t->o->direction)
        memcpy(rec + t->off_dir, back, 12);
    memcpy(rec + t->off_depth, &depth, 4);
    if (which == OUT_CAUSTIC) {
        for (int k = 0; k < 3; k++)
            c->power_caustic[k] += pw[k];
        return;
    }
    if (depth == 0) {
        c->first++;
        for (int k = 0; k < 3; k++)
            c->power_first[k] += pw[k];
    }
}

/* A photon at a mirror or glass (unit mesh normal ng, either side): the delta BSDF gives the
 * new direction and its weight (pm_specular_sample; photons carry power, so no 1 / eta^2),
 * Russian roulette on that weight as at the other bounces (survive with min(max weight,
 * rr_max), power divided by it), and the photon leaves from the side its new direction points
 * to. Nothing is stored on a specular surface: its BSDF is a delta, which no density estimate
 * can use. Returns 0 when the path ends here. */
static int specular_bounce(const tracer_t *t, chunk_t *c, const pm_material_t *m, pm_rng_t *rng, const float p[3],
                           const float ng[3], const float wo[3], uint32_t depth, double power[3], float org[3],
                           float dir[3])
{
    c->specular++;
    if (depth + 1 >= t->o->max_bounces) {
        c->capped++;
        return 0;
    }
    float wt[3], u = pm_rng_float(rng), v = pm_rng_float(rng);
    if (pm_specular_sample(m, ng, wo, u, 0, dir, wt) < 0) {
        c->absorbed++;
        return 0;
    }
    float q = fminf(fmaxf(wt[0], fmaxf(wt[1], wt[2])), (float)t->o->rr_max);
    if (!(v < q)) {
        c->absorbed++;
        return 0;
    }
    for (int k = 0; k < 3; k++)
        power[k] *= (double)wt[k] / q;
    float side = pm_dot3(ng, dir) >= 0.0f ? t->rt->epsilon : -t->rt->epsilon;
    for (int k = 0; k < 3; k++)
        org[k] = p[k] + side * ng[k];
    return 1;
}

/* A photon at a non-delta material other than the standard one (conductor, plastic, rough glass):
 * a direction from the BSDF's own sampler in importance mode (physics/bsdf.h: photons carry
 * power, so a transmission is not scaled by 1 / eta^2), about the normal nb (the front
 * geometric normal for rough glass, whose side tells inside from outside; the shading normal on
 * the photon's side otherwise); Russian roulette on the sample's weight, f |nb.wi| / pdf,
 * survival min(max weight, rr_max), power divided by it; the photon leaves from the side of the
 * geometric normal ng its new direction points to. Returns 0 when the path ends here. */
static int rough_bounce(const tracer_t *t, chunk_t *c, const pm_material_t *m, pm_rng_t *rng, const float p[3],
                        const float ng[3], const float nb[3], const float wo[3], uint32_t depth, double power[3],
                        float org[3], float dir[3])
{
    if (depth + 1 >= t->o->max_bounces) {
        c->capped++;
        return 0;
    }
    float u = pm_rng_float(rng), u1 = pm_rng_float(rng), u2 = pm_rng_float(rng), v = pm_rng_float(rng);
    pm_bsdf_sample_t bs;
    if (!pm_bsdf_sample_wi(m, nb, wo, u, u1, u2, PM_BSDF_IMPORTANCE, &bs)) {
        c->absorbed++;
        return 0;
    }
    float q = fminf(fmaxf(bs.weight[0], fmaxf(bs.weight[1], bs.weight[2])), (float)t->o->rr_max);
    if (!(v < q)) {
        c->absorbed++;
        return 0;
    }
    for (int k = 0; k < 3; k++)
        power[k] *= (double)bs.weight[k] / q, dir[k] = bs.wi[k];
    float side = pm_dot3(ng, dir) >= 0.0f ? t->rt->epsilon : -t->rt->epsilon;
    for (int k = 0; k < 3; k++)
        org[k] = p[k] + side * ng[k];
    return 1;
}

/* Traces photon `index` into chunk c. */
static void trace_one(const tracer_t *t, chunk_t *c, uint64_t index, struct RTCIntersectContext *ctx)
{
    const pm_scene_t *s = t->s;
    const float eps = t->rt->epsilon;
    pm_rng_t rng;
    pm_rng_init(&rng, t->o->seed, index);

    /* Emission: a light by power, then a point and a direction on it (render/light.h). */
    const pm_light_t *l = &t->lights.light[pm_lights_pick(&t->lights, pm_rng_double(&rng))];
    double power[3], flux[3];
    float org[3], dir[3];
    float u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng), u3 = pm_rng_float(&rng), u4 = pm_rng_float(&rng);
    pm_light_sample_le(&t->lights, l, u1, u2, u3, u4, eps, org, dir, flux);
    /* Flux of one photon: the light's power over the probability of picking it and the
     * number of photons, so that summing all photons gives the lights' total power. */
    double scale = t->lights.total / (l->weight * (double)t->o->photons);
    for (int k = 0; k < 3; k++) {
        power[k] = flux[k] * scale; /* a map's photons differ by direction */
        c->power_emitted[k] += power[k];
    }
    if (!(flux[0] > 0.0 || flux[1] > 0.0 || flux[2] > 0.0) && s->nportals) {
        c->portal_back++; /* would cross a portal outward: carries nothing, emitted but not traced */
        return;
    }

    /* spec_only: no diffuse or glossy bounce since the light; caustic: that, and at least one
     * specular bounce (the path so far is L S+, so a photon stored next is a caustic one). */
    int spec_only = 1, caustic = 0;
    float org0[3] = {org[0], org[1], org[2]}; /* where it left the light (pm_light_at_gather) */
    for (uint32_t depth = 0;; depth++) {
        if (t->o->record_rays && keep_ray(c, org, dir, 0.0f) != 0) {
            c->failed = 1;
            return;
        }
        float tfar, ng[3];
        uint32_t hit = pm_rt_intersect1(t->rt, ctx, org, dir, 0.0f, INFINITY, &tfar, ng);
        c->rays_traced++;
        if (depth > c->longest)
            c->longest = depth;
        if (hit == PM_RAY_MISS) {
            c->escaped++;
            return;
        }
        float p[3], n[3], wo[3] = {-dir[0], -dir[1], -dir[2]};
        pm_v3_store(p, pm_v3_add(pm_v3_load(org), pm_v3_scale(pm_v3_load(dir), tfar)));
        pm_v3_store(n, pm_v3_normalize(pm_v3_load(ng)));
        /* the material with its textures at p (render/scene.h): a map_Kd scales a PBR metal's F0 */
        pm_material_t textured;
        const pm_material_t *m = pm_scene_material_at(s, hit, p, &textured);
        if (pm_material_is_specular(m)) {
            if (!specular_bounce(t, c, m, &rng, p, n, wo, depth, power, org, dir))
                return;
            caustic = spec_only;
            continue;
        }
        if (pm_bsdf_transmits(m)) {
            /* Rough glass: no photon stored (pm_bsdf_stores_photons), a glossy bounce. */
            if (!rough_bounce(t, c, m, &rng, p, n, n, wo, depth, power, org, dir))
                return;
            spec_only = caustic = 0;
            continue;
        }
        if (pm_dot3(n, dir) > 0.0f) /* the side the photon arrived from */
            pm_v3_store(n, pm_v3_scale(pm_v3_load(n), -1.0f));
        /* Shading normals (render/transport.h, pm_shading_adjoint): the photon's power becomes
         * what the shading normal's cosine makes of it, ns.wo / ng.wo, so that a density
         * estimate and an eye ray's direct light agree; it is stored with ns, the normal the
         * gather tests it against, and bounces about ns. */
        float ns[3];
        int shaded = pm_scene_shading_normal(s, hit, p, n, ns);
        if (shaded && !pm_shading_adjoint(n, ns, wo, power)) {
            c->absorbed++; /* arrived from below the shading surface: reflects nothing */
            return;
        }
        float pd, ps;
        pm_bsdf_albedo(m, &pd, &ps);
        if (pm_material_keeps_photons(m)) {
            /* indirect_only: a first hit whose light the gather points' light samples bring */
            int drop = depth == 0 && t->o->indirect_only &&
                       pm_light_at_gather(&t->lights, l,
                                          (p[0] - org0[0]) * (p[0] - org0[0]) + (p[1] - org0[1]) * (p[1] - org0[1]) +
                                              (p[2] - org0[2]) * (p[2] - org0[2]));
            store_photon(t, c, drop ? OUT_DROP : OUT_GLOBAL, p, power, ns, wo, depth);
            if (caustic && t->o->caustics)
                store_photon(t, c, OUT_CAUSTIC, p, power, ns, wo, depth);
        }
        spec_only = caustic = 0;
        if (c->failed)
            return;
        if (depth + 1 >= t->o->max_bounces) {
            c->capped++;
            return;
        }
        if (m->kind != PM_MAT_STANDARD) {
            /* Conductor, plastic: the BSDF's own sampler, roulette on its weight, about ns. */
            if (!rough_bounce(t, c, m, &rng, p, n, ns, wo, depth, power, org, dir))
                return;
            if (shaded && !pm_shading_leave(n, ns, dir, power)) {
                c->absorbed++; /* below the geometric surface: not taken (no light leaks through) */
                return;
            }
            continue;
        }
        /* Russian roulette: survive with q = min(albedo, rr_max), reflecting diffusely
         * with probability pd' and glossily with ps' (pd' + ps' = q), and divide the
         * power by the probability of the branch taken. With q = albedo (rr_max 1, the
         * default) a grey photon's power stays as it was; a cap below albedo^2 lets the
         * power grow faster than survival falls, and the variance has no bound. */
        float q = pd + ps;
        if (q <= 0.0f) {
            c->absorbed++;
            return;
        }
        float qs = fminf(q, (float)t->o->rr_max) / q;
        float pdq = pd * qs, psq = ps * qs;
        float u = pm_rng_float(&rng), v1 = pm_rng_float(&rng), v2 = pm_rng_float(&rng);
        if (u < pdq) {
            /* f cos / pdf of the diffuse lobe is kd; a cosine sample is above the surface up to
             * rounding and is kept as drawn. */
            pm_bsdf_sample_lobe(m, PM_LOBE_DIFFUSE, ns, wo, v1, v2, dir);
            for (int k = 0; k < 3; k++)
                power[k] *= (double)m->kd[k] / pdq;
        } else if (u < pdq + psq) {
            if (!pm_bsdf_sample_lobe(m, PM_LOBE_GLOSSY, ns, wo, v1, v2, dir)) {
                c->absorbed++; /* below the surface: the lobe's energy loss */
                return;
            }
            double w = pm_bsdf_standard_phong_weight(m, pm_dot3(dir, ns)) / psq;
            for (int k = 0; k < 3; k++)
                power[k] *= m->ks[k] * w;
        } else {
            c->absorbed++;
            return;
        }
        if (shaded && !pm_shading_leave(n, ns, dir, power)) {
            c->absorbed++; /* below the geometric surface: not taken (no light leaks through) */
            return;
        }
        pm_v3_store(org, pm_v3_add(pm_v3_load(p), pm_v3_scale(pm_v3_load(n), eps)));
    }
}

pm_result_t pm_trace_photons(const pm_scene_t *s, const pm_rt_t *rt, const pm_trace_options_t *o,
                             pm_trace_result_t *out)
{
    memset(out, 0, sizeof *out);
    if (o->photons == 0)
        return pm_error_set(PM_ERR_USAGE, "--photons must be at least 1");
    tracer_t t = {.s = s, .rt = rt, .o = o};
    pm_result_t res = pm_lights_init(s, &t.lights);
    if (res != PM_OK)
        return res;
    if (t.lights.n == 0)
        res = pm_error_set(PM_ERR_INPUT, "scene '%s' has no light with positive power: no photons to trace", s->name);
    else if (!isfinite(t.lights.total))
        res =
            pm_error_set(PM_ERR_INPUT, "scene '%s': the lights' total power overflows (%g W)", s->name, t.lights.total);
    /* The largest and smallest channel a photon can start with must fit an f32. */
    for (size_t i = 0; res == PM_OK && i < t.lights.n; i++)
        for (int k = 0; k < 3; k++) {
            const pm_light_t *l = &t.lights.light[i];
            double p = l->power[k] * t.lights.total / (l->weight * (double)o->photons);
            if (p > 1e37)
                res = pm_error_set(PM_ERR_INPUT,
                                   "scene '%s': photons of %g W do not fit the f32 powers of the photons file; "
                                   "emit more photons or scale the lights (%g W in all)",
                                   s->name, p, t.lights.total);
        }
    uint64_t nchunks = (o->photons + CHUNK - 1) / CHUNK;
    /* Every photon is kept in memory until the file is written: a count whose chunk table and
     * one stored record a path (a closed scene stores at least that) exceed the physical memory
     * cannot finish; say so now rather than after hours of tracing. */
    size_t phys = physical_memory();
    uint32_t rs_min = pm_schema_record_size(&pm_photons_schema, pm_schema_required(&pm_photons_schema));
    double need = (double)nchunks * sizeof(chunk_t) + (double)o->photons * rs_min;
    if (res == PM_OK && need > (double)phys)
        res = pm_error_set(PM_ERR_NOMEM,
                           "%" PRIu64 " photons need at least %.3g GB (a %u-byte record a path, kept in memory until "
                           "written), more than this machine's %.3g GB of physical memory: trace fewer, or split "
                           "them into progressive passes",
                           o->photons, need / 1e9, rs_min, (double)phys / 1e9);
    arena_bytes = 0;
    arena_budget = phys;
    chunk_t *chunks = res == PM_OK ? aligned_alloc(64, nchunks * sizeof *chunks) : NULL;
    if (chunks)
        memset(chunks, 0, nchunks * sizeof *chunks);
    if (res == PM_OK && !chunks)
        res = pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " photon chunks", nchunks);
    if (res != PM_OK) {
        pm_lights_free(&t.lights);
        return res;
    }
    out->channels = pm_schema_required(&pm_photons_schema) | (o->direction ? 1u << PM_PHOTON_DIRECTION : 0u);
    t.rs = out->record_size = pm_schema_record_size(&pm_photons_schema, out->channels);
    t.off_pos = pm_schema_offset(&pm_photons_schema, out->channels, PM_PHOTON_POSITION);
    t.off_pow = pm_schema_offset(&pm_photons_schema, out->channels, PM_PHOTON_POWER);
    t.off_nor = pm_schema_offset(&pm_photons_schema, out->channels, PM_PHOTON_NORMAL);
    t.off_dir = pm_schema_offset(&pm_photons_schema, out->channels, PM_PHOTON_DIRECTION);
    t.off_depth = pm_schema_offset(&pm_photons_schema, out->channels, PM_PHOTON_DEPTH);

    pm_progress_t prog;
    pm_progress_begin(&prog, "photons", o->photons, o->progress);
    double t0 = pm_time_wall();
    int failed = 0;
    pm_error_slot_t err;
    pm_error_slot_init(&err);
    int nthreads = omp_get_max_threads();
    double per_thread = 2.0 * (double)o->photons * t.rs / (nthreads > 0 ? nthreads : 1);
    for (arena_first = ARENA_BLOCK_MIN; arena_first < ARENA_BLOCK && (double)arena_first < per_thread;)
        arena_first *= 2;
    /* Two arenas a thread: each output's runs stay contiguous in their own. */
    pm_trace_arena_t *arenas = aligned_alloc(64, (size_t)nthreads * NOUT * sizeof *arenas);
    if (arenas)
        memset(arenas, 0, (size_t)nthreads * NOUT * sizeof *arenas);
    if (!arenas) {
        free(chunks);
        pm_lights_free(&t.lights);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %d photon arenas", nthreads);
    }
#pragma omp parallel reduction(| : failed)
    {
        pm_trace_arena_t *arena = &arenas[NOUT * omp_get_thread_num()];
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
#pragma omp for schedule(dynamic, 1)
        for (uint64_t ci = 0; ci < nchunks; ci++) {
            chunk_t *c = &chunks[ci];
            for (int w = 0; w < NOUT; w++) {
                c->out[w].arena = &arena[w];
                c->out[w].buf = arena[w].cur + arena[w].used;
            }
            uint64_t b = ci * CHUNK, e = b + CHUNK < o->photons ? b + CHUNK : o->photons;
            for (uint64_t i = b; i < e && !c->failed; i++)
                trace_one(&t, c, i, &ctx);
            failed |= c->failed;
            /* Embree's errors are per thread: this worker's reach the caller through the slot. */
            pm_error_slot_record(&err, ci, pm_rt_thread_error(rt, "tracing photons %" PRIu64 " to %" PRIu64, b, e - 1));
            pm_progress_add(&prog, e - b);
        }
    }
    pm_result_t embree = pm_error_slot_raise(&err);
    failed |= embree != PM_OK;
    out->trace_s = pm_time_wall() - t0;
    pm_progress_end(&prog);

    /* The chunks in index order are the output; add up their counters the same way. */
    out->arenas = arenas;
    out->narenas = NOUT * nthreads;
    out->nchunks = nchunks;
    out->chunk_data = malloc(nchunks * sizeof *out->chunk_data);
    out->chunk_count = malloc(nchunks * sizeof *out->chunk_count);
    out->caustic_data = malloc(nchunks * sizeof *out->caustic_data);
    out->caustic_count = malloc(nchunks * sizeof *out->caustic_count);
    uint64_t nrays = 0;
    for (uint64_t ci = 0; ci < nchunks; ci++)
        nrays += chunks[ci].nrays;
    if (o->record_rays && !failed) {
        out->rays_kept = malloc(nrays ? nrays * 7 * sizeof(float) : 1);
        failed |= !out->rays_kept;
    }
    failed |= !out->chunk_data || !out->chunk_count || !out->caustic_data || !out->caustic_count;
    uint64_t total = 0, rat = 0;
    for (uint64_t ci = 0; ci < nchunks; ci++) {
        chunk_t *c = &chunks[ci];
        if (!failed) {
            out->chunk_data[ci] = c->out[OUT_GLOBAL].buf;
            out->chunk_count[ci] = c->out[OUT_GLOBAL].n;
            out->caustic_data[ci] = c->out[OUT_CAUSTIC].buf;
            out->caustic_count[ci] = c->out[OUT_CAUSTIC].n;
            if (o->record_rays)
                memcpy(out->rays_kept + 7 * rat, c->rays, c->nrays * 7 * sizeof(float));
        }
        total += c->out[OUT_GLOBAL].n;
        out->caustic += c->out[OUT_CAUSTIC].n;
        out->specular_bounces += c->specular;
        rat += c->nrays;
        out->rays += c->rays_traced;
        out->escaped += c->escaped;
        out->portal_back += c->portal_back;
        out->absorbed += c->absorbed;
        out->capped += c->capped;
        out->first_hits += c->first;
        if (c->longest > out->longest)
            out->longest = c->longest;
        for (int k = 0; k < 3; k++) {
            out->power_emitted[k] += c->power_emitted[k];
            out->power_first[k] += c->power_first[k];
            out->power_caustic[k] += c->power_caustic[k];
        }
        free(c->rays);
    }
    free(chunks);
    pm_lights_free(&t.lights);
    out->count = total;
    out->emitted = o->photons;
    if (failed) {
        pm_trace_free(out);
        if (embree != PM_OK)
            return embree; /* its message is already this thread's */
        return pm_error_set(PM_ERR_NOMEM, "out of memory storing the photons of scene '%s' (%" PRIu64 " stored so far)",
                            s->name, total);
    }
    return PM_OK;
}

double pm_trace_replay(const pm_rt_t *rt, const pm_trace_result_t *r)
{
    if (!r->rays_kept || r->rays == 0)
        return 0.0;
    uint64_t n = r->rays;
    uint64_t hits = 0;
    double t0 = pm_time_wall();
#pragma omp parallel reduction(+ : hits)
    {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
#pragma omp for schedule(dynamic, 4096)
        for (uint64_t i = 0; i < n; i++) {
            const float *p = &r->rays_kept[7 * i];
            float t;
            hits += pm_rt_intersect1(rt, &ctx, p, p + 3, p[6], INFINITY, &t, NULL) != PM_RAY_MISS;
        }
    }
    double dt = pm_time_wall() - t0;
    return dt > 0 ? (double)n / dt : 0.0;
}

void pm_trace_free(pm_trace_result_t *r)
{
    for (int i = 0; i < r->narenas; i++) {
        for (size_t b = 0; b < r->arenas[i].nblocks; b++)
            pm_free_aligned(r->arenas[i].blocks[b]);
        free(r->arenas[i].blocks);
    }
    free(r->arenas);
    free(r->chunk_data);
    free(r->chunk_count);
    free(r->caustic_data);
    free(r->caustic_count);
    free(r->rays_kept);
    memset(r, 0, sizeof *r);
}
