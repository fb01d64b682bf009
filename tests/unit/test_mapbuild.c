/* test_mapbuild.c: a photon map made from photons (common/photonmap/mapbuild.c) and records
 * written in a permutation's order (common/photonmap/reorder.c). The map holds the photons
 * asked for, each once, as a tree the format's reader accepts, with its header keys; kernel
 * widths on a regular grid come out near the radius that holds K photons at its density; the
 * reorder moves whole records of every queries layout, across chunk boundaries. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/formats.h"
#include "math/rng.h"
#include "photonmap/mapbuild.h"
#include "photonmap/reorder.h"
#include "unit.h"

enum { GRID = 64 };
#define SPACING 0.01 /* m between grid photons */

/* GRID x GRID photons on the plane z = 0, normals up; power x is the photon's index, depth
 * its index mod 3. */
static void grid_photons(pm_table_t *t)
{
    uint64_t n = GRID * GRID;
    assert_int_equal(pm_table_alloc(t, &pm_photons_schema, pm_schema_required(&pm_photons_schema), n), PM_OK);
    float *pos = t->col[PM_PHOTON_POSITION], *pow = t->col[PM_PHOTON_POWER], *nor = t->col[PM_PHOTON_NORMAL];
    uint32_t *depth = t->col[PM_PHOTON_DEPTH];
    for (uint64_t i = 0; i < n; i++) {
        pos[3 * i] = (float)((double)(i % GRID) * SPACING), pos[3 * i + 1] = (float)((double)(i / GRID) * SPACING);
        pos[3 * i + 2] = 0.0f;
        pow[3 * i] = (float)i, pow[3 * i + 1] = pow[3 * i + 2] = 1.0f;
        nor[3 * i] = nor[3 * i + 1] = 0.0f, nor[3 * i + 2] = 1.0f;
        depth[i] = (uint32_t)(i % 3);
    }
    float b[6] = {0, 0, 0, (GRID - 1) * SPACING, (GRID - 1) * SPACING, 0};
    memcpy(t->hdr.bounds, b, sizeof b);
    pm_header_set(&t->hdr, "emitted", "%u", GRID * GRID);
}

/* Every map photon is an input photon, at its place, each once, and the tree is valid. */
static void check_map(const pm_table_t *ph, const pm_table_t *map, int indirect)
{
    const float *ppos = ph->col[PM_PHOTON_POSITION], *mpos = map->col[PM_MAP_POSITION], *mpow = map->col[PM_MAP_POWER];
    char *seen = calloc(ph->count, 1);
    for (uint64_t i = 0; i < map->count; i++) {
        uint64_t s = (uint64_t)mpow[3 * i];
        assert_true(s < ph->count);
        assert_int_equal(seen[s], 0);
        seen[s] = 1;
        assert_memory_equal(&mpos[3 * i], &ppos[3 * s], 12);
        if (indirect)
            assert_true(s % 3 != 0);
    }
    free(seen);
    assert_int_equal(pm_photonmap_schema.validate_table(map, "test"), PM_OK);
}

static void test_mapbuild_global_and_indirect(void **state)
{
    pm_table_t ph, map;
    grid_photons(&ph);
    pm_map_build_params_t p = {.map = PM_MAP_GLOBAL, .split = PM_SPLIT_MEDIAN, .vvh_k = 50};
    pm_map_build_stats_t st;
    assert_int_equal(pm_map_build(&ph, "grid", &p, &map, &st), PM_OK);
    assert_int_equal(st.photons_in, GRID * GRID);
    assert_int_equal(st.photons, GRID * GRID);
    assert_int_equal(st.tree.depth, 13); /* ceil(log2(4097)) */
    assert_null(map.col[PM_MAP_WIDTH]);
    check_map(&ph, &map, 0);
    pm_table_free(&map);

    p.map = PM_MAP_INDIRECT;
    assert_int_equal(pm_map_build(&ph, "grid", &p, &map, &st), PM_OK);
    assert_int_equal(st.photons, GRID * GRID - (GRID * GRID + 2) / 3); /* depth 0 left out */
    check_map(&ph, &map, 1);
    char *argv[] = {"build-photonmap", "grid"};
    assert_int_equal(pm_map_build_header(&map, &ph, "grid", 2, argv, &p, &st), PM_OK);
    assert_string_equal(pm_header_get(&map.hdr, "map"), "indirect");
    assert_string_equal(pm_header_get(&map.hdr, "split"), "median");
    assert_string_equal(pm_header_get(&map.hdr, "emitted"), "4096");
    assert_non_null(pm_header_get(&map.hdr, "INPUT"));
    assert_null(pm_header_get(&map.hdr, "vvh_radius"));
    assert_null(pm_header_get(&map.hdr, "width_k"));
    pm_table_free(&map);
    pm_table_free(&ph);
}

static int by_value(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static void test_mapbuild_widths_and_vvh(void **state)
{
    pm_table_t ph, map;
    grid_photons(&ph);
    const uint32_t k = 16;
    pm_map_build_params_t p = {.map = PM_MAP_GLOBAL, .split = PM_SPLIT_VVH, .vvh_k = 16, .width_k = k};
    pm_map_build_stats_t st;
    assert_int_equal(pm_map_build(&ph, "grid", &p, &map, &st), PM_OK);
    check_map(&ph, &map, 0);
    assert_true(st.vvh_radius > 0.0);
    assert_non_null(map.col[PM_MAP_WIDTH]);
    /* At one photon per SPACING^2, K photons fill a disc of radius SPACING sqrt(K / pi); most
     * photons are inside the grid, where the count sees that density (the edge ones more). */
    double want = SPACING * sqrt(k / M_PI);
    float *w = malloc(map.count * sizeof *w);
    memcpy(w, map.col[PM_MAP_WIDTH], map.count * sizeof *w);
    qsort(w, map.count, sizeof *w, by_value);
    assert_true(w[0] > 0.0f);
    assert_true(fabs(w[map.count / 2] - want) < 0.2 * want);
    assert_true(st.mean_width >= w[0] && st.mean_width <= w[map.count - 1]);
    free(w);
    char *argv[] = {"build-photonmap"};
    assert_int_equal(pm_map_build_header(&map, &ph, "grid", 1, argv, &p, &st), PM_OK);
    assert_string_equal(pm_header_get(&map.hdr, "split"), "vvh");
    assert_non_null(pm_header_get(&map.hdr, "vvh_radius"));
    assert_string_equal(pm_header_get(&map.hdr, "width_k"), "16");
    pm_table_free(&map);

    /* --width-max caps every width */
    p.split = PM_SPLIT_MEDIAN, p.width_max = 0.5 * want;
    assert_int_equal(pm_map_build(&ph, "grid", &p, &map, &st), PM_OK);
    for (uint64_t i = 0; i < map.count; i++)
        assert_true(((float *)map.col[PM_MAP_WIDTH])[i] <= (float)(0.5 * want));
    pm_table_free(&map);
    pm_table_free(&ph);
}

static void test_reorder_gather(void **state)
{
    const size_t sizes[] = {24, 40, 42, 52, 54}; /* the four queries layouts, and another */
    const uint32_t n = 1000;
    pm_rng_t r;
    pm_rng_init(&r, 5, 0);
    uint32_t *perm = malloc(n * sizeof *perm);
    for (uint32_t i = 0; i < n; i++)
        perm[i] = i;
    for (uint32_t i = n - 1; i > 0; i--) { /* Fisher-Yates */
        uint32_t j = pm_rng_u32(&r) % (i + 1), t = perm[i];
        perm[i] = perm[j], perm[j] = t;
    }
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        size_t rs = sizes[s];
        unsigned char *src = malloc(n * rs), *dst = malloc(n * rs);
        for (size_t i = 0; i < n * rs; i++)
            src[i] = (unsigned char)pm_rng_u32(&r);
        pm_reorder_gather(dst, src, perm, n, rs);
        for (uint32_t i = 0; i < n; i++)
            assert_memory_equal(dst + i * rs, src + (size_t)perm[i] * rs, rs);
        free(src);
        free(dst);
    }
    free(perm);
}

static void test_reorder_write(void **state)
{
    /* three chunks, the last one short */
    const uint32_t w = 1000, h = 140;
    const uint64_t n = (uint64_t)w * h;
    assert_true(n > 2 * PM_REORDER_CHUNK && n < 3 * PM_REORDER_CHUNK);
    double *recs = malloc(n * 24);
    uint32_t *perm = malloc(n * sizeof *perm);
    for (uint64_t i = 0; i < n; i++) {
        recs[3 * i] = recs[3 * i + 1] = recs[3 * i + 2] = (double)i;
        perm[i] = (uint32_t)(n - 1 - i);
    }
    pm_header_t hdr;
    pm_header_init(&hdr, &pm_radiance_schema);
    hdr.count = n;
    hdr.channels = 1u << PM_RADIANCE_RGB;
    pm_header_set(&hdr, "width", "%u", w);
    pm_header_set(&hdr, "height", "%u", h);
    pm_header_set(&hdr, "component", "indirect");
    char path[600];
    snprintf(path, sizeof path, "%s/reorder.pm", unit_tmpdir());
    unsigned char *buf[2] = {malloc(PM_REORDER_CHUNK * 24), malloc(PM_REORDER_CHUNK * 24)};
    pm_writer_t *wr;
    assert_int_equal(pm_writer_open(path, &hdr, &wr), PM_OK);
    assert_int_equal(pm_reorder_write(wr, (const unsigned char *)recs, 24, n, perm, buf), PM_OK);
    assert_int_equal(pm_writer_commit(wr), PM_OK);
    pm_table_t t;
    assert_int_equal(pm_table_read(path, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, &t), PM_OK);
    assert_int_equal(t.count, n);
    const double *v = t.col[PM_RADIANCE_RGB];
    for (uint64_t i = 0; i < n; i++)
        assert_true(v[3 * i] == (double)(n - 1 - i) && v[3 * i + 2] == (double)(n - 1 - i));
    pm_table_free(&t);
    pm_header_free(&hdr);
    free(buf[0]);
    free(buf[1]);
    free(perm);
    free(recs);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_mapbuild_global_and_indirect),
    cmocka_unit_test(test_mapbuild_widths_and_vvh),
    cmocka_unit_test(test_reorder_gather),
    cmocka_unit_test(test_reorder_write),
};

UNIT_GROUP(unit_mapbuild, "mapbuild", tests);
