/* rgb.c: reading an image into f64 RGB from a radiance buffer or an OpenEXR file (rgb.h),
 * for measure-error's test and reference. */
#include "image/rgb.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "formats/formats.h"

static const char *const channel_names[3] = {"R", "G", "B"};

/* An OpenEXR file starts with the magic number 20000630 (76 2f 31 01). */
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

static pm_result_t read_exr(const char *path, pm_rgb_image_t *im)
{
    float *f;
    im->kind = "exr";
    pm_result_t r = pm_exr_read_rgb(path, &im->w, &im->h, &f);
    if (r != PM_OK)
        return r;
    size_t n = (size_t)im->w * im->h * 3;
    im->rgb = malloc(n * sizeof *im->rgb);
    if (!im->rgb) {
        free(f);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for '%s': %zu values", path, n);
    }
    for (size_t i = 0; i < n; i++)
        im->rgb[i] = f[i];
    free(f);
    return PM_OK;
}

static pm_result_t read_radiance(const char *path, pm_rgb_image_t *im)
{
    pm_table_t t;
    im->kind = "radiance";
    pm_result_t r = pm_table_read(path, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, &t);
    if (r != PM_OK)
        return r;
    r = pm_header_get_image_size(&t.hdr, path, &im->w, &im->h);
    if (r == PM_OK) {
        size_t n = (size_t)t.count * 3;
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
    return r;
}

pm_result_t pm_rgb_image_read(const char *path, pm_rgb_image_t *im)
{
    memset(im, 0, sizeof *im);
    im->path = path;
    pm_result_t r = is_exr(path) ? read_exr(path, im) : read_radiance(path, im);
    size_t n = (size_t)im->w * im->h * 3;
    for (size_t i = 0; r == PM_OK && i < n; i++)
        if (!isfinite(im->rgb[i])) {
            size_t p = i / 3;
            r = pm_error_set(PM_ERR_INPUT, "'%s' pixel (%zu, %zu) channel %s is %g: no error is defined", path,
                             p % im->w, p / im->w, channel_names[i % 3], im->rgb[i]);
        }
    if (r != PM_OK)
        pm_rgb_image_free(im);
    return r;
}

void pm_rgb_image_free(pm_rgb_image_t *im)
{
    free(im->rgb);
    free(im->var);
    im->rgb = im->var = NULL;
}
