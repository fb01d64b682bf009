/* reader.c: the streaming reader of the pmtk container. Opens a file or stream, reads the
 * header text and its byte-order marker, checks the size of a regular file against COUNT
 * before any record is read, then hands out records a chunk at a time, each chunk hashed
 * and its values checked (check.c), and at the end compares the XXH3 checksum and refuses
 * anything after it. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "formats/pmfile_impl.h"

const unsigned char pmfile_bom[4] = {0x04, 0x03, 0x02, 0x01};

static const char *reader_title(const pm_reader_t *r) { return pmfile_title(&r->hdr); }

#ifndef F_SETPIPE_SZ
#define F_SETPIPE_SZ 1031 /* Linux's fcntl command; glibc names it only under _GNU_SOURCE */
#endif
#define PM_PIPE_BYTES ((int)4 << 20) /* bytes asked for; Linux's default cap for a user is 1 MiB */

void pmfile_widen_pipe(int fd)
{
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISFIFO(st.st_mode))
        return;
    /* The largest size allowed: halve the request until the system takes it (EPERM past its
     * cap); the 64 KiB default stays when nothing larger is allowed. */
    for (int bytes = PM_PIPE_BYTES; bytes > (64 << 10); bytes /= 2)
        if (fcntl(fd, F_SETPIPE_SZ, bytes) >= 0)
            return;
}

/* Reads header text up to and including the blank line that ends it. */
static pm_result_t read_header_text(pm_reader_t *r, char **text_out, size_t *len_out)
{
    unsigned char magic[sizeof PM_MAGIC]; /* "#?PMTK\n" */
    size_t got = fread(magic, 1, sizeof magic, r->f);
    /* A short read is an empty or foreign file only when the stream says so: a directory,
     * an I/O error or a closed descriptor also read nothing, and errno says which. */
    if (got < sizeof magic && ferror(r->f))
        return pm_error_set(pm_result_of_errno(errno), "cannot read '%s': %s", r->path, strerror(errno));
    if (got < sizeof magic || memcmp(magic, PM_MAGIC "\n", sizeof magic) != 0) {
        if (got == 0)
            return pm_error_set(PM_ERR_INPUT, "empty input '%s': expected a pmtk file", r->path);
        char shown[64];
        pmfile_show_bytes(magic, got, shown, sizeof shown);
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
            if (ferror(r->f))
                return pm_error_set(pm_result_of_errno(errno), "cannot read the header of '%s': %s", r->path,
                                    strerror(errno));
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
                return pm_error_set(PM_ERR_INPUT, "header line of '%s' exceeds %u bytes", r->path, PM_HEADER_LINE_MAX);
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

static pm_result_t reader_start(pm_reader_t *r, const pm_schema_t *schema, uint32_t need, pm_reader_t **out);

pm_result_t pm_reader_open(const char *path, const pm_schema_t *schema, uint32_t need, pm_reader_t **out)
{
    *out = NULL;
    if (strcmp(path, "-") == 0)
        return pm_reader_open_stream(stdin, "stdin", schema, need, out);
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        return pm_error_set(pm_result_of_errno(e), "cannot open '%s': %s", path, strerror(e));
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

pm_result_t pm_stream_open(const char *path, FILE **out)
{
    *out = strcmp(path, "-") ? fopen(path, "rb") : stdin;
    return *out ? PM_OK : pm_error_set(pm_result_of_errno(errno), "cannot open '%s': %s", path, strerror(errno));
}

void pm_stream_close(FILE *f)
{
    if (f && f != stdin)
        fclose(f);
}

const char *pm_stream_frame_name(char *buf, size_t size, const char *path, uint64_t frame)
{
    snprintf(buf, size, "%s, frame %" PRIu64, strcmp(path, "-") ? path : "stdin", frame);
    return buf;
}

pm_result_t pm_reader_open_next(FILE *f, const char *name, const pm_schema_t *schema, uint32_t need, pm_reader_t **out)
{
    *out = NULL;
    int c = getc(f);
    if (c == EOF) {
        if (ferror(f))
            return pm_error_set(pm_result_of_errno(errno), "cannot read '%s': %s", name, strerror(errno));
        return PM_OK; /* the end of the stream, between documents */
    }
    ungetc(c, f);
    pm_reader_t *r = calloc(1, sizeof *r);
    if (!r)
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", name);
    r->f = f;
    r->in_stream = 1;
    r->path = strdup(name);
    r->hash = XXH3_createState();
    if (!r->path || !r->hash) {
        r->f = NULL;
        pm_reader_close(r);
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", name);
    }
    pm_header_init(&r->hdr, schema);
    XXH3_64bits_reset(r->hash);
    return reader_start(r, schema, need, out);
}

pm_result_t pm_reader_take_next(FILE *f, const char *name, const pm_schema_t *schema, unsigned char **buf_out,
                                size_t *len_out)
{
    *buf_out = NULL;
    *len_out = 0;
    pm_reader_t *r;
    pm_result_t res = pm_reader_open_next(f, name, schema, 0, &r);
    if (res != PM_OK || !r)
        return res;
    size_t head = strlen(r->raw), payload = (size_t)(r->hdr.count * r->hdr.record_size);
    size_t len = head + 4 + payload + 8;
    unsigned char *b = malloc(len);
    if (!b) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory for %s '%s' (%zu bytes)", reader_title(r), name, len);
    } else {
        memcpy(b, r->raw, head);
        memcpy(b + head, pmfile_bom, 4);
        size_t got = fread(b + head + 4, 1, payload + 8, f);
        if (got < payload + 8) {
            if (ferror(f))
                res = pm_error_set(pm_result_of_errno(errno), "cannot read %s '%s': %s", reader_title(r), name,
                                   strerror(errno));
            else if (got < payload)
                res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': ends in record %" PRIu64 " of %" PRIu64,
                                   reader_title(r), name, r->hdr.record_size ? got / r->hdr.record_size : 0,
                                   r->hdr.count);
            else
                res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': checksum missing after %" PRIu64 " records",
                                   reader_title(r), name, r->hdr.count);
        }
    }
    pm_reader_close(r);
    if (res != PM_OK) {
        free(b);
        return res;
    }
    *buf_out = b;
    *len_out = len;
    return PM_OK;
}

/* Reads and checks the header of r's stream; on failure closes r (not the stream). */
static pm_result_t reader_start(pm_reader_t *r, const pm_schema_t *schema, uint32_t need, pm_reader_t **out)
{
    const char *path = r->path;
    struct stat st;
    /* A document of a stream shares its file with others: the file's size says nothing of it. */
    if (!r->in_stream && fstat(fileno(r->f), &st) == 0 && S_ISREG(st.st_mode))
        r->file_size = (uint64_t)st.st_size;
    else if (fstat(fileno(r->f), &st) == 0 && S_ISDIR(st.st_mode)) {
        pm_result_t res = pm_error_set(PM_ERR_INPUT, "'%s' is a directory, not a pmtk file", path);
        pm_reader_close(r);
        return res;
    }

    if (!r->file_size)
        pmfile_widen_pipe(fileno(r->f));
    char *text = NULL;
    size_t len = 0;
    pm_result_t res = read_header_text(r, &text, &len);
    if (res == PM_OK) {
        XXH3_64bits_update(r->hash, text, len);
        char *work = strdup(text); /* the parser cuts its text into lines */
        res = work ? pmfile_header_parse(&r->hdr, r->path, work, schema, need)
                   : pm_error_set(PM_ERR_NOMEM, "out of memory reading '%s'", r->path);
        free(work);
    }
    r->raw = text;
    if (res == PM_OK) {
        unsigned char bom[4];
        size_t got = fread(bom, 1, 4, r->f);
        if (got < 4 && ferror(r->f))
            res = pm_error_set(pm_result_of_errno(errno), "cannot read %s '%s': %s", reader_title(r), r->path,
                               strerror(errno));
        else if (got < 4)
            res = pm_error_set(PM_ERR_INPUT, "truncated %s '%s': no byte-order marker after the header",
                               reader_title(r), r->path);
        else if (bom[0] == 0x01 && bom[1] == 0x02 && bom[2] == 0x03 && bom[3] == 0x04)
            res = pm_error_set(PM_ERR_INPUT, "%s '%s' is big-endian; pmtk reads little-endian files", reader_title(r),
                               r->path);
        else if (memcmp(bom, pmfile_bom, 4) != 0)
            res = pm_error_set(PM_ERR_INPUT, "%s '%s': bad byte-order marker %02x %02x %02x %02x", reader_title(r),
                               r->path, bom[0], bom[1], bom[2], bom[3]);
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

pm_result_t pm_reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out)
{
    return pmfile_reader_read(r, records, max, got_out, 1);
}

pm_result_t pmfile_reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out, int check)
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
                return pm_error_set(pm_result_of_errno(errno), "cannot read %s '%s': %s", reader_title(r), r->path,
                                    strerror(errno));
            return pm_error_set(PM_ERR_INPUT, "truncated %s '%s': ends in record %" PRIu64 " of %" PRIu64,
                                reader_title(r), r->path, r->next + got, r->hdr.count);
        }
        XXH3_64bits_update(r->hash, p, n * rs);
        pm_result_t res = check ? pmfile_check_records(&r->hdr, r->path, p, n, r->next) : PM_OK;
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
            return pm_error_set(pm_result_of_errno(errno), "cannot read %s '%s': %s", reader_title(r), r->path,
                                strerror(errno));
        return pm_error_set(PM_ERR_INPUT, "truncated %s '%s': checksum missing after %" PRIu64 " records",
                            reader_title(r), r->path, r->hdr.count);
    }
    uint64_t stored, computed = XXH3_64bits_digest(r->hash);
    memcpy(&stored, tail, 8);
    if (stored != computed)
        return pm_error_set(PM_ERR_INPUT, "checksum mismatch in %s '%s': stored %016" PRIx64 ", computed %016" PRIx64,
                            reader_title(r), r->path, stored, computed);
    int c = r->in_stream ? EOF : getc(r->f);
    if (c != EOF) {
        uint64_t extra = 1;
        while (getc(r->f) != EOF && extra < (1u << 20))
            extra++;
        return pm_error_set(PM_ERR_INPUT,
                            "wrong count in %s '%s': COUNT=%" PRIu64 " but %s%" PRIu64 " bytes follow the checksum",
                            reader_title(r), r->path, r->hdr.count, extra >= (1u << 20) ? "over " : "", extra);
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
