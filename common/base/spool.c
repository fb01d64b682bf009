/* spool.c: records held in memory, then in an unlinked temporary file, until they are
 * replayed (see spool.h). trace-gather-points spools its queries through it because the
 * queries file's header must state the count before the first record. */
#include "base/spool.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/memory.h"

/* Records per memory chunk: 128 Ki records make a chunk of at least 4 MiB for records of 32
 * bytes or more, big enough for huge pages (base/memory.h). */
#define CHUNK_RECORDS ((size_t)1 << 17)
/* Records per read when a spill file is replayed. */
#define REPLAY_RECORDS ((uint64_t)1 << 16)

void pm_spool_init(pm_spool_t *sp, size_t record_size, size_t mem_max, const char *dir)
{
    memset(sp, 0, sizeof *sp);
    sp->record_size = record_size ? record_size : 1;
    sp->chunk_bytes = sp->record_size * CHUNK_RECORDS;
    sp->mem_max = mem_max;
    snprintf(sp->dir, sizeof sp->dir, "%s", dir && *dir ? dir : ".");
}

/* Moves what memory holds into a new unlinked file, which then takes every later record. */
static pm_result_t spill(pm_spool_t *sp)
{
    /* O_TMPFILE: a file with no name, so nothing is left behind even on SIGKILL. Where dir
     * cannot have one (a file system without O_TMPFILE, a folder gone), tmpfile() puts it in
     * the system's temporary folder instead. */
    int fd = open(sp->dir, O_TMPFILE | O_RDWR, 0600);
    if (fd >= 0) {
        sp->f = fdopen(fd, "w+b");
        if (!sp->f)
            close(fd);
    }
    if (!sp->f)
        sp->f = tmpfile();
    if (!sp->f)
        return pm_error_set(pm_result_of_errno(errno), "cannot create a spool file in '%s': %s", sp->dir,
                            strerror(errno));
    for (size_t i = 0; i < sp->nchunks; i++) {
        size_t n = i + 1 < sp->nchunks ? sp->chunk_bytes : sp->fill;
        if (n && fwrite(sp->chunk[i], 1, n, sp->f) != n)
            return pm_error_set(pm_result_of_errno(errno), "cannot write the spool file in '%s': %s", sp->dir,
                                strerror(errno));
        pm_free_aligned(sp->chunk[i]);
        sp->chunk[i] = NULL;
    }
    sp->nchunks = sp->fill = sp->held = 0;
    return PM_OK;
}

pm_result_t pm_spool_add(pm_spool_t *sp, const void *records, uint64_t count)
{
    const unsigned char *src = records;
    size_t bytes = (size_t)count * sp->record_size;
    if (!sp->f && sp->held + bytes > sp->mem_max) {
        pm_result_t r = spill(sp);
        if (r != PM_OK)
            return r;
    }
    if (sp->f) {
        if (bytes && fwrite(src, 1, bytes, sp->f) != bytes)
            return pm_error_set(pm_result_of_errno(errno), "cannot write the spool file in '%s': %s", sp->dir,
                                strerror(errno));
        sp->count += count;
        return PM_OK;
    }
    /* Fixed chunks rather than one realloc'd block: what is held is never copied again. */
    for (size_t at = 0; at < bytes;) {
        if (sp->nchunks == 0 || sp->fill == sp->chunk_bytes) {
            if (sp->nchunks == sp->chunk_cap) {
                size_t cap = sp->chunk_cap ? 2 * sp->chunk_cap : 64;
                unsigned char **p = realloc(sp->chunk, cap * sizeof *p);
                if (!p)
                    return pm_error_set(PM_ERR_NOMEM, "out of memory for the spool's chunk table: %zu chunks", cap);
                sp->chunk = p, sp->chunk_cap = cap;
            }
            if (!(sp->chunk[sp->nchunks] = pm_alloc_aligned(sp->chunk_bytes)))
                return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu bytes of spooled records",
                                    sp->held + sp->chunk_bytes);
            sp->nchunks++;
            sp->fill = 0;
        }
        size_t room = sp->chunk_bytes - sp->fill, n = bytes - at < room ? bytes - at : room;
        memcpy(sp->chunk[sp->nchunks - 1] + sp->fill, src + at, n);
        sp->fill += n, sp->held += n, at += n;
    }
    sp->count += count;
    return PM_OK;
}

pm_result_t pm_spool_replay(pm_spool_t *sp, pm_spool_emit_fn emit, void *user)
{
    pm_result_t r = PM_OK;
    if (!sp->f) {
        for (size_t i = 0; i < sp->nchunks && r == PM_OK; i++) {
            size_t n = i + 1 < sp->nchunks ? sp->chunk_bytes : sp->fill;
            if (n)
                r = emit(user, sp->chunk[i], n / sp->record_size);
        }
        return r;
    }
    if (fflush(sp->f) != 0 || fseek(sp->f, 0, SEEK_SET) != 0)
        return pm_error_set(pm_result_of_errno(errno), "cannot rewind the spool file in '%s': %s", sp->dir,
                            strerror(errno));
    unsigned char *buf = malloc(REPLAY_RECORDS * sp->record_size);
    if (!buf)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu bytes of spool read buffer",
                            (size_t)REPLAY_RECORDS * sp->record_size);
    for (uint64_t at = 0; at < sp->count && r == PM_OK; at += REPLAY_RECORDS) {
        uint64_t n = sp->count - at < REPLAY_RECORDS ? sp->count - at : REPLAY_RECORDS;
        if (fread(buf, sp->record_size, n, sp->f) != n)
            r = pm_error_set(pm_result_of_errno(errno),
                             "cannot read the spool file in '%s' back: record %llu of %llu: %s", sp->dir,
                             (unsigned long long)at, (unsigned long long)sp->count,
                             ferror(sp->f) ? strerror(errno) : "it ends early");
        else
            r = emit(user, buf, n);
    }
    free(buf);
    return r;
}

void pm_spool_free(pm_spool_t *sp)
{
    for (size_t i = 0; i < sp->nchunks; i++)
        pm_free_aligned(sp->chunk[i]);
    free(sp->chunk);
    if (sp->f)
        fclose(sp->f);
    sp->chunk = NULL;
    sp->f = NULL;
    sp->nchunks = sp->chunk_cap = sp->fill = sp->held = 0;
    sp->count = 0;
}

void pm_spool_dir_for(const char *path, char *dir, size_t cap)
{
    if (!cap)
        return;
    /* stdout, or an output that is not a regular file (a FIFO, /dev/null): its folder is no
     * place for a spill file, so the system's temporary folder takes it. */
    struct stat sb;
    if (!path || strcmp(path, "-") == 0 || (stat(path, &sb) == 0 && !S_ISREG(sb.st_mode))) {
        const char *tmp = getenv("TMPDIR");
        snprintf(dir, cap, "%s", tmp && *tmp ? tmp : "/tmp");
        return;
    }
    snprintf(dir, cap, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash)
        snprintf(dir, cap, ".");
    else
        slash[slash == dir ? 1 : 0] = '\0'; /* "/name" keeps its "/" */
}
