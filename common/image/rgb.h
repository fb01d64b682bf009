/* rgb.h: an image as interleaved linear RGB in double, read from any kind of file an image
 * can come in: a pmtk radiance buffer (simd-gather, composite --radiance, trace-reference with
 * its per-pixel variance), an OpenEXR image (composite, trace-reference, pbrt-v4, Mitsuba 3;
 * the layouts base/exr.h reads) or a PFM (image/pfm.h). */
#ifndef PM_IMAGE_RGB_H
#define PM_IMAGE_RGB_H

#include <stdint.h>

#include "base/error.h"

typedef struct {
    const char *path; /* as given, not owned */
    const char *kind; /* "exr", "pfm" or "radiance" */
    uint32_t w, h;    /* pixels */
    double *rgb;      /* malloc'd, 3 w h values, rows from the top, W/(m^2 sr) */
    double *var;      /* malloc'd variance of each value's estimate when the file carries it, or NULL */
} pm_rgb_image_t;

/* Reads path ("-" for stdin, then a radiance buffer) into im. An OpenEXR file and a PFM are
 * known by their magic numbers; anything else is read as a radiance buffer, whose reader
 * names the error when it is none of them. A NaN or Inf value, or a negative one in an EXR or
 * PFM, is an error (PM_ERR_INPUT) naming the pixel and channel. On failure im holds nothing
 * to free. */
pm_result_t pm_rgb_image_read(const char *path, pm_rgb_image_t *im);

void pm_rgb_image_free(pm_rgb_image_t *im);

#endif
