/* scene-info: loads a scene file, builds its Embree BVH and prints what it holds:
 * triangles, materials, lights and their power, bounds, camera, and which optional
 * channels and stages the scene needs, as text or (--json) as one JSON object that
 * pipelines/render reads. With --probe it casts one primary ray per pixel as a check that
 * the camera sees the geometry. The first stage of every pipeline in spirit: if
 * scene-info is happy, the stages can load the scene. common/render/summary.c does the work;
 * this main loads the scene, builds its BVH and keeps the counters. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "base/stage.h"
#include "render/light.h"
#include "render/rt.h"
#include "render/summary.h"

typedef struct {
    int probe;
    const char *preview; /* PNG path, NULL for none */
    int json;            /* the summary as one JSON object instead of text */
} scene_info_options_t;

static pm_result_t run(pm_stage_t *st, const scene_info_options_t *o)
{
    if (o->preview && strcmp(o->preview, "-") == 0)
        return pm_error_set(PM_ERR_USAGE, "--preview needs a file: stdout carries the summary");
    pm_stage_output_set(st); /* the summary and the preview appear together, or neither */
    pm_scene_t s;
    pm_rt_t rt;
    FILE *out;
    double t0 = pm_time_wall();
    pm_result_t r = pm_scene_load(st->args.args[0], &s);
    if (r != PM_OK)
        return r;
    double t_load = pm_time_wall() - t0;
    pm_scene_warn_unsupported(&s, st);
    pm_scene_warn_flipped(&s, st);
    t0 = pm_time_wall();
    r = pm_rt_create(&s, 0, st->threads_used, &rt);
    double t_bvh = pm_time_wall() - t0;
    if (r == PM_OK)
        r = pm_stage_open_output(st, &out);
    if (r == PM_OK) {
        size_t nl, sampled;
        pm_lights_count(&s, &nl, &sampled);
        if (nl == 0)
            pm_stage_note(st, "warning: scene '%s' has no lights; every image of it is black", s.path);
        double p[3];
        pm_scene_power(&s, p);
        pm_stage_stat_int(st, "triangles", (int64_t)s.ntris);
        pm_stage_stat_int(st, "degenerate_triangles", (int64_t)s.ndropped);
        pm_stage_stat_int(st, "materials", (int64_t)s.nmaterials);
        pm_stage_stat_int(st, "point_lights", (int64_t)s.nlights);
        pm_stage_stat_int(st, "emissive_triangles", (int64_t)s.nemissive);
        pm_stage_stat_double(st, "power_w", p[0] + p[1] + p[2]);
        pm_stage_stat_double(st, "load_s", t_load);
        pm_stage_stat_double(st, "bvh_s", t_bvh);
        st->items = s.ntris;
        pm_summary_options_t so = {o->json, o->probe, o->preview, pm_stage_progress(st), t_load, t_bvh};
        pm_probe_t pr;
        r = pm_summary_write(out, &s, &rt, &so, &pr);
        if (pr.rays > 0) {
            pm_stage_stat_int(st, "probe_rays", (int64_t)pr.rays);
            pm_stage_stat_int(st, "probe_hits", (int64_t)pr.hits);
            pm_stage_stat_double(st, "probe_rays_per_s", pr.rays_per_s);
            st->items = pr.rays;
        }
    }
    pm_rt_destroy(&rt); /* safe after a failed create: it zeroes rt */
    pm_scene_free(&s);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    scene_info_options_t o = {0};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"probe", 0, PM_OPT_FLAG, &o.probe, NULL, "cast one primary ray per pixel and report the hit rate", 1, 0, NULL},
        {"preview", 0, PM_OPT_OUTPUT, &o.preview, "PNG",
         "also write an eye-light preview (albedo times cosine) of the camera's view", 1, 0, NULL},
        {"json", 0, PM_OPT_FLAG, &o.json, NULL, "print the summary as one JSON object instead of text", 1, 0, NULL},
        {0},
    };
    static const char about[] = "Load a scene file, build its ray-tracing structure and summarize it.";
    const pm_cli_t cli = {"scene-info", "[options] SCENE", about, options, 1, 1, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
