/* fuzz_scene_cache.c: libFuzzer target for the scene cache's decoder (render/scene_cache.c), past
 * its checksum (reseal.h): the bytes as a guarded load's child would hand them to its parent, so
 * that the payload's counts, lengths and indices are what is tried; whatever they say, the
 * decoder gives a scene or a miss, never a crash. LLVMFuzzerInitialize puts the Cornell box's
 * cache, made by this build, into the corpus as a seed (its BUILD key is this build's). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/scene.h"
#include "render/scene_cache.h"
#include "render/scene_load.h"
#include "reseal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    setenv("PMTK_IMPORT_SECONDS", "0", 1); /* the load in this process: no child per input */
    setenv("PMTK_IMPORT_MB", "0", 1);
    pm_scene_t s;
    unsigned char *bytes;
    size_t n;
    if (pm_scene_load("scenes/cornell-box/scene.json", &s) != PM_OK)
        return 0;
    if (pm_scene_cache_encode(&s, &bytes, &n) == PM_OK) {
        FILE *f = fopen("build/fuzz/corpus-fuzz_scene_cache/seed-cornell-box", "wb");
        if (f) {
            fwrite(bytes, 1, n, f);
            fclose(f);
        }
        free(bytes);
    }
    pm_scene_free(&s);
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    unsigned char *copy = malloc(size ? size : 1); /* the decoder writes into its bytes (and mends them) */
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    pm_scene_t s;
    pm_scene_cache_status_t st;
    if (pm_scene_cache_decode(copy, size, &s, &st) == PM_OK && st.hit)
        pm_scene_free(&s);
    free(copy);
    return 0;
}
