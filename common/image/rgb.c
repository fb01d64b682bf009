/* rgb.c: reading an image into f64 RGB from a radiance buffer, an OpenEXR file or a PFM
 * (rgb.h), for measure-error's test and reference: the last two are how other renderers'
 * references arrive. */
#include "image/rgb.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "formats/formats.h"
#include "image/pfm.h"

static const char *const channel_names[3] = {"R", "G", "B"};

typedef enum { KIND_RADIANCE, KIND_EXR, KIND_PFM } kind_t;

/* The kind of file at path by its first bytes: an OpenEXR file starts with the magic number
 * 20000630 (76 2f 31 01), a PFM with "PF" or "Pf" and whitespace; anything else (and stdin)
 * goes to the pmtk reader, which names the error when it is no radiance buffer either. */
static kind_t kind_of(const char *path)
{
    if (!strcmp(path, "-"))
        return KIND_RADIANCE;
    FILE *f = fopen(path, "rb");
    if (!f)
        return KIND_RADIANCE; /* the pmtk reader reports the open error */
    unsigned char m[4] = {0};
    size_t n = fread(m, 1, 4, f);
    fclose(f);
    if (n == 4 && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01)
        return KIND_EXR;
    return pm_pfm_magic(m, n) ? KIND_PFM : KIND_RADIANCE;
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

static pm_result_t read_pfm(const char *path, pm_rgb_image_t *im)
{
    int channels;
    im->kind = "pfm";
    return pm_pfm_read(path, &im->w, &im->h, &channels, &im->rgb);
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
    kind_t kind = kind_of(path);
    pm_result_t r = kind == KIND_EXR   ? read_exr(path, im)
                    : kind == KIND_PFM ? read_pfm(path, im)
                                       : read_radiance(path, im);
    size_t n = (size_t)im->w * im->h * 3;
    for (size_t i = 0; r == PM_OK && i < n; i++)
        if (!isfinite(im->rgb[i])) {
            size_t p = i / 3;
            r = pm_error_set(PM_ERR_INPUT, "'%s' pixel (%zu, %zu) channel %s is %g: no error is defined", path,
                             p % im->w, p / im->w, channel_names[i % 3], im->rgb[i]);
        } else if (im->rgb[i] < 0 && kind != KIND_RADIANCE) {
            /* Radiance is never negative; an image from elsewhere that holds a negative value
             * was filtered with negative lobes (Mitchell, Lanczos) and is no pixel mean. */
            size_t p = i / 3;
            r = pm_error_set(PM_ERR_INPUT,
                             "'%s' pixel (%zu, %zu) channel %s is %g: radiance cannot be negative (render the "
                             "reference with a box pixel filter)",
                             path, p % im->w, p / im->w, channel_names[i % 3], im->rgb[i]);
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
