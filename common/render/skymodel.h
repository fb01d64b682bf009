/* skymodel.h: the physical sky of Preetham, Shirley and Smits, "A Practical Analytic Model for
 * Daylight" (SIGGRAPH 1999): the clear sky's luminance and chromaticity for a turbidity T and
 * the sun's position, by the Perez sky function, tabulated into a lat-long map (the sky's
 * `model`, docs/scene-format.md) that the light module samples like any map.
 *
 * Units: angles in radians; luminance Y in kcd/m^2 (as the paper gives it); the map holds
 * linear Rec. 709 RGB radiance in W/(m^2 sr) with Y converted at 683 lm/W. */
#ifndef PM_SKYMODEL_H
#define PM_SKYMODEL_H

#include <stdint.h>

#include "base/error.h"

/* The turbidities the model was fitted for, and so accepted. */
#define PM_PREETHAM_T_MIN 2.0
#define PM_PREETHAM_T_MAX 10.0

/* The Perez function F(theta, gamma) = (1 + A e^(B / cos theta)) (1 + C e^(D gamma) + E cos^2 gamma)
 * with c = {A, B, C, D, E}; theta the view direction's angle from the zenith (< pi / 2), gamma its
 * angle from the sun. */
double pm_perez(const double c[5], double theta, double gamma);

/* The paper's coefficients A..E for luminance Y (channel 0), chromaticity x (1) and y (2) at
 * turbidity t (appendix A.2: linear in t). */
void pm_preetham_coefficients(double t, int channel, double c_out[5]);

/* The zenith's luminance Y_z (kcd/m^2) and chromaticity x_z, y_z for turbidity t with the sun
 * theta_s from the zenith (appendix A.2): Yxy_out = {Y_z, x_z, y_z}. */
void pm_preetham_zenith(double t, double theta_s, double Yxy_out[3]);

/* The sky's luminance and chromaticity toward a direction theta from the zenith, gamma from
 * the sun: each of Y, x, y is its zenith value times F(theta, gamma) / F(0, theta_s). */
void pm_preetham_Yxy(double t, double theta_s, double theta, double gamma, double Yxy_out[3]);

/* Yxy (Y in kcd/m^2) as linear Rec. 709 RGB radiance, W/(m^2 sr): XYZ from xyY, Y * 1000 / 683,
 * then the sRGB primaries' matrix; a channel below 0 (outside the gamut) clipped to 0. */
void pm_preetham_rgb(const double Yxy[3], float rgb_out[3]);

/* The sky as a w x h lat-long map in its own frame (+y the zenith, the map layout of
 * pm_envmap_t): sun_m is the unit direction toward the sun in that frame, above the horizon
 * (sun_m[1] > 0); the lower hemisphere is black (no ground). rgb_out: w * h * 3 floats,
 * allocated here (the caller frees). An error on running out of memory. */
pm_result_t pm_preetham_map(double t, const double sun_m[3], uint32_t w, uint32_t h, float **rgb_out);

#endif
