/* hilbert-sort: reorders gather points along a 3-D Hilbert curve, so that the queries that
 * simd-gather packs into one SIMD packet, and the packets that follow one another, lie close
 * together and walk the same part of the photon map (the paper, sections 4.3 and 6.2).
 *
 *   trace-gather-points -> hilbert-sort -> simd-gather
 *
 * Reads a queries file (or stdin) whole, computes the order with common/photonmap/hilbert.c (an octree
 * visited in curve order, stopping at cells of --leaf points), and writes the same records,
 * byte for byte, in that order (to a file or stdout). Memory: one copy of the records plus
 * 20 bytes per point of sort words and permutation. With --stream the input is a stream of
 * queries documents (docs/formats.md, "Streams"), one frame each, and each is sorted and
 * written to the output stream in turn, until the input ends. */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/memory.h"
#include "base/stage.h"
#include "formats/formats.h"
#include "photonmap/hilbert.h"
#include "photonmap/reorder.h"

typedef struct {
    int order;        /* pm_order_t */
    const char *leaf; /* "auto" or a count */
    int64_t cache;    /* bytes of cache --leaf auto assumes; 0 asks the system for L2 */
    int stream;       /* the input is a stream of documents, the output one document for each */
} sort_options_t;

/* What the documents sorted so far took, for --stats (wall seconds). */
typedef struct {
    uint64_t points, frames;
    double read_s, keys_s, sort_s, reorder_s, write_s;
    uint64_t leaf;
    int is_auto, depth;
    uint64_t leaves;
    const char *leaf_from;
    size_t rs;
} sort_totals_t;

/* --leaf: a positive count or "auto". */
static pm_result_t parse_leaf(const char *s, uint64_t *leaf_out, int *is_auto_out)
{
    *is_auto_out = strcmp(s, "auto") == 0;
    if (*is_auto_out)
        return PM_OK;
    int64_t v;
    if (pm_parse_i64(s, &v) != PM_OK || v < 1)
        return pm_error_set(PM_ERR_USAGE, "bad value for --leaf '%s': expected a count of at least 1 or auto", s);
    *leaf_out = (uint64_t)v;
    return PM_OK;
}

static uint64_t cache_bytes(int64_t asked)
{
    if (asked > 0)
        return (uint64_t)asked;
    long l2 = sysconf(_SC_LEVEL2_CACHE_SIZE);
    return l2 > 0 ? (uint64_t)l2 : 1u << 20; /* 1 MiB when the system does not say */
}

/* The output header: the input's provenance, this command, the input's hash, the order,
 * then every other key of the input (width, height, materials, unknown keys). */
static pm_result_t make_header(const pm_stage_t *st, const pm_header_t *in, const char *in_name, uint64_t in_hash,
                               pm_order_t order, uint64_t leaf, int is_auto, pm_header_t *h)
{
    pm_header_init(h, &pm_queries_schema);
    h->count = in->count;
    h->channels = in->channels;
    memcpy(h->bounds, in->bounds, sizeof h->bounds);
    pm_result_t r = pm_header_inherit(h, in);
    if (r == PM_OK)
        r = pm_header_add_command(h, st->argc, st->argv);
    if (r == PM_OK)
        r = pm_header_add_input(h, in_name, in_hash);
    if (r == PM_OK) {
        if (order == PM_ORDER_NONE)
            r = pm_header_set(h, "order", "none");
        else
            r = pm_header_set(h, "order", "%s leaf=%" PRIu64 "%s", pm_order_names[order], leaf, is_auto ? " auto" : "");
    }
    if (r == PM_OK)
        r = pm_header_copy_keys(h, in); /* an earlier sort's order key is replaced, not copied */
    return r;
}

/* The arrays a sort needs, kept from one document of a stream to the next so that a frame
 * does not map and fault in fresh pages for its records. */
typedef struct {
    unsigned char *recs;
    uint32_t *perm;
    unsigned char *chunk[2];
    uint64_t n; /* records they have room for */
    size_t rs;  /* of this record size */
} sort_bufs_t;

static void bufs_free(sort_bufs_t *b)
{
    pm_free_aligned(b->recs);
    pm_free_aligned(b->perm);
    free(b->chunk[0]);
    free(b->chunk[1]);
    memset(b, 0, sizeof *b);
}

/* Room for n records of rs bytes (and the reorder's chunks when sorting); 0 when out of memory. */
static int bufs_reserve(sort_bufs_t *b, uint64_t n, size_t rs)
{
    if (b->recs && n <= b->n && rs == b->rs)
        return 1;
    bufs_free(b);
    /* An eighth more than asked: the next frame's count is seldom the same, often a little more. */
    n += n / 8;
    b->recs = pm_alloc_aligned(n ? n * rs : 1);
    b->perm = pm_alloc_aligned(n ? n * sizeof *b->perm : 1);
    b->chunk[0] = malloc((size_t)PM_REORDER_CHUNK * rs), b->chunk[1] = malloc((size_t)PM_REORDER_CHUNK * rs);
    b->n = n, b->rs = rs;
    if (b->recs && b->perm && b->chunk[0] && b->chunk[1])
        return 1;
    bufs_free(b);
    return 0;
}

/* Sorts the one document rd holds (its header read) and writes it to -o. */
static pm_result_t sort_doc(pm_stage_t *st, const sort_options_t *o, pm_reader_t *rd, const char *in_name,
                            sort_bufs_t *bufs, sort_totals_t *tot)
{
    uint64_t leaf = 16;
    int is_auto = 0;
    pm_result_t res = parse_leaf(o->leaf, &leaf, &is_auto);
    if (res != PM_OK)
        return res;
    pm_order_t order = (pm_order_t)o->order;
    double t0 = pm_time_wall();
    const pm_header_t *in = pm_reader_header(rd);
    /* Without --leaf, the scene's render.leaf, which trace-gather-points copies into the header. */
    const char *scene_leaf = pm_args_given(&st->args, "leaf") ? NULL : pm_header_get(in, "render.leaf");
    if (scene_leaf && (res = parse_leaf(scene_leaf, &leaf, &is_auto)) != PM_OK)
        return pm_error_set(PM_ERR_INPUT, "queries '%s': header key render.leaf '%s' is not a count of at least 1",
                            in_name, scene_leaf);
    uint64_t n = in->count;
    size_t rs = in->record_size;
    if (n > UINT32_MAX)
        return pm_error_set(PM_ERR_INPUT, "queries '%s' has %" PRIu64 " records; hilbert-sort sorts at most %" PRIu32,
                            in_name, n, UINT32_MAX);
    pm_header_t h = {0};
    pm_writer_t *w = NULL;
    if (!bufs_reserve(bufs, n, rs)) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " queries of '%s' (%.0f MB)", n, in_name,
                           n * (rs + 20.0) / 1e6);
        goto done;
    }
    unsigned char *recs = bufs->recs, **chunk = bufs->chunk;
    uint32_t *perm = bufs->perm;
    uint64_t got, in_hash = 0;
    if ((res = pm_reader_read(rd, recs, n, &got)) != PM_OK || (res = pm_reader_finish(rd, &in_hash)) != PM_OK)
        goto done;
    double t1 = pm_time_wall();

    if (is_auto)
        leaf = pm_reorder_auto_leaf(n, cache_bytes(o->cache));
    pm_reorder_info_t info;
    if ((res = pm_reorder_points(recs, rs, n, order, leaf, perm, &info)) != PM_OK)
        goto done;
    double t2 = pm_time_wall();

    if ((res = make_header(st, in, in_name, in_hash, order, leaf, is_auto, &h)) != PM_OK ||
        (res = pm_writer_open(st->output, &h, &w)) != PM_OK)
        goto done;
    if (order == PM_ORDER_NONE)
        res = pm_writer_write_checked(w, recs, n); /* the reader checked them */
    else
        res = pm_reorder_write(w, recs, rs, n, perm, chunk);
    if (res == PM_OK)
        res = pm_writer_commit(w);
    else
        pm_writer_abort(w);
    w = NULL;
    double t3 = pm_time_wall();
    if (res == PM_OK) {
        tot->points += n;
        tot->frames++;
        tot->read_s += t1 - t0;
        tot->keys_s += info.keys_s;
        tot->sort_s += info.sort_s;
        tot->reorder_s += t2 - t1;
        tot->write_s += t3 - t2;
        tot->leaf = leaf;
        tot->is_auto = is_auto;
        tot->depth = info.depth;
        tot->leaves += info.leaves;
        tot->rs = rs;
        tot->leaf_from = scene_leaf ? "render.leaf" : pm_args_given(&st->args, "leaf") ? "--leaf" : "default";
    }
done:
    pm_writer_abort(w);
    pm_header_free(&h);
    return res;
}

static pm_result_t run(pm_stage_t *st, const sort_options_t *o)
{
    const char *path = st->args.nargs ? st->args.args[0] : "-";
    const char *in_name = strcmp(path, "-") == 0 ? "stdin" : path;
    sort_totals_t tot = {0};
    double t0 = pm_time_wall();
    pm_reader_t *rd = NULL;
    pm_result_t res = PM_OK;
    sort_bufs_t bufs = {0};
    if (!o->stream) {
        if ((res = pm_reader_open(path, &pm_queries_schema, 0, &rd)) != PM_OK)
            return res;
        res = sort_doc(st, o, rd, in_name, &bufs, &tot);
        pm_reader_close(rd);
    } else {
        if (strcmp(st->output, "-") != 0)
            return pm_error_set(PM_ERR_USAGE,
                                "--stream writes one queries document per frame to stdout: give -o - (not '%s')",
                                st->output);
        pm_memory_reuse(PM_MEMORY_STREAM_REUSE); /* a frame's arrays are allocated again for the next: its freed
                                                    mappings serve them */
        FILE *f;
        if ((res = pm_stream_open(path, &f)) != PM_OK)
            return res;
        char name[1200];
        for (;;) {
            pm_stream_frame_name(name, sizeof name, path, tot.frames);
            if ((res = pm_reader_open_next(f, name, &pm_queries_schema, 0, &rd)) != PM_OK || !rd)
                break;
            res = sort_doc(st, o, rd, name, &bufs, &tot);
            pm_reader_close(rd);
            if (res != PM_OK)
                break;
        }
        pm_stream_close(f);
        if (res == PM_OK && tot.frames == 0)
            res = pm_error_set(PM_ERR_INPUT, "empty stream '%s': no queries document", in_name);
    }
    bufs_free(&bufs);
    double t3 = pm_time_wall();
    if (res == PM_OK) {
        uint64_t n = tot.points;
        st->items = n;
        pm_stage_stat_int(st, "points", (int64_t)n);
        pm_stage_stat_double(st, "points_per_s", t3 > t0 ? n / (t3 - t0) : 0.0);
        pm_stage_stat_string(st, "order", pm_order_names[o->order]);
        pm_stage_stat_int(st, "leaf", (int64_t)tot.leaf);
        pm_stage_stat_string(st, "leaf_rule", tot.is_auto ? "auto" : "fixed");
        pm_stage_stat_string(st, "leaf_from", tot.leaf_from);
        pm_stage_stat_int(st, "octree_depth", tot.depth);
        pm_stage_stat_int(st, "leaves", (int64_t)tot.leaves);
        pm_stage_stat_int(st, "record_bytes", (int64_t)tot.rs);
        pm_stage_stat_double(st, "read_s", tot.read_s);
        pm_stage_stat_double(st, "keys_s", tot.keys_s);
        pm_stage_stat_double(st, "sort_s", tot.sort_s);
        pm_stage_stat_double(st, "reorder_s", tot.reorder_s);
        pm_stage_stat_double(st, "reorder_points_per_s", tot.reorder_s > 0 ? n / tot.reorder_s : 0.0);
        pm_stage_stat_double(st, "write_s", tot.write_s);
        if (o->stream)
            pm_stage_stat_int(st, "frames", (int64_t)tot.frames);
    }
    return res;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    sort_options_t o = {.order = PM_ORDER_HILBERT, .leaf = "16"};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"order", 0, PM_OPT_CHOICE, &o.order, "ORDER",
         "hilbert (the curve), morton (Z-order, for comparison) or none (records pass through unchanged)", 1, 0,
         pm_order_names},
        {"leaf", 0, PM_OPT_STRING, &o.leaf, "N|auto",
         "stop splitting cells of N points or fewer (1 sorts fully); auto picks N from the point count and cache", 1, 0,
         NULL},
        {"cache", 0, PM_OPT_INT, &o.cache, "BYTES", "cache size --leaf auto assumes; 0 asks the system (L2)", 0, 9e18,
         NULL},
        {"stream", 0, PM_OPT_FLAG, &o.stream, NULL,
         "QUERIES is a stream of documents (a frame each): sort each in turn, one document per frame to stdout", 1, 0,
         NULL},
        {0},
    };
    static const char about[] = "Reorder gather points (a queries file) along a 3-D Hilbert curve, so that packets of "
                                "queries are coherent; the records are unchanged, only their order.";
    const pm_cli_t cli = {"hilbert-sort", "[options] [QUERIES|-] [-o OUT|-]", about, options, 0, 1, "queries"};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
