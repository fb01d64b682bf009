/* spool.h: fixed-size records kept in arrival order until their number is known.
 *
 * A pmtk header carries COUNT before the first record, so a stage that learns its count only
 * at the end (trace-gather-points) holds its records here and replays them once it knows.
 * Records are kept in memory, in fixed chunks (no copying of what is held), up to a limit;
 * past it everything held and everything after goes to an unlinked temporary file in a
 * directory the caller names. The spool knows nothing of what the records mean.
 *
 * Not thread-safe: one thread at a time adds and replays, the calls ordered by the caller (in
 * trace-gather-points, bands go in from whichever thread delivers them, one band after another,
 * ordered by OpenMP's barriers). */
#ifndef PM_SPOOL_H
#define PM_SPOOL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"

typedef struct {
    unsigned char **chunk; /* records in memory, chunk_bytes each (whole records), the last one filling */
    size_t nchunks, chunk_cap;
    size_t fill;        /* bytes used in the last chunk */
    size_t chunk_bytes; /* bytes per chunk, a whole number of records */
    size_t held;        /* bytes in memory */
    size_t mem_max;     /* bytes held in memory before spilling */
    size_t record_size; /* bytes per record */
    FILE *f;            /* spilled records, NULL while they fit in memory */
    char dir[1024];     /* where a spill file goes */
    uint64_t count;     /* records added */
} pm_spool_t;

/* An empty spool of records of record_size bytes (>= 1) that spills past mem_max bytes into an
 * unlinked file in dir (O_TMPFILE, else tmpfile()). Allocates nothing. */
void pm_spool_init(pm_spool_t *sp, size_t record_size, size_t mem_max, const char *dir);

/* Appends count records (count * record_size bytes). On failure (PM_ERR_IO: the spill file
 * cannot be made or written; PM_ERR_NOMEM) the spool is only good for pm_spool_free. */
pm_result_t pm_spool_add(pm_spool_t *sp, const void *records, uint64_t count);

/* Hands every record back, in order, to emit in runs of at most a few MiB; stops at and
 * returns the first failure. The spool itself is unchanged, except that a spill file is read. */
typedef pm_result_t (*pm_spool_emit_fn)(void *user, const void *records, uint64_t count);
pm_result_t pm_spool_replay(pm_spool_t *sp, pm_spool_emit_fn emit, void *user);

/* 1 once the records went to a file. */
static inline int pm_spool_spilled(const pm_spool_t *sp) { return sp->f != NULL; }

/* Frees the chunks and closes (so removes) the spill file; the spool is then empty. */
void pm_spool_free(pm_spool_t *sp);

/* The directory a spool for output path belongs in, into dir (cap bytes): the folder of path,
 * so that the spill lands on the disk the output goes to, or $TMPDIR (else /tmp) for "-" and for an
 * output that exists and is not a regular file (a FIFO, /dev/null). */
void pm_spool_dir_for(const char *path, char *dir, size_t cap);

#endif
