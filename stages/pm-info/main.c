/* pm-info: prints the header of any pmtk file and, with --records, its records as text;
 * with --json, the header as one JSON object per file, for scripts (pipelines/render).
 *
 * Reads every byte and checks it (header, values, tree shape, checksum) before it
 * says "ok", so `pm-info FILE` is also the way to validate a cached intermediate. */
#include <inttypes.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/stage.h"
#include "formats/formats.h"

typedef struct {
    int records;        /* print records as text */
    int64_t limit;      /* at most this many records; -1 all */
    int header_only;    /* do not read the payload */
    int json;           /* the header (and the check's verdict) as JSON instead of text */
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

/* Strings go into JSON through one door that remembers the first that failed: JSON carries
 * UTF-8 only, and a header value in another encoding must be an error naming its key, not a
 * key silently left out. */
typedef struct {
    const char *failed; /* the key of the first string that could not be made, or NULL */
    int nomem;          /* it failed for want of memory, not for its encoding */
} json_strings_t;

static json_t *jstr(json_strings_t *js, const char *key, const char *s, size_t n)
{
    json_t *v = json_stringn(s, n);
    if (!v && !js->failed) {
        json_t *raw = json_stringn_nocheck(s, n); /* succeeds unless memory is short */
        js->failed = key;
        js->nomem = raw == NULL;
        json_decref(raw);
    }
    return v;
}

/* The value of the first line KEY=... of a header text, up to its newline; null if none.
 * SOFTWARE is read here because the reader drops it (each writer rewrites it). */
static json_t *text_key(json_strings_t *js, const char *text, const char *key)
{
    size_t n = strlen(key);
    for (const char *p = text; *p;) {
        const char *end = strchr(p, '\n');
        size_t len = end ? (size_t)(end - p) : strlen(p);
        if (len > n && !strncmp(p, key, n) && p[n] == '=')
            return jstr(js, key, p + n + 1, len - n - 1);
        if (!end)
            break;
        p = end + 1;
    }
    return json_null();
}

/* An INPUT value, "<path> xxh3:<hex>", as {"path", "hash"}: the path is everything before
 * the last " xxh3:" (docs/formats.md). */
static json_t *input_json(json_strings_t *js, const char *value)
{
    const char *at = NULL;
    for (const char *p = strstr(value, " xxh3:"); p; p = strstr(p + 1, " xxh3:"))
        at = p;
    json_t *o = json_object();
    json_object_set_new(o, "path", jstr(js, "INPUT", value, at ? (size_t)(at - value) : strlen(value)));
    json_object_set_new(o, "hash", at ? jstr(js, "INPUT", at + 1, strlen(at + 1)) : json_null());
    return o;
}

/* One file's header as a JSON object: the structural keys typed (count and record size as
 * integers, channels as names, bounds as numbers), COMMAND and INPUT lines as arrays in file
 * order, every other key as a string under "keys" (a repeated one by its first value). */
static pm_result_t header_json(const char *name, const pm_header_t *h, const char *text, json_t **out)
{
    json_strings_t js = {0};
    json_t *j = json_object(), *ch = json_array(), *b = json_array(), *cmds = json_array(),
           *inputs = json_array(), *keys = json_object();
    char version[32];
    snprintf(version, sizeof version, "%u.%u", h->major, h->minor);
    json_object_set_new(j, "file", jstr(&js, "the file name", name, strlen(name)));
    json_object_set_new(j, "format", json_string(h->schema->name));
    json_object_set_new(j, "version", json_string(version));
    json_object_set_new(j, "byte_order", json_string("little-endian")); /* the only order a reader accepts */
    json_object_set_new(j, "count", json_integer((json_int_t)h->count));
    json_object_set_new(j, "record_size", json_integer(h->record_size));
    for (unsigned ci = 0; ci < h->schema->nchannels; ci++)
        if (h->channels & (1u << ci))
            json_array_append_new(ch, json_string(h->schema->channels[ci].name));
    json_object_set_new(j, "channels", ch);
    for (int k = 0; k < 6; k++)
        json_array_append_new(b, json_real(h->bounds[k]));
    json_object_set_new(j, "bounds", b);
    json_object_set_new(j, "software", text_key(&js, text, "SOFTWARE"));
    for (size_t i = 0; i < h->ncommands; i++)
        json_array_append_new(cmds, jstr(&js, "COMMAND", h->commands[i], strlen(h->commands[i])));
    json_object_set_new(j, "commands", cmds);
    for (size_t i = 0; i < h->nkeys; i++) {
        const pm_kv_t *kv = &h->keys[i];
        if (!strcmp(kv->key, "INPUT"))
            json_array_append_new(inputs, input_json(&js, kv->value));
        else if (!json_object_get(keys, kv->key))
            json_object_set_new(keys, kv->key, jstr(&js, kv->key, kv->value, strlen(kv->value)));
    }
    json_object_set_new(j, "inputs", inputs);
    json_object_set_new(j, "keys", keys);
    if (js.failed && !js.nomem) {
        json_decref(j);
        return pm_error_set(PM_ERR_INPUT, "cannot describe '%s' as JSON: %s is not UTF-8", name, js.failed);
    }
    if (!j || js.failed) {
        json_decref(j);
        return pm_error_set(PM_ERR_NOMEM, "out of memory describing '%s' as JSON", name);
    }
    *out = j;
    return PM_OK;
}

static pm_result_t write_json(FILE *out, json_t *j, const char *name)
{
    int bad = json_dumpf(j, out, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
              fputc('\n', out) == EOF;
    json_decref(j);
    return bad ? pm_error_set(PM_ERR_IO, "cannot write the JSON of '%s'", name) : PM_OK;
}

static pm_result_t info_file(FILE *out, const char *path, const info_options_t *o, pm_stage_t *st)
{
    pm_reader_t *r;
    pm_result_t res = pm_reader_open(path, NULL, 0, &r);
    if (res != PM_OK)
        return res;
    /* JSON is written after the check, so that a reader of it sees a whole object or none. */
    json_t *j = NULL;
    if (o->json && (res = header_json(path, pm_reader_header(r), pm_reader_header_text(r), &j)) != PM_OK) {
        pm_reader_close(r);
        return res;
    }
    if (!o->json)
        fputs(pm_reader_header_text(r), out);
    if (o->header_only) {
        pm_reader_close(r);
        if (o->json) {
            json_object_set_new(j, "checked", json_false());
            return write_json(out, j, path);
        }
        return PM_OK;
    }
    /* Read as a table so that cross-record checks (tree shape, pixel indices) run too. */
    pm_table_t t;
    res = pm_table_read_from(r, 0, UINT64_MAX, &t);
    pm_reader_close(r);
    if (res != PM_OK) {
        json_decref(j);
        return res;
    }
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
        if (o->json) {
            char sum[32];
            snprintf(sum, sizeof sum, "xxh3:%016" PRIx64, t.checksum);
            json_object_set_new(j, "checked", json_true());
            json_object_set_new(j, "checksum", json_string(sum));
            res = write_json(out, j, path);
            j = NULL;
        } else {
            fprintf(out, "# ok: %" PRIu64 " records, checksum xxh3:%016" PRIx64 "\n", n, t.checksum);
        }
        st->items += n;
    }
    json_decref(j);
    pm_table_free(&t);
    return res;
}

static pm_result_t run(pm_stage_t *st, const info_options_t *o)
{
    if (o->json && o->records)
        return pm_error_set(PM_ERR_USAGE, "--json describes the header; --records prints the records as text: "
                                          "give one of them");
    FILE *out;
    pm_result_t res = pm_stage_open_output(st, &out);
    if (res == PM_OK && st->args.nargs == 0)
        res = info_file(out, "-", o, st);
    for (int i = 0; i < st->args.nargs && res == PM_OK; i++)
        res = info_file(out, st->args.args[i], o, st);
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
        {"json", 0, PM_OPT_FLAG, &o.json, NULL,
         "print each file's header as a JSON object (after the check, with its checksum) instead of text", 1, 0,
         NULL},
        {0},
    };
    const pm_cli_t cli = {"pm-info", "[options] FILE...",
                          "Print the header of pmtk files (photons, photonmap, queries, radiance), check every byte, "
                          "and optionally print the records.",
                          options, 0, -1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
