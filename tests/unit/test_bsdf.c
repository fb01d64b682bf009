/* test_bsdf.c: every material kind of physics/bsdf.h against its own definitions and physics.
 *
 * For the standard kind, conductors (Schlick's f0 and a complex index), rough glass (indices 1.5
 * and 3, from outside and inside) and plastic, at GGX widths from the smooth limit to 1:
 *   - white furnace: the directional albedo in importance mode (energy a photon keeps), by the
 *     sampler's mean weight and by quadrature of f |cos|, is at most 1; exactly 1 for a smooth
 *     dielectric's R + T and a conductor of f0 = 1 at alpha 0, and within 0.5% at alpha 0.01;
 *   - reciprocity: f(wi, wo) = f(wo, wi) for reflection, f(wi, wo) / n_wo^2 = f(wo, wi) / n_wi^2
 *     for transmission, and the importance mode equal to the radiance mode with its arguments
 *     swapped;
 *   - pm_bsdf_pdf_wi integrates over the sphere (quadrature) to the fraction of samples that are
 *     not absorbed; the sampler's histogram matches it (chi-square) for every sampled lobe;
 *   - each sample's weight is f |n.wi| / pdf and its pdf is pm_bsdf_pdf_wi;
 *   - stiff cases (alpha 0, 1e-4 and 1, index 1, 1.0001, 3 and 1e6, grazing and horizontal
 *     directions) give no NaN or Inf anywhere.
 * GGX's D is normalized and the visible-normal pdf integrates to 1; the Fresnel functions meet
 * their closed forms. Samples come from Philox streams of fixed seeds: every run draws the same. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/error.h"
#include "formats/formats.h"
#include "math/rng.h"
#include "math/sampling.h"
#include "math/vec.h"
#include "physics/bsdf.h"
#include "unit.h"

static const float N_UP[3] = {0.0f, 0.0f, 1.0f};

/* A named material built in C (the scene reader's values). */
typedef struct {
    const char *name;
    pm_material_t m;
} named_t;

static pm_material_t base(int kind)
{
    pm_material_t m;
    memset(&m, 0, sizeof m);
    m.kind = kind;
    m.ior = 1.5f;
    for (int k = 0; k < 3; k++)
        m.tf[k] = 1.0f;
    return m;
}

static pm_material_t standard(float kd, float ks, float ns)
{
    pm_material_t m = base(PM_MAT_STANDARD);
    for (int k = 0; k < 3; k++)
        m.kd[k] = kd, m.ks[k] = ks;
    m.ns = ns;
    return m;
}

static pm_material_t conductor_f0(float f0, float alpha)
{
    pm_material_t m = base(PM_MAT_CONDUCTOR);
    for (int k = 0; k < 3; k++)
        m.f0[k] = f0 * (1.0f - 0.2f * (float)k);
    m.alpha = alpha;
    return m;
}

/* Gold's complex index at about 650, 550 and 450 nm. */
static pm_material_t gold(float alpha)
{
    pm_material_t m = base(PM_MAT_CONDUCTOR);
    const float eta[3] = {0.18f, 0.42f, 1.37f}, k[3] = {3.42f, 2.35f, 1.77f};
    memcpy(m.eta, eta, sizeof eta), memcpy(m.k, k, sizeof k);
    m.alpha = alpha;
    return m;
}

static pm_material_t rough_glass(float ior, float alpha)
{
    pm_material_t m = base(PM_MAT_ROUGH_GLASS);
    m.ior = ior, m.alpha = alpha;
    return m;
}

static pm_material_t plastic(float kd, float ior, float alpha)
{
    pm_material_t m = base(PM_MAT_PLASTIC);
    for (int k = 0; k < 3; k++)
        m.kd[k] = kd * (1.0f - 0.3f * (float)k);
    m.ior = ior, m.alpha = alpha;
    return m;
}

/* Unit direction at theta degrees from +z (negative: below), azimuth phi degrees. */
static void dir_deg(double theta, double phi, float w[3])
{
    double t = theta * M_PI / 180.0, p = phi * M_PI / 180.0;
    w[0] = (float)(sin(t) * cos(p)), w[1] = (float)(sin(t) * sin(p)), w[2] = (float)cos(t);
}

static int finite3(const float v[3]) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

/* Quadrature over the sphere in (theta, phi), nt x nphi midpoints (theta, not cos theta: a lobe
 * at a pole, as at normal incidence, is a few 1e-4 wide in cos): of f |cos| (channel `ch`,
 * importance mode) when `what` is 0, of pm_bsdf_pdf_wi when 1. */
static double sphere_integral(const pm_material_t *m, const float wo[3], int what, int ch, int nt, int nphi)
{
    double acc = 0.0, dt = M_PI / nt, dp = 2.0 * M_PI / nphi;
    for (int i = 0; i < nt; i++) {
        double t = (i + 0.5) * dt, c = cos(t), s = sin(t), row = 0.0;
        for (int j = 0; j < nphi; j++) {
            double p = (j + 0.5) * dp;
            float wi[3] = {(float)(s * cos(p)), (float)(s * sin(p)), (float)c}, f[3];
            if (what == 0) {
                pm_bsdf_eval(m, N_UP, wi, wo, PM_BSDF_IMPORTANCE, f);
                row += f[ch] * fabs(c);
            } else {
                row += pm_bsdf_pdf_wi(m, N_UP, wi, wo);
            }
        }
        acc += row * s;
    }
    return acc * dt * dp;
}

/* The sampler's statistics at wo over n samples: mean weight per channel (importance mode),
 * its standard error (channel 0), the fraction of samples drawn (not absorbed) and of those from
 * delta lobes. Every sample is checked on the way: finite, weight >= 0, a unit wi, and for a
 * non-delta one weight = f |cos| / pdf and pdf = pm_bsdf_pdf_wi within 1e-3 relative. */
typedef struct {
    double mean[3], se, drawn, delta;
} stats_t;

static stats_t sample_stats(const char *name, const pm_material_t *m, const float wo[3], int n, uint64_t seed,
                            pm_bsdf_mode_t mode)
{
    stats_t st;
    memset(&st, 0, sizeof st);
    double sq = 0.0;
    pm_rng_t rng;
    pm_rng_init(&rng, seed, 0);
    for (int i = 0; i < n; i++) {
        float u = pm_rng_float(&rng), u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng);
        pm_bsdf_sample_t s;
        if (!pm_bsdf_sample_wi(m, N_UP, wo, u, u1, u2, mode, &s))
            continue;
        if (!finite3(s.weight) || !finite3(s.wi) || !isfinite(s.pdf) || !(s.pdf > 0.0f))
            fail_msg("%s: sample %d not finite (pdf %g)", name, i, s.pdf);
        for (int k = 0; k < 3; k++)
            if (!(s.weight[k] >= 0.0f))
                fail_msg("%s: sample %d has weight %g", name, i, s.weight[k]);
        if (fabsf(pm_dot3(s.wi, s.wi) - 1.0f) > 1e-5f)
            fail_msg("%s: sample %d's direction has length^2 %g", name, i, pm_dot3(s.wi, s.wi));
        int below = s.wi[2] < 0.0f, above_o = wo[2] >= 0.0f;
        if (((s.lobe & PM_BSDF_TRANSMIT) != 0) != (below == above_o))
            fail_msg("%s: sample %d flagged %s but wi.z %g, wo.z %g", name, i,
                     (s.lobe & PM_BSDF_TRANSMIT) ? "transmit" : "reflect", s.wi[2], wo[2]);
        if (s.lobe & PM_BSDF_DELTA) {
            st.delta++;
        } else {
            float f[3], pdf = pm_bsdf_pdf_wi(m, N_UP, s.wi, wo);
            pm_bsdf_eval(m, N_UP, s.wi, wo, mode, f);
            if (fabsf(pdf - s.pdf) > 1e-3f * pdf)
                fail_msg("%s: sample %d's pdf %g, pm_bsdf_pdf_wi %g", name, i, s.pdf, pdf);
            for (int k = 0; k < 3; k++) {
                float w = f[k] * fabsf(s.wi[2]) / pdf;
                if (fabsf(w - s.weight[k]) > 1e-3f * fmaxf(w, 1e-3f))
                    fail_msg("%s: sample %d channel %d weight %g, f cos / pdf %g", name, i, k, s.weight[k], w);
            }
        }
        st.drawn++;
        for (int k = 0; k < 3; k++)
            st.mean[k] += s.weight[k];
        sq += (double)s.weight[0] * s.weight[0];
    }
    for (int k = 0; k < 3; k++)
        st.mean[k] /= n;
    st.se = sqrt(fmax(0.0, sq / n - st.mean[0] * st.mean[0]) / n);
    st.drawn /= n, st.delta /= n;
    return st;
}

/* (a) White furnace: the albedo is at most 1 for every kind and view (importance mode: power),
 * and where the BSDF keeps all the energy it is 1. */
static void test_bsdf_white_furnace(void **state)
{
    (void)state;
    named_t ms[] = {
        {"standard kd 0.6 ks 0.4 ns 30", standard(0.6f, 0.4f, 30.0f)},
        {"conductor f0 1 alpha 0.2", conductor_f0(1.0f, 0.2f)},
        {"conductor f0 1 alpha 1", conductor_f0(1.0f, 1.0f)},
        {"gold alpha 0.3", gold(0.3f)},
        {"rough glass 1.5 alpha 0.2", rough_glass(1.5f, 0.2f)},
        {"rough glass 1.5 alpha 1", rough_glass(1.5f, 1.0f)},
        {"rough glass 3 alpha 0.5", rough_glass(3.0f, 0.5f)},
        {"plastic kd 1 alpha 0.2", plastic(1.0f, 1.5f, 0.2f)},
        {"plastic kd 1 alpha 1", plastic(1.0f, 1.5f, 1.0f)},
        {"plastic kd 1 smooth", plastic(1.0f, 1.5f, 0.0f)},
        {"plastic kd 1 ior 3 alpha 0.5", plastic(1.0f, 3.0f, 0.5f)},
    };
    const double thetas[] = {0.0, 30.0, 60.0, 80.0, 89.0, 120.0, 150.0};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (size_t t = 0; t < sizeof thetas / sizeof thetas[0]; t++) {
            if (thetas[t] > 90.0 && ms[i].m.kind == PM_MAT_STANDARD)
                continue; /* the standard kind reflects on n's side as given */
            float wo[3];
            dir_deg(thetas[t], 0.0, wo);
            stats_t st = sample_stats(ms[i].name, &ms[i].m, wo, 50000, 7 + t, PM_BSDF_IMPORTANCE);
            char name[128];
            snprintf(name, sizeof name, "%s at %.0f degrees", ms[i].name, thetas[t]);
            for (int k = 0; k < 3; k++)
                if (!(st.mean[k] <= 1.0 + 5.0 * st.se + 1e-4))
                    fail_msg("%s: albedo %.5f (channel %d) above 1 (standard error %.1e)", name, st.mean[k], k, st.se);
            /* The sampler's mean against quadrature of f |cos| (non-delta kinds). */
            if (st.delta == 0.0 && thetas[t] < 85.0) {
                double q = sphere_integral(&ms[i].m, wo, 0, 0, 1024, 192);
                if (!(q <= 1.0 + 2e-3))
                    fail_msg("%s: albedo by quadrature %.5f above 1", name, q);
                if (fabs(q - st.mean[0]) > 5.0 * st.se + 5e-3)
                    fail_msg("%s: albedo by sampling %.5f, by quadrature %.5f (standard error %.1e)", name, st.mean[0],
                             q, st.se);
            }
        }

    /* Exactly 1: a smooth dielectric's R + T, each sample of weight 1; a conductor of f0 1 at
     * alpha 0, each sample of weight 1. */
    pm_material_t glass = base(PM_MAT_GLASS), rg0 = rough_glass(1.5f, 0.0f), c0 = conductor_f0(1.0f, 0.0f);
    for (int k = 0; k < 3; k++)
        c0.f0[k] = 1.0f;
    for (size_t t = 0; t < sizeof thetas / sizeof thetas[0]; t++) {
        float wo[3];
        dir_deg(thetas[t], 30.0, wo);
        stats_t a = sample_stats("glass", &glass, wo, 20000, 3, PM_BSDF_IMPORTANCE),
                b = sample_stats("rough glass alpha 0", &rg0, wo, 20000, 3, PM_BSDF_IMPORTANCE);
        stats_t c = sample_stats("conductor f0 1 alpha 0", &c0, wo, 2000, 3, PM_BSDF_IMPORTANCE);
        for (int k = 0; k < 3; k++) {
            assert_true(fabs(a.mean[k] - 1.0) < 1e-6);
            assert_true(fabs(b.mean[k] - 1.0) < 1e-6);
            assert_true(fabs(c.mean[k] - 1.0) < 1e-6);
        }
        assert_true(a.delta == 1.0 && b.delta == 1.0 && c.delta == 1.0);
    }
    /* At alpha 0.01 single scattering loses little: f0 1 keeps at least 99.5% up to 60 degrees
     * and 98% at 80; a rough glass of alpha 0.01 as much of R + T. */
    pm_material_t c1 = conductor_f0(1.0f, 0.01f), rg1 = rough_glass(1.5f, 0.01f);
    for (int k = 0; k < 3; k++)
        c1.f0[k] = 1.0f;
    const double th2[] = {0.0, 30.0, 60.0, 80.0, 150.0};
    for (size_t t = 0; t < sizeof th2 / sizeof th2[0]; t++) {
        float wo[3];
        dir_deg(th2[t], 0.0, wo);
        double want = fabs(cos(th2[t] * M_PI / 180.0)) >= 0.49 ? 0.995 : 0.98;
        stats_t c = sample_stats("conductor f0 1 alpha 0.01", &c1, wo, 50000, 5, PM_BSDF_IMPORTANCE);
        stats_t g = sample_stats("rough glass alpha 0.01", &rg1, wo, 50000, 5, PM_BSDF_IMPORTANCE);
        if (th2[t] < 90.0 && !(c.mean[0] >= want && c.mean[0] <= 1.0 + 1e-4))
            fail_msg("conductor f0 1 alpha 0.01 at %.0f degrees: albedo %.5f, want [%.3f, 1]", th2[t], c.mean[0], want);
        if (!(g.mean[0] >= want && g.mean[0] <= 1.0 + 5.0 * g.se + 1e-4))
            fail_msg("rough glass alpha 0.01 at %.0f degrees: R + T %.5f, want [%.3f, 1]", th2[t], g.mean[0], want);
    }
}

/* (b) Reciprocity on random direction pairs, and the adjoint. */
static void test_bsdf_reciprocity(void **state)
{
    (void)state;
    named_t ms[] = {
        {"standard", standard(0.5f, 0.4f, 12.0f)},
        {"conductor 0.3", conductor_f0(0.9f, 0.3f)},
        {"gold 0.05", gold(0.05f)},
        {"rough glass 1.5 0.3", rough_glass(1.5f, 0.3f)},
        {"rough glass 3 0.05", rough_glass(3.0f, 0.05f)},
        {"plastic 0.2", plastic(0.8f, 1.5f, 0.2f)},
        {"plastic smooth", plastic(0.8f, 1.5f, 0.0f)},
    };
    pm_rng_t rng;
    pm_rng_init(&rng, 11, 0);
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++) {
        const pm_material_t *m = &ms[i].m;
        int compared = 0;
        for (int s = 0; s < 20000; s++) {
            pm_vec3_t a = pm_sample_sphere(pm_rng_float(&rng), pm_rng_float(&rng)),
                      b = pm_sample_sphere(pm_rng_float(&rng), pm_rng_float(&rng));
            float wi[3], wo[3], f1[3], f2[3], fa[3];
            pm_v3_store(wi, a), pm_v3_store(wo, b);
            if (m->kind == PM_MAT_STANDARD && !(wi[2] > 0.0f && wo[2] > 0.0f))
                continue; /* the standard kind reflects on n's side as given */
            pm_bsdf_eval(m, N_UP, wi, wo, PM_BSDF_RADIANCE, f1);
            pm_bsdf_eval(m, N_UP, wo, wi, PM_BSDF_RADIANCE, f2);
            pm_bsdf_eval(m, N_UP, wo, wi, PM_BSDF_IMPORTANCE, fa);
            double ni = 1.0, no = 1.0;
            if (pm_bsdf_transmits(m)) {
                ni = wi[2] > 0.0f ? 1.0 : m->ior;
                no = wo[2] > 0.0f ? 1.0 : m->ior;
            }
            for (int k = 0; k < 3; k++) {
                if (!isfinite(f1[k]) || !isfinite(f2[k]) || f1[k] < 0.0f)
                    fail_msg("%s: f not finite or negative", ms[i].name);
                /* f(wi, wo) / n_wo^2 = f(wo, wi) / n_wi^2 */
                double l = f1[k] / (no * no), r = f2[k] / (ni * ni);
                if (fabs(l - r) > 2e-3 * fmax(l, r) + 1e-6)
                    fail_msg("%s: f(wi, wo) / n_o^2 = %g, f(wo, wi) / n_i^2 = %g (wi.z %g, wo.z %g)", ms[i].name, l, r,
                             wi[2], wo[2]);
                /* the adjoint: importance f(wo <- wi) is radiance f(wi, wo) */
                if (fabs(fa[k] - f1[k]) > 2e-3 * fmax(fa[k], f1[k]) + 1e-6)
                    fail_msg("%s: importance f(wo, wi) %g, radiance f(wi, wo) %g", ms[i].name, fa[k], f1[k]);
            }
            compared += f1[0] > 0.0f;
        }
        if (compared < 1000)
            fail_msg("%s: only %d pairs with f > 0", ms[i].name, compared);
    }
}

/* (c) The pdf integrates to the probability of a drawn non-delta sample. */
static void test_bsdf_pdf_integrates(void **state)
{
    (void)state;
    named_t ms[] = {
        {"standard", standard(0.5f, 0.4f, 12.0f)},        {"conductor 0.1", conductor_f0(0.9f, 0.1f)},
        {"conductor 1", conductor_f0(0.9f, 1.0f)},        {"gold 0.3", gold(0.3f)},
        {"rough glass 1.5 0.1", rough_glass(1.5f, 0.1f)}, {"rough glass 1.5 0.5", rough_glass(1.5f, 0.5f)},
        {"rough glass 3 1", rough_glass(3.0f, 1.0f)},     {"plastic 0.2", plastic(0.7f, 1.5f, 0.2f)},
        {"plastic 1", plastic(0.7f, 1.5f, 1.0f)},         {"plastic smooth", plastic(0.7f, 1.5f, 0.0f)},
    };
    const double thetas[] = {0.0, 45.0, 75.0, 135.0};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (size_t t = 0; t < sizeof thetas / sizeof thetas[0]; t++) {
            if (thetas[t] > 90.0 && ms[i].m.kind == PM_MAT_STANDARD)
                continue;
            float wo[3];
            dir_deg(thetas[t], 0.0, wo);
            double q = sphere_integral(&ms[i].m, wo, 1, 0, 1024, 192);
            stats_t st = sample_stats(ms[i].name, &ms[i].m, wo, 100000, 17 + t, PM_BSDF_RADIANCE);
            double p = st.drawn - st.delta, se = sqrt(p * (1.0 - p) / 100000.0);
            if (!(q <= 1.0 + 2e-3) || fabs(q - p) > 5.0 * se + 3e-3)
                fail_msg("%s at %.0f degrees: pdf integrates to %.5f, non-delta samples drawn %.5f", ms[i].name,
                         thetas[t], q, p);
        }
}

/* (d) Chi-square of each sampler against its pdf: 24 bins in cos theta over [-1, 1] by 12 in
 * phi about the normal, and one for absorbed samples (expecting 1 minus the pdf's integral);
 * each bin's expectation by a 32 x 24 midpoint quadrature of pm_bsdf_pdf_wi. 200,000 samples. */
enum { CB = 24, PB = 12, NBIN = CB * PB + 1, SUBC = 32, SUBP = 24 };

static void chi2_one(const char *name, const pm_material_t *m, const float wo[3], uint64_t seed)
{
    static double obs[NBIN], expect[NBIN];
    const int n = 200000;
    memset(obs, 0, sizeof obs);
    pm_rng_t rng;
    pm_rng_init(&rng, seed, 0);
    for (int s = 0; s < n; s++) {
        float u = pm_rng_float(&rng), u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng);
        pm_bsdf_sample_t bs;
        if (!pm_bsdf_sample_wi(m, N_UP, wo, u, u1, u2, PM_BSDF_RADIANCE, &bs)) {
            obs[NBIN - 1]++;
            continue;
        }
        double phi = atan2(bs.wi[1], bs.wi[0]);
        if (phi < 0.0)
            phi += 2.0 * M_PI;
        int ic = (int)((bs.wi[2] + 1.0) / 2.0 * CB), ip = (int)(phi / (2.0 * M_PI) * PB);
        ic = ic < 0 ? 0 : ic >= CB ? CB - 1 : ic, ip = ip >= PB ? PB - 1 : ip;
        obs[ic * PB + ip]++;
    }
    double total = 0.0, dc = 2.0 / (CB * SUBC), dp = 2.0 * M_PI / (PB * SUBP);
    for (int ic = 0; ic < CB; ic++)
        for (int ip = 0; ip < PB; ip++) {
            double acc = 0.0;
            for (int a = 0; a < SUBC; a++) {
                double c = -1.0 + (ic * SUBC + a + 0.5) * dc, sn = sqrt(fmax(0.0, 1.0 - c * c));
                for (int b = 0; b < SUBP; b++) {
                    double p = (ip * SUBP + b + 0.5) * dp;
                    float wi[3] = {(float)(sn * cos(p)), (float)(sn * sin(p)), (float)c};
                    acc += pm_bsdf_pdf_wi(m, N_UP, wi, wo);
                }
            }
            expect[ic * PB + ip] = acc * dc * dp;
            total += expect[ic * PB + ip];
        }
    expect[NBIN - 1] = fmax(0.0, 1.0 - total);
    int dof;
    double chi2 = unit_chi2_pooled(name, obs, expect, NBIN, n, &dof);
    unit_check_chi2(name, chi2, dof);
}

static void test_bsdf_sampler_chi2(void **state)
{
    (void)state;
    named_t ms[] = {
        {"conductor 0.2", conductor_f0(0.9f, 0.2f)},
        {"conductor 1", conductor_f0(0.9f, 1.0f)},
        {"gold 0.4", gold(0.4f)},
        {"rough glass 1.5 0.2", rough_glass(1.5f, 0.2f)},
        {"rough glass 1.5 0.6", rough_glass(1.5f, 0.6f)},
        {"rough glass 3 0.3", rough_glass(3.0f, 0.3f)},
        {"plastic 0.25", plastic(0.7f, 1.5f, 0.25f)},
        {"plastic 1", plastic(0.7f, 1.5f, 1.0f)},
        {"standard", standard(0.5f, 0.4f, 8.0f)},
    };
    const double thetas[] = {20.0, 65.0, 140.0};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (size_t t = 0; t < sizeof thetas / sizeof thetas[0]; t++) {
            if (thetas[t] > 90.0 && ms[i].m.kind == PM_MAT_STANDARD)
                continue;
            float wo[3];
            dir_deg(thetas[t], 0.0, wo);
            char name[128];
            snprintf(name, sizeof name, "%s at %.0f degrees", ms[i].name, thetas[t]);
            chi2_one(name, &ms[i].m, wo, 100 + t);
        }
}

/* (e) Stiff cases: widths 0, 1e-4, 1e-3 and 1, indices 1, 1.0001, 3 and 1e6, grazing and
 * horizontal directions: eval, pdf, sample and the albedo estimate stay finite and >= 0. */
static void test_bsdf_stiff(void **state)
{
    (void)state;
    const float alphas[] = {0.0f, 1e-4f, 1e-3f, 0.5f, 1.0f}, iors[] = {1.0f, 1.0001f, 1.5f, 3.0f, 1e6f, 0.5f};
    const double thetas[] = {0.0, 89.9, 89.999, 90.0, 90.001, 179.9, 180.0};
    int checked = 0;
    for (int kind = PM_MAT_STANDARD; kind <= PM_MAT_PLASTIC; kind++)
        for (size_t a = 0; a < sizeof alphas / sizeof alphas[0]; a++)
            for (size_t e = 0; e < sizeof iors / sizeof iors[0]; e++) {
                pm_material_t m = base(kind);
                m.alpha = alphas[a], m.ior = iors[e], m.ns = alphas[a] * 1000.0f;
                for (int k = 0; k < 3; k++)
                    m.kd[k] = 0.5f, m.ks[k] = 0.5f, m.kr[k] = 1.0f, m.f0[k] = 1.0f;
                if (e == 3) /* a complex index too */
                    for (int k = 0; k < 3; k++)
                        m.eta[k] = 0.2f, m.k[k] = 3.0f;
                for (size_t i = 0; i < sizeof thetas / sizeof thetas[0]; i++)
                    for (size_t o = 0; o < sizeof thetas / sizeof thetas[0]; o++) {
                        float wi[3], wo[3], f[3], al[3];
                        dir_deg(thetas[i], 10.0, wi);
                        dir_deg(thetas[o], 190.0, wo);
                        for (int mode = 0; mode < 2; mode++) {
                            pm_bsdf_eval(&m, N_UP, wi, wo, (pm_bsdf_mode_t)mode, f);
                            float p = pm_bsdf_pdf_wi(&m, N_UP, wi, wo);
                            pm_bsdf_sample_t s;
                            int ok = pm_bsdf_sample_wi(&m, N_UP, wo, 0.3f, 0.7f, 0.2f, (pm_bsdf_mode_t)mode, &s);
                            int ok2 =
                                pm_bsdf_sample_wi(&m, N_UP, wo, 0.9f, 0.999999f, 0.999999f, (pm_bsdf_mode_t)mode, &s);
                            if (!finite3(f) || !(f[0] >= 0.0f) || !isfinite(p) || !(p >= 0.0f) || !finite3(s.weight) ||
                                !finite3(s.wi) || !isfinite(s.pdf) || (ok && !(s.weight[0] >= 0.0f)))
                                fail_msg("kind %d alpha %g ior %g: wi %.3f deg, wo %.3f deg: f %g pdf %g sample %d/%d "
                                         "weight %g pdf %g",
                                         kind, alphas[a], iors[e], thetas[i], thetas[o], f[0], p, ok, ok2, s.weight[0],
                                         s.pdf);
                        }
                        pm_bsdf_albedo_wo(&m, N_UP, wo, al);
                        for (int k = 0; k < 3; k++)
                            if (!(al[k] >= 0.0f && al[k] <= 1.0f))
                                fail_msg("kind %d alpha %g ior %g: albedo estimate %g", kind, alphas[a], iors[e],
                                         al[k]);
                        checked++;
                    }
            }
    assert_true(checked > 1000);
    /* The rough glass of index 1 straight through: wi = -wo exactly makes the generalized half
     * vector 0; f and pdf are 0 there, not NaN. */
    pm_material_t m = rough_glass(1.0f, 0.3f);
    float wo[3], wi[3], f[3];
    dir_deg(30.0, 0.0, wo);
    for (int k = 0; k < 3; k++)
        wi[k] = -wo[k];
    pm_bsdf_eval(&m, N_UP, wi, wo, PM_BSDF_RADIANCE, f);
    assert_true(finite3(f) && isfinite(pm_bsdf_pdf_wi(&m, N_UP, wi, wo)));
}

/* (f) What callers choose behaviour by: the lobes of each kind, delta-only equal to
 * pm_material_is_specular, and where photons are stored. */
static void test_bsdf_lobes(void **state)
{
    (void)state;
    pm_material_t mirror = base(PM_MAT_MIRROR), glass = base(PM_MAT_GLASS);
    assert_true(pm_bsdf_is_delta(&mirror) && pm_bsdf_is_delta(&glass) && pm_bsdf_transmits(&glass));
    for (int kind = PM_MAT_STANDARD; kind <= PM_MAT_PLASTIC; kind++)
        for (int a = 0; a < 4; a++) {
            pm_material_t m = base(kind);
            const float al[] = {0.0f, 5e-4f, PM_MAT_ALPHA_DELTA, 0.5f};
            m.alpha = al[a];
            m.kd[0] = 0.5f;
            assert_int_equal(pm_bsdf_is_delta(&m), pm_material_is_specular(&m));
            if (pm_bsdf_is_delta(&m))
                assert_false(pm_bsdf_has_density(&m) || pm_bsdf_stores_photons(&m));
        }
    pm_material_t c = conductor_f0(1.0f, 0.0f), c2 = conductor_f0(1.0f, 0.3f), p = plastic(0.5f, 1.5f, 0.0f),
                  rg = rough_glass(1.5f, 0.3f);
    assert_true(pm_bsdf_is_delta(&c) && !pm_bsdf_stores_photons(&c));
    assert_true(!pm_bsdf_is_delta(&c2) && pm_bsdf_stores_photons(&c2) && pm_material_is_glossy(&c2));
    assert_true(!pm_bsdf_is_delta(&p) && pm_bsdf_stores_photons(&p) && (pm_bsdf_lobes(&p) & PM_BSDF_DELTA));
    assert_true(pm_bsdf_has_density(&rg) && pm_bsdf_transmits(&rg) && !pm_bsdf_stores_photons(&rg));
    pm_material_t black = standard(0.0f, 0.0f, 0.0f);
    assert_false(pm_bsdf_has_density(&black) || pm_bsdf_stores_photons(&black));
}

/* (g) The building blocks: D normalized, the visible-normal pdf a density, the Fresnel
 * functions at their closed forms, the plastic's internal average against a finer quadrature. */
static void test_bsdf_microfacet_fresnel(void **state)
{
    (void)state;
    const float alphas[] = {0.05f, 0.2f, 0.6f, 1.0f};
    for (size_t a = 0; a < sizeof alphas / sizeof alphas[0]; a++) {
        /* integral of D cos over the hemisphere of h, in theta_h: 2 pi integral D cos sin dtheta
         * (theta resolves a narrow peak where cos would not) */
        double acc = 0.0;
        const int n = 200000;
        for (int i = 0; i < n; i++) {
            double t = (i + 0.5) * (M_PI / 2.0) / n;
            acc += pm_ggx_d(alphas[a], (float)cos(t)) * cos(t) * sin(t);
        }
        acc *= 2.0 * M_PI * (M_PI / 2.0) / n;
        if (fabs(acc - 1.0) > 2e-3)
            fail_msg("GGX alpha %g: integral of D cos %.5f", alphas[a], acc);
        /* the visible normals of v at 70 degrees: D_v integrates to 1 over h */
        float v[3];
        dir_deg(70.0, 0.0, v);
        double vis = 0.0;
        const int nt = 4000, np = 400;
        for (int i = 0; i < nt; i++) {
            double t = (i + 0.5) * (M_PI / 2.0) / nt, c = cos(t), s = sin(t);
            for (int j = 0; j < np; j++) {
                double p = (j + 0.5) * 2.0 * M_PI / np;
                float h[3] = {(float)(s * cos(p)), (float)(s * sin(p)), (float)c};
                vis += pm_ggx_visible_pdf(alphas[a], v[2], (float)c, pm_dot3(v, h)) * s;
            }
        }
        vis *= ((M_PI / 2.0) / nt) * (2.0 * M_PI / np);
        if (fabs(vis - 1.0) > 5e-3)
            fail_msg("GGX alpha %g: visible normals of 70 degrees integrate to %.5f", alphas[a], vis);
    }
    /* conductor: k 0 is the dielectric; normal incidence ((n-1)^2 + k^2) / ((n+1)^2 + k^2) */
    for (int i = 0; i <= 10; i++) {
        float c = i / 10.0f;
        assert_true(fabsf(pm_fresnel_conductor(c, 1.5f, 0.0f) - pm_fresnel_dielectric(c, 1.5f)) < 1e-5f);
    }
    float e = 0.2f, k = 3.0f, r0 = ((e - 1) * (e - 1) + k * k) / ((e + 1) * (e + 1) + k * k);
    assert_true(fabsf(pm_fresnel_conductor(1.0f, e, k) - r0) < 1e-5f);
    assert_true(pm_fresnel_conductor(0.0f, e, k) == 1.0f && pm_fresnel_conductor(1e-4f, e, k) > 0.99f);
    assert_true(pm_fresnel_schlick(1.0f, 0.3f) == 0.3f && pm_fresnel_schlick(0.0f, 0.3f) == 1.0f);
    /* the internal diffuse reflectance: 0 at index 1; against 20,000 points in theta */
    assert_true(pm_fresnel_diffuse_inside(1.0f) < 1e-4f);
    const float iors[] = {1.33f, 1.5f, 2.0f, 3.0f};
    for (size_t i = 0; i < sizeof iors / sizeof iors[0]; i++) {
        double acc = 0.0;
        const int n = 20000;
        for (int j = 0; j < n; j++) {
            double t = (j + 0.5) * (M_PI / 2.0) / n;
            acc += pm_fresnel_dielectric((float)cos(t), 1.0f / iors[i]) * 2.0 * cos(t) * sin(t);
        }
        acc *= (M_PI / 2.0) / n;
        if (fabs(acc - pm_fresnel_diffuse_inside(iors[i])) > 1e-3)
            fail_msg("ior %g: inside diffuse reflectance %.5f, quadrature %.5f", iors[i],
                     pm_fresnel_diffuse_inside(iors[i]), acc);
    }
}

/* (h) The standard kind keeps the tracers' arithmetic: the mixture's sample is its lobe sample,
 * eval is kd / pi plus the Phong lobe, and the smooth limits sample what the specular path did. */
static void test_bsdf_standard_and_limits(void **state)
{
    (void)state;
    pm_material_t m = standard(0.4f, 0.5f, 20.0f);
    float wo[3];
    dir_deg(40.0, 0.0, wo);
    pm_rng_t rng;
    pm_rng_init(&rng, 5, 0);
    for (int i = 0; i < 2000; i++) {
        float u = pm_rng_float(&rng), u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng), wi[3];
        pm_bsdf_sample_t s;
        int ok = pm_bsdf_sample_wi(&m, N_UP, wo, u, u1, u2, PM_BSDF_RADIANCE, &s);
        int lobe = u < pm_bsdf_standard_diffuse_share(&m) ? 0 : 1;
        int above = pm_bsdf_standard_sample_lobe(&m, lobe, N_UP, wo, u1, u2, wi);
        assert_int_equal(ok, above);
        if (ok)
            assert_memory_equal(wi, s.wi, sizeof wi);
    }
    /* a rough glass below the smooth limit samples exactly what glass samples */
    pm_material_t g = base(PM_MAT_GLASS), rg = rough_glass(1.5f, 5e-4f);
    for (int i = 0; i < 200; i++) {
        float u = pm_rng_float(&rng), w[3];
        dir_deg(180.0 * pm_rng_float(&rng), 0.0, w);
        pm_bsdf_sample_t a, b;
        int oa = pm_bsdf_sample_wi(&g, N_UP, w, u, 0.5f, 0.5f, PM_BSDF_RADIANCE, &a);
        int ob = pm_bsdf_sample_wi(&rg, N_UP, w, u, 0.5f, 0.5f, PM_BSDF_RADIANCE, &b);
        assert_int_equal(oa, ob);
        assert_memory_equal(&a, &b, sizeof a);
    }
    /* a smooth conductor reflects into the mirror direction with weight F(n.wo) */
    pm_material_t c = gold(0.0f);
    pm_bsdf_sample_t s;
    assert_true(pm_bsdf_sample_wi(&c, N_UP, wo, 0.5f, 0.5f, 0.5f, PM_BSDF_RADIANCE, &s));
    assert_true(fabsf(s.wi[0] + wo[0]) < 1e-6f && fabsf(s.wi[2] - wo[2]) < 1e-6f);
    for (int k = 0; k < 3; k++)
        assert_true(fabsf(s.weight[k] - pm_fresnel_conductor(wo[2], c.eta[k], c.k[k])) < 1e-6f);
    /* a glass transmission carries 1 / eta^2 of radiance and all of a photon's power */
    dir_deg(0.0, 0.0, wo);
    pm_bsdf_sample_t r, p;
    assert_true(pm_bsdf_sample_wi(&g, N_UP, wo, 0.99f, 0.0f, 0.0f, PM_BSDF_RADIANCE, &r));
    assert_true(pm_bsdf_sample_wi(&g, N_UP, wo, 0.99f, 0.0f, 0.0f, PM_BSDF_IMPORTANCE, &p));
    assert_true(r.lobe & PM_BSDF_TRANSMIT);
    assert_true(fabsf(r.weight[0] - 1.0f / 2.25f) < 1e-6f && p.weight[0] == 1.0f && r.eta == 1.5f);
}

/* (i) The queries header's material table carries every kind's fields, and its reader refuses
 * an entry out of range or not a number with one line naming the key, the field and the value. */
static void test_bsdf_queries_material_table(void **state)
{
    (void)state;
    pm_material_t m[4] = {gold(0.3f), rough_glass(1.33f, 0.2f), plastic(0.6f, 1.5f, 0.05f), standard(0.5f, 0.2f, 9.0f)};
    m[0].f0[1] = 0.5f, m[1].tf[2] = 0.25f;
    snprintf(m[0].name, sizeof m[0].name, "gold");
    pm_header_t h;
    pm_header_init(&h, &pm_queries_schema);
    assert_int_equal(pm_queries_set_materials(&h, m, 4), PM_OK);
    pm_material_t *back;
    size_t n;
    assert_int_equal(pm_queries_get_materials(&h, "t.pm", &back, &n), PM_OK);
    assert_int_equal(n, 4);
    for (size_t i = 0; i < 4; i++) {
        assert_int_equal(back[i].kind, m[i].kind);
        assert_true(back[i].alpha == m[i].alpha &&
                    (m[i].kind == PM_MAT_CONDUCTOR || m[i].kind == PM_MAT_STANDARD || back[i].ior == m[i].ior));
        for (int k = 0; k < 3; k++)
            assert_true(back[i].eta[k] == m[i].eta[k] && back[i].k[k] == m[i].k[k] && back[i].f0[k] == m[i].f0[k] &&
                        back[i].tf[k] == m[i].tf[k] && back[i].kd[k] == m[i].kd[k]);
    }
    free(back);
    /* each bad value refused, the message naming it */
    const struct {
        int which;
        const char *from, *to, *want;
    } bad[] = {
        {0, "conductor alpha 0.300000012", "conductor alpha 1.5", "material.0 conductor alpha 1.5 outside [0, 1]"},
        {0, "conductor alpha 0.300000012", "conductor alpha nan", "material.0 conductor alpha nan outside [0, 1]"},
        {0, "k 3.42000008", "k -1", "material.0 conductor eta 0.18 k -1 (channel 0)"},
        {0, "eta 0.180000007", "eta 0", "material.0 conductor eta 0.42 k 2.35 (channel 1)"},
        {0, "f0 0 0.5", "f0 0 1.5", "material.0 conductor f0 1.5 (channel 1) outside [0, 1]"},
        {1, "ior 1.33000004", "ior 0", "material.1 roughglass ior 0 outside (0, 1e6]"},
        {1, "tf 1 1 0.25", "tf 1 1 inf", "material.1 roughglass tf inf (channel 2) outside [0, 1]"},
        {2, "ks 0 0 0", "ks 0.1 0 0", "material.2 plastic has kd 0.6, ks 0.1 (channel 0); want ks 0"},
        {2, "plastic alpha 0.0500000007", "plastic alpha -0.1", "material.2 plastic alpha -0.1 outside [0, 1]"},
        {2, "plastic alpha 0.0500000007 ior 1.5", "plastic alpha 0.05", "header key material.2 is not"},
    };
    for (size_t b = 0; b < sizeof bad / sizeof bad[0]; b++) {
        char key[32], val[512];
        snprintf(key, sizeof key, "material.%d", bad[b].which);
        const char *v = pm_header_get(&h, key);
        const char *at = strstr(v, bad[b].from);
        if (!at)
            fail_msg("'%s' not in '%s'", bad[b].from, v);
        snprintf(val, sizeof val, "%.*s%s%s", (int)(at - v), v, bad[b].to, at + strlen(bad[b].from));
        pm_header_t h2;
        pm_header_init(&h2, &pm_queries_schema);
        assert_int_equal(pm_queries_set_materials(&h2, m, 4), PM_OK);
        assert_int_equal(pm_header_set(&h2, key, "%s", val), PM_OK);
        assert_int_equal(pm_queries_get_materials(&h2, "t.pm", &back, &n), PM_ERR_INPUT);
        const char *msg = pm_error_message();
        if (!strstr(msg, bad[b].want) || strchr(msg, '\n'))
            fail_msg("'%s': message '%s', want '%s'", val, msg, bad[b].want);
        pm_header_free(&h2);
    }
    pm_header_free(&h);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_bsdf_white_furnace),
    cmocka_unit_test(test_bsdf_reciprocity),
    cmocka_unit_test(test_bsdf_pdf_integrates),
    cmocka_unit_test(test_bsdf_sampler_chi2),
    cmocka_unit_test(test_bsdf_stiff),
    cmocka_unit_test(test_bsdf_lobes),
    cmocka_unit_test(test_bsdf_microfacet_fresnel),
    cmocka_unit_test(test_bsdf_standard_and_limits),
    cmocka_unit_test(test_bsdf_queries_material_table),
};

UNIT_GROUP(bsdf_group, "bsdf", tests)
