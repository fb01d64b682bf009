/* describe.c: any pmtk file as text or JSON, for pm-info (describe.h).
 *
 * Reads the whole file as a table, so that the cross-record checks (tree shape, pixel indices)
 * run too, before it says "ok"; prints records from the file's layout, channel by channel in
 * schema order, floats to round-trip precision (9 digits for f32, 17 for f64). */
#include <inttypes.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "formats/describe.h"
#include "formats/formats.h"

/* ------------------------------------------------------------------ JSON habits */

json_t *pm_json_stringn(pm_json_strings_t *js, const char *what, const char *s, size_t n)
{
    json_t *v = json_stringn(s, n);
    if (!v && !js->failed) {
        json_t *raw = json_stringn_nocheck(s, n); /* succeeds unless memory is short */
        js->failed = what;
        js->nomem = raw == NULL;
        json_decref(raw);
    }
    return v;
}

pm_result_t pm_json_strings_finish(const pm_json_strings_t *js, json_t *j, json_t **j_out, const char *fmt, ...)
{
    if (j && !js->failed) {
        *j_out = j;
        return PM_OK;
    }
    json_decref(j);
    char subject[PM_ERROR_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(subject, sizeof subject, fmt, ap);
    va_end(ap);
    if (js->failed && !js->nomem)
        return pm_error_set(PM_ERR_INPUT, "cannot describe %s as JSON: %s is not UTF-8", subject, js->failed);
    return pm_error_set(PM_ERR_NOMEM, "out of memory describing %s as JSON", subject);
}

pm_result_t pm_json_write(FILE *out, json_t *j, const char *fmt, ...)
{
    int bad = json_dumpf(j, out, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) != 0 ||
              fputc('\n', out) == EOF;
    json_decref(j);
    if (!bad)
        return PM_OK;
    char what[PM_ERROR_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return pm_error_set(PM_ERR_IO, "cannot write %s", what);
}

/* ------------------------------------------------------------------ header as JSON */

/* The value of the first line KEY=... of a header text, up to its newline; null if none.
 * SOFTWARE is read here because the reader drops it (each writer rewrites it). */
static json_t *text_key(pm_json_strings_t *js, const char *text, const char *key)
{
    size_t n = strlen(key);
    for (const char *p = text; *p;) {
        const char *end = strchr(p, '\n');
        size_t len = end ? (size_t)(end - p) : strlen(p);
        if (len > n && !strncmp(p, key, n) && p[n] == '=')
            return pm_json_stringn(js, key, p + n + 1, len - n - 1);
        if (!end)
            break;
        p = end + 1;
    }
    return json_null();
}

/* An INPUT value, "<path> xxh3:<hex>", as {"path", "hash"}: the path is everything before
 * the last " xxh3:" (docs/formats.md). */
static json_t *input_json(pm_json_strings_t *js, const char *value)
{
    const char *at = NULL;
    for (const char *p = strstr(value, " xxh3:"); p; p = strstr(p + 1, " xxh3:"))
        at = p;
    json_t *o = json_object();
    json_object_set_new(o, "path", pm_json_stringn(js, "INPUT", value, at ? (size_t)(at - value) : strlen(value)));
    json_object_set_new(o, "hash", at ? pm_json_stringn(js, "INPUT", at + 1, strlen(at + 1)) : json_null());
    return o;
}

pm_result_t pm_describe_header_json(const char *name, const pm_header_t *h, const char *text, json_t **j_out)
{
    pm_json_strings_t js = {0};
    json_t *j = json_object(), *ch = json_array(), *b = json_array(), *cmds = json_array(), *inputs = json_array(),
           *keys = json_object();
    char version[32];
    snprintf(version, sizeof version, "%u.%u", h->major, h->minor);
    json_object_set_new(j, "file", pm_json_stringn(&js, "the file name", name, strlen(name)));
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
        json_array_append_new(cmds, pm_json_stringn(&js, "COMMAND", h->commands[i], strlen(h->commands[i])));
    json_object_set_new(j, "commands", cmds);
    for (size_t i = 0; i < h->nkeys; i++) {
        const pm_kv_t *kv = &h->keys[i];
        if (!strcmp(kv->key, "INPUT"))
            json_array_append_new(inputs, input_json(&js, kv->value));
        else if (!json_object_get(keys, kv->key))
            json_object_set_new(keys, kv->key, pm_json_stringn(&js, kv->key, kv->value, strlen(kv->value)));
    }
    json_object_set_new(j, "inputs", inputs);
    json_object_set_new(j, "keys", keys);
    return pm_json_strings_finish(&js, j, j_out, "'%s'", name);
}

/* ------------------------------------------------------------------ records as text */

/* The column line: a channel of one component by its name, of three as name.x/y/z (name.r/g/b
 * for colours: watts, weights, rgb), of any other count as name.0, name.1, ... */
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

/* One record in the file's layout as a line: its index, then every component; a photon map's
 * node word as "leaf" or axis=split, its child index as "-" when there is none. */
static void print_record(FILE *out, const pm_header_t *h, const unsigned char *p, uint64_t index)
{
    const pm_schema_t *s = h->schema;
    fprintf(out, "%" PRIu64, index);
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        int node = s == &pm_photonmap_schema && ci == PM_MAP_NODE;
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
                if (node && k == 0) {
                    pm_kdnode_t n;
                    memcpy(&n, p, 8);
                    uint32_t axis = pm_kdnode_axis(n);
                    if (axis == PM_KD_LEAF)
                        fprintf(out, " leaf");
                    else
                        fprintf(out, " %c=%.9g", "xyz"[axis], n.split);
                } else if (node && v == PM_KD_NONE) {
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

/* ------------------------------------------------------------------ a whole file */

pm_result_t pm_describe_file(FILE *out, const char *path, const pm_describe_options_t *o, uint64_t *count_out)
{
    *count_out = 0;
    if (o->json && o->records)
        return pm_error_set(PM_ERR_USAGE, "--json describes the header; --records prints the records as text: "
                                          "give one of them");
    pm_reader_t *r;
    pm_result_t res = pm_reader_open(path, NULL, 0, &r);
    if (res != PM_OK)
        return res;
    json_t *j = NULL;
    if (o->json && (res = pm_describe_header_json(path, pm_reader_header(r), pm_reader_header_text(r), &j)) != PM_OK) {
        pm_reader_close(r);
        return res;
    }
    if (!o->json)
        fputs(pm_reader_header_text(r), out);
    if (o->header_only) {
        pm_reader_close(r);
        if (o->json) {
            json_object_set_new(j, "checked", json_false());
            return pm_json_write(out, j, "the JSON of '%s'", path);
        }
        return PM_OK;
    }
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
            res = pm_json_write(out, j, "the JSON of '%s'", path);
            j = NULL;
        } else {
            fprintf(out, "# ok: %" PRIu64 " records, checksum xxh3:%016" PRIx64 "\n", n, t.checksum);
        }
        *count_out = n;
    }
    json_decref(j);
    pm_table_free(&t);
    return res;
}
