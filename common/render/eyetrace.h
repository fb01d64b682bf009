/* eyetrace.h: the eye side of the final gather (the paper, sections 5.1 and 6.1), the engine of
 * trace-gather-points.
 *
 * Casts `primary` rays per pixel as Embree packets: by default at stratified, jittered points
 * over the pixel's area (pm_pixel_offset), so that the pixel is the mean over its area (a box
 * filter), or all through its centre (PM_PIXEL_CENTER). At each
 * primary hit adds emission seen directly and direct light (shadow rays to point lights and to
 * sampled points of emissive triangles) into the direct radiance buffer; and spawns `spp`
 * secondary rays (cosine-weighted at a Lambertian surface, or half of them from a photon guide,
 * render/guide.h, where one is given; drawn from the BSDF mixture at a glossy one), stratified with PM_EYE_PER_CELL
 * samples per cell so that groups of four share origin and direction, also traced as packets. Each secondary hit
 * becomes one gather point, a record of the queries format (formats/formats.h) with the weight contract of
 * docs/formats.md. PM_EYE_DIRECT_VIS makes the primary hits themselves the queries (the paper's Figure 4, left).
 *
 * Rows are the unit of work: rows of a band run in parallel, and the caller's sink receives their
 * records and direct radiance in pixel order, one call at a time, on one of the threads while the
 * others trace the next band, so what it receives is the same bytes for any thread count and
 * schedule. Pixel p draws from the Philox streams
 * (seed, 4p + purpose): jitter, light samples, secondary rays. */
#ifndef PM_EYETRACE_H
#define PM_EYETRACE_H

#include <stdint.h>

#include "base/cpu.h"
#include "base/error.h"
#include "base/stage.h"
#include "formats/pmfile.h"
#include "render/guide.h"
#include "render/rt.h"
#include "render/scene.h"

#define PM_EYE_PER_CELL 4       /* secondary samples per stratum cell: the paper's four */
#define PM_EYE_MAX_SPECULAR 256 /* specular bounces in a row an eye path may take; more are cut (lost light) */
/* Glossy paths (docs/accuracy.md): a secondary ray that hits a Phong lobe of exponent
 * PM_EYE_GLOSSY_NS or more (a half-width at half maximum of 9.5 degrees and less, where a
 * gather's few photons inside the lobe make speckle) continues along the lobe instead of
 * gathering there, up to pm_eye_options_t's glossy_depth bounces, with Russian roulette from the
 * PM_EYE_GLOSSY_RR-th bounce on. */
#define PM_EYE_GLOSSY_NS 50.0f
/* The same for the GGX kinds (conductor, plastic): a width alpha under this (the GGX width whose
 * Beckmann-equivalent Phong exponent 2 / alpha^2 - 2 is 48). */
#define PM_EYE_GLOSSY_ALPHA 0.2f
#define PM_EYE_GLOSSY_RR 3
#define PM_EYE_GLOSSY_DEPTH 8 /* trace-gather-points' default glossy_depth */

enum { PM_EYE_GATHER = 0, PM_EYE_DIRECT_VIS = 1 };                    /* where the queries are */
enum { PM_EYE_INTERLEAVE = 0, PM_EYE_TILES = 1, PM_EYE_DYNAMIC = 2 }; /* rows of a band to threads */
/* Their names, indexed by the enums and NULL-terminated (option tables, headers, stats). */
extern const char *const pm_eye_mode_names[];
extern const char *const pm_eye_schedule_names[];

typedef struct {
    int mode;               /* PM_EYE_GATHER or PM_EYE_DIRECT_VIS */
    int schedule;           /* PM_EYE_INTERLEAVE, PM_EYE_TILES or PM_EYE_DYNAMIC */
    uint32_t width, height; /* pixels; 0 takes the scene camera's */
    uint32_t spp;           /* secondary rays per primary hit (gather mode); 0 takes the scene's render.spp */
    uint32_t primary;       /* primary rays per pixel, >= 1 */
    int pixel;              /* PM_PIXEL_BOX (the default: rays stratified over the pixel) or PM_PIXEL_CENTER */
    uint32_t light_samples; /* area-light samples per primary hit */
    uint64_t seed;
    pm_isa_t isa;    /* packet width (narrowed to what Embree runs natively) */
    int threads;     /* worker threads, >= 1 */
    int progress;    /* a progress line on a terminal */
    int caustics;    /* also deliver the caustic queries (sink->caustic); a scene with mirrors or glass, gather mode */
    int direct_only; /* the direct radiance alone, no queries: secondary rays are traced only in a scene with
                      * emissive triangles, a sun or a sky, for the light they find there (the same direct buffer,
                      * bit for bit) */
    unsigned glossy_depth;         /* glossy bounces a secondary path may continue through before it gathers (gather
                                    * mode); 0 gathers on every glossy surface */
    const pm_guide_t *guide;       /* photon guide of the secondary rays at Lambertian hits (render/guide.h), NULL for
                                    * none; read only, must outlive the context */
    int secondary_direct;          /* gather mode: next-event estimation at every gather point too, into the direct
                                    * buffer, for a map without the first-hit photons it stands for (trace-photons
                                    * --indirect-only; render/light.h, pm_light_at_gather) */
    unsigned diffuse_depth;        /* gather mode: Lambertian bounces a secondary path takes before it gathers, each
                                    * with a light sample of every light and one cosine-weighted ray on (0: it gathers
                                    * at its first hit, the paper's final gather; header diffuse_depth=N) */
    int strata_hit;                /* 1: every hit's secondary rays and light samples stratified alone (the paper's
                                    * section 6.1, files as before); 0: a pixel's primary rays' stratified together
                                    * (math/strata.h, pm_strata_pixel; header strata=pixel) */
    const uint32_t *pixel_primary; /* adaptive passes: primary rays of each pixel (width x height, each >= 1), each
                                    * weighted by 1 / its pixel's count, instead of `primary` everywhere; NULL for
                                    * none. Read only, must outlive the context */
} pm_eye_options_t;

/* What a context settled on: sizes, the effective spp, the queries' record layout. */
typedef struct {
    int mode;
    uint32_t width, height;
    uint32_t spp; /* 0 in direct-vis mode */
    uint32_t primary, light_samples;
    int pixel; /* PM_PIXEL_BOX or PM_PIXEL_CENTER */
    uint64_t seed;
    int packet_width;      /* lanes: 1, 4, 8 or 16 */
    uint32_t channels;     /* mask of the queries channels written (direction, material only when needed) */
    uint32_t record_size;  /* bytes per query record */
    int specular;          /* the scene has mirrors or glass: eye paths pass through them */
    int caustics;          /* caustic queries are delivered */
    unsigned glossy_depth; /* glossy paths are followed up to this many bounces (0: the scene has none, or off) */
    int guided;            /* secondary rays are guided by photons (pm_eye_options_t guide) */
    int secondary_direct; /* the gather points' direct light is in the direct buffer (header secondary_direct=1 or 2) */
    int strata_pixel;     /* secondary rays and light samples stratified over each pixel (header strata=pixel) */
    unsigned diffuse_depth; /* Lambertian bounces before the gather (header diffuse_depth=N when > 0) */
} pm_eye_info_t;

/* Counters of one pm_eye_trace. */
typedef struct {
    uint64_t primary_rays, secondary_rays, shadow_rays, queries;
    uint64_t caustic_queries;  /* records delivered to sink->caustic */
    uint64_t specular_rays;    /* single rays of the chains through mirrors and glass */
    uint64_t specular_cut;     /* chains cut at PM_EYE_MAX_SPECULAR bounces */
    uint64_t glossy_rays;      /* single rays of the glossy paths */
    uint64_t guided_hits;      /* primary hits whose secondary rays a guide cell shaped */
    uint64_t guided_rays;      /* secondary rays drawn from a guide cell (the rest: cosine) */
    double trace_s;            /* wall s of the row loop, without the sink calls no tracing hid: the
                                * last band's, and on one thread every band's */
    double sink_s;             /* wall s spent in the sink, every band's (the caller's output cost) */
    double sink_alone_s;       /* of it, the wall s no tracing hid: trace_s + sink_alone_s is the loop's */
    double trace_cpu_s;        /* CPU s the threads spent tracing rows: immune to other processes' load */
    double secondary_embree_s; /* s inside Embree for secondary rays, summed over threads */
} pm_eye_stats_t;

/* Where the results go. The calls are made one at a time, never concurrently, in pixel order,
 * but not always on the thread that called pm_eye_trace: a band's records go out on one of the
 * tracing threads while the others trace the next band. A failure they return (with its
 * message, pm_error_set on that thread) stops the trace and is returned as it is, once the band
 * traced beside it has ended. */
typedef struct {
    /* count query records (pm_eye_info_t's record_size bytes each), in pixel order; the
     * queries of a pixel are contiguous and pixels come in row-major order. */
    pm_result_t (*queries)(void *user, const void *records, uint64_t count);
    /* Direct radiance of rows [y0, y0 + rows): width * rows RGB triples, W/(m^2 sr). */
    pm_result_t (*direct)(void *user, uint32_t y0, uint32_t rows, const double *rgb);
    /* With pm_eye_options_t caustics: count caustic query records, as queries, in pixel order
     * (each row's after that row's queries). */
    pm_result_t (*caustic)(void *user, const void *records, uint64_t count);
    void *user;
} pm_eye_sink_t;

typedef struct pm_eye pm_eye_t;

/* A context over a loaded scene and its Embree scene (both must outlive it). Fails with
 * PM_ERR_INPUT when the scene's render.spp is needed and is not a positive multiple of
 * PM_EYE_PER_CELL up to 65536 (PM_ERR_USAGE when o->spp is the one), or PM_ERR_NOMEM. */
pm_result_t pm_eye_create(const pm_scene_t *s, const pm_rt_t *rt, const pm_eye_options_t *o, pm_eye_t **out);

const pm_eye_info_t *pm_eye_info(const pm_eye_t *e);

/* Traces every row and feeds sink. A failure on a worker thread (out of memory for a row's
 * rays or records) reaches the caller whole, with the lowest failing row's message. */
pm_result_t pm_eye_trace(pm_eye_t *e, const pm_eye_sink_t *sink, pm_eye_stats_t *stats_out);

/* The headers of the two outputs, initialized here (free with pm_header_free): provenance
 * (argc, argv: this command), SCENE, sizes, mode, spp, primary, pixel, seed; the queries header also
 * its channels, the material table, the weight contract and the scene's render.k, render.radius
 * and render.leaf for the stages downstream, with COUNT count; the direct one
 * component=direct and light_samples, with COUNT width * height. */
pm_result_t pm_eye_queries_header(const pm_eye_t *e, int argc, char **argv, uint64_t count, pm_header_t *h);
pm_result_t pm_eye_direct_header(const pm_eye_t *e, int argc, char **argv, pm_header_t *h);

void pm_eye_destroy(pm_eye_t *e);

/* What trace-gather-points reports: the tracer's settings and counters into st's --stats
 * (rays, queries, rates per second of wall and CPU time) and its one-line note. schedule is
 * the pm_eye_schedule_names index, spilled whether the records went past memory. */
void pm_eye_report(pm_stage_t *st, const pm_eye_info_t *in, const pm_eye_stats_t *x, int schedule, int spilled,
                   pm_isa_t isa);

#endif
