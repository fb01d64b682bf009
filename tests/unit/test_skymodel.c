/* test_skymodel.c: the Preetham et al. 1999 sky (render/skymodel.h) against the paper's formulas
 * evaluated independently (the literals below were computed in double precision by a separate
 * script from the formulas of the paper's appendix A.2, not by this code): the zenith's
 * luminance and chromaticity at four turbidities and sun positions, the Perez function, the
 * zenith's normalisation F(theta, gamma) / F(0, theta_s), and the tabulated map: each pixel's
 * RGB turned back into xyY is the model at the pixel's centre, the ground is black, the sky is
 * mirror-symmetric about the sun's meridian and brightest about the sun. */
#include <math.h>
#include <stdlib.h>

#include "render/skymodel.h"
#include "unit.h"

static void near(const char *what, double got, double want, double rel)
{
    if (!(fabs(got - want) <= rel * fabs(want)))
        fail_msg("%s: %.9g, the paper's formula gives %.9g", what, got, want);
}

static void test_preetham_zenith(void **state)
{
    (void)state;
    /* turbidity, theta_s (degrees), Y_z (kcd/m^2), x_z, y_z */
    static const double cases[][5] = {
        {2, 0, 15.5006721, 0.26674, 0.2772},
        {3, 30, 10.4130869, 0.253434184, 0.259792522},
        {6, 60, 9.58526981, 0.265467947, 0.281788814},
        {10, 80, 4.76060104, 0.306355829, 0.331475294},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double z[3];
        pm_preetham_zenith(cases[i][0], cases[i][1] * M_PI / 180.0, z);
        near("zenith Y", z[0], cases[i][2], 1e-7);
        near("zenith x", z[1], cases[i][3], 1e-7);
        near("zenith y", z[2], cases[i][4], 1e-7);
    }
}

static void test_preetham_perez(void **state)
{
    (void)state;
    double c[5], Yxy[3], z[3];
    pm_preetham_coefficients(3.0, 0, c);
    near("coefficient A_Y at T 3", c[0], 0.1787 * 3 - 1.4630, 1e-12);
    near("coefficient D_Y at T 3", c[3], 0.1206 * 3 - 2.5771, 1e-12);
    near("F(45, 20) at T 3", pm_perez(c, 45 * M_PI / 180, 20 * M_PI / 180), 2.2325024, 1e-7);
    near("F(0, 30) at T 3", pm_perez(c, 0, 30 * M_PI / 180), 1.41700772, 1e-7);
    /* toward the zenith gamma is theta_s: the model is the zenith's values exactly */
    pm_preetham_zenith(4.0, 0.7, z);
    pm_preetham_Yxy(4.0, 0.7, 0.0, 0.7, Yxy);
    for (int k = 0; k < 3; k++)
        near("Yxy at the zenith", Yxy[k], z[k], 1e-12);
}

static void test_preetham_map(void **state)
{
    (void)state;
    enum { W = 64, H = 32 };
    double ts = 50 * M_PI / 180.0, sun[3] = {sin(ts), cos(ts), 0.0}; /* azimuth 0: toward +x */
    float *rgb;
    assert_int_equal(pm_preetham_map(3.0, sun, W, H, &rgb), PM_OK);
    double best = -1.0;
    int bx = 0, by = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const float *p = rgb + 3 * (y * W + x);
            if (y >= H / 2) {
                if (p[0] != 0.0f || p[1] != 0.0f || p[2] != 0.0f)
                    fail_msg("pixel (%d, %d) below the horizon is not black", x, y);
                continue;
            }
            const float *q = rgb + 3 * (y * W + (W - 1 - x)); /* mirrored about the sun's meridian */
            for (int k = 0; k < 3; k++)
                near("mirror pixel", q[k], p[k], 1e-5);
            double th = M_PI * (y + 0.5) / H, ph = 2.0 * M_PI * (x + 0.5) / W;
            double m[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            double g = acos(fmin(1.0, m[0] * sun[0] + m[1] * sun[1] + m[2] * sun[2])), want[3];
            pm_preetham_Yxy(3.0, ts, th, g, want);
            /* back to XYZ by the sRGB primaries, then xyY, Y in kcd/m^2 */
            double X = 0.4124564 * p[0] + 0.3575761 * p[1] + 0.1804375 * p[2];
            double Y = 0.2126729 * p[0] + 0.7151522 * p[1] + 0.0721750 * p[2];
            double Z = 0.0193339 * p[0] + 0.1191920 * p[1] + 0.9503041 * p[2];
            if (p[0] > 0.0f && p[1] > 0.0f && p[2] > 0.0f) { /* no channel clipped */
                near("map Y", Y * 683.0 / 1000.0, want[0], 1e-4);
                near("map x", X / (X + Y + Z), want[1], 1e-4);
                near("map y", Y / (X + Y + Z), want[2], 1e-4);
            }
            if (Y > best)
                best = Y, bx = x, by = y;
        }
    double th = M_PI * (by + 0.5) / H, ph = 2.0 * M_PI * (bx + 0.5) / W;
    double g = acos(sin(th) * cos(ph) * sun[0] + cos(th) * sun[1]) * 180.0 / M_PI;
    if (!(g < 10.0))
        fail_msg("the brightest pixel (%d, %d) is %.3g degrees from the sun", bx, by, g);
    free(rgb);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_preetham_zenith),
    cmocka_unit_test(test_preetham_perez),
    cmocka_unit_test(test_preetham_map),
};
UNIT_GROUP(skymodel_group, "skymodel", tests)
