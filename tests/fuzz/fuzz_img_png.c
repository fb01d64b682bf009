/* fuzz_img_png.c: libFuzzer target for the PNG decoder of base/imgdecode.h (fuzz_image.h).
 * Seeds: tests/fuzz/image-seeds.sh png. */
#define FUZZ_IMAGE_NAME "fuzz.png"
#include "fuzz_image.h"
