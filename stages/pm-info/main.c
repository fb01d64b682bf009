/* pm-info: prints the header of any pmtk file and, with --records, its records as text.
 *
 * Reads every byte and checks it (header, values, tree shape, checksum) before it
 * says "ok", so `pm-info FILE` is also the way to validate a cached intermediate. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/stage.h"
#include "formats/formats.h"

typedef struct {
    int records;        /* print records as text */
    int64_t limit;      /* at most this many records; -1 all */
    int header_only;    /* do not read the payload */
} info_options_t;

static void print_columns(FILE *out, const pm_header_t *h)
{
    const pm_schema_t *s = h->schema;
    static const char *const xyz[] = {"x", "y", "z"}, *const rgb[] = {"r", "g", "b"};
    fprintf(out, "# record");
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        if (c->components == 1) {
            fprintf(out, " %s", c->name);
            continue;
        }
        int color = !strcmp(c->unit, "W") || !strcmp(c->name, "weight") || !strcmp(c->name, "rgb");
        for (unsigned k = 0; k < c->components; k++) {
            if (c->components == 3)
                fprintf(out, " %s.%s", c->name, color ? rgb[k] : xyz[k]);
            else
                fprintf(out, " %s.%u", c->name, k);
        }
    }
    fputc('\n', out);
}

static void print_record(FILE *out, const pm_header_t *h, const unsigned char *p, uint64_t index)
{
    const pm_schema_t *s = h->schema;
    fprintf(out, "%" PRIu64, index);
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        for (unsigned k = 0; k < c->components; k++) {
            switch (c->type) {
            case PM_TYPE_U16: {
                uint16_t v;
                memcpy(&v, p, 2);
                fprintf(out, " %u", v);
                p += 2;
                break;
            }
            case PM_TYPE_U32: {
                uint32_t v;
                memcpy(&v, p, 4);
                if (s == &pm_photonmap_schema && ci == PM_MAP_NODE && k == 0) {
                    pm_kdnode_t n;
                    memcpy(&n, p, 8);
                    uint32_t axis = pm_kdnode_axis(n);
                    if (axis == PM_KD_LEAF)
                        fprintf(out, " leaf");
                    else
                        fprintf(out, " %c=%.9g", "xyz"[axis], n.split);
                } else if (v == PM_KD_NONE && s == &pm_photonmap_schema && ci == PM_MAP_NODE) {
                    fprintf(out, " -");
                } else {
                    fprintf(out, " %" PRIu32, v);
                }
                p += 4;
                break;
            }
            case PM_TYPE_F32: {
                float v;
                memcpy(&v, p, 4);
                fprintf(out, " %.9g", v);
                p += 4;
                break;
            }
            case PM_TYPE_F64: {
                double v;
                memcpy(&v, p, 8);
                fprintf(out, " %.17g", v);
                p += 8;
                break;
            }
            }
        }
    }
    fputc('\n', out);
}

static pm_result_t info_file(FILE *out, const char *path, const info_options_t *o, pm_stage_t *st)
{
    pm_reader_t *r;
    pm_result_t res = pm_reader_open(path, NULL, 0, &r);
    if (res != PM_OK)
        return res;
    fputs(pm_reader_header_text(r), out);
    if (o->header_only) {
        pm_reader_close(r);
        return PM_OK;
    }
    /* Read as a table so that cross-record checks (tree shape, pixel indices) run too. */
    pm_table_t t;
    res = pm_table_read_from(r, 0, UINT64_MAX, &t);
    pm_reader_close(r);
    if (res != PM_OK)
        return res;
    uint64_t n = t.count;
    unsigned char *rec = o->records ? malloc(t.hdr.record_size + 1) : NULL;
    if (o->records && !rec)
        res = pm_error_set(PM_ERR_NOMEM, "out of memory");
    if (rec) {
        print_columns(out, &t.hdr);
        uint64_t shown = o->limit < 0 || (uint64_t)o->limit > n ? n : (uint64_t)o->limit;
        for (uint64_t i = 0; i < shown; i++) {
            pm_table_record(&t, i, rec);
            print_record(out, &t.hdr, rec, i);
        }
    }
    free(rec);
    if (res == PM_OK) {
        fprintf(out, "# ok: %" PRIu64 " records, checksum xxh3:%016" PRIx64 "\n", n, t.checksum);
        st->items += n;
    }
    pm_table_free(&t);
    return res;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    info_options_t o = {.limit = -1};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"records", 'r', PM_OPT_FLAG, &o.records, NULL, "print every record as a line of text after the header", 1,
         0, NULL},
        {"limit", 'n', PM_OPT_INT, &o.limit, "N", "print at most N records; -1 prints all", -1, 9e18, NULL},
        {"header", 0, PM_OPT_FLAG, &o.header_only, NULL, "print the header only; do not read or check the payload",
         1, 0, NULL},
        {0},
    };
    const pm_cli_t cli = {"pm-info", "[options] FILE...",
                          "Print the header of pmtk files (photons, photonmap, queries, radiance), check every byte, "
                          "and optionally print the records.",
                          options, 0, -1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    FILE *out;
    pm_result_t res = pm_stage_open_output(&st, &out);
    if (res == PM_OK && st.args.nargs == 0)
        res = info_file(out, "-", &o, &st);
    for (int i = 0; i < st.args.nargs && res == PM_OK; i++)
        res = info_file(out, st.args.args[i], &o, &st);
    return pm_stage_end(&st, res);
}
