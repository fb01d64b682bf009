/* fuzz_photonmap.c: libFuzzer target for the photon map as simd-gather reads it: the
 * reader's value and KD-tree checks (past the checksum: reseal.h rewrites it after each
 * mutation), then a gather of a fixed queries file (tests/golden/queries-all.pm, or
 * $PMTK_FUZZ_QUERIES) through the tree. A map the checks pass must be safe to walk. Seeds:
 * the photon maps of tests/golden. Run with `make fuzz`. */
#include <stdint.h>

#include "fuzz_file.h"
#include "fuzz_gather.h"
#include "reseal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static pm_table_t queries;
    static int ready;
    if (!ready)
        ready = fuzz_partner("PMTK_FUZZ_QUERIES", "tests/golden/queries-all.pm", &pm_queries_schema, &queries);
    const char *path = fuzz_write_file(data, size, ".pm");
    pm_table_t map;
    if (!path || pm_table_read(path, &pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema), &map) != PM_OK)
        return 0;
    fuzz_gather(&map, &queries, "queries");
    pm_table_free(&map);
    return 0;
}
