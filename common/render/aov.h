/* aov.h: what a denoiser wants beside the beauty (Open Image Denoise, Blender's): per pixel, the
 * first surface's albedo, shading normal and distance, the mean over the pixel's primary rays,
 * for trace-gather-points --aov and trace-reference --aov (docs/formats.md, the aov format).
 *
 * The rays are the eye tracers' own: P per pixel at pm_pixel_offset over the pixel's area (or
 * through its centre), from the pixel's Philox stream 4p (the jitter stream of
 * render/eyetrace.c). A ray that escapes adds zero; a mirror or glass surface shows its own
 * albedo and normal (the rays do not follow it). Rows are independent, so the buffer is the
 * same bytes for any thread count. */
#ifndef PM_AOV_H
#define PM_AOV_H

#include <stdint.h>

#include "base/error.h"
#include "formats/pmfile.h"
#include "render/rt.h"
#include "render/scene.h"

#define PM_AOV_FLOATS 7 /* per pixel: albedo RGB, normal XYZ, depth (m) */

/* Fills out (w * h * PM_AOV_FLOATS floats, pixel y * w + x) for the scene's camera at w x h,
 * primary rays per pixel (>= 1), pixel PM_PIXEL_BOX or PM_PIXEL_CENTER, seed the eye rays'.
 * PM_ERR_NOMEM when a thread's rays cannot be allocated. */
pm_result_t pm_aov_trace(const pm_scene_t *s, const pm_rt_t *rt, uint32_t w, uint32_t h, uint32_t primary, int pixel,
                         uint64_t seed, int threads, float *out);

/* The header of an aov file of these rays: this command, SCENE, width, height, primary, pixel,
 * seed (pm_header_init'd by the caller with pm_aov_schema; COUNT w * h). */
pm_result_t pm_aov_header(pm_header_t *hd, int argc, char **argv, const pm_scene_t *s, uint32_t w, uint32_t h,
                          uint32_t primary, int pixel, uint64_t seed);

#endif
