/* atomic.c: temporary-file-and-rename outputs with signal cleanup (see atomic.h). */
#define _POSIX_C_SOURCE 200809L
#include "base/atomic.h"

#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PM_ATOMIC_SLOTS 16 /* temporary files open at once in one process */

/* Paths the signal handler removes. A slot is published by storing its pointer last,
 * and the handler only reads pointers and calls unlink, which is async-signal-safe. */
static char *volatile cleanup_paths[PM_ATOMIC_SLOTS];

static void on_signal(int sig)
{
    for (int i = 0; i < PM_ATOMIC_SLOTS; i++)
        if (cleanup_paths[i])
            unlink(cleanup_paths[i]);
    signal(sig, SIG_DFL);
    raise(sig);
}

void pm_atomic_install_cleanup(void)
{
    static int installed;
    if (installed)
        return;
    installed = 1;
    /* SIGPIPE too: a stage writing stdout and a file must not leave the file's temporary
     * behind when its reader goes away. A signal the caller ignores (nohup) stays ignored. */
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGPIPE};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN)
            continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

static int register_path(char *p)
{
    for (int i = 0; i < PM_ATOMIC_SLOTS; i++)
        if (!cleanup_paths[i]) {
            cleanup_paths[i] = p;
            return i;
        }
    return -1;
}

static void unregister(pm_atomic_t *a)
{
    if (a->slot >= 0)
        cleanup_paths[a->slot] = NULL;
    a->slot = -1;
}

/* Creates the temporary file beside path with a unique name (mkstemp: O_EXCL, never
 * following a planted link), registered for cleanup; *fd_out is open for writing. */
static pm_result_t make_temp(const char *path, pm_atomic_t *out, int *fd_out)
{
    memset(out, 0, sizeof *out);
    out->slot = -1;
    const char *slash = strrchr(path, '/');
    size_t dirlen = slash ? (size_t)(slash - path + 1) : 0;
    const char *base = slash ? slash + 1 : path;
    if (!*base)
        return pm_error_set(PM_ERR_USAGE, "output '%s' names a directory, not a file", path);
    size_t n = strlen(path) + 16;
    out->path = strdup(path);
    out->tmp_path = malloc(n);
    if (!out->path || !out->tmp_path) {
        free(out->path);
        free(out->tmp_path);
        out->path = out->tmp_path = NULL;
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    }
    snprintf(out->tmp_path, n, "%.*s.%s.XXXXXX", (int)dirlen, path, base);
    int fd = mkstemp(out->tmp_path);
    if (fd < 0) {
        int e = errno;
        free(out->path);
        free(out->tmp_path);
        out->path = out->tmp_path = NULL;
        return pm_error_set(e == ENOENT || e == ENOTDIR ? PM_ERR_INPUT : PM_ERR_IO, "cannot create output '%s': %s",
                            path, strerror(e));
    }
    out->slot = register_path(out->tmp_path);
    /* mkstemp makes 0600; an output should get the permissions any new file would. */
    mode_t mask = umask(0);
    umask(mask);
    fchmod(fd, 0666 & ~mask);
    *fd_out = fd;
    return PM_OK;
}

pm_result_t pm_atomic_reserve(const char *path, pm_atomic_t *out)
{
    int fd;
    pm_result_t r = make_temp(path, out, &fd);
    if (r == PM_OK)
        close(fd); /* the library that writes by name reopens (and truncates) it */
    return r;
}

pm_result_t pm_atomic_open(const char *path, pm_atomic_t *out)
{
    if (strcmp(path, "-") == 0) {
        memset(out, 0, sizeof *out);
        out->slot = -1;
        out->f = stdout;
        return PM_OK;
    }
    int fd;
    pm_result_t r = make_temp(path, out, &fd);
    if (r != PM_OK)
        return r;
    out->f = fdopen(fd, "wb");
    if (!out->f) {
        int e = errno;
        close(fd);
        pm_atomic_abort(out);
        return pm_error_set(PM_ERR_IO, "cannot create output '%s': %s", path, strerror(e));
    }
    return PM_OK;
}

pm_result_t pm_atomic_commit(pm_atomic_t *a)
{
    int bad = 0, e = 0;
    if (a->f) {
        if (fflush(a->f) != 0 || ferror(a->f))
            bad = 1, e = errno;
        if (a->f != stdout && fclose(a->f) != 0 && !bad)
            bad = 1, e = errno;
        a->f = NULL;
    }
    if (!bad && a->tmp_path && rename(a->tmp_path, a->path) != 0)
        bad = 2, e = errno;
    if (bad) {
        /* The message first: abort frees the path it names. */
        pm_error_set(PM_ERR_IO, "cannot %s '%s': %s", bad == 1 ? "write" : "rename output into",
                     a->path ? a->path : "stdout", strerror(e ? e : EIO));
        pm_atomic_abort(a);
        return PM_ERR_IO;
    }
    unregister(a);
    free(a->tmp_path);
    free(a->path);
    a->tmp_path = a->path = NULL;
    return PM_OK;
}

void pm_atomic_abort(pm_atomic_t *a)
{
    if (a->f && a->f != stdout)
        fclose(a->f);
    a->f = NULL;
    if (a->tmp_path)
        unlink(a->tmp_path);
    unregister(a);
    free(a->tmp_path);
    free(a->path);
    a->tmp_path = a->path = NULL;
}
