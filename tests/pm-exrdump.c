/* pm-exrdump: reads an OpenEXR image back through common/base/exr.c (the OpenEXR C API) and prints
 * it as text, for the stage tests of composite:
 *
 *   pm-exrdump FILE            "size W H", then one line per pixel: "x y r g b" (%.9g)
 *   pm-exrdump FILE ATTR...    the value of each string attribute, one per line
 *   pm-exrdump --channels FILE "channels NAME...": every channel's name in the file's order
 *                              (sorted), then one line per pixel: "x y v..." (%.9g, each value
 *                              converted to float; scanline files, as pmtk writes them)
 *
 * Exit 0 ok, 1 when the file or an attribute cannot be read. */
#include <inttypes.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"

/* Every channel of a scanline image, read straight through the OpenEXR C API: the layers
 * (albedo.R, normal.X, Z) that pm_exr_read_rgb does not read. */
static int dump_channels(const char *path)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    const exr_attr_chlist_t *cl = NULL;
    exr_attr_box2i_t dw;
    int32_t lines = 1;
    if (exr_start_read(&ctx, path, &init) || exr_get_channels(ctx, 0, &cl) || exr_get_data_window(ctx, 0, &dw) ||
        exr_get_scanlines_per_chunk(ctx, 0, &lines)) {
        fprintf(stderr, "pm-exrdump: cannot read '%s'\n", path);
        return 1;
    }
    int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1, n = cl->num_channels;
    float *v = calloc((size_t)w * h * n, sizeof *v), *plane = malloc((size_t)w * lines * n * 4);
    printf("channels");
    for (int c = 0; c < n; c++)
        printf(" %s", cl->entries[c].name.str);
    printf("\n");
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int live = 0, bad = !v || !plane;
    for (int y = 0; y < h && !bad; y += lines) {
        exr_chunk_info_t ci;
        bad = exr_read_scanline_chunk_info(ctx, 0, dw.min.y + y, &ci) != EXR_ERR_SUCCESS;
        if (!bad)
            bad = (live ? exr_decoding_update(ctx, 0, &ci, &dec) : exr_decoding_initialize(ctx, 0, &ci, &dec)) !=
                  EXR_ERR_SUCCESS;
        if (bad)
            break;
        live = 1;
        for (int k = 0; k < dec.channel_count; k++) { /* the decoder's channels are the list's, in order */
            exr_coding_channel_info_t *ch = &dec.channels[k];
            ch->decode_to_ptr = (uint8_t *)(plane + (size_t)k * w * lines);
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = 4;
            ch->user_line_stride = 4 * ci.width;
        }
        bad = exr_decoding_choose_default_routines(ctx, 0, &dec) || exr_decoding_run(ctx, 0, &dec);
        for (int c = 0; !bad && c < n; c++)
            for (int i = 0; i < ci.width * ci.height; i++)
                v[((size_t)(ci.start_y - dw.min.y) * w + i) * n + c] = plane[(size_t)c * w * lines + i];
    }
    if (live)
        exr_decoding_destroy(ctx, &dec);
    exr_finish(&ctx);
    for (int i = 0; !bad && i < w * h; i++) {
        printf("%d %d", i % w, i / w);
        for (int c = 0; c < n; c++)
            printf(" %.9g", (double)v[(size_t)i * n + c]);
        printf("\n");
    }
    free(v);
    free(plane);
    if (bad)
        fprintf(stderr, "pm-exrdump: cannot decode '%s'\n", path);
    return bad;
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--channels"))
        return dump_channels(argv[2]);
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
