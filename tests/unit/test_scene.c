/* test_scene.c: scene loading (the Cornell box's published numbers), bad scene input
 * with clear messages, degenerate triangles, Embree rays against known distances, what is
 * reported, the PBR materials (MTL Pr/Pm, glTF metallic-roughness) and the scene's identity
 * (its canonical serialisation and its parts). */
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/rt.h"
#include "render/scene.h"
#include "unit.h"

static void write_file(const char *name, const char *text, char *path_out, size_t cap)
{
    snprintf(path_out, cap, "%s/%s", unit_tmpdir(), name);
    FILE *f = fopen(path_out, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void test_scene_cornell_box(void **state)
{
    pm_scene_t s;
    pm_result_t r = pm_scene_load("scenes/cornell-box/scene.json", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_string_equal(s.name, "cornell-box");
    assert_int_equal(s.ntris, 32);
    assert_int_equal(s.nmaterials, 4); /* white, red, green, light: assimp's default is dropped */
    assert_int_equal(s.nemissive, 2);
    assert_int_equal(s.any_glossy, 0);
    /* light: 130 mm x 105 mm, Ke (17, 12, 4) W/(m^2 sr): power = pi Ke A */
    double p[3];
    pm_scene_power(&s, p);
    assert_true(fabs(p[0] - M_PI * 17 * 0.130 * 0.105) < 1e-5);
    assert_true(fabs(p[2] - M_PI * 4 * 0.130 * 0.105) < 1e-5);
    assert_true(fabsf(s.bounds[4] - 0.5488f) < 1e-6f);
    assert_int_equal(s.camera.width, 256);
    /* SCENE: the whole scene's key; not the one-hash form of files before the parts (and before
     * the identity's version 2) */
    char id[300], old[200];
    pm_scene_id(&s, id, sizeof id);
    snprintf(old, sizeof old, "cornell-box xxh3:%016llx", (unsigned long long)s.hash);
    assert_true(pm_scene_id_matches(&s, id));
    assert_false(pm_scene_id_matches(&s, old));
    pm_scene_id_part(&s, PM_SCENE_VIEW, id, sizeof id);
    assert_false(pm_scene_id_matches(&s, id));
    assert_false(pm_scene_id_matches(&s, "cornell-box xxh3:0000000000000000"));

    pm_rt_t rt;
    assert_int_equal(pm_rt_create(&s, 0, 2, &rt), PM_OK);
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    /* straight down from 0.5 m above the floor, away from the blocks */
    struct RTCRayHit rh = {
        .ray = {.org_x = 0.1f, .org_y = 0.5f, .org_z = 0.1f, .dir_y = -1.0f, .tfar = INFINITY, .mask = 0xffffffffu},
        .hit = {.geomID = RTC_INVALID_GEOMETRY_ID}};
    rtcIntersect1(rt.scene, &ctx, &rh);
    assert_int_equal(rh.hit.geomID, 0);
    assert_true(fabsf(rh.ray.tfar - 0.5f) < 1e-5f);
    assert_true(rh.hit.Ng_y > 0.0f); /* the floor faces into the box */
    /* up from the same point: the ceiling at 548.8 mm */
    rh.ray.dir_y = 1.0f;
    rh.ray.tfar = INFINITY;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rt.scene, &ctx, &rh);
    assert_true(fabsf(rh.ray.tfar - 0.0488f) < 1e-5f);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static void expect_scene_error(const char *json, const char *needle)
{
    char path[256];
    write_file("bad.json", json, path, sizeof path);
    pm_scene_t s;
    assert_int_equal(pm_scene_load(path, &s), PM_ERR_INPUT);
    if (!strstr(pm_error_message(), needle))
        fail_msg("message '%s' lacks '%s'", pm_error_message(), needle);
}

#define CAM "\"camera\": {\"eye\": [0,0,-1], \"look_at\": [0,0,0], \"fov_y\": 40, \"width\": 4, \"height\": 4}"

/* A load imports each mesh once, in one forked child for the whole load (render/mesh_guard.c,
 * pm_scene_load_guarded): one child per load, none with the import limits off or from the scene
 * cache. The children are counted by SIGCHLD. */
static volatile sig_atomic_t children;
static void count_child(int sig)
{
    (void)sig;
    children++;
}

static int load_children(const char *path)
{
    struct sigaction sa = {0}, old;
    sa.sa_handler = count_child;
    sa.sa_flags = SA_RESTART;
    sigaction(SIGCHLD, &sa, &old);
    children = 0;
    pm_scene_t s;
    pm_result_t r = pm_scene_load(path, &s);
    sigaction(SIGCHLD, &old, NULL);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_string_equal(s.name, "x");
    assert_int_equal(s.ntris, 1);
    pm_scene_free(&s);
    return (int)children;
}

static void test_scene_guarded_once(void **state)
{
    (void)state;
    char mesh[256], mtl[256], path[256], cache[600];
    write_file("once.mtl", "newmtl a\nKd 0.5 0.5 0.5\n", mtl, sizeof mtl);
    write_file("once.obj", "mtllib once.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n", mesh, sizeof mesh);
    write_file("once.json", "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"once.obj\"}], " CAM "}",
               path, sizeof path);
    unsetenv("PMTK_SCENE_CACHE");
    assert_int_equal(load_children(path), 1); /* the guarded load */
    assert_int_equal(load_children(path), 1); /* each load: no bytes are taken on trust */
    setenv("PMTK_IMPORT_SECONDS", "0", 1);
    setenv("PMTK_IMPORT_MB", "0", 1);
    assert_int_equal(load_children(path), 0); /* limits off: in this process */
    unsetenv("PMTK_IMPORT_SECONDS");
    unsetenv("PMTK_IMPORT_MB");
    snprintf(cache, sizeof cache, "%s/once.cache", unit_tmpdir());
    setenv("PMTK_SCENE_CACHE", cache, 1);
    assert_int_equal(load_children(path), 1); /* a miss: the guarded load, then the cache written */
    assert_int_equal(load_children(path), 0); /* a hit */
    unsetenv("PMTK_SCENE_CACHE");
}

static void test_scene_bad_input(void **state)
{
    char mesh[256], mtl[256];
    write_file("m.mtl", "newmtl hot\nKd 0.9 0.5 0.5\nKs 0.2 0 0\n", mtl, sizeof mtl);
    write_file("m.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl hot\nf 1 2 3\n", mesh, sizeof mesh);
    expect_scene_error("{\n  \"pmtk_scene\": 1,\n  \"name\": \"x\",,\n}", "line 3");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"camra\": {}}", "unknown key 'camra'");
    expect_scene_error("{\"pmtk_scene\": 2, \"name\": \"x\", " CAM "}", "pmtk_scene: 2 is outside [1, 1]");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"camera\": {\"eye\": [0,0,-1], \"look_at\": [0,0,0], "
                       "\"fov_y\": 200, \"width\": 4, \"height\": 4}}",
                       "camera.fov_y: 200 is outside");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"camera\": {\"eye\": [0,0,0], \"look_at\": [0,0,0], "
                       "\"fov_y\": 40, \"width\": 4, \"height\": 4}}",
                       "camera.look_at: equals camera.eye");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"nope.obj\"}], " CAM "}",
                       "cannot open mesh");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", " CAM ", \"point_lights\": [{\"position\": [0,0,0], "
                       "\"intensity\": [1,-1,1]}]}",
                       "point_lights[0].intensity: element 1 = -1 is outside");
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"name\": \"y\", " CAM "}", "duplicate");
    /* Kd + Ks above 1 is read, both scaled by one factor to sum to 1, and said once (issue 29) */
    char path[256];
    write_file("kdks.json", "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"m.obj\"}], " CAM "}", path,
               sizeof path);
    pm_scene_t s;
    assert_int_equal(pm_scene_load(path, &s), PM_OK);
    assert_float_equal(s.materials[0].kd[0], 0.9f / 1.1f, 1e-6);
    assert_float_equal(s.materials[0].ks[0], 0.2f / 1.1f, 1e-6);
    assert_float_equal(s.materials[0].kd[1], 0.5f / 1.1f, 1e-6);
    assert_int_equal(s.nunsupported, 1);
    assert_string_equal(s.unsupported[0].key, "Kd + Ks");
    assert_non_null(strstr(s.unsupported[0].note, "scaled by 0.909091"));
    pm_scene_free(&s);
}

static void test_scene_mesh_faults(void **state)
{
    char p[256];
    write_file("a.mtl", "newmtl a\nKd 0.5 0.5 0.5\n", p, sizeof p);
    write_file("nomtl.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", p, sizeof p);
    write_file("badmtl.obj", "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl nosuch\nf 1 2 3\n", p, sizeof p);
    write_file("gonemtl.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n", p, sizeof p);
    /* assimp gives faces before the first usemtl the last material of the .mtl */
    write_file("two.mtl", "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 10 10 10\n", p, sizeof p);
    write_file("lastmtl.obj", "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\ng floor\nf 1 2 3\n", p, sizeof p);
    write_file("latelib.obj", "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nusemtl a\nmtllib two.mtl\nv 0 1 0\nf 1 2 3\n", p,
               sizeof p);
    write_file("badidx.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n", p, sizeof p);
    write_file("tri.ply",
               "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
               p, sizeof p);
    static const char *const cases[][2] = {
        {"lastmtl.obj", "face 1 (line 6, group 'floor') comes before any usemtl"},
        {"latelib.obj", "mtllib on line 5 comes after the usemtl on line 4"},
        {"badmtl.obj", "failed to locate material nosuch"},
        {"gonemtl.obj", "Unable to locate material file gone.mtl"},
        {"badidx.obj", "vertex index out of range"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char json[512];
        snprintf(json, sizeof json, "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"%s\"}], " CAM "}",
                 cases[i][0]);
        char path[256];
        write_file("m.json", json, path, sizeof path);
        pm_scene_t s;
        assert_int_equal(pm_scene_load(path, &s), PM_ERR_INPUT);
        const char *msg = pm_error_message();
        if (!strstr(msg, "scene '") || !strstr(msg, cases[i][0]))
            fail_msg("'%s' does not name the scene and the mesh", msg);
        if (!strstr(msg, cases[i][1]))
            fail_msg("message '%s' lacks '%s'", msg, cases[i][1]);
    }
    /* a PLY names no material: a grey Lambertian default, not assimp's Ks = 1 */
    char path[256];
    write_file("ply.json", "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"tri.ply\"}], " CAM "}", path,
               sizeof path);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(path, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.ntris, 1);
    assert_int_equal(s.nmaterials, 1);
    assert_true(s.materials[0].kd[0] == 0.8f && s.materials[0].ks[0] == 0.0f);
    assert_int_equal(s.materials[0].kind, PM_MAT_STANDARD);
    pm_scene_free(&s);
    /* an OBJ with no mtllib and no usemtl is geometry: the same grey, and a note (issue 29) */
    write_file("nomtl.json", "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"nomtl.obj\"}], " CAM "}",
               path, sizeof path);
    if ((r = pm_scene_load(path, &s)) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 1);
    assert_true(s.materials[0].kd[0] == 0.8f && s.materials[0].ks[0] == 0.0f);
    assert_int_equal(s.nnotes, 1);
    assert_non_null(strstr(s.notes[0].text, "names no material: its faces are the default grey (Kd 0.8)"));
    pm_scene_free(&s);
}

/* Shapes (issue 29): every triangle of a sphere, a box and a disk wound with its front face
 * outward (away from the centre; a disk's and a rectangle's toward +z before their transform),
 * a sphere's and a disk's facets of the curved area exactly (to float rounding), a box's its
 * six faces; a mirroring matrix keeps the fronts outward. */
static void test_scene_shapes(void **state)
{
    (void)state;
    char path[256];
    write_file("shapes.json",
               "{\"pmtk_scene\": 1, \"name\": \"x\", \"shapes\": ["
               "{\"type\": \"sphere\", \"radius\": 0.5, \"segments\": 12, \"translate\": [3, 0, 0]},"
               "{\"type\": \"box\", \"size\": [1, 2, 3], \"translate\": [-3, 0, 0]},"
               "{\"type\": \"disk\", \"radius\": 2, \"segments\": 5, \"rotate\": {\"axis\": [1, 0, 0], "
               "\"degrees\": -90}, \"translate\": [0, -5, 0]},"
               "{\"type\": \"sphere\", \"radius\": 1, \"matrix\": [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 9, 0, 0, 0, 1]}"
               "], " CAM "}",
               path, sizeof path);
    pm_scene_t s;
    if (pm_scene_load(path, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nplacements, 4);
    static const double centre[4][3] = {{3, 0, 0}, {-3, 0, 0}, {0, -6, 0}, {0, 0, 9}};
    const double want[4] = {M_PI, 2 * (2 + 3 + 6), 4 * M_PI, 4 * M_PI};
    for (size_t p = 0; p < 4; p++) {
        const pm_placement_t *pl = &s.placements[p];
        double area = 0.0;
        for (uint32_t t = pl->tri0; t < pl->tri0 + pl->ntris; t++) {
            const float *a = &s.verts[3 * s.tris[3 * t]], *b = &s.verts[3 * s.tris[3 * t + 1]],
                        *c = &s.verts[3 * s.tris[3 * t + 2]];
            double e1[3], e2[3], n[3], d = 0.0;
            for (int k = 0; k < 3; k++)
                e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
            n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2],
            n[2] = e1[0] * e2[1] - e1[1] * e2[0];
            /* a disk: away from the point below its centre (its front faces +y after the turn) */
            for (int k = 0; k < 3; k++)
                d += n[k] * (((double)a[k] + b[k] + c[k]) / 3.0 - centre[p][k]);
            if (!(d > 0.0))
                fail_msg("shape %zu triangle %u faces inward", p, t);
            area += pm_scene_triangle_area(&s, t);
        }
        if (fabs(area / want[p] - 1.0) > 1e-6)
            fail_msg("shape %zu: area %.9g, expected %.9g", p, area, want[p]);
    }
    pm_scene_free(&s);
}

/* A Collada (or glTF 1) material gives no metallic or roughness factor: it stays the Phong
 * material its format describes, not glTF 2's default rough metal. */
static void test_scene_phong_formats_stay_phong(void **state)
{
    (void)state;
    char p[256];
    write_file("phong.dae",
               "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
               "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
               "<library_effects><effect id=\"fx\"><profile_COMMON><technique sid=\"t\"><phong>\n"
               "<diffuse><color>0.6 0.5 0.4 1</color></diffuse><specular><color>0.2 0.2 0.2 "
               "1</color></specular><shininess><float>60</float></shininess>\n"
               "</phong></technique></profile_COMMON></effect></library_effects>\n"
               "<library_materials><material id=\"paint\" name=\"paint\"><instance_effect "
               "url=\"#fx\"/></material></library_materials>\n"
               "<library_geometries><geometry id=\"g\"><mesh>\n"
               "<source id=\"p\"><float_array id=\"pa\" count=\"9\">0 0 0 1 0 0 0 1 "
               "0</float_array><technique_common><accessor source=\"#pa\" count=\"3\" stride=\"3\"><param name=\"X\" "
               "type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" "
               "type=\"float\"/></accessor></technique_common></source>\n"
               "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#p\"/></vertices>\n"
               "<triangles material=\"m\" count=\"1\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><p>0 1 "
               "2</p></triangles>\n"
               "</mesh></geometry></library_geometries>\n"
               "<library_visual_scenes><visual_scene id=\"s\"><node id=\"n\"><instance_geometry "
               "url=\"#g\"><bind_material><technique_common><instance_material symbol=\"m\" "
               "target=\"#paint\"/></technique_common></bind_material></instance_geometry></node></visual_scene></"
               "library_visual_scenes>\n"
               "<scene><instance_visual_scene url=\"#s\"/></scene>\n"
               "</COLLADA>\n",
               p, sizeof p);
    write_file("dae.json", "{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"phong.dae\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(p, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 1);
    assert_int_equal(s.materials[0].kind, PM_MAT_STANDARD);
    assert_true(fabsf(s.materials[0].kd[0] - 0.6f) < 1e-6f && fabsf(s.materials[0].ks[0] - 0.2f) < 1e-6f);
    assert_true(s.materials[0].ns == 60.0f);
    pm_scene_free(&s);
}

static void test_scene_degenerate_triangles(void **state)
{
    char mesh[256], path[256];
    /* one good triangle, one with a repeated vertex, one with collinear vertices */
    write_file("d.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n", mesh, sizeof mesh);
    write_file("d.obj", "mtllib d.mtl\nusemtl grey\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\nf 1 2 4\n",
               mesh, sizeof mesh);
    write_file("d.json",
               "{\"pmtk_scene\": 1, \"name\": \"d\", \"meshes\": [{\"file\": \"d.obj\", \"scale\": 1e-4}], " CAM "}",
               path, sizeof path);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(path, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.ntris, 1);
    assert_int_equal(s.ndropped, 2);
    assert_true(fabs(pm_scene_triangle_area(&s, 0) - 0.5e-8) < 1e-14);
    pm_rt_t rt;
    assert_int_equal(pm_rt_create(&s, 0, 2, &rt), PM_OK);
    assert_true(rt.epsilon > 0.0f && rt.epsilon < 1e-8f); /* scales with the 0.1 mm scene */
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

/* Properties the loader does not honour are kept once per material and key, for the materials
 * some triangle uses; neutral values (d 1, illum 2) are not reported; keys assimp drops
 * (sharpness, refl) are read from the .mtl itself. */
static void test_scene_unsupported(void **state)
{
    char p[256];
    write_file("u.mtl",
               "newmtl tex\nKd 0.5 0.5 0.5\nmap_Ka tex.png\ndisp b.png\nd 0.5\nTr 0.25\nillum 6\nNi 1.5\n"
               "Tf 0.9 0.8 0.7\nsharpness 60\nrefl -type sphere r.png\nnewmtl plain\nKd 0.5 0.5 0.5\nd 1\nillum "
               "2\nnewmtl unused\nKd 0.1 0.1 0.1\n"
               "map_Kd u.png\n",
               p, sizeof p);
    write_file("u.obj", "mtllib u.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl tex\nf 1 2 3\nusemtl plain\nf 1 3 2\n", p,
               sizeof p);
    write_file("u.json", "{\"pmtk_scene\": 1, \"name\": \"u\", \"meshes\": [{\"file\": \"u.obj\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(p, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 2);
    static const char *const want[][2] = {
        {"map_Ka", "tex.png"}, {"disp", "b.png"},     {"d", "0.75"},       {"illum", "6"},
        {"Ni", "1.5"},         {"Tf", "0.9 0.8 0.7"}, {"sharpness", "60"}, {"refl", "-type sphere r.png"}};
    assert_int_equal(s.nunsupported, sizeof want / sizeof want[0]);
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        size_t found = 0;
        for (size_t u = 0; u < s.nunsupported; u++)
            if (strcmp(s.unsupported[u].key, want[i][0]) == 0) {
                found++;
                assert_string_equal(s.unsupported[u].value, want[i][1]);
                assert_string_equal(s.materials[s.unsupported[u].material].name, "tex");
            }
        if (found != 1)
            fail_msg("%s reported %zu times", want[i][0], found);
    }
    /* as the warnings print them: a texture's file quoted, a number as it is */
    char text[300];
    for (size_t u = 0; u < s.nunsupported; u++) {
        pm_scene_unsupported_text(&s.unsupported[u], text, sizeof text);
        if (strcmp(s.unsupported[u].key, "map_Ka") == 0)
            assert_string_equal(text, "map_Ka 'tex.png'");
        if (strcmp(s.unsupported[u].key, "illum") == 0)
            assert_string_equal(text, "illum 6");
    }
    pm_scene_free(&s);
}

/* A glTF material: base colour is Kd; its emissive texture (in assimp's emissive and emission
 * colour slots) is reported once; metallic 0 and roughness 0.5 make it plastic (honoured, not
 * reported), alphaMode OPAQUE is not reported. (A base colour texture is honoured:
 * tests/unit/test_texture.c.) */
static void test_scene_unsupported_gltf(void **state)
{
    char p[256];
    write_file("g.gltf",
               "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": "
               "[{\"mesh\": 0}], \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 1, "
               "\"material\": 0}]}], \"materials\": [{\"name\": \"m\", \"pbrMetallicRoughness\": {\"baseColorFactor\": "
               "[0.5, 0.4, 0.3, 1], \"metallicFactor\": 0, \"roughnessFactor\": 0.5}, \"emissiveTexture\": "
               "{\"index\": 0}}], \"textures\": [{\"source\": 0}], \"images\": [{\"uri\": \"tex.png\"}], "
               "\"buffers\": [{\"byteLength\": 44, \"uri\": \"data:application/octet-stream;base64,"
               "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/AAABAAIAAAA=\"}], \"bufferViews\": [{\"buffer\": 0, "
               "\"byteOffset\": 0, \"byteLength\": 36}, {\"buffer\": 0, \"byteOffset\": 36, \"byteLength\": 6}], "
               "\"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\", "
               "\"min\": [0, 0, 0], \"max\": [1, 0, 1]}, {\"bufferView\": 1, \"componentType\": 5123, \"count\": 3, "
               "\"type\": \"SCALAR\"}]}\n",
               p, sizeof p);
    write_file("g.json", "{\"pmtk_scene\": 1, \"name\": \"g\", \"meshes\": [{\"file\": \"g.gltf\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(p, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 1);
    assert_int_equal(s.materials[0].kind, PM_MAT_PLASTIC);
    assert_true(fabsf(s.materials[0].kd[1] - 0.4f) < 1e-6f);
    assert_int_equal(s.nunsupported, 1);
    assert_string_equal(s.unsupported[0].key, "emissive texture");
    assert_string_equal(s.unsupported[0].value, "tex.png");
    pm_scene_free(&s);
}

/* The material named name in s, or a failed test. */
static const pm_material_t *material_named(const pm_scene_t *s, const char *name)
{
    for (size_t m = 0; m < s->nmaterials; m++)
        if (strcmp(s->materials[m].name, name) == 0)
            return &s->materials[m];
    fail_msg("no material '%s'", name);
    return NULL;
}

/* The unsupported entry of material name with key, or NULL. */
static const pm_scene_unsupported_t *reported(const pm_scene_t *s, const char *name, const char *key)
{
    for (size_t u = 0; u < s->nunsupported; u++)
        if (strcmp(s->materials[s->unsupported[u].material].name, name) == 0 && strcmp(s->unsupported[u].key, key) == 0)
            return &s->unsupported[u];
    return NULL;
}

static void assert_rgb(const float got[3], float r, float g, float b)
{
    const float want[3] = {r, g, b};
    for (int k = 0; k < 3; k++)
        if (!(fabsf(got[k] - want[k]) < 1e-6f))
            fail_msg("channel %d: %.9g, want %.9g", k, (double)got[k], (double)want[k]);
}

/* An OBJ whose .mtl has the PBR extension: Pm 1 is a conductor of F0 Kd and width Pr^2 (width 0,
 * the smooth limit, at Pr 0), Pr without Pm plastic under a coat of index 1.5 (Ni when given),
 * Pm 0.7 the nearer kind (a metal of F0 lerp(0.04, Kd, 0.7)) with a note, illum 7 with Pr rough
 * glass; a material without Pr or Pm stays standard; a PBR material's Ks is reported. */
static void test_scene_pbr_mtl(void **state)
{
    char p[256];
    write_file("pbr.mtl",
               "newmtl metal\nKd 0.9 0.6 0.3\nPm 1\nPr 0.5\n"
               "newmtl polished\nKd 0.9 0.6 0.3\nPm 1\nPr 0\nillum 2\n"
               "newmtl plastic\nKd 0.5 0.4 0.3\nKs 0.2 0.2 0.2\nNs 50\nPr 0.6\n"
               "newmtl coated\nKd 0.5 0.4 0.3\nPr 0.2\nNi 1.3\n"
               "newmtl half\nKd 0.5 0.5 0.5\nPm 0.7\nPr 0.5\n"
               "newmtl frosted\nKd 0 0 0\nillum 7\nNi 1.5\nTf 0.9 0.8 0.7\nPr 0.3\n"
               "newmtl plain\nKd 0.5 0.5 0.5\nKs 0.25 0.25 0.25\nNs 20\n",
               p, sizeof p);
    write_file("pbr.obj",
               "mtllib pbr.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl metal\nf 1 2 3\nusemtl polished\nf 1 3 2\n"
               "usemtl plastic\nf 2 1 3\nusemtl coated\nf 2 3 1\nusemtl half\nf 3 1 2\nusemtl frosted\nf 3 2 1\n"
               "usemtl plain\nf 1 2 3\n",
               p, sizeof p);
    write_file("pbr.json", "{\"pmtk_scene\": 1, \"name\": \"pbr\", \"meshes\": [{\"file\": \"pbr.obj\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    if (pm_scene_load(p, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 7);
    const pm_material_t *m = material_named(&s, "metal");
    assert_int_equal(m->kind, PM_MAT_CONDUCTOR);
    assert_rgb(m->f0, 0.9f, 0.6f, 0.3f);
    assert_rgb(m->kd, 0, 0, 0);
    assert_true(m->alpha == 0.25f && m->eta[0] == 0.0f);
    m = material_named(&s, "polished"); /* the smooth limit: a delta conductor */
    assert_int_equal(m->kind, PM_MAT_CONDUCTOR);
    assert_rgb(m->f0, 0.9f, 0.6f, 0.3f);
    assert_true(m->alpha == 0.0f);
    assert_null(reported(&s, "polished", "Kd")); /* a PBR metal's Kd is its F0 */
    m = material_named(&s, "plastic");
    assert_int_equal(m->kind, PM_MAT_PLASTIC);
    assert_rgb(m->kd, 0.5f, 0.4f, 0.3f);
    assert_rgb(m->ks, 0, 0, 0);
    assert_true(m->ior == 1.5f && fabsf(m->alpha - 0.36f) < 1e-6f && m->ns == 0.0f);
    assert_non_null(reported(&s, "plastic", "Ks"));
    assert_null(reported(&s, "plastic", "Ns"));
    assert_null(reported(&s, "plastic", "Pr"));
    m = material_named(&s, "coated");
    assert_int_equal(m->kind, PM_MAT_PLASTIC);
    assert_true(fabsf(m->ior - 1.3f) < 1e-6f);
    assert_null(reported(&s, "coated", "Ni"));
    m = material_named(&s, "half");
    assert_int_equal(m->kind, PM_MAT_CONDUCTOR);
    assert_rgb(m->f0, 0.7f * 0.5f + 0.3f * 0.04f, 0.7f * 0.5f + 0.3f * 0.04f, 0.7f * 0.5f + 0.3f * 0.04f);
    const pm_scene_unsupported_t *u = reported(&s, "half", "Pm");
    assert_non_null(u);
    assert_string_equal(u->value, "0.7");
    assert_non_null(strstr(u->note, "rendered as metal"));
    m = material_named(&s, "frosted");
    assert_int_equal(m->kind, PM_MAT_ROUGH_GLASS);
    assert_true(fabsf(m->alpha - 0.09f) < 1e-6f && m->ior == 1.5f);
    assert_rgb(m->tf, 0.9f, 0.8f, 0.7f);
    assert_null(reported(&s, "frosted", "Pr"));
    m = material_named(&s, "plain");
    assert_int_equal(m->kind, PM_MAT_STANDARD);
    assert_rgb(m->ks, 0.25f, 0.25f, 0.25f);
    assert_true(m->ns == 20.0f);
    assert_true(s.any_glossy);
    pm_scene_free(&s);

    /* out of range: one line naming the material, the key and the value */
    static const char *const bad[][2] = {
        {"newmtl x\nKd 0.5 0.5 0.5\nPr 1.5\n", "material 'x': Pr 1.5 must lie in [0, 1]"},
        {"newmtl x\nKd 0.5 0.5 0.5\nPm -0.5\n", "material 'x': Pm -0.5 must lie in [0, 1]"},
        {"newmtl x\nillum 7\nNi 1.5\nPr 2\n", "material 'x': Pr 2 must lie in [0, 1]"},
        {"newmtl x\nKd 0.5 0.5 0.5\nPr 0.5\nNi 0.5\n", "material 'x': Ni 0.5 must lie in [1, 10]"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        write_file("bad.mtl", bad[i][0], p, sizeof p);
        write_file("bad.obj", "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n", p, sizeof p);
        expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"bad.obj\"}], " CAM "}",
                           bad[i][1]);
    }
}

/* A PBR metal's base colour texture scales its F0 (map_Kd times Kd is the base colour): a 1 x 1
 * TGA of (255, 0, 255), texel (1, 0, 1) after sRGB decoding, on F0 (0.9, 0.6, 0.3). */
static void test_scene_pbr_texture(void **state)
{
    char p[256];
    static const unsigned char tga[21] = {0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 1, 0, 24, 0, 255, 0, 255};
    snprintf(p, sizeof p, "%s/m.tga", unit_tmpdir());
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(tga, 1, sizeof tga, f), sizeof tga);
    fclose(f);
    write_file("tm.mtl", "newmtl tm\nKd 0.9 0.6 0.3\nPm 1\nPr 0.5\nmap_Kd m.tga\n", p, sizeof p);
    write_file("tm.obj", "mtllib tm.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl tm\nf 1/1 2/1 3/1\n", p, sizeof p);
    write_file("tm.json", "{\"pmtk_scene\": 1, \"name\": \"tm\", \"meshes\": [{\"file\": \"tm.obj\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    if (pm_scene_load(p, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.materials[0].kind, PM_MAT_CONDUCTOR);
    pm_material_t scratch;
    const float at[3] = {0.25f, 0.25f, 0.0f};
    const pm_material_t *m = pm_scene_material_at(&s, 0, at, &scratch);
    assert_rgb(m->f0, 0.9f, 0.0f, 0.3f);
    assert_rgb(s.materials[0].f0, 0.9f, 0.6f, 0.3f); /* the scene's own material is not touched */
    pm_scene_free(&s);
}

/* A glTF of one triangle per material (materials: the JSON array's body). */
static void write_gltf(const char *name, const char *materials, size_t n, char *path_out, size_t cap)
{
    char prims[2048] = "", text[8192];
    for (size_t i = 0; i < n; i++)
        snprintf(prims + strlen(prims), sizeof prims - strlen(prims),
                 "%s{\"attributes\": {\"POSITION\": 0}, \"material\": %zu}", i ? ", " : "", i);
    snprintf(text, sizeof text,
             "{\"asset\": {\"version\": \"2.0\"}, \"extensionsUsed\": [\"KHR_materials_transmission\", "
             "\"KHR_materials_ior\"], \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}], "
             "\"meshes\": [{\"primitives\": [%s]}], \"materials\": [%s], \"buffers\": [{\"byteLength\": 36, \"uri\": "
             "\"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/\"}], "
             "\"bufferViews\": [{\"buffer\": 0, \"byteLength\": 36}], \"accessors\": [{\"bufferView\": 0, "
             "\"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\", \"min\": [0, 0, 0], \"max\": [1, 0, 1]}]}\n",
             prims, materials);
    write_file(name, text, path_out, cap);
}

/* glTF metallic-roughness: metallic 1 (glTF's default) a conductor of F0 the base colour and
 * width roughness^2, metallic 0 plastic (coat index 1.5, or KHR_materials_ior's; index 1 is
 * exactly Lambertian: a standard material), metallic 0.3 plastic of kd 0.7 base with a note,
 * transmission with roughness rough glass; a factor outside [0, 1] is an error. */
static void test_scene_pbr_gltf(void **state)
{
    char p[256];
    write_gltf("pbr.gltf",
               "{\"name\": \"metal\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.9, 0.8, 0.7, 1], "
               "\"roughnessFactor\": 0.4}}, "
               "{\"name\": \"plastic\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.5, 0.4, 0.3, 1], "
               "\"metallicFactor\": 0, \"roughnessFactor\": 0.2}, \"extensions\": {\"KHR_materials_ior\": {\"ior\": "
               "1.4}}}, "
               "{\"name\": \"matte\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.5, 0.4, 0.3, 1], "
               "\"metallicFactor\": 0}, \"extensions\": {\"KHR_materials_ior\": {\"ior\": 1}}}, "
               "{\"name\": \"mix\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.5, 0.5, 0.5, 1], "
               "\"metallicFactor\": 0.3, \"roughnessFactor\": 0.5}}, "
               "{\"name\": \"frosted\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.9, 0.9, 0.8, 1], "
               "\"metallicFactor\": 0, \"roughnessFactor\": 0.3}, \"extensions\": {\"KHR_materials_transmission\": "
               "{\"transmissionFactor\": 1}, \"KHR_materials_ior\": {\"ior\": 1.7}}}",
               5, p, sizeof p);
    write_file("pbrg.json", "{\"pmtk_scene\": 1, \"name\": \"g\", \"meshes\": [{\"file\": \"pbr.gltf\"}], " CAM "}", p,
               sizeof p);
    pm_scene_t s;
    if (pm_scene_load(p, &s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nmaterials, 5);
    const pm_material_t *m = material_named(&s, "metal");
    assert_int_equal(m->kind, PM_MAT_CONDUCTOR);
    assert_rgb(m->f0, 0.9f, 0.8f, 0.7f);
    assert_true(fabsf(m->alpha - 0.16f) < 1e-6f);
    m = material_named(&s, "plastic");
    assert_int_equal(m->kind, PM_MAT_PLASTIC);
    assert_rgb(m->kd, 0.5f, 0.4f, 0.3f);
    assert_true(fabsf(m->ior - 1.4f) < 1e-6f && fabsf(m->alpha - 0.04f) < 1e-6f);
    m = material_named(&s, "matte");
    assert_int_equal(m->kind, PM_MAT_STANDARD);
    assert_rgb(m->kd, 0.5f, 0.4f, 0.3f);
    assert_rgb(m->ks, 0, 0, 0);
    m = material_named(&s, "mix");
    assert_int_equal(m->kind, PM_MAT_PLASTIC);
    assert_rgb(m->kd, 0.35f, 0.35f, 0.35f);
    assert_non_null(reported(&s, "mix", "metallicFactor"));
    assert_non_null(strstr(reported(&s, "mix", "metallicFactor")->note, "rendered as plastic"));
    m = material_named(&s, "frosted");
    assert_int_equal(m->kind, PM_MAT_ROUGH_GLASS);
    assert_true(fabsf(m->alpha - 0.09f) < 1e-6f && fabsf(m->ior - 1.7f) < 1e-6f);
    assert_rgb(m->tf, 0.9f, 0.9f, 0.8f);
    /* honoured keys are not reported; the note is the only entry */
    assert_int_equal(s.nunsupported, 1);
    pm_scene_free(&s);

    write_gltf("bad.gltf", "{\"name\": \"x\", \"pbrMetallicRoughness\": {\"metallicFactor\": 1.5}}", 1, p, sizeof p);
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"bad.gltf\"}], " CAM "}",
                       "material 'x': metallicFactor 1.5 must lie in [0, 1]");
    write_gltf("bad.gltf", "{\"name\": \"x\", \"pbrMetallicRoughness\": {\"roughnessFactor\": -1}}", 1, p, sizeof p);
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"bad.gltf\"}], " CAM "}",
                       "material 'x': roughnessFactor -1 must lie in [0, 1]");
    write_gltf("bad.gltf",
               "{\"name\": \"x\", \"pbrMetallicRoughness\": {\"roughnessFactor\": 0.5}, \"extensions\": "
               "{\"KHR_materials_transmission\": {\"transmissionFactor\": 1}}}",
               1, p, sizeof p);
    expect_scene_error("{\"pmtk_scene\": 1, \"name\": \"x\", \"meshes\": [{\"file\": \"bad.gltf\"}], " CAM "}",
                       "metallicFactor 1 with roughnessFactor 0.5 a metal: it cannot be both");
}

/* Fields of pm_material_t by offset and float count, and which kinds read them. */
typedef struct {
    const char *name;
    size_t offset, n;
    unsigned kinds; /* bit k: kind k reads the field */
} mat_field_t;

#define K(k) (1u << (k))
#define FIELD(f, kinds)                                                                                                \
    {                                                                                                                  \
#f, offsetof(pm_material_t, f), sizeof((pm_material_t *)0)->f / sizeof(float), kinds                           \
    }
static const mat_field_t mat_fields[] = {
    FIELD(ke, 0x3fu),
    FIELD(kd, K(PM_MAT_STANDARD) | K(PM_MAT_PLASTIC)),
    FIELD(ks, K(PM_MAT_STANDARD)),
    FIELD(ns, K(PM_MAT_STANDARD)),
    FIELD(kr, K(PM_MAT_MIRROR)),
    FIELD(ior, K(PM_MAT_GLASS) | K(PM_MAT_ROUGH_GLASS) | K(PM_MAT_PLASTIC)),
    FIELD(tf, K(PM_MAT_GLASS) | K(PM_MAT_ROUGH_GLASS)),
    FIELD(alpha, K(PM_MAT_CONDUCTOR) | K(PM_MAT_ROUGH_GLASS) | K(PM_MAT_PLASTIC)),
    FIELD(f0, K(PM_MAT_CONDUCTOR)),
};

/* A material of kind `kind` whose every byte is first `fill`, then its name and the fields its
 * kind reads set to the same values whatever fill is (a glossy standard material, so that its
 * ns is read; a conductor by F0, so that eta and k are not). */
static void make_material(pm_material_t *m, int kind, unsigned char fill)
{
    memset(m, fill, sizeof *m);
    snprintf(m->name, sizeof m->name, "brass");
    m->kind = kind;
    m->two_sided = 0; /* read (for an emitter) like the kind */
    for (size_t f = 0; f < sizeof mat_fields / sizeof mat_fields[0]; f++)
        for (size_t i = 0; i < mat_fields[f].n; i++)
            ((float *)((char *)m + mat_fields[f].offset))[i] = 0.25f + 0.125f * (float)(f + i);
    m->eta[0] = 0.0f; /* a conductor of F0: eta[1], eta[2] and k are not read */
}

/* The scene identity's serialisation: two materials equal in every field their kind reads hash
 * the same whatever their other bytes (name after its end, padding, fields of other kinds);
 * changing any field a kind reads, the name or the kind changes the hash. Likewise lights: an
 * isotropic light's axis is not read, a spot's is. */
static void test_scene_identity_fields(void **state)
{
    for (int kind = PM_MAT_STANDARD; kind <= PM_MAT_PLASTIC; kind++) {
        pm_material_t a, b;
        make_material(&a, kind, 0x00);
        make_material(&b, kind, 0xa5);
        uint64_t h = pm_scene_materials_hash(&a, 1);
        if (pm_scene_materials_hash(&b, 1) != h)
            fail_msg("kind %d: unused bytes change the hash", kind);
        for (size_t f = 0; f < sizeof mat_fields / sizeof mat_fields[0]; f++)
            for (size_t i = 0; i < mat_fields[f].n; i++) {
                pm_material_t c = a;
                float *x = (float *)((char *)&c + mat_fields[f].offset) + i;
                *x = nextafterf(*x, 2.0f);
                int reads = (mat_fields[f].kinds >> kind) & 1;
                if (reads && pm_scene_materials_hash(&c, 1) == h)
                    fail_msg("kind %d: %s[%zu] changes and the hash does not", kind, mat_fields[f].name, i);
                if (!reads && pm_scene_materials_hash(&c, 1) != h)
                    fail_msg("kind %d: %s[%zu] is not read and changes the hash", kind, mat_fields[f].name, i);
            }
        pm_material_t c = a;
        c.name[0] = 'B';
        assert_true(pm_scene_materials_hash(&c, 1) != h);
        c = a;
        c.kind = kind == PM_MAT_PLASTIC ? PM_MAT_STANDARD : kind + 1;
        assert_true(pm_scene_materials_hash(&c, 1) != h);
        c = a; /* an emitter lighting from both faces is another light */
        c.two_sided = 1;
        assert_true(pm_scene_materials_hash(&c, 1) != h);
        c.ke[0] = c.ke[1] = c.ke[2] = 0.0f; /* not read where nothing is emitted */
        pm_material_t d = c;
        d.two_sided = 0;
        assert_true(pm_scene_materials_hash(&c, 1) == pm_scene_materials_hash(&d, 1));
    }
    /* a conductor by complex index reads eta and k, not f0 */
    pm_material_t a, b;
    make_material(&a, PM_MAT_CONDUCTOR, 0);
    a.eta[0] = a.eta[1] = a.eta[2] = 0.2f, a.k[0] = a.k[1] = a.k[2] = 3.0f;
    b = a;
    b.f0[1] = 0.9f;
    assert_true(pm_scene_materials_hash(&a, 1) == pm_scene_materials_hash(&b, 1));
    b = a;
    b.k[2] = 3.5f;
    assert_true(pm_scene_materials_hash(&a, 1) != pm_scene_materials_hash(&b, 1));
    /* a Lambertian standard material (ks 0) does not read ns */
    make_material(&a, PM_MAT_STANDARD, 0);
    a.ks[0] = a.ks[1] = a.ks[2] = 0.0f;
    b = a;
    b.ns = 77.0f;
    assert_true(pm_scene_materials_hash(&a, 1) == pm_scene_materials_hash(&b, 1));
    /* the order of materials and their number count */
    pm_material_t two[2], swapped[2];
    make_material(&two[0], PM_MAT_STANDARD, 0);
    make_material(&two[1], PM_MAT_PLASTIC, 0);
    swapped[0] = two[1], swapped[1] = two[0];
    assert_true(pm_scene_materials_hash(two, 2) != pm_scene_materials_hash(swapped, 2));
    assert_true(pm_scene_materials_hash(two, 2) != pm_scene_materials_hash(two, 1));

    pm_point_light_t l[2];
    memset(l, 0, sizeof l);
    l[0] = (pm_point_light_t){{1, 2, 3}, {4, 5, 6}, {0, 0, 0}, -1.0f, 0.0f};
    l[1] = l[0];
    l[1].axis[1] = 1.0f; /* not read: isotropic */
    assert_true(pm_scene_lights_hash(&l[0], 1) == pm_scene_lights_hash(&l[1], 1));
    l[1] = l[0];
    l[1].intensity[2] = 6.5f;
    assert_true(pm_scene_lights_hash(&l[0], 1) != pm_scene_lights_hash(&l[1], 1));
    l[0].cos_cone = l[1].cos_cone = 0.5f; /* spots: the axis is read */
    l[1] = l[0];
    l[1].axis[1] = 1.0f;
    assert_true(pm_scene_lights_hash(&l[0], 1) != pm_scene_lights_hash(&l[1], 1));
}

/* A loaded scene's identity is its content's: the same file loaded twice hashes the same; an
 * .mtl edit the renderer cannot see (Ns of a Lambertian material) leaves every part alone, a
 * Kd edit changes the geometry, photons and view parts, a camera move only the view's, a point
 * light's move only the photons'. */
static void test_scene_identity_parts(void **state)
{
    char p[256];
    pm_scene_t s[5];
    static const char *const mtl[] = {"newmtl w\nKd 0.5 0.5 0.5\n", "newmtl w\nKd 0.5 0.5 0.5\nNs 30\n",
                                      "newmtl w\nKd 0.5 0.5 0.6\n"};
    static const char *const json[] = {
        "{\"pmtk_scene\": 1, \"name\": \"id\", \"meshes\": [{\"file\": \"id.obj\"}], " CAM
        ", \"point_lights\": [{\"position\": [0, 1, 0], \"intensity\": [1, 1, 1]}]}",
        "{\"pmtk_scene\": 1, \"name\": \"id\", \"meshes\": [{\"file\": \"id.obj\"}], \"camera\": {\"eye\": "
        "[0,0,-2], \"look_at\": [0,0,0], \"fov_y\": 40, \"width\": 4, \"height\": 4}, \"point_lights\": "
        "[{\"position\": [0, 1, 0], \"intensity\": [1, 1, 1]}]}",
        "{\"pmtk_scene\": 1, \"name\": \"id\", \"meshes\": [{\"file\": \"id.obj\"}], " CAM
        ", \"point_lights\": [{\"position\": [0, 2, 0], \"intensity\": [1, 1, 1]}]}",
    };
    /* s[0]: the base; s[1]: Ns added; s[2]: Kd changed; s[3]: camera moved; s[4]: light moved */
    static const int use[5][2] = {{0, 0}, {1, 0}, {2, 0}, {0, 1}, {0, 2}};
    write_file("id.obj", "mtllib id.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl w\nf 1 2 3\n", p, sizeof p);
    for (int i = 0; i < 5; i++) {
        write_file("id.mtl", mtl[use[i][0]], p, sizeof p);
        write_file("id.json", json[use[i][1]], p, sizeof p);
        if (pm_scene_load(p, &s[i]) != PM_OK)
            fail_msg("%s", pm_error_message());
    }
    pm_scene_t again;
    write_file("id.mtl", mtl[0], p, sizeof p);
    write_file("id.json", json[0], p, sizeof p);
    assert_int_equal(pm_scene_load(p, &again), PM_OK);
    assert_true(again.hash == s[0].hash && again.parts.eye == s[0].parts.eye);
    pm_scene_free(&again);
    assert_true(s[1].parts.geometry == s[0].parts.geometry && s[1].parts.photons == s[0].parts.photons &&
                s[1].parts.view == s[0].parts.view);
    assert_true(s[2].parts.geometry != s[0].parts.geometry && s[2].parts.photons != s[0].parts.photons &&
                s[2].parts.view != s[0].parts.view);
    assert_true(s[3].parts.geometry == s[0].parts.geometry && s[3].parts.photons == s[0].parts.photons &&
                s[3].parts.view != s[0].parts.view && s[3].hash != s[0].hash);
    assert_true(s[4].parts.geometry == s[0].parts.geometry && s[4].parts.photons != s[0].parts.photons &&
                s[4].parts.view == s[0].parts.view && s[4].parts.eye != s[0].parts.eye);
    for (int i = 0; i < 5; i++)
        pm_scene_free(&s[i]);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_scene_cornell_box),
    cmocka_unit_test(test_scene_bad_input),
    cmocka_unit_test(test_scene_mesh_faults),
    cmocka_unit_test(test_scene_shapes),
    cmocka_unit_test(test_scene_degenerate_triangles),
    cmocka_unit_test(test_scene_unsupported),
    cmocka_unit_test(test_scene_unsupported_gltf),
    cmocka_unit_test(test_scene_pbr_mtl),
    cmocka_unit_test(test_scene_phong_formats_stay_phong),
    cmocka_unit_test(test_scene_pbr_gltf),
    cmocka_unit_test(test_scene_pbr_texture),
    cmocka_unit_test(test_scene_identity_fields),
    cmocka_unit_test(test_scene_identity_parts),
    cmocka_unit_test(test_scene_guarded_once),
};
UNIT_GROUP(unit_scene, "scene", tests);
