/* test_transport.c: the shared physics of render/transport.h against its own definitions.
 *
 * For a Lambertian material, pure Phong lobes of ns 1, 10 and 200, a mixed one and a grazing
 * view: every pdf integrates to one over the sphere (quadrature), every sampler's histogram
 * matches its pdf (chi-square), the BSDF is reciprocal; the single-ray wrappers hit and miss
 * what they should (the lights' own checks are test_light.c's).
 * Mirrors and glass: Fresnel against the angle form and its symmetries, Snell's law and the
 * reflect/refract split of the specular sampler, its weights, and no NaN at grazing angles.
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
    return unit_chi2_pooled(name, obs, expect, NB, n, dof);
}

/* unit_check_chi2 under the name "case, what". */
static void check_chi2(const char *name, const char *what, double chi2, int dof)
{
    char label[160];
    snprintf(label, sizeof label, "%s, %s", name, what);
    unit_check_chi2(label, chi2, dof);
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
 * (legs 1 by 1 and 1 by 3), or one square of side 2 m centred above the origin at height 1
 * made of two triangles. */
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

/* ---- specular materials ---- */

static pm_material_t glass(float ior, float tf)
{
    pm_material_t m;
    memset(&m, 0, sizeof m);
    m.kind = PM_MAT_GLASS, m.ior = ior;
    for (int k = 0; k < 3; k++)
        m.tf[k] = tf;
    return m;
}

/* Fresnel from the angles, in double, the textbook form (rs = -sin(ti - tt) / sin(ti + tt),
 * rp = tan(ti - tt) / tan(ti + tt)): an independent check on the cosine form of transport.c. */
static double fresnel_angles(double ti, double eta)
{
    double st = sin(ti) / eta;
    if (st >= 1.0)
        return 1.0;
    double tt = asin(st);
    if (ti == 0.0)
        return pow((eta - 1.0) / (eta + 1.0), 2.0);
    double rs = -sin(ti - tt) / sin(ti + tt), rp = tan(ti - tt) / tan(ti + tt);
    return 0.5 * (rs * rs + rp * rp);
}

/* Normal incidence gives ((n - 1) / (n + 1))^2 from either side; every angle matches the
 * angle form; eta and 1 / eta agree at Snell partner angles; beyond the critical angle F is 1;
 * index 1 reflects nothing. */
static void test_transport_fresnel(void **state)
{
    (void)state;
    const float etas[] = {1.0f, 1.33f, 1.5f, 2.4f, 3.0f};
    for (size_t e = 0; e < sizeof etas / sizeof etas[0]; e++) {
        float n = etas[e], r0 = (n - 1.0f) * (n - 1.0f) / ((n + 1.0f) * (n + 1.0f));
        assert_true(fabsf(pm_fresnel_dielectric(1.0f, n) - r0) < 1e-6f);
        assert_true(fabsf(pm_fresnel_dielectric(1.0f, 1.0f / n) - r0) < 1e-6f);
        for (int i = 0; i <= 90; i++) {
            double ti = i * M_PI / 180.0;
            for (int inv = 0; inv < 2; inv++) {
                double eta = inv ? 1.0 / n : n;
                float f = pm_fresnel_dielectric((float)cos(ti), (float)eta);
                if (!(fabs(f - fresnel_angles(ti, eta)) < 2e-5))
                    fail_msg("F(%d deg, eta %g) = %.7f, the angle form gives %.7f", i, eta, f, fresnel_angles(ti, eta));
                double st = sin(ti) / eta;
                if (st < 1.0 && i < 90) {
                    /* the same boundary crossed the other way at the refracted angle */
                    float back = pm_fresnel_dielectric((float)sqrt(1.0 - st * st), (float)(1.0 / eta));
                    if (!(fabsf(back - f) < 1e-4f))
                        fail_msg("F(%d deg, eta %g) = %.7f but %.7f back at the refracted angle", i, eta, f, back);
                } else if (st >= 1.0) {
                    assert_true(f == 1.0f);
                }
            }
        }
    }
    for (int i = 1; i <= 100; i++)
        assert_true(pm_fresnel_dielectric(i / 100.0f, 1.0f) < 1e-6f);
    /* total internal reflection: glass of 1.5 from inside beyond asin(1 / 1.5) = 41.8 degrees */
    assert_true(pm_fresnel_dielectric(cosf(42.0f * PM_PI / 180.0f), 1.0f / 1.5f) == 1.0f);
    assert_true(pm_fresnel_dielectric(cosf(41.0f * PM_PI / 180.0f), 1.0f / 1.5f) < 0.9f);
    assert_true(fabsf(pm_fresnel_dielectric(1.0f, 3.0f) - 0.25f) < 1e-6f);
    /* anything a tracer can pass in: finite and within [0, 1] */
    const float cs[] = {0.0f, -0.0f, 1e-30f, 1e-7f, 0.5f, 1.0f, 1.0000001f, 1.5f, -0.5f, -1.0f};
    const float es[] = {1e-38f, 1e-6f, 1e-3f, 0.3333f, 0.999999f, 1.0f, 1.000001f, 3.0f, 1e3f, 1e6f, 1e30f, 3e38f};
    for (size_t i = 0; i < sizeof cs / sizeof cs[0]; i++)
        for (size_t j = 0; j < sizeof es / sizeof es[0]; j++) {
            float f = pm_fresnel_dielectric(cs[i], es[j]);
            if (!(f >= 0.0f && f <= 1.0f))
                fail_msg("F(%g, %g) = %g", cs[i], es[j], f);
        }
}

/* Unit wo at theta degrees from +z (theta > 90: below the surface) in the x-z plane. */
static void unit_at(double theta_deg, float w[3])
{
    double t = theta_deg * M_PI / 180.0;
    w[0] = (float)sin(t), w[1] = 0.0f, w[2] = (float)cos(t);
}

/* Reflection is the mirror direction; refraction obeys Snell's law (n_i sin_i = n_t sin_t, in
 * the plane of wo and the normal, on the far side) from the front and from the back; a
 * refracted ray sent back the way it came leaves along wo; weights are kr, 1 and tf (times
 * 1 / eta^2 for radiance); index 1 passes straight through. */
static void test_transport_specular_directions(void **state)
{
    (void)state;
    const float ng[3] = {0.0f, 0.0f, 1.0f};
    pm_material_t mirror;
    memset(&mirror, 0, sizeof mirror);
    mirror.kind = PM_MAT_MIRROR, mirror.kr[0] = 0.9f, mirror.kr[1] = 0.5f, mirror.kr[2] = 0.1f;
    const float iors[] = {1.0f, 1.5f, 3.0f};
    for (int th = 0; th <= 180; th += 5) {
        if (th == 90)
            continue;
        float wo[3], wi[3], w[3];
        unit_at(th, wo);
        assert_int_equal(pm_specular_sample(&mirror, ng, wo, 0.5f, 1, wi, w), 0);
        assert_true(fabsf(wi[0] + wo[0]) < 1e-6f && fabsf(wi[1]) < 1e-6f && fabsf(wi[2] - wo[2]) < 1e-6f);
        assert_true(w[0] == 0.9f && w[1] == 0.5f && w[2] == 0.1f);
        for (size_t g = 0; g < sizeof iors / sizeof iors[0]; g++) {
            pm_material_t m = glass(iors[g], 0.8f);
            int front = wo[2] > 0.0f;
            float eta = front ? m.ior : 1.0f / m.ior, cos_o = fabsf(wo[2]);
            float f = pm_fresnel_dielectric(cos_o, eta);
            /* u just below F reflects, u at F refracts (when F < 1) */
            if (f > 0.0f) {
                assert_int_equal(pm_specular_sample(&m, ng, wo, nextafterf(f, 0.0f), 1, wi, w), 0);
                assert_true(fabsf(wi[0] + wo[0]) < 1e-6f && fabsf(wi[2] - wo[2]) < 1e-6f);
                assert_true(w[0] == 1.0f && w[1] == 1.0f && w[2] == 1.0f);
            }
            if (f >= 1.0f)
                continue;
            int t = pm_specular_sample(&m, ng, wo, f, 1, wi, w);
            assert_int_equal(t, 1);
            assert_true(fabsf(pm_dot3(wi, wi) - 1.0f) < 1e-5f && fabsf(wi[1]) < 1e-6f);
            assert_true(front ? wi[2] < 0.0f : wi[2] > 0.0f); /* the far side */
            /* Snell, with signs: the tangential parts point the same way round (wo's is reversed) */
            float lhs = -wo[0], rhs = eta * wi[0];
            if (!(fabsf(lhs - rhs) < 2e-6f * (1.0f + eta)))
                fail_msg("Snell at %d deg, ior %g: sin_i %g but eta sin_t %g", th, m.ior, lhs, rhs);
            float expect = 0.8f / (eta * eta);
            assert_true(fabsf(w[0] - expect) < 1e-6f * expect && w[0] == w[1] && w[1] == w[2]);
            float wp[3];
            assert_int_equal(pm_specular_sample(&m, ng, wo, f, 0, wi, wp), 1);
            assert_true(wp[0] == 0.8f); /* power: tf alone */
            /* wi seen from the far side is a wo there; its refraction is the original wo */
            float back[3] = {wi[0], wi[1], wi[2]}, wi2[3];
            float f2 = pm_fresnel_dielectric(fabsf(back[2]), 1.0f / eta);
            assert_true(fabsf(f2 - f) < 2e-5f); /* the same boundary, either way */
            assert_int_equal(pm_specular_sample(&m, ng, back, 0.999999f, 1, wi2, w), 1);
            for (int k = 0; k < 3; k++)
                if (!(fabsf(wi2[k] - wo[k]) < 2e-5f))
                    fail_msg("ior %g at %d deg: the refracted ray sent back leaves along (%g %g %g), not wo", m.ior, th,
                             wi2[0], wi2[1], wi2[2]);
            if (m.ior == 1.0f) {
                assert_true(f < 1e-6f);
                for (int k = 0; k < 3; k++)
                    assert_true(fabsf(wi[k] + wo[k]) < 1e-6f);
            }
        }
    }
    /* a black mirror sends nothing on; a standard material is not sampled here */
    pm_material_t black = mirror, plain = material(0.5f, 0.0f, 0.0f);
    black.kr[0] = black.kr[1] = black.kr[2] = 0.0f;
    float wo[3], wi[3], w[3];
    unit_at(30.0, wo);
    assert_int_equal(pm_specular_sample(&black, ng, wo, 0.5f, 0, wi, w), -1);
    assert_true(w[0] == 0.0f && w[1] == 0.0f && w[2] == 0.0f);
    assert_int_equal(pm_specular_sample(&plain, ng, wo, 0.5f, 0, wi, w), -1);
}

/* The reflect/refract split of the glass sampler is F: a histogram of 200000 uniforms at each
 * angle, from both sides, within 5 standard deviations of the binomial. Under total internal
 * reflection every sample reflects. Photons never gain power: every weight is in [0, 1] and
 * the mean of the weight is F + (1 - F) tf. */
static void test_transport_specular_split(void **state)
{
    (void)state;
    const float ng[3] = {0.0f, 0.0f, 1.0f};
    pm_material_t m = glass(1.5f, 0.7f);
    pm_rng_t rng;
    pm_rng_init(&rng, 18, 0);
    const int n = 200000;
    const double thetas[] = {0.0, 30.0, 60.0, 80.0, 89.0, 120.0, 135.0, 140.0, 150.0, 180.0};
    for (size_t a = 0; a < sizeof thetas / sizeof thetas[0]; a++) {
        float wo[3], wi[3], w[3];
        unit_at(thetas[a], wo);
        double f = pm_fresnel_dielectric(fabsf(wo[2]), wo[2] > 0.0f ? 1.5f : 1.0f / 1.5f);
        int refl = 0;
        double wsum = 0.0;
        for (int i = 0; i < n; i++) {
            int t = pm_specular_sample(&m, ng, wo, pm_rng_float(&rng), 0, wi, w);
            assert_true(t == 0 || t == 1);
            refl += t == 0;
            assert_true(w[0] >= 0.0f && w[0] <= 1.0f);
            wsum += w[0];
        }
        double sd = sqrt(n * f * (1.0 - f)), mean = f + (1.0 - f) * 0.7;
        if (!(fabs(refl - n * f) <= 5.0 * sd + 1e-9))
            fail_msg("at %g deg: %d of %d reflected, F = %.5f expects %.0f +- %.0f", thetas[a], refl, n, f, n * f, sd);
        if (!(fabs(wsum / n - mean) <= 5.0 * 0.3 * sd / n + 1e-6))
            fail_msg("at %g deg: mean photon weight %.5f, expected F + (1 - F) tf = %.5f", thetas[a], wsum / n, mean);
    }
}

/* No direction a tracer can meet gives a NaN, an Inf or a non-unit wi: grazing on both sides
 * (cos 0, 1e-8, denormal), directions a little off unit length, the inverted normal, indices
 * from 1 to 3 and the extremes the loader allows (any finite float > 0). */
static void test_transport_specular_stiff(void **state)
{
    (void)state;
    const float iors[] = {1e-30f, 1e-3f, 0.5f, 1.0f, 1.0001f, 1.5f, 3.0f, 1e3f, 1e30f, 3e38f};
    const float zs[] = {0.0f, -0.0f, 1e-38f, -1e-38f, 1e-8f, -1e-8f, 1e-4f, -1e-4f, 0.5f, -0.5f, 1.0f, -1.0f};
    const float us[] = {0.0f, 0.25f, 0.5f, 0.9999999f};
    for (size_t g = 0; g < sizeof iors / sizeof iors[0]; g++)
        for (size_t z = 0; z < sizeof zs / sizeof zs[0]; z++)
            for (int flip = 0; flip < 2; flip++)
                for (size_t ui = 0; ui < sizeof us / sizeof us[0]; ui++) {
                    pm_material_t m = glass(iors[g], 1.0f);
                    float ng[3] = {0.0f, 0.0f, flip ? -1.0f : 1.0f}, wo[3], wi[3], w[3];
                    float zz = zs[z], x = sqrtf(fmaxf(0.0f, 1.0f - zz * zz)) * 1.0000001f;
                    wo[0] = x, wo[1] = 0.0f, wo[2] = zz;
                    int t = pm_specular_sample(&m, ng, wo, us[ui], 1, wi, w);
                    float len = pm_dot3(wi, wi);
                    if (!(t == 0 || t == 1) || !(fabsf(len - 1.0f) < 1e-5f) || !isfinite(w[0]) || !(w[0] >= 0.0f))
                        fail_msg("ior %g, wo z %g, normal %s, u %g: returned %d, |wi|^2 %g, weight %g", iors[g], zz,
                                 flip ? "down" : "up", us[ui], t, len, w[0]);
                }
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_transport_pdf_integrates_to_one),
    cmocka_unit_test(test_transport_sampler_matches_pdf),
    cmocka_unit_test(test_transport_brdf_reciprocal),
    cmocka_unit_test(test_transport_rt_single_rays),
    cmocka_unit_test(test_transport_fresnel),
    cmocka_unit_test(test_transport_specular_directions),
    cmocka_unit_test(test_transport_specular_split),
    cmocka_unit_test(test_transport_specular_stiff),
};
UNIT_GROUP(transport_group, "transport", tests)
