/* table.c: whole files in memory as pm_table_t, one aligned array per present channel
 * (structure of arrays). Reads a file or a range of its records into the columns, checking
 * every chunk on its columns before the next is read; writes a table back through the
 * streaming writer; moves records between the file's layout and the columns. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "base/memory.h"
#include "formats/pmfile_impl.h"

/* Resizes every present column to cap rows, keeping the first `keep` rows. */
static pm_result_t cols_resize(pm_table_t *t, uint64_t keep, uint64_t cap)
{
    const pm_schema_t *s = t->hdr.schema;
    for (unsigned i = 0; i < s->nchannels; i++) {
        if (!(t->hdr.channels & (1u << i)))
            continue;
        size_t cs = pmfile_channel_size(&s->channels[i]), bytes = (size_t)cap * cs;
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
            memset(t->col[i], 0, (size_t)count * pmfile_channel_size(&s->channels[i]));
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
#define PM_COPY(SIZE)                                                                                                  \
    for (uint64_t i = 0; i < n; i++)                                                                                   \
        memcpy(dst + i * dstride, src + i * sstride, SIZE);                                                            \
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
        size_t cs = pmfile_channel_size(&s->channels[ci]);
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
        size_t cs = pmfile_channel_size(&s->channels[ci]);
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
        r = c ? pmfile_command_append(dst, c) : pm_error_set(PM_ERR_NOMEM, "out of memory copying a header");
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
        res = pmfile_reader_read(r, r->scratch, PM_CHUNK_RECORDS, &got, 0);
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
        int suspect = lo == pos && hi == pos + got ? pmfile_columns_suspect(out, at, got)
                                                   : pmfile_records_suspect(h, r->scratch, got);
        res = pmfile_check_after(h, r->path, r->scratch, got, pos, suspect);
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

pm_result_t pm_table_chunks_open(pm_reader_t *r, uint64_t cap, pm_table_t *out)
{
    memset(out, 0, sizeof *out);
    const pm_header_t *h = pm_reader_header(r);
    pm_header_init(&out->hdr, h->schema);
    out->hdr.channels = h->channels;
    out->hdr.record_size = h->record_size;
    out->hdr.count = h->count;
    out->count = 0;
    pm_result_t res = cols_resize(out, 0, cap ? cap : 1);
    if (res == PM_OK)
        res = header_copy(&out->hdr, h);
    if (res != PM_OK)
        pm_table_free(out);
    return res;
}

pm_result_t pm_table_chunks_read(pm_reader_t *r, pm_table_t *t, uint64_t cap, uint64_t *first_out)
{
    const pm_header_t *h = pm_reader_header(r);
    uint64_t at = 0;
    *first_out = r->next;
    t->count = 0;
    while (at < cap) {
        uint64_t want = cap - at < PM_CHUNK_RECORDS ? cap - at : PM_CHUNK_RECORDS, got, first = r->next;
        pm_result_t res = pmfile_reader_read(r, r->scratch, want, &got, 0);
        if (res != PM_OK)
            return res;
        if (got == 0)
            break;
        scatter(t, r->scratch, got, at);
        res = pmfile_check_after(h, r->path, r->scratch, got, first, pmfile_columns_suspect(t, at, got));
        if (res != PM_OK)
            return res;
        at += got;
    }
    t->count = at;
    return at ? PM_OK : pm_reader_finish(r, &t->checksum);
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
        res = pmfile_writer_write(w, buf, n, t, at);
    }
    free(buf);
    if (res != PM_OK) {
        pm_writer_abort(w);
        return res;
    }
    return pm_writer_commit(w);
}
