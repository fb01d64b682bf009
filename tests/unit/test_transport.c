/* test_transport.c: the shared physics of render/transport.h against its own definitions.
 *
 * For a Lambertian material, pure Phong lobes of ns 1, 10 and 200, a mixed one and a grazing
 * view: every pdf integrates to one over the sphere (quadrature), every sampler's histogram
 * matches its pdf (chi-square), the BSDF is reciprocal; the area-light sampler picks triangles
 * in proportion to their area and points uniformly on them, its solid-angle pdf gives the
 * solid angle of a known square, and a point light gives the right distance and cosines.
 * The random numbers are Philox streams of fixed seeds, so every run draws the same samples. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "render/rt.h"
#include "render/transport.h"
#include "unit.h"

static pm_material_t material(float kd, float ks, float ns)
{
    pm_material_t m;
    memset(&m, 0, sizeof m);
    for (int k = 0; k < 3; k++)
        m.kd[k] = kd * (1.0f - 0.1f * (float)k), m.ks[k] = ks;
    m.ns = ns;
    return m;
}

static const float N_UP[3] = {0.0f, 0.0f, 1.0f};

/* Unit wo at theta degrees from the normal (0, 0, 1), in the x-z plane. */
static void view(float theta_deg, float wo[3])
{
    float t = theta_deg * PM_PI / 180.0f;
    wo[0] = sinf(t), wo[1] = 0.0f, wo[2] = cosf(t);
}

/* What a test samples and integrates: one lobe (over the sphere, the sampler's flag ignored)
 * or the mixture (0 below the surface, where the sampler reports a rejection). */
typedef enum { KIND_DIFFUSE = PM_LOBE_DIFFUSE, KIND_GLOSSY = PM_LOBE_GLOSSY, KIND_MIXTURE } kind_t;

static float pdf_of(kind_t kind, const pm_material_t *m, const float wi[3], const float wo[3])
{
    return kind == KIND_MIXTURE ? pm_bsdf_pdf(m, N_UP, wi, wo) : pm_bsdf_lobe_pdf(m, (pm_lobe_t)kind, N_UP, wi, wo);
}

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

static void dir_in(const frame_t *f, double c, double phi, float d[3])
{
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    for (int k = 0; k < 3; k++)
        d[k] = (float)(s * cos(phi) * f->t[k] + s * sin(phi) * f->b[k] + c * f->a[k]);
}

/* Integral of the pdf over the sphere by the midpoint rule on an nc x nphi grid uniform in
 * cos(theta) and phi about the normal (not about the lobe: the pdf is taken as a function on
 * the sphere, whatever axis it was written about). */
static double integrate(kind_t kind, const pm_material_t *m, const float wo[3], int nc, int nphi)
{
    frame_t f = frame_about(N_UP);
    double sum = 0.0, dc = 2.0 / nc, dphi = 2.0 * M_PI / nphi;
    for (int i = 0; i < nc; i++)
        for (int j = 0; j < nphi; j++) {
            float d[3];
            dir_in(&f, -1.0 + (i + 0.5) * dc, (j + 0.5) * dphi, d);
            sum += pdf_of(kind, m, d, wo);
        }
    return sum * dc * dphi;
}

/* Cases: a material, a view, and the lobes that exist for it. */
typedef struct {
    const char *name;
    float kd, ks, ns, theta;
} tcase_t;

static const tcase_t cases[] = {
    {"lambert", 0.8f, 0.0f, 0.0f, 30.0f},      {"phong ns 1", 0.0f, 0.9f, 1.0f, 30.0f},
    {"phong ns 10", 0.0f, 0.9f, 10.0f, 30.0f}, {"phong ns 200", 0.0f, 0.9f, 200.0f, 30.0f},
    {"mixed ns 20", 0.4f, 0.5f, 20.0f, 40.0f}, {"grazing ns 200", 0.2f, 0.7f, 200.0f, 85.0f},
};
enum { NCASES = sizeof cases / sizeof cases[0] };

/* (a) Each lobe's pdf integrates to 1 over the sphere. A grid of 1000 cosines by 2000 angles
 * puts more than ten points across the narrowest lobe (ns 200: about 0.07 rad wide; the grid
 * steps 0.004 rad or less away from the pole, where the lobes are), so the midpoint rule's error
 * stays well below the bound of 2e-4, while a Phong pdf normalized by
 * (ns + 2) instead of (ns + 1) is off by 1 / (ns + 1) = 5e-3 at ns 200. The mixture
 * integrates to its probability of sampling above the surface: diffuse share + glossy share
 * times the glossy lobe's mass above the surface. */
static void test_transport_pdf_integrates_to_one(void **state)
{
    for (int c = 0; c < NCASES; c++) {
        pm_material_t m = material(cases[c].kd, cases[c].ks, cases[c].ns);
        float wo[3];
        view(cases[c].theta, wo);
        double sd = pm_bsdf_diffuse_share(&m), mix = integrate(KIND_MIXTURE, &m, wo, 1000, 2000);
        if (cases[c].kd > 0.0f) {
            double i = integrate(KIND_DIFFUSE, &m, wo, 1000, 2000);
            if (fabs(i - 1.0) > 2e-4)
                fail_msg("%s: the diffuse pdf integrates to %.6f", cases[c].name, i);
        }
        double above = 0.0;
        if (cases[c].ks > 0.0f) {
            double i = integrate(KIND_GLOSSY, &m, wo, 1000, 2000);
            if (fabs(i - 1.0) > 2e-4)
                fail_msg("%s: the glossy pdf integrates to %.6f", cases[c].name, i);
            /* the glossy lobe's mass above the surface, by the same grid over the upper half */
            frame_t f = frame_about(N_UP);
            for (int a = 0; a < 500; a++)
                for (int j = 0; j < 2000; j++) {
                    float d[3];
                    dir_in(&f, (a + 0.5) / 500.0, (j + 0.5) * M_PI / 1000.0, d);
                    above += pm_bsdf_lobe_pdf(&m, PM_LOBE_GLOSSY, N_UP, d, wo);
                }
            above *= (1.0 / 500.0) * (M_PI / 1000.0);
        }
        double want = sd + (1.0 - sd) * above;
        if (fabs(mix - want) > 2e-4)
            fail_msg("%s: the mixture pdf integrates to %.6f, its lobes say %.6f", cases[c].name, mix, want);
    }
}

/* Histogram of n samples of `kind` about frame f, in kw bins of w = cos(alpha)^q (alpha from
 * the axis) by kphi bins of phi; one more bin for directions at or below 90 degrees from the
 * axis and one for samples the mixture rejects. The expected mass of each bin is the pdf
 * integrated over it by the midpoint rule in (w, phi), with dcos/dw as the Jacobian: q = 1
 * about the normal, and q = ns + 1 about a Phong lobe's axis, where the Jacobian cancels the
 * lobe's cos^ns and the integrand stays smooth (q = 2 would leave a 1 / sqrt(w) singularity at
 * the horizon where the pdf is not zero), so 32 x 64 points per bin suffice.
 * Returns chi-square over the bins expecting at least 5 samples (the rest pooled into one),
 * with its degrees of freedom in *dof; fails at once on a sample in a bin expecting none. */
enum { KW = 16, KPHI = 8, NB = KW * KPHI + 2, SUBW = 32, SUBPHI = 64 };

static double histogram_chi2(const char *name, kind_t kind, const pm_material_t *m, const float wo[3], const frame_t *f,
                             double q, int n, uint64_t seed, int *dof)
{
    static double obs[NB], expect[NB];
    memset(obs, 0, sizeof obs);
    memset(expect, 0, sizeof expect);
    pm_rng_t rng;
    pm_rng_init(&rng, seed, 0);
    for (int s = 0; s < n; s++) {
        float wi[3], u = pm_rng_float(&rng), u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng);
        int above = kind == KIND_MIXTURE ? pm_bsdf_sample(m, N_UP, wo, u, u1, u2, wi)
                                         : (pm_bsdf_sample_lobe(m, (pm_lobe_t)kind, N_UP, wo, u1, u2, wi), 1);
        if (kind == KIND_MIXTURE && !above) {
            obs[NB - 1]++;
            continue;
        }
        double c = pm_dot3(wi, f->a);
        if (c <= 0.0) {
            obs[NB - 2]++;
            continue;
        }
        double phi = atan2(pm_dot3(wi, f->b), pm_dot3(wi, f->t));
        if (phi < 0.0)
            phi += 2.0 * M_PI;
        int iw = (int)(pow(fmin(c, 1.0), q) * KW), ip = (int)(phi / (2.0 * M_PI) * KPHI);
        iw = iw < KW ? iw : KW - 1, ip = ip < KPHI ? ip : KPHI - 1;
        obs[iw * KPHI + ip]++;
    }
    double total = 0.0;
    for (int iw = 0; iw < KW; iw++)
        for (int ip = 0; ip < KPHI; ip++) {
            double acc = 0.0, dw = 1.0 / (KW * SUBW), dphi = 2.0 * M_PI / (KPHI * SUBPHI);
            for (int a = 0; a < SUBW; a++) {
                double w = (iw * SUBW + a + 0.5) * dw, c = pow(w, 1.0 / q), jac = c / (q * w);
                for (int b = 0; b < SUBPHI; b++) {
                    float d[3];
                    dir_in(f, c, (ip * SUBPHI + b + 0.5) * dphi, d);
                    acc += pdf_of(kind, m, d, wo) * jac;
                }
            }
            expect[iw * KPHI + ip] = acc * dw * dphi;
            total += expect[iw * KPHI + ip];
        }
    /* below the axis: uniform in cos(alpha) over [-1, 0] */
    double below = 0.0;
    for (int a = 0; a < 256; a++)
        for (int b = 0; b < 512; b++) {
            float d[3];
            dir_in(f, -(a + 0.5) / 256.0, (b + 0.5) * 2.0 * M_PI / 512.0, d);
            below += pdf_of(kind, m, d, wo);
        }
    expect[NB - 2] = below / 256.0 * 2.0 * M_PI / 512.0;
    total += expect[NB - 2];
    expect[NB - 1] = kind == KIND_MIXTURE ? fmax(0.0, 1.0 - total) : 0.0;
    double chi2 = 0.0, pool_o = 0.0, pool_e = 0.0;
    int bins = 0;
    for (int i = 0; i < NB; i++) {
        double e = expect[i] * n;
        if (e < 1e-3 && obs[i] > 0)
            fail_msg("%s: %.0f samples in bin %d, where the pdf expects %.2g", name, obs[i], i, e);
        if (e >= 5.0) {
            chi2 += (obs[i] - e) * (obs[i] - e) / e;
            bins++;
        } else {
            pool_o += obs[i], pool_e += e;
        }
    }
    if (pool_e >= 5.0) {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        bins++;
    }
    *dof = bins - 1;
    return chi2;
}

/* The bound on chi-square: mean plus 5 standard deviations of a chi-square of dof degrees. */
static void check_chi2(const char *name, const char *what, double chi2, int dof)
{
    double bound = dof + 5.0 * sqrt(2.0 * dof);
    if (!(chi2 <= bound))
        fail_msg("%s, %s: chi-square %.1f over %d degrees of freedom (bound %.1f)", name, what, chi2, dof, bound);
}

/* (b) Each sampler against its pdf: the diffuse lobe binned about the normal in cos, the
 * glossy lobe about the mirror direction in cos^(ns + 1), the mixture about the normal (its
 * glossy peak then falls across bins, which the fine quadrature follows). 400,000 samples
 * over 130 bins expect about 3,000 per bin: a pdf whose Phong part is normalized by (ns + 2)
 * instead of (ns + 1) moves every glossy bin by 1 / (ns + 1), 50 standard deviations at ns 1
 * and 5 at ns 10 in each bin; at ns 200 the quadrature of test (a) is the finer check. */
static void test_transport_sampler_matches_pdf(void **state)
{
    const int n = 400000;
    for (int c = 0; c < NCASES; c++) {
        pm_material_t m = material(cases[c].kd, cases[c].ks, cases[c].ns);
        float wo[3], r[3];
        view(cases[c].theta, wo);
        pm_reflect(N_UP, wo, r);
        frame_t fn = frame_about(N_UP), fr = frame_about(r);
        int dof;
        double chi2;
        if (cases[c].kd > 0.0f) {
            chi2 = histogram_chi2(cases[c].name, KIND_DIFFUSE, &m, wo, &fn, 1.0, n, 11 + (uint64_t)c, &dof);
            check_chi2(cases[c].name, "diffuse lobe", chi2, dof);
        }
        if (cases[c].ks > 0.0f) {
            chi2 =
                histogram_chi2(cases[c].name, KIND_GLOSSY, &m, wo, &fr, cases[c].ns + 1.0, n, 21 + (uint64_t)c, &dof);
            check_chi2(cases[c].name, "glossy lobe", chi2, dof);
        }
        chi2 = histogram_chi2(cases[c].name, KIND_MIXTURE, &m, wo, &fn, 1.0, n, 31 + (uint64_t)c, &dof);
        check_chi2(cases[c].name, "mixture", chi2, dof);
    }
}

/* (c) f(wi, wo) = f(wo, wi). The two sides compute the Phong cosine as r(wi).wo and r(wo).wi,
 * which agree to a few float roundings (2e-6 is about 30 ulps of 1); f may differ by that
 * times its derivative in the cosine, ks (ns + 2) / (2 pi) ns cos^(ns - 1), and by 1e-6 of
 * itself. */
static void test_transport_brdf_reciprocal(void **state)
{
    pm_rng_t rng;
    pm_rng_init(&rng, 7, 0);
    for (int c = 0; c < NCASES; c++) {
        pm_material_t m = material(cases[c].kd, cases[c].ks, cases[c].ns);
        for (int i = 0; i < 20000; i++) {
            float wi[3], wo[3], f1[3], f2[3];
            pm_v3_store(wi, pm_sample_cosine_hemisphere(pm_rng_float(&rng), pm_rng_float(&rng)));
            if (i % 4 == 0) /* grazing: a lobe reflected about the normal near the horizon */
                view(80.0f + 10.0f * pm_rng_float(&rng), wo);
            else
                pm_v3_store(wo, pm_sample_cosine_hemisphere(pm_rng_float(&rng), pm_rng_float(&rng)));
            pm_brdf(&m, N_UP, wi, wo, f1);
            pm_brdf(&m, N_UP, wo, wi, f2);
            float rr[3];
            pm_reflect(N_UP, wi, rr);
            double cr = fmax(0.0, pm_dot3(rr, wo)) + 2e-6, ns = m.ns;
            double slope = cases[c].ks > 0.0f ? (ns + 2.0) / (2.0 * M_PI) * ns * pow(cr, fmax(0.0, ns - 1.0)) : 0.0;
            for (int k = 0; k < 3; k++) {
                double tol = m.ks[k] * slope * 2e-6 + 1e-6 * fmax(f1[k], f2[k]);
                if (!(fabs((double)f1[k] - f2[k]) <= tol))
                    fail_msg("%s: f(wi, wo) = %.9g but f(wo, wi) = %.9g (channel %d, cosine %.7f)", cases[c].name,
                             f1[k], f2[k], k, cr);
            }
        }
    }
}

/* A scene of two emissive triangles in the plane z = 1, facing down, of areas 0.5 and 1.5 m^2
 * (legs 1 by 1 and 1 by 3), and one square of side 2 m centred above the origin at height 1
 * made of two triangles (the solid-angle check). */
typedef struct {
    pm_scene_t s;
    float verts[3 * 10];
    uint32_t tris[3 * 4], mat[4], emissive[4];
    pm_material_t lamp;
} light_scene_t;

static void light_scene(light_scene_t *ls, int square)
{
    memset(ls, 0, sizeof *ls);
    static const float two[] = {0, 0, 1, 0, 1, 1, 1, 0, 1,  /* triangle 0: right angle at (0, 0) */
                                2, 0, 1, 2, 3, 1, 3, 0, 1}; /* triangle 1: right angle at (2, 0) */
    static const float sq[] = {-1, -1, 1, -1, 1, 1, 1, 1, 1, 1, -1, 1};
    ls->lamp.ke[0] = ls->lamp.ke[1] = ls->lamp.ke[2] = 1.0f;
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
}

/* (d) The area-light sampler: the triangle in proportion to its area (0.25 and 0.75, within
 * 5 binomial standard deviations of 200,000 picks: 0.005), the point uniform on it (chi-square
 * over an 8 x 8 grid of its legs, the cells on the hypotenuse expecting half), and the distance
 * and cosines of each sample consistent with the point. */
static void test_transport_area_light_uniform(void **state)
{
    light_scene_t ls;
    light_scene(&ls, 0);
    pm_shade_geom_t g;
    assert_int_equal(pm_shade_geom_init(&ls.s, &g), PM_OK);
    assert_true(fabs(g.area - 2.0) < 1e-6);
    enum { K = 8 };
    double cells[2][K][K];
    memset(cells, 0, sizeof cells);
    const float p[3] = {1.0f, 0.5f, 0.0f}, up[3] = {0.0f, 0.0f, 1.0f};
    pm_rng_t rng;
    pm_rng_init(&rng, 5, 0);
    const int n = 200000;
    int picks[2] = {0, 0};
    for (int i = 0; i < n; i++) {
        pm_light_sample_t s;
        assert_int_equal(pm_area_light_sample(&ls.s, &g, &rng, p, up, &s), 1);
        assert_true(s.tri < 2);
        picks[s.tri]++;
        float y[3];
        for (int k = 0; k < 3; k++)
            y[k] = p[k] + s.wi[k] * s.r;
        assert_true(fabsf(y[2] - 1.0f) < 1e-5f);
        assert_true(fabsf(s.r2 - s.r * s.r) <= 1e-6f * s.r2);
        assert_true(fabsf(s.cosx - s.wi[2]) < 1e-6f &&
                    fabsf(s.cosy - s.wi[2]) < 1e-6f); /* both faces face each other */
        /* legs: triangle 0 spans x in [0, 1], y in [0, 1]; triangle 1 x in [2, 3], y in [0, 3] */
        double u = s.tri == 0 ? y[0] : y[0] - 2.0, v = s.tri == 0 ? y[1] : y[1] / 3.0;
        int cu = (int)(u * K), cv = (int)(v * K);
        cu = cu < 0 ? 0 : cu >= K ? K - 1 : cu, cv = cv < 0 ? 0 : cv >= K ? K - 1 : cv;
        assert_true(cu + cv <= K); /* inside the triangle: u + v <= 1, to rounding */
        cells[s.tri][cu][cv]++;
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
    pm_shade_geom_free(&g);
}

/* The solid-angle pdf: the mean of 1 / pdf over light samples is the solid angle the lights
 * fill, here a 2 m square at 1 m above the point, 4 asin(1/2) = 2 pi / 3 sr. 100,000 samples
 * have a standard error below 0.005 of that; the bound is 0.02. */
static void test_transport_area_light_pdf(void **state)
{
    light_scene_t ls;
    light_scene(&ls, 1);
    pm_shade_geom_t g;
    assert_int_equal(pm_shade_geom_init(&ls.s, &g), PM_OK);
    const float p[3] = {0.0f, 0.0f, 0.0f}, up[3] = {0.0f, 0.0f, 1.0f};
    pm_rng_t rng;
    pm_rng_init(&rng, 9, 0);
    double sum = 0.0;
    const int n = 100000;
    for (int i = 0; i < n; i++) {
        pm_light_sample_t s;
        assert_int_equal(pm_area_light_sample(&ls.s, &g, &rng, p, up, &s), 1);
        sum += 1.0 / pm_area_light_pdf(&g, s.r2, s.cosy);
    }
    double omega = sum / n, want = 2.0 * M_PI / 3.0;
    if (fabs(omega / want - 1.0) > 0.02)
        fail_msg("the lights fill %.5f sr by their pdf, %.5f sr by geometry", omega, want);
    pm_shade_geom_free(&g);
}

/* A point light: direction, distance and cosines, and no light from behind or from p. */
static void test_transport_point_light(void **state)
{
    pm_point_light_t l;
    memset(&l, 0, sizeof l);
    l.position[0] = 1.0f, l.position[1] = 2.0f, l.position[2] = 3.0f;
    const float p[3] = {0.0f, 0.0f, 1.0f}, up[3] = {0.0f, 0.0f, 1.0f}, down[3] = {0.0f, 0.0f, -1.0f};
    pm_light_sample_t s;
    assert_int_equal(pm_point_light_toward(&l, p, up, &s), 1);
    assert_true(fabsf(s.r2 - 9.0f) < 1e-6f && fabsf(s.r - 3.0f) < 1e-6f);
    assert_true(fabsf(s.wi[0] - 1.0f / 3) < 1e-6f && fabsf(s.wi[1] - 2.0f / 3) < 1e-6f &&
                fabsf(s.wi[2] - 2.0f / 3) < 1e-6f);
    assert_true(fabsf(s.cosx - 2.0f / 3) < 1e-6f && s.cosy == 1.0f && s.tri == UINT32_MAX);
    assert_int_equal(pm_point_light_toward(&l, p, down, &s), 0);        /* behind the surface */
    assert_int_equal(pm_point_light_toward(&l, l.position, up, &s), 0); /* at the point */
}

/* The single-ray wrappers on the two-triangle lights, and an Embree error raised on one OpenMP
 * worker (a geometry of no valid type) reaching the caller whole through pm_rt_thread_error
 * and a pm_error_slot_t, as the tracers' parallel regions report it. */
static void test_transport_rt_single_rays(void **state)
{
    light_scene_t ls;
    light_scene(&ls, 0);
    pm_rt_t rt;
    assert_int_equal(pm_rt_create(&ls.s, 0, 1, &rt), PM_OK);
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    const float o[3] = {0.25f, 0.25f, 0.0f}, up[3] = {0.0f, 0.0f, 1.0f}, side[3] = {1.0f, 0.0f, 0.0f};
    float t, ng[3];
    assert_int_equal(pm_rt_intersect1(&rt, &ctx, o, up, 0.0f, INFINITY, &t, ng), 0);
    assert_true(fabsf(t - 1.0f) < 1e-6f && ng[2] < 0.0f); /* (v1 - v0) x (v2 - v0) faces down */
    assert_int_equal(pm_rt_intersect1(&rt, &ctx, o, side, 0.0f, INFINITY, &t, NULL), PM_RAY_MISS);
    assert_true(t == INFINITY);
    assert_int_equal(pm_rt_occluded1(&rt, &ctx, o, up, 0.0f, 2.0f), 1);
    assert_int_equal(pm_rt_occluded1(&rt, &ctx, o, up, 0.0f, 0.5f), 0); /* stops short */
    assert_int_equal(pm_rt_thread_error(&rt, "before anything failed"), PM_OK);

    pm_error_slot_t slot;
    pm_error_slot_init(&slot);
#pragma omp parallel for num_threads(2) schedule(static, 1)
    for (int task = 0; task < 4; task++) {
        if (task == 3) {
            RTCGeometry g = rtcNewGeometry(rt.device, (enum RTCGeometryType)999);
            if (g)
                rtcReleaseGeometry(g);
        }
        pm_error_slot_record(&slot, (uint64_t)task, pm_rt_thread_error(&rt, "in task %d", task));
    }
    assert_int_not_equal(pm_error_slot_raise(&slot), PM_OK);
    if (!strstr(pm_error_message(), "embree failed in task 3: "))
        fail_msg("the worker's message came back as '%s'", pm_error_message());
    pm_rt_destroy(&rt);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_transport_pdf_integrates_to_one), cmocka_unit_test(test_transport_sampler_matches_pdf),
    cmocka_unit_test(test_transport_brdf_reciprocal),       cmocka_unit_test(test_transport_area_light_uniform),
    cmocka_unit_test(test_transport_area_light_pdf),        cmocka_unit_test(test_transport_point_light),
    cmocka_unit_test(test_transport_rt_single_rays),
};
UNIT_GROUP(transport_group, "transport", tests)
