/* texture.h: image textures of the scene model (MTL map_Kd, map_Ks, map_d; glTF base colour):
 * decoding PNG, JPEG, OpenEXR and TGA files or embedded images (base/imgdecode.h) into memory
 * once per stage, and looking them up with bilinear filtering and repeat addressing.
 *
 * 8-bit images keep their bytes (4 per texel: R G B A) and decode sRGB colour to linear at each
 * lookup through a 256-entry table; alpha, and the grey of a mask read as alpha, are linear.
 * OpenEXR images are linear already and kept as floats. Texture coordinates follow OBJ: (0, 0)
 * is the image's lower-left corner, v up (assimp turns glTF's v-down coordinates into this). */
#ifndef PM_TEXTURE_H
#define PM_TEXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

#define PM_TEXTURE_MAX_SIDE 65536 /* pixels: a larger image is refused */
/* bytes: one texture's decoded texels at most, unless the scene says otherwise (image_budgets) */
#define PM_TEXTURE_BUDGET_DEFAULT ((uint64_t)256 << 20)

typedef struct {
    char path[1024]; /* as resolved, for messages */
    uint32_t w, h;   /* pixels, 1 to PM_TEXTURE_MAX_SIDE */
    int has_alpha;   /* the file has an alpha channel (else A is 1) */
    int grey;        /* the file has one colour channel (R = G = B) */
    uint8_t *u8;     /* w * h * 4 bytes, rows from the top, or NULL */
    float *f32;      /* w * h * 4 linear floats (OpenEXR), or NULL */
    uint64_t hash;   /* XXH3-64 of the size and texels, for the scene's hash */
} pm_texture_t;

/* Reads an image file (its kind from its first bytes, checked against its name) into *out,
 * its texels taking at most max_bytes (4 bytes a texel for 8-bit images, 16 for OpenEXR), which
 * is checked before they are allocated. Errors (PM_ERR_INPUT) name the file and what is wrong:
 * missing or unreadable, not a regular file, not PNG, JPEG, OpenEXR or (named .tga) TGA, named
 * as another format than it holds, truncated or corrupt, 0 x 0 or wider or taller than
 * PM_TEXTURE_MAX_SIDE, above the budget (budget says how it is set, for the message; NULL: the
 * default), an OpenEXR value that is NaN, negative or above 1. */
pm_result_t pm_texture_load_budget(const char *path, uint64_t max_bytes, const char *budget, pm_texture_t *out);
/* pm_texture_load_budget with PM_TEXTURE_BUDGET_DEFAULT. */
pm_result_t pm_texture_load(const char *path, pm_texture_t *out);
/* Makes ready what lookups read besides the texels (the sRGB table); the loaders call it, and
 * so must any code that makes textures without them (render/scene_cache.c), before threads
 * look texels up. */
void pm_texture_prepare(void);
/* The same for size bytes in memory (a texture embedded in a glTF): name for messages, hint a
 * format name standing in for its extension ("png", "jpg") or NULL. */
pm_result_t pm_texture_decode(const char *name, const char *hint, const void *data, size_t size, uint64_t max_bytes,
                              const char *budget, pm_texture_t *out);
/* A texture from w x h raw texels, 4 bytes each (B G R A, rows from the top: assimp's aiTexel
 * of an uncompressed embedded texture), within max_bytes. */
pm_result_t pm_texture_from_bgra(const char *name, uint32_t w, uint32_t h, const uint8_t *bgra, uint64_t max_bytes,
                                 const char *budget, pm_texture_t *out);
/* The bytes t's texels take (what the budgets count). */
uint64_t pm_texture_bytes(const pm_texture_t *t);
/* A 1 x 1 texture of linear colour rgb (alpha 1), as float texels: the stand-in for a missing
 * file under missing_textures "magenta". */
pm_result_t pm_texture_solid(const char *name, const float rgb[3], pm_texture_t *out);
void pm_texture_free(pm_texture_t *t);

/* Bilinear lookup at texture coordinates (u, v), repeat addressing, into rgba_out: colour
 * linear (8-bit colour decoded from sRGB when srgb is 1, taken as linear bytes / 255 when 0),
 * alpha linear. Non-finite coordinates read texel (0, 0). */
void pm_texture_lookup(const pm_texture_t *t, float u, float v, int srgb, float rgba_out[4]);

/* The linear value of an 8-bit sRGB code (IEC 61966-2-1). */
float pm_srgb_to_linear(uint8_t c);

#endif
