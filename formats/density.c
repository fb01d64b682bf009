/* density.c: per-pixel positive numbers that steer and weigh adaptive progressive passes
 * (docs/formats.md, "density"). Two kinds, by the header key `kind`:
 *   multiplier  a pass's primary rays per pixel over the pass's own count (composite
 *               --adaptive-map, pm-render ADAPTIVE) -> trace-gather-points --adaptive
 *   weight      the running image's per-pixel sum of the passes' weights, beside the state
 *               of composite --accumulate once a pass was adaptive (STATE.weight)
 * Records are pixels in row order from the top-left, as the radiance buffer's; header keys
 * width, height and kind. */
#include "formats/formats.h"

static const pm_channel_t density_channels[] = {
    {"value", PM_TYPE_F32, 1, PM_CH_REQUIRED | PM_CH_POSITIVE, "1",
     "the pixel's sample-count multiplier (kind=multiplier) or its summed pass weight (kind=weight)"},
};

const char *const pm_density_kind_names[] = {"multiplier", "weight", NULL};

static pm_result_t validate_header(const pm_header_t *h, const char *path)
{
    pm_result_t r = pm_header_check_pixels(h, path);
    if (r != PM_OK)
        return r;
    const char *k = pm_header_get(h, "kind");
    if (!k || (strcmp(k, "multiplier") && strcmp(k, "weight")))
        return pm_error_set(PM_ERR_INPUT, "density map '%s': kind '%s' is not multiplier or weight", path,
                            k ? k : "(missing)");
    return PM_OK;
}

const pm_schema_t pm_density_schema = {
    .name = "density",
    .major = 2, /* the container's first version without CHANNEL_MASK, as every format's newest */
    .minor = 0,
    .oldest_major = 2,
    .title = "density map",
    .channels = density_channels,
    .nchannels = sizeof density_channels / sizeof density_channels[0],
    .validate_header = validate_header,
};
