/* header.c: the schema helpers and the header model of the pmtk container: record sizes
 * and offsets of a channel mask, the KEY=VALUE store with its reserved keys, COMMAND lines
 * (provenance) and how a stage takes them over from its inputs. The header as text is in
 * header_text.c; docs/formats.md is the byte-level spec. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/pmfile_impl.h"

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

size_t pmfile_channel_size(const pm_channel_t *c) { return pm_type_size(c->type) * c->components; }

uint32_t pm_schema_record_size(const pm_schema_t *s, uint32_t mask)
{
    uint32_t n = 0;
    for (unsigned i = 0; i < s->nchannels; i++)
        if (mask & (1u << i))
            n += (uint32_t)pmfile_channel_size(&s->channels[i]);
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

int pmfile_key_char_ok(int c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '.' ||
           c == '-';
}

int pmfile_key_ok(const char *k)
{
    if (!*k)
        return 0;
    for (; *k; k++)
        if (!pmfile_key_char_ok((unsigned char)*k))
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
    static const char *const reserved[] = {"FORMAT",   "VERSION",      "BYTE_ORDER", "COUNT",    "RECORD_SIZE",
                                           "CHANNELS", "CHANNEL_MASK", "BOUNDS",     "SOFTWARE", "COMMAND",
                                           NULL};
    for (const char *const *r = reserved; *r; r++)
        if (strcmp(*r, k) == 0)
            return 1;
    return 0;
}

pm_result_t pmfile_kv_append(pm_header_t *h, const char *key, char *value_owned)
{
    if (key_reserved(key)) {
        free(value_owned);
        return pm_error_set(PM_ERR_INTERNAL, "header key '%s' is the container's own, not a stage's", key);
    }
    if (!pmfile_key_ok(key)) {
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
    return pmfile_kv_append(h, key, v);
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
    return pmfile_kv_append(h, key, v);
}

const char *pm_header_get(const pm_header_t *h, const char *key)
{
    for (size_t i = 0; i < h->nkeys; i++)
        if (strcmp(h->keys[i].key, key) == 0)
            return h->keys[i].value;
    return NULL;
}

const char *pmfile_title(const pm_header_t *h) { return h->schema ? h->schema->title : "pmtk file"; }

/* Header numbers have one spelling: decimal digits only (no sign, exponent or space), so
 * that two files with equal content have equal bytes and a reader cannot be fooled. */
int pmfile_parse_decimal(const char *v, uint64_t *out)
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
        return pm_error_set(PM_ERR_INPUT, "%s '%s' lacks header key '%s'", pmfile_title(h), path, key);
    if (!pmfile_parse_decimal(v, out))
        return pm_error_set(PM_ERR_INPUT, "%s '%s': header key %s='%s' is not a decimal integer", pmfile_title(h), path,
                            key, v);
    return PM_OK;
}

pm_result_t pmfile_command_append(pm_header_t *h, char *cmd_owned)
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
        if (!(pmfile_key_char_ok((unsigned char)*s) || strchr("/:,=+@%^", *s)))
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
    return pmfile_command_append(h, s);
}

/* The length of a SCENE value's "NAME xxh3:HASH", before its parts. */
static size_t scene_head(const char *v)
{
    const char *sp = strchr(v, ' ');
    if (!sp)
        return strlen(v);
    const char *sp2 = strchr(sp + 1, ' ');
    return sp2 ? (size_t)(sp2 - v) : strlen(v);
}

int pm_scene_key_same_scene(const char *a, const char *b)
{
    size_t n = scene_head(a);
    return n == scene_head(b) && strncmp(a, b, n) == 0;
}

/* The word of SCENE value v that starts with label ("photons:xxh3:..."), into out (64
 * bytes); out untouched when v has none. */
static void scene_part(const char *v, const char *label, char out[64])
{
    size_t n = strlen(label);
    for (const char *w = v + scene_head(v); *w;) {
        while (*w == ' ')
            w++;
        size_t len = strcspn(w, " ");
        if (len > n && len < 64 && strncmp(w, label, n) == 0) {
            memcpy(out, w, len);
            out[len] = 0;
            return;
        }
        w += len;
    }
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
        pm_result_t r = pmfile_command_append(h, c);
        if (r != PM_OK)
            return r;
    }
    const char *scene = pm_header_get(src, "SCENE"), *mine = pm_header_get(h, "SCENE");
    if (scene && !mine)
        return pm_header_set(h, "SCENE", "%s", scene);
    if (scene && pm_scene_key_same_scene(mine, scene)) {
        /* Parts of the same scene: the result names each part either names, in the order
         * photons then view, so that the gather's output and the direct light agree. */
        char photons[64] = "", view[64] = "";
        scene_part(mine, "photons:", photons);
        scene_part(mine, "view:", view);
        if (!photons[0])
            scene_part(scene, "photons:", photons);
        if (!view[0])
            scene_part(scene, "view:", view);
        if (photons[0] || view[0])
            return pm_header_set(h, "SCENE", "%.*s%s%s%s%s", (int)scene_head(mine), mine, photons[0] ? " " : "",
                                 photons, view[0] ? " " : "", view);
    }
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
