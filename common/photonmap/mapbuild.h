/* mapbuild.h: a photon map made from a photons file, as build-photonmap writes it: the photons
 * the map holds, the KD-tree over them (kdtree.h, median or voxel-volume splits), their
 * channels laid out in node order, hot (nodes, positions) and cold (power, normal, direction),
 * and optionally each photon's kernel width for the variable-width estimator. */
#ifndef PM_MAPBUILD_H
#define PM_MAPBUILD_H

#include <stdint.h>

#include "base/error.h"
#include "formats/formats.h"
#include "photonmap/kdtree.h"

typedef enum {
    PM_MAP_GLOBAL = 0,   /* every stored photon */
    PM_MAP_INDIRECT = 1, /* only photons that bounced (depth > 0): direct light comes from shadow rays */
    PM_MAP_CAUSTIC = 2   /* every photon of a caustic photons file (kind=caustic: L S+ D, trace-photons) */
} pm_map_kind_t;

typedef enum {
    PM_SPLIT_MEDIAN = 0, /* balanced, the paper's */
    PM_SPLIT_VVH = 1     /* the voxel-volume heuristic for searches of one radius (pm_kd_build_vvh) */
} pm_split_t;

/* Words for --map and --split and the header keys map and split, NULL-terminated. */
extern const char *const pm_map_kind_names[];
extern const char *const pm_split_names[];

typedef struct {
    pm_map_kind_t map;
    pm_split_t split;
    double vvh_radius; /* m, the radius the vvh split plans for; 0: the one holding vvh_k photons */
    uint32_t vvh_k;    /* photons per search that radius is chosen for */
    uint32_t width_k;  /* photons a kernel width holds; 0: no width channel */
    double width_max;  /* m, the largest kernel width; 0: no limit */
} pm_map_build_params_t;

typedef struct {
    uint64_t photons_in, photons; /* read, and kept in the map */
    pm_kd_build_stats_t tree;
    double vvh_radius;   /* m, the radius the vvh split planned for (0 with median) */
    double build_s;      /* s: the tree alone (both trees with vvh) */
    double layout_s;     /* s: node-order channels, and the vvh radius */
    double width_s;      /* s: kernel widths */
    double mean_width;   /* m, mean kernel width (0 without widths) */
    double pilot_radius; /* m, the radius holding width_k photons on average */
} pm_map_build_stats_t;

/* Builds the map of the photons table read from path (path names it in messages) into
 * *map_out: nodes, channels in node order (direction when the photons have it, width when
 * p->width_k > 0) and the photons' bounds; the header's keys are pm_map_build_header's.
 * On failure *map_out holds nothing to free. At most 2^32 - 2 photons. */
pm_result_t pm_map_build(const pm_table_t *photons, const char *path, const pm_map_build_params_t *p,
                         pm_table_t *map_out, pm_map_build_stats_t *stats_out);

/* The map's header: the photons file's provenance and an INPUT line with its checksum, the
 * command (argc, argv), then map, split, vvh_radius (vvh only), emitted (when the photons
 * file has it) and width_k (with widths). */
pm_result_t pm_map_build_header(pm_table_t *map, const pm_table_t *photons, const char *path, int argc, char **argv,
                                const pm_map_build_params_t *p, const pm_map_build_stats_t *stats);

/* A global map of median splits (no widths) from n photons given as arrays (position, power and
 * normal, 3 floats each; direction likewise, or NULL), their bounds the table's, into *map_out;
 * with argv, also pm_map_build_header's keys (name standing for the photons file). For callers
 * that hold photons in memory: the library's pmtk_photonmap_build, the area samples of
 * photonmap/coverage.c. On failure *map_out holds nothing to free. */
pm_result_t pm_map_build_arrays(const float *pos, const float *power, const float *normal, const float *dir, uint64_t n,
                                const char *name, int argc, char **argv, pm_table_t *map_out);

#endif
