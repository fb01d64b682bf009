/* photons.c: the photons format, written by trace-photons and read by build-photonmap.
 * One record per photon stored at a diffuse hit, first hits included and marked by
 * depth 0, so one file serves both a global and an indirect-only map. */
#include "formats/formats.h"

static const pm_channel_t photon_channels[] = {
    {"position", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_FINITE, "m", "where the photon landed"},
    {"power", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "W", "RGB flux the photon carries"},
    {"normal", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_UNIT, "1",
     "unit surface normal on the side the photon arrived from"},
    {"direction", PM_TYPE_F32, 3, PM_CH_UNIT, "1",
     "unit direction back toward where the photon came from (glossy scenes only)"},
    {"depth", PM_TYPE_U32, 1, PM_CH_REQUIRED, "1", "diffuse bounces before this hit; 0 is a first hit"},
};

const pm_schema_t pm_photons_schema = {
    .name = "photons",
    .major = 2,
    .minor = 0,
    .oldest_major = 1,
    .title = "photons file",
    .channels = photon_channels,
    .nchannels = sizeof photon_channels / sizeof photon_channels[0],
};
