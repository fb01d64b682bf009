/* imgdecode.c: image files pmtk did not make, decoded strictly (imgdecode.h). The format comes
 * from the first bytes and must agree with the name's extension; the declared size is checked
 * against PM_IMG_MAX_SIDE and the caller's byte budget before the pixels are allocated; libpng
 * and libjpeg warnings (a CRC error, premature end of data, corrupt entropy data) are errors.
 * TGA and Radiance RGBE are decoded here: every byte read is bounds-checked, a truncated file is
 * an error, and every output pixel is written. Used by render/texture.c (textures, embedded
 * glTF textures) and render/envmap_load.c (sky maps). */
#include "base/imgdecode.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* after stdio.h: jpeglib.h uses FILE without including it */
#include <jpeglib.h>

#include "base/exr.h"

#define MIB (1024.0 * 1024.0)

const char *pm_img_format_name(pm_img_format_t f)
{
    switch (f) {
    case PM_IMG_PNG: return "PNG";
    case PM_IMG_JPEG: return "JPEG";
    case PM_IMG_EXR: return "OpenEXR";
    case PM_IMG_TGA: return "TGA";
    case PM_IMG_HDR: return "Radiance HDR";
    }
    return "unknown";
}

void pm_img_free(pm_img_t *im)
{
    free(im->u8);
    free(im->f32);
    memset(im, 0, sizeof *im);
}

/* ---- format by content and by name */

/* The format of the first bytes, 0 when none of ours; *other_out names a format pmtk knows by
 * its signature and does not read (so that a BMP named .tga is called a BMP). */
static unsigned sniff(const uint8_t *d, size_t n, const char **other_out)
{
    *other_out = NULL;
    if (n >= 8 && memcmp(d, "\x89PNG\r\n\x1a\n", 8) == 0)
        return PM_IMG_PNG;
    if (n >= 3 && d[0] == 0xff && d[1] == 0xd8 && d[2] == 0xff)
        return PM_IMG_JPEG;
    if (n >= 4 && memcmp(d, "\x76\x2f\x31\x01", 4) == 0)
        return PM_IMG_EXR;
    if (n >= 2 && d[0] == '#' && d[1] == '?')
        return PM_IMG_HDR;
    static const struct {
        const char *magic;
        size_t len;
        const char *name;
    } others[] = {{"BM", 2, "BMP"},
                  {"GIF8", 4, "GIF"},
                  {"8BPS", 4, "Photoshop (PSD)"},
                  {"DDS ", 4, "DDS"},
                  {"II*\0", 4, "TIFF"},
                  {"MM\0*", 4, "TIFF"},
                  {"\x53\x80\xf6\x34", 4, "Softimage PIC"},
                  {"\xabKTX", 4, "KTX"},
                  {"qoif", 4, "QOI"},
                  {"\0\0\0\x0cjP  ", 8, "JPEG 2000"},
                  {"\xff\x0a", 2, "JPEG XL"},
                  {"\0\0\0\x0cJXL ", 8, "JPEG XL"}};
    for (size_t i = 0; i < sizeof others / sizeof others[0]; i++)
        if (n >= others[i].len && memcmp(d, others[i].magic, others[i].len) == 0) {
            *other_out = others[i].name;
            return 0;
        }
    if (n >= 12 && memcmp(d, "RIFF", 4) == 0 && memcmp(d + 8, "WEBP", 4) == 0) {
        *other_out = "WebP";
        return 0;
    }
    if (n >= 3 && d[0] == 'P' && d[1] >= '1' && d[1] <= '7' && (d[2] == '\n' || d[2] == ' ' || d[2] == '\r')) {
        *other_out = "netpbm (PNM/PAM)";
        return 0;
    }
    if (n >= 3 && d[0] == 'P' && (d[1] == 'F' || d[1] == 'f') && (d[2] == '\n' || d[2] == '\r')) {
        *other_out = "PFM";
        return 0;
    }
    return 0;
}

/* The format an extension (or a glTF format hint) names, 0 for none of ours. */
static unsigned by_extension(const char *ext)
{
    static const struct {
        const char *ext;
        unsigned f;
    } exts[] = {{"png", PM_IMG_PNG},  {"jpg", PM_IMG_JPEG},  {"jpeg", PM_IMG_JPEG},
                {"jpe", PM_IMG_JPEG}, {"jfif", PM_IMG_JPEG}, {"exr", PM_IMG_EXR},
                {"tga", PM_IMG_TGA},  {"hdr", PM_IMG_HDR},   {"rgbe", PM_IMG_HDR}};
    for (size_t i = 0; ext && i < sizeof exts / sizeof exts[0]; i++)
        if (strcasecmp(ext, exts[i].ext) == 0)
            return exts[i].f;
    return 0;
}

static const char *extension_of(const char *name)
{
    const char *base = strrchr(name, '/');
    base = base ? base + 1 : name;
    const char *dot = strrchr(base, '.');
    return dot && dot[1] ? dot + 1 : NULL;
}

/* The bytes w x h pixels take decoded, checked against the side limit and the budget. */
static pm_result_t check_size(const char *name, const pm_img_limits_t *lim, uint64_t w, uint64_t h, int is_float)
{
    if (w == 0 || h == 0 || w > PM_IMG_MAX_SIDE || h > PM_IMG_MAX_SIDE)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': %llu x %llu pixels: each side must be 1 to %u", lim->what, name,
                            (unsigned long long)w, (unsigned long long)h, PM_IMG_MAX_SIDE);
    uint64_t bytes = w * h * (is_float ? 4u * (uint64_t)lim->fchannels : 4u);
    if (bytes > lim->max_bytes)
        return pm_error_set(PM_ERR_INPUT,
                            "%s '%s': %llu x %llu pixels would take %.1f MiB decoded, above its budget (%s)", lim->what,
                            name, (unsigned long long)w, (unsigned long long)h, bytes / MIB,
                            lim->budget ? lim->budget : "image_budgets");
    return PM_OK;
}

static pm_result_t alloc_u8(const char *name, const pm_img_limits_t *lim, pm_img_t *im)
{
    im->u8 = malloc((size_t)im->w * im->h * 4);
    return im->u8 ? PM_OK
                  : pm_error_set(PM_ERR_NOMEM, "out of memory for %s '%s' (%u x %u)", lim->what, name, im->w, im->h);
}

/* ---- PNG: libpng's simplified reader; a warning fails the image (extra or damaged image data,
 * a chunk it cannot use), unless it is about an ancillary chunk whose loss leaves the pixels as
 * they are: by the PNG naming rule, a chunk whose name starts in lower case ("iCCP: known
 * incorrect sRGB profile", common in real assets, or a text chunk's CRC), other than gAMA and
 * sRGB, which the reader's conversion to sRGB uses. */
static int png_warning_fatal(const char *msg)
{
    if (!(msg[0] >= 'a' && msg[0] <= 'z') || strlen(msg) < 6 || msg[4] != ':')
        return 1;
    for (int i = 1; i < 4; i++)
        if (!((msg[i] >= 'a' && msg[i] <= 'z') || (msg[i] >= 'A' && msg[i] <= 'Z')))
            return 1;
    return strncmp(msg, "gAMA", 4) == 0 || strncmp(msg, "sRGB", 4) == 0;
}

static pm_result_t decode_png(const char *name, const uint8_t *data, size_t size, const pm_img_limits_t *lim,
                              pm_img_t *im)
{
    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&pi, data, size))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': libpng: %s", lim->what, name, pi.message);
    pm_result_t r = check_size(name, lim, pi.width, pi.height, 0);
    if (r == PM_OK && (pi.warning_or_error & PNG_IMAGE_WARNING) && png_warning_fatal(pi.message))
        r = pm_error_set(PM_ERR_INPUT, "%s '%s': libpng: %s", lim->what, name, pi.message);
    if (r != PM_OK) {
        png_image_free(&pi);
        return r;
    }
    im->has_alpha = (pi.format & PNG_FORMAT_FLAG_ALPHA) != 0;
    im->grey = (pi.format & PNG_FORMAT_FLAG_COLOR) == 0;
    im->w = pi.width, im->h = pi.height;
    pi.format = PNG_FORMAT_RGBA; /* 8-bit sRGB colour, linear alpha */
    if ((r = alloc_u8(name, lim, im)) != PM_OK) {
        png_image_free(&pi);
        return r;
    }
    if (!png_image_finish_read(&pi, NULL, im->u8, 0, NULL))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': libpng: %s", lim->what, name, pi.message);
    if ((pi.warning_or_error & PNG_IMAGE_WARNING) && png_warning_fatal(pi.message))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': libpng: %s", lim->what, name, pi.message);
    return PM_OK;
}

/* ---- JPEG: libjpeg(-turbo) from memory; its warnings (premature end of data, corrupt data)
 * jump out as errors, and its working memory is capped at twice the budget. */

typedef struct {
    struct jpeg_error_mgr pub;
    jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
} jpeg_fail_t;

static void jpeg_on_error(j_common_ptr cinfo)
{
    jpeg_fail_t *f = (jpeg_fail_t *)cinfo->err;
    f->pub.format_message(cinfo, f->message);
    longjmp(f->jump, 1);
}

static void jpeg_on_message(j_common_ptr cinfo, int level)
{
    if (level < 0) /* a warning: the data is corrupt or cut short, and the decoder would guess */
        jpeg_on_error(cinfo);
}

static pm_result_t decode_jpeg(const char *name, const uint8_t *data, size_t size, const pm_img_limits_t *lim,
                               pm_img_t *im)
{
    struct jpeg_decompress_struct cinfo;
    jpeg_fail_t err;
    memset(&err, 0, sizeof err);
    memset(&cinfo, 0, sizeof cinfo);
    cinfo.err = jpeg_std_error(&err.pub);
    err.pub.error_exit = jpeg_on_error;
    err.pub.emit_message = jpeg_on_message;
    uint8_t *volatile row = NULL;
    pm_result_t r = PM_OK;
    if (setjmp(err.jump)) {
        jpeg_destroy_decompress(&cinfo);
        free(row);
        return pm_error_set(PM_ERR_INPUT, "%s '%s': libjpeg: %s", lim->what, name, err.message);
    }
    jpeg_create_decompress(&cinfo);
    cinfo.mem->max_memory_to_use =
        (long)(lim->max_bytes < ((uint64_t)1 << 40) ? 2 * lim->max_bytes + (1 << 24) : (uint64_t)1 << 41);
    jpeg_mem_src(&cinfo, data, (unsigned long)size);
    jpeg_read_header(&cinfo, TRUE);
    if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK)
        r = pm_error_set(PM_ERR_INPUT, "%s '%s': a CMYK JPEG: only grey and RGB JPEGs are read", lim->what, name);
    if (r == PM_OK)
        r = check_size(name, lim, cinfo.image_width, cinfo.image_height, 0);
    if (r != PM_OK) {
        jpeg_destroy_decompress(&cinfo);
        return r;
    }
    im->grey = cinfo.num_components == 1;
    cinfo.out_color_space = JCS_RGB;
    jpeg_start_decompress(&cinfo);
    im->w = cinfo.output_width, im->h = cinfo.output_height;
    if (im->w != cinfo.image_width || im->h != cinfo.image_height || cinfo.output_components != 3) {
        jpeg_destroy_decompress(&cinfo);
        return pm_error_set(PM_ERR_INTERNAL, "%s '%s': libjpeg output of %u x %u x %d", lim->what, name, im->w, im->h,
                            cinfo.output_components);
    }
    row = malloc((size_t)im->w * 3);
    if (!row || (r = alloc_u8(name, lim, im)) != PM_OK) {
        jpeg_destroy_decompress(&cinfo);
        free(row);
        return r != PM_OK ? r : pm_error_set(PM_ERR_NOMEM, "out of memory for %s '%s'", lim->what, name);
    }
    while (cinfo.output_scanline < cinfo.output_height) {
        uint32_t y = cinfo.output_scanline;
        JSAMPROW rp = row;
        if (jpeg_read_scanlines(&cinfo, &rp, 1) != 1) { /* cannot happen from memory: never loop */
            jpeg_destroy_decompress(&cinfo);
            free(row);
            return pm_error_set(PM_ERR_INPUT, "%s '%s': libjpeg stopped at row %u of %u", lim->what, name, y, im->h);
        }
        uint8_t *o = im->u8 + (size_t)4 * im->w * y;
        for (uint32_t x = 0; x < im->w; x++)
            o[4 * x] = row[3 * x], o[4 * x + 1] = row[3 * x + 1], o[4 * x + 2] = row[3 * x + 2], o[4 * x + 3] = 255;
    }
    jpeg_finish_decompress(&cinfo);
    jpeg_destroy_decompress(&cinfo);
    free(row);
    return PM_OK;
}

/* ---- OpenEXR through base/exr.h, the data window checked against the budget first. */

static pm_result_t decode_exr(const char *name, const uint8_t *data, size_t size, const pm_img_limits_t *lim,
                              pm_img_t *im)
{
    uint64_t max_px = lim->max_bytes / (4u * (uint64_t)lim->fchannels);
    uint32_t w = 0, h = 0;
    float *rgb = NULL;
    pm_result_t r = pm_exr_read_rgb_mem(name, data, size, max_px, &w, &h, &rgb);
    if (r != PM_OK) {
        pm_error_prefix("%s", lim->what);
        return r;
    }
    if ((r = check_size(name, lim, w, h, 1)) != PM_OK) {
        free(rgb);
        return r;
    }
    im->w = w, im->h = h;
    if (lim->fchannels == 3) {
        im->f32 = rgb;
        return PM_OK;
    }
    im->f32 = malloc((size_t)w * h * 4 * sizeof(float));
    if (!im->f32) {
        free(rgb);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %s '%s' (%u x %u)", lim->what, name, w, h);
    }
    for (size_t i = 0; i < (size_t)w * h; i++) {
        memcpy(im->f32 + 4 * i, rgb + 3 * i, 3 * sizeof(float));
        im->f32[4 * i + 3] = 1.0f;
    }
    free(rgb);
    return PM_OK;
}

/* ---- Truevision TGA (version 1 and 2): colour-mapped (8-bit indices), true-colour (15, 16,
 * 24, 32 bits) and grey (8 bits), raw or run-length encoded, either origin. */

static uint8_t scale5(unsigned v) { return (uint8_t)((v * 255u + 15u) / 31u); }

/* The bpp-bit little-endian pixel at p as R G B A. */
static void tga_pixel(const uint8_t *p, int bpp, uint8_t o[4])
{
    if (bpp == 8) {
        o[0] = o[1] = o[2] = p[0], o[3] = 255;
    } else if (bpp == 15 || bpp == 16) {
        unsigned v = p[0] | (unsigned)p[1] << 8; /* A RRRRR GGGGG BBBBB; the A bit is not alpha in practice */
        o[0] = scale5((v >> 10) & 31), o[1] = scale5((v >> 5) & 31), o[2] = scale5(v & 31), o[3] = 255;
    } else {
        o[0] = p[2], o[1] = p[1], o[2] = p[0], o[3] = bpp == 32 ? p[3] : 255;
    }
}

static pm_result_t tga_bad(const char *name, const pm_img_limits_t *lim, const char *what)
{
    return pm_error_set(PM_ERR_INPUT, "%s '%s': not a TGA image pmtk reads: %s", lim->what, name, what);
}

static pm_result_t decode_tga(const char *name, const uint8_t *d, size_t size, const pm_img_limits_t *lim, pm_img_t *im)
{
    if (size < 18)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': truncated TGA: %zu bytes, the header alone is 18", lim->what, name,
                            size);
    unsigned idlen = d[0], cmtype = d[1], type = d[2];
    unsigned cmfirst = d[3] | (unsigned)d[4] << 8, cmlen = d[5] | (unsigned)d[6] << 8, cmbits = d[7];
    unsigned w = d[12] | (unsigned)d[13] << 8, h = d[14] | (unsigned)d[15] << 8, bpp = d[16], desc = d[17];
    char why[96];
    int mapped = type == 1 || type == 9, grey = type == 3 || type == 11, rle = type >= 9;
    if (!(type == 1 || type == 2 || type == 3 || type == 9 || type == 10 || type == 11)) {
        snprintf(why, sizeof why, "image type %u (1, 2, 3, 9, 10 or 11 are read)", type);
        return tga_bad(name, lim, why);
    }
    if (cmtype > 1 || (mapped && cmtype != 1)) {
        snprintf(why, sizeof why, "colour map type %u with image type %u", cmtype, type);
        return tga_bad(name, lim, why);
    }
    if (cmtype == 1 && !(cmbits == 15 || cmbits == 16 || cmbits == 24 || cmbits == 32)) {
        snprintf(why, sizeof why, "colour map entries of %u bits", cmbits);
        return tga_bad(name, lim, why);
    }
    if (mapped ? (bpp != 8 || cmlen == 0) : grey ? bpp != 8 : !(bpp == 15 || bpp == 16 || bpp == 24 || bpp == 32)) {
        snprintf(why, sizeof why, "%u bits per pixel for image type %u", bpp, type);
        return tga_bad(name, lim, why);
    }
    pm_result_t r = check_size(name, lim, w, h, 0);
    if (r != PM_OK)
        return r;
    size_t cmbytes = (size_t)cmlen * ((cmbits + 7) / 8), pos = 18 + idlen + (cmtype ? cmbytes : 0);
    const uint8_t *cmap = d + 18 + idlen;
    if (pos > size)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': truncated TGA: %zu bytes, its header and colour map take %zu",
                            lim->what, name, size, pos);
    size_t ps = (bpp + 7) / 8, n = (size_t)w * h;
    if (!rle && size - pos < n * ps)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': truncated TGA: %zu bytes of pixels for %u x %u at %u bits (%zu)",
                            lim->what, name, size - pos, w, h, bpp, n * ps);
    im->w = w, im->h = h, im->grey = grey, im->has_alpha = mapped ? cmbits == 32 : bpp == 32;
    if ((r = alloc_u8(name, lim, im)) != PM_OK)
        return r;
    /* Pixels in file order into i = 0 .. n - 1, then placed by the origin bits. */
    int top = (desc >> 5) & 1, right = (desc >> 4) & 1;
    size_t i = 0;
    const uint8_t *last = NULL;
    while (i < n) {
        size_t count = 1;
        int run = 0;
        if (rle) {
            if (pos >= size)
                goto truncated;
            count = (d[pos] & 127u) + 1, run = d[pos] >> 7;
            pos++;
            if (count > n - i)
                return pm_error_set(PM_ERR_INPUT, "%s '%s': corrupt TGA: a run of %zu pixels at pixel %zu of %zu",
                                    lim->what, name, count, i, n);
        }
        for (size_t k = 0; k < count; k++, i++) {
            if (!run || k == 0) {
                if (size - pos < ps)
                    goto truncated;
                last = d + pos;
                pos += ps;
            }
            size_t x = i % w, y = i / w;
            x = right ? w - 1 - x : x;
            y = top ? y : h - 1 - y;
            uint8_t *o = im->u8 + 4 * (y * w + x);
            if (mapped) {
                if (last[0] < cmfirst || last[0] - cmfirst >= cmlen)
                    return pm_error_set(PM_ERR_INPUT,
                                        "%s '%s': corrupt TGA: colour index %u outside the map (%u to %u)", lim->what,
                                        name, last[0], cmfirst, cmfirst + cmlen - 1);
                tga_pixel(cmap + (size_t)(last[0] - cmfirst) * ((cmbits + 7) / 8), (int)cmbits, o);
            } else {
                tga_pixel(last, (int)bpp, o);
            }
        }
    }
    return PM_OK;
truncated:
    return pm_error_set(PM_ERR_INPUT, "%s '%s': truncated TGA: pixel data ends at pixel %zu of %zu", lim->what, name, i,
                        n);
}

/* ---- Radiance RGBE (.hdr): the header (FORMAT, EXPOSURE), the resolution line -Y H +X W (or
 * +Y), scanlines flat, old-style run-length or new-style (per-component) run-length. */

static pm_result_t hdr_bad(const char *name, const pm_img_limits_t *lim, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static pm_result_t hdr_bad(const char *name, const pm_img_limits_t *lim, const char *fmt, ...)
{
    char why[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    return pm_error_set(PM_ERR_INPUT, "%s '%s': Radiance HDR: %s", lim->what, name, why);
}

/* One scanline of w pixels as RGBE bytes into s (4 * w bytes) from d at *pos. */
static pm_result_t hdr_scanline(const char *name, const pm_img_limits_t *lim, const uint8_t *d, size_t size,
                                size_t *pos, uint32_t w, uint32_t y, uint8_t *s)
{
    size_t p = *pos;
    if (w >= 8 && w < 32768 && size - p >= 4 && d[p] == 2 && d[p + 1] == 2 && !(d[p + 2] & 0x80)) {
        if (((uint32_t)d[p + 2] << 8 | d[p + 3]) != w)
            return hdr_bad(name, lim, "scanline %u says %u pixels", y, (uint32_t)d[p + 2] << 8 | d[p + 3]);
        p += 4;
        for (int c = 0; c < 4; c++)
            for (uint32_t x = 0; x < w;) {
                if (p >= size)
                    return hdr_bad(name, lim, "truncated in scanline %u", y);
                unsigned cnt = d[p++];
                if (cnt > 128) {
                    cnt -= 128;
                    if (p >= size)
                        return hdr_bad(name, lim, "truncated in scanline %u", y);
                    if (cnt > w - x)
                        return hdr_bad(name, lim, "corrupt run in scanline %u at pixel %u", y, x);
                    for (unsigned k = 0; k < cnt; k++)
                        s[4 * (x + k) + c] = d[p];
                    p++;
                } else {
                    if (cnt == 0 || cnt > w - x || size - p < cnt)
                        return hdr_bad(name, lim, "corrupt or truncated scanline %u at pixel %u", y, x);
                    for (unsigned k = 0; k < cnt; k++)
                        s[4 * (x + k) + c] = d[p + k];
                    p += cnt;
                }
                x += cnt;
            }
        *pos = p;
        return PM_OK;
    }
    /* Flat pixels, where (1, 1, 1, n) repeats the previous pixel n times (n << 8 after another). */
    int shift = 0;
    for (uint32_t x = 0; x < w;) {
        if (size - p < 4)
            return hdr_bad(name, lim, "truncated in scanline %u at pixel %u", y, x);
        const uint8_t *q = d + p;
        p += 4;
        if (q[0] == 1 && q[1] == 1 && q[2] == 1) {
            if (x == 0 || shift > 16)
                return hdr_bad(name, lim, "corrupt run in scanline %u at pixel %u", y, x);
            uint64_t cnt = (uint64_t)q[3] << shift;
            if (cnt > w - x)
                return hdr_bad(name, lim, "corrupt run in scanline %u at pixel %u", y, x);
            for (uint64_t k = 0; k < cnt; k++, x++)
                memcpy(s + 4 * x, s + 4 * (x - 1), 4);
            shift += 8;
        } else {
            memcpy(s + 4 * x, q, 4);
            x++;
            shift = 0;
        }
    }
    *pos = p;
    return PM_OK;
}

static pm_result_t decode_hdr(const char *name, const uint8_t *d, size_t size, const pm_img_limits_t *lim, pm_img_t *im)
{
    /* The header: text lines up to a blank one, at most 64 KiB. */
    size_t pos = 0;
    double exposure = 1.0;
    int lines = 0;
    char line[256];
    for (;;) {
        size_t e = pos;
        while (e < size && d[e] != '\n' && e - pos < 65536)
            e++;
        if (e >= size || d[e] != '\n' || e >= 65536)
            return hdr_bad(name, lim, "header without an end (a blank line) in its first %u bytes", 65536u);
        size_t len = e - pos < sizeof line - 1 ? e - pos : sizeof line - 1;
        memcpy(line, d + pos, len);
        line[len] = '\0';
        pos = e + 1;
        if (lines++ == 0)
            continue; /* #?RADIANCE, #?RGBE */
        if (len == 0)
            break;
        if (strncmp(line, "FORMAT=", 7) == 0 && strcmp(line + 7, "32-bit_rle_rgbe") != 0) {
            return pm_error_set(PM_ERR_INPUT, "%s '%s': Radiance HDR of FORMAT=%s: only 32-bit_rle_rgbe is read",
                                lim->what, name, line + 7);
        } else if (strncmp(line, "EXPOSURE=", 9) == 0) {
            char *end;
            double v = strtod(line + 9, &end);
            if (!(v > 0.0 && isfinite(v)) || (*end && *end != ' ' && *end != '\t'))
                return pm_error_set(PM_ERR_INPUT, "%s '%s': Radiance HDR EXPOSURE='%s' is not a positive number",
                                    lim->what, name, line + 9);
            exposure *= v; /* the values were multiplied by it: divided back below */
        } else if (strncmp(line, "COLORCORR=", 10) == 0) {
            return pm_error_set(PM_ERR_INPUT, "%s '%s': Radiance HDR with COLORCORR is not read", lim->what, name);
        }
    }
    /* The resolution line. */
    size_t e = pos;
    while (e < size && d[e] != '\n' && e - pos < 64)
        e++;
    if (e >= size || d[e] != '\n')
        return hdr_bad(name, lim, "no resolution line after the header (%u, %u)", (unsigned)pos, (unsigned)size);
    char ys = 0, res[65];
    unsigned long h = 0, w = 0;
    memcpy(res, d + pos, e - pos);
    res[e - pos] = '\0';
    pos = e + 1;
    int used = 0;
    for (size_t k = strlen(res); k > 0 && (res[k - 1] == '\r' || res[k - 1] == ' '); k--)
        res[k - 1] = '\0';
    if (sscanf(res, "%cY %lu +X %lu%n", &ys, &h, &w, &used) != 3 || (ys != '-' && ys != '+') || res[used] != '\0') {
        return pm_error_set(PM_ERR_INPUT,
                            "%s '%s': Radiance HDR resolution '%s': only -Y H +X W and +Y H +X W are read", lim->what,
                            name, res);
    }
    pm_result_t r = check_size(name, lim, w, h, 1);
    if (r != PM_OK)
        return r;
    im->w = (uint32_t)w, im->h = (uint32_t)h, im->fchannels = lim->fchannels;
    im->f32 = malloc((size_t)w * h * (size_t)lim->fchannels * sizeof(float));
    uint8_t *s = malloc((size_t)w * 4);
    if (!im->f32 || !s) {
        free(s);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %s '%s' (%lu x %lu)", lim->what, name, w, h);
    }
    for (uint32_t y = 0; y < h && r == PM_OK; y++) {
        if ((r = hdr_scanline(name, lim, d, size, &pos, (uint32_t)w, y, s)) != PM_OK)
            break;
        uint32_t row = ys == '-' ? y : (uint32_t)h - 1 - y;
        float *o = im->f32 + (size_t)row * w * (size_t)lim->fchannels;
        for (uint32_t x = 0; x < w; x++, o += lim->fchannels) {
            const uint8_t *q = s + 4 * x;
            /* Radiance's colr_color: (mantissa + 1/2) 2^(e - 136); exponent 0 is black */
            double f = q[3] ? ldexp(1.0, (int)q[3] - 136) / exposure : 0.0;
            for (int c = 0; c < 3; c++)
                o[c] = q[3] ? (float)((q[c] + 0.5) * f) : 0.0f;
            if (lim->fchannels == 4)
                o[3] = 1.0f;
        }
    }
    free(s);
    return r;
}

/* ---- the entry points */

pm_result_t pm_img_decode(const char *name, const char *hint, const void *data, size_t size, const pm_img_limits_t *lim,
                          pm_img_t *out)
{
    memset(out, 0, sizeof *out);
    const uint8_t *d = data;
    const char *other = NULL;
    unsigned got = sniff(d, size, &other);
    const char *ext = hint && *hint ? hint : extension_of(name);
    unsigned named = by_extension(ext);
    if (!got && named == PM_IMG_TGA && !other)
        got = PM_IMG_TGA; /* TGA has no signature: a name that says so, and no other format's */
    char read_list[96] = "";
    for (unsigned f = 1; f <= PM_IMG_HDR; f <<= 1)
        if (lim->formats & f)
            snprintf(read_list + strlen(read_list), sizeof read_list - strlen(read_list), "%s%s",
                     read_list[0] ? ", " : "", pm_img_format_name(f));
    if (!got && other)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': a %s image%s%s; a %s is read from %s: convert it", lim->what, name,
                            other, named ? " named as " : "", named ? pm_img_format_name(named) : "", lim->what,
                            read_list);
    if (!got)
        return pm_error_set(
            PM_ERR_INPUT,
            "%s '%s': not a PNG, JPEG, OpenEXR or (named .tga) TGA%s image (%zu bytes; first bytes %02x "
            "%02x %02x %02x)",
            lim->what, name, (lim->formats & PM_IMG_HDR) ? " or Radiance HDR" : "", size, size > 0 ? d[0] : 0,
            size > 1 ? d[1] : 0, size > 2 ? d[2] : 0, size > 3 ? d[3] : 0);
    if (named && named != got)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': named as %s but holds a %s image", lim->what, name,
                            pm_img_format_name(named), pm_img_format_name(got));
    if (!(lim->formats & got))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': a %s image: a %s is read from %s", lim->what, name,
                            pm_img_format_name(got), lim->what, read_list);
    out->format = got;
    out->fchannels = lim->fchannels;
    pm_result_t r = got == PM_IMG_PNG    ? decode_png(name, d, size, lim, out)
                    : got == PM_IMG_JPEG ? decode_jpeg(name, d, size, lim, out)
                    : got == PM_IMG_EXR  ? decode_exr(name, d, size, lim, out)
                    : got == PM_IMG_TGA  ? decode_tga(name, d, size, lim, out)
                                         : decode_hdr(name, d, size, lim, out);
    if (r != PM_OK)
        pm_img_free(out);
    else
        out->format = got, out->fchannels = lim->fchannels;
    return r;
}

pm_result_t pm_img_read_file(const char *path, const char *what, uint64_t max_size, void **data_out, size_t *size_out)
{
    *data_out = NULL;
    *size_out = 0;
    /* O_NONBLOCK: a FIFO named as an image must not wait for a writer */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return pm_error_set(pm_result_of_errno(errno), "cannot open %s '%s': %s", what, path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return pm_error_set(pm_result_of_errno(e), "cannot read %s '%s': %s", what, path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is not a regular file (a %s)", what, path,
                            S_ISFIFO(st.st_mode)   ? "FIFO"
                            : S_ISDIR(st.st_mode)  ? "folder"
                            : S_ISSOCK(st.st_mode) ? "socket"
                                                   : "device");
    }
    if ((uint64_t)st.st_size > max_size) {
        close(fd);
        return pm_error_set(PM_ERR_INPUT, "%s '%s': %lld bytes, above the %.1f MiB its budget allows (image_budgets)",
                            what, path, (long long)st.st_size, max_size / MIB);
    }
    size_t n = (size_t)st.st_size, got = 0;
    uint8_t *buf = malloc(n ? n : 1);
    if (!buf) {
        close(fd);
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading %s '%s' (%zu bytes)", what, path, n);
    }
    while (got < n) {
        ssize_t k = read(fd, buf + got, n - got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0) {
            int e = k < 0 ? errno : 0;
            close(fd);
            free(buf);
            return k < 0 ? pm_error_set(pm_result_of_errno(e), "cannot read %s '%s': %s", what, path, strerror(e))
                         : pm_error_set(PM_ERR_IO, "%s '%s' shrank while read: %zu of %zu bytes", what, path, got, n);
        }
        got += (size_t)k;
    }
    close(fd);
    *data_out = buf;
    *size_out = n;
    return PM_OK;
}

pm_result_t pm_img_load(const char *path, const pm_img_limits_t *lim, pm_img_t *out)
{
    memset(out, 0, sizeof *out);
    void *data = NULL;
    size_t size = 0;
    uint64_t cap = lim->max_bytes < ((uint64_t)1 << 50) ? 2 * lim->max_bytes + (1u << 20) : (uint64_t)1 << 51;
    pm_result_t r = pm_img_read_file(path, lim->what, cap, &data, &size);
    if (r == PM_OK)
        r = pm_img_decode(path, NULL, data, size, lim, out);
    free(data);
    return r;
}
