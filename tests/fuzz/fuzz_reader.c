/* fuzz_reader.c: libFuzzer target for every pmtk reader. The input is written to a file
 * and read as a table of whatever format its header names (header, values, tree shape,
 * checksum); any input must end in PM_OK or a clean error, never a crash or a leak.
 * The seed corpus is tests/golden. Run with `make fuzz`. */
#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

#include "formats/formats.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[64];
    if (!path[0])
        snprintf(path, sizeof path, "/tmp/pmtk-fuzz-%ld.pm", (long)getpid());
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    fwrite(data, 1, size, f);
    fclose(f);
    pm_table_t t;
    if (pm_table_read(path, NULL, 0, &t) == PM_OK)
        pm_table_free(&t);
    return 0;
}
