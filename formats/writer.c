/* writer.c: the streaming writer of the pmtk container. Formats the header and runs the
 * reader's parser on it, writes through a temporary file renamed into place on commit
 * (base/atomic.h), checks every record as a reader would before it is written, hashes all
 * of it and ends the file with the XXH3 checksum. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/atomic.h"
#include "formats/pmfile_impl.h"

struct pm_writer {
    pm_header_t layout; /* the header as a reader parses it, for checking records */
    char *name;         /* the path, for messages */
    pm_atomic_t out;
    XXH3_state_t *hash;
    uint64_t count, written;
    int err; /* errno of the first failed write, 0 while all is well */
};

/* Frees a writer whose output is already committed, aborted or never opened. */
static void writer_free(pm_writer_t *w)
{
    pm_header_free(&w->layout);
    XXH3_freeState(w->hash);
    free(w->name);
    free(w);
}

pm_result_t pm_writer_check_stream(const char *option, const char *path)
{
    struct stat sb;
    if (!path || !strcmp(path, "-") || !strncmp(path, "/dev/fd/", 8) || !strcmp(path, "/dev/stdout") ||
        (stat(path, &sb) == 0 && !S_ISREG(sb.st_mode) && !S_ISDIR(sb.st_mode)))
        return PM_OK;
    return pm_error_set(PM_ERR_USAGE,
                        "a stream of documents (several scenes or passes) goes to a pipe: %s must be - (stdout), a "
                        "pipe or /dev/fd/N, not the file '%s'",
                        option, path);
}

pm_result_t pm_writer_open(const char *path, const pm_header_t *h, pm_writer_t **out)
{
    *out = NULL;
    /* Binary records on a terminal are garbage on the screen and can set the terminal's
     * modes: refuse, as gzip does, before a byte is written. */
    if (strcmp(path, "-") == 0 && isatty(STDOUT_FILENO))
        return pm_error_set(PM_ERR_USAGE,
                            "refusing to write a binary %s file to a terminal (stdout): give -o FILE or pipe it",
                            h->schema ? h->schema->name : "pmtk");
    char *text = NULL;
    size_t len = 0;
    pm_result_t res = pm_header_format(h, &text, &len);
    if (res != PM_OK)
        return res;
    /* Never write a header a reader would refuse: run the reader's own parser on it (which
     * also applies the format's rules: image size, material table, finite bounds, ...). */
    const char *shown = strcmp(path, "-") == 0 ? "stdout" : path;
    pm_header_t probe;
    pm_header_init(&probe, NULL);
    char *work = strdup(text);
    res = work ? pmfile_header_parse(&probe, shown, work, h->schema, 0) : pm_error_set(PM_ERR_NOMEM, "out of memory");
    free(work);
    if (res != PM_OK) {
        pm_header_free(&probe);
        free(text);
        if (res == PM_ERR_NOMEM)
            return res;
        pm_error_prefix("refusing to write");
        return PM_ERR_INTERNAL;
    }
    pm_writer_t *w = calloc(1, sizeof *w);
    if (!w) {
        pm_header_free(&probe);
        free(text);
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    }
    w->out.slot = -1;
    w->count = h->count;
    w->layout = probe; /* the header as a reader will see it, for the record checks */
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
    pmfile_widen_pipe(fileno(w->out.f));
    XXH3_64bits_update(w->hash, text, len);
    XXH3_64bits_update(w->hash, pmfile_bom, 4);
    if (fwrite(text, 1, len, w->out.f) != len || fwrite(pmfile_bom, 1, 4, w->out.f) != 4)
        w->err = errno ? errno : EIO;
    free(text);
    *out = w;
    return PM_OK;
}

pm_result_t pm_writer_write(pm_writer_t *w, const void *records, uint64_t n)
{
    return pmfile_writer_write(w, records, n, NULL, 0);
}

pm_result_t pm_writer_write_checked(pm_writer_t *w, const void *records, uint64_t n)
{
    if (w->written + n > w->count)
        return pm_error_set(PM_ERR_INTERNAL, "writer given %" PRIu64 " records, header says %" PRIu64, w->written + n,
                            w->count);
    size_t bytes = (size_t)(n * w->layout.record_size);
    XXH3_64bits_update(w->hash, records, bytes);
    if (!w->err && bytes && fwrite(records, 1, bytes, w->out.f) != bytes)
        w->err = errno ? errno : EIO;
    if (w->err)
        return pm_error_set(pm_result_of_errno(w->err), "cannot write '%s': %s", w->name, strerror(w->err));
    w->written += n;
    return PM_OK;
}

pm_result_t pmfile_writer_write(pm_writer_t *w, const void *records, uint64_t n, const pm_table_t *t, uint64_t t_at)
{
    if (w->written + n > w->count)
        return pm_error_set(PM_ERR_INTERNAL, "writer given %" PRIu64 " records, header says %" PRIu64, w->written + n,
                            w->count);
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
        int suspect = t ? pmfile_columns_suspect(t, t_at + i, m) : pmfile_records_suspect(&w->layout, rec + i * rs, m);
        if (pmfile_check_after(&w->layout, w->name, rec + i * rs, m, first + i, suspect) != PM_OK) {
            pmfile_check_exact(&w->layout, w->name, rec, n, first);
            pm_error_prefix("refusing to write");
            return PM_ERR_INTERNAL;
        }
        size_t bytes = (size_t)(m * rs);
        XXH3_64bits_update(w->hash, rec + i * rs, bytes);
        if (!w->err && bytes && fwrite(rec + i * rs, 1, bytes, w->out.f) != bytes)
            w->err = errno ? errno : EIO;
        if (w->err) /* a full disk: stop now rather than after writing the rest into nothing */
            return pm_error_set(pm_result_of_errno(w->err), "cannot write '%s': %s", w->name, strerror(w->err));
        w->written += m;
        i += m;
    } while (i < n);
    return PM_OK;
}

pm_result_t pm_writer_commit(pm_writer_t *w)
{
    if (w->written != w->count) {
        pm_result_t r =
            pm_error_set(PM_ERR_INTERNAL, "writer got %" PRIu64 " records, header says %" PRIu64, w->written, w->count);
        pm_writer_abort(w);
        return r;
    }
    uint64_t sum = XXH3_64bits_digest(w->hash);
    unsigned char tail[8];
    memcpy(tail, &sum, 8);
    if (!w->err && fwrite(tail, 1, 8, w->out.f) != 8)
        w->err = errno ? errno : EIO;
    if (w->err) {
        pm_result_t r = pm_error_set(pm_result_of_errno(w->err), "cannot write '%s': %s", w->name, strerror(w->err));
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
