/* fuzz_queries.c: libFuzzer target for a queries file as simd-gather reads it: the reader's
 * checks (image size, pixels, the material table and indices, unit normals and directions;
 * past the checksum: reseal.h rewrites it after each mutation), then a gather of it with a
 * fixed photon map (tests/golden/photonmap-all.pm, or $PMTK_FUZZ_MAP), where the material
 * table and the glossy lobes are used. Seeds: the queries files of tests/golden. */
#include <stdint.h>

#include "fuzz_file.h"
#include "fuzz_gather.h"
#include "reseal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static pm_table_t map;
    static int ready;
    if (!ready)
        ready = fuzz_partner("PMTK_FUZZ_MAP", "tests/golden/photonmap-all.pm", &pm_photonmap_schema, &map);
    const char *path = fuzz_write_file(data, size, ".pm");
    pm_table_t q;
    if (!path || pm_table_read(path, &pm_queries_schema, pm_schema_required(&pm_queries_schema), &q) != PM_OK)
        return 0;
    fuzz_gather(&map, &q, path);
    pm_table_free(&q);
    return 0;
}
