/* pm-testgen: writes small, deterministic, valid files of every pmtk format for the
 * format tests, and, with --poison, files whose checksum is right but whose content
 * is not (a NaN, an Inf, a broken tree, a pixel outside the image), which only the
 * readers' value checks can catch.
 *
 *   pm-testgen FORMAT N OUT [--all] [--poison nan|inf|negative|tree|pixel|unit]
 *              [--shape equal|line|plane|huge] [--size WxH] [--range LO:HI]
 *
 * A radiance buffer is 4 x 3 pixels; a density map too, or --size's, its values uniform in
 * --range (LO = HI: a constant map), kind=multiplier.
 *   pm-testgen reseal IN OUT
 *
 * reseal copies IN to OUT with its last 8 bytes replaced by the XXH3-64 of all before them:
 * a header edited by a test (a value no writer would write) then reaches the reader's
 * value checks instead of stopping at the checksum.
 *
 * The photon map it writes is a median-split KD-tree of its photons, which the reader
 * checks in full (shape, order, planes). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <xxhash.h>

#include "formats/formats.h"
#include "math/rng.h"

static void unit_vector(pm_rng_t *r, float *v)
{
    float x = 2.0f * pm_rng_float(r) - 1.0f, y = 2.0f * pm_rng_float(r) - 1.0f, z = 2.0f * pm_rng_float(r) - 1.0f;
    float len = sqrtf(x * x + y * y + z * z);
    if (len < 1e-3f)
        x = 1.0f, y = z = 0.0f, len = 1.0f;
    v[0] = x / len, v[1] = y / len, v[2] = z / len;
}

/* A plain median-split KD-tree over the records' positions, in the format's layout
 * (depth-first; left subtree [i+1, child)), built by sorting: a test fixture, not the
 * fast builder of build-photonmap. The records are permuted into tree order. */
static const float *sort_pos;
static unsigned sort_axis;

static int by_axis(const void *a, const void *b)
{
    float x = sort_pos[3 * (size_t) * (const uint32_t *)a + sort_axis];
    float y = sort_pos[3 * (size_t) * (const uint32_t *)b + sort_axis];
    return (x > y) - (x < y);
}

/* Places the photons idx[0..n) into tree slots [at, at+n); order[slot] = source record. */
static void kd_build(uint32_t *idx, uint32_t n, uint32_t at, unsigned depth, const float *pos, uint32_t *order,
                     pm_kdnode_t *node)
{
    if (n == 0)
        return;
    unsigned axis = depth % 3;
    sort_pos = pos;
    sort_axis = axis;
    qsort(idx, n, sizeof *idx, by_axis);
    uint32_t m = n / 2, nl = m, nr = n - m - 1;
    order[at] = idx[m];
    if (n == 1)
        node[at] = pm_kdnode_make(pos[3 * (size_t)idx[m]], PM_KD_LEAF, PM_KD_NONE);
    else
        node[at] = pm_kdnode_make(pos[3 * (size_t)idx[m] + axis], axis, nr ? at + 1 + nl : PM_KD_NONE);
    kd_build(idx, nl, at + 1, depth + 1, pos, order, node);
    kd_build(idx + m + 1, nr, at + 1 + nl, depth + 1, pos, order, node);
}

/* Reorders every column of t so that record i becomes record order[i]'s content. */
static void permute(pm_table_t *t, const uint32_t *order)
{
    const pm_schema_t *s = t->hdr.schema;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!t->col[ci] || ci == PM_MAP_NODE)
            continue;
        size_t cs = pm_type_size(s->channels[ci].type) * s->channels[ci].components;
        unsigned char *copy = malloc(t->count * cs + 1);
        memcpy(copy, t->col[ci], t->count * cs);
        for (uint64_t i = 0; i < t->count; i++)
            memcpy((unsigned char *)t->col[ci] + i * cs, copy + order[i] * cs, cs);
        free(copy);
    }
}

static void fill_f32(pm_rng_t *r, float *p, uint64_t n, float lo, float hi)
{
    for (uint64_t i = 0; i < n; i++)
        p[i] = lo + (hi - lo) * pm_rng_float(r);
}

static unsigned dens_w = 4, dens_h = 3;
static float dens_lo = 0.25f, dens_hi = 4.0f;

static int make(const char *format, uint64_t n, int all, pm_table_t *t)
{
    pm_rng_t r;
    pm_rng_init(&r, 7, 0);
    const pm_schema_t *s = pm_schema_find(format);
    if (!s)
        return fprintf(stderr, "pm-testgen: unknown format '%s'\n", format), 1;
    uint32_t mask = all ? (1u << s->nchannels) - 1 : pm_schema_required(s);
    if (s == &pm_radiance_schema)
        n = 4 * 3; /* a 4x3 image */
    if (s == &pm_density_schema)
        n = (uint64_t)dens_w * dens_h;
    if (pm_table_alloc(t, s, mask, n) != PM_OK)
        return fprintf(stderr, "pm-testgen: %s\n", pm_error_message()), 1;
    float b[6] = {-1, -2, -3, 4, 5, 6};
    memcpy(t->hdr.bounds, b, sizeof b);
    char *argv[] = {"pm-testgen", (char *)format, all ? "--all" : "--required"};
    pm_header_add_command(&t->hdr, 3, argv);
    pm_header_set(&t->hdr, "SCENE", "test xxh3:0123456789abcdef");
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        void *col = t->col[ci];
        const pm_channel_t *c = &s->channels[ci];
        if (!col)
            continue;
        if (c->flags & PM_CH_UNIT) {
            for (uint64_t i = 0; i < n; i++)
                unit_vector(&r, (float *)col + 3 * i);
        } else if (c->type == PM_TYPE_F32) {
            fill_f32(&r, col, n * c->components, (c->flags & PM_CH_FINITE) ? -1.0f : 0.01f, 1.0f);
        } else if (c->type == PM_TYPE_F64) {
            for (uint64_t i = 0; i < n * c->components; i++)
                ((double *)col)[i] = pm_rng_double(&r);
        }
    }
    if (s == &pm_photons_schema) {
        for (uint64_t i = 0; i < n; i++)
            ((uint32_t *)t->col[PM_PHOTON_DEPTH])[i] = (uint32_t)(i % 4);
        pm_header_set(&t->hdr, "emitted", "%llu", (unsigned long long)(2 * n));
    } else if (s == &pm_photonmap_schema && n) {
        uint32_t *idx = malloc(n * sizeof *idx), *order = malloc(n * sizeof *order);
        for (uint32_t i = 0; i < n; i++)
            idx[i] = i;
        kd_build(idx, (uint32_t)n, 0, 0, t->col[PM_MAP_POSITION], order, t->col[PM_MAP_NODE]);
        permute(t, order);
        free(idx);
        free(order);
    } else if (s == &pm_queries_schema) {
        pm_header_set(&t->hdr, "width", "8");
        pm_header_set(&t->hdr, "height", "4");
        pm_material_t m[2] = {{.name = "white", .kd = {0.7f, 0.7f, 0.7f}},
                              {.name = "gloss", .kd = {0.2f, 0.3f, 0.4f}, .ks = {0.5f, 0.5f, 0.5f}, .ns = 20}};
        pm_queries_set_materials(&t->hdr, m, all ? 2 : 1);
        for (uint64_t i = 0; i < n; i++) {
            ((uint32_t *)t->col[PM_QUERY_PIXEL])[i] = (uint32_t)(i % 32);
            if (all)
                ((uint16_t *)t->col[PM_QUERY_MATERIAL])[i] = (uint16_t)(i % 2);
        }
    } else if (s == &pm_density_schema) {
        pm_header_set(&t->hdr, "width", "%u", dens_w);
        pm_header_set(&t->hdr, "height", "%u", dens_h);
        pm_header_set(&t->hdr, "kind", "multiplier");
        fill_f32(&r, t->col[PM_DENSITY_VALUE], n, dens_lo, dens_hi);
    } else if (s == &pm_radiance_schema) {
        pm_header_set(&t->hdr, "width", "4");
        pm_header_set(&t->hdr, "height", "3");
        pm_header_set(&t->hdr, "component", "indirect");
    }
    return 0;
}

/* Degenerate query positions for hilbert-sort's tests. */
static int shape_queries(pm_table_t *t, const char *shape)
{
    float *p = t->col[PM_QUERY_POSITION];
    for (uint64_t i = 0; i < t->count; i++) {
        float u = p[3 * i], *q = p + 3 * i;
        if (!strcmp(shape, "equal"))
            q[0] = 0.25f, q[1] = -0.5f, q[2] = 0.75f;
        else if (!strcmp(shape, "line"))
            q[1] = q[2] = q[0] = u;
        else if (!strcmp(shape, "plane"))
            q[1] = 0.5f;
        else if (!strcmp(shape, "huge"))
            q[0] = u * 1e30f, q[1] = u < 0 ? -3e38f : 3e38f;
        else
            return 1;
    }
    return 0;
}

/* Patches `len` bytes at record 0, byte `off` of the payload, and re-seals the checksum. */
static int poison(const char *path, size_t off, const void *bytes, size_t len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 1;
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    rewind(f);
    unsigned char *d = malloc((size_t)size);
    if (!d || fread(d, 1, (size_t)size, f) != (size_t)size)
        return fclose(f), free(d), 1;
    fclose(f);
    unsigned char *end = (unsigned char *)strstr((char *)d, "\n\n");
    size_t payload = (size_t)(end - d) + 2 + 4;
    memcpy(d + payload + off, bytes, len);
    uint64_t h = XXH3_64bits(d, (size_t)size - 8);
    memcpy(d + size - 8, &h, 8);
    f = fopen(path, "wb");
    int bad = !f || fwrite(d, 1, (size_t)size, f) != (size_t)size;
    if (f)
        bad |= fclose(f) != 0;
    free(d);
    return bad;
}

static int reseal(const char *in, const char *out)
{
    FILE *f = fopen(in, "rb");
    unsigned char *b = NULL;
    long n = -1;
    if (f && fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 8 && fseek(f, 0, SEEK_SET) == 0 &&
        (b = malloc((size_t)n)) && fread(b, 1, (size_t)n, f) == (size_t)n) {
        uint64_t h = XXH3_64bits(b, (size_t)n - 8);
        for (int i = 0; i < 8; i++)
            b[n - 8 + i] = (unsigned char)(h >> (8 * i));
        FILE *o = fopen(out, "wb");
        int ok = o && fwrite(b, 1, (size_t)n, o) == (size_t)n;
        if (o && fclose(o) != 0)
            ok = 0;
        fclose(f);
        free(b);
        if (ok)
            return 0;
        fprintf(stderr, "pm-testgen: cannot write '%s'\n", out);
        return 1;
    }
    if (f)
        fclose(f);
    free(b);
    fprintf(stderr, "pm-testgen: cannot read '%s' (at least 8 bytes)\n", in);
    return 1;
}

int main(int argc, char **argv)
{
    if (argc == 4 && !strcmp(argv[1], "reseal"))
        return reseal(argv[2], argv[3]);
    if (argc < 4) {
        fprintf(stderr, "usage: pm-testgen FORMAT N OUT [--all] [--set KEY=VALUE]... [--shape equal|line|plane|huge] "
                        "[--poison nan|inf|negative|unit|tree|order|pixel|nudge]\n");
        return 2;
    }
    int all = 0;
    const char *what = NULL, *sets[8], *shape = NULL;
    int nset = 0;
    for (int i = 4; i < argc; i++) {
        if (!strcmp(argv[i], "--all"))
            all = 1;
        else if (!strcmp(argv[i], "--poison") && i + 1 < argc)
            what = argv[++i];
        else if (!strcmp(argv[i], "--shape") && i + 1 < argc)
            shape = argv[++i];
        else if (!strcmp(argv[i], "--set") && i + 1 < argc && strchr(argv[i + 1], '=') && nset < 8)
            sets[nset++] = argv[++i];
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%ux%u", &dens_w, &dens_h) == 2)
            i++;
        else if (!strcmp(argv[i], "--range") && i + 1 < argc && sscanf(argv[i + 1], "%f:%f", &dens_lo, &dens_hi) == 2)
            i++;
        else
            return fprintf(stderr, "pm-testgen: bad argument '%s'\n", argv[i]), 2;
    }
    pm_table_t t;
    if (make(argv[1], strtoull(argv[2], NULL, 10), all, &t))
        return 1;
    if (shape && (t.hdr.schema != &pm_queries_schema || shape_queries(&t, shape))) {
        fprintf(stderr, "pm-testgen: cannot shape %s as '%s'\n", t.hdr.schema->name, shape);
        pm_table_free(&t);
        return 2;
    }
    for (int k = 0; k < nset; k++) { /* --set KEY=VALUE: header keys, for tests of header comparisons */
        const char *set = sets[k];
        char key[64];
        snprintf(key, sizeof key, "%.*s", (int)(strchr(set, '=') - set), set);
        pm_header_set(&t.hdr, key, "%s", strchr(set, '=') + 1);
    }
    if (pm_table_write(&t, argv[3]) != PM_OK) {
        fprintf(stderr, "pm-testgen: %s\n", pm_error_message());
        pm_table_free(&t);
        return 1;
    }
    const pm_schema_t *s = t.hdr.schema;
    pm_table_free(&t);
    if (!what)
        return 0;
    float nan = NAN, inf = INFINITY, neg = -1.0f, two = 2.0f;
    uint32_t big = 1000000;
    float big_coord = 1000.0f; /* far right of any plane: outside the left subtree */
    /* Offsets within record 0: position (or the first channel) starts at 0 except in a
     * photon map, where the 8-byte node comes first. */
    size_t first_float = s == &pm_photonmap_schema ? 8 : 0;
    int bad;
    double dnan = NAN, dinf = INFINITY;
    double nudged = 0.0;
    if (!strcmp(what, "nudge") && s == &pm_radiance_schema) { /* a valid but different value */
        pm_table_t u;
        if (pm_table_read(argv[3], s, 0, &u) != PM_OK)
            return fprintf(stderr, "pm-testgen: %s\n", pm_error_message()), 1;
        nudged = ((double *)u.col[PM_RADIANCE_RGB])[4] + 1e-7;
        pm_table_free(&u);
        bad = poison(argv[3], 4 * 8, &nudged, 8);
    } else if (!strcmp(what, "nan") && s == &pm_radiance_schema)
        bad = poison(argv[3], 0, &dnan, 8);
    else if (!strcmp(what, "inf") && s == &pm_radiance_schema)
        bad = poison(argv[3], 8, &dinf, 8);
    else if (!strcmp(what, "nan"))
        bad = poison(argv[3], first_float, &nan, 4);
    else if (!strcmp(what, "inf"))
        bad = poison(argv[3], first_float + 4, &inf, 4);
    else if (!strcmp(what, "order") && s == &pm_photonmap_schema)
        bad = poison(argv[3], 60 + 8, &big_coord,
                     4); /* record 1 (root's left child, split on y): x beyond the root's plane */
    else if (!strcmp(what, "negative") && s == &pm_photons_schema)
        bad = poison(argv[3], 12, &neg, 4); /* power.r */
    else if (!strcmp(what, "negative") && s == &pm_density_schema)
        bad = poison(argv[3], 4, &neg, 4); /* pixel 1 */
    else if (!strcmp(what, "unit") && s == &pm_photons_schema)
        bad = poison(argv[3], 24, &two, 4); /* normal.x */
    else if (!strcmp(what, "tree") && s == &pm_photonmap_schema)
        bad = poison(argv[3], 4, &big, 4); /* root's right child */
    else if (!strcmp(what, "pixel") && s == &pm_queries_schema)
        bad = poison(argv[3], 36, &big, 4);
    else
        return fprintf(stderr, "pm-testgen: cannot poison %s with '%s'\n", s->name, what), 2;
    return bad ? (fprintf(stderr, "pm-testgen: cannot patch '%s'\n", argv[3]), 1) : 0;
}
