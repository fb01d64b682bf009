/* fuzz_image.h: the body of the image decoder targets (fuzz_img_*.c): the input decoded from
 * memory by pm_img_decode (base/imgdecode.h) as a file named FUZZ_IMAGE_NAME, so that the
 * format sniffed by content must agree with the name, as for a texture or sky map on disk.
 * Budget 64 MiB, so that a declared size libFuzzer finds cannot take the machine; RGBA floats,
 * as textures take them. Seeds: tests/fuzz/image-seeds.sh. */
#ifndef PM_FUZZ_IMAGE_H
#define PM_FUZZ_IMAGE_H

#include <stdint.h>

#include "base/imgdecode.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pm_img_limits_t lim = {PM_IMG_PNG | PM_IMG_JPEG | PM_IMG_EXR | PM_IMG_TGA | PM_IMG_HDR, (uint64_t)64 << 20, 4,
                           "texture", NULL};
    pm_img_t im;
    if (pm_img_decode(FUZZ_IMAGE_NAME, NULL, data, size, &lim, &im) == PM_OK) {
        /* every texel written: reading them all lets MSan-like checks and ASan see them */
        volatile uint64_t sum = 0;
        size_t n = (size_t)im.w * im.h * 4;
        for (size_t i = 0; im.u8 && i < n; i++)
            sum += im.u8[i];
        for (size_t i = 0; im.f32 && i < n; i++)
            sum += (uint64_t)(im.f32[i] != im.f32[i]);
        pm_img_free(&im);
    }
    return 0;
}

#endif
