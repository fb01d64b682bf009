/* composite.h: the sum of radiance buffers that the composite stage writes: the direct light
 * of trace-gather-points, the indirect light of a gather or its shards, each times a scale,
 * added in f64 into one image, then written as OpenEXR, an 8-bit PNG preview, or a radiance
 * buffer again.
 *
 *   pm_composite_open      every header first: resolution, scene and component checked
 *   pm_composite_sum       every buffer read in chunks and added, in the order given
 *   pm_composite_accumulate  optional: the sum is one progressive pass, averaged into a running
 *                          image (a state file) with its variance
 *   pm_composite_finish    the f32 pixels of the EXR, each value checked, luminance statistics
 *   pm_composite_write_*   the outputs, any of them
 *   pm_composite_free
 *
 * Memory is one f64 RGB accumulator and one f32 RGB image per pixel; the sum depends on
 * nothing but the buffers, their scales and their order. */
#ifndef PM_IMAGE_COMPOSITE_H
#define PM_IMAGE_COMPOSITE_H

#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "base/exr.h"
#include "image/tone.h"

/* Which buffers are added, by their header's component key. */
typedef enum {
    PM_ONLY_ALL = 0,      /* every buffer */
    PM_ONLY_DIRECT = 1,   /* only component=direct */
    PM_ONLY_INDIRECT = 2, /* only component=indirect */
    PM_ONLY_CAUSTIC = 3   /* only component=caustic (the caustic map seen at the first diffuse hits) */
} pm_composite_only_t;

/* Words for the --only option, indexed by pm_composite_only_t, NULL-terminated. */
extern const char *const pm_composite_only_names[];

typedef struct pm_composite pm_composite_t;

/* What a composite is, valid from pm_composite_open (sizes, buffers, components) and
 * pm_composite_finish (luminances, in the buffers' unit, W/(m^2 sr)). */
typedef struct {
    uint32_t width, height; /* pixels */
    uint64_t pixels;
    int buffers;            /* buffers added: those --only keeps */
    const char *components; /* "direct", "indirect" or "total" (direct and indirect, or a total buffer) */
    double luminance_min, luminance_max, luminance_mean; /* Rec. 709 weights */
    uint64_t passes;       /* after pm_composite_accumulate: passes in the running image; else 0 */
    double relative_error; /* after it: RMS over pixels and channels of standard error / mean (NAN: one pass) */
} pm_composite_info_t;

/* Splits an argument "FILE:SCALE" when what follows the last ':' is a whole number, which must
 * be finite; otherwise the whole word is the path (scale 1), so "a:b.pm" is a path and a file
 * named "x:2" is given as "x:2:1". *path_out is malloc'd. */
pm_result_t pm_composite_parse_input(const char *arg, char **path_out, double *scale_out);

/* Opens the n buffers args[i] ("FILE[:SCALE]", "-" for stdin at most once) and checks every
 * header before any pixel is read: each must have the first's resolution and SCENE, and with
 * only != PM_ONLY_ALL each must be direct, indirect or caustic, and one at least of that component.
 * Free with pm_composite_free, also after a failure (*c_out is then set or NULL). */
pm_result_t pm_composite_open(pm_composite_t **c_out, char *const *args, int n, pm_composite_only_t only);
/* The same with buffer i read as the next document of the stream files[i] (docs/formats.md,
 * "Streams"; args[i] names it in messages, with its scale); a stream that has ended is an error. */
pm_result_t pm_composite_open_streams(pm_composite_t **c_out, char *const *args, FILE *const *files, int n,
                                      pm_composite_only_t only);

/* Called for a buffer whose content equals an earlier one's, most likely a slip. */
typedef void (*pm_composite_note_fn)(void *ctx, const char *path, const char *same_as, uint64_t hash);

/* Reads every buffer kept and adds it, times its scale, in the order given. The provenance
 * of the outputs gathers the kept buffers' COMMAND lines once each and SCENE, then this
 * command (argc, argv) and one INPUT per buffer read. note (may be NULL) hears of repeats. */
pm_result_t pm_composite_sum(pm_composite_t *c, int argc, char **argv, pm_composite_note_fn note, void *note_ctx);

/* Takes the sum as the image of one progressive pass of weight w (> 0; 1 for passes of one
 * size, else the pass's size: its variance is taken as sigma^2 / w; an adaptive pass, whose
 * buffers' header key adaptive names its density map, weighs pixel p by w times its primary
 * rays over the pass's, and the state then keeps per-pixel sums, pm_composite_write_state) and averages it into the
 * running image of the earlier passes, held in the radiance buffer `state` (rgb: the weighted
 * mean of the passes, variance: the squared standard error of that mean; header passes=N,
 * alpha, radius1, and weight=W, the sum of the weights, when it is not N). A missing state
 * file is no pass yet. West's weighted form of Welford's update, so that nothing but the state
 * is read: with W the weights so far, mean += (x - mean) w / W and the weighted sum of squared
 * deviations S (stored as variance W (n - 1)) += w (x - mean_old) (x - mean_new); with every
 * weight 1 that is Welford's, to the bit. pass (0: any) must be the state's passes + 1, and
 * the pass's alpha and radius1 (from its gather's header) the state's, so a pass is neither
 * added twice nor mixed with another schedule. From here on the outputs are the mean, and
 * pm_composite_write_radiance writes the new state. */
pm_result_t pm_composite_accumulate(pm_composite_t *c, const char *state, uint64_t pass, double w);

/* The progressive pass the kept buffers name (header key pass, as the tracers and the gather
 * write it with --pass) into *pass_out, 0 when none does; buffers that disagree, or a key that
 * is not a pass of at least 1, are an input error. Valid from pm_composite_open. */
pm_result_t pm_composite_pass(const pm_composite_t *c, uint64_t *pass_out);

/* Converts the sum to the f32 pixels of the EXR and takes the luminance statistics. A value
 * beyond half (half != 0) or float, or not finite, is an error naming the pixel: a scale
 * can overflow even though every input is finite. */
pm_result_t pm_composite_finish(pm_composite_t *c, int half);

/* After pm_composite_finish: the layers (PM_EXR_AOV_* of base/exr.h) pm_composite_write_exr adds
 * beside R G B: variance from the running image (after pm_composite_accumulate; a usage error
 * without it), albedo, normal and depth from aov_path (an aov file, trace-gather-points --aov, of
 * the image's size and scene; a usage error when NULL and they are asked for). */
pm_result_t pm_composite_set_aov(pm_composite_t *c, unsigned mask, const char *aov_path);

/* After pm_composite_finish: the OpenEXR image (R G B, half or float as finished), with the
 * provenance as string attributes SOFTWARE, SCENE, components, COMMAND.i and INPUT.i; after
 * pm_composite_accumulate also passes, alpha and radius1 (the schedule). */
pm_result_t pm_composite_write_exr(const pm_composite_t *c, const char *path, pm_exr_compression_t comp);

/* The 8-bit sRGB preview (pm_tone_write_png) of the f64 sum. */
pm_result_t pm_composite_write_png(const pm_composite_t *c, const char *path, double exposure, pm_tone_t tone,
                                   double *clipped_out);

/* The f64 sum as a pmtk radiance buffer (RGB channel only), with the first buffer's bounds,
 * the provenance, width, height and component; after pm_composite_accumulate the running
 * image: the mean, the variance channel and the keys passes, alpha, radius1 and
 * relative_error. */
pm_result_t pm_composite_write_radiance(const pm_composite_t *c, const char *path);

/* The running image as pm_composite_write_radiance writes it, and, once an adaptive pass is in it,
 * its per-pixel summed weights as the density file STATE.weight beside it (header key
 * pixel_weights=1 in the state): the new state of pm_composite_accumulate. */
pm_result_t pm_composite_write_state(const pm_composite_t *c, const char *path);

/* After pm_composite_accumulate: the sample-count multiplier of the next adaptive passes from
 * the running image (image/adaptive.h, pm_adaptive_make) as a density file, with this command's
 * provenance (argc, argv). */
pm_result_t pm_composite_write_adaptive_map(const pm_composite_t *c, const char *path, int argc, char **argv);

const pm_composite_info_t *pm_composite_info(const pm_composite_t *c);

void pm_composite_free(pm_composite_t *c);

#endif
