/* light.h: the lights of the scene model, one module for every tracer: the photon tracer
 * (render/photontrace.c) emits from them, the eye-ray tracer of trace-gather-points
 * (render/eyetrace.c) and the reference path tracer (render/pathtrace.c) sample them for direct
 * light and weigh what their own rays find against those samples. The tracers loop over a
 * light set (pm_lights_t) and never ask what kind a light is: light.c alone switches on the
 * kind, so that a new kind is that switch, the scene reader and their docs and tests.
 *
 * The kinds are what the scene model loads (render/scene.h): point lights of intensity I (W/sr),
 * spots (the same with a cone and a falloff), emissive triangles of radiance Ke (W/(m^2 sr)) from
 * their front face (both with the scene key two_sided_lights or their material's two_sided:
 * pm_scene_emits_both), the sun (a disc of radiance L at
 * infinity) and the sky (a constant radiance or a lat-long map, at infinity).
 *
 * Units: metres; power W; intensity W/sr; radiance W/(m^2 sr); pdfs over solid angle 1/sr,
 * over area 1/m^2. */
#ifndef PM_LIGHT_H
#define PM_LIGHT_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "math/rng.h"
#include "render/scene.h"

typedef enum {
    PM_LIGHT_POINT, /* isotropic point light, s->lights[index] */
    PM_LIGHT_SPOT,  /* point light with a cone or a falloff, s->lights[index] */
    PM_LIGHT_AREA,  /* emissive triangle `index`; in the direct list, every emissive triangle together */
    PM_LIGHT_SUN,   /* s->sun */
    PM_LIGHT_SKY,   /* s->sky, or its map s->envmap */
    PM_LIGHT_KINDS
} pm_light_kind_t;

/* One light of the set. */
typedef struct {
    pm_light_kind_t kind;
    uint32_t index;  /* see pm_light_kind_t; 0 for the sun and the sky */
    double power[3]; /* W per channel (pm_light_power) */
    double weight;   /* W: power[0] + power[1] + power[2], what light choice is in proportion to */
    int delta;       /* 1: a point or a spot, which no ray can hit (one sample, no random numbers, no MIS) */
    int infinite;    /* 1: at infinity (sun, sky): its shadow rays are unbounded, rays that escape find it */
} pm_light_t;

/* The lights of a scene, built once after loading it and read by any number of threads. */
typedef struct {
    const pm_scene_t *s;
    /* Emission: every light of positive power, point lights and spots in scene order, then the
     * emissive triangles in s->emissive order, then the sun, then the sky. */
    pm_light_t *light;
    size_t n;
    double *cdf;  /* n: probability of choosing lights 0..i in proportion to weight, the last 1 */
    double total; /* W: the sum of the weights */
    /* Next-event estimation: each point light and spot, the emissive triangles as one area light
     * sampled uniformly by area, the sun and the sky, each present in the scene (power 0 or not),
     * in that order: the first ndelta are the delta lights. */
    pm_light_t *direct;
    size_t ndirect, ndelta;
    size_t nlights; /* point lights, emissive triangles, sun and sky: every light of the scene */
    /* The area lights, uniform by area: cumulative area ending at exactly 1, total area (m^2),
     * unit front normals (3 per emissive triangle, in double before rounding). */
    double *area_cdf;
    double area;
    float *front;
    /* The sun's cone frame (pm_onb of its direction): built once, not per sample. */
    float sun_t[3], sun_b[3];
} pm_lights_t;

/* Builds the set of scene s (which must outlive it); an error on running out of memory. */
pm_result_t pm_lights_init(const pm_scene_t *s, pm_lights_t *out);
void pm_lights_free(pm_lights_t *l);

/* "point", "spot", "area", "sun", "sky". */
const char *pm_light_kind_name(pm_light_kind_t kind);

/* Light l's emitted power in channel k, W: 4 pi I for a point light, 2 pi I (1 - cos_cone) /
 * (falloff + 1) for a spot, pi Ke A (twice that when two-sided) for a triangle, and for the sun
 * and the sky the power their photons carry into the scene's bounding sphere (pm_sun_power,
 * pm_sky_power). */
double pm_light_power(const pm_scene_t *s, pm_light_kind_t kind, uint32_t index, int k);

/* The sun's (power_out[0]) and the sky's (power_out[1]) power through s's portals, W, RGB: the
 * mean flux pm_light_sample_le gives their photons. The sun's at its cone's axis, exact while the
 * cone lies wholly in front of each portal; a sky map's summed over its pixels at their centres. */
void pm_portals_power(const pm_scene_t *s, double power_out[2][3]);

/* The emission light chosen by uniform u in [0, 1): index into L->light, in proportion to weight. */
size_t pm_lights_pick(const pm_lights_t *L, double u);

/* A photon of light l from four uniforms in [0, 1): its origin (m; an area light's is lifted eps
 * m off the surface on the side it leaves), unit direction, and flux_out, W per channel: the
 * light's power were this its only photon, so that its mean over photons is l->power (the sun's
 * and the sky's differ by direction for a map: L(w) pi R^2 / pdf(w)). Point lights and spots:
 * a direction distributed as the intensity; triangles: a uniform point, cosine-weighted about the
 * emitting face (either face by half of u3 when two-sided); sun and sky: a direction of the
 * light, then a point on the disc of radius R facing it, tangent to pm_scene_sphere; with portals
 * (s->portals), a point uniform over their area and flux L(w) A cos / pdf(w), 0 for a photon that
 * would leave through a portal's back (a caller traces none of those, and counts them emitted). */
void pm_light_sample_le(const pm_lights_t *L, const pm_light_t *l, float u1, float u2, float u3, float u4, float eps,
                        float org_out[3], float dir_out[3], double flux_out[3]);

/* A direct-light sample at a shading point. The estimate of the light reflected toward wo is
 * f(wi, wo) Li cosx / pdf (times a MIS weight where another strategy can find the light). */
typedef struct {
    float wi[3];  /* unit, from the shading point toward the light */
    float r, r2;  /* m to the point on the light and its square, m^2; INFINITY for a light at infinity */
    float cosx;   /* cosine of wi to the shading normal, > 0 */
    float cosy;   /* cosine at the light's emitting face (area lights), else 1 */
    float Li[3];  /* incident radiance W/(m^2 sr); a delta light's irradiance at normal incidence, I s / r^2 (W/m^2) */
    float pdf;    /* solid-angle pdf of wi, 1/sr; 1 for a delta light */
    int delta;    /* a point light or spot: pdf is not a density, no MIS */
    int infinite; /* the sun or the sky */
} pm_light_li_t;

/* Samples direct light i (0 <= i < L->ndirect) from point p (m) with shading normal n (unit).
 * Random numbers from rng: none for a delta light, a double (the triangle) and two floats (the
 * point) for the area lights, two floats for the sun and the sky, drawn whether or not the sample
 * is kept. Returns 1 with *out filled, 0 when it brings nothing: the light is at p, behind the
 * surface (cosx <= 0), sees p from its back, or p is outside a spot's cone or the pdf is 0. */
int pm_lights_sample_li(const pm_lights_t *L, size_t i, pm_rng_t *rng, const float p[3], const float n[3],
                        pm_light_li_t *out);
/* pm_lights_sample_li with the two floats of the point (area lights) or the direction (the sun,
 * the sky) given in u[0], u[1] (in [0, 1); a stratified set's), rng drawing the rest: the
 * area lights' triangle. u NULL draws them from rng, as pm_lights_sample_li does. */
int pm_lights_sample_li_u(const pm_lights_t *L, size_t i, pm_rng_t *rng, const float *u, const float p[3],
                          const float n[3], pm_light_li_t *out);

/* The length of sample li's shadow ray from a point lifted eps (m) off the surface: unbounded
 * for a light at infinity, r - eps for a point light, stopping short of an area light's own
 * surface by the offset and a relative margin. */
float pm_light_shadow_tmax(const pm_light_li_t *li, float eps);

/* The solid-angle pdf, 1/sr, with which pm_lights_sample_li of direct light i draws unit
 * direction w from a point with shading normal n, when a ray along w escapes the scene: nonzero
 * only for a light at infinity. */
float pm_lights_pdf_li_escape(const pm_lights_t *L, size_t i, const float n[3], const float w[3]);

/* The solid-angle pdf, 1/sr, with which the direct list's area light draws the point a ray found
 * on an emitter, dist m away, seen at cosine cos_emit (> 0) to its emitting face: dist^2 / (cos_emit A). */
float pm_lights_pdf_li_hit(const pm_lights_t *L, float dist, float cos_emit);

/* Radiance of direct light i seen along unit direction w by a ray that escaped, W/(m^2 sr); zero
 * for a light not at infinity or w outside it (the sun's cone). */
void pm_lights_le_escape_one(const pm_lights_t *L, size_t i, const float w[3], float le_out[3]);

/* Radiance, W/(m^2 sr), that a ray escaping along unit direction w brings back: the sky's plus
 * the sun's within its cone; zero in a scene with neither. */
void pm_lights_le_escape(const pm_lights_t *L, const float w[3], float le_out[3]);

/* Whether the hit on triangle tri at cosine cos_front (the triangle's front normal with the
 * direction back along the ray) sees emission: its material emits and the ray arrives at the
 * emitting face (the front, dot 0 included; either when pm_scene_emits_both). Then le_out is Ke,
 * W/(m^2 sr), and *cos_emit_out the cosine at the emitting face (>= 0). */
int pm_lights_le_hit(const pm_lights_t *L, uint32_t tri, float cos_front, float le_out[3], float *cos_emit_out);

/* Counts the lights of scene s without building a set: every light (point lights and spots,
 * emissive triangles, sun, sky, whatever their power: scene-info's lights_total) and those that
 * take light_samples direct-light samples at a shading point rather than one (all but the delta
 * lights: scene-info's sampled_lights; 0 means light_samples changes nothing). */
void pm_lights_count(const pm_scene_t *s, size_t *total_out, size_t *sampled_out);

/* scene-info's description of the lights that are not triangles (the emissive triangles are
 * counted with the materials): as text, "point lights: N" then a line per point light or spot,
 * then the sun's and the sky's lines; as a JSON array of one object per light, with "kind"
 * (pm_light_kind_name) and its parameters, units in the keys (docs/programs/scene-info.md). */
void pm_lights_describe_text(const pm_scene_t *s, FILE *out);
json_t *pm_lights_describe_json(const pm_scene_t *s);
/* The portals for scene-info --json: corner, edges, inward normal, area of each. */
json_t *pm_portals_describe_json(const pm_scene_t *s);

/* The lights that take LIGHT_SAMPLES direct-light samples a shading point (area lights, the sun,
 * the sky: scene-info's sampled_lights), and whether a ray can hit one (some triangle emits). */
size_t pm_lights_sampled(const pm_lights_t *L);
int pm_lights_has_emitters(const pm_lights_t *L);
/* Whether the light that light l brings straight to a gather point r2 m^2 from where it left l
 * is the gather point's light samples' (secondary direct light, trace-gather-points
 * --secondary-direct), its first-hit photons then left out of the map (trace-photons
 * --indirect-only), or the map's (0): the point lights, spots, the sun and a sky map (which
 * may hold a sun) always; an area light only from r2 >= L->area (its total emissive area) on.
 * Nearer, a light sample carries the emitter's 1/r^2 with no BSDF sample at the gather point
 * to share it by MIS, and made fireflies (the atrium's sky panel); the photons there stay. A
 * constant sky never: the light it brings varies slowly over a surface, which the map's
 * density estimate renders well, while a sample of it from a gather point under an arcade or
 * in a room is mostly blocked and costs a shadow ray at every gather point (measured on the
 * sky-lit atrium: variance 0.92 times, the pass 0.85 times the time; docs/accuracy.md). The
 * same function of the light point and the gather point on both sides, so each path is
 * counted once. */
int pm_light_at_gather(const pm_lights_t *L, const pm_light_t *l, float r2);
/* Which rule pm_light_at_gather follows for scene s, the value of the headers' secondary_direct
 * (trace-gather-points) and indirect_only (trace-photons): 2 when the scene has a constant sky,
 * which the rule leaves to the map since pmtk 0.1's fourth round (files that say 1 sampled it at
 * the gather points), else 1. A gather takes queries and a map of one rule only. */
int pm_light_gather_rule(const pm_scene_t *s);
/* How many lights of scene s secondary direct light may sample (0: it has nothing to do). */
size_t pm_lights_count_at_gather(const pm_scene_t *s);

/* ---- per-kind primitives (light.c's switch calls them; exposed for the unit tests) ---- */

/* The spot factor s of point light l toward unit direction w (from the light outward):
 * ((cos - cos_cone) / (1 - cos_cone))^falloff inside the cone, 0 outside; exactly 1 for an
 * isotropic light. */
float pm_spot_factor(const pm_point_light_t *l, const float w[3]);

/* A photon direction of point light l from u1, u2 in [0, 1), distributed as its intensity:
 * uniform on the sphere for an isotropic light, for a spot cos(theta) to the axis = cos_cone +
 * (1 - cos_cone) u1^(1 / (falloff + 1)) and azimuth 2 pi u2. */
void pm_point_light_emit(const pm_point_light_t *l, float u1, float u2, float dir_out[3]);
/* The solid-angle pdf, 1/sr, of pm_point_light_emit at unit direction w: s(w) (falloff + 1) /
 * (2 pi (1 - cos_cone)), 1 / (4 pi) for an isotropic light. */
float pm_point_light_emit_pdf(const pm_point_light_t *l, const float w[3]);

/* A direction in the sun's cone, uniform over its solid angle (pdf 1 / omega), from u1, u2:
 * cos(theta) to the axis = 1 - u1 (1 - cos_max), azimuth 2 pi u2. */
void pm_sun_sample(const pm_sun_t *sun, float u1, float u2, float wi_out[3]);
/* The pdf of pm_sun_sample at unit direction w, 1/sr: 1 / omega inside the cone, 0 outside. */
float pm_sun_pdf(const pm_sun_t *sun, const float w[3]);

/* A direction toward the sky for next-event estimation, from u1, u2: a constant sky's
 * cosine-weighted about n (pdf cos / pi), a map's by its pixels' luminance (the normal plays no
 * part). */
void pm_sky_sample(const pm_scene_t *s, const float n[3], float u1, float u2, float wi_out[3]);
/* The pdf of pm_sky_sample at unit direction w, 1/sr. */
float pm_sky_pdf(const pm_scene_t *s, const float n[3], const float w[3]);
/* The sky's radiance along w, W/(m^2 sr) (its map's pixel, or the constant); zero without a sky. */
void pm_sky_radiance(const pm_scene_t *s, const float w[3], float L_out[3]);

/* A map's sampler and its pdf, 1/sr: a pixel with probability pix_p (row by row_cdf, column by
 * col_cdf), then (theta, phi) uniform within it: pdf pix_p w h / (2 pi^2 sin theta). 0 for a
 * black map. */
void pm_envmap_sample(const pm_envmap_t *e, float u1, float u2, float wi_out[3]);
float pm_envmap_pdf(const pm_envmap_t *e, const float w[3]);
/* The map's pixel that direction w falls in (column, row). */
void pm_envmap_pixel(const pm_envmap_t *e, const float w[3], uint32_t *x_out, uint32_t *y_out);

#endif
