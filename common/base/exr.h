/* exr.h: OpenEXR images through the OpenEXR 3 C API (OpenEXRCore), for composite's HDR
 * output, the tests that read it back, and reference images from other renderers.
 *
 * One scanline part, channels R G B (stored B G R, the order OpenEXR sorts them in), ZIP
 * compression by default, float or half. String attributes carry provenance. Writes go
 * through a temporary file renamed into place (common/base/atomic.h); OpenEXR needs a seekable
 * file, so there is no stdout variant, and an EXR for a FIFO or device is written to a
 * temporary file first and copied in when complete. */
#ifndef PM_EXR_H
#define PM_EXR_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

typedef enum { PM_EXR_FLOAT = 0, PM_EXR_HALF = 1 } pm_exr_pixel_t;
typedef enum { PM_EXR_ZIP = 0, PM_EXR_NONE = 1, PM_EXR_PIZ = 2 } pm_exr_compression_t;

/* A string attribute; name at most 31 bytes (OpenEXR's limit without long names). */
typedef struct {
    const char *name;
    const char *value;
} pm_exr_attr_t;

/* Largest finite half value: a pixel above it cannot be written as half. */
#define PM_EXR_HALF_MAX 65504.0f

/* Writes w x h pixels of interleaved linear RGB (rows top to bottom, rgb[3 * (y * w + x) + c])
 * to path, atomically. Every value must be finite and, for half, within +-PM_EXR_HALF_MAX:
 * the caller checks (composite names the pixel); a value outside fails with PM_ERR_INTERNAL. */
pm_result_t pm_exr_write_rgb(const char *path, uint32_t w, uint32_t h, const float *rgb, pm_exr_pixel_t type,
                             pm_exr_compression_t comp, const pm_exr_attr_t *attrs, size_t nattrs);

/* Reads the first part of an OpenEXR file, as composite, pbrt-v4 and Mitsuba 3 write it,
 * into a malloc'd interleaved array *rgb_out of *w_out x *h_out pixels (the data window, rows
 * from the top whatever the file's line order). Read: scanline or tiled storage (of a
 * mipmapped or ripmapped file, the full-resolution level), any compression OpenEXR decodes,
 * channels R G B of type half, float or uint (uint converted to the nearest float), other
 * channels (A, AOV layers) ignored, or a Y channel alone (grey, copied to R G and B).
 * Refused with PM_ERR_INPUT and a message naming the file and what it holds: deep images,
 * luminance-chroma (Y RY BY), no R G B or Y channel, subsampled channels. *rgb_out is NULL
 * after a failure. */
pm_result_t pm_exr_read_rgb(const char *path, uint32_t *w_out, uint32_t *h_out, float **rgb_out);

/* pm_exr_read_rgb on size bytes of data in memory (a texture embedded in a glTF, a file the
 * caller has read); name is for messages. A data window of more than max_pixels pixels is
 * refused (PM_ERR_INPUT) before anything of its size is allocated. */
pm_result_t pm_exr_read_rgb_mem(const char *name, const void *data, size_t size, uint64_t max_pixels, uint32_t *w_out,
                                uint32_t *h_out, float **rgb_out);

/* The value of string attribute name of the first part, malloc'd into *value_out, or
 * PM_ERR_INPUT when there is none (or it is not a string). */
pm_result_t pm_exr_read_string_attr(const char *path, const char *name, char **value_out);

#endif
