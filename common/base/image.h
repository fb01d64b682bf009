/* image.h: 8-bit previews for people who just want to look (PNG through libpng).
 * HDR output goes through OpenEXR in composite; this is the quick look. */
#ifndef PM_IMAGE_H
#define PM_IMAGE_H

#include <stdint.h>

#include "base/error.h"

/* Writes an sRGB 8-bit RGB PNG of w x h pixels, rows top to bottom, atomically. */
pm_result_t pm_png_write_rgb8(const char *path, uint32_t w, uint32_t h, const uint8_t *rgb);

/* Linear [0, 1] -> sRGB-encoded 8-bit value (IEC 61966-2-1 transfer), clamped; NaN -> 0. */
uint8_t pm_srgb8(float linear);

#endif
