/* radiance.c: per-pixel radiance buffers, written by trace-gather-points (direct light)
 * and simd-gather (indirect), added by composite. Records are pixels in row order from
 * the top-left; header keys width, height and component (direct, indirect, caustic or total). The
 * optional variance channel is the estimate's own squared standard error per pixel:
 * trace-reference writes it so that a reference says how wrong it is. */
#include <inttypes.h>

#include "formats/formats.h"

static const pm_channel_t radiance_channels[] = {
    {"rgb", PM_TYPE_F64, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "W/(m^2 sr)", "RGB radiance toward the camera"},
    /* Optional: only an estimator that knows its own spread writes it (trace-reference). */
    {"variance", PM_TYPE_F64, 3, PM_CH_NONNEG, "(W/(m^2 sr))^2",
     "variance of the pixel's estimate (its squared standard error), RGB"},
};

static pm_result_t validate_header(const pm_header_t *h, const char *path)
{
    pm_result_t r = pm_header_check_pixels(h, path);
    if (r != PM_OK)
        return r;
    const char *c = pm_header_get(h, "component");
    if (!c || (strcmp(c, "direct") && strcmp(c, "indirect") && strcmp(c, "caustic") && strcmp(c, "total")))
        return pm_error_set(PM_ERR_INPUT,
                            "radiance buffer '%s': component '%s' is not direct, indirect, caustic or total", path,
                            c ? c : "(missing)");
    return PM_OK;
}

const pm_schema_t pm_radiance_schema = {
    .name = "radiance",
    .major = 2,
    .minor = 0,
    .oldest_major = 1,
    .title = "radiance buffer",
    .channels = radiance_channels,
    .nchannels = sizeof radiance_channels / sizeof radiance_channels[0],
    .validate_header = validate_header,
};
