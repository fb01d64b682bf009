/* test_summary.c: render/summary, what scene-info computes: the needs of a glossy, a Lambertian
 * and an area-lit scene; the probe and its preview on a one-pixel camera looking straight down
 * at a floor (every ray hits; cos 1, so the pixel is the albedo); the summary as JSON and text. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/image.h"
#include "render/summary.h"
#include "unit.h"

static void load(const char *path, pm_scene_t *s, pm_rt_t *rt)
{
    if (pm_scene_load(path, s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(pm_rt_create(s, 0, 1, rt), PM_OK);
}

static void test_summary_needs(void **state)
{
    static const struct {
        const char *path;
        int directions, material_ids, area_lights;
    } cases[] = {
        {"tests/scenes/glossy-box/scene.json", 1, 1, 0}, /* two materials, one glossy */
        {"tests/scenes/lit-floor/scene.json", 0, 0, 0},  /* Lambertian, a point light */
        {"scenes/cornell-box/scene.json", 0, 0, 1},      /* Lambertian, an emitting quad */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        pm_scene_t s;
        if (pm_scene_load(cases[i].path, &s) != PM_OK)
            fail_msg("%s", pm_error_message());
        pm_scene_needs_t n = pm_scene_needs(&s);
        assert_int_equal(n.directions, cases[i].directions);
        assert_int_equal(n.material_ids, cases[i].material_ids);
        assert_int_equal(n.area_lights, cases[i].area_lights);
        pm_scene_free(&s);
    }
}

static void test_summary_probe_preview(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load("tests/scenes/lit-floor/scene.json", &s, &rt);
    assert_int_equal(s.camera.width * s.camera.height, 1);
    uint8_t rgb[3] = {0};
    pm_probe_t p;
    assert_int_equal(pm_scene_probe(&s, &rt, 0, rgb, &p), PM_OK);
    assert_int_equal(p.rays, 1);
    assert_int_equal(p.hits, 1);
    /* kd 0.5 0.25 0.125 seen head-on: (kd + ks) (0.2 + 0.8 cos) with cos 1 */
    const float *kd = s.materials[0].kd;
    for (int k = 0; k < 3; k++)
        assert_int_equal(rgb[k], pm_srgb8(kd[k]));
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static void test_summary_json(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load("tests/scenes/glossy-box/scene.json", &s, &rt);
    pm_summary_options_t o = {.load_s = 0.25, .bvh_s = 0.5};
    json_t *j = NULL;
    if (pm_summary_json(&s, &rt, &o, NULL, &j) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_string_equal(json_string_value(json_object_get(j, "name")), "glossy-box");
    assert_int_equal(json_integer_value(json_object_get(j, "triangles")), 12);
    json_t *mats = json_object_get(j, "materials");
    assert_int_equal(json_array_size(mats), 2);
    assert_string_equal(json_string_value(json_object_get(json_array_get(mats, 1), "name")), "gloss");
    assert_true(json_is_true(json_object_get(j, "glossy")));
    json_t *needs = json_object_get(j, "needs");
    assert_true(json_is_true(json_object_get(needs, "direction_channels")));
    assert_true(json_is_true(json_object_get(needs, "material_ids")));
    assert_true(json_is_false(json_object_get(needs, "area_light_sampling")));
    /* one point light of intensity 1 W/sr: 4 pi W per channel */
    assert_true(fabs(json_real_value(json_array_get(json_object_get(j, "power_w"), 0)) - 4.0 * M_PI) < 1e-5);
    assert_true(json_real_value(json_object_get(j, "bvh_s")) == 0.5);
    assert_null(json_object_get(j, "probe"));
    json_decref(j);

    pm_probe_t p = {64, 48, 1e6};
    assert_int_equal(pm_summary_json(&s, &rt, &o, &p, &j), PM_OK);
    assert_true(json_real_value(json_object_get(json_object_get(j, "probe"), "hit_fraction")) == 0.75);
    json_decref(j);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static void test_summary_text(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load("tests/scenes/glossy-box/scene.json", &s, &rt);
    FILE *f = tmpfile();
    assert_non_null(f);
    pm_summary_options_t o = {.probe = 1};
    pm_probe_t p;
    assert_int_equal(pm_summary_write(f, &s, &rt, &o, &p), PM_OK);
    assert_int_equal(p.rays, 64); /* 8 x 8 */
    assert_int_equal(p.hits, 64); /* inside a closed box */
    rewind(f);
    char line[512];
    int needs = 0, probe = 0;
    while (fgets(line, sizeof line, f)) {
        needs += !strcmp(line, "needs: direction channels yes, material ids yes, area-light sampling no\n");
        probe += !strncmp(line, "probe: 64 primary rays, 100.0% hit geometry, ", 45);
    }
    fclose(f);
    assert_int_equal(needs, 1);
    assert_int_equal(probe, 1);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_summary_needs),
    cmocka_unit_test(test_summary_probe_preview),
    cmocka_unit_test(test_summary_json),
    cmocka_unit_test(test_summary_text),
};
UNIT_GROUP(unit_summary, "summary", tests);
