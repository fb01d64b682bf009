/* aov.c: per-pixel surface buffers for denoisers (Open Image Denoise, Blender's), written by
 * trace-gather-points --aov and read by composite --aov-buffer, which lays them beside the
 * beauty as EXR layers. Records are pixels in row order from the top-left, as the radiance
 * buffer's; header keys width and height. Each value is the mean over the pixel's primary rays
 * of what the ray's first surface (past mirrors and glass, the first other one) shows; a ray
 * that escapes adds zero, so a pixel of sky is all zero. */
#include "formats/formats.h"

static const pm_channel_t aov_channels[] = {
    {"albedo", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "1",
     "directional albedo toward the eye at the first surface, RGB (textures included)"},
    {"normal", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_FINITE, "1",
     "shading normal at the first surface, facing the eye, world space (length <= 1: a mean)"},
    {"depth", PM_TYPE_F32, 1, PM_CH_REQUIRED | PM_CH_NONNEG, "m", "distance from the eye to the first surface"},
};

const pm_schema_t pm_aov_schema = {
    .name = "aov",
    .major = 2,
    .minor = 0,
    .oldest_major = 2,
    .title = "AOV buffer",
    .channels = aov_channels,
    .nchannels = sizeof aov_channels / sizeof aov_channels[0],
    .validate_header = pm_header_check_pixels,
};
