/* trace-reference: scene -> reference image (OpenEXR) and optionally its radiance buffer with
 * each pixel's variance: ground truth for the photon pipeline. An unbiased path tracer with
 * next-event estimation, MIS and Russian roulette over the same scene model and the same
 * physics as trace-photons and trace-gather-points; common/render/pathtrace.c does the work
 * (its header says how), this main reads the options, loads the scene and reports.
 *
 * Progressive: passes of --pass samples per pixel until --spp in all or --time seconds; the
 * outputs are rewritten after every pass, so a run can be stopped and continued with
 * --resume. The same settings give the same bits for any --threads. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "base/memory.h"
#include "base/stage.h"
#include "base/timer.h"
#include "formats/formats.h"
#include "render/aov.h"
#include "render/light.h"
#include "render/pathtrace.h"
#include "render/rt.h"
#include "render/scene.h"

typedef struct {
    int64_t spp;         /* samples per pixel in all, resumed ones included */
    int64_t pass;        /* samples per pixel per pass */
    double time_s;       /* stop after this many seconds (at a pass boundary); 0: no limit */
    int64_t max_bounces; /* safety net: a path is cut after this many bounces */
    int64_t rr_start;    /* bounces before Russian roulette starts */
    int64_t width, height;
    int pixel, component;
    const char *radiance; /* --radiance FILE: f64 mean and variance per pixel */
    const char *resume;   /* --resume FILE: a --radiance file to continue */
    const char *aov;      /* --aov LIST: denoiser layers beside R G B, NULL for none */
} ref_options_t;

/* The counters and timings of a finished render as --stats and the closing note. */
static void report(pm_stage_t *st, const pm_pathtracer_t *pt, const pm_pathtrace_run_t *run)
{
    pm_pathtrace_counts_t sum;
    pm_pathtrace_counts(pt, &sum);
    double rmse, mean, rel, t = run->trace_s;
    pm_pathtrace_image_error(pt, &rmse, &mean, &rel);
    uint64_t rays = sum.rays + sum.shadow_rays;
    pm_stage_stat_int(st, "width", pt->set.width);
    pm_stage_stat_int(st, "height", pt->set.height);
    pm_stage_stat_int(st, "samples", (int64_t)pt->n);
    pm_stage_stat_int(st, "samples_resumed", (int64_t)run->resumed);
    pm_stage_stat_int(st, "passes", run->passes);
    pm_stage_stat_int(st, "timed_out", run->timed_out);
    pm_stage_stat_int(st, "paths", (int64_t)sum.paths);
    pm_stage_stat_int(st, "rays", (int64_t)sum.rays);
    pm_stage_stat_int(st, "shadow_rays", (int64_t)sum.shadow_rays);
    pm_stage_stat_double(st, "rays_per_s", t > 0 ? (double)rays / t : 0.0);
    pm_stage_stat_double(st, "rays_per_path", sum.paths ? (double)sum.rays / (double)sum.paths : 0.0);
    pm_stage_stat_int(st, "longest_path", (int64_t)sum.longest);
    pm_stage_stat_int(st, "capped_paths", (int64_t)sum.capped);
    pm_stage_stat_int(st, "nonfinite_samples", (int64_t)sum.nonfinite);
    pm_stage_stat_double(st, "trace_s", t);
    pm_stage_stat_double(st, "write_s", run->write_s);
    pm_stage_stat_double(st, "mean_radiance", mean);
    pm_stage_stat_double(st, "stderr_rms", rmse);
    pm_stage_stat_double(st, "stderr_rel", rel);
    st->items = sum.paths;
    pm_stage_note(st,
                  "%" PRIu64 " samples per pixel (%d passes, %.3f s, %.2f Mrays/s); standard error %.3g W/(m^2 sr) "
                  "RMS, %.3g%% of the mean%s",
                  pt->n, run->passes, t, t > 0 ? 1e-6 * (double)rays / t : 0.0, rmse, 100.0 * rel,
                  run->timed_out ? " (stopped by --time)" : "");
    if (sum.capped)
        pm_stage_note(st, "warning: %" PRIu64 " paths reached --max-bounces %u and were cut (biased low)", sum.capped,
                      pt->set.max_bounces);
    if (sum.nonfinite)
        pm_stage_note(st, "warning: %" PRIu64 " samples were not finite and were dropped", sum.nonfinite);
}

static pm_result_t run(pm_stage_t *st, const ref_options_t *o, const pm_scene_t *s, const pm_rt_t *rt)
{
    pm_pathtrace_settings_t set = {
        .width = o->width ? (uint32_t)o->width : s->camera.width,
        .height = o->height ? (uint32_t)o->height : s->camera.height,
        .seed = (uint64_t)(pm_args_given(&st->args, "seed") ? st->seed : s->defaults.seed),
        .max_bounces = (unsigned)o->max_bounces,
        .rr_start = (unsigned)o->rr_start,
        .pixel = o->pixel,
        .component = o->component,
        .threads = st->threads_used > 0 ? st->threads_used : 1,
    };
    /* The scene's own camera is within the image limits (scene.c): only --width or --height
     * can take it beyond them, a usage error. */
    if (pm_image_size_check(set.width, set.height) != PM_OK) {
        char why[PM_ERROR_MAX];
        snprintf(why, sizeof why, "%s", pm_error_message());
        return pm_error_set(PM_ERR_USAGE, "--width %" PRId64 " --height %" PRId64 " (0: the camera's): %s", o->width,
                            o->height, why);
    }
    char cmd[4096];
    pm_stage_command_line(st, cmd, sizeof cmd);
    unsigned aov = 0;
    float *surf = NULL;
    if (o->aov) {
        pm_result_t ra = pm_exr_aov_parse("--aov", o->aov, &aov);
        if (ra == PM_OK && (aov & PM_EXR_AOV_SURFACE)) {
            /* The first surface of each pixel, seen through the reference's own pixel footprint:
             * 64 rays a box pixel, one through a centre. */
            uint32_t nray = o->pixel == PM_PIXEL_BOX ? 64 : 1;
            if (!(surf = malloc((size_t)set.width * set.height * PM_AOV_FLOATS * sizeof *surf)))
                ra = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " AOV image", set.width,
                                  set.height);
            else
                ra = pm_aov_trace(s, rt, set.width, set.height, nray, o->pixel, set.seed, set.threads, surf);
        }
        if (ra != PM_OK) {
            free(surf);
            return ra;
        }
    }
    const pm_pathtrace_output_t out = {st->output, o->radiance, st->argc, st->argv, cmd, aov, surf};
    const pm_pathtrace_plan_t plan = {(uint64_t)o->spp, (uint64_t)o->pass, o->time_s, pm_stage_progress(st)};
    pm_pathtracer_t pt;
    pm_pathtrace_run_t ran;
    pm_result_t r = pm_pathtracer_init(&pt, s, rt, &set);
    if (r != PM_OK) {
        free(surf);
        return r;
    }
    if (o->resume)
        r = pm_pathtrace_resume(&pt, o->resume);
    if (r == PM_OK)
        r = pm_pathtrace_render(&pt, &plan, &out, &ran);
    if (r == PM_OK)
        report(st, &pt, &ran);
    pm_pathtracer_free(&pt);
    free(surf);
    return r;
}

int main(int argc, char **argv)
{
    /* malloc on huge pages (the scene's load), as pm-render's stages have them */
    pm_memory_huge_malloc(argv, pm_time_wall());
    (void)pm_memory_started(pm_time_wall()); /* takes PMTK_START_S out of the environment */
    pm_stage_t st;
    pm_stage_defaults(&st);
    ref_options_t o = {.pixel = PM_PIXEL_BOX, .spp = 64, .pass = 16, .max_bounces = 1 << 20, .rr_start = 3};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"spp", 0, PM_OPT_INT, &o.spp, "N", "samples (paths) per pixel in all, resumed ones included", 1, 4e9, NULL},
        {"pass", 0, PM_OPT_INT, &o.pass, "N", "samples per pixel per pass; the outputs are rewritten after each", 1,
         4e9, NULL},
        {"time", 0, PM_OPT_DOUBLE, &o.time_s, "S",
         "stop after S seconds, at the end of a pass (at least one pass runs); 0: no limit", 0, 1e9, NULL},
        {"aov", 0, PM_OPT_STRING, &o.aov, "LIST",
         "also write these layers into the image for a denoiser, comma-separated: albedo (albedo.R/G/B), normal "
         "(normal.X/Y/Z), depth (Z) of the first surface, variance (variance.R/G/B) of each pixel's mean",
         1, 0, NULL},
        {"radiance", 0, PM_OPT_OUTPUT, &o.radiance, "FILE",
         "also write the f64 radiance buffer with each pixel's variance (for measure-error and --resume)", 1, 0, NULL},
        {"resume", 0, PM_OPT_STRING, &o.resume, "FILE",
         "continue the samples of an earlier --radiance FILE of the same scene, size, seed and pixel", 1, 0, NULL},
        {"pixel", 0, PM_OPT_CHOICE, &o.pixel, "HOW",
         "box: the pixel's mean over its area (stratified over the samples); center: through pixel centres, as "
         "trace-gather-points --pixel center",
         1, 0, pm_pixel_names},
        {"component", 0, PM_OPT_CHOICE, &o.component, "WHICH",
         "total, or only direct (emission seen and direct light: trace-gather-points --direct), indirect "
         "(simd-gather's part) or caustic (light through mirrors or glass onto the first diffuse surface seen)",
         1, 0, pm_pt_component_names},
        {"width", 0, PM_OPT_INT, &o.width, "N", "image width in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"height", 0, PM_OPT_INT, &o.height, "N", "image height in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"max-bounces", 0, PM_OPT_INT, &o.max_bounces, "N",
         "safety net: cut a path after N bounces (counted in --stats; Russian roulette ends paths first)", 1, 1e9,
         NULL},
        {"rr-start", 0, PM_OPT_INT, &o.rr_start, "N", "bounces before Russian roulette may end a path", 0, 1e9, NULL},
        {0},
    };
    static const char about[] = "Render a reference image with an unbiased path tracer (next-event estimation, MIS, "
                                "Russian roulette) over the photon stages' scene model; progressive.";
    const pm_cli_t cli = {"trace-reference", "[options] SCENE [-o] OUT.exr", about, options, 1, 2, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    if (st.args.nargs == 2) {
        if (strcmp(st.output, "-"))
            return pm_stage_end(&st,
                                pm_error_set(PM_ERR_USAGE, "give the output once: as -o or as the second argument"));
        st.output = st.args.args[1];
    }
    if (!strcmp(st.output, "-"))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "an OpenEXR output needs a file name (OpenEXR cannot "
                                                            "write to a pipe): -o OUT.exr"));
    if (o.radiance && (!strcmp(o.radiance, "-") || pm_atomic_same_file(o.radiance, st.output)))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--radiance needs a file of its own"));
    pm_scene_t s;
    pm_result_t r = pm_scene_load(st.args.args[0], &s);
    if (r != PM_OK)
        return pm_stage_end(&st, r);
    pm_scene_warn_unsupported(&s, &st);
    double power[3];
    pm_scene_power(&s, power);
    if (!(power[0] + power[1] + power[2] > 0.0)) {
        size_t nl, sampled;
        pm_lights_count(&s, &nl, &sampled);
        r = pm_error_set(PM_ERR_INPUT,
                         "scene '%s' has no lights (its %zu lights emit 0 W): its reference image is black", s.path,
                         nl);
        pm_scene_free(&s);
        return pm_stage_end(&st, r);
    }
    pm_rt_t rt;
    r = pm_rt_create(&s, 1, st.threads_used, &rt);
    if (r == PM_OK)
        r = run(&st, &o, &s, &rt);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    return pm_stage_end(&st, r);
}
