/* metrics.h: how far an image is from a reference, as the numbers measure-error reports and an
 * error-against-run-time sweep plots. With t the test value and r the reference value of one
 * channel of one pixel, and eps keeping dark reference pixels from dominating:
 *
 *   rmse         = sqrt(mean (t - r)^2)                   W/(m^2 sr)
 *   relmse       = mean (t - r)^2 / (r^2 + eps)           (Rousselle et al. 2011's relative MSE)
 *   mean_abs_rel = mean |t - r| / (|r| + eps)
 *
 * over every pixel and channel. Sums are in double; images are at most 65536^2 pixels. */
#ifndef PM_IMAGE_METRICS_H
#define PM_IMAGE_METRICS_H

#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "image/rgb.h"

/* What the error image holds per value. */
typedef enum {
    PM_ERRIMG_ABS = 0, /* |t - r| */
    PM_ERRIMG_REL = 1  /* |t - r| / (|r| + eps) */
} pm_errimg_t;

/* Words for the --error-kind option, indexed by pm_errimg_t, NULL-terminated. */
extern const char *const pm_errimg_names[];

typedef struct {
    uint64_t values; /* 3 w h */
    double epsilon;  /* as given: added to r^2 ((W/(m^2 sr))^2) and to |r| (W/(m^2 sr)) */
    double rmse, relmse, mean_abs_rel;
    double max_abs; /* largest |t - r| */
    double mean_test, mean_ref;
    double ch_rmse[3]; /* rmse of R, G, B alone */
    /* The reference's own noise, when it reports its variance: E[(t - r)^2] = (t - R)^2 + var(r)
     * for the true R, so these are the floor under rmse and relmse that a better test cannot pass. */
    int has_ref_noise;
    double ref_rmse, ref_relmse;
} pm_image_errors_t;

/* The metrics of t against r, which must be of one size (PM_ERR_USAGE naming both otherwise),
 * and, when err_out is not NULL, the error image of the given kind: 3 w h floats, malloc'd
 * into *err_out (NULL after a failure). */
pm_result_t pm_image_errors(const pm_rgb_image_t *t, const pm_rgb_image_t *r, double epsilon, pm_errimg_t kind,
                            pm_image_errors_t *e_out, float **err_out);

/* The metrics as one JSON object (2-space indent, 9 significant digits) and a newline to out:
 * test, reference, width, height, values, epsilon, the metrics, rmse_rgb, and reference_rmse
 * and reference_relmse when the reference carries its variance. */
pm_result_t pm_image_errors_write_json(FILE *out, const pm_rgb_image_t *t, const pm_rgb_image_t *r,
                                       const pm_image_errors_t *e);

#endif
