/* measure-error: how far a rendered image is from a reference, as numbers an error-against-
 * run-time sweep can plot. Reads two images of the same size, each a pmtk radiance file
 * (simd-gather, composite --radiance), an OpenEXR image (composite, trace-reference, or
 * another renderer: pbrt-v4, Mitsuba 3) or a PFM, and writes one JSON object: RMSE, relative
 * MSE and mean absolute relative error over every pixel and channel, optionally an error image.
 *
 *   composite ... -o test.exr ──────────┐
 *   reference.exr or reference.pfm ─────┴─> measure-error -> JSON on stdout [, error.exr]
 *
 * The images are read by common/image/rgb.c and compared by common/image/metrics.c, whose
 * header gives the formulas (eps is --epsilon). A NaN or Inf in either image, or a negative
 * value in an EXR or PFM, is an error naming the pixel: no error number means anything then.
 * Images of two sizes are a usage error (exit 2): the wrong pair of files was given. */
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "base/stage.h"
#include "base/version.h"
#include "image/metrics.h"
#include "image/rgb.h"

typedef struct {
    double epsilon;         /* added to r^2 (relmse) and |r| (mean_abs_rel), (W/(m^2 sr))^2 and W/(m^2 sr) */
    const char *error_path; /* --error-image FILE.exr, NULL for none */
    int error_kind;         /* pm_errimg_t */
} measure_options_t;

static pm_result_t run(pm_stage_t *st, const measure_options_t *o)
{
    pm_stage_output_set(st); /* the JSON and the error image appear together, or neither */
    pm_rgb_image_t t, r;
    const char *tn = st->args.args[0], *rn = st->args.args[1];
    if (!strcmp(tn, "-") && !strcmp(rn, "-"))
        return pm_error_set(PM_ERR_USAGE, "only one of TEST and REFERENCE can be stdin");
    pm_result_t res = pm_rgb_image_read(tn, &t);
    if (res != PM_OK)
        return res;
    if ((res = pm_rgb_image_read(rn, &r)) != PM_OK) {
        pm_rgb_image_free(&t);
        return res;
    }
    float *err = NULL;
    pm_image_errors_t e;
    FILE *out;
    res = pm_image_errors(&t, &r, o->epsilon, (pm_errimg_t)o->error_kind, &e, o->error_path ? &err : NULL);
    if (res == PM_OK) {
        st->items = (uint64_t)t.w * t.h;
        pm_stage_stat_double(st, "rmse", e.rmse);
        pm_stage_stat_double(st, "relmse", e.relmse);
        pm_stage_stat_double(st, "mean_abs_rel", e.mean_abs_rel);
    }
    if (res == PM_OK && err) {
        char cmd[1024];
        pm_stage_command_line(st, cmd, sizeof cmd);
        const pm_exr_attr_t attrs[] = {{"SOFTWARE", "pmtk " PM_VERSION_STRING},
                                       {"COMMAND.0", cmd},
                                       {"components", o->error_kind == PM_ERRIMG_REL ? "error-rel" : "error-abs"}};
        res = pm_exr_write_rgb(o->error_path, t.w, t.h, err, PM_EXR_FLOAT, PM_EXR_ZIP, attrs, 3);
    }
    if (res == PM_OK)
        res = pm_stage_open_output(st, &out);
    if (res == PM_OK)
        res = pm_image_errors_write_json(out, &t, &r, &e);
    free(err);
    pm_rgb_image_free(&t);
    pm_rgb_image_free(&r);
    return res;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    measure_options_t o = {.epsilon = 1e-2, .error_path = NULL, .error_kind = PM_ERRIMG_ABS};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"epsilon", 0, PM_OPT_DOUBLE, &o.epsilon, "E",
         "added to r^2 in relmse and to |r| in mean_abs_rel, so dark reference pixels do not dominate", 1e-300, 1e300,
         NULL},
        {"error-image", 0, PM_OPT_OUTPUT, &o.error_path, "FILE", "also write the per-pixel error as a float EXR", 1, 0,
         NULL},
        {"error-kind", 0, PM_OPT_CHOICE, &o.error_kind, "KIND",
         "what the error image holds: |t - r| or |t - r| / (|r| + epsilon)", 1, 0, pm_errimg_names},
        {0},
    };
    static const char about[] =
        "Error of an image against a reference (pmtk radiance files, OpenEXR or PFM, same size): RMSE, "
        "relative MSE and mean absolute relative error as JSON.";
    const pm_cli_t cli = {"measure-error", "[options] TEST REFERENCE", about, options, 2, 2, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
