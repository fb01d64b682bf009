/* pm-exrdump: reads an OpenEXR image back through common/base/exr.c (the OpenEXR C API) and prints
 * it as text, for the stage tests of composite:
 *
 *   pm-exrdump FILE            "size W H", then one line per pixel: "x y r g b" (%.9g)
 *   pm-exrdump FILE ATTR...    the value of each string attribute, one per line
 *
 * Exit 0 ok, 1 when the file or an attribute cannot be read. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/exr.h"

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: pm-exrdump FILE [ATTRIBUTE...]\n");
        return 2;
    }
    if (argc > 2) {
        for (int i = 2; i < argc; i++) {
            char *v;
            if (pm_exr_read_string_attr(argv[1], argv[i], &v) != PM_OK) {
                fprintf(stderr, "pm-exrdump: %s\n", pm_error_message());
                return 1;
            }
            printf("%s\n", v);
            free(v);
        }
        return 0;
    }
    uint32_t w, h;
    float *rgb;
    if (pm_exr_read_rgb(argv[1], &w, &h, &rgb) != PM_OK) {
        fprintf(stderr, "pm-exrdump: %s\n", pm_error_message());
        return 1;
    }
    printf("size %" PRIu32 " %" PRIu32 "\n", w, h);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            const float *p = rgb + 3 * ((size_t)y * w + x);
            printf("%" PRIu32 " %" PRIu32 " %.9g %.9g %.9g\n", x, y, (double)p[0], (double)p[1], (double)p[2]);
        }
    free(rgb);
    return 0;
}
