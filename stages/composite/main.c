/* composite: the last stage. Adds radiance buffers (the direct light of trace-gather-points,
 * the indirect light of simd-gather, or the shards of a gather split with --range) into one
 * image, and writes it as OpenEXR (float or half, channels R G B, the provenance of every
 * input as string attributes) and, for people who just want to look, as a PNG preview.
 *
 *   trace-gather-points --direct ──┐
 *   simd-gather (one or N shards) ─┴─> composite -> image.exr, image.png
 *
 * Buffers are read one after the other in chunks and added in f64 in the order given, so
 * memory is one f64 RGB accumulator per pixel and the sum does not depend on anything but
 * the arguments. Every buffer must have the resolution and the SCENE of the first. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr.h"
#include "base/image.h"
#include "base/memory.h"
#include "base/stage.h"
#include "base/version.h"
#include "formats/formats.h"

#define CHUNK_PIXELS 65536 /* records read at a time: 1.5 MB of f64 RGB */

enum { ONLY_ALL = 0, ONLY_DIRECT = 1, ONLY_INDIRECT = 2 };
static const char *const only_names[] = {"all", "direct", "indirect", NULL};
enum { TONE_SRGB = 0, TONE_FILMIC = 1 };
static const char *const tone_names[] = {"srgb", "filmic", NULL};
static const char *const compression_names[] = {"zip", "none", "piz", NULL}; /* pm_exr_compression_t order */

typedef struct {
    int only, tone, half, compression;
    const char *png;      /* --png FILE, NULL for none */
    const char *radiance; /* --radiance FILE: the sum as a pmtk radiance buffer */
    double exposure;      /* EV: the PNG shows radiance x 2^EV */
} composite_options_t;

/* One input: a path with an optional ":SCALE" suffix. */
typedef struct {
    char *path;
    double scale;
    pm_reader_t *rd;
    const char *component;
    int used;             /* not filtered out by --only */
    uint64_t hash;        /* content hash, once read */
} input_t;

/* Splits "FILE:SCALE" when what follows the last ':' is a whole finite number; otherwise the
 * whole word is the path (so "a:b.pm" is a path, and a file named "x:2" is given as "x:2:1"). */
static pm_result_t parse_input(const char *arg, input_t *in)
{
    const char *colon = strrchr(arg, ':');
    double s;
    in->scale = 1.0;
    if (colon && colon != arg && pm_parse_double(colon + 1, &s) == PM_OK) {
        if (!isfinite(s))
            return pm_error_set(PM_ERR_USAGE, "bad scale in '%s': %g is not finite", arg, s);
        in->scale = s;
        in->path = strndup(arg, (size_t)(colon - arg));
    } else {
        in->path = strdup(arg);
    }
    return in->path ? PM_OK : pm_error_set(PM_ERR_NOMEM, "out of memory");
}

/* Rec. 709 / sRGB primaries: relative luminance of linear RGB. */
static double luminance(const double *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

/* Narkowicz's fit of the ACES filmic curve (2015): a shoulder that rolls highlights off
 * instead of clipping them; maps [0, inf) to [0, 1), about 0.8 at x = 1. */
static float filmic(float x)
{
    if (!(x > 0.0f))
        return 0.0f;
    float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    return y < 1.0f ? y : 1.0f;
}

/* The checks across buffers: the first buffer sets the resolution and the scene. */
static pm_result_t check_same(const char *first, const pm_header_t *h0, const char *path, const pm_header_t *h)
{
    uint32_t w0, ht0, w, ht;
    pm_result_t r = pm_header_get_image_size(h0, first, &w0, &ht0);
    if (r == PM_OK)
        r = pm_header_get_image_size(h, path, &w, &ht);
    if (r != PM_OK)
        return r;
    if (w != w0 || ht != ht0)
        return pm_error_set(PM_ERR_INPUT, "resolution mismatch: '%s' is %" PRIu32 "x%" PRIu32 ", '%s' is %" PRIu32
                            "x%" PRIu32, path, w, ht, first, w0, ht0);
    const char *s0 = pm_header_get(h0, "SCENE"), *s = pm_header_get(h, "SCENE");
    if ((s0 || s) && (!s0 || !s || strcmp(s0, s)))
        return pm_error_set(PM_ERR_INPUT, "scene mismatch: '%s' is of scene '%s', '%s' of scene '%s'", path,
                            s ? s : "(none)", first, s0 ? s0 : "(none)");
    return PM_OK;
}

/* Adds one buffer, scaled, into acc (3 doubles per pixel), reading it in chunks. */
static pm_result_t accumulate(input_t *in, double *acc, double *chunk, uint64_t n, uint64_t *hash_out)
{
    uint64_t done = 0, got;
    pm_result_t r;
    /* rgb is each record's first channel; a record may carry more (trace-reference's variance). */
    uint32_t stride = pm_reader_header(in->rd)->record_size / (uint32_t)sizeof(double);
    while (done < n) {
        uint64_t want = n - done < CHUNK_PIXELS ? n - done : CHUNK_PIXELS;
        if ((r = pm_reader_read(in->rd, chunk, want, &got)) != PM_OK)
            return r;
        if (got != want) /* the reader reports truncation itself; this is a guard */
            return pm_error_set(PM_ERR_INPUT, "truncated radiance buffer '%s': %" PRIu64 " of %" PRIu64 " pixels",
                                in->path, done + got, n);
        double *a = acc + 3 * done, s = in->scale;
        for (uint64_t i = 0; i < got; i++)
            for (int c = 0; c < 3; c++)
                a[3 * i + (uint64_t)c] += s * chunk[stride * i + (uint64_t)c];
        done += got;
    }
    return pm_reader_finish(in->rd, hash_out);
}

/* The EXR's string attributes: this stage's provenance in the pmtk header's words. */
static pm_result_t exr_attrs(const pm_header_t *h, const char *components, pm_exr_attr_t **attrs_out, size_t *n_out,
                             char ***names_out)
{
    size_t ninput = 0;
    for (size_t i = 0; i < h->nkeys; i++)
        ninput += !strcmp(h->keys[i].key, "INPUT");
    size_t cap = 4 + h->ncommands + ninput, n = 0;
    pm_exr_attr_t *a = calloc(cap, sizeof *a);
    char **names = calloc(cap + 1, sizeof *names); /* owned names, NULL-terminated */
    if (!a || !names) {
        free(a);
        free(names);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for OpenEXR attributes");
    }
    a[n++] = (pm_exr_attr_t){"SOFTWARE", "pmtk " PM_VERSION_STRING};
    const char *scene = pm_header_get(h, "SCENE");
    if (scene)
        a[n++] = (pm_exr_attr_t){"SCENE", scene};
    a[n++] = (pm_exr_attr_t){"components", components};
    size_t nn = 0, ki = 0;
    for (size_t i = 0; i < h->ncommands; i++) {
        char buf[32];
        snprintf(buf, sizeof buf, "COMMAND.%zu", i);
        names[nn] = strdup(buf);
        a[n++] = (pm_exr_attr_t){names[nn++], h->commands[i]};
    }
    for (size_t i = 0; i < h->nkeys; i++) {
        if (strcmp(h->keys[i].key, "INPUT"))
            continue;
        char buf[32];
        snprintf(buf, sizeof buf, "INPUT.%zu", ki++);
        names[nn] = strdup(buf);
        a[n++] = (pm_exr_attr_t){names[nn++], h->keys[i].value};
    }
    for (size_t i = 0; i < nn; i++)
        if (!names[i]) {
            for (size_t j = 0; j < nn; j++)
                free(names[j]);
            free(names);
            free(a);
            return pm_error_set(PM_ERR_NOMEM, "out of memory for OpenEXR attributes");
        }
    *attrs_out = a, *n_out = n, *names_out = names;
    return PM_OK;
}

/* The 8-bit preview: radiance x 2^EV, then the tone curve, then the sRGB transfer.
 * Returns the fraction of channel values that clipped at white. */
static pm_result_t write_png(const char *path, const double *acc, uint32_t w, uint32_t h, double exposure, int tone,
                             double *clipped_out)
{
    size_t n = (size_t)w * h;
    uint8_t *img = malloc(3 * n);
    if (!img)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the %ux%u preview '%s'", w, h, path);
    double gain = exp2(exposure);
    size_t clipped = 0;
    for (size_t i = 0; i < 3 * n; i++) {
        float v = (float)(acc[i] * gain);
        if (tone == TONE_FILMIC)
            v = filmic(v);
        clipped += v >= 1.0f;
        img[i] = pm_srgb8(v);
    }
    pm_result_t r = pm_png_write_rgb8(path, w, h, img);
    free(img);
    *clipped_out = n ? (double)clipped / (3.0 * (double)n) : 0.0;
    return r;
}

static pm_result_t run(pm_stage_t *st, const composite_options_t *o)
{
    int nin = st->args.nargs, nstdin = 0;
    int to_exr = strcmp(st->output, "-") != 0;
    if (!to_exr && !o->png && !o->radiance)
        return pm_error_set(PM_ERR_USAGE, "no output: give -o IMAGE.exr (OpenEXR cannot write to a pipe), --png or "
                            "--radiance");
    input_t *in = calloc((size_t)nin, sizeof *in);
    if (!in)
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    pm_result_t r = PM_OK;
    double *acc = NULL, *chunk = NULL;
    float *pix = NULL;
    pm_header_t h = {0};
    pm_exr_attr_t *attrs = NULL;
    char **names = NULL;
    size_t nattrs = 0;
    pm_header_init(&h, &pm_radiance_schema);

    /* Every header first, so that a mismatch is reported before any pixel is read. */
    int first = -1, ndirect = 0, nindirect = 0, ntotal = 0;
    for (int i = 0; i < nin && r == PM_OK; i++)
        if ((r = parse_input(st->args.args[i], &in[i])) == PM_OK && !strcmp(in[i].path, "-") && ++nstdin > 1)
            r = pm_error_set(PM_ERR_USAGE, "stdin ('-') given twice");
    for (int i = 0; i < nin && r == PM_OK; i++) {
        if ((r = pm_reader_open(in[i].path, &pm_radiance_schema, 0, &in[i].rd)) != PM_OK)
            break;
        const pm_header_t *hi = pm_reader_header(in[i].rd);
        in[i].component = pm_header_get(hi, "component");
        int is_direct = !strcmp(in[i].component, "direct"), is_indirect = !strcmp(in[i].component, "indirect");
        if (o->only != ONLY_ALL && !is_direct && !is_indirect) {
            r = pm_error_set(PM_ERR_INPUT, "--only %s: radiance buffer '%s' is component=%s, direct and indirect "
                             "together", only_names[o->only], in[i].path, in[i].component);
            break;
        }
        in[i].used = o->only == ONLY_ALL || (o->only == ONLY_DIRECT ? is_direct : is_indirect);
        if (first < 0)
            first = i;
        else if ((r = check_same(in[first].path, pm_reader_header(in[first].rd), in[i].path, hi)) != PM_OK)
            break;
        if (in[i].used)
            ndirect += is_direct, nindirect += is_indirect, ntotal += !is_direct && !is_indirect;
    }
    if (r != PM_OK)
        goto done;
    if (ndirect + nindirect + ntotal == 0) {
        r = pm_error_set(PM_ERR_INPUT, "--only %s: none of the %d buffers is %s", only_names[o->only], nin,
                         only_names[o->only]);
        goto done;
    }
    const pm_header_t *h0 = pm_reader_header(in[first].rd);
    uint32_t w, ht;
    if ((r = pm_header_get_image_size(h0, in[first].path, &w, &ht)) != PM_OK)
        goto done;
    uint64_t n = (uint64_t)w * ht;
    const char *components = ntotal || (ndirect && nindirect) ? "total" : ndirect ? "direct" : "indirect";

    acc = pm_alloc_aligned(3 * n * sizeof *acc);
    chunk = pm_alloc_aligned(pm_schema_record_size(&pm_radiance_schema, ~0u) * CHUNK_PIXELS); /* the widest record */
    if (!acc || !chunk) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image (%.0f MB)", w, ht,
                         n * 24.0 / 1e6);
        goto done;
    }
    memset(acc, 0, 3 * n * sizeof *acc);
    double t0 = pm_time_wall();
    /* The output header gathers the provenance: inputs' COMMAND lines once each, SCENE, this
     * command, one INPUT per buffer read. Buffers left out by --only are not read. */
    for (int i = 0; i < nin && r == PM_OK; i++)
        if (in[i].used)
            r = pm_header_inherit(&h, pm_reader_header(in[i].rd));
    if (r == PM_OK)
        r = pm_header_add_command(&h, st->argc, st->argv);
    for (int i = 0; i < nin && r == PM_OK; i++) {
        if (!in[i].used)
            continue;
        if ((r = accumulate(&in[i], acc, chunk, n, &in[i].hash)) != PM_OK ||
            (r = pm_header_add_input(&h, strcmp(in[i].path, "-") ? in[i].path : "stdin", in[i].hash)) != PM_OK)
            break;
        for (int j = 0; j < i; j++) /* the same content twice is most likely a slip: say so */
            if (in[j].used && in[j].hash == in[i].hash) {
                pm_stage_note(st, "note: '%s' has the same content as '%s' (xxh3:%016" PRIx64 "); both are added",
                              in[i].path, in[j].path, in[i].hash);
                break;
            }
    }
    if (r != PM_OK)
        goto done;
    double t1 = pm_time_wall();

    /* NaN and Inf are never written: inputs are finite (the reader checks), but a scale can
     * overflow f64, f32 or half. Stats in the same pass. */
    double lmin = INFINITY, lmax = -INFINITY, lsum = 0.0;
    float lim = o->half ? PM_EXR_HALF_MAX : 3.4028235e38f;
    pix = pm_alloc_aligned(3 * n * sizeof *pix);
    if (!pix) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", w, ht);
        goto done;
    }
    for (uint64_t p = 0; p < n; p++) {
        for (int c = 0; c < 3; c++) {
            double v = acc[3 * p + (uint64_t)c];
            if (!(fabs(v) <= (double)lim)) {
                r = pm_error_set(PM_ERR_INPUT, "pixel (%" PRIu64 ", %" PRIu64 ") channel %c is %g after scaling, "
                                 "beyond %s (largest %g)", p % w, p / w, "RGB"[c], v,
                                 o->half ? "half" : "float", (double)lim);
                goto done;
            }
            pix[3 * p + (uint64_t)c] = (float)v;
        }
        double l = luminance(acc + 3 * p);
        lmin = l < lmin ? l : lmin, lmax = l > lmax ? l : lmax, lsum += l;
    }

    if (to_exr) {
        if ((r = exr_attrs(&h, components, &attrs, &nattrs, &names)) != PM_OK ||
            (r = pm_exr_write_rgb(st->output, w, ht, pix, o->half ? PM_EXR_HALF : PM_EXR_FLOAT,
                                  (pm_exr_compression_t)o->compression, attrs, nattrs)) != PM_OK)
            goto done;
    }
    double clipped = 0.0;
    if (o->png && (r = write_png(o->png, acc, w, ht, o->exposure, o->tone, &clipped)) != PM_OK)
        goto done;
    if (o->radiance) {
        pm_table_t t;
        if ((r = pm_table_alloc(&t, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, n)) != PM_OK)
            goto done;
        memcpy(t.hdr.bounds, h0->bounds, sizeof t.hdr.bounds);
        r = pm_header_inherit(&t.hdr, &h);
        for (size_t i = 0; i < h.nkeys && r == PM_OK; i++)
            if (!strcmp(h.keys[i].key, "INPUT"))
                r = pm_header_add(&t.hdr, "INPUT", "%s", h.keys[i].value);
        if (r == PM_OK)
            r = pm_header_set(&t.hdr, "width", "%" PRIu32, w);
        if (r == PM_OK)
            r = pm_header_set(&t.hdr, "height", "%" PRIu32, ht);
        if (r == PM_OK)
            r = pm_header_set(&t.hdr, "component", "%s", components);
        if (r == PM_OK) {
            memcpy(t.col[PM_RADIANCE_RGB], acc, 3 * n * sizeof *acc);
            r = pm_table_write(&t, o->radiance);
        }
        pm_table_free(&t);
        if (r != PM_OK)
            goto done;
    }
    double t2 = pm_time_wall();

    st->items = n;
    pm_stage_stat_int(st, "pixels", (int64_t)n);
    pm_stage_stat_int(st, "width", w);
    pm_stage_stat_int(st, "height", ht);
    pm_stage_stat_int(st, "buffers", ndirect + nindirect + ntotal);
    pm_stage_stat_string(st, "components", components);
    pm_stage_stat_double(st, "luminance_min", lmin);
    pm_stage_stat_double(st, "luminance_max", lmax);
    pm_stage_stat_double(st, "luminance_mean", n ? lsum / (double)n : 0.0);
    pm_stage_stat_string(st, "exr_pixel", o->half ? "half" : "float");
    if (o->png)
        pm_stage_stat_double(st, "png_clipped_fraction", clipped);
    pm_stage_stat_double(st, "read_add_s", t1 - t0);
    pm_stage_stat_double(st, "write_s", t2 - t1);
done:
    if (names)
        for (size_t i = 0; names[i]; i++)
            free(names[i]);
    free(names);
    free(attrs);
    pm_free_aligned(pix);
    pm_free_aligned(chunk);
    pm_free_aligned(acc);
    pm_header_free(&h);
    for (int i = 0; i < nin; i++) {
        pm_reader_close(in[i].rd);
        free(in[i].path);
    }
    free(in);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    composite_options_t o = {.only = ONLY_ALL, .tone = TONE_SRGB};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"only", 0, PM_OPT_CHOICE, &o.only, "WHICH",
         "add every buffer (all), or only those whose component is direct or indirect", 1, 0, only_names},
        {"half", 0, PM_OPT_FLAG, &o.half, NULL, "write the EXR as half floats (16-bit) instead of float (32-bit)", 1,
         0, NULL},
        {"compression", 0, PM_OPT_CHOICE, &o.compression, "HOW", "EXR compression: zip (lossless), none or piz", 1,
         0, compression_names},
        {"png", 0, PM_OPT_STRING, &o.png, "FILE", "also write an 8-bit sRGB PNG preview here", 1, 0, NULL},
        {"exposure", 0, PM_OPT_DOUBLE, &o.exposure, "EV", "the preview shows radiance times 2^EV", -64, 64, NULL},
        {"tone", 0, PM_OPT_CHOICE, &o.tone, "CURVE",
         "preview tone curve: srgb (clip at 1) or filmic (ACES fit, rolls highlights off)", 1, 0, tone_names},
        {"radiance", 0, PM_OPT_STRING, &o.radiance, "FILE", "also write the sum as a pmtk radiance buffer", 1, 0,
         NULL},
        {0},
    };
    const pm_cli_t cli = {"composite", "[options] BUFFER[:SCALE]... -o IMAGE.exr [--png PREVIEW.png]",
                          "Add radiance buffers (direct, indirect, shards), each times its SCALE, into an OpenEXR "
                          "image and a PNG preview.",
                          options, 1, -1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
