/* test_texture.c: image textures (render/texture.h): PNG, JPEG and OpenEXR decoding, sRGB,
 * bilinear filtering and repeat addressing at known texels; bad images refused; and through
 * the scene loader: map_Kd scaling Kd at a hit, map_d cutting holes that every ray passes,
 * missing textures (an error, or magenta on request), a glTF base colour texture. */
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <string.h>

/* after stdio.h: jpeglib.h uses FILE without including it */
#include <jpeglib.h>

#include "base/exr.h"
#include "render/rt.h"
#include "render/scene.h"
#include "render/texture.h"
#include "unit.h"

static void tmp_path(const char *name, char *out, size_t cap) { snprintf(out, cap, "%s/%s", unit_tmpdir(), name); }

static void write_text(const char *name, const char *text)
{
    char p[512];
    tmp_path(name, p, sizeof p);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* A PNG of w x h pixels in libpng's simplified format fmt (PNG_FORMAT_RGBA, _GA, _GRAY, ...). */
static void write_png(const char *name, uint32_t w, uint32_t h, uint32_t fmt, const uint8_t *px)
{
    char p[512];
    tmp_path(name, p, sizeof p);
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    im.width = w, im.height = h, im.format = fmt;
    assert_true(png_image_write_to_file(&im, p, 0, px, 0, NULL));
}

static int near(float a, float b, float tol) { return fabsf(a - b) <= tol; }

static void test_texture_png_lookup(void **state)
{
    (void)state;
    /* top row red, green; bottom row blue, white with alpha 0 */
    static const uint8_t px[16] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 0};
    write_png("q.png", 2, 2, PNG_FORMAT_RGBA, px);
    char p[512];
    tmp_path("q.png", p, sizeof p);
    pm_texture_t t;
    if (pm_texture_load(p, &t) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(t.w, 2);
    assert_true(t.has_alpha && !t.grey);
    float o[4];
    pm_texture_lookup(&t, 0.25f, 0.75f, 1, o); /* texel centre, top left: v goes up */
    assert_true(near(o[0], 1, 1e-6f) && near(o[1], 0, 1e-6f) && near(o[2], 0, 1e-6f) && near(o[3], 1, 1e-6f));
    pm_texture_lookup(&t, 0.75f, 0.25f, 1, o); /* bottom right */
    assert_true(near(o[0], 1, 1e-6f) && near(o[1], 1, 1e-6f) && near(o[3], 0, 1e-6f));
    pm_texture_lookup(&t, 0.5f, 0.5f, 1, o); /* the middle: the mean of all four */
    assert_true(near(o[0], 0.5f, 1e-6f) && near(o[1], 0.5f, 1e-6f) && near(o[2], 0.5f, 1e-6f) &&
                near(o[3], 0.75f, 1e-6f));
    pm_texture_lookup(&t, 0.5f, 0.75f, 1, o); /* between red and green on the top row */
    assert_true(near(o[0], 0.5f, 1e-6f) && near(o[1], 0.5f, 1e-6f) && near(o[2], 0.0f, 1e-6f));
    float r[4];
    pm_texture_lookup(&t, -1.75f, 3.75f, 1, r); /* repeat: the same point, whole periods away */
    pm_texture_lookup(&t, 0.25f, 0.75f, 1, o);
    assert_memory_equal(r, o, sizeof r);
    pm_texture_lookup(&t, 0.0f, 0.75f, 1, o); /* u = 0 is the left edge: half red, half green (wrapped) */
    assert_true(near(o[0], 0.5f, 1e-6f) && near(o[1], 0.5f, 1e-6f));
    pm_texture_lookup(&t, NAN, 0.5f, 1, o);
    assert_true(isfinite(o[0]) && isfinite(o[3]));
    pm_texture_free(&t);

    /* sRGB: code 128 is 0.2158605 linear; read as linear bytes it is 128/255 */
    static const uint8_t grey[1] = {128};
    write_png("g.png", 1, 1, PNG_FORMAT_GRAY, grey);
    tmp_path("g.png", p, sizeof p);
    assert_int_equal(pm_texture_load(p, &t), PM_OK);
    assert_true(t.grey && !t.has_alpha);
    pm_texture_lookup(&t, 0.3f, 0.3f, 1, o);
    assert_true(near(o[0], 0.2158605f, 1e-6f) && near(o[2], 0.2158605f, 1e-6f) && near(o[3], 1, 0));
    pm_texture_lookup(&t, 0.3f, 0.3f, 0, o);
    assert_true(near(o[0], 128.0f / 255.0f, 1e-6f));
    pm_texture_free(&t);
}

static void test_texture_jpeg_exr(void **state)
{
    (void)state;
    char p[512];
    /* TGA (Crytek Sponza's textures): 2 x 2, 24-bit BGR, rows stored bottom first (origin bit 0):
     * blue, white at the bottom; red, green at the top */
    static const uint8_t tga[18 + 12] = {0, 0,  2, 0,   0, 0, 0,   0,   0,   0, 0, 0,   2, 0,   2,
                                         0, 24, 0, 255, 0, 0, 255, 255, 255, 0, 0, 255, 0, 255, 0};
    tmp_path("c.TGA", p, sizeof p);
    FILE *tf = fopen(p, "wb");
    assert_non_null(tf);
    fwrite(tga, 1, sizeof tga, tf);
    fclose(tf);
    pm_texture_t tt;
    if (pm_texture_load(p, &tt) != PM_OK)
        fail_msg("%s", pm_error_message());
    float q[4];
    pm_texture_lookup(&tt, 0.25f, 0.75f, 1, q); /* top left: red */
    assert_true(q[0] == 1.0f && q[1] == 0.0f && q[2] == 0.0f && q[3] == 1.0f);
    pm_texture_lookup(&tt, 0.25f, 0.25f, 1, q); /* bottom left: blue */
    assert_true(q[0] == 0.0f && q[2] == 1.0f);
    pm_texture_lookup(&tt, 0.75f, 0.25f, 1, q); /* bottom right: white */
    assert_true(q[0] == 1.0f && q[1] == 1.0f && q[2] == 1.0f);
    assert_false(tt.has_alpha);
    pm_texture_free(&tt);

    tmp_path("c.jpg", p, sizeof p);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    struct jpeg_compress_struct ci;
    struct jpeg_error_mgr je;
    ci.err = jpeg_std_error(&je);
    jpeg_create_compress(&ci);
    jpeg_stdio_dest(&ci, f);
    ci.image_width = 16, ci.image_height = 16, ci.input_components = 3, ci.in_color_space = JCS_RGB;
    jpeg_set_defaults(&ci);
    jpeg_set_quality(&ci, 100, TRUE);
    jpeg_start_compress(&ci, TRUE);
    uint8_t row[48];
    for (int x = 0; x < 16; x++)
        row[3 * x] = 200, row[3 * x + 1] = 100, row[3 * x + 2] = 50;
    while (ci.next_scanline < 16) {
        JSAMPROW rp = row;
        jpeg_write_scanlines(&ci, &rp, 1);
    }
    jpeg_finish_compress(&ci);
    jpeg_destroy_compress(&ci);
    fclose(f);
    pm_texture_t t;
    if (pm_texture_load(p, &t) != PM_OK)
        fail_msg("%s", pm_error_message());
    float o[4];
    pm_texture_lookup(&t, 0.4f, 0.6f, 1, o);
    /* a flat colour survives JPEG within one code */
    assert_true(o[0] >= pm_srgb_to_linear(199) && o[0] <= pm_srgb_to_linear(201));
    assert_true(o[1] >= pm_srgb_to_linear(99) && o[1] <= pm_srgb_to_linear(101));
    assert_true(o[2] >= pm_srgb_to_linear(49) && o[2] <= pm_srgb_to_linear(51));
    pm_texture_free(&t);

    /* OpenEXR: linear floats kept as they are */
    static const float px[6] = {0.25f, 0.5f, 0.75f, 1.0f, 0.0f, 0.125f};
    tmp_path("e.exr", p, sizeof p);
    assert_int_equal(pm_exr_write_rgb(p, 2, 1, px, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    assert_int_equal(pm_texture_load(p, &t), PM_OK);
    pm_texture_lookup(&t, 0.25f, 0.5f, 1, o);
    assert_true(o[0] == 0.25f && o[1] == 0.5f && o[2] == 0.75f && o[3] == 1.0f);
    pm_texture_lookup(&t, 0.5f, 0.5f, 1, o);
    assert_true(near(o[0], 0.625f, 1e-6f) && near(o[2], 0.4375f, 1e-6f));
    pm_texture_free(&t);
    static const float hot[3] = {0.5f, 1.5f, 0.5f};
    assert_int_equal(pm_exr_write_rgb(p, 1, 1, hot, PM_EXR_FLOAT, PM_EXR_ZIP, NULL, 0), PM_OK);
    assert_int_equal(pm_texture_load(p, &t), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "pixel (0, 0) channel g = 1.5 is outside [0, 1]"));
}

/* A PNG claiming w x h pixels with an empty IDAT: the size is refused before anything is
 * decoded (and a legal size fails for want of data). */
static void write_png_header(const char *name, uint32_t w, uint32_t h)
{
    uint8_t b[45] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R'};
    static const uint8_t idat[12] = {0, 0, 0, 0, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e};
    memcpy(b + 33, idat, sizeof idat);
    for (int i = 0; i < 4; i++)
        b[16 + i] = (uint8_t)(w >> (24 - 8 * i)), b[20 + i] = (uint8_t)(h >> (24 - 8 * i));
    b[24] = 8, b[25] = 2;       /* 8-bit RGB */
    uint32_t crc = 0xffffffffu; /* CRC-32 of the chunk type and data, as PNG asks */
    for (int i = 12; i < 29; i++) {
        crc ^= b[i];
        for (int k = 0; k < 8; k++)
            crc = crc & 1 ? (crc >> 1) ^ 0xedb88320u : crc >> 1;
    }
    crc ^= 0xffffffffu;
    for (int i = 0; i < 4; i++)
        b[29 + i] = (uint8_t)(crc >> (24 - 8 * i));
    char p[512];
    tmp_path(name, p, sizeof p);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    fwrite(b, 1, sizeof b, f);
    fclose(f);
}

static void expect_texture_error(const char *name, const char *needle)
{
    char p[512];
    tmp_path(name, p, sizeof p);
    pm_texture_t t;
    assert_int_equal(pm_texture_load(p, &t), PM_ERR_INPUT);
    if (!strstr(pm_error_message(), needle))
        fail_msg("message '%s' lacks '%s'", pm_error_message(), needle);
    assert_null(t.u8);
    assert_null(t.f32);
}

static void test_texture_bad_images(void **state)
{
    (void)state;
    expect_texture_error("none.png", "cannot open texture");
    write_text("t.tga", ""); /* empty */
    expect_texture_error("t.tga", "truncated TGA: 0 bytes");
    write_text("t.bmp", "BM not really");
    expect_texture_error("t.bmp", "a BMP image");
    write_text("t.xyz", "not an image");
    expect_texture_error("t.xyz", "not a PNG, JPEG, OpenEXR or (named .tga) TGA image");
    write_png_header("wide.png", 70000, 1);
    expect_texture_error("wide.png", "70000 x 1 pixels: each side must be 1 to 65536");
    write_png_header("tall.png", 1, 65537);
    expect_texture_error("tall.png", "1 x 65537 pixels");
    write_png_header("empty.png", 0, 0); /* libpng itself refuses a zero side */
    expect_texture_error("empty.png", "texture '");
    write_png_header("cut.png", 4, 4); /* a header and no image data */
    expect_texture_error("cut.png", "libpng");
}

#define CAM "\"camera\": {\"eye\": [0.5,0.5,3], \"look_at\": [0.5,0.5,0], \"fov_y\": 40, \"width\": 4, \"height\": 4}"

/* A unit quad in z = 0 with texture coordinates equal to x and y, material "stone" with the
 * MTL lines mtl_extra, in a scene whose top level adds json_extra; *s loaded (result returned). */
static pm_result_t textured_quad(const char *mtl_extra, const char *json_extra, pm_scene_t *s)
{
    char mtl[512], json[1024], p[512];
    snprintf(mtl, sizeof mtl, "newmtl stone\nKd 0.8 0.6 0.4\n%s", mtl_extra);
    write_text("quad.mtl", mtl);
    write_text("quad.obj", "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                           "usemtl stone\nf 1/1 2/2 3/3 4/4\n"
                           /* a floor behind, untextured, to see through the holes */
                           "v -5 -5 -1\nv 5 -5 -1\nv 5 5 -1\nv -5 5 -1\nusemtl floor\nf 5 6 7 8\n");
    FILE *f = fopen((tmp_path("quad.mtl", p, sizeof p), p), "a");
    assert_non_null(f);
    fputs("\nnewmtl floor\nKd 0.5 0.5 0.5\n", f);
    fclose(f);
    snprintf(json, sizeof json, "{\"pmtk_scene\": 1, \"name\": \"quad\", \"meshes\": [{\"file\": \"quad.obj\"}], %s%s}",
             CAM, json_extra);
    write_text("quad.json", json);
    tmp_path("quad.json", p, sizeof p);
    return pm_scene_load(p, s);
}

static uint32_t cast_down(const pm_rt_t *rt, float x, float y, float *t_out)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    const float o[3] = {x, y, 2}, d[3] = {0, 0, -1};
    return pm_rt_intersect1(rt, &ctx, o, d, 0.0f, INFINITY, t_out, NULL);
}

static void test_texture_scene(void **state)
{
    (void)state;
    /* map_Kd: left column white, right column sRGB 128 grey; map_d: left half opaque, right cut */
    static const uint8_t kd[4] = {255, 128, 255, 128}, mask[2] = {255, 0};
    write_png("kd map.png", 2, 2, PNG_FORMAT_GRAY, kd);
    write_png("mask.png", 2, 1, PNG_FORMAT_GRAY, mask);
    pm_scene_t s;
    pm_result_t r = textured_quad("map_Kd kd map.png\nmap_d mask.png\n", "", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_non_null(s.maps);
    assert_int_equal(s.ntextures, 2);
    assert_true(s.any_alpha);
    uint32_t stone = 0;
    while (strcmp(s.materials[s.tri_material[stone]].name, "stone") != 0)
        stone++;
    pm_material_t scratch;
    const float left[3] = {0.2f, 0.5f, 0}, right[3] = {0.8f, 0.5f, 0};
    uint32_t tl = stone, tr = stone + 1; /* the quad's two triangles: find the one under each point */
    float b[2];
    pm_scene_barycentrics(&s, tl, left, b);
    if (b[0] + b[1] >= 1.0f || b[0] <= 0.0f || b[1] <= 0.0f)
        tl = stone + 1, tr = stone;
    const pm_material_t *m = pm_scene_material_at(&s, tl, left, &scratch);
    /* u = 0.2: 0.9 of the white column and 0.1 of the grey one (bilinear, wrapped at u = 0) */
    float w = 0.9f * 1.0f + 0.1f * 0.2158605f;
    if (!(near(m->kd[0], 0.8f * w, 1e-4f) && near(m->kd[1], 0.6f * w, 1e-4f) && near(m->kd[2], 0.4f * w, 1e-4f)))
        fail_msg("kd at u 0.2: %g %g %g, expected %g %g %g", m->kd[0], m->kd[1], m->kd[2], 0.8f * w, 0.6f * w,
                 0.4f * w);
    m = pm_scene_material_at(&s, tr, right, &scratch);
    w = 0.1f * 1.0f + 0.9f * 0.2158605f;
    assert_true(near(m->kd[0], 0.8f * w, 1e-4f));

    /* the cut-out: a ray at x 0.1 stops on the quad (t 2), one at x 0.9 goes on to the floor (t 3) */
    pm_rt_t rt;
    assert_int_equal(pm_rt_create(&s, 0, 1, &rt), PM_OK);
    float t;
    assert_int_not_equal(cast_down(&rt, 0.1f, 0.5f, &t), PM_RAY_MISS);
    assert_true(near(t, 2.0f, 1e-5f));
    assert_int_not_equal(cast_down(&rt, 0.9f, 0.5f, &t), PM_RAY_MISS);
    assert_true(near(t, 3.0f, 1e-5f));
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    const float o1[3] = {0.1f, 0.5f, 2}, o2[3] = {0.9f, 0.5f, 2}, d[3] = {0, 0, -1};
    assert_true(pm_rt_occluded1(&rt, &ctx, o1, d, 0.0f, 2.5f)); /* shadow rays too */
    assert_false(pm_rt_occluded1(&rt, &ctx, o2, d, 0.0f, 2.5f));
    pm_rt_destroy(&rt);
    uint64_t hash = s.hash;
    pm_scene_free(&s);

    /* the scene's hash covers the texels: one changed texel changes it */
    static const uint8_t kd2[4] = {255, 128, 255, 127};
    write_png("kd map.png", 2, 2, PNG_FORMAT_GRAY, kd2);
    assert_int_equal(textured_quad("map_Kd kd map.png\nmap_d mask.png\n", "", &s), PM_OK);
    assert_true(s.hash != hash);
    pm_scene_free(&s);

    /* untextured: no tables, the material itself returned */
    assert_int_equal(textured_quad("", "", &s), PM_OK);
    assert_null(s.maps);
    assert_null(s.uvs);
    assert_int_equal(s.ntextures, 0);
    assert_true(pm_scene_material_at(&s, 0, left, &scratch) == &s.materials[s.tri_material[0]]);
    pm_scene_free(&s);
}

static void test_texture_missing(void **state)
{
    (void)state;
    pm_scene_t s;
    assert_int_equal(textured_quad("map_Kd gone/no such.png\n", "", &s), PM_ERR_INPUT);
    const char *msg = pm_error_message();
    if (!strstr(msg, "material 'stone': map_Kd 'gone/no such.png': cannot open texture") || !strstr(msg, "quad.obj"))
        fail_msg("message '%s'", msg);
    assert_int_equal(textured_quad("map_Kd gone.png\n", ", \"missing_textures\": \"purple\"", &s), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "missing_textures: must be \"error\""));
    pm_result_t r = textured_quad("map_Kd gone.png\n", ", \"missing_textures\": \"magenta\"", &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    pm_material_t scratch;
    const float p[3] = {0.5f, 0.5f, 0};
    uint32_t t = 0;
    while (strcmp(s.materials[s.tri_material[t]].name, "stone") != 0)
        t++;
    const pm_material_t *m = pm_scene_material_at(&s, t, p, &scratch);
    assert_true(m->kd[0] == 0.8f && m->kd[1] == 0.0f && m->kd[2] == 0.4f);
    assert_int_equal(s.nunsupported, 1);
    assert_true(s.unsupported[0].missing);
    assert_string_equal(s.unsupported[0].key, "map_Kd");
    pm_scene_free(&s);
}

/* glTF's base colour texture scales baseColorFactor (the mesh has no texture coordinates:
 * every point reads texel (0, 0) of a one-texel image). */
static void test_texture_gltf(void **state)
{
    (void)state;
    static const uint8_t px[3] = {255, 128, 0};
    write_png("base.png", 1, 1, PNG_FORMAT_RGB, px);
    write_text("b.gltf",
               "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": "
               "[{\"mesh\": 0}], \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 1, "
               "\"material\": 0}]}], \"materials\": [{\"name\": \"m\", \"pbrMetallicRoughness\": {\"baseColorFactor\": "
               "[0.5, 0.4, 0.3, 1], \"metallicFactor\": 0, \"baseColorTexture\": {\"index\": 0}}}], "
               "\"textures\": [{\"source\": 0}], \"images\": [{\"uri\": \"base.png\"}], "
               "\"buffers\": [{\"byteLength\": 44, \"uri\": \"data:application/octet-stream;base64,"
               "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/AAABAAIAAAA=\"}], \"bufferViews\": [{\"buffer\": 0, "
               "\"byteOffset\": 0, \"byteLength\": 36}, {\"buffer\": 0, \"byteOffset\": 36, \"byteLength\": 6}], "
               "\"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\", "
               "\"min\": [0, 0, 0], \"max\": [1, 0, 1]}, {\"bufferView\": 1, \"componentType\": 5123, \"count\": 3, "
               "\"type\": \"SCALAR\"}]}\n");
    write_text("b.json", "{\"pmtk_scene\": 1, \"name\": \"b\", \"meshes\": [{\"file\": \"b.gltf\"}], " CAM "}");
    char p[512];
    tmp_path("b.json", p, sizeof p);
    pm_scene_t s;
    pm_result_t r = pm_scene_load(p, &s);
    if (r != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(s.nunsupported, 1); /* the mesh has no texture coordinates: said so */
    assert_string_equal(s.unsupported[0].key, "texture coordinates");
    pm_material_t scratch;
    const float q[3] = {0.2f, 0, 0.2f};
    const pm_material_t *m = pm_scene_material_at(&s, 0, q, &scratch);
    assert_true(near(m->kd[0], 0.5f, 1e-6f) && near(m->kd[1], 0.4f * 0.2158605f, 1e-6f) && m->kd[2] == 0.0f);
    pm_scene_free(&s);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_texture_png_lookup), cmocka_unit_test(test_texture_jpeg_exr),
    cmocka_unit_test(test_texture_bad_images), cmocka_unit_test(test_texture_scene),
    cmocka_unit_test(test_texture_missing),    cmocka_unit_test(test_texture_gltf),
};
UNIT_GROUP(unit_texture, "texture", tests);
