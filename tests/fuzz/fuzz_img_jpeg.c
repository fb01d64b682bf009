/* fuzz_img_jpeg.c: libFuzzer target for the JPEG decoder of base/imgdecode.h (fuzz_image.h).
 * Seeds: tests/fuzz/image-seeds.sh jpeg. */
#define FUZZ_IMAGE_NAME "fuzz.jpg"
#include "fuzz_image.h"
