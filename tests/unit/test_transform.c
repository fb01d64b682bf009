/* test_transform.c: mesh placement in the scene file (rotate, matrix, their order with scale
 * and translate), mirroring maps keeping emitters' front faces, and bad transforms refused. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "render/rt.h"
#include "render/scene.h"
#include "unit.h"

static void write_tmp(const char *name, const char *text, char *path_out, size_t cap)
{
    snprintf(path_out, cap, "%s/%s", unit_tmpdir(), name);
    FILE *f = fopen(path_out, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

#define CAM "\"camera\": {\"eye\": [0,0,-9], \"look_at\": [0,0,0], \"fov_y\": 40, \"width\": 4, \"height\": 4}"

/* A scene of xf.obj (one emissive triangle (0 0 0) (1 0 0) (0 1 0), front +z) placed by the
 * JSON members `place`. */
static pm_result_t load_placed(const char *place, pm_scene_t *s)
{
    char obj[256], mtl[256], json[256], text[1024];
    write_tmp("xf.mtl", "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n", mtl, sizeof mtl);
    write_tmp("xf.obj", "mtllib xf.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n", obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"pmtk_scene\": 1, \"name\": \"xf\", \"meshes\": [{\"file\": \"xf.obj\"%s%s}], " CAM "}",
             place[0] ? ", " : "", place);
    write_tmp("xf.json", text, json, sizeof json);
    return pm_scene_load(json, s);
}

/* The placed triangle's vertices, in triangle order, and its unit right-hand-rule normal. */
static void placed(const pm_scene_t *s, float v_out[3][3], float n_out[3])
{
    assert_int_equal(s->ntris, 1);
    for (int i = 0; i < 3; i++)
        memcpy(v_out[i], &s->verts[3 * s->tris[i]], sizeof v_out[i]);
    float e1[3], e2[3];
    for (int k = 0; k < 3; k++)
        e1[k] = v_out[1][k] - v_out[0][k], e2[k] = v_out[2][k] - v_out[0][k];
    n_out[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n_out[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n_out[2] = e1[0] * e2[1] - e1[1] * e2[0];
    float l = sqrtf(n_out[0] * n_out[0] + n_out[1] * n_out[1] + n_out[2] * n_out[2]);
    for (int k = 0; k < 3; k++)
        n_out[k] /= l;
}

static int near3(const float a[3], float x, float y, float z, float tol)
{
    return fabsf(a[0] - x) <= tol && fabsf(a[1] - y) <= tol && fabsf(a[2] - z) <= tol;
}

static void test_transform_order(void **state)
{
    (void)state;
    pm_scene_t s;
    float v[3][3], n[3];
    /* scale 2, a quarter turn about +z (x -> y, y -> -x), then translate: (1 0 0) -> (0 2 0) + t */
    pm_result_t r = load_placed("\"scale\": 2, \"rotate\": {\"axis\": [0, 0, 1], \"degrees\": 90}, "
                                "\"translate\": [10, 20, 30]",
                                &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    placed(&s, v, n);
    assert_true(near3(v[0], 10, 20, 30, 0));
    assert_true(near3(v[1], 10, 22, 30, 0));
    assert_true(near3(v[2], 8, 20, 30, 0));
    assert_true(near3(n, 0, 0, 1, 1e-6f)); /* a rotation about the normal keeps it */
    float before[9];
    memcpy(before, s.verts, sizeof before);
    pm_scene_free(&s);
    /* the same as one row-major matrix: identical vertices, to the bit */
    r = load_placed("\"matrix\": [0, -2, 0, 10,  2, 0, 0, 20,  0, 0, 2, 30,  0, 0, 0, 1]", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_memory_equal(before, s.verts, sizeof before);
    pm_scene_free(&s);
    /* matrix comes after translate: a translate then a quarter turn about +x as matrix */
    r = load_placed("\"translate\": [0, 0, 1], \"matrix\": [1, 0, 0, 0,  0, 0, -1, 0,  0, 1, 0, 0,  0, 0, 0, 1]", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    placed(&s, v, n);
    assert_true(near3(v[0], 0, -1, 0, 0)); /* (0 0 1) turned about x: (0 -1 0) */
    assert_true(near3(v[2], 0, -1, 1, 0)); /* (0 1 1) -> (0 -1 1) */
    assert_true(near3(n, 0, -1, 0, 1e-6f));
    pm_scene_free(&s);
    /* an oblique rotation: 120 degrees about (1 1 1) cycles the axes x -> y -> z */
    r = load_placed("\"rotate\": {\"axis\": [1, 1, 1], \"degrees\": 120}", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    placed(&s, v, n);
    assert_true(near3(v[1], 0, 1, 0, 1e-6f));
    assert_true(near3(v[2], 0, 0, 1, 1e-6f));
    assert_true(near3(n, 1, 0, 0, 1e-6f));
    pm_scene_free(&s);
}

static void test_transform_mirror(void **state)
{
    (void)state;
    pm_scene_t s;
    float v[3][3], n[3];
    /* z -> -z: the mirror image of a triangle facing +z faces -z, and so does its emitting side */
    pm_result_t r = load_placed("\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, -1, 0,  0, 0, 0, 1]", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    placed(&s, v, n);
    assert_true(near3(n, 0, 0, -1, 1e-6f));
    pm_scene_free(&s);
    /* x -> -x: the triangle stays in z = 0 and its front face stays +z (winding swapped) */
    r = load_placed("\"matrix\": [-1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    placed(&s, v, n);
    assert_true(near3(n, 0, 0, 1, 1e-6f));
    pm_scene_free(&s);
}

static void expect_bad(const char *place, const char *needle)
{
    pm_scene_t s;
    assert_int_equal(load_placed(place, &s), PM_ERR_INPUT);
    if (!strstr(pm_error_message(), needle))
        fail_msg("message '%s' lacks '%s'", pm_error_message(), needle);
}

static void test_transform_bad_input(void **state)
{
    (void)state;
    expect_bad("\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0]",
               "meshes[0].matrix: must be an array of 16 numbers");
    expect_bad("\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 0, 0,  0, 0, 0, 1]", "matrix: is singular");
    expect_bad("\"matrix\": [1, 2, 3, 0,  2, 4, 6.000000001, 0,  0, 0, 1, 0,  0, 0, 0, 1]", "matrix: is singular");
    expect_bad("\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 1, 1]", "is not 0 0 0 1");
    expect_bad("\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, \"1\"]", "element 15 is not a number");
    /* jansson refuses NaN and Infinity literals: the scene is a syntax error naming the line */
    expect_bad("\"matrix\": [NaN, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]", "line 1");
    expect_bad("\"matrix\": [1e300, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]",
               "element 0 = 1e+300 is not finite");
    expect_bad("\"rotate\": {\"axis\": [0, 0, 0], \"degrees\": 10}", "rotate.axis: is the zero vector");
    expect_bad("\"rotate\": {\"axis\": [0, 0, 1]}", "rotate.degrees: missing");
    expect_bad("\"rotate\": {\"axis\": [0, 1], \"degrees\": 3}", "rotate.axis: must be an array of 3 numbers");
    expect_bad("\"rotate\": {\"axis\": [0, 0, 1], \"degrees\": 3, \"angle\": 1}", "unknown key 'angle'");
    expect_bad("\"rotate\": [0, 0, 1, 90]", "rotate: must be an object");
    expect_bad("\"rotate\": {\"axis\": [0, 0, 1], \"degrees\": 1e9}", "rotate.degrees: 1e+09 is outside");
}

/* A mesh file placed by four entries (turned, mirrored, scaled, moved) is built once and
 * instanced; every ray finds the same triangle at the same distance with the same normal as in
 * the same scene built flat ("instancing": false). */
static void test_transform_instances(void **state)
{
    (void)state;
    char p[512], text[2048];
    /* a unit cube, open at the bottom, with a second material on its top */
    write_tmp("cube.mtl", "newmtl side\nKd 0.5 0.5 0.5\nnewmtl top\nKd 0.2 0.2 0.2\n", p, sizeof p);
    write_tmp("cube.obj",
              "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\n"
              "usemtl side\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\nusemtl top\nf 5 6 7 8\n",
              p, sizeof p);
    static const char *const places[] = {
        "\"translate\": [-3, 0, 0]",
        "\"rotate\": {\"axis\": [1, 2, 3], \"degrees\": 33}, \"translate\": [0, 0.5, 0]",
        "\"matrix\": [-1, 0, 0, 3,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]",
        "\"scale\": 0.5, \"translate\": [0, 0, 3]",
    };
    for (int flat = 0; flat < 2; flat++) {
        size_t n = (size_t)snprintf(text, sizeof text, "{\"pmtk_scene\": 1, \"name\": \"inst\", %s\"meshes\": [",
                                    flat ? "\"instancing\": false, " : "");
        for (size_t i = 0; i < 4; i++)
            n +=
                (size_t)snprintf(text + n, sizeof text - n, "%s{\"file\": \"cube.obj\", %s}", i ? ", " : "", places[i]);
        snprintf(text + n, sizeof text - n, "], " CAM "}");
        write_tmp(flat ? "flat.json" : "inst.json", text, p, sizeof p);
    }
    pm_scene_t si, sf;
    write_tmp("unused", "", p, sizeof p);
    snprintf(p + strlen(p) - strlen("unused"), 16, "inst.json");
    if (pm_scene_load(p, &si) != PM_OK)
        fail_msg("%s", pm_error_message());
    snprintf(p + strlen(p) - strlen("inst.json"), 16, "flat.json");
    if (pm_scene_load(p, &sf) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_non_null(si.local_verts);
    assert_null(sf.local_verts);
    assert_int_equal(si.nplacements, 4);
    assert_int_equal(si.placements[3].proto, 0);
    assert_int_equal(si.placements[1].proto, 0);
    assert_int_equal(si.placements[2].proto, -1); /* mirrored: its winding differs, placed once: built flat */
    assert_int_equal(si.ntris, sf.ntris);
    assert_memory_equal(si.verts, sf.verts, 3 * si.nverts * sizeof(float));
    pm_rt_t ri, rf;
    assert_int_equal(pm_rt_create(&si, 0, 1, &ri), PM_OK);
    assert_int_equal(pm_rt_create(&sf, 0, 1, &rf), PM_OK);
    assert_non_null(ri.base);
    assert_null(rf.base);
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    uint32_t state_rng = 12345u, hits = 0;
    for (int k = 0; k < 20000; k++) {
        float o[3], d[3], l = 0;
        /* from anywhere in a 10 m box toward a point among the cubes */
        static const float lo[3] = {-4, -0.5f, -1}, size[3] = {8, 2, 5};
        for (int c = 0; c < 3; c++) {
            state_rng = state_rng * 1664525u + 1013904223u;
            o[c] = (float)(state_rng >> 8) / 16777216.0f * 10.0f - 5.0f;
            state_rng = state_rng * 1664525u + 1013904223u;
            d[c] = lo[c] + (float)(state_rng >> 8) / 16777216.0f * size[c] - o[c];
            l += d[c] * d[c];
        }
        for (int c = 0; c < 3; c++)
            d[c] /= sqrtf(l);
        float ti, tf, ni[3], nf[3];
        uint32_t hi = pm_rt_intersect1(&ri, &ctx, o, d, 0.0f, INFINITY, &ti, ni);
        uint32_t hf = pm_rt_intersect1(&rf, &ctx, o, d, 0.0f, INFINITY, &tf, nf);
        if (hi != hf)
            fail_msg("ray %d: triangle %u instanced, %u flat", k, hi, hf);
        if (hi == PM_RAY_MISS)
            continue;
        hits++;
        assert_true(fabsf(ti - tf) <= 1e-5f * (1.0f + tf));
        float li = sqrtf(ni[0] * ni[0] + ni[1] * ni[1] + ni[2] * ni[2]),
              lf = sqrtf(nf[0] * nf[0] + nf[1] * nf[1] + nf[2] * nf[2]);
        for (int c = 0; c < 3; c++)
            if (!(fabsf(ni[c] / li - nf[c] / lf) < 1e-5f))
                fail_msg("ray %d: normal %g %g %g instanced, %g %g %g flat", k, ni[0], ni[1], ni[2], nf[0], nf[1],
                         nf[2]);
    }
    if (hits < 1000)
        fail_msg("%u of 20000 rays hit", hits);
    pm_rt_destroy(&ri);
    pm_rt_destroy(&rf);
    pm_scene_free(&si);
    pm_scene_free(&sf);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_transform_instances),
    cmocka_unit_test(test_transform_order),
    cmocka_unit_test(test_transform_mirror),
    cmocka_unit_test(test_transform_bad_input),
};
UNIT_GROUP(unit_transform, "transform", tests);
