/* metrics.c: the error of an image against a reference (RMSE, relative MSE, mean absolute
 * relative error, an error image) and its JSON report; see metrics.h. measure-error's work. */
#include "image/metrics.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

const char *const pm_errimg_names[] = {"abs", "rel", NULL};

pm_result_t pm_image_errors(const pm_rgb_image_t *t, const pm_rgb_image_t *r, double epsilon, pm_errimg_t kind,
                            pm_image_errors_t *e, float **err_out)
{
    float *err = NULL;
    if (err_out)
        *err_out = NULL;
    /* Two images of different sizes are the wrong pair of files to compare: the command line
     * is at fault (exit 2), not either file. */
    if (t->w != r->w || t->h != r->h)
        return pm_error_set(PM_ERR_USAGE, "'%s' is %" PRIu32 "x%" PRIu32 " but '%s' is %" PRIu32 "x%" PRIu32, t->path,
                            t->w, t->h, r->path, r->w, r->h);
    if (err_out && !(*err_out = err = malloc((size_t)t->w * t->h * 3 * sizeof *err)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the error image: %" PRIu32 "x%" PRIu32, t->w, t->h);
    size_t n = (size_t)t->w * t->h * 3;
    double s2 = 0, srel2 = 0, sabs = 0, st = 0, sr = 0, ch2[3] = {0, 0, 0};
    memset(e, 0, sizeof *e);
    for (size_t i = 0; i < n; i++) {
        double a = t->rgb[i], b = r->rgb[i], d = a - b;
        s2 += d * d;
        ch2[i % 3] += d * d;
        srel2 += d * d / (b * b + epsilon);
        double rel = fabs(d) / (fabs(b) + epsilon);
        sabs += rel;
        st += a;
        sr += b;
        e->max_abs = fmax(e->max_abs, fabs(d));
        if (r->var) {
            e->ref_rmse += r->var[i];
            e->ref_relmse += r->var[i] / (b * b + epsilon);
        }
        if (err)
            err[i] = (float)(kind == PM_ERRIMG_REL ? rel : fabs(d));
    }
    double dn = (double)n;
    e->values = n;
    e->epsilon = epsilon;
    e->rmse = sqrt(s2 / dn);
    e->relmse = srel2 / dn;
    e->mean_abs_rel = sabs / dn;
    e->mean_test = st / dn;
    e->mean_ref = sr / dn;
    for (int c = 0; c < 3; c++)
        e->ch_rmse[c] = sqrt(ch2[c] / (dn / 3));
    e->has_ref_noise = r->var != NULL;
    e->ref_rmse = sqrt(e->ref_rmse / dn);
    e->ref_relmse /= dn;
    return PM_OK;
}

pm_result_t pm_image_errors_write_json(FILE *out, const pm_rgb_image_t *t, const pm_rgb_image_t *r,
                                       const pm_image_errors_t *e)
{
    json_t *j = json_object();
    if (!j)
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing the result");
    json_object_set_new(j, "test", json_string(t->path));
    json_object_set_new(j, "reference", json_string(r->path));
    json_object_set_new(j, "width", json_integer(t->w));
    json_object_set_new(j, "height", json_integer(t->h));
    json_object_set_new(j, "values", json_integer((json_int_t)e->values));
    json_object_set_new(j, "epsilon", json_real(e->epsilon));
    json_object_set_new(j, "rmse", json_real(e->rmse));
    json_object_set_new(j, "relmse", json_real(e->relmse));
    json_object_set_new(j, "mean_abs_rel", json_real(e->mean_abs_rel));
    json_object_set_new(j, "max_abs", json_real(e->max_abs));
    json_object_set_new(j, "mean_test", json_real(e->mean_test));
    json_object_set_new(j, "mean_reference", json_real(e->mean_ref));
    json_t *ch = json_array();
    for (int c = 0; c < 3; c++)
        json_array_append_new(ch, json_real(e->ch_rmse[c]));
    json_object_set_new(j, "rmse_rgb", ch);
    if (e->has_ref_noise) {
        json_object_set_new(j, "reference_rmse", json_real(e->ref_rmse));
        json_object_set_new(j, "reference_relmse", json_real(e->ref_relmse));
    }
    int bad = json_dumpf(j, out, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
              fputc('\n', out) == EOF;
    json_decref(j);
    return bad ? pm_error_set(PM_ERR_IO, "cannot write the result") : PM_OK;
}
