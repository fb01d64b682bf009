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
 * the arguments. Every buffer must have the resolution and the SCENE of the first.
 *
 * With --accumulate STATE the sum is one progressive pass: it is averaged into the running
 * image held in STATE (mean and variance of the passes so far), the outputs show the new
 * mean; every output, STATE included, is one output set (renamed into place together at
 * the end, or none), so that a failure anywhere leaves the earlier passes' image and state
 * as they were.
 *
 * An OpenEXR input (trace-reference's or measure-error's images) is previewed instead: the
 * one image, times its SCALE, tone-mapped into the --png PNG.
 *
 * With --stream every input is a stream of radiance documents (docs/formats.md, "Streams"), one
 * per frame, and each frame's documents are added into that frame's outputs, whose names are
 * patterns holding the frame number (frame-%04d.exr), until the streams end together. Each
 * frame's outputs appear together, or none of them.
 *
 * --stream with --accumulate STATE is resident progressive passes (common/engine/progressive.c):
 * each document set is one pass (the pass its header key names), averaged into STATE, and -o,
 * --png and --radiance (plain names, no pattern) are rewritten after every pass, together with
 * STATE, so that the image is whole after every pass; --pass-log FILE hears a line
 * "PASS PASSES RELATIVE_ERROR" when a pass's outputs are in place (a driver's pipe). */
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/atomic.h"
#include "base/exr.h"
#include "base/memory.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "image/composite.h"
#include "image/rgb.h"
#include "image/tone.h"

static const char *const compression_names[] = {"zip", "none", "piz", NULL}; /* pm_exr_compression_t order */

typedef struct {
    int only, tone, half, compression;
    const char *png;      /* --png FILE, NULL for none */
    const char *radiance; /* --radiance FILE: the sum as a pmtk radiance buffer */
    double exposure;      /* EV: the PNG shows radiance x 2^EV */
    const char *state;    /* --accumulate FILE: the running image of progressive passes */
    int64_t pass;         /* --pass N: the pass the sum is (0: the next one) */
    int stream;           /* --stream: the inputs are streams of documents, one frame each */
    const char *pass_log; /* --pass-log FILE: a line per pass added (--stream --accumulate) */
    double weight;        /* --weight W: the pass's weight in the running image */
    const char *weights;  /* --weights FILE: a line "PASS WEIGHT" per pass (--stream --accumulate) */
    const char *aov;      /* --aov LIST: denoiser layers beside R G B (albedo,normal,depth,variance), NULL for none */
    const char *aov_file; /* --aov-buffer FILE: the aov file albedo, normal and depth come from */
    const char *map;      /* --adaptive-map FILE: the next adaptive passes' multiplier, from the running image */
} composite_options_t;

/* pattern with its one %d (or %0Nd, N < 10) replaced by frame; NULL pattern gives NULL. */
static pm_result_t frame_path(const char *option, const char *pattern, uint64_t frame, char *out, size_t cap,
                              const char **path_out)
{
    *path_out = NULL;
    if (!pattern)
        return PM_OK;
    const char *pc = strchr(pattern, '%');
    int width = 0;
    const char *d = pc ? pc + 1 : NULL;
    if (d && *d == '0' && d[1] >= '1' && d[1] <= '9')
        width = d[1] - '0', d += 2;
    if (!d || *d != 'd' || strchr(d, '%'))
        return pm_error_set(PM_ERR_USAGE,
                            "--stream: %s '%s' must hold one %%d or %%0Nd for the frame number (frame-%%04d.exr)",
                            option, pattern);
    int n = snprintf(out, cap, "%.*s%0*" PRIu64 "%s", (int)(pc - pattern), pattern, width, frame, d + 1);
    if (n < 0 || (size_t)n >= cap)
        return pm_error_set(PM_ERR_USAGE, "--stream: %s '%s' is too long", option, pattern);
    *path_out = out;
    return PM_OK;
}

/* 1 when f has nothing more to read (the clean end of its stream), 0 when a document follows. */
static int stream_ended(FILE *f)
{
    int c = getc(f);
    if (c == EOF)
        return !ferror(f);
    ungetc(c, f);
    return 0;
}

/* The same content twice is most likely a slip: say so, and add both. */
static void note_repeat(void *ctx, const char *path, const char *same_as, uint64_t hash)
{
    pm_stage_note(ctx, "note: '%s' has the same content as '%s' (xxh3:%016" PRIx64 "); both are added", path, same_as,
                  hash);
}

/* 1 when path starts with OpenEXR's magic number (0x762f3101, little-endian). */
static int is_exr(const char *path)
{
    unsigned char m[4] = {0};
    FILE *f = strcmp(path, "-") ? fopen(path, "rb") : NULL;
    size_t n = f ? fread(m, 1, sizeof m, f) : 0;
    if (f)
        fclose(f);
    return n == 4 && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01;
}

/* The PNG preview of one OpenEXR image, times its scale: the only output it makes. */
static pm_result_t preview_exr(pm_stage_t *st, const composite_options_t *o)
{
    char *path = NULL;
    double scale = 1.0, clipped = 0.0;
    pm_result_t r = pm_composite_parse_input(st->args.args[0], &path, &scale);
    if (r != PM_OK)
        return r;
    if (st->args.nargs != 1 || strcmp(st->output, "-") != 0 || o->radiance || o->state || !o->png ||
        o->only != PM_ONLY_ALL) {
        r = pm_error_set(PM_ERR_USAGE,
                         "'%s' is an OpenEXR image: composite makes its PNG preview alone (one input, --png FILE, "
                         "no -o, --radiance, --accumulate or --only)",
                         path);
        free(path);
        return r;
    }
    pm_stage_output_set(st);
    pm_rgb_image_t im;
    r = pm_rgb_image_read(path, &im);
    free(path);
    if (r != PM_OK)
        return r;
    size_t n = (size_t)im.w * im.h * 3;
    for (size_t i = 0; i < n; i++)
        im.rgb[i] *= scale;
    r = pm_tone_write_png(o->png, im.rgb, im.w, im.h, o->exposure, (pm_tone_t)o->tone, &clipped);
    if (r == PM_OK) {
        st->items = (uint64_t)im.w * im.h;
        pm_stage_stat_int(st, "pixels", (int64_t)im.w * im.h);
        pm_stage_stat_int(st, "width", im.w);
        pm_stage_stat_int(st, "height", im.h);
        pm_stage_stat_string(st, "input", "exr");
        pm_stage_stat_double(st, "png_clipped_fraction", clipped);
    }
    pm_rgb_image_free(&im);
    return r;
}

/* The weight of pass `pass` from --weights' next line "PASS WEIGHT" (a driver writes it as it
 * asks for the pass). */
static pm_result_t next_weight(FILE *f, const char *path, uint64_t pass, double *w_out)
{
    char line[256], extra[8];
    unsigned long long p = 0;
    double w = 0.0;
    if (!fgets(line, sizeof line, f))
        return pm_error_set(PM_ERR_INPUT, "the weights '%s' end before pass %" PRIu64, path, pass);
    if (sscanf(line, "%llu %lf %7s", &p, &w, extra) != 2 || p != pass || !(w > 0.0 && isfinite(w)))
        return pm_error_set(
            PM_ERR_INPUT, "the weights '%s': expected 'PASS WEIGHT' for pass %" PRIu64 ", a weight above 0, not '%.*s'",
            path, pass, (int)strcspn(line, "\n"), line);
    *w_out = w;
    return PM_OK;
}

/* --stream: a frame per document of every input, written to the patterns' names. */
static pm_result_t run_stream(pm_stage_t *st, const composite_options_t *o)
{
    int n = st->args.nargs, to_exr = strcmp(st->output, "-") != 0;
    if (o->pass)
        return pm_error_set(PM_ERR_USAGE, "--stream: the documents name their passes (--pass is for one pass)");
    if (!to_exr && !o->png && !o->radiance && !o->state)
        return pm_error_set(PM_ERR_USAGE, "no output: give -o FRAME-%%04d.exr, --png or --radiance patterns");
    if (o->pass_log && !o->state)
        return pm_error_set(PM_ERR_USAGE, "--pass-log reports the passes of --accumulate");
    if (o->map && !o->state)
        return pm_error_set(PM_ERR_USAGE, "--adaptive-map is made from the running image: it needs --accumulate STATE");
    if (o->weights && !o->state)
        return pm_error_set(PM_ERR_USAGE, "--weights gives the passes of --accumulate their weights");
    FILE *log = NULL, *wf = NULL;
    if (o->weights && !(wf = strcmp(o->weights, "-") ? fopen(o->weights, "r") : NULL))
        return pm_error_set(strcmp(o->weights, "-") ? PM_ERR_INPUT : PM_ERR_USAGE, "cannot read the weights '%s'%s%s",
                            o->weights, strcmp(o->weights, "-") ? ": " : ": stdin holds a stream",
                            strcmp(o->weights, "-") ? strerror(errno) : "");
    if (o->pass_log && !(log = fopen(o->pass_log, "w"))) {
        if (wf)
            fclose(wf);
        return pm_error_set(PM_ERR_IO, "cannot open the pass log '%s': %s", o->pass_log, strerror(errno));
    }
    pm_memory_reuse(
        PM_MEMORY_STREAM_REUSE); /* a frame's arrays are allocated again for the next: its freed mappings serve them */
    FILE **files = calloc((size_t)n, sizeof *files);
    char **paths = calloc((size_t)n, sizeof *paths), **names = calloc((size_t)n, sizeof *names);
    double *scales = calloc((size_t)n, sizeof *scales);
    pm_result_t r = files && paths && names && scales ? PM_OK : pm_error_set(PM_ERR_NOMEM, "out of memory");
    int nstdin = 0;
    for (int i = 0; i < n && r == PM_OK; i++) {
        if ((r = pm_composite_parse_input(st->args.args[i], &paths[i], &scales[i])) != PM_OK)
            break;
        if (!strcmp(paths[i], "-"))
            files[i] = nstdin++ ? NULL : stdin;
        else
            files[i] = fopen(paths[i], "rb");
        if (!files[i])
            r = nstdin > 1 ? pm_error_set(PM_ERR_USAGE, "stdin ('-') given twice")
                           : pm_error_set(pm_result_of_errno(errno), "cannot open '%s': %s", paths[i], strerror(errno));
    }
    uint64_t frame = 0;
    double t_add = 0.0, t_write = 0.0;
    pm_composite_info_t last = {0};
    char exr[4096], png[4096], rad[4096];
    FILE **mem = calloc((size_t)n, sizeof *mem);
    unsigned char **doc = calloc((size_t)n, sizeof *doc);
    if (r == PM_OK && (!mem || !doc))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory");
    while (r == PM_OK) {
        /* Each input's document is taken off its stream whole, in the order given, before the
         * next input is waited on: the stage writing the first is never held up by the second. */
        int ended = 0;
        for (int i = 0; i < n && r == PM_OK; i++) {
            char name[4200];
            pm_stream_frame_name(name, sizeof name, paths[i], frame);
            size_t len;
            free(doc[i]);
            doc[i] = NULL;
            if ((r = pm_reader_take_next(files[i], name, &pm_radiance_schema, &doc[i], &len)) != PM_OK)
                break;
            if (!doc[i] && i == 0) {
                ended = 1;
                break;
            }
            if (!doc[i]) {
                r = pm_error_set(PM_ERR_INPUT, "stream '%s' has ended at frame %" PRIu64 " while '%s' goes on",
                                 paths[i], frame, paths[0]);
                break;
            }
            if (mem[i])
                fclose(mem[i]);
            if (!(mem[i] = fmemopen(doc[i], len, "rb")))
                r = pm_error_set(PM_ERR_NOMEM, "out of memory");
            snprintf(name + strlen(name), sizeof name - strlen(name), ":%.17g", scales[i]);
            free(names[i]);
            if (r == PM_OK && !(names[i] = strdup(name)))
                r = pm_error_set(PM_ERR_NOMEM, "out of memory");
        }
        if (r == PM_OK && ended)
            for (int i = 1; i < n && r == PM_OK; i++)
                if (!stream_ended(files[i]))
                    r = pm_error_set(PM_ERR_INPUT, "stream '%s' has ended at frame %" PRIu64 " while '%s' goes on",
                                     paths[0], frame, paths[i]);
        if (r != PM_OK || ended)
            break;
        const char *exr_path = to_exr ? st->output : NULL, *png_path = o->png, *rad_path = o->radiance;
        if (!o->state && /* frames: a name each; passes: the same names, rewritten */
            ((r = frame_path("-o", exr_path, frame, exr, sizeof exr, &exr_path)) != PM_OK ||
             (r = frame_path("--png", o->png, frame, png, sizeof png, &png_path)) != PM_OK ||
             (r = frame_path("--radiance", o->radiance, frame, rad, sizeof rad, &rad_path)) != PM_OK))
            break;
        pm_atomic_set_t set;
        pm_atomic_set_begin(&set); /* the frame's outputs appear together, or none */
        pm_composite_t *c;
        double t0 = pm_time_wall(), clipped = 0.0;
        r = pm_composite_open_streams(&c, names, mem, n, (pm_composite_only_t)o->only);
        if (r == PM_OK)
            r = pm_composite_sum(c, st->argc, st->argv, note_repeat, st);
        uint64_t pass = 0;
        double w = o->weight;
        if (r == PM_OK && o->state && (r = pm_composite_pass(c, &pass)) == PM_OK && wf)
            r = next_weight(wf, o->weights, pass, &w);
        if (r == PM_OK && o->state)
            r = pm_composite_accumulate(c, o->state, pass, w);
        if (r == PM_OK)
            r = pm_composite_finish(c, o->half);
        double t1 = pm_time_wall();
        if (r == PM_OK && exr_path)
            r = pm_composite_write_exr(c, exr_path, (pm_exr_compression_t)o->compression);
        if (r == PM_OK && png_path)
            r = pm_composite_write_png(c, png_path, o->exposure, (pm_tone_t)o->tone, &clipped);
        if (r == PM_OK && rad_path)
            r = pm_composite_write_radiance(c, rad_path);
        if (r == PM_OK && o->state)
            r = pm_composite_write_state(c, o->state);
        if (r == PM_OK && o->map)
            r = pm_composite_write_adaptive_map(c, o->map, st->argc, st->argv);
        r = pm_atomic_set_end(&set, r);
        t_add += t1 - t0;
        t_write += pm_time_wall() - t1;
        if (r == PM_OK)
            last = *pm_composite_info(c);
        if (r == PM_OK && log) {
            /* the pass is in place: say so at once (a driver waits on this line) */
            char err[32] = "-";
            if (isfinite(last.relative_error))
                snprintf(err, sizeof err, "%.6g", last.relative_error);
            if (fprintf(log, "%" PRIu64 " %" PRIu64 " %s\n", pass ? pass : last.passes, last.passes, err) < 0 ||
                fflush(log) != 0)
                r = pm_error_set(PM_ERR_IO, "cannot write the pass log '%s': %s", o->pass_log, strerror(errno));
        }
        pm_composite_free(c);
        if (r == PM_OK)
            frame++;
    }
    if (r == PM_OK && frame == 0)
        r = pm_error_set(PM_ERR_INPUT, "empty streams: no radiance document");
    if (wf)
        fclose(wf);
    if (log && fclose(log) != 0 && r == PM_OK)
        r = pm_error_set(PM_ERR_IO, "cannot write the pass log '%s': %s", o->pass_log, strerror(errno));
    if (r == PM_OK) {
        st->items = last.pixels * frame;
        pm_stage_stat_int(st, "frames", (int64_t)frame);
        if (o->state) {
            pm_stage_stat_int(st, "passes", (int64_t)last.passes);
            pm_stage_stat_double(st, "relative_error", last.relative_error); /* null after one pass */
        }
        pm_stage_stat_int(st, "pixels", (int64_t)last.pixels);
        pm_stage_stat_int(st, "width", last.width);
        pm_stage_stat_int(st, "height", last.height);
        pm_stage_stat_int(st, "buffers", last.buffers);
        pm_stage_stat_string(st, "exr_pixel", o->half ? "half" : "float");
        pm_stage_stat_double(st, "read_add_s", t_add);
        pm_stage_stat_double(st, "write_s", t_write);
    }
    for (int i = 0; i < n; i++) {
        if (files)
            pm_stream_close(files[i]);
        if (mem && mem[i])
            fclose(mem[i]);
        if (doc)
            free(doc[i]);
        if (paths)
            free(paths[i]);
        if (names)
            free(names[i]);
    }
    free(files), free(paths), free(names), free(scales), free(mem), free(doc);
    return r;
}

static pm_result_t run(pm_stage_t *st, const composite_options_t *o)
{
    if ((o->aov || o->aov_file) && o->stream)
        return pm_error_set(PM_ERR_USAGE, "--aov and --aov-buffer are not done for --stream (one image at a time)");
    if (o->stream)
        return run_stream(st, o);
    for (int i = 0; i < st->args.nargs; i++) {
        char *path = NULL;
        double scale;
        if (pm_composite_parse_input(st->args.args[i], &path, &scale) == PM_OK && is_exr(path)) {
            free(path);
            return preview_exr(st, o);
        }
        free(path);
    }
    int to_exr = strcmp(st->output, "-") != 0;
    if (!to_exr && !o->png && !o->radiance && !o->state)
        return pm_error_set(PM_ERR_USAGE, "no output: give -o IMAGE.exr (OpenEXR cannot write to a pipe), --png, "
                                          "--radiance or --accumulate");
    if (o->pass && !o->state)
        return pm_error_set(PM_ERR_USAGE, "--pass %" PRId64 " needs --accumulate STATE (the running image)", o->pass);
    if (o->map && !o->state)
        return pm_error_set(PM_ERR_USAGE,
                            "--adaptive-map %s is made from the running image: it needs --accumulate STATE", o->map);
    if (pm_args_given(&st->args, "weight") && !o->state)
        return pm_error_set(PM_ERR_USAGE, "--weight %g is a pass's weight: it needs --accumulate STATE", o->weight);
    unsigned aov = 0;
    if (o->aov) {
        pm_result_t ra = pm_exr_aov_parse("--aov", o->aov, &aov);
        if (ra != PM_OK)
            return ra;
        if (!to_exr)
            return pm_error_set(PM_ERR_USAGE, "--aov %s: the layers go into the EXR: give -o IMAGE.exr", o->aov);
        if ((aov & PM_EXR_AOV_VARIANCE) && !o->state)
            return pm_error_set(PM_ERR_USAGE, "--aov variance is the running image's: give --accumulate STATE");
        if ((aov & PM_EXR_AOV_SURFACE) && !o->aov_file)
            return pm_error_set(PM_ERR_USAGE,
                                "--aov %s: albedo, normal and depth come from --aov-buffer FILE "
                                "(trace-gather-points --aov)",
                                o->aov);
    }
    if (o->aov_file && !(aov & PM_EXR_AOV_SURFACE))
        return pm_error_set(PM_ERR_USAGE, "--aov-buffer %s is read for --aov albedo, normal or depth: none asked for",
                            o->aov_file);
    pm_stage_output_set(st); /* the EXR, the PNG, the radiance buffer and the running image appear together, or none */
    pm_composite_t *c;
    pm_result_t r = pm_composite_open(&c, st->args.args, st->args.nargs, (pm_composite_only_t)o->only);
    double t0 = pm_time_wall();
    if (r == PM_OK)
        r = pm_composite_sum(c, st->argc, st->argv, note_repeat, st);
    if (r == PM_OK && o->state)
        r = pm_composite_accumulate(c, o->state, (uint64_t)o->pass, o->weight);
    double t1 = pm_time_wall(), clipped = 0.0;
    if (r == PM_OK)
        r = pm_composite_finish(c, o->half);
    if (r == PM_OK && aov)
        r = pm_composite_set_aov(c, aov, o->aov_file);
    if (r == PM_OK && to_exr)
        r = pm_composite_write_exr(c, st->output, (pm_exr_compression_t)o->compression);
    if (r == PM_OK && o->png)
        r = pm_composite_write_png(c, o->png, o->exposure, (pm_tone_t)o->tone, &clipped);
    if (r == PM_OK && o->radiance)
        r = pm_composite_write_radiance(c, o->radiance);
    if (r == PM_OK && o->state)
        r = pm_composite_write_state(c, o->state);
    if (r == PM_OK && o->map)
        r = pm_composite_write_adaptive_map(c, o->map, st->argc, st->argv);
    double t2 = pm_time_wall();

    if (r == PM_OK) {
        const pm_composite_info_t *in = pm_composite_info(c);
        st->items = in->pixels;
        pm_stage_stat_int(st, "pixels", (int64_t)in->pixels);
        pm_stage_stat_int(st, "width", in->width);
        pm_stage_stat_int(st, "height", in->height);
        pm_stage_stat_int(st, "buffers", in->buffers);
        pm_stage_stat_string(st, "components", in->components);
        pm_stage_stat_double(st, "luminance_min", in->luminance_min);
        pm_stage_stat_double(st, "luminance_max", in->luminance_max);
        pm_stage_stat_double(st, "luminance_mean", in->luminance_mean);
        pm_stage_stat_string(st, "exr_pixel", o->half ? "half" : "float");
        if (o->png)
            pm_stage_stat_double(st, "png_clipped_fraction", clipped);
        if (o->state) {
            pm_stage_stat_int(st, "passes", (int64_t)in->passes);
            pm_stage_stat_double(st, "relative_error", in->relative_error); /* null after one pass */
        }
        pm_stage_stat_double(st, "read_add_s", t1 - t0);
        pm_stage_stat_double(st, "write_s", t2 - t1);
    }
    pm_composite_free(c);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    composite_options_t o = {.only = PM_ONLY_ALL, .tone = PM_TONE_SRGB, .weight = 1.0};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"only", 0, PM_OPT_CHOICE, &o.only, "WHICH",
         "add every buffer (all), or only those whose component is direct, indirect or caustic", 1, 0,
         pm_composite_only_names},
        {"half", 0, PM_OPT_FLAG, &o.half, NULL, "write the EXR as half floats (16-bit) instead of float (32-bit)", 1, 0,
         NULL},
        {"compression", 0, PM_OPT_CHOICE, &o.compression, "HOW", "EXR compression: zip (lossless), none or piz", 1, 0,
         compression_names},
        {"png", 0, PM_OPT_OUTPUT, &o.png, "FILE", "also write an 8-bit sRGB PNG preview here", 1, 0, NULL},
        {"exposure", 0, PM_OPT_DOUBLE, &o.exposure, "EV", "the preview shows radiance times 2^EV", -64, 64, NULL},
        {"tone", 0, PM_OPT_CHOICE, &o.tone, "CURVE",
         "preview tone curve: srgb (clip at 1) or filmic (ACES fit, rolls highlights off)", 1, 0, pm_tone_names},
        {"radiance", 0, PM_OPT_OUTPUT, &o.radiance, "FILE", "also write the sum as a pmtk radiance buffer", 1, 0, NULL},
        {"accumulate", 0, PM_OPT_OUTPUT, &o.state, "STATE",
         "the sum is one progressive pass: average it into the running image STATE (a radiance buffer with the "
         "mean and variance of the passes; created when missing, rewritten with the other outputs); the outputs show "
         "the mean",
         1, 0, NULL},
        {"pass", 0, PM_OPT_INT, &o.pass, "N",
         "with --accumulate: the sum is pass N, which must be STATE's passes + 1 (0: the next, unchecked)", 0,
         (double)((int64_t)1 << 40), NULL},
        {"stream", 0, PM_OPT_FLAG, &o.stream, NULL,
         "every BUFFER is a stream of documents, one per frame: write a frame per document of each, to -o, --png and "
         "--radiance names holding %04d (the frame number from 0); with --accumulate each document set is a pass and "
         "the outputs (plain names) are rewritten after each",
         1, 0, NULL},
        {"weight", 0, PM_OPT_DOUBLE, &o.weight, "W",
         "with --accumulate: the pass's weight, its size against the others' (its variance taken as sigma^2 / W)", 1e-9,
         1e9, NULL},
        {"adaptive-map", 0, PM_OPT_OUTPUT, &o.map, "FILE",
         "with --accumulate: write the next adaptive passes' sample-count multiplier (a density map for "
         "trace-gather-points --adaptive) from the running image: rays where its relative error is",
         1, 0, NULL},
        {"weights", 0, PM_OPT_STRING, &o.weights, "FILE",
         "with --stream --accumulate: a line 'PASS WEIGHT' per pass, read as each pass arrives (a driver's pipe)", 1, 0,
         NULL},
        {"aov", 0, PM_OPT_STRING, &o.aov, "LIST",
         "also write these layers into the EXR for a denoiser, comma-separated: albedo (albedo.R/G/B), normal "
         "(normal.X/Y/Z), depth (Z) from --aov-buffer, variance (variance.R/G/B) of the running image (--accumulate)",
         1, 0, NULL},
        {"aov-buffer", 0, PM_OPT_STRING, &o.aov_file, "FILE",
         "the aov file (trace-gather-points --aov) that --aov albedo, normal and depth come from", 1, 0, NULL},
        {"pass-log", 0, PM_OPT_OUTPUT, &o.pass_log, "FILE",
         "with --stream --accumulate: a line 'PASS PASSES RELATIVE_ERROR' here as each pass's outputs are in place "
         "(- for the error until a second pass)",
         1, 0, NULL},
        {0},
    };
    static const char about[] =
        "Add radiance buffers (direct, indirect, shards), each times its SCALE, into an OpenEXR "
        "image and a PNG preview; or make the PNG preview of one OpenEXR image (IMAGE.exr[:SCALE] --png FILE).";
    const pm_cli_t cli = {
        "composite", "[options] BUFFER[:SCALE]... -o IMAGE.exr [--png PREVIEW.png]", about, options, 1, -1, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
