/* composite.c: radiance buffers (direct, indirect, shards), each times a scale, summed into
 * one image and written as OpenEXR, PNG preview or radiance buffer: the work of the composite
 * stage (see composite.h). Buffers are read one after the other in chunks and added in f64 in
 * the order given, so the sum depends on nothing but the arguments. */
#include "image/composite.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/args.h"
#include "base/memory.h"
#include "base/version.h"
#include "formats/formats.h"
#include "image/adaptive.h"

#define CHUNK_PIXELS 65536 /* records read at a time: 1.5 MB of f64 RGB */

const char *const pm_composite_only_names[] = {"all", "direct", "indirect", "caustic", NULL};

/* One buffer: a path with its scale. */
typedef struct {
    char *path;
    double scale;
    pm_reader_t *rd;
    const char *component; /* the header's, owned by the reader */
    int used;              /* not left out by --only */
    uint64_t hash;         /* content hash, once read */
} input_t;

struct pm_composite {
    pm_composite_info_t info;
    input_t *in;
    int nin;
    int first;                   /* the buffer whose resolution, scene and bounds the others must share */
    pm_header_t hdr;             /* the outputs' provenance, from pm_composite_sum */
    double *acc;                 /* 3 per pixel, the sum; after pm_composite_accumulate the mean of the passes */
    double *var;                 /* 3 per pixel after pm_composite_accumulate: squared standard error of the mean */
    char alpha[40], radius1[40]; /* the schedule's words, as the gather wrote them ("" when not given) */
    double weight;               /* after pm_composite_accumulate: the passes' weights summed */
    double *pws; /* 1 per pixel after an adaptive pass entered the running image: its weights summed, else NULL */
    float *pix;  /* 3 per pixel, the EXR's values, from pm_composite_finish */
    int half;
    unsigned aov; /* PM_EXR_AOV_* layers the EXR carries beside R G B (pm_composite_set_aov) */
    float *surf;  /* 7 per pixel: albedo, normal, depth from an aov file, when aov asks for them */
    float *varf;  /* 3 per pixel: var as the EXR's floats, when aov asks for variance */
};

pm_result_t pm_composite_parse_input(const char *arg, char **path_out, double *scale_out)
{
    const char *colon = strrchr(arg, ':');
    double s;
    *scale_out = 1.0;
    if (colon && colon != arg && pm_parse_double(colon + 1, &s) == PM_OK) {
        if (!isfinite(s))
            return pm_error_set(PM_ERR_USAGE, "bad scale in '%s': %g is not finite", arg, s);
        *scale_out = s;
        *path_out = strndup(arg, (size_t)(colon - arg));
    } else {
        *path_out = strdup(arg);
    }
    return *path_out ? PM_OK : pm_error_set(PM_ERR_NOMEM, "out of memory");
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
        return pm_error_set(PM_ERR_INPUT,
                            "resolution mismatch: '%s' is %" PRIu32 "x%" PRIu32 ", '%s' is %" PRIu32 "x%" PRIu32, path,
                            w, ht, first, w0, ht0);
    const char *s0 = pm_header_get(h0, "SCENE"), *s = pm_header_get(h, "SCENE");
    if ((s0 || s) && (!s0 || !s || strcmp(s0, s)))
        return pm_error_set(PM_ERR_INPUT, "scene mismatch: '%s' is of scene '%s', '%s' of scene '%s'", path,
                            s ? s : "(none)", first, s0 ? s0 : "(none)");
    return PM_OK;
}

pm_result_t pm_composite_open(pm_composite_t **c_out, char *const *args, int nin, pm_composite_only_t only)
{
    return pm_composite_open_streams(c_out, args, NULL, nin, only);
}

pm_result_t pm_composite_open_streams(pm_composite_t **c_out, char *const *args, FILE *const *files, int nin,
                                      pm_composite_only_t only)
{
    pm_composite_t *c = calloc(1, sizeof *c);
    *c_out = c;
    if (!c || !(c->in = calloc(nin > 0 ? (size_t)nin : 1, sizeof *c->in)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory");
    c->nin = nin;
    c->first = -1;
    pm_header_init(&c->hdr, &pm_radiance_schema);
    input_t *in = c->in;
    pm_result_t r = PM_OK;
    int nstdin = 0, ndirect = 0, nindirect = 0, ncaustic = 0, ntotal = 0;
    for (int i = 0; i < nin && r == PM_OK; i++)
        if ((r = pm_composite_parse_input(args[i], &in[i].path, &in[i].scale)) == PM_OK && !strcmp(in[i].path, "-") &&
            ++nstdin > 1)
            r = pm_error_set(PM_ERR_USAGE, "stdin ('-') given twice");
    for (int i = 0; i < nin && r == PM_OK; i++) {
        if ((r = files ? pm_reader_open_next(files[i], in[i].path, &pm_radiance_schema, 0, &in[i].rd)
                       : pm_reader_open(in[i].path, &pm_radiance_schema, 0, &in[i].rd)) != PM_OK)
            break;
        if (!in[i].rd) {
            r = pm_error_set(PM_ERR_INPUT, "stream '%s' has ended: no radiance buffer for this frame", in[i].path);
            break;
        }
        const pm_header_t *hi = pm_reader_header(in[i].rd);
        in[i].component = pm_header_get(hi, "component");
        int is_direct = !strcmp(in[i].component, "direct"), is_indirect = !strcmp(in[i].component, "indirect"),
            is_caustic = !strcmp(in[i].component, "caustic");
        if (only != PM_ONLY_ALL && !is_direct && !is_indirect && !is_caustic) {
            r = pm_error_set(PM_ERR_INPUT,
                             "--only %s: radiance buffer '%s' is component=%s, direct, indirect and caustic "
                             "together",
                             pm_composite_only_names[only], in[i].path, in[i].component);
            break;
        }
        in[i].used = only == PM_ONLY_ALL || (only == PM_ONLY_DIRECT     ? is_direct
                                             : only == PM_ONLY_INDIRECT ? is_indirect
                                                                        : is_caustic);
        if (c->first < 0)
            c->first = i;
        else if ((r = check_same(in[c->first].path, pm_reader_header(in[c->first].rd), in[i].path, hi)) != PM_OK)
            break;
        if (in[i].used)
            ndirect += is_direct, nindirect += is_indirect, ncaustic += is_caustic,
                ntotal += !is_direct && !is_indirect && !is_caustic;
    }
    if (r != PM_OK)
        return r;
    if (ndirect + nindirect + ncaustic + ntotal == 0)
        return pm_error_set(PM_ERR_INPUT, "--only %s: none of the %d buffers is %s", pm_composite_only_names[only], nin,
                            pm_composite_only_names[only]);
    pm_composite_info_t *info = &c->info;
    if ((r = pm_header_get_image_size(pm_reader_header(in[c->first].rd), in[c->first].path, &info->width,
                                      &info->height)) != PM_OK)
        return r;
    info->pixels = (uint64_t)info->width * info->height;
    info->buffers = ndirect + nindirect + ncaustic + ntotal;
    int kinds = (ndirect > 0) + (nindirect > 0) + (ncaustic > 0);
    info->components = ntotal || kinds > 1 ? "total" : ndirect ? "direct" : nindirect ? "indirect" : "caustic";
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

pm_result_t pm_composite_sum(pm_composite_t *c, int argc, char **argv, pm_composite_note_fn note, void *note_ctx)
{
    uint64_t n = c->info.pixels;
    input_t *in = c->in;
    pm_result_t r = PM_OK;
    c->acc = pm_alloc_aligned(3 * n * sizeof *c->acc);
    double *chunk = pm_alloc_aligned(pm_schema_record_size(&pm_radiance_schema, ~0u) * CHUNK_PIXELS); /* widest */
    if (!c->acc || !chunk) {
        pm_free_aligned(chunk);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image (%.0f MB)", c->info.width,
                            c->info.height, n * 24.0 / 1e6);
    }
    memset(c->acc, 0, 3 * n * sizeof *c->acc);
    /* Buffers left out by --only are not read, and give no provenance. */
    for (int i = 0; i < c->nin && r == PM_OK; i++)
        if (in[i].used)
            r = pm_header_inherit(&c->hdr, pm_reader_header(in[i].rd));
    if (r == PM_OK)
        r = pm_header_add_command(&c->hdr, argc, argv);
    for (int i = 0; i < c->nin && r == PM_OK; i++) {
        if (!in[i].used)
            continue;
        if ((r = accumulate(&in[i], c->acc, chunk, n, &in[i].hash)) != PM_OK ||
            (r = pm_header_add_input(&c->hdr, strcmp(in[i].path, "-") ? in[i].path : "stdin", in[i].hash)) != PM_OK)
            break;
        for (int j = 0; j < i && note; j++)
            if (in[j].used && in[j].hash == in[i].hash) {
                note(note_ctx, in[i].path, in[j].path, in[i].hash);
                break;
            }
    }
    pm_free_aligned(chunk);
    return r;
}

/* The schedule's key `key` of the pass (the first kept buffer that has it) into out: empty when
 * no buffer has it; two buffers that disagree are an error. A caustic buffer's radius1 is its
 * own map's (the caustic map is far sparser than the global one): the running image keeps the
 * global gather's. */
static pm_result_t pass_key(const pm_composite_t *c, const char *key, char *out, size_t size)
{
    out[0] = 0;
    const char *first = NULL;
    for (int i = 0; i < c->nin; i++) {
        const char *v = c->in[i].used ? pm_header_get(pm_reader_header(c->in[i].rd), key) : NULL;
        if (!v || (!strcmp(key, "radius1") && !strcmp(c->in[i].component, "caustic")))
            continue;
        if (first && strcmp(v, out))
            return pm_error_set(PM_ERR_INPUT, "buffers of one pass disagree on %s: '%s' says %s, '%s' says %s", key,
                                first, out, c->in[i].path, v);
        if (!first)
            snprintf(out, size, "%s", v), first = c->in[i].path;
    }
    return PM_OK;
}

pm_result_t pm_composite_pass(const pm_composite_t *c, uint64_t *pass_out)
{
    *pass_out = 0;
    const char *first = NULL;
    for (int i = 0; i < c->nin; i++) {
        const char *v = c->in[i].used ? pm_header_get(pm_reader_header(c->in[i].rd), "pass") : NULL;
        int64_t p;
        if (!v)
            continue;
        if (pm_parse_i64(v, &p) != PM_OK || p < 1)
            return pm_error_set(PM_ERR_INPUT, "'%s': header key pass '%s' is not a pass of at least 1", c->in[i].path,
                                v);
        if (first && (uint64_t)p != *pass_out)
            return pm_error_set(PM_ERR_INPUT,
                                "buffers of one pass disagree on pass: '%s' says %" PRIu64 ", '%s' says %s", first,
                                *pass_out, c->in[i].path, v);
        *pass_out = (uint64_t)p, first = c->in[i].path;
    }
    return PM_OK;
}

/* The state's key must equal the pass's, when both have it. */
static pm_result_t same_key(const char *state, const pm_header_t *sh, const char *key, char *pass_value, size_t size,
                            uint64_t pass)
{
    const char *v = pm_header_get(sh, key);
    if (!v)
        return PM_OK;
    if (!pass_value[0]) {
        snprintf(pass_value, size, "%s", v);
        return PM_OK;
    }
    if (strcmp(v, pass_value))
        return pm_error_set(PM_ERR_INPUT,
                            "pass %" PRIu64 " has %s=%s but the running image '%s' has %s=%s: one schedule per "
                            "running image",
                            pass, key, pass_value, state, key, v);
    return PM_OK;
}

/* The pass's per-pixel weights when it was adaptive: the kept buffers' key adaptive ("MAP
 * xxh3:HASH", trace-gather-points --adaptive) names the map, which must still hold that content;
 * pixel p's weight is its primary rays over the pass's (header key primary), the counts
 * trace-gather-points gave it. *pw_out (malloc'd) stays NULL for a uniform pass. */
static pm_result_t pass_pixel_weights(const pm_composite_t *c, double **pw_out)
{
    *pw_out = NULL;
    const char *key = NULL, *from = NULL, *prim = NULL;
    for (int i = 0; i < c->nin; i++) {
        const pm_header_t *h = pm_reader_header(c->in[i].rd);
        const char *v = c->in[i].used ? pm_header_get(h, "adaptive") : NULL;
        if (!v)
            continue;
        if (key && strcmp(key, v))
            return pm_error_set(PM_ERR_INPUT, "buffers of one pass disagree on adaptive: '%s' says %s, '%s' says %s",
                                from, key, c->in[i].path, v);
        if (!key)
            key = v, from = c->in[i].path, prim = pm_header_get(h, "primary");
    }
    if (!key)
        return PM_OK;
    const char *sp = strrchr(key, ' ');
    int64_t p = 0;
    uint64_t want = 0, got = 0;
    if (!sp || sscanf(sp + 1, "xxh3:%16" SCNx64, &want) != 1 || !prim || pm_parse_i64(prim, &p) != PM_OK || p < 1)
        return pm_error_set(PM_ERR_INPUT,
                            "'%s': header key adaptive '%s' (primary '%s') is not 'MAP xxh3:HASH' of a pass "
                            "of at least 1 primary ray",
                            from, key, prim ? prim : "(missing)");
    char *path = strndup(key, (size_t)(sp - key));
    float *m = NULL;
    uint64_t n = c->info.pixels;
    double *pw = NULL;
    pm_result_t r = path ? pm_adaptive_read(path, PM_DENSITY_MULTIPLIER, c->info.width, c->info.height, &m, &got, NULL)
                         : pm_error_set(PM_ERR_NOMEM, "out of memory");
    if (r == PM_OK && got != want)
        r = pm_error_set(PM_ERR_INPUT,
                         "density map '%s' is not the one pass '%s' was traced with (xxh3:%016" PRIx64 ", it says %s)",
                         path, from, got, sp + 1);
    if (r == PM_OK && !(pw = malloc((n ? n : 1) * sizeof *pw)))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of a %" PRIu32 "x%" PRIu32 " image",
                         c->info.width, c->info.height);
    for (uint64_t i = 0; r == PM_OK && i < n; i++) {
        uint32_t k = pm_adaptive_count(m[i], (uint32_t)p);
        if (!k)
            r = pm_error_set(PM_ERR_INPUT, "density map '%s': pixel %" PRIu64 " multiplier %g is above %d rays", path,
                             i, (double)m[i], PM_ADAPTIVE_RAYS_MAX);
        pw[i] = (double)k / (double)p;
    }
    free(path);
    free(m);
    if (r != PM_OK)
        free(pw);
    else
        *pw_out = pw;
    return r;
}

/* The running image's per-pixel weights, STATE.weight beside it (its header pixel_weights=1),
 * of the state's w x h and passes. */
static pm_result_t state_pixel_weights(const pm_composite_t *c, const char *state, uint64_t passes, double **out)
{
    char *path = NULL;
    float *v = NULL;
    pm_header_t h;
    uint64_t n = c->info.pixels, wp = 0;
    pm_result_t r = pm_adaptive_weight_path(state, &path);
    if (r == PM_OK &&
        (r = pm_adaptive_read(path, PM_DENSITY_WEIGHT, c->info.width, c->info.height, &v, NULL, &h)) == PM_OK) {
        if ((r = pm_header_get_u64(&h, path, "passes", &wp)) == PM_OK && wp != passes)
            r = pm_error_set(PM_ERR_INPUT,
                             "the weights '%s' are of %" PRIu64 " passes, the running image '%s' of %" PRIu64, path, wp,
                             state, passes);
        pm_header_free(&h);
    }
    if (r == PM_OK && !(*out = malloc((n ? n : 1) * sizeof **out)))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of a %" PRIu32 "x%" PRIu32 " image",
                         c->info.width, c->info.height);
    for (uint64_t i = 0; r == PM_OK && i < n; i++)
        (*out)[i] = v[i];
    free(v);
    free(path);
    return r;
}

pm_result_t pm_composite_accumulate(pm_composite_t *c, const char *state, uint64_t pass, double w)
{
    uint64_t n = c->info.pixels, n0 = 0;
    double w0 = 0.0; /* the weights of the passes in the state */
    pm_result_t r;
    if (!(w > 0.0 && isfinite(w)))
        return pm_error_set(PM_ERR_USAGE, "a pass's weight must be a finite number above 0, not %g", w);
    if ((r = pass_key(c, "alpha", c->alpha, sizeof c->alpha)) != PM_OK ||
        (r = pass_key(c, "radius1", c->radius1, sizeof c->radius1)) != PM_OK)
        return r;
    if (!(c->var = pm_alloc_aligned(3 * (n ? n : 1) * sizeof *c->var)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the variance of a %" PRIu32 "x%" PRIu32 " image",
                            c->info.width, c->info.height);
    pm_table_t t = {0};
    const double *mean0 = NULL, *var0 = NULL;
    double *pw = NULL, *sw = NULL; /* the pass's per-pixel weights (over w), the state's summed; NULL: uniform */
    if ((r = pass_pixel_weights(c, &pw)) != PM_OK)
        return r;
    if (access(state, F_OK) == 0) {
        const uint32_t need = 1u << PM_RADIANCE_RGB | 1u << PM_RADIANCE_VARIANCE;
        if ((r = pm_table_read(state, &pm_radiance_schema, need, &t)) != PM_OK)
            return r;
        const input_t *f = &c->in[c->first];
        if ((r = check_same(f->path, pm_reader_header(f->rd), state, &t.hdr)) != PM_OK ||
            (r = pm_header_get_u64(&t.hdr, state, "passes", &n0)) != PM_OK)
            goto done;
        if (n0 == 0) {
            r = pm_error_set(PM_ERR_INPUT, "running image '%s' says passes=0", state);
            goto done;
        }
        const char *wk = pm_header_get(&t.hdr, "weight");
        w0 = (double)n0;
        if (wk && (pm_parse_double(wk, &w0) != PM_OK || !(w0 > 0.0 && isfinite(w0)))) {
            r = pm_error_set(PM_ERR_INPUT, "running image '%s': weight '%s' is not a number above 0", state, wk);
            goto done;
        }
        mean0 = t.col[PM_RADIANCE_RGB];
        var0 = t.col[PM_RADIANCE_VARIANCE];
        if (pm_header_get(&t.hdr, "pixel_weights") && (r = state_pixel_weights(c, state, n0, &sw)) != PM_OK)
            goto done;
        uint64_t p = pass ? pass : n0 + 1;
        if ((r = same_key(state, &t.hdr, "alpha", c->alpha, sizeof c->alpha, p)) != PM_OK ||
            (r = same_key(state, &t.hdr, "radius1", c->radius1, sizeof c->radius1, p)) != PM_OK ||
            (r = pm_header_add_input(&c->hdr, state, t.checksum)) != PM_OK)
            goto done;
    }
    if (pass && pass != n0 + 1) {
        r = pm_error_set(PM_ERR_INPUT,
                         pass <= n0 ? "running image '%s' holds %" PRIu64 " passes: pass %" PRIu64 " is in it already"
                                    : "running image '%s' holds %" PRIu64 " passes: pass %" PRIu64
                                      " would leave a gap (add the passes in order)",
                         state, n0, pass);
        goto done;
    }
    uint64_t k = n0 + 1;
    double *x = c->acc, *v = c->var, sq = 0.0, wk = w0 + w;
    uint64_t counted = 0;
    if ((pw || sw) && !(c->pws = malloc((n ? n : 1) * sizeof *c->pws))) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of a %" PRIu32 "x%" PRIu32 " image",
                         c->info.width, c->info.height);
        goto done;
    }
    for (uint64_t i = 0; i < 3 * n; i++) {
        /* per pixel: the pass's weight times the pixel's share of its rays, and the earlier
         * passes' summed (the same w and W for every pixel of uniform passes) */
        double wi = pw ? w * pw[i / 3] : w, w0i = sw ? sw[i / 3] : w0, wki = w0i + wi;
        double m0 = mean0 ? mean0[i] : 0.0;
        /* S of the earlier passes from their stored squared standard error: var = S / (W (n - 1)). */
        double m2 = n0 >= 2 ? var0[i] * w0i * (double)(n0 - 1) : 0.0;
        double d = x[i] - m0, m = m0 + d * wi / wki;
        m2 += wi * d * (x[i] - m);
        x[i] = m;
        v[i] = k >= 2 ? m2 / (wki * (double)(k - 1)) : 0.0;
        if (m > 0.0)
            sq += v[i] / (m * m), counted++;
        if (c->pws)
            c->pws[i / 3] = wki;
    }
    c->info.passes = k;
    c->weight = wk;
    c->info.relative_error = k >= 2 && counted ? sqrt(sq / (double)counted) : (k >= 2 ? 0.0 : NAN);
done:
    free(pw);
    free(sw);
    pm_table_free(&t);
    return r;
}

pm_result_t pm_composite_finish(pm_composite_t *c, int half)
{
    uint64_t n = c->info.pixels;
    uint32_t w = c->info.width;
    const double *acc = c->acc;
    double lmin = INFINITY, lmax = -INFINITY, lsum = 0.0;
    float lim = half ? PM_EXR_HALF_MAX : 3.4028235e38f;
    c->half = half;
    if (!(c->pix = pm_alloc_aligned(3 * n * sizeof *c->pix)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", w, c->info.height);
    for (uint64_t p = 0; p < n; p++) {
        for (int ch = 0; ch < 3; ch++) {
            double v = acc[3 * p + (uint64_t)ch];
            if (!(fabs(v) <= (double)lim))
                return pm_error_set(PM_ERR_INPUT,
                                    "pixel (%" PRIu64 ", %" PRIu64 ") channel %c is %g after scaling, "
                                    "beyond %s (largest %g)",
                                    p % w, p / w, "RGB"[ch], v, half ? "half" : "float", (double)lim);
            c->pix[3 * p + (uint64_t)ch] = (float)v;
        }
        double l = pm_luminance(acc + 3 * p);
        lmin = l < lmin ? l : lmin, lmax = l > lmax ? l : lmax, lsum += l;
    }
    c->info.luminance_min = lmin;
    c->info.luminance_max = lmax;
    c->info.luminance_mean = n ? lsum / (double)n : 0.0;
    return PM_OK;
}

/* The EXR's string attributes: the provenance in the pmtk header's words, and a running
 * image's passes and schedule (passes: room for the count's text). names_out holds the names
 * made here, NULL-terminated. */
static pm_result_t exr_attrs(const pm_composite_t *c, pm_exr_attr_t **attrs_out, size_t *n_out, char ***names_out,
                             char *passes, size_t passes_size)
{
    const pm_header_t *h = &c->hdr;
    const char *components = c->info.components;
    size_t ninput = 0;
    for (size_t i = 0; i < h->nkeys; i++)
        ninput += !strcmp(h->keys[i].key, "INPUT");
    size_t cap = 7 + h->ncommands + ninput, n = 0;
    pm_exr_attr_t *a = calloc(cap, sizeof *a);
    char **names = calloc(cap + 1, sizeof *names);
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
    if (c->info.passes) {
        snprintf(passes, passes_size, "%" PRIu64, c->info.passes);
        a[n++] = (pm_exr_attr_t){"passes", passes};
        if (c->alpha[0])
            a[n++] = (pm_exr_attr_t){"alpha", c->alpha};
        if (c->radius1[0])
            a[n++] = (pm_exr_attr_t){"radius1", c->radius1};
    }
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

pm_result_t pm_composite_set_aov(pm_composite_t *c, unsigned mask, const char *aov_path)
{
    uint64_t n = c->info.pixels;
    uint32_t w = c->info.width;
    if (mask & PM_EXR_AOV_VARIANCE) {
        if (!c->var)
            return pm_error_set(PM_ERR_USAGE, "--aov variance: the variance is the running image's: give "
                                              "--accumulate STATE (progressive passes)");
        float lim = c->half ? PM_EXR_HALF_MAX : 3.4028235e38f;
        if (!(c->varf = pm_alloc_aligned(3 * (n ? n : 1) * sizeof *c->varf)))
            return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " variance layer", w,
                                c->info.height);
        for (uint64_t i = 0; i < 3 * n; i++) {
            if (!(c->var[i] <= (double)lim))
                return pm_error_set(
                    PM_ERR_INPUT, "pixel (%" PRIu64 ", %" PRIu64 ") variance %c is %g, beyond %s (largest %g)",
                    i / 3 % w, i / 3 / w, "RGB"[i % 3], c -> var[i], c -> half ? "half" : "float", (double)lim);
            c->varf[i] = (float)c->var[i];
        }
    }
    if (mask & PM_EXR_AOV_SURFACE) {
        if (!aov_path)
            return pm_error_set(PM_ERR_USAGE, "--aov albedo, normal and depth come from an aov file: give "
                                              "--aov-buffer FILE (trace-gather-points --aov)");
        pm_table_t t;
        pm_result_t r = pm_table_read(aov_path, &pm_aov_schema, 0, &t);
        if (r != PM_OK)
            return r;
        const pm_header_t *h0 = pm_reader_header(c->in[c->first].rd);
        uint32_t aw, ah;
        r = pm_header_get_image_size(&t.hdr, aov_path, &aw, &ah);
        const char *s0 = pm_header_get(h0, "SCENE"), *s = pm_header_get(&t.hdr, "SCENE");
        if (r == PM_OK && (aw != w || ah != c->info.height))
            r = pm_error_set(PM_ERR_INPUT,
                             "resolution mismatch: AOV buffer '%s' is %" PRIu32 "x%" PRIu32 ", the image %" PRIu32
                             "x%" PRIu32,
                             aov_path, aw, ah, w, c->info.height);
        else if (r == PM_OK && (s0 || s) && (!s0 || !s || !pm_scene_key_same_scene(s0, s)))
            r = pm_error_set(PM_ERR_INPUT, "scene mismatch: AOV buffer '%s' is of scene '%s', '%s' of scene '%s'",
                             aov_path, s ? s : "(none)", c->in[c->first].path, s0 ? s0 : "(none)");
        if (r == PM_OK && !(c->surf = pm_alloc_aligned(7 * (n ? n : 1) * sizeof *c->surf)))
            r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " AOV image", w, c->info.height);
        /* Values in range: albedo in [0, 1], normals of length <= 1, depth a scene's size, and half
         * holds them; the reader has checked them finite. */
        for (uint64_t i = 0; r == PM_OK && i < n; i++) {
            const float *a = t.col[PM_AOV_ALBEDO], *nm = t.col[PM_AOV_NORMAL], *d = t.col[PM_AOV_DEPTH];
            float *o = c->surf + 7 * i;
            for (int k = 0; k < 3; k++)
                o[k] = a[3 * i + (uint64_t)k], o[3 + k] = nm[3 * i + (uint64_t)k];
            o[6] = d[i];
            for (int k = 0; k < 7; k++)
                if (c->half && !(fabsf(o[k]) <= PM_EXR_HALF_MAX))
                    r = pm_error_set(PM_ERR_INPUT, "AOV buffer '%s': pixel %" PRIu64 " holds %g, beyond half", aov_path,
                                     i, (double)o[k]);
        }
        pm_table_free(&t);
        if (r != PM_OK)
            return r;
    }
    c->aov = mask;
    return PM_OK;
}

pm_result_t pm_composite_write_exr(const pm_composite_t *c, const char *path, pm_exr_compression_t comp)
{
    pm_exr_attr_t *attrs = NULL;
    char **names = NULL;
    size_t nattrs = 0;
    char passes[24];
    pm_result_t r = exr_attrs(c, &attrs, &nattrs, &names, passes, sizeof passes);
    if (r != PM_OK)
        return r;
    pm_exr_channel_t ch[PM_EXR_MAX_CHANNELS] = {{"R", c->pix, 3, 0}, {"G", c->pix + 1, 3, 0}, {"B", c->pix + 2, 3, 0}};
    size_t nch = 3 + pm_exr_aov_channels(c->aov, c->surf, c->varf, ch + 3);
    r = pm_exr_write_channels(path, c->info.width, c->info.height, ch, nch, c->half ? PM_EXR_HALF : PM_EXR_FLOAT, comp,
                              attrs, nattrs);
    for (size_t i = 0; names[i]; i++)
        free(names[i]);
    free(names);
    free(attrs);
    return r;
}

pm_result_t pm_composite_write_png(const pm_composite_t *c, const char *path, double exposure, pm_tone_t tone,
                                   double *clipped_out)
{
    return pm_tone_write_png(path, c->acc, c->info.width, c->info.height, exposure, tone, clipped_out);
}

static pm_result_t write_radiance(const pm_composite_t *c, const char *path, int state)
{
    const pm_header_t *h = &c->hdr, *h0 = pm_reader_header(c->in[c->first].rd);
    uint64_t n = c->info.pixels;
    pm_table_t t;
    uint32_t channels = 1u << PM_RADIANCE_RGB | (c->var ? 1u << PM_RADIANCE_VARIANCE : 0);
    pm_result_t r = pm_table_alloc(&t, &pm_radiance_schema, channels, n);
    if (r != PM_OK)
        return r;
    memcpy(t.hdr.bounds, h0->bounds, sizeof t.hdr.bounds);
    r = pm_header_inherit(&t.hdr, h);
    for (size_t i = 0; i < h->nkeys && r == PM_OK; i++)
        if (!strcmp(h->keys[i].key, "INPUT"))
            r = pm_header_add(&t.hdr, "INPUT", "%s", h->keys[i].value);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "width", "%" PRIu32, c->info.width);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "height", "%" PRIu32, c->info.height);
    if (r == PM_OK)
        r = pm_header_set(&t.hdr, "component", "%s", c->info.components);
    if (r == PM_OK && c->var) {
        r = pm_header_set(&t.hdr, "passes", "%" PRIu64, c->info.passes);
        if (r == PM_OK && c->alpha[0])
            r = pm_header_set(&t.hdr, "alpha", "%s", c->alpha);
        if (r == PM_OK && c->radius1[0])
            r = pm_header_set(&t.hdr, "radius1", "%s", c->radius1);
        if (r == PM_OK && c->weight != (double)c->info.passes) /* passes of several sizes */
            r = pm_header_set(&t.hdr, "weight", "%.17g", c->weight);
        if (r == PM_OK && isfinite(c->info.relative_error))
            r = pm_header_set(&t.hdr, "relative_error", "%.6g", c->info.relative_error);
        if (r == PM_OK && state && c->pws) /* STATE.weight beside it holds the per-pixel weights */
            r = pm_header_set(&t.hdr, "pixel_weights", "1");
        if (r == PM_OK)
            memcpy(t.col[PM_RADIANCE_VARIANCE], c->var, 3 * n * sizeof *c->var);
    }
    if (r == PM_OK) {
        memcpy(t.col[PM_RADIANCE_RGB], c->acc, 3 * n * sizeof *c->acc);
        r = pm_table_write(&t, path);
    }
    pm_table_free(&t);
    return r;
}

pm_result_t pm_composite_write_radiance(const pm_composite_t *c, const char *path)
{
    return write_radiance(c, path, 0);
}

pm_result_t pm_composite_write_state(const pm_composite_t *c, const char *path)
{
    pm_result_t r = write_radiance(c, path, 1);
    if (r != PM_OK || !c->pws)
        return r;
    uint64_t n = c->info.pixels;
    float *v = malloc((n ? n : 1) * sizeof *v);
    char *wpath = NULL, passes[48], *extra[] = {passes, NULL};
    if (!v)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for the weights of a %" PRIu32 "x%" PRIu32 " image",
                            c->info.width, c->info.height);
    for (uint64_t i = 0; i < n; i++)
        v[i] = (float)c->pws[i];
    snprintf(passes, sizeof passes, "passes=%" PRIu64, c->info.passes);
    if ((r = pm_adaptive_weight_path(path, &wpath)) == PM_OK)
        r = pm_adaptive_write(wpath, PM_DENSITY_WEIGHT, c->info.width, c->info.height, v, &c->hdr, 0, NULL,
                              (const char *const *)extra);
    free(wpath);
    free(v);
    return r;
}

pm_result_t pm_composite_write_adaptive_map(const pm_composite_t *c, const char *path, int argc, char **argv)
{
    if (!c->var)
        return pm_error_set(PM_ERR_USAGE, "--adaptive-map is made from the running image: give --accumulate STATE");
    uint64_t n = c->info.pixels;
    float *m = malloc((n ? n : 1) * sizeof *m);
    if (!m)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " map", c->info.width,
                            c->info.height);
    pm_adaptive_make(c->acc, c->var, c->pws, c->weight, c->info.passes, c->info.width, c->info.height, m);
    pm_result_t r =
        pm_adaptive_write(path, PM_DENSITY_MULTIPLIER, c->info.width, c->info.height, m, &c->hdr, argc, argv, NULL);
    free(m);
    return r;
}

const pm_composite_info_t *pm_composite_info(const pm_composite_t *c) { return &c->info; }

void pm_composite_free(pm_composite_t *c)
{
    if (!c)
        return;
    pm_free_aligned(c->pix);
    pm_free_aligned(c->surf);
    pm_free_aligned(c->varf);
    pm_free_aligned(c->acc);
    pm_free_aligned(c->var);
    free(c->pws);
    pm_header_free(&c->hdr);
    for (int i = 0; c->in && i < c->nin; i++) {
        pm_reader_close(c->in[i].rd);
        free(c->in[i].path);
    }
    free(c->in);
    free(c);
}
