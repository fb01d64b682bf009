/* pmfile.c: reader and writer of the pmtk container (see pmfile.h, docs/formats.md). */
#define _POSIX_C_SOURCE 200809L
#include "formats/pmfile.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <xxhash.h>
#if defined(__x86_64__)
/* libxxhash's run-time dispatch: XXH3 in AVX2 or AVX-512 where the CPU has them (4x the
 * SSE2 default here), the same hash. */
#include <xxh_x86dispatch.h>
#endif

#include "base/args.h"
#include "base/atomic.h"
#include "base/memory.h"
#include "base/version.h"

_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "pmtk files are little-endian; port the codecs");
_Static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE binary32 and binary64 expected");

/* The byte-order marker: the 32-bit value 0x01020304 as written by a little-endian
 * writer. A big-endian file would show 01 02 03 04. */
static const unsigned char pm_bom[4] = {0x04, 0x03, 0x02, 0x01};

#define PM_CHUNK_RECORDS 4096 /* records per I/O and transposition step */

/* ------------------------------------------------------------------ schemas */

size_t pm_type_size(pm_type_t t)
{
    switch (t) {
    case PM_TYPE_U16: return 2;
    case PM_TYPE_U32: return 4;
    case PM_TYPE_F32: return 4;
    case PM_TYPE_F64: return 8;
    }
    return 0;
}

static size_t channel_size(const pm_channel_t *c) { return pm_type_size(c->type) * c->components; }

uint32_t pm_schema_record_size(const pm_schema_t *s, uint32_t mask)
{
    uint32_t n = 0;
    for (unsigned i = 0; i < s->nchannels; i++)
        if (mask & (1u << i))
            n += (uint32_t)channel_size(&s->channels[i]);
    return n;
}

uint32_t pm_schema_offset(const pm_schema_t *s, uint32_t mask, unsigned channel)
{
    return pm_schema_record_size(s, mask & ((1u << channel) - 1));
}

uint32_t pm_schema_required(const pm_schema_t *s)
{
    uint32_t m = 0;
    for (unsigned i = 0; i < s->nchannels; i++)
        if (s->channels[i].flags & PM_CH_REQUIRED)
            m |= 1u << i;
    return m;
}

const pm_schema_t *pm_schema_find(const char *name)
{
    for (const pm_schema_t *const *s = pm_schema_all(); *s; s++)
        if (strcmp((*s)->name, name) == 0)
            return *s;
    return NULL;
}

/* ------------------------------------------------------------------ headers */

void pm_header_init(pm_header_t *h, const pm_schema_t *s)
{
    memset(h, 0, sizeof *h);
    h->schema = s;
    if (s) {
        h->major = s->major;
        h->minor = s->minor;
    }
}

void pm_header_free(pm_header_t *h)
{
    for (size_t i = 0; i < h->ncommands; i++)
        free(h->commands[i]);
    free(h->commands);
    for (size_t i = 0; i < h->nkeys; i++) {
        free(h->keys[i].key);
        free(h->keys[i].value);
    }
    free(h->keys);
    h->commands = NULL;
    h->keys = NULL;
    h->ncommands = h->nkeys = 0;
}

static int key_char_ok(int c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == '-';
}

static int key_ok(const char *k)
{
    if (!*k)
        return 0;
    for (; *k; k++)
        if (!key_char_ok((unsigned char)*k))
            return 0;
    return 1;
}

/* Values are one line of printable text; a writer replaces anything else. */
static void value_clean(char *v)
{
    for (; *v; v++)
        if ((unsigned char)*v < 0x20 || *v == 0x7f)
            *v = ' ';
}

/* Keys the container writes itself; a stage setting one would write it twice. */
static int key_reserved(const char *k)
{
    static const char *const reserved[] = {"FORMAT",   "VERSION", "BYTE_ORDER", "COUNT",   "RECORD_SIZE",
                                           "CHANNELS", "CHANNEL_MASK", "BOUNDS", "SOFTWARE", "COMMAND", NULL};
    for (const char *const *r = reserved; *r; r++)
        if (strcmp(*r, k) == 0)
            return 1;
    return 0;
}

static pm_result_t kv_append(pm_header_t *h, const char *key, char *value_owned)
{
    if (key_reserved(key)) {
        free(value_owned);
        return pm_error_set(PM_ERR_INTERNAL, "header key '%s' is the container's own, not a stage's", key);
    }
    if (!key_ok(key)) {
        free(value_owned);
        return pm_error_set(PM_ERR_INTERNAL, "header key '%s' has characters outside [A-Za-z0-9_.-]", key);
    }
    pm_kv_t *k = realloc(h->keys, (h->nkeys + 1) * sizeof *k);
    char *kc = strdup(key);
    if (!k || !kc) {
        if (k)
            h->keys = k;
        free(kc);
        free(value_owned);
        return pm_error_set(PM_ERR_NOMEM, "out of memory adding header key '%s'", key);
    }
    h->keys = k;
    value_clean(value_owned);
    k[h->nkeys].key = kc;
    k[h->nkeys].value = value_owned;
    h->nkeys++;
    return PM_OK;
}

static char *vformat(const char *fmt, va_list ap)
{
    va_list ap2;
    va_copy(ap2, ap);
    int n = vsnprintf(NULL, 0, fmt, ap2);
    va_end(ap2);
    if (n < 0)
        return NULL;
    char *s = malloc((size_t)n + 1);
    if (s)
        vsnprintf(s, (size_t)n + 1, fmt, ap);
    return s;
}

pm_result_t pm_header_add(pm_header_t *h, const char *key, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *v = vformat(fmt, ap);
    va_end(ap);
    if (!v)
        return pm_error_set(PM_ERR_NOMEM, "out of memory adding header key '%s'", key);
    return kv_append(h, key, v);
}

pm_result_t pm_header_set(pm_header_t *h, const char *key, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *v = vformat(fmt, ap);
    va_end(ap);
    if (!v)
        return pm_error_set(PM_ERR_NOMEM, "out of memory setting header key '%s'", key);
    for (size_t i = 0; i < h->nkeys && !key_reserved(key); i++)
        if (strcmp(h->keys[i].key, key) == 0) {
            free(h->keys[i].value);
            value_clean(v);
            h->keys[i].value = v;
            return PM_OK;
        }
    return kv_append(h, key, v);
}

const char *pm_header_get(const pm_header_t *h, const char *key)
{
    for (size_t i = 0; i < h->nkeys; i++)
        if (strcmp(h->keys[i].key, key) == 0)
            return h->keys[i].value;
    return NULL;
}

static const char *title_of(const pm_header_t *h) { return h->schema ? h->schema->title : "pmtk file"; }

/* Header numbers have one spelling: decimal digits only (no sign, exponent or space), so
 * that two files with equal content have equal bytes and a reader cannot be fooled. */
static int parse_decimal(const char *v, uint64_t *out)
{
    uint64_t x = 0;
    if (!*v || strlen(v) > 19 || (v[0] == '0' && v[1])) /* no leading zeros: 07 is not 7's spelling */
        return 0;
    for (; *v; v++) {
        if (*v < '0' || *v > '9')
            return 0;
        x = 10 * x + (uint64_t)(*v - '0');
    }
    *out = x;
    return 1;
}

pm_result_t pm_header_get_u64(const pm_header_t *h, const char *path, const char *key, uint64_t *out)
{
    const char *v = pm_header_get(h, key);
    if (!v)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks header key '%s'", title_of(h), path, key);
    if (!parse_decimal(v, out))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': header key %s='%s' is not a decimal integer", title_of(h),
                            path, key, v);
    return PM_OK;
}

static pm_result_t command_append(pm_header_t *h, char *cmd_owned)
{
    char **c = realloc(h->commands, (h->ncommands + 1) * sizeof *c);
    if (!c) {
        free(cmd_owned);
        return pm_error_set(PM_ERR_NOMEM, "out of memory adding a command line");
    }
    value_clean(cmd_owned);
    h->commands = c;
    c[h->ncommands++] = cmd_owned;
    return PM_OK;
}

static int needs_quotes(const char *s)
{
    if (!*s)
        return 1;
    for (; *s; s++)
        if (!(key_char_ok((unsigned char)*s) || strchr("/:,=+@%^", *s)))
            return 1;
    return 0;
}

pm_result_t pm_header_add_command(pm_header_t *h, int argc, char *const *argv)
{
    size_t n = 1;
    for (int i = 0; i < argc; i++)
        n += 4 * strlen(argv[i]) + 3; /* worst case: every char a quoted quote */
    char *s = malloc(n), *p = s;
    if (!s)
        return pm_error_set(PM_ERR_NOMEM, "out of memory recording the command line");
    for (int i = 0; i < argc; i++) {
        if (i)
            *p++ = ' ';
        const char *a = argv[i];
        if (i == 0) { /* the program's name, not the path it was run by */
            const char *slash = strrchr(a, '/');
            a = slash ? slash + 1 : a;
        }
        if (!needs_quotes(a)) {
            p += sprintf(p, "%s", a);
            continue;
        }
        *p++ = '\'';
        for (; *a; a++) {
            if (*a == '\'') {
                memcpy(p, "'\\''", 4);
                p += 4;
            } else {
                *p++ = *a;
            }
        }
        *p++ = '\'';
    }
    *p = '\0';
    /* Provenance, not data: a command longer than a header line may be is cut, visibly. */
    if (strlen(s) > PM_COMMAND_MAX)
        strcpy(s + PM_COMMAND_MAX - 4, " ...");
    return command_append(h, s);
}

pm_result_t pm_header_inherit(pm_header_t *h, const pm_header_t *src)
{
    for (size_t i = 0; i < src->ncommands; i++) {
        int seen = 0;
        for (size_t j = 0; j < h->ncommands && !seen; j++)
            seen = strcmp(h->commands[j], src->commands[i]) == 0;
        if (seen)
            continue;
        char *c = strdup(src->commands[i]);
        if (!c)
            return pm_error_set(PM_ERR_NOMEM, "out of memory copying provenance");
        pm_result_t r = command_append(h, c);
        if (r != PM_OK)
            return r;
    }
    const char *scene = pm_header_get(src, "SCENE");
    if (scene && !pm_header_get(h, "SCENE"))
        return pm_header_set(h, "SCENE", "%s", scene);
    return PM_OK;
}

pm_result_t pm_header_add_input(pm_header_t *h, const char *path, uint64_t hash)
{
    return pm_header_add(h, "INPUT", "%s xxh3:%016" PRIx64, path, hash);
}

pm_result_t pm_header_copy_keys(pm_header_t *h, const pm_header_t *src)
{
    for (size_t i = 0; i < src->nkeys; i++) {
        if (strcmp(src->keys[i].key, "INPUT") == 0 || pm_header_get(h, src->keys[i].key))
            continue;
        pm_result_t r = pm_header_add(h, src->keys[i].key, "%s", src->keys[i].value);
        if (r != PM_OK)
            return r;
    }
    return PM_OK;
}

/* Growable text buffer for formatting headers. */
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
    text_printf(&t, "\nCHANNEL_MASK=0x%08" PRIx32 "\n", h->channels);
    /* %.9g round-trips every float exactly. */
    text_printf(&t, "BOUNDS=%.9g %.9g %.9g %.9g %.9g %.9g\n", h->bounds[0], h->bounds[1], h->bounds[2],
                h->bounds[3], h->bounds[4], h->bounds[5]);
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

/* ------------------------------------------------------------------ reader */

struct pm_reader {
    FILE *f;
    int own_file;
    char *path;
    pm_header_t hdr;
    XXH3_state_t *hash;
    uint64_t next;            /* index of the next record to read */
    uint64_t file_size;       /* bytes, when the input is a regular file; else 0 */
    uint64_t payload_offset;  /* bytes before the first record */
    unsigned char *scratch;   /* one chunk of raw records for validation */
    char *raw;                /* the header text as read */
};

static const char *reader_title(const pm_reader_t *r) { return title_of(&r->hdr); }

/* Shows up to 8 bytes of what was found where a magic was expected. */
static void show_bytes(const unsigned char *b, size_t n, char *out, size_t cap)
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

/* Reads header text up to and including the blank line that ends it. */
static pm_result_t read_header_text(pm_reader_t *r, char **text_out, size_t *len_out)
{
    unsigned char magic[sizeof PM_MAGIC]; /* "#?PMTK\n" */
    size_t got = fread(magic, 1, sizeof magic, r->f);
    if (got < sizeof magic || memcmp(magic, PM_MAGIC "\n", sizeof magic) != 0) {
        if (got == 0)
            return pm_error_set(PM_ERR_INPUT, "empty input '%s': expected a pmtk file", r->path);
        char shown[64];
        show_bytes(magic, got, shown, sizeof shown);
        return pm_error_set(PM_ERR_INPUT, "bad magic in '%s': expected '#?PMTK', found '%s'", r->path, shown);
    }
    size_t cap = 4096, n = sizeof magic;
    char *t = malloc(cap);
    if (!t)
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading the header of '%s'", r->path);
    memcpy(t, magic, n);
    size_t line_start = n;
    for (;;) {
        int c = getc_unlocked(r->f);
        if (c == EOF) {
            free(t);
            return pm_error_set(PM_ERR_INPUT, "truncated header in '%s': no blank line ends it", r->path);
        }
        if (n >= PM_HEADER_MAX) {
            free(t);
            return pm_error_set(PM_ERR_INPUT, "header of '%s' exceeds %u bytes", r->path, PM_HEADER_MAX);
        }
        if (n + 1 >= cap) {
            char *t2 = realloc(t, cap * 2);
            if (!t2) {
                free(t);
                return pm_error_set(PM_ERR_NOMEM, "out of memory reading the header of '%s'", r->path);
            }
            t = t2;
            cap *= 2;
        }
        if (c == '\0') { /* the header is text: a NUL would cut it short when parsed */
            free(t);
            return pm_error_set(PM_ERR_INPUT, "malformed header in '%s': NUL byte at offset %zu", r->path, n);
        }
        t[n++] = (char)c;
        if (c != '\n') {
            if (n - line_start > PM_HEADER_LINE_MAX) {
                free(t);
                return pm_error_set(PM_ERR_INPUT, "header line of '%s' exceeds %u bytes", r->path,
                                    PM_HEADER_LINE_MAX);
            }
            continue;
        }
        if (n - line_start == 1) /* an empty line: the end */
            break;
        line_start = n;
    }
    t[n] = '\0';
    *text_out = t;
    *len_out = n;
    return PM_OK;
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

/* Parses the header lines into r->hdr; checks structure, version, channels. */
static pm_result_t parse_header(pm_reader_t *r, char *text, const pm_schema_t *want, uint32_t need)
{
    pm_header_t *h = &r->hdr;
    const char *path = r->path;
    const char *format = NULL, *version = NULL, *count = NULL, *rsize = NULL, *chans = NULL, *mask = NULL,
               *bounds = NULL, *order = NULL;
    pm_result_t res = PM_OK;
    char *line = text + strlen(PM_MAGIC) + 1;
    for (unsigned lineno = 2; *line != '\n' && res == PM_OK; lineno++) {
        char *nl = strchr(line, '\n');
        if (!nl) /* read_header_text guarantees a newline; never trust it blindly */
            return pm_error_set(PM_ERR_INTERNAL, "header of '%s' ends without a newline", path);
        *nl = '\0';
        char *eq = strchr(line, '=');
        if (!eq) {
            char shown[80];
            show_bytes((const unsigned char *)line, strnlen(line, 40), shown, sizeof shown);
            return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': '%s' has no '='", lineno, path,
                                shown);
        }
        *eq = '\0';
        const char *key = line, *val = eq + 1;
        if (!key_ok(key))
            return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': bad key", lineno, path);
        for (const char *c = val; *c; c++)
            if ((unsigned char)*c < 0x20 || *c == 0x7f)
                return pm_error_set(PM_ERR_INPUT, "malformed header line %u in '%s': control byte in %s",
                                    lineno, path, key);
        const struct {
            const char *key;
            const char **value;
        } structural[] = {{"FORMAT", &format}, {"VERSION", &version},     {"COUNT", &count},
                          {"RECORD_SIZE", &rsize}, {"CHANNELS", &chans}, {"CHANNEL_MASK", &mask},
                          {"BOUNDS", &bounds}, {"BYTE_ORDER", &order}};
        const char **slot = NULL;
        for (size_t k = 0; k < sizeof structural / sizeof structural[0] && !slot; k++)
            if (!strcmp(key, structural[k].key))
                slot = structural[k].value;
        if (slot) {
            if (*slot)
                return pm_error_set(PM_ERR_INPUT, "header of '%s' repeats %s (line %u)", path, key, lineno);
            *slot = val;
        } else if (!strcmp(key, "SOFTWARE")) {
            /* the writer's version: rewritten by whoever writes next */
        } else if (!strcmp(key, "COMMAND")) {
            char *c = strdup(val);
            res = c ? command_append(h, c) : pm_error_set(PM_ERR_NOMEM, "out of memory");
        } else {
            char *v = strdup(val);
            res = v ? kv_append(h, key, v) : pm_error_set(PM_ERR_NOMEM, "out of memory");
        }
        line = nl + 1;
    }
    if (res != PM_OK)
        return res;

#define REQUIRE(var, name)                                                                                  \
    if (!(var))                                                                                             \
        return pm_error_set(PM_ERR_INPUT, "header of '%s' lacks %s", path, name);
    REQUIRE(format, "FORMAT")
    REQUIRE(version, "VERSION")
    REQUIRE(order, "BYTE_ORDER")
    REQUIRE(count, "COUNT")
    REQUIRE(rsize, "RECORD_SIZE")
    REQUIRE(chans, "CHANNELS")
    REQUIRE(mask, "CHANNEL_MASK")
    REQUIRE(bounds, "BOUNDS")
#undef REQUIRE

    const pm_schema_t *s = pm_schema_find(format);
    if (!s)
        return pm_error_set(PM_ERR_INPUT, "'%s' has unknown format '%s'", path, format);
    if (want && s != want)
        return pm_error_set(PM_ERR_INPUT, "'%s' is a %s, expected a %s", path, s->title, want->title);
    h->schema = s;

    unsigned major, minor;
    uint64_t vmaj, vmin;
    char vbuf[32];
    const char *dot = strchr(version, '.');
    int vok = dot && (size_t)(dot - version) < sizeof vbuf && strlen(dot + 1) < 8;
    if (vok) {
        memcpy(vbuf, version, (size_t)(dot - version));
        vbuf[dot - version] = '\0';
        vok = parse_decimal(vbuf, &vmaj) && parse_decimal(dot + 1, &vmin) && vmaj < 1000000 && vmin < 1000000;
    }
    if (!vok)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': malformed VERSION '%s'", s->title, path, version);
    major = (unsigned)vmaj;
    minor = (unsigned)vmin;
    if (major > s->major)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is version %u.%u, newer than this reader (%u.x)", s->title,
                            path, major, minor, s->major);
    if (major < s->major)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' is version %u.%u, older than this reader (%u.x)", s->title,
                            path, major, minor, s->major);
    h->major = major;
    h->minor = minor;

    if (strcmp(order, "little-endian") != 0)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': BYTE_ORDER '%s' is not little-endian", s->title, path, order);

    if (!parse_decimal(count, &h->count) || h->count > PM_COUNT_MAX)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': absurd COUNT '%s'", s->title, path, count);

    if (parse_u32_hex(mask, &h->channels) != PM_OK)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': malformed CHANNEL_MASK '%s'", s->title, path, mask);
    uint32_t known = s->nchannels >= 32 ? 0xffffffffu : (1u << s->nchannels) - 1;
    if (h->channels & ~known)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': CHANNEL_MASK 0x%08" PRIx32 " names channels unknown to version %u.%u",
                            s->title, path, h->channels, s->major, s->minor);
    text_t ct = {0};
    channels_text(s, h->channels, &ct);
    int agree = !ct.oom && strcmp(ct.s ? ct.s : "", chans) == 0;
    free(ct.s);
    if (!agree)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': CHANNELS '%s' disagrees with CHANNEL_MASK %s", s->title, path,
                            chans, mask);
    uint32_t missing = pm_schema_required(s) & ~h->channels;
    if (missing)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks required channel '%s'", s->title, path,
                            s->channels[__builtin_ctz(missing)].name);
    missing = need & ~h->channels;
    if (missing)
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks channel '%s' needed here", s->title, path,
                            s->channels[__builtin_ctz(missing)].name);

    uint64_t rs;
    uint32_t expect = pm_schema_record_size(s, h->channels);
    if (!parse_decimal(rsize, &rs) || rs != expect)
        return pm_error_set(PM_ERR_INPUT, "%s '%s': RECORD_SIZE '%s' but its channels take %" PRIu32 " bytes",
                            s->title, path, rsize, expect);
    h->record_size = expect;

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
        return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' is not six numbers", s->title, path, bounds);
    for (int i = 0; i < 6; i++) {
        if (!isfinite(b[i]) || fabs(b[i]) > 3.4e38)
            return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' has a non-finite value", s->title, path,
                                bounds);
        h->bounds[i] = (float)b[i];
    }
    for (int i = 0; i < 3; i++)
        if (h->bounds[i] > h->bounds[i + 3])
            return pm_error_set(PM_ERR_INPUT, "%s '%s': BOUNDS '%s' has min above max on axis %c", s->title, path,
                                bounds, "xyz"[i]);
    if (s->validate_header)
        return s->validate_header(h, path);
    return PM_OK;
}

static pm_result_t reader_start(pm_reader_t *r, const pm_schema_t *schema, uint32_t need, pm_reader_t **out);

pm_result_t pm_reader_open(const char *path, const pm_schema_t *schema, uint32_t need, pm_reader_t **out)
{
    *out = NULL;
    if (strcmp(path, "-") == 0)
        return pm_reader_open_stream(stdin, "stdin", schema, need, out);
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        return pm_error_set(e == ENOENT ? PM_ERR_INPUT : PM_ERR_IO, "cannot open '%s': %s", path, strerror(e));
    }
    pm_result_t res = pm_reader_open_stream(f, path, schema, need, out);
    if (res != PM_OK)
        fclose(f);
    else
        (*out)->own_file = 1;
    return res;
}

pm_result_t pm_reader_open_stream(FILE *f, const char *name, const pm_schema_t *schema, uint32_t need,
                                  pm_reader_t **out)
{
    *out = NULL;
    pm_reader_t *r = calloc(1, sizeof *r);
    if (!r)
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", name);
    r->f = f;
    r->path = strdup(name);
    r->hash = XXH3_createState();
    if (!r->path || !r->hash) {
        r->f = NULL; /* the caller's stream */
        pm_reader_close(r);
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", name);
    }
    pm_header_init(&r->hdr, schema);
    XXH3_64bits_reset(r->hash);
    return reader_start(r, schema, need, out);
}

/* Reads and checks the header of r's stream; on failure closes r (not the stream). */
static pm_result_t reader_start(pm_reader_t *r, const pm_schema_t *schema, uint32_t need, pm_reader_t **out)
{
    const char *path = r->path;
    struct stat st;
    if (fstat(fileno(r->f), &st) == 0 && S_ISREG(st.st_mode))
        r->file_size = (uint64_t)st.st_size;
    else if (fstat(fileno(r->f), &st) == 0 && S_ISDIR(st.st_mode)) {
        pm_result_t res = pm_error_set(PM_ERR_INPUT, "'%s' is a directory, not a pmtk file", path);
        pm_reader_close(r);
        return res;
    }

    char *text = NULL;
    size_t len = 0;
    pm_result_t res = read_header_text(r, &text, &len);
    if (res == PM_OK) {
        XXH3_64bits_update(r->hash, text, len);
        char *work = strdup(text); /* parse_header cuts its text into lines */
        res = work ? parse_header(r, work, schema, need)
                   : pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", r->path);
        free(work);
    }
    r->raw = text;
    if (res == PM_OK) {
        unsigned char bom[4];
        size_t got = fread(bom, 1, 4, r->f);
        if (got < 4)
            res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': no byte-order marker after the header",
                               reader_title(r), r->path);
        else if (bom[0] == 0x01 && bom[1] == 0x02 && bom[2] == 0x03 && bom[3] == 0x04)
            res = pm_error_set(PM_ERR_INPUT, "%s '%s' is big-endian; pmtk reads little-endian files",
                               reader_title(r), r->path);
        else if (memcmp(bom, pm_bom, 4) != 0)
            res = pm_error_set(PM_ERR_INPUT, "%s '%s': bad byte-order marker %02x %02x %02x %02x",
                               reader_title(r), r->path, bom[0], bom[1], bom[2], bom[3]);
        else
            XXH3_64bits_update(r->hash, bom, 4);
        r->payload_offset = len + 4;
    }
    if (res == PM_OK && r->file_size) {
        /* A regular file's size tells truncation and extra bytes before any record is read. */
        uint64_t want = r->payload_offset + r->hdr.count * r->hdr.record_size + 8;
        if (r->file_size < want) {
            uint64_t have = r->file_size > r->payload_offset ? r->file_size - r->payload_offset : 0;
            if (have >= r->hdr.count * r->hdr.record_size)
                res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': checksum missing after %" PRIu64 " records",
                                   reader_title(r), r->path, r->hdr.count);
            else
                res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': ends in record %" PRIu64 " of %" PRIu64,
                                   reader_title(r), r->path, have / r->hdr.record_size, r->hdr.count);
        } else if (r->file_size > want) {
            res = pm_error_set(PM_ERR_INPUT,
                               "wrong count in %s '%s': COUNT=%" PRIu64 " but %" PRIu64 " bytes follow the checksum",
                               reader_title(r), r->path, r->hdr.count, r->file_size - want);
        }
    }
    if (res == PM_OK) {
        r->scratch = malloc((size_t)PM_CHUNK_RECORDS * (r->hdr.record_size ? r->hdr.record_size : 1));
        if (!r->scratch)
            res = pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", r->path);
    }
    if (res != PM_OK) {
        pm_reader_close(r);
        return res;
    }
    *out = r;
    return PM_OK;
}

const pm_header_t *pm_reader_header(const pm_reader_t *r) { return &r->hdr; }

/* The exact check, value by value in double, and the source of every message: checks the
 * values of n raw records starting at record index first, against the channel flags of h's
 * schema, channel by channel; path names the file in messages. check_values runs it only on
 * a chunk where its fast pass saw a value that may fail. */
static pm_result_t check_values_exact(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                      uint64_t first)
{
    const pm_schema_t *s = h->schema;
    size_t off = 0;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        unsigned fl = c->flags;
        size_t csize = channel_size(c);
        if ((c->type == PM_TYPE_F32 || c->type == PM_TYPE_F64) &&
            (fl & (PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE))) {
            for (uint64_t i = 0; i < n; i++) {
                const unsigned char *p = rec + i * h->record_size + off;
                double len2 = 0.0;
                for (unsigned k = 0; k < c->components; k++) {
                    double v;
                    if (c->type == PM_TYPE_F32) {
                        float f;
                        memcpy(&f, p + 4 * k, 4);
                        v = f;
                    } else {
                        memcpy(&v, p + 8 * k, 8);
                    }
                    const char *why = NULL;
                    if (!isfinite(v))
                        why = "not finite";
                    else if ((fl & PM_CH_NONNEG) && v < 0.0)
                        why = "negative";
                    else if ((fl & PM_CH_POSITIVE) && !(v > 0.0))
                        why = "not positive";
                    if (why)
                        return pm_error_set(PM_ERR_INPUT,
                                            "bad value in %s '%s': record %" PRIu64 " channel '%s'[%u] is %g (%s)",
                                            s->title, path, first + i, c->name, k, v, why);
                    len2 += v * v;
                }
                if ((fl & PM_CH_UNIT) && fabs(len2 - 1.0) > 2e-3)
                    return pm_error_set(PM_ERR_INPUT,
                                        "bad value in %s '%s': record %" PRIu64 " channel '%s' has length %g, not 1",
                                        s->title, path, first + i, c->name, sqrt(len2));
            }
        }
        off += csize;
    }
    return s->validate_records ? s->validate_records(h, path, rec, n, first) : PM_OK;
}

/* ---- the fast pass of the value checks ----
 *
 * Every chunk a reader reads and a writer writes is checked, so this runs at the speed of
 * the I/O. It answers one question, "might any value of these records fail?", and is
 * conservative: it says yes for every value the exact check rejects, and perhaps for a few
 * it accepts (a negative subnormal, a unit vector within 1e-5 of the tolerance, a channel
 * with a check it does not model). Then the chunk goes through check_values_exact, which
 * decides and words the message, so the accepted values and the messages are exactly the
 * exact check's.
 *
 * Records are AoS with any size and alignment (54-byte records put floats at odd offsets),
 * so each channel of a block of PM_CHECK_BLOCK records is first copied into one small
 * column per component (in L1), and the tests run as fixed-length loops over those columns
 * that the compiler vectorizes: integer tests on the bits for finite / >= 0 / > 0, float
 * arithmetic for unit length. */
#define PM_CHECK_BLOCK 256 /* records per block: 4 columns of 1 KiB */
#define PM_F32_EXP 0x7f800000u
#define PM_F32_ONE 0x3f800000u

typedef struct {
    uint32_t v[4][PM_CHECK_BLOCK] __attribute__((aligned(64))); /* component k of record i: bits of an f32 */
} check_block_t;

/* 1 when some value in the block might fail; the block holds PM_CHECK_BLOCK rows (the
 * rows past the last record are padded with values that pass every check but > 0 on a
 * unit vector's y and z). */
static uint32_t block_suspect(const check_block_t *b, unsigned comps, unsigned fl)
{
    uint32_t bad = 0;
    for (unsigned k = 0; k < comps; k++) {
        const uint32_t *v = b->v[k];
        /* Not finite: exponent all ones. (x & 0x7fffffff) + 2^23 reaches bit 31 exactly
         * when x's magnitude is at least that of infinity. */
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
            bad |= (v[i] & 0x7fffffffu) + 0x00800000u;
        if (fl & PM_CH_NONNEG) /* negative: the sign set on a nonzero magnitude (-0 passes) */
            for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
                bad |= (uint32_t)(v[i] > 0x80000000u) << 31;
        if (fl & PM_CH_POSITIVE) /* not a positive normal number (zero, subnormal, sign set) */
            for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
                bad |= (uint32_t)(v[i] - 0x00800000u > PM_F32_EXP - 1 - 0x00800000u) << 31;
    }
    if ((fl & PM_CH_UNIT) && comps == 3) {
        /* |x^2 + y^2 + z^2 - 1| <= 2e-3 in double; in float the sum is within 3 ulp (2e-7)
         * of it, so a float sum inside [1 - 2e-3 + 1e-5, 1 + 2e-3 - 1e-5] surely passes.
         * Outside it, or NaN, the exact check decides. */
        float acc = 0.0f;
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++) {
            float x, y, z;
            memcpy(&x, &b->v[0][i], 4);
            memcpy(&y, &b->v[1][i], 4);
            memcpy(&z, &b->v[2][i], 4);
            float d = x * x + y * y + z * z - 1.0f;
            /* d * d <= t * t also rejects NaN; acc stays 0 while every row passes */
            acc += d * d <= (2e-3f - 1e-5f) * (2e-3f - 1e-5f) ? 0.0f : 1.0f;
        }
        bad |= (uint32_t)!(acc == 0.0f) << 31;
    } else if (fl & PM_CH_UNIT) {
        bad |= 1u << 31; /* no such channel yet: let the exact check have it */
    }
    return bad >> 31;
}

/* Copies component k of channel bytes [off, off + 4 * comps) of records [i0, i0 + m) into
 * the block's columns, padding the rest. */
static void block_load(check_block_t *b, const unsigned char *rec, size_t rs, size_t off, unsigned comps,
                       uint64_t m, unsigned fl)
{
    const unsigned char *p = rec + off;
    if (comps == 3) {
        for (uint64_t i = 0; i < m; i++, p += rs) {
            memcpy(&b->v[0][i], p, 4);
            memcpy(&b->v[1][i], p + 4, 4);
            memcpy(&b->v[2][i], p + 8, 4);
        }
    } else {
        for (uint64_t i = 0; i < m; i++, p += rs)
            for (unsigned k = 0; k < comps; k++)
                memcpy(&b->v[k][i], p + 4 * k, 4);
    }
    for (unsigned k = 0; k < comps; k++) { /* pad: 1.0 on the first component, 0 (unit) or 1.0 */
        uint32_t pad = k == 0 || !(fl & PM_CH_UNIT) ? PM_F32_ONE : 0;
        for (uint64_t i = m; i < PM_CHECK_BLOCK; i++)
            b->v[k][i] = pad;
    }
}

/* 1 when some f64 value of the channel might fail (the same tests on 64-bit patterns). */
static int f64_suspect(const unsigned char *rec, size_t rs, size_t off, unsigned comps, uint64_t n, unsigned fl)
{
    if (fl & PM_CH_UNIT)
        return 1;
    uint64_t bad = 0;
    for (uint64_t i = 0; i < n; i++)
        for (unsigned k = 0; k < comps; k++) {
            uint64_t v;
            memcpy(&v, rec + i * rs + off + 8 * k, 8);
            bad |= (v & 0x7fffffffffffffffull) + 0x0010000000000000ull;
            if (fl & PM_CH_NONNEG)
                bad |= (uint64_t)(v > 0x8000000000000000ull) << 63;
            if (fl & PM_CH_POSITIVE)
                bad |= (uint64_t)(v - 0x0010000000000000ull > 0x7fefffffffffffffull - 0x0010000000000000ull) << 63;
        }
    return (int)(bad >> 63);
}

/* The fast pass over n raw records: 1 when some value might fail. */
static int records_suspect(const pm_header_t *h, const unsigned char *rec, uint64_t n)
{
    const pm_schema_t *s = h->schema;
    const unsigned checked = PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE;
    size_t rs = h->record_size, off = 0;
    check_block_t blk;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        size_t at = off;
        off += channel_size(c);
        if (!(c->flags & checked))
            continue;
        if (c->type == PM_TYPE_F64) {
            if (f64_suspect(rec, rs, at, c->components, n, c->flags))
                return 1;
        } else if (c->type == PM_TYPE_F32) {
            if (c->components > 4)
                return 1;
            for (uint64_t i = 0; i < n; i += PM_CHECK_BLOCK) {
                uint64_t m = n - i < PM_CHECK_BLOCK ? n - i : PM_CHECK_BLOCK;
                block_load(&blk, rec + i * rs, rs, at, c->components, m, c->flags);
                if (block_suspect(&blk, c->components, c->flags))
                    return 1;
            }
        }
    }
    return 0;
}

/* The fast pass over the nv values of PM_CHECK_BLOCK rows of an f32 column already in
 * memory (SoA: the components of a row side by side): no copy, one flat loop per test (nv
 * is a constant where it is inlined, so that the loops vectorize), and for a unit vector
 * one loop over the rows. */
static inline uint32_t column_block_suspect_n(const float *v, const unsigned nv, unsigned comps, unsigned fl)
{
    uint32_t bad = 0;
    for (unsigned i = 0; i < nv; i++) {
        uint32_t b;
        memcpy(&b, &v[i], 4);
        bad |= (b & 0x7fffffffu) + 0x00800000u;
    }
    if (fl & PM_CH_NONNEG)
        for (unsigned i = 0; i < nv; i++) {
            uint32_t b;
            memcpy(&b, &v[i], 4);
            bad |= (uint32_t)(b > 0x80000000u) << 31;
        }
    if (fl & PM_CH_POSITIVE)
        for (unsigned i = 0; i < nv; i++) {
            uint32_t b;
            memcpy(&b, &v[i], 4);
            bad |= (uint32_t)(b - 0x00800000u > PM_F32_EXP - 1 - 0x00800000u) << 31;
        }
    if ((fl & PM_CH_UNIT) && comps == 3) {
        float acc = 0.0f; /* as in block_suspect */
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++) {
            float d = v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2] - 1.0f;
            acc += d * d <= (2e-3f - 1e-5f) * (2e-3f - 1e-5f) ? 0.0f : 1.0f;
        }
        bad |= (uint32_t)!(acc == 0.0f) << 31;
    } else if (fl & PM_CH_UNIT) {
        bad |= 1u << 31;
    }
    return bad >> 31;
}

static uint32_t column_block_suspect(const float *v, unsigned comps, unsigned fl)
{
    switch (comps) { /* the component counts channels have, as constants */
    case 1: return column_block_suspect_n(v, PM_CHECK_BLOCK, 1, fl);
    case 3: return column_block_suspect_n(v, 3 * PM_CHECK_BLOCK, 3, fl);
    default: return column_block_suspect_n(v, comps * PM_CHECK_BLOCK, comps, fl);
    }
}

/* The fast pass over rows [at, at + n) of a table's columns: 1 when some value might
 * fail. The same answer records_suspect gives for those rows as records, with no
 * transposition: the table already holds each channel apart. */
static int columns_suspect(const pm_table_t *t, uint64_t at, uint64_t n)
{
    const pm_schema_t *s = t->hdr.schema;
    const unsigned checked = PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE;
    float tail[PM_CHECK_BLOCK * 4] __attribute__((aligned(64)));
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(t->hdr.channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        if (!(c->flags & checked))
            continue;
        size_t cs = channel_size(c);
        const unsigned char *col = (const unsigned char *)t->col[ci] + at * cs;
        if (c->type == PM_TYPE_F64) {
            if (f64_suspect(col, cs, 0, c->components, n, c->flags))
                return 1;
        } else if (c->type == PM_TYPE_F32) {
            if (c->components > 4)
                return 1;
            unsigned comps = c->components;
            uint64_t i = 0;
            for (; i + PM_CHECK_BLOCK <= n; i += PM_CHECK_BLOCK)
                if (column_block_suspect((const float *)(const void *)(col + i * cs), comps, c->flags))
                    return 1;
            if (i < n) { /* the last rows, padded as block_load pads */
                uint64_t m = n - i;
                memcpy(tail, col + i * cs, (size_t)m * cs);
                for (uint64_t r = m; r < PM_CHECK_BLOCK; r++)
                    for (unsigned k = 0; k < comps; k++)
                        tail[r * comps + k] = k == 0 || !(c->flags & PM_CH_UNIT) ? 1.0f : 0.0f;
                if (column_block_suspect(tail, comps, c->flags))
                    return 1;
            }
        }
    }
    return 0;
}

/* The checks of n raw records starting at record index first, once a fast pass has said
 * whether some value might fail: the exact check when it might, then (as the exact check
 * does at its end) the format's record checks. */
static pm_result_t check_values_after(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                      uint64_t first, int suspect)
{
    if (suspect)
        return check_values_exact(h, path, rec, n, first);
    return h->schema->validate_records ? h->schema->validate_records(h, path, rec, n, first) : PM_OK;
}

/* Checks the values of n raw records starting at record index first (see above). */
static pm_result_t check_values(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                uint64_t first)
{
    return check_values_after(h, path, rec, n, first, records_suspect(h, rec, n));
}

/* pm_reader_read, with the value checks left to the caller when check is 0 (a table read
 * checks each chunk itself, on its columns, before it reads the next). */
static pm_result_t reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out, int check);

pm_result_t pm_reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out)
{
    return reader_read(r, records, max, got_out, 1);
}

static pm_result_t reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out, int check)
{
    *got_out = 0;
    uint64_t left = r->hdr.count - r->next;
    uint64_t want = max < left ? max : left;
    size_t rs = r->hdr.record_size;
    unsigned char *dst = records;
    while (*got_out < want) {
        uint64_t n = want - *got_out;
        if (n > PM_CHUNK_RECORDS)
            n = PM_CHUNK_RECORDS;
        unsigned char *p = dst + *got_out * rs;
        size_t got = rs ? fread(p, rs, (size_t)n, r->f) : (size_t)n;
        if (got < n) {
            if (ferror(r->f))
                return pm_error_set(PM_ERR_IO, "cannot read %s '%s': %s", reader_title(r), r->path,
                                    strerror(errno));
            return pm_error_set(PM_ERR_INPUT, "truncated %s '%s': ends in record %" PRIu64 " of %" PRIu64,
                                reader_title(r), r->path, r->next + got, r->hdr.count);
        }
        XXH3_64bits_update(r->hash, p, n * rs);
        pm_result_t res = check ? check_values(&r->hdr, r->path, p, n, r->next) : PM_OK;
        if (res != PM_OK)
            return res;
        r->next += n;
        *got_out += n;
    }
    return PM_OK;
}

pm_result_t pm_reader_finish(pm_reader_t *r, uint64_t *checksum_out)
{
    /* Records the caller skipped are still read and checked: a checksum covers all. */
    while (r->next < r->hdr.count) {
        uint64_t got;
        pm_result_t res = pm_reader_read(r, r->scratch, PM_CHUNK_RECORDS, &got);
        if (res != PM_OK)
            return res;
    }
    unsigned char tail[8];
    size_t got = fread(tail, 1, 8, r->f);
    if (got < 8) {
        if (ferror(r->f))
            return pm_error_set(PM_ERR_IO, "cannot read %s '%s': %s", reader_title(r), r->path, strerror(errno));
        return pm_error_set(PM_ERR_INPUT, "truncated %s '%s': checksum missing after %" PRIu64 " records",
                            reader_title(r), r->path, r->hdr.count);
    }
    uint64_t stored, computed = XXH3_64bits_digest(r->hash);
    memcpy(&stored, tail, 8);
    if (stored != computed)
        return pm_error_set(PM_ERR_INPUT, "checksum mismatch in %s '%s': stored %016" PRIx64 ", computed %016" PRIx64,
                            reader_title(r), r->path, stored, computed);
    int c = getc(r->f);
    if (c != EOF) {
        uint64_t extra = 1;
        while (getc(r->f) != EOF && extra < (1u << 20))
            extra++;
        return pm_error_set(PM_ERR_INPUT, "wrong count in %s '%s': COUNT=%" PRIu64 " but %s%" PRIu64
                            " bytes follow the checksum", reader_title(r), r->path, r->hdr.count,
                            extra >= (1u << 20) ? "over " : "", extra);
    }
    if (checksum_out)
        *checksum_out = computed;
    return PM_OK;
}

void pm_reader_close(pm_reader_t *r)
{
    if (!r)
        return;
    if (r->own_file && r->f)
        fclose(r->f);
    XXH3_freeState(r->hash);
    pm_header_free(&r->hdr);
    free(r->scratch);
    free(r->raw);
    free(r->path);
    free(r);
}

const char *pm_reader_header_text(const pm_reader_t *r) { return r->raw; }

/* ------------------------------------------------------------------ writer */

struct pm_writer {
    pm_header_t layout;  /* the header as a reader parses it, for checking records */
    char *name;          /* the path, for messages */
    pm_atomic_t out;
    XXH3_state_t *hash;
    uint64_t count, written;
    int err;             /* errno of the first failed write, 0 while all is well */
};

/* Frees a writer whose output is already committed, aborted or never opened. */
static void writer_free(pm_writer_t *w)
{
    pm_header_free(&w->layout);
    XXH3_freeState(w->hash);
    free(w->name);
    free(w);
}

pm_result_t pm_writer_open(const char *path, const pm_header_t *h, pm_writer_t **out)
{
    *out = NULL;
    char *text = NULL;
    size_t len = 0;
    pm_result_t res = pm_header_format(h, &text, &len);
    if (res != PM_OK)
        return res;
    /* Never write a header a reader would refuse: run the reader's own parser on it (which
     * also applies the format's rules: image size, material table, finite bounds, ...). */
    const char *shown = strcmp(path, "-") == 0 ? "stdout" : path;
    pm_reader_t probe;
    memset(&probe, 0, sizeof probe);
    probe.path = (char *)shown;
    pm_header_init(&probe.hdr, NULL);
    char *work = strdup(text);
    res = work ? parse_header(&probe, work, h->schema, 0) : pm_error_set(PM_ERR_NOMEM, "out of memory");
    free(work);
    if (res != PM_OK) {
        pm_header_free(&probe.hdr);
        free(text);
        if (res == PM_ERR_NOMEM)
            return res;
        pm_error_prefix("refusing to write");
        return PM_ERR_INTERNAL;
    }
    pm_writer_t *w = calloc(1, sizeof *w);
    if (!w) {
        pm_header_free(&probe.hdr);
        free(text);
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    }
    w->out.slot = -1;
    w->count = h->count;
    w->layout = probe.hdr; /* the header as a reader will see it, for the record checks */
    w->hash = XXH3_createState();
    w->name = strdup(shown);
    if (!w->hash || !w->name) {
        writer_free(w);
        free(text);
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    }
    XXH3_64bits_reset(w->hash);
    res = pm_atomic_open(path, &w->out);
    if (res != PM_OK) {
        writer_free(w);
        free(text);
        return res;
    }
    XXH3_64bits_update(w->hash, text, len);
    XXH3_64bits_update(w->hash, pm_bom, 4);
    if (fwrite(text, 1, len, w->out.f) != len || fwrite(pm_bom, 1, 4, w->out.f) != 4)
        w->err = errno ? errno : EIO;
    free(text);
    *out = w;
    return PM_OK;
}

/* pm_writer_write; with t, the records are rows [t_at, t_at + n) of table t, whose columns
 * the fast pass of the checks reads instead of the records. */
static pm_result_t writer_write(pm_writer_t *w, const void *records, uint64_t n, const pm_table_t *t,
                                uint64_t t_at);

pm_result_t pm_writer_write(pm_writer_t *w, const void *records, uint64_t n)
{
    return writer_write(w, records, n, NULL, 0);
}

static pm_result_t writer_write(pm_writer_t *w, const void *records, uint64_t n, const pm_table_t *t,
                                uint64_t t_at)
{
    if (w->written + n > w->count)
        return pm_error_set(PM_ERR_INTERNAL, "writer given %" PRIu64 " records, header says %" PRIu64,
                            w->written + n, w->count);
    /* Checked, hashed and written a chunk at a time, so that the three passes find the
     * chunk in the cache. */
    const unsigned char *rec = records;
    size_t rs = w->layout.record_size;
    uint64_t first = w->written;
    uint64_t i = 0;
    do { /* once when n is 0: a failed header write is still reported */
        uint64_t m = n - i < PM_CHUNK_RECORDS ? n - i : PM_CHUNK_RECORDS;
        /* The same checks a reader makes: a stage with a bug (a NaN, a negative power) fails
         * here with its own name in the message, instead of leaving a file no reader takes.
         * A refused record is never written (the records before it may be). The message is
         * the one the check of all n records gives, as if they were checked at once. */
        int suspect = t ? columns_suspect(t, t_at + i, m) : records_suspect(&w->layout, rec + i * rs, m);
        if (check_values_after(&w->layout, w->name, rec + i * rs, m, first + i, suspect) != PM_OK) {
            check_values_exact(&w->layout, w->name, rec, n, first);
            pm_error_prefix("refusing to write");
            return PM_ERR_INTERNAL;
        }
        size_t bytes = (size_t)(m * rs);
        XXH3_64bits_update(w->hash, rec + i * rs, bytes);
        if (!w->err && bytes && fwrite(rec + i * rs, 1, bytes, w->out.f) != bytes)
            w->err = errno ? errno : EIO;
        if (w->err) /* a full disk: stop now rather than after writing the rest into nothing */
            return pm_error_set(PM_ERR_IO, "cannot write '%s': %s", w->name, strerror(w->err));
        w->written += m;
        i += m;
    } while (i < n);
    return PM_OK;
}

pm_result_t pm_writer_commit(pm_writer_t *w)
{
    if (w->written != w->count) {
        pm_result_t r = pm_error_set(PM_ERR_INTERNAL, "writer got %" PRIu64 " records, header says %" PRIu64,
                                     w->written, w->count);
        pm_writer_abort(w);
        return r;
    }
    uint64_t sum = XXH3_64bits_digest(w->hash);
    unsigned char tail[8];
    memcpy(tail, &sum, 8);
    if (!w->err && fwrite(tail, 1, 8, w->out.f) != 8)
        w->err = errno ? errno : EIO;
    if (w->err) {
        pm_result_t r = pm_error_set(PM_ERR_IO, "cannot write '%s': %s", w->name, strerror(w->err));
        pm_writer_abort(w);
        return r;
    }
    pm_result_t r = pm_atomic_commit(&w->out);
    writer_free(w);
    return r;
}

void pm_writer_abort(pm_writer_t *w)
{
    if (!w)
        return;
    pm_atomic_abort(&w->out);
    writer_free(w);
}

/* ------------------------------------------------------------------ tables */

/* Resizes every present column to cap rows, keeping the first `keep` rows. */
static pm_result_t cols_resize(pm_table_t *t, uint64_t keep, uint64_t cap)
{
    const pm_schema_t *s = t->hdr.schema;
    for (unsigned i = 0; i < s->nchannels; i++) {
        if (!(t->hdr.channels & (1u << i)))
            continue;
        size_t cs = channel_size(&s->channels[i]), bytes = (size_t)cap * cs;
        void *p = pm_alloc_aligned(bytes + 64); /* + 64: SIMD loads may run past the last row */
        if (!p)
            return pm_error_set(PM_ERR_NOMEM, "out of memory for %" PRIu64 " records of %s", cap, s->title);
        if (t->col[i] && keep)
            memcpy(p, t->col[i], (size_t)keep * cs);
        pm_free_aligned(t->col[i]);
        t->col[i] = p;
    }
    return PM_OK;
}

pm_result_t pm_table_alloc(pm_table_t *t, const pm_schema_t *s, uint32_t channels, uint64_t count)
{
    memset(t, 0, sizeof *t);
    pm_header_init(&t->hdr, s);
    t->hdr.channels = channels;
    t->hdr.count = count;
    t->hdr.record_size = pm_schema_record_size(s, channels);
    t->count = count;
    pm_result_t r = cols_resize(t, 0, count);
    if (r != PM_OK) {
        pm_table_free(t);
        return r;
    }
    for (unsigned i = 0; i < s->nchannels; i++)
        if (t->col[i])
            memset(t->col[i], 0, (size_t)count * channel_size(&s->channels[i]));
    return PM_OK;
}

void pm_table_free(pm_table_t *t)
{
    for (unsigned i = 0; i < PM_MAX_CHANNELS; i++)
        pm_free_aligned(t->col[i]);
    pm_header_free(&t->hdr);
    memset(t, 0, sizeof *t);
}

/* Copies n elements of cs bytes between strided layouts. The sizes channels have are
 * spelled out so that each memcpy is a fixed-size move, not a call into libc (which
 * dominated read time when every 12-byte element went through memmove). */
static void copy_strided(unsigned char *dst, size_t dstride, const unsigned char *src, size_t sstride, uint64_t n,
                         size_t cs)
{
#define PM_COPY(SIZE)                                                                                        \
    for (uint64_t i = 0; i < n; i++)                                                                         \
        memcpy(dst + i * dstride, src + i * sstride, SIZE);                                                  \
    return;
    switch (cs) {
    case 2: PM_COPY(2)
    case 4: PM_COPY(4)
    case 8: PM_COPY(8)
    case 12: PM_COPY(12)
    case 24: PM_COPY(24)
    default: PM_COPY(cs)
    }
#undef PM_COPY
}

/* Moves n AoS records into the table's columns starting at row `at`. */
static void scatter(pm_table_t *t, const unsigned char *rec, uint64_t n, uint64_t at)
{
    const pm_schema_t *s = t->hdr.schema;
    size_t rs = t->hdr.record_size, off = 0;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(t->hdr.channels & (1u << ci)))
            continue;
        size_t cs = channel_size(&s->channels[ci]);
        copy_strided((unsigned char *)t->col[ci] + at * cs, cs, rec + off, rs, n, cs);
        off += cs;
    }
}

/* Moves n rows starting at `at` out of the columns into AoS records. */
static void gather(const pm_table_t *t, unsigned char *rec, uint64_t n, uint64_t at)
{
    const pm_schema_t *s = t->hdr.schema;
    size_t rs = t->hdr.record_size, off = 0;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(t->hdr.channels & (1u << ci)))
            continue;
        size_t cs = channel_size(&s->channels[ci]);
        copy_strided(rec + off, rs, (const unsigned char *)t->col[ci] + at * cs, cs, n, cs);
        off += cs;
    }
}

static pm_result_t header_copy(pm_header_t *dst, const pm_header_t *src)
{
    const pm_schema_t *s = dst->schema;
    uint32_t ch = dst->channels;
    uint64_t count = dst->count;
    uint32_t rs = dst->record_size;
    pm_header_free(dst);
    pm_header_init(dst, s);
    dst->channels = ch;
    dst->count = count;
    dst->record_size = rs;
    dst->major = src->major;
    dst->minor = src->minor;
    memcpy(dst->bounds, src->bounds, sizeof dst->bounds);
    /* A faithful copy of the file's header: every COMMAND and every key, INPUT included. */
    pm_result_t r = PM_OK;
    for (size_t i = 0; i < src->ncommands && r == PM_OK; i++) {
        char *c = strdup(src->commands[i]);
        r = c ? command_append(dst, c) : pm_error_set(PM_ERR_NOMEM, "out of memory copying a header");
    }
    for (size_t i = 0; i < src->nkeys && r == PM_OK; i++)
        r = pm_header_add(dst, src->keys[i].key, "%s", src->keys[i].value);
    return r;
}

void pm_table_record(const pm_table_t *t, uint64_t i, void *record_out) { gather(t, record_out, 1, i); }

pm_result_t pm_table_read_from(pm_reader_t *r, uint64_t begin, uint64_t end, pm_table_t *out)
{
    memset(out, 0, sizeof *out);
    pm_result_t res = PM_OK;
    const pm_header_t *h = pm_reader_header(r);
    if (end > h->count)
        end = h->count;
    if (begin > end)
        begin = end;
    uint64_t keep = end - begin;
    /* A regular file's size has vouched for COUNT; a pipe's COUNT has not, so its
     * columns grow as records actually arrive instead of trusting it up front. */
    uint64_t cap = r->file_size || keep < (1u << 16) ? keep : (1u << 16);
    pm_header_init(&out->hdr, h->schema);
    out->hdr.channels = h->channels;
    out->hdr.record_size = h->record_size;
    out->hdr.count = out->count = keep;
    res = cols_resize(out, 0, cap);
    if (res == PM_OK)
        res = header_copy(&out->hdr, h);
    uint64_t at = 0, pos = 0;
    while (res == PM_OK && pos < end) {
        uint64_t got;
        res = reader_read(r, r->scratch, PM_CHUNK_RECORDS, &got, 0);
        if (res != PM_OK || got == 0)
            break;
        /* The overlap of [pos, pos + got) with [begin, end). */
        uint64_t lo = pos > begin ? pos : begin, hi = pos + got < end ? pos + got : end;
        if (lo < hi && at + (hi - lo) > cap) {
            uint64_t grow = 2 * cap > at + (hi - lo) ? 2 * cap : at + (hi - lo);
            cap = grow < keep ? grow : keep;
            res = cols_resize(out, at, cap);
            if (res != PM_OK)
                break;
        }
        if (lo < hi)
            scatter(out, r->scratch + (lo - pos) * h->record_size, hi - lo, at);
        /* The chunk's checks, before the next chunk is read: on the columns when the whole
         * chunk went there, else on the records; messages from the records either way. */
        int suspect = lo == pos && hi == pos + got ? columns_suspect(out, at, got)
                                                   : records_suspect(h, r->scratch, got);
        res = check_values_after(h, r->path, r->scratch, got, pos, suspect);
        if (res != PM_OK)
            break;
        if (lo < hi)
            at += hi - lo;
        pos += got;
    }
    if (res == PM_OK)
        res = pm_reader_finish(r, &out->checksum);
    if (res == PM_OK && keep == h->count && h->schema->validate_table)
        res = h->schema->validate_table(out, r->path);
    if (res != PM_OK)
        pm_table_free(out);
    return res;
}

pm_result_t pm_table_read_range(const char *path, const pm_schema_t *schema, uint32_t need, uint64_t begin,
                                uint64_t end, pm_table_t *out)
{
    memset(out, 0, sizeof *out);
    pm_reader_t *r;
    pm_result_t res = pm_reader_open(path, schema, need, &r);
    if (res != PM_OK)
        return res;
    res = pm_table_read_from(r, begin, end, out);
    pm_reader_close(r);
    return res;
}

pm_result_t pm_table_read(const char *path, const pm_schema_t *schema, uint32_t need, pm_table_t *out)
{
    return pm_table_read_range(path, schema, need, 0, UINT64_MAX, out);
}

pm_result_t pm_table_write(const pm_table_t *t, const char *path)
{
    if (t->hdr.count != t->count)
        return pm_error_set(PM_ERR_INTERNAL, "table holds %" PRIu64 " records, header says %" PRIu64, t->count,
                            t->hdr.count);
    /* Relations across records (tree shape, pixel indices), as a reader checks them. */
    const pm_schema_t *s = t->hdr.schema;
    pm_result_t vr = s->validate_table ? s->validate_table(t, strcmp(path, "-") == 0 ? "stdout" : path) : PM_OK;
    if (vr != PM_OK) {
        pm_error_prefix("refusing to write");
        return PM_ERR_INTERNAL;
    }
    pm_writer_t *w;
    pm_result_t res = pm_writer_open(path, &t->hdr, &w);
    if (res != PM_OK)
        return res;
    size_t rs = t->hdr.record_size;
    unsigned char *buf = malloc((size_t)PM_CHUNK_RECORDS * (rs ? rs : 1));
    if (!buf) {
        pm_writer_abort(w);
        return pm_error_set(PM_ERR_NOMEM, "out of memory writing '%s'", path);
    }
    for (uint64_t at = 0; at < t->count && res == PM_OK; at += PM_CHUNK_RECORDS) {
        uint64_t n = t->count - at < PM_CHUNK_RECORDS ? t->count - at : PM_CHUNK_RECORDS;
        gather(t, buf, n, at);
        res = writer_write(w, buf, n, t, at);
    }
    free(buf);
    if (res != PM_OK) {
        pm_writer_abort(w);
        return res;
    }
    return pm_writer_commit(w);
}
