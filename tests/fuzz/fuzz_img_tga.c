/* fuzz_img_tga.c: libFuzzer target for the TGA decoder of base/imgdecode.h (fuzz_image.h).
 * Seeds: tests/fuzz/image-seeds.sh tga. */
#define FUZZ_IMAGE_NAME "fuzz.tga"
#include "fuzz_image.h"
