/* adaptive.h: adaptive progressive passes (docs/accuracy.md, "Adaptive sampling"): a
 * per-pixel sample-count multiplier made from the running image, the primary rays it gives a
 * pixel, and the density files (formats/density.c) that carry it from composite (or pm-render)
 * to trace-gather-points --adaptive and back to composite, which weighs each pixel's pass by
 * the rays the pixel got.
 *
 *   pm_adaptive_make   the multiplier from a running image's mean, variance and weights
 *   pm_adaptive_count  a pixel's primary rays in a pass of `primary` rays per pixel
 *   pm_adaptive_read / pm_adaptive_write   density files of either kind, checked */
#ifndef PM_IMAGE_ADAPTIVE_H
#define PM_IMAGE_ADAPTIVE_H

#include <stdint.h>

#include "base/error.h"
#include "formats/pmfile.h"

#define PM_ADAPTIVE_MIN 0.25       /* the multiplier's clamp, times the mean multiplier (1) */
#define PM_ADAPTIVE_MAX 8.0        /*   ... a pixel gets 1/4 to 8 times the pass's rays */
#define PM_ADAPTIVE_EPS 0.01       /* added to the squared luminance: measure-error's relMSE epsilon */
#define PM_ADAPTIVE_RAYS_MAX 65536 /* primary rays a pixel may get in one pass */

enum { PM_DENSITY_MULTIPLIER = 0, PM_DENSITY_WEIGHT = 1 }; /* pm_density_kind_names' indices */

/* The multiplier m[0 .. w h) of the next passes from a running image of `passes` passes: mean
 * and var (3 per pixel: the weighted mean and its squared standard error, composite
 * --accumulate's rgb and variance), wsum (per pixel, the summed pass weights; NULL: w0 for every
 * pixel). Aims at relative MSE: each pixel's rays in proportion to its per-sample standard
 * deviation of luminance, sqrt(var wsum) (the channels' deviations summed with Rec. 709
 * weights), over sqrt(luminance^2 + PM_ADAPTIVE_EPS); then the 3 x 3 maximum (a pixel whose few
 * rays all missed a bright patch beside it is not starved), clamped to [PM_ADAPTIVE_MIN,
 * PM_ADAPTIVE_MAX] by a scale found by bisection so that the mean is 1 (the pass's rays
 * unchanged; where clamping cannot reach 1 the scale that comes nearest). Fewer than two passes,
 * or no spread anywhere: every m is 1. Deterministic: sums in pixel order. */
void pm_adaptive_make(const double *mean, const double *var, const double *wsum, double w0, uint64_t passes, uint32_t w,
                      uint32_t h, float *m);

/* Primary rays of a pixel of multiplier m in a pass of `primary` per pixel: m primary rounded
 * to the nearest, at least 1. m * primary above PM_ADAPTIVE_RAYS_MAX returns 0 (the caller's
 * error). */
uint32_t pm_adaptive_count(float m, uint32_t primary);

/* Reads the density file at path, which must be of `kind` and w x h (0 x 0: any size, given
 * back in *w_out, *h_out when not NULL): *v_out (malloc'd, w h values) and its content hash.
 * A wrong kind or size, a value that is not a finite number above 0, a truncated file: an
 * input error naming the file and the value. */
pm_result_t pm_adaptive_read(const char *path, int kind, uint32_t w, uint32_t h, float **v_out, uint64_t *hash_out,
                             pm_header_t *hdr_out);

/* Writes v (w h values > 0) as a density file of `kind` at path, atomically, with prov's
 * provenance (COMMAND lines, SCENE; may be NULL), the keys of extra (NULL-terminated
 * "KEY=VALUE" strings, may be NULL) and INPUT lines of `inputs` (NULL-terminated path and
 * hash pairs as "PATH xxh3:HASH", may be NULL). */
pm_result_t pm_adaptive_write(const char *path, int kind, uint32_t w, uint32_t h, const float *v,
                              const pm_header_t *prov, int argc, char **argv, const char *const *extra);

/* The multiplier from the running image `state` (composite --accumulate's, with STATE.weight
 * beside it when its header says pixel_weights=1) into the density file `map` (pm-render's
 * adaptive passes). *passes_out: the state's passes. */
pm_result_t pm_adaptive_from_state(const char *state, const char *map, int argc, char **argv, uint64_t *passes_out);

/* The path of the per-pixel weights beside a running image: STATE.weight (*out malloc'd). */
pm_result_t pm_adaptive_weight_path(const char *state, char **out);

#endif
