/* fuzz_radiance.c: libFuzzer target for a radiance buffer as composite, pm-compare and
 * measure-error read it (pm_rgb_image_read: the table, its width and height against COUNT,
 * the optional variance), past the checksum (reseal.h rewrites it after each mutation).
 * Seeds: the radiance buffers of tests/golden. */
#include <stdint.h>

#include "fuzz_file.h"
#include "image/rgb.h"
#include "reseal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write_file(data, size, ".pm");
    pm_rgb_image_t im;
    if (path && pm_rgb_image_read(path, &im) == PM_OK)
        pm_rgb_image_free(&im);
    return 0;
}
