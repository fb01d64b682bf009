/* formats.c: the registry of every format pmtk reads, for pm-info and pm_schema_find. */
#include "formats/formats.h"

static const pm_schema_t *const all_schemas[] = {
    &pm_photons_schema,
    &pm_photonmap_schema,
    &pm_queries_schema,
    &pm_radiance_schema,
    &pm_aov_schema,
    &pm_density_schema,
    NULL,
};

const pm_schema_t *const *pm_schema_all(void) { return all_schemas; }
