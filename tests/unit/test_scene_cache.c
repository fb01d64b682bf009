/* test_scene_cache.c: the scene cache (render/scene_cache.h): a scene read back is the scene
 * written, field by field and array by array; a file whose checksum is good but whose payload
 * does not hold together (an index past its array, a count too large, bytes cut off) is a miss
 * with its reason, never a crash; another scene path is a miss. tests/stage/scene-cache.sh
 * checks the stages' outputs and what makes a miss from outside. */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "render/scene.h"
#include "render/scene_cache.h"
#include "unit.h"

static const char *const CORNELL = "scenes/cornell-box/scene.json";

static unsigned char *slurp(const char *path, size_t *n_out)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *d = malloc((size_t)n);
    assert_non_null(d);
    assert_int_equal(fread(d, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *n_out = (size_t)n;
    return d;
}

/* d (n bytes, its old trailer dropped) written to path with a good trailer */
static void spit_rehashed(const char *path, const unsigned char *d, size_t n)
{
    uint64_t h = pm_hash_bytes(d, n);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(d, 1, n, f), n);
    assert_int_equal(fwrite(&h, 1, sizeof h, f), sizeof h);
    fclose(f);
}

/* where the payload starts: after the header's empty line */
static size_t payload_at(const unsigned char *d, size_t n)
{
    for (size_t i = 0; i + 1 < n; i++)
        if (d[i] == '\n' && d[i + 1] == '\n')
            return i + 2;
    fail_msg("no end of the header");
    return 0;
}

static void cache_path(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", unit_tmpdir(), name); }

/* scene loaded (its files noted for a cache: the cache named, not yet there) into *s and written
 * to the unit directory's NAME, whose path goes into path */
static void load_and_write(const char *scene, const char *name, pm_scene_t *s, char *path, size_t cap)
{
    cache_path(path, cap, name);
    if (pm_scene_load_cached(scene, path, 0, s, NULL) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s->uncacheable, 0);
    assert_int_equal(pm_scene_cache_write(s, path), PM_OK);
}

static void test_scene_cache_roundtrip(void **state)
{
    pm_scene_t a, b;
    pm_scene_cache_status_t st;
    char path[600];
    load_and_write(CORNELL, "cb.cache", &a, path, sizeof path);
    /* with no cache named, no file is hashed (nothing would keep the hashes) */
    pm_scene_t plain;
    if (pm_scene_load_cached(CORNELL, NULL, 1, &plain, NULL) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(plain.nsources, 0);
    assert_int_equal(plain.uncacheable, 1);
    pm_scene_free(&plain);
    assert_int_equal(pm_scene_cache_read(path, CORNELL, &b, &st), PM_OK);
    assert_int_equal(st.hit, 1);
    assert_string_equal(a.name, b.name);
    assert_true(a.hash == b.hash && a.parts.eye == b.parts.eye);
    assert_int_equal(a.nverts, b.nverts);
    assert_int_equal(a.ntris, b.ntris);
    assert_int_equal(a.nemissive, b.nemissive);
    assert_memory_equal(a.verts, b.verts, 3 * a.nverts * sizeof(float));
    assert_memory_equal(a.tris, b.tris, 3 * a.ntris * sizeof(uint32_t));
    assert_memory_equal(a.tri_material, b.tri_material, a.ntris * sizeof(uint32_t));
    assert_memory_equal(a.materials, b.materials, a.nmaterials * sizeof *a.materials);
    assert_memory_equal(a.emissive, b.emissive, a.nemissive * sizeof *a.emissive);
    assert_int_equal(a.nsources, b.nsources);
    assert_string_equal(a.sources[0].path, CORNELL);
    /* another path to the same file is a miss */
    pm_scene_t c;
    assert_int_equal(pm_scene_cache_read(path, "./scenes/cornell-box/scene.json", &c, &st), PM_OK);
    assert_int_equal(st.hit, 0);
    assert_string_equal(st.why, "of another scene path");
    pm_scene_free(&a);
    pm_scene_free(&b);
}

/* The cache at path changed by change (applied to the bytes before the trailer, n may shrink)
 * and given a good checksum again: a miss, "damaged (...)". */
static void expect_damaged(const char *path, const char *scene,
                           void (*change)(unsigned char *d, size_t *n, size_t payload, size_t nverts), size_t nverts)
{
    size_t n;
    unsigned char *d = slurp(path, &n);
    n -= 8;
    change(d, &n, payload_at(d, n), nverts);
    char bad[600];
    cache_path(bad, sizeof bad, "bad.cache");
    spit_rehashed(bad, d, n);
    free(d);
    pm_scene_t s;
    pm_scene_cache_status_t st;
    assert_int_equal(pm_scene_cache_read(bad, scene, &s, &st), PM_OK);
    assert_int_equal(st.hit, 0);
    assert_non_null(strstr(st.why, "damaged"));
}

/* the first triangle's first vertex index past the vertices: after the scene struct, the
 * vertices' length and bytes, the triangles' length */
static void index_past(unsigned char *d, size_t *n, size_t p, size_t nverts)
{
    uint32_t big = 0xfffffff0u;
    memcpy(d + p + sizeof(pm_scene_t) + 8 + 3 * nverts * sizeof(float) + 8, &big, sizeof big);
}

static void count_huge(unsigned char *d, size_t *n, size_t p, size_t nverts)
{
    size_t huge = (size_t)1 << 62;
    memcpy(d + p + offsetof(pm_scene_t, nverts), &huge, sizeof huge);
}

static void cut_short(unsigned char *d, size_t *n, size_t p, size_t nverts) { *n -= 40; }

static void length_huge(unsigned char *d, size_t *n, size_t p, size_t nverts)
{
    uint64_t huge = UINT64_MAX - 3;
    memcpy(d + p + sizeof(pm_scene_t), &huge, sizeof huge);
}

static void test_scene_cache_damaged(void **state)
{
    pm_scene_t a;
    char path[600];
    load_and_write(CORNELL, "cb2.cache", &a, path, sizeof path);
    expect_damaged(path, CORNELL, index_past, a.nverts);
    expect_damaged(path, CORNELL, count_huge, a.nverts);
    expect_damaged(path, CORNELL, cut_short, a.nverts);
    expect_damaged(path, CORNELL, length_huge, a.nverts);
    pm_scene_free(&a);
}

/* A scene with textures (whose struct in the file holds the writer's pointers), damaged before
 * its textures are read: the read frees only what it read (the fuzz target's first find). */
static void test_scene_cache_damaged_textured(void **state)
{
    pm_scene_t a;
    char path[600];
    load_and_write("scenes/atrium/textured.json", "tex.cache", &a, path, sizeof path);
    assert_true(a.ntextures > 0);
    expect_damaged(path, "scenes/atrium/textured.json", length_huge, a.nverts);
    pm_scene_free(&a);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_scene_cache_roundtrip),
    cmocka_unit_test(test_scene_cache_damaged),
    cmocka_unit_test(test_scene_cache_damaged_textured),
};
UNIT_GROUP(unit_scene_cache, "scene_cache", tests);
