/* build-photonmap: photons file -> photon map (the paper, section 5.2).
 *
 * Builds the KD-tree with one photon per node on the node's split plane and writes it in
 * depth-first node order (common/photonmap/mapbuild.c, the tree in kdtree.c): the 8-byte
 * nodes and positions are the hot channels a gather reads on every visit, power and normal
 * the cold ones read only when a photon is shaded, and direction only when the photons file
 * has it (scenes with glossy materials). `--map indirect` leaves out first-hit photons, for
 * renders whose direct light comes from shadow rays; `--map caustic` builds the caustic map
 * from the caustic photons file of trace-photons --caustic-output, and nothing else does. `--width-k K` adds each
 * photon's kernel width for the variable-width estimator: the radius of the disc around it that holds K photons.
 * With --stream PHOTONS is a stream of photons documents (docs/formats.md, "Streams"), one per
 * frame of a light path, and a map document is written to stdout for each until it ends. */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "base/memory.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "photonmap/mapbuild.h"

typedef struct {
    int map;           /* pm_map_kind_t */
    int split;         /* pm_split_t */
    int64_t width_k;   /* 0: no width channel */
    double vvh_radius; /* m; 0: from vvh_k */
    int64_t vvh_k;
    double width_max; /* m; 0: no limit */
    int stream;       /* --stream: PHOTONS is a stream of documents, a map written for each */
} build_options_t;

/* The library's build parameters from the options (photonmap/mapbuild.h). */
static pm_map_build_params_t build_params(const build_options_t *o)
{
    return (pm_map_build_params_t){.map = (pm_map_kind_t)o->map,
                                   .split = (pm_split_t)o->split,
                                   .vvh_radius = o->vvh_radius,
                                   .vvh_k = (uint32_t)o->vvh_k,
                                   .width_k = (uint32_t)o->width_k,
                                   .width_max = o->width_max};
}

/* Builds the map of one photons document (rd: its header read; in names it) and writes it. */
static pm_result_t build_doc(pm_stage_t *st, const build_options_t *o, pm_reader_t *rd, const char *in,
                             pm_map_build_stats_t *bs_out, double *t_read_out, double *t_write_out)
{
    pm_table_t ph = {0}, map = {0};
    pm_map_build_params_t p = build_params(o);
    double t0 = pm_time_wall();
    pm_result_t r = pm_table_read_from(rd, 0, UINT64_MAX, &ph);
    *t_read_out += pm_time_wall() - t0;
    if (r == PM_OK && (r = pm_map_build(&ph, in, &p, &map, bs_out)) == PM_OK &&
        (r = pm_map_build_header(&map, &ph, in, st->argc, st->argv, &p, bs_out)) == PM_OK) {
        t0 = pm_time_wall();
        r = pm_table_write(&map, st->output);
        *t_write_out += pm_time_wall() - t0;
    }
    pm_table_free(&map);
    pm_table_free(&ph);
    return r;
}

/* --stream: a map per photons document until the stream ends. */
static pm_result_t run_stream(pm_stage_t *st, const build_options_t *o)
{
    const char *path = st->args.args[0], *sname = strcmp(path, "-") ? path : "stdin";
    if (strcmp(st->output, "-") != 0)
        return pm_error_set(PM_ERR_USAGE, "--stream writes one map document per frame to stdout: give -o - (not '%s')",
                            st->output);
    FILE *f;
    pm_result_t r = pm_stream_open(path, &f);
    if (r != PM_OK)
        return r;
    pm_memory_reuse(
        PM_MEMORY_STREAM_REUSE); /* a frame's arrays are allocated again for the next: its freed mappings serve them */
    pm_map_build_stats_t bs = {0};
    double t_read = 0.0, t_write = 0.0, t_build = 0.0;
    uint64_t frames = 0, photons = 0;
    char name[1200];
    for (;;) {
        pm_stream_frame_name(name, sizeof name, path, frames);
        pm_reader_t *rd;
        if ((r = pm_reader_open_next(f, name, &pm_photons_schema, pm_schema_required(&pm_photons_schema), &rd)) !=
                PM_OK ||
            !rd)
            break;
        r = build_doc(st, o, rd, name, &bs, &t_read, &t_write);
        pm_reader_close(rd);
        if (r != PM_OK)
            break;
        frames++;
        photons += bs.photons;
        t_build += bs.build_s;
    }
    pm_stream_close(f);
    if (r == PM_OK && frames == 0)
        r = pm_error_set(PM_ERR_INPUT, "empty stream '%s': no photons document", sname);
    if (r == PM_OK) {
        st->items = photons;
        pm_stage_stat_int(st, "frames", (int64_t)frames);
        pm_stage_stat_int(st, "photons", (int64_t)photons);
        pm_stage_stat_string(st, "map", pm_map_kind_names[o->map]);
        pm_stage_stat_double(st, "read_s", t_read);
        pm_stage_stat_double(st, "build_s", t_build);
        pm_stage_stat_double(st, "write_s", t_write);
    }
    return r;
}

static pm_result_t run(pm_stage_t *st, const build_options_t *o)
{
    if (o->stream)
        return run_stream(st, o);
    const char *in = st->args.args[0];
    pm_table_t ph = {0}, map = {0};
    pm_map_build_params_t p = build_params(o);
    pm_map_build_stats_t bs;
    double t0 = pm_time_wall();
    pm_result_t r = pm_table_read(in, &pm_photons_schema, pm_schema_required(&pm_photons_schema), &ph);
    if (r != PM_OK)
        return r;
    double t_read = pm_time_wall() - t0;
    if ((r = pm_map_build(&ph, in, &p, &map, &bs)) != PM_OK ||
        (r = pm_map_build_header(&map, &ph, in, st->argc, st->argv, &p, &bs)) != PM_OK)
        goto done;
    t0 = pm_time_wall();
    r = pm_table_write(&map, st->output);
    double t_write = pm_time_wall() - t0;
    if (r != PM_OK)
        goto done;

    uint64_t n = bs.photons;
    st->items = n;
    pm_stage_stat_int(st, "photons_in", (int64_t)bs.photons_in);
    pm_stage_stat_int(st, "photons", (int64_t)n);
    pm_stage_stat_string(st, "map", pm_map_kind_names[o->map]);
    pm_stage_stat_int(st, "depth", bs.tree.depth);
    pm_stage_stat_int(st, "leaves", (int64_t)bs.tree.leaves);
    pm_stage_stat_double(st, "read_s", t_read);
    pm_stage_stat_double(st, "build_s", bs.build_s);
    pm_stage_stat_double(st, "build_photons_per_s", bs.build_s > 0 ? (double)n / bs.build_s : 0.0);
    pm_stage_stat_double(st, "gather_s", bs.layout_s);
    if (o->width_k > 0) {
        pm_stage_stat_double(st, "width_s", bs.width_s);
        pm_stage_stat_double(st, "mean_width_m", bs.mean_width);
        pm_stage_stat_double(st, "pilot_radius_m", bs.pilot_radius);
    }
    pm_stage_stat_double(st, "write_s", t_write);
    pm_stage_note(st, "%" PRIu64 " photons (%s map of %" PRIu64 "), depth %u, built in %.3f s", n,
                  pm_map_kind_names[o->map], bs.photons_in, bs.tree.depth, bs.build_s);
done:
    pm_table_free(&map);
    pm_table_free(&ph);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    build_options_t o = {
        .map = PM_MAP_GLOBAL, .split = PM_SPLIT_MEDIAN, .width_k = 0, .width_max = 0.0, .vvh_radius = 0.0, .vvh_k = 50};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"map", 0, PM_OPT_CHOICE, &o.map, "KIND",
         "global: every stored photon; indirect: only photons that bounced (direct light from shadow rays); "
         "caustic: a caustic photons file (trace-photons --caustic-output), every photon",
         0, 0, pm_map_kind_names},
        {"split", 0, PM_OPT_CHOICE, &o.split, "RULE",
         "median: balanced, the paper's; vvh: the voxel-volume heuristic for searches of one radius", 0, 0,
         pm_split_names},
        {"vvh-radius", 0, PM_OPT_DOUBLE, &o.vvh_radius, "R",
         "search radius the vvh split plans for, m (0: the radius holding --vvh-k photons)", 0, 1e30, NULL},
        {"vvh-k", 0, PM_OPT_INT, &o.vvh_k, "K", "photons per search the vvh radius is chosen for", 1, 1e6, NULL},
        {"width-k", 0, PM_OPT_INT, &o.width_k, "K",
         "store each photon's kernel width: the radius holding K photons around it (0: none)", 0, 65536, NULL},
        {"width-max", 0, PM_OPT_DOUBLE, &o.width_max, "M", "largest kernel width, m, for --width-k (0: no limit)", 0,
         1e30, NULL},
        {"stream", 0, PM_OPT_FLAG, &o.stream, NULL,
         "PHOTONS is a stream of documents (a frame each): build a map of each, one document per frame to stdout", 1, 0,
         NULL},
        {0},
    };
    static const char about[] = "Build the photon map KD-tree (one photon per node, 8-byte nodes) from a photons file; "
                                "PHOTONS may be - for stdin.";
    const pm_cli_t cli = {"build-photonmap", "[options] PHOTONS -o MAP", about, options, 1, 1, "photonmap"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
