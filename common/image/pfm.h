/* pfm.h: the Portable Float Map (PFM), the plain float image pbrt, Mitsuba and many tools
 * write, read so that an image from another renderer can be a reference.
 *
 * A PFM is a text header, "PF" (RGB) or "Pf" (grey), whitespace, the width and height in
 * decimal, whitespace, a scale, one whitespace character, then width x height pixels of 3 or
 * 1 IEEE float32 values with no padding, rows from the BOTTOM of the image to the top. The
 * scale's sign gives the byte order (negative: little-endian, positive: big-endian) and its
 * magnitude multiplies every value, as pbrt-v4 reads it (writers put 1 or -1 there). */
#ifndef PM_IMAGE_PFM_H
#define PM_IMAGE_PFM_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

/* Largest width or height read, pixels (the limit of pmtk's images). */
#define PM_PFM_MAX_SIDE 65536u

/* Whether the n bytes at head start a PFM: "PF" or "Pf" and a whitespace character. */
int pm_pfm_magic(const unsigned char *head, size_t n);

/* Reads the PFM at path into a malloc'd interleaved RGB array *rgb_out of *w_out x *h_out
 * pixels, rows from the top (the file's last row first), grey copied to all three channels;
 * *channels_out is 3 for "PF", 1 for "Pf". Refused with PM_ERR_INPUT and a message naming
 * the file: a malformed header, a size of 0 or above PM_PFM_MAX_SIDE, a scale of 0 or not
 * finite, fewer pixel bytes than the header says (truncated) or more (trailing bytes), and a
 * value that is NaN, infinite or negative (naming the pixel, counted from the top left, and
 * the channel). A file that cannot be opened or read is PM_ERR_IO. On failure *rgb_out is
 * NULL. */
pm_result_t pm_pfm_read(const char *path, uint32_t *w_out, uint32_t *h_out, int *channels_out, double **rgb_out);

#endif
