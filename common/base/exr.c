/* exr.c: OpenEXR output and reading through the OpenEXR 3 C API (see exr.h).
 *
 * Writing follows the Core API's steps: start a write context on a temporary path, define
 * one scanline part (required attributes, channels, string attributes), write the header,
 * then encode chunk after chunk (16 scanlines for ZIP, 32 for PIZ, 1 uncompressed) from the
 * caller's interleaved buffer through strides, and finish. Reading walks the chunks of the
 * first part (bands of scanlines, or the tiles of level 0), decodes the chosen channels in
 * the file's own pixel type into planes and converts them to float while placing each chunk
 * at its position in the data window. OpenEXR's own messages go through
 * an error handler into a thread-local buffer, so a failure is one pmtk message naming the
 * file and OpenEXR's words. */
#include "base/exr.h"

#include <errno.h>
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/atomic.h"

/* The last message OpenEXR reported on this thread (contexts are used by one thread). */
static _Thread_local char exr_msg[512];

static void exr_error_handler(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    snprintf(exr_msg, sizeof exr_msg, "%s (%s)", msg ? msg : "", exr_get_error_code_as_string(code));
}

/* A pmtk error for OpenEXR result rv while doing what to path. */
static pm_result_t exr_fail(exr_result_t rv, const char *what, const char *path)
{
    /* A file that cannot be opened is classed by the open's errno (base/error.h): a missing
     * path is the user's input, a full disk the system's; OpenEXR leaves errno as open set it. */
    int e = errno;
    const char *detail = exr_msg[0] ? exr_msg : exr_get_default_error_message(rv);
    pm_result_t code = rv == EXR_ERR_OUT_OF_MEMORY                         ? PM_ERR_NOMEM
                       : rv == EXR_ERR_FILE_ACCESS                         ? pm_result_of_errno(e)
                       : (rv == EXR_ERR_WRITE_IO || rv == EXR_ERR_READ_IO) ? PM_ERR_IO
                                                                           : PM_ERR_INPUT;
    return pm_error_set(code, "cannot %s OpenEXR image '%s': %s", what, path, detail);
}

static exr_context_initializer_t exr_init(void)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_error_handler;
    exr_msg[0] = '\0';
    return init;
}

/* One half-precision value from a float, rounded to nearest even. gcc (and clang from 15) have
 * _Float16 on x86-64 and convert in hardware or libgcc; clang 14, which builds the fuzz targets,
 * has no _Float16 there, so it gets the same rounding written out on the bit patterns. */
#ifdef __FLT16_MAX__
typedef _Float16 exr_half_t;
static inline exr_half_t exr_half_from_float(float f) { return (_Float16)f; }
static inline float exr_half_bits_to_float(uint16_t bits)
{
    _Float16 h;
    memcpy(&h, &bits, 2);
    return (float)h;
}
#else
typedef uint16_t exr_half_t;
static exr_half_t exr_half_from_float(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u, a = x & 0x7fffffffu;
    if (a >= 0x7f800000u) /* Inf stays Inf; NaN stays a quiet NaN with its top payload bits */
        return (exr_half_t)(sign | 0x7c00u | (a > 0x7f800000u ? 0x200u | ((a >> 13) & 0x3ffu) : 0));
    if (a >= 0x477ff000u) /* 65520 and up round past the largest half, 65504 */
        return (exr_half_t)(sign | 0x7c00u);
    if (a >= 0x38800000u) { /* a normal half: rebias the exponent (127 - 15), keep 10 mantissa bits */
        uint32_t h = (a - 0x38000000u) >> 13, rest = a & 0x1fffu;
        h += rest > 0x1000u || (rest == 0x1000u && (h & 1u)); /* a carry moves to the next exponent */
        return (exr_half_t)(sign | h);
    }
    if (a <= 0x33000000u) /* 2^-25 and below round to zero (2^-25 is a tie, to the even 0) */
        return (exr_half_t)sign;
    /* A subnormal half counts units of 2^-24: the float's significand shifted by its exponent. */
    uint32_t e = a >> 23, m = (a & 0x7fffffu) | 0x800000u, shift = 126u - e;
    uint32_t h = m >> shift, rest = m & ((1u << shift) - 1u), tie = 1u << (shift - 1u);
    h += rest > tie || (rest == tie && (h & 1u));
    return (exr_half_t)(sign | h);
}
/* Every half is exactly a float: rebias a normal's exponent, normalize a subnormal. */
static float exr_half_bits_to_float(uint16_t bits)
{
    uint32_t sign = (uint32_t)(bits & 0x8000u) << 16, e = (bits >> 10) & 0x1fu, m = bits & 0x3ffu, x;
    if (e == 0x1fu) /* Inf, or NaN with its payload */
        x = sign | 0x7f800000u | (m << 13);
    else if (e) /* normal: exponent 15-biased to 127-biased */
        x = sign | ((e + 112u) << 23) | (m << 13);
    else if (!m) /* signed zero */
        x = sign;
    else { /* subnormal: m * 2^-24, shifted until its leading one is the implicit bit */
        e = 113u;
        while (!(m & 0x400u))
            m <<= 1, e--;
        x = sign | (e << 23) | ((m & 0x3ffu) << 13);
    }
    float f;
    memcpy(&f, &x, 4);
    return f;
}
#endif

/* Converts rows [y0, y0 + lines) of each channel into the file's pixel type, one plane per
 * channel (planar data needs no strides the encoder might misread). */
static void pack_rows(const pm_exr_channel_t *ch, size_t nch, uint32_t w, uint32_t y0, int32_t lines,
                      pm_exr_pixel_t type, void **planes)
{
    size_t n = (size_t)w * (size_t)lines, base = (size_t)y0 * w;
    for (size_t c = 0; c < nch; c++) {
        const float *src = ch[c].data;
        size_t st = ch[c].stride;
        if (type == PM_EXR_HALF) {
            exr_half_t *p = planes[c];
            for (size_t i = 0; i < n; i++)
                p[i] = exr_half_from_float(src[st * (base + i)]);
        } else {
            float *p = planes[c];
            for (size_t i = 0; i < n; i++)
                p[i] = src[st * (base + i)];
        }
    }
}

/* OpenEXR Core 3.1 (Debian 12's) keeps a ZIP chunk's deflated bytes when they come out exactly
 * as long as the packed pixels, and every reader takes a chunk of that size for raw pixels: it
 * reads back as noise (OpenEXR issue 2306, fixed in 3.4; seen here as rows 64-79 of a 128 x 128
 * path-traced image reading +-1e38). The format's rule is to store a chunk that does not shrink
 * raw, so such a chunk is put back raw after the library's compressor. */
typedef struct {
    exr_result_t (*compress)(exr_encode_pipeline_t *);
} zip_guard_t;

static exr_result_t compress_guarded(exr_encode_pipeline_t *e)
{
    const zip_guard_t *g = e->encoding_user_data;
    exr_result_t rv = g->compress(e);
    if (rv == EXR_ERR_SUCCESS && e->compressed_buffer && e->compressed_buffer != e->packed_buffer &&
        e->packed_bytes > 0 && e->compressed_bytes >= e->packed_bytes && e->compressed_alloc_size >= e->packed_bytes) {
        memcpy(e->compressed_buffer, e->packed_buffer, e->packed_bytes);
        e->compressed_bytes = e->packed_bytes;
    }
    return rv;
}

pm_result_t pm_exr_write_rgb(const char *path, uint32_t w, uint32_t h, const float *rgb, pm_exr_pixel_t type,
                             pm_exr_compression_t comp, const pm_exr_attr_t *attrs, size_t nattrs)
{
    const pm_exr_channel_t ch[3] = {{"R", rgb, 3, 0}, {"G", rgb + 1, 3, 0}, {"B", rgb + 2, 3, 0}};
    return pm_exr_write_channels(path, w, h, ch, 3, type, comp, attrs, nattrs);
}

pm_result_t pm_exr_write_channels(const char *path, uint32_t w, uint32_t h, const pm_exr_channel_t *ch, size_t nch,
                                  pm_exr_pixel_t type, pm_exr_compression_t comp, const pm_exr_attr_t *attrs,
                                  size_t nattrs)
{
    if (!path || !strcmp(path, "-"))
        return pm_error_set(PM_ERR_USAGE, "OpenEXR needs a seekable file, not stdout");
    if (w < 1 || h < 1 || w > INT32_MAX / 2 || h > INT32_MAX / 2)
        return pm_error_set(PM_ERR_INTERNAL, "OpenEXR image '%s': size %ux%u out of range", path, w, h);
    if (nch < 1 || nch > PM_EXR_MAX_CHANNELS)
        return pm_error_set(PM_ERR_INTERNAL, "OpenEXR image '%s': %zu channels, not 1 to %d", path, nch,
                            PM_EXR_MAX_CHANNELS);
    /* The contract: the caller has checked every value; a bad one here is a bug upstream. */
    float lim = type == PM_EXR_HALF ? PM_EXR_HALF_MAX : 3.4028235e38f;
    for (size_t c = 0; c < nch; c++) {
        for (size_t d = 0; d < c; d++)
            if (!strcmp(ch[c].name, ch[d].name))
                return pm_error_set(PM_ERR_INTERNAL, "OpenEXR image '%s': channel '%s' given twice", path, ch[c].name);
        for (size_t i = 0; i < (size_t)w * h; i++)
            if (!(fabsf(ch[c].data[ch[c].stride * i]) <= lim))
                return pm_error_set(PM_ERR_INTERNAL, "refusing to write OpenEXR image '%s': pixel %zu channel %s is %g",
                                    path, i, ch[c].name, (double)ch[c].data[ch[c].stride * i]);
    }

    pm_atomic_t tmp;
    pm_result_t r = pm_atomic_reserve(path, &tmp);
    if (r != PM_OK)
        return r;
    exr_context_initializer_t init = exr_init();
    exr_context_t ctx = NULL;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int enc_live = 0, part = 0;
    zip_guard_t guard = {NULL};
    void *planes[PM_EXR_MAX_CHANNELS] = {NULL};
    static const exr_compression_t comps[] = {EXR_COMPRESSION_ZIP, EXR_COMPRESSION_NONE, EXR_COMPRESSION_PIZ};
    exr_pixel_type_t ptype = type == PM_EXR_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    size_t esize = type == PM_EXR_HALF ? 2 : 4;

    exr_result_t rv = exr_start_write(&ctx, tmp.tmp_path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_add_part(ctx, "rgb", EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, part, (int32_t)w, (int32_t)h, comps[comp]);
    /* Colour channels are perceptually logarithmic (the hint lossy codecs read); normals,
     * depth and the like are linear data. */
    for (size_t c = 0; c < nch && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, part, ch[c].name, ptype,
                             ch[c].linear ? EXR_PERCEPTUALLY_LINEAR : EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    for (size_t i = 0; i < nattrs && rv == EXR_ERR_SUCCESS; i++)
        rv = exr_attr_set_string(ctx, part, attrs[i].name, attrs[i].value);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_write_header(ctx);
    int32_t lines = 1;
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "write", path);
        goto done;
    }
    for (size_t c = 0; c < nch; c++)
        if (!(planes[c] = malloc((size_t)w * (size_t)lines * esize))) {
            r = pm_error_set(PM_ERR_NOMEM, "out of memory writing OpenEXR image '%s'", path);
            goto done;
        }
    for (uint32_t y = 0; y < h && rv == EXR_ERR_SUCCESS; y += (uint32_t)lines) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(ctx, part, (int)y, &ci);
        if (rv != EXR_ERR_SUCCESS)
            break;
        rv = enc_live ? exr_encoding_update(ctx, part, &ci, &enc) : exr_encoding_initialize(ctx, part, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS)
            break;
        enc_live = 1;
        pack_rows(ch, nch, w, y, ci.height, type, planes);
        /* OpenEXR keeps its channels sorted by name: each finds its plane by name */
        for (int k = 0; k < enc.channel_count; k++) {
            exr_coding_channel_info_t *ec = &enc.channels[k];
            size_t c = 0;
            while (c + 1 < nch && strcmp(ec->channel_name, ch[c].name))
                c++;
            ec->user_bytes_per_element = (int16_t)esize;
            ec->user_data_type = (uint16_t)ptype;
            ec->user_pixel_stride = (int32_t)esize;
            ec->user_line_stride = (int32_t)(esize * w);
            ec->encode_from_ptr = planes[c];
        }
        if (y == 0) {
            rv = exr_encoding_choose_default_routines(ctx, part, &enc);
            if (rv == EXR_ERR_SUCCESS && enc.compress_fn) {
                guard.compress = enc.compress_fn;
                enc.encoding_user_data = &guard;
                enc.compress_fn = compress_guarded;
            }
        }
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_encoding_run(ctx, part, &enc);
    }
    if (enc_live) {
        exr_result_t rv2 = exr_encoding_destroy(ctx, &enc);
        if (rv == EXR_ERR_SUCCESS)
            rv = rv2;
        enc_live = 0;
    }
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "write", path);
        goto done;
    }
    rv = exr_finish(&ctx); /* writes the chunk offset table and closes the file */
    ctx = NULL;
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "finish", path);
        goto done;
    }
    r = pm_atomic_commit(&tmp);
done:
    if (enc_live)
        exr_encoding_destroy(ctx, &enc);
    if (ctx)
        exr_finish(&ctx);
    for (size_t c = 0; c < nch; c++)
        free(planes[c]);
    if (r != PM_OK)
        pm_atomic_abort(&tmp);
    return r;
}

pm_result_t pm_exr_aov_parse(const char *option, const char *list, unsigned *mask_out)
{
    static const char *const names[] = {"albedo", "normal", "depth", "variance"};
    unsigned mask = 0;
    const char *p = list;
    for (;;) {
        size_t len = strcspn(p, ",");
        unsigned bit = 0;
        for (unsigned k = 0; k < 4; k++)
            if (len == strlen(names[k]) && !strncmp(p, names[k], len))
                bit = 1u << k;
        if (!bit || (mask & bit))
            return pm_error_set(PM_ERR_USAGE, "%s: %s layer '%.*s' in '%s' (each of %s at most once)", option,
                                bit ? "repeated" : "unknown", (int)len, p, list, PM_EXR_AOV_NAMES);
        mask |= bit;
        if (!p[len])
            break;
        p += len + 1;
    }
    *mask_out = mask;
    return PM_OK;
}

size_t pm_exr_aov_channels(unsigned mask, const float *surf, const float *var, pm_exr_channel_t *ch)
{
    static const char *const names[] = {"albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "Z"};
    size_t n = 0;
    for (int k = 0; k < 7; k++) {
        unsigned bit = k < 3 ? PM_EXR_AOV_ALBEDO : k < 6 ? PM_EXR_AOV_NORMAL : PM_EXR_AOV_DEPTH;
        if (mask & bit)
            ch[n++] = (pm_exr_channel_t){names[k], surf + k, 7, k >= 3};
    }
    if (mask & PM_EXR_AOV_VARIANCE)
        for (int k = 0; k < 3; k++)
            ch[n++] = (pm_exr_channel_t){(const char *[]){"variance.R", "variance.G", "variance.B"}[k], var + k, 3, 1};
    return n;
}

/* The channels an image is read from: R G B, or Y alone (grey, copied to all three). */
typedef struct {
    const char *name[3]; /* the channel feeding R, G, B (the context's strings) */
    int grey;            /* 1: all three are one Y channel */
    int32_t chunk_px;    /* pixels in the largest chunk */
} exr_layout_t;

static const char *storage_name(exr_storage_t s)
{
    return s == EXR_STORAGE_DEEP_SCANLINE ? "deep scanline" : s == EXR_STORAGE_DEEP_TILED ? "deep tiled" : "unknown";
}

/* Picks the channels to read from the first part's channel list, or names why none fit. */
static pm_result_t choose_channels(exr_const_context_t ctx, const char *path, exr_layout_t *lay)
{
    const exr_attr_chlist_t *cl = NULL;
    exr_result_t rv = exr_get_channels(ctx, 0, &cl);
    if (rv != EXR_ERR_SUCCESS)
        return exr_fail(rv, "read", path);
    int at[6] = {-1, -1, -1, -1, -1, -1}; /* R G B Y RY BY */
    static const char *const wanted[6] = {"R", "G", "B", "Y", "RY", "BY"};
    char found[256] = "";
    size_t fl = 0;
    for (int i = 0; i < cl->num_channels; i++) {
        const char *n = cl->entries[i].name.str;
        for (int k = 0; k < 6; k++)
            if (!strcmp(n, wanted[k]))
                at[k] = i;
        if (fl < sizeof found - 1)
            fl += (size_t)snprintf(found + fl, sizeof found - fl, "%s%s", fl ? " " : "", n);
    }
    if (fl >= sizeof found - 1)
        memcpy(found + sizeof found - 4, "...", 4);
    if (at[0] >= 0 && at[1] >= 0 && at[2] >= 0) {
        lay->grey = 0;
        for (int c = 0; c < 3; c++)
            lay->name[c] = cl->entries[at[c]].name.str;
    } else if (at[3] >= 0 && at[4] < 0 && at[5] < 0 && at[0] < 0 && at[1] < 0 && at[2] < 0) {
        lay->grey = 1;
        lay->name[0] = lay->name[1] = lay->name[2] = cl->entries[at[3]].name.str;
    } else if (at[4] >= 0 || at[5] >= 0) {
        return pm_error_set(PM_ERR_INPUT,
                            "OpenEXR image '%s' is luminance-chroma (channels %s); pmtk reads R G B (A ignored) or Y "
                            "alone: write the image as RGB",
                            path, found);
    } else {
        return pm_error_set(PM_ERR_INPUT,
                            "OpenEXR image '%s' has no channels R, G and B (channels %s); pmtk reads R G B (A "
                            "ignored) or Y alone",
                            path, cl->num_channels ? found : "none");
    }
    for (int c = 0; c < 3; c++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[at[lay->grey ? 3 : c]];
        if (e->x_sampling != 1 || e->y_sampling != 1)
            return pm_error_set(PM_ERR_INPUT,
                                "OpenEXR image '%s' channel %s is subsampled %dx%d; pmtk reads only channels with "
                                "a value at every pixel",
                                path, e->name.str, e->x_sampling, e->y_sampling);
    }
    return PM_OK;
}

/* One decoded value of pixel type t at p as float (uint as its nearest float). */
static float value_at(const uint8_t *p, uint16_t t)
{
    if (t == EXR_PIXEL_HALF) {
        uint16_t bits;
        memcpy(&bits, p, 2);
        return exr_half_bits_to_float(bits);
    }
    if (t == EXR_PIXEL_UINT) {
        uint32_t u;
        memcpy(&u, p, 4);
        return (float)u;
    }
    float f;
    memcpy(&f, p, 4);
    return f;
}

/* An image in memory, read through OpenEXR's custom stream (pread semantics). */
typedef struct {
    const uint8_t *data;
    size_t size;
} exr_mem_t;

static int64_t exr_mem_read(exr_const_context_t ctxt, void *user, void *buffer, uint64_t sz, uint64_t offset,
                            exr_stream_error_func_ptr_t error_cb)
{
    (void)ctxt, (void)error_cb;
    const exr_mem_t *m = user;
    if (offset >= m->size)
        return 0;
    uint64_t n = m->size - offset < sz ? m->size - offset : sz;
    memcpy(buffer, m->data + offset, (size_t)n);
    return (int64_t)n;
}

static int64_t exr_mem_size(exr_const_context_t ctxt, void *user)
{
    (void)ctxt;
    return (int64_t)((const exr_mem_t *)user)->size;
}

static pm_result_t read_rgb(const char *path, exr_context_initializer_t init, uint64_t max_pixels, uint32_t *w_out,
                            uint32_t *h_out, float **rgb_out);

pm_result_t pm_exr_read_rgb(const char *path, uint32_t *w_out, uint32_t *h_out, float **rgb_out)
{
    return read_rgb(path, exr_init(), (uint64_t)1 << 31, w_out, h_out, rgb_out);
}

pm_result_t pm_exr_read_rgb_mem(const char *name, const void *data, size_t size, uint64_t max_pixels, uint32_t *w_out,
                                uint32_t *h_out, float **rgb_out)
{
    exr_mem_t m = {data, size};
    exr_context_initializer_t init = exr_init();
    init.user_data = &m;
    init.read_fn = exr_mem_read;
    init.size_fn = exr_mem_size;
    return read_rgb(name, init, max_pixels, w_out, h_out, rgb_out);
}

static pm_result_t read_rgb(const char *path, exr_context_initializer_t init, uint64_t max_pixels, uint32_t *w_out,
                            uint32_t *h_out, float **rgb_out)
{
    *rgb_out = NULL;
    *w_out = *h_out = 0;
    exr_context_t ctx = NULL;
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int dec_live = 0;
    float *rgb = NULL;
    uint8_t *planes[3] = {NULL, NULL, NULL};
    pm_result_t r = PM_OK;
    exr_attr_box2i_t dw;
    exr_storage_t storage;
    exr_layout_t lay = {{NULL, NULL, NULL}, 0, 0};
    int32_t lines = 1, tw = 0, th = 0, nx = 1, ny = 0;
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_storage(ctx, 0, &storage);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_data_window(ctx, 0, &dw);
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "read", path);
        goto done;
    }
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
        r = pm_error_set(PM_ERR_INPUT, "OpenEXR image '%s' is a %s image; pmtk reads flat scanline or tiled images",
                         path, storage_name(storage));
        goto done;
    }
    int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
    if (w < 1 || h < 1 || w * h > (int64_t)1 << 31) {
        r = pm_error_set(PM_ERR_INPUT, "OpenEXR image '%s': data window of %lldx%lld pixels", path, (long long)w,
                         (long long)h);
        goto done;
    }
    if ((uint64_t)(w * h) > max_pixels) { /* before any allocation the size asks for */
        r = pm_error_set(PM_ERR_INPUT,
                         "OpenEXR image '%s': data window of %lldx%lld pixels is above the budget of %llu pixels", path,
                         (long long)w, (long long)h, (unsigned long long)max_pixels);
        goto done;
    }
    if ((r = choose_channels(ctx, path, &lay)) != PM_OK)
        goto done;
    /* Chunks: bands of `lines` scanlines, or the tiles of level (0, 0), the full-resolution
     * level of a mipmapped or ripmapped file. */
    if (storage == EXR_STORAGE_SCANLINE) {
        rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
        ny = (int32_t)((h + lines - 1) / lines);
        lay.chunk_px = (int32_t)w * (lines < h ? lines : (int32_t)h); /* a band never exceeds the image */
    } else {
        int32_t lw = 0, lh = 0;
        rv = exr_get_tile_sizes(ctx, 0, 0, 0, &tw, &th);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_get_level_sizes(ctx, 0, 0, 0, &lw, &lh);
        if (rv == EXR_ERR_SUCCESS && (tw < 1 || th < 1 || lw != w || lh != h || (int64_t)tw * th > (int64_t)1 << 28)) {
            r = pm_error_set(PM_ERR_INPUT, "OpenEXR image '%s': tiles of %dx%d over a level of %dx%d pixels", path, tw,
                             th, lw, lh);
            goto done;
        }
        nx = (lw + tw - 1) / tw, ny = (lh + th - 1) / th;
        /* A tile larger than the level holds the level: the planes need no more (a corrupt
         * header may declare tiles of 2^28 pixels over a tiny image). */
        lay.chunk_px = (tw < lw ? tw : lw) * (th < lh ? th : lh);
    }
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "read", path);
        goto done;
    }
    rgb = malloc((size_t)(3 * w * h) * sizeof *rgb);
    for (int c = 0; c < 3; c++)
        planes[c] = malloc((size_t)lay.chunk_px * 4);
    if (!rgb || !planes[0] || !planes[1] || !planes[2]) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory reading OpenEXR image '%s'", path);
        goto done;
    }
    for (int32_t cy = 0; cy < ny && rv == EXR_ERR_SUCCESS; cy++)
        for (int32_t cx = 0; cx < nx && rv == EXR_ERR_SUCCESS; cx++) {
            exr_chunk_info_t ci;
            rv = storage == EXR_STORAGE_SCANLINE ? exr_read_scanline_chunk_info(ctx, 0, dw.min.y + cy * lines, &ci)
                                                 : exr_read_tile_chunk_info(ctx, 0, cx, cy, 0, 0, &ci);
            if (rv != EXR_ERR_SUCCESS)
                break;
            /* The chunk's place in the data window: a band's first scanline is its start_y;
             * a tile's chunk info holds its tile indices, so its pixels start at index times
             * tile size. It must fit the window and the planes (a corrupt file may say
             * otherwise). */
            int64_t x0 = storage == EXR_STORAGE_SCANLINE ? 0 : (int64_t)cx * tw;
            int64_t y0 = storage == EXR_STORAGE_SCANLINE ? (int64_t)ci.start_y - dw.min.y : (int64_t)cy * th;
            if (x0 < 0 || y0 < 0 || ci.width < 1 || ci.height < 1 || x0 + ci.width > w || y0 + ci.height > h ||
                (int64_t)ci.width * ci.height > lay.chunk_px) {
                r = pm_error_set(PM_ERR_INPUT,
                                 "OpenEXR image '%s': chunk of %dx%d pixels at (%d, %d) outside the data window", path,
                                 ci.width, ci.height, ci.start_x, ci.start_y);
                goto done;
            }
            rv = dec_live ? exr_decoding_update(ctx, 0, &ci, &dec) : exr_decoding_initialize(ctx, 0, &ci, &dec);
            if (rv != EXR_ERR_SUCCESS)
                break;
            dec_live = 1;
            uint16_t type[3] = {0, 0, 0};
            int8_t size[3] = {4, 4, 4};
            for (int k = 0; k < dec.channel_count; k++) {
                exr_coding_channel_info_t *ch = &dec.channels[k];
                ch->decode_to_ptr = NULL; /* channels not read are skipped */
                for (int c = 0; c < (lay.grey ? 1 : 3); c++)
                    if (!strcmp(ch->channel_name, lay.name[c])) {
                        /* Decoded in the file's own type; converted below. */
                        type[c] = ch->data_type;
                        size[c] = ch->bytes_per_element;
                        ch->user_bytes_per_element = ch->bytes_per_element;
                        ch->user_data_type = ch->data_type;
                        ch->user_pixel_stride = ch->bytes_per_element;
                        ch->user_line_stride = ch->bytes_per_element * ci.width;
                        ch->decode_to_ptr = planes[c];
                    }
            }
            rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
            if (rv == EXR_ERR_SUCCESS)
                rv = exr_decoding_run(ctx, 0, &dec);
            for (int32_t y = 0; rv == EXR_ERR_SUCCESS && y < ci.height; y++)
                for (int32_t x = 0; x < ci.width; x++) {
                    size_t i = (size_t)y * (size_t)ci.width + (size_t)x;
                    float *px = rgb + 3 * ((size_t)(y0 + y) * (size_t)w + (size_t)(x0 + x));
                    for (int c = 0; c < 3; c++) {
                        int s = lay.grey ? 0 : c;
                        px[c] = value_at(planes[s] + i * (size_t)size[s], type[s]);
                    }
                }
        }
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "read", path);
        goto done;
    }
    *w_out = (uint32_t)w, *h_out = (uint32_t)h;
    *rgb_out = rgb;
    rgb = NULL;
done:
    if (dec_live)
        exr_decoding_destroy(ctx, &dec);
    if (ctx)
        exr_finish(&ctx);
    for (int c = 0; c < 3; c++)
        free(planes[c]);
    free(rgb);
    return r;
}

pm_result_t pm_exr_read_string_attr(const char *path, const char *name, char **value_out)
{
    *value_out = NULL;
    exr_context_initializer_t init = exr_init();
    exr_context_t ctx = NULL;
    pm_result_t r = PM_OK;
    const char *s = NULL;
    int32_t len = 0;
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    if (rv != EXR_ERR_SUCCESS) {
        r = exr_fail(rv, "read", path);
    } else if (exr_attr_get_string(ctx, 0, name, &len, &s) != EXR_ERR_SUCCESS || !s) {
        r = pm_error_set(PM_ERR_INPUT, "OpenEXR image '%s' has no string attribute '%s'", path, name);
    } else if (!(*value_out = malloc((size_t)len + 1))) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory reading OpenEXR image '%s'", path);
    } else {
        memcpy(*value_out, s, (size_t)len);
        (*value_out)[len] = '\0';
    }
    if (ctx)
        exr_finish(&ctx);
    return r;
}
