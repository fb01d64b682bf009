/* atomic.c: temporary-file-and-rename outputs with signal cleanup (see atomic.h). */
#define _POSIX_C_SOURCE 200809L
#include "atomic.h"

#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
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
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
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

pm_result_t pm_atomic_reserve(const char *path, pm_atomic_t *out)
{
    memset(out, 0, sizeof *out);
    out->slot = -1;
    const char *slash = strrchr(path, '/');
    size_t dirlen = slash ? (size_t)(slash - path + 1) : 0;
    const char *base = slash ? slash + 1 : path;
    if (!*base)
        return pm_error_set(PM_ERR_USAGE, "output '%s' names a directory, not a file", path);
    size_t n = strlen(path) + 48;
    out->path = strdup(path);
    out->tmp_path = malloc(n);
    if (!out->path || !out->tmp_path) {
        free(out->path);
        free(out->tmp_path);
        out->path = out->tmp_path = NULL;
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    }
    snprintf(out->tmp_path, n, "%.*s.%s.tmp.%ld", (int)dirlen, path, base, (long)getpid());
    out->slot = register_path(out->tmp_path);
    return PM_OK;
}

pm_result_t pm_atomic_open(const char *path, pm_atomic_t *out)
{
    if (strcmp(path, "-") == 0) {
        memset(out, 0, sizeof *out);
        out->slot = -1;
        out->f = stdout;
        return PM_OK;
    }
    pm_result_t r = pm_atomic_reserve(path, out);
    if (r != PM_OK)
        return r;
    out->f = fopen(out->tmp_path, "wb");
    if (!out->f) {
        int e = errno;
        pm_atomic_abort(out);
        return pm_error_set(PM_ERR_IO, "cannot create output '%s': %s", path, strerror(e));
    }
    return PM_OK;
}

pm_result_t pm_atomic_commit(pm_atomic_t *a)
{
    const char *name = a->path ? a->path : "stdout";
    int bad = 0, e = 0;
    if (a->f) {
        if (fflush(a->f) != 0 || ferror(a->f))
            bad = 1, e = errno;
        if (a->f != stdout) {
            if (fclose(a->f) != 0 && !bad)
                bad = 1, e = errno;
        }
        a->f = NULL;
    }
    if (bad) {
        pm_atomic_abort(a);
        return pm_error_set(PM_ERR_IO, "cannot write '%s': %s", name, strerror(e ? e : EIO));
    }
    if (a->tmp_path && rename(a->tmp_path, a->path) != 0) {
        e = errno;
        pm_atomic_abort(a);
        return pm_error_set(PM_ERR_IO, "cannot rename output into '%s': %s", name, strerror(e));
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
