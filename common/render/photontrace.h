/* photontrace.h: forward photon tracing (the paper, section 5.1), the engine of
 * trace-photons.
 *
 * Photon i is emitted from a light chosen in proportion to its power (render/light.h,
 * pm_light_sample_le), traced with single Embree rays (pm_rt_intersect1), and stored at every hit on a
 * surface where the gather estimates (physics/bsdf.h, pm_bsdf_stores_photons: a standard
 * material that reflects, a rough conductor, a plastic; first hits too, marked depth 0).
 * Delta-only surfaces (mirrors, glass, smooth conductors: pm_specular_sample) redirect a photon
 * and never store it; a photon that reaches a storing surface through one or more of them and
 * nothing else since the light (L S+ D) is also a caustic photon, the second output when asked
 * for. Rough glass stores none either and counts as a glossy bounce. At a standard surface each
 * bounce samples one lobe (cosine for the Lambertian part, the Phong lobe for the glossy part)
 * and Russian roulette ends the path without bias: the photon survives with probability q (its
 * albedo, capped at rr_max) and its power is divided by q (a cap below albedo^2 makes the
 * variance unbounded). At the other kinds the BSDF's own sampler draws the direction in
 * importance mode (photons carry power: no 1 / eta^2 through a refraction) and the roulette
 * uses the sample's weight f cos / pdf as q. Powers are in watts, so that a density
 * estimate of them is irradiance in W/m^2.
 *
 * Determinism: photon i draws only from the counter-based stream (seed, i), and photons
 * are stored in index order, so the output is bit-identical for any thread count. */
#ifndef PM_PHOTONTRACE_H
#define PM_PHOTONTRACE_H

#include <stdint.h>

#include "base/error.h"
#include "math/rng.h"
#include "render/rt.h"
#include "render/scene.h"

typedef struct {
    uint64_t photons; /* photon paths to emit, >= 1 */
    uint64_t seed;
    uint32_t max_bounces; /* safety cap on a path's bounces (paths cut there are counted) */
    double rr_max;        /* highest survival probability of Russian roulette, in (0, 1] */
    int direction;        /* store the direction channel (scenes with glossy materials) */
    int caustics;         /* also collect the caustic photons (L S+ D) as a second output */
    int indirect_only;    /* store in the main output no first hit (depth 0) of a light the gather points sample
                           * (pm_light_at_gather: every light but an area light near the hit), whose shadow rays bring that
                           * light (trace-gather-points --secondary-direct); first_hits still counts them */
    int record_rays;      /* keep every ray for pm_trace_replay (benchmark baseline) */
    int progress;         /* progress bar on a terminal */
} pm_trace_options_t;

/* The seed of progressive pass `pass` (1-based; 0: no pass, the seed itself) of a run seeded
 * `seed`: one Philox block of the pass number under the seed, so that every pass draws numbers
 * independent of every other pass's and of the seeds' order. trace-photons and
 * trace-gather-points both key their streams with it, so one --pass changes photons and eye
 * rays together. */
static inline uint64_t pm_trace_pass_seed(uint64_t seed, uint64_t pass)
{
    if (pass == 0)
        return seed;
    const uint32_t ctr[4] = {(uint32_t)pass, (uint32_t)(pass >> 32), 0x70617373u /* "pass" */, 0};
    const uint32_t key[2] = {(uint32_t)seed, (uint32_t)(seed >> 32)};
    uint32_t out[4];
    pm_philox4x32_10(ctr, key, out);
    return (uint64_t)out[0] | (uint64_t)out[1] << 32;
}

typedef struct pm_trace_arena pm_trace_arena_t;

typedef struct {
    /* The photons in the photons format's record layout, as nchunks runs in photon-index
     * order: run i is chunk_count[i] records at chunk_data[i]. */
    const unsigned char **chunk_data;
    uint64_t *chunk_count;
    /* With o->caustics, the caustic photons (stored after one or more specular bounces and no
     * other since the light: Jensen's caustic map) in the same layout and chunking; every one
     * of them is among the runs above too. Empty runs without o->caustics. */
    const unsigned char **caustic_data;
    uint64_t *caustic_count;
    uint64_t caustic; /* caustic photons in all */
    uint64_t nchunks;
    pm_trace_arena_t *arenas; /* where the runs live */
    int narenas;
    uint64_t count;
    uint32_t channels, record_size;
    uint64_t emitted, first_hits, rays, escaped, absorbed, capped, longest;
    uint64_t portal_back;      /* photons that would have left through a portal's back: emitted, not traced */
    double power_emitted[3];   /* W: sum over emitted photons */
    double power_first[3];     /* W: sum over stored first hits */
    double power_caustic[3];   /* W: sum over the caustic photons */
    uint64_t specular_bounces; /* hits on mirrors and glass (never stored) */
    double trace_s;            /* wall seconds of the tracing loop */
    float *rays_kept;          /* record_rays: 7 floats per ray (origin, direction, tnear) */
} pm_trace_result_t;

/* Traces o->photons photons through s and rt. Fails with a clear message when the scene
 * has no lights, its power does not fit the photons' f32 powers, or memory runs out. */
pm_result_t pm_trace_photons(const pm_scene_t *s, const pm_rt_t *rt, const pm_trace_options_t *o,
                             pm_trace_result_t *out);

/* Re-traces the rays kept by record_rays with single rays and nothing else
 * (pm_rt_intersect1, a thin inline around rtcIntersect1), on as many threads as the trace
 * used: Embree's own single-ray rate on exactly the same rays. Returns rays/s. */
double pm_trace_replay(const pm_rt_t *rt, const pm_trace_result_t *r);

void pm_trace_free(pm_trace_result_t *r);

#endif
