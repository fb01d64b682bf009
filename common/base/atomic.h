/* atomic.h: outputs that appear whole or not at all.
 *
 * A stage writes into DIR/.NAME.XXXXXX (mkstemp) and renames it onto DIR/NAME only after
 * the last byte is flushed and checked, so an interrupted or failing stage never leaves a
 * file that looks complete. Temporary files are registered so that SIGINT, SIGTERM, SIGHUP
 * and SIGPIPE remove them before the process dies. "-" means stdout, written directly.
 * No fsync: after a power loss a renamed file may be short, and then its reader rejects
 * it (truncated, checksum), which is the promise; durability is not worth a sync per file. */
#ifndef PM_ATOMIC_H
#define PM_ATOMIC_H

#include <stdio.h>

#include "base/error.h"

typedef struct {
    FILE *f;        /* where to write */
    char *path;     /* the final path; NULL for stdout */
    char *tmp_path; /* the temporary path; NULL for stdout */
    int slot;       /* index in the cleanup registry, -1 when none */
} pm_atomic_t;

/* Installs the signal handlers that remove registered temporary files. Idempotent. */
void pm_atomic_install_cleanup(void);

/* Opens path ("-" for stdout) for writing through a temporary file. */
pm_result_t pm_atomic_open(const char *path, pm_atomic_t *out);

/* For libraries that write by name (OpenEXR): reserves a temporary path beside `path`
 * and registers it for cleanup; no file is opened. */
pm_result_t pm_atomic_reserve(const char *path, pm_atomic_t *out);

/* Flushes, checks every write succeeded, closes and renames into place. On failure the
 * temporary file is removed and nothing appears at path. */
pm_result_t pm_atomic_commit(pm_atomic_t *a);

/* Closes and removes the temporary file; safe on a zeroed or committed handle. */
void pm_atomic_abort(pm_atomic_t *a);

#endif
