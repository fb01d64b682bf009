/* measure-error: how far a rendered image is from a reference, as numbers an error-against-
 * run-time sweep can plot. Reads two images of the same size, each a pmtk radiance file
 * (simd-gather, composite --radiance) or an OpenEXR image (composite, trace-reference), and
 * writes one JSON object: RMSE, relative MSE and mean absolute relative error over every pixel
 * and channel, optionally an error image.
 *
 *   composite ... -o test.exr ──┐
 *   reference.exr ──────────────┴─> measure-error -> JSON on stdout [, error.exr]
 *
 * With t the test value and r the reference value of one channel of one pixel, and eps
 * (--epsilon) keeping dark reference pixels from dominating:
 *   rmse         = sqrt(mean (t - r)^2)                   W/(m^2 sr)
 *   relmse       = mean (t - r)^2 / (r^2 + eps)           (Rousselle et al. 2011's relative MSE)
 *   mean_abs_rel = mean |t - r| / (|r| + eps)
 * A NaN or Inf in either image is an error naming the pixel: no error number means anything
 * then. Sums are in double; the inputs are at most 65536^2 pixels. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "base/exr.h"
#include "base/stage.h"
#include "base/version.h"
#include "formats/formats.h"

enum { ERRIMG_ABS = 0, ERRIMG_REL = 1 };
static const char *const errimg_names[] = {"abs", "rel", NULL};

typedef struct {
    double epsilon;         /* added to r^2 (relmse) and |r| (mean_abs_rel), (W/(m^2 sr))^2 and W/(m^2 sr) */
    const char *error_path; /* --error-image FILE.exr, NULL for none */
    int error_kind;         /* ERRIMG_* */
} measure_options_t;

/* One input image as interleaved linear RGB in double, rows from the top. */
typedef struct {
    const char *path;
    const char *kind; /* "exr" or "radiance" */
    uint32_t w, h;
    double *rgb;      /* malloc'd, 3 w h values */
    double *var;      /* the variance of each value's estimate when the file carries it (trace-reference), or NULL */
} image_t;

static const char *const channel_names[3] = {"R", "G", "B"};

/* An OpenEXR file starts with the magic number 20000630 (76 2f 31 01); anything else is read
 * as a pmtk file, whose reader gives the error when it is neither. */
static int is_exr(const char *path)
{
    if (!strcmp(path, "-"))
        return 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0; /* the pmtk reader reports the open error */
    unsigned char m[4] = {0};
    size_t n = fread(m, 1, 4, f);
    fclose(f);
    return n == 4 && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01;
}

static pm_result_t image_read(const char *path, image_t *im)
{
    memset(im, 0, sizeof *im);
    im->path = path;
    size_t n;
    if (is_exr(path)) {
        float *f;
        im->kind = "exr";
        pm_result_t r = pm_exr_read_rgb(path, &im->w, &im->h, &f);
        if (r != PM_OK)
            return r;
        n = (size_t)im->w * im->h * 3;
        im->rgb = malloc(n * sizeof *im->rgb);
        if (!im->rgb) {
            free(f);
            return pm_error_set(PM_ERR_NOMEM, "out of memory for '%s': %zu values", path, n);
        }
        for (size_t i = 0; i < n; i++)
            im->rgb[i] = f[i];
        free(f);
    } else {
        pm_table_t t;
        im->kind = "radiance";
        pm_result_t r = pm_table_read(path, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, &t);
        if (r != PM_OK)
            return r;
        r = pm_header_get_image_size(&t.hdr, path, &im->w, &im->h);
        if (r == PM_OK) {
            n = (size_t)t.count * 3;
            im->rgb = malloc(n * sizeof *im->rgb);
            if (!im->rgb)
                r = pm_error_set(PM_ERR_NOMEM, "out of memory for '%s': %zu values", path, n);
            else
                memcpy(im->rgb, t.col[PM_RADIANCE_RGB], n * sizeof *im->rgb);
            if (r == PM_OK && t.col[PM_RADIANCE_VARIANCE]) {
                if (!(im->var = malloc(n * sizeof *im->var)))
                    r = pm_error_set(PM_ERR_NOMEM, "out of memory for '%s': %zu values", path, n);
                else
                    memcpy(im->var, t.col[PM_RADIANCE_VARIANCE], n * sizeof *im->var);
            }
        }
        pm_table_free(&t);
        if (r != PM_OK) {
            free(im->rgb);
            free(im->var);
            im->rgb = im->var = NULL;
            return r;
        }
    }
    n = (size_t)im->w * im->h * 3;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(im->rgb[i])) {
            size_t p = i / 3;
            pm_result_t r = pm_error_set(PM_ERR_INPUT, "'%s' pixel (%zu, %zu) channel %s is %g: no error is defined",
                                         path, p % im->w, p / im->w, channel_names[i % 3], im->rgb[i]);
            free(im->rgb);
            free(im->var);
            im->rgb = im->var = NULL;
            return r;
        }
    return PM_OK;
}

typedef struct {
    uint64_t values;
    double rmse, relmse, mean_abs_rel, max_abs, mean_test, mean_ref;
    double ch_rmse[3];
    /* The reference's own noise, when it reports its variance: E[(t - r)^2] = (t - R)^2 + var(r)
     * for the true R, so these are the floor under rmse and relmse that a better test cannot pass. */
    double ref_rmse, ref_relmse;
} errors_t;

/* The metrics, and the error image into err (3 w h floats) when err is not NULL. */
static void measure(const image_t *t, const image_t *r, const measure_options_t *o, errors_t *e, float *err)
{
    size_t n = (size_t)t->w * t->h * 3;
    double s2 = 0, srel2 = 0, sabs = 0, st = 0, sr = 0, ch2[3] = {0, 0, 0};
    memset(e, 0, sizeof *e);
    for (size_t i = 0; i < n; i++) {
        double a = t->rgb[i], b = r->rgb[i], d = a - b;
        s2 += d * d;
        ch2[i % 3] += d * d;
        srel2 += d * d / (b * b + o->epsilon);
        double rel = fabs(d) / (fabs(b) + o->epsilon);
        sabs += rel;
        st += a;
        sr += b;
        e->max_abs = fmax(e->max_abs, fabs(d));
        if (r->var) {
            e->ref_rmse += r->var[i];
            e->ref_relmse += r->var[i] / (b * b + o->epsilon);
        }
        if (err)
            err[i] = (float)(o->error_kind == ERRIMG_REL ? rel : fabs(d));
    }
    double dn = (double)n;
    e->values = n;
    e->rmse = sqrt(s2 / dn);
    e->relmse = srel2 / dn;
    e->mean_abs_rel = sabs / dn;
    e->mean_test = st / dn;
    e->mean_ref = sr / dn;
    for (int c = 0; c < 3; c++)
        e->ch_rmse[c] = sqrt(ch2[c] / (dn / 3));
    e->ref_rmse = sqrt(e->ref_rmse / dn);
    e->ref_relmse /= dn;
}

static pm_result_t write_json(FILE *out, const image_t *t, const image_t *r, const measure_options_t *o,
                              const errors_t *e)
{
    json_t *j = json_object();
    if (!j)
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing the result");
    json_object_set_new(j, "test", json_string(t->path));
    json_object_set_new(j, "reference", json_string(r->path));
    json_object_set_new(j, "width", json_integer(t->w));
    json_object_set_new(j, "height", json_integer(t->h));
    json_object_set_new(j, "values", json_integer((json_int_t)e->values));
    json_object_set_new(j, "epsilon", json_real(o->epsilon));
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
    if (r->var) {
        json_object_set_new(j, "reference_rmse", json_real(e->ref_rmse));
        json_object_set_new(j, "reference_relmse", json_real(e->ref_relmse));
    }
    int bad = json_dumpf(j, out, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
              fputc('\n', out) == EOF;
    json_decref(j);
    return bad ? pm_error_set(PM_ERR_IO, "cannot write the result") : PM_OK;
}

static pm_result_t run(pm_stage_t *st, const measure_options_t *o)
{
    image_t t, r;
    const char *tn = st->args.args[0], *rn = st->args.args[1];
    if (!strcmp(tn, "-") && !strcmp(rn, "-"))
        return pm_error_set(PM_ERR_USAGE, "only one of TEST and REFERENCE can be stdin");
    pm_result_t res = image_read(tn, &t);
    if (res != PM_OK)
        return res;
    res = image_read(rn, &r);
    if (res != PM_OK) {
        free(t.rgb);
        free(t.var);
        return res;
    }
    float *err = NULL;
    if (t.w != r.w || t.h != r.h) {
        res = pm_error_set(PM_ERR_INPUT, "'%s' is %" PRIu32 "x%" PRIu32 " but '%s' is %" PRIu32 "x%" PRIu32, tn, t.w,
                           t.h, rn, r.w, r.h);
    } else if (o->error_path && !(err = malloc((size_t)t.w * t.h * 3 * sizeof *err))) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory for the error image: %" PRIu32 "x%" PRIu32, t.w, t.h);
    } else {
        errors_t e;
        FILE *out;
        measure(&t, &r, o, &e, err);
        st->items = (uint64_t)t.w * t.h;
        pm_stage_stat_double(st, "rmse", e.rmse);
        pm_stage_stat_double(st, "relmse", e.relmse);
        pm_stage_stat_double(st, "mean_abs_rel", e.mean_abs_rel);
        if (err) {
            char cmd[1024];
            pm_stage_command_line(st, cmd, sizeof cmd);
            const pm_exr_attr_t attrs[] = {{"SOFTWARE", "pmtk " PM_VERSION_STRING},
                                           {"COMMAND.0", cmd},
                                           {"components", o->error_kind == ERRIMG_REL ? "error-rel" : "error-abs"}};
            res = pm_exr_write_rgb(o->error_path, t.w, t.h, err, PM_EXR_FLOAT, PM_EXR_ZIP, attrs, 3);
        }
        if (res == PM_OK)
            res = pm_stage_open_output(st, &out);
        if (res == PM_OK)
            res = write_json(out, &t, &r, o, &e);
    }
    free(err);
    free(t.rgb);
    free(r.rgb);
    free(t.var);
    free(r.var);
    return res;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    measure_options_t o = {.epsilon = 1e-2, .error_path = NULL, .error_kind = ERRIMG_ABS};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"epsilon", 0, PM_OPT_DOUBLE, &o.epsilon, "E",
         "added to r^2 in relmse and to |r| in mean_abs_rel, so dark reference pixels do not dominate", 1e-300, 1e300,
         NULL},
        {"error-image", 0, PM_OPT_STRING, &o.error_path, "FILE", "also write the per-pixel error as a float EXR",
         1, 0, NULL},
        {"error-kind", 0, PM_OPT_CHOICE, &o.error_kind, "KIND",
         "what the error image holds: |t - r| or |t - r| / (|r| + epsilon)", 1, 0, errimg_names},
        {0},
    };
    const pm_cli_t cli = {"measure-error", "[options] TEST REFERENCE",
                          "Error of an image against a reference (pmtk radiance files or OpenEXR, same size): RMSE, "
                          "relative MSE and mean absolute relative error as JSON.",
                          options, 2, 2};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
