/* fuzz_img_hdr.c: libFuzzer target for the Radiance RGBE decoder of base/imgdecode.h (fuzz_image.h).
 * Seeds: tests/fuzz/image-seeds.sh hdr. */
#define FUZZ_IMAGE_NAME "fuzz.hdr"
#include "fuzz_image.h"
