/* header_text.c: the pmtk header as text, both ways: pm_header_format writes the lines
 * a writer puts before the records, and pmfile_header_parse reads them back and checks
 * every container key (format, version, byte order, count, channels, record size,
 * bounds) before the format's own rules. A writer runs the same parser on what it is about
 * to write, so that no file leaves pmtk that its reader would refuse. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/version.h"
#include "formats/pmfile_impl.h"

typedef struct {
    char *s;
    size_t n, cap;
    int oom;
} text_t;

static void text_printf(text_t *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void text_printf(text_t *t, const char *fmt, ...)
{
    if (t->oom)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(t->s ? t->s + t->n : NULL, t->s ? t->cap - t->n : 0, fmt, ap);
        va_end(ap);
        if (n < 0) {
            t->oom = 1;
            return;
        }
        if (t->s && t->n + (size_t)n < t->cap) {
            t->n += (size_t)n;
            return;
        }
        size_t cap = t->cap ? t->cap : 1024;
        while (cap <= t->n + (size_t)n)
            cap *= 2;
        char *s = realloc(t->s, cap);
        if (!s) {
            t->oom = 1;
            return;
        }
        t->s = s;
        t->cap = cap;
    }
}

static void channels_text(const pm_schema_t *s, uint32_t mask, text_t *t)
{
    int first = 1;
    for (unsigned i = 0; i < s->nchannels; i++)
        if (mask & (1u << i)) {
            text_printf(t, "%s%s", first ? "" : " ", s->channels[i].name);
            first = 0;
        }
}

pm_result_t pm_header_format(const pm_header_t *h, char **text_out, size_t *len_out)
{
    const pm_schema_t *s = h->schema;
    if (!s)
        return pm_error_set(PM_ERR_INTERNAL, "header has no format");
    text_t t = {0};
    text_printf(&t, "%s\n", PM_MAGIC);
    text_printf(&t, "FORMAT=%s\n", s->name);
    text_printf(&t, "VERSION=%u.%u\n", s->major, s->minor);
    text_printf(&t, "BYTE_ORDER=little-endian\n");
    text_printf(&t, "COUNT=%" PRIu64 "\n", h->count);
    text_printf(&t, "RECORD_SIZE=%" PRIu32 "\n", pm_schema_record_size(s, h->channels));
    text_printf(&t, "CHANNELS=");
    channels_text(s, h->channels, &t);
    text_printf(&t, "\n");
    /* %.9g round-trips every float exactly. */
    text_printf(&t, "BOUNDS=%.9g %.9g %.9g %.9g %.9g %.9g\n", h->bounds[0], h->bounds[1], h->bounds[2], h->bounds[3],
                h->bounds[4], h->bounds[5]);
    text_printf(&t, "SOFTWARE=pmtk %s\n", PM_VERSION_STRING);
    for (size_t i = 0; i < h->ncommands; i++)
        text_printf(&t, "COMMAND=%s\n", h->commands[i]);
    for (size_t i = 0; i < h->nkeys; i++)
        text_printf(&t, "%s=%s\n", h->keys[i].key, h->keys[i].value);
    text_printf(&t, "\n");
    if (t.oom) {
        free(t.s);
        return pm_error_set(PM_ERR_NOMEM, "out of memory formatting a header");
    }
    /* Never write a header that a reader would refuse. */
    if (t.n > PM_HEADER_MAX) {
        free(t.s);
        return pm_error_set(PM_ERR_INTERNAL, "%s header of %zu bytes exceeds %u", s->title, t.n, PM_HEADER_MAX);
    }
    for (const char *line = t.s; *line;) {
        const char *nl = strchr(line, '\n');
        if ((size_t)(nl - line) > PM_HEADER_LINE_MAX) { /* the reader's rule: the newline not counted */
            size_t len = (size_t)(nl - line);
            free(t.s);
            return pm_error_set(PM_ERR_INTERNAL, "%s header line of %zu bytes exceeds %u", s->title, len,
                                PM_HEADER_LINE_MAX);
        }
        line = nl + 1;
    }
    *text_out = t.s;
    *len_out = t.n;
    return PM_OK;
}

/* ------------------------------------------------------------------ reading */

/* Shows up to 8 bytes of what was found where a magic was expected. */
void pmfile_show_bytes(const unsigned char *b, size_t n, char *out, size_t cap)
{
    size_t o = 0;
    for (size_t i = 0; i < n && o + 5 < cap; i++) {
        if (b[i] >= 0x20 && b[i] < 0x7f && b[i] != '\'' && b[i] != '\\')
            out[o++] = (char)b[i];
        else
            o += (size_t)snprintf(out + o, cap - o, "\\x%02x", b[i]);
    }
    out[o] = '\0';
}

/* "0x" and exactly eight lower-case hex digits, as the writer writes it. */
static pm_result_t parse_u32_hex(const char *v, uint32_t *out)
{
    uint32_t x = 0;
    if (strncmp(v, "0x", 2) != 0 || strlen(v) != 10)
        return PM_ERR_INPUT;
    for (v += 2; *v; v++) {
        int d = *v >= '0' && *v <= '9' ? *v - '0' : *v >= 'a' && *v <= 'f' ? *v - 'a' + 10 : -1;
        if (d < 0)
            return PM_ERR_INPUT;
        x = 16 * x + (uint32_t)d;
    }
    *out = x;
    return PM_OK;
}

/* The container's own keys of one header, pointing into its text; NULL while absent. */
typedef struct {
    const char *format, *version, *count, *rsize, *chans, *mask, *bounds, *order;
} fields_t;

/* One "KEY=VALUE" line, NUL-terminated (cut in place at the '='): a container key goes
 * into f, a COMMAND or any other key into h; SOFTWARE is dropped. */
static pm_result_t parse_line(pm_header_t *h, const char *path, unsigned lineno, char *line, fields_t *f)
{
    char *eq = strchr(line, '=');
    if (!eq) {
        char shown[80];
        pmfile_show_bytes((const unsigned char *)line, strnlen(line, 40), shown, sizeof shown);
        return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': '%s' has no '='", lineno, path, shown);
    }
    *eq = '\0';
    const char *key = line, *val = eq + 1;
    if (!pmfile_key_ok(key))
        return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': bad key", lineno, path);
    for (const char *c = val; *c; c++)
        if ((unsigned char)*c < 0x20 || *c == 0x7f)
            return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': control byte in %s", lineno, path,
                                key);
    const struct {
        const char *key;
        const char **value;
    } structural[] = {{"FORMAT", &f->format},     {"VERSION", &f->version}, {"COUNT", &f->count},
                      {"RECORD_SIZE", &f->rsize}, {"CHANNELS", &f->chans},  {"CHANNEL_MASK", &f->mask},
                      {"BOUNDS", &f->bounds},     {"BYTE_ORDER", &f->order}};
    for (size_t k = 0; k < sizeof structural / sizeof structural[0]; k++)
        if (!strcmp(key, structural[k].key)) {
            if (*structural[k].value)
                return pm_error_set(PM_ERR_INPUT, "header of '%s' repeats %s (line %u)", path, key, lineno);
            *structural[k].value = val;
            return PM_OK;
        }
    if (!strcmp(key, "SOFTWARE")) /* the writer's version: rewritten by whoever writes next */
        return PM_OK;
    if (!strcmp(key, "COMMAND")) {
        char *c = strdup(val);
        return c ? pmfile_command_append(h, c) : pm_error_set(PM_ERR_NOMEM, "out of memory");
    }
    char *v = strdup(val);
    return v ? pmfile_kv_append(h, key, v) : pm_error_set(PM_ERR_NOMEM, "out of memory");
}

/* Every line after the magic up to the blank one, through parse_line. */
static pm_result_t parse_lines(pm_header_t *h, const char *path, char *text, fields_t *f)
{
    char *line = text + strlen(PM_MAGIC) + 1;
    for (unsigned lineno = 2; *line != '\n'; lineno++) {
        char *nl = strchr(line, '\n');
        if (!nl) /* the reader guarantees a newline; never trust it blindly */
            return pm_error_set(PM_ERR_INTERNAL, "header of '%s' ends without a newline", path);
        *nl = '\0';
        pm_result_t res = parse_line(h, path, lineno, line, f);
        if (res != PM_OK)
            return res;
        line = nl + 1;
    }
    return PM_OK;
}

/* The container keys every version's header has; the first one missing is named
 * (CHANNEL_MASK, of version 1 alone, once the version is known). */
static pm_result_t require_fields(const char *path, const fields_t *f)
{
    const struct {
        const char *value, *key;
    } required[] = {{f->format, "FORMAT"},     {f->version, "VERSION"}, {f->order, "BYTE_ORDER"}, {f->count, "COUNT"},
                    {f->rsize, "RECORD_SIZE"}, {f->chans, "CHANNELS"},  {f->bounds, "BOUNDS"}};
    for (size_t k = 0; k < sizeof required / sizeof required[0]; k++)
        if (!required[k].value)
            return pm_error_set(PM_ERR_INPUT, "header of '%s' lacks %s", path, required[k].key);
    return PM_OK;
}

/* VERSION=MAJOR.MINOR, each decimal below a million; a major above the schema's or below
 * the oldest it reads is refused. */
static pm_result_t parse_version(pm_header_t *h, const char *path, const char *version)
{
    const pm_schema_t *s = h->schema;
    uint64_t vmaj, vmin;
    char vbuf[32];
    const char *dot = strchr(version, '.');
    int vok = dot && (size_t)(dot - version) < sizeof vbuf && strlen(dot + 1) < 8;
    if (vok) {
        memcpy(vbuf, version, (size_t)(dot - version));
        vbuf[dot - version] = '\0';
        vok = pmfile_parse_decimal(vbuf, &vmaj) && pmfile_parse_decimal(dot + 1, &vmin) && vmaj < 1000000 &&
              vmin < 1000000;
    }
    if (!vok)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': malformed VERSION '%s'", s->title, path, version);
    unsigned major = (unsigned)vmaj, minor = (unsigned)vmin;
    if (major > s->major)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is version %u.%u, newer than this reader (%u.x)", s->title, path,
                            major, minor, s->major);
    unsigned oldest = s->oldest_major ? s->oldest_major : s->major;
    if (major < oldest)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is version %u.%u, older than this reader (%u.x to %u.x)", s->title,
                            path, major, minor, oldest, s->major);
    h->major = major;
    h->minor = minor;
    return PM_OK;
}

/* Version 1: CHANNEL_MASK well formed and of known channels, and CHANNELS exactly the
 * names it implies. */
static pm_result_t channels_from_mask(pm_header_t *h, const char *path, const fields_t *f)
{
    const pm_schema_t *s = h->schema;
    if (!f->mask)
        return pm_error_set(PM_ERR_INPUT, "header of '%s' lacks CHANNEL_MASK", path);
    if (parse_u32_hex(f->mask, &h->channels) != PM_OK)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': malformed CHANNEL_MASK '%s'", s->title, path, f->mask);
    uint32_t known = s->nchannels >= 32 ? 0xffffffffu : (1u << s->nchannels) - 1;
    if (h->channels & ~known)
        return pm_error_set(PM_ERR_INPUT,
                            "%s '%s': CHANNEL_MASK 0x%08" PRIx32 " names channels unknown to version %u.%u", s->title,
                            path, h->channels, s->major, s->minor);
    text_t ct = {0};
    channels_text(s, h->channels, &ct);
    int agree = !ct.oom && strcmp(ct.s ? ct.s : "", f->chans) == 0;
    free(ct.s);
    if (!agree)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': CHANNELS '%s' disagrees with CHANNEL_MASK %s", s->title, path,
                            f->chans, f->mask);
    return PM_OK;
}

/* The index of the schema's channel named by the len bytes at p, or nchannels if none. */
static unsigned channel_named(const pm_schema_t *s, const char *p, size_t len)
{
    unsigned ci = 0;
    while (ci < s->nchannels && !(strlen(s->channels[ci].name) == len && !strncmp(s->channels[ci].name, p, len)))
        ci++;
    return ci;
}

/* Version 2 on: CHANNELS alone, each name a channel of the schema, spelled as a writer
 * writes it (channel order, each once, one space apart), so that one set of channels has
 * one spelling. A CHANNEL_MASK is refused: no writer of these versions writes one, and a
 * second statement of the channels could only disagree with the first. */
static pm_result_t channels_from_names(pm_header_t *h, const char *path, const fields_t *f)
{
    const pm_schema_t *s = h->schema;
    if (f->mask)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is version %u.%u but has CHANNEL_MASK, a version-%u key", s->title,
                            path, h->major, h->minor, PM_MAJOR_WITH_MASK);
    uint32_t mask = 0;
    for (const char *p = f->chans; *p;) {
        size_t len = strcspn(p, " ");
        unsigned ci = channel_named(s, p, len);
        if (len && ci == s->nchannels)
            return pm_error_set(PM_ERR_INPUT, "%s '%s': CHANNELS names '%.*s', not a channel of version %u.%u",
                                s->title, path, (int)(len < 64 ? len : 64), p, s->major, s->minor);
        if (len)
            mask |= 1u << ci;
        p += len + (p[len] == ' ');
    }
    text_t ct = {0};
    channels_text(s, mask, &ct);
    if (ct.oom) {
        free(ct.s);
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", path);
    }
    const char *canonical = ct.s ? ct.s : "";
    int same = strcmp(canonical, f->chans) == 0;
    pm_result_t res = same ? PM_OK
                           : pm_error_set(PM_ERR_INPUT,
                                          "%s '%s': CHANNELS '%s' is not spelled '%s' (channel order, each once, "
                                          "one space apart)",
                                          s->title, path, f->chans, canonical);
    free(ct.s);
    h->channels = mask;
    return res;
}

/* The channels present, from CHANNEL_MASK and CHANNELS (version 1) or CHANNELS alone; the
 * schema's required channels and the caller's among them. */
static pm_result_t parse_channels(pm_header_t *h, const char *path, const fields_t *f, uint32_t need)
{
    const pm_schema_t *s = h->schema;
    pm_result_t res = h->major <= PM_MAJOR_WITH_MASK ? channels_from_mask(h, path, f) : channels_from_names(h, path, f);
    if (res != PM_OK)
        return res;
    uint32_t missing = pm_schema_required(s) & ~h->channels;
    if (missing)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks required channel '%s'", s->title, path,
                            s->channels[__builtin_ctz(missing)].name);
    missing = need & ~h->channels;
    if (missing)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks channel '%s' needed here", s->title, path,
                            s->channels[__builtin_ctz(missing)].name);
    return PM_OK;
}

/* RECORD_SIZE: exactly the bytes the present channels take. */
static pm_result_t parse_record_size(pm_header_t *h, const char *path, const char *rsize)
{
    uint64_t rs;
    uint32_t expect = pm_schema_record_size(h->schema, h->channels);
    if (!pmfile_parse_decimal(rsize, &rs) || rs != expect)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': RECORD_SIZE '%s' but its channels take %" PRIu32 " bytes",
                            h->schema->title, path, rsize, expect);
    h->record_size = expect;
    return PM_OK;
}

/* BOUNDS: six finite numbers that fit a float, min <= max on each axis. */
static pm_result_t parse_bounds(pm_header_t *h, const char *path, const char *bounds)
{
    const char *title = h->schema->title;
    double b[6];
    int nb = 0, pos = 0;
    const char *p = bounds;
    for (; nb < 6; nb++) {
        if (sscanf(p, "%lf%n", &b[nb], &pos) != 1)
            break;
        p += pos;
    }
    while (*p == ' ')
        p++;
    if (nb != 6 || *p)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' is not six numbers", title, path, bounds);
    for (int i = 0; i < 6; i++) {
        if (!isfinite(b[i]) || fabs(b[i]) > 3.4e38)
            return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' has a non-finite value", title, path, bounds);
        h->bounds[i] = (float)b[i];
    }
    for (int i = 0; i < 3; i++)
        if (h->bounds[i] > h->bounds[i + 3])
            return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' has min above max on axis %c", title, path, bounds,
                                "xyz"[i]);
    return PM_OK;
}

pm_result_t pmfile_header_parse(pm_header_t *h, const char *path, char *text, const pm_schema_t *want, uint32_t need)
{
    fields_t f = {0};
    pm_result_t res = parse_lines(h, path, text, &f);
    if (res == PM_OK)
        res = require_fields(path, &f);
    if (res != PM_OK)
        return res;

    const pm_schema_t *s = pm_schema_find(f.format);
    if (!s)
        return pm_error_set(PM_ERR_INPUT, "'%s' has unknown format '%s'", path, f.format);
    if (want && s != want)
        return pm_error_set(PM_ERR_INPUT, "'%s' is a %s, expected a %s", path, s->title, want->title);
    h->schema = s;

    res = parse_version(h, path, f.version);
    if (res != PM_OK)
        return res;
    if (strcmp(f.order, "little-endian") != 0)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': BYTE_ORDER '%s' is not little-endian", s->title, path, f.order);
    if (!pmfile_parse_decimal(f.count, &h->count) || h->count > PM_COUNT_MAX)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': absurd COUNT '%s'", s->title, path, f.count);
    res = parse_channels(h, path, &f, need);
    if (res == PM_OK)
        res = parse_record_size(h, path, f.rsize);
    if (res == PM_OK)
        res = parse_bounds(h, path, f.bounds);
    if (res == PM_OK && s->validate_header)
        res = s->validate_header(h, path);
    return res;
}
