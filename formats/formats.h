/* formats.h: the file formats that flow between pmtk stages (docs/formats.md).
 *
 *   photons    trace-photons  -> build-photonmap       one record per stored photon
 *   photonmap  build-photonmap -> simd-gather          one record per KD-tree node
 *   queries    trace-gather-points -> hilbert-sort -> simd-gather   one per gather point
 *   radiance   trace-gather-points, simd-gather -> composite        one per pixel
 *   aov        trace-gather-points --aov -> composite --aov-buffer  one per pixel
 *   density    composite --adaptive-map -> trace-gather-points --adaptive, composite  one per pixel
 *
 * Channel indices below are bit positions in CHANNEL_MASK and indices of pm_table_t.col. */
#ifndef PM_FORMATS_H
#define PM_FORMATS_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "formats/material.h"
#include "formats/pmfile.h"

/* ---- photons ---- */
enum {
    PM_PHOTON_POSITION = 0,  /* f32 x3, m: where the photon landed */
    PM_PHOTON_POWER = 1,     /* f32 x3, W: RGB flux it carries */
    PM_PHOTON_NORMAL = 2,    /* f32 x3: unit surface normal, on the side the photon came from */
    PM_PHOTON_DIRECTION = 3, /* f32 x3: unit direction back toward where it came from (glossy scenes only) */
    PM_PHOTON_DEPTH = 4      /* u32: diffuse bounces before this hit; 0 = first hit from a light */
};
extern const pm_schema_t pm_photons_schema;

/* ---- photonmap ---- */
enum {
    PM_MAP_NODE = 0,      /* 8 bytes: pm_kdnode_t */
    PM_MAP_POSITION = 1,  /* f32 x3, m (hot data: read on every visit) */
    PM_MAP_POWER = 2,     /* f32 x3, W (cold data: read only when shading) */
    PM_MAP_NORMAL = 3,    /* f32 x3 */
    PM_MAP_DIRECTION = 4, /* f32 x3 (glossy scenes only) */
    PM_MAP_WIDTH = 5      /* f32, m: kernel width h(x_i) (variable-width estimator only) */
};
extern const pm_schema_t pm_photonmap_schema;

/* The paper's 8-byte KD-tree node. The photon stored with node i lies on the node's
 * split plane. The low 2 mantissa bits of `split` hold the axis (0 x, 1 y, 2 z) or
 * PM_KD_LEAF; the other 30 bits are those of the photon's coordinate on that axis, so
 * the plane is within 3 ulp of the photon. Nodes are in depth-first order: the left
 * subtree is exactly [i + 1, child) (empty when child == i + 1) and the right subtree
 * starts at `child`, or there is none when child == PM_KD_NONE (then the left runs to
 * the end of i's subtree). An inner node has at least one child. Photons of the left
 * subtree have coordinate <= node i's photon's on the axis, those of the right >=. */
typedef struct {
    float split;
    uint32_t child;
} pm_kdnode_t;
_Static_assert(sizeof(pm_kdnode_t) == 8, "the paper's KD-tree node is 8 bytes");
_Static_assert(offsetof(pm_kdnode_t, child) == 4, "split first, child second");

#define PM_KD_LEAF 3u
#define PM_KD_NONE 0xffffffffu
/* Deepest tree a photon map may hold (the root is level 1): searches keep a fixed-size
 * stack, as ray tracers do. A balanced tree of 2^32 - 2 photons is 32 levels deep. */
#define PM_KD_MAX_DEPTH 128u

static inline uint32_t pm_kdnode_axis(pm_kdnode_t n)
{
    uint32_t b;
    memcpy(&b, &n.split, 4);
    return b & 3u;
}

/* A node on coordinate `coord` of axis `axis` (or PM_KD_LEAF). */
static inline pm_kdnode_t pm_kdnode_make(float coord, uint32_t axis, uint32_t child)
{
    uint32_t b;
    memcpy(&b, &coord, 4);
    b = (b & ~3u) | axis;
    pm_kdnode_t n;
    memcpy(&n.split, &b, 4);
    n.child = child;
    return n;
}

/* ---- queries (gather points) ---- */
enum {
    PM_QUERY_POSITION = 0, /* f32 x3, m: where the radiance estimate is made */
    PM_QUERY_NORMAL = 1,   /* f32 x3: unit surface normal (photons on other surfaces are rejected) */
    PM_QUERY_WEIGHT = 2,   /* f32 x3: RGB factor from the estimate to the pixel's radiance */
    PM_QUERY_PIXEL = 3,    /* u32: y * width + x */
    PM_QUERY_MATERIAL = 4, /* u16: index into the header's material table (scenes with several) */
    PM_QUERY_DIRECTION = 5 /* f32 x3: unit outgoing direction (glossy scenes only) */
};
extern const pm_schema_t pm_queries_schema;

/* Writes the materials= and material.K= header keys (reflectance only; emission is not
 * the gather's business). */
pm_result_t pm_queries_set_materials(pm_header_t *h, const pm_material_t *m, size_t n);
/* Reads them back; *m_out is malloc'd. */
pm_result_t pm_queries_get_materials(const pm_header_t *h, const char *path, pm_material_t **m_out, size_t *n_out);

/* ---- radiance (per-pixel buffers) ---- */
enum {
    PM_RADIANCE_RGB = 0,     /* f64 x3, W/(m^2 sr): accumulated in double so millions of small terms keep precision */
    PM_RADIANCE_VARIANCE = 1 /* f64 x3, (W/(m^2 sr))^2: variance of the estimate (optional; trace-reference) */
};
extern const pm_schema_t pm_radiance_schema;

/* ---- aov (per-pixel surface buffers for denoisers) ---- */
enum {
    PM_AOV_ALBEDO = 0, /* f32 x3: directional albedo at the first surface */
    PM_AOV_NORMAL = 1, /* f32 x3: shading normal there, facing the eye (a mean over the pixel's rays) */
    PM_AOV_DEPTH = 2   /* f32, m: distance from the eye */
};
extern const pm_schema_t pm_aov_schema;

/* ---- density (per-pixel positive numbers of adaptive passes) ---- */
enum {
    PM_DENSITY_VALUE = 0 /* f32, > 0: a sample-count multiplier, or a running image's summed pass weight */
};
/* The header key kind's words: "multiplier", "weight", NULL-terminated. */
extern const char *const pm_density_kind_names[];
extern const pm_schema_t pm_density_schema;

/* The largest image pmtk makes or reads: at most PM_IMAGE_SIDE_MAX pixels a side and
 * PM_IMAGE_PIXELS_MAX in all (8192 x 8192; its radiance buffer is 1.5 GiB of f64 RGB), so
 * that a header cannot make a reader allocate what its records never fill. */
#define PM_IMAGE_SIDE_MAX 65536u
#define PM_IMAGE_PIXELS_MAX (1u << 26)

/* Fails (PM_ERR_INPUT) unless w x h is an image size within the limits above: "image size
 * WxH outside ...". */
pm_result_t pm_image_size_check(uint64_t w, uint64_t h);

/* Width and height (header keys width, height) of a queries or radiance header, within the
 * limits above. */
pm_result_t pm_header_get_image_size(const pm_header_t *h, const char *path, uint32_t *w_out, uint32_t *h_out);
/* The same, and COUNT must be width x height (a per-pixel format: radiance, aov): "wrong count
 * in TITLE 'PATH': COUNT=N for a WxH image". */
pm_result_t pm_header_check_pixels(const pm_header_t *h, const char *path);

#endif
