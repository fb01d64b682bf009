/* test_light.c: the light module (render/light.h) against its own definitions and closed forms.
 *
 * The set: which lights it holds for emission and for next-event estimation, their powers
 * against pm_scene_power, light choice in proportion to power. Direct light: each kind's
 * sample_li against its pdf_li (the pdf a ray that finds the light would be weighted with),
 * and the mean of Li cos / pdf against the irradiance by quadrature; the area sampler's
 * triangles by area and points uniform on them; a point light's distance and 1/r^2. Emission:
 * sample_le's flux averages to the light's power, a triangle's directions are cosine-weighted
 * (chi-square), a spot's, the sun's and the sky's directions follow their pdfs (chi-square)
 * and those pdfs integrate to 1, a sky map's sampler follows its pixels. Portals: sun and sky
 * photons start on them by area, carry flux only inward, and average to the power through
 * them. The random numbers are Philox streams of fixed seeds, so every run draws the same
 * samples. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "render/light.h"
#include "unit.h"

/* A frame (t, b, a) about unit axis a. */
typedef struct {
    float t[3], b[3], a[3];
} frame_t;

static frame_t frame_about(const float a[3])
{
    frame_t f;
    pm_vec3_t t, b, av = pm_v3_normalize(pm_v3_load(a));
    pm_onb(av, &t, &b);
    pm_v3_store(f.t, t), pm_v3_store(f.b, b), pm_v3_store(f.a, av);
    return f;
}

/* The unit direction at cosine c to f's axis and azimuth phi. */
static void dir_in(const frame_t *f, double c, double phi, float d[3])
{
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    for (int k = 0; k < 3; k++)
        d[k] = (float)(s * cos(phi) * f->t[k] + s * sin(phi) * f->b[k] + c * f->a[k]);
}

/* The bound on chi-square: mean plus 5 standard deviations of a chi-square of dof degrees. */
static void check_chi2(const char *name, const char *what, double chi2, int dof)
{
    double bound = dof + 5.0 * sqrt(2.0 * dof);
    if (!(chi2 <= bound))
        fail_msg("%s, %s: chi-square %.1f over %d degrees of freedom (bound %.1f)", name, what, chi2, dof, bound);
}

/* A hand-made scene: up to four triangles (two emissive ones in the plane z = 1 facing down, of
 * areas 0.5 and 1.5 m^2, legs 1 by 1 and 1 by 3; or a square of side 2 m centred above the
 * origin at height 1), point lights, a sun, a sky, bounds [-2, 3] x [-2, 3] x [-1, 2]. */
typedef struct {
    pm_scene_t s;
    float verts[3 * 6];
    uint32_t tris[3 * 2], mat[2], emissive[2];
    pm_material_t lamp;
    pm_point_light_t lights[3];
} light_scene_t;

static void light_scene(light_scene_t *ls, int square)
{
    memset(ls, 0, sizeof *ls);
    static const float two[] = {0, 0, 1, 0, 1, 1, 1, 0, 1,  /* triangle 0: right angle at (0, 0) */
                                2, 0, 1, 2, 3, 1, 3, 0, 1}; /* triangle 1: right angle at (2, 0) */
    static const float sq[] = {-1, -1, 1, -1, 1, 1, 1, 1, 1, 1, -1, 1};
    ls->lamp.ke[0] = 1.0f, ls->lamp.ke[1] = 2.0f, ls->lamp.ke[2] = 0.5f;
    if (!square) {
        memcpy(ls->verts, two, sizeof two);
        for (uint32_t i = 0; i < 6; i++)
            ls->tris[i] = i;
        ls->s.nverts = 6;
    } else {
        memcpy(ls->verts, sq, sizeof sq);
        const uint32_t t[] = {0, 1, 2, 0, 2, 3};
        memcpy(ls->tris, t, sizeof t);
        ls->s.nverts = 4;
    }
    ls->s.ntris = ls->s.nemissive = 2;
    ls->emissive[0] = 0, ls->emissive[1] = 1;
    ls->s.verts = ls->verts, ls->s.tris = ls->tris, ls->s.tri_material = ls->mat, ls->s.emissive = ls->emissive;
    ls->s.materials = &ls->lamp, ls->s.nmaterials = 1;
    ls->s.lights = ls->lights;
    const float lo[3] = {-2, -2, -1}, hi[3] = {3, 3, 2};
    memcpy(ls->s.bounds, lo, sizeof lo), memcpy(ls->s.bounds + 3, hi, sizeof hi);
    strcpy(ls->s.name, "light-test");
}

static void add_point(light_scene_t *ls, float x, float y, float z, float i)
{
    pm_point_light_t *l = &ls->lights[ls->s.nlights++];
    memset(l, 0, sizeof *l);
    l->position[0] = x, l->position[1] = y, l->position[2] = z;
    l->intensity[0] = i, l->intensity[1] = 2.0f * i, l->intensity[2] = 3.0f * i;
    l->cos_cone = -1.0f;
}

static void add_spot(light_scene_t *ls, float cone_deg, float falloff)
{
    add_point(ls, 0.5f, 0.5f, 0.9f, 4.0f);
    pm_point_light_t *l = &ls->lights[ls->s.nlights - 1];
    l->axis[2] = -1.0f;
    l->cos_cone = cosf(cone_deg * PM_PI / 180.0f), l->falloff = falloff;
}

static void add_sun(light_scene_t *ls, float omega)
{
    static const float dir[3] = {0.36f, -0.48f, 0.8f};
    ls->s.has_sun = 1;
    memcpy(ls->s.sun.direction, dir, sizeof dir);
    ls->s.sun.radiance[0] = 100.0f, ls->s.sun.radiance[1] = 90.0f, ls->s.sun.radiance[2] = 80.0f;
    ls->s.sun.solid_angle = omega, ls->s.sun.cos_max = 1.0f - omega / (2.0f * PM_PI);
}

static void add_sky(light_scene_t *ls)
{
    ls->s.has_sky = 1;
    ls->s.sky[0] = 1.0f, ls->s.sky[1] = 1.5f, ls->s.sky[2] = 2.0f;
}

/* A 16 x 8 sky map of uneven luminance (a hot pixel at 50 times the rest, a black row). */
static pm_envmap_t *make_map(void)
{
    enum { W = 16, H = 8 };
    float *rgb = malloc(W * H * 3 * sizeof(float));
    pm_envmap_t *e = calloc(1, sizeof *e);
    assert_non_null(rgb);
    assert_non_null(e);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int k = 0; k < 3; k++)
                rgb[3 * (y * W + x) + k] = y == 5 ? 0.0f : (float)(1 + (x * 7 + y * 3) % 5) * (k == 1 ? 1.0f : 0.5f);
    for (int k = 0; k < 3; k++)
        rgb[3 * (2 * W + 11) + k] *= 50.0f;
    assert_int_equal(pm_envmap_init(e, W, H, rgb), PM_OK);
    return e;
}

/* ---- the set ---- */

/* What the set holds: zero-power lights out of emission but in the direct list, the direct
 * list's order (delta lights first, the triangles as one), the counts scene-info prints, the
 * total power pm_scene_power's, and light choice in proportion to power (chi-square of 200,000
 * picks over the five lights). */
static void test_light_set(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    add_point(&ls, 0.5f, 0.5f, 0.5f, 1.0f);
    add_point(&ls, 0.5f, 0.5f, 0.5f, 0.0f); /* dark: no photons, still a direct light */
    add_spot(&ls, 30.0f, 1.0f);
    add_sun(&ls, 0.05f);
    add_sky(&ls);
    pm_lights_t L;
    assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
    assert_int_equal(L.n, 6); /* 2 point lights of power, 2 triangles, sun, sky */
    assert_int_equal(L.ndirect, 6);
    assert_int_equal(L.ndelta, 3);
    assert_int_equal(L.nlights, 7);
    assert_int_equal(pm_lights_sampled(&L), 4);
    assert_true(pm_lights_has_emitters(&L));
    const pm_light_kind_t want[6] = {PM_LIGHT_POINT, PM_LIGHT_SPOT, PM_LIGHT_AREA,
                                     PM_LIGHT_AREA,  PM_LIGHT_SUN,  PM_LIGHT_SKY};
    for (size_t i = 0; i < L.n; i++)
        if (L.light[i].kind != want[i])
            fail_msg("light %zu is a %s, not a %s", i, pm_light_kind_name(L.light[i].kind),
                     pm_light_kind_name(want[i]));
    assert_true(L.direct[1].kind == PM_LIGHT_POINT && L.direct[1].weight == 0.0);
    assert_true(L.direct[3].kind == PM_LIGHT_AREA && L.direct[3].delta == 0 && L.direct[3].infinite == 0);
    assert_true(L.direct[4].infinite && L.direct[5].infinite && L.direct[0].delta);
    assert_true(fabs(L.area - 2.0) < 1e-9);
    /* The area light of the direct list carries the triangles' power: pi Ke A. */
    assert_true(fabs(L.direct[3].power[1] - M_PI * 2.0 * 2.0) < 1e-9);
    double p[3], sum = 0.0;
    pm_scene_power(&ls.s, p);
    for (size_t i = 0; i < L.n; i++)
        sum += L.light[i].weight;
    if (!(fabs(sum / (p[0] + p[1] + p[2]) - 1.0) < 1e-12 && fabs(L.total / sum - 1.0) < 1e-12))
        fail_msg("the set's power %.9g W, the scene's %.9g W", sum, p[0] + p[1] + p[2]);

    long picks[6] = {0};
    pm_rng_t rng;
    pm_rng_init(&rng, 3, 0);
    const int n = 200000;
    for (int i = 0; i < n; i++)
        picks[pm_lights_pick(&L, pm_rng_double(&rng))]++;
    double chi2 = 0.0;
    for (size_t i = 0; i < L.n; i++) {
        double e = n * L.light[i].weight / L.total;
        chi2 += (picks[i] - e) * (picks[i] - e) / e;
    }
    check_chi2("light choice", "picks", chi2, (int)L.n - 1);
    pm_lights_free(&L);

    /* A scene without lights: an empty set, nothing to pick. */
    light_scene(&ls, 0);
    ls.s.nemissive = 0;
    assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
    assert_true(L.n == 0 && L.ndirect == 0 && L.nlights == 0 && !pm_lights_has_emitters(&L));
    pm_lights_free(&L);
}

/* ---- direct light ---- */

/* The area sampler: the triangle in proportion to its area (0.25 and 0.75, within 5 binomial
 * standard deviations of 200,000 picks), the point uniform on it (chi-square over an 8 x 8 grid
 * of its legs, the cells on the hypotenuse expecting half), the distance and cosines of each
 * sample consistent with the point, Li the lamp's Ke, and the pdf pm_lights_pdf_li_hit gives for
 * that point (the weight a ray finding it gets). */
static void test_light_area_uniform(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    pm_lights_t L;
    assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
    assert_int_equal(L.ndirect, 1);
    enum { K = 8 };
    double cells[2][K][K];
    memset(cells, 0, sizeof cells);
    const float p[3] = {1.0f, 0.5f, 0.0f}, up[3] = {0.0f, 0.0f, 1.0f};
    pm_rng_t rng;
    pm_rng_init(&rng, 5, 0);
    const int n = 200000;
    int picks[2] = {0, 0};
    for (int i = 0; i < n; i++) {
        pm_light_li_t s;
        assert_int_equal(pm_lights_sample_li(&L, 0, &rng, p, up, &s), 1);
        assert_true(!s.delta && !s.infinite);
        float y[3];
        for (int k = 0; k < 3; k++)
            y[k] = p[k] + s.wi[k] * s.r;
        int tri = y[0] > 1.5f;
        picks[tri]++;
        assert_true(fabsf(y[2] - 1.0f) < 1e-5f);
        assert_true(fabsf(s.r2 - s.r * s.r) <= 1e-6f * s.r2);
        assert_true(fabsf(s.cosx - s.wi[2]) < 1e-6f && fabsf(s.cosy - s.wi[2]) < 1e-6f);
        assert_true(s.Li[0] == 1.0f && s.Li[1] == 2.0f && s.Li[2] == 0.5f);
        float ph = pm_lights_pdf_li_hit(&L, s.r, s.cosy);
        if (!(fabsf(ph / s.pdf - 1.0f) < 1e-5f))
            fail_msg("sample %d: sample_li's pdf %g, pdf_li's %g", i, s.pdf, ph);
        /* legs: triangle 0 spans x in [0, 1], y in [0, 1]; triangle 1 x in [2, 3], y in [0, 3] */
        double u = tri == 0 ? y[0] : y[0] - 2.0, v = tri == 0 ? y[1] : y[1] / 3.0;
        int cu = (int)(u * K), cv = (int)(v * K);
        cu = cu < 0 ? 0 : cu >= K ? K - 1 : cu, cv = cv < 0 ? 0 : cv >= K ? K - 1 : cv;
        assert_true(cu + cv <= K); /* inside the triangle: u + v <= 1, to rounding */
        cells[tri][cu][cv]++;
    }
    for (int t = 0; t < 2; t++) {
        double frac = (double)picks[t] / n, want = t == 0 ? 0.25 : 0.75;
        if (fabs(frac - want) > 5.0 * sqrt(want * (1.0 - want) / n))
            fail_msg("triangle %d (area %g m^2 of 2) picked %.4f of the time", t, want * 2.0, frac);
        double chi2 = 0.0;
        int bins = 0;
        for (int a = 0; a < K; a++)
            for (int b = 0; b < K; b++) {
                if (a + b > K - 1) {
                    assert_true(cells[t][a][b] < 1e-3 * picks[t]); /* outside but for rounding */
                    continue;
                }
                double e = picks[t] * (a + b == K - 1 ? 0.5 : 1.0) / (K * K / 2.0);
                chi2 += (cells[t][a][b] - e) * (cells[t][a][b] - e) / e;
                bins++;
            }
        check_chi2(t == 0 ? "triangle 0" : "triangle 1", "points", chi2, bins - 1);
    }
    /* From behind the lamp (above it) nothing; nor from a surface facing away. */
    const float above[3] = {1.0f, 0.5f, 2.0f}, down[3] = {0.0f, 0.0f, -1.0f};
    pm_light_li_t s;
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, above, down, &s), 0);
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, p, down, &s), 0);
    /* Two-sided lamps light from above too. */
    ls.s.two_sided_lights = 1;
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, above, down, &s), 1);
    pm_lights_free(&L);
}

/* The irradiance each sampled kind gives a surface, as the mean of Li cos / pdf over 100,000
 * samples, against quadrature of the light's own radiance (pm_lights_le_escape_one for the sun
 * and the sky, Ke cos cos / r^2 over the lamp's area for the square): a pdf that did not match
 * its sampler would be off by far more than the bound of 1.5%. Each sample's pdf must also be
 * the pdf_li a ray finding the light would be weighted with. */
static void test_light_sample_li_vs_pdf_li(void **state)
{
    (void)state;
    const float n[3] = {0.0f, 0.0f, 1.0f}, p[3] = {0.0f, 0.0f, 0.0f};
    for (int kind = 0; kind < 4; kind++) { /* the square lamp, the sun, a constant sky, a map */
        light_scene_t ls;
        light_scene(&ls, 1);
        if (kind > 0)
            ls.s.nemissive = 0;
        if (kind == 1)
            add_sun(&ls, 0.3f);
        if (kind >= 2)
            add_sky(&ls);
        if (kind == 3)
            ls.s.envmap = make_map();
        pm_lights_t L;
        assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
        assert_int_equal(L.ndirect, 1);
        pm_rng_t rng;
        pm_rng_init(&rng, 11, (uint64_t)kind);
        const int ns = 100000;
        double est[3] = {0, 0, 0};
        for (int i = 0; i < ns; i++) {
            pm_light_li_t s;
            if (!pm_lights_sample_li(&L, 0, &rng, p, n, &s))
                continue;
            float pl = s.infinite ? pm_lights_pdf_li_escape(&L, 0, n, s.wi) : pm_lights_pdf_li_hit(&L, s.r, s.cosy);
            if (!(fabsf(pl / s.pdf - 1.0f) < 1e-4f))
                fail_msg("kind %d, sample %d: sample_li's pdf %g, pdf_li's %g", kind, i, s.pdf, pl);
            if (s.infinite) {
                float le[3];
                pm_lights_le_escape_one(&L, 0, s.wi, le);
                assert_true(le[0] == s.Li[0] && le[1] == s.Li[1] && le[2] == s.Li[2]);
                assert_true(isinf(pm_light_shadow_tmax(&s, 1e-4f)));
            }
            for (int k = 0; k < 3; k++)
                est[k] += s.Li[k] * s.cosx / s.pdf / ns;
        }
        double want[3] = {0, 0, 0};
        if (kind == 0) { /* over the square's area: Ke cos^2 / r^2, cos = 1 / r at height 1 */
            const int g = 400;
            for (int a = 0; a < g; a++)
                for (int b = 0; b < g; b++) {
                    double x = -1.0 + 2.0 * (a + 0.5) / g, y = -1.0 + 2.0 * (b + 0.5) / g, r2 = x * x + y * y + 1.0;
                    for (int k = 0; k < 3; k++)
                        want[k] += ls.lamp.ke[k] / (r2 * r2) * (4.0 / (g * g));
                }
        } else { /* over the upper hemisphere: Le cos */
            frame_t f = frame_about(n);
            const int nc = 2000, nphi = 2000;
            for (int a = 0; a < nc; a++)
                for (int b = 0; b < nphi; b++) {
                    float w[3], le[3];
                    double c = (a + 0.5) / nc;
                    dir_in(&f, c, 2.0 * M_PI * (b + 0.5) / nphi, w);
                    pm_lights_le_escape_one(&L, 0, w, le);
                    for (int k = 0; k < 3; k++)
                        want[k] += le[k] * c * (1.0 / nc) * (2.0 * M_PI / nphi);
                }
        }
        for (int k = 0; k < 3; k++)
            if (!(fabs(est[k] / want[k] - 1.0) < 0.015))
                fail_msg("kind %d, channel %d: irradiance %.6g W/m^2 by sample_li, %.6g by quadrature", kind, k, est[k],
                         want[k]);
        pm_lights_free(&L);
        if (ls.s.envmap) {
            pm_envmap_free(ls.s.envmap);
            free(ls.s.envmap);
        }
    }
}

/* A point light and a spot: direction, distance, I s / r^2 as Li, a delta of pdf 1, a shadow ray
 * that stops short of the light; nothing from behind, from the light's own position, or
 * outside the cone. */
static void test_light_point(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    ls.s.nemissive = 0;
    add_point(&ls, 1.0f, 2.0f, 3.0f, 9.0f);
    add_spot(&ls, 30.0f, 2.0f); /* at (0.5, 0.5, 0.9) pointing down */
    pm_lights_t L;
    assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
    assert_int_equal(L.ndirect, 2);
    assert_int_equal(pm_lights_sampled(&L), 0);
    const float p[3] = {0.0f, 0.0f, 1.0f}, up[3] = {0.0f, 0.0f, 1.0f}, down[3] = {0.0f, 0.0f, -1.0f};
    pm_rng_t rng;
    pm_rng_init(&rng, 1, 0);
    pm_light_li_t s;
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, p, up, &s), 1);
    assert_true(s.delta && !s.infinite && s.pdf == 1.0f);
    assert_true(fabsf(s.r - 3.0f) < 1e-6f);
    assert_true(fabsf(s.wi[0] - 1.0f / 3) < 1e-6f && fabsf(s.wi[1] - 2.0f / 3) < 1e-6f &&
                fabsf(s.wi[2] - 2.0f / 3) < 1e-6f);
    assert_true(fabsf(s.cosx - 2.0f / 3) < 1e-6f);
    assert_true(fabsf(s.Li[0] - 1.0f) < 1e-6f && fabsf(s.Li[2] - 3.0f) < 1e-6f); /* 9 / 9, 27 / 9 */
    assert_true(fabsf(pm_light_shadow_tmax(&s, 1e-3f) - (3.0f - 1e-3f)) < 1e-6f);
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, p, down, &s), 0); /* behind the surface */
    const float at[3] = {1.0f, 2.0f, 3.0f};
    assert_int_equal(pm_lights_sample_li(&L, 0, &rng, at, up, &s), 0); /* at the point */
    /* The spot: straight below it on the axis s = 1; at 45 degrees outside its 30-degree cone. */
    const float below[3] = {0.5f, 0.5f, 0.0f}, aside[3] = {1.4f, 0.5f, 0.0f};
    assert_int_equal(pm_lights_sample_li(&L, 1, &rng, below, up, &s), 1);
    assert_true(fabsf(s.Li[0] - 4.0f / (0.9f * 0.9f)) < 1e-4f);
    assert_int_equal(pm_lights_sample_li(&L, 1, &rng, aside, up, &s), 0);
    /* Delta lights draw no random numbers. */
    pm_rng_t before = rng;
    pm_lights_sample_li(&L, 0, &rng, p, up, &s);
    assert_memory_equal(&before, &rng, sizeof rng);
    pm_lights_free(&L);
}

/* What a ray that hits an emitter or escapes sees: the front face only (dot 0 counts as the
 * front), both with two-sided lights; the sun within its cone on top of the sky. */
static void test_light_le(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    add_sun(&ls, 0.05f);
    add_sky(&ls);
    pm_lights_t L;
    assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
    float le[3], c;
    assert_int_equal(pm_lights_le_hit(&L, 0, 0.5f, le, &c), 1);
    assert_true(le[1] == 2.0f && c == 0.5f);
    assert_int_equal(pm_lights_le_hit(&L, 0, 0.0f, le, &c), 1);
    assert_int_equal(pm_lights_le_hit(&L, 0, -0.5f, le, &c), 0);
    ls.s.two_sided_lights = 1;
    assert_int_equal(pm_lights_le_hit(&L, 0, -0.5f, le, &c), 1);
    assert_true(c == 0.5f);
    ls.lamp.ke[0] = ls.lamp.ke[1] = ls.lamp.ke[2] = 0.0f; /* a material that does not emit */
    assert_int_equal(pm_lights_le_hit(&L, 0, 0.5f, le, &c), 0);
    pm_lights_le_escape(&L, ls.s.sun.direction, le);
    assert_true(fabsf(le[0] - 101.0f) < 1e-4f && fabsf(le[2] - 82.0f) < 1e-4f);
    const float away[3] = {0.0f, 0.0f, -1.0f};
    pm_lights_le_escape(&L, away, le);
    assert_true(le[0] == 1.0f && le[1] == 1.5f && le[2] == 2.0f);
    pm_lights_free(&L);
}

/* ---- emission ---- */

/* sample_le's flux, averaged over 200,000 photons, is the light's power (within 1% for a sky
 * map, whose flux varies by direction; exactly for the others); a triangle's photons start on
 * it, eps off its emitting face, with directions cosine-weighted about it (cos^2 uniform on
 * [0, 1]: chi-square over 40 bins) and both faces equally when two-sided; the sun's and the
 * sky's start on the disc tangent to the bounding sphere, heading in. */
static void test_light_sample_le(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    add_point(&ls, 0.5f, 0.5f, 0.5f, 1.0f);
    add_spot(&ls, 40.0f, 3.0f);
    add_sun(&ls, 0.05f);
    add_sky(&ls);
    pm_lights_t L;
    for (int variant = 0; variant < 2; variant++) {
        if (variant == 1) { /* a two-sided lamp and a sky map */
            ls.s.two_sided_lights = 1;
            ls.s.envmap = make_map();
        }
        assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
        double c[3], R;
        pm_scene_sphere(&ls.s, c, &R);
        const float eps = 1e-3f;
        for (size_t i = 0; i < L.n; i++) {
            const pm_light_t *l = &L.light[i];
            pm_rng_t rng;
            pm_rng_init(&rng, 21, i);
            const int ns = 200000;
            enum { NB = 40 };
            long bins[NB] = {0}, below = 0;
            double mean[3] = {0, 0, 0};
            for (int j = 0; j < ns; j++) {
                float u[4], org[3], dir[3];
                double flux[3];
                for (int k = 0; k < 4; k++)
                    u[k] = pm_rng_float(&rng);
                pm_light_sample_le(&L, l, u[0], u[1], u[2], u[3], eps, org, dir, flux);
                if (!(fabs(pm_dot3(dir, dir) - 1.0) < 1e-5))
                    fail_msg("%s light %zu: a direction of length %.7f", pm_light_kind_name(l->kind), i,
                             sqrt(pm_dot3(dir, dir)));
                for (int k = 0; k < 3; k++)
                    mean[k] += flux[k] / ns;
                if (l->kind == PM_LIGHT_AREA) {
                    /* The lamps face down (-z) from z = 1. */
                    float cz = -dir[2];
                    int back = cz < 0.0f;
                    below += back;
                    if (!(fabsf(org[2] - (back ? 1.0f + eps : 1.0f - eps)) < 1e-5f))
                        fail_msg("area light %u: a photon starts at z %.7f", l->index, org[2]);
                    int b = (int)(cz * cz * NB);
                    bins[b < 0 ? 0 : b >= NB ? NB - 1 : b]++;
                } else if (l->infinite) {
                    double o[3] = {org[0] - c[0], org[1] - c[1], org[2] - c[2]};
                    double along = -(o[0] * dir[0] + o[1] * dir[1] + o[2] * dir[2]);
                    if (!(fabs(along / R - 1.0) < 1e-4))
                        fail_msg("%s: a photon starts %.6f m before the centre, not R = %.6f m",
                                 pm_light_kind_name(l->kind), along, R);
                }
            }
            double tol = variant == 1 && l->kind == PM_LIGHT_SKY ? 0.01 : 1e-9;
            for (int k = 0; k < 3; k++)
                if (!(fabs(mean[k] / l->power[k] - 1.0) < tol))
                    fail_msg("%s light %zu, channel %d: photons carry %.6g W on average, its power is %.6g W",
                             pm_light_kind_name(l->kind), i, k, mean[k], l->power[k]);
            if (l->kind == PM_LIGHT_AREA) {
                double chi2 = 0.0;
                for (int b = 0; b < NB; b++)
                    chi2 += (bins[b] - ns / (double)NB) * (bins[b] - ns / (double)NB) / (ns / (double)NB);
                check_chi2("area light", "cos^2 of the direction", chi2, NB - 1);
                double back = (double)below / ns, want = variant == 1 ? 0.5 : 0.0;
                if (fabs(back - want) > 5.0 * sqrt(0.25 / ns))
                    fail_msg("area light: %.4f of the photons leave the back face, not %.1f", back, want);
            }
        }
        pm_lights_free(&L);
    }
    pm_envmap_free(ls.s.envmap);
    free(ls.s.envmap);
}

/* ---- per-kind directions: spots, the sun, the sky ---- */

/* A light's direction pdf on the sphere (1/sr) and its sampler, for the checks below. */
typedef struct {
    const char *name;
    pm_point_light_t spot; /* used when kind 0 */
    pm_sun_t sun;          /* kind 1 */
    int kind;              /* 0 spot emission, 1 sun, 2 sky about AXIS */
} dirlight_t;

static const float AXIS[3] = {0.36f, -0.48f, 0.8f}; /* unit */

static dirlight_t spot_case(const char *name, float cone_deg, float falloff)
{
    dirlight_t d;
    memset(&d, 0, sizeof d);
    d.name = name, d.kind = 0;
    memcpy(d.spot.axis, AXIS, sizeof d.spot.axis);
    d.spot.intensity[0] = d.spot.intensity[1] = d.spot.intensity[2] = 2.0f;
    d.spot.cos_cone = cone_deg >= 180.0f ? -1.0f : cosf(cone_deg * PM_PI / 180.0f);
    d.spot.falloff = falloff;
    return d;
}

static dirlight_t sun_case(const char *name, float omega)
{
    dirlight_t d;
    memset(&d, 0, sizeof d);
    d.name = name, d.kind = 1;
    memcpy(d.sun.direction, AXIS, sizeof d.sun.direction);
    d.sun.solid_angle = omega, d.sun.cos_max = 1.0f - omega / (2.0f * PM_PI);
    return d;
}

/* A scene with a constant sky and nothing else: what the sky's sampler reads. */
static const pm_scene_t *sky_scene(void)
{
    static pm_scene_t s;
    s.has_sky = 1, s.sky[0] = s.sky[1] = s.sky[2] = 1.0f;
    return &s;
}

static float dl_pdf(const dirlight_t *d, const float w[3])
{
    return d->kind == 0   ? pm_point_light_emit_pdf(&d->spot, w)
           : d->kind == 1 ? pm_sun_pdf(&d->sun, w)
                          : pm_sky_pdf(sky_scene(), AXIS, w);
}

static void dl_sample(const dirlight_t *d, float u1, float u2, float w[3])
{
    if (d->kind == 0)
        pm_point_light_emit(&d->spot, u1, u2, w);
    else if (d->kind == 1)
        pm_sun_sample(&d->sun, u1, u2, w);
    else
        pm_sky_sample(sky_scene(), AXIS, u1, u2, w);
}

/* Probability of cos(theta) to the axis in [c0, c1] under the light's pdf, in closed form. */
static double dl_mass(const dirlight_t *d, double c0, double c1)
{
    if (d->kind == 0) {
        double cc = d->spot.cos_cone, e = d->spot.falloff;
        double x0 = fmin(1.0, fmax(0.0, (c0 - cc) / (1.0 - cc))), x1 = fmin(1.0, fmax(0.0, (c1 - cc) / (1.0 - cc)));
        return pow(x1, e + 1.0) - pow(x0, e + 1.0);
    }
    if (d->kind == 1) {
        double cm = d->sun.cos_max, a = fmax(c0, cm), b = fmax(c1, cm);
        return (b - a) / (1.0 - cm);
    }
    double a = fmax(c0, 0.0), b = fmax(c1, 0.0);
    return b * b - a * a;
}

static const dirlight_t *dl_cases(int *n_out)
{
    static dirlight_t c[7];
    c[0] = spot_case("spot 30 deg hard", 30.0f, 0.0f);
    c[1] = spot_case("spot 45 deg falloff 1", 45.0f, 1.0f);
    c[2] = spot_case("spot 120 deg falloff 4", 120.0f, 4.0f);
    c[3] = spot_case("spot 180 deg falloff 2", 180.0f, 2.0f);
    c[4] = sun_case("sun 0.05 sr", 0.05f);
    c[5] = sun_case("sun 2 sr", 2.0f);
    c[6] = (dirlight_t){.name = "sky", .kind = 2};
    *n_out = 7;
    return c;
}

/* Each light's direction pdf integrates to 1 over the sphere (midpoint rule about the axis, 4000
 * cosines by 64 angles on each side of the cone's edge: the pdfs depend on the cosine alone and
 * are smooth inside the cone, so the rule is well within 1e-3), and a spot's power is the
 * integral of its intensity: a pdf normalized by (1 - cos) / e instead of / (e + 1), or a power
 * of 4 pi I for a cone, is off by far more. */
static void test_light_pdfs_integrate_to_one(void **state)
{
    (void)state;
    int n;
    const dirlight_t *c = dl_cases(&n);
    frame_t f = frame_about(AXIS);
    const int nc = 4000, nphi = 64;
    for (int i = 0; i < n; i++) {
        /* Two grids: from -1 to the light's lowest cosine lo (where the pdf must be 0) and
         * from lo to 1, so that the edge of a narrow cone falls between two grids. */
        double lo = c[i].kind == 0 ? c[i].spot.cos_cone : c[i].kind == 1 ? c[i].sun.cos_max : 0.0;
        double sum = 0.0, isum = 0.0, dphi = 2.0 * M_PI / nphi;
        for (int part = 0; part < 2; part++) {
            double c0 = part ? lo : -1.0, dc = ((part ? 1.0 : lo) - c0) / nc;
            for (int a = 0; a < nc && dc > 0.0; a++)
                for (int b = 0; b < nphi; b++) {
                    float w[3];
                    dir_in(&f, c0 + (a + 0.5) * dc, (b + 0.5) * dphi, w);
                    sum += dl_pdf(&c[i], w) * dc * dphi;
                    if (c[i].kind == 0)
                        isum += c[i].spot.intensity[0] * pm_spot_factor(&c[i].spot, w) * dc * dphi;
                }
        }
        if (!(fabs(sum - 1.0) < 1e-3))
            fail_msg("%s: the pdf integrates to %.6f", c[i].name, sum);
        if (c[i].kind == 0 && !(fabs(isum / pm_point_light_power(&c[i].spot, 0) - 1.0) < 1e-3))
            fail_msg("%s: power %.6f W, the intensity integrates to %.6f W", c[i].name,
                     pm_point_light_power(&c[i].spot, 0), isum);
    }
}

/* Each light's sampler against its pdf: 200,000 directions binned in 50 equal steps of
 * cos(theta) to the axis over the range the light covers, chi-square against the masses in
 * closed form (dl_mass); every direction must also have a positive pdf. A sampler drawing cos
 * uniformly for a spot of falloff 1 moves the bins by up to half their mass. */
static void test_light_samplers_match_pdf(void **state)
{
    (void)state;
    int n;
    const dirlight_t *c = dl_cases(&n);
    enum { NBINS = 50 };
    const int ns = 200000;
    for (int i = 0; i < n; i++) {
        double lo = c[i].kind == 0 ? c[i].spot.cos_cone : c[i].kind == 1 ? c[i].sun.cos_max : 0.0;
        long bins[NBINS] = {0};
        pm_rng_t r;
        pm_rng_init(&r, 77, (uint64_t)i);
        for (int k = 0; k < ns; k++) {
            float w[3];
            dl_sample(&c[i], pm_rng_float(&r), pm_rng_float(&r), w);
            double cw = pm_dot3(w, AXIS);
            if (!(fabs(pm_dot3(w, w) - 1.0) < 1e-5))
                fail_msg("%s: a direction of length %.7f", c[i].name, sqrt(pm_dot3(w, w)));
            if (!(dl_pdf(&c[i], w) > 0.0f) && cw < 1.0 - 1e-6 && cw > lo + 1e-5)
                fail_msg("%s: a direction of zero pdf (cos %.7f)", c[i].name, cw);
            int b = (int)((cw - lo) / (1.0 - lo) * NBINS);
            bins[b < 0 ? 0 : b >= NBINS ? NBINS - 1 : b]++;
        }
        double chi2 = 0.0;
        int dof = 0;
        for (int b = 0; b < NBINS; b++) {
            double e = ns * dl_mass(&c[i], lo + (1.0 - lo) * b / NBINS, lo + (1.0 - lo) * (b + 1) / NBINS);
            if (e < 20.0) {
                if (bins[b] > 5.0 * e + 20.0)
                    fail_msg("%s: bin %d holds %ld, expected %.1f", c[i].name, b, bins[b], e);
                continue;
            }
            chi2 += (bins[b] - e) * (bins[b] - e) / e;
            dof++;
        }
        check_chi2(c[i].name, "direction", chi2, dof - 1);
    }
}

/* A lat-long map's sampler: the map of make_map. Its pdf integrates to 1 over the sphere
 * (midpoint rule on a grid aligned with the pixels, 64 x 64 points per pixel: within 1e-3), the
 * pdf of each sample is positive and agrees with pm_envmap_pixel's pixel, 400,000 samples land
 * in the pixels as pix_p says (chi-square), the pixel probabilities follow luminance times sin
 * theta, and a NaN or negative value is refused naming the pixel and channel. */
static void test_light_envmap_sampler(void **state)
{
    (void)state;
    enum { W = 16, H = 8 };
    pm_envmap_t *ep = make_map(), e = *ep;
    const float *rgb = e.rgb;
    double sum = 0.0;
    const int sub = 64;
    for (int y = 0; y < H * sub; y++)
        for (int x = 0; x < W * sub; x++) {
            double th = M_PI * (y + 0.5) / (H * sub), ph = 2.0 * M_PI * (x + 0.5) / (W * sub);
            float w[3] = {(float)(sin(th) * cos(ph)), (float)cos(th), (float)(sin(th) * sin(ph))};
            sum += pm_envmap_pdf(&e, w) * sin(th) * (M_PI / (H * sub)) * (2.0 * M_PI / (W * sub));
        }
    if (!(fabs(sum - 1.0) < 1e-3))
        fail_msg("envmap: the pdf integrates to %.6f", sum);
    for (int y = 0; y < H; y++) {
        double lum =
            0.2126 * rgb[3 * (y * W + 3)] + 0.7152 * rgb[3 * (y * W + 3) + 1] + 0.0722 * rgb[3 * (y * W + 3) + 2];
        double want = lum * sin(M_PI * (y + 0.5) / H) / e.total;
        if (!(fabs(e.pix_p[y * W + 3] - want) <= 1e-12 + 1e-9 * want))
            fail_msg("envmap: pixel (3, %d) has probability %.9g, luminance times sin says %.9g", y, e.pix_p[y * W + 3],
                     want);
    }
    static long bins[W * H];
    memset(bins, 0, sizeof bins);
    const int ns = 400000;
    pm_rng_t r;
    pm_rng_init(&r, 5, 5);
    for (int i = 0; i < ns; i++) {
        float w[3];
        pm_envmap_sample(&e, pm_rng_float(&r), pm_rng_float(&r), w);
        uint32_t x, y;
        pm_envmap_pixel(&e, w, &x, &y);
        if (!(pm_envmap_pdf(&e, w) > 0.0f))
            fail_msg("envmap: a sample of zero pdf in pixel (%u, %u)", x, y);
        bins[y * W + x]++;
    }
    double chi2 = 0.0;
    int dof = 0;
    for (int i = 0; i < W * H; i++) {
        double ex = ns * e.pix_p[i];
        if (ex == 0.0) {
            if (bins[i])
                fail_msg("envmap: %ld samples in black pixel %d", bins[i], i);
            continue;
        }
        chi2 += (bins[i] - ex) * (bins[i] - ex) / ex;
        dof++;
    }
    check_chi2("envmap", "pixels", chi2, dof - 1);
    pm_envmap_free(ep);
    free(ep);

    float *bad = calloc(W * H * 3, sizeof(float));
    assert_non_null(bad);
    bad[3 * (4 * W + 9) + 1] = -0.5f;
    assert_int_equal(pm_envmap_init(&e, W, H, bad), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "pixel (9, 4) channel G = -0.5"));
    bad = calloc(W * H * 3, sizeof(float));
    assert_non_null(bad);
    bad[3 * 2 + 2] = NAN;
    assert_int_equal(pm_envmap_init(&e, W, H, bad), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "pixel (2, 0) channel B = nan"));
}

/* The sky's frame (sky.up, sky.rotate): its axes for +y, +z and -y up (rotate 90 shows the map's
 * longitude 0 at azimuth 90: +z), elevation and azimuth as directions, and a turned map against
 * the same map unturned: for random world directions w, the turned map's pixel and pdf at w are
 * the plain map's at the frame's image of w, and its sample from (u1, u2) is the plain map's
 * sample turned back into the world. A rotated map is then the rotated scene, in sampling, pdf
 * and lookup alike. */
static void test_light_envmap_frame(void **state)
{
    (void)state;
    static const struct {
        double up[3], rot, want[9];
    } cases[] = {
        {{0, 1, 0}, 0, {1, 0, 0, 0, 1, 0, 0, 0, 1}},
        {{0, 1, 0}, 90, {0, 0, 1, 0, 1, 0, -1, 0, 0}},
        {{0, 0, 3}, 0, {1, 0, 0, 0, 0, 1, 0, -1, 0}},
        {{0, -1, 0}, 0, {1, 0, 0, 0, -1, 0, 0, 0, -1}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double f[9];
        pm_sky_frame(cases[i].up, cases[i].rot, f);
        for (int k = 0; k < 9; k++)
            if (!(fabs(f[k] - cases[i].want[k]) < 1e-12))
                fail_msg("sky frame %zu: element %d is %.17g, want %g", i, k, f[k], cases[i].want[k]);
    }
    double f[9], d[3], up[3] = {1, 2, 0.5};
    pm_sky_frame((double[3]){0, 1, 0}, 0, f);
    pm_sky_frame_direction(f, 30, 90, d);
    if (!(fabs(d[0]) < 1e-12 && fabs(d[1] - 0.5) < 1e-12 && fabs(d[2] - sqrt(0.75)) < 1e-12))
        fail_msg("elevation 30, azimuth 90: %g %g %g, want 0 0.5 0.866", d[0], d[1], d[2]);
    pm_sky_frame(up, 37, f);
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double dot = f[3 * a] * f[3 * b] + f[3 * a + 1] * f[3 * b + 1] + f[3 * a + 2] * f[3 * b + 2];
            if (!(fabs(dot - (a == b)) < 1e-12))
                fail_msg("sky frame for up 1 2 0.5: rows %d, %d have dot %.17g", a, b, dot);
        }
    if (!(fabs(f[3] - 1 / sqrt(5.25)) < 1e-12 && fabs(f[4] - 2 / sqrt(5.25)) < 1e-12))
        fail_msg("sky frame for up 1 2 0.5: its y row is %g %g %g", f[3], f[4], f[5]);
    /* the y row is up, and the determinant +1 (a turn, no mirror) */
    double det =
        f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6]) + f[2] * (f[3] * f[7] - f[4] * f[6]);
    if (!(fabs(det - 1.0) < 1e-12))
        fail_msg("sky frame for up 1 2 0.5: determinant %.17g", det);

    pm_envmap_t *plain = make_map(), *turned = make_map();
    pm_envmap_set_frame(turned, f);
    assert_int_equal(turned->framed, 1);
    pm_rng_t r;
    pm_rng_init(&r, 7, 3);
    for (int i = 0; i < 20000; i++) {
        float w[3], m[3], ws[3], wp[3];
        pm_v3_store(w, pm_sample_sphere(pm_rng_float(&r), pm_rng_float(&r)));
        for (int k = 0; k < 3; k++)
            m[k] = (float)(f[3 * k] * w[0] + f[3 * k + 1] * w[1] + f[3 * k + 2] * w[2]);
        uint32_t x1, y1, x2, y2;
        pm_envmap_pixel(turned, w, &x1, &y1);
        pm_envmap_pixel(plain, m, &x2, &y2);
        float p1 = pm_envmap_pdf(turned, w), p2 = pm_envmap_pdf(plain, m);
        /* a direction within float rounding of a pixel's edge may fall either side */
        if (x1 == x2 && y1 == y2 && !(fabsf(p1 - p2) <= 1e-5f * p2))
            fail_msg("turned map: pdf %.9g at w, the plain map's %.9g at its image", p1, p2);
        if ((x1 != x2 || y1 != y2) && i % 1000 == 0)
            print_message("turned map: w on a pixel edge (%u %u vs %u %u)\n", x1, y1, x2, y2);
        float u1 = pm_rng_float(&r), u2 = pm_rng_float(&r);
        pm_envmap_sample(turned, u1, u2, ws);
        pm_envmap_sample(plain, u1, u2, wp);
        for (int k = 0; k < 3; k++) {
            float back = (float)(wp[0] * f[k] + wp[1] * f[3 + k] + wp[2] * f[6 + k]);
            if (!(fabsf(back - ws[k]) < 1e-5f))
                fail_msg("turned map: sample %d component %d is %.9g, the plain map's turned %.9g", i, k, ws[k], back);
        }
    }
    pm_envmap_free(plain);
    pm_envmap_free(turned);
    free(plain);
    free(turned);
}

/* ---- portals ---- */

/* Portals (scene key portals): two parallelograms of 1 and 3 m^2 facing different ways. Each
 * sun and sky photon starts on one of them (each by its area), carries flux only when it
 * travels through the portal's front (inward), and the fluxes average to the power through the
 * portals that pm_portals_power gives (the sun's and a constant sky's in closed form, a map's
 * summed over its pixels: within 5 standard errors, and 2% more for the map's pixel centres). */
static void test_light_portals(void **state)
{
    (void)state;
    light_scene_t ls;
    light_scene(&ls, 0);
    add_sun(&ls, 0.05f);
    add_sky(&ls);
    pm_portal_t portals[2] = {
        {.corner = {0, 0, 1.5f}, .edge_u = {1, 0, 0}, .edge_v = {0, 1, 0}, .inward = {0, 0, -1}, .area = 1.0},
        {.corner = {-1, -1, 0}, .edge_u = {0, 3, 0}, .edge_v = {0, 0, 1}, .inward = {-1, 0, 0}, .area = 3.0}};
    ls.s.portals = portals, ls.s.nportals = 2, ls.s.portal_area = 4.0;
    for (int variant = 0; variant < 2; variant++) {
        if (variant == 1)
            ls.s.envmap = make_map();
        pm_portals_power(&ls.s, ls.s.portal_power);
        pm_lights_t L;
        assert_int_equal(pm_lights_init(&ls.s, &L), PM_OK);
        for (size_t i = 0; i < L.n; i++) {
            const pm_light_t *l = &L.light[i];
            if (!l->infinite)
                continue; /* the scene's two lamps: no portal concerns them */
            int sun = l->kind == PM_LIGHT_SUN;
            pm_rng_t rng;
            pm_rng_init(&rng, 31, i + 2 * (size_t)variant);
            const int ns = 200000;
            double sum[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
            long on[2] = {0, 0};
            for (int j = 0; j < ns; j++) {
                float u[4], org[3], dir[3];
                double flux[3];
                for (int k = 0; k < 4; k++)
                    u[k] = pm_rng_float(&rng);
                pm_light_sample_le(&L, l, u[0], u[1], u[2], u[3], 1e-3f, org, dir, flux);
                /* the portal it starts on: in its plane, within its edges */
                int p = fabsf(org[2] - 1.5f) < 1e-5f && org[0] >= -1e-5f && org[0] <= 1.00001f && org[1] >= -1e-5f &&
                                org[1] <= 1.00001f
                            ? 0
                        : fabsf(org[0] + 1.0f) < 1e-5f && org[1] >= -1.00001f && org[1] <= 2.00001f &&
                                org[2] >= -1e-5f && org[2] <= 1.00001f
                            ? 1
                            : -1;
                if (p < 0)
                    fail_msg("%s photon %d starts off the portals at %g %g %g", pm_light_kind_name(l->kind), j, org[0],
                             org[1], org[2]);
                on[p]++;
                float c = pm_dot3(dir, portals[p].inward);
                if ((flux[0] > 0.0 || flux[1] > 0.0 || flux[2] > 0.0) && !(c > 0.0f))
                    fail_msg("%s photon %d carries flux %g outward through portal %d (cos %g)",
                             pm_light_kind_name(l->kind), j, flux[0], p, c);
                for (int k = 0; k < 3; k++)
                    sum[k] += flux[k], sq[k] += flux[k] * flux[k];
            }
            /* by area: a quarter on the first */
            double f0 = (double)on[0] / ns;
            if (!(fabs(f0 - 0.25) < 5.0 * sqrt(0.25 * 0.75 / ns)))
                fail_msg("%s: %.4f of the photons on the 1 m^2 portal of 4 m^2 in all", pm_light_kind_name(l->kind),
                         f0);
            for (int k = 0; k < 3; k++) {
                double mean = sum[k] / ns, se = sqrt(fmax(0.0, sq[k] / ns - mean * mean) / ns),
                       want = ls.s.portal_power[sun ? 0 : 1][k];
                double tol = 5.0 * se + (variant == 1 && !sun ? 0.02 * want : 1e-9 * want);
                if (!(fabs(mean - want) <= tol))
                    fail_msg("%s%s channel %d: mean flux %.6g, power through the portals %.6g (tolerance %.3g)",
                             pm_light_kind_name(l->kind), variant ? " (map)" : "", k, mean, want, tol);
            }
        }
        pm_lights_free(&L);
    }
    /* the constant sky's and the sun's in closed form: pi L A, and L omega (1 + cos a) / 2 cos A */
    pm_envmap_free(ls.s.envmap);
    free(ls.s.envmap);
    ls.s.envmap = NULL;
    pm_portals_power(&ls.s, ls.s.portal_power);
    assert_true(fabs(ls.s.portal_power[1][0] - M_PI * 1.0 * 4.0) < 1e-9);
    double cs0 = 0.8, cs1 = 0.36, half = 0.5 * (1.0 + (double)ls.s.sun.cos_max);
    assert_true(fabs(ls.s.portal_power[0][0] - 100.0 * 0.05 * half * (cs0 * 1.0 + cs1 * 3.0)) < 1e-4);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_light_set),
    cmocka_unit_test(test_light_area_uniform),
    cmocka_unit_test(test_light_sample_li_vs_pdf_li),
    cmocka_unit_test(test_light_point),
    cmocka_unit_test(test_light_le),
    cmocka_unit_test(test_light_sample_le),
    cmocka_unit_test(test_light_pdfs_integrate_to_one),
    cmocka_unit_test(test_light_samplers_match_pdf),
    cmocka_unit_test(test_light_envmap_sampler),
    cmocka_unit_test(test_light_envmap_frame),
    cmocka_unit_test(test_light_portals),
};
UNIT_GROUP(light_group, "light", tests)
