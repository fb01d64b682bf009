/* fuzz_scene.c: libFuzzer target for the scene-file reader (JSON part; meshes named in
 * it resolve against /tmp and are usually missing, which must be a clean error). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "render/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[64];
    if (!path[0]) {
        snprintf(path, sizeof path, "/tmp/pmtk-fuzz-%ld.json", (long)getpid());
        /* the load in this process, as the guarded child runs it (a fork per input is slow) */
        setenv("PMTK_IMPORT_SECONDS", "0", 1);
        setenv("PMTK_IMPORT_MB", "0", 1);
    }
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    fwrite(data, 1, size, f);
    fclose(f);
    pm_scene_t s;
    if (pm_scene_load(path, &s) == PM_OK)
        pm_scene_free(&s);
    return 0;
}
