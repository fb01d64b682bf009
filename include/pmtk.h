/* pmtk.h: the public C API of libpmtk, the photon map of pmtk as a library a renderer links
 * (docs/api.md). The paper's SIMD packet gather with the sample-point estimator, the k-NN
 * baseline, Hilbert order, and every pmtk file format, behind opaque handles.
 *
 * Conventions (Embree's and OpenEXR Core's): every object with a lifetime is an opaque handle
 * with a create (or read) and a destroy; every call that can fail returns a pmtk_result_t
 * (PMTK_OK = 0) and writes its results through *_out parameters; a failure's one-line message
 * goes to the context's error callback and stays readable with pmtk_context_error. There is no
 * global state: two contexts never see each other's errors or settings. A context is used by
 * one thread at a time; handles made through one may be read by many threads at once (a map
 * gathered from two threads with two contexts is fine). Calls parallelize inside with OpenMP.
 *
 * Units: positions and radii in metres, powers in watts, radiance sums in W/m^2 (the density
 * estimate; multiply by the surface's BRDF, 1/sr, for radiance). Vectors are 3 floats x, y, z
 * packed (array of structures). Build with `pkg-config --cflags --libs pmtk`. */
#ifndef PMTK_H
#define PMTK_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(PMTK_BUILDING) && defined(__GNUC__)
#define PMTK_API __attribute__((visibility("default")))
#else
#define PMTK_API
#endif

/* The API's version: the soname's major (libpmtk.so.1); a change that breaks callers bumps it. */
#define PMTK_API_VERSION 1

/* ---- results ---- */
typedef int32_t pmtk_result_t;
enum {
    PMTK_OK = 0,
    PMTK_ERR_USAGE = 1,   /* a bad argument: NULL where a value is needed, a radius of 0 */
    PMTK_ERR_INPUT = 2,   /* bad data: a malformed file, a NaN position, a wrong format */
    PMTK_ERR_IO = 3,      /* the system failed: open, read, write (a retry may succeed) */
    PMTK_ERR_NOMEM = 4,   /* an allocation failed */
    PMTK_ERR_INTERNAL = 5 /* a bug in pmtk */
};
/* "ok", "usage", "input", "io", "nomem", "internal" (static strings). */
PMTK_API const char *pmtk_result_string(pmtk_result_t code);
/* The library's version, "pmtk X.Y" (static). */
PMTK_API const char *pmtk_version(void);

/* ---- contexts ---- */
typedef struct pmtk_context pmtk_context_t;
/* Called on the context's thread with every failure's code and one-line message (valid only
 * during the call). */
typedef void (*pmtk_error_fn_t)(void *user, pmtk_result_t code, const char *message);

PMTK_API pmtk_result_t pmtk_context_create(pmtk_context_t **ctx_out);
PMTK_API void pmtk_context_destroy(pmtk_context_t *ctx); /* NULL is fine */
/* fn NULL: no callback (the message is still kept). */
PMTK_API void pmtk_context_set_error_callback(pmtk_context_t *ctx, pmtk_error_fn_t fn, void *user);
/* Threads the context's calls use; 0 (the default): OpenMP's default (OMP_NUM_THREADS or the
 * cores). Results do not depend on it. */
PMTK_API pmtk_result_t pmtk_context_set_threads(pmtk_context_t *ctx, int threads);
/* The message of the context's last failure, "" when none; valid until its next call. */
PMTK_API const char *pmtk_context_error(const pmtk_context_t *ctx);

/* ---- instruction sets ---- */
typedef enum {
    PMTK_ISA_AUTO = -1, /* the widest this CPU runs */
    PMTK_ISA_SCALAR = 0,
    PMTK_ISA_SSE4 = 1,  /* packets of 4, the paper's */
    PMTK_ISA_AVX2 = 2,  /* packets of 8 */
    PMTK_ISA_AVX512 = 3 /* packets of 16 */
} pmtk_isa_t;
PMTK_API int pmtk_isa_supported(pmtk_isa_t isa); /* 1 when this CPU and OS run it */
PMTK_API pmtk_isa_t pmtk_isa_best(void);
PMTK_API const char *pmtk_isa_name(pmtk_isa_t isa); /* "auto", "scalar", "sse4", "avx2", "avx512" */

/* ---- photon maps ---- */
typedef struct pmtk_photonmap pmtk_photonmap_t;

/* Photons as a renderer stores them; the arrays are read during the build only. */
typedef struct {
    uint64_t count;         /* at most 2^30 - 1 */
    const float *position;  /* 3 * count, m, finite */
    const float *power;     /* 3 * count, W, RGB, >= 0 */
    const float *normal;    /* 3 * count, unit: the surface's, on the side the photon arrived from */
    const float *direction; /* 3 * count, unit, or NULL: back toward where the photon came from */
} pmtk_photons_t;

/* Builds the paper's KD-tree (balanced, median splits) over a copy of the photons. */
PMTK_API pmtk_result_t pmtk_photonmap_build(pmtk_context_t *ctx, const pmtk_photons_t *photons,
                                            pmtk_photonmap_t **map_out);
/* Reads a photonmap file (build-photonmap's), checking every byte and its checksum. */
PMTK_API pmtk_result_t pmtk_photonmap_read(pmtk_context_t *ctx, const char *path, pmtk_photonmap_t **map_out);
/* Writes the map as a photonmap file, atomically (a temporary file renamed into place). */
PMTK_API pmtk_result_t pmtk_photonmap_write(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const char *path);
PMTK_API uint64_t pmtk_photonmap_count(const pmtk_photonmap_t *map);
PMTK_API void pmtk_photonmap_destroy(pmtk_photonmap_t *map); /* NULL is fine */

/* ---- gathers ---- */
typedef enum {
    PMTK_KERNEL_UNIFORM = 0,     /* 1 / (pi h^2) inside the disc */
    PMTK_KERNEL_EPANECHNIKOV = 1 /* 2 / (pi h^2) (1 - d^2 / h^2) */
} pmtk_kernel_t;

/* Queries (gather points); packets are PMTK-chosen runs of consecutive queries, so queries
 * near one another in the array (pmtk_hilbert_order) gather faster. */
typedef struct {
    uint64_t count;
    const float *position; /* 3 * count, m */
    const float *normal;   /* 3 * count, unit: photons whose normal disagrees are not counted */
    const float *radius;   /* count, m, > 0, or NULL: every query uses the params' radius */
} pmtk_queries_t;

typedef struct {
    double radius; /* m: the kernel width h when queries have no radius array */
    pmtk_kernel_t kernel;
    float normal_cos; /* a photon counts when dot(its normal, the query's) >= this */
    pmtk_isa_t isa;   /* PMTK_ISA_AUTO, or one to force (PMTK_ERR_USAGE if the CPU lacks it) */
} pmtk_gather_params_t;

/* Defaults: radius 0 (to be set), uniform kernel, normal_cos 0, isa auto. */
PMTK_API void pmtk_gather_params_init(pmtk_gather_params_t *p);

typedef struct {
    uint64_t shader_ops;    /* photon-query pairs inside the kernel with agreeing normals */
    uint64_t nodes_visited; /* packet-node visits */
    uint64_t packets;
    int packet_width; /* lanes of the ISA that ran */
    double cpu_s;     /* CPU seconds in the kernels, all threads */
} pmtk_gather_stats_t;

/* The sample-point estimator (the paper's section 3): for each query q,
 *     out[3 q + c] = sum over photons i within h of q, normals agreeing, of power_i,c K(d / h) / h^2
 * in W/m^2, double. SIMD packets walk the tree together; the result does not depend on the
 * thread count. stats_out may be NULL. */
PMTK_API pmtk_result_t pmtk_gather(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const pmtk_queries_t *queries,
                                   const pmtk_gather_params_t *params, double *out, pmtk_gather_stats_t *stats_out);

typedef struct {
    uint32_t k;        /* photons per estimate, >= 1 */
    double max_radius; /* m; 0: unlimited */
    pmtk_kernel_t kernel;
    float normal_cos;
} pmtk_knn_params_t;

/* The baseline: Jensen's k-nearest-neighbour estimate, a scalar walk with a heap per query,
 * the same sums with h the distance of the k-th photon. The queries' radius array is unused. */
PMTK_API pmtk_result_t pmtk_knn_gather(pmtk_context_t *ctx, const pmtk_photonmap_t *map, const pmtk_queries_t *queries,
                                       const pmtk_knn_params_t *params, double *out);

/* The order of n points along a 3-D Hilbert curve: perm_out[i] (n entries) is the index of the
 * point that goes to place i. Points are 3 floats every `stride` bytes from `position`
 * (stride 12 for packed). leaf >= 1 stops at cells of that many points (partial order; 1: full).
 * The same for any thread count. */
PMTK_API pmtk_result_t pmtk_hilbert_order(pmtk_context_t *ctx, const float *position, size_t stride, uint64_t n,
                                          uint64_t leaf, uint32_t *perm_out);

/* ---- files of every pmtk format (docs/formats.md) ---- */
typedef struct pmtk_file pmtk_file_t;

typedef enum { PMTK_TYPE_U16 = 0, PMTK_TYPE_U32 = 1, PMTK_TYPE_F32 = 2, PMTK_TYPE_F64 = 3 } pmtk_type_t;

/* Reads any pmtk file whole, checking every value and the checksum. */
PMTK_API pmtk_result_t pmtk_file_read(pmtk_context_t *ctx, const char *path, pmtk_file_t **file_out);
/* A new file of format ("photons", "photonmap", "queries", "radiance") with count zeroed
 * records of the named channels (NULL-terminated; NULL: the required ones only). */
PMTK_API pmtk_result_t pmtk_file_create(pmtk_context_t *ctx, const char *format, const char *const *channels,
                                        uint64_t count, pmtk_file_t **file_out);
/* Writes it atomically; every value is checked as a reader checks it, so a file this writes
 * reads back. */
PMTK_API pmtk_result_t pmtk_file_write(pmtk_context_t *ctx, const pmtk_file_t *file, const char *path);
PMTK_API void pmtk_file_destroy(pmtk_file_t *file); /* NULL is fine */
PMTK_API const char *pmtk_file_format(const pmtk_file_t *file);
PMTK_API uint64_t pmtk_file_count(const pmtk_file_t *file);
/* Channel `name`'s values (count * components of its type, structure of arrays; writable),
 * or NULL when the file lacks it; type_out and components_out may be NULL. */
PMTK_API void *pmtk_file_channel(pmtk_file_t *file, const char *name, pmtk_type_t *type_out, unsigned *components_out);
/* A header key's value (NULL when absent), and setting one (KEY=VALUE, no newline). */
PMTK_API const char *pmtk_file_header_get(const pmtk_file_t *file, const char *key);
PMTK_API pmtk_result_t pmtk_file_header_set(pmtk_context_t *ctx, pmtk_file_t *file, const char *key, const char *value);

#ifdef __cplusplus
}
#endif

#endif
