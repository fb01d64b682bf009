/* test_pmfile.c: the container and the four formats: round trips of every format with
 * every and only the required channels, empty and chunk-crossing counts, ranges,
 * provenance, and the writer's all-or-nothing promise. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "formats/formats.h"
#include "math/rng.h"
#include "photonmap/kdtree.h"
#include "unit.h"

static void tmp_path(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", unit_tmpdir(), name); }

/* Fills a table with valid random content for its schema. */
static void fill(pm_table_t *t, uint32_t seed)
{
    pm_rng_t r;
    pm_rng_init(&r, seed, 0);
    const pm_schema_t *s = t->hdr.schema;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        const pm_channel_t *c = &s->channels[ci];
        if (!t->col[ci])
            continue;
        for (uint64_t i = 0; i < t->count; i++) {
            if (c->flags & PM_CH_UNIT) {
                float *v = (float *)t->col[ci] + 3 * i;
                v[0] = 0.6f, v[1] = 0.0f, v[2] = 0.8f;
            } else if (c->type == PM_TYPE_F32) {
                for (unsigned k = 0; k < c->components; k++)
                    ((float *)t->col[ci])[c->components * i + k] = 0.001f + pm_rng_float(&r);
            } else if (c->type == PM_TYPE_F64) {
                for (unsigned k = 0; k < c->components; k++)
                    ((double *)t->col[ci])[c->components * i + k] = pm_rng_double(&r);
            } else if (c->type == PM_TYPE_U16) {
                ((uint16_t *)t->col[ci])[i] = (uint16_t)(i % 2);
            } else if (s != &pm_photonmap_schema) {
                ((uint32_t *)t->col[ci])[c->components * i] = (uint32_t)(i % 6);
            }
        }
    }
    if (s == &pm_photonmap_schema && t->count) { /* the random positions as a real KD-tree */
        pm_kdnode_t *n = t->col[PM_MAP_NODE];
        float *p = t->col[PM_MAP_POSITION], *q = malloc(t->count * 12);
        uint32_t *perm = malloc(t->count * 4);
        assert_int_equal(pm_kd_build(p, t->count, n, perm, NULL), PM_OK);
        for (uint64_t i = 0; i < t->count; i++)
            memcpy(&q[3 * i], &p[3 * (size_t)perm[i]], 12);
        memcpy(p, q, t->count * 12);
        free(q);
        free(perm);
    }
    if (s == &pm_queries_schema || s == &pm_radiance_schema || s == &pm_aov_schema || s == &pm_density_schema) {
        pm_header_set(&t->hdr, "width", "3");
        pm_header_set(&t->hdr, "height", "2");
    }
    if (s == &pm_queries_schema) {
        pm_material_t m[2] = {{.name = "a", .kd = {0.5f, 0.5f, 0.5f}}, {.name = "b", .kd = {0.1f, 0.2f, 0.3f}}};
        pm_queries_set_materials(&t->hdr, m, t->col[PM_QUERY_MATERIAL] ? 2 : 1);
    }
    if (s == &pm_radiance_schema)
        pm_header_set(&t->hdr, "component", "direct");
    if (s == &pm_density_schema)
        pm_header_set(&t->hdr, "kind", "multiplier");
}

static void roundtrip(const pm_schema_t *s, uint32_t mask, uint64_t n)
{
    char path[256];
    tmp_path(path, sizeof path, "rt.pm");
    pm_table_t t, u;
    assert_int_equal(pm_table_alloc(&t, s, mask, n), PM_OK);
    fill(&t, 9);
    float b[6] = {-1e30f, -1e-30f, 0, 1e30f, 1e-30f, 1};
    memcpy(t.hdr.bounds, b, sizeof b);
    char *argv[] = {"/usr/bin/stage", "a b", "it's"};
    assert_int_equal(pm_header_add_command(&t.hdr, 3, argv), PM_OK);
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    pm_result_t r = pm_table_read(path, s, mask, &u);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(u.count, n);
    assert_int_equal(u.hdr.channels, mask);
    assert_memory_equal(u.hdr.bounds, b, sizeof b);
    assert_int_equal(u.hdr.ncommands, 1);
    assert_string_equal(u.hdr.commands[0], "stage 'a b' 'it'\\''s'");
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(mask & (1u << ci))) {
            assert_null(u.col[ci]);
            continue;
        }
        size_t bytes = n * pm_type_size(s->channels[ci].type) * s->channels[ci].components;
        if (bytes)
            assert_memory_equal(u.col[ci], t.col[ci], bytes);
    }
    pm_table_free(&t);
    pm_table_free(&u);
}

static void test_pmfile_roundtrip_every_format(void **state)
{
    static const uint64_t counts[] = {0, 1, 2, 4095, 4096, 4097, 10000};
    for (const pm_schema_t *const *s = pm_schema_all(); *s; s++) {
        uint32_t all = (1u << (*s)->nchannels) - 1, req = pm_schema_required(*s);
        for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++) {
            uint64_t n = *s == &pm_radiance_schema || *s == &pm_aov_schema || *s == &pm_density_schema
                             ? 6
                             : counts[i]; /* width * height */
            roundtrip(*s, all, n);
            roundtrip(*s, req, n);
        }
    }
}

static void test_pmfile_record_sizes(void **state)
{
    /* The byte counts docs/formats.md promises. */
    assert_int_equal(pm_schema_record_size(&pm_photons_schema, pm_schema_required(&pm_photons_schema)), 40);
    assert_int_equal(pm_schema_record_size(&pm_photons_schema, 0x1f), 52);
    assert_int_equal(pm_schema_record_size(&pm_photonmap_schema, pm_schema_required(&pm_photonmap_schema)), 44);
    assert_int_equal(pm_schema_record_size(&pm_queries_schema, pm_schema_required(&pm_queries_schema)), 40);
    assert_int_equal(pm_schema_record_size(&pm_queries_schema, 0x3f), 54);
    assert_int_equal(pm_schema_record_size(&pm_radiance_schema, 1), 24);
}

static void test_pmfile_range_and_need(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "range.pm");
    pm_table_t t, u;
    uint32_t req = pm_schema_required(&pm_queries_schema);
    assert_int_equal(pm_table_alloc(&t, &pm_queries_schema, req, 9000), PM_OK);
    fill(&t, 3);
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    assert_int_equal(pm_table_read_range(path, &pm_queries_schema, 0, 4000, 8500, &u), PM_OK);
    assert_int_equal(u.count, 4500);
    assert_memory_equal(u.col[PM_QUERY_POSITION], (float *)t.col[PM_QUERY_POSITION] + 3 * 4000, 4500 * 12);
    assert_int_equal(u.hdr.count, 4500);
    pm_table_free(&u);
    assert_int_equal(pm_table_read_range(path, &pm_queries_schema, 0, 8000, 99999, &u), PM_OK);
    assert_int_equal(u.count, 1000);
    pm_table_free(&u);
    /* a channel the caller needs but the file lacks */
    assert_int_equal(pm_table_read(path, &pm_queries_schema, 1u << PM_QUERY_DIRECTION, &u), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "lacks channel 'direction'"));
    /* the wrong format */
    assert_int_equal(pm_table_read(path, &pm_photons_schema, 0, &u), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "is a queries, expected a photons file"));
    pm_table_free(&t);
}

static void test_pmfile_writer_all_or_nothing(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "partial.pm");
    unlink(path);
    pm_header_t h;
    pm_header_init(&h, &pm_photons_schema);
    h.channels = pm_schema_required(&pm_photons_schema);
    h.count = 10;
    pm_writer_t *w;
    assert_int_equal(pm_writer_open(path, &h, &w), PM_OK);
    unsigned char rec[40] = {0};
    float up = 1.0f;
    memcpy(rec + 32, &up, 4); /* normal (0, 0, 1): the writer checks values too */
    assert_int_equal(pm_writer_write(w, rec, 1), PM_OK);
    assert_int_not_equal(access(path, F_OK), 0);            /* nothing at the final path while writing */
    assert_int_equal(pm_writer_commit(w), PM_ERR_INTERNAL); /* 1 of 10 records */
    assert_int_not_equal(access(path, F_OK), 0);
    assert_int_equal(pm_writer_open(path, &h, &w), PM_OK);
    pm_writer_abort(w);
    assert_int_not_equal(access(path, F_OK), 0);
    /* no temporary files left behind either */
    char cmd[300];
    snprintf(cmd, sizeof cmd, "ls -A %s | grep -q '^\\.'", unit_tmpdir());
    assert_int_not_equal(system(cmd), 0);
    assert_int_equal(pm_writer_open("/nonexistent-dir/x.pm", &h, &w),
                     PM_ERR_INPUT); /* a bad path, not a failing disk */
    assert_non_null(strstr(pm_error_message(), "/nonexistent-dir/x.pm"));
    pm_header_free(&h);
}

static void test_pmfile_provenance(void **state)
{
    pm_header_t a, b;
    pm_header_init(&a, &pm_photons_schema);
    pm_header_init(&b, &pm_photonmap_schema);
    char *c1[] = {"trace-photons", "s.json"}, *c2[] = {"build-photonmap"};
    pm_header_add_command(&a, 2, c1);
    pm_header_set(&a, "SCENE", "s xxh3:00");
    pm_header_set(&a, "emitted", "5");
    pm_header_inherit(&b, &a);
    pm_header_inherit(&b, &a); /* a second input with the same history adds nothing */
    pm_header_add_command(&b, 1, c2);
    pm_header_add_input(&b, "p.pm", 0xabcdefULL);
    assert_int_equal(b.ncommands, 2);
    assert_string_equal(b.commands[0], "trace-photons s.json");
    assert_string_equal(pm_header_get(&b, "SCENE"), "s xxh3:00");
    assert_null(pm_header_get(&b, "emitted")); /* format keys stay with their format */
    assert_string_equal(pm_header_get(&b, "INPUT"), "p.pm xxh3:0000000000abcdef");
    pm_header_copy_keys(&b, &a);
    assert_string_equal(pm_header_get(&b, "emitted"), "5");
    /* a newline in a value cannot break the header into two lines */
    pm_header_set(&b, "note", "two\nlines");
    assert_string_equal(pm_header_get(&b, "note"), "two lines");
    assert_int_equal(pm_header_set(&b, "bad key", "x"), PM_ERR_INTERNAL);
    pm_header_free(&a);
    pm_header_free(&b);
    /* SCENE by parts: a map's photons and queries' view of one scene join into both; another
     * scene, or the one-hash form, does not join and matches only itself. */
    const char *map = "s xxh3:01 photons:xxh3:02", *q = "s xxh3:01 view:xxh3:03";
    assert_true(pm_scene_key_same_scene(map, q));
    assert_false(pm_scene_key_same_scene(map, "s xxh3:09 view:xxh3:03"));
    assert_false(pm_scene_key_same_scene(map, "t xxh3:01 view:xxh3:03"));
    assert_true(pm_scene_key_same_scene("s xxh3:00", "s xxh3:00"));
    assert_false(pm_scene_key_same_scene("s xxh3:00", "s xxh3:01"));
    pm_header_init(&a, &pm_photonmap_schema);
    pm_header_init(&b, &pm_queries_schema);
    pm_header_set(&a, "SCENE", "%s", map);
    pm_header_set(&b, "SCENE", "%s", q);
    pm_header_t out;
    pm_header_init(&out, &pm_radiance_schema);
    assert_int_equal(pm_header_inherit(&out, &a), PM_OK);
    assert_int_equal(pm_header_inherit(&out, &b), PM_OK);
    assert_string_equal(pm_header_get(&out, "SCENE"), "s xxh3:01 photons:xxh3:02 view:xxh3:03");
    pm_header_set(&b, "SCENE", "t xxh3:01 view:xxh3:03");
    assert_int_equal(pm_header_inherit(&out, &b), PM_OK);
    assert_string_equal(pm_header_get(&out, "SCENE"), "s xxh3:01 photons:xxh3:02 view:xxh3:03");
    pm_header_free(&out);
    pm_header_free(&a);
    pm_header_free(&b);
}

static void test_pmfile_kdnode(void **state)
{
    float coords[] = {0.0f, -0.0f, 1.0f, -3.5e-30f, 7.25e30f, 0.1f};
    for (size_t i = 0; i < sizeof coords / sizeof coords[0]; i++)
        for (uint32_t axis = 0; axis < 4; axis++) {
            pm_kdnode_t n = pm_kdnode_make(coords[i], axis, 17);
            assert_int_equal(pm_kdnode_axis(n), axis);
            assert_int_equal(n.child, 17);
            /* the plane is within 3 ulp of the coordinate */
            assert_true(fabsf(n.split - coords[i]) <= 3.0f * fabsf(nextafterf(coords[i], INFINITY) - coords[i]) ||
                        fabsf(n.split) < 1e-38f);
        }
}

static void test_pmfile_writer_refuses_bad_values(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "nan.pm");
    unlink(path);
    pm_table_t t;
    assert_int_equal(pm_table_alloc(&t, &pm_photons_schema, pm_schema_required(&pm_photons_schema), 5000), PM_OK);
    fill(&t, 1);
    ((float *)t.col[PM_PHOTON_POWER])[3 * 4321 + 1] = -1.0f;
    assert_int_equal(pm_table_write(&t, path), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "refusing to write: bad value in photons file"));
    assert_non_null(strstr(pm_error_message(), "record 4321 channel 'power'[1] is -1"));
    assert_int_not_equal(access(path, F_OK), 0); /* and nothing was left behind */
    ((float *)t.col[PM_PHOTON_POWER])[3 * 4321 + 1] = 1.0f;
    ((float *)t.col[PM_PHOTON_POSITION])[0] = NAN;
    assert_int_equal(pm_table_write(&t, path), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "record 0 channel 'position'[0] is nan"));
    pm_table_free(&t);
}

/* The reference of the value checks (formats.md section 3): every f32 in double, as the
 * original check was written. The fast pass of check_values must agree with it on every
 * value, edge cases included. */
static int ref_value_ok(float f, unsigned fl)
{
    volatile double v = f; /* at run time, in the thread's FTZ/DAZ mode, as the check runs */
    if (!isfinite(v))
        return 0;
    if ((fl & PM_CH_NONNEG) && v < 0.0)
        return 0;
    if ((fl & PM_CH_POSITIVE) && !(v > 0.0))
        return 0;
    return 1;
}

static int ref_record_ok(const unsigned char *rec, uint32_t mask)
{
    const pm_schema_t *s = &pm_photonmap_schema;
    size_t off = 0;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(mask & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        if (c->type == PM_TYPE_F32) {
            double len2 = 0.0;
            for (unsigned k = 0; k < c->components; k++) {
                float f;
                memcpy(&f, rec + off + 4 * k, 4);
                if (!ref_value_ok(f, c->flags))
                    return 0;
                volatile double v = f;
                len2 += v * v;
            }
            if ((c->flags & PM_CH_UNIT) && fabs(len2 - 1.0) > 2e-3)
                return 0;
        }
        off += pm_type_size(c->type) * c->components;
    }
    return 1;
}

/* A value from the edges of the checks: zeros of both signs, subnormals, the largest
 * floats, infinities, NaNs of both signs, ordinary numbers. */
static const uint32_t edge_bits[] = {0x00000000, 0x80000000, 0x00000001, 0x80000001, 0x007fffff, 0x807fffff,
                                     0x00800000, 0x80800000, 0x7f7fffff, 0xff7fffff, 0x7f800000, 0xff800000,
                                     0x7fc00000, 0xffc00000, 0x7f800001, 0x3f800000, 0xbf800000, 0x2f000000};
#define NEDGE (sizeof edge_bits / sizeof edge_bits[0])

static float edge_value(pm_rng_t *r)
{
    const uint32_t *bits = edge_bits;
    uint32_t u = pm_rng_u32(r), b;
    if (u % 4 == 0) {
        b = bits[(u >> 2) % NEDGE];
    } else {
        float f = (pm_rng_float(r) - 0.25f) * 4.0f;
        memcpy(&b, &f, 4);
    }
    float f;
    memcpy(&f, &b, 4);
    return f;
}

/* A unit vector whose squared length is 1 + e, e near the tolerance 2e-3 (or far off). */
static void edge_unit(pm_rng_t *r, float v[3])
{
    double e = (pm_rng_double(r) * 2.0 - 1.0) * 2.2e-3;
    if (pm_rng_u32(r) % 8 == 0)
        e = (pm_rng_u32(r) % 2 ? 2e-3 : -2e-3) * (1.0 + (pm_rng_double(r) - 0.5) * 1e-4);
    double x = pm_rng_double(r) - 0.5, y = pm_rng_double(r) - 0.5, z = pm_rng_double(r) - 0.5;
    double k = sqrt((1.0 + e) / (x * x + y * y + z * z));
    v[0] = (float)(x * k), v[1] = (float)(y * k), v[2] = (float)(z * k);
}

static void test_pmfile_value_checks_match_reference(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "edges.pm");
    pm_header_t h;
    pm_header_init(&h, &pm_photonmap_schema);
    h.channels = 0x3f; /* every channel, 60-byte records: floats at every offset mod 8 */
    const size_t rs = 60, n = 3000;
    h.count = 100 * n; /* more than written: the writer is aborted at the end */
    pm_writer_t *w;
    assert_int_equal(pm_writer_open(path, &h, &w), PM_OK);
    unsigned char *rec = calloc(n, rs);
    pm_rng_t r;
    pm_rng_init(&r, 77, 0);
    size_t accepted = 0, refused = 0;
    /* One record per write: each goes through the fast pass alone (a block mostly padding). */
    for (size_t i = 0; i < n; i++) {
        unsigned char *p = rec + i * rs;
        float v[3];
        for (unsigned c = 0; c < 4; c++) { /* position, power: edge values; normal, direction: near unit */
            if (c < 2)
                for (unsigned k = 0; k < 3; k++)
                    v[k] = pm_rng_u32(&r) % 3 ? 0.5f : edge_value(&r);
            else
                edge_unit(&r, v);
            if (c >= 2 && pm_rng_u32(&r) % 16 == 0)
                v[pm_rng_u32(&r) % 3] = edge_value(&r);
            memcpy(p + 8 + 12 * c, v, 12);
        }
        float width = pm_rng_u32(&r) % 2 ? 0.25f : edge_value(&r);
        memcpy(p + 56, &width, 4);
        int want = ref_record_ok(p, h.channels);
        pm_result_t got = pm_writer_write(w, p, 1);
        assert_int_equal(got == PM_OK, want);
        if (!want)
            assert_non_null(strstr(pm_error_message(), "refusing to write: bad value in photon map"));
        accepted += (size_t)want, refused += (size_t)!want;
    }
    assert_true(accepted > n / 10 && refused > n / 10);
    /* Many records per write, one bad value each time at a random place: found, and named
     * as the check of the whole write names it. */
    for (size_t i = 0; i < n; i++) {
        unsigned char *p = rec + i * rs;
        float pos[3] = {1, 2, 3}, pw[3] = {0.0f, -0.0f, 1e-30f}, nrm[3] = {0, 0, 1}, dir[3] = {0.6f, 0.8f, 0},
              wd = 1e-3f;
        memcpy(p + 8, pos, 12), memcpy(p + 20, pw, 12), memcpy(p + 32, nrm, 12), memcpy(p + 44, dir, 12);
        memcpy(p + 56, &wd, 4);
    }
    assert_int_equal(pm_writer_write(w, rec, n), PM_OK); /* -0 and tiny powers pass; records now number accepted + n */
    for (int t = 0; t < 40; t++) {
        size_t i = pm_rng_u32(&r) % n, at = 8 + 4 * (pm_rng_u32(&r) % 13);
        unsigned char save[4];
        memcpy(save, rec + i * rs + at, 4);
        float bad = at < 20 ? NAN : at < 32 ? -1.0f : at < 56 ? 2.0f : 0.0f;
        memcpy(rec + i * rs + at, &bad, 4);
        assert_int_equal(pm_writer_write(w, rec, n), PM_ERR_INTERNAL);
        char want[64];
        snprintf(want, sizeof want, "record %zu channel '", accepted + n + i);
        assert_non_null(strstr(pm_error_message(), want));
        memcpy(rec + i * rs + at, save, 4);
    }
    /* Two bad values in one write: the first channel wins, as it did when a write was
     * checked channel by channel, though the chunks are checked one at a time. */
    float nan = NAN, two = 2.0f;
    memcpy(rec + 100 * rs + 32, &two, 4); /* normal of record 100 */
    memcpy(rec + 2900 * rs + 8, &nan, 4); /* position of record 2900, another chunk */
    assert_int_equal(pm_writer_write(w, rec, n), PM_ERR_INTERNAL);
    char want[96];
    snprintf(want, sizeof want, "record %zu channel 'position'[0] is nan (not finite)", accepted + n + 2900);
    assert_non_null(strstr(pm_error_message(), want));
    pm_writer_abort(w);
    free(rec);
    pm_header_free(&h);
}

/* The same agreement through whole tables, whose checks read the columns: writing a table
 * with one edge value somewhere, and reading a file with a value patched on disk, whole and
 * as a range (whose chunks are checked as records). */
static void test_pmfile_table_value_checks(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "tedges.pm");
    pm_table_t t;
    const uint64_t n = 5000; /* two chunks, the second partly full */
    assert_int_equal(pm_table_alloc(&t, &pm_photons_schema, 0x1f, n), PM_OK);
    fill(&t, 5);
    pm_rng_t r;
    pm_rng_init(&r, 78, 0);
    for (unsigned trial = 0; trial < 4 * NEDGE + 100; trial++) { /* every edge in every channel, then random */
        uint64_t i = pm_rng_u32(&r) % n;
        unsigned ci = trial < 4 * NEDGE ? trial % 4 : pm_rng_u32(&r) % 4, k = pm_rng_u32(&r) % 3;
        float *v = (float *)t.col[ci] + 3 * i, save[3];
        memcpy(save, v, 12);
        if (trial < 4 * NEDGE)
            memcpy(&v[k], &edge_bits[trial / 4], 4);
        else if (ci >= 2 && pm_rng_u32(&r) % 2)
            edge_unit(&r, v);
        else
            v[k] = edge_value(&r);
        double len2 = (double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2];
        int want = ref_value_ok(v[0], pm_photons_schema.channels[ci].flags) &&
                   ref_value_ok(v[1], pm_photons_schema.channels[ci].flags) &&
                   ref_value_ok(v[2], pm_photons_schema.channels[ci].flags) &&
                   !((pm_photons_schema.channels[ci].flags & PM_CH_UNIT) && fabs(len2 - 1.0) > 2e-3);
        pm_result_t got = pm_table_write(&t, path);
        assert_int_equal(got == PM_OK, want);
        if (!want) {
            char msg[96];
            snprintf(msg, sizeof msg, "record %llu channel '%s'", (unsigned long long)i,
                     pm_photons_schema.channels[ci].name);
            assert_non_null(strstr(pm_error_message(), msg));
        }
        memcpy(v, save, 12);
    }
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    pm_table_free(&t);
    /* a NaN patched into record 4500's position: found whole and through a range */
    FILE *f = fopen(path, "r+b");
    assert_non_null(f);
    fseek(f, -8 - (long)(n - 4500) * 52, SEEK_END);
    float nan = NAN;
    fwrite(&nan, 4, 1, f);
    fclose(f);
    assert_int_equal(pm_table_read(path, &pm_photons_schema, 0, &t), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "record 4500 channel 'position'[0] is nan (not finite)"));
    assert_int_equal(pm_table_read_range(path, &pm_photons_schema, 0, 4400, 4450, &t), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "record 4500 channel 'position'[0] is nan (not finite)"));
}

static void test_pmfile_writer_refuses_bad_headers_and_tables(void **state)
{
    char path[256];
    tmp_path(path, sizeof path, "badhdr.pm");
    unlink(path);
    pm_table_t t;
    assert_int_equal(pm_table_alloc(&t, &pm_queries_schema, pm_schema_required(&pm_queries_schema), 3), PM_OK);
    fill(&t, 2);
    ((uint32_t *)t.col[PM_QUERY_PIXEL])[2] = 6; /* the image is 3x2: pixel 6 is outside */
    assert_int_equal(pm_table_write(&t, path), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "refusing to write: bad value in queries"));
    ((uint32_t *)t.col[PM_QUERY_PIXEL])[2] = 5;
    pm_header_set(&t.hdr, "width", "0");
    assert_int_equal(pm_table_write(&t, path), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "refusing to write"));
    assert_non_null(strstr(pm_error_message(), "image size 0x2"));
    assert_int_not_equal(access(path, F_OK), 0);
    pm_table_free(&t);
    /* a header line at the reader's limit is written; one byte more is refused */
    pm_header_t h;
    pm_header_init(&h, &pm_photons_schema);
    h.channels = pm_schema_required(&pm_photons_schema);
    char *big = malloc(PM_HEADER_LINE_MAX + 2);
    memset(big, 'x', PM_HEADER_LINE_MAX + 1);
    big[PM_HEADER_LINE_MAX - 5] = '\0'; /* "note=" + value = PM_HEADER_LINE_MAX bytes */
    pm_header_set(&h, "note", "%s", big);
    pm_writer_t *w;
    assert_int_equal(pm_writer_open(path, &h, &w), PM_OK);
    assert_int_equal(pm_writer_commit(w), PM_OK);
    /* keys the container owns cannot be set by a stage */
    assert_int_equal(pm_header_set(&h, "COUNT", "5"), PM_ERR_INTERNAL);
    assert_int_equal(pm_header_add(&h, "BOUNDS", "0 0 0 1 1 1"), PM_ERR_INTERNAL);
    /* a header the reader would refuse (NaN bounds) is not written */
    h.bounds[2] = NAN;
    assert_int_equal(pm_writer_open(path, &h, &w), PM_ERR_INTERNAL);
    assert_non_null(strstr(pm_error_message(), "refusing to write"));
    h.bounds[2] = 0.0f;
    pm_table_t u;
    assert_int_equal(pm_table_read(path, &pm_photons_schema, 0, &u), PM_OK);
    pm_table_free(&u);
    big[PM_HEADER_LINE_MAX - 5] = 'x';
    big[PM_HEADER_LINE_MAX - 4] = '\0';
    pm_header_set(&h, "note", "%s", big);
    assert_int_equal(pm_writer_open(path, &h, &w), PM_ERR_INTERNAL);
    free(big);
    pm_header_free(&h);
}

/* Reads a whole small file into a NUL-terminated string (the header text is what matters). */
static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    char *buf = calloc(1, 1 << 16);
    assert_non_null(buf);
    size_t n = fread(buf, 1, (1 << 16) - 1, f);
    fclose(f);
    buf[n] = '\0';
    return buf;
}

/* Version 1 headers carry CHANNEL_MASK beside CHANNELS; version 2 drops the mask. A
 * version-1 file reads into the same table as its version-2 twin, and nothing of its mask
 * reaches a file written from it, whether the table is written back or a new header takes
 * its provenance and keys. */
static void test_pmfile_version1_read_and_rewritten(void **state)
{
    pm_table_t v1, v2;
    assert_int_equal(pm_table_read("tests/golden/v1/photons-all.pm", &pm_photons_schema, 0, &v1), PM_OK);
    assert_int_equal(pm_table_read("tests/golden/photons-all.pm", &pm_photons_schema, 0, &v2), PM_OK);
    assert_int_equal(v1.hdr.major, 1);
    assert_int_equal(v2.hdr.major, 2);
    assert_int_equal(pm_photons_schema.major, 2);
    assert_int_equal(v1.hdr.channels, 0x1f);
    assert_int_equal(v2.hdr.channels, v1.hdr.channels);
    assert_int_equal(v1.count, v2.count);
    for (unsigned ci = 0; ci < pm_photons_schema.nchannels; ci++) {
        const pm_channel_t *c = &pm_photons_schema.channels[ci];
        assert_memory_equal(v1.col[ci], v2.col[ci], v1.count * pm_type_size(c->type) * c->components);
    }
    assert_int_not_equal(v1.checksum, v2.checksum); /* the headers differ */

    /* written back, the version-1 table is a version-2 file */
    char path[256];
    tmp_path(path, sizeof path, "from-v1.pm");
    assert_int_equal(pm_table_write(&v1, path), PM_OK);
    char *text = slurp(path);
    assert_non_null(strstr(text, "\nVERSION=2.0\n"));
    assert_null(strstr(text, "CHANNEL_MASK"));
    assert_non_null(strstr(text, "\nCHANNELS=position power normal direction depth\n"));
    free(text);
    pm_table_t back;
    assert_int_equal(pm_table_read(path, &pm_photons_schema, 0, &back), PM_OK);
    assert_int_equal(back.hdr.major, 2);
    pm_table_free(&back);

    /* a derived header takes provenance and keys from it, never the mask */
    pm_header_t h;
    pm_header_init(&h, &pm_photons_schema);
    h.channels = pm_schema_required(&pm_photons_schema);
    assert_int_equal(pm_header_inherit(&h, &v1.hdr), PM_OK);
    assert_int_equal(pm_header_copy_keys(&h, &v1.hdr), PM_OK);
    assert_null(pm_header_get(&h, "CHANNEL_MASK"));
    assert_int_equal(pm_header_set(&h, "CHANNEL_MASK", "0x0000001f"), PM_ERR_INTERNAL); /* the container's key */
    size_t len;
    assert_int_equal(pm_header_format(&h, &text, &len), PM_OK);
    assert_non_null(strstr(text, "\nVERSION=2.0\n"));
    assert_null(strstr(text, "CHANNEL_MASK"));
    assert_non_null(strstr(text, "\nemitted=14\n"));
    free(text);
    pm_header_free(&h);
    pm_table_free(&v1);
    pm_table_free(&v2);
}

/* Opens an in-memory radiance file (1x1, its record not read) whose header has the given
 * lines besides the fixed ones: the header parser on the versions it takes and the CHANNELS
 * it refuses. */
static pm_result_t open_text(const char *header)
{
    char buf[1024];
    int n = snprintf(buf, sizeof buf,
                     "#?PMTK\nFORMAT=radiance\n%sBYTE_ORDER=little-endian\nCOUNT=1\n"
                     "BOUNDS=0 0 0 1 1 1\nwidth=1\nheight=1\ncomponent=direct\n\n\x04\x03\x02\x01",
                     header);
    FILE *f = fmemopen(buf, (size_t)n, "rb");
    assert_non_null(f);
    pm_reader_t *r;
    pm_result_t res = pm_reader_open_stream(f, "mem", NULL, 0, &r);
    if (res == PM_OK)
        pm_reader_close(r);
    fclose(f);
    return res;
}

static void test_pmfile_version_and_channels_keys(void **state)
{
    const char *rs = "RECORD_SIZE=24\n";
    char h[256];
#define HDR(...) (snprintf(h, sizeof h, __VA_ARGS__), h)
    assert_int_equal(open_text(HDR("VERSION=2.0\n%sCHANNELS=rgb\n", rs)), PM_OK);
    assert_int_equal(open_text(HDR("VERSION=2.7\n%sCHANNELS=rgb\n", rs)), PM_OK); /* any minor */
    assert_int_equal(open_text(HDR("VERSION=1.0\n%sCHANNELS=rgb\nCHANNEL_MASK=0x00000001\n", rs)), PM_OK);
    assert_int_equal(open_text(HDR("VERSION=1.0\n%sCHANNELS=rgb\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "lacks CHANNEL_MASK"));
    assert_int_equal(open_text(HDR("VERSION=1.0\n%sCHANNELS=rgb variance\nCHANNEL_MASK=0x00000001\n", rs)),
                     PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "disagrees with CHANNEL_MASK"));
    assert_int_equal(open_text(HDR("VERSION=2.0\n%sCHANNELS=rgb\nCHANNEL_MASK=0x00000001\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "has CHANNEL_MASK, a version-1 key"));
    assert_int_equal(open_text(HDR("VERSION=3.0\n%sCHANNELS=rgb\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "newer than this reader"));
    assert_int_equal(open_text(HDR("VERSION=0.1\n%sCHANNELS=rgb\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "older than this reader"));
    assert_int_equal(open_text(HDR("VERSION=2.0\n%sCHANNELS=\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "lacks required channel 'rgb'"));
    assert_int_equal(open_text(HDR("VERSION=2.0\n%sCHANNELS=rgb rgb\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "is not spelled 'rgb'"));
    assert_int_equal(open_text(HDR("VERSION=2.0\n%sCHANNELS=RGB\n", rs)), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "names 'RGB', not a channel"));
    assert_int_equal(open_text(HDR("VERSION=2.0\nRECORD_SIZE=48\nCHANNELS=rgb variance\n")), PM_OK);
    assert_int_equal(open_text(HDR("VERSION=2.0\nRECORD_SIZE=48\nCHANNELS=variance rgb\n")), PM_ERR_INPUT);
#undef HDR
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_pmfile_version1_read_and_rewritten),
    cmocka_unit_test(test_pmfile_version_and_channels_keys),
    cmocka_unit_test(test_pmfile_writer_refuses_bad_headers_and_tables),
    cmocka_unit_test(test_pmfile_writer_refuses_bad_values),
    cmocka_unit_test(test_pmfile_value_checks_match_reference),
    cmocka_unit_test(test_pmfile_table_value_checks),
    cmocka_unit_test(test_pmfile_roundtrip_every_format),
    cmocka_unit_test(test_pmfile_record_sizes),
    cmocka_unit_test(test_pmfile_range_and_need),
    cmocka_unit_test(test_pmfile_writer_all_or_nothing),
    cmocka_unit_test(test_pmfile_provenance),
    cmocka_unit_test(test_pmfile_kdnode),
};
UNIT_GROUP(unit_pmfile, "pmfile", tests);
