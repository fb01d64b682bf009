/* fuzz_img_exr.c: libFuzzer target for the OpenEXR decoder of base/imgdecode.h (fuzz_image.h).
 * Seeds: tests/fuzz/image-seeds.sh exr. */
#define FUZZ_IMAGE_NAME "fuzz.exr"
#include "fuzz_image.h"
