/* gather_stage.h: what the three gather stages (simd-gather, knn-gather, reverse-gather)
 * share around their estimators, so that they are swappable: the same inputs read and
 * refused by the same rules, the same kernel width from --k, and the same output (queries
 * added to pixels in file order, provenance of both inputs). */
#ifndef PM_GATHER_STAGE_H
#define PM_GATHER_STAGE_H

#include <stdint.h>
#include <stdio.h>

#include "base/args.h"
#include "base/error.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "photonmap/coverage.h"
#include "photonmap/gather.h"

/* The kernels' names, in pm_kernel_t order, for --kernel and the `kernel` header key. */
extern const char *const pm_kernel_names[];

/* The options every gather stage has, with the same meaning and help: --normal-cos C (a
 * double) and --range B:E (a string). */
/* A table, one option a line, as in the stages' own tables; clang-format would set each field on a line of its own. */
/* clang-format off */
#define PM_GATHER_COMMON_OPTIONS(normal_cos, range)                                                                    \
    {"normal-cos", 0, PM_OPT_DOUBLE, &(normal_cos), "C",                                                               \
     "a photon counts when the cosine between its normal and the query's is at least C", -1, 1, NULL},                 \
        {"range", 0, PM_OPT_STRING, &(range), "B:E", "gather only queries [B, E) (shards; composite adds them)",       \
         1, 0, NULL}
/* clang-format on */

/* The progressive passes' options (Knaus and Zwicker 2011): --pass N (1-based; 0: none),
 * --alpha A, the schedule's parameter in (0, 1), and the photons that place a pass on the
 * schedule: --pass-photons B (emitted in the passes before it) and --unit-photons U (pass 1's),
 * so that passes of any size shrink the kernel as their photons justify. */
/* clang-format off */
#define PM_GATHER_PASS_OPTIONS(pass, alpha, before, unit)                                                              \
    {"pass", 0, PM_OPT_INT, &(pass), "N",                                                                              \
     "progressive pass N (1-based): gather with r_N of the schedule r_(i+1)^2 = r_i^2 (i + A) / (i + 1), r_1 being "   \
     "--radius or the width --k measures; 0: no pass, the width as given",                                           \
     0, (double)((int64_t)1 << 40), NULL},                                                                             \
        {"alpha", 0, PM_OPT_DOUBLE, &(alpha), "A",                                                                     \
         "the schedule's alpha with --pass, in (0, 1): smaller shrinks the width faster (less bias, more noise)",       \
         1e-9, 1 - 1e-9, NULL},                                                                                        \
        {"pass-photons", 0, PM_OPT_INT, &(before), "B",                                                                \
         "with --pass and --unit-photons: the photons emitted in the passes before this one; the pass then sits at "   \
         "n = 1 + B / U of the schedule (the product's continuous form), not at N; -1: not given",                    \
         -1, (double)((int64_t)1 << 62), NULL},                                                                        \
        {"unit-photons", 0, PM_OPT_INT, &(unit), "U",                                                                  \
         "with --pass-photons: the photons of pass 1, the schedule's unit (passes of U photons each: n = N exactly); "  \
         "0: not given",                                                                                               \
         0, (double)((int64_t)1 << 62), NULL}
/* clang-format on */

/* The default alpha of the schedule, the value Knaus and Zwicker recommend. */
#define PM_PASS_ALPHA_DEFAULT (2.0 / 3.0)

/* r_pass of the progressive schedule r_(i+1)^2 = r_i^2 (i + alpha) / (i + 1) from r_1 (m):
 * the area of the kernel shrinks by (i + alpha) / (i + 1) from pass i to pass i + 1, so that
 * the average of the passes loses its bias and its noise together. pass 0 and 1 give r1. */
double pm_gather_pass_radius(double r1, uint64_t pass, double alpha);

/* The schedule at a real pass index n >= 1 (in units of pass 1's photons: n = 1 + photons
 * emitted before the pass / pass 1's photons): r_1 times the square root of
 * Gamma(n + alpha) / (Gamma(1 + alpha) Gamma(n + 1)), the product's continuous form. At an
 * integral n it is pm_gather_pass_radius's value to the bit. */
double pm_gather_schedule_radius(double r1, double n, double alpha);

/* The real pass index of a pass with `before` photons emitted before it, pass 1 having `unit`:
 * 1 + before / unit; `pass` itself when unit is 0 (no photon counts: every pass alike). */
double pm_gather_pass_index(uint64_t pass, uint64_t before, uint64_t unit);

/* The keys a pass's gather output carries: pass, alpha and radius1 (r_1; the caller's own
 * `radius` key is r_pass), and with unit > 0 pass_photons (before) and unit_photons (unit).
 * Nothing when pass is 0. */
pm_result_t pm_gather_pass_header(pm_header_t *h, uint64_t pass, double alpha, double r1, uint64_t before,
                                  uint64_t unit);

/* Checks --pass-photons (before; -1: not given) and --unit-photons (unit; 0: not given)
 * against --pass: only with a pass, before only with unit, unit after pass 1 only with before,
 * and pass 1 has no photons before it. */
pm_result_t pm_gather_pass_check(int64_t pass, int64_t before, int64_t unit);

/* A photon map and a queries file (or the range [begin, end) of one), as the gathers read
 * them. Row i of `q` is query begin + i of the file. */
typedef struct {
    const char *map_path, *q_path;
    pm_table_t map_table, q_table;
    pm_gather_map_t map;
    pm_gather_queries_t q;
    pm_material_t *materials;
    uint64_t begin, end, total; /* the range held, and the file's query count */
    int ranged;                 /* --range was given */
    int caustic;                /* caustic queries against a caustic map: the output is component=caustic */
    uint32_t width, height;     /* image size, pixels */
    double read_s;              /* wall seconds spent reading and checking both files */
    double *per_query;          /* owned, 3 per row of q: for the gather's weighted radiance, W/(m^2 sr) */
    pm_reader_t *stream;        /* streamed queries (pm_gather_inputs_open): the reader, NULL once read whole */
    double *pixels;             /* owned, with a stream: RGB sums of the pixels up to the last one a
                                 * query names (pixels_used), filled by pm_gather_stream */
    uint64_t pixels_used;       /* with a stream: the pixels in pixels (grown as the queries name them) */
    pm_coverage_t *cover;       /* not owned: the boundary correction to apply to each query, or NULL */
} pm_gather_inputs_t;

/* pm_gather_run over in's map and queries [begin, end) into in->per_query, then with in->cover
 * each query's result divided by its kernel's covered part (pm_coverage_apply_queries). */
pm_result_t pm_gather_inputs_run(pm_gather_inputs_t *in, uint64_t begin, uint64_t end, const pm_gather_params_t *p,
                                 pm_gather_stats_t *stats);

/* Reads MAP and QUERIES (range "B:E" or NULL for all; QUERIES may be "-"), checks the
 * weight contract and that both are of one scene, views them for the gathers (`variable`:
 * per-photon widths, see pm_gather_map_init) and allocates per_query. Free with
 * pm_gather_inputs_free, also after a failure. */
pm_result_t pm_gather_inputs_read(pm_gather_inputs_t *in, const char *map_path, const char *q_path, const char *range,
                                  int variable);
void pm_gather_inputs_free(pm_gather_inputs_t *in);
/* Like pm_gather_inputs_read for all the queries, but reads only their header: q_table holds
 * it and columns for PM_GATHER_STREAM_ROWS queries, `q` views them (n 0) and per_query has as
 * many rows. Then either pm_gather_stream gathers the queries a chunk at a time as they
 * arrive (the memory of one chunk, and the gather overlaps the stage that writes them), or
 * pm_gather_inputs_read_rest reads them whole as pm_gather_inputs_read does (for --k, whose
 * width is measured on all of them). */
pm_result_t pm_gather_inputs_open(pm_gather_inputs_t *in, const char *map_path, const char *q_path, int variable);
pm_result_t pm_gather_inputs_read_rest(pm_gather_inputs_t *in, int variable);
/* Queries a chunk holds: a whole number of the gather's blocks, so that every packet and
 * every sum is the one a gather of the whole file makes, bit for bit. */
#define PM_GATHER_STREAM_ROWS ((uint64_t)1 << 17)
/* Gathers the streamed queries chunk by chunk with pm_gather_run (parameters p), checks each
 * chunk as pm_gather_check_finite does and adds its queries to in->pixels in file order; at
 * the end in->q.n is the number of queries, in->q_table.checksum their file's checksum and
 * the stats the sums of every chunk's (gather_s_out: wall seconds in pm_gather_run). */
pm_result_t pm_gather_stream(pm_gather_inputs_t *in, const pm_gather_params_t *p, pm_gather_stats_t *stats,
                             double *gather_s_out);

/* Streams of documents (docs/formats.md, "Streams"): a gather that keeps one input and takes
 * the other one document at a time. pm_gather_inputs_read_map reads the map alone (the queries
 * come from a stream); pm_gather_inputs_next_queries then reads the next queries document of f
 * (name: what messages and the INPUT line call it), whole when `whole` (the width is measured on
 * it) or opened to be gathered by pm_gather_stream, checked against the kept map as
 * pm_gather_inputs_open checks them. pm_gather_inputs_read_queries reads a queries file whole
 * (the map comes from a stream) and pm_gather_inputs_next_map reads the next map document of f
 * in place of the last one. Both set *end_out (and read nothing) at the clean end of f. */
pm_result_t pm_gather_inputs_read_map(pm_gather_inputs_t *in, const char *map_path, int variable);
pm_result_t pm_gather_inputs_next_queries(pm_gather_inputs_t *in, FILE *f, const char *name, int whole, int variable,
                                          int *end_out);
pm_result_t pm_gather_inputs_read_queries(pm_gather_inputs_t *in, const char *q_path);
pm_result_t pm_gather_inputs_next_map(pm_gather_inputs_t *in, FILE *f, const char *name, int variable, int *end_out);

/* The kernel width options after the scene's suggestions. An option given on the command line
 * wins (a given --k alone also sets the width from k, leaving the scene's radius aside);
 * otherwise the queries header's render.radius (when > 0) and render.k, which
 * trace-gather-points copies from the scene's render block (docs/formats.md 3.3); a file without
 * them keeps the options' defaults. radius is NULL for a stage without --radius (knn-gather).
 * from_out names what set the width: "--radius", "--k", "render.radius", "render.k" or
 * "default k". Fails with PM_ERR_INPUT on a header value that is not a number in range. */
pm_result_t pm_gather_inputs_scene_kernel(const pm_gather_inputs_t *in, const pm_args_t *args, double *radius,
                                          double *k, const char **from_out);

/* The kernel width at which about k photons contribute to a query (pm_gather_radius_for_k),
 * measured on the queries of the pixels a hash picks, so that it does not depend on the
 * order of the queries; a shard samples the whole file (which must then not be stdin). */
pm_result_t pm_gather_inputs_radius_for_k(const pm_gather_inputs_t *in, double k, float normal_cos, double *radius_out);

/* The radiance buffer of in->per_query (or of in->pixels after pm_gather_stream): each query
 * added to its pixel in file order, so the
 * buffer does not depend on how the sums were computed in parallel. The header inherits both
 * inputs, names them, adds the command line, width, height, component=indirect, the kernel
 * (pm_kernel_names[kernel]) and widths (fixed, variable, knn); the caller adds its own keys
 * and then calls pm_gather_output_write. */
pm_result_t pm_gather_output_init(pm_table_t *out, const pm_gather_inputs_t *in, int argc, char **argv, int kernel,
                                  const char *widths);

/* Writes a table of pm_gather_output_init to path atomically: its records, then zero ones up
 * to its header's count (the pixels past the last one a query names, which it does not hold). */
pm_result_t pm_gather_table_write(const pm_table_t *out, const char *path);

/* Adds range=B:E for a shard and writes `out` to path atomically. */
pm_result_t pm_gather_output_write(pm_table_t *out, const pm_gather_inputs_t *in, const char *path);

/* The counters every gather stage reports in --stats under the same names, so that the
 * three can be compared key for key: queries (also st->items), photons, kernel, shader_ops
 * and its rates per query, per second of the gather (gather_s, wall) and per CPU second of
 * its workers (cpu_s), read_s, gather_s and write_s. */
void pm_gather_stage_stats(pm_stage_t *st, const pm_gather_inputs_t *in, int kernel, uint64_t shader_ops,
                           double gather_s, double cpu_s, double write_s);

/* The same check of in->per_query every estimator needs: no NaN or Inf reaches a file.
 * Names the first bad query (its index in the file) and `what` computed it. */
pm_result_t pm_gather_check_finite(const pm_gather_inputs_t *in, const char *what);

#endif
