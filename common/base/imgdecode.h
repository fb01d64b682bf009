/* imgdecode.h: the one way pmtk decodes an image file it did not make (textures, sky maps,
 * textures embedded in a glTF): the format sniffed from the content and checked against the
 * name, the declared size checked against a memory budget before any large allocation, and
 * every decoder strict (a truncated or corrupt file is an error, never grey or uninitialised
 * texels). PNG through libpng, JPEG through libjpeg(-turbo), both with their warnings taken as
 * errors; OpenEXR through base/exr.h; Truevision TGA and Radiance RGBE (.hdr) by our own small
 * decoders (docs/formats.md, Images). Safe from any thread (no shared state). */
#ifndef PM_IMGDECODE_H
#define PM_IMGDECODE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

typedef enum {
    PM_IMG_PNG = 1 << 0,
    PM_IMG_JPEG = 1 << 1,
    PM_IMG_EXR = 1 << 2,
    PM_IMG_TGA = 1 << 3,
    PM_IMG_HDR = 1 << 4, /* Radiance RGBE */
} pm_img_format_t;

#define PM_IMG_MAX_SIDE 65536u /* pixels: a wider or taller image is refused */

/* A decoded image: 8-bit formats as 4 bytes per pixel (R G B A, colour as stored, sRGB for
 * textures), the HDR formats (OpenEXR, RGBE) as `fchannels` linear floats per pixel (R G B, and
 * A = 1 when 4). Rows from the top. */
typedef struct {
    pm_img_format_t format;
    uint32_t w, h;
    int grey;      /* the file has one colour channel */
    int has_alpha; /* the file has an alpha channel (8-bit formats) */
    int fchannels; /* floats per pixel in f32: 3 or 4 */
    uint8_t *u8;   /* w * h * 4 bytes, or NULL */
    float *f32;    /* w * h * fchannels floats, or NULL */
} pm_img_t;

typedef struct {
    unsigned formats;   /* the pm_img_format_t bits accepted */
    uint64_t max_bytes; /* the decoded pixels (u8 or f32 above) may take at most this */
    int fchannels;      /* floats per pixel for the HDR formats: 3 or 4 */
    const char *what;   /* "texture", "sky map": the first word of messages */
    const char *budget; /* how the budget is set, for messages ("image_budgets.texture_mib 256"), or NULL */
} pm_img_limits_t;

/* The format's name ("PNG", "JPEG", ...). */
const char *pm_img_format_name(pm_img_format_t f);

/* Decodes size bytes of data into *out. name is the file's name (checked against the content:
 * a .tga holding a PNG is refused) and names it in messages; hint, when not NULL, is a format
 * hint standing in for the name's extension (a glTF's embedded "png", "jpg"). Errors
 * (PM_ERR_INPUT; PM_ERR_NOMEM): a format not in limits->formats, a disguised or unknown format
 * (BMP, GIF, PSD, ... named as such), a size above PM_IMG_MAX_SIDE or limits->max_bytes, a
 * truncated or corrupt file. *out is empty after a failure. */
pm_result_t pm_img_decode(const char *name, const char *hint, const void *data, size_t size,
                          const pm_img_limits_t *limits, pm_img_t *out);

/* Reads the whole of file path into a malloc'd *data_out without blocking: a FIFO, device or
 * folder is refused (opened O_NONBLOCK, then checked to be a regular file), and so is a file
 * larger than max_size bytes. */
pm_result_t pm_img_read_file(const char *path, const char *what, uint64_t max_size, void **data_out, size_t *size_out);

/* pm_img_read_file and pm_img_decode: the file may be at most 2 * max_bytes + 1 MiB long. */
pm_result_t pm_img_load(const char *path, const pm_img_limits_t *limits, pm_img_t *out);

void pm_img_free(pm_img_t *im);

#endif
