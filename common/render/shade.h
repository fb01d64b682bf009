/* shade.h: the eye side of the scene model that trace-gather-points and trace-reference share:
 * the pinhole camera and the keys an image-shaped output starts with. The physics (the BRDF,
 * per-triangle front normals, the MIS weight) is render/transport.h and the lights are
 * render/light.h, both included here so that the eye tracers reach all of it through this header.
 *
 * Units: metres; radiance W/(m^2 sr). */
#ifndef PM_SHADE_H
#define PM_SHADE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "formats/pmfile.h"
#include "render/light.h"
#include "render/scene.h"
#include "render/transport.h"

/* A pinhole camera for a w x h image: pixel (px, py) in [0, w) x [0, h), y down. */
typedef struct {
    float eye[3], fwd[3], right[3], up[3];
    float tan_half, aspect;
    uint32_t w, h;
} pm_camera_rays_t;

void pm_camera_setup(const pm_camera_t *cam, uint32_t w, uint32_t h, pm_camera_rays_t *out);
/* Unit direction of the ray through image point (px, py). */
void pm_camera_dir(const pm_camera_rays_t *c, float px, float py, float d_out[3]);

/* Where in its pixel a camera ray starts. box: the pixel is an area and its value the mean
 * radiance over it (a box filter, as pbrt, Mitsuba and LuxCore compute with theirs); center:
 * every ray through the pixel's centre, a point sample of the image. Zero is box, the default. */
enum { PM_PIXEL_BOX = 0, PM_PIXEL_CENTER = 1 };
extern const char *const pm_pixel_names[]; /* "box", "center", NULL: option words and header values */

/* Offset in [0, 1)^2 of ray k of a pixel: point k of a (0,2)-sequence in base 2 (the radical
 * inverse and Sobol's second dimension), its bits XOR-scrambled by (sx, sy), the pixel's own
 * uniform random words. Each point alone is uniform over the pixel; the first 2^m points of a
 * pixel fall one in each of its 2^m elementary intervals of any shape (2^m strata), whatever
 * the scramble, so any prefix of rays is stratified. */
void pm_pixel_offset(uint32_t k, uint32_t sx, uint32_t sy, float *jx_out, float *jy_out);

/* The keys every image-shaped output of a scene starts with: this command's COMMAND line, the
 * scene bounds, SCENE (name and content hash), width and height. */
pm_result_t pm_image_header_begin(pm_header_t *h, int argc, char **argv, const pm_scene_t *s, uint32_t w, uint32_t ht);

#endif
