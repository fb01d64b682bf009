/* pathtrace.h: the reference path tracer, the engine of trace-reference: ground truth for the
 * photon pipeline over the same scene model (render/shade.h camera, render/transport.h BSDF,
 * render/light.h lights: point lights in W/sr, Ke in W/(m^2 sr), front-face emitters), so that
 * measure-error can say how wrong a photon-mapped image is.
 *
 * Estimator: at every non-specular vertex, next-event estimation toward each point light
 * (delta: light sampling only) and toward one point on the area lights (uniform over their
 * total area), combined with BSDF sampling by the power heuristic; the BSDF is sampled as the
 * mixture of its lobes (pm_bsdf_sample for the standard kind, physics/bsdf.h's
 * pm_bsdf_sample_wi in radiance mode for conductor, rough glass and plastic). At a vertex whose
 * lobes are all deltas (mirror, glass, a smooth conductor) the delta BSDF is sampled alone
 * (pm_specular_sample, carrying radiance): no light sample, no MIS, and emission the next ray
 * finds counts whole, since no light sample could have found it; the same holds after a delta
 * lobe of a mixed material (a smooth plastic coat) and after a rough-glass transmission (light
 * samples look only at wo's side of the surface). Light from a point
 * light reaching a diffuse surface only through mirrors or glass (a point light's caustic)
 * is therefore never found: a path tracer cannot sample it, and it is zero in this estimate.
 * Paths end by Russian roulette with survival min(1, max throughput times the product of
 * eta^2 over the refractions so far), which keeps them unbiased, their weights bounded by 1 at
 * any albedo outside glass, and does not cull a path inside glass for the 1/eta^2 its way
 * out gives back; max_bounces is a safety net whose paths are counted (a lossless mirror
 * cavity never ends otherwise).
 *
 * Progressive: pm_pathtrace_render runs passes of samples per pixel and rewrites the outputs
 * (an OpenEXR image and optionally the f64 radiance buffer with each pixel's variance) after
 * every pass, so a long run can be stopped at any time and continued from that buffer
 * (pm_pathtrace_resume). Sample k of pixel p draws from the Philox stream (seed, p << 32 | k)
 * whatever the thread, pass or resume, and starts at point k of the pixel's scrambled
 * (0,2)-sequence (pm_pixel_offset, scramble from stream p << 32 | 2^32 - 1), and pixels are summed sample by sample in
 * order: the same settings give the same bits for any thread count.
 *
 * Units: radiance W/(m^2 sr). */
#ifndef PM_PATHTRACE_H
#define PM_PATHTRACE_H

#include <stdint.h>

#include "base/error.h"
#include "render/rt.h"
#include "render/scene.h"
#include "render/shade.h"

/* Which light: a contribution that met b non-specular surfaces (diffuse or glossy) on its way
 * to the camera, mirrors and glass not counted, is
 *   direct for b = 0 (emission seen, directly or through mirrors and glass) and for b = 1 when
 *     no mirror or glass lies between the light and that surface (L D S* E, Heckbert's
 *     notation: as trace-gather-points' direct buffer samples it);
 *   caustic for b = 1 with one or more mirror or glass bounces between the light and the
 *     surface (L S+ D S* E: what a caustic photon map holds);
 *   indirect for b >= 2 (simd-gather's indirect buffer).
 * In a scene without mirrors or glass b counts every bounce and caustic is 0. The three add up
 * to the total. */
enum { PM_PT_TOTAL = 0, PM_PT_DIRECT = 1, PM_PT_INDIRECT = 2, PM_PT_CAUSTIC = 3 };
extern const char *const pm_pt_component_names[]; /* "total", "direct", "indirect", "caustic", NULL */

typedef struct {
    uint32_t width, height; /* pixels */
    uint64_t seed;
    unsigned max_bounces; /* a path is cut after this many bounces (counted in capped) */
    unsigned rr_start;    /* bounces before Russian roulette may end a path */
    int pixel;            /* PM_PIXEL_BOX (sample k at pm_pixel_offset k) or PM_PIXEL_CENTER */
    int component;        /* PM_PT_* */
    int threads;          /* OpenMP threads of a pass, >= 1 */
} pm_pathtrace_settings_t;

/* Counters of traced work; per thread during a pass, each on its own cache line. */
typedef struct {
    _Alignas(64) uint64_t paths, rays, shadow_rays, capped, nonfinite, longest;
} pm_pathtrace_counts_t;

/* A render in progress. The scene and rt are borrowed and must outlive it; the rest is its
 * own. mean and m2 hold 3 doubles per pixel (row-major, y down): the running mean of the n
 * samples so far and their sum of squared deviations, merged pass by pass (Chan et al.) so
 * that neither cancels in long runs. */
typedef struct {
    const pm_scene_t *s;
    const pm_rt_t *rt;
    pm_pathtrace_settings_t set;
    pm_shade_geom_t geom;
    pm_lights_t lights;
    pm_camera_rays_t cam;
    double *mean, *m2;
    uint64_t n;                   /* samples per pixel merged so far */
    pm_pathtrace_counts_t *count; /* set.threads of them */
} pm_pathtracer_t;

/* Sets up a render of s through rt with no samples yet; fails on memory only. */
pm_result_t pm_pathtracer_init(pm_pathtracer_t *pt, const pm_scene_t *s, const pm_rt_t *rt,
                               const pm_pathtrace_settings_t *set);
void pm_pathtracer_free(pm_pathtracer_t *pt);

/* One path through pixel (x, y), sample k: its radiance estimate in L_out (0 for a sample
 * that is not finite, which is counted in cnt->nonfinite). ctx is the calling thread's. */
void pm_pathtrace_sample(const pm_pathtracer_t *pt, struct RTCIntersectContext *ctx, uint32_t x, uint32_t y, uint32_t k,
                         pm_pathtrace_counts_t *cnt, double L_out[3]);

/* Samples [pt->n, k1) of every pixel, traced on set.threads threads and merged into the
 * running mean; pt->n becomes k1. An Embree error on a worker fails the pass with its message. */
pm_result_t pm_pathtrace_pass(pm_pathtracer_t *pt, uint32_t k1);

/* The counters of all threads so far, added up (longest: the maximum). */
void pm_pathtrace_counts(const pm_pathtracer_t *pt, pm_pathtrace_counts_t *sum_out);

/* How wrong the image is by its own spread: RMS standard error over pixels and channels, the
 * mean radiance, and the first over the second (0 when the mean is not positive). */
void pm_pathtrace_image_error(const pm_pathtracer_t *pt, double *rmse_out, double *mean_out, double *rel_out);

/* Takes over the samples of an earlier radiance buffer of this very render (same estimator,
 * scene, size, seed, pixel and component); fails with a message naming what differs. */
pm_result_t pm_pathtrace_resume(pm_pathtracer_t *pt, const char *path);

/* Where the image goes, and what its headers say about the command that made it. */
typedef struct {
    const char *exr;      /* OpenEXR image of the mean (a file: OpenEXR cannot write to a pipe) */
    const char *radiance; /* NULL, or the radiance buffer with each pixel's variance */
    int argc;             /* the command, for the radiance buffer's COMMAND line */
    char **argv;
    const char *command; /* the same as one line, for the image's COMMAND.0 attribute */
    unsigned aov;        /* PM_EXR_AOV_* layers the image carries beside R G B (base/exr.h); 0: none */
    const float *surf;   /* with albedo, normal or depth in aov: render/aov.h's 7 floats a pixel */
} pm_pathtrace_output_t;

/* Writes the image and, when asked, the radiance buffer, each atomically. */
pm_result_t pm_pathtrace_write(const pm_pathtracer_t *pt, const pm_pathtrace_output_t *out);

typedef struct {
    uint64_t spp;  /* samples per pixel in all, resumed ones included */
    uint64_t pass; /* samples per pixel per pass, >= 1 */
    double time_s; /* stop at the first pass boundary after this many seconds; 0: no limit */
    int progress;  /* a progress bar on a terminal */
} pm_pathtrace_plan_t;

typedef struct {
    uint64_t resumed; /* samples per pixel that were there before */
    int passes, timed_out;
    double trace_s, write_s; /* wall seconds tracing and writing the outputs */
} pm_pathtrace_run_t;

/* Passes until plan->spp samples per pixel or plan->time_s, the outputs rewritten after
 * each; with no pass to run (already at spp) the outputs are written once. */
pm_result_t pm_pathtrace_render(pm_pathtracer_t *pt, const pm_pathtrace_plan_t *plan, const pm_pathtrace_output_t *out,
                                pm_pathtrace_run_t *run_out);

#endif
