/* atomic.h: outputs that appear whole or not at all, and never clobber what is not a file.
 *
 * A regular output is written into DIR/.NAME.XXXXXX (mkstemp; the NAME part shortened so that
 * the temporary name fits NAME_MAX) and renamed onto DIR/NAME only after the last byte is
 * flushed, checked and fsync'ed; the directory is fsync'ed after the rename, so that after a
 * power loss NAME is either the old file or the whole new one (PMTK_FSYNC=0 in the environment
 * leaves out both fsyncs, for callers that check a file's checksum before they trust it: then
 * a power loss can leave NAME torn, never a reader fooled). Temporary files are registered
 * so that SIGINT, SIGTERM, SIGHUP and SIGPIPE remove them before the process dies.
 *
 * What the path names decides how it is written (docs/cli.md, "Outputs"):
 *   "-"                   stdout, written directly
 *   a FIFO, a device, a socket (also /dev/null, /dev/stdout on a pipe or a terminal)
 *                         opened and written directly: no temporary file, no rename
 *   /dev/stdout, /dev/fd/N on a regular file
 *                         appended to directly: the file the descriptor holds is kept
 *   a symbolic link       followed to the end of its chain; the file it points to (which may
 *                         not exist yet) is replaced as above, and the link stays a link
 *   a directory           refused
 * A rename never replaces anything but a regular file: the target is checked again just
 * before it.
 *
 * Output sets: several outputs of one command appear together. While a set is open on a
 * thread, pm_atomic_commit there only prepares an output (written, checked, synced, closed)
 * and hands it to the set; pm_atomic_set_commit renames them all, pm_atomic_set_abort removes
 * them all, so that a failure of the last output leaves none of the others at its final name. */
#ifndef PM_ATOMIC_H
#define PM_ATOMIC_H

#include <stddef.h>
#include <stdio.h>

#include "base/error.h"

typedef struct {
    FILE *f;        /* where to write; NULL for a reserved name */
    char *path;     /* the path as given, for messages; NULL for stdout */
    char *target;   /* what the rename replaces: path, or the end of its symbolic links */
    char *tmp_path; /* the temporary path; NULL for stdout and for a special file */
    int slot;       /* index in the cleanup registry, -1 when none */
    int special;    /* 1: a FIFO or device, 2: a regular file behind /dev/fd/N; written through (a
                     * reserved name is copied to it) */
    int no_sync;    /* 1 (set by the caller after open): no fsync for this output, as PMTK_FSYNC=0 for
                     * it alone, when every reader checks its checksum (a cache) */
} pm_atomic_t;

/* Outputs prepared while the set is open, renamed into place together. */
typedef struct pm_atomic_set {
    pm_atomic_t *items;
    size_t n, cap;
    struct pm_atomic_set *outer; /* the set open on this thread before this one; NULL when none */
    int open;
} pm_atomic_set_t;

/* Installs the signal handlers that remove registered temporary files. Idempotent. */
void pm_atomic_install_cleanup(void);

/* Opens path ("-" for stdout) for writing, as the rules above say. */
pm_result_t pm_atomic_open(const char *path, pm_atomic_t *out);

/* For libraries that write by name (OpenEXR): reserves a temporary path (out->tmp_path) and
 * registers it for cleanup; no file is left open. Beside path for a regular output; for a
 * special file, in $TMPDIR (or /tmp), copied to the special file on commit. */
pm_result_t pm_atomic_reserve(const char *path, pm_atomic_t *out);

/* Whether path could be opened as an output, without writing to it: a temporary file is made
 * and removed beside a regular target; a special file is only checked for write permission
 * (opening a FIFO would wait for, then end, its reader's stream). "-" is always fine. */
pm_result_t pm_atomic_check(const char *path);

/* Flushes, checks every write succeeded, fsyncs, closes and renames into place (with a set
 * open on this thread: hands the output to the set instead). On failure the temporary file is
 * removed and nothing appears at path. */
pm_result_t pm_atomic_commit(pm_atomic_t *a);

/* Closes and removes the temporary file; safe on a zeroed or committed handle. */
void pm_atomic_abort(pm_atomic_t *a);

/* Opens a set on this thread: outputs committed on it from now on wait for the set. A set
 * opened while another is open on the thread joins that one: its commit and abort are left to
 * the outer set. */
void pm_atomic_set_begin(pm_atomic_set_t *s);

/* Closes the set and renames every output it holds into place, after checking that each
 * target may still be replaced. A rename that fails after others succeeded (rare: everything
 * that can fail on a full disk has failed before the first rename) removes those of them that
 * created a new name; a file they replaced stays replaced. */
pm_result_t pm_atomic_set_commit(pm_atomic_set_t *s);

/* Closes the set and removes every output it holds; safe after commit. */
void pm_atomic_set_abort(pm_atomic_set_t *s);

/* Ends a set by the result of the work that wrote it: commits on PM_OK (returning the
 * commit's result), otherwise aborts and returns result. */
pm_result_t pm_atomic_set_end(pm_atomic_set_t *s, pm_result_t result);

/* Whether two output paths name one file: the same words, the same existing file (device and
 * inode; /dev/null excepted: it takes any number of outputs), or the same name in the same
 * directory once that is resolved. "-" is stdout: the same as a name of the file or pipe stdout
 * is open on (/dev/stdout, /dev/fd/1), by device and inode. */
int pm_atomic_same_file(const char *a, const char *b);

#endif
