/* tone.h: from linear radiance to what a screen shows: the luminance of an RGB value, the
 * tone curves of composite's preview, and the 8-bit sRGB preview itself (PNG). */
#ifndef PM_IMAGE_TONE_H
#define PM_IMAGE_TONE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

typedef enum {
    PM_TONE_SRGB = 0,  /* clip at 1, then the sRGB transfer */
    PM_TONE_FILMIC = 1 /* an ACES filmic fit rolls highlights off before the sRGB transfer */
} pm_tone_t;

/* Words for the --tone option, indexed by pm_tone_t, NULL-terminated. */
extern const char *const pm_tone_names[];

/* Relative luminance of linear RGB with the Rec. 709 / sRGB primaries, in the unit of rgb. */
double pm_luminance(const double rgb[3]);

/* Narkowicz's fit of the ACES filmic curve: [0, inf) to [0, 1], about 0.8 at x = 1; 0 for
 * x <= 0 and NaN. */
float pm_tone_filmic(float x);

/* The 8-bit preview of n interleaved RGB pixels: each value times 2^exposure (EV), the
 * tone curve, then the sRGB transfer, into rgb8_out (3 n bytes). Returns how many of the
 * 3 n values reached white (1 or more before the transfer). */
uint64_t pm_tone_rgb8(const double *rgb, size_t n, double exposure, pm_tone_t tone, uint8_t *rgb8_out);

/* The same preview written as a PNG of w x h pixels (rows from the top) to path, atomically;
 * *clipped_out is the fraction of values that reached white (0 for an empty image). */
pm_result_t pm_tone_write_png(const char *path, const double *rgb, uint32_t w, uint32_t h, double exposure,
                              pm_tone_t tone, double *clipped_out);

#endif
