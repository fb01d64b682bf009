/* lock.c: one render at a time in an OUTDIR (engine.h, pm_engine_lock), for pm-render's single
 * renders and its resident passes alike. */
#include "engine/engine.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <unistd.h>

#include "base/error.h"

int pm_engine_lock(const char *me, const char *outdir, int wait, const char *cmdline, int *fd_out)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/.lock", outdir);
    *fd_out = -1;
    /* Not close-on-exec: the stages inherit the lock, so that after a render is killed its
     * orphaned stages, still writing into OUTDIR, hold it until they end. */
    int fd = open(path, O_RDWR | O_CREAT, 0666);
    if (fd < 0) {
        int e = errno;
        fprintf(stderr, "%s: cannot open the lock file '%s': %s\n", me, path, strerror(e));
        return pm_result_exit_code(pm_result_of_errno(e));
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        char holder[1001] = "";
        ssize_t n = pread(fd, holder, 1000, 0);
        holder[n > 0 ? n : 0] = '\0';
        holder[strcspn(holder, "\n")] = '\0';
        if (!wait) {
            /* not a failure of the system, and no retry at once would help: the input's class */
            fprintf(stderr, "%s: '%s' is in use by another render (%s); WAIT=0 does not wait\n", me, outdir,
                    holder[0] ? holder : "holder unknown");
            close(fd);
            return 1;
        }
        fprintf(stderr, "%s: waiting for '%s', in use by another render (%s)\n", me, outdir,
                holder[0] ? holder : "holder unknown");
        int rc;
        while ((rc = flock(fd, LOCK_EX)) != 0 && errno == EINTR)
            ;
        if (rc != 0) {
            int e = errno;
            fprintf(stderr, "%s: cannot lock '%s': %s\n", me, path, strerror(e));
            close(fd);
            return pm_result_exit_code(pm_result_of_errno(e));
        }
    }
    /* The holder's line, for a second render's message: its pid and command line. */
    char line[8192];
    int n = snprintf(line, sizeof line, "pid %d: %s\n", (int)getpid(), cmdline);
    n = n > (int)sizeof line - 1 ? (int)sizeof line - 1 : n;
    if (ftruncate(fd, 0) != 0 || pwrite(fd, line, (size_t)n, 0) != n) {
        int e = errno;
        fprintf(stderr, "%s: cannot write the lock file '%s': %s\n", me, path, strerror(e));
        close(fd);
        return pm_result_exit_code(pm_result_of_errno(e));
    }
    *fd_out = fd;
    return 0;
}
