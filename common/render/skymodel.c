/* skymodel.c: the Preetham et al. 1999 daylight sky (skymodel.h), tabulated into a lat-long map
 * for the sky light (render/scene_json.c loads it, render/light.c samples it as a map). Only
 * the sky's luminance distribution: the sun itself is the scene's sun light, whose direction
 * the sky follows. */
#include "render/skymodel.h"

#include <math.h>
#include <stdlib.h>

double pm_perez(const double c[5], double theta, double gamma)
{
    double cg = cos(gamma);
    return (1.0 + c[0] * exp(c[1] / cos(theta))) * (1.0 + c[2] * exp(c[3] * gamma) + c[4] * cg * cg);
}

void pm_preetham_coefficients(double t, int channel, double c[5])
{
    /* Appendix A.2: rows Y, x, y; each coefficient a t + b as {a, b}. */
    static const double k[3][5][2] = {
        {{0.1787, -1.4630}, {-0.3554, 0.4275}, {-0.0227, 5.3251}, {0.1206, -2.5771}, {-0.0670, 0.3703}},
        {{-0.0193, -0.2592}, {-0.0665, 0.0008}, {-0.0004, 0.2125}, {-0.0641, -0.8989}, {-0.0033, 0.0452}},
        {{-0.0167, -0.2608}, {-0.0950, 0.0092}, {-0.0079, 0.2102}, {-0.0441, -1.6537}, {-0.0109, 0.0529}},
    };
    for (int i = 0; i < 5; i++)
        c[i] = k[channel][i][0] * t + k[channel][i][1];
}

void pm_preetham_zenith(double t, double ts, double out[3])
{
    /* Y_z = (4.0453 T - 4.9710) tan chi - 0.2155 T + 2.4192, chi = (4/9 - T/120)(pi - 2 theta_s). */
    double chi = (4.0 / 9.0 - t / 120.0) * (M_PI - 2.0 * ts);
    out[0] = (4.0453 * t - 4.9710) * tan(chi) - 0.2155 * t + 2.4192;
    /* x_z, y_z: (T^2, T, 1) times a matrix times (theta_s^3, theta_s^2, theta_s, 1). */
    static const double mx[3][4] = {{0.00166, -0.00375, 0.00209, 0.0},
                                    {-0.02903, 0.06377, -0.03202, 0.00394},
                                    {0.11693, -0.21196, 0.06052, 0.25886}};
    static const double my[3][4] = {{0.00275, -0.00610, 0.00317, 0.0},
                                    {-0.04214, 0.08970, -0.04153, 0.00516},
                                    {0.15346, -0.26756, 0.06670, 0.26688}};
    double tv[3] = {t * t, t, 1.0}, sv[4] = {ts * ts * ts, ts * ts, ts, 1.0};
    out[1] = out[2] = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++) {
            out[1] += tv[i] * mx[i][j] * sv[j];
            out[2] += tv[i] * my[i][j] * sv[j];
        }
}

void pm_preetham_Yxy(double t, double ts, double theta, double gamma, double out[3])
{
    double z[3], c[5];
    pm_preetham_zenith(t, ts, z);
    for (int k = 0; k < 3; k++) {
        pm_preetham_coefficients(t, k, c);
        out[k] = z[k] * pm_perez(c, theta, gamma) / pm_perez(c, 0.0, ts);
    }
}

void pm_preetham_rgb(const double Yxy[3], float rgb[3])
{
    double Y = Yxy[0] * 1000.0 / 683.0, x = Yxy[1], y = Yxy[2];
    double X = y > 0.0 ? x * Y / y : 0.0, Z = y > 0.0 ? (1.0 - x - y) * Y / y : 0.0;
    double r = 3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z;
    double g = -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z;
    double b = 0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z;
    rgb[0] = (float)fmax(r, 0.0), rgb[1] = (float)fmax(g, 0.0), rgb[2] = (float)fmax(b, 0.0);
}

pm_result_t pm_preetham_map(double t, const double sun[3], uint32_t w, uint32_t h, float **rgb_out)
{
    float *rgb = malloc((size_t)w * h * 3 * sizeof *rgb);
    *rgb_out = NULL;
    if (!rgb)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %ux%u sky map", (unsigned)w, (unsigned)h);
    double ts = acos(fmin(1.0, fmax(-1.0, sun[1])));
    for (uint32_t y = 0; y < h; y++) {
        /* Each pixel holds the model at its centre, like a map read from a file. */
        double th = M_PI * (y + 0.5) / h;
        for (uint32_t x = 0; x < w; x++) {
            float *p = rgb + 3 * ((size_t)y * w + x);
            if (!(th < 0.5 * M_PI)) {
                p[0] = p[1] = p[2] = 0.0f;
                continue;
            }
            double ph = 2.0 * M_PI * (x + 0.5) / w;
            double m[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            double cg = fmin(1.0, fmax(-1.0, m[0] * sun[0] + m[1] * sun[1] + m[2] * sun[2])), Yxy[3];
            pm_preetham_Yxy(t, ts, th, acos(cg), Yxy);
            pm_preetham_rgb(Yxy, p);
        }
    }
    *rgb_out = rgb;
    return PM_OK;
}
