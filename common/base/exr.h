/* exr.h: OpenEXR images through the OpenEXR 3 C API (OpenEXRCore), for composite's HDR
 * output, the tests that read it back, and reference images from other renderers.
 *
 * One scanline part, channels R G B (stored B G R, the order OpenEXR sorts them in) and, with
 * pm_exr_write_channels, named layers beside them (albedo.R, normal.X, Z), ZIP
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

/* One channel of an image to write: its name ("R", "albedo.R", "Z"), the value of pixel i at
 * data[stride * i], and linear 1 for data that is not a colour (normals, depth: the hint lossy
 * codecs read). */
typedef struct {
    const char *name;
    const float *data;
    size_t stride;
    int linear;
} pm_exr_channel_t;

#define PM_EXR_MAX_CHANNELS 16

/* Writes w x h pixels of nch named channels (1 to PM_EXR_MAX_CHANNELS, names distinct) to
 * path, atomically, as pm_exr_write_rgb does: layers such as albedo.R albedo.G albedo.B beside
 * R G B (OpenEXR stores them sorted by name). The same contract on values. */
pm_result_t pm_exr_write_channels(const char *path, uint32_t w, uint32_t h, const pm_exr_channel_t *ch, size_t nch,
                                  pm_exr_pixel_t type, pm_exr_compression_t comp, const pm_exr_attr_t *attrs,
                                  size_t nattrs);

/* The layers a denoiser reads beside the beauty (Open Image Denoise, Blender): albedo.R/G/B,
 * normal.X/Y/Z, depth as Z, variance.R/G/B. A mask of them: */
enum { PM_EXR_AOV_ALBEDO = 1, PM_EXR_AOV_NORMAL = 2, PM_EXR_AOV_DEPTH = 4, PM_EXR_AOV_VARIANCE = 8 };
#define PM_EXR_AOV_SURFACE (PM_EXR_AOV_ALBEDO | PM_EXR_AOV_NORMAL | PM_EXR_AOV_DEPTH)
#define PM_EXR_AOV_NAMES "albedo,normal,depth,variance"

/* The mask of a comma-separated list of layer names (albedo, normal, depth, variance, each at
 * most once); PM_ERR_USAGE naming the word otherwise. option names the option in the message. */
pm_result_t pm_exr_aov_parse(const char *option, const char *list, unsigned *mask_out);

/* Appends to ch the channels of the layers in mask: albedo, normal and depth from surf (7 floats
 * a pixel: albedo RGB, normal XYZ, depth), variance from var (3 floats a pixel); returns how
 * many (at most 10). The caller has both arrays for the layers it asks for. */
size_t pm_exr_aov_channels(unsigned mask, const float *surf, const float *var, pm_exr_channel_t *ch);

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
