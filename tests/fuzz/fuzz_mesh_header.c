/* fuzz_mesh_header.c: libFuzzer target for the mesh header checks that run before libassimp
 * (common/render/mesh_guard.c, pm_scene_mesh_precheck): the input is written as a .ply, an
 * .off and an .stl file and each is checked; every outcome must be PM_OK or one error line,
 * never a crash, a hang or an over-read. Seeds: assimp-testmodels' PLY, OFF and STL files. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "render/scene.h"
#include "render/scene_load.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const ext[] = {"ply", "off", "stl"};
    for (int i = 0; i < 3; i++) {
        char path[64];
        snprintf(path, sizeof path, "/tmp/pmtk-fuzz-%ld.%s", (long)getpid(), ext[i]);
        FILE *f = fopen(path, "wb");
        if (!f)
            return 0;
        fwrite(data, 1, size, f);
        fclose(f);
        if (pm_scene_mesh_precheck(path) != PM_OK && strchr(pm_error_message(), '\n'))
            __builtin_trap(); /* a message of more than one line */
        unlink(path);
    }
    return 0;
}
